"""roboticstoolbox-python interop: a robocal :class:`~robocal.serial_robot.Robot` as a
``roboticstoolbox.DHRobot`` and back (the optional extra ``robocal[rtb]``, imported on use).

The two models are the same equations: roboticstoolbox's standard DH link is
``Rz(theta) Tz(d) Tx(a) Rx(alpha)`` and its modified DH link ``Rx(alpha) Tx(a) Rz(theta) Tz(d)``,
robocal's without Hayati's ``beta``; the joint variable adds to ``theta`` (revolute) or ``d``
(prismatic) through the link's ``offset``. So a robocal joint maps to a link as:

=============  ====================================  ====================================
robocal        ``RevoluteDH`` / ``RevoluteMDH``       ``PrismaticDH`` / ``PrismaticMDH``
=============  ====================================  ====================================
``alpha``      ``alpha`` (rad)                        ``alpha`` (rad)
``a``          ``a``                                  ``a``
``d``          ``d``                                  ``offset``
``theta``      ``offset`` (rad)                       ``theta`` (rad)
``limits``     ``qlim`` (rad)                         ``qlim``
=============  ====================================  ====================================

and the base and tool frames to ``DHRobot.base`` / ``DHRobot.tool`` (``SE3``). Lengths are
metres on the toolbox side by default (its own robot models are in metres; ``length_unit="mm"``
keeps millimetres), so a prismatic joint's value is in metres there too. What a ``DHRobot`` cannot
hold is refused rather than dropped: a non-zero Hayati ``beta`` (DHRobot has no such parameter;
export the robot as URDF instead) and a chain that mixes DH and MDH joints (DHRobot refuses
those too). The cable-sensor parameters (anchor, ``cable_offset``, ``cable_scale``) are not part
of a DHRobot: :func:`from_roboticstoolbox` sets them to their neutral values.
"""

from __future__ import annotations

import math

import numpy as np

from .exceptions import InvalidParameterError, MissingDependencyError
from .geometry import frame_params, frame_transform
from .serial_robot import Joint, Robot

_SCALE = {"m": 1000.0, "mm": 1.0}  # mm per unit of the toolbox's lengths


def _toolbox(what: str):
    try:
        import roboticstoolbox
        from spatialmath import SE3
    except ImportError:
        raise MissingDependencyError(f"{what} needs roboticstoolbox-python, an optional dependency: pip install 'robocal[rtb]'") from None
    return roboticstoolbox, SE3


def _scale(length_unit: str) -> float:
    if length_unit not in _SCALE:
        raise InvalidParameterError(f"`length_unit` must be one of {sorted(_SCALE)}; got {length_unit!r}")
    return _SCALE[length_unit]


def to_roboticstoolbox(robot: Robot, *, length_unit: str = "m"):
    """The robot as a ``roboticstoolbox.DHRobot`` (see the module docstring for the mapping).

    Parameters
    ----------
    robot : Robot
        All joints standard DH or all modified DH; every Hayati ``beta`` zero.
    length_unit : {"m", "mm"}
        The toolbox's length unit (``a``, ``d``, base and tool translations, prismatic values).

    Returns
    -------
    roboticstoolbox.DHRobot
        ``fkine(q)`` equals ``robot.fkine(q, tool=True)`` (lengths in ``length_unit``).

    Raises
    ------
    MissingDependencyError
        roboticstoolbox-python is not installed.
    InvalidParameterError
        A non-zero ``beta`` or mixed conventions, naming the joints.
    """
    scale = _scale(length_unit)
    rtb, SE3 = _toolbox("to_roboticstoolbox")
    conventions = {j.convention for j in robot.joints}
    if len(conventions) != 1:
        raise InvalidParameterError(
            f"robot {robot.name!r} mixes conventions {[j.convention for j in robot.joints]}; a DHRobot is all DH or all MDH "
            f"(Robot.to_mdh converts an all-DH robot)"
        )
    n = robot.n_joints
    values = robot.params[: 5 * n].reshape(n, 5)  # alpha, a, d, theta, beta
    tilted = [f"joint {j + 1} (beta = {math.degrees(b):.6g} deg)" for j, b in enumerate(values[:, 4]) if b != 0.0]
    if tilted:
        raise InvalidParameterError(
            f"robot {robot.name!r}: {', '.join(tilted)}: a DHRobot has no Hayati beta, so it cannot reproduce this robot; "
            f"export it as URDF instead (robocal export --format urdf)"
        )
    mdh = conventions == {"mdh"}
    links = []
    for joint, (alpha, a, d, theta, _) in zip(robot.joints, values):
        if joint.kind == "revolute":
            cls = rtb.RevoluteMDH if mdh else rtb.RevoluteDH
            links.append(cls(alpha=alpha, a=a / scale, d=d / scale, offset=theta, qlim=list(joint.limits)))
        else:
            cls = rtb.PrismaticMDH if mdh else rtb.PrismaticDH
            links.append(cls(alpha=alpha, a=a / scale, theta=theta, offset=d / scale, qlim=[v / scale for v in joint.limits]))

    def frame(prefix: str):
        start = robot.index(f"{prefix}_x")
        p = robot.params[start : start + 6].copy()
        p[:3] /= scale
        return SE3(frame_transform(p), check=False)

    return rtb.DHRobot(links, name=robot.name, base=frame("base"), tool=frame("tool"))


