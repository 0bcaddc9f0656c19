"""Compensation: joint commands that make the calibrated robot reach desired tool positions.

``robocal compensate RESULT TARGETS.csv --out joints.csv`` reads a result file
(:mod:`robocal.results`) and a CSV of targets ``x, y, z`` (mm) — optionally ``qw, qx, qy, qz``
for full poses, and optionally the joint commands ``q1 … qN`` (deg) the nominal model would use,
which then seed the solution. Targets are in the frame the calibrated model predicts in: the
measurement frame of the calibration (the tracker's frame for tracker data, the robot base for
cable data).

For each target: a seed (the given joints, else the nominal model's inverse kinematics from the
middle of the joint ranges), then Levenberg–Marquardt on the joint angles of the *calibrated*
model with the joint limits kept at every step (:func:`bounded_lm`: projected steps, accepted
only when they decrease the error, damping by the gain ratio) — with the joint causes of an
extended model (``calibrate --causes``: compliance, periodic gear errors, scale, coupling)
applied to the commanded angles; backlash and sensor causes are named in the status as not
compensated. Where the result found how the controller reads its joints (``structure``), seeds
and commands are the controller's readings, converted to the model's angles and back. The Jacobian
comes from the Rust core (``∂h/∂q_j`` is the ``theta_j`` column).
Position targets leave three degrees of freedom of a 6-axis arm free: the damped steps take a
small change from the seed, so the tool keeps the seed's orientation as far as possible. A
target that the seed does not lead to is tried from the middle of the joint ranges and from
:data:`RESTARTS` random configurations within the limits; only then is it reported
unreachable — a row with its reason, never dropped. ``benches/bench_compensation.py`` compares
the reach rate and time with scipy's ``least_squares(bounds=...)``.
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
from .causes.candidates import COMPENSABLE, joint_offsets, map_coverage_report, uncovered_words
from .data.table import check_unit_quaternions, numeric_columns, read_text, require_columns, split_delimited
from .data.dataset import angle_unit_check
from .exceptions import DataError, InvalidParameterError, ShapeError
from .outputs import Staged
from .results import load_result
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


def read_targets(path, n_joints: int, angle_unit: Optional[str] = None) -> Targets:
    """Targets from a CSV with ``x, y, z`` [``qw, qx, qy, qz``] [``q1..qN`` in ``angle_unit``,
    deg by default; seed joints implausible for the default unit are refused]."""
    header, body = split_delimited(read_text(path), ",", path)
    require_columns(header, ["x", "y", "z"], path, "a targets file")
    quaternion, joints = ["qw", "qx", "qy", "qz"], [f"q{j}" for j in range(1, n_joints + 1)]
    expected = f"a targets file holds x,y,z, optionally qw,qx,qy,qz (pose targets) and q1..q{n_joints} (seed joints, {angle_unit or 'deg'})"
    unknown = [h for h in header if h not in ["x", "y", "z", *quaternion, *joints]]
    if unknown:  # a misnamed column would otherwise be solved without
        raise DataError(f"unknown columns {[h[:40] for h in unknown[:8]]}: {expected}", path, 1)
    present = [c for c in quaternion if c in header]
    if 0 < len(present) < 4:
        raise DataError(f"only {present} of the quaternion columns: pose targets need all of qw,qx,qy,qz, position targets none; {expected}", path, 1)
    pose = len(present) == 4
    columns = ["x", "y", "z"] + (quaternion if pose else [])
    values, rows, _ = numeric_columns(header, body, columns, path)
    if pose:
        check_unit_quaternions(values[:, 3:], rows, path)
    seeds = None
    if any(j in header for j in joints):
        require_columns(header, joints, path, "seed joints")
        seeds, seed_rows, _ = numeric_columns(header, body, joints, path)
        seeds = np.radians(seeds) if angle_unit in (None, "deg") else seeds
        check = angle_unit_check(seeds, angle_unit or "deg", seed_rows)
        if not check["plausible"] and angle_unit is None:
            raise DataError(f"seed joints: {check['message']}; pass --angle-unit {check['likely']} (or --angle-unit deg to confirm)", path)
    return Targets(values, seeds, rows)


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


def _into_limits(q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """``q`` moved by whole turns towards the middle of each range, then clipped into it: the
    same joint angles where the range allows (revolute joints), the nearest ones otherwise."""
    q = q + 2.0 * np.pi * np.round((0.5 * (lower + upper) - q) / (2.0 * np.pi))
    return np.clip(q, lower, upper)


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
    robot: Robot, target: np.ndarray, seed: np.ndarray, tol: float = 1e-4, max_iter: int = 100, offsets=None, restarts: Optional[int] = None
) -> tuple[np.ndarray, float, str]:
    """Joint commands (rad) within the joint limits with which ``robot`` reaches ``target``
    (xyz, or xyz + quaternion).

    :func:`bounded_lm` from ``seed`` (moved into the limits), then from the middle of the joint
    ranges and from ``restarts`` random configurations within the limits (seeded: the same
    target gives the same answer; default :data:`RESTARTS`, :data:`RESTARTS_POSE` for a pose)
    until one reaches the target. ``offsets(q) -> Δq`` are joint
    causes of an extended model: the links take ``q + Δq(q)`` (the Jacobian neglects
    ``∂Δq/∂q``, a relative change of order 1e-4).
    Returns ``(q, residual_mm, status)``; ``status`` is ``"ok"`` or the reason it is not.
    """
    measurement = "pose" if target.size == 7 else "position"
    cols = joint_columns(robot)
    lower, upper = joint_limits(robot)
    y = target[None, :]
    weight = residual_weights(measurement)

    def actual(q):
        return q[None, :] if offsets is None else q[None, :] + offsets(q[None, :])

    def residual(q):
        return robot.residuals(measurement, actual(q), y).ravel() * weight

    def jacobian(q):
        return robot.jacobian(measurement, actual(q), y=y, cols=cols) * weight[:, None]

    def reached(r):
        return np.linalg.norm(r[:3]) < tol and (measurement == "position" or np.linalg.norm(r[3:]) < tol * 1e-3 * ROTATION_WEIGHT_MM)

    if restarts is None:
        restarts = RESTARTS if measurement == "position" else RESTARTS_POSE
    rng = np.random.default_rng(0)
    starts = [_into_limits(np.asarray(seed, dtype=np.float64), lower, upper), 0.5 * (lower + upper)]
    starts += list(lower + (upper - lower) * rng.random((restarts, len(lower))))
    best = None
    for start in starts:
        q, r = bounded_lm(residual, jacobian, start, lower, upper, reached, max_iter)
        error = float(np.linalg.norm(r[:3]))
        if not np.isfinite(error):
            continue
        if reached(r):
            return q, error, "ok"
        if best is None or r @ r < best[2]:
            best = (q, error, r @ r)
    if best is None:
        return starts[0], float("nan"), "unreachable: the calibrated model's residual is not finite"
    return best[0], best[1], (f"unreachable within the joint limits: from {len(starts)} starts the calibrated model gets no closer than {best[1]:.3g} mm")


def nominal_seed(nominal: Robot, target: np.ndarray) -> np.ndarray:
    """The nominal model's solution within the limits (a start for the calibrated one)."""
    lower, upper = joint_limits(nominal)
    q, _, _ = solve_joints(nominal, target, 0.5 * (lower + upper))
    return q


