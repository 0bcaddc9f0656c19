"""The library of candidate causes: physical models of what a geometric calibration leaves out.

Every candidate is linear in its coefficients ``c`` and acts at one stage of the measurement:

``joints``
    the angle the link really takes, ``q_j + B(q, order)·c`` (compliance, periodic gear error,
    scale, coupling, backlash, a joint error map). Its Jacobian columns are ``∂h/∂q_j · B`` — and ``∂h/∂q_j`` is the
    ``theta_j`` column of the identification Jacobian, since ``theta_j`` adds to ``q_j``.
``observations``
    the reading, ``h + B·c`` (drift, temperature, a step of the sensor's zero, the sensor's own
    error: a cable drum's once-a-turn error, a tracker's azimuth encoder).
``parameters``
    parameters of the robot's own vector that the baseline leaves out (``cable_scale``, Hayati
    ``beta_j`` on a plain-DH baseline, base / tool / anchor terms).

The models are the simulator's (:mod:`robocal.effects`, on the shared :mod:`robocal.physics`), so a hidden effect is found as
the physical quantity it was simulated with. Bases are computed once on the whole dataset in
acquisition order (backlash needs each sample's predecessor) and sliced for the folds.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, replace
from typing import Optional

import numpy as np

from ..data.dataset import Dataset
from ..physics import DEG, approach_directions, gravity_base_columns, gravity_regressor, gravity_torques, mass_model, standard_poses
from ..kernels import as_float_array, cable_initial_guess, is_sparse
from ..exceptions import InvalidParameterError
from ..geometry import skew
from ..serial_robot import RESIDUAL_WIDTH, Robot
from ..stats import robust_sigma

#: Physically plausible ranges of the fitted quantities (a fit outside is rejected as implausible).
#: Compliance: joint stiffness above 1e3 N·m/rad; gear errors, backlash and misalignments below
#: 1 deg; scale and coupling below 1 %; drift below 10 mm/h; expansion coefficients
#: 0-100e-6/K (steel 12, aluminium 23, plastics up to ~100).
#: A sensor's own error: a cable sensor's periodic error below 1 mm (a 2 m drawstring sensor's
#: linearity is 0.05 % of its range), a tracker's angle encoder's below 1 mrad (200 arcsec).
LIMITS = {"compliance": 1e-3, "angle": 1.0 * DEG, "ratio": 1e-2, "drift_mm_per_h": 10.0, "alpha": 100e-6, "sensor_mm": 1.0, "sensor_rad": 1e-3}

#: Detail keys shown in a cause's label (the others — units, axes, a map's range and weight —
#: only describe it).
LABELLED = ("harmonic", "source", "target", "sample", "row", "frame", "spacing", "roughness", "trend", "degree", "settling", "masses", "period", "station")


def _order(data: Dataset) -> tuple[np.ndarray, str]:
    """Acquisition time in hours (``t`` if the data carry it, else the row order in 1000s of
    samples), centred, and its unit."""
    if data.t is not None:
        return (data.t - data.t.mean()) / 3600.0, "h"
    i = np.arange(len(data), dtype=np.float64)
    return (i - i.mean()) / 1000.0, "1000 samples"


@dataclass(eq=False)  # compared by identity: a candidate is one object of one library
class Candidate:
    """One candidate cause.

    Attributes
    ----------
    kind : str
        One of the names of the report (``joint_compliance``, ``joint_periodic``, ...).
    joint : int or None
        0-based joint it acts on.
    stage : {"joints", "observations", "parameters"}
    basis : ndarray
        ``joints``: (M, n_c) over the whole dataset; ``observations``: (M, k, n_c).
    params : list of str
        ``parameters``: the parameter names it frees.
    detail : dict
        Extra identification (``harmonic``, ``source`` joint, ``target``; ``unit`` and ``axes``
        of a drift, not shown in the label).
    signal : ndarray, optional
        A per-sample signal the columns are built from at fit time (the temperature rise of
        ``temperature`` on the links, whose columns depend on the current parameters).
    penalty : ndarray, optional
        Rows ``P`` (mm) added to the residuals as ``P·c``: the roughness penalty of a joint map.
    """

    kind: str
    joint: Optional[int]
    stage: str
    basis: Optional[np.ndarray] = None
    params: list = field(default_factory=list)
    detail: dict = field(default_factory=dict)
    signal: Optional[np.ndarray] = None
    penalty: Optional[np.ndarray] = None

    @property
    def label(self) -> str:
        where = f" joint {self.joint + 1}" if self.joint is not None else ""
        extra = "".join(f" {k}={v}" for k, v in self.detail.items() if k in LABELLED)
        return f"{self.kind}{where}{extra}"

    @property
    def size(self) -> int:
        if self.stage == "parameters":
            return len(self.params)
        return 1 if self.basis is None else self.basis.shape[-1]

    def physical(self, c: np.ndarray, std: Optional[np.ndarray], robot: Robot, nominal: np.ndarray) -> tuple[dict, Optional[str]]:
        """The fitted coefficients as physical quantities (``{name: {value, std, unit}}``), and
        the reason they are implausible (``None`` if they are not)."""
        s = np.full(len(c), np.nan) if std is None else np.asarray(std)

        def q(value, sd, unit):
            return {"value": float(value), "std": None if not np.isfinite(sd) else float(sd), "unit": unit}

        kind = self.kind
        if on_free_masses(self):
            return free_mass_compliance(robot, self.joint, c)
        if kind == "joint_compliance":
            out = {"compliance": q(c[0] / DEG * 1000.0, s[0] / DEG * 1000.0, "deg/(kN·m)")}
            if c[0] > 0:  # the joint's stiffness k = 1/c, its std by first-order propagation
                out["stiffness"] = q(1.0 / c[0], s[0] / c[0] ** 2, "N·m/rad")
            bad = not 0.0 < c[0] < LIMITS["compliance"]
            return out, (f"compliance {c[0]:.3g} rad/(N·m) is not within (0, {LIMITS['compliance']:g})" if bad else None)
        if kind == "joint_periodic":
            amp, phase = math.hypot(c[0], c[1]), math.atan2(c[1], c[0])
            sd = math.hypot(s[0], s[1]) / math.sqrt(2.0) if np.all(np.isfinite(s)) else np.nan
            out = {
                "amplitude": q(amp / DEG, sd / DEG, "deg"),
                "phase": q(phase / DEG, np.nan, "deg"),
                "harmonic": q(self.detail["harmonic"], np.nan, "cycles/rev"),
            }
            return out, (f"amplitude {amp / DEG:.3g} deg exceeds {LIMITS['angle'] / DEG:g} deg" if amp > LIMITS["angle"] else None)
        if kind == "joint_map":
            curve = map_curve(self.detail, c)
            peak = float(np.max(np.abs(curve["value_deg"])))
            rms = float(np.sqrt(np.mean(np.square(curve["value_deg"]))))
            out = {
                "peak": q(peak, np.nan, "deg"),
                "rms": q(rms, np.nan, "deg"),
                "spacing": q(self.detail["spacing"], np.nan, "deg"),
                "coefficients": q(len(c), np.nan, ""),
            }
            return out, (f"peak {peak:.3g} deg exceeds {LIMITS['angle'] / DEG:g} deg" if peak > LIMITS["angle"] / DEG else None)
        if kind in ("joint_scale", "joint_coupling"):
            name = "scale" if kind == "joint_scale" else "coefficient"
            out = {name: q(c[0], s[0], "1")}
            if kind == "joint_coupling":
                out["source"] = q(self.detail["source"], np.nan, "joint")
            return out, (f"{name} {c[0]:.3g} exceeds {LIMITS['ratio']:g}" if abs(c[0]) > LIMITS["ratio"] else None)
        if kind == "backlash":
            # Lost motion, Δq = −(b/2)·direction: b > 0 the link lags its reading (backlash),
            # b < 0 it leads (the encoder behind an elastic stage, a servo's following error,
            # preload). Both are named, with the sign; only the size is limited.
            width = -2.0 * c[0]
            # A prismatic joint's reading is mm: its lost motion too (a screw's), limited as a sensor's error.
            scale, unit, limit = (1.0, "mm", LIMITS["sensor_mm"]) if self.joint in robot.prismatic else (1.0 / DEG, "deg", LIMITS["angle"])
            out = {
                "width": q(width * scale, 2.0 * s[0] * scale, unit),
                "direction": q(1.0 if width > 0 else -1.0, np.nan, "(+1: the link lags its reading, -1: it leads)"),
            }
            bad = not abs(width) < limit
            return out, (f"width {width * scale:.3g} {unit} is not within ±{limit * scale:g} {unit}" if bad else None)
        if curved_drift(self):  # the change over the session and its mean rate
            offsets = self.basis @ c  # (m, k): the sensor's offset at every sample
            first, last = self.detail["first"], self.detail["last"]
            change = [float(offsets[last, a] - offsets[first, a]) for a in range(len(self.detail["axes"]))]
            rates = np.array(change) / max(self.detail["span"], 1e-12)
            out = {f"change_{a}": q(v, np.nan, "mm") for a, v in zip(self.detail["axes"], change)}
            out.update({f"mean_rate_{a}": q(v, np.nan, "mm/" + self.detail["unit"]) for a, v in zip(self.detail["axes"], rates)})
            fastest = float(np.max(np.abs(rates)))
            bad = self.detail["unit"] == "h" and fastest > LIMITS["drift_mm_per_h"]
            return out, (f"drift {fastest:.3g} mm/h exceeds {LIMITS['drift_mm_per_h']:g} mm/h" if bad else None)
        if kind == "drift":
            unit = "mm/" + self.detail["unit"]
            out = {f"rate_{a}": q(v, sd, unit) for a, v, sd in zip(self.detail["axes"], c, s)}
            fastest = float(np.max(np.abs(c)))
            bad = self.detail["unit"] == "h" and fastest > LIMITS["drift_mm_per_h"]
            return out, (f"drift {fastest:.3g} mm/h exceeds {LIMITS['drift_mm_per_h']:g} mm/h" if bad else None)
        if kind == "wander":
            path = self.basis @ c  # (M, k): the sensor's offset at every sample
            rms = float(np.sqrt(np.mean(np.sum(path**2, axis=1))))
            return {"rms": q(rms, np.nan, "mm"), "spacing": q(self.detail["spacing"], np.nan, "samples")}, None
        if kind == "step":
            out = {}
            for a, v, sd in zip(self.detail["axes"], c, s):
                if a in TURN_AXES:  # mrad -> deg
                    out[f"turn_{a[1]}"] = q(v / 1000.0 / DEG, sd / 1000.0 / DEG, "deg")
                else:  # the zero ("size"), a translation at the readings' centroid, an anchor's move
                    out["size" if a == "L" else a if a.startswith("anchor") else f"size_{a}"] = q(v, sd, "mm")
            out["sample"] = q(self.detail["sample"], np.nan, "")
            out["row"] = q(self.detail["row"], np.nan, "")
            return out, None
        if kind in SENSOR_KINDS:  # a sine and a cosine: the amplitude, its phase
            amp, phase = math.hypot(c[0], c[1]), math.atan2(c[1], c[0])
            sd = math.hypot(s[0], s[1]) / math.sqrt(2.0) if np.all(np.isfinite(s)) else np.nan
            if kind == "sensor_periodic":
                out = {"amplitude": q(amp, sd, "mm"), "phase": q(phase / DEG, np.nan, "deg"), "period": q(self.detail["period"], np.nan, "mm")}
                return out, (f"amplitude {amp:.3g} mm exceeds {LIMITS['sensor_mm']:g} mm" if amp > LIMITS["sensor_mm"] else None)
            arcsec = 1e-3 / DEG * 3600.0  # the coefficients are mrad
            out = {
                "amplitude": q(amp * arcsec, sd * arcsec, "arcsec"),
                "phase": q(phase / DEG, np.nan, "deg"),
                "harmonic": q(self.detail["harmonic"], np.nan, "cycles/rev"),
                "station_x": q(self.detail["station_xy"][0], np.nan, "mm"),
                "station_y": q(self.detail["station_xy"][1], np.nan, "mm"),
            }
            bad = amp * 1e-3 > LIMITS["sensor_rad"]
            return out, (f"amplitude {amp * arcsec:.3g} arcsec exceeds {LIMITS['sensor_rad'] / DEG * 3600:.3g} arcsec" if bad else None)
        if kind == "temperature":
            out = {"alpha": q(c[0] * 1e6, s[0] * 1e6, "1e-6/K"), "target": q(np.nan, np.nan, self.detail["target"])}
            bad = not 0.0 < c[0] < LIMITS["alpha"]
            return out, (f"expansion coefficient {c[0] * 1e6:.3g}e-6/K is not within (0, {LIMITS['alpha'] * 1e6:g})" if bad else None)
        # parameters: deviations from nominal
        out, why = {}, None
        for name, v, sd in zip(self.params, c, s):
            k = robot.index(name)
            unit = robot.param_units[k]
            dev = v - nominal[k]
            if unit == "rad":
                out[name] = q(dev / DEG, sd / DEG, "deg")
                if kind == "axis_misalignment" and abs(dev) > LIMITS["angle"]:
                    why = f"{name} {dev / DEG:.3g} deg exceeds {LIMITS['angle'] / DEG:g} deg"
            else:
                out[name] = q(dev, sd, unit)
                if kind == "cable_scale" and abs(dev) > LIMITS["ratio"]:
                    why = f"scale error {dev:.3g} exceeds {LIMITS['ratio']:g}"
        return out, why


def free_mass_compliance(robot: Robot, joint: int, c: np.ndarray, cov: Optional[np.ndarray] = None) -> tuple[dict, Optional[str]]:
    """A compliance fitted on the static gravity regressor (``masses=free``: the deflection
    ``Δq = Y·c`` for any masses, ``c`` the compliance times the base parameters of the links'
    masses and first moments) as physical quantities, on :func:`~robocal.physics.standard_poses`:
    the compliance that the mass model's torque gives the deflection (least squares), the share
    of the deflection that torque explains, and the base parameters (kg, kg·m) the deflection
    implies at that compliance. With the coefficients' covariance ``cov``, the compliance, the
    stiffness and the base parameters carry their standard deviations (first order: the
    compliance is linear in ``c``, the rest its ratios). Implausible as any compliance is, and
    where the mass model's torque explains less than :data:`MIN_MODEL_TORQUE_SHARE` of it."""
    poses = standard_poses(robot)
    Y = joint_basis(robot, poses, "joint_compliance", joint, {"masses": "free"})
    deflection = Y @ c
    torque = gravity_torques(robot, poses)[:, joint]
    along = Y.T @ torque / max(float(torque @ torque), 1e-300)  # the compliance is along · c
    compliance = float(along @ c)
    left = deflection - compliance * torque
    share = 1.0 - float(left @ left) / max(float(deflection @ deflection), 1e-300)
    sd = None if cov is None else math.sqrt(max(float(along @ cov @ along), 0.0))
    out = {
        "compliance": {"value": compliance / DEG * 1000.0, "std": None if sd is None else sd / DEG * 1000.0, "unit": "deg/(kN·m)"},
        "model_torque_share": {"value": share, "std": None, "unit": "1"},
        "deflection_rms": {"value": float(np.sqrt(np.mean(deflection**2))) / DEG, "std": None, "unit": "deg"},
    }
    if compliance > 0:
        out["stiffness"] = {"value": 1.0 / compliance, "std": None if sd is None else sd / compliance**2, "unit": "N·m/rad"}
        base = c / compliance
        spread = None
        if cov is not None:  # d(c/κ)/dc = I/κ − c·alongᵀ/κ²
            D = np.eye(len(c)) / compliance - np.outer(c, along) / compliance**2
            spread = np.sqrt(np.maximum(np.diag(D @ cov @ D.T), 0.0))
        for i, (k, value) in enumerate(zip(gravity_base_columns(robot, joint), base)):  # base parameters: combinations of the links'
            link, part = joint + 1 + k // 4, ("m", "mx", "my", "mz")[k % 4]
            out[f"{part}{link}"] = {"value": float(value), "std": None if spread is None else float(spread[i]), "unit": "kg" if part == "m" else "kg·m"}
    if not 0.0 < compliance < LIMITS["compliance"]:
        return out, f"compliance {compliance:.3g} rad/(N·m) is not within (0, {LIMITS['compliance']:g})"
    if share < MIN_MODEL_TORQUE_SHARE:
        return out, f"the mass model's torque explains {share:.2f} of the deflection, below {MIN_MODEL_TORQUE_SHARE:g}: not these links' weight"
    return out, None


