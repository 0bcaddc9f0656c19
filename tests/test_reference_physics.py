"""Physics of the pure-NumPy twin (``robocal.reference``) against independent constructions:
textbook DH / MDH matrices, central differences, exact identities of the unscented transform,
closed forms. Needs only NumPy and SciPy (not the compiled core)."""

from __future__ import annotations

import math

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
from hypothesis import assume, given
from hypothesis import strategies as st

seeds = st.integers(0, 2**32 - 1)


# --- textbook matrices, written out independently of the twin -------------------------------
def trans(x=0.0, y=0.0, z=0.0) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = x, y, z
    return T


def rot_x(v: float) -> np.ndarray:
    c, s = math.cos(v), math.sin(v)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def rot_y(v: float) -> np.ndarray:
    c, s = math.cos(v), math.sin(v)
    return np.array([[c, 0, s, 0], [0, 1, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1.0]])


def rot_z(v: float) -> np.ndarray:
    c, s = math.cos(v), math.sin(v)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def dh_textbook(alpha, a, d, theta) -> np.ndarray:
    """Standard DH link, the paper's eq. (1)."""
    ct, st_, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    return np.array([[ct, -st_ * ca, st_ * sa, a * ct], [st_, ct * ca, -ct * sa, a * st_], [0, sa, ca, d], [0, 0, 0, 1.0]])


def mdh_textbook(alpha, a, d, theta) -> np.ndarray:
    """Modified DH link (Craig, eq. 3.6)."""
    ct, st_, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    return np.array([[ct, -st_, 0, a], [st_ * ca, ct * ca, -sa, -sa * d], [st_ * sa, ct * sa, ca, ca * d], [0, 0, 0, 1.0]])


def rpy_textbook(x, y, z, rx, ry, rz) -> np.ndarray:
    """``Tx Ty Tz Rz(rz) Ry(ry) Rx(rx)`` multiplied out."""
    ca, sa, cb, sb, cg, sg = math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry), math.cos(rz), math.sin(rz)
    return np.array(
        [
            [cg * cb, cg * sb * sa - sg * ca, cg * sb * ca + sg * sa, x],
            [sg * cb, sg * sb * sa + cg * ca, sg * sb * ca - cg * sa, y],
            [-sb, cb * sa, cb * ca, z],
            [0, 0, 0, 1.0],
        ]
    )


def joint_values(case: Case, i: int, j: int):
    """``(alpha, a, d, theta, beta)`` of joint j for sample i, the joint variable included."""
    alpha, a, d, theta, beta = case.params[5 * j : 5 * j + 5]
    if case.kinds[j] == "revolute":
        theta = theta + case.q[i, j]
    else:
        d = d + case.q[i, j]
    return alpha, a, d, theta, beta


def base_tool(case: Case):
    b = 5 * case.n
    return case.params[b : b + 6], case.params[b + 6 : b + 12]


# --- rotations --------------------------------------------------------------------------------
def assert_rotations(R: np.ndarray) -> None:
    eye = np.broadcast_to(np.eye(3), R.shape)
    assert_close(np.swapaxes(R, -1, -2) @ R, eye, rtol=1e-12, what="R^T R")
    assert_close(np.linalg.det(R), np.ones(R.shape[:-2]), rtol=1e-12, what="det R")


@given(cases(), st.booleans())
def test_fk_rotations_are_orthonormal(case, tool):
    T = ref.fk(*case.chain, case.params, case.q, tool=tool)
    assert T.shape == (case.q.shape[0], 4, 4)
    assert_rotations(T[:, :3, :3])
    assert_close(T[:, 3, :], np.tile([0, 0, 0, 1.0], (len(T), 1)), rtol=0, what="bottom row")


