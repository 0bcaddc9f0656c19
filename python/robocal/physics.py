"""Physics of the robot beyond its kinematics: mass models (masses and centres of mass), gravity torques about
the joints and the approach direction that decides a joint's backlash.

Part of the model layer: the simulator's effects (:mod:`robocal.effects`) generate data with it
and the diagnosis (:mod:`robocal.causes.candidates`) fits the same signatures.
"""

from __future__ import annotations

import math
from typing import Optional

import numpy as np

from .exceptions import InvalidParameterError
from .serial_robot import MassModel, Robot

DEG = math.pi / 180.0
GRAVITY = 9.81  # m/s², acting along −z of the robot base frame (a floor-mounted robot)

# ---------------------------------------------------------------------------------------------
# Mass models of the built-in robots, for the gravity torques of `joint_compliance`.
#
# Each link j (moved by joint j) has a mass and a centre of mass (COM) given in its own DH frame j
# (the frame after joint j's link transform, which moves with link j), in mm. A link without a
# COM is lumped at the midpoint of the segment joining the origins of DH frames j-1 and j.
# A robot file can carry its own model (its `masses` section, docs/data-format.md), which
# :func:`mass_model` prefers over the built-in one of the same name. Sources:
# * hsr-jr680: an APPROXIMATION (midpoints). HSR does not publish a link breakdown and its total
#   mass was not at hand; about 620 kg is assumed from robots of the same class (80 kg payload,
#   ~2 m reach: ABB IRB 4600-60 435 kg, KUKA KR 60-3 665 kg), split plausibly over column, arms
#   and wrist (the rest, ~120 kg, is the fixed base). Rated payload 80 kg (catalog).
# * abb-irb120: an APPROXIMATION (midpoints): total 25 kg and rated payload 3 kg from ABB's
#   product specification, split plausibly (the fixed base takes ~9.5 kg).
# * ur10: the masses AND centres of mass Universal Robots publishes with its DH parameters for
#   dynamics ("Parameters for calculations of kinematics and dynamics", universal-robots.com,
#   articles/ur/parameters-for-calculations-of-kinematics-and-dynamics; robot 28.9 kg, payload
#   10 kg): masses 7.1, 12.7, 4.27, 2.0, 2.0, 0.365 kg, COMs in the DH link frames [m]
#   [0.021, 0, 0.027], [0.38, 0, 0.158], [0.24, 0, 0.068], [0, 0.007, 0.018], [0, 0.007, 0.018],
#   [0, 0, -0.026]. The UR10 (CB3) rows were read through Peter Corke's Robotics Toolbox for
#   Python (roboticstoolbox/models/DH/UR10.py, which cites that page and uses the same DH as
#   robocal's ur10: a2 = -612, a3 = -572.3 mm); the stored copy of UR's page lists the same COMs
#   for the UR10e's links 1-5. Link 2's COM, 0.38 m along x2 from the elbow, sits 232 mm from the
#   shoulder (the midpoint model put it at 306 mm) and 158 mm along the shoulder axis.
# Default compliances (rad/(N·m)) are literature orders of magnitude for the joint class: large
# industrial robots have joint stiffnesses ~1e6-1e7 N·m/rad (Dumas et al., "Joint stiffness
# identification of six-revolute industrial serial robots", RCIM 2011); small robots and
# harmonic-drive cobots ~1e4-1e5 N·m/rad.
# ---------------------------------------------------------------------------------------------


def _mm(metres) -> tuple:
    return tuple(round(1000.0 * v, 9) for v in metres)


MASS_MODELS = {
    "hsr-jr680": MassModel((220.0, 110.0, 95.0, 55.0, 18.0, 5.0), rated_payload=80.0, compliance=3e-7),
    "abb-irb120": MassModel((5.5, 4.0, 3.5, 1.8, 0.6, 0.1), rated_payload=3.0, compliance=2e-5),
    "ur10": MassModel(
        (7.1, 12.7, 4.27, 2.0, 2.0, 0.365),
        rated_payload=10.0,
        compliance=1e-5,
        centres_of_mass=tuple(_mm(c) for c in ([0.021, 0, 0.027], [0.38, 0, 0.158], [0.24, 0, 0.068], [0, 0.007, 0.018], [0, 0.007, 0.018], [0, 0, -0.026])),
    ),
}


