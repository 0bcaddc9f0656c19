"""robocal — fast, honest kinematic calibration of industrial robots.

The hot core (kinematics, identification Jacobians, sigma points, damped solves,
identifiability) is Rust in :mod:`robocal._robocal`; this package is the thin Python layer.
Units: mm and radians everywhere inside.
"""

from __future__ import annotations

from . import exceptions
from ._robocal import __version__
from .core import cable_initial_guess, covariance, identifiability, merwe_sigma_points, solve_damped, unscented_transform
from .robot import MEASUREMENTS, Joint, Robot, robot

__all__ = [
    "MEASUREMENTS",
    "Joint",
    "Robot",
    "__version__",
    "cable_initial_guess",
    "calibrate",
    "covariance",
    "diagnose",
    "exceptions",
    "identifiability",
    "merwe_sigma_points",
    "robot",
    "solve_damped",
    "unscented_transform",
]


def __getattr__(name: str):
    # `robocal.calibrate` and `robocal.diagnose` load (with scipy) on first use, not at `import robocal`.
    if name == "calibrate":
        from .calibration import calibrate

        return calibrate
    if name == "diagnose":
        from .diagnose import diagnose

        return diagnose
    raise AttributeError(f"module 'robocal' has no attribute {name!r}")
