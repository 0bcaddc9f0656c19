"""What an information matrix determines (:class:`_Uncertainty`): the covariance of the model's
entries, which are undetermined, the tool point's standard deviation over the workspace, the
error predicted on a new session and the figures the report states — all from one generalised
inverse (:func:`_inverse_half`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np
from scipy.linalg import solve_triangular

from ..causes.candidates import map_curve
from ..physics import DEG
from ..robot import Robot
from .criteria import RIDGE
from .design import _Design

#: A direction of the information matrix weaker than this (relative to its largest) is undetermined.
UNDETERMINED = 1e-13


@dataclass
class _Uncertainty:
    """What an information matrix determines: the covariance of the model's entries (physical
    units; the pseudo-inverse's), which entries are undetermined, the tool point's standard
    deviation (mm) at each workspace pose (NaN where undetermined) and ``log det`` with the ridge."""

    cov: np.ndarray
    loose: np.ndarray
    position: np.ndarray
    undetermined: int
    logdet: float
    prediction: Optional[float]

    @classmethod
    def of(cls, design: _Design, M: np.ndarray, sigma: float, W: np.ndarray) -> "_Uncertainty":
        """Also the error predicted on a new session over the workspace, ``σ·√tr(W M⁺)`` (mm;
        None where ``W`` needs a direction ``M`` leaves undetermined): one factorisation
        (:func:`_inverse_half`) serves every figure."""
        half, null = _inverse_half(M)
        cov = half @ half.T
        w, k, p = design.position.shape
        P = design.position.reshape(w * k, p)
        spread = np.sqrt(np.sum((P @ half) ** 2, axis=1).reshape(w, k).sum(axis=1)) * sigma  # products, not an einsum over p²: 1 000 entries take a second
        loose = np.linalg.norm(null, axis=1) > 1e-6
        unsure = np.linalg.norm((P @ null).reshape(w, -1), axis=1) > 1e-6 * np.linalg.norm(P.reshape(w, -1), axis=1)
        covariance = sigma**2 * cov / np.outer(design.scale, design.scale)  # back in the parameters' own units
        logdet = float(np.linalg.slogdet(M + RIDGE * np.eye(len(M)))[1])
        needs = null.size and np.linalg.norm(W @ null) > 1e-9 * max(np.linalg.norm(W), 1e-300)
        prediction = None if needs else float(sigma * math.sqrt(max(float(np.sum((W @ half) * half)), 0.0)))
        return cls(
            cov=covariance,
            loose=loose,
            position=np.where(unsure, np.nan, spread),
            undetermined=int(null.shape[1]),
            logdet=logdet,
            prediction=prediction,
        )

    def std(self, i) -> Optional[np.ndarray]:
        """Standard deviations of the entries ``i`` (mm, rad, ...), None if any is undetermined."""
        return None if np.any(self.loose[i]) else np.sqrt(np.maximum(np.diag(self.cov)[i], 0.0))

    def position_summary(self) -> dict:
        """RMS and largest standard deviation of the tool point over the workspace (mm, over the
        poses where it is determined: None if nowhere) and the share where it is not."""
        known = self.position[np.isfinite(self.position)]
        return {
            "rms_mm": float(np.sqrt(np.mean(known**2))) if known.size else None,
            "max_mm": float(known.max()) if known.size else None,
            "undetermined_share": float(np.mean(~np.isfinite(self.position))),
        }


def _inverse_half(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``H`` with ``G = H·Hᵀ`` a generalised inverse of ``M`` (``M G M = M``: every determined
    quantity's variance is the same with any; ``M⁻¹`` on the entries ``M`` holds something on,
    when those determine each other) and a basis (unit columns) of the directions ``M`` leaves
    undetermined: those weaker than :data:`UNDETERMINED` of the largest once ``M`` is scaled to a
    unit diagonal (a result's prior holds map coefficients ten decades better than a weakly seen
    length: unscaled, that length looked undetermined), and the entries ``M`` holds nothing on
    (zero rows: a new session's set-up before it is measured). By Cholesky (a tenth of an
    eigendecomposition's time) where no direction can be that weak (``λ_min/λ_max ≥ 1/(tr M⁻¹·tr
    M)``); else by eigenvalues."""
    p = len(M)
    live = np.flatnonzero(np.diag(M) > 0.0)
    root = np.sqrt(np.diag(M)[live])
    Ms = M[np.ix_(live, live)] / np.outer(root, root)
    half, null = np.zeros((p, live.size)), np.eye(p)[:, np.setdiff1d(np.arange(p), live)]
    try:
        if not live.size:
            return half, null
        inverse = solve_triangular(np.linalg.cholesky(Ms), np.eye(live.size), lower=True).T  # L⁻ᵀ
        if float(np.sum(inverse**2)) * float(np.trace(Ms)) > 1.0 / UNDETERMINED:
            raise np.linalg.LinAlgError("perhaps undetermined")
    except np.linalg.LinAlgError:
        values, V = np.linalg.eigh(Ms)
        keep = values > UNDETERMINED * max(float(values[-1]), 0.0)
        inverse = V[:, keep] / np.sqrt(values[keep])
        weak = np.zeros((p, int((~keep).sum())))
        weak[live] = V[:, ~keep] / root[:, None]
        null = np.hstack([null, weak / np.linalg.norm(weak, axis=0)])
        half = np.zeros((p, inverse.shape[1]))
    half[live] = inverse / root[:, None]
    return half, null


def _shown(std: Optional[np.ndarray], unit: str) -> Optional[float]:
    """One standard deviation as the report states it (deg for an angle), None if undetermined."""
    return None if std is None else float(std[0] / DEG if unit == "rad" else std[0])


def _cause_std(design: _Design, u: _Uncertainty, robot: Robot) -> list:
    """Per cause acting on the joints or the readings, its physical quantities' standard
    deviations (a joint map: its largest over the range), None where undetermined."""
    out = []
    for c, s in zip(design.causes, design.slices):
        if c.stage == "parameters":  # its parameters are among the parameters
            continue
        std = u.std(s)
        if std is None:
            out.append(None)
        elif c.kind == "joint_map":
            curve = map_curve(c.detail, np.zeros(c.size), u.cov[s, s])
            out.append({"largest": {"std": float(np.max(curve["std_deg"])), "unit": "deg"}})
        else:
            physical, _ = c.physical(np.zeros(c.size), std, robot, robot.params)
            out.append({name: {"std": q["std"], "unit": q["unit"]} for name, q in physical.items() if q.get("std") is not None})
    return out
