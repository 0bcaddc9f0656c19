"""Compensation: joint commands that make the calibrated robot reach desired tool positions.

A robot program's joint targets (a file of ``q1 … qN`` alone, :class:`JointProgram`) are
filtered too: each becomes the pose the nominal model reaches there, and the commands out reach
it under the result's full model.

``robocal compensate RESULT TARGETS.csv [--frame F] [--user-frame X,Y,Z,RX,RY,RZ] --out joints.csv``
reads a result file (:mod:`robocal.results`) and a CSV of targets.

The targets file: a header, then one row per target (in program order), comma-separated —
``x, y, z`` (mm): where the calibration's tool point is to go; optionally ``qw, qx, qy, qz``
(unit quaternion, scalar first): the tool frame's orientation too (pose targets); optionally
``q1 … qN``: the joint commands the nominal model would use (deg, or ``--angle-unit rad``), which
then seed the solution. The tool is the one the calibration fitted (a tracker's reflector or
T-Mac, a cable's hook): a target is a position (pose) of that point (frame).

The frame of the targets (``frame=``, ``--frame``):

``base`` (default)
    The robot's base frame: the calibrated chain without the measurement set-up (the result's
    ``base_*`` set to the identity), with the calibrated tool (for a multi-session result, session
    1's). The base frame of a tracker calibration is the chain's own: what the tracker cannot
    tell apart from its own placement (``d1`` against ``base_z``, ``theta1`` against ``base_rz``,
    listed under the result's ``fixed``) is held nominal by the fit, the set-up taking it. A cable
    calibration's frame is already the robot base (the anchor is placed in it; ``base_*`` are not
    fitted), so ``base`` and ``session`` agree there unless the robot file places the base.
``session``, ``session:K``
    The calibration's measurement frame (the tracker's for tracker data): that of session K
    (1-based) of a multi-session result — each session's set-up (base frame and tool) is in the
    result's ``sessions`` — or of the first.
``user``
    A user frame (work object) ``x, y, z`` (mm), ``rx, ry, rz`` (deg) given in the base frame,
    in robocal's frame convention ``Tx·Ty·Tz·Rz·Ry·Rx`` (:func:`robocal.geometry.frame_transform`):
    a target ``p`` in it is ``T_user·p`` in the base frame.

For each target: a seed (the given joints; else the nominal model's inverse kinematics started
from the previous target's command — program order: consecutive targets stay on one branch and
turn of the arm —, the first from the middle of the joint ranges), then Levenberg–Marquardt on the
joint angles of the *calibrated* model with the joint limits kept at every step (:func:`bounded_lm`:
projected steps, accepted only when they decrease the error, damping by the gain ratio) — with the
joint causes of an extended model (``calibrate --causes``: compliance, periodic gear errors,
scale, coupling, joint maps) applied to the commanded angles; backlash and sensor causes are named
in the status as not compensated. Where the result found how the controller reads its joints
(``structure``), seeds and commands are the controller's readings, converted to the model's angles
and back. The Jacobian comes from the Rust core (``∂h/∂q_j`` is the ``theta_j`` column).
Position targets leave three degrees of freedom of a 6-axis arm free: the damped steps take a
small change from the seed, so the tool keeps the seed's orientation as far as possible. A
target that the seed does not lead to is tried from the middle of the joint ranges and from
:data:`RESTARTS` random configurations within the limits; only then is it reported
unreachable — a row with its reason, never dropped.

A revolute joint reaches the same place a whole turn away: every command is the equivalent
(± k·360°) within the joint limits nearest its seed (:func:`nearest_turn`) — within 180° of it
wherever the limits allow one so near. Where a joint map of the result has data at some of the
equivalents but not the nearest, the nearest of those is taken and the status says so (the map's
correction only fades out beyond its data).

The joints file (:func:`write_joints`): ``row`` (the target's row in its file, header = 1),
``q1 … qN`` (deg, the commands as the controller reads its joints), ``dq1 … dqN`` (deg, the
commands minus the seed: the correction to the nominal commands where no seeds were given),
``residual_mm`` (the calibrated model's distance to the target), ``frame`` (``base``,
``session K`` or ``user x y z rx ry rz``) and ``status`` (``ok``, or why not; notes after ``;``).
``benches/bench_compensation.py`` compares the reach rate and time with scipy's
``least_squares(bounds=...)``.
"""

from __future__ import annotations

