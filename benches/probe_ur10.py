"""Probes behind docs/findings.md (D3) on the public UR10 series, with robocal's own folds and
nonlinear re-fits (not timings; minutes each, mostly the diagnosis itself).

``--probe coverage``: a joint map added to a series' diagnosis, its blocked-fold held-out RMSE
split into the samples the fold's map covers and those beyond or in its gaps, and the arm-link
lengths each fold's fit moves to beside the map (what held series B's joint-3 map back).

``--probe bending``: link bending's cross terms — joint j turned in proportion to joint j−1's
gravity torque, and the reverse — added one at a time to a series' diagnosis, with their
held-out RMSE on random and blocked folds.

``--probe outliers --report R.json``: the outliers a series' diagnosis (``robocal diagnose
<series> --json R.json``) named, beside the joint move that preceded each sample (a reading
taken before the arm settled) and, where the series revisits the sample's joint configuration,
how far apart the two visits' measured positions lie (a glitch of one reading).

    python benches/probe_ur10.py --probe coverage --series B --joint 3
    python benches/probe_ur10.py --probe bending --series A --measurement position
    robocal diagnose $A --measurement position --json a.json && python benches/probe_ur10.py --probe outliers --series A --report a.json
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import numpy as np
import robocal
from robocal.diagnosis.budget import REVISIT_TOLERANCE
from robocal.causes.candidates import Candidate, acquisition_order, covered_when_fitted_on, map_candidates, map_noise
from robocal.causes.problem import ExtendedProblem, reported_rmse
from robocal.diagnosis.select import diagnose
from robocal.diagnosis.validation import coefficient_std, fit_problem, fold_problem, fold_schemes, held_out_errors, cross_validate
from robocal.diagnosis.settling import LONG_MOVE_DEG, preceding_move_deg
from robocal.physics import gravity_torques
from robocal.stats import rmse_of_squares
from scipy.spatial import cKDTree

SERIES = {"A": "Series_A/measurements_grid.csv", "B": "Series_B/measurements_joint_configurations.csv", "C": "Series_C/measurements_random_poses.csv"}
ROOT = Path(os.environ.get("ROBOCAL_DATASETS", Path(__file__).resolve().parents[1] / ".." / "shared" / "datasets")) / "ipa-robot-accuracy-ur10"


def _diagnosed(series: str, measurement):
    """The series' final diagnosis model, its fit and its fold schemes (as diagnose built them)."""
    d = diagnose(ROOT / SERIES[series], measurement=measurement)
    model, keep = d.model, d.model.idx
    order = acquisition_order(model.full_data)
    schemes = fold_schemes(model.full_data.q[keep], 5, 0, np.searchsorted(keep, order[np.isin(order, keep)]), None)
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
                fold = fold_problem(ext, train)
                fit = fit_problem(fold)
                e = held_out_errors(ext, fold, train, test, fit.x)[:, 0]
                parts = [f"{rmse_of_squares(e[m]):.3f}" if m.any() else "-" for m in (covered, ~covered)]
                links = ", ".join(f"{n} {fit.x[fold.names.index(n)]:.3f}" for n in lengths)
                row.append(f"{name} map: covered {parts[0]} / beyond {parts[1]} mm, {links}")
            print("; ".join(row), flush=True)


def bending(series: str, measurement) -> None:
    model, x, schemes = _diagnosed(series, measurement)
    data, keep = model.full_data, model.idx
    tau = gravity_torques(model.robot, data.q)
    base_cv, base_fits = cross_validate(model, schemes)
    print("diagnosis: " + ", ".join(f"{n} {reported_rmse(e):.4f}" for n, e in base_cv.items()) + " mm")
    for joint, source in ((3, 2), (2, 3), (4, 3), (3, 4)):  # 1-based: joint turned, torque that turns it
        c = Candidate("joint_compliance", joint - 1, "joints", tau[:, source - 1 : source].copy(), detail={"source": source})
        trial = ExtendedProblem(model.base, model.causes + [c], data, keep)
        fit = fit_problem(trial, x0=trial.start_from(x, model))
        std = coefficient_std(trial, fit, c)
        cv, _ = cross_validate(trial, schemes, base_fits, model)
        print(
            f"dq{joint} = c·tau{source}: c {trial.coefficients(fit.x, c)[0]:.3g} ± {np.nan if std is None else std[0]:.2g} rad/(N·m); "
            + ", ".join(f"{n} {reported_rmse(base_cv[n]):.4f} -> {reported_rmse(cv[n]):.4f}" for n in schemes)
            + " mm",
            flush=True,
        )


def outliers(series: str, report: Path) -> None:
    data = robocal.load(ROOT / SERIES[series], measurement=json.loads(report.read_text())["measurement"])
    named = next((e["params"] for e in json.loads(report.read_text())["effects"] if e["kind"] == "outliers"), None)
    if named is None:
        print("no outliers named")
        return
    samples, revealed = np.array(named["samples"]), set(named.get("revealed_by_causes", []))
    move = preceding_move_deg(data)
    is_revealed = np.array([r in revealed for r in data.rows[samples]], dtype=bool)
    long = move >= LONG_MOVE_DEG
    print(f"{len(samples)} outliers, {is_revealed.sum()} revealed by the causes")
    for name, group in (("baseline's", samples[~is_revealed]), ("revealed", samples[is_revealed])):
        if len(group):
            print(
                f"  {name}: {np.sum(long[group])} of {len(group)} follow a joint move of {LONG_MOVE_DEG:g} deg or more "
                f"({np.mean(long[group]):.0%}; of all samples {np.mean(long):.1%}); moves before them (deg): {np.round(move[group], 1).tolist()}"
            )
    tree = cKDTree(data.q)
    for s in samples:
        others = [j for j in tree.query_ball_point(data.q[s], REVISIT_TOLERANCE, p=np.inf) if j != s]
        if others:
            gap = [float(np.linalg.norm(data.y[s, :3] - data.y[j, :3])) for j in others]
            print(f"  row {data.rows[s]}: measured {np.round(gap, 3).tolist()} mm from its revisit(s), rows {data.rows[others].tolist()}")
    pairs = tree.query_pairs(REVISIT_TOLERANCE, p=np.inf, output_type="ndarray")
    if len(pairs):
        gap = np.linalg.norm(data.y[pairs[:, 0], :3] - data.y[pairs[:, 1], :3], axis=1)
        print(
            f"  every revisit: {len(pairs)} pairs, measured positions apart by median {np.median(gap):.3f} mm, 90th percentile {np.percentile(gap, 90):.3f} mm"
        )


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--probe", choices=["coverage", "bending", "outliers"], required=True)
    parser.add_argument("--series", choices=sorted(SERIES), required=True)
    parser.add_argument("--measurement", choices=["position", "pose"], default=None)
    parser.add_argument("--joint", type=int, default=3, help="coverage: the joint whose map is added (1-based)")
    parser.add_argument("--report", type=Path, help="outliers: the series' diagnose --json report")
    args = parser.parse_args()
    if args.probe == "coverage":
        coverage(args.series, args.measurement, args.joint)
    elif args.probe == "outliers":
        outliers(args.series, args.report)
    else:
        bending(args.series, args.measurement)
