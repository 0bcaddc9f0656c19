"""``robocal calibrate``: :func:`robocal.calibrate` on a measurement file, a summary or the result JSON."""

from __future__ import annotations

import argparse
import json

from ..calibration.api import method_choices
from ..calibration.result import describe_implausible, verdict
from ..causes.extended import calibrate
from ..diagnosis_file import load_diagnosis
from ..exceptions import InvalidParameterError
from ..outputs import printable
from ..remastering import remaster
from ..results import load_result, save_result
from .arguments import add_data_arguments, add_kinematic_prior_argument, files_angle_unit


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_data_arguments(parser, sessions=True)
    parser.add_argument("--method", default="lm", help=f"one of {method_choices()} (default lm)")
    parser.add_argument("--test-fraction", type=float, help="held-out share, seeded random split (default 0.2)")
    parser.add_argument("--seed", type=int, help="seed of the held-out split (default 0)")
    add_kinematic_prior_argument(parser)
    parser.add_argument(
        "--loss", choices=["linear", "huber", "cauchy"], default="linear", help="robust loss of method lm; outlying rows are reported (default linear)"
    )
    parser.add_argument(
        "--causes", nargs="+", metavar="CAUSE", help="fit an extended model (method lm): a diagnose report JSON, or cause labels as diagnose prints them"
    )
    parser.add_argument(
        "--prior",
        metavar="RESULT",
        help="re-master: a calibration result held as it is but for each joint's zero; find from a few new points whose zero moved, and by how much",
    )
    parser.add_argument(
        "--alpha",
        type=float,
        help="re-master (--prior): the level at which a joint's zero is named moved, Bonferroni over the joints the points tell apart "
        "(default 0.05: a session where nothing moved names a joint at most this often)",
    )
    parser.add_argument("--out", help="write the result JSON here")
    parser.add_argument("--json", action="store_true", help="print the result JSON instead of a summary")


#: Options of a full calibration that a re-mastering (``--prior``) does not take: option -> its value when not given.
NOT_WITH_PRIOR = {"method": "lm", "test_fraction": None, "seed": None, "kinematic_prior": None, "loss": "linear", "causes": None}


def run(args: argparse.Namespace) -> int:
    if args.prior is not None:
        return _remaster(args)
    if args.alpha is not None:
        raise InvalidParameterError("--alpha: only a re-mastering (--prior RESULT) names joints at a test level; a calibration takes none")
    report = args.causes[0] if args.causes and len(args.causes) == 1 and args.causes[0].endswith(".json") else None
    if report is not None:
        report = load_diagnosis(report)  # a corrupt or malformed report is refused naming the file, before the data are read
    data = args.data[0] if len(args.data) == 1 else args.data
    result = calibrate(
        data,
        robot=args.robot,
        measurement=args.measurement,
        method=args.method,
        test_fraction=0.2 if args.test_fraction is None else args.test_fraction,
        seed=0 if args.seed is None else args.seed,
        kinematic_prior=args.kinematic_prior,
        angle_unit=files_angle_unit(args),
        causes=report or args.causes or None,
        **({"loss": args.loss} if args.loss != "linear" else {}),
    )
    doc = result.to_dict()
    if args.out:
        save_result(doc, args.out)
    if args.json:
        print(json.dumps(doc, indent=2))
        return 0
    train, test = doc["metrics"]["train"], doc["metrics"]["test"]
    print("verdict: {}: {}".format(*verdict(doc)))
    print(
        f"{doc['method']} on {printable(doc['robot'], one_line=True)} ({doc['measurement']}, {train['n']} training samples): "
        f"{doc['convergence']['message']} after {doc['convergence']['nit']} iterations, {doc['convergence']['time_s'] * 1e3:.0f} ms"
    )
    print(f"  train: RMSE {train['rmse']:.4f}  MAE {train['mae']:.4f}  MAX {train['max']:.4f} mm")
    if test:
        print(f"  test:  RMSE {test['rmse']:.4f}  MAE {test['mae']:.4f}  MAX {test['max']:.4f} mm ({test['n']} samples)")
    for s, session in enumerate(doc.get("sessions", []), start=1):
        held = session["metrics"]["test"]
        print(
            f"  session {s} ({printable(session['source'] or 'data', one_line=True)}): train RMSE {session['metrics']['train']['rmse']:.4f} mm"
            + (f", test RMSE {held['rmse']:.4f} mm ({held['n']} samples)" if held else "")
            + (f"; own terms: {', '.join(session['terms'])}" if session["terms"] else "")
        )
    # Every fixed parameter is named: a count above the names it lists reads as a contradiction.
    print(f"  estimated {len(doc['free'])} parameters; fixed {len(doc['fixed'])}: " + "; ".join(f"{k} ({v})" for k, v in doc["fixed"].items()))
    for cause in doc.get("causes", []):
        shown = ", ".join(
            f"{k} {v['value']:.4g}" + (f" ± {v['std']:.2g}" if v["std"] is not None else "") + f" {v['unit']}"
            for k, v in cause["params"].items()
            if v["value"] == v["value"]
        )
        print(f"  cause {cause['label']}: {shown}")
    geometry_only = doc.get("geometry_only")
    if geometry_only:
        held = geometry_only["held_out"][geometry_only["choice"]]
        print(
            f"  geometry alone (what export writes; it leaves out {len(geometry_only['not_carried'])} joint causes): "
            + (f"held-out RMSE {held['rmse']:.4f} mm, " if held else "")
            + ("re-fitted without them" if geometry_only["choice"] == "refit" else "the extended fit's")
        )
    if "robust" in doc:
        rows = doc["robust"]["outlying_rows"]
        print(
            f"  {doc['robust']['loss']} loss, scale {doc['robust']['f_scale']:.3g} mm: {len(rows)} outlying rows"
            + (f" {rows[:12]}" + (" ..." if len(rows) > 12 else "") if rows else "")
        )
    for note in result.problem.data.notes:  # what the reader noticed, e.g. angles kept in an unlikely unit as asked
        print(f"  note: {note}")
    if doc["implausible"]:
        print("  warning: " + describe_implausible(doc["implausible"]))
    if doc["undetermined"]:
        widest = max(doc["undetermined"], key=lambda u: u["std"])
        combination = " ".join(f"{w:+.2f}·{n}" for n, w in widest["combination"].items())
        print(
            f"  {len(doc['undetermined'])} parameter combinations are undetermined (standard deviation beyond 10 mm / 2 deg); "
            f"the widest, {widest['std']:.3g} limits: {combination}"
        )
    if args.out:
        print(f"  result written to {args.out}")
    return 0


