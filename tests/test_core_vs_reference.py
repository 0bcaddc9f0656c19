"""The compiled core (``robocal._robocal``) held equal to its pure-NumPy twin
(``robocal.reference``) on random robots, parameters and configurations, and its handling of bad
input (NaN/inf, wrong shapes, empty arrays, wrong dtypes).

Tolerances are relative to the scale of the compared quantity (``max(1, max|expected|)``, per
column for Jacobians, position and rotation rows apart): 1e-10 where both sides evaluate the
same closed form; where a result is a linear solve, scaled by its condition number.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import (
    MEASUREMENTS,
    Case,
    assert_close,
    assert_jacobian_close,
    cases,
    observations,
    random_params,
    random_q,
    random_spd,
    ref,
)
from hypothesis import given
from hypothesis import strategies as st

import robocal._robocal as core
from robocal.exceptions import (
    InvalidParameterError,
    NoConvergenceError,
    NonFiniteError,
    NotPositiveDefiniteError,
    RobocalError,
    ShapeError,
    SingularError,
)

RTOL = 1e-10
seeds = st.integers(0, 2**32 - 1)


def compiled(case: Case):
    return core.Chain(case.conventions, case.kinds)


def assert_rows_close(got, want, measurement: str, what: str, rtol: float = RTOL) -> None:
    """Per-sample arrays (m, width): pose positions (mm) and orientations compared apart."""
    if measurement == "pose":
        assert_close(got[:, :3], want[:, :3], rtol, what=f"{what} (position)")
        assert_close(got[:, 3:], want[:, 3:], rtol, what=f"{what} (orientation)")
    else:
        assert_close(got, want, rtol, what=what)


# --- the chain and the measurement models -----------------------------------------------------
@given(st.integers(1, 12))
def test_parameter_names_and_units(n):
    chain = core.Chain(["dh"] * n, ["revolute"] * n)
    assert (chain.n_joints, chain.n_params) == (n, 5 * n + 17)
    assert chain.param_names() == ref.param_names(n)
    assert chain.param_units() == ref.param_units(n)


@given(cases(), st.booleans())
def test_fk(case, tool):
    got = compiled(case).fk(case.params, case.q, tool)
    want = ref.fk(*case.chain, case.params, case.q, tool=tool)
    assert_close(got[:, :3, :3], want[:, :3, :3], what="fk rotation")
    assert_close(got[:, :3, 3], want[:, :3, 3], what="fk translation")
    assert_close(got[:, 3], want[:, 3], rtol=0, what="fk bottom row")


@given(cases(max_samples=1), st.integers(0, 2**32 - 1), st.sampled_from([250, 256, 257, 515, 1031]))
def test_fk_large_batches_and_angles(case, seed, m):
    """Batches across the core's lane (4) and task (256) boundaries, with revolute joint values
    up to 3e5 rad — either side of the core's polynomial-sine range (1e5)."""
    rng = np.random.default_rng(seed)
    q = random_q(rng, case.kinds, m)
    q[::3] *= np.where(np.array(case.kinds) == "revolute", rng.uniform(1, 1e5), 1.0)
    got = compiled(case).fk(case.params, q, True)
    want = ref.fk(*case.chain, case.params, q, tool=True)
    assert_close(got[:, :3, :3], want[:, :3, :3], what="fk rotation")
    assert_close(got[:, :3, 3], want[:, :3, 3], what="fk translation")


@given(cases(), st.sampled_from(MEASUREMENTS))
def test_predict_and_residuals(case, measurement):
    chain = compiled(case)
    y = observations(case, measurement, max_angle=3.0)
    got, want = chain.predict(measurement, case.params, case.q), ref.predict(*case.chain, measurement, case.params, case.q)
    assert_rows_close(got, want, measurement, "predict")
    got, want = chain.residuals(measurement, case.params, case.q, y), ref.residuals(*case.chain, measurement, case.params, case.q, y)
    assert_rows_close(got, want, measurement, "residuals")


@given(cases(), st.sampled_from(MEASUREMENTS), st.sampled_from([1e-9, 0.3, 3.0]), st.booleans())
def test_jacobian(case, measurement, max_angle, subset):
    chain = compiled(case)
    y = observations(case, measurement, max_angle=max_angle)
    cols = case.rng.choice(case.params.size, size=case.rng.integers(0, 10)).tolist() if subset else None
    got = chain.jacobian(measurement, case.params, case.q, y, cols)
    want = ref.jacobian(*case.chain, measurement, case.params, case.q, y=y, cols=cols)
    assert_jacobian_close(got, want, measurement, what=f"jacobian(cols={cols})")
    if measurement != "pose":  # y is optional there
        got = chain.jacobian(measurement, case.params, case.q, None, cols)
        assert_jacobian_close(got, want, measurement, what="jacobian without y")


