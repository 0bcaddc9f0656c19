"""The in-memory dataset every reader produces and every calibrator consumes."""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace
from typing import Optional

import numpy as np

from ..kernels import as_float_array
from ..exceptions import InvalidParameterError, ShapeError

logger = logging.getLogger(__name__)

#: Observation columns per measurement type, in order (mm; pose adds a unit quaternion).
OBSERVATION_COLUMNS = {
    "cable": ("L",),
    "position": ("x", "y", "z"),
    "pose": ("x", "y", "z", "qw", "qx", "qy", "qz"),
}


#: Units of the joint columns of canonical tables (files and DataFrames).
ANGLE_UNITS = ("deg", "rad")
#: Columns of a canonical table beside ``q1..qN`` and the observations.
OPTIONAL_COLUMNS = ("t", "temp", "sample")


def require_pandas(what: str):
    """The pandas module, or an ImportError saying which feature needs it (pandas is optional)."""
    try:
        import pandas
    except ImportError:
        raise ImportError(f"{what} needs pandas, an optional dependency: pip install pandas") from None
    return pandas


#: |q| above this (rad) cannot be a joint angle in rad: the unit is probably deg.
MAX_PLAUSIBLE_RAD = 4 * math.pi


#: A degree file's rows or columns whose values all stay within ±2π, while the rest of the file
#: reaches beyond this (deg), are radians written into it (random poses of a 6-axis arm put every
#: joint within ±6.3° almost never; a joint that varies but stays within ±6.3° while the others
#: sweep tens of degrees is a column converted in one place and not in another).
PARTIAL_RADIANS_CONTRAST_DEG = 20.0
#: Such rows also come by chance, as often as every joint is within ±2π at once (one row in 9 of a
#: one-joint arm of ±57°, whose own simulated data were refused): they are named only when as many
#: would come by chance, the joints taken independent, with at most this probability.
PARTIAL_RADIANS_ROWS_P = 1e-6


def row_ranges(rows) -> str:
    """``[2, 3, 4, 9]`` as ``"2-4, 9"`` (the first 5 runs; ``rows`` sorted)."""
    rows = [int(r) for r in rows]
    runs, start = [], rows[0]
    for a, b in zip(rows, rows[1:] + [None]):
        if b != a + 1:
            runs.append(f"{start}-{a}" if a != start else f"{a}")
            start = b
    return ", ".join(runs[:5]) + (", ..." if len(runs) > 5 else "")


def _beyond_chance(small: int, by_joint: np.ndarray) -> bool:
    """Whether ``small`` rows with every joint within ±2π are more than independent joints
    (``by_joint``: |values|, (N, m)) give by chance (:data:`PARTIAL_RADIANS_ROWS_P`)."""
    from scipy.special import pdtrc  # Poisson upper tail; here, as the check runs on few files

    chance = by_joint.shape[1] * float(np.prod((by_joint <= 2 * math.pi).mean(axis=1)))
    return float(pdtrc(small - 1, chance)) < PARTIAL_RADIANS_ROWS_P


def _radians_in_part(values: np.ndarray, rows=None) -> str | None:
    """A message naming the rows or the columns of a degree table (``values``: |file values|,
    (m, N)) that look like radians while the rest does not, or None."""
    if len(values) < 4:
        return None
    rows = np.arange(2, len(values) + 2) if rows is None else np.asarray(rows)
    # Reduced as (N, m) rows: across the N values of each (m, N) row NumPy takes 1 ms for 20 000 rows, 40 us this way.
    by_joint = np.ascontiguousarray(values.T)
    row_max = by_joint.max(axis=0)
    small = (row_max <= 2 * math.pi) & (row_max > 0.5)  # within ±2π but not a pose at the zeros
    wide = row_max > PARTIAL_RADIANS_CONTRAST_DEG
    if small.sum() >= 2 and wide.sum() >= 2 and _beyond_chance(int(small.sum()), by_joint):
        return (
            f"rows {row_ranges(rows[small])} ({int(small.sum())} rows): every joint value within ±2 pi (at most {row_max[small].max():.4g}) "
            f"while the other rows reach {row_max[wide].max():.4g} deg: these rows look like radians in a degree table; "
            "convert them to degrees"
        )
    column_max = by_joint.max(axis=1)
    spread = column_max - by_joint.min(axis=1)
    narrow = (column_max <= 2 * math.pi) & (spread > 0.5)
    if narrow.any() and (column_max > PARTIAL_RADIANS_CONTRAST_DEG).sum() >= 2:
        columns = ", ".join(f"q{j + 1}" for j in np.flatnonzero(narrow))
        return (
            f"column(s) {columns} stay within ±2 pi (at most {column_max[narrow].max():.4g}) while the other joints reach "
            f"{column_max.max():.4g} deg: they look like radians in a degree table; convert them to degrees"
        )
    return None


