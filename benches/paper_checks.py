"""The checks behind the discussion in docs/paper-reproduction.md, in one command.

    python benches/paper_checks.py [--datasets ../shared/datasets]

Prints: the joint ranges of the public D1 file; the column-scaled condition number of D1's
identification Jacobian at the production LM's optimum and its implausible parameters; a sweep of the fixed damping λ of the
paper's eq. (14) on the first paper split of D1; the production LM on the five paper splits of D2
(iterations, stop reason, condition number); the UR10 "Goal" columns against nominal forward
kinematics.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import robocal
from robocal.calibration import METHODS, Problem, metrics
from robocal.calibration.lm import levenberg_marquardt
from robocal.data import load, paper_split, random_split


def scaled_condition(J: np.ndarray) -> float:
    s = np.linalg.svd(J / np.linalg.norm(J, axis=0), compute_uv=False)
    return float(s[0] / s[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--datasets", default=str(Path(__file__).resolve().parents[1] / ".." / "shared" / "datasets"))
    root = Path(parser.parse_args().datasets)

    d1 = load(root / "hsr-robotcali" / "HSR-RobotCali.xlsx")
    deg = np.degrees(d1.q)
    print("D1 joint ranges (deg): " + ", ".join(f"q{j + 1} {lo:.1f}..{hi:.1f}" for j, (lo, hi) in enumerate(zip(deg.min(0), deg.max(0)))))

    hsr = robocal.robot("hsr-jr680")
    train, _ = random_split(len(d1), 0.2, seed=0)
    p = Problem.build(hsr, d1.subset(train))
    fit = levenberg_marquardt(p)
    print(f"D1 80 % training: {len(p.free)} free parameters, scaled condition number at the LM optimum {scaled_condition(p.jacobian(fit.x)):.2g}")
    flags = sorted(fit.implausible(), key=lambda f: -abs(f["deviation"]) / f["limit"])
    shown = [
        f"{f['name']} {f['deviation'] if f['unit'] == 'mm' else np.degrees(f['deviation']):+.0f} {'mm' if f['unit'] == 'mm' else 'deg'}" for f in flags[:6]
    ]
    print(f"  {len(flags)} kinematic parameters moved beyond 10 mm / 2 deg from nominal; largest: " + ", ".join(shown))

    tr, te = paper_split(len(d1), seed=0)
    p = Problem.build(hsr, d1.subset(tr))
    eig = np.linalg.eigvalsh(p.jacobian(p.x0).T @ p.jacobian(p.x0))
    print(f"D1 first paper split: eigenvalues of the unscaled JᵀJ from {eig[0]:.3g} to {eig[-1]:.3g}")
    print(f"  production LM: train RMSE {levenberg_marquardt(p).metrics['train']['rmse']:.3f} mm")
    for lam in (1e2, 1e3, 1e4, 1e5, 1e6):
        res = METHODS["lm-paper"][2](p, lam=lam, max_iter=500)
        monotone = bool(np.all(np.diff(res.history) <= 1e-9))
        test = metrics(p.with_data(d1.subset(te)).data_residuals(res.x), "cable")["rmse"]
        print(f"  eq. 14, λ = {lam:g}: train RMSE {res.metrics['train']['rmse']:.3f} mm, test {test:.3f} mm, cost monotone {monotone}")

    d2 = load(root / "robotcali-abb-irb120" / "RobotCali-new.xlsx")
    abb = robocal.robot("abb-irb120")
    for seed in range(5):
        tr, _ = paper_split(len(d2), seed=seed)
        p = Problem.build(abb, d2.subset(tr))
        res = levenberg_marquardt(p)
        h = res.history
        print(
            f"D2 paper split {seed}: {res.nit} iterations, {res.nfev} evaluations ({res.message}); cost after 100 iterations "
            f"{h[min(100, len(h) - 1)]:.4g}, final {res.cost:.4g}; scaled condition {scaled_condition(p.jacobian(res.x)):.2g}"
        )

    text = (root / "ipa-robot-accuracy-ur10" / "Series_B" / "measurements_joint_configurations.csv").read_text().splitlines()
    header = text[0].split(";")
    table = np.array([[float(v.replace(",", ".")) for v in line.split(";")] for line in text[1:] if line.strip()])
    joints = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]
    q = table[:, [header.index(n) for n in joints]]
    goal = table[:, [header.index(f"Goal {c}") for c in "xyz"]] * 1000.0
    diff = np.abs(robocal.robot("ur10").fkine(q)[:, :3, 3] - goal)
    print("UR10 Series B, |nominal FK − Goal| median (mm): x {:.2f}, y {:.2f}, z {:.2f}".format(*np.median(diff, axis=0)))


if __name__ == "__main__":
    main()
