"""In-line monitoring: a calibrated robot watched sample by sample as it works.

``Monitor(result)`` takes measured samples in acquisition order (``update(q, y)``, one or a
block) and says when something changed since the calibration — a joint's zero (a collision, a
motor or encoder swap), the sensor's frame or zero (a bumped tracker, a re-zeroed cable), a slow
drift of the sensor —, when it began, how large it is, and applies it to the model, which
``result_document()`` then holds (``verify``, ``compensate`` and ``export`` take it).

The estimator
-------------
Each sample's innovation is the measured reading less the result's model (its parameters, reading
conventions and joint causes: :func:`~robocal.causes.result_model.result_model`'s model), with the
Jacobian of each change on the Rust core. A change of parameters ``θ`` (one joint's zero; the
sensor frame's translation, or the cable's zero) from sample ``τ`` on moves the innovations by
``J_t δ``; a drift by ``J_t δ (t − τ)``. The generalised likelihood ratio of each against "no
change" over the last :data:`WINDOW` samples is ``gᵀ G⁻¹ g`` with ``g = Σ_{t≥τ} J_tᵀ W e_t`` and
``G = Σ_{t≥τ} J_tᵀ W J_t`` (``W`` the readings' inverse variance), maximised over ``τ``: the
least-squares estimate of the change given where it began, its χ² evidence. The sums are kept
per sample in ring buffers: an update costs one model evaluation and a few suffix sums, and the
memory does not grow with the stream. Why a GLR rather than the paper's UKF on the parameters: a
filter tracks a drift that is there, a change detector says *that* and *when* something changed,
with a false-alarm rate one can state; the parameters it finds are then the UKF's fixed point.

False alarms
------------
Under no change each statistic is χ² with as many degrees of freedom as the change has
parameters. The threshold is the χ² quantile of ``1 / (mean_run_length · WINDOW · changes)`` —
a Bonferroni bound over every start in the window and every change — so false alarms come at
most once per ``mean_run_length`` samples (default :data:`MEAN_RUN_LENGTH`). Real innovations
are correlated in time (the model's own errors along a path, a sensor that wanders): each
statistic is divided by the larger of the innovations' long-run inflation (:class:`~robocal.monitor_window.LongRunVariance`:
batch means of the innovations leaving the window) and its own yardstick
(:class:`~robocal.monitor_window.StatisticScale`: its mean per degree of freedom over past segments), and the variance
``W⁻¹`` is the opening innovations' per reading. No alarm is raised during the opening (:data:`OPENING` samples): a
change there cannot be told from the set-up. With ``new_session`` the opening samples first
re-fit the session's set-up (as ``verify`` does).
"""

from __future__ import annotations

import logging
import math
from collections import deque
from dataclasses import dataclass, field, replace
from typing import Optional

import numpy as np
from scipy.special import chdtri, gammaincc

from .calibration.lm import levenberg_marquardt
from .calibration.problem import TOLERANCE, Problem, is_kinematic
from .causes import structure
from .causes.candidates import COMPENSABLE, joint_offsets
from .data.dataset import OBSERVATION_COLUMNS, Dataset
from .exceptions import InvalidParameterError, ShapeError
from .kernels import as_count, as_float_array, as_positive
from .monitor_window import BATCH, MEMORY_BATCHES, SEGMENT, WINDOW, LongRunVariance, StatisticScale, WindowSums, quadratic_form, ridged_inverse
from .results import load_result
from .serial_robot import RESIDUAL_WIDTH, setup_names, zero_names

logger = logging.getLogger(__name__)

