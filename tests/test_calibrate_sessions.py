"""One robot from several sessions: ``robocal.calibrate([a, b, c])`` and ``robocal calibrate A B C``."""

import json
import shutil

import numpy as np
import pytest

import robocal
from robocal.cli import main
from robocal.data import write_canonical
from robocal.results import file_sha256
from robocal.exceptions import InvalidParameterError

BACKLASH = "backlash:joint=2,width=0.03"


def sessions(n=3, samples=240, effects=(BACKLASH,), robot="ur10", measurement="position"):
    """``n`` sessions of one simulated robot (same kinematic errors and effects, new set-ups) and the truth."""
    out = [robocal.simulate(robot, measurement, samples=samples, seed=7, session=s, effects=list(effects)) for s in range(n)]
    return [d for d, _ in out], out[0][1]


def test_sessions_fit_one_robot_and_find_the_cause():
    data, truth = sessions()
    result = robocal.calibrate(data, causes=["backlash joint 2"])
    doc = result.to_dict()
    width = next(c for c in doc["causes"] if c["kind"] == "backlash")["params"]["width"]["value"]
    assert width == pytest.approx(0.03, abs=0.003)
    noise = truth["noise"]["sigma"]["value"]  # mm per axis
    assert len(doc["sessions"]) == 3
    for session in doc["sessions"]:
        assert session["metrics"]["test"]["rmse"] < 1.5 * np.sqrt(3) * noise  # within 1.5x the noise floor of a 3-D position
        assert set(session["setup"]) >= {"base_x", "base_rz", "tool_z"}
    # each session keeps its own set-up: the simulated placements differ by tens of mm
    bases = np.array([[s["setup"]["base_x"], s["setup"]["base_y"], s["setup"]["base_z"]] for s in doc["sessions"]])
    assert np.ptp(bases, axis=0).max() > 1.0
    assert doc["metrics"]["test"]["n"] == sum(s["metrics"]["test"]["n"] for s in doc["sessions"])


def test_a_robot_from_sessions_predicts_a_session_it_never_saw(tmp_path):
    data, _ = sessions(n=4)
    result = robocal.calibrate(data[:3], causes=["backlash joint 2"])
    path = tmp_path / "robot.json"
    path.write_text(json.dumps(result.to_dict()))
    seen = robocal.verify(path, data[3])
    geometric = robocal.calibrate(data[:3])
    path_geometric = tmp_path / "geometric.json"
    path_geometric.write_text(json.dumps(geometric.to_dict()))
    assert seen["metrics"]["rmse"] < 0.06
    assert seen["metrics"]["rmse"] < 0.8 * robocal.verify(path_geometric, data[3])["metrics"]["rmse"]  # the cause carries


def test_a_joint_map_spans_every_session():
    data, _ = sessions(n=2, effects=("joint_periodic:joint=2,amplitude=0.02,harmonic=5",))
    q2 = [np.degrees(d.q[:, 1]) for d in data]
    result = robocal.calibrate(data, causes=["joint_map joint 2 spacing=5.0 roughness=0.03"], test_fraction=0.0)
    detail = next(c for c in result.to_dict()["causes"] if c["kind"] == "joint_map")["detail"]
    assert detail["lo"] <= min(q.min() for q in q2) + 1e-6 and detail["hi"] >= max(q.max() for q in q2) - 1e-6


def test_the_same_session_twice_is_refused(tmp_path):
    data, _ = sessions(n=2, samples=60)
    with pytest.raises(InvalidParameterError, match="the same samples"):
        robocal.calibrate([data[0], data[1], data[0]])


def test_sessions_of_other_robots_or_measurements_are_refused():
    ur10, _ = sessions(n=1, samples=60)
    hsr, _ = sessions(n=1, samples=60, robot="hsr-jr680", measurement="cable", effects=())
    with pytest.raises(InvalidParameterError, match="session 2"):
        robocal.calibrate([ur10[0], hsr[0]])


def test_a_step_needs_the_multi_session_report():
    data, _ = sessions(n=2, samples=60)
    with pytest.raises(InvalidParameterError, match="multi-session diagnose report"):
        robocal.calibrate(data, causes=["step sample=20 row=22"])
    with pytest.raises(InvalidParameterError, match="method 'lm'"):
        robocal.calibrate(data, method="ukf-vslm")


