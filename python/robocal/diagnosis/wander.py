"""A sensor that wanders in time: the evidence in the residuals.

A cable sensor's zero or a tracker's frame that moves slowly and irregularly leaves residuals
that are alike for samples taken one after another — whatever the joints did between them. A
cause of the robot leaves residuals that are alike for samples taken in similar configurations —
whenever they were taken. On a path that moves the joints little between samples the two look
the same; the test therefore compares two sets of pairs that tell them apart:

* pairs **near in time, apart in joints**: at most :data:`MAX_LAG` samples apart in acquisition
  order, their configurations farther apart than the typical distance to a sample's nearest
  neighbours in joint space;
* pairs **near in joints, apart in time**: each sample's :data:`NEIGHBOURS` nearest neighbours in
  joint space among the samples more than ``2·MAX_LAG`` apart in time.

The correlation of the residuals over each set is ``mean(e_i·e_j) / mean(|e|²)``. A robot cause
correlates the second set at least as much as the first (its pairs are nearer in the cause's own
variable); a wander correlates the first and not the second. The difference is judged by a z
score of the per-pair products (pairs overlap, so the score is approximate; the bound
:data:`Z_BOUND` is set high for that reason).

A wander found is fitted as a term of its session: :mod:`robocal.causes.wander`.
"""

from __future__ import annotations

import threading
from typing import Optional

import numpy as np
from scipy.spatial import cKDTree
from scipy.stats import f as f_dist
from scipy.stats import norm

from ..causes.candidates import acquisition_position
from ..data.dataset import Dataset
from .budget import REVISIT_TOLERANCE

#: Pairs up to this many samples apart in acquisition order are "near in time".
MAX_LAG = 20
#: Nearest neighbours in joint space per sample (among samples far apart in time).
NEIGHBOURS = 3
#: A correlation this many approximate standard errors beyond zero (or beyond the other set's)
#: counts; pairs overlap, so the standard errors are optimistic and the bound is high.
Z_BOUND = 5.0
#: Neighbours in time are alike when their correlation exceeds this many standard errors
#: (``1/sqrt(m)`` for independent residuals).
Z_LAG1 = 3.0
#: Smallest correlation worth naming (a fifth of the residual's variance shared by neighbours).
MIN_CORRELATION = 0.2


def acquisition_rank(data: Dataset, idx: np.ndarray) -> np.ndarray:
    """Rank of each of the samples ``idx`` in acquisition order (0 .. len(idx)-1)."""
    return np.argsort(np.argsort(acquisition_position(data)[idx], kind="stable"), kind="stable")


def sensor_part(data: Dataset, residuals: np.ndarray) -> np.ndarray:
    """The components of a residual (or a reading) that the sensor itself moves: the length, or
    the position."""
    return residuals[:, :1] if data.measurement == "cable" else residuals[:, :3]


def z_score(products: np.ndarray) -> float:
    """How many standard errors the mean of ``products`` (one per pair) lies from zero."""
    return float(np.mean(products) / max(np.std(products) / np.sqrt(len(products)), 1e-300)) if len(products) > 1 else 0.0


