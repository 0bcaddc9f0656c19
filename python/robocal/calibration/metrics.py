"""The paper's evaluation metrics, eq. (28), on per-sample errors.

``e_i`` is the per-sample error: ``|Z_i − Z'_i|`` for cable lengths, the Euclidean position
error for position and pose data (mm). The paper calls ``mean(e)`` "STD"; by its formula it is
the mean absolute error, and robocal names it so (``mae``).
"""

from __future__ import annotations

import numpy as np

from ..robot import RESIDUAL_WIDTH


def sample_errors(residuals: np.ndarray, measurement: str) -> np.ndarray:
    """Per-sample error (mm) from residuals of shape (m, k) or flattened (m·k,)."""
    width = RESIDUAL_WIDTH[measurement]
    r = np.asarray(residuals, dtype=np.float64).reshape(-1, width)
    return np.abs(r[:, 0]) if width == 1 else np.linalg.norm(r[:, :3], axis=1)


def metrics(residuals: np.ndarray, measurement: str) -> dict:
    """``{"rmse", "mae", "max", "n"}`` of eq. (28), in mm; pose data add ``rotation_rmse_deg``,
    the RMS of the orientation error's angle (the rotation residual ``log(R_meas·Rᵀ)``)."""
    e = sample_errors(residuals, measurement)
    out = {"rmse": float(np.sqrt(np.mean(e**2))), "mae": float(np.mean(e)), "max": float(np.max(e)), "n": int(e.size)}
    if RESIDUAL_WIDTH[measurement] == 6:
        angle = np.linalg.norm(np.asarray(residuals, dtype=np.float64).reshape(-1, 6)[:, 3:], axis=1)
        out["rotation_rmse_deg"] = float(np.degrees(np.sqrt(np.mean(angle**2))))
    return out
