"""The linear screening of a selection round: every candidate cause judged against the current
model linearised at its fit, ``r ≈ J·δ``, by cross-validation and by the extra-sum-of-squares F
test (:class:`Screen`; used by :func:`~.select.screen_round` and the backward check's linear
pre-check)."""

from __future__ import annotations

from typing import Optional

import numpy as np
from scipy.stats import f as f_dist

from ..data.splits import residual_rows
from ..kernels import SVD_RCOND, truncated_svd, unit_columns
from ..stats import robust_sigma


#: Singular values below this fraction of the largest count as zero in the linear screening.
RCOND = SVD_RCOND


#: Residual components whose robust noise differs by more than this factor are scaled apart in
#: the screening's F test.
WHITEN_RATIO = 1.2


class Fold:
    """A fold of the screening's ``r ≈ J·δ``: its training and held-out rows, the held-out samples,
    the held-out rows of ``J`` and ``r``, and the training rows' truncated SVD of ``J`` (``s, Vᵀ``)
    with ``Uᵀr``, from the triangular factor ``R`` of their ``[J r]`` (``U`` is not formed: a
    candidate's ``UᵀC`` comes from products, :func:`_from_products`). ``rows`` (:meth:`rows`):
    the SVD of the training rows themselves, for a candidate projected row by row."""

    def __init__(self, J: np.ndarray, r: np.ndarray, rows_tr: np.ndarray, rows_te: np.ndarray, test: np.ndarray, R: np.ndarray):
        p = J.shape[1]
        self.J, self.r, self.rows_tr, self.rows_te, self.test = J, r, rows_tr, rows_te, test
        self.J_te, self.r_te = J[rows_te], r[rows_te]
        R = np.vstack([R, np.zeros((max(p + 1 - len(R), 0), p + 1))])  # fewer rows than columns: padded
        U, sv, self.Vt = np.linalg.svd(R[:p, :p])
        keep = sv > RCOND * sv[0] if sv.size else sv > 0
        U, self.sv, self.Vt = U[:, keep], sv[keep], self.Vt[keep]
        z = R[:p, p]  # Qᵀr: r's part in the span of the training rows of J
        self.coef = U.T @ z
        self.rss = float(R[p, p] ** 2 + np.sum((z - U @ self.coef) ** 2))  # what J leaves of r
        self._rows = None

    def rows(self) -> tuple:
        """``(U, s, Vᵀ, Uᵀr, r⊥)`` of the training rows' own truncated SVD (computed once)."""
        if self._rows is None:
            U, sv, Vt = truncated_svd(self.J[self.rows_tr], RCOND)
            coef = U.T @ self.r[self.rows_tr]
            self._rows = (U, sv, Vt, coef, self.r[self.rows_tr] - U @ coef)
        return self._rows


def scheme_folds(J: np.ndarray, r: np.ndarray, folds: list, k: int) -> list[Fold]:
    """The :class:`Fold` of each ``(train, test)`` pair of samples. Where the held-out samples
    partition the data and each fold trains on the rest, the training rows' triangular factors
    come from the held-out blocks' (a tall-skinny QR: each row factored once a scheme)."""
    rows = lambda samples: residual_rows(samples, k)
    Jr = np.column_stack([J, r])
    factor = lambda A: np.linalg.qr(A, mode="r")
    m = len(r) // k
    tests = np.sort(np.concatenate([test for _, test in folds]))
    partition = np.array_equal(tests, np.arange(m)) and all(len(np.union1d(train, test)) == m == len(train) + len(test) for train, test in folds)
    blocks = [factor(Jr[rows(test)]) for _, test in folds] if partition else None
    out = []
    for i, (train, test) in enumerate(folds):
        R = factor(np.vstack([b for j, b in enumerate(blocks) if j != i])) if partition else factor(Jr[rows(train)])
        out.append(Fold(J, r, rows(train), rows(test), test, R))
    return out


