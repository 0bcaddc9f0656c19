"""One result type for every calibrator (scipy's vocabulary: ``x, cost, nit, nfev, status,
success, message``), serialisable to the result JSON other tools read."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from ..kernels import covariance, factor_damped, is_sparse, sparse_gram
from .metrics import metrics
from ..data.dataset import Dataset, require_pandas
from ..results import result_document
from .problem import PLAUSIBLE, Problem, implausible_parameters
from ..robot import Robot


#: What implausible parameters usually mean, and the remedy.
UNDETERMINED = "the data do not determine them; a kinematic prior or more varied poses are needed"
#: ... and when a geometry within the tolerances was tried and fits worse.
CONTRADICTED = "the data demand them (a geometry within the tolerances fits worse): they describe the measured region, not the robot"


def implausible_meaning(tolerance_prior) -> str:
    """What a final model's implausible parameters mean, given the report's ``tolerance_prior``
    (:class:`~robocal.diagnosis_file.TolerancePrior` or None): demanded by the data if the prior
    was tried and not kept, undetermined otherwise."""
    return CONTRADICTED if tolerance_prior is not None and not tolerance_prior.accepted else UNDETERMINED


#: Deviations beyond this many times :data:`PLAUSIBLE` (100 mm, 20 deg) are no error of an arm's
#: manufacture or an undetermined direction alone: the geometry is another robot's.
GROSS_FACTOR = 10.0
#: ... what they most likely mean.
GROSS = (
    "far beyond any manufacturing error: the data are probably of another robot than the one given (check `--robot`), "
    "or their joint or length unit is not the one read (deg, mm), or a joint reads from another zero or direction (`robocal diagnose` names such reading conventions)"
)


def grossly_implausible(implausible: list[dict]) -> int:
    """How many kinematic parameters lie beyond :data:`GROSS_FACTOR` times their plausibility
    limit (100 mm, 20°): structure, not a cause a flexible term may fit around — a parameter
    just past its limit (an undetermined last-joint offset) is not."""
    return sum(abs(f["deviation"]) > GROSS_FACTOR * f["limit"] for f in implausible)


def describe_implausible(flags: list[dict], shown: int = 3, meaning: str = UNDETERMINED) -> str:
    """One line on :meth:`CalibrationResult.implausible` flags: how many, the worst ones and
    ``meaning`` — preceded by :data:`GROSS` when the worst is beyond :data:`GROSS_FACTOR` limits."""
    worst = sorted(flags, key=lambda f: -abs(f["deviation"]) / f["limit"])[:shown]
    parts = [f"{f['name']} {f['deviation'] if f['unit'] == 'mm' else np.degrees(f['deviation']):+.4g} {'mm' if f['unit'] == 'mm' else 'deg'}" for f in worst]
    more = ", ..." if len(flags) > shown else ""
    if worst and abs(worst[0]["deviation"]) > GROSS_FACTOR * worst[0]["limit"]:
        meaning = f"{GROSS}; if neither, {meaning}"
    return f"{len(flags)} kinematic parameters moved beyond 10 mm / 2 deg from nominal ({', '.join(parts)}{more}): {meaning}"


#: Held-out RMSE beyond this many times the training RMSE: the fit does not carry to new poses.
OVERFIT_RATIO = 2.0
#: The three verdicts, best first.
VERDICTS = ("trusted", "describes the measured region only", "not determined")


def verdict(doc: dict) -> tuple[str, str]:
    """One of :data:`VERDICTS` on a result document and why, in words: what a user may take
    from it before any figure.

    ``not determined``: the solver did not converge, or the held-out error exceeds
    :data:`OVERFIT_RATIO` times the training error. ``describes the measured region only``:
    parameters beyond 10 mm / 2 deg from nominal, or combinations the data do not determine —
    the model predicts poses like the measured ones, but its parameters are not the robot's.
    ``trusted``: neither.
    """
    train, test = doc["metrics"]["train"], doc["metrics"].get("test")
    if not doc.get("convergence", {}).get("success", True):
        return VERDICTS[2], f"the fit did not converge ({doc['convergence'].get('message', 'no message')})"
    if test and train and train["rmse"] > 0 and test["rmse"] > OVERFIT_RATIO * train["rmse"]:
        return VERDICTS[
            2
        ], f"held-out RMSE {test['rmse']:.4g} mm is over {OVERFIT_RATIO:g}x the training {train['rmse']:.4g} mm: the fit does not carry to new poses"
    implausible, undetermined = doc.get("implausible") or [], doc.get("undetermined") or []
    if implausible or undetermined:
        why = []
        if implausible:
            worst = max(implausible, key=lambda f: abs(f["deviation"]) / f["limit"])
            size = worst["deviation"] if worst["unit"] == "mm" else np.degrees(worst["deviation"])
            why.append(
                f"{len(implausible)} parameters beyond 10 mm / 2 deg from nominal (worst {worst['name']} {size:+.4g} {'mm' if worst['unit'] == 'mm' else 'deg'})"
            )
        if undetermined:
            why.append(f"{len(undetermined)} parameter combinations the data do not determine")
        return VERDICTS[1], "; ".join(why) + ": its predictions hold for poses like the measured ones, its parameters are not the robot's"
    held = f"held-out RMSE {test['rmse']:.4g} mm, " if test else "no held-out samples, "
    return VERDICTS[0], f"converged, {held}every parameter determined and within 10 mm / 2 deg of nominal"


def bounds_against_nominal(problem, x: np.ndarray) -> list[str]:
    """``"a2 at 1 mm (nominal -612.7 mm)"`` for every free parameter of ``x`` that sits on a bound
    of ``problem`` whose interval excludes the parameter's nominal value."""
    bounds, robot = getattr(problem, "bounds", None) or {}, problem.robot
    held = []
    for name, value in zip(problem.names, x):
        if name not in bounds or name not in robot.param_names:
            continue
        k = robot.index(name)
        lower, upper = bounds[name]
        nominal, unit = float(robot.params[k]), robot.param_units[k]
        at_bound = min(abs(value - lower), abs(value - upper)) <= 1e-9 * (1.0 + abs(value))
        if at_bound and not lower <= nominal <= upper:
            show = np.degrees if unit == "rad" else float
            shown_unit = "deg" if unit == "rad" else unit
            held.append(f"{name} at {show(value):.4g} {shown_unit} (nominal {show(nominal):.4g} {shown_unit})")
    return held


