"""Rigid-body geometry shared by the package: elementary rotations, the base/tool frame
parameters ``(x, y, z, rx, ry, rz)``, SO(3) exponential and logarithm, quaternions, the Kabsch
alignment and the chain as a list of elementary transforms.

Pure NumPy (no SciPy, no compiled core), so that any layer can import it at no cost. The
oracle :mod:`robocal.reference` keeps its own copy of these functions: it must stay a
self-contained twin that the tests load from its file alone.
Quaternions are ``(w, x, y, z)``; units mm and rad.
"""

from __future__ import annotations

from typing import NamedTuple, Optional, Sequence

import numpy as np

X, Y, Z = 0, 1, 2
#: Below this rotation angle (rad) the Rodrigues coefficients are their Taylor series.
SMALL_ANGLE = 1e-4


def rotation(axis: int, angle) -> np.ndarray:
    """Elementary rotation matrices about axis ``axis`` (0 = x, 1 = y, 2 = z).

    Parameters
    ----------
    axis : {0, 1, 2}
    angle : array_like, shape (...)
        Angles in rad.

    Returns
    -------
    ndarray, shape (..., 3, 3)
    """
    angle = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(angle), np.sin(angle)
    i, j = (axis + 1) % 3, (axis + 2) % 3
    R = np.zeros(angle.shape + (3, 3))
    R[..., axis, axis] = 1.0
    R[..., i, i], R[..., i, j] = c, -s
    R[..., j, i], R[..., j, j] = s, c
    return R


