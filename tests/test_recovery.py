"""The core end to end: simulated measurements of a perturbed robot, a damped Gauss-Newton
identification with the core's Jacobian, solver and identifiability, and the recovered
parameters checked against the truth within the covariance the core reports."""

from __future__ import annotations

import numpy as np
import pytest

import robocal
from robocal import kernels


def simulate(r: robocal.Robot, measurement: str, m: int, noise: float, seed: int):
    """Joint configurations spread over the limits, a true robot (nominal + ~0.5 mm / 0.05 deg
    errors on the identifiable parameters) and its noisy observations."""
    rng = np.random.default_rng(seed)
    lo, hi = np.array([j.limits for j in r.joints]).T
    q = rng.uniform(np.maximum(lo, -2.5), np.minimum(hi, 2.5), size=(m, r.n_joints))
    start = r.with_params(
        tool_x=30.0,
        tool_y=-10.0,
        tool_z=80.0,
        anchor_x=1800.0,
        anchor_y=400.0,
        anchor_z=-300.0,
        cable_offset=900.0,
        base_x=2000.0,
        base_y=-500.0,
        base_z=100.0,
        base_rz=0.4,
    )
    cols = np.flatnonzero(r.default_mask(measurement))
    ident = kernels.identifiability(start.jacobian(measurement, q, y=start.predict(measurement, q), cols=cols))
    free = cols[ident["identifiable"]]
    true = start.params.copy()
    units = np.array(r.param_units)[free]
    true[free] += np.where(units == "mm", rng.normal(0, 0.5, free.size), np.radians(rng.normal(0, 0.05, free.size)))
    y = start.predict(measurement, q, params=true)
    if measurement == "cable":
        y = y + rng.normal(0, noise, y.shape)
    else:
        y[:, :3] += rng.normal(0, noise, (m, 3))
    return q, y, start.params, true, free


def gauss_newton(r, measurement, q, y, params, free, iterations=8):
    params = params.copy()
    for _ in range(iterations):
        res = r.residuals(measurement, q, y, params=params).ravel()
        step, _ = kernels.solve_damped(r.jacobian(measurement, q, y=y, params=params, cols=free), res, lam=0.0)
        params[free] += step
    J = r.jacobian(measurement, q, y=y, params=params, cols=free)
    res = r.residuals(measurement, q, y, params=params).ravel()
    return params, kernels.covariance(J, res)


@pytest.mark.parametrize("name", ["hsr-jr680", "abb-irb120", "ur10"])
@pytest.mark.parametrize("measurement", ["cable", "position"])
def test_identified_parameters_match_the_truth_within_their_uncertainty(name, measurement):
    r = robocal.robot(name)
    noise = 0.03 if measurement == "cable" else 0.02
    q, y, start, true, free = simulate(r, measurement, 400, noise, seed=11)
    est, (cov, sigma2, dof, rank) = gauss_newton(r, measurement, q, y, start, free)
    assert rank == free.size
    assert np.sqrt(sigma2) == pytest.approx(noise, rel=0.15)  # the residual reaches the noise floor
    z = (est[free] - true[free]) / np.sqrt(np.diag(cov))
    # Normalised errors of a correct estimator with a correct covariance: N(0, 1).
    assert np.max(np.abs(z)) < 4.5, dict(zip(np.array(r.param_names)[free], np.round(z, 2)))
    assert 0.5 < np.sqrt(np.mean(z**2)) < 1.6


def test_pose_data_recover_base_and_tool_frames():
    r = robocal.robot("ur10")
    rng = np.random.default_rng(5)
    q = rng.uniform(-2.5, 2.5, size=(300, 6))
    start = r.with_params(base_x=1000.0, base_rz=0.3, tool_z=50.0)
    true = start.with_params(base_x=1000.6, base_y=-0.4, base_rz=0.3012, tool_x=0.3, tool_z=50.2, tool_ry=0.002).params
    y = start.predict("pose", q, params=true)
    cols = np.flatnonzero(r.default_mask("pose"))
    free = cols[kernels.identifiability(start.jacobian("pose", q, y=y, cols=cols))["identifiable"]]
    est, (cov, sigma2, dof, rank) = gauss_newton(r, "pose", q, y, start.params, free)
    np.testing.assert_allclose(r.residuals("pose", q, y, params=est), 0.0, atol=1e-8)
    for name in ("base_x", "base_y", "tool_ry"):  # not redundant with any DH parameter of the UR10
        assert r.index(name) in free, name
        assert est[r.index(name)] == pytest.approx(true[r.index(name)], abs=1e-6), name
    # base_rz and theta1 turn about the same axis: only their sum is identifiable, and recovered.
    pair = [r.index("base_rz"), r.index("theta1")]
    assert len(set(pair) & set(free)) == 1
    assert est[pair].sum() == pytest.approx(true[pair].sum(), abs=1e-9)