import csv
import logging
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from .kernels import as_float_array, solve_damped
from .causes import structure
from .causes.candidates import COMPENSABLE, joint_offsets, map_coverage, map_coverage_report, uncovered_words
from .data.table import Table, check_unit_quaternions, read_delimited
from .data.dataset import angle_unit_check
from .exceptions import DataError, InvalidParameterError, ShapeError
from .outputs import Staged
from .geometry import frame_params, frame_transform
from .results import load_result, result_sessions, session_robot
from .serial_robot import Robot

logger = logging.getLogger(__name__)


@dataclass
class Targets:
    """Desired positions (m, 3) or poses (m, 7) with optional seed joints (m, N) in rad."""

    y: np.ndarray
    seeds: Optional[np.ndarray]
    rows: np.ndarray

    def __post_init__(self):
        self.y = as_float_array(self.y, "targets y")
        if self.y.ndim != 2 or self.y.shape[1] not in (3, 7):
            raise ShapeError(f"`targets y` must have shape (m, 3) or (m, 7); got {self.y.shape}")
        m = len(self.y)
        self.rows = np.asarray(self.rows)
        if self.rows.shape != (m,) or self.rows.dtype.kind not in "iu":
            raise ShapeError(f"`targets rows` must be {m} integers; got {self.rows!r}")
        if self.seeds is not None:
            self.seeds = as_float_array(self.seeds, "targets seeds")
            if self.seeds.ndim != 2 or len(self.seeds) != m:
                raise ShapeError(f"`targets seeds` must have shape ({m}, N); got {self.seeds.shape}")


@dataclass
class JointProgram:
    """A robot program's joint targets ``q`` (m, N), rad, the controller's readings, taught or
    planned on the nominal model, with their file ``rows``: :func:`compensate` gives the
    commands with which the calibrated robot — its joint causes too — puts the tool where the
    nominal model puts it at ``q`` (position and orientation)."""

    q: np.ndarray
    rows: np.ndarray


def read_targets(path, n_joints: int, angle_unit: Optional[str] = None):
    """Targets from a CSV with ``x, y, z`` [``qw, qx, qy, qz``] [``q1..qN`` in ``angle_unit``,
    deg by default; seed joints implausible for the default unit are refused] — or, with
    ``q1..qN`` alone, a robot program's joint targets (:class:`JointProgram`)."""
    table = read_delimited(path)
    header = table.header
    quaternion, joints = ["qw", "qx", "qy", "qz"], [f"q{j}" for j in range(1, n_joints + 1)]
    if not any(c in header for c in ("x", "y", "z")) and all(j in header for j in joints):
        return JointProgram(*_seed_joints(table, joints, angle_unit))
    table.require(["x", "y", "z"], "a targets file")
    expected = f"a targets file holds x,y,z, optionally qw,qx,qy,qz (pose targets) and q1..q{n_joints} (seed joints, {angle_unit or 'deg'})"
    unknown = [h for h in header if h not in ["x", "y", "z", *quaternion, *joints]]
    if unknown:  # a misnamed column would otherwise be solved without
        raise DataError(f"unknown columns {[h[:40] for h in unknown[:8]]}: {expected}", path, 1)
    present = [c for c in quaternion if c in header]
    if 0 < len(present) < 4:
        raise DataError(f"only {present} of the quaternion columns: pose targets need all of qw,qx,qy,qz, position targets none; {expected}", path, 1)
    pose = len(present) == 4
    columns = ["x", "y", "z"] + (quaternion if pose else [])
    values, rows, _ = table.numeric(columns)
    if pose:
        check_unit_quaternions(values[:, 3:], rows, path)
    seeds = None
    if any(j in header for j in joints):
        table.require(joints, "seed joints")
        seeds, _ = _seed_joints(table, joints, angle_unit)
    return Targets(values, seeds, rows)


def _seed_joints(table: Table, joints: list, angle_unit: Optional[str]) -> tuple[np.ndarray, np.ndarray]:
    """The joint columns (rad) and their rows; values implausible for the default unit refused."""
    seeds, rows, _ = table.numeric(joints)
    seeds = np.radians(seeds) if angle_unit in (None, "deg") else seeds
    check = angle_unit_check(seeds, angle_unit or "deg", rows)
    if not check["plausible"] and angle_unit is None:
        advice = f"pass --angle-unit {check['likely']} (or --angle-unit deg to confirm)" if check["likely"] != "deg" else "or pass --angle-unit deg to confirm"
        raise DataError(f"seed joints: {check['message']}; {advice}", table.path)
    return seeds, rows


