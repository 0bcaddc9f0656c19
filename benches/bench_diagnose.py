"""Wall time and peak memory of ``robocal.diagnose`` with the full candidate library, on simulated
data and on the public files.

    python benches/bench_diagnose.py                                               # both cores
    RAYON_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benches/bench_diagnose.py     # one core

Simulated (each run ``--repeats`` times, median reported): 2 000 HSR JR680 tracker positions with a
periodic gear error on joint 2 and backlash on joint 3, and 2 000 cable lengths with the gear
error alone. Scaling (one run each, ``--no-scaling`` skips them): UR10 tracker positions with a
gear-mesh error (harmonic 6, which only a joint map follows) on joints 2 and 3, at 12 500 and
50 000 samples; ``--six-maps`` adds 50 000 samples with it on every joint (the peak memory of six
joint maps). Public (one run each; ``--no-public`` skips them): D1, the HSR JR680 cable file,
UR10 Series A (11 911 tracker positions) and the three UR10 series as sessions of one robot
(``--no-sessions`` skips that). Every case runs in a process of its own, which reports its peak
resident memory. Prints a Markdown table with the machine, the load, the thread settings, the
number of candidates screened, what was found, the held-out RMSE before and after, the time and
the peak memory; ``--figure PNG`` also draws time against samples (log-log, with the line of
time proportional to samples through the smallest scaling case).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

import robocal
from machine import cpu_model, load_text
from record import add_argument, recording
from robocal.diagnosis import diagnose
from robocal.simulation import simulate

DATASETS = Path(os.environ.get("ROBOCAL_DATASETS", Path(__file__).resolve().parents[2] / "shared" / "datasets"))
PUBLIC = {
    "D1 HSR JR680 cable": ("hsr-robotcali/HSR-RobotCali.xlsx", None),
    "D3 Series A UR10 position": ("ipa-robot-accuracy-ur10/Series_A/measurements_grid.csv", "position"),
}
SERIES = ["Series_A/measurements_grid.csv", "Series_B/measurements_joint_configurations.csv", "Series_C/measurements_random_poses.csv"]
CASES = [
    ("position", ["joint_periodic:joint=2,amplitude=0.01", "backlash:joint=3,width=0.02"]),
    ("cable", ["joint_periodic:joint=2,amplitude=0.01"]),
]
SCALING = (12_500, 50_000)
GEAR_MESH = ["joint_periodic:joint=2,amplitude=0.005,harmonic=6", "joint_periodic:joint=3,amplitude=0.005,harmonic=6"]
#: ``--six-maps``: the gear mesh on every joint, so that the model ends with six joint maps.
SIX_MAPS = (50_000, [f"joint_periodic:joint={j},amplitude=0.005,harmonic=6" for j in range(1, 7)])


def case_data(case: str):
    """The data of a case (``kind:argument``), built in the process that diagnoses it."""
    kind, _, argument = case.partition(":")
    if kind == "simulated":
        measurement, samples = argument.split(",")
        effects = dict(CASES)[measurement]
        return simulate("hsr-jr680", measurement, samples=int(samples), seed=7, effects=effects)[0]
    if kind == "scaling":
        return simulate("ur10", "position", samples=int(argument), seed=7, effects=GEAR_MESH)[0]
    if kind == "six_maps":
        return simulate("ur10", "position", samples=int(argument), seed=7, effects=SIX_MAPS[1])[0]
    if kind == "public":
        path, measurement = PUBLIC[argument]
        return robocal.load(DATASETS / path, measurement=measurement)
    return [robocal.load(DATASETS / "ipa-robot-accuracy-ur10" / series, measurement="position") for series in SERIES]


def run_one(case: str) -> None:
    """Diagnoses one case and prints its figures as one JSON line (with this process's peak memory)."""
    data = case_data(case)
    t0 = time.perf_counter()
    report = diagnose(data).to_dict()
    elapsed = time.perf_counter() - t0
    if "sessions" in report:  # the multi-session report: its causes and leave-one-session-out figures
        found = ", ".join(e["label"] for e in report.get("effects", [])) or "nothing"
        samples, screened = sum(len(d) for d in data), "—"
        before, after = report["baseline"]["rmse_loso"], report["final"]["rmse_loso"]  # leave-one-session-out
    else:
        found = ", ".join(e["label"] for e in report["effects"]) or "nothing"
        samples = len(data)
        screened = next((e["significance"]["candidates"] for e in report["effects"] if "candidates" in e["significance"]), "—")
        before, after = report["baseline"]["rmse_heldout"], report["final"]["rmse_heldout"]
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # kB on Linux
    print(json.dumps({"samples": samples, "screened": screened, "found": found, "before": before, "after": after, "time": elapsed, "peak_mb": peak}))


def row(name: str, case: str, repeats: int, measured: list) -> str:
    """The table row of ``case`` run ``repeats`` times; appends ``(name, samples, median time)``
    to ``measured``."""
    runs = []
    for _ in range(repeats):
        done = subprocess.run([sys.executable, __file__, "--one", case], capture_output=True, text=True, check=True)
        runs.append(json.loads(done.stdout.strip().splitlines()[-1]))
    times = [r["time"] for r in runs]
    r = runs[-1]
    measured.append((name, r["samples"], statistics.median(times)))
    return (
        f"| {name} | {r['samples']} | {r['screened']} | {r['found']} | {r['before']:.4f} → {r['after']:.4f} | "
        f"{statistics.median(times):.2f} | {', '.join(f'{t:.2f}' for t in times)} | {max(x['peak_mb'] for x in runs):.0f} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=2000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-public", action="store_true", help="skip the public files")
    parser.add_argument("--no-sessions", action="store_true", help="skip the three UR10 series as sessions")
    parser.add_argument("--no-scaling", action="store_true", help="skip the simulated UR10 files of 12 500 and 50 000 samples")
    parser.add_argument(
        "--six-maps",
        action="store_true",
        help="also the 50 000-sample UR10 file with a gear mesh on every joint (a joint map for each joint whose error the data show; long)",
    )
    parser.add_argument("--figure", help="also draw time against samples into this PNG")
    parser.add_argument("--one", help=argparse.SUPPRESS)  # a single case, in a process of its own
    add_argument(parser)
    args = parser.parse_args()
    with recording(args.record):
        if args.one:
            run_one(args.one)
            return
        print(
            f"machine: {cpu_model()}, {os.cpu_count()} logical CPUs; Python {platform.python_version()}, robocal {robocal.__version__}; "
            f"load average {load_text()} at the start"
        )
        print(
            f"threads: RAYON_NUM_THREADS={os.environ.get('RAYON_NUM_THREADS', 'all')}, OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'default')}\n"
        )
        print("| data | samples | candidates screened (first round) | found | held-out RMSE (mm) | median time (s) | runs (s) | peak memory (MB) |")
        print("|---|---|---|---|---|---|---|---|")
        measured: list = []
        for measurement, _ in CASES:
            print(row(f"simulated HSR JR680 {measurement}", f"simulated:{measurement},{args.samples}", args.repeats, measured), flush=True)
        if not args.no_scaling:
            for samples in SCALING:
                print(row("simulated UR10 position, gear mesh on joints 2 and 3", f"scaling:{samples}", 1, measured), flush=True)
        if args.six_maps:
            print(row("six maps: simulated UR10 position, gear mesh on every joint", f"six_maps:{SIX_MAPS[0]}", 1, measured), flush=True)
        if not args.no_public:
            for name in PUBLIC:
                print(row(name, f"public:{name}", 1, measured), flush=True)
            if not args.no_sessions:
                print(row("D3 Series A + B + C UR10 position, as sessions", "sessions:", 1, measured), flush=True)
        print(f"\nload average {load_text()} at the end")
        if args.figure:
            draw(measured, args.figure)


def draw(measured: list, path: str) -> None:
    """Time against samples, log-log, each case a labelled point; the scaling cases joined, with
    the line of time proportional to samples through the first of them."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    fig, ax = plt.subplots(figsize=(7, 4.5))
    scaling = [(n, t) for name, n, t in measured if name.startswith("simulated UR10")]
    for name, n, t in measured:
        ax.plot(n, t, "o", color="C0" if name.startswith("simulated UR10") else "C1")
        ax.annotate(name.replace("simulated ", "sim. "), (n, t), textcoords="offset points", xytext=(5, 3), fontsize=7)
    if len(scaling) > 1:
        (n0, t0), ns = scaling[0], [n for n, _ in scaling]
        ax.plot(ns, [t for _, t in scaling], "-", color="C0")
        ax.plot([n0, max(ns)], [t0, t0 * max(ns) / n0], ":", color="grey", label="time ∝ samples")
        ax.legend(loc="upper left", fontsize=8)
    ax.set(xscale="log", yscale="log", xlabel="samples", ylabel="diagnose wall time (s)", title="robocal diagnose: time against samples")
    ax.set_xlim(min(n for _, n, _ in measured) / 1.5, max(n for _, n, _ in measured) * 6)  # room for the labels
    ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"figure: {path}")


if __name__ == "__main__":
    main()
