"""One robot schema (``robocal.robot/1``): ``robocal.write_robot`` / ``robocal.robot`` round-trip every
field exactly; the result file's ``robot_model`` is the same document (older result files still
read); ``robocal.robot(path)`` reads robot, result and robot_model files; robot files written
before the schema still read; optional dependencies fail with a clear error."""

from __future__ import annotations

import json
import math
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import robocal
from robocal.catalog import BUILTIN
from robocal.exceptions import InvalidParameterError, MissingDependencyError, RobocalError
from robocal.results import load_result
from robocal.serial_robot import Joint, Robot
from robocal.robot_file import robot_document
from robocal.robot_table import export_table, robot_from_table


def _assert_identical(a: Robot, b: Robot):
    assert a.name == b.name and a.joints == b.joints
    np.testing.assert_array_equal(a.params, b.params)


def _everything(name="everything") -> Robot:
    """Every field away from its default: mixed conventions, a prismatic joint, Hayati, beta,
    base, tool and sensor."""
    joints = [Joint("dh", "revolute", False, (-2.5, 2.9)), Joint("mdh", "prismatic", True, (-10.0, 400.0)), Joint("dh", "revolute", True, (-1.0, 1.0))]
    params = np.r_[0.3, 120.1, 400.2, 0.2, 1e-17, -1.2, 35.0, 80.0, 0.1, 0.01, 0.4, 20.0, 60.0, -0.3, 0.02 / 3, 10.0, -5.0, 3.0, 0.01, -0.02, 0.3]
    params = np.r_[params, 1.0, 2.0, 90.0, 0.1, 0.2, -math.pi / 3, 1500.5, 300.25, -200.0, 950.0, 1.0001]
    return Robot(name, joints, params)


@pytest.mark.parametrize("suffix", [".json", ".yaml"])
@pytest.mark.parametrize("which", sorted(BUILTIN) + ["everything"])
def test_to_file_from_file_is_exact(which, suffix, tmp_path):
    r = _everything() if which == "everything" else robocal.robot(which)
    path = robocal.write_robot(r, tmp_path / f"robot{suffix}")
    _assert_identical(robocal.robot(path), r)
    _assert_identical(robocal.robot(str(path)), r)
    in_degrees = robocal.robot(robocal.write_robot(r, tmp_path / f"deg{suffix}", degrees=True))
    assert in_degrees.joints == r.joints or np.allclose([j.limits for j in in_degrees.joints], [j.limits for j in r.joints], rtol=1e-15)
    np.testing.assert_allclose(in_degrees.params, r.params, rtol=1e-15, atol=1e-15)


@settings(max_examples=40, deadline=None)
@given(
    values=st.lists(st.floats(-1e4, 1e4, allow_subnormal=True), min_size=5 * 3 + 17, max_size=5 * 3 + 17),
    conventions=st.lists(st.sampled_from(["dh", "mdh"]), min_size=3, max_size=3),
    kinds=st.lists(st.sampled_from(["revolute", "prismatic"]), min_size=3, max_size=3),
    hayati=st.lists(st.booleans(), min_size=3, max_size=3),
)
def test_any_robot_round_trips_exactly(values, conventions, kinds, hayati, tmp_path_factory):
    r = Robot("h", [Joint(c, k, h, (-1.5, 2.5)) for c, k, h in zip(conventions, kinds, hayati)], np.array(values))
    folder = tmp_path_factory.mktemp("rf")
    for suffix in (".json", ".yml"):
        _assert_identical(robocal.robot(robocal.write_robot(r, folder / f"r{suffix}")), r)


