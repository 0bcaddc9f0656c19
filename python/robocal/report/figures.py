"""The report's figures (matplotlib, PNG): per-sample errors before and after calibration,
parameter deviations, the solver's convergence, the identification Jacobian's singular values,
ISO 9283 accuracy per target, and a diagnose report's held-out RMSE per cause and its joint maps.

Each takes plain values (arrays, a result or diagnose document) and a path; the page
(:mod:`robocal.report.page`) and the command line (``robocal diagnose --figures``) place them.
"""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Optional

import numpy as np

from ..calibration.problem import is_kinematic
from ..diagnosis_file import Effect, load_diagnosis
from ..outputs import save_figure
from .text import SHOWN


_DPI = 120


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path) -> Path:
    save_figure(fig, path, dpi=_DPI)
    _pyplot().close(fig)
    return path


def rms(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(e**2)))


def condition_number(s: np.ndarray) -> float:
    return float(s[0] / s[-1]) if s[-1] > 0 else float("inf")


def estimated(doc: dict) -> list[dict]:
    """The estimated joint parameters. Base, tool and sensor parameters are fitted from scratch
    (their nominal values are placeholders), so their "deviation" means nothing and would set the
    scale: they are in the table only."""
    return [p for p in doc["parameters"] if p.get("std") is not None and is_kinematic(p["name"])]


def residual_figures(before: np.ndarray, after: np.ndarray, held_out: Optional[np.ndarray], causes: int, meas: str, out: Path) -> list[Path]:
    """The per-sample errors ``before`` and ``after`` calibration (mm; ``after`` with ``causes``
    joint causes) as histograms and along the samples, ``held_out`` samples marked: two PNGs."""
    plt = _pyplot()
    what = {"cable": "|cable length residual|", "position": "position error", "pose": "position error (of the pose)"}[meas]
    colours = {"before": "tab:orange", "after": "tab:blue"}
    errors = {"before": before, "after": after}
    labels = {
        "before": "before: nominal kinematics",
        "after": "after: calibrated" + (f" with its {causes} joint cause{'s' if causes > 1 else ''}" if causes else ""),
    }

    # (a) Histograms on log-spaced bins: before and after often differ by orders of magnitude.
    positive = np.concatenate([e[e > 0] for e in errors.values()])
    lo = float(positive.min()) if positive.size else 1e-6
    hi = float(max(e.max() for e in errors.values()))
    hi = max(hi, lo * 10)
    bins = np.geomspace(lo, hi * 1.0001, 45)
    fig, ax = plt.subplots(figsize=(7.0, 4.0))
    for key in ("before", "after"):
        e = np.clip(errors[key], lo, None)
        ax.hist(e, bins=bins, color=colours[key], alpha=0.55, label=f"{labels[key]} (RMSE {rms(errors[key]):.4g} mm)")
        ax.axvline(rms(errors[key]), color=colours[key], lw=1.5, ls="--")
    ax.set_xscale("log")
    ax.set(xlabel=f"per-sample {what} (mm, log scale)", ylabel="samples", title=f"Per-sample error before and after calibration ({len(after)} samples)")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.17), ncol=2, fontsize=8, frameon=False, title="dashed lines: RMSE", title_fontsize=8)
    fig.tight_layout()
    paths = [_save(fig, out / "residuals_histogram.png")]

    # (b) Along the samples (file order), held-out samples marked.
    idx = np.arange(len(after))
    fig, ax = plt.subplots(figsize=(7.0, 4.0))
    small, cross = (6, 22) if len(idx) <= 500 else (4, 12)
    held = held_out if held_out is not None else np.zeros(len(idx), dtype=bool)
    for key in ("before", "after"):
        e = np.clip(errors[key], lo, None)
        name = key
        ax.scatter(idx[~held], e[~held], s=small, color=colours[key], alpha=0.6, lw=0, label=f"{name}, training" if held.any() else name)
        if held.any():
            ax.scatter(idx[held], e[held], s=cross, marker="x", color=colours[key], lw=1.0, label=f"{name}, held out")
    ax.set_yscale("log")
    ax.set_xlim(-0.01 * len(idx), 1.01 * len(idx))
    ax.set(xlabel="sample (order in the measurement file)", ylabel=f"{what} (mm, log scale)", title="Per-sample error along the acquisition")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.17), ncol=4, fontsize=8, frameon=False, markerscale=1.5)
    fig.tight_layout()
    paths.append(_save(fig, out / "residuals_samples.png"))
    return paths