@given(seeds)
def test_so3_and_quaternion_helpers(seed):
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=(8, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    # Angles across (0, pi), including the small-angle branch and the neighbourhood of pi.
    angles = np.concatenate([rng.uniform(0, np.pi, 5), [1e-9, 3e-5, np.pi - 1e-7]])
    phi = axis * angles[:, None]
    R = ref.so3_exp(phi)
    assert_rotations(R)
    assert_close(ref.so3_log(R), phi, rtol=1e-7, what="log(exp(phi))")
    q = ref.quaternion_from_matrix(R)
    assert np.all(q[:, 0] >= 0)
    assert_close(np.linalg.norm(q, axis=1), np.ones(8), rtol=1e-14, what="|q|")
    assert_close(ref.matrix_from_quaternion(q), R, rtol=1e-13, what="R(q(R))")
    assert_close(ref.matrix_from_quaternion(-q), R, rtol=1e-13, what="R(-q)")
    # exp against the textbook elementary rotation about z.
    assert_close(ref.so3_exp(np.array([0, 0, 0.7])), rot_z(0.7)[:3, :3], rtol=1e-15, what="exp about z")


@given(seeds)
def test_right_jacobian_inverse_is_the_derivative_of_log(seed):
    rng = np.random.default_rng(seed)
    for angle in (1e-6, 0.5, 2.5):  # series branch, ordinary, close to pi
        phi = rng.normal(size=3)
        phi *= angle / np.linalg.norm(phi)
        h = 1e-6
        log_after = lambda d: ref.so3_log(ref.so3_exp(phi) @ ref.so3_exp(d))  # noqa: E731
        numeric = np.column_stack([(log_after(h * e) - log_after(-h * e)) / (2 * h) for e in np.eye(3)])
        assert_close(ref.right_jacobian_inverse(phi), numeric, rtol=1e-7, what=f"J_r^-1 at |phi|={angle}")


@given(seeds)
def test_frame_transform_is_rpy_and_inverts(seed):
    rng = np.random.default_rng(seed)
    p = np.concatenate([rng.uniform(-500, 500, 3), rng.uniform(-np.pi, np.pi, 3)])
    p[4] = rng.uniform(-1.5, 1.5)  # ry away from gimbal lock
    assert_close(ref.frame_transform(p), rpy_textbook(*p), rtol=1e-14, what="frame_transform")
    assert_close(ref.frame_params(ref.frame_transform(p)), p, rtol=1e-12, what="frame_params")
    locked = p.copy()
    locked[4] = np.pi / 2
    T_locked = ref.frame_transform(locked)
    assert_close(ref.frame_transform(ref.frame_params(T_locked)), T_locked, rtol=1e-12, what="gimbal lock")


# --- chain structure against textbook products ------------------------------------------------
@given(cases(nominal=True))
def test_zero_beta_is_plain_dh_and_mdh(case):
    """With beta = 0 (and no base or tool) each link is exactly the textbook DH / MDH matrix."""
    T = ref.fk(*case.chain, case.params, case.q)
    for i in range(case.q.shape[0]):
        expected = np.eye(4)
        for j, convention in enumerate(case.conventions):
            alpha, a, d, theta, _ = joint_values(case, i, j)
            expected = expected @ (dh_textbook if convention == "dh" else mdh_textbook)(alpha, a, d, theta)
        assert_close(T[i], expected, rtol=1e-12, what=f"sample {i}")


@given(cases())
def test_chain_is_base_links_with_beta_and_tool(case):
    """``Base · prod Link_i · Tool`` with Hayati's Ry(beta) in its place in each link."""
    T_flange = ref.fk(*case.chain, case.params, case.q)
    T_tool = ref.fk(*case.chain, case.params, case.q, tool=True)
    base, tool = base_tool(case)
    for i in range(case.q.shape[0]):
        expected = rpy_textbook(*base)
        for j, convention in enumerate(case.conventions):
            alpha, a, d, theta, beta = joint_values(case, i, j)
            if convention == "dh":
                expected = expected @ dh_textbook(alpha, a, d, theta) @ rot_y(beta)
            else:
                expected = expected @ rot_x(alpha) @ trans(x=a) @ rot_y(beta) @ rot_z(theta) @ trans(z=d)
        assert_close(T_flange[i], expected, rtol=1e-12, what=f"flange, sample {i}")
        assert_close(T_tool[i], expected @ rpy_textbook(*tool), rtol=1e-12, what=f"tool, sample {i}")


@given(cases(conventions=("dh",)))
def test_dh_regroups_as_mdh_with_last_link_in_the_tool(case):
    """``Rz Tz · [Tx Rx Ry · Rz Tz] · ...``: the MDH chain whose joint i takes alpha, a, beta of
    DH joint i-1 (joint 1 none), times ``Tx(aN) Rx(alphaN) Ry(betaN) · Tool``, is the DH chain."""
    n = case.n
    dh = case.params[: 5 * n].reshape(n, 5)  # alpha, a, d, theta, beta
    mdh = dh.copy()
    mdh[0, [0, 1, 4]] = 0.0
    mdh[1:, [0, 1, 4]] = dh[:-1, [0, 1, 4]]
    p_mdh = case.params.copy()
    p_mdh[: 5 * n] = mdh.ravel()
    alpha_n, a_n, _, _, beta_n = dh[-1]
    _, tool = base_tool(case)
    moved = trans(x=a_n) @ rot_x(alpha_n) @ rot_y(beta_n) @ rpy_textbook(*tool)
    T_dh = ref.fk(case.conventions, case.kinds, case.params, case.q, tool=True)
    T_mdh = ref.fk(["mdh"] * n, case.kinds, p_mdh, case.q)
    assert_close(T_mdh @ moved, T_dh, rtol=1e-12, what="MDH regrouping")


# --- measurement models -----------------------------------------------------------------------
@given(cases(), st.sampled_from(MEASUREMENTS))
def test_residuals_are_observation_minus_prediction(case, measurement):
    y = observations(case, measurement)
    r = ref.residuals(*case.chain, measurement, case.params, case.q, y)
    h = ref.predict(*case.chain, measurement, case.params, case.q)
    T = ref.fk(*case.chain, case.params, case.q, tool=True)
    if measurement == "pose":
        assert_close(h[:, :3], T[:, :3, 3], what="predicted position")
        assert_close(ref.matrix_from_quaternion(h[:, 3:]), T[:, :3, :3], rtol=1e-13, what="predicted rotation")
        assert np.all(h[:, 3] >= 0)
        assert_close(r[:, :3], y[:, :3] - h[:, :3], what="position residual")
        # exp(e) · R = R_meas
        R_meas = ref.matrix_from_quaternion(y[:, 3:])
        assert_close(ref.so3_exp(r[:, 3:]) @ T[:, :3, :3], R_meas, rtol=1e-12, what="rotation residual")
        assert_close(ref.residuals(*case.chain, measurement, case.params, case.q, h), np.zeros_like(r), what="r(h)")
    else:
        assert_close(r, y - h, what="r = y - h")
    if measurement == "position":
        assert_close(h, T[:, :3, 3], what="position = tool origin")
    if measurement == "cable":
        s = 5 * case.n + 12
        anchor, offset, scale = case.params[s : s + 3], case.params[s + 3], case.params[s + 4]
        assert_close(h[:, 0], scale * np.linalg.norm(T[:, :3, 3] - anchor, axis=1) - offset, what="cable")


def numeric_jacobian(case: Case, measurement: str, y: np.ndarray) -> np.ndarray:
    """``-dr/dparams`` by central differences: steps of 1e-3 mm and 1e-6 rad, which keep both the
    truncation and the rounding error (residuals up to ~1e4 mm) near 1e-9 of each column."""
    step = {"mm": 1e-3, "rad": 1e-6, "1": 1e-6}
    columns = []
    for k, unit in enumerate(ref.param_units(case.n)):
        h = step[unit]
        plus, minus = case.params.copy(), case.params.copy()
        plus[k] += h
        minus[k] -= h
        r_plus = ref.residuals(*case.chain, measurement, plus, case.q, y)
        r_minus = ref.residuals(*case.chain, measurement, minus, case.q, y)
        columns.append(-(r_plus - r_minus).ravel() / (2 * h))
    return np.column_stack(columns)


@given(cases(), st.sampled_from(MEASUREMENTS), st.sampled_from([1e-8, 0.3, 1.5]))
def test_analytic_jacobian_matches_central_differences(case, measurement, max_angle):
    y = observations(case, measurement, max_angle=max_angle)
    if measurement == "cable":
        s = 5 * case.n + 12
        p = ref.fk(*case.chain, case.params, case.q, tool=True)[:, :3, 3]
        # Away from the kink at the anchor, where central differences need h << distance.
        assume(np.all(np.linalg.norm(p - case.params[s : s + 3], axis=1) > 50.0))
    J = ref.jacobian(*case.chain, measurement, case.params, case.q, y=y)
    assert J.shape == (case.q.shape[0] * ref.MEASUREMENTS[measurement][1], case.params.size)
    assert_jacobian_close(J, numeric_jacobian(case, measurement, y), measurement, rtol=1e-6, what=measurement)


@given(cases(), st.sampled_from(MEASUREMENTS))
def test_jacobian_columns_select(case, measurement):
    y = observations(case, measurement)
    cols = case.rng.permutation(case.params.size)[: case.rng.integers(0, 8)].tolist()
    full = ref.jacobian(*case.chain, measurement, case.params, case.q, y=y)
    some = ref.jacobian(*case.chain, measurement, case.params, case.q, y=y, cols=cols)
    assert some.shape == (full.shape[0], len(cols))
    np.testing.assert_array_equal(some, full[:, cols])


@given(cases(max_samples=4), st.sampled_from(MEASUREMENTS))
def test_sigma_residuals_set_the_chosen_parameters(case, measurement):
    y = observations(case, measurement)
    cols = sorted(case.rng.choice(case.params.size, size=3, replace=False).tolist())
    sigmas = case.params[cols] + case.rng.normal(0, 0.01, (5, 3))
    out = ref.sigma_residuals(*case.chain, measurement, case.params, cols, sigmas, case.q, y)
    assert out.shape == (5, y.shape[0] * ref.MEASUREMENTS[measurement][1])
    for s, sigma in enumerate(sigmas):
        p = case.params.copy()
        p[cols] = sigma
        assert_close(out[s], ref.residuals(*case.chain, measurement, p, case.q, y).ravel(), rtol=1e-14, what=f"sigma {s}")


# --- unscented transform ----------------------------------------------------------------------
sigma_settings = st.tuples(seeds, st.integers(1, 8), st.floats(0.1, 1.0), st.floats(0.0, 3.0), st.floats(0.0, 3.0))


@given(sigma_settings)
def test_sigma_points_reproduce_mean_and_covariance(setting):
    seed, n, alpha, beta, kappa = setting
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1000, 1000, n)
    P = random_spd(rng, n, scales=rng.uniform(1e-3, 10, n))
    sigmas, Wm, Wc = ref.merwe_sigma_points(x, P, alpha, beta, kappa)
    assert sigmas.shape == (2 * n + 1, n) and Wm.shape == Wc.shape == (2 * n + 1,)
    assert_close(Wm.sum(), 1.0, rtol=1e-13, what="sum Wm")
    assert_close(Wm @ sigmas, x, rtol=1e-12, what="sum Wm chi")
    d = sigmas - x
    assert_close(np.einsum("s,si,sj->ij", Wc, d, d), P, rtol=1e-12, what="sum Wc (chi - x)(chi - x)^T")
    lam = alpha**2 * (n + kappa) - n
    assert_close(Wc[0] - Wm[0], 1 - alpha**2 + beta, rtol=1e-12, what="Wc0 - Wm0")
    assert_close(Wm[0], lam / (n + lam), rtol=1e-12, what="Wm0")