@given(cases(max_samples=1), st.sampled_from(MEASUREMENTS), seeds, st.sampled_from([5, 9, 256, 261]))
def test_measurement_models_on_large_batches(case, measurement, seed, m):
    rng = np.random.default_rng(seed)
    case = Case(case.conventions, case.kinds, case.params, random_q(rng, case.kinds, m), rng)
    chain, y = compiled(case), observations(case, measurement)
    got, want = chain.residuals(measurement, case.params, case.q, y), ref.residuals(*case.chain, measurement, case.params, case.q, y)
    assert_rows_close(got, want, measurement, "residuals")
    got, want = chain.jacobian(measurement, case.params, case.q, y), ref.jacobian(*case.chain, measurement, case.params, case.q, y=y)
    assert_jacobian_close(got, want, measurement, what="jacobian")


@given(cases(max_samples=1), st.sampled_from(MEASUREMENTS), seeds, st.sampled_from([1, 5, 17, 261, 1031]), st.booleans())
def test_residuals_and_jacobian_in_one_pass_are_the_two_calls_bit_for_bit(case, measurement, seed, m, subset):
    """One pass gives what ``residuals`` (its own, wider lane groups) and ``jacobian`` give, bit
    for bit, across the lane (4), small-batch (16) and task (256) boundaries; no column, one
    residual per sample still."""
    rng = np.random.default_rng(seed)
    case = Case(case.conventions, case.kinds, case.params, random_q(rng, case.kinds, m), rng)
    chain, y = compiled(case), observations(case, measurement, max_angle=0.3)
    cols = rng.choice(case.params.size, size=rng.integers(0, 10)).tolist() if subset else None
    r, J = chain.residuals_and_jacobian(measurement, case.params, case.q, y, cols)
    np.testing.assert_array_equal(r, chain.residuals(measurement, case.params, case.q, y))
    np.testing.assert_array_equal(J, chain.jacobian(measurement, case.params, case.q, y, cols))
    assert J.shape == (r.size, case.params.size if cols is None else len(cols))


def test_residuals_and_jacobian_check_their_columns():
    chain = core.Chain(["dh"] * 2, ["revolute"] * 2)
    params, q, y = np.zeros(chain.n_params), np.zeros((3, 2)), np.ones((3, 3))
    with pytest.raises(InvalidParameterError, match="column index 99 out of range"):
        chain.residuals_and_jacobian("position", params, q, y, [0, 99])


@given(cases(max_samples=5), st.sampled_from(MEASUREMENTS), st.integers(1, 9))
def test_sigma_residuals(case, measurement, n_sigmas):
    y = observations(case, measurement)
    cols = case.rng.choice(case.params.size, size=case.rng.integers(1, 8), replace=False).tolist()
    sigmas = case.params[cols] + case.rng.normal(0, 0.05, (n_sigmas, len(cols))) * np.maximum(1, np.abs(case.params[cols]))
    got = compiled(case).sigma_residuals(measurement, case.params, cols, sigmas, case.q, y)
    want = ref.sigma_residuals(*case.chain, measurement, case.params, cols, sigmas, case.q, y)
    k = ref.MEASUREMENTS[measurement][1]
    assert got.shape == want.shape
    assert_rows_close(got.reshape(-1, k), want.reshape(-1, k), measurement, f"sigma_residuals(cols={cols})")


# --- unscented transform ----------------------------------------------------------------------
sigma_settings = st.tuples(seeds, st.integers(1, 10), st.sampled_from([1e-3, 0.1, 0.5, 1.0]), st.floats(0.0, 3.0), st.floats(0.0, 3.0))


@given(sigma_settings)
def test_merwe_sigma_points(setting):
    seed, n, alpha, beta, kappa = setting
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1000, 1000, n)
    P = random_spd(rng, n, scales=rng.uniform(1e-3, 10, n))
    got = core.merwe_sigma_points(x, P, alpha, beta, kappa)
    want = ref.merwe_sigma_points(x, P, alpha, beta, kappa)
    for g, w, name in zip(got, want, ("sigmas", "Wm", "Wc")):
        assert_close(g, w, rtol=1e-12, what=name)