#: A compliance on free masses refines the mass model's: that model's torque must explain at
#: least this share of the fitted deflection. Masses elsewhere and a payload (the mismatch
#: section: ±30 % in mass, centres anywhere along the link and 60 mm off it) left it 0.93-0.99;
#: where it was lower the free masses followed another cause — a harmonic of the same joint
#: (0.49), the joint maps of UR10 series C (0.61, whose compliance then turned negative). The
#: bar sits between those two groups of cases, which it was chosen on.
MIN_MODEL_TORQUE_SHARE = 0.8


def on_free_masses(c: Candidate) -> bool:
    """Whether ``c`` is a gravity compliance on free masses (:func:`free_mass_candidate`)."""
    return c.kind == "joint_compliance" and c.detail.get("masses") == "free"


def free_mass_candidate(robot: Robot, data: Dataset, joint: int) -> Candidate:
    """The gravity compliance of ``joint`` (0-based) for any masses and payload it carries: its
    deflection on the static gravity regressor's base parameters (``masses=free``)."""
    detail = {"masses": "free"}
    return Candidate("joint_compliance", joint, "joints", joint_basis(robot, data.q, "joint_compliance", joint, detail), detail=detail)


def compliance_candidate(robot: Robot, data: Dataset, joint: int) -> Candidate:
    """The gravity compliance of ``joint`` (0-based) on the mass model's torque (one coefficient)."""
    return Candidate("joint_compliance", joint, "joints", joint_basis(robot, data.q, "joint_compliance", joint, {}), detail={})


