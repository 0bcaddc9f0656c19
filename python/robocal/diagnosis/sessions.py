"""Several sessions of one robot: ``robocal diagnose A.csv B.csv C.csv``.

Each session is first diagnosed on its own (:func:`~robocal.diagnosis.select.diagnose`): its
outliers, the steps and drift of its sensor, the causes its data support. What belongs to the
*robot* — the reading conventions of its joints and the causes acting on them — must then hold
on a session it was not fitted on. Every such candidate found in any session is judged by
leave-one-session-out cross-validation: the robot (kinematics and shared causes) is fitted on
all sessions but one, each with its own set-up and its own session terms
(:class:`~robocal.calibration.sessions.Sessions`); on the left-out session only its set-up and
its session terms are fitted, the robot held (:class:`~robocal.calibration.sessions.Partial`).
Candidates are accepted greedily: one must lower the pooled held-out RMSE by ``min_gain`` while
no left-out session gets worse by more than that. Session terms are never carried from one
session to another.
"""

from __future__ import annotations

import inspect
import logging
import time
from dataclasses import dataclass, field, replace
from typing import Optional

import numpy as np
from threadpoolctl import threadpool_limits

from ..calibration.problem import TOLERANCE, implausible_parameters, kinematic_prior_pairs, start_parameters
from ..calibration.sessions import SESSION_KINDS, Partial, Sessions, is_private, load_sessions, session_problems
from ..causes import structure
from . import conventions
from ..causes.candidates import PHYSICAL_KINDS, library, map_candidate, map_coverage_mask
from ..causes.problem import ExtendedProblem, judged_rmse, judged_unit, reported_rmse, rotation_squared_rad, squared_errors, stack
from ..causes.wander import TIME_TERMS
from ..kernels import as_count, is_sparse, truncated_svd, unit_columns
from ..data.dataset import Dataset
from ..diagnosis_file import load_diagnosis
from ..exceptions import InvalidParameterError
from ..results import recorded_path
from ..physics import DEG
from ..progress import progress
from ..threads import thread_map
from ..serial_robot import Robot
from .physical import judge_tolerance_prior
from .select import (
    Diagnosis,
    baseline_mask,
    coefficient_reference,
    diagnose,
    physics_first,
    require_enough_samples,
    undetermined,
)
from .uncertainty import uncertainty_entries
from .validation import fit_problem

logger = logging.getLogger(__name__)

#: Kinds of a session's own diagnosis that stay with the session (its sensor and set-up).
SESSION_TERMS = SESSION_KINDS + ("frame",)


@dataclass
class _Session:
    """One session: the data as read, the samples kept (its outliers out), its own terms."""

    data: Dataset
    diagnosis: Diagnosis
    keep: np.ndarray = field(init=False)
    terms: list = field(init=False)

    def __post_init__(self):
        self.keep = np.asarray(self.diagnosis.model.idx)
        # A wander is the session's own too, but its dozens of coefficients would be fitted on a
        # left-out session's own samples: that session's figure would not be held out. Left out.
        self.terms = [c for c in self.diagnosis.model.causes if c.kind in SESSION_TERMS and c.kind not in TIME_TERMS]


@dataclass(frozen=True)
class _Model:
    """What the sessions share beyond the kinematics: reading conventions and cause labels."""

    structures: tuple = ()
    causes: tuple = ()
    prior: tuple = ()  # (name, (mean, sigma)) of a tolerance prior on the kinematics

    @property
    def conventions(self) -> tuple:
        """Labels of the reading conventions: models with the same read the same joint angles."""
        return tuple(c.label for c in self.structures)

    def plus(self, candidate) -> "_Model":
        """With one more convention (a :class:`Structure`) or cause (a :class:`Candidate` of any
        session's library: causes are kept by label, each session has its own bases)."""
        if isinstance(candidate, structure.Structure):
            return replace(self, structures=self.structures + (candidate,))
        return replace(self, causes=self.causes + (candidate.label,))

    def stacked(self, problems: list) -> Sessions:
        return stack(problems, dict(self.prior))


