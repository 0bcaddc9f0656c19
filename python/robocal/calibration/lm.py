"""robocal's production Levenberg–Marquardt (Marquardt 1963 with Nielsen's damping update).

Each step solves ``(JᵀJ + λ·diag(JᵀJ)) δ = Jᵀr`` in the Rust core (``factor="lstsq"``): by the
normal equations while they are well conditioned, else as the least squares of
``[J; √λ·diag(JᵀJ)^½] δ ≈ [r; 0]`` (faer column-pivoted QR of ``J`` itself, SVD fallback). The
normal equations square the condition number, and on ill-conditioned real data (D1) their rank
cut-off alone stopped the iteration in a flat valley above the least-squares optimum
(``benches/lm_step_conditioning.py``). The step is projected onto the problem's bounds if it has
any. The damping adapts to the gain ratio ρ = actual / predicted cost reduction
(Nielsen 1999: λ ← λ·max(1/3, 1 − (2ρ − 1)³) on success, λ ← λ·ν, ν ← 2ν on failure), and the
iteration stops on any of scipy's tests: relative cost change < ``ftol``, relative step <
``xtol``, or ``‖Jᵀr‖∞`` < ``gtol``.

Robust losses (``loss="huber"`` or ``"cauchy"``): the cost is ``½ s² Σ_i ρ(‖r_i‖² / s²)`` over the
samples ``i`` (a sample's residual rows together), minimised by iteratively reweighted least
squares — each step's rows are weighted by ``√ρ′`` at the current residuals (scipy's loss
functions without their second-order term). The scale ``s`` (``f_scale``) defaults to 2.5
robust sigmas (1.4826 · median of the per-sample errors) of a plain fit, which is done first,
then of the robust fit, which is repeated once with it.
"""

from __future__ import annotations

import time

import numpy as np

from ..core import as_count, as_positive, as_tolerance, solve_damped
from ..exceptions import InvalidParameterError
from ..robot import RESIDUAL_WIDTH
from .problem import Problem, initial_x
from .result import CalibrationResult

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
            return 0.5 * float(r @ r), np.ones_like(r)
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
) -> CalibrationResult:
    """Minimises ``½‖r(x)‖²`` (or the robust cost of ``loss``) of ``problem`` from ``x0``
    (default ``problem.x0``).

    Returns a :class:`CalibrationResult`; non-convergence within ``max_nfev`` is reported in
    ``success``/``message``, not raised. With a robust ``loss`` the result's ``robust`` holds
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
    fit = _minimise(problem, x0, _Cost(problem, "linear", 1.0), **options)
    if loss == "linear":
        return fit
    for _ in range(1 if f_scale is not None else 2):
        scale = f_scale if f_scale is not None else 2.5 * 1.4826 * float(np.median(_sample_errors(problem, fit.x)))
        fit = _minimise(problem, fit.x, _Cost(problem, loss, scale), **options)
    outlying = np.flatnonzero(_sample_errors(problem, fit.x) > OUTLYING * scale)
    rows = problem.data.rows[outlying] if problem.data.rows is not None else outlying
    fit.robust = {"loss": loss, "f_scale": float(scale), "outlying_rows": [int(v) for v in rows]}
    fit.time_s = time.perf_counter() - start  # all passes
    return fit


def _sample_errors(problem: Problem, x: np.ndarray) -> np.ndarray:
    """Per-sample error norms (mm) of the data residuals."""
    return np.sqrt((problem.data_residuals(x).reshape(len(problem.data), -1) ** 2).sum(axis=1))


def _minimise(problem: Problem, x0, objective: _Cost, max_nfev: int, ftol: float, xtol: float, gtol: float, lam0: float, method: str) -> CalibrationResult:
    """The damped iteration on ``objective`` (see the module notes)."""
    start = time.perf_counter()
    x = initial_x(problem, x0)
    r = problem.residuals(x)
    cost, w = objective(r)
    history, nfev, nit, lam, nu = [cost], 1, 0, lam0, 2.0
    success, message = False, f"the maximum number of function evaluations ({max_nfev}) is exceeded"
    J = problem.jacobian(x)
    while nfev < max_nfev:
        Jw, rw = J * w[:, None], r * w
        g = Jw.T @ rw
        if np.max(np.abs(g)) < gtol:
            success, message = True, "`gtol` termination condition is satisfied"
            break
        step, _ = solve_damped(Jw, rw, lam, "marquardt", "lstsq")
        # Projected onto the bounds (if any); the gain ratio uses the step actually taken.
        x_new = problem.clip(x + step)
        step = x_new - x
        r_new = problem.residuals(x_new)
        nfev += 1
        cost_new, w_new = objective(r_new)
        Js = Jw @ step
        predicted = float(step @ g) - 0.5 * float(Js @ Js)
        rho = (cost - cost_new) / predicted if predicted > 0 else -1.0
        small_step = np.linalg.norm(step) < xtol * (xtol + np.linalg.norm(x))
        if rho > 0:
            nit += 1
            small_change = cost - cost_new < ftol * cost
            x, r, cost, w = x_new, r_new, cost_new, w_new
            history.append(cost)
            lam *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
            nu = 2.0
            if small_change or small_step:
                success = True
                message = "`ftol` termination condition is satisfied" if small_change else "`xtol` termination condition is satisfied"
                break
            J = problem.jacobian(x)
        elif small_step:
            # Even tiny steps no longer lower the cost: a minimum to within rounding.
            success, message = True, "`xtol` termination condition is satisfied"
            break
        else:
            lam *= nu
            nu *= 2.0
    return CalibrationResult.from_fit(method, problem, x, history, nit, nfev, success, message, time.perf_counter() - start)
