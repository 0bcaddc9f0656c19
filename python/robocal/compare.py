"""The paper's comparison of calibrators (Section IV-B): every method on the same splits.

:func:`compare` runs each method of :data:`robocal.calibration.api.METHODS` on each train/test
split of one dataset and collects, per run, the held-out and training metrics of eq. (28), the
iterations, the fit time, the cost history, the identified DH deviations and the per-sample
held-out errors. A method that fails on a split is recorded with its message; the comparison
goes on. :meth:`ComparisonResult.write` turns the runs into the paper's tables and figures:

- Table VIII: RMSE / MAE / MAX on the held-out samples per method (mean ± std over the splits).
  The paper calls the mean per-sample error "STD"; by its formula it is the MAE.
- Table IX: iterations and fit time per method.
- Tables X and XI: Wilcoxon signed-rank tests (:func:`scipy.stats.wilcoxon`) of M9 against every
  other method, paired over the splits, on RMSE / MAE / MAX and on the fit time. The paper pairs
  over datasets and metrics instead; here a single dataset is compared, split by split.
- Tables XII and XIII: identified deviations Δα, Δa, Δd, Δθ of every joint, of M9 and of every
  method (mean over the splits).
- Fig. 5 (metric bars), Fig. 6 (cost history per iteration), Fig. 7 (per-sample held-out errors
  of the first split), as PNG files; and ``comparison.json`` with everything.

Every table is written as Markdown and as CSV from the same rows, which ``comparison.json``
holds as well.
"""

from __future__ import annotations

import csv
import io
import logging
import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Union

import numpy as np
from scipy.stats import rankdata, wilcoxon

from .calibration.api import METHODS, held_out_residuals, load_inputs, method_choices
from .calibration.metrics import metrics, sample_errors
from .calibration.problem import Problem, kinematic_prior_sigmas
from .calibration.rbf import RBFResult
from .data.dataset import Dataset
from .data.splits import chronological, configuration_groups, kfold, paper_split, random_split
from .kernels import as_count, check_seed, seeded_rng
from .exceptions import InvalidParameterError
from .outputs import make_folder, save_figure, write_json, write_text
from .progress import progress
from .serial_robot import Robot

logger = logging.getLogger(__name__)

PROTOCOLS = ("paper", "kfold", "80-20", "chronological")

#: The method the paper's Wilcoxon tests compare every other method against.
REFERENCE = "ukf-vslm"

#: The smallest number of pairs for which the exact two-sided Wilcoxon p-value can fall below
#: 0.05 (with 5 pairs its minimum is 2 / 2⁵ = 0.0625).
MIN_PAIRS = 6

#: Paired values closer than this (relative) are equal: the same optimum up to round-off.
TIE_TOLERANCE = 1e-9

#: DH parameter prefix -> (symbol, display unit) for Tables XII and XIII.
DH_PARAMETERS = {"alpha": ("Δα", "deg"), "a": ("Δa", "mm"), "d": ("Δd", "mm"), "theta": ("Δθ", "deg")}

METRICS = ("rmse", "mae", "max")
METRIC_HEADERS = {"rmse": "RMSE (mm)", "mae": "MAE (mm)", "max": "MAX (mm)"}


def default_methods() -> list[str]:
    """M1–M9 in label order, then robocal's own ``lm``."""
    labelled = sorted((label, name) for name, (label, _, _) in METHODS.items() if label != "-")
    return [name for _, name in labelled] + ["lm"]


def method_label(name: str) -> str:
    """``"M1 EKF"`` ... ``"M9 UKF-VSLM"``, ``"M6 LM"`` for ``lm-paper``, ``"robocal LM"`` for ``lm``."""
    label = METHODS[name][0] if name in METHODS else "-"
    short = {"lm-paper": "LM"}.get(name, name.upper())
    return f"robocal {short}" if label == "-" else f"{label} {short}"


