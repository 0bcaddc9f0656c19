"""Re-mastering from a dozen points (issue 54): ``robocal calibrate NEW --prior RESULT`` names the joint
whose zero moved, by how much, and no other; zeros the new set-up reproduces are said to be so;
``plan --criterion Ds`` proposes the points. The zero is moved in the joint readings of a simulated
new session (the simulator knows no re-mastering), not in the model robocal fits."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

import robocal
from robocal.cli import main
from robocal.data import write_canonical
from robocal.exceptions import InvalidParameterError
from robocal.remastering import remaster
from robocal.report import report
from robocal.robot import RESIDUAL_WIDTH
from robocal.simulation import simulate

CHANGE = 0.05  # deg


@pytest.fixture(scope="module", params=[("ur10", "position"), ("hsr-jr680", "cable")])
def case(request, tmp_path_factory):
    """A result calibrated from a file (its training data readable: its own error is counted) and
    12 poses planned for a re-mastering."""
    robot, measurement = request.param
    folder = tmp_path_factory.mktemp(robot)
    data, _ = simulate(robot, measurement, samples=400, seed=2)
    write_canonical(data, folder / "train.csv")
    result = robocal.calibrate(str(folder / "train.csv"), robot=robot).to_dict()
    poses = robocal.plan(result=result, poses=12, criterion="Ds").q
    return robot, measurement, result, poses, folder


def _session(case, joint=None, change=CHANGE, session=1):
    robot, measurement, _, poses, _ = case
    data, _ = simulate(robot, measurement, seed=2, session=session, poses=poses)
    if joint is None:
        return data
    q = data.q.copy()
    q[:, joint - 1] -= np.radians(change)  # the reading that much below the angle: the model's zero moved by +change
    return replace(data, q=q)


def _moved(report) -> dict:
    return {j["joint"]: j for j in report["joints"] if j["status"] == "moved"}


@pytest.mark.parametrize("joint", [2, 3, 5])
def test_a_moved_zero_is_found_within_0005_deg_and_no_other_joint_is_named(case, joint):
    report = remaster(case[2], _session(case, joint)).report
    moved = _moved(report)
    assert list(moved) == [joint], report["joints"]
    found = moved[joint]
    # Within 0.005 deg where the points determine the zero that well; a cable sensor's 12 readings
    # leave the HSR's wrist zeros a std of about 0.008 deg (benches/bench_remaster.py), and there the
    # stated std is the claim to hold.
    assert abs(found["change"] - CHANGE) <= max(0.005, 3 * found["std"]), found
    assert abs(found["change"] - CHANGE) <= 4 * found["std"]  # the std it states is honest
    assert report["result_error_counted"]


def test_a_session_without_change_names_no_joint(case):
    """Without the result's own error in the readings' covariance, planned poses named a joint in 3 of
    these 8 clean UR10 sessions and in 6 of the HSR's: the calibration's error, the same on every
    pose beyond its path, passed for a zero's change."""
    named = [list(_moved(remaster(case[2], _session(case, session=session)).report)) for session in range(1, 9)]
    # At most one: the test's family-wise rate is 5 % by design (none of these 8, nor of 20, at this commit).
    assert sum(bool(n) for n in named) <= 1, named


def test_joint_1_cannot_be_told_from_the_setup(case):
    """Joint 1's zero turns the robot about its base axis: a tracker's frame or a cable's anchor does
    the same. Moved, it is absorbed by the set-up — said so, not named as moved, the fit unharmed:
    the same statistics and figures as the same session without the change."""
    robot, measurement = case[:2]
    report = remaster(case[2], _session(case, 1, change=0.5)).report
    unchanged = remaster(case[2], _session(case)).report
    status = {j["joint"]: j["status"] for j in report["joints"]}
    assert status[1] == "indistinguishable" and report["joints"][0]["redundant_with"]
    assert status == {j["joint"]: j["status"] for j in unchanged["joints"]}
    for joint, same in zip(report["joints"], unchanged["joints"]):
        assert joint["statistic"] == pytest.approx(same["statistic"], abs=1e-6)
    assert report["rmse"]["setup_alone"] == pytest.approx(unchanged["rmse"]["setup_alone"], abs=1e-6)
    # On a tracker the tool point does what joint 6's zero does; a cable's hook on the tool is the robot's, held.
    assert status[6] == ("indistinguishable" if measurement == "position" else "held")


