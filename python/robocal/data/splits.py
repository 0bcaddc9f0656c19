"""Train / test splits of a dataset's samples, as index arrays.

Every function takes the number of samples ``m`` and returns positions ``0..m-1`` (use
:meth:`Dataset.subset <robocal.data.Dataset.subset>` to cut the dataset). Random splits are
deterministic per ``seed`` (:func:`numpy.random.default_rng`); indices come back sorted.
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from ..core import as_count, seeded_rng
from ..exceptions import InvalidParameterError


def _check_m(m: int, least: int, split: str) -> int:
    """``m`` if it is a sample count of at least ``least``, else an error saying what ``split``
    needs (the user sees a sample count, not an argument name)."""
    m = as_count(m, "m", 0)
    if m < least:
        raise InvalidParameterError(f"{split} needs at least {least} samples; the data have {m}")
    return m


def _test_count(m: int, test_fraction: float) -> int:
    if not 0 < test_fraction < 1:
        raise InvalidParameterError(f"`test_fraction` must be in (0, 1); got {test_fraction!r}")
    return min(max(1, round(m * test_fraction)), m - 1)


def paper_split(m: int, seed: int = 0, n_train: int = 100, n_test: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """The paper's protocol: a random subset of ``n_train + n_test`` (120) samples, split into
    ``n_train`` (100) for calibration and ``n_test`` (20) for validation.

    Returns
    -------
    train, test : ndarray of int
        Disjoint, sorted.
    """
    m = _check_m(m, n_train + n_test, f"the paper's split ({n_train} training + {n_test} test samples)")
    if n_train < 1 or n_test < 1:
        raise InvalidParameterError(f"`n_train` and `n_test` must be >= 1; got {n_train}, {n_test}")
    pick = seeded_rng(seed).choice(m, size=n_train + n_test, replace=False)
    return np.sort(pick[:n_train]), np.sort(pick[n_train:])


def random_split(m: int, test_fraction: float = 0.2, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A random ``1 - test_fraction`` / ``test_fraction`` split of all samples (each side >= 1)."""
    m = _check_m(m, 2, "a random training / held-out split")
    order = seeded_rng(seed).permutation(m)
    n_test = _test_count(m, test_fraction)
    return np.sort(order[n_test:]), np.sort(order[:n_test])


def kfold(m: int, k: int = 5, seed: int = 0) -> list[tuple[np.ndarray, np.ndarray]]:
    """``k`` folds of a random permutation: each sample is in exactly one test set.

    Returns
    -------
    list of (train, test)
        Fold sizes differ by at most one.
    """
    m = _check_m(m, 2, "k-fold cross-validation")
    if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 2 <= k <= m:
        raise InvalidParameterError(f"`k` must be an integer in [2, m={m}]; got {k!r}")
    folds = np.array_split(seeded_rng(seed).permutation(m), k)
    return [(np.sort(np.concatenate(folds[:i] + folds[i + 1 :])), np.sort(test)) for i, test in enumerate(folds)]


def chronological(m: int, test_fraction: float = 0.2, t: Optional[np.ndarray] = None) -> tuple[np.ndarray, np.ndarray]:
    """Train on the earlier samples, test on the later ones (drift, temperature, wear).

    Parameters
    ----------
    m : int
    test_fraction : float
    t : array_like, shape (m,), optional
        Acquisition times; row order is the acquisition order without them.
    """
    m = _check_m(m, 2, "a chronological split")
    order = np.arange(m)
    if t is not None:
        t = np.asarray(t, dtype=np.float64)
        if t.shape != (m,) or not np.all(np.isfinite(t)):
            raise InvalidParameterError(f"`t` must be {m} finite times; got shape {t.shape}")
        order = np.argsort(t, kind="stable")
    n_test = _test_count(m, test_fraction)
    return np.sort(order[: m - n_test]), np.sort(order[m - n_test :])
