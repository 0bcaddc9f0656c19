"""``robocal report``: the HTML report of a result file (:func:`robocal.report.report`)."""

from __future__ import annotations

import argparse

from ..report import report


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("result", help="calibration result file (JSON of `robocal calibrate --out`)")
    parser.add_argument("--out", metavar="DIR", required=True, help="folder for index.html and its figures")
    parser.add_argument("--data", metavar="FILE", help="measurement file (default: the one the result names)")
    parser.add_argument("--diagnosis", metavar="REPORT.json", help="a `robocal diagnose --json` report to include")
    parser.add_argument("--angle-unit", choices=("deg", "rad"), help="unit of the q columns of a canonical --data file (default deg)")


def run(args: argparse.Namespace) -> int:
    path = report(args.result, args.out, data=args.data, diagnosis=args.diagnosis, angle_unit=args.angle_unit)
    print(f"wrote {path}")
    return 0
