"""What the covariance of a diagnosis' final fit says about its causes, for the report: a joint
map's curve with its band, and how well the data split neighbouring joints' compliances.

One covariance per fit serves both: on UR10 series A it is that of ~850 parameters on 36 000
residual rows."""

from __future__ import annotations

import numpy as np

from ..causes.candidates import PHYSICAL_KINDS, free_mass_compliance, map_curve, on_free_masses
from ..kernels import covariance


def uncertainty_entries(problem, x: np.ndarray, causes) -> dict:
    """Report entries of ``causes`` fitted at ``x`` of ``problem`` (one session's
    :class:`~robocal.causes.problem.ExtendedProblem` or the sessions stacked), keyed by cause label:

    - a joint map's ``curve``: its angles, values and standard deviation (deg; the roughness
      prior included). Its coefficients are the entries named ``"<label> c<i>"``.
    - with two or more gravity compliances, each one's ``correlation`` with every other
      (``{label: r}``). Neighbouring joints carry much of the same gravity torque, so the split
      between their stiffnesses can be weakly determined whatever each one's standard deviation
      says (UR10 joints 2 and 3, one series against three: docs/findings.md, D3).
    - a compliance on free masses: its ``params`` with their standard deviations (the compliance,
      the stiffness and the base parameters all come from several coefficients:
      :func:`~robocal.causes.candidates.free_mass_compliance`).
    """
    maps = [c for c in causes if c.kind == "joint_map"]
    compliances = [c for c in causes if c.kind in PHYSICAL_KINDS]
    free = [c for c in compliances if on_free_masses(c)]
    if not maps and len(compliances) < 2 and not free:
        return {}
    cov, *_ = covariance(problem.jacobian(x), problem.residuals(x))
    names = list(problem.names)
    out: dict = {}
    for c in maps:
        at = [i for i, n in enumerate(names) if n.startswith(c.label + " c")]
        curve = map_curve(c.detail, np.asarray(x)[at], cov[np.ix_(at, at)])
        out[c.label] = {"curve": {k: [float(v) for v in values] for k, values in curve.items()}}
    for c in free:
        at = [i for i, n in enumerate(names) if n.startswith(c.label + " c")]
        out[c.label] = {"params": free_mass_compliance(problem.robot, c.joint, np.asarray(x)[at], cov[np.ix_(at, at)])[0]}
    if len(compliances) > 1:
        at = [names.index(f"{c.label} c0") for c in compliances]
        sd = np.sqrt(np.diag(cov)[at])
        if np.all(sd > 0):
            block = cov[np.ix_(at, at)]
            r = (block + block.T) / 2.0 / np.outer(sd, sd)  # symmetric to the last bit, as a correlation is
            for i, c in enumerate(compliances):
                out.setdefault(c.label, {})["correlation"] = {o.label: float(r[i, j]) for j, o in enumerate(compliances) if j != i}
    return out
