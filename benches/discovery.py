"""Discovery benchmark: how often a cause ``robocal.diagnose`` names is real, and how often a real
one is found (issue 25).

    python benches/discovery.py [--section matched|mismatch] [--files N] [--seed S] [--jobs J] [--kinds k1,k2] [--out F]

Data. About 380 simulated files (deterministic from ``--seed``; 300 samples each, the simulator's
default geometric errors and sensor noise): the built-in robots (HSR JR680, ABB IRB 120, UR10) ×
cable / position / pose × a *scenario*: clean (no effect, ~16 % of the files), one hidden cause, or
two of different scenarios. The scenarios cover every cause kind diagnose can name:

- reading conventions (:class:`robocal.causes.structure.Structure`, applied to the readings with
  ``Structure.invert``): on one joint a quarter/half-turn zero offset (``joint_zero``), a sign flip
  (``joint_sign``) or a reading relative to the previous joint (``joint_reference``, ±1); on two
  joints at once zero offsets and sign flips. Zero offsets are not put on joint 1 (a rotation of
  the base frame or of the cable anchor absorbs them) nor on the last joint (the tool point
  absorbs them): no data can see those;
- ``step`` (the sensor's zero jumps once), ``wander`` (the sensor wanders in time, correlation
  length 5-20 samples), ``drift`` linear and non-linear (exponent 0.4-0.7 or 1.5-3),
  ``temperature`` (links; or the cable), ``cable_scale`` (cable only), ``outliers``;
- joint causes on a random joint: lost motion of both signs (``backlash``, width > 0 the link
  lags, < 0 it leads), ``joint_compliance`` on joint 2 or 3 whose true masses and centres of mass
  are up to ±30 % off the built-in mass model (``mass_error`` uniform in 0-0.3), harmonics
  (``joint_periodic``, harmonic 1-3, and 4-6, which only a joint error map can follow),
  ``joint_scale``, ``joint_coupling``.

Combinations the simulator refuses (``InvalidParameterError``: e.g. readings pushed out of the
cable sensor's range) and effects that cannot reach the detection limit within a plausible size
are skipped, listed, and not counted.

Sizes: the detection limit. An effect's size is set as a multiple ``k`` of what the file can
detect, ``k`` drawn log-uniformly in [1, 10] and recorded. The limit is defined the same way for
every kind: simulate the file noiseless with the effect at a unit size and without it (same seed:
the simulator draws path, geometric errors, noise and effects from independent streams, so the
difference of the residuals at the nominal geometry is the effect's signature ``Δy``); project
``Δy`` off the column space of the geometric identification Jacobian at the nominal geometry
(``Robot.jacobian`` over ``Robot.default_mask``: every DH parameter and the set-up — anchor and
sensor zero, or base and tool frames), in units of the sensor noise ``σ`` (``DEFAULT_NOISE``).
Of a pose only the position rows count: the simulated orientation noise (1e-5 rad against
0.02 mm) would weigh orientation 2000 mm/rad, diagnose weighs it 200 mm/rad
(``POSE_ROTATION_WEIGHT``); the position rows give a limit any weighting reaches. The
noncentrality of the unit effect is ``λ₁ = ‖P⊥ Δy / σ‖²``, and the detection limit ``λ_lim = (z_{1−0.05/(2·60)} +
z_{0.8})² ≈ 17.5``: 80 % power for a two-sided test at a Bonferroni level over ~60 candidates.
Every effect used is linear (to first order) in its size key, so the size at ``k`` times the
limit is ``k · unit · sqrt(λ_lim / λ₁)``. Sizes are capped below diagnose's plausibility limits
and the simulator's (angles 0.9°, ratios 0.009, compliance 9e-4 rad/(N·m), drift 9 mm/h,
temperature rise 40 K at α = 23e-6/K); a capped effect records the ``k`` it reached. A cable
scale error is absorbed exactly by the geometry (scaling every length, the tool and the anchor
scales the cable length), so no file can detect it: its files are skipped as undetectable. Conventions and outliers
(1-3 % of the samples, 1-3 mm) are not small: they are recorded as fixed (``k`` null), counted
among the effects "at ≥ 3× the limit".

Scoring. A named cause is TRUE if it matches a hidden effect by kind and joint: ``joint_map``
matches a ``joint_periodic``, ``joint_scale`` or ``joint_coupling`` of its joint; ``backlash``
must have the hidden width's sign; a ``step`` must lie within ±5 samples; conventions must have
the same joint and value (offset modulo 360° within 0.5°; a reference's source and sign). Each
hidden effect is matched once; another named cause claiming it counts as false. Hidden effects
nobody matched are false negatives. A joint's scale, harmonic or coupling that names other shapes
of its joint's error the data could not tell from it (``undetermined_between``) is scored by its
label; the precision *of the claims as stated* counts it true as well when one of those shapes is
a hidden effect nothing else found — reported beside the precision, never in its place. Reported: per hidden kind the recall (overall and for effects
at ≥ 3× the limit), per named kind the precision, the share of clean files with anything named,
a confusion matrix (hidden kind → what was named for it: its match, every false cause named
in the same file, or "nothing"), and the files whose leftover is said to hold an error of 9–360
cycles a turn of one joint (none is hidden, so each such claim is false). Every file's record (truth, named causes, ``k``, time) goes to
``--out`` as JSON.

``--section mismatch``: the same scoring on files made by ``benches/mismatch.py``, a simulator
that shares only the nominal chain with robocal and makes its effects with physically different
models (its module notes); each family states the named kinds that are true for it, noise
families hide no cause. Reported apart, with how often what is left is called noise.

BLAS (and, with ``--jobs`` > 1, Rayon) threads are limited to 1; the time of a diagnosis is
measured with this setting. Uses only robocal's public API.
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS", "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_var] = "1"  # before NumPy is imported: one BLAS thread here and in every worker

import argparse
import dataclasses
import json
import math
import multiprocessing
import sys
import tempfile
import time
from collections import Counter, defaultdict
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import mismatch
import numpy as np
import robocal
from robocal.causes.structure import KINDS as CONVENTION_KINDS
from robocal.causes.structure import Structure, parse_all, to_model
from robocal.exceptions import InvalidParameterError
from robocal.serial_robot import setup_names
from robocal.simulation import DEFAULT_NOISE, setup, simulate
from scipy.stats import norm

ROBOTS = ("hsr-jr680", "abb-irb120", "ur10")
MEASUREMENTS = ("cable", "position", "pose")
SAMPLES = 300
#: Candidates a diagnosis tests (order of magnitude), the level and the power of the limit.
CANDIDATES, ALPHA, POWER = 60, 0.05, 0.8
LAMBDA_LIMIT = float((norm.ppf(1.0 - ALPHA / (2 * CANDIDATES)) + norm.ppf(POWER)) ** 2)
K_RANGE = (1.0, 10.0)
#: An effect at least this many times the limit counts as "large".
LARGE = 3.0
STEP_TOLERANCE = 5  # samples
OFFSET_TOLERANCE_DEG = 0.5
#: Files per robot × measurement: clean ones, and pairs of scenarios.
CLEAN_PER_SETUP, PAIRS_PER_SETUP = 7, 20

#: Scenarios of one hidden cause: the row of the tables and the kind diagnose should name.
SCENARIOS = {
    "convention": "one convention",
    "conventions2": "two conventions",
    "step": "step",
    "wander": "wander",
    "backlash_lag": "backlash (lags)",
    "backlash_lead": "backlash (leads)",
    "compliance": "joint_compliance",
    "periodic": "joint_periodic (h 1-3)",
    "periodic_high": "joint_periodic (h 4-6)",
    "scale": "joint_scale",
    "coupling": "joint_coupling",
    "temperature": "temperature",
    "drift": "drift",
    "drift_nonlinear": "drift (non-linear)",
    "cable_scale": "cable_scale",
    "outliers": "outliers",
}
#: Scenarios that may not share a file.
EXCLUSIVE = [{"convention", "conventions2"}, {"drift", "drift_nonlinear"}, {"periodic", "periodic_high"}]
#: Effect size: (key, unit size, cap) — cap below diagnose's plausibility limits (angles 1°,
#: ratios 0.01, compliance 1e-3 rad/(N·m), drift 10 mm/h) and the simulator's (angles ≤ 1°).
SIZES = {
    "step": ("size", 0.1, 10.0),  # mm
    "wander": ("rms", 0.1, 5.0),  # mm
    "backlash": ("width", 0.01, 0.9),  # deg
    "joint_compliance": ("compliance", None, 0.9e-3 * 1000.0 / math.radians(1.0)),  # deg/(kN·m); unit: the robot's own
    "joint_periodic": ("amplitude", 0.005, 0.9),  # deg
    "joint_scale": ("scale", 1e-4, 0.009),
    "joint_coupling": ("coefficient", 1e-4, 0.009),
    "temperature": ("rise", 1.0, 40.0),  # K
    "drift": ("rate", 0.1, 9.0),  # mm/h
    "cable_scale": ("scale", 1e-4, 0.009),
}
JOINT_KINDS = {"backlash", "joint_compliance", "joint_periodic", "joint_scale", "joint_coupling", "joint_zero", "joint_sign", "joint_reference"}
MAP_TARGETS = {"joint_periodic", "joint_scale", "joint_coupling"}
#: Other names a diagnosis may give a kind (lost motion of either sign).
ALIASES = {"lost_motion": "backlash"}


# ---------------------------------------------------------------------------------------------
# The plan: which files, deterministically from the seed
# ---------------------------------------------------------------------------------------------
def applicable(scenario: str, measurement: str) -> bool:
    return scenario != "cable_scale" or measurement == "cable"


def draw_effect(scenario: str, robot: str, measurement: str, n: int, rng: np.random.Generator, used: set) -> list[dict]:
    """The hidden effects of one scenario (before sizing): ``kind``, fixed keys, the size key, the
    drawn ``k``; conventions as Structure arguments. ``used`` holds joints already given a
    convention in the file."""
    k = float(np.exp(rng.uniform(*np.log(K_RANGE))))
    row = SCENARIOS[scenario]
    axis = {} if measurement == "cable" else {"axis": "xyz"[rng.integers(3)]}

    def effect(kind, **keys):
        return {"scenario": scenario, "row": row, "kind": kind, "keys": keys, "k_drawn": k, "joint": keys.get("joint")}

    if scenario in ("convention", "conventions2"):
        out = []
        for _ in range(1 if scenario == "convention" else 2):
            choices = ["joint_zero", "joint_sign"] + (["joint_reference"] if scenario == "convention" else [])
            kind = choices[rng.integers(len(choices))]
            joints = [j for j in (range(2, n) if kind == "joint_zero" else range(2, n + 1)) if j not in used]
            j = int(joints[rng.integers(len(joints))])
            used.add(j)
            conv = {"scenario": scenario, "row": row, "kind": kind, "joint": j, "k_drawn": None, "fixed": True}
            if kind == "joint_zero":
                conv["offset_deg"] = float((90.0, 180.0, 270.0)[rng.integers(3)])
            elif kind == "joint_reference":
                conv["source"], conv["coefficient"] = j - 1, float((1.0, -1.0)[rng.integers(2)])
            out.append(conv)
        return out
    if scenario == "step":
        return [effect("step", sample=int(rng.integers(30, SAMPLES - 30)), **axis)]
    if scenario == "wander":
        keys = {"length": round(float(rng.uniform(5.0, 20.0)), 1)}
        if measurement != "cable" and rng.random() < 0.5:
            keys.update(axis)
        return [effect("wander", **keys)]
    if scenario in ("backlash_lag", "backlash_lead"):
        e = effect("backlash", joint=int(rng.integers(1, n + 1)))
        e["sign"] = 1.0 if scenario == "backlash_lag" else -1.0
        return [e]
    if scenario == "compliance":
        return [effect("joint_compliance", joint=int(rng.integers(2, 4)), mass_error=round(float(rng.uniform(0.0, 0.3)), 3))]
    if scenario in ("periodic", "periodic_high"):
        harmonic = int(rng.integers(1, 4) if scenario == "periodic" else rng.integers(4, 7))
        return [effect("joint_periodic", joint=int(rng.integers(1, n + 1)), harmonic=harmonic, phase=round(float(rng.uniform(0, 360)), 1))]
    if scenario == "scale":
        return [effect("joint_scale", joint=int(rng.integers(1, n + 1)))]
    if scenario == "coupling":
        j = int(rng.integers(1, n + 1))
        source = int(rng.choice([s for s in range(1, n + 1) if s != j]))
        return [effect("joint_coupling", joint=j, source=source)]
    if scenario == "temperature":
        target = "cable" if measurement == "cable" and rng.random() < 0.5 else "links"
        return [effect("temperature", target=target, tau=round(float(rng.uniform(300.0, 1200.0))), alpha=23.0)]
    if scenario in ("drift", "drift_nonlinear"):
        exponent = 1.0 if scenario == "drift" else (float(rng.uniform(0.4, 0.7)) if rng.random() < 0.5 else float(rng.uniform(1.5, 3.0)))
        return [effect("drift", exponent=round(exponent, 3), **axis)]
    if scenario == "cable_scale":
        return [effect("cable_scale")]
    if scenario == "outliers":
        e = effect("outliers", fraction=round(float(rng.uniform(0.01, 0.03)), 4), size=round(float(rng.uniform(1.0, 3.0)), 3))
        e["k_drawn"], e["fixed"] = None, True
        return [e]
    raise ValueError(scenario)


def plan(seed: int) -> list[dict]:
    """Every file of the benchmark (unsized), in a stratified order: any prefix holds clean files,
    single causes and pairs in about their overall proportions."""
    rng = np.random.default_rng([seed, 0])
    files = []
    for robot in ROBOTS:
        n = robocal.robot(robot).n_joints
        for measurement in MEASUREMENTS:
            cases = [("clean", [])] * CLEAN_PER_SETUP
            singles = [s for s in SCENARIOS if applicable(s, measurement)]
            cases += [(s, [s]) for s in singles]
            for _ in range(PAIRS_PER_SETUP):
                while True:
                    pair = sorted(rng.choice(singles, 2, replace=False).tolist())
                    if not any(set(pair) <= ex for ex in EXCLUSIVE):
                        break
                cases.append(("pair", pair))
            for group, scenarios in cases:
                files.append({"robot": robot, "measurement": measurement, "group": group, "scenarios": scenarios, "n_joints": n})
    for i, f in enumerate(files):
        f["seed"] = int(seed) * 1000 + i
        r = np.random.default_rng([seed, 1, i])
        used: set = set()
        f["hidden"] = [e for s in f["scenarios"] for e in draw_effect(s, f["robot"], f["measurement"], f["n_joints"], r, used)]
    return stratified(files, rng)


def stratified(files: list[dict], rng: np.random.Generator) -> list[dict]:
    """``files`` in a stratified order, indexed: item i of a group of n_g at (i + u)/n_g,
    groups shuffled within — any prefix holds each group in about its overall proportion."""
    groups = defaultdict(list)
    for f in files:
        groups[f["group"]].append(f)
    keyed = []
    for g, (name, members) in enumerate(sorted(groups.items())):
        order = rng.permutation(len(members))
        u = rng.uniform()
        keyed += [((i + u) / len(members), g, members[o]) for i, o in enumerate(order)]
    ordered = [f for _, _, f in sorted(keyed, key=lambda t: (t[0], t[1]))]
    for index, f in enumerate(ordered):
        f["index"] = index
    return ordered


# ---------------------------------------------------------------------------------------------
# Detection limit and sizes
# ---------------------------------------------------------------------------------------------
def spec(kind: str, keys: dict) -> str:
    parts = [
        f"{k}={v:d}" if isinstance(v, (int, np.integer)) and not isinstance(v, bool) else f"{k}={v:.8g}" if isinstance(v, float) else f"{k}={v}"
        for k, v in keys.items()
    ]
    return kind + (":" + ",".join(parts) if parts else "")


def geometric_basis(nominal, measurement: str, q: np.ndarray, y: np.ndarray) -> np.ndarray:
    """An orthonormal basis of what the geometry absorbs: the column space of the geometric
    identification Jacobian (every DH parameter and the set-up) at the nominal geometry, in units
    of the sensor noise; of a pose its position rows (see the module notes)."""
    cols = np.flatnonzero(nominal.default_mask(measurement))
    width = 1 if measurement == "cable" else 3
    J = nominal.jacobian(measurement, q, y=y, cols=cols)
    J = J.reshape(len(q), -1, len(cols))[:, :width].reshape(-1, len(cols)) / DEFAULT_NOISE[measurement].sigma
    u, s, _ = np.linalg.svd(J, full_matrices=False)
    return u[:, s > s[0] * 1e-9]


def noncentrality(basis: np.ndarray, dy: np.ndarray, sigma: float) -> float:
    """``λ₁ = ‖P⊥ Δy / σ‖²`` of an effect's signature ``dy`` (m, k)."""
    d = (dy / sigma).ravel()
    d -= basis @ (basis.T @ d)
    return float(d @ d)


