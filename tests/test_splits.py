"""Train / test splits: disjoint, complete where promised, deterministic per seed."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import robocal
from robocal.data import chronological, configuration_groups, kfold, paper_split, random_split
from robocal.data.splits import CONFIGURATION_TOLERANCE
from robocal.exceptions import InvalidParameterError
from robocal.kernels import configuration_groups as chained_groups


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


def _sweep(samples: int, step: float = 0.0009) -> np.ndarray:
    """Issue 52 #5's path: each joint moves ``step`` rad or less a sample, over 28–61° in all."""
    amp = np.array([0.4, 0.3, 0.3, 0.5, 0.5, 0.6])
    return np.radians([0, -60, 60, 0, 45, 0]) + amp * np.sin(np.outer(np.arange(samples), step / amp) + np.arange(6))


@given(
    q=hnp.arrays(np.float64, st.tuples(st.integers(1, 40), st.integers(1, 4)), elements=st.integers(0, 8).map(lambda k: k * 4e-4)),
    tol=st.sampled_from([0.0, 5e-4, 1e-3, 2e-3]),
)
def test_grouping_never_joins_samples_farther_apart_than_the_tolerance(q, tol):
    """Issue 52 #5: whatever the path between them, two samples of one group are within ``tol`` on
    every joint; samples the chaining keeps apart stay apart, and repeats share a group."""
    labels = configuration_groups(q, tol)
    same = labels[:, None] == labels[None, :]
    far = np.max(np.abs(q[:, None, :] - q[None, :, :]), axis=2) > tol
    assert not np.any(same & far)
    chained = chained_groups(q, tol)
    assert not np.any(same & (chained[:, None] != chained[None, :]))
    identical = np.all(q[:, None, :] == q[None, :, :], axis=2)
    assert np.all(same[identical])
    _, first = np.unique(labels, return_index=True)
    assert np.array_equal(labels[np.sort(first)], np.arange(len(first)))  # numbered in order of first appearance


def test_a_sweep_in_steps_under_the_tolerance_is_not_one_configuration():
    """Issue 52 #5: 1500 samples 0.0009 rad apart were chained into one "target"; a 1500-sample
    trajectory was refused as 1 distinct joint configuration."""
    q = _sweep(1500)
    labels = configuration_groups(q)
    assert chained_groups(q, CONFIGURATION_TOLERANCE).max() == 0  # the chaining's one component
    assert labels.max() + 1 >= 1500 // 2
    data, _ = robocal.simulate("ur10", "position", seed=2, session=3, poses=q)
    result = robocal.calibrate(data, robot="ur10")
    assert result.metrics["test"]["rmse"] < 0.1
    # ISO 9283: no pose of the path is commanded twice, so no repeatability (it was 17.9 mm for 0.02 mm of noise)
    iso = robocal.verify(result.to_dict(), data)["iso9283"]
    assert iso["n_targets"] == 1500 and iso["repeatability_mm"] is None


def test_a_wide_component_among_thousands_of_distinct_configurations_is_still_cut():
    """Issue 53: only components of two or more samples are looked at (20 000 distinct samples
    were split one array each); a sweep among them is still cut, a revisit still joined."""
    rng = np.random.default_rng(5)
    distinct = rng.uniform(-3.0, 3.0, size=(5000, 6))
    sweep = _sweep(300) + 10.0  # away from the distinct samples: a component of its own
    q = np.vstack([distinct[:2500], sweep, distinct[2500:], distinct[7][None, :] + 1e-4])
    labels = configuration_groups(q)
    assert chained_groups(q, CONFIGURATION_TOLERANCE).max() + 1 == 5000 + 1  # the sweep one chained component, the revisit in sample 7's
    assert labels[-1] == labels[7] and len(np.unique(labels[:2500])) == 2500 and len(np.unique(labels[2800:-1])) == 2500
    assert len(np.unique(labels[2500:2800])) >= 300 // 2  # the sweep cut, as on its own
    np.testing.assert_array_equal(np.unique(labels[2500:2800], return_inverse=True)[1], np.unique(configuration_groups(sweep), return_inverse=True)[1])
