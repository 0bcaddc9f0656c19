"""``robocal export``: DH / MDH tables and URDF of a calibrated robot that reproduce its tool
frame (the round-trip check reads them back with robocal's readers; a URDF is cross-checked by
yourdfpy's own forward kinematics), the files load back, bad input fails clearly, and the
round-trip check catches an export that is wrong."""

from __future__ import annotations

import argparse
import csv
import io
import json
import sys
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import robocal
from robocal import export as ex
from robocal.cli import export as export_cli
from robocal.exceptions import InvalidParameterError, MissingDependencyError
from robocal.results import load_result
from robocal.simulation import simulate

from helpers import three_joint_robot

POS_TOL, ROT_TOL = 1e-6, 1e-9  # mm, rad


def _result_file(tmp_path_factory, robot: str, measurement: str) -> str:
    data, _ = simulate(robot, measurement, samples=150, seed=2)
    res = robocal.calibrate(data, robot=robot)
    path = tmp_path_factory.mktemp("export") / f"{robot}-{measurement}.json"
    path.write_text(json.dumps(res.to_dict()))
    return str(path)


@pytest.fixture(scope="module")
def ur10_file(tmp_path_factory):
    """UR10 calibrated from tracker positions: a non-zero base frame."""
    return _result_file(tmp_path_factory, "ur10", "position")


@pytest.fixture(scope="module")
def hsr_file(tmp_path_factory):
    """HSR JR680 calibrated from cable lengths: a Hayati joint (joint 2), base frame zero."""
    return _result_file(tmp_path_factory, "hsr-jr680", "cable")


@pytest.fixture(params=["ur10", "hsr"])
def calibrated(request, ur10_file, hsr_file):
    path = {"ur10": ur10_file, "hsr": hsr_file}[request.param]
    robot, _ = load_result(path)
    return path, robot


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="robocal export")
    export_cli.add_arguments(parser)
    return parser


def _yourdfpy_fkine(urdf: str, q: np.ndarray, link: str) -> np.ndarray:
    """Poses (mm) of ``link`` in the root link's frame by yourdfpy's scene graph, which shares
    nothing with robocal's chain: an oracle for the export."""
    yourdfpy = pytest.importorskip("yourdfpy")
    model = yourdfpy.URDF.load(io.BytesIO(urdf.encode()), build_scene_graph=True, load_meshes=False)
    poses = []
    for qi in q:
        model.update_cfg({f"joint{j}": v for j, v in enumerate(qi, start=1)})
        poses.append(model.get_transform(link))
    poses = np.array(poses)
    poses[:, :3, 3] *= 1000.0
    return poses


def _assert_exact(check: dict) -> None:
    assert check["samples"] == 200
    assert check["max_position_error_mm"] < POS_TOL, check
    assert check["max_rotation_error_rad"] < ROT_TOL, check


# --------------------------------------------------------------------------------------------
# Round trips
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("convention", ["dh", "mdh"])
@pytest.mark.parametrize("table_format", ["csv", "json"])
def test_table_round_trip_is_exact(calibrated, convention, table_format, tmp_path):
    _, robot = calibrated
    rows = ex.export_table(robot, convention)
    _assert_exact(ex.roundtrip_check(robot, rows))
    path = ex.write_table(rows, tmp_path / f"table.{table_format}", name=robot.name)
    _assert_exact(ex.roundtrip_check(robot, path))
    back = ex.read_table(path)
    assert [r["frame"] for r in back] == [f"joint{j}" for j in range(1, 7)] + ["base", "tool"]
    assert all(r["convention"] == convention for r in back[:6])


def test_dh_table_holds_the_calibrated_values(calibrated):
    _, robot = calibrated
    rows = ex.export_table(robot, "dh")
    for j, row in enumerate(rows[:6], start=1):
        assert row["a_mm"] == robot.params[robot.index(f"a{j}")]
        assert math.radians(row["theta_deg"]) == pytest.approx(robot.params[robot.index(f"theta{j}")], abs=1e-15)
        assert math.radians(row["beta_deg"]) == pytest.approx(robot.params[robot.index(f"beta{j}")], abs=1e-15)
        assert row["hayati"] == robot.joints[j - 1].hayati
        assert math.radians(row["lower"]) == pytest.approx(robot.joints[j - 1].limits[0])
    assert rows[-2]["x_mm"] == robot.params[robot.index("base_x")]
    assert math.radians(rows[-1]["rz_deg"]) == pytest.approx(robot.params[robot.index("tool_rz")], abs=1e-15)


