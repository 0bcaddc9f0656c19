"""Readers of the three public calibration datasets in their original formats, and :func:`load`,
which recognises a file's format by its content.

========== =========================================== ============= ===========
format     files                                       robot         measurement
========== =========================================== ============= ===========
hsr        ``HSR-RobotCali.xlsx`` (D1)                  hsr-jr680     cable
robotcali  ``RobotCali-new.xlsx``, ``RobotCali.xlsx``,  abb-irb120    cable
           ``abb_irb120_cable.csv`` (D2)
ipa        ``Series_*/measurements_*.csv`` (D3)         ur10          pose / position
canonical  robocal's own CSV (docs/data-format.md)      given         from the header
========== =========================================== ============= ===========

Every reader returns a :class:`~robocal.data.Dataset` (mm, rad) whose ``rows`` are the rows of
the source file (header = row 1) and raises :class:`~robocal.exceptions.DataError` naming file,
row and column. A row with a bad cell is an error unless ``exclude_bad_rows=True``, which records
it in ``Dataset.excluded``.
"""

from __future__ import annotations

import csv
import io
import logging
import os
import re
from datetime import datetime
from pathlib import Path
from typing import Optional

import numpy as np

from ..exceptions import DataError
from .canonical import ANGLE_UNITS, read_canonical
from .dataset import OBSERVATION_COLUMNS, Dataset, angle_unit_check, row_ranges, time_order_notes
from .frame import SOURCE as FRAME
from .frame import is_frame, read_frame
from .table import (
    UncachedFormula,
    check_header,
    excluded_notes,
    numeric_columns,
    open_data,
    read_data,
    read_text,
    require_columns,
    shown,
    split_delimited,
    text_column,
)

logger = logging.getLogger(__name__)

FORMATS = ("canonical", "hsr", "robotcali", "ipa")
#: The robot each public format belongs to.
FORMAT_ROBOT = {"hsr": "hsr-jr680", "robotcali": "abb-irb120", "ipa": "ur10"}

JOINTS6 = [f"q{i}" for i in range(1, 7)]
HSR_COLUMNS = JOINTS6 + ["L"]
ROBOTCALI_COLUMNS = ["x", "y", "z"] + JOINTS6 + ["L"]
IPA_JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]
IPA_POSITION = ["measurement_x", "measurement_y", "measurement_z"]
IPA_EULER = ["measurement_rx", "measurement_ry", "measurement_rz"]
IPA_STD = [f"measurement_std_{c}" for c in ("x", "y", "z", "rx", "ry", "rz")]
IPA_GOAL = ["Goal x", "Goal y", "Goal z", "Goal roll", "Goal pitch", "Goal yaw"]

XLSX_SIGNATURE = b"PK\x03\x04"
#: ``text.splitlines()[0]`` without splitting the rest: everything up to a line boundary.
_FIRST_LINE = re.compile("[^\n\r\x0b\x0c\x1c-\x1e\x85\u2028\u2029]*")


# -- tables ------------------------------------------------------------------------------------
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


def _read_table(path, sheet: Optional[str] = None, delimiter: str = ","):
    """Header, body and notes of an .xlsx workbook (by signature) or a delimited text file."""
    path = Path(path)
    if _signature(path) == XLSX_SIGNATURE:
        return _read_xlsx(path, sheet)
    if sheet is not None:
        raise DataError(f"`sheet` applies to .xlsx workbooks; this is a text file (sheet={sheet!r})", path)
    header, body = split_delimited(read_text(path), delimiter, path)
    return header, body, []


def _signature(path: Path) -> bytes:
    with open_data(path) as f:
        try:
            return f.read(4)
        except OSError as exc:
            raise DataError(f"cannot read the file ({exc.strerror or exc})", path) from None


def _check_joint_columns(header, n: int, robot: str, path) -> None:
    joints = sorted((h for h in header if re.fullmatch(r"q\d+", h)), key=lambda h: int(h[1:]))
    if joints and joints != [f"q{i}" for i in range(1, n + 1)]:
        raise DataError(f"the {robot} has {n} joints (columns q1..q{n}); the header has joint columns {joints}", path, 1)


