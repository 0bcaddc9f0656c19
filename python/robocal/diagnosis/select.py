"""Choosing causes by held-out gain: ``robocal.diagnose``.

:func:`diagnose` first applies the reading conventions that make an implausible geometry
plausible (:func:`~.conventions.reading_conventions`, :mod:`robocal.causes.structure`), then runs one pass of the selection
(:func:`_select`), and a second pass, which only confirms what the first decided, when the first
pass's final model shows gross outliers that the geometric baseline's residuals hid. A pass is a
sequence of stages, each a function that takes the pass's state (:class:`~.state.Pass`: the kept samples
and their fold schemes, the current model with its fit, held-out errors and fold fits, and the
report as far as it is written) and leaves it updated:

1. :func:`geometric_baseline`: the geometric baseline (the identifiable subset; Hayati ``beta``
   on nominally parallel axes unless ``hayati=False``), fitted and cross-validated. Gross
   outliers are named first: samples whose residual lies beyond the Bonferroni bound of a robust
   (MAD) noise scale and beyond :data:`~.outliers.GROSS_SIGMAS`, re-decided after refitting without them
   until the set is stable (and checked again under the final model, stage 8).
2. :func:`forward_selection`: causes added one at a time, in rounds of two steps.
   :func:`screen_round` screens every candidate by cross-validation of the model linearised at
   the current fit (:class:`~.screening.Screen`): per fold, least squares of the residuals on
   ``[J_model, C_candidate]`` over the training samples (the geometric columns refit with it, so
   what the geometry can absorb is projected off), errors on the held-out samples. Two fold
   schemes: random k-fold and contiguous blocks in acquisition order (a cause must also help on
   a block of the session it was not fitted on), plus leave-one-group-out when ``groups`` are
   given. A candidate is significant if the extra-sum-of-squares F test of adding its columns
   passes at ``alpha`` / (number of candidates × rounds the selection may run) (Bonferroni over
   the whole search), its held-out gain is positive on every fold scheme and at least
   ``min_gain`` of the held-out RMSE. :func:`confirm` then fits the significant ones in order
   (largest gain first, with the exceptions of :func:`confirmation_order`; nonlinear, all
   parameters re-fitted) and takes the first whose physical parameters are plausible
   (:data:`~robocal.causes.candidates.LIMITS`) and whose held-out gain survives nonlinear
   re-fits per fold. A round whose linear drift gains on the random folds but not on the
   blocked ones screens the drift's curves too (:func:`bent_drift`). The rounds end when one
   takes nothing.
3. :func:`wander_keeps_its_trend`: a linear drift beside a wander that is no more than the trend
   the wander makes by chance is the wander's. :func:`try_curved_drift`: a linear drift replaced
   by a curved one where that gains.
4. :func:`backward`: every cause must still earn its place once those found after it are in.
5. :func:`joint_maps`: a joint error map per joint (:mod:`.maps`), then the backward check again.
6. :func:`recheck_compliances`: a gravity compliance whose size became implausible or
   undetermined is dropped.
7. :func:`~.physical.physical_model`: a tolerance prior on the kinematics where the data leave the geometry
   undetermined, kept if it costs at most :data:`~.physical.PRIOR_COST` of held-out error.
8. The report (:mod:`.entries`): :func:`~.entries.describe_causes` (uncertainties, shares of what is
   explained), :func:`~.entries.one_claim_per_joint` (one joint's harmonics and map one entry), :func:`~.entries.final_residuals` (error floor, what the residuals are),
   :func:`~.outliers.name_outliers` (the outliers re-decided under the final model),
   :func:`~.entries.baseline_entry` and :func:`~.entries.final_entry`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Union

import numpy as np
from scipy.stats import norm
from threadpoolctl import threadpool_limits

from ..calibration.api import load_inputs
from ..calibration.problem import Problem
from ..calibration.result import GROSS_FACTOR, CalibrationResult, grossly_implausible
from ..causes import structure
from ..causes.candidates import (
    CURVED_DRIFT_DEGREE,
    PHYSICAL_KINDS,
    SENSOR_KINDS,
    SETTLING_TIMES,
    Candidate,
    compliance_candidate,
    acquisition_order,
    acquisition_position,
    curved_drift,
    drift_candidate,
    free_mass_candidate,
    library,
    on_free_masses,
)
from ..causes.problem import ExtendedProblem, judged_rmse, reported_rmse
from ..causes.wander import ROUGHNESS, TIME_TERMS, wander_candidate, within_session
from ..data.dataset import Dataset
from ..exceptions import InvalidParameterError
from ..kernels import as_count, as_float, as_tolerance, is_sparse
from ..progress import progress, stage
from ..robot import Robot
from ..stats import paired_z, rmse_of_squares
from . import conventions
from .change_points import ramps, step_candidates, transitions
from .entries import baseline_entry, describe_causes, final_entry, final_residuals, one_claim_per_joint
from .leftover import unexplained
from .maps import map_stage, merge_harmonics
from .outliers import gross_outliers, name_outliers
from .physical import physical_model
from .screening import Screen
from .sensor_field import sensor_candidates
from .state import Baseline, Decided, Pass, refusal_record, retraction
from .validation import GAIN_LEVEL, GAIN_Z, coefficient_std, cross_validate, fit_problem, fold_schemes, judgeable, weak_gain
from .wander import CHANCE_ORDERS, residual_correlation, serial_inflation, time_inflation, trend_beyond_chance


@dataclass
class Diagnosis:
    """What :func:`diagnose` found; :meth:`to_dict` is the JSON report."""

    robot: Robot
    data: Dataset
    baseline: dict
    effects: list
    rejected: list
    final: dict
    model: ExtendedProblem
    x: np.ndarray
    outliers: list = field(default_factory=list)
    time_s: float = 0.0
    plots: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {
            "robot": self.robot.name,
            "measurement": self.data.measurement,
            "samples": len(self.data),
            "source": self.data.source,
            "baseline": self.baseline,
            "effects": self.effects,
            "rejected": self.rejected,
            "final": self.final,
            "model": {
                "free": [self.robot.param_names[k] for k in self.model.free],
                "parameters": {n: float(v) for n, v in zip(self.robot.param_names, self.model.full(self.x))},
                "causes": [c.label for c in self.model.causes],
                "structure": [e["label"] for e in self.effects if e["kind"] in structure.KINDS],
                # (mm, deg) of the final model's tolerance prior on the kinematics, if it has one
                "kinematic_prior": [prior["sigma_mm"], prior["sigma_deg"]] if (prior := self.final.get("tolerance_prior")) and prior["accepted"] else None,
            },
            "time_s": self.time_s,
        }


#: Kinds that belong to the session and change smoothly in time (a wandering sensor): fitted
#: on neighbours in time, they predict samples between their training samples (random folds)
#: but not a block of the session they never saw (blocked, group folds), where they must only
#: do no harm — within :data:`SESSION_TERM_COST` of the model without them (the blocked
#: figure of five folds moves by a few per cent with any change of the geometry fitted beside
#: a new term; at 1 % a wander's 30 % random-fold gain was refused for a 1.0 % blocked change and
#: five false causes took its place).
SESSION_TERM_COST = 0.05


#: The highest harmonic offered while the geometry is implausible (higher ones are flexible terms).
MAX_HARMONIC_UNEXPLAINED = 2


#: Screening gains within this fraction of each other are the same gain.
SAME_GAIN = 0.01


def simplest_first(ranked: list) -> list:
    """``ranked`` ((gain, candidate, ...) best first) with a joint's candidate of fewer
    coefficients moved before a richer one of the same joint that gains no more than
    :data:`SAME_GAIN` above it: over a joint's range a scale error and a first harmonic (or a
    harmonic and its neighbour) fit alike, and the data then speak for the simpler one. Likewise
    a drift before a step of no more gain (a linear drift and a step placed half-way along it
    gain alike), and a step that shifts the readings before the sensor's rigid move at the same
    sample (a re-zeroed cable before an anchor that moved)."""
    out = list(ranked)
    for i in range(len(out)):
        gain, c = out[i][0], out[i][1]
        if c.kind == "step" and gain > 0:  # a drift's shape is not chosen among every sample, as a step's place is
            simpler = [j for j in range(i + 1, len(out)) if out[j][1].kind == "drift" and out[j][0] >= (1.0 - SAME_GAIN) * gain]
            # the readings shifted before the sensor's rigid move at the same sample, if it gains as much
            simpler += [
                j
                for j in range(i + 1, len(out))
                if out[j][1].kind == "step"
                and out[j][1].detail["sample"] == c.detail["sample"]
                and out[j][1].size < c.size
                and out[j][0] >= (1.0 - SAME_GAIN) * gain
            ]
            if simpler:
                out.insert(i, out.pop(simpler[0]))
            continue
        if c.stage != "joints" or gain <= 0:
            continue
        same_joint = [j for j in range(i + 1, len(out)) if out[j][1].joint == c.joint and out[j][1].stage == "joints"]
        simpler = [j for j in same_joint if out[j][1].size < c.size and out[j][0] >= (1.0 - SAME_GAIN) * gain]
        if simpler:
            out.insert(i, out.pop(min(simpler, key=lambda j: (out[j][1].size, -out[j][0]))))
    return out


def is_flexible(c: Candidate) -> bool:
    """A joint term flexible enough to fit around a wrong geometry: a harmonic above
    :data:`MAX_HARMONIC_UNEXPLAINED` (maps are offered by their own stage)."""
    return c.kind == "joint_periodic" and c.detail.get("harmonic", 1) > MAX_HARMONIC_UNEXPLAINED


def structure_note(implausible: int) -> Optional[dict]:
    """The report's ``structure_unexplained``: the number of kinematic parameters still far beyond
    their limits (:func:`grossly_implausible`) and why no flexible term was tried; None if none."""
    if not implausible:
        return None
    far = f"the geometric fit stays far from any robot ({implausible} parameters beyond {GROSS_FACTOR:g} times the limits)"
    untried = f"joint maps and harmonics above order {MAX_HARMONIC_UNEXPLAINED} were not tried, as they would fit around a wrong geometry"
    return {"implausible": implausible, "note": f"{far} and no reading convention makes it plausible: {untried}"}


def gains_everywhere(c: Candidate, gains: dict) -> bool:
    """A screening gain on every fold scheme (a time term: on the random folds; the linear
    screening extrapolates it into a held-out block, so the nonlinear check, which does not,
    judges it there)."""
    if within_session(c):
        return gains["random"] > 0
    return all(g > 0 for g in gains.values())


#: A linear drift or a step is judged before a wander when it gains at least this share of the
#: wander's screening gain.
SENSOR_TERM_SHARE = 0.5


#: A step is named only if its held-out errors beat those of its best gradual alternative (a
#: ramp from its sample, a curve of the model's drift) by this many standard errors, sample by
#: sample (one-sided 2.5 %): a jump is a claim that a ramp from the same sample cannot make. On
#: simulated files (seed 101 of benches/discovery.py) the steps named where none was hidden —
#: cut out of wandering readings, bent drifts and leftovers of other causes — beat their ramp by
#: 0-1.8 standard errors, the true steps at three times their detection limit by 2-9.
JUMP_Z = float(norm.isf(0.025))


#: Knot spacings (samples) of the wanders a step must also beat where the round offers none (the
#: residual test measured no correlation length): a sensor's zero that wanders over 5-20
#: samples leaves arcs that a change-point search cuts into steps.
ARC_SPACINGS = (4.0, 8.0, 16.0)
#: ... and, as shares of the session, the knot spacings of the slow arcs a step must also beat:
#: a wave of the reading on a trend (a drift that is neither a line nor one of its curves). They
#: keep their trend, as a step's level change does: the wave rides on the drift's line (without
#: it they left the verdict on a wave cut into a step as it was: the mismatch section of
#: benches/discovery.py, seed 34, file 189). Their roughness penalty is the
#: stiffer of the wanders' (:data:`WANDER_STIFFER`): at the wanders' own a slow arc turned as
#: sharply as a true knock of 1.5-2.3 times its detection limit and took its place (seed 35,
#: files 61, 74, 174, 203); three times as stiff it still did, thirty times as stiff it followed
#: no wave.
SLOW_ARC_SHARES = (1 / 8, 1 / 4)

#: Terms of acquisition time judged with the correlation in time of the residuals they leave
#: (:func:`~.wander.serial_inflation`); a wander models that correlation itself.
SERIAL_TERMS = ("step", "drift")
#: Knot spacings of the wander candidates, in correlation lengths of the residuals.
WANDER_SPACINGS = (0.5, 1.0, 2.0)
#: ... and roughness penalties, in multiples of :data:`~robocal.causes.wander.ROUGHNESS`.
WANDER_STIFFER = (1.0, 10.0)


def improves(c: Candidate, scheme: str, before: np.ndarray, after: np.ndarray) -> bool:
    """Whether the held-out squared errors (n, 2) ``after`` adding ``c`` count as a gain over
    ``before`` on ``scheme``: a lower RMSE — a time term must only do no harm beyond the random
    folds, within :data:`SESSION_TERM_COST` (judged against chance instead, a wander took the
    place of a 0.3 mm step)."""
    b, a = judged_rmse(before), judged_rmse(after)
    if within_session(c) and scheme != "random":
        return a <= (1.0 + SESSION_TERM_COST) * b
    return a < b


def held_out_refusal(c: Candidate, schemes: dict, idx: np.ndarray, before: dict, after: dict) -> Optional[str]:
    """Why ``c`` is no held-out gain of the model with it over the model without it (``after``,
    ``before``: held-out squared errors per fold scheme, nonlinear re-fits), or None if it is:
    a gain on every scheme (:func:`improves`) that is significant on the random folds
    (:func:`~.validation.weak_gain`), on the samples that can judge it (:func:`judgeable`). The
    one test a cause passes to enter the model (:func:`confirm`) and to stay in it
    (:func:`backward`)."""
    on = judgeable(c, idx, schemes)
    lost = [name for name in schemes if not improves(c, name, before[name][on[name]], after[name][on[name]])]
    if lost:
        worse = ", ".join(f"{name} folds {judged_rmse(before[name][on[name]]):.4g} -> {judged_rmse(after[name][on[name]]):.4g} mm" for name in lost)
        return f"no held-out gain after the nonlinear re-fit: {worse}"
    return weak_gain(before["random"][on["random"]], after["random"][on["random"]])


#: Significant joint candidates given a nonlinear fit per round, in order of screening gain. On
#: an ill-conditioned geometry (D1) dozens of screening-significant joint candidates in a row
#: fail the plausibility check, each after a full fit; the rest are reported as not fitted.
#: Sensor (observation) and parameter candidates are always fitted.
MAX_TRIALS = 8


def baseline_mask(robot: Robot, measurement: str, hayati: bool) -> np.ndarray:
    mask = robot.default_mask(measurement)
    if not hayati:
        for j, joint in enumerate(robot.joints, start=1):
            if joint.hayati:
                mask[robot.index(f"beta{j}")], mask[robot.index(f"d{j}")] = False, True
    return mask


def require_enough_samples(dataset: Dataset, folds: int) -> None:
    """An error naming the data when ``dataset`` is too small for ``folds`` folds (four samples
    per fold); a multi-session diagnosis asks it of every session before any work."""
    if len(dataset) < 4 * folds:
        raise InvalidParameterError(f"{dataset.source or 'the data'}: diagnose needs at least {4 * folds} samples for {folds} folds; got {len(dataset)}")


# Diagnosis solves thousands of small least-squares problems: a multi-threaded BLAS only adds
# hand-over cost there, and on a loaded machine its spinning threads made it 20x slower.
@threadpool_limits.wrap(limits=1, user_api="blas")
def diagnose(
    data: Union[str, Path, Dataset],
    robot: Union[str, Robot, None] = None,
    measurement: Optional[str] = None,
    folds: int = 5,
    alpha: float = 0.05,
    max_effects: int = 4,
    min_gain: float = 0.005,
    hayati: bool = True,
    groups=None,
    seed: int = 0,
    angle_unit: Optional[str] = None,
    maps: bool = True,
) -> Diagnosis:
    """Shows what the geometric model gets wrong on ``data``, names the causes, measures the gain.

    Parameters
    ----------
    data : path or Dataset
    robot : str or Robot, optional
        Default: the robot recorded in the data.
    measurement : {"cable", "position", "pose"}, optional
    folds : int
        Folds of the random and the blocked cross-validation.
    alpha : float
        Family-wise significance level of each selection round (Bonferroni over the candidates).
    max_effects : int
        Most causes accepted.
    min_gain : float
        Smallest held-out gain worth a cause, as a fraction of the current held-out RMSE
        (practical significance beside the statistical test).
    hayati : bool
        Baseline with Hayati ``beta`` on nominally parallel axes (default); ``False`` makes the
        baseline plain DH and ``axis_misalignment`` a candidate.
    groups : array_like, optional
        A label per sample (session, series): adds leave-one-group-out folds.
    seed : int
        Seeds the random folds.
    angle_unit : {"deg", "rad"} or list of them, optional
        Unit of a canonical file's joint columns (see :func:`robocal.data.load`); of several
        sessions, one for all or a list of one per session.
    maps : bool
        After the named causes, try a joint error map per joint (:mod:`.maps`; default).

    Returns
    -------
    Diagnosis
        ``to_dict()`` is the JSON report (``baseline``, ``effects``, ``rejected``, ``final``).

    Examples
    --------
    >>> from robocal.simulation import simulate
    >>> data, _ = simulate("abb-irb120", "position", samples=300, seed=3, effects=["joint_scale:joint=2,scale=3e-4"])
    >>> [e["kind"] for e in diagnose(data).effects]
    ['joint_scale']
    """
    t0 = time.perf_counter()
    folds, max_effects, min_gain = as_count(folds, "folds", 2), as_count(max_effects, "max_effects", 0), as_tolerance(min_gain, "min_gain")
    if not 0.0 < as_float(alpha, "alpha") < 1.0:
        raise InvalidParameterError(f"`alpha` must lie in (0, 1); got {alpha!r}")
    dataset, rob = load_inputs(data, robot, measurement, angle_unit)
    if groups is not None and np.shape(groups) != (len(dataset),):
        raise InvalidParameterError(f"`groups` needs one label per sample, shape ({len(dataset)},); got {groups!r}")
    require_enough_samples(dataset, folds)
    mask = baseline_mask(rob, dataset.measurement, hayati)
    dataset, effects, rejected, geometric_cv = conventions.reading_conventions(rob, dataset, mask, folds, seed, groups)
    base = Problem.build(rob, dataset, mask=mask)
    settings = {
        "folds": folds,
        "seed": seed,
        "groups": groups,
        "alpha": alpha,
        "max_effects": max_effects,
        "min_gain": min_gain,
        "hayati": hayati,
        "maps": maps,
    }
    diagnosis, revealed, decided = _select(
        rob, dataset, base, [dict(e) for e in effects], list(rejected), np.zeros(0, dtype=int), geometric_cv=geometric_cv, **settings
    )
    if len(revealed):
        # Gross errors the geometric baseline's large residuals hid, beyond the bound only once
        # the causes are in: named, and the causes found confirmed again without them (the
        # search is not repeated), so that every held-out figure (baseline included) is over
        # the same samples.
        known = np.union1d(diagnosis.outliers, revealed)
        diagnosis, _, _ = _select(rob, dataset, base, effects, rejected, known, geometric_cv=geometric_cv, revealed=revealed, replay=decided, **settings)
    diagnosis.time_s = time.perf_counter() - t0
    return diagnosis


def _select(
    rob: Robot,
    dataset: Dataset,
    base: Problem,
    effects: list,
    rejected: list,
    known: np.ndarray,
    *,
    folds: int,
    seed: int,
    groups,
    alpha: float,
    max_effects: int,
    min_gain: float,
    hayati: bool,
    maps: bool,
    geometric_cv: Optional[tuple] = None,
    revealed: Optional[np.ndarray] = None,
    replay: Optional[Decided] = None,
) -> tuple[Diagnosis, np.ndarray, Decided]:
    """One pass of :func:`diagnose` after the structural stage, with the ``known`` outliers
    (``revealed``: those an earlier pass's final model named); the kept samples its final
    model puts beyond the outlier bound; and what it decided. With ``replay`` (an earlier pass's
    decisions) only the causes and maps that pass accepted are offered, with its Bonferroni
    counts, and its other refusals are reported as they were.

    The stages of the module notes, in order, on the pass's :class:`~.state.Pass`."""
    revealed = np.zeros(0, dtype=int) if revealed is None else revealed
    state = geometric_baseline(rob, dataset, base, known, effects, rejected, folds=folds, seed=seed, groups=groups, min_gain=min_gain)
    pool = library(rob, dataset, list(base.names) + list(base.fixed), hayati=hayati) if replay is None else list(replay.causes)
    # A geometry that stays implausible after the reading conventions is structure not
    # explained: a flexible joint term would only make a wrong geometry fit better (D1's joint
    # maps: docs/findings.md). Those are not offered until it is.
    unexplained_structure = grossly_implausible(state.baseline.fit.implausible())
    if unexplained_structure:
        pool = [c for c in pool if not is_flexible(c)]
    searched, found = forward_selection(state, pool, alpha=alpha, max_effects=max_effects, replay=replay)
    forward = list(state.model.causes)
    wander_keeps_its_trend(state)
    try_curved_drift(state)
    backward(state, not_physical)
    if unexplained_structure:  # the causes found may have been what bent the geometry
        unexplained_structure = grossly_implausible(fit_problem(state.model, x0=state.x).implausible())
    accepted_maps, rejected_maps = joint_maps(state, alpha, replay) if maps and not unexplained_structure else ([], [])
    recheck_compliances(state)
    unconstrained = reported_rmse(state.cv["random"])  # the final model's held-out error without a tolerance prior
    final_fit, prior = physical_model(state)
    describe_causes(state)
    one_claim_per_joint(state.effects)
    budget, leftover, z = final_residuals(state)
    outliers, beyond_bound, gathered = name_outliers(state, z, revealed, folds=folds, seed=seed, geometric_cv=geometric_cv)
    if gathered is not None:  # what is left is not noise there
        leftover["findings"].append(gathered)
        leftover["noise"] = leftover["unexplained"] = False
    if replay is not None:  # the earlier pass's other refusals and alike shapes, as that pass measured them
        for e in state.effects:
            if e["label"] in replay.alike and e.get("significance") is not None:
                e["significance"]["undetermined_between"] = replay.alike[e["label"]]
        decided_now = {e["label"] for e in state.rejected} | {e["label"] for e in state.effects}
        state.rejected += [{**e, "decided_with_outliers": True} for e in replay.rejected if e["label"] not in decided_now]
    decided = Decided(
        forward,
        {m["candidate"].label for m in accepted_maps},
        searched,
        max((m["tests"] for m in accepted_maps + rejected_maps), default=0),
        list(state.rejected),
        found,
        {e["label"]: e["significance"]["undetermined_between"] for e in state.effects if (e.get("significance") or {}).get("undetermined_between")},
    )
    diagnosis = Diagnosis(
        robot=rob,
        data=dataset,
        baseline=baseline_entry(state, hayati=hayati, folds=folds),
        effects=state.effects,
        rejected=state.rejected,
        final=final_entry(state, final_fit, prior, unconstrained, budget, leftover, found, structure_note(unexplained_structure)),
        model=state.model,
        x=state.x,
        outliers=[int(v) for v in outliers],
        plots=state.plots,
    )
    return diagnosis, beyond_bound, decided


def geometric_baseline(
    rob: Robot, dataset: Dataset, base: Problem, known: np.ndarray, effects: list, rejected: list, *, folds: int, seed: int, groups, min_gain: float
) -> Pass:
    """Stage 1: the gross outliers named (the ``known`` ones among them: :func:`~.outliers.gross_outliers`), the
    fold schemes drawn over the samples kept, and the geometric baseline fitted and
    cross-validated there. The pass starts from the baseline, with the report so far (``effects``
    and ``rejected``: the reading conventions')."""
    outliers, z_bound, x_outliers = gross_outliers(base, dataset, known)
    keep = np.setdiff1d(np.arange(len(dataset)), outliers)
    order = acquisition_order(dataset)
    kept_order = np.searchsorted(keep, order[np.isin(order, keep)])
    schemes = fold_schemes(dataset.q[keep], folds, seed, kept_order, None if groups is None else np.asarray(groups)[keep])
    ext = ExtendedProblem(base, [], dataset, keep)
    fit = fit_problem(ext, x0=x_outliers)
    cv, fold_x = cross_validate(ext, schemes)
    residual_test = residual_correlation(dataset, keep, ext.residuals(fit.x).reshape(len(keep), ext.k))
    baseline = Baseline(fit, cv, outliers, z_bound, residual_test)
    return Pass(rob, dataset, base, keep, schemes, min_gain, baseline, ext, fit.x, cv, fold_x, effects, rejected)


def forward_selection(state: Pass, pool: list, *, alpha: float, max_effects: int, replay: Optional[Decided]) -> tuple[int, list]:
    """Stage 2: causes added one at a time from ``pool``. Each round screens every candidate
    against the current model (:func:`screen_round`) and fits the significant ones in order
    until one passes the nonlinear checks (:func:`confirm`); the rounds stop when one takes
    nothing or ``max_effects`` causes are in.

    Returns the most candidates a round screened (the Bonferroni count a replay uses) and the
    candidates the last round refused although they would have explained much
    (:func:`~.leftover.unexplained`; a replay's: the earlier pass's)."""
    # No wander while the geometric fit's residuals are alike in joint space and not beyond it
    # in time: that is evidence for the robot's causes, and a wander offered in a later round
    # would take what is left of them along the path, raising the held-out error (UR10 series A:
    # docs/findings.md).
    wander_test = state.baseline.residual_test
    wander_offered = replay is None and (wander_test is None or wander_test["verdict"] != "joints")
    searched = 0  # the most candidates a round screened
    last_refusals, last_rmse = len(state.rejected), None  # where the last round's refusals start, and its model's held-out RMSE
    while len(state.model.causes) < max_effects:
        last_refusals = len(state.rejected)
        screening = screen_round(state, pool, wander_offered, alpha=alpha, max_effects=max_effects, replay=replay)
        last_rmse, searched = screening.rmse, max(searched, screening.candidates)
        with stage(f"diagnose: confirming round {len(state.model.causes) + 1}"):  # the nonlinear re-fits: most of a diagnosis' time
            taken = confirm(state, screening)
        if taken is None:
            _refuse_best(state, screening)
            break
        if taken.kind == "drift":
            # its shape settled before the next round: the bends a line leaves would be taken by
            # joint causes that outlive its curve (seed 33 of benches/discovery.py, file 24: a
            # drift ∝ t^0.65 left a compliance and a coupling)
            try_curved_drift(state)
        pool = [o for o in screening.offered if o is not taken]
        if taken.kind == "joint_compliance" and not on_free_masses(taken):
            # the same joint on any masses competes from the next round on: what the mass
            # model's torque misses of a deflection was taken by couplings and harmonics of the
            # joints that move with it
            pool.append(free_mass_candidate(state.robot, state.dataset, taken.joint))
    if replay is not None:
        return searched, replay.unexplained
    return searched, unexplained(state.rejected[last_refusals:], last_rmse)


@dataclass
class Round:
    """A screening round (:func:`screen_round`) as :func:`confirm` takes it: the candidates
    ``offered``, those screened ``ranked`` in the order they are tried — ``(gain, candidate,
    p_value, gains)``: the held-out gain on the random folds and per fold scheme (mm) and the F
    test's p-value — and what judges them: the current model's ``residual`` (its data rows),
    its held-out RMSE on the random folds in the screening, and the number of ``candidates``
    the tests are corrected for."""

    offered: list
    ranked: list
    residual: np.ndarray
    rmse: float
    candidates: int
    k: int
    alpha: float
    min_gain: float
    max_effects: int
    #: Per step (label): the largest random-fold gain of a gradual change: its ramps
    #: (:func:`~.change_points.ramps`), the curves of the model's linear drift and, where no
    #: wander is offered, the arcs of a wandering reading (:data:`ARC_SPACINGS`).
    gradual: dict = field(default_factory=dict)
    #: Per step (label): by how many standard errors the step's held-out errors on the random
    #: folds beat those of its best gradual alternative, sample by sample (:func:`paired_z`), or
    #: of the best slow arc (:data:`SLOW_ARC_SHARES`) on the samples around it, whichever is less.
    jump_z: dict = field(default_factory=dict)
    #: Per step (label): the same against its smooth level changes (:func:`~.change_points.transitions`):
    #: below :data:`SHAPE_Z` the step is named with "drift" as what the data cannot tell it from.
    smooth_z: dict = field(default_factory=dict)
    #: Per shape of a joint or compliance screened (label): its held-out squared errors on the
    #: random folds (what :meth:`told_apart` compares).
    shape_errs: dict = field(default_factory=dict)
    #: Per rigid step (label): by how many standard errors its held-out errors on the random
    #: folds beat those of the shift at the same sample (:func:`paired_z`): the turn (or the
    #: anchor's move) it claims beyond a shift must show, as a step's jump must.
    turn_z: dict = field(default_factory=dict)
    #: Per sensor's field (label): by how many standard errors its held-out errors on the random
    #: folds beat those of the best smooth function of time (the round's drift, a drift's curves),
    #: sample by sample: it must show that it follows where, not when.
    where_z: dict = field(default_factory=dict)

    def tests(self, c: Candidate) -> int:
        """How many tests ``c``'s p-value is corrected for (Bonferroni)."""
        # Bonferroni over the whole search, not one round: every candidate of every round the
        # selection may run (max_effects). A step's position was chosen from the data among
        # every sample: Bonferroni over those positions as well (its p-value is that of the
        # best of them). The sensor's own error likewise over the shapes it was chosen among.
        chosen_among = len(self.residual) // self.k if c.kind == "step" else c.detail.get("scanned", 0)
        return (self.candidates + chosen_among) * max(1, self.max_effects)

    def significant(self, gain: float, c: Candidate, p_value: float, gains: dict) -> bool:
        """Whether a screened candidate passes the F test at ``alpha`` / :meth:`tests`, gains at
        least ``min_gain`` of the held-out RMSE and gains on every fold scheme."""
        relevant = gain >= self.min_gain * self.rmse
        return p_value * self.tests(c) < self.alpha and relevant and gains_everywhere(c, gains)

    def told_apart(self, better: Candidate, worse: Candidate, on=slice(None)) -> bool:
        """Whether the data tell the joint candidate ``better`` from ``worse``: its held-out
        errors on the random folds beat ``worse``'s by :data:`SHAPE_Z` standard errors, sample by
        sample (on the samples ``on``; False where either was not screened as a joint shape)."""
        if better.label not in self.shape_errs or worse.label not in self.shape_errs:
            return False
        return paired_z(self.shape_errs[worse.label][on], self.shape_errs[better.label][on]) >= SHAPE_Z

    def refusal(self, item: tuple, physical, reason: str) -> dict:
        """The report's record of the screened ``item`` refused for ``reason``."""
        gain, c, p_value, gains = item
        return refusal_record(c, gain, gains, p_value, self.tests(c), physical, reason)


def screen_round(state: Pass, pool: list, wander_offered: bool, *, alpha: float, max_effects: int, replay: Optional[Decided]) -> Round:
    """One round's screening: the candidates of ``pool`` with this round's steps and wanders
    (:func:`round_candidates`), each scored against the current model linearised at its fit
    (:class:`~.screening.Screen`: held-out gain per fold scheme, F test), and ranked in the order
    :func:`confirm` tries them (:func:`confirmation_order`). The screening's per-fold bases, the
    largest arrays of a diagnosis (a sixth of its peak memory at 3000 samples), are locals here:
    freed when the round ends, not carried through the later stages."""
    ext, x, k, keep, schemes = state.model, state.x, state.k, state.keep, state.schemes
    rows = len(keep) * k  # the data rows: a penalised cause (a wander) appends its roughness rows
    J = ext.jacobian(x)[:rows]
    r = ext.residuals(x)[:rows]
    # What is left alike in time (a wandering reading, a drift that is not linear) is no
    # independent evidence for the candidates that do not model it (round 1: the baseline's
    # residuals, tested already).
    round_test = residual_correlation(state.dataset, keep, r.reshape(len(keep), k)) if ext.causes else state.baseline.residual_test
    inflation = time_inflation(round_test)
    # Residuals alike in joint space and not beyond it in time are evidence for the robot's
    # causes: a wander would take them along the path (UR10 series B: docs/findings.md, D3).
    in_joints = bool(round_test) and round_test.get("verdict") == "joints"
    pool = round_candidates(state, pool, J, r, round_test, wander_offered, replay)
    params = sorted({n for c in pool if c.stage == "parameters" for n in c.params})
    _, p, parts = ext.jacobian_parts(x, [state.robot.index(n) for n in params])
    screen = Screen(J, r, schemes, k)
    model_err = screen.errors(np.zeros((len(r), 0)))
    scored, step_errs, shape_errs, time_errs = [], {}, {}, {}

    def score(c: Candidate) -> None:
        # weighted as the screen's Jacobian and residuals are (pose: the rotation rows)
        if c.stage == "parameters":
            C = parts["extra"][:, [params.index(n) for n in c.params]] * ext.row_weights[:, None]
        else:
            C = ext.weighted_columns(x, c, parts, p)
        errs = screen.errors(C, c.penalty)
        p_value = screen.f_test(C, 1.0 if c.kind in TIME_TERMS else inflation, c.penalty)
        if c.kind in SERIAL_TERMS and p_value < alpha:  # judged with the correlation in time of what it leaves
            left = r - C @ np.linalg.lstsq(C, r, rcond=None)[0]
            p_value = screen.f_test(C, max(inflation, serial_inflation(state.dataset, keep, left.reshape(len(keep), k))), c.penalty)
        on = judgeable(c, keep, schemes)
        gains = {name: rmse_of_squares(model_err[name][on[name]]) - rmse_of_squares(errs[name][on[name]]) for name in schemes}
        if c.kind == "step":
            step_errs[c.label] = errs["random"]
        elif c.kind in SENSOR_KINDS or c.kind == "drift":
            time_errs[c.label] = errs["random"]
        elif c.kind in READING_SHAPES or c.kind in PHYSICAL_KINDS:
            shape_errs[c.label] = errs["random"]
        scored.append((gains["random"], c, p_value, gains))

    for c in progress(pool, desc=f"diagnose: screening round {len(ext.causes) + 1}", unit="candidate"):
        if not (in_joints and c.kind in TIME_TERMS):
            score(c)
    candidates = len(scored) if replay is None else replay.tests
    screening = Round(pool, [], r, rmse_of_squares(model_err["random"]), candidates, k, alpha, state.min_gain, max_effects, shape_errs=shape_errs)
    if replay is None and bent_drift(screening, scored, ext.causes):
        # A drift the random folds show whose line misses the held-out blocks bends: its curves
        # compete in this round (judged within the session, as in try_curved_drift), else a
        # joint cause whose source joint moves with time takes the bend (a coupling named for a
        # drift growing as t^2.5, seed 33 of benches/discovery.py, file 223).
        for curve in curved_drifts(state.dataset):
            score(curve)
        screening.candidates = len(scored)
    # What a gradual change gains, for each step: a ramp from its sample, and the curves of a
    # linear drift the model has (a drift that is not linear leaves bends a step would take).
    steps = [c for _, c, _, _ in scored if c.kind == "step"]
    screened_curves: dict = {}

    def curve_errs() -> dict:
        """The drift's curves' held-out errors on the random folds (label -> errors), screened
        once a round for the steps and the sensor's field alike (a bent drift's were already)."""
        if not screened_curves:
            for curve in curved_drifts(state.dataset):
                screened = time_errs.get(curve.label)
                screened_curves[curve.label] = screened if screened is not None else screen.errors(ext.weighted_columns(x, curve, parts, p))["random"]
        return screened_curves

    shared_errs, slow_errs = [], []  # every step's alternatives
    if steps and any(c.kind == "drift" and not curved_drift(c) for c in ext.causes):
        shared_errs = list(curve_errs().values())
    if steps and state.arcs is None:  # built once a pass: they depend on the samples' order alone
        span = len(state.dataset) - 1
        fine_arcs = [wander_candidate(state.dataset, spacing) for spacing in ARC_SPACINGS]
        slow_arcs = [wander_candidate(state.dataset, share * span, ROUGHNESS * max(WANDER_STIFFER), trend=True) for share in SLOW_ARC_SHARES]
        # a long session widens the fine arcs alike (a wander has at most MAX_KNOTS knots)
        state.arcs = {"fine": list({arc.label: arc for arc in fine_arcs}.values()), "slow": slow_arcs}
    if steps:
        # Where no wander is offered (the residual test measured no correlation length), the arcs
        # of a wandering reading must not be taken for a jump. (Where wanders are offered they
        # compete as candidates: as arcs here, a 5x step lost to the wander that follows it over
        # the random folds, seed 30 of benches/discovery.py, file 48.) Nor, wanders offered or
        # not, a slow wave on a trend: those offered follow the residuals' correlation length,
        # and one of a few samples' knots misses every held-out block (a wave of 1.7 periods cut
        # into two steps, seed 34, file 111).
        fine = [] if any(c.kind == "wander" for c in pool + ext.causes) else state.arcs["fine"]
        arcs = progress(fine + state.arcs["slow"], desc=f"diagnose: round {len(ext.causes) + 1}, the steps against a wandering reading's arcs", unit="arc")
        arc_errs = {arc.label: screen.errors(ext.weighted_columns(x, arc, parts, p), arc.penalty)["random"] for arc in arcs}
        shared_errs += [arc_errs[arc.label] for arc in fine]
        slow_errs = [arc_errs[arc.label] for arc in state.arcs["slow"]]
    position = acquisition_position(state.dataset)
    kept_position, around = position[keep], min(SLOW_ARC_SHARES) * np.ptp(position)  # the finer slow arc's knot spacing
    for c in steps:  # judged on the samples the step is
        on = judgeable(c, keep, schemes)["random"]
        errs = [screen.errors(ext.weighted_columns(x, ramp, parts, p))["random"] for ramp in ramps(state.dataset, c)] + shared_errs
        best = min(errs, key=lambda e: float(np.mean(e[on])))  # the gradual change that gains most
        screening.gradual[c.label] = rmse_of_squares(model_err["random"][on]) - rmse_of_squares(best[on])
        # Not scaled for residuals alike in time: the differences gather where the two models
        # differ (around the step); the public D2 file's 2.9 mm jump of the cable zero, 1.6
        # standard errors so scaled, beats its ramp by 8.3.
        z = paired_z(best[on], step_errs[c.label][on])
        # ... and the slow arcs where a jump differs from them: within the finer arc's knot
        # spacing of the step (judged on every sample, the arcs' fit of the whole session
        # outweighed a true knock of 1.5-2.3 times its limit, seed 36, file 193).
        near = on & (np.abs(kept_position - position[c.detail["sample"]]) <= around)
        if slow_errs and near.any():
            closest = min(slow_errs, key=lambda e: float(np.mean(e[near])))
            z = min(z, paired_z(closest[near], step_errs[c.label][near]))
        screening.jump_z[c.label] = z
        smooth = [screen.errors(ext.weighted_columns(x, t, parts, p))["random"] for t in transitions(state.dataset, c)]
        screening.smooth_z[c.label] = min(paired_z(e[on], step_errs[c.label][on]) for e in smooth)
        shift = c.label.replace(" frame=rigid", "")
        if shift != c.label and shift in step_errs:
            screening.turn_z[c.label] = paired_z(step_errs[shift][on], step_errs[c.label][on])
    # The sensor's field is a function of where each reading was, a time term of when: along a
    # path that wanders through the workspace the two correlate, and the field must predict the
    # held-out samples better than a drift and its curves (a knock and a wave of a tracker, a
    # warm-up, were taken as an azimuth error: the mismatch section). Not better than a wander,
    # which follows any slow change along the path, the field's too (3 of 12 azimuth errors at
    # 3x their limit were then refused).
    sensors = [c for _, c, _, _ in scored if c.kind in SENSOR_KINDS]
    if sensors:
        alternatives = {label: e for label, e in time_errs.items() if not label.startswith(SENSOR_KINDS)} | curve_errs()
        best = min(alternatives.values(), key=lambda e: float(np.mean(e)))
        for c in sensors:
            screening.where_z[c.label] = paired_z(best, time_errs[c.label])
    screening.ranked = confirmation_order(
        scored, screening.significant, inflation, established=any(c.kind in PHYSICAL_KINDS for c in ext.causes), told_apart=screening.told_apart
    )
    return screening


def curved_drifts(dataset: Dataset) -> list:
    """The drifts that are not linear: a natural spline of time and lines with an exponential
    settling (:func:`try_curved_drift`)."""
    return [drift_candidate(dataset, CURVED_DRIFT_DEGREE)] + [drift_candidate(dataset, settling=tau) for tau in SETTLING_TIMES]


def bent_drift(screening: Round, scored: list, causes: list) -> bool:
    """Whether a round's linear drift (``scored``: its screening) passes the F test and gains
    enough on the random folds but not on every fold scheme, in a model (``causes``) with no drift
    and no wander (beside a wander, the screening's blocked figures mean nothing: the trend a
    wander leaves is no bent drift)."""
    if any(c.kind == "drift" or c.kind in TIME_TERMS for c in causes):
        return False
    for gain, c, p_value, gains in scored:
        if c.kind == "drift" and not curved_drift(c):
            return p_value * screening.tests(c) < screening.alpha and gain >= screening.min_gain * screening.rmse and not gains_everywhere(c, gains)
    return False


def round_candidates(state: Pass, pool: list, J, residual: np.ndarray, residual_test: Optional[dict], wander_offered: bool, replay: Optional[Decided]) -> list:
    """``pool`` with a round's own candidates (a replay's pool as it is): steps where the current
    model's ``residual`` changes level, the sensor's own error in the shape the residuals follow
    best with the model's Jacobian ``J`` beside it (:func:`~.sensor_field.sensor_candidates`), and
    wanders on the ``residual_test``'s correlation length while they are ``wander_offered`` and
    the model has none."""
    if replay is not None:
        return pool
    causes, keep, k = state.model.causes, state.keep, state.k
    # Steps where the current model's residuals change level: those of the geometric fit
    # alone misplace a step by the geometry's errors along the path (7-14 samples off on
    # simulated files).
    taken = {c.detail["sample"] for c in causes if c.kind == "step"}
    pool = [c for c in pool if c.kind != "step"] + [
        c
        for c in step_candidates(
            state.dataset, keep, residual.reshape(len(keep), k), state.robot.with_vector(state.model.full(state.x)), J[:, : len(state.model.free)]
        )
        if c.detail["sample"] not in taken
    ]
    pool = [c for c in pool if c.kind not in SENSOR_KINDS] + sensor_candidates(state.dataset, keep, J, residual, [c for c in causes if c.kind in SENSOR_KINDS])
    # Residuals alike from one sample to the next: the sensor may wander (a wander a larger
    # cause hid shows once that cause is in). Its knots at half the correlation length and
    # coarser, and its roughness penalty as set and stronger: noise and unmodelled causes
    # shorten the measured length, and a wander more flexible than the sensor's takes
    # geometry along (simulated wanders of length 17-20 measured 8-16; knots 4 samples apart
    # cost the blocked folds 47 %, ten times the penalty 10 % instead of 36 %). The most
    # flexible that does the geometry no harm is taken (each is tried in turn).
    length = None if residual_test is None else residual_test["correlation_length_samples"]
    pool = [c for c in pool if c.kind != "wander"]
    if wander_offered and length is not None and not any(c.kind == "wander" for c in causes):
        pool += [wander_candidate(state.dataset, length * factor, ROUGHNESS * stiffer) for factor in WANDER_SPACINGS for stiffer in WANDER_STIFFER]
    return pool


def confirmation_order(scored: list, significant, inflation: float, established: bool, told_apart=lambda better, worse: False) -> list:
    """A round's ``scored`` candidates (``(gain, candidate, p_value, gains)``; ``significant``
    judges one: :meth:`Round.significant`) in the order :func:`confirm` tries them: largest gain
    first, the simpler of two alike first (:func:`simplest_first`), a gravity compliance before
    the free joint shape it resembles (:func:`physics_first`; ``established``: the model has
    one), a drift or a step that gains about as much as a wander before the wander (and only
    before the wanders: what gains more keeps its place), and, when
    the residuals wander in time (``inflation`` > 1), the significant time terms ahead of the
    rest."""
    scored = sorted(scored, key=lambda s: -s[0])
    scored = simplest_first(scored)
    scored = physics_first(scored, lambda s: s[0], lambda s: s[1], lambda s: significant(*s), established=established, told_apart=told_apart)
    scored = mass_model_first(scored, significant)
    # A drift or a step that gains at least SENSOR_TERM_SHARE of what a significant wander gains
    # is judged before it: one coefficient per axis against dozens, and a wander fine enough
    # follows a drift, or smooths a jump, as well (a simulated drift well beyond its detection
    # limit was named a wander; on the public D2 file a wander took the place of the step and
    # ended higher: docs/findings.md) — also where the residual test does not say the residuals
    # wander (a drift beside a joint's error, seed 27 of benches/discovery.py: named a wander).
    wander_gain = max((s[0] for s in scored if s[1].kind in TIME_TERMS and significant(*s)), default=np.inf)

    def simpler_than_wander(s) -> bool:  # a curve of time (within_session) is no simpler than a wander
        return s[1].kind in ("drift", "step") and not within_session(s[1]) and significant(*s) and s[0] >= SENSOR_TERM_SHARE * wander_gain

    if inflation > 1.0:
        # The residuals wander in time: the significant time terms are judged before the rest —
        # a temperature first, the measured signal a wander would otherwise imitate (a warm-up
        # is smooth in time), then the simpler sensor terms, then the wander, before the steps
        # and trends that would chop it up.
        def time_rank(s) -> int:
            if not significant(*s):
                return 3
            if s[1].kind == "temperature":
                return 0
            if simpler_than_wander(s):
                return 1
            return 2 if within_session(s[1]) else 3

        return sorted(scored, key=time_rank)
    # Only the wanders wait for the simpler sensor terms: a candidate that gains more than a
    # drift keeps its place before it (a temperature that gained 40 % more than a drift was tried
    # after it, and the drift took its place: seed 30 of benches/discovery.py, file 33).
    last = max((i for i, s in enumerate(scored) if simpler_than_wander(s)), default=None)
    if last is None:
        return scored
    deferred = [s for s in scored[:last] if within_session(s[1])]
    ahead = [s for s in scored[:last] if not within_session(s[1])] + [scored[last]]
    return ahead + deferred + scored[last + 1 :]


def confirm(state: Pass, screening: Round) -> Optional[Candidate]:
    """The nonlinear checks of a round's significant candidates, in the round's order: each is
    fitted (all parameters re-fitted); the first whose physical parameters are plausible
    (:data:`~robocal.causes.candidates.LIMITS`) and determined and whose held-out gain
    survives the nonlinear re-fits on every fold scheme is taken into the model and the report
    (:func:`_take_cause`) and returned; None if none is. Each one that fails is refused with its
    reason (as is a step that is not significant); after :data:`MAX_TRIALS` joint candidates,
    the rest are not fitted."""
    rob, ext, x, keep, schemes, rejected = state.robot, state.model, state.x, state.keep, state.schemes, state.rejected
    joint_trials, gradual_level = 0, None
    for item in screening.ranked:
        _, c, p_value, gains = item
        significant = screening.significant(*item)
        if not significant and c.kind == "step":
            if not any(e["label"] == c.label for e in rejected):
                rejected.append(screening.refusal(item, None, "not significant over every possible step position"))
            continue
        if not significant:  # a larger gain of more coefficients may miss the level a smaller one passes
            continue
        if c.kind == "step" and (gradual_level or screening.jump_z.get(c.label, np.inf) < JUMP_Z):
            # A drift that sets in, ends or bends, or an arc of a wandering reading, changes the
            # level gradually: a ramp or a curve predicts the held-out samples about as well, and
            # the jump is not shown. The round's other steps are pieces of the same change (one
            # refused let the next one in).
            if gradual_level:
                why = f"the round's largest level change ({gradual_level}) is gradual: no jump shown"
            else:
                gradual = "a gradual change (a ramp from the same sample, a curve of the model's drift, a wandering reading, or a slow change around it)"
                why = (
                    f"{gradual} gains {screening.gradual[c.label]:.3g} mm on the random folds against the step's {item[0]:.3g} mm; "
                    f"the step's held-out errors beat it by {screening.jump_z[c.label]:.2f} standard errors, below {JUMP_Z:.2f}: no jump shown"
                )
                gradual_level = c.label
            rejected.append(screening.refusal(item, None, why))
            continue
        if screening.where_z.get(c.label, np.inf) < JUMP_Z:
            rejected.append(
                screening.refusal(
                    item,
                    None,
                    f"a function of time (a drift or its curves) predicts as well: the sensor's field beats it by "
                    f"{screening.where_z[c.label]:.2f} standard errors, below {JUMP_Z:.2f}: not shown to follow where the readings were",
                )
            )
            continue
        if screening.turn_z.get(c.label, np.inf) < JUMP_Z:
            # The sensor's rigid move claims a turn (or the anchor's move) beyond a shift of its
            # readings: the shift at the same sample must predict the held-out samples worse
            # (a rigid step took the leftover of time-correlated noise and of a sensor's own error).
            why = (
                f"the readings shifted at the same sample predict as well: the move and turn beat the shift by {screening.turn_z[c.label]:.2f} "
                f"standard errors, below {JUMP_Z:.2f}: no turn shown"
            )
            rejected.append(screening.refusal(item, None, why))
            continue
        if c.stage == "joints":
            if joint_trials >= MAX_TRIALS:
                why = f"not fitted: {MAX_TRIALS} joint candidates with larger screening gains failed the nonlinear checks this round"
                rejected.append(screening.refusal(item, None, why))
                continue
            joint_trials += 1
        trial = state.problem(with_cause(ext.causes, c))
        fit = fit_problem(trial, x0=trial.start_from(x, ext))
        physical, why = c.physical(trial.coefficients(fit.x, c), coefficient_std(trial, fit, c), rob, rob.params)
        why = f"implausible: {why}" if why else undetermined(trial.coefficients(fit.x, c) - coefficient_reference(c, rob), coefficient_std(trial, fit, c))
        if why is not None:
            rejected.append(screening.refusal(item, physical, why))
            continue
        # The screening is linear; the gain must survive the nonlinear re-fit on every scheme.
        new_cv, new_fold_x = cross_validate(trial, schemes, state.fold_x, ext)
        refusal = held_out_refusal(c, schemes, keep, state.cv, new_cv)
        if refusal:
            rejected.append(screening.refusal(item, physical, refusal))
            continue
        _take_cause(state, screening, c, p_value, gains, physical, trial, fit, new_cv, new_fold_x)
        return c
    return None


def _take_cause(
    state: Pass,
    screening: Round,
    c: Candidate,
    p_value: float,
    gains: dict,
    physical,
    trial: ExtendedProblem,
    fit: CalibrationResult,
    new_cv: dict,
    new_fold_x: dict,
) -> None:
    """The confirmed cause ``c`` taken: ``trial`` (the model with it, fitted by ``fit``, its held-out
    errors ``new_cv`` and fold fits ``new_fold_x``) becomes the current model; its report entry and its plot (the residual
    it was found in, against its fitted signature) are written, and the entry of a cause it took
    the place of retracted."""
    for refined in [o for o in state.model.causes if o not in trial.causes]:  # what c took the place of (:func:`with_cause`)
        state.retract(refined, None, f"replaced by {c.label} (the same joint's compliance on any masses and payload)")
    signature = trial.columns(fit.x, c) @ (trial.coefficients(fit.x, c) - coefficient_reference(c, state.robot))
    state.plots[c.label] = {"residual": screening.residual, "signature": signature, "k": state.k}
    state.effects.append(
        {
            "kind": c.kind,
            "joint": None if c.joint is None else c.joint + 1,
            "label": c.label,
            "params": physical,
            "rmse_heldout_before": reported_rmse(state.cv["random"]),
            "rmse_heldout_after": reported_rmse(new_cv["random"]),
            "significance": {
                "test": "extra-sum-of-squares F test of the linearised model, Bonferroni over the candidates; held-out gain required on every fold scheme",
                "p_value": p_value,
                "p_adjusted": min(1.0, p_value * screening.tests(c)),
                "candidates": screening.candidates,
                "screening_gain_mm": gains,
                "rmse_heldout_blocked_before": reported_rmse(state.cv["blocked"]),
                "rmse_heldout_blocked_after": reported_rmse(new_cv["blocked"]),
                "undetermined_between": alike_shapes(screening, c, judgeable(c, state.keep, state.schemes)["random"]),
            },
        }
    )
    state.model, state.x, state.cv, state.fold_x = trial, fit.x, new_cv, new_fold_x


#: Kinds of a joint's reading error whose shapes a joint's range may not tell apart: over a few
#: tens of degrees a scale error, a first harmonic and a coupling to a joint that moves with it
#: bend the readings alike.
READING_SHAPES = ("joint_scale", "joint_periodic", "joint_coupling")
#: The named shape must beat another significant one of its joint by this many standard errors
#: (paired z of the screening's held-out errors, one-sided 2.5 %), or the report names both.
SHAPE_Z = float(norm.isf(0.025))


def alike_shapes(screening: Round, c: Candidate, on: np.ndarray) -> list:
    """The labels of the other significant shapes of ``c``'s joint's reading error, or of any
    joint's driven by the same joint's angle (:data:`READING_SHAPES`, :func:`driving_joint`),
    whose held-out errors in the round's screening ``c``'s do not beat by :data:`SHAPE_Z`
    standard errors on the samples ``on``: alternatives the data cannot tell from ``c``. The
    claim is then "one of these", as a convention's is. Of a step: a drift, where it does not
    beat a smooth level change through its sample (:attr:`Round.smooth_z`)."""
    if c.kind == "step":
        return ["drift"] if screening.smooth_z.get(c.label, np.inf) < SHAPE_Z else []
    if c.kind not in READING_SHAPES:
        return []
    return [
        o.label
        for item in screening.ranked
        if (o := item[1]).kind in READING_SHAPES
        and (o.joint == c.joint or driving_joint(o) == driving_joint(c))
        and o.label != c.label
        and screening.significant(*item)
        and not screening.told_apart(c, o, on)
    ]


def driving_joint(c: Candidate) -> int:
    """The joint whose angle a reading shape is a function of: its own, a coupling's source (a
    coupling of joint 5 to joint 6 and a scale error of joint 6 both grow with joint 6's angle:
    the simulated scale of joint 6 was named a coupling of joint 5 with no alternative stated,
    seed 33 of benches/discovery.py, file 98)."""
    return c.detail["source"] - 1 if c.kind == "joint_coupling" else c.joint


def _refuse_best(state: Pass, screening: Round) -> None:
    """A round that took nothing: its five best candidates not refused yet, refused with the test
    they failed."""
    for item in screening.ranked[:5]:
        gain, c, p_value, _ = item
        if not any(e["label"] == c.label for e in state.rejected):
            if p_value * screening.tests(c) >= screening.alpha:
                why = "not significant"
            elif gain < screening.min_gain * screening.rmse:
                why = f"held-out gain below {screening.min_gain:.1%} of the RMSE"
            else:
                why = "no gain on every fold scheme"
            state.rejected.append(screening.refusal(item, None, why))


#: A linear drift beside a wander is named only when the sensor's time term puts more into its
#: line than a wander puts by chance, at this level (:func:`~.wander.trend_beyond_chance`).
CHANCE_TREND_LEVEL = 0.05


def wander_keeps_its_trend(state: Pass) -> None:
    """Stage 3a: a drift and a wander judged on equal terms. The wander is fitted without its
    trend (a steady trend is a drift, one coefficient per axis), so a wandering reading's
    chance trend over the session was named a drift beside it. A linear drift beside a wander
    stays named only when the sensor's time term (wander and drift) puts more into its line than
    into the next orders of the session (:func:`~.wander.trend_beyond_chance` at
    :data:`CHANCE_TREND_LEVEL`); otherwise the wander keeps its trend (``trend=kept``: the
    same columns, the same fit in the model) and the drift is retracted."""
    model, x = state.model, state.x
    wander = next((c for c in model.causes if c.kind == "wander" and "trend" not in c.detail), None)
    drift = next((c for c in model.causes if c.kind == "drift" and not curved_drift(c)), None)
    if wander is None or drift is None:
        return
    axes = len(wander.detail["axes"])
    order = acquisition_order(model.full_data)
    order = order[np.isin(order, model.idx)]
    path = (wander.basis @ model.coefficients(x, wander))[order, :axes]
    trend = (drift.basis @ model.coefficients(x, drift))[order, :axes]
    ratio, p = trend_beyond_chance(path, trend)
    if p < CHANCE_TREND_LEVEL:
        return
    kept = wander_candidate(model.full_data, wander.detail["spacing"], wander.detail.get("roughness", ROUGHNESS), trend=True)
    trial = state.problem([kept if c is wander else c for c in model.causes if c is not drift])
    fit = fit_problem(trial, x0=trial.start_from(x, model))
    cv, fold_x = cross_validate(trial, state.schemes, state.fold_x, model)
    why = (
        f"the wander's own trend: the sensor's time term puts {ratio:.3g}× as much into its line as into the next "
        f"{CHANCE_ORDERS} orders of the session, as a wander does by chance (p = {p:.2g} ≥ {CHANCE_TREND_LEVEL:g}); the wander keeps it ({kept.label})"
    )
    state.retract(drift, None, why)
    entry = next(e for e in state.effects if e["label"] == wander.label)
    entry["label"], entry["params"] = kept.label, kept.physical(trial.coefficients(fit.x, kept), None, model.robot, model.robot.params)[0]
    entry["rmse_heldout_after"] = reported_rmse(cv["random"])
    if wander.label in state.plots:
        state.plots[kept.label] = state.plots.pop(wander.label)
    state.model, state.x, state.cv, state.fold_x = trial, fit.x, cv, fold_x


def with_cause(causes: list, c: Candidate) -> list:
    """``causes`` with ``c``: in the place of what it refines (a compliance on any masses in the
    place of its joint's on the mass model's torque, whose columns it spans), else added."""
    refined = [o for o in causes if on_free_masses(c) and o.kind == "joint_compliance" and o.joint == c.joint]
    return [c if o in refined else o for o in causes] if refined else causes + [c]


def try_curved_drift(state: Pass) -> None:
    """Stage 3: a drift that is not linear (a warm-up, a stand settling). The model's linear
    drift, if it has one, is replaced by the best of a natural spline of time
    (:data:`~robocal.causes.candidates.CURVED_DRIFT_DEGREE`) and a line with an exponential settling
    (:data:`~robocal.causes.candidates.SETTLING_TIMES`) when that lowers the random folds' held-out RMSE by
    ``min_gain`` of it, significantly as any cause must (:func:`held_out_refusal`: a settling
    fitted to a linear drift gained 1 % by chance), and does no harm on the others. Its leftovers would otherwise be taken by
    steps, harmonics and couplings that the backward check then no longer needs (a drift fast
    at first left a step in its first dozen samples). In the report, the curved drift's entry
    (and plot) takes the linear one's place, and the steps it made unnecessary are retracted."""
    model, x, schemes, current_cv, fold_x, min_gain = state.model, state.x, state.schemes, state.cv, state.fold_x, state.min_gain
    linear = [c for c in model.causes if c.kind == "drift" and not curved_drift(c)]
    if not linear:
        return
    before = judged_rmse(current_cv["random"])
    best = None
    shapes = curved_drifts(model.full_data)
    steps = [c for c in model.causes if c.kind == "step"]
    for curved in shapes:
        # with the steps, and without them: a drift fast at first has bred a step in its first
        # samples before the curved shape was tried; the model without them is simpler, and
        # taken when it is as good
        for leave_out in [[], steps] if steps else [[]]:
            trial = ExtendedProblem(
                model.base, [curved if c is linear[0] else c for c in model.causes if not any(c is o for o in leave_out)], model.full_data, model.idx
            )
            fit = fit_problem(trial, x0=trial.start_from(x, model))
            cv, trial_fold_x = cross_validate(trial, schemes, fold_x, model)
            after = judged_rmse(cv["random"])
            physical, why = curved.physical(trial.coefficients(fit.x, curved), coefficient_std(trial, fit, curved), model.robot, model.robot.params)
            if leave_out:
                on = judgeable(curved, model.idx, schemes)
                passes = after <= (1.0 + SAME_GAIN) * before and all(improves(curved, name, current_cv[name][on[name]], cv[name][on[name]]) for name in schemes)
            else:  # a claim of a shape: the held-out test any cause passes (a settling fitted to a linear drift)
                passes = before - after >= min_gain * before and held_out_refusal(curved, schemes, model.idx, current_cv, cv) is None
            if why is None and passes:
                key = (len(trial.causes), after)
                if best is None or key < best[0]:
                    best = (key, curved, trial, fit, trial_fold_x, cv, physical, leave_out)
    if best is None:
        return
    _, curved, trial, fit, trial_fold_x, cv, physical, left_out = best
    shape = (
        f"a line and an exponential settling of time constant {curved.detail['settling']:g} of the session"
        if "settling" in curved.detail
        else f"a natural spline of time of {CURVED_DRIFT_DEGREE} coefficients"
    )
    polynomial = f"{shape} in the place of the linear drift (the best held-out of {len(shapes)} shapes)"
    entry = {
        "kind": "drift",
        "joint": None,
        "label": curved.label,
        "params": physical,
        "rmse_heldout_before": reported_rmse(current_cv["random"]),
        "rmse_heldout_after": reported_rmse(cv["random"]),
        "significance": {
            "test": f"{polynomial}: held-out gain of at least {min_gain:.1%} on the random folds, significant at one-sided {GAIN_LEVEL:g} (paired z), no harm on the others",
            "p_value": None,
            "p_adjusted": None,
            "screening_gain_mm": None,
            "rmse_heldout_blocked_before": reported_rmse(current_cv["blocked"]),
            "rmse_heldout_blocked_after": reported_rmse(cv["blocked"]),
        },
    }
    state.model, state.x, state.cv, state.fold_x = trial, fit.x, cv, trial_fold_x
    for c in left_out:
        state.retract(c, None, f"a curve of the drift ({curved.label}) explains it as well")
    replaced = next(e for e in state.effects if e["kind"] == "drift")  # in the linear drift's place, in the report too
    state.effects[state.effects.index(replaced)] = entry
    if replaced["label"] in state.plots:
        state.plots[curved.label] = state.plots.pop(replaced["label"])


def backward(state: Pass, droppable=lambda c: True) -> None:
    """Stage 4: every cause of the model must still earn its place once the causes found after
    it are in.

    The forward selection judges a cause against the model before it; leftovers of a cause
    whose model is slightly off (a compliance on masses that are not the mass model's, a drift
    that is not linear), or of a cause found later, are taken by small causes that the later
    model no longer needs. Each cause is left out in turn and the model re-fitted (nonlinear,
    on every fold scheme, from the fold fits of the full model); a cause that fails the test of
    a new one against the model without it (:func:`held_out_refusal`: a significant held-out
    gain on every scheme; and at least ``min_gain`` of the RMSE on the random folds) is
    dropped, the cheapest first, until every cause earns its place (only the ``droppable``
    ones are judged). The causes dropped are retracted from the report. Run again after the
    maps (:func:`joint_maps`)."""
    model, x, schemes, current_cv, fold_x, min_gain = state.model, state.x, state.schemes, state.cv, state.fold_x, state.min_gain
    causes = list(model.causes)
    while len(causes) >= 2:
        full = ExtendedProblem(model.base, causes, model.full_data, model.idx)
        weakest, linear, with_it = None, _linearised(full, x), judged_rmse(current_cv["random"])
        for c in filter(droppable, causes):
            if linear is not None and _clearly_earns(full, linear, x, c, schemes, min_gain):
                continue
            rest = ExtendedProblem(model.base, [o for o in causes if o is not c], model.full_data, model.idx)
            cv, rest_fold_x = cross_validate(rest, schemes, fold_x, full)
            without = judged_rmse(cv["random"])
            refusal = held_out_refusal(c, schemes, model.idx, cv, current_cv)
            if refusal is None and without - with_it < min_gain * without:
                refusal = f"held-out gain below {min_gain:.1%} of the RMSE"
            if refusal and (weakest is None or without < weakest[1]):
                weakest = (c, without, rest, cv, rest_fold_x, refusal)
        if weakest is None:
            break
        c, without, rest, rest_cv, rest_fold_x, refusal = weakest
        state.retract(
            c, None, f"no longer earns its place once the causes found after it are in: held-out RMSE {with_it:.4g} with it, {without:.4g} without ({refusal})"
        )
        x = fit_problem(rest, x0=rest.start_from(x, full)).x
        current_cv, fold_x = rest_cv, rest_fold_x
        causes = list(rest.causes)
    state.model, state.x, state.cv, state.fold_x = state.problem(causes), x, current_cv, fold_x


#: A cause whose linearised held-out gain over the model without it is this many times what
#: the forward test asks earns its place without the nonlinear re-fits.
CLEAR_MARGIN = 3.0


def _linearised(full: ExtendedProblem, x: np.ndarray) -> Optional[tuple]:
    """The data rows of ``full``'s Jacobian and residuals at ``x``, once per backward round, or
    None for a sparse Jacobian (joint maps), which the linear pre-check does not take."""
    J = full.jacobian(x)
    if is_sparse(J):
        return None
    rows = len(full.idx) * full.k
    return J[:rows, : full.n], full.residuals(x)[:rows]


def _clearly_earns(full: ExtendedProblem, linear: tuple, x: np.ndarray, c: Candidate, schemes: dict, min_gain: float) -> bool:
    """Whether ``c`` earns its place in ``full`` by a wide margin already in the model
    linearised at ``x`` (``linear``: :func:`_linearised`; the screening's cross-validation of its
    columns against the rest, its coefficients set to zero in the residual): a gain on every
    scheme of :data:`CLEAR_MARGIN` times what the forward test asks, significant as that asks
    (:data:`~.validation.GAIN_Z`). The backward check then needs no nonlinear re-fits for it.
    Only for a cause with columns of its own."""
    if c.stage == "parameters":
        return False
    J, r = linear
    at = full.slices[full.causes.index(c)]
    C = J[:, at]
    rest = np.delete(J, np.arange(at.start, at.stop), axis=1)
    screen = Screen(rest, r + C @ np.asarray(x)[at], schemes, full.k)  # the residual with the cause taken out
    base, errs = screen.errors(np.zeros((len(r), 0))), screen.errors(C, c.penalty)
    on = judgeable(c, full.idx, schemes)
    gains = {name: rmse_of_squares(base[name][on[name]]) - rmse_of_squares(errs[name][on[name]]) for name in schemes}
    clear = gains_everywhere(c, gains) and gains["random"] >= CLEAR_MARGIN * min_gain * rmse_of_squares(base["random"])
    return clear and paired_z(base["random"][on["random"]], errs["random"][on["random"]]) >= GAIN_Z


def joint_maps(state: Pass, alpha: float, replay: Optional[Decided]) -> tuple[list, list]:
    """Stage 5: joint error maps (:mod:`.maps`). A joint's harmonics are merged into one map
    where it does as well (:func:`~.maps.merge_harmonics`); then a map per joint is screened and
    confirmed (:func:`~.maps.map_stage`; a ``replay`` offers only the maps the earlier pass took,
    with its Bonferroni count). Each map taken enters the report in the place of the causes it
    replaces, each refused one among the rejected; if a map was taken, the earlier free shapes
    go through the :func:`backward` check again. Returns the map stage's records of the maps
    accepted and refused."""
    model, x, current_cv, fold_x, merged = merge_harmonics(state.model, state.x, state.schemes, state.cv, state.fold_x)
    state.model, state.x, state.cv, state.fold_x = model, x, current_cv, fold_x
    # ``{label}`` is filled in by _take_map with the merged map's label.
    within = f"the same held-out error within {conventions.EQUAL:.0%}"
    merged_why = f"merged with the joint's other harmonics into {{label}} ({within}: one periodic error of the joint, not several gear harmonics)"
    for m in merged:
        test = f"in the place of {len(m['replaces'])} harmonics of its joint, held-out error within {conventions.EQUAL:.0%} of theirs on every fold scheme"
        significance = {"test": test, "p_value": None, "p_adjusted": None, "screening_gain_mm": None}
        _take_map(state, m, merged_why, significance)
    model, x, current_cv, fold_x, accepted_maps, rejected_maps = map_stage(
        model,
        x,
        state.schemes,
        current_cv,
        fold_x,
        alpha=alpha,
        min_gain=state.min_gain,
        only=None if replay is None else replay.maps,
        tests=None if replay is None else replay.map_tests,
    )
    state.model, state.x, state.cv, state.fold_x = model, x, current_cv, fold_x
    replaced_why = "replaced by {label} (the same joint's error in finer detail; held-out gain of the map in its place)"
    map_test = (
        "extra-sum-of-squares F test of the unpenalised map columns, Bonferroni over the maps tried; "
        "held-out gain of the penalised map required on every fold scheme"
    )
    for m in accepted_maps:
        significance = {"test": map_test, "p_value": m["p_value"], "p_adjusted": min(1.0, m["p_value"] * m["tests"]), "screening_gain_mm": m["gains_mm"]}
        _take_map(state, m, replaced_why, significance)
    for m in rejected_maps:
        c = m["candidate"]
        state.rejected.append(refusal_record(c, m["gains_mm"]["random"], m["gains_mm"], m["p_value"], m["tests"], m.get("params"), m["reason"]))
    if accepted_maps and any(c.kind != "joint_map" for c in model.causes):
        # a map may explain what a cause found before it took (a time term along a path
        # that sweeps the mapped joint): every earlier free shape must earn its place again
        # (a gravity compliance keeps its place before a map, as in the forward selection)
        backward(state, lambda c: c.kind != "joint_map" and not_physical(c))
    return accepted_maps, rejected_maps


def _take_map(state: Pass, m: dict, why_replaced: str, significance: dict) -> None:
    """A map the map stage accepted (or merged in) into the report: the causes it takes the place
    of retracted (``why_replaced`` with ``{label}`` the map's), its entry with ``significance``
    and its held-out figures."""
    c = m["candidate"]
    for o in m["replaces"]:
        state.rejected.append({**retraction(o, state.effects, state.plots, None, why_replaced.format(label=c.label)), "replaced_by": c.label})
    before, after = m["rmse_heldout_before"], m["rmse_heldout_after"]
    state.effects.append(
        {
            "kind": c.kind,
            "joint": c.joint + 1,
            "label": c.label,
            "params": m["params"],
            "rmse_heldout_before": before["random"],
            "rmse_heldout_after": after["random"],
            "significance": {**significance, "rmse_heldout_blocked_before": before["blocked"], "rmse_heldout_blocked_after": after["blocked"]},
        }
    )


def recheck_compliances(state: Pass) -> None:
    """Stage 6: the compliances whose size, fitted with every cause found after them, is
    implausible or undetermined dropped from the model (:func:`physics_first` lets a compliance
    go before a free shape it resembles; when that shape is the real cause — a scale error of
    the same joint, say — the compliance is left with nothing to explain), its held-out errors
    measured again, and each one dropped retracted from the report. A compliance on free masses
    so judged gives its place back to its joint's compliance on the mass model's torque, which
    is judged the same way (on UR10 series C joint 2's free masses fell implausible once the
    joint maps were in, and dropped with them the compliance the series needs: 0.096 -> 0.109 mm
    held out)."""
    model, x, schemes, fold_x = state.model, state.x, state.schemes, state.fold_x
    if not any(c.kind in PHYSICAL_KINDS for c in model.causes):
        return
    before_cv = state.cv
    causes, dropped, restored = list(model.causes), [], []
    fit = fit_problem(model, x0=x)
    current = model
    for _ in range(2):  # the free masses' fallbacks are judged once more, after their refit
        failed = []
        for c in [c for c in causes if c.kind in PHYSICAL_KINDS]:
            values, std = current.coefficients(fit.x, c), coefficient_std(current, fit, c)
            physical, why = c.physical(values, std, current.robot, current.robot.params)
            why = f"implausible: {why}" if why else undetermined(values - coefficient_reference(c, current.robot), std)
            if why is not None:
                failed.append((c, physical, why))
        if not failed:
            break
        dropped += failed
        fallbacks = {c: compliance_candidate(current.robot, current.full_data, c.joint) for c, _, _ in failed if on_free_masses(c)}
        restored += list(fallbacks.values())
        causes = [fallbacks.get(c, c) for c in causes if c in fallbacks or all(c is not d for d, _, _ in failed)]
        trial = ExtendedProblem(model.base, causes, model.full_data, model.idx)
        fit = fit_problem(trial, x0=trial.start_from(fit.x, current))
        current = trial
        if not fallbacks:
            break
    if not dropped:
        return
    state.model, state.x = current, fit.x
    state.cv, state.fold_x = cross_validate(current, schemes, fold_x, model)
    for c, physical, why in dropped:
        if c in restored:  # a fallback that failed too: never in the report
            state.rejected.append(refusal_record(c, None, None, None, 1, physical, f"in the place of its free masses: {why}"))
        else:
            state.retract(c, physical, f"dropped once the causes found after it were in: {why}")
    restored = [c for c in restored if c in causes]
    for c in restored:  # back in the report, in the place of its free masses
        physical, _ = c.physical(current.coefficients(fit.x, c), coefficient_std(current, fit, c), current.robot, current.robot.params)
        state.effects.append(
            {
                "kind": c.kind,
                "joint": c.joint + 1,
                "label": c.label,
                "params": physical,
                "rmse_heldout_before": reported_rmse(before_cv["random"]),
                "rmse_heldout_after": reported_rmse(state.cv["random"]),
                "significance": {
                    "test": "the compliance on the mass model's torque, back in the place of its joint's compliance on free masses, which fell implausible or undetermined once the causes found after it were in; its size plausible and determined",
                    "p_value": None,
                    "p_adjusted": None,
                    "screening_gain_mm": None,
                    "rmse_heldout_blocked_before": reported_rmse(before_cv["blocked"]),
                    "rmse_heldout_blocked_after": reported_rmse(state.cv["blocked"]),
                },
            }
        )


#: A cause with a physical model of how it carries is tried before the best free joint shape
#: when its screening gain is at least this share of the shape's — or whatever its share once
#: the model has one. The share separates a compliance that a harmonic would replace from a
#: harmonic the compliance only grazes (the shares measured: docs/findings.md, D3).
PHYSICS_SHARE = 0.5


def physics_first(ranked: list, gain, cause, eligible=lambda item: True, established: bool = False, told_apart=lambda better, worse: False) -> list:
    """``ranked`` (best first; ``gain(item)`` the item's held-out gain, ``cause(item)`` its
    candidate) with each ``eligible`` cause that has a physical model of how it carries
    (:data:`PHYSICAL_KINDS`: gravity compliance) moved before the first eligible free joint
    shape (harmonic, scale, coupling, backlash, map) if it gains at least :data:`PHYSICS_SHARE`
    of that shape's gain, or any share if one is ``established`` (the model already has a
    compliance: the data have shown the robot bends under gravity, and the other loaded joints
    bend too). Until one is, it stays behind the free shapes of its own joint ranked ahead of it
    that the data tell from it (``told_apart(better, worse)``: :meth:`Round.told_apart`): a scale
    error of joint 2 that beat joint 2's compliance by 2-5 standard errors was named a compliance
    (seeds 36 and 37 of benches/discovery.py). Within one session a harmonic — and then a joint map — can take a compliance's
    shape and raise the error on other sessions, while a compliance, driven by the gravity torque
    of the pose, carries to any session; across sessions, maps of other joints taken first can
    leave a compliance nothing to gain (both seen on the UR10 series: docs/findings.md, D3).
    A sensor's drift or step, a reading convention and a harmonic the compliance only
    grazes keep their rank. Used by the single-session selection (screening gains) and the
    multi-session one (leave-one-session-out gains)."""

    def free_shape(item) -> bool:
        c = cause(item)
        return getattr(c, "stage", None) == "joints" and c.kind not in PHYSICAL_KINDS and eligible(item)

    at = next((i for i, item in enumerate(ranked) if free_shape(item)), None)
    if at is None:
        return ranked
    bar = 0.0 if established else PHYSICS_SHARE * gain(ranked[at])
    order, front = list(ranked), at
    for item in ranked[at + 1 :]:
        if cause(item).kind in PHYSICAL_KINDS and eligible(item) and gain(item) >= bar:
            # ahead of the first free shape (behind those moved before it), but behind the shapes
            # of its own joint that the data tell from it
            i = next(n for n, o in enumerate(order) if o is item)
            own = [] if established else [n for n, f in enumerate(order[:i]) if free_shape(f) and cause(f).joint == cause(item).joint]
            place = max([front] + [n + 1 for n in own if told_apart(cause(order[n]), cause(item))])
            order.insert(place, order.pop(i))
            if place == front:  # the next compliance moved goes behind this one
                front += 1
    return order


def mass_model_first(ranked: list, significant) -> list:
    """``ranked`` ((gain, candidate, ...) best first) with each significant compliance on the mass
    model's torque (one coefficient) moved before a compliance on free masses (a coefficient per
    base parameter of static gravity) that gains less than 1/:data:`PHYSICS_SHARE` times as
    much: the mass model is the prior, left only where the data ask for it (joint 2's free
    masses took joint 3's compliance and a harmonic of joint 2 where both were hidden)."""
    out = list(ranked)
    for i in range(len(out)):
        gain, c = out[i][0], out[i][1]
        if on_free_masses(c):
            simpler = [
                j
                for j in range(i + 1, len(out))
                if out[j][1].kind == "joint_compliance" and not on_free_masses(out[j][1]) and significant(*out[j]) and out[j][0] >= PHYSICS_SHARE * gain
            ]
            if simpler:
                out.insert(i, out.pop(simpler[0]))
    return out


def not_physical(c: Candidate) -> bool:
    """Whether the backward check may drop ``c``: not a gravity compliance (a harmonic or a
    joint's other free shapes take a compliance's shape within one session and would win by a
    little, but only the compliance carries to other poses: :func:`physics_first`; UR10 series A
    lost joint 3's compliance to harmonics before its maps were in). A compliance is dropped
    only when its size is implausible or undetermined (:func:`recheck_compliances`)."""
    return c.kind not in PHYSICAL_KINDS


def coefficient_reference(cause: Candidate, robot: Robot) -> np.ndarray:
    """What a cause's coefficients are measured from: zero, or nominal for parameters."""
    if cause.stage == "parameters":
        return robot.params[[robot.index(n) for n in cause.params]]
    return np.zeros(cause.size)


def undetermined(values: np.ndarray, std: Optional[np.ndarray]) -> Optional[str]:
    """A reason if the fitted values are not distinguishable from zero (|value| < 2 std): the
    data then cannot say how large the cause is, whatever the fit gained."""
    if std is None:
        return "undetermined: singular covariance"
    if np.all(np.abs(values) < 2.0 * std):
        return f"undetermined: {values[0]:.3g} ± {std[0]:.2g} (less than 2 standard deviations)"
    return None
