"""A pass of the selection as its stages hand it on (:class:`Pass`), what a pass decided for the
pass that confirms it (:class:`Decided`), and the report's records of refused causes.

The stages of :mod:`.select` (and :mod:`.outliers`, :mod:`.physical`, :mod:`.entries`) each take
the pass's state and leave it updated; the records here are how a cause enters the report's
``rejected``: refused when screened (:func:`refusal_record`) or taken back after it was accepted
(:func:`retraction`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from ..calibration.problem import Problem
from ..calibration.result import CalibrationResult
from ..causes.candidates import Candidate
from ..causes.problem import ExtendedProblem
from ..data.dataset import Dataset
from ..robot import Robot


@dataclass
class Decided:
    """What a pass of :func:`~.select._select` decided, for a second pass that only confirms it:
    the causes its forward selection accepted (in order) and the maps its map stage accepted
    (labels), the number of candidates and of maps its tests were corrected for (Bonferroni), and
    its refusals and unexplained findings (reported as they were: decided over the samples it
    had)."""

    causes: list
    maps: set
    tests: int
    map_tests: int
    rejected: list
    unexplained: list
    #: Per cause taken (label): the shapes of its joint's reading error the data could not tell
    #: from it (:func:`~.select.alike_shapes`), which a replay does not screen again.
    alike: dict = field(default_factory=dict)


@dataclass
class Baseline:
    """The geometric baseline of a pass (:func:`~.select.geometric_baseline`): its fit on the kept
    samples and held-out squared errors per fold scheme, the outliers named before any cause is in
    (and their bound, in robust sigmas), and the test of its residuals for correlation in
    acquisition order and in joint space (:func:`~.wander.residual_correlation`)."""

    fit: CalibrationResult
    cv: dict
    outliers: np.ndarray
    bound: float
    residual_test: Optional[dict]


@dataclass
class Pass:
    """One pass of the selection (:func:`~.select._select`) as its stages hand it on.

    The data, the samples kept (the baseline's outliers left out) and their fold ``schemes``,
    the geometric ``baseline``; the current ``model``, its fit ``x``, its held-out squared
    errors per fold scheme (``cv``) and fold fits (``fold_x``: where the next nonlinear re-fits
    start); and the report as far as it is written: the causes' ``effects``, the ``rejected``
    candidates and the causes' ``plots``. Each stage reads it and leaves it updated."""

    robot: Robot
    dataset: Dataset
    base: Problem
    keep: np.ndarray
    schemes: dict
    min_gain: float
    baseline: Baseline
    model: ExtendedProblem
    x: np.ndarray
    cv: dict
    fold_x: dict
    effects: list
    rejected: list
    plots: dict = field(default_factory=dict)
    #: The arcs of a wandering reading a step must beat (:func:`~.select.screen_round`), once
    #: built: ``{"fine": [...], "slow": [...]}``.
    arcs: Optional[dict] = None

    @property
    def k(self) -> int:
        """Residual rows per sample."""
        return self.model.k

    def problem(self, causes: list) -> ExtendedProblem:
        """The model of ``causes`` on the kept samples."""
        return ExtendedProblem(self.base, causes, self.dataset, self.keep)

    def retract(self, c: Candidate, physical, reason: str) -> None:
        """The accepted cause ``c`` out of the report, into the rejected with ``reason``
        (:func:`retraction`)."""
        self.rejected.append(retraction(c, self.effects, self.plots, physical, reason))


def retraction(c: Candidate, effects: list, plots: dict, physical, reason: str) -> dict:
    """Takes the accepted cause ``c`` out of the report's ``effects`` (and its plot) and returns
    its rejection record: its screening figures, ``physical`` (default: those it was accepted
    with) and ``reason``."""
    found = next(e for e in effects if e["label"] == c.label)
    effects.remove(found)
    plots.pop(c.label, None)
    sig = found["significance"]
    screening = sig.get("screening_gain_mm") or {}  # none for a cause merged in or put in another's place
    params = found["params"] if physical is None else physical
    return refusal_record(c, screening.get("random"), screening or None, sig.get("p_value"), sig.get("candidates") or 1, params, reason)


def refusal_record(c: Candidate, gain: float, gains: dict, p_value: float, n_tests: int, physical, reason: str) -> dict:
    return {
        "kind": c.kind,
        "joint": None if c.joint is None else c.joint + 1,
        "label": c.label,
        "gain_mm": gain,
        "gains_mm": gains,
        "p_value": p_value,
        "p_adjusted": None if p_value is None else min(1.0, p_value * n_tests),
        "params": physical,
        "reason": reason,
    }
