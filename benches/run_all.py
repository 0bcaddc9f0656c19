"""Runs every calibration benchmark of the "prove it" issue in sequence and writes each one's
Markdown to stdout (and, with ``--out``, to a file): robocal vs the alternatives
(``bench_alternatives.py``), scaling (``bench_scaling.py``), fleets (``bench_fleet.py``) and robocal vs its NumPy twin
(``bench_calibration.py``, both sides on their default threads).

    python benches/run_all.py --out /tmp/benchmarks.md
    python benches/run_all.py --record benches/records    # the records the manual's benchmark pages render
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
SCRIPTS = [["bench_alternatives.py"], ["bench_scaling.py"], ["bench_fleet.py"], ["bench_calibration.py"]]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", help="also write the Markdown here")
    parser.add_argument("--quick", action="store_true", help="development sizes (bench_calibration.py is skipped)")
    parser.add_argument("--record", metavar="DIR", help="each script also writes its run as DIR/<script>.json (see benches/record.py)")
    args = parser.parse_args()
    chunks = []
    for script in SCRIPTS:
        if args.quick and script[0] == "bench_calibration.py":
            continue
        cmd = [sys.executable, str(HERE / script[0]), *script[1:], *(["--quick"] if args.quick else []), *(["--record", args.record] if args.record else [])]
        out = subprocess.run(cmd, stdout=subprocess.PIPE, text=True, check=True).stdout
        print(out, flush=True)
        chunks.append(out)
    if args.out:
        Path(args.out).write_text("\n".join(chunks))


if __name__ == "__main__":
    main()