def test_the_rmse_with_the_set_up_alone_is_verify_s_on_the_same_points(case):
    """The figure is of the set-up's least-squares fit: the χ² fit weighs the result's own error and
    left 20 points of an HSR session at 0.087 mm where verify stated 0.024 mm."""
    data = _session(case, session=4)
    report = remaster(case[2], data).report
    assert report["rmse"]["setup_alone"] == pytest.approx(robocal.verify(case[2], data)["metrics"]["rmse"], rel=1e-3)


def test_the_document_carries_the_new_zero_for_verify(case):
    _, _, result, _, folder = case
    data = _session(case, 3)
    found = remaster(result, data)
    old = {p["name"]: p["value"] for p in result["parameters"]}
    new = {p["name"]: p["value"] for p in found.document["parameters"]}
    assert np.degrees(new["theta3"] - old["theta3"]) == pytest.approx(found.report["joints"][2]["change"])
    assert all(new[n] == old[n] for n in old if n != "theta3" and n in result["free"] and not n.startswith(("base_", "tool_", "anchor_", "cable_")))
    checked = robocal.verify(found.document, data)
    assert checked["metrics"]["rmse"] < robocal.verify(result, data)["metrics"]["rmse"]
    # The points fitted the zeros and the set-up: verify says its figure on them is no held-out one.
    assert checked["held_out"] is False and "the re-mastering's points" in checked["notes"][0]
    other = _session(case, 3, session=2)
    assert robocal.verify(found.document, other)["held_out"] is True


def test_plan_ds_separates_the_zeros_better_than_random_poses(case):
    report = robocal.plan(result=case[2], poses=12, criterion="Ds").to_dict()
    zeros = {z["joint"]: z for z in report["zeros"]}
    assert zeros[1]["after"] is None and zeros[1]["absorbed_by"]
    apart = [z for z in zeros.values() if z["after"] is not None]
    assert apart and sum(z["after"] for z in apart) < sum(z["random"] for z in apart)
    assert robocal.plan(result=case[2], poses=12, criterion="D").to_dict()["zeros"] is None


def test_a_result_without_readable_training_data_says_its_error_is_not_counted(case):
    _, _, result, _, _ = case
    in_memory = {**result, "dataset": {**result["dataset"], "source": None}}
    report = remaster(in_memory, _session(case)).report
    assert not report["result_error_counted"]
    assert any("own error is not counted" in n for n in report["notes"])


def test_a_result_calibrated_from_a_relative_path_finds_its_training_data_from_another_folder(case, tmp_path, monkeypatch):
    robot, _, _, _, folder = case
    monkeypatch.chdir(folder)
    result = robocal.calibrate("train.csv", robot=robot).to_dict()
    assert result["dataset"]["source"] == str(folder / "train.csv")
    monkeypatch.chdir(tmp_path)  # another folder: a relative record would no longer find the file
    assert remaster(result, _session(case)).report["result_error_counted"]


def test_bad_arguments_are_refused(case):
    with pytest.raises(InvalidParameterError, match="alpha"):
        remaster(case[2], _session(case), alpha=1.5)
    few = _session(case)
    with pytest.raises(robocal.exceptions.RobocalError, match="too few|degrees of freedom"):
        remaster(case[2], few.subset(np.arange(2)))