class _Evaluator:
    """Per-session problems of a model (cached by their conventions) and their
    leave-one-session-out errors."""

    def __init__(self, robot: Robot, sessions: list[_Session], mask: np.ndarray, hayati: bool):
        self.robot, self.sessions, self.mask, self.hayati = robot, sessions, mask, hayati
        self.measurement = sessions[0].data.measurement
        self._bases: dict = {}
        self._starts: dict = {}
        self._fits: dict = {}
        self.maps: dict = {}  # label -> a session's joint map: its spacing, roughness and weight
        self._map_cache: dict = {}
        self.coverage: dict = {}  # model -> per session, its held-out samples that every map covers

    def bases(self, model: _Model) -> list[tuple]:
        """Per session, under the model's conventions: its base problem, its data and its
        candidate library (by label)."""
        key = model.conventions
        if key not in self._bases:
            datas = [structure.apply_all(session.data, list(model.structures)) for session in self.sessions]
            bases = session_problems(self.robot, datas, self.mask)
            pools = [{c.label: c for c in library(self.robot, d, list(b.names) + list(b.fixed), hayati=self.hayati)} for d, b in zip(datas, bases)]
            self._bases[key] = list(zip(bases, datas, pools))
        return self._bases[key]

    def problems(self, model: _Model, span: Optional[tuple] = None) -> list[ExtendedProblem]:
        """Per session, the model's problem. Joint maps cover the joint's angles in the sessions
        ``span`` (0-based; default all): one basis for every session, fading beyond (a left-out
        session is placed as ``verify`` would place it: :func:`~robocal.causes.candidates.map_reach`)."""
        span = tuple(range(len(self.sessions))) if span is None else span
        bases = self.bases(model)
        out = []
        for s, (session, (base, data, pool)) in enumerate(zip(self.sessions, bases)):
            # a cause whose joint does not move in a session does not act there
            shared = [self._map(label, s, bases, span) if label in self.maps else pool[label] for label in model.causes if label in pool or label in self.maps]
            out.append(ExtendedProblem(base, session.terms + shared, data, session.keep))
        return out

    def _map(self, label: str, s: int, bases: list, span: tuple):
        """The joint map ``label`` on session ``s``'s data (of ``bases``: the model's readings),
        covering the joint's angles in the sessions ``span``."""
        key = (label, s, span, id(bases[s][1]))
        if key not in self._map_cache:
            c = self.maps[label]
            angles = np.concatenate([bases[t][1].q[self.sessions[t].keep, c.joint] for t in span])
            noise = c.detail["weight"] * c.detail["roughness"] * DEG
            self._map_cache[key] = map_candidate(bases[s][1], c.joint, c.detail["spacing"], c.detail["roughness"], noise, angles)
        return self._map_cache[key]

    def fit(self, model: _Model):
        """The model fitted on every session (once per model): the stacked problem and its fit."""
        if model not in self._fits:
            stacked = model.stacked(self.problems(model))
            self._fits[model] = (stacked, self._fitted(stacked, (model.conventions, "all"), with_std=True))
        return self._fits[model]

    def cause_check(self, model: _Model, label: str) -> Optional[str]:
        """Why the cause ``label`` of ``model``, fitted on every session, is implausible or its
        size undetermined (the checks of a single-session diagnosis), or None."""
        stacked, fit = self.fit(model)
        spread = fit.std if fit.std is not None else _pseudo_std(stacked, fit.x)
        for s, problem in enumerate(stacked.problems):
            cause = next((c for c in problem.causes if c.label == label), None)
            if cause is None:
                continue
            values = problem.coefficients(stacked.session_x(fit.x, s), cause)
            std = problem.coefficients(stacked.session_x(spread, s), cause)
            _, why = cause.physical(values, std, self.robot, self.robot.params)
            if why or cause.kind == "joint_map":  # a penalised map is judged by its held-out gain, not coefficient by coefficient
                return f"implausible: {why}" if why else None
            return undetermined(values - coefficient_reference(cause, self.robot), std)
        return None

    def implausible(self, model: _Model) -> list[dict]:
        """Kinematic parameters beyond the limits when ``model`` is fitted on every session."""
        stacked, fit = self.fit(model)
        return implausible_parameters(self.robot, dict(zip(stacked.names, fit.x)))

    def held_out(self, model: _Model) -> list[np.ndarray]:
        """Per session, the :func:`~robocal.causes.problem.squared_errors` of its samples under the model fitted
        on the others (joint maps over the others' range). Keeps, per session, which of them every map
        covers (``coverage``)."""

        def held_out_session(h: int) -> tuple:
            problems = self.problems(model, span=tuple(s for s in range(len(self.sessions)) if s != h))
            held = problems[h]
            covered = map_coverage_mask([(c.joint, c.detail) for c in held.causes if c.kind == "joint_map"], held.data.q)
            train = model.stacked([p for s, p in enumerate(problems) if s != h])
            key = (model.conventions, h)  # a smaller model's fits on the same readings start it
            self._fitted(train, (*key, "train"))
            part = Partial(held, [n for n in held.names if is_private(n, self.measurement)], self._held_start(held, self._starts[(*key, "train")]))
            fitted = self._fitted(part, (*key, "held"))
            return squared_errors(part.data_residuals(fitted.x) * held.row_weights, held.k), covered

        self.bases(model)  # built once, before the threads read it
        left_out = thread_map(held_out_session, range(len(self.sessions)))  # the sessions left out in parallel (each a nonlinear fit)
        self.coverage[model] = [covered for _, covered in left_out]
        return [errors for errors, _ in left_out]

    def rotation_entries(self, model: _Model, errors: list[np.ndarray]) -> dict:
        """The held-out orientation error of pose data from ``model``'s :meth:`held_out`
        ``errors``: ``rotation_rmse_loso_deg`` pooled and ``rotation_per_session_deg``; nothing
        otherwise."""
        if self.measurement != "pose":
            return {}
        rad2 = [rotation_squared_rad(e, base.data) for e, (base, _, _) in zip(errors, self.bases(model))]  # each session weighed by its own noise
        return {
            "rotation_rmse_loso_deg": float(np.degrees(np.sqrt(np.mean(np.concatenate(rad2))))),
            "rotation_per_session_deg": [float(np.degrees(np.sqrt(np.mean(a)))) for a in rad2],
        }

    def _held_start(self, held: ExtendedProblem, trained: dict) -> np.ndarray:
        """The left-out session's start: the trained robot, and the set-up that places it best
        on that session's own data (:func:`start_parameters` under the trained kinematics — the
        nominal ones may lie in another basin, e.g. a joint fitted reversed)."""
        names, robot = held.names, self.robot
        p = held.full(held.x0)
        shared = {n: v for n, v in trained.items() if n in robot.param_names and not is_private(n, self.measurement)}
        p[[robot.index(n) for n in shared]] = list(shared.values())
        placed = start_parameters(robot, held.data, params=p)

        def start(n: str, v: float) -> float:  # the session's own set-up placed anew, the rest as trained
            if is_private(n, self.measurement):
                return placed[robot.index(n)] if n in robot.param_names else v
            return trained.get(n, v)

        return np.array([start(n, v) for n, v in zip(names, held.x0)])

    def _fitted(self, problem, key, with_std: bool = False):
        """``problem`` fitted from ``problem.x0`` with the entries the previous fit of the same
        ``key`` (the same readings and sessions; a smaller model's) found, kept for the next.
        From such a warm start it is fitted as a fold's fit is (:func:`~.validation.fit_problem`)."""
        previous = self._starts.get(key)
        x0 = None if previous is None else np.array([previous.get(n, v) for n, v in zip(problem.names, problem.x0)])
        fit = fit_problem(problem, x0=x0, with_std=with_std)
        self._starts[key] = dict(zip(problem.names, fit.x))
        return fit