def test_cli_calibrates_sessions_and_refuses_a_file_twice(tmp_path, capsys):
    data, _ = sessions(n=2, samples=120)
    files = []
    for i, d in enumerate(data):
        files.append(tmp_path / f"s{i}.csv")
        write_canonical(d, files[-1])
    out = tmp_path / "robot.json"
    assert main(["calibrate", *map(str, files), "--robot", "ur10", "--causes", "backlash joint 2", "--out", str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "session 1 (" in printed and "session 2 (" in printed
    doc = json.loads(out.read_text())
    assert [s["sha256"] for s in doc["sessions"]] == [file_sha256(f) for f in files]
    copy = tmp_path / "copy.csv"
    shutil.copy(files[0], copy)
    assert main(["calibrate", str(files[0]), str(files[1]), str(copy), "--robot", "ur10", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "the same samples" in err and "Traceback" not in err


def test_sessions_recorded_in_other_angle_units_are_read_each_in_its_own(tmp_path, capsys):
    data, _ = sessions(n=2, samples=120, effects=())
    files = [write_canonical(data[0], tmp_path / "deg.csv"), write_canonical(data[1], tmp_path / "rad.csv", angle_unit="rad")]
    both = [str(f) for f in files]
    # Before, one unit for both: the radian file could only be refused, naming it.
    assert main(["calibrate", *both, "--robot", "ur10", "--quiet"]) == 2
    assert "rad.csv" in capsys.readouterr().err
    out = tmp_path / "r.json"
    assert main(["calibrate", *both, "--robot", "ur10", "--angle-unit", "deg,rad", "--out", str(out), "--quiet"]) == 0
    each = robocal.calibrate(data, robot="ur10").to_dict()
    assert json.loads(out.read_text())["metrics"]["train"]["rmse"] == pytest.approx(each["metrics"]["train"]["rmse"], rel=1e-6)
    assert main(["calibrate", *both, "--robot", "ur10", "--angle-unit", "deg,rad,deg", "--quiet"]) == 2
    assert "3 units for 2 file(s)" in capsys.readouterr().err
    assert main(["calibrate", both[0], "--robot", "ur10", "--angle-unit", "deg,rad", "--quiet"]) == 2
    assert "2 units for 1 file(s)" in capsys.readouterr().err
    with pytest.raises(InvalidParameterError, match="3 units for 2 sessions"):
        robocal.calibrate(both, robot="ur10", angle_unit=["deg", "rad", "deg"])
    with pytest.raises(SystemExit):  # argparse's usage error
        main(["calibrate", *both, "--robot", "ur10", "--angle-unit", "deg,grad", "--quiet"])
    assert "deg or rad; got 'grad'" in capsys.readouterr().err


def test_verify_on_a_session_the_robot_was_fitted_on_says_so(tmp_path):
    data, _ = sessions(n=2, samples=120)
    files = [write_canonical(d, tmp_path / f"s{i}.csv") for i, d in enumerate(data)]
    path = tmp_path / "robot.json"
    path.write_text(json.dumps(robocal.calibrate([str(f) for f in files], robot="ur10").to_dict()))
    seen = robocal.verify(path, str(files[1]), measurement="position")
    assert seen["held_out"] is False and "training samples of session 2 of the calibration" in seen["notes"][0]


def test_report_of_sessions_draws_the_first_session(tmp_path):
    data, _ = sessions(n=2, samples=120)
    files = [write_canonical(d, tmp_path / f"s{i}.csv") for i, d in enumerate(data)]
    path = tmp_path / "robot.json"
    path.write_text(json.dumps(robocal.calibrate([str(f) for f in files], robot="ur10", causes=["backlash joint 2"]).to_dict()))
    assert main(["report", str(path), "--out", str(tmp_path / "report"), "--quiet"]) == 0
    page = (tmp_path / "report" / "index.html").read_text()
    assert "session 1 of 2" in page and (tmp_path / "report" / "residuals_samples.png").is_file()


def test_a_report_on_three_sessions_calibrates_two_and_refuses_one_it_never_saw(tmp_path, capsys):
    """Checking on a session left out is one line: the causes of a three-session report serve a
    fit on two of its sessions (each with its own terms, found by its file); a session the
    report never diagnosed is refused in words."""
    data, _ = sessions(n=4, samples=120, effects=())
    files = []
    for i, d in enumerate(data):
        files.append(tmp_path / f"s{i}.csv")
        write_canonical(d, files[-1])
    report = tmp_path / "diagnosis.json"
    assert main(["diagnose", *map(str, files[:3]), "--robot", "ur10", "--json", str(report), "--quiet"]) == 0
    out = tmp_path / "two.json"
    assert main(["calibrate", str(files[0]), str(files[2]), "--robot", "ur10", "--causes", str(report), "--out", str(out), "--quiet"]) == 0
    listed = json.loads(report.read_text())["model"]["sessions"]
    doc = json.loads(out.read_text())
    assert [s["terms"] for s in doc["sessions"]] == [listed[0]["causes"], listed[2]["causes"]]
    capsys.readouterr()
    assert main(["calibrate", str(files[0]), str(files[3]), "--robot", "ur10", "--causes", str(report), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"session {files[3]} is not among the report's sessions" in err and "Traceback" not in err
