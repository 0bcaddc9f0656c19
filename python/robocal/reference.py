"""The readable pure-NumPy twin of robocal's Rust core (:mod:`robocal._robocal`).

Every kernel of the compiled core is written here again, plainly, as module-level functions that
take the chain description (``conventions``, ``kinds``) explicitly. The maths is that of
``docs/core-model.md``; the tests hold the Rust core equal to these functions. Nothing here is
meant to be fast: it is vectorised over samples (NumPy broadcasting and ``einsum``), with Python
loops only over the elementary transforms of the chain.

Conventions
-----------
* Units: mm and rad (``cable_scale`` is dimensionless).
* Arrays are float64 with samples as rows: ``q`` is (m, N), observations ``y`` are
  (m, obs_width), residuals (m, res_width), Jacobian rows are sample-major (row ``i*k + c``).
* Quaternions are ``(w, x, y, z)``; those produced here have ``w >= 0``.
* ``J = dh/dparams``, so ``r(params + delta) ~ r(params) - J @ delta`` with ``r = y - h``.

Bad input raises :class:`ValueError` with a message naming the argument, e.g.
"`q` must have shape (m, 6); got (3, 7)"; degenerate linear algebra raises
:class:`numpy.linalg.LinAlgError`. This module imports neither the compiled core nor the rest
of the package.

Numerical thresholds the model document leaves open are module constants (below) and match the
Rust core.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import scipy.linalg

# The geometry is shared with production code: pure NumPy, tested against SciPy's rotations
# (tests/test_geometry.py), so the oracle stays independent of the Rust-backed modules.
from .geometry import (
    SMALL_ANGLE,
    Op,
    chain_ops,
    frame_params,
    frame_transform,
    matrix_from_quaternion,
    quaternion_from_matrix,
    rotation,
    skew,
    so3_exp,
    so3_log,
)
from .geometry import homogeneous as _homogeneous

__all__ = [
    "MEASUREMENTS",
    "param_names",
    "param_units",
    "chain_ops",
    "fk",
    "predict",
    "residuals",
    "jacobian",
    "sigma_residuals",
    "merwe_sigma_points",
    "unscented_transform",
    "solve_damped",
    "identifiability",
    "covariance",
    "cable_initial_guess",
    "rotation",
    "frame_transform",
    "frame_params",
    "skew",
    "so3_exp",
    "so3_log",
    "right_jacobian_inverse",
    "quaternion_from_matrix",
    "matrix_from_quaternion",
]

#: ``measurement -> (observation width, residual width)``.
MEASUREMENTS = {"cable": (1, 1), "position": (3, 3), "pose": (7, 6)}

JOINT_PARAMS = (("alpha", "rad"), ("a", "mm"), ("d", "mm"), ("theta", "rad"), ("beta", "rad"))
FRAME_PARAMS = (("x", "mm"), ("y", "mm"), ("z", "mm"), ("rx", "rad"), ("ry", "rad"), ("rz", "rad"))
SENSOR_PARAMS = (("anchor_x", "mm"), ("anchor_y", "mm"), ("anchor_z", "mm"), ("cable_offset", "mm"), ("cable_scale", "1"))

#: An observed pose quaternion must have norm within this of 1 (it is then normalised).
QUATERNION_NORM_TOL = 1e-3
#: A Jacobian column whose norm is <= this times the largest column norm has "no effect".
NO_EFFECT_REL = 1e-12
#: Redundancy coefficients (on unit-norm columns) at or below this are not reported.
REDUNDANCY_COEF_MIN = 1e-6
#: Pivot ties of :func:`identifiability`: remaining column norms within this relative distance
#: of the largest go to the lowest column index (exactly equal scaled columns then never depend
#: on rounding).
PIVOT_TIE_REL = 1e-9
#: :func:`identifiability`'s ``first`` columns (a session's set-up) are pivoted before the others
#: while their largest remaining norm is at least this fraction of the largest of all.
FIRST_MIN_REL = 1e-3
#: ``solve_damped``: a Cholesky factor whose smallest squared pivot is <= this times the largest
#: counts as failed; the SVD fallback drops singular values <= this * n * the largest.
RANK_TOL = 1e-13
#: ``solve_damped(factor="lstsq")``: the normal equations are used when every squared Cholesky
#: pivot exceeds this times the largest (condition below ~1e12), else QR of the augmented system.
WELL_CONDITIONED = 1e-12
#: ``cable_initial_guess``: the centred design matrix must have ``s_min > this * s_max``.
CABLE_CONDITION_MIN = 1e-10
#: ``merwe_sigma_points``: ``P`` must be symmetric to ``max|P - P^T| <= this * max|P|``.
SYMMETRY_TOL = 1e-9


# --------------------------------------------------------------------------------------------
# Input checking
# --------------------------------------------------------------------------------------------
def _shape_str(shape) -> str:
    parts = [str(d) for d in shape]
    return f"({parts[0]},)" if len(parts) == 1 else f"({', '.join(parts)})"


def _array(value, name: str, shape: Sequence) -> np.ndarray:
    """``value`` as a float64 array of ``shape`` (ints are exact sizes, strings any size),
    finite, or a :class:`ValueError` naming ``name``."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"`{name}` must be a numeric array; got {type(value).__name__}") from None
    if arr.ndim != len(shape) or any(isinstance(e, int) and e != g for e, g in zip(shape, arr.shape)):
        raise ValueError(f"`{name}` must have shape {_shape_str(shape)}; got {_shape_str(arr.shape)}")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise ValueError(f"`{name}` must be finite; got {arr.flat[bad[0]]} at flat index {bad[0]}")
    return arr


