"""An acquisition simulator that shares no effect model with robocal: the mismatch section of the
discovery benchmark (issue 51).

robocal's own simulator (:mod:`robocal.simulation`, :mod:`robocal.effects`) makes each hidden
effect in exactly the shape one of diagnose's candidates fits, so a benchmark built on it
measures agreement with itself. This module makes the data another way:

- its own forward kinematics (standard DH, written here with SciPy's rotations; checked against
  robocal's nominal model to 1e-9 mm at the start of every file, which is the only thing the two
  share: the nominal robot);
- geometric errors that are not DH errors: every link frame gets a small rigid-body error of all
  six components (translation N(0, 0.4) mm, rotation N(0, 0.04)° per axis), and the tool point
  and the sensor's placement errors of their own;
- hidden effects made by physical models that differ from every candidate (:data:`FAMILIES`):
  gravity deflection from point masses placed elsewhere than robocal's mass model, with a
  payload; a tracker (or cable anchor) knocked so that its frame moves *and turns*; warm-up
  exponentials and waves on a ramp; lost motion with a friction-like (tanh) transition; joint
  errors periodic in the angle but of other wave forms (sawtooth, triangle, a clipped sine); a
  sensor's own error (the cable drum's once-a-turn error; the tracker's angle encoder's error);
  heavy-tailed (Student t, 3 degrees of freedom) and time-correlated (AR(1)) noise;
- its own noise: Gaussian of the sensors' stated sigma (cable 0.03 mm quantised to 0.004 mm,
  tracker 0.02 mm and 1e-5 rad), unless the family replaces it.

Only the *path* (the joint configurations, drawn as robocal's simulator draws them: a random walk
within the limits and the cable's range) and the nominal set-up (tool point, anchor) come from
robocal: what was measured where, not how the robot erred.

Each family states which named causes are true for it (``accept``: a claim about the robot a user
could act on): gravity deflection of joint 2 is found by a compliance of joint 2 (a joint map of
joint 2 follows an error of that joint's angle alone, not a deflection that depends on every
joint's); a knocked sensor by a step within ±5 samples; a warm-up by one of a drift, a wander or
a temperature term (a second claims nothing). Families of noise hide no cause (``optional``):
naming one there is false, but for the shape noted (outliers in heavy-tailed noise, a wander in
AR(1) noise), which counts as true; missing it is no error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import robocal
from robocal.simulation import acquisition_path, setup
from scipy.spatial.transform import Rotation

GRAVITY = 9.80665  # m/s²
#: Link-frame errors of the true robot (per axis): translation mm, rotation deg.
LINK_ERROR_MM, LINK_ERROR_DEG = 0.4, 0.04
TOOL_ERROR_MM, ANCHOR_ERROR_MM = 0.5, 2.0
#: The tracker's frame relative to the robot base: translation mm and rotation deg per axis.
TRACKER_PLACEMENT_MM, TRACKER_PLACEMENT_DEG = 5.0, 0.5
NOISE = {"cable": (0.03, 0.004), "position": (0.02, 0.0), "pose": (0.02, 0.0)}  # sigma mm, resolution mm
SIGMA_ROTATION = 1e-5  # rad
DT = 2.0  # s per sample

#: Point masses of the true robots (kg), one per link 2..N (link 1 turns about a vertical axis:
#: its mass exerts no torque on a horizontal joint), and a rated payload (kg). robocal's mass
#: model puts its masses at mid-link (HSR, ABB) or at UR's published centres; these sit at a
#: random fraction 0.15-0.85 of the link, up to 60 mm (15 % of the link on small robots) off it.
MASSES = {
    "hsr-jr680": ((120.0, 80.0, 40.0, 15.0, 5.0), 80.0),
    "abb-irb120": ((4.0, 3.0, 1.5, 0.6, 0.1), 3.0),
    "ur10": ((13.0, 4.0, 2.0, 2.0, 0.4), 10.0),
}


# ---------------------------------------------------------------------------------------------
# Kinematics of the true robot
# ---------------------------------------------------------------------------------------------
def dh(theta, d, a, alpha) -> np.ndarray:
    """Standard DH link transforms (m, 4, 4): Rz(theta) Tz(d) Tx(a) Rx(alpha); theta (m,)."""
    ct, st, ca, sa = np.cos(theta), np.sin(theta), math.cos(alpha), math.sin(alpha)
    T = np.zeros((len(theta), 4, 4))
    T[:, 0] = np.stack([ct, -st * ca, st * sa, a * ct], -1)
    T[:, 1] = np.stack([st, ct * ca, -ct * sa, a * st], -1)
    T[:, 2, 1:] = (sa, ca, d)
    T[:, 3, 3] = 1.0
    return T


def rigid(rotvec, translation) -> np.ndarray:
    """A 4x4 transform from a rotation vector (rad) and a translation (mm)."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:3, 3] = translation
    return T


