"""The linear screening of a selection round: every candidate cause judged against the current
model linearised at its fit, ``r ≈ J·δ``, by cross-validation and by the extra-sum-of-squares F
test (:class:`Screen`; used by :func:`~.select.screen_round` and the backward check's linear
pre-check)."""

from __future__ import annotations

from typing import Optional

import numpy as np
from scipy.stats import f as f_dist

from ..kernels import SVD_RCOND, truncated_svd, unit_columns
from ..stats import robust_sigma
from ..threads import thread_map


#: Singular values below this fraction of the largest count as zero in the linear screening.
RCOND = SVD_RCOND


#: Residual components whose robust noise differs by more than this factor are scaled apart in
#: the screening's F test.
WHITEN_RATIO = 1.2


class Screen:
    """Linear screening of candidates against the current model ``r ≈ J·δ``.

    Adding columns ``C`` to ``J`` is solved by the Frisch–Waugh–Lovell split: ``C`` and ``r``
    projected off ``J``'s (truncated) column space, the small problem in ``C`` solved there and
    ``J``'s coefficients recovered from the SVD. The SVD of each fold's ``J`` is computed once per
    round and shared by every candidate — one ``lstsq`` of ``[J, C]`` per candidate and fold
    before, which was most of a diagnosis's time.
    """

    def __init__(self, J: np.ndarray, r: np.ndarray, schemes: dict, k: int):
        self.J, self.r, self.k = unit_columns(J)[0], r, k
        self.m = len(r) // k
        self.folds = {name: [self._fold(train, test, self.J, r) for train, test in folds] for name, folds in schemes.items()}
        # The F test assumes one noise level for every row: a pose's position and rotation rows
        # (weighted as the fit weighs them) need not share one, and a test pooled over both
        # over-rates a candidate that touches the noisier rows (a step of the position reading
        # on clean pose data: p = 1e-6). Its rows are scaled by each component's robust noise.
        sigma = robust_sigma(r.reshape(self.m, k))
        self.whiten = np.tile(1.0 / sigma, self.m) if k > 1 and np.max(sigma) > WHITEN_RATIO * np.min(sigma) else None
        w = np.ones(len(r)) if self.whiten is None else self.whiten
        self.all = self._fold(np.arange(self.m), np.array([], dtype=int), unit_columns(J * w[:, None])[0], r * w)

    def _fold(self, train: np.ndarray, test: np.ndarray, J: np.ndarray, r: np.ndarray) -> tuple:
        rows_tr, rows_te = (train[:, None] * self.k + np.arange(self.k)).ravel(), (test[:, None] * self.k + np.arange(self.k)).ravel()
        U, sv, Vt = truncated_svd(J[rows_tr], RCOND)
        coef = U.T @ r[rows_tr]
        return rows_tr, rows_te, test, U, sv, Vt, coef, r[rows_tr] - U @ coef

    def _solve(self, fold: tuple, C: np.ndarray, P: Optional[np.ndarray] = None) -> tuple[np.ndarray, np.ndarray, float]:
        """Coefficients ``(δ_J, c)`` of ``r ≈ J·δ_J + C·c`` on the fold's training rows (``c``
        penalised by ``‖P·c‖²`` if ``P`` is given: a wander's roughness), and the degrees of
        freedom ``C`` adds (its rank, or the trace of its share of the hat matrix)."""
        rows_tr, _, _, U, sv, Vt, coef, r_perp = fold
        if C.shape[1] == 0:
            return Vt.T @ (coef / sv), np.zeros(0), 0
        Ct = C[rows_tr]
        UC = U.T @ Ct
        C_perp = Ct - U @ UC
        if P is None:
            c, _, rank, _ = np.linalg.lstsq(C_perp, r_perp, rcond=RCOND * (sv[0] if sv.size else 1.0) / max(np.linalg.norm(C_perp, 2), 1e-300))
            return Vt.T @ ((coef - UC @ c) / sv), c, float(rank)
        G = C_perp.T @ C_perp
        inverse = np.linalg.pinv(G + P.T @ P, rcond=RCOND)
        c = inverse @ (C_perp.T @ r_perp)
        return Vt.T @ ((coef - UC @ c) / sv), c, float(np.trace(inverse @ G))

    def errors(self, C: np.ndarray, P: Optional[np.ndarray] = None) -> dict:
        """Held-out squared error per sample of ``r ≈ [J, C]·δ`` (``C`` penalised by ``P``)
        fitted per fold, per scheme."""
        C, P = _unit_penalised(C, P)

        def fold_errors(fold: tuple) -> np.ndarray:  # one fold's held-out samples
            rows_te = fold[1]
            dJ, c = self._solve(fold, C, P)[:2]
            e = self.r[rows_te] - self.J[rows_te] @ dJ - C[rows_te] @ c
            return (e * e).reshape(-1, self.k).sum(axis=1)

        folds = [(name, fold) for name, scheme in self.folds.items() for fold in scheme]
        out = {name: np.zeros(self.m) for name in self.folds}
        for (name, fold), err in zip(folds, thread_map(fold_errors, [fold for _, fold in folds], rows=len(self.r))):
            out[name][fold[2]] = err
        return out

    def f_test(self, C: np.ndarray, inflation: float = 1.0, P: Optional[np.ndarray] = None) -> float:
        """p-value of the extra-sum-of-squares F test for adding ``C`` (exact for independent
        Gaussian noise in the linearised model; for residuals correlated in time, the statistic
        and the residual degrees of freedom divided by their variance ``inflation``; a penalised
        ``C`` counts its effective degrees of freedom)."""
        if self.whiten is not None:  # the penalty is in the residual's units: scaled as its rows are
            C, P = C * self.whiten[:, None], None if P is None else P * float(np.median(self.whiten))
        C, P = _unit_penalised(C, P)
        _, _, _, U, sv, _, coef, r_perp = self.all
        _, c, extra = self._solve(self.all, C, P)
        rss0 = float(r_perp @ r_perp)
        e = r_perp - (C - U @ (U.T @ C)) @ c
        rss1, dof = float(e @ e), len(self.r) - len(sv) - extra
        if extra < 0.5 or dof < 1 or rss1 <= 0:
            return 1.0
        return float(f_dist.sf(max(rss0 - rss1, 0.0) / extra / (rss1 / dof) / inflation, extra, max(dof / inflation, 1.0)))


def _unit_penalised(C: np.ndarray, P: Optional[np.ndarray]) -> tuple[np.ndarray, Optional[np.ndarray]]:
    """``C`` with unit columns, and its penalty ``P`` for the coefficients so scaled."""
    scale = np.linalg.norm(C, axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    return C / scale, None if P is None else P / scale
