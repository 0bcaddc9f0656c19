"""A fixed subset of the discovery benchmark (``benches/discovery.py``): each hidden effect is
named — with its sign and size where it has them — **and nothing else is**. The effects are the
classes diagnose used to misname: a sensor that wanders in time, lost motion of the unexpected
sign, a compliance whose true masses are not the mass model's, and pairs of effects."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from robocal.cli.diagnose import summary
from robocal.diagnosis import diagnose
from robocal.causes.structure import Structure, to_readings
from robocal.simulation import simulate

from helpers import with_sensor_error


def named(robot: str, measurement: str, effects: list[str], seed: int = 3) -> dict:
    data, _ = simulate(robot, measurement, samples=300, seed=seed, effects=effects)
    return diagnose(data).to_dict()


def kinds(report: dict) -> list[tuple]:
    return sorted((e["kind"], e["joint"]) for e in report["effects"])


@pytest.mark.parametrize(
    "robot, measurement, rms, length",
    [("ur10", "position", 0.2, 10), ("hsr-jr680", "cable", 0.2, 8), ("abb-irb120", "pose", 0.2, 15), ("abb-irb120", "cable", 0.1, 5)],
)
def test_a_wandering_sensor_is_named_as_wander_and_nothing_else(robot, measurement, rms, length):
    report = named(robot, measurement, [f"wander:rms={rms},length={length}"])
    assert kinds(report) == [("wander", None)]
    found = report["effects"][0]["params"]["rms"]["value"]
    assert 0.7 * rms < found < 1.3 * rms  # the fitted path's RMS, mm, within 30 % (it takes some of the noise)
    # most of the error above the floor explained (held out, a wander corrects a sample only
    # between fitted ones: the short wander on cable keeps 0.51 of the baseline's RMS)
    assert report["final"]["explained"] > 0.7


def test_lost_motion_of_the_unexpected_sign_is_named_with_its_sign():
    report = named("ur10", "position", ["backlash:joint=2,width=-0.03"])
    assert kinds(report) == [("backlash", 2)]
    params = report["effects"][0]["params"]
    assert params["width"]["value"] == pytest.approx(-0.03, abs=0.003)
    assert params["direction"]["value"] == -1.0  # the link leads its reading


def test_a_compliance_on_masses_off_the_mass_model_breeds_no_other_causes():
    report = named("ur10", "position", ["joint_compliance:joint=2,mass_error=0.3"])
    assert kinds(report) == [("joint_compliance", 2)]


@pytest.mark.parametrize("seed", [3, 7])
@pytest.mark.parametrize(
    "robot, measurement, spec, sample",
    [("hsr-jr680", "position", "step:sample=30,axis=z,size=0.3", 30), ("abb-irb120", "cable", "step:sample=275,size=0.3", 275)],
)
def test_a_step_in_the_first_or_last_stretch_is_named_where_it_is_and_nothing_else(robot, measurement, spec, sample, seed):
    """A step in the first or last block of the blocked folds: that block's fold cannot estimate
    it (its training samples all lie on one side), so only the other folds judge it — and the
    samples right after it are no gross outliers."""
    report = named(robot, measurement, [spec], seed=seed)
    assert kinds(report) == [("step", None)]
    assert abs(report["effects"][0]["params"]["sample"]["value"] - sample) <= 5


def test_a_drift_that_bends_is_one_drift_and_no_steps():
    """A drift ∝ t^0.46 (fast at first): steps are offered at its first dozen samples and at a
    bend, and refused — a curve of the drift gains as much (no jump shown), or they are not
    significant once a step is the sensor frame's move and turn. It is named as the one curved
    drift it is (discovery benchmark, seed 25, file 57)."""
    report = named("abb-irb120", "pose", ["drift:exponent=0.461,axis=x,rate=1.907"], seed=25232)
    assert kinds(report) == [("drift", None)]
    refused = [r for r in report["rejected"] if r["kind"] == "step"]
    assert refused and all("no jump shown" in r["reason"] or "not significant" in r["reason"] for r in refused)


@pytest.mark.parametrize(
    "robot, measurement, spec, seed",
    [
        ("hsr-jr680", "position", "drift:exponent=1,axis=z,rate=0.430508", 101062),
        ("hsr-jr680", "pose", "wander:length=9.3,axis=x,rms=0.0187147", 101095),
    ],
)
def test_a_step_must_beat_a_ramp_from_its_sample(robot, measurement, spec, seed):
    """A linear drift and a wander, each below twice its detection limit (discovery benchmark,
    seed 101, files 312 and 142): each left a significant level change that was named a step,
    although a ramp from the same sample predicted the held-out samples as well (within 0.5
    standard errors). A jump is shown only when the step beats the ramp, sample by sample."""
    report = named(robot, measurement, [spec], seed=seed)
    assert ("step", None) not in kinds(report)
    refused = [r for r in report["rejected"] if r["kind"] == "step" and "no jump shown" in r["reason"] and "standard errors" in r["reason"]]
    assert refused


def test_a_step_must_beat_the_arcs_of_a_wandering_reading_the_residual_test_did_not_measure():
    """A cable zero that wanders slowly (correlation length 19 samples, 1.6 times its detection
    limit) without a correlation the residual test measures: no wander is offered, and the
    change-point search cut one of its arcs into a step that beat its ramps (discovery
    benchmark, seed 30, file 23). A smooth wander of the acquisition order predicts the held-out
    samples as well: no jump shown, and nothing named."""
    report = named("abb-irb120", "cable", ["wander:length=19.2,rms=0.048378"], seed=30137)
    assert kinds(report) == []
    steps = [r for r in report["rejected"] if r["kind"] == "step" and "wandering reading" in r["reason"]]
    assert steps and "no jump shown" in steps[0]["reason"]


def test_a_joint_error_the_data_cannot_tell_from_another_shape_names_both():
    """A scale error of joint 6 at its limit is fitted as well by a first harmonic over the joint's
    range (discovery benchmark, seed 32, file 29: named a harmonic). The named shape does not beat
    the scale by 1.96 standard errors held out, so the report says so: the claim is "one of
    these". A third harmonic well above the limit beats every other shape: no alternative."""
    report = named("abb-irb120", "position", ["joint_scale:joint=6,scale=0.009"], seed=32186)
    (cause,) = report["effects"]
    assert cause["joint"] == 6
    assert "joint_scale joint 6" in [cause["label"]] + cause["significance"]["undetermined_between"]
    assert "the data cannot tell it from joint_" in summary(report)
    clear = named("ur10", "position", ["joint_periodic:joint=3,harmonic=3,amplitude=0.05"], seed=3)
    assert [(e["label"], e["significance"]["undetermined_between"]) for e in clear["effects"]] == [("joint_periodic joint 3 harmonic=3", [])]