def time_order_notes(t, rows, source) -> list[str]:
    """A note (and a logged warning naming ``source``) when the times ``t`` (m,) of samples in
    file ``rows`` (m,) go back somewhere, else none.

    robocal takes ``t`` as the acquisition order (drift, wander, settling and steps are fitted
    along it; a chronological split and backlash follow it): rows out of time order are read in
    time order. That is right for files merged or sorted by pose, and wrong when the rows are in
    acquisition order and ``t`` is not (a shuffled or mis-pasted column): the note names the rows
    so that a user can tell which, and correct or drop ``t``. Logged too, since not every command
    prints a reader's notes (``diagnose``).
    """
    if t is None or len(t) < 2:
        return []
    back = np.flatnonzero(np.diff(t) < 0) + 1
    if not back.size:
        return []
    listed = ", ".join(str(r) for r in np.asarray(rows)[back][:10]) + (", ..." if back.size > 10 else "")
    note = (
        f"the clock goes backwards at {back.size} rows ({listed}): file order is not acquisition order; robocal orders the samples by `t` "
        "(drift, settling, steps, backlash and chronological splits follow it); if the rows are in acquisition order, correct `t` or drop the column"
    )
    logger.warning("%s: %s", source, note)
    return [note]


def angle_unit_check(q: np.ndarray, unit: str, rows=None, prismatic: tuple = ()) -> dict:
    """Whether joint values ``q`` (m, N), read as ``unit`` and converted to rad, are plausible.

    In rad, a value beyond ``4 pi`` cannot be a joint angle; in deg, a file whose values all lie
    within ``±2 pi`` (i.e. within ±6.3 deg) almost certainly holds radians. The ``prismatic``
    joints' columns (0-based) are mm: they say nothing of the angle unit and are left out. Returns
    ``{unit, plausible, message, likely}``; ``message`` names the columns and the likely unit.
    """
    q = np.abs(np.asarray(q, dtype=np.float64))  # rad
    if prismatic and q.ndim == 2:
        q = q.copy()
        q[:, [j for j in prismatic if j < q.shape[1]]] = 0.0  # a zero column neither passes nor fails the check
    if q.size == 0:
        return {"unit": unit, "plausible": True, "likely": unit, "message": "no joint values"}
    if unit == "rad" and q.max() > MAX_PLAUSIBLE_RAD:
        columns = [f"q{j + 1}" for j in np.flatnonzero(q.max(axis=0) > MAX_PLAUSIBLE_RAD)]
        bad = (q > MAX_PLAUSIBLE_RAD).any(axis=1)
        first = f", first row {rows[bad][0]}" if rows is not None else ""
        message = f"columns {', '.join(columns)} hold |q| up to {q.max():.4g}, beyond 4 pi: the angles look like degrees ({int(bad.sum())} rows{first})"
        return {"unit": unit, "plausible": False, "likely": "deg", "message": message}
    if unit == "deg" and np.degrees(q.max()) <= 2 * math.pi and len(q) > 1:
        message = f"every joint value (columns q1..q{q.shape[1]}) is at most {np.degrees(q.max()):.4g} in size (within 2 pi): the angles look like radians"
        return {"unit": unit, "plausible": False, "likely": "rad", "message": message}
    if unit == "deg" and (partial := _radians_in_part(np.degrees(q), rows)):
        return {"unit": unit, "plausible": False, "likely": unit, "partial": True, "message": partial}
    return {"unit": unit, "plausible": True, "likely": unit, "message": f"joint values plausible in {unit} (max |q| = {np.degrees(q.max()):.4g} deg)"}


