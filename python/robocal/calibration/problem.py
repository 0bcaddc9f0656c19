"""A calibration problem: robot, data, which parameters are estimated, and where they start.

Every calibrator works on the same :class:`Problem`: a residual ``r(x) = y − h(θ(x))`` and its
identification Jacobian ``J = ∂h/∂x`` over the free parameters ``x = θ[free]``. By default the
free set is the *identifiable* subset of the robot's default mask for the measurement type,
decided from the data at the start point; every parameter left out says why.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Mapping, Optional

import numpy as np

from ..kernels import as_float_array, cable_initial_guess, solve_damped
from ..data.dataset import Dataset
from ..data.splits import configuration_groups
from ..exceptions import DataError, InvalidParameterError, NonFiniteError
from ..geometry import frame_params, kabsch
from ..robot import RESIDUAL_WIDTH, Robot
from ..sensors import DEFAULT_NOISE


#: Parameter-name prefixes of the kinematic (joint) parameters, as opposed to the set-up (base,
#: tool, anchor, sensor) that every calibration fits from scratch.
KINEMATIC = ("alpha", "a", "d", "theta", "beta")

#: Deviations from nominal beyond which a calibrated kinematic parameter is flagged implausible
#: (mm, rad): manufacturing and assembly errors of industrial arms are tenths of a mm to a few
#: mm and hundredths to tenths of a degree; 10 mm or 2 degrees is a curve fit, not a calibration.
PLAUSIBLE = {"mm": 10.0, "rad": np.radians(2.0)}
#: Standard deviations of the manufacturing-tolerance prior of a physical model (mm, rad): what
#: the geometry of an industrial arm deviates from its drawing, as a Gaussian at nominal.
TOLERANCE = {"mm": 1.0, "rad": np.radians(0.1)}
#: Sigmas a ``kinematic_prior`` may take (mm, deg): below, the prior rows' weights overflow the
#: kernels' squares; above, it constrains nothing.
KINEMATIC_PRIOR_RANGE = {"mm": (1e-6, 1e6), "deg": (1e-6, 360.0)}
#: Distinct joint configurations the closed-form start of each measurement needs: a cable's
#: anchor and zero (4 unknowns, the differences of squared lengths), a tracker's frame (Kabsch).
MIN_CONFIGURATIONS = {"cable": 5, "position": 3, "pose": 3}
#: The measured points' spread against the robot's tool points' at the same joint values
#: (median distance from the median point; for cables, the lengths' spread) beyond which the
#: observations are in another unit than mm: a rigid frame keeps distances (ratio about 1), a
#: cable's length varies by a fraction of the points' spread (the public cable data's: docs/findings.md, D1).
SCALE_RATIO = {"cable": (0.02, 20.0), "position": (0.1, 10.0), "pose": (0.1, 10.0)}
#: A sample whose observation lies further from the median than this many times the largest
#: distance between the robot's tool points cannot be a reading of that robot: no rigid frame or
#: cable makes two readings differ by more than their points do.
IMPOSSIBLE_SPREAD = 10.0
#: Unit factors (measured / mm) that name a likely unit in the messages.
LIKELY_UNITS = {"metres": 1e-3, "centimetres": 1e-1, "inches": 1 / 25.4, "micrometres": 1e3}


def is_kinematic(name: str) -> bool:
    """True for a joint parameter (``alpha3``, ``d6``, ...), False for base, tool and sensor."""
    return name.rstrip("0123456789") in KINEMATIC


def kinematic_prior_sigmas(kinematic_prior) -> dict:
    """A ``kinematic_prior`` ``(mm, deg)`` checked, as the sigmas :func:`kinematic_prior_pairs`
    takes (``{"mm": ..., "rad": ...}``)."""
    try:
        length, angle = (float(v) for v in kinematic_prior)
    except (TypeError, ValueError):
        raise InvalidParameterError(f"`kinematic_prior` must be (mm, deg); got {kinematic_prior!r}") from None
    (mm_low, mm_high), (deg_low, deg_high) = KINEMATIC_PRIOR_RANGE["mm"], KINEMATIC_PRIOR_RANGE["deg"]
    if not (mm_low <= length <= mm_high and deg_low <= angle <= deg_high):
        raise InvalidParameterError(
            f"`kinematic_prior` must be (mm, deg) sigmas in [{mm_low:g}, {mm_high:g}] mm and [{deg_low:g}, {deg_high:g}] deg; got ({length:g}, {angle:g})"
        )
    return {"mm": length, "rad": np.radians(angle)}


def kinematic_prior_pairs(robot: Robot, names, means: dict, sigma: dict) -> dict:
    """``name -> (mean, sigma[unit])`` for the kinematic parameters among ``names`` whose unit
    ``sigma`` gives (mm, rad); ``means`` maps each name to its prior mean."""
    units = dict(zip(robot.param_names, robot.param_units))
    return {n: (float(means[n]), sigma[units[n]]) for n in names if n in units and is_kinematic(n) and units[n] in sigma}


def implausible_parameters(robot: Robot, values: dict) -> list[dict]:
    """The kinematic parameters of ``values`` (``name -> value``) further from nominal than
    :data:`PLAUSIBLE`: ``{name, unit, deviation, limit}`` each."""
    flagged = []
    for name, value in values.items():
        if name in robot.param_names and is_kinematic(name):
            k = robot.index(name)
            unit, deviation = robot.param_units[k], float(value - robot.params[k])
            if unit in PLAUSIBLE and abs(deviation) > PLAUSIBLE[unit]:
                flagged.append({"name": name, "unit": unit, "deviation": deviation, "limit": float(PLAUSIBLE[unit])})
    return flagged


#: :func:`start_parameters` fits the set-up on every k-th sample, about this many of them.
START_SAMPLES = 2000


def redundancy_words(partners) -> str:
    """Why a parameter is held fixed: ``partners`` — (name, coefficient on unit-norm columns) of the
    identifiable parameters that reproduce its effect — the three strongest named."""
    strongest = sorted(partners, key=lambda p: -abs(p[1]))[:3]
    if not strongest:
        return "no effect on the measurements"
    return "redundant with " + ", ".join(f"{name} ({c:+.3g})" for name, c in strongest)


def start_parameters(robot: Robot, data: Dataset, params: Optional[np.ndarray] = None, points: Optional[np.ndarray] = None) -> np.ndarray:
    """Nominal kinematics plus a fitted measurement set-up.

    Cable: the anchor and sensor zero in closed form (:func:`robocal.cable_initial_guess`).
    Position and pose: the base frame (measurement frame → robot base) that best maps the
    nominal tool points onto the measured points (Kabsch). Then a few Gauss-Newton steps on the
    set-up and the tool point alone, kinematics held nominal: the closed forms minimise
    algebraic errors that the unknown tool offset biases. Nothing needs to be supplied.
    ``points``: the nominal tool points of ``data`` (m, 3) where the caller has them
    (:func:`check_observations` returns them), used when ``params`` is None.
    """
    p = robot.params.copy() if params is None else np.array(params, dtype=np.float64)
    if data.measurement == "cable":
        if points is None or params is not None:
            points = robot.fkine(data.q, params=p, tool=True)[:, :3, 3]
        anchor, offset = cable_initial_guess(points, data.y[:, 0])
        setup = [robot.index(n) for n in ("anchor_x", "anchor_y", "anchor_z", "cable_offset")]
        p[setup] = (*anchor, offset)
    else:
        base = [robot.index(f"base_{c}") for c in ("x", "y", "z", "rx", "ry", "rz")]
        p_no_base = p.copy()
        p_no_base[base] = 0.0
        local = robot.fkine(data.q, params=p_no_base, tool=True)[:, :3, 3]
        p[base] = frame_params(kabsch(local, data.y[:, :3]))
        setup = base
    cols = setup + [robot.index(n) for n in ("tool_x", "tool_y", "tool_z")]
    # On a subsample of START_SAMPLES spread over the data: a start, which the fit refines with
    # every other parameter on every sample (steps on every sample here cost four residual and
    # Jacobian evaluations of 20 000 samples and moved the fit's result by nothing but the split of
    # a redundant pair, a6 + tool_x, between its members).
    every = max(len(data) // START_SAMPLES, 1)
    q, y = data.q[::every], data.y[::every]
    for _ in range(20):
        r, J = robot.residuals_and_jacobian(data.measurement, q, y, params=p, cols=cols)
        step, _ = solve_damped(J, r.ravel(), 1e-9)
        p[cols] += step
        if np.max(np.abs(step)) < 1e-9:
            break
    return p


def _spread(points: np.ndarray) -> np.ndarray:
    """Distances of ``points`` (m, k) from their median point, column by column: the same values
    as NumPy's median and norm along the short axis of a C-ordered (m, k) array, in 0.7 ms
    instead of 1.1 on 20 000 rows."""
    offsets = [column - np.median(column) for column in points.T]
    return np.sqrt(sum(d * d for d in offsets))


def check_readings(robot: Robot, data: Dataset) -> None:
    """An error when ``data`` have another joint count than ``robot`` or values that are not
    finite (the sample and its row named): what every other check of the observations assumes."""
    if data.n_joints != robot.n_joints:
        raise InvalidParameterError(f"the data have {data.n_joints} joints but robot {robot.name!r} has {robot.n_joints}")
    for name, values in (("q", data.q), ("y", data.y)):
        if not np.isfinite(values).all():
            bad = np.argwhere(~np.isfinite(values))[0]
            raise NonFiniteError(f"the data's `{name}` must be finite; got {values[tuple(bad)]} in sample {bad[0]} (row {data.rows[bad[0]]})")


def distinct_configurations(data: Dataset, labels: np.ndarray) -> int:
    """The count of distinct joint configurations among ``labels`` (one per sample of ``data``,
    :func:`~robocal.data.splits.configuration_groups`, or a subset of such labels), or an error
    when there are too few to place the sensor (:data:`MIN_CONFIGURATIONS`)."""
    distinct = int(np.count_nonzero(np.bincount(labels))) if len(labels) else 0
    kind = data.measurement
    if distinct < MIN_CONFIGURATIONS[kind]:
        repeated = f" ({distinct} distinct joint configurations)" if distinct < len(data) else ""
        sensor = "the cable sensor's anchor and zero" if kind == "cable" else "the tracker's frame"
        needed = f"placing {sensor} needs at least {MIN_CONFIGURATIONS[kind]} distinct joint configurations"
        raise DataError(f"{len(data)} {kind} samples{repeated} are too few: {needed}", data.source)
    return distinct


def check_observations(robot: Robot, data: Dataset, labels: Optional[np.ndarray] = None) -> np.ndarray:
    """An error naming the likely cause when ``data``'s observations cannot be readings of
    ``robot`` at its joint values: another joint count, values that are not finite (:func:`check_readings`), too few distinct
    configurations to place the sensor (:func:`distinct_configurations`), observations in another unit than mm (their spread against
    the robot's tool points', :data:`SCALE_RATIO`), or single readings further from the others
    than the robot's points are from each other (:data:`IMPOSSIBLE_SPREAD`), named by row.
    ``labels``: :func:`~robocal.data.splits.configuration_groups` of ``data.q`` if the caller has them.
    Returns the robot's nominal tool points at ``data.q`` (m, 3) it compared the observations with."""
    check_readings(robot, data)
    kind, where = data.measurement, data.source
    distinct_configurations(data, configuration_groups(data.q) if labels is None else labels)
    points = robot.fkine(data.q, tool=True)[:, :3, 3]
    robot_spread = _spread(points)
    observed = data.y[:, :1] if kind == "cable" else data.y[:, :3]
    observed_spread = _spread(observed)
    typical = float(np.median(robot_spread))
    if typical < 1.0:  # the joints barely move: nothing to compare with
        return points
    ratio = float(np.median(observed_spread)) / typical
    low, high = SCALE_RATIO[kind]
    if ratio == 0.0:
        moving = f"the tool points of {robot.name} at these joint values move by {typical:.4g} mm"
        raise DataError(f"most readings are equal while {moving}: the observations do not follow the joints", where)
    if not low <= ratio <= high:
        unit = min(LIKELY_UNITS, key=lambda u: abs(np.log(ratio / LIKELY_UNITS[u])))
        guess = f"{unit}?" if abs(np.log(ratio / LIKELY_UNITS[unit])) < np.log(3) else "another unit or another robot?"
        what = "cable lengths" if kind == "cable" else "measured positions"
        raise DataError(
            f"the {what} vary by {np.median(observed_spread):.4g} mm around their median, the tool points of {robot.name} at these "
            f"joint values by {typical:.4g} mm: {max(ratio, 1 / ratio):.3g}x {'smaller' if ratio < 1 else 'larger'} — {guess} "
            "robocal reads observations in mm",
            where,
        )
    bound = IMPOSSIBLE_SPREAD * 2.0 * float(robot_spread.max())
    wild = np.flatnonzero(observed_spread > bound)
    if wild.size:
        rows = ", ".join(str(r) for r in data.rows[wild[:5]]) + (", ..." if wild.size > 5 else "")
        shown = ", ".join(f"{v:.4g}" for v in observed[wild[0]])
        raise DataError(
            f"{wild.size} reading(s) lie more than {bound:.4g} mm from the others' median (row(s) {rows}; the first reads {shown} mm), "
            f"while {robot.name}'s tool points at these joint values are at most {2 * robot_spread.max():.4g} mm apart: a wrong value "
            "— correct or remove the row(s)",
            where,
            int(data.rows[wild[0]]),
        )
    return points