def has_mass_model(robot: Robot) -> bool:
    """Gravity torques are available (a mass model and a revolute standard-DH chain)."""
    return mass_model(robot) is not None and all(j.convention == "dh" and j.kind == "revolute" for j in robot.joints)


def joint_basis(robot: Robot, q: np.ndarray, kind: str, joint: int, detail: dict, tau: Optional[np.ndarray] = None) -> np.ndarray:
    """The basis ``B`` (m, n_c) of a joint cause at joint angles ``q`` (m, N), rows in
    acquisition order (backlash needs it): ``Δq_joint = B·c``."""
    qj = q[:, joint]
    if kind == "joint_compliance" and detail.get("masses") == "free":  # any masses: the static gravity regressor
        return gravity_regressor(robot, q, joint)[:, gravity_base_columns(robot, joint)]
    if kind == "joint_compliance":
        torques = gravity_torques(robot, q) if tau is None else tau
        return torques[:, joint : joint + 1].copy()
    if kind == "joint_periodic":
        h = detail["harmonic"]
        return np.column_stack([np.sin(h * qj), np.cos(h * qj)])
    if kind == "joint_scale":
        return qj[:, None].copy()
    if kind == "joint_coupling":
        return q[:, detail["source"] - 1 : detail["source"]].copy()
    if kind == "backlash":
        return approach_directions(qj)[:, None]
    if kind == "joint_map":
        return map_basis(qj, detail)
    raise InvalidParameterError(f"{kind!r} is not a joint cause")


