"""Compensation (inverse kinematics on the calibrated model within the joint limits): robocal's
bounded Levenberg–Marquardt with restarts against scipy's ``least_squares(bounds=...)``.

Targets are made from joint configurations drawn uniformly inside the joint limits, so every
one is reachable within them: tool positions, then tool poses (position and orientation, the
calibrated model's ``predict("pose")``). The solvers start from the same seed — the nominal
model's solution, as ``robocal compensate`` computes it when the targets carry no joints — and
solve on the calibrated model (pose residuals weighted as compensate weighs them,
``ROTATION_WEIGHT_MM``); a target counts as reached when the position error is below 1e-4 mm
(and, for a pose, the rotation error below 1e-7 rad) with every joint inside its limits. Times
are per target, the seed included, one process, one core.

    python benches/bench_compensation.py [--robot abb-irb120] [--targets 200] [--seed 0]
"""

from __future__ import annotations

import argparse
import os
import time

from record import add_argument, recording

os.environ.setdefault("RAYON_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from scipy.optimize import least_squares  # noqa: E402

import robocal  # noqa: E402
from robocal.compensation import Targets, compensate, joint_columns, joint_limits, nominal_seed, residual_weights, solve_joints  # noqa: E402
from robocal.simulation import simulate  # noqa: E402

TOL_MM = 1e-4
TOL_RAD = 1e-7


def scipy_solve(robot, measurement, target, seed, lower, upper):
    cols = joint_columns(robot)
    y = target[None, :]
    w = residual_weights(measurement)
    fun = lambda q: -robot.residuals(measurement, q[None, :], y).ravel() * w  # noqa: E731  h - y
    jac = lambda q: robot.jacobian(measurement, q[None, :], y=y, cols=cols) * w[:, None]  # noqa: E731
    # least_squares needs a start strictly inside the bounds
    x0 = np.clip(seed, lower + 1e-9 * (upper - lower), upper - 1e-9 * (upper - lower))
    sol = least_squares(fun, x0, jac=jac, bounds=(lower, upper), method="trf", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=200)
    return sol.x


def _reached(robot, measurement, q, target, lower, upper) -> bool:
    """Within the limits, and on the target to TOL_MM (and TOL_RAD): checked on the model, not taken from a solver's word."""
    r = robot.residuals(measurement, q[None, :], target[None, :])[0]
    close = np.linalg.norm(r[:3]) < TOL_MM and (measurement == "position" or np.linalg.norm(r[3:]) < TOL_RAD)
    return bool(close and np.all(q >= lower - 1e-12) and np.all(q <= upper + 1e-12))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="abb-irb120")
    parser.add_argument("--targets", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    add_argument(parser)
    args = parser.parse_args()
    with recording(args.record):
        data, _ = simulate(args.robot, "position", samples=300, seed=args.seed + 1)
        result = robocal.calibrate(data, robot=args.robot, test_fraction=0.0)
        doc = result.to_dict()
        calibrated, _ = robocal.load_result(doc)
        nominal = robocal.Robot(calibrated.name, calibrated.joints, doc["robot_model"]["nominal"])
        setup = [k for k, n in enumerate(calibrated.param_names) if n.startswith(("base_", "tool_"))]
        nominal.params[setup] = calibrated.params[setup]  # as compensate() builds it
        lower, upper = joint_limits(calibrated)
        rng = np.random.default_rng(args.seed)
        q_true = lower + (upper - lower) * rng.random((args.targets, calibrated.n_joints))
        with open("/proc/loadavg") as f:
            load = f.read().split()[:3]
        print(f"{args.robot}, {args.targets} targets from configurations inside the joint limits (seed {args.seed}); load {' '.join(load)}")
        for measurement in ("position", "pose"):
            targets = calibrated.predict(measurement, q_true)

            t0 = time.perf_counter()
            rows = compensate(doc, Targets(targets, None, np.arange(2, args.targets + 2)), frame="session")  # the calibrated set-up's frame
            t_robocal = (time.perf_counter() - t0) / args.targets
            ok_robocal = sum(_reached(calibrated, measurement, np.radians(r["q"]), y, lower, upper) for r, y in zip(rows, targets))

            t0 = time.perf_counter()
            ok_first = 0
            for target in targets:  # robocal from the nominal seed alone: the bounded LM without restarts
                q, _, _ = solve_joints(calibrated, target, nominal_seed(nominal, target), restarts=0)
                ok_first += _reached(calibrated, measurement, q, target, lower, upper)
            t_first = (time.perf_counter() - t0) / args.targets

            t0 = time.perf_counter()
            ok_scipy = 0
            for target in targets:
                q = scipy_solve(calibrated, measurement, target, nominal_seed(nominal, target), lower, upper)
                ok_scipy += _reached(calibrated, measurement, q, target, lower, upper)
            t_scipy = (time.perf_counter() - t0) / args.targets

            print(f"\n{measurement} targets")
            print(f"{'solver':58s} {'reached':>9s} {'rate':>7s} {'ms/target':>10s}")
            for name, ok, t in (
                ("robocal compensate (bounded LM, nominal seed + restarts)", ok_robocal, t_robocal),
                ("robocal bounded LM, no restarts on the calibrated model", ok_first, t_first),
                ("scipy least_squares(bounds=..., trf), nominal seed", ok_scipy, t_scipy),
            ):
                print(f"{name:58s} {ok:>5d}/{args.targets:<3d} {ok / args.targets:>7.1%} {t * 1e3:>10.2f}")


if __name__ == "__main__":
    main()
