"""Fuzzing of every public entry point with malformed input.

The property, for every call: it either succeeds with all-finite outputs (arrays, metrics,
parameter values), or raises a :class:`robocal.exceptions.RobocalError` with a message — never
another exception type, never a crash, never a NaN or infinity in a result. Malformed means
NaN/inf, empty, beyond ±1e12, wrong shapes and dtypes (object, complex, strings, bool, int),
non-contiguous and Fortran-order arrays, degenerate configurations, singular geometry, too
few samples and wrong option types or values. ``test_bad_input.py`` holds the exact messages of
the kinematics, ``test_data_fuzz.py`` the file readers' bytes; this file covers the rest of the
API (``robocal.__all__``).
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import array_shapes, arrays

import robocal
from robocal import kernels
from robocal.compensation import Targets
from robocal.data import Dataset, write_canonical
from robocal.exceptions import InvalidParameterError, RobocalError, ShapeError

FAST = settings(max_examples=200, deadline=None)
SLOW = settings(max_examples=80, deadline=None)

R = robocal.robot("abb-irb120")
FLAT = robocal.Robot.from_dh("flat", [(0, 0, 0, 0)] * 6)  # singular geometry: the tool point never moves
Q = np.random.default_rng(0).uniform(-1.0, 1.0, (8, 6))
DATA, _ = robocal.simulate("abb-irb120", "position", samples=24, seed=5)

# -- malformed values -------------------------------------------------------------------------
SPECIAL = st.sampled_from([math.nan, math.inf, -math.inf, 1e12, 1.5e12, -1e300, 0.0, 5e-324])
ELEMENTS = st.one_of(st.floats(-1e3, 1e3), SPECIAL)
#: Things that are not arrays, or not numeric ones.
JUNK = st.sampled_from([None, "abc", "", b"xy", 5, -1, True, 2.5, 1j, [], [[1.0, 2.0], [3.0]], {"a": 1}, object(), (None,)])
LAYOUTS = ["c", "fortran", "strided", "int", "bool", "complex", "object", "str", "list"]


def _with_layout(values: np.ndarray, layout: str):
    """``values`` in another memory layout, dtype or container."""
    if layout == "fortran":
        return np.asfortranarray(values)
    if layout == "strided":
        return np.repeat(values, 2, axis=-1)[..., ::2] if values.ndim else values
    if layout == "int":
        return np.clip(np.nan_to_num(values), -(2**40), 2**40).astype(np.int64)
    if layout == "bool":
        return values > 0
    if layout == "complex":
        return values + 1j
    if layout == "object":
        return values.astype(object)
    if layout == "str":
        return values.astype(str)
    if layout == "list":
        return values.tolist()
    return values


@st.composite
def malformed(draw, shape: tuple):
    """Arrays of (mostly) ``shape`` or of any other, with NaN/inf/huge elements, in any layout
    or dtype — or junk that is no array at all."""
    if draw(st.integers(0, 9)) == 0:
        return draw(JUNK)
    shape = draw(st.one_of(st.just(shape), array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=7)))
    values = draw(arrays(np.float64, shape, elements=ELEMENTS))
    return _with_layout(values, draw(st.sampled_from(LAYOUTS)))


@st.composite
def nearly_valid(draw, value: np.ndarray):
    """``value`` with a few entries replaced by special values, in any layout."""
    out = np.array(value, dtype=np.float64, copy=True)
    for _ in range(draw(st.integers(0, 3))):
        out.flat[draw(st.integers(0, out.size - 1))] = draw(SPECIAL)
    return _with_layout(out, draw(st.sampled_from(["c", "fortran", "strided", "int", "object"])))


@st.composite
def arguments(draw, valid: dict, bad: dict):
    """Keyword arguments, each drawn from ``valid`` except up to two (or none) drawn from
    ``bad``: most calls then get past the checks of the other arguments."""
    spoilt = draw(st.lists(st.sampled_from(sorted(bad)), max_size=2, unique=True))
    return {name: draw(bad[name] if name in spoilt else strategy) for name, strategy in valid.items()}


def layouts(value) -> st.SearchStrategy:
    """``value`` in any memory layout (C, Fortran, strided, object dtype, nested lists)."""
    return st.sampled_from(["c", "fortran", "strided", "object", "list"]).map(lambda layout: _with_layout(np.asarray(value, dtype=np.float64), layout))


# -- the property -----------------------------------------------------------------------------
def assert_finite(value, where: str = "result") -> None:
    """Every number in ``value`` (arrays, dicts, lists, tuples, dataclasses) is finite."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        value = value.to_dict() if hasattr(value, "to_dict") else dataclasses.asdict(value)
    if isinstance(value, dict):
        for k, v in value.items():
            assert_finite(v, f"{where}[{k!r}]")
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            assert_finite(v, f"{where}[{i}]")
    elif isinstance(value, np.ndarray) and value.dtype.kind in "fc":
        bad = np.flatnonzero(~np.isfinite(value))
        assert bad.size == 0, f"{where}: non-finite {value.flat[bad[0]]} at flat index {bad[0]}"
    elif isinstance(value, (float, np.floating)):
        assert math.isfinite(value), f"{where}: non-finite {value}"


