"""roboticstoolbox interop: ``robocal.to_roboticstoolbox(robot)`` gives a ``DHRobot`` whose ``fkine`` is
robocal's tool pose, ``robocal.from_roboticstoolbox`` takes it (and the toolbox's own models)
back, and what a DHRobot cannot hold (Hayati beta, mixed conventions) is refused by joint."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import robocal
from robocal.catalog import BUILTIN
from robocal.exceptions import InvalidParameterError
from robocal.serial_robot import Joint, Robot

from helpers import three_joint_robot

rtb = pytest.importorskip("roboticstoolbox")


def _q(robot: Robot, m: int, seed: int) -> np.ndarray:
    lo, hi = np.array([j.limits for j in robot.joints]).T
    return lo + (hi - lo) * np.random.default_rng(seed).random((m, robot.n_joints))


def _toolbox_fkine(dh, q_si) -> np.ndarray:
    return np.array([dh.fkine(qi).A for qi in q_si])


def _assert_same(robot: Robot, dh, q, length_unit="m"):
    """robocal's tool pose (mm) against the toolbox's ``fkine`` (``length_unit``)."""
    scale = 1000.0 if length_unit == "m" else 1.0
    q_tb = q.copy()
    prismatic = [j.kind == "prismatic" for j in robot.joints]
    q_tb[:, prismatic] /= scale
    want = robot.fkine(q, tool=True)
    got = _toolbox_fkine(dh, q_tb)
    np.testing.assert_allclose(got[:, :3, 3] * scale, want[:, :3, 3], rtol=0, atol=1e-9 * max(1.0, np.abs(want[:, :3, 3]).max()))
    np.testing.assert_allclose(got[:, :3, :3], want[:, :3, :3], rtol=0, atol=1e-12)


def _with_frames(robot: Robot) -> Robot:
    return robot.with_params(base_x=150.0, base_y=-40.0, base_z=10.0, base_rx=0.01, base_ry=-0.02, base_rz=2.0, tool_x=5.0, tool_z=120.0, tool_ry=0.3)


@pytest.mark.parametrize("name", sorted(BUILTIN))
@pytest.mark.parametrize("convention", ["dh", "mdh"])
def test_builtin_robots_agree_with_fkine(name, convention):
    robot = _with_frames(robocal.robot(name))
    robot = robot.to_mdh() if convention == "mdh" else robot
    dh = robocal.to_roboticstoolbox(robot)
    assert isinstance(dh, rtb.DHRobot) and dh.n == robot.n_joints and dh.mdh == (convention == "mdh") and dh.name == name
    np.testing.assert_allclose(dh.qlim.T, [j.limits for j in robot.joints])
    _assert_same(robot, dh, _q(robot, 100, 1))
    back = robocal.from_roboticstoolbox(dh)
    assert [j.convention for j in back.joints] == [j.convention for j in robot.joints]
    np.testing.assert_allclose(back.params, robot.params, rtol=1e-15, atol=1e-12)
    assert [j.limits for j in back.joints] == [j.limits for j in robot.joints]


def test_millimetres_and_prismatic_joints():
    robot = three_joint_robot(["dh"] * 3, ["revolute", "prismatic", "revolute"], beta=False, name="rpr")
    for unit in ("m", "mm"):
        dh = robocal.to_roboticstoolbox(robot, length_unit=unit)
        assert dh.links[1].isprismatic and dh.links[1].qlim[1] == pytest.approx(400.0 if unit == "mm" else 0.4)
        _assert_same(robot, dh, _q(robot, 50, 2), unit)
        back = robocal.from_roboticstoolbox(dh, length_unit=unit)
        np.testing.assert_allclose(back.params, robot.params, rtol=1e-14, atol=1e-12)
        assert [j.kind for j in back.joints] == ["revolute", "prismatic", "revolute"]


def test_the_toolboxs_own_models_come_in():
    """A model defined by the toolbox itself (metres), not by robocal."""
    for model in (rtb.models.DH.Puma560(), rtb.models.DH.UR10(), rtb.models.DH.Panda()):
        robot = robocal.from_roboticstoolbox(model)
        assert robot.n_joints == model.n and {j.convention for j in robot.joints} == {"mdh" if model.mdh else "dh"}
        _assert_same(robot, model, _q(robot, 50, 3))


_angle = st.floats(-math.pi, math.pi)
_length = st.floats(-900.0, 900.0)


@settings(max_examples=30, deadline=None)
@given(links=st.lists(st.tuples(_angle, _length, _length, _angle, st.booleans()), min_size=1, max_size=7), mdh=st.booleans(), seed=st.integers(0, 99))
def test_random_chains_agree(links, mdh, seed):
    joints = [Joint("mdh" if mdh else "dh", "prismatic" if p else "revolute", False, (-500.0, 500.0) if p else (-3.0, 3.0)) for *_, p in links]
    params = np.concatenate(
        [
            np.ravel([(al, a, d, th, 0.0) for al, a, d, th, _ in links]),
            np.random.default_rng(seed).normal(0, 1, 12) * np.tile([100, 100, 100, 0.4, 0.4, 0.4], 2),
            [0, 0, 0, 0, 1.0],
        ]
    )
    robot = Robot("random", joints, params)
    dh = robocal.to_roboticstoolbox(robot)
    _assert_same(robot, dh, _q(robot, 20, seed))
    np.testing.assert_allclose(robocal.from_roboticstoolbox(dh).params, robot.params, rtol=1e-13, atol=1e-9)


def test_what_a_dhrobot_cannot_hold_is_refused():
    with pytest.raises(InvalidParameterError, match=r"joint 2 \(beta = 0\.0572958 deg\).*no Hayati beta.*URDF"):
        robocal.to_roboticstoolbox(robocal.robot("ur10").with_params(beta2=1e-3))
    mixed = Robot("mixed", [Joint("dh"), Joint("mdh")], np.r_[np.zeros(10 + 16), 1.0])
    with pytest.raises(InvalidParameterError, match=r"mixes conventions \['dh', 'mdh'\]"):
        robocal.to_roboticstoolbox(mixed)
    with pytest.raises(InvalidParameterError, match="length_unit"):
        robocal.to_roboticstoolbox(robocal.robot("ur10"), length_unit="inch")
    with pytest.raises(InvalidParameterError, match="takes a roboticstoolbox DHRobot; got dict"):
        robocal.from_roboticstoolbox({})
    flipped = rtb.DHRobot([rtb.RevoluteDH(a=0.1, flip=True)], name="f")
    with pytest.raises(InvalidParameterError, match="link 1: its joint is flipped"):
        robocal.from_roboticstoolbox(flipped)
    no_range = rtb.DHRobot([rtb.PrismaticDH(a=0.1)], name="p")
    with pytest.raises(InvalidParameterError, match="link 1: a prismatic joint needs qlim"):
        robocal.from_roboticstoolbox(no_range)