def mass_model(robot: Robot) -> Optional[MassModel]:
    """The robot's mass model: its own (a robot file's ``masses``, :attr:`Robot.mass_model`),
    else the built-in one of its name (:data:`MASS_MODELS`), else None."""
    return robot.mass_model if robot.mass_model is not None else MASS_MODELS.get(robot.name)


def _zero_base(robot: Robot, params: np.ndarray) -> np.ndarray:
    p = np.array(params, dtype=float)
    base = robot.index("base_x")
    p[base : base + 6] = 0.0
    return p


def link_transforms(robot: Robot, q, params=None) -> np.ndarray:
    """Poses of DH frames 0..N in the robot base frame (base transform left out).

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
    ndarray, shape (m, N + 1, 4, 4)
        Homogeneous transforms, translations in mm.
    """
    p = _zero_base(robot, robot.params if params is None else params)
    q = robot._joints_array(q)
    n = robot.n_joints
    T = np.zeros((len(q), n + 1, 4, 4))
    T[:, 0] = np.eye(4)
    frames = p[5 * n :].copy()
    frames[6:12] = 0.0  # no tool: the chain ends at the flange
    for j in range(1, n + 1):
        part = Robot(robot.name, robot.joints[:j], np.concatenate([p[: 5 * j], frames]))
        T[:, j] = part.fkine(q[:, :j])
    return T


def link_frames(robot: Robot, q, params=None) -> tuple[np.ndarray, np.ndarray]:
    """Origins (mm) and unit z axes, each (m, N + 1, 3), of DH frames 0..N in the robot base
    frame (base transform left out): :func:`link_transforms`."""
    T = link_transforms(robot, q, params)
    return T[:, :, :3, 3], T[:, :, :3, 2]


def centres_of_mass(model: MassModel, T: np.ndarray) -> np.ndarray:
    """The links' centres of mass (m, N, 3) in mm in the robot base frame, from the DH frames
    ``T`` (m, N + 1, 4, 4) of :func:`link_transforms`: ``R_j c_j + o_j`` for a link with a
    centre of mass ``c_j`` (frame j), the midpoint of ``o_{j-1}`` and ``o_j`` otherwise."""
    origins = T[:, :, :3, 3]
    centres = 0.5 * (origins[:, :-1] + origins[:, 1:])  # link k at index k-1
    for k, com in enumerate(model.centres_of_mass or ()):
        if com is not None:
            centres[:, k] = T[:, k + 1, :3, :3] @ np.asarray(com, dtype=float) + origins[:, k + 1]
    return centres


def gravity_torques(robot: Robot, q, params=None, payload: float = 0.0, model: Optional[MassModel] = None) -> np.ndarray:
    """Gravity torque about each joint axis from the robot's mass model, in N·m.

    ``τ_j = Σ_{loads k distal to joint j} z_{j-1} · ((c_k − o_{j-1}) × m_k g)``, with ``g``
    along −z of the robot base frame, link masses ``m_k`` at their centres of mass
    (:func:`centres_of_mass`: given in the link's DH frame, else the midpoint of consecutive DH
    frame origins) and ``payload`` (kg) at the tool point. ``τ_j`` is the torque gravity exerts
    on the links beyond joint j, about joint j's axis (standard DH: the z axis of frame j-1
    through its origin), ``−∂V/∂q_j`` of the potential energy ``V = −Σ m_k g · c_k``.

    Parameters
    ----------
    robot : Robot
        A chain of revolute standard-DH joints with a mass model (:func:`mass_model`).
    q : array_like, shape (m, N)
        Joint values in rad.
    params : array_like, optional
        Parameter vector (nominal by default); the tool point comes from its tool frame.
    payload : float
        Payload in kg at the tool point.
    model : MassModel, optional
        The masses; :func:`mass_model` of ``robot`` by default.

    Returns
    -------
    ndarray, shape (m, N)
    """
    model = mass_model(robot) if model is None else model
    if model is None:
        raise InvalidParameterError(
            f"no mass model for robot {robot.name!r}: give its robot file a 'masses' section (docs/data-format.md) "
            f"or use a built-in robot with one ({sorted(MASS_MODELS)})"
        )
    if any(j.convention != "dh" or j.kind != "revolute" for j in robot.joints):
        raise InvalidParameterError("gravity torques need a chain of revolute standard-DH joints")
    if len(model.link_masses) != robot.n_joints:
        raise InvalidParameterError(f"the mass model has {len(model.link_masses)} links; robot {robot.name!r} has {robot.n_joints} joints")
    p = _zero_base(robot, robot.params if params is None else params)
    T = link_transforms(robot, q, p)
    origins, z_axes = T[:, :, :3, 3], T[:, :, :3, 2]
    tool_point = robot.fkine(q, p, tool=True)[:, :3, 3]
    points = np.concatenate([centres_of_mass(model, T), tool_point[:, None]], axis=1) / 1000.0  # m
    weights = np.array(tuple(model.link_masses) + (payload,)) * GRAVITY  # N, pointing down
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


