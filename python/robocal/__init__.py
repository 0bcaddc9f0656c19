"""robocal — fast, honest kinematic calibration of industrial robots.

The hot core (kinematics, identification Jacobians, sigma points, damped solves,
identifiability) is Rust in :mod:`robocal._robocal`; this package is the thin Python layer.
Units: mm and radians everywhere inside.
"""

from __future__ import annotations

from . import exceptions
from ._robocal import __version__
from .core import cable_initial_guess, covariance, identifiability, merwe_sigma_points, solve_damped, unscented_transform
from .robot import MEASUREMENTS, Joint, Robot, robot, write_robot

__all__ = [
    "MEASUREMENTS",
    "Joint",
    "Robot",
    "__version__",
    "cable_initial_guess",
    "calibrate",
    "calibrate_many",
    "compensate",
    "covariance",
    "diagnose",
    "exceptions",
    "from_roboticstoolbox",
    "identifiability",
    "load",
    "load_result",
    "merwe_sigma_points",
    "plan",
    "robot",
    "simulate",
    "to_roboticstoolbox",
    "solve_damped",
    "unscented_transform",
    "verify",
    "write_robot",
]


#: The API that mirrors the command line, loaded on first use (with scipy) rather than at
#: ``import robocal``: name -> (module, attribute).
_LAZY = {
    "load": ("robocal.data", "load"),
    "simulate": ("robocal.simulation", "simulate"),
    "calibrate": ("robocal.diagnosis.extended", "calibrate"),
    "calibrate_many": ("robocal.fleet", "calibrate_many"),
    "diagnose": ("robocal.diagnosis", "diagnose"),
    "compensate": ("robocal.compensation", "compensate"),
    "load_result": ("robocal.results", "load_result"),
    "verify": ("robocal.verification", "verify"),
    "plan": ("robocal.planning", "plan"),
    "from_roboticstoolbox": ("robocal.rtb", "from_roboticstoolbox"),
    "to_roboticstoolbox": ("robocal.rtb", "to_roboticstoolbox"),
}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        module, attribute = _LAZY[name]
        return getattr(importlib.import_module(module), attribute)
    raise AttributeError(f"module 'robocal' has no attribute {name!r}")
