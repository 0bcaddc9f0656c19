"""``robocal demo``: robocal's main job on a built-in default (no files needed).

Simulates an HSR JR680 measured with a cable sensor, with a non-geometric effect hidden in the
data (backlash of joint 2); calibrates it with UKF-VSLM (the paper's M9); diagnoses what the
geometric model still misses; prints a short summary and writes a report folder: the simulated
data (canonical CSV) and their truth, the result file, the diagnosis report and its figures, and
the HTML report when ``robocal.report`` is available.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from .. import __version__
from ..calibration.api import held_out_problem
from ..calibration.problem import is_kinematic
from ..causes.extended import calibrate
from ..diagnosis import diagnose
from ..exceptions import InvalidParameterError
from ..outputs import make_folder, write_json
from ..robot import robot as load_robot
from ..simulation import simulate, write_simulation
from .diagnose import write_figures

#: The effect the demo hides: backlash of 0.03 deg on joint 2 (about 0.5 mm at the tool).
EFFECT = "backlash:joint=2,width=0.03"


def demo(seed: int = 0, samples: int = 600, out: str = "robocal-demo") -> int:
    t0 = time.perf_counter()
    data, truth = simulate("hsr-jr680", "cable", samples=samples, seed=seed, effects=[EFFECT])
    # Before the first file is written: the calibration's split of these samples must leave it
    # degrees of freedom (the same check calibrate makes), or the folder would keep half a demo.
    try:
        held_out_problem(load_robot("hsr-jr680"), data, 0.2, seed)
    except InvalidParameterError as exc:
        raise InvalidParameterError(f"--samples {samples} is too few for the demo: {exc}") from None
    folder = make_folder(out)
    csv, _ = write_simulation(data, truth, folder / "data.csv", folder / "truth.json")
    print(f"robocal {__version__} demo: a simulated HSR JR680 with a cable sensor, {samples} samples (seed {seed}), hidden effect {EFFECT}")

    result = calibrate(str(csv), robot="hsr-jr680", method="ukf-vslm", seed=seed)
    doc = result.to_dict()
    write_json(folder / "result.json", doc)
    start = result.problem.with_data(result.held_out).data_residuals(result.problem.x0)
    before = float(np.sqrt(np.mean(start**2)))
    after = doc["metrics"]["test"]["rmse"]
    print(
        f"\ncalibration (UKF-VSLM, {len(doc['free'])} parameters, {doc['convergence']['time_s'] * 1e3:.0f} ms): "
        f"held-out cable RMSE {before:.3f} mm (nominal) -> {after:.4f} mm (calibrated)"
    )
    rows = [p for p in doc["parameters"] if p["std"] is not None and is_kinematic(p["name"])]
    rows.sort(key=lambda p: -abs(p["deviation"]) / (1.0 if p["unit"] == "mm" else math.radians(0.1)))
    # Deviations are determined up to the redundancies listed in result.json (e.g. theta6 trades
    # with the tool point): compare predictions, not single parameters, with the truth.
    print("largest kinematic deviations from nominal (± std):")
    for p in rows[:4]:
        scale, unit = (1.0, "mm") if p["unit"] == "mm" else (180.0 / math.pi, "deg")
        print(f"  {p['name']:>8s} {p['deviation'] * scale:+8.3f} ± {p['std'] * scale:.3f} {unit}")

    diagnosis = diagnose(data, seed=seed)
    report = diagnosis.to_dict()
    write_json(folder / "diagnosis.json", report)
    figures = write_figures(diagnosis, folder)
    print(f"\ndiagnosis: geometric model held-out RMSE {report['baseline']['rmse_heldout']:.4f} mm")
    for e in report["effects"]:
        shown = ", ".join(f"{k} {v['value']:.3g} {v['unit']}" for k, v in e["params"].items() if isinstance(v, dict) and v.get("std") is not None)
        print(f"  found {e['label']}: {shown}; held-out RMSE {e['rmse_heldout_before']:.4f} -> {e['rmse_heldout_after']:.4f} mm")
    if not report["effects"]:
        print("  nothing beyond the geometric model was found")
    written = [csv.name, "truth.json", "result.json", "diagnosis.json"] + [f.name for f in figures]
    try:
        from ..report import report as html_report

        written.append(html_report(folder / "result.json", folder, diagnosis=folder / "diagnosis.json").name)
    except ImportError:
        pass
    print(f"\nwrote {', '.join(written)} to {folder}/ ({time.perf_counter() - t0:.1f} s in all)")
    return 0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--samples", type=int, default=600)
    parser.add_argument("--out", default="robocal-demo", help="report folder (default ./robocal-demo)")


def run(args: argparse.Namespace) -> int:
    return demo(args.seed, args.samples, args.out)
