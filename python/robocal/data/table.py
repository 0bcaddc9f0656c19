"""Any file to one parsed table, and cells to numbers: what every format reader stands on.

A :class:`Table` is a header (list of column names) and a body of ``(row_number, cells)`` records,
row numbers 1-based with the header as row 1, read by :func:`read_table` from an .xlsx workbook
(recognised by its signature) or a delimited text. Cells are strings (CSV) or numbers / ``None``
(spreadsheets). Every problem is a :class:`~robocal.exceptions.DataError` naming file, row and
column — or, when the caller asks for it, an entry of the excluded-rows list. Nothing is dropped
silently. This module knows no file format: the readers in :mod:`robocal.data.formats` build a
:class:`~robocal.data.Dataset` from a table, and nothing here calls them.

Delimited text is read twice over only when it must be: :func:`split_delimited` hands out a
:class:`DelimitedBody`, whose numeric columns come from pyarrow's columnar CSV reader (all cells
read as text, checked and converted column by column in C++). That fast path *accepts* a column
only when every cell is one the per-cell rules take with the same value (ASCII digits, sign,
point, exponent; no empty cell, no NaN / infinity, within ``MAX_ABS``) and the file's line
structure is one it reproduces exactly (no quotes, no lone CR, no Unicode line separator, no
over-long line). Anything else — or pyarrow missing — falls back to the per-cell path over
:func:`csv.reader` records, which names the bad file, row and column: errors are the same either
way, because the fast path never raises.
"""

from __future__ import annotations

import csv
import difflib
import io
import math
import re
import sys
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Iterable, Optional, Sequence

import numpy as np

from ..kernels import MAX_ABS, QUATERNION_NORM_TOL
from ..exceptions import DataError
from ..files import MAX_FILE_BYTES, open_regular, read_regular
from .dataset import row_ranges

#: Read numeric columns of delimited text with the columnar reader (pyarrow) where it can;
#: ``False`` reads every cell with the per-cell path (the benchmarks and tests compare the two).
COLUMNAR = True
#: Below this size (bytes of text), and while pyarrow is not yet imported, a file is read cell by
#: cell: importing pyarrow (~0.1 s) costs more than the per-cell path on ~1 MB of cells
#: (benches/bench_loading.py). Once pyarrow is loaded, every file takes the columnar reader.
COLUMNAR_MIN_BYTES = 1 << 20
#: A number as a person writes it in a table: no underscores (Python's ``float("1_0")`` is 10),
#: no hex, no non-ASCII digits; ``nan`` / ``inf`` are recognised to be refused by name.
#: (Unambiguous, hence linear-time: a 100 000-digit cell must not backtrack.)
_NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?|[+-]?(?:nan|inf|infinity)", re.IGNORECASE | re.ASCII)


def shown(value, limit: int = 40) -> str:
    """``repr(value)`` cut to ``limit`` characters: a 100 000-digit cell is not echoed."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[:limit]}... ({len(str(value))} characters)"


def _refusal(path):
    """The :class:`DataError` naming ``path`` for a problem :mod:`robocal.files` found."""
    return lambda problem: DataError(problem, path)


def open_data(path):
    """``path`` opened for reading in binary mode, once it is known to be a regular file of at
    most :data:`MAX_FILE_BYTES` (:func:`robocal.files.open_regular`); else a :class:`DataError`
    naming it."""
    return open_regular(path, _refusal(path), limit=MAX_FILE_BYTES)


def read_data(path) -> bytes:
    """The bytes of the data file ``path`` (see :func:`open_data`), at most :data:`MAX_FILE_BYTES`
    even if it grows while being read."""
    return read_regular(path, _refusal(path), limit=MAX_FILE_BYTES)


def read_text(path) -> str:
    """The file's text (UTF-8, an optional BOM removed), or a :class:`DataError`."""
    path = Path(path)
    data = read_data(path)
    try:  # bytes then decode: no newline translation to pay for (str.splitlines reads CRLF and CR alike)
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        utf16 = data[:2] in (b"\xff\xfe", b"\xfe\xff")  # what spreadsheets write as "Unicode text"
        hint = ": it starts with a UTF-16 byte-order mark; save it as UTF-8 (CSV UTF-8)" if utf16 else ""
        raise DataError(f"not a UTF-8 text file (undecodable byte at offset {exc.start}){hint}", path) from None


