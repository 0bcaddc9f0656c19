"""``--record PATH``: a bench's run as a JSON record, the source of the benchmark pages of the manual.

A bench opens ``with recording(args.record):`` around its work; everything it prints is also kept, and at the end the
record is written: the exact command line, the git commit (and whether the tree was dirty), the machine
(:func:`machine.describe`), the load average at the start and the end, the date, the wall time, the printed Markdown
(``output``) and its tables parsed into columns and rows (``tables``). ``tools/bench_pages.py`` renders the records
into the pages at every build of the manual. PATH is a ``.json`` file, or a folder that gets ``<script>.json``.
"""

from __future__ import annotations

import contextlib
import datetime
import io
import json
import os
import re
import shlex
import sys
import time
from pathlib import Path

from machine import ROOT, describe, git_state, load_averages

# Variables that change what a bench measures; recorded when set.
ENVIRONMENT = ("RAYON_NUM_THREADS", "ROBOCAL_THREADS", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_CORETYPE")


def add_argument(parser) -> None:
    parser.add_argument("--record", metavar="PATH", help="also write the run as a JSON record (a .json file, or a folder: <script>.json)")


def parse_tables(markdown: str) -> list[dict]:
    """The Markdown tables of ``markdown``: each with the nearest heading above it, its columns and its rows."""
    tables, heading, lines = [], None, markdown.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i].strip()
        if line.startswith("#"):
            heading = line.lstrip("#").strip()
        if line.startswith("|") and i + 1 < len(lines) and re.fullmatch(r"\|(\s*:?-+:?\s*\|)+", lines[i + 1].strip()):
            rows = []
            j = i + 2
            while j < len(lines) and lines[j].strip().startswith("|"):
                rows.append(_cells(lines[j]))
                j += 1
            tables.append({"heading": heading, "columns": _cells(line), "rows": rows})
            i = j
            continue
        i += 1
    return tables


def _cells(line: str) -> list[str]:
    # Split on bars that are not escaped (a cell may show a literal \|).
    return [c.strip() for c in re.split(r"(?<!\\)\|", line.strip())[1:-1]]


class _Tee(io.TextIOBase):
    def __init__(self, stream):
        self.stream, self.kept = stream, io.StringIO()

    def write(self, text):
        self.kept.write(text)
        return self.stream.write(text)

    def flush(self):
        self.stream.flush()


@contextlib.contextmanager
def recording(path: str | None, argv: list[str] | None = None):
    """Keep what the block prints and write it, with its provenance, to ``path`` (nothing when ``path`` is None)."""
    if path is None:
        yield
        return
    argv = sys.argv if argv is None else argv
    script = Path(argv[0]).resolve()
    start, load_start, date = time.perf_counter(), load_averages(), datetime.datetime.now(datetime.timezone.utc)
    code = git_state()  # the code as it was when the bench started
    tee = _Tee(sys.stdout)
    with contextlib.redirect_stdout(tee):
        yield
    output = tee.kept.getvalue()
    record = {
        # The command as run from the repository root, without the --record option (it changes nothing measured).
        "command": shlex.join(["python", str(script.relative_to(ROOT)) if script.is_relative_to(ROOT) else str(script), *_without_record(argv[1:])]),
        "environment": {k: os.environ[k] for k in ENVIRONMENT if k in os.environ},
        **code,
        "date": date.isoformat(timespec="seconds"),
        "seconds": round(time.perf_counter() - start, 1),
        "load": {"start": load_start, "end": load_averages()},
        "machine": describe(),
        "output": output,
        "tables": parse_tables(output),
    }
    target = Path(path)
    if target.suffix != ".json":
        target = target / f"{script.stem}.json"
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(json.dumps(record, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
    print(f"record written to {target}", file=sys.stderr)


def _without_record(args: list[str]) -> list[str]:
    out, skip = [], False
    for a in args:
        if skip:
            skip = False
        elif a == "--record":
            skip = True
        elif not a.startswith("--record="):
            out.append(a)
    return out
