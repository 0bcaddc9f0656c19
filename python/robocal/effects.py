"""Non-geometric effects for the simulator: physical models that a purely geometric (DH)
calibration does not describe.

Each effect acts on one stage of a simulated acquisition (:class:`Acquisition`):

``parameters``
    the true kinematic parameters, per sample (axis misalignment, thermal expansion of links);
``joints``
    the difference ``Δq = q_actual − q_recorded`` between the joint angle the links really take
    and the one the controller records (compliance, gear errors, backlash, coupling);
``observations``
    the sensor reading after noise (drift, scale error, thermal scale, gross outliers).

Effects are written as specs ``KIND[:key=value,...]``, for example
``"joint_periodic:joint=2,amplitude=0.01,harmonic=1"``. Angles are in degrees at the spec level
(converted to rad inside), lengths in mm, times in s, temperatures in deg C (differences in K).
Every key has a default taken from the typical magnitude stated in its class docstring, except
``joint`` where the effect acts on one joint. :func:`parse_effect` reads a spec; each applied
effect reports what it did (:meth:`Effect.record`) for the simulation's ground truth.

The simulator (:mod:`robocal.simulation`) applies the stages in the order parameters, joints,
prediction, sensor noise, observations, quantisation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, ClassVar, Optional

import numpy as np

from .exceptions import InvalidParameterError
from .physics import DEG, MASS_MODELS, MassModel, approach_directions, gravity_torques, mass_model
from .serial_robot import MEASUREMENTS, Robot


# ---------------------------------------------------------------------------------------------
# The acquisition effects act on
# ---------------------------------------------------------------------------------------------
@dataclass
class Acquisition:
    """A simulated acquisition while effects are applied to it.

    Attributes
    ----------
    robot : Robot
        The robot with the simulation's tool and sensor placement (nominal values).
    measurement : {"cable", "position", "pose"}
    q : ndarray, shape (m, N)
        Recorded joint values in rad, rows in acquisition order.
    t : ndarray, shape (m,)
        Acquisition time in s.
    params : ndarray, shape (m, P)
        True parameters per sample (mm, rad).
    dq : ndarray, shape (m, N)
        Actual minus recorded joint values, rad.
    rng : numpy.random.Generator
        Randomness for effects that need it (outliers).
    y : ndarray, optional
        Observations, once predicted.
    temp : ndarray, optional
        Temperature in deg C, when an effect defines it.
    """

    robot: Robot
    measurement: str
    q: np.ndarray
    t: np.ndarray
    params: np.ndarray
    dq: np.ndarray
    rng: np.random.Generator
    y: Optional[np.ndarray] = None
    temp: Optional[np.ndarray] = None


# ---------------------------------------------------------------------------------------------
# Spec keys and the base class
# ---------------------------------------------------------------------------------------------
REQUIRED = object()


@dataclass(frozen=True)
class Key:
    """One key of an effect spec.

    Attributes
    ----------
    unit : str
        Unit at the spec level.
    default : object
        Default value (spec units); :data:`REQUIRED` if it must be given; ``None`` for "not set".
    factor : float
        Spec value times ``factor`` is the value in internal units (mm, rad, s).
    choices : tuple of str
        For a word-valued key, the accepted words.
    integer : bool
        The value must be an integer.
    """

    unit: str
    default: Any = REQUIRED
    factor: float = 1.0
    choices: tuple = ()
    integer: bool = False

    def convert(self, raw, where: str):
        """``raw`` (a spec string or a number) as the key's type; errors name ``where``."""
        if self.choices:
            if raw not in self.choices:
                raise InvalidParameterError(f"{where} must be one of {list(self.choices)}; got {raw!r}")
            return raw
        try:
            value = float(raw)
        except (TypeError, ValueError):
            raise InvalidParameterError(f"{where} must be a number; got {raw!r}") from None
        if not math.isfinite(value):
            raise InvalidParameterError(f"{where} must be finite; got {raw!r}")
        if self.integer:
            if value != int(value):
                raise InvalidParameterError(f"{where} must be an integer; got {raw!r}")
            return int(value)
        return value


JOINT = Key("1-based joint number", integer=True)


