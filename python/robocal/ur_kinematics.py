"""Universal Robots' kinematics parameter file (``robocal export --format ur-yaml``).

``ur_description`` (ROS 2: ``config/<type>/default_kinematics.yaml``, the ``kinematics_params_file``
of ``ur_robot_driver``'s launch files; ROS 1 the same form) builds a UR arm's joint origins from
one YAML file, which ``ur_calibration`` otherwise extracts from the controller::

    kinematics:
      shoulder:  {x: ..., y: ..., z: ..., roll: ..., pitch: ..., yaw: ...}   # m, rad
      upper_arm: ...
      forearm:   ...
      wrist_1:   ...
      wrist_2:   ...
      wrist_3:   ...
      hash: calib_...

Each entry is the ``<origin xyz rpy>`` (``R = Rz(yaw)·Ry(pitch)·Rx(roll)``) of one joint in
``urdf/ur_macro.xacro``: ``shoulder`` of ``shoulder_pan_joint`` … ``wrist_3`` of ``wrist_3_joint``,
every joint turning about its local z. Around them the macro puts fixed frames:
``base_link → base_link_inertia`` is ``Rz(pi)`` (``base_link_inertia``, like the ``base`` frame, is
the controller's base frame, which the shoulder origin starts from), and ``wrist_3_link → flange →
tool0`` are rpy ``(0, -pi/2, -pi/2)`` then ``(pi/2, 0, pi/2)``, together the identity:
``tool0`` is ``wrist_3_link``. So::

    base_link → tool0 = Rz(pi) · Π_j (origin_j · Rz(q_j))

How robocal's calibrated chain becomes that file
------------------------------------------------
* robocal's ``base_*`` parameters place the robot in the measurement frame (tracker → robot
  base): they are the set-up, not the robot, and are left out. The robot's own base frame — the
  frame of its nominal DH table — is UR's ``base_link_inertia``. What a calibration could not
  tell apart from the set-up (typically ``d1`` and ``theta1``, fixed and left to ``base_z`` /
  ``base_rz``) stays at its nominal value.
* Joint ``j``'s origin is the constant transform between the joint variables ``q_{j-1}`` and
  ``q_j`` (:func:`robocal.export.urdf_segments`, ``theta_j`` included), with each joint's
  translation along its own axis (``d_j``, which robocal's chain applies after ``Rz(q_j)``)
  moved before the variable: ``Tz(d)`` commutes with ``Rz(q)``. That is the form of UR's own
  files (``wrist_1 = Tx(a3)·Tz(d4)``), so the nominal UR10 writes UR's published numbers.
* What follows ``q_6`` is robocal's flange then its tool. The flange's translation along the
  wrist_3 axis goes into ``wrist_3``'s origin (it commutes with ``Rz(q_6)``), so ``tool0`` is
  robocal's flange frame whenever the last link has no ``a_6``/``alpha_6``/``beta_6``. The rest
  (those and robocal's tool frame) cannot be written into the file: ``tool0`` is fixed on
  ``wrist_3_link``. It is the **TCP**, ``tool0 → calibrated tool``, which the user sets on the
  teach pendant (Installation → TCP: x, y, z in mm and the rotation vector rx, ry, rz in rad).
  The file carries it as the extra top-level key ``robocal_tcp`` (``x y z roll pitch yaw``, m
  and rad), which ``ur_description`` does not read, and ``robocal export`` prints it.
* UR's driver reports the controller's joint readings, which go into this chain as they are. A
  result whose calibration found a reading convention (the result's ``structure``,
  :mod:`robocal.causes.structure`) is written so that the file works at the readings
  (:func:`robocal.export.deliverable`): a ``joint_zero`` offset (model angle = reading +
  offset) ends up as ``Rz(offset)`` at the end of that joint's origin. ``joint_sign`` and
  ``joint_reference`` are refused: a UR joint's reading turns the way its model angle turns
  and depends on no other joint.
* ``hash`` is ``calib_robocal_`` and 16 hex digits of the SHA-256 of the values. The driver
  compares it with the hash of the controller's own factory calibration and, when they differ —
  as they always do for this file — logs an error at start-up ("The calibration parameters of
  the connected robot don't match …") and runs on: the message is expected, it says the file
  is not the controller's factory calibration.

Only a chain of six revolute joints can be written. The numbers are Python's shortest
round-trip representation in metres, written so that YAML 1.1 readers (PyYAML, hence xacro's
``load_yaml``) read them as floats.

Reading back: :func:`read_ur_kinematics` reads such a file (or one of UR's, which has no
``robocal_tcp``) and :func:`robot_from_ur_kinematics` builds the chain above — ``base_link``,
``Rz(pi)``, the six origins, ``flange``, ``tool0`` and the TCP — as a :class:`~robocal.Robot`
with robocal's URDF chain reader (:func:`robocal.urdf.robot_from_chain`): its
``fkine(q, tool=True)`` is the calibrated tool in ``base_link`` at the controller's readings
``q``. ``robocal export`` checks what it wrote this way against :func:`ur_reference`.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from .exceptions import InvalidParameterError
from .geometry import frame_params, frame_transform, so3_log
from .outputs import printable
from .robot_file import parse_document, read_file
from .serial_robot import Robot
from .urdf import robot_from_chain

#: The joint origins of ``kinematics:``, from the base out (ur_macro.xacro's joints in order).
SEGMENTS = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")
#: ur_macro.xacro's joint of each entry.
JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint")
#: The values of one entry: position (m), then roll, pitch, yaw (rad) about fixed x, y, z.
KEYS = ("x", "y", "z", "roll", "pitch", "yaw")
#: The top-level key of the TCP (tool0 → calibrated tool) robocal adds; ur_description ignores it.
TCP_KEY = "robocal_tcp"
HASH_PREFIX = "calib_robocal_"

_M_TO_MM = 1000.0


def _rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    return frame_transform([0.0, 0.0, 0.0, roll, pitch, yaw])


#: ur_macro.xacro's fixed frames (rpy as written there): ``base_link → base_link_inertia``, and
#: ``wrist_3_link → flange → tool0``.
BASE_LINK_TO_BASE = _rpy(0.0, 0.0, math.pi)
WRIST_3_TO_FLANGE = _rpy(0.0, -math.pi / 2.0, -math.pi / 2.0)
FLANGE_TO_TOOL0 = _rpy(math.pi / 2.0, 0.0, math.pi / 2.0)


@dataclass(frozen=True)
class URKinematics:
    """The content of a UR kinematics file, in mm and rad.

    Attributes
    ----------
    origins : tuple of ndarray, shape (4, 4)
        The six joint origins, :data:`SEGMENTS` in order.
    tcp : ndarray, shape (4, 4)
        ``tool0 → calibrated tool`` (the identity for a file without ``robocal_tcp``).
    hash : str
    """

    origins: tuple
    tcp: np.ndarray
    hash: str

    def tcp_pendant(self) -> tuple[np.ndarray, np.ndarray]:
        """The TCP as the teach pendant takes it: position (mm) and rotation vector (rad)."""
        return self.tcp[:3, 3].copy(), so3_log(self.tcp[:3, :3])


def _tz(z: float) -> np.ndarray:
    T = np.eye(4)
    T[2, 3] = z
    return T


def ur_kinematics(robot: Robot, segments) -> URKinematics:
    """The UR kinematics file of a calibrated robot (see the module docstring for the mapping).

    Parameters
    ----------
    robot : Robot
        Six revolute joints, whose joint variables are the controller's readings (a result's
        reading conventions folded in: :func:`robocal.export.deliverable`).
    segments : tuple
        ``robocal.export.urdf_segments(robot)``: ``(base, origins, flange, tool)``, the chain
        regrouped around its joint variables.

    Returns
    -------
    URKinematics

    Raises
    ------
    InvalidParameterError
        Not six revolute joints.
    """
    kinds = [j.kind for j in robot.joints]
    if kinds != ["revolute"] * len(SEGMENTS):
        raise InvalidParameterError(
            f"--format ur-yaml writes a Universal Robots arm: 6 revolute joints; robot {robot.name!r} has {len(kinds)} joints ({', '.join(kinds)})"
        )
    _, origins, flange, tool = segments
    # Each joint's own translation along its axis (the z of what follows its variable) moves
    # before the variable, as UR's files have it; Tz(c)·Rz(q) = Rz(q)·Tz(c).
    after = list(origins[1:]) + [flange]
    along = [float(T[2, 3]) for T in after]
    before = [0.0] + along[:-1]
    ur_origins = tuple(_tz(-b) @ T @ _tz(c) for T, b, c in zip(origins, before, along))
    tcp = np.linalg.solve(WRIST_3_TO_FLANGE @ FLANGE_TO_TOOL0, _tz(-along[-1]) @ flange @ tool)
    return URKinematics(ur_origins, tcp, HASH_PREFIX + hashlib.sha256(_values_text(ur_origins).encode()).hexdigest()[:16])


def ur_reference(robot: Robot) -> Robot:
    """The calibrated robot as the exported file must reproduce it: in ``base_link`` (the base
    frame is ``Rz(pi)``, the measurement set-up left out). What :func:`robot_from_ur_kinematics`
    of the written file is checked against."""
    return robot.with_params(**{f"base_{k}": float(v) for k, v in zip(("x", "y", "z", "rx", "ry", "rz"), frame_params(BASE_LINK_TO_BASE))})


def yaml_float(value: float) -> str:
    """``repr(value)``, written so that YAML 1.1 (PyYAML) reads a float: it needs a ``.`` in an
    exponent's mantissa (``1e-05`` would be read as a string)."""
    text = repr(float(value))
    mantissa, e, exponent = text.partition("e")
    return f"{mantissa}.0e{exponent}" if e and "." not in mantissa else text


