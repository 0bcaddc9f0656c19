"""Progress bars for long work (tqdm, on stderr): shown on a terminal, silent with the CLI's
``--quiet`` or when stderr is not a terminal (a pipe, a log file, a test)."""

from __future__ import annotations

#: Set by ``robocal --quiet``.
QUIET = False


def progress(iterable=None, **options):
    """``tqdm(iterable, **options)``, disabled when :data:`QUIET` or not on a terminal."""
    from tqdm import tqdm  # on first use: the CLI imports this module before it knows the command

    return tqdm(iterable, disable=True if QUIET else None, leave=False, **options)