def sum_of_squares(r: np.ndarray) -> float:
    """``r @ r`` without the BLAS: OpenBLAS runs a dot product of a residual vector's length
    (tens of thousands) on its threads, which then spin for a while after it returns and take a
    core from the Rust kernels that follow (2 cores, loaded: calibrate 0.11 s → 0.29 s)."""
    return float(np.einsum("i,i->", r, r))


#: Largest condition number of the column-scaled ``JᵀJ`` inverted as it is for the covariance
#: (``J``'s up to 10⁵, far inside the full rank that :func:`robocal.kernels.covariance`'s SVD
#: tolerance of 10⁻⁹ decides); beyond it the SVD of ``J``'s triangular factor decides the rank.
NORMAL_CONDITION = 1e10


def normal_covariance(gram: np.ndarray, r: np.ndarray) -> Optional[np.ndarray]:
    """``σ̂²(JᵀJ)⁻¹`` with ``σ̂² = ‖r‖²/(rows − n)`` from the normal matrix ``gram = JᵀJ`` (n, n)
    when its column-scaled form is well conditioned (:data:`NORMAL_CONDITION`), else None: the
    covariance :func:`robocal.kernels.covariance` gives a full-rank ``J``, without a pass over ``J``."""
    n = len(gram)
    d = np.sqrt(np.diag(gram))
    if n == 0 or len(r) <= n or not np.all(d > 0):
        return None
    w, V = np.linalg.eigh(gram / np.outer(d, d))
    if not w[0] > w[-1] / NORMAL_CONDITION:
        return None
    sigma2 = sum_of_squares(r) / (len(r) - n)
    return sigma2 * ((V / w) @ V.T) / np.outer(d, d)


