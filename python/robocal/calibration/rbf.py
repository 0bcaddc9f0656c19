"""M5 of the paper's Table VI: a radial-basis-function network that learns the error of the
nominal model (after Chen et al. 2019, "positional error compensation ... RBF neural network").

This is a black-box corrector, not a calibration: the kinematic parameters stay at
``problem.x0`` (nominal kinematics with the closed-form measurement set-up of
:func:`~robocal.calibration.problem.start_parameters`), and the network predicts the residual
``y − h(x0)`` from the joint angles ``q``::

    c(q) = Σ_j W_j · exp(−‖q − μ_j‖² / (2σ²)) + b

with centres ``μ_j`` from k-means on the training joint angles, ``σ`` the median distance
between centres, and output weights ``[W; b]`` from ridge regression on the training residuals.
The corrected prediction is ``h(x0) + c(q)``, so the corrected residual is ``y − h(x0) − c(q)``.

Held-out metrics (the harness's ``held_out.data_residuals(result.x)`` would give the *uncorrected*
nominal error)::

    result = rbf(problem)
    test_metrics = metrics(result.corrected_residuals(test_dataset), test_dataset.measurement)
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Optional, Union

import numpy as np

from ..kernels import as_count, as_tolerance, seeded_rng
from ..data.dataset import Dataset
from .metrics import metrics
from .problem import Problem
from .result import CalibrationResult


@dataclass
class RBFResult(CalibrationResult):
    """A :class:`CalibrationResult` whose ``x`` is ``problem.x0`` (no parameter is estimated)
    plus the fitted corrector. ``cost``, ``history`` and ``metrics["train"]`` are of the
    corrected training residuals (``history``: nominal cost, then corrected cost).

    Attributes
    ----------
    centers : ndarray, shape (n_centers, N)
        Kernel centres in joint space (rad).
    width : float
        Gaussian width ``σ`` (rad).
    weights : ndarray, shape (n_centers + 1, k)
        Output weights; the last row is the bias.
    ridge : float
        Ridge penalty used.
    """

    centers: Optional[np.ndarray] = None
    width: float = 1.0
    weights: Optional[np.ndarray] = None
    ridge: float = 0.0

    def _features(self, q) -> np.ndarray:
        return _features(np.atleast_2d(np.asarray(q, dtype=np.float64)), self.centers, self.width)

    def predict_correction(self, q) -> np.ndarray:
        """The predicted residual of the nominal model, ``c(q)``, shape (m, k) (k = 1 | 3 | 6)."""
        return self._features(q) @ self.weights

    def corrected_residuals(self, data: Union[Problem, Dataset]) -> np.ndarray:
        """``y − h(x0) − c(q)`` on other data (same robot and measurement), flattened (m·k,).

        ``data`` is a :class:`Dataset` or a :class:`Problem` (its dataset is used). The nominal
        model is always the *training* one (``self.params``, including the set-up fitted on the
        training data), never a set-up re-fitted on the new data.
        """
        dataset = data.data if isinstance(data, Problem) else data
        robot = self.problem.robot
        r = robot.residuals(dataset.measurement, dataset.q, dataset.y, params=self.params)
        return (r - self.predict_correction(dataset.q)).ravel()

    def to_dict(self) -> dict:
        doc = super().to_dict()
        doc["corrector"] = {"kind": "rbf", "n_centers": int(len(self.centers)), "width_rad": float(self.width), "ridge": float(self.ridge)}
        return doc


def _features(q: np.ndarray, centers: np.ndarray, width: float) -> np.ndarray:
    """Gaussian kernels plus a constant column, (m, n_centers + 1)."""
    from scipy.spatial.distance import cdist  # here, as in rbf(): every command imports this module

    phi = np.exp(-cdist(q, centers, "sqeuclidean") / (2.0 * width**2))
    return np.hstack([phi, np.ones((len(q), 1))])


def rbf(problem: Problem, n_centers: Optional[int] = None, ridge: float = 1e-6, seed: int = 0, method: str = "rbf") -> RBFResult:
    """M5: fits an RBF network to the nominal model's training residuals.

    Parameters
    ----------
    problem : Problem
        Its start ``problem.x0`` is the nominal model that is corrected.
    n_centers : int, optional
        Kernels; default ``min(50, m // 4)`` (at least 1) for ``m`` training samples.
    ridge : float
        Ridge penalty ``λ`` of ``(ΦᵀΦ + λ·m·I) W = Φᵀ R`` (scaled by ``m`` so that it does not
        weaken as data grow; the bias is penalised as well). The default is light: on simulated
        HSR JR680 cable data (300 samples) 1e-6 generalised better than 1e-4..1e-2.
    seed : int
        Seed of the k-means initialisation.
    method : str

    Returns
    -------
    RBFResult
    """
    # scipy.cluster and scipy.spatial take half a second to import; every command imports this module, few fit an RBF.
    from scipy.cluster.vq import kmeans2
    from scipy.spatial.distance import pdist

    t0 = time.perf_counter()
    data = problem.data
    q = np.asarray(data.q, dtype=np.float64)
    m = len(q)
    r0 = problem.robot.residuals(data.measurement, q, data.y, params=problem.start)
    # No more centres than distinct poses: k-means++ cannot place two centres on one point.
    distinct = len(np.unique(q, axis=0))
    k = min(distinct, as_count(n_centers, "n_centers") if n_centers is not None else max(1, min(50, m // 4)))
    ridge = as_tolerance(ridge, "ridge")
    centers, _ = kmeans2(q, k, minit="++", seed=seeded_rng(seed))
    distances = pdist(centers)
    width = float(np.median(distances)) if distances.size and np.median(distances) > 0 else 1.0
    phi = _features(q, centers, width)
    weights = np.linalg.solve(phi.T @ phi + ridge * m * np.eye(phi.shape[1]), phi.T @ r0)
    r = (r0 - phi @ weights).ravel()
    cost0, cost = 0.5 * float(np.sum(r0 * r0)), 0.5 * float(r @ r)
    message = f"RBF corrector on the nominal model ({k} Gaussian centres, closed-form ridge fit); kinematic parameters not identified"
    return RBFResult(
        method=method,
        problem=problem,
        x=problem.x0,
        std=None,
        cost=cost,
        history=[cost0, cost],
        nit=1,
        nfev=1,
        success=True,
        message=message,
        time_s=time.perf_counter() - t0,
        metrics={"train": metrics(r, data.measurement), "test": None},
        centers=centers,
        width=width,
        weights=weights,
        ridge=ridge,
    )


#: method name -> (paper label, description, function(problem, **options) -> CalibrationResult)
METHODS = {"rbf": ("M5", "RBF network on the nominal model's residual", rbf)}
