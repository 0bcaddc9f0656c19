"""The order of measuring: a short tour through the poses (nearest neighbour, then 2-opt on the sum
of joint moves) is dealt into ``passes`` interleaved passes — pass ``b`` takes every ``passes``-th
pose of the tour, alternate passes run backwards — so each pass sweeps the whole workspace and a
sensor that drifts or wanders in time cannot pass for a joint cause: no joint sweeps slowly across
the session. The report gives the travel (sum of joint moves) and each joint's correlation with
the acquisition order."""

from __future__ import annotations

import math

import numpy as np

from ..physics import DEG
from ..robot import Robot


def travel(q: np.ndarray) -> float:
    """Sum of the joint moves from one pose to the next (rows of ``q``, in the order given)."""
    return float(np.abs(np.diff(q, axis=0)).sum())


def _tour(q: np.ndarray) -> np.ndarray:
    """A short open path through the rows of ``q`` (L1 distances): nearest neighbour from the
    pose nearest the middle of them, then 2-opt (reverse a segment while that shortens it)."""
    n = len(q)
    D = np.abs(q[:, None, :] - q[None, :, :]).sum(axis=2)
    start = int(np.argmin(np.abs(q - np.median(q, axis=0)).sum(axis=1)))
    tour, left = [start], np.ones(n, dtype=bool)
    left[start] = False
    for _ in range(n - 1):
        d = np.where(left, D[tour[-1]], np.inf)
        nxt = int(np.argmin(d))
        tour.append(nxt)
        left[nxt] = False
    tour = np.array(tour)
    improved = True
    while improved and n > 3:
        improved = False
        for i in range(n - 2):
            a, b = tour[i], tour[i + 1]
            c, d = tour[i + 2 :], np.append(tour[i + 3 :], -1)
            # Reversing tour[i+1..j] replaces edges (a,b), (c,d) with (a,c), (b,d); the last pose has no d.
            old = D[a, b] + np.where(d >= 0, D[c, d], 0.0)
            new = D[a, c] + np.where(d >= 0, D[b, d], 0.0)
            j = int(np.argmax(old - new))
            if old[j] - new[j] > 1e-9:
                tour[i + 1 : i + 3 + j] = tour[i + 1 : i + 3 + j][::-1]
                improved = True
    return tour


def default_passes(n: int) -> int:
    """Passes over the workspace for ``n`` poses: about √n / 2 (3 for 40 poses, 5 for 100),
    each of at least 4 poses."""
    return int(max(1, min(round(math.sqrt(n) / 2.0), n // 4)))


def measuring_order(q: np.ndarray, passes: int) -> np.ndarray:
    """The order to measure the rows of ``q`` in: a short tour (:func:`_tour`) dealt into
    ``passes`` passes, pass ``b`` taking every ``passes``-th pose of it from the ``b``-th, the odd
    passes backwards (each starts near where the last ended)."""
    tour = _tour(q)
    parts = [tour[b::passes] for b in range(passes)]
    return np.concatenate([p[::-1] if b % 2 else p for b, p in enumerate(parts)])


def order_correlations(q: np.ndarray) -> list[float]:
    """Each joint's correlation with the acquisition order (rows of ``q``); 0 for a joint that does not move."""
    t = np.arange(len(q), dtype=np.float64)
    out = []
    for j in range(q.shape[1]):
        s = np.std(q[:, j])
        out.append(float(np.corrcoef(t, q[:, j])[0, 1]) if s > 0 and len(q) > 1 else 0.0)
    return out


def _per_degree(robot: Robot) -> np.ndarray:
    """Per joint, the joint value of one degree (rad) — or of 1 mm for a prismatic joint: joint moves as the report states them."""
    return np.array([1.0 if j.kind == "prismatic" else DEG for j in robot.joints])
