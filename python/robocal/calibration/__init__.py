"""Calibrators on the core: the shared :class:`Problem`, one :class:`CalibrationResult`, the
paper's metrics and the methods."""

from .api import METHODS, calibrate
from .fleet import calibrate_many
from .metrics import metrics, sample_errors
from .problem import Problem, start_parameters
from .result import CalibrationResult

__all__ = ["METHODS", "CalibrationResult", "Problem", "calibrate", "calibrate_many", "metrics", "sample_errors", "start_parameters"]
