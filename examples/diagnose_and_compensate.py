"""Find a hidden non-geometric effect, fit the extended model, compensate target positions.

python examples/diagnose_and_compensate.py [OUT_DIR]
"""

import json
import sys
from pathlib import Path

import numpy as np

import robocal

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
out.mkdir(parents=True, exist_ok=True)

# A UR10 measured by a laser tracker, with a periodic gear error on joint 2 hidden in the data.
data, truth = robocal.simulate("ur10", "position", samples=800, seed=4, effects=["joint_periodic:joint=2,amplitude=0.02,harmonic=2"])

diagnosis = robocal.diagnose(data)
report = diagnosis.to_dict()
for effect in report["effects"]:
    amplitude = effect["params"].get("amplitude", {})
    print(
        f"found {effect['label']} ({amplitude.get('value', float('nan')):.4f} deg); held-out RMSE "
        f"{effect['rmse_heldout_before']:.4f} -> {effect['rmse_heldout_after']:.4f} mm"
    )

geometric = robocal.calibrate(data)
extended = robocal.calibrate(data, causes=report)
print(f"held-out RMSE: geometric {geometric.metrics['test']['rmse']:.4f} mm, extended {extended.metrics['test']['rmse']:.4f} mm")

# Joint commands for three target positions on the calibrated model: measured points, so in the
# tracker frame (frame="session"; by default targets are in the robot base frame).
result = out / "result.json"
result.write_text(json.dumps(geometric.to_dict()))
targets = out / "targets.csv"
targets.write_text("x,y,z\n" + "\n".join(",".join(f"{v:.3f}" for v in p) for p in data.y[:3, :3]) + "\n")
for row in robocal.compensate(result, targets, frame="session"):
    print(f"target row {row['row']}: q = {np.round(row['q'], 3).tolist()} deg, residual {row['residual_mm']:.1e} mm, {row['status']}")
