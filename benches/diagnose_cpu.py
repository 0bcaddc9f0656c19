"""CPU seconds of ``robocal.diagnose`` on the first N files of the discovery benchmark's mismatch
section, for two or more code trees in turn (a regression check of one change, not a comparison
with another tool): process CPU time, so other jobs on the machine weigh on it less than on wall
time; the trees alternate round by round and the median of the rounds is printed per tree.

    python benches/diagnose_cpu.py --code OLD/python --code NEW/python [--files 40] [--rounds 2]

Each tree needs its compiled core (``_robocal*.so``) beside its Python sources.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def worker(files: int) -> None:
    """In a process of one tree: the CPU seconds of diagnose over the first ``files`` files."""
    import time

    sys.path.insert(0, str(HERE))
    import discovery
    import mismatch
    from threadpoolctl import threadpool_limits

    import robocal
    from robocal.exceptions import InvalidParameterError

    total, done = 0.0, 0
    with threadpool_limits(1):
        for f in discovery.mismatch_plan(25)[:files]:
            acq = mismatch.acquisition(f["robot"], f["measurement"], discovery.SAMPLES, f["seed"])
            try:
                effects, _ = discovery.mismatch_effects(f, acq)
            except InvalidParameterError:
                continue
            data = robocal.Dataset(q=acq.q, y=mismatch.readings(acq, effects), measurement=f["measurement"], robot=f["robot"], t=acq.t)
            start = time.process_time()
            robocal.diagnose(data, robot=f["robot"])
            total, done = total + time.process_time() - start, done + 1
    print(json.dumps({"files": done, "cpu_s": total}))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--code", action="append", default=[], help="a tree's python/ folder (give two or more)")
    parser.add_argument("--files", type=int, default=40)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        worker(args.files)
        return
    if len(args.code) < 2:
        parser.error("give two code trees or more (--code OLD/python --code NEW/python)")
    seconds: dict = {code: [] for code in args.code}
    for _ in range(args.rounds):
        for code in args.code:
            env = {**os.environ, "PYTHONPATH": code, "OPENBLAS_NUM_THREADS": "1"}
            out = subprocess.run([sys.executable, __file__, "--worker", "--files", str(args.files)], env=env, capture_output=True, text=True, check=True)
            seconds[code].append(json.loads(out.stdout.strip().splitlines()[-1])["cpu_s"])
    load = Path("/proc/loadavg").read_text().split()[:3] if Path("/proc/loadavg").exists() else ["?"]
    first = statistics.median(seconds[args.code[0]])
    for code, values in seconds.items():
        median = statistics.median(values)
        print(f"{code}: CPU s per round {', '.join(f'{v:.1f}' for v in values)}; median {median:.1f} ({median / first:.2f}x the first); load {' '.join(load)}")


if __name__ == "__main__":
    main()
