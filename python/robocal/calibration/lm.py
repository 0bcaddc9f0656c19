"""robocal's production Levenberg–Marquardt (Marquardt 1963 with Nielsen's damping update).

Each step solves ``(JᵀJ + λ·diag(JᵀJ)) δ = Jᵀr`` in the Rust core (faer Cholesky, SVD
fallback), projected onto the problem's bounds if it has any. The damping adapts to the gain ratio ρ = actual / predicted cost reduction
(Nielsen 1999: λ ← λ·max(1/3, 1 − (2ρ − 1)³) on success, λ ← λ·ν, ν ← 2ν on failure), and the
iteration stops on any of scipy's tests: relative cost change < ``ftol``, relative step <
``xtol``, or ``‖Jᵀr‖∞`` < ``gtol``.
"""

from __future__ import annotations

import time

import numpy as np

from ..core import solve_damped
from .problem import Problem
from .result import CalibrationResult


def levenberg_marquardt(
    problem: Problem,
    x0=None,
    max_nfev: int = 2000,
    ftol: float = 1e-10,
    xtol: float = 1e-10,
    gtol: float = 1e-10,
    lam0: float = 1e-3,
    method: str = "lm",
) -> CalibrationResult:
    """Minimises ``½‖r(x)‖²`` of ``problem`` from ``x0`` (default ``problem.x0``).

    Returns a :class:`CalibrationResult`; non-convergence within ``max_nfev`` is reported in
    ``success``/``message``, not raised.
    """
    start = time.perf_counter()
    x = problem.x0 if x0 is None else np.array(x0, dtype=np.float64)
    r = problem.residuals(x)
    cost = 0.5 * float(r @ r)
    history, nfev, nit, lam, nu = [cost], 1, 0, lam0, 2.0
    success, message = False, f"the maximum number of function evaluations ({max_nfev}) is exceeded"
    J = problem.jacobian(x)
    while nfev < max_nfev:
        g = J.T @ r
        if np.max(np.abs(g)) < gtol:
            success, message = True, "`gtol` termination condition is satisfied"
            break
        step, _ = solve_damped(J, r, lam, "marquardt")
        # Projected onto the bounds (if any); the gain ratio uses the step actually taken.
        x_new = problem.clip(x + step)
        step = x_new - x
        r_new = problem.residuals(x_new)
        nfev += 1
        cost_new = 0.5 * float(r_new @ r_new)
        Js = J @ step
        predicted = float(step @ g) - 0.5 * float(Js @ Js)
        rho = (cost - cost_new) / predicted if predicted > 0 else -1.0
        small_step = np.linalg.norm(step) < xtol * (xtol + np.linalg.norm(x))
        if rho > 0:
            nit += 1
            small_change = cost - cost_new < ftol * cost
            x, r, cost = x_new, r_new, cost_new
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
