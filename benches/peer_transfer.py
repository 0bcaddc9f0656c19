"""Does pybotics' UR10 fit carry from one series to another better than robocal's? (issue 55)

    python benches/peer_transfer.py [--datasets ../shared/datasets] [--record PATH]

Needs pybotics 3.1.2 (``pip install pybotics==3.1.2`` in a virtual environment that sees the system
packages). Issue 55 quotes pybotics at 0.540 mm on the UR10 fitted on all of series A (positions)
and verified on series C with only the base frame and the tool re-fitted, against robocal's 0.571.
The same protocol for both tools, on every ordered pair of series:

* pybotics: its UR10 MDH model (``predefined_models.ur10``), all 24 MDH parameters, the tool position
  and the world frame free (``OptimizationHandler``), its world frame started by a Kabsch fit of its
  nominal flange points, its residual ``optimize_accuracy`` (each sample's distance), solved by
  scipy's ``least_squares`` with its defaults (trf, tolerances 1e-8, 2-point differences), then with
  ``method="lm"`` (its defaults too), and that fit continued to convergence (tolerances 1e-15). The residual is
  evaluated through robocal's core on the same MDH chain (the fitted pybotics robot converted into a
  robocal robot with MDH joints); the conversion is checked against pybotics' own
  ``optimize_accuracy`` at the start and the end of every fit.
* robocal: ``levenberg_marquardt`` on ``Problem.build`` (its DH + Hayati model, its default mask).

Verified as ``robocal.verify`` does: only the tracker's base frame and the tool point re-fitted on
the other series (``Problem.build(..., mask=setup_names(...))`` + ``levenberg_marquardt``); for the
robocal fit, ``robocal.verify`` itself gives the same figure. Nothing of the verifying series enters
a fit.
"""

from __future__ import annotations

import argparse
import sys
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import numpy as np
import robocal
from record import add_argument, recording
from robocal.calibration.lm import levenberg_marquardt
from robocal.calibration.problem import Problem, implausible_parameters
from robocal.geometry import frame_params, kabsch
from robocal.robot import Joint, Robot, setup_names

SERIES = {"A": "Series_A/measurements_grid.csv", "B": "Series_B/measurements_joint_configurations.csv", "C": "Series_C/measurements_random_poses.csv"}
#: label -> scipy least_squares options of the pybotics fit (2-point differences, its default Jacobian)
SOLVES = {
    "least_squares defaults (trf)": {},
    "least_squares method='lm', defaults": {"method": "lm"},
}
#: the lm fit continued from where its defaults stopped: does the stop matter?
CONVERGED = {"method": "lm", "ftol": 1e-15, "xtol": 1e-15, "gtol": 1e-15, "max_nfev": 20000}


def rmse(residuals: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(residuals.reshape(-1, 3) ** 2, axis=1))))


def as_robocal(peer) -> Robot:
    """pybotics' robot as a robocal robot: MDH joints (``beta`` 0; ``d`` free, as pybotics fits it),
    world frame → base, tool → tool. Same forward kinematics (checked where it is used)."""
    template = robocal.robot("ur10")
    joints = [Joint("mdh", j.kind, False, j.limits) for j in template.joints]
    params = template.params.copy()
    n = len(joints)
    dh = params[: 5 * n].reshape(n, 5)  # alpha, a, d, theta, beta
    mdh = peer.kinematic_chain.matrix  # alpha, a, theta, d
    dh[:] = np.column_stack([mdh[:, 0], mdh[:, 1], mdh[:, 3], mdh[:, 2], np.zeros(n)])
    base, tool = template.index("base_x"), template.index("tool_x")
    params[base : base + 6] = frame_params(peer.world_frame)
    params[tool : tool + 6] = frame_params(peer.tool.matrix)
    return Robot("ur10 (pybotics MDH)", joints, params)


def pybotics_fit(data, options: dict, start=None):
    """pybotics' calibration of ``data``: the fitted robot (robocal's), the scipy result, the largest
    gap between robocal's residual and pybotics' own ``optimize_accuracy`` (start and end),
    pybotics' nominal robot (robocal's) and, after each residual evaluation (2-point differences
    included), the best robot so far (what a stop there would return). ``start``: pybotics' vector to
    start from (default: its nominal robot, the world frame placed by Kabsch)."""
    import scipy.optimize
    from pybotics.optimization import OptimizationHandler, optimize_accuracy
    from pybotics.predefined_models import ur10
    from pybotics.robot import Robot as PyboticsRobot

    q, y = data.q, data.y
    peer = PyboticsRobot.from_parameters(ur10())
    peer.world_frame = kabsch(np.array([peer.fk(qi)[:3, 3] for qi in q]), y)
    handler = OptimizationHandler(robot=peer, kinematic_chain_mask=True, tool_mask=[True] * 3 + [False] * 3, world_mask=True)
    x0 = handler.generate_optimization_vector()

    def robot_at(x) -> Robot:
        handler.apply_optimization_vector(x)
        return as_robocal(handler.robot)

    path = []  # per evaluation, (the lowest cost so far, its parameters): where a stop after so many evaluations leaves the fit

    def distances(x):
        d = np.linalg.norm(robot_at(x).residuals("position", q, y), axis=1)
        cost = float(d @ d)
        path.append((cost, x.copy()) if not path or cost < path[-1][0] else path[-1])
        return d

    out = scipy.optimize.least_squares(distances, x0 if start is None else start, **options)
    stops = [robot_at(x) for _, x in path]
    gap = max(float(np.max(np.abs(distances(x) - optimize_accuracy(x, handler, q, y)))) for x in (x0, out.x))
    return robot_at(out.x), out, gap, as_robocal(PyboticsRobot.from_parameters(ur10())), stops


