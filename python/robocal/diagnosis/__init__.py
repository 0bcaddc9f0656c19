"""Diagnosis: what the geometric model gets wrong on measured data, its cause, and the gain of
modelling it (:func:`diagnose`)."""

from .candidates import LIMITS, Candidate, library
from .model import ExtendedProblem
from .select import Diagnosis, diagnose

__all__ = ["LIMITS", "Candidate", "Diagnosis", "ExtendedProblem", "diagnose", "library"]
