"""Joint error maps: the stage of a diagnosis that fits what the named causes leave on each joint.

A harmonic-drive or RV reducer's transmission error is a fine, smooth function of the joint's own
angle (energy at 10-30 cycles per revolution on the UR10), which a few harmonics cannot follow. A
*joint map* is a cubic B-spline correction of one joint's angle over the range the data cover,
with a second-difference roughness penalty (a P-spline, Eilers & Marx 1996); its constant is
left to the geometry's ``theta`` offset and its linear part to ``joint_scale``
(:func:`~robocal.causes.candidates.map_constraint`).

The stage runs after the named causes. Each round screens, for every joint without a map, every
knot spacing and roughness of :data:`~robocal.causes.candidates.MAP_SPACINGS_DEG` ×
:data:`~robocal.causes.candidates.MAP_ROUGHNESS_DEG` against the current model, linearised, through the
normal equations (cheap: a map's columns are sparse); the best variant per joint by held-out
error summed over the fold schemes is checked by the extra-sum-of-squares F test of its
unpenalised columns (Bonferroni over the variants tried) and then re-fitted (nonlinear) on every
fold of every scheme: a map is accepted only if it lowers the held-out RMSE of every scheme
(blocked folds and, with groups, held-out groups included) by :data:`min_gain` of it.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.linalg import LinAlgError, cho_solve, cholesky
from scipy.stats import f as f_dist

from ..data.splits import residual_rows
from ..kernels import fold_products, is_sparse, sparse_gram
from ..progress import progress
from ..stats import rmse_of_squares
from ..threads import thread_map
from ..causes.candidates import MAX_HARMONIC, covered_when_fitted_on, map_candidates, map_noise, periodic_candidate
from ..causes.problem import ExtendedProblem, judged_rmse, reported_rmse
from .conventions import EQUAL
from .validation import cross_validate, fit_problem, weak_gain
from .wander import serial_inflation

#: Relative ridge of the screening's normal equations (directions the data leave free).
RIDGE = 1e-10
#: A fold's system solved by its Schur complement is solved whole when its scaled residual is
#: beyond this fraction of the right-hand side's and the solution's norms.
SCHUR_TOLERANCE = 1e-8


def _dense(A) -> np.ndarray:
    return A.toarray() if is_sparse(A) else np.asarray(A)


def _gram(A) -> np.ndarray:
    """``AᵀA``, dense; a sparse ``A``'s from the Rust core's sparse Gram (what the LM uses too)
    rather than scipy's sparse product."""
    return sparse_gram(A) if is_sparse(A) else A.T @ A