@given(sigma_settings, st.integers(1, 6))
def test_unscented_transform(setting, k):
    seed, n, alpha, beta, kappa = setting
    rng = np.random.default_rng(seed)
    sigmas, Wm, Wc = ref.merwe_sigma_points(rng.normal(0, 100, n), random_spd(rng, n), alpha, beta, kappa)
    images = np.tanh(sigmas @ rng.normal(size=(n, k)) / 100) * 50 + rng.normal(size=k)  # nonlinear
    got = core.unscented_transform(sigmas, images, Wm, Wc)
    want = ref.unscented_transform(sigmas, images, Wm, Wc)
    # With alpha = 1e-3 the weights reach ~1e6 with opposite signs: sums lose |W|·eps.
    rtol = RTOL * max(1.0, np.abs(Wm).max() * 1e-4)
    for g, w, name in zip(got, want, ("mean_y", "cov_y", "cross")):
        assert_close(g, w, rtol=rtol, what=name)


# --- damped solve, identifiability, covariance, cable start ----------------------------------
def random_jacobian(rng, m, n, rank_deficient: bool, dead: bool) -> np.ndarray:
    """Columns with scales from 1e-2 to 1e3 (mm and rad mixed); optionally a duplicated (scaled)
    column and a combination of two others, and a zero column."""
    J = rng.normal(size=(m, n)) * rng.uniform(0.01, 1000, n)
    if rank_deficient and n >= 3:
        J[:, -1] = -3.0 * J[:, 0]
        J[:, -2] = 0.5 * J[:, 1] + 2.0 * J[:, 0]
    if dead:
        J[:, rng.integers(n)] = 0.0
    return J


jacobian_settings = st.tuples(seeds, st.integers(1, 30), st.integers(1, 12), st.booleans(), st.booleans())


@given(seeds, st.integers(1, 12), st.integers(-11, 30), st.sampled_from([1e-6, 1e-3, 1.0, 100.0]))
def test_damped_qr(seed, n, extra_rows, lam):
    """One factorisation, many damped steps: equal to the NumPy twin's augmented least squares,
    and ``‖Qᵀb‖`` equal to the norm of ``b``'s least-squares fit by ``J`` (fewer rows than
    columns too: a diagnosis fold can be underdetermined)."""
    rng = np.random.default_rng(seed)
    J = random_jacobian(rng, max(1, n + extra_rows), n, rank_deficient=False, dead=False)
    J /= np.linalg.norm(J, axis=0)  # the LM passes unit-scale columns
    b = rng.normal(size=len(J))
    factored = core.DampedQr(J)
    c = factored.project(b)
    want, explained = ref.damped_qr_step(J, b, lam)
    s = np.linalg.svd(np.vstack([J, np.sqrt(lam) * np.eye(n)]), compute_uv=False)
    assert_close(factored.solve(c, lam), want, rtol=1e-12 * s[0] / s[-1] * max(1.0, s[0] / s[-1]), what="step")
    assert np.linalg.norm(c) == pytest.approx(explained, rel=1e-9, abs=1e-12)


@given(jacobian_settings, st.sampled_from([0.0, 1e-6, 1e-3, 1.0, 100.0]), st.sampled_from(["marquardt", "identity"]), st.sampled_from(["normal", "lstsq"]))
def test_solve_damped(setting, lam, damping, factor):
    seed, m, n, deficient, dead = setting
    rng = np.random.default_rng(seed)
    J = random_jacobian(rng, m, n, deficient, dead)
    r = rng.normal(size=m)
    got, got_method = core.solve_damped(J, r, lam, damping, factor)
    want, want_method = ref.solve_damped(J, r, lam, damping, factor)
    if factor == "normal" or want_method == "cholesky":
        A = J.T @ J + lam * (np.diag(np.diag(J.T @ J)) if damping == "marquardt" else np.eye(n))
        cut = ref.RANK_TOL * n
    else:  # the scaled augmented matrix
        norms = np.linalg.norm(J, axis=0)
        scale = np.where(norms > 0, norms, 1.0)
        A = np.vstack([J / scale, np.diag(np.sqrt(lam) * (norms if damping == "marquardt" else 1.0) / scale)])
        cut = np.finfo(float).eps * (m + n)
    s = np.linalg.svd(A, compute_uv=False)
    assert got_method == want_method, f"method {got_method!r} != {want_method!r} (singular values of the damped matrix {s})"
    # The step is as accurate as the damped matrix is conditioned (on the singular values the
    # SVD fallback keeps): eps · cond.
    kept = s[s > (cut * s[0] if want_method == "svd" else 0.0)]
    cond = kept[0] / kept[-1] if kept.size else 1.0
    sensitivity = cond
    if factor == "lstsq" and want_method != "cholesky" and kept.size:
        # A least-squares solution with a residual is sensitive to cond² (Golub & Van Loan 5.3):
        # eps · (cond + cond² · ‖b − A·y‖ / (‖A‖ ‖y‖)), y the solution in scaled columns.
        y = want * scale
        b = np.concatenate([r, np.zeros(n)])
        sensitivity += cond**2 * np.linalg.norm(b - A @ y) / (s[0] * max(np.linalg.norm(y), 1e-300))
    assert_close(got, want, rtol=RTOL + 1e-15 * sensitivity, what=f"delta ({want_method}, cond {cond:.2e})")


