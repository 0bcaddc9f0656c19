"""A joint map's coverage: a map asks for a pose every knot spacing along its joint's range
(:func:`map_bins`); the poses the data and a result's training data leave uncovered are required
first (:func:`_required`), each the best by the D-criterion in its bin (:func:`_coverage`) —
unless that takes more poses than planned: then the criterion places every pose."""

from __future__ import annotations

import math
from typing import Optional

import numpy as np

from ..causes.candidates import map_coverage
from ..physics import DEG
from .criteria import _blocks, _gains, _update, _whitened
from .design import _Design


def map_bins(q: np.ndarray, lower: float, upper: float, spacing: float) -> np.ndarray:
    """Bin (0-based) of each angle ``q`` (rad) in ``lower..upper`` cut into bins of ``spacing``
    (rad): a pose in every bin leaves no stretch longer than two spacings without one (what a
    joint map needs, :data:`~robocal.causes.candidates.MAP_GAP_SPACINGS`)."""
    bins = max(1, int(math.ceil((upper - lower) / spacing - 1e-9)))
    return np.clip(((q - lower) / spacing).astype(int), 0, bins - 1)


def _coverage(A: np.ndarray, M0: np.ndarray, bins: list[np.ndarray], covered: list[np.ndarray]) -> list[int]:
    """Candidates that put a pose in every bin no measured pose covers, each the best by the
    D-criterion among its bin's candidates (``bins``: per map, each candidate's bin;
    ``covered``: per map, the bins the data already cover)."""
    required = []
    A, Minv = _whitened(A, M0)
    S = _blocks(A, Minv)
    for bin_of, done in zip(bins, covered):
        for b in np.setdiff1d(np.unique(bin_of), done):
            members = np.flatnonzero(bin_of == b)
            members = members[~np.isin(members, required)]
            if not members.size:
                continue
            i = int(members[np.argmax(_gains(S[members]))])
            required.append(i)
            Minv, S = _update(A, Minv, S, i, 1.0)
    return required


def _required(design: _Design, A: np.ndarray, pool: np.ndarray, seen: Optional[np.ndarray], start: np.ndarray, poses: int, notes: list) -> list[int]:
    """Candidates (of ``A``, ``pool``) that put a pose in every knot spacing of a joint map's range that no pose
    already measured (``seen``: the data's and a result's training angles, model's) covers
    (:func:`_coverage`) — if that takes at most ``poses``; else none, and a note: the criterion
    then places every pose (filling the first maps' bins and none of the others' is worse). A
    result's map has no bins beyond its range or in the gaps of its data: it has no
    coefficients there."""
    bins, covered = [], []
    for c in design.causes:
        if c.kind == "joint_map":
            span = (float(c.detail["lo"]) * DEG, float(c.detail["hi"]) * DEG, float(c.detail["spacing"]) * DEG)
            b = map_bins(pool[:, c.joint], *span)
            bins.append(np.where(map_coverage(pool[:, c.joint], c.detail), b, -1) if c.label in design.fitted else b)
            covered.append(np.unique(np.concatenate([[-1], [] if seen is None else map_bins(seen[:, c.joint], *span)])))
    needed = sum(np.setdiff1d(b, done).size for b, done in zip(bins, covered))
    if needed > poses:
        notes.append(
            f"a pose every knot spacing along the joint maps' ranges would take {needed} poses, more than the {poses} planned: the criterion places "
            "them all, and a map's correction fades out within a few knot spacings where its joint's range is left without poses"
        )
        return []
    return _coverage(A, start, bins, covered) if needed else []