def _remaster(args: argparse.Namespace) -> int:
    """``--prior RESULT``: :func:`robocal.remastering.remaster` on one file, its summary or the re-mastered result JSON."""
    given = [f"--{name.replace('_', '-')}" for name, default in NOT_WITH_PRIOR.items() if getattr(args, name) != default]
    if given:
        raise InvalidParameterError(f"{', '.join(given)}: a re-mastering (--prior) fits only the set-up and the joints' zeros; it takes none of these")
    if len(args.data) != 1:
        raise InvalidParameterError(f"a re-mastering (--prior) reads one session's file; got {len(args.data)}")
    if args.robot is not None:
        # The same command line as the calibration's, plus --prior, is welcome; another robot is not.
        named = load_result(args.prior)[1].get("robot")
        if args.robot != named:
            raise InvalidParameterError(f"--robot {args.robot}: a re-mastering (--prior) is of the result's robot, {named!r}; omit --robot or give that one")
    level = {} if args.alpha is None else {"alpha": args.alpha}
    found = remaster(args.prior, args.data[0], measurement=args.measurement, angle_unit=files_angle_unit(args), **level)
    if args.out:
        save_result(found.document, args.out)
    if args.json:
        print(json.dumps(found.document, indent=2))
        return 0
    print(remaster_summary(found.report, found.document))
    if args.out:
        print(f"  result written to {args.out}")
    return 0


def remaster_summary(report: dict, doc: dict) -> str:
    """A few lines for the terminal: what moved, what held, what these points cannot tell."""
    joints = report["joints"]
    lines = [
        (
            f"re-mastering {printable(doc['robot'], one_line=True)} from {report['samples']} {doc['measurement']} samples: the new session's set-up fitted "
            f"({', '.join(report['setup'])}), every other parameter held at the result's"
        ),
        (
            f"  noise {report['noise_mm']:.4g} mm per reading ({report['noise_from']}); a joint is named when its change passes χ² {report['threshold']:.3g} "
            f"(Bonferroni, {report['alpha']:.0%} over the {sum(j['status'] != 'indistinguishable' for j in joints)} joints these points tell apart)"
        ),
    ]
    for j in joints:
        if j["status"] == "moved":
            lines.append(f"  joint {j['joint']}: zero moved {j['change']:+.4f} ± {j['std']:.4f} {j['unit']} ({j['name']}; χ² {j['statistic']:.1f})")
    held = [j for j in joints if j["status"] == "held"]
    if held:
        lines.append("  no change found: " + ", ".join(f"joint {j['joint']} (± {j['detectable_std']:.2g} {j['unit']} were it the only change)" for j in held))
    for j in joints:
        if j["status"] == "indistinguishable":
            lines.append(
                f"  joint {j['joint']}: cannot be told apart from the set-up with these points"
                + (f" (the set-up's {', '.join(j['redundant_with'])} does the same)" if j["redundant_with"] else "")
            )
    rmse = report["rmse"]
    lines.append(f"  RMSE {rmse['setup_alone']:.4f} mm with the set-up alone, {rmse['remastered']:.4f} mm re-mastered")
    lines += [f"  note: {n}" for n in report["notes"]]
    return "\n".join(lines)
