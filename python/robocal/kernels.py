"""The Python wrapper around the compiled kernels (:mod:`robocal._robocal`, the Rust core):
its free functions (sigma points, the unscented transform, damped solves, identifiability,
covariance, the cable's initial guess) with NumPy-friendly arguments, and the argument checks
every layer shares (``as_float_array``, ``as_count``, ``seeded_rng`` …).

Inputs may be any array-like; they are converted here to contiguous float64 (the compiled
module takes nothing else) with errors that name the argument. Shapes, finiteness and values are
checked again in Rust. The kernels are library internals rather than the user API: reach them as
``robocal.kernels.solve_damped`` etc.
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from . import _robocal
from .exceptions import InvalidParameterError

#: Largest magnitude of a kinematic input (mm, rad): beyond ±1e12 the core's squares overflow.
#: The core refuses such inputs by index; readers check first, to name the cell or parameter.
MAX_ABS = 1e12
#: How far from 1 the norm of an observed quaternion may be: the core refuses a pose beyond it
#: (by sample index); readers check first, to name the file and row.
QUATERNION_NORM_TOL = 1e-3


def _real_array(value, name: str) -> np.ndarray:
    """``value`` as a float64 array of any shape. Complex, boolean and date values are refused
    rather than cast: the cast would silently drop an imaginary part, or read a mask or a time as
    numbers. Numbers written as text ("0.2") are read, as users pass them."""
    try:
        array = np.asarray(value)
        if array.dtype.kind in "bcVmM":
            raise TypeError(f"{array.dtype} values")
        return array.astype(np.float64, copy=False)
    except (TypeError, ValueError) as exc:
        raise InvalidParameterError(f"`{name}` must be numeric array-like; got {type(value).__name__} ({exc})") from None


def as_float_array(value, name: str) -> np.ndarray:
    """``value`` as a C-contiguous float64 array, or an error naming ``name``."""
    return np.ascontiguousarray(_real_array(value, name))


def as_float(value, name: str) -> float:
    """``value`` as a real scalar (float), or an error naming ``name``."""
    array = _real_array(value, name)
    if array.ndim != 0:
        raise InvalidParameterError(f"`{name}` must be a real number; got {value!r}")
    return float(array)


def as_str(value, name: str) -> str:
    """``value`` if it is a string, else an error naming ``name``."""
    if not isinstance(value, str):
        raise InvalidParameterError(f"`{name}` must be a string; got {type(value).__name__} {value!r}")
    return value


def merwe_sigma_points(x, P, alpha: float = 1e-3, beta: float = 2.0, kappa: float = 0.0):
    """Merwe scaled sigma points (filterpy's ``MerweScaledSigmaPoints``).

    Parameters
    ----------
    x : array_like, shape (n,)
    P : array_like, shape (n, n)
        Symmetric positive definite covariance.
    alpha, beta, kappa : float

    Returns
    -------
    sigmas : ndarray, shape (2n+1, n)
    Wm, Wc : ndarray, shape (2n+1,)
    """
    return _robocal.merwe_sigma_points(
        as_float_array(x, "x"), as_float_array(P, "P"), as_float(alpha, "alpha"), as_float(beta, "beta"), as_float(kappa, "kappa")
    )


def unscented_transform(sigmas_x, sigmas_y, Wm, Wc):
    """Mean and covariance of propagated sigma points and their cross-covariance.

    Returns ``(mean_y (k,), cov_y (k, k), cross (n, k))`` — the paper's eq. (10)-(11).
    """
    return _robocal.unscented_transform(
        as_float_array(sigmas_x, "sigmas_x"), as_float_array(sigmas_y, "sigmas_y"), as_float_array(Wm, "Wm"), as_float_array(Wc, "Wc")
    )


def solve_damped(J, r, lam: float, damping: str = "marquardt", factor: str = "normal"):
    """Damped step ``(JᵀJ + λD) δ = Jᵀr``.

    ``damping="marquardt"`` uses ``D = diag(JᵀJ)``, ``"identity"`` the paper's ``D = I`` (eq. 14).
    ``factor="normal"`` solves the normal equations as the paper writes them (Cholesky, or an SVD
    for a matrix that is not positive definite); ``"lstsq"`` solves the same step as the least
    squares of ``[J; √λ·D^½] δ ≈ [r; 0]`` by QR of ``J`` itself (an SVD if rank-deficient), which
    keeps directions the normal equations lose to their squared condition number.
    Returns ``(delta (n,), method)`` with method ``"cholesky"``, ``"qr"`` or ``"svd"``.
    """
    return _robocal.solve_damped(as_float_array(J, "J"), as_float_array(r, "r"), as_float(lam, "lam"), as_str(damping, "damping"), as_str(factor, "factor"))


def factor_damped(J):
    """A dense ``J`` (m, n) factored once as ``J = Q·R`` (Householder QR, in Rust) for many
    damped steps ``min ‖J·δ − b‖² + λ‖δ‖²`` (a sparse ``J``, a model with joint maps, goes
    through its normal equations in the LM: :func:`robocal.calibration.lm.levenberg_marquardt`).

    Returns a ``DampedQr`` with ``project(b)`` → ``c = Qᵀb`` (n,) — ``‖c‖`` is the norm of
    ``b``'s part that ``J`` explains — and ``solve(c, lam)`` → the step ``δ`` (n,); its ``r`` is
    ``R`` (n, n), whose singular values and right singular vectors are ``J``'s. Scale the
    columns of ``J`` beforehand for Marquardt's damping.
    """
    return _robocal.DampedQr(as_float_array(J, "J"))


def normal_equations(J, r) -> tuple[np.ndarray, np.ndarray]:
    """``(JᵀJ (n, n), Jᵀr (n,))`` of a dense ``J`` (m, n) and ``r`` (m,), in Rust: fixed row blocks
    on the core's threads, summed in order (the same result on any number of threads, and no
    BLAS threads that a loaded machine leaves spinning)."""
    return _robocal.normal_equations(as_float_array(J, "J"), as_float_array(r, "r"))


def is_sparse(J) -> bool:
    """True for a scipy.sparse matrix (tested without importing scipy)."""
    return type(J).__module__.startswith("scipy.sparse")


def sparse_gram(J) -> np.ndarray:
    """``JᵀJ`` (n, n) of a scipy.sparse ``J``, in Rust from its CSR rows (each row's pairs of
    entries: a tenth of the dense product for a model with joint maps; fastest with each row's
    columns ascending, as a copy of ``J`` is sorted here if they are not)."""
    J = J.tocsr()
    if not J.has_sorted_indices:
        J = J.sorted_indices()
    return _robocal.sparse_gram(J.indptr, J.indices, as_float_array(J.data, "J"), J.shape[1])


def fold_products(C, J, r, labels: list, folds: list) -> list:
    """Per fold of each labelling (``labels[s]``: a fold below ``folds[s]`` per row), the fold's
    rows' ``(CᵀJ (F, nc, p), Cᵀr (F, nc), CᵀC (F, nc, nc))`` of scipy.sparse ``C`` and ``J`` and
    ``r``, in Rust: one pass over the rows for every fold of every labelling."""
    C, J = (A.tocsr() for A in (C, J))
    csr = lambda A, arg: (A.indptr, A.indices, as_float_array(A.data, arg), A.shape[1])
    return _robocal.fold_products(
        csr(C, "C"), csr(J, "J"), as_float_array(r, "r"), [np.asarray(label, dtype=np.int64) for label in labels], [int(f) for f in folds]
    )


def stack_csr(dense: np.ndarray, dense_cols: np.ndarray, thin: list, weights: np.ndarray, extra, pattern: bool = True) -> tuple:
    """``(indptr, indices, data)`` of a Jacobian from its blocks, in Rust: per data row the dense
    block's values (``dense`` (m, nd), columns ``dense_cols``), then each thin block's entries
    (``thin``: pairs of a scipy.sparse block (m, ·) and its column offset), all times the row's
    ``weights``; then the rows of ``extra`` (scipy.sparse, the Jacobian's column count).
    ``pattern=False``: the values only (``indptr`` and ``indices`` None), for a pattern known."""
    thin = [(block.tocsr(), int(offset)) for block, offset in thin]
    blocks = [(b.indptr, b.indices, as_float_array(b.data, "thin"), offset) for b, offset in thin]
    extra = extra.tocsr()
    return _robocal.stack_csr(
        as_float_array(dense, "dense"),
        np.asarray(dense_cols, dtype=np.int64),
        blocks,
        as_float_array(weights, "weights"),
        (extra.indptr, extra.indices, as_float_array(extra.data, "extra"), extra.shape[1]),
        pattern,
    )


def identifiability(J, tol: float = 1e-9, first=None) -> dict:
    """Rank, singular values, identifiable subset and redundancies of a Jacobian (m, n).

    Computed on unit-norm columns. ``redundant`` lists, for each parameter outside the subset,
    ``(j, [(k, c_k), ...])`` with scaled column ``j ≈ Σ c_k · column k``. ``first`` (n bools,
    optional) marks columns to keep in the subset before the others where they explain the same
    (a session's set-up: :meth:`robocal.robot.Robot.identifiability`).
    """
    J = as_float_array(J, "J")
    if first is None:
        return _robocal.identifiability(J, as_float(tol, "tol"))
    marked = np.asarray(first)
    if marked.dtype.kind != "b" or marked.shape != J.shape[1:]:
        raise InvalidParameterError(f"`first` must hold one boolean per column of J, shape {J.shape[1:]}; got {marked.dtype} of shape {marked.shape}")
    return _robocal.identifiability(J, as_float(tol, "tol"), marked.tolist())


def covariance(J, r, tol: float = 1e-9):
    """Parameter covariance ``σ̂²(JᵀJ)⁺`` with ``σ̂² = ‖r‖²/(rows − rank)``.

    Returns ``(cov (n, n), sigma2, dof, rank)``. A sparse ``J`` goes through its normal equations.
    """
    if is_sparse(J):
        r = as_float_array(r, "r")
        s2, V = np.linalg.eigh(sparse_gram(J))
        keep = s2 > as_float(tol, "tol") ** 2 * max(float(s2[-1]), 1e-300)
        rank = int(np.count_nonzero(keep))
        dof = max(J.shape[0] - rank, 1)
        sigma2 = float(r @ r) / dof
        cov = (V[:, keep] / s2[keep]) @ V[:, keep].T * sigma2
        return cov, sigma2, dof, rank
    return _robocal.covariance(as_float_array(J, "J"), as_float_array(r, "r"), as_float(tol, "tol"))


#: Singular values at or below this fraction of the largest count as zero in :func:`truncated_svd`.
SVD_RCOND = 1e-10


def unit_columns(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(A / scale, scale)``: the columns of a dense ``A`` (m, n) divided by their norms
    ``scale`` (n,), a zero column left as it is (its scale 1). In these units the singular values
    of a Jacobian compare directions of the data, not the units of its parameters."""
    scale = np.linalg.norm(A, axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    return A / scale, scale


def truncated_svd(A: np.ndarray, rcond: Optional[float] = SVD_RCOND) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``U (m, k), s (k,), Vt (k, n)`` of the thin SVD of a dense ``A`` (m, n) (scaled by the caller,
    e.g. with :func:`unit_columns`), keeping the ``k`` singular values above ``rcond`` times the
    largest: the directions the data determine (every one, zeros included, if ``rcond`` is None)."""
    U, s, Vt = np.linalg.svd(A, full_matrices=False)
    if rcond is None:
        return U, s, Vt
    keep = s > rcond * s[0] if s.size else s > 0
    return U[:, keep], s[keep], Vt[keep]


def configuration_groups(q, tol: float) -> np.ndarray:
    """One label per sample of ``q`` (m, N): samples whose joint values agree within ``tol`` on
    every joint (chained) share one, numbered ``0..g-1`` in order of first appearance — a k-d
    tree's pairs and connected components (:func:`robocal.reference.configuration_groups`), from a
    sort-and-sweep in Rust (20 000 samples: 2 ms instead of 60 ms). Chained components can span
    far more than ``tol``: :func:`robocal.data.splits.configuration_groups` cuts those."""
    return _robocal.configuration_groups(as_float_array(q, "q"), as_float(tol, "tol"))


def cable_initial_guess(p, L):
    """Closed-form cable anchor ``P0`` (mm) and sensor zero ``L0`` (mm) from tool points ``p``
    (m, 3) and cable lengths ``L`` (m,). Exact on noiseless data."""
    return _robocal.cable_initial_guess(as_float_array(p, "p"), as_float_array(L, "L"))


def check_seed(seed, name: str = "seed"):
    """``seed`` if it is None (fresh entropy) or an integer >= 0 (what NumPy's generators take),
    else an error naming ``name``."""
    if seed is None or (isinstance(seed, (int, np.integer)) and not isinstance(seed, bool) and seed >= 0):
        return seed
    raise InvalidParameterError(f"`{name}` must be None or an integer >= 0; got {seed!r}")


def seeded_rng(seed, name: str = "seed") -> np.random.Generator:
    """``numpy.random.default_rng(seed)`` after :func:`check_seed`."""
    return np.random.default_rng(check_seed(seed, name))


#: Upper bound of sample counts a user asks for (simulate, export's round trip): a million
#: samples is far beyond any calibration and still fits in memory; a typo of 1e8 does not.
MAX_SAMPLES = 1_000_000


def as_count(value, name: str, least: int = 1, most: Optional[int] = None) -> int:
    """``value`` as an int if it is an integer in ``[least, most]`` (not a bool), else an error naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
        raise InvalidParameterError(f"`{name}` must be an integer >= {least}; got {value!r}")
    if most is not None and value > most:
        raise InvalidParameterError(f"`{name}` must be at most {most:,}; got {value:,}")
    return int(value)


def as_positive(value, name: str) -> float:
    """``value`` as a float if it is finite and > 0, else an error naming ``name``."""
    number = as_float(value, name)
    if not (np.isfinite(number) and number > 0):
        raise InvalidParameterError(f"`{name}` must be finite and > 0; got {value!r}")
    return number


def as_tolerance(value, name: str) -> float:
    """``value`` as a float if it is finite and >= 0, else an error naming ``name``."""
    number = as_float(value, name)
    if not (np.isfinite(number) and number >= 0):
        raise InvalidParameterError(f"`{name}` must be finite and >= 0; got {value!r}")
    return number