def joint_columns(robot: Robot) -> list[int]:
    """Indices of the joint offsets ``theta1..thetaN`` in the parameter vector: the columns the
    inverse kinematics solves for (revolute joints only)."""
    if any(j.kind != "revolute" for j in robot.joints):
        raise InvalidParameterError("compensation handles revolute joints only")
    return [robot.index(f"theta{j}") for j in range(1, robot.n_joints + 1)]


#: Random starts within the joint limits tried after the given seed and the middle of the
#: ranges before a target is called unreachable (a 6-axis arm has up to 8 inverse-kinematics
#: branches; a start on the wrong side of a limit cannot cross it).
RESTARTS = 24
#: ... for pose targets. Position and orientation together leave one inverse-kinematics branch
#: (of up to 8, each cut by the limits): on the HSR JR680 and UR10 a random start within the limits
#: reaches the hardest of 200 reachable pose targets once in 10–30 tries (24 missed 5 of 200).
#: Tried only where the first starts fail; a miss costs ~100 short LM runs.
RESTARTS_POSE = 256
#: Weight of the rotation residual (rad) against the position residual (mm) of pose targets: a
#: length of the order of the arm, so that neither part dominates the damped steps.
ROTATION_WEIGHT_MM = 1000.0


def residual_weights(measurement: str) -> np.ndarray:
    """Weights of a target's residual rows: 1 on x, y, z (mm), :data:`ROTATION_WEIGHT_MM` on the
    rotation vector (rad) of a pose."""
    return np.array([1.0, 1.0, 1.0] + [ROTATION_WEIGHT_MM] * 3)[: 3 if measurement == "position" else 6]


def joint_limits(robot: Robot) -> tuple[np.ndarray, np.ndarray]:
    """The joints' lower and upper limits (rad), each of shape (N,)."""
    return np.array([j.limits[0] for j in robot.joints]), np.array([j.limits[1] for j in robot.joints])


#: A full turn of a revolute joint (rad): its angles ``q + k·TURN`` put the links in the same place.
TURN = 2.0 * np.pi
#: Equivalent angles considered either side of the one nearest the seed (ranges of more turns
#: than a real joint has would otherwise make the list endless).
MAX_TURNS = 4


def nearest_turn(q: np.ndarray, toward: np.ndarray, lower: np.ndarray, upper: np.ndarray, covered=None) -> tuple[np.ndarray, list[int]]:
    """``q`` (N,) with each joint moved by whole turns to its equivalent angle within the limits
    nearest ``toward`` (N,); a joint with no equivalent within its limits is clipped into them.

    ``covered(j, angles)`` says which equivalent angles of joint ``j`` (0-based) a joint map of
    the result has data at (None: the joint has no map): where it covers some but not the nearest,
    the nearest covered one is taken — the map's correction only fades out beyond its data.
    Returns the angles and the joints the map's data moved off the nearest equivalent.
    """
    q = np.asarray(q, dtype=np.float64)
    toward = np.asarray(toward, dtype=np.float64)
    with np.errstate(invalid="ignore"):  # an infinite angle: NaN here, clipped below
        first = lower + np.mod(q - lower, TURN)  # each joint's lowest equivalent within its limits
        valid = first <= upper  # False where none lies within (or for a non-finite angle)
        count = np.floor((upper - first) / TURN)  # equivalents above the lowest within the limits
        aim = np.where(np.isfinite(toward), toward, q)
        near = np.clip(np.round((aim - first) / TURN), 0.0, count)  # the nearest: turns from the lowest
        # Turns counted from q itself: where q is the one chosen it comes back unchanged, bit for bit.
        from_q = np.round((first - q) / TURN)
        out = np.where(valid, q + TURN * (from_q + near), q)
    off = []
    for j in np.flatnonzero(valid) if covered is not None else ():
        k = np.arange(max(0.0, near[j] - MAX_TURNS), min(count[j], near[j] + MAX_TURNS) + 1)
        angles = q[j] + TURN * (from_q[j] + k)
        inside = covered(j, angles) if k.size else None
        if inside is not None and inside.any() and not covered(j, out[j : j + 1])[0]:
            out[j] = angles[inside][np.argmin(np.abs(angles[inside] - aim[j]))]
            off.append(int(j))
    out = np.clip(out, lower, upper)
    return out, off