def correlation_length(e: np.ndarray) -> Optional[float]:
    """Lag (samples) at which the autocorrelation of the residuals ``e`` (m, k, in acquisition
    order) falls below 1/e of its value at lag 1 (white noise on top of a wander lowers every lag
    alike); None if neighbours in time are not significantly alike (lag-1 correlation below
    :data:`Z_LAG1` standard errors, Bonferroni over the axes). Each axis is tested on its own: a
    tracker's frame may wander along one axis, and pooled with two quiet ones its correlation
    falls to a third."""
    e = e - e.mean(axis=0)
    m = len(e)
    var = np.mean(e * e, axis=0)
    if m < 8 or not np.any(var > 0):
        return None

    def rho(lag: int) -> np.ndarray:
        return np.mean(e[lag:] * e[:-lag], axis=0) / np.where(var > 0, var, np.inf)

    first = rho(1)
    axis = int(np.argmax(first))
    if first[axis] * np.sqrt(m) < float(norm.isf(norm.sf(Z_LAG1) / e.shape[1])):
        return None
    longest = min(m // 4, 10 * MAX_LAG)
    return float(next((lag for lag in range(2, longest) if rho(lag)[axis] < first[axis] / np.e), longest))


#: The pairs of the last few sample sets tested (:func:`_pairs`): a diagnosis tests the same
#: samples' residuals once a round.
_PAIRS: dict = {}
_PAIRS_LOCK = threading.Lock()  # the sessions of a multi-session diagnosis are tested in threads


def _pairs(data: Dataset, idx: np.ndarray) -> Optional[tuple]:
    """The pairs :func:`residual_correlation` compares, which depend on the samples only: the
    samples' acquisition order; each sample's :data:`NEIGHBOURS` nearest neighbours in joint space
    more than ``2·MAX_LAG`` apart in time (positions in that order) and the typical distance to
    them; the pairs up to :data:`MAX_LAG` apart in time, their joint distances and which of them
    are farther apart than that; and which samples moved from the one before. None with too
    few neighbour pairs. Cached by data set and samples (the entry holds the data set, so its
    id is not reused)."""
    key = (id(data), idx.tobytes())
    with _PAIRS_LOCK:
        if key in _PAIRS:
            return _PAIRS[key][1]
    m = len(idx)
    order = np.argsort(acquisition_rank(data, idx))
    q = data.q[idx][order]
    far = 2 * MAX_LAG
    dist, near = cKDTree(q).query(q, min(m, NEIGHBOURS + 2 * far + 2))
    keep = np.abs(near - np.arange(m)[:, None]) > far
    keep &= np.cumsum(keep, axis=1) <= NEIGHBOURS  # each sample's nearest ones far enough apart in time
    ji, jj, jd = np.nonzero(keep)[0], near[keep], dist[keep]
    pairs = None
    if len(ji) >= 10:
        reach = float(np.median(jd))
        ti = np.concatenate([np.arange(m - lag) for lag in range(1, MAX_LAG + 1)])
        tj = np.concatenate([np.arange(lag, m) for lag in range(1, MAX_LAG + 1)])
        td = np.linalg.norm(q[ti] - q[tj], axis=1)
        moved = np.any(np.abs(q[1:] - q[:-1]) > REVISIT_TOLERANCE, axis=1)  # a row repeated in the file is no neighbour in time
        pairs = (order, ji, jj, reach, ti, tj, td, td > reach, moved)
    with _PAIRS_LOCK:
        if len(_PAIRS) >= 4:
            _PAIRS.pop(next(iter(_PAIRS)))
        _PAIRS[key] = (data, pairs)
    return pairs


def residual_correlation(data: Dataset, idx: np.ndarray, residuals: np.ndarray) -> Optional[dict]:
    """The test of the module notes on ``residuals`` (len(idx), k) of the samples ``idx``.

    Returns a report entry — the correlation of each set of pairs, their z scores and typical
    joint distances (deg), the correlation length in samples, and a ``verdict``: ``time`` (the
    sensor wanders), ``joints`` (a cause of the robot), ``both``, ``confounded`` (the path never
    puts samples near in time far apart in joints) or ``none`` — or None with too few samples.
    """
    m = len(idx)
    if m < 4 * MAX_LAG:
        return None
    pairs = _pairs(data, idx)
    if pairs is None:
        return None
    order, ji, jj, reach, ti, tj, td, apart, moved = pairs
    e = sensor_part(data, residuals)[order]
    var = float(np.mean(np.sum(e * e, axis=1)))
    if var <= 0:
        return None
    far = 2 * MAX_LAG
    lag1 = float(np.mean(np.sum(e[1:][moved] * e[:-1][moved], axis=1))) / var if moved.any() else 0.0
    entry = {
        "lag1": {"correlation": lag1, "z": lag1 * float(np.sqrt(max(int(moved.sum()), 1)))},
        "test": f"residual correlation of pairs <= {MAX_LAG} samples apart in acquisition order but farther apart in joints than the typical "
        f"nearest neighbour ({np.degrees(reach):.3g} deg), against each sample's {NEIGHBOURS} nearest neighbours in joint space more than {far} samples apart",
        "correlation_length_samples": correlation_length(e),
        "joint_distance_deg": {"time_pairs": float(np.degrees(np.median(td[apart]))) if apart.any() else None, "joint_pairs": float(np.degrees(reach))},
    }
    p_joint = np.sum(e[ji] * e[jj], axis=1) / var
    entry["joints"] = {"correlation": float(np.mean(p_joint)), "z": z_score(p_joint), "pairs": int(len(p_joint))}
    if apart.sum() < 10:
        entry["time"] = None
        entry["verdict"] = "confounded"
        return entry
    p_time = np.sum(e[ti[apart]] * e[tj[apart]], axis=1) / var
    entry["time"] = {"correlation": float(np.mean(p_time)), "z": z_score(p_time), "pairs": int(apart.sum())}
    difference = float(np.mean(p_time) - np.mean(p_joint))
    se = np.sqrt(np.var(p_time) / len(p_time) + np.var(p_joint) / len(p_joint))
    entry["difference_z"] = float(difference / max(se, 1e-300))
    in_time = entry["difference_z"] > Z_BOUND and entry["time"]["z"] > Z_BOUND and entry["time"]["correlation"] >= MIN_CORRELATION
    in_joints = entry["joints"]["z"] > Z_BOUND and entry["joints"]["correlation"] >= MIN_CORRELATION
    entry["verdict"] = "both" if in_time and in_joints else "time" if in_time else "joints" if in_joints else "none"
    return entry


#: The largest lag-1 correlation :func:`time_inflation` takes (beyond it the residuals are one
#: slow curve, and the inflation factor would exceed 39).
MAX_LAG1 = 0.95


def time_inflation(test: Optional[dict]) -> float:
    """How many consecutive residuals count as one independent piece of evidence when the
    :func:`residual_correlation` ``test`` says they are alike in time (verdict ``time`` or
    ``both``): the AR(1) variance inflation ``(1 + ρ₁)/(1 − ρ₁)`` of the lag-1 correlation
    (Bartlett's effective sample size); 1 otherwise. A least-squares test that counts every
    sample as independent finds a step, a drift or a harmonic in the bends of a wandering
    reading; divided by this it weighs them as what they are."""
    if not test or test.get("verdict") not in ("time", "both"):
        return 1.0
    rho = min(max(float(test["lag1"]["correlation"]), 0.0), MAX_LAG1)
    return (1.0 + rho) / (1.0 - rho)


def serial_inflation(data: Dataset, idx: np.ndarray, residuals: np.ndarray) -> float:
    """The AR(1) variance inflation ``(1 + ρ₁)/(1 − ρ₁)`` of the sensor's part of ``residuals``
    (the samples ``idx``, (len(idx), k)) for their lag-1 correlation in acquisition order, pooled
    over the axes, where it exceeds :data:`Z_LAG1` standard errors; 1 otherwise. A term of time
    (a step, a drift) is judged with the correlation of the residuals it leaves: noise correlated
    in time (a sensor's AR(1) noise) otherwise makes a step of its own wiggles, whatever the
    residual test says of time against joints."""
    e = sensor_part(data, residuals)[np.argsort(acquisition_rank(data, idx))]
    e = e - e.mean(axis=0)
    total = float(np.sum(e * e))
    if len(e) < 8 or total <= 0.0:
        return 1.0
    rho = float(np.sum(e[1:] * e[:-1])) / total
    if rho * np.sqrt(len(e)) < Z_LAG1:
        return 1.0
    rho = min(rho, MAX_LAG1)
    return (1.0 + rho) / (1.0 - rho)


#: Orthogonal polynomials of the session above the line the trend is judged against.
CHANCE_ORDERS = 3


def trend_beyond_chance(path: np.ndarray, trend: np.ndarray) -> tuple[float, float]:
    """Whether the linear ``trend`` (m, axes; in acquisition order) beside a wandering reading's
    ``path`` (same shape, fitted without its trend) is more than the wander's own trend. The
    sensor's whole time term ``path + trend`` is expanded in orthonormal polynomials of the
    acquisition order; a stationary wander puts about as much into the line as into the next
    :data:`CHANCE_ORDERS` (its spectrum is smooth at the lowest frequencies, whatever its
    shape), a drift puts more. Returns the largest F ratio over the axes (line against the mean
    of the next orders) and its p-value, Bonferroni over the axes (large: the wander's own
    trend). Long correlation times leave few independent pieces in a session: there the test
    errs toward naming the drift (simulated Gaussian and exponential wanders of 5-40 samples
    in 300: 5-13 % at p 0.05)."""
    m, axes = path.shape
    u = np.linspace(-1.0, 1.0, m)
    polys, _ = np.linalg.qr(np.vander(u, CHANCE_ORDERS + 2, increasing=True))
    a = polys.T @ (path + trend)  # (orders, axes)
    ratio = a[1] ** 2 / np.maximum(np.mean(a[2:] ** 2, axis=0), 1e-300)
    worst = int(np.argmax(ratio))
    return float(ratio[worst]), min(1.0, float(f_dist.sf(ratio[worst], 1, CHANCE_ORDERS)) * axes)