def test_command_line(case, tmp_path, capsys):
    robot, _, result, _, _ = case
    (tmp_path / "result.json").write_text(json.dumps(result))
    write_canonical(_session(case, 3), tmp_path / "new.csv")
    before = (tmp_path / "result.json").read_bytes()
    assert main(["calibrate", str(tmp_path / "new.csv"), "--prior", str(tmp_path / "result.json"), "--out", str(tmp_path / "re.json")]) == 0
    out = capsys.readouterr().out
    assert "joint 3: zero moved +0.0" in out and "joint 1: cannot be told apart from the set-up" in out
    assert (tmp_path / "result.json").read_bytes() == before
    doc = json.loads((tmp_path / "re.json").read_text())
    assert [j["joint"] for j in doc["remaster"]["joints"] if j["status"] == "moved"] == [3]
    assert main(["verify", str(tmp_path / "re.json"), str(tmp_path / "new.csv")]) == 0
    capsys.readouterr()
    assert main(["plan", "--from", str(tmp_path / "result.json"), "--poses", "12", "--criterion", "Ds", "--out", str(tmp_path / "p.csv")]) == 0
    out = capsys.readouterr().out
    assert "a re-mastering on these poses: each zero's change ±" in out and "joint 1: no pose tells its zero from the set-up" in out
    # The calibration's own command line plus --prior is taken; another robot is refused.
    assert main(["calibrate", str(tmp_path / "new.csv"), "--prior", str(tmp_path / "result.json"), "--robot", robot, "--quiet"]) == 0
    capsys.readouterr()
    other = "abb-irb120" if robot != "abb-irb120" else "ur10"
    for extra in (["--method", "vslm"], ["--test-fraction", "0.3"], ["--kinematic-prior", "1,0.1"], ["--robot", other]):
        assert main(["calibrate", str(tmp_path / "new.csv"), "--prior", str(tmp_path / "result.json"), *extra]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("robocal: error: --"), err
    # The test level: taken by a re-mastering and recorded; out of (0, 1), or without --prior, refused.
    assert main(["calibrate", str(tmp_path / "new.csv"), "--prior", str(tmp_path / "result.json"), "--alpha", "0.001", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["remaster"]["alpha"] == 0.001
    for extra in (["--prior", str(tmp_path / "result.json"), "--alpha", "1.5"], ["--robot", robot, "--alpha", "0.01"]):
        assert main(["calibrate", str(tmp_path / "new.csv"), *extra]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "alpha" in err[0], err
    # The result given as the output too: refused before any work, the result untouched.
    assert main(["calibrate", str(tmp_path / "new.csv"), "--prior", str(tmp_path / "result.json"), "--out", str(tmp_path / "result.json")]) == 2
    assert (tmp_path / "result.json").read_bytes() == before


def test_ds_optimal_beats_the_d_optimal_and_random_designs_on_its_criterion():
    """The zeros' log det with the set-up eliminated, computed afresh on the chosen poses (the
    greedy's and the exchange's rank-k updates are not trusted): the Ds design's is the largest."""
    from robocal.planning import d_optimal, ds_optimal

    rng = np.random.default_rng(4)
    A = rng.normal(size=(300, 3, 7))
    A[:, :, 5:] += 3.0 * A[:, :, :1]  # the zeros' columns lean on a set-up column: D spends poses on what Ds eliminates
    of, M0 = [5, 6], 1e-6 * np.eye(7)

    def criterion(idx):
        M = M0 + np.einsum("nki,nkj->ij", A[idx], A[idx])
        s = [0, 1, 2, 3, 4]
        schur = M[np.ix_(of, of)] - M[np.ix_(of, s)] @ np.linalg.solve(M[np.ix_(s, s)], M[np.ix_(s, of)])
        return np.linalg.slogdet(schur)[1]

    chosen = ds_optimal(A, M0, 6, of)
    assert len(set(chosen.tolist())) == 6
    best = criterion(chosen)
    assert best >= criterion(d_optimal(A, M0, 6)) - 1e-9
    assert all(best >= criterion(rng.choice(300, 6, replace=False)) for _ in range(200))


def test_the_remaster_key_is_validated_when_read_back(case):
    found = remaster(case[2], _session(case, 3))
    robot, _ = robocal.results.load_result(found.document)  # the key as written passes its schema
    assert robot.n_params == len(found.document["parameters"])
    broken = {**found.document, "remaster": {**found.report, "joints": [{**found.report["joints"][0], "status": "gone"}]}}
    with pytest.raises(InvalidParameterError, match=r"key 'remaster', joint 1, key 'status'"):
        robocal.results.load_result(broken)


def test_the_report_of_a_remastered_result_shows_the_remastering_not_a_corrupt_file(case, tmp_path):
    """The re-mastered document's set-up is the new session's: on the data calibrated on its values
    cannot reproduce the calibration's figures, and the report says why instead of calling the file
    edited; its figures are computed on the re-mastering's points."""
    result = case[2]
    write_canonical(_session(case, 3), tmp_path / "new.csv")
    found = remaster(result, str(tmp_path / "new.csv"))
    page = report(found.document, tmp_path / "page").read_text()
    assert "edited or is corrupt" not in page
    assert "<h2>Re-mastering</h2>" in page and "it was re-mastered since" in page
    assert (
        "new.csv, 12 samples; the re-mastering&#x27;s points (sha256 matches)" in page
        or "new.csv, 12 samples; the re-mastering's points (sha256 matches)" in page
    )
    moved = [j for j in found.report["joints"] if j["status"] == "moved"]
    assert [j["joint"] for j in moved] == [3] and f"{moved[0]['change']:+.4g} ± " in page


def test_a_re_mastering_that_raises_the_error_says_its_zeros_are_not_to_be_trusted(tmp_path, capsys):
    """Points of another robot (seed 3's, from a pose file), read as positions: the premise (only
    zeros moved) is rejected, and where the re-mastered zeros (one linearised step from the result)
    fit the points worse than the set-up alone, the note says they are not to be trusted."""
    data, _ = simulate("ur10", "position", samples=300, seed=2)
    write_canonical(data, tmp_path / "p.csv")
    other, _ = simulate("ur10", "pose", samples=300, seed=3, session=3)
    write_canonical(other, tmp_path / "ps.csv")
    assert main(["calibrate", str(tmp_path / "p.csv"), "--robot", "ur10", "--out", str(tmp_path / "r.json"), "--quiet"]) == 0
    assert main(["calibrate", str(tmp_path / "ps.csv"), "--prior", str(tmp_path / "r.json"), "--out", str(tmp_path / "re.json"), "--quiet"]) == 0
    capsys.readouterr()
    report = json.loads((tmp_path / "re.json").read_text())["remaster"]
    assert report["rmse"]["remastered"] > report["rmse"]["setup_alone"], report["rmse"]
    assert any("not to be trusted" in note for note in report["notes"]), report["notes"]


def test_the_plan_states_the_std_the_remastering_will(case):
    """The plan counts the result's own error on its poses as the re-mastering weighs it (σ²I + J C Jᵀ):
    without it, the HSR's plan promised its wrist zeros 0.003° where the re-mastering on those
    poses stated 0.009°, and chose poses where the calibration's error passed for a zero's change."""
    robot, measurement, result, _, _ = case
    noise = result["metrics"]["test"]["rmse"] / np.sqrt(min(RESIDUAL_WIDTH[measurement], 3))  # as the re-mastering takes it
    planned = robocal.plan(result=result, poses=12, criterion="Ds", noise=noise)
    data, _ = simulate(robot, measurement, seed=2, session=1, poses=planned.q)
    for joint in (2, 3, 4, 5):
        q = data.q.copy()
        q[:, joint - 1] -= np.radians(CHANGE)
        stated = remaster(result, replace(data, q=q)).report["joints"][joint - 1]["std"]
        assert 0.6 < planned.report["zeros"][joint - 1]["after"] / stated < 1.5, (joint, planned.report["zeros"][joint - 1], stated)


def _scara():
    """A SCARA with a prismatic third joint: every axis vertical, so the set-up's base and tool heights are nearly
    one column (the training data's set-up information conditioned about 1e12)."""
    from robocal.serial_robot import Robot

    rows = [(0, 400, 300, 0, (-150, 150)), (180, 300, 0, 0, (-140, 140)), (0, 0, 0, 0, (0, 200), False, "prismatic"), (0, 0, 50, 0)]
    return Robot.from_dh("scara", rows).with_params(tool_x=20.0, tool_y=10.0, tool_z=30.0)


def test_a_plan_for_a_prismatic_robot_whose_set_up_is_nearly_redundant(tmp_path, capsys):
    """The result's information with the set-up eliminated had eigenvalues of -2e-6 of its largest (rounding), and
    the plan's Cholesky factor of it failed (a traceback); the summary printed a prismatic joint's mm as deg."""
    robot = _scara()
    path, _ = simulate(robot, "position", samples=400, seed=3)
    q = path.q.copy()
    q[:, 2] = 55.0 + np.abs(np.cumsum(np.random.default_rng(3).normal(0.0, 0.087, len(q))))  # the vertical axis barely moves
    data, _ = simulate(robot, "position", seed=3, poses=q)
    write_canonical(data, tmp_path / "train.csv")
    (tmp_path / "result.json").write_text(json.dumps(robocal.calibrate(str(tmp_path / "train.csv"), robot=robot).to_dict()))
    assert main(["plan", "--from", str(tmp_path / "result.json"), "--poses", "12", "--criterion", "Ds", "--out", str(tmp_path / "p.csv")]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if "a re-mastering on these poses" in x)
    zeros = {z["joint"]: z for z in robocal.plan(result=str(tmp_path / "result.json"), poses=12, criterion="Ds").report["zeros"]}
    assert zeros[3]["unit"] == "mm" and zeros[2]["unit"] == "deg"
    assert f"joint 3 {zeros[3]['after']:.2g} mm" in line and f"joint 2 {zeros[2]['after']:.2g} deg" in line, line


def test_a_re_mastered_result_re_masters_and_plans_as_the_result_it_came_from(case):
    """A re-mastered (or monitored) result holds the new session's set-up: its training data were read again at that
    set-up, their residuals another session's (the UR10's tracker 116 mm away), and the result's covariance of the
    robot with them: the stated stds were 1000x too large (0.8-2.7 deg instead of 0.0006-0.0023), and a later
    re-mastering named no change, nor did the plan promise one."""
    robot, measurement, result, poses, _ = case
    first = remaster(result, _session(case, 3)).document
    later = replace(_session(case, session=2), q=_session(case, 3, session=2).q.copy())
    later.q[:, 1] -= np.radians(CHANGE)  # joint 2 moved too, since the first re-mastering
    again = remaster(first, later).report
    assert list(_moved(again)) == [2], again["joints"]
    assert abs(_moved(again)[2]["change"] - CHANGE) < 5 * _moved(again)[2]["std"], _moved(again)[2]
    direct = remaster(result, _session(case, 2, session=2)).report
    for a, b in zip(again["joints"], direct["joints"]):
        if b["detectable_std"] is not None:
            assert 0.7 < a["detectable_std"] / b["detectable_std"] < 1.4, (a, b)
    planned = [z["after"] for z in robocal.plan(result=first, poses=12, criterion="Ds").report["zeros"] if z["after"] is not None]
    original = [z["after"] for z in robocal.plan(result=result, poses=12, criterion="Ds").report["zeros"] if z["after"] is not None]
    assert np.allclose(planned, original, rtol=0.5), (planned, original)  # the new set-up (a cable's anchor) changes the candidates


def test_a_plan_of_too_few_poses_for_a_re_mastering_is_refused(case):
    """``plan --criterion Ds --poses 1`` stated each zero's std (1-6 deg: the ridge's) for poses the re-mastering then
    refuses (the new set-up needs more readings than its parameters)."""
    robot, measurement, result, _, _ = case
    least = {"position": 4, "cable": 5}[measurement]
    with pytest.raises(InvalidParameterError, match=f"plan at least {least} poses"):
        robocal.plan(result=result, poses=least - 1, criterion="Ds")
    assert all(z["after"] is None or z["after"] > 0 for z in robocal.plan(result=result, poses=least, criterion="Ds").report["zeros"])
