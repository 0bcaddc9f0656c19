"""Acceptance figures of a calibrated model on measurements, after ISO 9283:1998.

ISO 9283 judges a robot on *targets*: poses commanded several times (cycles), each reached at an
*attained* pose the instrument measures. robocal's targets are joint configurations — the samples
:func:`~robocal.data.splits.configuration_groups` puts together within :data:`TARGET_TOLERANCE` are visits of one target — and its
*command* is the calibrated model's prediction at the target's joints (in the measurement frame):
the figures say how well the model predicts where the robot goes.

* **Position accuracy** AP of a target: the distance from the barycentre of its measured positions
  to the predicted one (mm); ``mean``, ``rms`` and ``max`` over the targets. Cable data measure a
  length, not a position: AP is then the length error ``|mean L − predicted L|``.
* **Orientation accuracy** (pose data): the angle of the mean rotation residual
  ``log(R_meas·R_predᵀ)`` of a target's visits (deg; the mean of rotation vectors, exact to second
  order in angles of a fraction of a degree). ISO states it per axis (a, b, c); one angle is given.
* **Distance accuracy** AD of two targets: ``| |P̄₁ − P̄₂| − |C₁ − C₂| |``, measured against
  predicted distance between their barycentres. A rigid change of the measurement frame leaves it
  unchanged, so it does not depend on how the tracker was registered to the robot. All pairs up to
  :data:`MAX_PAIRS`; beyond, :data:`MAX_PAIRS` pairs drawn uniformly with a fixed seed (0), so the
  figure is deterministic. Not available from cable lengths (one length per sample, not a point).
* **Repeatability** RP = l̄ + 3·S_l, ``l`` the distance of each visit to its target's barycentre
  (for cable data, of each length to the mean length), ``S_l`` its sample standard deviation;
  pooled over the targets visited more than once, and per target. ISO asks 30 cycles of 5 poses;
  with two visits a target's own S_l is 0 by construction (both lie at the same distance from their
  barycentre), so the pooled figure is the one to quote. Absent without revisits.
"""

from __future__ import annotations

import logging
from typing import Optional

import numpy as np
from scipy.spatial.distance import pdist

from .data.splits import configuration_groups

logger = logging.getLogger(__name__)

#: Joint readings of one target (rad, 0.003°): the cycles of one commanded pose read alike to the
#: encoders' resolution and the file's rounding (D1: 0.001°, revisits one step apart), far below
#: the splits' 1e-3 rad, over which a 1.5 m arm's tool moves 1.5 mm — joined as one target, those
#: moves were counted as repeatability (D1: RP 0.77 mm at 1e-3 rad, 0.11 mm at this).
TARGET_TOLERANCE = 5e-5

#: Pairs of targets beyond which distance accuracy is estimated on this many random pairs: all
#: pairs of 1414 targets; 8 MB per distance vector.
MAX_PAIRS = 1_000_000

STANDARD = "ISO 9283:1998 figures; command = the calibrated model's prediction at a target's joints, attained = the measurement"


def _summary(values: np.ndarray) -> dict:
    return {"mean": float(np.mean(values)), "rms": float(np.sqrt(np.mean(values**2))), "max": float(np.max(values)), "n": int(values.size)}


