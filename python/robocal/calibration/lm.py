"""robocal's production Levenberg–Marquardt: geodesic acceleration, uphill steps and a stop at
the noise level (Transtrum & Sethna 2012, "Improvements to the Levenberg-Marquardt algorithm
for nonlinear least-squares minimization", arXiv:1201.5885).

Calibration problems on real data are *sloppy*: a narrow workspace leaves long, curved valleys
in which the cost still falls, slowly, over meters of link length. A plain LM crawls along them
in thousands of tiny steps without converging (D1: docs/findings.md). Three changes fix that:

- **Scaled damping with a memory, one factorisation per Jacobian.** Each step solves
  ``(JᵀJ + λ·D) v = Jᵀr`` with ``D`` the running maximum of ``diag(JᵀJ)`` (MINPACK's scaling)
  as the least squares of ``[J·D^-½; √λ·I] z ≈ [r; 0]`` (the normal equations would square the
  condition number): ``J·D^-½`` is factored once by Householder QR in the Rust core
  (:func:`robocal.kernels.factor_damped`), and every λ tried and the acceleration below reuse it.
- **Geodesic acceleration.** A second-order correction ``a`` from the residuals' directional
  second derivative along ``v`` (one extra residual evaluation at ``x + h·v``) bends the step
  along the valley: the step is ``v + a/2``, taken only while ``2‖a‖/‖v‖ ≤ α``.
- **Uphill steps.** A step that raises the cost slightly is still taken when it continues the
  previous direction (``(1 − cos β)·C_new ≤ C_old``), so the iteration follows a valley's bends
  instead of stopping at each; the best point seen is returned.

The damping follows Nielsen (1999): ``λ·max(1/3, 1 − (2ρ − 1)³)`` after a step with gain ratio
``ρ``, ``λ·ν, ν ← 2ν`` after a rejected one (``1 − (2ρ − 1)³`` = 2 for an uphill step: λ/3 then). The iteration
stops when more iterations cannot change the fit by what the data's noise can tell apart
(``σ̂² = 2·cost/(rows − n)``), either of:

- the Gauss–Newton step of the linearised problem would move the fit by less than
  :data:`NOISE_DISTANCE` standard deviations (``‖J·δ_GN‖ / σ̂``: every parameter then lies
  within that fraction of its standard deviation of the linearised optimum);
- the last :data:`STALL_STEPS` downhill steps lowered ``χ² = 2·cost/σ̂²`` by less than
  :data:`STALL_CHI2` in all: what is left lies along directions the data barely determine
  (the result's ``undetermined`` lists them);

or on scipy's tests (relative cost change < ``ftol``, relative step < ``xtol``, ``‖Jᵀr‖∞`` <
``gtol``). ``statistical_stop=False`` keeps only scipy's tests, to run to full convergence.
A fit started next to its optimum whose ``x`` alone is wanted (a cross-validation fold's, from
the previous model's fold fit: ``frozen_check=True``) first tests the Gauss–Newton distance after
a step with the Jacobian the step was taken with, whose factorisation it has, where the step
was linear (its cost fell as predicted, to :data:`LINEAR_STEP`): where that says the step ended
within the noise, the fit stops without evaluating the Jacobian and its normal matrix at the
new point (what it saves and what it changes: docs/diagnose.md, Performance).
Bounds (if the problem has any) project each step.

Robust losses (``loss="huber"`` or ``"cauchy"``): the cost is ``½ s² Σ_i ρ(‖r_i‖² / s²)`` over the
samples ``i`` (a sample's residual rows together), minimised by iteratively reweighted least
squares — each step's rows are weighted by ``√ρ′`` at the current residuals (scipy's loss
functions without their second-order term). The scale ``s`` (``f_scale``) defaults to 2.5
robust sigmas per component on a ``k``-component residual, ``2.5·√k·σ̂`` with ``σ̂`` the RMS of
the components' robust sigmas (:func:`robocal.stats.robust_sigma`), of a plain fit, which is
done first, then of the robust fit, which is repeated once with it.
"""

