"""What the final model leaves: noise, or something it does not explain.

"The residuals look like noise" is a claim, and it is tested before it is made: the final
model's residuals against the noise the data show (the repeatability at revisited
configurations, or the floor where it includes the sensor's recorded noise; a residual many
times that is not noise; where the data show no noise of their own, what is left is "not
explained", never "noise": a cause outside the library twice the sensor's noise and uncorrelated
on the path would look the same), for correlation between samples taken one after another (a sensor that
wanders, settling, a cause that follows the path) and between samples taken in similar
configurations far apart in time (a cause of the robot outside the library), and for an error
periodic in one joint's angle at more cycles a turn than the library's harmonics and the joint
maps' knots follow (a gear's tooth mesh, an encoder's cycle: :func:`periodic_leftover`), and
between samples whose readings are alike although their configurations are not (an error of the
sensor itself — a tracker's angle encoders or distance meter, a cable's linearity — follows the
reading, whatever the joints: :func:`sensor_correlation`). Candidates the
selection refused although they would have explained a large share of the error are reported
beside it, with their values and why they were refused: a cause the data show but whose model
robocal rejected is a finding, not noise.
"""

from __future__ import annotations

from typing import Optional

import numpy as np
from scipy.spatial import cKDTree
from scipy.stats import f as f_dist

from ..causes.candidates import MAX_HARMONIC
from ..causes.wander import TIME_TERMS
from ..data.dataset import Dataset
from .wander import MIN_CORRELATION, Z_BOUND, acquisition_rank, residual_correlation, sensor_part, time_inflation, z_score

#: A final RMSE beyond this multiple of the floor is more than the data's resolution.
FLOOR_MULTIPLE = 3.0
#: A refused candidate whose screening gain would have removed this share of the held-out mean
#: square error is reported as an unexplained finding.
LARGE_SHARE = 0.2


def noise_reference(budget: dict) -> tuple[Optional[float], str]:
    """The noise a perfect model would leave, as far as the data show it (mm), and what it is:
    the repeatability measured at revisited configurations, else the floor when it includes the
    sensor's own recorded noise; None when neither is known (a floor of rounding alone says
    nothing of a sensor whose noise is finer than its readings' grid is coarse)."""
    revisits = budget.get("revisits")
    if revisits and revisits.get("repeatability_mm"):
        return float(revisits["repeatability_mm"]), "the repeatability measured at revisited configurations"
    if budget.get("sensor_std_recorded") and budget.get("floor_mm", 0) > 0:
        return float(budget["floor_mm"]), "the floor of the data's resolution and the sensor's recorded noise"
    return None, "no measured noise to compare with (no revisits, no recorded sensor noise)"


#: Harmonics of a joint's angle the leftover scan tries: beyond the library's (up to
#: :data:`~robocal.causes.candidates.MAX_HARMONIC`) up to periods of one degree.
SCAN_HARMONICS = np.arange(MAX_HARMONIC + 1, 361)
#: Harmonics scanned at once (memory: samples × this many values per array).
SCAN_CHUNK = 32
#: A periodic leftover is reported when both its tests, each corrected for every joint and
#: harmonic scanned (Bonferroni), are below this level.
SCAN_LEVEL = 1e-3


