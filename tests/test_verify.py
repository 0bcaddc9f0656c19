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
    from robocal.data.canonical import write_canonical

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