def split_delimited(text: str, delimiter: str, path):
    """Header and ``(row_number, cells)`` records of a delimited text (blank lines skipped).

    The records are a :class:`DelimitedBody` (split on first use; numeric columns by the
    columnar reader) when the text's structure allows it, else a list.
    """
    body = DelimitedBody.of(text, delimiter, path)
    lines = [] if body is None else [next(csv.reader([body.first_line], delimiter=delimiter))]
    if body is None:
        lines = _records(text, delimiter, path)
    if not lines or not any(cell.strip() for cell in lines[0]):
        raise DataError("the file is empty (a header row is expected)", path, 1)
    header = [h.strip() for h in lines[0]]
    check_header(header, path, delimiter)
    if body is not None:
        body.n_columns = len(header)
        return header, body
    return header, _data_records(lines)


def _data_records(lines: list[list[str]]) -> list[tuple[int, list[str]]]:
    """The ``(row_number, cells)`` records after the header, blank lines skipped (they hold no
    cells). A row of only empty cells (``,,,,``, a spreadsheet's empty row) is kept: it is left
    out by :func:`numeric_columns`, which says so."""
    return [(i, row) for i, row in enumerate(lines[1:], start=2) if len(row) > 1 or any(cell.strip() for cell in row)]


def _records(text: str, delimiter: str, path) -> list[list[str]]:
    """Every line of ``text`` split into cells by :func:`csv.reader` (the per-cell path); an
    error names the line (row) it stopped at, and the column of a cell beyond the reader's size limit."""
    lines = text.splitlines()
    reader = csv.reader(lines, delimiter=delimiter)
    try:
        return list(reader)
    except csv.Error as exc:
        row = reader.line_num
        limit = csv.field_size_limit()
        cells = lines[row - 1].split(delimiter) if 0 < row <= len(lines) else []
        long = next((k for k, cell in enumerate(cells) if len(cell) > limit), None)
        if long is None:
            raise DataError(f"not a readable {delimiter!r}-separated text ({exc})", path, row or None) from None
        names = lines[0].split(delimiter) if row > 1 else []
        column = names[long].strip()[:40] if long < len(names) else f"cell {long + 1}"
        raise DataError(f"a cell of {len(cells[long])} characters, beyond the {limit} a cell of a delimited text may hold", path, row, column) from None


#: Bytes a text may hold for the columnar reader to split it exactly as :func:`csv.reader`
#: over ``str.splitlines()`` does: tab, LF, CR (only as CRLF, checked apart), printable ASCII but
#: the quote (deleted by ``bytes.translate``; what is left is refused), and the bytes of
#: multi-byte UTF-8 characters (U+0085, U+2028 and U+2029, where ``splitlines`` breaks lines,
#: are checked apart). The other controls (VT, FF, FS, GS, RS also break lines; NUL) are left to
#: the per-cell path.
_TEXT_BYTES = bytes([9, 10, 13, *(c for c in range(32, 127) if c != ord('"')), *range(128, 256)])
_UNICODE_BREAKS = ("\x85", "\u2028", "\u2029")
#: Bytes of a numeric cell on the fast path: ASCII digits, sign, point, exponent, and the spaces
#: / tabs ``str.strip()`` removes around them (a comma too, for a decimal comma).
_NUMBER_BYTES = b"0123456789+-.eE \t"


def _only_number_bytes(cells: bytes, decimal_comma: bool) -> bool:
    rest = cells.translate(None, _NUMBER_BYTES)
    return not (rest.translate(None, b",") if decimal_comma else rest)


def _arrow():
    """pyarrow, with its ``csv`` and ``compute`` modules loaded, or None where it is missing
    (then every cell takes the per-cell path). Imported on first use: ``import robocal`` stays light."""
    try:
        import pyarrow
        import pyarrow.compute
        import pyarrow.csv  # noqa: F401
    except ImportError:
        return None
    return pyarrow


