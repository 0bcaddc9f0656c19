"""The model a calibration will fit, linearised (:func:`_design`): each candidate contributes the
rows ``J_i`` of the identification Jacobian — the identifiable geometry of
:meth:`~robocal.calibration.problem.Problem.build` and, given a diagnosis or an extended result,
the causes acting on the joints (:class:`~robocal.causes.problem.ExtendedProblem`) — so the plan
is judged on the same Jacobian the fit uses, evaluated by the Rust core. Beside them: what the
data already measured say, the joint maps' roughness prior and the tool point's Jacobian over a
sample of the workspace, every column scaled to its RMS over the candidates."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Optional

import numpy as np

from ..calibration.problem import Problem, fit_row_weights, is_kinematic
from ..calibration.sessions import concatenate, session_problems, setup_eliminated
from ..causes.extended import extended_problem
from ..data.dataset import Dataset
from ..kernels import is_sparse
from ..robot import RESIDUAL_WIDTH, Robot, setup_names, zero_names
from .criteria import RIDGE

#: Poses on which the predicted position's standard deviation over the workspace is averaged.
WORKSPACE_POSES = 500


@dataclass
class _Design:
    """The model the calibration will fit, linearised: its entries' names, the robot's parameter
    units (None for a cause's coefficient), the column scales (each column's RMS over the
    candidates), every candidate's rows (scaled, (n, k, p)), the information of the measured data
    and of the joint maps' roughness priors (scaled, (p, p)), the Jacobian of the tool point over a
    sample of the workspace (scaled, (w, 3, p)), the causes with their slices of the entries, and
    the parameters left out with why."""

    names: list
    units: list
    scale: np.ndarray
    A: np.ndarray
    M_data: np.ndarray
    M_prior: np.ndarray
    position: np.ndarray
    causes: list
    slices: list
    fixed: dict
    base_free: np.ndarray
    labels: list
    fitted: dict


def _design(
    robot: Robot,
    measurement: str,
    params: np.ndarray,
    data: Optional[Dataset],
    pool: np.ndarray,
    labels: list,
    sigma: float,
    rng: np.random.Generator,
    fitted: Optional[dict] = None,
    mask: Optional[list] = None,
) -> _Design:
    """The model over the measured samples and the candidates (model angles, (n, N)), linearised
    at ``params``; ``fitted``: label -> detail of the joint maps a result fitted (they keep its
    range and knots); ``mask``: the parameters of a result, considered with the set-up kept
    first (a parameter redundant with a new session's set-up, as ``a6`` with ``tool_x``, is the
    set-up's: :func:`~robocal.calibration.sessions.session_problems`); default the robot's, the
    identifiable subset as a calibration on the data decides it."""
    k = RESIDUAL_WIDTH[measurement]
    expected = Dataset(q=pool, y=robot.predict(measurement, pool, params), measurement=measurement, robot=robot.name)
    both = expected if data is None else concatenate([replace(data, extra={}), expected])
    m = 0 if data is None else len(data)
    problem = Problem.build(robot, both, params=params) if mask is None else session_problems(robot, [both], mask)[0]
    problem.start = params.copy()  # linearised at the set-up given or fitted before, not re-fitted on expected readings
    model = problem if not labels else extended_problem(problem, both, np.arange(len(both)), labels, noise=sigma, fitted=fitted)
    J = model.jacobian(model.x0)
    J = J.toarray() if is_sparse(J) else np.asarray(J)
    data_rows, pool_rows, prior_rows = J[: m * k], J[m * k : (m + len(pool)) * k], J[(m + len(pool)) * k :]
    scale = np.sqrt(np.sum(pool_rows**2, axis=0) / len(pool))
    scale = np.where(scale > 0, scale, 1.0)
    names = list(model.names)
    causes, slices = list(getattr(model, "causes", [])), list(getattr(model, "slices", []))
    # The tool point in the robot's base frame: the robot's own entries move it (kinematics, the
    # tool, the causes acting on the joints: ∂p/∂q_j·B), the sensor's set-up does not.
    w = rng.choice(len(pool), size=min(WORKSPACE_POSES, len(pool)), replace=False)
    zeroed = params.copy()
    zeroed[[robot.index(f"base_{c}") for c in ("x", "y", "z", "rx", "ry", "rz")]] = 0.0
    own = [i for i, n in enumerate(names) if n in robot.param_names and (is_kinematic(n) or n.startswith("tool_"))]
    thetas = [robot.index(f"theta{j + 1}") for j in range(robot.n_joints)]
    Jp = robot.jacobian("position", pool[w], params=zeroed, cols=[robot.index(names[i]) for i in own] + thetas)
    position = np.zeros((len(w) * 3, len(names)))
    position[:, own] = Jp[:, : len(own)]
    for c, s in zip(causes, slices):
        if c.stage == "joints":
            B = c.basis[m + w]
            B = B.toarray() if is_sparse(B) else np.asarray(B)
            position[:, s] = Jp[:, len(own) + c.joint][:, None] * np.repeat(B, 3, axis=0)
    units = dict(zip(robot.param_names, robot.param_units))
    data_scaled, prior_scaled = data_rows / scale, prior_rows / scale  # every column in units of its scale
    return _Design(
        names=names,
        units=[units.get(n) for n in names],
        scale=scale,
        A=(pool_rows / scale).reshape(len(pool), k, -1),
        M_data=data_scaled.T @ data_scaled,
        M_prior=prior_scaled.T @ prior_scaled,
        position=(position / scale).reshape(len(w), 3, -1),
        causes=causes,
        slices=slices,
        fixed=dict(problem.fixed),
        base_free=np.asarray(problem.free),
        labels=list(labels),
        fitted=dict(fitted or {}),
    )


@dataclass
class _ZeroDesign:
    """A re-mastering's model linearised on the candidates (criterion ``"Ds"``): the new session's
    set-up and the joints' zero offsets, the rest of the robot held — and, where the result's
    information is known, the result's own error as a nuisance with that information as its prior
    (:func:`with_result_error`). Its entries' names, the column scales (RMS over the candidates),
    every candidate's rows (scaled, (n, k, p)), the prior information (scaled, (p, p)), the
    positions of the zeros the candidates can tell from the set-up, and for the others the set-up
    entries that reproduce them."""

    names: list
    scale: np.ndarray
    A: np.ndarray
    M0: np.ndarray
    of: list
    absorbed: dict


def _zero_design(robot: Robot, measurement: str, params: np.ndarray, pool: np.ndarray) -> _ZeroDesign:
    """The set-up's and the zeros' columns of the identification Jacobian on the candidates
    ``pool`` (model angles) at ``params``, weighted as a fit weighs them; a zero the set-up
    reproduces on every candidate (:func:`~robocal.calibration.sessions.setup_eliminated`: joint 1's
    zero against a tracker's frame or a cable's anchor) is left out — no pose separates it."""
    k = RESIDUAL_WIDTH[measurement]
    setup, zeros = setup_names(robot, measurement), zero_names(robot)
    expected = Dataset(q=pool, y=robot.predict(measurement, pool, params), measurement=measurement, robot=robot.name)
    J = robot.jacobian(measurement, pool, y=expected.y, params=params, cols=setup + zeros) * fit_row_weights(expected)[:, None]
    S, Z = J[:, : len(setup)], J[:, len(setup) :]
    _, absorbed = setup_eliminated(S, Z)
    apart = np.array([z not in absorbed for z in range(len(zeros))], dtype=bool)
    kept = setup + [n for n, a in zip(zeros, apart) if a]
    J = np.hstack([S, Z[:, apart]])
    scale = np.sqrt(np.sum(J**2, axis=0) / len(pool))
    scale = np.where(scale > 0, scale, 1.0)
    return _ZeroDesign(
        names=kept,
        scale=scale,
        A=(J / scale).reshape(len(pool), k, -1),
        M0=RIDGE * np.eye(len(kept)),
        of=list(range(len(setup), len(kept))),
        absorbed={zeros[z]: [setup[i] for i in by] for z, by in absorbed.items()},
    )


def with_result_error(zeros: _ZeroDesign, design: _Design, M_result: np.ndarray) -> _ZeroDesign:
    """The re-mastering's model with the result's own error beside the zeros' changes: the
    robot's entries of ``design`` (all but the set-up), held at the result's values, err as the
    result's training data left them — a nuisance with prior information ``M_result`` (scaled as
    ``design``), as :func:`~robocal.remastering.remaster` weighs the new points by ``σ²I + J C Jᵀ``.
    A pose where the result's error is large (beyond the path it was calibrated on) then tells a
    zero's change less, and the plan states the standard deviation the re-mastering will."""
    setup = set(zeros.names) - {zeros.names[i] for i in zeros.of}
    own = [i for i, n in enumerate(design.names) if n not in setup]  # a zero's own error too: the change found includes it
    A = np.concatenate([zeros.A, design.A[:, :, own]], axis=2)
    M0 = np.zeros((A.shape[2],) * 2)
    M0[: len(zeros.names), : len(zeros.names)] = zeros.M0
    M0[len(zeros.names) :, len(zeros.names) :] = M_result[np.ix_(own, own)] + design.M_prior[np.ix_(own, own)] + RIDGE * np.eye(len(own))
    return replace(zeros, names=zeros.names + [f"result's {design.names[i]}" for i in own], scale=np.concatenate([zeros.scale, design.scale[own]]), A=A, M0=M0)