# -- joint error maps -------------------------------------------------------------------------
#: Knot spacings (deg) and roughness scales (deg, the prior width of a second difference of the
#: map's spline coefficients) a joint map is tried with; grouped cross-validation chooses.
MAP_SPACINGS_DEG = (2.0, 5.0, 15.0)
MAP_ROUGHNESS_DEG = (1e-3, 3e-3, 1e-2, 3e-2, 1e-1)
#: Cubic B-splines.
MAP_DEGREE = 3


def _map_knots(detail: dict) -> np.ndarray:
    """Uniform knots of ``spacing`` from ``lo`` past ``hi`` (deg → rad), with the ``MAP_DEGREE``
    extra knots each side a B-spline basis needs."""
    lo, hi, h = (float(detail[k]) * DEG for k in ("lo", "hi", "spacing"))
    spans = max(1, int(math.ceil((hi - lo) / h - 1e-9)))
    return lo + h * np.arange(-MAP_DEGREE, spans + MAP_DEGREE + 1)


def map_constraint(detail: dict) -> np.ndarray:
    """``Z`` (n, n−2): spline coefficients ``Z·c`` with no constant and no linear part.

    A cubic spline is constant or linear in the angle exactly when its coefficients are
    ``a + b·ξ`` (``ξ`` the Greville abscissae of the knots), so ``Z`` spans the coefficients
    orthogonal to ``1`` and ``ξ`` (the first and last solved from the others). A constant map is the
    joint's ``theta`` offset and a linear one its scale error (``joint_scale``), which the
    geometry and the named causes fit; both are also the null space of the roughness penalty,
    so without them every part of a map is penalised and the geometry takes precedence. (Maps
    that kept their linear part traded it with the geometry and did not carry to other sessions:
    docs/findings.md, D3.)"""
    t = _map_knots(detail)
    n = len(t) - MAP_DEGREE - 1
    xi = np.array([t[i + 1 : i + 1 + MAP_DEGREE].mean() for i in range(n)])
    A = np.column_stack([np.ones(n), xi - xi.mean()])
    # The first and the last coefficient are solved from the others (ξ at the two ends keeps the
    # 2×2 system well conditioned; the last two alone made Z's entries grow as 1/spacing).
    ends, inner = [0, n - 1], np.arange(1, n - 1)
    Z = np.zeros((n, n - 2))
    Z[inner, np.arange(n - 2)] = 1.0
    Z[ends] = -np.linalg.solve(A[ends].T, A[inner].T)  # A_endsᵀ·c_ends = −A_innerᵀ·c_inner
    return Z


def map_basis(qj: np.ndarray, detail: dict) -> np.ndarray:
    """``B·Z`` (m, n−1, scipy.sparse) of a joint map at angles ``qj`` (rad): cubic B-splines on
    :func:`_map_knots`, constrained by :func:`map_constraint`. Where the map does not cover the
    angle (:func:`map_coverage`: beyond its range ``[lo, hi]`` or in a gap of its data) a row is
    the row of the nearest angle it covers, fading out with the distance (:func:`map_reach`):
    the data say nothing of the error far from them, and the geometry's ``theta`` (fitted with
    the map's mean) is the best guess there. Holding the end value instead carries the map's
    error to angles the calibration never saw, and bridging a gap (the roughness penalty draws a
    straight line across it) to angles between those it saw (both measured across the UR10
    series: docs/findings.md, D3)."""
    from scipy import sparse
    from scipy.interpolate import BSpline  # imported on use: only maps need it

    t = _map_knots(detail)
    nearest, fade = map_reach(qj, detail)
    B = sparse.csr_array(BSpline.design_matrix(nearest, t, MAP_DEGREE, extrapolate=True))
    return (sparse.diags_array(fade) @ B @ sparse.csr_array(map_constraint(detail))).tocsr().sorted_indices()  # each row's columns ascending


#: Knot spacings over which a map's correction fades beyond its data: about the correlation
#: length of the maps found (their autocorrelation falls to 1/e at 1.9–2.4 spacings on UR10
#: series A or B alone, 2° knots). Fading from the edge value, the best linear guess of an error
#: so correlated, lowered the held-out error of every UR10 series left out of a fit on the other
#: two (pose: C 0.428 → 0.417, B 0.250 → 0.225, A 0.218 → 0.203 mm; positions: 0.442 → 0.439,
#: 0.252 → 0.228, 0.218 → 0.201; 1 to 2.5 spacings alike), where a map that stopped at its data
#: gave up what its edge value says of the angles next to them.
MAP_REACH_SPACINGS = 2.0


def map_reach(qj: np.ndarray, detail: dict) -> tuple[np.ndarray, np.ndarray]:
    """For joint angles ``qj`` (m,) (rad): the nearest angle the map of ``detail`` covers (rad) and
    the factor ``exp(−distance / reach)`` by which its correction there carries (1 where the map
    covers ``qj``; ``reach`` :data:`MAP_REACH_SPACINGS` knot spacings)."""
    qj = np.asarray(qj, dtype=np.float64)
    nearest = np.clip(qj, float(detail["lo"]) * DEG, float(detail["hi"]) * DEG)
    for a, b in detail.get("gaps", ()):
        a, b = float(a) * DEG, float(b) * DEG
        within = (nearest > a) & (nearest < b)
        nearest[within] = np.where(nearest[within] - a <= b - nearest[within], a, b)
    reach = MAP_REACH_SPACINGS * float(detail["spacing"]) * DEG
    return nearest, np.exp(-np.abs(qj - nearest) / reach)


def map_penalty(detail: dict, weight: float) -> np.ndarray:
    """Roughness rows ``weight·D₂·Z`` of a map: the second differences of its spline
    coefficients, ``weight`` (mm/rad) the noise over the roughness scale."""
    n = len(_map_knots(detail)) - MAP_DEGREE - 1
    D2 = np.diff(np.eye(n), n=2, axis=0)
    return weight * D2 @ map_constraint(detail)


