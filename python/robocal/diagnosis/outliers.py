"""Gross outliers: samples a slipped cable or a broken beam put many sigmas off.

Named before any cause is in, beyond the Bonferroni bound of a robust (MAD) noise scale and
beyond :data:`GROSS_SIGMAS` (:func:`gross_outliers`, re-decided after refitting without them
until the set is stable); runs of them in acquisition order are an event in time, left to the
step and wander candidates. Under the final model they are re-decided, and samples that model
alone puts beyond the bound — hidden by the geometric baseline's large residuals — are revealed
(:func:`name_outliers`, :func:`isolated`).
"""

from __future__ import annotations

from typing import Optional

import numpy as np
from scipy.spatial import cKDTree
from scipy.special import gammaln
from scipy.stats import chi2, ks_2samp

from ..calibration.problem import Problem
from ..causes.candidates import acquisition_order
from ..causes.problem import ExtendedProblem, reported_rmse
from ..data.dataset import Dataset
from ..data.splits import configuration_groups, kfold
from ..robot import RESIDUAL_WIDTH
from ..stats import robust_sigma
from .settling import after_long_moves, preceding_moves
from .state import Pass
from .validation import cross_validate, fit_problem, same_folds


#: Gross errors lie beyond at least this many robust sigmas: a slipped cable or a broken beam
#: is off by many sigmas, while a cause the geometric model misses bends many residuals a little.
GROSS_SIGMAS = 8.0


def gross_outliers(base: Problem, data: Dataset, known: np.ndarray, level: float = 0.01) -> tuple[np.ndarray, float, np.ndarray]:
    """Samples beyond the Bonferroni bound (family-wise ``level``) of a robust noise scale, and
    beyond :data:`GROSS_SIGMAS`, with the ``known`` outliers always among them; and the last
    fit without them (each refit starts from the previous one)."""
    m = len(data)
    k = RESIDUAL_WIDTH[data.measurement]
    bound = max(float(chi2.ppf(1.0 - level / m, k)), GROSS_SIGMAS**2)
    always = np.isin(np.arange(m), known)
    flagged, x = always.copy(), None
    for _ in range(5):
        ext = ExtendedProblem(base, [], data, np.flatnonzero(~flagged))
        fit = fit_problem(ext, x0=x)
        x = fit.x
        r = ExtendedProblem(base, [], data, np.arange(m)).residuals(fit.x).reshape(m, k)
        sigma = robust_sigma(r[~flagged])
        now = isolated_in_time((np.sum((r / sigma) ** 2, axis=1) > bound), acquisition_order(data)) | always
        if np.array_equal(now, flagged):
            break
        flagged = now
    return np.flatnonzero(flagged), float(np.sqrt(bound)), x


#: Samples beyond the bound this many in a row in acquisition order are an event in time (a step
#: the geometry half absorbed, a sensor that jumped), not independent gross errors: the step and
#: wander candidates judge them.
RUN = 3


def isolated_in_time(beyond: np.ndarray, order: np.ndarray) -> np.ndarray:
    """``beyond`` (m,) without the samples that lie in runs of :data:`RUN` or more consecutive
    flagged samples in acquisition ``order``."""
    flagged = beyond[order].astype(np.int64)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], flagged, [0]])))
    starts, ends = edges[::2], edges[1::2]
    in_run = np.zeros(len(order), dtype=bool)
    for a, b in zip(starts, ends):
        if b - a >= RUN:
            in_run[a:b] = True
    out = beyond.copy()
    out[order[in_run]] = False
    return out


#: A revealed outlier's residual is compared with those of this many samples nearest to it in
#: joint space.
NEIGHBOURS = 5


def isolated(q: np.ndarray, z: np.ndarray, suspects: np.ndarray, keep: np.ndarray, z_bound: float) -> np.ndarray:
    """The ``suspects`` (kept samples beyond the bound) whose scaled residual ``z`` also lies
    beyond ``z_bound`` from the median residual of their :data:`NEIGHBOURS` nearest kept samples
    in joint space ``q``. Large residuals that a region of the workspace shares are error the
    model still makes there, not gross errors."""
    if len(suspects) == 0 or len(keep) <= NEIGHBOURS:
        return suspects[:0]
    _, near = cKDTree(q[keep]).query(q[suspects], NEIGHBOURS + 1)
    near = keep[near]
    others = np.array([row[row != s][:NEIGHBOURS] for row, s in zip(near, suspects)])
    contrast = np.sqrt(np.sum((z[suspects] - np.median(z[others], axis=1)) ** 2, axis=1))
    return suspects[contrast > z_bound]