def from_roboticstoolbox(dhrobot, *, length_unit: str = "m") -> Robot:
    """A :class:`Robot` from a ``roboticstoolbox.DHRobot`` (the inverse of
    :func:`to_roboticstoolbox`).

    Parameters
    ----------
    dhrobot : roboticstoolbox.DHRobot
    length_unit : {"m", "mm"}
        The DHRobot's length unit.

    Returns
    -------
    Robot
        Same tool kinematics: ``robot.fkine(q, tool=True)`` equals ``dhrobot.fkine(q)`` (mm).
        Limits from ``qlim`` (±π for a revolute joint without one); sensor parameters neutral.

    Raises
    ------
    InvalidParameterError
        Not a DHRobot, a link with a flipped joint, a prismatic joint without ``qlim``, or a
        non-finite value, naming the link.
    """
    scale = _scale(length_unit)
    links = getattr(dhrobot, "links", None)
    if links is None or not hasattr(dhrobot, "mdh") or not hasattr(dhrobot, "base"):
        raise InvalidParameterError(f"from_roboticstoolbox takes a roboticstoolbox DHRobot; got {type(dhrobot).__name__}")
    joints, values = [], []
    for j, link in enumerate(links, start=1):
        where = f"DHRobot {dhrobot.name!r}, link {j}"
        if getattr(link, "isflip", False):
            raise InvalidParameterError(f"{where}: its joint is flipped (flip=True); robocal's joints turn about +z")
        prismatic = bool(link.isprismatic)
        alpha, a = float(link.alpha), float(link.a) * scale
        d, theta = (float(link.offset) * scale, float(link.theta)) if prismatic else (float(link.d) * scale, float(link.offset))
        qlim = link.qlim
        if qlim is None:
            if prismatic:
                raise InvalidParameterError(f"{where}: a prismatic joint needs qlim (its range)")
            limits = (-math.pi, math.pi)
        else:
            limits = tuple(float(v) * (scale if prismatic else 1.0) for v in np.ravel(qlim))
        if not np.all(np.isfinite([alpha, a, d, theta])):
            raise InvalidParameterError(f"{where}: alpha, a, d, theta must be finite; got {[alpha, a, d, theta]}")
        joints.append(Joint("mdh" if link.mdh else "dh", "prismatic" if prismatic else "revolute", False, limits))
        values += [alpha, a, d, theta, 0.0]
    frames = []
    for T in (dhrobot.base, dhrobot.tool):
        p = frame_params(np.asarray(T.A if hasattr(T, "A") else T, dtype=np.float64))
        p[:3] *= scale
        frames += p.tolist()
    return Robot(dhrobot.name or "roboticstoolbox", joints, np.array(values + frames + [0.0, 0.0, 0.0, 0.0, 1.0]))
