"""The Rust UKF sweep (`Chain.ukf_sweep`) against its NumPy twin (`reference.ukf_sweep`)."""

from __future__ import annotations

import numpy as np
import pytest

import robocal
from robocal import reference as ref
from robocal.calibration import Problem
from robocal.exceptions import NotPositiveDefiniteError, ShapeError
from robocal.simulation import simulate


@pytest.mark.parametrize("robot, measurement", [("hsr-jr680", "cable"), ("ur10", "position"), ("abb-irb120", "pose")])
def test_rust_sweep_equals_the_numpy_twin(robot, measurement):
    data, _ = simulate(robot, measurement, samples=25, seed=5)
    r = robocal.robot(robot)
    p = Problem.build(r, data)
    n, k = len(p.free), {"cable": 1, "position": 3, "pose": 6}[measurement]
    rng = np.random.default_rng(0)
    A = rng.normal(size=(n, n)) * 1e-2
    P = A @ A.T + np.eye(n) * 1e-4
    Q, R = np.eye(n) * 1e-10, np.eye(k) * 4e-4
    x0 = p.x0 + rng.normal(0, 1e-3, n)
    conv, kinds = [j.convention for j in r.joints], [j.kind for j in r.joints]
    x_rust, P_rust = r.chain.ukf_sweep(measurement, p.start, p.free.tolist(), data.q, data.y, x0, P, Q, R, 0.1, 2.0, 0.0)
    x_twin, P_twin = ref.ukf_sweep(conv, kinds, measurement, p.start, p.free, data.q, data.y, x0, P, Q, R, 0.1, 2.0, 0.0)
    np.testing.assert_allclose(x_rust, x_twin, rtol=0, atol=1e-9 * (1 + np.abs(x_twin).max()))
    np.testing.assert_allclose(P_rust, P_twin, rtol=1e-7, atol=1e-12 * np.abs(P_twin).max())


def test_sweep_errors_name_the_problem():
    data, _ = simulate("hsr-jr680", "cable", samples=5, seed=1)
    r = robocal.robot("hsr-jr680")
    cols = [1, 4]
    with pytest.raises(NotPositiveDefiniteError, match="before sample 0"):
        r.chain.ukf_sweep("cable", r.params, cols, data.q, data.y, r.params[cols], -np.eye(2), np.zeros((2, 2)), np.eye(1), 0.1, 2.0, 0.0)
    with pytest.raises(ShapeError, match="`R` must have shape"):
        r.chain.ukf_sweep("cable", r.params, cols, data.q, data.y, r.params[cols], np.eye(2), np.zeros((2, 2)), np.eye(3), 0.1, 2.0, 0.0)
