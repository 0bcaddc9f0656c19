"""The paper's population-based comparison methods (Table VI): M2 beetle antennae search, M4
particle swarm optimisation and M7 differential evolution.

All three minimise ``problem.cost`` (``½‖r‖²``) over the free parameters inside a box around
``problem.x0`` and search in the box's unit cube, ``x = lower + u·(upper − lower)``, so that
millimetres and radians are searched on the same footing. None of them has a convergence proof:
``success`` means the method finished its budget or met its tolerance, and ``message`` says
which. Everything random draws from ``numpy.random.default_rng(seed)``: equal seeds give equal
results.

The default box (:data:`HALF_WIDTHS`) is sized for kinematic *errors* around a good start. When
the start is far from the optimum (e.g. an unknown tool offset, which the identifiability
analysis may alias into ``a6``/``d6``), widen it with ``bounds``; the methods cannot leave it.
"""

from __future__ import annotations

import math
import time
from typing import Callable, Mapping, Optional, Union

import numpy as np

from ..kernels import as_count, as_float_array, as_positive, as_tolerance, seeded_rng
from ..exceptions import InvalidParameterError
from .problem import Problem
from .result import CalibrationResult

#: Default half-width of the search box per parameter unit: 2 mm for lengths, 0.2° for angles,
#: 1e-3 for dimensionless parameters (``cable_scale``).
HALF_WIDTHS = {"mm": 2.0, "rad": math.radians(0.2), "1": 1e-3}

Bounds = Union[None, Mapping[str, float], tuple]


def search_box(problem: Problem, bounds: Bounds = None) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds of the free parameters.

    Parameters
    ----------
    problem : Problem
    bounds : None, mapping or (lower, upper)
        ``None``: ``x0 ± HALF_WIDTHS[unit]``. A mapping: half-widths by parameter name or by
        unit (a name wins over its unit; units not given keep the default). A pair of arrays
        (or scalars) of shape ``(n_free,)``: the box itself.

    Returns
    -------
    lower, upper : ndarray, shape (n_free,)
    """
    x0 = problem.x0
    if bounds is None or isinstance(bounds, Mapping):
        given = dict(bounds or {})
        units = [problem.robot.param_units[k] for k in problem.free]
        half = np.array([given.get(name, given.get(unit, HALF_WIDTHS[unit])) for name, unit in zip(problem.names, units)], dtype=np.float64)
        lower, upper = x0 - half, x0 + half
    else:
        lower, upper = (np.broadcast_to(np.asarray(b, dtype=np.float64), x0.shape).copy() for b in bounds)
    # The problem's own hard limits always hold.
    lower, upper = np.maximum(lower, problem.lower), np.minimum(upper, problem.upper)
    if not np.all(upper > lower):
        raise InvalidParameterError("every bound must satisfy lower < upper (search box within the problem's bounds)")
    return lower, upper


class _Objective:
    """``problem.cost`` on points of the unit cube, counting evaluations."""

    def __init__(self, problem: Problem, bounds: Bounds):
        self.problem = problem
        self.lower, self.upper = search_box(problem, bounds)
        self.nfev = 0

    def to_x(self, u: np.ndarray) -> np.ndarray:
        return self.lower + u * (self.upper - self.lower)

    def start(self) -> np.ndarray:
        """``problem.x0`` in unit-cube coordinates (clipped into the box)."""
        return np.clip((self.problem.x0 - self.lower) / (self.upper - self.lower), 0.0, 1.0)

    def __call__(self, U: np.ndarray) -> np.ndarray:
        """Costs of a population ``U`` (pop, n) of unit-cube points."""
        X = self.to_x(np.atleast_2d(U))
        self.nfev += len(X)
        return self.problem.costs(X)


def _converged(costs: np.ndarray, tol: float) -> bool:
    """scipy's ``differential_evolution`` test: ``std(costs) ≤ tol·|mean(costs)|``."""
    return bool(np.std(costs) <= tol * abs(np.mean(costs)))


def _result(method: str, f: _Objective, u_best, history, nit: int, converged: bool, budget: str, tol_message: str, t0: float) -> CalibrationResult:
    message = tol_message if converged else f"finished the budget of {budget} (no convergence test met; not a proof of optimality)"
    return CalibrationResult.from_fit(method, f.problem, f.to_x(u_best), history, nit, f.nfev, True, message, time.perf_counter() - t0)


