"""Planning a measurement (``robocal plan``): which joint configurations to measure, in which
order, so that the model's parameters are best determined (:func:`plan`, its :class:`Plan`).

One module per concept, each importing only those listed before it:

- ``constraints``: the cell — candidate poses drawn uniformly within the joint ranges and kept
  where the cell allows them (:class:`Constraints`, :func:`candidate_poses`);
- ``criteria``: the design criteria on the candidates' Jacobian rows — I-optimal (the default:
  the least mean variance of a new session's readings over the workspace) and D-optimal (the
  least volume of the parameters' confidence ellipsoid), by greedy selection with Woodbury
  updates and Fedorov exchange (:func:`i_optimal`, :func:`d_optimal`), Ds-optimal for a re-mastering (the joints'
  zeros with a new session's set-up eliminated, :func:`ds_optimal`), and the least any ``N``
  poses could reach (:func:`i_bound`);
- ``order``: the order of measuring — a short tour dealt into interleaved passes, so that a
  sensor drifting in time cannot pass for a joint cause (:func:`measuring_order`);
- ``design``: the model a calibration will fit, linearised on the candidates — the same Jacobian
  the fit uses, evaluated by the Rust core;
- ``prior``: what a calibration result already knows, the prior of a plan for a new session of a
  calibrated robot (``--from RESULT``);
- ``coverage``: a joint map's coverage — a pose every knot spacing along its joint's range
  (:func:`map_bins`);
- ``uncertainty``: what an information matrix determines — the figures the report states;
- ``planner``: :func:`plan`, which runs them in turn, and :class:`Plan`.

Units: mm and rad inside; degrees in the plan file and the report's angles.
"""

from __future__ import annotations

from .constraints import CANDIDATES, MAX_DRAW_FACTOR, NOT_CHECKED, TRACKER_RANGE, Constraints, candidate_poses
from .coverage import map_bins
from .criteria import (
    BOUND_ITERATIONS,
    CRITERIA,
    EXCHANGE_PASSES,
    RIDGE,
    SHORTLIST,
    d_optimal,
    ds_optimal,
    i_bound,
    i_criterion,
    i_optimal,
    workspace_weights,
)
from .criteria import _i_blocks as _i_blocks
from .criteria import _i_update as _i_update
from .design import WORKSPACE_POSES
from .order import default_passes, measuring_order, order_correlations, travel
from .planner import LARGE_BOUND_ITERATIONS, LARGE_MODEL, MAX_CANDIDATES, MAX_POSES, POSE_KINDS, SCHEMA, WORKING, Plan, plan
from .uncertainty import UNDETERMINED
from .uncertainty import _inverse_half as _inverse_half

# ``_i_blocks``, ``_i_update`` and ``_inverse_half`` are internal: handed on (``x as x``) for the tests that import
# them from here, as they did from the module, and left out of ``__all__``.
__all__ = [
    # planner
    "plan",
    "Plan",
    "SCHEMA",
    "MAX_POSES",
    "MAX_CANDIDATES",
    "LARGE_MODEL",
    "WORKING",
    "LARGE_BOUND_ITERATIONS",
    "POSE_KINDS",
    # constraints
    "Constraints",
    "candidate_poses",
    "CANDIDATES",
    "MAX_DRAW_FACTOR",
    "TRACKER_RANGE",
    "NOT_CHECKED",
    # criteria
    "d_optimal",
    "ds_optimal",
    "i_optimal",
    "i_criterion",
    "i_bound",
    "workspace_weights",
    "CRITERIA",
    "RIDGE",
    "EXCHANGE_PASSES",
    "SHORTLIST",
    "BOUND_ITERATIONS",
    # order
    "measuring_order",
    "default_passes",
    "order_correlations",
    "travel",
    # design, coverage, uncertainty
    "WORKSPACE_POSES",
    "map_bins",
    "UNDETERMINED",
]
