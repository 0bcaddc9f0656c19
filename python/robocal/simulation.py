"""The simulator ("digital twin"): a simulated acquisition with known ground truth.

A simulation draws an acquisition path within the joint limits and the sensor's range, a true
robot (nominal kinematics plus random geometric errors of realistic size), applies the requested
non-geometric effects (:mod:`robocal.effects`) and sensor noise, and returns the data as a
:class:`~robocal.data.Dataset` together with a JSON-serialisable record of everything it drew.
See ``docs/simulator.md``.

Units: mm and rad inside, degrees for joint angles in files, s for time.
"""

from __future__ import annotations

import json
import math
from contextlib import nullcontext
from dataclasses import fields, replace
from pathlib import Path
from typing import Iterable, Mapping, Optional, Sequence, Union

import numpy as np

from .kernels import MAX_SAMPLES, as_count, as_float, as_float_array, as_positive, check_seed
from .data.formats.canonical import write_canonical
from .data.dataset import Dataset
from .effects import EFFECTS, Acquisition, Effect, parse_effect
from .exceptions import InvalidParameterError
from .geometry import matrix_from_quaternion, quaternion_from_matrix, so3_exp
from .outputs import Staged, check_outputs
from .robot import robot as load_robot
from .sensors import DEFAULT_NOISE, SensorNoise
from .serial_robot import MEASUREMENTS, Robot, setup_names

#: The cable sensor (a HY150-2000 draw-wire encoder): readings 0..2000 mm.
CABLE_SENSOR = "HY150-2000"
CABLE_RANGE = (0.0, 2000.0)
#: The path keeps nominal readings this far (mm) inside the range, so that geometric errors and
#: mm-size effects stay within it.
RANGE_MARGIN = 25.0
#: The measured point on the flange (mm): a cable attachment or tracker reflector holder.
DEFAULT_TOOL = (30.0, -10.0, 80.0)
#: Geometric errors: standard deviations of lengths (mm) and angles (deg).
LENGTH_ERROR_MM = 0.5
ANGLE_ERROR_DEG = 0.05
#: The seed's true robot is drawn on the first this many configurations of its path (the default
#: ``samples``), whatever ``samples`` is: which parameters the path identifies, and so which ones
#: the draws perturb, would otherwise depend on its length (300 and 400 samples of seed 1 were
#: robots 1.7 mm apart in a2).
TRUTH_PATH_SAMPLES = 400
#: Random-walk step per joint and sample (deg, standard deviation), and candidates per step.
STEP_DEG = 5.0
CANDIDATES = 64
ROUNDS = 50


def sensor_noise(measurement: str, noise=None) -> SensorNoise:
    """The noise of a simulation.

    ``None``: the sensor's default (:data:`DEFAULT_NOISE`); ``0``: noiseless (no quantisation
    either); another number: ``sigma`` in mm, the rest default; a mapping: defaults with some
    fields replaced; or a :class:`SensorNoise`.
    """
    default = DEFAULT_NOISE[measurement]
    if noise is None:
        return default
    if isinstance(noise, SensorNoise):
        chosen = noise
    elif isinstance(noise, Mapping):
        unknown = sorted(set(noise) - {f.name for f in fields(SensorNoise)})
        if unknown:
            raise InvalidParameterError(f"`noise` has unknown key {unknown[0]!r}; keys are {[f.name for f in fields(SensorNoise)]}")
        chosen = replace(default, **{k: as_float(v, f"noise {k}") for k, v in noise.items()})
    elif isinstance(noise, (int, float)) and not isinstance(noise, bool):
        chosen = SensorNoise() if noise == 0 else replace(default, sigma=float(noise))
    else:
        raise InvalidParameterError(f"`noise` must be None, a number (mm), a mapping or SensorNoise; got {noise!r}")
    for f in fields(SensorNoise):
        value = getattr(chosen, f.name)
        if not (math.isfinite(value) and value >= 0):
            raise InvalidParameterError(f"`noise` {f.name} must be finite and >= 0; got {value}")
    return chosen


