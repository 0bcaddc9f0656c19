"""In-line monitoring (issue 54): a change hidden in a simulated stream is alarmed as what it is,
near where it began; clean streams, also with time-correlated sensor noise, raise none; bad
samples are refused and the stream goes on; the command line writes JSON lines and the updated
result."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
import robocal
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from robocal.cli import main
from robocal.data import write_canonical
from robocal.exceptions import RobocalError, ShapeError
from robocal.monitor_window import BATCH, WINDOW, LongRunVariance, quadratic_form, ridged_inverse
from robocal.monitoring import FIT_RATIO, MAX_WAIT, MIN_OPENING, OPENING, Monitor
from robocal.results import load_result
from robocal.simulation import simulate

CHANGE_AT = 600


@pytest.fixture(scope="module")
def monitor_result():
    data, _ = simulate("ur10", "position", samples=150, seed=3)
    return robocal.calibrate(data, robot="ur10").to_dict()


@pytest.fixture(scope="module", params=[("ur10", "position"), ("hsr-jr680", "cable"), ("abb-irb120", "position")])
def calibrated(request):
    """A robot calibrated on one session, and a new session of the same robot (1,000 samples)."""
    robot, measurement = request.param
    data, _ = simulate(robot, measurement, samples=400, seed=2)
    result = robocal.calibrate(data, robot=robot).to_dict()
    stream, _ = simulate(robot, measurement, samples=1000, seed=2, session=1)
    return result, stream


def _wander(shape, rng, phi=0.9, sigma=0.05) -> np.ndarray:
    """The sensor's reading wandering as an AR(1) process (correlation ``phi`` from sample to sample, ``sigma`` mm stationary)."""
    wander = np.zeros(shape)
    for t in range(1, shape[0]):
        wander[t] = phi * wander[t - 1] + sigma * np.sqrt(1 - phi**2) * rng.standard_normal(shape[1])
    return wander


def _replay(result, q, y, **options) -> tuple[Monitor, list]:
    monitor = Monitor(result, new_session=True, **options)
    alarms = []
    for qi, yi in zip(q, y):
        alarms += monitor.update(qi, yi)
    return monitor, alarms


def test_a_clean_stream_raises_no_alarm(calibrated):
    result, stream = calibrated
    monitor, alarms = _replay(result, stream.q, stream.y)
    assert alarms == [], [a.words() for a in alarms]
    assert monitor._buffers.rings["G"].shape[0] == WINDOW and len(monitor._delayed) < WINDOW  # memory bounded by the window


def test_time_correlated_sensor_noise_raises_no_alarm(calibrated):
    """The sensor's reading wanders as an AR(1) process (correlation 0.9 from sample to sample,
    0.05 mm stationary): the yardsticks, not the threshold, absorb it; no alarm of any kind."""
    result, stream = calibrated
    _, alarms = _replay(result, stream.q, stream.y + _wander(stream.y.shape, np.random.default_rng(5)))
    assert alarms == [], [a.words() for a in alarms]


def test_the_yardstick_learns_a_correlation_the_opening_did_not_show():
    """Innovations white over the opening's four batches, then correlated (AR(1), 0.8: their sums
    vary 9x as much): the long-run inflation reaches the new correlation within 30 batches (the
    opening's estimate weighed as 100 batches kept it near 3), and over the opening alone it is
    taken at its upper confidence bound (4 batches cannot show a correlation they missed)."""
    rng = np.random.default_rng(0)
    yardstick = LongRunVariance(rng.standard_normal((OPENING, 1)))
    assert yardstick.inflation > 2.0
    z = np.zeros(30 * BATCH)
    for t in range(1, len(z)):
        z[t] = 0.8 * z[t - 1] + 0.6 * rng.standard_normal()
    for v in z:
        yardstick.add(np.array([v]))
    assert yardstick.inflation > 0.6 * 9.0


