"""Structural causes: how the controller reports its joints.

A geometric model fitted to joint readings in another convention than its own does not fit
slightly worse — it runs to implausible parameters (tens of degrees, metres) or does not fit at
all. Three conventions are common, each a transformation of the readings ``q`` into the angles
the model needs:

``joint_zero``
    ``q_j + offset``: the DH θ offset already included in the reading, or not (a multiple of
    90°), or a joint re-mastered after a crash or a motor change (any offset).
``joint_sign``
    ``−q_j``: the joint counts the other way.
``joint_reference``
    ``q_j + c·q_s`` with ``c = ±1``: joint ``j`` read relative to joint ``s`` (the J2/J3
    "interaction" of parallelogram arms and many controllers).

This module says what a convention is and how it applies; the search for the conventions a data
set was read in is the diagnosis': :mod:`robocal.diagnosis.conventions`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Optional

import numpy as np

from ..data.dataset import Dataset
from ..exceptions import InvalidParameterError
from ..geometry import frame_params, frame_transform, rotation
from ..physics import DEG
from ..serial_robot import Robot

#: The kinds of reading convention.
KINDS = ("joint_zero", "joint_sign", "joint_reference")


@dataclass(frozen=True)
class Structure:
    """One hypothesis on the joint readings: ``kind``, 0-based ``joint``, ``value`` (offset in
    rad, or the coefficient of ``source``)."""

    kind: str
    joint: int
    value: float = 0.0
    source: Optional[int] = None

    def apply(self, q: np.ndarray) -> np.ndarray:
        """The model's angles from readings ``q`` (m, N)."""
        out = np.array(q, dtype=np.float64, copy=True)
        if self.kind == "joint_zero":
            out[:, self.joint] += self.value
        elif self.kind == "joint_sign":
            out[:, self.joint] *= -1.0
        else:
            out[:, self.joint] += self.value * q[:, self.source]
        return out

    def invert(self, q: np.ndarray) -> np.ndarray:
        """The readings from the model's angles ``q`` (m, N): what the controller reports."""
        out = np.array(q, dtype=np.float64, copy=True)
        if self.kind == "joint_zero":
            out[:, self.joint] -= self.value
        elif self.kind == "joint_sign":
            out[:, self.joint] *= -1.0
        else:
            out[:, self.joint] -= self.value * q[:, self.source]
        return out

    @property
    def label(self) -> str:
        if self.kind == "joint_zero":
            return f"joint_zero joint {self.joint + 1} offset={self.value / DEG:.6g}"
        if self.kind == "joint_sign":
            return f"joint_sign joint {self.joint + 1}"
        return f"joint_reference joint {self.joint + 1} source={self.source + 1} coefficient={self.value:+g}"

    @property
    def params(self) -> dict:
        def q(value, unit):
            return {"value": float(value), "std": None, "unit": unit}

        if self.kind == "joint_zero":
            return {"offset": q(self.value / DEG, "deg")}
        if self.kind == "joint_sign":
            return {"sign": q(-1.0, "1")}
        return {"coefficient": q(self.value, "1"), "source": q(self.source + 1, "joint")}

    @property
    def quarter_turn(self) -> bool:
        """A convention of whole quarter turns (a DH table's offsets, a counting direction), as
        against a joint re-mastered at some angle."""
        return self.kind != "joint_zero" or abs(self.value / DEG / 90.0 - round(self.value / DEG / 90.0)) < 1e-9

    def size(self) -> float:
        """How large a change to the readings it is (for preferring the smaller)."""
        return abs(self.value) if self.kind == "joint_zero" else (np.pi if self.kind == "joint_sign" else 2.0 * np.pi)


def parse(label: str, n_joints: int) -> Optional[Structure]:
    """The :class:`Structure` of a report label, or None if ``label`` is not structural."""
    parts = label.split()
    if len(parts) < 3 or parts[0] not in ("joint_zero", "joint_sign", "joint_reference") or parts[1] != "joint":
        return None
    try:
        joint = int(parts[2]) - 1
        keys = dict(p.split("=", 1) for p in parts[3:])
        if parts[0] == "joint_zero":
            s = Structure("joint_zero", joint, float(keys["offset"]) * DEG)
        elif parts[0] == "joint_sign":
            s = Structure("joint_sign", joint)
        else:
            s = Structure("joint_reference", joint, float(keys["coefficient"]), int(keys["source"]) - 1)
    except (ValueError, KeyError):
        return None
    if not 0 <= s.joint < n_joints or (s.source is not None and not 0 <= s.source < n_joints):
        return None
    return s


def parse_all(labels: list[str], n_joints: int) -> list[Structure]:
    """The :class:`Structure` of every label of a result's ``structure``, or an error naming the
    unreadable ones."""
    parsed = [parse(label, n_joints) for label in labels]
    bad = [label for label, s in zip(labels, parsed) if s is None]
    if bad:
        raise InvalidParameterError(f"result: unreadable reading conventions {bad}")
    return parsed


def to_readings(q: np.ndarray, structures: list[Structure]) -> np.ndarray:
    """Model angles ``q`` back to the controller's readings: ``structures`` undone in reverse
    order (the inverse of :func:`apply_all` on the joints)."""
    for s in reversed(structures):
        q = s.invert(q)
    return q


def to_model(q: np.ndarray, structures: list[Structure]) -> np.ndarray:
    """The controller's readings ``q`` as the model's angles (``structures`` in order)."""
    for s in structures:
        q = s.apply(q)
    return q


