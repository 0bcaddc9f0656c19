"""``robocal monitor``: a calibrated robot watched sample by sample (:class:`robocal.monitoring.Monitor`).

DATA is a measurement file (canonical CSV or a public dataset, replayed in acquisition order) or
``-``: a canonical CSV on standard input, its header first, read line by line as the lines come,
so that a cell can pipe its readings in. One JSON line per alarm goes to ``--json-lines``; a
readable line per alarm and a summary to the terminal; ``--out`` writes the result with what
changed applied.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import json
import sys

from ..calibration.api import load_inputs
from ..causes.candidates import acquisition_order
from ..data import load
from ..data.formats.canonical import canonical_columns, canonical_dataset
from ..data.table import Table, check_header
from ..exceptions import DataError
from ..monitoring import MEAN_RUN_LENGTH, MIN_OPENING, OPENING, Monitor
from ..outputs import Staged, printable
from ..results import save_result
from .arguments import add_angle_unit_argument

STDIN = "<stdin>"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("result", help="a result file of robocal calibrate (--out)")
    parser.add_argument("data", help="measurements of the robot in acquisition order: a file, or - for a canonical CSV on standard input")
    parser.add_argument("--json-lines", help="write one JSON line per alarm here")
    parser.add_argument("--out", help="write the result with what changed applied (verify, compensate and export take it)")
    parser.add_argument(
        "--new-session", action="store_true", help="re-fit the session's set-up on the opening samples (default: the calibration's session goes on)"
    )
    parser.add_argument("--mean-run-length", type=float, default=MEAN_RUN_LENGTH, help=f"mean samples between false alarms (default {MEAN_RUN_LENGTH:,})")
    parser.add_argument(
        "--opening",
        type=int,
        default=OPENING,
        help=f"samples that set the innovations' scale; no alarm before them (default {OPENING}, at least {MIN_OPENING})",
    )
    add_angle_unit_argument(parser)


def _stdin_lines():
    """``(number, line)`` of standard input as the lines come, numbered and split as the file
    reader splits a file (``str.splitlines``: LF, CRLF and CR alike), an opening BOM dropped."""
    number = 0
    for chunk in sys.stdin:
        for line in chunk.splitlines():
            number += 1
            yield number, line.removeprefix("\ufeff") if number == 1 else line


def _stdin_samples(monitor: Monitor, angle_unit):
    """``(q, y, row)`` of each line of a canonical CSV on standard input, as it comes; a header
    that is not a canonical one of the result's measurement stops the stream, a line that does
    not parse is refused with a note naming its row, and the stream goes on."""
    header, last_t = None, -float("inf")
    for number, line in _stdin_lines():
        if not line.strip():
            continue
        try:
            try:
                cells = [c.strip() for c in next(csv.reader([line]))]  # quoted cells as a file's
            except csv.Error as exc:  # a cell beyond csv's size limit
                raise DataError(f"not a readable CSV line ({exc})", STDIN, number) from None
            if header is None:  # checked once: else every line is refused for it
                check_header(cells, STDIN, ",")
                canonical_columns(Table(cells, [], STDIN), monitor.measurement)
                header = cells
                continue
            sample = canonical_dataset(
                Table(header, [(number, cells)], STDIN), angle_unit or "deg", monitor.measurement, None, False, prismatic=monitor.robot.prismatic
            )
            if sample.t is not None and not sample.t[0] >= last_t:
                # the stream is taken in the order it comes: a sample from the past is not acquisition order
                raise DataError(f"the clock goes backwards: t = {sample.t[0]:g} after {last_t:g}", STDIN, number, "t")
        except DataError as exc:
            if header is None:  # the stream cannot be read
                raise
            _refuse(monitor, number, exc)
            continue
        last_t = last_t if sample.t is None else float(sample.t[0])
        yield sample.q[0], sample.y[0], number
    if header is None:
        raise DataError("no header line: a canonical CSV starts with its column names", STDIN, 1)


def _refuse(monitor: Monitor, row: int, why: DataError) -> None:
    """A row that does not parse, noted where the monitor's own refusals are, and the stream goes on."""
    monitor.refused.append(f"row {row} refused: {why}")
    print(f"  row {row} refused: {printable(str(why), one_line=True)}", file=sys.stderr)


def _file_samples(monitor: Monitor, path, angle_unit):
    """``(q, y, row)`` of a recorded file in acquisition order, replayed as its stream would be:
    a row that does not parse is refused with a note as on standard input, not the whole file."""
    data = load(path, measurement=monitor.measurement, angle_unit=angle_unit, robot=monitor.robot, exclude_bad_rows=True)
    data, _ = load_inputs(data, monitor.robot, monitor.measurement)
    for bad in data.excluded:
        _refuse(monitor, bad["row"], DataError(bad["reason"], path, bad["row"], bad.get("column")))
    return ((data.q[i], data.y[i], int(data.rows[i])) for i in acquisition_order(data))


def run(args: argparse.Namespace) -> int:
    monitor = Monitor(args.result, new_session=args.new_session, mean_run_length=args.mean_run_length, opening=args.opening)
    if args.data == "-":
        samples = _stdin_samples(monitor, args.angle_unit)
    else:
        samples = _file_samples(monitor, args.data, args.angle_unit)
    with contextlib.ExitStack() as stack:  # the JSON lines file is complete, and replaces any old one, when the stream ends
        out = stack.enter_context(stack.enter_context(Staged(args.json_lines)).tmp.open("w")) if args.json_lines else None
        for q, y, row in samples:
            for alarm in monitor.update(q, y, rows=[row]):
                print(alarm.words(), flush=True)
                if out:
                    out.write(json.dumps(alarm.to_dict()) + "\n")
    summary = monitor.summary()
    limits = ", ".join(f"{'joint ' + str(l['joint']) if l['joint'] else l['kind']} {l['size']:.3g} {l['unit']}" for l in summary["detection_limits"])
    print(
        f"{summary['samples']} samples, {len(summary['alarms'])} alarms, {len(summary['refused'])} refused; "
        f"thresholds for one false alarm per {args.mean_run_length:,.0f} samples"
        + (
            f"; innovations' long-run inflation {monitor.inflation:.2f}"
            if monitor.sigma is not None
            else f"; fewer than the {monitor.opening} opening samples: nothing tested"
        )
    )
    if limits:
        print(f"  detection limits (found within {summary['detection_limits'][0]['within']} samples): {limits}")
    if args.out:
        save_result(monitor.result_document(), args.out)
        print(f"  the result with what changed applied written to {args.out}")
    return 0