def homogeneous(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    T = np.zeros(R.shape[:-2] + (4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = t
    T[..., 3, 3] = 1.0
    return T


def frame_transform(xyzrpy) -> np.ndarray:
    """``Tx(x) Ty(y) Tz(z) Rz(rz) Ry(ry) Rx(rx)`` — the base and tool frames.

    Parameters
    ----------
    xyzrpy : array_like, shape (..., 6)
        ``x, y, z`` (mm), ``rx, ry, rz`` (rad): the order of the parameter vector.

    Returns
    -------
    ndarray, shape (..., 4, 4)
    """
    p = np.asarray(xyzrpy, dtype=np.float64)
    R = rotation(Z, p[..., 5]) @ rotation(Y, p[..., 4]) @ rotation(X, p[..., 3])
    return homogeneous(R, p[..., :3])


def frame_params(T) -> np.ndarray:
    """Inverse of :func:`frame_transform`: ``(x, y, z, rx, ry, rz)`` of homogeneous transforms.

    ``ry`` is returned in ``[-pi/2, pi/2]``; at gimbal lock (``|ry| = pi/2``) ``rx`` is set to 0.

    Parameters
    ----------
    T : array_like, shape (..., 4, 4)

    Returns
    -------
    ndarray, shape (..., 6)
    """
    T = np.asarray(T, dtype=np.float64)
    R = T[..., :3, :3]
    cy = np.hypot(R[..., 0, 0], R[..., 1, 0])
    ry = np.arctan2(-R[..., 2, 0], cy)
    locked = cy < 1e-12
    # Away from gimbal lock: R = Rz Ry Rx gives rz from column 0 and rx from row 2.
    rz = np.where(locked, np.arctan2(-R[..., 0, 1], R[..., 1, 1]), np.arctan2(R[..., 1, 0], R[..., 0, 0]))
    rx = np.where(locked, 0.0, np.arctan2(R[..., 2, 1], R[..., 2, 2]))
    return np.concatenate([T[..., :3, 3], np.stack([rx, ry, rz], axis=-1)], axis=-1)


def skew(v) -> np.ndarray:
    """Cross-product matrices ``[v]x`` (``[v]x @ w = v x w``), shape (..., 3) -> (..., 3, 3)."""
    v = np.asarray(v, dtype=np.float64)
    K = np.zeros(v.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2] = -v[..., 2], v[..., 1]
    K[..., 1, 0], K[..., 1, 2] = v[..., 2], -v[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -v[..., 1], v[..., 0]
    return K


def so3_exp(phi) -> np.ndarray:
    """Rotation matrices of rotation vectors (Rodrigues), shape (..., 3) -> (..., 3, 3)."""
    phi = np.asarray(phi, dtype=np.float64)
    th = np.linalg.norm(phi, axis=-1)[..., None, None]
    small = th < SMALL_ANGLE
    safe = np.where(small, 1.0, th)
    a = np.where(small, 1.0 - th**2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - th**2 / 24.0, (1.0 - np.cos(safe)) / safe**2)
    K = skew(phi)
    return np.eye(3) + a * K + b * (K @ K)


def quaternion_from_matrix(R) -> np.ndarray:
    """Unit quaternions ``(w, x, y, z)`` of rotation matrices, sign chosen with ``w >= 0``.

    Shepperd's method: ``Q = 4 q q^T`` is assembled from the matrix entries and ``q`` is read
    from its row with the largest diagonal entry (the best-conditioned one).

    Parameters
    ----------
    R : array_like, shape (..., 3, 3)

    Returns
    -------
    ndarray, shape (..., 4)
    """
    R = np.asarray(R, dtype=np.float64)
    r = lambda i, j: R[..., i, j]  # noqa: E731
    Q = np.stack(
        [
            np.stack([1 + r(0, 0) + r(1, 1) + r(2, 2), r(2, 1) - r(1, 2), r(0, 2) - r(2, 0), r(1, 0) - r(0, 1)], -1),
            np.stack([r(2, 1) - r(1, 2), 1 + r(0, 0) - r(1, 1) - r(2, 2), r(0, 1) + r(1, 0), r(0, 2) + r(2, 0)], -1),
            np.stack([r(0, 2) - r(2, 0), r(0, 1) + r(1, 0), 1 - r(0, 0) + r(1, 1) - r(2, 2), r(1, 2) + r(2, 1)], -1),
            np.stack([r(1, 0) - r(0, 1), r(0, 2) + r(2, 0), r(1, 2) + r(2, 1), 1 - r(0, 0) - r(1, 1) + r(2, 2)], -1),
        ],
        -2,
    )
    k = np.argmax(np.diagonal(Q, axis1=-2, axis2=-1), axis=-1)[..., None, None]
    row = np.take_along_axis(Q, np.broadcast_to(k, Q.shape[:-2] + (1, 4)), axis=-2)[..., 0, :]
    q = row / np.linalg.norm(row, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def matrix_from_quaternion(q) -> np.ndarray:
    """Rotation matrices of quaternions ``(w, x, y, z)`` (normalised first), (..., 4) -> (..., 3, 3)."""
    q = np.asarray(q, dtype=np.float64)
    w, x, y, z = np.moveaxis(q / np.linalg.norm(q, axis=-1, keepdims=True), -1, 0)
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def so3_log(R) -> np.ndarray:
    """Rotation vectors ``log(R)`` (rad, angle in ``[0, pi]``), (..., 3, 3) -> (..., 3).

    Computed through the quaternion, ``angle = 2 atan2(|v|, w)``, so it stays accurate near pi.
    """
    q = quaternion_from_matrix(R)
    w, v = q[..., :1], q[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    tiny = s < 1e-12
    return v * np.where(tiny, 2.0, 2.0 * np.arctan2(s, w) / np.where(tiny, 1.0, s))


def kabsch(points: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Rigid transform (4x4) best mapping ``points`` onto ``targets`` (both (m, 3)), least squares."""
    pc, tc = points.mean(axis=0), targets.mean(axis=0)
    u, _, vt = np.linalg.svd((points - pc).T @ (targets - tc))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    R = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return homogeneous(R, tc - R @ pc)


class Op(NamedTuple):
    """One elementary transform of the chain: a rotation about (or translation along) local
    axis ``axis`` by ``params[param]`` plus, for a joint's variable, ``q[:, joint]``."""

    rotation: bool
    axis: int
    param: int
    joint: Optional[int]


def chain_ops(conventions: Sequence[str], kinds: Sequence[str]) -> tuple[list[Op], int]:
    """The chain as a flat list of elementary transforms.

    ``Base = Tx Ty Tz Rz Ry Rx``; each joint ``dh``: ``Rz(theta+q) Tz(d) Tx(a) Rx(alpha) Ry(beta)``
    or ``mdh``: ``Rx(alpha) Tx(a) Ry(beta) Rz(theta+q) Tz(d)`` (``q`` adds to ``d`` instead on a
    prismatic joint); ``Tool = Tx Ty Tz Rz Ry Rx``.

    Parameters
    ----------
    conventions : sequence of {"dh", "mdh"}, length N >= 1
    kinds : sequence of {"revolute", "prismatic"}, length N

    Returns
    -------
    ops : list of Op
    flange_end : int
        ``ops[:flange_end]`` is the flange frame (no tool).
    """
    conventions, kinds = list(conventions), list(kinds)
    if not conventions or len(conventions) != len(kinds):
        raise ValueError(
            f"`kinds` must have one entry per joint of `conventions` (at least one joint); got {len(kinds)} kinds for {len(conventions)} conventions"
        )
    n = len(conventions)

    def frame_ops(start: int) -> list[Op]:  # Tx Ty Tz Rz Ry Rx from x y z rx ry rz
        return [
            Op(False, X, start, None),
            Op(False, Y, start + 1, None),
            Op(False, Z, start + 2, None),
            Op(True, Z, start + 5, None),
            Op(True, Y, start + 4, None),
            Op(True, X, start + 3, None),
        ]

    ops = frame_ops(5 * n)  # the base's parameters follow the joints' five each
    for j, (convention, kind) in enumerate(zip(conventions, kinds)):
        alpha, a, d, theta, beta = range(5 * j, 5 * j + 5)
        if kind not in ("revolute", "prismatic"):
            raise ValueError(f"`kinds` must hold 'revolute' or 'prismatic'; got {kind!r}")
        q_theta, q_d = (j, None) if kind == "revolute" else (None, j)
        link = {
            "dh": [Op(True, Z, theta, q_theta), Op(False, Z, d, q_d), Op(False, X, a, None), Op(True, X, alpha, None), Op(True, Y, beta, None)],
            "mdh": [Op(True, X, alpha, None), Op(False, X, a, None), Op(True, Y, beta, None), Op(True, Z, theta, q_theta), Op(False, Z, d, q_d)],
        }.get(convention)
        if link is None:
            raise ValueError(f"`conventions` must hold 'dh' or 'mdh'; got {convention!r}")
        ops += link
    flange_end = len(ops)
    return ops + frame_ops(5 * n + 6), flange_end
