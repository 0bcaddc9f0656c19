"""Issue 55: ``compensate`` takes targets in the robot base frame (default), a session's
measurement frame or a user frame, and gives joint commands within a turn of their seeds."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import robocal
from robocal.cli import main
from robocal.compensation import Targets, joint_limits, nearest_turn
from robocal.exceptions import RobocalError
from robocal.geometry import frame_transform, matrix_from_quaternion, quaternion_from_matrix
from robocal.simulation import simulate

#: Where Series A's laser tracker stood in the UR10's base frame (its calibration's base_*: mm, deg).
TRACKER = {"base_x": 2673.6, "base_y": -1531.5, "base_z": -1306.3, "base_rx": 0.63, "base_ry": -0.10, "base_rz": -30.2}
BASE = ("base_x", "base_y", "base_z", "base_rx", "base_ry", "base_rz")


def _placed(doc: dict, setup: dict) -> dict:
    """``doc`` with the measurement set-up ``setup`` (base_* in mm and deg): the same robot
    calibrated with the tracker standing there."""
    doc = copy.deepcopy(doc)
    for p in doc["parameters"]:
        if p["name"] in setup:
            p["value"] = setup[p["name"]] if p["name"] in BASE[:3] else math.radians(setup[p["name"]])
    return doc


@pytest.fixture(scope="module")
def far():
    """A UR10 calibrated on simulated tracker poses, the tracker 3 m from the robot (as in the
    public Series A): the measurement frame is far from the base frame."""
    data, _ = simulate("ur10", "pose", samples=200, seed=3)
    doc = _placed(robocal.calibrate(data, robot="ur10", test_fraction=0.0).to_dict(), TRACKER)
    robot, _ = robocal.load_result(doc)
    base = robot.with_params(**{n: 0.0 for n in BASE})  # the calibrated chain without the tracker
    return doc, robot, base


def _joints(rows) -> np.ndarray:
    return np.radians([r["q"] for r in rows])


def test_base_frame_targets_are_reached_at_their_joints(far):
    """Targets made by the calibrated chain's FK (tracker left out) at known joints, seeded with
    those joints: reached (< 1e-4 mm) at the joints themselves — no ±360° correction for seeds
    beyond ±180° (the seed was moved a turn towards the middle of the range), no joint 6 flip.
    Before issue 55 the default frame was the tracker's: every target 3 m away, unreachable."""
    doc, _, base = far
    q = np.radians([[200.0, -100.0, 90.0, -250.0, 190.0, 181.0], [-30.0, -60.0, -120.0, 300.0, -200.0, -179.5], [10.0, -80.0, 70.0, -90.0, 90.0, 359.0]])
    for measurement in ("position", "pose"):
        rows = robocal.compensate(doc, Targets(base.predict(measurement, q), q, np.arange(2, 5)))
        assert [r["status"] for r in rows] == ["ok"] * 3 and [r["frame"] for r in rows] == ["base"] * 3
        assert max(r["residual_mm"] for r in rows) < 1e-4
        assert np.abs([r["correction"] for r in rows]).max() < 1e-6  # deg: the seed already reaches


def test_base_frame_targets_without_seeds_stay_within_a_turn_of_their_nominal_seed(far):
    """200 targets from joints within the limits, no seeds: every one reached, each command
    within 180° of its seed (the nominal solution: ``dq`` is the correction)."""
    doc, robot, base = far
    lower, upper = joint_limits(robot)
    q = lower + (upper - lower) * np.random.default_rng(4).random((200, 6))
    rows = robocal.compensate(doc, base.predict("position", q))
    assert all(r["status"] == "ok" for r in rows), [r["status"] for r in rows if r["status"] != "ok"]
    assert max(r["residual_mm"] for r in rows) < 1e-4
    assert np.abs([r["correction"] for r in rows]).max() <= 180.0
    reached = base.predict("position", _joints(rows))  # checked on the model, not taken from the residual column
    assert np.linalg.norm(reached - base.predict("position", q), axis=1).max() < 2e-4


def test_session_frame_is_the_tracker_and_targets_there_reach_the_same_joints(far):
    doc, robot, base = far
    q = np.radians([[20.0, -70.0, 80.0, -100.0, 60.0, 30.0]])
    in_base = robocal.compensate(doc, Targets(base.predict("pose", q), q, np.array([2])))
    in_session = robocal.compensate(doc, Targets(robot.predict("pose", q), q, np.array([2])), frame="session")
    assert in_session[0]["frame"] == "session 1" and in_session[0]["status"] == "ok"
    assert np.allclose(in_session[0]["q"], in_base[0]["q"], atol=1e-6)
    # the same tracker-frame target read as a base-frame one is 3 m away
    (wrong,) = robocal.compensate(doc, robot.predict("position", q))
    assert wrong["status"].startswith("unreachable")


