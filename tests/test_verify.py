"""``robocal verify``: a calibration result on another session of the same robot."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

import robocal
from robocal.cli import main
from robocal.exceptions import InvalidParameterError
from robocal.simulation import simulate

PERIODIC = "joint_periodic:joint=2,amplitude=0.02,harmonic=2"


@pytest.fixture(scope="module")
def sessions():
    """Two sessions of one UR10 with a gear error on joint 2: the tracker stands elsewhere in the
    second, whose path and noise are new."""
    first, _ = simulate("ur10", "position", samples=400, seed=3, effects=[PERIODIC])
    second, _ = simulate("ur10", "position", samples=400, seed=3, session=1, effects=[PERIODIC])
    return first, second


def test_sessions_share_the_robot_and_not_the_setup():
    _, a = simulate("ur10", "position", samples=200, seed=5)
    _, b = simulate("ur10", "position", samples=200, seed=5, session=2)
    differs = sorted(n for n in a["parameters"] if a["parameters"][n]["value"] != b["parameters"][n]["value"])
    assert differs and all(n.startswith(("base_", "tool_")) for n in differs)
    shift = np.linalg.norm([b["parameters"][f"base_{c}"]["value"] - a["parameters"][f"base_{c}"]["value"] for c in "xyz"])
    assert shift > 10.0  # the tracker moved


def test_a_joint_cause_carries_to_a_new_session(sessions):
    """The gear error found in session 1 lowers the error on session 2, where only the tracker's
    base and the tool point are re-fitted; the nominal model is far worse than either."""
    first, second = sessions
    geometric = robocal.verify(robocal.calibrate(first).to_dict(), second)
    report = robocal.diagnose(first).to_dict()
    assert "joint_periodic joint 2 harmonic=2" in report["model"]["causes"]
    extended = robocal.verify(robocal.calibrate(first, causes=report).to_dict(), second)
    assert extended["applied"]["causes"] == ["joint_periodic joint 2 harmonic=2"]
    assert extended["refit"] == ["base_x", "base_y", "base_z", "base_rx", "base_ry", "base_rz", "tool_x", "tool_y", "tool_z"]
    assert extended["metrics"]["rmse"] < 0.5 * geometric["metrics"]["rmse"] < geometric["nominal"]["metrics"]["rmse"]
    assert extended["metrics"]["n"] == len(second)
    # the base found is the second session's, not the first one's
    assert abs(extended["setup"]["base_y"] - geometric["setup"]["base_y"]) < 1.0


def test_a_session_term_is_not_carried(tmp_path):
    """A step of the first session's cable zero is that session's: named as not applied, and the
    new session's error is that of the calibration without it."""
    first, _ = simulate("hsr-jr680", "cable", samples=500, seed=4, effects=["step:sample=250,size=0.3"])
    second, _ = simulate("hsr-jr680", "cable", samples=500, seed=4, session=1)
    report = robocal.diagnose(first).to_dict()
    step = [label for label in report["model"]["causes"] if label.startswith("step")]
    assert step, report["model"]["causes"]
    result = robocal.calibrate(first, causes=report)
    checked = robocal.verify(result.to_dict(), second)
    assert [item["label"] for item in checked["not_applied"]] == step
    assert checked["applied"]["causes"] == []
    assert checked["refit"] == ["anchor_x", "anchor_y", "anchor_z", "cable_offset"]
    assert checked["metrics"]["rmse"] < 0.1  # mm: the robot is right; the old zero step is gone
    # a cable length is no point: accuracy is the length's, no distance between targets
    iso = checked["iso9283"]
    assert iso["position_accuracy_mm"]["rms"] == pytest.approx(checked["metrics"]["rmse"], rel=1e-12)
    assert iso["distance_accuracy_mm"] is None and "not a point" in iso["absent"]["distance_accuracy_mm"]
    from robocal.acceptance import summary_rows

    assert summary_rows(iso)[0][0] == "length accuracy AP (cable)"


