"""Fleet calibration: many robots in one call, serial vs threads vs processes vs a local Dask
cluster, with the parallel efficiency on this machine.

    python benches/bench_fleet.py [--robots 200] [--samples 2000] [--method lm]

Each robot is a simulated HSR JR680 with its own geometric errors (seed = robot index), cable
data, written as a canonical CSV (workers read files, as a fleet job would). Efficiency =
one-core time / (cores used × wall time). Dask: ``distributed.LocalCluster`` with one
single-threaded worker process per core and ``client.map(calibrate_one, paths, ...)`` — the
same call a user runs on a real cluster (``Client("scheduler:8786")``).

The baseline of speed-up and efficiency is the serial loop on one core: a fresh process with
``RAYON_NUM_THREADS=1``, timed inside it (its start-up excluded). "serial" is the same loop in
this process, whose Rust kernels use every core. The process pool's and Dask's times include
starting their workers, as a user pays it.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from machine import cpu_model
from record import add_argument, recording

import robocal
from robocal.fleet import calibrate_many, calibrate_one
from robocal.data import write_canonical


def serial_wall_time(paths: list[str], options: dict) -> float:
    t0 = time.perf_counter()
    calibrate_many(paths, backend="serial", **options)
    return time.perf_counter() - t0


def one_core_wall_time(paths: list[str], options: dict) -> float:
    """The serial loop in a fresh single-threaded process (see the module doc)."""
    env = dict(os.environ, RAYON_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    job = json.dumps({"paths": paths, "options": options})
    out = subprocess.run([sys.executable, __file__, "--one-core", job], env=env, check=True, capture_output=True, text=True)
    return float(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=200)
    parser.add_argument("--samples", type=int, default=2000)
    parser.add_argument("--method", default="lm")
    parser.add_argument("--quick", action="store_true", help="development size: 24 robots x 500 samples")
    parser.add_argument("--one-core", help=argparse.SUPPRESS)  # internal: the baseline's process
    add_argument(parser)
    args = parser.parse_args()
    with recording(args.record):
        if args.quick:
            args.robots, args.samples = 24, 500
        if args.one_core:
            job = json.loads(args.one_core)
            print(serial_wall_time(job["paths"], job["options"]))
            return
        workers = os.cpu_count() or 1
        folder = Path(tempfile.mkdtemp(prefix="robocal-fleet-"))
        paths = []
        for i in range(args.robots):
            data, _ = robocal.simulate("hsr-jr680", "cable", samples=args.samples, seed=i)
            paths.append(str(write_canonical(data, folder / f"robot{i:04d}.csv")))
        options = {"robot": "hsr-jr680", "method": args.method}
        print(f"machine: {cpu_model()}, {workers} logical CPUs; robocal {robocal.__version__}")
        print(f"{args.robots} robots × {args.samples} cable samples, method {args.method}\n")
        print("| backend | workers | wall time (s) | robots/s | speed-up | efficiency | all succeeded |")
        print("|---|---|---|---|---|---|---|")
        one_core = one_core_wall_time(paths, options)
        print(f"| serial, one core | 1 | {one_core:.2f} | {args.robots / one_core:.1f} | 1.00× | 100% | |")
        for backend, n in (("serial", 1), ("thread", workers), ("process", workers)):
            t0 = time.perf_counter()
            results = calibrate_many(paths, workers=n, backend=backend, **options)
            wall = time.perf_counter() - t0
            ok = all("error" not in r for r in results)
            cores = workers if backend in ("serial", "thread") else n
            print(f"| {backend} | {n} | {wall:.2f} | {args.robots / wall:.1f} | {one_core / wall:.2f}× | {one_core / (cores * wall):.0%} | {ok} |")
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            print("| dask | — | not installed (pip install 'dask[distributed]') | | | | |")
            return
        with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, env={"RAYON_NUM_THREADS": "1"}) as cluster, Client(cluster) as client:
            client.gather(client.map(calibrate_one, paths[:workers], pure=False, **options))  # warm the workers
            t0 = time.perf_counter()
            results = client.gather(client.map(calibrate_one, paths, pure=False, **options))
            wall = time.perf_counter() - t0
        ok = all("error" not in r for r in results)
        print(f"| dask LocalCluster | {workers} | {wall:.2f} | {args.robots / wall:.1f} | {one_core / wall:.2f}× | {one_core / (workers * wall):.0%} | {ok} |")


if __name__ == "__main__":
    main()