def test_user_frame_round_trip(far):
    """Pose targets moved into a user frame (given in the base frame as x, y, z, rx, ry, rz in mm
    and deg, Tx·Ty·Tz·Rz·Ry·Rx) reach the joints the base-frame targets reach."""
    doc, robot, base = far
    lower, upper = joint_limits(robot)
    q = lower + (upper - lower) * np.random.default_rng(7).random((12, 6))
    in_base = base.predict("pose", q)
    user = (350.0, -200.0, 120.0, 10.0, -25.0, 40.0)
    T = np.linalg.inv(frame_transform([*user[:3], *np.radians(user[3:])]))  # base -> user
    in_user = np.column_stack(
        [in_base[:, :3] @ T[:3, :3].T + T[:3, 3], [quaternion_from_matrix(T[:3, :3] @ matrix_from_quaternion(p)) for p in in_base[:, 3:]]]
    )
    seeds = q + np.radians(np.random.default_rng(8).normal(0.0, 3.0, q.shape))
    rows_base = robocal.compensate(doc, Targets(in_base, seeds, np.arange(2, 14)))
    rows_user = robocal.compensate(doc, Targets(in_user, seeds, np.arange(2, 14)), user_frame=",".join(f"{v:g}" for v in user))
    assert all(r["status"] == "ok" for r in rows_base + rows_user)
    assert rows_user[0]["frame"] == "user 350 -200 120 10 -25 40"
    assert np.abs(np.array([r["q"] for r in rows_user]) - [r["q"] for r in rows_base]).max() < 1e-5  # deg
    assert robocal.compensate(doc, in_user[:1, :3], frame="user", user_frame=user)[0]["status"] == "ok"  # a sequence too


def test_session_k_of_a_multi_session_result():
    """A result of two sessions (the tracker moved between them): ``session:2`` targets are in the
    second tracker's frame, which the result's ``sessions`` hold."""
    data = [simulate("ur10", "pose", samples=200, seed=5, session=s)[0] for s in (0, 1)]
    doc = robocal.calibrate(data, robot="ur10", test_fraction=0.0).to_dict()
    robot, _ = robocal.load_result(doc)
    second = robot.with_params(**doc["sessions"][1]["setup"])
    q = np.radians([[15.0, -75.0, 85.0, -95.0, 70.0, 200.0], [-40.0, -110.0, 60.0, -30.0, -80.0, -20.0]])
    rows = robocal.compensate(doc, Targets(second.predict("pose", q), q, np.arange(2, 4)), frame="session:2")
    assert [r["frame"] for r in rows] == ["session 2"] * 2 and all(r["status"] == "ok" for r in rows)
    assert np.abs([r["correction"] for r in rows]).max() < 1e-6
    first = robocal.compensate(doc, Targets(second.predict("pose", q), q, np.arange(2, 4)), frame="session:1")
    assert np.abs(np.array([r["q"] for r in first]) - [r["q"] for r in rows]).max() > 1.0  # the other tracker: other joints
    with pytest.raises(RobocalError, match="holds 2 sessions: K must be 1..2"):
        robocal.compensate(doc, second.predict("pose", q), frame="session:3")


TURNS = settings(max_examples=200, deadline=None, derandomize=True)


@TURNS
@given(
    q=st.floats(-20.0, 20.0),
    toward=st.floats(-20.0, 20.0),
    lo=st.floats(-15.0, 5.0),
    width=st.floats(0.1, 15.0),
)
def test_nearest_turn_is_the_equivalent_within_the_limits_nearest_the_seed(q, toward, lo, width):
    lower, upper = np.array([lo]), np.array([lo + width])
    (out,), off = nearest_turn(np.array([q]), np.array([toward]), lower, upper)
    assert lower[0] <= out <= upper[0] and off == []
    k = np.arange(-10, 11)
    equivalents = q + 2 * np.pi * k
    inside = equivalents[(equivalents >= lower[0]) & (equivalents <= upper[0])]
    if inside.size:  # the same angle, and none nearer the seed
        assert abs(math.remainder(out - q, 2 * np.pi)) < 1e-9
        assert abs(out - toward) <= np.abs(inside - toward).min() + 1e-9
    else:
        assert out == min(max(q, lower[0]), upper[0])


