"""``robocal compare``: the paper's comparison of calibrators (:func:`robocal.compare.compare`)."""

from __future__ import annotations

import argparse

from ..calibration.api import method_choices
from ..compare import PROTOCOLS, compare
from ..exceptions import InvalidParameterError
from .arguments import add_data_arguments, add_kinematic_prior_argument


#: Exit status when every run failed: the tables hold no method's figure (written all the same, with the failures).
ALL_FAILED = 1


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.epilog = (
        f"exit status: 0 when at least one run succeeded (failed runs are named in the failures column), "
        f"{ALL_FAILED} when every run failed (the tables and comparison.json are written, with the failures), 2 when refused"
    )
    add_data_arguments(parser)
    parser.add_argument(
        "--protocol",
        choices=PROTOCOLS,
        default="paper",
        help="paper: 120 random samples -> 100 train / 20 test per repeat; kfold: REPEATS folds; "
        "80-20: random 80/20 per repeat; chronological: last 20%% held out (default paper)",
    )
    parser.add_argument("--repeats", type=int, default=5, help="splits (paper, 80-20) or folds (kfold) (default 5)")
    parser.add_argument("--methods", nargs="+", metavar="METHOD", help=f"default: M1..M9 and lm; any of {method_choices()}")
    parser.add_argument("--subset", type=int, help="first draw this many samples at random (e.g. 200 of UR10 Series A)")
    parser.add_argument("--seed", type=int, default=0)
    add_kinematic_prior_argument(parser)
    parser.add_argument("--out", required=True, help="output folder for the tables, figures and comparison.json")


#: compare()'s arguments that no option of the same name sets (for :func:`robocal.cli.cli_words`).
API_WORDS = {"k": "--repeats"}


def run(args: argparse.Namespace) -> int:
    least = 2 if args.protocol == "kfold" else 1  # folds: one to hold out, at least one to fit
    if args.repeats < least:
        what = "the number of folds of --protocol kfold" if args.protocol == "kfold" else f"the number of splits of --protocol {args.protocol}"
        raise InvalidParameterError(f"--repeats is {what}: it must be at least {least}; got {args.repeats}")
    result = compare(
        args.data,
        robot=args.robot,
        measurement=args.measurement,
        methods=args.methods,
        protocol=args.protocol,
        repeats=args.repeats,
        seed=args.seed,
        subset=args.subset,
        kinematic_prior=args.kinematic_prior,
        angle_unit=args.angle_unit,
    )
    paths = result.write(args.out)
    print(result.table_viii().markdown())
    failed = [r for r in result.runs if r["status"] == "failed"]
    if failed:
        print(f"{len(failed)} of {len(result.runs)} runs failed (see the failures column and comparison.json)")
    print(f"wrote {len(paths)} files to {args.out}")
    return ALL_FAILED if failed and len(failed) == len(result.runs) else 0