@given(sigma_settings, st.integers(1, 5))
def test_unscented_transform_of_a_linear_map_is_exact(setting, k):
    seed, n, alpha, beta, kappa = setting
    rng = np.random.default_rng(seed)
    x = rng.normal(0, 10, n)
    P = random_spd(rng, n)
    A, b = rng.normal(size=(k, n)), rng.normal(size=k)
    sigmas, Wm, Wc = ref.merwe_sigma_points(x, P, alpha, beta, kappa)
    mean, cov, cross = ref.unscented_transform(sigmas, sigmas @ A.T + b, Wm, Wc)
    assert_close(mean, A @ x + b, rtol=1e-11, what="mean")
    assert_close(cov, A @ P @ A.T, rtol=1e-10, what="cov")
    assert_close(cross, P @ A.T, rtol=1e-10, what="cross")


@given(sigma_settings)
def test_sigma_points_match_filterpy(setting):
    filterpy_kalman = pytest.importorskip("filterpy.kalman")
    seed, n, alpha, beta, kappa = setting
    rng = np.random.default_rng(seed)
    x, P = rng.normal(size=n), random_spd(rng, n)
    theirs = filterpy_kalman.MerweScaledSigmaPoints(n, alpha, beta, kappa)
    sigmas, Wm, Wc = ref.merwe_sigma_points(x, P, alpha, beta, kappa)
    assert_close(sigmas, theirs.sigma_points(x, P), rtol=1e-12, what="sigmas")
    assert_close(Wm, theirs.Wm, rtol=1e-12, what="Wm")
    assert_close(Wc, theirs.Wc, rtol=1e-12, what="Wc")


