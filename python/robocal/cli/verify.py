"""``robocal verify``: :func:`robocal.verify` of a result file on new measurements, a summary or the JSON report."""

from __future__ import annotations

import argparse
import json

from ..acceptance import summary_rows
from ..causes.candidates import uncovered_words
from ..outputs import printable, write_text
from ..verification import verify
from .arguments import add_angle_unit_argument


def summary(report: dict) -> str:
    m, n = report["metrics"], report["nominal"]["metrics"]
    applied = report["applied"]["structure"] + report["applied"]["causes"]
    lines = [
        f"verdict: {report['verdict']['verdict']}: {report['verdict']['why']}",
        f"{printable(report['robot'], one_line=True)} on {report['samples']} {'new ' if report.get('held_out', True) else ''}{report['measurement']} samples "
        f"({report['data'] or 'data'}), "
        f"session set-up re-fitted ({', '.join(report['refit'])}):",
        f"  calibrated: RMSE {m['rmse']:.4f}  MAE {m['mae']:.4f}  MAX {m['max']:.4f} mm",
        f"  nominal:    RMSE {n['rmse']:.4f}  MAE {n['mae']:.4f}  MAX {n['max']:.4f} mm",
    ]
    lines += [f"  note: {note}" for note in report.get("notes", [])]
    if applied:
        lines.append("  applied: " + "; ".join(applied))
    for item in report["not_applied"]:
        lines.append(f"  not applied: {item['label']} ({item['reason']})")
    covered = report.get("metrics_covered")
    if covered is not None and covered["n"] < m["n"]:
        lines.append(
            f"  within the maps' ranges ({covered['n']} of {m['n']} samples): calibrated RMSE {covered['rmse']:.4f}, "
            f"nominal {report['nominal']['metrics_covered']['rmse']:.4f} mm"
        )
    for c in report.get("coverage", []):
        if c["outside"]:
            lines.append(
                f"  beyond its map's data: {c['outside']} samples have joint {c['joint']} {uncovered_words(c)} "
                f"(its fit had no data there: its correction fades out within a few knot spacings; first rows {c['rows'][:5]})"
            )
    iso = report.get("iso9283")
    if iso is not None:
        lines.append(f"  ISO 9283 ({iso['n_targets']} targets, {iso['n_measurements']} measurements; command = the calibrated model's prediction):")
        rows = summary_rows(iso)
        width = max(len(name) for name, _ in rows)
        lines += [f"    {name:<{width}}  {value}" for name, value in rows]
    if "rotation_rmse_deg" in m:
        lines.insert(3, f"  orientation: calibrated RMS {m['rotation_rmse_deg']:.4f} deg, nominal {n['rotation_rmse_deg']:.4f} deg")
    return "\n".join(lines)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("result", help="a result file of robocal calibrate (--out)")
    parser.add_argument("data", help="new measurements of the same robot (canonical CSV or a public dataset)")
    parser.add_argument("--measurement", choices=["cable", "position", "pose"], help="default: the result's")
    add_angle_unit_argument(parser)
    parser.add_argument("--json", metavar="FILE", help="write the JSON report here ('-' for standard output)")


def run(args: argparse.Namespace) -> int:
    report = verify(args.result, args.data, measurement=args.measurement, angle_unit=args.angle_unit)
    text = json.dumps(report, indent=2)
    if args.json == "-":
        print(text)
        return 0
    print(summary(report))
    if args.json:
        write_text(args.json, text + "\n")
        print(f"  report written to {args.json}")
    return 0
