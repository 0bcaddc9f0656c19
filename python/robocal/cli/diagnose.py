"""``robocal diagnose``: the report (JSON, text summary, figures) of :func:`robocal.diagnose`."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Optional

import numpy as np

from ..calibration.result import describe_implausible, implausible_meaning
from ..diagnosis import diagnose
from ..diagnosis.leftover import leftover_words
from ..diagnosis_file import Effect, Figures, Quantity, load_diagnosis
from ..outputs import make_folder, printable, save_figure, write_text
from ..report.figures import diagnosis_figure, map_figure
from ..report.text import alike_words, correlation_words, map_tables, settling_words
from .arguments import add_data_arguments, files_angle_unit


def _quantities(params: Optional[dict]) -> str:
    shown = []
    for name, q in (params or {}).items():
        if isinstance(q, Quantity) and q.value is not None and np.isfinite(q.value):
            sd = f" ± {q.std:.2g}" if q.std is not None else ""
            unit = "" if q.unit == "1" else q.unit  # a pure number: "sign -1", not "sign -1 1"
            shown.append(f"{name} {q.value:.4g}{sd} {unit}".rstrip())
        elif isinstance(q, list):
            shown.append(f"{name} {q[:8]}{' ...' if len(q) > 8 else ''}")
    return ", ".join(shown)


def _implausible(flags: list) -> str:
    return describe_implausible([flag.model_dump() for flag in flags])


def summary(report) -> str:
    """A few lines for the terminal (a report on one session: typed, or its document)."""
    report = load_diagnosis(report).needs_figures("the summary")
    b, f = report.baseline, report.final
    lines = [
        f"{printable(report.robot, one_line=True)}, {report.measurement} data, {report.samples} samples: geometric baseline "
        f"({b.n_params} parameters) held-out RMSE {b.rmse_heldout:.4f} mm (blocked {b.rmse_heldout_blocked:.4f} mm)"
    ]
    if b.implausible:
        lines.append("  warning: geometric baseline: " + _implausible(b.implausible))
    if not report.effects:
        lines.append("  no cause beyond the geometric model is significant")
    for e in report.effects:
        where = f" joint {e.joint}" if e.joint is not None else ""
        lines.append(
            f"  + {e.kind}{where}: {_quantities(e.params)}{correlation_words(e.correlation)}{alike_words(e.significance)}{settling_words(e.after_long_moves)}"
            + "".join(f", beside its {h.label} ({_quantities(h.params)})" for h in e.with_harmonics)
            + "; "
            f"held-out RMSE {e.rmse_heldout_before:.4f} -> {e.rmse_heldout_after:.4f} mm"
            + (f" ({e.share_of_explained:.0%} of what the causes explain)" if e.share_of_explained is not None else "")
        )
    lines.append(f"  final held-out RMSE {f.rmse_heldout:.4f} mm (blocked {f.rmse_heldout_blocked:.4f} mm), {f.n_params} parameters")
    if f.rotation_rmse_heldout_deg is not None:
        lines.append(
            f"  held-out orientation RMS {b.rotation_rmse_heldout_deg:.4f} -> {f.rotation_rmse_heldout_deg:.4f} deg "
            f"(blocked {b.rotation_rmse_heldout_blocked_deg:.4f} -> {f.rotation_rmse_heldout_blocked_deg:.4f} deg)"
        )
    lines += _physical_lines(f, several=False)
    floor = f.floor if f.floor_mm is not None else None
    if floor is not None:
        lines.append(
            f"  error floor from the data's own resolution {f.floor_mm:.4f} mm "
            f"(joints {floor.joints_mm:.4f}, sensor {floor.sensor_mm:.4f} mm; "
            f"{floor.note}): {max(f.rmse_heldout - f.floor_mm, 0.0):.4f} mm above it"
        )
    if floor is not None and (revisits := floor.revisits):
        lines.append(
            f"  measured at {revisits.pairs} revisits of a joint configuration: one reading's repeatability {revisits.repeatability_mm:.4f} mm; "
            f"what the final model still gets wrong there, beyond that noise, at least {revisits.systematic_mm:.4f} mm"
        )
    if report.effects and f.explained is not None:
        lines.append(f"  the causes explain {f.explained:.0%} of the baseline's held-out mean square error above that floor")
    if f.structure_unexplained:
        lines.append(f"  structure unexplained: {f.structure_unexplained.get('note')}")
    if words := leftover_words(f.residuals):
        lines.append(f"  what is left: {words}")
    for u in f.unexplained:
        lines.append(
            f"  unexplained finding: {u.label} would explain {u.share:.0%} of the held-out mean square error left "
            f"({_quantities(u.params)}); refused: {u.reason}"
        )
    for r in report.rejected[:3]:
        gain = "" if r.gain_mm is None else f"gain {r.gain_mm:.2g} mm, "  # none for a cause put in another's place
        lines.append(f"  rejected {r.label}: {gain}{r.reason}")
    return "\n".join(lines)


def _physical_lines(final: Figures, several: bool) -> list[str]:
    """The final model's tolerance prior (kept or why not) and its implausible parameters."""
    lines, prior = [], final.tolerance_prior
    if prior and prior.accepted:
        lines.append(
            f"  physical model: the geometry held near nominal by a tolerance prior (±{prior.sigma_mm:g} mm, ±{prior.sigma_deg:g} deg) "
            f"where the data leave it undetermined; unconstrained held-out RMSE {final.unconstrained(several):.4f} mm"
        )
    elif prior:
        lines.append(f"  no physical model: a tolerance prior (±{prior.sigma_mm:g} mm, ±{prior.sigma_deg:g} deg) was tried; {prior.reason}")
    if final.implausible:
        flags = [flag.model_dump() for flag in final.implausible]
        lines.append("  warning: final model: " + describe_implausible(flags, meaning=implausible_meaning(prior)))
    return lines