def test_a_drift_is_judged_before_a_wander_that_gains_not_twice_as_much():
    """A drift that bends (∝ t^0.64) and a 0.1 mm step of the cable zero, each about twice its
    detection limit (discovery benchmark, seed 27, file 48): the residual test does not say the
    residuals wander, and a wander — gaining most in the screening — was named alone. The drift
    gains more than half of what the wander does: tried first, it is named, and the step with it."""
    report = named("hsr-jr680", "cable", ["drift:exponent=0.636,rate=1.65136", "step:sample=115,size=0.0958032"], seed=27048)
    assert kinds(report) == [("drift", None), ("step", None)]
    (step,) = [e for e in report["effects"] if e["kind"] == "step"]
    assert abs(step["params"]["sample"]["value"] - 115) <= 2


@pytest.mark.parametrize(
    "robot, measurement, specs, seed, expected",
    [
        ("ur10", "pose", ["backlash:joint=5,width=-0.00606357", "wander:length=7.8,axis=z,rms=0.0109979"], 101363, {("backlash", 5), ("wander", None)}),
        ("hsr-jr680", "cable", ["backlash:joint=1,width=-0.0182408", "joint_scale:joint=3,scale=0.00033882"], 101036, {("backlash", 1), ("joint_scale", 3)}),
        ("hsr-jr680", "position", ["step:sample=108,axis=z,size=0.0622541", "wander:length=5.2,rms=0.0144802"], 102072, {("step", None), ("wander", None)}),
    ],
)
def test_a_cause_whose_held_out_gain_is_not_significant_is_not_named(robot, measurement, specs, seed, expected):
    """Beside a true cause, a coupling or a harmonic that is significant in the fit gains held
    out 1-2 standard errors of the per-sample errors (discovery benchmark, seeds 101 and 102):
    refused, with its numbers, instead of named. What is named is real."""
    report = named(robot, measurement, specs, seed=seed)
    assert kinds(report) and set(kinds(report)) <= expected
    weak = [r for r in report["rejected"] if r["reason"].startswith("held-out gain not significant")]
    assert weak and "standard errors" in weak[0]["reason"]