@dataclass
class CalibrationResult:
    """What a calibration found.

    Attributes
    ----------
    method : str
        The method's name (``lm``, ``ukf-vslm``, ...).
    problem : Problem
        Robot, training data, free parameters and start.
    x : ndarray
        Estimated free parameters (in ``problem.free`` order).
    std : ndarray or None
        Their standard deviations from ``σ̂²(JᵀJ)⁺`` where defined.
    cost : float
        Final ``½‖r‖²`` on the training data.
    history : list of float
        Cost after each iteration (index 0: the start).
    nit, nfev : int
        Iterations and residual evaluations.
    njev : int, optional
        Jacobian evaluations (methods that count them).
    structure : list of str
        Labels of the reading conventions applied to the joint readings before the fit.
    success : bool
    message : str
    time_s : float
        Wall time of the fit.
    metrics : dict
        ``{"train": {...}, "test": {...} or None}`` per eq. (28).
    held_out : Dataset, optional
        The held-out samples the test metrics were computed on (for the provenance).
    robust : dict, optional
        A robust fit's ``loss``, ``f_scale`` (mm) and ``outlying_rows``.
    sessions : list of dict, optional
        A fit on several sessions at once: each session's provenance, set-up, own terms and
        metrics (``problem`` is then the stacked :class:`~robocal.calibration.sessions.Sessions`).
    geometry_only : dict, optional
        An extended model's best geometry without its joint causes — what a URDF or DH table can
        carry — and what leaving them out costs on the held-out samples
        (:func:`robocal.causes.extended.geometry_only_record`).
    """

    method: str
    problem: Problem
    x: np.ndarray
    std: Optional[np.ndarray]
    cost: float
    history: list
    nit: int
    nfev: int
    success: bool
    message: str
    time_s: float
    metrics: dict = field(default_factory=dict)
    held_out: Optional[Dataset] = None
    robust: Optional[dict] = None
    njev: Optional[int] = None
    structure: list = field(default_factory=list)
    sessions: Optional[list] = None
    geometry_only: Optional[dict] = None

    @property
    def params(self) -> np.ndarray:
        """The full calibrated parameter vector."""
        return self.problem.full(self.x)

    @property
    def robot(self) -> Robot:
        """The calibrated robot: its joints with the calibrated parameters. (Causes of an
        extended model and reading conventions are not part of a :class:`Robot`; ``compensate``
        and ``verify`` apply them from :meth:`to_dict`.)"""
        robot = self.problem.robot
        return Robot(robot.name, robot.joints, self.params, mass_model=robot.mass_model)

    @property
    def fun(self) -> np.ndarray:
        """The residuals ``y − h`` at the solution (scipy's ``fun``), prior rows included."""
        return self.problem.residuals(self.x)

    @property
    def status(self) -> int:
        """scipy ``least_squares``'s termination code: 0 the evaluation budget ran out, 1 gtol,
        2 ftol (also the stop at the noise level: the cost cannot fall meaningfully), 3 xtol,
        -1 any other failure."""
        if self.success:
            return 1 if "gtol" in self.message else 3 if "xtol" in self.message else 2
        return 0 if "function evaluations" in self.message else -1

    def parameters(self) -> list[dict]:
        """``{name, unit, nominal, value, std}`` for every parameter of the robot (``std`` is
        ``None`` for parameters that were not estimated)."""
        robot, full = self.problem.robot, self.params
        std = dict(zip(self.problem.free.tolist(), self.std.tolist())) if self.std is not None else {}
        return [
            {"name": n, "unit": u, "nominal": float(nom), "value": float(v), "std": std.get(k)}
            for k, (n, u, nom, v) in enumerate(zip(robot.param_names, robot.param_units, robot.params, full))
        ]

    def parameters_frame(self):
        """:meth:`parameters` as a pandas DataFrame, one row per robot parameter, indexed by
        position: columns ``name``, ``value``, ``nominal``, ``deviation`` (value − nominal),
        ``std`` (NaN where not estimated), ``unit`` (mm or rad) and ``estimated`` (bool).
        pandas is optional: needed only here."""
        pd = require_pandas("CalibrationResult.parameters_frame")
        rows = self.parameters()
        estimated = np.zeros(len(rows), dtype=bool)
        estimated[self.problem.free] = True
        return pd.DataFrame(
            {
                "name": [p["name"] for p in rows],
                "value": np.array([p["value"] for p in rows], dtype=np.float64),
                "nominal": np.array([p["nominal"] for p in rows], dtype=np.float64),
                "deviation": np.array([p["value"] - p["nominal"] for p in rows], dtype=np.float64),
                "std": np.array([np.nan if p["std"] is None else p["std"] for p in rows], dtype=np.float64),
                "unit": [p["unit"] for p in rows],
                "estimated": estimated,
            }
        )

    def implausible(self) -> list[dict]:
        """Kinematic parameters that moved further from nominal than :data:`PLAUSIBLE`: the data
        did not determine them (a narrow workspace lets weak directions absorb other errors);
        a ``kinematic_prior`` or more varied poses are the remedies."""
        robot, full = self.problem.robot, self.params
        return implausible_parameters(robot, {robot.param_names[k]: full[k] for k in self.problem.free})

    def undetermined(self, shown: int = 4) -> list[dict]:
        """Parameter combinations the data leave wider than :data:`PLAUSIBLE`.

        In coordinates scaled by the limits (10 mm, 2°; 1 % for a scale factor), the singular
        directions ``v`` of the scaled Jacobian with standard deviation ``σ̂/s`` above one: the fit
        can move along them by more than a limit without changing what the data can tell apart.
        Each is ``{"std": σ̂/s (in limits), "combination": {name: weight}}`` with the ``shown``
        largest weights of ``v`` (unit norm; a parameter's move is weight · std · its limit).
        """
        both = getattr(self.problem, "residuals_and_jacobian", None)  # one pass of the core where the problem has it
        r, J = both(self.x) if both else (self.problem.residuals(self.x), self.problem.jacobian(self.x))
        if J.shape[0] <= J.shape[1] or J.shape[1] == 0:
            return []
        units = [self.problem.robot.param_units[k] for k in self.problem.free]
        limits = np.array([PLAUSIBLE.get(u, 0.01) for u in units] + [1.0] * (J.shape[1] - len(units)))
        if is_sparse(J):  # a model with joint maps: the singular values from the normal equations
            s2, V = np.linalg.eigh(sparse_gram(J) * np.outer(limits, limits))
            sv, Vt = np.sqrt(np.maximum(s2[::-1], 0.0)), V[:, ::-1].T  # largest first, as an SVD gives them
        else:  # every direction (a null one is the most undetermined), from the SVD of J's triangular factor (n, n) rather than of J (m, n)
            _, sv, Vt = np.linalg.svd(factor_damped(J * limits).r)
        noise = float(np.sqrt(r @ r / (J.shape[0] - J.shape[1])))
        names = list(self.problem.names)
        out = []
        for s, v in zip(sv, Vt):
            std = noise / s if s > 0 else np.inf
            if std > 1.0:
                top = np.argsort(-np.abs(v))[:shown]
                out.append({"std": float(std), "combination": {names[k]: float(v[k]) for k in top}})
        return out

    def to_dict(self) -> dict:
        """The result file (:mod:`robocal.results`, schema ``robocal.result/1``): ``method``,
        ``robot``, ``measurement``, ``parameters``, ``free``, ``fixed`` (name -> reason),
        ``implausible`` (see :meth:`implausible`), ``undetermined`` (:meth:`undetermined`), ``metrics``, ``convergence``, ``causes`` for
        an extended model, the robot's definition and the dataset's provenance (per session in
        ``sessions`` for a fit on several)."""
        if self.sessions is not None:
            return result_document(self._core(), self.problem.robot)
        return result_document(self._core(), self.problem.robot, self.problem.data, self.held_out)

    def _core(self) -> dict:
        return self._with_model(
            {
                "method": self.method,
                "robot": self.problem.robot.name,
                "measurement": self.problem.data.measurement,
                "parameters": self.parameters(),
                "free": self.problem.names,
                "fixed": self.problem.fixed,
                "implausible": self.implausible(),
                "undetermined": self.undetermined(),
                "metrics": self.metrics,
                "convergence": {
                    "success": bool(self.success),
                    "message": self.message,
                    "nit": int(self.nit),
                    "nfev": int(self.nfev),
                    "njev": None if self.njev is None else int(self.njev),
                    "cost": float(self.cost),
                    "history": [float(c) for c in self.history],
                    "time_s": float(self.time_s),
                },
            }
        )

    def _with_model(self, doc: dict) -> dict:
        """What goes beyond the geometry: an extended model's causes
        (:class:`robocal.causes.ExtendedProblem`), a robust fit's outliers, the reading
        conventions, the sessions of a fit on several."""
        if hasattr(self.problem, "describe_causes"):
            doc["causes"] = self.problem.describe_causes(self.x, self.std)
        if self.robust is not None:
            doc["robust"] = self.robust
        if self.structure:
            doc["structure"] = list(self.structure)  # reading conventions applied to the joint readings
        if self.sessions is not None:
            doc["sessions"] = self.sessions
        if self.geometry_only is not None:
            doc["geometry_only"] = self.geometry_only
        return doc

    @classmethod
    def from_fit(
        cls,
        method: str,
        problem: Problem,
        x,
        history,
        nit: int,
        nfev: int,
        success: bool,
        message: str,
        time_s: float,
        *,
        evaluated=None,
        with_std: bool = True,
    ) -> "CalibrationResult":
        """Wraps a fitted ``x``: cost, covariance-based ``std`` (``with_std=False``: None) and
        training metrics. ``evaluated``: ``(problem.residuals(x), problem.jacobian(x), JᵀJ or
        None)`` when the caller has them."""
        x = np.asarray(x, dtype=np.float64)
        held = bounds_against_nominal(problem, x)
        if held and success:  # the optimum lies beyond the bounds: no convergence to the data
            success, message = (
                False,
                f"stopped at bounds that exclude the nominal value ({'; '.join(held)}): the data pull beyond them (the solver's stop: {message})",
            )
        if evaluated is None:
            evaluated = (problem.residuals(x), problem.jacobian(x) if with_std else None, None)
        r, J, gram = evaluated
        # A plain problem without priors and with unit row weights minimises its data residuals themselves.
        plain = type(problem) is Problem and not problem.prior and problem.data.measurement != "pose"
        data_r = r if plain else problem.data_residuals(x)
        std = None
        if with_std and J.shape[0] > J.shape[1]:
            cov = None if gram is None else normal_covariance(gram, r)
            if cov is None:
                cov, _, _, rank = covariance(J, r)
                cov = cov if rank == J.shape[1] else None
            std = None if cov is None else np.sqrt(np.diag(cov))
        return cls(
            method=method,
            problem=problem,
            x=x,
            std=std,
            cost=0.5 * sum_of_squares(r),
            history=list(history),
            nit=nit,
            nfev=nfev,
            success=success,
            message=message,
            time_s=time_s,
            metrics={"train": metrics(data_r, problem.data.measurement), "test": None},
        )