def _pseudo_std(stacked: Sessions, x: np.ndarray) -> np.ndarray:
    """Standard deviations from ``σ̂²(JᵀJ)⁺`` with scaled columns: stacked sessions can leave a
    few combinations of shared and set-up parameters near-redundant (a full-rank covariance is
    then not defined), while a cause's own coefficient is still determined."""
    J, r = stacked.jacobian(x), stacked.residuals(x)
    J = J.toarray() if is_sparse(J) else J
    scaled, scale = unit_columns(J)
    _, sv, Vt = truncated_svd(scaled)
    sigma2 = float(r @ r) / max(len(r) - len(sv), 1)
    return np.sqrt(sigma2 * np.sum((Vt / sv[:, None]) ** 2, axis=0)) / scale


def _rmse(errors: list[np.ndarray], rmse) -> float:
    """Pooled held-out RMSE of per-session :func:`~robocal.causes.problem.squared_errors`: what selection judges
    (``rmse=judged_rmse``) or what the report states (``reported_rmse``)."""
    return rmse(np.concatenate(errors))


def _per_session(errors: list[np.ndarray], rmse) -> list[float]:
    return [rmse(e) for e in errors]


@dataclass
class SessionsDiagnosis:
    """What :func:`diagnose_sessions` found; :meth:`to_dict` is the JSON report."""

    robot: Robot
    measurement: str
    sessions: list
    baseline: dict
    effects: list
    rejected: list
    final: dict
    model: dict
    time_s: float = 0.0

    def to_dict(self) -> dict:
        return {
            "robot": self.robot.name,
            "measurement": self.measurement,
            "samples": sum(len(s.data) for s in self.sessions),
            "sessions": [{"source": recorded_path(s.data.source), "samples": len(s.data), "diagnosis": s.diagnosis.to_dict()} for s in self.sessions],
            "baseline": self.baseline,
            "effects": self.effects,
            "rejected": self.rejected,
            "final": self.final,
            "model": self.model,
            "time_s": self.time_s,
        }