def outcome(call, *args, **kwargs):
    """``call(*args, **kwargs)`` if it succeeds with finite outputs (returned), None if it raises
    a RobocalError with a message; any other exception propagates and fails the test."""
    try:
        result = call(*args, **kwargs)
    except RobocalError as exc:
        assert str(exc).strip(), f"{type(exc).__name__} without a message"
        return None
    assert_finite(result)
    return result


# -- robots and kinematics --------------------------------------------------------------------
JOINT_VALUES = st.one_of(st.floats(-200, 200), SPECIAL, JUNK)
JOINT_SPEC = st.fixed_dictionaries(
    {"alpha": JOINT_VALUES, "a": JOINT_VALUES, "d": JOINT_VALUES, "theta": JOINT_VALUES},
    optional={"limits": st.one_of(st.lists(JOINT_VALUES, max_size=3), JUNK), "hayati": st.one_of(st.booleans(), JUNK)},
)
ROBOT_SPEC = st.one_of(
    st.fixed_dictionaries(
        {"joints": st.lists(st.one_of(JOINT_SPEC, JUNK), max_size=4)}, optional={"convention": st.one_of(st.sampled_from(["dh", "mdh"]), JUNK), "name": JUNK}
    ),
    JUNK,
)


def _json_default(value):
    return repr(value)


@FAST
@given(name=st.one_of(st.text(max_size=12), JUNK, st.sampled_from(["ur10", "UR10", "hsr-jr680 ", "x.json", "/", "a.yaml"])))
def test_robot_by_name(name):
    outcome(robocal.robot, name)


@FAST
@given(spec=ROBOT_SPEC, suffix=st.sampled_from([".json", ".yaml"]), raw=st.one_of(st.none(), st.binary(max_size=40)))
def test_robot_files(tmp_path_factory, spec, suffix, raw):
    path = tmp_path_factory.mktemp("robot") / f"r{suffix}"
    path.write_bytes(raw if raw is not None else json.dumps(spec, default=_json_default).encode())
    r = outcome(robocal.robot, str(path))
    if r is not None:
        outcome(r.fkine, np.zeros((2, r.n_joints)))


def test_robot_file_errors_name_the_file(tmp_path):
    for text, why in [
        ("{", "not a robot file"),
        ('{"joints": 5}', "key 'joints': input should be a valid list"),
        ('{"joints": [7]}', "joint 1: input should be a valid dictionary"),
        ("[]", "input should be a valid dictionary"),
    ]:
        path = tmp_path / "r.json"
        path.write_text(text)
        with pytest.raises(InvalidParameterError, match=why) as info:
            robocal.robot(str(path))
        assert str(path) in str(info.value)
    with pytest.raises(InvalidParameterError, match="cannot read the robot file"):
        robocal.robot(str(tmp_path / "missing.json"))
    with pytest.raises(InvalidParameterError, match="limits must be finite"):
        robocal.Robot.from_dh("x", [(0, 100, 0, 0, (10,))])