def transferred(robot: Robot, data) -> float:
    """RMSE of ``robot`` on ``data`` with the session set-up alone re-fitted (as ``robocal.verify``)."""
    problem = Problem.build(robot, data, mask=setup_names(robot, data.measurement))
    return rmse(problem.data_residuals(levenberg_marquardt(problem).x))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--datasets", default=str(Path(__file__).resolve().parents[1] / ".." / "shared" / "datasets"))
    add_argument(parser)
    args = parser.parse_args()
    try:
        peer_version = version("pybotics")
    except PackageNotFoundError:
        sys.exit("benches/peer_transfer.py needs pybotics (pip install pybotics==3.1.2 in a virtual environment): it is not installed")
    root = Path(args.datasets) / "ipa-robot-accuracy-ur10"
    with recording(args.record):
        data = {k: robocal.load(root / v, measurement="position") for k, v in SERIES.items()}
        print(f"pybotics {peer_version}, robocal {robocal.__version__}; positions; verified with the base frame and tool point re-fitted\n")
        print("### Each fit on one series, verified on the others (mm)\n")
        print(
            "| fit on | tool, solve | training RMSE | verified on | evaluations (scipy's nfev: its 2-point differences not counted) | stop | implausible parameters |"
        )
        print("|---|---|---|---|---|---|---|")
        paths = {}
        for source, train in data.items():
            result = levenberg_marquardt(Problem.build(robocal.robot("ur10"), train))
            doc = result.to_dict()
            cells = []
            for target, test in data.items():
                if target != source:
                    ours, verified = transferred(result.robot, test), robocal.verify(doc, test)["metrics"]["rmse"]
                    assert abs(ours - verified) < 1e-6, (ours, verified)  # the re-fit here is verify's
                    cells.append(f"{target} {verified:.4f}")
            train_rmse = rmse(result.problem.data_residuals(result.x))
            print(
                f"| {source} | robocal `levenberg_marquardt`, default | {train_rmse:.4f} | {', '.join(cells)} | {result.nfev} | {result.status} | {len(result.implausible())} |"
            )
            fits = {}
            for label, options in SOLVES.items():
                fits[label] = pybotics_fit(train, options)
                if source == "A":
                    paths[label] = fits[label][4]
            label = "lm continued to convergence (tolerances 1e-15)"
            fits[label] = pybotics_fit(train, CONVERGED, start=fits["least_squares method='lm', defaults"][1].x)
            for label, (robot, out, gap, nominal, _) in fits.items():
                assert gap < 1e-6, f"robocal's MDH chain differs from pybotics' optimize_accuracy by {gap} mm"
                cells = [f"{t} {transferred(robot, d):.4f}" for t, d in data.items() if t != source]
                free = [n for n, k in zip(robot.param_names, robot.default_mask("position")) if k]
                flagged = implausible_parameters(nominal, {n: robot.params[robot.index(n)] for n in free})
                print(
                    f"| {source} | pybotics, {label} | {np.sqrt(np.mean(out.fun**2)):.4f} | {', '.join(cells)} | "
                    f"{out.nfev} | {out.status}: {out.message} | {len(flagged)} {', '.join(f['name'] for f in flagged)} |"
                )
        print("\n### pybotics' fit on A stopped after so many residual evaluations, verified on the others (mm)\n")
        print("| solve | evaluations (2-point differences included) | training RMSE | verified on B | verified on C |")
        print("|---|---|---|---|---|")
        for label, stops in paths.items():
            for k in sorted({*(k for k in (1, 35, 70, 140, 280, 560, 1120, 2240) if k < len(stops)), len(stops)}):
                robot = stops[k - 1]
                train = rmse(robot.residuals("position", data["A"].q, data["A"].y))
                print(f"| {label} | {k} | {train:.4f} | {transferred(robot, data['B']):.4f} | {transferred(robot, data['C']):.4f} |")


if __name__ == "__main__":
    main()