@dataclass
class Dataset:
    """Measured (or simulated) samples of one robot.

    Attributes
    ----------
    q : ndarray, shape (m, N)
        Joint values in rad (mm for prismatic joints).
    y : ndarray, shape (m, 1 | 3 | 7)
        Observations: cable length ``L`` (mm); or ``x, y, z`` (mm, measurement frame); or
        ``x, y, z, qw, qx, qy, qz``.
    measurement : {"cable", "position", "pose"}
    robot : str, optional
        Name of the robot the data belong to (a built-in name or a robot file).
    t : ndarray, shape (m,), optional
        Acquisition time in s: the acquisition order (the readers note rows out of ``t`` order,
        :func:`time_order_notes`). Without it, row order is the acquisition order.
    temp : ndarray, shape (m,), optional
        Temperature in deg C.
    rows : ndarray of int, shape (m,)
        Each sample's row in the source file (1-based, the header is row 1); for a DataFrame,
        its position in the frame (0-based, as ``frame.iloc``).
    source : str, optional
        The file the samples came from.
    excluded : list of dict
        Rows left out, each ``{"row": int, "reason": str}``: rows with a bad cell on request, rows
        of only empty cells always. Nothing is ever left out silently.
    notes : list of str
        What the reader noticed (ignored columns, degraded timestamps, ...).
    extra : dict of str to ndarray
        Side columns a source file carries beside the samples, each an array of first dimension m
        (e.g. ``controller_xyz`` of the RobotCali data). Sliced with the samples.
    prismatic : tuple of int
        Joints (0-based) that are prismatic: their ``q`` column is mm, in files too (never
        converted between degrees and radians).
    """

    q: np.ndarray
    y: np.ndarray
    measurement: str
    robot: Optional[str] = None
    t: Optional[np.ndarray] = None
    temp: Optional[np.ndarray] = None
    rows: Optional[np.ndarray] = None
    source: Optional[str] = None
    excluded: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    extra: dict = field(default_factory=dict)
    prismatic: tuple = ()

    def __post_init__(self):
        if not isinstance(self.measurement, str) or self.measurement not in OBSERVATION_COLUMNS:
            raise ShapeError(f"`measurement` must be one of {tuple(OBSERVATION_COLUMNS)}; got {self.measurement!r}")
        self.q = as_float_array(self.q, "q")
        self.y = as_float_array(self.y, "y")
        if self.y.ndim == 1:
            self.y = self.y[:, None]
        m, width = len(self.q), len(OBSERVATION_COLUMNS[self.measurement])
        if self.q.ndim != 2 or self.y.shape != (m, width):
            raise ShapeError(f"a {self.measurement} dataset needs `q` (m, N) and `y` ({m}, {width}); got {self.q.shape} and {self.y.shape}")
        for name in ("t", "temp"):
            value = getattr(self, name)
            if value is not None:
                value = np.asarray(value, dtype=np.float64)
                if value.shape != (m,):
                    raise ShapeError(f"`{name}` must have shape ({m},); got {value.shape}")
                setattr(self, name, value)
        self.rows = np.arange(2, m + 2) if self.rows is None else np.asarray(self.rows, dtype=np.int64)
        if self.rows.shape != (m,):
            raise ShapeError(f"`rows` must have shape ({m},); got {self.rows.shape}")
        self.extra = {name: np.asarray(value) for name, value in self.extra.items()}
        for name, value in self.extra.items():
            if value.ndim == 0 or len(value) != m:
                raise ShapeError(f"`extra[{name!r}]` must have first dimension {m}; got shape {value.shape}")

    def __len__(self) -> int:
        return len(self.q)

    @property
    def n_joints(self) -> int:
        return self.q.shape[1]

    def subset(self, index) -> "Dataset":
        """The samples at ``index`` (an index array or boolean mask), provenance kept."""
        idx = np.asarray(index)
        if idx.dtype == bool:
            idx = np.flatnonzero(idx)
        pick = lambda a: None if a is None else a[idx]  # noqa: E731
        extra = {k: v[idx] for k, v in self.extra.items()}
        lists = dict(excluded=list(self.excluded), notes=list(self.notes))
        return replace(self, q=self.q[idx], y=self.y[idx], t=pick(self.t), temp=pick(self.temp), rows=self.rows[idx], extra=extra, **lists)

    def canonical_columns(self, angle_unit: str = "deg") -> tuple[list[str], np.ndarray]:
        """Column names and values (m, k) of the canonical table: ``q1..qN`` in ``angle_unit``
        (prismatic joints in mm), the observation columns, then ``t`` and ``temp`` where present (docs/data-format.md)."""
        if angle_unit not in ANGLE_UNITS:
            raise InvalidParameterError(f"`angle_unit` must be one of {ANGLE_UNITS}; got {angle_unit!r}")
        q = self.q.copy()
        if angle_unit == "deg":
            revolute = [j for j in range(self.n_joints) if j not in self.prismatic]
            q[:, revolute] = np.degrees(q[:, revolute])  # a prismatic joint's column stays in mm
        columns = [f"q{i}" for i in range(1, self.n_joints + 1)] + list(OBSERVATION_COLUMNS[self.measurement])
        blocks = [q, self.y]
        for name in ("t", "temp"):
            value = getattr(self, name)
            if value is not None:
                columns.append(name)
                blocks.append(value[:, None])
        return columns, np.hstack(blocks)

    def to_frame(self, angle_unit: str = "rad"):
        """The samples as a pandas DataFrame with the canonical columns (those
        :func:`~robocal.data.write_canonical` writes; ``extra`` side columns are left out).

        ``frame.attrs`` records ``angle_unit`` and ``robot``, so that ``robocal.load(frame)``
        gives back an equal dataset (its ``rows`` become the frame's positions, 0-based).

        Parameters
        ----------
        angle_unit : {"rad", "deg"}
            Unit of the ``q`` columns: radians (exact round trip) by default; ``"deg"`` for the
            values a canonical file holds (``load`` reads the unit from ``attrs``).

        Returns
        -------
        pandas.DataFrame, shape (m, N + 1 | 3 | 7 [+ t] [+ temp])
        """
        pd = require_pandas("Dataset.to_frame")
        columns, values = self.canonical_columns(angle_unit)
        frame = pd.DataFrame(values, columns=columns)
        frame.attrs["angle_unit"] = angle_unit
        if self.robot is not None:
            frame.attrs["robot"] = self.robot
        return frame

    def __repr__(self) -> str:
        where = f" from {self.source}" if self.source else ""
        return f"Dataset({len(self)} {self.measurement} samples, {self.n_joints} joints, robot={self.robot!r}{where})"