def test_reading_conventions_are_applied(sessions):
    """A result found with joint 4 read reversed applies the convention to the new readings."""
    first, second = sessions
    flip = lambda d: replace(d, q=d.q * np.where(np.arange(6) == 3, -1.0, 1.0))  # noqa: E731
    result = robocal.calibrate(flip(first), causes=["joint_sign joint 4"])
    checked = robocal.verify(result.to_dict(), flip(second))
    plain = robocal.verify(robocal.calibrate(first).to_dict(), second)
    assert checked["applied"]["structure"] == ["joint_sign joint 4"]
    assert checked["metrics"]["rmse"] == pytest.approx(plain["metrics"]["rmse"], rel=0.05)


def test_cli_writes_the_report_and_refuses_bad_results(tmp_path, sessions, capsys):
    first, second = sessions
    from robocal.data import write_canonical

    data = tmp_path / "second.csv"
    write_canonical(second, data)
    result = tmp_path / "result.json"
    result.write_text(json.dumps(robocal.calibrate(first).to_dict()))
    assert main(["verify", str(result), str(data), "--json", str(tmp_path / "v.json"), "--quiet"]) == 0
    report = json.loads((tmp_path / "v.json").read_text())
    assert set(report["metrics"]) == {"rmse", "mae", "max", "n"} and report["refit"][0] == "base_x"
    assert "calibrated: RMSE" in capsys.readouterr().out
    (tmp_path / "bad.json").write_text("{}")
    assert main(["verify", str(tmp_path / "bad.json"), str(data)]) == 2
    assert "not a robocal result file" in capsys.readouterr().err
    with pytest.raises(InvalidParameterError, match="cable"):
        robocal.verify(robocal.calibrate(first).to_dict(), second, measurement="cable")


def test_cli_prints_the_iso9283_table(tmp_path, sessions, capsys):
    """Random poses visit no target twice: repeatability is absent with its reason, and position
    data have no orientation; the figures the data allow are printed in the table."""
    first, second = sessions
    from robocal.cli.verify import summary

    report = robocal.verify(robocal.calibrate(first).to_dict(), second)
    iso = report["iso9283"]
    assert iso["n_targets"] == iso["n_measurements"] == len(second)
    assert iso["repeatability_mm"] is None and "more than once" in iso["absent"]["repeatability_mm"]
    assert iso["orientation_accuracy_deg"] is None and "orientation" in iso["absent"]["orientation_accuracy_deg"]
    # one visit per target: position accuracy is the per-sample error of the metrics
    assert iso["position_accuracy_mm"]["rms"] == pytest.approx(report["metrics"]["rmse"], rel=1e-12)
    assert iso["distance_accuracy_mm"]["n"] == len(second) * (len(second) - 1) // 2 and not iso["distance_accuracy_mm"]["sampled"]
    text = summary(report)
    assert "ISO 9283 (400 targets" in text and "distance accuracy AD" in text and "repeatability RP         absent: no target" in text


def test_repeated_poses_give_the_repeatability_their_noise_implies():
    """100 poses of a UR10 measured 5 times each with isotropic noise sigma: the distance of a visit
    to its barycentre is Maxwell distributed with scale sigma·sqrt(4/5), so RP = l̄ + 3 S_l is
    (2·sqrt(2/pi) + 3·sqrt(3 − 8/pi))·sigma·sqrt(4/5). Pose data: orientation accuracy is there."""
    first, _ = simulate("ur10", "pose", samples=300, seed=6)
    clean, _ = simulate("ur10", "pose", samples=300, seed=6, session=1, noise=0)
    repeated = clean.subset(np.repeat(np.arange(100), 5))
    sigma = 0.05
    y = repeated.y.copy()
    y[:, :3] += np.random.default_rng(0).normal(0.0, sigma, (len(y), 3))
    iso = robocal.verify(robocal.calibrate(first).to_dict(), replace(repeated, y=y))["iso9283"]
    assert iso["n_targets"] == 100 and iso["n_measurements"] == 500
    rp = iso["repeatability_mm"]
    assert rp["n_targets"] == 100 and rp["visits"] == [5, 5] and rp["n_measurements"] == 500
    expected = (2 * np.sqrt(2 / np.pi) + 3 * np.sqrt(3 - 8 / np.pi)) * sigma * np.sqrt(4 / 5)
    assert rp["rp"] == pytest.approx(expected, rel=0.1)
    assert all(v is not None for v in iso["targets"]["repeatability_mm"])
    assert iso["orientation_accuracy_deg"]["n"] == 100 and "orientation_accuracy_deg" not in iso["absent"]
    # a barycentre of 5 visits averages the noise: the targets' error is below the samples'
    assert iso["position_accuracy_mm"]["rms"] < 0.7 * np.sqrt(3) * sigma