from __future__ import annotations

import time

import numpy as np

from ..kernels import as_count, as_positive, as_tolerance, factor_damped, is_sparse
from ..kernels import normal_equations, sparse_gram
from ..exceptions import InvalidParameterError, NonFiniteError
from ..robot import RESIDUAL_WIDTH
from ..stats import robust_sigma
from .problem import Problem, initial_x
from .result import CalibrationResult, sum_of_squares

#: ``loss -> (ρ(z), ρ′(z))`` for ``z = (error / f_scale)²``.
LOSSES = {
    "linear": (lambda z: z, lambda z: np.ones_like(z)),
    "huber": (lambda z: np.where(z <= 1.0, z, 2.0 * np.sqrt(z) - 1.0), lambda z: np.where(z <= 1.0, 1.0, 1.0 / np.sqrt(np.maximum(z, 1.0)))),
    "cauchy": (lambda z: np.log1p(z), lambda z: 1.0 / (1.0 + z)),
}

#: Samples beyond this many ``f_scale`` are reported as outlying by a robust fit.
OUTLYING = 3.0


class _Cost:
    """The (robust) cost of a residual vector and the row weights ``√ρ′`` of its linearisation."""

    def __init__(self, problem: Problem, loss: str, f_scale: float):
        self.loss, self.s = loss, f_scale
        self.k = RESIDUAL_WIDTH[problem.data.measurement]
        self.n_data = len(problem.data) * self.k

    def __call__(self, r: np.ndarray) -> tuple[float, np.ndarray]:
        if self.loss == "linear":
            return 0.5 * sum_of_squares(r), np.ones_like(r)
        rho, drho = LOSSES[self.loss]
        data, prior = r[: self.n_data], r[self.n_data :]
        z = (data.reshape(-1, self.k) ** 2).sum(axis=1) / self.s**2
        weights = np.ones_like(r)
        weights[: self.n_data] = np.repeat(np.sqrt(drho(z)), self.k)
        return 0.5 * self.s**2 * float(np.sum(rho(z))) + 0.5 * float(prior @ prior), weights


def levenberg_marquardt(
    problem: Problem,
    x0=None,
    max_nfev: int = 2000,
    ftol: float = 1e-10,
    xtol: float = 1e-10,
    gtol: float = 1e-10,
    lam0: float = 1e-3,
    method: str = "lm",
    loss: str = "linear",
    f_scale: float = None,
    statistical_stop: bool = True,
    with_std: bool = True,
    frozen_check: bool = False,
) -> CalibrationResult:
    """Minimises ``½‖r(x)‖²`` (or the robust cost of ``loss``) of ``problem`` from ``x0``
    (default ``problem.x0``).

    Returns a :class:`CalibrationResult`; non-convergence within ``max_nfev`` is reported in
    ``success``/``message``, not raised; ``statistical_stop=False`` runs to scipy's
    tolerances instead of stopping at the noise level (see the module notes); ``with_std=False``
    leaves the result's ``std`` None (a fit whose ``x`` alone is wanted); ``frozen_check=True``
    first tests the noise-level stop after a linear step (:data:`LINEAR_STEP`) with the Jacobian
    the step was taken with (see the module notes), for a warm start's fit whose ``x`` alone is
    wanted. With a robust ``loss`` the result's ``robust`` holds
    the loss, the scale and the rows of the samples beyond :data:`OUTLYING` scales. Without
    ``f_scale`` the scale is estimated from a plain fit, then once more from the robust fit.
    """
    if not isinstance(loss, str) or loss not in LOSSES:
        raise InvalidParameterError(f"`loss` must be one of {sorted(LOSSES)}; got {loss!r}")
    f_scale = None if f_scale is None else as_positive(f_scale, "f_scale")
    max_nfev = as_count(max_nfev, "max_nfev")
    ftol, xtol, gtol, lam0 = (as_tolerance(v, n) for v, n in ((ftol, "ftol"), (xtol, "xtol"), (gtol, "gtol"), (lam0, "lam0")))
    start = time.perf_counter()
    options = dict(max_nfev=max_nfev, ftol=ftol, xtol=xtol, gtol=gtol, lam0=lam0, method=method)
    options.update(statistical_stop=bool(statistical_stop), with_std=bool(with_std), frozen_check=bool(frozen_check))
    fit = _minimise(problem, x0, _Cost(problem, "linear", 1.0), **options)
    if loss == "linear":
        return fit
    for _ in range(1 if f_scale is not None else 2):
        scale = f_scale if f_scale is not None else _default_scale(problem, fit.x)
        fit = _minimise(problem, fit.x, _Cost(problem, loss, scale), **options)
    outlying = np.flatnonzero(_sample_errors(problem, fit.x) > OUTLYING * scale)
    rows = problem.data.rows[outlying] if problem.data.rows is not None else outlying
    fit.robust = {"loss": loss, "f_scale": float(scale), "outlying_rows": [int(v) for v in rows]}
    fit.time_s = time.perf_counter() - start  # all passes
    return fit