def _pairs(value, what: str) -> Mapping:
    """A ``name -> pair`` mapping (None: empty), or an error naming ``what``."""
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise InvalidParameterError(f"`{what}` must be a mapping of parameter name -> pair; got {type(value).__name__} {value!r}")
    return value


def initial_x(problem, x0=None) -> np.ndarray:
    """A calibrator's start on ``problem`` (a :class:`Problem` or an extended one): its ``x0``,
    or ``x0`` checked to hold one finite value per free parameter."""
    start = problem.x0
    if x0 is None:
        return start
    x = as_float_array(x0, "x0")
    if x.shape != start.shape or not np.all(np.isfinite(x)):
        raise InvalidParameterError(f"`x0` must hold {start.size} finite values (the free parameters {problem.names[:3]} ...); got {x0!r}")
    return x


#: Weight (mm/rad) of a pose's rotation residual against its position residual when the data
#: record no per-reading standard deviations: about the ratio of a laser tracker's position to
#: its orientation noise, as the public UR10 tracker files record them. Unweighted (1 mm/rad) the
#: orientation would weigh nothing beside millimetres; much heavier, it costs position accuracy
#: (the figures: docs/findings.md, D3).
POSE_ROTATION_WEIGHT = 200.0


def rotation_weight(data: Dataset) -> float:
    """Weight (mm/rad) of the rotation residuals of pose ``data``: the ratio of the mean recorded
    position and orientation standard deviations (``extra["measurement_std"]``, mm and deg)
    where the data record them, else :data:`POSE_ROTATION_WEIGHT`; 1 for other measurements."""
    if data.measurement != "pose":
        return 1.0
    std = data.extra.get("measurement_std")
    if std is None or np.shape(std)[1:] != (6,):
        return POSE_ROTATION_WEIGHT
    std = np.asarray(std, dtype=np.float64)
    position, rotation = float(np.mean(std[:, :3])), float(np.radians(np.mean(std[:, 3:])))
    return position / rotation if position > 0 and rotation > 0 else POSE_ROTATION_WEIGHT


