"""``robocal export --format ur-yaml``: Universal Robots' kinematics file (ur_description's
``kinematics_params_file``). The nominal UR10 writes UR's published numbers; a calibrated UR10's
file, rebuilt the way ur_macro.xacro builds the chain (here in NumPy, and by xacro itself from a
macro of the same structure), reproduces the calibrated tool at the controller's readings; reading
conventions are folded in or refused; bad robots and files fail clearly."""

from __future__ import annotations

import json
import math
import re
from dataclasses import replace

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

import robocal
from robocal import export as ex
from robocal import ur_kinematics as urk
from robocal.causes import structure
from robocal.cli import main
from robocal.exceptions import InvalidParameterError
from robocal.geometry import frame_transform, rotation, so3_log
from robocal.results import load_result
from robocal.robot_table import frame_slice
from robocal.serial_robot import Joint, Robot
from robocal.simulation import simulate
from robocal.urdf import robot_from_urdf

from helpers import random_params, three_joint_robot

POS_TOL, ROT_TOL = 1e-6, 1e-9  # mm, rad: the export's tolerances

# UR's published nominal UR10 (CB3) file: UniversalRobots/Universal_Robots_ROS2_Description, release
# 2.4.5, config/ur10/default_kinematics.yaml (m, rad), as (x, y, z, roll, pitch, yaw) per entry.
UR10_PUBLISHED = {
    "shoulder": (0.0, 0.0, 0.1273, 0.0, 0.0, 0.0),
    "upper_arm": (0.0, 0.0, 0.0, 1.570796327, 0.0, 0.0),
    "forearm": (-0.612, 0.0, 0.0, 0.0, 0.0, 0.0),
    "wrist_1": (-0.5723, 0.0, 0.163941, 0.0, 0.0, 0.0),
    "wrist_2": (0.0, -0.1157, -2.373046667922381e-11, 1.570796327, 0.0, 0.0),
    "wrist_3": (0.0, 0.0922, -1.891053610911353e-11, 1.570796326589793, 3.141592653589793, 3.141592653589793),
}
UR10_PUBLISHED_HASH = "calib_17227329492635474227"


def _published_text(**changes) -> str:
    doc = {"kinematics": {name: dict(zip(urk.KEYS, values)) for name, values in UR10_PUBLISHED.items()}}
    doc["kinematics"]["hash"] = UR10_PUBLISHED_HASH
    doc["kinematics"].update(changes)
    return yaml.safe_dump(doc)


def _ur_chain(kin: urk.URKinematics, q: np.ndarray) -> np.ndarray:
    """base_link → calibrated tool as ur_macro.xacro chains it, written out here on its own:
    Rz(pi) · Π (origin_j · Rz(q_j)) · flange rpy(0, -pi/2, -pi/2) · tool0 rpy(pi/2, 0, pi/2) · TCP."""
    T = np.broadcast_to(frame_transform([0, 0, 0, 0, 0, math.pi]), (len(q), 4, 4))
    for j, origin in enumerate(kin.origins):
        Rz = np.zeros((len(q), 4, 4))
        Rz[:, :3, :3], Rz[:, 3, 3] = rotation(2, q[:, j]), 1.0
        T = T @ origin @ Rz
    return T @ frame_transform([0, 0, 0, 0, -math.pi / 2, -math.pi / 2]) @ frame_transform([0, 0, 0, math.pi / 2, 0, math.pi / 2]) @ kin.tcp


def _in_base_link(robot: Robot, q_model: np.ndarray) -> np.ndarray:
    """The calibrated tool in UR's base_link: the measurement set-up (robocal's base) taken off,
    base_link_inertia = the robot's base frame = base_link · Rz(pi)."""
    base = frame_transform(robot.params[frame_slice(robot, "base")])
    return frame_transform([0, 0, 0, 0, 0, math.pi]) @ np.linalg.solve(base, robot.fkine(q_model, tool=True))


def _errors(got: np.ndarray, want: np.ndarray) -> tuple[float, float]:
    pos = np.linalg.norm(got[:, :3, 3] - want[:, :3, 3], axis=1).max()
    rot = np.linalg.norm(so3_log(np.swapaxes(want[:, :3, :3], -1, -2) @ got[:, :3, :3]), axis=1).max()
    return float(pos), float(rot)


@pytest.fixture(scope="module")
def ur10_result(tmp_path_factory):
    """The brief's calibrated UR10: simulate --robot ur10 --measurement position --samples 300 --seed 2, then calibrate."""
    folder = tmp_path_factory.mktemp("ur")
    data, _ = simulate("ur10", "position", samples=300, seed=2)
    path = folder / "rp.json"
    path.write_text(json.dumps(robocal.calibrate(data, robot="ur10").to_dict()))
    return path


