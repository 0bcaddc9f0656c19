"""``robocal verify``: a calibration result evaluated on new measurements of the same robot.

The honest test of a calibration — and of every cause it models — is a measurement set it never
saw. ``verify`` applies what the result says about the *robot*: its calibrated parameters, the
reading conventions of its joints (``structure``) and the causes acting on its joints
(compliance, gear errors, scale, coupling, backlash) with their fitted coefficients. It re-fits
only what belongs to the new *session* (:func:`~robocal.robot.setup_names`): the
tracker's base frame and the tool point, or the cable's anchor and zero. The old session's own
terms (a step of its sensor's zero, its drift, its outliers) are not carried. Beside the
calibrated model's eq. (28) metrics it reports the nominal model's on the same data, set-up
and tool point fitted (:func:`~robocal.calibration.api.nominal_residuals`, the figure the report
shows too): what the calibration gains where it was not fitted; and the acceptance
figures of ISO 9283 (:mod:`robocal.acceptance`). The model is the one ``robocal report`` draws
(:func:`~robocal.causes.result_model.result_model`).
"""

from __future__ import annotations

import logging

from pathlib import Path
from typing import Optional, Union

import numpy as np

from .acceptance import iso9283
from .calibration.api import load_inputs, nominal_residuals
from .calibration.lm import levenberg_marquardt
from .calibration.metrics import metrics
from .calibration.problem import Problem
from .calibration.result import VERDICTS, verdict
from .causes.result_model import result_model
from .data.dataset import Dataset
from .data.identity import Fingerprint
from .results import file_sha256, load_result
from .serial_robot import Robot, setup_names

logger = logging.getLogger(__name__)

SCHEMA = "robocal.verify/1"
#: Readings the calibrated model reproduces within this (mm, every reading) are its own predictions
#: (a plan's expected readings, simulated data), not measurements: no sensor resolves 1 nm.
OWN_PREDICTION_MM = 1e-6


def _refit_setup(robot: Robot, data: Dataset) -> tuple[np.ndarray, dict, list[str]]:
    """Residuals (m, k) of ``robot`` on ``data`` with only the session set-up fitted, the
    set-up found and the names fitted."""
    names = setup_names(robot, data.measurement)
    problem = Problem.build(robot, data, mask=names)
    problem.require_dof("re-fitting the session set-up", "more samples: a figure with none would be 0 whatever the calibration")
    # The closed-form start also moves a cable's tool point: the calibrated one is kept.
    held = [robot.index(n) for n in ("tool_x", "tool_y", "tool_z") if n not in names]
    problem.start[held] = robot.params[held]
    fit = levenberg_marquardt(problem)
    return problem.data_residuals(fit.x).reshape(len(data), -1), dict(zip(problem.names, map(float, fit.x))), problem.names


def _seen_by_fit(doc: dict, dataset: Dataset, read: Dataset) -> tuple[bool, list[str]]:
    """Whether ``dataset`` is new samples, and notes when it is not or in part: samples a fit of
    ``doc`` was trained on (in its ``dataset``, one of its ``sessions`` or a re-mastering's points), recognised by their
    content in any order or encoding (the recorded :class:`~robocal.data.identity.Fingerprint`,
    compared with ``read``, the samples in the model's reading convention as the fit saw them);
    for a result without a fingerprint, by the file's SHA-256."""
    digest = file_sha256(dataset.source) if dataset.source else None
    partly = []
    sessions = [(f"session {k} of the calibration", s) for k, s in enumerate(doc.get("sessions") or [], start=1)]
    # A re-mastered result's points (robocal.remastering) fitted its zeros and set-up: no held-out figure either.
    for which, fitted in [("the calibration's data", doc.get("dataset")), *sessions, ("the re-mastering's points", doc.get("remaster"))]:
        fitted = fitted if isinstance(fitted, dict) else {}
        recorded = Fingerprint.from_dict(fitted.get("fingerprint"))
        if recorded is not None:
            overlap = recorded.overlap(read)
            if overlap.same:
                return False, [
                    f"these are not new samples: {overlap.count} of the {len(dataset)} samples are training samples of {which} "
                    "(the same joint values and readings, in any order or file encoding), so these figures are no held-out error"
                ]
            if overlap.count:
                partly.append(
                    f"{overlap.count} of the {len(dataset)} samples are training samples of {which} (the same joint values and readings): "
                    "these figures are in part a training error"
                )
        elif digest is not None and fitted.get("sha256") == digest:  # a result written before fingerprints: the file's bytes
            used = len(fitted.get("rows_used") or [])
            return False, [
                f"these are not new samples: {dataset.source} is a file the result was calibrated on (same SHA-256); "
                f"{used} of its rows trained the fit, so these figures are no held-out error"
            ]
    return True, partly


