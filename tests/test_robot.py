"""The Python surface of robots: built-ins, files, forward kinematics, masks, DH -> MDH."""

from __future__ import annotations

import json
import math
import pickle

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import robocal
from robocal.catalog import BUILTIN

from helpers import cases


def dh_link(alpha, a, d, theta):
    """The paper's eq. (1), written out."""
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st], [0, sa, ca, d], [0, 0, 0, 1.0]])


@pytest.mark.parametrize("name", sorted(BUILTIN))
def test_builtin_fkine_is_the_product_of_eq1_matrices(name):
    r = robocal.robot(name)
    rng = np.random.default_rng(1)
    q = rng.uniform(-math.pi, math.pi, size=(5, 6))
    T = r.fkine(q)
    assert T.shape == (5, 4, 4) and T.flags.c_contiguous
    for qi, Ti in zip(q, T):
        expected = np.eye(4)
        for j, (alpha, a, d, theta, *_rest) in enumerate(BUILTIN[name]["dh"]):
            expected = expected @ dh_link(math.radians(alpha), a, d, math.radians(theta) + qi[j])
        np.testing.assert_allclose(Ti, expected, atol=1e-9)


def test_param_vector_names_and_units():
    r = robocal.robot("hsr-jr680")
    assert r.n_params == 5 * 6 + 17
    assert r.param_names[:5] == ["alpha1", "a1", "d1", "theta1", "beta1"]
    assert r.param_names[-5:] == ["anchor_x", "anchor_y", "anchor_z", "cable_offset", "cable_scale"]
    assert dict(zip(r.param_names, r.param_units))["d4"] == "mm"
    assert r.params[r.index("d4")] == pytest.approx(1030.2)
    assert r.params[r.index("theta2")] == pytest.approx(math.radians(-90))


def test_default_masks_follow_hayati_flags():
    r = robocal.robot("ur10")
    mask = r.default_mask("cable")
    chosen = {n for n, m in zip(r.param_names, mask) if m}
    assert {"beta2", "beta3"} <= chosen and not {"d2", "d3", "beta1"} & chosen
    assert {"anchor_x", "cable_offset", "tool_x"} <= chosen and "base_x" not in chosen
    assert "base_rz" in {n for n, m in zip(r.param_names, r.default_mask("position")) if m}
    with pytest.raises(robocal.exceptions.InvalidParameterError, match="measurement"):
        r.default_mask("laser")


def test_abb_nominal_model_matches_controller_positions(datasets):
    """D2 carries the controller's own x, y, z (rounded to 0.1 mm) beside the joint angles: the
    built-in IRB 120 model must reproduce them (a few rows of the public file are corrupt)."""
    data = np.genfromtxt(datasets / "robotcali-abb-irb120" / "abb_irb120_cable.csv", delimiter=",", names=True)
    q = np.radians(np.column_stack([data[f"q{i}"] for i in range(1, 7)]))
    xyz = np.column_stack([data["x"], data["y"], data["z"]])
    abb = robocal.robot("abb-irb120")
    err = np.linalg.norm(abb.fkine(q)[:, :3, 3] - xyz, axis=1)
    # What rounding alone explains: joints rounded to 0.1 deg (uniform +-0.05 deg), x/y/z to 0.1 mm.
    rng = np.random.default_rng(0)
    q_rounding = q + np.radians(rng.uniform(-0.05, 0.05, q.shape))
    xyz_rounding = rng.uniform(-0.05, 0.05, xyz.shape)
    expected = np.linalg.norm(abb.fkine(q_rounding)[:, :3, 3] + xyz_rounding - abb.fkine(q)[:, :3, 3], axis=1)
    assert np.median(err) < 1.25 * np.median(expected)
    assert np.mean(err < 2.0) > 0.97


def test_to_mdh_preserves_tool_kinematics():
    r = robocal.robot("hsr-jr680").with_params(tool_x=12.0, tool_y=-4.0, tool_z=150.0, tool_ry=0.3, beta2=0.01, beta6=-0.02)
    m = r.to_mdh()
    assert all(j.convention == "mdh" for j in m.joints)
    q = np.random.default_rng(3).uniform(-3, 3, size=(20, 6))
    np.testing.assert_allclose(m.fkine(q, tool=True), r.fkine(q, tool=True), atol=1e-9)