def test_sigma_points_reject_indefinite_covariance():
    with pytest.raises(np.linalg.LinAlgError, match="positive definite"):
        ref.merwe_sigma_points(np.zeros(2), np.array([[1.0, 2.0], [2.0, 1.0]]), 0.5, 2.0, 0.0)


# --- cable start, damped solve, identifiability, covariance -----------------------------------
@given(seeds, st.integers(5, 40))
def test_cable_initial_guess_is_exact_on_noiseless_data(seed, m):
    rng = np.random.default_rng(seed)
    anchor = rng.uniform(-3000, 3000, 3)
    offset = rng.uniform(0, 500)
    p = rng.uniform(-1500, 1500, (m, 3)) + np.array([1000.0, 0, 800])
    L = np.linalg.norm(p - anchor, axis=1) - offset
    got_anchor, got_offset = ref.cable_initial_guess(p, L)
    # One scale for all four unknowns (mm): the offset is as accurate as the anchor.
    assert_close(np.r_[got_anchor, got_offset], np.r_[anchor, offset], rtol=1e-9, what="anchor, offset")


def test_cable_initial_guess_reports_degenerate_points():
    with pytest.raises(np.linalg.LinAlgError, match="anchor"):
        ref.cable_initial_guess(np.tile([100.0, 0, 0], (8, 1)), np.full(8, 50.0))


