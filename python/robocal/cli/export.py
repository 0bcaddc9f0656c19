"""``robocal export``: a result file's calibrated robot as a DH / MDH table, a URDF or UR's
kinematics file, checked by a round trip (:func:`robocal.export.export_checked`)."""

from __future__ import annotations

import argparse

from ..export import FORMATS, TABLE_FORMATS, deliverable, export_checked, suffix_note, table_format_of
from ..outputs import printable
from ..results import load_result
from ..ur_kinematics import read_ur_kinematics, tcp_message


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``robocal export``."""
    parser.add_argument("result", help="calibration result JSON (robocal calibrate --out)")
    parser.add_argument("--format", required=True, choices=FORMATS, help="dh / mdh parameter table, urdf, or ur-yaml (Universal Robots' kinematics file)")
    parser.add_argument(
        "--table-format", choices=TABLE_FORMATS, default=None, help="dh / mdh table as csv or json (default: from the --out suffix, csv unless .json)"
    )
    parser.add_argument("--out", required=True, help="file to write")
    parser.add_argument("--name", default=None, help="robot name in the export (default: the result's robot)")
    parser.add_argument("--samples", type=int, default=200, help="joint vectors of the round-trip check (default 200)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the round-trip check (default 0)")
    parser.add_argument(
        "--angles",
        choices=("readings", "model"),
        default="readings",
        help="joint values of the file: the controller's readings, the result's reading conventions folded in (default), or the model's angles",
    )


def run(args: argparse.Namespace) -> int:
    """Runs ``robocal export``: writes the file, then checks its round trip; returns the exit code."""
    robot, doc = load_result(args.result)
    delivered = deliverable(robot, doc, args.angles)
    kind = {"urdf": "URDF", "ur-yaml": "UR kinematics file"}.get(args.format, f"{args.format.upper()} table")
    check, failed = export_checked(
        robot, args.format, args.out, table_format=args.table_format, name=args.name, samples=args.samples, seed=args.seed, delivered=delivered
    )
    print(
        f"round trip over {check['samples']} joint vectors within limits: max tool position error "
        f"{check['max_position_error_mm']:.3g} mm, max rotation error {check['max_rotation_error_rad']:.3g} rad"
    )
    if failed:
        print(f"robocal export: the {kind} does not reproduce the calibrated kinematics, {args.out} not written: " + "; ".join(failed))
        return 1
    article = "" if args.format == "urdf" else ("an " if args.format == "mdh" else "a ")
    print(f"wrote the calibrated {printable(robot.name, one_line=True)} ({robot.n_joints} joints) as {article}{kind} to {args.out}")
    for note in delivered.notes:
        print(f"note: {note}")
    if args.format == "ur-yaml":
        print(tcp_message(read_ur_kinematics(args.out)))
        return 0
    if delivered.notes and table_format_of(args.out, args.table_format) == "csv" and args.format != "urdf":
        print("note: a CSV table has no room for these notes; the URDF and the JSON table record them")
    note = suffix_note(args.format, args.out, args.table_format)
    if note:
        print(f"note: {note}")
    return 0