class Limit:
    """The noncentrality of effects on one file: nominal geometry, weighted projector and the
    noiseless residuals without any effect."""

    def __init__(self, robot: str, measurement: str, seed: int):
        self.robot, self.measurement, self.seed = robot, measurement, seed
        self.nominal = setup(robocal.robot(robot), measurement)
        clean, _ = simulate(robot, measurement, samples=SAMPLES, seed=seed, noise=0)
        self.q = clean.q
        self.r0 = self.residuals(clean)
        self.basis = geometric_basis(self.nominal, measurement, self.q, clean.y)

    def residuals(self, data) -> np.ndarray:
        """Residuals at the nominal geometry; of a pose its position part (see the module notes)."""
        return self.nominal.residuals(self.measurement, data.q, data.y)[:, :3]

    def noncentrality(self, effect_spec: str) -> tuple[float, dict]:
        """``λ₁`` of an effect (a spec) on this file, and its truth record."""
        data, truth = simulate(self.robot, self.measurement, samples=SAMPLES, seed=self.seed, effects=[effect_spec], noise=0)
        return noncentrality(self.basis, self.residuals(data) - self.r0, DEFAULT_NOISE[self.measurement].sigma), truth["effects"][0]


def sized(limit: Limit, hidden: dict) -> dict:
    """The effect's spec at ``k_drawn`` times the detection limit (capped), with ``k``, ``λ₁``."""
    kind, keys = hidden["kind"], dict(hidden["keys"])
    out = dict(hidden)
    if hidden.get("fixed"):
        out.update(spec=spec(kind, keys), k=None)
        return out
    name, unit, cap = SIZES[kind]
    if kind == "joint_compliance":  # unit: the robot's own compliance
        _, record = limit.noncentrality(spec(kind, keys))
        unit = record["parameters"]["compliance"]["value"]
    unit *= hidden.get("sign", 1.0)
    lam, _ = limit.noncentrality(spec(kind, {**keys, name: unit}))
    if not lam > 1e-12:
        raise InvalidParameterError(f"{spec(kind, keys)} leaves no trace the geometry cannot absorb (λ₁ = {lam:.3g})")
    at_limit = abs(unit) * math.sqrt(LAMBDA_LIMIT / lam)  # size at the detection limit
    size = min(hidden["k_drawn"] * at_limit, cap)
    k = size / at_limit
    if k < 1.0:
        raise InvalidParameterError(f"{spec(kind, keys)}: the detection limit needs {name}={at_limit:.3g}, beyond the cap {cap:g}")
    size = math.copysign(size, unit)
    keys[name] = float(f"{size:.6g}")
    out.update(spec=spec(kind, keys), k=k, lambda_unit=lam, unit_size=unit, size_at_limit=math.copysign(at_limit, unit), size=keys[name])
    return out