def test_robot_from_json_and_yaml(tmp_path):
    spec = {"name": "two-link", "joints": [{"alpha": 0, "a": 300, "d": 0, "theta": 0}, {"alpha": 0, "a": 200, "d": 0, "theta": 0, "limits": [-90, 90]}]}
    (tmp_path / "r.json").write_text(json.dumps(spec))
    yaml = pytest.importorskip("yaml")
    (tmp_path / "r.yaml").write_text(yaml.safe_dump(spec))
    for path in ("r.json", "r.yaml"):
        r = robocal.robot(str(tmp_path / path))
        assert r.name == "two-link" and r.n_joints == 2
        assert r.joints[1].limits == pytest.approx((-math.pi / 2, math.pi / 2))
        np.testing.assert_allclose(r.fkine([0.0, math.pi / 2])[0, :3, 3], [300.0, 200.0, 0.0], atol=1e-9)
    (tmp_path / "bad.json").write_text(json.dumps({"joints": [{"alpha": 0, "a": 1}]}))
    with pytest.raises(robocal.exceptions.InvalidParameterError, match="joint 1 lacks d, theta"):
        robocal.robot(str(tmp_path / "bad.json"))


def test_unknown_robot_names_the_choices():
    with pytest.raises(robocal.exceptions.InvalidParameterError, match="hsr-jr680"):
        robocal.robot("kuka-kr16")


def test_demo_runs_end_to_end(capsys, tmp_path):
    """The README's main job: simulate with a hidden backlash, calibrate with UKF-VSLM,
    diagnose, write the report folder."""
    from robocal.cli import main

    assert main(["demo", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    nominal, calibrated = (float(v) for v in out.split("held-out cable RMSE ")[1].split(" mm (calibrated)")[0].replace(" mm (nominal) ->", "").split())
    assert calibrated < 0.2 * nominal
    assert "found backlash joint 2" in out
    for name in ("data.csv", "truth.json", "result.json", "diagnosis.json", "cause_1.png"):
        assert (tmp_path / name).stat().st_size > 0


def test_cli_bad_use_is_one_line_and_exit_code_2(capsys):
    from robocal.cli import main

    assert main(["calibrate", "no-such-file.csv", "--robot", "hsr-jr680"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("robocal: error:") and "no-such-file.csv" in err[0]


@given(cases(), st.booleans())
def test_a_robot_survives_pickling_with_identical_kinematics(case, with_masses):
    """A Robot crosses a process boundary (``calibrate_many(..., robot=<Robot>)``, issue 52 #14):
    its compiled chain is rebuilt from the joints, so the copy computes exactly the same."""
    joints = [robocal.Joint(convention=c, kind=k, hayati=bool(i % 2)) for i, (c, k) in enumerate(zip(*case.chain))]
    masses = robocal.MassModel(tuple(range(1, case.n + 1)), 3.0) if with_masses else None
    r = robocal.Robot("random", joints, case.params, masses)
    copy = pickle.loads(pickle.dumps(r))
    assert copy.joints == r.joints and copy.mass_model == r.mass_model and copy.param_names == r.param_names
    assert np.array_equal(copy.params, r.params)
    assert np.array_equal(copy.fkine(case.q, tool=True), r.fkine(case.q, tool=True))
    assert np.array_equal(copy.jacobian("position", case.q), r.jacobian("position", case.q))


def test_a_calibration_result_survives_pickling():
    data, _ = robocal.simulate("ur10", "position", samples=120, seed=2)
    result = robocal.calibrate(data, robot=robocal.robot("ur10"))
    copy = pickle.loads(pickle.dumps(result))
    assert json.dumps(copy.to_dict(), sort_keys=True) == json.dumps(result.to_dict(), sort_keys=True)
    assert np.array_equal(copy.robot.params, result.robot.params)
