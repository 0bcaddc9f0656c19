"""Arguments shared by the subcommands that read measurements."""

from __future__ import annotations

import argparse

from ..calibration.problem import KINEMATIC_PRIOR_RANGE
from ..exceptions import InvalidParameterError


def _mm_deg(text: str) -> tuple[float, float]:
    try:
        length, angle = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected MM,DEG (e.g. 10,1); got {text!r}") from None
    (mm_low, mm_high), (deg_low, deg_high) = KINEMATIC_PRIOR_RANGE["mm"], KINEMATIC_PRIOR_RANGE["deg"]
    if not (mm_low <= length <= mm_high and deg_low <= angle <= deg_high):
        raise argparse.ArgumentTypeError(f"MM must lie in [{mm_low:g}, {mm_high:g}] and DEG in [{deg_low:g}, {deg_high:g}]; got {text!r}")
    return length, angle


def add_kinematic_prior_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--kinematic-prior",
        type=_mm_deg,
        metavar="MM,DEG",
        help="Gaussian prior at nominal on every kinematic parameter, sigma MM for lengths and DEG for angles",
    )


def add_data_arguments(parser: argparse.ArgumentParser, sessions: bool = False) -> None:
    """The arguments of every command that calibrates on a measurement file (``sessions``: on
    one or more, each a session of one robot)."""
    if sessions:
        parser.add_argument("data", nargs="+", help="measurement file(s); several files are sessions of one robot, each with its own set-up")
    else:
        parser.add_argument("data", help="measurement file (canonical CSV or a public dataset)")
    parser.add_argument("--robot", help="robot name, or a robot / result .json/.yaml, exported table or .urdf file (default: the one the data name)")
    parser.add_argument("--measurement", choices=["cable", "position", "pose"])
    if sessions:
        parser.add_argument(
            "--angle-unit",
            type=angle_units,
            metavar="UNIT[,UNIT...]",
            help="unit of the q columns of canonical files, deg or rad: one for all files, or one per file in their order "
            "(default deg; values implausible for the default are refused)",
        )
    else:
        add_angle_unit_argument(parser)


def add_angle_unit_argument(parser: argparse.ArgumentParser, what: str = "q columns of a canonical file") -> None:
    parser.add_argument("--angle-unit", choices=("deg", "rad"), help=f"unit of the {what} (default deg; values implausible for the default are refused)")


def files_angle_unit(args: argparse.Namespace):
    """``--angle-unit`` of a command taking several files (``args.data``), its count checked against them."""
    unit = args.angle_unit
    if isinstance(unit, list) and len(unit) != len(args.data):
        raise InvalidParameterError(f"--angle-unit gives {len(unit)} units for {len(args.data)} file(s): give one for all, or one per file in their order")
    return unit


def angle_units(text: str):
    """``--angle-unit`` of a command taking several files: one unit, or a list of one per file."""
    units = [u.strip() for u in text.split(",")]
    wrong = [u for u in units if u not in ("deg", "rad")]
    if wrong:
        raise argparse.ArgumentTypeError(f"each unit must be deg or rad; got {wrong[0]!r}")
    return units[0] if len(units) == 1 else units