class ColumnarBody(Sequence):
    """Rows of a table with two readings: ``(row_number, cells)`` records for the per-cell
    path, built on first use, and :meth:`numeric`, which :func:`numeric_columns` tries first."""

    #: Row numbers of the records :meth:`numeric` answers for.
    rows: np.ndarray

    def numeric(self, positions: Sequence[int], decimal_comma: bool = False, finite=None) -> Optional[np.ndarray]:
        """Columns ``positions`` as floats (one row per :attr:`rows`) when every cell is one the
        per-cell rules take with the same value; None for the per-cell path to name a bad cell.
        ``finite``: per position, whether NaN / infinity are refused."""
        raise NotImplementedError

    def _records(self) -> list[tuple[int, list]]:
        raise NotImplementedError

    @cached_property
    def records(self) -> list[tuple[int, list]]:
        return self._records()

    def __len__(self) -> int:
        return len(self.records)

    def __getitem__(self, index):
        return self.records[index]

    def __iter__(self):
        return iter(self.records)


class DelimitedBody(ColumnarBody):
    """The data rows of a delimited text: a sequence of ``(row_number, cells)`` records (split by
    :func:`csv.reader` on first use, as :func:`split_delimited` always did), and numeric columns
    read by pyarrow's columnar CSV reader (:meth:`numeric`) without splitting a row in Python.

    Built by :meth:`of` only for texts whose line structure the columnar reader reproduces.
    """

    def __init__(self, text: str, data: bytes, delimiter: str, path, newlines: np.ndarray, rest: bytes):
        self.text, self.data, self.delimiter, self.path = text, data, delimiter, path
        self.newlines = newlines
        first = newlines[0] if newlines.size else len(data)
        self.first_line = data[:first].rstrip(b"\r").decode("utf-8")
        self.n_columns = 0
        # ``rest``: the body's bytes beside number bytes, delimiters and line ends
        self.number_bytes_only = {False: not rest, True: not rest.translate(None, b",")}
        self.padded = data.find(b" ", first) >= 0 or data.find(b"\t", first) >= 0

    @classmethod
    def of(cls, text: str, delimiter: str, path) -> Optional["DelimitedBody"]:
        """A body for ``text``, or None where only the per-cell path splits it exactly."""
        if not COLUMNAR or ("pyarrow" not in sys.modules and len(text) < COLUMNAR_MIN_BYTES):
            return None
        data = text.encode("utf-8")
        if len(delimiter) != 1 or not delimiter.isascii() or delimiter == '"':
            return None
        first = data.find(b"\n")
        first = len(data) if first < 0 else first
        # one pass over the body: what is left beside number bytes must be text bytes too
        rest = data[first:].translate(None, b"\r\n" + delimiter.encode() + _NUMBER_BYTES)
        if data[:first].translate(None, _TEXT_BYTES) or rest.translate(None, _TEXT_BYTES):
            return None
        if not data.isascii() and any(c in text for c in _UNICODE_BREAKS):
            return None
        buf = np.frombuffer(data, dtype=np.uint8)
        newlines = np.flatnonzero(buf == 10)
        # CR only in CRLF, which both readers take as one line end: every CR is one that ends before a LF
        if b"\r" in data and np.count_nonzero(buf == 13) != np.count_nonzero(buf[newlines[newlines > 0] - 1] == 13):
            return None
        longest = np.diff(newlines, prepend=-1, append=len(data)).max() if data else 0
        if longest > csv.field_size_limit() or not data[:first].strip():
            return None  # csv.reader refuses over-long fields; a blank first line is the empty-file error
        return cls(text, data, delimiter, path, newlines, rest)

    def _records(self) -> list[tuple[int, list[str]]]:
        """The records as the per-cell path has always split them."""
        return _data_records(_records(self.text, self.delimiter, self.path))

    # -- the columnar reader
    @cached_property
    def rows(self) -> np.ndarray:
        """Row numbers (header = 1) of the non-empty lines after the header."""
        ends = np.append(self.newlines, len(self.data))
        starts = np.concatenate([[0], self.newlines + 1])
        buf = np.frombuffer(self.data, dtype=np.uint8)
        cr = np.zeros(len(ends), dtype=np.int64)
        inside = ends > starts
        cr[inside] = buf[ends[inside] - 1] == 13
        lines = np.flatnonzero(ends - starts - cr > 0)
        return lines[lines > 0] + 1

    @cached_property
    def columns(self):
        """The cells as a pyarrow Table of text columns, or None (pyarrow missing, a row with
        another cell count than the header — anything the per-cell path must look at)."""
        pa = _arrow()
        return None if pa is None else self._read({str(i): pa.string() for i in range(self.n_columns)})

    def numeric(self, positions: Sequence[int], decimal_comma: bool = False, finite=None) -> Optional[np.ndarray]:
        """See :meth:`ColumnarBody.numeric`: here every cell must be finite and within
        ``MAX_ABS`` (an empty or NaN cell always goes to the per-cell path, ``finite`` or not)."""
        if self.number_bytes_only[bool(decimal_comma)] and not self.padded:
            out = self._floats(positions, decimal_comma)  # every cell of the body is made of number bytes
        else:
            out = self._cast(positions, decimal_comma)
        if out is None or not np.isfinite(out).all() or (np.abs(out) > MAX_ABS).any():
            return None
        return out

    def _read(self, column_types: dict, **convert):
        """pyarrow's ``read_csv`` of the body with ``column_types`` (name = position), or None."""
        pa = _arrow()
        if pa is None:
            return None
        pacsv = pa.csv
        names = [str(i) for i in range(self.n_columns)]
        try:
            table = pacsv.read_csv(
                pa.py_buffer(self.data),
                read_options=pacsv.ReadOptions(column_names=names, skip_rows=1),
                parse_options=pacsv.ParseOptions(delimiter=self.delimiter, quote_char=False, escape_char=False, ignore_empty_lines=True),
                convert_options=pacsv.ConvertOptions(
                    column_types=column_types, null_values=[], strings_can_be_null=False, include_columns=list(column_types), check_utf8=False, **convert
                ),
            )
        except (pa.ArrowException, ValueError):
            return None
        return table if table.num_rows == len(self.rows) and table.num_rows > 0 else None

    def text_column(self, position: int) -> Optional[list[str]]:
        """The raw cells of column ``position`` for every row of :attr:`rows`, or None."""
        pa = _arrow()
        if pa is None:
            return None
        table = self.columns if "columns" in vars(self) else self._read({str(position): pa.string()})
        return None if table is None else table.column(str(position)).to_pylist()

    def _floats(self, positions: Sequence[int], decimal_comma: bool) -> Optional[np.ndarray]:
        """The columns parsed to float64 by the CSV reader itself (no text columns built)."""
        pa = _arrow()
        if pa is None:
            return None
        table = self._read({str(p): pa.float64() for p in dict.fromkeys(positions)}, decimal_point="," if decimal_comma else ".")
        if table is None:
            return None
        columns = [_float_values(table.column(str(p))) for p in positions]
        return None if any(c is None for c in columns) else np.column_stack(columns)

    def _cast(self, positions: Sequence[int], decimal_comma: bool) -> Optional[np.ndarray]:
        """The columns as text, each checked for number bytes, trimmed, then cast to float64."""
        table = self.columns
        if table is None:
            return None
        pa = _arrow()
        pc = pa.compute

        out = np.empty((table.num_rows, len(positions)), dtype=np.float64)
        for k, position in enumerate(positions):
            column = table.column(position)
            padded = self.padded
            if not self.number_bytes_only[bool(decimal_comma)]:
                cells = b"".join(_chunk_bytes(chunk) for chunk in column.chunks)
                if not _only_number_bytes(cells, decimal_comma):
                    return None
                padded = b" " in cells or b"\t" in cells
            if padded:
                column = pc.utf8_trim(column, characters=" \t")
            if decimal_comma:
                column = pc.replace_substring(column, ",", ".")
            if any(_chunk_has_empty(chunk) for chunk in column.chunks):
                return None
            try:
                values = _float_values(pc.cast(column, pa.float64()))
            except (pa.ArrowException, ValueError):
                return None
            if values is None:
                return None
            out[:, k] = values
        return out