def map_curve(detail: dict, c: np.ndarray, cov: Optional[np.ndarray] = None, points: int = 0) -> dict:
    """The map as a table: angles (deg) over its range but for the gaps of its data, the
    correction (deg) and, given the coefficients' covariance ``cov``, its standard deviation
    (deg)."""
    lo, hi = float(detail["lo"]), float(detail["hi"])
    n = points or max(2, int(round((hi - lo) / (float(detail["spacing"]) / 4.0))) + 1)
    angles = np.linspace(lo, hi, n)
    angles = angles[map_coverage(angles * DEG, detail)]
    B = map_basis(angles * DEG, detail).toarray()
    out = {"angle_deg": angles, "value_deg": B @ np.asarray(c) / DEG}
    if cov is not None:
        out["std_deg"] = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", B, cov, B), 0.0)) / DEG
    return out


def map_coverage(qj: np.ndarray, detail: dict) -> np.ndarray:
    """True where an angle lies within the range the map was fitted on and outside the gaps of
    its data (``detail["gaps"]``, deg; none in maps saved before gaps were kept)."""
    qj = np.asarray(qj, dtype=np.float64)
    inside = (qj >= float(detail["lo"]) * DEG - 1e-9) & (qj <= float(detail["hi"]) * DEG + 1e-9)
    for a, b in detail.get("gaps", ()):
        inside &= ~((qj > float(a) * DEG) & (qj < float(b) * DEG))
    return inside


#: A stretch of a joint's range longer than this many knot spacings without a sample is a gap of
#: the map's data: the roughness penalty alone would draw the map across it.
MAP_GAP_SPACINGS = 2.0


def map_support(angles: np.ndarray, spacing: float) -> dict:
    """The range a map with knots every ``spacing`` deg fitted on joint ``angles`` (rad) covers:
    ``lo`` and ``hi`` (deg, rounded outwards) and ``gaps``, the ``[a, b]`` (deg, rounded
    inwards) between consecutive angles more than :data:`MAP_GAP_SPACINGS` spacings apart."""
    a = np.sort(np.asarray(angles, dtype=np.float64)) / DEG
    wide = np.flatnonzero(np.diff(a) > MAP_GAP_SPACINGS * float(spacing))
    down, up = (lambda v: math.floor(v * 1e6) / 1e6), (lambda v: math.ceil(v * 1e6) / 1e6)  # to a micro-degree, outwards
    return {"lo": down(a[0]), "hi": up(a[-1]), "gaps": [[up(a[i]), down(a[i + 1])] for i in wide]}


def covered_when_fitted_on(detail: dict, fitted: np.ndarray, qj: np.ndarray) -> np.ndarray:
    """:func:`map_coverage` of the angles ``qj`` (rad) by the map of ``detail`` fitted on the
    joint angles ``fitted`` (rad) instead: a fold's map is the map of its training samples."""
    return map_coverage(qj, {**detail, **map_support(fitted, detail["spacing"])})


def map_within(c: Candidate, data: Dataset, angles: np.ndarray) -> Candidate:
    """The joint map ``c`` (its knots and coefficients unchanged) correcting only where the joint
    ``angles`` (rad) it is fitted on support it (:func:`covered_when_fitted_on`): held-out samples
    beyond them get nothing from it, where a new session's get its fading edge value
    (:func:`map_reach`) — the folds do not credit a map with what it does beyond its data."""
    from scipy import sparse

    inside = sparse.diags_array(covered_when_fitted_on(c.detail, angles, data.q[:, c.joint]).astype(np.float64))
    return replace(c, basis=(inside @ c.basis).tocsr())


def map_coverage_mask(maps: list[tuple], q: np.ndarray) -> np.ndarray:
    """True for the samples of joint angles ``q`` (m, N, rad) that every joint map of ``maps``
    — ``(joint, detail)`` pairs, 0-based joint — covers (all of them when there is none)."""
    inside = np.ones(len(q), dtype=bool)
    for joint, detail in maps:
        inside &= map_coverage(q[:, joint], detail)
    return inside


def result_maps(causes: list[dict]) -> list[tuple]:
    """The joint maps among a result file's ``causes`` as :func:`map_coverage_mask` takes them."""
    return [(c["joint"] - 1, c["detail"]) for c in causes if c.get("kind") == "joint_map"]


def map_coverage_report(causes: list[dict], q: np.ndarray, rows: Optional[np.ndarray] = None) -> list[dict]:
    """For each joint map among a result file's ``causes``: how many of the joint angles ``q``
    (m, N, rad) it does not cover — beyond the range it was fitted on or in a gap of its data,
    where its correction only fades out from its edge value (:func:`map_reach`) —, and the first
    rows (``rows``, default 0-based sample indices) that it does not."""
    out = []
    for cause in causes:
        if cause.get("kind") != "joint_map":
            continue
        j, detail = cause["joint"] - 1, cause["detail"]
        outside = np.flatnonzero(~map_coverage(q[:, j], detail))
        where = outside if rows is None else np.asarray(rows)[outside]
        span = {"range_deg": [detail["lo"], detail["hi"]], "gaps_deg": detail.get("gaps", [])}
        out.append({"label": cause.get("label", cause["kind"]), "joint": j + 1, **span, "outside": int(len(outside)), "rows": [int(v) for v in where[:20]]})
    return out


def uncovered_words(entry: dict) -> str:
    """Where a :func:`map_coverage_report` entry's map has no data, in words."""
    lo, hi = entry["range_deg"]
    gaps = ", ".join(f"{a:g}..{b:g}" for a, b in entry.get("gaps_deg", []))
    return f"beyond the range {lo:g}..{hi:g} deg" + (f" or in the gaps {gaps} deg of its data" if gaps else "")


def map_noise(residuals: np.ndarray) -> float:
    """Robust scale (mm) of one component of a fit's residuals (m, k): what weighs a map's roughness."""
    return float(np.sqrt(np.mean(robust_sigma(np.asarray(residuals)) ** 2)))


