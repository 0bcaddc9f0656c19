"""The error budget: how much of the remaining residual the data's own resolution explains.

Joint readings and sensor readings are written with a finite number of decimals (D2's joints on
a 0.1° grid, D1's on 0.001°, its cable on 0.01 mm). A reading rounded to a grid of step ``r``
carries a uniform error of variance ``r²/12``; propagated through the measurement model's
sensitivity to each joint (the ``θ_j`` columns of the identification Jacobian) and added to the
sensor's own (its grid, or the per-reading standard deviations a tracker file records), it gives
the residual a perfect model would still leave: the floor. A final RMSE near the floor means
nothing is left to find; well above it, that much is unexplained.

Where the data revisit a joint configuration (UR10 series B reaches each configuration again a few
samples later), the floor is also *measured*: the difference of the model's residuals at two
visits is the noise of two readings (the model predicts both alike), and their mean, less that
noise, is what the model still gets wrong at that configuration — systematic, so findable.
"""

from __future__ import annotations

from typing import Optional

import numpy as np
from scipy.spatial import cKDTree

from ..data.dataset import Dataset
from ..serial_robot import RESIDUAL_WIDTH, Robot

#: Decimal grids tried, as powers of ten (10⁰ … 10⁻⁸ of the unit).
DECIMALS = range(0, 9)


def resolution(values: np.ndarray) -> Optional[float]:
    """The coarsest decimal grid ``10⁻ᵏ`` on which every value lies (to 1e-6 of a step), or None
    if the values are on none (continuous, or finer than 10⁻⁸)."""
    v = np.asarray(values, dtype=np.float64).ravel()
    v = v[np.isfinite(v)]
    if v.size == 0 or np.ptp(v) == 0:
        return None
    for k in DECIMALS:
        step = 10.0**-k
        units = v / step
        if np.all(np.abs(units - np.round(units)) < 1e-6 * np.maximum(1.0, np.abs(units) * 1e-9)):
            return step
    return None


def joint_resolution(q: np.ndarray) -> tuple[Optional[float], str]:
    """The grid of one joint's readings (rad) and the unit it was written in: degrees if the
    readings lie on a decimal grid of degrees, else radians (a degree file converted to radians
    lies on no decimal grid of radians, and the other way round)."""
    deg, rad = resolution(np.degrees(q)), resolution(q)
    candidates = [(np.radians(deg), "deg")] if deg is not None else []
    candidates += [(rad, "rad")] if rad is not None else []
    if not candidates:
        return None, ""
    return max(candidates)


def floor(robot: Robot, data: Dataset, params: np.ndarray) -> dict:
    """The residual floor of ``data`` at parameters ``params``: ``floor_mm`` in eq. (28)'s RMSE,
    its parts from the joint readings and from the sensor, and the resolutions found."""
    k = RESIDUAL_WIDTH[data.measurement]
    n = robot.n_joints
    theta = [robot.index(f"theta{j + 1}") for j in range(n)]
    J = robot.jacobian(data.measurement, data.q, y=data.y, params=params, cols=theta)  # ∂h/∂q_j
    joint_var = np.zeros(len(data) * k)
    steps = []
    for j in range(n):
        step, unit = joint_resolution(data.q[:, j])
        steps.append(None if step is None else {"step": float(np.degrees(step) if unit == "deg" else step), "unit": unit})
        if step is not None:
            joint_var += J[:, j] ** 2 * step**2 / 12.0
    observed = data.y[:, :3] if data.measurement != "cable" else data.y
    sensor_step = resolution(observed)
    sensor_var = np.full((len(data), k), 0.0 if sensor_step is None else sensor_step**2 / 12.0)
    recorded = data.extra.get("measurement_std")
    if recorded is not None and np.shape(recorded)[1:] and np.shape(recorded)[1] >= min(k, 3):
        sensor_var[:, :3] += np.asarray(recorded, dtype=np.float64)[:, :3] ** 2  # the tracker's own

    def per_sample(var: np.ndarray) -> float:  # eq. (28): the RMS over samples of the summed components
        return float(np.sqrt(np.mean(var.reshape(len(data), k).sum(axis=1))))

    return {
        "floor_mm": per_sample(joint_var + sensor_var.ravel()),
        "joints_mm": per_sample(joint_var),
        "sensor_mm": per_sample(sensor_var.ravel()),
        "joint_resolution": steps,
        "sensor_resolution_mm": sensor_step,
        "sensor_std_recorded": recorded is not None,
        # Noise finer than the reading's grid is invisible in the data unless the file records it.
        "note": "joint and sensor rounding"
        + (
            " and the per-reading standard deviations the file records"
            if recorded is not None
            else "; sensor noise finer than its grid is not in the data and not counted"
        ),
    }


#: Joint readings within this of each other on every joint (rad, 0.06°) are one configuration
#: revisited: far below the scale on which any modelled error varies (a joint map's knots are 2°
#: or more apart), so the residuals' difference at two visits is the readings' noise alone.
REVISIT_TOLERANCE = 1e-3


def repeatability(q: np.ndarray, residuals: np.ndarray) -> Optional[dict]:
    """The floor measured from revisited configurations: ``q`` (m, n) joint readings, ``residuals``
    (m, k) a model's residuals (position components) at them. ``repeatability_mm`` is the RMS
    length of one reading's noise, ``sqrt(mean|r_a − r_b|² / 2)`` over the pairs; ``systematic_mm``
    the RMS length of the residual the visits share, less the noise it carries
    (``sqrt(mean|(r_a + r_b)/2|² − repeatability²/2)``; from residuals of a fit that saw the
    samples, so a lower bound). None without revisits."""
    pairs = cKDTree(q).query_pairs(REVISIT_TOLERANCE, p=np.inf, output_type="ndarray")
    # A row repeated in the file is the same reading twice, not a revisit: its noise is not in it.
    pairs = pairs[np.any(residuals[pairs[:, 0]] != residuals[pairs[:, 1]], axis=1)] if len(pairs) else pairs
    if len(pairs) == 0:
        return None
    a, b = pairs[:, 0], pairs[:, 1]
    noise = float(np.sqrt(np.mean(np.sum((residuals[a] - residuals[b]) ** 2, axis=1)) / 2.0))
    shared = float(np.mean(np.sum(((residuals[a] + residuals[b]) / 2.0) ** 2, axis=1)))
    systematic = float(np.sqrt(max(shared - noise**2 / 2.0, 0.0)))
    return {"pairs": int(len(pairs)), "samples": int(np.unique(pairs).size), "repeatability_mm": noise, "systematic_mm": systematic}
