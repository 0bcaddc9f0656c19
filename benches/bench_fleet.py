"""Fleet calibration: many robots in one call, serial vs threads vs processes vs a local Dask
cluster, with the parallel efficiency on this machine.

    python benches/bench_fleet.py [--robots 24] [--samples 1000] [--method lm]

Each robot is a simulated HSR JR680 with its own geometric errors (seed = robot index), cable
data, written as a canonical CSV (workers read files, as a fleet job would). Efficiency =
one-core time / (cores used × wall time). Dask: ``distributed.LocalCluster`` with one
single-threaded worker process per core and ``client.map(calibrate_one, paths, ...)`` — the
same call a user runs on a real cluster (``Client("scheduler:8786")``).

The baseline of speed-up and efficiency is one worker process with a single-threaded core (one
core); "serial" is the plain loop in this process, whose Rust kernels use every core.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from machine import cpu_model

import robocal
from robocal.calibration.fleet import calibrate_many, calibrate_one
from robocal.data import write_canonical


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=24)
    parser.add_argument("--samples", type=int, default=1000)
    parser.add_argument("--method", default="lm")
    args = parser.parse_args()
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
    one_core = None
    for backend, n in (("process", 1), ("serial", 1), ("thread", workers), ("process", workers)):
        t0 = time.perf_counter()
        results = calibrate_many(paths, workers=n, backend=backend, **options)
        wall = time.perf_counter() - t0
        one_core = one_core or wall
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
