"""A sensor that wanders in time: its session term.

A cable sensor's zero or a tracker's frame that moves slowly and irregularly leaves residuals
that are alike for samples taken one after another — whatever the joints did between them (the
test that tells it from a cause of the robot is :mod:`robocal.diagnosis.wander`'s).

The session term is a cubic B-spline of the acquisition order per sensor axis, knots a fraction
of the correlation length apart, with a second-difference roughness penalty (so that it bridges
a held-out block by a straight line instead of guessing). It belongs to the session: it is never
carried to another one.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.interpolate import BSpline
from scipy.linalg import null_space

from ..data.dataset import Dataset
from ..robot import RESIDUAL_WIDTH
from .candidates import Candidate, acquisition_order, acquisition_position, curved_drift

#: Kinds that are smooth functions of time within one session (this module's term).
TIME_TERMS = ("wander",)


def within_session(c: Candidate) -> bool:
    """Whether ``c`` is judged within its session only: a block of the session the fit never saw
    cannot tell where or how far it goes, so the blocked folds judge only that it does no harm
    (:data:`TIME_TERMS`, and a curved drift, whose curve a held-out end block would extrapolate).
    A linear drift is not among them: judged so, it was named beside wanders and in the place of
    steps. A step is not either: judged on every scheme (on the folds that can estimate it), it
    is not named at the bends of a wandering reading."""
    return c.kind in TIME_TERMS or curved_drift(c)


#: Roughness penalty of the wander spline (mm per mm of second difference of its coefficients).
ROUGHNESS = 0.3
#: Most spline coefficients per axis (a long session gets wider knots).
MAX_KNOTS = 80


def wander_candidate(data: Dataset, spacing: float, roughness: float = ROUGHNESS, trend: bool = False) -> Candidate:
    """The session term of a wandering sensor: a cubic B-spline of the acquisition order with
    knots ``spacing`` samples apart (at least so many that there are at most
    :data:`MAX_KNOTS` per axis), one per sensor axis, and its ``roughness`` penalty. With
    ``trend`` it keeps its trend (a wander whose trend is no more than chance: labelled
    ``trend=kept``)."""
    m, k = len(data), RESIDUAL_WIDTH[data.measurement]
    spacing = max(float(spacing), (m - 1) / (MAX_KNOTS - 3), 2.0)
    rank = acquisition_position(data)
    inner = np.arange(0.0, m - 1 + spacing, spacing)
    knots = np.concatenate([[inner[0]] * 3, inner, [inner[-1]] * 3])
    B = BSpline.design_matrix(np.clip(rank, inner[0], inner[-1]), knots, 3).toarray()
    # Without its mean and its trend: a constant offset of the sensor is the set-up's (anchor,
    # cable zero, tracker base), which the geometric model already fits, and a steady trend is
    # a drift, a cause of its own with one coefficient per axis.
    centred = null_space(np.vstack([B.sum(axis=0)] + ([] if trend else [rank @ B])))
    B = B @ centred
    axes = ["L"] if data.measurement == "cable" else ["x", "y", "z"]
    n = B.shape[1]
    basis = np.zeros((m, k, n * len(axes)))
    for a in range(len(axes)):
        basis[:, a, a * n : (a + 1) * n] = B
    second = np.diff(np.eye(len(centred)), 2, axis=0) @ centred
    penalty = roughness * np.kron(np.eye(len(axes)), second)  # per axis, no coupling between axes
    detail = {"spacing": round(spacing, 3), "axes": axes} | ({} if roughness == ROUGHNESS else {"roughness": roughness}) | ({"trend": "kept"} if trend else {})
    return Candidate("wander", None, "observations", basis, detail=detail, penalty=penalty)


def wander_centred(c: Candidate, fitted: np.ndarray) -> Candidate:
    """``c`` without its mean over the samples ``fitted``: the wander term is centred over the
    whole session, and fitted on part of it, it would otherwise take a share of the set-up's
    constant, which it does not carry into the samples it never saw (the blocked folds lost 8 %).
    (Its trend is left: taken out too, a pose wander lost to two steps and a map.)"""
    return replace(c, basis=c.basis - c.basis[fitted].mean(axis=0, keepdims=True))


def wander_within(c: Candidate, data: Dataset, fitted: np.ndarray) -> Candidate:
    """``c`` correcting only samples with fitted samples within one knot spacing (in
    acquisition order) on both sides: a session term fitted on some samples interpolates between
    them, but says nothing about a stretch of the session it never saw (a blocked fold's test
    block), where its roughness penalty would only continue its last slope — as a joint map says
    nothing beyond its angles."""
    rank = np.empty(len(data))
    rank[acquisition_order(data)] = np.arange(len(data))
    seen = np.sort(rank[fitted])
    after = np.searchsorted(seen, rank)  # first fitted sample at or after each sample
    before_gap = np.where(after > 0, rank - seen[np.maximum(after - 1, 0)], np.inf)
    after_gap = np.where(after < len(seen), seen[np.minimum(after, len(seen) - 1)] - rank, np.inf)
    inside = (after_gap == 0) | ((before_gap <= c.detail["spacing"]) & (after_gap <= c.detail["spacing"]))
    return replace(c, basis=np.where(inside[:, None, None], c.basis, 0.0))
