"""robocal.calibrate: the problem set-up, the production LM against scipy, the API, the CLI."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from scipy.optimize import least_squares

import robocal
from robocal.data import Dataset
from robocal.calibration import Problem, metrics
from robocal.calibration.problem import PLAUSIBLE
from robocal.calibration.lm import levenberg_marquardt
from robocal.exceptions import InvalidParameterError
from robocal.simulation import simulate


@pytest.fixture(scope="module")
def cable_data():
    data, truth = simulate("hsr-jr680", "cable", samples=300, seed=3)
    return data, truth


def test_metrics_follow_eq_28():
    m = metrics(np.array([3.0, -4.0, 0.0, 1.0]), "cable")
    assert m == {"rmse": pytest.approx(np.sqrt(26 / 4)), "mae": 2.0, "max": 4.0, "n": 4}
    # Position: the per-sample error is the Euclidean norm.
    assert metrics(np.array([[3.0, 4.0, 0.0]]), "position")["max"] == 5.0


def test_problem_starts_from_closed_form_setup_and_names_what_it_fixes(cable_data):
    data, truth = cable_data
    p = Problem.build(robocal.robot("hsr-jr680"), data)
    # With nominal kinematics and no tool offset, the anchor and sensor zero already explain the
    # cable to well within the size of the still unknown tool offset (85 mm).
    anchorless = p.robot.residuals("cable", data.q, data.y, params=p.robot.params)
    assert np.sqrt(np.mean(p.residuals(p.x0) ** 2)) < 40.0 < np.sqrt(np.mean(anchorless**2))
    assert len(p.free) + len(p.fixed) == int(p.robot.default_mask("cable").sum())
    assert all(reason.startswith(("redundant with", "no effect")) for reason in p.fixed.values())


def test_position_start_fits_the_base_frame_and_lm_finishes_the_job():
    data, truth = simulate("ur10", "position", samples=100, seed=2)
    p = Problem.build(robocal.robot("ur10"), data)
    # The start (Kabsch base, tool point unknown) is within the tool offset's size (~85 mm) ...
    assert np.sqrt(np.mean(p.residuals(p.x0) ** 2)) < 85.0
    # ... and close enough for LM to reach the noise floor: sigma·sqrt(3) per sample.
    fit = levenberg_marquardt(p)
    sigma = truth["noise"]["sigma"]["value"]
    assert fit.success and fit.metrics["train"]["rmse"] == pytest.approx(sigma * np.sqrt(3), rel=0.25)


def test_the_set_up_takes_what_it_explains_alike_with_a_link_parameter():
    """A position sensor's tool point and theta6 (and the base's rz and z, theta1 and d1) explain
    the same: the set-up is kept and the link parameter stays nominal. Chosen by remaining norm,
    this draw kept theta6 and fixed a tool coordinate, and the clean fit put the start's tool error
    into theta6 (2.37 deg, "implausible")."""
    data, truth = simulate("hsr-jr680", "position", samples=600, seed=649)
    result = robocal.calibrate(data, robot="hsr-jr680")
    fixed = result.problem.fixed
    assert {"theta1", "d1", "theta6"} <= set(fixed) and not {"tool_x", "tool_y", "base_rz", "base_z"} & set(fixed)
    assert "tool_x" in fixed["theta6"] and "tool_y" in fixed["theta6"]
    assert result.implausible() == []
    assert result.metrics["test"]["rmse"] < 2 * truth["noise"]["sigma"]["value"] * np.sqrt(3)


def test_production_lm_reaches_the_scipy_optimum(cable_data):
    data, _ = cable_data
    p = Problem.build(robocal.robot("hsr-jr680"), data)
    ours = levenberg_marquardt(p, statistical_stop=False)
    ref = least_squares(p.residuals, p.x0, jac=lambda x: -p.jacobian(x), method="lm", xtol=1e-14, ftol=1e-14, gtol=1e-14)
    assert ours.success, ours.message
    assert ours.cost == pytest.approx(ref.cost, rel=1e-8)
    assert np.all(np.abs(ours.x - ref.x) < 1e-3 * ours.std)  # same optimum, to a thousandth of the uncertainty
    assert ours.metrics["train"]["rmse"] == pytest.approx(0.03, rel=0.2)  # the simulated noise floor


@pytest.mark.parametrize("robot, measurement", [("hsr-jr680", "cable"), ("ur10", "position"), ("abb-irb120", "pose")])
def test_statistical_stop_lands_within_the_uncertainty_of_the_full_optimum(robot, measurement):
    data, _ = simulate(robot, measurement, samples=400, seed=5)
    p = Problem.build(robocal.robot(robot), data)
    stopped = levenberg_marquardt(p)
    full = levenberg_marquardt(p, statistical_stop=False, max_nfev=5000)
    assert stopped.success and "within the noise" in stopped.message, stopped.message
    assert full.success and "within the noise" not in full.message
    assert stopped.nfev < full.nfev
    # Every parameter within a tenth of its standard deviation of the fully converged optimum,
    # and chi-square higher by less than the noise can tell apart.
    assert np.all(np.abs(stopped.x - full.x) < 0.1 * full.std)
    sigma2 = 2.0 * full.cost / (len(p.residuals(full.x)) - len(full.x))
    assert 2.0 * (stopped.cost - full.cost) / sigma2 < 0.1


def test_lm_converges_on_a_deliberately_flat_direction():
    """Narrow joint ranges (q6 constant, the others within ±5°, as in D1) and a joint-1 reading
    the geometric model cannot represent leave a long curved valley: the LM before geodesic
    acceleration used its 2000-evaluation budget here without converging. It must end with
    success in a few hundred evaluations, at the training error of the full convergence."""
    robot = robocal.robot("hsr-jr680")
    rng = np.random.default_rng(3)
    q = np.radians([5, -60, 200, -160, 40, 60]) + np.radians(rng.uniform(-5, 5, (600, 6))) * [1, 1, 1, 1, 1, 0]
    true = robot.with_params(a2=900.5, d4=1030.9, tool_z=60.0, anchor_x=1500.0, anchor_y=300.0, anchor_z=-200.0, cable_offset=950.0)
    L = true.predict("cable", q * [1.3, 1, 1, 1, 1, 1])[:, 0] + rng.normal(0.0, 0.01, 600)
    p = Problem.build(robot, Dataset(q=q, y=L[:, None], measurement="cable", robot="hsr-jr680"))
    fit = levenberg_marquardt(p)
    full = levenberg_marquardt(p, statistical_stop=False)
    assert fit.success and full.success, (fit.message, full.message)
    assert fit.nfev <= 300
    assert fit.metrics["train"]["rmse"] <= 1.001 * full.metrics["train"]["rmse"]


def test_the_residuals_build_evaluated_at_the_start_are_the_starts_and_taken_once(cable_data):
    """``Problem.build`` evaluates the residuals with the start's Jacobian; the fit's first
    ``residuals`` takes them (bit for bit what an evaluation gives), once."""
    p = Problem.build(robocal.robot("hsr-jr680"), cable_data[0])
    first = p.residuals(p.x0)
    assert "_start_residuals" not in vars(p)
    np.testing.assert_array_equal(first, p.residuals(p.x0))
    moved = Problem.build(robocal.robot("hsr-jr680"), cable_data[0])
    x = moved.x0 + 1e-3
    np.testing.assert_array_equal(moved.residuals(x), p.residuals(x))  # elsewhere: not the start's


def test_the_jacobian_build_evaluated_at_the_start_is_the_starts_and_c_ordered(cable_data):
    """The fit's first ``jacobian`` takes the free columns of the one ``Problem.build`` evaluated
    for the identifiability analysis: bit for bit what an evaluation gives, in C order (the core
    and the normal equations read rows)."""
    p = Problem.build(robocal.robot("hsr-jr680"), cable_data[0])
    first = p.jacobian(p.x0)
    assert "_start_jacobian" not in vars(p) and first.flags.c_contiguous
    np.testing.assert_array_equal(first, p.jacobian(p.x0))


def test_undetermined_gives_the_directions_of_an_svd_of_the_scaled_jacobian_itself():
    """``undetermined`` takes the SVD of ``J``'s triangular factor (n, n): the same singular
    values and directions (up to sign) as the SVD of ``J·diag(limits)`` (m, n), on narrow joint
    ranges that leave some combinations undetermined."""
    robot = robocal.robot("hsr-jr680")
    rng = np.random.default_rng(5)
    q = np.radians([5, -60, 200, -160, 40, 60]) + np.radians(rng.uniform(-3, 3, (400, 6))) * [1, 1, 1, 1, 1, 0]
    L = robot.with_params(anchor_x=1500.0, anchor_y=300.0, anchor_z=-200.0, cable_offset=950.0).predict("cable", q)[:, 0] + rng.normal(0.0, 0.05, 400)
    fit = levenberg_marquardt(Problem.build(robot, Dataset(q=q, y=L[:, None], measurement="cable", robot="hsr-jr680")))
    names = fit.problem.names
    got = fit.undetermined(shown=len(names))
    J, r = fit.problem.jacobian(fit.x), fit.problem.residuals(fit.x)
    limits = np.array([PLAUSIBLE.get(robot.param_units[k], 0.01) for k in fit.problem.free])
    _, s, Vt = np.linalg.svd(J * limits, full_matrices=False)
    std = np.sqrt(r @ r / (J.shape[0] - J.shape[1])) / s
    assert len(got) == int(np.sum(std > 1.0)) > 0
    for entry, want_std, v in zip(got, std[std > 1.0], Vt[std > 1.0]):
        assert entry["std"] == pytest.approx(want_std, rel=1e-8)
        w = np.array([entry["combination"][n] for n in names])
        np.testing.assert_allclose(np.sign(w @ v) * w, v, atol=1e-8)


def test_calibrate_api_result_json(cable_data, tmp_path):
    data, _ = cable_data
    result = robocal.calibrate(data, robot="hsr-jr680", method="lm", test_fraction=0.25, seed=1)
    doc = json.loads(json.dumps(result.to_dict()))
    assert doc["method"] == "lm" and doc["robot"] == "hsr-jr680" and doc["measurement"] == "cable"
    by_name = {p["name"]: p for p in doc["parameters"]}
    assert set(by_name["a2"]) == {"name", "unit", "nominal", "value", "deviation", "std"} and by_name["a2"]["unit"] == "mm"
    assert by_name["a2"]["std"] > 0 and by_name["beta1"]["std"] is None
    assert doc["metrics"]["train"]["n"] == 225 and doc["metrics"]["test"]["n"] == 75
    assert doc["metrics"]["test"]["rmse"] < 0.06
    again = robocal.calibrate(data, robot="hsr-jr680", method="lm", test_fraction=0.25, seed=1)
    np.testing.assert_array_equal(again.x, result.x)
    assert robocal.calibrate(data, robot="hsr-jr680", test_fraction=0.0).metrics["test"] is None


def test_calibrate_bad_use(cable_data):
    data, _ = cable_data
    with pytest.raises(InvalidParameterError, match="unknown method 'newton'"):
        robocal.calibrate(data, robot="hsr-jr680", method="newton")
    with pytest.raises(InvalidParameterError, match="test_fraction"):
        robocal.calibrate(data, robot="hsr-jr680", test_fraction=1.0)
    with pytest.raises(InvalidParameterError, match="joints"):
        robocal.calibrate(data, robot=robocal.Robot.from_dh("two", [(0, 100, 0, 0), (0, 100, 0, 0)]))


def test_cli_calibrate_writes_the_result(cable_data, tmp_path, capsys):
    from robocal.cli import main
    from robocal.data import write_canonical

    data, _ = cable_data
    csv = write_canonical(data, tmp_path / "d.csv")
    assert main(["calibrate", str(csv), "--robot", "hsr-jr680", "--out", str(tmp_path / "r.json")]) == 0
    doc = json.loads((tmp_path / "r.json").read_text())
    assert doc["metrics"]["test"]["rmse"] < 0.06
    out = capsys.readouterr().out
    assert "test:  RMSE" in out
    # the count of fixed parameters and the names listed agree (issue 52: "fixed 6" and four names)
    line = next(s for s in out.splitlines() if "parameters; fixed" in s)
    assert len(doc["fixed"]) > 4 and f"fixed {len(doc['fixed'])}:" in line
    assert all(f"{name} (" in line for name in doc["fixed"])
    assert main(["calibrate", str(tmp_path / "missing.csv"), "--robot", "hsr-jr680"]) == 2


def test_priors_pull_estimates_and_stay_out_of_the_metrics(cable_data):
    data, _ = cable_data
    r = robocal.robot("hsr-jr680")
    free = Problem.build(r, data)
    a2 = free.x0[free.names.index("a2")]
    # A tight prior pins a2 to a value 1 mm off; a loose one leaves the fit as it was.
    pinned = levenberg_marquardt(Problem.build(r, data, prior={"a2": (a2 + 1.0, 1e-4)}))
    loose = levenberg_marquardt(Problem.build(r, data, prior={"a2": (a2 + 1.0, 1e4)}))
    plain = levenberg_marquardt(free)
    assert pinned.x[free.names.index("a2")] == pytest.approx(a2 + 1.0, abs=1e-3)
    assert np.all(np.abs(loose.x - plain.x) < 1e-2 * plain.std)
    assert pinned.metrics["train"]["n"] == len(data)  # metrics are of the samples only
    assert pinned.metrics["train"]["rmse"] > plain.metrics["train"]["rmse"]
    # Kalman filters take the prior as their own: the UKF starts there and keeps a2 pinned too.
    from robocal.calibration.kalman import ukf

    assert ukf(Problem.build(r, data, prior={"a2": (a2 + 1.0, 1e-4)})).x[free.names.index("a2")] == pytest.approx(a2 + 1.0, abs=1e-3)


def test_prior_errors_name_the_parameter(cable_data):
    data, _ = cable_data
    r = robocal.robot("hsr-jr680")
    with pytest.raises(InvalidParameterError, match="prior on 'beta1', which is not estimated"):
        Problem.build(r, data, prior={"beta1": (0.0, 0.01)})
    with pytest.raises(InvalidParameterError, match="sigma > 0"):
        Problem.build(r, data, prior={"a2": (900.0, 0.0)})
    result = robocal.calibrate(data, robot="hsr-jr680", prior={"a2": (900.0, 0.5)}, test_fraction=0.25)
    assert result.metrics["test"]["n"] == 75


@pytest.mark.parametrize("method", ["lm", "lm-paper", "vslm", "ukf", "ekf", "pso"])
def test_bounds_hold_for_every_method(cable_data, method):
    data, _ = cable_data
    r = robocal.robot("hsr-jr680")
    plain = levenberg_marquardt(Problem.build(r, data))
    k = plain.problem.names.index("a2")
    # A limit that excludes the unconstrained optimum: the estimate must respect it.
    limit = plain.x[k] - 0.2
    options = {"max_iter": 20} if method == "pso" else {}
    fit = robocal.calibrate(data, robot=r, method=method, test_fraction=0.0, bounds={"a2": (limit - 5.0, limit)}, **options)
    assert fit.x[k] <= limit + 1e-12
    if method == "lm":
        assert fit.x[k] == pytest.approx(limit)  # the bound is active at the constrained optimum
        assert fit.cost > plain.cost


def test_bounds_errors(cable_data):
    data, _ = cable_data
    with pytest.raises(InvalidParameterError, match="bounds on 'a2' needs lower < upper"):
        Problem.build(robocal.robot("hsr-jr680"), data, bounds={"a2": (901.0, 899.0)})


def test_result_speaks_scipys_vocabulary_and_gives_the_calibrated_robot():
    data, truth = robocal.simulate("abb-irb120", "position", samples=200, seed=2)
    result = robocal.calibrate(data)
    assert result.status in (1, 2, 3) and result.success
    assert np.allclose(result.fun, result.problem.residuals(result.x)) and 0.5 * result.fun @ result.fun == pytest.approx(result.cost)
    robot = result.robot
    assert isinstance(robot, robocal.Robot) and np.array_equal(robot.params, result.params)
    assert np.allclose(robot.predict("position", data.q[:5]), result.problem.robot.predict("position", data.q[:5], result.params))
    stopped = robocal.calibrate(data, max_nfev=2)
    assert stopped.status == 0 and not stopped.success


def test_a_pose_fit_weighs_the_orientation_by_the_sensors_noise():
    """Rotation residuals (rad) enter the fit weighted by the ratio of the recorded position and
    orientation standard deviations (mm / deg), else by POSE_ROTATION_WEIGHT; data residuals and
    other measurements are unweighted."""
    from robocal.calibration.problem import POSE_ROTATION_WEIGHT, rotation_weight

    data, _ = simulate("ur10", "pose", samples=50, seed=4)
    problem = Problem.build(robocal.robot("ur10"), data)
    x = problem.x0
    raw, weighted = problem.data_residuals(x).reshape(-1, 6), problem.residuals(x)[: len(data) * 6].reshape(-1, 6)
    assert np.allclose(weighted[:, :3], raw[:, :3]) and np.allclose(weighted[:, 3:], POSE_ROTATION_WEIGHT * raw[:, 3:])
    J, J_raw = problem.jacobian(x), robocal.robot("ur10").jacobian("pose", data.q, y=data.y, params=problem.full(x), cols=problem.free)
    assert np.allclose(J[: len(data) * 6].reshape(len(data), 6, -1)[:, 3:], POSE_ROTATION_WEIGHT * J_raw.reshape(len(data), 6, -1)[:, 3:])
    recorded = replace(data, extra={**data.extra, "measurement_std": np.tile([0.01, 0.01, 0.01, 0.002, 0.002, 0.002], (len(data), 1))})
    assert np.isclose(rotation_weight(recorded), 0.01 / np.radians(0.002))  # ≈ 286 mm/rad
    position, _ = simulate("ur10", "position", samples=20, seed=4)
    assert rotation_weight(position) == 1.0


def test_build_places_a_cable_from_the_tool_points_it_checked(monkeypatch):
    """The nominal tool points that `check_observations` compares the cable lengths with are
    those the closed-form anchor is fitted to: `Problem.build` runs the forward kinematics for
    them once, and starts where `start_parameters` alone does."""
    from robocal.calibration.problem import start_parameters

    data, _ = simulate("hsr-jr680", "cable", samples=200, seed=5)
    r = robocal.robot("hsr-jr680")
    alone = start_parameters(r, data)
    calls, fkine = [], type(r).fkine
    monkeypatch.setattr(type(r), "fkine", lambda self, *args, **kw: calls.append(args) or fkine(self, *args, **kw))
    problem = Problem.build(r, data)
    assert len(calls) == 1
    np.testing.assert_array_equal(problem.start, alone)


def test_held_out_problem_checks_the_observations_once(monkeypatch):
    """The check of every sample before the split gives the training problem its configuration
    labels and tool points: the forward kinematics and the grouping run once, and the problem is
    the one `Problem.build` makes of the training samples alone."""
    from robocal.calibration import api
    from robocal.calibration import problem as problem_module

    data, _ = simulate("hsr-jr680", "cable", samples=200, seed=5)
    r = robocal.robot("hsr-jr680")
    calls, fkine, groups = [], type(r).fkine, problem_module.configuration_groups
    monkeypatch.setattr(type(r), "fkine", lambda self, *args, **kw: calls.append("fkine") or fkine(self, *args, **kw))
    for module in (api, problem_module):
        monkeypatch.setattr(module, "configuration_groups", lambda q: calls.append("groups") or groups(q))
    problem, train, test = api.held_out_problem(r, data, 0.25, 3)
    assert sorted(calls) == ["fkine", "groups"] and len(test) == 50
    monkeypatch.undo()
    alone = Problem.build(r, data.subset(train))
    np.testing.assert_array_equal(problem.start, alone.start)
    np.testing.assert_array_equal(problem.free, alone.free)
    assert problem.fixed == alone.fixed and problem._distinct[1] == alone._distinct[1] == 150
