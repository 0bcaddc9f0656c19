"""What a calibration result says about the robot, applied to joint readings.

A result file holds the calibrated parameters, the reading conventions of the joints
(``structure``) and the causes fitted with them (``causes``: coefficients and their basis). Every
product that evaluates a result on measurements — ``verify`` on a new session, ``report`` on the
file it was calibrated on — must evaluate the same model, or its figures and its metrics disagree.
:func:`result_model` is that model: the readings in the model's convention and the joint angles
the links take under the result's joint causes. The terms of the calibration's own session (a
step of its sensor's zero, its drift, its outliers) are named, not applied: they are not the
robot's.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Optional

import numpy as np

from ..calibration.sessions import SESSION_KINDS
from ..data.dataset import Dataset
from ..serial_robot import Robot
from . import structure
from .candidates import JOINT_KINDS, acquisition_order, joint_offsets, map_coverage_mask, map_coverage_report, result_maps


@dataclass(frozen=True)
class ResultModel:
    """A result's model of the robot on some measurements (:func:`result_model`)."""

    #: The measurements with the joint readings in the model's convention (``structure`` applied).
    read: Dataset
    #: ``read`` with the joint causes' ``Δq`` added: the angles the links take.
    links: Dataset
    #: The result file's joint causes (entries of its ``causes``), applied.
    carried: list
    #: ``{label, reason}`` of the result's causes not applied.
    not_applied: list
    #: Labels of the reading conventions applied.
    structure: list
    #: Labels of the causes of the calibration's own session among ``not_applied``.
    session_terms: list
    #: The nominal robot the calibration started from.
    nominal: Robot

    @property
    def applied(self) -> dict:
        """``structure`` and ``causes``: the labels of what the model applies."""
        return {"structure": list(self.structure), "causes": [c.get("label", c["kind"]) for c in self.carried]}

    @property
    def covered(self) -> np.ndarray:
        """(m,) bool: the samples every joint map of the result covers (all without maps)."""
        return map_coverage_mask(result_maps(self.carried), self.read.q)

    def coverage(self) -> list[dict]:
        """Per joint map: the samples beyond its fitted range (:func:`map_coverage_report`)."""
        return map_coverage_report(self.carried, self.read.q, self.read.rows)

    def residuals(self, robot: Robot, params: Optional[np.ndarray] = None) -> np.ndarray:
        """``y − h`` (m, k) of ``robot`` (at ``params``, default its own) at the angles the links take."""
        return robot.residuals(self.links.measurement, self.links.q, self.links.y, params=params)


def _with_joint_causes(robot: Robot, data: Dataset, causes: list[dict]) -> Dataset:
    """``data`` with the joint angles the links take: readings plus the causes' ``Δq``
    (evaluated in acquisition order, which backlash needs) on the bases of ``robot``."""
    offsets = joint_offsets(robot, causes, kinds=JOINT_KINDS)
    if offsets is None:
        return data
    order = acquisition_order(data)
    q = data.q.copy()
    q[order] += offsets(data.q[order])
    return replace(data, q=q)


def result_model(robot: Robot, doc: dict, data: Dataset) -> ResultModel:
    """The model of the result ``doc`` (its calibrated ``robot``, :func:`robocal.results.load_result`)
    on the measurements ``data``: reading conventions and joint causes applied, the other causes
    named with the reason they are not.

    Raises
    ------
    InvalidParameterError
        A reading convention or a joint cause of ``doc`` is malformed (naming it).
    """
    conventions = structure.parse_all(doc.get("structure", []), robot.n_joints)
    read = structure.apply_all(data, conventions)
    causes = doc.get("causes", [])
    carried = [c for c in causes if c.get("kind") in JOINT_KINDS]
    session_term = "a term of the calibration's own session (its sensor), not of the robot"
    robot_parameter = "a parameter of the robot: in the calibrated parameters"
    not_applied = [
        {"label": c.get("label", c.get("kind")), "reason": session_term if c.get("kind") in SESSION_KINDS else robot_parameter}
        for c in causes
        if c not in carried
    ]
    nominal = Robot(robot.name, robot.joints, doc["robot_model"]["nominal"], mass_model=robot.mass_model)  # checked by load_result
    # The causes' bases as the fit built them, on the nominal robot: a compliance's coefficient
    # was fitted against the gravity torques of the nominal geometry (the calibrated one moves
    # them by about 1e-3 relative, and the held-out error by as much).
    links = _with_joint_causes(nominal, read, carried)
    session = [c.get("label", c.get("kind")) for c in causes if c.get("kind") in SESSION_KINDS]
    return ResultModel(read, links, carried, not_applied, list(doc.get("structure", [])), session, nominal)
