"""Convergence on real, ill-conditioned data: robocal's production LM against scipy, side by side.

    python benches/bench_convergence.py            # D1, D2, D3 B and 20 000 simulated cable samples

Each problem is the one ``robocal.calibrate`` solves (80/20 random split, seed 0; UR10 tracker
positions), solved from the same start by

* robocal's LM as shipped (geodesic acceleration, uphill steps, stop at the noise level);
* the same LM run to scipy's tolerances (``statistical_stop=False``, 1e-10, budget 20 000);
* scipy ``least_squares`` ``trf`` with ``x_scale="jac"`` and the analytic Jacobian (Rust);
* scipy ``least_squares`` ``lm`` (MINPACK) with the analytic Jacobian.

Prints residual and Jacobian evaluations, wall time, whether the solver says it converged, the
final training RMSE and the held-out RMSE (eq. 28: the cable residual, or the norm of the 3-D
position residual, per sample). Run it alone on the machine: the times are
wall-clock.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np
from machine import cpu_model, load_text
from record import add_argument, recording
from scipy.optimize import least_squares

import robocal
from robocal.calibration import Problem, metrics
from robocal.calibration.lm import levenberg_marquardt
from robocal.data import random_split

DATASETS = Path(os.environ.get("ROBOCAL_DATASETS", Path(__file__).resolve().parents[2] / "shared" / "datasets"))
CASES = {
    "D1 (HSR JR680, cable)": (DATASETS / "hsr-robotcali" / "HSR-RobotCali.xlsx", None),
    "D2 (ABB IRB 120, cable)": (DATASETS / "robotcali-abb-irb120" / "RobotCali-new.xlsx", None),
    "D3 B (UR10, positions)": (DATASETS / "ipa-robot-accuracy-ur10" / "Series_B" / "measurements_joint_configurations.csv", "position"),
}
BUDGET = 20000


def rmse(problem: Problem, x: np.ndarray) -> float:
    """Eq. (28): per-sample error the cable residual or the norm of the 3-D position residual."""
    return metrics(problem.data_residuals(x), problem.data.measurement)["rmse"]


def problems(samples: int):
    for name, (path, measurement) in CASES.items():
        yield name, robocal.load(path, measurement=measurement)
    data, _ = robocal.simulate("hsr-jr680", "cable", samples=samples, seed=0)
    yield f"simulated HSR JR680 cable, {samples} samples", data


def scipy_solver(method: str):
    def solve(problem: Problem):
        counts = {"jac": 0}

        def jac(x):
            counts["jac"] += 1
            return -problem.jacobian(x)

        options = {"x_scale": "jac"} if method == "trf" else {}
        res = least_squares(problem.residuals, problem.x0, jac=jac, method=method, ftol=1e-10, xtol=1e-10, gtol=1e-10, max_nfev=BUDGET, **options)
        return res.x, res.nfev, counts["jac"], res.status > 0, res.message

    return solve


def robocal_solver(**options):
    def solve(problem: Problem):
        fit = levenberg_marquardt(problem, **options)
        return fit.x, fit.nfev, fit.njev, fit.success, fit.message

    return solve


SOLVERS = {
    "robocal LM (stop at the noise level)": robocal_solver(),
    "robocal LM to scipy's tolerances": robocal_solver(statistical_stop=False, max_nfev=BUDGET),
    'scipy trf, x_scale="jac", analytic J': scipy_solver("trf"),
    "scipy lm (MINPACK), analytic J": scipy_solver("lm"),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=20000, help="simulated samples (default 20000)")
    add_argument(parser)
    args = parser.parse_args()
    with recording(args.record):
        print(f"machine: {cpu_model()}, {os.cpu_count()} logical CPUs; load average {load_text()} at the start; robocal {robocal.__version__}\n")
        print("| problem | solver | residual evals | Jacobian evals | time (s) | converged | training RMSE (mm) | held-out RMSE (mm) |")
        print("|---|---|---:|---:|---:|---|---:|---:|")
        for name, data in problems(args.samples):
            train, test = random_split(len(data), 0.2, seed=0)
            problem = Problem.build(robocal.robot(data.robot), data.subset(train))
            held_out = problem.with_data(data.subset(test))
            for solver, solve in SOLVERS.items():
                t0 = time.perf_counter()
                x, nfev, njev, converged, _ = solve(problem)
                elapsed = time.perf_counter() - t0
                print(
                    f"| {name} | {solver} | {nfev} | {njev} | {elapsed:.2f} | {'yes' if converged else 'no'} | {rmse(problem, x):.6f} | {rmse(held_out, x):.6f} |",
                    flush=True,
                )
        print(f"\nload average {load_text()} at the end")


if __name__ == "__main__":
    main()
