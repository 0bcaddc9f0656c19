"""``robocal.calibrate``: data in, calibrated robot and held-out metrics out."""

from __future__ import annotations

import argparse
import inspect
import json
import re
from pathlib import Path
from typing import Callable, Optional, Union

import numpy as np

from ..core import as_float
from ..data.dataset import Dataset
from ..data.public import load
from ..data.splits import random_split
from ..exceptions import InvalidParameterError
from ..results import save_result
from ..robot import Robot, robot as load_robot
from . import cascade, kalman, metaheuristics, rbf, vslm
from .lm import levenberg_marquardt
from .metrics import metrics
from .problem import Problem
from .result import CalibrationResult, describe_implausible

#: method name -> (paper label, description, function(problem, **options) -> CalibrationResult)
METHODS: dict[str, tuple[str, str, Callable[..., CalibrationResult]]] = {
    "lm": ("-", "robocal's production Levenberg-Marquardt (adaptive damping)", levenberg_marquardt),
    **kalman.METHODS,
    **vslm.METHODS,
    **cascade.METHODS,
    **metaheuristics.METHODS,
    **rbf.METHODS,
}


def load_inputs(
    data: Union[str, Path, Dataset], robot: Union[str, Robot, None] = None, measurement: Optional[str] = None, angle_unit: Optional[str] = None
) -> tuple[Dataset, Robot]:
    """The dataset and the robot a calibration runs on.

    Parameters
    ----------
    data : path or Dataset
        A measurement file (see :func:`robocal.data.load`) or a :class:`Dataset`.
    robot : str or Robot, optional
        Default: the robot recorded in the data.
    measurement : {"cable", "position", "pose"}, optional
        Required of the data; chooses among them for files that provide more than one.
    angle_unit : {"deg", "rad"}, optional
        Unit of the joint columns of a canonical file (see :func:`robocal.data.load`, which
        refuses values implausible for the unit unless it is given).

    Returns
    -------
    dataset : Dataset
    robot : Robot
    """
    dataset = data if isinstance(data, Dataset) else load(data, measurement=measurement, angle_unit=angle_unit, robot=robot if isinstance(robot, str) else None)
    if measurement is not None and dataset.measurement != measurement:
        raise InvalidParameterError(f"the data hold {dataset.measurement} measurements, not {measurement}")
    if robot is None:
        if dataset.robot is None:
            raise InvalidParameterError("the data do not name their robot: pass `robot`")
        robot = dataset.robot
    return dataset, robot if isinstance(robot, Robot) else load_robot(robot)


def held_out_residuals(result: CalibrationResult, test: Dataset) -> np.ndarray:
    """Residuals ``y − prediction`` of a fitted ``result`` on held-out samples, flattened.

    A corrector (M5, :class:`~robocal.calibration.rbf.RBFResult`) changes the prediction, not the
    parameters: it is evaluated as it predicts (its corrected residuals). Every other method is
    evaluated with its parameters on the training problem's parameterisation.
    """
    if isinstance(result, rbf.RBFResult):
        return result.corrected_residuals(test)
    return result.problem.with_data(test).data_residuals(result.x)


