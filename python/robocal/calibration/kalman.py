"""Kalman-filter calibrators: the extended (M1) and unscented (M3) Kalman filter of Table VI.

The filter state is the free-parameter vector ``x`` of the :class:`Problem` (a constant-parameter
model: the transition ``Φ`` of eq. (8) is the identity, plus a small process noise ``Q``). The
training samples are processed one at a time as observations: sample ``i`` contributes the
innovation ``r_i(x) = y_i − h_i(x)`` (the residual form of ``Y_k − ŷ_{k|k−1}`` in eq. (12)),
and the data are swept ``sweeps`` times (the outer loop ``k = 1..T_3`` of Algorithm 1). As in
Algorithm 1 (line 4), the covariance restarts from ``P0`` at the start of every sweep, so each
sweep is a fresh filter started from the previous sweep's estimate (``reset=False`` carries ``P``
over instead, which makes later sweeps count the same data again with growing confidence).

Defaults (the paper states none of them):

* ``P0 = diag(σ_p²)`` with ``σ_p`` = 1 mm for lengths, 0.1° for angles and 1e-3 for unitless
  parameters (``problem.robot.param_units``) — about twice the geometric errors the simulator
  draws (0.5 mm, 0.05°), i.e. a realistic prior uncertainty of nominal kinematics.
* ``R = diag(σ_y²)`` from the sensor's default noise (:data:`robocal.sensors.DEFAULT_NOISE`):
  (0.03 mm)² for the cable sensor, (0.02 mm)² per coordinate for a laser tracker and
  (1e-5 rad)² per rotation-vector component of a pose.
* ``Q = 1e-12 · P0`` per sample: the parameters are constant; this only keeps ``P``
  positive definite over thousands of updates.
* Merwe sigma points (UKF) ``alpha=0.1, beta=2, kappa=0``: ``beta=2`` is optimal for Gaussian
  priors; ``alpha=0.1`` keeps the sigma points within the prior while avoiding the large negative
  centre weights (``1 − 1/alpha²``) and cancellation of very small ``alpha``.
"""

from __future__ import annotations

import math
import time
from typing import Callable

import numpy as np

from ..kernels import as_count, as_float, as_float_array
from ..exceptions import InvalidParameterError
from ..sensors import DEFAULT_NOISE
from .problem import Problem, initial_x
from .result import CalibrationResult

#: Prior standard deviation of a parameter by unit (mm, rad, unitless), see the module notes.
PRIOR_SIGMA = {"mm": 1.0, "rad": math.radians(0.1), "1": 1e-3}
#: Process noise per sample as a fraction of ``P0``.
Q_FRACTION = 1e-12


def prior_covariance(problem: Problem) -> np.ndarray:
    """Default ``P0``: diagonal, with :data:`PRIOR_SIGMA` ² by the unit of each free parameter."""
    units = [problem.robot.param_units[k] for k in problem.free]
    return np.diag([PRIOR_SIGMA[u] ** 2 for u in units])


def sensor_covariance(measurement: str) -> np.ndarray:
    """Default ``R`` of one sample: the sensor's default noise variances, shape (k, k)."""
    noise = DEFAULT_NOISE[measurement]
    sigmas = {"cable": [noise.sigma], "position": [noise.sigma] * 3, "pose": [noise.sigma] * 3 + [noise.sigma_rotation] * 3}[measurement]
    return np.diag(np.square(sigmas))


def _matrix(value, size: int, name: str) -> np.ndarray:
    """A covariance option as a (size, size) matrix: a scalar variance, a diagonal or a matrix."""
    a = as_float_array(value, name)
    if a.ndim == 0:
        a = np.full(size, float(a))
    if a.ndim == 1 and a.shape == (size,):
        a = np.diag(a)
    if a.shape != (size, size) or not np.all(np.isfinite(a)):
        raise InvalidParameterError(f"`{name}` must be a finite variance, ({size},) variances or a ({size}, {size}) matrix; got shape {a.shape}")
    return a


