"""What the final model leaves: noise, or something it does not explain.

"The residuals look like noise" is a claim, and it is tested before it is made: the final
model's residuals against the noise the data show (the repeatability at revisited
configurations, or the floor where it includes the sensor's recorded noise; a residual many
times that is not noise), for correlation between samples taken one after another (a sensor that
wanders, settling, a cause that follows the path) and between samples taken in similar
configurations far apart in time (a cause of the robot outside the library). Candidates the
selection refused although they would have explained a large share of the error are reported
beside it, with their values and why they were refused: a cause the data show but whose model
robocal rejected is a finding, not noise.
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from ..causes.wander import TIME_TERMS
from ..data.dataset import Dataset
from .wander import Z_BOUND, residual_correlation

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


def residual_verdict(data: Dataset, idx: np.ndarray, residuals: np.ndarray, rmse: float, budget: dict) -> dict:
    """The tests of the module notes on the final model's ``residuals`` (len(idx), k) of the
    samples ``idx`` whose held-out RMSE is ``rmse`` (mm), with the error ``budget``
    (:func:`~.budget.floor` and its revisits): a report entry with each test, ``noise`` (True
    only if none of them finds anything) and ``findings`` (plain words)."""
    correlation = residual_correlation(data, idx, residuals)
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
    multiple = None if reference is None else float(rmse / reference)
    return {
        "noise": not findings,
        "findings": findings,
        "correlation": correlation,
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
    if verdict.get("noise"):
        near = "near the measured noise, and " if verdict.get("noise_multiple") is not None else ""
        return f"the residuals look like noise: {near}neither correlated in acquisition order nor in joint space"
    return "not noise: " + "; ".join(str(f) for f in verdict["findings"])