@dataclass
class TrueRobot:
    """A robot as it is: the nominal DH chain, each link frame followed by a rigid error."""

    theta: np.ndarray
    d: np.ndarray
    a: np.ndarray
    alpha: np.ndarray
    link_errors: np.ndarray  # (N, 4, 4)
    tool: np.ndarray  # (3,) mm, in the flange frame

    def frames(self, q: np.ndarray) -> np.ndarray:
        """Frames 0..N (m, N + 1, 4, 4) in the robot base frame at link angles ``q`` (rad)."""
        m, n = q.shape
        T = np.zeros((m, n + 1, 4, 4))
        T[:, 0] = np.eye(4)
        for j in range(n):
            T[:, j + 1] = T[:, j] @ dh(q[:, j] + self.theta[j], self.d[j], self.a[j], self.alpha[j]) @ self.link_errors[j]
        return T

    def tool_points(self, q: np.ndarray) -> np.ndarray:
        T = self.frames(q)[:, -1]
        return T[:, :3, :3] @ self.tool + T[:, :3, 3]


def nominal_robot(name: str, measurement: str) -> tuple[robocal.Robot, TrueRobot]:
    """robocal's nominal robot (set up as its simulator sets it up) and the same chain as a
    :class:`TrueRobot` without errors."""
    nominal = setup(robocal.robot(name), measurement)
    n = nominal.n_joints
    if any(j.convention != "dh" or j.kind != "revolute" for j in nominal.joints):
        raise ValueError(f"{name}: the mismatch simulator models revolute standard-DH chains only")
    p = {k: float(v) for k, v in zip(nominal.param_names, nominal.params)}
    if any(abs(p[f"beta{j}"]) > 0 for j in range(1, n + 1)) or any(abs(p[f"base_{c}"]) > 0 for c in ("x", "y", "z", "rx", "ry", "rz")):
        raise ValueError(f"{name}: a nominal Hayati beta or base frame is not modelled here")
    chain = TrueRobot(
        *(np.array([p[f"{k}{j}"] for j in range(1, n + 1)]) for k in ("theta", "d", "a", "alpha")),
        link_errors=np.tile(np.eye(4), (n, 1, 1)),
        tool=np.array([p["tool_x"], p["tool_y"], p["tool_z"]]),
    )
    return nominal, chain


def check_against_robocal(nominal: robocal.Robot, chain: TrueRobot, q: np.ndarray) -> None:
    """The one thing shared with robocal: the nominal chain. Raise if the two disagree."""
    gap = np.abs(chain.tool_points(q) - nominal.fkine(q, tool=True)[:, :3, 3]).max()
    if gap > 1e-9:
        raise AssertionError(f"the mismatch simulator's nominal FK differs from robocal's by {gap:.3g} mm")


# ---------------------------------------------------------------------------------------------
# An acquisition: the path, the true robot and its set-up, then effects and noise
# ---------------------------------------------------------------------------------------------
@dataclass
class Acquisition:
    robot: str
    measurement: str
    q: np.ndarray  # (m, N) joint readings, rad
    t: np.ndarray  # (m,) s
    chain: TrueRobot
    tracker: np.ndarray  # (4, 4) the robot base in the tracker frame (position, pose)
    anchor: np.ndarray  # (3,) mm, cable
    offset: float  # mm, cable zero
    rng_effect: np.random.Generator
    rng_noise: np.random.Generator

    @property
    def n(self) -> int:
        return self.q.shape[1]


