"""The ``robocal`` command line: one subcommand per module ``robocal.cli.NAME``, each providing
``add_arguments(parser)`` and ``run(args) -> exit code``.

Only the module of the subcommand that runs is imported (with it NumPy's and SciPy's share of the
package): the top-level parser is built from :data:`COMMANDS` alone, so that ``robocal --version``
and ``robocal --help`` start fast.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import re
import sys
from dataclasses import dataclass

from .. import __version__, progress
from ..exceptions import RobocalError
from ..outputs import PrintableStream, check_outputs, printable
from ..results import recorded_data_files


@dataclass(frozen=True)
class Paths:
    """Which arguments of a subcommand name files it reads, files it writes and folders it
    writes into: :func:`robocal.outputs.check_outputs` refuses a clash before any work."""

    inputs: tuple = ()
    files: tuple = ()
    folders: tuple = ()


#: subcommand -> (help, paths); its arguments and its work are in ``robocal.cli.<subcommand>``.
COMMANDS = {
    "demo": ("run the core on a built-in simulated robot (no files needed)", Paths(folders=("out",))),
    "inspect": ("validate a measurement file (canonical CSV or a public dataset)", Paths(("path", "robot"), ("json",))),
    "calibrate": (
        "identify a robot's kinematic parameters from measurements (with --prior RESULT: which joints' zeros moved since)",
        Paths(("data", "robot", "causes", "prior"), ("out",)),
    ),
    "simulate": ("simulate measurements of a robot with known truth and injectable effects", Paths(("robot",), ("out", "truth"))),
    "compare": ("run the paper's comparison of calibrators and write its tables and figures", Paths(("data", "robot"), (), ("out",))),
    "diagnose": ("show what the geometric model gets wrong, name the cause, measure the held-out gain", Paths(("data", "robot"), ("json",), ("out",))),
    "verify": ("evaluate a calibration result on new measurements, re-fitting only the session set-up", Paths(("result", "data"), ("json",))),
    "compensate": ("joint commands that make the calibrated robot reach desired tool positions", Paths(("result", "targets"), ("out",))),
    "report": ("an HTML page with figures of a calibration result (and its diagnosis)", Paths(("result", "data", "diagnosis"), (), ("out",))),
    "export": ("write a calibrated robot as a DH / MDH table (CSV, JSON), URDF or UR kinematics YAML, checked by a round trip", Paths(("result",), ("out",))),
    "monitor": (
        "watch a calibrated robot sample by sample: what changed since the calibration, when, how much",
        Paths(("result", "data"), ("json_lines", "out")),
    ),
    "plan": ("the poses to measure next, and their order, that determine the model's parameters best", Paths(("robot", "source", "data"), ("out", "json"))),
}


def command_module(name: str):
    """The module of subcommand ``name`` (imported now)."""
    return importlib.import_module(f"{__name__}.{name}")


def _global_options(parser: argparse.ArgumentParser, default) -> None:
    # Added to the main parser and to every subparser so that they work on either side of the
    # subcommand; the subparsers' default SUPPRESS keeps a value given before it.
    parser.add_argument("--debug", action="store_true", default=default, help="show tracebacks and the diagnostic log")
    parser.add_argument("--quiet", action="store_true", default=default, help="no progress bars and no warnings")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser; only subcommand ``command`` gets its arguments (the others are listed with
    their help and are never parsed in the same run)."""
    parser = argparse.ArgumentParser(prog="robocal", description="Fast, honest kinematic calibration of industrial robots.")
    parser.add_argument("--version", action="version", version=f"robocal {__version__}")
    _global_options(parser, False)
    sub = parser.add_subparsers(dest="command", required=True)
    for name, (help_text, paths) in COMMANDS.items():
        parser_of = sub.add_parser(name, help=help_text, description=help_text)
        if name == command:
            command_module(name).add_arguments(parser_of)
            parser.command_parser = parser_of  # its options name the library's arguments in errors (cli_words)
        _global_options(parser_of, argparse.SUPPRESS)
        if paths.folders:
            parser_of.add_argument("--force", action="store_true", help="write into an existing, non-empty output folder (its files are overwritten)")
    return parser


def cli_words(message: str, parser: argparse.ArgumentParser, aliases: dict) -> str:
    """``message`` of the library in the command line's words: an argument it names in backticks
    (`` `candidates` ``, `` `joint_ranges` ``) becomes the option that sets it (``--candidates``,
    ``--joint-range``): the option's destination, or ``aliases`` (library argument -> option,
    the command module's ``API_WORDS``) where the two differ. Other names are left as they are."""
    options = {a.dest: max(a.option_strings, key=len) for a in parser._actions if a.option_strings}
    options.update(aliases)

    def option(match: re.Match) -> str:
        return f"`{options[match[1]]}`" if match[1] in options else match[0]

    return re.sub(r"`([A-Za-z_]\w*)`", option, message)