@given(seeds, st.integers(1, 8), st.sampled_from(["marquardt", "identity"]))
def test_solve_damped_without_damping_is_the_least_squares_solution(seed, n, damping):
    rng = np.random.default_rng(seed)
    J = rng.normal(size=(n + 5, n)) * rng.uniform(0.01, 1000, n)
    r = rng.normal(size=n + 5)
    delta, method = ref.solve_damped(J, r, 0.0, damping)
    assert method == "cholesky"
    assert_close(delta, np.linalg.solve(J.T @ J, J.T @ r), rtol=1e-9, what="delta")
    assert_close(delta, np.linalg.lstsq(J, r, rcond=None)[0], rtol=1e-9, what="delta vs lstsq")


@given(seeds, st.integers(1, 8), st.floats(1e-6, 1e3), st.sampled_from(["marquardt", "identity"]))
def test_solve_damped_with_damping(seed, n, lam, damping):
    rng = np.random.default_rng(seed)
    J, r = rng.normal(size=(n + 3, n)), rng.normal(size=n + 3)
    A = J.T @ J
    D = np.diag(np.diag(A)) if damping == "marquardt" else np.eye(n)
    delta, method = ref.solve_damped(J, r, lam, damping)
    assert method == "cholesky"
    assert_close(delta, np.linalg.solve(A + lam * D, J.T @ r), rtol=1e-10, what="delta")