@pytest.mark.parametrize("session, samples", [(1, 3000), (8, 700)])
def test_a_clean_cable_stream_that_leaves_the_calibrations_region_raises_no_alarm(session, samples):
    """Session 1, 3,000 samples: the path leaves the 200 opening samples' region (and the
    calibration's cable lengths, 869-1975 mm, for 540 mm): the set-up the opening fitted then
    errs, the innovations correlate over hundreds of samples, and the yardstick must follow
    (before it did, a joint's zero and a 0.24 mm step were alarmed). Session 8 of
    benches/monitor_false_alarms.py, its first 700 samples: by sample 440 the cable is down to
    598 mm and the model errs along the path by 0.4 mm RMS, five times the noise, which the
    calibration's parameters within their standard deviations and the set-up explain to the
    noise (alarmed as a change no kind explains while the window's constant was held near the
    calibration's lengths by a ridge of the angles' information)."""
    data, _ = simulate("hsr-jr680", "cable", samples=400, seed=2)
    result = robocal.calibrate(data, robot="hsr-jr680").to_dict()
    stream, _ = simulate("hsr-jr680", "cable", samples=samples, seed=2, session=session)
    _, alarms = _replay(result, stream.q, stream.y)
    assert alarms == [], [a.words() for a in alarms]


def test_the_windows_constant_is_free_in_every_unit():
    """The ridge that keeps an undetermined direction at the calibration's value is per column: a
    length's information beside an angle's (mm² against rad², 10⁷ apart) is not held down by it,
    and the constant does not change with the columns' units."""
    G = np.array([[4e10, 2e6], [2e6, 1.4e3]])
    g = np.array([3e5, 40.0])
    exact = np.linalg.solve(G, g)
    assert np.allclose(ridged_inverse(G) @ g, exact, rtol=1e-4)
    scale = np.diag([1.0, 1e-3])  # the length in metres
    assert np.allclose(scale @ ridged_inverse(scale @ G @ scale) @ (scale @ g), exact, rtol=1e-4)
    assert np.all(np.isfinite(ridged_inverse(np.array([[1.0, 1.0], [1.0, 1.0]]))))  # undetermined: finite


def test_a_joint_zero_change_is_alarmed_as_that_joint_near_where_it_began(calibrated):
    result, stream = calibrated
    probe = Monitor(result, new_session=True)
    probe.update(stream.q[:OPENING], stream.y[:OPENING])
    limits = {entry["joint"]: entry["size"] for entry in probe.summary()["detection_limits"] if entry["kind"] == "joint_zero"}
    for joint in (2, 3):
        size = 5 * limits[joint]  # deg
        q = stream.q.copy()
        q[CHANGE_AT:, joint - 1] -= np.radians(size)  # re-mastered: the reading is that much below the angle from then on
        _, alarms = _replay(result, q, stream.y)
        named = [a for a in alarms if not a.provisional]  # a provisional alarm (the sensor's step, as long as it explains the change alike) may come first
        assert named, f"joint {joint}: a zero change of {size:.4f} deg (5x its limit) was not named"
        first = named[0]
        assert (first.kind, first.joint) == ("joint_zero", joint), first.words()
        assert abs(first.since - CHANGE_AT) <= 5 and first.sample - CHANGE_AT <= 40, first.words()
        assert first.size[0] == pytest.approx(size, rel=0.3)


def test_a_change_of_three_times_its_stated_limit_is_alarmed_in_time(calibrated):
    """The detection limits the monitor states just before a change (each change's smallest size
    found within LIMIT_SAMPLES, measured in the stream's own windows) hold: 3x a joint's zero is
    alarmed within 25 samples, 3x the sensor's step within 10 (issue 54's targets). The limits
    the opening's mean information gave promised up to 2x too much: the step on the ABB came 19
    samples late at 3x them."""
    result, stream = calibrated
    probe = Monitor(result, new_session=True)
    probe.update(stream.q[:CHANGE_AT], stream.y[:CHANGE_AT])
    limits = {(e["kind"], e["joint"]): e["size"] for e in probe.summary()["detection_limits"]}
    for (kind, joint), within in ((("joint_zero", 2), 25), (("joint_zero", 3), 25), (("step", None), 10)):
        size = 3 * limits[(kind, joint)]
        q, y = stream.q.copy(), stream.y.copy()
        if joint:
            q[CHANGE_AT:, joint - 1] -= np.radians(size)
        else:
            y[CHANGE_AT:] += size * np.ones(y.shape[1]) / np.sqrt(y.shape[1])
        _, alarms = _replay(result, q, y)
        assert alarms, f"{kind} {joint}: 3x its limit ({size:.4g}) not alarmed"
        assert alarms[0].sample - CHANGE_AT <= within and abs(alarms[0].since - CHANGE_AT) <= 5, alarms[0].words()


