"""Why robocal's production LM stops earlier than MINPACK on D1: the normal-equation step.

Runs robocal's LM loop on D1 (80 % random training split, seed 0) twice from the same start:
with its damped step from the normal equations (``robocal.solve_damped``, Rust) and with the
same damped step as a least-squares solve of the augmented system ``[J; sqrt(lam)·D] s ≈ [r; 0]``
(NumPy ``lstsq``, which factors ``J`` itself as MINPACK does). Prints training and held-out
RMSE, iterations, the stop message and ``a1``, and the condition number of the column-scaled
Jacobian at the first solution.

    python benches/lm_step_conditioning.py
"""

from __future__ import annotations

import os
from pathlib import Path
from unittest import mock

import numpy as np

import robocal
import robocal.calibration.lm as lm
from robocal.calibration import Problem
from robocal.data import random_split

D1 = Path(os.environ.get("ROBOCAL_DATASETS", Path(__file__).resolve().parents[2] / "shared" / "datasets")) / "hsr-robotcali" / "HSR-RobotCali.xlsx"


def augmented_step(J, r, lam, damping):
    """The Marquardt-damped step as the least-squares solution of the augmented system."""
    d = np.sqrt(lam * np.einsum("ij,ij->j", J, J))
    A = np.vstack([J, np.diag(d)])
    b = np.concatenate([r, np.zeros(J.shape[1])])
    return np.linalg.lstsq(A, b, rcond=None)[0], "lstsq"


def rmse(r: np.ndarray) -> float:
    return float(np.sqrt(np.mean(r * r)))


def main() -> None:
    data = robocal.load(D1)
    train, test = random_split(len(data), 0.2, seed=0)
    problem = Problem.build(robocal.robot("hsr-jr680"), data.subset(train))
    held_out = problem.with_data(data.subset(test))
    a1 = list(problem.names).index("a1")
    print("| damped step | iterations | stop | training RMSE (mm) | held-out RMSE (mm) | a1 (mm) |")
    print("|---|---:|---|---:|---:|---:|")
    for label, step in (("normal equations (robocal)", None), ("augmented least squares", augmented_step)):
        with mock.patch.object(lm, "solve_damped", step or lm.solve_damped):
            fit = lm.levenberg_marquardt(problem)
        print(f"| {label} | {fit.nit} | {fit.message} | {rmse(problem.data_residuals(fit.x)):.6f} | {rmse(held_out.data_residuals(fit.x)):.6f} | {fit.x[a1]:.1f} |")
        if step is None:
            J = problem.jacobian(fit.x)
            s = np.linalg.svd(J / np.linalg.norm(J, axis=0), compute_uv=False)
            condition = s[0] / s[-1]
    print(f"\ncondition number of the column-scaled Jacobian at robocal's solution: {condition:.3g} (normal equations: {condition ** 2:.3g})")


if __name__ == "__main__":
    main()
