"""Writing outputs without ever destroying an input.

Every file robocal writes goes through :class:`Staged`: the content is written to a temporary
file in the target folder and renamed over the target only when it is complete (and, where the
caller validates it, valid), so an interrupted or failed write never leaves a truncated file and
never replaces a good one. :func:`check_outputs` runs before any work: it refuses an output that
is one of the inputs, an output file whose folder is missing or unwritable, an output that exists
and is not a regular file (a device, a FIFO, a symbolic link: a rename would replace the node
itself), and an existing, non-empty output folder unless the user passed ``--force``. It claims
every output folder with a lock file, so that two runs cannot both find the same folder empty.
Every problem is an :class:`~robocal.exceptions.OutputError` naming the path.

What goes to the terminal is text from files too (a robot's name, a column name): :func:`printable`
escapes the characters a terminal acts on instead of showing them.
"""

from __future__ import annotations

import json
import os
import re
import stat
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterable, Optional

from .exceptions import OutputError
from .files import file_kind


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


def special_kind(path) -> str | None:
    """What ``path`` is when it exists and is not a regular file ("a FIFO (named pipe)", "a
    symbolic link to ...", ...), else None. A symbolic link is not followed: renaming over it
    would replace the link, and writing through it could reach anything."""
    try:
        mode = os.lstat(path).st_mode
    except (OSError, ValueError):  # missing (or a NUL in the name, refused by the callers)
        return None
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISLNK(mode):
        target = os.readlink(path)
        return f"a symbolic link to {target}" + ("" if os.path.exists(path) else " (which does not exist)")
    return file_kind(mode)


def refuse_special(path) -> None:
    """An :class:`OutputError` when ``path`` exists and is not a regular file."""
    kind = special_kind(path)
    if kind is not None:
        raise OutputError(f"{path}: is {kind}, not a regular file; robocal writes only regular files (it would replace this one), choose another path")


#: Suffixes of the files robocal writes: a new output folder so named is a file name given in the
#: wrong place (`diagnose --out report.json` made a folder called report.json).
FILE_SUFFIXES = (".json", ".jsonl", ".csv", ".html", ".htm", ".png", ".svg", ".pdf", ".urdf", ".yaml", ".yml", ".txt", ".xlsx", ".md")