def calibrate(
    data: Union[str, Path, Dataset],
    robot: Union[str, Robot, None] = None,
    measurement: Optional[str] = None,
    method: str = "lm",
    test_fraction: float = 0.2,
    seed: int = 0,
    mask=None,
    prior=None,
    bounds=None,
    kinematic_prior=None,
    causes=None,
    angle_unit: Optional[str] = None,
    **options,
) -> CalibrationResult:
    """Calibrates ``robot`` on ``data`` and evaluates it on a held-out random split.

    Parameters
    ----------
    data : path or Dataset
        A measurement file (canonical CSV or a public dataset, see :func:`robocal.data.load`)
        or a :class:`Dataset`.
    robot : str or Robot, optional
        Default: the robot recorded in the data.
    measurement : {"cable", "position", "pose"}, optional
        For files that can provide more than one (the UR10 tracker files: ``pose`` or ``position``).
    method : str
        One of :data:`METHODS`.
    test_fraction : float
        Share of samples held out (seeded random split); 0 fits on everything.
    seed : int
        Seeds the held-out split and the draws of the stochastic methods (``pso``, ``de``,
        ``bas``, ``rbf``): equal seeds give bit-identical results.
    mask : optional
        Parameters to consider (default: the robot's default mask for the measurement).
    prior : dict, optional
        ``name -> (mean, sigma)`` Gaussian priors (mm / rad) on estimated parameters (see
        :class:`Problem`); Kalman filters take them as their prior mean and covariance.
    bounds : dict, optional
        ``name -> (lower, upper)`` hard limits (mm / rad) on estimated parameters, kept by every
        method (projected LM steps; Kalman estimates clipped after each sweep; the
        metaheuristics' search box intersected with them).
    kinematic_prior : (float, float), optional
        ``(mm, deg)`` Gaussian prior at nominal on every estimated kinematic parameter (see
        :meth:`Problem.build`).
    causes : list of str, dict or path, optional
        An extended model: cause labels as ``robocal diagnose`` reports them (e.g.
        ``"joint_periodic joint 2 harmonic=3"``, ``"joint_sign joint 4"``), or a diagnose report
        (dict or JSON file) whose causes — and the tolerance prior of its final model, unless
        ``kinematic_prior`` is given — are taken. Reading conventions (``joint_zero``,
        ``joint_sign``, ``joint_reference``) transform the joint readings before the fit. Fitted with the geometric parameters by ``method="lm"``; the result
        JSON then has ``causes`` with their physical parameters.
    angle_unit : {"deg", "rad"}, optional
        Unit of the joint columns of a canonical file (degrees by default; values implausible
        for the default unit are refused, see :func:`robocal.data.load`).
    **options
        Passed to the method.

    Returns
    -------
    CalibrationResult
        ``to_dict()`` is the result JSON (``method``, ``parameters``, ``metrics`` with ``train``
        and ``test``, ...).
    """
    if not isinstance(method, str) or method not in METHODS:
        raise InvalidParameterError(f"unknown method {method!r}; choose one of {sorted(METHODS)}")
    test_fraction = as_float(test_fraction, "test_fraction")
    if not 0.0 <= test_fraction < 1.0:
        raise InvalidParameterError(f"`test_fraction` must lie in [0, 1); got {test_fraction}")
    dataset, r = load_inputs(data, robot, measurement, angle_unit)
    labels = structures = None
    if causes is not None:
        from ..diagnosis import structure  # the diagnose package imports this module

        labels, reported_prior = read_causes(causes)
        kinematic_prior = reported_prior if kinematic_prior is None else kinematic_prior
        parsed = [(label, structure.parse(label, r.n_joints)) for label in labels]
        structures = [s for _, s in parsed if s is not None]
        labels = [label for label, s in parsed if s is None]
        dataset = structure.apply_all(dataset, structures)  # the readings in the model's convention
    train_idx, test_idx = None, None
    if test_fraction > 0:
        train_idx, test_idx = random_split(len(dataset), test_fraction=test_fraction, seed=seed)
        train, test = dataset.subset(train_idx), dataset.subset(test_idx)
    else:
        train, test = dataset, None
    problem = Problem.build(r, train, mask=mask, prior=prior, bounds=bounds, kinematic_prior=kinematic_prior)
    problem.require_dof()
    if causes is None:
        fit = METHODS[method][2]
        if "seed" in inspect.signature(fit).parameters:
            options = {**options, "seed": seed}
        result = fit(problem, **_checked_options(fit, method, options))
        if test is not None:
            result.metrics["test"] = metrics(held_out_residuals(result, test), test.measurement)
            result.held_out = test
        return result
    if method != "lm":
        raise InvalidParameterError(f"an extended model (causes) is fitted by method 'lm' only; got {method!r}")
    model = extended_problem(problem, dataset, train_idx if test is not None else np.arange(len(dataset)), labels)
    result = levenberg_marquardt(model, **_checked_options(levenberg_marquardt, method, options))
    result.structure = [s.label for s in structures]
    if test is not None:
        result.metrics["test"] = metrics(model.with_samples(test_idx).data_residuals(result.x), test.measurement)
        result.held_out = test
    return result