Y = {m: R.predict(m, Q) for m in robocal.MEASUREMENTS}


@FAST
@given(
    measurement=st.sampled_from(robocal.MEASUREMENTS),
    args=arguments(
        valid={
            "q": layouts(Q),
            "params": st.one_of(st.none(), layouts(R.params)),
            "cols": st.one_of(st.none(), st.just([1, 6, 30]), st.just(["a2", "tool_x"])),
        },
        bad={
            "q": st.one_of(nearly_valid(Q), malformed((8, 6))),
            "params": st.one_of(nearly_valid(R.params), malformed((R.n_params,))),
            "cols": st.one_of(
                st.lists(st.integers(-2, 50), max_size=5), malformed((R.n_params,)), st.lists(st.sampled_from(R.param_names + ["zz"]), max_size=3)
            ),
        },
    ),
    bad_measurement=st.one_of(st.none(), JUNK, st.just("Cable")),
    bad_y=st.one_of(st.none(), malformed((8, 3))),
)
def test_robot_kinematics(measurement, args, bad_measurement, bad_y):
    q, params, cols = args["q"], args["params"], args["cols"]
    y = Y[measurement] if bad_y is None else bad_y
    measurement = measurement if bad_measurement is None else bad_measurement
    outcome(R.fkine, q, params=params, tool=True)
    outcome(R.predict, measurement, q, params=params)
    outcome(R.residuals, measurement, q, y, params=params)
    outcome(R.jacobian, measurement, q, y=y, params=params, cols=cols)


@FAST
@given(name=st.sampled_from(R.param_names[::5] + ["zz", ""]), value=st.one_of(st.floats(allow_nan=True), SPECIAL, JUNK, malformed(())))
def test_with_params(name, value):
    r = outcome(R.with_params, **{name: value})
    if r is not None:
        outcome(r.fkine, Q)


def test_option_type_errors_name_the_argument():
    with pytest.raises(InvalidParameterError, match="`a2` must be"):
        R.with_params(a2="x")
    with pytest.raises(InvalidParameterError, match="`q` must be numeric.*complex"):
        R.fkine(Q + 1j)
    # A mask is not read as numbers: True would be 1 rad.
    with pytest.raises(InvalidParameterError, match="`q` must be numeric.*bool values"):
        R.fkine(Q > 0)
    with pytest.raises(ShapeError, match=r"`cols` as a boolean mask must have shape \(47,\); got \(5,\)"):
        R.jacobian("position", Q, cols=np.ones(5, bool))
    with pytest.raises(InvalidParameterError, match="`cols` must hold booleans, integer indices or parameter names"):
        R.jacobian("position", Q, cols=[0.5])
    with pytest.raises(InvalidParameterError, match="`tol` must be numeric"):
        kernels.identifiability(np.eye(3), tol="x")
    with pytest.raises(InvalidParameterError, match="`damping` must be a string; got int"):
        kernels.solve_damped(np.eye(3), np.ones(3), 0.1, 5)
    with pytest.raises(InvalidParameterError, match="`robot` must be a robot name"):
        robocal.robot(5)


def test_singular_geometry_and_degenerate_configurations():
    """A robot with every length zero (the tool point never moves) and samples all at one pose."""
    q = np.tile(Q[:1], (10, 1))
    for r, qq in ((FLAT, Q), (R, q)):
        J = outcome(r.jacobian, "position", qq, cols=np.flatnonzero(r.default_mask("position")))
        ident = outcome(identifiability, J)
        assert ident["rank"] < J.shape[1]
        outcome(kernels.solve_damped, J, np.ones(J.shape[0]), 0.0)
        outcome(kernels.covariance, J, np.ones(J.shape[0]))
        outcome(kernels.cable_initial_guess, r.fkine(qq, tool=True)[:, :3, 3], np.full(len(qq), 500.0))