class Effect:
    """Base class of the effects: parses and checks the keys, reports what was applied.

    Subclasses set :attr:`kind`, :attr:`stage` (``parameters``, ``joints`` or ``observations``),
    :attr:`keys` and, to restrict them, :attr:`measurements`, and implement :meth:`apply`.

    Parameters
    ----------
    spec : str, optional
        The spec the effect was parsed from (for messages and the record).
    **values
        Key values in spec units (numbers, or strings as written in a spec).
    """

    kind: ClassVar[str] = ""
    stage: ClassVar[str] = ""
    keys: ClassVar[dict] = {}
    measurements: ClassVar[tuple] = MEASUREMENTS

    def __init__(self, spec: Optional[str] = None, **values):
        self.spec = spec or self.kind + (":" + ",".join(f"{k}={v}" for k, v in values.items()) if values else "")
        unknown = sorted(set(values) - set(self.keys))
        if unknown:
            raise InvalidParameterError(f"effect {self.spec!r}: unknown key {unknown[0]!r}; {self.kind} takes {list(self.keys)}")
        self.values = {}
        for name, key in self.keys.items():
            raw = values.get(name, key.default)
            if raw is REQUIRED:
                raise InvalidParameterError(f"effect {self.spec!r}: key {name!r} is required ({key.unit})")
            self.values[name] = None if raw is None else key.convert(raw, f"effect {self.spec!r}: key {name!r}")

    def __getitem__(self, name: str):
        """Value of key ``name`` in internal units (mm, rad, s)."""
        value, key = self.values[name], self.keys[name]
        return value * key.factor if isinstance(value, float) else value

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.spec!r})"

    def error(self, message: str) -> InvalidParameterError:
        return InvalidParameterError(f"effect {self.spec!r}: {message}")

    def joint_index(self, robot: Robot, name: str = "joint") -> Optional[int]:
        """The 0-based index of the joint in key ``name`` (None if unset), checked against ``robot``."""
        j = self.values[name]
        if j is not None and not 1 <= j <= robot.n_joints:
            raise self.error(f"key {name!r} must be a joint number 1..{robot.n_joints} of {robot.name}; got {j}")
        return None if j is None else j - 1

    def check(self, robot: Robot, measurement: str) -> None:
        """Raises :class:`InvalidParameterError` if the effect does not apply to this setup."""
        if measurement not in self.measurements:
            raise self.error(f"applies to {list(self.measurements)} measurements, not {measurement!r}")
        if "joint" in self.keys:
            self.joint_index(robot)

    def prepare(self, acq: Acquisition) -> None:
        """Sets what the acquisition records before any stage runs (e.g. its temperature)."""

    def apply(self, acq: Acquisition) -> dict:
        """Applies the effect to ``acq`` in place; returns its magnitude (``value``, ``unit``,
        ``what``)."""
        raise NotImplementedError

    def record(self, magnitude: dict) -> dict:
        """What the effect did, for the ground truth (JSON-serialisable)."""
        return {
            "kind": self.kind,
            "spec": self.spec,
            "stage": self.stage,
            "joint": self.values.get("joint"),
            "parameters": {k: {"value": v, "unit": self.keys[k].unit} for k, v in self.values.items() if k != "joint"},
            "magnitude": magnitude,
        }


#: Largest joint-angle error an effect may have (deg): beyond it no reducer or encoder is in
#: working order, and a diagnosis' plausibility limit would reject it as a cause.
MAX_ANGLE_DEG = 1.0


def check_angle(effect: "Effect", key: str) -> None:
    """Refuses an angle key beyond ±:data:`MAX_ANGLE_DEG`."""
    if abs(effect.values[key]) > MAX_ANGLE_DEG:
        raise effect.error(f"key {key!r} must be within ±{MAX_ANGLE_DEG:g} deg; got {effect.values[key]}")


def _largest(change: np.ndarray, unit: str, what: str, factor: float = 1.0) -> dict:
    value = float(np.max(np.abs(change))) / factor if change.size else 0.0
    return {"value": value, "unit": unit, "what": what}


