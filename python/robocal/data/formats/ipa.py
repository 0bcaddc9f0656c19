"""D3, ipa-robot-accuracy (UR10, laser tracker): the ``;``-separated ``Series_*/measurements_*.csv``
files with decimal commas, read from a :class:`~robocal.data.table.Table`.
"""

from __future__ import annotations

import re
from datetime import datetime
from typing import Optional

import numpy as np

from ...exceptions import DataError
from ..dataset import Dataset, time_order_notes
from ..table import Table, excluded_notes, read_table

IPA_JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]
IPA_POSITION = ["measurement_x", "measurement_y", "measurement_z"]
IPA_EULER = ["measurement_rx", "measurement_ry", "measurement_rz"]
IPA_STD = [f"measurement_std_{c}" for c in ("x", "y", "z", "rx", "ry", "rz")]
IPA_GOAL = ["Goal x", "Goal y", "Goal z", "Goal roll", "Goal pitch", "Goal yaw"]


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


def read_ipa(path, measurement: str = "pose", exclude_bad_rows: bool = False, *, table: Optional[Table] = None) -> Dataset:
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
    table : Table, optional
        The file's table (``;``-separated) where the caller has read it already
        (:func:`robocal.data.load` has, to recognise the format).

    Returns
    -------
    Dataset
        ``robot="ur10"``. ``extra["goal_pose"]`` (m, 6): the commanded flange pose in the robot
        base frame, x, y, z in mm and roll, pitch, yaw in rad; ``extra["measurement_std"]``
        (m, 6) where the file has it: standard deviations of x, y, z (mm) and rx, ry, rz (deg).
    """
    if measurement not in ("pose", "position"):
        raise DataError(f"`measurement` must be 'pose' or 'position' for tracker data; got {measurement!r}", path)
    table = read_table(path, delimiter=";") if table is None else table
    header = table.header
    obs = IPA_POSITION + (IPA_EULER if measurement == "pose" else [])
    table.require(IPA_JOINTS + obs, f"an ipa-robot-accuracy (D3) {measurement} file")
    optional = [c for c in ["measurement_temperature"] + IPA_GOAL + IPA_STD if c in header]
    wanted = IPA_JOINTS + obs + optional
    values, rows, excluded = table.numeric(wanted, decimal_comma=True, allow_nonfinite=["measurement_temperature"], exclude_bad_rows=exclude_bad_rows)
    column = dict(zip(wanted, values.T))
    y = values[:, 6:9]
    if measurement == "pose":
        y = np.hstack([y, _quaternions(values[:, 9:12])])
    notes, t = [], None
    if "Timestamp" in header:
        stamps = table.text("Timestamp", rows)
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
        notes=notes + table.ignored_note(used) + excluded_notes(excluded),
        extra=extra,
    )