# -- the core's free functions ----------------------------------------------------------------
def identifiability(J, tol=1e-9) -> dict:
    """:func:`robocal.kernels.identifiability` with the condition number of rank 0 left out: it is
    documented as inf (``sigma_1 / sigma_rank`` has no denominator)."""
    ident = kernels.identifiability(J, tol)
    assert ident["rank"] > 0 or ident["condition_number"] == math.inf
    return {**ident, "condition_number": 0.0 if ident["rank"] == 0 else ident["condition_number"]}


SCALARS = st.one_of(st.floats(allow_nan=True, allow_infinity=True), SPECIAL, JUNK)


J0 = np.random.default_rng(1).normal(size=(6, 3))


@FAST
@given(
    args=arguments(
        valid={
            "J": layouts(J0),
            "r": layouts(np.arange(6.0)),
            "lam": st.sampled_from([0.0, 1e-3, 1e9]),
            "tol": st.sampled_from([1e-9, 0.5]),
            "damping": st.sampled_from(["marquardt", "identity"]),
        },
        bad={
            "J": st.one_of(nearly_valid(J0), malformed((6, 3))),
            "r": st.one_of(nearly_valid(np.arange(6.0)), malformed((6,))),
            "lam": SCALARS,
            "tol": SCALARS,
            "damping": st.one_of(st.just("Marquardt"), JUNK),
        },
    )
)
def test_linear_algebra(args):
    J, r = args["J"], args["r"]
    outcome(identifiability, J, tol=args["tol"])
    outcome(kernels.solve_damped, J, r, args["lam"], args["damping"])
    outcome(kernels.covariance, J, r, args["tol"])


P_CABLE = R.fkine(np.vstack([Q, -Q]), tool=True)[:, :3, 3]


@FAST
@given(
    args=arguments(
        valid={"p": layouts(P_CABLE), "L": layouts(np.linalg.norm(P_CABLE - [900.0, 100.0, -50.0], axis=1))},
        bad={"p": st.one_of(nearly_valid(P_CABLE), malformed((16, 3))), "L": st.one_of(nearly_valid(np.full(16, 500.0)), malformed((16,)))},
    )
)
def test_cable_initial_guess(args):
    outcome(kernels.cable_initial_guess, args["p"], args["L"])


SIGMAS, WM, WC = kernels.merwe_sigma_points(np.zeros(3), np.eye(3))


@FAST
@given(
    args=arguments(
        valid={
            "x": layouts(np.ones(3)),
            "P": layouts(np.diag([1.0, 2.0, 3.0])),
            "alpha": st.just(1e-3),
            "beta": st.just(2.0),
            "kappa": st.just(0.0),
            "sigmas_y": layouts(SIGMAS[:, :2] ** 2),
            "Wc": layouts(WC),
        },
        bad={
            "x": malformed((3,)),
            "P": st.one_of(nearly_valid(np.eye(3)), malformed((3, 3))),
            "alpha": SCALARS,
            "beta": SCALARS,
            "kappa": SCALARS,
            "sigmas_y": st.one_of(nearly_valid(SIGMAS[:, :2]), malformed((7, 2))),
            "Wc": st.one_of(nearly_valid(WC), malformed((7,))),
        },
    )
)
def test_sigma_points(args):
    outcome(kernels.merwe_sigma_points, args["x"], args["P"], args["alpha"], args["beta"], args["kappa"])
    outcome(kernels.unscented_transform, SIGMAS, args["sigmas_y"], WM, args["Wc"])


