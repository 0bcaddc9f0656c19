"""Where the sensor may have stepped: change points of a fit's residuals in acquisition order,
each proposed as a step candidate (:func:`robocal.causes.candidates.step_candidate`) that the
selection tests like any other cause — the gradual changes a step must beat to be named
(:func:`ramps`), and the smooth ones it is stated against (:func:`transitions`)."""

from __future__ import annotations

from typing import Optional

import numpy as np

from ..causes.candidates import SHIFT_AXES, Candidate, acquisition_order, acquisition_position, cable_directions, step_candidate
from ..data.dataset import Dataset
from ..kernels import is_sparse
from ..serial_robot import Robot

#: Change points proposed per diagnosis: ruptures' binary segmentation asked for this many.
STEPS_PROPOSED = 3


def _summed_l2_cost():
    """ruptures' l2 cost (a segment's squared deviations from its mean) from running sums: each
    segment's cost in O(1) instead of a variance over its samples — binary segmentation asks for
    every split of every segment, which made ruptures' own l2 cost O(m²) per split (two minutes of
    a 12 000-sample diagnosis)."""
    from ruptures.base import BaseCost

    class SummedL2(BaseCost):
        model = "l2 (running sums)"
        min_size = 1

        def fit(self, signal):
            self.signal = x = signal.reshape(len(signal), -1)
            self.s1 = np.vstack([np.zeros(x.shape[1]), np.cumsum(x, axis=0)])
            self.s2 = np.concatenate([[0.0], np.cumsum(np.sum(x * x, axis=1))])
            return self

        def error(self, start, end):
            s = self.s1[end] - self.s1[start]
            return float(self.s2[end] - self.s2[start] - s @ s / (end - start))

    return SummedL2()