class Screen:
    """Linear screening of candidates against the current model ``r ≈ J·δ``.

    Adding columns ``C`` to ``J`` is solved by the Frisch–Waugh–Lovell split: ``C`` and ``r``
    projected off the column space of each fold's ``J`` (its truncated SVD, computed once per
    round and shared by every candidate), the small problem in ``C`` solved there and ``J``'s
    coefficients recovered from the SVD. The projection needs only products where they are
    accurate (:func:`_from_products`): a candidate then costs a pass over all rows and one over
    each scheme's held-out rows, not a projection of every fold's training rows (five times more
    rows a scheme). A candidate nearly in the span of ``J``'s barely determined directions is
    projected row by row (:func:`_projected_rows`), as every candidate was before.
    """

    def __init__(self, J: np.ndarray, r: np.ndarray, schemes: dict, k: int):
        self.J, self.r, self.k = unit_columns(J)[0], r, k
        self.m = len(r) // k
        self.folds = {name: scheme_folds(self.J, r, folds, k) for name, folds in schemes.items()}
        # The F test assumes one noise level for every row: a pose's position and rotation rows
        # (weighted as the fit weighs them) need not share one, and a test pooled over both
        # over-rates a candidate that touches the noisier rows (a step of the position reading
        # on clean pose data: p = 1e-6). Its rows are scaled by each component's robust noise.
        sigma = robust_sigma(r.reshape(self.m, k))
        self.whiten = np.tile(1.0 / sigma, self.m) if k > 1 and np.max(sigma) > WHITEN_RATIO * np.min(sigma) else None
        w = np.ones(len(r)) if self.whiten is None else self.whiten
        self.Jw, self.rw = unit_columns(J * w[:, None])[0], r * w
        none = np.array([], dtype=int)
        self.all = Fold(self.Jw, self.rw, np.arange(len(r)), none, none, np.linalg.qr(np.column_stack([self.Jw, self.rw]), mode="r"))

    def errors(self, C: np.ndarray, P: Optional[np.ndarray] = None) -> dict:
        """Held-out squared error per sample of ``r ≈ [J, C]·δ`` (``C`` penalised by ``P``)
        fitted per fold, per scheme."""
        C, P = _unit_penalised(C, P)
        JtC, CtC, Ctr = self.J.T @ C, C.T @ C, C.T @ self.r
        out = {}
        for name, folds in self.folds.items():
            out[name] = np.zeros(self.m)
            for fold in folds:
                C_te = C[fold.rows_te]
                trained = (JtC - fold.J_te.T @ C_te, CtC - C_te.T @ C_te, Ctr - C_te.T @ fold.r_te)  # the training rows' products
                dJ, c = _solve(fold, C, P, trained)[:2]
                e = fold.r_te - fold.J_te @ dJ - C_te @ c
                out[name][fold.test] = (e * e).reshape(-1, self.k).sum(axis=1)
        return out

    def f_test(self, C: np.ndarray, inflation: float = 1.0, P: Optional[np.ndarray] = None) -> float:
        """p-value of the extra-sum-of-squares F test for adding ``C`` (exact for independent
        Gaussian noise in the linearised model; for residuals correlated in time, the statistic
        and the residual degrees of freedom divided by their variance ``inflation``; a penalised
        ``C`` counts its effective degrees of freedom)."""
        if self.whiten is not None:  # the penalty is in the residual's units: scaled as its rows are
            C, P = C * self.whiten[:, None], None if P is None else P * float(np.median(self.whiten))
        C, P = _unit_penalised(C, P)
        _, c, extra, h, G, rss0 = _solve(self.all, C, P, (self.Jw.T @ C, C.T @ C, C.T @ self.rw))
        rss1, dof = rss0 - 2.0 * float(c @ h) + float(c @ G @ c), len(self.rw) - len(self.all.sv) - extra
        if extra < 0.5 or dof < 1 or rss1 <= 0:
            return 1.0
        return float(f_dist.sf(max(rss0 - rss1, 0.0) / extra / (rss1 / dof) / inflation, extra, max(dof / inflation, 1.0)))


#: Relative rounding of a product of unit columns over one row (double precision, with room for
#: the sums' growth); see :func:`_from_products`.
ROUNDING = 1e-15
#: The products are used when ``C⊥ᵀC⊥`` (with the penalty) exceeds their rounding by this factor
#: in every direction: its coefficients are then accurate to about its inverse.
TRUSTED = 1e4


