"""Physics of the robot beyond its kinematics: approximate mass models, gravity torques about
the joints and the approach direction that decides a joint's backlash.

Part of the model layer: the simulator's effects (:mod:`robocal.effects`) generate data with it
and the diagnosis (:mod:`robocal.diagnosis.candidates`) fits the same signatures.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .exceptions import InvalidParameterError
from .robot import Robot

DEG = math.pi / 180.0
GRAVITY = 9.81  # m/s², acting along −z of the robot base frame (a floor-mounted robot)

# ---------------------------------------------------------------------------------------------
# Approximate mass models of the built-in robots, for the gravity torques of `joint_compliance`.
#
# These are APPROXIMATIONS, good enough for a realistic size and shape of the compliance error,
# not identified dynamics. Each link's mass is lumped at the midpoint of the segment joining the
# origins of DH frames j-1 and j (a point that moves with link j). Sources:
# * hsr-jr680: HSR does not publish a link breakdown and its total mass was not at hand; about
#   620 kg is assumed from robots of the same class (80 kg payload, ~2 m reach: ABB IRB 4600-60
#   435 kg, KUKA KR 60-3 665 kg), split plausibly over column, arms and wrist (the rest, ~120 kg,
#   is the fixed base). Rated payload 80 kg (catalog).
# * abb-irb120: total 25 kg and rated payload 3 kg from ABB's product specification, split
#   plausibly (the fixed base takes ~9.5 kg).
# * ur10: the link masses Universal Robots publishes with its DH parameters for dynamics
#   (7.1, 12.7, 4.27, 2.0, 2.0, 0.365 kg; robot 28.9 kg, payload 10 kg).
# Default compliances (rad/(N·m)) are literature orders of magnitude for the joint class: large
# industrial robots have joint stiffnesses ~1e6-1e7 N·m/rad (Dumas et al., "Joint stiffness
# identification of six-revolute industrial serial robots", RCIM 2011); small robots and
# harmonic-drive cobots ~1e4-1e5 N·m/rad.
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class MassModel:
    """Approximate masses of a robot for gravity torques.

    Attributes
    ----------
    link_masses : tuple of float
        Mass of link j (moved by joint j) in kg, lumped at the midpoint of DH frame origins
        ``o_{j-1}`` and ``o_j``.
    rated_payload : float
        The robot's rated payload in kg (for reference; the effect's payload defaults to 0).
    compliance : float
        Default joint compliance in rad/(N·m).
    """

    link_masses: tuple
    rated_payload: float
    compliance: float


MASS_MODELS = {
    "hsr-jr680": MassModel((220.0, 110.0, 95.0, 55.0, 18.0, 5.0), rated_payload=80.0, compliance=3e-7),
    "abb-irb120": MassModel((5.5, 4.0, 3.5, 1.8, 0.6, 0.1), rated_payload=3.0, compliance=2e-5),
    "ur10": MassModel((7.1, 12.7, 4.27, 2.0, 2.0, 0.365), rated_payload=10.0, compliance=1e-5),
}


def _zero_base(robot: Robot, params: np.ndarray) -> np.ndarray:
    p = np.array(params, dtype=float)
    base = robot.index("base_x")
    p[base : base + 6] = 0.0
    return p


def link_frames(robot: Robot, q, params=None) -> tuple[np.ndarray, np.ndarray]:
    """Origins and z axes of DH frames 0..N in the robot base frame (base transform left out).

    Frame j is the frame after joint j's link transform, computed with the robot's own chain
    truncated after joint j; frame 0 is the base.

    Parameters
    ----------
    robot : Robot
    q : array_like, shape (m, N)
        Joint values in rad.
    params : array_like, shape (5N + 17,), optional
        Parameter vector; the nominal one by default. Its base frame is ignored.

    Returns
    -------
    origins, z_axes : ndarray, shape (m, N + 1, 3)
        Origins in mm and unit z axes.
    """
    p = _zero_base(robot, robot.params if params is None else params)
    q = robot._joints_array(q)
    n = robot.n_joints
    m = len(q)
    origins, z_axes = np.zeros((m, n + 1, 3)), np.zeros((m, n + 1, 3))
    z_axes[:, 0, 2] = 1.0
    frames = p[5 * n :].copy()
    frames[6:12] = 0.0  # no tool: the chain ends at the flange
    for j in range(1, n + 1):
        part = Robot(robot.name, robot.joints[:j], np.concatenate([p[: 5 * j], frames]))
        T = part.fkine(q[:, :j])
        origins[:, j], z_axes[:, j] = T[:, :3, 3], T[:, :3, 2]
    return origins, z_axes


def gravity_torques(robot: Robot, q, params=None, payload: float = 0.0) -> np.ndarray:
    """Gravity torque about each joint axis from an approximate mass model, in N·m.

    ``τ_j = Σ_{loads k distal to joint j} z_{j-1} · ((c_k − o_{j-1}) × m_k g)``, with ``g``
    along −z of the robot base frame, link masses ``m_k`` at the midpoints of consecutive DH
    frame origins (:data:`MASS_MODELS`) and ``payload`` (kg) at the tool point. ``τ_j`` is the
    torque gravity exerts on the links beyond joint j, about joint j's axis (standard DH: the z
    axis of frame j-1 through its origin).

    Parameters
    ----------
    robot : Robot
        A built-in robot (standard DH) with a mass model.
    q : array_like, shape (m, N)
        Joint values in rad.
    params : array_like, optional
        Parameter vector (nominal by default); the tool point comes from its tool frame.
    payload : float
        Payload in kg at the tool point.

    Returns
    -------
    ndarray, shape (m, N)
    """
    model = MASS_MODELS.get(robot.name)
    if model is None:
        raise InvalidParameterError(f"no mass model for robot {robot.name!r}; gravity torques are available for {sorted(MASS_MODELS)}")
    if any(j.convention != "dh" or j.kind != "revolute" for j in robot.joints):
        raise InvalidParameterError("gravity torques need a chain of revolute standard-DH joints")
    p = _zero_base(robot, robot.params if params is None else params)
    origins, z_axes = link_frames(robot, q, p)
    tool_point = robot.fkine(q, p, tool=True)[:, :3, 3]
    centres = 0.5 * (origins[:, :-1] + origins[:, 1:])  # (m, N, 3): link k at index k-1
    points = np.concatenate([centres, tool_point[:, None]], axis=1) / 1000.0  # m
    weights = np.array(model.link_masses + (payload,)) * GRAVITY  # N, pointing down
    n = robot.n_joints
    tau = np.zeros((len(points), n))
    for j in range(n):  # joint j+1 carries links j+1..N and the payload: loads j..N
        lever = points[:, j:] - origins[:, j, None] / 1000.0
        moment = np.cross(lever, np.array([0.0, 0.0, -1.0])) * weights[j:, None]  # (m, loads, 3)
        tau[:, j] = np.einsum("mk,mk->m", moment.sum(axis=1), z_axes[:, j])
    return tau


def approach_directions(q: np.ndarray) -> np.ndarray:
    """Approach direction (+1 / −1) of each sample of one joint's values ``q`` (m,), in
    acquisition order: the sign of the last nonzero move, +1 before the first (backlash)."""
    step = np.sign(np.diff(q, prepend=q[0]))
    step[0] = 1.0
    last_move = np.maximum.accumulate(np.where(step != 0, np.arange(len(q)), 0))
    return step[last_move]