def test_a_drift_waits_for_a_wander_only_not_for_a_temperature_that_gains_more():
    """A drift gaining half a wander's screening gain is tried before the wander — and only
    before it: a temperature of the links gaining 40 % more than the drift keeps its place.
    Tried after the drift, it was taken by the drift and a wander, and the step beside it was
    missed (discovery benchmark, seed 30, file 33)."""
    effects = ["step:sample=103,axis=z,size=0.150872", "temperature:target=links,tau=828,alpha=23,rise=28.7306"]
    report = named("hsr-jr680", "position", effects, seed=30071)
    assert kinds(report) == [("step", None), ("temperature", None)]
    (step,) = [e for e in report["effects"] if e["kind"] == "step"]
    assert abs(step["params"]["sample"]["value"] - 103) <= 3


def test_a_cause_the_later_ones_make_insignificant_is_retracted_with_its_z_score():
    """The backward check asks of a cause in the model what the forward test asked of it: a
    significant held-out gain over the model without it. A coupling taken early, beside a
    compliance off the mass model and two conventions, still gains on the random folds once the
    later causes are in, but by 1.8 standard errors: retracted, with its z score. (Found by running
    the scenario of the discovery benchmark's seed 28, file 13, on the next seeds: whether a cause
    is taken early and then retracted hangs on the draw.)"""
    data, _ = simulate("ur10", "cable", samples=300, seed=28296, effects=["joint_compliance:joint=2,mass_error=0.284,compliance=7.51761"])
    hidden = [Structure("joint_zero", 1, np.pi), Structure("joint_zero", 2, np.pi)]
    report = diagnose(replace(data, q=to_readings(data.q, hidden))).to_dict()
    retracted = [r for r in report["rejected"] if r["reason"].startswith("no longer earns its place")]
    assert retracted and not {r["label"] for r in retracted} & {e["label"] for e in report["effects"]}
    assert all("held-out gain not significant" in r["reason"] and "standard errors" in r["reason"] for r in retracted), retracted


@pytest.mark.parametrize("seed", [3, 7])
@pytest.mark.parametrize("robot, measurement, joint, harmonic", [("ur10", "position", 3, 5), ("hsr-jr680", "cable", 2, 6)])
def test_a_harmonic_beyond_the_library_is_one_cause_of_its_joint(robot, measurement, joint, harmonic, seed):
    """Harmonics 1-3 are the library's; a higher one is approximated by two or three of them,
    which are then replaced by one periodic error of the joint: the single harmonic, or the joint's map."""
    report = named(robot, measurement, [f"joint_periodic:joint={joint},harmonic={harmonic},amplitude=0.03"], seed=seed)
    assert len(report["effects"]) == 1
    (effect,) = report["effects"]
    assert effect["joint"] == joint and effect["kind"] in ("joint_periodic", "joint_map")
    if effect["kind"] == "joint_periodic":
        assert effect["params"]["harmonic"]["value"] == harmonic


@pytest.mark.parametrize(
    "robot, measurement, effects, expected",
    [
        ("abb-irb120", "position", ["step:sample=150,size=0.3", "backlash:joint=2,width=-0.02"], [("backlash", 2), ("step", None)]),
        (
            "hsr-jr680",
            "position",
            ["joint_compliance:joint=2,mass_error=0.3", "joint_periodic:joint=3,amplitude=0.02,harmonic=2"],
            [("joint_compliance", 2), ("joint_periodic", 3)],
        ),
    ],
)
def test_pairs_of_effects_are_both_named_and_nothing_else(robot, measurement, effects, expected):
    # A joint's map is its periodic error in finer detail: the benchmark's scoring counts it as
    # the harmonic of its joint (benches/discovery.py, `matches`), and so does this test.
    found = [("joint_periodic", joint) if kind == "joint_map" else (kind, joint) for kind, joint in kinds(named(robot, measurement, effects))]
    assert sorted(found) == expected