#: The options of a single-session diagnosis, with their defaults: a multi-session one takes them.
OPTIONS = {
    n: p.default
    for n, p in inspect.signature(diagnose).parameters.items()
    if p.default is not inspect.Parameter.empty and n not in ("robot", "measurement", "angle_unit", "groups")
}


@threadpool_limits.wrap(limits=1, user_api="blas")
def diagnose_sessions(data: list, robot=None, measurement: Optional[str] = None, angle_unit: Optional[str] = None, **options) -> SessionsDiagnosis:
    """Diagnoses several sessions of one robot (see the module notes).

    ``data`` is a list of at least two files or Datasets, one per session, of the same robot and
    measurement; the other parameters and ``options`` (:data:`OPTIONS`: ``folds``, ``alpha``,
    ``max_effects``, ``min_gain``, ``hayati``, ``seed``) are those of
    :func:`~robocal.diagnosis.select.diagnose`.

    Returns
    -------
    SessionsDiagnosis
        ``to_dict()``: ``sessions`` (each with its own diagnosis), ``baseline`` and ``final``
        (pooled leave-one-session-out RMSE ``rmse_loso``, ``per_session``, ``implausible``),
        ``effects`` and ``rejected`` (the shared candidates with their held-out errors), ``model``
        (``structure`` and ``causes`` shared by the robot — what ``calibrate --causes`` takes —
        and each session's own terms).
    """
    unknown = sorted(set(options) - set(OPTIONS))
    if unknown:
        raise InvalidParameterError(f"a multi-session diagnosis takes the options {sorted(OPTIONS)}; got {unknown}")
    options = {**OPTIONS, **options}
    max_effects, min_gain, hayati = options["max_effects"], options["min_gain"], options["hayati"]
    t0 = time.perf_counter()
    datas, rob = load_sessions(data, robot, measurement, angle_unit, "a multi-session diagnosis")
    for d in datas:  # up front: a session too small would otherwise stop the run after the others' diagnoses
        require_enough_samples(d, as_count(options["folds"], "folds", 2))
    kind = datas[0].measurement
    sessions = []
    for d in progress(datas, desc="diagnose: each session on its own", unit="session"):
        sessions.append(_Session(d, diagnose(d, rob, **options)))
        logger.info("diagnose: session %d of %d (%s): %s", len(sessions), len(datas), d.source, [c.label for c in sessions[-1].diagnosis.model.causes])
    evaluator = _Evaluator(rob, sessions, baseline_mask(rob, kind, hayati), hayati)

    found: dict = {}  # label -> (candidate, sessions it was found in)
    replaced: dict = {}  # label -> sessions in which a joint map took the place of this harmonic
    for s, session in enumerate(sessions, start=1):
        report = load_diagnosis(session.diagnosis.to_dict())  # the session's report as a reader sees it
        for label in report.structure:
            found.setdefault(label, (structure.parse(label, rob.n_joints), []))[1].append(s)
        for c in session.diagnosis.model.causes:
            if c.kind not in SESSION_TERMS:
                found.setdefault(c.label, (c, []))[1].append(s)
                if c.kind == "joint_map":
                    evaluator.maps.setdefault(c.label, c)
        for r in report.rejected:
            if r.replaced_by:
                replaced.setdefault(r.label, []).append(s)
    # Gravity compliance is the cause with a physical model of how it carries to other poses;
    # within one session a harmonic may fit its shape better and win the selection, so every
    # compliance the robot's mass model offers is judged across sessions too. A harmonic that a
    # session's map replaced is judged too: across sessions the map may not carry and it may.
    for _, _, pool in evaluator.bases(_Model()):
        for label, c in pool.items():
            if c.kind == "joint_compliance":
                found.setdefault(label, (c, []))
            if label in replaced:
                found.setdefault(label, (c, replaced[label]))

    model = _Model()
    current = evaluator.held_out(model)
    geometric, geometric_fit = evaluator.fit(model)
    baseline = {
        "rmse_loso": _rmse(current, reported_rmse),
        "per_session": _per_session(current, reported_rmse),
        **evaluator.rotation_entries(model, current),
        "rmse_train": geometric_fit.metrics["train"]["rmse"],
        "implausible": implausible_parameters(rob, dict(zip(geometric.names, geometric_fit.x))),
    }
    effects, rejected = [], []
    # Every map variant the sessions found is judged (the smoothness that carries across
    # sessions need not be the one a session chose alone); one map per joint is accepted.
    pending = dict(found)
    while pending and sum(e["kind"] != "joint_map" for e in effects) < max_effects:  # maps do not count: one per joint at most
        trials = []
        for label, (candidate, where) in progress(list(pending.items()), desc="diagnose: leave-one-session-out", unit="candidate"):
            trials.append((_rmse(errors := evaluator.held_out(model.plus(candidate)), judged_rmse), label, candidate, where, errors))
        # judged by pooled held-out RMSE, a gravity compliance first as within one session
        trials = physics_first(
            sorted(trials, key=lambda t: t[0]),
            lambda t: _rmse(current, judged_rmse) - t[0],
            lambda t: t[2],
            established=any(e["kind"] in PHYSICAL_KINDS for e in effects),
        )
        before, reasons = _per_session(current, judged_rmse), {}
        for rmse, label, candidate, where, errors in trials:  # the best that helps without hurting a session
            worse = [s + 1 for s, (b, a) in enumerate(zip(before, _per_session(errors, judged_rmse))) if a > (1.0 + min_gain) * b]
            if rmse > (1.0 - min_gain) * _rmse(current, judged_rmse):
                reasons[label] = f"pooled held-out RMSE {rmse:.4g} {judged_unit(kind)} is not {min_gain:.1%} below {_rmse(current, judged_rmse):.4g}"
            elif worse:
                reasons[label] = f"held-out error on session(s) {worse} rises"
            elif not isinstance(candidate, structure.Structure) and (why := evaluator.cause_check(model.plus(candidate), label)):
                reasons[label] = why  # implausible or undetermined, as within one session
            elif (
                isinstance(candidate, structure.Structure)
                and rmse > (1.0 - conventions.REAL_GAIN) * _rmse(current, judged_rmse)
                and evaluator.implausible(model.plus(candidate))
            ):
                # A convention is no small correction: as within one session, it must make the
                # geometry plausible or gain REAL_GAIN.
                gain = 1.0 - rmse / _rmse(current, judged_rmse)
                left = len(evaluator.implausible(model.plus(candidate)))
                reasons[label] = (
                    f"a reading convention must make the geometry plausible or lower the held-out RMSE by {conventions.REAL_GAIN:.0%}; "
                    f"it gains {gain:.1%} and leaves {left} parameters implausible"
                )
            else:
                break
        else:
            rejected += [_entry(kind, label, candidate, where, current, errors, reasons[label]) for _, label, candidate, where, errors in trials]
            logger.info("diagnose: no further cause lowers the pooled held-out error (%d tried)", len(trials))
            break
        logger.info("diagnose: %s kept: pooled held-out RMSE %.4g %s", label, rmse, judged_unit(kind))
        effects.append(_entry(kind, label, candidate, where, current, errors, None))
        model, current = model.plus(candidate), errors
        del pending[label]
        if candidate.kind == "joint_map":  # one map per joint
            pending = {k: v for k, v in pending.items() if not (v[0].kind == "joint_map" and v[0].joint == candidate.joint)}

    unconstrained = _rmse(current, reported_rmse)
    model, current, physical = _physical(evaluator, model, current)
    problems = evaluator.problems(model)
    joint, fit = evaluator.fit(model)
    values = {n: float(v) for n, v in zip(joint.names, fit.x) if not is_private(n, kind)}
    spread = fit.std if fit.std is not None else _pseudo_std(joint, fit.x)
    parameters = {n: v for n, v in values.items() if n in rob.param_names}
    for e in effects:  # physical size from the fit on every session
        s = next(i for i, p in enumerate(problems) if any(c.label == e["label"] for c in p.causes)) if e["kind"] not in structure.KINDS else None
        if s is not None:
            described = problems[s].describe_causes(joint.session_x(fit.x, s), joint.session_x(spread, s))
            e["params"] = next(c["params"] for c in described if c["label"] == e["label"])
    # each map's curve and band, the compliances' correlation, from the fit on every session
    shared = {c.label: c for p in problems for c in p.causes if c.label in {e["label"] for e in effects}}
    described = uncertainty_entries(joint, fit.x, list(shared.values()))
    for e in effects:
        e.update(described.get(e["label"], {}))
    covered = evaluator.coverage[model]
    final = {
        "rmse_loso": _rmse(current, reported_rmse),
        "per_session": _per_session(current, reported_rmse),
        **evaluator.rotation_entries(model, current),
        "implausible": implausible_parameters(rob, parameters),
        "tolerance_prior": physical,
        # where the joint maps fitted on the other sessions apply: what they can do, apart from the samples they cannot correct
        "per_session_covered": [{"samples": int(m.sum()), "rmse": reported_rmse(e[m]) if m.any() else None} for e, m in zip(current, covered)],
        "rmse_loso_unconstrained": unconstrained,
        **({"rmse_loso_judged": _rmse(current, judged_rmse)} if kind == "pose" else {}),
        "rmse_train": fit.metrics["train"]["rmse"],
        "n_params": len(joint.names),
    }
    return SessionsDiagnosis(
        robot=rob,
        measurement=kind,
        sessions=sessions,
        baseline=baseline,
        effects=effects,
        rejected=rejected,
        final=final,
        model={
            "structure": [s.label for s in model.structures],
            "causes": list(model.causes),
            "parameters": parameters,
            "kinematic_prior": [physical["sigma_mm"], physical["sigma_deg"]] if physical and physical["accepted"] else None,
            # absolute: calibrate --causes matches its sessions to these files from any folder
            "sessions": [{"source": recorded_path(s.data.source), "causes": [c.label for c in s.terms]} for s in sessions],
        },
        time_s=time.perf_counter() - t0,
    )


