"""What reaches the robot: an export of an extended UR10 result against the geometric calibration,
on a session neither saw.

    python benches/delivery_ur10.py [--datasets ../shared/datasets] [--diagnosis-a A.json] [--diagnosis-abc ABC.json]

For each split (fit on A, held out B and C; fit on two series, held out the third): the geometric
calibration and the extended one (the joint causes of a diagnosis: of series A alone for the fit on
A, of all three series for the others — which then saw the held-out series), both on all of their
training data. Each is checked on the held-out series with only its set-up re-fitted: the result as
``robocal verify`` applies it, and its URDF export (``export.deliverable``: the geometry the result
chose to carry) read back and its set-up re-fitted the same way. Prints a Markdown table of RMSE
(mm) and the extended result's ``geometry_only`` record. Without ``--diagnosis-*`` the diagnoses are
run here (several minutes each).
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import robocal
from robocal.calibration.metrics import metrics
from robocal.calibration.problem import Problem
from robocal.calibration.lm import levenberg_marquardt
from robocal.export import deliverable, export_checked
from robocal.results import load_result
from robocal.robot import setup_names

SERIES = {"A": "Series_A/measurements_grid.csv", "B": "Series_B/measurements_joint_configurations.csv", "C": "Series_C/measurements_random_poses.csv"}
SPLITS = (("A", "BC", "a"), ("AB", "C", "abc"), ("AC", "B", "abc"), ("BC", "A", "abc"))


def _setup_refitted_rmse(robot, data) -> float:
    """RMSE of ``robot`` on ``data`` with only the session set-up fitted (as ``verify`` does)."""
    problem = Problem.build(robot, data, mask=setup_names(robot, data.measurement))
    return metrics(problem.data_residuals(levenberg_marquardt(problem).x), data.measurement)["rmse"]


def _model(path: str | None, files: list[str]) -> dict:
    if path:
        return json.loads(Path(path).read_text())["model"]
    return robocal.diagnose(files if len(files) > 1 else files[0], robot="ur10", measurement="position").to_dict()["model"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--datasets", default=str(Path(__file__).resolve().parents[1] / ".." / "shared" / "datasets"))
    parser.add_argument("--diagnosis-a", help="a diagnose report (JSON) of series A")
    parser.add_argument("--diagnosis-abc", help="a diagnose report (JSON) of series A, B and C at once")
    args = parser.parse_args()
    files = {k: str(Path(args.datasets) / "ipa-robot-accuracy-ur10" / v) for k, v in SERIES.items()}
    models = {"a": _model(args.diagnosis_a, [files["A"]]), "abc": _model(args.diagnosis_abc, list(files.values()))}
    print("| fit on → held out | nominal | geometric | extended (verify) | export of the extended | geometry_only: choice, held-out RMSE extended / refit |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for train, held, which in SPLITS:
            model = models[which]
            data = [files[k] for k in train]
            data = data if len(data) > 1 else data[0]
            fits = {
                "geometric": robocal.calibrate(data, robot="ur10", measurement="position", test_fraction=0.2),
                "extended": robocal.calibrate(data, robot="ur10", measurement="position", causes=model["structure"] + model["causes"]),
            }
            paths = {}
            for name, fit in fits.items():
                paths[name] = Path(tmp) / f"{train}-{name}.json"
                paths[name].write_text(json.dumps(fit.to_dict()))
            robot, doc = load_result(paths["extended"])
            urdf = Path(tmp) / f"{train}.urdf"
            export_checked(robot, "urdf", urdf, delivered=deliverable(robot, doc))
            record = doc["geometry_only"]
            chosen = f"{record['choice']}, {record['held_out']['extended']['rmse']:.3f} / {record['held_out']['refit']['rmse']:.3f}"
            for h in held:
                checks = {name: robocal.verify(str(path), files[h], measurement="position") for name, path in paths.items()}
                exported = _setup_refitted_rmse(robocal.robot(str(urdf)), robocal.data.load(files[h], measurement="position"))
                print(
                    f"| {'+'.join(train)} → {h} | {checks['geometric']['nominal']['metrics']['rmse']:.3f} | {checks['geometric']['metrics']['rmse']:.3f} "
                    f"| {checks['extended']['metrics']['rmse']:.3f} | {exported:.3f} | {chosen} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