def text_column(body, position: int, rows: np.ndarray) -> list[str]:
    """The cells of column ``position`` (stripped) in the records numbered ``rows``: from the
    columnar table when those are all its rows, else record by record."""
    if isinstance(body, DelimitedBody) and np.array_equal(rows, body.rows):
        column = body.text_column(position)
        if column is not None:
            return [cell.strip() for cell in column]
    kept = {int(r) for r in rows}
    return [cells[position].strip() for number, cells in body if number in kept]


def _float_values(column) -> Optional[np.ndarray]:
    """A pyarrow float64 column without nulls as one NumPy array. From the buffers: pyarrow's
    ``to_numpy`` imports pandas when it is installed (~0.4 s on a first call)."""
    if column.null_count:  # not produced (null_values=[], no text nulls); were it, the per-cell path
        return None
    parts = [np.frombuffer(c.buffers()[1], dtype=np.float64)[c.offset : c.offset + len(c)] for c in column.chunks]
    return np.concatenate(parts) if parts else np.zeros(0)


def _offsets(chunk) -> np.ndarray:
    return np.frombuffer(chunk.buffers()[1], dtype=np.int32)[chunk.offset : chunk.offset + len(chunk) + 1]


def _chunk_bytes(chunk) -> bytes:
    """The UTF-8 bytes of a pyarrow string array's cells, one after the other."""
    offsets, data = _offsets(chunk), chunk.buffers()[2]
    return b"" if data is None or not len(chunk) else data.to_pybytes()[offsets[0] : offsets[-1]]


