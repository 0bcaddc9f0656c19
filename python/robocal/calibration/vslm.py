"""The paper's Levenberg–Marquardt (M6, eq. 14) and variable step-size LM (M8, VSLM, eq. 15).

Both iterate ``x ← x + δ_t (JᵀJ + λI)⁻¹ Jᵀ r`` with a FIXED damping ``λ`` and identity damping
matrix (``solve_damped(J, r, λ, "identity")``); M6 has ``δ_t = 1``, M8 ``δ_{t+1} = μ δ_t``.
Unlike robocal's production :func:`~robocal.calibration.lm.levenberg_marquardt` there is no gain
test: every step is taken, as the paper describes, so the cost may rise on an iteration.

The damping ``λ``: the paper calls it a learning rate and does not give its value. The default
``λ = 1e-6`` (in the units of ``JᵀJ``, i.e. mm²/mm² for lengths and mm²/rad² for angles) is
chosen well below the smallest eigenvalue of ``JᵀJ`` met on 100-sample simulated cable and
position problems (≈1e-4 to 1e-2), so it only regularises truly singular directions and does not
stall convergence in weakly identified ones (a direction with eigenvalue ``s²`` contracts by
``λ / (s² + λ)`` per full step).

With ``δ_0 = 0.8`` and ``μ = 0.95`` the step sizes sum to ``δ_0 / (1 − μ) = 16``; near the
solution the error contracts by ``Π_t (1 − δ_t) ≈ 3.5e-10`` in total, so VSLM converges in
practice although its steps vanish geometrically.
"""

from __future__ import annotations

import time

import numpy as np

from ..kernels import as_count, as_float, as_tolerance, solve_damped
from ..exceptions import InvalidParameterError
from .problem import Problem, initial_x
from .result import CalibrationResult

#: Default fixed damping of eq. (14)-(15); see the module notes.
LAMBDA = 1e-6


def damped_iterations(
    problem: Problem,
    method: str,
    x0=None,
    lam: float = LAMBDA,
    max_iter: int = 100,
    delta0: float = 1.0,
    mu: float = 1.0,
    ftol: float = 1e-10,
    xtol: float = 1e-10,
) -> CalibrationResult:
    """``x ← x + δ_t (JᵀJ + λI)⁻¹ Jᵀ r``, ``δ_{t+1} = μ δ_t`` (eq. 15; eq. 14 with ``δ = μ = 1``).

    Stops after ``max_iter`` iterations (``success=False``), or when the step is small,
    ``‖Δx‖ < xtol (xtol + ‖x‖)``, or the cost changes by less than ``ftol · cost``
    (``success=True``). The history holds the cost at the start and after every iteration.
    """
    lam, ftol, xtol = as_tolerance(lam, "lam"), as_tolerance(ftol, "ftol"), as_tolerance(xtol, "xtol")
    max_iter = as_count(max_iter, "max_iter")
    if not (np.isfinite(as_float(delta0, "delta0")) and delta0 > 0 and 0 < as_float(mu, "mu") <= 1):
        raise InvalidParameterError(f"need `delta0` > 0 and 0 < `mu` <= 1; got delta0={delta0!r}, mu={mu!r}")
    start = time.perf_counter()
    x = initial_x(problem, x0)
    r = problem.residuals(x)
    cost, delta = 0.5 * float(r @ r), float(delta0)
    history, nit = [cost], 0
    success, message = False, f"the maximum number of iterations ({max_iter}) is reached"
    while nit < max_iter:
        step, _ = solve_damped(problem.jacobian(x), r, lam, "identity")
        step *= delta
        x_new = problem.clip(x + step)  # bounds, if the problem has any
        step, x = x_new - x, x_new
        r = problem.residuals(x)
        cost_new = 0.5 * float(r @ r)
        nit += 1
        history.append(cost_new)
        delta *= mu
        small_step = np.linalg.norm(step) < xtol * (xtol + np.linalg.norm(x))
        small_change = abs(cost - cost_new) < ftol * cost
        cost = cost_new
        if small_step or small_change:
            success = True
            message = "`xtol` termination condition is satisfied" if small_step else "`ftol` termination condition is satisfied"
            break
    return CalibrationResult.from_fit(method, problem, x, history, nit, nit + 1, success, message, time.perf_counter() - start)


def lm_paper(problem: Problem, x0=None, lam: float = LAMBDA, max_iter: int = 100, ftol: float = 1e-10, xtol: float = 1e-10) -> CalibrationResult:
    """M6: Levenberg–Marquardt as in the paper's eq. (14), fixed ``λ``, identity damping, unit step.

    Parameters
    ----------
    problem : Problem
    x0 : array_like, optional
        Start (default ``problem.x0``).
    lam : float
        Fixed damping ``λ`` (default :data:`LAMBDA`; the paper gives none, see the module notes).
    max_iter : int
        Iteration budget (``T_6``).
    ftol, xtol : float
        Relative cost-change and step tolerances.

    Returns
    -------
    CalibrationResult
        ``method="lm-paper"``.
    """
    return damped_iterations(problem, "lm-paper", x0=x0, lam=lam, max_iter=max_iter, ftol=ftol, xtol=xtol)


def vslm(
    problem: Problem,
    x0=None,
    delta0: float = 0.8,
    mu: float = 0.95,
    lam: float = LAMBDA,
    max_iter: int = 200,
    ftol: float = 1e-10,
    xtol: float = 1e-10,
    method: str = "vslm",
) -> CalibrationResult:
    """M8: variable step-size Levenberg–Marquardt, eq. (15).

    Parameters
    ----------
    problem : Problem
    x0 : array_like, optional
        Start (default ``problem.x0``).
    delta0, mu : float
        Initial step size ``δ_0`` and its decay ``μ`` (the paper's 0.8 and 0.95).
    lam : float
        Fixed damping ``λ`` (default :data:`LAMBDA`; the paper gives none, see the module notes).
    max_iter : int
        Iteration budget (``T_9``).
    ftol, xtol : float
        Relative cost-change and step tolerances.
    method : str
        Name recorded in the result.

    Returns
    -------
    CalibrationResult
    """
    return damped_iterations(problem, method, x0=x0, lam=lam, max_iter=max_iter, delta0=delta0, mu=mu, ftol=ftol, xtol=xtol)


#: Entries for ``robocal.calibration.api.METHODS``.
METHODS = {
    "lm-paper": ("M6", "Levenberg-Marquardt of eq. (14): fixed damping, identity damping matrix", lm_paper),
    "vslm": ("M8", "variable step-size Levenberg-Marquardt, eq. (15)", vslm),
}