def gravity_regressor(robot: Robot, q, joint: int, params=None) -> np.ndarray:
    """The static gravity regressor of joint ``joint`` (0-based): its gravity torque (N·m) is
    ``Y·π`` for any masses of the links it carries, ``π`` their masses (kg) and first mass
    moments (kg·m, in each link's DH frame), four per link ``joint+1 .. N`` (a payload is part of
    the last link's). ``τ = z·((o_k − o) × m_k g) + z·((R_k h_k) × g)`` about the joint's axis
    ``z`` through ``o``, ``g`` along −z of the robot base frame (:func:`gravity_torques`, whose
    mass model is one ``π``). Returns ``Y``, (m, 4·(N − joint))."""
    if any(j.convention != "dh" or j.kind != "revolute" for j in robot.joints):
        raise InvalidParameterError("gravity torques need a chain of revolute standard-DH joints")
    p = _zero_base(robot, robot.params if params is None else params)
    T = link_transforms(robot, q, p)
    origin, axis = T[:, joint, :3, 3] / 1000.0, T[:, joint, :3, 2]
    down = np.array([0.0, 0.0, -GRAVITY])
    columns = []
    for k in range(joint + 1, robot.n_joints + 1):  # the frame of each link the joint carries
        lever = T[:, k, :3, 3] / 1000.0 - origin
        columns.append(np.einsum("mi,mi->m", np.cross(lever, down), axis))  # its mass at the frame's origin
        # its first moment h (frame k): z·((R h) × g) = h · Rᵀ(g × z)
        columns.append(np.einsum("mji,mj->mi", T[:, k, :3, :3], np.cross(down, axis)))
    return np.column_stack(columns)


#: Configurations (uniform within the joint limits, a fixed draw) on which the base parameters
#: of static gravity are found: the regressor's columns that are independent at every pose.
BASE_CONFIGURATIONS = 200


def standard_poses(robot: Robot) -> np.ndarray:
    """:data:`BASE_CONFIGURATIONS` joint configurations uniform within the joint limits (at most
    a turn), the same draw every time: where a deflection is summarised independently of the
    data."""
    lower, upper = np.array([j.limits for j in robot.joints]).T
    return np.random.default_rng(0).uniform(np.maximum(lower, -math.pi), np.minimum(upper, math.pi), size=(BASE_CONFIGURATIONS, robot.n_joints))


def gravity_base_columns(robot: Robot, joint: int) -> np.ndarray:
    """The columns of :func:`gravity_regressor` that are independent (pivoted QR on
    :data:`BASE_CONFIGURATIONS` poses of the nominal robot, as dynamic identification finds its
    base parameters): the rest are combinations of them at every pose (a mass at a frame's
    origin is the previous link's moment along its ``a``; a moment along a vertical axis makes
    no torque). Fixed for a robot and a joint, so that a fitted deflection carries to any pose."""
    from scipy.linalg import qr  # imported on use: only the free-mass compliance needs it

    # Found once per chain and joint (200 poses' link frames, ~40 ms): a compensation evaluates
    # the deflection at every step. Keyed by what the columns depend on, not by the object.
    key = (robot.name, robot.params.tobytes(), tuple((j.convention, j.kind, tuple(j.limits)) for j in robot.joints), joint)
    if key not in _BASE_COLUMNS:
        Y = gravity_regressor(robot, standard_poses(robot), joint)
        _, R, order = qr(Y, mode="economic", pivoting=True)
        d = np.abs(np.diag(R))
        rank = int(np.count_nonzero(d > 1e-9 * max(float(d[0]), 1e-300))) if len(d) else 0
        _BASE_COLUMNS[key] = np.sort(order[:rank])
    return _BASE_COLUMNS[key].copy()


#: :func:`gravity_base_columns` found so far (a handful of robots and joints per process).
_BASE_COLUMNS: dict = {}
