"""What an export of a result delivers to the robot (issue 55): the file works at the
controller's readings (reading conventions folded in), a result with joint causes exports the
best geometry without them and says what it leaves out and what that costs, and nothing of
this is silent."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import robocal
from robocal import export as ex
from robocal.causes import structure
from robocal.cli import main
from robocal.exceptions import InvalidParameterError
from robocal.results import load_result
from robocal.simulation import simulate

from helpers import three_joint_robot

POS_TOL = 1e-6  # mm

CONVENTIONS = st.lists(
    st.one_of(
        st.builds(lambda j, deg: structure.Structure("joint_zero", j, np.radians(deg)), st.integers(0, 2), st.floats(-180, 180)),
        st.builds(lambda j: structure.Structure("joint_sign", j), st.integers(0, 2)),
    ),
    max_size=4,
)


@settings(max_examples=60, deadline=None)
@given(
    conventions=CONVENTIONS,
    chain=st.sampled_from([("dh",) * 3, ("mdh",) * 3]),
    kinds=st.sampled_from([("revolute",) * 3, ("revolute", "prismatic", "revolute")]),
    seed=st.integers(0, 2**16),
)
def test_the_robot_at_readings_is_the_model_at_its_angles(conventions, chain, kinds, seed):
    """Zero offsets and counting directions, in any order and on any joint of a skew DH or MDH
    chain (Hayati beta, base and tool frames), fold into a robot whose joint variables are the
    readings: its tool frame at readings r is the model's at to_model(r)."""
    robot = three_joint_robot(chain, kinds)
    folded = structure.robot_at_readings(robot, conventions)
    q = np.random.default_rng(seed).uniform(-3.0, 3.0, (40, 3))
    q[:, 1] = np.abs(q[:, 1]) * 100 if kinds[1] == "prismatic" else q[:, 1]
    want = robot.fkine(structure.to_model(q, conventions), tool=True)
    got = folded.fkine(q, tool=True)
    assert np.abs(got[:, :3, 3] - want[:, :3, 3]).max() < 1e-9
    assert np.abs(got[:, :3, :3] - want[:, :3, :3]).max() < 1e-12
    model_limits = np.array([j.limits for j in robot.joints])
    reading_limits = np.array([j.limits for j in folded.joints])
    ends = structure.to_model(reading_limits.T, conventions)  # each reading limit is a model limit
    assert np.allclose(np.sort(ends, axis=0), model_limits.T)


def test_a_joint_read_relative_to_another_is_refused_joint_by_joint():
    robot = three_joint_robot(("dh",) * 3, ("revolute",) * 3)
    coupled = structure.parse_all(["joint_reference joint 3 source=2 coefficient=+1"], 3)
    with pytest.raises(InvalidParameterError, match=r"joint_reference joint 3 .*\(--angles model\)"):
        structure.robot_at_readings(robot, coupled)


@pytest.fixture(scope="module")
def signed(tmp_path_factory):
    """A UR10 whose controller counts joint 3 the other way and reads joint 2 90 deg off,
    calibrated with those conventions: the result's model angles are not the readings."""
    data, _ = simulate("ur10", "position", samples=200, seed=3)
    readings = structure.to_readings(data.q, structure.parse_all(["joint_sign joint 3", "joint_zero joint 2 offset=90"], 6))
    result = robocal.calibrate(replace(data, q=readings), robot="ur10", causes=["joint_sign joint 3", "joint_zero joint 2 offset=90"])
    path = tmp_path_factory.mktemp("signed") / "result.json"
    path.write_text(json.dumps(result.to_dict()))
    return path, readings


@pytest.mark.parametrize("fmt, suffix", [("urdf", ".urdf"), ("dh", ".csv"), ("mdh", ".json")])
def test_an_export_works_at_the_controllers_readings(signed, tmp_path, capsys, fmt, suffix):
    path, readings = signed
    out = tmp_path / f"robot{suffix}"
    assert main(["export", str(path), "--format", fmt, "--out", str(out)]) == 0
    assert "joint values are the controller's readings: joint_sign joint 3, joint_zero joint 2 offset=90" in capsys.readouterr().out
    calibrated, doc = load_result(path)
    conventions = structure.parse_all(doc["structure"], 6)
    exported = robocal.robot(str(out))
    got = exported.fkine(readings, tool=True)[:, :3, 3]
    want = calibrated.fkine(structure.to_model(readings, conventions), tool=True)[:, :3, 3]
    assert np.abs(got - want).max() < POS_TOL
    # The model's angles, asked for, are what the file then takes, and it says so.
    assert main(["export", str(path), "--format", fmt, "--angles", "model", "--out", str(out)]) == 0
    assert "the model's angles, not the controller's readings" in capsys.readouterr().out
    at_model = robocal.robot(str(out)).fkine(structure.to_model(readings, conventions), tool=True)[:, :3, 3]
    assert np.abs(at_model - want).max() < POS_TOL


