"""``robocal inspect``: the validation report of a measurement file (:mod:`robocal.inspection`)
for humans, or as JSON."""

from __future__ import annotations

import json

from ..data.loader import FORMATS
from ..inspection import OUTLIER_SIGMAS, inspect
from ..outputs import printable, write_json


def _first(items: list, limit: int) -> list:
    return items[:limit] if limit else items


def _column(cell: dict) -> str:
    """``", column 'q3'"``, or nothing for a finding about a whole row (its cell count, or only empty cells)."""
    return "" if cell["column"] is None else f", column {cell['column']!r}"


def format_report(report: dict, limit: int = 20) -> str:
    """The report as text for humans, at most ``limit`` entries per list (0: all)."""
    lines = [
        f"{report['source'] or 'dataset'}: {report['rows']} {report['measurement']} samples"
        + (f" ({report['format']} format)" if report["format"] else "")
        + f", robot {printable(report['robot'] or 'not given', one_line=True)}"
    ]
    lines += [f"  note: {n}" for n in report["notes"]]
    lines.append(f"  bad cells: {len(report['bad_cells'])}")
    lines += [f"    row {e['row']}{_column(e)}: {e['reason']}" for e in _first(report["bad_cells"], limit)]
    lines.append(f"  duplicate rows: {len(report['duplicates'])} groups")
    lines += [f"    rows {g}" for g in _first(report["duplicates"], limit)]
    lines.append(f"  angle unit: {report['angle_unit']['message']}")
    lines.append(f"  outside joint limits: {len(report['out_of_limits'])}")
    lines += [
        f"    row {e['row']}, q{e['joint']} = {e['value']:.3f} {e['unit']} (limits {e['limits'][0]:g}..{e['limits'][1]:g})"
        for e in _first(report["out_of_limits"], limit)
    ]
    fit = report["fit"]
    if fit and "error" in fit:
        lines.append(f"  robust nominal-model fit not possible: {fit['error']}")
        fit = None
    if fit:
        scale = ", ".join(f"{k} {v:.4g}" for k, v in fit["scale"].items())
        lines.append(f"  robust nominal-model fit ({', '.join(fit['fitted'])}): robust sigma {scale}; inlier rms {fit['rms_mm']:.4g} mm")
        if fit["not_identifiable"]:
            lines.append(f"    not identifiable from these data, held at nominal: {fit['not_identifiable']}")
        lines.append(f"  outliers beyond {fit['threshold']:g} sigma: {len(fit['outliers'])}")
        lines += [
            f"    row {e['row']}: residual {e['residual_mm']:.3f} mm"
            + (f", {e['rotation_deg']:.4f} deg" if "rotation_deg" in e else "")
            + f" ({e['sigmas']:.1f} sigma)"
            for e in _first(fit["outliers"], limit)
        ]
    if report["another_robot"]:
        lines.append(f"  another robot? {report['another_robot']}")
    check = report["cross_check"]
    if check:
        lines.append(
            f"  controller x,y,z vs FK(q): median {check['median_mm']:.3f} mm; {len(check['inconsistent'])} of {check['rows_checked']} rows beyond rounding"
        )
        lines += [
            f"    row {e['row']}: FK - controller = {e['difference_mm']} mm (|.| {e['norm_mm']:.2f}; bound {e['bound_mm']}, {e['ratio']:.1f}x)"
            for e in _first(check["inconsistent"], limit)
        ]
    lists = [report["bad_cells"], report["duplicates"], report["out_of_limits"], fit["outliers"] if fit else [], check["inconsistent"] if check else []]
    if limit and any(len(items) > limit for items in lists):
        lines.append(f"  (lists show their first {limit} entries; the JSON report has all)")
    lines.append(f"  problems found: {report['problems']}")
    return "\n".join(lines)


def add_arguments(parser) -> None:
    """Arguments of ``robocal inspect``."""
    parser.add_argument("path", help="measurement file (canonical CSV, D1/D2 .xlsx or CSV, D3 tracker CSV)")
    parser.add_argument("--robot", help="built-in robot name or robot file (default: the format's robot)")
    parser.add_argument("--format", choices=FORMATS, help="file format (default: detected from the content)")
    parser.add_argument("--angle-unit", choices=("deg", "rad"), help="unit of canonical q columns (default deg)")
    parser.add_argument("--measurement", choices=("cable", "position", "pose"), help="observation to read")
    parser.add_argument("--sigmas", type=float, default=OUTLIER_SIGMAS, help="outlier threshold in robust sigmas (default %(default)s)")
    parser.add_argument("--json", metavar="OUT", help="also write the report as JSON to OUT ('-' for stdout)")
    parser.add_argument("--strict", action="store_true", help="exit with status 1 when problems are found")


def run(args) -> int:
    """Runs ``robocal inspect``; returns the exit status."""
    report = inspect(args.path, args.robot, args.format, args.angle_unit, args.measurement, args.sigmas)
    if args.json == "-":
        print(json.dumps(report, indent=2))
    else:
        print(format_report(report))
        if args.json:
            write_json(args.json, report)
    return 1 if args.strict and report["problems"] else 0