@pytest.fixture(scope="module")
def zero_result(tmp_path_factory):
    """A UR10 whose controller reads joint 2 90° off the model (model = reading + 90°), calibrated
    with that convention; with the data and the readings."""
    data, _ = simulate("ur10", "position", samples=200, seed=3)
    readings = data.q.copy()
    readings[:, 1] -= math.radians(90.0)
    result = robocal.calibrate(replace(data, q=readings), robot="ur10", test_fraction=0.0, causes=["joint_zero joint 2 offset=90"])
    path = tmp_path_factory.mktemp("ur") / "zero.json"
    path.write_text(json.dumps(result.to_dict()))
    return path, data, readings


def test_nominal_ur10_writes_urs_published_numbers(tmp_path):
    """robocal's nominal UR10 gives UR's own default_kinematics.yaml for the UR10: the same joint
    origins (UR rounds pi/2 to 1.570796327, hence 1e-9 rad / 1e-10 m) and an identity TCP."""
    out = tmp_path / "ur10.yaml"
    check, failed = ex.export_checked(robocal.robot("ur10"), "ur-yaml", out)
    assert failed == [] and check["representation"] == "ur-yaml"
    kin = urk.read_ur_kinematics(out)
    published = urk.ur_kinematics_from_text(_published_text())
    for name, got, want in zip(urk.SEGMENTS, kin.origins, published.origins):
        np.testing.assert_allclose(got[:3, 3] / 1000.0, want[:3, 3] / 1000.0, atol=1e-10, err_msg=name)
        np.testing.assert_allclose(got[:3, :3], want[:3, :3], atol=2e-9, err_msg=name)
    # The entries without rotation ambiguity carry UR's very numbers.
    doc = yaml.safe_load(out.read_text())
    for name in ("shoulder", "forearm", "wrist_1"):
        np.testing.assert_allclose([doc["kinematics"][name][k] for k in urk.KEYS], UR10_PUBLISHED[name], atol=1e-15, err_msg=name)
    np.testing.assert_allclose(kin.tcp, np.eye(4), atol=1e-12)
    assert doc["kinematics"]["hash"].startswith("calib_robocal_") and doc["kinematics"]["hash"] != UR10_PUBLISHED_HASH


def test_calibrated_ur10_round_trip(ur10_result, tmp_path):
    """The calibrated UR10's file, chained as ur_macro.xacro chains it (written out in this test),
    gives the calibrated tool in base_link on random joints; the TCP holds the calibrated tool."""
    robot, _ = load_result(ur10_result)
    out = tmp_path / "my_robot_calibration.yaml"
    check, failed = ex.export_checked(robot, "ur-yaml", out)
    assert failed == [], failed
    assert check["max_position_error_mm"] <= POS_TOL and check["max_rotation_error_rad"] <= ROT_TOL
    kin = urk.read_ur_kinematics(out)
    q = np.random.default_rng(5).uniform(-2 * np.pi, 2 * np.pi, (300, 6))
    pos, rot = _errors(_ur_chain(kin, q), _in_base_link(robot, q))
    assert pos <= POS_TOL and rot <= ROT_TOL, (pos, rot)
    # The calibration's tool point (a tracker target off the flange) cannot go into the file: it is the TCP.
    assert np.linalg.norm(kin.tcp[:3, 3]) > 50.0


def test_the_chain_is_the_calibrated_one_not_the_nominal(ur10_result, tmp_path):
    """The file holds the calibration: the calibrated and the nominal UR10 differ by more than a
    tenth of a millimetre at tool0 on some joints (a regression guard against writing the nominal)."""
    robot, _ = load_result(ur10_result)
    ex.export_checked(robot, "ur-yaml", tmp_path / "c.yaml")
    ex.export_checked(robocal.robot("ur10"), "ur-yaml", tmp_path / "n.yaml")
    q = np.random.default_rng(1).uniform(-np.pi, np.pi, (50, 6))
    calibrated, nominal = (urk.read_ur_kinematics(tmp_path / f).origins for f in ("c.yaml", "n.yaml"))
    no_tcp = np.eye(4)
    pos, _ = _errors(_ur_chain(urk.URKinematics(calibrated, no_tcp, ""), q), _ur_chain(urk.URKinematics(nominal, no_tcp, ""), q))
    assert pos > 0.1