def step_candidates(data: Dataset, idx: np.ndarray, residuals: np.ndarray, robot: Optional[Robot] = None, jacobian=None) -> list[Candidate]:
    """Steps at the change points of a fit's residuals (``residuals`` (len(idx), k) of the
    samples ``idx``) in acquisition order: ruptures' binary segmentation with the l2 cost on the
    residuals scaled per axis, :data:`STEPS_PROPOSED` change points, segments of at least 1 % of
    the samples (and 5). Each becomes two candidates that the selection tests like any other: the
    readings shifted, and the sensor moved as a rigid body (:func:`step_candidate`; a cable's
    directions to the tool points of ``robot``, the fitted one). A cable's rigid move is also
    proposed where its columns beside the robot's columns of the model's ``jacobian`` (its rows
    of ``idx``, weighted as ``residuals`` are) explain most (:func:`best_place`)."""
    import ruptures  # imported on use: only a diagnosis needs it

    order = np.argsort(np.argsort(acquisition_order(data))[idx], kind="stable")  # idx in acquisition order
    # Only the components a step moves: a pose's rotation rows would add their noise to the
    # change-point cost and misplace the step (7-14 samples on simulated pose files).
    signal = residuals[order][:, :3]
    scale = np.std(signal, axis=0)
    signal = signal / np.where(scale > 0, scale, 1.0)
    m = len(signal)
    min_size = max(5, m // 100)
    if m < 2 * min_size + 1:
        return []
    breaks = ruptures.Binseg(custom_cost=_summed_l2_cost(), min_size=min_size, jump=1).fit(signal).predict(n_bkps=min(STEPS_PROPOSED, m // min_size - 1))
    # each as a shift of the readings and as the sensor's rigid move (the selection prefers the shift where it gains as much);
    # a cable's move needs its directions, a robot's tool points
    directions = cable_directions(data, robot) if data.measurement == "cable" else None
    moves = (False,) if data.measurement == "cable" and directions is None else (False, True)
    places = {(b, rigid) for b in breaks if b < m for rigid in moves}
    # A cable's anchor moved across the cable lengthens some readings and shortens others: the
    # readings' mean hardly changes, and the model's geometry takes most of it up. Its place is
    # where its own columns, beside the model's, explain most (a cable sensor knocked 5-8 times
    # its detection limit was placed 13-100 samples off by the mean's change points, the mismatch
    # section of benches/discovery.py). A tracker's knock moves the mean by its translation, where
    # the change points find it; proposed there too, such scans cut slow waves of a drift into steps.
    if directions is not None and jacobian is not None:
        whole = step_candidate(data, int(idx[order[1]]), True, directions).basis[idx][order][:, :3]
        model = np.asarray(jacobian.toarray() if is_sparse(jacobian) else jacobian)
        model = model.reshape(len(idx), -1, model.shape[1])[order][:, :3]
        places.add((best_place(whole, model, residuals[order][:, :3], min_size), True))
    return [step_candidate(data, int(idx[order[b]]), rigid, directions) for b, rigid in sorted(places)]


def best_place(basis: np.ndarray, model: np.ndarray, residuals: np.ndarray, min_size: int) -> int:
    """The split ``s`` (``min_size`` ≤ s ≤ m − ``min_size``) where the columns ``basis`` (m, k, n),
    zero before ``s``, fitted beside the ``model``'s (m, k, p) remove most of ``residuals`` (m, k):
    the scan statistic of a change in a regression, from suffix sums over an orthonormal basis of
    the model's columns (O(m·p·n²) for every split)."""
    m, n = len(residuals), basis.shape[2]
    flat_model = model.reshape(-1, model.shape[2])
    q, diagonal = np.linalg.qr(flat_model)
    q = q[:, np.abs(np.diag(diagonal)) > 1e-10 * max(float(np.abs(np.diag(diagonal)).max(initial=0.0)), 1e-300)]
    left = residuals.reshape(-1) - q @ (q.T @ residuals.reshape(-1))  # what the model leaves on these rows
    q = q.reshape(m, -1, q.shape[1])

    def suffix(terms: np.ndarray) -> np.ndarray:
        return np.cumsum(terms[::-1], axis=0)[::-1]

    split = np.arange(min_size, m - min_size + 1)
    normal = suffix(np.einsum("mki,mkj->mij", basis, basis))[split]
    cross = suffix(np.einsum("mkp,mkj->mpj", q, basis))[split]  # the step's columns along the model's
    moment = suffix(np.einsum("mki,mk->mi", basis, left.reshape(m, -1)))[split]
    schur = normal - np.einsum("spi,spj->sij", cross, cross)
    schur += (1e-9 * np.trace(normal, axis1=1, axis2=2) + 1e-300)[:, None, None] * np.eye(n)
    explained = np.einsum("si,si->s", moment, np.linalg.solve(schur, moment[..., None])[..., 0])
    return int(split[np.argmax(explained)])


def ramps(data: Dataset, step: Candidate) -> list[Candidate]:
    """The gradual alternatives to ``step``: the level changing linearly from its sample on, and
    linearly up to its sample (a drift that sets in, or ends; one arc of a wandering reading),
    each on the step's axes. Screened beside the step, never named: a step is a claim that the
    level jumped, which a ramp from the same sample must not explain as well."""
    position = acquisition_position(data)
    at = position[step.detail["sample"]]
    return [
        Candidate(
            "ramp", None, "observations", _level_change(step, shape / max(float(shape.max()), 1.0)), detail={"sample": step.detail["sample"], "side": side}
        )
        for side, shape in (("after", np.maximum(position - at, 0.0)), ("before", np.maximum(at - position, 0.0)))
    ]


def _level_change(step: Candidate, shape: np.ndarray) -> np.ndarray:
    """The basis (M, k, n) of the readings' level changing by ``shape`` (M,) on each axis ``step``
    shifts (not a rigid step's turns: an alternative to a step shifts the level)."""
    shifts = [a for a in step.detail["axes"] if a in SHIFT_AXES]
    basis = np.zeros(step.basis.shape[:2] + (len(shifts),))
    for a in range(len(shifts)):
        basis[:, a, a] = shape
    return basis


#: Widths (shares of the session's acquisition span) of the smooth level changes a step is set
#: against (:func:`transitions`): a slow wave of a drift crosses its mean over a fifth to a half of
#: a session.
TRANSITION_WIDTHS = (0.15, 0.4)


def transitions(data: Dataset, step: Candidate) -> list[Candidate]:
    """The smooth alternatives to ``step``: the level changing as ``tanh`` of the acquisition
    position through its sample, over :data:`TRANSITION_WIDTHS` of the session, on the step's
    axes. Screened beside the step, never named, never a reason to refuse it (a true step of 1-3
    times its detection limit is not told from them either, the matched section of
    benches/discovery.py): a step that does not beat them is named with them as what the data
    cannot tell it from — a level that changed smoothly (a drift), not at once."""
    position = acquisition_position(data)
    at = position[step.detail["sample"]]
    span = max(float(np.ptp(position)), 1.0)
    return [
        Candidate(
            "transition",
            None,
            "observations",
            _level_change(step, np.tanh((position - at) / (width * span))),
            detail={"sample": step.detail["sample"], "width": width},
        )
        for width in TRANSITION_WIDTHS
    ]