def test_a_second_change_is_found_after_the_first_is_applied():
    """Joint 2's zero moves at sample 750 and the cable is re-zeroed at 1,500 (each 5x the limit
    stated before the first): both are alarmed, the second as quickly as it would be alone. The
    innovations the first change made, fed to the yardstick as they left the window, had raised
    the long-run inflation from 5 to 300 and hid the second."""
    data, _ = simulate("hsr-jr680", "cable", samples=400, seed=2)
    result = robocal.calibrate(data, robot="hsr-jr680").to_dict()
    stream, _ = simulate("hsr-jr680", "cable", samples=2200, seed=2, session=1)
    q, y = stream.q.copy(), stream.y.copy()
    probe = Monitor(result, new_session=True)
    probe.update(q[:750], y[:750])
    before = probe.inflation
    limits = {(e["kind"], e["joint"]): e["size"] for e in probe.summary()["detection_limits"]}
    q[750:, 1] -= np.radians(5 * limits[("joint_zero", 2)])
    monitor = Monitor(result, new_session=True)
    first = monitor.update(q[:1500], y[:1500])
    assert [(a.kind, a.joint) for a in first if not a.provisional] == [("joint_zero", 2)], [a.words() for a in first]
    assert monitor.inflation < 2 * before, (monitor.inflation, before)
    y[1500:] += 5 * limits[("step", None)]
    second = monitor.update(q[1500:], y[1500:])
    assert second and abs(second[0].since - 1500) <= 3 and second[0].sample - 1500 <= 10, [a.words() for a in second]


def test_each_changes_statistic_is_measured_against_its_own_yardstick():
    """Under no change each statistic, per degree of freedom and divided by what the monitor divides
    it by, averages at most 1 (χ²): on a long clean HSR cable stream whose reading wanders (AR(1),
    0.9, 0.05 mm), over segments of 25 and 75 samples (the yardstick is measured on 50). The
    innovations' long-run inflation alone fell short for the drift by 2x, and such streams raised
    40 false alarms in 870,000 samples where one per 100,000 was stated."""
    data, _ = simulate("hsr-jr680", "cable", samples=400, seed=2)
    result = robocal.calibrate(data, robot="hsr-jr680").to_dict()
    stream, _ = simulate("hsr-jr680", "cable", samples=3000, seed=2, session=5)
    monitor = Monitor(result, new_session=True, mean_run_length=1e15)  # no alarm: the null throughout
    at_scale, at_inflation = {}, {}
    for i, (qi, yi) in enumerate(zip(stream.q, stream.y + _wander(stream.y.shape, np.random.default_rng(5)))):
        monitor.update(qi, yi)
        if monitor._scale.count < 20 or i % 10:  # once its yardstick rests on 20 segments
            continue
        b = monitor._buffers
        groups, _ = b.evidence(b.n - 2, monitor.prior)
        scale = monitor._scale.scale(monitor.inflation)
        for which, score, info in groups:
            for after in (25, 75):
                at = WINDOW - after - 1
                per_dof = quadratic_form(info[at] + 1e-12 * np.eye(score.shape[2]), score[at]) / score.shape[2]
                for j, k in enumerate(which):
                    kind = monitor.changes[k].kind
                    at_scale.setdefault(kind, []).append(per_dof[j] / scale)
                    at_inflation.setdefault(kind, []).append(per_dof[j] / monitor.inflation)
    mean = {kind: float(np.mean(v)) for kind, v in at_scale.items()}
    # At most χ² for every kind (one divisor for all, at its upper confidence bound: the zeros' well below).
    assert all(0.4 < m < 1.1 for m in mean.values()), mean
    assert np.mean(at_inflation["drift"]) > 1.5  # what the inflation alone made of it


def test_a_sensor_step_is_alarmed_as_a_step(calibrated):
    result, stream = calibrated
    y = stream.y.copy()
    y[CHANGE_AT:] += 0.5 if stream.measurement == "cable" else np.array([0.3, -0.2, 0.25])  # the cable re-zeroed, the tracker moved
    _, alarms = _replay(result, stream.q, y)
    assert alarms and alarms[0].kind == "step", [a.words() for a in alarms]
    # A cable's one reading cannot tell its zero from a joint's for a few samples: the monitor waits until it can, at most
    # MAX_WAIT samples (the cable's innovations correlate along the path, which the yardstick counts: the evidence grows slowly).
    assert abs(alarms[0].since - CHANGE_AT) <= 3 and alarms[0].sample - CHANGE_AT <= (MAX_WAIT if stream.measurement == "cable" else 10)