def bas(
    problem: Problem,
    bounds: Bounds = None,
    max_iter: int = 3000,
    step: float = 0.5,
    step_decay: float = 0.995,
    antenna_ratio: float = 0.5,
    xtol: float = 1e-6,
    seed: int = 0,
    method: str = "bas",
) -> CalibrationResult:
    """M2: beetle antennae search (Jiang & Li 2017, arXiv:1710.10724).

    Each iteration draws a random unit direction ``b``, smells the cost at the two antennae
    ``x ± d·b`` and moves ``x ← x − δ·b·sign(f(x + d·b) − f(x − d·b))``; the step shrinks as
    ``δ ← η·δ`` and the antenna length follows it, ``d = c·δ`` (the ``d = δ/c`` variant of the
    follow-up BAS papers). The best point seen is returned. Coordinates are those of the unit
    cube of the box (see :func:`search_box`); the beetle is clipped into it.

    Parameters
    ----------
    problem : Problem
    bounds : optional
        See :func:`search_box`.
    max_iter : int
        Iterations (3 cost evaluations each: two antennae and the new position).
    step : float
        Initial step ``δ₀`` in unit-cube coordinates (0.5: half the box).
    step_decay : float
        ``η``. Jiang & Li use 0.95 for short runs; 0.995 spreads the decay over ~1000 iterations.
    antenna_ratio : float
        ``c = d/δ``.
    xtol : float
        Stop once ``δ < xtol``.
    seed : int
    method : str
        Name recorded in the result.

    Returns
    -------
    CalibrationResult
        ``history`` holds the best cost after each iteration (index 0: the start).
    """
    max_iter, xtol = as_count(max_iter, "max_iter", 0), as_tolerance(xtol, "xtol")
    step, step_decay, antenna_ratio = (as_positive(v, n) for v, n in ((step, "step"), (step_decay, "step_decay"), (antenna_ratio, "antenna_ratio")))
    t0 = time.perf_counter()
    rng = seeded_rng(seed)
    f = _Objective(problem, bounds)
    u = f.start()
    best_u, best = u.copy(), float(f(u[None])[0])
    history, nit, converged = [best], 0, False
    for nit in range(1, max_iter + 1):
        b = rng.standard_normal(u.size)
        b /= np.linalg.norm(b)
        d = antenna_ratio * step
        right, left = f(np.clip(np.stack([u + d * b, u - d * b]), 0.0, 1.0))
        u = np.clip(u - step * b * np.sign(right - left), 0.0, 1.0)
        cost = float(f(u[None])[0])
        if cost < best:
            best_u, best = u.copy(), cost
        history.append(best)
        step *= step_decay
        if step < xtol:
            converged = True
            break
    return _result(method, f, best_u, history, nit, converged, f"{max_iter} iterations", f"the step fell below xtol={xtol:g} after {nit} iterations", t0)


def pso(
    problem: Problem,
    bounds: Bounds = None,
    population: int = 40,
    max_iter: int = 300,
    w: tuple = (0.9, 0.4),
    c1: float = 2.0,
    c2: float = 2.0,
    vmax: float = 0.2,
    tol: float = 1e-8,
    seed: int = 0,
    method: str = "pso",
) -> CalibrationResult:
    """M4: global-best particle swarm optimisation.

    Kennedy & Eberhart (1995) with Shi & Eberhart's (1998) inertia weight, decreased linearly
    from ``w[0]`` to ``w[1]`` over the run::

        v ← w·v + c1·r1·(p_best − x) + c2·r2·(g_best − x),   x ← x + v

    with ``r1, r2 ~ U(0, 1)`` per particle and coordinate, ``|v| ≤ vmax`` per coordinate and the
    particles clipped into the unit cube of the box (velocity zeroed where clipped). Particle 0
    starts at ``problem.x0``, the others uniformly in the box.

    Parameters
    ----------
    problem : Problem
    bounds : optional
        See :func:`search_box`.
    population : int
        Particles.
    max_iter : int
        Iterations (``population`` cost evaluations each).
    w : (float, float)
        Inertia weight at the first and the last iteration (Shi & Eberhart: 0.9 → 0.4).
    c1, c2 : float
        Cognitive and social coefficients (Kennedy & Eberhart: 2, 2).
    vmax : float
        Velocity clamp in unit-cube coordinates.
    tol : float
        Stop when the personal-best costs agree: ``std ≤ tol·|mean|``.
    seed : int
    method : str

    Returns
    -------
    CalibrationResult
        ``history`` holds the global-best cost after each iteration (index 0: the initial swarm).
    """
    population, max_iter, tol = as_count(population, "population"), as_count(max_iter, "max_iter", 0), as_tolerance(tol, "tol")
    c1, c2, vmax = (as_positive(v, n) for v, n in ((c1, "c1"), (c2, "c2"), (vmax, "vmax")))
    w = as_float_array(w, "w")
    if w.shape != (2,) or not np.all(np.isfinite(w)):
        raise InvalidParameterError(f"`w` must be the inertia weights (first, last); got {w!r}")
    t0 = time.perf_counter()
    rng = seeded_rng(seed)
    f = _Objective(problem, bounds)
    n = f.lower.size
    x = rng.random((population, n))
    x[0] = f.start()
    v = rng.uniform(-vmax, vmax, (population, n))
    p_best, p_cost = x.copy(), f(x)
    g = int(np.argmin(p_cost))
    history, nit, converged = [float(p_cost[g])], 0, False
    for nit in range(1, max_iter + 1):
        weight = w[0] + (w[1] - w[0]) * (nit - 1) / max(max_iter - 1, 1)
        r1, r2 = rng.random((2, population, n))
        v = np.clip(weight * v + c1 * r1 * (p_best - x) + c2 * r2 * (p_best[g] - x), -vmax, vmax)
        x = x + v
        outside = (x < 0.0) | (x > 1.0)
        x = np.clip(x, 0.0, 1.0)
        v[outside] = 0.0
        cost = f(x)
        better = cost < p_cost
        p_best[better], p_cost[better] = x[better], cost[better]
        g = int(np.argmin(p_cost))
        history.append(float(p_cost[g]))
        if _converged(p_cost, tol):
            converged = True
            break
    return _result(
        method, f, p_best[g], history, nit, converged, f"{max_iter} iterations", f"the personal-best costs agree to tol={tol:g} after {nit} iterations", t0
    )


