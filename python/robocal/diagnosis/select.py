"""Choosing causes by held-out gain: ``robocal.diagnose``.

1. Fit the geometric baseline (the identifiable subset; Hayati ``beta`` on nominally parallel
   axes unless ``hayati=False``). Gross outliers are named first: samples whose residual lies
   beyond the Bonferroni bound of a robust (MAD) noise scale and beyond :data:`GROSS_SIGMAS`,
   re-decided after refitting without them until the set is stable, and checked again under
   the final extended model.
2. Screen every candidate by cross-validation of the model linearised at the current fit:
   per fold, least squares of the residuals on ``[J_model, C_candidate]`` over the training
   samples (the geometric columns refit with it, so what the geometry can absorb is projected
   off), errors on the held-out samples. Two fold schemes: random k-fold and contiguous blocks
   in acquisition order (a cause must also help on a block of the session it was not fitted
   on), plus leave-one-group-out when ``groups`` are given.
3. A candidate is significant if the extra-sum-of-squares F test of adding its columns passes at
   ``alpha`` / (number of candidates × rounds the selection may run) (Bonferroni over the whole search), its held-out gain is positive on every
   fold scheme and at least ``min_gain`` of the held-out RMSE. The one with the largest gain is fitted (nonlinear,
   all parameters re-fitted) and kept if its physical parameters are plausible
   (:data:`~robocal.diagnosis.candidates.LIMITS`); otherwise the next one is tried.
4. Repeat from 2 with the extended model until nothing is significant. The held-out RMSE of
   every model along the way is then measured honestly: nonlinear re-fits per fold.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Optional, Union

import numpy as np
from scipy.spatial import cKDTree
from scipy.stats import chi2
from scipy.stats import f as f_dist
from threadpoolctl import threadpool_limits

from ..calibration.api import load_inputs
from ..calibration.lm import levenberg_marquardt
from ..calibration.problem import TOLERANCE, Problem, kinematic_prior_pairs
from ..calibration.result import GROSS_FACTOR
from ..kernels import SVD_RCOND, as_count, as_float, as_tolerance, is_sparse, truncated_svd, unit_columns
from ..data.dataset import Dataset
from ..data.splits import configuration_groups, kfold
from ..exceptions import InvalidParameterError
from ..progress import progress
from ..threads import thread_map
from ..robot import RESIDUAL_WIDTH, Robot, setup_names
from ..stats import rmse_of_squares, robust_sigma
from ..causes import structure
from .budget import floor as error_floor
from .budget import repeatability
from ..causes.candidates import CURVED_DRIFT_DEGREE, PHYSICAL_KINDS, SETTLING_TIMES, Candidate, acquisition_order, drift_candidate, library, step_candidates
from .leftover import residual_verdict, unexplained
from .maps import map_stage, merge_harmonics
from ..causes.problem import ExtendedProblem, judged_rmse, judged_unit, reported_rmse, rotation_rmse_deg
from .settling import after_long_moves
from .uncertainty import uncertainty_entries
from .validation import coefficient_std, fit_problem, fold_schemes, judgeable, nonlinear_cv
from ..causes.wander import ROUGHNESS, TIME_TERMS, wander_candidate, within_session
from .wander import residual_correlation, time_inflation


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


#: Singular values below this fraction of the largest count as zero in the linear screening.
RCOND = SVD_RCOND


#: Residual components whose robust noise differs by more than this factor are scaled apart in
#: the screening's F test.
WHITEN_RATIO = 1.2


class _Screen:
    """Linear screening of candidates against the current model ``r ≈ J·δ``.

    Adding columns ``C`` to ``J`` is solved by the Frisch–Waugh–Lovell split: ``C`` and ``r``
    projected off ``J``'s (truncated) column space, the small problem in ``C`` solved there and
    ``J``'s coefficients recovered from the SVD. The SVD of each fold's ``J`` is computed once per
    round and shared by every candidate — one ``lstsq`` of ``[J, C]`` per candidate and fold
    before, which was most of a diagnosis's time.
    """

    def __init__(self, J: np.ndarray, r: np.ndarray, schemes: dict, k: int):
        self.J, self.r, self.k = unit_columns(J)[0], r, k
        self.m = len(r) // k
        self.folds = {name: [self._fold(train, test, self.J, r) for train, test in folds] for name, folds in schemes.items()}
        # The F test assumes one noise level for every row: a pose's position and rotation rows
        # (weighted as the fit weighs them) need not share one, and a test pooled over both
        # over-rates a candidate that touches the noisier rows (a step of the position reading
        # on clean pose data: p = 1e-6). Its rows are scaled by each component's robust noise.
        sigma = robust_sigma(r.reshape(self.m, k))
        self.whiten = np.tile(1.0 / sigma, self.m) if k > 1 and np.max(sigma) > WHITEN_RATIO * np.min(sigma) else None
        w = np.ones(len(r)) if self.whiten is None else self.whiten
        self.all = self._fold(np.arange(self.m), np.array([], dtype=int), unit_columns(J * w[:, None])[0], r * w)

    def _fold(self, train: np.ndarray, test: np.ndarray, J: np.ndarray, r: np.ndarray) -> tuple:
        rows_tr, rows_te = (train[:, None] * self.k + np.arange(self.k)).ravel(), (test[:, None] * self.k + np.arange(self.k)).ravel()
        U, sv, Vt = truncated_svd(J[rows_tr], RCOND)
        coef = U.T @ r[rows_tr]
        return rows_tr, rows_te, test, U, sv, Vt, coef, r[rows_tr] - U @ coef

    def _solve(self, fold: tuple, C: np.ndarray, P: Optional[np.ndarray] = None) -> tuple[np.ndarray, np.ndarray, float]:
        """Coefficients ``(δ_J, c)`` of ``r ≈ J·δ_J + C·c`` on the fold's training rows (``c``
        penalised by ``‖P·c‖²`` if ``P`` is given: a wander's roughness), and the degrees of
        freedom ``C`` adds (its rank, or the trace of its share of the hat matrix)."""
        rows_tr, _, _, U, sv, Vt, coef, r_perp = fold
        if C.shape[1] == 0:
            return Vt.T @ (coef / sv), np.zeros(0), 0
        Ct = C[rows_tr]
        UC = U.T @ Ct
        C_perp = Ct - U @ UC
        if P is None:
            c, _, rank, _ = np.linalg.lstsq(C_perp, r_perp, rcond=RCOND * (sv[0] if sv.size else 1.0) / max(np.linalg.norm(C_perp, 2), 1e-300))
            return Vt.T @ ((coef - UC @ c) / sv), c, float(rank)
        G = C_perp.T @ C_perp
        inverse = np.linalg.pinv(G + P.T @ P, rcond=RCOND)
        c = inverse @ (C_perp.T @ r_perp)
        return Vt.T @ ((coef - UC @ c) / sv), c, float(np.trace(inverse @ G))

    def errors(self, C: np.ndarray, P: Optional[np.ndarray] = None) -> dict:
        """Held-out squared error per sample of ``r ≈ [J, C]·δ`` (``C`` penalised by ``P``)
        fitted per fold, per scheme."""
        C, P = _unit_penalised(C, P)

        def fold_errors(fold: tuple) -> np.ndarray:  # one fold's held-out samples
            rows_te = fold[1]
            dJ, c = self._solve(fold, C, P)[:2]
            e = self.r[rows_te] - self.J[rows_te] @ dJ - C[rows_te] @ c
            return (e * e).reshape(-1, self.k).sum(axis=1)

        folds = [(name, fold) for name, scheme in self.folds.items() for fold in scheme]
        out = {name: np.zeros(self.m) for name in self.folds}
        for (name, fold), err in zip(folds, thread_map(fold_errors, [fold for _, fold in folds], rows=len(self.r))):
            out[name][fold[2]] = err
        return out

    def f_test(self, C: np.ndarray, inflation: float = 1.0, P: Optional[np.ndarray] = None) -> float:
        """p-value of the extra-sum-of-squares F test for adding ``C`` (exact for independent
        Gaussian noise in the linearised model; for residuals correlated in time, the statistic
        and the residual degrees of freedom divided by their variance ``inflation``; a penalised
        ``C`` counts its effective degrees of freedom)."""
        if self.whiten is not None:  # the penalty is in the residual's units: scaled as its rows are
            C, P = C * self.whiten[:, None], None if P is None else P * float(np.median(self.whiten))
        C, P = _unit_penalised(C, P)
        _, _, _, U, sv, _, coef, r_perp = self.all
        _, c, extra = self._solve(self.all, C, P)
        rss0 = float(r_perp @ r_perp)
        e = r_perp - (C - U @ (U.T @ C)) @ c
        rss1, dof = float(e @ e), len(self.r) - len(sv) - extra
        if extra < 0.5 or dof < 1 or rss1 <= 0:
            return 1.0
        return float(f_dist.sf(max(rss0 - rss1, 0.0) / extra / (rss1 / dof) / inflation, extra, max(dof / inflation, 1.0)))


def _unit_penalised(C: np.ndarray, P: Optional[np.ndarray]) -> tuple[np.ndarray, Optional[np.ndarray]]:
    """``C`` with unit columns, and its penalty ``P`` for the coefficients so scaled."""
    scale = np.linalg.norm(C, axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    return C / scale, None if P is None else P / scale


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
    gain alike)."""
    out = list(ranked)
    for i in range(len(out)):
        gain, c = out[i][0], out[i][1]
        if c.kind == "step" and gain > 0:  # a drift's shape is not chosen among every sample, as a step's place is
            simpler = [j for j in range(i + 1, len(out)) if out[j][1].kind == "drift" and out[j][0] >= (1.0 - SAME_GAIN) * gain]
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