def within_limits(structures: list[Structure], q: np.ndarray, robot: Robot) -> list[Structure]:
    """``structures`` with each revolute joint's zero offset taken the whole turns over that put the most model
    angles of the readings ``q`` (m, N) within the robot's joint limits (then the smallest offset). The kinematics
    see an offset only modulo a turn, the limits do not: a UR10 joint read 90° over its angle, given as an offset of
    270°, put every model angle of its data beyond the ±360° limits — the monitor refused every sample, and the
    exported URDF's limits left out every reading."""
    out: list[Structure] = []
    for s in structures:
        if s.kind == "joint_zero" and robot.joints[s.joint].kind == "revolute":
            lower, upper = robot.joints[s.joint].limits
            before = to_model(q, out)[:, s.joint]
            turns = np.arange(-3, 4)
            offsets = s.value + 2.0 * np.pi * turns
            inside = [int(np.count_nonzero((before + o >= lower) & (before + o <= upper))) for o in offsets]
            best = min(range(len(turns)), key=lambda k: (-inside[k], round(abs(offsets[k]), 9), abs(turns[k])))  # ties: as given
            s = replace(s, value=float(offsets[best]))
        out.append(s)
    return out


def apply_all(data: Dataset, structures: list[Structure]) -> Dataset:
    """``data`` with its joint readings transformed by ``structures`` in order."""
    return replace(data, q=to_model(data.q, structures))


def affine_readings(structures: list[Structure], n_joints: int) -> tuple[np.ndarray, np.ndarray]:
    """``(sign, offset)`` with ``model angle_j = sign_j · reading_j + offset_j`` for every joint,
    or an error when a joint is read relative to another (``joint_reference``): no joint-by-joint
    form (a URDF joint, a DH row) can carry that."""
    offset = to_model(np.zeros((1, n_joints)), structures)[0]
    slope = to_model(np.eye(n_joints), structures) - offset  # row i: the model's answer to reading i alone
    coupled = [s.label for s in structures if s.kind == "joint_reference"]
    if coupled or np.any(np.abs(slope - np.diag(np.diag(slope))) > 1e-12):
        raise InvalidParameterError(
            f"the controller reads {', '.join(coupled) or 'a joint relative to another'}: a joint-by-joint format cannot carry that; "
            "export at the model's angles (--angles model) and convert the readings on the controller's side"
        )
    return np.diag(slope).copy(), offset


def reading_limits(robot: Robot, structures: list[Structure]) -> list[tuple[float, float]]:
    """Each joint's limits (of the model's angles) as the controller's readings (:func:`affine_readings`)."""
    sign, offset = affine_readings(structures, robot.n_joints)
    return [tuple(sorted((limit - offset[j]) / sign[j] for limit in joint.limits)) for j, joint in enumerate(robot.joints)]


def robot_at_readings(robot: Robot, structures: list[Structure]) -> Robot:
    """The same tool frame as ``robot`` with the controller's readings as its joint variables:
    ``robot_at_readings(robot, s).fkine(r) == robot.fkine(to_model(r, s))``.

    A zero offset adds to the joint's ``theta`` (``d`` when prismatic). A joint counted the
    other way turns its axis over: ``Rz(θ − r) = Rx(π)·Rz(r − θ)·Rx(π)``, so ``θ`` and ``d``
    change sign, ``alpha`` takes a half turn, and the ``Rx(π)`` left over moves into the link
    before it (standard DH: its ``alpha`` and ``beta``; the base for joint 1) or after it
    (modified DH: the next link's ``alpha``; the tool for the last joint). Joint limits follow.
    """
    sign, offset = affine_readings(structures, robot.n_joints)
    p = robot.params.copy()
    joints = list(robot.joints)
    for j, (joint, limits) in enumerate(zip(robot.joints, reading_limits(robot, structures))):
        variable = robot.index(f"theta{j + 1}" if joint.kind == "revolute" else f"d{j + 1}")
        p[variable] += offset[j]
        joints[j] = replace(joint, limits=limits)
        if sign[j] > 0:
            continue
        for name in ("theta", "d"):
            p[robot.index(f"{name}{j + 1}")] *= -1.0
        p[robot.index(f"alpha{j + 1}")] += np.pi
        if joint.convention == "mdh":
            p[robot.index(f"beta{j + 1}")] *= -1.0
        neighbour = j - 1 if joint.convention == "dh" else j + 1  # where the spare Rx(pi) goes
        if 0 <= neighbour < robot.n_joints:
            if joints[neighbour].convention != joint.convention:
                raise InvalidParameterError(f"joint {j + 1} is counted the other way beside a joint of the other DH convention: not carried joint by joint")
            p[robot.index(f"alpha{neighbour + 1}")] += np.pi
            if joint.convention == "dh":
                p[robot.index(f"beta{neighbour + 1}")] *= -1.0
        else:
            end = "base" if joint.convention == "dh" else "tool"
            frame = [robot.index(f"{end}_{k}") for k in ("x", "y", "z", "rx", "ry", "rz")]
            flip = np.eye(4)
            flip[:3, :3] = rotation(0, np.pi)
            T = frame_transform(p[frame])
            p[frame] = frame_params(T @ flip if end == "base" else flip @ T)
    return Robot(robot.name, joints, p, mass_model=robot.mass_model)