def acquisition(robot: str, measurement: str, samples: int, seed: int) -> Acquisition:
    """The file's path and its true robot and set-up, deterministic from ``seed``."""
    nominal, chain = nominal_robot(robot, measurement)
    rng_path, rng_robot, rng_effect, rng_noise = (np.random.default_rng(s) for s in np.random.SeedSequence([seed, 51]).spawn(4))
    q = acquisition_path(nominal, measurement, samples, rng_path)
    check_against_robocal(nominal, chain, q[:20])
    n = nominal.n_joints
    chain.link_errors = np.stack([rigid(np.radians(rng_robot.normal(0.0, LINK_ERROR_DEG, 3)), rng_robot.normal(0.0, LINK_ERROR_MM, 3)) for _ in range(n)])
    chain.tool = chain.tool + rng_robot.normal(0.0, TOOL_ERROR_MM, 3)
    p = dict(zip(nominal.param_names, nominal.params))
    anchor = np.array([p["anchor_x"], p["anchor_y"], p["anchor_z"]]) + rng_robot.normal(0.0, ANCHOR_ERROR_MM, 3)
    tracker = rigid(np.radians(rng_robot.normal(0.0, TRACKER_PLACEMENT_DEG, 3)), rng_robot.normal(0.0, TRACKER_PLACEMENT_MM, 3))
    offset = float(rng_robot.normal(0.0, 5.0))
    return Acquisition(robot, measurement, q, DT * np.arange(samples), chain, tracker, anchor, offset, rng_effect, rng_noise)


@dataclass
class State:
    """What one pass of the generator changes: the link angles, the sensor's frame per sample
    (a tracker transform, or a cable anchor and zero), and additive sensor errors."""

    dq: np.ndarray  # (m, N) rad added to the readings
    tracker: np.ndarray  # (m, 4, 4)
    anchor: np.ndarray  # (m, 3)
    offset: np.ndarray  # (m,) mm
    sensor: np.ndarray  # (m, k) mm added to the reading (cable: L; tracker: x, y, z in its frame)
    noise: str = "gaussian"
    noise_keys: dict = None


def observe(acq: Acquisition, s: State) -> np.ndarray:
    """Noise-free readings of the true robot under state ``s``: (m, 1 | 3 | 7)."""
    q = acq.q + s.dq
    T = acq.chain.frames(q)[:, -1]
    point = T[:, :3, :3] @ acq.chain.tool + T[:, :3, 3]
    if acq.measurement == "cable":
        L = np.linalg.norm(point - s.anchor, axis=1) + s.offset
        return (L + s.sensor[:, 0])[:, None]
    W = s.tracker @ T  # the flange in the tracker frame
    xyz = np.einsum("mij,j->mi", W[:, :3, :3], acq.chain.tool) + W[:, :3, 3] + s.sensor
    if acq.measurement == "position":
        return xyz
    quat = Rotation.from_matrix(W[:, :3, :3]).as_quat()  # x, y, z, w
    wxyz = np.column_stack([quat[:, 3], quat[:, :3]])
    wxyz *= np.where(wxyz[:, :1] < 0, -1.0, 1.0)
    return np.column_stack([xyz, wxyz])


def clean_state(acq: Acquisition) -> State:
    m = len(acq.q)
    k = 1 if acq.measurement == "cable" else 3
    return State(
        dq=np.zeros_like(acq.q),
        tracker=np.tile(acq.tracker, (m, 1, 1)),
        anchor=np.tile(acq.anchor, (m, 1)),
        offset=np.full(m, acq.offset),
        sensor=np.zeros((m, k)),
        noise_keys={},
    )


