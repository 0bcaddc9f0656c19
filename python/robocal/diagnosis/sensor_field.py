"""The sensor's own error: which of its shapes the current residuals follow best.

A sensor errs in its own variable, not in the robot's joints: a drawstring sensor's drum once a
turn of the length it reads; a laser tracker's azimuth encoder with the direction from the
tracker's standing axis. Neither shape is fixed in advance — a drum's circumference, where the
tracker stood — so each round scans them against the current model's residuals
(:func:`sensor_candidates`) and offers the best as one candidate, its p-value corrected for the
number of shapes scanned (``detail["scanned"]``, as a step's for the positions it was chosen
among). Without such a candidate, a tracker's azimuth error was named as joint 1's scale,
harmonic and coupling and a drum's as a wander or steps (the mismatch section of
``benches/discovery.py``).
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from ..causes.candidates import Candidate, sensor_periodic_candidate, tracker_azimuth_candidate
from ..data.dataset import Dataset
from ..kernels import is_sparse

#: Shortest drum period scanned (mm): drawstring sensors' drums are 30 mm round and more.
SHORTEST_PERIOD_MM = 30.0
#: A period must repeat this many times over the lengths read: one arc is a scale or a drift.
CYCLES_SEEN = 1.5
#: Frequencies scanned per independent one (1 / the lengths' span): a peak between two is not missed.
OVERSAMPLING = 4
#: Where a tracker may have stood: this far beyond the farthest reading from the readings'
#: centre (mm), in this many directions about it. A tracker is not among the points it measures,
#: and a station near the robot's base axis would be joint 1's own error.
STATION_DISTANCES_MM = (1000.0, 2000.0, 3500.0)
STATION_DIRECTIONS = 24
#: The nearest a tracker stands to a point it measures (mm): the readings' own origin (a
#: tracker's frame) is scanned only beyond it.
NEAREST_READING_MM = 1000.0
#: Azimuth harmonics scanned (cycles a turn).
AZIMUTH_HARMONICS = (1, 2, 3)
#: Candidates scored at once (their columns side by side).
CHUNK = 16


def drum_periods(lengths: np.ndarray) -> tuple[np.ndarray, int]:
    """The periods (mm) scanned for a cable's readings ``lengths`` and how many of them are
    independent (the frequency band times the span: the Bonferroni count)."""
    span = float(np.ptp(lengths))
    if span <= 0:
        return np.zeros(0), 0
    low, high = CYCLES_SEEN / span, 1.0 / SHORTEST_PERIOD_MM
    if low >= high:
        return np.zeros(0), 0
    freqs = np.arange(low, high, 1.0 / (OVERSAMPLING * span))
    return 1.0 / freqs, int(np.ceil((high - low) * span))


def tracker_stations(points: np.ndarray) -> np.ndarray:
    """Where a tracker may have stood (x, y in the readings' frame, mm), for the readings
    ``points`` (m, 3): a ring of directions at each of :data:`STATION_DISTANCES_MM` beyond the
    farthest reading, and the frame's origin if it lies that far from every reading (readings
    in the tracker's own frame)."""
    xy = points[:, :2]
    centre = xy.mean(axis=0)
    reach = float(np.max(np.linalg.norm(xy - centre, axis=1)))
    angles = np.arange(STATION_DIRECTIONS) * (2.0 * np.pi / STATION_DIRECTIONS)
    ring = np.column_stack([np.cos(angles), np.sin(angles)])
    stations = [centre + (reach + d) * ring for d in STATION_DISTANCES_MM]
    if np.min(np.linalg.norm(xy, axis=1)) > NEAREST_READING_MM:
        stations.append(np.zeros((1, 2)))
    return np.vstack(stations)


def sensor_shapes(data: Dataset, named: list[Candidate]) -> tuple[list, int]:
    """Every shape of the sensor's own error scanned on ``data`` (builders of candidates, each
    called with nothing) and the count the chosen one's test is corrected for. Beside the
    sensor's errors ``named`` already, only what the same instrument can add: a session has one
    drum and one station, so the drum's harmonics (half, a third of its period) and the
    station's other harmonics."""
    if data.measurement == "cable":
        if named:
            periods = np.array([c.detail["period"] / h for c in named[:1] for h in (2, 3)])
            return [lambda P=P: sensor_periodic_candidate(data, P) for P in periods], len(periods)
        periods, independent = drum_periods(data.y[:, 0])
        return [lambda P=P: sensor_periodic_candidate(data, P) for P in periods], independent
    stations = [np.array(named[0].detail["station_xy"], dtype=float)] if named else tracker_stations(data.y[:, :3])
    taken = {c.detail["harmonic"] for c in named}
    shapes = [lambda s=s, h=h: tracker_azimuth_candidate(data, s, h) for s in stations for h in AZIMUTH_HARMONICS if h not in taken]
    return shapes, len(shapes)


def sensor_candidates(data: Dataset, idx: np.ndarray, J, residual: np.ndarray, weights: np.ndarray, named: list[Candidate]) -> list[Candidate]:
    """The sensor's own error most like the current model's residuals: of every shape scanned
    (:func:`sensor_shapes`; ``named``: the sensor's errors the model has) the one whose columns, with the model's Jacobian ``J`` (data rows of
    the samples ``idx``, weighted by ``weights``) refitted beside them, remove most of
    ``residual`` — as one candidate whose ``detail["scanned"]`` says how many shapes it was
    chosen among. Empty if nothing is scanned."""
    shapes, scanned = sensor_shapes(data, named)
    if not shapes:
        return []
    gram = J.T @ J
    gram = np.asarray(gram.toarray() if is_sparse(gram) else gram)
    inverse = np.linalg.pinv(gram)  # the model's own columns projected off each candidate's
    best, best_gain = None, -np.inf
    for start in range(0, len(shapes), CHUNK):
        built = [make() for make in shapes[start : start + CHUNK]]
        C = np.concatenate([c.basis[idx].reshape(len(residual), -1) for c in built], axis=1) * weights[:, None]
        JC = np.asarray(J.T @ C)
        CC = C.T @ C - JC.T @ inverse @ JC
        Cr = C.T @ residual
        for i, c in enumerate(built):
            block = slice(2 * i, 2 * i + 2)
            gain = _explained(CC[block, block], Cr[block])
            if gain is not None and gain > best_gain:
                best, best_gain = c, gain
    if best is None:
        return []
    best.detail["scanned"] = scanned
    return [best]


def _explained(CC: np.ndarray, Cr: np.ndarray) -> Optional[float]:
    """The residual sum of squares two columns remove (``CC`` their projected Gram matrix,
    ``Cr`` their products with the residuals); None where they are degenerate."""
    values = np.linalg.eigvalsh(CC)
    if values[0] <= 1e-9 * max(values[-1], 1e-300):  # the model's columns take one of them whole
        return None
    return float(Cr @ np.linalg.solve(CC, Cr))
