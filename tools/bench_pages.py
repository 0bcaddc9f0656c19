"""mkdocs hook: the benchmark pages' figures, rendered at every build from the records the benches wrote.

A bench run with ``--record benches/records`` writes ``benches/records/<name>.json`` (``benches/record.py``): the
command, the commit and whether its code was dirty, the machine, the load average at the start and the end, the date
and what the bench printed. A page under ``docs/`` holds the hand-written prose (what a benchmark compares, why the
baseline is fair) and, on a line of its own, ``<!-- record: NAME -->`` where a record's figures go; the hook replaces
the line by the record's provenance and its printed tables. A marker without its record, or a record without its
command, commit or machine, fails the build.

Why at build time rather than committed pages checked by a test: the records are the one copy of the figures (a
generated page committed beside them would be a second copy to keep equal), and the other generated pages of the
manual (``tools/mkdocs_reference.py``) are made the same way. The cost: read on GitHub, a page shows the marker, not
the table; the record beside it is plain JSON.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RECORDS = ROOT / "benches" / "records"
MARKER = re.compile(r"^<!-- record: (?P<name>[\w.-]+) -->[ \t]*$", re.MULTILINE)
REQUIRED = ("command", "commit", "machine", "date", "load", "output")
MACHINE = ("cpu", "cores", "python", "numpy", "robocal")
# The records' headings nest under the page's "##" section that holds the marker.
LEVEL = 3


def load(name: str, records: Path = RECORDS) -> dict:
    """The record ``name`` (``records/<name>.json``), checked by :func:`check`."""
    path = records / f"{name}.json"
    if not path.exists():
        raise ValueError(f"no benchmark record {path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}")
    record = json.loads(path.read_text(encoding="utf-8"))
    check(record, name)
    return record


def check(record: dict, name: str) -> None:
    """Refuse a record that does not say how, from which code and on what machine it was measured."""
    missing = [k for k in REQUIRED if not record.get(k) or record[k] == "unknown"]
    if "machine" not in missing:
        missing += [f"machine.{k}" for k in MACHINE if not record["machine"].get(k)]
    if missing:
        raise ValueError(f"benchmark record {name!r} lacks {', '.join(missing)}")


def provenance(record: dict) -> str:
    """The lines that head a record's figures: command, code, machine, load and date."""
    m = record["machine"]
    code = f"commit `{record['commit'][:10]}`"
    if record.get("dirty"):
        code += " **with uncommitted changes to the code**"
    elif record.get("dirty") is None:
        code += " (whether the code differed from it is unknown)"
    env = " ".join(f"{k}={v}" for k, v in sorted(record.get("environment", {}).items()))
    software = ", ".join(f"{label} {m[k]}" for label, k in (("Python", "python"), ("NumPy", "numpy"), ("SciPy", "scipy"), ("robocal", "robocal")) if m.get(k))
    hardware = f"{m['cpu']}, {m['cores']} logical CPUs" + (f", {m['ram_gib']} GiB" if m.get("ram_gib") else "") + (f", {m['os']}" if m.get("os") else "")
    start, end = record["load"]["start"], record["load"]["end"]
    load = f"load average {start[0]:.2f} at the start, {end[0]:.2f} at the end (1 min; the bench's own threads count in it)"
    if start[0] >= 0.5 * m["cores"]:
        load += ": **the machine was busy when the run began; these are not idle timings**"
    lines = [
        f"- **Command**: `{record['command']}`" + (f" (in effect, set by the bench or its caller: `{env}`)" if env else ""),
        f"- **Code**: {code}; run {record['date'][:16].replace('T', ' ')} UTC" + (f", {record['seconds']:.0f} s" if record.get("seconds") else ""),
        f"- **Machine**: {hardware}; {software}",
        f"- **Load**: {load}",
    ]
    if record.get("transcribed"):
        lines.insert(0, f"- **Transcribed, not re-run**: {record['transcribed']}")
    return "\n".join(lines)


def render(record: dict, name: str) -> str:
    """A record as Markdown: its provenance, then what the bench printed, headings moved under the page's section."""
    check(record, name)
    output = record["output"].strip("\n")
    if not record.get("tables"):
        # A bench that prints aligned plain text, not Markdown: kept as printed.
        return f"{provenance(record)}\n\n```text\n{output}\n```\n"
    levels = [len(h) for h in re.findall(r"^(#+) ", output, re.MULTILINE)]
    shift = LEVEL - min(levels) if levels else 0
    output = re.sub(r"^(#+) ", lambda h: "#" * min(6, len(h.group(1)) + shift) + " ", output, flags=re.MULTILINE)
    return f"{provenance(record)}\n\n{output}\n"


def expand(markdown: str, records: Path = RECORDS) -> str:
    """``markdown`` with every ``<!-- record: NAME -->`` line replaced by the rendered record."""
    return MARKER.sub(lambda m: render(load(m["name"], records), m["name"]), markdown)


def on_page_markdown(markdown, page, config, files):
    from mkdocs.exceptions import PluginError

    try:
        return expand(markdown)
    except ValueError as error:
        raise PluginError(f"{page.file.src_path}: {error}") from error
