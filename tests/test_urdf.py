"""URDF input (``robocal.robot("x.urdf")``): what ``export --format urdf`` writes reads back to
the same flange and tool kinematics; a hand-written, not DH-shaped URDF gives the forward
kinematics an independent parser (urdf_parser_py) and a NumPy chain written here compute, at its
tip and at its flange; bad URDF fails by file and joint / link."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import robocal
from robocal import export as ex
from robocal.catalog import BUILTIN
from robocal.exceptions import InvalidParameterError
from robocal.serial_robot import Joint, Robot

from helpers import three_joint_robot

pytest.importorskip("yourdfpy")
from robocal.urdf import read_urdf  # noqa: E402

REL = 1e-9  # relative to the chain's reach


def _same_kinematics(a: Robot, b: Robot, q, rel=REL, mm=None, flange=True):
    """Tool poses and, with ``flange``, flange poses (``fkine(q)``) agree: positions to ``mm``
    (default ``rel`` of the chain's reach), rotation matrix entries to ``rel``."""
    for tool in (True, False) if flange else (True,):
        A, B = a.fkine(q, tool=tool), b.fkine(q, tool=tool)
        tol = rel * max(1.0, float(np.abs(A[:, :3, 3]).max())) if mm is None else mm
        assert np.abs(A[:, :3, 3] - B[:, :3, 3]).max() <= tol, (f"tool={tool}", np.abs(A[:, :3, 3] - B[:, :3, 3]).max())
        assert np.abs(A[:, :3, :3] - B[:, :3, :3]).max() <= rel, (f"tool={tool}", np.abs(A[:, :3, :3] - B[:, :3, :3]).max())


def _within_limits(robot: Robot, m: int, seed: int) -> np.ndarray:
    lo, hi = np.array([j.limits for j in robot.joints]).T
    return lo + (hi - lo) * np.random.default_rng(seed).random((m, robot.n_joints))


def _through_urdf(robot: Robot, tmp_path, **kwargs) -> Robot:
    path = tmp_path / "robot.urdf"
    path.write_text(ex.export_urdf(robot))
    return read_urdf(path, **kwargs)


def _perturbed(name: str, seed: int = 0) -> Robot:
    """A built-in robot as a calibration leaves it: every DH value, beta, base and tool moved."""
    r = robocal.robot(name)
    n = r.n_joints
    rng = np.random.default_rng(seed)
    p = r.params.copy()
    p[: 5 * n] += rng.normal(0.0, [2e-3, 0.5, 0.5, 2e-3, 1e-3] * n)
    p[5 * n : 5 * n + 12] = rng.normal(0.0, [300.0, 300.0, 300.0, 0.5, 0.5, 0.5, 20.0, 20.0, 120.0, 0.5, 0.5, 0.5])
    return Robot(name, r.joints, p)


# --------------------------------------------------------------------------------------------
# Round trips through export --format urdf
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(BUILTIN))
def test_builtin_robot_round_trip(name, tmp_path):
    r = robocal.robot(name)
    (tmp_path / "x.urdf").write_text(ex.export_urdf(r))
    back = robocal.robot(str(tmp_path / "x.urdf"))
    assert back.name == name and back.n_joints == r.n_joints
    assert [j.kind for j in back.joints] == [j.kind for j in r.joints]
    assert [j.hayati for j in back.joints] == [j.hayati for j in r.joints]  # parallel axes found where the catalog flags them
    np.testing.assert_allclose([j.limits for j in back.joints], [j.limits for j in r.joints], rtol=1e-15)
    _same_kinematics(r, back, _within_limits(r, 200, 1), mm=1e-9)  # the flange too (issue 27: the HSR's was 200 mm off)
    # the DH lengths of a built-in come back (up to the sign of a and d the normal's direction picks)
    n = r.n_joints
    np.testing.assert_allclose(np.abs(back.params[1 : 5 * (n - 1) : 5]), np.abs(r.params[1 : 5 * (n - 1) : 5]), atol=1e-9)