def test_d2s_cable_re_zeroing_is_alarmed_at_once_as_a_step(datasets):
    """D2 (ABB IRB 120, cable), calibrated on its samples 230-498 and replayed from 230 on: the
    cable re-zeroed at file row 508 is alarmed as the sensor's step within 5 samples, from the
    right sample. Joint zeros explain the jump alike for a while (the reading after it is no
    constant against this calibration's model): the alarm says so and is provisional — not
    applied — until one kind is told apart."""
    data = robocal.load(datasets / "robotcali-abb-irb120" / "abb_irb120_cable.csv")
    result = robocal.calibrate(data.subset(np.arange(230, 499)), robot="abb-irb120", test_fraction=0)
    rows = np.asarray(data.rows)[230:]
    re_zero = int(np.flatnonzero(rows == 508)[0])  # its stream sample
    monitor = Monitor(result.to_dict())
    before = monitor.params.copy()
    alarms = monitor.update(data.q[230 : 230 + re_zero + 6], data.y[230 : 230 + re_zero + 6], rows=rows[: re_zero + 6])
    assert len(alarms) == 1, [a.words() for a in alarms]
    first = alarms[0]
    assert first.kind == "step" and first.sample - re_zero <= 5 and first.since == re_zero, first.words()
    assert first.provisional and any("joint" in c for c in first.could_be), first.words()
    assert np.array_equal(monitor.params, before)  # told, not applied


def test_d2s_re_zeroing_is_not_named_as_a_joint_it_does_not_fit(datasets):
    """Past the provisional step, the likeliest single kind on D2 (joint 4's zero) leaves the
    innovations after the re-zero at several times their noise: the monitor names no joint,
    applies nothing, says no single kind explains it and opens anew."""
    data = robocal.load(datasets / "robotcali-abb-irb120" / "abb_irb120_cable.csv")
    result = robocal.calibrate(data.subset(np.arange(230, 499)), robot="abb-irb120", test_fraction=0)
    rows = np.asarray(data.rows)[230:]
    re_zero = int(np.flatnonzero(rows == 508)[0])
    monitor = Monitor(result.to_dict())
    before = monitor.params.copy()
    alarms = monitor.update(data.q[230 : 230 + re_zero + 30], data.y[230 : 230 + re_zero + 30], rows=rows[: re_zero + 30])
    assert [a.kind for a in alarms] == ["step", "unexplained"], [a.words() for a in alarms]
    last = alarms[-1]
    assert last.since == re_zero and last.evidence > FIT_RATIO and last.could_be[0] == "joint 4's zero", last.words()
    assert np.array_equal(monitor.params, before) and monitor.sigma is None  # nothing applied; a new opening under way


def test_a_sensor_moved_before_the_stream_is_said_and_its_set_up_re_fitted():
    """The calibration's session goes on by default; a stream from a sensor placed elsewhere (a new
    session) differs from the first sample, which the window's constant would absorb unseen: the
    opening says so, re-fits the set-up as ``new_session`` does, and the clean stream raises no
    other alarm. The calibration's own session raises none."""
    data, _ = simulate("ur10", "position", samples=300, seed=2)
    result = robocal.calibrate(data, robot="ur10").to_dict()
    other, _ = simulate("ur10", "position", samples=600, seed=2, session=1)
    monitor = Monitor(result)
    alarms = monitor.update(other.q, other.y)
    assert [a.kind for a in alarms] == ["setup"] and alarms[0].since == 0 and alarms[0].sample == OPENING - 1, [a.words() for a in alarms]
    fresh = Monitor(result, new_session=True)
    fresh.update(other.q, other.y)
    assert np.allclose(monitor.params, fresh.params) and monitor.refit == fresh.refit
    same, _ = simulate("ur10", "position", samples=600, seed=2)
    assert Monitor(result).update(same.q, same.y) == []


def test_a_slow_drift_raises_no_step(calibrated):
    result, stream = calibrated
    ramp = np.clip(np.arange(len(stream.y)) - CHANGE_AT, 0, None)[:, None] * 0.002  # mm per sample
    _, alarms = _replay(result, stream.q, stream.y + ramp * (1.0 if stream.measurement == "cable" else np.array([0.6, -0.6, 0.5])))
    assert all(a.kind == "drift" for a in alarms), [a.words() for a in alarms]