def _chunk_has_empty(chunk) -> bool:
    return bool((np.diff(_offsets(chunk)) == 0).any())


def check_header(header: Sequence[str], path, delimiter: Optional[str] = None) -> None:
    """A :class:`DataError` on row 1 for a header of one column holding another separator than
    the text's ``delimiter`` (it is of another format), or naming the first column name that appears
    twice (which of the two holds the data cannot be guessed). Linear in the number of columns."""
    if delimiter is not None and len(header) == 1:
        seen = next((d for d in (",", ";", "\t") if d != delimiter and d in header[0]), None)
        if seen is not None:
            name = {",": "','", ";": "';'", "\t": "tab"}
            raise DataError(
                f"the header is a single column containing {name[seen]}: this file looks {name[seen]}-separated; "
                f"the format it is read as is {name[delimiter]}-separated",
                path,
                1,
            )
    seen = set()
    for name in header:
        if name and name in seen:
            raise DataError(f"the column {shown(name)} appears more than once in the header", path, 1, name[:40])
        seen.add(name)


class UncachedFormula(str):
    """A spreadsheet cell holding a formula (``"=J4+1"``) but no computed value."""


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
    if isinstance(cell, UncachedFormula):
        message = f"the cell holds the formula {shown(str(cell))} without a cached value: open and save the workbook in a spreadsheet program to compute it"
        raise DataError(message, path, row, column)
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


#: The reason recorded for a row of only empty cells, which every reader leaves out.
EMPTY_ROW = "every cell of the row is empty"


def excluded_notes(excluded: list) -> list[str]:
    """The notes of a dataset on the rows :func:`numeric_columns` left out: rows of only empty
    cells (always) and rows with bad cells (on request)."""
    empty = [e["row"] for e in excluded if e["reason"] == EMPTY_ROW]
    bad = len(excluded) - len(empty)
    notes = [f"left out {len(empty)} row(s) of only empty cells (rows {row_ranges(empty)}; see `excluded`)"] if empty else []
    return notes + ([f"excluded {bad} rows with bad cells (see `excluded`)"] if bad else [])


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
        raising. A row of only empty cells is always recorded there (reason :data:`EMPTY_ROW`), never an error.

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
    first = {}
    for i, name in enumerate(header):
        first.setdefault(name, i)
    position = [first[name] for name in wanted]
    fast = body.numeric(position, decimal_comma, [name not in allow_nonfinite for name in wanted]) if isinstance(body, ColumnarBody) else None
    if fast is not None:
        return fast, body.rows.copy(), []
    if not body:
        raise DataError("the file has a header but no data rows", path, 2)
    values, rows, excluded = [], [], []
    for row_number, cells in body:
        if all(cell is None or (isinstance(cell, str) and not cell.strip()) for cell in cells):
            excluded.append({"row": row_number, "column": None, "reason": EMPTY_ROW})  # no data to lose, but never silently
            continue
        try:
            if len(cells) != len(header):
                raise DataError(f"expected {len(header)} cells like the header; got {len(cells)}", path, row_number)
            values.append([parse_number(cells[i], path, row_number, name, decimal_comma, name not in allow_nonfinite) for i, name in zip(position, wanted)])
            rows.append(row_number)
        except DataError as exc:
            if not exclude_bad_rows:
                raise
            excluded.append({"row": row_number, "column": exc.column, "reason": exc.message})
    if not rows:
        why = ""
        if excluded:
            first = excluded[0]
            where = f"row {first['row']}" + (f", column {first['column']!r}" if first["column"] else "")
            why = f" ({len(excluded)} rows with bad cells excluded; the first, {where}: {first['reason']})"
        raise DataError("no valid data rows" + why, path, 2)
    return np.array(values, dtype=np.float64), np.array(rows, dtype=np.int64), excluded