def _default_scale(problem: Problem, x: np.ndarray) -> float:
    """``2.5·√k·σ̂``: 2.5 robust sigmas per component of the ``k``-component residuals (as the
    cost weighs them: a pose's rotation rows weighted)."""
    k = RESIDUAL_WIDTH[problem.data.measurement]
    components = problem.residuals(x)[: len(problem.data) * k].reshape(len(problem.data), k)
    sigma = robust_sigma(components)
    return 2.5 * float(np.sqrt(np.sum(sigma**2)))


def _sample_errors(problem: Problem, x: np.ndarray) -> np.ndarray:
    """Per-sample error norms (mm) of the data residuals."""
    return np.sqrt((problem.data_residuals(x).reshape(len(problem.data), -1) ** 2).sum(axis=1))


#: Stop when the Gauss–Newton step moves the fit by less than this many standard deviations.
NOISE_DISTANCE = 0.1
#: ... or when this many downhill steps together lowered χ² by less than :data:`STALL_CHI2`.
STALL_STEPS = 5
STALL_CHI2 = 0.1
#: A step whose cost fell as its linear model predicted to within this fraction (gain ratio
#: ``ρ``) may check the stop with the Jacobian it was taken with (``frozen_check``): on UR10
#: series A the steps where that check agreed with a fresh Jacobian's had ``|1 − ρ|`` ≤ 0.009,
#: on the public D2 file the five where it did not 0.27–0.52.
LINEAR_STEP = 0.01
#: Geodesic acceleration: finite-difference step along the velocity, and the largest
#: acceleration-to-velocity ratio accepted (Transtrum & Sethna's recommended values).
GEODESIC_H = 0.1
GEODESIC_ALPHA = 0.75