@pytest.mark.parametrize("robot, measurement", [("ur10", "position"), ("hsr-jr680", "cable")])
def test_clean_data_name_nothing_and_say_noise_only_where_they_measure_their_noise(robot, measurement):
    """Clean data name nothing. What is left is called noise only where the data measure their
    own noise (here: every configuration measured twice, the repeatability); without, nothing
    tells noise from an uncorrelated cause outside the library, and the verdict says so: "not
    explained", with the size of what is left."""
    report = named(robot, measurement, [])
    assert report["effects"] == []
    verdict = report["final"]["residuals"]
    assert verdict["noise"] is False and verdict["unexplained"] is True and verdict["findings"] == []
    assert abs(verdict["correlation"]["lag1"]["z"]) < 5.0
    words = summary(report)
    assert "not explained" in words and f"{verdict['rmse_mm']:.3g} mm" in words and "look like noise" not in words

    once, _ = simulate(robot, measurement, samples=150, seed=3)
    twice, _ = simulate(robot, measurement, samples=150, seed=3, poses=np.repeat(once.q, 2, axis=0))
    revisited = diagnose(twice).to_dict()
    assert revisited["effects"] == []
    verdict = revisited["final"]["residuals"]
    assert verdict["noise"] is True and verdict["unexplained"] is False
    assert "look like noise" in summary(revisited)


def test_an_error_of_many_cycles_a_turn_is_found_in_what_is_left():
    """Joint 3's error of 128 cycles a turn (7.2 arcsec: a gear's tooth mesh or an encoder's cycle,
    finer than the library's harmonics and the joint maps' knots follow): nothing is named for
    it, and what is left is not called noise but that error, at its joint, harmonic and size."""
    data, _ = simulate("ur10", "position", samples=1500, seed=4, effects=["joint_periodic:joint=3,amplitude=0.002,harmonic=128"])
    report = diagnose(data).to_dict()
    verdict = report["final"]["residuals"]
    assert verdict["noise"] is False
    found = verdict["periodic"]
    assert (found["joint"], found["harmonic"]) == (3, 128)
    assert found["amplitude_arcsec"] == pytest.approx(7.2, rel=0.15)
    assert any("128 cycles a turn" in f for f in verdict["findings"])
    assert verdict["sensor"]["verdict"] is False  # an error of the robot's joint, not of the sensor


@pytest.mark.parametrize("robot, measurement, period", [("hsr-jr680", "cable", 100.0), ("ur10", "position", 300.0)])
def test_an_error_of_the_sensor_is_told_from_the_robots(robot, measurement, period):
    """A sensor's own error, 0.1 mm periodic in what it reads (a drawstring's along its length; a
    tracker's across its field, each axis periodic in another — no azimuth encoder's shape): no
    cause of the robot is named. The drawstring's is named as the sensor's own periodic error of
    its period; the tracker's, which no candidate describes, is left, and what is left is said to
    follow the sensor's reading — pairs of samples alike in reading in configurations far apart
    agree, neighbours in joint space do not."""
    data, _ = simulate(robot, measurement, samples=1000, seed=5)
    report = diagnose(with_sensor_error(data, 0.1, period)).to_dict()
    verdict = report["final"]["residuals"]
    if measurement == "cable":
        assert [e["kind"] for e in report["effects"]] == ["sensor_periodic"]
        assert report["effects"][0]["params"]["period"]["value"] == pytest.approx(period, rel=0.02)
        assert report["effects"][0]["params"]["amplitude"]["value"] == pytest.approx(0.1, rel=0.1)
        return
    assert [e["label"] for e in report["effects"]] == []
    assert verdict["noise"] is False
    assert verdict["sensor"]["verdict"] is True
    assert verdict["sensor"]["correlation"] > verdict["correlation"]["joints"]["correlation"] + 0.2
    assert any("follows the sensor's reading" in f for f in verdict["findings"])


