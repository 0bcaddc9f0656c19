"""The report of a pass (stage 8 of :mod:`.select`): what each cause carries, what the final
model leaves, and the report's ``baseline`` and ``final`` entries.

:func:`describe_causes` completes each cause's entry (uncertainty, share of what is explained),
:func:`final_residuals` measures the error floor and tests what the residuals are,
:func:`baseline_entry` and :func:`final_entry` assemble the JSON entries.
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from ..calibration.result import CalibrationResult
from ..causes import structure
from ..causes.problem import ExtendedProblem, reported_rmse, rotation_rmse_deg
from ..data.dataset import Dataset
from ..stats import robust_sigma
from .budget import floor as error_floor
from .budget import repeatability
from .leftover import residual_verdict
from .state import Pass
from .uncertainty import uncertainty_entries


def describe_causes(state: Pass) -> None:
    """Stage 8, the report: each cause's entry completed with its uncertainty
    (:func:`~.uncertainty.uncertainty_entries`) and its share of what the causes explain
    (:func:`explained_shares`)."""
    described = uncertainty_entries(state.model, state.x, state.model.causes)
    for effect in state.effects:
        effect.update(described.get(effect["label"], {}))
    explained_shares(state.effects, reported_rmse(state.baseline.cv["random"]), reported_rmse(state.cv["random"]))


def explained_shares(effects: list, baseline: float, final: float) -> None:
    """Each found cause's ``share_of_explained``: the held-out mean square error its own step
    removed (``before² − after²``, in the order the causes were found) as a share of all that
    the causes removed from the geometric baseline (``baseline² − final²``). Reading conventions
    act before the baseline and outliers are left out of it: None for them."""
    total = baseline**2 - final**2
    for e in effects:
        inside = e["kind"] not in structure.KINDS and e["kind"] != "outliers" and total > 0
        e["share_of_explained"] = float((e["rmse_heldout_before"] ** 2 - e["rmse_heldout_after"] ** 2) / total) if inside else None


def one_claim_per_joint(effects: list) -> None:
    """The harmonics of one joint, and a joint map beside them, as one entry of ``effects``: the
    map's, else the first harmonic named, with the other harmonics' entries under
    ``with_harmonics`` (their shares of what is explained added to its own). All are the error
    of one joint's angle — a map the part the harmonics do not follow — and one claim of it (a
    clipped sine of a joint was named a harmonic and, beside it, a map or its third harmonic:
    two causes, the mismatch section)."""
    for joint in dict.fromkeys(e["joint"] for e in effects if e["kind"] == "joint_periodic"):
        own = [e for e in effects if e["kind"] in ("joint_map", "joint_periodic") and e["joint"] == joint]
        claim = next((e for e in own if e["kind"] == "joint_map"), own[0])
        others = [e for e in own if e is not claim and e["kind"] == "joint_periodic"]
        if not others:
            continue
        claim["with_harmonics"] = others
        if claim.get("share_of_explained") is not None:
            claim["share_of_explained"] += sum(e.get("share_of_explained") or 0.0 for e in others)
        effects[:] = [e for e in effects if not any(e is o for o in others)]


def final_residuals(state: Pass) -> tuple[dict, dict, np.ndarray]:
    """What the final model leaves: the error budget (:func:`~.budget.floor`, with the
    repeatability at the revisits), the verdict on its residuals
    (:func:`~.leftover.residual_verdict`, with its scan for a periodic error of one joint's
    angle), and every sample's residual, the outliers' too, in
    robust sigmas of the kept samples' residuals."""
    model, x, dataset, keep = state.model, state.x, state.dataset, state.keep
    budget = error_floor(state.robot, dataset.subset(keep), model.full(x))
    r = all_residuals(model, x)
    budget["revisits"] = repeatability(dataset.q[keep], r[keep, :3])
    _, _, parts = model.jacobian_parts(x, [])
    dh_dq = parts["joints"] * model.row_weights[:, None]  # weighted as the fit weighs the residuals
    weighted = r[keep].ravel() * model.row_weights
    leftover = residual_verdict(dataset, keep, r[keep], reported_rmse(state.cv["random"]), budget, weighted=weighted, dh_dq=dh_dq)
    return budget, leftover, r / robust_sigma(r[keep])