def test_a_coupled_reading_is_refused_in_words_unless_model_angles_are_asked(tmp_path, capsys):
    data, _ = simulate("ur10", "position", samples=120, seed=4)
    label = "joint_reference joint 3 source=2 coefficient=+1"
    readings = structure.to_readings(data.q, structure.parse_all([label], 6))
    path = tmp_path / "r.json"
    path.write_text(json.dumps(robocal.calibrate(replace(data, q=readings), robot="ur10", causes=[label]).to_dict()))
    out = tmp_path / "r.urdf"
    assert main(["export", str(path), "--format", "urdf", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "joint_reference joint 3" in err and "--angles model" in err and "Traceback" not in err
    assert not out.exists()
    assert main(["export", str(path), "--format", "urdf", "--angles", "model", "--out", str(out)]) == 0


@pytest.fixture(scope="module")
def periodic(tmp_path_factory):
    """A UR10 with a once-per-turn error of joint 2, calibrated with that cause."""
    data, _ = simulate("ur10", "position", samples=300, seed=2, effects=["joint_periodic:joint=2,amplitude=0.05"])
    result = robocal.calibrate(data, robot="ur10", causes=["joint_periodic joint 2 harmonic=1"])
    path = tmp_path_factory.mktemp("periodic") / "result.json"
    path.write_text(json.dumps(result.to_dict()))
    return path


def test_calibrate_records_the_best_geometry_without_its_joint_causes(periodic):
    doc = json.loads(periodic.read_text())
    record = doc["geometry_only"]
    assert record["not_carried"] == ["joint_periodic joint 2 harmonic=1"]
    held = record["held_out"]
    assert held["full_model"] == doc["metrics"]["test"]
    other = "extended" if record["choice"] == "refit" else "refit"
    assert held[record["choice"]]["rmse"] <= held[other]["rmse"]
    # A geometry fitted with a cause it then loses predicts worse than one fitted alone here;
    # the full model, which keeps the cause, predicts best.
    assert record["choice"] == "refit" and held["full_model"]["rmse"] < held["refit"]["rmse"] < held["extended"]["rmse"]
    assert len(record["parameters"]) == len(doc["parameters"])


def test_export_of_an_extended_result_carries_the_chosen_geometry_and_says_what_it_leaves(periodic, tmp_path, capsys):
    out = tmp_path / "robot.urdf"
    assert main(["export", str(periodic), "--format", "urdf", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "not carried (a joint-by-joint geometry has no place for them): joint_periodic joint 2 harmonic=1" in printed
    assert "the geometry is fitted again without them" in printed and "the full model at" in printed
    text = out.read_text()
    assert "joint_periodic joint 2 harmonic=1" in text  # recorded in the file, not only printed
    doc = json.loads(periodic.read_text())
    chosen = robocal.Robot("ur10", robocal.robot("ur10").joints, np.array(doc["geometry_only"]["parameters"]))
    check = ex.roundtrip_check(chosen, str(out))
    assert check["max_position_error_mm"] < POS_TOL
    table = tmp_path / "robot.json"
    assert main(["export", str(periodic), "--format", "dh", "--out", str(table)]) == 0
    assert any("joint_periodic joint 2" in note for note in json.loads(table.read_text())["notes"])


def test_an_older_result_without_the_record_is_exported_with_its_cost_in_mm(periodic, tmp_path, capsys):
    doc = json.loads(periodic.read_text())
    del doc["geometry_only"]
    old = tmp_path / "old.json"
    old.write_text(json.dumps(doc))
    assert main(["export", str(old), "--format", "dh", "--out", str(tmp_path / "t.csv")]) == 0
    printed = capsys.readouterr().out
    assert "calibrate again for the best geometry without them" in printed
    assert "mm RMS (at most" in printed and "a CSV table has no room for these notes" in printed


def test_a_malformed_geometry_record_is_refused_naming_the_key(periodic, tmp_path, capsys):
    doc = json.loads(periodic.read_text())
    doc["geometry_only"]["parameters"] = doc["geometry_only"]["parameters"][:-1]
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    assert main(["export", str(bad), "--format", "urdf", "--out", str(tmp_path / "x.urdf")]) == 2
    assert "key 'geometry_only', key 'parameters'" in capsys.readouterr().err


def test_a_multi_session_result_records_its_geometry_without_joint_causes():
    effect = ["joint_periodic:joint=2,amplitude=0.05"]
    sessions = [simulate("ur10", "position", samples=200, seed=5, session=s, effects=effect)[0] for s in (0, 1)]
    result = robocal.calibrate(sessions, robot="ur10", causes=["joint_periodic joint 2 harmonic=1"])
    record = result.to_dict()["geometry_only"]
    assert record["not_carried"] == ["joint_periodic joint 2 harmonic=1"]
    assert record["held_out"]["full_model"]["rmse"] < min(record["held_out"][k]["rmse"] for k in ("extended", "refit"))
    assert record["held_out"]["extended"]["n"] == record["held_out"]["refit"]["n"] == result.metrics["test"]["n"]


def test_calibrate_verify_and_report_open_with_one_verdict_and_agree_on_the_nominal_figure(periodic, tmp_path, capsys):
    """A verdict first, in words; the nominal robot's figure is the same in verify and report."""
    from robocal.calibration.result import VERDICTS, verdict

    doc = json.loads(periodic.read_text())
    assert verdict(doc)[0] == "trusted"
    bad = {**doc, "implausible": [{"name": "a3", "unit": "mm", "deviation": 856.0, "limit": 10.0}]}
    word, why = verdict(bad)
    assert word == VERDICTS[1] and "a3 +856 mm" in why
    assert verdict({**doc, "convergence": {"success": False, "message": "stopped"}})[0] == VERDICTS[2]
    data, _ = simulate("ur10", "position", samples=150, seed=2, session=1, effects=["joint_periodic:joint=2,amplitude=0.05"])  # the same robot, a new session
    new = tmp_path / "new.csv"
    robocal.data.write_canonical(data, new)
    report = tmp_path / "verify.json"
    assert main(["verify", str(periodic), str(new), "--json", str(report), "--quiet"]) == 0
    first = capsys.readouterr().out.splitlines()[0]
    assert first.startswith("verdict: trusted: ") and "on these new data RMSE" in first
    nominal = json.loads(report.read_text())["nominal"]["metrics"]["rmse"]
    assert main(["report", str(periodic), "--data", str(new), "--out", str(tmp_path / "page"), "--quiet"]) == 0
    page = (tmp_path / "page" / "index.html").read_text()
    assert "Verdict: trusted" in page
    assert f"RMSE {nominal:.4g} mm with the nominal kinematics" in page
    other, _ = simulate("ur10", "position", samples=150, seed=9, session=1)  # another UR10's errors
    robocal.data.write_canonical(other, new)
    capsys.readouterr()
    assert main(["verify", str(periodic), str(new), "--quiet"]) == 0
    assert capsys.readouterr().out.startswith("verdict: not determined: on these new data it predicts worse than the nominal robot")


def test_the_nominal_robot_of_a_tracker_with_a_turned_probe_has_its_tool_orientation_fitted(datasets):
    """UR10 series A as poses, the probe mounted a quarter turn off the flange: the nominal
    figure beside a calibration fits the tool's orientation too (it was 90 deg off)."""
    series = datasets / "ipa-robot-accuracy-ur10"
    result = robocal.calibrate(str(series / "Series_A" / "measurements_grid.csv"), robot="ur10", measurement="pose").to_dict()
    report = robocal.verify(result, str(series / "Series_B" / "measurements_joint_configurations.csv"), measurement="pose")
    assert report["nominal"]["metrics"]["rotation_rmse_deg"] < 1.0
    assert report["nominal"]["metrics"]["rmse"] > report["metrics"]["rmse"]


def test_a_zero_offset_is_taken_the_turns_that_keep_the_readings_within_the_limits(tmp_path):
    """A joint read 90 deg over its angle, given as the offset 270 deg (as diagnose names it: its offsets are 90, 180
    and 270), put every model angle of the UR10's data beyond its 360 deg limits: the URDF's limits left out every
    reading the robot took, and the monitor refused every sample of the calibration's own data."""
    data, _ = simulate("ur10", "position", samples=250, seed=2)
    readings = data.q.copy()
    readings[:, 1] += np.radians(90.0)
    assert (np.degrees(readings[:, 1]) + 270.0 > 360.0).any()
    result = robocal.calibrate(replace(data, q=readings), robot="ur10", causes=["joint_zero joint 2 offset=270"]).to_dict()
    assert result["structure"] == ["joint_zero joint 2 offset=-90"]
    (tmp_path / "r.json").write_text(json.dumps(result))
    assert main(["export", str(tmp_path / "r.json"), "--format", "urdf", "--out", str(tmp_path / "r.urdf")]) == 0
    lower, upper = robocal.robot(str(tmp_path / "r.urdf")).joints[1].limits
    assert (readings[:, 1] >= lower).all() and (readings[:, 1] <= upper).all(), (lower, upper)
    from robocal.monitoring import Monitor

    monitor = Monitor(result)
    monitor.update(readings, data.y)
    assert not monitor.refused, monitor.refused[:3]