def _writable_folder(folder: Path, what) -> None:
    if not folder.is_dir():
        raise OutputError(f"{what}: the folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputError(f"{what}: the folder {folder} is not writable")


def check_outputs(inputs: Iterable = (), files: Iterable = (), folders: Iterable = (), force: bool = False, recorded: dict = None) -> list[FolderClaim]:
    """Refuses outputs that would destroy an input or cannot be written, before any work, and
    claims the output folders.

    Parameters
    ----------
    inputs : iterable of path
        Files read by the command (names that are not paths, such as a built-in robot, are skipped).
    recorded : dict, optional
        Data files an input depends on (a result's training data: its path -> the result's),
        not to be replaced either.
    files : iterable of path
        Output files (``None`` and ``"-"``, standard output, are skipped).
    folders : iterable of path
        Output folders, created if missing.
    force : bool
        Allow writing into an existing, non-empty output folder.

    Returns
    -------
    list of FolderClaim
        One per output folder (created if missing): call :meth:`FolderClaim.release` when the
        work is done, whatever its outcome.

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
    folders = [Path(f) for f in folders if f not in (None, "")]
    for i, out in enumerate(files):
        clash = next((s for s in sources if same_file(out, s)), None)
        if clash is not None:
            raise OutputError(f"{out}: this output is the input {clash}; writing it would destroy the input, choose another path")
        owner = next((o for d, o in (recorded or {}).items() if same_file(out, d)), None)
        if owner is not None:
            raise OutputError(f"{out}: this output is the training data of {owner}; writing it would destroy them, choose another path")
        other = next((o for o in files[:i] if same_file(out, o)), None)
        if other is not None:
            raise OutputError(f"{out}: the same file is given for two outputs")
        # Before the folder is created below: afterwards the file would find a folder in its place,
        # and only at the end of the work (`diagnose --json X --out X`).
        if any(same_file(out, folder) for folder in folders):
            raise OutputError(f"{out}: the same path is given as an output file and as an output folder")
        if out.is_dir():
            raise OutputError(f"{out}: is a folder; a file path is expected")
        refuse_special(out)
        _writable_folder(out.resolve().parent, out)
    for folder in folders:
        if os.path.lexists(folder) and not folder.exists():
            raise OutputError(f"{folder}: is {special_kind(folder)}; an output folder is expected")
        if folder.exists() and not folder.is_dir():
            raise OutputError(f"{folder}: exists and is not a folder")
        if folder.is_dir():
            inside = next((s for s in sources if same_file(s.resolve().parent, folder)), None)
            if inside is not None and force:
                raise OutputError(f"{folder}: the output folder holds the input {inside}; choose another folder")
            _writable_folder(folder, folder)
        else:
            if folder.suffix.lower() in FILE_SUFFIXES:
                raise OutputError(
                    f"{folder}: an output folder is expected here (it would hold several files), and this name ends like one file "
                    f"({folder.suffix}); name the folder without it, or give the command's option for that file"
                )
            ancestor = next(p for p in folder.resolve().parents if p.exists())
            _writable_folder(ancestor, folder)
    claims: list[FolderClaim] = []
    try:  # claimed last: a refusal above leaves nothing behind
        for folder in folders:
            claims.append(FolderClaim(folder, force))
    except BaseException:  # an OutputError, or Ctrl-C between two claims
        for claim in claims:
            claim.release()
        raise
    return claims


class FolderClaim:
    """An output folder held by this run: created if missing, with a lock file created
    exclusively (``O_CREAT | O_EXCL``) in it.

    The emptiness check runs under the lock: of two runs started together into one new folder,
    the second is refused instead of both finding it empty and the later overwriting the
    earlier's files. :meth:`release` removes the lock, and the folder too when this run created
    it and wrote nothing into it.
    """

    LOCK = ".robocal-writing"

    def __init__(self, folder: Path, force: bool = False):
        self.folder = Path(folder)
        missing = [p for p in self._chain() if not p.exists()]
        self.created = missing[-1] if missing else None  # the topmost folder this run creates
        make_folder(self.folder)
        self.lock = self.folder / self.LOCK
        try:
            fd = os.open(self.lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            raise OutputError(
                f"{self.folder}: another robocal run is writing into this folder (if none is, remove {self.lock}, left by an interrupted run)"
            ) from None
        except OSError as exc:
            raise OutputError(f"{self.folder}: cannot write into the folder ({exc.strerror or exc})") from None
        with os.fdopen(fd, "w") as f:
            f.write(f"{os.getpid()}\n")
        if not force and any(p.name != self.LOCK for p in self.folder.iterdir()):
            self.release()
            raise OutputError(f"{self.folder}: the output folder exists and is not empty; pass --force to overwrite the files in it")

    def release(self) -> None:
        """Removes the lock, and the folders this run created if they are still empty."""
        try:
            self.lock.unlink()
        except FileNotFoundError:
            pass
        if self.created is None:
            return
        for folder in self._chain():
            try:
                folder.rmdir()
            except OSError:  # not empty: something was written, keep it
                return
            if folder == self.created:
                return

    def _chain(self) -> list[Path]:
        """The folder and its parents, absolute."""
        folder = self.folder.absolute()
        return [folder, *folder.parents]


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
        refuse_special(self.path)
        try:
            # Same folder: the final rename stays on one file system, hence atomic. Same suffix:
            # writers that choose the format by suffix (matplotlib, the export tables) still can.
            fd, name = tempfile.mkstemp(dir=self.path.resolve().parent, prefix=f".{self.path.name}.", suffix=f".tmp{self.path.suffix}")
        except OSError as exc:
            raise OutputError(f"{self.path}: cannot write it ({exc.strerror or exc})") from None
        self.tmp = Path(name)
        try:
            os.close(fd)
            # mkstemp creates the file readable by its owner only; an output gets the mode a plain
            # open() would give it (the existing file's, else 0o666 less the umask).
            os.chmod(self.tmp, self.path.stat().st_mode & 0o7777 if self.path.is_file() else 0o666 & ~_umask())
        except BaseException:  # Ctrl-C before the with block owns the temporary
            self.tmp.unlink(missing_ok=True)
            raise
        return self

    def discard(self) -> None:
        self._keep = False

    @contextmanager
    def writing(self):
        """A block that writes this output: an operating-system error in it (a full disk, a file
        size limit) is an :class:`OutputError` naming this output. Needed where several stages are
        open at once: the innermost ``with`` sees every error first and would otherwise blame its
        own file for another's (``simulate --out big.csv --truth t.json`` blamed t.json)."""
        try:
            yield self.tmp
        except OSError as exc:
            raise OutputError(f"{self.path}: cannot write it ({exc.strerror or exc})") from None

    def __exit__(self, kind, exc, tb) -> bool:
        try:
            if kind is None and self._keep:
                # Again: since the check before the work, the path may have become a FIFO or a link.
                refuse_special(self.path)
                os.replace(self.tmp, self.path)
                return False
        except OSError as error:
            exc, kind = error, OSError
        except BaseException:  # the refusal above, or Ctrl-C during the rename
            self.tmp.unlink(missing_ok=True)
            raise
        if self.tmp.exists():
            self.tmp.unlink()
        if kind is not None and issubclass(kind, OSError):  # e.g. a full disk while writing
            raise OutputError(f"{self.path}: cannot write it ({exc.strerror or exc})") from None
        return False


#: Characters a terminal acts on instead of showing: C0 and C1 controls and DEL (ESC starts a
#: sequence that can erase or rewrite lines, CR returns to the line start), bidirectional
#: overrides and isolates (U+202E shows text reversed), zero-width and other invisible format
#: characters, line and paragraph separators. Newline and tab are kept by :func:`printable`.
_TERMINAL = "\x00-\x08\x0b-\x1f\x7f-\x9f\u00ad\u061c\u180e\u200b-\u200f\u2028-\u202e\u2060-\u206f\ufeff\ufff9-\ufffb"
_HIDDEN = re.compile(f"[{_TERMINAL}]")
_HIDDEN_OR_BREAK = re.compile(f"[{_TERMINAL}\n\t]")


def _escape(match: re.Match) -> str:
    return match.group().encode("unicode_escape").decode("ascii")


def printable(text: str, one_line: bool = False) -> str:
    """``text`` with every character a terminal would act on written as its escape (``\\x1b``,
    ``\\u202e``); with ``one_line``, newlines and tabs too (for a name inside a line)."""
    return (_HIDDEN_OR_BREAK if one_line else _HIDDEN).sub(_escape, str(text))


class PrintableStream:
    """A text stream that writes everything through :func:`printable`: what a command prints
    may hold text from files (names, columns, paths a result records)."""

    def __init__(self, stream):
        self.stream = stream

    def write(self, text: str) -> int:
        self.stream.write(printable(text))
        return len(text)

    def writelines(self, lines) -> None:
        for line in lines:
            self.write(line)

    def __getattr__(self, name):  # flush, isatty, encoding, buffer, ...
        return getattr(self.stream, name)


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