def check_unit_quaternions(quaternions: np.ndarray, rows: np.ndarray, path) -> None:
    """A :class:`DataError` naming ``path`` and the first row whose quaternion ``qw, qx, qy, qz``
    (one per row of ``quaternions``, shape (m, 4)) is not of unit norm within the core's tolerance."""
    norms = np.linalg.norm(quaternions, axis=1)
    bad = np.flatnonzero(np.abs(norms - 1.0) > QUATERNION_NORM_TOL)
    if bad.size:
        k = bad[0]
        quaternion = tuple(float(v) for v in quaternions[k])
        more = f" ({bad.size} rows like it)" if bad.size > 1 else ""
        message = f"the quaternion (qw,qx,qy,qz) = {quaternion} must have unit norm (within {QUATERNION_NORM_TOL:g}); got norm {norms[k]:.6g}{more}"
        raise DataError(message, path, int(rows[k]))


# -- workbooks ---------------------------------------------------------------------------------
XLSX_SIGNATURE = b"PK\x03\x04"


def is_workbook(path) -> bool:
    """Whether ``path`` starts with the .xlsx (zip) signature: a workbook is judged by its
    content, never by its extension."""
    with open_data(path) as f:
        try:
            return f.read(4) == XLSX_SIGNATURE
        except OSError as exc:
            raise DataError(f"cannot read the file ({exc.strerror or exc})", path) from None


def _open_workbook(path: Path, data_only: bool = True):
    """The workbook at ``path``: cell values as last computed (``data_only``) or as typed (formulas)."""
    import openpyxl

    content = read_data(path)
    try:  # from bytes: openpyxl would judge a path by its extension, we judge by content
        return openpyxl.load_workbook(io.BytesIO(content), read_only=True, data_only=data_only)
    except Exception as exc:  # openpyxl raises many types (zipfile, KeyError, XML errors) on corrupt files
        raise DataError(f"not a readable .xlsx workbook ({type(exc).__name__}: {exc})", path) from None


def _sheet_rows(sheet) -> list[tuple]:
    """The rows of a worksheet without trailing empty columns and empty rows (as
    ``(row_number, cells)``) plus the header, or ``([], [])`` for an empty sheet."""
    rows = list(sheet.iter_rows(values_only=True))
    if not rows:
        return [], []
    head = list(rows[0])
    while head and (head[-1] is None or str(head[-1]).strip() == ""):
        head.pop()
    header = ["" if h is None else str(h).strip() for h in head]
    body = []
    for number, cells in enumerate(rows[1:], start=2):
        cells = list(cells)
        if all(c is None or (isinstance(c, str) and not c.strip()) for c in cells):
            continue
        if any(c is not None for c in cells[len(header) :]):
            # a value beyond the header: keep the row's full width so that the cell count check names it
            body.append((number, cells))
        else:
            body.append((number, (cells + [None] * len(header))[: len(header)]))
    return header, body


def _read_xlsx(path: Path, sheet: Optional[str] = None):
    """Header, body and notes (other non-empty sheets) of one worksheet."""
    book = _open_workbook(path)
    try:
        names = book.sheetnames
        if sheet is not None and sheet not in names:
            raise DataError(f"no sheet {sheet!r}; the workbook has {names}", path)
        chosen = sheet or names[0]
        header, body = _sheet_rows(book[chosen])
        notes = [f"read sheet {chosen!r}"] if len(names) > 1 else []
        where = {tuple(cells): number for number, cells in body}
        for name in names:
            if name != chosen:
                other_header, other_body = _sheet_rows(book[name])
                if other_body:
                    repeats = [where[tuple(cells)] for _, cells in other_body if tuple(cells) in where]
                    same = f"; {len(repeats)} of its rows repeat rows {row_ranges(sorted(set(repeats)))} of this sheet" if repeats else ""
                    notes.append(f"sheet {name!r} ({len(other_body)} rows, columns {other_header}) not read{same}; pass sheet={name!r} to read it")
    finally:
        book.close()
    if not header:
        raise DataError(f"sheet {chosen!r} is empty (a header row is expected)", path, 1)
    check_header(header, path)
    if any(c is None for _, cells in body for c in cells):
        body = _mark_uncached_formulas(path, chosen, body)
    return header, body, notes