def test_bad_samples_are_refused_and_the_stream_goes_on():
    data, _ = simulate("ur10", "position", samples=300, seed=2)
    result = robocal.calibrate(data, robot="ur10").to_dict()
    monitor = Monitor(result)
    q, y = data.q.copy(), data.y.copy()
    q[150, 2] = np.nan
    q[160, 0] = 10.0  # beyond the joint's range
    monitor.update(q, y, rows=list(range(2, 302)))
    assert monitor.samples == 300 and len(monitor.refused) == 2
    assert "row 152" in monitor.refused[0] and "finite" in monitor.refused[0] and "limits" in monitor.refused[1]
    with pytest.raises(ShapeError, match="has 3 joint values; the result's robot 'ur10' has 6"):
        monitor.update(q[:1, :3], y[:1])
    with pytest.raises(ShapeError, match=r"`y` must hold 3 readings \(position\) for each of the 2 samples; got shape \(1, 6\)"):
        monitor.update(q[:2], y[:2].ravel())
    # rows for fewer samples than given: refused whole (zip would have dropped the rest unseen)
    seen = monitor.samples
    with pytest.raises(ShapeError, match="`rows` must name the file row of each of the 2 samples; got 1"):
        monitor.update(q[:2], y[:2], rows=[7])
    with pytest.raises(ShapeError, match=r"one sample \(N,\) or a block of samples \(m, N\); got shape \(1, 2, 6\)"):
        monitor.update(q[None, :2], y[None, :2])
    assert monitor.samples == seen


def test_the_monitors_options_are_checked_by_name(monitor_result):
    """An infinite mean run length was taken: every threshold infinite, no change ever alarmed, the detection limits
    "inf deg"; a string one raised a TypeError; a NumPy integer opening was refused, one shorter than a batch (50)
    crashed when it was complete (a traceback)."""
    for bad in (float("inf"), float("nan"), 5, "x", None):
        with pytest.raises(RobocalError, match="mean_run_length"):
            Monitor(monitor_result, mean_run_length=bad)
    for bad in (5, 50, 99, 120.0, True, "150"):  # fewer than two batches: an opening of 10 crashed at its end
        with pytest.raises(RobocalError, match="opening"):
            Monitor(monitor_result, opening=bad)
    assert Monitor(monitor_result, opening=np.int64(150)).opening == 150
    data, _ = simulate("ur10", "position", samples=110, seed=3, session=1)
    monitor = Monitor(monitor_result, opening=MIN_OPENING, new_session=True)
    monitor.update(data.q, data.y)
    assert monitor.sigma is not None and monitor.inflation >= 1.0


@settings(max_examples=60, deadline=None)
@given(
    q=arrays(np.float64, st.tuples(st.integers(1, 3), st.integers(1, 7)), elements=st.floats(allow_nan=True, allow_infinity=True, width=64)),
    y=arrays(np.float64, st.tuples(st.integers(1, 3), st.integers(1, 7)), elements=st.floats(allow_nan=True, allow_infinity=True, width=64)),
)
def test_malformed_samples_raise_a_robocal_error_or_are_refused(monitor_result, q, y):
    """Any shape, NaN, infinity, huge values: a RobocalError naming the problem, or the sample
    refused with a note; never another exception, never a crash."""
    monitor = Monitor(monitor_result, opening=MIN_OPENING)
    try:
        monitor.update(q, y)
    except RobocalError:
        return
    assert monitor.samples == len(q)


