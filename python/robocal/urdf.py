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
* the last link is the identity (``theta_N = d_N = a_N = alpha_N = 0``) and everything between
  the last joint's axis frame and the tip link, the fixed joints included, is the **tool** frame.

Each joint's variable is then the URDF joint position (rad, or mm for a prismatic joint) with
the same sign: z points along the URDF axis. Because ``Rz(q)`` about an axis through the frame
origin is the URDF joint's motion (``Tz(q)`` along it for a prismatic joint), the robot's tool
pose equals the URDF tip link's pose for every joint vector, not only at zero.

Units: URDF lengths are metres, robocal's millimetres (× 1000); angles stay radians. Joint limits
come from ``<limit>``; a ``continuous`` joint (a revolute joint without limits) gets ±π.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Optional

import numpy as np

from .exceptions import InvalidParameterError, MissingDependencyError
from .geometry import X, Y, frame_params, homogeneous, rotation
from .robot import Joint, Robot
from .robot_file import read_file

#: Consecutive joint axes closer to parallel than this (degrees) get Hayati's ``beta`` instead of ``d``.
PARALLEL_DEG = 1.0
#: URDF joint types robocal reads: the movable ones it converts and ``fixed``.
MOVABLE = {"revolute": "revolute", "continuous": "revolute", "prismatic": "prismatic"}
_M_TO_MM = 1000.0


def _parse(path: Path):
    """The yourdfpy model of ``path``, or an error naming the file."""
    text = read_file(path, "URDF file")
    try:  # the stdlib names the line and column of malformed XML; yourdfpy does not
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise InvalidParameterError(f"{path}: not well-formed XML ({exc})") from None
    if root.tag != "robot":
        raise InvalidParameterError(f"{path}: not a URDF file (root element <{root.tag}>, expected <robot>)")
    try:
        import yourdfpy
    except ImportError:
        raise MissingDependencyError(f"{path}: reading URDF needs yourdfpy, an optional dependency: pip install 'robocal[urdf]'") from None
    try:
        return yourdfpy.URDF.load(str(path), build_scene_graph=False, build_collision_scene_graph=False, load_meshes=False, load_collision_meshes=False)
    except Exception as exc:  # yourdfpy reports a missing attribute as a bare KeyError / AttributeError
        raise InvalidParameterError(f"{path}: not a valid URDF ({type(exc).__name__}: {exc})") from None


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
                f"{where}: not a serial chain: link {link!r} branches into joints {[j.name for j in children]}; name the tip link to follow one branch"
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


def robot_from_chain(chain, where: str, name: str) -> Robot:
    """A standard-DH :class:`Robot` whose tool pose is the chain's tip pose (see the module
    docstring). ``chain``: yourdfpy joints in order from the root (origins in metres)."""
    movable, T, axes = [], np.eye(4), []
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
        if joint.type == "fixed":
            continue
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
    links.append({"alpha": 0.0, "a": 0.0, "d": 0.0, "theta": 0.0, "beta": 0.0, "hayati": False})
    tool = np.linalg.solve(frame, tip)

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


def read_urdf(path, tip: Optional[str] = None, convention: str = "dh") -> Robot:
    """The robot of a URDF file.

    Parameters
    ----------
    path : str or Path
    tip : str, optional
        The link the tool frame is (default: the chain's one leaf; needed when the tree branches).
    convention : {"dh", "mdh"}
        ``mdh`` converts the DH result with :meth:`Robot.to_mdh` (the tool frame is the same).

    Returns
    -------
    Robot
        Named after the URDF's ``<robot name>``; joint values in rad (mm for prismatic joints).

    Raises
    ------
    InvalidParameterError
        Unreadable or malformed file, not a serial chain, an unsupported joint type (floating,
        planar), a mimic joint, a bad origin, axis or limit — naming the file and the joint or link.

    Examples
    --------
    >>> import robocal
    >>> r = robocal.robot("ur10.urdf")  # doctest: +SKIP
    """
    if convention not in ("dh", "mdh"):
        raise InvalidParameterError(f"`convention` must be 'dh' or 'mdh'; got {convention!r}")
    path = Path(path)
    model = _parse(path)
    chain = serial_chain(model.robot.joints, str(path), tip)
    robot = robot_from_chain(chain, str(path), model.robot.name or path.stem)
    return robot.to_mdh() if convention == "mdh" else robot