def setup(r: Robot, measurement: str, tool=None, anchor=None) -> Robot:
    """The nominal robot of a simulation: ``r`` with the tool point and, for cable data, the
    sensor placed.

    The cable anchor defaults to ``(reach/2, 0, 0)``: on the floor in front of the robot, with
    ``reach`` the sum of the link lengths beyond the base column plus the tool (an upper bound
    of the horizontal reach); the sensor zero (``cable_offset``) is 0.
    """
    tool = DEFAULT_TOOL if tool is None else tuple(as_float_array(tool, "tool").ravel())
    if len(tool) != 3:
        raise InvalidParameterError(f"`tool` must be (x, y, z) in mm; got {tool!r}")
    values = dict(zip(("tool_x", "tool_y", "tool_z"), tool))
    if measurement == "cable":
        if anchor is None:
            n = r.n_joints
            lengths = [abs(r.params[r.index(f"a{j}")]) for j in range(1, n + 1)] + [abs(r.params[r.index(f"d{j}")]) for j in range(2, n + 1)]
            anchor = (0.5 * (sum(lengths) + math.hypot(*tool)), 0.0, 0.0)
        anchor = tuple(as_float_array(anchor, "anchor").ravel())
        if len(anchor) != 3:
            raise InvalidParameterError(f"`anchor` must be (x, y, z) in mm; got {anchor!r}")
        values.update(zip(("anchor_x", "anchor_y", "anchor_z"), anchor), cable_offset=0.0)
    return r.with_params(**values)


def _valid(r: Robot, measurement: str, q: np.ndarray) -> np.ndarray:
    """Which configurations can be measured: the tool point above the mounting plane (z > 0 in
    the robot base frame, a crude stand-in for collision checks) and, for the cable sensor, the
    nominal reading inside the range by :data:`RANGE_MARGIN`."""
    ok = r.fkine(q, tool=True)[:, 2, 3] > 0.0
    if measurement == "cable":
        L = r.predict("cable", q)[:, 0]
        ok &= (L > CABLE_RANGE[0] + RANGE_MARGIN) & (L < CABLE_RANGE[1] - RANGE_MARGIN)
    return ok


