"""The search for the reading conventions (:mod:`robocal.causes.structure`) a data set was read in.

Conventions are not small, so each hypothesis is judged by full nonlinear re-fits, never by a
linearisation: a screening fit of every hypothesis on a subsample (capped), then the most
promising on all samples, then cross-validation. A hypothesis is accepted when it makes the
geometric fit plausible (no parameter beyond the limits) at an equal or better held-out error,
or lowers the held-out error by :data:`REAL_GAIN` with fewer implausible parameters; hypotheses
the data cannot tell apart are reported together, as undetermined. Single-joint hypotheses are
every quarter-turn zero offset and sign of a moving joint and the references of coupled joints
(:func:`coupled`); a re-mastered joint's zero is proposed where a geometric fit moves
``theta_j`` beyond the limits (:func:`zero_errors`). Two conventions wrong at once, neither of
which helps alone, are found by :func:`screen_combinations`: every quarter-turn offset and sign
on one or two joints, judged by the nominal geometry with only the set-up fitted.
:func:`reading_conventions` is the diagnosis' structural stage: the search run where the geometric
fit of the data as read is implausible.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from ..calibration.lm import levenberg_marquardt
from ..calibration.problem import Problem
from ..causes.candidates import acquisition_order
from ..causes.problem import ExtendedProblem, reported_rmse
from ..causes.structure import Structure, apply_all, within_limits
from ..data.dataset import Dataset
from ..exceptions import DataError
from ..physics import DEG
from ..robot import Robot, setup_names
from ..threads import thread_map
from .validation import cross_validate, fold_schemes

#: Zero offsets tried on every moving joint (deg).
ZERO_OFFSETS = (90.0, 180.0, 270.0)
#: Samples of the screening fits, their evaluation budget and how many hypotheses go on to
#: full fits.
SCREEN_SAMPLES, SCREEN_NFEV, SHORTLIST = 400, 60, 4
#: Held-out errors within this fraction count as equal.
EQUAL = 0.01
#: A hypothesis that leaves the geometry implausible must lower the held-out error by this much;
#: and an implausible geometry must be this much better on the blocked (or group) folds to be
#: kept over a plausible one as good on the random folds: two fits of one geometry from other
#: starts differ by a few per cent on blocks of the session (an HSR's joint 5 read 270° off,
#: fitted as read and under the convention: 1.6 %).
REAL_GAIN = 0.10
#: Joints that move less than this (deg) are no source of a reference: reading relative to a
#: constant is a zero offset.
MOVING_DEG = 1.0


def coupled(j: int, s: int, n_joints: int) -> bool:
    """Joints whose readings a controller may report relative to each other: neighbours (the
    J2/J3 interaction of parallelogram arms) and any two of the wrist's last three (wrist axis
    coupling). Reading joint 4 relative to joint 1 is no convention in use."""
    wrist = n_joints - 3
    return abs(j - s) == 1 or (j >= wrist and s >= wrist and j != s)


def hypotheses(data: Dataset) -> list[Structure]:
    """Every single-joint hypothesis on the joints that move in ``data``."""
    moving = [j for j in range(data.n_joints) if np.ptp(data.q[:, j]) > MOVING_DEG * DEG]
    revolute = [j for j in moving if j not in data.prismatic]  # a zero offset is a quarter turn: no mm of a prismatic joint
    out = [Structure("joint_zero", j, z * DEG) for j in revolute for z in ZERO_OFFSETS]
    out += [Structure("joint_sign", j) for j in moving]
    out += [
        Structure("joint_reference", j, c, s)
        for j in moving
        for s in moving
        if coupled(j, s, data.n_joints) and (j in data.prismatic) == (s in data.prismatic)  # a reading of the same unit
        for c in (1.0, -1.0)
    ]
    return out


@dataclass
class Trial:
    """A hypothesis (or none) fitted: training RMSE, implausible parameters, held-out RMSE."""

    structures: list
    rmse: float
    implausible: int
    heldout: Optional[dict] = None


def zero_errors(implausible: list[dict]) -> list[Structure]:
    """Continuous zero errors (a joint re-mastered after a crash or a motor change): one
    ``joint_zero`` per ``theta`` offset a geometric fit moved beyond the plausibility limits
    (``implausible`` as :meth:`CalibrationResult.implausible` lists them), at the offset it
    found (rounded to 0.001°)."""
    zeros = [f for f in implausible if f["name"].startswith("theta")]
    return [Structure("joint_zero", int(f["name"][len("theta") :]) - 1, round(f["deviation"] / DEG, 3) * DEG) for f in zeros]


def combinations(data: Dataset) -> list[tuple]:
    """Every controller convention on one or two of the joints that move in ``data``: per joint
    a quarter-turn zero offset (0, 90, 180, 270°), read with its sign or reversed — the
    conventions a DH table's offsets and a controller's counting directions differ by. Two joints
    wrong at once is common (a DH table whose θ offsets the controller already includes on
    joints 2 and 3), and neither helps alone."""
    moving = [j for j in range(data.n_joints) if np.ptp(data.q[:, j]) > MOVING_DEG * DEG]

    def options(j: int) -> list[tuple]:
        out = []
        for sign in (False, True):
            for zero in (0.0,) + (ZERO_OFFSETS if j not in data.prismatic else ()):
                parts = ((Structure("joint_sign", j),) if sign else ()) + ((Structure("joint_zero", j, zero * DEG),) if zero else ())
                if parts:
                    out.append(parts)
        return out

    singles = {j: options(j) for j in moving}
    pairs = [a + b for i, j in enumerate(moving) for k in moving[i + 1 :] for a in singles[j] for b in singles[k]]
    return [h for j in moving for h in singles[j]] + pairs


#: Conventions on one or two joints kept from the set-up-only screening for the full checks.
COMBINED_SHORTLIST = 3
#: ... if their set-up-only fit is at most this fraction of the readings as read.
COMBINED_GAIN = 0.5


def screen_combinations(data: Dataset, setup_rmse: Callable, seed: int = 0) -> list[tuple]:
    """The :func:`combinations` under which the *nominal* geometry, with only the set-up fitted
    (``setup_rmse(dataset) -> RMSE``), explains the data far better than as read (at most
    :data:`COMBINED_GAIN` of its RMSE), best first, at most :data:`COMBINED_SHORTLIST`. A
    controller's convention leaves the robot's geometry nominal, so the right one shows before
    any kinematic parameter is fitted; set-up-only fits on a subsample are cheap enough to try
    all of them (about a thousand on six joints)."""
    rng = np.random.default_rng(seed)
    sub = data.subset(np.sort(rng.choice(len(data), min(COMBINED_SAMPLES, len(data)), replace=False)))
    as_read = setup_rmse(sub)
    scored = sorted(((setup_rmse(apply_all(sub, list(h))), sum(s.size() for s in h), h) for h in combinations(data)), key=lambda t: t[:2])
    return [h for rmse, _, h in scored[:COMBINED_SHORTLIST] if rmse <= COMBINED_GAIN * as_read]


#: Samples of the set-up-only screening fits.
COMBINED_SAMPLES = 120


def _labels(parts) -> str:
    return " + ".join(s.label for s in parts)


#: A convention the set-up-only fit explains no better than this fraction of its RMSE without
#: it is one the set-up absorbs.
ABSORBED = 0.01


def absorbed_by_setup(sample: Dataset, accepted: list[Structure], h: tuple, setup_rmse: Callable) -> tuple[tuple, list[Structure]]:
    """``h`` without the conventions the set-up absorbs — the nominal geometry with only the
    set-up fitted (``setup_rmse``) explains ``sample`` as well without them — and those. A zero
    offset of the last joint is a rotation of a free tool, one of the first a rotation of a free
    base: the data cannot show it, and a geometric fit that "gains" from it has only been
    restarted elsewhere (simulated cable files: a −2.0° zero of joint 6 named on a clean file)."""
    kept, absorbed = list(h), []
    with_all = setup_rmse(apply_all(sample, accepted + kept))
    for s in h:
        rest = [o for o in kept if o is not s]
        without = setup_rmse(apply_all(sample, accepted + rest))
        if abs(without - with_all) <= ABSORBED * max(without, with_all):
            kept, with_all = rest, without
            absorbed.append(s)
    return tuple(kept), absorbed


def search(
    data: Dataset,
    fit: Callable,
    cross_validate: Callable,
    baseline: Trial,
    seed: int = 0,
    extra: tuple = (),
    setup_rmse: Optional[Callable] = None,
) -> tuple[list[Structure], list[dict], list[dict]]:
    """Greedy search for the reading conventions that make the geometry plausible.

    ``fit(dataset, max_nfev) -> (rmse, n_implausible)`` fits the geometric model (infinite for
    a hypothesis under which the readings cannot be the robot's);
    ``cross_validate(dataset) -> {scheme: held-out RMSE}``. ``baseline`` is the fit of the data
    as read (its held-out RMSE is cross-validated when a hypothesis needs the comparison);
    ``extra`` hypotheses (:func:`zero_errors` of that fit) join the first round;
    ``setup_rmse(dataset) -> RMSE``, the nominal geometry with only the set-up fitted, refuses a
    convention the set-up absorbs (:func:`absorbed_by_setup`). Returns the accepted structures,
    their report entries and the rejected or undetermined alternatives.
    """
    accepted, effects, rejected = [], [], []
    current = baseline
    rng = np.random.default_rng(seed)
    screen = np.sort(rng.choice(len(data), min(SCREEN_SAMPLES, len(data)), replace=False))
    for _ in range(2):  # at most two changes of convention
        if current.implausible == 0:
            break
        now = apply_all(data, accepted)
        # a hypothesis is one or more conventions applied together (two joints wrong at once)
        candidates = [(s,) for s in hypotheses(now)] + ([] if accepted else [tuple(e) if isinstance(e, (list, tuple)) else (e,) for e in extra])
        sample = now.subset(screen)
        # each screening fit is a whole nonlinear fit: worth a thread
        screened = thread_map(lambda h: fit(apply_all(sample, list(h)), SCREEN_NFEV), candidates)
        scored = [(bad, rmse, h) for (rmse, bad), h in zip(screened, candidates)]
        scored.sort(key=lambda s: (s[0], s[1], sum(p.size() for p in s[2])))
        trials, tried = [], []  # the shortlist, each hypothesis once
        for _, _, h in scored[:SHORTLIST]:
            if setup_rmse is not None:
                h, absorbed = absorbed_by_setup(sample, accepted, h, setup_rmse)
                for a in absorbed:
                    if any(r["label"] == a.label for r in rejected):
                        continue  # absorbed in another hypothesis too: said once
                    rejected.append(
                        {
                            "kind": a.kind,
                            "joint": a.joint + 1,
                            "label": a.label,
                            "gain_mm": None,
                            "gains_mm": None,
                            "p_value": None,
                            "p_adjusted": None,
                            "params": a.params,
                            "reason": "not identifiable: the set-up absorbs it (the nominal geometry with only the set-up fitted explains the data as well without it)",
                        }
                    )
            if h and h not in tried:
                tried.append(h)
        # Cross-validation (the expensive part) only for what could pass: a plausible fit as
        # good as now, or a training error already lower by the gain asked of the held-out one.
        for h, (rmse, bad) in zip(tried, thread_map(lambda h: fit(apply_all(now, list(h)), None), tried)):
            if (bad == 0 and rmse <= (1.0 + EQUAL) * current.rmse) or (bad < current.implausible and rmse <= (1.0 - REAL_GAIN) * current.rmse):
                trials.append(Trial(accepted + list(h), rmse, bad))
        if trials and current.heldout is None:
            current.heldout = cross_validate(apply_all(data, accepted))
        for t in trials:
            t.heldout = cross_validate(apply_all(data, t.structures))
        good = [
            t
            for t in trials
            if (t.implausible == 0 and all(t.heldout[k] <= (1.0 + (EQUAL if k == "random" else REAL_GAIN)) * current.heldout[k] for k in current.heldout))
            or all(t.heldout[k] <= (1.0 - REAL_GAIN) * current.heldout[k] for k in current.heldout)
        ]
        if not good:
            for t in trials:
                first = t.structures[len(accepted)]
                implausible = f"{t.implausible} implausible parameters instead of {current.implausible}"
                heldout = f"held-out RMSE {t.heldout['random']:.4g} mm instead of {current.heldout['random']:.4g} mm"
                rejected.append(
                    {
                        "kind": first.kind,
                        "joint": first.joint + 1,
                        "label": _labels(t.structures[len(accepted) :]),
                        "gain_mm": current.heldout["random"] - t.heldout["random"],
                        "gains_mm": {k: current.heldout[k] - t.heldout[k] for k in current.heldout},
                        "p_value": None,
                        "p_adjusted": None,
                        "params": first.params,
                        "reason": f"{implausible} at {heldout}: neither plausible nor {REAL_GAIN:.0%} better",
                    }
                )
            break
        good.sort(key=lambda t: (t.implausible, t.heldout["random"], sum(p.size() for p in t.structures[len(accepted) :])))
        # Among hypotheses the data cannot tell apart, the fewest conventions: a zero offset of a
        # joint the set-up absorbs (the last one, before a free tool point) explains nothing.
        level = [t for t in good if t.implausible == good[0].implausible and t.heldout["random"] <= (1.0 + EQUAL) * good[0].heldout["random"]]
        best = min(
            level,
            key=lambda t: (
                len(t.structures),
                sum(not p.quarter_turn for p in t.structures),
                sum(p.size() for p in t.structures[len(accepted) :]),
                t.heldout["random"],
            ),
        )
        good = [best] + [t for t in good if t is not best]
        alike = [t for t in good[1:] if t.implausible == best.implausible and t.heldout["random"] <= (1.0 + EQUAL) * best.heldout["random"]]
        plausible_or_better = "a plausible geometry at an equal or better held-out error"
        for s in best.structures[len(accepted) :]:
            effects.append(
                {
                    "kind": s.kind,
                    "joint": s.joint + 1,
                    "label": s.label,
                    "params": s.params,
                    "rmse_heldout_before": current.heldout["random"],
                    "rmse_heldout_after": best.heldout["random"],
                    "significance": {
                        "test": f"nonlinear re-fits: {plausible_or_better}, or a held-out gain of {REAL_GAIN:.0%} (random and blocked folds)",
                        "implausible_before": current.implausible,
                        "implausible_after": best.implausible,
                        "rmse_heldout_blocked_before": current.heldout["blocked"],
                        "rmse_heldout_blocked_after": best.heldout["blocked"],
                        "undetermined_between": [_labels(t.structures[len(accepted) :]) for t in alike],
                        "together_with": [o.label for o in best.structures[len(accepted) :] if o is not s],
                    },
                }
            )
        accepted = list(best.structures)
        current = best
    return accepted, effects, rejected


def reading_conventions(robot: Robot, data: Dataset, mask: np.ndarray, folds: int, seed: int, groups) -> tuple[Dataset, list, list, Optional[tuple]]:
    """The joint-reading conventions (:mod:`robocal.causes.structure`) that make an implausible geometric fit
    plausible: the data with them applied, their report entries, the alternatives rejected and,
    if the search cross-validated it, the geometric model of the data returned as ``(fold
    schemes, held-out errors)`` over all its samples. Searched only when the geometric fit of the
    data as read is implausible."""

    def hypothesis_problem(d: Dataset, free) -> Optional[Problem]:
        """The problem of ``d`` (the data under a hypothesis), or None where its readings cannot
        be the robot's (the input check's DataError): a wrong hypothesis, not a wrong file."""
        try:
            return Problem.build(robot, d, mask=free)
        except DataError:
            return None

    def fit(d: Dataset, max_nfev=None):
        problem = hypothesis_problem(d, mask)
        if problem is None:
            return np.inf, np.inf
        result = levenberg_marquardt(problem, **({"max_nfev": max_nfev} if max_nfev else {}))
        return result.metrics["train"]["rmse"], len(result.implausible())

    order = acquisition_order(data)
    schemes = fold_schemes(data.q, folds, seed, order, groups)

    errors_of = {}  # each data set cross-validated (by its joint readings): its held-out errors

    def heldout(d: Dataset) -> dict:
        ext = ExtendedProblem(Problem.build(robot, d, mask=mask), [], d, np.arange(len(d)))
        errors = errors_of[d.q.tobytes()] = cross_validate(ext, schemes)[0]
        return {name: reported_rmse(err) for name, err in errors.items()}

    as_read = levenberg_marquardt(Problem.build(robot, data, mask=mask))  # the data as given: a DataError is the user's
    bad = as_read.implausible()
    if not bad:
        return data, [], [], None
    baseline = Trial([], as_read.metrics["train"]["rmse"], len(bad))
    setup = setup_names(robot, data.measurement) + (["tool_x", "tool_y", "tool_z"] if data.measurement == "cable" else [])

    def setup_rmse(d: Dataset) -> float:  # the nominal geometry, only the set-up fitted
        problem = hypothesis_problem(d, setup)
        return np.inf if problem is None else levenberg_marquardt(problem, max_nfev=SCREEN_NFEV // 2).metrics["train"]["rmse"]

    combined = screen_combinations(data, setup_rmse, seed)
    accepted, effects, rejected = search(
        data, fit, heldout, baseline, seed, extra=[z for z in zero_errors(bad) if z.joint not in data.prismatic] + combined, setup_rmse=setup_rmse
    )
    errors = errors_of.get(apply_all(data, accepted).q.tobytes())
    # Each offset the whole turns that keep the model's angles within the limits (as calibrate takes them): the
    # report's labels are what calibrate and plan read (a plan's readings drawn 360 deg off the controller's).
    named = {a.label: b for a, b in zip(accepted, within_limits(accepted, data.q, robot))}
    for effect in effects:
        if effect["label"] in named:
            effect["label"], effect["params"] = named[effect["label"]].label, named[effect["label"]].params
        together = effect.get("significance", {}).get("together_with")
        if together:
            effect["significance"]["together_with"] = [named[t].label if t in named else t for t in together]
    accepted = [named[a.label] for a in accepted]
    return apply_all(data, accepted), effects, rejected, None if errors is None else (schemes, errors)
