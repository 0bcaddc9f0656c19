"""robocal's canonical measurement file: a CSV with a header (see docs/data-format.md).

Columns: ``q1..qN`` (degrees by default), the observation columns of the measurement type
(``L``; ``x,y,z``; ``x,y,z,qw,qx,qy,qz``), optionally ``t`` (s), ``temp`` (deg C) and ``sample``.
Rows are in acquisition order. Unknown columns are reported in ``Dataset.notes`` and ignored.
Every problem is a :class:`~robocal.exceptions.DataError` naming file, row and column.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Optional

import numpy as np

from ...exceptions import DataError
from ..dataset import ANGLE_UNITS, OBSERVATION_COLUMNS, OPTIONAL_COLUMNS, Dataset, time_order_notes
from ..table import Table, check_unit_quaternions, excluded_notes, read_delimited

NUMERIC_OPTIONAL = ("t", "temp")


def _measurement_from_header(header: list[str], path) -> str:
    present = set(header)
    if "L" in present:
        return "cable"
    if set(OBSERVATION_COLUMNS["pose"]) <= present:
        return "pose"
    if set(OBSERVATION_COLUMNS["position"]) <= present:
        return "position"
    raise DataError(f"no measurement columns: expected 'L' (cable), 'x,y,z' (position) or 'x,y,z,qw,qx,qy,qz' (pose); got {header}", path, 1)


def read_canonical(
    path,
    angle_unit: str = "deg",
    measurement: Optional[str] = None,
    robot: Optional[str] = None,
    exclude_bad_rows: bool = False,
    *,
    prismatic: tuple = (),
    table: Optional[Table] = None,
) -> Dataset:
    """Reads a canonical CSV file into a :class:`Dataset` (joint angles converted to rad).

    Parameters
    ----------
    path : str or Path
    angle_unit : {"deg", "rad"}
        Unit of the ``q`` columns in the file.
    measurement : {"cable", "position", "pose"}, optional
        Which observation to read; detected from the header by default.
    robot : str, optional
        Recorded in the dataset.
    exclude_bad_rows : bool
        Leave out rows with a bad cell, recording each in ``Dataset.excluded``, instead of
        raising a :class:`DataError` on the first.
    prismatic : tuple of int
        Joints (0-based) that are prismatic: their columns are mm, read as they are.
    table : Table, optional
        The file's table (:func:`~robocal.data.table.read_delimited`) where the caller has read
        it already (:func:`robocal.data.load` has, to recognise the format).
    """
    path = Path(path)
    if angle_unit not in ANGLE_UNITS:
        raise DataError(f"`angle_unit` must be one of {ANGLE_UNITS}; got {angle_unit!r}", path)
    return canonical_dataset(read_delimited(path) if table is None else table, angle_unit, measurement, robot, exclude_bad_rows, prismatic=prismatic)


def canonical_columns(table: Table, measurement: Optional[str]) -> tuple[list, str, list]:
    """The joint columns, the measurement and every numeric column read of a canonical header
    (``table.header``); a :class:`DataError` on row 1 for a header that is not one."""
    header, path = table.header, table.path
    joints = table.joint_columns()
    expected = [f"q{i}" for i in range(1, len(joints) + 1)]
    if not joints or joints != expected:
        raise DataError(f"joint columns must be q1..qN without gaps; got {joints or 'none'}", path, 1)
    measurement = measurement or _measurement_from_header(header, path)
    if not isinstance(measurement, str) or measurement not in OBSERVATION_COLUMNS:
        raise DataError(f"`measurement` must be one of {tuple(OBSERVATION_COLUMNS)}; got {measurement!r}", path)
    table.require(OBSERVATION_COLUMNS[measurement], f"a {measurement} file")
    return joints, measurement, joints + list(OBSERVATION_COLUMNS[measurement]) + [c for c in NUMERIC_OPTIONAL if c in header]


def canonical_dataset(
    table: Table, angle_unit: str, measurement: Optional[str], robot: Optional[str], exclude_bad_rows: bool, *, prismatic: tuple = ()
) -> Dataset:
    """The :class:`Dataset` of a canonical :class:`~robocal.data.table.Table` (from a file, a
    DataFrame or a line of a stream; its ``path`` names the source in errors); the ``prismatic``
    joints' columns (0-based) are mm, never converted from degrees."""
    header, path = table.header, table.path
    joints, measurement, wanted = canonical_columns(table, measurement)
    obs = OBSERVATION_COLUMNS[measurement]
    known = set(wanted) | set(OPTIONAL_COLUMNS)  # the sample label is text, documented and not used
    ignored = [h for h in header if h not in known]
    values, rows, excluded = table.numeric(wanted, allow_nonfinite=("temp",), exclude_bad_rows=exclude_bad_rows)
    n = len(joints)
    if measurement == "pose":
        check_unit_quaternions(values[:, n + 3 : n + 7], rows, path)
    q = values[:, :n].copy()
    if angle_unit == "deg":
        revolute = [j for j in range(n) if j not in prismatic]
        if len(revolute) == n:  # in place: a column index gathers and scatters (2 ms on 20 000 rows)
            np.radians(q, out=q)
        else:
            q[:, revolute] = np.radians(q[:, revolute])
    column = {name: values[:, i] for i, name in enumerate(wanted)}
    notes = ([f"ignored unknown columns {ignored}"] if ignored else []) + excluded_notes(excluded) + time_order_notes(column.get("t"), rows, path)
    return Dataset(
        q=q,
        y=values[:, n : n + len(obs)],
        measurement=measurement,
        robot=robot,
        t=column.get("t"),
        temp=column.get("temp"),
        rows=rows,
        source=str(path),
        excluded=excluded,
        notes=notes,
        prismatic=tuple(j for j in prismatic if j < n),
    )


def write_canonical(dataset: Dataset, path, angle_unit: str = "deg") -> Path:
    """Writes ``dataset`` as a canonical CSV (joint angles in ``angle_unit``); returns the path."""
    if angle_unit not in ANGLE_UNITS:
        raise DataError(f"`angle_unit` must be one of {ANGLE_UNITS}; got {angle_unit!r}", path)
    path = Path(path)
    columns, table = dataset.canonical_columns(angle_unit)
    with path.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(columns)
        writer.writerows([[repr(float(v)) for v in row] for row in table])
    return path
