"""Compensation: joint commands that make the calibrated robot reach desired tool positions.

``robocal compensate RESULT TARGETS.csv --out joints.csv`` reads a result file
(:mod:`robocal.results`) and a CSV of targets ``x, y, z`` (mm) — optionally ``qw, qx, qy, qz``
for full poses, and optionally the joint commands ``q1 … qN`` (deg) the nominal model would use,
which then seed the solution. Targets are in the frame the calibrated model predicts in: the
measurement frame of the calibration (the tracker's frame for tracker data, the robot base for
cable data).

For each target: a seed (the given joints, else the nominal model's inverse kinematics from the
middle of the joint ranges), then damped Gauss–Newton on the joint angles of the *calibrated*
model — with the joint causes of an extended model (``calibrate --causes``: compliance,
periodic gear errors, scale, coupling) applied to the commanded angles; backlash and sensor
causes are named in the status as not compensated — (Jacobian from the Rust core: ``∂h/∂q_j`` is the ``theta_j`` column). Position targets
leave three degrees of freedom of a 6-axis arm free: the damped steps take the smallest change
from the seed, so the tool keeps the seed's orientation as far as possible. A target is
reported unreachable — a row with its reason, never dropped — when the iteration does not get
within ``tol`` mm or leaves the joint limits.
"""

from __future__ import annotations

import argparse
import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from .core import as_float_array, solve_damped
from .diagnosis.candidates import COMPENSABLE, joint_offsets
from .data.table import numeric_columns, read_text, require_columns, split_delimited
from .exceptions import InvalidParameterError, ShapeError
from .outputs import Staged
from .results import load_result
from .robot import Robot


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


def read_targets(path, n_joints: int) -> Targets:
    """Targets from a CSV with ``x, y, z`` [``qw, qx, qy, qz``] [``q1..qN`` in deg]."""
    header, body = split_delimited(read_text(path), ",", path)
    require_columns(header, ["x", "y", "z"], path, "a targets file")
    pose = all(c in header for c in ("qw", "qx", "qy", "qz"))
    columns = ["x", "y", "z"] + (["qw", "qx", "qy", "qz"] if pose else [])
    values, rows, _ = numeric_columns(header, body, columns, path)
    joints = [f"q{j}" for j in range(1, n_joints + 1)]
    seeds = None
    if any(j in header for j in joints):
        require_columns(header, joints, path, "seed joints")
        seeds = np.radians(numeric_columns(header, body, joints, path)[0])
    return Targets(values, seeds, rows)


def _joint_columns(robot: Robot) -> list[int]:
    if any(j.kind != "revolute" for j in robot.joints):
        raise InvalidParameterError("compensation handles revolute joints only")
    return [robot.index(f"theta{j}") for j in range(1, robot.n_joints + 1)]


def solve_joints(robot: Robot, target: np.ndarray, seed: np.ndarray, tol: float = 1e-4, max_iter: int = 100, offsets=None) -> tuple[np.ndarray, float, str]:
    """Joint commands (rad) with which ``robot`` reaches ``target`` (xyz, or xyz + quaternion).

    ``offsets(q) -> Δq`` are joint causes of an extended model: the links take ``q + Δq(q)``
    (the Jacobian neglects ``∂Δq/∂q``, a relative change of order 1e-4).
    Returns ``(q, residual_mm, status)``; ``status`` is ``"ok"`` or the reason it is not.
    """
    measurement = "pose" if target.size == 7 else "position"
    cols = _joint_columns(robot)
    q = np.array(seed, dtype=np.float64)[None, :]
    y = target[None, :]
    lam = 1e-6

    def actual(q):
        return q if offsets is None else q + offsets(q)

    for _ in range(max_iter):
        r = robot.residuals(measurement, actual(q), y).ravel()
        error = float(np.linalg.norm(r[:3]))
        if error < tol and (measurement == "position" or np.linalg.norm(r[3:]) < tol * 1e-3):
            break
        J = robot.jacobian(measurement, actual(q), y=y, cols=cols)
        step, _ = solve_damped(J, r, lam, "identity")
        q = q + step[None, :]
    else:
        r = robot.residuals(measurement, actual(q), y).ravel()
    error = float(np.linalg.norm(r[:3]))
    lower = np.array([j.limits[0] for j in robot.joints])
    upper = np.array([j.limits[1] for j in robot.joints])
    # Revolute joints: the same pose modulo 2π; bring the solution into the limits if it can be.
    q0 = q[0] + 2.0 * np.pi * np.round((0.5 * (lower + upper) - q[0]) / (2.0 * np.pi))
    if error > tol or not np.all(np.isfinite(q0)):
        return q0, error, f"unreachable: the calibrated model gets no closer than {error:.3g} mm"
    outside = [f"q{j + 1}" for j in np.flatnonzero((q0 < lower - 1e-9) | (q0 > upper + 1e-9))]
    if outside:
        return q0, error, f"unreachable: the solution leaves the joint limits of {', '.join(outside)}"
    return q0, error, "ok"