# -- simulate ---------------------------------------------------------------------------------
@SLOW
@given(
    args=arguments(
        valid={
            "robot": st.sampled_from(["ur10", "abb-irb120"]),
            "measurement": st.sampled_from(robocal.MEASUREMENTS),
            "samples": st.integers(1, 6),
            "seed": st.integers(0, 2**64),
            "noise": st.sampled_from([None, 0, 0.1, {"sigma": 0.5}]),
            "dt": st.sampled_from([0.1, 2.0]),
            "outliers": st.sampled_from([0.0, 0.5]),
            "tool": st.sampled_from([None, (0.0, 0.0, 100.0)]),
            "effects": st.sampled_from([(), ["backlash:joint=2"], ["joint_periodic:joint=3,amplitude=0.01"]]),
        },
        bad={
            "robot": JUNK,
            "measurement": st.one_of(JUNK, st.just("Pose")),
            "samples": st.one_of(st.integers(-1, 0), JUNK),
            "seed": st.one_of(st.integers(-5, -1), JUNK),
            "noise": st.one_of(SCALARS, st.dictionaries(st.sampled_from(["sigma", "resolution", "x"]), SCALARS, min_size=1, max_size=2)),
            "dt": SCALARS,
            "outliers": SCALARS,
            "tool": malformed((3,)),
            "effects": st.one_of(
                st.lists(st.sampled_from(["backlash:joint=9", "drift:rate=nan", "joint_scale:joint=2,scale=1e300", "x", ""]), min_size=1, max_size=2), JUNK
            ),
        },
    )
)
def test_simulate(args):
    outcome(robocal.simulate, **args)


def test_simulate_options_name_the_argument():
    for kwargs, message in [
        ({"dt": "x"}, "`dt`"),
        ({"seed": -1}, "`seed` must be None or an integer >= 0"),
        ({"tool": "abc"}, "`tool`"),
        ({"effects": 5}, "`effects` must be a list"),
        ({"noise": {"sigma": "x"}}, "`noise sigma`"),
    ]:
        with pytest.raises(InvalidParameterError, match=message):
            robocal.simulate("ur10", "position", samples=3, **kwargs)


# -- calibrate --------------------------------------------------------------------------------
def _dataset(q, y, robot="abb-irb120") -> Dataset:
    return Dataset(q=q, y=y, measurement="position", robot=robot)


DEGENERATE = {
    "one pose": _dataset(np.tile(DATA.q[:1], (24, 1)), np.tile(DATA.y[:1], (24, 1))),
    "joint 2 constant": _dataset(np.column_stack([DATA.q[:, :1], np.full(24, 0.3), DATA.q[:, 2:]]), DATA.y),
    "three samples": DATA.subset([0, 1, 2]),
    "one sample": DATA.subset([0]),
    "y far away": _dataset(DATA.q, DATA.y + 1e9),
    "y zero": _dataset(DATA.q, np.zeros_like(DATA.y)),
    "noiseless copy of one row": _dataset(np.tile(DATA.q[:1], (24, 1)) + 1e-12, np.tile(DATA.y[:1], (24, 1))),
}
#: Options of ``calibrate`` (and of method ``lm``), each valid or malformed.
OPTION_VALUES = {
    "test_fraction": st.one_of(st.sampled_from([0.0, 0.2, 0.9]), SCALARS),
    "seed": st.one_of(st.integers(-1, 3), JUNK),
    "mask": st.one_of(st.just(["a2", "d3"]), st.just([]), malformed((R.n_params,)), st.lists(st.integers(-1, 60), max_size=3)),
    "prior": st.one_of(st.just({"a2": (0.0, 1.0)}), st.just({"a2": "x"}), st.just({"zz": (0, 1)}), JUNK),
    "bounds": st.one_of(st.just({"a2": (-1e6, 1e6)}), st.just({"a2": (1, 0)}), st.just({"a2": (math.nan, 1)}), JUNK),
    "kinematic_prior": st.one_of(st.just((1.0, 0.1)), st.tuples(SCALARS, SCALARS), JUNK),
    "max_nfev": st.one_of(st.integers(-1, 5), JUNK),
    "ftol": SCALARS,
    "lam0": SCALARS,
    "loss": st.one_of(st.sampled_from(["linear", "huber", "cauchy"]), JUNK),
    "f_scale": SCALARS,
    "causes": st.one_of(st.just(["backlash joint 2"]), st.just({"model": {"causes": 5}}), JUNK),
    "no_such_option": st.just(1),
}
#: Up to two of them at a time, so that most calls get past the checks of the others.
OPTIONS = st.lists(st.sampled_from(sorted(OPTION_VALUES)), max_size=2, unique=True).flatmap(
    lambda names: st.fixed_dictionaries({n: OPTION_VALUES[n] for n in names})
)


