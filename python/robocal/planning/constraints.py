"""The cell: what it allows (:class:`Constraints`: the joint ranges, the cable sensor's reading
range, the tracker's distances, a box for the tool point) and the pool of candidate poses drawn
uniformly within the joint ranges and kept where every constraint allows them
(:func:`candidate_poses`); :data:`NOT_CHECKED` is what the plan does not check.

Units: mm and rad inside; the descriptions state angles in degrees."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Optional

import numpy as np

from ..causes import structure
from ..exceptions import InvalidParameterError
from ..kernels import as_float_array
from ..physics import DEG
from ..robot import Robot
from ..simulation import RANGE_MARGIN, setup

#: Candidates drawn within the constraints; the draws stop after this many times as many tries.
CANDIDATES = 10_000


MAX_DRAW_FACTOR = 200


#: Distances (mm) a laser tracker measures at, when only its position is given: beyond the
#: near limit of common trackers' specifications, within their 20 m or more.
TRACKER_RANGE = (1000.0, 20000.0)


#: What the plan does not check.
NOT_CHECKED = (
    "collisions of the robot with itself, the cell or the sensor",
    "the cable touching or wrapping around the robot's links",
    "the tracker's line of sight and the reflector's acceptance angle",
    "singular configurations and how the robot moves between poses (only the joint values are planned)",
)


def _ranges(robot: Robot, joint_ranges, structures: list = ()) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds (rad; mm for prismatic joints) of every joint's reading: the robot's limits (of its
    model's angles) at the controller's readings (``structures``, its reading conventions), narrowed by
    ``joint_ranges`` (1-based joint -> (lower, upper), readings)."""
    limits = [j.limits for j in robot.joints]
    if structures and not any(s.kind == "joint_reference" for s in structures):  # a joint read relative to another has no box
        # The limits bound the model's angles: a UR10 joint read 90 deg off, held to -360..360 as read, was planned
        # at model angles to -400 deg, beyond what the robot reaches (and what simulate, monitor and export allow).
        limits = structure.reading_limits(robot, list(structures))
    lo, hi = (np.array(v, dtype=np.float64) for v in zip(*limits))
    if joint_ranges is None:
        return lo, hi
    if not isinstance(joint_ranges, Mapping):
        raise InvalidParameterError(f"`joint_ranges` must map a 1-based joint to (lower, upper); got {joint_ranges!r}")
    for joint, bounds in joint_ranges.items():
        if isinstance(joint, bool) or not isinstance(joint, (int, np.integer)) or not 1 <= joint <= robot.n_joints:
            raise InvalidParameterError(f"`joint_ranges`: joint {joint!r} is not a joint of {robot.name} (1..{robot.n_joints})")
        pair = as_float_array(bounds, f"joint_ranges[{joint}]")
        if pair.shape != (2,) or not np.all(np.isfinite(pair)) or pair[0] >= pair[1]:
            raise InvalidParameterError(f"`joint_ranges[{joint}]` must be finite (lower, upper) with lower < upper; got {bounds!r}")
        j = joint - 1
        if pair[1] < lo[j] or pair[0] > hi[j]:
            unit, f = ("mm", 1.0) if robot.joints[j].kind == "prismatic" else ("deg", 1 / DEG)
            raise InvalidParameterError(
                f"joint range: joint {joint} within {pair[0] * f:g}..{pair[1] * f:g} {unit} lies outside its limits "
                f"{lo[j] * f:g}..{hi[j] * f:g} {unit}: no candidate"
            )
        lo[j], hi[j] = max(lo[j], pair[0]), min(hi[j], pair[1])
    return lo, hi


def _vector(value, name: str, size: int) -> Optional[np.ndarray]:
    """``value`` as ``size`` finite floats (None stays None), or an error naming ``name``."""
    if value is None:
        return None
    v = as_float_array(value, name).ravel()
    if v.shape != (size,) or not np.all(np.isfinite(v)):
        raise InvalidParameterError(f"`{name}` must be {size} finite numbers; got {value!r}")
    return v


