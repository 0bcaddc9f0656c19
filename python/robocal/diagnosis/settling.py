"""Whether a diagnosis' outliers are readings taken before the arm settled.

A reading taken right after a long joint move can be off by a vibration that has not died down
(on UR10 series A, far more of the outliers than of the samples are the first reading after a
long move: docs/findings.md, D3). Such an outlier is a bad reading, not
a model error; knowing its cause tells the user to add a settling time, not to re-calibrate.
"""

from __future__ import annotations

from typing import Optional

import numpy as np
from scipy.stats import binomtest

from ..causes.candidates import acquisition_order
from ..data.dataset import Dataset

#: A joint move at least this large (deg, the largest over the joints) counts as long.
LONG_MOVE_DEG = 90.0

#: Family-wise level at which outliers are said to follow long moves more often than chance.
LEVEL = 0.01


def preceding_moves(data: Dataset) -> np.ndarray:
    """Per sample and joint, the size of the joint's move (rad) from the sample before it in
    acquisition order (0 for the first), (m, n)."""
    order = acquisition_order(data)
    moves = np.zeros_like(data.q)
    moves[order[1:]] = np.abs(np.diff(data.q[order], axis=0))
    return moves


def preceding_move_deg(data: Dataset) -> np.ndarray:
    """Per sample, the largest joint move (deg) from the sample before it in acquisition order
    (0 for the first), (m,)."""
    return np.degrees(np.max(preceding_moves(data), axis=1))


def after_long_moves(data: Dataset, outliers: np.ndarray) -> Optional[dict]:
    """How many of the ``outliers`` (sample indices) follow a long joint move, against the share
    of all samples that do, with the one-sided binomial test's p-value; ``settling`` says whether
    they do so beyond chance at :data:`LEVEL`. None if there are no outliers or no long moves."""
    long = preceding_move_deg(data) >= LONG_MOVE_DEG
    if len(outliers) == 0 or not long.any():
        return None
    hits, share = int(np.sum(long[outliers])), float(np.mean(long))
    p_value = float(binomtest(hits, len(outliers), share, alternative="greater").pvalue)
    return {
        "threshold_deg": LONG_MOVE_DEG,
        "outliers": hits,
        "of": int(len(outliers)),
        "share_of_samples": share,
        "p_value": p_value,
        "settling": p_value < LEVEL,
    }
