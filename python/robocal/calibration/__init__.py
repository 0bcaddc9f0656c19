"""Calibrators on the core: the shared :class:`Problem`, one :class:`CalibrationResult`, the
paper's metrics and the methods."""

from .api import METHODS, calibrate
from .metrics import metrics, sample_errors
from .problem import Problem, start_parameters
from .result import CalibrationResult

__all__ = ["METHODS", "CalibrationResult", "Problem", "calibrate", "metrics", "sample_errors", "start_parameters"]