# ---------------------------------------------------------------------------------------------
# Joint effects: Δq = q_actual − q_recorded
# ---------------------------------------------------------------------------------------------
class JointEffect(Effect):
    """An effect on the actual joint angles: observations are predicted at ``q + Δq``."""

    stage = "joints"

    def offsets(self, acq: Acquisition) -> np.ndarray:
        """``Δq`` in rad, shape (m, N)."""
        raise NotImplementedError

    def check(self, robot, measurement):
        super().check(robot, measurement)
        # A prismatic joint moves in mm: an angle key would be read as rad of it (backlash width=0.1 deg as 0.0017 mm).
        angles = [k for k, key in self.keys.items() if key.unit == "deg"]
        j = self.joint_index(robot) if "joint" in self.keys else None
        if angles and j is not None and robot.joints[j].kind == "prismatic":
            raise self.error(
                f"joint {j + 1} of {robot.name} is prismatic (it moves in mm); {', '.join(map(repr, angles))} {'is' if len(angles) == 1 else 'are'} in deg"
            )

    def offset_of_joint(self, acq: Acquisition, values: np.ndarray) -> np.ndarray:
        """A (m, N) offset that is ``values`` on this effect's joint and 0 elsewhere."""
        dq = np.zeros_like(acq.q)
        dq[:, self.joint_index(acq.robot)] = values
        return dq

    def apply(self, acq: Acquisition) -> dict:
        dq = self.offsets(acq)
        acq.dq += dq
        j = self.joint_index(acq.robot) if "joint" in self.keys else None
        if j is not None and acq.robot.joints[j].kind == "prismatic":
            return _largest(dq, "mm", "largest |Δq|")
        return _largest(dq, "deg", "largest |Δq|", DEG)


class JointCompliance(JointEffect):
    """Joint elasticity under gravity: ``Δq_j = k_j · τ_j(q)``.

    ``τ_j`` (N·m) is the gravity torque about joint j from the robot's mass model
    (:func:`robocal.physics.mass_model`: a robot file's ``masses``, else the built-in model;
    :func:`robocal.physics.gravity_torques`, links and a payload at the tool point); ``k_j`` is the joint
    compliance (inverse stiffness). The link sags in the direction gravity pulls it, while the
    motor encoder records the commanded angle. Torques are evaluated at the recorded angles
    (first order in ``k``).

    Keys: ``joint`` (optional; all joints when omitted), ``compliance`` in deg/(kN·m)
    (1 deg/(kN·m) = 1.745e-5 rad/(N·m); default: the mass model's, 3e-7 rad/(N·m) for the
    JR680, 2e-5 for the IRB 120, 1e-5 for the UR10, a robot file's ``compliance_rad_per_Nm``), ``payload`` in kg (default 0),
    ``mass_error`` (default 0): the true robot's link masses and centres of mass each differ from
    the mass model by a factor drawn uniformly from ``1 ± mass_error`` — a real arm is never its
    mass model, and a diagnosis must not need it to be.
    Typical: joint stiffness 1e6-1e7 N·m/rad on large industrial robots (Dumas et al. 2011),
    1e4-1e5 N·m/rad on small ones; sag of ~0.01-0.1 deg at the shoulder.
    """

    kind = "joint_compliance"
    keys = {
        "joint": Key(JOINT.unit, None, integer=True),
        "compliance": Key("deg/(kN·m)", None, DEG / 1000.0),
        "payload": Key("kg", 0.0),
        "mass_error": Key("1", 0.0),
    }

    def check(self, robot, measurement):
        super().check(robot, measurement)
        model = mass_model(robot)
        if model is None:
            raise self.error(
                f"no mass model for robot {robot.name!r}: give its robot file a 'masses' section (docs/data-format.md) "
                f"or use a built-in robot with one ({sorted(MASS_MODELS)})"
            )
        if self.values["payload"] < 0:
            raise self.error(f"key 'payload' must be >= 0 kg; got {self.values['payload']}")
        if not 0.0 <= self.values["mass_error"] < 1.0:
            raise self.error(f"key 'mass_error' must be within [0, 1); got {self.values['mass_error']}")
        if self.values["compliance"] is None:  # the robot's default, in spec units for the record
            if model.compliance is None:
                raise self.error(f"robot {robot.name!r}'s mass model has no default compliance: give key 'compliance' (deg/(kN·m))")
            self.values["compliance"] = model.compliance / self.keys["compliance"].factor

    def true_masses(self, robot: Robot, rng: np.random.Generator) -> MassModel:
        """The mass model with each link's mass and centre of mass off by ``1 ± mass_error``."""
        model, e = mass_model(robot), self["mass_error"]
        if e == 0.0:
            return model
        n = len(model.link_masses)
        masses = np.array(model.link_masses) * rng.uniform(1.0 - e, 1.0 + e, n)
        centres = (
            None
            if model.centres_of_mass is None
            else tuple(None if c is None else tuple(np.array(c) * rng.uniform(1.0 - e, 1.0 + e, 3)) for c in model.centres_of_mass)
        )
        return replace(model, link_masses=tuple(masses), centres_of_mass=centres)

    def offsets(self, acq):
        compliance = self["compliance"]
        tau = gravity_torques(acq.robot, acq.q, acq.params[0], self["payload"], model=self.true_masses(acq.robot, acq.rng))
        j = self.joint_index(acq.robot)
        return compliance * tau if j is None else self.offset_of_joint(acq, compliance * tau[:, j])


