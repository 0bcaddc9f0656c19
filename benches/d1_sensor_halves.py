"""Is D1's periodic error the cable sensor's? The causes a diagnosis of D1 named, fitted on parts
of the file: each half in acquisition order, the odd and the even rows. An error of the sensor is
one error, of one size and phase, in every part; its held-out gain is reported per part beside
the model without it.

    robocal diagnose ../shared/datasets/hsr-robotcali/HSR-RobotCali.xlsx --json d1.json
    python benches/d1_sensor_halves.py d1.json
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

import numpy as np

import robocal
from robocal.data import load

D1 = Path(os.environ.get("ROBOCAL_DATASETS", Path(__file__).resolve().parents[2] / "shared" / "datasets")) / "hsr-robotcali" / "HSR-RobotCali.xlsx"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("report", help="robocal diagnose's JSON report of D1")
    args = parser.parse_args()
    report = json.loads(Path(args.report).read_text())
    labels = report["model"]["structure"] + report["model"]["causes"]
    periodic = [label for label in labels if label.startswith("sensor_periodic")]
    if not periodic:
        raise SystemExit(f"{args.report} names no sensor_periodic cause")
    data = load(D1)
    m = len(data)
    parts = {"first half": np.arange(m // 2), "second half": np.arange(m // 2, m), "even rows": np.arange(0, m, 2), "odd rows": np.arange(1, m, 2)}
    print("| part | amplitude (mm) | phase (deg) | held-out RMSE with it (mm) | without it (mm) |")
    print("|---|---|---|---|---|")
    for name, idx in parts.items():
        part = data.subset(idx)
        with_it = robocal.calibrate(part, robot="hsr-jr680", causes=labels)
        without = robocal.calibrate(part, robot="hsr-jr680", causes=[label for label in labels if label not in periodic])
        term = next(c for c in with_it.to_dict()["causes"] if c["kind"] == "sensor_periodic")["params"]
        print(
            f"| {name} | {term['amplitude']['value']:.4f} | {term['phase']['value']:.1f} | "
            f"{with_it.metrics['test']['rmse']:.4f} | {without.metrics['test']['rmse']:.4f} |"
        )


if __name__ == "__main__":
    main()
