"""Calibrate and diagnose a public dataset: UR10 Series B (laser tracker), positions.

    python examples/public_dataset.py [DATASETS_DIR]

DATASETS_DIR defaults to $ROBOCAL_DATASETS or ../shared/datasets (see docs/datasets.md).
"""

import os
import sys
from pathlib import Path

import robocal

root = Path(sys.argv[1] if len(sys.argv) > 1 else os.environ.get("ROBOCAL_DATASETS", Path(__file__).resolve().parents[1] / ".." / "shared" / "datasets"))
path = root / "ipa-robot-accuracy-ur10" / "Series_B" / "measurements_joint_configurations.csv"
data = robocal.load(path, measurement="position")
print(data)

result = robocal.calibrate(data, method="lm")
print(f"geometric calibration: held-out RMSE {result.metrics['test']['rmse']:.3f} mm")
report = robocal.diagnose(data).to_dict()
print(
    f"diagnosis: baseline {report['baseline']['rmse_heldout']:.3f} mm -> {report['final']['rmse_heldout']:.3f} mm with "
    + (", ".join(e["label"] for e in report["effects"]) or "no cause")
)
