"""The physical model (stage 7 of :mod:`.select`): where the data leave the geometry undetermined,
a manufacturing-tolerance prior holds it near the drawing, kept only if held-out error allows.

:func:`judge_tolerance_prior` is the policy, shared by the single-session selection (every fold
scheme: :func:`physical_model`) and the multi-session one (leave-one-session-out:
:mod:`.sessions`).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Optional

import numpy as np

from ..calibration.problem import TOLERANCE, kinematic_prior_pairs
from ..calibration.result import CalibrationResult
from ..causes.problem import ExtendedProblem, judged_rmse, judged_unit, reported_rmse
from .state import Pass
from .validation import cross_validate, fit_problem


#: The tolerance prior may cost at most this fraction of held-out error: beyond it the data
#: contradict a physical geometry rather than leave it undetermined.
PRIOR_COST = 0.05


#: The tolerance prior's sigmas as the report states them.
TOLERANCE_SIGMAS = {"sigma_mm": TOLERANCE["mm"], "sigma_deg": float(np.degrees(TOLERANCE["rad"]))}


def judge_tolerance_prior(checks, measurement: str) -> dict:
    """The report entry of a tolerance prior on the kinematics, judged by its held-out errors:
    :data:`TOLERANCE_SIGMAS`, ``accepted`` and, per check, the held-out RMSE with the prior
    (:func:`~robocal.causes.problem.reported_rmse`); if it is not accepted, the ``reason``.

    ``checks`` yields, in order, ``(key, what, without, with_prior)``: the entry's key, the
    held-out error's name (``"random-fold held-out"``) and the squared errors
    (:func:`~robocal.causes.problem.squared_errors`) of ``measurement`` data without and with the prior. The prior
    is accepted if on every check its :func:`~robocal.causes.problem.judged_rmse` is within :data:`PRIOR_COST` of
    the model's without it; the first check where it is not ends the judging (a lazy ``checks``
    computes no more). Used by the single-session selection (every fold scheme) and the
    multi-session one (leave-one-session-out).
    """
    entry = {**TOLERANCE_SIGMAS, "accepted": False}
    for key, what, without, with_prior in checks:
        entry[key] = reported_rmse(with_prior)
        before, after = judged_rmse(without), judged_rmse(with_prior)
        if not after <= (1.0 + PRIOR_COST) * before:
            raised = f"the prior raises the {what} RMSE from {before:.4g} to {after:.4g} {judged_unit(measurement)}"
            entry["reason"] = f"{raised}: the data contradict a geometry within the tolerances; the unconstrained model is kept"
            return entry
    entry["accepted"] = True
    return entry


def physical_model(state: Pass) -> tuple[CalibrationResult, Optional[dict]]:
    """Stage 7: the final model made physical where the data leave the geometry undetermined.

    A fit whose kinematic parameters lie beyond the plausibility limits, or whose parameter
    combinations are wider than them (:meth:`CalibrationResult.undetermined`), is fitted again
    with a manufacturing-tolerance prior at nominal on every kinematic parameter
    (:data:`TOLERANCE`, weighted against the sensor's nominal noise): well-determined directions
    keep what the data say, the others stay near the drawing instead of running to metres. The
    prior is kept if its held-out error (on every fold scheme) is within
    :data:`PRIOR_COST` of the unconstrained model's; otherwise the data contradict a physical
    geometry, and the unconstrained model stays with its implausible parameters listed.

    Returns the final fit (the pass's model re-fitted, with the prior if it was kept) and the
    report entry of the prior (``None`` if the fit was physical already).
    """
    model, schemes, current_cv, fold_x = state.model, state.schemes, state.cv, state.fold_x
    fit = fit_problem(model, x0=state.x)
    state.x = fit.x
    if not fit.implausible() and not fit.undetermined():
        return fit, None
    robot = model.robot
    prior = kinematic_prior_pairs(robot, [robot.param_names[k] for k in model.free], dict(zip(robot.param_names, model.base.start)), TOLERANCE)
    physical = ExtendedProblem(replace(model.base, prior=prior), model.causes, model.full_data, model.idx)
    x0 = np.array([prior[n][0] if n in prior else v for n, v in zip(model.names, fit.x)])  # the kinematics from the drawing
    cv, fits = {}, {}

    def checks():
        for name, folds in schemes.items():  # random, blocked, then groups
            errors, fold_fits = cross_validate(physical, {name: folds}, fold_x, model)  # each fold from its own unconstrained fit
            cv[name], fits[name] = errors[name], fold_fits[name]
            yield f"rmse_heldout_{name}", f"{name}-fold held-out", current_cv[name], cv[name]

    entry = judge_tolerance_prior(checks(), model.data.measurement)
    if not entry["accepted"]:
        return fit, entry
    fit = fit_problem(physical, x0=x0)
    state.model, state.x, state.cv, state.fold_x = physical, fit.x, cv, fits
    return fit, entry