def fit_row_weights(data: Dataset, samples: Optional[int] = None) -> np.ndarray:
    """Weights of the residual rows of ``samples`` samples (default all) of ``data``'s kind in
    a fit, (samples·k,): 1, and :func:`rotation_weight` for the rotation rows of pose data."""
    w = np.ones((len(data) if samples is None else samples, RESIDUAL_WIDTH[data.measurement]))
    w[:, 3:] = rotation_weight(data)
    return w.ravel()


@dataclass
class Problem:
    """Residuals and Jacobians of one robot on one dataset over the free parameters.

    Attributes
    ----------
    robot : Robot
    data : Dataset
    free : ndarray of int
        Indices (into the full parameter vector) of the estimated parameters.
    start : ndarray, shape (P,)
        Full parameter vector at the start; the fixed entries keep these values.
    fixed : dict
        ``name -> reason`` for every masked parameter that is not estimated.
    prior : dict, optional
        ``name -> (mean, sigma)`` (mm / rad) Gaussian priors on free parameters. Each adds a
        residual row ``prior_scale·(mean − x)/sigma``, so least squares on :meth:`residuals`
        is the maximum a posteriori estimate for measurement noise ``prior_scale``.
    prior_scale : float
        The measurement noise (mm) the prior rows are expressed in.
    bounds : dict, optional
        ``name -> (lower, upper)`` hard limits (mm / rad) on free parameters. Every method keeps
        its iterates inside them (:meth:`clip`).

    Pose data's rotation residuals (rad) enter :meth:`residuals` and :meth:`jacobian` weighted by
    :func:`rotation_weight` (mm/rad), so that orientation and position weigh as the sensor's
    noise says; :meth:`data_residuals` stays in mm and rad.
    """

    robot: Robot
    data: Dataset
    free: np.ndarray
    start: np.ndarray
    fixed: dict = field(default_factory=dict)
    prior: dict = field(default_factory=dict)
    prior_scale: float = 1.0
    bounds: dict = field(default_factory=dict)

    @classmethod
    def build(
        cls, robot: Robot, data: Dataset, mask=None, params=None, tol: float = 1e-9, prior=None, bounds=None, kinematic_prior=None, observations=None
    ) -> "Problem":
        """The identifiable subset of ``mask`` (default: ``robot.default_mask``) at the start point.

        Parameters
        ----------
        robot : Robot
        data : Dataset
            Must have ``data.n_joints == robot.n_joints``.
        mask : array_like of bool or of names, optional
        params : array_like, optional
            Start parameter vector (default: nominal + closed-form set-up, see
            :func:`start_parameters`).
        tol : float
            Rank tolerance of the identifiability analysis.
        prior : dict, optional
            ``name -> (mean, sigma)`` priors (mm / rad) on estimated parameters; the rows are
            scaled by the sensor's default noise (:data:`robocal.sensors.DEFAULT_NOISE`).
        bounds : dict, optional
            ``name -> (lower, upper)`` hard limits (mm / rad) on estimated parameters; the start
            is moved inside them.
        kinematic_prior : (float, float), optional
            ``(mm, deg)``: a Gaussian prior at the start value on every estimated kinematic
            parameter (lengths ``mm``, angles ``deg``), unless ``prior`` names it. It keeps the
            weakly determined directions of a narrow workspace near nominal instead of letting
            them absorb what the geometry cannot explain.
        observations : (ndarray, ndarray), optional
            ``(labels, points)`` of ``data``'s samples from the caller's :func:`check_observations`
            of a dataset ``data`` is part of (a training split's): configuration labels
            (:func:`~robocal.data.splits.configuration_groups`) and nominal tool points (m, 3).
            ``data`` is then checked only for its count of distinct configurations.
        """
        if observations is None:
            labels = configuration_groups(data.q)
            points = check_observations(robot, data, labels)
        else:
            labels, points = observations
        distinct = distinct_configurations(data, labels)
        cols = robot.columns(robot.default_mask(data.measurement) if mask is None else mask, "mask")
        if cols.size == 0:
            raise InvalidParameterError(f"`mask` must select at least one of the {robot.n_params} parameters; got {mask!r}")
        cols = np.unique(cols)  # the core checks the range
        start = start_parameters(robot, data, params, points)
        r, J = robot.residuals_and_jacobian(data.measurement, data.q, data.y, params=start, cols=cols)
        ident = robot.identifiability(data.measurement, J, cols, tol)
        names = [robot.param_names[c] for c in cols]
        fixed = {names[j]: "no effect on the measurements" for j in ident["no_effect"]}
        for j, partners in ident["redundant"]:
            fixed[names[j]] = redundancy_words([(names[k], c) for k, c in partners])
        free = cols[np.sort(ident["identifiable"])]
        problem = cls(robot=robot, data=data, free=free, start=start, fixed=fixed, prior_scale=DEFAULT_NOISE[data.measurement].sigma)
        problem._distinct = (data, distinct)  # for require_dof, while the data are these
        prior = dict(_pairs(prior, "prior"))
        if kinematic_prior is not None:
            start_of = dict(zip(robot.param_names, start))
            prior = {**kinematic_prior_pairs(robot, [robot.param_names[k] for k in free], start_of, kinematic_prior_sigmas(kinematic_prior)), **prior}
        problem.prior = problem._checked_pairs(prior, "prior", "(mean, sigma)", lambda a, b: np.isfinite(a) and np.isfinite(b) and b > 0)
        problem.bounds = problem._checked_pairs(_pairs(bounds, "bounds"), "bounds", "(lower, upper)", lambda a, b: a < b)
        problem.start[problem.free] = problem.clip(problem.start[problem.free])
        # The start is where r and J were evaluated: the fit's first residuals, and J's free columns (if nothing changes);
        # `take` gives them C-ordered in one pass (a fancy index gives them F-ordered: a copy that cost 6 ms on 16 000 rows).
        if not problem.bounds:
            problem._start_residuals = (data, free.copy(), start.copy(), r.ravel())
            problem._start_jacobian = (data, free.copy(), start.copy(), J.take(np.searchsorted(cols, free), axis=1))
        return problem

    def require_dof(self, purpose: str = "a calibration", remedy: str = "more samples, or a kinematic prior") -> None:
        """An error with the counts when the residuals do not outnumber the estimated parameters
        and no prior regularises them: any data are then fitted exactly (RMSE 0), nothing is
        learnt. (A Kalman filter's own prior covariance makes such problems well posed for it.)
        ``purpose`` and ``remedy`` word the message (``verify`` re-fits a set-up, not a robot)."""
        # A repeated configuration averages the noise but adds no geometry: it counts once.
        known = getattr(self, "_distinct", None)
        distinct = known[1] if known is not None and known[0] is self.data else int(configuration_groups(self.data.q).max(initial=-1)) + 1
        residuals = distinct * RESIDUAL_WIDTH[self.data.measurement]
        if residuals <= len(self.free) and not self.prior:
            repeated = f" ({distinct} distinct joint configurations)" if distinct < len(self.data) else ""
            raise InvalidParameterError(
                f"{len(self.data)} {self.data.measurement} samples{repeated} give {residuals} residuals for {len(self.free)} identifiable "
                f"parameters: {residuals - len(self.free)} degrees of freedom; {purpose} needs more residuals than parameters ({remedy})"
            )

    def _checked_pairs(self, pairs: dict, what: str, form: str, valid) -> dict:
        """``name -> (a, b)`` on estimated parameters, each pair checked with ``valid(a, b)``."""
        checked = {}
        for name, value in pairs.items():
            if name not in self.names:
                why = self.fixed.get(name, "not among the parameters considered")
                raise InvalidParameterError(f"{what} on {name!r}, which is not estimated ({why})")
            try:
                a, b = (float(v) for v in value)
            except (TypeError, ValueError):
                raise InvalidParameterError(f"{what} on {name!r} must be {form}; got {value!r}") from None
            if not valid(a, b):
                rule = "a finite mean and sigma > 0" if what == "prior" else "lower < upper"
                raise InvalidParameterError(f"{what} on {name!r} needs {rule}; got ({a}, {b})")
            checked[name] = (a, b)
        return checked

    @property
    def lower(self) -> np.ndarray:
        """Lower limits of the free parameters (−inf where none)."""
        return np.array([self.bounds.get(n, (-np.inf, np.inf))[0] for n in self.names])

    @property
    def upper(self) -> np.ndarray:
        """Upper limits of the free parameters (+inf where none)."""
        return np.array([self.bounds.get(n, (-np.inf, np.inf))[1] for n in self.names])

    def clip(self, x: np.ndarray) -> np.ndarray:
        """``x`` moved inside the bounds."""
        return np.clip(x, self.lower, self.upper) if self.bounds else np.asarray(x, dtype=np.float64)

    # -- the free vector ----------------------------------------------------------------------
    @property
    def x0(self) -> np.ndarray:
        return self.start[self.free].copy()

    @property
    def names(self) -> list[str]:
        return [self.robot.param_names[k] for k in self.free]

    def full(self, x: np.ndarray) -> np.ndarray:
        """The full parameter vector with the free entries set to ``x``."""
        p = self.start.copy()
        p[self.free] = x
        return p

    def with_data(self, data: Dataset) -> "Problem":
        """The same parameterisation on other data (e.g. the held-out samples)."""
        return Problem(self.robot, data, self.free, self.start, dict(self.fixed), dict(self.prior), self.prior_scale, dict(self.bounds))

    # -- residuals ----------------------------------------------------------------------------
    def _prior_rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions in ``x``, means and sigmas of the priors."""
        names = self.names
        idx = np.array([names.index(n) for n in self.prior], dtype=int)
        mean = np.array([m for m, _ in self.prior.values()])
        sigma = np.array([s for _, s in self.prior.values()])
        return idx, mean, sigma

    def data_residuals(self, x: np.ndarray) -> np.ndarray:
        """``y − h`` of every sample, flattened to (m·k,): what the metrics are computed on (at the
        start point, once, those :meth:`build` evaluated there with the Jacobian)."""
        params = self.full(x)
        r = self._evaluated_at_start("_start_residuals", params)
        return self.robot.residuals(self.data.measurement, self.data.q, self.data.y, params=params).ravel() if r is None else r

    def _evaluated_at_start(self, name: str, params: np.ndarray) -> Optional[np.ndarray]:
        """What :meth:`build` left under ``name`` (``(data, free, start, value)``), taken once: the
        value if ``params``, the data and the free set are still the start's, else None."""
        cached = self.__dict__.pop(name, None)
        if cached is not None and cached[0] is self.data and np.array_equal(cached[1], self.free) and np.array_equal(cached[2], params):
            return cached[3]
        return None

    @cached_property
    def _unit_weights(self) -> bool:
        """True when every row weight is 1 (all but pose data): no product needed."""
        return bool(np.all(self.row_weights == 1.0))

    def _data_jacobian(self, x: np.ndarray) -> np.ndarray:
        """The weighted data rows of :meth:`jacobian`; at the start point, the columns of the
        Jacobian :meth:`build` evaluated there for the identifiability analysis, once."""
        params = self.full(x)
        J = self._evaluated_at_start("_start_jacobian", params)
        if J is None:
            J = self.robot.jacobian(self.data.measurement, self.data.q, y=self.data.y, params=params, cols=self.free)
        return self._weighted(J)

    def _weighted(self, data_rows: np.ndarray) -> np.ndarray:
        """Data residuals (m·k,) or Jacobian rows (m·k, n) times :attr:`row_weights`."""
        if self._unit_weights:
            return data_rows
        return data_rows * (self.row_weights if data_rows.ndim == 1 else self.row_weights[:, None])

    @cached_property
    def row_weights(self) -> np.ndarray:
        """Weights of the data rows in :meth:`residuals` (:func:`fit_row_weights`)."""
        return fit_row_weights(self.data)

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """What the calibrators minimise: :meth:`data_residuals` (weighted: :attr:`row_weights`)
        followed by the prior rows."""
        return self._with_prior_residuals(self._weighted(self.data_residuals(x)), x)

    def _with_prior_residuals(self, r: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Weighted data residuals ``r`` followed by the prior rows at ``x``."""
        if not self.prior:
            return r
        idx, mean, sigma = self._prior_rows()
        return np.concatenate([r, self.prior_scale * (mean - np.asarray(x)[idx]) / sigma])

    def costs(self, X: np.ndarray) -> np.ndarray:
        """:meth:`cost` of every row of ``X`` (S, n_free), the data part evaluated in one Rust call."""
        X = np.atleast_2d(np.asarray(X, dtype=np.float64))
        R = self.robot.residuals_at(self.data.measurement, self.data.q, self.data.y, self.free, X, params=self.start) * self.row_weights
        c = 0.5 * np.einsum("ij,ij->i", R, R)
        if self.prior:
            idx, mean, sigma = self._prior_rows()
            c += 0.5 * np.sum((self.prior_scale * (mean - X[:, idx]) / sigma) ** 2, axis=1)
        return c

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """``∂h/∂x`` of :meth:`residuals` (data rows, then prior rows), (rows, n_free)."""
        return self._with_prior_jacobian(self._data_jacobian(x))

    def _with_prior_jacobian(self, J: np.ndarray) -> np.ndarray:
        """Weighted data Jacobian rows ``J`` followed by the prior rows."""
        if not self.prior:
            return J
        idx, _, sigma = self._prior_rows()
        rows = np.zeros((len(idx), len(self.free)))
        rows[np.arange(len(idx)), idx] = self.prior_scale / sigma
        return np.vstack([J, rows])

    def residuals_and_jacobian(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`residuals` and :meth:`jacobian` at ``x`` from one pass of the core: the forward
        kinematics once for both (each bit for bit what its own method gives)."""
        r, J = self.robot.residuals_and_jacobian(self.data.measurement, self.data.q, self.data.y, params=self.full(x), cols=self.free)
        return self._with_prior_residuals(self._weighted(r.ravel()), x), self._with_prior_jacobian(self._weighted(J))

    def cost(self, x: np.ndarray) -> float:
        """``½‖r‖²`` of :meth:`residuals` (scipy's convention)."""
        r = self.residuals(x)
        return 0.5 * float(r @ r)