@dataclass
class Constraints:
    """What a cell allows: joint ranges (the controller's readings, rad), the cable sensor's
    reading range (mm; kept :data:`~robocal.simulation.RANGE_MARGIN` inside), the tracker's
    position (robot base frame, mm) and the distances it measures at, and a box the tool point
    must stay in (robot base frame, ``(xmin, xmax, ymin, ymax, zmin, zmax)`` mm; default: above
    the mounting plane, ``z > 0``)."""

    lower: np.ndarray
    upper: np.ndarray
    cable_range: Optional[np.ndarray] = None
    tracker: Optional[np.ndarray] = None
    tracker_range: Optional[np.ndarray] = None
    box: Optional[np.ndarray] = None

    def masks(self, robot: Robot, measurement: str, params: np.ndarray, q: np.ndarray) -> dict:
        """``description -> bool (m,)`` for the model's joint angles ``q`` (m, N): which
        configurations each constraint allows (the joint ranges are applied when drawing)."""
        zeroed = params.copy()  # the tool point in the robot's base frame, whatever the tracker's frame
        zeroed[[robot.index(f"base_{c}") for c in ("x", "y", "z", "rx", "ry", "rz")]] = 0.0
        point = robot.fkine(q, params=zeroed, tool=True)[:, :3, 3]
        out = {}
        if self.box is None:
            out["the tool point above the mounting plane (z > 0 mm in the base frame)"] = point[:, 2] > 0.0
        else:
            b = self.box
            inside = np.all((point >= b[[0, 2, 4]]) & (point <= b[[1, 3, 5]]), axis=1)
            out[f"the tool point inside the box x {b[0]:g}..{b[1]:g}, y {b[2]:g}..{b[3]:g}, z {b[4]:g}..{b[5]:g} mm"] = inside
        if measurement == "cable":
            low, high = self.cable_range + np.array([RANGE_MARGIN, -RANGE_MARGIN])
            reading = robot.predict("cable", q, params)[:, 0]
            anchor = params[[robot.index(f"anchor_{c}") for c in "xyz"]]
            where = ", ".join(f"{v:.0f}" for v in anchor)
            out[f"the cable reading within {low:g}..{high:g} mm (sensor range {self.cable_range[0]:g}..{self.cable_range[1]:g} mm, anchor at {where} mm)"] = (
                reading > low
            ) & (reading < high)
        if self.tracker is not None:
            near, far = self.tracker_range
            distance = np.linalg.norm(point - self.tracker, axis=1)
            where = ", ".join(f"{v:.0f}" for v in self.tracker)
            out[f"the tool point {near:g}..{far:g} mm from the tracker at {where} mm"] = (distance >= near) & (distance <= far)
        return out

    def describe(self, robot: Robot, measurement: str, params: np.ndarray, structures: list) -> list[str]:
        """Every constraint in words: the joint ranges (deg; mm for prismatic joints; the
        controller's readings), then those of :meth:`masks`."""
        parts = []
        for j, joint in enumerate(robot.joints):
            f, unit = (1.0, "mm") if joint.kind == "prismatic" else (1 / DEG, "deg")
            parts.append(f"q{j + 1} {self.lower[j] * f:.4g}..{self.upper[j] * f:.4g} {unit}")
        read = " (the controller's readings; the model's angles follow its reading conventions)" if structures else ""
        return ["joint ranges " + ", ".join(parts) + read, *self.masks(robot, measurement, params, self.lower[None, :])]  # the names alone


