"""The static gravity regressor (issue 51): a compliance whose masses are not the mass model's.

A joint's gravity torque is linear in the masses and first mass moments of the links it carries;
the regressor's base columns span the torque of *any* mass distribution and payload, so a
compliance fitted on them follows a deflection whatever the true masses. Checked against
:func:`robocal.physics.gravity_torques` with mass models drawn at random (not the built-in ones),
and on data of ``benches/mismatch.py``, whose point masses sit elsewhere than robocal's."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import robocal
from robocal.diagnosis import diagnose
from robocal.physics import gravity_base_columns, gravity_regressor, gravity_torques
from robocal.serial_robot import MassModel

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benches"))
import mismatch  # noqa: E402

ROBOTS = ("ur10", "hsr-jr680", "abb-irb120")


def drawn_model(seed: int) -> tuple[MassModel, float]:
    rng = np.random.default_rng(seed)
    masses = rng.uniform(0.1, 50.0, 6)
    centres = rng.uniform(-300.0, 300.0, (6, 3))
    return MassModel(tuple(masses), centres_of_mass=tuple(map(tuple, centres))), float(rng.uniform(0.0, 40.0))


@settings(max_examples=25, deadline=None)
@given(robot=st.sampled_from(ROBOTS), seed=st.integers(0, 2**32 - 1), joint=st.integers(1, 5))
def test_any_masses_and_payload_torque_lies_in_the_base_columns(robot, seed, joint):
    """Any link masses, centres of mass and payload: the joint's torque is a combination of the
    base columns, to rounding (a payload is a mass and a moment of the last link)."""
    r = robocal.robot(robot)
    model, payload = drawn_model(seed)
    q = np.random.default_rng(seed ^ 1).uniform(-np.pi, np.pi, (60, 6))
    tau = gravity_torques(r, q, payload=payload, model=model)[:, joint]
    Y = gravity_regressor(r, q, joint)[:, gravity_base_columns(r, joint)]
    c = np.linalg.lstsq(Y, tau, rcond=None)[0]
    assert np.max(np.abs(Y @ c - tau)) <= 1e-9 * max(1.0, float(np.max(np.abs(tau))))


@pytest.mark.parametrize("robot", ROBOTS)
def test_the_regressor_times_the_masses_and_moments_is_the_torque(robot):
    """Column by column: link k's mass, then its first moment in its DH frame (kg·m)."""
    r = robocal.robot(robot)
    model, _ = drawn_model(3)
    q = np.random.default_rng(4).uniform(-np.pi, np.pi, (40, 6))
    tau = gravity_torques(r, q, model=model)
    for joint in range(1, 6):
        pi = np.concatenate([[m, *(m * np.array(c) / 1000.0)] for m, c in list(zip(model.link_masses, model.centres_of_mass))[joint:]])
        assert gravity_regressor(r, q, joint) @ pi == pytest.approx(tau[:, joint], abs=1e-9 * np.max(np.abs(tau)))


def test_a_deflection_by_masses_elsewhere_is_one_compliance_and_nothing_else():
    """Point masses placed otherwise than the mass model, and a payload (the other simulator):
    the compliance of the mass model's torque leaves a few per cent of the deflection, which
    couplings and harmonics took; on the base parameters of static gravity it is one compliance
    of joint 2 (``masses=free``), with the mass model's share of it reported, and nothing else
    is named. The label rebuilds the cause for a calibration."""
    acq = mismatch.acquisition("abb-irb120", "pose", 300, seed=25214)
    keys = {
        "masses": [3.44, 2.64, 1.43, 0.53, 0.09],
        "places": [[0.74, -7.7, -46.6, 40.0], [0.21, 48.4, 20.3, 37.7], [0.42, 39.2, 40.2, 39.9], [0.65, 51.6, -36.0, 0.5], [0.68, 34.0, 54.3, -52.7]],
        "payload": 1.08,
        "joints": [2],
        "share": {"2": 1.0},
    }
    data = robocal.Dataset(
        q=acq.q, y=mismatch.readings(acq, [{"family": "gravity", "keys": keys, "size": 4.0}]), measurement="pose", robot="abb-irb120", t=acq.t
    )
    report = diagnose(data).to_dict()
    assert [e["label"] for e in report["effects"]] == ["joint_compliance joint 2 masses=free"]
    params = report["effects"][0]["params"]
    assert 0.5 < params["model_torque_share"]["value"] < 1.0
    # each stiffness with its uncertainty (from the coefficients' covariance), and the moments found with theirs
    compliance, stiffness = params["compliance"], params["stiffness"]
    assert 0.0 < compliance["std"] < 0.2 * compliance["value"]
    assert stiffness["std"] == pytest.approx(compliance["std"] / compliance["value"] * stiffness["value"], rel=1e-6)
    moments = [v for name, v in params.items() if name[:2] in ("mx", "my", "mz") or name[:1] == "m" and name[1:].isdigit()]
    assert moments and all(v["std"] is not None and v["std"] > 0 for v in moments)
    fit = robocal.calibrate(data, causes=["joint_compliance joint 2 masses=free"])
    assert fit.metrics["train"]["rmse"] < report["baseline"]["rmse_train"]


def test_a_free_mass_compliance_must_be_mostly_the_mass_models_torque():
    """The free masses refine the mass model's torque; a deflection that torque explains less than
    MIN_MODEL_TORQUE_SHARE of is another cause's shape (a harmonic, a joint map) and is refused."""
    from robocal.causes.candidates import MIN_MODEL_TORQUE_SHARE, free_mass_compliance
    from robocal.physics import standard_poses

    r = robocal.robot("ur10")
    poses, joint = standard_poses(r), 1
    Y = gravity_regressor(r, poses, joint)[:, gravity_base_columns(r, joint)]
    tau = gravity_torques(r, poses)[:, joint]
    model = np.linalg.lstsq(Y, 1e-5 * tau, rcond=None)[0]  # the model's torque at 1e-5 rad/(N·m)
    params, why = free_mass_compliance(r, joint, model)
    assert why is None and params["model_torque_share"]["value"] == pytest.approx(1.0)
    assert params["compliance"]["value"] == pytest.approx(1e-5 * 180 / np.pi * 1000, rel=1e-6)
    # the same plus a shape orthogonal to that torque, twice as large: a share of 0.2
    other = Y @ np.random.default_rng(0).normal(size=Y.shape[1])
    other -= (other @ tau) / (tau @ tau) * tau
    other *= 2.0 * np.linalg.norm(1e-5 * tau) / np.linalg.norm(other)
    mixed = np.linalg.lstsq(Y, 1e-5 * tau + other, rcond=None)[0]
    params, why = free_mass_compliance(r, joint, mixed)
    assert params["model_torque_share"]["value"] == pytest.approx(0.2, abs=0.01) and 0.2 < MIN_MODEL_TORQUE_SHARE
    assert why is not None and "explains 0.20 of the deflection" in why