@pytest.mark.parametrize("name", sorted(BUILTIN))
@pytest.mark.parametrize("convention", ["dh", "mdh"])
def test_perturbed_robot_round_trip(name, convention, tmp_path):
    r = _perturbed(name)
    exported = r if convention == "dh" else r.to_mdh()
    back = _through_urdf(exported, tmp_path, convention=convention)
    assert {j.convention for j in back.joints} == {convention}
    q = _within_limits(r, 200, 2)
    _same_kinematics(r, back, q, flange=False)  # to_mdh keeps the tool frame, not the flange
    _same_kinematics(exported, _through_urdf(exported, tmp_path), q)  # read as DH: the exporting robot's flange, whichever convention


def test_calibrated_robot_round_trip(tmp_path):
    from robocal.simulation import simulate

    data, _ = simulate("ur10", "position", samples=120, seed=4)
    calibrated = robocal.calibrate(data, robot="ur10").robot
    assert np.any(calibrated.params[calibrated.index("base_x") : calibrated.index("base_x") + 6] != 0.0)
    _same_kinematics(calibrated, _through_urdf(calibrated, tmp_path), _within_limits(calibrated, 200, 3), mm=1e-9)


def test_prismatic_and_mixed_conventions(tmp_path):
    r = three_joint_robot(["dh", "mdh", "mdh"], ["revolute", "prismatic", "revolute"])
    back = _through_urdf(r, tmp_path)
    assert [j.kind for j in back.joints] == ["revolute", "prismatic", "revolute"]
    assert back.joints[1].limits == pytest.approx((0.0, 400.0))  # m in the URDF, mm here
    _same_kinematics(r, back, _within_limits(r, 200, 4))


_angle = st.floats(-math.pi, math.pi)
_length = st.floats(-800.0, 800.0)
_link = st.tuples(
    _angle, _length, _length, _angle, st.floats(-0.05, 0.05), st.sampled_from(["dh", "mdh"]), st.sampled_from(["revolute", "revolute", "prismatic"])
)


@settings(max_examples=40, deadline=None)
@given(links=st.lists(_link, min_size=1, max_size=7), frames=st.lists(st.floats(-500.0, 500.0), min_size=12, max_size=12))
def test_any_chain_round_trips(links, frames, tmp_path_factory):
    """Random chains (DH, MDH, mixed; revolute and prismatic; parallel, intersecting and skew
    axes; Hayati beta; any base and tool) read back with the same tool kinematics."""
    alpha = [lk[0] for lk in links]
    links = [(round(a / (math.pi / 2)) * (math.pi / 2) if i % 2 else a,) + lk[1:] for i, (a, lk) in enumerate(zip(alpha, links))]  # some exact 0 / 90 deg
    joints = [Joint(c, k, False, (-3.0, 3.0) if k == "revolute" else (-300.0, 300.0)) for *_, c, k in links]
    params = np.concatenate([np.ravel([lk[:5] for lk in links]), np.array(frames) * ([1, 1, 1, 0.006] * 3)[:12], [0, 0, 0, 0, 1.0]])
    params[5 * len(links) + 3 : 5 * len(links) + 6] = np.array(frames[3:6]) / 160.0
    params[5 * len(links) + 9 : 5 * len(links) + 12] = np.array(frames[9:12]) / 160.0
    r = Robot("random", joints, params)
    back = _through_urdf(r, tmp_path_factory.mktemp("h"))
    _same_kinematics(r, back, _within_limits(r, 50, 5), rel=1e-8)


