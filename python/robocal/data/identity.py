"""Which samples are the same samples, from their content: not from a file's bytes, name or order.

A held-out figure is honest only if the fit saw none of its samples. A file's SHA-256 recognises
only that file byte for byte: the same samples with other line ends, a BOM, reordered columns,
rows shuffled, ``t`` dropped, or a reading moved by 1e-9 mm are other bytes. Here a sample is
recognised by its joint values (rounded to :data:`JOINT_GRID`, the joints' repeatability: the
tolerance of :data:`~robocal.data.splits.CONFIGURATION_TOLERANCE`) and its readings (rounded to
:data:`READING_GRID`, far below any sensor's noise: a copy, not a second measurement of the same
pose, which differs by the noise). Each sample gets a 64-bit key of those rounded values; a set of
samples is the set of its keys, whatever their order.

Two sets are the same samples when half or more of one's samples are among the other's
(:data:`SAME_SHARE`): a copy in any order or encoding, with rows added, removed or edited. A
few shared samples can be chance (a pose revisited with a reading that the sensor's resolution
rounds to the same value) and are said, not refused.

The one test serves both places that ask: two sessions of a multi-session fit
(:func:`require_distinct_sessions`, for ``calibrate`` and ``diagnose``) and ``verify``, against the
:class:`Fingerprint` a result records of its training samples (its ``dataset`` and each of its
``sessions``): the keys themselves, at most :data:`MAX_KEYS` of them (the smallest, a bottom-k
sketch: a sample whose key is at most the largest kept is checked exactly; beyond that count the
share is estimated from those samples).
"""

from __future__ import annotations

import base64
import logging
import os
from dataclasses import dataclass
from typing import Optional

import numpy as np

from ..exceptions import InvalidParameterError
from .dataset import Dataset, row_ranges
from .splits import CONFIGURATION_TOLERANCE

logger = logging.getLogger(__name__)

#: Joint values (rad; mm for a prismatic joint) are compared on this grid: the joints' repeatability.
JOINT_GRID = CONFIGURATION_TOLERANCE
#: Readings (mm; a quaternion's components) are compared on this grid: far below any sensor's noise
#: (a second measurement differs by it), far above the rounding of a rewritten file (1e-13 mm).
READING_GRID = 1e-6
#: Two sets of samples are one when at least this share of either is in the other.
SAME_SHARE = 0.5
#: A result records at most this many keys of its training samples (128 kB in the file).
MAX_KEYS = 1 << 14
SCHEME = "robocal.samples/1"

_U64 = np.uint64


def _mix(x: np.ndarray) -> np.ndarray:
    """splitmix64's finaliser: a bijection of uint64 that spreads every input bit (wrapping arithmetic)."""
    x = (x ^ (x >> _U64(30))) * _U64(0xBF58476D1CE4E5B9)
    x = (x ^ (x >> _U64(27))) * _U64(0x94D049BB133111EB)
    return x ^ (x >> _U64(31))


def sample_keys(q, y, joint_grid: float = JOINT_GRID, reading_grid: float = READING_GRID) -> np.ndarray:
    """A 64-bit key per sample (uint64, shape (m,)) of its joint values ``q`` (m, N) and readings
    ``y`` (m, k), rounded to the grids: equal keys are the same sample (but for a collision,
    2^-64 a pair)."""
    q, y = np.asarray(q, dtype=np.float64), np.asarray(y, dtype=np.float64).reshape(len(q), -1)
    # Rounded to the nearest grid point: a reading written with few decimals (1683.92) sits on a
    # grid point of 1e-6 mm, far from the boundaries where a 1e-9 mm change would move it.
    cells = np.hstack([np.rint(q / joint_grid), np.rint(y / reading_grid)]).astype(np.int64)  # |values| <= 1e12: within int64
    h = np.full(len(q), _U64(cells.shape[1]), dtype=np.uint64)
    with np.errstate(over="ignore"):
        for column in cells.T:
            h = _mix(h ^ _mix(column.view(np.uint64)))
    return h