def compensate(result, targets, *, angle_unit: Optional[str] = None) -> list[dict]:
    """Joint commands for every target (see the module notes).

    Parameters
    ----------
    result : path or dict
        A result file (:func:`robocal.results.load_result`).
    targets : path, array_like (m, 3 | 7) or Targets
        A targets CSV (:func:`read_targets`), target rows ``x, y, z`` [``qw, qx, qy, qz``] (mm),
        or :class:`Targets`.
    angle_unit : {"deg", "rad"}, optional
        Unit of the seed joint columns of a targets file (deg by default).

    Returns
    -------
    list of dict
        Per target, in order: ``row``, ``q`` (deg), ``correction`` (deg, against the seed),
        ``residual_mm`` (the calibrated model's distance to the target), ``status`` (which says
        when a joint lies beyond the range a joint map was fitted on).
    """
    calibrated, doc = load_result(result)
    nominal = Robot(calibrated.name, calibrated.joints, doc["robot_model"]["nominal"], mass_model=calibrated.mass_model)  # checked by load_result
    # The nominal model in the calibration's measurement frame: nominal kinematics, the
    # calibrated set-up (base frame, tool), as a user's controller would have it after a
    # base/tool calibration.
    setup = [k for k, n in enumerate(calibrated.param_names) if n.startswith(("base_", "tool_"))]
    nominal.params[setup] = calibrated.params[setup]
    if isinstance(targets, (str, os.PathLike)):
        targets = read_targets(targets, calibrated.n_joints, angle_unit)
    elif not isinstance(targets, Targets):  # an array of x, y, z [qw, qx, qy, qz] rows; shape checked by Targets
        y = as_float_array(targets, "targets")
        targets = Targets(y, None, np.arange(2, 2 + (len(y) if y.ndim else 0)))
    conventions = structure.parse_all(doc.get("structure", []), calibrated.n_joints)
    causes = doc.get("causes", [])
    offsets = joint_offsets(calibrated, causes)
    skipped = sorted({str(c.get("label", c.get("kind"))) for c in causes if c.get("kind") not in COMPENSABLE})
    note = f" (not compensated: {', '.join(skipped)})" if skipped else ""
    out = []
    for i, target in enumerate(targets.y):
        # Seeds and commands in the controller's convention; the model solves in its own.
        seed = targets.seeds[i] if targets.seeds is not None else structure.to_readings(nominal_seed(nominal, target)[None, :], conventions)[0]
        q, error, status = solve_joints(calibrated, target, structure.to_model(seed[None, :], conventions)[0], offsets=offsets)
        beyond = [m for m in map_coverage_report(causes, q[None, :]) if m["outside"]]
        q = structure.to_readings(q[None, :], conventions)[0]
        status += note if status == "ok" else ""
        if beyond:  # the map's correction only fades out there: the user must know
            status += "; beyond its map's data: " + ", ".join(f"joint {m['joint']} {uncovered_words(m)}" for m in beyond)
        out.append(
            {"row": int(targets.rows[i]), "q": np.degrees(q).tolist(), "correction": np.degrees(q - seed).tolist(), "residual_mm": error, "status": status}
        )
        logger.debug("compensate: target row %d: %s", targets.rows[i], status)
    return out


def write_joints(rows: list[dict], path, n_joints: int) -> Path:
    with Staged(path) as stage, stage.tmp.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["row"] + [f"q{j}" for j in range(1, n_joints + 1)] + [f"dq{j}" for j in range(1, n_joints + 1)] + ["residual_mm", "status"])
        for r in rows:
            w.writerow([r["row"]] + [f"{v:.6f}" for v in r["q"]] + [f"{v:.6f}" for v in r["correction"]] + [f"{r['residual_mm']:.3g}", r["status"]])
    return stage.path
