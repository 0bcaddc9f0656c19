"""Wall time of ``robocal.diagnose`` on 2 000 simulated samples with the full candidate library.

    RAYON_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benches/bench_diagnose.py     # one core

Two cases, each run ``--repeats`` times (median reported): HSR JR680 tracker positions with a
periodic gear error on joint 2 and backlash on joint 3, and HSR JR680 cable lengths with the
gear error alone. Prints a Markdown table with the machine, the thread settings, the number of
candidates screened, what was found and the time (target: within 30 s on one core).
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time

from machine import cpu_model

import robocal
from robocal.diagnosis import diagnose
from robocal.simulation import simulate

CASES = [
    ("position", ["joint_periodic:joint=2,amplitude=0.01", "backlash:joint=3,width=0.02"]),
    ("cable", ["joint_periodic:joint=2,amplitude=0.01"]),
]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    print(f"machine: {cpu_model()}, {os.cpu_count()} logical CPUs; Python {platform.python_version()}, robocal {robocal.__version__}")
    print(f"threads: RAYON_NUM_THREADS={os.environ.get('RAYON_NUM_THREADS', 'all')}, OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'default')}\n")
    print("| data | samples | candidates screened (first round) | found | median time (s) | runs (s) |")
    print("|---|---|---|---|---|---|")
    for measurement, effects in CASES:
        data, _ = simulate("hsr-jr680", measurement, samples=args.samples, seed=7, effects=effects)
        times, report = [], None
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            report = diagnose(data).to_dict()
            times.append(time.perf_counter() - t0)
        found = ", ".join(e["label"] for e in report["effects"]) or "nothing"
        screened = report["effects"][0]["significance"]["candidates"] if report["effects"] else "—"
        print(f"| HSR JR680 {measurement} | {args.samples} | {screened} | {found} | {statistics.median(times):.2f} | {', '.join(f'{t:.2f}' for t in times)} |")


if __name__ == "__main__":
    main()
