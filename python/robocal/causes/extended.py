"""``robocal.calibrate``: a calibration with the geometric model or, given ``causes``, with an
extended model — the diagnosed causes fitted together with the geometry — on one session or on
several at once (one robot; each session with its own set-up and its own sensor terms).

It sits above both the calibration (the geometric fit, :mod:`robocal.calibration.api`) and the
cause model (:class:`~robocal.causes.problem.ExtendedProblem`) and is what
:func:`robocal.calibrate` names: its arguments are checked here once, then the fit is dispatched.
"""

from __future__ import annotations

import difflib
import logging
import re
from pathlib import Path
from typing import Optional, Union

import numpy as np

from ..calibration import api
from ..calibration.lm import levenberg_marquardt
from ..calibration.metrics import metrics
from ..calibration.problem import Problem, check_observations
from ..calibration.result import CalibrationResult
from ..calibration.sessions import SESSION_KINDS, is_private, load_sessions, session_problems
from ..data.dataset import Dataset
from ..data.splits import configuration_groups, random_split
from ..diagnosis_file import DiagnosisReport, load_diagnosis
from ..exceptions import InvalidParameterError
from ..serial_robot import Robot
from ..results import file_sha256, recorded_source, training_fingerprint
from . import structure
from .candidates import (
    JOINT_KINDS,
    MAP_LABEL,
    cable_directions,
    drift_candidate,
    fitted_map,
    free_mass_candidate,
    has_mass_model,
    library,
    map_candidate,
    map_noise,
    periodic_candidate,
    sensor_periodic_candidate,
    step_candidate,
    tracker_azimuth_candidate,
)
from .problem import ExtendedProblem, stack
from .wander import ROUGHNESS, wander_candidate

logger = logging.getLogger(__name__)


