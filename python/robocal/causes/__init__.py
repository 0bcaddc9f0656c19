"""The cause model: what a cause is and how it changes the measurement model — the candidate
causes (:mod:`.candidates`, a wandering sensor's session term :mod:`.wander`), the reading
conventions of the joints (:mod:`.structure`), the geometric problem extended by causes
(:mod:`.problem`), a calibration with given causes (:mod:`.extended`, :func:`robocal.calibrate`)
and a result's model applied to readings (:mod:`.result_model`). Which causes the data show is
the diagnosis' question (:mod:`robocal.diagnosis`)."""

from .candidates import LIMITS, Candidate, library
from .problem import ExtendedProblem

__all__ = ["LIMITS", "Candidate", "ExtendedProblem", "library"]
