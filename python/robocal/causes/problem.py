"""The extended model: the geometric calibration problem plus the coefficients of named causes.

:class:`ExtendedProblem` has the interface the production LM works on (``x0``, ``residuals``,
``jacobian``, ``data_residuals``, ``clip``, ``data``), so the same solver fits it; every residual
and Jacobian is evaluated by the Rust core (at the effect-corrected joint angles), only the
cause columns are assembled here. Several sessions' extended problems are fitted at once
stacked (:func:`stack`).
"""

from __future__ import annotations

from dataclasses import replace
from functools import cached_property
from typing import Optional

import numpy as np

from ..calibration.problem import Problem, fit_row_weights, rotation_weight
from ..calibration.sessions import Sessions
from ..kernels import is_sparse, stack_csr
from ..data.dataset import Dataset
from ..serial_robot import RESIDUAL_WIDTH
from ..stats import rmse_of_squares
from .candidates import Candidate


def squared_errors(weighted: np.ndarray, k: int) -> np.ndarray:
    """Per sample, the squared position (or cable) error and the squared rotation error as a
    fit weighs it (both mm²; the second zero but for pose data), (m, 2), from the residuals
    ``weighted`` (m·k,) with the fit's row weights applied. The first is what a report states,
    their sum what the fit minimises: held-out selection judges the sum, so that a cause seen
    only in the orientation (joint 6's error) counts as the sensor's noise says it should."""
    r = weighted.reshape(-1, k)
    return np.column_stack([np.sum(r[:, :3] ** 2, axis=1), np.sum(r[:, 3:] ** 2, axis=1)])


def reported_rmse(errors: np.ndarray) -> float:
    """RMSE of eq. (28) of :func:`squared_errors` ``errors``: the position (or cable) error, mm."""
    return rmse_of_squares(errors[:, 0])


def judged_rmse(errors: np.ndarray) -> float:
    """RMS of what the fit minimises (position and weighted rotation) of :func:`squared_errors`
    ``errors``, mm: what held-out selection compares. The same as :func:`reported_rmse` but for
    pose data."""
    return rmse_of_squares(errors.sum(axis=1))


def judged_unit(measurement: str) -> str:
    """The unit of a :func:`judged_rmse` of ``measurement`` data, as a report states it."""
    return "mm (position and orientation weighed as in the fit)" if measurement == "pose" else "mm"


def rotation_squared_rad(errors: np.ndarray, data: Dataset) -> np.ndarray:
    """Per sample, the squared orientation error (rad²) of pose ``data``'s :func:`squared_errors`
    ``errors``."""
    return errors[:, 1] / rotation_weight(data) ** 2


def rotation_rmse_deg(errors: np.ndarray, data: Dataset) -> float:
    """RMS orientation error (deg) of pose ``data``'s :func:`squared_errors` ``errors``."""
    return float(np.degrees(np.sqrt(np.mean(rotation_squared_rad(errors, data)))))


def _plain(detail: dict) -> dict:
    """A cause's detail as JSON values."""
    return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in detail.items()}


def _rows_of(cache: dict, basis, rows):
    """``basis[rows]`` as CSR (``rows`` or a function giving them), kept in ``cache`` under the
    basis itself: a problem's samples do not change, and a map's roughness variants share one
    basis, so they share its rows too (the entry holds the basis, so its id is not reused)."""
    held = cache.get(id(basis))
    if held is None or held[0] is not basis:
        held = cache[id(basis)] = (basis, basis[rows() if callable(rows) else rows].tocsr())
    return held[1]