def calibrate(
    data: Union[str, Path, Dataset, list],
    *,
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
    data : path or Dataset, or a list of them
        A measurement file (canonical CSV or a public dataset, see :func:`robocal.data.load`)
        or a :class:`Dataset`; a list of two or more: sessions of one robot, fitted at once, each
        with its own set-up and sensor terms and its own held-out samples (method ``lm``; the
        result's ``sessions`` lists them).
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
    causes : list of str, DiagnosisReport, dict or path, optional
        An extended model: cause labels as ``robocal diagnose`` reports them (e.g.
        ``"joint_periodic joint 2 harmonic=3"``, ``"joint_sign joint 4"``), or a diagnose report
        (:func:`robocal.load_diagnosis`: typed, a dict or its JSON file) whose causes — and the tolerance prior of its final model, unless
        ``kinematic_prior`` is given — are taken. Reading conventions (``joint_zero``,
        ``joint_sign``, ``joint_reference``) transform the joint readings before the fit. Fitted with the geometric parameters by ``method="lm"``; the result
        JSON then has ``causes`` with their physical parameters.
    angle_unit : {"deg", "rad"} or list of them, optional
        Unit of the joint columns of a canonical file (degrees by default; values implausible
        for the default unit are refused, see :func:`robocal.data.load`); of several sessions,
        one for all or a list of one per session.
    **options
        Passed to the method.

    Returns
    -------
    CalibrationResult
        ``to_dict()`` is the result JSON (``method``, ``parameters``, ``metrics`` with ``train``
        and ``test``, ...).
    """
    several = isinstance(data, (list, tuple))
    if several and (mask is not None or prior is not None or bounds is not None):
        raise InvalidParameterError("a fit on several sessions takes no `mask`, `prior` or `bounds`")
    if several and method != "lm":
        raise InvalidParameterError(f"a fit on several sessions is made by method 'lm' only; got {method!r}")
    api.check_method(method)
    test_fraction = api.check_test_fraction(test_fraction)
    if _is_report(causes):
        causes = load_diagnosis(causes)  # read and checked once, before the data
    if several:
        datasets, r = load_sessions(data, robot, measurement, angle_unit, "a fit on several sessions")
    else:
        dataset, r = api.load_inputs(data, robot, measurement, angle_unit)
    labels, reported_prior = read_causes(causes, r.name) if causes is not None else ([], None)
    kinematic_prior = reported_prior if kinematic_prior is None else kinematic_prior
    parsed = [(label, structure.parse(label, r.n_joints)) for label in labels]
    structures = [s for _, s in parsed if s is not None]
    labels = [label for label, s in parsed if s is None]
    wrong = [s.label for s in structures if s.kind == "joint_zero" and s.joint in r.prismatic]
    if wrong:  # its offset is read in deg: 10 would move a prismatic joint by 0.17 mm
        raise InvalidParameterError(f"{', '.join(wrong)}: a zero convention is an angle (deg); joint {wrong[0].split()[2]} of {r.name} is prismatic")
    if structures:
        structures = structure.within_limits(structures, np.vstack([d.q for d in datasets]) if several else dataset.q, r)
    if several:
        terms = session_terms(causes, labels, [d.source for d in datasets])
        return _fit_sessions(datasets, r, structures, labels, terms, kinematic_prior, test_fraction, seed, options)
    if causes is None:
        problem, _, test_idx = api.held_out_problem(r, dataset, test_fraction, seed, mask=mask, prior=prior, bounds=bounds, kinematic_prior=kinematic_prior)
        result = api.fit(problem, method, seed, options)
        return _held_out(result, dataset, test_idx, lambda test: api.held_out_residuals(result, test))
    dataset = structure.apply_all(dataset, structures)  # the readings in the model's convention
    problem, train_idx, test_idx = api.held_out_problem(r, dataset, test_fraction, seed, mask=mask, prior=prior, bounds=bounds, kinematic_prior=kinematic_prior)
    if method != "lm":
        raise InvalidParameterError(f"an extended model (causes) is fitted by method 'lm' only; got {method!r}")
    model = extended_problem(problem, dataset, train_idx, labels)
    logger.info("calibrate: %d training samples, %d causes, %d reading conventions", len(train_idx), len(labels), len(structures))
    result = api.fit(model, method, seed, options)
    logger.info("calibrate: %s after %d iterations, training RMSE %.4g", result.message, result.nit, result.metrics["train"]["rmse"])
    result.structure = [s.label for s in structures]
    result = _held_out(result, dataset, test_idx, lambda test: model.with_samples(test_idx).data_residuals(result.x))
    not_carried = [c.label for c in model.causes if c.kind in JOINT_KINDS]
    if not_carried:
        refit_model = extended_problem(problem, dataset, train_idx, [label for label in labels if label not in not_carried])
        refit = api.fit(refit_model, method, seed, options)

        def held_out(m: ExtendedProblem, x: np.ndarray) -> Optional[dict]:
            return None if test_idx is None else metrics(m.with_samples(test_idx).data_residuals(x), dataset.measurement)

        candidates = {
            "extended": (model.full(result.x), held_out(model, without_joint_causes(model, result.x))),
            "refit": (refit_model.full(refit.x), held_out(refit_model, refit.x)),
        }
        result.geometry_only = geometry_only_record(not_carried, candidates, result.metrics.get("test"))
    return result


def without_joint_causes(problem: ExtendedProblem, x: np.ndarray) -> np.ndarray:
    """``x`` with the coefficients of its joint causes at zero: the geometry alone, as a URDF or
    DH table carries it."""
    x = np.array(x, dtype=np.float64, copy=True)
    for cause, at in zip(problem.causes, problem.slices):
        if cause.kind in JOINT_KINDS:
            x[at] = 0.0
    return x


def geometry_only_record(not_carried: list[str], candidates: dict, full_model: Optional[dict]) -> dict:
    """What a geometry-only export of an extended result carries (``geometry_only`` of the
    result file), from two ``candidates`` ``name -> (parameter vector, held-out metrics or
    None)``: ``extended`` (the extended fit's geometry, its joint causes left out) and
    ``refit`` (the geometry fitted again without them, the session's sensor terms kept).

    The geometry of an extended fit is fitted *with* its causes: without them it may predict
    worse than a geometry fitted alone. The one that predicts the held-out samples better is
    chosen (a choice between two, made on those samples: its figure is not a blind one); with no
    held-out samples, the refit. Keys: ``not_carried`` (labels), ``choice``, ``why``,
    ``held_out`` (metrics of ``full_model``, ``extended`` and ``refit``), ``parameters`` (the
    chosen vector, in the result's ``parameters`` order).
    """
    held = {name: figures for name, (_, figures) in candidates.items()}
    if any(m is None for m in held.values()):
        choice, why = "refit", "no held-out samples: the geometry fitted without the causes"
    else:
        choice = min(held, key=lambda name: held[name]["rmse"])
        other = next(name for name in held if name != choice)
        why = f"it predicts the held-out samples better: RMSE {held[choice]['rmse']:.4g} against {held[other]['rmse']:.4g} mm ({other})"
    return {
        "not_carried": list(not_carried),
        "choice": choice,
        "why": why,
        "held_out": {"full_model": full_model, **held},
        "parameters": [float(v) for v in candidates[choice][0]],
    }


def _held_out(result: CalibrationResult, dataset: Dataset, test_idx: Optional[np.ndarray], residuals) -> CalibrationResult:
    """``result`` with the metrics of ``residuals(test)`` on the held-out samples ``test_idx`` of ``dataset`` (if any)."""
    if test_idx is not None:
        test = dataset.subset(test_idx)
        result.metrics["test"] = metrics(residuals(test), test.measurement)
        result.held_out = test
    return result


def _fit_sessions(
    datasets: list[Dataset],
    r: Robot,
    structures: list,
    shared: list[str],
    terms: list[list[str]],
    kinematic_prior,
    test_fraction: float,
    seed: int,
    options: dict,
) -> CalibrationResult:
    """One robot from several sessions (:func:`calibrate` given a list, its arguments checked):
    its kinematics, reading conventions ``structures`` and the causes ``shared`` by its joints
    fitted on every session at once, each session with its own set-up (tracker base and tool, or
    cable anchor and zero) and its own sensor terms ``terms`` (steps, drift, wander).

    A joint map covers its joint's angles in the training samples of every session. Each session
    holds out ``test_fraction`` of its samples (seeded, repeated configurations whole);
    ``metrics["test"]`` pools them. The result's ``to_dict()`` has the robot and the first
    session's set-up in ``parameters``, and ``sessions``: per session its ``source``, ``sha256``,
    ``rows_used``, ``fingerprint`` (of its training samples), ``rows_held_out``, ``setup`` (name -> value, mm / rad), ``terms`` (labels) and
    ``metrics``.
    """
    shared = [label for label in shared if not _session_term(label)]
    raw, datasets = datasets, [structure.apply_all(d, structures) for d in datasets]
    splits = [_split(d, test_fraction, seed) for d in datasets]
    for d in datasets:
        check_observations(r, d)
    bases = session_problems(r, [d.subset(train) for d, (train, _) in zip(datasets, splits)], r.default_mask(datasets[0].measurement), kinematic_prior)
    covered = np.vstack([d.q[train] for d, (train, _) in zip(datasets, splits)])  # a joint map spans every session's angles
    problems = [extended_problem(b, d, train, shared + own, covered, every=False) for b, d, (train, _), own in zip(bases, datasets, splits, terms)]
    acting = {c.label for p in problems for c in p.causes}
    absent = [label for label in shared + [t for own in terms for t in own] if label not in acting]
    if absent:
        raise InvalidParameterError(f"causes {absent} act in none of the sessions (unknown, or their joint does not move)")
    stacked = stack(problems)
    result = api.fit(stacked, "lm", seed, options)
    result.structure = [s.label for s in structures]
    result.sessions, pooled = [], []
    for s, (d, (train, test), problem, own) in enumerate(zip(datasets, splits, problems, terms)):
        x = stacked.session_x(result.x, s)
        entry = {
            **recorded_source(d.source),
            "samples": len(d),
            "rows_used": [int(v) for v in d.rows[train]],
            "rows_held_out": [int(v) for v in d.rows[test]] if test is not None else [],
            "rows_excluded": list(d.excluded),
            "fingerprint": training_fingerprint(d.subset(train)),
            "setup": {n: float(v) for n, v in zip(r.param_names, problem.full(x)) if is_private(n, d.measurement)},
            "terms": own,
            "metrics": {"train": metrics(problem.data_residuals(x), d.measurement), "test": None},
        }
        if test is not None:
            residuals = problem.with_samples(test).data_residuals(x)
            entry["metrics"]["test"] = metrics(residuals, d.measurement)
            pooled.append(residuals)
        result.sessions.append(entry)
    if pooled:
        result.metrics["test"] = metrics(np.concatenate(pooled), datasets[0].measurement)
    not_carried = sorted({c.label for p in problems for c in p.causes if c.kind in JOINT_KINDS})
    if not_carried:
        refit = _fit_sessions(raw, r, structures, [label for label in shared if label not in not_carried], terms, kinematic_prior, test_fraction, seed, options)
        extended = [
            p.with_samples(test).data_residuals(without_joint_causes(p, stacked.session_x(result.x, s)))
            for s, (p, (_, test)) in enumerate(zip(problems, splits))
            if test is not None
        ]
        held_out = metrics(np.concatenate(extended), datasets[0].measurement) if extended else None
        candidates = {"extended": (result.params, held_out), "refit": (refit.params, refit.metrics.get("test"))}
        result.geometry_only = geometry_only_record(not_carried, candidates, result.metrics.get("test"))
    return result


def _split(dataset: Dataset, test_fraction: float, seed: int) -> tuple[np.ndarray, Optional[np.ndarray]]:
    """A session's training and held-out samples (repeated configurations whole on one side)."""
    if test_fraction == 0:
        return np.arange(len(dataset)), None
    return random_split(len(dataset), test_fraction=test_fraction, seed=seed, groups=configuration_groups(dataset.q))


def _session_term(label: str) -> bool:
    return label.split(" ")[0] in SESSION_KINDS


def _is_report(causes) -> bool:
    """A diagnose report (typed, a dict or its JSON file), rather than cause labels."""
    return isinstance(causes, (dict, DiagnosisReport)) or (isinstance(causes, (str, Path)) and str(causes).endswith(".json"))


def session_terms(causes, labels: list[str], sources: list) -> list[list[str]]:
    """Each session's own terms, for the sessions read from ``sources`` (in order).

    From a multi-session diagnose report: its ``model.sessions``, each given session matched to
    the report's by its file (the same path, or the same content); a report on more sessions
    than given serves a fit on some of them (a session left out to check the model on). A
    session the report did not diagnose is refused: its own terms are not known. Without a
    report: the session-kind ``labels`` that hold in any session (a drift, a wander: each session
    fits its own); a step sits at one session's sample and needs the report."""
    report = load_diagnosis(causes) if _is_report(causes) else None
    listed = report.needs_model().sessions if report is not None else None
    if listed is not None:
        if any(entry.source is None for entry in listed) or any(source is None for source in sources):  # unnamed: in order
            if len(listed) != len(sources):
                raise InvalidParameterError(
                    f"{report.where}: key 'model', key 'sessions' lists {len(listed)} sessions; "
                    f"the causes of each of the {len(sources)} sessions given are needed, in order (or name their files)"
                )
            return [list(entry.causes) for entry in listed]
        terms = []
        for source in sources:
            found = [entry for entry in listed if entry.source is not None and _same_file(entry.source, source)]
            if not found:
                named = "; ".join(str(entry.source) for entry in listed)
                raise InvalidParameterError(
                    f"{report.where}: session {source} is not among the report's sessions ({named}): its own terms (steps, drift) "
                    "were not diagnosed; diagnose it with the others, or pass cause labels"
                )
            terms.append(list(found[0].causes))
        return terms
    steps = [label for label in labels if label.startswith("step ")]
    if steps:
        raise InvalidParameterError(f"{steps[0]!r} is a step of one session's sensor: for several sessions pass the multi-session diagnose report")
    return [[label for label in labels if _session_term(label)] for _ in sources]


def _same_file(a, b) -> bool:
    """Whether two recorded sources name one file: the same resolved path, or the same content."""
    if a is None or b is None:
        return False
    if Path(a).resolve() == Path(b).resolve():
        return True
    digest = file_sha256(a)
    return digest is not None and digest == file_sha256(b)


def read_causes(causes, robot: str) -> tuple[list[str], Optional[tuple]]:
    """Cause labels from labels or a diagnose report (:func:`robocal.load_diagnosis`: typed, a
    dict or its JSON file) of robot ``robot`` (a report of another robot is refused) — the
    report's reading conventions (``model.structure``) first, then its ``model.causes`` — and the
    report's tolerance prior ``(mm, deg)`` on the kinematics, if its final model has one."""
    if _is_report(causes):
        model = load_diagnosis(causes).check_robot(robot).needs_model()
        return model.structure + model.causes, None if model.kinematic_prior is None else tuple(model.kinematic_prior)
    if isinstance(causes, str):
        causes = [causes]
    if not isinstance(causes, (list, tuple)) or not all(isinstance(c, str) for c in causes):
        raise InvalidParameterError(f"`causes` must be cause labels, a diagnose report or its JSON file; got {causes!r}")
    return list(causes), None


def extended_problem(
    problem: Problem,
    dataset: Dataset,
    idx: np.ndarray,
    causes: list[str],
    map_angles: Optional[np.ndarray] = None,
    every: bool = True,
    noise: Optional[float] = None,
    fitted: Optional[dict] = None,
):
    """``problem`` extended by the causes labelled ``causes`` on the samples ``idx`` of
    ``dataset`` (bases such as backlash and drift need the whole sequence). A joint map covers
    the joint angles ``map_angles`` (rows of joint values; default the samples ``idx``), its
    roughness weighed against ``noise`` (mm; default the geometric fit's residuals: a plan has
    none). With ``every=False`` a cause the data cannot show (its joint does not move) is left
    out, not refused. ``fitted``: label -> ``detail`` of joint maps fitted before (a result's):
    such a map keeps its range and knots (:func:`~robocal.causes.candidates.fitted_map`)."""
    pool = {c.label: c for c in library(problem.robot, dataset, list(problem.names) + list(problem.fixed))}
    directions = None
    for label in causes:  # steps sit where diagnose found them, maps span the fitted samples: their label says how
        step = re.fullmatch(r"step sample=(\d+) row=\d+( frame=rigid)?", label)
        if step:
            rigid = bool(step.group(2))
            if rigid and dataset.measurement == "cable" and directions is None:  # the cable's directions to the fitted tool points
                directions = cable_directions(dataset, problem.robot.with_vector(problem.full(levenberg_marquardt(problem).x)))
            pool[label] = step_candidate(dataset, int(step.group(1)), rigid, directions if rigid else None)
        wander = re.fullmatch(r"wander spacing=([0-9.]+)(?: roughness=([0-9.eE+-]+))?( trend=kept)?", label)
        if wander:  # the session's own wander, refitted on these data (a term of the session, never carried)
            roughness = float(wander.group(2)) if wander.group(2) else ROUGHNESS
            pool[label] = wander_candidate(dataset, float(wander.group(1)), roughness, trend=bool(wander.group(3)))
        curved = re.fullmatch(r"drift degree=(\d+)", label)
        if curved:  # the session's own drift, refitted on these data
            pool[label] = drift_candidate(dataset, int(curved.group(1)))
        settling = re.fullmatch(r"drift settling=([0-9.]+)", label)
        if settling:
            pool[label] = drift_candidate(dataset, settling=float(settling.group(1)))
        drum = re.fullmatch(r"sensor_periodic period=([0-9.]+)", label)
        if drum and float(drum.group(1)) > 0:  # the sensor's own error, refitted on these data
            pool[label] = sensor_periodic_candidate(dataset, float(drum.group(1)))
        azimuth = re.fullmatch(r"tracker_azimuth harmonic=(\d+) station=(-?\d+),(-?\d+)", label)
        if azimuth and dataset.measurement != "cable":
            pool[label] = tracker_azimuth_candidate(dataset, np.array([float(azimuth.group(2)), float(azimuth.group(3))]), int(azimuth.group(1)))
        periodic = re.fullmatch(r"joint_periodic joint (\d+) harmonic=(\d+)", label)
        if periodic and 1 <= int(periodic.group(1)) <= problem.robot.n_joints and label not in pool:  # a harmonic found in the place of several
            if int(periodic.group(1)) - 1 in problem.robot.prismatic:  # harmonics of a turn: a prismatic joint's reading (mm) makes none
                raise InvalidParameterError(
                    f"{label}: a periodic error is in harmonics of a turn; joint {periodic.group(1)} of {problem.robot.name} is prismatic"
                )
            pool[label] = periodic_candidate(problem.robot, dataset, int(periodic.group(1)) - 1, int(periodic.group(2)))
        free = re.fullmatch(r"joint_compliance joint (\d+) masses=free", label)
        if free and 1 <= int(free.group(1)) <= problem.robot.n_joints and has_mass_model(problem.robot):  # a compliance on any masses
            pool[label] = free_mass_candidate(problem.robot, dataset, int(free.group(1)) - 1)
        joint_map = MAP_LABEL.fullmatch(label)
        if joint_map and 1 <= int(joint_map.group(1)) <= problem.robot.n_joints:
            if noise is None:  # the roughness is weighed against the geometric fit's residuals
                geometric = levenberg_marquardt(problem)
                noise = map_noise(problem.data_residuals(geometric.x).reshape(len(problem.data), -1))
            j = int(joint_map.group(1)) - 1
            if fitted and label in fitted:
                pool[label] = fitted_map(dataset, j, fitted[label], noise)
                continue
            angles = dataset.q[idx, j] if map_angles is None else map_angles[:, j]
            pool[label] = map_candidate(dataset, j, float(joint_map.group(2)), float(joint_map.group(3)), noise, angles)
    unknown = [c for c in causes if c not in pool]
    if unknown and every:
        # The labels nearest to the asked ones: the first six of 66 in order said nothing of `joint_periodic joint 2`'s.
        near = sorted({m for c in unknown for m in difflib.get_close_matches(c, list(pool), n=3, cutoff=0.6)})
        raise InvalidParameterError(f"unknown causes {unknown} for these data; known: {near or sorted(pool)[:6]} ... ({len(pool)} in all)")
    return ExtendedProblem(problem, [pool[c] for c in causes if c in pool], dataset, idx)