def _minimise(
    problem: Problem,
    x0,
    objective: _Cost,
    max_nfev: int,
    ftol: float,
    xtol: float,
    gtol: float,
    lam0: float,
    method: str,
    statistical_stop: bool,
    with_std: bool,
    frozen_check: bool,
) -> CalibrationResult:
    """The damped iteration on ``objective`` (see the module notes)."""
    start = time.perf_counter()
    x = initial_x(problem, x0)
    r = problem.residuals(x)
    cost, w = objective(r)
    dof = max(len(r) - len(x), 1)
    history, nfev, njev, nit, lam, nu = [cost], 1, 1, 0, lam0, 2.0
    best_x, best_cost, previous, gains = x, cost, None, []
    success, message = False, f"the maximum number of function evaluations ({max_nfev}) is exceeded"
    J, J_at, gram_at = problem.jacobian(x), x, None  # where J and its normal matrix were evaluated
    scale, fresh = None, True
    weighted = objective.loss != "linear"  # least squares: the weights are all 1
    # A trial point that is taken needs its Jacobian, whose forward kinematics also gives its
    # residuals: one pass of the core for both, where the problem has it. A frozen-check fit keeps
    # trial residuals alone: it stops after a linear step without that Jacobian.
    both = None if frozen_check else getattr(problem, "residuals_and_jacobian", None)
    while nfev < max_nfev:
        if fresh:  # a new Jacobian: factor it once for every step tried from this point
            fresh = False
            Jw, rw = (_scaled(J, rows=w), r * w) if weighted else (J, r)
            gram_at = J_at
            # JᵀJ (n, n) and Jᵀr: a sparse J's from its rows' pairs of entries, a dense one's in one pass
            gram, g = (sparse_gram(Jw), Jw.T @ rw) if is_sparse(Jw) else normal_equations(Jw, rw)
            if np.max(np.abs(g)) < gtol:
                success, message = True, "`gtol` termination condition is satisfied"
                break
            squares = np.diag(gram).copy()
            scale = squares if scale is None else np.maximum(scale, squares)
            d = np.sqrt(np.where(scale > 0, scale, 1.0))
            factored = _factor(Jw, d, gram)
            # Qᵀr; a sparse J's factorisation takes it from Jᵀr = g, which it would compute again
            c = factored.project_products(g / d) if is_sparse(Jw) else factored.project(rw)
            if statistical_stop:
                if cost == 0.0:
                    success, message = True, "the residuals are zero"
                    break
                distance = _gauss_newton_distance(c, cost, dof)
                if distance < NOISE_DISTANCE:
                    success, message = True, f"converged to within the noise: a Gauss-Newton step would move the fit by {distance:.2g} standard deviations"
                    break
                if len(gains) >= STALL_STEPS and sum(gains[-STALL_STEPS:]) < STALL_CHI2:
                    success = True
                    stalled = f"the last {STALL_STEPS} steps lowered chi-square by {sum(gains[-STALL_STEPS:]):.2g} in all"
                    remaining = f"a Gauss-Newton step would still move the fit by {distance:.2g} standard deviations along directions the data barely determine"
                    message = f"converged to within the noise: {stalled} ({remaining})"
                    break
        v = factored.solve(c, lam) / d
        # Geodesic acceleration: r(x + h·v) ≈ r − h·J·v − ½h²·r_vv gives the second directional
        # derivative of the model along v, and its damped solve the acceleration a.
        r_probe = _refused_as_none(problem.residuals, x + GEODESIC_H * v)
        nfev += 1
        if r_probe is None:
            lam, nu = lam * nu, 2.0 * nu
            continue
        r_probe = r_probe * w if weighted else r_probe
        Jv = Jw @ v if is_sparse(Jw) else _product(Jw, v)
        second = (2.0 / GEODESIC_H) * ((rw - r_probe) / GEODESIC_H - Jv)
        a = factored.solve(factored.project(-second), lam) / d
        if 2.0 * np.linalg.norm(d * a) > GEODESIC_ALPHA * np.linalg.norm(d * v):
            lam, nu = lam * nu, 2.0 * nu
            continue
        x_new = problem.clip(x + v + 0.5 * a)
        step = x_new - x
        evaluated_new = _refused_as_none(both or problem.residuals, x_new)
        nfev += 1
        if evaluated_new is None:
            lam, nu = lam * nu, 2.0 * nu
            continue
        r_new, J_new = evaluated_new if both else (evaluated_new, None)
        njev += J_new is not None
        cost_new, w_new = objective(r_new)
        downhill = cost_new < cost
        # An uphill step is taken when it continues the previous direction (cos β near 1).
        uphill = not downhill and previous is not None and cost_new * (1.0 - _cosine(v, previous, d)) <= cost
        small_step = np.linalg.norm(step) < xtol * (xtol + np.linalg.norm(x))
        if downhill or uphill:
            nit += 1
            if downhill and cost > 0:
                gains.append((cost - cost_new) / (cost / dof))  # Δχ² in units of σ̂² = 2·cost/dof
            small_change = downhill and cost - cost_new < ftol * cost
            x, r, cost, w, previous = x_new, r_new, cost_new, w_new, v
            history.append(cost)
            if cost < best_cost:
                best_x, best_cost = x, cost
            # Nielsen's update from the gain ratio of the velocity's linear model.
            predicted = float(v @ g) - 0.5 * sum_of_squares(Jv)
            rho = (history[-2] - cost) / predicted if downhill and predicted > 0 else 0.0
            lam, nu = lam * max(1.0 / 3.0, 1.0 - (2.0 * min(rho, 1.0) - 1.0) ** 3), 2.0
            if small_change or small_step:
                success = True
                message = "`ftol` termination condition is satisfied" if small_change else "`xtol` termination condition is satisfied"
                break
            if frozen_check and statistical_stop and not weighted and abs(1.0 - rho) <= LINEAR_STEP and _within_noise(factored, r, cost, dof):
                success, message = True, "converged to within the noise (the Gauss-Newton step measured with the last step's Jacobian)"
                break
            if J_new is None:
                J_new = problem.jacobian(x)
                njev += 1
            J, J_at, fresh = J_new, x, True
        elif small_step:
            # Even tiny steps no longer lower the cost: a minimum to within rounding.
            success, message = True, "`xtol` termination condition is satisfied"
            break
        else:
            lam, nu = lam * nu, 2.0 * nu
    # The residuals and the Jacobian at the point returned, when the iteration has them (saves an evaluation of each).
    evaluated = None
    if best_x is x and J_at is x:
        evaluated = (r, J, gram if gram_at is x and not weighted else None)
    result = CalibrationResult.from_fit(
        method, problem, best_x, history, nit, nfev, success, message, time.perf_counter() - start, evaluated=evaluated, with_std=with_std
    )
    result.njev = njev
    return result


