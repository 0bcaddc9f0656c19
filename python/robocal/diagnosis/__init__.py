"""Diagnosis: what the geometric model gets wrong on measured data, its cause, and the gain of
modelling it (:func:`diagnose`)."""

from .select import Diagnosis, diagnose as diagnose_session
from .sessions import SessionsDiagnosis, diagnose_sessions

__all__ = ["Diagnosis", "SessionsDiagnosis", "diagnose", "diagnose_session", "diagnose_sessions"]


def diagnose(data, *, robot=None, **options):
    """What the geometric model gets wrong, its causes and their held-out gain: on one session
    (a file or Dataset, :func:`~robocal.diagnosis.select.diagnose`) or on a list of sessions of
    one robot (:func:`~robocal.diagnosis.sessions.diagnose_sessions`, leave-one-session-out).
    """
    if isinstance(data, (list, tuple)):
        return diagnose_sessions(data, robot, **options)
    return diagnose_session(data, robot, **options)
