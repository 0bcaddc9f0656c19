"""``robocal compensate``: joint commands for target positions (:func:`robocal.compensate`) as a CSV."""

from __future__ import annotations

import argparse

from ..compensation import FRAME_SPECS, compensate, parse_frame, write_joints


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("result", help="a result file of robocal calibrate (--out)")
    parser.add_argument("targets", help="CSV with x,y,z [qw,qx,qy,qz] (mm, in --frame) [q1..qN in deg, the nominal commands]")
    parser.add_argument("--out", required=True, help="joints CSV: one row per target, joints in deg, corrections, residual, frame, status")
    parser.add_argument("--angle-unit", choices=("deg", "rad"), help="unit of the q1..qN seed columns of the targets (default deg)")
    parser.add_argument("--frame", help=f"the frame of the targets: {FRAME_SPECS}; default base (the robot base frame), user with --user-frame")
    parser.add_argument(
        "--user-frame",
        metavar="X,Y,Z,RX,RY,RZ",
        help="the user frame (work object) in the robot base frame: mm and deg, Tx.Ty.Tz.Rz.Ry.Rx (a value starting with -: --user-frame=-100,0,...)",
    )


def run(args: argparse.Namespace) -> int:
    frame = parse_frame(args.frame, args.user_frame)  # a bad spec fails before the result and targets are read
    rows = compensate(args.result, args.targets, angle_unit=args.angle_unit, frame=args.frame, user_frame=args.user_frame)
    n_joints = len(rows[0]["q"]) if rows else 0
    write_joints(rows, args.out, n_joints)
    bad = [r for r in rows if not r["status"].startswith("ok")]
    reached = [r["residual_mm"] for r in rows if r["status"].startswith("ok")]
    largest = f" (largest residual {max(reached):.2g} mm)" if reached else ""  # none reached: no residual to show
    print(f"{len(reached)} of {len(rows)} targets reached{largest}; targets in {frame.words}; written to {args.out}")
    for r in bad[:10]:
        print(f"  row {r['row']}: {r['status']}")
    return 0 if not bad else 1