def _entry_lines(key: str, T: np.ndarray, indent: str) -> list[str]:
    values = frame_params(T)
    values[:3] /= _M_TO_MM
    return [f"{indent}{key}:"] + [f"{indent}  {k}: {yaml_float(v)}" for k, v in zip(KEYS, values)]


def _values_text(origins) -> str:
    return "\n".join(line for name, T in zip(SEGMENTS, origins) for line in _entry_lines(name, T, "  "))


def ur_yaml_text(kinematics: URKinematics, robot_name: str = "") -> str:
    """The YAML document of ``kinematics`` (comments say what wrote it and what the TCP is)."""
    position, rotvec = kinematics.tcp_pendant()
    lines = [
        "# Universal Robots kinematics parameters (ur_description's kinematics_params_file), written by robocal export"
        + (f" for robot {printable(robot_name, one_line=True)}" if robot_name else "")  # one line: a newline would end the comment
        + ":",
        "# the calibrated joint origins, m and rad. Joint positions are the controller's readings. The hash is not the controller's:",
        "# ur_robot_driver logs at start-up that the calibration does not match the robot's and runs on.",
        "# robocal_tcp (ignored by ur_description): tool0 -> the calibrated tool, to set as the TCP on the teach pendant:",
        f"#   x y z = {_digits(position, 6)} mm, rotation vector rx ry rz = {_digits(rotvec, 9)} rad",
        "kinematics:",
        _values_text(kinematics.origins),
        f"  hash: {kinematics.hash}",
        *_entry_lines(TCP_KEY, kinematics.tcp, ""),
    ]
    return "\n".join(lines) + "\n"