@SLOW
@given(case=st.sampled_from(sorted(DEGENERATE)), options=OPTIONS, method=st.one_of(st.just("lm"), JUNK, st.just(["lm"])))
def test_calibrate_dataset(case, options, method):
    outcome(robocal.calibrate, DEGENERATE[case], method=method, **options)


@SLOW
@given(
    q=nearly_valid(DATA.q),
    y=nearly_valid(DATA.y),
    robot=st.one_of(st.sampled_from(["abb-irb120", "ur10"]), JUNK, st.just(robocal.Robot.from_dh("three", [(0, 100, 0, 0)] * 3)), st.just(FLAT)),
)
def test_calibrate_special_values(q, y, robot):
    try:
        dataset = _dataset(q, y)  # a container: it may hold NaN, the calibration may not
    except RobocalError:
        return
    outcome(robocal.calibrate, dataset, robot=robot, method="lm", max_nfev=20)


@SLOW
@given(case=st.sampled_from(sorted(DEGENERATE)), measurement=st.one_of(st.none(), st.sampled_from(robocal.MEASUREMENTS), JUNK))
def test_calibrate_path(tmp_path_factory, case, measurement):
    path = write_canonical(DEGENERATE[case], tmp_path_factory.mktemp("cal") / "data.csv")
    outcome(robocal.calibrate, str(path), measurement=measurement, max_nfev=20)
    outcome(robocal.calibrate, Path(path), robot="abb-irb120", test_fraction=0.0, max_nfev=20)


COUNT = st.one_of(st.integers(-2, 0), JUNK)
COVARIANCE = st.one_of(SCALARS, malformed((3,)))
#: Per method: cheap valid options, and malformed ones.
METHOD_OPTIONS = {
    "ekf": ({"sweeps": st.just(1), "R": st.none()}, {"sweeps": COUNT, "R": COVARIANCE}),
    "ukf": (
        {"sweeps": st.just(1), "P0": st.none(), "Q": st.none(), "alpha": st.just(0.1), "x0": st.none()},
        {"sweeps": COUNT, "P0": COVARIANCE, "Q": COVARIANCE, "alpha": SCALARS, "x0": malformed((27,))},
    ),
    "ukf-vslm": ({"sweeps": st.just(1), "max_iter": st.just(3), "mu": st.just(0.95)}, {"sweeps": COUNT, "max_iter": COUNT, "mu": SCALARS}),
    "vslm": (
        {"max_iter": st.just(3), "delta0": st.just(0.8), "lam": st.just(1e-6), "ftol": st.just(1e-10)},
        {"max_iter": COUNT, "delta0": SCALARS, "lam": SCALARS, "ftol": SCALARS},
    ),
    "lm-paper": ({"max_iter": st.just(3), "lam": st.just(1e-6)}, {"max_iter": COUNT, "lam": SCALARS}),
    "pso": (
        {"population": st.just(6), "max_iter": st.just(3), "w": st.just((0.9, 0.4)), "c1": st.just(2.0), "vmax": st.just(0.2)},
        {"population": COUNT, "max_iter": st.one_of(st.just(-1), JUNK), "w": st.one_of(SCALARS, malformed((2,))), "c1": SCALARS, "vmax": SCALARS},
    ),
    "de": (
        {"population": st.just(6), "max_iter": st.just(3), "F": st.just(0.5), "CR": st.just(0.9)},
        {"population": st.one_of(st.integers(0, 3), JUNK), "max_iter": st.one_of(st.just(-1), JUNK), "F": SCALARS, "CR": SCALARS},
    ),
    "bas": (
        {"max_iter": st.just(5), "step": st.just(0.5), "antenna_ratio": st.just(0.5)},
        {"max_iter": st.one_of(st.just(-1), JUNK), "step": SCALARS, "antenna_ratio": SCALARS},
    ),
    "rbf": ({"n_centers": st.just(3), "ridge": st.just(1e-6)}, {"n_centers": COUNT, "ridge": SCALARS}),
}