@dataclass(frozen=True)
class Fingerprint:
    """The keys (:func:`sample_keys`) of a set of samples, order-free: sorted, unique, the
    smallest :data:`MAX_KEYS` when ``complete`` is False."""

    keys: np.ndarray
    samples: int
    complete: bool = True
    joint_grid: float = JOINT_GRID
    reading_grid: float = READING_GRID

    @classmethod
    def of(cls, dataset: Dataset, limit: Optional[int] = None) -> "Fingerprint":
        """The fingerprint of ``dataset``'s samples (at most ``limit`` keys, the smallest)."""
        keys = np.unique(sample_keys(dataset.q, dataset.y))
        complete = limit is None or len(keys) <= limit
        return cls(keys if complete else keys[:limit], len(dataset), complete)

    def to_dict(self) -> dict:
        """The form a result file records (the keys as base64 of little-endian uint64)."""
        return {
            "scheme": SCHEME,
            "samples": int(self.samples),
            "complete": bool(self.complete),
            "joint_grid": self.joint_grid,
            "reading_grid": self.reading_grid,
            "keys": base64.b64encode(self.keys.astype("<u8").tobytes()).decode("ascii"),
        }

    @classmethod
    def from_dict(cls, doc) -> Optional["Fingerprint"]:
        """The fingerprint a result records, or None where it has none or one of another scheme (a
        file written before robocal recorded it, or edited: the caller falls back to what it has)."""
        if not isinstance(doc, dict) or doc.get("scheme") != SCHEME:
            return None
        try:
            keys = np.frombuffer(base64.b64decode(doc["keys"], validate=True), dtype="<u8").astype(np.uint64)
            grids = float(doc["joint_grid"]), float(doc["reading_grid"])
            samples, complete = int(doc["samples"]), bool(doc["complete"])
        except (KeyError, TypeError, ValueError):
            return None
        if not all(np.isfinite(g) and g > 0 for g in grids):
            return None
        return cls(np.unique(keys), samples, complete, *grids)

    def overlap(self, dataset: Dataset) -> "Overlap":
        """Which of ``dataset``'s samples are among this fingerprint's."""
        keys = sample_keys(dataset.q, dataset.y, self.joint_grid, self.reading_grid)
        checked = np.ones(len(keys), dtype=bool) if self.complete else keys <= (self.keys[-1] if len(self.keys) else _U64(0))
        return Overlap(np.isin(keys, self.keys) & checked, checked)


@dataclass(frozen=True)
class Overlap:
    """Of a dataset's samples, those found among a fingerprint's (``shared``) and those that could
    be looked up (``checked``: all, unless the fingerprint is a sketch of a larger set)."""

    shared: np.ndarray
    checked: np.ndarray

    @property
    def share(self) -> float:
        """The share of the dataset's samples that are among the fingerprint's (estimated from the
        checked ones; 0 when none could be)."""
        n = int(self.checked.sum())
        return float(self.shared.sum()) / n if n else 0.0

    @property
    def count(self) -> int:
        """How many of the dataset's samples are the fingerprint's (estimated for a sketch)."""
        return int(self.shared.sum()) if self.checked.all() else round(self.share * len(self.checked))

    @property
    def same(self) -> bool:
        """Whether the dataset is the fingerprinted samples (:data:`SAME_SHARE`)."""
        return self.share >= SAME_SHARE


def require_distinct_sessions(datasets: list, what: str = "session") -> None:
    """An error naming both when two of ``datasets`` are one file (the same path, a link to it)
    or the same samples (:class:`Overlap.same`: in any order or encoding): a leave-one-session-out
    figure would then test on the data the fit saw. Fewer shared samples are logged as a warning,
    naming their rows.

    Parameters
    ----------
    datasets : list of Dataset
    what : str
        What one dataset is, for the message.
    """
    files: dict = {}
    prints = [Fingerprint.of(d) for d in datasets]
    for i, d in enumerate(datasets, start=1):
        name = d.source or "data"
        if d.source and os.path.exists(d.source):
            j = files.setdefault(os.path.realpath(d.source), i)
            if j != i:
                _refuse(what, j, datasets[j - 1], i, d, "the same file")
        for j in range(1, i):
            mine, theirs = prints[j - 1].overlap(d), prints[i - 1].overlap(datasets[j - 1])
            if mine.same or theirs.same:
                how = f"the same samples ({mine.count} of the {len(d)} samples of {what} {i} are samples of {what} {j}, in any order or encoding)"
                _refuse(what, j, datasets[j - 1], i, d, how)
            if mine.count:
                logger.warning(
                    "%s %d (%s) shares %d of its %d samples with %s %d (rows %s): same joint values and readings; "
                    "its held-out figure is in part a training error",
                    what,
                    i,
                    name,
                    mine.count,
                    len(d),
                    what,
                    j,
                    row_ranges(sorted(d.rows[mine.shared])),
                )


def _refuse(what: str, j: int, other: Dataset, i: int, d: Dataset, how: str):
    raise InvalidParameterError(
        f"{what}s {j} ({other.source or 'data'}) and {i} ({d.source or 'data'}) are {how}: a {what} held out would be one the fit saw; give each {what} once"
    )