def _float(value, name: str) -> float:
    v = float(value)
    if not np.isfinite(v):
        raise ValueError(f"`{name}` must be finite; got {v}")
    return v


def _obs_res_width(measurement: str) -> tuple[int, int]:
    if measurement not in MEASUREMENTS:
        raise ValueError(f"`measurement` must be one of {tuple(MEASUREMENTS)}; got {measurement!r}")
    return MEASUREMENTS[measurement]


def _columns(cols, n_params: int) -> np.ndarray:
    """Validated parameter indices ``cols`` (all parameters when None)."""
    if cols is None:
        return np.arange(n_params)
    c = np.asarray(cols)
    if c.size == 0:
        return np.zeros(0, dtype=int)
    if c.ndim != 1 or not np.issubdtype(c.dtype, np.integer):
        raise ValueError(f"`cols` must be a 1-D sequence of integer indices; got {c.dtype} with shape {c.shape}")
    if c.min() < 0 or c.max() >= n_params:
        bad = c[(c < 0) | (c >= n_params)][0]
        raise ValueError(f"`cols`: index {bad} out of range for {n_params} parameters")
    return c.astype(int)


# --------------------------------------------------------------------------------------------
# Parameter vector
# --------------------------------------------------------------------------------------------
def _layout(n_joints: int) -> list[tuple[str, str]]:
    out = [(f"{name}{j}", unit) for j in range(1, n_joints + 1) for name, unit in JOINT_PARAMS]
    out += [(f"{prefix}_{name}", unit) for prefix in ("base", "tool") for name, unit in FRAME_PARAMS]
    return out + list(SENSOR_PARAMS)


def param_names(n_joints: int) -> list[str]:
    """Names of the ``5N + 17`` parameters, in vector order (joints numbered from 1).

    ``alpha1 a1 d1 theta1 beta1 ... base_x base_y base_z base_rx base_ry base_rz
    tool_x ... tool_rz anchor_x anchor_y anchor_z cable_offset cable_scale``.
    """
    return [name for name, _ in _layout(n_joints)]


def param_units(n_joints: int) -> list[str]:
    """Units (``"rad"``, ``"mm"`` or ``"1"``) of the parameters, in vector order."""
    return [unit for _, unit in _layout(n_joints)]


def _sensor_index(n_joints: int) -> int:
    return 5 * n_joints + 12


# --------------------------------------------------------------------------------------------
# Rotations
# --------------------------------------------------------------------------------------------