def test_hayati_beta_is_exported(hsr_file):
    robot, _ = load_result(hsr_file)
    assert robot.joints[1].hayati
    row = ex.export_table(robot, "dh")[1]
    assert row["hayati"] is True and row["beta_deg"] != 0.0  # estimated by the cable calibration


def test_urdf_round_trip_and_structure(calibrated):
    _, robot = calibrated
    urdf = ex.export_urdf(robot)
    _assert_exact(ex.roundtrip_check(robot, urdf))
    root = ET.fromstring(urdf)
    assert root.tag == "robot" and root.get("name") == robot.name
    revolute = [j for j in root.iter("joint") if j.get("type") == "revolute"]
    assert [j.get("name") for j in revolute] == [f"joint{k}" for k in range(1, 7)]
    for joint, el in zip(robot.joints, revolute):
        limit = el.find("limit")
        assert float(limit.get("lower")) == joint.limits[0] and float(limit.get("upper")) == joint.limits[1]
        assert el.find("axis").get("xyz") == "0 0 1"
    links = {link.get("name") for link in root.iter("link")}
    assert {"base_link", "flange", "tool0"} | {f"link{k}" for k in range(1, 7)} <= links
    base_nonzero = np.any(robot.params[robot.index("base_x") : robot.index("base_x") + 6] != 0)
    assert ("world" in links) == bool(base_nonzero)
    # yourdfpy's forward kinematics of the file: tool0 is robocal's tool frame, flange its flange.
    q = np.random.default_rng(3).uniform(-1, 1, (20, 6))
    assert np.abs(_yourdfpy_fkine(urdf, q, "tool0") - robot.fkine(q, tool=True)).max() < POS_TOL
    assert np.abs(_yourdfpy_fkine(urdf, q, "flange") - robot.fkine(q)).max() < POS_TOL


def test_robot_reads_the_urdf_back_with_its_flange_and_tool(calibrated, tmp_path):
    """Issue 27: ``robocal.robot(exported.urdf).fkine(q)`` is the exporting robot's flange (it
    was joint 6's frame, 200 mm short on the HSR) and ``fkine(q, tool=True)`` its tool, to 1e-9 mm."""
    _, robot = calibrated
    path = tmp_path / "robot.urdf"
    path.write_text(ex.export_urdf(robot))
    back = robocal.robot(str(path))
    q = np.random.default_rng(4).uniform(-3.0, 3.0, (200, robot.n_joints))
    for tool in (False, True):
        want, got = robot.fkine(q, tool=tool), back.fkine(q, tool=tool)
        assert np.abs(got[:, :3, 3] - want[:, :3, 3]).max() < 1e-9
        assert np.abs(got[:, :3, :3] - want[:, :3, :3]).max() < ROT_TOL


def test_ur10_has_a_world_link(ur10_file):
    robot, _ = load_result(ur10_file)
    root = ET.fromstring(ex.export_urdf(robot))
    world = [j for j in root.iter("joint") if j.find("parent").get("link") == "world"]
    assert len(world) == 1 and world[0].get("type") == "fixed"


def test_urdf_of_an_mdh_robot(calibrated):
    _, robot = calibrated
    _assert_exact(ex.roundtrip_check(robot, ex.export_urdf(robot.to_mdh())))


def test_prismatic_joint():
    robot = three_joint_robot(["dh"] * 3, ["revolute", "prismatic", "revolute"])
    urdf = ex.export_urdf(robot)
    _assert_exact(ex.roundtrip_check(robot, urdf))
    prismatic = [j for j in ET.fromstring(urdf).iter("joint") if j.get("type") == "prismatic"]
    assert len(prismatic) == 1 and float(prismatic[0].find("limit").get("upper")) == pytest.approx(0.4)  # m
    for convention in ("dh", "mdh"):
        rows = ex.export_table(robot, convention)
        assert rows[1]["kind"] == "prismatic" and rows[1]["upper"] == 400.0  # mm
        _assert_exact(ex.roundtrip_check(robot, rows))


def test_mixed_convention_chain():
    robot = three_joint_robot(["dh", "mdh", "mdh"], ["revolute", "revolute", "prismatic"])
    _assert_exact(ex.roundtrip_check(robot, ex.export_urdf(robot)))
    for convention in ("dh", "mdh"):
        with pytest.raises(InvalidParameterError, match="modified DH only"):
            ex.export_table(robot, convention)


