"""``robocal.calibrate``: a calibration with the geometric model or, given ``causes``, with an
extended model — the diagnosed causes fitted together with the geometry.

It sits above both the calibration (the geometric fit, :func:`robocal.calibration.calibrate`) and
the diagnosis (the causes, :class:`~robocal.diagnosis.model.ExtendedProblem`) and is what
:func:`robocal.calibrate` names.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Optional, Union

import numpy as np

from ..calibration import api
from ..calibration.lm import levenberg_marquardt
from ..calibration.metrics import metrics
from ..calibration.problem import Problem
from ..calibration.result import CalibrationResult
from ..data.dataset import Dataset
from ..exceptions import InvalidParameterError
from ..robot import Robot
from ..robot_file import read_document
from . import structure
from .candidates import MAP_LABEL, library, map_candidate, map_noise, step_candidate
from .model import ExtendedProblem
from .wander import wander_candidate


def calibrate(
    data: Union[str, Path, Dataset],
    robot: Union[str, Robot, None] = None,
    measurement: Optional[str] = None,
    method: str = "lm",
    test_fraction: float = 0.2,
    seed: int = 0,
    mask=None,
    prior=None,
    bounds=None,
    kinematic_prior=None,
    causes=None,
    angle_unit: Optional[str] = None,
    **options,
) -> CalibrationResult:
    """Calibrates ``robot`` on ``data`` and evaluates it on a held-out random split.

    Parameters
    ----------
    data : path or Dataset
        A measurement file (canonical CSV or a public dataset, see :func:`robocal.data.load`)
        or a :class:`Dataset`.
    robot : str or Robot, optional
        Default: the robot recorded in the data.
    measurement : {"cable", "position", "pose"}, optional
        For files that can provide more than one (the UR10 tracker files: ``pose`` or ``position``).
    method : str
        One of :data:`METHODS`.
    test_fraction : float
        Share of samples held out (seeded random split); 0 fits on everything.
    seed : int
        Seeds the held-out split and the draws of the stochastic methods (``pso``, ``de``,
        ``bas``, ``rbf``): equal seeds give bit-identical results.
    mask : optional
        Parameters to consider (default: the robot's default mask for the measurement).
    prior : dict, optional
        ``name -> (mean, sigma)`` Gaussian priors (mm / rad) on estimated parameters (see
        :class:`Problem`); Kalman filters take them as their prior mean and covariance.
    bounds : dict, optional
        ``name -> (lower, upper)`` hard limits (mm / rad) on estimated parameters, kept by every
        method (projected LM steps; Kalman estimates clipped after each sweep; the
        metaheuristics' search box intersected with them).
    kinematic_prior : (float, float), optional
        ``(mm, deg)`` Gaussian prior at nominal on every estimated kinematic parameter (see
        :meth:`Problem.build`).
    causes : list of str, dict or path, optional
        An extended model: cause labels as ``robocal diagnose`` reports them (e.g.
        ``"joint_periodic joint 2 harmonic=3"``, ``"joint_sign joint 4"``), or a diagnose report
        (dict or JSON file) whose causes — and the tolerance prior of its final model, unless
        ``kinematic_prior`` is given — are taken. Reading conventions (``joint_zero``,
        ``joint_sign``, ``joint_reference``) transform the joint readings before the fit. Fitted with the geometric parameters by ``method="lm"``; the result
        JSON then has ``causes`` with their physical parameters.
    angle_unit : {"deg", "rad"}, optional
        Unit of the joint columns of a canonical file (degrees by default; values implausible
        for the default unit are refused, see :func:`robocal.data.load`).
    **options
        Passed to the method.

    Returns
    -------
    CalibrationResult
        ``to_dict()`` is the result JSON (``method``, ``parameters``, ``metrics`` with ``train``
        and ``test``, ...).
    """
    if causes is None:
        return api.calibrate(data, robot, measurement, method, test_fraction, seed, mask, prior, bounds, kinematic_prior, angle_unit, **options)
    api.check_method(method)
    test_fraction = api.check_test_fraction(test_fraction)
    dataset, r = api.load_inputs(data, robot, measurement, angle_unit)
    labels, reported_prior = read_causes(causes)
    kinematic_prior = reported_prior if kinematic_prior is None else kinematic_prior
    parsed = [(label, structure.parse(label, r.n_joints)) for label in labels]
    structures = [s for _, s in parsed if s is not None]
    labels = [label for label, s in parsed if s is None]
    dataset = structure.apply_all(dataset, structures)  # the readings in the model's convention
    problem, train_idx, test_idx = api.held_out_problem(r, dataset, test_fraction, seed, mask=mask, prior=prior, bounds=bounds, kinematic_prior=kinematic_prior)
    if method != "lm":
        raise InvalidParameterError(f"an extended model (causes) is fitted by method 'lm' only; got {method!r}")
    model = extended_problem(problem, dataset, train_idx, labels)
    result = levenberg_marquardt(model, **api.checked_options(levenberg_marquardt, method, options))
    result.structure = [s.label for s in structures]
    if test_idx is not None:
        test = dataset.subset(test_idx)
        result.metrics["test"] = metrics(model.with_samples(test_idx).data_residuals(result.x), test.measurement)
        result.held_out = test
    return result


def read_causes(causes) -> tuple[list[str], Optional[tuple]]:
    """Cause labels from labels, a diagnose report (dict) or its JSON file — the report's
    reading conventions (``model.structure``) first, then its ``model.causes`` — and the
    report's tolerance prior ``(mm, deg)`` on the kinematics, if its final model has one."""
    if isinstance(causes, (str, Path)) and str(causes).endswith(".json"):
        causes = read_document(causes, "diagnose report")
    prior = None
    if isinstance(causes, dict):
        try:
            prior = causes["model"].get("kinematic_prior")
            causes = list(causes["model"].get("structure", [])) + list(causes["model"]["causes"])
        except (KeyError, TypeError, AttributeError):
            raise InvalidParameterError("a diagnose report needs model.causes (the JSON of `robocal diagnose --json`)") from None
    if isinstance(causes, str):
        causes = [causes]
    if not isinstance(causes, (list, tuple)) or not all(isinstance(c, str) for c in causes):
        raise InvalidParameterError(f"`causes` must be cause labels, a diagnose report or its JSON file; got {causes!r}")
    return list(causes), None if prior is None else tuple(prior)


def extended_problem(problem: Problem, dataset: Dataset, idx: np.ndarray, causes: list[str]):
    """``problem`` extended by the causes labelled ``causes`` on the samples ``idx`` of
    ``dataset`` (bases such as backlash and drift need the whole sequence)."""
    pool = {c.label: c for c in library(problem.robot, dataset, list(problem.names) + list(problem.fixed))}
    noise = None
    for label in causes:  # steps sit where diagnose found them, maps span the fitted samples: their label says how
        step = re.fullmatch(r"step sample=(\d+) row=\d+", label)
        if step:
            pool[label] = step_candidate(dataset, int(step.group(1)))
        wander = re.fullmatch(r"wander spacing=([0-9.]+)", label)
        if wander:  # the session's own wander, refitted on these data (a term of the session, never carried)
            pool[label] = wander_candidate(dataset, float(wander.group(1)))
        joint_map = MAP_LABEL.fullmatch(label)
        if joint_map and 1 <= int(joint_map.group(1)) <= problem.robot.n_joints:
            if noise is None:  # the roughness is weighed against the geometric fit's residuals
                geometric = levenberg_marquardt(problem)
                noise = map_noise(problem.data_residuals(geometric.x).reshape(len(problem.data), -1))
            j = int(joint_map.group(1)) - 1
            pool[label] = map_candidate(dataset, j, float(joint_map.group(2)), float(joint_map.group(3)), noise, dataset.q[idx, j])
    unknown = [c for c in causes if c not in pool]
    if unknown:
        raise InvalidParameterError(f"unknown causes {unknown} for these data; known: {sorted(pool)[:6]} ... ({len(pool)} in all)")
    return ExtendedProblem(problem, [pool[c] for c in causes], dataset, idx)