def test_the_document_has_every_field_and_units():
    doc = robot_document(_everything(), degrees=True)
    assert doc["schema"] == "robocal.robot/1" and doc["units"] == {"length": "mm", "angle": "deg"}
    assert list(doc["joints"][1]) == ["convention", "kind", "alpha", "a", "d", "theta", "beta", "hayati", "limits"]
    assert doc["joints"][1]["limits"] == [-10.0, 400.0]  # mm: prismatic
    assert doc["joints"][0]["limits"] == pytest.approx([math.degrees(-2.5), math.degrees(2.9)])
    assert doc["tool"]["rz"] == pytest.approx(-60.0) and doc["sensor"]["cable_scale"] == 1.0001


def test_files_written_before_the_schema_still_read(tmp_path):
    old = {
        "name": "old",
        "convention": "mdh",
        "description": "hand-written",
        "joints": [{"alpha": 0, "a": 0, "d": 100, "theta": 0, "limits": [-90, 90]}, {"alpha": 90, "a": 300, "d": 0, "theta": -90, "hayati": True}],
    }
    (tmp_path / "old.json").write_text(json.dumps(old))
    r = robocal.robot(str(tmp_path / "old.json"))
    _assert_identical(r, Robot.from_dh("old", [(0, 0, 100, 0, (-90, 90)), (90, 300, 0, -90, (-180, 180), True)], convention="mdh"))


def test_the_export_table_and_the_robot_file_are_one_robot(tmp_path):
    r = robocal.robot("hsr-jr680").with_params(beta2=1e-3, base_x=10.0, tool_z=100.0, tool_rx=0.2)
    from_table = robot_from_table(export_table(r, "dh"))
    from_file = robocal.robot(robocal.write_robot(r, tmp_path / "r.json"))
    np.testing.assert_allclose(from_table.params, from_file.params, rtol=1e-15, atol=1e-15)
    assert from_table.joints == from_file.joints


# --------------------------------------------------------------------------------------------
# Result files
# --------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def result_path(tmp_path_factory):
    from robocal.simulation import simulate

    data, _ = simulate("abb-irb120", "position", samples=100, seed=1)
    path = tmp_path_factory.mktemp("res") / "result.json"
    path.write_text(json.dumps(robocal.calibrate(data, robot="abb-irb120").to_dict()))
    return path


def test_result_robot_model_is_a_robot_document(result_path, tmp_path):
    doc = json.loads(result_path.read_text())
    model = doc["robot_model"]
    assert model["schema"] == "robocal.robot/1" and model["units"]["angle"] == "rad"
    nominal = robocal.robot("abb-irb120")
    assert model["nominal"] == nominal.params.tolist()  # the vector form stays for robocal.result/1 readers
    # the section on its own is the nominal robot; the result file is the calibrated one
    (tmp_path / "model.json").write_text(json.dumps(model))
    _assert_identical(robocal.robot(str(tmp_path / "model.json")), nominal)
    calibrated, _ = load_result(result_path)
    _assert_identical(robocal.robot(str(result_path)), calibrated)
    assert not np.array_equal(calibrated.params, nominal.params)


def test_older_result_files_still_load(result_path, tmp_path):
    doc = json.loads(result_path.read_text())
    robot = robocal.robot("abb-irb120")
    doc["robot_model"] = {
        "name": robot.name,
        "joints": [{"convention": j.convention, "kind": j.kind, "hayati": j.hayati, "limits": list(j.limits)} for j in robot.joints],
        "nominal": robot.params.tolist(),
    }
    (tmp_path / "old.json").write_text(json.dumps(doc))
    _assert_identical(load_result(tmp_path / "old.json")[0], load_result(result_path)[0])
    (tmp_path / "old_model.json").write_text(json.dumps(doc["robot_model"]))
    _assert_identical(robocal.robot(str(tmp_path / "old_model.json")), robot)


def test_a_bad_robot_model_in_a_result_is_named(result_path, tmp_path):
    doc = json.loads(result_path.read_text())
    doc["robot_model"]["joints"][2]["kind"] = "spherical"
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    with pytest.raises(InvalidParameterError, match=r"bad.json: key 'robot_model', joint 3, key 'kind'"):
        load_result(tmp_path / "bad.json")


