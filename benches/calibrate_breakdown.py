"""Where one ``robocal.calibrate(csv, robot="hsr-jr680")`` spends its time (issue 53), section by
section: the wall time of each step and how often it ran, the part of it spent in compiled code (the Rust core and
pyarrow's CSV reader) and the rest (Python and NumPy), medians over repeated runs in this one
process. Unlike a profiler, nothing but the listed functions is instrumented, so small Python
calls are not inflated.

The file is benchmark part 0's: ``simulate("hsr-jr680", "cable", samples, seed=1)`` written by
``write_canonical``. The process first frees a 16 MB block: glibc pages large blocks in afresh on
every call (thousands of page faults per ``calibrate``) until it has freed one, which raises its
mmap and trim thresholds — as scipy's runs have in ``bench_calibration.py``. The faults per run
are printed.

    python benches/calibrate_breakdown.py
    python benches/calibrate_breakdown.py --runs 50
"""

from __future__ import annotations

import argparse
import importlib
import resource
import tempfile
import time
from collections import defaultdict
from pathlib import Path

from machine import load_text

#: (module, function, label): the steps of a calibration, each timed where its caller looks it up.
SECTIONS = [
    ("robocal.calibration.api", "load_inputs", "read the file"),
    ("robocal.data.loader", "read_delimited", "· split the text (checks for the columnar reader)"),
    ("robocal.data.loader", "read_canonical", "· numbers and dataset (pyarrow)"),
    ("robocal.data.loader", "angle_unit_check", "· angle unit check"),
    ("robocal.calibration.api", "held_out_problem", "split and Problem.build"),
    ("robocal.calibration.api", "configuration_groups", "· configuration groups"),
    ("robocal.calibration.api", "random_split", "· random split"),
    ("robocal.calibration.api", "check_observations", "· check the observations (nominal tool points)"),
    ("robocal.calibration.problem", "start_parameters", "· start: set-up fit (Gauss-Newton passes on a subsample)"),
    ("robocal.serial_robot", "identifiability", "· identifiability analysis"),
    ("robocal.calibration.api", "fit", "LM and result (covariance, training metrics)"),
    ("robocal.calibration.lm", "normal_equations", "· normal equations JᵀJ, Jᵀr"),
    ("robocal.calibration.lm", "_factor", "· their scaling and factor (eigenvalues, Cholesky)"),
    ("robocal.calibration.lm", "_refused_as_none", "· trial points: probe residuals, then residuals and Jacobian"),
    ("robocal.calibration.lm", "_product", "· products with J (Qᵀr, J·v: NumPy)"),
    ("robocal.causes.extended", "_held_out", "held-out metrics"),
]


def _faults() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt


def instrument() -> tuple[dict, dict]:
    """Wraps the compiled calls (accumulating into ``native["s"]``) and the sections; returns
    ``(native, sections)``, the latter ``label -> [wall, native, calls]`` of the current run."""
    import pyarrow.csv
    from robocal import _robocal
    from robocal.serial_robot import Robot

    native, sections = {"s": 0.0}, defaultdict(lambda: [0.0, 0.0, 0])

    def compiled(f):
        def timed(*args, **kwargs):
            start = time.perf_counter()
            try:
                return f(*args, **kwargs)
            finally:
                native["s"] += time.perf_counter() - start

        return timed

    for name in dir(_robocal):
        f = getattr(_robocal, name)
        if callable(f) and not isinstance(f, type) and not name.startswith("_"):
            setattr(_robocal, name, compiled(f))
    for name in ("residuals_and_jacobian", "residuals", "jacobian", "fkine"):  # the chain's methods, through their thin wrappers
        setattr(Robot, name, compiled(getattr(Robot, name)))
    pyarrow.csv.read_csv = compiled(pyarrow.csv.read_csv)

    def section(f, label):
        def timed(*args, **kwargs):
            start, inside = time.perf_counter(), native["s"]
            try:
                return f(*args, **kwargs)
            finally:
                sections[label][0] += time.perf_counter() - start
                sections[label][1] += native["s"] - inside
                sections[label][2] += 1

        return timed

    for module, name, label in SECTIONS:
        m = importlib.import_module(module)
        setattr(m, name, section(getattr(m, name), label))
    return native, sections


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=20_000)
    parser.add_argument("--runs", type=int, default=30)
    args = parser.parse_args()
    import numpy as np
    import robocal
    from robocal.data import write_canonical

    np.ones(2 << 20)  # 16 MB allocated and freed: glibc's mmap threshold rises to it, its trim threshold to twice that
    native, sections = instrument()
    with tempfile.TemporaryDirectory() as tmp:
        data, _ = robocal.simulate("hsr-jr680", "cable", samples=args.samples, seed=1)
        csv = write_canonical(data, Path(tmp) / "sim.csv")
        robocal.calibrate(csv, robot="hsr-jr680")  # warm: imports, the thread pools
        load, runs = load_text(all_three=True), defaultdict(list)
        for _ in range(args.runs):
            native["s"], faults = 0.0, _faults()
            sections.clear()
            start = time.perf_counter()
            robocal.calibrate(csv, robot="hsr-jr680")
            runs["total"].append((time.perf_counter() - start, native["s"], 1))
            runs["faults"].append((_faults() - faults, 0, 0))
            for label, times in sections.items():
                runs[label].append(tuple(times))
    median = {k: np.median(np.array(v), axis=0) for k, v in runs.items()}
    print(
        f"`robocal.calibrate` on {args.samples:,} simulated cable samples: medians of {args.runs} runs; load average {load} → {load_text(all_three=True)}; "
        f"{int(median['faults'][0])} minor page faults per run.\n"
    )
    print("| section | calls | wall (ms) | compiled (ms) | Python and NumPy (ms) |")
    print("|---|---:|---:|---:|---:|")
    for label in ["total"] + [s[2] for s in SECTIONS]:
        if label in median:
            wall, inside = median[label][:2] * 1e3
            print(f"| {label} | {median[label][2]:.0f} | {wall:.2f} | {inside:.2f} | {wall - inside:.2f} |")


if __name__ == "__main__":
    main()