def test_the_command_line_writes_alarms_and_the_updated_result(tmp_path, capsys):
    data, _ = simulate("ur10", "position", samples=400, seed=2)
    result = tmp_path / "r.json"
    result.write_text(json.dumps(robocal.calibrate(data, robot="ur10").to_dict()))
    stream, _ = simulate("ur10", "position", samples=800, seed=2, session=1)
    q = stream.q.copy()
    q[CHANGE_AT:, 2] -= np.radians(0.05)
    stream = replace(stream, q=q)
    path = tmp_path / "stream.csv"
    write_canonical(stream, path)
    lines, updated = tmp_path / "alarms.jsonl", tmp_path / "updated.json"
    assert main(["monitor", str(result), str(path), "--new-session", "--json-lines", str(lines), "--out", str(updated), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "joint 3's zero changed from sample" in printed and "detection limits" in printed
    alarm = json.loads(lines.read_text().splitlines()[0])
    assert alarm["kind"] == "joint_zero" and alarm["joint"] == 3 and abs(alarm["since"] - CHANGE_AT) <= 5
    assert alarm["row"] == int(stream.rows[alarm["sample"]])
    before, _ = load_result(result)
    after, doc = load_result(updated)
    moved = np.degrees(after.params[after.index("theta3")] - before.params[before.index("theta3")])
    assert moved == pytest.approx(0.05, abs=0.01) and doc["monitor"]["alarms"][0]["joint"] == 3
    other, _ = simulate("hsr-jr680", "cable", samples=200, seed=1)
    write_canonical(other, tmp_path / "hsr.csv")
    assert main(["monitor", str(result), str(tmp_path / "hsr.csv"), "--quiet"]) == 2
    assert "robocal: error:" in capsys.readouterr().err


def _window_evidence(samples, cols, ramp, prior, start):
    """The score and information of a change on ``cols`` from window sample ``start`` on, every
    column profiled out, straight from the window's samples ``(t, Jw, z)``: the Schur complement
    of the normal equations of ``z_t = Jw_t θ + x_t δ`` (``x_t`` the change's regressor)."""
    t0 = samples[start][0]
    X = np.concatenate([Jw[:, cols] * (t - t0 if ramp else 1.0) * (k >= start) for k, (t, Jw, _) in enumerate(samples)])
    J = np.concatenate([Jw for _, Jw, _ in samples])
    z = np.concatenate([z for _, _, z in samples])
    inverse = ridged_inverse(J.T @ J + np.diag(prior))  # the monitor's ridge
    score = X.T @ z - X.T @ J @ inverse @ (J.T @ z)
    info = X.T @ X - X.T @ J @ inverse @ (J.T @ X)
    return score, info


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), k=st.integers(1, 3), extra=st.integers(0, 2 * WINDOW), clear_at=st.none() | st.integers(0, 3 * WINDOW))
def test_the_window_sums_are_the_windows_own(seed, k, extra, clear_at):
    """The running totals, the ring and the packed sums give every change's score and
    information from every start as the window's own samples do, after the window has wrapped
    round any number of times and after a clear (an alarm)."""
    from robocal.monitor_window import WindowSums
    from robocal.monitoring import MIN_AFTER

    rng = np.random.default_rng(seed)
    p = 7
    hypotheses = [([0], False), ([3], False), ([5], False), ([1, 2, 6], False), ([1, 2, 6], True), ([4, 6], True)]
    buffers, prior = WindowSums(p, hypotheses), rng.uniform(0.0, 2.0, p)
    window, t = [], int(rng.integers(0, 10**5))
    for step in range(WINDOW // 2 + extra):
        t += int(rng.integers(1, 3))  # refused samples leave gaps in the times
        Jw, z = rng.standard_normal((k, p)), rng.standard_normal(k)
        if step == clear_at:
            buffers.clear()
            window.clear()
        buffers.push(t, Jw.T @ z, Jw.T @ Jw)
        window = (window + [(t, Jw, z)])[-WINDOW:]
    starts = buffers.n - MIN_AFTER + 1
    groups, _ = buffers.evidence(starts, prior)
    assert sorted(k for which, _, _ in groups for k in which) == list(range(len(hypotheses)))
    for which, score, info in groups:
        assert score.shape[0] == starts - 1
        for j, h in enumerate(which):
            for n, start in enumerate(range(1, starts)):
                s, F = _window_evidence(window, *hypotheses[h], prior, start)
                scale = np.abs(F).max()
                np.testing.assert_allclose(score[n, j], s, rtol=1e-7, atol=1e-7 * np.sqrt(scale))
                np.testing.assert_allclose(info[n, j], F, rtol=1e-7, atol=1e-7 * scale)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), d=st.integers(1, 4), condition=st.floats(0.0, 8.0))
def test_the_statistic_from_ldl_factors_is_the_solved_ones(seed, d, condition):
    """``bᵀ A⁻¹ b`` from the stacked ``LDLᵀ`` factors is what a solve per matrix gives, for
    symmetric positive definite matrices up to 10⁸ times as long along one axis as another."""
    rng = np.random.default_rng(seed)
    X = rng.standard_normal((5, 3, d, d)) * np.logspace(0.0, -condition / 2.0, d)
    A, b = X @ X.transpose(0, 1, 3, 2) + 1e-9 * np.eye(d), rng.standard_normal((5, 3, d))
    solved = np.einsum("...i,...i->...", b, np.linalg.solve(A, b[..., None])[..., 0])
    np.testing.assert_allclose(quadratic_form(A, b), solved, rtol=1e-6)


