"""The scan of the sensor's own error (:mod:`robocal.diagnosis.sensor_field`): its shortcut
products against a plain least-squares refit, and the shapes it may choose among."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

import robocal
from robocal.causes.candidates import tracker_azimuth_candidate
from robocal.diagnosis import sensor_field


def _removed(J: np.ndarray, C: np.ndarray, r: np.ndarray) -> float:
    """What ``C`` removes of ``r`` with ``J`` refitted beside it, by plain least squares."""

    def left(A):
        return r - A @ np.linalg.lstsq(A, r, rcond=None)[0]

    return float(np.sum(left(J) ** 2) - np.sum(left(np.hstack([J, C])) ** 2))


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), station=st.tuples(st.floats(-5000, 5000), st.floats(-5000, 5000)), harmonic=st.integers(1, 3))
def test_the_scans_gain_is_the_refits(seed, station, harmonic):
    """For a tracker's azimuth field about any station, the gain the scan computes from three
    products per station is what a least-squares refit of the model's columns beside the
    candidate's removes of the residuals (the residuals orthogonal to the model's columns, as a
    converged fit leaves them)."""
    rng = np.random.default_rng(seed)
    m, p = 40, 5
    points = rng.uniform(-800, 800, size=(m, 3))
    data = robocal.Dataset(q=rng.uniform(-1, 1, size=(m, 6)), y=points, measurement="position")
    J = rng.normal(size=(3 * m, p))
    r = rng.normal(size=3 * m)
    r -= J @ np.linalg.lstsq(J, r, rcond=None)[0]
    station = np.round(np.array(station))
    if np.min(np.linalg.norm(points[:, :2] - station, axis=1)) < 1.0:
        return  # a station on a reading: its azimuth is undefined there
    C = tracker_azimuth_candidate(data, station, harmonic).basis.reshape(3 * m, 2)
    rel = points[:, :2] - station
    azimuth = np.arctan2(rel[:, 1], rel[:, 0])
    rows = J.reshape(m, 3, p)
    W = np.stack([np.sin(harmonic * azimuth), np.cos(harmonic * azimuth)], axis=-1)[:, None, :]
    moved = (rows[:, 1] * rel[:, :1] - rows[:, 0] * rel[:, 1:]) * 1e-3
    along = (r.reshape(m, 3)[:, 1] * rel[:, 0] - r.reshape(m, 3)[:, 0] * rel[:, 1]) * 1e-3
    gain = sensor_field._gains(W, moved, along, np.linalg.pinv(J.T @ J), np.sum(rel**2, axis=1) * 1e-6)[0]
    assert np.isclose(gain, _removed(J, C, r), rtol=1e-6, atol=1e-9 * float(r @ r))


def test_a_drums_periods_and_their_count():
    """Periods from 30 mm to the span of the lengths over 1.5 cycles, four frequencies per
    independent one; the count a chosen period is corrected for is the independent ones."""
    periods, independent = sensor_field.drum_periods(np.linspace(500.0, 1400.0, 300))
    assert periods.max() <= 900.0 / 1.5 + 1e-9 and periods.min() >= 30.0 - 1e-9
    assert independent == int(np.ceil((1 / 30.0 - 1.5 / 900.0) * 900.0))
    assert len(periods) >= 4 * (independent - 1)
    assert len(sensor_field.drum_periods(np.full(10, 700.0))[0]) == 0  # a cable that never moved: no period to scan


def test_a_station_is_never_among_the_readings():
    """A station at the robot's own axis would be joint 1's error: every station scanned stands
    at least a metre beyond the farthest reading from their centre; the readings' own origin is
    scanned only where it lies that far from every reading (a tracker's frame)."""
    rng = np.random.default_rng(3)
    points = rng.uniform(-700, 700, size=(200, 3))
    stations = sensor_field.tracker_stations(points)
    nearest = np.min(np.linalg.norm(stations[:, None, :] - points[None, :, :2], axis=2), axis=1)
    assert np.all(nearest >= sensor_field.STATION_DISTANCES_MM[0] - 1e-6)
    assert not np.any(np.all(stations == 0.0, axis=1))  # the origin lies among these readings
    far = points + np.array([3000.0, 0.0, 0.0])
    assert np.any(np.all(sensor_field.tracker_stations(far) == 0.0, axis=1))