def _origin(entry: Effect) -> str:
    """Where a multi-session candidate came from: sessions whose own diagnosis found it, or the
    robot's mass model (gravity compliance is always judged)."""
    return f"found in sessions {entry.found_in_sessions}" if entry.found_in_sessions else "from the mass model"


def _judged(entry: Effect) -> str:
    """Pose data: what the selection compared (position and orientation weighed as in the fit),
    beside the position's error a cause may raise while it lowers the orientation's."""
    if entry.rmse_loso_judged_after is None:
        return ""
    return f"; position and orientation weighed as in the fit {entry.rmse_loso_judged_before:.4f} -> {entry.rmse_loso_judged_after:.4f} mm"


def sessions_summary(report) -> str:
    """A few lines for the terminal on a multi-session report (typed, or its document)."""
    report = load_diagnosis(report).needs_figures("the summary")
    b, f, model = report.baseline, report.final, report.needs_model()
    rmse = lambda values: " / ".join(f"{v:.4f}" for v in values)  # noqa: E731
    lines = [f"{printable(report.robot, one_line=True)}, {report.measurement} data, {len(report.sessions)} sessions:"]
    for i, s in enumerate(report.sessions, start=1):
        own = [e.label for e in s.diagnosis.effects] if s.diagnosis is not None else []
        lines.append(f"  session {i} ({s.source or 'data'}, {s.samples} samples) on its own: " + ("; ".join(own) if own else "nothing beyond the geometry"))
    lines.append(f"  geometric model, leave-one-session-out RMSE {b.rmse_loso:.4f} mm (per session {rmse(b.per_session)})")
    if b.implausible:
        lines.append("  warning: geometric model on all sessions: " + _implausible(b.implausible))
    for e in report.effects:
        lines.append(
            f"  + {e.label} ({_origin(e)}): {_quantities(e.params)}{correlation_words(e.correlation)}; held-out "
            f"{e.rmse_loso_before:.4f} -> {e.rmse_loso_after:.4f} mm (per session {rmse(e.per_session_after)})" + _judged(e)
        )
    for r in report.rejected:
        lines.append(f"  not carried: {r.label} ({_origin(r)}): {r.reason}")
    for i, s in enumerate(model.sessions or [], start=1):
        if s.causes:
            lines.append(f"  session {i} keeps its own: {'; '.join(s.causes)}")
    judged = "" if f.rmse_loso_judged is None else f"; position and orientation weighed as in the fit {f.rmse_loso_judged:.4f} mm"
    lines.append(f"  final leave-one-session-out RMSE {f.rmse_loso:.4f} mm (per session {rmse(f.per_session)}){judged}")
    if f.rotation_rmse_loso_deg is not None:
        lines.append(
            f"  held-out orientation RMS {b.rotation_rmse_loso_deg:.4f} -> {f.rotation_rmse_loso_deg:.4f} deg "
            f"(per session {' / '.join(f'{v:.4f}' for v in f.rotation_per_session_deg)})"
        )
    covered = f.per_session_covered
    if covered and any(c.startswith("joint_map") for c in model.causes):
        parts = [f"{c.rmse:.4f} mm on {c.samples}" if c.rmse is not None else "none covered" for c in covered]
        lines.append(f"  where the joint maps fitted on the other sessions apply: {', '.join(parts)} samples")
    lines += _physical_lines(f, several=True)
    return "\n".join(lines)


