"""Train / test splits: disjoint, complete where promised, deterministic per seed."""

from __future__ import annotations

import numpy as np
import pytest

from robocal.data import chronological, kfold, paper_split, random_split
from robocal.exceptions import InvalidParameterError


def test_paper_split():
    train, test = paper_split(1042, seed=3)
    assert (len(train), len(test)) == (100, 20)
    assert not set(train) & set(test) and max(train.max(), test.max()) < 1042
    np.testing.assert_array_equal(paper_split(1042, seed=3)[1], test)
    assert not np.array_equal(paper_split(1042, seed=4)[1], test)
    with pytest.raises(InvalidParameterError, match="needs at least 120 samples; the data have 119"):
        paper_split(119)


@pytest.mark.parametrize("m, k", [(10, 3), (120, 5), (7, 7)])
def test_kfold_covers_every_sample_once(m, k):
    folds = kfold(m, k, seed=1)
    assert len(folds) == k
    tests = np.concatenate([test for _, test in folds])
    np.testing.assert_array_equal(np.sort(tests), np.arange(m))
    for train, test in folds:
        assert len(train) + len(test) == m and not set(train) & set(test)
        assert abs(len(test) - m / k) < 1
    with pytest.raises(InvalidParameterError, match=r"`k` must be an integer in \[2, m=10\]"):
        kfold(10, 11)


def test_random_split():
    train, test = random_split(50, 0.2, seed=0)
    assert (len(train), len(test)) == (40, 10)
    np.testing.assert_array_equal(np.sort(np.concatenate([train, test])), np.arange(50))
    assert len(random_split(3, 0.01)[1]) == 1 and len(random_split(3, 0.99)[0]) == 1
    with pytest.raises(InvalidParameterError, match="`test_fraction` must be in"):
        random_split(10, 1.0)


def test_chronological():
    train, test = chronological(10, 0.3)
    np.testing.assert_array_equal(train, np.arange(7))
    np.testing.assert_array_equal(test, [7, 8, 9])
    t = np.array([5.0, 0.0, 9.0, 1.0, 2.0])  # acquisition times out of row order
    train, test = chronological(5, 0.4, t=t)
    np.testing.assert_array_equal(test, [0, 2])
    with pytest.raises(InvalidParameterError, match="`t` must be 5 finite times"):
        chronological(5, 0.4, t=[1, 2])
