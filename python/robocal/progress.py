"""Progress bars for long work (tqdm, on stderr): shown on a terminal, silent with the CLI's
``--quiet`` or when stderr is not a terminal (a pipe, a log file, a test)."""

from __future__ import annotations

from tqdm import tqdm

#: Set by ``robocal --quiet``.
QUIET = False


def progress(iterable=None, **options):
    """``tqdm(iterable, **options)``, disabled when :data:`QUIET` or not on a terminal."""
    return tqdm(iterable, disable=True if QUIET else None, leave=False, **options)