def name_outliers(
    state: Pass, z: np.ndarray, revealed: np.ndarray, *, folds: int, seed: int, geometric_cv: Optional[tuple] = None
) -> tuple[np.ndarray, np.ndarray, Optional[str]]:
    """The baseline's outliers re-decided with the final model (``z``: every sample's residual in
    robust sigmas, :func:`~.entries.final_residuals`), and their report entry put first among the
    effects (``revealed``: those an earlier pass's final model named). The geometric model's
    held-out error with them is ``geometric_cv``'s (:func:`~.conventions.reading_conventions`'s)
    where its folds are the same. Returns the outliers, the kept samples the final model puts
    beyond the bound on their own (:func:`isolated`) — none where they gather at some value of the
    robot's state (:func:`gathered_in_state`) — and that finding in words, or None."""
    dataset, keep, outliers, z_bound = state.dataset, state.keep, state.baseline.outliers, state.baseline.bound
    beyond = np.sqrt(np.sum(z**2, axis=1)) > z_bound
    if len(outliers) and state.model.causes:
        # Re-decided with the extended model: a sample flagged only because an unmodelled cause
        # bent the residuals is not an outlier.
        outliers = outliers[beyond[outliers]]
    if len(outliers):
        random = kfold(len(dataset), folds, seed, groups=configuration_groups(dataset.q))
        if geometric_cv is not None and same_folds(geometric_cv[0]["random"], random):
            before = geometric_cv[1]["random"]
        else:
            everyone = ExtendedProblem(state.base, [], dataset, np.arange(len(dataset)))
            before = cross_validate(everyone, {"random": random})[0]["random"]
        outliers_entry = {
            "kind": "outliers",
            "joint": None,
            "label": "outliers",
            "params": {
                "rows": [int(v) for v in dataset.rows[outliers]],
                "samples": [int(v) for v in outliers],
                "threshold_sigma": z_bound,
                # rows beyond the bound only under the final model (hidden by the baseline's residuals)
                "revealed_by_causes": [int(v) for v in dataset.rows[np.intersect1d(outliers, revealed)]],
            },
            "rmse_heldout_before": reported_rmse(before),
            "rmse_heldout_after": reported_rmse(state.baseline.cv["random"]),
            "significance": {"test": f"residual beyond max(Bonferroni bound at family-wise 0.01, {GROSS_SIGMAS:g}) MAD sigmas", "bound_sigma": z_bound},
            "after_long_moves": after_long_moves(dataset, outliers),  # readings taken before the arm settled?
        }
        state.effects.insert(0, outliers_entry)
    suspects = np.setdiff1d(keep[beyond[keep]], map_ends(state.model.causes, dataset.q, keep))
    revealed_now = isolated(dataset.q, z, suspects, keep, z_bound)
    gathered = gathered_in_state(dataset, revealed_now, keep)
    if gathered is not None:  # structure the model still misses: not gross errors, and kept in the fit
        return outliers, revealed_now[:0], gathered
    return outliers, revealed_now, None


#: Samples beyond the bound under the final model that gather at some value of the robot's state
#: are no independent gross errors, when there are at least this many to tell (three within a
#: degree of one joint angle among 300 samples: narrow-window p 3e-4; a sawtooth's jump).
GATHERED_MIN = 3
#: Family-wise level of the test that they gather (Bonferroni over the joints' angles and moves).
GATHERED_LEVEL = 0.01