@given(seeds, st.integers(2, 8))
def test_solve_damped_falls_back_to_minimum_norm_svd(seed, n):
    rng = np.random.default_rng(seed)
    J = rng.normal(size=(n + 4, n))
    J[:, -1] = 2.0 * J[:, 0]  # rank deficient
    r = rng.normal(size=n + 4)
    delta, method = ref.solve_damped(J, r, 0.0)
    assert method == "svd"
    assert_close(delta, np.linalg.pinv(J) @ r, rtol=1e-8, what="minimum-norm delta")


def hsr_jr680() -> Case:
    """The paper's HSR JR680 (Table I), nominal: no base rotation, so base_rz and theta1 turn
    about the same axis and base_z and d1 move along it."""
    table = [(-90, 250, 653.5, 0), (0, 900, 0, -90), (90, -205, 0, 180), (-90, 0, 1030.2, 0), (90, 0, 0, 90), (0, 0, 200.6, 0)]
    params = np.zeros(5 * 6 + 17)
    for j, (alpha, a, d, theta) in enumerate(table):
        params[5 * j : 5 * j + 4] = math.radians(alpha), a, d, math.radians(theta)
    params[-1] = 1.0
    params[5 * 6 + 6 : 5 * 6 + 9] = 12.0, -30.0, 95.0  # tool point
    rng = np.random.default_rng(1)
    kinds = ["revolute"] * 6
    return Case(["dh"] * 6, kinds, params, random_q(rng, kinds, 30), rng)


def test_identifiability_finds_theta1_base_rz_redundancy_and_dead_columns():
    """Every parameter but the betas, from positions: theta1 ~ base_rz and d1 ~ base_z (same
    axis), the sensor block and the tool's rotation have no effect on a point."""
    case = hsr_jr680()
    names = [n for n in ref.param_names(6) if not n.startswith("beta")]
    cols = [ref.param_names(6).index(n) for n in names]
    J = ref.jacobian(*case.chain, "position", case.params, case.q, cols=cols)
    result = ref.identifiability(J)
    dead = ["tool_rx", "tool_ry", "tool_rz", "anchor_x", "anchor_y", "anchor_z", "cable_offset", "cable_scale"]
    assert result["no_effect"] == [names.index(n) for n in dead]
    assert result["rank"] == len(result["identifiable"]) < len(names) - len(dead)
    redundant = dict(result["redundant"])
    assert sorted(result["identifiable"] + list(redundant) + result["no_effect"]) == list(range(len(names)))
    for a, b in (("theta1", "base_rz"), ("d1", "base_z")):
        kept, other = names.index(a), names.index(b)
        if other in result["identifiable"]:
            kept, other = other, kept
        assert kept in result["identifiable"] and other not in result["identifiable"]
        [(partner, coef)] = redundant[other]
        assert partner == kept and coef == pytest.approx(1.0, abs=1e-9)
    s = result["singular_values"]
    assert np.all(np.diff(s) <= 0)
    assert result["condition_number"] == pytest.approx(s[0] / s[result["rank"] - 1])
    assert_close(result["column_norms"], np.linalg.norm(J, axis=0), rtol=1e-14, what="column norms")


def test_identifiability_of_duplicate_and_zero_columns():
    J = np.array([[1.0, 0, 2, 0], [0, 1, 0, 0], [1, 1, 2, 0], [2, -1, 4, 0]])
    result = ref.identifiability(J)
    assert result["rank"] == 2 and result["no_effect"] == [3]
    assert sorted(result["identifiable"]) in ([0, 1], [1, 2])
    [(col, partners)] = result["redundant"]
    assert col in (0, 2) and len(partners) == 1 and partners[0][0] == 2 - col
    assert partners[0][1] == pytest.approx(1.0, abs=1e-12)
    assert result["condition_number"] == pytest.approx(result["singular_values"][0] / result["singular_values"][1])