def test_the_periodic_scan_tells_a_line_from_a_broad_leftover():
    """The scan's two tests on residuals made to order: white residuals pass neither; an error
    spread over every harmonic of joint 2 (a broad leftover) passes the F test but not the test
    against its joint's median harmonic; one line passes both."""
    from robocal.diagnosis.leftover import SCAN_HARMONICS, SCAN_LEVEL, periodic_leftover

    rng = np.random.default_rng(5)
    m, k = 3000, 3
    q = rng.uniform(-np.pi, np.pi, (m, 6))
    dh_dq = rng.normal(0.0, 1.0, (m * k, 6))
    noise = rng.normal(0.0, 1.0, (m, k))
    along = dh_dq[:, 1].reshape(m, k)  # what an error of joint 2's angle does to each reading
    phases = rng.uniform(0.0, 2.0 * np.pi, len(SCAN_HARMONICS))
    broad = np.sin(np.outer(q[:, 1], SCAN_HARMONICS) + phases).sum(axis=1) * 0.1
    line = 0.3 * np.sin(128 * q[:, 1] + 0.3)

    white = periodic_leftover(q, noise, dh_dq)
    assert min(white["p_adjusted"], white["p_line"]) > SCAN_LEVEL
    spread = periodic_leftover(q, noise + broad[:, None] * along, dh_dq)
    assert spread["p_adjusted"] < SCAN_LEVEL < spread["p_line"]
    found = periodic_leftover(q, noise + line[:, None] * along, dh_dq)
    assert max(found["p_adjusted"], found["p_line"]) < SCAN_LEVEL
    assert (white["reported"], spread["reported"], found["reported"]) == (False, False, True)
    assert (found["joint"], found["harmonic"]) == (2, 128)
    assert found["amplitude_arcsec"] == pytest.approx(np.degrees(0.3) * 3600.0, rel=0.1)


def test_residuals_correlated_in_time_are_not_called_noise():
    """With the wander term refused (no maps, a single cause allowed but none of its kind), what is
    left is said to be correlated in acquisition order — never 'noise'."""
    data, _ = simulate("ur10", "position", samples=300, seed=3, effects=["wander:rms=0.2,length=10"])
    report = diagnose(data, max_effects=0, maps=False).to_dict()
    verdict = report["final"]["residuals"]
    assert verdict["noise"] is False
    assert any("acquisition order" in f for f in verdict["findings"])


@pytest.mark.parametrize(
    "robot, measurement, conventions",
    [("hsr-jr680", "pose", [("joint_zero", 1, 90.0), ("joint_zero", 2, 180.0)]), ("ur10", "position", [("joint_sign", 2, 0.0), ("joint_zero", 4, 270.0)])],
)
def test_conventions_on_two_joints_at_once_are_found_and_nothing_else(robot, measurement, conventions):
    """Neither convention helps alone (the geometry stays ~100 mm off); together they make it nominal."""
    data, _ = simulate(robot, measurement, samples=300, seed=5)
    hidden = [Structure(kind, joint, np.radians(value)) for kind, joint, value in conventions]
    report = diagnose(replace(data, q=to_readings(data.q, hidden))).to_dict()
    assert sorted(e["label"] for e in report["effects"]) == sorted(s.label for s in hidden)
    assert report["final"]["rmse_heldout"] < 0.05


def test_a_wandering_sensor_and_a_robot_cause_tell_themselves_apart_by_the_pairs_they_correlate():
    """The test on the geometric fit's residuals: a wander correlates samples near in time and far
    apart in joints; a joint cause, samples near in joints and far apart in time."""
    wander, _ = simulate("ur10", "position", samples=600, seed=7, effects=["wander:rms=0.3,length=10"])
    joint, _ = simulate("ur10", "position", samples=600, seed=7, effects=["joint_periodic:joint=2,amplitude=0.05,harmonic=3"])
    assert diagnose(wander, max_effects=0, maps=False).baseline["residual_correlation"]["time"]["correlation"] > 0.3
    test = diagnose(joint, max_effects=0, maps=False).baseline["residual_correlation"]
    assert test["time"]["correlation"] < test["joints"]["correlation"]


