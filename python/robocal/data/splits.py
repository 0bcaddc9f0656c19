"""Train / test splits of a dataset's samples, as index arrays.

Every function takes the number of samples ``m`` and returns positions ``0..m-1`` (use
:meth:`Dataset.subset <robocal.data.Dataset.subset>` to cut the dataset). Random splits are
deterministic per ``seed`` (:func:`numpy.random.default_rng`); indices come back sorted.

A held-out figure is honest only if the fit saw none of the held-out configurations: samples
of one joint configuration (a repeated row, a revisit) carry the same geometric information,
so every split takes ``groups`` (:func:`configuration_groups`) and keeps each group on one side.
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from ..kernels import as_count, seeded_rng
from ..kernels import configuration_groups as configuration_labels
from ..exceptions import InvalidParameterError

#: Joint readings within this of each other on every joint (rad, 0.06°; mm for a prismatic
#: joint) are one configuration: far below the scale on which any modelled error varies, so a
#: second visit adds noise averaging, not geometry.
CONFIGURATION_TOLERANCE = 1e-3


def configuration_groups(q, tol: float = CONFIGURATION_TOLERANCE) -> np.ndarray:
    """One label per sample: samples of one label agree within ``tol`` on every joint, each pair
    of them — whatever the path between them.

    Chaining (a within tol of b, b of c) made a sweep in steps just under ``tol`` one
    "configuration" however far it went (issue 52: 1500 samples over 28–61° per joint were one;
    the HSR D1 file's ISO repeatability mixed targets metres apart). So the chained components
    (:func:`robocal.kernels.configuration_groups`, a sort-and-sweep in the core) are kept only
    where they span at most ``tol`` on every joint — revisits, repeated rows, the common case —
    and a wider one is cut into groups around representatives (:func:`_within`).

    Parameters
    ----------
    q : array_like, shape (m, N)
        Joint values (rad; mm for prismatic joints).
    tol : float
        Largest difference on any joint (Chebyshev distance) of two visits of one configuration.

    Returns
    -------
    ndarray of int, shape (m,)
        Labels ``0..g-1`` numbered in order of first appearance: for distinct configurations,
        ``arange(m)`` (so a grouped split equals the ungrouped one).
    """
    q = np.asarray(q, dtype=np.float64)
    if q.ndim != 2 or not np.all(np.isfinite(q)):
        raise InvalidParameterError(f"`q` must be finite joint values of shape (m, N); got shape {q.shape}")
    if not (np.isfinite(tol) and tol >= 0):
        raise InvalidParameterError(f"`tol` must be finite and >= 0; got {tol!r}")
    q = np.ascontiguousarray(q)
    chained = configuration_labels(q, float(tol))
    if len(q) == 0:
        return chained
    labels = chained.copy()
    # Only components of two or more samples can span more than tol: splitting every one of
    # 20 000 distinct samples into its own array took 60 ms of calibrate's 110 (issue 53).
    shared = np.isin(chained, np.flatnonzero(np.bincount(chained) > 1))
    order = np.flatnonzero(shared)[np.argsort(chained[shared], kind="stable")]
    for members in np.split(order, np.flatnonzero(np.diff(chained[order])) + 1) if order.size else ():
        if np.any(np.ptp(q[members], axis=0) > tol):
            labels[members] = len(q) + members[_within(q[members], tol)]  # unused labels: renumbered below
    return _labels(len(q), labels)[0]


def _within(q: np.ndarray, tol: float) -> np.ndarray:
    """For each sample of ``q`` (k, N), a sample of its group: groups whose joint ranges stay
    within ``tol`` on every joint (so every two of their samples do: the Chebyshev diameter is the
    widest range). A sweep along the joint of widest range, as the core's: each sample joins the
    first group it keeps within ``tol``, else starts one; a group that began more than ``tol``
    before the sample along the sweep can take no later sample, so only the last ``tol`` of
    groups are tried (1500 samples of a path: 0.04 s; 20 000: 0.6 s)."""
    axis = int(np.argmax(np.ptp(q, axis=0)))
    lo, hi, first = np.empty_like(q), np.empty_like(q), np.empty(len(q), dtype=np.int64)
    out, groups, start = np.empty(len(q), dtype=np.int64), 0, 0
    for i in np.argsort(q[:, axis], kind="stable"):
        x = q[i]
        while start < groups and lo[start, axis] < x[axis] - tol:
            start += 1
        fits = np.flatnonzero(np.all(np.maximum(hi[start:groups], x) - np.minimum(lo[start:groups], x) <= tol, axis=1))
        g = start + int(fits[0]) if fits.size else groups
        if g == groups:
            lo[g], hi[g], first[g], groups = x, x, i, groups + 1
        else:
            lo[g], hi[g] = np.minimum(lo[g], x), np.maximum(hi[g], x)
        out[i] = first[g]
    return out


def residual_rows(samples: np.ndarray, k: int) -> np.ndarray:
    """The rows of a residual vector that hold ``samples`` (positions), ``k`` consecutive rows a
    sample (a cable's 1, a position's 3, a pose's 6)."""
    return (np.asarray(samples)[:, None] * k + np.arange(k)).ravel()


def _labels(m: int, groups) -> tuple[np.ndarray, int]:
    """Dense group labels (first appearance order) of ``m`` samples and their count."""
    if groups is None:
        return np.arange(m), m
    groups = np.asarray(groups)
    if groups.shape != (m,):
        raise InvalidParameterError(f"`groups` must hold one label per sample, shape ({m},); got shape {groups.shape}")
    if groups.dtype.kind in "iu" and m and groups[0] == 0:
        # Labels that are already 0..g-1 in order of first appearance (configuration_groups'
        # own): each new label is the largest so far plus one. Kept as they are, without a sort.
        largest = np.maximum.accumulate(groups)
        if groups.min() >= 0 and np.all(np.diff(largest) <= 1):
            return groups.astype(np.int64), int(largest[-1]) + 1
    _, first, inverse = np.unique(groups, return_index=True, return_inverse=True)
    rank = np.empty(len(first), dtype=np.int64)
    rank[np.argsort(first)] = np.arange(len(first))
    return rank[inverse.ravel()], len(first)


def _members(labels: np.ndarray, chosen) -> np.ndarray:
    """Sorted positions of the samples whose group (dense labels, :func:`_labels`) is among ``chosen``."""
    picked = np.zeros(int(labels.max(initial=-1)) + 1, dtype=bool)
    picked[np.asarray(chosen, dtype=np.int64)] = True
    return np.flatnonzero(picked[labels])


def _check_m(m: int, least: int, split: str, groups: int) -> int:
    """``m`` if the samples form at least ``least`` groups, else an error saying what ``split``
    needs (the user sees a sample count, not an argument name)."""
    if groups < least:
        distinct = f" ({groups} distinct joint configurations)" if groups < m else ""
        raise InvalidParameterError(f"{split} needs at least {least} samples; the data have {m}{distinct}")
    return m


def _test_count(m: int, test_fraction: float) -> int:
    if not 0 < test_fraction < 1:
        raise InvalidParameterError(f"`test_fraction` must be in (0, 1); got {test_fraction!r}")
    return min(max(1, round(m * test_fraction)), m - 1)


def paper_split(m: int, seed: int = 0, n_train: int = 100, n_test: int = 20, *, groups=None) -> tuple[np.ndarray, np.ndarray]:
    """The paper's protocol: a random subset of ``n_train + n_test`` (120) samples, split into
    ``n_train`` (100) for calibration and ``n_test`` (20) for validation.

    With ``groups`` (:func:`configuration_groups`), the counts are of groups and every sample
    of a chosen group goes with it.

    Returns
    -------
    train, test : ndarray of int
        Disjoint, sorted.
    """
    m = as_count(m, "m", 0)
    labels, g = _labels(m, groups)
    _check_m(m, n_train + n_test, f"the paper's split ({n_train} training + {n_test} test samples)", g)
    if n_train < 1 or n_test < 1:
        raise InvalidParameterError(f"`n_train` and `n_test` must be >= 1; got {n_train}, {n_test}")
    pick = seeded_rng(seed).choice(g, size=n_train + n_test, replace=False)
    return _members(labels, pick[:n_train]), _members(labels, pick[n_train:])


def random_split(m: int, test_fraction: float = 0.2, seed: int = 0, *, groups=None) -> tuple[np.ndarray, np.ndarray]:
    """A random ``1 - test_fraction`` / ``test_fraction`` split of all samples (each side >= 1);
    with ``groups``, of the groups (each group whole on one side)."""
    m = as_count(m, "m", 0)
    labels, g = _labels(m, groups)
    _check_m(m, 2, "a random training / held-out split", g)
    order = seeded_rng(seed).permutation(g)
    n_test = _test_count(g, test_fraction)
    return _members(labels, order[n_test:]), _members(labels, order[:n_test])


def kfold(m: int, k: int = 5, seed: int = 0, *, groups=None) -> list[tuple[np.ndarray, np.ndarray]]:
    """``k`` folds of a random permutation: each sample is in exactly one test set; with
    ``groups``, folds of the groups (each group whole in one fold).

    Returns
    -------
    list of (train, test)
        Fold sizes (in groups) differ by at most one.
    """
    m = as_count(m, "m", 0)
    labels, g = _labels(m, groups)
    _check_m(m, 2, "k-fold cross-validation", g)
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 2 <= k <= g:
        what = f"m={m}" if g == m else f"the {g} distinct configurations"
        raise InvalidParameterError(f"`k` must be an integer in [2, {what}]; got {k!r}")
    folds = np.array_split(seeded_rng(seed).permutation(g), k)
    return [(_members(labels, np.concatenate(folds[:i] + folds[i + 1 :])), _members(labels, test)) for i, test in enumerate(folds)]


def chronological(m: int, test_fraction: float = 0.2, t: Optional[np.ndarray] = None, *, groups=None) -> tuple[np.ndarray, np.ndarray]:
    """Train on the earlier samples, test on the later ones (drift, temperature, wear).

    Parameters
    ----------
    m : int
    test_fraction : float
    t : array_like, shape (m,), optional
        Acquisition times; row order is the acquisition order without them.
    groups : array_like of int, shape (m,), optional
        A group is held out when its first visit is (a later revisit of a training
        configuration trains).
    """
    m = as_count(m, "m", 0)
    labels, g = _labels(m, groups)
    _check_m(m, 2, "a chronological split", g)
    order = np.arange(m)
    if t is not None:
        t = np.asarray(t, dtype=np.float64)
        if t.shape != (m,) or not np.all(np.isfinite(t)):
            raise InvalidParameterError(f"`t` must be {m} finite times; got shape {t.shape}")
        order = np.argsort(t, kind="stable")
    _, first = np.unique(labels[order], return_index=True)
    group_order = labels[order][np.sort(first)]  # groups by their first visit in time
    n_test = _test_count(g, test_fraction)
    return _members(labels, group_order[: g - n_test]), _members(labels, group_order[g - n_test :])
