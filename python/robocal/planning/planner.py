"""The entry, :func:`plan`: it draws the candidates within the cell (:mod:`~robocal.planning.constraints`),
linearises the model a calibration will fit on them (:mod:`~robocal.planning.design`), adds what the data and a
result already know (:mod:`~robocal.planning.prior`), requires a joint map's coverage
(:mod:`~robocal.planning.coverage`), chooses the poses by the criterion (:mod:`~robocal.planning.criteria`), orders
them (:mod:`~robocal.planning.order`) and states what they buy (:mod:`~robocal.planning.uncertainty`): the report of
its :class:`Plan`.

A model of more than :data:`LARGE_MODEL` entries is planned among :data:`WORKING` of the candidates drawn at random
(each exchange step reads every candidate's rows); the report's ``model`` says what is counted and what is known
before."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Optional, Sequence, Union

import numpy as np
from threadpoolctl import threadpool_limits

from ..calibration.api import another_robot, load_inputs
from ..calibration.problem import TOLERANCE, start_parameters
from ..calibration.sessions import SESSION_KINDS, concatenate
from ..causes import structure
from ..causes.extended import read_causes
from ..data.formats.canonical import write_canonical
from ..data.dataset import Dataset
from ..exceptions import DataError, InvalidParameterError
from ..kernels import as_count, as_positive, seeded_rng
from ..outputs import Staged
from ..physics import DEG
from ..results import file_sha256, load_result
from ..robot import MEASUREMENTS, RESIDUAL_WIDTH, Robot, setup_names, zero_names
from ..robot import robot as load_robot
from ..sensors import DEFAULT_NOISE
from ..simulation import CABLE_RANGE
from .constraints import CANDIDATES, NOT_CHECKED, Constraints, _checked_setup, _ranges, candidate_poses
from .coverage import _required
from .criteria import (
    BOUND_ITERATIONS,
    CRITERIA,
    RIDGE,
    _information,
    d_optimal,
    ds_optimal,
    i_bound,
    i_optimal,
    workspace_weights,
)
from .design import _Design, _design, _zero_design, _ZeroDesign, with_result_error
from .order import _per_degree, _tour, default_passes, measuring_order, order_correlations, travel
from .prior import _Known, _result_information, _result_mask, _training_sessions
from .uncertainty import _cause_std, _shown, _Uncertainty

SCHEMA = "robocal.plan/1"
#: Upper bounds of ``poses`` and ``candidates``, checked before any work: the design holds every
#: candidate's rows (100 000 pose candidates: about 1 GB and half a minute), and the exchange's
#: time grows with poses × candidates (1 000 poses among 10 000 candidates: five minutes). A
#: measuring campaign of more than a few hundred poses is several sessions, each planned anew.
MAX_POSES = 500
MAX_CANDIDATES = 100_000
#: A model of more entries than this is planned among :data:`WORKING` of the candidates (:func:`_working`).
LARGE_MODEL = 200
WORKING = 2000
#: Iterations of :func:`~robocal.planning.criteria.i_bound` for a model of more than :data:`LARGE_MODEL` entries: each
#: iteration reads every candidate's rows thrice.
LARGE_BOUND_ITERATIONS = 20
#: Causes whose columns depend on the pose alone: the poses can determine them.
POSE_KINDS = ("joint_compliance", "joint_periodic", "joint_scale", "joint_coupling", "joint_map", "cable_scale", "axis_misalignment", "frame")


def _working(entries: int, candidates: int, poses: int, rng: np.random.Generator, notes: list) -> np.ndarray:
    """The candidates the design is chosen among: all of them, or for a model of more than
    :data:`LARGE_MODEL` entries (a result's joint maps) :data:`WORKING` (at least 11 per pose)
    drawn at random from them, and a note. Each exchange step reads every candidate's rows, a
    time ∝ entries: 700 entries over 10 000 candidates took minutes."""
    size = max(WORKING, 11 * poses)
    if entries <= LARGE_MODEL or candidates <= size:
        return np.arange(candidates)
    notes.append(
        f"the model has {entries} entries: the poses are chosen among {size:,} of the {candidates:,} candidates, drawn at random "
        "(the random poses compared with and the workspace are drawn from all of them)"
    )
    return np.sort(rng.choice(candidates, size=size, replace=False))


@dataclass
class Plan:
    """A measurement plan.

    Attributes
    ----------
    q : ndarray, shape (N, n_joints)
        The poses in the order to measure them: the controller's joint readings, rad (mm for
        prismatic joints).
    expected : Dataset
        The same poses with the readings the model expects there (cable length, or the tool
        point in the tracker's frame): what :meth:`write` puts in the observation columns.
    report : dict
        What the plan buys (see :func:`plan`); :meth:`to_dict` is it as JSON.
    """

    q: np.ndarray
    expected: Dataset
    report: dict

    def to_dict(self) -> dict:
        return self.report

    def write(self, path) -> Path:
        """The plan as a canonical CSV (joint columns in degrees, measuring order); the
        observation columns hold the expected readings — overwrite them with the measured ones."""
        with Staged(path) as stage:
            write_canonical(self.expected, stage.tmp)
        return Path(path)


def _sources(robot, measurement, result, causes, data, angle_unit):
    """The robot, the measurement, the parameters a result gives (or None), the cause labels,
    the reading conventions, the measured data (in the model's angles, or None) and the result's
    document (or None)."""
    params, labels, doc = None, [], None
    if result is not None:
        calibrated, doc = load_result(result)
        named = None if robot is None else (robot if isinstance(robot, Robot) else load_robot(robot)).name
        if named not in (None, calibrated.name):
            raise InvalidParameterError(f"the result is a calibration of {calibrated.name}, not of {named}")
        robot, params = calibrated, calibrated.params.copy()
        if measurement is not None and measurement != doc["measurement"]:
            raise InvalidParameterError(f"the result is a {doc['measurement']} calibration; the plan is for {measurement} measurements")
        measurement = doc["measurement"]
        labels = list(doc.get("structure", [])) + [c.get("label", c.get("kind")) for c in doc.get("causes", [])]
    datasets = []
    for d in [] if data is None else ([data] if isinstance(data, (str, Path, Dataset)) else list(data)):
        dataset, robot = load_inputs(d, robot, measurement, angle_unit)
        measurement = dataset.measurement
        datasets.append(dataset)
    if robot is None:
        raise InvalidParameterError("no robot: pass `robot`, a result or data that name it")
    robot = robot if isinstance(robot, Robot) else load_robot(robot)
    if causes is not None:
        labels += read_causes(causes, robot.name)[0]
    if measurement is None:
        raise InvalidParameterError(f"no measurement: pass `measurement`, one of {MEASUREMENTS}")
    if measurement not in MEASUREMENTS:
        raise InvalidParameterError(f"`measurement` must be one of {MEASUREMENTS}; got {measurement!r}")
    structures = [s for s in (structure.parse(label, robot.n_joints) for label in labels) if s is not None]
    datasets = [structure.apply_all(d, structures) for d in datasets]
    return robot, measurement, params, labels, structures, datasets, doc


def _check_setups(robot: Robot, datasets: list[Dataset], params: np.ndarray) -> None:
    """An error when the data files were measured with the sensor in different places: the plan
    continues one session."""
    if len(datasets) < 2:
        return
    names = setup_names(robot, datasets[0].measurement)
    cols = [robot.index(n) for n in names]
    fits = [start_parameters(robot, d, params)[cols] for d in datasets]
    units = np.array([robot.param_units[c] for c in cols])
    limit = np.where(units == "rad", math.radians(1.0), 10.0)
    for d, fit in zip(datasets[1:], fits[1:]):
        far = np.flatnonzero(np.abs(fit - fits[0]) > limit)
        if far.size:
            c = far[0]
            f, unit = (1 / DEG, "deg") if units[c] == "rad" else (1.0, units[c])
            raise InvalidParameterError(
                f"{datasets[0].source or 'data 1'} and {d.source or 'the other data'} were measured with the sensor in different places "
                f"({names[c]} {fits[0][c] * f:.4g} vs {fit[c] * f:.4g} {unit}): a plan continues one session — pass the files of one set-up"
            )


@threadpool_limits.wrap(limits=1, user_api="blas")  # see criteria.d_optimal: two BLAS threads on a loaded 2-core machine ran an eigh 15x slower
def plan(
    robot: Union[str, Robot, None] = None,
    measurement: Optional[str] = None,
    poses: int = 40,
    *,
    result=None,
    causes=None,
    data=None,
    candidates: int = CANDIDATES,
    seed: int = 0,
    joint_ranges: Optional[Mapping] = None,
    cable_range: Sequence[float] = CABLE_RANGE,
    anchor: Optional[Sequence[float]] = None,
    tool: Optional[Sequence[float]] = None,
    tracker: Optional[Sequence[float]] = None,
    tracker_range: Optional[Sequence[float]] = None,
    box: Optional[Sequence[float]] = None,
    noise: Optional[float] = None,
    passes: Optional[int] = None,
    angle_unit: Optional[str] = None,
    criterion: str = "I",
    bound: bool = False,
) -> Plan:
    """Chooses ``poses`` joint configurations, and the order to measure them in, that determine
    the model's parameters best (see :mod:`robocal.planning`).

    Parameters
    ----------
    robot : str or Robot, optional
        Default: the result's, or the one the data name.
    measurement : {"cable", "position", "pose"}, optional
        Default: the result's or the data's.
    poses : int
        How many poses to plan, at most :data:`MAX_POSES`.
    result : path or dict, optional
        A calibration result: the plan is linearised at its calibrated robot and set-up (the
        cable's anchor, the tracker's frame), its model has the result's entries (its joint maps on
        their fitted ranges) and a new session's set-up, and what the result's training data
        measured is the prior (:mod:`robocal.planning.prior`; files gone or changed: a note, no prior).
    causes : list of str, dict or path, optional
        Causes the model will include: labels as ``robocal diagnose`` prints them, or a diagnose
        report (dict or JSON file). Causes acting on the joints and parameters shape the poses
        (a joint map also asks for a pose every ``spacing`` along its joint's range); causes in
        time (drift, steps, a wander) are met by the order; backlash depends on the direction
        each pose is approached from, which the plan does not choose. Reading conventions
        (``joint_zero``, ...) convert the readings to the model's angles.
    data : path, Dataset or list of them, optional
        What is already measured, with the sensor where it still is (one set-up, fitted on them):
        the plan adds the poses that best determine what these leave open.
    candidates : int
        Candidate poses drawn within the constraints: at least ``poses``, at most :data:`MAX_CANDIDATES`.
    seed : int
        Seeds the candidates, the workspace sample and the random poses compared with.
    joint_ranges : mapping, optional
        ``1-based joint -> (lower, upper)``, rad (mm for prismatic joints), in the controller's
        readings: narrows the robot's joint limits.
    cable_range : (float, float)
        The cable sensor's reading range, mm; readings are kept 25 mm inside it.
    anchor : (3,) float, optional
        The cable's anchor in the robot's base frame, mm (default: the result's, the one fitted
        on the data, else the simulator's placement, :func:`robocal.simulation.setup`).
    tool : (3,) float, optional
        The measured point on the flange, mm (default: the result's, the data's, else the
        simulator's).
    tracker : (3,) float, optional
        The laser tracker's position in the robot's base frame, mm: the tool point must lie
        ``tracker_range`` from it.
    tracker_range : (float, float), optional
        Distances (mm) the tracker measures at (default :data:`TRACKER_RANGE`).
    box : (6,) float, optional
        ``(xmin, xmax, ymin, ymax, zmin, zmax)`` mm in the robot's base frame that the tool point
        must stay in (default: above the mounting plane, ``z > 0``).
    noise : float, optional
        The reading's standard deviation, mm (default: the sensor's, :data:`robocal.sensors.DEFAULT_NOISE`).
    passes : int, optional
        Interleaved passes over the workspace (default :func:`default_passes`).
    angle_unit : {"deg", "rad"}, optional
        Unit of the joint columns of canonical ``data`` files.
    criterion : {"I", "D", "Ds"}
        ``"I"`` (default): the I-optimal design, the least average variance of a new session's
        readings over the workspace (the set-up re-fitted), started from the D-optimal one;
        ``"D"``: the D-optimal design, the least volume of the parameters' confidence ellipsoid;
        ``"Ds"``: the poses of a re-mastering (``robocal calibrate NEW --prior RESULT``), the least
        volume of the joints' zero offsets' confidence ellipsoid with a new session's set-up fitted
        anew and the rest of the robot held (:func:`~robocal.planning.criteria.ds_optimal`).
    bound : bool
        Also state the least predicted error any ``poses`` poses among the candidates could reach
        (``prediction["least_possible"]``, :func:`i_bound`; seconds more).

    Returns
    -------
    Plan
        Its ``report`` (JSON): ``parameters`` (each estimated parameter's standard deviation
        ``before`` — from ``data`` alone —, ``after`` and with as many ``random`` poses within the
        same constraints; mm or deg; None where undetermined; ``within_tolerance`` of 1 mm /
        0.1°), ``causes`` (the same for the causes' physical quantities), ``position`` (the
        predicted tool point's standard deviation over the workspace: RMS and largest, mm),
        ``d_efficiency_random`` (what a random pose is worth against a planned one),
        ``prediction`` (the predicted RMS error of a new session's readings over the workspace,
        the set-up re-fitted, mm: ``before``, ``after``, ``random``; None where undetermined), ``order``
        (``passes``, ``travel_deg`` beside a single tour's and a random order's, each joint's
        ``correlation`` with the acquisition order), ``constraints`` and ``not_checked``,
        ``fixed`` (parameters left out, and why), ``model`` (what is counted: ``entries``,
        ``robot_parameters``, ``cause_coefficients``, ``setup``, each joint map's ``coefficients``,
        ``range_deg``, ``gaps_deg`` and ``range_from``; ``known_before``), ``causes_not_by_poses``
        ``zeros`` (criterion ``"Ds"``, else None: per joint the standard deviation of its zero's change
        a re-mastering would have on the planned and on random poses, ``after`` and ``random``, deg or
        mm, None with ``absorbed_by`` the set-up entries where no pose tells it from the set-up) and ``notes``.
    """
    poses = as_count(poses, "poses", least=1, most=MAX_POSES)  # before any file is read
    candidates = as_count(candidates, "candidates", least=poses, most=MAX_CANDIDATES)
    robot, measurement, params, labels, structures, datasets, doc = _sources(robot, measurement, result, causes, data, angle_unit)
    kinds = [label.split()[0] if label.strip() else "" for label in labels]
    unknown = [label for label, kind in zip(labels, kinds) if kind not in POSE_KINDS + SESSION_KINDS + structure.KINDS + ("backlash",)]
    if unknown:
        raise InvalidParameterError(f"unknown causes {unknown}: a cause is a label as robocal diagnose prints it (e.g. 'joint_compliance joint 2')")
    if criterion not in CRITERIA:
        raise InvalidParameterError(f"`criterion` must be one of {sorted(CRITERIA)}; got {criterion!r}")
    setup, per_pose = setup_names(robot, measurement), RESIDUAL_WIDTH[measurement]
    if criterion == "Ds" and poses * per_pose <= len(setup):  # the re-mastering would refuse them; their stds were the ridge's
        raise InvalidParameterError(
            f"{poses} poses give {poses * per_pose} readings: a re-mastering fits the new session's set-up ({len(setup)} parameters) "
            f"on them and needs more; plan at least {len(setup) // per_pose + 1} poses"
        )
    rng = seeded_rng(seed)
    sigma = DEFAULT_NOISE[measurement].sigma if noise is None else as_positive(noise, "noise")
    passes = default_passes(poses) if passes is None else as_count(passes, "passes", least=1, most=poses)
    lower, upper = _ranges(robot, joint_ranges, structures)
    params, (cable, tracker, distances, box) = _checked_setup(
        robot, measurement, params, tool, anchor, tracker, tracker_range, box, cable_range, bool(datasets)
    )
    measured = None
    if datasets:
        _check_setups(robot, datasets, params)
        measured = concatenate(datasets) if len(datasets) > 1 else datasets[0]
        params = start_parameters(robot, measured, params)
        wrong = another_robot(robot, measured)  # else the set-up fits another robot's data and the figures look like noise
        if wrong:
            raise DataError(wrong, measured.source)
    constraints = Constraints(lower, upper, cable, tracker, distances, box)
    readings, notes = candidate_poses(robot, measurement, params, constraints, structures, candidates, rng, least=poses)
    pool = structure.to_model(readings, structures)

    used = [label for label, kind in zip(labels, kinds) if kind in POSE_KINDS]
    fitted = {c["label"]: c["detail"] for c in ([] if doc is None else doc.get("causes", [])) if c.get("kind") == "joint_map" and c.get("label") in used}
    design = _design(robot, measurement, params, measured, pool, used, sigma, rng, fitted, None if doc is None else _result_mask(doc, robot, measurement))
    known = None if doc is None else _result_information(doc, robot, params, design, structures, sigma, angle_unit)
    if known is not None and known.why:
        notes.append(known.why)
    trained = {s.get("sha256") for s in _training_sessions(doc)} - {None} if doc is not None else set()
    twice = [d.source for d in datasets if d.source and file_sha256(d.source) in trained]
    if twice:
        notes.append(f"{twice[0]} is the result's training data and the data measured with the sensor in place: its information is counted twice")
    from_result = known is not None and known.M is not None
    before_info = design.M_data + design.M_prior + (known.M if from_result else 0.0)
    start = before_info + RIDGE * np.eye(len(design.names))
    seen = [] if measured is None else [measured.q]
    seen += [known.q] if from_result else []
    work = _working(len(design.names), len(pool), poses, rng, notes)
    A = design.A[work]  # the candidates the design is chosen among
    required = _required(design, A, pool[work], np.vstack(seen) if seen else None, start, poses, notes)
    if measured is None and not from_result and poses * per_pose <= len(design.names):
        notes.append(f"{poses} poses give {poses * per_pose} readings for {len(design.names)} parameters: too few to determine them all")
    weights = workspace_weights(design.A, design.names, setup)
    zeros = _zero_design(robot, measurement, params, pool) if criterion == "Ds" else None
    if zeros is not None and from_result:
        zeros = with_result_error(zeros, design, known.M)
    if zeros is not None:  # the re-mastering's model: the set-up and the zeros, the rest of the robot held at the result's values
        chosen = ds_optimal(zeros.A[work], zeros.M0, poses, zeros.of, required=required)
    else:
        chosen = d_optimal(A, start, poses, required=required)
    if criterion == "I":
        chosen = i_optimal(A, start, weights, poses, required=required, start=chosen)
    chosen = work[chosen]
    chosen = chosen[measuring_order(readings[chosen] / _per_degree(robot), passes)]
    planned = readings[chosen]
    random_pick = rng.choice(len(pool), size=poses, replace=False)

    picks = {"before": [], "after": chosen, "random": random_pick}
    states = {key: _Uncertainty.of(design, before_info + _information(design.A[idx]), sigma, weights) for key, idx in picks.items()}
    entries = []
    for i, (name, unit) in enumerate(zip(design.names, design.units)):
        if unit is not None:
            std = {key: _shown(u.std([i]), unit) for key, u in states.items()}
            within = None if std["after"] is None or unit not in TOLERANCE else bool(states["after"].std([i])[0] <= TOLERANCE[unit])
            entries.append({"name": name, "unit": "deg" if unit == "rad" else unit, **std, "within_tolerance": within})
    cause_std = {key: _cause_std(design, u, robot) for key, u in states.items()}
    prediction = {key: u.prediction for key, u in states.items()}
    if bound:
        iterations = BOUND_ITERATIONS if len(design.names) <= LARGE_MODEL else LARGE_BOUND_ITERATIONS
        if iterations < BOUND_ITERATIONS:
            notes.append(f"the least possible error is bounded after {iterations} iterations (a model of {len(design.names)} entries): a valid, looser bound")
        prediction["least_possible"] = float(sigma * math.sqrt(max(i_bound(A, start, weights, poses, iterations), 0.0)))
    shown_causes = [c for c in design.causes if c.stage != "parameters"]
    in_degrees = planned / _per_degree(robot)
    report = {
        "schema": SCHEMA,
        "robot": robot.name,
        "measurement": measurement,
        "poses": poses,
        "candidates": len(pool),
        "noise_mm": sigma,
        "criterion": CRITERIA[criterion],
        "parameters": entries,
        "tolerance": {"mm": TOLERANCE["mm"], "deg": float(TOLERANCE["rad"] / DEG), "beyond": [e["name"] for e in entries if e["within_tolerance"] is False]},
        "causes": [{"label": c.label, **{key: cause_std[key][n] for key in states}} for n, c in enumerate(shown_causes)],
        "undetermined": {key: u.undetermined for key, u in states.items()},
        "position": {key: u.position_summary() for key, u in states.items()},
        "d_efficiency_random": float(np.exp((states["random"].logdet - states["after"].logdet) / len(design.names))),
        "prediction": prediction,
        "order": {
            "passes": passes,
            "travel_deg": travel(in_degrees),
            "travel_single_tour_deg": travel(in_degrees[_tour(in_degrees)]),
            "travel_random_order_deg": travel(in_degrees[rng.permutation(poses)]),
            "correlation": order_correlations(planned),
        },
        "constraints": constraints.describe(robot, measurement, params, structures),
        "not_checked": list(NOT_CHECKED),
        "fixed": design.fixed,
        "model": _counted(design, robot, measurement, known, measured),
        "structure": [s.label for s in structures],
        "causes_not_by_poses": [{"label": label, "reason": _why_not(kind)} for label, kind in zip(labels, kinds) if kind not in POSE_KINDS + structure.KINDS],
        "data": {"samples": 0 if measured is None else len(measured), "files": [d.source for d in datasets]},
        "zeros": None if zeros is None else _zeros_report(zeros, robot, sigma, picks),
        "notes": notes,
    }
    expected_readings = robot.predict(measurement, pool[chosen], params)
    note = "a measurement plan: the observation columns hold the readings the model expects"
    expected = Dataset(q=planned, y=expected_readings, measurement=measurement, robot=robot.name, prismatic=robot.prismatic, notes=[note])
    return Plan(q=planned, expected=expected, report=report)


def _counted(design: _Design, robot: Robot, measurement: str, known: Optional[_Known], measured: Optional[Dataset]) -> dict:
    """What the plan counts (the report's ``model``): its entries — the robot's (parameters,
    causes' coefficients; each joint map's coefficients over its range, and where that range
    comes from) and the new session's set-up — and what is known before the poses."""
    setup = [n for n in design.names if n in setup_names(robot, measurement)]
    maps = [
        {
            "label": c.label,
            "coefficients": c.size,
            "range_deg": [float(c.detail["lo"]), float(c.detail["hi"])],
            "gaps_deg": [list(g) for g in c.detail.get("gaps", [])],
            "range_from": "the result's fit" if c.label in design.fitted else "the candidates' (and the data's) angles",
        }
        for c in design.causes
        if c.kind == "joint_map"
    ]
    causes = sum(c.size for c in design.causes if c.stage != "parameters")
    before = []
    if known is not None and known.M is not None:
        before.append(
            f"the result's {known.samples:,} training samples re-linearised, each of its sessions' set-up and sensor terms eliminated, "
            f"weighed by its training residual ({known.noise:.3g} mm per reading)"
        )
    if measured is not None:
        before.append(f"the {len(measured):,} samples measured with the sensor in place")
    if any(c.penalty is not None for c in design.causes):
        before.append("the joint maps' roughness")
    return {
        "entries": len(design.names),
        "robot_parameters": len(design.names) - len(setup) - causes,
        "cause_coefficients": causes,
        "setup": setup,
        "maps": maps,
        "known_before": before,
    }


def _zeros_report(zeros: _ZeroDesign, robot: Robot, sigma: float, picks: dict) -> list[dict]:
    """Per joint, the standard deviation of its zero's change a re-mastering on the planned and on
    as many random poses would have (deg; mm for a prismatic joint), the set-up fitted anew: the
    zeros' diagonal of ``σ² M⁻¹`` (the inverse of the set-up's Schur complement); None and the set-up
    entries that reproduce it for a zero no pose tells from the set-up."""
    std = {}
    for key in ("after", "random"):
        M = zeros.M0 + _information(zeros.A[picks[key]])
        std[key] = sigma * np.sqrt(np.diag(np.linalg.inv(M))) / zeros.scale
    entries = []
    for j, name in enumerate(zero_names(robot), start=1):
        unit = robot.param_units[robot.index(name)]
        f = 1.0 / DEG if unit == "rad" else 1.0
        at = zeros.names.index(name) if name in zeros.names else None
        entries.append(
            {
                "joint": j,
                "name": name,
                "unit": "deg" if unit == "rad" else unit,
                **{key: None if at is None else float(std[key][at] * f) for key in std},
                "absorbed_by": zeros.absorbed.get(name, []),
            }
        )
    return entries


def _why_not(kind: str) -> str:
    if kind in SESSION_KINDS:
        return "a term of the session in time, not of the pose: the interleaved order keeps it apart from the joints"
    if kind == "backlash":
        return "depends on the direction each pose is approached from, which the plan does not choose"
    return "not a cause the poses determine"
