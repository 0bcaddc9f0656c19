"""Progress for long work, on stderr: tqdm bars on a terminal; elsewhere (a pipe, a log file, a
CI job) one line per stage with its elapsed time, so that a run of minutes is not silent. The
command line's ``--quiet`` silences both; called from Python, only the bars are shown."""

from __future__ import annotations

import sys
import time
from contextlib import contextmanager

#: Set by ``robocal --quiet``.
QUIET = False
#: Set by the command line for its run (unless ``--quiet``): stage lines where no bar is drawn.
STAGE_LINES = False


def progress(iterable=None, **options):
    """``tqdm(iterable, **options)``, disabled when :data:`QUIET` or not on a terminal; there, with
    :data:`STAGE_LINES`, the stage ends with the line ``robocal: DESC: N UNITs in T s``."""
    from tqdm import tqdm  # on first use: the CLI imports this module before it knows the command

    bar = tqdm(iterable, disable=True if QUIET else None, leave=False, **options)
    if bar.disable and STAGE_LINES and not QUIET:
        return _stage_line(bar, options.get("desc", "working"), options.get("unit", "item"))
    return bar


def _stage_line(items, desc: str, unit: str):
    start, n = time.perf_counter(), 0
    for n, item in enumerate(items, start=1):
        yield item
    _line(f"{desc}: {n} {unit}{'' if n == 1 else 's'}", start)


@contextmanager
def stage(desc: str):
    """A stage of work that is not one loop (or leaves its loop early): where :func:`progress`
    prints stage lines, it ends with ``robocal: DESC in T s`` when it completes."""
    start = time.perf_counter()
    yield
    if STAGE_LINES and not QUIET and not sys.stderr.isatty():
        _line(desc, start)


def _line(what: str, start: float) -> None:
    print(f"robocal: {what} in {time.perf_counter() - start:.1f} s", file=sys.stderr, flush=True)