def scaled(J):
    """``J`` with unit-norm columns (zero columns kept at zero), as the twin scales it."""
    return ref._scaled_columns(J)[2]


def assert_identifiability_matches(got: dict, want: dict, J: np.ndarray) -> None:
    """Everything equal, the identifiable subset in the same pivot order too: both break pivot
    ties (every first pivot of unit-norm columns, exactly dependent columns) by the lowest column
    index. The core's subset is checked to be independent, and its redundancies against the
    twin's least squares on that subset."""
    assert set(got) == set(want)
    assert got["rank"] == want["rank"], f"rank {got['rank']} != {want['rank']}, singular values {want['singular_values']}"
    assert_close(got["singular_values"], want["singular_values"], what="singular values")
    cond = want["condition_number"]
    assert got["condition_number"] == pytest.approx(cond, rel=RTOL + 1e-14 * cond)
    assert_close(got["column_norms"], want["column_norms"], per_column=True, what="column norms")
    assert got["no_effect"] == want["no_effect"]
    rank, Jn = want["rank"], scaled(J)
    ident = got["identifiable"]
    assert ident == want["identifiable"], f"identifiable {ident} != {want['identifiable']}"
    assert len(ident) == len(set(ident)) == rank and not set(ident) & set(got["no_effect"])
    if rank:
        s_sub = np.linalg.svd(Jn[:, ident], compute_uv=False)
        assert s_sub[-1] > 1e-9 * want["singular_values"][0], f"core's subset {ident} is not independent: {s_sub}"
    others = sorted(set(range(J.shape[1])) - set(ident) - set(got["no_effect"]))
    assert [col for col, _ in got["redundant"]] == (others if rank else [])
    if rank and others:
        coefs = np.linalg.lstsq(Jn[:, ident], Jn[:, others], rcond=None)[0]
        for (col, partners), c in zip(got["redundant"], coefs.T):
            expected = [(k, v) for k, v in zip(ident, c) if abs(v) > ref.REDUNDANCY_COEF_MIN]
            assert [k for k, _ in partners] == [k for k, _ in expected], f"column {col}: partners {partners} != {expected}"
            assert_close([v for _, v in partners], [v for _, v in expected], rtol=1e-8, what=f"column {col} coefficients")


@given(jacobian_settings)
def test_identifiability_random(setting):
    seed, m, n, deficient, dead = setting
    J = random_jacobian(np.random.default_rng(seed), m, n, deficient, dead)
    assert_identifiability_matches(core.identifiability(J), ref.identifiability(J), J)


@given(cases(max_joints=6, max_samples=1), st.sampled_from(MEASUREMENTS), seeds)
def test_identifiability_and_covariance_of_robot_jacobians(case, measurement, seed):
    """Real identification Jacobians (rank deficient: DH redundancies, dead sensor columns)."""
    rng = np.random.default_rng(seed)
    case = Case(case.conventions, case.kinds, case.params, random_q(rng, case.kinds, 40), rng)
    J = ref.jacobian(*case.chain, measurement, case.params, case.q, y=observations(case, measurement))
    want = ref.identifiability(J)
    assert_identifiability_matches(core.identifiability(J), want, J)
    # Some columns marked to be pivoted first (as a session's set-up is): the same subset in both.
    first = [bool(v) for v in rng.random(J.shape[1]) < 0.3]
    assert_identifiability_matches(core.identifiability(J, 1e-9, first), ref.identifiability(J, first=first), J)
    r = rng.normal(0, 0.05, J.shape[0])
    assert_covariance_matches(core.covariance(J, r), ref.covariance(J, r), J, want["condition_number"])


