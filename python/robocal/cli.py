"""The ``robocal`` command line: one subcommand per module, each providing
``add_arguments(parser)`` and ``run(args) -> exit code``."""

from __future__ import annotations

import argparse
import importlib
import os
import sys

from . import __version__, progress
from .exceptions import RobocalError

#: subcommand -> (module, help)
COMMANDS = {
    "demo": ("robocal.demo", "run the core on a built-in simulated robot (no files needed)"),
    "inspect": ("robocal.data.inspect", "validate a measurement file (canonical CSV or a public dataset)"),
    "calibrate": ("robocal.calibration.api", "identify a robot's kinematic parameters from measurements"),
    "simulate": ("robocal.simulation", "simulate measurements of a robot with known truth and injectable effects"),
    "compare": ("robocal.compare", "run the paper's comparison of calibrators and write its tables and figures"),
    "diagnose": ("robocal.diagnosis.cli", "show what the geometric model gets wrong, name the cause, measure the held-out gain"),
    "compensate": ("robocal.compensation", "joint commands that make the calibrated robot reach desired tool positions"),
    "report": ("robocal.report", "an HTML page with figures of a calibration result (and its diagnosis)"),
    "export": ("robocal.export", "write a calibrated robot as a DH / MDH table (CSV, JSON) or URDF, checked by a round trip"),
}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="robocal", description="Fast, honest kinematic calibration of industrial robots.")
    parser.add_argument("--version", action="version", version=f"robocal {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    sub = parser.add_subparsers(dest="command", required=True)
    for name, (module_name, help_text) in COMMANDS.items():
        module = importlib.import_module(module_name)
        module.add_arguments(sub.add_parser(name, help=help_text, description=help_text))
    args = parser.parse_args(argv)
    progress.QUIET = args.quiet
    try:
        return importlib.import_module(COMMANDS[args.command][0]).run(args)
    except BrokenPipeError:
        # The reader went away (`robocal ... | head`): stop quietly, as Unix tools do.
        sys.stdout = open(os.devnull, "w")
        return 0
    except RobocalError as exc:
        if args.debug:
            raise
        print(f"robocal: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