def grossly_implausible(implausible: list[dict]) -> int:
    """How many kinematic parameters lie beyond :data:`GROSS_FACTOR` times their plausibility
    limit (100 mm, 20°): structure, not a cause a flexible term may fit around — a parameter
    just past its limit (an undetermined last-joint offset) is not."""
    return sum(abs(f["deviation"]) > GROSS_FACTOR * f["limit"] for f in implausible)


def is_flexible(c: Candidate) -> bool:
    """A joint term flexible enough to fit around a wrong geometry: a harmonic above
    :data:`MAX_HARMONIC_UNEXPLAINED` (maps are offered by their own stage)."""
    return c.kind == "joint_periodic" and c.detail.get("harmonic", 1) > MAX_HARMONIC_UNEXPLAINED


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


#: Knot spacings of the wander candidates, in correlation lengths of the residuals.
WANDER_SPACINGS = (0.5, 1.0, 2.0)
#: ... and roughness penalties, in multiples of :data:`~.wander.ROUGHNESS`.
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


#: Significant joint candidates given a nonlinear fit per round, in order of screening gain. On
#: an ill-conditioned geometry (D1) dozens of screening-significant joint candidates in a row
#: fail the plausibility check, each after a full fit; the rest are reported as not fitted.
#: Sensor (observation) and parameter candidates are always fitted.
MAX_TRIALS = 8


#: Gross errors lie beyond at least this many robust sigmas: a slipped cable or a broken beam
#: is off by many sigmas, while a cause the geometric model misses bends many residuals a little.
GROSS_SIGMAS = 8.0


def _outliers(base: Problem, data: Dataset, known: np.ndarray, level: float = 0.01) -> tuple[np.ndarray, float, np.ndarray]:
    """Samples beyond the Bonferroni bound (family-wise ``level``) of a robust noise scale, and
    beyond :data:`GROSS_SIGMAS`, with the ``known`` outliers always among them; and the last
    fit without them (each refit starts from the previous one)."""
    m = len(data)
    k = RESIDUAL_WIDTH[data.measurement]
    bound = max(float(chi2.ppf(1.0 - level / m, k)), GROSS_SIGMAS**2)
    always = np.isin(np.arange(m), known)
    flagged, x = always.copy(), None
    for _ in range(5):
        ext = ExtendedProblem(base, [], data, np.flatnonzero(~flagged))
        fit = fit_problem(ext, x0=x)
        x = fit.x
        r = ExtendedProblem(base, [], data, np.arange(m)).residuals(fit.x).reshape(m, k)
        sigma = robust_sigma(r[~flagged])
        now = _isolated_in_time((np.sum((r / sigma) ** 2, axis=1) > bound), acquisition_order(data)) | always
        if np.array_equal(now, flagged):
            break
        flagged = now
    return np.flatnonzero(flagged), float(np.sqrt(bound)), x


#: Samples beyond the bound this many in a row in acquisition order are an event in time (a step
#: the geometry half absorbed, a sensor that jumped), not independent gross errors: the step and
#: wander candidates judge them.
RUN = 3


def _isolated_in_time(beyond: np.ndarray, order: np.ndarray) -> np.ndarray:
    """``beyond`` (m,) without the samples that lie in runs of :data:`RUN` or more consecutive
    flagged samples in acquisition ``order``."""
    flagged = beyond[order].astype(np.int64)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], flagged, [0]])))
    starts, ends = edges[::2], edges[1::2]
    in_run = np.zeros(len(order), dtype=bool)
    for a, b in zip(starts, ends):
        if b - a >= RUN:
            in_run[a:b] = True
    out = beyond.copy()
    out[order[in_run]] = False
    return out


def _all_residuals(model: ExtendedProblem, x: np.ndarray) -> np.ndarray:
    """Residuals (m, k) of every sample of the dataset, the left-out ones too, under the fitted
    extended ``model``."""
    m = len(model.full_data)
    return model.with_samples(np.arange(m)).data_residuals(x).reshape(m, model.k)


#: A revealed outlier's residual is compared with those of this many samples nearest to it in
#: joint space.
NEIGHBOURS = 5