@SLOW
@given(case=st.sampled_from(sorted(METHOD_OPTIONS)).flatmap(lambda m: st.tuples(st.just(m), arguments(*METHOD_OPTIONS[m]))))
def test_method_options(case):
    method, options = case
    outcome(robocal.calibrate, DATA, method=method, **options)


@pytest.mark.parametrize("method", ["ukf", "ukf-vslm", "pso", "de", "rbf", "ekf", "vslm", "lm-paper", "bas"])
def test_every_method_on_degenerate_data(method):
    """All samples at one pose: every method ends finite or says why it cannot."""
    fast = {"pso": {"max_iter": 3}, "de": {"max_iter": 3}, "bas": {"max_iter": 3}}.get(method, {})
    outcome(robocal.calibrate, DEGENERATE["one pose"], method=method, **fast)
    outcome(robocal.calibrate, DEGENERATE["three samples"], method=method, **fast)


def test_calibrate_options_name_the_problem():
    for kwargs, message in [
        ({"method": ["lm"]}, "unknown method"),
        ({"test_fraction": "x"}, "`test_fraction`"),
        ({"seed": "x"}, "`seed`"),
        ({"mask": []}, "`mask` must select at least one"),
        ({"prior": [1]}, "`prior` must be a mapping"),
        ({"foo": 1}, "does not take these options.*foo"),
        ({"max_nfev": "x"}, "`max_nfev` must be an integer"),
        ({"robot": 5}, "`robot` must be"),
        ({"causes": 5}, "`causes` must be"),
    ]:
        with pytest.raises(InvalidParameterError, match=message):
            robocal.calibrate(DATA, **kwargs)
    with pytest.raises(RobocalError, match="`path` must be a file path"):
        robocal.calibrate(5)


# -- diagnose ---------------------------------------------------------------------------------
@settings(max_examples=20, deadline=None)
@given(
    case=st.sampled_from(["one pose", "joint 2 constant", "three samples", "y far away"]),
    args=arguments(
        valid={"folds": st.just(2), "alpha": st.just(0.05), "max_effects": st.just(1), "min_gain": st.just(0.005), "groups": st.none(), "seed": st.just(0)},
        bad={
            "folds": st.one_of(st.integers(-1, 1), JUNK),
            "alpha": SCALARS,
            "max_effects": st.one_of(st.integers(-1, 0), JUNK),
            "min_gain": SCALARS,
            "groups": st.one_of(JUNK, st.just(np.arange(5))),
            "seed": st.one_of(st.integers(-2, -1), JUNK),
        },
    ),
)
def test_diagnose(case, args):
    outcome(robocal.diagnose, DEGENERATE[case], **args)


# -- results, compensation, loading ----------------------------------------------------------
RESULT = robocal.calibrate(DATA, method="lm").to_dict()
#: An extended model: its joint causes are applied by compensate.
EXTENDED = robocal.calibrate(DATA, causes=["joint_scale joint 2", "joint_periodic joint 3 harmonic=2"]).to_dict()


@st.composite
def mangled(draw, doc):
    """``doc`` (JSON) with up to three leaves or keys deleted or replaced by junk."""
    doc = json.loads(json.dumps(doc))
    for _ in range(draw(st.integers(1, 3))):
        node = doc
        while isinstance(node, (dict, list)) and node and draw(st.booleans()):
            key = draw(st.sampled_from(sorted(node) if isinstance(node, dict) else range(len(node))))
            if not isinstance(node[key], (dict, list)) or not node[key]:
                break
            node = node[key]
        if isinstance(node, (dict, list)) and node:
            key = draw(st.sampled_from(sorted(node) if isinstance(node, dict) else range(len(node))))
            if draw(st.booleans()):
                del node[key]
            else:
                node[key] = draw(st.one_of(st.sampled_from([None, "x", -1, 1e308, [], {}, [1, 2], "NaN"]), st.floats()))
    return doc