def _reflect(q: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``q`` folded back into ``[lo, hi]`` at the limits (a mirror at each end)."""
    width = hi - lo
    u = np.mod(q - lo, 2.0 * width)
    return lo + width - np.abs(u - width)


def acquisition_path(r: Robot, measurement: str, samples: int, rng: np.random.Generator, step_deg: float = STEP_DEG) -> np.ndarray:
    """Joint configurations along a plausible acquisition path.

    A random walk: the first configuration is drawn uniformly within the joint limits, each next
    one is the previous plus a normal step (``step_deg`` per joint), mirrored at the limits. A
    candidate that cannot be measured (:func:`_valid`) is re-drawn, so the path has exactly
    ``samples`` rows.

    Returns
    -------
    ndarray, shape (samples, N)
        Joint values in rad (mm for prismatic joints).
    """
    lo, hi = np.array([j.limits for j in r.joints]).T
    # A prismatic joint (mm) steps the same share of its range as a revolute one of a turn: a step of
    # radians(5) mm moved a SCARA's 200 mm axis over 5 mm in 500 samples, and its parameters went undetermined.
    step = np.array([math.radians(step_deg) if j.kind == "revolute" else step_deg / 360.0 * (h - l) for j, l, h in zip(r.joints, lo, hi)])
    q = np.empty((samples, r.n_joints))
    for i in range(samples):
        for _ in range(ROUNDS):
            if i == 0:
                candidates = rng.uniform(lo, hi, (CANDIDATES, r.n_joints))
            else:
                candidates = _reflect(q[i - 1] + rng.normal(0.0, 1.0, (CANDIDATES, r.n_joints)) * step, lo, hi)
            ok = np.flatnonzero(_valid(r, measurement, candidates))
            if ok.size:
                q[i] = candidates[ok[0]]
                break
        else:
            raise InvalidParameterError(
                f"no measurable configuration found near sample {i} of the path of {r.name} ({measurement}); "
                "the sensor placement leaves too little of the workspace in range"
            )
    return q


def _checked_poses(r: Robot, poses) -> np.ndarray:
    """``poses`` as joint values (m, N) within ``r``'s limits, or an error naming the first that is not."""
    q = as_float_array(poses, "poses")
    if q.ndim != 2 or q.shape[1] != r.n_joints or not len(q):
        raise InvalidParameterError(f"`poses` must have shape (m, {r.n_joints}) with m >= 1; got {q.shape}")
    lo, hi = np.array([j.limits for j in r.joints]).T
    bad = np.argwhere(~np.isfinite(q) | (q < lo) | (q > hi))
    if bad.size:
        i, j = bad[0]
        raise InvalidParameterError(f"`poses`: pose {i} joint {j + 1} is {q[i, j]:.6g}, outside the joint's limits {lo[j]:.6g}..{hi[j]:.6g}")
    return q


def geometric_errors(r: Robot, measurement: str, q: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Random geometric errors on the identifiable subset of the default mask.

    Lengths get N(0, :data:`LENGTH_ERROR_MM`) mm, angles N(0, :data:`ANGLE_ERROR_DEG`) deg.
    Every parameter's error is drawn, in parameter order, whether it is kept or not: a parameter's
    error does not depend on which others the sensor identifies or on the order a factorisation
    finds them in. Parameters redundant with others on these configurations (e.g. ``theta1`` and
    ``base_rz``) keep their nominal values, so that the truth is unique.

    Returns
    -------
    errors : ndarray, shape (P,)
    perturbed : ndarray of int
        Indices of the perturbed parameters.
    """
    cols = np.flatnonzero(r.default_mask(measurement))
    J = r.jacobian(measurement, q, y=r.predict(measurement, q), cols=cols)
    perturbed = cols[r.identifiability(measurement, J, cols)["identifiable"]]
    drawn = rng.normal(0.0, 1.0, r.n_params) * np.where(np.array(r.param_units) == "mm", LENGTH_ERROR_MM, math.radians(ANGLE_ERROR_DEG))
    errors = np.zeros(r.n_params)
    errors[perturbed] = drawn[perturbed]
    return errors, np.sort(perturbed)


def _predict(r: Robot, measurement: str, q: np.ndarray, params: np.ndarray) -> np.ndarray:
    """Predictions with one parameter vector per sample (one call when they are all equal)."""
    if np.all(params == params[0]):
        return r.predict(measurement, q, params[0])
    return np.vstack([r.predict(measurement, q[i : i + 1], params[i]) for i in range(len(q))])


def _add_noise(measurement: str, y: np.ndarray, noise: SensorNoise, rng: np.random.Generator) -> np.ndarray:
    y = y.copy()
    width = 1 if measurement == "cable" else 3
    y[:, :width] += rng.normal(0.0, 1.0, (len(y), width)) * noise.sigma
    if measurement == "pose" and noise.sigma_rotation > 0:
        phi = rng.normal(0.0, 1.0, (len(y), 3)) * noise.sigma_rotation
        y[:, 3:] = quaternion_from_matrix(so3_exp(phi) @ matrix_from_quaternion(y[:, 3:]))
    return y


def _quantise(measurement: str, y: np.ndarray, resolution: float) -> np.ndarray:
    if resolution == 0:
        return y
    y = y.copy()
    width = 1 if measurement == "cable" else 3
    y[:, :width] = np.round(np.round(y[:, :width] / resolution) * resolution, 9)
    return y


def _quantity(value: float, unit: str) -> dict:
    return {"value": value, "unit": unit}


#: Standard deviation (mm per axis) of where a tracker stands in another session.
SESSION_SHIFT_MM = 200.0


def simulate(
    robot: Union[str, Robot] = "hsr-jr680",
    measurement: str = "cable",
    *,
    samples: int = TRUTH_PATH_SAMPLES,
    seed: int = 1,
    effects: Sequence[Union[str, Effect]] = (),
    noise=None,
    geometric_error: bool = True,
    outliers: float = 0.0,
    dt: float = 2.0,
    tool: Optional[Sequence[float]] = None,
    anchor: Optional[Sequence[float]] = None,
    session: int = 0,
    poses=None,
) -> tuple[Dataset, dict]:
    """Simulates an acquisition of ``robot`` with known ground truth.

    Parameters
    ----------
    robot : str or Robot
        A built-in robot name, a robot file, or a :class:`Robot`.
    measurement : {"cable", "position", "pose"}
    samples : int
        Number of samples (exactly).
    seed : int
        Seed of every random draw; equal seeds give equal simulations. The path, the geometric
        errors, the noise and the effects draw from independent streams, so adding an effect
        leaves the rest unchanged.
    effects : sequence of str or Effect
        Non-geometric effects, as specs ``KIND[:key=value,...]`` (see :mod:`robocal.effects`).
    noise : None, float, mapping or SensorNoise
        Sensor noise (see :func:`sensor_noise`); ``0`` for none.
    geometric_error : bool
        Perturb the nominal geometry (else the true robot is the nominal one).
    outliers : float
        Fraction of gross outliers (shorthand for the effect ``outliers:fraction=...``).
    dt : float
        Time per sample in s.
    tool : (3,) float, optional
        The measured point on the flange in mm (default :data:`DEFAULT_TOOL`).
    anchor : (3,) float, optional
        Cable anchor in mm (default: see :func:`setup`).
    session : int
        ``0``: the acquisition of ``seed``. ``s > 0``: the same robot (the kinematic errors of
        session 0, whatever the ``samples`` of either; the same draws of the effects) measured in
        another session: a new path and noise, and the set-up (base, tool, anchor, zero errors)
        drawn anew. One seed's errors are drawn for every parameter and kept where the kind of
        sensor identifies them (:func:`geometric_errors`): a position and a pose simulation of one
        seed are one robot up to what the position sensor cannot see (the tool's orientation); a
        cable keeps fewer (those redundant with its anchor and zero stay nominal).
    poses : array_like, shape (m, N), optional
        Joint values (rad; mm for prismatic joints) to measure at, in this order, instead of a
        random path — a plan of :func:`robocal.planning.plan`, say. The true robot is still drawn
        on the seed's path (its first :data:`TRUTH_PATH_SAMPLES` configurations, as for any
        ``samples``), so that one seed is one robot whatever the poses and the sample count: two
        plans compare on it.

    Returns
    -------
    dataset : Dataset
        Recorded joint values ``q`` (rad), observations, ``t`` (s) and, with a temperature
        effect, ``temp`` (deg C).
    truth : dict
        The ground truth (JSON-serialisable): true and nominal parameters, noise, effects and
        what they did, outlier rows.

    Examples
    --------
    >>> data, truth = simulate("ur10", "position", samples=50, effects=["backlash:joint=2"])
    >>> len(data), truth["effects"][0]["kind"]
    (50, 'backlash')
    """
    if measurement not in MEASUREMENTS:
        raise InvalidParameterError(f"`measurement` must be one of {MEASUREMENTS}; got {measurement!r}")
    samples = as_count(samples, "samples", least=1, most=MAX_SAMPLES)
    dt = as_positive(dt, "dt")  # s
    if not 0.0 <= as_float(outliers, "outliers") <= 1.0:
        raise InvalidParameterError(f"`outliers` must be a fraction within 0..1; got {outliers!r}")
    if isinstance(effects, (str, Effect)) or not isinstance(effects, Iterable):
        raise InvalidParameterError(f"`effects` must be a list of effect specs or Effects; got {effects!r}")
    base = robot if isinstance(robot, Robot) else load_robot(robot)
    nominal = setup(base, measurement, tool, anchor)
    chosen = [e if isinstance(e, Effect) else parse_effect(e) for e in effects]
    if outliers > 0:
        chosen.append(EFFECTS["outliers"](fraction=outliers))
    for effect in chosen:
        effect.check(nominal, measurement)
    if sum(e.kind == "temperature" for e in chosen) > 1:
        raise InvalidParameterError("at most one temperature effect: the dataset has one temperature column")
    noise = sensor_noise(measurement, noise)
    session = as_count(session, "session", least=0)
    seeds = np.random.SeedSequence(check_seed(seed))  # seed=None draws fresh entropy, recorded in the truth
    rng_path, rng_errors, rng_noise, rng_effects = (np.random.default_rng(s) for s in seeds.spawn(4))

    # One walk, long enough for both: a path's first rows do not depend on its length.
    walk = acquisition_path(nominal, measurement, max(int(samples), TRUTH_PATH_SAMPLES), rng_path)
    q = walk[: int(samples)]
    errors, perturbed = (
        geometric_errors(nominal, measurement, walk[:TRUTH_PATH_SAMPLES], rng_errors) if geometric_error else (np.zeros(nominal.n_params), np.array([], int))
    )
    if session:
        rng_path, rng_noise, rng_setup = (np.random.default_rng(s) for s in np.random.SeedSequence([seeds.entropy, session]).spawn(3))
        q = acquisition_path(nominal, measurement, int(samples), rng_path)
        setup_errors, _ = geometric_errors(nominal, measurement, q, rng_setup) if geometric_error else (errors, None)
        placed = [nominal.index(name) for name in setup_names(nominal, measurement)]
        errors[placed] = setup_errors[placed]
        if measurement != "cable":  # the tracker stands elsewhere: a translation of SESSION_SHIFT_MM per axis
            errors[[nominal.index(f"base_{c}") for c in "xyz"]] += rng_setup.normal(0.0, SESSION_SHIFT_MM, 3)
    if poses is not None:
        q = _checked_poses(nominal, poses)
    t = dt * np.arange(len(q))
    true = nominal.params + errors
    acq = Acquisition(nominal, measurement, q, t, np.tile(true, (len(q), 1)), np.zeros_like(q), rng_effects)
    for effect in chosen:
        effect.prepare(acq)
    stages = ("parameters", "joints", "observations")
    magnitudes = [None] * len(chosen)
    for k in sorted(range(len(chosen)), key=lambda k: stages.index(chosen[k].stage)):
        if chosen[k].stage == "observations" and acq.y is None:
            acq.y = _add_noise(measurement, _predict(nominal, measurement, q + acq.dq, acq.params), noise, rng_noise)
        magnitudes[k] = chosen[k].apply(acq)
    if acq.y is None:
        acq.y = _add_noise(measurement, _predict(nominal, measurement, q + acq.dq, acq.params), noise, rng_noise)
    y = _quantise(measurement, acq.y, noise.resolution)
    if measurement == "cable":
        outside = np.flatnonzero((y[:, 0] < CABLE_RANGE[0]) | (y[:, 0] > CABLE_RANGE[1]))
        if outside.size:
            raise InvalidParameterError(
                f"{outside.size} simulated readings fall outside the {CABLE_SENSOR} range {CABLE_RANGE[0]:g}..{CABLE_RANGE[1]:g} mm "
                f"(e.g. sample {outside[0]}: {y[outside[0], 0]:.3f} mm) with the effects {[e.spec for e in chosen]} "
                f"and noise sigma {noise.sigma:g} mm"
            )

    note = f"simulated by robocal.simulation (seed {seeds.entropy})"
    dataset = Dataset(q=q, y=y, measurement=measurement, robot=base.name, t=t, temp=acq.temp, prismatic=base.prismatic, notes=[note])
    records = [effect.record(magnitude) for effect, magnitude in zip(chosen, magnitudes)]
    outlier_samples = sorted({i for rec in records for i in rec.get("samples", [])})
    truth = {
        "robot": base.name,
        "measurement": measurement,
        "seed": int(seeds.entropy),
        "session": session,
        "samples": len(q),
        "dt": _quantity(dt, "s"),
        "parameters": {
            name: {"value": float(v), "nominal": float(v0), "unit": unit}
            for name, v, v0, unit in zip(nominal.param_names, acq.params[0], nominal.params, nominal.param_units)
        },
        "perturbed": [nominal.param_names[i] for i in perturbed],
        "geometric_error": {"lengths": _quantity(LENGTH_ERROR_MM, "mm"), "angles": _quantity(ANGLE_ERROR_DEG, "deg")} if geometric_error else None,
        "sensor": {"name": CABLE_SENSOR, "range": _quantity(list(CABLE_RANGE), "mm")} if measurement == "cable" else {"name": "laser tracker"},
        "noise": {
            "sigma": _quantity(noise.sigma, "mm"),
            "sigma_rotation": _quantity(noise.sigma_rotation, "rad"),
            "resolution": _quantity(noise.resolution, "mm"),
        },
        "effects": records,
        "outliers": [{"sample": i, "row": int(dataset.rows[i])} for i in outlier_samples],
    }
    return dataset, truth


def true_params(truth: Mapping, r: Robot) -> np.ndarray:
    """The true parameter vector (mm, rad) of a simulation's truth, in ``r``'s order.

    With a ``temperature`` effect on the links these are the values at its start temperature.
    """
    table = truth["parameters"]
    missing = [n for n in r.param_names if n not in table]
    if missing:
        raise InvalidParameterError(f"the truth lacks parameters {missing} of robot {r.name!r}")
    return np.array([table[n]["value"] for n in r.param_names])


def write_simulation(dataset: Dataset, truth: Mapping, out_csv, truth_json=None) -> tuple[Path, Optional[Path]]:
    """Writes the dataset as a canonical CSV (joint angles in deg) and, if asked, the truth as
    JSON; returns both paths."""
    # Both staged before either is renamed: a bad truth path leaves no CSV behind.
    check_outputs(files=[out_csv, truth_json])
    with Staged(out_csv) as data_stage, Staged(truth_json) if truth_json is not None else nullcontext() as truth_stage:
        with data_stage.writing():  # two stages open: each write names its own file if it fails
            write_canonical(dataset, data_stage.tmp)
        if truth_stage is not None:
            with truth_stage.writing():
                truth_stage.tmp.write_text(json.dumps(truth, indent=2) + "\n")
    return Path(out_csv), None if truth_json is None else Path(truth_json)
