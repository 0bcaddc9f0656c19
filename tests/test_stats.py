"""robocal.stats: the robust scale of residuals is taken per component; the paired z score of two models' per-sample errors."""

from __future__ import annotations

import numpy as np
import pytest

from robocal.exceptions import ShapeError
from robocal.stats import paired_z, robust_sigma


def test_robust_sigma_is_sigma_per_component_not_of_the_norms():
    rng = np.random.default_rng(0)
    sigma = np.array([0.05, 0.02, 0.1])
    r = rng.normal(0.0, sigma, (20000, 3))
    r[:200] += 50.0  # 1 % gross outliers barely move a robust scale
    np.testing.assert_allclose(robust_sigma(r), sigma, rtol=0.05)
    # The recipe it replaces (issue 14): 1.4826 x the median of the Euclidean norms over-states
    # sigma of isotropic 3-D errors about 2.3 times.
    iso = rng.normal(0.0, 0.05, (20000, 3))
    assert 2.2 < 1.4826 * np.median(np.linalg.norm(iso, axis=1)) / 0.05 < 2.4
    assert robust_sigma(iso) == pytest.approx([0.05] * 3, rel=0.05)


def test_robust_sigma_shapes_and_floor():
    assert robust_sigma(np.zeros(10)).tolist() == [1e-12]  # noiseless: a scale that can divide
    assert robust_sigma(np.arange(10.0)).shape == (1,)
    with pytest.raises(ShapeError, match="residuals"):
        robust_sigma(np.zeros((0, 3)))


def test_paired_z_is_the_mean_difference_in_standard_errors():
    rng = np.random.default_rng(1)
    before = rng.chisquare(3, 4000)
    # the same errors, 10 % lower: a gain many standard errors wide; the errors of an unrelated
    # model of the same size: no gain beyond chance
    assert paired_z(before, 0.9 * before) > 10.0
    assert abs(paired_z(before, rng.permutation(before))) < 4.0
    d = before - 0.95 * before
    assert paired_z(before, 0.95 * before) == pytest.approx(np.mean(d) / (np.std(d) / np.sqrt(len(d))))
    assert paired_z(before, before + 1.0) < 0.0 and paired_z(np.ones(1), np.zeros(1)) == 0.0
