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
#: Samples a scan chooses the shape on, at most.
SCANNED_SAMPLES = 3000
#: Azimuth harmonics scanned (cycles a turn).
AZIMUTH_HARMONICS = (1, 2, 3)


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


def sensor_candidates(data: Dataset, idx: np.ndarray, J, residual: np.ndarray, named: list[Candidate]) -> list[Candidate]:
    """The sensor's own error most like the current model's residuals: of every shape scanned
    (``named``: the sensor's errors the model has; beside them only what the same instrument can
    add: a session has one drum and one station, so the drum's harmonics — half, a third of its
    period — and the station's other harmonics) the one whose two columns, with the model's
    Jacobian ``J`` (its data rows of the samples ``idx``, weighted as a fit weighs them: a
    reading's position rows by one) refitted beside them, remove most of ``residual`` — as one
    candidate whose ``detail["scanned"]`` says how many shapes it was chosen among. Empty if
    nothing is scanned."""
    J = np.asarray(J.toarray() if is_sparse(J) else J)
    rows = J.reshape(len(idx), -1, J.shape[1])  # (samples, rows of a sample, parameters)
    left = residual.reshape(len(idx), -1)
    # The scan only proposes (the screening then tests the shape on every sample): on a long
    # session, an even share of its samples choose as well.
    every = slice(None, None, -(-len(idx) // SCANNED_SAMPLES))
    idx, rows, left = idx[every], rows[every], left[every]
    flat = rows.reshape(-1, rows.shape[2])
    inverse = np.linalg.pinv(flat.T @ flat)  # the model's own columns projected off each candidate's
    if data.measurement == "cable":
        lengths = data.y[idx, 0]
        if named:
            periods, scanned = np.array([named[0].detail["period"] / h for h in (2, 3)]), 2
        else:
            periods, scanned = drum_periods(data.y[:, 0])
        periods = np.round(periods, 1)  # as the candidate labels them
        phase = 2.0 * np.pi * lengths[:, None] / periods[None, :]
        W = np.stack([np.sin(phase), np.cos(phase)], axis=-1)  # (m, shapes, 2): a column pair per period
        gains = _gains(W, rows[:, 0, :], left[:, 0], inverse)
        best = int(np.argmax(gains)) if len(gains) else -1
        if best < 0 or not np.isfinite(gains[best]):
            return []
        chosen = sensor_periodic_candidate(data, periods[best])
    else:
        stations = [np.array(named[0].detail["station_xy"], dtype=float)] if named else list(np.round(tracker_stations(data.y[:, :3])))
        taken = {c.detail["harmonic"] for c in named}
        harmonics = [h for h in AZIMUTH_HARMONICS if h not in taken]
        scanned = len(stations) * len(harmonics)
        # The sideways unit times the reach, (−(y − s_y), x − s_x, 0), is linear in the station:
        # each station's products with the Jacobian and the residuals from three fixed ones.
        points = data.y[idx, :2]
        Jx, Jy = rows[:, 0, :], rows[:, 1, :]
        rx, ry = left[:, 0], left[:, 1]
        best, best_gain = None, -np.inf
        for station in stations:
            rel = points - station
            azimuth = np.arctan2(rel[:, 1], rel[:, 0])
            # J·(reach·sideways) per sample, and (reach·sideways)·residual, in mm per mrad
            moved = (Jy * rel[:, :1] - Jx * rel[:, 1:]) * 1e-3
            along = (ry * rel[:, 0] - rx * rel[:, 1]) * 1e-3
            W = np.stack([np.stack([np.sin(h * azimuth), np.cos(h * azimuth)], axis=-1) for h in harmonics], axis=1)  # (m, harmonics, 2)
            reach2 = np.sum(rel**2, axis=1) * 1e-6
            gains = _gains(W, moved, along, inverse, reach2)
            h = int(np.argmax(gains))
            if np.isfinite(gains[h]) and gains[h] > best_gain:
                best, best_gain = (station, harmonics[h]), gains[h]
        if best is None:
            return []
        chosen = tracker_azimuth_candidate(data, best[0], best[1])
    chosen.detail["scanned"] = scanned
    return [chosen]


def _gains(W: np.ndarray, JB: np.ndarray, rB: np.ndarray, inverse: np.ndarray, scale: Optional[np.ndarray] = None) -> np.ndarray:
    """The residual sum of squares each column pair removes, the model's columns refitted beside
    it: ``W`` (m, shapes, 2) the pairs' per-sample factors of a basis ``B`` (its rows per sample
    ``JB`` (m, p) as they meet the Jacobian, ``rB`` (m,) as they meet the residuals and
    ``scale`` (m,) their squared norm, default one). −inf where the pair is degenerate."""
    m, shapes = W.shape[:2]
    scale = np.ones(m) if scale is None else scale
    JC = (JB.T @ W.reshape(m, -1)).reshape(-1, shapes, 2)  # (p, shapes, 2): one product for every shape
    projected = (inverse @ JC.reshape(len(JC), -1)).reshape(JC.shape)
    CC = np.einsum("msc,msd->scd", W * scale[:, None, None], W, optimize=True) - np.einsum("psc,psd->scd", JC, projected, optimize=True)
    Cr = (rB @ W.reshape(m, -1)).reshape(shapes, 2)
    out = np.full(W.shape[1], -np.inf)
    for i in range(W.shape[1]):  # a 2x2 solve each
        values = np.linalg.eigvalsh(CC[i])
        if values[0] > 1e-9 * max(values[-1], 1e-300):  # else the model's columns take one of them whole
            out[i] = float(Cr[i] @ np.linalg.solve(CC[i], Cr[i]))
    return out
