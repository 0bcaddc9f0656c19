"""The measurement planner (``robocal plan``): better determined parameters than random poses,
the cell's constraints kept, an order that does not sweep a joint, bad input refused by name."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import robocal
from robocal.cli import main
from robocal.exceptions import InvalidParameterError, RobocalError
from robocal.planning import (
    Constraints,
    _i_blocks,
    _i_update,
    candidate_poses,
    d_optimal,
    i_bound,
    i_criterion,
    i_optimal,
    measuring_order,
    order_correlations,
    plan,
    workspace_weights,
    travel,
)
from robocal.simulation import CABLE_RANGE, RANGE_MARGIN, setup, simulate

SMALL = {"candidates": 1500, "seed": 1}


def test_d_optimal_beats_every_random_subset_of_a_linear_model():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(400, 2, 5)) * np.array([1.0, 0.2, 5.0, 1.0, 0.5])
    M0 = 1e-6 * np.eye(5)
    chosen = d_optimal(A, M0, 12)
    assert len(set(chosen.tolist())) == 12

    def logdet(idx):
        return np.linalg.slogdet(M0 + np.einsum("nkp,nkq->pq", A[idx], A[idx]))[1]

    best_random = max(logdet(rng.choice(400, 12, replace=False)) for _ in range(200))
    assert logdet(chosen) > best_random


def test_required_candidates_stay_in_the_design():
    rng = np.random.default_rng(1)
    A = rng.normal(size=(200, 1, 4))
    chosen = d_optimal(A, 1e-6 * np.eye(4), 8, required=[3, 7])
    assert {3, 7} <= set(chosen.tolist())


@pytest.mark.parametrize("k", [1, 3])
def test_the_i_criterions_rank_k_updates_match_a_fresh_computation(k):
    rng = np.random.default_rng(k)
    A = rng.normal(size=(120, k, 6))
    W = (lambda B: B @ B.T)(rng.normal(size=(6, 6)))
    M = np.eye(6) + np.einsum("nkp,nkq->pq", A[:10], A[:10])
    Minv = np.linalg.inv(M)
    S, T = _i_blocks(A, Minv, W)
    Minv, S, T = _i_update(A, Minv, W, S, T, 40, 1.0)
    Minv, S, T = _i_update(A, Minv, W, S, T, 3, -1.0)
    M += A[40].T @ A[40] - A[3].T @ A[3]
    fresh = _i_blocks(A, np.linalg.inv(M), W)
    np.testing.assert_allclose(Minv, np.linalg.inv(M), atol=1e-12)
    np.testing.assert_allclose(S, fresh[0], atol=1e-10)
    np.testing.assert_allclose(T, fresh[1], atol=1e-10)


def test_i_optimal_lowers_the_mean_prediction_variance_below_d_optimal_and_random_designs():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(400, 2, 5)) * np.array([1.0, 0.2, 5.0, 1.0, 0.5])
    W = np.diag([0.0, 4.0, 0.0, 1.0, 1.0])  # only some directions are predicted: D-optimality spends poses on the others too
    M0 = 1e-6 * np.eye(5)
    d = d_optimal(A, M0, 12)
    chosen = i_optimal(A, M0, W, 12, start=d)
    assert len(set(chosen.tolist())) == 12
    phi = i_criterion(A, M0, W, chosen)
    assert phi < 0.9 * i_criterion(A, M0, W, d)
    assert phi < min(i_criterion(A, M0, W, rng.choice(400, 12, replace=False)) for _ in range(200))
    assert i_criterion(A, M0, W, i_optimal(A, M0, W, 12)) < i_criterion(A, M0, W, d)  # from its own greedy start as well
    assert {3, 7} <= set(i_optimal(A, M0, W, 12, required=[3, 7]).tolist())
    least = i_bound(A, M0, W, 12)
    assert 0.5 * phi < least <= phi  # a lower bound of every design of 12, and not a vacuous one


def test_the_weights_eliminate_the_set_up():
    rng = np.random.default_rng(2)
    A = rng.normal(size=(300, 1, 4))
    A[:, 0, 3] = 2.0  # a reading offset, re-fitted on every session
    W = workspace_weights(A, ["a", "b", "c", "cable_offset"], ["cable_offset"])
    assert np.all(W[3] == 0.0) and np.all(W[:, 3] == 0.0)
    centred = A[:, 0, :3] - A[:, 0, :3].mean(axis=0)
    np.testing.assert_allclose(W[:3, :3], centred.T @ centred / 300, atol=1e-12)  # what an offset leaves: the spread about the mean


@pytest.mark.parametrize("robot,measurement", [("hsr-jr680", "cable"), ("ur10", "position")])
def test_planned_poses_determine_the_parameters_better_than_random_ones(robot, measurement):
    report = plan(robot, measurement, 30, **SMALL).report
    position = report["position"]
    assert position["before"]["rms_mm"] is None and report["undetermined"]["after"] == 0
    assert position["after"]["rms_mm"] < position["random"]["rms_mm"]
    assert position["after"]["max_mm"] < position["random"]["max_mm"]
    assert report["d_efficiency_random"] < 1.0
    after = np.array([p["after"] for p in report["parameters"]])
    random = np.array([p["random"] for p in report["parameters"]])
    assert np.median(after / random) < 1.0


def test_the_criteria_predict_the_error_of_a_new_session_and_its_least_possible():
    plans = {c: plan("abb-irb120", "cable", 30, criterion=c, causes=["joint_compliance joint 2"], bound=c == "I", **SMALL) for c in ("I", "D")}
    i, d = (plans[c].report["prediction"] for c in ("I", "D"))
    assert "I-optimal" in plans["I"].report["criterion"] and "D-optimal" in plans["D"].report["criterion"]
    assert i["before"] is None and i["random"] == d["random"]  # same candidates, same random draw
    assert i["least_possible"] <= i["after"] <= d["after"] * (1 + 1e-9) and i["after"] < i["random"]
    assert "least_possible" not in d
    with pytest.raises(InvalidParameterError, match="`criterion` must be one of"):
        plan("abb-irb120", "cable", 10, criterion="A", **SMALL)


def test_a_plan_is_deterministic_for_a_seed():
    a, b = plan("abb-irb120", "cable", 12, **SMALL), plan("abb-irb120", "cable", 12, **SMALL)
    np.testing.assert_array_equal(a.q, b.q)


def test_constraints_are_respected():
    box = (-800.0, 800.0, -800.0, 800.0, 100.0, 900.0)
    ranges = {1: np.radians((-60.0, 60.0)), 4: np.radians((-90.0, 10.0))}
    p = plan("abb-irb120", "cable", 20, joint_ranges=ranges, box=box, cable_range=(100.0, 700.0), anchor=(400.0, 0.0, 0.0), **SMALL)
    r = setup(robocal.robot("abb-irb120"), "cable", anchor=(400.0, 0.0, 0.0))
    lo, hi = np.array([j.limits for j in r.joints]).T
    for joint, (a, b) in ranges.items():
        lo[joint - 1], hi[joint - 1] = a, b
    assert np.all((p.q >= lo) & (p.q <= hi))
    point = r.fkine(p.q, tool=True)[:, :3, 3]
    assert np.all((point >= np.array(box[::2])) & (point <= np.array(box[1::2])))
    reading = r.predict("cable", p.q)[:, 0]
    assert np.all((reading > 100.0 + RANGE_MARGIN) & (reading < 700.0 - RANGE_MARGIN))
    np.testing.assert_allclose(p.expected.y[:, 0], reading)  # the file's L column: what the model expects there
    words = " ".join(p.report["constraints"])
    assert "q1 -60..60 deg" in words and "box" in words and "100..700" in words and "collisions" in " ".join(p.report["not_checked"])


def test_a_tracker_keeps_the_tool_point_within_its_range():
    tracker = np.array([2500.0, 0.0, 0.0])
    p = plan("ur10", "position", 15, tracker=tracker, tracker_range=(1800.0, 3000.0), **SMALL)
    point = setup(robocal.robot("ur10"), "position").fkine(p.q, tool=True)[:, :3, 3]
    distance = np.linalg.norm(point - tracker, axis=1)
    assert np.all((distance >= 1800.0) & (distance <= 3000.0))


@pytest.mark.parametrize(
    "kwargs,words",
    [
        ({"box": (3000.0, 3100.0, 0.0, 10.0, 0.0, 10.0)}, "no joint configuration within the joint ranges satisfies the tool point inside the box"),
        ({"anchor": (9000.0, 0.0, 0.0)}, "satisfies the cable reading within 25..1975 mm"),
        ({"joint_ranges": {2: np.radians((200.0, 210.0))}}, "joint 2 within 200..210 deg lies outside its limits"),
        ({"joint_ranges": {7: (0.0, 1.0)}}, "joint 7 is not a joint"),
        ({"joint_ranges": {2: (1.0, 0.0)}}, "lower < upper"),
        ({"poses": 50, "candidates": 20}, "`candidates` must be an integer >= 50"),
        ({"poses": 0}, "`poses` must be an integer >= 1"),
        ({"poses": 501, "candidates": 600}, "`poses` must be at most 500; got 501"),
        ({"candidates": 100_000_001}, "`candidates` must be at most 100,000; got 100,000,001"),
        ({"tracker": (1.0, 2.0, 3.0)}, "applies to position and pose measurements, not cable"),
        ({"cable_range": (0.0, 30.0)}, "`cable_range` must be (min, max)"),
        ({"box": (1.0, 0.0, 0.0, 1.0, 0.0, 1.0)}, "each min < max"),
        ({"anchor": (1.0, 2.0)}, "`anchor` must be 3 finite numbers"),
        ({"noise": -1.0}, "`noise` must be finite and > 0"),
        ({"passes": 99}, "`passes` must be at most 12"),
        ({"causes": ["joint_wobble joint 2"]}, "unknown causes ['joint_wobble joint 2']"),
        ({"causes": ["joint_periodic joint 9 harmonic=2"]}, "unknown causes"),
    ],
)
def test_bad_input_is_refused_by_name(kwargs, words):
    args = {"poses": 12, "candidates": 500, **kwargs}
    with pytest.raises(InvalidParameterError) as info:
        plan("hsr-jr680", "cable", **args)
    assert words in str(info.value)


def test_every_constraint_met_alone_but_not_together_is_named_with_its_share():
    r = setup(robocal.robot("hsr-jr680"), "cable")
    lo, hi = np.array([j.limits for j in r.joints]).T
    # the cable's reading needs the tool near the anchor (x > 0); the box keeps it at x < -500
    constraints = Constraints(lo, hi, np.array(CABLE_RANGE), box=np.array([-3000.0, -500.0, -3000.0, 3000.0, 0.0, 3000.0]))
    with pytest.raises(InvalidParameterError, match="fewer than the 5 poses asked; each alone passes"):
        candidate_poses(r.with_params(anchor_x=1500.0), "cable", r.with_params(anchor_x=1500.0).params, constraints, [], 5, np.random.default_rng(0), least=5)


def test_the_order_interleaves_passes_and_reports_its_travel():
    rng = np.random.default_rng(3)
    q = rng.uniform(-180.0, 180.0, (60, 6))
    tour = measuring_order(q, 1)
    assert sorted(tour.tolist()) == list(range(60))
    random_travel = np.median([travel(q[rng.permutation(60)]) for _ in range(20)])
    assert travel(q[tour]) < 0.5 * random_travel
    interleaved = measuring_order(q, 4)
    assert sorted(interleaved.tolist()) == list(range(60))
    # each pass sweeps the whole tour: its first pose and the next pass's last are the tour's first ones
    assert set(interleaved[:15].tolist()) == set(tour[0::4].tolist())
    p = plan("hsr-jr680", "cable", 24, passes=3, **SMALL)
    order = p.report["order"]
    assert order["passes"] == 3 and order["correlation"] == pytest.approx(order_correlations(p.q))
    assert order["travel_deg"] == pytest.approx(travel(np.degrees(p.q)))
    assert order["travel_single_tour_deg"] <= order["travel_deg"]


def test_a_joint_map_gets_its_range_covered_without_gaps():
    label = "joint_map joint 2 spacing=15.0 roughness=0.01"
    p = plan("hsr-jr680", "cable", 30, causes=[label], **SMALL)
    assert p.report["causes"][0]["label"] == label and p.report["causes"][0]["after"]["largest"]["unit"] == "deg"
    angles = np.sort(np.degrees(p.q[:, 1]))
    assert np.max(np.diff(angles)) <= 2 * 15.0
    lo, hi = robocal.robot("hsr-jr680").joints[1].limits
    assert angles[0] - np.degrees(lo) < 30.0 and np.degrees(hi) - angles[-1] < 30.0


def test_causes_are_planned_for_or_said_why_not():
    labels = ["joint_compliance joint 2", "drift", "backlash joint 3"]
    report = plan("abb-irb120", "cable", 40, causes=labels, **SMALL).report
    compliance = report["causes"][0]
    assert compliance["label"] == "joint_compliance joint 2" and compliance["before"] is None
    assert compliance["after"]["compliance"]["std"] < compliance["random"]["compliance"]["std"]
    reasons = {c["label"]: c["reason"] for c in report["causes_not_by_poses"]}
    assert "order" in reasons["drift"] and "approached" in reasons["backlash joint 3"]


def test_the_next_poses_fill_what_the_data_leave_open():
    data, _ = simulate("hsr-jr680", "cable", samples=60, seed=2)
    narrow = data.subset(np.argsort(data.q[:, 1])[:30])  # the measured half of joint 2's sweep
    report = plan("hsr-jr680", "cable", 20, data=narrow, **SMALL).report
    assert report["data"]["samples"] == 30
    before, after = report["position"]["before"], report["position"]["after"]
    assert after["rms_mm"] < (before["rms_mm"] if before["rms_mm"] is not None else np.inf)
    assert report["undetermined"]["before"] > 0 or before["rms_mm"] > after["rms_mm"]
    with pytest.raises(InvalidParameterError, match="fitted on the data"):
        plan("hsr-jr680", "cable", 5, data=narrow, anchor=(1.0, 2.0, 3.0), **SMALL)


def test_a_result_gives_the_robot_set_up_and_causes(tmp_path):
    data, _ = simulate("abb-irb120", "cable", samples=80, seed=4, effects=["joint_periodic:joint=2,amplitude=0.02,harmonic=2"])
    result = robocal.calibrate(data, causes=["joint_periodic joint 2 harmonic=2"], test_fraction=0).to_dict()
    report = plan(poses=15, result=result, **SMALL).report
    assert report["robot"] == "abb-irb120" and report["measurement"] == "cable"
    assert [c["label"] for c in report["causes"]] == ["joint_periodic joint 2 harmonic=2"]
    anchor = [result["parameters"][i]["value"] for i, p in enumerate(result["parameters"]) if p["name"] in ("anchor_x", "anchor_y", "anchor_z")]
    assert ", ".join(f"{v:.0f}" for v in anchor) in " ".join(report["constraints"])
    with pytest.raises(InvalidParameterError, match="a calibration of abb-irb120, not of ur10"):
        plan("ur10", poses=5, result=result, **SMALL)


def test_simulate_measures_given_poses_on_the_seeds_robot():
    q = np.radians([[0, -30, 20, 0, 40, 0], [10, -20, 10, 30, 30, 60], [-20, -40, 30, -30, 50, 90]] * 4)
    a, truth_a = simulate("ur10", "position", seed=5, poses=q, noise=0)
    b, truth_b = simulate("ur10", "position", seed=5, poses=q[::-1], noise=0)
    np.testing.assert_array_equal(a.q, q)
    assert truth_a["parameters"] == truth_b["parameters"]
    true = robocal.robot("ur10")
    params = np.array([truth_a["parameters"][n]["value"] for n in true.param_names])
    np.testing.assert_allclose(a.y, true.predict("position", q, params))
    with pytest.raises(InvalidParameterError, match="pose 0 joint 1 is 7, outside the joint's limits"):
        simulate("ur10", "position", seed=5, poses=[[7.0, 0, 0, 0, 0, 0]])


def test_the_cli_writes_a_canonical_plan_the_loader_reads_back(tmp_path, capsys):
    out = tmp_path / "plan.csv"
    set_up = ["--robot", "abb-irb120", "--measurement", "cable", "--poses", "40", "--candidates", "800", "--joint-range", "1=-30,30"]
    code = main(["plan", *set_up, "--out", str(out), "--json", str(tmp_path / "plan.json")])
    printed = capsys.readouterr().out
    assert code == 0 and "40 poses" in printed and "not checked" in printed and "I-optimal" in printed
    data = robocal.load(out)
    assert data.q.shape == (40, 6) and data.measurement == "cable"
    assert np.all(np.abs(np.degrees(data.q[:, 0])) <= 30.0)
    report = __import__("json").loads((tmp_path / "plan.json").read_text())
    assert report["poses"] == 40 and len(report["order"]["correlation"]) == 6


def test_the_cli_names_the_constraint_that_leaves_no_candidate(tmp_path, capsys):
    code = main(["plan", "--robot", "hsr-jr680", "--measurement", "cable", "--poses", "5", "--anchor", "9000,0,0", "--out", str(tmp_path / "p.csv")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "the cable reading within 25..1975 mm" in err[0] and err[0].startswith("robocal: error: ")
    assert not (tmp_path / "p.csv").exists()


@pytest.mark.parametrize(
    "counts,words",
    [(["--candidates", "100000000"], "at most 100,000; got 100,000,000"), (["--poses", "200000", "--candidates", "200000"], "at most 500; got 200,000")],
)
def test_the_cli_bounds_poses_and_candidates_before_any_work(tmp_path, capsys, counts, words):
    """Issue 52 #12, #13: a hundred million candidates ran out of memory with a traceback, 200 000 poses ran for minutes."""
    code = main(["plan", "--robot", "hsr-jr680", "--measurement", "cable", "--poses", "10", *counts, "--out", str(tmp_path / "p.csv")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and words in err[0]
    assert not (tmp_path / "p.csv").exists()


def test_data_of_another_robot_are_refused(tmp_path, capsys):
    """Issue 52 #7: ABB data planned for as an HSR JR680 fitted its anchor at (752, 674, 974) mm and stated figures as if at noise."""
    data, _ = simulate("abb-irb120", "cable", samples=200, seed=3)
    path = robocal.data.write_canonical(data, tmp_path / "abb.csv")  # a file that does not name its robot
    with pytest.raises(robocal.exceptions.DataError, match="the data do not fit hsr-jr680: .* another robot than the one given"):
        plan("hsr-jr680", "cable", 10, data=str(path), **SMALL)
    code = main(["plan", "--robot", "hsr-jr680", "--measurement", "cable", "--poses", "10", "--data", str(path), "--out", str(tmp_path / "p.csv")])
    assert code == 2 and "abb.csv: the data do not fit hsr-jr680" in capsys.readouterr().err
    assert plan("abb-irb120", "cable", 10, data=str(path), **SMALL).report["poses"] == 10


def test_the_cli_takes_the_criterion_and_the_bound(tmp_path, capsys):
    args = ["plan", "--robot", "ur10", "--measurement", "position", "--poses", "12", "--candidates", "400", "--out", str(tmp_path / "p.csv")]
    assert main([*args, "--criterion", "D", "--bound"]) == 0
    printed = capsys.readouterr().out
    assert "D-optimal" in printed and "the least any 12 poses could reach" in printed
    with pytest.raises(SystemExit):
        main([*args, "--criterion", "E"])


ODD = [None, 0, -1, 2.5, "x", float("nan"), np.inf, [], [1.0, 2.0], (np.nan, 1.0), {"a": 1}, True]
#: The arguments of robocal.plan the fuzz test gives odd values.
PLAN_ARGUMENTS = ["poses", "candidates", "seed", "joint_ranges", "cable_range", "anchor", "tool", "box", "noise", "passes", "causes", "measurement", "robot"]


@settings(max_examples=60, deadline=None, derandomize=True, suppress_health_check=list(HealthCheck))
@given(key=st.sampled_from(PLAN_ARGUMENTS), value=st.sampled_from(ODD) | st.integers(-3, 3) | st.lists(st.floats(allow_nan=True), max_size=7))
def test_fuzz_the_arguments(key, value):
    """Any odd argument: a plan, or a robocal error naming the problem — never another exception."""
    args = {"robot": "abb-irb120", "measurement": "cable", "poses": 30, "candidates": 300, key: value}
    try:
        p = plan(**args)
    except RobocalError as exc:
        assert str(exc)
    else:
        assert np.all(np.isfinite(p.q)) and len(p.q) == p.report["poses"]


def test_the_cli_plans_from_a_result_or_a_diagnosis_and_data(tmp_path, capsys):
    data, truth = simulate("abb-irb120", "position", samples=80, seed=6)
    robocal.simulation.write_simulation(data, truth, tmp_path / "d.csv")
    assert main(["calibrate", str(tmp_path / "d.csv"), "--robot", "abb-irb120", "--out", str(tmp_path / "result.json")]) == 0
    (tmp_path / "diag.json").write_text('{"model": {"structure": [], "causes": ["joint_scale joint 3", "drift"]}}')
    for source in ("result.json", "diag.json"):
        out = tmp_path / f"plan-{source}.csv"
        inputs = ["--from", str(tmp_path / source), "--data", str(tmp_path / "d.csv"), "--robot", "abb-irb120"]
        written = ["--out", str(out), "--json", str(tmp_path / f"{source}.plan.json")]
        code = main(["plan", *inputs, "--poses", "15", "--candidates", "600", *written])
        printed = capsys.readouterr().out
        assert code == 0, printed
        assert robocal.load(out).q.shape == (15, 6)
        known = (
            "known before the poses: the result's 64 training samples re-linearised" if source == "result.json" else "known before the poses: the 80 samples"
        )
        assert known in printed, printed
        assert ("d.csv is the result's training data and the data measured with the sensor in place" in printed) == (source == "result.json")
    report = __import__("json").loads((tmp_path / "diag.json.plan.json").read_text())
    assert report["data"]["samples"] == 80 and [c["label"] for c in report["causes"]] == ["joint_scale joint 3"]
    assert report["causes_not_by_poses"][0]["label"] == "drift" and "drift" in printed


# -- a plan for a new session of a calibrated robot (issue 55) -----------------------------------
MAP = "joint_map joint 2 spacing=10.0 roughness=0.01"


def _calibrated(tmp_path, causes=(), samples=150):
    """A UR10 tracker session with joint 2 within -100..-40 deg, written to a file, calibrated with ``causes``."""
    rng = np.random.default_rng(7)
    q = rng.uniform(-np.pi, np.pi, (samples, 6))
    q[:, 1] = np.radians(rng.uniform(-100.0, -40.0, samples))
    data, truth = simulate("ur10", "position", seed=7, poses=q)
    path, _ = robocal.simulation.write_simulation(data, truth, tmp_path / "session.csv")
    return path, robocal.calibrate(str(path), robot="ur10", measurement="position", causes=list(causes) or None).to_dict()


def test_a_plan_from_a_result_with_a_joint_map_counts_the_results_map_and_knows_what_it_knows(tmp_path):
    """Issue 55: a result's joint map spanned the candidates' whole range (±360 deg: 73 coefficients
    for the result's 7, 100 entries for its 34; on the UR10 of series A+B 1 763 for 709) and the
    figures were undetermined or meaningless (here 2.02 mm after, 0.21 mm random)."""
    _, result = _calibrated(tmp_path, [MAP])
    fitted = next(c for c in result["causes"] if c["label"] == MAP)
    report = plan(poses=20, result=result, candidates=1500, seed=1).report
    counted = report["model"]
    assert counted["maps"] == [
        {
            "label": MAP,
            "coefficients": len(fitted["coefficients"]),
            "range_deg": [fitted["detail"]["lo"], fitted["detail"]["hi"]],
            "gaps_deg": fitted["detail"]["gaps"],
            "range_from": "the result's fit",
        }
    ]
    assert counted["entries"] == len(result["free"])  # the result's entries: its robot and one session's set-up
    assert "training samples re-linearised" in counted["known_before"][0]
    prediction = report["prediction"]
    assert None not in (prediction["before"], prediction["after"], prediction["random"])
    assert prediction["after"] <= prediction["random"]
    assert prediction["after"] < prediction["before"]  # 20 more poses add to what the result knew


def test_the_results_information_is_its_covariance_of_the_robots_parameters(tmp_path):
    """Before any pose, a plan from a result knows the robot's parameters as the result does: the
    Schur complement of its training information, its set-up eliminated, is the inverse of its
    covariance of them; the new session's set-up is undetermined."""
    _, result = _calibrated(tmp_path)
    report = plan(poses=12, result=result, candidates=600, seed=1).report
    std = {p["name"]: p["std"] for p in result["parameters"]}
    before = {e["name"]: e["before"] for e in report["parameters"]}
    kinematic = [n for n in before if n in result["free"] and not n.startswith(("base_", "tool_"))]
    assert len(kinematic) > 10
    for name in kinematic:
        expected = std[name] if not name.startswith(("alpha", "theta", "beta")) else np.degrees(std[name])
        assert before[name] == pytest.approx(expected, rel=0.01), name
    assert all(before[n] is None for n in before if n.startswith(("base_", "tool_")))


def test_a_result_whose_training_data_are_gone_is_planned_without_them_and_says_so(tmp_path):
    path, result = _calibrated(tmp_path)
    path.unlink()
    report = plan(poses=12, result=result, candidates=600, seed=1).report
    assert any(f"its training data {path} are not found" in n for n in report["notes"])
    assert report["model"]["known_before"] == [] and report["prediction"]["before"] is None
    assert report["prediction"]["after"] is not None


def test_a_coverage_that_takes_more_poses_than_planned_is_left_to_the_criterion():
    report = plan("hsr-jr680", "cable", 12, causes=["joint_map joint 2 spacing=2.0 roughness=0.01"], **SMALL).report
    assert any("more than the 12 planned: the criterion places them all" in n for n in report["notes"])
    assert report["model"]["maps"][0]["range_from"] == "the candidates' (and the data's) angles"


@settings(max_examples=40, deadline=None, derandomize=True)
@given(p=st.integers(1, 7), rows=st.integers(0, 12), empty=st.integers(0, 3), seed=st.integers(0, 2**16))
def test_the_inverse_half_is_a_generalised_inverse_and_the_pseudo_inverse_where_only_empty_entries_are_undetermined(p, rows, empty, seed):
    """``G = H·Hᵀ`` satisfies ``M G M = M`` (what a determined quantity's variance needs: the same
    for every generalised inverse), is ``M⁺`` when only entries nothing is known of are
    undetermined, and the undetermined directions span M's null space — by Cholesky or eigenvalues."""
    from robocal.planning import _inverse_half

    rng = np.random.default_rng(seed)
    B = rng.normal(size=(rows, p)) * np.exp(rng.uniform(-3, 3, p))
    B[:, :empty] = 0.0  # entries nothing is known of (a new session's set-up)
    M = B.T @ B
    H, null = _inverse_half(M)
    G = H @ H.T
    assert H.shape[1] + null.shape[1] == p == H.shape[1] + p - np.linalg.matrix_rank(M)
    np.testing.assert_allclose(M @ G @ M, M, rtol=1e-6, atol=1e-9 * max(1.0, np.abs(M).max()))
    assert np.allclose(M @ null, 0.0, atol=1e-8 * max(1.0, np.abs(M).max()))
    if np.linalg.matrix_rank(M) == p - min(empty, p):
        np.testing.assert_allclose(G, np.linalg.pinv(M, hermitian=True), rtol=1e-6, atol=1e-9 * max(1.0, np.abs(G).max()))


def test_a_plan_for_a_result_with_reading_conventions_keeps_the_model_within_its_limits():
    """The joint limits bound the model's angles: a plan held the controller's readings to them, and for a UR10 read
    90 deg off on joint 2 it planned model angles to 450 deg, beyond what the robot reaches (simulate refused them,
    the monitor would refuse their samples)."""
    from dataclasses import replace

    from robocal.causes import structure
    from robocal.results import load_result

    data, _ = simulate("ur10", "position", samples=200, seed=3)
    conventions = structure.parse_all(["joint_zero joint 2 offset=90"], 6)
    result = robocal.calibrate(replace(data, q=structure.to_readings(data.q, conventions)), robot="ur10", causes=["joint_zero joint 2 offset=90"])
    robot, doc = load_result(result.to_dict())
    for criterion in ("D", "Ds"):
        readings = plan(result=result.to_dict(), poses=40, criterion=criterion, **SMALL).q
        model = structure.to_model(readings, structure.parse_all(doc["structure"], 6))
        lower, upper = np.array([j.limits for j in robot.joints]).T
        assert ((model >= lower - 1e-9) & (model <= upper + 1e-9)).all(), (criterion, np.degrees(model[:, 1]).max())