# --------------------------------------------------------------------------------------------
# Bad robot files
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "change, message",
    [
        ({"base": {"x": 1.0, "yaw": 2.0}}, r"key 'base', key 'yaw': unknown key \(allowed: x, y, z, rx, ry, rz\)"),
        ({"units": {"angle": "grad"}}, r"key 'units', key 'angle': input should be 'deg' or 'rad'"),
        ({"units": {"length": "m"}}, r"key 'units', key 'length': input should be 'mm'"),
        ({"sensor": {"cable_scale": "1"}}, r"key 'sensor', key 'cable_scale': input should be a valid number"),
        ({"schema": "robocal.robot/9"}, r"key 'schema': input should be 'robocal.robot/1'"),
        ({"tool": {"z": float("nan")}}, r"key 'tool', key 'z'"),
        ({"extra": 1}, r"key 'extra': unknown key \(allowed: schema, name, description, units, convention, joints, base, tool, sensor, masses\)"),
    ],
)
def test_bad_robot_files_are_named(change, message, tmp_path):
    doc = robot_document(robocal.robot("ur10"))
    doc.update(change)
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    with pytest.raises(InvalidParameterError, match=r"bad.json: " + message):
        robocal.robot(str(tmp_path / "bad.json"))


def test_joint_keys_are_named(tmp_path):
    doc = robot_document(robocal.robot("ur10"))
    doc["joints"][4]["gamma"] = 1.0
    (tmp_path / "bad.yaml").write_text(json.dumps(doc))  # JSON is YAML
    with pytest.raises(InvalidParameterError, match=r"bad.yaml: joint 5, key 'gamma': unknown key \(allowed: alpha, a, d, theta, beta, limits"):
        robocal.robot(str(tmp_path / "bad.yaml"))


# --------------------------------------------------------------------------------------------
# Optional dependencies
# --------------------------------------------------------------------------------------------
def test_missing_optional_dependencies_say_what_to_install(monkeypatch, tmp_path):
    (tmp_path / "r.urdf").write_text('<robot name="r"><link name="a"/></robot>')
    monkeypatch.setitem(sys.modules, "yourdfpy", None)
    monkeypatch.setitem(sys.modules, "roboticstoolbox", None)
    with pytest.raises(MissingDependencyError, match=r"r.urdf: reading URDF needs yourdfpy.*pip install 'robocal\[urdf\]'") as info:
        robocal.robot(str(tmp_path / "r.urdf"))
    assert isinstance(info.value, ImportError) and isinstance(info.value, RobocalError)
    with pytest.raises(MissingDependencyError, match=r"to_roboticstoolbox needs roboticstoolbox-python.*pip install 'robocal\[rtb\]'"):
        robocal.to_roboticstoolbox(robocal.robot("ur10"))


@pytest.mark.parametrize("suffix", [".json", ".yaml"])
def test_a_document_saved_with_a_bom_reads_as_without(tmp_path, suffix):
    """An editor's byte-order mark: a YAML robot file read, a JSON one (a result file edited in Notepad) was refused
    ("Unexpected UTF-8 BOM"), though the CSV reader drops it."""
    robot = robocal.robot("ur10")
    plain = tmp_path / f"r{suffix}"
    robocal.write_robot(robot, plain)
    marked = tmp_path / f"bom{suffix}"
    marked.write_bytes(b"\xef\xbb\xbf" + plain.read_bytes())
    assert np.array_equal(robocal.robot(str(marked)).params, robocal.robot(str(plain)).params)
    if suffix == ".json":
        from robocal.simulation import simulate

        data, _ = simulate("ur10", "position", samples=60, seed=1)
        result = json.dumps(robocal.calibrate(data, robot="ur10", test_fraction=0.0).to_dict()).encode()
        (tmp_path / "result.json").write_bytes(b"\xef\xbb\xbf" + result)
        assert load_result(str(tmp_path / "result.json"))[1] == json.loads(result)