def add_noise(acq: Acquisition, y: np.ndarray, s: State) -> np.ndarray:
    """The sensor's noise (its family: Gaussian, Student t or AR(1), each of the sensor's sigma)
    and quantisation."""
    rng = acq.rng_noise
    sigma, resolution = NOISE[acq.measurement]
    m, width = len(y), 1 if acq.measurement == "cable" else 3
    if s.noise == "student":
        dof = s.noise_keys["dof"]
        e = rng.standard_t(dof, (m, width)) * math.sqrt((dof - 2.0) / dof)
    elif s.noise == "ar1":
        phi = s.noise_keys["phi"]
        w = rng.normal(0.0, math.sqrt(1.0 - phi**2), (m, width))
        e = np.empty((m, width))
        e[0] = rng.normal(0.0, 1.0, width)
        for i in range(1, m):
            e[i] = phi * e[i - 1] + w[i]
    else:
        e = rng.normal(0.0, 1.0, (m, width))
    y = y.copy()
    y[:, :width] += sigma * e
    if acq.measurement == "pose":
        turn = Rotation.from_rotvec(rng.normal(0.0, SIGMA_ROTATION, (m, 3)))
        R = turn * Rotation.from_quat(np.column_stack([y[:, 4:7], y[:, 3]]))
        quat = R.as_quat()
        y[:, 3:] = np.column_stack([quat[:, 3], quat[:, :3]]) * np.where(quat[:, 3:4] < 0, -1.0, 1.0)
    if resolution:
        y[:, :width] = np.round(y[:, :width] / resolution) * resolution
    return y


# ---------------------------------------------------------------------------------------------
# The families of hidden effects
# ---------------------------------------------------------------------------------------------
def gravity_torques(acq: Acquisition, q: np.ndarray, masses: np.ndarray, places: np.ndarray, payload: float) -> np.ndarray:
    """Gravity torques (m, N) in N·m about each joint of the true robot: point masses
    ``masses`` (links 2..N) at ``places`` (fraction along the link, lateral offset mm in the
    link's frame), ``payload`` kg at the tool point."""
    F = acq.chain.frames(q)
    origins, z_axes = F[:, :, :3, 3], F[:, :, :3, 2]
    points = []
    for k, (fraction, ox, oy, oz) in enumerate(places):
        link = k + 1  # index of the link's distal frame: link k+2 lies between frames k+1 and k+2
        along = origins[:, link] + fraction * (origins[:, link + 1] - origins[:, link])
        points.append(along + F[:, link + 1, :3, :3] @ np.array([ox, oy, oz]))
    points.append(F[:, -1, :3, :3] @ acq.chain.tool + F[:, -1, :3, 3])
    points = np.stack(points, axis=1) / 1000.0  # (m, loads, 3) m
    weights = np.append(masses, payload) * GRAVITY
    down = np.array([0.0, 0.0, -1.0])
    tau = np.zeros(q.shape)
    for j in range(acq.n):
        first = max(j - 1, 0)  # loads beyond joint j+1: links j+2.. (index j-1 ..) and the payload
        lever = points[:, first:] - origins[:, j, None] / 1000.0
        moment = np.cross(lever, down) * weights[first:, None]
        tau[:, j] = np.einsum("mk,mk->m", moment.sum(axis=1), z_axes[:, j])
    return tau


def wave(kind: str, x: np.ndarray) -> np.ndarray:
    """Zero-mean periodic wave forms of unit amplitude, period 2π, none a pure sine."""
    u = np.mod(x, 2 * np.pi) / (2 * np.pi)
    if kind == "sawtooth":
        return 2.0 * u - 1.0
    if kind == "triangle":
        return 1.0 - 4.0 * np.abs(u - 0.5)
    if kind == "clipped":
        return np.clip(1.6 * np.sin(x), -1.0, 1.0)
    raise ValueError(kind)


