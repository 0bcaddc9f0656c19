"""D1 and D2, the two drawstring-sensor datasets of the RobotCali authors: ``HSR-RobotCali.xlsx``
(HSR JR680) and ``RobotCali-new.xlsx`` / ``RobotCali.xlsx`` (ABB IRB 120), each also as a CSV copy.
Both give joint angles ``q1..q6`` in degrees and the cable length ``L`` in mm; D2 adds the
controller's ``x, y, z``. Read from a :class:`~robocal.data.table.Table` of either file kind.
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from ...exceptions import DataError
from ..dataset import Dataset
from ..table import Table, excluded_notes, read_table

JOINTS6 = [f"q{i}" for i in range(1, 7)]
HSR_COLUMNS = JOINTS6 + ["L"]
ROBOTCALI_COLUMNS = ["x", "y", "z"] + JOINTS6 + ["L"]


def _cable_dataset(
    path, sheet: Optional[str], robot: str, columns: list, what: str, exclude_bad_rows: bool, extra: Optional[str] = None, table: Optional[Table] = None
) -> Dataset:
    """The cable :class:`Dataset` of a D1 / D2 file whose joint columns must be the six of
    ``robot``: ``columns`` end with ``q1..q6, L``; those before them (D2's x, y, z) go to ``extra[extra]``.
    ``table``: the file's (that sheet's) table where the caller has read it already."""
    table = read_table(path, sheet=sheet) if table is None else table
    joints = table.joint_columns()
    if joints and joints != JOINTS6:
        raise DataError(f"the {robot} has 6 joints (columns q1..q6); the header has joint columns {joints}", path, 1)
    table.require(columns, what)
    values, rows, excluded = table.numeric(columns, exclude_bad_rows=exclude_bad_rows)
    lead = len(columns) - 7
    return Dataset(
        q=np.radians(values[:, lead : lead + 6]),
        y=values[:, lead + 6],
        measurement="cable",
        robot=robot,
        rows=rows,
        source=str(path),
        excluded=excluded,
        notes=table.notes + table.ignored_note(columns) + excluded_notes(excluded),
        extra={extra: values[:, :lead]} if extra else {},
    )


def read_hsr(path, exclude_bad_rows: bool = False, *, table: Optional[Table] = None) -> Dataset:
    """Reads D1, HSR-RobotCali (HSR JR680, cable): ``HSR-RobotCali.xlsx`` or its CSV copy.

    Columns ``q1..q6`` (deg, controller readings) and ``L`` (mm, drawstring sensor).

    Parameters
    ----------
    path : str or Path
        The workbook or the comma-separated copy ``hsr_jr680_cable.csv``.
    exclude_bad_rows : bool
        Record rows with a bad cell in ``Dataset.excluded`` instead of raising.
    table : Table, optional
        The file's table (:func:`~robocal.data.table.read_table`) where the caller has read it
        already (:func:`robocal.data.load` has, to recognise the format).

    Returns
    -------
    Dataset
        ``robot="hsr-jr680"``, ``measurement="cable"``, q in rad.
    """
    return _cable_dataset(path, None, "hsr-jr680", HSR_COLUMNS, "an HSR-RobotCali (D1) file", exclude_bad_rows, table=table)


def read_robotcali(path, sheet: Optional[str] = None, exclude_bad_rows: bool = False, *, table: Optional[Table] = None) -> Dataset:
    """Reads D2, RobotCali (ABB IRB 120, cable): ``RobotCali-new.xlsx``, ``RobotCali.xlsx`` or
    the CSV copy ``abb_irb120_cable.csv``.

    Columns ``x, y, z`` (mm, the controller's own position of the flange — not a measurement),
    ``q1..q6`` (deg, rounded to 0.1) and ``L`` (mm, drawstring sensor).

    Parameters
    ----------
    path : str or Path
    sheet : str, optional
        Worksheet to read; the first by default. ``RobotCali.xlsx`` holds 120 samples in
        ``Sheet1`` and, in ``Sheet2``, 10 samples that repeat ``Sheet1`` rows 92-101.
    exclude_bad_rows : bool
        Record rows with a bad cell in ``Dataset.excluded`` instead of raising.
    table : Table, optional
        The table of that sheet (or of the CSV copy) where the caller has read it already.

    Returns
    -------
    Dataset
        ``robot="abb-irb120"``, ``measurement="cable"``; ``extra["controller_xyz"]`` (m, 3) holds
        the controller's x, y, z for the cross-check in :func:`robocal.inspection.inspect`.
    """
    return _cable_dataset(path, sheet, "abb-irb120", ROBOTCALI_COLUMNS, "a RobotCali (D2) file", exclude_bad_rows, "controller_xyz", table)
