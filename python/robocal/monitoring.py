"""In-line monitoring: a calibrated robot watched sample by sample as it works.

``Monitor(result)`` takes measured samples in acquisition order (``update(q, y)``, one or a
block) and says when something changed since the calibration — a joint's zero (a collision, a
motor or encoder swap), the sensor's frame or zero (a bumped tracker, a re-zeroed cable), a slow
drift of the sensor —, when it began, how large it is, and applies it to the model, which
``result_document()`` then holds (``verify``, ``compensate`` and ``export`` take it).

The estimator
-------------
Each sample's innovation is the measured reading less the result's model (its parameters, reading
conventions and joint causes: :func:`~robocal.causes.result_model.result_model`'s model), with the
Jacobian of each change on the Rust core. A change of parameters ``θ`` (one joint's zero; the
sensor frame's translation, or the cable's zero) from sample ``τ`` on moves the innovations by
``J_t δ``; a drift by ``J_t δ (t − τ)``. The generalised likelihood ratio of each against "no
change" over the last :data:`WINDOW` samples is ``gᵀ G⁻¹ g`` with ``g = Σ_{t≥τ} J_tᵀ W e_t`` and
``G = Σ_{t≥τ} J_tᵀ W J_t`` (``W`` the readings' inverse variance), maximised over ``τ``: the
least-squares estimate of the change given where it began, its χ² evidence. The sums are kept
per sample in ring buffers: an update costs one model evaluation and a few suffix sums, and the
memory does not grow with the stream. Why a GLR rather than the paper's UKF on the parameters: a
filter tracks a drift that is there, a change detector says *that* and *when* something changed,
with a false-alarm rate one can state; the parameters it finds are then the UKF's fixed point.

False alarms
------------
Under no change each statistic is χ² with as many degrees of freedom as the change has
parameters. The threshold is the χ² quantile of ``1 / (mean_run_length · WINDOW · changes)`` —
a Bonferroni bound over every start in the window and every change — so false alarms come at
most once per ``mean_run_length`` samples (default :data:`MEAN_RUN_LENGTH`). Real innovations
are correlated in time (the model's own errors along a path, a sensor that wanders): each
statistic is divided by the larger of the innovations' long-run inflation (:class:`_LongRunVariance`:
batch means of the innovations leaving the window) and its own yardstick
(:class:`_StatisticScale`: its mean per degree of freedom over past segments), and the variance
``W⁻¹`` is the opening innovations' per reading. No alarm is raised during the opening (:data:`OPENING` samples): a
change there cannot be told from the set-up. With ``new_session`` the opening samples first
re-fit the session's set-up (as ``verify`` does).
"""

from __future__ import annotations

import logging
import math
from collections import deque
from dataclasses import dataclass, field, replace
from typing import Optional

import numpy as np
from scipy.special import chdtri, gammaincc

from .calibration.lm import levenberg_marquardt
from .calibration.problem import TOLERANCE, Problem, is_kinematic
from .causes import structure
from .causes.candidates import COMPENSABLE, joint_offsets
from .data.dataset import OBSERVATION_COLUMNS, Dataset
from .exceptions import InvalidParameterError, ShapeError
from .kernels import as_float_array
from .results import load_result
from .serial_robot import RESIDUAL_WIDTH, setup_names, zero_names

logger = logging.getLogger(__name__)

#: Samples of the ring buffers: how far back a change may have begun to be found.
WINDOW = 100
#: Samples that set the innovations' scale and correlation (and the set-up with ``new_session``).
OPENING = 200
#: Samples per batch of the long-run variance (batch means) of the innovations.
BATCH = 50
#: Batches over which the long-run variance forgets (exponential weights).
MEMORY_BATCHES = 100
#: The long-run variance is taken at its upper confidence bound: P(χ² below it) = 1 − this.
CONFIDENCE = 0.95
#: Default mean number of samples between false alarms.
MEAN_RUN_LENGTH = 100_000
#: Fewest samples after a change's start before it may be tested (one bad sample is no change).
MIN_AFTER = 3
#: Samples after a change's estimated start before it is named for good: the kinds tell apart by then.
CONFIRM = 6
#: How much less likely under no change (natural log) the named change must be than any other
#: kind, else the monitor waits for more samples (having alarmed at once, provisionally, as the
#: sensor's step when the step is among the kinds within this margin) ...
DISTINCT = 5.0
#: ... up to this many after the change's start; then it names the likelier and says what else
#: it could be.
MAX_WAIT = 25
#: A provisional alarm needs the step's statistic at this many times its threshold: it then stands
#: even if the yardstick underestimates the innovations' long-run variance by as much (the false
#: alarms over long clean cable streams came at 1.0-1.5 times their thresholds, all but one).
TOLD_AT = 2.0
#: A change is named for good only if, fitted on the first half of the samples from its start
#: on, what it leaves of the second half is within this many times what the model left before
#: it (RMS; a drift: what it leaves of all of them): else no single kind explains it, and the
#: monitor says so and opens anew. (D2's re-zero as joint 4's zero: 2.7 times over its first 15
#: samples, 1.9 fitted on all of them.) The same ratio between the opening's
#: innovations at the calibration's set-up and with it re-fitted (and against the calibration's
#: held-out error) says the sensor stands elsewhere than the calibration placed it.
FIT_RATIO = 2.0
#: Segments whose statistics, taken every SEGMENT samples from a full window, measure each change's
#: own yardstick once they have left it.
SEGMENT = BATCH
#: Samples at which each change's detection limit is stated.
LIMIT_SAMPLES = 25
#: Full windows over which the stated detection limits are the median (as long as the long-run
#: variance remembers).
LIMIT_WINDOWS = MEMORY_BATCHES * BATCH // WINDOW


@dataclass(frozen=True)
class Change:
    """A change the monitor tests for: ``kind`` (``joint_zero``, ``step``, ``drift``), the
    1-based ``joint`` of a joint's zero, and the parameters (indices into the robot's vector) it moves."""

    kind: str
    joint: Optional[int]
    columns: tuple
    names: tuple

    @property
    def ramp(self) -> bool:
        return self.kind == "drift"