def all_residuals(model: ExtendedProblem, x: np.ndarray) -> np.ndarray:
    """Residuals (m, k) of every sample of the dataset, the left-out ones too, under the fitted
    extended ``model``."""
    m = len(model.full_data)
    return model.with_samples(np.arange(m)).data_residuals(x).reshape(m, model.k)


def baseline_entry(state: Pass, *, hayati: bool, folds: int) -> dict:
    """The report's ``baseline``: the geometric fit's held-out and training errors, its
    parameters, the test of its residuals and its implausible parameters."""
    baseline, dataset = state.baseline, state.dataset
    return {
        "rmse_heldout": reported_rmse(baseline.cv["random"]),
        "rmse_heldout_blocked": reported_rmse(baseline.cv["blocked"]),
        "rmse_train": baseline.fit.metrics["train"]["rmse"],
        **rotation_entries(dataset, baseline.cv),
        "n_params": int(len(state.base.free)),
        "hayati": hayati,
        "folds": folds,
        # where the geometric fit's residuals are alike: in acquisition order (a wandering sensor) or in joint space
        "residual_correlation": baseline.residual_test,
        # Kinematic parameters the geometric fit moved beyond 10 mm / 2 deg: the
        # geometry fits the data only with parameters no robot has.
        "implausible": baseline.fit.implausible(),
    }


def final_entry(
    state: Pass,
    final_fit: CalibrationResult,
    prior: Optional[dict],
    unconstrained: float,
    budget: dict,
    leftover: dict,
    found: list,
    structure_unexplained: Optional[dict],
) -> dict:
    """The report's ``final``: the final model's held-out errors (``unconstrained``: without a
    tolerance prior, whose entry is ``prior``) and parameters, the error ``budget``, the share of
    the baseline's error it explains, what its residuals are (``leftover``), and what it leaves
    unexplained: the refused candidates ``found`` to explain much, and a geometry still far
    from any robot (``structure_unexplained``: its entry, or None)."""
    baseline_rmse, rmse = reported_rmse(state.baseline.cv["random"]), reported_rmse(state.cv["random"])
    return {
        "rmse_heldout": rmse,
        "rmse_heldout_blocked": reported_rmse(state.cv["blocked"]),
        "n_params": int(state.model.n),
        **rotation_entries(state.dataset, state.cv),
        "floor_mm": budget["floor_mm"],
        "floor": budget,
        # Share of the baseline's held-out mean square error above the floor that the causes explain.
        "explained": explained(baseline_rmse, rmse, budget["floor_mm"]),
        # The physical model: a tolerance prior where the geometry is undetermined
        # (``tolerance_prior``: its sigmas, or None), and what still lies beyond the limits.
        "tolerance_prior": prior,
        "rmse_heldout_unconstrained": unconstrained,
        "implausible": final_fit.implausible(),
        # Noise or not (tested), and what the selection refused although it would have explained much.
        "structure_unexplained": structure_unexplained,
        "residuals": leftover,
        "unexplained": found,
    }


def rotation_entries(data: Dataset, cv: dict) -> dict:
    """``rotation_rmse_heldout_deg`` (random folds) and ``..._blocked_deg`` of a pose diagnosis'
    held-out errors ``cv``; nothing for other measurements."""
    if data.measurement != "pose":
        return {}
    return {f"rotation_rmse_heldout{'' if name == 'random' else '_' + name}_deg": rotation_rmse_deg(cv[name], data) for name in ("random", "blocked")}


def explained(before: float, after: float, floor: float) -> Optional[float]:
    """``(before² − after²) / (before² − floor²)``: the share of the mean square error above the
    floor that a model removes (None if the baseline is at the floor)."""
    room = before**2 - floor**2
    return None if room <= 0 else float((before**2 - after**2) / room)