def _solve(fold: Fold, C: np.ndarray, P: Optional[np.ndarray], trained: tuple) -> tuple:
    """``(δ_J, c, dof, C⊥ᵀr⊥, C⊥ᵀC⊥, r⊥ᵀr⊥)`` of ``r ≈ J·δ_J + C·c`` on ``fold``'s training rows:
    ``c`` penalised by ``‖P·c‖²`` if ``P`` is given (a wander's roughness), and the degrees of
    freedom ``C`` adds (its rank, or the trace of its share of the hat matrix). From the training
    rows' products ``trained`` (``JᵀC, CᵀC, Cᵀr``) where they are accurate
    (:func:`_from_products`), else from ``C``'s rows projected (:func:`_projected_rows`)."""
    sv, Vt, coef, rss = fold.sv, fold.Vt, fold.coef, fold.rss
    UC, G, h = _from_products(fold, *trained, P)
    if G is None:
        U, sv, Vt, coef, r_perp = fold.rows()
        UC, G, h = _projected_rows(fold, C, U, r_perp)
        rss = float(r_perp @ r_perp)
    if C.shape[1] == 0:
        c, dof = np.zeros(0), 0.0
    elif P is None:  # least squares of minimum norm: C⊥'s singular values beyond J's rcond
        values, vectors = np.linalg.eigh(G)
        keep = values > (RCOND * (sv[0] if sv.size else 1.0)) ** 2
        c, dof = vectors[:, keep] @ ((vectors[:, keep].T @ h) / values[keep]), float(np.count_nonzero(keep))
    else:
        inverse = np.linalg.pinv(G + P.T @ P, rcond=RCOND)
        c, dof = inverse @ h, float(np.trace(inverse @ G))
    return Vt.T @ ((coef - UC @ c) / sv), c, dof, h, G, rss


def _from_products(fold: Fold, JtC: np.ndarray, CtC: np.ndarray, Ctr: np.ndarray, P: Optional[np.ndarray]) -> tuple:
    """``(UᵀC, C⊥ᵀC⊥, C⊥ᵀr⊥)`` from the training rows' products: ``UᵀC = Σ⁻¹·Vᵀ·JᵀC`` and
    ``C⊥ᵀC⊥ = CᵀC − (UᵀC)ᵀUᵀC``, ``C⊥ᵀr⊥ = Cᵀr − (UᵀC)ᵀUᵀr``. ``JᵀC``'s rounding, divided by
    ``J``'s singular values, bounds what ``C⊥ᵀC⊥`` can resolve: if a direction of it (with the
    penalty) lies within :data:`TRUSTED` times that, ``C⊥ᵀC⊥`` is None (project the rows)."""
    UC = (fold.Vt @ JtC) / fold.sv[:, None]
    G = CtC - UC.T @ UC
    if G.size:
        # JᵀC's rounding, over Σ: each column's UᵀC, and twice its product with UᵀC in C⊥ᵀC⊥
        rounding = ROUNDING * np.sqrt(len(fold.rows_tr))
        error = rounding * (1.0 + 2.0 * float(np.max(np.abs(UC).T @ (1.0 / fold.sv))))
        if np.linalg.eigvalsh(G if P is None else G + P.T @ P)[0] <= TRUSTED * error:
            return UC, None, None
    return UC, G, Ctr - UC.T @ fold.coef


def _projected_rows(fold: Fold, C: np.ndarray, U: np.ndarray, r_perp: np.ndarray) -> tuple:
    """``(UᵀC, C⊥ᵀC⊥, C⊥ᵀr⊥)`` from ``C``'s training rows projected off ``U``, the training
    rows' left singular vectors (``r⊥``: what they leave of ``r``)."""
    C_tr = C[fold.rows_tr]
    UC = U.T @ C_tr
    C_perp = C_tr - U @ UC
    return UC, C_perp.T @ C_perp, C_perp.T @ r_perp


def _unit_penalised(C: np.ndarray, P: Optional[np.ndarray]) -> tuple[np.ndarray, Optional[np.ndarray]]:
    """``C`` with unit columns, and its penalty ``P`` for the coefficients so scaled."""
    scale = np.linalg.norm(C, axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    return C / scale, None if P is None else P / scale
