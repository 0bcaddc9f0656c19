"""The monitor's false alarms on long clean streams: the rate its thresholds state (one per ``--mean-run-length``
samples, 100 000 by default) measured over about 10⁵ monitored samples.

    python benches/monitor_false_alarms.py [--robot hsr-jr680] [--measurement cable] [--samples 10200] [--sessions 10]
                                           [--record PATH]

A calibration on 400 samples of one simulated session (as ``bench_monitor.py`` makes it), then ``--sessions`` new
sessions of the same robot, nothing changed, replayed with ``--new-session``. Prints a Markdown table per session: the
samples monitored, the alarms (sample, kind, evidence over its threshold; each counted, a provisional one too) and the
long-run inflation at the end.
"""

from __future__ import annotations

import argparse

import robocal
from bench_monitor import _run
from robocal.monitoring import OPENING
from robocal.simulation import simulate

from record import add_argument, recording


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="hsr-jr680")
    parser.add_argument("--measurement", default="cable")
    parser.add_argument("--samples", type=int, default=10_200)
    parser.add_argument("--sessions", type=int, default=10)
    add_argument(parser)
    args = parser.parse_args()
    with recording(args.record):
        data, _ = simulate(args.robot, args.measurement, samples=400, seed=2)
        result = robocal.calibrate(data, robot=args.robot).to_dict()
        print(f"{args.robot}, {args.measurement}: calibrated on 400 samples of session 0; clean sessions of {args.samples} samples\n")
        print("| session | monitored | alarms | long-run inflation at the end |")
        print("|---|---|---|---|")
        total = alarms_total = 0
        for s in range(1, args.sessions + 1):
            stream, _ = simulate(args.robot, args.measurement, samples=args.samples, seed=2, session=s)
            monitor, alarms, _ = _run(result, stream.q, stream.y)
            total += args.samples - OPENING
            alarms_total += len(alarms)
            said = (
                "; ".join(
                    f"{a.sample} {a.kind}{'' if a.joint is None else f' {a.joint}'} ({a.evidence:.2f}x{', provisional' if a.provisional else ''})"
                    for a in alarms
                )
                or "none"
            )
            print(f"| {s} | {args.samples - OPENING} | {said} | {monitor.inflation:.3g} |", flush=True)
        print(f"\n{alarms_total} alarms in {total} monitored samples: {alarms_total / total:.2g} per sample (stated: {1 / monitor.mean_run_length:.2g})")


if __name__ == "__main__":
    main()
