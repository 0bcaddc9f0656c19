"""``robocal plan``: the poses to measure next (:func:`robocal.planning.plan`) as a canonical CSV,
what they buy and what was not checked."""

from __future__ import annotations

import argparse
import json
import math
import time

from ..data.dataset import OBSERVATION_COLUMNS
from ..diagnosis_file import load_diagnosis
from ..exceptions import InvalidParameterError
from ..outputs import printable, write_text
from ..planning import CANDIDATES, CRITERIA, MAX_CANDIDATES, MAX_POSES, TRACKER_RANGE, plan
from ..results import load_result
from ..robot import MEASUREMENTS
from ..robot import robot as load_robot
from ..robot_file import RESULT_SCHEMA, read_document
from .arguments import add_angle_unit_argument


def _numbers(count: int, what: str):
    """An argparse type: ``count`` comma-separated numbers."""

    def parse(text: str) -> tuple:
        try:
            values = tuple(float(v) for v in text.split(","))
        except ValueError:
            values = ()
        if len(values) != count or not all(math.isfinite(v) for v in values):
            raise argparse.ArgumentTypeError(f"expected {what}: {count} comma-separated numbers; got {text!r}")
        return values

    return parse


#: plan()'s arguments that no option of the same name sets (for :func:`robocal.cli.cli_words`).
API_WORDS = {"joint_ranges": "--joint-range", "result": "--from", "causes": "--from"}


def _joint_range(text: str) -> tuple:
    joint, _, bounds = text.partition("=")
    try:
        joint, (lo, hi) = int(joint), _numbers(2, "LO,HI")(bounds)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected J=LO,HI (e.g. 2=-30,45); got {text!r}") from None
    if not lo < hi:  # here, in the user's degrees, not in the library's radians
        raise argparse.ArgumentTypeError(f"expected J=LO,HI with LO < HI; got {text!r}")
    return joint, (lo, hi)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", help="robot name, or a robot / result .json/.yaml, exported table or .urdf file (default: the result's or the data's)")
    parser.add_argument("--measurement", choices=MEASUREMENTS, help="what will be measured (default: the result's or the data's)")
    parser.add_argument("--poses", type=int, required=True, metavar="N", help=f"how many poses to plan (at most {MAX_POSES})")
    parser.add_argument(
        "--from", dest="source", metavar="FILE", help="a calibration result (its robot, set-up and causes) or a diagnose report (its causes) to plan for"
    )
    parser.add_argument("--data", nargs="+", metavar="MEASURED", help="what is already measured, sensor still in place: plan the next poses")
    parser.add_argument("--out", required=True, help="the plan: a canonical CSV (joints in deg, in measuring order; expected readings)")
    parser.add_argument("--json", metavar="FILE", help="write the JSON report here ('-' for standard output)")
    parser.add_argument(
        "--candidates", type=int, default=CANDIDATES, help=f"candidate poses drawn within the constraints (default {CANDIDATES}, at most {MAX_CANDIDATES:,})"
    )
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument(
        "--joint-range",
        action="append",
        type=_joint_range,
        default=[],
        metavar="J=LO,HI",
        help="keep joint J within LO..HI (deg, mm for a prismatic joint; the controller's readings); repeatable",
    )
    parser.add_argument(
        "--cable-range", type=_numbers(2, "MIN,MAX"), default=(0.0, 2000.0), metavar="MIN,MAX", help="the cable sensor's reading range, mm (default 0,2000)"
    )
    parser.add_argument("--anchor", type=_numbers(3, "X,Y,Z"), metavar="X,Y,Z", help="the cable's anchor in the robot base frame, mm")
    parser.add_argument("--tool", type=_numbers(3, "X,Y,Z"), metavar="X,Y,Z", help="the measured point on the flange, mm")
    parser.add_argument("--tracker", type=_numbers(3, "X,Y,Z"), metavar="X,Y,Z", help="the laser tracker's position in the robot base frame, mm")
    parser.add_argument(
        "--tracker-range",
        type=_numbers(2, "NEAR,FAR"),
        metavar="NEAR,FAR",
        help=f"distances the tracker measures at, mm (default {TRACKER_RANGE[0]:g},{TRACKER_RANGE[1]:g})",
    )
    parser.add_argument(
        "--box",
        type=_numbers(6, "XMIN,XMAX,YMIN,YMAX,ZMIN,ZMAX"),
        metavar="XMIN,XMAX,YMIN,YMAX,ZMIN,ZMAX",
        help="a box in the robot base frame the tool point must stay in, mm (default: above the mounting plane, z > 0)",
    )
    parser.add_argument("--noise", type=float, metavar="MM", help="the reading's standard deviation, mm (default: the sensor's)")
    parser.add_argument("--passes", type=int, help="interleaved passes over the workspace (default about sqrt(N)/2)")
    i_help = "I: the least mean error predicted over the workspace on a new session (default)"
    d_help = "D: the least volume of the parameters' confidence ellipsoid (log det)"
    ds_help = "Ds: the poses of a re-mastering (calibrate --prior): the joints' zeros apart from each other and from a new set-up"
    parser.add_argument("--criterion", choices=sorted(CRITERIA), default="I", help=f"{i_help}; {d_help}; {ds_help}")
    parser.add_argument("--bound", action="store_true", help="also state the least predicted error any N poses among the candidates could reach (seconds more)")
    add_angle_unit_argument(parser, "q columns of canonical --data files")