def apply(acq: Acquisition, s: State, family: str, keys: dict, size: float) -> None:
    """Adds the effect ``family`` with ``keys`` at ``size`` to the state (linear in ``size``)."""
    m = len(acq.q)
    order = np.arange(m)
    if family == "gravity":
        tau = gravity_torques(acq, acq.q, np.array(keys["masses"]), np.array(keys["places"]), keys["payload"])
        for j in keys["joints"]:  # compliance per joint: size (deg per kN·m) times the joint's share
            s.dq[:, j - 1] += np.radians(size * keys["share"][str(j)]) * tau[:, j - 1] / 1000.0
    elif family == "frame_knock":
        after = order >= keys["sample"]
        u = np.array(keys["direction"])
        w = np.array(keys["turn_axis"])
        if acq.measurement == "cable":  # the anchor moved: the length changes with the direction to it
            s.anchor[after] += size * u
        else:  # the tracker moved and turned (about a point 2 m from the robot: the tracker's head)
            knock = rigid(np.radians(size * keys["turn_deg_per_mm"]) * w, size * u)
            pivot = rigid(np.zeros(3), np.array(keys["pivot"]))
            s.tracker[after] = pivot @ knock @ np.linalg.inv(pivot) @ s.tracker[after]
    elif family in ("warmup", "wave_drift"):
        t = acq.t / acq.t[-1]
        if family == "warmup":
            curve = 1.0 - np.exp(-t / keys["tau"])
        else:
            curve = t + keys["wave"] * np.sin(2 * np.pi * t / keys["period"] + keys["phase"])
        direction = np.array(keys["direction"])
        s.sensor += size * curve[:, None] * direction[None, :]
    elif family == "lost_motion":
        j = keys["joint"] - 1
        v = np.diff(acq.q[:, j], prepend=acq.q[0, j])
        # friction-like: the link lags by half the width, reached smoothly over moves of v0
        s.dq[:, j] += -np.radians(size) / 2.0 * np.tanh(v / np.radians(keys["v0_deg"]))
    elif family == "periodic_shape":
        j = keys["joint"] - 1
        s.dq[:, j] += np.radians(size) * wave(keys["shape"], keys["harmonic"] * acq.q[:, j] + keys["phase"])
    elif family == "sensor_error":
        if acq.measurement == "cable":  # the drum's once-a-turn error: periodic in the length
            L = observe(acq, clean_state(acq))[:, 0]
            s.sensor[:, 0] += size * np.sin(2 * np.pi * L / keys["period_mm"] + keys["phase"])
        else:  # the tracker's azimuth encoder: a tangential error periodic in the azimuth
            W = s.tracker @ acq.chain.frames(acq.q)[:, -1]
            p = np.einsum("mij,j->mi", W[:, :3, :3], acq.chain.tool) + W[:, :3, 3]
            rel = p - np.array(keys["station"])
            az = np.arctan2(rel[:, 1], rel[:, 0])
            tangent = np.column_stack([-np.sin(az), np.cos(az), np.zeros(m)])
            s.sensor += size * np.sin(keys["cycles"] * az + keys["phase"])[:, None] * tangent
    elif family in ("heavy_tails", "ar1_noise"):
        pass  # the noise's family: set in the keys (no size)
    else:
        raise ValueError(family)


@dataclass(frozen=True)
class Family:
    """A kind of hidden effect: what it is, which named causes are true for it, its size unit."""

    row: str
    accept: tuple  # named kinds that are true for it ("joint": must name its joint)
    joint: bool = False
    unit: float | None = 1.0  # the size of the unit effect; None: a fixed effect (noise)
    cap: float = float("inf")
    measurements: tuple = ("cable", "position", "pose")
    optional: bool = False  # hides no cause: missing it is no error
    sign: bool = False  # lost motion: the named width's sign must be the hidden one's


FAMILIES = {
    "gravity": Family("gravity, masses elsewhere + payload", ("joint_compliance",), joint=True, unit=0.1, cap=50.0),
    "frame_knock": Family("sensor frame knocked (moves and turns)", ("step",), unit=0.1, cap=5.0),
    "warmup": Family("warm-up (exponential)", ("drift", "wander", "temperature"), unit=0.1, cap=5.0),
    "wave_drift": Family("drift with a wave", ("drift", "wander", "temperature"), unit=0.1, cap=5.0),
    "lost_motion": Family("lost motion (tanh)", ("backlash", "lost_motion"), joint=True, unit=0.01, cap=0.9, sign=True),
    "periodic_shape": Family("periodic, other wave forms", ("joint_periodic", "joint_map", "joint_scale"), joint=True, unit=0.005, cap=0.9),
    "sensor_error": Family("the sensor's own error", ("sensor_periodic", "tracker_azimuth"), unit=0.01, cap=1.0),
    "heavy_tails": Family("heavy-tailed noise (t, 3 dof)", ("outliers",), unit=None, optional=True),
    "ar1_noise": Family("AR(1) noise", ("wander",), unit=None, optional=True),
}


