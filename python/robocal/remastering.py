"""Re-mastering: which joints' zeros moved since a calibration, and by how much, from a dozen new points
(``robocal calibrate NEW --prior RESULT``, :func:`remaster`).

A joint's zero moves when a motor or an encoder is swapped, or after a collision; the rest of the
robot's geometry stays. A full calibration on ten or twenty points cannot see that: it re-estimates
dozens of parameters from as many readings, and a prior holding them near the result biases what
moved. Here the unknowns are only the new session's set-up (:func:`~robocal.robot.setup_names`:
the tracker's frame and the tool point, or the cable's anchor and zero; a new session places its
sensor anew) and each joint's zero change (:func:`~robocal.robot.zero_names`); everything else —
the result's parameters, its reading conventions and the causes on its joints
(:func:`~robocal.causes.result_model.result_model`) — is held at the result's values.

Which joints moved is a forward selection: from the set-up alone, the joint whose zero change lowers
the squared residuals most is named if that drop, in units of the reading's variance (a χ² of one
degree of freedom under no change), passes the χ² quantile of ``alpha / n`` — a Bonferroni bound over
the ``n`` joints the points can tell apart —, and so on until none passes. The variance is the
result's held-out error per reading (what its model errs by on new poses), not the few points'
own: a dozen points leave the set-up's fit too few degrees of freedom to measure it.

A zero change that the set-up reproduces exactly on these points (joint 1's zero against a tracker's
rotation about the base's z axis or a cable anchor's place; joint 6's against the tool point on a
tracker) cannot be told apart from it: such a joint is named as such, neither moved nor held.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Union

import numpy as np
from scipy.stats import chi2

from .calibration.api import load_inputs
from .calibration.lm import levenberg_marquardt
from .calibration.problem import Problem
from .calibration.sessions import setup_eliminated
from .causes.result_model import result_model
from .data.dataset import Dataset
from .data.identity import Fingerprint
from .exceptions import InvalidParameterError
from .kernels import as_positive
from .physics import DEG
from .results import file_sha256, load_result
from .robot import RESIDUAL_WIDTH, Robot, setup_names, zero_names

logger = logging.getLogger(__name__)

#: Default chance of naming any joint whose zero did not move (family-wise, over the joints).
ALPHA = 0.05


@dataclass
class Remastering:
    """What :func:`remaster` found.

    Attributes
    ----------
    document : dict
        The result with the new zeros applied and the new session's set-up (what ``verify``,
        ``compensate`` and ``export`` take), its ``remaster`` key the :attr:`report`.
    report : dict
        ``joints`` (each: ``joint``, ``name``, ``status`` — ``"moved"``, ``"held"`` or
        ``"indistinguishable"`` —, ``change`` and ``std`` in deg (mm for a prismatic joint; None
        where not estimated), ``detectable_std``: its standard deviation were it the only change,
        ``statistic`` of its last test, ``redundant_with``), ``threshold`` (the χ² a change had to
        pass), ``alpha``, ``noise_mm`` (the reading's standard deviation used) and where it comes
        from, ``setup`` (the set-up fitted), ``rmse`` (the set-up alone, and with the changes, mm),
        ``fit`` (the residuals' χ² against their degrees of freedom, and its p-value), ``samples``,
        ``data``, ``notes``.
    """

    document: dict
    report: dict

    def to_dict(self) -> dict:
        return self.document


def _noise(doc: dict, measurement: str, noise) -> tuple[float, str]:
    """The reading's standard deviation (mm) and where it comes from."""
    if noise is not None:
        return as_positive(noise, "noise"), "given"
    metrics = doc.get("metrics") or {}
    for key, words in (("test", "the result's held-out RMSE"), ("train", "the result's training RMSE")):
        figure = (metrics.get(key) or {}).get("rmse")
        if figure:
            # The RMSE is a point's distance: three readings of a position share it.
            return float(figure) / math.sqrt(min(RESIDUAL_WIDTH[measurement], 3)), f"{words} per reading"
    raise InvalidParameterError("the result records no RMSE to take the readings' noise from: pass `noise`")


def _fit(base: Problem, columns: list) -> tuple[np.ndarray, float, object]:
    """The problem of ``base``'s set-up and ``columns`` fitted: its full parameter vector, its
    squared weighted residuals and the fit."""
    problem = Problem(base.robot, base.data, free=np.array(sorted(set(base.free.tolist()) | set(columns)), dtype=int), start=base.start.copy())
    # To the tolerances, not the noise level: a 0.005° zero is below the noise of one reading.
    fit = levenberg_marquardt(problem, statistical_stop=False)
    r = problem.residuals(fit.x)
    return problem.full(fit.x), float(r @ r), fit


def _separable(base: Problem, zeros: list) -> tuple[dict, dict]:
    """Each zero's information once the set-up is eliminated, at the set-up's fit (the Schur
    complement's diagonal, in the weighted residuals' units), and for the zeros the set-up
    reproduces the set-up parameters that do (largest first)."""
    J = base.robot.jacobian(base.data.measurement, base.data.q, y=base.data.y, params=base.start, cols=list(base.free) + zeros) * base.row_weights[:, None]
    S, Z = J[:, : len(base.free)], J[:, len(base.free) :]
    rest, absorbed = setup_eliminated(S, Z)
    info, redundant = {}, {}
    for i, c in enumerate(zeros):
        if i in absorbed:
            redundant[c] = [base.names[k] for k in absorbed[i]]
        else:
            info[c] = float(rest[:, i] @ rest[:, i])
    return info, redundant


def remaster(
    result: Union[str, Path, dict],
    data: Union[str, Path, Dataset],
    *,
    measurement: Optional[str] = None,
    angle_unit: Optional[str] = None,
    alpha: float = ALPHA,
    noise: Optional[float] = None,
) -> Remastering:
    """The joints whose zero moved since the calibration ``result``, found on a few new points
    ``data`` (see the module notes).

    Parameters
    ----------
    result : path or dict
        A result file of ``robocal calibrate`` (:func:`robocal.results.load_result`).
    data : path or Dataset
        New measurements of the same robot, a new session (its set-up is fitted anew).
    measurement : {"cable", "position", "pose"}, optional
        Default: the result's.
    angle_unit : {"deg", "rad"}, optional
        Unit of a canonical file's joint columns.
    alpha : float
        The chance, in (0, 1), of naming a joint whose zero did not move (family-wise; Bonferroni).
    noise : float, optional
        The reading's standard deviation, mm (default: the result's held-out RMSE per reading).

    Returns
    -------
    Remastering

    Raises
    ------
    InvalidParameterError
        A malformed result, data of another robot or measurement, ``alpha`` outside (0, 1).
    DataError
        Data too few to place the sensor, or that cannot be readings of the robot.
    """
    if not (isinstance(alpha, (int, float)) and 0.0 < alpha < 1.0):
        raise InvalidParameterError(f"`alpha` must lie in (0, 1); got {alpha!r}")
    calibrated, doc = load_result(result)
    dataset, _ = load_inputs(data, calibrated, measurement or doc["measurement"], angle_unit)
    if dataset.measurement != doc["measurement"]:
        raise InvalidParameterError(f"the result is a {doc['measurement']} calibration; the data hold {dataset.measurement} measurements")
    sigma, sigma_from = _noise(doc, dataset.measurement, noise)
    model = result_model(calibrated, doc, dataset)
    links = model.links
    robot = calibrated
    # The set-up fitted with the result's robot, as verify does; a cable's hook on the tool is the robot's, kept.
    base = Problem.build(robot, links, mask=setup_names(robot, links.measurement), params=robot.params)
    held = [robot.index(n) for n in ("tool_x", "tool_y", "tool_z") if n not in base.names]
    base.start[held] = robot.params[held]
    base.require_dof("re-fitting the session set-up", "more points")
    start, rss0, _ = _fit(base, [])
    base.start = start
    zeros = [robot.index(n) for n in zero_names(robot)]
    info, redundant = _separable(base, zeros)
    candidates = list(info)
    threshold = float(chi2.isf(alpha / max(len(candidates), 1), 1))
    moved, statistic, rss = [], {}, rss0
    params, fit = start, None
    while len(moved) < len(candidates):
        trials = {c: _fit(base, moved + [c]) for c in candidates if c not in moved}
        for c, (_, trial_rss, _) in trials.items():
            statistic[c] = (rss - trial_rss) / sigma**2
        best = max(trials, key=lambda c: statistic[c])
        if statistic[best] <= threshold:
            break
        moved.append(best)
        params, rss, fit = trials[best]
    rows = len(links) * RESIDUAL_WIDTH[links.measurement]
    dof = rows - len(base.free) - len(moved)
    std = {}
    if fit is not None:
        J = fit.problem.jacobian(fit.x)
        cov = np.linalg.pinv(J.T @ J) * sigma**2
        std = {c: float(math.sqrt(cov[i, i])) for i, c in enumerate(fit.problem.free) if c in moved}
    entries = []
    for j, c in enumerate(zeros, start=1):
        name = robot.param_names[c]
        unit = 1.0 / DEG if robot.param_units[c] == "rad" else 1.0
        status = "moved" if c in moved else "indistinguishable" if c in redundant else "held"
        entries.append(
            {
                "joint": j,
                "name": name,
                "unit": "deg" if unit != 1.0 else robot.param_units[c],
                "status": status,
                "change": float((params[c] - robot.params[c]) * unit) if c in moved else None,
                "std": std[c] * unit if c in std else None,
                "detectable_std": sigma / math.sqrt(info[c]) * unit if c in info else None,
                "statistic": statistic.get(c),
                "redundant_with": redundant.get(c, []),
            }
        )
    p_value = float(chi2.sf(rss / sigma**2, dof)) if dof > 0 else None
    notes = list(dataset.notes)
    if p_value is not None and p_value < alpha:
        notes.append(
            f"the residuals are larger than the result's noise (χ² {rss / sigma**2:.1f} on {dof} degrees of freedom, p = {p_value:.2g}): "
            "more than joint zeros changed — a calibration is due"
        )
    setup = {n: float(params[robot.index(n)]) for n in base.names}
    report = {
        "joints": entries,
        "alpha": float(alpha),
        "threshold": threshold,
        "noise_mm": sigma,
        "noise_from": sigma_from,
        "setup": setup,
        "rmse": {"setup_alone": _rmse(rss0, len(links)), "remastered": _rmse(rss, len(links))},
        "fit": {"chi2": rss / sigma**2, "dof": dof, "p_value": p_value},
        "samples": len(links),
        "data": dataset.source,
        "sha256": file_sha256(dataset.source) if dataset.source else None,
        "fingerprint": Fingerprint.of(model.read).to_dict(),
        "result": None if isinstance(result, dict) else str(result),
        "notes": notes,
    }
    logger.info("remaster: %d samples, moved %s", len(links), [robot.param_names[c] for c in moved])
    return Remastering(_document(doc, robot, params, std, [robot.index(n) for n in base.names] + moved, report), report)


def _rmse(rss: float, samples: int) -> float:
    """The RMS of a sample's residual norm (eq. (28)'s RMSE) from the squared residuals."""
    return math.sqrt(rss / max(samples, 1))


def _document(doc: dict, robot: Robot, params: np.ndarray, std: dict, changed: list, report: dict) -> dict:
    """The result ``doc`` with ``params``' values of the ``changed`` columns (the new set-up and zeros)."""
    out = dict(doc)
    parameters = []
    for c, p in enumerate(doc["parameters"]):
        if c in changed:
            p = {**p, "value": float(params[c]), "deviation": float(params[c]) - p["nominal"]}
            if c in std:  # the new zero is the old one plus the change: their errors add
                p["std"] = math.sqrt((p.get("std") or 0.0) ** 2 + std[c] ** 2)
        parameters.append(p)
    out["parameters"] = parameters
    out["remaster"] = report
    return out