def test_the_public_d2_residuals_wander_in_time_and_d1_is_a_convention_on_two_joints(datasets):
    """What the public files are (issue 25): D2's geometric residuals are alike for samples near in
    time and far apart in joints, not for samples near in joints and far apart in time (a
    wandering measurement); D1's are alike in joint space, and its readings follow another zero
    convention on joints 2 and 3."""
    d2 = diagnose(datasets / "robotcali-abb-irb120" / "RobotCali-new.xlsx", max_effects=0, maps=False).baseline["residual_correlation"]
    assert d2["verdict"] == "time" and d2["time"]["correlation"] > 0.5 > d2["joints"]["correlation"]
    d1 = diagnose(datasets / "hsr-robotcali" / "HSR-RobotCali.xlsx", max_effects=0, maps=False)
    # -180 rather than +180 (the same kinematics): joint 3's readings of 209-221 deg then lie at 29-41 deg, within its
    # limits -90..270, not at 389-401 deg beyond them.
    assert sorted(e["label"] for e in d1.effects if e["kind"] == "joint_zero") == ["joint_zero joint 2 offset=90", "joint_zero joint 3 offset=-180"]


def test_the_public_d2_file_is_two_jumps_of_the_cable_zero_and_a_leftover_in_time(datasets):
    """D2's residuals wander in time; what wanders is first two jumps of the cable's zero of about
    3 mm (rows 142 and 508), tried before a wander because each gains more than half of what the
    wander would (a wander taken first smoothed them and ended at 0.47 mm held out). What the
    jumps leave is still correlated in acquisition order, and said so: a wander of a few tenths of
    a millimetre follows it on the random folds (0.40 -> 0.30 mm), and is named only where the
    blocked folds do not lose by it. D2's geometry is undetermined (a dozen parameters far from any
    arm), so its blocked folds turn on the parameterisation: with the set-up kept first they lose
    (1.35 -> 1.49 mm) and the wander is an unexplained finding, refused on them; with an anchor
    coordinate fixed instead of theta1 and d1 they did not, and it was named (0.30 mm)."""
    report = diagnose(datasets / "robotcali-abb-irb120" / "RobotCali-new.xlsx").to_dict()
    steps = sorted((e for e in report["effects"] if e["kind"] == "step"), key=lambda e: -abs(e["params"]["size"]["value"]))
    assert sorted(int(e["params"]["row"]["value"]) for e in steps[:2]) == [142, 508]
    assert all(abs(e["params"]["size"]["value"]) > 2.0 for e in steps[:2])
    named = "wander" in {e["kind"] for e in report["effects"]}
    refused_on_blocked = [r for r in report["rejected"] if r["kind"] == "wander" and "blocked folds" in r["reason"]]
    assert named or refused_on_blocked
    last_step = min(steps[:2], key=lambda e: e["rmse_heldout_after"])
    assert last_step["rmse_heldout_after"] ** 2 < 0.15 * report["baseline"]["rmse_heldout"] ** 2  # the jumps: most of the wandering (92 %)
    assert report["final"]["rmse_heldout_blocked"] <= 1.01 * last_step["significance"]["rmse_heldout_blocked_after"]  # nothing kept that loses there


def test_a_convention_the_set_up_absorbs_is_not_named():
    """A clean cable file whose geometric fit as read converged to a far geometry (a1 −249 mm,
    d4 −728 mm): a zero offset of joint 6 "made it plausible", but the tool point absorbs any
    zero of the last joint — the search restarted the fit, it found nothing of the robot."""
    report = named("abb-irb120", "cable", [], seed=25128)
    assert kinds(report) == []
    assert not any(r["kind"] == "joint_zero" and r["joint"] == 6 and "not identifiable" not in r["reason"] for r in report["rejected"])