def _into_limits(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """``q`` itself where it lies within the limits, else the same joint angles a whole turn or
    more away where the range allows (revolute joints), the nearest ones otherwise."""
    return nearest_turn(q, q, lower, upper)[0]


def bounded_lm(residual, jacobian, q0, lower, upper, done, max_iter: int = 100):
    """Levenberg–Marquardt on ``½‖r(q)‖²`` with ``lower <= q <= upper`` kept at every step.

    Each step is damped Gauss–Newton on the joints that are free — a joint at a limit whose
    gradient points outwards is held there — projected onto the box, and accepted only when the
    cost decreases; the damping follows the gain ratio of the actual to the predicted decrease
    (Nielsen's update, as in Madsen, Nielsen & Tingleff, *Methods for non-linear least squares
    problems*, 2004). Returns ``(q, r)`` at the last accepted point.
    """
    q = np.clip(np.asarray(q0, dtype=np.float64), lower, upper)
    r = residual(q)
    J = jacobian(q)
    mu, nu = None, 2.0
    for _ in range(max_iter):
        if done(r):
            break
        g = J.T @ r  # r = y - h: the cost decreases along +g
        free = ~(((q <= lower) & (g < 0)) | ((q >= upper) & (g > 0)))
        if not free.any():
            break
        if mu is None:
            mu = 1e-3 * max(float(np.max(np.sum(J * J, axis=0))), 1e-12)
        step = np.zeros_like(q)
        step[free], _ = solve_damped(J[:, free], r, mu, "identity")
        trial = np.clip(q + step, lower, upper)
        d = trial - q
        Jd = J @ d
        predicted = r @ Jd - 0.5 * Jd @ Jd  # ½‖r‖² − ½‖r − J·d‖²
        r_trial = residual(trial)
        actual = 0.5 * (r @ r - r_trial @ r_trial)
        if predicted > 0 and actual > 0:
            rho = actual / predicted
            q, r, J = trial, r_trial, jacobian(trial)
            mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
            nu = 2.0
        else:
            mu *= nu
            nu *= 2.0
            if mu > 1e20 or not np.any(np.abs(d) > 1e-15 * (1.0 + np.abs(q))):
                break
    return q, r


def solve_joints(
    robot: Robot,
    target: np.ndarray,
    seed: np.ndarray,
    tol: float = 1e-6,
    max_iter: int = 100,
    offsets=None,
    restarts: Optional[int] = None,
    covered=None,
) -> tuple[np.ndarray, float, str]:
    """Joint commands (rad) within the joint limits with which ``robot`` reaches ``target``
    (xyz, or xyz + quaternion).

    :func:`bounded_lm` from ``seed`` (moved into the limits), then from the middle of the joint
    ranges and from ``restarts`` random configurations within the limits (seeded: the same
    target gives the same answer; default :data:`RESTARTS`, :data:`RESTARTS_POSE` for a pose)
    until one reaches the target. The solution is then moved by whole turns to the equivalent
    angles within the limits nearest ``seed`` (:func:`nearest_turn`; ``covered``: a joint map's
    data, preferred) and polished there (a joint cause need not repeat with a turn).
    ``offsets(q) -> Δq`` are joint causes of an extended model: the links take ``q + Δq(q)``
    (the Jacobian neglects ``∂Δq/∂q``, a relative change of order 1e-4).
    Returns ``(q, residual_mm, status)``; ``status`` is ``"ok"`` (followed by ``"; ..."`` where a
    map's data took a joint off the turn nearest its seed) or the reason it is not.
    """
    measurement = "pose" if target.size == 7 else "position"
    cols = joint_columns(robot)
    lower, upper = joint_limits(robot)
    y = target[None, :]
    weight = residual_weights(measurement)
    seed = np.asarray(seed, dtype=np.float64)

    def actual(q):
        return q[None, :] if offsets is None else q[None, :] + offsets(q[None, :])

    def residual(q):
        return robot.residuals(measurement, actual(q), y).ravel() * weight

    def jacobian(q):
        return robot.jacobian(measurement, actual(q), y=y, cols=cols) * weight[:, None]

    def reached(r):
        return np.linalg.norm(r[:3]) < tol and (measurement == "position" or np.linalg.norm(r[3:]) < tol * 1e-3 * ROTATION_WEIGHT_MM)

    def near_seed(q, r):
        """The reached ``q`` a whole number of turns nearer the seed, where that still reaches."""
        turned, off = nearest_turn(q, seed, lower, upper, covered)
        if np.array_equal(turned, q):
            return q, r, ""
        q_t, r_t = bounded_lm(residual, jacobian, turned, lower, upper, reached, max_iter)
        if not reached(r_t):  # a joint cause that does not repeat with the turn, and no solution there
            return q, r, ""
        note = "".join(
            f"; joint {j + 1} {abs(np.degrees(q_t[j] - seed[j])):.0f} deg from its seed: the angle a turn nearer lies beyond its map's data" for j in off
        )
        return q_t, r_t, note

    if restarts is None:
        restarts = RESTARTS if measurement == "position" else RESTARTS_POSE
    rng = np.random.default_rng(0)
    starts = [_into_limits(seed, lower, upper), 0.5 * (lower + upper)]
    starts += list(lower + (upper - lower) * rng.random((restarts, len(lower))))
    best = None
    for start in starts:
        q, r = bounded_lm(residual, jacobian, start, lower, upper, reached, max_iter)
        error = float(np.linalg.norm(r[:3]))
        if not np.isfinite(error):
            continue
        if reached(r):
            q, r, note = near_seed(q, r)
            return q, float(np.linalg.norm(r[:3])), "ok" + note
        if best is None or r @ r < best[2]:
            best = (q, error, r @ r)
    if best is None:
        return starts[0], float("nan"), "unreachable: the calibrated model's residual is not finite"
    return best[0], best[1], (f"unreachable within the joint limits: from {len(starts)} starts the calibrated model gets no closer than {best[1]:.3g} mm")


def nominal_seed(nominal: Robot, target: np.ndarray, start: Optional[np.ndarray] = None) -> np.ndarray:
    """The nominal model's solution within the limits (a start for the calibrated one), from
    ``start`` (default: the middle of the joint ranges) and at the turns nearest it; where the
    nominal model does not reach the target (near a singularity, the calibrated one may), its
    closest approach from :data:`RESTARTS` random starts — a start, not worth a pose's 256."""
    lower, upper = joint_limits(nominal)
    q, _, _ = solve_joints(nominal, target, 0.5 * (lower + upper) if start is None else start, restarts=RESTARTS)
    return q


@dataclass(frozen=True)
class Frame:
    """The frame targets are given in: ``kind`` ``"base"``, ``"session"`` (``session``, 1-based)
    or ``"user"`` (``user``: its pose in the base frame, ``x, y, z`` mm, ``rx, ry, rz`` deg)."""

    kind: str
    session: int = 1
    user: Optional[tuple] = None

    @property
    def label(self) -> str:
        """The frame as a short word (the ``frame`` column of the joints file)."""
        if self.kind == "session":
            return f"session {self.session}"
        if self.kind == "user":
            return "user " + " ".join(f"{v:g}" for v in self.user)
        return "base"

    @property
    def words(self) -> str:
        if self.kind == "session":
            return f"the measurement frame of session {self.session} of the calibration"
        if self.kind == "user":
            x, y, z, rx, ry, rz = self.user
            return f"the user frame at {x:g},{y:g},{z:g} mm, {rx:g},{ry:g},{rz:g} deg in the robot base frame"
        return "the robot base frame"


FRAME_SPECS = "base, session, session:K (K = 1, 2, ...: a session of a multi-session result) or user (with a user frame x,y,z,rx,ry,rz)"


def parse_frame(frame: Optional[str] = None, user_frame=None) -> Frame:
    """The :class:`Frame` of a ``frame`` spec (None: ``user`` where ``user_frame`` is given,
    else ``base``) and ``user_frame``: six numbers ``x, y, z`` (mm), ``rx, ry, rz`` (deg, the
    frame convention ``Tx·Ty·Tz·Rz·Ry·Rx``: :func:`~robocal.geometry.frame_transform`) as a
    sequence or a comma-separated string."""
    if frame is None:
        frame = "user" if user_frame is not None else "base"
    if not isinstance(frame, str):
        raise InvalidParameterError(f"`frame` must be {FRAME_SPECS}; got {frame!r:.60}")
    kind, colon, k = frame.strip().partition(":")
    if kind == "user" and not colon:
        if user_frame is None:
            raise InvalidParameterError(
                f"`frame` user needs a user frame x,y,z,rx,ry,rz (mm, deg, in the robot base frame: --user-frame); got frame {frame!r:.60}"
            )
        try:
            values = np.asarray(user_frame.split(",") if isinstance(user_frame, str) else user_frame, dtype=np.float64)
        except (TypeError, ValueError):
            values = None
        if values is None or values.shape != (6,) or not np.all(np.isfinite(values)):
            raise InvalidParameterError(f"the user frame must be 6 finite numbers x,y,z,rx,ry,rz (mm, deg); got {user_frame!r:.80}")
        return Frame("user", user=tuple(float(v) for v in values))
    if user_frame is not None:
        raise InvalidParameterError(f"a user frame is given but `frame` is {frame!r:.60}: use frame user (or leave the user frame out)")
    if kind == "base" and not colon:
        return Frame("base")
    if kind == "session" and (not colon or (k.isdecimal() and int(k) >= 1)):
        return Frame("session", session=int(k) if k else 1)
    raise InvalidParameterError(f"`frame` must be {FRAME_SPECS}; got {frame!r:.60}")


def framed_robot(calibrated: Robot, doc: dict, frame: Frame) -> Robot:
    """The calibrated robot predicting in ``frame``: its base parameters (``base_*``) and tool.

    ``base``: the calibrated chain with ``base_*`` the identity and the result's tool (for a
    multi-session result, session 1's). ``session``: the set-up of that session (the result's
    ``parameters`` hold session 1's, ``sessions`` every session's). ``user``: ``base_*`` the
    inverse of the user frame — a target given in it is one in the base frame moved by the frame.
    """
    params = calibrated.params.copy()
    base = [calibrated.index(f"base_{c}") for c in ("x", "y", "z", "rx", "ry", "rz")]
    if frame.kind == "session":
        sessions = max(1, len(result_sessions(doc)))
        if frame.session > sessions:
            which = "1 session: K must be 1" if sessions == 1 else f"{sessions} sessions: K must be 1..{sessions}"
            raise InvalidParameterError(f"frame session:{frame.session}: the result holds {which}")
        if frame.session > 1:
            params = session_robot(calibrated, doc, frame.session - 1).params
    elif frame.kind == "base":
        params[base] = 0.0
    else:
        xyz, angles = np.array(frame.user[:3]), np.radians(frame.user[3:])
        params[base] = frame_params(np.linalg.inv(frame_transform(np.concatenate([xyz, angles]))))
    return Robot(calibrated.name, calibrated.joints, params, mass_model=calibrated.mass_model)


def _map_cover(causes: list[dict]):
    """``covered(j, angles)`` for :func:`nearest_turn`: where the joint maps of ``causes`` on joint
    ``j`` (0-based) all have data, or None for a joint without a map; None without maps."""
    details: dict = {}
    for c in causes:
        if c.get("kind") == "joint_map":
            details.setdefault(c["joint"] - 1, []).append(c["detail"])
    if not details:
        return None

    def covered(j, angles):
        return np.logical_and.reduce([map_coverage(angles, d) for d in details[j]]) if j in details else None

    return covered


def compensate(result, targets, *, angle_unit: Optional[str] = None, frame: Optional[str] = None, user_frame=None) -> list[dict]:
    """Joint commands for every target (see the module notes).

    Parameters
    ----------
    result : path or dict
        A result file (:func:`robocal.results.load_result`).
    targets : path, array_like (m, 3 | 7), Targets or JointProgram
        A targets CSV (:func:`read_targets`), target rows ``x, y, z`` [``qw, qx, qy, qz``] (mm),
        :class:`Targets`, or a robot program's joint targets (:class:`JointProgram`; a CSV of
        ``q1..qN`` alone): the poses the nominal model reaches there, the program's joints as seeds.
    angle_unit : {"deg", "rad"}, optional
        Unit of the seed joint columns of a targets file (deg by default).
    frame : {"base", "session", "session:K", "user"}, optional
        The frame the targets are given in: the robot base frame (default; ``user`` where
        ``user_frame`` is given), the calibration's measurement frame (of its K-th session, 1-based),
        or ``user_frame``.
    user_frame : str or sequence of 6 float, optional
        The user frame (work object) ``x, y, z`` (mm), ``rx, ry, rz`` (deg) in the robot base
        frame, as ``Tx·Ty·Tz·Rz·Ry·Rx`` (:func:`robocal.geometry.frame_transform`).

    Returns
    -------
    list of dict
        Per target, in order: ``row``, ``q`` (deg), ``correction`` (deg, against the seed),
        ``residual_mm`` (the calibrated model's distance to the target), ``frame`` (its label),
        ``status`` (which says when a joint lies beyond the range a joint map was fitted on, or
        was taken a turn from its seed into it).
    """
    where = parse_frame(frame, user_frame)
    calibrated, doc = load_result(result)
    joint_columns(calibrated)  # a robot it cannot solve for refused before its targets' joint columns are judged as angles
    framed = framed_robot(calibrated, doc, where)
    # The nominal model in the targets' frame: nominal kinematics with the frame's set-up (base
    # frame, tool), as a user's controller would have it after a base/tool calibration.
    nominal = Robot(calibrated.name, calibrated.joints, doc["robot_model"]["nominal"], mass_model=calibrated.mass_model)  # checked by load_result
    setup = [k for k, n in enumerate(calibrated.param_names) if n.startswith(("base_", "tool_"))]
    nominal.params[setup] = framed.params[setup]
    if isinstance(targets, (str, os.PathLike)):
        targets = read_targets(targets, calibrated.n_joints, angle_unit)
    elif not isinstance(targets, (Targets, JointProgram)):  # an array of x, y, z [qw, qx, qy, qz] rows; shape checked by Targets
        y = as_float_array(targets, "targets")
        targets = Targets(y, None, np.arange(2, 2 + (len(y) if y.ndim else 0)))
    conventions = structure.parse_all(doc.get("structure", []), calibrated.n_joints)
    if isinstance(targets, JointProgram):  # where the nominal model puts the tool at the program's joints: the poses to reach
        program = as_float_array(targets.q, "program joints")
        if program.ndim != 2 or program.shape[1] != calibrated.n_joints:
            raise ShapeError(f"`program joints` must have shape (m, {calibrated.n_joints}); got {program.shape}")
        targets = Targets(nominal.predict("pose", structure.to_model(program, conventions), nominal.params), program, targets.rows)
    causes = doc.get("causes", [])
    offsets = joint_offsets(calibrated, causes)  # the causes act on the joints whatever frame the targets are in
    covered = _map_cover(causes)
    skipped = sorted({str(c.get("label", c.get("kind"))) for c in causes if c.get("kind") not in COMPENSABLE})
    note = f" (not compensated: {', '.join(skipped)})" if skipped else ""
    out = []
    previous = None  # the last command that reached its target: where the next target's nominal solution starts
    for i, target in enumerate(targets.y):
        # Seeds and commands in the controller's convention; the model solves in its own.
        if targets.seeds is not None:
            seed = structure.to_model(targets.seeds[i][None, :], conventions)[0]
        else:  # program order: from the previous command, the nominal solution stays on its branch and turns
            seed = nominal_seed(nominal, target, previous)
        q, error, status = solve_joints(framed, target, seed, offsets=offsets, covered=covered)
        if status.startswith("ok"):
            previous = q
            status = "ok" + note + status[2:]
        beyond = [m for m in map_coverage_report(causes, q[None, :]) if m["outside"]]
        if beyond:  # the map's correction only fades out there: the user must know
            status += "; beyond its map's data: " + ", ".join(f"joint {m['joint']} {uncovered_words(m)}" for m in beyond)
        command, seed = (structure.to_readings(v[None, :], conventions)[0] for v in (q, seed))
        out.append(
            {
                "row": int(targets.rows[i]),
                "q": np.degrees(command).tolist(),
                "correction": np.degrees(command - seed).tolist(),
                "residual_mm": error,
                "frame": where.label,
                "status": status,
            }
        )
        logger.debug("compensate: target row %d: %s", targets.rows[i], status)
    return out


def write_joints(rows: list[dict], path, n_joints: int) -> Path:
    with Staged(path) as stage, stage.tmp.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["row"] + [f"q{j}" for j in range(1, n_joints + 1)] + [f"dq{j}" for j in range(1, n_joints + 1)] + ["residual_mm", "frame", "status"])
        for r in rows:
            # Joints written to the last bit (repr): six decimals of a degree move a 1 m arm's tool by 2e-5 mm.
            w.writerow(
                [r["row"]] + [repr(float(v)) for v in r["q"]] + [repr(float(v)) for v in r["correction"]] + [f"{r['residual_mm']:.3g}", r["frame"], r["status"]]
            )
    return stage.path