def _prismatic(args) -> tuple:
    """The prismatic joints (0-based) of the robot the plan is for: their ranges are mm."""
    if args.robot:
        return load_robot(args.robot).prismatic
    if args.source and not args.data:
        try:
            return load_result(args.source)[0].prismatic
        except InvalidParameterError:  # a diagnose report: the robot comes from the data or --robot, which plan() asks for
            return ()
    return ()


def _source(path):
    """``(result, causes)`` of ``--from``: a result file's document or a diagnose report's."""
    if path is None:
        return None, None
    document = read_document(path, "result or diagnose report")
    if isinstance(document, dict) and document.get("schema") == RESULT_SCHEMA:
        return document, None
    return None, load_diagnosis(path)  # read from its path, so that its errors name the file


def _mm(value) -> str:
    return "undetermined" if value is None else f"{value:.4f} mm RMS"


def _model_line(report: dict) -> str:
    """What the plan counts: its entries, the joint maps' coefficients and where their ranges come from, what is known before."""
    model = report["model"]
    maps = model["maps"]
    counted = f"  model: {model['entries']} entries: {model['robot_parameters']} parameters of the robot"
    if model["cause_coefficients"]:
        others = [c["label"] for c in report["causes"] if not c["label"].startswith("joint_map ")]
        spans = ", ".join(f"joint {m['label'].split()[2]} {m['coefficients']} over {m['range_deg'][0]:.0f}..{m['range_deg'][1]:.0f} deg" for m in maps)
        where = " and ".join(sorted({m["range_from"] for m in maps}))
        parts = ([", ".join(others)] if others else []) + ([f"joint maps over the ranges of {where}: {spans}"] if maps else [])
        counted += f", {model['cause_coefficients']} coefficients of its causes ({'; '.join(parts)})"
    counted += f", {len(model['setup'])} of the new session's set-up"
    counted += f"; left out (redundant or no effect here): {', '.join(report['fixed'])}" if report["fixed"] else ""
    return counted + "\n  known before the poses: " + ("; ".join(model["known_before"]) or "nothing (the nominal robot, no data)")


def _zeros_lines(report: dict) -> list[str]:
    """What a re-mastering on these poses would determine (criterion Ds)."""
    if not report.get("zeros"):
        return []
    n = report["poses"]
    apart = [z for z in report["zeros"] if z["after"] is not None]
    # One unit after the figures, or each its own where a prismatic joint's (mm) stands among the others' (deg).
    units = {z["unit"] for z in apart}
    each = (lambda z: f" {z['unit']}") if len(units) > 1 else (lambda z: "")
    lines = [
        f"  a re-mastering on these poses: each zero's change ± "
        + ", ".join(f"joint {z['joint']} {z['after']:.2g}{each(z)}" for z in apart)
        + f"{'' if len(units) > 1 else ' ' + (units.pop() if units else 'deg')} ({n} random poses: "
        + ", ".join(f"{z['random']:.2g}{each(z)}" for z in apart)
        + ")"
    ]
    lines += [
        f"  joint {z['joint']}: no pose tells its zero from the set-up ({', '.join(z['absorbed_by']) or 'the set-up'} does the same)"
        for z in report["zeros"]
        if z["after"] is None
    ]
    return lines


