"""What a measurement plan buys: held-out error after calibrating on planned poses against random
poses within the same constraints, the planner's speed, and how many planned poses the public
HSR set-up needs to determine every parameter within 1 mm / 0.1 deg.

    python benches/bench_plan.py [--seeds 3] [--quick] [--part heldout|narrow|speed|hsr] [--raw FILE]

Held-out: on each built-in robot, cable and tracker (position), a simulated robot with geometric
errors and one joint cause (``joint_compliance:joint=2``, the mass model's compliance) is
measured at ``N`` poses — planned (``robocal.plan`` with the cause in the model, criterion I and
D) or drawn uniformly among the same candidates (joint limits, the tool above the mounting plane,
the cable reading in range) —, calibrated with the cause (``robocal.calibrate(causes=...)``) and
judged by ``robocal.verify`` on 1000 other random poses measured without noise (the set-up
re-fitted, as on a new session): the error against the noise-free truth, which is the model's
own (no noise floor: calibrated on noise-free readings, it is 0.0002-0.0003 mm). Root mean
square over ``--seeds`` robots (the expected squared error the criteria minimise; each seed's
designs share the robot and the noise stream, a paired comparison). "a random N worth" is the
number of random poses whose error (a power law through the random 40, 80 and 120) equals the
planned 40's. "predicted": the plan's report — its ``prediction`` after the I-optimal 40, the
``least_possible`` of any 40 poses among the candidates (``bound=True``: the continuous
relaxation's lower bound) and the ``random`` of a 120-pose plan; "any 40 worth at most" puts
that least possible on the predicted random curve (a power law through the ``random`` of the 40-
and the 120-pose plans). A second table repeats this in a narrow cell
(every joint within ±25 deg of a measurable pose).

Speed: ``robocal.plan`` of 100 poses from 10 000 candidates, wall time, one run each (the
machine's other work shows in it).

HSR (criterion D: each parameter's standard deviation is asked for, not a prediction): the
public HSR-RobotCali file (D1) read with its reading conventions (``joint_zero`` of
joints 2 and 3, +90 and +180 deg: docs/findings.md), the cable's anchor and the tool fitted on
it with the nominal geometry; joints 1-3 and 4-6 each within the file's ranges or the robot's
limits; the noise the file's revisits measure (0.051 mm). For each set-up the smallest number
of planned poses whose predicted standard deviations are all within 1 mm / 0.1 deg, or, where
none up to the largest tried is, the worst parameter there and the poses the 1/N fall of the
variance would need.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
from machine import cpu_model

import robocal
from robocal.calibration.problem import is_kinematic, start_parameters
from robocal.causes import structure
from robocal.planning import CRITERIA, Constraints, candidate_poses
from robocal.simulation import CABLE_RANGE, setup, simulate

DATASETS = Path(os.environ.get("ROBOCAL_DATASETS", Path(__file__).resolve().parents[2] / "shared" / "datasets"))
ROBOTS = ("hsr-jr680", "abb-irb120", "ur10")
MEASUREMENTS = ("cable", "position")
EFFECT, CAUSE = "joint_compliance:joint=2", "joint_compliance joint 2"
RANDOM_SIZES = (40, 80, 120)
PLANNED = 40
TEST_POSES = 1000
NARROW_DEG = 25.0
HSR_CONVENTIONS = ["joint_zero joint 2 offset=90", "joint_zero joint 3 offset=180"]
HSR_NOISE_MM = 0.051
HSR_POSES = (26, 28, 30, 32, 36, 40, 60, 80, 120, 240, 480, 640, 960)


def ranges_around(robot: str, measurement: str, half_deg: float) -> dict:
    """Joint ranges (rad) ``half_deg`` either side of a pose the sensor can measure (the first
    of a seeded draw within the constraints), within the joint limits."""
    r = robocal.robot(robot)
    centre = random_poses(robot, measurement, 1, 0)[0]
    half = np.radians(half_deg)
    return {j: (max(joint.limits[0], c - half), min(joint.limits[1], c + half)) for j, (c, joint) in enumerate(zip(centre, r.joints), start=1)}


def random_poses(robot: str, measurement: str, n: int, seed: int, joint_ranges=None) -> np.ndarray:
    """``n`` poses drawn uniformly within the planner's own constraints (its defaults)."""
    r = robocal.robot(robot)
    lo, hi = (np.array(v) for v in zip(*(j.limits for j in r.joints)))
    for j, (a, b) in (joint_ranges or {}).items():
        lo[j - 1], hi[j - 1] = a, b
    constraints = Constraints(lo, hi, np.array(CABLE_RANGE) if measurement == "cable" else None)
    q, _ = candidate_poses(r, measurement, setup(r, measurement).params, constraints, [], n, np.random.default_rng(seed), least=n)
    return q