def test_a_stream_on_standard_input_refuses_bad_lines_and_goes_on(tmp_path, capsys, monkeypatch, monitor_result):
    """``robocal monitor RESULT -``: lines as they come; a line cut short, a value that is not a
    number, a repeated header and a clock that goes backwards are each refused naming their row;
    the samples around them are monitored."""
    import io

    result = tmp_path / "r.json"
    result.write_text(json.dumps(monitor_result))
    stream, _ = simulate("ur10", "position", samples=60, seed=3, session=1)
    write_canonical(stream, tmp_path / "s.csv")
    lines = (tmp_path / "s.csv").read_text().splitlines()
    header, rows = lines[0], lines[1:]
    t_at = header.split(",").index("t")
    back = rows[20].split(",")
    back[t_at] = "-5"
    bad = [rows[10][:25], rows[15].replace(rows[15].split(",")[0], "x", 1), header, ",".join(back)]
    text = "\n".join([header, *rows[:20], bad[0], bad[1], "", bad[2], bad[3], *rows[21:]])
    monkeypatch.setattr("sys.stdin", io.StringIO(text))
    assert main(["monitor", str(result), "-", "--new-session", "--quiet"]) == 0
    out, err = capsys.readouterr()
    refused = [line for line in err.splitlines() if "refused" in line]
    assert len(refused) == 4, err
    assert "row 22 refused" in refused[0] and "cells" in refused[0]
    assert "row 23 refused" in refused[1] and "'q1'" in refused[1]
    assert "row 25 refused" in refused[2]
    assert "row 26 refused" in refused[3] and "clock goes backwards" in refused[3] and "'t'" in refused[3]
    assert out.startswith(f"{len(rows) - 1} samples, 0 alarms, 4 refused")


@pytest.mark.parametrize("form", ["bom", "crlf", "cr", "quoted"])
def test_a_stream_on_standard_input_is_read_as_the_same_file_is(tmp_path, capsys, monkeypatch, monitor_result, form):
    """Standard input split its lines on LF alone and its cells on commas alone: with a BOM every line was refused
    for the header's first name, quoted numbers were refused, CR-ended lines made one header and no sample (exit 0).
    The file reader takes each of them; the stream now reads as the file does."""
    import io

    result = tmp_path / "r.json"
    result.write_text(json.dumps(monitor_result))
    stream, _ = simulate("ur10", "position", samples=230, seed=3, session=1)
    write_canonical(stream, tmp_path / "s.csv")
    lines = (tmp_path / "s.csv").read_text().splitlines()
    text = {
        "bom": "\ufeff" + "\n".join(lines),
        "crlf": "\r\n".join(lines),
        "cr": "\r".join(lines),
        "quoted": "\n".join([lines[0]] + [",".join(f'"{c}"' for c in line.split(",")) for line in lines[1:]]),
    }[form]
    (tmp_path / "f.csv").write_text(text, newline="")
    assert main(["monitor", str(result), str(tmp_path / "f.csv"), "--new-session", "--json-lines", str(tmp_path / "file.jsonl")]) == 0
    from_file = capsys.readouterr().out
    monkeypatch.setattr("sys.stdin", io.TextIOWrapper(io.BytesIO(text.encode()), encoding="utf-8", newline="\n"))  # as Python opens it on POSIX
    assert main(["monitor", str(result), "-", "--new-session", "--json-lines", str(tmp_path / "stdin.jsonl")]) == 0
    out, err = capsys.readouterr()
    assert out == from_file and out.startswith(f"{len(lines) - 1} samples, 0 alarms, 0 refused; ") and "refused" not in err, (out, err)