class _NormalScreen:
    """Held-out errors of ``r ≈ J·δ + C·c`` (``C`` penalised by ``P``), fitted per fold through
    the normal equations. ``J``'s rows beyond the data (priors, accepted maps' roughness) stay in
    every training set. ``q`` are the samples' joint angles: a fold's map corrects only the
    held-out samples within its training samples' angles (:func:`~robocal.causes.candidates.covered_when_fitted_on`).

    A scheme's held-out folds partition the data rows: ``C``'s products with the held-out rows of
    every fold of every scheme come from one pass of the Rust core over the rows
    (:func:`~robocal.kernels.fold_products`), and every held-out prediction from one product of
    ``C`` by fold (:meth:`_by_fold`)."""

    def __init__(self, J, r: np.ndarray, schemes: dict, k: int, n_data: int, q: np.ndarray):
        self.k, self.n_data, self.q, self._covered, self._last, self._factors = k, n_data, q, {}, None, {}
        self.J, self.r = J, r
        self.JtJ, self.Jtr = _gram(J), np.asarray(J.T @ r)
        self.Jd, self.rd = sparse.csr_array(J[:n_data]), r[:n_data]  # the data rows, all a candidate's columns touch
        self.folds = {name: [self._rows(train, test) for train, test in folds] for name, folds in schemes.items()}
        self.fold_of_row = {}
        for name, folds in self.folds.items():
            label = np.full(n_data, -1)
            for i, (_, _, rows, _, _, _) in enumerate(folds):
                label[rows] = i
            if np.any(label < 0):
                raise ValueError(f"the held-out folds of scheme {name!r} leave data rows out")
            self.fold_of_row[name] = label

    def _rows(self, train: np.ndarray, test: np.ndarray) -> tuple:
        rows = residual_rows(test, self.k)
        Jte = self.J[rows]
        return train, test, rows, Jte, _gram(Jte), np.asarray(Jte.T @ self.r[rows])

    def _covered_rows(self, joint_map, name: str) -> np.ndarray:
        """Per data row, 1 if the map fitted on the training samples of the row's fold of scheme
        ``name`` covers the row's sample, else 0."""
        key = (joint_map.joint, joint_map.detail["spacing"], name)  # the same for every roughness
        if key not in self._covered:
            covered = np.zeros(self.n_data)
            for train, test, rows, _, _, _ in self.folds[name]:
                inside = covered_when_fitted_on(joint_map.detail, self.q[train, joint_map.joint], self.q[test, joint_map.joint])
                covered[rows] = np.repeat(inside, self.k)
            self._covered[key] = covered
        return self._covered[key]

    def _by_fold(self, C, name: str):
        """``C`` (data rows, n) as (data rows, folds·n): each row's entries in its fold's copy of
        the columns."""
        n, folds = C.shape[1], len(self.folds[name])
        label = np.repeat(self.fold_of_row[name], np.diff(C.indptr))
        return sparse.csr_array((C.data, C.indices + n * label, C.indptr), shape=(self.n_data, n * folds))

    def _products(self, C, cause) -> tuple:
        """The normal-equation blocks of ``C`` with ``J`` and ``r``: over all data rows, and per
        scheme ``C`` by fold (:meth:`_by_fold`) with its folds' held-out shares
        (:func:`~robocal.kernels.fold_products`; all rows: the first scheme's folds summed). A
        map's roughness variants share their columns (and :attr:`Candidate.basis`): their
        products are computed once (the last ones are kept)."""
        if self._last is not None and cause is not None and self._last[0] is cause.basis:
            return self._last[1]
        C = sparse.csr_array(C)
        names = list(self.folds)
        by_scheme = fold_products(C, self.Jd, self.rd, [self.fold_of_row[name] for name in names], [len(self.folds[name]) for name in names])
        CtJ, Ctr, CtC = by_scheme[0]
        held_out = {name: (self._by_fold(C, name), *products) for name, products in zip(names, by_scheme)}
        products = (CtC.sum(axis=0), CtJ.sum(axis=0), Ctr.sum(axis=0), held_out, {})  # {}: per fold, A⁻¹Bᵀ and what follows of it
        if cause is not None:
            self._last = (cause.basis, products)
        return products

    def _geometry(self, name: str, i: int) -> tuple:
        """Fold ``i`` of scheme ``name``: its training rows' normal equations ``A·δ = b`` of ``J``,
        their unit-diagonal scaling ``d``, the upper Cholesky factor ``U`` of the scaled and ridged
        ``A`` (``UᵀU``) and the solution ``y0`` without a candidate (scaled) — or None for both if
        the factor fails. Computed once per fold, for every candidate."""
        if (name, i) not in self._factors:
            _, _, _, _, JteJte, Jter = self.folds[name][i]
            A, b = self.JtJ - JteJte, self.Jtr - Jter
            d = _diagonal_scale(A)
            try:
                U = cholesky(A / np.outer(d, d) + RIDGE * np.eye(len(A)))
                self._factors[name, i] = (b, d, U, cho_solve((U, False), b / d))
            except LinAlgError:
                self._factors[name, i] = (b, d, None, None)
        return self._factors[name, i]

    def errors(self, C=None, P=None, joint_map=None) -> dict:
        """Held-out squared error per sample, per scheme; ``C`` the columns of ``joint_map``.

        Each fold's system ``[A Bᵀ; B D]`` (``J`` and ``C``'s blocks, scaled to a unit diagonal
        with the ridge, as :func:`_solve` does) is solved by its Schur complement: ``A``'s factor
        is the fold's for every candidate, and ``A⁻¹Bᵀ`` the basis' for every roughness (only
        ``D`` holds the penalty), so a roughness variant costs a solve of ``C``'s size. The folds
        are solved in parallel (:func:`~robocal.threads.thread_map`)."""
        p = self.J.shape[1]
        if C is not None:
            CtC, CtJ, Ctr, held_out, shared = self._products(C, joint_map)
            if P is not None:
                CtC = CtC + P.T @ P

        def fold_solution(at: tuple) -> np.ndarray:
            name, i = at
            b, d, U, y0 = self._geometry(name, i)
            if C is None:
                return y0 / d if U is not None else _solve(self.JtJ - self.folds[name][i][4], b)
            _, CteJ, Cter, CteCte = held_out[name]
            B, D, bC = CtJ - CteJ[i], CtC - CteCte[i], Ctr - Cter[i]
            if U is None:
                return _solve(np.block([[self.JtJ - self.folds[name][i][4], B.T], [B, D]]), np.concatenate([b, bC]))
            if at not in shared:
                Bj = B / d
                W = cho_solve((U, False), Bj.T)
                shared[at] = (W, Bj @ W, Bj @ y0)
            W, M, g = shared[at]
            dC = _diagonal_scale(D)
            S = (D - M) / np.outer(dC, dC) + RIDGE * np.eye(len(D))
            # A candidate nearly in the span of the geometry's barely determined directions
            # cancels in D − M: checked by the scaled system's residual, solved whole if it fails.
            with np.errstate(over="ignore", invalid="ignore"):
                try:
                    yC = np.linalg.solve(S, (bC - g) / dC)
                except LinAlgError:  # exactly singular: the same cancellation
                    yC = np.full(len(D), np.nan)
                yJ = y0 - W @ (yC / dC)
                Bs = (B / d) / dC[:, None]
                r_J = U.T @ (U @ yJ) + Bs.T @ yC - b / d
                r_C = Bs @ yJ + (D / np.outer(dC, dC) + RIDGE * np.eye(len(D))) @ yC - bC / dC
                y = np.concatenate([yJ, yC])
                scale = np.linalg.norm(np.concatenate([b / d, bC / dC])) + np.linalg.norm(y)
                solved = np.all(np.isfinite(y)) and np.linalg.norm(np.concatenate([r_J, r_C])) <= SCHUR_TOLERANCE * scale
            if not solved:
                return _solve(np.block([[self.JtJ - self.folds[name][i][4], B.T], [B, D]]), np.concatenate([b, bC]))
            return np.concatenate([yJ / d, yC / dC])

        at = [(name, i) for name, folds in self.folds.items() for i in range(len(folds))]
        solutions = dict(zip(at, thread_map(fold_solution, at, rows=self.n_data)))
        out = {}
        for name, folds in self.folds.items():
            e = self.rd.copy()
            for i, (_, _, rows, Jte, _, _) in enumerate(folds):
                e[rows] -= Jte @ solutions[name, i][:p]
            if C is not None:  # every row's prediction by its own fold's coefficients, in one product
                correction = held_out[name][0] @ np.concatenate([solutions[name, i][p:] for i in range(len(folds))])
                covered = self._covered_rows(joint_map, name) if joint_map is not None and joint_map.kind == "joint_map" else 1.0
                e -= correction * covered
            # A fold the candidate leaves undetermined may predict beyond the float range: an infinite
            # error, which no gain survives (a simulated ABB cable file with a late step: one fold).
            with np.errstate(over="ignore"):
                out[name] = (e * e).reshape(-1, self.k).sum(axis=1)
        return out

    def f_test(self, C, inflation: float = 1.0) -> tuple[float, int]:
        """p-value of the extra-sum-of-squares F test for adding ``C`` unpenalised (all data), and
        the rank it adds; for residuals correlated in time, the statistic and the residual degrees
        of freedom divided by their variance ``inflation``."""
        CtC, CtJ, Ctr = _dense(C.T @ C), _dense(C.T @ self.Jd), np.asarray(C.T @ self.rd)
        rss0, rank0 = _rss(self.JtJ, self.Jtr, float(self.r @ self.r))
        rss1, rank1 = _rss(np.block([[self.JtJ, CtJ.T], [CtJ, CtC]]), np.concatenate([self.Jtr, Ctr]), float(self.r @ self.r))
        extra, dof = rank1 - rank0, len(self.r) - rank1
        if extra < 1 or dof < 1 or rss1 <= 0:
            return 1.0, max(extra, 0)
        return float(f_dist.sf(max(rss0 - rss1, 0.0) / extra / (rss1 / dof) / inflation, extra, max(dof / inflation, 1.0))), extra

    def left(self, C) -> np.ndarray:
        """The data rows' residuals once ``C`` is fitted to them (the geometry held)."""
        return self.rd - C @ _solve(_dense(C.T @ C), np.asarray(C.T @ self.rd))


