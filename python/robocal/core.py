"""NumPy-friendly entry points to the compiled core's free functions.

Inputs may be any array-like; they are converted here to contiguous float64 (the compiled
module takes nothing else) with errors that name the argument. Shapes, finiteness and values are
checked again in Rust.
"""

from __future__ import annotations

import numpy as np

from . import _robocal
from .exceptions import InvalidParameterError


def as_float_array(value, name: str) -> np.ndarray:
    """``value`` as a C-contiguous float64 array, or an error naming ``name``."""
    try:
        return np.ascontiguousarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidParameterError(f"`{name}` must be numeric array-like; got {type(value).__name__} ({exc})") from None


def merwe_sigma_points(x, P, alpha: float = 1e-3, beta: float = 2.0, kappa: float = 0.0):
    """Merwe scaled sigma points (filterpy's ``MerweScaledSigmaPoints``).

    Parameters
    ----------
    x : array_like, shape (n,)
    P : array_like, shape (n, n)
        Symmetric positive definite covariance.
    alpha, beta, kappa : float

    Returns
    -------
    sigmas : ndarray, shape (2n+1, n)
    Wm, Wc : ndarray, shape (2n+1,)
    """
    return _robocal.merwe_sigma_points(as_float_array(x, "x"), as_float_array(P, "P"), float(alpha), float(beta), float(kappa))


def unscented_transform(sigmas_x, sigmas_y, Wm, Wc):
    """Mean and covariance of propagated sigma points and their cross-covariance.

    Returns ``(mean_y (k,), cov_y (k, k), cross (n, k))`` — the paper's eq. (10)-(11).
    """
    return _robocal.unscented_transform(
        as_float_array(sigmas_x, "sigmas_x"), as_float_array(sigmas_y, "sigmas_y"), as_float_array(Wm, "Wm"), as_float_array(Wc, "Wc")
    )


def solve_damped(J, r, lam: float, damping: str = "marquardt"):
    """Damped normal-equation step ``(JᵀJ + λD) δ = Jᵀr``.

    ``damping="marquardt"`` uses ``D = diag(JᵀJ)``, ``"identity"`` the paper's ``D = I`` (eq. 14).
    Returns ``(delta (n,), method)`` with method ``"cholesky"`` or ``"svd"`` (the rank-revealing
    fallback for a matrix that is not positive definite).
    """
    return _robocal.solve_damped(as_float_array(J, "J"), as_float_array(r, "r"), float(lam), damping)


def identifiability(J, tol: float = 1e-9) -> dict:
    """Rank, singular values, identifiable subset and redundancies of a Jacobian (m, n).

    Computed on unit-norm columns. ``redundant`` lists, for each parameter outside the subset,
    ``(j, [(k, c_k), ...])`` with scaled column ``j ≈ Σ c_k · column k``.
    """
    return _robocal.identifiability(as_float_array(J, "J"), float(tol))


def covariance(J, r, tol: float = 1e-9):
    """Parameter covariance ``σ̂²(JᵀJ)⁺`` with ``σ̂² = ‖r‖²/(rows − rank)``.

    Returns ``(cov (n, n), sigma2, dof, rank)``.
    """
    return _robocal.covariance(as_float_array(J, "J"), as_float_array(r, "r"), float(tol))


def cable_initial_guess(p, L):
    """Closed-form cable anchor ``P0`` (mm) and sensor zero ``L0`` (mm) from tool points ``p``
    (m, 3) and cable lengths ``L`` (m,). Exact on noiseless data."""
    return _robocal.cable_initial_guess(as_float_array(p, "p"), as_float_array(L, "L"))
