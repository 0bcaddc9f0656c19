"""Can a choice made on one UR10 series alone make its geometric fit carry better to another?

    python benches/transfer_choices.py [--datasets ../shared/datasets] [--record PATH]

Issue 55's last target: the geometric fit on series A verified on series C (set-up re-fitted) at
≤ 0.54 mm; the default fit gives 0.571. Each series (positions) is fitted with a small family of
settings that shrink what the data determine weakly: the default fit, a tolerance prior at nominal
(``kinematic_prior``), and the LM stopped early (``max_nfev``, the peer's early stop). Each setting is
judged on the fitting series alone by two 5-fold schemes — blocks in acquisition order, and blocks of
each joint's range (for every joint, its angles cut into five contiguous ranges: the choice rewards
extrapolating in joint space, as a new series asks) — with the held-out error of the training fold's
own fit (same session: its set-up kept). The setting each scheme picks is then verified, once, on the
other series (``robocal.verify``: only the tracker base and the tool point re-fitted). Nothing of the
verifying series enters a fit or a choice.

The other tables say why little can move: the standard deviation the fit's parameter covariance gives
its predictions on each series (the part the target's set-up re-fit cannot absorb), against the gap
between the transferred fit and the target's own geometric fit; the series' estimates of a few
parameters with their standard deviations; A's kinematic parameters moved part of the way towards
C's own fit (an analysis of what a geometry good for C costs on A and B, not a choice); and A's fit
with one parameter pinned at nominal, or with the lengths and offsets alone.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import robocal
from record import add_argument, recording
from robocal.calibration.lm import levenberg_marquardt
from robocal.calibration.problem import Problem
from robocal.kernels import covariance
from robocal.robot import setup_names

#: Parameters whose estimates the series are compared on.
COMPARED = ("a2", "a3", "d1", "theta2", "theta3", "alpha3")
SERIES = {"A": "Series_A/measurements_grid.csv", "B": "Series_B/measurements_joint_configurations.csv", "C": "Series_C/measurements_random_poses.csv"}
FOLDS = 5
#: label -> (Problem.build options, levenberg_marquardt options)
CHOICES = {
    "default": ({}, {}),
    "prior 1 mm, 0.1°": ({"kinematic_prior": (1.0, 0.1)}, {}),
    "prior 0.3 mm, 0.03°": ({"kinematic_prior": (0.3, 0.03)}, {}),
    "prior 0.1 mm, 0.01°": ({"kinematic_prior": (0.1, 0.01)}, {}),
    "LM stopped, max_nfev 3": ({}, {"max_nfev": 3}),
    "LM stopped, max_nfev 5": ({}, {"max_nfev": 5}),
    "LM stopped, max_nfev 9": ({}, {"max_nfev": 9}),
}


def fit(robot, data, choice: str):
    build, lm = CHOICES[choice]
    return levenberg_marquardt(Problem.build(robot, data, **build), **lm)


def rmse(residuals: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(residuals.reshape(-1, 3) ** 2, axis=1))))


def schemes(data) -> dict:
    """``name -> [(train, test), ...]``: acquisition-order blocks; blocks of each joint's range (6 × 5 folds)."""
    m = len(data)
    orders = {"blocked": [np.arange(m)], "joint ranges": [np.argsort(data.q[:, j], kind="stable") for j in range(data.q.shape[1])]}
    out = {}
    for name, order_list in orders.items():
        out[name] = []
        for order in order_list:
            blocks = np.array_split(order, FOLDS)
            out[name] += [(np.sort(np.concatenate(blocks[:i] + blocks[i + 1 :])), np.sort(blocks[i])) for i in range(FOLDS)]
    return out


def held_out(robot, data, choice: str, folds: list) -> float:
    """Pooled held-out RMSE of ``choice`` over ``folds`` (each fold's fit keeps its own set-up)."""
    residuals = []
    for train, test in folds:
        result = fit(robot, data.subset(train), choice)
        residuals.append(result.problem.with_data(data.subset(test)).data_residuals(result.x))
    return rmse(np.concatenate(residuals))


