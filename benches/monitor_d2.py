"""The monitor on D2 (ABB IRB 120, cable): a calibration on samples 230-498, the file replayed from sample 230 on, the
calibration's session going on. The cable was re-zeroed at file row 508 (+2.92 mm, as diagnose finds it).

    python benches/monitor_d2.py [--datasets ../shared/datasets] [--record PATH]

Prints each alarm in words and the long-run inflation at the end.
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


if __name__ == "__main__":
    main()