class JointPeriodic(JointEffect):
    """Periodic transmission error (gear eccentricity): ``Δq_j = A · sin(h · q_j + φ)``.

    Keys: ``joint``, ``amplitude`` A in deg (default 0.01), ``harmonic`` h, cycles per joint
    revolution (integer, default 1), ``phase`` φ in deg (default 0). Typical: 0.005-0.02 deg
    (about 0.3-1 arcmin, the transmission error of RV and harmonic reducers).
    """

    kind = "joint_periodic"
    keys = {"joint": JOINT, "amplitude": Key("deg", 0.01, DEG), "harmonic": Key("cycles/rev", 1, integer=True), "phase": Key("deg", 0.0, DEG)}

    def check(self, robot, measurement):
        super().check(robot, measurement)
        if self.values["harmonic"] < 1:
            raise self.error(f"key 'harmonic' must be >= 1 cycle per revolution (0 would be a constant offset); got {self.values['harmonic']}")
        check_angle(self, "amplitude")

    def offsets(self, acq):
        j = self.joint_index(acq.robot)
        return self.offset_of_joint(acq, self["amplitude"] * np.sin(self["harmonic"] * acq.q[:, j] + self["phase"]))


class JointScale(JointEffect):
    """Transmission-ratio error: ``Δq_j = s · q_j``.

    Keys: ``joint``, ``scale`` s (dimensionless, default 2e-4). Typical: 1e-4-1e-3 (a gear
    ratio or encoder resolution set slightly wrong).
    """

    kind = "joint_scale"
    keys = {"joint": JOINT, "scale": Key("1", 2e-4)}

    def offsets(self, acq):
        j = self.joint_index(acq.robot)
        return self.offset_of_joint(acq, self["scale"] * acq.q[:, j])


class JointCoupling(JointEffect):
    """Cross-coupling of joints: ``Δq_j = c · q_k``.

    A wrist whose joint-j drive passes through joint k's transmission turns joint j when joint k
    moves; a controller decoupling with a slightly wrong ratio leaves ``c``.
    Keys: ``joint`` j, ``source`` k (another joint), ``coefficient`` c (dimensionless, default
    5e-4). Typical: 1e-4-1e-3.
    """

    kind = "joint_coupling"
    keys = {"joint": JOINT, "source": Key(JOINT.unit, integer=True), "coefficient": Key("1", 5e-4)}

    def check(self, robot, measurement):
        super().check(robot, measurement)
        source, joint = self.joint_index(robot, "source"), self.joint_index(robot)
        if source == joint:
            raise self.error("key 'source' must name a joint other than 'joint'")
        if robot.joints[source].kind != robot.joints[joint].kind:  # the coefficient would carry mm into rad
            raise self.error(f"joints {joint + 1} and {source + 1} of {robot.name} are a {robot.joints[joint].kind} and a {robot.joints[source].kind} one")

    def offsets(self, acq):
        k = self.joint_index(acq.robot, "source")
        return self.offset_of_joint(acq, self["coefficient"] * acq.q[:, k])


class Backlash(JointEffect):
    """Lost motion of joint j: ``Δq_j = −(b/2) · s_i``.

    ``s_i`` is the direction joint j last moved in, from the acquisition order: the sign of
    ``q_j(i) − q_j(i−1)``; a sample without motion keeps the previous direction and the first
    sample counts as approached in the positive direction. With ``b > 0`` the link lags behind
    the motor by half the play (backlash); with ``b < 0`` the reading lags behind the link — the
    link leads (an encoder on the motor side of an elastic stage, a servo's following error,
    preload).
    Keys: ``joint``, ``width`` b in deg (default 0.02; nonzero, |b| ≤ 1). Typical: 0.01-0.03 deg
    (≤ 1-2 arcmin for industrial reducers).
    """

    kind = "backlash"
    keys = {"joint": JOINT, "width": Key("deg", 0.02, DEG)}

    def check(self, robot, measurement):
        super().check(robot, measurement)
        if self.values["width"] == 0:
            raise self.error("key 'width' must be nonzero (deg; negative: the link leads its reading)")
        check_angle(self, "width")

    def offsets(self, acq):
        j = self.joint_index(acq.robot)
        return self.offset_of_joint(acq, -0.5 * self["width"] * approach_directions(acq.q[:, j]))


