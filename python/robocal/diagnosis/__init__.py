"""Diagnosis: what the geometric model gets wrong on measured data, its cause, and the gain of
modelling it (:func:`diagnose`)."""

from .candidates import LIMITS, Candidate, library
from .model import ExtendedProblem
from .select import Diagnosis, diagnose as diagnose_session
from .sessions import SessionsDiagnosis, diagnose_sessions

__all__ = ["LIMITS", "Candidate", "Diagnosis", "ExtendedProblem", "SessionsDiagnosis", "diagnose", "diagnose_session", "diagnose_sessions", "library"]


def diagnose(data, *, robot=None, **options):
    """What the geometric model gets wrong, its causes and their held-out gain: on one session
    (a file or Dataset, :func:`~robocal.diagnosis.select.diagnose`) or on a list of sessions of
    one robot (:func:`~robocal.diagnosis.sessions.diagnose_sessions`, leave-one-session-out).
    """
    if isinstance(data, (list, tuple)):
        return diagnose_sessions(data, robot, **options)
    return diagnose_session(data, robot, **options)
