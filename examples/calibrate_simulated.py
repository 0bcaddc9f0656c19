"""Calibrate a simulated robot, save the result file and load it back.

python examples/calibrate_simulated.py [OUT_DIR]
"""

import json
import sys
from pathlib import Path

import numpy as np

import robocal

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
out.mkdir(parents=True, exist_ok=True)

# 400 cable-sensor samples of an HSR JR680 whose geometry is off by ~0.5 mm / 0.05 deg.
data, truth = robocal.simulate("hsr-jr680", "cable", samples=400, seed=1)

for method in ("lm", "ukf-vslm"):
    result = robocal.calibrate(data, method=method)
    test = result.metrics["test"]
    print(
        f"{method:>8s}: held-out RMSE {test['rmse']:.4f} mm, MAE {test['mae']:.4f} mm, MAX {test['max']:.4f} mm "
        f"({len(result.problem.names)} parameters, {result.time_s * 1e3:.0f} ms)"
    )

path = out / "result.json"
path.write_text(json.dumps(result.to_dict(), indent=1))
robot, doc = robocal.load_result(path)
assert np.allclose(robot.params, result.params)
print(f"saved {path} (schema {doc['schema']}) and loaded it back: {robot.name}, {len(doc['free'])} parameters estimated")