# ---------------------------------------------------------------------------------------------
# One file: simulate, diagnose, score
# ---------------------------------------------------------------------------------------------
def structure_of(h: dict) -> Structure:
    if h["kind"] == "joint_zero":
        return Structure("joint_zero", h["joint"] - 1, math.radians(h["offset_deg"]))
    if h["kind"] == "joint_sign":
        return Structure("joint_sign", h["joint"] - 1)
    return Structure("joint_reference", h["joint"] - 1, h["coefficient"], h["source"] - 1)


def value(params: dict, name: str):
    entry = (params or {}).get(name)
    return entry.get("value") if isinstance(entry, dict) else None


def matches(named: dict, hidden: dict) -> bool:
    """Whether a named cause is the hidden effect (see the module notes)."""
    kind, target = ALIASES.get(named["kind"], named["kind"]), hidden["kind"]
    joint, params = named.get("joint"), named.get("params") or {}
    if hidden.get("accept") is not None:  # the mismatch section: the named kinds true for a family
        if kind not in hidden["accept"] or (hidden["joint"] is not None and joint != hidden["joint"]):
            return False
        target = kind
    elif kind == "joint_map":
        return target in MAP_TARGETS and joint == hidden["joint"]
    elif kind != target or (target in JOINT_KINDS and joint != hidden["joint"]):
        return False
    if target == "backlash":
        width = value(params, "width")
        width = value(params, "direction") if width is None else width
        return width is not None and np.sign(width) == np.sign(hidden["size"])
    if target == "step":
        sample = value(params, "sample")
        return sample is not None and abs(sample - hidden["keys"]["sample"]) <= STEP_TOLERANCE
    if target == "joint_zero":
        offset = value(params, "offset")
        return offset is not None and abs((offset - hidden["offset_deg"] + 180.0) % 360.0 - 180.0) <= OFFSET_TOLERANCE_DEG
    if target == "joint_reference":
        source, coefficient = value(params, "source"), value(params, "coefficient")
        return source == hidden["source"] and coefficient is not None and np.sign(coefficient) == np.sign(hidden["coefficient"])
    return True