def assert_covariance_matches(got, want, J, cond) -> None:
    cov, sigma2, dof, rank = got
    assert (dof, rank) == want[2:]
    assert sigma2 == pytest.approx(want[1], rel=1e-12)
    # Compared on unit-norm columns, where entries are sigma2 (Jn^T Jn)^+ ~ sigma2 / s_rank^2.
    norms = np.linalg.norm(J, axis=0)
    unit = np.outer(norms, norms)
    assert_close(cov * unit, want[0] * unit, rtol=RTOL + 1e-15 * cond**2, what=f"covariance on unit columns (cond {cond:.2e})")


@given(jacobian_settings)
def test_covariance_random(setting):
    seed, m, n, deficient, dead = setting
    rng = np.random.default_rng(seed)
    J = random_jacobian(rng, m + n, n, deficient, dead)  # at least one degree of freedom
    r = rng.normal(size=m + n)
    assert_covariance_matches(core.covariance(J, r), ref.covariance(J, r), J, ref.identifiability(J)["condition_number"])


@given(seeds, st.integers(5, 60), st.sampled_from([0.0, 0.05, 2.0]))
def test_cable_initial_guess(seed, m, noise):
    rng = np.random.default_rng(seed)
    anchor = rng.uniform(-3000, 3000, 3)
    p = rng.uniform(-1500, 1500, (m, 3)) + [1000.0, 0, 800]
    L = np.linalg.norm(p - anchor, axis=1) - rng.uniform(0, 500) + rng.normal(0, noise, m)
    got_anchor, got_offset = core.cable_initial_guess(p, L)
    want_anchor, want_offset = ref.cable_initial_guess(p, L)
    # One scale (mm) for the four unknowns of one least-squares problem.
    assert_close(np.r_[got_anchor, got_offset], np.r_[want_anchor, want_offset], rtol=1e-9, what="anchor, cable_offset")


# --- bad input --------------------------------------------------------------------------------
N = 3
CHAIN = (["dh", "mdh", "dh"], ["revolute", "prismatic", "revolute"])
_rng = np.random.default_rng(7)
PARAMS = random_params(_rng, N)
Q = random_q(_rng, CHAIN[1], 6)
Y = {meas: observations(Case(*CHAIN, PARAMS, Q, _rng), meas) for meas in MEASUREMENTS}
COLS = [0, 3, 7]
SIGMAS, WM, WC = ref.merwe_sigma_points(PARAMS[COLS], np.eye(3), 0.5, 2.0, 0.0)
J6 = random_jacobian(_rng, 20, 6, False, False)
P_CABLE = _rng.uniform(-1000, 1000, (10, 3))


class Entry:
    """One entry point, called with its array arguments by keyword: ``core(**arrays)`` on the
    compiled module (a method of ``Chain(*CHAIN)`` when ``method``), ``twin(**arrays)`` on the
    twin; ``fixed`` holds the non-array arguments."""

    def __init__(self, label: str, name: str, arrays: dict, method: bool = False, **fixed):
        self.label, self.name, self.arrays, self.method, self.fixed = label, name, arrays, method, fixed

    def core(self, **arrays):
        target = core.Chain(*CHAIN) if self.method else core
        return getattr(target, self.name)(**self.fixed, **arrays)

    def twin(self, **arrays):
        chain = CHAIN if self.method else ()
        return getattr(ref, self.name)(*chain, **self.fixed, **arrays)

    def with_value(self, side, name: str, value):
        """Calls ``side`` (``self.core`` or ``self.twin``) with argument ``name`` replaced."""
        return side(**{**self.arrays, name: value})


ENTRIES = [
    Entry("fk", "fk", {"params": PARAMS, "q": Q}, method=True, tool=True),
    Entry("predict", "predict", {"params": PARAMS, "q": Q}, method=True, measurement="pose"),
    *[Entry(f"residuals[{meas}]", "residuals", {"params": PARAMS, "q": Q, "y": Y[meas]}, method=True, measurement=meas) for meas in MEASUREMENTS],
    Entry("jacobian[pose]", "jacobian", {"params": PARAMS, "q": Q, "y": Y["pose"]}, method=True, measurement="pose"),
    Entry(
        "sigma_residuals",
        "sigma_residuals",
        {"params": PARAMS, "sigmas": SIGMAS, "q": Q, "y": Y["position"]},
        method=True,
        measurement="position",
        cols=COLS,
    ),
    Entry("merwe_sigma_points", "merwe_sigma_points", {"x": PARAMS[COLS], "P": np.eye(3)}, alpha=0.5, beta=2.0, kappa=0.0),
    Entry("unscented_transform", "unscented_transform", {"sigmas_x": SIGMAS, "sigmas_y": SIGMAS @ np.ones((3, 2)), "Wm": WM, "Wc": WC}),
    Entry("solve_damped", "solve_damped", {"J": J6, "r": np.ones(20)}, lam=0.1),
    Entry("identifiability", "identifiability", {"J": J6}),
    Entry("covariance", "covariance", {"J": J6, "r": np.ones(20)}),
    Entry("cable_initial_guess", "cable_initial_guess", {"p": P_CABLE, "L": np.linalg.norm(P_CABLE, axis=1)}),
]
ARGUMENTS = [pytest.param(entry, name, id=f"{entry.label}-{name}") for entry in ENTRIES for name in entry.arrays]


