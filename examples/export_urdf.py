"""Export a calibrated robot as a DH table and a URDF, each checked by a forward-kinematics round trip.

python examples/export_urdf.py [OUT_DIR]
"""

import json
import sys
from pathlib import Path

import robocal
from robocal.export import export_table, export_urdf, roundtrip_check, write_table

out = Path(sys.argv[1] if len(sys.argv) > 1 else ".")
out.mkdir(parents=True, exist_ok=True)
data, _ = robocal.simulate("ur10", "position", samples=200, seed=2)
result = robocal.calibrate(data)
(out / "result.json").write_text(json.dumps(result.to_dict()))
robot, _ = robocal.load_result(out / "result.json")

rows = export_table(robot, "dh")
write_table(rows, out / "ur10_dh.csv")
urdf = export_urdf(robot, name="ur10_calibrated")
(out / "ur10_calibrated.urdf").write_text(urdf)
for name, exported in (("DH table", rows), ("URDF", urdf)):
    check = roundtrip_check(robot, exported)
    print(f"{name}: round trip over {check['samples']} poses, max error {check['max_position_error_mm']:.1e} mm, {check['max_rotation_error_rad']:.1e} rad")