def score(named: list[dict], hidden: list[dict]) -> None:
    """Marks each named cause ``true`` (and which hidden effect it found) and each hidden effect
    ``found_by``; one named cause per hidden effect."""
    for h in hidden:
        h["found_by"] = None
    for i, n in enumerate(named):
        n["true"], n["finds"] = False, None
        for k, h in enumerate(hidden):
            if h["found_by"] is None and matches(n, h):
                n["true"], n["finds"], h["found_by"] = True, k, i
                break


#: Conventions are equivalent when the nominal geometry with only the set-up fitted explains the
#: readings taken through the named ones within this fraction of the true angles' RMSE.
EQUIVALENT = 0.02


def setup_rmse(data, q: np.ndarray) -> float:
    """RMSE of the nominal geometry with only the set-up fitted (a free base and tool, or anchor
    and tool point) to ``data`` with the angles ``q``."""
    robot = robocal.robot(data.robot)
    mask = setup_names(robot, data.measurement) + (["tool_x", "tool_y", "tool_z"] if data.measurement == "cable" else [])
    return robocal.calibrate(dataclasses.replace(data, q=q), robot=robot, mask=mask).metrics["train"]["rmse"]


def alike(a: float, b: float) -> bool:
    return a <= (1.0 + EQUIVALENT) * b


