"""Calibrators on the core: the shared :class:`Problem`, one :class:`CalibrationResult`, the
paper's metrics and the methods (run on data by :func:`robocal.calibrate`)."""

from .api import METHODS
from .metrics import metrics, sample_errors
from .problem import Problem, start_parameters
from .result import CalibrationResult

__all__ = ["METHODS", "CalibrationResult", "Problem", "metrics", "sample_errors", "start_parameters"]
