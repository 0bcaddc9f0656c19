"""The ``robocal`` command line: one subcommand per module, each providing
``add_arguments(parser)`` and ``run(args) -> exit code``."""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from dataclasses import dataclass

from . import __version__, progress
from .exceptions import RobocalError
from .outputs import check_outputs


@dataclass(frozen=True)
class Paths:
    """Which arguments of a subcommand name files it reads, files it writes and folders it
    writes into: :func:`robocal.outputs.check_outputs` refuses a clash before any work."""

    inputs: tuple = ()
    files: tuple = ()
    folders: tuple = ()


#: subcommand -> (module, help, paths)
COMMANDS = {
    "demo": ("robocal.demo", "run the core on a built-in simulated robot (no files needed)", Paths(folders=("out",))),
    "inspect": ("robocal.data.inspect", "validate a measurement file (canonical CSV or a public dataset)", Paths(("path", "robot"), ("json",))),
    "calibrate": ("robocal.calibration.api", "identify a robot's kinematic parameters from measurements", Paths(("data", "robot", "causes"), ("out",))),
    "simulate": ("robocal.simulation", "simulate measurements of a robot with known truth and injectable effects", Paths(("robot",), ("out", "truth"))),
    "compare": ("robocal.compare", "run the paper's comparison of calibrators and write its tables and figures", Paths(("data", "robot"), (), ("out",))),
    "diagnose": ("robocal.diagnosis.cli", "show what the geometric model gets wrong, name the cause, measure the held-out gain",
                 Paths(("data", "robot"), ("json",), ("out",))),  # fmt: skip
    "verify": ("robocal.verification", "evaluate a calibration result on new measurements, re-fitting only the session set-up", Paths(("result", "data"), ("json",))),
    "compensate": ("robocal.compensation", "joint commands that make the calibrated robot reach desired tool positions", Paths(("result", "targets"), ("out",))),
    "report": ("robocal.report", "an HTML page with figures of a calibration result (and its diagnosis)", Paths(("result", "data", "diagnosis"), (), ("out",))),
    "export": ("robocal.export", "write a calibrated robot as a DH / MDH table (CSV, JSON) or URDF, checked by a round trip", Paths(("result",), ("out",))),
}


def _global_options(parser: argparse.ArgumentParser, default) -> None:
    # Added to the main parser and to every subparser so that they work on either side of the
    # subcommand; the subparsers' default SUPPRESS keeps a value given before it.
    parser.add_argument("--debug", action="store_true", default=default, help="show tracebacks")
    parser.add_argument("--quiet", action="store_true", default=default, help="no progress bars")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="robocal", description="Fast, honest kinematic calibration of industrial robots.")
    parser.add_argument("--version", action="version", version=f"robocal {__version__}")
    _global_options(parser, False)
    sub = parser.add_subparsers(dest="command", required=True)
    for name, (module_name, help_text, paths) in COMMANDS.items():
        command = sub.add_parser(name, help=help_text, description=help_text)
        importlib.import_module(module_name).add_arguments(command)
        _global_options(command, argparse.SUPPRESS)
        if paths.folders:
            command.add_argument("--force", action="store_true", help="write into an existing, non-empty output folder (its files are overwritten)")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    progress.QUIET = args.quiet
    module_name, _, paths = COMMANDS[args.command]
    try:
        check_outputs(
            inputs=[getattr(args, a, None) for a in paths.inputs],
            files=[getattr(args, a, None) for a in paths.files],
            folders=[getattr(args, a, None) for a in paths.folders],
            force=getattr(args, "force", False),
        )
        return importlib.import_module(module_name).run(args)
    except BrokenPipeError:
        # The reader went away (`robocal ... | head`): stop quietly, as Unix tools do.
        sys.stdout = open(os.devnull, "w")
        return 0
    except (RobocalError, OSError) as exc:
        if args.debug:
            raise
        if isinstance(exc, OSError):  # a file error no reader turned into a RobocalError
            exc = f"{exc.filename}: {exc.strerror or exc}" if exc.filename else (exc.strerror or str(exc))
        print("robocal: error: " + " ".join(str(exc).split()), file=sys.stderr)  # one line, whatever the message holds
        return 2


if __name__ == "__main__":
    sys.exit(main())
