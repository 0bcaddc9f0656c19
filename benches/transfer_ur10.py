"""Fit on one UR10 series, verify on another: does what a calibration found carry to a new session?

    python benches/transfer_ur10.py [--datasets ../shared/datasets] [--measurement position|pose]

For each series (A, B, C): ``robocal.calibrate`` on all of it, geometric and with the causes
``robocal.diagnose`` names on it (``calibrate --causes``); then ``robocal.verify`` on each other
series — the robot as calibrated (kinematics, reading conventions, joint causes), only the
session set-up re-fitted (tracker base frame, tool point); the session's own terms (drift,
steps, outliers) are not carried. Prints a Markdown table of the verified RMSE (eq. 28) of the
nominal, geometric and extended models — the extended one without and with joint maps
(``diagnose(maps=False)``) — the share of the test samples beyond a map's fitted range (where
the map corrects nothing) and, on the other samples alone (every map applies; the set-up
re-fitted on them), the geometric and the extended model's RMSE. The CLI equivalent of one cell:

    robocal calibrate A.csv --measurement position --test-fraction 0 --out A.json
    robocal verify A.json B.csv
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import robocal
from robocal.causes import structure
from robocal.causes.candidates import map_coverage_mask, result_maps

#: Fewest covered samples the within-range comparison is made on.
MIN_COVERED = 50
SERIES = {"A": "Series_A/measurements_grid.csv", "B": "Series_B/measurements_joint_configurations.csv", "C": "Series_C/measurements_random_poses.csv"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--datasets", default=str(Path(__file__).resolve().parents[1] / ".." / "shared" / "datasets"))
    parser.add_argument("--measurement", default="position", choices=("position", "pose"))
    args = parser.parse_args()
    root = Path(args.datasets) / "ipa-robot-accuracy-ur10"
    data = {k: robocal.load(root / v, measurement=args.measurement) for k, v in SERIES.items()}
    print(
        f"| train → test ({args.measurement}) | causes carried | nominal (mm) | geometric (mm) | extended, no maps (mm) | extended with maps (mm) "
        "| beyond a map's range | within the maps' ranges: samples: geometric / with maps (mm) |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for train in SERIES:
        geometric = robocal.calibrate(data[train], test_fraction=0.0).to_dict()
        extended = {}
        for maps in (False, True):
            report = robocal.diagnose(data[train], maps=maps).to_dict()
            extended[maps] = robocal.calibrate(data[train], test_fraction=0.0, causes=report).to_dict()
        for test in SERIES:
            if test == train:
                continue
            geo, plain, ext = (robocal.verify(r, data[test]) for r in (geometric, extended[False], extended[True]))
            carried = ", ".join(ext["applied"]["structure"] + ext["applied"]["causes"]) or "none"
            n = ext["metrics_covered"]["n"] if ext["metrics_covered"] else 0
            beyond = 1.0 - n / ext["samples"]
            # the set-up is re-fitted on the covered samples: too few of them leave nothing to compare
            within = f"{n}: " + " / ".join(f"{v:.4f}" for v in _covered_rmse((geometric, extended[True]), data[test])) if n >= MIN_COVERED else f"{n}: —"
            print(
                f"| {train} → {test} | {carried} | {geo['nominal']['metrics']['rmse']:.4f} | {geo['metrics']['rmse']:.4f} | {plain['metrics']['rmse']:.4f} "
                f"| {ext['metrics']['rmse']:.4f} | {beyond:.0%} | {within} |",
                flush=True,
            )


def _covered_rmse(results: tuple, data: robocal.Dataset) -> list[float]:
    """Each result's verified RMSE on the samples of ``data`` that every joint map of the last
    result covers, its set-up re-fitted on those samples alone (so that they compare)."""
    read = structure.apply_all(data, structure.parse_all(results[-1].get("structure", []), data.q.shape[1]))
    inside = np.flatnonzero(map_coverage_mask(result_maps(results[-1]["causes"]), read.q))
    return [robocal.verify(r, data.subset(inside))["metrics"]["rmse"] for r in results]


if __name__ == "__main__":
    main()