def _checked_options(function: Callable, method: str, options: dict) -> dict:
    """``options`` if ``function(problem, **options)`` accepts them, else an error naming them."""
    try:
        inspect.signature(function).bind(None, **options)
    except TypeError as exc:
        raise InvalidParameterError(f"method {method!r} does not take these options: {exc}") from None
    return options


def read_causes(causes) -> tuple[list[str], Optional[tuple]]:
    """Cause labels from labels, a diagnose report (dict) or its JSON file — the report's
    reading conventions (``model.structure``) first, then its ``model.causes`` — and the
    report's tolerance prior ``(mm, deg)`` on the kinematics, if its final model has one."""
    if isinstance(causes, (str, Path)) and str(causes).endswith(".json"):
        try:
            causes = json.loads(Path(causes).read_text())
        except (OSError, ValueError) as exc:
            raise InvalidParameterError(f"cannot read the diagnose report {causes}: {exc}") from None
    prior = None
    if isinstance(causes, dict):
        try:
            prior = causes["model"].get("kinematic_prior")
            causes = list(causes["model"].get("structure", [])) + list(causes["model"]["causes"])
        except (KeyError, TypeError, AttributeError):
            raise InvalidParameterError("a diagnose report needs model.causes (the JSON of `robocal diagnose --json`)") from None
    if isinstance(causes, str):
        causes = [causes]
    if not isinstance(causes, (list, tuple)) or not all(isinstance(c, str) for c in causes):
        raise InvalidParameterError(f"`causes` must be cause labels, a diagnose report or its JSON file; got {causes!r}")
    return list(causes), None if prior is None else tuple(prior)


def extended_problem(problem: Problem, dataset: Dataset, idx: np.ndarray, causes: list[str]):
    """``problem`` extended by the causes labelled ``causes`` on the samples ``idx`` of
    ``dataset`` (bases such as backlash and drift need the whole sequence)."""
    from ..diagnosis import ExtendedProblem, library  # the diagnose package imports this module
    from ..diagnosis.candidates import step_candidate

    pool = {c.label: c for c in library(problem.robot, dataset, list(problem.names) + list(problem.fixed))}
    for label in causes:  # steps sit where diagnose found them: their label says where
        step = re.fullmatch(r"step sample=(\d+) row=\d+", label)
        if step:
            pool[label] = step_candidate(dataset, int(step.group(1)))
    unknown = [c for c in causes if c not in pool]
    if unknown:
        raise InvalidParameterError(f"unknown causes {unknown} for these data; known: {sorted(pool)[:6]} ... ({len(pool)} in all)")
    return ExtendedProblem(problem, [pool[c] for c in causes], dataset, idx)


def _mm_deg(text: str) -> tuple[float, float]:
    try:
        length, angle = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected MM,DEG (e.g. 10,1); got {text!r}") from None
    return length, angle


def add_kinematic_prior_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--kinematic-prior", type=_mm_deg, metavar="MM,DEG",
                        help="Gaussian prior at nominal on every kinematic parameter, sigma MM for lengths and DEG for angles")  # fmt: skip


def add_data_arguments(parser: argparse.ArgumentParser, sessions: bool = False) -> None:
    """The arguments of every command that calibrates on a measurement file (``sessions``: on
    one or more, each a session of one robot)."""
    if sessions:
        parser.add_argument("data", nargs="+", help="measurement file(s); several files are sessions of one robot (judged leave-one-session-out)")
    else:
        parser.add_argument("data", help="measurement file (canonical CSV or a public dataset)")
    parser.add_argument("--robot", help="robot name or .json/.yaml file (default: the one the data name)")
    parser.add_argument("--measurement", choices=["cable", "position", "pose"])
    add_angle_unit_argument(parser)