def test_joint_zero_is_folded_in_at_the_controllers_readings(zero_result, tmp_path, capsys):
    """A result whose controller reads joint 2 90° off: the file, at the controller's readings and
    placed by the calibrated set-up, reaches the measured positions (within the noise); read as
    model angles instead it would be off by metres."""
    path, data, readings = zero_result
    robot, doc = load_result(path)
    assert doc["structure"] == ["joint_zero joint 2 offset=90"]
    out = tmp_path / "z.yaml"
    assert main(["export", str(path), "--format", "ur-yaml", "--out", str(out)]) == 0
    kin = urk.read_ur_kinematics(out)
    base = frame_transform(robot.params[frame_slice(robot, "base")])
    to_tracker = base @ frame_transform([0, 0, 0, 0, 0, math.pi])  # tracker ← robot base ← base_link (Rz(pi) is its own inverse)
    predicted = (to_tracker @ _ur_chain(kin, readings))[:, :3, 3]
    assert np.abs(predicted - data.y).max() < 0.2
    # The reference the export checks against agrees with the convention's own code (structure.to_model).
    conventions = structure.parse_all(doc["structure"], 6)
    pos, rot = _errors(_ur_chain(kin, readings), _in_base_link(robot, structure.to_model(readings, conventions)))
    assert pos <= POS_TOL and rot <= ROT_TOL
    assert np.abs((to_tracker @ _ur_chain(kin, data.q))[:, :3, 3] - data.y).max() > 100.0


def test_causes_the_file_cannot_hold_are_named(tmp_path, capsys):
    """A result with a joint cause: the geometry is exported and the cause named as left out."""
    data, _ = simulate("ur10", "position", samples=150, seed=4)
    path = tmp_path / "scaled.json"
    path.write_text(json.dumps(robocal.calibrate(data, robot="ur10", causes=["joint_scale joint 2"]).to_dict()))
    assert main(["export", str(path), "--format", "ur-yaml", "--out", str(tmp_path / "s.yaml")]) == 0
    assert "note: not carried (a joint-by-joint geometry has no place for them): joint_scale joint 2" in capsys.readouterr().out


