"""The in-line monitor's speed: the median time of ``Monitor.update`` per sample, and of ``robocal
monitor FILE`` end to end per sample (wall and the process's CPU time each), on simulated streams of ``--samples`` samples (UR10 with a
position sensor, HSR JR680 with a cable sensor; calibrated on 400 samples of one session, the
stream a new session replayed with ``--new-session``), the machine's load beside each figure.

    python benches/bench_monitor_speed.py [--samples 3000] [--rounds 2] [--code PATH ...]

``--code`` names the ``python`` folder of a robocal tree to time (default: the one imported); with
several, they are timed in turn, round after round, in one run, so that a before/after ratio is
measured under the same load; the CPU times count less of what other processes take of the machine. Set
``OPENBLAS_NUM_THREADS=1`` on a shared machine.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from record import add_argument, recording

CASES = (("ur10", "position"), ("hsr-jr680", "cable"))


def _load() -> str:
    return Path("/proc/loadavg").read_text().split()[0] if Path("/proc/loadavg").exists() else "?"


def _children_cpu() -> float:
    """User and system CPU seconds of the child processes waited for so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _prepare(folder: Path, samples: int) -> None:
    """A result and a stream per case, written once and shared by every tree timed."""
    import robocal
    from robocal.data import write_canonical
    from robocal.simulation import simulate

    for robot, measurement in CASES:
        data, _ = simulate(robot, measurement, samples=400, seed=2)
        (folder / f"{robot}.json").write_text(json.dumps(robocal.calibrate(data, robot=robot).to_dict()))
        stream, _ = simulate(robot, measurement, samples=samples, seed=2, session=1)
        write_canonical(stream, folder / f"{robot}.csv")


def _time_updates(folder: Path) -> None:
    """Run inside the tree timed: the median wall and CPU times of one ``update`` after the opening."""
    import numpy as np
    from robocal.data import read_canonical
    from robocal.monitoring import Monitor

    out = {}
    for robot, measurement in CASES:
        monitor = Monitor(str(folder / f"{robot}.json"), new_session=True)
        data = read_canonical(folder / f"{robot}.csv", measurement=measurement)
        times, cpu = [], []
        for q, y in zip(data.q, data.y):
            t0, c0 = time.perf_counter(), time.process_time()
            monitor.update(q, y)
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
        out[robot] = [float(np.median(times[monitor.opening :])), float(np.median(cpu[monitor.opening :]))]
    print(json.dumps(out))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=3000)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--code", action="append", help="the python folder of a robocal tree (repeatable)")
    parser.add_argument("--updates-in", help=argparse.SUPPRESS)  # the child process that times updates
    add_argument(parser)
    args = parser.parse_args()
    with recording(args.record):
        if args.updates_in:
            _time_updates(Path(args.updates_in))
            return
        codes = args.code or [str(Path(__import__("robocal").__file__).parents[1])]
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp)
            _prepare(folder, args.samples)
            print(f"{args.samples} samples per stream; median over the samples after the opening; load = 1-minute load average")
            print("| code | round | robot, sensor | update (median): wall | CPU | load | robocal monitor end to end, per sample: wall | CPU | load |")
            print("|---|---|---|---|---|---|---|---|---|")
            for round_ in range(1, args.rounds + 1):
                for code in codes:
                    env = {**os.environ, "PYTHONPATH": code}
                    load = _load()
                    done = subprocess.run([sys.executable, __file__, "--updates-in", str(folder)], env=env, capture_output=True, text=True, check=True)
                    updates = json.loads(done.stdout.strip().splitlines()[-1])
                    for robot, measurement in CASES:
                        load_cli = _load()
                        t0, c0 = time.perf_counter(), _children_cpu()
                        subprocess.run(
                            [
                                sys.executable,
                                "-m",
                                "robocal",
                                "monitor",
                                str(folder / f"{robot}.json"),
                                str(folder / f"{robot}.csv"),
                                "--new-session",
                                "--quiet",
                            ],
                            env=env,
                            capture_output=True,
                            check=True,
                        )
                        end_to_end, cpu = (time.perf_counter() - t0) / args.samples, (_children_cpu() - c0) / args.samples
                        wall, cpu_update = updates[robot]
                        print(
                            f"| {code} | {round_} | {robot}, {measurement} | {wall * 1e3:.2f} ms | {cpu_update * 1e3:.2f} ms | {load} "
                            f"| {end_to_end * 1e3:.2f} ms | {cpu * 1e3:.2f} ms | {load_cli} |",
                            flush=True,
                        )


if __name__ == "__main__":
    main()
