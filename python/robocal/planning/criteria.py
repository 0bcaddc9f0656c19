"""The design criteria: which poses, among the candidates' rows ``A_i`` (k rows each, scaled
columns), determine the model best, given the information ``M_0`` known before them.

I-optimality (``criterion="I"``, the default), ``min tr(W M⁻¹)``: the mean variance of a new
session's readings over the workspace (``W``: the candidates' mean ``JᵀJ`` with the set-up's
columns eliminated, :func:`workspace_weights`) — what a held-out check measures —, by Fedorov
exchange from the D-optimal design (:func:`i_optimal`); :func:`i_bound` says the least any ``N``
poses could reach.

D-optimality (``criterion="D"``), ``max log det(M_0 + Σ J_iᵀJ_i)`` over the chosen poses
(``M_0``: what the data already measured say, the joint maps' roughness prior, a vanishing
ridge). It minimises the volume of the parameters' confidence ellipsoid, does not depend on the
parameters' units (any column scaling multiplies the determinant by a constant) and, unlike a sum
of variances, cannot be bought by one well-determined parameter — the reason Borm & Menq's
observability index O1 (the product of singular values) is its square root. Solver: Wynn's
greedy selection with rank-k determinant updates (``det(M + JᵀJ) = det(M)·det(I + J M⁻¹ Jᵀ)``,
``M⁻¹`` by Woodbury) and then Fedorov's exchange (swap a chosen pose for a candidate while the
determinant grows) (:func:`d_optimal`).

Design libraries (pyDOE, dexpy, OApackage, pyoptex) build designs for polynomial models of
factors; none takes a user's Jacobian blocks of k rows per pose with a prior information matrix,
and the two algorithms are a few lines on NumPy. Every update works in whitened coordinates
(:func:`_whitened`): the prior is the identity there."""

from __future__ import annotations

import logging
from typing import Optional, Sequence

import numpy as np
from scipy.linalg import solve_triangular
from threadpoolctl import threadpool_limits

logger = logging.getLogger(__name__)


#: The greedy start's ridge, in columns scaled to one candidate's information each: a millionth
#: of a pose, enough to invert the information before there are as many poses as parameters.
RIDGE = 1e-6


#: The design criteria :func:`~robocal.planning.plan` offers, as its report names them.
CRITERIA = {
    "I": "I-optimal: the least mean variance of a new session's readings over the workspace, its set-up re-fitted; Fedorov exchange from the D-optimal design",
    "D": "D-optimal: log det of the parameters' information; greedy selection, Fedorov exchange",
    "Ds": "Ds-optimal: log det of the joints' zero offsets' information, a new session's set-up eliminated (re-mastering); greedy selection, Fedorov exchange",
}


#: Fedorov exchange passes over the chosen poses (each stops early once no swap helps).
EXCHANGE_PASSES = 3


#: Iterations of the multiplicative algorithm behind :func:`i_bound` (its bound is valid after any number).
BOUND_ITERATIONS = 300


# -- the D-optimal design --------------------------------------------------------------------------
def _gains(S: np.ndarray) -> np.ndarray:
    """``log det(I + S_i)`` of every block ``S_i`` (n, k, k): what adding pose ``i`` adds to
    ``log det M``."""
    if S.shape[1] == 1:
        return np.log1p(S[:, 0, 0])
    return np.linalg.slogdet(np.eye(S.shape[1]) + S)[1]


def _update(A: np.ndarray, Minv: np.ndarray, S: np.ndarray, i: int, sign: float) -> tuple[np.ndarray, np.ndarray]:
    """``M⁻¹`` and the blocks ``S_j = A_j M⁻¹ A_jᵀ`` after adding (``sign`` +1) or removing (−1)
    candidate ``i``'s rows ``A_i`` to ``M``, by Woodbury: ``M⁻¹ − s·U W Uᵀ`` with ``U = M⁻¹A_iᵀ``
    and ``W = (I + s·S_i)⁻¹``; each ``S_j`` loses ``s·C_j W C_jᵀ``, ``C_j = A_j U``."""
    n, k, p = A.shape
    U = Minv @ A[i].T
    W = np.linalg.inv(np.eye(k) + sign * S[i])
    Minv = Minv - sign * U @ W @ U.T
    C = A.reshape(n * k, p) @ U
    CW = (C @ W).reshape(n, k, k)
    return Minv, S - sign * np.matmul(CW, C.reshape(n, k, k).transpose(0, 2, 1))


