"""Several sessions of one robot fitted together, and fits of part of a model.

A *session* is one measurement set-up: the tracker or the cable sensor placed once, the tool
point mounted once. From one session to the next the robot is the same — its kinematics and the
causes acting on its joints — while the set-up and the sensor's own terms (a step of its zero,
a drift) are new. :class:`Sessions` stacks one problem per session over a parameter vector in
which each shared entry appears once and each session's private entries once per session.
:class:`Partial` fits some entries of a problem with the others held at given values: a new
session's set-up under a calibrated robot.

Both have the interface the production LM works on (``x0``, ``residuals``, ``jacobian``,
``data_residuals``, ``clip``, ``data``, ``names``), so the same solver fits them.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..kernels import is_sparse
from ..data.dataset import Dataset
from ..data.identity import require_distinct_sessions
from ..exceptions import InvalidParameterError
from ..robot import RESIDUAL_WIDTH, Robot
from .api import load_inputs
from .problem import Problem, kinematic_prior_pairs, kinematic_prior_sigmas, redundancy_words

#: Causes whose coefficients belong to a session's sensor, not to the robot.
SESSION_KINDS = ("drift", "step", "wander", "temperature", "outliers", "sensor_periodic", "tracker_azimuth")


def is_private(name: str, measurement: str) -> bool:
    """True for an entry fitted per session: the set-up a new session places anew
    (:func:`~robocal.robot.setup_names`: tracker base and tool point; cable anchor and zero)
    or a coefficient of a session cause (``"step sample=12 row=14 c0"``)."""
    if name.split(" ")[0] in SESSION_KINDS:
        return True
    return name.startswith(("anchor_", "cable_offset") if measurement == "cable" else ("base_", "tool_"))


def load_sessions(data, robot=None, measurement=None, angle_unit=None, purpose: str = "a multi-session fit") -> tuple[list[Dataset], Robot]:
    """The sessions of ``data`` (a list of at least two files or Datasets) and their robot:
    each session given once, all of one robot and one measurement (else an error naming them).
    ``angle_unit`` is one unit for every session or a list of one per session (sessions recorded
    by different tools)."""
    if not isinstance(data, (list, tuple)) or len(data) < 2:
        raise InvalidParameterError(f"{purpose} needs a list of at least two sessions; got {data!r}")
    units = list(angle_unit) if isinstance(angle_unit, (list, tuple)) else [angle_unit] * len(data)
    if len(units) != len(data):
        raise InvalidParameterError(f"`angle_unit` gives {len(units)} units for {len(data)} sessions: give one for all, or one per session in their order")
    loaded = [load_inputs(d, robot, measurement, unit) for d, unit in zip(data, units)]
    require_distinct_sessions([d for d, _ in loaded])  # one session twice: its held-out figure would be a training error
    rob, kind = loaded[0][1], loaded[0][0].measurement
    for i, (d, r) in enumerate(loaded[1:], start=2):
        if r.name != rob.name or d.measurement != kind:
            raise InvalidParameterError(f"session {i} ({d.source or 'data'}) holds {d.measurement} data of {r.name}; session 1 holds {kind} data of {rob.name}")
    return [d for d, _ in loaded], rob


def concatenate(datasets: list[Dataset]) -> Dataset:
    """The samples of several sessions in one dataset (their file rows kept; ``t`` and ``temp``
    only where every session has them)."""
    first = datasets[0]

    def joined(name):
        values = [getattr(d, name) for d in datasets]
        return None if any(v is None for v in values) else np.concatenate(values)

    return replace(
        first,
        q=np.vstack([d.q for d in datasets]),
        y=np.vstack([d.y for d in datasets]),
        t=joined("t"),
        temp=joined("temp"),
        rows=np.concatenate([d.rows for d in datasets]),
        source=None,
        excluded=[],
        notes=[],
        extra={},
    )


#: A column whose part not explained by the columns kept before it is below this fraction of its
#: norm adds nothing the others cannot do: it is fixed.
REDUNDANT = 1e-7


def session_problems(robot: Robot, datasets: list[Dataset], mask, kinematic_prior=None) -> list[Problem]:
    """One :class:`Problem` per session with free sets that fit together (a ``kinematic_prior``
    ``(mm, deg)`` on the first only: it acts on the shared kinematics once).

    Fitted alone, each session keeps its set-up where it and the robot explain the same
    (:meth:`~robocal.robot.Robot.identifiability`); stacked, a shared parameter redundant with
    every session's set-up together (not with one alone) must be fixed too, since each session
    needs its own set-up. The columns
    of the stacked Jacobian at the sessions' starts are kept greedily — every session's set-up
    first, then the shared parameters — when they add a direction the kept ones do not span.
    """
    bases = [Problem.build(robot, d, mask=mask) for d in datasets]
    cols = np.unique(robot.columns(mask, "mask"))
    measurement = datasets[0].measurement
    private = [c for c in cols if is_private(robot.param_names[c], measurement)]
    shared = [c for c in cols if not is_private(robot.param_names[c], measurement)]
    starts = [b.start.copy() for b in bases]
    for start in starts[1:]:
        start[shared] = bases[0].start[shared]  # one robot: a shared parameter holds one value, at which every block is linearised
    blocks = [robot.jacobian(d.measurement, d.q, y=d.y, params=start, cols=private + shared) for d, start in zip(datasets, starts)]
    n, p = len(datasets), len(private)
    stacked = np.zeros((sum(len(J) for J in blocks), n * p + len(shared)))
    at = 0
    for s, J in enumerate(blocks):
        stacked[at : at + len(J), s * p : (s + 1) * p] = J[:, :p]
        stacked[at : at + len(J), n * p :] = J[:, p:]
        at += len(J)
    kept = _independent(stacked)
    labels = [f"{robot.param_names[c]} [session {s + 1}]" for s in range(n) for c in private] + [robot.param_names[c] for c in shared]
    why = {robot.param_names[c]: _redundancy(stacked, kept, n * p + i, labels) for i, c in enumerate(shared) if not kept[n * p + i]}
    out = []
    for s, (b, start) in enumerate(zip(bases, starts)):
        free = [c for i, c in enumerate(private) if kept[s * p + i]] + [c for i, c in enumerate(shared) if kept[n * p + i]]
        fixed = {robot.param_names[c]: why.get(robot.param_names[c], "redundant with the other sessions' set-ups") for c in cols if c not in free}
        out.append(replace(b, free=np.array(sorted(free), dtype=int), fixed=fixed, start=start))
    if kinematic_prior is not None:
        first = out[0]
        out[0] = replace(
            first, prior=kinematic_prior_pairs(robot, first.names, dict(zip(robot.param_names, first.start)), kinematic_prior_sigmas(kinematic_prior))
        )
    return out


def _independent(A: np.ndarray) -> np.ndarray:
    """Which columns of ``A``, taken in order, add a direction the kept ones do not span."""
    basis = np.zeros((A.shape[0], 0))
    kept = np.zeros(A.shape[1], dtype=bool)
    for j in range(A.shape[1]):
        norm = np.linalg.norm(A[:, j])
        if norm == 0.0:
            continue
        v = A[:, j] / norm
        v = v - basis @ (basis.T @ v)
        v = v - basis @ (basis.T @ v)  # twice: Gram-Schmidt keeps its orthogonality
        rest = np.linalg.norm(v)
        if rest > REDUNDANT:
            basis = np.column_stack([basis, v / rest])
            kept[j] = True
    return kept


def _redundancy(A: np.ndarray, kept: np.ndarray, j: int, labels: list) -> str:
    """Why column ``j`` of ``A`` was not kept: the kept columns before it that reproduce it, up to
    three, largest share first, with their coefficients on unit columns (as a single session's
    identifiability names them)."""
    before = np.flatnonzero(kept[:j])
    coef, *_ = np.linalg.lstsq(A[:, before], A[:, j], rcond=None)
    share = coef * np.linalg.norm(A[:, before], axis=0) / max(float(np.linalg.norm(A[:, j])), 1e-300)
    return redundancy_words([(labels[b], c) for b, c in zip(before, share) if abs(c) > 1e-3])


#: A column whose part the set-up's columns do not reproduce is below this fraction of its norm:
#: the set-up absorbs it on these poses (joint 1's zero and a tracker's rotation about the base's z).
INDISTINGUISHABLE = 1e-6


def setup_eliminated(S: np.ndarray, Z: np.ndarray) -> tuple[np.ndarray, dict]:
    """The columns ``Z`` (rows, p) with a session's set-up columns ``S`` (rows, s) eliminated:
    ``Z − S S⁺ Z``, whose Gram matrix is the Schur complement of the set-up in ``[S Z]ᵀ[S Z]``
    (what ``Z``'s entries are determined by once the set-up is fitted anew); and the columns the
    set-up reproduces (their rest below :data:`INDISTINGUISHABLE` of their norm), each with the
    set-up columns that do (up to three, largest share first)."""
    coef, *_ = np.linalg.lstsq(S, Z, rcond=None)
    rest = Z - S @ coef
    norm = np.linalg.norm(Z, axis=0)
    share = np.abs(coef) * np.linalg.norm(S, axis=0)[:, None] / np.maximum(norm, 1e-300)
    absorbed = {
        int(i): [int(k) for k in np.argsort(-share[:, i])[:3] if share[k, i] > 1e-3]
        for i in np.flatnonzero(np.linalg.norm(rest, axis=0) <= INDISTINGUISHABLE * norm)
    }
    return rest, absorbed


def schur_complement(G: np.ndarray, keep, drop) -> np.ndarray:
    """The information ``G[keep, keep] − G[keep, drop] G[drop, drop]⁺ G[drop, keep]`` on the entries
    ``keep`` once ``drop`` (a session's set-up) is fitted anew: symmetric, its negative eigenvalues
    set to zero. It is positive semi-definite in exact arithmetic; a set-up nearly redundant in
    itself (a SCARA's base and tool heights: ``G[drop, drop]`` conditioned 1e12) left eigenvalues
    of −2e-6 of the largest, and a Cholesky factor of a plan's prior failed."""
    keep, drop = np.asarray(keep, dtype=int), np.asarray(drop, dtype=int)
    S = G[np.ix_(keep, keep)]
    if drop.size:
        S = S - G[np.ix_(keep, drop)] @ np.linalg.pinv(G[np.ix_(drop, drop)], hermitian=True) @ G[np.ix_(drop, keep)]
    lam, U = np.linalg.eigh((S + S.T) / 2)
    return (U * np.clip(lam, 0.0, None)) @ U.T


def _split(problem, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A problem's residuals at ``x`` as (data rows, prior rows)."""
    r = problem.residuals(x)
    n = len(problem.data) * RESIDUAL_WIDTH[problem.data.measurement]
    return r[:n], r[n:]


def _csr_with_every_entry(J):
    """``J`` as CSR; a dense ``J`` with every entry kept, zeros too (its pattern then does not
    depend on its values)."""
    from scipy import sparse

    if is_sparse(J):
        return sparse.csr_array(J)
    m, n = J.shape
    return sparse.csr_array((np.ascontiguousarray(J).ravel(), np.tile(np.arange(n), m), np.arange(0, m * n + 1, n)), shape=(m, n))


class Sessions:
    """One problem per session over a shared parameter vector.

    ``x`` holds every shared entry once (named as in the sessions' problems) and every private
    entry (:func:`is_private`) once per session (named ``"<name> [session s]"``, 1-based). Shared
    entries start where the first session that has them starts.
    """

    def __init__(self, problems: list):
        self.problems = list(problems)
        self.robot, self.measurement = self.problems[0].robot, self.problems[0].data.measurement
        index: dict = {}
        self.names, self.maps = [], []
        start = []
        for s, p in enumerate(self.problems, start=1):
            positions = []
            for name, value in zip(p.names, p.x0):
                key = (name, s) if is_private(name, self.measurement) else (name, 0)
                if key not in index:
                    index[key] = len(self.names)
                    self.names.append(f"{name} [session {s}]" if key[1] else name)
                    start.append(value)
                positions.append(index[key])
            self.maps.append(np.array(positions, dtype=int))
        self._x0 = np.array(start, dtype=np.float64)
        self.data = concatenate([p.data for p in self.problems])
        self._layout = None  # of the stacked sparse Jacobian (:meth:`_stacked_sparse`)

    @property
    def x0(self) -> np.ndarray:
        return self._x0.copy()

    # A result of the stacked fit states the robot with the first session's set-up (each
    # session's own is in the result's ``sessions``): its entries come first in ``names``.
    @property
    def free(self) -> np.ndarray:
        return self.problems[0].free

    @property
    def fixed(self) -> dict:
        return self.problems[0].fixed

    def full(self, x: np.ndarray) -> np.ndarray:
        """The robot's parameter vector with the first session's set-up."""
        return self.problems[0].full(self.session_x(x, 0))

    def describe_causes(self, x: np.ndarray, std=None) -> list[dict]:
        """The causes of the sessions' problems (extended ones), each shared cause once and each
        session term with its ``session`` (1-based)."""
        out, seen = [], set()
        for s, p in enumerate(self.problems):
            if not hasattr(p, "describe_causes"):
                return []
            for cause in p.describe_causes(self.session_x(x, s), None if std is None else self.session_x(std, s)):
                if cause["kind"] in SESSION_KINDS:
                    out.append({**cause, "session": s + 1})
                elif cause["label"] not in seen:
                    seen.add(cause["label"])
                    out.append(cause)
        return out

    def session_x(self, x: np.ndarray, s: int) -> np.ndarray:
        """Session ``s``'s (0-based) own parameter vector in ``x``."""
        return np.asarray(x)[self.maps[s]]

    def data_residuals(self, x: np.ndarray) -> np.ndarray:
        return np.concatenate([p.data_residuals(self.session_x(x, s)) for s, p in enumerate(self.problems)])

    def residuals(self, x: np.ndarray) -> np.ndarray:
        # Data rows of every session first, then every prior row: what the robust loss expects.
        parts = [_split(p, self.session_x(x, s)) for s, p in enumerate(self.problems)]
        return np.concatenate([d for d, _ in parts] + [r for _, r in parts])

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        blocks = [(p.jacobian(self.session_x(x, s)), len(p.data) * RESIDUAL_WIDTH[p.data.measurement]) for s, p in enumerate(self.problems)]
        if any(is_sparse(J) for J, _ in blocks):  # joint maps: stacked sparse, data rows first
            return self._stacked_sparse([_csr_with_every_entry(J) for J, _ in blocks], [n for _, n in blocks])
        n_data, n_prior = sum(n for _, n in blocks), sum(J.shape[0] - n for J, n in blocks)
        J = np.zeros((n_data + n_prior, len(self.names)))
        at_data, at_prior = 0, n_data
        for (Js, n), cols in zip(blocks, self.maps):
            J[at_data : at_data + n, cols] = Js[:n]
            J[at_prior : at_prior + Js.shape[0] - n, cols] = Js[n:]
            at_data, at_prior = at_data + n, at_prior + Js.shape[0] - n
        return J

    def _stacked_sparse(self, blocks: list, n_data: list):
        """The sessions' CSR Jacobians ``blocks`` (the first ``n_data`` rows of each its data
        rows) stacked: every session's data rows, then every session's prior rows; each
        session's columns moved to their places among all :attr:`names`, ascending in every row
        (what the core's Gram adds fastest). The sessions' patterns do not change with ``x``:
        where the entries go is worked out once, and each call only moves the values."""
        from scipy import sparse

        # A session's pattern is fixed: an extended problem lays its sparse Jacobian out once, a
        # dense one keeps every entry. Its rows' lengths guard the layout (a full comparison of
        # the column indices cost as much as the gather).
        patterns = [J.indptr for J in blocks]
        if self._layout is None or not all(np.array_equal(a, b) for a, b in zip(patterns, self._layout[3])):
            starts = np.concatenate([[0], np.cumsum([J.nnz for J in blocks])])  # each block's entries among all
            pieces = [(s, 0, n) for s, n in enumerate(n_data)] + [(s, n, J.shape[0]) for s, (J, n) in enumerate(zip(blocks, n_data))]
            indptr, indices, source, at = [np.zeros(1, dtype=np.int64)], [], [], 0
            for s, lo, hi in pieces:
                J = blocks[s]
                first, last = J.indptr[lo], J.indptr[hi]
                cols = self.maps[s][J.indices[first:last]]
                order = np.lexsort((cols, np.repeat(np.arange(hi - lo), np.diff(J.indptr[lo : hi + 1]))))
                indices.append(cols[order])
                source.append(starts[s] + first + order)
                indptr.append(J.indptr[lo + 1 : hi + 1] - first + at)
                at += last - first
            self._layout = (np.concatenate(indptr), np.concatenate(indices), np.concatenate(source), [a.copy() for a in patterns])
        indptr, indices, source, _ = self._layout
        values = np.concatenate([J.data for J in blocks])[source]
        return sparse.csr_array((values, indices, indptr), shape=(len(indptr) - 1, len(self.names)))

    def clip(self, x: np.ndarray) -> np.ndarray:
        x = np.array(x, dtype=np.float64)
        for s, p in enumerate(self.problems):
            x[self.maps[s]] = p.clip(x[self.maps[s]])
        return x


class Partial:
    """``problem`` with only the entries named ``free`` fitted, the others held at ``x_full``."""

    def __init__(self, problem, free: list[str], x_full: np.ndarray):
        names = list(problem.names)
        missing = [n for n in free if n not in names]
        if missing:
            raise ValueError(f"{missing} are not entries of the problem")
        self.problem, self.robot, self.data = problem, problem.robot, problem.data
        self.cols = np.array([names.index(n) for n in free], dtype=int)
        self.names = list(free)
        self._full = np.array(x_full, dtype=np.float64)

    @property
    def x0(self) -> np.ndarray:
        return self._full[self.cols].copy()

    def full_x(self, x: np.ndarray) -> np.ndarray:
        """The problem's whole vector with the fitted entries set to ``x``."""
        full = self._full.copy()
        full[self.cols] = x
        return full

    def data_residuals(self, x: np.ndarray) -> np.ndarray:
        return self.problem.data_residuals(self.full_x(x))

    def residuals(self, x: np.ndarray) -> np.ndarray:
        return self.problem.residuals(self.full_x(x))

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        return self.problem.jacobian(self.full_x(x))[:, self.cols]

    def clip(self, x: np.ndarray) -> np.ndarray:
        return self.problem.clip(self.full_x(x))[self.cols]