# --------------------------------------------------------------------------------------------
# The check has teeth
# --------------------------------------------------------------------------------------------
def test_round_trip_catches_a_dropped_theta_offset(hsr_file):
    robot, _ = load_result(hsr_file)
    naive = robot.with_params(theta3=0.0)  # "URDF has no joint offset": forgetting theta is wrong
    check = ex.roundtrip_check(robot, ex.export_urdf(naive))
    assert check["max_position_error_mm"] > 1.0


def test_urdf_export_without_yourdfpy_writes_nothing(ur10_file, tmp_path, monkeypatch):
    """The URDF is checked by reading it back, which needs yourdfpy: without it the export is
    refused by name before anything is written."""
    monkeypatch.setitem(sys.modules, "yourdfpy", None)  # import yourdfpy now raises ImportError
    out = tmp_path / "r.urdf"
    with pytest.raises(MissingDependencyError, match=r"URDF export.*pip install 'robocal\[urdf\]'"):
        export_cli.run(_parser().parse_args([ur10_file, "--format", "urdf", "--out", str(out)]))
    assert list(tmp_path.iterdir()) == []


def test_run_fails_when_the_export_is_wrong(hsr_file, tmp_path, monkeypatch, capsys):
    good = ex.export_urdf
    monkeypatch.setattr(
        ex, "export_urdf", lambda robot, name=None, notes=(): good(robot.with_params(a2=robot.params[robot.index("a2")] + 1e-3), name, notes=notes)
    )
    code = export_cli.run(_parser().parse_args([hsr_file, "--format", "urdf", "--out", str(tmp_path / "r.urdf")]))
    assert code == 1
    assert "does not reproduce" in capsys.readouterr().out


# --------------------------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("fmt", ["dh", "mdh"])
def test_cli_writes_a_csv_table(calibrated, fmt, tmp_path, capsys):
    path, robot = calibrated
    out = tmp_path / f"robot_{fmt}.csv"
    assert export_cli.run(_parser().parse_args([path, "--format", fmt, "--out", str(out)])) == 0
    printed = capsys.readouterr().out
    assert str(out) in printed and "round trip over 200 joint vectors" in printed
    with out.open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == list(ex.TABLE_COLUMNS)
    joint_rows = [r for r in rows if r["frame"].startswith("joint")]
    assert len(joint_rows) == robot.n_joints and all(r["convention"] == fmt for r in joint_rows)
    assert [r["frame"] for r in rows[-2:]] == ["base", "tool"]
    assert all(r["x_mm"] == "" for r in joint_rows) and all(r["alpha_deg"] == "" for r in rows[-2:])
    float(rows[-1]["z_mm"])


def test_cli_json_table_and_urdf(ur10_file, tmp_path, capsys):
    out = tmp_path / "robot.json"
    assert export_cli.run(_parser().parse_args([ur10_file, "--format", "mdh", "--out", str(out)])) == 0
    doc = json.loads(out.read_text())
    assert doc["schema"] == ex.TABLE_SCHEMA and doc["convention"] == "mdh" and len(doc["rows"]) == 8
    out = tmp_path / "robot.txt"
    assert export_cli.run(_parser().parse_args([ur10_file, "--format", "dh", "--table-format", "json", "--out", str(out)])) == 0
    assert json.loads(out.read_text())["convention"] == "dh"
    out = tmp_path / "ur10.urdf"
    assert export_cli.run(_parser().parse_args([ur10_file, "--format", "urdf", "--name", "my_ur10", "--out", str(out)])) == 0
    assert ET.parse(out).getroot().get("name") == "my_ur10"
    assert "URDF" in capsys.readouterr().out


def test_cli_bad_input(ur10_file, tmp_path):
    parser = _parser()
    with pytest.raises(SystemExit):
        parser.parse_args([ur10_file, "--format", "sdf", "--out", str(tmp_path / "x")])
    with pytest.raises(SystemExit):
        parser.parse_args([ur10_file, "--format", "dh", "--table-format", "xlsx", "--out", str(tmp_path / "x")])
    with pytest.raises(InvalidParameterError, match="table-format"):
        export_cli.run(parser.parse_args([ur10_file, "--format", "urdf", "--table-format", "csv", "--out", str(tmp_path / "x.urdf")]))
    not_a_result = tmp_path / "other.json"
    not_a_result.write_text("{}")
    with pytest.raises(InvalidParameterError, match="not a robocal result file"):
        export_cli.run(parser.parse_args([str(not_a_result), "--format", "dh", "--out", str(tmp_path / "x.csv")]))
    mdh = robocal.robot("ur10").to_mdh()
    with pytest.raises(InvalidParameterError, match="modified DH only"):
        ex.export_table(mdh, "dh")
    with pytest.raises(InvalidParameterError, match="convention"):
        ex.export_table(mdh, "xyz")