def equivalent_conventions(data, q_true: np.ndarray, named: list[dict]) -> bool:
    """Whether the conventions ``named`` turn the readings ``data.q`` into angles the data
    cannot tell from the true ones ``q_true`` — with only the set-up fitted, the nominal geometry
    explains both alike — and the readings as read worse. A wrist flip (joint 4 +180°, joint 5
    reversed, joint 6 +180°) or a mirror of the arm (joints 1, 4 and 6 reversed) changes no
    measurement, so a diagnosis can only name one of the equivalent sets."""
    labels = [n["label"] for n in named if n["kind"] in CONVENTION_KINDS]
    through_named = setup_rmse(data, to_model(data.q, parse_all(labels, data.n_joints)))
    return alike(through_named, setup_rmse(data, q_true)) and not alike(setup_rmse(data, data.q), through_named)


def score_equivalent(data, q_true: np.ndarray, named: list[dict], hidden: list[dict]) -> None:
    """After :func:`score`: when the named conventions are not the hidden ones but an
    equivalent set (:func:`equivalent_conventions`), each is marked true (``equivalent``) and
    each hidden convention found — the claim "the readings follow these conventions, or an
    equivalent set" is true."""
    missed = [h for h in hidden if h["kind"] in CONVENTION_KINDS and h["found_by"] is None]
    claimed = [i for i, n in enumerate(named) if n["kind"] in CONVENTION_KINDS]
    if not missed or not claimed or not equivalent_conventions(data, q_true, named):
        return
    for i in claimed:
        named[i]["true"], named[i]["equivalent"] = True, True
    for h in missed:
        h["found_by"] = claimed[0]


def score_alike(named: list[dict], hidden: list[dict]) -> None:
    """After :func:`score`: a named cause that is false by its label but states shapes of its
    joint's error the data could not tell from it (``undetermined_between``), one of which is a
    hidden effect nothing found, is marked ``true_as_stated`` — the claim "one of these" is true.
    The strict figures (``true``) are left as they are."""
    for n in named:
        n["true_as_stated"] = n["true"]
        if n["true"]:
            continue
        for label in n.get("undetermined_between") or []:
            kind, _, rest = label.partition(" joint ")
            alternative = {"kind": kind, "joint": int(rest.split()[0]) if rest else None, "params": {}}
            if any(h["found_by"] is None and matches(alternative, h) for h in hidden):
                n["true_as_stated"] = True
                break


def diagnosed(data) -> tuple[dict, list[dict], float]:
    """The diagnosis of ``data`` (its report), the causes it names as the scoring reads them
    (kind, joint, label, params and the shapes it could not tell apart) and its time (s)."""
    t0 = time.perf_counter()
    report = robocal.diagnose(data).to_dict()
    elapsed = time.perf_counter() - t0
    named = [{k: e.get(k) for k in ("kind", "joint", "label", "params")} for e in report["effects"]]
    for n, e in zip(named, report["effects"]):
        n["undetermined_between"] = (e.get("significance") or {}).get("undetermined_between") or []
    return report, named, elapsed


def run_file(f: dict) -> dict:
    """Simulates, diagnoses and scores one planned file; a record (``skipped`` with the reason
    when the combination does not apply)."""
    record = {k: f[k] for k in ("index", "robot", "measurement", "group", "scenarios", "seed")}
    try:
        limit = Limit(f["robot"], f["measurement"], f["seed"])
        hidden = [h if h["kind"] in ("joint_zero", "joint_sign", "joint_reference") else sized(limit, h) for h in f["hidden"]]
        effects = [h["spec"] for h in hidden if "spec" in h]
        data, truth = simulate(f["robot"], f["measurement"], samples=SAMPLES, seed=f["seed"], effects=effects)
    except InvalidParameterError as exc:
        record["skipped"] = str(exc)
        return record
    q = q_true = data.q
    for h in hidden:
        if "spec" not in h:
            q = structure_of(h).invert(q)
    data = dataclasses.replace(data, q=q)
    if any("spec" not in h for h in hidden) and alike(setup_rmse(data, q), setup_rmse(data, q_true)):
        record["skipped"] = "the set-up absorbs the hidden conventions: no data can see them"
        return record
    for h, rec in zip((h for h in hidden if "spec" in h), truth["effects"]):
        if h["kind"] == "outliers":
            h["samples"] = rec.get("samples")
    report, named, elapsed = diagnosed(data)
    score(named, hidden)
    score_equivalent(data, q_true, named, hidden)
    score_alike(named, hidden)
    leftover = report["final"].get("residuals") or {}
    line = leftover.get("periodic") or {}
    record.update(
        hidden=hidden,
        named=named,
        # an error of 9-360 cycles a turn reported in what is left: none is hidden, so every one is false
        leftover_line={k: line[k] for k in ("joint", "harmonic", "amplitude_arcsec")} if line.get("reported") else None,
        # what is left said to follow the sensor's reading: no such error is hidden, so every one is false
        leftover_sensor=bool((leftover.get("sensor") or {}).get("verdict")),
        said_noise=bool(leftover.get("noise")),
        time_s=elapsed,
        rmse_heldout={"baseline": report["baseline"].get("rmse_heldout"), "final": report["final"].get("rmse_heldout")},
    )
    return record


# ---------------------------------------------------------------------------------------------
# The mismatch section: effects made by a model robocal does not fit (benches/mismatch.py)
# ---------------------------------------------------------------------------------------------
#: Files per robot × measurement: clean ones (another geometry, Gaussian noise), each family
#: this many times, and pairs of families (at most one of them a noise family).
MISMATCH_CLEAN, MISMATCH_REPEATS, MISMATCH_PAIRS = 2, 2, 4


