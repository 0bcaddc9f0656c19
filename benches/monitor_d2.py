"""The monitor on D2 (ABB IRB 120, cable): a calibration on samples 230-498, the file replayed from sample 230 on, the
calibration's session going on. The cable was re-zeroed at file row 508 (+2.92 mm, as diagnose finds it).

    python benches/monitor_d2.py [--datasets ../shared/datasets] [--record PATH]

Prints each alarm in words and the long-run inflation at the end; then, over the samples from the re-zero on, the RMS of
the innovations that each explanation leaves when fitted to them by least squares (a constant on the cable's reading,
joint 4's zero, the sensor's whole set-up), beside the innovations' RMS before it.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import robocal
from robocal.monitoring import Monitor

from record import add_argument, recording

TRAINING = slice(230, 499)  # between the file's other jumps of the cable zero (rows 142 and 508)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--datasets", default=str(Path(__file__).resolve().parents[1] / ".." / "shared" / "datasets"))
    add_argument(parser)
    args = parser.parse_args()
    with recording(args.record):
        data = robocal.load(Path(args.datasets) / "robotcali-abb-irb120" / "abb_irb120_cable.csv")
        result = robocal.calibrate(data.subset(np.arange(TRAINING.start, TRAINING.stop)), robot="abb-irb120", test_fraction=0)
        monitor = Monitor(result.to_dict())
        alarms = monitor.update(data.q[TRAINING.start :], data.y[TRAINING.start :], rows=np.asarray(data.rows)[TRAINING.start :])
        print(f"D2 replayed from sample {TRAINING.start} ({len(data) - TRAINING.start} samples): {len(alarms)} alarm(s)\n")
        for a in alarms:
            print(f"- {a.words()}")
        print(f"\nlong-run inflation at the end: {monitor.inflation:.4g}")
        _leftovers(Monitor(result.to_dict()), data)  # the calibration's model, before any alarm applied


RE_ZERO = 508  # the file row


def _leftovers(monitor: Monitor, data) -> None:
    """What each explanation of the re-zero leaves of the innovations after it, under the calibration's model."""
    robot, at = monitor.robot, int(np.flatnonzero(np.asarray(data.rows) == RE_ZERO)[0])
    names = robot.param_names
    setup = ["tool_x", "tool_y", "tool_z", "anchor_x", "anchor_y", "anchor_z", "cable_offset", "cable_scale"]

    def innovations(rows):
        links = monitor._links(data.q[rows])
        e = robot.residuals(monitor.measurement, links, data.y[rows], params=monitor.params).ravel()
        return e, robot.jacobian(monitor.measurement, links, y=data.y[rows], params=monitor.params, cols=list(range(len(names)))).reshape(len(e), -1)

    before, _ = innovations(slice(at - 76, at))
    print(f"\nthe innovations' RMS over the 76 samples before row {RE_ZERO}: {np.sqrt(np.mean(before**2)):.3f} mm; from it on, what each explanation leaves:")
    for n in (24, 144):
        e, J = innovations(slice(at, at + n))
        left = {}
        for label, cols in (("a constant", ["cable_offset"]), ("joint 4's zero", ["theta4"]), ("the set-up", setup)):
            A = J[:, [names.index(c) for c in cols]]
            left[label] = np.sqrt(np.mean((e - A @ np.linalg.lstsq(A, e, rcond=None)[0]) ** 2))
        print(f"- {n} samples (raw {np.sqrt(np.mean(e**2)):.3f} mm): " + ", ".join(f"{k} {v:.3f} mm" for k, v in left.items()))


if __name__ == "__main__":
    main()