def _refused_as_none(evaluate, x: np.ndarray):
    """``evaluate(x)`` at a trial point ``x``, or None where the model refuses it — a parameter
    beyond the range the core takes (±10¹² mm or rad), as a nearly singular system's step of
    little damping can reach (a fold fit of discovery seed 40's file 41): a failed step, which
    raises the damping, not an error."""
    try:
        return evaluate(x)
    except (InvalidParameterError, NonFiniteError):
        return None


def _gauss_newton_distance(c: np.ndarray, cost: float, dof: int) -> float:
    """How far the Gauss–Newton step of the linearised problem moves the fit, in standard
    deviations of the residuals: ``‖c‖ = ‖Qᵀr‖ = ‖J·δ_GN‖`` over ``σ̂ = √(2·cost/dof)`` (infinite
    for zero residuals)."""
    noise = np.sqrt(2.0 * cost / dof)
    return float(np.linalg.norm(c)) / noise if noise > 0.0 else np.inf


def _within_noise(factored, r: np.ndarray, cost: float, dof: int) -> bool:
    """Whether the Gauss–Newton step from residuals ``r`` (cost ``cost``) would move the fit by less
    than :data:`NOISE_DISTANCE` standard deviations, measured with ``factored`` — the Jacobian
    the last step was taken with, not one evaluated at the new point: the check that saves a
    Jacobian and its normal matrix where the step ends within the noise."""
    return _gauss_newton_distance(factored.project(r), cost, dof) < NOISE_DISTANCE


#: Ridge added to a sparse Jacobian's scaled normal matrix (unit diagonal): it keeps the
#: matrix definite where the data leave a direction free.
SPARSE_RIDGE = 1e-12