def mismatch_plan(seed: int) -> list[dict]:
    """Every file of the mismatch section, deterministically from ``seed``."""
    rng = np.random.default_rng([seed, 51])
    files = []
    for robot in ROBOTS:
        for measurement in MEASUREMENTS:
            families = [name for name, fam in mismatch.FAMILIES.items() if measurement in fam.measurements]
            causal = [name for name in families if not mismatch.FAMILIES[name].optional]
            cases = [("clean", [])] * MISMATCH_CLEAN + [("single", [name]) for name in families for _ in range(MISMATCH_REPEATS)]
            for _ in range(MISMATCH_PAIRS):
                first = str(rng.choice(causal))
                second = str(rng.choice([name for name in families if name != first]))
                cases.append(("pair", sorted([first, second])))
            files += [{"robot": robot, "measurement": measurement, "group": group, "families": fams} for group, fams in cases]
    for i, f in enumerate(files):
        f["seed"] = int(seed) * 1000 + i
        f["k_drawn"] = [float(np.exp(rng.uniform(*np.log(K_RANGE)))) for _ in f["families"]]
    return stratified(files, rng)


def mismatch_effects(f: dict, acq) -> tuple[list[dict], list[dict]]:
    """The file's effects for the generator (family, keys, size) and the hidden causes to score
    (one per joint a gravity deflection bends), each sized at its ``k`` times the detection
    limit as in the matched section, with the generator's own signature."""
    rng = np.random.default_rng([f["seed"], 2])
    nominal = setup(robocal.robot(f["robot"]), f["measurement"])
    width = 1 if f["measurement"] == "cable" else 3
    y0 = mismatch.readings(acq, [], noisy=False)
    basis = geometric_basis(nominal, f["measurement"], acq.q, y0)
    sigma = mismatch.NOISE[f["measurement"]][0]
    effects, hidden = [], []
    for name, k in zip(f["families"], f["k_drawn"]):
        family = mismatch.FAMILIES[name]
        keys = mismatch.draw(name, acq, rng)
        effect = {"family": name, "keys": keys, "size": None}
        record = {"kind": name, "row": family.row, "keys": keys, "joint": keys.get("joint"), "accept": list(family.accept), "optional": family.optional}
        if family.unit is None:
            record.update(fixed=True, k=None, k_drawn=None)
        else:
            unit = family.unit * (float(rng.choice([1.0, -1.0])) if family.sign else 1.0)
            dy = mismatch.readings(acq, [{**effect, "size": unit}], noisy=False)[:, :width] - y0[:, :width]
            lam = noncentrality(basis, dy, sigma)
            if not lam > 1e-12:
                raise InvalidParameterError(f"{name} leaves no trace the geometry cannot absorb (λ₁ = {lam:.3g})")
            at_limit = abs(unit) * math.sqrt(LAMBDA_LIMIT / lam)
            size = min(k * at_limit, family.cap)
            if size / at_limit < 1.0:
                raise InvalidParameterError(f"{name}: the detection limit needs size {at_limit:.3g}, beyond the cap {family.cap:g}")
            effect["size"] = math.copysign(float(f"{size:.6g}"), unit)
            record.update(k=size / at_limit, k_drawn=k, lambda_unit=lam, size_at_limit=at_limit, size=effect["size"])
        effects.append(effect)
        joints = keys.get("joints") or [keys.get("joint")]
        hidden += [{**record, "joint": j} for j in joints]
    return effects, hidden


#: ``found_by`` of a hidden effect found by the leftover's tests rather than a named cause.
FOUND_IN_LEFTOVER = -1


def found_as(r: dict, h: dict) -> str:
    """What found a hidden effect: the named cause's kind, or the leftover's verdict."""
    return "leftover: sensor" if h["found_by"] == FOUND_IN_LEFTOVER else named_kind(r["named"][h["found_by"]])


def run_mismatch_file(f: dict) -> dict:
    """Generates, diagnoses and scores one file of the mismatch section."""
    record = {k: f[k] for k in ("index", "robot", "measurement", "group", "families", "seed")}
    record["scenarios"] = f["families"]
    acq = mismatch.acquisition(f["robot"], f["measurement"], SAMPLES, f["seed"])
    try:
        effects, hidden = mismatch_effects(f, acq)
    except InvalidParameterError as exc:
        record["skipped"] = str(exc)
        return record
    y = mismatch.readings(acq, effects)
    data = robocal.Dataset(q=acq.q, y=y, measurement=f["measurement"], robot=f["robot"], t=acq.t)
    report, named, elapsed = diagnosed(data)
    score(named, hidden)
    score_alike(named, hidden)
    leftover = report["final"].get("residuals") or {}
    sensor_verdict = bool((leftover.get("sensor") or {}).get("verdict"))
    for h in hidden:  # the sensor's own error is no cause of the robot: named as the sensor's, or found as the leftover's verdict
        if h["kind"] == "sensor_error" and sensor_verdict and h["found_by"] is None:
            h["found_by"] = FOUND_IN_LEFTOVER
    final = report["final"].get("rmse_heldout")
    floor = mismatch.NOISE[f["measurement"]][0] * math.sqrt(1 if f["measurement"] == "cable" else 3)
    missed = [h for h in hidden if h["found_by"] is None and not h.get("optional") and large(h)]
    said_noise = bool(leftover.get("noise"))
    record.update(
        hidden=hidden,
        named=named,
        leftover_line=None,
        leftover_sensor=sensor_verdict,
        said_noise=said_noise,
        # "looks like noise" while a large effect is missed or the final error is 20 % above the noise
        false_noise=said_noise and (bool(missed) or (final is not None and final > 1.2 * floor)),
        noise_rmse=floor,
        time_s=elapsed,
        rmse_heldout={"baseline": report["baseline"].get("rmse_heldout"), "final": final},
    )
    return record


# ---------------------------------------------------------------------------------------------
# Summary
# ---------------------------------------------------------------------------------------------
def large(h: dict) -> bool:
    return h.get("fixed", False) or (h.get("k") or 0.0) >= LARGE