@given(seeds, st.integers(1, 6))
def test_covariance_of_a_linear_fit(seed, n):
    rng = np.random.default_rng(seed)
    m = n + 10
    J = rng.normal(size=(m, n)) * rng.uniform(0.01, 1000, n)
    r = rng.normal(size=m)
    cov, sigma2, dof, rank = ref.covariance(J, r)
    assert (dof, rank) == (m - n, n)
    assert sigma2 == pytest.approx(r @ r / (m - n), rel=1e-14)
    expected = sigma2 * np.linalg.inv(J.T @ J)
    scale = np.sqrt(np.outer(np.diag(expected), np.diag(expected)))
    assert_close(cov / scale, expected / scale, rtol=1e-9, what="cov / sqrt(cov_ii cov_jj)")


def test_covariance_needs_degrees_of_freedom():
    with pytest.raises(ValueError, match="degrees of freedom"):
        ref.covariance(np.eye(3), np.ones(3))


# --- input checking ---------------------------------------------------------------------------
def test_bad_inputs_name_the_argument():
    chain = (["dh"] * 6, ["revolute"] * 6)
    p = random_params(np.random.default_rng(0), 6)
    q = np.zeros((3, 6))
    with pytest.raises(ValueError, match=r"`q` must have shape \(m, 6\); got \(3, 7\)"):
        ref.fk(*chain, p, np.zeros((3, 7)))
    with pytest.raises(ValueError, match=r"`params` must have shape \(47,\); got \(46,\)"):
        ref.fk(*chain, p[:-1], q)
    bad = p.copy()
    bad[4] = np.nan
    with pytest.raises(ValueError, match="`params` must be finite"):
        ref.predict(*chain, "position", bad, q)
    with pytest.raises(ValueError, match=r"`y` must have shape \(3, 3\)"):
        ref.residuals(*chain, "position", p, q, np.zeros((3, 2)))
    with pytest.raises(ValueError, match="`measurement`"):
        ref.predict(*chain, "laser", p, q)
    with pytest.raises(ValueError, match="`y`"):
        ref.jacobian(*chain, "pose", p, q)
    with pytest.raises(ValueError, match="`y`.*unit norm"):
        ref.residuals(*chain, "pose", p, q, np.zeros((3, 7)))
    with pytest.raises(ValueError, match="`cols`"):
        ref.jacobian(*chain, "position", p, q, cols=[47])
    with pytest.raises(ValueError, match="`conventions`"):
        ref.fk(["xyz"] * 6, chain[1], p, q)
    with pytest.raises(ValueError, match="`kinds`"):
        ref.fk(chain[0], ["revolute"] * 5, p, q)
    with pytest.raises(ValueError, match="`lam`"):
        ref.solve_damped(np.eye(2), np.ones(2), -1.0)
    with pytest.raises(ValueError, match="`damping`"):
        ref.solve_damped(np.eye(2), np.ones(2), 0.0, "newton")
    with pytest.raises(ValueError, match="`tol`"):
        ref.identifiability(np.eye(2), tol=2.0)
    with pytest.raises(ValueError, match="`P`"):
        ref.merwe_sigma_points(np.zeros(2), np.eye(3), 0.5, 2.0, 0.0)
    with pytest.raises(ValueError, match=r"`sigmas_x` must have shape \(3, n\)"):
        ref.unscented_transform(np.zeros((6, 1)), np.zeros((3, 1)), np.ones(3) / 3, np.ones(3) / 3)
    with pytest.raises(ValueError, match="`p`"):
        ref.cable_initial_guess(np.zeros((4, 3)), np.zeros(4))
    # Integer arrays are numbers like any other.
    assert ref.fk(*chain, p, np.zeros((2, 6), dtype=int)).shape == (2, 4, 4)