def _ignored_note(header, used) -> list[str]:
    used = set(used)
    ignored = [h for h in header if h not in used]
    return [f"ignored columns {ignored}"] if ignored else []


# -- D1 and D2: cable ----------------------------------------------------------------------------
def read_hsr(path, exclude_bad_rows: bool = False) -> Dataset:
    """Reads D1, HSR-RobotCali (HSR JR680, cable): ``HSR-RobotCali.xlsx`` or its CSV copy.

    Columns ``q1..q6`` (deg, controller readings) and ``L`` (mm, drawstring sensor).

    Parameters
    ----------
    path : str or Path
        The workbook or the comma-separated copy ``hsr_jr680_cable.csv``.
    exclude_bad_rows : bool
        Record rows with a bad cell in ``Dataset.excluded`` instead of raising.

    Returns
    -------
    Dataset
        ``robot="hsr-jr680"``, ``measurement="cable"``, q in rad.
    """
    header, body, notes = _read_table(path)
    _check_joint_columns(header, 6, "hsr-jr680", path)
    require_columns(header, HSR_COLUMNS, path, "an HSR-RobotCali (D1) file")
    values, rows, excluded = numeric_columns(header, body, HSR_COLUMNS, path, exclude_bad_rows=exclude_bad_rows)
    return Dataset(
        q=np.radians(values[:, :6]),
        y=values[:, 6],
        measurement="cable",
        robot="hsr-jr680",
        rows=rows,
        source=str(path),
        excluded=excluded,
        notes=notes + _ignored_note(header, HSR_COLUMNS) + excluded_notes(excluded),
    )


