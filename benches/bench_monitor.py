"""The in-line monitor on simulated streams: detection delay per change kind and size, false alarms
on clean streams, time per update.

    python benches/bench_monitor.py [--samples 3000] [--seeds 3] [--factors 3,5] [--mean-run-lengths 1e5] [--figure PNG] [--record PATH]

Per robot and sensor (a tracker's positions or poses, a cable): a calibration on one simulated session, then new sessions of the same robot
(``--samples`` each, ``--new-session``) replayed sample by sample: clean (false alarms counted
over every monitored sample), and with a change at the middle of the stream — a joint's zero
(joints 2 and 3: the reading that much below the angle from then on) or the sensor's step (the
cable re-zeroed, the tracker moved), 3x and 5x the detection limit the monitor states for it
just before the change (the size column: their median over the streams).
Prints a Markdown table: samples from the change to the alarm (median over seeds; "missed" when
none named the change) and the error of its estimated start (the first alarm, provisional or not); the samples to the
first alarm that names it for good and whether its kind was right; and the median time per update.
With several ``--mean-run-lengths`` (the stated samples between false alarms, the monitor's
``mean_run_length``), every row is run at each, the changes of the same size: the multiples of the
limits stated at the monitor's default (``MEAN_RUN_LENGTH``), so that a rarer false alarm shows as a
longer delay; with ``--figure`` the median delay to the first alarm is drawn against the stated
false-alarm rate, a line per robot, sensor and change at the first of ``--factors``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import robocal
from robocal.monitoring import MEAN_RUN_LENGTH, OPENING, Monitor
from robocal.simulation import simulate

from record import add_argument, recording

CASES = (("ur10", "position"), ("hsr-jr680", "cable"), ("abb-irb120", "position"), ("ur10", "pose"), ("abb-irb120", "pose"))


def _run(result, q, y, mean_run_length, at=None):
    """The stream replayed; with ``at``, also the detection limits the monitor states just before sample ``at``."""
    monitor = Monitor(result, new_session=True, mean_run_length=mean_run_length)
    times, alarms, limits = [], [], None
    for i, (qi, yi) in enumerate(zip(q, y)):
        if i == at:
            limits = {(e["kind"], e["joint"]): e["size"] for e in monitor.summary()["detection_limits"]}
        t0 = time.perf_counter()
        alarms += monitor.update(qi, yi)
        times.append(time.perf_counter() - t0)
    return monitor, alarms, times[OPENING:], limits


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=3000)
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--factors", default="3,5", help="the changes' sizes in multiples of their detection limits (comma-separated)")
    parser.add_argument("--mean-run-lengths", default=f"{MEAN_RUN_LENGTH:g}", help="stated samples between false alarms (comma-separated)")
    parser.add_argument("--figure", default=None, help="a PNG of the delay against the stated false-alarm rate")
    add_argument(parser)
    args = parser.parse_args()
    with recording(args.record):
        run(args)


def run(args) -> None:
    at = args.samples // 2
    factors = [float(f) for f in args.factors.split(",")]
    lengths = [float(v) for v in args.mean_run_lengths.split(",")]
    print(
        "| robot, sensor | stated samples between false alarms | change | size (x limit) | delay, samples (median) | start error (median) "
        "| named after, samples (median) | named right | false alarms on clean streams | time per update (median) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    curves: dict = {}  # (robot, sensor, change) -> [(false-alarm rate, median delay)] at the first factor
    for robot, measurement in CASES:
        data, _ = simulate(robot, measurement, samples=400, seed=2)
        result = robocal.calibrate(data, robot=robot).to_dict()
        streams = [simulate(robot, measurement, samples=args.samples, seed=2, session=s + 1)[0] for s in range(args.seeds)]
        # the limits each change is sized by: those stated just before it at the monitor's default rate
        stated = [limits for _, _, _, limits in (_run(result, s.q, s.y, MEAN_RUN_LENGTH, at) for s in streams)]
        for length in lengths:
            clean = [_run(result, s.q, s.y, length) for s in streams]
            false = sum(len(a) for _, a, _, _ in clean)
            monitored = sum(len(s) - OPENING for s in streams)
            timing = np.median(np.concatenate([t for _, _, t, _ in clean])) * 1e3
            for kind, joint in (("joint_zero", 2), ("joint_zero", 3), ("step", None)):
                what = f"joint {joint} zero" if kind == "joint_zero" else "sensor step"
                for factor in factors:
                    sizes = [factor * limits[(kind, joint)] for limits in stated]
                    delays, starts, naming, right = [], [], [], 0
                    for s, size in zip(streams, sizes):
                        q, y = s.q.copy(), s.y.copy()
                        if kind == "joint_zero":
                            q[at:, joint - 1] -= np.radians(size)
                        else:
                            moved = min(y.shape[1], 3)  # the cable's length, or a tracker's point (a pose's orientation stays)
                            y[at:, :moved] += size / np.sqrt(moved)
                        _, alarms, _, _ = _run(result, q, y, length)
                        after = [a for a in alarms if a.sample >= at]
                        if after:
                            delays.append(after[0].sample - at)
                            starts.append(abs(after[0].since - at))
                        named = [a for a in after if not a.provisional]  # a provisional alarm (the sensor's step) is told, not the naming
                        if named:
                            naming.append(named[0].sample - at)
                            right += (named[0].kind, named[0].joint) == (kind, joint)
                    if factor == factors[0] and delays:
                        curves.setdefault((robot, measurement, what), []).append((1.0 / length, float(np.median(delays))))
                    unit = "deg" if kind == "joint_zero" else "mm"
                    delay = f"{np.median(delays):.0f}" if delays else "missed"
                    start = f"{np.median(starts):.0f}" if starts else "-"
                    named_after = f"{np.median(naming):.0f}" if naming else "-"
                    print(
                        f"| {robot}, {measurement} | {length:g} | {what} | {np.median(sizes):.3g} {unit} ({factor:g}x) | {delay} ({len(delays)}/{len(streams)} found) | "
                        f"{start} | {named_after} | {right}/{len(streams)} | {false} in {monitored} | {timing:.2f} ms |",
                        flush=True,
                    )
    if args.figure:
        _figure(curves, factors[0], args.figure)


def _figure(curves: dict, factor: float, path: str) -> None:
    """The median delay to the first alarm against the stated false-alarm rate, a line per case."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 4.8))
    colours = dict(zip(dict.fromkeys((r, m) for r, m, _ in curves), plt.get_cmap("tab10").colors))
    styles = {"joint 2 zero": "-", "joint 3 zero": ":", "sensor step": "--"}
    for (robot, measurement, what), points in curves.items():
        rate, delay = zip(*sorted(points))
        ax.plot(rate, delay, marker="o", color=colours[(robot, measurement)], linestyle=styles[what], label=f"{robot} {measurement}: {what}")
    ax.set_xscale("log")
    ax.set_xlabel("stated false-alarm rate (alarms per sample)")
    ax.set_ylabel("delay to the first alarm (samples, median)")
    ax.set_title(f"robocal monitor: a change of {factor:g}x the detection limit stated at {1 / MEAN_RUN_LENGTH:g} per sample")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"figure written to {path}")


if __name__ == "__main__":
    main()
