"""M9: the paper's UKF-VSLM cascade (Algorithm 1).

The UKF-step (lines 3-15) filters the samples one by one for ``sweeps`` passes to get
``x_ukf``; the VSLM-step (lines 16-21) starts eq. (15) from ``x_ukf`` on all samples at once.
"""

from __future__ import annotations

import time

from .kalman import ukf
from .problem import Problem
from .result import CalibrationResult
from .vslm import LAMBDA, vslm


def ukf_vslm(
    problem: Problem,
    x0=None,
    sweeps: int = 5,
    P0=None,
    Q=None,
    R=None,
    alpha: float = 0.1,
    beta: float = 2.0,
    kappa: float = 0.0,
    delta0: float = 0.8,
    mu: float = 0.95,
    lam: float = LAMBDA,
    max_iter: int = 200,
    ftol: float = 1e-10,
    xtol: float = 1e-10,
) -> CalibrationResult:
    """M9: UKF sweeps (:func:`~robocal.calibration.kalman.ukf`), then VSLM
    (:func:`~robocal.calibration.vslm.vslm`) from the UKF estimate (Algorithm 1).

    Parameters
    ----------
    problem : Problem
    x0 : array_like, optional
        Start of the UKF (default ``problem.x0``).
    sweeps, P0, Q, R, alpha, beta, kappa
        UKF options (``sweeps`` is ``T_3``).
    delta0, mu, lam, max_iter, ftol, xtol
        VSLM options (``max_iter`` is ``T_9``).

    Returns
    -------
    CalibrationResult
        ``method="ukf-vslm"``. ``history`` is the UKF's (start, then each sweep) followed by the
        VSLM's iterations (its start, the UKF estimate, is not repeated); ``nit`` and ``nfev`` add
        both stages; ``success`` is the VSLM's; ``message`` reports both.
    """
    start = time.perf_counter()
    first = ukf(problem, x0=x0, sweeps=sweeps, P0=P0, Q=Q, R=R, alpha=alpha, beta=beta, kappa=kappa)
    second = vslm(problem, x0=first.x, delta0=delta0, mu=mu, lam=lam, max_iter=max_iter, ftol=ftol, xtol=xtol, method="ukf-vslm")
    history = first.history + second.history[1:]
    message = f"UKF: {first.message}; VSLM: {second.nit} iterations, {second.message}"
    return CalibrationResult.from_fit(
        "ukf-vslm", problem, second.x, history, first.nit + second.nit, first.nfev + second.nfev, second.success, message, time.perf_counter() - start
    )


#: Entries for ``robocal.calibration.api.METHODS``.
METHODS = {"ukf-vslm": ("M9", "UKF-VSLM cascade (Algorithm 1): UKF sweeps, then VSLM from the UKF estimate", ukf_vslm)}