@pytest.mark.parametrize("q", [1e300, -1e300, np.inf, -np.inf, 7.0])
@pytest.mark.parametrize("toward", [0.0, 1e300, -np.inf, np.nan])
def test_nearest_turn_of_absurd_angles_is_within_the_limits(q, toward):
    """A seed of 1e300 or inf rad (the API takes any float) gives an angle within the limits, not
    an empty list of turns (found by tests/test_fuzz_api.py)."""
    (out,), _ = nearest_turn(np.array([q]), np.array([toward]), np.array([-2 * np.pi]), np.array([2 * np.pi]))
    assert -2 * np.pi <= out <= 2 * np.pi


@settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(u=st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6), s=st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6))
def test_no_command_is_more_than_half_a_turn_from_its_seed_where_an_equivalent_is(far, u, s):
    """Random target joints and random seeds within the limits: a joint further than 180° from
    its seed has no equivalent angle within the limits that is nearer."""
    doc, robot, base = far
    lower, upper = joint_limits(robot)
    q, seed = lower + (upper - lower) * np.array(u), lower + (upper - lower) * np.array(s)
    (row,) = robocal.compensate(doc, Targets(base.predict("position", q[None, :]), seed[None, :], np.array([2])))
    assert row["status"] == "ok" and row["residual_mm"] < 1e-4
    out = np.radians(row["q"])
    for j in range(6):
        if abs(out[j] - seed[j]) > np.pi:
            nearer = out[j] - 2 * np.pi * np.sign(out[j] - seed[j])
            assert not lower[j] <= nearer <= upper[j], (j, np.degrees(out[j]), np.degrees(seed[j]))


def test_a_joint_map_prefers_the_turn_it_has_data_at():
    """Joint 6's map was fitted on 100..260°: a seed at -160° (the same angle as 200°, where the
    map has data) gets the command 200° — a turn from the seed, which the status says — and not
    -160° beyond the map's data."""
    poses = np.radians(np.random.default_rng(2).uniform([-90, -150, -120, -180, -120, 100], [90, -30, 120, 0, 120, 260], (300, 6)))
    data, _ = simulate("ur10", "position", samples=300, seed=2, poses=poses)
    doc = robocal.calibrate(data, robot="ur10", test_fraction=0.0, causes=["joint_map joint 6 spacing=15.0 roughness=0.01"]).to_dict()
    (cause,) = doc["causes"]
    assert 100 <= cause["detail"]["lo"] and cause["detail"]["hi"] <= 260
    robot, _ = robocal.load_result(doc)
    q = np.radians([[30.0, -80.0, 75.0, -60.0, 70.0, 200.0]])
    seed = q.copy()
    seed[0, 5] -= 2 * np.pi  # -160°
    (row,) = robocal.compensate(doc, Targets(robot.predict("position", q), seed, np.array([2])), frame="session")
    assert row["status"].startswith("ok; joint 6 360 deg from its seed"), row["status"]
    assert abs(row["q"][5] - 200.0) < 1.0 and "; beyond its map's data:" not in row["status"]
    (near,) = robocal.compensate(doc, Targets(robot.predict("position", q), q, np.array([2])), frame="session")
    assert near["status"] == "ok" and abs(near["q"][5] - 200.0) < 1.0  # a seed at the covered turn: no note


def test_cli_frame_errors_and_summary(far, tmp_path, capsys):
    doc, _, base = far
    from robocal.results import save_result

    result = save_result(doc, tmp_path / "r.json")
    targets = tmp_path / "t.csv"
    targets.write_text("x,y,z\n" + ",".join(f"{v:.6f}" for v in base.predict("position", np.radians([[0, -90, 90, -90, 90, 0]]))[0]) + "\n")
    out = tmp_path / "j.csv"
    for options, words in (
        (["--frame", "tool"], "must be base, session, session:K"),
        (["--frame", "session:0"], "must be base, session, session:K"),
        (["--frame", "session:2"], "holds 1 session: K must be 1"),
        (["--frame", "user"], "needs a user frame x,y,z,rx,ry,rz"),
        (["--user-frame", "1,2,3"], "must be 6 finite numbers"),
        (["--user-frame", "1,2,3,4,5,x"], "must be 6 finite numbers"),
        (["--frame", "session", "--user-frame", "0,0,0,0,0,0"], "a user frame is given but `--frame` is 'session'"),
    ):
        assert main(["compensate", str(result), str(targets), "--out", str(out)] + options) == 2, options
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("robocal: error: ") and words in err[0], (options, err)
        assert not out.exists()
    assert main(["compensate", str(result), str(targets), "--out", str(out)]) == 0
    summary = capsys.readouterr().out
    assert "1 of 1 targets reached" in summary and "targets in the robot base frame" in summary
    header, row = out.read_text().splitlines()
    assert header.endswith("residual_mm,frame,status") and row.endswith(",base,ok")
    assert main(["compensate", str(result), str(targets), "--out", str(out), "--user-frame", "0,0,0,0,0,90"]) == 0
    assert "targets in the user frame at 0,0,0 mm, 0,0,90 deg in the robot base frame" in capsys.readouterr().out