# ---------------------------------------------------------------------------------------------
# Parameter effects
# ---------------------------------------------------------------------------------------------
class AxisMisalignment(Effect):
    """Nominally parallel axes that are not: Hayati's ``beta_j`` (rotation about y) is nonzero.

    Applies to a joint flagged ``hayati`` (its axis nominally parallel to the previous one);
    adds ``beta`` to ``beta_j`` of every sample. Plain DH cannot represent it (a small ``alpha``
    makes ``d`` ill-conditioned instead); Hayati's parametrisation can.
    Keys: ``joint``, ``beta`` in deg (default 0.05). Typical: 0.01-0.1 deg.
    """

    kind = "axis_misalignment"
    stage = "parameters"
    keys = {"joint": JOINT, "beta": Key("deg", 0.05, DEG)}

    def check(self, robot, measurement):
        super().check(robot, measurement)
        j = self.joint_index(robot)
        if not robot.joints[j].hayati:
            hayati = [i + 1 for i, joint in enumerate(robot.joints) if joint.hayati]
            raise self.error(f"joint {j + 1} of {robot.name} is not nominally parallel to the previous one; hayati joints: {hayati}")

    def apply(self, acq):
        acq.params[:, acq.robot.index(f"beta{self.values['joint']}")] += self["beta"]
        return {"value": abs(self.values["beta"]), "unit": "deg", "what": "|Δbeta|"}


class Temperature(Effect):
    """Thermal expansion during a warm-up.

    The temperature follows ``T(t) = T0 + ΔT · (1 − exp(−t/τ))`` (recorded as the dataset's
    ``temp`` column). With ``target=links`` every link length ``a_j``, ``d_j`` becomes
    ``(1 + α (T − T0))`` times its true value (T0 is the temperature of the true geometry);
    with ``target=cable`` the cable reading becomes ``L' = (1 + α (T − T0)) · L``.
    Keys: ``target`` (``links`` or ``cable``, default links), ``rise`` ΔT in K (default 5),
    ``tau`` τ in s (default 600), ``alpha`` α in 1e-6/K (default 12), ``start`` T0 in deg C
    (default 20). Typical: α 11-12e-6/K for steel and cast iron, 23e-6/K for aluminium; a
    robot warms by 2-10 K within the first hour: ~0.1 mm on a 2 m arm.
    """

    kind = "temperature"
    keys = {
        "target": Key("word", "links", choices=("links", "cable")),
        "rise": Key("K", 5.0),
        "tau": Key("s", 600.0),
        "alpha": Key("1e-6/K", 12.0, 1e-6),
        "start": Key("degC", 20.0),
    }

    @property
    def stage(self):
        return "parameters" if self.values["target"] == "links" else "observations"

    def check(self, robot, measurement):
        super().check(robot, measurement)
        if self.values["target"] == "cable" and measurement != "cable":
            raise self.error(f"target 'cable' needs cable measurements, not {measurement!r}")
        if self.values["tau"] <= 0:
            raise self.error(f"key 'tau' must be > 0 s; got {self.values['tau']}")

    def curve(self, t: np.ndarray) -> np.ndarray:
        """Temperature in deg C at times ``t`` (s)."""
        return self["start"] + self["rise"] * (1.0 - np.exp(-t / self["tau"]))

    def expansion(self, acq: Acquisition) -> np.ndarray:
        """``α (T − T0)`` per sample."""
        return self["alpha"] * (self.curve(acq.t) - self["start"])

    def prepare(self, acq):
        acq.temp = self.curve(acq.t)

    def apply(self, acq):
        factor = 1.0 + self.expansion(acq)[:, None]
        if self.values["target"] == "cable":
            before = acq.y.copy()
            acq.y = acq.y * factor
            return _largest(acq.y - before, "mm", "largest |ΔL|")
        n = acq.robot.n_joints
        lengths = [acq.robot.index(f"{p}{j}") for j in range(1, n + 1) for p in ("a", "d")]
        before = acq.params[:, lengths].copy()
        acq.params[:, lengths] *= factor
        return _largest(acq.params[:, lengths] - before, "mm", "largest change of a link length")


