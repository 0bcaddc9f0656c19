"""False-positive rate of ``robocal.diagnose`` on clean simulated data (no effect hidden).

    python benches/false_positives.py [--seeds 100] [--samples 300]

Seeds alternate over two robots (ABB IRB 120, HSR JR680) and two measurements (cable,
position), with the simulator's default geometric errors and sensor noise; every fourth dataset
is instead a narrow, D1-like region (HSR JR680 cable lengths, joints 1-5 within ±5° of a random
pose, joint 6 constant, small random geometric errors), where the geometry is poorly determined
and the reading-convention search runs. A false positive is a dataset on which diagnose accepts
any cause (outliers included). Prints each hit and the rate with its 95 % Clopper-Pearson
interval, overall and for the narrow datasets.
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.stats import beta

import robocal
from robocal.data import Dataset
from robocal.diagnosis import diagnose
from robocal.simulation import DEFAULT_NOISE, simulate


def narrow_clean(seed: int, samples: int) -> Dataset:
    """Clean cable lengths of a slightly perturbed HSR JR680 over a narrow region."""
    robot = robocal.robot("hsr-jr680")
    rng = np.random.default_rng(seed)
    centre = np.radians([rng.uniform(-30, 30), rng.uniform(-80, -50), rng.uniform(190, 220), rng.uniform(-180, -150), rng.uniform(30, 50), 60])
    q = centre + np.radians(rng.uniform(-5, 5, (samples, 6))) * [1, 1, 1, 1, 1, 0]
    params = robot.params.copy()
    for k, (name, unit) in enumerate(zip(robot.param_names, robot.param_units)):
        if name.rstrip("0123456789") in ("a", "d", "alpha", "theta"):
            params[k] += rng.normal(0, 0.5) if unit == "mm" else np.radians(rng.normal(0, 0.05))
    values = dict(zip(robot.param_names, params))
    values.update(tool_z=60.0, anchor_x=1500.0, anchor_y=300.0, anchor_z=-200.0, cable_offset=950.0)
    true = robot.with_params(**values)
    L = true.predict("cable", q)[:, 0] + rng.normal(0.0, DEFAULT_NOISE["cable"].sigma, samples)
    return Dataset(q=q, y=L[:, None], measurement="cable", robot="hsr-jr680")


def interval(hits: int, n: int) -> str:
    lo = beta.ppf(0.025, hits, n - hits + 1) if hits else 0.0
    hi = beta.ppf(0.975, hits + 1, n - hits) if hits < n else 1.0
    return f"{hits} of {n} = {hits / n:.1%} (95 % interval {lo:.1%}-{hi:.1%})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=100)
    parser.add_argument("--samples", type=int, default=300)
    args = parser.parse_args()
    hits, narrow_hits, narrow = 0, 0, 0
    for seed in range(args.seeds):
        robot, measurement = ("abb-irb120", "hsr-jr680")[seed % 2], ("cable", "position")[(seed // 2) % 2]
        if seed % 4 == 3:
            robot, measurement, narrow = "hsr-jr680 (narrow)", "cable", narrow + 1
            data = narrow_clean(10_000 + seed, args.samples)
        else:
            data, _ = simulate(robot, measurement, samples=args.samples, seed=10_000 + seed)
        effects = diagnose(data).effects
        if effects:
            hits += 1
            narrow_hits += seed % 4 == 3
            print(f"seed {10_000 + seed} ({robot}, {measurement}): {[e.get('label', e['kind']) for e in effects]}", flush=True)
    print(f"false positives: {interval(hits, args.seeds)} clean datasets, {args.samples} samples each; narrow ones: {interval(narrow_hits, narrow)}")


if __name__ == "__main__":
    main()
