"""pandas DataFrames in: a frame with the canonical columns (docs/data-format.md) read as the
canonical CSV with the same content is read, with the same checks and the same
:class:`~robocal.exceptions.DataError` naming the column and the row — the row being the
frame's position (0-based, ``frame.iloc[row]``). pandas is optional: it is imported only here and
in :meth:`Dataset.to_frame <robocal.data.Dataset.to_frame>`.
"""

from __future__ import annotations

import sys
from typing import Optional, Sequence

import numpy as np

from ...exceptions import DataError
from ..dataset import ANGLE_UNITS, Dataset, require_pandas
from ..table import MAX_ABS, ColumnarBody, Table, check_header
from .canonical import canonical_dataset

#: How a frame is named in errors and in ``Dataset.source``.
SOURCE = "DataFrame"


def is_frame(obj) -> bool:
    """Whether ``obj`` is a pandas DataFrame (without importing pandas: a frame's maker has)."""
    pandas = sys.modules.get("pandas")
    return pandas is not None and isinstance(obj, pandas.DataFrame)


class FrameBody(ColumnarBody):
    """The rows of a DataFrame as ``(position, cells)`` records (built on first use), and its
    numeric columns as one array when every cell is a number the per-cell rules take."""

    def __init__(self, frame):
        self.frame = frame
        self.rows = np.arange(len(frame), dtype=np.int64)

    def numeric(self, positions: Sequence[int], decimal_comma: bool = False, finite=None) -> Optional[np.ndarray]:
        """See :meth:`ColumnarBody.numeric`: here the columns must be of numeric dtypes (not
        bool), their values within ``MAX_ABS`` and finite where ``finite`` says."""
        pd = require_pandas("reading a DataFrame")
        columns = [self.frame.iloc[:, k] for k in positions]
        types = pd.api.types
        if not len(self.frame) or any(types.is_bool_dtype(c) or not types.is_numeric_dtype(c) or types.is_complex_dtype(c) for c in columns):
            return None
        try:
            values = np.column_stack([c.to_numpy(dtype=np.float64, na_value=np.nan) for c in columns])
        except (TypeError, ValueError, OverflowError):
            return None
        must = np.ones(len(positions), dtype=bool) if finite is None else np.asarray(finite, dtype=bool)
        ok = np.isfinite(values)
        if not ok[:, must].all() or (np.abs(values[ok]) > MAX_ABS).any():
            return None
        if not must.all() and any(c.hasnans for k, c in enumerate(columns) if not must[k] and not pd.api.types.is_float_dtype(c.dtype)):
            return None  # a missing value of a nullable integer column: left to the per-cell path
        return values

    def _records(self) -> list[tuple[int, list]]:
        """Python objects per cell (numbers, text, None for a missing value), as the per-cell
        rules of a spreadsheet take them."""
        pd = require_pandas("reading a DataFrame")
        cells = self.frame.astype(object).to_numpy().tolist()
        return [(i, [None if c is pd.NA or c is pd.NaT else c for c in row]) for i, row in enumerate(cells)]


def read_frame(
    frame, angle_unit: str = "deg", measurement: Optional[str] = None, robot: Optional[str] = None, exclude_bad_rows: bool = False, *, prismatic: tuple = ()
) -> Dataset:
    """Reads a DataFrame with the canonical columns into a :class:`Dataset`, as
    :func:`~robocal.data.read_canonical` reads the same table from a CSV file.

    Parameters
    ----------
    frame : pandas.DataFrame
        Columns ``q1..qN`` (in ``angle_unit``), the observation columns (``L``; ``x, y, z``;
        ``x, y, z, qw, qx, qy, qz``), optionally ``t``, ``temp`` and ``sample``; numbers or text
        cells (text is read by the same rules as a CSV cell).
    angle_unit : {"deg", "rad"}
    measurement : {"cable", "position", "pose"}, optional
        Detected from the columns by default.
    robot : str, optional
        Recorded in the dataset (default: ``frame.attrs["robot"]``, which
        :meth:`Dataset.to_frame` sets).
    exclude_bad_rows : bool
        Record rows with a bad cell in ``Dataset.excluded`` instead of raising.

    Returns
    -------
    Dataset
        ``rows`` are the frame's positions (0-based), ``source`` is ``"DataFrame"``.

    Raises
    ------
    DataError
        Naming the column and the row (position) of a bad cell, like the CSV reader.
    """
    if not is_frame(frame):
        raise DataError(f"expected a pandas DataFrame; got {type(frame).__name__}")
    if angle_unit not in ANGLE_UNITS:
        raise DataError(f"`angle_unit` must be one of {ANGLE_UNITS}; got {angle_unit!r}", SOURCE)
    if frame.columns.nlevels != 1:
        raise DataError(f"expected one header row (flat column names); got {frame.columns.nlevels} column levels", SOURCE)
    if not len(frame):
        raise DataError("the DataFrame has no rows", SOURCE)
    header = [str(name).strip() for name in frame.columns]
    check_header(header, SOURCE)
    return canonical_dataset(Table(header, FrameBody(frame), SOURCE), angle_unit, measurement, robot, exclude_bad_rows, prismatic=prismatic)
