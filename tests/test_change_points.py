"""Where a step is placed: the scan statistic of a change in a regression
(:func:`robocal.diagnosis.change_points.best_place`) against a brute-force refit at every split."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from robocal.diagnosis.change_points import best_place


def refit_gain(basis: np.ndarray, model: np.ndarray, residuals: np.ndarray, s: int) -> float:
    """What the step's columns, zero before ``s``, remove from ``residuals`` beside the model's,
    by least squares on the stacked rows (the reference the suffix sums must equal)."""
    m, k = residuals.shape
    after = basis * (np.arange(m) >= s)[:, None, None]
    r = residuals.reshape(-1)

    def left(columns: np.ndarray) -> float:
        return float(np.sum((r - columns @ np.linalg.lstsq(columns, r, rcond=None)[0]) ** 2))

    flat_model = model.reshape(m * k, -1)
    return left(flat_model) - left(np.hstack([flat_model, after.reshape(m * k, -1)]))


@given(seed=st.integers(0, 2**32 - 1), m=st.integers(24, 60), k=st.sampled_from([1, 3]), n=st.integers(1, 3), p=st.integers(1, 4))
def test_the_scan_places_the_split_a_refit_at_every_split_prefers(seed, m, k, n, p):
    """On any rows, the split the suffix sums choose removes as much as the best a full refit
    at every split removes (the model's columns, of any rank, projected out exactly)."""
    rng = np.random.default_rng(seed)
    basis, model, residuals = rng.normal(size=(m, k, n)), rng.normal(size=(m, k, p)), rng.normal(size=(m, k))
    min_size = 5
    gains = {s: refit_gain(basis, model, residuals, s) for s in range(min_size, m - min_size + 1)}
    chosen = best_place(basis, model, residuals, min_size)
    assert gains[chosen] >= max(gains.values()) - 1e-9 * (1.0 + max(gains.values()))


@given(seed=st.integers(0, 2**32 - 1), at=st.integers(20, 180))
def test_a_step_the_model_cannot_take_is_placed_where_it_is(seed, at):
    """A step along columns that vary from sample to sample (as a cable anchor's move does),
    with noise a tenth of its size, is placed within a few samples of its own (a sample whose
    columns happen to be small tells little); a model column that spans part of the step (a
    set-up parameter over the whole session) does not move it."""
    rng = np.random.default_rng(seed)
    m = 200
    basis = rng.normal(size=(m, 1, 3))
    model = np.concatenate([basis[:, :, :1], rng.normal(size=(m, 1, 2))], axis=2)  # the first step column is also the model's
    residuals = (basis[:, :, 1:] @ np.array([1.0, -0.5]) * (np.arange(m) >= at)[:, None]) + 0.1 * rng.normal(size=(m, 1))
    assert abs(best_place(basis, model, residuals, 5) - at) <= 3
