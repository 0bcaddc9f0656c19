"""Fit on one UR10 series, test on another: does what diagnose found on one session carry over?

    python benches/transfer_ur10.py [--datasets ../shared/datasets]

For each ordered pair of Series A, B and C (positions): run ``robocal.diagnose`` on the training
series; then on the test series keep every kinematic parameter and every joint cause fitted on
the training series, and re-fit only what differs between sessions — the tracker's base frame
and the tool point. Session-specific causes (drift, outliers) are not carried over. Prints the
test series' RMSE of the geometric model and of the extended model.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import robocal
from robocal.calibration import Problem
from robocal.calibration.lm import levenberg_marquardt
from robocal.data import load
from robocal.diagnosis import ExtendedProblem, diagnose, library

SERIES = {"A": "Series_A/measurements_grid.csv", "B": "Series_B/measurements_joint_configurations.csv", "C": "Series_C/measurements_random_poses.csv"}
SETUP = [f"base_{c}" for c in ("x", "y", "z", "rx", "ry", "rz")] + ["tool_x", "tool_y", "tool_z"]


def rmse_on(robot, data, params) -> float:
    """RMSE after re-fitting only the session set-up (base frame, tool point) on ``data``."""
    free = np.array([robot.index(n) for n in SETUP])
    fit = levenberg_marquardt(Problem(robot, data, free, np.asarray(params, dtype=float).copy()))
    return fit.metrics["train"]["rmse"]  # eq. (28): per-sample Euclidean errors


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--datasets", default=str(Path(__file__).resolve().parents[1] / ".." / "shared" / "datasets"))
    root = Path(parser.parse_args().datasets) / "ipa-robot-accuracy-ur10"
    robot = robocal.robot("ur10")
    data = {k: load(root / v, measurement="position") for k, v in SERIES.items()}
    print("| train → test | causes carried over | test RMSE geometric (mm) | test RMSE extended (mm) |")
    print("|---|---|---|---|")
    for train in SERIES:
        d = diagnose(data[train])
        geometric = levenberg_marquardt(ExtendedProblem(d.model.base, [], d.model.full_data, d.model.idx))
        causes = [c for c in d.model.causes if c.stage == "joints"]
        for test in SERIES:
            if test == train:
                continue
            target = data[test]
            # The same causes, with their bases evaluated on the test series' joint angles.
            pool = {c.label: c for c in library(robot, target, [])}
            q = target.q.copy()
            for c in causes:
                q[:, c.joint] += pool[c.label].basis @ d.model.coefficients(d.x, c)
            shifted = type(target)(q=q, y=target.y, measurement=target.measurement, robot=target.robot, rows=target.rows)
            geo = rmse_on(robot, target, geometric.problem.full(geometric.x))
            ext = rmse_on(robot, shifted, d.model.full(d.x))
            print(f"| {train} → {test} | {', '.join(c.label for c in causes) or 'none'} | {geo:.4f} | {ext:.4f} |")


if __name__ == "__main__":
    main()
