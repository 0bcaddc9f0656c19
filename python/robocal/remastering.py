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
the χ² of the residuals most is named if that drop (a χ² of one degree of freedom under no change)
passes the χ² quantile of ``alpha / n`` — a Bonferroni bound over the ``n`` joints the points can
tell apart —, and so on until none passes.

The χ² weighs the residuals by the readings' covariance ``V = σ² I + J_r C J_rᵀ``. ``σ`` is the
result's held-out error per reading (what its model errs by on new poses), not the few points' own:
a dozen points leave the set-up's fit too few degrees of freedom to measure it. ``C`` is the
covariance of the robot's parameters the result estimated (its training samples read again, its
session's set-up eliminated), ``J_r`` their Jacobian on the new points: the result's own error, the
same on every pose that sees it, which would otherwise pass for a zero's change — measured on the
simulated UR10 of ``benches/bench_remaster.py``, it is as large as the sensor's noise on poses
beyond the calibration's path. Where the training data cannot be read (a result of data in
memory, or of several sessions), it is not counted, and the report says so.

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
from scipy.linalg import solve_triangular
from scipy.stats import chi2

from .calibration.api import load_inputs
from .calibration.metrics import metrics
from .calibration.problem import Problem, fit_row_weights
from .calibration.lm import levenberg_marquardt
from .calibration.sessions import schur_complement, setup_eliminated
from .causes.result_model import result_model
from .data.dataset import Dataset
from .data.identity import Fingerprint
from .exceptions import InvalidParameterError
from .kernels import as_positive
from .physics import DEG
from .results import load_result, recorded_source, unread_training
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
        from, ``result_error_counted`` (whether the result's own covariance entered), ``setup`` (the set-up fitted), ``rmse`` (the set-up alone, and with the changes, mm),
        ``fit`` (the residuals' χ² against their degrees of freedom, and its p-value), ``samples``,
        ``data``, ``sha256`` and ``fingerprint`` (``verify`` recognises the points), ``notes``.
    """

    document: dict
    report: dict

    def to_dict(self) -> dict:
        """The re-mastered result document (:attr:`document`), as ``CalibrationResult.to_dict`` gives a result's."""
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


def _result_covariance(doc: dict, robot: Robot, angle_unit) -> tuple[list, Optional[np.ndarray], Optional[str]]:
    """The columns of the robot's parameters the result estimated and their covariance, from its
    training samples read again (its file and rows) and linearised at the result, its session's
    set-up eliminated (the Schur complement) and scaled by its residual variance; or no columns,
    None and why not."""
    if doc.get("sessions"):
        return [], None, "the result is a fit of several sessions: its own error is not counted — a joint may be named for what its calibration missed"
    d = doc.get("dataset") or {}
    why = unread_training([d])
    if why is not None:
        return [], None, f"the result's own error is not counted — {why}: a joint may be named for what its calibration missed"
    data, _ = load_inputs(d["source"], robot, doc["measurement"], angle_unit)
    train = result_model(robot, doc, data).links
    train = train.subset(np.flatnonzero(np.isin(train.rows, d["rows_used"])))
    setup = [robot.index(n) for n in setup_names(robot, train.measurement)]
    own = [robot.index(n) for n in doc.get("free", []) if n in robot.param_names and robot.index(n) not in setup]
    # Fitted again from the result's values: a result re-mastered or monitored since holds a later session's set-up
    # and moved zeros, at which its training residuals were another session's (a tracker 116 mm away: the robot's
    # covariance 10⁶ times too large, and a re-mastering from it named no change of 0.5°).
    problem = Problem(robot, train, np.asarray(own + setup, dtype=int), robot.params.copy())
    params = problem.full(levenberg_marquardt(problem, with_std=False).x)
    w = fit_row_weights(train)
    J = robot.jacobian(train.measurement, train.q, y=train.y, params=params, cols=own + setup) * w[:, None]
    r = robot.residuals(train.measurement, train.q, train.y, params=params).ravel() * w
    s2 = float(r @ r) / max(r.size - len(own) - len(setup), 1)
    G = J.T @ J
    n = len(own)
    # The information is positive semi-definite (schur_complement), its pseudo-inverse too: a covariance must be, or
    # σ²I + J C Jᵀ may not be (pose data's rotation rows, weighed 200 mm/rad, made rounding errors of C count).
    return own, s2 * np.linalg.pinv(schur_complement(G, range(n), range(n, len(G))), rcond=1e-12, hermitian=True), None


@dataclass
class _Whitened:
    """The new points' residuals and Jacobians whitened by the readings' covariance ``V = L Lᵀ``
    (rows weighted as a fit weighs them): squared whitened residuals are a χ²."""

    robot: Robot
    data: Dataset
    weights: np.ndarray
    L: np.ndarray

    def residuals(self, params: np.ndarray) -> np.ndarray:
        r = self.robot.residuals(self.data.measurement, self.data.q, self.data.y, params=params).ravel() * self.weights
        return solve_triangular(self.L, r, lower=True)

    def jacobian(self, params: np.ndarray, cols: list) -> np.ndarray:
        J = self.robot.jacobian(self.data.measurement, self.data.q, y=self.data.y, params=params, cols=cols) * self.weights[:, None]
        return solve_triangular(self.L, J, lower=True)


#: Gauss-Newton steps of a re-mastering fit at most; it stops once no step moves a parameter by
#: more than :data:`STEP_TOLERANCE` (mm, rad).
STEPS = 20
STEP_TOLERANCE = 1e-12


def _fit(model: _Whitened, start: np.ndarray, cols: list) -> tuple[np.ndarray, float, np.ndarray]:
    """``cols`` fitted from ``start`` by Gauss-Newton on the whitened residuals (the start is the
    set-up's own fit and a zero's change hundredths of a degree: no damping needed): the
    parameters, the χ² and the covariance of ``cols``."""
    p = start.copy()
    for _ in range(STEPS):
        step, *_ = np.linalg.lstsq(model.jacobian(p, cols), model.residuals(p), rcond=None)
        p[cols] += step
        if np.max(np.abs(step)) < STEP_TOLERANCE:
            break
    r, J = model.residuals(p), model.jacobian(p, cols)
    return p, float(r @ r), np.linalg.pinv(J.T @ J, hermitian=True)


def _separable(model: _Whitened, params: np.ndarray, setup: list, zeros: list) -> tuple[dict, dict]:
    """Each zero's information once the set-up is eliminated (the Schur complement's diagonal, in
    whitened units), and for the zeros the set-up reproduces the set-up parameters that do."""
    J = model.jacobian(params, setup + zeros)
    rest, absorbed = setup_eliminated(J[:, : len(setup)], J[:, len(setup) :])
    names = model.robot.param_names
    info = {c: float(rest[:, i] @ rest[:, i]) for i, c in enumerate(zeros) if i not in absorbed}
    return info, {zeros[i]: [names[setup[k]] for k in by] for i, by in absorbed.items()}


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
        Unit of a canonical file's joint columns (the new data's and the result's training data's).
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
    robot, doc = load_result(result)
    dataset, _ = load_inputs(data, robot, measurement or doc["measurement"], angle_unit)
    if dataset.measurement != doc["measurement"]:
        raise InvalidParameterError(f"the result is a {doc['measurement']} calibration; the data hold {dataset.measurement} measurements")
    sigma, sigma_from = _noise(doc, dataset.measurement, noise)
    modelled = result_model(robot, doc, dataset)
    links = modelled.links
    # The set-up fitted with the result's robot, as verify does; a cable's hook on the tool is the robot's, kept.
    base = Problem.build(robot, links, mask=setup_names(robot, links.measurement), params=robot.params)
    held = [robot.index(n) for n in ("tool_x", "tool_y", "tool_z") if n not in base.names]
    base.start[held] = robot.params[held]
    base.require_dof("re-fitting the session set-up", "more points")
    setup = [int(c) for c in base.free]
    own, C, why = _result_covariance(doc, robot, angle_unit)
    weights = fit_row_weights(links)
    V = sigma**2 * np.eye(len(weights))
    if C is not None:
        Jr = robot.jacobian(links.measurement, links.q, y=links.y, params=base.start, cols=own) * weights[:, None]
        V += Jr @ C @ Jr.T
    model = _Whitened(robot, links, weights, np.linalg.cholesky(V))
    start, chi0, _ = _fit(model, base.start, setup)
    zeros = [robot.index(n) for n in zero_names(robot)]
    info, redundant = _separable(model, start, setup, zeros)
    candidates = list(info)
    threshold = float(chi2.isf(alpha / max(len(candidates), 1), 1))
    moved, statistic, chi, params, cov = [], {}, chi0, start, None
    while len(moved) < len(candidates):
        trials = {c: _fit(model, start, setup + moved + [c]) for c in candidates if c not in moved}
        for c, (_, trial, _) in trials.items():
            statistic[c] = chi - trial
        best = max(trials, key=lambda c: statistic[c])
        if statistic[best] <= threshold:
            break
        moved.append(best)
        params, chi, cov = trials[best]
    std = {c: float(math.sqrt(cov[len(setup) + i, len(setup) + i])) for i, c in enumerate(moved)}
    dof = len(weights) - len(setup) - len(moved)
    entries = []
    for j, c in enumerate(zeros, start=1):
        unit = 1.0 / DEG if robot.param_units[c] == "rad" else 1.0
        entries.append(
            {
                "joint": j,
                "name": robot.param_names[c],
                "unit": "deg" if unit != 1.0 else robot.param_units[c],
                "status": "moved" if c in moved else "indistinguishable" if c in redundant else "held",
                "change": float((params[c] - robot.params[c]) * unit) if c in moved else None,
                "std": std[c] * unit if c in std else None,
                "detectable_std": unit / math.sqrt(info[c]) if c in info else None,
                "statistic": statistic.get(c),
                "redundant_with": redundant.get(c, []),
            }
        )
    p_value = float(chi2.sf(chi, dof)) if dof > 0 else None

    # The figures are of the set-up's least-squares fit, as verify's: the χ² fit lets the set-up leave
    # residuals where the result's own error is large (20 points of another HSR session: 0.087 mm
    # "with the set-up alone" where verify stated 0.024 mm on the same points).
    plain = _Whitened(robot, links, weights, np.eye(len(weights)))

    def rmse(p):
        p = _fit(plain, p, setup)[0]
        return metrics(robot.residuals(links.measurement, links.q, links.y, params=p), links.measurement)["rmse"]

    figures = {"setup_alone": rmse(start), "remastered": rmse(params)}
    notes = list(dataset.notes) + ([why] if why else [])
    if p_value is not None and p_value < alpha:
        worse = figures["remastered"] > figures["setup_alone"]
        notes.append(
            f"the residuals are larger than the result's noise and error (χ² {chi:.1f} on {dof} degrees of freedom, p = {p_value:.2g}): "
            "more than joint zeros changed — a calibration is due"
            + ("; re-mastered, the RMSE is even larger than with the set-up alone: the zeros found are not to be trusted" if worse and moved else "")
        )

    data_file = recorded_source(dataset.source)
    report = {
        "joints": entries,
        "alpha": float(alpha),
        "threshold": threshold,
        "noise_mm": sigma,
        "noise_from": sigma_from,
        "result_error_counted": C is not None,
        "setup": {robot.param_names[c]: float(params[c]) for c in setup},
        "rmse": figures,
        "fit": {"chi2": chi, "dof": dof, "p_value": p_value},
        "samples": len(links),
        "data": data_file["source"],
        "sha256": data_file["sha256"],
        "fingerprint": Fingerprint.of(modelled.read).to_dict(),  # verify recognises these points: they are no held-out data
        "result": None if isinstance(result, dict) else str(result),
        "notes": notes,
    }
    logger.info("remaster: %d samples, moved %s", len(links), [robot.param_names[c] for c in moved])
    return Remastering(_document(doc, params, std, setup + moved, report), report)


def _document(doc: dict, params: np.ndarray, std: dict, changed: list, report: dict) -> dict:
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