def _isolated(q: np.ndarray, z: np.ndarray, suspects: np.ndarray, keep: np.ndarray, z_bound: float) -> np.ndarray:
    """The ``suspects`` (kept samples beyond the bound) whose scaled residual ``z`` also lies
    beyond ``z_bound`` from the median residual of their :data:`NEIGHBOURS` nearest kept samples
    in joint space ``q``. Large residuals that a region of the workspace shares are error the
    model still makes there, not gross errors."""
    if len(suspects) == 0 or len(keep) <= NEIGHBOURS:
        return suspects[:0]
    _, near = cKDTree(q[keep]).query(q[suspects], NEIGHBOURS + 1)
    near = keep[near]
    others = np.array([row[row != s][:NEIGHBOURS] for row, s in zip(near, suspects)])
    contrast = np.sqrt(np.sum((z[suspects] - np.median(z[others], axis=1)) ** 2, axis=1))
    return suspects[contrast > z_bound]


def baseline_mask(robot: Robot, measurement: str, hayati: bool) -> np.ndarray:
    mask = robot.default_mask(measurement)
    if not hayati:
        for j, joint in enumerate(robot.joints, start=1):
            if joint.hayati:
                mask[robot.index(f"beta{j}")], mask[robot.index(f"d{j}")] = False, True
    return mask


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
    angle_unit : {"deg", "rad"}, optional
        Unit of a canonical file's joint columns (see :func:`robocal.data.load`).
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
    if len(dataset) < 4 * folds:
        raise InvalidParameterError(f"diagnose needs at least {4 * folds} samples for {folds} folds; got {len(dataset)}")
    mask = baseline_mask(rob, dataset.measurement, hayati)
    dataset, effects, rejected = _structure(rob, dataset, mask, folds, seed, groups)
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
    diagnosis, revealed, decided = _select(rob, dataset, base, [dict(e) for e in effects], list(rejected), np.zeros(0, dtype=int), **settings)
    if len(revealed):
        # Gross errors the geometric baseline's large residuals hid, beyond the bound only once
        # the causes are in: named, and the causes found confirmed again without them (the
        # search is not repeated), so that every held-out figure (baseline included) is over
        # the same samples.
        known = np.union1d(diagnosis.outliers, revealed)
        diagnosis, _, _ = _select(rob, dataset, base, effects, rejected, known, revealed=revealed, replay=decided, **settings)
    diagnosis.time_s = time.perf_counter() - t0
    return diagnosis