def parameter_figure(doc: dict, out: Path) -> Optional[Path]:
    groups = []
    for unit, title in (("mm", "joint lengths"), ("rad", "joint angles")):
        ps = [p for p in estimated(doc) if p["unit"] == unit]
        if ps:
            shown, factor = SHOWN[unit]
            dev = np.array([(p["value"] - p["nominal"]) * factor for p in ps])
            err = np.array([2.0 * p["std"] * factor for p in ps])
            groups.append((title, shown, [p["name"] for p in ps], dev, err))
    if not groups:
        return None
    plt = _pyplot()
    heights = [max(len(g[2]), 2) + 1.6 for g in groups]
    fig, axes = plt.subplots(len(groups), 1, figsize=(7.0, 0.22 * sum(heights) + 0.6), gridspec_kw={"height_ratios": heights}, squeeze=False)
    for ax, (title, unit, names, dev, err) in zip(axes[:, 0], groups):
        y = np.arange(len(names))[::-1]
        colour = np.where(np.abs(dev) > err, "tab:red", "tab:blue")
        ax.barh(y, dev, color=colour, alpha=0.7, height=0.7)
        ax.errorbar(dev, y, xerr=err, fmt="none", ecolor="k", elinewidth=0.9, capsize=2.5)
        ax.axvline(0.0, color="k", lw=0.8)
        ax.set_yticks(y, names, fontsize=9)
        ax.set_ylim(-0.7, len(names) - 0.3)
        size = np.abs(dev)
        scale = ""
        typical = float(np.median(size))
        if size.max() > 50 * max(typical, 1e-12):
            # Deviations spanning decades (one parameter 1000 mm off beside 0.1 mm ones): a
            # linear axis would show one bar.
            linthresh = 10.0 ** np.floor(np.log10(max(typical, 1e-12)))
            ax.set_xscale("symlog", linthresh=linthresh, linscale=1.0)
            scale = f"; symmetric log scale, linear within ±{linthresh:g}"
            # Each side to the decade above its largest deviation: no empty decades.
            lo = -(10.0 ** np.ceil(np.log10(max(-dev.min(), linthresh) * 1.05)))
            hi = 10.0 ** np.ceil(np.log10(max(dev.max(), linthresh) * 1.05))
        else:
            # Deviations set the scale; an error bar much longer than the largest deviation
            # runs off it, labelled.
            reach = np.minimum(size + err, 1.5 * size.max())
            hi = 1.08 * max(size.max(), float(reach.max()), float(np.median(err)), 1e-12)
            lo = -hi
        ax.set_xlim(lo, hi)
        for yi, d, e in zip(y, dev, err):
            if d - e < lo or d + e > hi:
                right = d < 0  # on the side the bar leaves free
                x, align = (0.99, "right") if right else (0.01, "left")
                box = {"fc": "white", "ec": "none", "pad": 0.5, "alpha": 0.85}
                label = f"±{e:.3g} {unit}, off scale"
                ax.text(x, yi, label, transform=ax.get_yaxis_transform(), ha=align, va="center", fontsize=7, color="0.25", bbox=box)
        ax.grid(axis="x", alpha=0.3)
        ax.set_xlabel(f"calibrated − nominal ({unit}{scale})", fontsize=9)
        ax.set_title(f"{title} ({len(names)} estimated): deviation ± 2 std (red: beyond 2 std)", fontsize=10)
    fig.tight_layout()
    return _save(fig, out / "parameters.png")