def propagated_std(result, data) -> float:
    """RMS over ``data``'s samples of the 3-D standard deviation of the fit's prediction from its
    kinematic parameters' covariance, less what a re-fit of the session set-up absorbs."""
    problem = result.problem
    J, r = problem.jacobian(result.x), problem.residuals(result.x)
    cov = covariance(J, r)[0]
    robot = problem.robot
    setup = set(setup_names(robot, data.measurement))
    kinematic = [i for i, n in enumerate(problem.names) if n not in setup]
    Jk = robot.residuals_and_jacobian(data.measurement, data.q, data.y, params=result.params, cols=problem.free[kinematic])[1]
    Js = robot.residuals_and_jacobian(data.measurement, data.q, data.y, params=result.params, cols=robot.columns(sorted(setup), "mask"))[1]
    Q = np.linalg.qr(Js)[0]
    A = Jk - Q @ (Q.T @ Jk)
    variance = np.einsum("ij,jk,ik->i", A, cov[np.ix_(kinematic, kinematic)], A)
    return float(np.sqrt(variance.reshape(-1, 3).sum(axis=1).mean()))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--datasets", default=str(Path(__file__).resolve().parents[1] / ".." / "shared" / "datasets"))
    add_argument(parser)
    args = parser.parse_args()
    root = Path(args.datasets) / "ipa-robot-accuracy-ur10"
    with recording(args.record):
        data = {k: robocal.load(root / v, measurement="position") for k, v in SERIES.items()}
        robot = robocal.robot("ur10")
        print("### Each setting: held out on the fitting series, verified on the others (mm)\n")
        print("| fit on | setting | held out: blocked | held out: joint ranges | verified on | implausible parameters |")
        print("|---|---|---|---|---|---|")
        picked, verified = {}, {}
        for source, train in data.items():
            folds = schemes(train)
            scores = {}
            for choice in CHOICES:
                scores[choice] = {name: held_out(robot, train, choice, f) for name, f in folds.items()}
                result = fit(robot, train, choice)
                doc = result.to_dict()
                verified[source, choice] = {t: robocal.verify(doc, data[t])["metrics"]["rmse"] for t in data if t != source}
                shown = ", ".join(f"{t} {v:.4f}" for t, v in verified[source, choice].items())
                print(
                    f"| {source} | {choice} | {scores[choice]['blocked']:.4f} | {scores[choice]['joint ranges']:.4f} | {shown} | {len(result.implausible())} |"
                )
            for name in folds:
                picked[source, name] = min(CHOICES, key=lambda c: scores[c][name])
        print("\n### The setting each scheme picks on the fitting series, verified once on the others (mm)\n")
        print("| fit → verified | default | picked by blocked folds | picked by joint-range folds |")
        print("|---|---|---|---|")
        for source in data:
            for target in data:
                if target != source:
                    cells = [f"{verified[source, picked[source, n]][target]:.4f} ({picked[source, n]})" for n in ("blocked", "joint ranges")]
                    print(f"| {source} → {target} | {verified[source, 'default'][target]:.4f} | " + " | ".join(cells) + " |")
        print("\n### What the parameters' uncertainty explains (default fit, mm)\n")
        print("| fit → verified | propagated std of the prediction | verified RMSE | target's own geometric fit (training RMSE) |")
        print("|---|---|---|---|")
        defaults = {k: fit(robot, d, "default") for k, d in data.items()}
        for source, result in defaults.items():
            for target, test in data.items():
                if target != source:
                    own = rmse(defaults[target].problem.data_residuals(defaults[target].x))
                    print(f"| {source} → {target} | {propagated_std(result, test):.4f} | {verified[source, 'default'][target]:.4f} | {own:.4f} |")

        print("\n### Each series' estimates (± their standard deviations; mm, deg)\n")
        print("| parameter | nominal | " + " | ".join(data) + " |")
        print("|---|---|" + "---|" * len(data))
        for name in COMPARED:
            k = robot.param_names.index(name)
            unit = 1.0 if robot.param_units[k] == "mm" else np.degrees(1.0)
            cells = [f"{r.params[k] * unit:.4f} ± {r.std[list(r.problem.free).index(k)] * unit:.4f}" for r in defaults.values()]
            print(f"| {name} | {robot.params[k] * unit:.4f} | " + " | ".join(cells) + " |")
        print("\n### A's kinematic parameters moved a share of the way towards C's own fit (set-up re-fitted on each series, mm)\n")
        print("| share | " + " | ".join(data) + " |")
        print("|---|" + "---|" * len(data))
        kinematic = np.array([not n.startswith(("base_", "tool_")) for n in robot.param_names])
        start, end = defaults["A"].params, defaults["C"].params
        for share in (0.0, 0.1, 0.2, 0.3, 0.5, 1.0):
            params = start.copy()
            params[kinematic] += share * (end[kinematic] - start[kinematic])
            doc = defaults["A"].to_dict()
            doc["parameters"] = [{**p, "value": float(v)} for p, v in zip(doc["parameters"], params)]
            cells = [f"{robocal.verify(doc, d)['metrics']['rmse']:.4f}" for d in data.values()]
            print(f"| {share:.1f} | " + " | ".join(cells) + " |")
        print("\n### A's fit with fewer parameters free, verified on B and C (mm)\n")
        print("| free | training RMSE on A | B | C |")
        print("|---|---|---|---|")
        names = defaults["A"].problem.names
        setup = set(setup_names(robot, "position"))
        masks = {
            "all (default)": names,
            "lengths and offsets alone (a, d, theta)": [n for n in names if n in setup or n[0] in "adt" and not n.startswith("alpha")],
        }
        masks.update({f"all but {n}": [m for m in names if m != n] for n in names if n not in setup})
        for label, mask in masks.items():
            result = levenberg_marquardt(Problem.build(robot, data["A"], mask=mask))
            doc = result.to_dict()
            cells = [f"{robocal.verify(doc, data[t])['metrics']['rmse']:.4f}" for t in "BC"]
            print(f"| {label} | {rmse(result.problem.data_residuals(result.x)):.4f} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