# --------------------------------------------------------------------------------------------
# An independent check on a URDF that is not DH-shaped
# --------------------------------------------------------------------------------------------
NOT_DH = """<?xml version="1.0"?>
<robot name="skewed">
  <link name="world"/><link name="base"/><link name="l1"/><link name="l2"/><link name="l3"/><link name="l4"/>
  <link name="l5"/><link name="l6"/><link name="flange"/><link name="tcp"/>
  <joint name="mount" type="fixed"><parent link="world"/><child link="base"/><origin xyz="0.3 -0.2 0.05" rpy="0.02 -0.01 1.2"/></joint>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0.01 0.02 0.3" rpy="0.1 -0.2 0.3"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0.15 0.05 0.2" rpy="1.5 0.1 -0.4"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="j3" type="revolute"><parent link="l2"/><child link="l3"/><origin xyz="0.6 0.0 0.01" rpy="0.0 0.0 0.002"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="j4" type="prismatic"><parent link="l3"/><child link="l4"/><origin xyz="0.1 0.3 -0.05" rpy="-0.7 0.3 0.2"/>
    <axis xyz="0.6 0 -0.8"/><limit lower="-0.1" upper="0.25" effort="1" velocity="1"/></joint>
  <joint name="j5" type="continuous"><parent link="l4"/><child link="l5"/><origin xyz="0 0 0.12" rpy="0 0 0"/>
    <axis xyz="-1 0 0"/></joint>
  <joint name="j6" type="revolute"><parent link="l5"/><child link="l6"/><origin xyz="0.0 0.0 0.0" rpy="0.3 0.4 0.5"/>
    <axis xyz="0.267261 0.534522 0.801784"/><limit lower="-6" upper="6" effort="1" velocity="1"/></joint>
  <joint name="to_flange" type="fixed"><parent link="l6"/><child link="flange"/><origin xyz="0 0 0.09" rpy="3.14159 0 0"/></joint>
  <joint name="to_tcp" type="fixed"><parent link="flange"/><child link="tcp"/><origin xyz="0.01 0.02 0.15" rpy="0 -0.5 0"/></joint>
</robot>
"""


def _rot(axis, angle):
    """Rodrigues, written here so that the check shares no code with robocal."""
    k = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def _independent_fkine(urdf_text: str, tip: str, q_si: np.ndarray) -> np.ndarray:
    """The tip pose by urdf_parser_py's reading of the file and a plain product of
    ``origin · motion(axis, q)`` (URDF's rpy: R = Rz(yaw) Ry(pitch) Rx(roll)); metres."""
    urdf_mod = pytest.importorskip("urdf_parser_py.urdf")
    model = urdf_mod.URDF.from_xml_string(urdf_text.encode())
    names = model.get_chain(model.get_root(), tip, links=False)
    joints = {j.name: j for j in model.joints}
    out = []
    for qi in q_si:
        T, k = np.eye(4), 0
        for name in names:
            j = joints[name]
            O = np.eye(4)
            if j.origin is not None:  # an absent <origin> is the identity
                roll, pitch, yaw = j.origin.rpy
                O[:3, :3] = _rot([0, 0, 1], yaw) @ _rot([0, 1, 0], pitch) @ _rot([1, 0, 0], roll)
                O[:3, 3] = j.origin.xyz
            T = T @ O
            if j.type == "fixed":
                continue
            M = np.eye(4)
            if j.type == "prismatic":
                M[:3, 3] = np.asarray(j.axis) / np.linalg.norm(j.axis) * qi[k]
            else:
                M[:3, :3] = _rot(j.axis, qi[k])
            T, k = T @ M, k + 1
        out.append(T)
    return np.array(out)


def test_not_dh_shaped_urdf_matches_an_independent_parser(tmp_path):
    path = tmp_path / "skewed.urdf"
    path.write_text(NOT_DH)
    r = robocal.robot(str(path))
    assert r.name == "skewed" and [j.kind for j in r.joints] == ["revolute"] * 3 + ["prismatic", "revolute", "revolute"]
    assert r.joints[1].hayati and not r.joints[0].hayati  # j2 and j3 are 0.1 deg from parallel
    assert r.joints[3].limits == pytest.approx((-100.0, 250.0))  # mm
    assert r.joints[4].limits == pytest.approx((-math.pi, math.pi))  # continuous
    q = _within_limits(r, 300, 6)
    q_si = q.copy()
    q_si[:, 3] /= 1000.0  # the prismatic joint: mm here, m in the URDF
    want = _independent_fkine(NOT_DH, "tcp", q_si)
    got = r.fkine(q, tool=True)
    np.testing.assert_allclose(got[:, :3, 3] / 1000.0, want[:, :3, 3], rtol=0, atol=1e-12)
    np.testing.assert_allclose(got[:, :3, :3], want[:, :3, :3], rtol=0, atol=1e-12)
    # the same in MDH
    m = read_urdf(path, convention="mdh")
    np.testing.assert_allclose(m.fkine(q, tool=True)[:, :3, 3] / 1000.0, want[:, :3, 3], rtol=0, atol=1e-12)


