"""Fitting joint maps with the geometry: the sparse normal-equation solve against the dense QR.

    OPENBLAS_NUM_THREADS=1 python benches/bench_maps.py [--series A] [--spacing 2] [--repeats 3]

One UR10 series (positions; A: 11 911 samples, 35 733 residual rows) with a joint map on every
joint (cubic B-splines, ``--spacing`` degrees, roughness 0.03°) fitted together with the
geometry by robocal's LM from the same start, twice: with the model's sparse Jacobian (normal
equations, the Cholesky factor of ``JᵀJ`` per damping) and with the same Jacobian made dense (the Rust
column-pivoted QR every other fit uses). Both runs reach the same cost; the table gives the
median wall time of ``--repeats`` runs, the Jacobian's size and the machine. Diagnose runs its
fits with one BLAS thread (``threadpool_limits``), as this script asks for through the variable.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import numpy as np
from machine import cpu_model, load_text
from record import add_argument, recording

import robocal
from robocal.calibration.problem import Problem
from robocal.causes.candidates import map_candidate, map_noise
from robocal.causes.problem import ExtendedProblem
from robocal.diagnosis.select import baseline_mask
from robocal.diagnosis.validation import fit_problem

DATASETS = Path(os.environ.get("ROBOCAL_DATASETS", Path(__file__).resolve().parents[2] / "shared" / "datasets"))
SERIES = {"A": "Series_A/measurements_grid.csv", "B": "Series_B/measurements_joint_configurations.csv", "C": "Series_C/measurements_random_poses.csv"}


class Dense(ExtendedProblem):
    """The same model with its Jacobian handed to the solver as a dense array."""

    def jacobian(self, x):
        J = super().jacobian(x)
        return J.toarray() if hasattr(J, "toarray") else J


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--series", default="A", choices=sorted(SERIES))
    parser.add_argument("--spacing", type=float, default=2.0)
    parser.add_argument("--repeats", type=int, default=3)
    add_argument(parser)
    args = parser.parse_args()
    with recording(args.record):
        data = robocal.load(DATASETS / "ipa-robot-accuracy-ur10" / SERIES[args.series], measurement="position")
        robot = robocal.robot("ur10")
        base = Problem.build(robot, data, mask=baseline_mask(robot, "position", True))
        idx = np.arange(len(data))
        plain = ExtendedProblem(base, [], data, idx)
        geometric = fit_problem(plain)
        noise = map_noise(plain.data_residuals(geometric.x).reshape(len(data), 3))
        maps = [map_candidate(data, j, args.spacing, 0.03, noise, data.q[:, j]) for j in range(6)]
        rows = []
        for name, cls in (("sparse normal equations (the LM's Cholesky of JᵀJ)", ExtendedProblem), ("dense QR (Rust DampedQr)", Dense)):
            model = cls(base, maps, data, idx)
            x0 = np.concatenate([geometric.x, np.zeros(model.n - len(geometric.x))])
            times, fit = [], None
            for _ in range(args.repeats):
                t = time.perf_counter()
                fit = fit_problem(model, x0=x0)
                times.append(time.perf_counter() - t)
            rows.append((name, statistics.median(times), fit.cost, fit.nfev, model.n))
        J = ExtendedProblem(base, maps, data, idx).jacobian(x0)
        print(f"machine: {cpu_model()}, {os.cpu_count()} cores, load {load_text()}; OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}")
        print(f"UR10 series {args.series}: {len(data)} samples, Jacobian {J.shape[0]} x {J.shape[1]}, {J.nnz / J.shape[0]:.1f} non-zeros per row\n")
        print("| solver | median fit time (s) | cost | evaluations | unknowns |")
        print("|---|---|---|---|---|")
        for name, t, cost, nfev, n in rows:
            print(f"| {name} | {t:.2f} | {cost:.6g} | {nfev} | {n} |")
        print(f"\nratio dense / sparse: {rows[1][1] / rows[0][1]:.1f}x")


if __name__ == "__main__":
    main()