#: Samples that set the innovations' scale and correlation (and the set-up with ``new_session``).
OPENING = 200
#: The fewest: two batches, the fewest a variance of batch means rests on (an opening shorter than a batch crashed
#: the long-run variance; one batch measured no correlation and held the yardstick at 1).
MIN_OPENING = 2 * BATCH
#: Default mean number of samples between false alarms.
MEAN_RUN_LENGTH = 100_000
#: Fewest samples after a change's start before it may be tested (one bad sample is no change).
MIN_AFTER = 3
#: Samples after a change's estimated start before it is named for good: the kinds tell apart by then.
CONFIRM = 6
#: How much less likely under no change (natural log) the named change must be than any other
#: kind, else the monitor waits for more samples (having alarmed at once, provisionally, as the
#: sensor's step when the step is among the kinds within this margin) ...
DISTINCT = 5.0
#: ... up to this many after the change's start; then it names the likelier and says what else
#: it could be.
MAX_WAIT = 25
#: A provisional alarm needs the step's statistic at this many times its threshold: it then stands
#: even if the yardstick underestimates the innovations' long-run variance by as much (the false
#: alarms over long clean cable streams came at 1.0-1.5 times their thresholds, all but one).
TOLD_AT = 2.0
#: A change is named for good only if, fitted on the first half of the samples from its start
#: on, what it leaves of the second half is within this many times what the model left before
#: it (RMS; a drift: what it leaves of all of them): else no single kind explains it, and the
#: monitor says so and opens anew. (D2's re-zero as joint 4's zero: 2.7 times over its first 15
#: samples, 1.9 fitted on all of them.) The same ratio between the opening's
#: innovations at the calibration's set-up and with it re-fitted (and against the calibration's
#: held-out error) says the sensor stands elsewhere than the calibration placed it.
FIT_RATIO = 2.0
#: Samples at which each change's detection limit is stated.
LIMIT_SAMPLES = 25
#: Full windows over which the stated detection limits are the median (as long as the long-run
#: variance remembers).
LIMIT_WINDOWS = MEMORY_BATCHES * BATCH // WINDOW


@dataclass(frozen=True)
class Change:
    """A change the monitor tests for: ``kind`` (``joint_zero``, ``step``, ``drift``), the
    1-based ``joint`` of a joint's zero, and the parameters (indices into the robot's vector) it moves."""

    kind: str
    joint: Optional[int]
    columns: tuple
    names: tuple

    @property
    def ramp(self) -> bool:
        return self.kind == "drift"


@dataclass
class Alarm:
    """A change found: at stream sample ``sample`` (0-based; file ``row``), begun at ``since``,
    of ``size`` (per parameter, ``unit``), with ``evidence`` (statistic over threshold).
    ``could_be``: the other kinds within a likelihood ratio of e^:data:`DISTINCT` (``margin``: the
    log ratio to the likeliest of them). A ``provisional`` alarm is raised as soon as a change is
    seen, as the sensor's step, while other kinds explain it as well; it is not applied: the
    same change is named for good (and applied) by a later alarm."""

    sample: int
    row: Optional[int]
    since: int
    kind: str
    joint: Optional[int]
    size: list
    unit: str
    names: list
    evidence: float
    margin: float = float("inf")
    could_be: list = field(default_factory=list)
    provisional: bool = False
    #: The change's estimate in the model's units (rad, mm), as fitted; not written.
    delta: Optional[np.ndarray] = field(default=None, repr=False)

    def to_dict(self) -> dict:
        return {
            "sample": self.sample,
            "row": self.row,
            "since": self.since,
            "kind": self.kind,
            "joint": self.joint,
            "size": self.size,
            "unit": self.unit,
            "parameters": self.names,
            "evidence": self.evidence,
            "distinct_by": self.margin,
            "could_be": list(self.could_be),
            "provisional": self.provisional,
        }

    def words(self) -> str:
        if self.kind == "unexplained":
            return (
                f"sample {self.sample} (row {self.row}): a change from sample {self.since} that no single kind explains: the likeliest, "
                f"{self.could_be[0]}, leaves {self.evidence:.1f}x what the model left before it (RMS)"
                + (f"; {' and '.join(self.could_be[1:])} explain it about as well" if len(self.could_be) > 1 else "")
                + ": nothing applied; the monitor opens anew, re-fitting the set-up on its next opening samples — a calibration may be due"
            )
        if self.kind == "setup":
            return (
                f"sample {self.sample} (row {self.row}): from sample {self.since} on the readings differ from the calibration's model as a moved sensor "
                f"would make them ({self.evidence:.1f}x the calibration's held-out error, RMS): the sensor stands elsewhere, or this is a new session; "
                "its set-up is re-fitted on the opening samples (as with --new-session)"
            )
        what = f"joint {self.joint}'s zero" if self.kind == "joint_zero" else f"the sensor's {'drift' if self.kind == 'drift' else 'set-up'}"
        size = ", ".join(f"{n} {v:+.4g}" for n, v in zip(self.names, self.size))
        doubt = f"; it could also be {' or '.join(self.could_be)} (likelihoods within e^{abs(self.margin):.1f})" if self.could_be else ""
        told = "provisionally, " if self.provisional else ""
        return f"sample {self.sample} (row {self.row}): {told}{what} changed from sample {self.since}: {size} {self.unit} ({self.evidence:.1f}x its threshold{doubt})"


def _kind_words(change) -> str:
    """A change's kind (a :class:`Change` or an :class:`Alarm`) as ``could_be`` lists it."""
    return change.kind if change.joint is None else f"joint {change.joint}'s zero"