def map_candidate(data: Dataset, joint: int, spacing: float, roughness: float, noise: float, angles: np.ndarray, basis=None) -> Candidate:
    """The joint map of ``joint`` (0-based) with knots every ``spacing`` deg and second
    differences of prior width ``roughness`` deg, over the joint ``angles`` (rad) it is fitted
    on (:func:`map_support`), weighed against residuals of scale ``noise`` mm. ``basis``: the
    same map's basis at another roughness (shared: the screening computes its products once)."""
    detail = {"spacing": float(spacing), "roughness": float(roughness), **map_support(angles, spacing)}
    detail["weight"] = noise / (roughness * DEG)
    basis = map_basis(data.q[:, joint], detail) if basis is None else basis
    return Candidate("joint_map", joint, "joints", basis, detail=detail, penalty=map_penalty(detail, detail["weight"]))


def fitted_map(data: Dataset, joint: int, detail: dict, noise: float) -> Candidate:
    """The joint map of ``joint`` (0-based) fitted before (a result's ``detail``: its knots over
    the range ``lo..hi`` and the gaps of its data, as the result holds them) on ``data``, its
    roughness weighed against ``noise`` mm: the same coefficients as the result's map, whatever
    angles ``data`` reach (beyond its range a row fades out, :func:`map_reach`)."""
    detail = {**detail, "weight": noise / (float(detail["roughness"]) * DEG)}
    return Candidate("joint_map", joint, "joints", map_basis(data.q[:, joint], detail), detail=detail, penalty=map_penalty(detail, detail["weight"]))


#: A joint map's label, as :attr:`Candidate.label` writes it.
MAP_LABEL = re.compile(r"joint_map joint (\d+) spacing=([0-9.]+) roughness=([0-9.eE+-]+)")


#: Harmonics the library offers one at a time; higher ones (a reducer's gear mesh) are found
#: where several of these fit together (:func:`~robocal.diagnosis.maps.merge_harmonics`).
LIBRARY_HARMONICS = (1, 2, 3)
#: The highest harmonic tried in the place of several.
MAX_HARMONIC = 8


#: A curved drift: powers of acquisition time up to this degree (a warm-up, a settling stand).
CURVED_DRIFT_DEGREE = 3
#: ... or a line and an exponential settling of these time constants (fractions of the session).
SETTLING_TIMES = (0.02, 0.05, 0.15)


def natural_spline(t: np.ndarray, knots: int) -> np.ndarray:
    """The natural cubic spline basis of ``t`` (m, knots − 1) without its constant, knots at
    equal steps over ``t``'s range (Hastie, Tibshirani & Friedman, eq. 5.4-5.5): ``t`` itself,
    then terms straight beyond the end knots, so that a fit without the first or last stretch
    of the session continues it by a line, not by a cubic's swing."""
    xi = np.linspace(t.min(), t.max(), knots)
    span = max(xi[-1] - xi[0], 1e-12)
    s = (t - xi[0]) / span  # on [0, 1]: cubes of hours stay O(1)
    xi = (xi - xi[0]) / span

    def d(k):
        return (np.maximum(s - xi[k], 0.0) ** 3 - np.maximum(s - xi[-1], 0.0) ** 3) / (xi[-1] - xi[k])

    columns = [t] + [d(k) - d(knots - 2) for k in range(knots - 2)]
    return np.column_stack([c - (c.mean() if i else 0.0) for i, c in enumerate(columns)])


def curved_drift(c: Candidate) -> bool:
    """Whether ``c`` is a drift that is not linear (:func:`drift_candidate`)."""
    return c.kind == "drift" and (c.detail.get("degree", 1) > 1 or "settling" in c.detail)


def drift_candidate(data: Dataset, degree: int = 1, settling: Optional[float] = None) -> Candidate:
    """The sensor's offset drifting with acquisition time, per axis: linear (``degree`` 1, its
    coefficient the rate), or a natural cubic spline of time with ``degree`` coefficients (its
    constant is the set-up's), or — with ``settling`` — a line plus an exponential settling
    ``exp(−(t − t₀)/τ)`` of time constant ``τ = settling`` × the session's span (a warm-up that
    is fast at first). :meth:`Candidate.physical` turns a curved one's coefficients into the
    change over the session."""
    order, unit = _order(data)
    axes = ["L"] if data.measurement == "cable" else ["x", "y", "z"]
    span = float(np.ptp(order))
    if settling is not None:
        fall = np.exp(-(order - order.min()) / max(settling * span, 1e-12))
        powers = np.column_stack([order, fall - fall.mean()])
    else:
        powers = order[:, None] if degree == 1 else natural_spline(order, degree + 1)
    n = powers.shape[1]
    drift = np.zeros((len(data), RESIDUAL_WIDTH[data.measurement], len(axes) * n))
    for a in range(len(axes)):
        drift[:, a, a * n : (a + 1) * n] = powers
    ends = {"span": span, "first": int(np.argmin(order)), "last": int(np.argmax(order))}
    shape = {"settling": settling} if settling is not None else {"degree": degree} if degree > 1 else None
    detail = {"unit": unit, "axes": axes, **({**shape, **ends} if shape else {})}
    return Candidate("drift", None, "observations", drift, detail=detail)


#: The sensor's own errors (:func:`sensor_periodic_candidate`, :func:`tracker_azimuth_candidate`):
#: of the instrument, not of the robot, fitted per session.
SENSOR_KINDS = ("sensor_periodic", "tracker_azimuth")


def sensor_periodic_candidate(data: Dataset, period: float) -> Candidate:
    """A cable sensor's own error, periodic in the length it reads: ``a·sin(2πL/P) + b·cos(2πL/P)``
    (mm) of period ``P = period`` (mm) — a drawstring sensor's drum, whose error repeats once a
    turn of the drum whatever the robot does."""
    period = round(float(period), 1)  # as labelled: a basis rebuilt from the label is this one
    phase = 2.0 * np.pi * data.y[:, 0] / period
    basis = np.stack([np.sin(phase), np.cos(phase)], axis=-1)[:, None, :]
    return Candidate("sensor_periodic", None, "observations", basis, detail={"period": period})