def named_kind(n: dict) -> str:
    return ALIASES.get(n["kind"], n["kind"])


def summarise(records: list[dict]) -> dict:
    done = [r for r in records if "skipped" not in r]
    recall = defaultdict(lambda: Counter())
    precision = defaultdict(lambda: Counter())
    confusion = defaultdict(Counter)
    clean_hit = 0
    strong = Counter()  # precision on files whose hidden effects are all at ≥ LARGE× the limit
    for r in done:
        false_kinds = [named_kind(n) for n in r["named"] if not n["true"]]
        if all(large(h) for h in r["hidden"]):
            strong["named"] += len(r["named"])
            strong["true"] += sum(n["true"] for n in r["named"])
        for n in r["named"]:
            precision[named_kind(n)]["named"] += 1
            precision[named_kind(n)]["true"] += n["true"]
        if not r["hidden"]:
            clean_hit += bool(r["named"])
            confusion["none (clean)"].update(false_kinds or ["nothing"])
        for h in r["hidden"]:
            found = h["found_by"] is not None
            if h.get("optional"):  # a noise family hides no cause: what was named for it, no recall
                confusion[h["row"]].update(([found_as(r, h)] if found else []) + (false_kinds or ([] if found else ["nothing"])))
                continue
            c = recall[h["row"]]
            c["hidden"] += 1
            c["found"] += found
            if large(h):
                c["large"] += 1
                c["large_found"] += found
            if found:
                confusion[h["row"]][found_as(r, h)] += 1
            confusion[h["row"]].update(false_kinds if false_kinds else ([] if found else ["nothing"]))
    clean = sum(1 for r in done if not r["hidden"])
    total = Counter()
    for c in recall.values():
        total.update(c)
    named_all = sum(c["named"] for c in precision.values())
    as_stated = sum(n.get("true_as_stated", n["true"]) for r in done for n in r["named"])
    with_alternatives = sum(bool(n.get("undetermined_between")) for r in done for n in r["named"])
    true_all = sum(c["true"] for c in precision.values())
    times = [r["time_s"] for r in done]
    return {
        "files": len(done),
        "skipped": len(records) - len(done),
        "leftover_lines": sum(r.get("leftover_line") is not None for r in done),
        "leftover_sensor": sum(bool(r.get("leftover_sensor")) for r in done),
        "said_noise": sum(bool(r.get("said_noise")) for r in done),
        "false_noise": sum(bool(r.get("false_noise")) for r in done),
        "clean_files": clean,
        "clean_with_anything_named": clean_hit,
        "false_discovery_rate_clean": clean_hit / clean if clean else None,
        "precision": true_all / named_all if named_all else None,
        "named": named_all,
        "true_named": true_all,
        "precision_as_stated": as_stated / named_all if named_all else None,
        "true_as_stated": as_stated,
        "named_with_alternatives": with_alternatives,
        "precision_large": strong["true"] / strong["named"] if strong["named"] else None,
        "named_large": strong["named"],
        "true_named_large": strong["true"],
        "recall": total["found"] / total["hidden"] if total["hidden"] else None,
        "recall_large": total["large_found"] / total["large"] if total["large"] else None,
        "hidden": total["hidden"],
        "hidden_large": total["large"],
        "recall_by_kind": {k: dict(v) for k, v in recall.items()},
        "precision_by_kind": {k: dict(v) for k, v in precision.items()},
        "confusion": {k: dict(v) for k, v in confusion.items()},
        "time_s": {"mean": float(np.mean(times)), "median": float(np.median(times)), "max": float(np.max(times))} if times else None,
    }


def fraction(a: int, b: int) -> str:
    return f"{a / b:.2f} ({a}/{b})" if b else "—"


def markdown(s: dict) -> str:
    hidden = f"{s['hidden']} hidden effects ({s['hidden_large']} at ≥ {LARGE:g}× the limit)"
    rows = [
        f"{s['files']} files ({s['skipped']} skipped), {hidden}, {s['named']} causes named",
        "",
        "| | value | target |",
        "|---|---|---|",
        f"| precision (named causes that are real) | {fraction(s['true_named'], s['named'])} | ≥ 0.95 |",
        f"| precision of the claims as stated ({s['named_with_alternatives']} name shapes of their joint the data could not tell apart: true if one is) "
        f"| {fraction(s['true_as_stated'], s['named'])} | |",
        f"| precision on files whose effects are all at ≥ {LARGE:g}× the limit (or none) | {fraction(s['true_named_large'], s['named_large'])} | |",
        f"| files whose leftover is said to hold a line of 9-360 cycles a turn (none hidden: each is false) | {fraction(s['leftover_lines'], s['files'])} | |",
        f"| files whose leftover is said to follow the sensor's reading | {fraction(s['leftover_sensor'], s['files'])} | |",
        f"| files whose leftover is said to look like noise | {fraction(s['said_noise'], s['files'])} | |",
        f"| ... of them falsely (a large effect missed, or the final error > 1.2× the noise) | {fraction(s['false_noise'], s['said_noise'])} | 0 |",
        f"| recall, effects at ≥ {LARGE:g}× the limit | {fraction(round((s['recall_large'] or 0) * s['hidden_large']), s['hidden_large'])} | ≥ 0.90 |",
        f"| recall, all (1-10× the limit) | {fraction(round((s['recall'] or 0) * s['hidden']), s['hidden'])} | |",
        f"| clean files with anything named | {fraction(s['clean_with_anything_named'], s['clean_files'])} | ≤ 0.05 |",
        "",
        f"| hidden kind | hidden | recall | at ≥ {LARGE:g}× | recall at ≥ {LARGE:g}× |",
        "|---|---|---|---|---|",
    ]
    order = list(SCENARIOS.values())
    for row in sorted(s["recall_by_kind"], key=lambda r: order.index(r) if r in order else len(order)):
        c = s["recall_by_kind"][row]
        rows.append(
            f"| {row} | {c.get('hidden', 0)} | {fraction(c.get('found', 0), c.get('hidden', 0))} | "
            f"{c.get('large', 0)} | {fraction(c.get('large_found', 0), c.get('large', 0))} |"
        )
    rows += ["", "| named kind | named | precision |", "|---|---|---|"]
    for kind, c in sorted(s["precision_by_kind"].items(), key=lambda kv: -kv[1]["named"]):
        rows.append(f"| {kind} | {c['named']} | {fraction(c['true'], c['named'])} |")
    columns = sorted({k for c in s["confusion"].values() for k in c} - {"nothing"}) + ["nothing"]
    rows += [
        "",
        "Confusion (hidden kind → what was named: its match, and every false cause named in the same file; 'nothing': missed and nothing else named)",
        "",
        "| hidden \\ named | " + " | ".join(columns) + " |",
        "|---" * (len(columns) + 1) + "|",
    ]
    for row in sorted(s["confusion"], key=lambda r: order.index(r) if r in order else len(order)):
        c = s["confusion"][row]
        rows.append(f"| {row} | " + " | ".join(str(c.get(k, "")) for k in columns) + " |")
    if s["time_s"]:
        t = s["time_s"]
        rows += ["", f"diagnosis time per file: mean {t['mean']:.2f} s, median {t['median']:.2f} s, max {t['max']:.2f} s"]
    return "\n".join(rows)


