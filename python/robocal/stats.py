"""Robust statistics shared by the layers above.

One rule: the robust scale of multi-component residuals (x, y, z; a pose's rotation vector) is
taken per component. The median of Euclidean norms times 1.4826 is not a standard deviation: for
Gaussian components of standard deviation σ the norm of a 3-D residual has median ≈ 1.54 σ, so
that recipe over-states σ about 2.3 times (and "2.5 robust sigmas" becomes ≈ 5.7 σ).
"""

from __future__ import annotations

import numpy as np

from .exceptions import ShapeError


def robust_sigma(residuals, floor: float = 1e-12) -> np.ndarray:
    """Robust standard deviation of each residual component.

    Parameters
    ----------
    residuals : array_like, shape (m,) or (m, k)
        Samples in rows, components (cable length; x, y, z; rotation vector) in columns.
    floor : float
        Smallest value returned, so that the scale can divide (noiseless data have MAD 0).

    Returns
    -------
    ndarray, shape (k,)
        ``scipy.stats.median_abs_deviation(scale="normal")`` of each column: 1.4826 × the
        median absolute deviation from the column's median, σ for normal errors.
    """
    r = np.asarray(residuals, dtype=np.float64)
    if r.ndim == 1:
        r = r[:, None]
    if r.ndim != 2 or len(r) == 0:
        raise ShapeError(f"`residuals` must have shape (m, k) with m >= 1; got {r.shape}")
    from scipy.stats import median_abs_deviation  # here: scipy.stats takes 0.6 s to import, which every command importing robocal.stats paid

    return np.maximum(median_abs_deviation(r, axis=0, scale="normal"), floor)


def rmse_of_squares(squared_errors) -> float:
    """RMSE of eq. (28) from per-sample squared errors (the per-sample error is the cable
    residual, or the Euclidean norm of the position and rotation residual)."""
    return float(np.sqrt(np.mean(squared_errors)))


def paired_z(alternative: np.ndarray, candidate: np.ndarray) -> float:
    """By how many standard errors ``candidate``'s squared errors per sample are below
    ``alternative``'s (a paired z score of the per-sample differences); 0 with fewer than two
    samples."""
    d = np.asarray(alternative, dtype=float) - np.asarray(candidate, dtype=float)
    if len(d) < 2:
        return 0.0
    return float(np.mean(d) / max(float(np.std(d)) / np.sqrt(len(d)), 1e-300))