def gathered_in_state(dataset: Dataset, suspects: np.ndarray, keep: np.ndarray) -> Optional[str]:
    """Why the ``suspects`` (kept samples the final model puts beyond the bound) are error the
    model still makes rather than gross readings: a slipped cable or a broken beam strikes
    whatever the robot does, so gross errors are a random draw of the samples, while a shape the
    model misses strikes at some angle or some move of a joint — lost motion whose transition is
    not a switch errs at the small moves of its joint (the mismatch section named 4-14 such
    samples outliers); suspects that follow long moves beyond chance are unsettled readings
    (:func:`~.settling.after_long_moves`), not structure. Two-sample Kolmogorov-Smirnov tests of each joint's angle and of the size
    of its move from the sample before (acquisition order), the suspects against the other kept
    samples, and of each joint's angle the test that they fall in a narrow window of it
    (:func:`narrow_window_p`), Bonferroni over them all at :data:`GATHERED_LEVEL`; None with fewer than
    :data:`GATHERED_MIN` suspects or where none separates them."""
    if len(suspects) < GATHERED_MIN:
        return None
    settling = after_long_moves(dataset, suspects)
    if settling is not None and settling["settling"]:
        # readings taken before the arm settled (:mod:`.settling`): gross readings of the
        # acquisition wherever its path puts them, and named (UR10 series A's gather at joint 3's
        # angle along its grid; kept in, its held-out error rose from 0.077 to 0.081 mm)
        return None
    moves = preceding_moves(dataset)
    others = np.setdiff1d(keep, suspects)
    tests = [(f"joint {j + 1}'s {what}", values) for j in range(dataset.q.shape[1]) for what, values in (("angle", dataset.q[:, j]), ("move", moves[:, j]))]
    tests = [(name, values) for name, values in tests if np.ptp(values[keep]) > 0]
    if not tests:
        return None
    found = [(ks_2samp(values[suspects], values[others]).pvalue, name, "Kolmogorov-Smirnov") for name, values in tests]
    found += [(narrow_window_p(values[suspects], values[keep]), name, "narrow-window") for name, values in tests if name.endswith("angle")]
    p, name, test = min(found)
    if p * len(found) >= GATHERED_LEVEL:
        return None
    return (
        f"{len(suspects)} samples beyond the outlier bound under the final model gather at {name} ({test} p {p:.2g} "
        f"over {len(found)} tests): error the model still makes there, not gross readings — kept in the fit, not named outliers"
    )


def narrow_window_p(chosen: np.ndarray, values: np.ndarray) -> float:
    """How likely at least k of ``chosen`` (s of the ``values``, drawn at random) fall within a
    window of the values as narrow as the narrowest that holds k of them, for the k from
    :data:`GATHERED_MIN` to s that makes it least likely (Bonferroni over them): a window of
    ``n`` of the m values holds k given draws with probability C(n, k) / C(m, k), any k of s in
    C(s, k) ways, and there are m − n + 1 such windows (a union bound). A shape the model misses at
    one angle (a sawtooth's jump, narrower than a joint map's knots) strikes samples within a
    degree or two of it, where a test of the whole distribution (Kolmogorov-Smirnov) sees little:
    six such samples of 300, p 3e-10 against 0.003; nine of ten, the tenth elsewhere."""
    s, m = len(chosen), len(values)
    chosen, values = np.sort(chosen), np.sort(values)
    best = 1.0
    for k in range(min(GATHERED_MIN, s), s + 1):
        # the fewest values any window holding k of the chosen holds
        n = int(np.min(np.searchsorted(values, chosen[k - 1 :], side="right") - np.searchsorted(values, chosen[: s - k + 1], side="left")))
        log_p = np.log(m - n + 1) + log_binomial(s, k) + log_binomial(n, k) - log_binomial(m, k)
        best = min(best, float(np.exp(log_p)))
    return min(1.0, best * (s - min(GATHERED_MIN, s) + 1))


def log_binomial(n: int, k: int) -> float:
    return float(gammaln(n + 1) - gammaln(k + 1) - gammaln(n - k + 1))


def map_ends(causes: list, q: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """The kept samples alone at an end of the range of a joint a joint map of ``causes``
    corrects: the lowest (or highest) angle, where a gap of more than :data:`LONELY` mean sample
    spacings of that joint separates it from the next. The map's roughness prior alone sets the
    map there, so a large residual there is the map's (a harmonic bending within the lonely end
    stretch), not a gross reading: on simulated joint-6 harmonics of 5 and 6 turns such an end
    sample was revealed as an outlier. (Where the ends are as dense as the rest — the UR10
    series — a revealed outlier there keeps its name.)"""
    ends = []
    for c in causes:
        if c.kind != "joint_map" or len(keep) < 3:
            continue
        order = keep[np.argsort(q[keep, c.joint])]
        angles = q[order, c.joint]
        lonely = LONELY * (angles[-1] - angles[0]) / (len(angles) - 1)
        ends += [order[i] for i, gap in ((0, angles[1] - angles[0]), (-1, angles[-1] - angles[-2])) if gap > lonely]
    return np.unique(np.array(ends, dtype=keep.dtype))


#: A map's end sample is alone when a gap of more than this many mean sample spacings of its
#: joint separates it from the next (simulated files where it was revealed: 21 and 36).
LONELY = 10.0