@dataclass
class Alarm:
    """A change found: at stream sample ``sample`` (0-based; file ``row``), begun at ``since``,
    of ``size`` (per parameter, ``unit``), with ``evidence`` (statistic over threshold).
    ``could_be``: the other kinds within a likelihood ratio of e^:data:`DISTINCT` (``margin``: the
    log ratio to the likeliest of them). A ``provisional`` alarm is raised as soon as a change is
    seen, as the sensor's step, while other kinds explain it as well; it is not applied: the
    same change is named for good (and applied) by a later alarm."""

    sample: int
    row: Optional[int]
    since: int
    kind: str
    joint: Optional[int]
    size: list
    unit: str
    names: list
    evidence: float
    margin: float = float("inf")
    could_be: list = field(default_factory=list)
    provisional: bool = False
    #: The change's estimate in the model's units (rad, mm), as fitted; not written.
    delta: Optional[np.ndarray] = field(default=None, repr=False)

    def to_dict(self) -> dict:
        return {
            "sample": self.sample,
            "row": self.row,
            "since": self.since,
            "kind": self.kind,
            "joint": self.joint,
            "size": self.size,
            "unit": self.unit,
            "parameters": self.names,
            "evidence": self.evidence,
            "distinct_by": self.margin,
            "could_be": list(self.could_be),
            "provisional": self.provisional,
        }

    def words(self) -> str:
        if self.kind == "unexplained":
            return (
                f"sample {self.sample} (row {self.row}): a change from sample {self.since} that no single kind explains: the likeliest, "
                f"{self.could_be[0]}, leaves {self.evidence:.1f}x what the model left before it (RMS)"
                + (f"; {' and '.join(self.could_be[1:])} explain it about as well" if len(self.could_be) > 1 else "")
                + ": nothing applied; the monitor opens anew, re-fitting the set-up on its next opening samples — a calibration may be due"
            )
        if self.kind == "setup":
            return (
                f"sample {self.sample} (row {self.row}): from sample {self.since} on the readings differ from the calibration's model as a moved sensor "
                f"would make them ({self.evidence:.1f}x the calibration's held-out error, RMS): the sensor stands elsewhere, or this is a new session; "
                "its set-up is re-fitted on the opening samples (as with --new-session)"
            )
        what = f"joint {self.joint}'s zero" if self.kind == "joint_zero" else f"the sensor's {'drift' if self.kind == 'drift' else 'set-up'}"
        size = ", ".join(f"{n} {v:+.4g}" for n, v in zip(self.names, self.size))
        doubt = f"; it could also be {' or '.join(self.could_be)} (likelihoods within e^{abs(self.margin):.1f})" if self.could_be else ""
        told = "provisionally, " if self.provisional else ""
        return f"sample {self.sample} (row {self.row}): {told}{what} changed from sample {self.since}: {size} {self.unit} ({self.evidence:.1f}x its threshold{doubt})"


def _kind_words(change) -> str:
    """A change's kind (a :class:`Change` or an :class:`Alarm`) as ``could_be`` lists it."""
    return change.kind if change.joint is None else f"joint {change.joint}'s zero"


def _surprise(stat: float, d: int) -> float:
    """``−log P(χ²_d > stat)``; beyond floating point, its asymptotic form (a statistic of
    thousands is no less a change than one of hundreds)."""
    tail = gammaincc(d / 2.0, stat / 2.0)  # the χ² survival function (scipy.stats' logsf costs half a millisecond a call)
    if tail > 1e-300:
        return float(-math.log(tail))
    return stat / 2.0 - (d / 2.0 - 1.0) * math.log(stat / 2.0) + math.lgamma(d / 2.0)


