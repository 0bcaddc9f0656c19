"""The damped step of robocal's LM on D1: normal equations vs the least squares of the
augmented system.

Runs robocal's LM loop on D1 (80 % random training split, seed 0) from the same start with its
damped step solved two ways (``robocal.solve_damped(..., factor=...)``, both in Rust): by the
normal equations (``"normal"``, the paper's formulation and robocal's LM before 2026-11-23) and
as the least squares of ``[J; sqrt(lam)·D^½] s ≈ [r; 0]`` by QR of ``J`` itself (``"lstsq"``,
robocal's LM now; MINPACK does the same). Prints iterations, the stop message, training and
held-out RMSE and ``a1``, the condition number of the column-scaled Jacobian, and the time of
one damped step of each kind there.

    python benches/lm_step_conditioning.py
"""

from __future__ import annotations

import os
import timeit
from pathlib import Path
from unittest import mock

import numpy as np

import robocal
import robocal.calibration.lm as lm
from robocal.calibration import Problem
from robocal.core import solve_damped
from robocal.data import random_split

D1 = Path(os.environ.get("ROBOCAL_DATASETS", Path(__file__).resolve().parents[2] / "shared" / "datasets")) / "hsr-robotcali" / "HSR-RobotCali.xlsx"


def rmse(r: np.ndarray) -> float:
    return float(np.sqrt(np.mean(r * r)))


def with_factor(factor: str):
    """``solve_damped`` with its ``factor`` fixed, whatever the LM asks for."""
    return lambda J, r, lam, damping, _factor=None: solve_damped(J, r, lam, damping, factor)


def main() -> None:
    data = robocal.load(D1)
    train, test = random_split(len(data), 0.2, seed=0)
    problem = Problem.build(robocal.robot("hsr-jr680"), data.subset(train))
    held_out = problem.with_data(data.subset(test))
    a1 = list(problem.names).index("a1")
    print("| damped step | iterations | evaluations | stop | training RMSE (mm) | held-out RMSE (mm) | a1 (mm) |")
    print("|---|---:|---:|---|---:|---:|---:|")
    for factor in ("normal", "lstsq"):
        with mock.patch.object(lm, "solve_damped", with_factor(factor)):
            fit = lm.levenberg_marquardt(problem)
        print(f"| {factor} | {fit.nit} | {fit.nfev} | {fit.message} | {rmse(problem.data_residuals(fit.x)):.6f} | {rmse(held_out.data_residuals(fit.x)):.6f} | {fit.x[a1]:.1f} |")
    # When the QR-step LM passes the normal-equation LM's stopping point and scipy's best of
    # docs/benchmarks.md (its history holds ½‖r‖² per iteration; one residual row per sample).
    path = np.sqrt(2.0 * np.asarray(fit.history) / len(problem.data))
    for level in (0.160614, 0.140747):
        k = int(np.argmax(path <= level))
        print(f"lstsq passes {level} mm at iteration {k} of {len(path) - 1} (~{fit.time_s * k / (len(path) - 1):.2f} s of its {fit.time_s:.2f} s)")
    J, r = problem.jacobian(fit.x), problem.residuals(fit.x)
    s = np.linalg.svd(J / np.linalg.norm(J, axis=0), compute_uv=False)
    print(f"\ncondition number of the column-scaled Jacobian at the last solution: {s[0] / s[-1]:.3g} (of JᵀJ: {(s[0] / s[-1]) ** 2:.3g})")
    # The price of one damped step there (λ = 1e-9, best of 200 calls).
    for factor in ("normal", "lstsq"):
        best = min(timeit.repeat(lambda: solve_damped(J, r, 1e-9, "marquardt", factor), number=1, repeat=200))
        print(f"one damped step, factor={factor!r} ({solve_damped(J, r, 1e-9, 'marquardt', factor)[1]}): {best * 1e3:.3f} ms for J of {J.shape[0]} x {J.shape[1]}")


if __name__ == "__main__":
    main()