def test_targets_without_seeds_follow_the_program_order(far):
    """Eleven targets along a joint path through ±180°, no seeds: each nominal solution starts at
    the previous command, so the commands follow the path (steps of ~6°). From the middle of the
    ranges every time, they jumped between branches and turns (steps of 200–360°)."""
    doc, _, base = far
    t = np.linspace(0.0, 1.0, 11)[:, None]
    q = np.radians([150.0, -70.0, 80.0, -100.0, 80.0, 150.0]) + t * np.radians([60.0, 10.0, -10.0, 20.0, 10.0, 60.0])
    for measurement in ("position", "pose"):
        rows = robocal.compensate(doc, base.predict(measurement, q))
        assert all(r["status"] == "ok" for r in rows)
        assert np.abs(np.diff([r["q"] for r in rows], axis=0)).max() < 10.0, measurement


def test_a_cable_results_base_frame_is_its_measurement_frame():
    """A cable calibration places the anchor in the robot base frame (``base_*`` not fitted): the
    two frames give the same commands."""
    data, _ = simulate("hsr-jr680", "cable", samples=300, seed=1)
    doc = robocal.calibrate(data, robot="hsr-jr680", test_fraction=0.0).to_dict()
    robot, _ = robocal.load_result(doc)
    lower, upper = joint_limits(robot)
    y = robot.predict("position", lower + (upper - lower) * np.random.default_rng(0).random((10, 6)))
    base, session = robocal.compensate(doc, y), robocal.compensate(doc, y, frame="session")
    assert all(r["status"] == "ok" for r in base + session)
    assert np.array_equal([r["q"] for r in base], [r["q"] for r in session])


def test_a_joint_program_is_filtered_to_commands_the_full_model_reaches(tmp_path, capsys):
    """A robot program's joint targets in (q1..qN alone), corrected joint targets out: at the
    commands the result's full model (geometry and joint causes) puts the tool where the nominal
    model puts it at the program's joints, within 1e-6 mm, and the commands stay near the program."""
    import json

    import robocal
    from robocal.causes.candidates import joint_offsets
    from robocal.cli import main
    from robocal.results import load_result
    from robocal.simulation import simulate

    data, _ = simulate("ur10", "position", samples=300, seed=2, effects=["joint_periodic:joint=2,amplitude=0.05"])
    result = tmp_path / "r.json"
    result.write_text(json.dumps(robocal.calibrate(data, robot="ur10", causes=["joint_periodic joint 2 harmonic=1"]).to_dict()))
    program = np.random.default_rng(3).uniform(-150.0, 150.0, (12, 6))
    path = tmp_path / "program.csv"
    np.savetxt(path, program, delimiter=",", header=",".join(f"q{j}" for j in range(1, 7)), comments="")
    out = tmp_path / "joints.csv"
    assert main(["compensate", str(result), str(path), "--out", str(out), "--quiet"]) == 0
    assert "12 of 12 targets reached" in capsys.readouterr().out
    commands = np.radians(np.loadtxt(out, delimiter=",", skiprows=1, usecols=range(1, 7)))
    calibrated, doc = load_result(result)
    nominal = robocal.Robot("ur10", calibrated.joints, np.array(doc["robot_model"]["nominal"]))
    base = [calibrated.index(f"base_{c}") for c in ("x", "y", "z", "rx", "ry", "rz")]
    tool = [calibrated.index(f"tool_{c}") for c in ("x", "y", "z", "rx", "ry", "rz")]
    in_base = calibrated.params.copy()
    in_base[base] = 0.0
    nominal.params[base], nominal.params[tool] = 0.0, calibrated.params[tool]
    offsets = joint_offsets(calibrated, doc["causes"])
    reached = calibrated.fkine(commands + offsets(commands), params=in_base, tool=True)
    wanted = nominal.fkine(np.radians(program), tool=True)
    assert np.abs(reached[:, :3, 3] - wanted[:, :3, 3]).max() < 1e-6
    assert np.abs(np.degrees(commands) - program).max() < 5.0  # corrections on the program's branch, not other branches