class ExtendedProblem:
    """Geometric free parameters and cause coefficients, on the samples ``idx`` of ``data``.

    ``x`` is ``[θ[free], c_1, c_2, ...]``: ``free`` is the baseline's free set plus the
    parameters of ``parameters``-stage causes, and each ``joints``/``observations`` cause
    appends its coefficients in order.
    """

    def __init__(self, base: Problem, causes: list[Candidate], data: Dataset, idx: np.ndarray):
        self.base, self.robot, self.causes = base, base.robot, list(causes)
        self.full_data, self.idx = data, np.asarray(idx)
        self.data = data.subset(self.idx)
        self.k = RESIDUAL_WIDTH[data.measurement]
        extra = [self.robot.index(n) for c in self.causes if c.stage == "parameters" for n in c.params]
        self.free = np.concatenate([base.free, np.array(extra, dtype=int)]).astype(int)
        self.start = base.start
        self.slices, at = [], len(self.free)
        for c in self.causes:
            n = 0 if c.stage == "parameters" else c.size
            self.slices.append(slice(at, at + n))
            at += n
        self.n = at
        # The base problem's priors (name -> (mean, sigma)) act on the same names here.
        names = self.names
        self._prior = [(names.index(n), m, sd) for n, (m, sd) in base.prior.items() if n in names]
        self._lengths = [self.robot.index(f"{p}{j + 1}") for j in range(self.robot.n_joints) for p in ("a", "d")]
        # The parameter each joint's reading adds to: a joint cause's Δq moves the chain as it does.
        self._joint_variables = [self.robot.index(f"{'d' if j in self.robot.prismatic else 'theta'}{j + 1}") for j in range(self.robot.n_joints)]
        # Joint maps' sparse basis rows (per cause) and the Jacobian's rows beyond the data, built
        # on first use: the samples of a problem do not change.
        self._sample_rows: dict = {}
        self._residual_rows: dict = {}
        self._constant_csr = None
        self._pattern = None  # the sparse Jacobian's (indptr, indices): the same at every x

    # -- the vector ---------------------------------------------------------------------------
    @property
    def x0(self) -> np.ndarray:
        return np.concatenate([self.start[self.free], np.zeros(self.n - len(self.free))])

    def start_from(self, x: np.ndarray, other: "ExtendedProblem") -> np.ndarray:
        """A start for this model from ``x`` of ``other`` (a model with other causes): the
        entries they share (by name) from ``x``, the others at their start values."""
        at = {name: i for i, name in enumerate(other.names)}
        out = self.x0
        for i, name in enumerate(self.names):
            if name in at:
                out[i] = x[at[name]]
        return out

    def full(self, x: np.ndarray) -> np.ndarray:
        p = self.start.copy()
        p[self.free] = x[: len(self.free)]
        return p

    def coefficients(self, x: np.ndarray, cause: Candidate) -> np.ndarray:
        """The coefficients of ``cause`` in ``x`` (parameter values for ``parameters`` causes)."""
        i = self.causes.index(cause)
        if cause.stage == "parameters":
            return np.array([x[list(self.free).index(self.robot.index(n))] for n in cause.params])
        return np.asarray(x[self.slices[i]])

    @property
    def names(self) -> list[str]:
        """Names of the entries of ``x``: parameters, then ``"<cause label> c<i>"``."""
        coefs = [f"{c.label} c{i}" for c in self.causes if c.stage != "parameters" for i in range(c.size)]
        return [self.robot.param_names[k] for k in self.free] + coefs

    @property
    def fixed(self) -> dict:
        return self.base.fixed

    def describe_causes(self, x: np.ndarray, std=None) -> list[dict]:
        """Each cause with its physical parameters (± std where ``std`` is given) and, if they
        are implausible, why."""
        out = []
        for c in self.causes:
            physical, why = c.physical(self.coefficients(x, c), None if std is None else self.coefficients(std, c), self.robot, self.robot.params)
            joint = None if c.joint is None else c.joint + 1
            coefficients = [float(v) for v in self.coefficients(x, c)]
            entry = {"kind": c.kind, "joint": joint, "label": c.label, "detail": _plain(c.detail), "coefficients": coefficients}
            out.append({**entry, "params": physical, "implausible": why})
        return out

    def clip(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(x, dtype=np.float64)

    def with_samples(self, idx: np.ndarray) -> "ExtendedProblem":
        """The same model on other samples of the same dataset."""
        return ExtendedProblem(self.base, self.causes, self.full_data, idx)

    # -- evaluation ---------------------------------------------------------------------------
    def joints(self, x: np.ndarray) -> np.ndarray:
        """Joint angles the links take: recorded plus every joint cause's ``B·c``."""
        q = self.data.q.copy()
        for c, s in zip(self.causes, self.slices):
            if c.stage == "joints":
                q[:, c.joint] += (self._sample_basis(c) if is_sparse(c.basis) else c.basis[self.idx]) @ x[s]
        return q

    def _sample_basis(self, cause: Candidate):
        """A joint map's basis at the problem's samples, CSR; cached (:func:`_rows_of`)."""
        return _rows_of(self._sample_rows, cause.basis, self.idx)

    def jacobian_parts(self, x: np.ndarray, extra: list[int]) -> tuple[np.ndarray, np.ndarray, dict]:
        """Rust Jacobian over ``free``, every joint variable's column (``theta``, or ``d`` of a
        prismatic joint), the link lengths and ``extra``: the free columns, the full parameters
        and the parts ``joints``, ``lengths`` and ``extra``
        that :meth:`columns` builds a cause's columns from. Computed once for many candidates at
        the same ``x``: one Jacobian of the whole chain serves them all."""
        p = self.full(x)
        J = self._chain_jacobian(x, p, list(self.free) + self._joint_variables + self._lengths + list(extra))
        at = len(self.free)
        lengths_at = at + len(self._joint_variables)
        extra_at = lengths_at + len(self._lengths)
        parts = {"joints": J[:, at:lengths_at], "lengths": J[:, lengths_at:extra_at], "extra": J[:, extra_at:]}
        return J[:, :at], p, parts

    def columns(self, x: np.ndarray, cause: Candidate, parts: dict = None, p: np.ndarray = None) -> np.ndarray:
        """``∂h/∂c`` of ``cause`` at ``x``, shape (m·k, n_c)."""
        if parts is None:
            extra = [self.robot.index(n) for n in cause.params]
            _, p, parts = self.jacobian_parts(x, extra)
            if cause.stage == "parameters":
                return parts["extra"]
        if cause.stage == "joints":
            dh_dq = parts["joints"][:, cause.joint]
            if is_sparse(cause.basis):  # a joint map: four spline coefficients per sample, each row scaled by ∂h/∂q_j
                from scipy import sparse

                B = self._basis_rows(cause)
                return sparse.csr_array((B.data * np.repeat(dh_dq, np.diff(B.indptr)), B.indices, B.indptr), shape=B.shape)
            return dh_dq[:, None] * np.repeat(cause.basis[self.idx], self.k, axis=0)
        if cause.stage == "observations":
            if cause.basis is None:  # thermal expansion of the links: Σ ∂h/∂ℓ · ℓ · ΔT
                stretch = parts["lengths"] @ p[self._lengths]
                return (stretch * np.repeat(cause.signal[self.idx], self.k))[:, None]
            return cause.basis[self.idx].reshape(len(self.idx) * self.k, -1)
        raise ValueError(f"columns of a parameters cause come from the Jacobian: {cause.label}")

    def weighted_columns(self, x: np.ndarray, cause: Candidate, parts: dict = None, p: np.ndarray = None):
        """:meth:`columns` weighted as the rows of :meth:`residuals` and :meth:`jacobian` are
        (pose data: the rotation rows by the noise ratio): what a screening beside them needs."""
        C = self.columns(x, cause, parts, p)
        if is_sparse(C):
            from scipy import sparse

            return sparse.diags_array(self.row_weights) @ C
        return C * self.row_weights[:, None]

    @cached_property
    def row_weights(self) -> np.ndarray:
        """Weights of the data rows in :meth:`residuals` (the base problem's: rotation rows of
        pose data weighted by :func:`~robocal.calibration.problem.rotation_weight`), (m·k,)."""
        return fit_row_weights(self.base.data, len(self.idx))

    def squared_errors(self, x: np.ndarray) -> np.ndarray:
        """:func:`squared_errors` of the samples under ``x``, (m, 2)."""
        return squared_errors(self.data_residuals(x) * self.row_weights, self.k)

    @property
    def _penalised(self) -> list:
        return [(c.penalty, s) for c, s in zip(self.causes, self.slices) if c.penalty is not None]

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """:meth:`data_residuals` followed by the prior rows of the base problem and the
        roughness rows of the causes that have them (joint maps)."""
        parts = [self.data_residuals(x) * self.row_weights]
        if self._prior:
            idx, mean, sigma = (np.array(v) for v in zip(*self._prior))
            parts.append(self.base.prior_scale * (mean - np.asarray(x)[idx]) / sigma)
        parts += [-P @ x[s] for P, s in self._penalised]
        return np.concatenate(parts)

    def data_residuals(self, x: np.ndarray) -> np.ndarray:
        """``y − h`` of every sample, flattened."""
        p, q = self.full(x), self.joints(x)
        r = self.robot.residuals(self.data.measurement, q, self.data.y, params=p).ravel()
        observed = [(c, s) for c, s in zip(self.causes, self.slices) if c.stage == "observations"]
        if observed:
            parts = self.jacobian_parts(x, [])[2] if any(c.basis is None for c, _ in observed) else {}
            for c, s in observed:
                r = r - self.columns(x, c, parts, p) @ x[s]
        return r

    def jacobian(self, x: np.ndarray, evaluated: Optional[tuple] = None) -> np.ndarray:
        """``∂r/∂x``: the data rows weighted, then the constant rows of the priors and penalties;
        ``evaluated``: :meth:`jacobian_parts` ``(x, [])`` if the caller has it."""
        if evaluated is None and not self._columned:  # the chain's free columns are all of it
            blocks = [self._chain_jacobian(x, self.full(x), self.free)]
        else:
            J, p, parts = self.jacobian_parts(x, []) if evaluated is None else evaluated
            blocks = [J] + [self.columns(x, c, parts, p) for c in self._columned]
        if any(is_sparse(b) for b in blocks):  # joint maps: the sparse Jacobian their solver takes
            return self._sparse_jacobian(blocks)
        J = (np.hstack(blocks) if len(blocks) > 1 else blocks[0]) * self.row_weights[:, None]
        rows = self._constant_rows(J.shape[1])
        return np.vstack([J, rows]) if len(rows) else J

    def _chain_jacobian(self, x: np.ndarray, p: np.ndarray, cols) -> np.ndarray:
        """The chain's Jacobian over the parameter columns ``cols`` at ``x`` (full parameters
        ``p``), at the joint angles the links take."""
        return self.robot.jacobian(self.data.measurement, self.joints(x), y=self.data.y, params=p, cols=cols)

    @cached_property
    def _columned(self) -> list:
        """The causes with columns of their own in the Jacobian (all but ``parameters`` causes)."""
        return [c for c in self.causes if c.stage != "parameters"]

    def _constant_rows(self, n: int) -> np.ndarray:
        """The Jacobian's rows beyond the data, (rows, n): the base problem's priors and the
        causes' roughness penalties, which do not depend on ``x``."""
        rows = np.zeros((len(self._prior), n))
        for row, (i, _, sigma) in enumerate(self._prior):
            rows[row, i] = self.base.prior_scale / sigma
        for P, s in self._penalised:
            block = np.zeros((len(P), n))
            block[:, s] = P
            rows = np.vstack([rows, block])
        return rows

    def _basis_rows(self, cause: Candidate):
        """A joint map's basis at every residual row (its sample's row repeated ``k`` times), CSR;
        cached (:func:`_rows_of`)."""
        return _rows_of(self._residual_rows, cause.basis, lambda: np.repeat(self.idx, self.k))

    def _sparse_jacobian(self, blocks: list):
        """The Jacobian as CSR, laid out from its blocks by the Rust core
        (:func:`~robocal.kernels.stack_csr`): the data rows weighted (:attr:`row_weights`) — the
        dense blocks (geometry, causes with a few columns) fill every row, the maps' sparse ones
        their four entries, each row's columns in ascending order (runs of consecutive columns:
        what the core's Gram adds fastest) — then the :meth:`_constant_rows`."""
        from scipy import sparse

        offsets = np.concatenate([[0], np.cumsum([b.shape[1] for b in blocks])])
        n = int(offsets[-1])
        dense = [i for i, b in enumerate(blocks) if not is_sparse(b)]
        if self._constant_csr is None:
            self._constant_csr = sparse.csr_array(self._constant_rows(n))
        dense_cols = np.concatenate([np.arange(offsets[i], offsets[i + 1]) for i in dense])
        thin = [(blocks[i], int(offsets[i])) for i, b in enumerate(blocks) if is_sparse(b)]
        indptr, indices, data = stack_csr(np.hstack([blocks[i] for i in dense]), dense_cols, thin, self.row_weights, self._constant_csr, self._pattern is None)
        if self._pattern is None:
            self._pattern = (indptr, indices)
        indptr, indices = self._pattern
        return sparse.csr_array((data, indices, indptr), shape=(len(indptr) - 1, n))

    def cost(self, x: np.ndarray) -> float:
        r = self.residuals(x)
        return 0.5 * float(r @ r)


def stack(problems: list, prior: Optional[dict] = None) -> Sessions:
    """The sessions' extended problems stacked, the ``prior`` (if any) and the joint maps'
    roughness penalties on the first one only: they act on the shared entries once."""
    first, rest = problems[0], [_without_penalties(p) for p in problems[1:]]
    if prior:
        first = ExtendedProblem(replace(first.base, prior=prior), first.causes, first.full_data, first.idx)
    return Sessions([first] + rest)


def _without_penalties(problem: ExtendedProblem) -> ExtendedProblem:
    if not any(c.penalty is not None for c in problem.causes):
        return problem
    causes = [replace(c, penalty=None) if c.penalty is not None else c for c in problem.causes]
    return ExtendedProblem(problem.base, causes, problem.full_data, problem.idx)