def test_the_flange_link_is_the_flange_when_the_last_link_can_hold_it(tmp_path):
    """The default tip is the end of the chain (tcp, past the fixed flange); ``fkine(q)`` is the
    ``flange`` link when five DH parameters can place it (here: its origin on joint 6's axis),
    else joint 6's child link (NOT_DH's flange is 34 mm off that axis)."""
    on_axis = NOT_DH.replace('<origin xyz="0 0 0.09" rpy="3.14159 0 0"/>', '<origin xyz="0.02405349 0.04810698 0.07216056" rpy="3.14159 0.2 -1"/>')
    assert on_axis != NOT_DH
    for text, flange in ((on_axis, "flange"), (NOT_DH, "l6")):
        path = tmp_path / "robot.urdf"
        path.write_text(text)
        r = robocal.robot(str(path))
        q = _within_limits(r, 100, 8)
        q_si = q.copy()
        q_si[:, 3] /= 1000.0
        for tool, link in ((False, flange), (True, "tcp")):
            want, got = _independent_fkine(text, link, q_si), r.fkine(q, tool=tool)
            np.testing.assert_allclose(got[:, :3, 3] / 1000.0, want[:, :3, 3], rtol=0, atol=1e-12, err_msg=link)
            np.testing.assert_allclose(got[:, :3, :3], want[:, :3, :3], rtol=0, atol=1e-12, err_msg=link)
    at_flange = read_urdf(path, tip="flange")  # a named tip ends the chain there: no tool
    np.testing.assert_allclose(at_flange.fkine(q, tool=True)[:, :3, 3] / 1000.0, _independent_fkine(NOT_DH, "flange", q_si)[:, :3, 3], atol=1e-12)


def test_a_branch_is_followed_to_the_named_tip(tmp_path):
    branched = NOT_DH.replace("</robot>", '<link name="camera"/><joint name="cam" type="fixed"><parent link="l2"/><child link="camera"/></joint></robot>')
    path = tmp_path / "branched.urdf"
    path.write_text(branched)
    # the leaves it may end at, and how (the command line cannot name a tip)
    leaves = r"\['camera', 'tcp'\]\): robocal.urdf.read_urdf\(path, tip=...\), and robocal.write_robot"
    with pytest.raises(InvalidParameterError, match=r"branched.urdf: not a serial chain: link 'l2' branches into joints \['j3', 'cam'\].* \(one of " + leaves):
        robocal.robot(str(path))
    r = read_urdf(path, tip="tcp")
    assert r.n_joints == 6
    camera = read_urdf(path, tip="camera")
    assert camera.n_joints == 2
    q = _within_limits(camera, 20, 7)
    np.testing.assert_allclose(camera.fkine(q, tool=True)[:, :3, 3] / 1000.0, _independent_fkine(branched, "camera", q)[:, :3, 3], atol=1e-12)


# --------------------------------------------------------------------------------------------
# Bad URDF
# --------------------------------------------------------------------------------------------
def _joint(name, kind, parent, child, extra=""):
    return f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>{extra}</joint>'