def _mark_uncached_formulas(path: Path, sheet: str, body: list) -> list:
    """``body`` with each empty cell that holds a formula as an :class:`UncachedFormula`: a
    workbook written by a program that computes nothing (openpyxl, pandas) has formulas without
    values, which are not empty cells and need another remedy."""
    book = _open_workbook(path, data_only=False)
    try:
        typed = list(book[sheet].iter_rows(values_only=True))
    finally:
        book.close()
    marked = []
    for number, cells in body:
        row = typed[number - 1] if number - 1 < len(typed) else ()
        formulas = [v if isinstance(v, str) and v.startswith("=") else None for v in row]
        marked.append((number, [UncachedFormula(formulas[k]) if c is None and k < len(formulas) and formulas[k] else c for k, c in enumerate(cells)]))
    return marked


# -- the table ---------------------------------------------------------------------------------
#: A joint column's name: ``q1``, ``q2``, ...
_JOINT = re.compile(r"q\d+")


@dataclass
class Table:
    """One parsed table: what every format reader builds its :class:`~robocal.data.Dataset` from.

    Attributes
    ----------
    header : list of str
        Column names (stripped; no name twice).
    body : sequence of (int, sequence)
        ``(row_number, cells)`` records (a :class:`ColumnarBody` where a columnar reading exists).
    path
        Where the table came from, as the caller named it: the readers' errors name it.
    notes : list of str
        What reading the table noticed (the sheet read, other sheets left unread).
    """

    header: list
    body: Sequence
    path: object
    notes: list = field(default_factory=list)

    def joint_columns(self) -> list[str]:
        """The header's joint columns ``q1``, ``q2``, ... in joint order (gaps and all)."""
        return sorted((h for h in self.header if _JOINT.fullmatch(h)), key=lambda h: int(h[1:]))

    def require(self, expected: Iterable[str], what: str) -> None:
        """See :func:`require_columns`."""
        require_columns(self.header, expected, self.path, what)

    def numeric(self, wanted: Sequence[str], *, decimal_comma: bool = False, allow_nonfinite: Sequence[str] = (), exclude_bad_rows: bool = False):
        """``values, rows, excluded`` of the ``wanted`` columns: see :func:`numeric_columns`."""
        return numeric_columns(self.header, self.body, wanted, self.path, decimal_comma, allow_nonfinite, exclude_bad_rows)

    def text(self, name: str, rows: np.ndarray) -> list[str]:
        """The stripped cells of column ``name`` in the records numbered ``rows`` (see :func:`text_column`)."""
        return text_column(self.body, self.header.index(name), rows)

    def ignored_note(self, used: Iterable[str]) -> list[str]:
        """The note naming the header's columns outside ``used``, if any."""
        used = set(used)
        ignored = [h for h in self.header if h not in used]
        return [f"ignored columns {ignored}"] if ignored else []


def read_delimited(path, delimiter: str = ",", text: Optional[str] = None) -> Table:
    """The :class:`Table` of a delimited text file (UTF-8; see :func:`split_delimited`);
    ``text``: the file's text (:func:`read_text`) where the caller has read it already."""
    header, body = split_delimited(read_text(path) if text is None else text, delimiter, path)
    return Table(header, body, path)


def read_table(path, *, sheet: Optional[str] = None, delimiter: str = ",") -> Table:
    """The :class:`Table` of an .xlsx workbook's sheet (by signature: the first sheet unless
    ``sheet``; the other sheets named in its notes) or of a ``delimiter``-separated text file.
    ``Table.path`` is ``path`` as given."""
    file = Path(path)
    if is_workbook(file):
        header, body, notes = _read_xlsx(file, sheet)
        return Table(header, body, path, notes)
    if sheet is not None:
        raise DataError(f"`sheet` applies to .xlsx workbooks; this is a text file (sheet={sheet!r})", file)
    table = read_delimited(file, delimiter)
    table.path = path
    return table