def nominal_seed(nominal: Robot, target: np.ndarray) -> np.ndarray:
    """The nominal model's solution from the middle of the joint ranges (a start for the
    calibrated one)."""
    middle = np.array([0.5 * (j.limits[0] + j.limits[1]) for j in nominal.joints])
    q, _, _ = solve_joints(nominal, target, middle)
    return q


def compensate(result, targets) -> list[dict]:
    """Joint commands for every target (see the module notes).

    Parameters
    ----------
    result : path or dict
        A result file (:func:`robocal.results.load_result`).
    targets : path or Targets

    Returns
    -------
    list of dict
        Per target, in order: ``row``, ``q`` (deg), ``correction`` (deg, against the seed),
        ``residual_mm`` (the calibrated model's distance to the target), ``status``.
    """
    calibrated, doc = load_result(result)
    nominal = Robot(calibrated.name, calibrated.joints, doc["robot_model"]["nominal"])  # checked by load_result
    # The nominal model in the calibration's measurement frame: nominal kinematics, the
    # calibrated set-up (base frame, tool), as a user's controller would have it after a
    # base/tool calibration.
    setup = [k for k, n in enumerate(calibrated.param_names) if n.startswith(("base_", "tool_"))]
    nominal.params[setup] = calibrated.params[setup]
    if not isinstance(targets, Targets):
        targets = read_targets(targets, calibrated.n_joints)
    causes = doc.get("causes", [])
    offsets = joint_offsets(calibrated, causes)
    skipped = sorted({str(c.get("label", c.get("kind"))) for c in causes if c.get("kind") not in COMPENSABLE})
    note = f" (not compensated: {', '.join(skipped)})" if skipped else ""
    out = []
    for i, target in enumerate(targets.y):
        seed = targets.seeds[i] if targets.seeds is not None else nominal_seed(nominal, target)
        q, error, status = solve_joints(calibrated, target, seed, offsets=offsets)
        status += note if status == "ok" else ""
        out.append({"row": int(targets.rows[i]), "q": np.degrees(q).tolist(), "correction": np.degrees(q - seed).tolist(), "residual_mm": error, "status": status})
    return out


def write_joints(rows: list[dict], path, n_joints: int) -> Path:
    with Staged(path) as stage, stage.tmp.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["row"] + [f"q{j}" for j in range(1, n_joints + 1)] + [f"dq{j}" for j in range(1, n_joints + 1)] + ["residual_mm", "status"])
        for r in rows:
            w.writerow([r["row"]] + [f"{v:.6f}" for v in r["q"]] + [f"{v:.6f}" for v in r["correction"]] + [f"{r['residual_mm']:.3g}", r["status"]])
    return stage.path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("result", help="a result file of robocal calibrate (--out)")
    parser.add_argument("targets", help="CSV with x,y,z [qw,qx,qy,qz] [q1..qN in deg, the nominal commands]")
    parser.add_argument("--out", required=True, help="joints CSV: one row per target, joints in deg, corrections, residual, status")


def run(args: argparse.Namespace) -> int:
    rows = compensate(args.result, args.targets)
    n_joints = len(rows[0]["q"]) if rows else 0
    write_joints(rows, args.out, n_joints)
    bad = [r for r in rows if not r["status"].startswith("ok")]
    print(f"{len(rows) - len(bad)} of {len(rows)} targets reached (largest residual "
          f"{max((r['residual_mm'] for r in rows if r['status'] == 'ok'), default=float('nan')):.2g} mm); written to {args.out}")  # fmt: skip
    for r in bad[:10]:
        print(f"  row {r['row']}: {r['status']}")
    return 0 if not bad else 1