def test_a_small_wander_on_one_axis_of_a_tracker_is_named_as_wander_and_not_as_steps():
    """A pose file whose frame wanders along x by 0.02 mm RMS (three times what the file can
    detect): knots at half the measured correlation length took the geometry along and were
    refused, and two steps were named in its bends; a stiffer wander is taken instead."""
    report = named("abb-irb120", "pose", ["wander:length=16.7,axis=x,rms=0.0201252"], seed=25222)
    assert kinds(report) == [("wander", None)]


@pytest.mark.parametrize("seed", [25221, 3])
def test_a_step_of_a_tracker_is_placed_by_its_position_rows(seed):
    """The change points are sought in the position rows a step moves: with the rotation rows'
    noise beside them a 0.037 mm step was placed 7 samples off. It is found where it is; named,
    unless a slow change of the level around it predicts the samples as well — then it is refused
    there as gradual (seed 25221: the slow arcs a step must beat, docs/diagnose.md), never named
    elsewhere."""
    report = named("abb-irb120", "pose", ["step:sample=117,axis=z,size=0.037267"], seed=seed)
    steps = [e["params"]["sample"]["value"] for e in report["effects"] if e["kind"] == "step"]
    gradual = [int(r["label"].split("sample=")[1].split()[0]) for r in report["rejected"] if r["kind"] == "step" and "no jump shown" in r["reason"]]
    assert len(steps) <= 1 and all(abs(v - 117) <= 5 for v in steps)
    assert steps or any(abs(v - 117) <= 5 for v in gradual)


@pytest.mark.parametrize(
    "robot, measurement, spec, seed",
    [("abb-irb120", "cable", "drift:exponent=1,rate=4.12105", 25146), ("hsr-jr680", "pose", "drift:exponent=2.097,axis=y,rate=1.68502", 25105)],
)
def test_a_drift_is_named_as_drift_not_as_a_wander(robot, measurement, spec, seed):
    """A wander fine enough follows a drift as well; one coefficient per axis is judged before
    dozens when it gains at least half as much."""
    report = named(robot, measurement, [spec], seed=seed)
    assert kinds(report) == [("drift", None)]


def test_a_drift_fast_at_first_is_one_curved_drift_and_no_step_at_its_start():
    """A warm-up ∝ t^0.57 left a step in its first dozen samples beside the linear drift; an
    exponential settling takes its place, and the step it makes unnecessary is dropped."""
    report = named("abb-irb120", "cable", ["drift:exponent=0.567,rate=3.79239", "outliers:fraction=0.0219,size=1.554"], seed=25169)
    assert kinds(report) == [("drift", None), ("outliers", None)]
    (drift,) = [e for e in report["effects"] if e["kind"] == "drift"]
    assert drift["label"] != "drift"  # a curved one


def test_a_drift_whose_line_misses_the_held_out_blocks_is_a_curved_drift_not_a_coupling():
    """A cable zero drifting ∝ t^2.5: its line gains on the random folds and loses on the blocked
    ones, and a coupling whose source joint moves with time took the bend (discovery benchmark,
    seed 33, file 223). The drift's curves compete in the same round and one is named, alone."""
    report = named("abb-irb120", "cable", ["drift:exponent=2.483,rate=3.63278"], seed=33147)
    assert kinds(report) == [("drift", None)]
    assert report["effects"][0]["label"] != "drift"  # a curved one


def test_a_curve_of_time_is_no_simpler_than_a_wander():
    """A wandering cable zero (length 17 samples) beside a small step: a settling drift gains less
    than the wander on the random folds and must not be judged before it as a linear drift would
    be (discovery benchmark, seed 33, file 341: a settling drift took the wander's place)."""
    report = named("abb-irb120", "cable", ["step:sample=269,size=0.219182", "wander:length=17,rms=0.0934442"], seed=33156)
    assert ("wander", None) in kinds(report)
    assert ("drift", None) not in kinds(report)


def test_a_sample_at_the_lonely_end_of_a_mapped_joint_is_not_an_outlier():
    """A fifth-turn harmonic of joint 6 the map takes: the sample at the end of joint 6's range,
    where only the map's roughness prior sets it, keeps a large residual that is the map's, not a
    gross reading (discovery benchmark, seed 36, file 270: named outliers beside the map)."""
    report = named("abb-irb120", "pose", ["joint_periodic:joint=6,harmonic=5,phase=341.6,amplitude=0.137839"], seed=36227)
    assert kinds(report) == [("joint_map", 6)]