def test_a_recorded_file_is_replayed_as_its_stream_a_bad_row_refused_not_the_file(tmp_path, capsys, monkeypatch, monitor_result):
    """A row that does not parse stopped a file at once, while the same stream refused it and went on."""
    import io

    result = tmp_path / "r.json"
    result.write_text(json.dumps(monitor_result))
    stream, _ = simulate("ur10", "position", samples=230, seed=3, session=1)
    write_canonical(stream, tmp_path / "s.csv")
    lines = (tmp_path / "s.csv").read_text().splitlines()
    lines[40] = lines[40].replace(",", ",x", 1)
    (tmp_path / "f.csv").write_text("\n".join(lines))
    assert main(["monitor", str(result), str(tmp_path / "f.csv"), "--new-session"]) == 0
    from_file = capsys.readouterr()
    monkeypatch.setattr("sys.stdin", io.StringIO("\n".join(lines)))
    assert main(["monitor", str(result), "-", "--new-session"]) == 0
    from_stdin = capsys.readouterr()
    assert from_file.out == from_stdin.out and from_file.out.startswith(f"{len(lines) - 2} samples, 0 alarms, 1 refused; ")
    assert from_file.err.replace(str(tmp_path / "f.csv"), "<stdin>") == from_stdin.err and "row 41 refused" in from_file.err


@pytest.mark.parametrize(
    "header, message",
    [("q1;q2;q3;q4;q5;q6;x;y;z", "';'-separated"), ("Q1,Q2,Q3,Q4,Q5,Q6,X,Y,Z", "joint columns"), ("q1,q2,q3,q4,q5,q6,L", "'x', 'y', 'z'")],
)
def test_a_stream_whose_header_is_not_the_results_stops_at_once(tmp_path, capsys, monkeypatch, monitor_result, header, message):
    """A header of another separator, case or measurement: every line was refused for it, one note each, and the
    command ended well (exit 0) having monitored nothing. Now the header is an error on row 1."""
    import io

    result = tmp_path / "r.json"
    result.write_text(json.dumps(monitor_result))
    monkeypatch.setattr("sys.stdin", io.StringIO("\n".join([header] + ["0,0,0,0,0,0,1,2,3"] * 5)))
    assert main(["monitor", str(result), "-", "--json-lines", str(tmp_path / "a.jsonl")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("robocal: error: <stdin>, row 1") and message in err[0], err
    assert not (tmp_path / "a.jsonl").exists()


def test_a_prismatic_joints_zero_and_its_detection_limit_are_in_mm(tmp_path, capsys, monkeypatch):
    """The summary's detection limits gave every joint's zero in deg: a prismatic joint's (mm) read through
    ``degrees``, 57 times too large. Standard input read a prismatic joint's column as degrees: its 0.2 mm change
    became 0.0035 mm, no alarm, the innovations' inflation 66."""
    import io

    from robocal.serial_robot import Robot

    rows = [(0, 400, 300, 0, (-150, 150)), (180, 300, 0, 0, (-140, 140)), (0, 0, 0, 0, (0, 200), False, "prismatic"), (0, 0, 50, 0)]
    robot = Robot.from_dh("scara", rows).with_params(tool_x=20.0, tool_y=10.0, tool_z=30.0)
    data, _ = simulate(robot, "position", samples=400, seed=1)
    result = robocal.calibrate(data, robot=robot).to_dict()
    stream, _ = simulate(robot, "position", samples=400, seed=1, session=1)
    q = stream.q.copy()
    q[300:, 2] -= 0.2  # the prismatic joint read 0.2 mm short from sample 300 on
    monitor, alarms = _replay(result, q, stream.y)
    alarms = [a for a in alarms if not a.provisional]
    assert [(a.kind, a.joint, a.unit) for a in alarms] == [("joint_zero", 3, "mm")], [a.to_dict() for a in alarms]
    assert abs(alarms[0].size[0] - 0.2) < 0.02
    limits = {l["joint"]: l for l in monitor.summary()["detection_limits"] if l["kind"] == "joint_zero"}
    assert limits[3]["unit"] == "mm" and limits[2]["unit"] == "deg"
    assert limits[3]["size"] < alarms[0].size[0] / 1.5 <= alarms[0].evidence * limits[3]["size"], (limits[3], alarms[0].to_dict())
    (tmp_path / "r.json").write_text(json.dumps(result))
    write_canonical(replace(stream, q=q), tmp_path / "s.csv")
    monkeypatch.setattr("sys.stdin", io.StringIO((tmp_path / "s.csv").read_text()))
    assert main(["monitor", str(tmp_path / "r.json"), "-", "--new-session", "--json-lines", str(tmp_path / "a.jsonl")]) == 0
    found = [json.loads(line) for line in (tmp_path / "a.jsonl").read_text().splitlines()]
    assert [(a["kind"], a["joint"]) for a in found if not a["provisional"]] == [("joint_zero", 3)], found
