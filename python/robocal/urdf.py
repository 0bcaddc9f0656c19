"""URDF input: a URDF's serial chain as a robocal :class:`~robocal.robot.Robot` (standard DH, or
MDH on request, with the base and tool frames).

The file is parsed by ``yourdfpy`` (a maintained URDF parser; the optional extra
``robocal[urdf]``), which gives each joint's origin as a 4×4 matrix, its axis, type and limits.
The chain from the root link to the tip is then converted into DH parameters from its joint axes
at the zero configuration (every joint at 0):

* frame 0 has z along joint 1's axis; its origin is the point of that axis nearest the root
  link's origin and its x the root's x (or y) made perpendicular: this pose is the **base** frame;
* link ``j`` goes from joint ``j``'s axis to joint ``j+1``'s along their common normal:
  ``theta_j`` turns the previous x onto the normal about z, ``d_j`` runs along z to its foot,
  ``a_j`` is its length (signed: the normal's direction is ``z_j × z_{j+1}``) and ``alpha_j``
  turns z onto the next axis about it. Intersecting axes have ``a_j = 0``;
* nearly parallel axes (within :data:`PARALLEL_DEG`) use Hayati's form instead: ``d_j = 0``, the
  normal runs in the plane perpendicular to joint ``j``'s axis through the frame origin, and
  ``beta_j`` (about y) with ``alpha_j`` turns z onto the next axis; the joint is flagged
  ``hayati`` (its ``d`` is ill-conditioned there, as for the built-in robots);
* the last link (``theta_N, d_N, a_N, alpha_N, beta_N``) takes joint ``N``'s axis frame to the
  **flange**: the link named ``flange`` among those after the last movable joint (ROS-Industrial's
  name, and what ``robocal export --format urdf`` writes), else the last movable joint's child
  link. Five link parameters cannot hold every placement of a frame (six degrees of freedom): a
  ``flange`` link they cannot hold to :data:`FLANGE_TOL_MM` / :data:`FLANGE_TOL_RAD` is passed
  over for the joint's child link, which they always hold (its origin lies on the axis);
* everything from the flange to the tip link, the fixed joints included, is the **tool** frame.
  The tip is by default the end of the chain, so a file that ends in fixed ``flange`` and
  ``tool0`` links reads with ``fkine(q)`` at ``flange`` and ``fkine(q, tool=True)`` at ``tool0``.

Each joint's variable is then the URDF joint position (rad, or mm for a prismatic joint) with
the same sign: z points along the URDF axis. Because ``Rz(q)`` about an axis through the frame
origin is the URDF joint's motion (``Tz(q)`` along it for a prismatic joint), the robot's tool
pose equals the URDF tip link's pose, and its flange pose the flange link's, for every joint
vector, not only at zero.

Units: URDF lengths are metres, robocal's millimetres (× 1000); angles stay radians. Joint limits
come from ``<limit>``; a ``continuous`` joint (a revolute joint without limits) gets ±π.
"""

from __future__ import annotations

import io
import logging
import math
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Optional

import numpy as np

from .exceptions import InvalidParameterError, MissingDependencyError
from .geometry import X, Y, Z, frame_params, homogeneous, rotation
from .robot_file import read_file
from .serial_robot import Joint, Robot

#: Consecutive joint axes closer to parallel than this (degrees) get Hayati's ``beta`` instead of ``d``.
PARALLEL_DEG = 1.0
#: URDF joint types robocal reads: the movable ones it converts and ``fixed``.
MOVABLE = {"revolute": "revolute", "continuous": "revolute", "prismatic": "prismatic"}
#: The link read as the robot's flange when the chain passes through it after the last movable joint.
FLANGE_LINK = "flange"
#: How closely (mm, rad) the last link must hold a ``flange`` link's frame for it to be the flange.
FLANGE_TOL_MM, FLANGE_TOL_RAD = 1e-10, 1e-12
_M_TO_MM = 1000.0

logger = logging.getLogger(__name__)


def require_yourdfpy(purpose: str):
    """The ``yourdfpy`` module, or a :class:`MissingDependencyError` saying that ``purpose`` needs it."""
    try:
        import yourdfpy
    except ImportError:
        raise MissingDependencyError(f"{purpose} needs yourdfpy, an optional dependency: pip install 'robocal[urdf]'") from None
    return yourdfpy


