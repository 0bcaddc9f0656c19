"""The in-line monitor's window (:mod:`robocal.monitoring`): the sums from which every change's
evidence from every start is one subtraction (:class:`WindowSums`), and the two yardsticks its
statistics are divided by — the innovations' long-run inflation (:class:`LongRunVariance`) and the
statistics' own (:class:`StatisticScale`)."""

from __future__ import annotations

from collections import deque
from typing import Optional

import numpy as np
from scipy.special import chdtri

#: Samples of the ring buffers: how far back a change may have begun to be found.
WINDOW = 100
#: Samples per batch of the long-run variance (batch means) of the innovations.
BATCH = 50
#: Batches over which the long-run variance forgets (exponential weights).
MEMORY_BATCHES = 100
#: The long-run variance is taken at its upper confidence bound: P(χ² below it) = 1 − this.
CONFIDENCE = 0.95
#: Segments whose statistics, taken every SEGMENT samples from a full window, measure each change's
#: own yardstick once they have left it.
SEGMENT = BATCH


def quadratic_form(A: np.ndarray, b: np.ndarray) -> np.ndarray:
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


def ridged_inverse(G: np.ndarray) -> np.ndarray:
    """``G⁻¹`` with a ridge of a millionth of each column's own information: a direction the
    window does not determine stays at the calibration's value instead of making the inverse blow
    up. Per column, not of the mean information: the columns mix mm and rad, an angle's
    information is up to 10⁷ times a length's, and a ridge of the mean held the lengths — the
    set-up's own among them — at their values, so that the model's error along a path, which they
    would have absorbed, read as a change (the false alarms over long clean cable streams). A
    column without any information (its row zero) gets a unit ridge: its level stays zero."""
    information = np.diag(G)
    return np.linalg.inv(G + np.diag(np.where(information > 0, 1e-6 * information, 1.0)))


class WindowSums:
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
        inverse = ridged_inverse(self.window_G + np.diag(prior))
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


class LongRunVariance:
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


class StatisticScale:
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
        self.bound = 0.0  # the largest factor at its upper bound: changes only as a segment is folded, not per sample

    def take(self, now: int, per_dof: np.ndarray) -> None:
        self.pending.append((now, per_dof))

    def fold(self, now: int) -> None:
        while self.pending and self.pending[0][0] <= now - WINDOW:
            _, per_dof = self.pending.popleft()
            self.count = min(self.count + 1, MEMORY_BATCHES)
            self.mean += (per_dof - self.mean) / self.count
            dof = self.count * self.dofs
            self.bound = float(np.max(self.mean * dof / chdtri(dof, CONFIDENCE)))

    def scale(self, inflation: float) -> float:
        """What every statistic is divided by: the larger of the long-run inflation and the
        statistics' own factors. One for all: the kinds are ranked by their statistics, and
        factors of their own, uncertain over a few segments, re-ranked them (a joint's zero at 5x
        its limit named as another's)."""
        return max(inflation, self.bound)
