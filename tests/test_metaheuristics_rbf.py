"""The paper's comparison methods M2 (BAS), M4 (PSO), M7 (DE) and M5 (RBF corrector)."""

from __future__ import annotations

import numpy as np
import pytest

import robocal
from robocal.calibration import Problem, metrics
from robocal.calibration.lm import levenberg_marquardt
from robocal.calibration.metaheuristics import bas, de, pso, search_box
from robocal.calibration.rbf import rbf
from robocal.data.splits import random_split
from robocal.simulation import simulate

# The simulator's tool point is (30, -10, 80) mm; with it known, the start (nominal kinematics +
# closed-form anchor) lies within the default ±2 mm / ±0.2° box of the optimum, on enough samples
# to determine it (on 80, the optimum of most seeds' robots lies outside: the noise's fit).
TOOL = {"tool_x": 30.0, "tool_y": -10.0, "tool_z": 80.0}
SMALL = dict(max_iter=60)  # short budgets keep the suite fast


@pytest.fixture(scope="module")
def problem():
    data, _ = simulate("hsr-jr680", "cable", samples=400, seed=4)
    return Problem.build(robocal.robot("hsr-jr680").with_params(**TOOL), data)


def test_the_optimum_lies_in_the_default_box_around_the_start(problem):
    """The premise of the methods' comparison: their search box holds the LM optimum."""
    lower, upper = search_box(problem)
    x = levenberg_marquardt(problem).x
    assert np.all((lower <= x) & (x <= upper)), [n for n, v, lo, hi in zip(problem.names, x, lower, upper) if not lo <= v <= hi]


def test_default_box_follows_units_and_mapping_overrides(problem):
    lower, upper = search_box(problem)
    half = (upper - lower) / 2
    units = [problem.robot.param_units[k] for k in problem.free]
    assert np.allclose(half[[u == "mm" for u in units]], 2.0)
    assert np.allclose(half[[u == "rad" for u in units]], np.radians(0.2))
    lower, upper = search_box(problem, {"mm": 5.0, "a2": 1.0})
    assert (upper - lower)[problem.names.index("a2")] == pytest.approx(2.0)
    assert (upper - lower)[problem.names.index("d4")] == pytest.approx(10.0)


@pytest.mark.parametrize("method, options", [(bas, dict(max_iter=1500)), (pso, SMALL), (de, dict(max_iter=150))])
def test_metaheuristics_lower_the_cost_and_are_deterministic(problem, method, options):
    # The start (nominal kinematics, fitted set-up and tool) is already good; with these short
    # budgets in 23 dimensions the methods improve on it without closing the gap to the LM
    # optimum (as the paper's Table VIII shows for M2/M4/M7 against M6). BAS's first steps (half
    # the box) land worse than the start: after 600 iterations the start was still its best point
    # for 4 of 10 beetle seeds on this problem, after 1 500 for none (cost 14.7 -> 2.2-6.3).
    start = problem.cost(problem.x0)
    a = method(problem, seed=7, **options)
    b = method(problem, seed=7, **options)
    assert a.success and a.message
    assert a.cost < start
    assert np.array_equal(a.x, b.x)
    assert a.history[0] <= start and np.all(np.diff(a.history) <= 0)  # best-so-far per iteration
    assert len(a.history) == a.nit + 1 and a.nfev > a.nit
    lower, upper = search_box(problem)
    assert np.all((lower <= a.x) & (a.x <= upper))


def test_de_reaches_the_lm_optimum_on_a_small_problem(problem):
    data, _ = simulate("hsr-jr680", "cable", samples=80, seed=4)
    small = Problem.build(problem.robot, data, mask=["a2", "d4", "theta2", "cable_offset"])
    assert len(small.free) == 4
    reference = levenberg_marquardt(small)
    # Widen the box so that it surely contains the LM optimum.
    fit = de(small, bounds={"mm": 10.0, "rad": np.radians(1.0)}, max_iter=300, seed=1)
    assert fit.cost == pytest.approx(reference.cost, rel=1e-3)
    assert np.allclose(fit.x, reference.x, atol=0.05 * np.maximum(reference.std, 1e-9) + 1e-9)


def test_rbf_corrects_the_nominal_model_and_generalises():
    data, _ = simulate("hsr-jr680", "cable", samples=400, seed=2)
    train_idx, test_idx = random_split(len(data), test_fraction=0.25, seed=0)
    train, test = data.subset(train_idx), data.subset(test_idx)
    p = Problem.build(robocal.robot("hsr-jr680").with_params(**TOOL), train)
    fit = rbf(p)
    assert np.array_equal(fit.x, p.x0) and "not identified" in fit.message
    nominal_train = metrics(p.residuals(p.x0), "cable")["rmse"]
    nominal_test = metrics(p.with_data(test).residuals(p.x0), "cable")["rmse"]
    corrected_test = metrics(fit.corrected_residuals(test), "cable")["rmse"]
    assert fit.metrics["train"]["rmse"] < 0.5 * nominal_train
    assert corrected_test < 0.7 * nominal_test
    # A Problem works as well as a Dataset, and the correction is additive on the residual.
    assert np.allclose(fit.corrected_residuals(p.with_data(test)), fit.corrected_residuals(test))
    r_nom = p.with_data(test).residuals(p.x0)
    assert np.allclose(r_nom - fit.predict_correction(test.q).ravel(), fit.corrected_residuals(test))
    assert fit.to_dict()["corrector"]["kind"] == "rbf"
