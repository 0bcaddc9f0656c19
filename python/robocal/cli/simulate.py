"""``robocal simulate``: simulated measurements (:func:`robocal.simulate`) as a canonical CSV and their truth."""

from __future__ import annotations

from ..effects import EFFECTS
from ..outputs import printable
from ..serial_robot import MEASUREMENTS
from ..simulation import simulate, write_simulation


def add_arguments(parser) -> None:
    """Arguments of ``robocal simulate``."""
    parser.add_argument(
        "--robot", default="hsr-jr680", help="built-in robot, or a robot / result .json/.yaml, exported table or .urdf file (default hsr-jr680)"
    )
    parser.add_argument("--measurement", default="cable", choices=MEASUREMENTS, help="observation type (default cable)")
    parser.add_argument("--samples", type=int, default=400, help="number of samples (default 400)")
    parser.add_argument("--seed", type=int, default=1, help="random seed (default 1)")
    parser.add_argument(
        "--session",
        type=int,
        default=0,
        help="another session of the same robot (same --seed; another --measurement sees the same robot as far as both sensors identify it): new path, noise and set-up (default 0)",
    )
    parser.add_argument(
        "--effect", action="append", default=[], metavar="KIND[:key=value,...]", help=f"a non-geometric effect; repeatable. Kinds: {', '.join(sorted(EFFECTS))}"
    )
    parser.add_argument("--noise", type=float, default=None, metavar="MM", help="sensor noise sigma in mm (0: noiseless; default: the sensor's)")
    parser.add_argument("--outliers", type=float, default=0.0, metavar="FRACTION", help="fraction of gross outliers (default 0)")
    parser.add_argument("--no-geometric-error", dest="geometric_error", action="store_false", help="true geometry = nominal")
    parser.add_argument("--out", required=True, help="output CSV (canonical format)")
    parser.add_argument("--truth", default=None, help="output JSON with the ground truth")


def run(args) -> int:
    """Runs ``robocal simulate``; returns the exit code."""
    options = dict(samples=args.samples, seed=args.seed, effects=args.effect, noise=args.noise, geometric_error=args.geometric_error)
    dataset, truth = simulate(args.robot, args.measurement, outliers=args.outliers, session=args.session, **options)
    csv_path, json_path = write_simulation(dataset, truth, args.out, args.truth)
    effects = ", ".join(e["spec"] for e in truth["effects"]) or "none"
    print(
        f"wrote {len(dataset)} {args.measurement} samples of {printable(truth['robot'], one_line=True)} to {csv_path}"
        + (f" and the truth to {json_path}" if json_path else "")
    )
    print(f"effects: {effects}")
    return 0
