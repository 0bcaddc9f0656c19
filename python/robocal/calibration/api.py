"""The geometric calibration's steps: the inputs loaded and checked, the held-out split, the fit
by a method of :data:`METHODS`. The public :func:`robocal.calibrate`
(:mod:`robocal.causes.extended`, which adds extended models) checks its arguments and runs them."""

from __future__ import annotations

import inspect
from pathlib import Path
from typing import Callable, Optional, Union

import numpy as np

from ..catalog import BUILTIN
from ..kernels import as_float
from ..data.dataset import Dataset
from ..data.loader import load
from ..data.splits import configuration_groups, random_split
from ..exceptions import DataError, InvalidParameterError
from ..robot import Robot, robot as load_robot, setup_names
from . import cascade, kalman, metaheuristics, rbf, vslm
from .lm import levenberg_marquardt
from .problem import TOLERANCE, Problem, check_observations, check_readings, start_parameters
from .result import CalibrationResult, describe_implausible, grossly_implausible

#: method name -> (paper label, description, function(problem, **options) -> CalibrationResult)
METHODS: dict[str, tuple[str, str, Callable[..., CalibrationResult]]] = {
    "lm": ("-", "robocal's production Levenberg-Marquardt (adaptive damping)", levenberg_marquardt),
    **kalman.METHODS,
    **vslm.METHODS,
    **cascade.METHODS,
    **metaheuristics.METHODS,
    **rbf.METHODS,
}


def method_choices() -> str:
    """The method names with the paper's labels, for help and errors (the tables say "M1 EKF"):
    ``"bas (M2), de (M7), ekf (M1), lm, ..."``."""
    return ", ".join(name if label == "-" else f"{name} ({label})" for name, (label, _, _) in sorted(METHODS.items()))


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
    named = getattr(data, "attrs", {}).get("robot") if not isinstance(data, (str, Path, Dataset)) else None  # a DataFrame's own
    # The robot goes to the reader in either form: its prismatic joints' columns are mm, not angles.
    dataset = data if isinstance(data, Dataset) else load(data, measurement=measurement, angle_unit=angle_unit, robot=robot)
    if measurement is not None and dataset.measurement != measurement:
        raise InvalidParameterError(f"the data hold {dataset.measurement} measurements, not {measurement}")
    if robot is None:
        if dataset.robot is None:
            raise InvalidParameterError("the data do not name their robot: pass `robot`")
        robot = dataset.robot
    model = robot if isinstance(robot, Robot) else load_robot(robot)
    if named is None and (isinstance(data, Dataset) or not isinstance(robot, str)):  # `load` checked a file against a name
        named = dataset.robot
    _check_named_robot(dataset, named, model)
    return dataset, model


def _check_named_robot(dataset: Dataset, named, model: Robot) -> None:
    """An error when the data name a built-in robot and ``model`` is another built-in one (one
    robot's data can fit another's geometry closely with absurd parameters: docs/findings.md,
    D3); a note on ``dataset`` when ``model`` is a robot of the user's own under another name."""
    if not isinstance(named, str) or named not in BUILTIN or named == model.name:
        return
    where = f" ({dataset.source})" if dataset.source else ""
    if model.name in BUILTIN:
        raise InvalidParameterError(f"the data{where} are of robot {named!r}; the robot given is {model.name!r}: pass the robot the data were measured on")
    dataset.notes.append(f"the data name robot {named!r}; used as asked: robot {model.name!r}")


def another_robot(robot: Robot, dataset: Dataset) -> Optional[str]:
    """Why ``dataset`` is probably not of ``robot`` (or not in its units), else None: a geometric
    fit (LM, every sample) moves kinematic parameters beyond
    :data:`~robocal.calibration.result.GROSS_FACTOR` times their plausibility limits (100 mm,
    20°) — what ``calibrate`` warns of (:func:`~robocal.calibration.result.describe_implausible`).
    The fit holds the manufacturing-tolerance prior (:data:`~robocal.calibration.problem.TOLERANCE`,
    against the sensor's noise, as diagnose's physical model): what the data leave undetermined
    stays near nominal (without it, 120 cable samples of the right robot, RobotCali.xlsx, move
    parameters by hundreds of mm), what they determine goes where the data put it. A fit on
    nominal kinematics alone cannot tell: its set-up (a cable's anchor, a tracker's frame) absorbs
    much of another robot's geometry. None too when the data cannot be fitted (too few
    configurations): the fit's own checks say so where a fit is made."""
    tolerance = (TOLERANCE["mm"], float(np.degrees(TOLERANCE["rad"])))
    try:
        flags = levenberg_marquardt(Problem.build(robot, dataset, kinematic_prior=tolerance)).implausible()
    except (DataError, InvalidParameterError):
        return None
    return f"the data do not fit {robot.name}: {describe_implausible(flags)}" if grossly_implausible(flags) else None