def add_angle_unit_argument(parser: argparse.ArgumentParser, what: str = "q columns of a canonical file") -> None:
    parser.add_argument("--angle-unit", choices=("deg", "rad"),
                        help=f"unit of the {what} (default deg; values implausible for the default are refused)")  # fmt: skip


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_data_arguments(parser)
    parser.add_argument("--method", default="lm", help=f"one of {sorted(METHODS)} (default lm)")
    parser.add_argument("--test-fraction", type=float, default=0.2, help="held-out share, seeded random split (default 0.2)")
    parser.add_argument("--seed", type=int, default=0)
    add_kinematic_prior_argument(parser)
    parser.add_argument("--loss", choices=["linear", "huber", "cauchy"], default="linear",
                        help="robust loss of method lm; outlying rows are reported (default linear)")  # fmt: skip
    parser.add_argument("--causes", nargs="+", metavar="CAUSE",
                        help="fit an extended model (method lm): a diagnose report JSON, or cause labels as diagnose prints them")  # fmt: skip
    parser.add_argument("--out", help="write the result JSON here")
    parser.add_argument("--json", action="store_true", help="print the result JSON instead of a summary")


def run(args: argparse.Namespace) -> int:
    result = calibrate(args.data, robot=args.robot, measurement=args.measurement, method=args.method,
                       test_fraction=args.test_fraction, seed=args.seed, kinematic_prior=args.kinematic_prior, angle_unit=args.angle_unit,
                       causes=(args.causes[0] if len(args.causes) == 1 and args.causes[0].endswith(".json") else args.causes) if args.causes else None,
                       **({"loss": args.loss} if args.loss != "linear" else {}))  # fmt: skip
    doc = result.to_dict()
    if args.out:
        save_result(doc, args.out)
    if args.json:
        print(json.dumps(doc, indent=2))
        return 0
    train, test = doc["metrics"]["train"], doc["metrics"]["test"]
    print(f"{doc['method']} on {doc['robot']} ({doc['measurement']}, {train['n']} training samples): "
          f"{doc['convergence']['message']} after {doc['convergence']['nit']} iterations, {doc['convergence']['time_s'] * 1e3:.0f} ms")  # fmt: skip
    print(f"  train: RMSE {train['rmse']:.4f}  MAE {train['mae']:.4f}  MAX {train['max']:.4f} mm")
    if test:
        print(f"  test:  RMSE {test['rmse']:.4f}  MAE {test['mae']:.4f}  MAX {test['max']:.4f} mm ({test['n']} samples)")
    print(f"  estimated {len(doc['free'])} parameters; fixed {len(doc['fixed'])}: " + "; ".join(f"{k} ({v})" for k, v in list(doc["fixed"].items())[:4]))
    for cause in doc.get("causes", []):
        shown = ", ".join(f"{k} {v['value']:.4g}" + (f" ± {v['std']:.2g}" if v["std"] is not None else "") + f" {v['unit']}"
                          for k, v in cause["params"].items() if v["value"] == v["value"])  # fmt: skip
        print(f"  cause {cause['label']}: {shown}")
    if "robust" in doc:
        rows = doc["robust"]["outlying_rows"]
        print(f"  {doc['robust']['loss']} loss, scale {doc['robust']['f_scale']:.3g} mm: {len(rows)} outlying rows" + (f" {rows[:12]}" + (" ..." if len(rows) > 12 else "") if rows else ""))
    for note in result.problem.data.notes:  # what the reader noticed, e.g. angles kept in an unlikely unit as asked
        print(f"  note: {note}")
    if doc["implausible"]:
        print("  warning: " + describe_implausible(doc["implausible"]))
    if doc["undetermined"]:
        widest = max(doc["undetermined"], key=lambda u: u["std"])
        combination = " ".join(f"{w:+.2f}·{n}" for n, w in widest["combination"].items())
        print(f"  {len(doc['undetermined'])} parameter combinations are undetermined (standard deviation beyond 10 mm / 2 deg); "
              f"the widest, {widest['std']:.3g} limits: {combination}")  # fmt: skip
    if args.out:
        print(f"  result written to {args.out}")
    return 0
