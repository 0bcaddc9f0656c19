"""The parameter table of a robot: one row per joint, then the base and the tool frames.

What ``robocal export --format dh|mdh`` writes (CSV, or JSON with schema
:data:`TABLE_SCHEMA`) and what :func:`robocal.robot` reads back: angles in degrees, lengths in mm,
joint limits in degrees (mm for a prismatic joint). Columns :data:`TABLE_COLUMNS`; a joint row has
the DH/MDH values and Hayati ``beta``, a frame row ``x, y, z, rx, ry, rz`` (``Tx Ty Tz Rz Ry Rx``).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Sequence

import numpy as np

from .exceptions import InvalidParameterError
from .robot_file import parse_document, read_document, read_file
from .serial_robot import Joint, Robot

TABLE_SCHEMA = "robocal.export.table/1"

JOINT_COLUMNS = ("alpha_deg", "a_mm", "d_mm", "theta_deg", "beta_deg")
FRAME_COLUMNS = ("x_mm", "y_mm", "z_mm", "rx_deg", "ry_deg", "rz_deg")
#: Columns of the parameter table, in file order.
TABLE_COLUMNS = ("frame", "kind", "convention", "hayati") + JOINT_COLUMNS + ("lower", "upper") + FRAME_COLUMNS
_ANGLE_JOINT = {"alpha_deg", "theta_deg", "beta_deg"}


def is_table(path) -> bool:
    """True for a file :func:`read_table` reads: a CSV, or a JSON document with the table's
    schema (a robot file is JSON too)."""
    path = Path(path)
    if path.suffix.lower() == ".csv":
        return True
    try:
        doc = read_document(path)
    except InvalidParameterError:
        return False  # the robot-file reader names what is wrong with it
    return isinstance(doc, dict) and doc.get("schema") == TABLE_SCHEMA


def frame_slice(robot: Robot, prefix: str) -> slice:
    """Where the base or tool frame's six parameters sit in the robot's vector."""
    start = robot.index(f"{prefix}_x")
    return slice(start, start + 6)


def _table_robot(robot: Robot, convention: str) -> Robot:
    """``robot`` in ``convention`` (``dh`` or ``mdh``), converting DH → MDH when asked."""
    if convention not in ("dh", "mdh"):
        raise InvalidParameterError(f"`convention` must be 'dh' or 'mdh'; got {convention!r}")
    have = {j.convention for j in robot.joints}
    if have == {convention}:
        return robot
    if convention == "mdh" and have == {"dh"}:
        return robot.to_mdh()
    raise InvalidParameterError(
        f"cannot export robot {robot.name!r} (joint conventions {sorted(have)}) as {convention!r}: "
        f"robocal converts standard DH to modified DH only; export it as 'urdf' or in its own convention"
    )


def export_table(robot: Robot, convention: str = "dh") -> list[dict]:
    """The robot's kinematic parameter table, one dict per row (see the module docstring).

    Parameters
    ----------
    robot : Robot
        Typically the calibrated robot of :func:`robocal.results.load_result`.
    convention : {"dh", "mdh"}
        ``mdh`` converts a standard-DH robot with :meth:`Robot.to_mdh` (exact for the tool frame).

    Returns
    -------
    list of dict
        ``N`` joint rows, then ``base`` and ``tool``; keys :data:`TABLE_COLUMNS`, ``None`` where
        a column does not apply. Angles in degrees, lengths in mm.

    Raises
    ------
    InvalidParameterError
        Unknown ``convention``, or a conversion robocal does not do (MDH → DH).
    """
    r = _table_robot(robot, convention)
    empty = dict.fromkeys(TABLE_COLUMNS)
    rows = []
    for j, joint in enumerate(r.joints, start=1):
        values = r.params[5 * (j - 1) : 5 * j]  # alpha, a, d, theta, beta
        row = dict(empty, frame=f"joint{j}", kind=joint.kind, convention=joint.convention, hayati=bool(joint.hayati))
        for col, v in zip(JOINT_COLUMNS, values):
            row[col] = math.degrees(v) if col in _ANGLE_JOINT else float(v)
        to_unit = math.degrees if joint.kind == "revolute" else float
        row["lower"], row["upper"] = (to_unit(float(v)) for v in joint.limits)
        rows.append(row)
    for prefix in ("base", "tool"):
        values = r.params[frame_slice(r, prefix)]
        row = dict(empty, frame=prefix)
        for k, (col, v) in enumerate(zip(FRAME_COLUMNS, values)):
            row[col] = math.degrees(v) if k >= 3 else float(v)
        rows.append(row)
    return rows


def read_table(path) -> list[dict]:
    """Rows of a table written by :func:`write_table` (CSV or JSON, told apart by content).

    Numbers come back as float, ``hayati`` as bool, empty cells as ``None``.
    """
    path = Path(path)
    text = read_file(path, "robocal parameter table")
    if text.lstrip().startswith("{"):
        doc = parse_document(text, str(path), "robocal parameter table")
        if not isinstance(doc, dict) or doc.get("schema") != TABLE_SCHEMA:
            raise InvalidParameterError(
                f"{path}: not a robocal parameter table (schema {TABLE_SCHEMA!r}); robocal reads a robot or result file by its suffix: name it .json"
            )
        return [dict(r) for r in doc["rows"]]
    if text.lstrip().startswith("<"):
        raise InvalidParameterError(f"{path}: holds XML (a URDF?), not a parameter table; robocal reads a robot file by its suffix: name a URDF .urdf")
    reader = csv.DictReader(text.splitlines())
    header = [h.strip() for h in reader.fieldnames or []]
    missing, unknown = [c for c in TABLE_COLUMNS if c not in header], [h for h in header if h not in TABLE_COLUMNS]
    if missing or unknown:  # a column the rows would silently lack, or one they would silently drop
        raise InvalidParameterError(
            f"{path}, row 1: not a robocal parameter table (its header is {TABLE_COLUMNS}): "
            + "; ".join(f"{what} {cols[:8]}" for what, cols in (("missing", missing), ("unknown", unknown)) if cols)
        )
    rows = []
    for i, raw in enumerate(reader, start=2):
        row = {}
        for col in TABLE_COLUMNS:
            cell = (raw.get(col) or "").strip()
            if cell == "":
                row[col] = None
            elif col in ("frame", "kind", "convention"):
                row[col] = cell
            elif col == "hayati":
                row[col] = cell.lower() in ("true", "1", "yes")
            else:
                try:
                    row[col] = float(cell)
                except ValueError:
                    raise InvalidParameterError(f"{path}, row {i}, column {col!r}: not a number: {cell!r}") from None
        rows.append(row)
    return rows


def robot_from_table(rows: Sequence[dict], name: str = "exported", source=None) -> Robot:
    """A :class:`Robot` rebuilt from table rows alone (sensor parameters at their neutral values:
    anchor 0, ``cable_offset`` 0, ``cable_scale`` 1). ``source``, the file the rows come from,
    is named in the errors.

    Raises
    ------
    InvalidParameterError
        A row lacks a value it needs, or the base / tool row is missing.
    """
    where = f"{source}: " if source is not None else ""
    joint_rows = [r for r in rows if str(r.get("frame", "")).startswith("joint")]
    frames = {r.get("frame"): r for r in rows if r.get("frame") in ("base", "tool")}
    if not joint_rows or set(frames) != {"base", "tool"}:
        raise InvalidParameterError(f"{where}a parameter table needs joint rows and one 'base' and one 'tool' row")

    def need(row, col):
        value = row.get(col)
        if value is None:
            raise InvalidParameterError(f"{where}table row {row.get('frame')!r} lacks {col!r}")
        return float(value)

    joints, values = [], []
    for row in joint_rows:
        kind = row.get("kind") or "revolute"
        to_internal = math.radians if kind == "revolute" else float
        limits = (to_internal(need(row, "lower")), to_internal(need(row, "upper")))
        joints.append(Joint(row.get("convention") or "dh", kind, bool(row.get("hayati")), limits))
        values += [math.radians(need(row, c)) if c in _ANGLE_JOINT else need(row, c) for c in JOINT_COLUMNS]
    for prefix in ("base", "tool"):
        values += [math.radians(need(frames[prefix], c)) if k >= 3 else need(frames[prefix], c) for k, c in enumerate(FRAME_COLUMNS)]
    values += [0.0, 0.0, 0.0, 0.0, 1.0]  # anchor, cable_offset, cable_scale
    return Robot(name, joints, np.array(values))
