"""The linear screening of a selection round (robocal.diagnosis.screening) held against a plain
least-squares fit per fold, and the map screening's solve on a fold its knots do not reach."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.stats import f as f_dist

from robocal.diagnosis.maps import _solve as map_solve
from robocal.diagnosis.screening import Screen
from robocal.diagnosis.validation import fold_schemes


def _problem(seed: int, m: int, p: int, nc: int, k: int):
    rng = np.random.default_rng(seed)
    J = rng.normal(size=(m * k, p)) * rng.uniform(0.1, 10.0, size=p)  # columns of other units
    C = rng.normal(size=(m * k, nc)) + 0.5 * J[:, rng.integers(0, p, nc)] / np.linalg.norm(J, axis=0).max() * np.sqrt(m * k)  # partly in J's span
    r = J @ rng.normal(size=p) + C @ rng.normal(size=nc) * 0.1 + rng.normal(size=m * k)
    schemes = fold_schemes(rng.normal(size=(m, 3)), 5, seed, rng.permutation(m), None)
    return J, C, r, schemes


def _reference_errors(J, C, r, schemes, k, P=None) -> dict:
    """Per scheme, each sample's held-out squared error of ``[J, C]`` fitted by least squares on the
    other folds (``C``'s coefficients penalised by ``‖P·c‖²``)."""
    A = np.hstack([J, C])
    out = {}
    for name, folds in schemes.items():
        out[name] = np.zeros(len(r) // k)
        for train, test in folds:
            rows_tr, rows_te = ((s[:, None] * k + np.arange(k)).ravel() for s in (train, test))
            A_tr, b = A[rows_tr], r[rows_tr]
            if P is not None:
                A_tr = np.vstack([A_tr, np.hstack([np.zeros((len(P), J.shape[1])), P])])
                b = np.concatenate([b, np.zeros(len(P))])
            x = np.linalg.lstsq(A_tr, b, rcond=None)[0]
            e = r[rows_te] - A[rows_te] @ x
            out[name][test] = (e * e).reshape(-1, k).sum(axis=1)
    return out


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), m=st.integers(40, 200), p=st.integers(2, 8), nc=st.integers(1, 3), k=st.sampled_from([1, 3]))
def test_the_screenings_held_out_errors_are_those_of_a_least_squares_fit_per_fold(seed, m, p, nc, k):
    J, C, r, schemes = _problem(seed, m, p, nc, k)
    screen = Screen(J, r, schemes, k)
    for name, errs in screen.errors(C).items():
        np.testing.assert_allclose(errs, _reference_errors(J, C, r, schemes, k)[name], rtol=1e-7, atol=1e-9)
    for name, errs in screen.errors(np.zeros((len(r), 0))).items():
        np.testing.assert_allclose(errs, _reference_errors(J, np.zeros((len(r), 0)), r, schemes, k)[name], rtol=1e-7, atol=1e-9)
    P = np.diff(np.eye(nc), n=1, axis=0) * 3.0 if nc > 1 else np.eye(1) * 3.0  # a roughness on C's coefficients
    for name, errs in screen.errors(C, P).items():
        np.testing.assert_allclose(errs, _reference_errors(J, C, r, schemes, k, P)[name], rtol=1e-7, atol=1e-9)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), m=st.integers(40, 200), p=st.integers(2, 8), nc=st.integers(1, 3))
def test_the_screenings_f_test_is_the_extra_sum_of_squares_test(seed, m, p, nc):
    J, C, r, schemes = _problem(seed, m, p, nc, 1)
    rss = lambda A: float(np.sum((r - A @ np.linalg.lstsq(A, r, rcond=None)[0]) ** 2))
    rss0, rss1 = rss(J), rss(np.hstack([J, C]))
    dof = len(r) - p - nc
    expected = f_dist.sf((rss0 - rss1) / nc / (rss1 / dof), nc, dof)
    assert Screen(J, r, schemes, 1).f_test(C) == pytest.approx(expected, rel=1e-6, abs=1e-300)


def test_a_candidate_in_the_span_of_the_model_gains_nothing_and_stays_finite():
    """A candidate the model's columns already hold (to rounding) is projected row by row: its
    direction beyond them is below the rank cutoff and counts as none — the same held-out errors
    and F test as without it, not a fit of the rounding."""
    J, _, r, schemes = _problem(7, 120, 5, 1, 1)
    C = (J[:, :2] @ [1.0, -2.0])[:, None] * (1.0 + 1e-15)
    screen = Screen(J, r, schemes, 1)
    without = screen.errors(np.zeros((len(r), 0)))
    for name, errs in screen.errors(C).items():
        assert np.all(np.isfinite(errs))
        np.testing.assert_allclose(errs, without[name], rtol=1e-8)
    assert screen.f_test(C) == 1.0


def test_the_map_screenings_solve_leaves_a_column_no_training_row_touches_at_zero():
    """A map knot beyond a fold's training angles has a zero diagonal and off-diagonal entries of
    rounding: it once raised a singular-matrix error (discovery seed 34, file 20); now its
    coefficient is zero and the rest solved as without it."""
    rng = np.random.default_rng(3)
    A = rng.normal(size=(30, 4))
    N = np.zeros((5, 5))
    N[:4, :4] = A.T @ A
    N[4, :4] = N[:4, 4] = 1e-17  # the rounding of a difference of products
    b = np.concatenate([A.T @ rng.normal(size=30), [1e-17]])
    x = map_solve(N, b)
    assert x[4] == 0.0
    np.testing.assert_allclose(x[:4], map_solve(N[:4, :4], b[:4]), rtol=1e-12)
