"""``robocal compensate`` on a result file, targets in a chosen frame: the reach and the wall time
of the command line.

Targets are the calibrated model's forward kinematics, in the frame (``--frame``, as
``compensate`` reads it), of random joint vectors within the limits — every one reachable. They
are written to a targets CSV (``x,y,z`` [``qw,qx,qy,qz``], no seed joints) and solved by
``robocal compensate`` in this process; the time is the command's, from reading the files to
writing the joints. A target counts as reached when its status is ``ok`` and the joints as
written (deg, 6 decimals) put the model within 2e-4 mm of it (checked here, on the model:
compensate's 1e-4 mm, past the round trip through the file).

    robocal calibrate ../shared/datasets/ipa-robot-accuracy-ur10/Series_A/measurements_grid.csv --robot ur10 --out r.json
    python benches/bench_compensation_frames.py r.json [--frame base] [--measurement position] [--targets 200] [--seed 0]
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import io
import os
import tempfile
import time
from pathlib import Path

from record import add_argument, recording

os.environ.setdefault("RAYON_NUM_THREADS", "1")

import numpy as np  # noqa: E402

import robocal  # noqa: E402
from robocal.cli import main as cli  # noqa: E402
from robocal.compensation import framed_robot, joint_limits, parse_frame  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("result")
    parser.add_argument("--frame", default="base")
    parser.add_argument("--user-frame")
    parser.add_argument("--measurement", choices=("position", "pose"), default="position")
    parser.add_argument("--targets", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    add_argument(parser)
    args = parser.parse_args()
    with recording(args.record):
        robot, doc = robocal.load_result(args.result)
        model = framed_robot(robot, doc, parse_frame(args.frame, args.user_frame))
        lower, upper = joint_limits(robot)
        q = lower + (upper - lower) * np.random.default_rng(args.seed).random((args.targets, robot.n_joints))
        y = model.predict(args.measurement, q)
        columns = ["x", "y", "z"] + (["qw", "qx", "qy", "qz"] if args.measurement == "pose" else [])
        with tempfile.TemporaryDirectory() as folder:
            targets, joints = Path(folder) / "targets.csv", Path(folder) / "joints.csv"
            targets.write_text(",".join(columns) + "\n" + "\n".join(",".join(repr(float(v)) for v in row) for row in y) + "\n")
            argv = ["--quiet", "compensate", args.result, str(targets), "--out", str(joints), "--frame", args.frame]
            argv += ["--user-frame", args.user_frame] if args.user_frame else []
            t0, c0 = time.perf_counter(), time.process_time()
            with contextlib.redirect_stdout(io.StringIO()) as out:
                code = cli(argv)
            elapsed, cpu = time.perf_counter() - t0, time.process_time() - c0
            rows = list(csv.DictReader(joints.open()))
        commands = np.radians([[float(r[f"q{j}"]) for j in range(1, robot.n_joints + 1)] for r in rows])
        error = np.linalg.norm(model.residuals(args.measurement, commands, y)[:, :3], axis=1)
        reached = int(np.count_nonzero((error < 2e-4) & np.array([r["status"].startswith("ok") for r in rows])))
        largest_dq = max(abs(float(r[f"dq{j}"])) for r in rows for j in range(1, robot.n_joints + 1))
        load = " ".join(Path("/proc/loadavg").read_text().split()[:3]) if Path("/proc/loadavg").exists() else "?"
        print(out.getvalue().strip())
        print(
            f"{args.measurement} targets in frame {args.frame}: {reached}/{args.targets} reached in {elapsed:.2f} s ({cpu:.2f} s CPU; exit {code}); "
            f"largest |dq| {largest_dq:.3g} deg; load {load}"
        )


if __name__ == "__main__":
    main()