def read_robotcali(path, sheet: Optional[str] = None, exclude_bad_rows: bool = False) -> Dataset:
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

    Returns
    -------
    Dataset
        ``robot="abb-irb120"``, ``measurement="cable"``; ``extra["controller_xyz"]`` (m, 3) holds
        the controller's x, y, z for the cross-check in :func:`robocal.inspection.inspect`.
    """
    header, body, notes = _read_table(path, sheet)
    _check_joint_columns(header, 6, "abb-irb120", path)
    require_columns(header, ROBOTCALI_COLUMNS, path, "a RobotCali (D2) file")
    values, rows, excluded = numeric_columns(header, body, ROBOTCALI_COLUMNS, path, exclude_bad_rows=exclude_bad_rows)
    return Dataset(
        q=np.radians(values[:, 3:9]),
        y=values[:, 9],
        measurement="cable",
        robot="abb-irb120",
        rows=rows,
        source=str(path),
        excluded=excluded,
        notes=notes + _ignored_note(header, ROBOTCALI_COLUMNS) + excluded_notes(excluded),
        extra={"controller_xyz": values[:, :3]},
    )


# -- D3: laser tracker ----------------------------------------------------------------------------
def _quaternions(euler_deg: np.ndarray) -> np.ndarray:
    """Unit quaternions ``w, x, y, z`` (w >= 0) of intrinsic XYZ Euler angles in degrees."""
    from scipy.spatial.transform import Rotation

    xyzw = Rotation.from_euler("XYZ", euler_deg, degrees=True).as_quat()
    wxyz = np.column_stack([xyzw[:, 3], xyzw[:, :3]])
    return wxyz * np.where(wxyz[:, :1] < 0, -1.0, 1.0)


def _clock(stamps: list[str]) -> Optional[np.ndarray]:
    """``datetime.strptime(s, "%Y%m%d%H%M%S").timestamp()`` of every stamp, without parsing
    each: the fields by array arithmetic, the local UTC offset once per distinct minute (time
    zone changes fall on whole minutes). None unless every stamp is 14 ASCII digits with each
    field in its two-digit range (then strptime reads exactly those fields) and a real date."""
    if not stamps or {len(s) for s in stamps} != {14}:
        return None
    joined = "".join(stamps)
    if not (joined.isascii() and joined.isdigit()):
        return None
    d = np.frombuffer(joined.encode(), dtype=np.uint8).reshape(-1, 14).astype(np.int64) - 48
    two = lambda k: 10 * d[:, k] + d[:, k + 1]  # noqa: E731
    year, month, day, hour, minute, second = 100 * two(0) + two(2), two(4), two(6), two(8), two(10), two(12)
    if not ((year >= 1) & (month >= 1) & (month <= 12) & (day >= 1) & (day <= 31) & (hour <= 23) & (minute <= 59) & (second <= 59)).all():
        return None
    minutes, index = np.unique(((year * 100 + month) * 100 + day) * 10000 + hour * 100 + minute, return_inverse=True)
    start = np.empty(len(minutes))
    for k, key in enumerate(minutes.tolist()):
        try:
            start[k] = datetime(key // 10**8, key // 10**6 % 100, key // 10**4 % 100, key // 100 % 100, key % 100).timestamp()
        except ValueError:  # 31 April, 29 February of a common year
            return None
    return start[index.ravel()] + second


def _timestamps(stamps: list[str], rows: np.ndarray, path):
    """``(t, notes)`` from the ``Timestamp`` cells: seconds since the earliest sample when every
    stamp is ``yyyymmddHHMMSS``; ``None`` with an explanatory note otherwise."""
    clock = _clock(stamps)
    if clock is not None or all(re.fullmatch(r"\d{14}", s) for s in stamps):
        if clock is None:  # a field out of range somewhere: strptime stamp by stamp names the row
            clock = []
            for s, row in zip(stamps, rows):
                try:
                    clock.append(datetime.strptime(s, "%Y%m%d%H%M%S").timestamp())
                except ValueError:
                    raise DataError(f"expected a time yyyymmddHHMMSS; got {s!r}", path, int(row), "Timestamp") from None
        t = np.array(clock) - min(clock)
        return t, time_order_notes(t, rows, path)
    if all(re.fullmatch(r"[-+]?\d+([.,]\d*)?[eE][-+]?\d+", s) for s in stamps):
        return None, [
            f"Timestamp is in a lossy scientific notation (e.g. {stamps[0]!r}; {len(set(stamps))} distinct value(s) over "
            f"{len(stamps)} rows): not usable as a clock, `t` left unset; row order is the only ordering"
        ]
    example = next(s for s in stamps if not re.fullmatch(r"\d{14}", s))
    return None, [f"Timestamp is not yyyymmddHHMMSS throughout (e.g. {example!r}): not used, `t` left unset"]


def read_ipa(path, measurement: str = "pose", exclude_bad_rows: bool = False) -> Dataset:
    """Reads D3, ipa-robot-accuracy (UR10, laser tracker): a ``Series_*/measurements_*.csv``.

    The files are ``;``-separated with decimal commas. Joints in rad; ``measurement_x/y/z`` in
    mm (tracker frame); ``measurement_rx/ry/rz`` in deg, intrinsic XYZ Euler angles of the T-Mac,
    converted to a unit quaternion ``w, x, y, z``; ``measurement_temperature`` (deg C) becomes
    ``temp``; ``Timestamp`` becomes ``t`` (s since the earliest sample) where it is a real
    ``yyyymmddHHMMSS`` clock (Series A), and is reported in the notes where it was exported in
    a lossy scientific notation (Series B and C).

    Parameters
    ----------
    path : str or Path
    measurement : {"pose", "position"}
        Read the full pose, or only the position.
    exclude_bad_rows : bool
        Record rows with a bad cell in ``Dataset.excluded`` instead of raising.

    Returns
    -------
    Dataset
        ``robot="ur10"``. ``extra["goal_pose"]`` (m, 6): the commanded flange pose in the robot
        base frame, x, y, z in mm and roll, pitch, yaw in rad; ``extra["measurement_std"]``
        (m, 6) where the file has it: standard deviations of x, y, z (mm) and rx, ry, rz (deg).
    """
    if measurement not in ("pose", "position"):
        raise DataError(f"`measurement` must be 'pose' or 'position' for tracker data; got {measurement!r}", path)
    header, body, _ = _read_table(path, delimiter=";")
    obs = IPA_POSITION + (IPA_EULER if measurement == "pose" else [])
    require_columns(header, IPA_JOINTS + obs, path, f"an ipa-robot-accuracy (D3) {measurement} file")
    optional = [c for c in ["measurement_temperature"] + IPA_GOAL + IPA_STD if c in header]
    wanted = IPA_JOINTS + obs + optional
    values, rows, excluded = numeric_columns(
        header, body, wanted, path, decimal_comma=True, allow_nonfinite=["measurement_temperature"], exclude_bad_rows=exclude_bad_rows
    )
    column = dict(zip(wanted, values.T))
    y = values[:, 6:9]
    if measurement == "pose":
        y = np.hstack([y, _quaternions(values[:, 9:12])])
    notes, t = [], None
    if "Timestamp" in header:
        stamps = text_column(body, header.index("Timestamp"), rows)
        t, notes = _timestamps(stamps, rows, path)
    extra = {}
    if all(c in column for c in IPA_GOAL):
        goal = np.column_stack([column[c] for c in IPA_GOAL])
        goal[:, :3] *= 1000.0
        extra["goal_pose"] = goal
    if all(c in column for c in IPA_STD):
        extra["measurement_std"] = np.column_stack([column[c] for c in IPA_STD])
    used = IPA_JOINTS + obs + optional + ["Timestamp"]
    return Dataset(
        q=values[:, :6],
        y=y,
        measurement=measurement,
        robot="ur10",
        t=t,
        temp=column.get("measurement_temperature"),
        rows=rows,
        source=str(path),
        excluded=excluded,
        notes=notes + _ignored_note(header, used) + excluded_notes(excluded),
        extra=extra,
    )


# -- detection and load ---------------------------------------------------------------------------
def _header_fields(first: str, sep: str) -> list[str]:
    """The names of a header line split at ``sep`` as CSV (quoted names are valid CSV); a line
    csv cannot split (a field beyond its size limit: a header of another separator) as plain text."""
    try:
        return [c.strip() for c in next(csv.reader([first], delimiter=sep), [])]
    except csv.Error:
        return [c.strip() for c in first.split(sep)]


def detect_format(path) -> str:
    """The format of ``path`` judged by its content: ``"hsr"``, ``"robotcali"``, ``"ipa"`` or
    ``"canonical"``.

    An .xlsx signature with the D1 or D2 header; a ``;``-separated header with the D3 joint and
    measurement columns; a comma-separated header ``x,y,z,q1..q6,L`` (D2's layout); any other
    comma-separated header with ``q1..qN`` columns (canonical; the CSV copy of D1 is one).

    Raises
    ------
    DataError
        Saying what was found when the content matches no format.
    """
    path = Path(path)
    if _signature(path) == XLSX_SIGNATURE:
        header, _, _ = _read_xlsx(path)
        if all(c in header for c in ROBOTCALI_COLUMNS):
            return "robotcali"
        if all(c in header for c in HSR_COLUMNS):
            return "hsr"
        raise DataError(f"an .xlsx workbook whose first sheet's header {header} is neither D1 ({HSR_COLUMNS}) nor D2 ({ROBOTCALI_COLUMNS})", path, 1)
    text = read_text(path)
    first = _FIRST_LINE.match(text).group() if text.strip() else ""
    if not first.strip():
        raise DataError("the file is empty (a header row is expected)", path, 1)
    fields = {sep: _header_fields(first, sep) for sep in (";", ",", "\t")}
    if "shoulder_pan_joint" in fields[";"] or "measurement_x" in fields[";"]:
        return "ipa"
    if fields[","] == ROBOTCALI_COLUMNS:
        return "robotcali"
    if any(re.fullmatch(r"q\d+", c) for c in fields[","]):
        return "canonical"
    expected = (
        "expected a canonical header with q1..qN columns, the D2 header x,y,z,q1..q6,L, the D3 ';'-separated tracker columns, or an .xlsx workbook of D1/D2"
    )
    if first.lstrip().startswith("#"):
        seen = f"the first line is a comment ({shown(first.strip())}): the header must be the first line; remove the comment lines"
    elif len(tabbed := fields["\t"]) > max(len(fields[","]), len(fields[";"])):
        seen = f"the first line is tab-separated ({len(tabbed)} fields {tabbed[:8]}): canonical files are comma-separated"
    else:
        seps = max((";", ","), key=lambda s: len(fields[s]))
        seen = f"the first line has {len(fields[seps])} {seps!r}-separated field(s) {fields[seps][:8]}"
    raise DataError(f"unknown format: {seen}; {expected}", path, 1)


def _check_robot(dataset: Dataset, fmt: str, robot, path) -> Dataset:
    """Records ``robot`` (a name or file) in ``dataset`` after checking it matches the file; a
    :class:`~robocal.robot.Robot` is checked for its joint count only, and the robot the data
    name is kept (:func:`robocal.calibration.api.load_inputs` compares the two)."""
    if robot is None:
        return dataset
    from ..catalog import BUILTIN
    from ..robot import Robot
    from ..robot import robot as load_robot

    native = FORMAT_ROBOT.get(fmt)
    if native and isinstance(robot, str) and robot in BUILTIN and robot != native:
        raise DataError(f"this is {fmt} data of the {native}; got robot={robot!r}", path)
    model = robot if isinstance(robot, Robot) else load_robot(robot)
    name = model.name if isinstance(robot, Robot) else robot
    if model.n_joints != dataset.n_joints:
        raise DataError(f"robot {name!r} has {model.n_joints} joints; the file has {dataset.n_joints} joint columns", path, 1)
    if not isinstance(robot, Robot):
        dataset.robot = robot
    return dataset


def _prismatic(robot) -> tuple:
    """The prismatic joints of ``robot`` (a name or file, a Robot, or None: none known)."""
    from ..robot import Robot
    from ..robot import robot as load_robot

    if robot is None:
        return ()
    return (robot if isinstance(robot, Robot) else load_robot(robot)).prismatic


def load(
    path,
    *,
    format: Optional[str] = None,
    measurement: Optional[str] = None,
    angle_unit: Optional[str] = None,
    robot=None,
    exclude_bad_rows: bool = False,
    sheet: Optional[str] = None,
    check_units: bool = True,
) -> Dataset:
    """Reads a measurement file of any supported format into a :class:`Dataset`.

    Parameters
    ----------
    path : str, Path or pandas.DataFrame
        A file, or a DataFrame with the canonical columns (read by
        :func:`~robocal.data.frame.read_frame` as the CSV with the same content; rows are its
        positions, 0-based; ``robot`` and ``angle_unit`` default to ``frame.attrs``, where
        :meth:`Dataset.to_frame` records them).
    format : {"canonical", "hsr", "robotcali", "ipa"}, optional
        Detected from the content by default (:func:`detect_format`).
    measurement : {"cable", "position", "pose"}, optional
        Canonical: detected from the header by default. ipa: ``"pose"`` (default) or
        ``"position"``. hsr / robotcali: ``"cable"`` only.
    angle_unit : {"deg", "rad"}, optional
        Unit of canonical ``q`` columns (``"deg"`` by default). The public formats have fixed
        units (D1, D2 deg; D3 rad): a contradicting value is an error.
    robot : str or Robot, optional
        Built-in robot name or robot file, checked against the file (the public formats belong to
        one robot each; the joint count must match), or a :class:`~robocal.robot.Robot` (joint
        count checked). Its prismatic joints' columns are read as mm: without a robot, every
        joint column is an angle.
    exclude_bad_rows : bool
        Record rows with a bad cell in ``Dataset.excluded`` instead of raising.
    sheet : str, optional
        Worksheet of an .xlsx workbook (first by default).
    check_units : bool
        Refuse joint values implausible for the unit they are read in
        (:func:`~robocal.data.dataset.angle_unit_check`: radians in a degree file, degrees read
        as radians) with an error naming the columns and the likely unit — unless ``angle_unit``
        was given explicitly, which records the finding in ``Dataset.notes`` instead.

    Raises
    ------
    DataError
        On an unknown format, a mismatching robot, measurement or unit, implausible joint
        values for the unit, or any bad content.
    """
    frame = is_frame(path)
    if not frame and not isinstance(path, (str, os.PathLike)):
        raise DataError(f"`path` must be a file path (str or Path) or a pandas DataFrame; got {type(path).__name__} {shown(path)}")
    source, path = (path, FRAME) if frame else (None, Path(path))
    if format is not None and format not in FORMATS:
        raise DataError(f"`format` must be one of {FORMATS}; got {format!r}", path)
    if frame:  # what Dataset.to_frame recorded, unless given
        robot = robot if robot is not None else source.attrs.get("robot")
        angle_unit = angle_unit if angle_unit is not None else source.attrs.get("angle_unit")
    if angle_unit is not None and angle_unit not in ANGLE_UNITS:
        raise DataError(f"`angle_unit` must be one of {ANGLE_UNITS}; got {angle_unit!r}", path)
    if measurement is not None and (not isinstance(measurement, str) or measurement not in OBSERVATION_COLUMNS):
        raise DataError(f"`measurement` must be one of {tuple(OBSERVATION_COLUMNS)}; got {measurement!r}", path)
    if frame and format not in (None, "canonical"):
        raise DataError(f"a DataFrame is read as a canonical table; got format={format!r}", path)
    fmt = "canonical" if frame else format or detect_format(path)
    native_unit = {"hsr": "deg", "robotcali": "deg", "ipa": "rad"}.get(fmt)
    if native_unit and angle_unit not in (None, native_unit):
        raise DataError(f"{fmt} files give joint angles in {native_unit}; got angle_unit={angle_unit!r}", path)
    if fmt in ("hsr", "robotcali") and measurement not in (None, "cable"):
        raise DataError(f"{fmt} files hold cable measurements; got measurement={measurement!r}", path)
    if fmt == "canonical":
        read = read_frame if frame else read_canonical
        dataset = read(source if frame else path, angle_unit or "deg", measurement, None, exclude_bad_rows, prismatic=_prismatic(robot))
        if sheet is not None:
            raise DataError(f"`sheet` applies to .xlsx workbooks; got sheet={sheet!r}", path)
    elif fmt == "hsr":
        dataset = read_hsr(path, exclude_bad_rows)
    elif fmt == "robotcali":
        dataset = read_robotcali(path, sheet, exclude_bad_rows)
    else:
        dataset = read_ipa(path, measurement or "pose", exclude_bad_rows)
    if check_units and len(dataset.prismatic) < dataset.n_joints:
        unit = angle_unit or native_unit or "deg"
        check = angle_unit_check(dataset.q, unit, dataset.rows, dataset.prismatic)
        if not check["plausible"] and angle_unit is None:
            read_as = (
                f"read them as {check['likely']} with angle_unit={check['likely']!r} (--angle-unit {check['likely']}), or "
                if check["likely"] != unit
                else "or "
            )
            raise DataError(f"{check['message']}; {read_as}confirm {unit} with angle_unit={unit!r} (--angle-unit {unit})", path)
        if not check["plausible"]:
            dataset.notes.append(f"{check['message']} (kept in {unit} as asked)")
    logger.info(
        "load: %s read as %s, %d %s samples (%d rows excluded)", dataset.source or "a DataFrame", fmt, len(dataset), dataset.measurement, len(dataset.excluded)
    )
    for note in dataset.notes:
        logger.debug("load: %s", note)
    return _check_robot(dataset, fmt, robot, path)