def _quadratic(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``bᵀ A⁻¹ b`` over the leading axes of ``A`` (..., d, d) symmetric and ``b`` (..., d), from
    ``A``'s ``LDLᵀ`` factors built element by element on the whole stack at once: the changes
    have a few parameters, and a LAPACK solve per start and change cost more than all of the
    window's sums."""
    d = b.shape[-1]
    L, D, w = {}, [], []
    for j in range(d):
        for i in range(j, d):
            x = A[..., i, j]
            for k in range(j):
                x = x - L[i, k] * L[j, k] * D[k]
            if i == j:
                D.append(x)
            else:
                L[i, j] = x / D[j]
        x = b[..., j]
        for k in range(j):
            x = x - L[j, k] * w[k]
        w.append(x)
    return sum(wj * wj / Dj for wj, Dj in zip(w, D))


def _ridged_inverse(G: np.ndarray) -> np.ndarray:
    """``G⁻¹`` with a ridge of a millionth of each column's own information: a direction the
    window does not determine stays at the calibration's value instead of making the inverse blow
    up. Per column, not of the mean information: the columns mix mm and rad, an angle's
    information is up to 10⁷ times a length's, and a ridge of the mean held the lengths — the
    set-up's own among them — at their values, so that the model's error along a path, which they
    would have absorbed, read as a change (the false alarms over long clean cable streams). A
    column without any information (its row zero) gets a unit ridge: its level stays zero."""
    information = np.diag(G)
    return np.linalg.inv(G + np.diag(np.where(information > 0, 1e-6 * information, 1.0)))


class _Buffers:
    """The window's sums, kept so that an update costs no copy of the window.

    Per sample ``t`` the monitor adds ``g_t = J_tᵀ W e_t`` and ``G_t = J_tᵀ W J_t`` over all
    ``p`` monitored columns. The window's own sums ``Σ g_t``, ``Σ G_t`` (for the constant profiled
    out) are kept by adding each sample and subtracting the one that leaves; the sums *from a
    start on* are needed only against the ``h`` columns a change acts on (and, weighted by ``t``
    and ``t²``, the ``r`` columns a ramp acts on): running totals, and per sample of the window
    the totals before it (a ring), so the sums from any start ``τ`` to now are one subtraction;
    the totals restart from the window's first sample every ``WINDOW`` samples. Memory and
    accuracy: the window's, whatever the stream's length.

    ``hypotheses`` are the changes tested, ``(cols, ramp)`` with ``cols`` indices into the
    monitored columns."""

    def __init__(self, p: int, hypotheses: list):
        self.p = p
        self.tested = sorted({c for cols, _ in hypotheses for c in cols})
        self.ramped = sorted({c for cols, ramp in hypotheses if ramp for c in cols})
        h, r = len(self.tested), len(self.ramped)
        # Rows of G_t (symmetric) rather than columns: the sums then come out as (start, column, p),
        # which the profile-out multiplies in one product.
        shapes = {"g": (h,), "tg": (r,), "G": (h, p), "tG": (r, p), "ttG": (r, r)}
        # All the running totals in one vector, and the ring in one array, so that the sums from
        # every start are one subtraction (``rings`` names views of its parts). The
        # last element stays zero: what a step's information gathers for a ramp's ``τ`` terms.
        base = dict(zip(shapes, np.cumsum([0] + [int(np.prod(s)) for s in shapes.values()])))
        zero = base["ttG"] + r * r
        # Each packed element is one element of (g_t, G_t) flattened, times 1, t or t² (or 0: the
        # last): a sample's share of every total is one gather and one product.
        H, R = self.tested, self.ramped
        packed = [(c, 0) for c in H] + [(c, 1) for c in R] + [(p + c * p + j, 0) for c in H for j in range(p)]
        packed += [(p + c * p + j, 1) for c in R for j in range(p)] + [(p + ci * p + cj, 2) for ci in R for cj in R] + [(0, 3)]
        self._source, self._power = (np.array(column) for column in zip(*packed))
        # The ring is held twice over (rows k and k + WINDOW alike): the totals before the window's
        # samples from any start on are then one slice, in order, not a gather across the wrap.
        self._total, self._ring = np.zeros(zero + 1), np.zeros((2 * WINDOW, zero + 1))
        self._parts = [(slice(base[n], base[n] + int(np.prod(s))), s) for n, s in shapes.items()]
        self.rings = {n: self._ring[:WINDOW, cut].reshape((WINDOW,) + s) for n, (cut, s) in zip(shapes, self._parts)}
        self.each_g, self.each_G = np.zeros((WINDOW, p)), np.zeros((WINDOW, p, p))
        self.times = np.zeros(WINDOW)
        # Every hypothesis is a set of the m = h + r "extended" columns: a step on a tested column
        # or a ramp on a ramped one. ``_ramp_at``: where each ramped column sits among the tested.
        pos, rpos = {c: i for i, c in enumerate(self.tested)}, {c: i for i, c in enumerate(self.ramped)}
        self._ramp_at = [pos[c] for c in self.ramped]
        ext = {**{(c, False): pos[c] for c in self.tested}, **{(c, True): h + rpos[c] for c in self.ramped}}
        # Only the information within each hypothesis is needed, not between them: per pair of its
        # extended columns, where its sums sit in the packed vector (Σ G_t for a step; Σ t² G_t,
        # Σ t G_t and Σ G_t for a ramp's Σ (t−τ)² G_t), hypotheses of d columns together.
        self.groups, pairs = [], []
        for d in sorted({len(cols) for cols, _ in hypotheses}):
            which = [k for k, (cols, _) in enumerate(hypotheses) if len(cols) == d]
            first = len(pairs)
            for k in which:
                cols, ramp = hypotheses[k]
                for ci in cols:
                    for cj in cols:
                        if ramp:
                            sums = (base["ttG"] + rpos[ci] * r + rpos[cj], base["tG"] + rpos[ci] * p + cj, base["G"] + pos[ci] * p + cj)
                        else:
                            sums = (base["G"] + pos[ci] * p + cj, zero, zero)
                        pairs.append((ext[ci, ramp], ext[cj, ramp]) + sums)
            idx = np.array([[ext[c, hypotheses[k][1]] for c in hypotheses[k][0]] for k in which])
            self.groups.append((which, idx, slice(first, len(pairs))))
        a, b, *sums = (np.array(column) for column in zip(*pairs))
        self._pairs = [a * (h + r) + b] + sums  # a pair's place in the (m, m) product
        # Work arrays for the largest window: arrays of this size, allocated anew per update, cost
        # more in page faults than their arithmetic.
        self._after, self._C = np.empty((WINDOW, zero + 1)), np.empty((WINDOW, h + r, p))
        self._profiled, self._Q = np.empty((WINDOW, h + r, p)), np.empty((WINDOW, h + r, h + r))
        self.clear()

    def clear(self) -> None:
        self.n, self.head, self.origin = 0, 0, None
        self._total[:] = 0.0
        self.window_g, self.window_G = np.zeros(self.p), np.zeros((self.p, self.p))

    def _packed(self, t: np.ndarray, g: np.ndarray, G: np.ndarray) -> np.ndarray:
        """What samples at times ``t`` (n,) (from :attr:`origin`) with ``g`` (n, p) and ``G``
        (n, p, p) add to the running totals, packed as they are: (n, K)."""
        n = len(t)
        flat = np.concatenate([g, G.reshape(n, -1)], axis=1)
        powers = np.zeros((n, 4))
        powers[:, 0], powers[:, 1], powers[:, 2] = 1.0, t, t * t
        return flat[:, self._source] * powers[:, self._power]

    def push(self, t: int, g: np.ndarray, G: np.ndarray) -> None:
        if self.n == WINDOW:  # the oldest leaves
            self.window_g -= self.each_g[self.head]
            self.window_G -= self.each_G[self.head]
            at, self.head = self.head, (self.head + 1) % WINDOW
        else:
            at = (self.head + self.n) % WINDOW
            self.n += 1
        if self.origin is None:
            self.origin = t
        self._ring[at] = self._ring[at + WINDOW] = self._total
        self.times[at], self.each_g[at], self.each_G[at] = t, g, G
        self.window_g += g
        self.window_G += G
        self._total += self._packed(np.array([t - self.origin], dtype=float), g[None], G[None])[0]
        if self.n == WINDOW and self.head == 0:
            self._rebase()

    def _rebase(self) -> None:
        """Every ``WINDOW`` samples, the totals from the window's first sample on, times from it.
        Kept from the stream's start they grow with its length (``Σ t² G_t`` as its cube), and a
        ramp's ``Σ (t−τ)² G_t`` — their difference — loses the digits it needs: 3e-7 relative a
        hundred thousand samples in. Also sheds the rounding the window's adds and subtractions
        gather."""
        order = self.order
        self.origin = self.times[order[0]]
        added = self._packed(self.times[order] - self.origin, self.each_g[order], self.each_G[order])
        sums = np.cumsum(added, axis=0)
        self._ring[order] = self._ring[order + WINDOW] = sums - added
        self._total[:] = sums[-1]
        self.window_g, self.window_G = self.each_g[order].sum(axis=0), self.each_G[order].sum(axis=0)

    @property
    def order(self) -> np.ndarray:
        return (self.head + np.arange(self.n)) % WINDOW

    def index(self, k: int) -> int:
        return int(self.times[self.order[k]])

    def evidence(self, starts: int, prior: np.ndarray) -> tuple[list, np.ndarray]:
        """The score and information of each hypothesis begun at each of the window's samples
        ``1 … starts − 1`` (a start at its first sample leaves no level before it), every
        monitored column held constant over the window and profiled out (``prior``: their
        information from the calibration): what the calibration left, or a change already in
        force, is no evidence; only a change *within* the window is. Returns per group of
        hypotheses of ``d`` columns ``(which, score, info)`` — ``which`` their indices, ``score``
        (n, k, d), ``info`` (n, k, d, d) — and the window's constant ``G_w⁻¹ g_w`` (the
        calibration's error as the window sees it)."""
        rows = self.order[1:starts]
        n, p, h = len(rows), self.p, len(self.tested)
        inverse = _ridged_inverse(self.window_G + np.diag(prior))
        level = inverse @ self.window_g
        tau = self.times[rows] - self.origin
        after = np.subtract(self._total, self._ring[self.head + 1 : self.head + starts], out=self._after[:n])
        g, tg, Gs, tG, _ = (after[:, cut].reshape((n,) + s) for cut, s in self._parts)
        at = self._ramp_at
        # The extended columns' scores (Σ (t−τ) g_t for a ramp) and cross-information with the
        # window's constant C (n, m, p), profiled out for all of them in one product.
        C = self._C[:n]
        C[:, :h] = Gs
        np.subtract(tG, tau[:, None, None] * Gs[:, at], out=C[:, h:])
        score = np.concatenate([g, tg - tau[:, None] * g[:, at]], axis=1) - C @ level
        profiled = self._profiled[:n]
        np.matmul(C.reshape(-1, p), inverse.T, out=profiled.reshape(-1, p))
        Q = np.matmul(C, profiled.transpose(0, 2, 1), out=self._Q[:n]).reshape(n, -1)
        pair, i0, i1, i2 = self._pairs
        info = after[:, i0] - 2.0 * tau[:, None] * after[:, i1] + tau[:, None] ** 2 * after[:, i2] - Q[:, pair]
        groups = [(which, score[:, idx], info[:, pairs].reshape(n, len(which), idx.shape[1], idx.shape[1])) for which, idx, pairs in self.groups]
        return groups, level


class _LongRunVariance:
    """How much more the innovations' sums over a window vary than independent samples of unit
    variance would, per reading, the largest taken: batch means capture any correlation shorter
    than a batch and a scale the opening misjudged. ``b`` times the variance of ``b``-sample means
    falls short of a ``WINDOW``-sample sum's by a term in ``1/b`` (AR(1) innovations with ρ = 0.9:
    15.4 at ``b`` = 50 against 17.2 for 100 samples, and the false alarms of such streams came at
    1.0-1.2 times their thresholds), so the means are taken at ``BATCH / 2`` and ``BATCH`` samples
    and extrapolated to ``WINDOW`` along that term, never below the ``BATCH`` figure; batches of the
    window's length would rest on half as many. Fed with innovations that have left the window, so
    a change under test does not inflate its own yardstick; forgets over :data:`MEMORY_BATCHES`
    batches."""

    def __init__(self, z: np.ndarray):
        half = BATCH // 2
        batches = len(z) // BATCH
        halves = z[: batches * BATCH].reshape(2 * batches, half, -1).mean(axis=1)
        wholes = halves.reshape(batches, 2, -1).mean(axis=1)
        self.mean = {half: halves.mean(axis=0), BATCH: wholes.mean(axis=0)}
        self.square = {b: np.mean((m - self.mean[b]) ** 2, axis=0) for b, m in ((half, halves), (BATCH, wholes))}
        self.batches = {half: 2 * batches, BATCH: batches}  # the opening's few batches weigh as many, not as the full memory
        self.pending: list = []
        self.first_half: Optional[np.ndarray] = None
        self.inflation = self._bound()

    def _bound(self) -> float:
        half = BATCH // 2
        whole, halved = BATCH * self.square[BATCH], half * self.square[half]
        window = whole + np.maximum(whole - halved, 0.0) * (1.0 - BATCH / WINDOW)
        # The upper bound at CONFIDENCE, given the batches it rests on: an opening of a few
        # batches cannot show a correlation it happened not to visit.
        dof = max(self.batches[BATCH] - 1, 1)
        return float(max(1.0, np.max(window) * dof / chdtri(dof, CONFIDENCE)))

    def _fold(self, size: int, m: np.ndarray) -> None:
        # An average over the batches so far, then forgetting: a yardstick from the opening's
        # four batches held as if from a hundred kept the inflation at 1 for a thousand samples
        # of innovations correlated 3.5x (a cable stream leaving the opening's region).
        self.batches[size] = min(self.batches[size] + 1, MEMORY_BATCHES * BATCH // size)
        w = 1.0 / self.batches[size]
        self.mean[size] = (1 - w) * self.mean[size] + w * m
        self.square[size] = (1 - w) * self.square[size] + w * (m - self.mean[size]) ** 2
        self.inflation = self._bound()  # changes once a batch: kept, not recomputed per sample

    def add(self, z: np.ndarray) -> None:
        self.pending.append(z)
        if len(self.pending) < BATCH // 2:
            return
        m = np.mean(self.pending, axis=0)
        self.pending.clear()
        self._fold(BATCH // 2, m)
        if self.first_half is None:
            self.first_half = m
            return
        self._fold(BATCH, (self.first_half + m) / 2)
        self.first_half = None


class _StatisticScale:
    """The statistics' own yardstick: each change's statistic under no change, per degree of
    freedom, averaged over past segments of SEGMENT samples — each taken at the end of a full
    window (the opening's at once) and counted once it has left the window; one taken while a
    change was under way is dropped with its alarm —, at its upper confidence bound for the χ²
    degrees of freedom it rests on, as the inflation is. The innovations' long-run inflation
    estimates the same factor from their sums, less each window's constant, and falls short
    where the model's error along the path and a wandering sensor shape the profiled contrasts
    otherwise (HSR cable with an AR(1) wander: the drift's statistic 2.0 times, the step's 1.8
    times its inflation; 40 false alarms in 870,000 samples where one per 100,000 was stated).
    Forgets over MEMORY_BATCHES segments."""

    def __init__(self, dofs: np.ndarray):
        self.pending: deque = deque()
        self.dofs = dofs  # each change's parameters
        self.mean, self.count = np.zeros(len(dofs)), 0

    def take(self, now: int, per_dof: np.ndarray) -> None:
        self.pending.append((now, per_dof))

    def fold(self, now: int) -> None:
        while self.pending and self.pending[0][0] <= now - WINDOW:
            _, per_dof = self.pending.popleft()
            self.count = min(self.count + 1, MEMORY_BATCHES)
            self.mean += (per_dof - self.mean) / self.count

    def scale(self, inflation: float) -> float:
        """What every statistic is divided by: the larger of the long-run inflation and the
        statistics' own factors. One for all: the kinds are ranked by their statistics, and
        factors of their own, uncertain over a few segments, re-ranked them (a joint's zero at 5x
        its limit named as another's)."""
        if not self.count:
            return inflation
        dof = self.count * self.dofs
        return float(max(inflation, np.max(self.mean * dof / chdtri(dof, CONFIDENCE))))


class Monitor:
    """Watches a calibrated robot sample by sample (see the module notes).

    Parameters
    ----------
    result : path or dict
        A result file of ``robocal calibrate`` (:func:`robocal.results.load_result`).
    new_session : bool
        Re-fit the session's set-up on the opening samples (default: the stream continues the
        calibration's session, its set-up as calibrated).
    mean_run_length : float
        Mean samples between false alarms the thresholds are set for.
    opening : int
        Samples that set the innovations' scale and correlation; no alarm before them.
    """

    def __init__(self, result, *, new_session: bool = False, mean_run_length: float = MEAN_RUN_LENGTH, opening: int = OPENING):
        if not mean_run_length >= 10:
            raise InvalidParameterError(f"`mean_run_length` must be at least 10 samples; got {mean_run_length!r}")
        if not isinstance(opening, int) or opening < 10:
            raise InvalidParameterError(f"`opening` must be an integer of at least 10 samples; got {opening!r}")
        self.robot, self.doc = load_result(result)
        self.measurement = self.doc["measurement"]
        self.params = self.robot.params.copy()
        self._drift, self._drift_left = np.zeros_like(self.params), 0  # per sample, of a drift found, for how many samples more
        self.structures = structure.parse_all(self.doc.get("structure", []), self.robot.n_joints)
        causes = self.doc.get("causes", [])
        self.offsets = joint_offsets(self.robot, causes, kinds=COMPENSABLE)
        self.not_applied = sorted({c.get("label", c.get("kind")) for c in causes if c.get("kind") not in COMPENSABLE})
        self.new_session, self.opening, self.mean_run_length = new_session, opening, float(mean_run_length)
        self.changes = self._changes()
        # The null hypothesis is no change in the window, the parameters then as the calibration
        # left them or anywhere near (its own error): every parameter it estimated is profiled out
        # over the window (the session's set-up free), so the calibration's error along a path is
        # no evidence. Each is held near its value by the calibration's standard deviation and, a
        # kinematic one, by the manufacturing tolerance too (TOLERANCE, the calibration's own
        # prior): a direction the calibration left undetermined (D2's: stds of tens of mm) would
        # otherwise let the constant absorb a change as a geometry no arm has. The parameters it
        # fixed stay at their values: redundant with estimated ones wherever the arm goes (a point
        # sensor's tool against the last joint, the base's turn against the first), profiling
        # them too explained nothing more of the long clean cable streams' innovations.
        names = self.robot.param_names
        fitted = [names.index(n) for n in self.doc.get("free", []) if n in names]
        self.columns = sorted({c for change in self.changes for c in change.columns} | set(fitted))
        std = {p["name"]: p.get("std") for p in self.doc["parameters"]}
        private = set(setup_names(self.robot, self.measurement)) | {"cable_offset"}
        units = dict(zip(names, self.robot.param_units))

        def hold(name: str) -> float:  # the inverse variance the window's constant is held by
            if name in private:
                return 0.0
            return (1.0 / std[name] ** 2 if std.get(name) else 0.0) + (1.0 / TOLERANCE[units[name]] ** 2 if is_kinematic(name) else 0.0)

        self.prior = np.array([hold(names[c]) for c in self.columns])
        self._level = np.zeros(len(self.columns))  # the window's constant (the calibration's error as it sees it)
        self.threshold = {d: float(chdtri(d, 1.0 / (self.mean_run_length * WINDOW * len(self.changes)))) for d in {len(c.columns) for c in self.changes}}
        # The joints' limits, a nanoradian's grace for rounding in the readings.
        self._limits = tuple(np.array([j.limits[k] for j in self.robot.joints]) + grace for k, grace in ((0, -1e-9), (1, 1e-9)))
        self.samples = 0
        self.alarms: list[Alarm] = []
        self.refused: list[str] = []
        self._opening: list = []  # (q, y, row) until the opening is complete
        self._buffers = _Buffers(len(self.columns), [([self.columns.index(c) for c in change.columns], change.ramp) for change in self.changes])
        self.sigma: Optional[np.ndarray] = None
        self.inflation = 1.0
        self._scale = _StatisticScale(np.array([len(c.columns) for c in self.changes]))
        self._delayed: deque = deque()
        self._told: Alarm | None = None  # the provisional alarm of the crossing under way
        self._reopened = False  # an unexplained change: the next opening re-fits the set-up
        self.limits: dict = {}
        self._window_limits: deque = deque(maxlen=LIMIT_WINDOWS)  # per full window, each change's limit in it
        self.refit: dict = {}

    # -- what is watched -----------------------------------------------------------------------
    def _changes(self) -> list[Change]:
        r = self.robot
        out = []
        for j, name in enumerate(zero_names(r), start=1):
            out.append(Change("joint_zero", j, (r.index(name),), (name,)))
        sensor = ("cable_offset",) if self.measurement == "cable" else ("base_x", "base_y", "base_z")
        columns = tuple(r.index(n) for n in sensor)
        out += [Change("step", None, columns, sensor), Change("drift", None, columns, sensor)]
        return out

    def _limit(self, change: Change, info: np.ndarray) -> float:
        """The smallest change (along its weakest direction) whose statistic reaches the threshold
        with information ``info``, at unit inflation (the summary states it at the correlation
        last measured)."""
        weakest = np.linalg.eigvalsh(info)[0]
        return float(np.sqrt(self.threshold[len(change.columns)] / max(weakest, 1e-300)))

    def _unit(self, change: Change) -> str:
        return "deg" if change.kind == "joint_zero" and self.robot.joints[change.joint - 1].kind == "revolute" else ("mm/sample" if change.ramp else "mm")

    # -- the model -----------------------------------------------------------------------------
    def _links(self, q: np.ndarray) -> np.ndarray:
        """The angles the links take at readings ``q`` (m, N)."""
        q = structure.to_model(q, self.structures)
        return q if self.offsets is None else q + self.offsets(q)

    def _innovations(self, q: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        e, J = self.robot.residuals_and_jacobian(self.measurement, self._links(q), y, params=self.params, cols=self.columns)
        e = e.reshape(len(q), -1)
        return e, J.reshape(len(q), e.shape[1], len(self.columns))

    # -- the stream ----------------------------------------------------------------------------
    def _checked(self, q, y) -> tuple[np.ndarray, np.ndarray]:
        q, y = np.atleast_2d(as_float_array(q, "q")), np.atleast_2d(as_float_array(y, "y"))
        readings = len(OBSERVATION_COLUMNS[self.measurement])
        if q.ndim != 2:
            raise ShapeError(f"`q` must be one sample (N,) or a block of samples (m, N); got shape {q.shape}")
        if q.shape[1] != self.robot.n_joints:
            raise ShapeError(f"a sample has {q.shape[-1]} joint values; the result's robot {self.robot.name!r} has {self.robot.n_joints}")
        if y.ndim != 2 or y.shape != (len(q), readings):
            raise ShapeError(f"`y` must hold {readings} readings ({self.measurement}) for each of the {len(q)} samples; got shape {y.shape}")
        return q, y

    def _refuse(self, i: int, row, why: str) -> None:
        note = f"sample {i} (row {row}) refused: {why}"
        self.refused.append(note)
        logger.warning("monitor: %s", note)

    def update(self, q, y, rows=None) -> list[Alarm]:
        """Takes one sample (``q`` (N,) rad — the controller's readings —, ``y`` (k,) mm) or a
        block ((m, N), (m, k)) in acquisition order; returns the alarms raised. A sample that
        is not finite or lies beyond the joint limits is refused with a note
        (:attr:`refused`) and the stream goes on."""
        q, y = self._checked(q, y)
        rows = [None] * len(q) if rows is None else list(rows)
        if len(rows) != len(q):  # else zip would drop the samples past the shorter
            raise ShapeError(f"`rows` must name the file row of each of the {len(q)} samples; got {len(rows)}")

        raised = []
        lower, upper = self._limits
        for qi, yi, row in zip(q, y, rows):
            i = self.samples
            self.samples += 1
            model_q = structure.to_model(qi[None, :], self.structures)[0]
            if not (np.isfinite(qi).all() and np.isfinite(yi).all()):
                self._refuse(i, row, "a value is not a finite number")
                continue
            if (model_q < lower).any() or (model_q > upper).any():
                self._refuse(i, row, "a joint lies beyond the robot's limits")
                continue
            if self.sigma is None:
                self._opening.append((i, qi, yi, row))
                if len(self._opening) == self.opening:
                    moved = self._start()
                    if moved is not None:
                        self.alarms.append(moved)
                        raised.append(moved)
                continue
            alarm = self._step(i, qi[None, :], yi[None, :], row)
            if alarm is not None:
                raised.append(alarm)
        return raised

    def _start(self) -> Optional[Alarm]:
        """The opening is complete: the set-up (``new_session``, after an unexplained change, or
        when the opening shows the sensor elsewhere: then a ``setup`` alarm, returned), the
        innovations' scale and correlation, the detection limits; then the opening samples enter
        the window."""
        index = [i for i, *_ in self._opening]
        q = np.array([s[1] for s in self._opening])
        y = np.array([s[2] for s in self._opening])
        # Never below what the calibration itself erred by on samples it did not fit: the model's
        # error on new poses, which a short opening may not show.
        figures = self.doc.get("metrics", {}).get("test") or self.doc.get("metrics", {}).get("train") or {}
        floor = np.full(RESIDUAL_WIDTH[self.measurement], (figures.get("rmse") or 0.0) / np.sqrt(3.0 if self.measurement != "cable" else 1.0))
        if self.measurement == "pose":
            floor[3:] = 0.0  # the rotation rows: the opening's figure alone
        moved = None
        if self.new_session or self._reopened:
            self._refit_setup(q, y)
        else:
            moved = self._moved_sensor(q, y, floor, index, self._opening[-1][3])
        self._reopened = False
        e, J = self._innovations(q, y)
        centred = e - e.mean(axis=0)
        fitted = len(self.refit.get("names", [])) + e.shape[1]  # the set-up re-fitted and the mean removed take degrees of freedom
        opening_sigma = np.sqrt(np.sum(centred**2, axis=0) / max(len(q) - fitted / e.shape[1], 1.0))
        self.sigma = np.maximum(opening_sigma, floor).clip(1e-9)
        Jw = J / self.sigma[None, :, None]
        z = e / self.sigma
        G = np.einsum("mkp,mkq->pq", Jw, Jw) + np.diag(self.prior)
        level = np.linalg.pinv(G, rcond=1e-12, hermitian=True) @ np.einsum("mkp,mk->p", Jw, z)
        self._variance = _LongRunVariance(z - Jw @ level)  # the opening less its constant, as the window will see it
        self._scale = _StatisticScale(self._scale.dofs)  # the innovations' scale is new: so are the statistics'
        self.inflation = self._variance.inflation
        Jw = J / self.sigma[None, :, None]
        per_sample = np.einsum("mkp,mkq->pq", Jw, Jw) / len(q)
        window = WINDOW * per_sample + np.diag(self.prior)
        window_inverse = _ridged_inverse(window)
        for change in self.changes:
            if change.ramp:
                continue
            cols = [self.columns.index(c) for c in change.columns]
            # Until the first full window: a window of the opening's mean information, the change
            # in its last LIMIT_SAMPLES samples, the constant profiled out.
            cross = LIMIT_SAMPLES * per_sample[:, cols]
            self.limits[(change.kind, change.joint)] = self._limit(change, cross[cols] - cross.T @ window_inverse @ cross)
        for (i, _, _, row), ei, Ji in zip(self._opening, e, J):
            self._push(i, ei, Ji)
            b = self._buffers
            if b.n == WINDOW and b.head % SEGMENT == 0:  # the opening's segments count at once: no change is tested there
                groups, _ = b.evidence(b.n - MIN_AFTER + 1, self.prior)
                self._take_segment(i, [(which, score, info + 1e-12 * np.eye(score.shape[2])) for which, score, info in groups])
        self._scale.fold(index[-1] + WINDOW)
        self._opening.clear()
        logger.info("monitor: opening of %d samples: sigma %s, long-run inflation %.2f", len(index), self.sigma, self.inflation)
        return moved

    def _refit_setup(self, q: np.ndarray, y: np.ndarray) -> None:
        """The session's set-up fitted anew on the samples ``q``, ``y`` (as ``verify`` does)."""
        data = Dataset(q=self._links(q), y=y, measurement=self.measurement, robot=self.robot.name)
        names = setup_names(self.robot, self.measurement)
        problem = Problem.build(self.robot, data, mask=names, params=self.params)
        fit = levenberg_marquardt(problem)
        self.params = problem.full(fit.x)
        self.refit = {"names": names, "samples": len(q)}

    def _moved_sensor(self, q: np.ndarray, y: np.ndarray, floor: np.ndarray, index: list, row) -> Optional[Alarm]:
        """A ``setup`` alarm if the opening's innovations at the calibration's set-up exceed its
        held-out error ``floor`` and the set-up re-fitted on them by :data:`FIT_RATIO` (RMS) each —
        the sensor stands elsewhere (a change before the stream, which the window's constant would
        absorb unseen) —, the set-up then kept re-fitted; else None and the set-up as calibrated."""
        seen = floor > 0
        if not seen.any():
            return None
        before, _ = self._innovations(q, y)
        rms = lambda e: float(np.sqrt(np.mean(e[:, seen] ** 2)))  # noqa: E731
        ratio = rms(before) / float(np.sqrt(np.mean(floor[seen] ** 2)))
        if ratio <= FIT_RATIO:  # as the calibration predicted: the set-up need not be re-fitted to tell
            return None
        calibrated = self.params.copy()
        self._refit_setup(q, y)
        after, _ = self._innovations(q, y)
        if rms(before) <= FIT_RATIO * rms(after):
            self.params, self.refit = calibrated, {}
            return None
        logger.info("monitor: the opening's readings are %.3g x the calibration's held-out error: the set-up re-fitted", ratio)
        return Alarm(index[-1], row, index[0], "setup", None, [], "", list(self.refit["names"]), ratio, provisional=False)

    def _push(self, i: int, e: np.ndarray, J: np.ndarray) -> None:
        z = e / self.sigma
        Jw = J / self.sigma[:, None]
        self._buffers.push(i, Jw.T @ z, Jw.T @ Jw)
        self._delayed.append((z, Jw))
        if len(self._delayed) == WINDOW:  # an innovation leaves the window: it now measures the yardstick, less the window's constant
            z_old, J_old = self._delayed.popleft()
            # Not while the window refills after a change: its constant rests on a few samples, and the
            # innovations leaving it were made by the model before the change, the change's own among them
            # (fed to it, they raised the long-run inflation from 5 to 300 after a joint's zero was found,
            # and the monitor was blind to the next change for thousands of samples).
            if self._buffers.n == WINDOW:
                self._variance.add(z_old - J_old @ self._level)
                self.inflation = self._variance.inflation

    def _step(self, i: int, q: np.ndarray, y: np.ndarray, row) -> Optional[Alarm]:
        if self._drift_left:  # a drift found goes on for a window: the model follows it sample by sample
            self.params += self._drift
            self._drift_left -= 1
        e, J = self._innovations(q, y)
        self._push(i, e[0], J[0])
        found, step = self._test(i, row)
        if found is None:
            self._told = None  # no crossing (any more): a provisional alarm of it stays unapplied
            return None
        waited = i - found.since
        # Named for good once enough samples after its start show which change it is, and no
        # other kind explains it alike (or it has waited long enough for more samples to tell).
        if waited < CONFIRM or (found.could_be and waited < MAX_WAIT):
            # Meanwhile, if the sensor's step is among the kinds that explain it, the change is
            # told at once as that step: the simplest explanation (a constant on the reading, no
            # fault of the robot), and the one a single reading cannot tell from a joint's zero
            # for a while. Once per crossing; not applied.
            if step is not None and self._told is None:
                self._told = step
                self.alarms.append(step)
                return step
            return None
        self._told = None
        left = self._left_by(found, i)
        if left > FIT_RATIO:  # no single kind explains it: said so, nothing applied, the monitor opens anew
            found = replace(found, kind="unexplained", joint=None, size=[], unit="", names=[], evidence=left, could_be=[_kind_words(found)] + found.could_be)
            self.alarms.append(found)
            self._reopen()
            return found
        self._apply(found)
        self.alarms.append(found)
        self._buffers.clear()  # the window starts anew under the changed model
        self._scale.pending.clear()  # taken while the change was under way
        return found

    def _left_by(self, found: Alarm, now: int) -> float:
        """How much more ``found`` leaves of the innovations after its start than the model left
        before it. The window's constant and the change are fitted together, as the test profiles
        them (the constant on every sample, the change from its start on), to the samples before
        the start and the first half of those after it; the RMS of what is left of the second half
        — samples the fit did not see — over that of the samples before the start (their degrees
        of freedom counted). About 1 where the change explains what follows as the model explained
        what preceded. (The constant fitted to the samples before the start alone carried the error
        of a direction they hardly determine — a cable's anchor along a slow path — into the
        samples after it.)"""
        change = next(c for c in self.changes if c.kind == found.kind and c.joint == found.joint)
        window = list(self._delayed)[-min(self._buffers.n, len(self._delayed)) :]
        z = np.array([zj for zj, _ in window])
        Jw = np.array([Jj for _, Jj in window])
        n_after = now - found.since + 1
        n_before = len(z) - n_after
        free = int(np.sum(self.prior == 0))  # the set-up's columns, which the constant fits unhindered
        held = n_before * z.shape[1] <= free + MIN_AFTER  # too few samples before it in this window: the constant held, against the noise
        cols = [self.columns.index(c) for c in change.columns]
        onset = np.arange(n_after, dtype=float) if change.ramp else np.ones(n_after)
        changed = np.zeros((len(z), Jw.shape[1], len(cols)))
        changed[n_before:] = Jw[n_before:][:, :, cols] * onset[:, None, None]
        X = changed if held else np.concatenate([Jw, changed], axis=2)
        penalty = np.zeros(len(cols)) if held else np.concatenate([self.prior, np.zeros(len(cols))])
        # Held out: a constant change fitted with the first half of the samples after its start predicts the second half (a
        # change that is there stays as it was; a kind that only follows the samples it sees does not predict the next ones:
        # D2's re-zero as joint 4's zero). A drift, whose start is uncertain by tens of samples, is judged on the samples it
        # is fitted to.
        fit_until = len(z) if change.ramp else n_before + (n_after + 1) // 2
        A, b = X[:fit_until].reshape(-1, X.shape[2]), z[:fit_until].ravel()
        left = z - X @ np.linalg.lstsq(A.T @ A + np.diag(penalty), A.T @ b, rcond=None)[0]
        before = 1.0 if held else float(np.sum(left[:n_before] ** 2) / (left[:n_before].size - free))
        if change.ramp:
            after = float(np.sum(left[n_before:] ** 2) / max(left[n_before:].size - len(cols), 1))
        else:
            after = float(np.mean(left[fit_until:] ** 2))
        return float(np.sqrt(after / max(before, 1e-300)))

    def _reopen(self) -> None:
        """Starts anew after an unexplained change: the next opening samples re-fit the set-up and
        measure the innovations again."""
        self.sigma = None
        self._opening.clear()
        self._buffers.clear()
        self._delayed.clear()
        self._drift_left = 0
        self._reopened = True

    def _test(self, now: int, row) -> tuple[Alarm | None, Alarm | None]:
        """The change with the strongest evidence over its threshold, or None; and the sensor's
        step as a provisional alarm if it is :data:`TOLD_AT` times over its threshold and within
        e^DISTINCT of that change."""
        b = self._buffers
        starts = b.n - MIN_AFTER + 1  # starts with at least MIN_AFTER samples from them on
        if starts <= 1:
            return None, None
        groups, self._level = b.evidence(starts, self.prior)
        if b.n == WINDOW and b.head == 0:  # once a window
            self._measure_limits(groups)
        groups = [(which, score, info + 1e-12 * np.eye(score.shape[2])) for which, score, info in groups]
        self._take_segment(now, groups)
        self._scale.fold(now)
        scale = self._scale.scale(self.inflation)
        # Per change: its largest statistic, at which start (1-based in the window), and its score and
        # information there (the estimate is solved only for an alarm).
        strongest: list = [None] * len(self.changes)
        for which, score, info in groups:  # the changes of d parameters each, all starts at once
            stat = _quadratic(info, score) / scale
            for j, k in enumerate(np.argmax(stat, axis=0)):
                strongest[which[j]] = (float(stat[k, j]), int(k) + 1, (info[k, j], score[k, j]))
        if all(stat <= self.threshold[len(c.columns)] for c, (stat, _, _) in zip(self.changes, strongest)):
            return None, None  # the common case: no change ranked (the χ² tails cost more than the test)
        # Kinds of other degrees of freedom compared by how unlikely each is under no change.
        ranked = sorted(((_surprise(stat, len(c.columns)), c, stat, k, fit) for c, (stat, k, fit) in zip(self.changes, strongest)), key=lambda r: -r[0])
        crossed = [r for r in ranked if r[2] > self.threshold[len(r[1].columns)]]

        def alarm(surprise, change, stat, k, fit) -> Alarm:
            info, score = fit
            delta = score / info[0] if len(score) == 1 else np.linalg.solve(info, score)
            scale = np.degrees(delta) if self._unit(change) == "deg" else delta
            found = Alarm(
                now,
                row,
                b.index(k),
                change.kind,
                change.joint,
                [float(v) for v in scale],
                self._unit(change),
                list(change.names),
                stat / self.threshold[len(change.columns)],
                delta=np.array(delta, dtype=float),
            )
            others = [r for r in ranked if r[1] is not change]
            found.margin = float(surprise - others[0][0]) if others else float("inf")
            found.could_be = [_kind_words(c) for v, c, *_ in others if v > surprise - DISTINCT]
            return found

        found = alarm(*crossed[0])
        step = next((r for r in crossed if r[1].kind == "step"), None)
        if step is None or not found.could_be or crossed[0][0] - step[0] >= DISTINCT or step[2] < TOLD_AT * self.threshold[len(step[1].columns)]:
            return found, None
        told = alarm(*step)
        told.provisional = True
        return found, told

    def _take_segment(self, now: int, groups: list) -> None:
        """Every SEGMENT samples of a full window, each change's statistic over its last SEGMENT
        samples, per degree of freedom, for its own yardstick."""
        if self._buffers.n != WINDOW or self._buffers.head % SEGMENT:
            return
        per_dof = np.zeros(len(self.changes))
        for which, score, info in groups:
            per_dof[which] = _quadratic(info[WINDOW - SEGMENT - 1], score[WINDOW - SEGMENT - 1]) / score.shape[2]
        self._scale.take(now, per_dof)

    def _measure_limits(self, groups: list) -> None:
        """Each change's detection limit in the window now, from the information of a change in
        its last LIMIT_SAMPLES samples; the stated limit is the median over the last
        LIMIT_WINDOWS windows. Not the opening's mean information: within a window the path
        keeps to a small region, where the session's set-up, free in the window's constant, can
        mimic a change far better than over the whole opening (a tracker's step on a simulated
        ABB IRB120: a third of the statistic the opening's figure promised)."""
        row = WINDOW - LIMIT_SAMPLES - 1  # the start LIMIT_SAMPLES before the end (rows begin at the window's second sample)
        here = {}
        for which, _, info in groups:
            for j, k in enumerate(which):
                change = self.changes[k]
                if not change.ramp:
                    here[(change.kind, change.joint)] = self._limit(change, info[row, j])
        self._window_limits.append(here)
        self.limits = {key: float(np.median([w[key] for w in self._window_limits])) for key in here}

    def _apply(self, alarm: Alarm) -> None:
        change = next(c for c in self.changes if c.kind == alarm.kind and c.joint == alarm.joint)
        size = np.radians(alarm.size) if alarm.unit == "deg" else np.asarray(alarm.size)
        if change.ramp:  # the drift so far, as a step of the set-up, and its rate for the next window
            # Carried for one window only: a drift that goes on is then seen anew against a level before it (a
            # drift from the window's first sample cannot be), one that stopped, or a false one, errs no further.
            if not self._drift_left:  # the last drift's window is over: this one alone goes on
                self._drift[:] = 0.0
            self._drift[list(change.columns)] += size
            self._drift_left = WINDOW
            size = size * (alarm.sample - alarm.since)
        self.params[list(change.columns)] += size

    # -- what it found -------------------------------------------------------------------------
    def summary(self) -> dict:
        scale = self._scale.scale(self.inflation)
        return {
            "samples": self.samples,
            "alarms": [a.to_dict() for a in self.alarms],
            "refused": list(self.refused),
            "opening": {"samples": self.opening, "started": self.sigma is not None, "refit": self.refit or None},
            "noise": None if self.sigma is None else [float(s) for s in self.sigma],
            "inflation": self.inflation,
            "mean_run_length": self.mean_run_length,
            "thresholds": {str(d): h for d, h in self.threshold.items()},
            "detection_limits": [
                {
                    "kind": kind,
                    "joint": joint,
                    "size": (np.degrees(v) if kind == "joint_zero" else v) * math.sqrt(scale),
                    "unit": "deg" if kind == "joint_zero" else "mm",
                    "within": LIMIT_SAMPLES,
                }
                for (kind, joint), v in self.limits.items()
            ],
            "not_applied": self.not_applied,
        }

    def result_document(self) -> dict:
        """The result with what changed applied: its parameters' values as the monitor holds them
        now, and a ``monitor`` record of the alarms."""
        doc = dict(self.doc)
        doc["parameters"] = [{**p, "value": float(v), "deviation": float(v) - p["nominal"]} for p, v in zip(self.doc["parameters"], self.params)]
        doc["monitor"] = self.summary()
        return doc
