"""Loading measurement files, and a whole calibration from a file, side by side in one process.

1. **Loading.** ``robocal.load(path)`` with the columnar reader (pyarrow; the default) against
   the per-cell path alone (``robocal.data.table.COLUMNAR = False``, what every release before
   issue 15 ran), on a 20 000-row canonical CSV of simulated HSR JR680 cable samples
   (``robocal.simulate`` + ``robocal.data.write_canonical``) and on the public CSV files where
   present (D1, D2 copies; D3 UR10 Series A/B/C, ``;``-separated with decimal commas). Both paths
   must give bit-identical datasets (checked). For scale, the bare parsers without any checks:
   ``pandas.read_csv`` and ``pyarrow.csv.read_csv`` to float columns. Interleaved runs, best of
   ``--repeats``.
2. **End to end.** ``robocal.calibrate(csv, robot="hsr-jr680")`` (load, 80/20 split, LM, result
   with covariance and held-out metrics) against what a user would write with scipy: read the
   CSV with pandas, the same split and the same start / free parameters, then
   ``scipy.optimize.least_squares`` with finite differences (``jac="2-point"``) on the NumPy model
   ``robocal.reference.residuals`` (scipy's default tolerances). Plus a cProfile of the
   robocal call.

    python benches/bench_loading.py            # ~1 min on 2 cores
    python benches/bench_loading.py --quick    # 2 000 samples, no scipy LM
"""

from __future__ import annotations

import argparse
import cProfile
import io
import os
import platform
import pstats
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from bench_calibration import load_avg, rmse, scipy_csv_fit
from machine import cpu_model
from record import add_argument, recording

DATASETS = Path(os.environ.get("ROBOCAL_DATASETS", Path(__file__).resolve().parents[2] / "shared" / "datasets"))
PUBLIC = {
    "D1 HSR (CSV copy)": "hsr-robotcali/hsr_jr680_cable.csv",
    "D2 ABB (CSV copy)": "robotcali-abb-irb120/abb_irb120_cable.csv",
    "D3 UR10 Series A": "ipa-robot-accuracy-ur10/Series_A/measurements_grid.csv",
    "D3 UR10 Series B": "ipa-robot-accuracy-ur10/Series_B/measurements_joint_configurations.csv",
    "D3 UR10 Series C": "ipa-robot-accuracy-ur10/Series_C/measurements_random_poses.csv",
}
LOAD_TARGET, CALIBRATE_TARGET = 15.0, 30.0


def same(a, b) -> bool:
    def eq(x, y):
        return (x is None and y is None) or (x is not None and y is not None and np.array_equal(np.asarray(x).view(np.int64), np.asarray(y).view(np.int64)))

    return all(eq(getattr(a, k), getattr(b, k)) for k in ("q", "y", "t", "temp")) and np.array_equal(a.rows, b.rows) and a.notes == b.notes


def interleaved(fns: dict, repeats: int) -> dict:
    """Best wall time of each ``fns[name]()`` over ``repeats`` rounds, the names taking turns."""
    best = {name: float("inf") for name in fns}
    out = {}
    for _ in range(repeats):
        for name, fn in fns.items():
            t = time.perf_counter()
            out[name] = fn()
            best[name] = min(best[name], time.perf_counter() - t)
    return best, out


def import_seconds(statement: str, repeats: int = 3) -> float:
    code = f"import time, numpy; t = time.perf_counter(); {statement}; print(time.perf_counter() - t)"
    return min(float(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout) for _ in range(repeats))


def part_loading(args, canonical: Path) -> None:
    import robocal
    from robocal.data import table

    def load(path, columnar):
        table.COLUMNAR = columnar
        try:
            return robocal.load(path)
        finally:
            table.COLUMNAR = True

    files = {f"simulated canonical, {args.samples:,} rows": canonical}
    files.update({name: DATASETS / rel for name, rel in PUBLIC.items() if (DATASETS / rel).exists()})
    try:
        import pandas as pd
    except ImportError:
        pd = None
    import pyarrow as pa
    import pyarrow.csv as pacsv

    print("## 1. Loading: `robocal.load(path)`, columnar reader vs the per-cell path\n")
    print(f"best of {args.repeats} interleaved runs; 'identical' = q, y, t, temp bit for bit, rows and notes equal.\n")
    print("| file | rows | per-cell path (before) | columnar reader (after) | speed-up | identical | bare pandas.read_csv | bare pyarrow.csv |")
    print("|---|---:|---:|---:|---:|---|---:|---:|")
    verdict = None
    for name, path in files.items():
        delimiter, decimal = (";", ",") if "UR10" in name else (",", ".")
        data = path.read_bytes()
        fns = {"before": lambda: load(path, False), "after": lambda: load(path, True)}
        fns["pyarrow"] = lambda: pacsv.read_csv(
            pa.py_buffer(data), parse_options=pacsv.ParseOptions(delimiter=delimiter), convert_options=pacsv.ConvertOptions(decimal_point=decimal)
        )
        if pd is not None:
            fns["pandas"] = lambda: pd.read_csv(io.BytesIO(data), sep=delimiter, decimal=decimal)
        load(path, True)  # warm: imports, page cache
        best, out = interleaved(fns, args.repeats)
        ratio = best["before"] / best["after"]
        ok = same(out["before"], out["after"])
        pandas_ms = f"{best['pandas'] * 1e3:.1f} ms" if "pandas" in best else "—"
        print(
            f"| {name} | {len(out['after']):,} | {best['before'] * 1e3:.1f} ms | {best['after'] * 1e3:.1f} ms | **{ratio:.1f}×** | "
            f"{'yes' if ok else 'NO'} | {pandas_ms} | {best['pyarrow'] * 1e3:.1f} ms |"
        )
        if verdict is None:
            verdict = (ratio, ok)
    ratio, ok = verdict
    print(
        f"\n**Target: {args.samples:,} rows ≥ {LOAD_TARGET:g}× faster than the per-cell path: "
        f"{'MET' if ratio >= LOAD_TARGET and ok else 'NOT MET'}** ({ratio:.1f}×; identical: {ok})."
    )
    print(
        f"\nOne-off import cost, fresh interpreter with NumPy loaded (best of 3): `import pyarrow.csv, pyarrow.compute` "
        f"{import_seconds('import pyarrow.csv, pyarrow.compute') * 1e3:.0f} ms"
        + (f"; `import pandas` {import_seconds('import pandas') * 1e3:.0f} ms" if pd is not None else "")
        + ". robocal imports pyarrow on the first delimited file it reads, not at `import robocal`.\n"
    )