def convergence_figure(doc: dict, out: Path) -> Optional[Path]:
    conv = doc.get("convergence") or {}
    history = np.asarray([c for c in conv.get("history") or [] if c is not None], dtype=np.float64)
    history = history[np.isfinite(history)]
    if history.size == 0:
        return None
    plt = _pyplot()
    positive = history[history > 0]
    floor = positive.min() * 1e-3 if positive.size else 1e-300
    fig, ax = plt.subplots(figsize=(7.0, 3.6))
    ax.plot(np.arange(history.size), np.maximum(history, floor), "o-", color="tab:blue", ms=4 if history.size < 60 else 0, lw=1.3)
    ax.set_yscale("log")
    ax.grid(alpha=0.3, which="both")
    ax.set_xlim(-0.5, max(history.size - 0.5, 1.5))
    if history.size < 15:
        ax.set_xticks(np.arange(history.size))
    status = "converged" if conv.get("success") else "did not converge"
    title = f"{doc.get('method', '')}: {status} after {conv.get('nit', history.size - 1)} iterations, final cost {history[-1]:.4g}"
    ax.set(xlabel="iteration (0: start)", ylabel="cost ½‖r‖² (mm², log scale)", title=title)
    fig.tight_layout()
    return _save(fig, out / "convergence.png")


def identifiability_figure(s: Optional[np.ndarray], n_cols: int, out: Path) -> Optional[Path]:
    """The singular values ``s`` of the column-scaled identification Jacobian (``n_cols``
    parameters) on a log scale, with its condition number; None without any."""
    if s is None or s.size == 0:
        return None
    plt = _pyplot()
    floor = s[0] * 1e-16
    fig, ax = plt.subplots(figsize=(7.0, 3.6))
    k = np.arange(1, s.size + 1)
    ax.semilogy(k, np.maximum(s, floor), "o-", color="tab:purple", ms=4, lw=1.0)
    ax.axhline(s[0] * 1e-3, color="0.5", ls=":", lw=1, label="σ₁ / 1000")
    ax.grid(alpha=0.3, which="both")
    ax.set_xticks(k if s.size <= 40 else k[::5])
    ax.tick_params(axis="x", labelsize=8)
    ax.legend(loc="lower left", fontsize=8)
    title = f"Column-scaled identification Jacobian ({n_cols} parameters): condition number {condition_number(s):.4g}"
    ax.set(xlabel="singular value index", ylabel="singular value (log scale)", title=title)
    ax.title.set_fontsize(10)
    fig.tight_layout()
    return _save(fig, out / "identifiability.png")


def acceptance_figure(figures: dict, maps: bool, out: Path) -> Path:
    """Position (or cable length) accuracy per target, coloured by whether the joint maps cover it."""
    plt = _pyplot()
    t = figures["targets"]
    error, covered = np.asarray(t["position_error_mm"]), np.asarray(t["covered"])
    idx = np.arange(error.size)
    fig, ax = plt.subplots(figsize=(7.0, 3.8), layout="constrained")
    size = 10 if error.size <= 500 else 4
    if maps:
        ax.scatter(idx[covered], error[covered], s=size, color="tab:blue", lw=0, label="within every joint map's range")
        ax.scatter(idx[~covered], error[~covered], s=size * 2, color="tab:red", marker="x", lw=1.0, label="beyond a joint map's range (not corrected)")
    else:
        ax.scatter(idx, error, s=size, color="tab:blue", lw=0, label="target (no joint map in the model)")
    ax.axhline(figures["position_accuracy_mm"]["rms"], color="tab:blue", ls="--", lw=1.0, label="RMS over the targets")
    if figures["repeatability_mm"] is not None:
        ax.axhline(figures["repeatability_mm"]["rp"], color="0.3", ls=":", lw=1.2, label="repeatability RP")
    what = "length" if figures["measurement"] == "cable" else "position"
    ax.set(xlabel="target (order of its first sample)", ylabel=f"{what} accuracy AP (mm)", ylim=(0, None))
    ax.set_title(f"ISO 9283 {what} accuracy per target ({error.size} targets)", fontsize=10)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.18), ncol=2, fontsize=8, frameon=False)
    return _save(fig, out / "acceptance.png")