def _parse(text: str, where: str):
    """The yourdfpy model of the URDF document ``text``, or an error naming ``where``."""
    try:  # the stdlib names the line and column of malformed XML; yourdfpy does not
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise InvalidParameterError(f"{where}: not well-formed XML ({exc})") from None
    if root.tag != "robot":
        raise InvalidParameterError(f"{where}: not a URDF file (root element <{root.tag}>, expected <robot>)")
    yourdfpy = require_yourdfpy(f"{where}: reading URDF")
    try:
        return yourdfpy.URDF.load(
            io.BytesIO(text.encode("utf-8")), build_scene_graph=False, build_collision_scene_graph=False, load_meshes=False, load_collision_meshes=False
        )
    except Exception as exc:  # yourdfpy reports a missing attribute as a bare KeyError / AttributeError
        raise InvalidParameterError(f"{where}: not a valid URDF ({type(exc).__name__}: {exc})") from None


def serial_chain(joints, where: str, tip: Optional[str] = None) -> list:
    """The joints from the root link to ``tip`` (default: the one leaf), in order.

    Parameters
    ----------
    joints : sequence
        Objects with ``name``, ``parent`` and ``child`` (link names), as yourdfpy's.
    where : str
        The file, for the messages.
    tip : str, optional
        The chain's last link; needed when the tree branches.

    Raises
    ------
    InvalidParameterError
        No joint, a link that is the child of two joints, several root links, a branch (without
        ``tip``) or an unknown ``tip``; naming the link and joints.
    """
    if not joints:
        raise InvalidParameterError(f"{where}: the URDF has no joint")
    by_child, by_parent = {}, {}
    for joint in joints:
        if joint.child in by_child:
            raise InvalidParameterError(f"{where}: link {joint.child!r} is the child of two joints ({by_child[joint.child].name!r}, {joint.name!r})")
        by_child[joint.child] = joint
        by_parent.setdefault(joint.parent, []).append(joint)
    roots = sorted({j.parent for j in joints} - set(by_child))
    if len(roots) != 1:
        raise InvalidParameterError(f"{where}: a serial chain has one root link; got {roots or 'none (the joints form a loop)'}")
    if tip is not None:
        if tip not in by_child:
            raise InvalidParameterError(f"{where}: no joint leads to the tip link {tip!r}")
        chain, link = [], tip
        while link in by_child:
            chain.append(by_child[link])
            link = by_child[link].parent
        return chain[::-1]
    chain, link = [], roots[0]
    while link in by_parent:
        children = by_parent[link]
        if len(children) > 1:
            raise InvalidParameterError(
                f"{where}: not a serial chain: link {link!r} branches into joints {[j.name for j in children]}; name the tip link "
                f"to follow one branch (one of {sorted(set(by_child) - set(by_parent))}): robocal.urdf.read_urdf(path, tip=...), "
                "and robocal.write_robot(that, 'arm.json') for the command line"
            )
        chain.append(children[0])
        link = children[0].child
    return chain


def _common_normal(O, x, z, p, u) -> tuple[dict, np.ndarray]:
    """Link parameters from the frame ``(O, x, z)`` on joint ``j``'s axis to the line ``p + t·u``
    (joint ``j+1``'s axis), and the frame they give (4×4, z along ``u``, origin on the line).

    Standard DH through the common normal; Hayati's ``d = 0``, ``beta`` form for nearly parallel
    axes (``hayati`` True in the returned dict).
    """
    n = np.cross(z, u)
    sin_angle = np.linalg.norm(n)
    hayati = sin_angle < math.sin(math.radians(PARALLEL_DEG))
    if not hayati:
        x_new = n / sin_angle
        a = float((p - O) @ x_new)  # the distance between the lines, along their normal
        if a < 0.0:
            x_new, a = -x_new, -a
        d = float(np.cross(p - O, u) @ n / sin_angle**2)  # foot of the normal on joint j's axis
    else:
        t = float((O - p) @ z / (u @ z))  # where joint j+1's axis crosses the plane through O perpendicular to z
        v = p + t * u - O
        v = v - (v @ z) * z
        a, d = float(np.linalg.norm(v)), 0.0
        x_new = v / a if a > 0.0 else x
    theta = math.atan2(float(np.cross(x, x_new) @ z), float(x @ x_new))
    R = np.column_stack([x_new, np.cross(z, x_new), z])  # after Rz(theta) Tz(d) Tx(a)
    ul = R.T @ u  # the next axis there: Rx(alpha) Ry(beta) e_z = (sin b, -sin a cos b, cos a cos b)
    alpha = math.atan2(-ul[1], ul[2])
    beta = math.atan2(ul[0], math.hypot(ul[1], ul[2])) if hayati else 0.0
    frame = homogeneous(R @ rotation(X, alpha) @ rotation(Y, beta), O + d * z + a * x_new)
    return {"alpha": alpha, "a": a, "d": d, "theta": theta, "beta": beta, "hayati": bool(hayati)}, frame