@pytest.mark.parametrize(
    "robot, measurement, spec, seed",
    [("hsr-jr680", "pose", "joint_scale:joint=2,scale=0.000140327", 36101), ("ur10", "cable", "joint_scale:joint=2,scale=0.00106313", 37270)],
)
def test_a_scale_error_the_data_tell_from_a_compliance_is_not_taken_for_one(robot, measurement, spec, seed):
    """A gravity compliance is tried before the free shapes of its joint only while the data
    cannot tell them apart: a scale error of joint 2 beating joint 2's compliance by 2-5 standard
    errors was named a compliance (discovery benchmark, seed 36 file 102, seed 37 file 40)."""
    report = named(robot, measurement, [spec], seed=seed)
    assert kinds(report) == [("joint_scale", 2)]


def test_a_fold_that_cannot_see_a_step_holds_it_at_zero():
    """A blocked fold whose training samples all follow a step cannot estimate it (it is a
    constant the set-up takes): the step is held at zero there, so the fold's held-out error
    does not depend on how the solver happened to split that constant (D2's blocked folds moved
    from 0.80 to 0.85 mm with the starting damping alone)."""
    from robocal.calibration.problem import Problem
    from robocal.diagnosis import validation
    from robocal.causes.candidates import step_candidate
    from robocal.causes.problem import ExtendedProblem

    data, _ = simulate("abb-irb120", "cable", samples=300, seed=4, effects=["step:sample=20,size=0.5"])
    base = Problem.build(robot_of(data), data)
    step = step_candidate(data, 20)
    model = ExtendedProblem(base, [step], data, np.arange(len(data)))
    train, test = np.arange(60, 300), np.arange(60)  # all training samples after the step
    fold = validation.fold_problem(model, train)
    assert not np.allclose(fold.causes[0].penalty, 0.0)  # held
    errors = {}
    for damping in (1e-6, 1e-3):
        start = model.x0.copy()
        start[model.slices[0]] = 0.3  # an arbitrary start for the undetermined coefficient
        fit = validation.levenberg_marquardt(fold, x0=start, method="diagnose", lam0=damping)
        assert abs(fold.coefficients(fit.x, fold.causes[0])[0]) < 1e-2
        errors[damping] = validation.held_out_errors(model, fold, train, test, fit.x).sum()
    assert errors[1e-6] == pytest.approx(errors[1e-3], rel=1e-3)
    # a fold with samples on both sides estimates it
    both = validation.fold_problem(model, np.arange(0, 300, 2))
    assert both.causes[0].penalty is None


def robot_of(data):
    from robocal.robot import robot

    return robot(data.robot)


def test_a_step_cut_from_a_slow_wave_is_not_named_but_a_sharp_step_is():
    """A drift with a slow wave (made outside robocal's candidates: a ramp plus a sine of a third of it, period two thirds
    of the session, along a tracker direction) was named a step and nothing else, as if the level had jumped (later with
    "drift" as what the data cannot tell it from). A step must beat the slow arcs of the session around it: this one does
    not, and is not named; a sharp step of the same size is, with nothing it cannot be told from."""
    data, _ = simulate("hsr-jr680", "position", samples=300, seed=8)
    t = np.linspace(0.0, 1.0, len(data))
    wave = 0.05 * (t + 0.36 * np.sin(2.0 * np.pi * t / 0.645 + 1.13))
    named = diagnose(replace(data, y=data.y + np.outer(wave, [-0.3356, 0.3077, 0.8903])), robot="hsr-jr680").effects
    assert not [e for e in named if e["kind"] == "step"], [e["label"] for e in named]
    sharp, _ = simulate("hsr-jr680", "position", samples=300, seed=8, effects=["step:sample=150,size=0.1"])
    [step] = [e for e in diagnose(sharp, robot="hsr-jr680").effects if e["kind"] == "step"]
    assert step["params"]["sample"]["value"] == 150 and step["significance"]["undetermined_between"] == []