def is_ur_yaml(text: str) -> bool:
    """Whether ``text`` looks like a UR kinematics file (a top-level ``kinematics:`` line)."""
    return any(line.rstrip() == "kinematics:" for line in text.splitlines())


def _number(value, where: str, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InvalidParameterError(f"{where}: {key} must be a finite number; got {value!r}")
    return float(value)


def _entry(section, where: str, key: str) -> np.ndarray:
    if not isinstance(section, dict):
        raise InvalidParameterError(f"{where}: {key} must be a mapping of {', '.join(KEYS)}; got {section!r}")
    unknown = sorted(set(map(str, section)) - set(KEYS))
    missing = [k for k in KEYS if k not in section]
    if unknown or missing:
        raise InvalidParameterError(f"{where}: {key} must have exactly the keys {', '.join(KEYS)}; missing {missing}, unknown {unknown}")
    values = np.array([_number(section[k], where, f"{key}.{k}") for k in KEYS])
    values[:3] *= _M_TO_MM
    return frame_transform(values)


def ur_kinematics_from_text(text: str, where: str = "UR kinematics file") -> URKinematics:
    """:func:`read_ur_kinematics` of a document given as a string (``where`` names it)."""
    doc = parse_document(text, where, "UR kinematics file", yaml_text=True)
    if not isinstance(doc, dict) or not isinstance(doc.get("kinematics"), dict):
        raise InvalidParameterError(f"{where}: not a UR kinematics file: expected a top-level mapping 'kinematics'")
    unknown = sorted(set(map(str, doc)) - {"kinematics", TCP_KEY})
    if unknown:
        raise InvalidParameterError(f"{where}: unknown top-level keys {unknown}; a UR kinematics file has 'kinematics' (and robocal's '{TCP_KEY}')")
    section = doc["kinematics"]
    unknown = sorted(set(map(str, section)) - set(SEGMENTS) - {"hash"})
    missing = [k for k in (*SEGMENTS, "hash") if k not in section]
    if unknown or missing:
        raise InvalidParameterError(f"{where}: kinematics must have {', '.join(SEGMENTS)} and hash; missing {missing}, unknown {unknown}")
    if not isinstance(section["hash"], str):
        raise InvalidParameterError(f"{where}: kinematics.hash must be a string; got {section['hash']!r}")
    origins = tuple(_entry(section[name], where, f"kinematics.{name}") for name in SEGMENTS)
    tcp = _entry(doc[TCP_KEY], where, TCP_KEY) if TCP_KEY in doc else np.eye(4)
    return URKinematics(origins, tcp, section["hash"])


def read_ur_kinematics(path) -> URKinematics:
    """The content of a UR kinematics file (robocal's or UR's own).

    Raises
    ------
    InvalidParameterError
        Unreadable, not YAML, a missing or unknown key, a value that is not a finite number —
        naming the file and the key (``kinematics.wrist_2.roll``).
    """
    path = Path(path)
    return ur_kinematics_from_text(read_file(path, "UR kinematics file"), where=str(path))


def _fixed(name: str, child: str, origin: np.ndarray) -> SimpleNamespace:
    return SimpleNamespace(name=name, type="fixed", child=child, origin=origin, axis=None, limit=None, mimic=None)


def robot_from_ur_kinematics(kinematics: URKinematics, name: str = "ur") -> Robot:
    """The chain ``base_link → tool0 → TCP`` of ur_macro.xacro with these origins, as a robot.

    Its ``fkine(q, tool=True)`` is the calibrated tool in ``base_link`` at the controller's
    readings ``q`` (rad); joint limits are ±pi (the file has none).
    """

    def metres(T: np.ndarray) -> np.ndarray:
        T = T.copy()
        T[:3, 3] /= _M_TO_MM
        return T

    chain = [_fixed("base_link-base_link_inertia", "base_link_inertia", BASE_LINK_TO_BASE)]
    for joint, segment, origin in zip(JOINTS, SEGMENTS, kinematics.origins):
        chain.append(
            SimpleNamespace(name=joint, type="continuous", child=f"{segment}_link", origin=metres(origin), axis=[0.0, 0.0, 1.0], limit=None, mimic=None)
        )
    chain += [
        _fixed("wrist_3-flange", "flange", WRIST_3_TO_FLANGE),
        _fixed("flange-tool0", "tool0", FLANGE_TO_TOOL0),
        _fixed("tool0-tcp", "tcp", metres(kinematics.tcp)),
    ]
    return robot_from_chain(chain, "UR kinematics", name)


def read_ur_yaml(path) -> Robot:
    """:func:`robot_from_ur_kinematics` of the file at ``path`` (named after it)."""
    path = Path(path)
    return robot_from_ur_kinematics(read_ur_kinematics(path), name=path.stem)


def _digits(values, digits: int) -> str:
    """``values`` to ``digits`` decimals; a rounding residue (UR's fixed frames compose to the
    identity to 1e-16) prints as 0, not -0."""
    return " ".join(f"{round(float(v), digits) + 0.0:.{digits}f}" for v in values)


def tcp_message(kinematics: URKinematics) -> str:
    """One line saying which TCP to set on the pendant for the file's tool frame."""
    position, rotvec = kinematics.tcp_pendant()
    return (
        f"set the TCP on the teach pendant to x y z = {_digits(position, 4)} mm, rx ry rz = {_digits(rotvec, 6)} rad "
        "(tool0 -> the calibrated tool: what UR's kinematics file cannot hold)"
    )