def _dh_link(link: dict) -> np.ndarray:
    """``Rz(theta)·Tz(d)·Tx(a)·Rx(alpha)·Ry(beta)`` (4×4): a standard-DH link at its joint's zero."""
    Rz = rotation(Z, link["theta"])
    return homogeneous(Rz @ rotation(X, link["alpha"]) @ rotation(Y, link["beta"]), Rz @ np.array([link["a"], 0.0, link["d"]]))


def _last_link(F: np.ndarray) -> tuple[dict, float, float]:
    """The last link's parameters that come closest to ``F`` (4×4, mm): joint ``N``'s axis frame
    to the flange at the joint's zero; and how far the transform they give is from ``F`` (mm, rad).

    ``Rz(theta)·Rx(alpha)·Ry(beta)`` has no x component of y, so ``theta`` must turn F's y axis
    into the y-z plane; when that axis lies along z (``alpha`` = ±90°) ``theta`` is free, and the
    direction of F's origin off the z axis gives it instead (``a`` its distance from the axis).
    """
    R, t = F[:3, :3], F[:3, 3]
    best = None
    for theta in (math.atan2(-R[0, 1], R[1, 1]), math.atan2(t[1], t[0])):
        M = rotation(Z, -theta) @ R
        link = {
            "alpha": math.atan2(M[2, 1], M[1, 1]),
            "a": float(t[0] * math.cos(theta) + t[1] * math.sin(theta)),
            "d": float(t[2]),
            "theta": theta,
            "beta": math.atan2(M[0, 2], M[0, 0]),
            "hayati": False,
        }
        G = _dh_link(link)
        mm, rad = float(np.abs(G[:3, 3] - t).max()), float(np.abs(G[:3, :3] - R).max())
        if best is None or max(mm / FLANGE_TOL_MM, rad / FLANGE_TOL_RAD) < max(best[1] / FLANGE_TOL_MM, best[2] / FLANGE_TOL_RAD):
            best = (link, mm, rad)
    return best