def _physical(evaluator: _Evaluator, model: _Model, current: list):
    """The selected model with a manufacturing-tolerance prior on the kinematics where its fit on
    every session is implausible, kept if its pooled leave-one-session-out RMSE is within
    :data:`~robocal.diagnosis.physical.PRIOR_COST` of the model's without it
    (:func:`~robocal.diagnosis.physical.judge_tolerance_prior`, as
    :func:`~robocal.diagnosis.select.diagnose` judges it within one session).
    Returns the model, its held-out errors and the prior's report entry (None if not tried)."""
    stacked, _ = evaluator.fit(model)
    if not evaluator.implausible(model):
        return model, current, None
    robot = evaluator.robot
    prior = kinematic_prior_pairs(robot, stacked.names, dict(zip(robot.param_names, robot.params)), TOLERANCE)
    trial = replace(model, prior=tuple(sorted(prior.items())))
    errors = evaluator.held_out(trial)
    entry = judge_tolerance_prior([("rmse_loso", "leave-one-session-out", np.concatenate(current), np.concatenate(errors))], evaluator.measurement)
    return (trial, errors, entry) if entry["accepted"] else (model, current, entry)


def _entry(measurement: str, label: str, candidate, where: list, before: list, after: list, reason: Optional[str]) -> dict:
    joint = None if candidate.joint is None else candidate.joint + 1
    entry = {
        "kind": candidate.kind,
        "joint": joint,
        "label": label,
        "params": candidate.params if isinstance(candidate, structure.Structure) else {},
        "found_in_sessions": where,
        "rmse_loso_before": _rmse(before, reported_rmse),
        "rmse_loso_after": _rmse(after, reported_rmse),
        "per_session_before": _per_session(before, reported_rmse),
        "per_session_after": _per_session(after, reported_rmse),
    }
    if measurement == "pose":  # what the selection compared: the position's error alone may rise
        entry["rmse_loso_judged_before"] = _rmse(before, judged_rmse)
        entry["rmse_loso_judged_after"] = _rmse(after, judged_rmse)
    if reason is not None:
        entry["reason"] = reason
    return entry