def candidate_poses(
    robot: Robot, measurement: str, params: np.ndarray, constraints: Constraints, structures: list, count: int, rng: np.random.Generator, least: int = 1
) -> tuple[np.ndarray, list[str]]:
    """Up to ``count`` joint configurations (readings, rad) drawn uniformly within the joint
    ranges that every constraint allows, and notes; an error naming the constraint that leaves
    fewer than ``least``."""
    kept, drawn, passed = [], 0, {}
    found = 0
    while found < count and drawn < MAX_DRAW_FACTOR * count:
        batch = max(1000, 2 * (count - found))
        q = rng.uniform(constraints.lower, constraints.upper, (batch, robot.n_joints))
        masks = constraints.masks(robot, measurement, params, structure.to_model(q, structures))
        ok = np.ones(batch, dtype=bool)
        for name, mask in masks.items():
            passed[name] = passed.get(name, 0) + int(mask.sum())
            ok &= mask
        kept.append(q[ok])
        found += int(ok.sum())
        drawn += batch
    pool = np.vstack(kept)[:count]
    notes = []
    if len(pool) < least:
        blocking = [name for name, n in passed.items() if n == 0]
        rates = "; ".join(f"{name}: {n / drawn:.2%}" for name, n in passed.items())
        if blocking:
            raise InvalidParameterError(f"no joint configuration within the joint ranges satisfies {blocking[0]} (0 of {drawn:,} drawn): relax it")
        raise InvalidParameterError(
            f"only {len(pool)} of {drawn:,} joint configurations drawn within the joint ranges satisfy every constraint, fewer than the {least} "
            f"poses asked; each alone passes: {rates}"
        )
    if len(pool) < count:
        notes.append(f"only {len(pool)} of {drawn:,} configurations drawn satisfy the constraints: the poses are chosen among those")
    return pool, notes


def _checked_setup(robot: Robot, measurement: str, params, tool, anchor, tracker, tracker_range, box, cable_range, has_data: bool) -> tuple:
    """The parameters the plan is linearised at (before any data) and its :class:`Constraints`
    beside the joint ranges, from the arguments — or an error naming the one that is wrong."""
    anchor, tool, tracker, box = _vector(anchor, "anchor", 3), _vector(tool, "tool", 3), _vector(tracker, "tracker", 3), _vector(box, "box", 6)
    if box is not None and not np.all(box[[0, 2, 4]] < box[[1, 3, 5]]):
        raise InvalidParameterError(f"`box` must be (xmin, xmax, ymin, ymax, zmin, zmax) with each min < max; got {box.tolist()}")
    if has_data and (anchor is not None or tool is not None):
        raise InvalidParameterError("`anchor` and `tool` are fitted on the data: give the data or the set-up, not both")
    if measurement == "cable" and tracker is not None:
        raise InvalidParameterError("`tracker` places a laser tracker: it applies to position and pose measurements, not cable")
    if measurement != "cable" and anchor is not None:
        raise InvalidParameterError(f"`anchor` places a cable sensor: it applies to cable measurements, not {measurement}")
    if tracker is None and tracker_range is not None:
        raise InvalidParameterError("`tracker_range` needs `tracker`, the tracker's position")
    cable = None
    if measurement == "cable":
        cable = _vector(cable_range, "cable_range", 2)
        if not 0 <= cable[0] < cable[1] - 2 * RANGE_MARGIN:
            raise InvalidParameterError(f"`cable_range` must be (min, max) mm with 0 <= min and max - min > {2 * RANGE_MARGIN:g}; got {cable.tolist()}")
    distances = None
    if tracker is not None:
        distances = _vector(TRACKER_RANGE if tracker_range is None else tracker_range, "tracker_range", 2)
        if not 0 <= distances[0] < distances[1]:
            raise InvalidParameterError(f"`tracker_range` must be (near, far) mm with 0 <= near < far; got {distances.tolist()}")
    if params is None:
        params = setup(robot, measurement, tool, anchor).params
    else:
        params = params.copy()
        for names, value in ((("tool_x", "tool_y", "tool_z"), tool), (("anchor_x", "anchor_y", "anchor_z"), anchor)):
            if value is not None:
                params[[robot.index(n) for n in names]] = value
    return params, (cable, tracker, distances, box)