def test_distance_accuracy_does_not_depend_on_the_registration():
    """Moving the measurement frame rigidly (a tracker registered elsewhere, not re-fitted) ruins
    position accuracy and leaves distance accuracy as it was."""
    from robocal.acceptance import iso9283
    from scipy.spatial.transform import Rotation

    data, truth = simulate("ur10", "position", samples=200, seed=2)
    true = robocal.robot("ur10").with_params(**{n: p["value"] for n, p in truth["parameters"].items()})
    predicted = true.predict("position", data.q)
    moved = Rotation.from_rotvec([0.1, -0.2, 0.3]).apply(data.y) + np.array([50.0, -20.0, 10.0])
    here = iso9283(data.y - predicted, data.y, data.q, "position")
    there = iso9283(moved - predicted, moved, data.q, "position")
    assert there["position_accuracy_mm"]["rms"] > 100 * here["position_accuracy_mm"]["rms"]
    for key in ("mean", "rms", "max"):
        assert there["distance_accuracy_mm"][key] == pytest.approx(here["distance_accuracy_mm"][key], rel=1e-9, abs=1e-12)


def test_distance_accuracy_samples_pairs_deterministically(monkeypatch):
    """Beyond MAX_PAIRS pairs of targets the figure comes from that many pairs drawn with a fixed
    seed: the same on every call, and near the all-pairs figure."""
    from robocal import acceptance

    rng = np.random.default_rng(1)
    q = rng.uniform(-3, 3, (300, 6))
    y = rng.uniform(-500, 500, (300, 3))
    r = rng.normal(0, 0.1, (300, 3))
    every = acceptance.iso9283(r, y, q, "position")["distance_accuracy_mm"]
    monkeypatch.setattr(acceptance, "MAX_PAIRS", 5000)
    drawn = acceptance.iso9283(r, y, q, "position")["distance_accuracy_mm"]
    assert drawn["sampled"] and drawn["n"] == 5000 and drawn["of_pairs"] == every["n"] == 300 * 299 // 2
    assert drawn == acceptance.iso9283(r, y, q, "position")["distance_accuracy_mm"]
    assert drawn["rms"] == pytest.approx(every["rms"], rel=0.05)


def test_a_plans_expected_readings_are_not_taken_for_measurements(tmp_path, sessions, capsys):
    """``plan --from`` writes the readings the model expects, to be overwritten with the sensor's:
    verified as they are, the calibrated model reproduces them exactly — no figure of the robot.
    verify says so and does not call them held out."""
    first, _ = sessions
    result = tmp_path / "r.json"
    result.write_text(json.dumps(robocal.calibrate(first, robot="ur10").to_dict()))
    assert main(["plan", "--from", str(result), "--poses", "12", "--out", str(tmp_path / "p.csv"), "--quiet"]) == 0
    capsys.readouterr()
    report = robocal.verify(str(result), str(tmp_path / "p.csv"))
    assert report["held_out"] is False
    assert any("not measurements" in note for note in report["notes"])
    assert "its own predictions" in report["verdict"]["why"]