def _group_means(labels: np.ndarray, values: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Per target, the mean of the rows of ``values`` (m, c) of its visits: (g, c)."""
    return np.column_stack([np.bincount(labels, weights=values[:, c], minlength=len(counts)) for c in range(values.shape[1])]) / counts[:, None]


def _pairs(g: int) -> tuple[Optional[np.ndarray], Optional[np.ndarray]]:
    """Index pairs of the targets whose distances are compared: None (all pairs, ``pdist``
    order) when there are at most :data:`MAX_PAIRS`, else that many drawn with seed 0."""
    if g * (g - 1) // 2 <= MAX_PAIRS:
        return None, None
    rng = np.random.default_rng(0)
    i = rng.integers(0, g, MAX_PAIRS)
    k = rng.integers(0, g - 1, MAX_PAIRS)
    return i, k + (k >= i)  # never a target with itself


def _distance_accuracy(measured: np.ndarray, predicted: np.ndarray) -> dict:
    g = len(measured)
    i, k = _pairs(g)
    if i is None:
        error = np.abs(pdist(measured) - pdist(predicted))
    else:
        error = np.abs(np.linalg.norm(measured[i] - measured[k], axis=1) - np.linalg.norm(predicted[i] - predicted[k], axis=1))
    return {**_summary(error), "of_pairs": g * (g - 1) // 2, "sampled": i is not None}


def _repeatability(labels: np.ndarray, points: np.ndarray, barycentres: np.ndarray, counts: np.ndarray) -> tuple[Optional[dict], list]:
    """Pooled RP (None without revisits) and per target (None for one visit)."""
    l = np.linalg.norm(points - barycentres[labels], axis=1)  # ISO 9283 names it l
    repeated = counts[labels] > 1
    per_target: list = [None] * len(counts)
    if not repeated.any():
        return None, per_target
    g = len(counts)
    mean = np.bincount(labels, weights=l, minlength=g) / counts
    square = np.bincount(labels, weights=l**2, minlength=g)
    many = counts > 1
    std = np.sqrt(np.maximum(square[many] - counts[many] * mean[many] ** 2, 0.0) / (counts[many] - 1))
    for t, rp in zip(np.flatnonzero(many), mean[many] + 3.0 * std):
        per_target[t] = float(rp)
    pooled = l[repeated]
    s_l = float(np.std(pooled, ddof=1)) if pooled.size > 1 else 0.0
    visits = counts[many]
    summary = {
        "rp": float(np.mean(pooled) + 3.0 * s_l),
        "l_mean": float(np.mean(pooled)),
        "s_l": s_l,
        "n_targets": int(many.sum()),
        "n_measurements": int(pooled.size),
        "visits": [int(visits.min()), int(visits.max())],
    }
    return summary, per_target


def iso9283(
    residuals: np.ndarray,
    y: np.ndarray,
    q: np.ndarray,
    measurement: str,
    *,
    covered: Optional[np.ndarray] = None,
    rows: Optional[np.ndarray] = None,
) -> dict:
    """The acceptance figures (see the module notes) of a model's ``residuals`` on measurements.

    Parameters
    ----------
    residuals : ndarray, shape (m, k)
        ``y − h`` of the model (k = 1 cable, 3 position, 6 pose: position then rotation vector, rad).
    y : ndarray, shape (m, 1 or ≥ 3)
        The measurements (mm): cable lengths or positions first.
    q : ndarray, shape (m, N)
        The joint readings: samples whose readings agree are visits of one target.
    measurement : {"cable", "position", "pose"}
    covered : ndarray of bool, shape (m,), optional
        Samples the model's joint maps cover (a target is covered when all its visits are).
    rows : ndarray of int, shape (m,), optional
        File rows of the samples (default 0-based sample indices): a target is named by its first.

    Returns
    -------
    dict
        ``standard``, ``measurement``, ``n_targets``, ``n_measurements``, ``position_accuracy_mm`` (``mean, rms,
        max, n``; of the length for cable data), ``orientation_accuracy_deg`` (pose data),
        ``distance_accuracy_mm`` (``n`` pairs of ``of_pairs``, ``sampled``),
        ``repeatability_mm`` (``rp, l_mean, s_l, n_targets, n_measurements, visits``), each None
        when absent, with the reason in ``absent``; ``targets`` (per target, lists: ``row``,
        ``visits``, ``position_error_mm``, ``orientation_error_deg``, ``repeatability_mm``,
        ``covered``).
    """
    m = len(residuals)
    r = np.asarray(residuals, dtype=np.float64).reshape(m, -1)
    labels = configuration_groups(q, TARGET_TOLERANCE)
    counts = np.bincount(labels)
    g = len(counts)
    rows = np.arange(m) if rows is None else np.asarray(rows)
    first = np.full(g, m)
    np.minimum.at(first, labels, np.arange(m))
    points = np.asarray(y, dtype=np.float64)[:, : 1 if measurement == "cable" else 3]
    width = points.shape[1]
    mean_residual = _group_means(labels, r, counts)
    barycentres = _group_means(labels, points, counts)
    position = np.linalg.norm(mean_residual[:, :width], axis=1)
    absent = {}
    orientation = None
    if measurement == "pose":
        orientation = np.degrees(np.linalg.norm(mean_residual[:, 3:6], axis=1))
    else:
        absent["orientation_accuracy_deg"] = f"{measurement} data measure no orientation"
    if measurement == "cable":
        distance = None
        absent["distance_accuracy_mm"] = "a cable sensor measures one length to its anchor per sample, not a point: no distance between two targets is measured"
    elif g < 2:
        distance = None
        absent["distance_accuracy_mm"] = "one target: no pair to measure a distance between"
    else:
        distance = _distance_accuracy(barycentres, barycentres - mean_residual[:, :width])
    repeatability, per_target_rp = _repeatability(labels, points, barycentres, counts)
    if repeatability is None:
        absent["repeatability_mm"] = "no target was measured more than once (no two samples share a joint configuration)"
    covered_targets = np.ones(g, dtype=bool) if covered is None else np.bincount(labels, weights=~np.asarray(covered, dtype=bool), minlength=g) == 0
    return {
        "standard": STANDARD,
        "measurement": measurement,
        "n_targets": int(g),
        "n_measurements": int(m),
        "position_accuracy_mm": _summary(position),
        "orientation_accuracy_deg": None if orientation is None else _summary(orientation),
        "distance_accuracy_mm": distance,
        "repeatability_mm": repeatability,
        "absent": absent,
        "targets": {
            "row": [int(v) for v in rows[first]],
            "visits": [int(v) for v in counts],
            "position_error_mm": [float(v) for v in position],
            "orientation_error_deg": None if orientation is None else [float(v) for v in orientation],
            "repeatability_mm": per_target_rp,
            "covered": [bool(v) for v in covered_targets],
        },
    }


def summary_rows(figures: dict) -> list[tuple[str, str]]:
    """``(figure, value)`` lines of :func:`iso9283` ``figures`` as a table shows them: every
    figure, an absent one with its reason."""

    def spread(s: dict, unit: str) -> str:
        return f"mean {s['mean']:.4f}  RMS {s['rms']:.4f}  max {s['max']:.4f} {unit}"

    absent = figures.get("absent", {})
    rows = []
    for key, name in (
        ("position_accuracy_mm", "position accuracy AP"),
        ("orientation_accuracy_deg", "orientation accuracy AP"),
        ("distance_accuracy_mm", "distance accuracy AD"),
        ("repeatability_mm", "repeatability RP"),
    ):
        s = figures.get(key)
        if s is None:
            rows.append((name, f"absent: {absent.get(key, 'not computed')}"))
        elif key == "position_accuracy_mm":
            rows.append(("length accuracy AP (cable)" if figures["measurement"] == "cable" else name, spread(s, "mm") + f" over {s['n']} targets"))
        elif key == "orientation_accuracy_deg":
            rows.append((name, spread(s, "deg")))
        elif key == "distance_accuracy_mm":
            drawn = f" ({s['n']} of {s['of_pairs']} drawn, seed 0)" if s["sampled"] else ""
            rows.append((name, spread(s, "mm") + f" over {s['n']} pairs of targets{drawn}"))
        else:
            visits = f"{s['visits'][0]}" if s["visits"][0] == s["visits"][1] else f"{s['visits'][0]}-{s['visits'][1]}"
            rows.append((name, f"{s['rp']:.4f} mm = l̄ {s['l_mean']:.4f} + 3·S_l {s['s_l']:.4f}; {s['n_targets']} targets measured {visits} times"))
    return rows