def _surprise(stat: float, d: int) -> float:
    """``−log P(χ²_d > stat)``; beyond floating point, its asymptotic form (a statistic of
    thousands is no less a change than one of hundreds)."""
    tail = gammaincc(d / 2.0, stat / 2.0)  # the χ² survival function (scipy.stats' logsf costs half a millisecond a call)
    if tail > 1e-300:
        return float(-math.log(tail))
    return stat / 2.0 - (d / 2.0 - 1.0) * math.log(stat / 2.0) + math.lgamma(d / 2.0)


class Monitor:
    """Watches a calibrated robot sample by sample (see the module notes).

    Parameters
    ----------
    result : path or dict
        A result file of ``robocal calibrate`` (:func:`robocal.results.load_result`).
    new_session : bool
        Re-fit the session's set-up on the opening samples (default: the stream continues the
        calibration's session, its set-up as calibrated).
    mean_run_length : float
        Mean samples between false alarms the thresholds are set for.
    opening : int
        Samples that set the innovations' scale and correlation; no alarm before them (at least
        :data:`MIN_OPENING`).
    """

    def __init__(self, result, *, new_session: bool = False, mean_run_length: float = MEAN_RUN_LENGTH, opening: int = OPENING):
        # Finite: at an infinite one every threshold is infinite and no change is ever alarmed (a monitor that says nothing).
        if not as_positive(mean_run_length, "mean_run_length") >= 10:
            raise InvalidParameterError(f"`mean_run_length` must be at least 10 samples; got {mean_run_length!r}")
        opening = as_count(opening, "opening", least=MIN_OPENING)
        self.robot, self.doc = load_result(result)
        self.measurement = self.doc["measurement"]
        self.params = self.robot.params.copy()
        self._drift, self._drift_left = np.zeros_like(self.params), 0  # per sample, of a drift found, for how many samples more
        self.structures = structure.parse_all(self.doc.get("structure", []), self.robot.n_joints)
        causes = self.doc.get("causes", [])
        self.offsets = joint_offsets(self.robot, causes, kinds=COMPENSABLE)
        self.not_applied = sorted({c.get("label", c.get("kind")) for c in causes if c.get("kind") not in COMPENSABLE})
        self.new_session, self.opening, self.mean_run_length = new_session, opening, float(mean_run_length)
        self.changes = self._changes()
        # The null hypothesis is no change in the window, the parameters then as the calibration
        # left them or anywhere near (its own error): every parameter it estimated is profiled out
        # over the window (the session's set-up free), so the calibration's error along a path is
        # no evidence. Each is held near its value by the calibration's standard deviation and, a
        # kinematic one, by the manufacturing tolerance too (TOLERANCE, the calibration's own
        # prior): a direction the calibration left undetermined (D2's: stds of tens of mm) would
        # otherwise let the constant absorb a change as a geometry no arm has. The parameters it
        # fixed stay at their values: redundant with estimated ones wherever the arm goes (a point
        # sensor's tool against the last joint, the base's turn against the first), profiling
        # them too explained nothing more of the long clean cable streams' innovations.
        names = self.robot.param_names
        fitted = [names.index(n) for n in self.doc.get("free", []) if n in names]
        self.columns = sorted({c for change in self.changes for c in change.columns} | set(fitted))
        std = {p["name"]: p.get("std") for p in self.doc["parameters"]}
        private = set(setup_names(self.robot, self.measurement)) | {"cable_offset"}
        units = dict(zip(names, self.robot.param_units))

        def hold(name: str) -> float:  # the inverse variance the window's constant is held by
            if name in private:
                return 0.0
            return (1.0 / std[name] ** 2 if std.get(name) else 0.0) + (1.0 / TOLERANCE[units[name]] ** 2 if is_kinematic(name) else 0.0)

        self.prior = np.array([hold(names[c]) for c in self.columns])
        self._level = np.zeros(len(self.columns))  # the window's constant (the calibration's error as it sees it)
        self.threshold = {d: float(chdtri(d, 1.0 / (self.mean_run_length * WINDOW * len(self.changes)))) for d in {len(c.columns) for c in self.changes}}
        # The joints' limits, a nanoradian's grace for rounding in the readings.
        self._limits = tuple(np.array([j.limits[k] for j in self.robot.joints]) + grace for k, grace in ((0, -1e-9), (1, 1e-9)))
        self.samples = 0
        self.alarms: list[Alarm] = []
        self.refused: list[str] = []
        self._opening: list = []  # (q, y, row) until the opening is complete
        self._buffers = WindowSums(len(self.columns), [([self.columns.index(c) for c in change.columns], change.ramp) for change in self.changes])
        self.sigma: Optional[np.ndarray] = None
        self.inflation = 1.0
        self._scale = StatisticScale(np.array([len(c.columns) for c in self.changes]))
        self._delayed: deque = deque()
        self._told: Alarm | None = None  # the provisional alarm of the crossing under way
        self._reopened = False  # an unexplained change: the next opening re-fits the set-up
        self.limits: dict = {}
        self._window_limits: deque = deque(maxlen=LIMIT_WINDOWS)  # per full window, each change's limit in it
        self.refit: dict = {}

    # -- what is watched -----------------------------------------------------------------------
    def _changes(self) -> list[Change]:
        r = self.robot
        out = []
        for j, name in enumerate(zero_names(r), start=1):
            out.append(Change("joint_zero", j, (r.index(name),), (name,)))
        sensor = ("cable_offset",) if self.measurement == "cable" else ("base_x", "base_y", "base_z")
        columns = tuple(r.index(n) for n in sensor)
        out += [Change("step", None, columns, sensor), Change("drift", None, columns, sensor)]
        return out

    def _limit(self, change: Change, info: np.ndarray) -> float:
        """The smallest change (along its weakest direction) whose statistic reaches the threshold
        with information ``info``, at unit inflation (the summary states it at the correlation
        last measured)."""
        weakest = np.linalg.eigvalsh(info)[0]
        return float(np.sqrt(self.threshold[len(change.columns)] / max(weakest, 1e-300)))

    def _unit(self, change: Change) -> str:
        return "deg" if change.kind == "joint_zero" and self.robot.joints[change.joint - 1].kind == "revolute" else ("mm/sample" if change.ramp else "mm")

    # -- the model -----------------------------------------------------------------------------
    def _links(self, q: np.ndarray) -> np.ndarray:
        """The angles the links take at readings ``q`` (m, N)."""
        q = structure.to_model(q, self.structures)
        return q if self.offsets is None else q + self.offsets(q)

    def _innovations(self, q: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        e, J = self.robot.residuals_and_jacobian(self.measurement, self._links(q), y, params=self.params, cols=self.columns)
        e = e.reshape(len(q), -1)
        return e, J.reshape(len(q), e.shape[1], len(self.columns))

    # -- the stream ----------------------------------------------------------------------------
    def _checked(self, q, y) -> tuple[np.ndarray, np.ndarray]:
        q, y = np.atleast_2d(as_float_array(q, "q")), np.atleast_2d(as_float_array(y, "y"))
        readings = len(OBSERVATION_COLUMNS[self.measurement])
        if q.ndim != 2:
            raise ShapeError(f"`q` must be one sample (N,) or a block of samples (m, N); got shape {q.shape}")
        if q.shape[1] != self.robot.n_joints:
            raise ShapeError(f"a sample has {q.shape[-1]} joint values; the result's robot {self.robot.name!r} has {self.robot.n_joints}")
        if y.ndim != 2 or y.shape != (len(q), readings):
            raise ShapeError(f"`y` must hold {readings} readings ({self.measurement}) for each of the {len(q)} samples; got shape {y.shape}")
        return q, y

    def _refuse(self, i: int, row, why: str) -> None:
        note = f"sample {i} (row {row}) refused: {why}"
        self.refused.append(note)
        logger.warning("monitor: %s", note)

    def update(self, q, y, rows=None) -> list[Alarm]:
        """Takes one sample (``q`` (N,) rad — the controller's readings —, ``y`` (k,) mm) or a
        block ((m, N), (m, k)) in acquisition order; returns the alarms raised. A sample that
        is not finite or lies beyond the joint limits is refused with a note
        (:attr:`refused`) and the stream goes on."""
        q, y = self._checked(q, y)
        rows = [None] * len(q) if rows is None else list(rows)
        if len(rows) != len(q):  # else zip would drop the samples past the shorter
            raise ShapeError(f"`rows` must name the file row of each of the {len(q)} samples; got {len(rows)}")

        raised = []
        lower, upper = self._limits
        for qi, yi, row in zip(q, y, rows):
            i = self.samples
            self.samples += 1
            model_q = structure.to_model(qi[None, :], self.structures)[0]
            if not (np.isfinite(qi).all() and np.isfinite(yi).all()):
                self._refuse(i, row, "a value is not a finite number")
                continue
            if (model_q < lower).any() or (model_q > upper).any():
                self._refuse(i, row, "a joint lies beyond the robot's limits")
                continue
            if self.sigma is None:
                self._opening.append((i, qi, yi, row))
                if len(self._opening) == self.opening:
                    moved = self._start()
                    if moved is not None:
                        self.alarms.append(moved)
                        raised.append(moved)
                continue
            alarm = self._step(i, qi[None, :], yi[None, :], row)
            if alarm is not None:
                raised.append(alarm)
        return raised

    def _start(self) -> Optional[Alarm]:
        """The opening is complete: the set-up (``new_session``, after an unexplained change, or
        when the opening shows the sensor elsewhere: then a ``setup`` alarm, returned), the
        innovations' scale and correlation, the detection limits; then the opening samples enter
        the window."""
        index = [i for i, *_ in self._opening]
        q = np.array([s[1] for s in self._opening])
        y = np.array([s[2] for s in self._opening])
        # Never below what the calibration itself erred by on samples it did not fit: the model's
        # error on new poses, which a short opening may not show.
        figures = self.doc.get("metrics", {}).get("test") or self.doc.get("metrics", {}).get("train") or {}
        floor = np.full(RESIDUAL_WIDTH[self.measurement], (figures.get("rmse") or 0.0) / np.sqrt(3.0 if self.measurement != "cable" else 1.0))
        if self.measurement == "pose":
            floor[3:] = 0.0  # the rotation rows: the opening's figure alone
        moved = None
        if self.new_session or self._reopened:
            self._refit_setup(q, y)
        else:
            moved = self._moved_sensor(q, y, floor, index, self._opening[-1][3])
        self._reopened = False
        e, J = self._innovations(q, y)
        centred = e - e.mean(axis=0)
        fitted = len(self.refit.get("names", [])) + e.shape[1]  # the set-up re-fitted and the mean removed take degrees of freedom
        opening_sigma = np.sqrt(np.sum(centred**2, axis=0) / max(len(q) - fitted / e.shape[1], 1.0))
        self.sigma = np.maximum(opening_sigma, floor).clip(1e-9)
        Jw = J / self.sigma[None, :, None]
        z = e / self.sigma
        G = np.einsum("mkp,mkq->pq", Jw, Jw) + np.diag(self.prior)
        level = np.linalg.pinv(G, rcond=1e-12, hermitian=True) @ np.einsum("mkp,mk->p", Jw, z)
        self._variance = LongRunVariance(z - Jw @ level)  # the opening less its constant, as the window will see it
        self._scale = StatisticScale(self._scale.dofs)  # the innovations' scale is new: so are the statistics'
        self.inflation = self._variance.inflation
        Jw = J / self.sigma[None, :, None]
        per_sample = np.einsum("mkp,mkq->pq", Jw, Jw) / len(q)
        window = WINDOW * per_sample + np.diag(self.prior)
        window_inverse = ridged_inverse(window)
        for change in self.changes:
            if change.ramp:
                continue
            cols = [self.columns.index(c) for c in change.columns]
            # Until the first full window: a window of the opening's mean information, the change
            # in its last LIMIT_SAMPLES samples, the constant profiled out.
            cross = LIMIT_SAMPLES * per_sample[:, cols]
            self.limits[(change.kind, change.joint)] = self._limit(change, cross[cols] - cross.T @ window_inverse @ cross)
        for (i, _, _, row), ei, Ji in zip(self._opening, e, J):
            self._push(i, ei, Ji)
            b = self._buffers
            if b.n == WINDOW and b.head % SEGMENT == 0:  # the opening's segments count at once: no change is tested there
                groups, _ = b.evidence(b.n - MIN_AFTER + 1, self.prior)
                self._take_segment(i, [(which, score, info + 1e-12 * np.eye(score.shape[2])) for which, score, info in groups])
        self._scale.fold(index[-1] + WINDOW)
        self._opening.clear()
        logger.info("monitor: opening of %d samples: sigma %s, long-run inflation %.2f", len(index), self.sigma, self.inflation)
        return moved

    def _refit_setup(self, q: np.ndarray, y: np.ndarray) -> None:
        """The session's set-up fitted anew on the samples ``q``, ``y`` (as ``verify`` does)."""
        data = Dataset(q=self._links(q), y=y, measurement=self.measurement, robot=self.robot.name)
        names = setup_names(self.robot, self.measurement)
        problem = Problem.build(self.robot, data, mask=names, params=self.params)
        fit = levenberg_marquardt(problem)
        self.params = problem.full(fit.x)
        self.refit = {"names": names, "samples": len(q)}

    def _moved_sensor(self, q: np.ndarray, y: np.ndarray, floor: np.ndarray, index: list, row) -> Optional[Alarm]:
        """A ``setup`` alarm if the opening's innovations at the calibration's set-up exceed its
        held-out error ``floor`` and the set-up re-fitted on them by :data:`FIT_RATIO` (RMS) each —
        the sensor stands elsewhere (a change before the stream, which the window's constant would
        absorb unseen) —, the set-up then kept re-fitted; else None and the set-up as calibrated."""
        seen = floor > 0
        if not seen.any():
            return None
        before, _ = self._innovations(q, y)
        rms = lambda e: float(np.sqrt(np.mean(e[:, seen] ** 2)))  # noqa: E731
        ratio = rms(before) / float(np.sqrt(np.mean(floor[seen] ** 2)))
        if ratio <= FIT_RATIO:  # as the calibration predicted: the set-up need not be re-fitted to tell
            return None
        calibrated = self.params.copy()
        self._refit_setup(q, y)
        after, _ = self._innovations(q, y)
        if rms(before) <= FIT_RATIO * rms(after):
            self.params, self.refit = calibrated, {}
            return None
        logger.info("monitor: the opening's readings are %.3g x the calibration's held-out error: the set-up re-fitted", ratio)
        return Alarm(index[-1], row, index[0], "setup", None, [], "", list(self.refit["names"]), ratio, provisional=False)

    def _push(self, i: int, e: np.ndarray, J: np.ndarray) -> None:
        z = e / self.sigma
        Jw = J / self.sigma[:, None]
        self._buffers.push(i, Jw.T @ z, Jw.T @ Jw)
        self._delayed.append((z, Jw))
        if len(self._delayed) == WINDOW:  # an innovation leaves the window: it now measures the yardstick, less the window's constant
            z_old, J_old = self._delayed.popleft()
            # Not while the window refills after a change: its constant rests on a few samples, and the
            # innovations leaving it were made by the model before the change, the change's own among them
            # (fed to it, they raised the long-run inflation from 5 to 300 after a joint's zero was found,
            # and the monitor was blind to the next change for thousands of samples).
            if self._buffers.n == WINDOW:
                self._variance.add(z_old - J_old @ self._level)
                self.inflation = self._variance.inflation

    def _step(self, i: int, q: np.ndarray, y: np.ndarray, row) -> Optional[Alarm]:
        if self._drift_left:  # a drift found goes on for a window: the model follows it sample by sample
            self.params += self._drift
            self._drift_left -= 1
        e, J = self._innovations(q, y)
        self._push(i, e[0], J[0])
        found, step = self._test(i, row)
        if found is None:
            self._told = None  # no crossing (any more): a provisional alarm of it stays unapplied
            return None
        waited = i - found.since
        # Named for good once enough samples after its start show which change it is, and no
        # other kind explains it alike (or it has waited long enough for more samples to tell).
        if waited < CONFIRM or (found.could_be and waited < MAX_WAIT):
            # Meanwhile, if the sensor's step is among the kinds that explain it, the change is
            # told at once as that step: the simplest explanation (a constant on the reading, no
            # fault of the robot), and the one a single reading cannot tell from a joint's zero
            # for a while. Once per crossing; not applied.
            if step is not None and self._told is None:
                self._told = step
                self.alarms.append(step)
                return step
            return None
        self._told = None
        left = self._left_by(found, i)
        if left > FIT_RATIO:  # no single kind explains it: said so, nothing applied, the monitor opens anew
            found = replace(found, kind="unexplained", joint=None, size=[], unit="", names=[], evidence=left, could_be=[_kind_words(found)] + found.could_be)
            self.alarms.append(found)
            self._reopen()
            return found
        self._apply(found)
        self.alarms.append(found)
        self._buffers.clear()  # the window starts anew under the changed model
        self._scale.pending.clear()  # taken while the change was under way
        return found

    def _left_by(self, found: Alarm, now: int) -> float:
        """How much more ``found`` leaves of the innovations after its start than the model left
        before it. The window's constant and the change are fitted together, as the test profiles
        them (the constant on every sample, the change from its start on), to the samples before
        the start and the first half of those after it; the RMS of what is left of the second half
        — samples the fit did not see — over that of the samples before the start (their degrees
        of freedom counted). About 1 where the change explains what follows as the model explained
        what preceded. (The constant fitted to the samples before the start alone carried the error
        of a direction they hardly determine — a cable's anchor along a slow path — into the
        samples after it.)"""
        change = next(c for c in self.changes if c.kind == found.kind and c.joint == found.joint)
        window = list(self._delayed)[-min(self._buffers.n, len(self._delayed)) :]
        z = np.array([zj for zj, _ in window])
        Jw = np.array([Jj for _, Jj in window])
        n_after = now - found.since + 1
        n_before = len(z) - n_after
        free = int(np.sum(self.prior == 0))  # the set-up's columns, which the constant fits unhindered
        held = n_before * z.shape[1] <= free + MIN_AFTER  # too few samples before it in this window: the constant held, against the noise
        cols = [self.columns.index(c) for c in change.columns]
        onset = np.arange(n_after, dtype=float) if change.ramp else np.ones(n_after)
        changed = np.zeros((len(z), Jw.shape[1], len(cols)))
        changed[n_before:] = Jw[n_before:][:, :, cols] * onset[:, None, None]
        X = changed if held else np.concatenate([Jw, changed], axis=2)
        penalty = np.zeros(len(cols)) if held else np.concatenate([self.prior, np.zeros(len(cols))])
        # Held out: a constant change fitted with the first half of the samples after its start predicts the second half (a
        # change that is there stays as it was; a kind that only follows the samples it sees does not predict the next ones:
        # D2's re-zero as joint 4's zero). A drift, whose start is uncertain by tens of samples, is judged on the samples it
        # is fitted to.
        fit_until = len(z) if change.ramp else n_before + (n_after + 1) // 2
        A, b = X[:fit_until].reshape(-1, X.shape[2]), z[:fit_until].ravel()
        left = z - X @ np.linalg.lstsq(A.T @ A + np.diag(penalty), A.T @ b, rcond=None)[0]
        before = 1.0 if held else float(np.sum(left[:n_before] ** 2) / (left[:n_before].size - free))
        if change.ramp:
            after = float(np.sum(left[n_before:] ** 2) / max(left[n_before:].size - len(cols), 1))
        else:
            after = float(np.mean(left[fit_until:] ** 2))
        return float(np.sqrt(after / max(before, 1e-300)))

    def _reopen(self) -> None:
        """Starts anew after an unexplained change: the next opening samples re-fit the set-up and
        measure the innovations again."""
        self.sigma = None
        self._opening.clear()
        self._buffers.clear()
        self._delayed.clear()
        self._drift_left = 0
        self._reopened = True

    def _test(self, now: int, row) -> tuple[Alarm | None, Alarm | None]:
        """The change with the strongest evidence over its threshold, or None; and the sensor's
        step as a provisional alarm if it is :data:`TOLD_AT` times over its threshold and within
        e^DISTINCT of that change."""
        b = self._buffers
        starts = b.n - MIN_AFTER + 1  # starts with at least MIN_AFTER samples from them on
        if starts <= 1:
            return None, None
        groups, self._level = b.evidence(starts, self.prior)
        if b.n == WINDOW and b.head == 0:  # once a window
            self._measure_limits(groups)
        groups = [(which, score, info + 1e-12 * np.eye(score.shape[2])) for which, score, info in groups]
        self._take_segment(now, groups)
        self._scale.fold(now)
        scale = self._scale.scale(self.inflation)
        # Per change: its largest statistic, at which start (1-based in the window), and its score and
        # information there (the estimate is solved only for an alarm).
        strongest: list = [None] * len(self.changes)
        for which, score, info in groups:  # the changes of d parameters each, all starts at once
            stat = quadratic_form(info, score) / scale
            for j, k in enumerate(np.argmax(stat, axis=0)):
                strongest[which[j]] = (float(stat[k, j]), int(k) + 1, (info[k, j], score[k, j]))
        if all(stat <= self.threshold[len(c.columns)] for c, (stat, _, _) in zip(self.changes, strongest)):
            return None, None  # the common case: no change ranked (the χ² tails cost more than the test)
        # Kinds of other degrees of freedom compared by how unlikely each is under no change.
        ranked = sorted(((_surprise(stat, len(c.columns)), c, stat, k, fit) for c, (stat, k, fit) in zip(self.changes, strongest)), key=lambda r: -r[0])
        crossed = [r for r in ranked if r[2] > self.threshold[len(r[1].columns)]]

        def alarm(surprise, change, stat, k, fit) -> Alarm:
            info, score = fit
            delta = score / info[0] if len(score) == 1 else np.linalg.solve(info, score)
            scale = np.degrees(delta) if self._unit(change) == "deg" else delta
            found = Alarm(
                now,
                row,
                b.index(k),
                change.kind,
                change.joint,
                [float(v) for v in scale],
                self._unit(change),
                list(change.names),
                stat / self.threshold[len(change.columns)],
                delta=np.array(delta, dtype=float),
            )
            others = [r for r in ranked if r[1] is not change]
            found.margin = float(surprise - others[0][0]) if others else float("inf")
            found.could_be = [_kind_words(c) for v, c, *_ in others if v > surprise - DISTINCT]
            return found

        found = alarm(*crossed[0])
        step = next((r for r in crossed if r[1].kind == "step"), None)
        if step is None or not found.could_be or crossed[0][0] - step[0] >= DISTINCT or step[2] < TOLD_AT * self.threshold[len(step[1].columns)]:
            return found, None
        told = alarm(*step)
        told.provisional = True
        return found, told

    def _take_segment(self, now: int, groups: list) -> None:
        """Every SEGMENT samples of a full window, each change's statistic over its last SEGMENT
        samples, per degree of freedom, for its own yardstick."""
        if self._buffers.n != WINDOW or self._buffers.head % SEGMENT:
            return
        per_dof = np.zeros(len(self.changes))
        for which, score, info in groups:
            per_dof[which] = quadratic_form(info[WINDOW - SEGMENT - 1], score[WINDOW - SEGMENT - 1]) / score.shape[2]
        self._scale.take(now, per_dof)

    def _measure_limits(self, groups: list) -> None:
        """Each change's detection limit in the window now, from the information of a change in
        its last LIMIT_SAMPLES samples; the stated limit is the median over the last
        LIMIT_WINDOWS windows. Not the opening's mean information: within a window the path
        keeps to a small region, where the session's set-up, free in the window's constant, can
        mimic a change far better than over the whole opening (a tracker's step on a simulated
        ABB IRB120: a third of the statistic the opening's figure promised)."""
        row = WINDOW - LIMIT_SAMPLES - 1  # the start LIMIT_SAMPLES before the end (rows begin at the window's second sample)
        here = {}
        for which, _, info in groups:
            for j, k in enumerate(which):
                change = self.changes[k]
                if not change.ramp:
                    here[(change.kind, change.joint)] = self._limit(change, info[row, j])
        self._window_limits.append(here)
        self.limits = {key: float(np.median([w[key] for w in self._window_limits])) for key in here}

    def _apply(self, alarm: Alarm) -> None:
        change = next(c for c in self.changes if c.kind == alarm.kind and c.joint == alarm.joint)
        size = np.radians(alarm.size) if alarm.unit == "deg" else np.asarray(alarm.size)
        if change.ramp:  # the drift so far, as a step of the set-up, and its rate for the next window
            # Carried for one window only: a drift that goes on is then seen anew against a level before it (a
            # drift from the window's first sample cannot be), one that stopped, or a false one, errs no further.
            if not self._drift_left:  # the last drift's window is over: this one alone goes on
                self._drift[:] = 0.0
            self._drift[list(change.columns)] += size
            self._drift_left = WINDOW
            size = size * (alarm.sample - alarm.since)
        self.params[list(change.columns)] += size

    # -- what it found -------------------------------------------------------------------------
    def summary(self) -> dict:
        scale = self._scale.scale(self.inflation)
        units = {(c.kind, c.joint): self._unit(c) for c in self.changes}
        return {
            "samples": self.samples,
            "alarms": [a.to_dict() for a in self.alarms],
            "refused": list(self.refused),
            "opening": {"samples": self.opening, "started": self.sigma is not None, "refit": self.refit or None},
            "noise": None if self.sigma is None else [float(s) for s in self.sigma],
            "inflation": self.inflation,
            "mean_run_length": self.mean_run_length,
            "thresholds": {str(d): h for d, h in self.threshold.items()},
            "detection_limits": [
                {
                    "kind": kind,
                    "joint": joint,
                    "size": (np.degrees(v) if units[kind, joint] == "deg" else v) * math.sqrt(scale),
                    "unit": units[kind, joint],
                    "within": LIMIT_SAMPLES,
                }
                for (kind, joint), v in self.limits.items()
            ],
            "not_applied": self.not_applied,
        }

    def result_document(self) -> dict:
        """The result with what changed applied: its parameters' values as the monitor holds them
        now, and a ``monitor`` record of the alarms."""
        doc = dict(self.doc)
        doc["parameters"] = [{**p, "value": float(v), "deviation": float(v) - p["nominal"]} for p, v in zip(self.doc["parameters"], self.params)]
        doc["monitor"] = self.summary()
        return doc
