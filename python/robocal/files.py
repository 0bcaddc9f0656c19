"""Reading an input file without hanging or filling the memory: only a regular file, and only up
to a size.

A FIFO, ``/dev/zero`` or a terminal given where a file is expected would block the reader (a
FIFO waits for a writer) or never end. :func:`open_regular` opens the path without blocking and
judges what was opened by ``fstat``, so a file swapped after a check cannot slip through;
:func:`read_regular` reads at most ``limit`` bytes even if the file grows while it is read. Both
report a problem through the caller's ``error`` (a function of the problem's text that returns the
exception to raise), so each layer raises its own error type: a data file a
:class:`~robocal.exceptions.DataError`, a robot, result or diagnose report an
:class:`~robocal.exceptions.InvalidParameterError`. This module imports nothing from robocal: it
sits below every other layer (pyproject.toml, ``[tool.importlinter]``).
"""

from __future__ import annotations

import logging
import os
import stat
from typing import BinaryIO, Callable

logger = logging.getLogger(__name__)

#: Largest input file read (bytes): a million pose samples, the most ``simulate`` writes, take
#: about 260 MB; a larger file is refused before it is read instead of filling the memory.
MAX_FILE_BYTES = 1 << 30

#: Builds the exception to raise from a problem's text (the caller adds the path and its wording).
ErrorFactory = Callable[[str], Exception]


def file_kind(mode: int) -> str:
    """The kind of file an ``st_mode`` describes, as a phrase for a message."""
    kinds = [
        (stat.S_ISREG, "a regular file"),
        (stat.S_ISDIR, "a folder"),
        (stat.S_ISFIFO, "a FIFO (named pipe)"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
        (stat.S_ISLNK, "a symbolic link"),
    ]
    return next((phrase for test, phrase in kinds if test(mode)), "not a regular file")


def open_regular(path, error: ErrorFactory, *, limit: int | None = None, what: str = "file") -> BinaryIO:
    """``path`` opened for reading in binary mode, once it is known to be a regular file of at
    most ``limit`` bytes (default :data:`MAX_FILE_BYTES`); else ``error(problem)`` is raised.

    The problem reads "cannot read the {what} (...)" (``what``: "file", "robot file", ...), "is a
    FIFO (named pipe), not a regular file; ..." or "the file has N bytes; robocal reads files up to
    L bytes"; a path holding a NUL character is refused by name (the operating system cannot take it).
    """
    if "\x00" in str(path):
        raise error("a path cannot contain a NUL character")
    limit = MAX_FILE_BYTES if limit is None else limit
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as exc:
        raise error(f"cannot read the {what} ({exc.strerror or exc})") from None
    info = os.fstat(fd)
    problem = None
    if not stat.S_ISREG(info.st_mode):
        problem = f"is {file_kind(info.st_mode)}, not a regular file; robocal reads only regular files"
    elif info.st_size > limit:
        problem = f"the file has {info.st_size:,} bytes; robocal reads files up to {limit:,} bytes"
    if problem is not None:
        os.close(fd)
        raise error(problem)
    return os.fdopen(fd, "rb")


def read_regular(path, error: ErrorFactory, *, limit: int | None = None, what: str = "file") -> bytes:
    """The bytes of ``path`` (see :func:`open_regular`), at most ``limit`` even if the file grows
    while being read; else ``error(problem)`` is raised."""
    limit = MAX_FILE_BYTES if limit is None else limit
    with open_regular(path, error, limit=limit, what=what) as f:
        try:  # the size it has (read(n) allocates n bytes), then what it may have grown by, bounded
            chunks = [f.read(os.fstat(f.fileno()).st_size + 1)]
            size = len(chunks[0])
            while chunks[-1] and size <= limit:
                chunks.append(f.read(1 << 20))
                size += len(chunks[-1])
        except OSError as exc:
            raise error(f"cannot read the {what} ({exc.strerror or exc})") from None
    if size > limit:
        raise error(f"the file grew beyond {limit:,} bytes while it was read")
    return b"".join(chunks)