@pytest.mark.parametrize("entry", ENTRIES, ids=[e.label for e in ENTRIES])
def test_valid_inputs_agree(entry):
    """The fixtures of this section are valid, and core and twin agree on them."""
    got, want = entry.core(**entry.arrays), entry.twin(**entry.arrays)
    for g, w in zip(got if isinstance(got, tuple) else [got], want if isinstance(want, tuple) else [want]):
        if isinstance(w, np.ndarray):
            assert_close(g, w, rtol=1e-9, what=entry.label)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("entry, name", ARGUMENTS)
def test_non_finite_input_names_the_argument(entry, name, bad):
    value = entry.arrays[name].copy()
    value.flat[value.size // 2] = bad
    with pytest.raises(NonFiniteError, match=f"`{name}` must be finite"):
        entry.with_value(entry.core, name, value)
    with pytest.raises(ValueError, match=f"`{name}` must be finite"):  # the twin mirrors the check
        entry.with_value(entry.twin, name, value)


@pytest.mark.parametrize("entry, name", ARGUMENTS)
def test_wrong_dimensionality_names_the_argument(entry, name):
    with pytest.raises(ShapeError, match=f"`{name}` must have shape"):
        entry.with_value(entry.core, name, entry.arrays[name][None])
    with pytest.raises(ValueError, match=f"`{name}` must have shape"):
        entry.with_value(entry.twin, name, entry.arrays[name][None])


@pytest.mark.parametrize("dtype", [np.int64, np.float32, "list"])
@pytest.mark.parametrize("entry, name", ARGUMENTS)
def test_other_dtypes_name_the_argument(entry, name, dtype):
    """The compiled module takes float64 arrays only (the Python layer converts)."""
    value = entry.arrays[name].tolist() if dtype == "list" else entry.arrays[name].astype(dtype)
    with pytest.raises(RobocalError, match=f"`{name}`"):
        entry.with_value(entry.core, name, value)


def assert_same_result(got, want, what: str) -> None:
    """Bit-identical results (arrays, scalars, strings, and tuples / lists / dicts of them)."""
    if isinstance(want, dict):
        assert set(got) == set(want), what
        for key in want:
            assert_same_result(got[key], want[key], f"{what}[{key!r}]")
    elif isinstance(want, (tuple, list)):
        assert len(got) == len(want), what
        for i, (g, w) in enumerate(zip(got, want)):
            assert_same_result(g, w, f"{what}[{i}]")
    else:
        np.testing.assert_array_equal(got, want, err_msg=what)


def layouts(a: np.ndarray) -> dict:
    """The same logical array in other memory layouts (those that are not C-contiguous)."""
    out = {"strided view": np.repeat(a, 2, axis=-1)[..., ::2], "Fortran order": np.asfortranarray(a)}
    return {name: v for name, v in out.items() if not v.flags.c_contiguous}


LAYOUTS = [
    pytest.param(entry, name, layout, id=f"{entry.label}-{name}-{layout}")
    for entry in ENTRIES
    for name in entry.arrays
    for layout in layouts(entry.arrays[name])
]


@pytest.mark.parametrize("entry, name, layout", LAYOUTS)
def test_memory_layout_does_not_change_results(entry, name, layout):
    """A Fortran-ordered or strided float64 array is the same logical input as its C copy:
    the core must read it in logical order (or refuse it naming it), never reinterpret its memory."""
    try:
        got = entry.with_value(entry.core, name, layouts(entry.arrays[name])[layout])
    except RobocalError as exc:
        assert f"`{name}`" in str(exc)
        return
    assert_same_result(got, entry.core(**entry.arrays), f"{entry.label} with `{name}` in {layout}")


def chain_call(method: str, *args):
    return lambda: getattr(core.Chain(*CHAIN), method)(*args)


# (label, call, the argument the ShapeError must name)
SHAPE_MISMATCHES = [
    ("q has 4 joints", chain_call("fk", PARAMS, np.zeros((2, 4))), "q"),
    ("q has 2 joints", chain_call("residuals", "position", PARAMS, Q[:, :2], Y["position"]), "q"),
    ("params too short", chain_call("predict", "cable", PARAMS[:-1], Q), "params"),
    ("params of a 4-joint chain", chain_call("fk", np.zeros(5 * 4 + 17), Q), "params"),
    ("y has too few rows", chain_call("residuals", "position", PARAMS, Q, Y["position"][:-1]), "y"),
    ("cable y is 1-D", chain_call("residuals", "cable", PARAMS, Q, Y["cable"][:, 0]), "y"),
    ("pose y has 6 columns", chain_call("jacobian", "pose", PARAMS, Q, Y["pose"][:, :6]), "y"),
    ("sigmas columns != len(cols)", chain_call("sigma_residuals", "position", PARAMS, COLS[:2], SIGMAS, Q, Y["position"]), "sigmas"),
    ("P is 3x2", lambda: core.merwe_sigma_points(np.zeros(3), np.eye(3)[:, :2], 0.5, 2.0, 0.0), "P"),
    ("P is 2x2 for x of 3", lambda: core.merwe_sigma_points(np.zeros(3), np.eye(2), 0.5, 2.0, 0.0), "P"),
    ("Wc shorter than Wm", lambda: core.unscented_transform(SIGMAS, SIGMAS, WM, WC[:-1]), "Wc"),
    ("sigmas_x has 2S rows", lambda: core.unscented_transform(np.vstack([SIGMAS, SIGMAS]), SIGMAS, WM, WC), "sigmas_x"),
    ("sigmas_y has S-1 rows", lambda: core.unscented_transform(SIGMAS, SIGMAS[:-1], WM, WC), "sigmas_y"),
    ("r shorter than J", lambda: core.solve_damped(J6, np.ones(19), 0.0), "r"),
    ("r longer than J", lambda: core.covariance(J6, np.ones(21)), "r"),
    ("p has 2 columns", lambda: core.cable_initial_guess(P_CABLE[:, :2], np.ones(10)), "p"),
    ("L shorter than p", lambda: core.cable_initial_guess(P_CABLE, np.ones(9)), "L"),
    ("kinds shorter than conventions", lambda: core.Chain(["dh", "dh"], ["revolute"]), "kinds"),
]


@pytest.mark.parametrize("label, call, name", SHAPE_MISMATCHES, ids=[s[0] for s in SHAPE_MISMATCHES])
def test_shape_mismatch_names_the_argument(label, call, name):
    with pytest.raises(ShapeError, match=f"`{name}`"):
        call()


def test_empty_inputs():
    chain = core.Chain(*CHAIN)
    none = np.zeros((0, N))
    # An empty batch of configurations has poses (none); measurement models need samples.
    assert chain.fk(PARAMS, none).shape == (0, 4, 4)
    for meas in MEASUREMENTS:
        with pytest.raises(ShapeError, match="`q`"):
            chain.predict(meas, PARAMS, none)
    with pytest.raises(ShapeError, match="`params`"):
        chain.fk(np.zeros(0), Q)
    with pytest.raises(ShapeError, match="at least one joint"):
        core.Chain([], [])
    assert chain.jacobian("position", PARAMS, Q, None, []).shape == (Q.shape[0] * 3, 0)
    with pytest.raises(ShapeError, match="`sigmas`"):
        chain.sigma_residuals("position", PARAMS, [], np.zeros((2, 0)), Q, Y["position"])
    with pytest.raises(ShapeError):
        core.merwe_sigma_points(np.zeros(0), np.zeros((0, 0)), 0.5, 2.0, 0.0)
    with pytest.raises(ShapeError):
        core.unscented_transform(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), np.zeros(0))
    with pytest.raises(ShapeError, match="`p`"):
        core.cable_initial_guess(np.zeros((0, 3)), np.zeros(0))
    with pytest.raises(InvalidParameterError, match="degrees of freedom"):
        core.covariance(np.zeros((0, 3)), np.zeros(0))
    # A Jacobian without rows identifies nothing; a step without rows is zero.
    got, want = core.identifiability(np.zeros((0, 3))), ref.identifiability(np.zeros((0, 3)))
    for key in ("rank", "no_effect", "identifiable"):
        assert got[key] == want[key]
    assert (want["rank"], want["no_effect"], want["identifiable"]) == (0, [0, 1, 2], [])
    delta, _ = core.solve_damped(np.zeros((0, 3)), np.zeros(0), 0.0)
    np.testing.assert_array_equal(delta, np.zeros(3))


