"""robocal — fast, honest kinematic calibration of industrial robots.

The hot core (kinematics, identification Jacobians, sigma points, damped solves,
identifiability) is Rust in :mod:`robocal._robocal`, wrapped for NumPy in
:mod:`robocal.kernels`; this package is the thin Python layer. Units: mm and radians everywhere
inside.

The public API: the functions that mirror the command line (``load``, ``simulate``,
``calibrate``, ``diagnose``, ``verify``, ``compensate``, ``plan`` …; positional for their data
or file arguments, keyword-only options), robots (``robot``, ``write_robot``, the
roboticstoolbox bridge) and the types they take and return (``Robot``, ``Dataset``,
``CalibrationResult``, ``Diagnosis``, ``SessionsDiagnosis``, ``Plan`` …), and the documents they
write read back typed (``load_result``, ``load_diagnosis``: a diagnose report as a
:class:`~robocal.diagnosis_file.DiagnosisReport`).
"""

from __future__ import annotations

import logging

from . import exceptions
from ._robocal import __version__
from .robot import MEASUREMENTS, Joint, MassModel, Robot, robot, write_robot

# Diagnostic messages go to the standard ``logging`` module, one logger per module under
# "robocal"; silent unless the application (or ``robocal --debug``) configures logging.
logging.getLogger(__name__).addHandler(logging.NullHandler())

__all__ = [
    "MEASUREMENTS",
    "CalibrationResult",
    "Constraints",
    "Dataset",
    "Diagnosis",
    "DiagnosisReport",
    "Joint",
    "MassModel",
    "Monitor",
    "Plan",
    "Remastering",
    "Robot",
    "SessionsDiagnosis",
    "__version__",
    "calibrate",
    "calibrate_many",
    "compensate",
    "diagnose",
    "exceptions",
    "from_roboticstoolbox",
    "load",
    "load_diagnosis",
    "load_result",
    "plan",
    "remaster",
    "robot",
    "simulate",
    "to_roboticstoolbox",
    "verify",
    "write_robot",
]


#: The API that mirrors the command line and the types it returns, loaded on first use (with
#: scipy) rather than at ``import robocal``: name -> (module, attribute).
_LAZY = {
    "load": ("robocal.data", "load"),
    "simulate": ("robocal.simulation", "simulate"),
    "calibrate": ("robocal.causes.extended", "calibrate"),
    "calibrate_many": ("robocal.fleet", "calibrate_many"),
    "diagnose": ("robocal.diagnosis", "diagnose"),
    "compensate": ("robocal.compensation", "compensate"),
    "load_result": ("robocal.results", "load_result"),
    "load_diagnosis": ("robocal.diagnosis_file", "load_diagnosis"),
    "verify": ("robocal.verification", "verify"),
    "Monitor": ("robocal.monitoring", "Monitor"),
    "plan": ("robocal.planning", "plan"),
    "remaster": ("robocal.remastering", "remaster"),
    "Remastering": ("robocal.remastering", "Remastering"),
    "from_roboticstoolbox": ("robocal.rtb", "from_roboticstoolbox"),
    "to_roboticstoolbox": ("robocal.rtb", "to_roboticstoolbox"),
    "Dataset": ("robocal.data.dataset", "Dataset"),
    "CalibrationResult": ("robocal.calibration.result", "CalibrationResult"),
    "Diagnosis": ("robocal.diagnosis", "Diagnosis"),
    "SessionsDiagnosis": ("robocal.diagnosis", "SessionsDiagnosis"),
    "DiagnosisReport": ("robocal.diagnosis_file", "DiagnosisReport"),
    "Plan": ("robocal.planning", "Plan"),
    "Constraints": ("robocal.planning", "Constraints"),
}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        module, attribute = _LAZY[name]
        return getattr(importlib.import_module(module), attribute)
    raise AttributeError(f"module 'robocal' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