def verify(
    result: Union[str, Path, dict],
    data: Union[str, Path, Dataset],
    *,
    measurement: Optional[str] = None,
    angle_unit: Optional[str] = None,
) -> dict:
    """Evaluates a calibration ``result`` on new measurements ``data`` (see the module notes).

    Parameters
    ----------
    result : path or dict
        A result file of ``robocal calibrate`` (:func:`robocal.results.load_result`).
    data : path or Dataset
        New measurements of the same robot (any format :func:`robocal.data.load` reads).
    measurement : {"cable", "position", "pose"}, optional
        Default: the result's (a tracker file read as positions for a position calibration).
    angle_unit : {"deg", "rad"}, optional
        Unit of a canonical file's joint columns.

    Returns
    -------
    dict
        ``held_out`` (False when half or more of ``data``'s samples trained the calibration, in any
        order or file encoding; or, for a result without a fingerprint, it is its file) and ``notes`` (why, and what
        reading the data noticed: a robot named by the data other than the result's),
        ``metrics`` (``rmse, mae, max, n``, mm) of the calibrated model, ``metrics_covered``
        (the same over the samples every joint map covers; None if none is), ``refit`` (the set-up
        names fitted on ``data``) and ``setup`` (their values), ``nominal`` (the nominal model's
        ``metrics`` and ``metrics_covered``), ``applied`` (``structure`` and ``causes`` labels), ``not_applied``
        (``{label, reason}``), ``coverage`` (per joint map: the samples beyond its fitted range,
        :func:`~robocal.causes.candidates.map_coverage_report`), ``iso9283`` (the acceptance
        figures of the calibrated model, :func:`robocal.acceptance.iso9283`: position,
        orientation and distance accuracy, repeatability), ``robot``, ``measurement``,
        ``samples``, ``data`` (its source).
    """
    calibrated, doc = load_result(result)
    dataset, _ = load_inputs(data, calibrated, measurement or doc["measurement"], angle_unit)
    model = result_model(calibrated, doc, dataset)
    residuals, setup, refit = _refit_setup(calibrated, model.links)
    logger.info("verify: %d samples, the session set-up re-fitted (%s)", len(dataset), ", ".join(refit) if isinstance(refit, list) else refit)
    nominal = nominal_residuals(model.nominal, model.read)
    covered = model.covered
    held_out, seen = _seen_by_fit(doc, dataset, model.read)
    not_held = "these data trained it, so they cannot bear it out"
    if held_out and np.max(np.abs(residuals)) < OWN_PREDICTION_MM:
        held_out, not_held = False, "these readings are its own predictions, not measurements, so they cannot bear it out"
        seen = seen + [
            f"these readings are what the calibrated model predicts, within {OWN_PREDICTION_MM:g} mm at every sample: they are not "
            "measurements (a plan's expected readings not yet overwritten with the sensor's?), so these figures say nothing of the robot"
        ]
    here, before = (metrics(r, dataset.measurement)["rmse"] for r in (residuals, nominal))
    return {
        "verdict": _verdict_here(doc, here, before, held_out, not_held),
        "held_out": held_out,
        "notes": seen + list(dataset.notes),  # and what the reader and load_inputs noticed (data naming another robot)
        "schema": SCHEMA,
        "robot": calibrated.name,
        "measurement": dataset.measurement,
        "samples": len(dataset),
        "data": dataset.source,
        "result": None if isinstance(result, dict) else str(result),
        "metrics": metrics(residuals, dataset.measurement),
        # Where every joint map applies (the joints within the ranges they were fitted on):
        # what the maps can do, apart from the samples they cannot correct.
        "metrics_covered": metrics(residuals[covered], dataset.measurement) if covered.any() else None,
        "refit": refit,
        "setup": setup,
        "nominal": {
            "metrics": metrics(nominal, dataset.measurement),
            "metrics_covered": metrics(nominal[covered], dataset.measurement) if covered.any() else None,
        },
        "applied": model.applied,
        "not_applied": model.not_applied,
        # Joint maps correct nothing beyond the range they were fitted on.
        "coverage": model.coverage(),
        "iso9283": iso9283(residuals, model.read.y, model.read.q, dataset.measurement, covered=covered, rows=model.read.rows),
    }


def _verdict_here(doc: dict, rmse: float, nominal_rmse: float, held_out: bool, not_held: str) -> dict:
    """The result's verdict (:func:`~robocal.calibration.result.verdict`) as these data bear it
    out: a calibration that predicts new data worse than the nominal robot is not determined;
    ``not_held`` says why data that are not held out cannot bear it out."""
    word, why = verdict(doc)
    if held_out and rmse > nominal_rmse:
        word, why = VERDICTS[2], f"on these new data it predicts worse than the nominal robot (RMSE {rmse:.4g} against {nominal_rmse:.4g} mm); {why}"
    elif held_out:
        why += f"; on these new data RMSE {rmse:.4g} mm against the nominal robot's {nominal_rmse:.4g} mm"
    else:
        why += f"; {not_held}"
    return {"verdict": word, "why": why}
