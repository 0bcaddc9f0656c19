"""The sensors' noise: what a reading's error is, by measurement type.

Part of the model: the simulator draws its noise from it, and a calibration scales its priors
(:class:`~robocal.calibration.problem.Problem`) and its Kalman filters' measurement covariance
by it.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SensorNoise:
    """Sensor noise.

    Attributes
    ----------
    sigma : float
        Standard deviation of a length (cable) or of each position coordinate, mm.
    sigma_rotation : float
        Standard deviation of each rotation-vector component of a pose, rad.
    resolution : float
        Quantisation step of the reading, mm (0: none).
    """

    sigma: float = 0.0
    sigma_rotation: float = 0.0
    resolution: float = 0.0


#: Defaults: cable HY150-2000 (0.004 mm resolution, ~0.03 mm repeatability); laser tracker
#: (~0.02 mm, ~1e-5 rad for a 6-DoF probe).
DEFAULT_NOISE = {
    "cable": SensorNoise(sigma=0.03, resolution=0.004),
    "position": SensorNoise(sigma=0.02),
    "pose": SensorNoise(sigma=0.02, sigma_rotation=1e-5),
}