def brief(r: dict) -> str:
    head = f"[{r['index']}] {r['robot']} {r['measurement']} {r['group']}"
    if "skipped" in r:
        return f"{head}: skipped ({r['skipped'][:160]})"

    def what(h):
        joint = "" if h["joint"] is None else f" j{h['joint']}"
        size = "" if h.get("k") is None else f" ({h['k']:.1f}x)"
        return f"{h['kind']}{joint}{size}{'' if h['found_by'] is None else ' ✓'}"

    hidden = ", ".join(what(h) for h in r["hidden"]) or "nothing"
    named = ", ".join(f"{n['label']}{'' if n['true'] else ' ✗'}" for n in r["named"]) or "nothing"
    return f"{head}: hidden {hidden} → named {named} ({r['time_s']:.1f} s)"


def limit_threads() -> None:
    try:
        from threadpoolctl import threadpool_limits

        threadpool_limits(1)
    except ImportError:
        pass


def default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON-serialisable: {type(o)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--files", type=int, default=None, help="the first N files of the stratified order (default all)")
    parser.add_argument("--seed", type=int, default=25)
    parser.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    parser.add_argument("--kinds", default=None, help="only files hiding one of these scenarios or kinds (comma-separated; 'clean' for clean files)")
    parser.add_argument(
        "--section",
        choices=("matched", "mismatch"),
        default="matched",
        help="matched: effects made by robocal's own simulator, in its candidates' shapes; mismatch: effects made by "
        "benches/mismatch.py, a physically different model (default matched)",
    )
    parser.add_argument("--out", default=None, help="per-file records (JSON; default discovery.json, discovery-mismatch.json)")
    args = parser.parse_args()
    if args.jobs < 1 or (args.files is not None and args.files < 1):
        parser.error("--jobs and --files must be >= 1")
    matched = args.section == "matched"
    files = plan(args.seed) if matched else mismatch_plan(args.seed)
    runner = run_file if matched else run_mismatch_file
    if args.kinds:
        wanted = {k.strip() for k in args.kinds.split(",") if k.strip()}
        kinds_of = (lambda f: set(f["scenarios"]) | {h["kind"] for h in f["hidden"]}) if matched else (lambda f: set(f["families"]))
        known = set().union(*(kinds_of(f) for f in files)) | {"clean"}
        if wanted - known:
            parser.error(f"--kinds: unknown {sorted(wanted - known)}; known: {sorted(known)}")
        files = [f for f in files if ("clean" in wanted and f["group"] == "clean") or wanted & kinds_of(f)]
    if args.files is not None:
        files = files[: args.files]
    out = Path(args.out or ("discovery.json" if matched else "discovery-mismatch.json"))
    print(
        f"robocal {robocal.__version__}: {args.section} section, {len(files)} files, seed {args.seed}, {args.jobs} job(s); detection limit λ = {LAMBDA_LIMIT:.2f}; records → {out}",
        flush=True,
    )
    t0 = time.perf_counter()
    records = []
    if args.jobs == 1:
        limit_threads()
        for i, f in enumerate(files, start=1):
            records.append(runner(f))
            print(f"{i}/{len(files)} {brief(records[-1])}", flush=True)
    else:
        os.environ["RAYON_NUM_THREADS"] = "1"  # the workers share the cores
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(args.jobs, mp_context=context, initializer=limit_threads) as pool:
            futures = [pool.submit(runner, f) for f in files]
            for i, future in enumerate(as_completed(futures), start=1):
                records.append(future.result())
                print(f"{i}/{len(files)} {brief(records[-1])}", flush=True)
        records.sort(key=lambda r: r["index"])
    summary = summarise(records)
    table = markdown(summary)
    print("\n" + table)
    print(f"\nwall time {time.perf_counter() - t0:.0f} s")
    document = {
        "command": " ".join([Path(sys.argv[0]).name] + sys.argv[1:]),
        "robocal": robocal.__version__,
        "seed": args.seed,
        "section": args.section,
        "samples": SAMPLES,
        "lambda_limit": LAMBDA_LIMIT,
        "summary": summary,
        "records": records,
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile("w", dir=out.parent, prefix=out.name + ".", suffix=".tmp", delete=False) as tmp:
        json.dump(document, tmp, indent=1, default=default)
    os.replace(tmp.name, out)


if __name__ == "__main__":
    main()