def tracker_azimuth_candidate(data: Dataset, station: np.ndarray, harmonic: int) -> Candidate:
    """A laser tracker's azimuth encoder error about a standing axis through ``station`` (x, y in
    the readings' frame, mm; the frame's z standing, as a levelled tracker's): the azimuth ``φ``
    of each reading off by ``a·sin(hφ) + b·cos(hφ)`` (mrad: a coefficient's plausible limit is
    one, as :meth:`~robocal.calibration.result.CalibrationResult.undetermined` scales them), which moves the reading sideways
    by that angle times its horizontal distance from the station. A pose's orientation rows are
    the probe's own (no columns)."""
    station = np.round(np.asarray(station, dtype=np.float64))  # as labelled (mm): a basis rebuilt from the label is this one
    rel = data.y[:, :2] - station
    azimuth, reach = np.arctan2(rel[:, 1], rel[:, 0]), np.hypot(rel[:, 0], rel[:, 1])
    sideways = np.column_stack([-np.sin(azimuth), np.cos(azimuth), np.zeros(len(data))]) * (reach * 1e-3)[:, None]  # mm per mrad
    basis = np.zeros((len(data), RESIDUAL_WIDTH[data.measurement], 2))
    basis[:, :3, 0] = sideways * np.sin(harmonic * azimuth)[:, None]
    basis[:, :3, 1] = sideways * np.cos(harmonic * azimuth)[:, None]
    x, y = (int(v) for v in station)
    return Candidate("tracker_azimuth", None, "observations", basis, detail={"harmonic": harmonic, "station": f"{x},{y}", "station_xy": (x, y)})


def periodic_candidate(robot: Robot, data: Dataset, joint: int, harmonic: int) -> Candidate:
    """Joint ``joint``'s error ``a·sin(h·q) + b·cos(h·q)`` of harmonic ``h``, over every sample of ``data``."""
    detail = {"harmonic": harmonic}
    return Candidate("joint_periodic", joint, "joints", joint_basis(robot, data.q, "joint_periodic", joint, detail), detail=detail)


def map_candidates(robot: Robot, data: Dataset, joints: list[int], noise: float, idx: Optional[np.ndarray] = None) -> list[Candidate]:
    """Joint maps of every spacing and roughness in :data:`MAP_SPACINGS_DEG` ×
    :data:`MAP_ROUGHNESS_DEG` for the revolute ``joints``, each over the joint's range in the
    samples ``idx`` of ``data`` (default all)."""
    q = data.q if idx is None else data.q[idx]
    out = []
    for j in joints:
        if robot.joints[j].kind != "revolute":
            continue
        spacings = [spacing for spacing in MAP_SPACINGS_DEG if np.ptp(q[:, j]) / DEG >= 2.0 * spacing]  # two spacings at least across its range
        for spacing in spacings:
            first = map_candidate(data, j, spacing, MAP_ROUGHNESS_DEG[0], noise, q[:, j])
            out += [first] + [map_candidate(data, j, spacing, roughness, noise, q[:, j], first.basis) for roughness in MAP_ROUGHNESS_DEG[1:]]
    return out


def library(robot: Robot, data: Dataset, considered: list[str], hayati: bool = True) -> list[Candidate]:
    """Every candidate that applies to ``robot`` and ``data`` (see the module notes).

    Joints that do not move in the data get no joint candidates (their effect would be a
    constant the geometry absorbs); compliance needs a mass model and a joint whose gravity
    torque varies; temperature needs ``data.temp``. Parameter candidates are the parameters the
    baseline did not consider at all (``considered``: estimated or fixed by the identifiability
    analysis).
    """
    n = robot.n_joints
    q = data.q
    moving = [j for j in range(n) if np.ptp(q[:, j]) > 1e-6]
    out: list[Candidate] = []
    tau = gravity_torques(robot, q) if has_mass_model(robot) else None

    def joint_candidate(kind, j, **detail):
        return Candidate(kind, j, "joints", joint_basis(robot, q, kind, j, detail, tau), detail=detail)

    for j in moving:
        if tau is not None and np.ptp(tau[:, j]) > 1e-3 * max(1.0, np.max(np.abs(tau))):
            out.append(joint_candidate("joint_compliance", j))
        if j not in robot.prismatic:  # harmonics of a turn: a prismatic joint's mm make no turn
            out += [periodic_candidate(robot, data, j, h) for h in LIBRARY_HARMONICS]
        out.append(joint_candidate("joint_scale", j))
        # A reading coupled to another of its unit: the simulator's and the report's coefficient is a ratio.
        out += [joint_candidate("joint_coupling", j, source=s + 1) for s in moving if s != j and (s in robot.prismatic) == (j in robot.prismatic)]
        out.append(joint_candidate("backlash", j))
    out.append(drift_candidate(data))
    if data.temp is not None and np.ptp(data.temp) > 0:
        dT = data.temp - data.temp[0]
        out.append(Candidate("temperature", None, "observations", None, detail={"target": "links"}, signal=dT))
        if data.measurement == "cable":
            out.append(Candidate("temperature", None, "observations", (data.y[:, 0] * dT)[:, None, None], detail={"target": "cable"}))
    free = set(considered)
    if data.measurement == "cable" and "cable_scale" not in free:
        out.append(Candidate("cable_scale", None, "parameters", params=["cable_scale"]))
    if not hayati:
        for j, joint in enumerate(robot.joints):
            if joint.hayati and f"beta{j + 1}" not in free:
                out.append(Candidate("axis_misalignment", j, "parameters", params=[f"beta{j + 1}"]))
    axes = ("x", "y", "z", "rx", "ry", "rz")
    frame = {
        "cable": ["anchor_x", "anchor_y", "anchor_z", "tool_x", "tool_y", "tool_z"],
        "position": [f"base_{c}" for c in axes] + ["tool_x", "tool_y", "tool_z"],
        "pose": [f"{f}_{c}" for f in ("base", "tool") for c in axes],
    }[data.measurement]
    missing = [p for p in frame if p not in free]
    if missing:
        out.append(Candidate("frame", None, "parameters", params=missing))
    return out


#: The axes of a step that turn the sensor's frame (its coefficients in mrad).
TURN_AXES = ("rx", "ry", "rz")
#: The axes of a step that shift its readings alike at every sample after it (mm).
SHIFT_AXES = ("L", "x", "y", "z")