#: Largest condition number of the scaled normal matrix ``D^-½·JᵀJ·D^-½`` whose Cholesky factor
#: gives the steps (``J``'s condition up to 10⁵: steps accurate to ~10⁻⁶, and every step's gain
#: is checked on the residuals); beyond it (D1: 10⁷) ``J·D^-½`` is factored by QR.
NORMAL_CONDITION = 1e10


def _factor(Jw, d: np.ndarray, gram):
    """The damped steps of ``Jw·D^-½`` (``d = √diag(D)``) from the normal equations ``gram``
    (``JwᵀJw``). A dense ``Jw``'s when they are well conditioned (:data:`NORMAL_CONDITION`),
    else a QR of the scaled ``Jw`` (:func:`robocal.kernels.factor_damped`); a
    sparse one's always (a model with joint maps: a QR would fill it in), with :data:`SPARSE_RIDGE`."""
    normal = gram / np.outer(d, d)
    if is_sparse(Jw):
        return _DampedGram(normal + SPARSE_RIDGE * np.eye(len(normal)), lambda b: (Jw.T @ b) / d)
    if gram.size:
        eigenvalues = np.linalg.eigvalsh(normal)
        if eigenvalues[0] > eigenvalues[-1] / NORMAL_CONDITION:
            return _DampedGram(normal, lambda b: _product(b, Jw) / d)
    return factor_damped(_scaled(Jw, columns=1.0 / d))


class _DampedGram:
    """``factor_damped``'s ``project``/``solve`` from a well-conditioned normal matrix
    ``N = AᵀA = L·Lᵀ`` (n, n) of the scaled Jacobian ``A``, in the basis ``Q = A·L⁻ᵀ``
    (orthonormal columns): ``c = L⁻¹·Aᵀb`` (``‖c‖`` = the norm of ``b``'s part that ``A``
    explains) and the step ``(N + λI)⁻¹·L·c`` — O(n³) per step instead of a QR of ``A``."""

    def __init__(self, normal: np.ndarray, transpose_times):
        from scipy.linalg import cholesky

        self.normal, self.transpose_times = normal, transpose_times
        self.L = cholesky(normal, lower=True)
        self._damped = (None, None)  # (λ, the factor of N + λI): a step and its acceleration share λ

    def project(self, b: np.ndarray) -> np.ndarray:
        return self.project_products(self.transpose_times(b))

    def project_products(self, Atb: np.ndarray) -> np.ndarray:
        """``c = L⁻¹·Aᵀb`` from ``Aᵀb`` itself."""
        from scipy.linalg import solve_triangular

        return solve_triangular(self.L, Atb, lower=True)

    def solve(self, c: np.ndarray, lam: float) -> np.ndarray:
        from scipy.linalg import cho_factor, cho_solve

        if self._damped[0] != lam:
            self._damped = (lam, cho_factor(self.normal + lam * np.eye(len(self.normal)), lower=True))
        return cho_solve(self._damped[1], self.L @ c)


def _product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b`` of a matrix and a vector without the BLAS (see :func:`~robocal.calibration.result.sum_of_squares`)."""
    return np.einsum("ij,j->i", a, b) if a.ndim == 2 else np.einsum("i,ij->j", a, b)


def _scaled(J, rows=None, columns=None):
    """``diag(rows)·J·diag(columns)`` of a dense or a scipy.sparse ``J``."""
    if is_sparse(J):
        from scipy import sparse

        J = J if rows is None else sparse.diags_array(rows) @ J
        return (J if columns is None else J @ sparse.diags_array(columns)).tocsr()
    J = J if rows is None else J * rows[:, None]
    return J if columns is None else J * columns


def _cosine(u: np.ndarray, v: np.ndarray, d: np.ndarray) -> float:
    """Cosine of the angle between ``u`` and ``v`` in the scaled metric ``diag(d)``."""
    du, dv = d * u, d * v
    return float(du @ dv) / max(float(np.linalg.norm(du) * np.linalg.norm(dv)), 1e-300)