def robot_from_chain(chain, where: str, name: str) -> Robot:
    """A standard-DH :class:`Robot` whose tool pose is the chain's tip pose and whose flange pose
    is its flange link's (see the module docstring). ``chain``: yourdfpy joints in order from the
    root (origins in metres)."""
    movable, T, axes, after = [], np.eye(4), [], []
    for joint in chain:
        if joint.type not in MOVABLE and joint.type != "fixed":
            raise InvalidParameterError(
                f"{where}: joint {joint.name!r} has type {joint.type!r}; robocal reads revolute, continuous, prismatic and fixed joints"
            )
        if getattr(joint, "mimic", None) is not None:
            raise InvalidParameterError(f"{where}: joint {joint.name!r} mimics joint {joint.mimic.joint!r}; robocal needs independent joints")
        origin = np.eye(4) if joint.origin is None else np.array(joint.origin, dtype=np.float64)
        if origin.shape != (4, 4) or not np.all(np.isfinite(origin)):
            raise InvalidParameterError(f"{where}: joint {joint.name!r}: its <origin> must be finite xyz and rpy; got {origin.tolist()}")
        T = T @ homogeneous(origin[:3, :3], origin[:3, 3] * _M_TO_MM)
        after.append((joint.child, T))  # the links after the last movable joint: where the flange may be
        if joint.type == "fixed":
            continue
        after = after[-1:]
        axis = np.array([1.0, 0.0, 0.0] if joint.axis is None else joint.axis, dtype=np.float64)
        norm = np.linalg.norm(axis) if axis.shape == (3,) and np.all(np.isfinite(axis)) else 0.0
        if not norm > 0.0:
            raise InvalidParameterError(f"{where}: joint {joint.name!r}: its <axis> must be a non-zero finite 3-vector; got {np.asarray(joint.axis).tolist()}")
        movable.append(joint)
        axes.append((T[:3, 3].copy(), T[:3, :3] @ (axis / norm)))
    if not movable:
        raise InvalidParameterError(f"{where}: the chain {[j.name for j in chain]} has no movable joint")
    tip = T  # the tip link at the zero configuration

    # Frame 0: on joint 1's axis, nearest the root origin; x the root's x (y if that is the axis) made perpendicular.
    p1, z = axes[0]
    O = p1 - (p1 @ z) * z
    x = np.eye(3)[0] if abs(z[0]) < 0.9 else np.eye(3)[1]
    x = x - (x @ z) * z
    x /= np.linalg.norm(x)
    base = homogeneous(np.column_stack([x, np.cross(z, x), z]), O)
    frame, links = base, []
    for p, u in axes[1:]:
        link, frame = _common_normal(frame[:3, 3], frame[:3, 0], frame[:3, 2], p, u)
        links.append(link)
    flange = next((pose for child, pose in after if child == FLANGE_LINK), None)
    if flange is not None:
        link, mm, rad = _last_link(np.linalg.solve(frame, flange))
        if not (mm <= FLANGE_TOL_MM and rad <= FLANGE_TOL_RAD):
            logger.info("%s: the last link cannot hold link %r (off by %.3g mm, %.3g rad): the flange is link %r", where, FLANGE_LINK, mm, rad, after[0][0])
            flange = None
    if flange is None:
        link, _, _ = _last_link(np.linalg.solve(frame, after[0][1]))  # the joint's child: its origin is on the axis
    links.append(link)
    tool = np.linalg.solve(frame @ _dh_link(link), tip)

    joints, values = [], []
    for joint, link in zip(movable, links):
        kind = MOVABLE[joint.type]
        limit = joint.limit
        lower, upper = (None, None) if limit is None else (limit.lower, limit.upper)
        if joint.type == "continuous" or lower is None or upper is None:
            lower, upper = -math.pi, math.pi
        scale = _M_TO_MM if kind == "prismatic" else 1.0
        limits = (float(lower) * scale, float(upper) * scale)
        if not (math.isfinite(limits[0]) and math.isfinite(limits[1]) and limits[0] < limits[1]):
            raise InvalidParameterError(f"{where}: joint {joint.name!r}: its <limit> must have finite lower < upper; got lower={lower}, upper={upper}")
        joints.append(Joint("dh", kind, link["hayati"], limits))
        values += [link["alpha"], link["a"], link["d"], link["theta"], link["beta"]]
    values += frame_params(base).tolist() + frame_params(tool).tolist() + [0.0, 0.0, 0.0, 0.0, 1.0]  # anchor, cable_offset, cable_scale
    return Robot(name, joints, np.array(values))


def robot_from_urdf(text: str, *, where: str = "URDF", tip: Optional[str] = None, convention: str = "dh") -> Robot:
    """The robot of a URDF document.

    Parameters
    ----------
    text : str
        The URDF (XML).
    where : str
        Names the document in messages, and the robot when the URDF's ``<robot>`` has no name.
    tip : str, optional
        The link the tool frame is. By default the end of the chain: its one leaf, past any fixed
        joints after the last movable one (a ``tool0`` after ``flange``). Needed when the tree
        branches.
    convention : {"dh", "mdh"}
        ``mdh`` converts the DH result with :meth:`Robot.to_mdh` (the tool frame is the same;
        the flange frame moves, as that method says).

    Returns
    -------
    Robot
        Named after the URDF's ``<robot name>``; joint values in rad (mm for prismatic joints);
        ``fkine(q)`` is the flange link's pose, ``fkine(q, tool=True)`` the tip's (module
        docstring).

    Raises
    ------
    InvalidParameterError
        Malformed document, not a serial chain, an unsupported joint type (floating, planar), a
        mimic joint, a bad origin, axis or limit — naming ``where`` and the joint or link.
    MissingDependencyError
        yourdfpy is not installed.
    """
    if convention not in ("dh", "mdh"):
        raise InvalidParameterError(f"`convention` must be 'dh' or 'mdh'; got {convention!r}")
    model = _parse(text, where)
    chain = serial_chain(model.robot.joints, where, tip)
    robot = robot_from_chain(chain, where, model.robot.name or Path(where).stem)
    return robot.to_mdh() if convention == "mdh" else robot


def read_urdf(path, tip: Optional[str] = None, convention: str = "dh") -> Robot:
    """The robot of a URDF file: :func:`robot_from_urdf` of its text (``tip`` and ``convention``
    as there; errors name the file).

    Examples
    --------
    >>> import robocal
    >>> r = robocal.robot("ur10.urdf")  # doctest: +SKIP
    """
    path = Path(path)
    return robot_from_urdf(read_file(path, "URDF file"), where=str(path), tip=tip, convention=convention)
