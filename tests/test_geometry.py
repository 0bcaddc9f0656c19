"""``robocal.geometry`` (pure NumPy, shared by production code and the NumPy oracle) against
SciPy's independent rotations."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from robocal import geometry


@pytest.fixture(scope="module")
def rotations():
    """Rotation vectors: generic, tiny (the small-angle series) and close to pi."""
    rng = np.random.default_rng(0)
    phi = rng.normal(0, 1, (60, 3))
    phi[:10] *= 1e-7
    direction = phi[10:20] / np.linalg.norm(phi[10:20], axis=1, keepdims=True)
    phi[10:20] = direction * (np.pi - 1e-4)
    return phi


def test_elementary_rotations_and_frames_match_scipy():
    rng = np.random.default_rng(1)
    angles = rng.uniform(-np.pi, np.pi, 40)
    for axis, name in enumerate("xyz"):
        assert np.allclose(geometry.rotation(axis, angles), Rotation.from_euler(name, angles[:, None]).as_matrix(), atol=1e-14)
    frames = np.column_stack([rng.normal(0, 100, (40, 3)), rng.uniform(-np.pi, np.pi, (40, 3))])
    frames[:, 4] = rng.uniform(-1.5, 1.5, 40)  # ry within (-pi/2, pi/2): a unique inverse
    T = geometry.frame_transform(frames)
    # Tx Ty Tz Rz(rz) Ry(ry) Rx(rx): SciPy's intrinsic "ZYX" with angles (rz, ry, rx)
    assert np.allclose(T[:, :3, :3], Rotation.from_euler("ZYX", frames[:, [5, 4, 3]]).as_matrix(), atol=1e-14)
    assert np.allclose(T[:, :3, 3], frames[:, :3]) and np.all(T[:, 3] == [0, 0, 0, 1])
    assert np.allclose(geometry.frame_params(T), frames, atol=1e-12)


def test_so3_exp_log_and_quaternions_match_scipy(rotations):
    R = geometry.so3_exp(rotations)
    assert np.allclose(R, Rotation.from_rotvec(rotations).as_matrix(), atol=1e-13)
    assert np.allclose(geometry.so3_exp(geometry.so3_log(R)), R, atol=1e-12)
    generic = np.linalg.norm(rotations, axis=1) < np.pi - 1e-3
    assert np.allclose(geometry.so3_log(R)[generic], Rotation.from_matrix(R[generic]).as_rotvec(), atol=1e-12)
    q = geometry.quaternion_from_matrix(R)  # (w, x, y, z), w >= 0
    xyzw = Rotation.from_matrix(R).as_quat()
    scipy_wxyz = np.column_stack([xyzw[:, 3], xyzw[:, :3]])
    assert np.all(q[:, 0] >= 0) and np.allclose(np.abs(np.sum(q * scipy_wxyz, axis=1)), 1.0, atol=1e-12)
    assert np.allclose(geometry.matrix_from_quaternion(3.0 * q), R, atol=1e-12)  # normalised first
    assert np.allclose(geometry.skew([1.0, 2.0, 3.0]) @ [4.0, 5.0, 6.0], np.cross([1.0, 2.0, 3.0], [4.0, 5.0, 6.0]))


@pytest.mark.parametrize("conventions, kinds", [(["dh"] * 6, ["revolute"] * 6), (["mdh", "dh", "mdh"], ["revolute", "prismatic", "revolute"])])
def test_chain_ops_lay_out_base_joints_and_tool(conventions, kinds):
    """Base (6 transforms), five per joint, tool (6); the joint variable on theta (revolute) or
    d (prismatic). (The chain's values are held against the Rust core through the oracle's FK.)"""
    ops, flange_end = geometry.chain_ops(conventions, kinds)
    n = len(conventions)
    assert len(ops) == 6 + 5 * n + 6 and flange_end == 6 + 5 * n
    variables = [o for o in ops if o.joint is not None]
    assert [o.joint for o in variables] == list(range(n))
    assert [o.rotation for o in variables] == [k == "revolute" for k in kinds] and all(o.axis == 2 for o in variables)


def test_kabsch_recovers_a_rigid_transform():
    rng = np.random.default_rng(1)
    T = geometry.frame_transform([10.0, -20.0, 30.0, 0.3, -0.2, 1.1])
    points = rng.normal(0, 500, (20, 3))
    targets = points @ T[:3, :3].T + T[:3, 3]
    assert np.allclose(geometry.kabsch(points, targets), T, atol=1e-9)
