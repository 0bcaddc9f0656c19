"""Validation report of a measurement file or :class:`~robocal.data.Dataset`: bad cells, duplicate
rows, joint angles outside the limits or implausible for the unit, measurement outliers against a
robust fit of the nominal model, and the cross-check of redundant columns.

The report is a plain (JSON-serialisable) dict (``robocal inspect`` renders it,
:mod:`robocal.cli.inspect`). Row numbers are rows of the source file (header = row 1). It sits
above the calibration: the outliers are judged against a fit by the production
Levenberg-Marquardt.
"""

from __future__ import annotations

import math
from typing import Optional

import numpy as np

from .calibration.api import another_robot
from .calibration.lm import levenberg_marquardt
from .calibration.problem import Problem, start_parameters
from .kernels import as_float
from .data.dataset import Dataset, angle_unit_check
from .data.loader import detect_format, load
from .exceptions import DataError, InvalidParameterError, RobocalError
from .geometry import frame_params, homogeneous, matrix_from_quaternion
from .robot import robot as load_robot
from .stats import robust_sigma

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
        identical values), ``out_of_limits`` (``{row, joint, value, limits, unit}``),
        ``angle_unit`` (``{unit, plausible, message}``), ``fit`` (the robust nominal-model fit
        and its ``outliers``, ``{"error": message}`` when the data cannot be fitted — counted as a problem — or
        None), ``cross_check`` (D2's controller x, y, z against the
        nominal forward kinematics, or None), ``another_robot`` (why the data are probably not of
        the robot: :func:`robocal.calibration.api.another_robot`, or None) and ``problems`` (the number of findings).
    """
    sigmas = as_float(sigmas, "sigmas")
    if not (np.isfinite(sigmas) and sigmas > 0):  # 0 or less calls every sample an outlier
        raise InvalidParameterError(f"`sigmas`, the outlier threshold in robust standard deviations, must be finite and > 0; got {sigmas:g}")
    if isinstance(source, Dataset):
        dataset, fmt, unit = source, None, "rad"
    else:
        fmt = format or detect_format(source)
        options = dict(measurement=measurement, angle_unit=angle_unit, robot=robot)
        dataset = load(source, format=fmt, exclude_bad_rows=True, check_units=False, **options)  # bad rows and units: reported below
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
        "angle_unit": angle_unit_check(dataset.q, unit, dataset.rows, dataset.prismatic),
        "out_of_limits": out_of_limits(dataset, model) if model else [],
        "fit": _fit_or_error(dataset, model, sigmas) if model else None,
        "cross_check": cross_check(dataset, model) if model and "controller_xyz" in dataset.extra else None,
    }
    # The robust fit holds the kinematics nominal: its set-up absorbs much of another robot's
    # geometry, and its inliers' RMS has no bound that tells a worn robot from another one.
    report["another_robot"] = another_robot(model, dataset) if report["fit"] and "error" not in report["fit"] else None
    report["problems"] = (
        len(report["bad_cells"])
        + len(report["duplicates"])
        + len(report["out_of_limits"])
        + (not report["angle_unit"]["plausible"])
        + (len(report["fit"].get("outliers", [])) + ("error" in report["fit"]) if report["fit"] else 0)  # a failed fit is a finding
        + (len(report["cross_check"]["inconsistent"]) if report["cross_check"] else 0)
        + (report["another_robot"] is not None)
    )
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
    """``{row, joint, value, limits, unit}`` for every joint value outside the robot's limits, in
    the file's units: deg, mm for a prismatic joint."""
    found = []
    for j, joint in enumerate(robot.joints):
        lower, upper = joint.limits
        unit, shown = ("mm", float) if joint.kind == "prismatic" else ("deg", lambda v: float(np.degrees(v)))
        for k in np.flatnonzero((dataset.q[:, j] < lower) | (dataset.q[:, j] > upper)):
            found.append({"row": int(dataset.rows[k]), "joint": j + 1, "value": shown(dataset.q[k, j]), "limits": [shown(lower), shown(upper)], "unit": unit})
    return sorted(found, key=lambda f: (f["row"], f["joint"]))


