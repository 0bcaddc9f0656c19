"""Probes behind docs/findings.md (D3) on the public UR10 series, with robocal's own folds and
nonlinear re-fits (not timings; minutes each, mostly the diagnosis itself).

``--probe coverage``: a joint map added to a series' diagnosis, its blocked-fold held-out RMSE
split into the samples the fold's map covers and those beyond or in its gaps, and the arm-link
lengths each fold's fit moves to beside the map (what held series B's joint-3 map back).

``--probe bending``: link bending's cross terms — joint j turned in proportion to joint j−1's
gravity torque, and the reverse — added one at a time to a series' diagnosis, with their
held-out RMSE on random and blocked folds.

    python benches/probe_ur10.py --probe coverage --series B --joint 3
    python benches/probe_ur10.py --probe bending --series A --measurement position
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np

from robocal.diagnosis.candidates import Candidate, acquisition_order, covered_when_fitted_on, map_candidates, map_noise
from robocal.diagnosis.model import ExtendedProblem
from robocal.diagnosis.select import _fit, _fold_problem, _folds, _held_out_residuals, _nonlinear_cv, _std, diagnose
from robocal.physics import gravity_torques
from robocal.stats import rmse_of_squares

SERIES = {"A": "Series_A/measurements_grid.csv", "B": "Series_B/measurements_joint_configurations.csv", "C": "Series_C/measurements_random_poses.csv"}
ROOT = Path(os.environ.get("ROBOCAL_DATASETS", Path(__file__).resolve().parents[1] / ".." / "shared" / "datasets")) / "ipa-robot-accuracy-ur10"


def _diagnosed(series: str, measurement):
    """The series' final diagnosis model, its fit and its fold schemes (as diagnose built them)."""
    d = diagnose(ROOT / SERIES[series], measurement=measurement)
    model, keep = d.model, d.model.idx
    order = acquisition_order(model.full_data)
    schemes = _folds(len(keep), 5, 0, np.searchsorted(keep, order[np.isin(order, keep)]), None)
    print("causes:", [c.label for c in model.causes])
    return model, d.x, schemes


def coverage(series: str, measurement, joint: int) -> None:
    model, x, schemes = _diagnosed(series, measurement)
    data, keep, j = model.full_data, model.idx, joint - 1
    q = data.q[keep]
    noise = map_noise(model.data_residuals(x).reshape(len(keep), model.k))
    lengths = [n for n in model.names if n in (f"a{joint - 1}", f"a{joint}")]
    for c in [m for m in map_candidates(model.robot, data, [j], noise, keep) if m.detail["spacing"] == 2.0 and m.detail["roughness"] in (0.003, 0.1)]:
        print(c.label)
        for i, (train, test) in enumerate(schemes["blocked"]):
            covered = covered_when_fitted_on(c.detail, q[train, j], q[test, j])
            row = [f"  fold {i}: {np.sum(~covered)} of {len(test)} held out beyond the map"]
            for name, causes in (("without", model.causes), ("with", model.causes + [c])):
                ext = ExtendedProblem(model.base, causes, data, keep)
                fold = _fold_problem(ext, train)
                fit = _fit(fold)
                e = np.sum(_held_out_residuals(ext, fold, train, test, fit.x).reshape(len(test), -1)[:, :3] ** 2, axis=1)
                parts = [f"{rmse_of_squares(e[m]):.3f}" if m.any() else "-" for m in (covered, ~covered)]
                links = ", ".join(f"{n} {fit.x[fold.names.index(n)]:.3f}" for n in lengths)
                row.append(f"{name} map: covered {parts[0]} / beyond {parts[1]} mm, {links}")
            print("; ".join(row), flush=True)


def bending(series: str, measurement) -> None:
    model, x, schemes = _diagnosed(series, measurement)
    data, keep = model.full_data, model.idx
    tau = gravity_torques(model.robot, data.q)
    base = {n: _nonlinear_cv(model, f) for n, f in schemes.items()}
    print("diagnosis: " + ", ".join(f"{n} {rmse_of_squares(e):.4f}" for n, (e, _) in base.items()) + " mm")
    for joint, source in ((3, 2), (2, 3), (4, 3), (3, 4)):  # 1-based: joint turned, torque that turns it
        c = Candidate("joint_compliance", joint - 1, "joints", tau[:, source - 1 : source].copy(), detail={"source": source})
        trial = ExtendedProblem(model.base, model.causes + [c], data, keep)
        fit = _fit(trial, x0=trial.start_from(x, model))
        std = _std(trial, fit, c)
        cv = {n: _nonlinear_cv(trial, f, [(s, trial.start_from(xf, model)) for s, xf in base[n][1]])[0] for n, f in schemes.items()}
        print(f"dq{joint} = c·tau{source}: c {trial.coefficients(fit.x, c)[0]:.3g} ± {np.nan if std is None else std[0]:.2g} rad/(N·m); "
              + ", ".join(f"{n} {rmse_of_squares(base[n][0]):.4f} -> {rmse_of_squares(cv[n]):.4f}" for n in schemes) + " mm", flush=True)  # fmt: skip


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--probe", choices=["coverage", "bending"], required=True)
    parser.add_argument("--series", choices=sorted(SERIES), required=True)
    parser.add_argument("--measurement", choices=["position", "pose"], default=None)
    parser.add_argument("--joint", type=int, default=3, help="coverage: the joint whose map is added (1-based)")
    args = parser.parse_args()
    if args.probe == "coverage":
        coverage(args.series, args.measurement, args.joint)
    else:
        bending(args.series, args.measurement)
