"""Wall time of ``robocal.diagnose`` with the full candidate library, on simulated data and on
the public files.

    python benches/bench_diagnose.py                                               # both cores
    RAYON_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benches/bench_diagnose.py     # one core

Simulated (each run ``--repeats`` times, median reported): 2 000 HSR JR680 tracker positions with a
periodic gear error on joint 2 and backlash on joint 3, and 2 000 cable lengths with the gear
error alone (target: 5 s). Public (one run each; ``--no-public`` skips them): D1, the HSR JR680
cable file (target 20 s), and UR10 Series A, 11 911 tracker positions (target 90 s). Prints a
Markdown table with the machine, the load, the thread settings, the number of candidates
screened, what was found, the held-out RMSE before and after, and the time.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from pathlib import Path

from machine import cpu_model

import robocal
from robocal.diagnosis import diagnose
from robocal.simulation import simulate

DATASETS = Path(os.environ.get("ROBOCAL_DATASETS", Path(__file__).resolve().parents[2] / "shared" / "datasets"))
PUBLIC = {
    "D1 HSR JR680 cable": ("hsr-robotcali/HSR-RobotCali.xlsx", None),
    "D3 Series A UR10 position": ("ipa-robot-accuracy-ur10/Series_A/measurements_grid.csv", "position"),
}
CASES = [
    ("position", ["joint_periodic:joint=2,amplitude=0.01", "backlash:joint=3,width=0.02"]),
    ("cable", ["joint_periodic:joint=2,amplitude=0.01"]),
]


def row(name: str, data, repeats: int) -> str:
    times, report = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        report = diagnose(data).to_dict()
        times.append(time.perf_counter() - t0)
    found = ", ".join(e["label"] for e in report["effects"]) or "nothing"
    screened = next((e["significance"]["candidates"] for e in report["effects"] if "candidates" in e["significance"]), "—")
    return (
        f"| {name} | {len(data)} | {screened} | {found} | {report['baseline']['rmse_heldout']:.4f} → {report['final']['rmse_heldout']:.4f} | "
        f"{statistics.median(times):.2f} | {', '.join(f'{t:.2f}' for t in times)} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-public", action="store_true", help="skip the public files")
    args = parser.parse_args()
    print(
        f"machine: {cpu_model()}, {os.cpu_count()} logical CPUs; Python {platform.python_version()}, robocal {robocal.__version__}; "
        f"load average {os.getloadavg()[0]:.2f} at the start"
    )
    print(
        f"threads: RAYON_NUM_THREADS={os.environ.get('RAYON_NUM_THREADS', 'all')}, OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'default')}\n"
    )
    print("| data | samples | candidates screened (first round) | found | held-out RMSE (mm) | median time (s) | runs (s) |")
    print("|---|---|---|---|---|---|---|")
    for measurement, effects in CASES:
        data, _ = simulate("hsr-jr680", measurement, samples=args.samples, seed=7, effects=effects)
        print(row(f"simulated HSR JR680 {measurement}", data, args.repeats), flush=True)
    if not args.no_public:
        for name, (path, measurement) in PUBLIC.items():
            print(row(name, robocal.load(DATASETS / path, measurement=measurement), 1), flush=True)
    print(f"\nload average {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    main()
