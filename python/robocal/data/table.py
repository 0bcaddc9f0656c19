"""Cells to numbers: the row-by-row parsing shared by every reader.

A *table* is a header (list of column names) and a body of ``(row_number, cells)`` records, row
numbers 1-based with the header as row 1. Cells are strings (CSV) or numbers / ``None``
(spreadsheets). Every problem is a :class:`~robocal.exceptions.DataError` naming file, row and
column — or, when the caller asks for it, an entry of the excluded-rows list. Nothing is dropped
silently.
"""

from __future__ import annotations

import csv
import difflib
import math
import re
from pathlib import Path
from typing import Iterable, Sequence

import numpy as np

from ..exceptions import DataError

#: Largest magnitude a cell may hold: beyond ±1e12 mm / rad the core's squares overflow (the
#: core refuses such inputs too, but here the error can name the file, row and column).
MAX_ABS = 1e12
#: A number as a person writes it in a table: no underscores (Python's ``float("1_0")`` is 10),
#: no hex, no non-ASCII digits; ``nan`` / ``inf`` are recognised to be refused by name.
#: (Unambiguous, hence linear-time: a 100 000-digit cell must not backtrack.)
_NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?|[+-]?(?:nan|inf|infinity)", re.IGNORECASE | re.ASCII)


def shown(value, limit: int = 40) -> str:
    """``repr(value)`` cut to ``limit`` characters: a 100 000-digit cell is not echoed."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit]}... ({len(str(value))} characters)"


def read_text(path) -> str:
    """The file's text (UTF-8, an optional BOM removed), or a :class:`DataError`."""
    path = Path(path)
    try:
        return path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise DataError(f"cannot read the file ({exc.strerror or exc})", path) from None
    except UnicodeDecodeError as exc:
        raise DataError(f"not a UTF-8 text file (undecodable byte at offset {exc.start})", path) from None


def split_delimited(text: str, delimiter: str, path):
    """Header and ``(row_number, cells)`` records of a delimited text (blank lines skipped)."""
    try:
        lines = list(csv.reader(text.splitlines(), delimiter=delimiter))
    except csv.Error as exc:
        raise DataError(f"not a readable {delimiter!r}-separated text ({exc})", path) from None
    if not lines or not any(cell.strip() for cell in lines[0]):
        raise DataError("the file is empty (a header row is expected)", path, 1)
    header = [h.strip() for h in lines[0]]
    check_header(header, path)
    body = [(i, row) for i, row in enumerate(lines[1:], start=2) if any(cell.strip() for cell in row)]
    return header, body


def check_header(header: Sequence[str], path) -> None:
    """A :class:`DataError` on row 1 naming the first column name that appears twice (which of
    the two holds the data cannot be guessed). Linear in the number of columns."""
    seen = set()
    for name in header:
        if name and name in seen:
            raise DataError(f"the column {shown(name)} appears more than once in the header", path, 1, name[:40])
        seen.add(name)


def parse_number(cell, path, row: int, column: str, decimal_comma: bool = False, finite: bool = True) -> float:
    """One cell as a float, or a :class:`DataError` naming ``path``, ``row`` and ``column``.

    Parameters
    ----------
    cell : str, int, float or None
        The raw cell: text from a CSV, or a value from a spreadsheet.
    path, row, column
        Where the cell is, for the error message.
    decimal_comma : bool
        Text uses ``,`` as the decimal separator (``"1,5"`` is 1.5).
    finite : bool
        Reject NaN and infinity.
    """
    if isinstance(cell, bool) or not isinstance(cell, (str, int, float, type(None))):
        raise DataError(f"expected a number; got {cell!r} ({type(cell).__name__})", path, row, column)
    if cell is None or (isinstance(cell, str) and not cell.strip()):
        if not finite:  # a column that may hold NaN may also be left empty (docs/data-format.md)
            return math.nan
        raise DataError("expected a number; the cell is empty", path, row, column)
    if isinstance(cell, str):
        text = cell.strip()
        text = text.replace(",", ".") if decimal_comma else text
        if not _NUMBER.fullmatch(text):
            raise DataError(f"expected a number; got {shown(cell.strip())}", path, row, column)
        value = float(text)
    else:
        try:
            value = float(cell)
        except OverflowError:  # a spreadsheet integer beyond float range
            value = math.inf
    if finite and not math.isfinite(value):
        raise DataError(f"expected a finite number; got {shown(cell)}", path, row, column)
    if math.isfinite(value) and abs(value) > MAX_ABS:
        raise DataError(f"{value:.3g} is beyond ±{MAX_ABS:.0e}, the largest value robocal takes", path, row, column)
    return value


def require_columns(header: Sequence[str], expected: Iterable[str], path, what: str) -> None:
    """Raises a :class:`DataError` on row 1 for any of ``expected`` missing from ``header``,
    suggesting the closest name present (a misspelt column is the usual cause)."""
    expected = list(expected)
    missing = [name for name in expected if name not in header]
    if not missing:
        return
    spare = [h for h in header if h and h not in expected]
    hints = [f"{close[0]!r} for {name!r}" for name in missing if (close := difflib.get_close_matches(name, spare, n=1, cutoff=0.6))]
    hint = f" (misspelt? found {', '.join(hints)})" if hints else ""
    raise DataError(f"{what} needs columns {expected}; missing {missing}{hint}; the header is {list(header)}", path, 1)


def numeric_columns(
    header: Sequence[str],
    body: Sequence[tuple[int, Sequence]],
    wanted: Sequence[str],
    path,
    decimal_comma: bool = False,
    allow_nonfinite: Sequence[str] = (),
    exclude_bad_rows: bool = False,
):
    """The ``wanted`` columns of ``body`` as floats.

    Parameters
    ----------
    header : sequence of str
        Column names; ``wanted`` must be among them.
    body : sequence of (int, sequence)
        ``(row_number, cells)`` records; each needs as many cells as ``header``.
    wanted : sequence of str
    path
        The file, for error messages.
    decimal_comma : bool
        Text cells use ``,`` as decimal separator.
    allow_nonfinite : sequence of str
        Columns where NaN / infinity are allowed (e.g. an optional temperature).
    exclude_bad_rows : bool
        Record a row with a bad cell (or the wrong number of cells) in ``excluded`` instead of
        raising.

    Returns
    -------
    values : ndarray, shape (m, len(wanted))
    rows : ndarray of int, shape (m,)
        Row numbers of the kept records.
    excluded : list of dict
        ``{"row", "column", "reason"}`` per left-out row (``column`` is None for a wrong cell count).

    Raises
    ------
    DataError
        On the first bad row unless ``exclude_bad_rows``; when no row is left.
    """
    if not body:
        raise DataError("the file has a header but no data rows", path, 2)
    first = {}
    for i, name in enumerate(header):
        first.setdefault(name, i)
    position = [first[name] for name in wanted]
    values, rows, excluded = [], [], []
    for row_number, cells in body:
        try:
            if len(cells) != len(header):
                raise DataError(f"expected {len(header)} cells like the header; got {len(cells)}", path, row_number)
            values.append(
                [parse_number(cells[i], path, row_number, name, decimal_comma, name not in allow_nonfinite) for i, name in zip(position, wanted)]
            )
            rows.append(row_number)
        except DataError as exc:
            if not exclude_bad_rows:
                raise
            excluded.append({"row": row_number, "column": exc.column, "reason": exc.message})
    if not rows:
        raise DataError("no valid data rows" + (f" ({len(excluded)} rows with bad cells excluded)" if excluded else ""), path, 2)
    return np.array(values, dtype=np.float64), np.array(rows, dtype=np.int64), excluded