def test_sigma_residuals_of_no_sigma_points_keep_their_width():
    """(S, m·res_width) with S = 0 is (0, m·res_width)."""
    got = core.Chain(*CHAIN).sigma_residuals("position", PARAMS, COLS, np.zeros((0, 3)), Q, Y["position"])
    assert got.shape == (0, Q.shape[0] * 3)


def test_domain_errors():
    chain = core.Chain(*CHAIN)
    with pytest.raises(InvalidParameterError, match="`measurement`"):
        chain.predict("laser", PARAMS, Q)
    with pytest.raises(InvalidParameterError, match="`cols`"):
        chain.jacobian("cable", PARAMS, Q, None, [5 * N + 17])
    with pytest.raises(InvalidParameterError, match="`cols`"):
        chain.sigma_residuals("position", PARAMS, [0, -1, 2], SIGMAS, Q, Y["position"])
    with pytest.raises(InvalidParameterError, match="`tol`"):
        core.identifiability(J6, 0.0)
    with pytest.raises(InvalidParameterError, match="`tol`"):
        core.covariance(J6, np.ones(20), 1.5)
    with pytest.raises(NotPositiveDefiniteError):
        core.merwe_sigma_points(np.zeros(2), np.array([[1.0, 2.0], [2.0, 1.0]]), 0.5, 2.0, 0.0)
    with pytest.raises(SingularError):
        core.cable_initial_guess(np.tile([100.0, 0, 0], (8, 1)), np.full(8, 50.0))