def part_end_to_end(args, canonical: Path) -> None:

    import robocal

    print(f"## 2. End to end: a calibration from a {args.samples:,}-row CSV file\n")
    r = robocal.robot("hsr-jr680")
    robocal.calibrate(canonical, robot="hsr-jr680")  # warm
    times = []
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        res = robocal.calibrate(canonical, robot="hsr-jr680")
        times.append(time.perf_counter() - t0)
    t_robocal, t_median = min(times), float(np.median(times))

    rows = [
        (
            "`robocal.calibrate(csv, robot='hsr-jr680')`",
            t_robocal,
            f"{res.nfev} (+{res.njev} J)" if res.njev else res.nfev,
            rmse(res.problem.data_residuals(res.x)),
            res.metrics["test"]["rmse"],
            res.message,
        )
    ]
    if not args.quick:
        for method in ("lm", "trf"):
            t0 = time.perf_counter()
            calls, train_rmse, test_rmse, message = scipy_csv_fit(canonical, r, method)
            rows.append(
                (
                    f"`pandas.read_csv` + scipy `least_squares(method={method!r}, jac='2-point')`, NumPy model",
                    time.perf_counter() - t0,
                    calls,
                    train_rmse,
                    test_rmse,
                    message,
                )
            )
    print("| pipeline (read the file, 80/20 split, fit) | wall time (s) | residual evaluations | training RMSE (mm) | held-out RMSE (mm) | stop |")
    print("|---|---:|---:|---:|---:|---|")
    for name, t, nfev, train, test, message in rows:
        print(f"| {name} | {t:.3f} | {nfev} | {train:.6f} | {test:.6f} | {message[:90]} |")
    if len(rows) > 1:
        fastest = min(rows[1:], key=lambda row: row[1])
        ratio = fastest[1] / rows[0][1]
        print(
            f"\n**Target: robocal.calibrate(file) ≥ {CALIBRATE_TARGET:g}× scipy with finite differences: "
            f"{'MET' if ratio >= CALIBRATE_TARGET else 'NOT MET'}** ({ratio:.1f}× the faster scipy run, {fastest[1]:.2f} s vs "
            f"{rows[0][1]:.3f} s; robocal best of {args.repeats} after a warm-up call — {fastest[1] / t_median:.1f}× against its "
            f"median {t_median:.3f} s —, each scipy method one run; scipy's residual evaluations counted in the function, "
            "finite-difference ones included)."
        )
    prof = cProfile.Profile()
    prof.enable()
    robocal.calibrate(canonical, robot="hsr-jr680")
    prof.disable()
    text = io.StringIO()
    pstats.Stats(prof, stream=text).sort_stats("tottime").print_stats(12)
    print("\nWhere `robocal.calibrate(csv)` spends its time (cProfile of one call, sorted by own time):\n\n```")
    lines = text.getvalue().splitlines()
    top = next(i for i, line in enumerate(lines) if "ncalls" in line)
    print("\n".join(line.replace(str(Path(robocal.__file__).parent) + "/", "") for line in lines[top : top + 13] if line.strip()))
    print("```")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=20000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--scipy-method", default="lm", choices=["lm", "trf"])
    parser.add_argument("--quick", action="store_true", help="2 000 samples, 3 repeats, no scipy fit")
    add_argument(parser)
    args = parser.parse_args()
    with recording(args.record):
        if args.quick:
            args.samples, args.repeats = 2000, 3
        import pyarrow
        import scipy

        import robocal
        from robocal.data import write_canonical

        print("# Loading benchmark (`python benches/bench_loading.py" + (" --quick" if args.quick else "") + "`)\n")
        print(
            f"machine: {cpu_model()}, {os.cpu_count()} logical CPUs; Python {platform.python_version()}, NumPy {np.__version__}, "
            f"SciPy {scipy.__version__}, pyarrow {pyarrow.__version__}, robocal {robocal.__version__}; load average {load_avg()} at the start\n"
        )
        with tempfile.TemporaryDirectory() as tmp:
            data, _ = robocal.simulate("hsr-jr680", "cable", samples=args.samples, seed=1)
            canonical = write_canonical(data, Path(tmp) / "sim.csv")
            print(
                f"canonical file: `robocal.simulate('hsr-jr680', 'cable', samples={args.samples}, seed=1)` written by "
                f"`robocal.data.write_canonical` ({canonical.stat().st_size / 1e6:.1f} MB, columns q1..q6 (deg), L, t)\n"
            )
            part_loading(args, canonical)
            part_end_to_end(args, canonical)
        print(f"\nload average {load_avg()} at the end")


if __name__ == "__main__":
    main()