def _sample(problem: Problem, i: int) -> tuple[np.ndarray, np.ndarray]:
    """Joint values and observation of sample ``i``, each of shape (1, ·)."""
    return problem.data.q[i : i + 1], problem.data.y[i : i + 1].reshape(1, -1)


def ekf_update(problem: Problem, i: int, x: np.ndarray, P: np.ndarray, Q: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One EKF step on sample ``i``: predict with ``Φ = I`` and ``Q``, update with the sample's
    residual and Jacobian ``J_i = ∂h_i/∂x`` (eq. 5).

    ``S = J P⁻ Jᵀ + R``, ``K = P⁻ Jᵀ S⁻¹``, ``x ← x + K r_i``, ``P ← P⁻ − K S Kᵀ`` (the
    linearised counterpart of eq. 11-12).

    Returns the updated estimate and covariance.
    """
    q, y = _sample(problem, i)
    params, m = problem.full(x), problem.data.measurement
    P = P + Q
    r = problem.robot.residuals(m, q, y, params=params).ravel()
    J = problem.robot.jacobian(m, q, y=y, params=params, cols=problem.free)
    S = J @ P @ J.T + R
    K = np.linalg.solve(S, J @ P).T  # P Jᵀ S⁻¹ (S and P symmetric)
    return x + K @ r, P - K @ S @ K.T


def ekf_sweep(problem: Problem, x: np.ndarray, P0: np.ndarray, Q: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One EKF pass over the training samples in order (see :func:`ekf_update`)."""
    P = P0
    for i in range(len(problem.data)):
        x, P = ekf_update(problem, i, x, P, Q, R)
        P = 0.5 * (P + P.T)
    return x, P


def ukf_sweep(
    problem: Problem, x: np.ndarray, P0: np.ndarray, Q: np.ndarray, R: np.ndarray, alpha: float = 0.1, beta: float = 2.0, kappa: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """One UKF pass over the training samples (eq. 8-12), run entirely in the Rust core.

    Per sample the Merwe sigma points ``X'`` of ``(x, P)`` pass through ``Φ = I`` (eq. 8), so
    ``x̂⁻ = x`` and ``P⁻ = P + Q`` (eq. 9); their predicted observations give ``ŷ``, ``S``
    (+ ``R``), ``P_xy`` and the gain ``ρ = P_xy S⁻¹`` (eq. 10-11); then
    ``x̂ = x̂⁻ + ρ (Y − ŷ)``, ``P = P⁻ − ρ S ρᵀ`` (eq. 12). In residual form ``Y'_i = −r(X'_i)``
    and the observation is 0: the same gain and innovation, with mm-size numbers instead of
    metre-size readings. The NumPy twin is :func:`robocal.reference.ukf_sweep`.
    """
    d = problem.data
    return problem.robot.chain.ukf_sweep(d.measurement, problem.start, problem.free.tolist(), d.q, d.y, x, P0, Q, R, alpha, beta, kappa)


def kalman_filter(
    problem: Problem,
    sweep: Callable,
    method: str,
    model_evaluations: int,
    x0=None,
    sweeps: int = 5,
    P0=None,
    Q=None,
    R=None,
    reset: bool = True,
    **sweep_options,
) -> CalibrationResult:
    """The sweep loop shared by :func:`ekf` and :func:`ukf` (Algorithm 1, lines 3-14).

    Runs ``sweep(problem, x, P, Q, R, **sweep_options)`` over the samples ``sweeps`` times;
    ``P`` restarts from ``P0`` at every sweep unless ``reset=False``. The history holds the
    training cost ``½‖r‖²`` at the start and after every sweep; ``nit`` is the number of sweeps
    and ``nfev`` counts model evaluations in units of the whole training set
    (``model_evaluations`` per sample and sweep, plus one for each cost).
    """
    sweeps = as_count(sweeps, "sweeps")
    start = time.perf_counter()
    n, m = len(problem.free), len(problem.data)
    P0 = prior_covariance(problem) if P0 is None else _matrix(P0, n, "P0").copy()
    x = initial_x(problem, x0)
    # Priors given with the problem are the filter's own prior: mean as start, sigma² in P0.
    for name, (mean, sigma) in problem.prior.items():
        k = problem.names.index(name)
        P0[k, :] = P0[:, k] = 0.0
        P0[k, k] = sigma**2
        if x0 is None:
            x[k] = mean
    Q = Q_FRACTION * P0 if Q is None else _matrix(Q, n, "Q")
    R_sensor = sensor_covariance(problem.data.measurement)
    R = R_sensor if R is None else _matrix(R, len(R_sensor), "R")
    P, history = P0.copy(), [problem.cost(x)]
    for _ in range(sweeps):
        x, P = sweep(problem, x, P0.copy() if reset else P, Q, R, **sweep_options)
        x = problem.clip(x)  # bounds, if the problem has any, hold after every sweep
        history.append(problem.cost(x))
    message = f"{sweeps} sweeps of {m} samples completed (cost {history[0]:.6g} -> {history[-1]:.6g})"
    nfev = 1 + sweeps * (model_evaluations + 1)
    return CalibrationResult.from_fit(method, problem, x, history, sweeps, nfev, True, message, time.perf_counter() - start)


def ekf(problem: Problem, x0=None, sweeps: int = 5, P0=None, Q=None, R=None, reset: bool = True) -> CalibrationResult:
    """M1: extended Kalman filter over the free parameters (Table VI; Jiang et al. [9]).

    Parameters
    ----------
    problem : Problem
    x0 : array_like, optional
        Start (default ``problem.x0``).
    sweeps : int
        Passes through the training samples (``T_1``).
    P0, Q, R : float, array_like or None
        Prior, process-noise (per sample) and measurement-noise covariances: a variance, a
        diagonal or a matrix. Defaults: see the module notes.
    reset : bool
        Restart ``P`` from ``P0`` at every sweep (Algorithm 1, line 4).

    Returns
    -------
    CalibrationResult
        ``method="ekf"``, the cost history per sweep, ``nit = sweeps``.
    """
    return kalman_filter(problem, ekf_sweep, "ekf", 1, x0=x0, sweeps=sweeps, P0=P0, Q=Q, R=R, reset=reset)


def ukf(
    problem: Problem,
    x0=None,
    sweeps: int = 5,
    P0=None,
    Q=None,
    R=None,
    alpha: float = 0.1,
    beta: float = 2.0,
    kappa: float = 0.0,
    reset: bool = True,
) -> CalibrationResult:
    """M3: unscented Kalman filter over the free parameters (Table VI; the UKF-step of Algorithm 1,
    eq. 8-12).

    Parameters
    ----------
    problem : Problem
    x0 : array_like, optional
        Start (default ``problem.x0``).
    sweeps : int
        Passes through the training samples (``T_3``).
    P0, Q, R : float, array_like or None
        Prior, process-noise (per sample) and measurement-noise covariances: a variance, a
        diagonal or a matrix. Defaults: see the module notes.
    alpha, beta, kappa : float
        Merwe scaled sigma-point parameters (filterpy's ``MerweScaledSigmaPoints``).
    reset : bool
        Restart ``P`` from ``P0`` at every sweep (Algorithm 1, line 4).

    Returns
    -------
    CalibrationResult
        ``method="ukf"``, the cost history per sweep, ``nit = sweeps``.
    """
    n_sigma = 2 * len(problem.free) + 1
    sigma_points = {"alpha": as_float(alpha, "alpha"), "beta": as_float(beta, "beta"), "kappa": as_float(kappa, "kappa")}
    return kalman_filter(problem, ukf_sweep, "ukf", n_sigma, x0=x0, sweeps=sweeps, P0=P0, Q=Q, R=R, reset=reset, **sigma_points)


#: Entries for ``robocal.calibration.api.METHODS``.
METHODS = {
    "ekf": ("M1", "extended Kalman filter over the parameters, samples one by one", ekf),
    "ukf": ("M3", "unscented Kalman filter over the parameters, samples one by one (eq. 8-12)", ukf),
}