# ---------------------------------------------------------------------------------------------
# Observation effects (the sensor)
# ---------------------------------------------------------------------------------------------
class ObservationEffect(Effect):
    """An effect on the sensor readings (after sensor noise, before quantisation)."""

    stage = "observations"

    def check_axis(self, measurement: str) -> None:
        """Refuses key ``axis`` on cable data: a cable reading has one axis, its length."""
        if measurement == "cable" and self.values.get("axis") is not None:
            raise self.error(f"key 'axis' applies to position and pose measurements; a cable's {self.kind} is along its length")

    def observe(self, acq: Acquisition) -> np.ndarray:
        """The changed observations (m, k)."""
        raise NotImplementedError

    def apply(self, acq):
        before = acq.y
        acq.y = self.observe(acq)
        return _largest((acq.y - before)[:, :3], "mm", "largest |Δy|")


class Drift(ObservationEffect):
    """A sensor offset drifting with time: cable ``ΔL = r · t``; position and pose
    ``Δp = r · t · e_axis`` (the position part).

    Keys: ``rate`` r in mm/h (default 0.2), ``axis`` (``x``, ``y`` or ``z``, default z; position
    and pose only), ``exponent`` p (default 1): a drift that is not linear,
    ``r · T · (t/T)^p`` over a session of length ``T`` (the same offset at its end). Typical:
    0.05-0.5 mm/h (thermal drift of a sensor or its stand).
    """

    kind = "drift"
    keys = {"rate": Key("mm/h", 0.2, 1.0 / 3600.0), "axis": Key("word", None, choices=("x", "y", "z")), "exponent": Key("1", 1.0)}

    def check(self, robot, measurement):
        super().check(robot, measurement)
        self.check_axis(measurement)
        if self.values["exponent"] <= 0:
            raise self.error(f"key 'exponent' must be > 0; got {self.values['exponent']}")

    def observe(self, acq):
        y = acq.y.copy()
        column = 0 if acq.measurement == "cable" else "xyz".index(self.values["axis"] or "z")
        span = max(float(acq.t[-1]), 1e-12)
        y[:, column] += self["rate"] * span * (acq.t / span) ** self["exponent"]
        return y


class Step(ObservationEffect):
    """The sensor's zero jumps once in the session (a cable re-hooked or re-zeroed, a tracker
    bumped): from sample ``sample`` on, cable ``ΔL = size``; position and pose ``Δp = size·e_axis``.

    Keys: ``sample`` (0-based index of the first sample after the step, required), ``size`` in mm
    (default 0.5), ``axis`` (``x``, ``y`` or ``z``, default z; position and pose only).
    """

    kind = "step"
    keys = {"sample": Key("0-based sample", integer=True), "size": Key("mm", 0.5), "axis": Key("word", None, choices=("x", "y", "z"))}

    def check(self, robot, measurement):
        super().check(robot, measurement)
        self.check_axis(measurement)

    def observe(self, acq):
        if not 0 < self.values["sample"] < len(acq.y):
            raise self.error(f"key 'sample' must lie within 1..{len(acq.y) - 1}; got {self.values['sample']}")
        y = acq.y.copy()
        column = 0 if acq.measurement == "cable" else "xyz".index(self.values["axis"] or "z")
        y[self.values["sample"] :, column] += self["size"]
        return y


class Wander(ObservationEffect):
    """The sensor itself wanders in time: the cable sensor's zero, or the tracker's frame (its
    translation), moves slowly and irregularly — a stand warming and cooling, air currents, a
    base settling. A smooth random process in acquisition order: white noise smoothed by a
    Gaussian of ``length`` samples (its correlation length), scaled to RMS ``rms``; independent
    on x, y and z (position and pose) unless ``axis`` names one.

    Keys: ``rms`` in mm (default 0.2), ``length`` in samples (default 10), ``axis`` (``x``,
    ``y`` or ``z``; position and pose only). Typical: a few tenths of a mm over 5-20 samples.
    """

    kind = "wander"
    keys = {"rms": Key("mm", 0.2), "length": Key("samples", 10.0), "axis": Key("word", None, choices=("x", "y", "z"))}

    def check(self, robot, measurement):
        super().check(robot, measurement)
        self.check_axis(measurement)
        if self.values["rms"] <= 0:
            raise self.error(f"key 'rms' must be > 0 mm; got {self.values['rms']}")
        if not 1.0 <= self.values["length"] <= 1e4:
            raise self.error(f"key 'length' must be within 1..10000 samples; got {self.values['length']}")

    def observe(self, acq):
        from scipy.ndimage import gaussian_filter1d  # imported on use: only this effect needs it

        m = len(acq.y)
        columns = [0] if acq.measurement == "cable" else ["xyz".index(self.values["axis"])] if self.values["axis"] else [0, 1, 2]
        path = gaussian_filter1d(acq.rng.normal(size=(m, len(columns))), self["length"], axis=0, mode="reflect")
        path -= path.mean(axis=0)
        path *= self["rms"] / max(float(np.sqrt(np.mean(np.sum(path**2, axis=1)))), 1e-300)
        y = acq.y.copy()
        y[:, columns] += path
        return y