def de(
    problem: Problem,
    bounds: Bounds = None,
    population: Optional[int] = None,
    max_iter: int = 1000,
    F: float = 0.5,
    CR: float = 0.9,
    tol: float = 1e-8,
    seed: int = 0,
    method: str = "de",
) -> CalibrationResult:
    """M7: differential evolution, DE/rand/1/bin (Storn & Price 1997).

    For every target ``x_i`` a mutant ``v = x_r1 + F·(x_r2 − x_r3)`` (``r1, r2, r3`` distinct and
    ≠ ``i``) is crossed binomially with it (each coordinate from ``v`` with probability ``CR``,
    at least one always); the trial replaces the target if its cost is not worse. Mutants
    leaving the unit cube of the box are reset uniformly between the parent and the violated
    bound. Member 0 starts at ``problem.x0``, the others uniformly in the box.

    Parameters
    ----------
    problem : Problem
    bounds : optional
        See :func:`search_box`.
    population : int, optional
        ``NP``; default ``10·n_free`` (Storn & Price's rule of thumb), at least 8.
    max_iter : int
        Generations (``NP`` cost evaluations each).
    F, CR : float
        Differential weight and crossover rate (Storn & Price: F = 0.5, CR = 0.9 as a start).
    tol : float
        Stop when the population's costs agree: ``std ≤ tol·|mean|`` (scipy's test).
    seed : int
    method : str

    Returns
    -------
    CalibrationResult
        ``history`` holds the best cost after each generation (index 0: the initial population).
    """
    max_iter, tol = as_count(max_iter, "max_iter", 0), as_tolerance(tol, "tol")
    F, CR = as_positive(F, "F"), as_positive(CR, "CR")
    t0 = time.perf_counter()
    rng = seeded_rng(seed)
    f = _Objective(problem, bounds)
    n = f.lower.size
    NP = max(8, 10 * n) if population is None else as_count(population, "population", 4)  # DE/rand/1 draws 3 others
    x = rng.random((NP, n))
    x[0] = f.start()
    cost = f(x)
    history, nit, converged = [float(cost.min())], 0, False
    others = np.array([np.delete(np.arange(NP), i) for i in range(NP)])
    for nit in range(1, max_iter + 1):
        # Three distinct members other than i: the first three of a random permutation of the others.
        r = np.take_along_axis(others, np.argpartition(rng.random(others.shape), 3, axis=1)[:, :3], axis=1)
        mutant = x[r[:, 0]] + F * (x[r[:, 1]] - x[r[:, 2]])
        low, high = mutant < 0.0, mutant > 1.0
        mutant[low] = rng.random(low.sum()) * x[low]
        mutant[high] = x[high] + rng.random(high.sum()) * (1.0 - x[high])
        cross = rng.random((NP, n)) < CR
        cross[np.arange(NP), rng.integers(0, n, NP)] = True
        trial = np.where(cross, mutant, x)
        trial_cost = f(trial)
        keep = trial_cost <= cost
        x[keep], cost[keep] = trial[keep], trial_cost[keep]
        history.append(float(cost.min()))
        if _converged(cost, tol):
            converged = True
            break
    return _result(
        method,
        f,
        x[int(np.argmin(cost))],
        history,
        nit,
        converged,
        f"{max_iter} generations",
        f"the population's costs agree to tol={tol:g} after {nit} generations",
        t0,
    )


#: method name -> (paper label, description, function(problem, **options) -> CalibrationResult)
METHODS: dict[str, tuple[str, str, Callable[..., CalibrationResult]]] = {
    "bas": ("M2", "beetle antennae search", bas),
    "pso": ("M4", "particle swarm optimisation", pso),
    "de": ("M7", "differential evolution", de),
}
