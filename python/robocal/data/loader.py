"""The dispatcher: :func:`load` recognises a file's format by its content (:func:`detect_format`)
and calls the reader of that format in :mod:`robocal.data.formats`, then checks the result against
the robot and the units asked for.

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
import logging
import os
import re
from pathlib import Path
from typing import Optional, Union

from ..exceptions import DataError
from .dataset import ANGLE_UNITS, OBSERVATION_COLUMNS, Dataset, angle_unit_check
from .formats.cable import HSR_COLUMNS, ROBOTCALI_COLUMNS, read_hsr, read_robotcali
from .formats.canonical import read_canonical
from .formats.frame import SOURCE as FRAME
from .formats.frame import is_frame, read_frame
from .formats.ipa import read_ipa
from .table import Table, is_workbook, read_delimited, read_table, read_text, shown

logger = logging.getLogger(__name__)

FORMATS = ("canonical", "hsr", "robotcali", "ipa")
#: The robot each public format belongs to.
FORMAT_ROBOT = {"hsr": "hsr-jr680", "robotcali": "abb-irb120", "ipa": "ur10"}

#: ``text.splitlines()[0]`` without splitting the rest: everything up to a line boundary.
_FIRST_LINE = re.compile("[^\n\r\x0b\x0c\x1c-\x1e\x85\u2028\u2029]*")


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
    return _detect(Path(path))[0]


def _detect(path: Path) -> tuple[str, Union[Table, str]]:
    """:func:`detect_format`'s answer and what it read to give it, for the reader not to read
    the file again: a workbook's first sheet as a :class:`Table`, a text file's text."""
    if is_workbook(path):
        table = read_table(path)
        header = table.header
        if all(c in header for c in ROBOTCALI_COLUMNS):
            return "robotcali", table
        if all(c in header for c in HSR_COLUMNS):
            return "hsr", table
        raise DataError(f"an .xlsx workbook whose first sheet's header {header} is neither D1 ({HSR_COLUMNS}) nor D2 ({ROBOTCALI_COLUMNS})", path, 1)
    text = read_text(path)
    first = _FIRST_LINE.match(text).group() if text.strip() else ""
    if not first.strip():
        raise DataError("the file is empty (a header row is expected)", path, 1)
    fields = {sep: _header_fields(first, sep) for sep in (";", ",", "\t")}
    if "shoulder_pan_joint" in fields[";"] or "measurement_x" in fields[";"]:
        return "ipa", text
    if fields[","] == ROBOTCALI_COLUMNS:
        return "robotcali", text
    if any(re.fullmatch(r"q\d+", c) for c in fields[","]):
        return "canonical", text
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
        :func:`~robocal.data.formats.frame.read_frame` as the CSV with the same content; rows are its
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
    fmt, content = ("canonical", None) if frame else (format, None) if format else _detect(path)
    native_unit = {"hsr": "deg", "robotcali": "deg", "ipa": "rad"}.get(fmt)
    if native_unit and angle_unit not in (None, native_unit):
        raise DataError(f"{fmt} files give joint angles in {native_unit}; got angle_unit={angle_unit!r}", path)
    if fmt in ("hsr", "robotcali") and measurement not in (None, "cable"):
        raise DataError(f"{fmt} files hold cable measurements; got measurement={measurement!r}", path)
    # What detection read (a workbook's first sheet, a text) serves the reader, unless it is to read another sheet.
    table = content if isinstance(content, Table) and sheet is None else None
    if isinstance(content, str) and sheet is None:
        table = read_delimited(path, ";" if fmt == "ipa" else ",", content)
    if frame:
        dataset = read_frame(source, angle_unit or "deg", measurement, None, exclude_bad_rows, prismatic=_prismatic(robot))
    elif fmt == "canonical":
        dataset = read_canonical(path, angle_unit or "deg", measurement, None, exclude_bad_rows, prismatic=_prismatic(robot), table=table)
    elif fmt == "hsr":
        dataset = read_hsr(path, exclude_bad_rows, table=table)
    elif fmt == "robotcali":
        dataset = read_robotcali(path, sheet, exclude_bad_rows, table=table)
    else:
        dataset = read_ipa(path, measurement or "pose", exclude_bad_rows, table=table)
    if fmt == "canonical" and sheet is not None:
        raise DataError(f"`sheet` applies to .xlsx workbooks; got sheet={sheet!r}", path)
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