def right_jacobian_inverse(phi) -> np.ndarray:
    """Inverse right Jacobian of SO(3): ``log(exp(phi) exp(d)) ~ phi + J_r^-1(phi) d``.

    ``J_r^-1(phi) = I + 1/2 [phi]x + (1/th^2 - (1 + cos th) / (2 th sin th)) [phi]x^2``,
    ``th = |phi|``; below :data:`SMALL_ANGLE` the coefficient is its series ``1/12 + th^2/720``.

    Parameters
    ----------
    phi : array_like, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    phi = np.asarray(phi, dtype=np.float64)
    th = np.linalg.norm(phi, axis=-1)[..., None, None]
    small = th < SMALL_ANGLE
    safe = np.where(small, 1.0, th)
    coef = np.where(small, 1.0 / 12.0 + th**2 / 720.0, 1.0 / safe**2 - (1.0 + np.cos(safe)) / (2.0 * safe * np.sin(safe)))
    K = skew(phi)
    return np.eye(3) + 0.5 * K + coef * (K @ K)


# --------------------------------------------------------------------------------------------
# The chain
# --------------------------------------------------------------------------------------------


def _chain_inputs(conventions, kinds, params, q) -> tuple[list[Op], int, np.ndarray, np.ndarray]:
    ops, flange_end = chain_ops(conventions, kinds)
    n = len(conventions)
    params = _array(params, "params", (5 * n + 17,))
    q = _array(q, "q", ("m", n))
    return ops, flange_end, params, q


def _forward(ops: Sequence[Op], params: np.ndarray, q: np.ndarray):
    """Runs the elementary transforms ``ops`` from the identity.

    ``params`` is (P,) or one vector per sample (m, P). Returns the final rotation ``R`` (m,3,3)
    and origin ``t`` (m,3), and for every op the world axis it acts along and the origin of the
    frame *before* it (each (m, 3)) — what the analytic Jacobian needs.
    """
    m = q.shape[0]
    R = np.broadcast_to(np.eye(3), (m, 3, 3))
    t = np.zeros((m, 3))
    axes, origins = [], []
    for op in ops:
        value = params[..., op.param] + (q[:, op.joint] if op.joint is not None else 0.0)
        value = np.broadcast_to(value, (m,))
        axes.append(R[:, :, op.axis])
        origins.append(t)
        if op.rotation:
            R = R @ rotation(op.axis, value)
        else:
            t = t + R[:, :, op.axis] * value[:, None]
    return R, t, axes, origins


def _tool_jacobian(ops: Sequence[Op], params: np.ndarray, q: np.ndarray, n_params: int):
    """Tool frame ``(R, t)`` and its parameter derivatives ``dp``, ``dw`` (m, n_params, 3): the
    world-frame velocity of the tool origin and angular velocity per unit of each parameter.

    Rotation about world axis ``w`` through ``o``: ``dp = w x (t - o)``, ``dw = w``;
    translation along world axis ``u``: ``dp = u``, ``dw = 0``.
    """
    R, t, axes, origins = _forward(ops, params, q)
    dp = np.zeros((q.shape[0], n_params, 3))
    dw = np.zeros_like(dp)
    for op, w, o in zip(ops, axes, origins):
        if op.rotation:
            dp[:, op.param] += np.cross(w, t - o)
            dw[:, op.param] += w
        else:
            dp[:, op.param] += w
    return R, t, dp, dw


def fk(conventions, kinds, params, q, tool: bool = False) -> np.ndarray:
    """Forward kinematics ``Base · prod_i Link_i(q_i) [· Tool]``.

    Parameters
    ----------
    conventions : sequence of {"dh", "mdh"}, length N
    kinds : sequence of {"revolute", "prismatic"}, length N
    params : array_like, shape (5N + 17,)
        Parameter vector (mm, rad).
    q : array_like, shape (m, N)
        Joint values (rad; mm for prismatic joints). ``m = 0`` gives an empty result.
    tool : bool
        Pose of the tool frame instead of the flange.

    Returns
    -------
    ndarray, shape (m, 4, 4)
        Homogeneous transforms in the base (measurement) frame, translations in mm.
    """
    ops, flange_end, params, q = _chain_inputs(conventions, kinds, params, q)
    R, t, _, _ = _forward(ops if tool else ops[:flange_end], params, q)
    return _homogeneous(R, t)


# --------------------------------------------------------------------------------------------
# Measurement models
# --------------------------------------------------------------------------------------------
def _measurement_inputs(conventions, kinds, measurement, params, q, y, need_y):
    obs_width, _ = _obs_res_width(measurement)
    ops, _, params, q = _chain_inputs(conventions, kinds, params, q)
    if q.shape[0] == 0:
        raise ValueError(f"`q` must have shape (m, {q.shape[1]}) with m >= 1; got {_shape_str(q.shape)}")
    if y is None:
        if need_y:
            raise ValueError(f"`y`: the {measurement} model needs the measured observations")
        return ops, params, q, None
    y = _array(y, "y", (q.shape[0], obs_width))
    if measurement == "pose":
        norms = np.linalg.norm(y[:, 3:], axis=1)
        bad = np.flatnonzero(np.abs(norms - 1.0) > QUATERNION_NORM_TOL)
        if bad.size:
            raise ValueError(f"`y`: row {bad[0]}: quaternion (qw,qx,qy,qz) must have unit norm; got norm {norms[bad[0]]}")
    return ops, params, q, y


def _cable_terms(params: np.ndarray, t: np.ndarray, n_joints: int):
    """``dist = |t - anchor|``, unit direction ``u`` (x axis where ``dist = 0``, a valid
    subgradient that keeps the Jacobian finite), ``cable_offset``, ``cable_scale``."""
    s = _sensor_index(n_joints)
    diff = t - params[..., s : s + 3]
    dist = np.linalg.norm(diff, axis=1)
    u = np.where(dist[:, None] > 0, diff / np.where(dist > 0, dist, 1.0)[:, None], np.array([1.0, 0.0, 0.0]))
    return dist, u, params[..., s + 3], params[..., s + 4]


def _predict(ops, n_joints, measurement, params, q) -> np.ndarray:
    R, t, _, _ = _forward(ops, params, q)
    if measurement == "cable":
        dist, _, offset, scale = _cable_terms(params, t, n_joints)
        return (scale * dist - offset)[:, None]
    if measurement == "position":
        return t
    return np.concatenate([t, quaternion_from_matrix(R)], axis=1)


def _residuals_of_frame(n_joints, measurement, params, R, t, y) -> np.ndarray:
    if measurement == "cable":
        dist, _, offset, scale = _cable_terms(params, t, n_joints)
        return y - (scale * dist - offset)[:, None]
    if measurement == "position":
        return y - t
    return np.concatenate([y[:, :3] - t, so3_log(matrix_from_quaternion(y[:, 3:]) @ np.swapaxes(R, 1, 2))], axis=1)


def _residuals(ops, n_joints, measurement, params, q, y) -> np.ndarray:
    R, t, _, _ = _forward(ops, params, q)
    return _residuals_of_frame(n_joints, measurement, params, R, t, y)


def predict(conventions, kinds, measurement: str, params, q) -> np.ndarray:
    """Model prediction ``h`` per sample.

    Parameters
    ----------
    conventions, kinds : sequences of str, length N
        See :func:`chain_ops`.
    measurement : {"cable", "position", "pose"}
    params : array_like, shape (5N + 17,)
    q : array_like, shape (m, N), m >= 1

    Returns
    -------
    ndarray, shape (m, 1 | 3 | 7)
        ``cable``: ``cable_scale * |p - anchor| - cable_offset`` (mm); ``position``: ``p`` (mm);
        ``pose``: ``x, y, z`` (mm), ``qw, qx, qy, qz`` with ``qw >= 0``.
    """
    ops, params, q, _ = _measurement_inputs(conventions, kinds, measurement, params, q, None, need_y=False)
    return _predict(ops, len(conventions), measurement, params, q)


def residuals(conventions, kinds, measurement: str, params, q, y) -> np.ndarray:
    """Residuals ``r = y - h`` per sample.

    Parameters
    ----------
    conventions, kinds, measurement, params, q
        See :func:`predict`.
    y : array_like, shape (m, 1 | 3 | 7)
        Observations: cable length (mm); ``x, y, z`` (mm); or ``x, y, z, qw, qx, qy, qz``
        (quaternion of unit norm within :data:`QUATERNION_NORM_TOL`, normalised here).

    Returns
    -------
    ndarray, shape (m, 1 | 3 | 6)
        For ``pose``: ``y_p - p`` (mm) then ``log(R_meas R^T)`` (rad).
    """
    ops, params, q, y = _measurement_inputs(conventions, kinds, measurement, params, q, y, need_y=True)
    return _residuals(ops, len(conventions), measurement, params, q, y)


def jacobian(conventions, kinds, measurement: str, params, q, y=None, cols=None) -> np.ndarray:
    """Analytic identification Jacobian ``J = dh/dparams[cols]``.

    ``r(params + delta) ~ r(params) - J delta``. For ``pose`` the rotation rows are
    ``J_r^-1(e) · Omega`` with ``e = log(R_meas R^T)`` and ``Omega`` the world-frame angular
    Jacobian: the exact derivative of the rotation residual.

    Parameters
    ----------
    conventions, kinds, measurement, params, q
        See :func:`predict`.
    y : array_like, shape (m, obs_width), optional
        Observations; required for ``pose``.
    cols : sequence of int, optional
        Parameter indices (default: all ``5N + 17``).

    Returns
    -------
    ndarray, shape (m * res_width, len(cols))
        Rows sample-major (row ``i * res_width + c``); units mm or rad per unit of the parameter.
    """
    ops, params, q, y = _measurement_inputs(conventions, kinds, measurement, params, q, y, need_y=measurement == "pose")
    n = len(conventions)
    cols = _columns(cols, params.size)
    R, t, dp, dw = _tool_jacobian(ops, params, q, params.size)
    if measurement == "cable":
        dist, u, _, scale = _cable_terms(params, t, n)
        J = scale * np.einsum("mi,mpi->mp", u, dp)[:, None, :]
        s = _sensor_index(n)
        J[:, 0, s : s + 3] = -scale * u
        J[:, 0, s + 3] = -1.0
        J[:, 0, s + 4] = dist
    elif measurement == "position":
        J = np.swapaxes(dp, 1, 2)
    else:
        e = _residuals_of_frame(n, measurement, params, R, t, y)[:, 3:]
        rot = np.einsum("mij,mpj->mip", right_jacobian_inverse(e), dw)
        J = np.concatenate([np.swapaxes(dp, 1, 2), rot], axis=1)
    return np.ascontiguousarray(J[:, :, cols].reshape(J.shape[0] * J.shape[1], cols.size))


def sigma_residuals(conventions, kinds, measurement: str, params, cols, sigmas, q, y) -> np.ndarray:
    """Residuals of every sigma point (the UKF's propagation step).

    Parameters
    ----------
    conventions, kinds, measurement, params, q, y
        See :func:`residuals`.
    cols : sequence of int, length n >= 1
        Indices of the parameters the sigma points set.
    sigmas : array_like, shape (S, n)
        Absolute values of ``params[cols]``, one row per sigma point.

    Returns
    -------
    ndarray, shape (S, m * res_width)
        Row ``s``: ``r`` (flattened sample-major) with ``params[cols] = sigmas[s]``.
    """
    ops, params, q, y = _measurement_inputs(conventions, kinds, measurement, params, q, y, need_y=True)
    cols = _columns(cols, params.size)
    if cols.size == 0:
        raise ValueError("`cols` must hold at least one parameter index; got none")
    sigmas = _array(sigmas, "sigmas", ("S", cols.size))
    m, S = q.shape[0], sigmas.shape[0]
    per_sigma = np.tile(params, (S, 1))
    per_sigma[:, cols] = sigmas
    # All S·m (sigma point, sample) pairs in one batch: sample i of sigma point s is row s·m + i.
    r = _residuals(ops, len(conventions), measurement, np.repeat(per_sigma, m, axis=0), np.tile(q, (S, 1)), np.tile(y, (S, 1)))
    return r.reshape(S, m * r.shape[1])


# --------------------------------------------------------------------------------------------
# Unscented transform
# --------------------------------------------------------------------------------------------
def merwe_sigma_points(x, P, alpha: float, beta: float, kappa: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Merwe scaled sigma points (filterpy's ``MerweScaledSigmaPoints(n, alpha, beta, kappa)``).

    ``lambda = alpha^2 (n + kappa) - n``; ``chi_0 = x``, ``chi_i = x + col_i(L)``,
    ``chi_{n+i} = x - col_i(L)`` with ``L L^T = (n + lambda) P`` (Cholesky);
    ``Wm_0 = lambda / (n + lambda)``, ``Wc_0 = Wm_0 + 1 - alpha^2 + beta``,
    ``Wm_i = Wc_i = 1 / (2 (n + lambda))``.

    Parameters
    ----------
    x : array_like, shape (n,), n >= 1
        Mean.
    P : array_like, shape (n, n)
        Symmetric positive definite covariance.
    alpha : float
        Spread, > 0 (with ``alpha^2 (n + kappa) > 0``).
    beta, kappa : float

    Returns
    -------
    sigmas : ndarray, shape (2n + 1, n)
    Wm, Wc : ndarray, shape (2n + 1,)
    """
    x = _array(x, "x", ("n",))
    n = x.size
    if n == 0:
        raise ValueError("`x` must have shape (n,) with n >= 1; got (0,)")
    P = _array(P, "P", (n, n))
    alpha, beta, kappa = _float(alpha, "alpha"), _float(beta, "beta"), _float(kappa, "kappa")
    lam = alpha**2 * (n + kappa) - n
    if not (alpha > 0 and n + lam > 0):
        raise ValueError(f"`alpha`: need alpha > 0 and alpha^2 (n + kappa) > 0; got alpha={alpha}, kappa={kappa}, n={n}")
    scaled = (n + lam) * P
    asym = np.abs(scaled - scaled.T).max()
    if asym > SYMMETRY_TOL * np.abs(scaled).max():
        raise ValueError(f"`P` must be symmetric; got max |P - P^T| = {asym:e} (scaled by n + lambda)")
    try:
        L = np.linalg.cholesky(scaled)
    except np.linalg.LinAlgError:
        raise np.linalg.LinAlgError("`P` (sigma-point covariance) is not positive definite") from None
    sigmas = np.ascontiguousarray(np.vstack([x, x + L.T, x - L.T]))
    Wm = np.full(2 * n + 1, 1.0 / (2.0 * (n + lam)))
    Wc = Wm.copy()
    Wm[0] = lam / (n + lam)
    Wc[0] = Wm[0] + 1.0 - alpha**2 + beta
    return sigmas, Wm, Wc


def unscented_transform(sigmas_x, sigmas_y, Wm, Wc) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Weighted statistics of propagated sigma points (the paper's eq. 10-11).

    Parameters
    ----------
    sigmas_x : array_like, shape (S, n)
        Sigma points.
    sigmas_y : array_like, shape (S, k)
        Their images.
    Wm, Wc : array_like, shape (S,)
        Mean and covariance weights.

    Returns
    -------
    mean_y : ndarray, shape (k,)
        ``sum_s Wm_s y_s``.
    cov_y : ndarray, shape (k, k)
        ``sum_s Wc_s (y_s - mean_y)(y_s - mean_y)^T``.
    cross : ndarray, shape (n, k)
        ``sum_s Wc_s (x_s - mean_x)(y_s - mean_y)^T`` with ``mean_x = sum_s Wm_s x_s``.
    """
    Wm = _array(Wm, "Wm", ("S",))
    S = Wm.size
    if S == 0:
        raise ValueError("`Wm` must have shape (S,) with S >= 1; got (0,)")
    Wc = _array(Wc, "Wc", (S,))
    sx = _array(sigmas_x, "sigmas_x", (S, "n"))
    sy = _array(sigmas_y, "sigmas_y", (S, "k"))
    dx = sx - Wm @ sx
    mean_y = Wm @ sy
    dy = sy - mean_y
    return mean_y, np.einsum("s,si,sj->ij", Wc, dy, dy), np.einsum("s,si,sj->ij", Wc, dx, dy)


# --------------------------------------------------------------------------------------------
# Damped solve, identifiability, covariance
# --------------------------------------------------------------------------------------------
def damped_qr_step(J, b, lam: float) -> tuple[np.ndarray, float]:
    """Twin of ``DampedQr(J)``: the step minimising ``‖J·δ − b‖² + lam‖δ‖²`` (least squares of
    ``[J; sqrt(lam) I] δ ≈ [b; 0]``, minimum-norm with NumPy's default cut-off) and ``‖Qᵀb‖``, the
    norm of ``b``'s projection on the columns of ``J``."""
    J = _array(J, "J", ("m", "n"))
    b = _array(b, "b", (J.shape[0],))
    lam = _float(lam, "lam")
    if lam < 0:
        raise ValueError(f"`lam` must be finite and >= 0; got {lam}")
    n = J.shape[1]
    step = np.linalg.lstsq(np.vstack([J, np.sqrt(lam) * np.eye(n)]), np.concatenate([b, np.zeros(n)]), rcond=None)[0]
    explained = J @ np.linalg.lstsq(J, b, rcond=None)[0]
    return step, float(np.linalg.norm(explained))


def solve_damped(J, r, lam: float, damping: str = "marquardt", factor: str = "normal") -> tuple[np.ndarray, str]:
    """Damped step ``(J^T J + lam D) delta = J^T r``.

    ``factor="normal"``: Cholesky of the normal matrix first; if it is not positive definite
    (or its factor has a squared pivot <= :data:`RANK_TOL` times the largest), the minimum-norm
    solution through the SVD (singular values <= ``RANK_TOL * n`` times the largest dropped).
    ``factor="lstsq"``: the same Cholesky if every squared pivot exceeds :data:`WELL_CONDITIONED`
    times the largest; else the least squares of ``[J; sqrt(lam) D^1/2] delta ~ [r; 0]`` in
    columns scaled to unit norm, by column-pivoted QR; if its smallest pivot is <= ``eps (m + n)``
    times the largest, the minimum-norm solution through the SVD with that cut-off.

    Parameters
    ----------
    J : array_like, shape (m, n)
    r : array_like, shape (m,)
    lam : float
        Damping, finite and >= 0.
    damping : {"marquardt", "identity"}
        ``D = diag(J^T J)`` (Marquardt) or ``D = I`` (Levenberg, the paper's eq. 14;
        ``"levenberg"`` is an alias).
    factor : {"normal", "lstsq"}

    Returns
    -------
    delta : ndarray, shape (n,)
    method : {"cholesky", "qr", "svd"}
    """
    if damping not in ("marquardt", "identity", "levenberg"):
        raise ValueError(f"`damping` must be 'marquardt' or 'identity'; got {damping!r}")
    J = _array(J, "J", ("m", "n"))
    r = _array(r, "r", (J.shape[0],))
    lam = _float(lam, "lam")
    if lam < 0:
        raise ValueError(f"`lam` must be finite and >= 0; got {lam}")
    if factor not in ("normal", "lstsq"):
        raise ValueError(f"`factor` must be 'normal' or 'lstsq'; got {factor!r}")
    if factor == "lstsq":
        return _solve_damped_lstsq(J, r, lam, damping)
    M, g = _damped_normal(J, r, lam, damping)
    n = len(g)
    if n == 0:
        return np.zeros(0), "cholesky"
    step = _cholesky_step(M, g, RANK_TOL)
    if step is not None:
        return step, "cholesky"
    return np.linalg.lstsq(M, g, rcond=RANK_TOL * n)[0], "svd"


def _damped_normal(J: np.ndarray, r: np.ndarray, lam: float, damping: str) -> tuple[np.ndarray, np.ndarray]:
    """``(J^T J + lam D, J^T r)``."""
    A = J.T @ J
    D = np.diag(np.diag(A)) if damping == "marquardt" else np.eye(A.shape[0])
    return A + lam * D, J.T @ r


def _cholesky_step(M: np.ndarray, g: np.ndarray, min_ratio: float):
    """The Cholesky solution of ``M x = g`` if every squared pivot exceeds ``min_ratio`` times the
    largest, else None."""
    try:
        factor = scipy.linalg.cho_factor(M, lower=True)
    except np.linalg.LinAlgError:
        return None
    pivots = np.diag(factor[0]) ** 2
    return scipy.linalg.cho_solve(factor, g) if pivots.min() > min_ratio * pivots.max() else None


def _solve_damped_lstsq(J: np.ndarray, r: np.ndarray, lam: float, damping: str) -> tuple[np.ndarray, str]:
    """``solve_damped(..., factor="lstsq")``."""
    m, n = J.shape
    if n == 0:
        return np.zeros(0), "qr"
    step = _cholesky_step(*_damped_normal(J, r, lam, damping), WELL_CONDITIONED)
    if step is not None:
        return step, "cholesky"
    norms = np.linalg.norm(J, axis=0)
    scale = np.where(norms > 0, norms, 1.0)
    damping_rows = np.sqrt(lam) * (norms if damping == "marquardt" else np.ones(n)) / scale
    A = np.vstack([J / scale, np.diag(damping_rows)])
    b = np.concatenate([r, np.zeros(n)])
    rcond = np.finfo(float).eps * (m + n)
    Q, R, perm = scipy.linalg.qr(A, mode="economic", pivoting=True)
    pivots = np.abs(np.diag(R))
    if pivots.min() > rcond * pivots.max():
        y = np.empty(n)
        y[perm] = scipy.linalg.solve_triangular(R, Q.T @ b)
        return y / scale, "qr"
    return np.linalg.lstsq(A, b, rcond=rcond)[0] / scale, "svd"


def _scaled_columns(J: np.ndarray):
    """Column norms, the "has an effect" mask (:data:`NO_EFFECT_REL`) and ``J`` with unit-norm
    columns (columns without effect left at zero, never divided by 0)."""
    norms = np.linalg.norm(J, axis=0)
    effective = (norms > NO_EFFECT_REL * norms.max(initial=0.0)) & (norms > 0)
    scaled = np.where(effective, J / np.where(effective, norms, 1.0), 0.0)
    return norms, effective, scaled


def _kept(s: np.ndarray, tol: float) -> np.ndarray:
    """Singular values that count towards the rank: ``s > tol * s_max`` (and non-zero)."""
    return (s > tol * s.max(initial=0.0)) & (s > 0)


def _check_tol(tol) -> float:
    tol = _float(tol, "tol")
    if not 0 < tol < 1:
        raise ValueError(f"`tol` must lie in (0, 1); got {tol}")
    return tol


def _pivoted_qr_order(A: np.ndarray, first: np.ndarray) -> list[int]:
    """Pivot order of a Householder QR of ``A`` (p, k) with column pivoting: each step the largest
    remaining column norm among the columns ``first`` (k bools) marks if it is at least
    :data:`FIRST_MIN_REL` of the largest of all, otherwise among all; ties within
    :data:`PIVOT_TIE_REL` to the lowest column index."""
    A = np.array(A, dtype=np.float64)
    p, k = A.shape
    perm = list(range(k))
    for i in range(min(p, k)):
        norms = np.linalg.norm(A[i:, i:], axis=0)
        marked = np.asarray(first)[perm[i:]]
        preferred = norms[marked].max(initial=0.0)
        pool = marked if preferred > 0 and preferred >= FIRST_MIN_REL * norms.max() else np.ones(k - i, bool)
        tied = np.flatnonzero(pool & (norms >= norms[pool].max() * (1.0 - PIVOT_TIE_REL)))
        best = i + min(tied, key=lambda j: perm[i + j])
        A[:, [i, best]] = A[:, [best, i]]
        perm[i], perm[best] = perm[best], perm[i]
        if norms.max() == 0.0:
            break
        v = A[i:, i].copy()
        v[0] += np.copysign(np.linalg.norm(v), v[0])
        A[i:, i:] -= np.outer(v, 2.0 * (v @ A[i:, i:]) / (v @ v))
    return perm


def identifiability(J, tol: float = 1e-9, first=None) -> dict:
    """Which parameters a Jacobian identifies, on unit-norm columns.

    The rank counts singular values of the scaled ``J`` above ``tol * sigma_1``; a column-pivoted
    Householder QR of the columns with an effect picks the identifiable subset (its first
    ``rank`` pivots; the columns ``first`` marks before the others while they add at least
    :data:`FIRST_MIN_REL` of the largest remaining norm; ties within :data:`PIVOT_TIE_REL` go to
    the lowest column index); each other column ``j`` is written by least
    squares as ``J_j ~ sum_k c_k J_k`` over that subset, and the partners ``k`` with
    ``|c_k| >`` :data:`REDUNDANCY_COEF_MIN` (1e-6) are reported. A column counts as having no
    effect when its norm is at most :data:`NO_EFFECT_REL` (1e-12) times the largest.

    Parameters
    ----------
    J : array_like, shape (m, n)
    tol : float
        Relative singular-value threshold, in (0, 1).
    first : array_like of bool, shape (n,), optional
        Columns to pivot first (a session's set-up): default none.

    Returns
    -------
    dict
        ``singular_values`` (min(m, n),) descending; ``rank`` int; ``condition_number``
        ``sigma_1 / sigma_rank`` (inf for rank 0); ``column_norms`` (n,) of the unscaled ``J``;
        ``identifiable`` list of int in pivot order; ``no_effect`` list of int (zero columns);
        ``redundant`` list of ``(j, [(k, c_k), ...])``.

    Notes
    -----
    The scaled columns all have norm 1, so the first pivot is a tie: the lowest column index.
    Exactly redundant columns (``theta1`` and ``base_rz``) keep the lower index the same way;
    only columns whose remaining norms differ by about :data:`PIVOT_TIE_REL` could be chosen
    otherwise by another implementation's rounding.
    """
    tol = _check_tol(tol)
    J = _array(J, "J", ("m", "n"))
    norms, effective, scaled = _scaled_columns(J)
    s = np.linalg.svd(scaled, compute_uv=False)
    rank = int(_kept(s, tol).sum())
    condition = float(s[0] / s[rank - 1]) if rank else float("inf")
    candidates = np.flatnonzero(effective)
    identifiable: list[int] = []
    if candidates.size:
        marked = np.zeros(J.shape[1], bool) if first is None else _array(first, "first", (J.shape[1],)) != 0
        pivots = _pivoted_qr_order(scaled[:, candidates], marked[candidates])
        identifiable = [int(c) for c in candidates[pivots[:rank]]]
    others = [int(c) for c in candidates if c not in identifiable]
    redundant = []
    if identifiable and others:
        coefs = np.linalg.lstsq(scaled[:, identifiable], scaled[:, others], rcond=None)[0]
        for col, c in zip(others, coefs.T):
            redundant.append((col, [(k, float(v)) for k, v in zip(identifiable, c) if abs(v) > REDUNDANCY_COEF_MIN]))
    return {
        "singular_values": s,
        "rank": rank,
        "condition_number": condition,
        "column_norms": norms,
        "identifiable": identifiable,
        "no_effect": [int(c) for c in np.flatnonzero(~effective)],
        "redundant": redundant,
    }


def covariance(J, r, tol: float = 1e-9) -> tuple[np.ndarray, float, int, int]:
    """Parameter covariance ``sigma2 (J^T J)^+`` of a least-squares fit.

    The pseudo-inverse is taken on unit-norm columns, ``(J^T J)^+ = N^-1 (Jn^T Jn)^+ N^-1``
    with ``J = Jn N``, rank by ``tol`` as in :func:`identifiability` (columns without effect get
    zero rows and columns); ``sigma2 = |r|^2 / (rows - rank)``.

    Parameters
    ----------
    J : array_like, shape (m, n)
    r : array_like, shape (m,)
        Final residuals.
    tol : float
        Relative singular-value threshold, in (0, 1).

    Returns
    -------
    cov : ndarray, shape (n, n)
        Entry ``(i, j)`` in unit_i · unit_j (mm², mm·rad, rad², ...).
    sigma2 : float
    dof : int
        ``m - rank`` (must be >= 1).
    rank : int
    """
    tol = _check_tol(tol)
    J = _array(J, "J", ("m", "n"))
    r = _array(r, "r", (J.shape[0],))
    norms, effective, scaled = _scaled_columns(J)
    _, s, Vt = np.linalg.svd(scaled, full_matrices=False)
    keep = _kept(s, tol)
    rank = int(keep.sum())
    m = J.shape[0]
    if m <= rank:
        raise ValueError(f"`J`: {m} residuals leave no degrees of freedom for {rank} identifiable parameters")
    dof = m - rank
    sigma2 = float(r @ r / dof)
    V = Vt[keep].T / s[keep]
    inv_norms = np.where(effective, 1.0 / np.where(effective, norms, 1.0), 0.0)
    cov = sigma2 * (V @ V.T) * np.outer(inv_norms, inv_norms)
    return cov, sigma2, dof, rank


def cable_initial_guess(p, L) -> tuple[np.ndarray, float]:
    """Closed-form cable anchor ``P0`` and sensor zero ``L0`` (``cable_offset``).

    ``|p_i - P0| = L_i + L0`` squared is linear in ``(P0, L0, c = L0^2 - |P0|^2)``:
    ``|p_i|^2 - L_i^2 = 2 p_i·P0 + 2 L_i L0 + c``, solved by least squares on positions centred
    on their mean (for conditioning). Exact on noiseless data with ``cable_scale = 1``.

    Parameters
    ----------
    p : array_like, shape (m, 3)
        Tool points (mm), m >= 5.
    L : array_like, shape (m,)
        Cable readings (mm).

    Returns
    -------
    anchor : ndarray, shape (3,)
        ``P0`` (mm).
    cable_offset : float
        ``L0`` (mm).

    Raises
    ------
    numpy.linalg.LinAlgError
        If the points do not determine the anchor (condition number above
        ``1 / CABLE_CONDITION_MIN``).
    """
    L = _array(L, "L", ("m",))
    m = L.size
    p = _array(p, "p", (m, 3))
    if m < 5:
        raise ValueError(f"`p` must have shape (m, 3) with m >= 5 samples; got {_shape_str(p.shape)}")
    centre = p.mean(axis=0)
    x = p - centre
    A = np.column_stack([2.0 * x, 2.0 * L, np.ones(m)])
    b = np.sum(x * x, axis=1) - L * L
    s = np.linalg.svd(A, compute_uv=False)
    if not s.min() > CABLE_CONDITION_MIN * s.max():
        condition = s.max() / s.min() if s.min() > 0 else np.inf
        raise np.linalg.LinAlgError(
            f"the {m} tool positions and lengths do not determine the cable anchor (condition number {condition:.3e}); use configurations spread over 3-D space"
        )
    sol = np.linalg.lstsq(A, b, rcond=None)[0]
    return sol[:3] + centre, float(sol[3])


def ukf_sweep(conventions, kinds, measurement: str, params, cols, q, y, x, P, Q, R, alpha: float, beta: float, kappa: float):
    """One UKF sweep over the samples, the parameters ``params[cols]`` as the state (twin of the
    Rust ``Chain.ukf_sweep``; the paper's eq. 8-12 with identity transition).

    Per sample: Merwe sigma points ``χ`` of ``(x, P)``; ``P⁻ = P + Q``; predicted observations in
    residual form ``z = −r(χ)`` (observation 0); ``ẑ = Σ Wm z``,
    ``S = Σ Wc (z − ẑ)(z − ẑ)ᵀ + R``, ``P_xz = Σ Wc (χ − x)(z − ẑ)ᵀ``, ``K = P_xz S⁻¹``;
    ``x ← x − K ẑ``, ``P ← P⁻ − K S Kᵀ`` (symmetrised).

    Returns
    -------
    x : ndarray, shape (n,)
    P : ndarray, shape (n, n)
    """
    y = np.asarray(y, dtype=np.float64)
    x = np.array(x, dtype=np.float64)
    P = np.array(P, dtype=np.float64)
    for i in range(len(q)):
        sigmas, Wm, Wc = merwe_sigma_points(x, P, alpha, beta, kappa)
        z = -sigma_residuals(conventions, kinds, measurement, params, cols, sigmas, q[i : i + 1], y[i : i + 1])
        z_mean = Wm @ z
        dz, dx = z - z_mean, sigmas - x
        S = (Wc * dz.T) @ dz + R
        K = np.linalg.solve(S, ((Wc * dx.T) @ dz).T).T
        x = x - K @ z_mean
        P = P + Q - K @ S @ K.T
        P = 0.5 * (P + P.T)
    return x, P


def configuration_groups(q: np.ndarray, tol: float) -> np.ndarray:
    """Oracle for the core's configuration labels: samples of ``q`` (m, N) within ``tol`` of each
    other on every joint (chained) share a label, ``0..g-1`` in order of first appearance — a k-d
    tree's pairs (Chebyshev distance) and their connected components."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    m = len(q)
    if m == 0:
        return np.zeros(0, dtype=np.int64)
    pairs = cKDTree(q).query_pairs(tol, p=np.inf, output_type="ndarray")
    if len(pairs) == 0:
        return np.arange(m)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(m, m))
    _, component = connected_components(graph, directed=False)
    _, first, inverse = np.unique(component, return_index=True, return_inverse=True)
    rank = np.empty(len(first), dtype=np.int64)
    rank[np.argsort(first)] = np.arange(len(first))
    return rank[inverse.ravel()]