def make_splits(dataset: Dataset, protocol: str, repeats: int, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """The train/test index pairs of a protocol (positions into ``dataset``).

    ``paper``: :func:`~robocal.data.paper_split` (120 random samples → 100 / 20) with seeds
    ``seed, seed + 1, ...``; ``80-20``: :func:`~robocal.data.random_split` likewise; ``kfold``:
    ``repeats`` folds of one permutation (:func:`~robocal.data.kfold`); ``chronological``: one
    split, the last 20 % of the acquisition order held out (``repeats`` does not apply). Every
    protocol keeps each joint configuration on one side (:func:`~robocal.data.configuration_groups`).
    """
    m = len(dataset)
    groups = configuration_groups(dataset.q)  # a repeated configuration is never on both sides
    if protocol == "paper":
        return [paper_split(m, seed=seed + k, groups=groups) for k in range(repeats)]
    if protocol == "80-20":
        return [random_split(m, test_fraction=0.2, seed=seed + k, groups=groups) for k in range(repeats)]
    if protocol == "kfold":
        return kfold(m, k=repeats, seed=seed, groups=groups)
    if protocol == "chronological":
        return [chronological(m, test_fraction=0.2, t=dataset.t, groups=groups)]
    raise InvalidParameterError(f"unknown protocol {protocol!r}; choose one of {PROTOCOLS}")


# -- running -------------------------------------------------------------------------------------
def _dh_names(robot: Robot) -> list[tuple[str, str]]:
    """``(name, display unit)`` of every DH parameter, joint by joint."""
    return [(f"{prefix}{joint}", unit) for joint in range(1, robot.n_joints + 1) for prefix, (_, unit) in DH_PARAMETERS.items()]


def _dh_deviations(result) -> dict:
    """``value − nominal`` of every DH parameter (deg for angles, mm for lengths)."""
    deviation = {p["name"]: p["value"] - p["nominal"] for p in result.parameters()}
    return {name: math.degrees(deviation[name]) if unit == "deg" else deviation[name] for name, unit in _dh_names(result.problem.robot)}


def _run(problem: Problem, test: Dataset, method: str, options: dict) -> dict:
    """One method on one split: the run record (``status`` ``"ok"`` or ``"failed"``)."""
    try:
        result = METHODS[method][2](problem, **options)
        residuals = held_out_residuals(result, test)
    except Exception as exc:  # one method failing on one split must not end the comparison
        return {"status": "failed", "error": f"{type(exc).__name__}: {exc}"}
    estimated = set(problem.names)
    return {
        "status": "ok",
        "error": None,
        "success": bool(result.success),
        "message": result.message,
        "nit": int(result.nit),
        "nfev": int(result.nfev),
        "time_s": float(result.time_s),
        "history": [float(c) for c in result.history],
        "train": result.metrics["train"],
        "test": metrics(residuals, test.measurement),
        "test_errors": sample_errors(residuals, test.measurement).tolist(),
        # A corrector (M5) keeps the start parameters: it identifies none.
        "identifies_parameters": not isinstance(result, RBFResult),
        "dh_deviations": _dh_deviations(result),
        "dh_estimated": [name for name, _ in _dh_names(problem.robot) if name in estimated],
        "implausible": [] if isinstance(result, RBFResult) else [flag["name"] for flag in result.implausible()],
    }


def compare(
    data: Union[str, Path, Dataset],
    robot: Union[str, Robot, None] = None,
    measurement: Optional[str] = None,
    methods: Optional[list[str]] = None,
    protocol: str = "paper",
    repeats: int = 5,
    seed: int = 0,
    subset: Optional[int] = None,
    method_options: Optional[dict] = None,
    kinematic_prior=None,
    angle_unit: Optional[str] = None,
) -> "ComparisonResult":
    """Runs every method on every split of ``data`` (the same splits for all methods).

    Parameters
    ----------
    data : path or Dataset
        A measurement file (see :func:`robocal.data.load`) or a :class:`Dataset`.
    robot : str or Robot, optional
        Default: the robot recorded in the data.
    measurement : {"cable", "position", "pose"}, optional
    methods : str or list of str, optional
        Names in :data:`~robocal.calibration.api.METHODS`; default :func:`default_methods`.
    protocol : {"paper", "kfold", "80-20", "chronological"}
        See :func:`make_splits`.
    repeats : int
        Splits (``paper``, ``80-20``) or folds (``kfold``).
    seed : int
        Seeds the subset and the random splits.
    subset : int, optional
        First draw this many samples at random (``numpy.random.default_rng(seed)``), kept in
        acquisition order, then split them (e.g. 200 samples of UR10 Series A, as the paper did).
    method_options : dict, optional
        ``method name -> {option: value}``, passed to that method on every split.
    kinematic_prior : (float, float), optional
        ``(mm, deg)`` prior at nominal on the kinematic parameters, for every method (see
        :meth:`~robocal.calibration.Problem.build`).
    angle_unit : {"deg", "rad"}, optional
        Unit of the joint columns of a canonical file (see :func:`robocal.data.load`).

    Returns
    -------
    ComparisonResult
    """
    methods = [methods] if isinstance(methods, str) else methods  # one name, not its letters
    methods = list(dict.fromkeys(methods)) if methods is not None else default_methods()
    unknown = [m for m in methods if m not in METHODS]
    if unknown or not methods:
        raise InvalidParameterError(f"{f'unknown methods {unknown}' if unknown else 'no method given'}; choose from {method_choices()}")
    if protocol not in PROTOCOLS:
        raise InvalidParameterError(f"unknown protocol {protocol!r}; choose one of {PROTOCOLS}")
    repeats = as_count(repeats, "repeats")
    check_seed(seed)
    if kinematic_prior is not None:  # up front: in each split's set-up, it made every run a failure
        kinematic_prior_sigmas(kinematic_prior)
    method_options = dict(method_options or {})
    if unknown := [m for m in method_options if m not in METHODS]:
        raise InvalidParameterError(f"`method_options` names unknown methods {unknown}; choose from {method_choices()}")
    dataset, robot_model = load_inputs(data, robot, measurement, angle_unit)
    notes = list(dataset.notes)  # the reader's: angles kept in an implausible unit as asked, the sheet read ...
    if subset is not None:
        if isinstance(subset, bool) or not isinstance(subset, (int, np.integer)) or not 2 <= subset <= len(dataset):
            raise InvalidParameterError(f"`subset` must lie in [2, {len(dataset)}]; got {subset}")
        dataset = dataset.subset(np.sort(seeded_rng(seed).choice(len(dataset), size=subset, replace=False)))
        notes.append(f"a random subset of {subset} samples (seed {seed}) was drawn before splitting")
    if protocol == "chronological" and repeats > 1:
        notes.append(f"the chronological split is deterministic: one split, not {repeats}")
    splits, runs = [], []
    for k, (train_idx, test_idx) in enumerate(progress(make_splits(dataset, protocol, repeats, seed), desc="compare: splits", unit="split")):
        train, test = dataset.subset(train_idx), dataset.subset(test_idx)
        split = {"index": k, "train": train_idx.tolist(), "test": test_idx.tolist(), "test_rows": test.rows.tolist()}
        try:  # the start point and free set, shared by all methods on this split
            problem = Problem.build(robot_model, train, kinematic_prior=kinematic_prior)
            problem.require_dof()  # as calibrate: a split without more residuals than parameters is fitted exactly, learns nothing
            before = problem.with_data(test).data_residuals(problem.x0)
            split.update(
                error=None,
                free=problem.names,
                fixed=problem.fixed,
                before=metrics(before, test.measurement),
                before_errors=sample_errors(before, test.measurement).tolist(),
            )
        except Exception as exc:  # recorded for every method of this split
            split.update(error=f"{type(exc).__name__}: {exc}", free=[], fixed={}, before=None, before_errors=[])
        splits.append(split)
        for method in methods:
            if split["error"] is None:
                record = _run(problem, test, method, method_options.get(method, {}))
            else:
                record = {"status": "failed", "error": f"problem set-up failed: {split['error']}"}
            logger.debug("compare: split %d, %s: %s", k, method, record.get("error") or record.get("status"))
            runs.append({"method": method, "split": k, "test_rows": split["test_rows"], **record})
    config = {
        "data": str(data) if not isinstance(data, Dataset) else (data.source or repr(data)),
        "robot": robot_model.name,
        "measurement": dataset.measurement,
        "samples": len(dataset),
        "protocol": protocol,
        "repeats": repeats,
        "seed": seed,
        "subset": subset,
        "kinematic_prior": list(kinematic_prior) if kinematic_prior is not None else None,
        "method_options": method_options,
        "notes": notes,
    }
    return ComparisonResult(config=config, methods=methods, splits=splits, runs=runs, n_joints=robot_model.n_joints)


# -- tables --------------------------------------------------------------------------------------
def _fmt(value) -> str:
    if value is None:
        return "—"
    if isinstance(value, (bool, str)):
        return str(value)
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    return f"{value:.4g}"


@dataclass
class Table:
    """A table of rows (dicts), rendered as Markdown and CSV.

    Attributes
    ----------
    name : str
        File stem (``table_VIII``).
    title : str
    columns : list of (header, key)
        ``key`` is a row key, or a pair ``(mean_key, std_key)`` shown as ``mean ± std`` in
        Markdown (the CSV has both keys as columns).
    rows : list of dict
    notes : list of str
    """

    name: str
    title: str
    columns: list
    rows: list
    notes: list = field(default_factory=list)

    def _keys(self) -> list[str]:
        return [k for _, key in self.columns for k in (key if isinstance(key, tuple) else (key,))]

    def _cell(self, row: dict, key) -> str:
        if not isinstance(key, tuple):
            return _fmt(row.get(key))
        mean, std = row.get(key[0]), row.get(key[1])
        return _fmt(mean) if mean is None or std is None else f"{_fmt(mean)} ± {_fmt(std)}"

    def markdown(self) -> str:
        lines = [f"## {self.title}", "", "| " + " | ".join(h for h, _ in self.columns) + " |", "|" + "---|" * len(self.columns)]
        lines += ["| " + " | ".join(self._cell(row, key) for _, key in self.columns) + " |" for row in self.rows]
        return "\n".join(lines + [""] + [f"- {note}" for note in self.notes]) + "\n"

    def csv(self) -> str:
        out = io.StringIO()
        writer = csv.DictWriter(out, fieldnames=self._keys(), extrasaction="ignore", lineterminator="\n")
        writer.writeheader()
        writer.writerows({k: ("" if row.get(k) is None else row.get(k)) for k in self._keys()} for row in self.rows)
        return out.getvalue()

    def to_dict(self) -> dict:
        return {"title": self.title, "columns": [[h, list(k) if isinstance(k, tuple) else k] for h, k in self.columns], "rows": self.rows, "notes": self.notes}


def _mean_std(values) -> tuple[Optional[float], Optional[float]]:
    """Mean and sample standard deviation (``None`` when undefined)."""
    values = np.asarray(values, dtype=np.float64)
    if values.size == 0:
        return None, None
    return float(np.mean(values)), (float(np.std(values, ddof=1)) if values.size > 1 else None)


def _failures(runs: list[dict]) -> str:
    messages = sorted({r["error"] for r in runs if r["status"] == "failed"})
    return "; ".join(messages)


def _quantity(run: dict, key: str) -> float:
    """``time_s`` of a run, or a held-out metric (``rmse``, ``mae``, ``max``)."""
    return run["time_s"] if key == "time_s" else run["test"][key]


def wilcoxon_row(reference: list, other: list) -> dict:
    """Paired Wilcoxon signed-rank test of ``reference`` against ``other`` (lower is better).

    Returns
    -------
    dict
        ``n`` (pairs with a nonzero difference), ``r_plus`` (rank sum where the reference is
        better, as in the paper), ``r_minus``, ``statistic`` and ``p_value`` of
        :func:`scipy.stats.wilcoxon` (two-sided), ``better`` (``"reference"``, ``"other"`` or
        ``"tie"`` by the rank sums) and a ``note``. Differences within :data:`TIE_TOLERANCE`
        (relative) count as zero and, as in scipy's default ``zero_method="wilcox"``, are dropped.
    """
    reference, other = np.asarray(reference, dtype=np.float64), np.asarray(other, dtype=np.float64)
    d = other - reference
    d[np.abs(d) <= TIE_TOLERANCE * (np.abs(reference) + np.abs(other))] = 0.0  # equal up to round-off
    nonzero = d[d != 0]
    row = {"pairs": int(d.size), "n": int(nonzero.size), "r_plus": None, "r_minus": None, "statistic": None, "p_value": None, "better": None, "note": ""}
    if nonzero.size == 0:
        row["note"] = "no paired runs" if d.size == 0 else "all paired differences are zero"
        return row
    ranks = rankdata(np.abs(nonzero))
    row["r_plus"], row["r_minus"] = float(ranks[nonzero > 0].sum()), float(ranks[nonzero < 0].sum())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        test = wilcoxon(d)
    row["statistic"], row["p_value"] = float(test.statistic), float(test.pvalue)
    row["better"] = "reference" if row["r_plus"] > row["r_minus"] else "other" if row["r_minus"] > row["r_plus"] else "tie"
    if nonzero.size < MIN_PAIRS:
        row["note"] = f"too few pairs for a meaningful test (n={nonzero.size} < {MIN_PAIRS}: p cannot fall below 0.05)"
    return row


@dataclass
class ComparisonResult:
    """What :func:`compare` found: the configuration, the splits and one record per run.

    Attributes
    ----------
    config : dict
        Data, robot, measurement, protocol, repeats, seed, subset, method options, notes.
    methods : list of str
    splits : list of dict
        ``index``, ``train`` / ``test`` (positions in the possibly sub-sampled dataset),
        ``test_rows`` (rows in the source file), ``free`` / ``fixed`` parameters, ``before``
        (held-out metrics of the start: nominal kinematics with the fitted measurement set-up),
        ``before_errors``, ``error`` (if the problem could not be set up).
    runs : list of dict
        ``method``, ``split``, ``status`` (``"ok"`` | ``"failed"``), ``error``; for ``ok`` runs
        also ``success``, ``message``, ``nit``, ``nfev``, ``time_s``, ``history``, ``train`` and
        ``test`` metrics, ``test_errors`` (per held-out sample, in ``test_rows`` order),
        ``identifies_parameters``, ``dh_deviations`` (deg / mm) and ``dh_estimated``.
    n_joints : int
    """

    config: dict
    methods: list
    splits: list
    runs: list
    n_joints: int

    def runs_of(self, method: str, ok: bool = False) -> list[dict]:
        """The runs of ``method`` in split order (only the successful ones with ``ok``)."""
        return [r for r in self.runs if r["method"] == method and (r["status"] == "ok" or not ok)]

    def _protocol_note(self) -> str:
        c = self.config
        return f"{c['robot']}, {c['measurement']} data ({c['samples']} samples), protocol {c['protocol']}: {len(self.splits)} split(s), seed {c['seed']}"

    # The tables ---------------------------------------------------------------------------------
    def table_viii(self) -> Table:
        rows = []
        before = [s["before"] for s in self.splits if s["before"] is not None]
        entries = [("Before (start)", "before", before, len(self.splits), "")]
        for m in self.methods:
            runs = self.runs_of(m)
            entries.append((method_label(m), m, [r["test"] for r in runs if r["status"] == "ok"], len(runs), _failures(runs)))
        for label, name, tests, total, failures in entries:
            row = {"method": label, "name": name, "runs_ok": f"{len(tests)}/{total}", "failures": failures}
            for metric in METRICS:
                row[f"{metric}_mean"], row[f"{metric}_std"] = _mean_std([t[metric] for t in tests])
            if name != "before":
                row["train_rmse_mean"], _ = _mean_std([r["train"]["rmse"] for r in self.runs_of(name, ok=True)])
            rows.append(row)
        columns = [("Method", "method"), ("runs ok", "runs_ok")]
        columns += [(METRIC_HEADERS[m], (f"{m}_mean", f"{m}_std")) for m in METRICS]
        columns += [("train RMSE (mm)", "train_rmse_mean"), ("failures", "failures")]
        notes = [
            self._protocol_note(),
            'Held-out samples; mean ± sample std over the splits. MAE is the mean per-sample error, which the paper calls "STD" (eq. 28).',
            "Before (start): nominal kinematics with the measurement set-up (cable anchor and zero, or base frame and tool) fitted on the training samples.",
            "M5 RBF is a corrector of the nominal model, evaluated with its corrected prediction.",
        ] + self.config["notes"]
        return Table("table_VIII", "Table VIII: held-out accuracy per method", columns, rows, notes)

    def table_ix(self) -> Table:
        rows = []
        for m in self.methods:
            runs = self.runs_of(m, ok=True)
            row = {
                "method": method_label(m),
                "name": m,
                "runs_ok": f"{len(runs)}/{len(self.runs_of(m))}",
                "converged": f"{sum(r['success'] for r in runs)}/{len(runs)}",
                "total_time_s": float(sum(r["time_s"] for r in runs)) if runs else None,
            }
            row["nit_mean"], row["nit_std"] = _mean_std([r["nit"] for r in runs])
            row["time_mean_s"], row["time_std_s"] = _mean_std([r["time_s"] for r in runs])
            rows.append(row)
        columns = [
            ("Method", "method"),
            ("runs ok", "runs_ok"),
            ("success", "converged"),
            ("iterations", ("nit_mean", "nit_std")),
            ("time per run (s)", ("time_mean_s", "time_std_s")),
            ("total time (s)", "total_time_s"),
        ]
        notes = [
            self._protocol_note(),
            "Iterations are each method's own: sweeps (Kalman filters), generations (metaheuristics), steps (LM variants; "
            "M9 counts UKF sweeps plus VSLM steps), 1 for the closed-form RBF fit. They are not equal units of work.",
            "Time is the wall time of the fit alone (not loading, not the start-point fit), on this machine.",
            "success: runs whose method reported success (for metaheuristics: finished the budget or met the tolerance; not a proof of optimality).",
        ]
        return Table("table_IX", "Table IX: iterations and time per method", columns, rows, notes)

    def _wilcoxon(self, name: str, title: str, quantities: list[tuple[str, str]]) -> Table:
        rows = []
        if REFERENCE in self.methods:
            reference = {r["split"]: r for r in self.runs_of(REFERENCE, ok=True)}
            for m in self.methods:
                if m == REFERENCE:
                    continue
                pairs = [(reference[r["split"]], r) for r in self.runs_of(m, ok=True) if r["split"] in reference]
                for label, key in quantities:
                    row = wilcoxon_row([_quantity(a, key) for a, _ in pairs], [_quantity(b, key) for _, b in pairs])
                    better = {"reference": method_label(REFERENCE), "other": method_label(m), "tie": "tie", None: None}[row["better"]]
                    rows.append({"comparison": f"{method_label(REFERENCE)} vs. {method_label(m)}", "quantity": label, **row, "better": better})
        columns = [
            ("Comparison", "comparison"),
            ("quantity", "quantity"),
            ("pairs", "pairs"),
            ("n", "n"),
            ("R+", "r_plus"),
            ("R−", "r_minus"),
            ("statistic", "statistic"),
            ("p-value", "p_value"),
            ("better", "better"),
            ("note", "note"),
        ]
        notes = [
            self._protocol_note(),
            f"Two-sided scipy.stats.wilcoxon on the paired per-split values (other − {method_label(REFERENCE)}), splits where both methods ran; "
            "n counts the nonzero differences. R+ is the rank sum where M9 is better (lower), as in the paper; statistic = min(R+, R−).",
            f"With fewer than {MIN_PAIRS} pairs the exact two-sided p-value cannot fall below 0.05.",
            "The paper pairs over datasets and metrics; here one dataset is compared split by split.",
        ]
        if REFERENCE not in self.methods:
            notes.insert(0, f"{method_label(REFERENCE)} was not among the compared methods: no tests.")
        return Table(name, title, columns, rows, notes)

    def table_x(self) -> Table:
        quantities = [(METRIC_HEADERS[m].split()[0], m) for m in METRICS]
        return self._wilcoxon("table_X", "Table X: Wilcoxon signed-rank tests of M9 on held-out RMSE / MAE / MAX", quantities)

    def table_xi(self) -> Table:
        return self._wilcoxon("table_XI", "Table XI: Wilcoxon signed-rank tests of M9 on fit time", [("time (s)", "time_s")])

    def _mean_deviations(self, method: str) -> dict:
        """``name -> mean deviation`` over the successful runs, or ``"fixed"`` if never estimated."""
        runs = self.runs_of(method, ok=True)
        out = {}
        for name in runs[0]["dh_deviations"]:
            estimated = any(name in r["dh_estimated"] for r in runs)
            out[name] = float(np.mean([r["dh_deviations"][name] for r in runs])) if estimated else "fixed"
        return out

    def table_xii(self) -> Table:
        columns = [("Joint i", "joint")] + [(f"{sym}i ({unit})", prefix) for prefix, (sym, unit) in DH_PARAMETERS.items()]
        notes = [self._protocol_note(), 'Identified value − nominal, mean over the splits; "fixed": not estimated (not identifiable, or outside the mask).']
        rows = []
        if self.runs_of(REFERENCE, ok=True):
            deviations = self._mean_deviations(REFERENCE)
            rows = [{"joint": j, **{p: deviations[f"{p}{j}"] for p in DH_PARAMETERS}} for j in range(1, self.n_joints + 1)]
        else:
            notes.insert(0, f"{method_label(REFERENCE)} has no successful run: nothing identified.")
        return Table("table_XII", f"Table XII: DH deviations identified by {method_label(REFERENCE)}", columns, rows, notes)

    def table_xiii(self) -> Table:
        shown, notes = [], [self._protocol_note(), 'Identified value − nominal, mean over the splits; "fixed": not estimated.']
        for m in self.methods:
            runs = self.runs_of(m, ok=True)
            if not runs:
                notes.append(f"{method_label(m)}: no successful run.")
            elif not runs[0]["identifies_parameters"]:
                notes.append(f"{method_label(m)}: a corrector of the nominal model; it identifies no parameters.")
            else:
                shown.append(m)
        deviations = {m: self._mean_deviations(m) for m in shown}
        rows = []
        for j in range(1, self.n_joints + 1):
            for prefix, (sym, unit) in DH_PARAMETERS.items():
                rows.append({"parameter": f"{sym}{j} ({unit})", **{m: deviations[m][f"{prefix}{j}"] for m in shown}})
        columns = [("Parameter", "parameter")] + [(method_label(m), m) for m in shown]
        return Table("table_XIII", "Table XIII: DH deviations identified by every method", columns, rows, notes)

    def tables(self) -> list[Table]:
        return [self.table_viii(), self.table_ix(), self.table_x(), self.table_xi(), self.table_xii(), self.table_xiii()]

    # Output -------------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """Everything: ``config``, ``methods`` (name, label, description), ``splits``, ``runs`` and ``tables``."""
        return _jsonable(
            {
                "config": self.config,
                "methods": [{"name": m, "label": method_label(m), "description": METHODS[m][1]} for m in self.methods],
                "splits": self.splits,
                "runs": self.runs,
                "tables": {t.name: t.to_dict() for t in self.tables()},
            }
        )

    def write(self, out: Union[str, Path]) -> list[Path]:
        """Writes ``table_*.md`` / ``table_*.csv``, ``tables.md`` (all tables), the figures
        ``fig5_metrics.png``, ``fig6_convergence.png``, ``fig7_errors.png`` and
        ``comparison.json`` into ``out`` (created). Returns the paths."""
        out = make_folder(out)
        written = []
        tables = self.tables()
        for table in tables:
            for suffix, text in ((".md", table.markdown()), (".csv", table.csv())):
                written.append(out / f"{table.name}{suffix}")
                write_text(written[-1], text)
        written.append(out / "tables.md")
        write_text(written[-1], f"# Comparison of calibrators\n\n{self._protocol_note()}\n\n" + "\n".join(t.markdown() for t in tables))
        written += _figures(self, out)
        written.append(out / "comparison.json")
        write_json(written[-1], self.to_dict(), indent=1, default=repr)  # repr: options that are not JSON
        return written


def _jsonable(obj):
    """Plain JSON types; non-finite floats become ``null``."""
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return float(obj) if math.isfinite(obj) else None
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    return obj


# -- figures -------------------------------------------------------------------------------------
def _log_if_wide(ax, values, axis: str = "y") -> None:
    """Log scale when positive values span more than two decades (e.g. a diverged method)."""
    v = np.asarray([x for x in values if x is not None and np.isfinite(x) and x > 0])
    if v.size and v.max() > 100 * v.min():
        (ax.set_yscale if axis == "y" else ax.set_xscale)("log")


def _figures(result: ComparisonResult, out: Path) -> list[Path]:
    """Figs. 5–7 as PNG (matplotlib's object API: the Agg canvas, no global backend change)."""
    from matplotlib import colormaps
    from matplotlib.figure import Figure

    palette = colormaps["tab20"].colors
    color = {m: palette[(2 * i) % 20 + (2 * i) // 20 % 2] for i, m in enumerate(result.methods)}  # one colour per method
    paths = []
    rows = result.table_viii().rows
    fig = Figure(figsize=(max(8, 0.9 * len(rows) + 2), 4.5), layout="constrained")
    ax = fig.add_subplot()
    x, width = np.arange(len(rows)), 0.27
    for i, metric in enumerate(METRICS):
        means = [np.nan if r[f"{metric}_mean"] is None else r[f"{metric}_mean"] for r in rows]
        errs = [0.0 if r[f"{metric}_std"] is None else r[f"{metric}_std"] for r in rows]
        ax.bar(x + (i - 1) * width, means, width, yerr=errs, capsize=2, label=METRIC_HEADERS[metric].split()[0])
    for i, r in enumerate(rows):
        if r["rmse_mean"] is None:
            ax.annotate("failed", (i, 0), xytext=(0, 4), textcoords="offset points", ha="center", rotation=90, va="bottom")
    _log_if_wide(ax, [r[f"{m}_mean"] for r in rows for m in METRICS])
    ax.set_xticks(x, [r["method"] for r in rows], rotation=30, ha="right")
    ax.set_ylabel("held-out error (mm)")
    ax.set_title(f"Held-out RMSE / MAE / MAX, mean ± std over {len(result.splits)} split(s) (cf. paper Fig. 5)")
    ax.legend()
    paths.append(out / "fig5_metrics.png")
    save_figure(fig, paths[-1], dpi=110)

    fig = Figure(figsize=(8, 5), layout="constrained")
    ax = fig.add_subplot()
    for m in result.methods:
        runs = result.runs_of(m, ok=True)
        if runs:
            history = np.asarray(runs[0]["history"], dtype=np.float64)
            ax.plot(np.arange(len(history)), history, marker="." if len(history) < 30 else None, color=color[m], label=method_label(m))
    ax.set_yscale("log")
    ax.set_xscale("symlog", linthresh=10)
    ax.set_xlim(left=0)
    ax.set_xlabel("iteration (each method's own unit; symlog scale)")
    ax.set_ylabel("training cost ½‖r‖² (mm²)")
    ax.set_title("Cost history of the first successful split per method (cf. paper Fig. 6)")
    if ax.lines:
        ax.legend(fontsize="small")
    else:  # every run failed: a legend of nothing is what matplotlib warns about
        ax.text(0.5, 0.5, "no method succeeded on any split", transform=ax.transAxes, ha="center", va="center")
    paths.append(out / "fig6_convergence.png")
    save_figure(fig, paths[-1], dpi=110)

    fig = Figure(figsize=(9, 5), layout="constrained")
    ax = fig.add_subplot()
    first = result.splits[0]
    ax.plot(np.arange(1, len(first["before_errors"]) + 1), first["before_errors"], "k--", marker="o", markersize=3, label="Before (start)")
    errors = first["before_errors"]
    for r in result.runs:
        if r["split"] == 0 and r["status"] == "ok":
            ax.plot(
                np.arange(1, len(r["test_errors"]) + 1), r["test_errors"], marker="o", markersize=3, color=color[r["method"]], label=method_label(r["method"])
            )
            errors = errors + r["test_errors"]
    _log_if_wide(ax, errors)
    ax.set_xlabel(f"held-out sample of split 1 ({len(first['test'])} samples, in file-row order)")
    ax.set_ylabel("error (mm)")
    ax.set_title("Per-sample held-out errors (cf. paper Fig. 7)")
    ax.legend(fontsize="small", ncol=2)
    paths.append(out / "fig7_errors.png")
    save_figure(fig, paths[-1], dpi=110)
    return paths
