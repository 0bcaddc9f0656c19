"""The monitor's false alarms on long clean streams: the rate its thresholds state (one per ``--mean-run-length``
samples, 100 000 by default) measured over about 10⁵ monitored samples.

    python benches/monitor_false_alarms.py [--robot hsr-jr680] [--measurement cable] [--samples 10200] [--sessions 10]
                                           [--wander RHO SIGMA] [--record PATH]

A calibration on 400 samples of one simulated session (as ``bench_monitor.py`` makes it), then ``--sessions`` new
sessions of the same robot, nothing changed, replayed with ``--new-session``; with ``--wander``, the sensor's readings
wander as an AR(1) process (correlation ``RHO`` from sample to sample, ``SIGMA`` mm stationary; each session its own draw). Prints a Markdown table per session: the
samples monitored, the alarms (sample, kind, evidence over its threshold; each counted, a provisional one too) and the
long-run inflation at the end.
"""

from __future__ import annotations

import argparse

import numpy as np
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
    parser.add_argument("--wander", type=float, nargs=2, metavar=("RHO", "SIGMA"), help="an AR(1) wander of the readings")
    add_argument(parser)
    args = parser.parse_args()
    with recording(args.record):
        data, _ = simulate(args.robot, args.measurement, samples=400, seed=2)
        result = robocal.calibrate(data, robot=args.robot).to_dict()
        wander = "" if args.wander is None else f", the readings wandering as AR(1) ({args.wander[0]:g}, {args.wander[1]:g} mm)"
        print(f"{args.robot}, {args.measurement}: calibrated on 400 samples of session 0; clean sessions of {args.samples} samples{wander}\n")
        print("| session | monitored | alarms | long-run inflation at the end |")
        print("|---|---|---|---|")
        total = alarms_total = 0
        for s in range(1, args.sessions + 1):
            stream, _ = simulate(args.robot, args.measurement, samples=args.samples, seed=2, session=s)
            y = stream.y if args.wander is None else stream.y + _wander(stream.y.shape, *args.wander, np.random.default_rng(s))
            monitor, alarms, _, _ = _run(result, stream.q, y)
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


def _wander(shape, rho: float, sigma: float, rng) -> np.ndarray:
    """An AR(1) process of ``shape`` (samples, readings), correlation ``rho``, stationary std ``sigma``, from zero."""
    w = np.zeros(shape)
    for t in range(1, shape[0]):
        w[t] = rho * w[t - 1] + sigma * np.sqrt(1 - rho**2) * rng.standard_normal(shape[1])
    return w


if __name__ == "__main__":
    main()