@dataclass
class Decided:
    """What a pass of :func:`_select` decided, for a second pass that only confirms it: the causes
    its forward selection accepted (in order) and the maps its map stage accepted (labels), the
    number of candidates and of maps its tests were corrected for (Bonferroni), and its refusals
    and unexplained findings (reported as they were: decided over the samples it had)."""

    causes: list
    maps: set
    tests: int
    map_tests: int
    rejected: list
    unexplained: list


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
    revealed: Optional[np.ndarray] = None,
    replay: Optional[Decided] = None,
) -> tuple[Diagnosis, np.ndarray, Decided]:
    """One pass of :func:`diagnose` after the structural stage, with the ``known`` outliers
    (``revealed``: those an earlier pass's final model named); the kept samples its final
    model puts beyond the outlier bound; and what it decided. With ``replay`` (an earlier pass's
    decisions) only the causes and maps that pass accepted are offered, with its Bonferroni
    counts, and its other refusals are reported as they were."""
    k = RESIDUAL_WIDTH[dataset.measurement]
    revealed = np.zeros(0, dtype=int) if revealed is None else revealed
    plots = {}
    outliers, z_bound, x_outliers = _outliers(base, dataset, known)
    keep = np.setdiff1d(np.arange(len(dataset)), outliers)
    order = acquisition_order(dataset)
    kept_order = np.searchsorted(keep, order[np.isin(order, keep)])
    schemes = fold_schemes(dataset.q[keep], folds, seed, kept_order, None if groups is None else np.asarray(groups)[keep])

    causes: list[Candidate] = []
    ext = ExtendedProblem(base, causes, dataset, keep)
    base_fit = fit_problem(ext, x0=x_outliers)
    x = base_fit.x
    baseline = {name: nonlinear_cv(ext, f) for name, f in schemes.items()}
    baseline_cv = {name: err for name, (err, _) in baseline.items()}
    fold_x = {name: xs for name, (_, xs) in baseline.items()}
    pool = library(rob, dataset, list(base.names) + list(base.fixed), hayati=hayati) if replay is None else list(replay.causes)
    # A geometry that stays implausible after the reading conventions is structure not
    # explained: a flexible joint term would only make a wrong geometry fit better (D1's joint
    # maps: docs/findings.md). Those are not offered until it is.
    unexplained_structure = grossly_implausible(base_fit.implausible())
    if unexplained_structure:
        pool = [c for c in pool if not is_flexible(c)]
    base_residuals = ext.residuals(x).reshape(len(keep), k)
    wander_test = residual_correlation(dataset, keep, base_residuals)
    # No wander while the geometric fit's residuals are alike in joint space and not beyond it
    # in time: that is evidence for the robot's causes, and a wander offered in a later round
    # would take what is left of them along the path, raising the held-out error (UR10 series A:
    # docs/findings.md).
    wander_offered = replay is None and (wander_test is None or wander_test["verdict"] != "joints")
    current_cv = baseline_cv
    searched = 0  # the most candidates a round screened
    last_round = (len(rejected), None)  # where the last screening round's refusals start, and its model's held-out RMSE
    while len(causes) < max_effects:
        last_round = (len(rejected), None)
        ext = ExtendedProblem(base, causes, dataset, keep)
        rows = len(keep) * k  # the data rows: a penalised cause (a wander) appends its roughness rows
        J = ext.jacobian(x)[:rows]
        r = ext.residuals(x)[:rows]
        # Steps where the current model's residuals change level: those of the geometric fit
        # alone misplace a step by the geometry's errors along the path (7-14 samples off on
        # simulated files).
        if replay is None:
            taken = {c.detail["sample"] for c in causes if c.kind == "step"}
            pool = [c for c in pool if c.kind != "step"] + [
                c for c in step_candidates(dataset, keep, r.reshape(len(keep), k)) if c.detail["sample"] not in taken
            ]
        params = sorted({n for c in pool if c.stage == "parameters" for n in c.params})
        _, p, parts = ext._jacobian_columns(x, [rob.index(n) for n in params])
        screen = _Screen(J, r, schemes, k)
        model_err = screen.errors(np.zeros((len(r), 0)))
        # What is left alike in time (a wandering reading, a drift that is not linear) is no
        # independent evidence for the candidates that do not model it.
        round_test = wander_test if not causes else residual_correlation(dataset, keep, r.reshape(len(keep), k))  # round 1: the baseline's residuals
        inflation = time_inflation(round_test)
        # Residuals alike in joint space and not beyond it in time are evidence for the robot's
        # causes: a wander would take them along the path (UR10 series B: docs/findings.md, D3).
        in_joints = bool(round_test) and round_test.get("verdict") == "joints"
        # Residuals alike from one sample to the next: the sensor may wander (a wander a larger
        # cause hid shows once that cause is in). Its knots at half the correlation length and
        # coarser, and its roughness penalty as set and stronger: noise and unmodelled causes
        # shorten the measured length, and a wander more flexible than the sensor's takes
        # geometry along (simulated wanders of length 17-20 measured 8-16; knots 4 samples apart
        # cost the blocked folds 47 %, ten times the penalty 10 % instead of 36 %). The most
        # flexible that does the geometry no harm is taken (each is tried in turn).
        length = None if round_test is None else round_test["correlation_length_samples"]
        if replay is None:
            pool = [c for c in pool if c.kind != "wander"]
        if wander_offered and length is not None and not any(c.kind == "wander" for c in causes):
            pool += [wander_candidate(dataset, length * factor, ROUGHNESS * stiffer) for factor in WANDER_SPACINGS for stiffer in WANDER_STIFFER]
        last_round = (last_round[0], rmse_of_squares(model_err["random"]))
        scored = []
        for c in progress(pool, desc=f"diagnose: screening round {len(causes) + 1}", unit="candidate"):
            if in_joints and c.kind in TIME_TERMS:
                continue
            # weighted as the screen's Jacobian and residuals are (pose: the rotation rows)
            if c.stage == "parameters":
                C = parts["extra"][:, [params.index(n) for n in c.params]] * ext.row_weights[:, None]
            else:
                C = ext.weighted_columns(x, c, parts, p)
            errs = screen.errors(C, c.penalty)
            p_value = screen.f_test(C, 1.0 if c.kind in TIME_TERMS else inflation, c.penalty)
            on = judgeable(c, keep, schemes)
            gains = {name: rmse_of_squares(model_err[name][on[name]]) - rmse_of_squares(errs[name][on[name]]) for name in schemes}
            scored.append((gains["random"], c, p_value, gains))
        scored.sort(key=lambda s: -s[0])
        n_tests = len(scored) if replay is None else replay.tests
        searched = max(searched, n_tests)

        def tests_of(c: Candidate) -> int:
            # Bonferroni over the whole search, not one round: every candidate of every round the
            # selection may run (max_effects). A step's position was chosen from the data among
            # every sample: Bonferroni over those positions as well (its p-value is that of the
            # best of them).
            return (n_tests + (len(r) // k if c.kind == "step" else 0)) * max(1, max_effects)

        def is_significant(gain: float, c: Candidate, p_value: float, gains: dict) -> bool:
            relevant = gain >= min_gain * rmse_of_squares(model_err["random"])
            return p_value * tests_of(c) < alpha and relevant and gains_everywhere(c, gains)

        scored = simplest_first(scored)
        scored = physics_first(scored, lambda s: s[0], lambda s: s[1], lambda s: is_significant(*s), established=any(c.kind in PHYSICAL_KINDS for c in causes))
        if inflation > 1.0:
            # The residuals wander in time: a wander is judged before the steps and trends that
            # would chop it up — after a significant temperature, the measured signal a wander
            # would otherwise imitate (a warm-up is smooth in time), and after a drift or a step
            # that gains at least SENSOR_TERM_SHARE of what the wander gains: one coefficient per axis
            # against dozens, and a wander fine enough follows a drift, or smooths a jump, as well
            # (a simulated drift well beyond its detection limit was named a wander; on the public
            # D2 file a wander took the place of the step and ended higher: docs/findings.md).
            wander_gain = max((s[0] for s in scored if s[1].kind in TIME_TERMS and is_significant(*s)), default=np.inf)

            def time_rank(s) -> int:
                if not is_significant(*s):
                    return 3
                if s[1].kind == "temperature":
                    return 0
                if s[1].kind in ("drift", "step") and s[0] >= SENSOR_TERM_SHARE * wander_gain:
                    return 1
                return 2 if s[1].kind in TIME_TERMS else 3

            scored = sorted(scored, key=time_rank)
        accepted = None
        joint_trials = 0
        for gain, c, p_value, gains in scored:
            significant = is_significant(gain, c, p_value, gains)
            if not significant and c.kind == "step":
                if not any(x["label"] == c.label for x in rejected):
                    rejected.append(_record(c, gain, gains, p_value, tests_of(c), None, "not significant over every possible step position"))
                continue
            if not significant:  # a larger gain of more coefficients may miss the level a smaller one passes
                continue
            if c.stage == "joints":
                if joint_trials >= MAX_TRIALS:
                    rejected.append(
                        _record(
                            c,
                            gain,
                            gains,
                            p_value,
                            tests_of(c),
                            None,
                            f"not fitted: {MAX_TRIALS} joint candidates with larger screening gains failed the nonlinear checks this round",
                        )
                    )
                    continue
                joint_trials += 1
            trial = ExtendedProblem(base, causes + [c], dataset, keep)
            fit = fit_problem(trial, x0=trial.start_from(x, ext))
            physical, why = c.physical(trial.coefficients(fit.x, c), coefficient_std(trial, fit, c), rob, rob.params)
            why = f"implausible: {why}" if why else undetermined(trial.coefficients(fit.x, c) - coefficient_reference(c, rob), coefficient_std(trial, fit, c))
            if why is not None:
                rejected.append(_record(c, gain, gains, p_value, tests_of(c), physical, why))
                continue
            # The screening is linear; the gain must survive the nonlinear re-fit on every scheme.
            refits = {name: nonlinear_cv(trial, f, [(setup, trial.start_from(xf, ext)) for setup, xf in fold_x[name]]) for name, f in schemes.items()}
            new_cv = {name: err for name, (err, _) in refits.items()}
            on = judgeable(c, keep, schemes)
            lost = [name for name in schemes if not improves(c, name, current_cv[name][on[name]], new_cv[name][on[name]])]
            if lost:
                rejected.append(
                    _record(
                        c,
                        gain,
                        gains,
                        p_value,
                        tests_of(c),
                        physical,
                        "no held-out gain after the nonlinear re-fit: "
                        + ", ".join(
                            f"{name} folds {judged_rmse(current_cv[name][on[name]]):.4g} -> {judged_rmse(new_cv[name][on[name]]):.4g} mm" for name in lost
                        ),
                    )
                )
                continue
            accepted = (c, fit, p_value, gains, physical, trial, new_cv, {name: xs for name, (_, xs) in refits.items()})
            break
        if accepted is None:
            for gain, c, p_value, gains in scored[:5]:
                if not any(r["label"] == c.label for r in rejected):
                    if p_value * tests_of(c) >= alpha:
                        why = "not significant"
                    elif gain < min_gain * rmse_of_squares(model_err["random"]):
                        why = f"held-out gain below {min_gain:.1%} of the RMSE"
                    else:
                        why = "no gain on every fold scheme"
                    rejected.append(_record(c, gain, gains, p_value, tests_of(c), None, why))
            break
        c, fit, p_value, gains, physical, trial, new_cv, fold_x = accepted
        # For the report's plot: the residual the cause was found in, against its fitted signature.
        signature = trial.columns(fit.x, c) @ (trial.coefficients(fit.x, c) - coefficient_reference(c, rob))
        plots[c.label] = {"residual": r, "signature": signature, "k": k}
        causes.append(c)
        pool = [o for o in pool if o is not c]
        x = fit.x
        effects.append(
            {
                "kind": c.kind,
                "joint": None if c.joint is None else c.joint + 1,
                "label": c.label,
                "params": physical,
                "rmse_heldout_before": reported_rmse(current_cv["random"]),
                "rmse_heldout_after": reported_rmse(new_cv["random"]),
                "significance": {
                    "test": "extra-sum-of-squares F test of the linearised model, Bonferroni over the candidates; held-out gain required on every fold scheme",
                    "p_value": p_value,
                    "p_adjusted": min(1.0, p_value * tests_of(c)),
                    "candidates": n_tests,
                    "screening_gain_mm": gains,
                    "rmse_heldout_blocked_before": reported_rmse(current_cv["blocked"]),
                    "rmse_heldout_blocked_after": reported_rmse(new_cv["blocked"]),
                },
            }
        )
        current_cv = new_cv

    last_round = (*last_round, len(rejected))  # ... and where they end (maps are screened otherwise)
    # The last round's screening is done with: its per-fold bases are the largest arrays of a
    # diagnosis (a sixth of its peak memory at 3000 samples), not to be carried through the maps.
    screen = J = r = None
    forward = list(causes)
    causes, x, current_cv, fold_x, curved, left_out = _curved_drift(ExtendedProblem(base, causes, dataset, keep), x, schemes, current_cv, fold_x, min_gain)
    for c in left_out:
        rejected.append(_retract(c, effects, plots, None, f"a curve of the drift ({curved['label']}) explains it as well"))
    if curved is not None:  # in the linear drift's place, in the report too
        linear = next(e for e in effects if e["kind"] == "drift")
        effects[effects.index(linear)] = curved
        if linear["label"] in plots:
            plots[curved["label"]] = plots.pop(linear["label"])
    causes, x, current_cv, fold_x, dropped = backward(ExtendedProblem(base, causes, dataset, keep), x, schemes, current_cv, fold_x, min_gain, not_physical)
    for c, why in dropped:
        rejected.append(_retract(c, effects, plots, None, why))
    model = ExtendedProblem(base, causes, dataset, keep)
    if unexplained_structure:  # the causes found may have been what bent the geometry
        unexplained_structure = grossly_implausible(fit_problem(model, x0=x).implausible())
    accepted_maps, rejected_maps = [], []
    if maps and not unexplained_structure:
        model, x, current_cv, fold_x, merged = merge_harmonics(model, x, schemes, current_cv, fold_x)
        # ``{label}`` is filled in by _take_map with the merged map's label.
        within = f"the same held-out error within {structure.EQUAL:.0%}"
        merged_why = f"merged with the joint's other harmonics into {{label}} ({within}: one periodic error of the joint, not several gear harmonics)"
        for m in merged:
            test = f"in the place of {len(m['replaces'])} harmonics of its joint, held-out error within {structure.EQUAL:.0%} of theirs on every fold scheme"
            significance = {"test": test, "p_value": None, "p_adjusted": None, "screening_gain_mm": None}
            _take_map(m, effects, rejected, plots, merged_why, significance)
        model, x, current_cv, fold_x, accepted_maps, rejected_maps = map_stage(
            model,
            x,
            schemes,
            current_cv,
            fold_x,
            alpha=alpha,
            min_gain=min_gain,
            only=None if replay is None else replay.maps,
            tests=None if replay is None else replay.map_tests,
        )
        replaced_why = "replaced by {label} (the same joint's error in finer detail; held-out gain of the map in its place)"
        map_test = (
            "extra-sum-of-squares F test of the unpenalised map columns, Bonferroni over the maps tried; "
            "held-out gain of the penalised map required on every fold scheme"
        )
        for m in accepted_maps:
            significance = {"test": map_test, "p_value": m["p_value"], "p_adjusted": min(1.0, m["p_value"] * m["tests"]), "screening_gain_mm": m["gains_mm"]}
            _take_map(m, effects, rejected, plots, replaced_why, significance)
        for m in rejected_maps:
            c = m["candidate"]
            rejected.append(_record(c, m["gains_mm"]["random"], m["gains_mm"], m["p_value"], m["tests"], m.get("params"), m["reason"]))
        if accepted_maps and any(c.kind != "joint_map" for c in model.causes):
            # a map may explain what a cause found before it took (a time term along a path
            # that sweeps the mapped joint): every earlier free shape must earn its place again
            # (a gravity compliance keeps its place before a map, as in the forward selection)
            kept, x, current_cv, fold_x, dropped = backward(
                model, x, schemes, current_cv, fold_x, min_gain, lambda c: c.kind != "joint_map" and not_physical(c)
            )
            model = ExtendedProblem(base, kept, dataset, keep)
            for c, why in dropped:
                rejected.append(_retract(c, effects, plots, None, why))
    model, x, current_cv, fold_x, dropped = _recheck_compliance(model, x, schemes, current_cv, fold_x)
    for c, physical, why in dropped:
        rejected.append(_retract(c, effects, plots, physical, f"dropped once the causes found after it were in: {why}"))
    unconstrained = reported_rmse(current_cv["random"])
    model, final_fit, current_cv, fold_x, prior = _physical(model, x, schemes, current_cv, fold_x)
    x = final_fit.x
    described = uncertainty_entries(model, x, model.causes)
    for effect in effects:
        effect.update(described.get(effect["label"], {}))
    explained_shares(effects, reported_rmse(baseline_cv["random"]), reported_rmse(current_cv["random"]))
    budget = error_floor(rob, dataset.subset(keep), model.full(x))
    r = _all_residuals(model, x)
    budget["revisits"] = repeatability(dataset.q[keep], r[keep, :3])
    leftover = residual_verdict(dataset, keep, r[keep], reported_rmse(current_cv["random"]), budget)
    z = r / robust_sigma(r[keep])  # in robust sigmas of the kept samples' residuals
    beyond = np.sqrt(np.sum(z**2, axis=1)) > z_bound
    if len(outliers) and model.causes:
        # Re-decided with the extended model: a sample flagged only because an unmodelled cause
        # bent the residuals is not an outlier.
        outliers = outliers[beyond[outliers]]
    if len(outliers):
        everyone = ExtendedProblem(base, [], dataset, np.arange(len(dataset)))
        before, _ = nonlinear_cv(everyone, kfold(len(dataset), folds, seed, groups=configuration_groups(dataset.q)))
        outliers_entry = {
            "kind": "outliers",
            "joint": None,
            "label": "outliers",
            "params": {
                "rows": [int(v) for v in dataset.rows[outliers]],
                "samples": [int(v) for v in outliers],
                "threshold_sigma": z_bound,
                # rows beyond the bound only under the final model (hidden by the baseline's residuals)
                "revealed_by_causes": [int(v) for v in dataset.rows[np.intersect1d(outliers, revealed)]],
            },
            "rmse_heldout_before": reported_rmse(before),
            "rmse_heldout_after": reported_rmse(baseline_cv["random"]),
            "significance": {"test": f"residual beyond max(Bonferroni bound at family-wise 0.01, {GROSS_SIGMAS:g}) MAD sigmas", "bound_sigma": z_bound},
            "after_long_moves": after_long_moves(dataset, outliers),  # readings taken before the arm settled?
        }
        effects.insert(0, outliers_entry)
    found = unexplained(rejected[last_round[0] : last_round[2]], last_round[1]) if replay is None else replay.unexplained
    if replay is not None:  # the earlier pass's other refusals, as that pass measured them
        decided_now = {e["label"] for e in rejected} | {e["label"] for e in effects}
        rejected += [{**e, "decided_with_outliers": True} for e in replay.rejected if e["label"] not in decided_now]
    decided = Decided(
        forward,
        {m["candidate"].label for m in accepted_maps},
        searched,
        max((m["tests"] for m in accepted_maps + rejected_maps), default=0),
        list(rejected),
        found,
    )
    structure_unexplained = None
    if unexplained_structure:
        far = f"the geometric fit stays far from any robot ({unexplained_structure} parameters beyond {GROSS_FACTOR:g} times the limits)"
        untried = f"joint maps and harmonics above order {MAX_HARMONIC_UNEXPLAINED} were not tried, as they would fit around a wrong geometry"
        structure_unexplained = {"implausible": unexplained_structure, "note": f"{far} and no reading convention makes it plausible: {untried}"}
    return (
        Diagnosis(
            robot=rob,
            data=dataset,
            baseline={
                "rmse_heldout": reported_rmse(baseline_cv["random"]),
                "rmse_heldout_blocked": reported_rmse(baseline_cv["blocked"]),
                "rmse_train": base_fit.metrics["train"]["rmse"],
                **_rotation_entries(dataset, baseline_cv),
                "n_params": int(len(base.free)),
                "hayati": hayati,
                "folds": folds,
                # where the geometric fit's residuals are alike: in acquisition order (a wandering sensor) or in joint space
                "residual_correlation": wander_test,
                # Kinematic parameters the geometric fit moved beyond 10 mm / 2 deg: the
                # geometry fits the data only with parameters no robot has.
                "implausible": base_fit.implausible(),
            },
            effects=effects,
            rejected=rejected,
            final={
                "rmse_heldout": reported_rmse(current_cv["random"]),
                "rmse_heldout_blocked": reported_rmse(current_cv["blocked"]),
                "n_params": int(model.n),
                **_rotation_entries(dataset, current_cv),
                "floor_mm": budget["floor_mm"],
                "floor": budget,
                # Share of the baseline's held-out mean square error above the floor that the causes explain.
                "explained": _explained(reported_rmse(baseline_cv["random"]), reported_rmse(current_cv["random"]), budget["floor_mm"]),
                # The physical model: a tolerance prior where the geometry is undetermined
                # (``tolerance_prior``: its sigmas, or None), and what still lies beyond the limits.
                "tolerance_prior": prior,
                "rmse_heldout_unconstrained": unconstrained,
                "implausible": final_fit.implausible(),
                # Noise or not (tested), and what the selection refused although it would have explained much.
                "structure_unexplained": structure_unexplained,
                "residuals": leftover,
                "unexplained": found,
            },
            model=model,
            x=x,
            outliers=[int(v) for v in outliers],
            plots=plots,
        ),
        _isolated(dataset.q, z, keep[beyond[keep]], keep, z_bound),
        decided,
    )


def explained_shares(effects: list, baseline: float, final: float) -> None:
    """Each found cause's ``share_of_explained``: the held-out mean square error its own step
    removed (``before² − after²``, in the order the causes were found) as a share of all that
    the causes removed from the geometric baseline (``baseline² − final²``). Reading conventions
    act before the baseline and outliers are left out of it: None for them."""
    total = baseline**2 - final**2
    for e in effects:
        inside = e["kind"] not in structure.KINDS and e["kind"] != "outliers" and total > 0
        e["share_of_explained"] = float((e["rmse_heldout_before"] ** 2 - e["rmse_heldout_after"] ** 2) / total) if inside else None


def _take_map(m: dict, effects: list, rejected: list, plots: dict, why_replaced: str, significance: dict) -> None:
    """A map the map stage accepted (or merged in) into the report: the causes it takes the place
    of retracted (``why_replaced`` with ``{label}`` the map's), its entry with ``significance``
    and its held-out figures."""
    c = m["candidate"]
    for o in m["replaces"]:
        rejected.append({**_retract(o, effects, plots, None, why_replaced.format(label=c.label)), "replaced_by": c.label})
    before, after = m["rmse_heldout_before"], m["rmse_heldout_after"]
    effects.append(
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


def _rotation_entries(data: Dataset, cv: dict) -> dict:
    """``rotation_rmse_heldout_deg`` (random folds) and ``..._blocked_deg`` of a pose diagnosis'
    held-out errors ``cv``; nothing for other measurements."""
    if data.measurement != "pose":
        return {}
    return {f"rotation_rmse_heldout{'' if name == 'random' else '_' + name}_deg": rotation_rmse_deg(cv[name], data) for name in ("random", "blocked")}


def _explained(before: float, after: float, floor: float) -> Optional[float]:
    """``(before² − after²) / (before² − floor²)``: the share of the mean square error above the
    floor that a model removes (None if the baseline is at the floor)."""
    room = before**2 - floor**2
    return None if room <= 0 else float((before**2 - after**2) / room)


#: The tolerance prior may cost at most this fraction of held-out error: beyond it the data
#: contradict a physical geometry rather than leave it undetermined.
PRIOR_COST = 0.05


#: The tolerance prior's sigmas as the report states them.
TOLERANCE_SIGMAS = {"sigma_mm": TOLERANCE["mm"], "sigma_deg": float(np.degrees(TOLERANCE["rad"]))}


def judge_tolerance_prior(checks, measurement: str) -> dict:
    """The report entry of a tolerance prior on the kinematics, judged by its held-out errors:
    :data:`TOLERANCE_SIGMAS`, ``accepted`` and, per check, the held-out RMSE with the prior
    (:func:`~.model.reported_rmse`); if it is not accepted, the ``reason``.

    ``checks`` yields, in order, ``(key, what, without, with_prior)``: the entry's key, the
    held-out error's name (``"random-fold held-out"``) and the squared errors
    (:func:`~.model.squared_errors`) of ``measurement`` data without and with the prior. The prior
    is accepted if on every check its :func:`~.model.judged_rmse` is within :data:`PRIOR_COST` of
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


def _physical(model: ExtendedProblem, x: np.ndarray, schemes: dict, current_cv: dict, fold_x: dict):
    """The final model made physical where the data leave the geometry undetermined.

    A fit whose kinematic parameters lie beyond the plausibility limits, or whose parameter
    combinations are wider than them (:meth:`CalibrationResult.undetermined`), is fitted again
    with a manufacturing-tolerance prior at nominal on every kinematic parameter
    (:data:`TOLERANCE`, weighted against the sensor's nominal noise): well-determined directions
    keep what the data say, the others stay near the drawing instead of running to metres. The
    prior is kept if its held-out error (on every fold scheme) is within
    :data:`PRIOR_COST` of the unconstrained model's; otherwise the data contradict a physical
    geometry, and the unconstrained model stays with its implausible parameters listed.

    Returns the model, its fit, its held-out errors and fold fits (``fold_x``: those of
    ``model``) and the report entry of the prior (``None`` if the fit was physical already).
    """
    fit = fit_problem(model, x0=x)
    if not fit.implausible() and not fit.undetermined():
        return model, fit, current_cv, fold_x, None
    robot = model.robot
    prior = kinematic_prior_pairs(robot, [robot.param_names[k] for k in model.free], dict(zip(robot.param_names, model.base.start)), TOLERANCE)
    physical = ExtendedProblem(replace(model.base, prior=prior), model.causes, model.full_data, model.idx)
    x0 = np.array([prior[n][0] if n in prior else v for n, v in zip(model.names, fit.x)])  # the kinematics from the drawing
    cv, fits = {}, {}

    def checks():
        for name, folds in schemes.items():  # random, blocked, then groups
            cv[name], fits[name] = nonlinear_cv(physical, folds, fold_x[name])  # each fold from its own unconstrained fit
            yield f"rmse_heldout_{name}", f"{name}-fold held-out", current_cv[name], cv[name]

    entry = judge_tolerance_prior(checks(), model.data.measurement)
    if not entry["accepted"]:
        return model, fit, current_cv, fold_x, entry
    return physical, fit_problem(physical, x0=x0), cv, fits, entry


def _structure(robot: Robot, data: Dataset, mask: np.ndarray, folds: int, seed: int, groups) -> tuple[Dataset, list, list]:
    """The joint-reading conventions (:mod:`.structure`) that make an implausible geometric fit
    plausible: the data with them applied, their report entries and the alternatives rejected.
    Searched only when the geometric fit of the data as read is implausible."""

    def geometric(d: Dataset, max_nfev=None):
        return levenberg_marquardt(Problem.build(robot, d, mask=mask), **({"max_nfev": max_nfev} if max_nfev else {}))

    def fit(d: Dataset, max_nfev=None):
        result = geometric(d, max_nfev)
        return result.metrics["train"]["rmse"], len(result.implausible())

    order = acquisition_order(data)
    schemes = fold_schemes(data.q, folds, seed, order, groups)

    def cross_validate(d: Dataset) -> dict:
        ext = ExtendedProblem(Problem.build(robot, d, mask=mask), [], d, np.arange(len(d)))
        return {name: reported_rmse(nonlinear_cv(ext, f)[0]) for name, f in schemes.items()}

    as_read = geometric(data)
    bad = as_read.implausible()
    if not bad:
        return data, [], []
    baseline = structure.Trial([], as_read.metrics["train"]["rmse"], len(bad))
    setup = setup_names(robot, data.measurement) + (["tool_x", "tool_y", "tool_z"] if data.measurement == "cable" else [])

    def setup_rmse(d: Dataset) -> float:  # the nominal geometry, only the set-up fitted
        return levenberg_marquardt(Problem.build(robot, d, mask=setup), max_nfev=structure.SCREEN_NFEV // 2).metrics["train"]["rmse"]

    combined = structure.screen_combinations(data, setup_rmse, seed)
    accepted, effects, rejected = structure.search(
        data, fit, cross_validate, baseline, seed, extra=structure.zero_errors(bad) + combined, setup_rmse=setup_rmse
    )
    return structure.apply_all(data, accepted), effects, rejected


#: A cause with a physical model of how it carries is tried before the best free joint shape
#: when its screening gain is at least this share of the shape's — or whatever its share once
#: the model has one. The share separates a compliance that a harmonic would replace from a
#: harmonic the compliance only grazes (the shares measured: docs/findings.md, D3).
PHYSICS_SHARE = 0.5


def physics_first(ranked: list, gain, cause, eligible=lambda item: True, established: bool = False) -> list:
    """``ranked`` (best first; ``gain(item)`` the item's held-out gain, ``cause(item)`` its
    candidate) with each ``eligible`` cause that has a physical model of how it carries
    (:data:`PHYSICAL_KINDS`: gravity compliance) moved before the first eligible free joint
    shape (harmonic, scale, coupling, backlash, map) if it gains at least :data:`PHYSICS_SHARE`
    of that shape's gain, or any share if one is ``established`` (the model already has a
    compliance: the data have shown the robot bends under gravity, and the other loaded joints
    bend too). Within one session a harmonic — and then a joint map — can take a compliance's
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
    moved = [item for item in ranked[at + 1 :] if cause(item).kind in PHYSICAL_KINDS and eligible(item) and gain(item) >= bar]
    rest = [item for item in ranked if all(item is not m for m in moved)]
    return rest[:at] + moved + rest[at:]


def not_physical(c: Candidate) -> bool:
    """Whether the backward check may drop ``c``: not a gravity compliance (a harmonic or a
    joint's other free shapes take a compliance's shape within one session and would win by a
    little, but only the compliance carries to other poses: :func:`physics_first`; UR10 series A
    lost joint 3's compliance to harmonics before its maps were in). A compliance is dropped
    only when its size is implausible or undetermined (:func:`_recheck_compliance`)."""
    return c.kind not in PHYSICAL_KINDS


def _curved_drift(model: ExtendedProblem, x: np.ndarray, schemes: dict, current_cv: dict, fold_x: dict, min_gain: float):
    """A drift that is not linear (a warm-up, a stand settling): the model's linear drift, if it
    has one, replaced by the best of a natural spline of time
    (:data:`~.candidates.CURVED_DRIFT_DEGREE`) and a line with an exponential settling
    (:data:`~.candidates.SETTLING_TIMES`) when that lowers the random folds' held-out RMSE by
    ``min_gain`` of it and does no harm on the others. Its leftovers would otherwise be taken by
    steps, harmonics and couplings that the backward check then no longer needs (a drift fast
    at first left a step in its first dozen samples). Returns the causes, fit, held-out errors,
    fold fits, the report entry of the curved drift (None if it was not taken) and the steps it
    made unnecessary."""
    linear = [c for c in model.causes if c.kind == "drift"]
    if not linear:
        return list(model.causes), x, current_cv, fold_x, None, []
    before = judged_rmse(current_cv["random"])
    best = None
    shapes = [drift_candidate(model.full_data, CURVED_DRIFT_DEGREE)] + [drift_candidate(model.full_data, settling=tau) for tau in SETTLING_TIMES]
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
            refits = {name: nonlinear_cv(trial, f, [(setup, trial.start_from(xf, model)) for setup, xf in fold_x[name]]) for name, f in schemes.items()}
            cv = {name: err for name, (err, _) in refits.items()}
            after = judged_rmse(cv["random"])
            physical, why = curved.physical(trial.coefficients(fit.x, curved), coefficient_std(trial, fit, curved), model.robot, model.robot.params)
            gains = before - after >= min_gain * before if not leave_out else after <= (1.0 + SAME_GAIN) * before
            on = judgeable(curved, model.idx, schemes)
            if why is None and gains and all(improves(curved, name, current_cv[name][on[name]], cv[name][on[name]]) for name in schemes):
                key = (len(trial.causes), after)
                if best is None or key < best[0]:
                    best = (key, curved, trial, fit, refits, cv, physical, leave_out)
    if best is None:
        return list(model.causes), x, current_cv, fold_x, None, []
    _, curved, trial, fit, refits, cv, physical, left_out = best
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
            "test": f"{polynomial}: held-out gain of at least {min_gain:.1%} on the random folds, no harm on the others",
            "p_value": None,
            "p_adjusted": None,
            "screening_gain_mm": None,
            "rmse_heldout_blocked_before": reported_rmse(current_cv["blocked"]),
            "rmse_heldout_blocked_after": reported_rmse(cv["blocked"]),
        },
    }
    return list(trial.causes), fit.x, cv, {name: xs for name, (_, xs) in refits.items()}, entry, left_out


def backward(model: ExtendedProblem, x: np.ndarray, schemes: dict, current_cv: dict, fold_x: dict, min_gain: float, droppable=lambda c: True):
    """Every cause of ``model`` must still earn its place once the causes found after it are in.

    The forward selection judges a cause against the model before it; leftovers of a cause
    whose model is slightly off (a compliance on masses that are not the mass model's, a drift
    that is not linear), or of a cause found later, are taken by small causes that the later
    model no longer needs. Each cause is left out in turn and the model re-fitted (nonlinear,
    on every fold scheme, from the fold fits of the full model); a cause whose removal costs
    less than the forward test asks of a new one (a held-out gain on every scheme, at least
    ``min_gain`` of the RMSE on the random folds) is dropped, the cheapest first, until every
    cause earns its place (only the ``droppable`` ones are judged). Returns the causes kept,
    their fit, held-out errors and fold fits, and ``(cause, reason)`` of each one dropped."""
    causes, dropped = list(model.causes), []
    while len(causes) >= 2:
        full = ExtendedProblem(model.base, causes, model.full_data, model.idx)
        weakest, linear = None, _linearised(full, x)
        for c in filter(droppable, causes):
            if linear is not None and _clearly_earns(full, linear, x, c, schemes, min_gain):
                continue
            rest = ExtendedProblem(model.base, [o for o in causes if o is not c], model.full_data, model.idx)
            refits = {name: nonlinear_cv(rest, f, [(setup, rest.start_from(xf, full)) for setup, xf in fold_x[name]]) for name, f in schemes.items()}
            cv = {name: err for name, (err, _) in refits.items()}
            without, with_it = judged_rmse(cv["random"]), judged_rmse(current_cv["random"])
            on = judgeable(c, model.idx, schemes)
            earns = all(improves(c, name, cv[name][on[name]], current_cv[name][on[name]]) for name in schemes)
            earns = earns and without - with_it >= min_gain * without
            if not earns and (weakest is None or without < weakest[1]):
                weakest = (c, without, rest, refits, with_it)
        if weakest is None:
            break
        c, without, rest, refits, with_it = weakest
        dropped.append((c, f"no longer earns its place once the causes found after it are in: held-out RMSE {with_it:.4g} with it, {without:.4g} without"))
        x = fit_problem(rest, x0=rest.start_from(x, full)).x
        current_cv, fold_x = {name: err for name, (err, _) in refits.items()}, {name: xs for name, (_, xs) in refits.items()}
        causes = list(rest.causes)
    return causes, x, current_cv, fold_x, dropped


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
    columns against the rest, its coefficients set to zero in the residual): the backward check
    then needs no nonlinear re-fits for it. Only for a cause with columns of its own."""
    if c.stage == "parameters":
        return False
    J, r = linear
    at = full.slices[full.causes.index(c)]
    C = J[:, at]
    rest = np.delete(J, np.arange(at.start, at.stop), axis=1)
    screen = _Screen(rest, r + C @ np.asarray(x)[at], schemes, full.k)  # the residual with the cause taken out
    base, errs = screen.errors(np.zeros((len(r), 0))), screen.errors(C, c.penalty)
    on = judgeable(c, full.idx, schemes)
    gains = {name: rmse_of_squares(base[name][on[name]]) - rmse_of_squares(errs[name][on[name]]) for name in schemes}
    return gains_everywhere(c, gains) and gains["random"] >= CLEAR_MARGIN * min_gain * rmse_of_squares(base["random"])


def _recheck_compliance(model: ExtendedProblem, x: np.ndarray, schemes: dict, current_cv: dict, fold_x: dict):
    """The final model without the compliances whose size, fitted with every cause found after
    them, is implausible or undetermined (:func:`physics_first` lets a compliance go before a
    free shape it resembles; when that shape is the real cause — a scale error of the same
    joint, say — the compliance is left with nothing to explain). Returns the model, its ``x``,
    held-out errors (measured again if anything was dropped) and the ``(cause, physical,
    reason)`` of each compliance dropped."""
    compliances = [c for c in model.causes if c.kind in PHYSICAL_KINDS]
    if not compliances:
        return model, x, current_cv, fold_x, []
    fit = fit_problem(model, x0=x)
    dropped = []
    for c in compliances:
        values, std = model.coefficients(fit.x, c), coefficient_std(model, fit, c)
        physical, why = c.physical(values, std, model.robot, model.robot.params)
        why = f"implausible: {why}" if why else undetermined(values - coefficient_reference(c, model.robot), std)
        if why is not None:
            dropped.append((c, physical, why))
    if not dropped:
        return model, x, current_cv, fold_x, []
    kept = ExtendedProblem(model.base, [c for c in model.causes if all(c is not d for d, _, _ in dropped)], model.full_data, model.idx)
    x = fit_problem(kept, x0=kept.start_from(fit.x, model)).x
    refits = {name: nonlinear_cv(kept, folds, [(setup, kept.start_from(xf, model)) for setup, xf in fold_x[name]]) for name, folds in schemes.items()}
    return kept, x, {name: err for name, (err, _) in refits.items()}, {name: xs for name, (_, xs) in refits.items()}, dropped


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


def _retract(c: Candidate, effects: list, plots: dict, physical, reason: str) -> dict:
    """Takes the accepted cause ``c`` out of the report's ``effects`` (and its plot) and returns
    its rejection record: its screening figures, ``physical`` (default: those it was accepted
    with) and ``reason``."""
    found = next(e for e in effects if e["label"] == c.label)
    effects.remove(found)
    plots.pop(c.label, None)
    sig = found["significance"]
    screening = sig.get("screening_gain_mm") or {}  # none for a cause merged in or put in another's place
    params = found["params"] if physical is None else physical
    return _record(c, screening.get("random"), screening or None, sig.get("p_value"), sig.get("candidates") or 1, params, reason)


def _record(c: Candidate, gain: float, gains: dict, p_value: float, n_tests: int, physical, reason: str) -> dict:
    return {
        "kind": c.kind,
        "joint": None if c.joint is None else c.joint + 1,
        "label": c.label,
        "gain_mm": gain,
        "gains_mm": gains,
        "p_value": p_value,
        "p_adjusted": None if p_value is None else min(1.0, p_value * n_tests),
        "params": physical,
        "reason": reason,
    }
