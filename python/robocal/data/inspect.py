"""Validation report of a measurement file or :class:`~robocal.data.Dataset`: bad cells, duplicate
rows, joint angles outside the limits or implausible for the unit, measurement outliers against a
robust fit of the nominal model, and the cross-check of redundant columns.

The report is a plain (JSON-serialisable) dict; :func:`format_report` renders it for humans and
:func:`add_arguments` / :func:`run` make it the ``robocal inspect`` subcommand. Row numbers are
rows of the source file (header = row 1).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Optional

import numpy as np

from ..core import identifiability, solve_damped
from ..exceptions import DataError, RobocalError
from ..outputs import write_json
from ..stats import robust_sigma
from .dataset import Dataset, angle_unit_check
from .public import FORMATS, detect_format, load

#: Residuals beyond this many robust sigmas are reported as outliers.
OUTLIER_SIGMAS = 5.0
#: D2 rounding: joint angles to 0.1 deg, controller positions to 0.1 mm (half of each is the bound).
JOINT_ROUNDING_DEG = 0.1
POSITION_ROUNDING_MM = 0.1


def inspect(
    source,
    robot: Optional[str] = None,
    format: Optional[str] = None,
    angle_unit: Optional[str] = None,
    measurement: Optional[str] = None,
    sigmas: float = OUTLIER_SIGMAS,
) -> dict:
    """Validates a measurement file (any format :func:`robocal.data.load` reads) or a dataset.

    Parameters
    ----------
    source : str, Path or Dataset
        A file is read with ``exclude_bad_rows=True``: rows with bad cells are reported, not fatal.
    robot : str, optional
        Robot name or file; the dataset's own by default. Without one, the limit checks and the
        model fit are skipped.
    format, angle_unit, measurement
        Passed to :func:`robocal.data.load` for a file.
    sigmas : float
        Outlier threshold in robust standard deviations.

    Returns
    -------
    dict
        ``source``, ``format``, ``robot``, ``measurement``, ``rows`` (count), ``notes`` (reader's),
        ``bad_cells`` (list of ``{row, column, reason}``), ``duplicates`` (lists of rows with
        identical values), ``out_of_limits`` (``{row, joint, value_deg, limits_deg}``),
        ``angle_unit`` (``{unit, plausible, message}``), ``fit`` (the robust nominal-model fit
        and its ``outliers``, or None), ``cross_check`` (D2's controller x, y, z against the
        nominal forward kinematics, or None) and ``problems`` (the number of findings).
    """
    from ..robot import robot as load_robot

    if isinstance(source, Dataset):
        dataset, fmt, unit = source, None, "rad"
    else:
        fmt = format or detect_format(source)
        dataset = load(source, fmt, measurement, angle_unit, robot, exclude_bad_rows=True, check_units=False)  # reported below
        unit = angle_unit or {"ipa": "rad"}.get(fmt, "deg")
    name = robot or dataset.robot
    model = load_robot(name) if name else None
    if model is not None and model.n_joints != dataset.n_joints:
        raise DataError(f"robot {name!r} has {model.n_joints} joints; the data have {dataset.n_joints}", dataset.source)
    report = {
        "source": dataset.source,
        "format": fmt,
        "robot": name,
        "measurement": dataset.measurement,
        "rows": len(dataset),
        "notes": list(dataset.notes),
        "bad_cells": [{"row": int(e["row"]), "column": e.get("column"), "reason": e["reason"]} for e in dataset.excluded],
        "duplicates": duplicate_rows(dataset),
        "angle_unit": angle_unit_check(dataset.q, unit, dataset.rows),
        "out_of_limits": out_of_limits(dataset, model) if model else [],
        "fit": _fit_or_error(dataset, model, sigmas) if model else None,
        "cross_check": cross_check(dataset, model) if model and "controller_xyz" in dataset.extra else None,
    }
    report["problems"] = (
        len(report["bad_cells"]) + len(report["duplicates"]) + len(report["out_of_limits"]) + (not report["angle_unit"]["plausible"])
        + (len(report["fit"].get("outliers", [])) if report["fit"] else 0)
        + (len(report["cross_check"]["inconsistent"]) if report["cross_check"] else 0)
    )  # fmt: skip
    return report


def _fit_or_error(dataset: Dataset, model, sigmas: float) -> dict:
    """The robust fit, or ``{"error": message}`` when the data cannot determine it."""
    try:
        return robust_fit(dataset, model, sigmas)
    except (RobocalError, np.linalg.LinAlgError) as exc:
        return {"error": f"{type(exc).__name__}: {exc}"}


# -- table checks --------------------------------------------------------------------------------
def duplicate_rows(dataset: Dataset) -> list[list[int]]:
    """Groups of rows with identical joint values and observations (and side columns)."""
    table = np.hstack([dataset.q, dataset.y] + [v.reshape(len(dataset), -1) for v in dataset.extra.values()])
    _, inverse, counts = np.unique(table, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    groups = [dataset.rows[inverse == g].tolist() for g in np.flatnonzero(counts > 1)]
    return sorted(groups)


def out_of_limits(dataset: Dataset, robot) -> list[dict]:
    """``{row, joint, value_deg, limits_deg}`` for every joint value outside the robot's limits."""
    found = []
    for j, joint in enumerate(robot.joints):
        lower, upper = joint.limits
        for k in np.flatnonzero((dataset.q[:, j] < lower) | (dataset.q[:, j] > upper)):
            found.append({"row": int(dataset.rows[k]), "joint": j + 1, "value_deg": float(np.degrees(dataset.q[k, j])),
                          "limits_deg": [float(np.degrees(lower)), float(np.degrees(upper))]})  # fmt: skip
    return sorted(found, key=lambda f: (f["row"], f["joint"]))


# -- the robust nominal-model fit --------------------------------------------------------------
def _start(dataset: Dataset, robot) -> tuple[np.ndarray, list[str]]:
    """Starting parameters and the names to fit: the sensor's (cable) or the frames' (tracker)."""
    from ..core import cable_initial_guess
    from ..reference import frame_params

    params = robot.params.copy()
    T = robot.fkine(dataset.q)
    if dataset.measurement == "cable":
        anchor, offset = cable_initial_guess(T[:, :3, 3], dataset.y[:, 0])
        params[[robot.index(f"anchor_{c}") for c in "xyz"]] = anchor
        params[robot.index("cable_offset")] = offset
        return params, ["anchor_x", "anchor_y", "anchor_z", "cable_offset", "tool_x", "tool_y", "tool_z"]
    base = np.eye(4)  # Kabsch: measured ≈ R · flange + t
    p, y = T[:, :3, 3], dataset.y[:, :3]
    pc, yc = p - p.mean(0), y - y.mean(0)
    U, _, Vt = np.linalg.svd(yc.T @ pc)
    base[:3, :3] = U @ np.diag([1, 1, np.linalg.det(U @ Vt)]) @ Vt
    base[:3, 3] = y.mean(0) - base[:3, :3] @ p.mean(0)
    params[robot.index("base_x") : robot.index("base_x") + 6] = frame_params(base)
    names = [f"base_{c}" for c in ("x", "y", "z", "rx", "ry", "rz")] + ["tool_x", "tool_y", "tool_z"]
    if dataset.measurement == "pose":
        from scipy.spatial.transform import Rotation

        measured = Rotation.from_quat(dataset.y[:, [4, 5, 6, 3]]).as_matrix()
        tool = np.eye(4)
        tool[:3, :3] = Rotation.from_matrix(np.swapaxes(T[:, :3, :3], 1, 2) @ base[:3, :3].T @ measured).mean().as_matrix()
        params[robot.index("tool_rx") : robot.index("tool_rx") + 3] = frame_params(tool)[3:]
        names += ["tool_rx", "tool_ry", "tool_rz"]
    return params, names


def _pooled(sigmas: np.ndarray) -> float:
    """One σ for the report from per-component σ: their root mean square."""
    return float(np.sqrt(np.mean(sigmas**2)))


def robust_fit(dataset: Dataset, robot, sigmas: float = OUTLIER_SIGMAS, iterations: int = 100) -> dict:
    """Fits the measurement set-up to the data under the NOMINAL kinematics, robustly.

    Cable: anchor, sensor zero and tool point from :func:`robocal.cable_initial_guess`; position /
    pose: base frame from a Kabsch alignment of flange and measured positions, the tool point (and
    rotation). Only the identifiable subset of these is fitted. Then Levenberg-Marquardt on
    Huber-weighted residuals (per sample, each component standardised by its own robust scale,
    :func:`robocal.stats.robust_sigma`), re-weighting at every step until the step vanishes. Samples whose
    standardised residual norm exceeds ``sigmas`` are outliers.

    Returns
    -------
    dict
        ``fitted`` (name -> value; mm, rad), ``not_identifiable`` (names held at their start),
        ``scale`` (robust sigma: ``cable_mm``, or ``position_mm`` — the RMS of the x, y, z
        components' — and ``rotation_deg`` for poses), ``threshold`` (sigmas), ``iterations``, ``outliers``
        (``{row, residual_mm[, rotation_deg], sigmas}``, largest first) and ``rms_mm`` of the inliers.
    """
    from scipy.stats import chi2

    params, names = _start(dataset, robot)
    cols = [robot.index(n) for n in names]
    J = robot.jacobian(dataset.measurement, dataset.q, dataset.y, params, cols)
    keep = sorted(identifiability(J)["identifiable"])
    cols = [cols[i] for i in keep]
    y = dataset.y
    r = robot.residuals(dataset.measurement, dataset.q, y, params)
    m, k = r.shape
    c = math.sqrt(chi2.ppf(0.95, k))  # Huber threshold on the standardised norm of one sample

    def whitened(r, s):
        z = np.linalg.norm(r / s, axis=1)
        w = np.sqrt(np.minimum(1.0, c / np.maximum(z, 1e-300)))
        return w, (r / s * w[:, None]).ravel()

    lam, done = 1e-3, 0
    for done in range(1, iterations + 1):
        s = robust_sigma(r)
        w, rw = whitened(r, s)
        J = robot.jacobian(dataset.measurement, dataset.q, y, params, cols)
        Jw = J * np.tile(1 / s, m)[:, None] * np.repeat(w, k)[:, None]
        cost = rw @ rw
        while True:
            delta, _ = solve_damped(Jw, rw, lam)
            trial = params.copy()
            trial[cols] += delta
            r_trial = robot.residuals(dataset.measurement, dataset.q, y, trial)
            rt = (r_trial / s * w[:, None]).ravel()
            if rt @ rt <= cost or lam > 1e8:
                break
            lam *= 10
        params, r, lam = trial, r_trial, max(lam / 10, 1e-9)
        if np.all(np.abs(delta) <= 1e-10 * (1 + np.abs(params[cols]))) or (cost - rt @ rt) <= 1e-12 * cost:
            break
    s = robust_sigma(r)
    z = np.linalg.norm(r / s, axis=1)  # standardised residual norm of each sample
    outliers = []
    for i in np.argsort(-z):
        if z[i] <= sigmas:
            break
        entry = {"row": int(dataset.rows[i]), "residual_mm": float(np.linalg.norm(r[i, :3]) if k > 1 else r[i, 0]), "sigmas": float(z[i])}
        if k == 6:
            entry["rotation_deg"] = float(np.degrees(np.linalg.norm(r[i, 3:])))
        outliers.append(entry)
    inliers = z <= sigmas
    return {
        "fitted": {robot.param_names[j]: float(params[j]) for j in cols},
        "not_identifiable": [n for i, n in enumerate(names) if i not in keep],
        "scale": {"position_mm" if k > 1 else "cable_mm": _pooled(s[: min(k, 3)])} | ({"rotation_deg": float(np.degrees(_pooled(s[3:])))} if k == 6 else {}),
        "threshold": float(sigmas),
        "iterations": done,
        "rms_mm": float(np.sqrt(np.mean(r[inliers, : min(k, 3)] ** 2) * min(k, 3))),
        "outliers": outliers,
    }


# -- redundant columns ---------------------------------------------------------------------------
def cross_check(dataset: Dataset, robot) -> dict:
    """Controller-reported x, y, z (``extra["controller_xyz"]``) against the nominal flange
    position FK(q).

    A row is inconsistent when any axis differs by more than the rounding explains: half a
    :data:`JOINT_ROUNDING_DEG` step on every joint propagated through the position Jacobian
    (``sum_i |dP/dq_i| * 0.05 deg``) plus half a :data:`POSITION_ROUNDING_MM` step.

    Returns
    -------
    dict
        ``rows_checked``, ``median_mm`` (median |FK - controller|), ``inconsistent``
        (``{row, difference_mm: [dx, dy, dz], norm_mm, bound_mm: [bx, by, bz], ratio}``, worst first).
    """
    controller = dataset.extra["controller_xyz"]
    fk = robot.predict("position", dataset.q)
    theta = [robot.index(f"theta{j}") for j in range(1, robot.n_joints + 1)]
    dP = robot.jacobian("position", dataset.q, cols=theta).reshape(len(dataset), 3, robot.n_joints)
    bound = np.abs(dP).sum(axis=2) * math.radians(JOINT_ROUNDING_DEG / 2) + POSITION_ROUNDING_MM / 2
    diff = fk - controller
    ratio = (np.abs(diff) / bound).max(axis=1)
    bad = [i for i in np.argsort(-ratio) if ratio[i] > 1]
    return {
        "rows_checked": len(dataset),
        "median_mm": float(np.median(np.linalg.norm(diff, axis=1))),
        "inconsistent": [{"row": int(dataset.rows[i]), "difference_mm": diff[i].round(3).tolist(), "norm_mm": float(np.linalg.norm(diff[i])),
                          "bound_mm": bound[i].round(3).tolist(), "ratio": float(ratio[i])} for i in bad],  # fmt: skip
    }


# -- presentation and CLI ------------------------------------------------------------------------
def _first(items: list, limit: int) -> list:
    return items[:limit] if limit else items


def format_report(report: dict, limit: int = 20) -> str:
    """The report as text for humans, at most ``limit`` entries per list (0: all)."""
    lines = [f"{report['source'] or 'dataset'}: {report['rows']} {report['measurement']} samples"
             + (f" ({report['format']} format)" if report["format"] else "") + f", robot {report['robot'] or 'not given'}"]  # fmt: skip
    lines += [f"  note: {n}" for n in report["notes"]]
    lines.append(f"  bad cells: {len(report['bad_cells'])}")
    lines += [f"    row {e['row']}, column {e['column']!r}: {e['reason']}" for e in _first(report["bad_cells"], limit)]
    lines.append(f"  duplicate rows: {len(report['duplicates'])} groups")
    lines += [f"    rows {g}" for g in _first(report["duplicates"], limit)]
    lines.append(f"  angle unit: {report['angle_unit']['message']}")
    lines.append(f"  outside joint limits: {len(report['out_of_limits'])}")
    lines += [f"    row {e['row']}, q{e['joint']} = {e['value_deg']:.3f} deg (limits {e['limits_deg'][0]:g}..{e['limits_deg'][1]:g})"
              for e in _first(report["out_of_limits"], limit)]  # fmt: skip
    fit = report["fit"]
    if fit and "error" in fit:
        lines.append(f"  robust nominal-model fit not possible: {fit['error']}")
        fit = None
    if fit:
        scale = ", ".join(f"{k} {v:.4g}" for k, v in fit["scale"].items())
        lines.append(f"  robust nominal-model fit ({', '.join(fit['fitted'])}): robust sigma {scale}; inlier rms {fit['rms_mm']:.4g} mm")
        if fit["not_identifiable"]:
            lines.append(f"    not identifiable from these data, held at nominal: {fit['not_identifiable']}")
        lines.append(f"  outliers beyond {fit['threshold']:g} sigma: {len(fit['outliers'])}")
        lines += [f"    row {e['row']}: residual {e['residual_mm']:.3f} mm" + (f", {e['rotation_deg']:.4f} deg" if "rotation_deg" in e else "")
                  + f" ({e['sigmas']:.1f} sigma)" for e in _first(fit["outliers"], limit)]  # fmt: skip
    check = report["cross_check"]
    if check:
        lines.append(f"  controller x,y,z vs FK(q): median {check['median_mm']:.3f} mm; {len(check['inconsistent'])} of "
                     f"{check['rows_checked']} rows beyond rounding")  # fmt: skip
        lines += [f"    row {e['row']}: FK - controller = {e['difference_mm']} mm (|.| {e['norm_mm']:.2f}; bound {e['bound_mm']}, {e['ratio']:.1f}x)"
                  for e in _first(check["inconsistent"], limit)]  # fmt: skip
    lists = [report["bad_cells"], report["duplicates"], report["out_of_limits"], fit["outliers"] if fit else [], check["inconsistent"] if check else []]
    if limit and any(len(items) > limit for items in lists):
        lines.append(f"  (lists show their first {limit} entries; the JSON report has all)")
    lines.append(f"  problems found: {report['problems']}")
    return "\n".join(lines)


def add_arguments(parser) -> None:
    """Arguments of ``robocal inspect``."""
    parser.add_argument("path", help="measurement file (canonical CSV, D1/D2 .xlsx or CSV, D3 tracker CSV)")
    parser.add_argument("--robot", help="built-in robot name or robot file (default: the format's robot)")
    parser.add_argument("--format", choices=FORMATS, help="file format (default: detected from the content)")
    parser.add_argument("--angle-unit", choices=("deg", "rad"), help="unit of canonical q columns (default deg)")
    parser.add_argument("--measurement", choices=("cable", "position", "pose"), help="observation to read")
    parser.add_argument("--sigmas", type=float, default=OUTLIER_SIGMAS, help="outlier threshold in robust sigmas (default %(default)s)")
    parser.add_argument("--json", metavar="OUT", help="also write the report as JSON to OUT ('-' for stdout)")
    parser.add_argument("--strict", action="store_true", help="exit with status 1 when problems are found")


def run(args) -> int:
    """Runs ``robocal inspect``; returns the exit status."""
    report = inspect(args.path, args.robot, args.format, args.angle_unit, args.measurement, args.sigmas)
    if args.json == "-":
        print(json.dumps(report, indent=2))
    else:
        print(format_report(report))
        if args.json:
            write_json(args.json, report)
    return 1 if args.strict and report["problems"] else 0