#: Formats of the diagnostic log on stderr: one line per message, the module's name with --debug.
LOG_FORMAT = "robocal: %(levelname)s: %(message)s"
DEBUG_LOG_FORMAT = "robocal: %(levelname)s: %(name)s: %(message)s"


class _Log:
    """The package's logger (``logging.getLogger("robocal")``) for one run of the command line:
    warnings on stderr by default, nothing below errors with ``--quiet``, every message (debug
    included) with ``--debug``; its earlier state is restored at the end of the run, so that
    :func:`main` called from Python leaves the caller's logging as it was."""

    def __init__(self, quiet: bool, debug: bool):
        self.logger = logging.getLogger("robocal")
        self.saved = (self.logger.level, self.logger.propagate)
        self.handler = logging.StreamHandler(sys.stderr)
        self.handler.setFormatter(logging.Formatter(DEBUG_LOG_FORMAT if debug else LOG_FORMAT))
        self.logger.addHandler(self.handler)
        self.logger.setLevel(logging.DEBUG if debug else logging.ERROR if quiet else logging.WARNING)
        self.logger.propagate = False

    def close(self) -> None:
        self.logger.removeHandler(self.handler)
        self.logger.setLevel(self.saved[0])
        self.logger.propagate = self.saved[1]


def main(argv: list[str] | None = None) -> int:
    """Runs the command line ``argv`` (default ``sys.argv[1:]``); returns the exit code: 0, 1 (a
    check failed, a target unreachable, every run of ``compare`` failed), 2 (refused: one line
    ``robocal: error: ...``), 130 (interrupted)."""
    argv = sys.argv[1:] if argv is None else [str(a) for a in argv]
    try:
        return _run(argv)
    except KeyboardInterrupt:
        # Ctrl-C, even while the subcommand's modules load: staged outputs are discarded on the
        # way out (no temporary left, no file replaced), so one line and the shell's code for
        # SIGINT (128 + 2) say it all.
        if "--debug" in argv:
            raise
        print("robocal: interrupted", file=sys.stderr)
        return 130


def _run(argv: list[str]) -> int:
    # The options before the subcommand are flags without values: the first word that is not an
    # option names it.
    command = next((a for a in argv if not a.startswith("-")), None)
    parser = build_parser(command)
    args = parser.parse_args(argv)
    progress.QUIET = args.quiet
    progress.STAGE_LINES = not args.quiet  # reset below: robocal called from Python draws only bars
    log = _Log(args.quiet, args.debug)
    paths = COMMANDS[args.command][1]
    claims = []
    stdout = sys.stdout
    sys.stdout = PrintableStream(stdout)  # names and columns from files may hold terminal escapes
    try:
        inputs = [getattr(args, a, None) for a in paths.inputs]
        files = [getattr(args, a, None) for a in paths.files]
        claims = check_outputs(
            inputs=inputs,
            # a result's training data, read from it only when a file is written (the command reads the result again)
            recorded=recorded_data_files(inputs) if any(f not in (None, "", "-") for f in files) else {},
            files=files,
            folders=[getattr(args, a, None) for a in paths.folders],
            force=getattr(args, "force", False),
        )
        return command_module(args.command).run(args)
    except BrokenPipeError:
        # The reader went away (`robocal ... | head`): stop quietly, as Unix tools do.
        stdout = open(os.devnull, "w")  # noqa: SIM115 (stays open: the interpreter flushes stdout at exit)
        return 0
    except (RobocalError, OSError) as exc:
        if args.debug:
            raise
        if isinstance(exc, OSError):  # a file error no reader turned into a RobocalError
            message = f"{exc.filename}: {exc.strerror or exc}" if exc.filename else (exc.strerror or str(exc))
        else:  # the library names its arguments; the user typed options
            message = cli_words(str(exc), parser.command_parser, getattr(command_module(args.command), "API_WORDS", {}))
        # one line, whatever the message holds (a name from a file may hold terminal escapes)
        print("robocal: error: " + printable(" ".join(message.split()), one_line=True), file=sys.stderr)
        return 2
    finally:
        progress.STAGE_LINES = False
        log.close()
        for claim in claims:
            claim.release()
        if isinstance(sys.stdout, PrintableStream):  # a command may have replaced it
            sys.stdout = stdout
