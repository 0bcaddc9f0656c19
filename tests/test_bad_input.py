"""Bad input reaches the user as a robocal exception naming the argument, expected vs. got —
never a panic, a TypeError from the binding layer or a NaN result."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import robocal
from robocal import kernels
from robocal import _robocal
from robocal.exceptions import (
    InvalidParameterError,
    NonFiniteError,
    NotPositiveDefiniteError,
    RobocalError,
    ShapeError,
    SingularError,
)

R = robocal.robot("hsr-jr680")
Q = np.random.default_rng(0).uniform(-1, 1, size=(20, 6))


def test_wrong_joint_count_names_q_and_shapes():
    with pytest.raises(ShapeError, match=r"`q` must have shape \(m, 6\); got \(3, 7\)"):
        R.fkine(np.zeros((3, 7)))
    with pytest.raises(ShapeError, match=r"`q` must have shape \(m, 6\); got \(3, 7\)"):
        R.chain.fk(R.params, np.zeros((3, 7)))


def test_nan_and_inf_are_reported_with_their_position():
    q = Q.copy()
    q[4, 2] = np.nan
    with pytest.raises(NonFiniteError, match=r"`q` must be finite; got NaN at index 26"):
        R.fkine(q)
    params = R.params.copy()
    params[3] = np.inf
    with pytest.raises(NonFiniteError, match="`params`"):
        R.fkine(Q, params=params)
    with pytest.raises(NonFiniteError, match="`y`"):
        R.residuals("cable", Q, np.full(20, np.inf))


def test_empty_batch_is_a_shape_error():
    with pytest.raises(ShapeError, match="m >= 1"):
        R.predict("cable", np.zeros((0, 6)))


def test_dtypes_and_layouts():
    # The Python layer converts integers and non-contiguous views; results are identical.
    q_int = np.arange(12).reshape(2, 6)
    np.testing.assert_array_equal(R.fkine(q_int), R.fkine(q_int.astype(float)))
    wide = np.zeros((20, 12))
    wide[:, ::2] = Q
    view = wide[:, ::2]
    assert not view.flags.c_contiguous
    np.testing.assert_array_equal(R.fkine(view), R.fkine(Q))
    # The compiled module itself takes float64 only, and says so.
    with pytest.raises(InvalidParameterError, match="`q`: must be a float64 NumPy array; got an array of dtype int64"):
        R.chain.fk(R.params, q_int)
    with pytest.raises(InvalidParameterError, match="`q` must be numeric"):
        R.fkine([["a"] * 6])


def test_unknown_names():
    with pytest.raises(InvalidParameterError, match="'cable', 'position' or 'pose'"):
        R.chain.predict("laser", R.params, Q)
    with pytest.raises(InvalidParameterError, match="'dh' or 'mdh'"):
        _robocal.Chain(["dh", "craig"], ["revolute", "revolute"])
    with pytest.raises(ShapeError, match="kinds"):
        _robocal.Chain(["dh", "dh"], ["revolute"])
    with pytest.raises(InvalidParameterError, match="unknown parameter 'd7'"):
        R.index("d7")


def test_pose_needs_unit_quaternions_and_observations():
    y = R.predict("pose", Q)
    y[3, 3:] = 0.0
    with pytest.raises(InvalidParameterError, match="row 3: quaternion"):
        R.residuals("pose", Q, y)
    with pytest.raises(InvalidParameterError, match="pose residuals need the measured values"):
        R.jacobian("pose", Q)


def test_jacobian_column_indices_are_checked():
    with pytest.raises(InvalidParameterError, match="out of range"):
        R.jacobian("cable", Q, cols=[0, 99])
    with pytest.raises(InvalidParameterError, match=">= 0"):
        R.jacobian("cable", Q, cols=[-1])


def test_solver_and_sigma_point_errors():
    with pytest.raises(InvalidParameterError, match="`lam`"):
        kernels.solve_damped(np.eye(3), np.ones(3), -1.0)
    with pytest.raises(ShapeError, match=r"`r` must have shape \(3,\)"):
        kernels.solve_damped(np.eye(3), np.ones(4), 0.1)
    with pytest.raises(NotPositiveDefiniteError):
        kernels.merwe_sigma_points(np.zeros(2), [[1.0, 2.0], [2.0, 1.0]])
    with pytest.raises(InvalidParameterError, match="symmetric"):
        kernels.merwe_sigma_points(np.zeros(2), [[1.0, 0.5], [0.0, 1.0]])
    with pytest.raises(InvalidParameterError, match="alpha"):
        kernels.merwe_sigma_points(np.zeros(2), np.eye(2), alpha=0.0)


def test_identifiability_takes_one_flag_per_column():
    J = np.random.default_rng(0).normal(size=(20, 4))
    for first in ([True, False], [[True, False, False, True]], [1, 0, 0, 1]):  # too few, 2-D, not booleans
        with pytest.raises(InvalidParameterError, match="`first`"):
            kernels.identifiability(J, first=first)
    assert kernels.identifiability(J, first=[True, False, False, True])["rank"] == 4


def test_exceptions_derive_from_the_stdlib_types():
    assert issubclass(ShapeError, ValueError) and issubclass(SingularError, np.linalg.LinAlgError)
    with pytest.raises(ValueError):
        R.fkine(np.zeros((1, 5)))


def test_identical_configurations_report_rank_not_garbage():
    """Degenerate data: every sample at one configuration. The rank says so; nothing is NaN."""
    q = np.tile(Q[:1], (30, 1))
    cols = np.flatnonzero(R.default_mask("cable"))
    J = R.jacobian("cable", q, cols=cols)
    ident = kernels.identifiability(J)
    assert ident["rank"] == 1
    assert np.all(np.isfinite(ident["singular_values"])) and np.isfinite(ident["condition_number"])
    step, method = kernels.solve_damped(J, np.ones(30), 0.0)
    assert method == "svd" and np.all(np.isfinite(step))
    with pytest.raises(SingularError, match="do not determine the cable anchor"):
        kernels.cable_initial_guess(R.fkine(q)[:, :3, 3], np.full(30, 500.0))


@given(arrays(np.float64, st.tuples(st.integers(0, 4), st.integers(0, 8)), elements=st.floats(allow_nan=True, allow_infinity=True)))
def test_any_q_gives_poses_or_a_robocal_error(q):
    """Fuzz: arbitrary shapes and values never crash and never return non-finite poses."""
    try:
        T = R.fkine(q)
    except RobocalError:
        return
    assert T.shape == (q.shape[0], 4, 4) and np.all(np.isfinite(T))
