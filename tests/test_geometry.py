"""The production geometry (``robocal.geometry``) against the oracle's own copy
(``robocal.reference``, kept self-contained): the two must not drift apart."""

from __future__ import annotations

import numpy as np
import pytest

from helpers import ref
from robocal import geometry


def test_geometry_equals_the_oracle():
    rng = np.random.default_rng(0)
    frames = np.concatenate([rng.normal(0, 100, (50, 3)), rng.uniform(-np.pi, np.pi, (50, 3))], axis=1)
    frames[0, 4] = np.pi / 2  # gimbal lock
    phi = rng.normal(0, 1, (50, 3))
    phi[:10] *= 1e-6  # the small-angle series
    phi[10:20] *= 3.0  # angles near pi
    T = geometry.frame_transform(frames)
    assert np.array_equal(T, ref.frame_transform(frames))
    assert np.array_equal(geometry.frame_params(T), ref.frame_params(T))
    R = geometry.so3_exp(phi)
    assert np.array_equal(R, ref.so3_exp(phi))
    assert np.array_equal(geometry.so3_log(R), ref.so3_log(R))
    assert np.array_equal(geometry.quaternion_from_matrix(R), ref.quaternion_from_matrix(R))
    q = rng.normal(size=(50, 4))
    assert np.array_equal(geometry.matrix_from_quaternion(q), ref.matrix_from_quaternion(q))
    for axis in range(3):
        assert np.array_equal(geometry.rotation(axis, frames[:, 3]), ref.rotation(axis, frames[:, 3]))


@pytest.mark.parametrize("conventions, kinds", [(["dh"] * 6, ["revolute"] * 6), (["mdh", "dh", "mdh"], ["revolute", "prismatic", "revolute"])])
def test_chain_ops_equal_the_oracle(conventions, kinds):
    ops, end = geometry.chain_ops(conventions, kinds)
    want, want_end = ref.chain_ops(conventions, kinds)
    assert end == want_end and [tuple(o) for o in ops] == [tuple(o) for o in want]


def test_kabsch_recovers_a_rigid_transform():
    rng = np.random.default_rng(1)
    T = geometry.frame_transform([10.0, -20.0, 30.0, 0.3, -0.2, 1.1])
    points = rng.normal(0, 500, (20, 3))
    targets = points @ T[:3, :3].T + T[:3, 3]
    assert np.allclose(geometry.kabsch(points, targets), T, atol=1e-9)