@pytest.mark.parametrize("label", ["joint_sign joint 3", "joint_reference joint 3 source=2 coefficient=-1"])
def test_other_reading_conventions_are_refused(ur10_result, tmp_path, capsys, label):
    doc = json.loads(ur10_result.read_text())
    doc["structure"] = [label]
    path = tmp_path / "r.json"
    path.write_text(json.dumps(doc))
    out = tmp_path / "o.yaml"
    assert main(["export", str(path), "--format", "ur-yaml", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("robocal: error: ") and "joint 3" in err and label.split()[0] in err and len(err.strip().splitlines()) == 1
    assert not out.exists()
    # a URDF can turn a joint's axis over; a joint read relative to another it writes at the model's angles, when asked
    angles = ["--angles", "model"] if label.startswith("joint_reference") else []
    assert main(["export", str(path), "--format", "urdf", *angles, "--out", str(tmp_path / "o.urdf")]) == 0


def test_only_six_revolute_joints(tmp_path):
    three = three_joint_robot(["dh"] * 3, ["revolute"] * 3)
    with pytest.raises(InvalidParameterError, match=r"6 revolute joints; robot 'custom' has 3 joints"):
        ex.export(three, "ur-yaml", tmp_path / "t.yaml")
    six = Robot("sixp", [Joint("dh", "prismatic" if j == 2 else "revolute", False, (-3.0, 3.0)) for j in range(6)], robocal.robot("ur10").params)
    with pytest.raises(InvalidParameterError, match="prismatic"):
        ex.export(six, "ur-yaml", tmp_path / "t.yaml")
    assert not (tmp_path / "t.yaml").exists()


def test_cli(ur10_result, tmp_path, capsys):
    out = tmp_path / "my_robot_calibration.yaml"
    assert main(["export", str(ur10_result), "--format", "ur-yaml", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "as a UR kinematics file to" in printed and "set the TCP on the teach pendant to x y z =" in printed
    doc = yaml.safe_load(out.read_text())
    assert set(doc) == {"kinematics", urk.TCP_KEY}
    assert list(doc["kinematics"]) == [*urk.SEGMENTS, "hash"]
    assert all(type(doc["kinematics"][s][k]) is float for s in urk.SEGMENTS for k in urk.KEYS)
    # The pendant's TCP is printed without rounding residues (UR's fixed frames compose to the identity to 1e-16).
    assert "rx ry rz = 0.000000 0.000000 0.000000 rad" in printed
    # A robot name that would end the YAML comment it is written in stays on its line.
    named = tmp_path / "named.yaml"
    assert main(["export", str(ur10_result), "--format", "ur-yaml", "--name", "x\nrobocal_tcp: 1\u2028hash: 2", "--out", str(named)]) == 0
    assert urk.read_ur_kinematics(named).origins[2].tolist() == urk.read_ur_kinematics(out).origins[2].tolist()
    assert main(["export", str(ur10_result), "--format", "ur-yaml", "--table-format", "csv", "--out", str(tmp_path / "x.yaml")]) == 2
    assert "--table-format applies to --format dh and mdh, not ur-yaml" in capsys.readouterr().err


def test_round_trip_catches_a_wrong_file(ur10_result, tmp_path):
    """The check reads the file: an origin changed by 0.1 mm after writing is caught."""
    robot, _ = load_result(ur10_result)
    out = tmp_path / "c.yaml"
    ex.export_checked(robot, "ur-yaml", out)
    doc = yaml.safe_load(out.read_text())
    doc["kinematics"]["forearm"]["x"] += 1e-4
    out.write_text(yaml.safe_dump(doc))
    check = ex.roundtrip_check(urk.ur_reference(robot), out)
    assert check["max_position_error_mm"] > 0.09


def test_urs_own_file_reads_and_bad_files_are_named(tmp_path):
    published = urk.ur_kinematics_from_text(_published_text(), "published")
    assert published.hash == UR10_PUBLISHED_HASH and np.array_equal(published.tcp, np.eye(4))
    nominal = urk.ur_reference(robocal.robot("ur10"))
    q = np.random.default_rng(2).uniform(-np.pi, np.pi, (100, 6))
    pos, _ = _errors(urk.robot_from_ur_kinematics(published).fkine(q, tool=True), nominal.fkine(q, tool=True))
    assert pos < 1e-6  # UR's rounded pi/2 (3.4e-10 rad) over a 1.3 m arm
    bad = {
        "kinematics.wrist_2.roll must be a finite number; got 'x'": _published_text(wrist_2={**dict(zip(urk.KEYS, UR10_PUBLISHED["wrist_2"])), "roll": "x"}),
        "kinematics.forearm must have exactly the keys": _published_text(forearm={"x": 0.0}),
        "missing ['hash']": _published_text().replace(f"  hash: {UR10_PUBLISHED_HASH}\n", ""),
        "unknown top-level keys ['extra']": _published_text() + "extra: 1\n",
        "not a UR kinematics file": "joints: []\n",
        "kinematics.hash must be a string": _published_text(hash=12),
        "must be a finite number; got True": _published_text(shoulder={**dict(zip(urk.KEYS, UR10_PUBLISHED["shoulder"])), "x": True}),
    }
    for message, text in bad.items():
        path = tmp_path / "bad.yaml"
        path.write_text(text)
        with pytest.raises(InvalidParameterError, match=r"bad\.yaml: .*" + re.escape(message)):
            urk.read_ur_kinematics(path)


@given(st.floats(allow_nan=False, allow_infinity=False))
def test_yaml_floats_read_back_as_the_same_float(value):
    """PyYAML (xacro's load_yaml) reads 1e-05 as a string: every number is written so it reads back as the very float."""
    got = yaml.safe_load(f"v: {urk.yaml_float(value)}")["v"]
    assert type(got) is float and got == value and math.copysign(1.0, got) == math.copysign(1.0, value)


@settings(deadline=None, max_examples=25)
@given(
    seed=st.integers(0, 2**32 - 1),
    conventions=st.lists(st.sampled_from(["dh", "mdh"]), min_size=6, max_size=6),
    zeros=st.dictionaries(st.integers(0, 5), st.floats(-360.0, 360.0), max_size=3),
)
def test_any_6r_chain_round_trips(tmp_path_factory, seed, conventions, zeros):
    """Random 6R chains of mixed conventions with Hayati beta, any base and tool, and joint_zero
    offsets: the file (read by the NumPy chain of this test) reproduces the robot at the readings."""
    params = random_params(np.random.default_rng(seed), 6)
    robot = Robot("r", [Joint(c, "revolute", False, (-math.pi, math.pi)) for c in conventions], params)
    conventions_ = [structure.Structure("joint_zero", j, math.radians(v)) for j, v in zeros.items()]
    out = tmp_path_factory.mktemp("h") / "r.yaml"
    delivered = ex.Deliverable(structure.robot_at_readings(robot, conventions_), robot, conventions_, [])
    check, failed = ex.export_checked(robot, "ur-yaml", out, samples=50, seed=seed, delivered=delivered)
    assert failed == [], (failed, check)
    readings = np.random.default_rng(seed + 1).uniform(-math.pi, math.pi, (50, 6))
    pos, rot = _errors(_ur_chain(urk.read_ur_kinematics(out), readings), _in_base_link(robot, structure.to_model(readings, conventions_)))
    assert pos <= POS_TOL and rot <= ROT_TOL


# --------------------------------------------------------------------------------------------
# xacro: the file expanded by xacro, from a macro of ur_macro.xacro's structure written here
# --------------------------------------------------------------------------------------------
_MACRO = """<?xml version="1.0"?>
<robot name="ur_test" xmlns:xacro="http://wiki.ros.org/xacro">
  <xacro:property name="kin" value="${{xacro.load_yaml('{path}')['kinematics']}}"/>
  <xacro:macro name="ur_joint" params="name parent child entry">
    <link name="${{child}}"/>
    <joint name="${{name}}" type="revolute">
      <parent link="${{parent}}"/>
      <child link="${{child}}"/>
      <origin xyz="${{kin[entry]['x']}} ${{kin[entry]['y']}} ${{kin[entry]['z']}}" rpy="${{kin[entry]['roll']}} ${{kin[entry]['pitch']}} ${{kin[entry]['yaw']}}"/>
      <axis xyz="0 0 1"/>
      <limit lower="-6.283185307179586" upper="6.283185307179586" effort="0" velocity="0"/>
    </joint>
  </xacro:macro>
  <link name="base_link"/>
  <link name="base_link_inertia"/>
  <joint name="base_link-base_link_inertia" type="fixed">
    <parent link="base_link"/>
    <child link="base_link_inertia"/>
    <origin xyz="0 0 0" rpy="0 0 ${{pi}}"/>
  </joint>
  <xacro:ur_joint name="shoulder_pan_joint" parent="base_link_inertia" child="shoulder_link" entry="shoulder"/>
  <xacro:ur_joint name="shoulder_lift_joint" parent="shoulder_link" child="upper_arm_link" entry="upper_arm"/>
  <xacro:ur_joint name="elbow_joint" parent="upper_arm_link" child="forearm_link" entry="forearm"/>
  <xacro:ur_joint name="wrist_1_joint" parent="forearm_link" child="wrist_1_link" entry="wrist_1"/>
  <xacro:ur_joint name="wrist_2_joint" parent="wrist_1_link" child="wrist_2_link" entry="wrist_2"/>
  <xacro:ur_joint name="wrist_3_joint" parent="wrist_2_link" child="wrist_3_link" entry="wrist_3"/>
  <link name="flange"/>
  <joint name="wrist_3-flange" type="fixed">
    <parent link="wrist_3_link"/>
    <child link="flange"/>
    <origin xyz="0 0 0" rpy="0 ${{-pi/2.0}} ${{-pi/2.0}}"/>
  </joint>
  <link name="tool0"/>
  <joint name="flange-tool0" type="fixed">
    <parent link="flange"/>
    <child link="tool0"/>
    <origin xyz="0 0 0" rpy="${{pi/2.0}} 0 ${{pi/2.0}}"/>
  </joint>
</robot>
"""


def test_xacro_expands_the_file_into_the_calibrated_chain(zero_result, tmp_path):
    """xacro, loading the file with load_yaml into a macro built like ur_macro.xacro, gives a URDF
    whose tool0 (read by robocal / yourdfpy) is the calibrated tool less the TCP, at the readings."""
    xacro = pytest.importorskip("xacro", reason="xacro (the test extra) is not installed: the file is not expanded by ROS's macro processor")
    pytest.importorskip("yourdfpy", reason="yourdfpy (the test extra) is not installed: the expanded URDF cannot be read")
    path, _, _ = zero_result
    robot, doc = load_result(path)
    conventions = structure.parse_all(doc["structure"], 6)
    out = tmp_path / "my_robot_calibration.yaml"
    assert ex.export_checked(robot, "ur-yaml", out, delivered=ex.deliverable(robot, doc))[1] == []
    macro = tmp_path / "ur_test.urdf.xacro"
    macro.write_text(_MACRO.format(path=out))
    urdf = xacro.process_file(str(macro)).toxml()
    expanded = robot_from_urdf(urdf, where="xacro")
    readings = np.random.default_rng(4).uniform(-2 * np.pi, 2 * np.pi, (200, 6))
    tcp = urk.read_ur_kinematics(out).tcp
    want = _in_base_link(robot, structure.to_model(readings, conventions)) @ np.linalg.inv(tcp)
    pos, rot = _errors(expanded.fkine(readings, tool=True), want)
    assert pos <= POS_TOL and rot <= ROT_TOL, (pos, rot)