def draw(family: str, acq: Acquisition, rng: np.random.Generator) -> dict:
    """The fixed keys of one effect of ``family`` (everything but its size)."""
    n, m = acq.n, len(acq.q)
    k = 1 if acq.measurement == "cable" else 3
    if family == "gravity":
        masses, payload = MASSES[acq.robot]
        masses = np.array(masses) * rng.uniform(0.7, 1.3, len(masses))
        scale = float(np.max(np.abs(acq.chain.a)) + np.max(np.abs(acq.chain.d)))
        lateral = min(60.0, 0.15 * scale)
        places = [[float(rng.uniform(0.15, 0.85)), *rng.uniform(-lateral, lateral, 3).round(1).tolist()] for _ in masses]
        joints = [2, 3] if rng.random() < 0.4 else [int(rng.integers(2, 4))]
        share = {str(j): float(rng.uniform(0.5, 1.5)) if len(joints) > 1 else 1.0 for j in joints}
        return {
            "masses": masses.round(2).tolist(),
            "places": places,
            "payload": round(float(rng.uniform(0.1, 0.5) * payload), 2),
            "joints": joints,
            "share": share,
        }
    if family == "frame_knock":
        u = rng.normal(size=3)
        w = rng.normal(size=3)
        return {
            "sample": int(rng.integers(30, m - 30)),
            "direction": (u / np.linalg.norm(u)).round(4).tolist(),
            "turn_axis": (w / np.linalg.norm(w)).round(4).tolist(),
            "turn_deg_per_mm": round(float(rng.uniform(0.005, 0.02)), 4),  # 0.01° for a 0.7 mm knock, as the issue's
            "pivot": [2000.0, 0.0, 0.0],
        }
    if family in ("warmup", "wave_drift"):
        u = rng.normal(size=k)
        keys = {"direction": (u / np.linalg.norm(u)).round(4).tolist()}
        if family == "warmup":
            keys["tau"] = round(float(rng.uniform(0.1, 0.4)), 3)  # of the session's length
        else:
            keys.update(
                wave=round(float(rng.uniform(0.15, 0.4)), 3), period=round(float(rng.uniform(0.3, 0.7)), 3), phase=round(float(rng.uniform(0, 6.28)), 2)
            )
        return keys
    if family == "lost_motion":
        return {"joint": int(rng.integers(1, n + 1)), "v0_deg": round(float(rng.uniform(0.5, 3.0)), 2)}
    if family == "periodic_shape":
        return {
            "joint": int(rng.integers(1, n + 1)),
            "shape": ("sawtooth", "triangle", "clipped")[int(rng.integers(3))],
            "harmonic": int(rng.integers(1, 4)),
            "phase": round(float(rng.uniform(0, 6.28)), 2),
        }
    if family == "sensor_error":
        if acq.measurement == "cable":
            return {"period_mm": round(float(rng.uniform(100.0, 400.0)), 1), "phase": round(float(rng.uniform(0, 6.28)), 2)}
        return {"station": [-2000.0, 500.0, 300.0], "cycles": int(rng.integers(1, 4)), "phase": round(float(rng.uniform(0, 6.28)), 2)}
    if family == "heavy_tails":
        return {"dof": 3.0}
    if family == "ar1_noise":
        return {"phi": round(float(rng.uniform(0.3, 0.7)), 2)}
    raise ValueError(family)


def readings(acq: Acquisition, effects: list[dict], noisy: bool = True) -> np.ndarray:
    """The file's readings with ``effects`` (each ``family``, ``keys``, ``size``)."""
    s = clean_state(acq)
    for e in effects:
        apply(acq, s, e["family"], e["keys"], e.get("size") or 0.0)
        if e["family"] == "heavy_tails":
            s.noise, s.noise_keys = "student", e["keys"]
        elif e["family"] == "ar1_noise":
            s.noise, s.noise_keys = "ar1", e["keys"]
    y = observe(acq, s)
    return add_noise(acq, y, s) if noisy else y