def periodic_leftover(q: np.ndarray, weighted: np.ndarray, dh_dq: np.ndarray, inflation: float = 1.0, prismatic=()) -> Optional[dict]:
    """The strongest error periodic in one joint's angle that the residuals still hold.

    ``q`` (m, N) the samples' joint angles, ``weighted`` (m, k) their residuals as the fit weighs
    them, ``dh_dq`` (m·k, N) the measurement's derivatives by each joint angle, weighted alike;
    ``inflation`` the variance inflation of residuals alike in time
    (:func:`~.wander.time_inflation`); ``prismatic`` the joints not scanned (their readings are
    mm: no turn to be periodic in). For every moving revolute joint and harmonic ``h`` of
    :data:`SCAN_HARMONICS`, the error ``a·sin(h·q_j) + b·cos(h·q_j)`` of joint ``j`` is fitted to
    the residuals alone (its columns not projected off the model's: the gain found is at most
    what the full refit would give) and judged by the extra-sum-of-squares F test. Returns the
    best one — joint (1-based), harmonic, amplitude (arcsec), share of the residual sum of squares,
    two p-values corrected for every joint and harmonic tried, and whether both are below
    :data:`SCAN_LEVEL` (``reported``) — or None when nothing was scanned.

    The F test alone asks whether the gain stands out of white residuals; a leftover that is broad
    in a joint's angle (a cause outside the library, a geometry the data barely determine) raises
    the gain of every harmonic alike, and its best one passes that test too (the public D1 file:
    p 2·10⁻⁶ for joint 2's 96th harmonic, no higher than its others). So the best gain is also set
    against the median gain of its joint's harmonics: under a flat spectrum each gain is that
    median times an exponential variable over ln 2, so the ratio ``ρ`` is exceeded with
    probability ``2^-ρ`` (``p_line``, Bonferroni as the F test's). A line of the spectrum passes
    both; a broad leftover only the first."""
    r = weighted.reshape(len(q), -1)
    k = r.shape[1]
    rss, n = float(np.sum(r * r)), r.size
    best = None
    tried = 0
    for j in range(q.shape[1]):
        if np.ptp(q[:, j]) <= 1e-6 or j in prismatic:
            continue
        t = dh_dq[:, j].reshape(len(q), k)
        a, b = np.sum(t * r, axis=1), np.sum(t * t, axis=1)  # per sample: Σ ∂h/∂q·r and Σ (∂h/∂q)²
        v, gss, gsc, gcc = np.zeros((len(SCAN_HARMONICS), 2)), *np.zeros((3, len(SCAN_HARMONICS)))
        for at in range(0, len(SCAN_HARMONICS), SCAN_CHUNK):  # a few harmonics at once: (samples × chunk) arrays
            part = slice(at, at + SCAN_CHUNK)
            phase = np.outer(q[:, j], SCAN_HARMONICS[part])
            s, c = np.sin(phase), np.cos(phase)
            v[part] = np.stack([a @ s, a @ c], axis=1)  # Cᵀr per harmonic
            gss[part], gsc[part], gcc[part] = b @ (s * s), b @ (s * c), b @ (c * c)  # CᵀC per harmonic
        det = gss * gcc - gsc * gsc
        ok = det > 1e-12 * np.maximum(gss * gcc, 1e-300)
        coef = np.where(ok[:, None], np.stack([gcc * v[:, 0] - gsc * v[:, 1], gss * v[:, 1] - gsc * v[:, 0]], axis=1) / np.where(ok, det, 1.0)[:, None], 0.0)
        gains = np.sum(coef * v, axis=1)
        tried += len(SCAN_HARMONICS)
        i = int(np.argmax(gains))
        if best is None or gains[i] > best[0]:
            best = (float(gains[i]), j, int(SCAN_HARMONICS[i]), coef[i], float(np.median(gains)))
    if best is None or rss <= 0:
        return None
    gain, j, h, coef, background = best
    dof = n - 2
    F = (gain / 2.0) / max((rss - gain) / dof, 1e-300) / inflation
    p = float(f_dist.sf(F, 2, max(dof / inflation, 1.0)))
    ratio = gain / max(background, 1e-300)
    p_adjusted, p_line = min(1.0, p * tried), min(1.0, tried * 2.0**-ratio)
    return {
        "joint": j + 1,
        "harmonic": h,
        "amplitude_arcsec": float(np.degrees(np.hypot(*coef)) * 3600.0),
        "share": gain / rss,
        "p_adjusted": p_adjusted,
        "peak_ratio": ratio,
        "p_line": p_line,
        "reported": max(p_adjusted, p_line) < SCAN_LEVEL,
        "tried": tried,
        "test": f"an error a·sin(h·q) + b·cos(h·q) of one joint's angle fitted to the final residuals, harmonics {SCAN_HARMONICS[0]}–{SCAN_HARMONICS[-1]} "
        f"of every moving joint; F test against the residuals, and the gain against its joint's median harmonic (a line, not a broad leftover), "
        f"both Bonferroni over the {tried} tried",
    }


#: Candidates per sample among its nearest readings, of which the nearest far enough apart in
#: joints and in time is kept (one: an error of the sensor may vary over a few millimetres).
READING_CANDIDATES = 64