def step_candidate(data: Dataset, sample: int, rigid: bool = False, directions: Optional[np.ndarray] = None) -> Candidate:
    """A step of the sensor's set-up at ``sample`` (0-based index of the first sample after
    it): every sample acquired from then on is read by a sensor placed otherwise.

    A shift (``rigid`` False): the readings jump alike — a cable sensor re-zeroed (``L``, mm), a
    tracker's frame moved without turning (``x, y, z``, mm). A sensor is a rigid body, though,
    and a knock moves it as one (``rigid``, labelled ``frame=rigid``): a tracker's frame moves
    *and turns* (``x, y, z`` its translation at the centroid of the readings after the step, mm;
    ``rx, ry, rz`` its rotation, mrad — a frame turned by ω reads ``ω × y`` more at a point
    ``y``, and a pose's orientation ``ω`` more); a cable sensor's zero jumps and its anchor moves
    (``anchor_u``, ``anchor_v``: across the mean direction of the cable after the step, mm; along
    it the anchor's move is the zero's). Only those directions the readings determine are
    columns: the rotation where the points after the step spread, the anchor where the cable's
    ``directions`` are given (:func:`cable_directions`, once for all of a round's steps). Both are offered; the
    selection takes the shift where the turn gains nothing (:func:`~robocal.diagnosis.select.simplest_first`)."""
    m, k = len(data), RESIDUAL_WIDTH[data.measurement]
    if not 0 < sample < m:
        raise InvalidParameterError(f"a step needs its first sample within 1..{m - 1}; got {sample}")
    position = acquisition_position(data)
    after = position >= position[sample]
    if data.measurement == "cable":
        axes, columns = ["L"], [np.ones((m, 1, 1))]
        u = directions if rigid else None
        if u is not None:
            mean = u[after].mean(axis=0)
            across = np.linalg.svd(np.eye(3) - np.outer(mean, mean) / (mean @ mean))[0][:, :2]  # two unit vectors ⟂ the mean direction
            axes += ["anchor_u", "anchor_v"]
            columns.append(-(u @ across)[:, None, :])  # L = |p − a| + c: moving a by δa reads −u·δa
    else:
        axes = ["x", "y", "z"]
        shift = np.zeros((m, k, 3))
        shift[:, :3] = np.eye(3)
        columns = [shift]
        if rigid:
            points = data.y[:, :3] - data.y[after, :3].mean(axis=0)
            turn = np.zeros((m, k, 3))
            turn[:, :3] = -skew(points) / 1000.0  # ω × y = −[y]× ω, ω in mrad
            if k == 6:
                turn[:, 3:] = np.eye(3) / 1000.0
            axes += ["rx", "ry", "rz"]
            columns.append(turn)
    basis = np.concatenate(columns, axis=2) * after[:, None, None]
    row = int(data.rows[sample]) if data.rows is not None else sample
    detail = {"sample": int(sample), "row": row, "axes": axes} | ({"frame": "rigid"} if any(a not in SHIFT_AXES for a in axes) else {})
    return Candidate("step", None, "observations", basis, detail=detail)


def cable_directions(data: Dataset, robot: Optional[Robot]) -> Optional[np.ndarray]:
    """Unit vectors (m, 3) from the cable's anchor to the tool point of each sample: the nominal
    tool points of ``robot`` and the anchor placed on them in closed form; None without a robot
    (the anchor's move is then not modelled)."""
    if robot is None:
        return None
    points = robot.fkine(data.q, tool=True)[:, :3, 3]
    anchor, _ = cable_initial_guess(points, data.y[:, 0])
    d = points - anchor
    return d / np.linalg.norm(d, axis=1)[:, None]


def acquisition_order(data: Dataset) -> np.ndarray:
    """Sample indices in acquisition order: by ``t`` if the data carry it, else row order."""
    return np.argsort(data.t, kind="stable") if data.t is not None else np.arange(len(data))


def acquisition_position(data: Dataset) -> np.ndarray:
    """Each sample's place (0 .. m-1) in :func:`acquisition_order`."""
    position = np.empty(len(data), dtype=int)
    position[acquisition_order(data)] = np.arange(len(data))
    return position


#: Joint causes a compensation can apply from the joint angles alone (backlash needs the
#: approach direction, observation causes belong to the sensor, not the robot).
COMPENSABLE = ("joint_compliance", "joint_periodic", "joint_scale", "joint_coupling", "joint_map")
#: Causes with a physical model of how they carry from one session to another (gravity
#: compliance: the torque follows the pose): the selection tries them before free shapes.
PHYSICAL_KINDS = ("joint_compliance",)
#: Every cause acting on the joints: what a result carries to a new session of the same robot.
JOINT_KINDS = COMPENSABLE + ("backlash",)


def _check_joint_cause(robot: Robot, cause: dict) -> np.ndarray:
    """A result file's joint cause as :func:`joint_offsets` needs it — its coefficients, (n_c,) —
    or an error naming it."""
    where = f"cause {cause.get('label', cause['kind'])!r}"
    joint, detail = cause.get("joint"), cause.get("detail", {})
    if isinstance(joint, bool) or not isinstance(joint, int) or not 1 <= joint <= robot.n_joints or not isinstance(detail, dict):
        raise InvalidParameterError(f"{where}: needs `joint` 1..{robot.n_joints} and a `detail` object; got {joint!r}, {detail!r}")
    try:
        basis = joint_basis(robot, np.zeros((1, robot.n_joints)), cause["kind"], joint - 1, detail)
    except (KeyError, TypeError, IndexError) as exc:
        raise InvalidParameterError(f"{where}: malformed `detail` {detail!r} ({type(exc).__name__}: {exc})") from None
    coefficients = as_float_array(cause.get("coefficients"), f"{where} coefficients")
    values = basis.data if is_sparse(basis) else basis
    if (
        np.ndim(cause.get("coefficients")) != 1
        or coefficients.shape != (basis.shape[1],)
        or not (np.all(np.isfinite(coefficients)) and np.all(np.isfinite(values)))
    ):
        raise InvalidParameterError(f"{where}: needs a list of {basis.shape[1]} finite coefficients for a finite basis; got {cause.get('coefficients')!r}")
    return coefficients


def joint_offsets(robot: Robot, causes: list[dict], kinds: tuple = COMPENSABLE):
    """``Δq(q)`` (m, N) of the joint causes of ``kinds`` among a result file's ``causes``
    entries (``kind``, 1-based ``joint``, ``detail``, ``coefficients``), or None if there are
    none. (Backlash needs ``q`` in acquisition order: it is not among the default kinds.)"""
    usable = [c for c in causes if c.get("kind") in kinds]
    if not usable:
        return None
    checked = [(cause, _check_joint_cause(robot, cause)) for cause in usable]

    def offsets(q: np.ndarray) -> np.ndarray:
        dq = np.zeros_like(q)
        for c, coefficients in checked:
            j = c["joint"] - 1
            dq[:, j] += joint_basis(robot, q, c["kind"], j, c.get("detail", {})) @ coefficients
        return dq

    return offsets
