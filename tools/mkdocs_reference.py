"""mkdocs hook: the reference pages that are generated from the code at every build, never copied by hand.

- ``reference/cli.md``: every subcommand from its argparse parser (``robocal.cli.build_parser``), so an option
  added, renamed or re-described in the code is what the manual shows.
- ``reference/api.md``: every public name of ``robocal.__all__``, through mkdocstrings from its docstring (the package
  exports most names lazily, which a static reader of ``robocal/__init__.py`` cannot follow: the hook resolves them).
- ``reference/schemas.md``: the JSON Schema of the robot, result and diagnose documents from their pydantic models
  (``model_json_schema()`` of :class:`robocal.schemas.RobotSpec`, :class:`robocal.schemas.ResultSpec` and
  :class:`robocal.diagnosis_file.DiagnosisReport`), the models the readers validate with.

It also refuses a public name without a docstring (``robocal.__all__``): the API reference is rendered from the
docstrings, and a name without one would be an empty entry. The pages are added to the build in memory
(``File.generated``); nothing is written into ``docs/``.
"""

from __future__ import annotations

import argparse
import html
import inspect
import json
import os

from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File


def _cell(text: str) -> str:
    # A table cell: one line, the Markdown table's bar and HTML escaped, code-like words kept readable.
    text = html.escape(" ".join(str(text).split()), quote=False)
    # A bar would end the cell; brackets would read as a Markdown link (or an autorefs cross-reference).
    return text.replace("|", "\\|").replace("[", "\\[").replace("]", "\\]")


def _argument_rows(parser: argparse.ArgumentParser) -> list[str]:
    formatter = parser._get_formatter()
    rows = ["| argument | meaning |", "|---|---|"]
    for action in parser._actions:
        if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
            continue  # help is on every command; the subcommands have a table of their own
        if action.option_strings:
            name = ", ".join(action.option_strings)
            if action.nargs != 0:
                name += " " + formatter._format_args(action, formatter._get_default_metavar_for_optional(action))
        else:
            name = formatter._format_args(action, formatter._get_default_metavar_for_positional(action))
        meaning = formatter._expand_help(action) if action.help else ""
        rows.append(f"| `{_cell(name)}` | {_cell(meaning)} |")
    return rows


def cli_page() -> str:
    from robocal.cli import COMMANDS, build_parser

    os.environ["COLUMNS"] = "100"  # argparse wraps usage lines to the terminal; the page has one width
    main = build_parser()
    lines = [
        "# Command line",
        "",
        "Generated from the argparse parsers of `robocal.cli` at every build of this manual: what `robocal COMMAND --help` prints.",
        "",
        "Exit codes: 0 success; 1 the job ran but not everything succeeded (a target unreachable, an export round trip beyond",
        "tolerance, every run of `compare` failed); 2 bad use, with one line `robocal: error: ...` on stderr naming the file,",
        "row, column or option ([what is refused, and why](../explanation/robustness.md)); 130 interrupted (Ctrl-C: nothing",
        "half-written is left). `--debug` shows the traceback and the diagnostic log (from Python the same messages go to",
        "the `robocal` logger of the standard `logging` module); `--quiet` drops progress bars and warnings (where stderr is",
        "not a terminal a long stage ends with one line instead of a bar). `python -m robocal` is the same command. The",
        "environment variable `ROBOCAL_THREADS=N` caps the threads `diagnose` spreads its fold fits over (default: every core",
        "the process may use).",
        "",
        "```text",
        main.format_usage().strip(),
        "```",
        "",
        *_argument_rows(main),
        "",
        "| command | what it does |",
        "|---|---|",
        *(f"| [`{name}`](#robocal-{name}) | {_cell(help_text)} |" for name, (help_text, _) in COMMANDS.items()),
    ]
    for name in COMMANDS:
        parser = build_parser(name).command_parser
        lines += [
            "",
            f"## robocal {name} {{ #robocal-{name} }}",
            "",
            _cell(parser.description),
            "",
            "```text",
            parser.format_usage().strip(),
            "```",
            "",
            *_argument_rows(parser),
        ]
        if parser.epilog:
            lines += ["", _cell(parser.epilog)]
    return "\n".join(lines) + "\n"


def schemas_page() -> str:
    from robocal.diagnosis_file import DiagnosisReport
    from robocal.schemas import ResultSpec, RobotSpec

    documents = [
        ("Robot file", RobotSpec, "A robot file (`robocal.robot/1`, JSON or YAML; `robocal.write_robot` writes one)."),
        ("Result file", ResultSpec, "What `robocal calibrate --out` writes (`robocal.result/1`): the keys robocal reads back; others are kept."),
        ("Diagnose report", DiagnosisReport, "What `robocal diagnose --json` writes and `calibrate --causes`, `plan --from` and `report --diagnosis` read."),
    ]
    lines = [
        "# JSON schemas",
        "",
        "Generated at every build from the pydantic models robocal validates these documents with (`model_json_schema()`).",
        "The models are strict: a value of the wrong type is refused, never coerced. Robot files also refuse unknown keys;",
        "result files and diagnose reports keep keys they do not read. Field meanings and units: [File formats](../data-format.md).",
    ]
    for title, model, what in documents:
        lines += [
            "",
            f"## {title}",
            "",
            what,
            f"Model: `{model.__module__}.{model.__name__}`.",
            "",
            "```json",
            json.dumps(model.model_json_schema(), indent=2),
            "```",
        ]
    return "\n".join(lines) + "\n"


def api_page() -> str:
    import robocal

    lines = [
        "# Python API",
        "",
        "The public names of the `robocal` package (`robocal.__all__`), rendered from their docstrings at every build; each",
        "heading is the name as you use it (`robocal.calibrate`), the line under it where it is defined. Everything else is",
        "reachable but internal: its place in the package may change between versions.",
        "",
        f"`robocal.__version__`: the version, `{robocal.__version__}` for this manual.",
    ]
    for name in sorted((n for n in robocal.__all__ if not n.startswith("__")), key=lambda n: (not inspect.ismodule(getattr(robocal, n)), n.lower())):
        obj = getattr(robocal, name)
        if inspect.ismodule(obj):
            path = obj.__name__
        elif inspect.isclass(obj) or inspect.isroutine(obj):
            path = f"{obj.__module__}.{obj.__qualname__}"
        else:  # a constant: its value says it all
            lines += ["", f"## robocal.{name}", "", f"`{obj!r}`"]
            continue
        lines += ["", f"## robocal.{name}", "", f"Defined as `{path}`.", "", f"::: {path}", "    options:", "      show_root_heading: false"]
    return "\n".join(lines) + "\n"


def check_docstrings() -> None:
    import robocal

    missing = [name for name in robocal.__all__ if not name.startswith("__") and not inspect.getdoc(getattr(robocal, name))]
    if missing:
        raise PluginError(f"public names without a docstring (robocal.__all__): {', '.join(missing)}")


def on_files(files, config):
    check_docstrings()
    for path, text in (("reference/cli.md", cli_page()), ("reference/api.md", api_page()), ("reference/schemas.md", schemas_page())):
        files.append(File.generated(config, path, content=text))
    return files