def sensor_correlation(data: Dataset, idx: np.ndarray, residuals: np.ndarray, correlation: Optional[dict]) -> Optional[dict]:
    """Whether what is left follows the sensor's reading rather than the joints.

    Each of the samples ``idx`` paired with the sample nearest in what the sensor read (the
    measured point, or the cable's length) among those whose configuration lies farther away
    than the typical joint-space neighbour distance of ``correlation``
    (:func:`~.wander.residual_correlation` of the same ``residuals``) and which were taken farther
    apart in time than the residuals' correlation length (if neighbours in time are alike): the
    correlation of the pairs' residuals, against that of the joint-space neighbours. An error of
    the sensor correlates the first pairs, and more than the second; a cause of the robot the
    second more (its pairs are nearer in its own variable). None without the joint-space test or
    with fewer than ten such pairs."""
    if correlation is None or correlation.get("joints") is None:
        return None
    m = len(idx)
    reading = sensor_part(data, data.y[idx])
    q, rank = data.q[idx], acquisition_rank(data, idx)
    reach = np.radians(correlation["joint_distance_deg"]["joint_pairs"])
    # apart in time by more than the residuals' correlation length, if they have one (a wander
    # would correlate them)
    lag = int(np.ceil(correlation.get("correlation_length_samples") or 0))
    dist, near = cKDTree(reading).query(reading, min(m, READING_CANDIDATES))
    joint_d2 = sum((q[near, j] - q[:, j, None]) ** 2 for j in range(q.shape[1]))  # (m, candidates): no (m, candidates, joints) array
    apart = (np.abs(rank[near] - rank[:, None]) > lag) & (joint_d2 > reach**2)
    apart &= np.cumsum(apart, axis=1) <= 1
    si, sj = np.nonzero(apart)[0], near[apart]
    if len(si) < 10:
        return None
    e = sensor_part(data, residuals)
    var = float(np.mean(np.sum(e * e, axis=1)))
    if var <= 0:
        return None
    products = np.sum(e[si] * e[sj], axis=1) / var
    entry = {
        "test": f"residual correlation of each sample with the sample of the nearest reading among those farther apart in joints than the "
        f"typical nearest neighbour ({np.degrees(reach):.3g} deg)"
        + (f" and more than {lag} samples apart in time" if lag else "")
        + ", against the joint-space neighbours'",
        "pairs": int(len(si)),
        "correlation": float(np.mean(products)),
        "z": z_score(products),
        "reading_distance_mm": float(np.median(dist[apart])),
        "joint_distance_deg": float(np.degrees(np.median(np.sqrt(joint_d2[apart])))),
    }
    entry["verdict"] = bool(entry["z"] > Z_BOUND and entry["correlation"] >= MIN_CORRELATION and entry["correlation"] > correlation["joints"]["correlation"])
    return entry


