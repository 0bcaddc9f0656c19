"""What a calibration result already knows: the prior of a plan for a new session of a calibrated
robot (``result=``, ``--from RESULT``).

A result with causes is a model of hundreds of entries (the UR10 of series A and B with joint maps
on every joint: 700 of the robot), which a session of 60 poses cannot fit anew. Its entries are
the result's — its estimated parameters, its causes, each joint map on the range, knots and gaps
it was fitted on (the cause's ``detail``), a parameter redundant with a new session's set-up left
to the set-up (:func:`_result_mask`) — and what the result knows is the prior ``M_0``
(:func:`_result_information`): its training samples read again (each session's file and rows, as
the result records them), re-linearised with the plan's model, each old session's set-up and
sensor terms eliminated (a Schur complement: the new session places its sensor anew), weighed by
the result's training residual so that ``σ² M_0⁻¹`` is the result's covariance of the robot's
entries. The plan then chooses the poses by what they add to it."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from ..calibration.api import load_inputs
from ..calibration.lm import levenberg_marquardt
from ..calibration.problem import Problem
from ..calibration.sessions import SESSION_KINDS, is_private, schur_complement
from ..causes import structure
from ..causes.extended import extended_problem
from ..kernels import is_sparse
from ..results import unread_training
from ..robot import RESIDUAL_WIDTH, Robot, setup_names
from .design import _Design


@dataclass
class _Known:
    """What a calibration result already knows of the robot (:func:`_result_information`): the
    information of its training data on the design's entries (scaled columns; the set-up's and
    the old sessions' own terms eliminated: zero there), their joint angles (model's), how many,
    and a note on why it is not used (then ``M`` is None)."""

    M: Optional[np.ndarray]
    q: Optional[np.ndarray]
    samples: int
    noise: float
    why: Optional[str] = None


def _result_mask(doc: dict, robot: Robot, measurement: str) -> list[str]:
    """The parameters a result estimated (its ``free``, each session's set-up once) and the whole
    set-up: the robot's parameters it held fixed as redundant with its sessions' set-ups stay
    fixed, so that a new session's set-up is free and the robot's entries are the result's."""
    free = {name.split(" [session")[0] for name in doc.get("free", [])}
    return [n for n in robot.param_names if n in free or n in setup_names(robot, measurement)]


def _training_sessions(doc: dict) -> list[dict]:
    """A result's training sessions as its ``sessions`` lists them (a fit on several), or its one
    ``dataset`` with the session terms among its causes."""
    if doc.get("sessions"):
        return doc["sessions"]
    d = doc.get("dataset") or {}
    terms = [c.get("label", c.get("kind")) for c in doc.get("causes", []) if c.get("kind") in SESSION_KINDS]
    return [{"source": d.get("source"), "sha256": d.get("sha256"), "rows_used": d.get("rows_used"), "setup": None, "terms": terms}]


def _result_information(doc: dict, robot: Robot, params: np.ndarray, design: _Design, structures: list, sigma: float, angle_unit) -> _Known:
    """What the result ``doc`` knows of the robot's entries of ``design``, in the plan's units:
    its training samples (each session's file and rows) re-linearised at the calibrated robot
    (each session at its own set-up) with the design's model — the same entries, the maps on the
    result's knots —, each session's own columns (its set-up, its sensor terms) eliminated by the
    Schur complement ``G_rr − G_rs G_ss⁺ G_sr`` (a new session places its sensor anew), summed and
    weighed by ``(σ / s)²``: ``s`` the result's training residual per reading (its weighted
    residuals' ``√(Σr² / (rows − entries))``, as its covariance; else from its RMSE), so that
    ``σ² M⁻¹`` is the result's own covariance of those entries (its residuals, larger than the
    sensor's noise where the model misses something, are what its figures rest on)."""
    measurement = doc["measurement"]
    sessions = _training_sessions(doc)
    noise = float(doc["metrics"]["train"]["rmse"]) / math.sqrt(min(RESIDUAL_WIDTH[measurement], 3))  # the RMSE is a position's norm: 3 readings
    why = unread_training(sessions)
    if why is not None:
        return _Known(None, None, 0, noise, f"the result's information is not used — {why}: the plan counts only what its poses (and the data) measure")
    at = {n: i for i, n in enumerate(design.names)}
    cols = np.array(sorted(set(design.base_free.tolist()) | {robot.index(n) for n in setup_names(robot, measurement)}), dtype=int)
    M = np.zeros((len(design.names),) * 2)
    angles, squares, rows = [], 0.0, 0
    fitted = {(c.get("label"), c.get("session")): c.get("coefficients") for c in doc.get("causes", [])}
    for number, s in enumerate(sessions, start=1):
        data, _ = load_inputs(s["source"], robot, measurement, angle_unit)
        data = structure.apply_all(data, structures)  # the readings in the model's angles, as the fit read them
        idx = np.flatnonzero(np.isin(data.rows, s["rows_used"]))
        if len(idx) != len(s["rows_used"]):
            lost = f"{len(s['rows_used']) - len(idx)} of its training rows are not in {s['source']}"
            return _Known(None, None, 0, noise, f"the result's information is not used — {lost}: the plan counts only what its poses (and the data) measure")
        p = params.copy()
        for name, value in (s.get("setup") or {}).items():
            p[robot.index(name)] = value
        base = Problem(robot, data.subset(idx), free=cols, start=p)
        model = extended_problem(base, data, idx, design.labels + list(s.get("terms", [])), every=False, noise=sigma, fitted=design.fitted)
        known = _result_x(model, fitted, number)
        # The training data's own fit from the result's values (as robocal.remastering's covariance does): a result
        # re-mastered or monitored since holds a later session's set-up, at which these residuals were metres.
        x = model.x0 if known is None else levenberg_marquardt(model, x0=known, with_std=False).x
        J = model.jacobian(x)[: len(idx) * model.k]  # the data rows: the maps' roughness is the design's prior, counted once
        G = J.T @ J
        G = G.toarray() if is_sparse(G) else np.asarray(G)
        names = model.names
        own = np.array([n in at and not is_private(n, measurement) for n in names])  # the rest is this session's: eliminated
        r, e = np.flatnonzero(own), np.flatnonzero(~own)
        to = [at[names[i]] for i in r]
        M[np.ix_(to, to)] += schur_complement(G, r, e)
        angles.append(data.q[idx])
        if known is not None and squares is not None:
            weighted = model.data_residuals(x) * model.row_weights  # as the fit weighs them (pose data's rotation rows)
            squares, rows = squares + float(weighted @ weighted), rows + weighted.size
        else:
            squares = None
    if squares is not None and rows > len(doc.get("free", [])):  # the result's own residual variance (its covariance's)
        noise = math.sqrt(squares / (rows - len(doc["free"])))
    M *= (sigma / noise) ** 2 / np.outer(design.scale, design.scale)
    q = np.vstack(angles)
    return _Known(M, q, len(q), noise)


def _result_x(model, fitted: dict, session: int) -> Optional[np.ndarray]:
    """The result's values of ``model``'s entries (its parameters at the model's start, each
    cause's coefficients from ``fitted``: ``(label, session or None) -> coefficients``), or None
    where the result lacks one."""
    x = model.x0
    for cause, at in zip(getattr(model, "causes", []), getattr(model, "slices", [])):
        if cause.stage == "parameters":
            continue
        values = fitted.get((cause.label, session), fitted.get((cause.label, None)))
        if values is None or len(values) != at.stop - at.start:
            return None
        x[at] = values
    return x