def _diagonal_scale(N: np.ndarray) -> np.ndarray:
    """``√diag(N)``: the scaling that gives ``N`` a unit diagonal."""
    return np.sqrt(np.maximum(np.diag(N), 1e-300))


def _solve(N: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``N⁻¹·b`` on unit-diagonal scaling with a relative ridge. A column no training row touches
    (a map's knot beyond the fold's angles: a zero diagonal, its other entries the rounding of
    the products' differences, 10¹³³ once scaled) gets coefficient zero."""
    present = np.diag(N) > 0.0
    d = _diagonal_scale(N[np.ix_(present, present)])
    Ns = N[np.ix_(present, present)] / np.outer(d, d) + RIDGE * np.eye(len(d))
    x = np.zeros(len(N))
    x[present] = np.linalg.solve(Ns, b[present] / d) / d
    return x


def _rss(N: np.ndarray, b: np.ndarray, rr: float) -> tuple[float, int]:
    """Residual sum of squares of the least-squares fit with normal equations ``N·δ = b``, and
    its rank."""
    d = _diagonal_scale(N)
    s2, V = np.linalg.eigh(N / np.outer(d, d))
    keep = s2 > 1e-12 * max(float(s2[-1]), 1e-300)
    coef = V[:, keep].T @ (b / d)
    return rr - float(coef @ (coef / s2[keep])), int(np.count_nonzero(keep))


def map_stage(
    model: ExtendedProblem,
    x: np.ndarray,
    schemes: dict,
    current_cv: dict,
    fold_x: dict,
    *,
    alpha: float,
    min_gain: float,
    only=None,
    tests=None,
):
    """Joint maps added to ``model`` (see the module notes).

    ``fold_x`` is the diagnosis' per-scheme fold fits of ``model`` (warm starts). ``only``: the
    labels of the maps to offer (default all), ``tests``: the number of maps the F test is
    corrected for (default those offered in the round) — an earlier pass's, to confirm its maps.
    Returns the new model, its
    ``x``, held-out errors and fold fits, the report entries of the maps accepted and of those
    rejected (each with a ``candidate`` key: the :class:`Candidate`; an accepted map's
    ``replaces``: the harmonics it took the place of).
    """
    robot, data = model.robot, model.full_data
    moving = [j for j in range(robot.n_joints) if np.ptp(data.q[model.idx, j]) > 1e-6]
    pool = map_candidates(robot, data, moving, map_noise(model.data_residuals(x).reshape(len(model.idx), model.k)), model.idx)
    pool = pool if only is None else [c for c in pool if c.label in only]
    accepted, rejected = [], []
    while pool:
        evaluated = model.jacobian_parts(x, [])  # with ∂h/∂q of every joint: what each map's columns scale
        J, r = model.jacobian(x, evaluated), model.residuals(x)
        n_data = len(model.idx) * model.k
        screen = _NormalScreen(J, r, schemes, model.k, n_data, data.q[model.idx])
        base_err = screen.errors()
        _, p, parts = evaluated
        best: dict = {}
        for c in progress(pool, desc=f"diagnose: joint maps round {len(accepted) + 1}", unit="map"):
            C = model.weighted_columns(x, c, parts, p)  # weighted as J and r are
            errs = screen.errors(C, c.penalty, c)
            score = sum(np.mean(errs[name]) for name in schemes)
            if c.joint not in best or score < best[c.joint][0]:
                best[c.joint] = (score, c, errs, C)
        ranked = sorted(best.values(), key=lambda v: v[0])
        n_tests = len(pool) if tests is None else tests
        chosen = None
        for score, c, errs, C in ranked:
            gains = {name: rmse_of_squares(base_err[name]) - rmse_of_squares(errs[name]) for name in schemes}
            # judged with the correlation in time of what it leaves: a map follows noise
            # correlated in time along a path that moves the joints a little at a time
            p_value, _ = screen.f_test(C, serial_inflation(data, model.idx, screen.left(C).reshape(len(model.idx), model.k)))
            entry = {"candidate": c, "gains_mm": gains, "p_value": p_value, "tests": n_tests}
            if not all(g >= min_gain * rmse_of_squares(base_err[name]) for name, g in gains.items()) or p_value * n_tests >= alpha:
                rejected.append(
                    {**entry, "reason": "not significant" if p_value * n_tests >= alpha else f"held-out gain below {min_gain:.1%} on some fold scheme"}
                )
                continue
            for causes in _variants(model.causes, c):
                trial = ExtendedProblem(model.base, causes, data, model.idx)
                trial_fit = fit_problem(trial, x0=trial.start_from(x, model))
                coefficients = trial.coefficients(trial_fit.x, c)
                std = None if trial_fit.std is None else trial.coefficients(trial_fit.std, c)
                physical, why = c.physical(coefficients, std, robot, robot.params)
                if why is not None:
                    reason = f"implausible: {why}"
                    continue
                new_cv, new_fold_x = cross_validate(trial, schemes, fold_x, model)
                lost = [name for name in schemes if judged_rmse(new_cv[name]) > (1.0 - min_gain) * judged_rmse(current_cv[name])]
                if lost:
                    reason = f"no held-out gain after the nonlinear re-fit ({', '.join(lost)} folds)"
                    continue
                # A map in place of its joint's harmonics is judged against them (they earned
                # their significance when they were taken); one beside the model's causes must
                # gain significantly.
                replaced = [o for o in model.causes if o not in causes]
                reason = None if replaced else weak_gain(current_cv["random"], new_cv["random"])
                if reason:
                    continue
                chosen = (c, trial, trial_fit, new_cv, new_fold_x, {**entry, "replaces": replaced}, physical)
                break
            if chosen is not None:
                break
            rejected.append({**entry, "params": physical, "reason": reason})
        if chosen is None:
            break
        c, model, trial_fit, new_cv, fold_x, entry, physical = chosen
        before, after = ({n: reported_rmse(cv[n]) for n in schemes} for cv in (current_cv, new_cv))
        accepted.append({**entry, "params": physical, "rmse_heldout_before": before, "rmse_heldout_after": after})
        x, current_cv = trial_fit.x, new_cv
        pool = [o for o in pool if o.joint != c.joint]
    return model, x, current_cv, fold_x, accepted, rejected


def _variants(causes: list, joint_map) -> list[list]:
    """The cause lists a map is tried in: first in place of its joint's harmonics, if the model
    has any — the map follows the same joint's error in finer detail and, unlike a harmonic,
    claims nothing beyond the range it saw (UR10 harmonics fitted within one series raised the
    error on the others) — then beside every cause the model has."""
    subsumed = [o for o in causes if o.kind == "joint_periodic" and o.joint == joint_map.joint]
    plain = causes + [joint_map]
    return [[o for o in causes if o not in subsumed] + [joint_map], plain] if subsumed else [plain]


def merge_harmonics(model: ExtendedProblem, x: np.ndarray, schemes: dict, current_cv: dict, fold_x: dict):
    """One periodic error in the place of two or more harmonics of one joint.

    Harmonics 1-3 are the library's; a joint whose error holds a higher harmonic (a reducer's
    gear mesh) is approximated by two or three of them, each a claim of a gear harmonic that is
    not there. Where the model holds two or more harmonics of a joint, first the single harmonic
    (1 to :data:`~robocal.causes.candidates.MAX_HARMONIC`), then the joint's map, each the best screened
    against the model without them, is fitted in their place and kept if its held-out error is
    within :data:`~.conventions.EQUAL` of theirs on every scheme: the same error, one honest claim
    — "harmonic h of this joint" or "a periodic error of this joint", with its curve — instead of
    several. Returns the model, its ``x``, held-out errors, fold fits and the report entries of
    the causes merged in (``candidate``, ``replaces``, ``params``, held-out RMSE before and after)."""
    robot, data = model.robot, model.full_data
    merged = []
    for j in sorted({c.joint for c in model.causes if c.kind == "joint_periodic"}):
        harmonics = [c for c in model.causes if c.kind == "joint_periodic" and c.joint == j]
        if len(harmonics) < 2 or any(c.kind == "joint_map" and c.joint == j for c in model.causes):
            continue
        rest = ExtendedProblem(model.base, [c for c in model.causes if c not in harmonics], data, model.idx)
        x_rest = fit_problem(rest, x0=rest.start_from(x, model)).x
        J, r = rest.jacobian(x_rest), rest.residuals(x_rest)
        screen = _NormalScreen(J, r, schemes, rest.k, len(rest.idx) * rest.k, data.q[rest.idx])
        present = {c.detail["harmonic"] for c in harmonics}  # one of them alone was not enough (the backward check)
        singles = [periodic_candidate(robot, data, j, h) for h in range(1, MAX_HARMONIC + 1) if h not in present]
        maps = map_candidates(robot, data, [j], map_noise(rest.data_residuals(x_rest).reshape(len(rest.idx), rest.k)), rest.idx)
        for pool in (singles, maps):
            scored = [
                (sum(np.mean(e) for e in screen.errors(rest.weighted_columns(x_rest, c), c.penalty, c).values()), i)
                for i, c in enumerate(progress(pool, desc=f"diagnose: one error for joint {j + 1}'s harmonics", unit="candidate"))
            ]
            if not scored:
                continue
            best = pool[min(scored)[1]]
            trial = ExtendedProblem(model.base, rest.causes + [best], data, model.idx)
            trial_fit = fit_problem(trial, x0=trial.start_from(x, model))
            if best.physical(trial.coefficients(trial_fit.x, best), None, robot, robot.params)[1] is not None:
                continue
            new_cv, new_fold_x = cross_validate(trial, schemes, fold_x, model)
            if all(judged_rmse(new_cv[name]) <= (1.0 + EQUAL) * judged_rmse(current_cv[name]) for name in schemes):
                before = {name: reported_rmse(current_cv[name]) for name in schemes}
                model, x, current_cv, fold_x = trial, trial_fit.x, new_cv, new_fold_x
                physical = best.physical(trial.coefficients(x, best), None, robot, robot.params)[0]
                after = {name: reported_rmse(current_cv[name]) for name in schemes}
                merged.append({"candidate": best, "replaces": harmonics, "params": physical, "rmse_heldout_before": before, "rmse_heldout_after": after})
                break
    return model, x, current_cv, fold_x, merged