def residual_verdict(
    data: Dataset, idx: np.ndarray, residuals: np.ndarray, rmse: float, budget: dict, weighted: Optional[np.ndarray] = None, dh_dq: Optional[np.ndarray] = None
) -> dict:
    """The tests of the module notes on the final model's ``residuals`` (len(idx), k) of the
    samples ``idx`` whose held-out RMSE is ``rmse`` (mm), with the error ``budget``
    (:func:`~.budget.floor` and its revisits): a report entry with each test, ``noise`` (True
    only if none of them finds anything) and ``findings`` (plain words). With the residuals as
    the fit weighs them (``weighted``) and the derivatives by the joint angles (``dh_dq``), the
    scan for a periodic error of one joint (:func:`periodic_leftover`) too."""
    correlation = residual_correlation(data, idx, residuals)
    sensor = sensor_correlation(data, idx, residuals, correlation)
    periodic = None if weighted is None or dh_dq is None else periodic_leftover(data.q[idx], weighted, dh_dq, time_inflation(correlation), data.prismatic)
    findings = []
    reference, what = noise_reference(budget)
    if reference is not None and rmse > FLOOR_MULTIPLE * reference:
        findings.append(f"the held-out RMSE is {rmse / reference:.3g} times {what} ({reference:.3g} mm)")
    lag1 = None if correlation is None else correlation.get("lag1")
    if lag1 is not None and lag1["z"] > Z_BOUND:
        findings.append(
            f"samples taken one after another are alike (correlation {lag1['correlation']:.2f}, z {lag1['z']:.1f}): correlated in acquisition order"
        )
    joints = None if correlation is None else correlation.get("joints")
    if joints is not None and joints["z"] > Z_BOUND:
        findings.append(
            f"samples in similar configurations far apart in time are alike (correlation {joints['correlation']:.2f}, z {joints['z']:.1f}): "
            "systematic in joint space, a cause of the robot"
        )
    if sensor is not None and sensor["verdict"]:
        findings.append(
            f"samples whose readings are alike ({sensor['reading_distance_mm']:.3g} mm apart) in configurations {sensor['joint_distance_deg']:.3g} deg apart "
            f"are alike (correlation {sensor['correlation']:.2f}, z {sensor['z']:.1f}), more than neighbours in joint space "
            f"({correlation['joints']['correlation']:.2f}): it follows the sensor's reading, not the joints — an error of the sensor or of its frame"
        )
    if periodic is not None and periodic["reported"]:
        findings.append(
            f"joint {periodic['joint']}'s angle carries an error of {periodic['harmonic']} cycles a turn ({periodic['amplitude_arcsec']:.3g} arcsec, "
            f"{periodic['share']:.1%} of the residual sum of squares, {periodic['peak_ratio']:.3g} times its joint's median harmonic; "
            f"p {max(periodic['p_adjusted'], periodic['p_line']):.2g} over {periodic['tried']} tried): finer than the "
            "library's harmonics and the joint maps' knots follow, as a gear's tooth mesh or an encoder's cycle would leave"
        )
    multiple = None if reference is None else float(rmse / reference)
    return {
        # noise only where the data measure their noise: else what is left is "not explained"
        "noise": not findings and reference is not None,
        "unexplained": not findings and reference is None,
        "rmse_mm": float(rmse),
        "findings": findings,
        "periodic": periodic,
        "correlation": correlation,
        "sensor": sensor,
        "noise_reference_mm": reference,
        "noise_reference": what,
        "noise_multiple": multiple,
    }


def unexplained(rejected: list, rmse: Optional[float]) -> list[dict]:
    """The candidates the last screening round refused (``rejected``, screened against a model
    of held-out RMSE ``rmse``) whose gain would have removed at least :data:`LARGE_SHARE` of
    that model's held-out mean square error on every fold scheme (the smallest of their screening
    gains; a time term's on the random folds): label, share, values and why they were refused
    (largest first). Earlier rounds' refusals are left out: a later cause took what they saw."""
    out = []
    baseline_rmse = rmse or 0.0
    for r in rejected:
        # what it explains on every fold scheme (a time term: within the session's stretches)
        gains = r.get("gains_mm") or {}
        gain = gains.get("random") if r.get("kind") in TIME_TERMS else min(gains.values(), default=None)
        if gain is None or not np.isfinite(gain) or baseline_rmse <= 0 or gain <= 0:
            continue
        share = 1.0 - max(baseline_rmse - gain, 0.0) ** 2 / baseline_rmse**2
        if share >= LARGE_SHARE and all(o["label"] != r["label"] for o in out):
            out.append({"label": r["label"], "kind": r["kind"], "share": float(share), "params": r.get("params"), "reason": r.get("reason")})
    return sorted(out, key=lambda o: -o["share"])


def leftover_words(verdict: Optional[dict]) -> Optional[str]:
    """One sentence on what the final model leaves (its ``residuals`` verdict,
    :func:`residual_verdict`: for the command line and the report), or None for a report
    without the tests."""
    if not isinstance(verdict, dict) or not isinstance(verdict.get("findings"), list):
        return None
    periodic = ", nor periodic in one joint's angle" if verdict.get("periodic") is not None else ""
    sensor = ", nor in the sensor's reading" if verdict.get("sensor") is not None else ""
    tried = f"neither correlated in acquisition order nor in joint space{sensor}{periodic}"
    if verdict.get("noise"):
        return f"the residuals look like noise: within {FLOOR_MULTIPLE:g} times {verdict.get('noise_reference')}, and {tried}"
    if not verdict["findings"]:  # nothing found, and no measured noise to call it noise
        return (
            f"not explained: {verdict['rmse_mm']:.3g} mm held out is left, {tried}; but there is {verdict.get('noise_reference')}, "
            "so it is not known to be noise — revisit configurations, or record the sensor's noise, to tell"
        )
    return "not noise: " + "; ".join(str(f) for f in verdict["findings"])