def calibrated_params(source) -> np.ndarray:
    """The calibrated parameters of a result (the document itself comes back as it was given)."""
    return robocal.load_result(source)[0].params


@FAST
@given(doc=mangled(RESULT))
def test_load_result_wrong_schema(doc):
    if outcome(calibrated_params, doc) is not None:
        outcome(robocal.load_result(doc)[0].fkine, Q)


@FAST
@given(
    text=st.one_of(st.binary(max_size=60), mangled(RESULT).map(lambda d: json.dumps(d).encode()), st.just(b"NaN"), st.just(b'{"schema": "robocal.result/1"}'))
)
def test_load_result_corrupt_files(tmp_path_factory, text):
    path = tmp_path_factory.mktemp("res") / "result.json"
    path.write_bytes(text)
    outcome(calibrated_params, path)


@FAST
@given(
    result=st.one_of(mangled(RESULT), mangled(EXTENDED["causes"]).map(lambda causes: {**EXTENDED, "causes": causes}), JUNK),
    y=st.one_of(malformed((2, 3)), nearly_valid(R.fkine(Q[:2], tool=True)[:, :3, 3])),
    seeds=st.one_of(st.none(), malformed((2, 6))),
)
def test_compensate(result, y, seeds):
    try:
        targets = Targets(y, seeds, np.arange(2, 4))
    except RobocalError:
        return
    outcome(robocal.compensate, result, targets)


@FAST
@given(body=st.lists(st.sampled_from(["1", "nan", "1e300", "x", "", "-5"]), min_size=3, max_size=9))
def test_compensate_target_files(tmp_path_factory, body):
    path = tmp_path_factory.mktemp("targets") / "t.csv"
    rows = [body[i : i + 3] for i in range(0, len(body) - 2, 3)]
    path.write_text("x,y,z\n" + "\n".join(",".join(row) for row in rows) + "\n")
    outcome(robocal.compensate, RESULT, path)


@FAST
@given(
    path=st.one_of(JUNK, st.sampled_from(["/nonexistent.csv", "/", ""])),
    options=st.fixed_dictionaries(
        {}, optional={"format": st.one_of(st.sampled_from(["canonical", "x"]), JUNK), "measurement": JUNK, "angle_unit": JUNK, "robot": JUNK, "sheet": JUNK}
    ),
)
def test_load_paths_and_options(tmp_path_factory, path, options):
    outcome(robocal.load, path, **options)
    good = write_canonical(DATA.subset([0, 1, 2]), tmp_path_factory.mktemp("load") / "d.csv")
    outcome(robocal.load, good, **options)


# -- calibrate_many ---------------------------------------------------------------------------
@settings(max_examples=8, deadline=None)
@given(
    items=st.lists(st.one_of(st.sampled_from(sorted(DEGENERATE)), JUNK), max_size=3),
    workers=st.one_of(st.none(), st.integers(-1, 2)),
    backend=st.one_of(st.sampled_from(["serial", "thread"]), JUNK),
)
def test_calibrate_many(items, workers, backend):
    datasets = [DEGENERATE[i] if isinstance(i, str) and i in DEGENERATE else i for i in items]
    results = outcome(robocal.calibrate_many, datasets, workers=workers, backend=backend, max_nfev=10)
    if results is not None:
        assert len(results) == len(datasets)
        for doc in results:
            assert "error" in doc or doc["schema"] == "robocal.result/1"


@pytest.mark.parametrize(
    "kwargs", [{"datasets": 5}, {"datasets": None}, {"datasets": "abc"}, {"datasets": [DATA], "workers": "x"}, {"datasets": [DATA], "workers": 2.5}]
)
def test_calibrate_many_arguments_name_the_problem(kwargs):
    with pytest.raises(InvalidParameterError):
        robocal.calibrate_many(backend="serial", max_nfev=5, **kwargs)