def _diagnosis_steps(report) -> list[tuple[str, float]]:
    report = load_diagnosis(report).needs_figures("the held-out RMSE figure")
    steps = []
    outliers = [e for e in report.effects if e.kind == "outliers"]
    if outliers and outliers[0].rmse_heldout_before is not None:
        steps.append(("geometric, outliers kept", outliers[0].rmse_heldout_before))
    steps.append(("geometric baseline" + (" (outliers removed)" if steps else ""), report.baseline.held_out(report.several)))
    for e in report.effects:
        if e.kind != "outliers":
            steps.append((f"+ {e.label}", e.rmse_after))
    return steps


def diagnosis_figure(report, path: Path) -> Path:
    """A bar chart of the held-out RMSE of a diagnose report (one session or several; typed, or
    its document: :func:`robocal.load_diagnosis`) as its causes are added, written to ``path``."""
    plt = _pyplot()
    report = load_diagnosis(report).needs_figures("the held-out RMSE figure")
    steps = _diagnosis_steps(report)
    names, rmse = [s[0] for s in steps], np.array([s[1] for s in steps])
    # Constrained layout and a figure title: long cause labels push the axes right, and a title
    # centred on them would run off the figure's right edge.
    fig, ax = plt.subplots(figsize=(7.0, 0.45 * len(steps) + 1.7), layout="constrained")
    y = np.arange(len(steps))[::-1]
    ax.barh(y, rmse, color=["0.6" if n.endswith("outliers kept") else "tab:blue" for n in names], height=0.6)
    for i, (yi, v) in enumerate(zip(y, rmse)):
        change = f" ({(v - rmse[i - 1]) / rmse[i - 1]:+.1%})" if i > 0 and rmse[i - 1] > 0 else ""
        ax.text(v, yi, f" {v:.4g} mm{change}", va="center", fontsize=8)
    ax.set_yticks(y, [textwrap.fill(n, 34) for n in names], fontsize=9)
    ax.set_xlim(0, rmse.max() * 1.3)
    folds = report.baseline.folds
    how = ", leave-one-session-out" if report.several else (f", {folds}-fold cross-validation" if folds else "")
    ax.set(xlabel=f"held-out RMSE (mm){how}")
    fig.suptitle("Held-out error as the diagnosed causes are added", fontsize=11)
    return _save(fig, Path(path))


def map_figure(effect: Effect, path: Path) -> Path:
    """A joint map of a diagnose report (an effect with a ``curve``): the correction of the
    joint's angle against its reading, with its ±2 std band, written to ``path``."""
    plt = _pyplot()
    curve = effect.curve
    angle, value = np.asarray(curve.angle_deg), np.asarray(curve.value_deg) * 3600.0
    band = 2.0 * np.asarray(curve.std_deg if curve.std_deg is not None else np.zeros(len(angle))) * 3600.0
    # the curve leaves out the gaps of the map's data (it corrects nothing there): break the line
    steps = np.diff(angle)
    breaks = np.flatnonzero(steps > 1.5 * np.median(steps)) + 1 if len(steps) else []
    angle, value, band = (np.insert(a, breaks, np.nan) for a in (angle, value, band))
    fig, ax = plt.subplots(figsize=(7.0, 3.4))
    if curve.std_deg is not None:
        ax.fill_between(angle, value - band, value + band, color="tab:blue", alpha=0.25, lw=0, label="±2 std")
    ax.plot(angle, value, color="tab:blue", lw=1.2, label="map")
    ax.axhline(0.0, color="0.5", lw=0.6)
    ax.set(xlabel=f"joint {effect.joint} reading (deg)", ylabel="correction (arcsec)", title=effect.label)
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    return _save(fig, Path(path))