@pytest.mark.parametrize("convention", ["dh", "mdh"])
@pytest.mark.parametrize("table_format", ["csv", "json"])
def test_robot_reads_what_export_writes(calibrated, convention, table_format, tmp_path):
    """``robocal.robot(path)`` takes an exported table back: the same tool poses as the
    calibrated robot; a robot file (JSON) is still read as one, and a JSON that is neither is
    refused by name."""
    _, robot = calibrated
    path = ex.write_table(ex.export_table(robot, convention), tmp_path / f"robot.{table_format}")
    back = robocal.robot(str(path))
    q = np.random.default_rng(3).uniform(-2.0, 2.0, (30, robot.n_joints))
    assert np.allclose(back.fkine(q, tool=True), robot.fkine(q, tool=True), atol=1e-9)
    assert {j.convention for j in back.joints} == {convention}
    (tmp_path / "file.json").write_text(
        json.dumps({"name": "two", "joints": [{"alpha": 90, "a": 0, "d": 100, "theta": 0}, {"alpha": 0, "a": 300, "d": 0, "theta": 0}]})
    )
    assert robocal.robot(str(tmp_path / "file.json")).n_joints == 2
    (tmp_path / "other.json").write_text(json.dumps({"schema": "something/1"}))
    with pytest.raises(InvalidParameterError, match="other.json"):
        robocal.robot(str(tmp_path / "other.json"))


@settings(deadline=None, max_examples=20, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(
    fmt=st.sampled_from(["dh", "urdf"]),
    table_format=st.sampled_from([None, "csv", "json"]),
    suffix=st.sampled_from([".csv", ".json", ".urdf", ".txt", ""]),
)
def test_an_export_is_read_back_or_a_note_says_why_not(ur10_file, tmp_path_factory, capsys, fmt, table_format, suffix):
    """Issue 52 #22: ``--format urdf --out e.csv`` was written without a note, and reading it back
    failed naming no file. Whatever the suffix, ``robocal.robot`` reads the export back, or the
    export printed a note saying under which suffix it would, and the reader's error names the file."""
    if fmt == "urdf" and table_format is not None:
        return  # refused: --table-format applies to tables (test_cli_bad_input)
    out = tmp_path_factory.mktemp("suffix") / f"e{suffix}"
    argv = [ur10_file, "--format", fmt, "--out", str(out), "--samples", "5"] + (["--table-format", table_format] if table_format else [])
    assert export_cli.run(_parser().parse_args(argv)) == 0
    noted = "note:" in capsys.readouterr().out
    try:
        back = robocal.robot(str(out))
    except InvalidParameterError as exc:
        assert noted and str(out) in str(exc), (noted, str(exc))
    else:
        assert not noted
        robot, _ = load_result(ur10_file)
        q = np.random.default_rng(3).uniform(-2.0, 2.0, (10, robot.n_joints))
        assert np.allclose(back.fkine(q, tool=True), robot.fkine(q, tool=True), atol=1e-6)


def test_a_table_with_a_misnamed_column_is_refused_by_name(hsr_file, tmp_path):
    """A column the reader does not know was read as missing (its values dropped silently)."""
    robot, _ = load_result(hsr_file)
    path = ex.write_table(ex.export_table(robot, "dh"), tmp_path / "t.csv")
    path.write_text(path.read_text().replace("theta_deg", "theta_dg", 1))
    with pytest.raises(InvalidParameterError, match=r"t\.csv, row 1: not a robocal parameter table .*missing \['theta_deg'\]; unknown \['theta_dg'\]"):
        robocal.robot(str(path))


def test_a_result_under_a_table_suffix_says_how_it_is_read(hsr_file, tmp_path):
    """A result file saved as ``r.csv`` is read as a parameter table (by its suffix): the error says so."""
    path = tmp_path / "r.csv"
    path.write_text(open(hsr_file).read())
    with pytest.raises(InvalidParameterError, match=r"r\.csv: not a robocal parameter table .*by its suffix: name it \.json"):
        robocal.robot(str(path))