def test_exception_hierarchy():
    for cls in (ShapeError, NonFiniteError, InvalidParameterError):
        assert issubclass(cls, RobocalError) and issubclass(cls, ValueError)
    for cls in (SingularError, NotPositiveDefiniteError):
        assert issubclass(cls, RobocalError) and issubclass(cls, np.linalg.LinAlgError)
    assert issubclass(NoConvergenceError, RobocalError) and issubclass(NoConvergenceError, RuntimeError)


@pytest.mark.parametrize("seed", range(5))
def test_configuration_groups_equal_the_kd_tree_labels(seed):
    """The core's sort-and-sweep labels (the chained components ``data.splits.configuration_groups``
    cuts where they span more than ``tol``) are the oracle's: a k-d tree's pairs within ``tol`` on
    every joint, connected components, first-appearance order."""
    from robocal.kernels import configuration_groups
    from robocal.reference import configuration_groups as oracle

    rng = np.random.default_rng(seed)
    for _ in range(40):
        m, n = int(rng.integers(1, 300)), int(rng.integers(1, 7))
        q = rng.integers(0, 25, size=(m, n)) * 1e-3 + rng.normal(0.0, 3e-4, size=(m, n)) * rng.integers(0, 2)
        revisits = rng.integers(0, m, size=m // 3)
        q[revisits] = q[rng.integers(0, m, size=revisits.size)]
        tol = float(rng.choice([0.0, 5e-4, 1e-3, 2e-3]))
        np.testing.assert_array_equal(configuration_groups(q, tol), oracle(q, tol))


def test_normal_equations_and_the_damped_steps_from_them():
    """``normal_equations`` is ``(JᵀJ, Jᵀr)``; the LM's steps from it equal the pivoted QR's on a
    well-conditioned Jacobian."""
    from robocal.calibration.lm import _factor

    rng = np.random.default_rng(3)
    J = rng.normal(size=(5000, 12)) * np.logspace(0, 3, 12)
    r = rng.normal(size=5000)
    gram, g = core.normal_equations(J, r)
    assert_close(gram, J.T @ J, rtol=1e-12)
    assert_close(g, J.T @ r, rtol=1e-12)
    d = np.sqrt(np.diag(gram))
    fast, qr = _factor(J, d, gram), core.DampedQr(J / d)
    assert type(fast).__name__ == "_DampedGram"
    # Other orthonormal bases of J's columns (Cholesky's, the pivoted QR's): the same norm of r's part in them.
    assert_close(np.linalg.norm(fast.project(r)), np.linalg.norm(qr.project(r)), rtol=1e-9)
    for lam in (0.0, 1e-3, 10.0):
        assert_close(fast.solve(fast.project(r), lam), qr.solve(qr.project(r), lam), rtol=1e-9)