# -- the robust nominal-model fit --------------------------------------------------------------
def _setup_problem(dataset: Dataset, robot) -> Problem:
    """The measurement set-up under the NOMINAL kinematics, as a calibration problem: the
    sensor's (cable) or the frames' (tracker) parameters, their identifiable subset."""
    if dataset.measurement == "cable":
        return Problem.build(robot, dataset, mask=["anchor_x", "anchor_y", "anchor_z", "cable_offset", "tool_x", "tool_y", "tool_z"])
    names = [f"base_{c}" for c in ("x", "y", "z", "rx", "ry", "rz")] + ["tool_x", "tool_y", "tool_z"]
    params = None
    if dataset.measurement == "pose":  # the tool rotation starts at the mean of what the poses imply
        from scipy.spatial.transform import Rotation

        params = start_parameters(robot, dataset)
        flange = robot.fkine(dataset.q, params=params)[:, :3, :3]
        measured = matrix_from_quaternion(dataset.y[:, 3:7])
        tool_rotation = Rotation.from_matrix(np.swapaxes(flange, 1, 2) @ measured).mean().as_matrix()  # flange -> tool, averaged
        rx = robot.index("tool_rx")
        params[rx : rx + 3] = frame_params(homogeneous(tool_rotation, np.zeros(3)))[3:]
        names += ["tool_rx", "tool_ry", "tool_rz"]
    return Problem.build(robot, dataset, mask=names, params=params)


def _pooled(sigmas: np.ndarray) -> float:
    """One σ for the report from per-component σ: their root mean square."""
    return float(np.sqrt(np.mean(sigmas**2)))


def robust_fit(dataset: Dataset, robot, sigmas: float = OUTLIER_SIGMAS) -> dict:
    """Fits the measurement set-up to the data under the NOMINAL kinematics, robustly.

    The set-up starts where every calibration starts (:func:`~robocal.calibration.problem.start_parameters`:
    cable anchor and sensor zero in closed form, tracker base frame by Kabsch; for poses the tool
    rotation from the mean implied rotation); only its identifiable subset is fitted, by the
    production Levenberg-Marquardt with a Huber loss (:func:`~robocal.calibration.lm.levenberg_marquardt`).
    Samples whose residual, each component standardised by its own robust scale
    (:func:`robocal.stats.robust_sigma`), has a norm beyond ``sigmas`` are outliers.

    Returns
    -------
    dict
        ``fitted`` (name -> value; mm, rad), ``not_identifiable`` (names held at their start),
        ``scale`` (robust sigma: ``cable_mm``, or ``position_mm`` — the RMS of the x, y, z
        components' — and ``rotation_deg`` for poses), ``threshold`` (sigmas), ``iterations``, ``outliers``
        (``{row, residual_mm[, rotation_deg], sigmas}``, largest first) and ``rms_mm`` of the inliers.
    """
    problem = _setup_problem(dataset, robot)
    fit = levenberg_marquardt(problem, loss="huber")
    r = problem.data_residuals(fit.x).reshape(len(dataset), -1)
    k = r.shape[1]
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
        "fitted": dict(zip(problem.names, map(float, fit.x))),
        "not_identifiable": list(problem.fixed),
        "scale": {"position_mm" if k > 1 else "cable_mm": _pooled(s[: min(k, 3)])} | ({"rotation_deg": float(np.degrees(_pooled(s[3:])))} if k == 6 else {}),
        "threshold": float(sigmas),
        "iterations": fit.nit,
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
        "inconsistent": [
            {
                "row": int(dataset.rows[i]),
                "difference_mm": diff[i].round(3).tolist(),
                "norm_mm": float(np.linalg.norm(diff[i])),
                "bound_mm": bound[i].round(3).tolist(),
                "ratio": float(ratio[i]),
            }
            for i in bad
        ],
    }