def held_out_residuals(result: CalibrationResult, test: Dataset) -> np.ndarray:
    """Residuals ``y − prediction`` of a fitted ``result`` on held-out samples, flattened.

    A corrector (M5, :class:`~robocal.calibration.rbf.RBFResult`) changes the prediction, not the
    parameters: it is evaluated as it predicts (its corrected residuals). Every other method is
    evaluated with its parameters on the training problem's parameterisation.
    """
    if isinstance(result, rbf.RBFResult):
        return result.corrected_residuals(test)
    return result.problem.with_data(test).data_residuals(result.x)


def fit(problem: Problem, method: str, seed: int, options: dict) -> CalibrationResult:
    """``problem`` fitted by ``method`` (one of :data:`METHODS`, checked by the caller) with its
    ``options``, refused by name if the method does not take them; a stochastic method also
    takes ``seed``."""
    function = METHODS[method][2]
    if "seed" in inspect.signature(function).parameters:
        options = {**options, "seed": seed}
    return function(problem, **checked_options(function, method, options))


def check_method(method) -> None:
    if not isinstance(method, str) or method not in METHODS:
        raise InvalidParameterError(f"unknown method {method!r}; choose one of {method_choices()}")


def check_test_fraction(test_fraction) -> float:
    test_fraction = as_float(test_fraction, "test_fraction")
    if not 0.0 <= test_fraction < 1.0:
        raise InvalidParameterError(f"`test_fraction` must lie in [0, 1); got {test_fraction}")
    return test_fraction


def held_out_problem(robot: Robot, dataset: Dataset, test_fraction: float, seed: int, **build) -> tuple[Problem, np.ndarray, Optional[np.ndarray]]:
    """The :class:`Problem` on the training samples of a seeded random split (``Problem.build``
    options in ``build``), the training and the held-out indices (None when ``test_fraction`` is 0).

    The split keeps every joint configuration whole (:func:`~robocal.data.splits.configuration_groups`):
    a repeated row on both sides would make the held-out error a training error."""
    check_readings(robot, dataset)  # before the configurations are grouped: a bad value named by its row
    labels = configuration_groups(dataset.q)
    train_idx, test_idx = np.arange(len(dataset)), None
    if test_fraction > 0:
        train_idx, test_idx = random_split(len(dataset), test_fraction=test_fraction, seed=seed, groups=labels)
    points = check_observations(robot, dataset, labels)  # held-out samples too: a wrong reading there would only inflate the test error
    try:
        # the training samples are checked with the rest: build takes their labels and points
        train, observed = (dataset, (labels, points)) if test_idx is None else (dataset.subset(train_idx), (labels[train_idx], points[train_idx]))
        problem = Problem.build(robot, train, observations=observed, **build)
        problem.require_dof()
    except (DataError, InvalidParameterError) as exc:
        if test_idx is None or "too few" not in str(exc) and "degrees of freedom" not in str(exc):
            raise
        # The user counts the file's samples: say where the others went.
        held = f"; these are the training samples: {len(test_idx)} of the {len(dataset)} are held out (`test_fraction`)"
        if isinstance(exc, DataError):
            raise DataError(exc.message + held, exc.path, exc.row, exc.column) from None
        raise InvalidParameterError(str(exc) + held) from None
    return problem, train_idx, test_idx


def checked_options(function: Callable, method: str, options: dict) -> dict:
    """``options`` if ``function(problem, **options)`` accepts them, else an error naming them."""
    try:
        inspect.signature(function).bind(None, **options)
    except TypeError as exc:
        raise InvalidParameterError(f"method {method!r} does not take these options: {exc}") from None
    return options


def nominal_residuals(robot: Robot, data: Dataset) -> np.ndarray:
    """Residuals (m, k) of ``robot``'s kinematics as they stand on ``data``, with the session's
    set-up and the tool point fitted (:func:`~robocal.calibration.problem.start_parameters`,
    then a least-squares fit of those alone — a pose's tool orientation too): the "nominal"
    figure ``verify`` and the report give beside a calibration's (a nominal robot knows no tool
    point to keep)."""
    names = list(dict.fromkeys(setup_names(robot, data.measurement) + [n for n in ("tool_x", "tool_y", "tool_z") if n in robot.param_names]))
    problem = Problem.build(robot, data, mask=names, params=start_parameters(robot, data))
    return problem.data_residuals(levenberg_marquardt(problem).x).reshape(len(data), -1)