def summary(report: dict, out: str, seconds: float) -> str:
    """A few lines for the terminal."""
    position = report["position"]

    def mm(key):
        entry, open_ = position[key], report["undetermined"][key]
        if entry["rms_mm"] is None:
            return f"undetermined ({open_} directions the data leave open)" if key == "before" and report["data"]["samples"] else "undetermined"
        return f"{entry['rms_mm']:.4f} mm RMS (largest {entry['max_mm']:.4f})" + (f", {entry['undetermined_share']:.0%} of it undetermined" if open_ else "")

    prediction = report["prediction"]
    params = report["parameters"]
    determined = [p for p in params if p["after"] is not None]
    worst = max(determined, key=lambda p: p["after"] / report["tolerance"].get(p["unit"], 1.0), default=None)
    beyond = report["tolerance"]["beyond"]
    undetermined = [p["name"] for p in params if p["after"] is None]
    order = report["order"]
    travel_compared = f"one tour {order['travel_single_tour_deg']:,.0f}, a random order {order['travel_random_order_deg']:,.0f}"
    lines = [
        f"plan: {report['poses']} poses of {printable(report['robot'], one_line=True)} for {report['measurement']} measurements, "
        f"chosen among {report['candidates']:,} candidates ({report['criterion']}), {seconds:.1f} s",
        _model_line(report),
        f"  the tool point's standard deviation over the workspace: {mm('before')} before, {mm('after')} after; {report['poses']} random poses: {mm('random')}",
        f"  predicted error of a new session over the workspace (its set-up re-fitted): {_mm(prediction['before'])} before, "
        f"{_mm(prediction['after'])} after; {report['poses']} random poses: {_mm(prediction['random'])}"
        + (f"; the least any {report['poses']} poses could reach: {_mm(prediction['least_possible'])}" if "least_possible" in prediction else ""),
        f"  every parameter within {report['tolerance']['mm']:g} mm / {report['tolerance']['deg']:g} deg: "
        + ("yes" if not beyond and not undetermined else f"no — {len(beyond)} beyond, {len(undetermined)} undetermined")
        + (f" (the largest against it: {worst['name']} ± {worst['after']:.3g} {worst['unit']})" if worst else ""),
        f"  order: {order['passes']} interleaved passes, travel {order['travel_deg']:,.0f} deg of joint moves ({travel_compared}); correlation with the order: "
        + ", ".join(f"q{j + 1} {c:+.2f}" for j, c in enumerate(order["correlation"])),
        "  checked: " + "; ".join(report["constraints"]),
        "  not checked: " + "; ".join(report["not_checked"]),
    ]
    lines += [f"  {c['label']}: {c['reason']}" for c in report["causes_not_by_poses"]]
    lines += _zeros_lines(report)
    lines += [f"  note: {n}" for n in report["notes"]]
    columns = OBSERVATION_COLUMNS[report["measurement"]]
    named = f"its {', '.join(columns)} column{'s' * (len(columns) > 1)}"
    lines.append(f"wrote the {report['poses']} poses to {out} ({named}: the readings the model expects — overwrite them with what you measure)")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    started = time.perf_counter()
    if args.out == "-":
        raise InvalidParameterError("--out: the plan is a CSV file; give its path")
    result, causes = _source(args.source)
    prismatic = _prismatic(args) if args.joint_range else ()
    ranges = {j: tuple(v if j - 1 in prismatic else math.radians(v) for v in bounds) for j, bounds in args.joint_range}
    limits = {"joint_ranges": ranges or None, "cable_range": args.cable_range, "box": args.box}
    set_up = {"anchor": args.anchor, "tool": args.tool, "tracker": args.tracker, "tracker_range": args.tracker_range, "noise": args.noise}
    search = {"candidates": args.candidates, "seed": args.seed, "passes": args.passes, "criterion": args.criterion, "bound": args.bound}
    planned = plan(
        args.robot, args.measurement, args.poses, result=result, causes=causes, data=args.data, angle_unit=args.angle_unit, **limits, **set_up, **search
    )
    planned.write(args.out)
    report = planned.to_dict()
    text = json.dumps(report, indent=2)
    if args.json == "-":
        print(text)
        return 0
    print(summary(report, args.out, time.perf_counter() - started))
    if args.json:
        write_text(args.json, text)
    return 0