LIMIT = '<limit lower="-1" upper="1" effort="0" velocity="0"/>'
BAD = {
    "floating": (_joint("j1", "floating", "a", "b"), r"joint 'j1' has type 'floating'"),
    "planar": (_joint("j1", "planar", "a", "b"), r"joint 'j1' has type 'planar'"),
    "mimic": (_joint("j1", "revolute", "a", "b", LIMIT) + _joint("j2", "revolute", "b", "c", LIMIT + '<mimic joint="j1"/>'), r"joint 'j2' mimics joint 'j1'"),
    "nan origin": (_joint("j1", "revolute", "a", "b", '<origin xyz="0 0 nan"/>' + LIMIT), r"joint 'j1': its <origin> must be finite"),
    "zero axis": (_joint("j1", "revolute", "a", "b", '<axis xyz="0 0 0"/>' + LIMIT), r"joint 'j1': its <axis> must be a non-zero"),
    "bad limits": (
        _joint("j1", "revolute", "a", "b", '<limit lower="1" upper="-1" effort="0" velocity="0"/>'),
        r"joint 'j1': its <limit> must have finite lower < upper",
    ),
    "fixed only": (_joint("j1", "fixed", "a", "b"), r"has no movable joint"),
    "two roots": (_joint("j1", "revolute", "a", "b", LIMIT) + _joint("j2", "revolute", "c", "d", LIMIT), r"one root link; got \['a', 'c'\]"),
    "two parents": (
        _joint("j1", "revolute", "a", "b", LIMIT) + _joint("j2", "revolute", "c", "b", LIMIT),
        r"link 'b' is the child of two joints \('j1', 'j2'\)",
    ),
    "no joint": ("", r"the URDF has no joint"),
    "attribute missing": ('<joint type="revolute"><parent link="a"/><child link="b"/></joint>', r"not a valid URDF"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_urdf_names_the_file_and_joint(case, tmp_path):
    body, message = BAD[case]
    path = tmp_path / "bad.urdf"
    path.write_text(f'<robot name="r"><link name="a"/><link name="b"/><link name="c"/><link name="d"/>{body}</robot>')
    with pytest.raises(InvalidParameterError, match="bad.urdf: .*" + message):
        robocal.robot(str(path))


def test_unreadable_or_not_urdf(tmp_path):
    with pytest.raises(InvalidParameterError, match=r"missing.urdf: cannot read the URDF file"):
        robocal.robot(str(tmp_path / "missing.urdf"))
    (tmp_path / "broken.urdf").write_text("<robot name='x'><link name='a'>")
    with pytest.raises(InvalidParameterError, match=r"broken.urdf: not well-formed XML \(.*line 1"):
        robocal.robot(str(tmp_path / "broken.urdf"))
    (tmp_path / "sdf.urdf").write_text("<sdf version='1.6'/>")
    with pytest.raises(InvalidParameterError, match=r"sdf.urdf: not a URDF file \(root element <sdf>"):
        robocal.robot(str(tmp_path / "sdf.urdf"))
    with pytest.raises(InvalidParameterError, match="tip link 'nowhere'"):
        (tmp_path / "ok.urdf").write_text(NOT_DH)
        read_urdf(tmp_path / "ok.urdf", tip="nowhere")
    with pytest.raises(InvalidParameterError, match="convention"):
        read_urdf(tmp_path / "ok.urdf", convention="xyz")


def test_cli_reports_a_bad_urdf_in_one_line(tmp_path, capsys):
    from robocal.cli import main

    path = tmp_path / "bad.urdf"
    path.write_text('<robot name="r"><link name="a"/><link name="b"/>' + _joint("j1", "floating", "a", "b") + "</robot>")
    assert main(["simulate", "--robot", str(path), "--samples", "10", "--out", str(tmp_path / "d.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.urdf" in err[0] and "'j1'" in err[0] and "floating" in err[0]


def test_simulate_with_a_urdf_robot(tmp_path):
    path = tmp_path / "skewed.urdf"
    path.write_text(NOT_DH)
    from robocal.simulation import simulate

    data, truth = simulate(str(path), "position", samples=20, seed=0)
    assert len(data) == 20 and truth["robot"] == "skewed"
