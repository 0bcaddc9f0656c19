"""Mass models with centres of mass: gravity torques against the potential energy (an independent
NumPy chain), the midpoint default, the robot file's ``masses`` section (round trip, named errors)
and a user's robot with masses in the simulator and the diagnosis."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import robocal
from robocal import simulation as sim
from robocal.causes.candidates import has_mass_model, library
from robocal.exceptions import InvalidParameterError
from robocal.physics import GRAVITY, MASS_MODELS, MassModel, gravity_torques, mass_model
from robocal.robot_file import robot_document

UR10_COM_M = ([0.021, 0, 0.027], [0.38, 0, 0.158], [0.24, 0, 0.068], [0, 0.007, 0.018], [0, 0.007, 0.018], [0, 0, -0.026])


# -- an independent chain: standard DH with Hayati's beta, written out here ----------------------
def _dh(alpha, a, d, theta, beta):
    ct, st_, ca, sa, cb, sb = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha), math.cos(beta), math.sin(beta)
    rz = np.array([[ct, -st_, 0, 0], [st_, ct, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    tz, tx = np.eye(4), np.eye(4)
    tz[2, 3], tx[0, 3] = d, a
    rx = np.array([[1, 0, 0, 0], [0, ca, -sa, 0], [0, sa, ca, 0], [0, 0, 0, 1.0]])
    ry = np.array([[cb, 0, sb, 0], [0, 1, 0, 0], [-sb, 0, cb, 0], [0, 0, 0, 1.0]])
    return rz @ tz @ tx @ rx @ ry


def _tool(x, y, z, rx, ry, rz):
    c = np.cos([rx, ry, rz])
    s = np.sin([rx, ry, rz])
    Rx = np.array([[1, 0, 0], [0, c[0], -s[0]], [0, s[0], c[0]]])
    Ry = np.array([[c[1], 0, s[1]], [0, 1, 0], [-s[1], 0, c[1]]])
    Rz = np.array([[c[2], -s[2], 0], [s[2], c[2], 0], [0, 0, 1]])
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = Rz @ Ry @ Rx, (x, y, z)
    return T


def potential(robot, model, q, payload):
    """V = Σ m g z_c (J, z in m): link centres of mass (frame j, or the midpoint of o_{j-1}, o_j)
    and the payload at the tool point, the base frame left out."""
    n, p = robot.n_joints, robot.params
    T, origins, heights = np.eye(4), [np.zeros(3)], []
    for j in range(n):
        alpha, a, d, theta, beta = p[5 * j : 5 * j + 5]
        T = T @ _dh(alpha, a, d, theta + q[j], beta)
        origins.append(T[:3, 3].copy())
        com = None if model.centres_of_mass is None else model.centres_of_mass[j]
        c = 0.5 * (origins[j] + origins[j + 1]) if com is None else T[:3, :3] @ np.array(com) + T[:3, 3]
        heights.append(c[2])
    tool = (T @ _tool(*p[robot.index("tool_x") : robot.index("tool_x") + 6]))[2, 3]
    return GRAVITY * (np.dot(model.link_masses, heights) + payload * tool) / 1000.0


def torques_from_energy(robot, model, q, payload, h=1e-6):
    """τ_j = −∂V/∂q_j by central differences."""
    tau = np.zeros(len(q))
    for j in range(len(q)):
        dq = np.zeros(len(q))
        dq[j] = h
        tau[j] = -(potential(robot, model, q + dq, payload) - potential(robot, model, q - dq, payload)) / (2 * h)
    return tau


ANGLES = arrays(np.float64, 6, elements=st.floats(-math.pi, math.pi))


@given(q=ANGLES, name=st.sampled_from(sorted(MASS_MODELS)), payload=st.sampled_from([0.0, 7.5]))
def test_torques_are_minus_the_gradient_of_the_potential_energy(q, name, payload):
    r = robocal.robot(name).with_params(tool_x=30.0, tool_z=150.0, tool_ry=0.3)
    model = MASS_MODELS[name]
    tau = gravity_torques(r, q[None], payload=payload)[0]
    scale = GRAVITY * (sum(model.link_masses) + payload) * 2.0  # N·m at a 2 m lever
    np.testing.assert_allclose(tau, torques_from_energy(r, model, q, payload), rtol=0, atol=1e-7 * scale)


@given(q=ANGLES, com=arrays(np.float64, (6, 3), elements=st.floats(-300, 300)), midpoint=st.lists(st.booleans(), min_size=6, max_size=6))
def test_any_centres_of_mass_against_the_potential_energy(q, com, midpoint):
    """Centres of mass anywhere in their link frames, some links left at their midpoints."""
    r = robocal.robot("abb-irb120").with_params(beta2=0.01, tool_y=-40.0)
    model = MassModel((5.5, 4.0, 3.5, 1.8, 0.6, 0.1), centres_of_mass=tuple(None if m else tuple(c) for m, c in zip(midpoint, com)))
    tau = gravity_torques(r, q[None], payload=2.0, model=model)[0]
    np.testing.assert_allclose(tau, torques_from_energy(r, model, q, 2.0), rtol=0, atol=1e-7 * GRAVITY * 20)


def test_ur10_matches_roboticstoolbox_gravload():
    """The Robotics Toolbox's UR10 has the same DH, UR's masses and centres of mass: its holding
    torque (gravity (0, 0, −9.81)) is minus the torque gravity exerts."""
    rtb = pytest.importorskip("roboticstoolbox")
    ur = rtb.models.DH.UR10()
    q = np.random.default_rng(4).uniform(-3, 3, (8, 6))
    ours = gravity_torques(robocal.robot("ur10"), q)
    theirs = np.array([ur.gravload(qi, gravity=[0, 0, -GRAVITY]) for qi in q])
    np.testing.assert_allclose(ours, -theirs, rtol=0, atol=1e-9)


def test_ur10_uses_ur_centres_of_mass_and_midpoints_are_the_default():
    assert MASS_MODELS["ur10"].centres_of_mass == tuple(tuple(1000.0 * v for v in c) for c in UR10_COM_M)
    assert MASS_MODELS["hsr-jr680"].centres_of_mass is None and MASS_MODELS["abb-irb120"].centres_of_mass is None
    r = robocal.robot("ur10")
    q = np.random.default_rng(2).uniform(-3, 3, (30, 6))
    midpoints = replace(MASS_MODELS["ur10"], centres_of_mass=None)
    every_link_none = replace(MASS_MODELS["ur10"], centres_of_mass=(None,) * 6)
    np.testing.assert_array_equal(gravity_torques(r, q, model=midpoints), gravity_torques(r, q, model=every_link_none))
    # Link 2's centre of mass sits 232 mm from the shoulder instead of 306: joint 2 carries less.
    assert not np.allclose(gravity_torques(r, q), gravity_torques(r, q, model=midpoints), atol=1e-3)


def test_mass_model_is_the_robots_own_first():
    r = robocal.robot("ur10")
    assert r.mass_model is None and mass_model(r) is MASS_MODELS["ur10"]
    own = MassModel((1.0,) * 6, compliance=2e-6)
    mine = robocal.Robot("ur10", r.joints, r.params, own)
    assert mass_model(mine) is own and mass_model(mine.with_params(tool_z=10.0)) is own
    assert mass_model(robocal.Robot("my-robot", r.joints, r.params)) is None
    with pytest.raises(robocal.exceptions.ShapeError, match="mass model has 2 links; expected one per joint"):
        robocal.Robot("x", r.joints, r.params, MassModel((1.0, 2.0)))


# -- robot files -----------------------------------------------------------------------------------
def my_robot(compliance=1.5e-5) -> robocal.Robot:
    """The UR10's kinematics under another name, with UR's masses (one link at its midpoint)."""
    ur = robocal.robot("ur10")
    com = tuple(tuple(1000.0 * v for v in c) for c in UR10_COM_M)
    model = MassModel(MASS_MODELS["ur10"].link_masses, rated_payload=10.0, compliance=compliance, centres_of_mass=com[:5] + (None,))
    return robocal.Robot("my-robot", ur.joints, ur.params, model)


@pytest.mark.parametrize("suffix", [".json", ".yaml"])
@pytest.mark.parametrize("compliance", [1.5e-5, None])
def test_masses_round_trip(tmp_path, suffix, compliance):
    r = my_robot(compliance)
    back = robocal.robot(robocal.write_robot(r, tmp_path / f"r{suffix}"))
    assert back.mass_model == r.mass_model
    np.testing.assert_array_equal(back.params, r.params)
    doc = robot_document(r)["masses"]
    assert doc["links"][0] == {"mass_kg": 7.1, "com_mm": [21.0, 0.0, 27.0]} and doc["links"][5] == {"mass_kg": 0.365}
    assert ("compliance_rad_per_Nm" in doc) == (compliance is not None)
    # the built-ins keep their model by name and write none
    assert "masses" not in robot_document(robocal.robot("ur10"))


def test_hand_written_masses(tmp_path):
    doc = robot_document(robocal.robot("abb-irb120"))
    doc["masses"] = {"links": [{"mass_kg": m} for m in (5.5, 4.0, 3.5, 1.8, 0.6, 0.1)]}
    (tmp_path / "irb.json").write_text(json.dumps(doc))
    r = robocal.robot(str(tmp_path / "irb.json"))
    assert r.mass_model == MassModel((5.5, 4.0, 3.5, 1.8, 0.6, 0.1))
    q = np.random.default_rng(3).uniform(-2, 2, (10, 6))
    np.testing.assert_array_equal(gravity_torques(r, q), gravity_torques(robocal.robot("abb-irb120"), q))


LINKS = [{"mass_kg": 2.0, "com_mm": [0.0, 0.0, 10.0]}] * 6


@pytest.mark.parametrize(
    "masses, message",
    [
        ({"links": [{"mass_kg": -1.0}] + LINKS[1:]}, r"key 'masses', link 1, key 'mass_kg': input should be greater than 0; got -1.0"),
        ({"links": LINKS[:4]}, r"key 'masses': key 'links' has 4 entries; expected one per joint \(6\)$"),
        ({"links": LINKS[:2] + [{"mass_kg": 1.0, "com_mm": [0.0, float("nan"), 0.0]}] + LINKS[3:]}, r"key 'masses', link 3, key 'com_mm', item 2: .*finite"),
        ({"links": LINKS[:5] + [{"mass_kg": 1.0, "com_mm": [1.0, 2.0]}]}, r"key 'masses', link 6, key 'com_mm': list should have at least 3 items"),
        ({"links": LINKS, "compliance_rad_per_Nm": 0.0}, r"key 'masses', key 'compliance_rad_per_Nm': input should be greater than 0"),
        ({"links": LINKS, "payload": 3}, r"key 'masses', key 'payload': unknown key \(allowed: links, rated_payload_kg, compliance_rad_per_Nm\)"),
        ({"links": [{"mass": 1.0}] * 6}, r"key 'masses', link 1 lacks mass_kg"),
        ({"links": [{"mass_kg": 1.0, "com": [0, 0, 0]}] * 6}, r"key 'masses', link 1, key 'com': unknown key \(allowed: mass_kg, com_mm\)"),
        ({"links": [{"mass_kg": "2"}] * 6}, r"key 'masses', link 1, key 'mass_kg': input should be a valid number"),
    ],
)
def test_bad_masses_are_named(tmp_path, masses, message):
    doc = robot_document(robocal.robot("ur10"))
    doc["masses"] = masses
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    with pytest.raises(InvalidParameterError, match=r"bad.json: " + message):
        robocal.robot(tmp_path / "bad.json")


# -- a user's robot with masses: simulator and diagnosis ---------------------------------------------
def test_a_robot_file_with_masses_gets_compliance(tmp_path):
    r = robocal.robot(str(robocal.write_robot(my_robot(), tmp_path / "my-robot.yaml")))
    assert r.name == "my-robot" and r.name not in MASS_MODELS and has_mass_model(r)
    assert not has_mass_model(robocal.Robot("my-robot", r.joints, r.params))

    data, truth = sim.simulate(r, "position", samples=80, seed=5, noise=0, effects=["joint_compliance:joint=2,payload=5"])
    record = truth["effects"][0]
    assert record["kind"] == "joint_compliance"
    assert record["parameters"]["compliance"]["value"] == pytest.approx(np.degrees(1.5e-5) * 1000)  # the file's default
    P = sim.true_params(truth, r)
    q = data.q.copy()
    q[:, 1] += 1.5e-5 * gravity_torques(r, data.q, P, payload=5)[:, 1]
    np.testing.assert_allclose(data.y, r.predict("position", q, P), rtol=0, atol=1e-9)

    kinds = {(c.kind, c.joint) for c in library(r, data, considered=list(r.param_names))}
    assert ("joint_compliance", 1) in kinds and ("joint_compliance", 2) in kinds

    # without a default compliance the effect asks for one
    bare = robocal.Robot("my-robot", r.joints, r.params, replace(r.mass_model, compliance=None))
    with pytest.raises(InvalidParameterError, match="no default compliance: give key 'compliance'"):
        sim.simulate(bare, "position", samples=20, effects=["joint_compliance:joint=2"])
    sim.simulate(bare, "position", samples=20, effects=["joint_compliance:joint=2,compliance=0.5"])
    with pytest.raises(InvalidParameterError, match="no mass model for robot 'my-robot': give its robot file a 'masses' section"):
        sim.simulate(robocal.Robot("my-robot", r.joints, r.params), "position", samples=20, effects=["joint_compliance:joint=2"])