def heldout(robot: str, measurement: str, q: np.ndarray, seed: int, test_q: np.ndarray) -> float:
    """Held-out RMSE (mm) on noiseless measurements at ``test_q`` after calibrating at ``q``."""
    data, _ = simulate(robot, measurement, seed=seed, effects=[EFFECT], poses=q)
    result = robocal.calibrate(data, robot=robot, causes=[CAUSE], test_fraction=0)
    test, _ = simulate(robot, measurement, seed=seed, effects=[EFFECT], poses=test_q, noise=0)
    return robocal.verify(result.to_dict(), test)["metrics"]["rmse"]


#: Every seed's errors, for ``--raw``.
RAW: list = []


def rms(values) -> float:
    """Root mean square over the seeds: the expected squared error the criteria minimise (a
    median understates the errors of ill-conditioned designs, whose spread is skewed)."""
    return float(np.sqrt(np.mean(np.square(values))))


def worth(planned: float, random: dict) -> float:
    """Random poses with the planned error, by a power law through the random medians."""
    n, e = np.log(list(random)), np.log(list(random.values()))
    slope, intercept = np.polyfit(n, e, 1)
    return float(np.exp((np.log(planned) - intercept) / slope))


def heldout_table(seeds: int, joint_ranges_of=None) -> list[str]:
    rows = [
        "| robot | measurement | planned 40, I | planned 40, D | random 40 | random 80 | random 120 | a random N worth: I, D | "
        "predicted: planned 40 (I), least any 40, random 120 | any 40 worth at most | planned 40 (I) ≤ random 120 |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    print("\n".join(rows), flush=True)
    for robot in ROBOTS:
        for measurement in MEASUREMENTS:
            ranges = joint_ranges_of(robot, measurement) if joint_ranges_of else None
            errors = {"I": [], "D": [], "predicted": [], "least": [], "predicted_random_40": [], "predicted_random_120": [], **{n: [] for n in RANDOM_SIZES}}
            for seed in range(seeds):
                test_q = random_poses(robot, measurement, TEST_POSES, 10_000 + seed, ranges)
                for criterion in CRITERIA:
                    p = robocal.plan(robot, measurement, PLANNED, causes=[CAUSE], seed=seed, joint_ranges=ranges, criterion=criterion, bound=criterion == "I")
                    errors[criterion].append(heldout(robot, measurement, p.q, seed, test_q))
                    if criterion == "I":
                        errors["predicted"].append(p.report["prediction"]["after"])
                        errors["least"].append(p.report["prediction"]["least_possible"])
                        errors["predicted_random_40"].append(p.report["prediction"]["random"])
                # the report's "random": as many poses drawn among the plan's candidates, predicted like the plan
                big = robocal.plan(robot, measurement, RANDOM_SIZES[-1], causes=[CAUSE], seed=seed, joint_ranges=ranges, criterion="D")
                errors["predicted_random_120"].append(big.report["prediction"]["random"])
                for n in RANDOM_SIZES:
                    errors[n].append(heldout(robot, measurement, random_poses(robot, measurement, n, 100 * n + seed, ranges), seed, test_q))
            RAW.append({"robot": robot, "measurement": measurement, "narrow": joint_ranges_of is not None, **{str(k): v for k, v in errors.items()}})
            e = {k: rms(v) for k, v in errors.items()}
            random = {n: e[n] for n in RANDOM_SIZES}
            measured = f"{e['I']:.4f} | {e['D']:.4f} | {e[40]:.4f} | {e[80]:.4f} | {e[120]:.4f}"
            worth_measured = f"{worth(e['I'], random):.0f}, {worth(e['D'], random):.0f}"
            predicted_random = {40: e["predicted_random_40"], 120: e["predicted_random_120"]}
            predicted = f"{e['predicted']:.4f}, {e['least']:.4f}, {e['predicted_random_120']:.4f} | {worth(e['least'], predicted_random):.0f}"
            beats_random = "yes" if e["I"] <= e[120] else "no"
            rows.append(f"| {robot} | {measurement} | {measured} | {worth_measured} | {predicted} | {beats_random} |")
            print(rows[-1], flush=True)
    return rows


def speed_table() -> list[str]:
    rows = ["| robot | measurement | parameters | plan 100 of 10 000 (s) |", "|---|---|---:|---:|"]
    print("\n".join(rows), flush=True)
    for robot in ROBOTS:
        for measurement in ("cable", "position", "pose"):
            started = time.perf_counter()
            report = robocal.plan(robot, measurement, 100, candidates=10_000).report
            rows.append(f"| {robot} | {measurement} | {len(report['parameters'])} | {time.perf_counter() - started:.2f} |")
            print(rows[-1], flush=True)
    return rows


def _beyond(report: dict, kinematic: bool) -> list[str]:
    """The parameters of a plan's report beyond 1 mm / 0.1 deg or undetermined (the kinematic ones alone: ``kinematic``)."""
    return [p["name"] for p in report["parameters"] if (not kinematic or is_kinematic(p["name"])) and p["within_tolerance"] is not True]


def hsr_table(quick: bool) -> list[str]:
    data = robocal.load(DATASETS / "hsr-robotcali" / "HSR-RobotCali.xlsx")
    r = robocal.robot("hsr-jr680")
    fitted = start_parameters(r, structure.apply_all(data, structure.parse_all(HSR_CONVENTIONS, r.n_joints)))
    anchor, tool = (fitted[[r.index(f"{what}_{c}") for c in "xyz"]] for what in ("anchor", "tool"))
    file_ranges = {j + 1: (data.q[:, j].min(), data.q[:, j].max()) for j in range(r.n_joints)}
    print(f"HSR: anchor {np.round(anchor, 1).tolist()} mm, tool {np.round(tool, 1).tolist()} mm (fitted on D1, nominal geometry)\n", flush=True)
    header = (
        "| joints 1-3 | joints 4-6 | poses: kinematic parameters within 1 mm / 0.1 deg | poses: every parameter | beyond at 40 poses (kinematic) | "
        "beyond at the largest tried (kinematic) | worst kinematic there | poses its 1/N fall would need |"
    )
    rows = [header, "|---|---|---|---|---:|---:|---|---:|"]
    set_up = {"causes": HSR_CONVENTIONS, "anchor": anchor, "tool": tool, "noise": HSR_NOISE_MM}
    print("\n".join(rows), flush=True)
    for first in ("file", "limits"):
        for last in ("file", "limits"):
            ranges = {j: file_ranges[j] for j in (1, 2, 3) if first == "file"} | {j: file_ranges[j] for j in (4, 5, 6) if last == "file"}
            found, at40 = {True: None, False: None}, ""
            for n in HSR_POSES[:6] if quick else HSR_POSES:
                report = robocal.plan("hsr-jr680", "cable", n, joint_ranges=ranges or None, criterion="D", **set_up).report
                if n == 40:
                    at40 = f"{len(_beyond(report, False))} ({len(_beyond(report, True))})"
                for kinematic in found:
                    if found[kinematic] is None and not _beyond(report, kinematic):
                        found[kinematic] = n
                if found[False] is not None:
                    break
            ratio = {p["name"]: p["after"] / report["tolerance"][p["unit"]] for p in report["parameters"] if is_kinematic(p["name"]) and p["after"] is not None}
            worst = max(ratio, key=ratio.get)
            entry = next(p for p in report["parameters"] if p["name"] == worst)
            need = "" if found[True] else f"{n * ratio[worst] ** 2:.2g}"
            smallest = f"{found[True] or f'none up to {n}'} | {found[False] or f'none up to {n}'}"
            beyond_last = f"{len(_beyond(report, False))} ({len(_beyond(report, True))}) of {len(report['parameters'])}"
            rows.append(f"| {first} | {last} | {smallest} | {at40 or '-'} | {beyond_last} | {worst} ± {entry['after']:.3g} {entry['unit']} | {need} |")
            print(rows[-1], flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="one seed, fewer HSR sizes")
    parser.add_argument("--part", choices=("heldout", "narrow", "speed", "hsr"), action="append")
    parser.add_argument("--raw", metavar="FILE", help="write every seed's held-out errors here (JSON)")
    args = parser.parse_args()
    parts = args.part or ["heldout", "narrow", "speed", "hsr"]
    seeds = 1 if args.quick else args.seeds
    print(f"Machine: {cpu_model()}, {os.cpu_count()} cores; robocal {robocal.__version__}\n", flush=True)
    if "heldout" in parts:
        print(f"Held-out RMSE (mm), root mean square over {seeds} simulated robots, whole joint ranges:\n", flush=True)
        heldout_table(seeds)
    if "narrow" in parts:
        print(f"\nThe same in a narrow cell (every joint within ±{NARROW_DEG:g} deg of a measurable pose):\n", flush=True)
        heldout_table(seeds, lambda robot, measurement: ranges_around(robot, measurement, NARROW_DEG))
    if args.raw:
        Path(args.raw).write_text(json.dumps(RAW, indent=1))
    if "speed" in parts:
        print("\nSpeed:\n", flush=True)
        speed_table()
    if "hsr" in parts:
        print(f"\nThe public HSR set-up (noise {HSR_NOISE_MM} mm):\n", flush=True)
        hsr_table(args.quick)


if __name__ == "__main__":
    main()