def write_figures(diagnosis, out: Path) -> list[Path]:
    """One PNG per accepted cause of a single-session diagnosis (residual against the cause's
    fitted signature), one per joint map (its curve and band, and its table as
    ``map_joint<j>.csv``) and one of the held-out RMSE along the selection (for several
    sessions, leave-one-session-out: that one only)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    make_folder(out)
    paths = []
    for i, (label, d) in enumerate(getattr(diagnosis, "plots", {}).items(), start=1):
        fig, ax = plt.subplots(figsize=(5.5, 4.5))
        sig, res = d["signature"], d["residual"]
        ax.scatter(sig, res, s=4, alpha=0.25, color="0.6", label="residual components")
        # Binned means show the cause through the noise: on the diagonal if it explains them.
        edges = np.unique(np.quantile(sig, np.linspace(0.0, 1.0, 16)))
        which = np.clip(np.digitize(sig, edges[1:-1]), 0, len(edges) - 2)
        bins = [b for b in range(len(edges) - 1) if np.sum(which == b) > 1]
        centre = [sig[which == b].mean() for b in bins]
        mean = [res[which == b].mean() for b in bins]
        err = [res[which == b].std(ddof=1) / np.sqrt(np.sum(which == b)) for b in bins]
        ax.errorbar(centre, mean, yerr=err, fmt="o", color="tab:red", ms=4, label="binned mean ± s.e.")
        lo, hi = float(sig.min()), float(sig.max())
        ax.plot([lo, hi], [lo, hi], "k--", lw=1, label="residual = signature")
        spread = np.quantile(np.abs(res), 0.99)
        ax.set_ylim(-1.1 * spread, 1.1 * spread)
        ax.set(xlabel="fitted signature of the cause (mm)", ylabel="residual before the cause (mm)", title=label)
        ax.legend(loc="upper left", fontsize=8)
        fig.tight_layout()
        path = save_figure(fig, out / f"cause_{i}.png", dpi=120)
        plt.close(fig)
        paths.append(path)
    report = load_diagnosis(diagnosis.to_dict())
    for e in report.effects:
        if e.kind == "joint_map" and e.curve is not None:
            paths.append(map_figure(e, Path(out) / f"map_joint{e.joint}.png"))
    for name, text in map_tables(report):
        write_text(Path(out) / name, text)
    return paths + [diagnosis_figure(report, Path(out) / "heldout_rmse.png")]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_data_arguments(parser, sessions=True)
    parser.add_argument("--folds", type=int, default=5, help="folds of the random and the blocked cross-validation (default 5)")
    parser.add_argument("--alpha", type=float, default=0.05, help="family-wise significance level per selection round (default 0.05)")
    parser.add_argument("--plain-dh", action="store_true", help="baseline without Hayati beta (makes axis_misalignment a candidate)")
    parser.add_argument("--no-maps", action="store_true", help="do not try joint error maps after the named causes")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", metavar="FILE", help="write the JSON report here ('-' for standard output)")
    parser.add_argument("--out", metavar="DIR", help="write report.json and the figures to this folder")


def run(args: argparse.Namespace) -> int:
    d = diagnose(
        args.data[0] if len(args.data) == 1 else args.data,
        robot=args.robot,
        measurement=args.measurement,
        folds=args.folds,
        alpha=args.alpha,
        hayati=not args.plain_dh,
        seed=args.seed,
        angle_unit=files_angle_unit(args),
        maps=not args.no_maps,
    )
    report = d.to_dict()
    text = json.dumps(report, indent=2)
    if args.json == "-":
        print(text)
    else:
        print(summary(report) if len(args.data) == 1 else sessions_summary(report))
        if args.json:
            write_text(args.json, text)
    if args.out:
        out = make_folder(args.out)
        write_text(out / "report.json", text)
        paths = write_figures(d, out)
        if args.json != "-":
            print(f"  wrote report.json and {len(paths)} figures to {out}")
    return 0