class CableScale(ObservationEffect):
    """Scale error of the cable sensor: ``L' = (1 + ε) · L``.

    Keys: ``scale`` ε (dimensionless, default 2e-4). Typical: 1e-4-5e-4 (linearity of a
    draw-wire sensor such as the HY150-2000, ±0.02-0.05 % of full scale).
    """

    kind = "cable_scale"
    measurements = ("cable",)
    keys = {"scale": Key("1", 2e-4)}

    def observe(self, acq):
        return (1.0 + self["scale"]) * acq.y


class Outliers(ObservationEffect):
    """Gross errors on a fraction of the observations (a slipped cable, a broken beam).

    ``round(fraction · m)`` samples (at least one for a positive fraction), chosen at random,
    get an error of size uniform in ``[size, 3·size]`` mm: along ±L for the cable, in a random
    direction for positions (the position part of a pose). Their rows are in the record.
    Keys: ``fraction`` (0..1, default 0.01), ``size`` in mm (default 2). Typical: ~1 % of
    samples, errors of mm to cm.
    """

    kind = "outliers"
    keys = {"fraction": Key("1", 0.01), "size": Key("mm", 2.0)}

    def check(self, robot, measurement):
        super().check(robot, measurement)
        if not 0.0 <= self.values["fraction"] <= 1.0:
            raise self.error(f"key 'fraction' must be within 0..1; got {self.values['fraction']}")
        if self.values["size"] <= 0:
            raise self.error(f"key 'size' must be > 0 mm; got {self.values['size']}")

    def observe(self, acq):
        m = len(acq.y)
        count = min(m, max(1, round(self["fraction"] * m))) if self["fraction"] > 0 else 0
        self.samples = np.sort(acq.rng.choice(m, size=count, replace=False))
        size = acq.rng.uniform(self["size"], 3.0 * self["size"], count)
        width = 1 if acq.measurement == "cable" else 3
        direction = acq.rng.normal(size=(count, width))
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        y = acq.y.copy()
        y[self.samples, :width] += size[:, None] * direction
        return y

    def record(self, magnitude):
        record = super().record(magnitude)
        record["samples"] = [int(i) for i in self.samples]
        return record


EFFECTS = {
    cls.kind: cls
    for cls in (JointCompliance, JointPeriodic, JointScale, JointCoupling, Backlash, Drift, Step, Wander, Temperature, CableScale, AxisMisalignment, Outliers)
}


def parse_effect(spec: str) -> Effect:
    """An effect from a spec ``KIND[:key=value,...]``.

    Examples
    --------
    >>> parse_effect("joint_periodic:joint=2,amplitude=0.01,harmonic=1")
    JointPeriodic('joint_periodic:joint=2,amplitude=0.01,harmonic=1')
    """
    if not isinstance(spec, str) or not spec.strip():
        raise InvalidParameterError(f"an effect spec must be a non-empty string 'KIND[:key=value,...]'; got {spec!r}")
    kind, _, rest = spec.strip().partition(":")
    cls = EFFECTS.get(kind.strip())
    if cls is None:
        raise InvalidParameterError(f"effect {spec!r}: unknown kind {kind!r}; known kinds are {sorted(EFFECTS)}")
    values = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        key, eq, value = item.partition("=")
        if not eq or not key.strip() or not value.strip():
            raise InvalidParameterError(f"effect {spec!r}: expected key=value; got {item!r}")
        if key.strip() in values:
            raise InvalidParameterError(f"effect {spec!r}: key {key.strip()!r} given twice")
        values[key.strip()] = value.strip()
    return cls(spec=spec.strip(), **values)
