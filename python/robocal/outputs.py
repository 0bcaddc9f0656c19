"""Writing outputs without ever destroying an input.

Every file robocal writes goes through :class:`Staged`: the content is written to a temporary
file in the target folder and renamed over the target only when it is complete (and, where the
caller validates it, valid), so an interrupted or failed write never leaves a truncated file and
never replaces a good one. :func:`check_outputs` runs before any work: it refuses an output that
is one of the inputs, an output file whose folder is missing or unwritable, and an existing,
non-empty output folder unless the user passed ``--force``. Every problem is an
:class:`~robocal.exceptions.OutputError` naming the path.
"""

from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path
from typing import Iterable, Optional

from .exceptions import OutputError


def same_file(a, b) -> bool:
    """Whether paths ``a`` and ``b`` name the same file (hard links and symlinks included)."""
    try:
        return os.path.samefile(a, b)
    except OSError:  # one does not exist (yet): compare where they would be
        return Path(a).resolve() == Path(b).resolve()


def _flat(paths: Iterable) -> list:
    """``paths`` with nested lists (an option given several values) flattened."""
    return [q for p in paths for q in (_flat(p) if isinstance(p, (list, tuple)) else [p])]


def _existing(paths: Iterable) -> list[Path]:
    """The paths among ``paths`` that name something on disk (a built-in robot name does not)."""
    return [Path(p) for p in _flat(paths) if p not in (None, "", "-") and os.path.exists(p)]


def _writable_folder(folder: Path, what) -> None:
    if not folder.is_dir():
        raise OutputError(f"{what}: the folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputError(f"{what}: the folder {folder} is not writable")


def check_outputs(inputs: Iterable = (), files: Iterable = (), folders: Iterable = (), force: bool = False) -> None:
    """Refuses outputs that would destroy an input or cannot be written, before any work.

    Parameters
    ----------
    inputs : iterable of path
        Files read by the command (names that are not paths, such as a built-in robot, are skipped).
    files : iterable of path
        Output files (``None`` and ``"-"``, standard output, are skipped).
    folders : iterable of path
        Output folders, created if missing.
    force : bool
        Allow writing into an existing, non-empty output folder.

    Raises
    ------
    OutputError
        Naming the output and what is wrong with it.
    """
    files, folders = list(files), list(folders)
    for p in [*_flat(inputs), *files, *folders]:
        if p is not None and "\x00" in str(p):
            raise OutputError(f"{str(p)!r}: a path cannot contain a NUL character")
    sources = _existing(inputs)
    files = [Path(f) for f in files if f not in (None, "", "-")]
    for i, out in enumerate(files):
        clash = next((s for s in sources if same_file(out, s)), None)
        if clash is not None:
            raise OutputError(f"{out}: this output is the input {clash}; writing it would destroy the input, choose another path")
        other = next((o for o in files[:i] if same_file(out, o)), None)
        if other is not None:
            raise OutputError(f"{out}: the same file is given for two outputs")
        if out.is_dir():
            raise OutputError(f"{out}: is a folder; a file path is expected")
        _writable_folder(out.resolve().parent, out)
    for folder in (Path(f) for f in folders if f not in (None, "")):
        if folder.exists() and not folder.is_dir():
            raise OutputError(f"{folder}: exists and is not a folder")
        if folder.is_dir():
            if any(folder.iterdir()) and not force:
                raise OutputError(f"{folder}: the output folder exists and is not empty; pass --force to overwrite the files in it")
            inside = next((s for s in sources if same_file(s.resolve().parent, folder)), None)
            if inside is not None:
                raise OutputError(f"{folder}: the output folder holds the input {inside}; choose another folder")
            _writable_folder(folder, folder)
        else:
            ancestor = next(p for p in folder.resolve().parents if p.exists())
            _writable_folder(ancestor, folder)


def make_folder(folder) -> Path:
    """``folder`` created (with its parents) if needed, or an :class:`OutputError` naming it."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{folder}: cannot create the folder ({exc.strerror or exc})") from None
    return folder


def _umask() -> int:
    mask = os.umask(0)  # the only way to read it is to set it
    os.umask(mask)
    return mask


class Staged:
    """A temporary file beside ``path`` that replaces ``path`` when the ``with`` block ends
    without an exception and :meth:`discard` was not called.

    Examples
    --------
    >>> with Staged("out.csv") as stage:          # doctest: +SKIP
    ...     stage.tmp.write_text("a,b\\n1,2\\n")
    ...     if not valid(stage.tmp):
    ...         stage.discard()                    # out.csv is left as it was
    """

    def __init__(self, path):
        self.path = Path(path)
        self.tmp: Optional[Path] = None
        self._keep = True

    def __enter__(self) -> "Staged":
        try:
            # Same folder: the final rename stays on one file system, hence atomic. Same suffix:
            # writers that choose the format by suffix (matplotlib, the export tables) still can.
            fd, name = tempfile.mkstemp(dir=self.path.resolve().parent, prefix=f".{self.path.name}.", suffix=f".tmp{self.path.suffix}")
        except OSError as exc:
            raise OutputError(f"{self.path}: cannot write it ({exc.strerror or exc})") from None
        os.close(fd)
        self.tmp = Path(name)
        # mkstemp creates the file readable by its owner only; an output gets the mode a plain
        # open() would give it (the existing file's, else 0o666 less the umask).
        os.chmod(self.tmp, self.path.stat().st_mode & 0o7777 if self.path.is_file() else 0o666 & ~_umask())
        return self

    def discard(self) -> None:
        self._keep = False

    def __exit__(self, kind, exc, tb) -> bool:
        try:
            if kind is None and self._keep:
                os.replace(self.tmp, self.path)
                return False
        except OSError as error:
            exc, kind = error, OSError
        if self.tmp.exists():
            self.tmp.unlink()
        if kind is not None and issubclass(kind, OSError):  # e.g. a full disk while writing
            raise OutputError(f"{self.path}: cannot write it ({exc.strerror or exc})") from None
        return False


def write_text(path, text: str) -> Path:
    """Writes ``text`` (UTF-8) to ``path`` through a :class:`Staged` file; returns the path."""
    with Staged(path) as stage:
        stage.tmp.write_text(text, encoding="utf-8")
    return stage.path


def write_json(path, document, **options) -> Path:
    """Writes ``document`` as indented JSON (``indent=2`` unless given) through :func:`write_text`."""
    return write_text(path, json.dumps(document, **{"indent": 2, **options}) + "\n")


def save_figure(fig, path, **options) -> Path:
    """``fig.savefig(path, **options)`` through a :class:`Staged` file; returns the path."""
    path = Path(path)
    with Staged(path) as stage:
        fig.savefig(stage.tmp, format=path.suffix.lstrip(".") or "png", **options)
    return path
