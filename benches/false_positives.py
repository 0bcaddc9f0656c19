"""False-positive rate of ``robocal.diagnose`` on clean simulated data (no effect hidden).

    python benches/false_positives.py [--seeds 100] [--samples 300]

Seeds alternate over two robots (ABB IRB 120, HSR JR680) and two measurements (cable,
position), with the simulator's default geometric errors and sensor noise. A false positive is
a dataset on which diagnose accepts any cause (outliers included). Prints each hit and the rate
with its 95 % Clopper-Pearson interval.
"""

from __future__ import annotations

import argparse

from scipy.stats import beta

from robocal.diagnosis import diagnose
from robocal.simulation import simulate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=100)
    parser.add_argument("--samples", type=int, default=300)
    args = parser.parse_args()
    hits = 0
    for seed in range(args.seeds):
        robot, measurement = ("abb-irb120", "hsr-jr680")[seed % 2], ("cable", "position")[(seed // 2) % 2]
        data, _ = simulate(robot, measurement, samples=args.samples, seed=10_000 + seed)
        effects = diagnose(data).effects
        if effects:
            hits += 1
            print(f"seed {10_000 + seed} ({robot}, {measurement}): {[e.get('label', e['kind']) for e in effects]}")
    n = args.seeds
    lo = beta.ppf(0.025, hits, n - hits + 1) if hits else 0.0
    hi = beta.ppf(0.975, hits + 1, n - hits) if hits < n else 1.0
    print(f"false positives: {hits} of {n} clean datasets = {hits / n:.1%} (95 % interval {lo:.1%}-{hi:.1%}), {args.samples} samples each")


if __name__ == "__main__":
    main()