def _blocks(A: np.ndarray, Minv: np.ndarray) -> np.ndarray:
    """``A_j M⁻¹ A_jᵀ`` (n, k, k) of every candidate's rows ``A_j``."""
    n, k, p = A.shape
    return np.matmul((A.reshape(n * k, p) @ Minv).reshape(n, k, p), A.transpose(0, 2, 1))


#: Candidates an exchange pass considers: the best by the current design, at least this many
#: (and ten per pose); the others gain too little from any one swap to matter.
SHORTLIST = 2000


def _whitened(A: np.ndarray, M0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``A·L⁻ᵀ`` with ``M0 = L·Lᵀ``, and the identity: the same determinants up to ``det M0``,
    but every information matrix after it at least ``I``, so that the rank-k updates work on
    inverses of norm at most 1 (measured data beside a ridge span ten decades: updated in those
    coordinates, the blocks drifted below −1)."""
    L = np.linalg.cholesky(M0)
    n, k, p = A.shape
    # C order: every rank-k update reshapes it to (n·k, p), which copies a transposed array (a
    # copy of 200 MB per update at 10 000 candidates of 700 entries).
    return np.ascontiguousarray(solve_triangular(L, A.reshape(n * k, p).T, lower=True).T).reshape(n, k, p), np.eye(p)


def _greedy(A: np.ndarray, Minv: np.ndarray, chosen: list, size: int) -> list:
    """Adds the candidate of largest gain until ``size`` are chosen (Wynn), every candidate's
    block ``S_j`` kept current by rank-k updates (:func:`_update`). (Lazy evaluation does not
    pay here: from the ridge start every gain falls at each step, so the stale bounds all lead.)"""
    free = np.ones(len(A), dtype=bool)
    free[chosen] = False
    S = _blocks(A, Minv)
    while len(chosen) < size:
        i = int(np.argmax(np.where(free, _gains(S), -np.inf)))
        chosen.append(i)
        free[i] = False
        Minv, S = _update(A, Minv, S, i, 1.0)
    return chosen


def _shortlist(A: np.ndarray, gain: np.ndarray, chosen: list) -> tuple:
    """The exchange's candidates: the chosen poses and those of largest ``gain`` (at least
    :data:`SHORTLIST`, 11 per chosen pose); their indices, rows of ``A``, each chosen pose's
    place among them, and which are free to enter."""
    size = min(len(A), max(SHORTLIST, 11 * len(chosen)))
    short = np.argpartition(-gain, size - 1)[:size]
    at = {int(c): int(np.flatnonzero(short == c)[0]) for c in chosen}
    free = np.ones(len(short), dtype=bool)
    free[list(at.values())] = False
    return short, A[short], at, free


def _exchange(A: np.ndarray, M0: np.ndarray, chosen: list, fixed: int) -> int:
    """One Fedorov exchange pass over the slots after ``fixed``: each chosen pose is swapped for
    the candidate of :data:`SHORTLIST` that raises the determinant most, if any does; returns
    the number of swaps (``chosen`` is changed in place)."""
    Minv = np.linalg.inv(M0 + sum(A[i].T @ A[i] for i in chosen))  # afresh: no drift from the updates
    gain = _gains(_blocks(A, Minv))
    gain[chosen] = np.inf
    short, At, at, free = _shortlist(A, gain, chosen)
    S = _blocks(At, Minv)
    swaps = 0
    for slot in range(fixed, len(chosen)):
        i = at[chosen[slot]]
        if 1.0 - float(np.max(np.linalg.eigvalsh(S[i]))) < 1e-9:  # the design cannot do without it
            continue
        without, S_without = _update(At, Minv, S, i, -1.0)
        gains = _gains(S_without)
        j = int(np.argmax(np.where(free, gains, -np.inf)))
        if gains[j] <= gains[i] + 1e-9:
            continue
        chosen[slot] = int(short[j])
        free[i], free[j] = True, False
        Minv, S = _update(At, without, S_without, j, 1.0)
        swaps += 1
    return swaps


# Hundreds of rank-k updates of skinny products: a multi-threaded BLAS only adds hand-over cost
# (4x slower on this 2-core machine while others work), as in diagnose.
@threadpool_limits.wrap(limits=1, user_api="blas")
def d_optimal(A: np.ndarray, M0: np.ndarray, size: int, required: Sequence[int] = (), passes: int = EXCHANGE_PASSES) -> np.ndarray:
    """Indices of ``size`` distinct candidates that (nearly) maximise ``log det(M0 + Σ A_iᵀA_i)``:
    greedy selection (:func:`_greedy`), then up to ``passes`` Fedorov exchange passes
    (:func:`_exchange`).

    Parameters
    ----------
    A : ndarray, shape (n, k, p)
        Each candidate's rows.
    M0 : ndarray, shape (p, p)
        Positive definite information before the plan.
    size : int
    required : sequence of int
        Candidates that must be among the chosen (never exchanged).
    passes : int
    """
    A, identity = _whitened(A, M0)
    chosen = [int(i) for i in list(required)[:size]]
    Minv = np.linalg.inv(identity + sum(A[i].T @ A[i] for i in chosen))
    chosen = _greedy(A, Minv, chosen, size)
    for _ in range(passes):
        swaps = _exchange(A, identity, chosen, min(len(required), size))
        logger.debug("exchange pass: %d swaps", swaps)
        if not swaps:
            break
    return np.array(chosen, dtype=int)


# -- the Ds-optimal design --------------------------------------------------------------------------
@threadpool_limits.wrap(limits=1, user_api="blas")
def ds_optimal(A: np.ndarray, M0: np.ndarray, size: int, of: Sequence[int], required: Sequence[int] = (), passes: int = EXCHANGE_PASSES) -> np.ndarray:
    """Indices of ``size`` distinct candidates that (nearly) maximise the log det of the information
    on the columns ``of`` with the others (nuisance: a session's set-up) eliminated, the Schur
    complement ``M_ss − M_sn M_nn⁻¹ M_ns`` of ``M = M0 + Σ A_iᵀA_i``: its log det is
    ``log det M − log det M_nn``, so a pose's gain is its D-gain on the whole model less its D-gain on
    the nuisance alone (:func:`_gains`, both kept current by :func:`_update`). Greedy selection,
    then up to ``passes`` Fedorov exchange passes (each chosen pose after ``required`` swapped for
    the candidate of largest gain once it is taken out, if that gains more)."""
    of = set(int(i) for i in of)
    nuisance = [i for i in range(A.shape[2]) if i not in of]
    models = [_whitened(A, M0)[0]] + ([_whitened(A[:, :, nuisance], M0[np.ix_(nuisance, nuisance)])[0]] if nuisance else [])

    def state(B, chosen):
        Minv = np.linalg.inv(np.eye(B.shape[2]) + sum(B[i].T @ B[i] for i in chosen))
        return [Minv, _blocks(B, Minv)]

    def gains(states):
        g = _gains(states[0][1])
        return g - _gains(states[1][1]) if len(states) > 1 else g

    def move(states, i, sign):
        for B, st in zip(models, states):
            st[:] = _update(B, st[0], st[1], i, sign)

    chosen = [int(i) for i in list(required)[:size]]
    states = [state(B, chosen) for B in models]
    free = np.ones(len(A), dtype=bool)
    free[chosen] = False
    while len(chosen) < size:
        i = int(np.argmax(np.where(free, gains(states), -np.inf)))
        chosen.append(i)
        free[i] = False
        move(states, i, 1.0)
    for _ in range(passes):
        swaps = 0
        for slot in range(min(len(required), size), size):
            i = chosen[slot]
            move(states, i, -1.0)
            free[i] = True
            g = gains(states)
            j = int(np.argmax(np.where(free, g, -np.inf)))
            if g[j] <= g[i] + 1e-9:
                j = i
            else:
                swaps += 1
            chosen[slot] = j
            free[j] = False
            move(states, j, 1.0)
        logger.debug("Ds exchange pass: %d swaps", swaps)
        if not swaps:
            break
    return np.array(chosen, dtype=int)


# -- the I-optimal design --------------------------------------------------------------------------
def _i_blocks(A: np.ndarray, Minv: np.ndarray, W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``S_j = A_j M⁻¹ A_jᵀ`` and ``T_j = A_j M⁻¹ W M⁻¹ A_jᵀ`` (n, k, k) of every candidate."""
    n, k, p = A.shape
    H = A.reshape(n * k, p) @ Minv
    Ht = H.reshape(n, k, p).transpose(0, 2, 1)
    return np.matmul(A, Ht), np.matmul((H @ W).reshape(n, k, p), Ht)


def _i_gains(S: np.ndarray, T: np.ndarray) -> np.ndarray:
    """``tr((I + S_i)⁻¹ T_i)`` of every candidate: what adding pose ``i`` takes off ``tr(W M⁻¹)``."""
    if S.shape[1] == 1:
        return T[:, 0, 0] / (1.0 + S[:, 0, 0])
    return np.trace(np.linalg.solve(np.eye(S.shape[1]) + S, T), axis1=1, axis2=2)


def _i_update(A: np.ndarray, Minv: np.ndarray, W: np.ndarray, S: np.ndarray, T: np.ndarray, i: int, sign: float) -> tuple:
    """``M⁻¹``, ``S`` and ``T`` (:func:`_i_blocks`) after adding (``sign`` +1) or removing (−1)
    candidate ``i``: with ``U = M⁻¹A_iᵀ`` and ``R = (I + s·S_i)⁻¹``, ``M⁻¹`` loses ``s·U R Uᵀ``,
    each ``S_j`` loses ``s·C_j R C_jᵀ`` and ``T_j`` becomes
    ``T_j − s(C_j R E_jᵀ + E_j R C_jᵀ) + C_j R Q R C_jᵀ`` (``C_j = A_j U``, ``E_j = A_j M⁻¹ W U``,
    ``Q = Uᵀ W U``)."""
    n, k, p = A.shape
    U = Minv @ A[i].T
    R = np.linalg.inv(np.eye(k) + sign * S[i])
    CE = A.reshape(n * k, p) @ np.hstack([U, Minv @ (W @ U)])  # one pass over the candidates' rows, the time it takes
    C, E = CE[:, :k].reshape(n, k, k), CE[:, k:].reshape(n, k, k)
    CR = C @ R
    cross = np.matmul(CR, E.transpose(0, 2, 1))
    T = T - sign * (cross + cross.transpose(0, 2, 1)) + np.matmul(CR @ (U.T @ W @ U), CR.transpose(0, 2, 1))
    return Minv - sign * U @ R @ U.T, S - sign * np.matmul(CR, C.transpose(0, 2, 1)), T


def _i_exchange(A: np.ndarray, W: np.ndarray, chosen: list, fixed: int) -> int:
    """One Fedorov exchange pass for the I-criterion (whitened: the prior is the identity): each
    chosen pose after ``fixed`` is swapped for the candidate of :data:`SHORTLIST` that lowers
    ``tr(W M⁻¹)`` most, if any does; returns the number of swaps."""
    p = A.shape[2]
    Minv = np.linalg.inv(np.eye(p) + sum(A[i].T @ A[i] for i in chosen))
    S, T = _i_blocks(A, Minv, W)
    gain = _i_gains(S, T)
    gain[chosen] = np.inf
    short, At, at, free = _shortlist(A, gain, chosen)
    S, T = S[short], T[short]
    swaps = 0
    for slot in range(fixed, len(chosen)):
        i = at[chosen[slot]]
        if 1.0 - float(np.max(np.linalg.eigvalsh(S[i]))) < 1e-9:  # the design cannot do without it
            continue
        without = _i_update(At, Minv, W, S, T, i, -1.0)
        gains = _i_gains(without[1], without[2])
        j = int(np.argmax(np.where(free, gains, -np.inf)))
        if gains[j] <= gains[i] * (1.0 + 1e-9):
            continue
        chosen[slot] = int(short[j])
        free[i], free[j] = True, False
        Minv, S, T = _i_update(At, without[0], W, without[1], without[2], j, 1.0)
        swaps += 1
    return swaps


def i_criterion(A: np.ndarray, M0: np.ndarray, W: np.ndarray, chosen) -> float:
    """``tr(W M⁻¹)``, ``M = M0 + Σ A_iᵀA_i`` over ``chosen``: the average prediction variance
    (in units of the reading's variance) over the poses ``W`` averages."""
    idx = np.asarray(chosen, dtype=int)
    M = M0 + _information(A[idx])
    return float(np.trace(np.linalg.solve(M, W)))


@threadpool_limits.wrap(limits=1, user_api="blas")
def i_optimal(
    A: np.ndarray, M0: np.ndarray, W: np.ndarray, size: int, required: Sequence[int] = (), passes: int = EXCHANGE_PASSES, start: Optional[Sequence[int]] = None
) -> np.ndarray:
    """Indices of ``size`` distinct candidates that (nearly) minimise ``tr(W M⁻¹)``,
    ``M = M0 + Σ A_iᵀA_i``: the I-optimal (V-optimal) design, the average variance of what is
    predicted with weights ``W`` (the mean of the test poses' ``JᵀJ``). Fedorov exchange passes
    from ``start`` (a design of ``size``, e.g. the D-optimal one: greedy steps for a trace from a
    near-singular start pick what the ridge leaves loose, not what the test poses need), else
    from a greedy selection."""
    L = np.linalg.cholesky(M0)
    A, _ = _whitened(A, M0)
    W = np.linalg.solve(L, np.linalg.solve(L, W).T)  # L⁻¹ W L⁻ᵀ: the same trace in whitened coordinates
    fixed = min(len(required), size)
    if start is not None:
        chosen = [int(i) for i in start]
    else:
        chosen = [int(i) for i in list(required)[:size]]
        p = A.shape[2]
        Minv = np.linalg.inv(np.eye(p) + sum(A[i].T @ A[i] for i in chosen))
        S, T = _i_blocks(A, Minv, W)
        free = np.ones(len(A), dtype=bool)
        free[chosen] = False
        while len(chosen) < size:
            i = int(np.argmax(np.where(free, _i_gains(S, T), -np.inf)))
            chosen.append(i)
            free[i] = False
            Minv, S, T = _i_update(A, Minv, W, S, T, i, 1.0)
    for _ in range(passes):
        swaps = _i_exchange(A, W, chosen, fixed)
        logger.debug("I exchange pass: %d swaps", swaps)
        if not swaps:
            break
    return np.array(chosen, dtype=int)


@threadpool_limits.wrap(limits=1, user_api="blas")
def i_bound(A: np.ndarray, M0: np.ndarray, W: np.ndarray, size: int, iterations: int = BOUND_ITERATIONS) -> float:
    """A lower bound of ``tr(W M⁻¹)`` over every design of ``size`` poses among the candidates
    ``A`` (repeats allowed): the continuous relaxation — weights ``ξ`` on the candidates, summing
    to one, ``M = M0 + size·Σ ξ_i A_iᵀA_i`` — improved by the multiplicative algorithm
    (``ξ_i ∝ ξ_i √d_i``, ``d_i = tr(A_i M⁻¹ W M⁻¹ A_iᵀ)``), and bounded by its convexity:
    ``Φ* ≥ Φ(ξ) − size·(max d_i − Σ ξ_i d_i)`` (the Frank–Wolfe gap), whatever the iterations."""
    n, k, p = A.shape
    flat = A.reshape(n * k, p)
    xi = np.full(n, 1.0 / n)
    best = 0.0
    for _ in range(iterations):
        M = M0 + size * (flat.T @ (flat * np.repeat(xi, k)[:, None]))
        Minv = np.linalg.inv((M + M.T) / 2)
        H = flat @ Minv
        d = np.maximum(np.sum((H @ W) * H, axis=1).reshape(n, k).sum(axis=1), 0.0)
        phi = float(np.trace(W @ Minv))
        mean = float(xi @ d)
        best = max(best, phi - size * (float(d.max()) - mean))
        xi = xi * np.sqrt(d / max(mean, 1e-300))
        xi /= xi.sum()
    return best


def workspace_weights(A: np.ndarray, names: Sequence[str], setup: Sequence[str]) -> np.ndarray:
    """``W``, the mean over the candidates of ``JᵀJ`` with the set-up's columns eliminated (the
    Schur complement): ``tr(W Cov)`` is the mean variance of a new session's readings at poses
    drawn like the candidates, its set-up fitted anew on them (as ``robocal verify`` does)."""
    F = _information(A) / len(A)
    s = [i for i, n in enumerate(names) if n in setup]
    r = [i for i in range(len(names)) if i not in s]
    W = np.zeros_like(F)
    W[np.ix_(r, r)] = F[np.ix_(r, r)] - F[np.ix_(r, s)] @ np.linalg.pinv(F[np.ix_(s, s)]) @ F[np.ix_(s, r)] if s else F
    return (W + W.T) / 2


def _information(A: np.ndarray) -> np.ndarray:
    """``Σ A_iᵀA_i`` of the candidates' rows ``A`` (n, k, p), by one BLAS product (an einsum
    over ten thousand candidates of a thousand entries takes a minute)."""
    flat = A.reshape(-1, A.shape[2])
    return flat.T @ flat
