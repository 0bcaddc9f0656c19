"""The calibration report: one self-contained HTML page with figures, from a result file.

The page, the inputs it reads and their evaluation; the figures are in
:mod:`robocal.report.figures`, the words shared with the command line in :mod:`robocal.report.text`.

``robocal report RESULT --out DIR`` reads a result file (:mod:`robocal.results`, written by
``robocal calibrate --out``) and writes ``DIR/index.html`` with PNG figures beside it:

1. the per-sample error before calibration (nominal kinematics, measurement set-up and tool point
   refitted: :func:`~robocal.calibration.api.nominal_residuals`, the figure ``verify`` reports) and after it, as histograms and along
   the samples, held-out samples marked. "After" is the model ``verify`` evaluates
   (:func:`~robocal.causes.result_model.result_model`: the result's reading conventions and
   joint causes), so an extended result's figures include its causes; beside them the ISO 9283
   acceptance figures of the held-out samples (:mod:`robocal.acceptance`) with the accuracy of
   each target;
2. the estimated parameters' deviations from nominal with ±2 std error bars (mm, deg);
3. the solver's cost per iteration;
4. the singular values of the column-scaled identification Jacobian at the calibrated
   parameters, with its condition number;
5. with ``--diagnosis REPORT.json`` (``robocal diagnose --json``): the held-out RMSE as the
   diagnosed causes are added, and a table of the causes.

Figures 1 and 4 and the acceptance figures need the measurements: the file the result names (``dataset.source``) or
``--data FILE``. Without them the page says so and shows the rest. The page has no scripts and
loads nothing from elsewhere; the PNGs are referenced by relative path, so the folder can be
moved or archived as a whole.
"""

from __future__ import annotations

import html
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Union

import numpy as np

from .._robocal import __version__
from ..acceptance import iso9283, summary_rows
from ..calibration.api import load_inputs, nominal_residuals
from ..calibration.metrics import sample_errors
from ..calibration.problem import implausible_parameters
from ..calibration.result import describe_implausible, implausible_meaning, verdict
from ..causes import structure
from ..causes.result_model import ResultModel, result_model
from ..data.dataset import Dataset
from ..diagnosis.leftover import leftover_words
from ..diagnosis_file import DiagnosisReport, Quantity, load_diagnosis
from ..exceptions import InvalidParameterError, RobocalError
from ..outputs import make_folder, printable, write_text
from ..results import file_sha256, load_result, result_sessions, session_robot
from ..serial_robot import Robot
from .figures import (
    acceptance_figure,
    condition_number,
    convergence_figure,
    diagnosis_figure,
    estimated,
    identifiability_figure,
    map_figure,
    parameter_figure,
    residual_figures,
    rms,
)
from .text import SHOWN, alike_words, correlation_words, settling_words

logger = logging.getLogger(__name__)


def _esc(value) -> str:
    # Text from files (a robot's name, a path) may hold terminal controls: shown as escapes, as the
    # CLI prints them, so that neither a browser's page nor `cat index.html` acts on them.
    return html.escape(printable(value), quote=True)


def _num(value, digits: int = 4) -> str:
    if value is None:
        return "–"
    value = float(value)
    if not np.isfinite(value):
        return str(value)
    return f"{value:.{digits}g}"


def _fixed(value, decimals: int) -> str:
    return "–" if value is None else f"{float(value):.{decimals}f}"


@dataclass
class _Data:
    """The measurements a report evaluates on, or why there are none."""

    dataset: Optional[Dataset] = None
    path: Optional[str] = None
    notes: list = field(default_factory=list)
    same_file: bool = False
    session: int = 0  # of a multi-session result, the one (0-based) whose file it is


def _load_data(doc: dict, data, angle_unit: Optional[str] = None, robot: Optional[Robot] = None) -> _Data:
    """The measurements of the report: ``data`` when given, read and checked as ``verify`` reads
    them (:func:`~robocal.calibration.api.load_inputs`: data naming another built-in robot than
    ``robot``, the result's, are refused; another name is a note), else the file the result names."""
    recorded = _fitted(doc).get("source")
    if isinstance(data, Dataset):
        if data.measurement != doc["measurement"]:
            raise InvalidParameterError(f"`data` hold {data.measurement} measurements; the result is of {doc['measurement']} data")
        load_inputs(data, robot, doc["measurement"])
        return _Data(data, data.source, ["measurements passed as a Dataset", *data.notes], same_file=data.source is not None and data.source == recorded)
    if data is not None:
        # An explicit file must load: its errors are the caller's to see.
        dataset, _ = load_inputs(data, robot, doc["measurement"], angle_unit)
        session = _session_of(doc, data)
        same = session is not None or _same_file(_fitted(doc), data)
        return _Data(dataset, str(data), [f"measurements from {data} (given with --data)", *dataset.notes], same_file=same, session=session or 0)
    if _monitored(doc):
        return _Data(
            notes=[
                "the result was updated by robocal monitor (what changed in its stream applied): its values are the robot and set-up of that stream "
                "now, not those of the data calibrated on; the figures that need the data are left out (pass --data FILE)"
            ]
        )
    return _load_recorded(_fitted(doc), doc["measurement"], robot)


def _session_of(doc: dict, path) -> Optional[int]:
    """The session (0-based) of a multi-session result whose file ``path`` is, byte for byte; None
    for another file, or a result re-mastered or monitored since (its set-up is then another's)."""
    if doc.get("remaster") or _monitored(doc):
        return None
    digest = file_sha256(path)
    return next((s for s, fitted in enumerate(result_sessions(doc)) if fitted.get("sha256") == digest), None)


def _monitored(doc: dict) -> bool:
    """Whether ``robocal monitor --out`` applied a change to the result's values."""
    monitor = doc.get("monitor")
    return isinstance(monitor, dict) and bool(monitor.get("alarms"))


def _load_recorded(fitted: dict, measurement: str, robot: Optional[Robot], what: str = "the result") -> _Data:
    """The measurement file a result's provenance ``fitted`` (its ``dataset``, or one of its
    ``sessions``; ``what`` names it in the notes) records, when it is on this machine and is, byte
    for byte, the one recorded; else why it is not read."""
    from ..data import load

    recorded = fitted.get("source")
    if not recorded:
        return _Data(notes=[f"{what} names no measurement file: the figures that need the data are left out (pass --data FILE)"])
    recorded = str(recorded)
    if not Path(recorded).is_file():
        return _Data(
            path=recorded, notes=[f"the measurement file {recorded} is not on this machine: the figures that need the data are left out (pass --data FILE)"]
        )
    # A result file may come from someone else and name any local file: it is read only when it
    # is, byte for byte, the file the result was calibrated on, and its content is never shown.
    if not _same_file(fitted, recorded):
        return _Data(
            path=recorded,
            notes=[
                f"the file {recorded} named by {what} is not read: its sha256 does not match the one recorded "
                "in the result; the figures that need the data are left out (pass --data FILE)"
            ],
        )
    try:
        dataset = load(recorded, measurement=measurement, robot=robot)  # the robot says which columns are mm
    except RobocalError:
        return _Data(path=recorded, notes=[f"the measurement file {recorded} could not be read: the figures that need the data are left out"])
    return _Data(dataset, recorded, [], same_file=True)


def _calibrated_on(doc: dict) -> dict:
    """The provenance of the file the result was calibrated on: its ``dataset``, or for a fit on
    several sessions the first session."""
    sessions = doc.get("sessions")
    if isinstance(sessions, list) and sessions and isinstance(sessions[0], dict):
        return sessions[0]
    return doc.get("dataset") or {}


def _fitted(doc: dict) -> dict:
    """The provenance of the file the result's set-up belongs to (whose set-up ``parameters``
    state): the file calibrated on (:func:`_calibrated_on`), or for a re-mastered result the
    re-mastering's points, none of them held out."""
    remastered = doc.get("remaster")
    if isinstance(remastered, dict):
        return {"source": remastered.get("data"), "sha256": remastered.get("sha256"), "rows_held_out": []}
    return _calibrated_on(doc)


def _same_file(fitted: dict, path) -> bool:
    """Whether ``path`` is, byte for byte, the file of the provenance ``fitted`` (its SHA-256)."""
    recorded = fitted.get("sha256")
    return isinstance(recorded, str) and file_sha256(path) == recorded


def nominal_robot(robot: Robot, doc: dict) -> Robot:
    """The robot with the nominal parameters the calibration started from."""
    nominal = {p["name"]: float(p["nominal"]) for p in doc["parameters"]}
    return Robot(robot.name, robot.joints, np.array([nominal[n] for n in robot.param_names]), mass_model=robot.mass_model)


@dataclass
class _Evaluation:
    before: np.ndarray
    after: np.ndarray
    held_out: Optional[np.ndarray]
    singular: Optional[np.ndarray]
    n_cols: int
    #: The result's model on the data (the one ``verify`` evaluates) and its residuals (m, k).
    model: ResultModel
    residuals: np.ndarray


def _evaluate(robot: Robot, doc: dict, dataset: Dataset, same_file: bool, fitted: Optional[dict] = None) -> _Evaluation:
    """The nominal and the calibrated model's errors on ``dataset``: the calibrated one is the
    result's model as ``verify`` applies it (reading conventions, joint causes), at the
    calibrated set-up; the nominal one reads the joints in the same convention. ``fitted``: the
    provenance of the data (default the result's, :func:`_fitted`), whose held-out rows are marked."""
    fitted = _fitted(doc) if fitted is None else fitted
    meas = dataset.measurement
    model = result_model(robot, doc, dataset)
    before = sample_errors(nominal_residuals(model.nominal, model.read), meas)
    residuals = model.residuals(robot)
    after = sample_errors(residuals, meas)
    held_out = None
    if same_file:
        held_out = np.isin(dataset.rows, np.asarray(fitted.get("rows_held_out") or [], dtype=np.int64))
    names = set(robot.param_names)
    cols = [robot.index(n) for n in doc.get("free", []) if n in names]
    singular = None
    if cols:
        J = robot.jacobian(meas, model.links.q, y=model.links.y, cols=cols)
        norm = np.linalg.norm(J, axis=0)
        J = J / np.where(norm > 0, norm, 1.0)
        singular = np.linalg.svd(J, compute_uv=False)
    return _Evaluation(before, after, held_out, singular, len(cols), model, residuals)


def _acceptance(ev: _Evaluation) -> tuple[dict, str]:
    """The ISO 9283 figures of the calibrated model on the held-out samples (all samples when they
    are not known) and which samples they are, in words."""
    held = ev.held_out is not None and ev.held_out.any()
    mask = ev.held_out if held else np.ones(len(ev.after), dtype=bool)
    read = ev.model.read
    figures = iso9283(ev.residuals[mask], read.y[mask], read.q[mask], read.measurement, covered=ev.model.covered[mask], rows=read.rows[mask])
    which = (
        f"the {int(mask.sum())} held-out samples (the fit saw none of their joint configurations)"
        if held
        else f"all {len(mask)} samples at the calibrated set-up (the held-out samples are unknown; "
        "on new measurements `robocal verify` re-fits the set-up first)"
    )
    return figures, which


def _acceptance_section(ev: _Evaluation, out: Path, several: bool = False, session: int = 0) -> str:
    figures, which = _acceptance(ev)
    if several:  # each session has its own set-up: distances between targets of two sessions mean nothing
        which = f"session {session + 1}'s samples only (each session has its own set-up): {which}"
    rows = [[_esc(name), _esc(value)] for name, value in summary_rows(figures)]
    maps = any(c.get("kind") == "joint_map" for c in ev.model.carried)
    caption = "Accuracy of each target: the distance from the barycentre of its measurements to the calibrated model's prediction" + (
        ", red where a joint map of the model does not reach." if maps else "."
    )
    return (
        f"<p>ISO 9283:1998 figures on {_esc(which)}: {figures['n_targets']} targets (joint configurations), the command being the calibrated "
        "model's prediction at the target's joints and the attained pose the measurement. Distance accuracy compares measured and predicted "
        "distances between targets: it does not depend on how the instrument was registered to the robot.</p>"
        + _table(["figure", "value"], rows)
        + _figure(acceptance_figure(figures, maps, out), caption)
    )


_CSS = """
body { font-family: -apple-system, "Segoe UI", Helvetica, Arial, sans-serif; max-width: 980px; margin: 2em auto; padding: 0 1em;
       color: #222; line-height: 1.45; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; } h2 { font-size: 1.25em; margin-top: 1.8em; border-bottom: 1px solid #ddd; padding-bottom: 0.2em; }
table { border-collapse: collapse; margin: 0.6em 0; font-size: 0.9em; }
th, td { border: 1px solid #ddd; padding: 0.25em 0.6em; text-align: left; vertical-align: top; }
th { background: #f4f4f4; } td.n { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
table.meta th { width: 11em; } tr.flag td { background: #fff1f0; } tr.off td { color: #777; }
.note { background: #f5f8ff; border-left: 4px solid #6b8bd6; padding: 0.5em 0.8em; margin: 0.8em 0; }
.verdict { background: #fffbe6; border-left: 4px solid #c9a100; padding: 0.5em 0.8em; margin: 0.8em 0; font-size: 1.05em; }
.warn { background: #fff6e5; border-left: 4px solid #e0a030; padding: 0.5em 0.8em; margin: 0.8em 0; }
figure { margin: 1.2em 0; } figure img { max-width: 100%; border: 1px solid #eee; }
figcaption { font-size: 0.9em; color: #444; margin-top: 0.3em; }
code { font-size: 0.95em; } .small { font-size: 0.85em; color: #555; }
"""


def _table(header: list[str], rows: list[list[str]], numeric: set = frozenset(), cls: str = "", row_classes: Optional[list[str]] = None) -> str:
    head = "".join(f"<th>{_esc(h)}</th>" for h in header)
    body = []
    for i, row in enumerate(rows):
        rc = row_classes[i] if row_classes else ""
        cells = "".join(f'<td class="n">{c}</td>' if j in numeric else f"<td>{c}</td>" for j, c in enumerate(row))
        body.append(f'<tr class="{rc}">{cells}</tr>' if rc else f"<tr>{cells}</tr>")
    return (
        f'<table class="{cls}"><thead><tr>{head}</tr></thead><tbody>{"".join(body)}</tbody></table>'
        if cls
        else f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"
    )


def _header(doc: dict, data: _Data) -> str:
    ds = _calibrated_on(doc)
    remastered = doc.get("remaster") or {}
    conv = doc.get("convergence") or {}
    rows = [
        ("robot", doc.get("robot")),
        ("method", doc.get("method")),
        ("measurement", doc.get("measurement")),
        ("written by", f"robocal {doc.get('robocal_version')} (this report: robocal {__version__})"),
        ("source file", (ds.get("source") or "not recorded") + (f" (session 1 of {len(doc['sessions'])})" if doc.get("sessions") else "")),
        ("sha256", ds.get("sha256") or "not recorded"),
        *(
            [("sessions", "; ".join(f"{i}: {f.get('source') or 'not recorded'}" for i, f in enumerate(result_sessions(doc), start=1)))]
            if result_sessions(doc)
            else []
        ),
        ("samples", f"{len(ds.get('rows_used') or [])} training, {len(ds.get('rows_held_out') or [])} held out, {len(ds.get('rows_excluded') or [])} excluded"),
        *(
            [
                (
                    "re-mastered on",
                    f"{remastered.get('data') or 'data in memory'}, {remastered.get('samples')} samples (sha256 {remastered.get('sha256') or 'not recorded'})",
                )
            ]
            if remastered
            else []
        ),
        ("figures computed on", _data_row(data, "the re-mastering's points" if remastered else "the file calibrated on")),
        (
            "solver",
            f"{'converged' if conv.get('success') else 'did not converge'}: {conv.get('message', '')} "
            f"({conv.get('nit', '?')} iterations, {conv.get('nfev', '?')} evaluations, {_num(conv.get('time_s'), 3)} s)",
        ),
    ]
    body = "".join(f"<tr><th>{_esc(k)}</th><td>{_esc(v)}</td></tr>" for k, v in rows)
    return f'<table class="meta"><tbody>{body}</tbody></table>'


def _data_row(data: _Data, fitted: str) -> str:
    """What the figures were computed on; ``fitted``: what the result's set-up was fitted on."""
    if data.dataset is None:
        return "no measurements (see the note under Figures)"
    fitted = f"the file of session {data.session + 1}" if data.session else fitted
    where = data.path or "a Dataset"
    same = f"{fitted} (sha256 matches)" if data.same_file else f"not verified to be {fitted}"
    return f"{where}, {len(data.dataset)} samples; {same}"


def _errors(ev: _Evaluation, dataset: Dataset, fitted: dict) -> dict:
    """The calibrated model's per-sample errors on the training rows of the provenance ``fitted``
    and on its held-out rows."""
    used = np.isin(dataset.rows, np.asarray(fitted.get("rows_used") or [], dtype=np.int64))
    return {"train": ev.after[used], "test": ev.after[ev.held_out]}


def _compare(said: dict, errors: dict, label: str) -> tuple[dict, list[str]]:
    """The metrics ``said`` (``train``, ``test``) with those of ``errors`` in their place, and
    what differs (each prefixed by ``label``)."""
    out, differ = dict(said), []
    for key, e in errors.items():
        if not e.size or not isinstance(said.get(key), dict):
            continue
        mine = {"rmse": rms(e), "mae": float(np.mean(e)), "max": float(np.max(e)), "n": int(e.size)}
        if not all(isinstance(said[key].get(k), (int, float)) and np.isclose(said[key][k], v, rtol=1e-6, atol=1e-9) for k, v in mine.items()):
            was = said[key].get("rmse")
            differ.append(f"{label}{key} RMSE {mine['rmse']:.4g} mm" + (f", the file says {was:.4g}" if isinstance(was, (int, float)) else ""))
        out[key] = {**said[key], **mine}
    return out, differ


def checked_metrics(doc: dict, ev: Optional[_Evaluation], dataset: Optional[Dataset], sessions: list = ()) -> tuple[dict, str, list]:
    """The result's training and held-out metrics, recomputed from its parameter values where the
    data it was calibrated on are at hand, a note saying whether they could be checked (a
    hand-edited file must not show the metrics of other values) and, for a multi-session result,
    each session's metrics ``(s, metrics)``, recomputed where its file is at hand.

    ``ev`` and ``dataset`` are the result's data (a multi-session result's first session);
    ``sessions``: ``(s, evaluation, dataset)`` of its other sessions (``s`` 0-based) whose files
    are at hand, each evaluated at its own set-up. A multi-session result's metrics pool its
    sessions: they are recomputed only from all of them, and each session is compared with its own."""
    m = doc.get("metrics") or {}
    recorded = result_sessions(doc)
    copied = [(s, f.get("metrics") or {}) for s, f in enumerate(recorded)]
    if _monitored(doc):
        return m, "the calibration's, copied from the result file: robocal monitor has applied changes to its values since (see Monitoring)", copied
    if ev is None or ev.held_out is None:
        return m, "copied from the result file: they cannot be checked without the measurement file it was calibrated on (its sha256 must match)", copied
    if doc.get("method") == "rbf":
        return m, "copied from the result file: its network is not held in it, so its values alone do not reproduce them", copied
    if doc.get("remaster"):
        return (
            m,
            "the calibration's, copied from the result file: it was re-mastered since (see Re-mastering), so its set-up is the new session's "
            "and its values no longer reproduce them on the data calibrated on",
            copied,
        )
    if ev.model.session_terms:
        return (
            m,
            "copied from the result file: the terms of its own session are not applied here (they are not the robot's), so they cannot be reproduced",
            copied,
        )
    if not recorded:
        out, differ = _compare(m, _errors(ev, dataset, _fitted(doc)), "")
        per_session, missing = [], []
    else:
        parts = [(0, ev, dataset), *sessions]
        per_session, differ, pooled = [], [], {"train": [], "test": []}
        for s, ev_s, d_s in parts:
            errors = _errors(ev_s, d_s, recorded[s])
            mine, wrong = _compare(recorded[s].get("metrics") or {}, errors, f"session {s + 1} ")
            per_session.append((s, mine))
            differ += wrong
            for key in pooled:
                pooled[key].append(errors[key])
        missing = sorted(set(range(len(recorded))) - {s for s, _, _ in parts})
        per_session += [(s, recorded[s].get("metrics") or {}) for s in missing]
        per_session.sort(key=lambda item: item[0])
        out = m
        if not missing:
            out, wrong = _compare(m, {key: np.concatenate(v) for key, v in pooled.items()}, "all sessions ")
            differ += wrong
    if differ:
        return (
            out,
            (
                "recomputed from the parameter values on the data: the result file's metrics do not match its values ("
                + "; ".join(differ)
                + "): the file was edited or is corrupt"
            ),
            per_session,
        )
    if recorded and missing:
        sessions_missing = ", ".join(str(s + 1) for s in missing)
        return (
            out,
            (
                f"of all sessions copied from the result file (the files of sessions {sessions_missing} are not at hand); "
                "each session at hand recomputed from the parameter values and its own set-up: they match the result file"
            ),
            per_session,
        )
    return (
        out,
        "recomputed from the parameter values on the data" + (" of every session, each at its own set-up" if recorded else "") + ": they match the result file",
        per_session,
    )


def _remastering(doc: dict) -> str:
    """The re-mastering's section: each joint's verdict and change, the test, and the points."""
    found = doc.get("remaster")
    if not found:
        return ""
    rows = []
    for j in found["joints"]:
        unit = j.get("unit", "")
        change = "" if j.get("change") is None else f"{j['change']:+.4g} ± {_num(j.get('std'))} {unit}"
        why = ", ".join(j.get("redundant_with") or [])
        rows.append([str(j["joint"]), _esc(j["status"] + (f" (by {why})" if why else "")), _esc(change), _esc(f"{_num(j.get('detectable_std'))} {unit}")])
    rmse = found.get("rmse") or {}
    fit = found.get("fit") or {}
    return (
        "<h2>Re-mastering</h2>"
        f"<p>Re-mastered on {found.get('samples')} points of a new session ({_esc(found.get('data') or 'data in memory')}): the joints whose zero "
        f"moved, each named when its χ² drop passed {_num(found.get('threshold'))} (family-wise chance {_num(found.get('alpha'))} of naming one that did "
        f"not move; reading noise {_num(found.get('noise_mm'))} mm, {_esc(found.get('noise_from', ''))}). RMSE on these points: "
        f"{_num(rmse.get('setup_alone'))} mm with the set-up alone, {_num(rmse.get('remastered'))} mm re-mastered; "
        f"χ² {_num(fit.get('chi2'))} on {fit.get('dof')} degrees of freedom (p = {_num(fit.get('p_value'))}).</p>"
        + _table(["joint", "zero", "change", "smallest change it could show (1 std)"], rows, numeric={0, 2, 3})
        + "".join(f'<p class="note">{_esc(n[0].upper() + n[1:])}.</p>' for n in found.get("notes") or [])
    )


def _monitoring(doc: dict) -> str:
    """The changes ``robocal monitor`` found and applied to the result's values."""
    if not _monitored(doc):
        return ""
    found = doc["monitor"]
    rows = [
        [
            str(a.get("sample")),
            str(a.get("row")),
            str(a.get("since")),
            _esc(a.get("kind")) + ("" if a.get("joint") is None else f" of joint {a['joint']}"),
            _esc(", ".join(_num(v) for v in a.get("size") or []) + f" {a.get('unit', '')}"),
        ]
        for a in found["alarms"]
    ]
    return (
        f"<h2>Monitoring</h2><p>robocal monitor watched {found.get('samples')} samples and applied what changed to the values below "
        f"(thresholds for one false alarm per {_num(found.get('mean_run_length'))} samples).</p>"
        + _table(["alarm at sample", "row", "since sample", "change", "size"], rows, numeric={0, 1, 2, 4})
    )


def _metrics(doc: dict, m: dict, note: str, per_session: list = ()) -> str:
    rows = []
    named = [(m, "")] + [(ms, f"session {s + 1}, ") for s, ms in per_session]
    for metrics_, prefix in named:
        for key, label in (("train", "training"), ("test", "held out")):
            v = metrics_.get(key)
            if v is None:
                rows.append([_esc(prefix + label), "–", "–", "–", "–"])
            else:
                rows.append([_esc(prefix + label), _fixed(v.get("rmse"), 4), _fixed(v.get("mae"), 4), _fixed(v.get("max"), 4), _esc(v.get("n", "–"))])
    per = "|cable residual|" if doc.get("measurement") == "cable" else "Euclidean position error"
    warn = "warn" if "do not match" in note else "small"
    return (
        _table(["samples", "RMSE (mm)", "MAE (mm)", "max (mm)", "n"], rows, numeric={1, 2, 3, 4})
        + f'<p class="{warn}">Metrics {_esc(note)}.</p>'
        + f'<p class="small">Per-sample error: {_esc(per)}; eq. (28) of the paper (its "STD" is the MAE).</p>'
    )


def checked_implausible(robot: Robot, doc: dict) -> tuple[list[dict], str]:
    """The kinematic parameters beyond 10 mm / 2 deg from nominal, recomputed from the result's
    parameter values (as the table shows them), and a note when the file's own list differs."""
    values = {p["name"]: p["value"] for p in doc["parameters"]}
    flags = implausible_parameters(nominal_robot(robot, doc), values)
    listed, found = sorted(f["name"] for f in doc.get("implausible") or []), sorted(f["name"] for f in flags)
    if listed == found:
        return flags, ""
    return flags, (
        f"the result file lists {listed or 'none'} as implausible, but its parameter values put {found or 'none'} beyond the limits: "
        "the file was edited or is corrupt; the list is recomputed from the values"
    )


def _implausible(flags: list[dict], note: str) -> str:
    note = f'<p class="warn">{_esc(note[0].upper() + note[1:])}.</p>' if note else ""
    if not flags:
        return note + '<p class="note">No kinematic parameter moved beyond 10 mm / 2 deg from nominal.</p>'
    items = []
    for f in sorted(flags, key=lambda f: -abs(f["deviation"]) / f["limit"]):
        unit, factor = SHOWN.get(f["unit"], (f["unit"], 1.0))
        items.append(f"<li><code>{_esc(f['name'])}</code>: {f['deviation'] * factor:+.4g} {_esc(unit)} (limit ±{f['limit'] * factor:.3g} {_esc(unit)})</li>")
    return note + (
        f'<div class="warn"><strong>{len(flags)} kinematic parameter{"s" if len(flags) != 1 else ""} moved beyond 10 mm / 2 deg from nominal</strong>: '
        "the data do not determine them (the fit bends weakly determined directions to absorb other errors); "
        f"a kinematic prior (<code>--kinematic-prior</code>) or more varied poses are needed.<ul>{''.join(items)}</ul></div>"
    )


def _fixed_params(doc: dict) -> str:
    fixed = doc.get("fixed") or {}
    if not fixed:
        return "<p>None: every parameter considered was estimated.</p>"
    rows = [[f"<code>{_esc(n)}</code>", _esc(why)] for n, why in fixed.items()]
    return _table(["parameter", "why it was not estimated"], rows)


def _parameters(doc: dict, flags: list[dict]) -> str:
    flagged = {f["name"] for f in flags}
    fixed = doc.get("fixed") or {}
    rows, classes = [], []
    for p in doc["parameters"]:
        unit, factor = SHOWN.get(p["unit"], (p["unit"], 1.0))
        value_unit, value_factor = ("deg", factor) if p["unit"] == "rad" else (p["unit"], 1.0)
        decimals = 6 if p["unit"] == "1" else 4
        dev = (p["value"] - p["nominal"]) * factor
        std = None if p.get("std") is None else p["std"] * factor
        status = "estimated" if std is not None else ("fixed" if p["name"] in fixed else "not considered")
        nominal, value = _fixed(p["nominal"] * value_factor, decimals), _fixed(p["value"] * value_factor, decimals)
        deviation = "–" if std is None and dev == 0 else f"{dev:+.4g} {_esc(unit) if unit != value_unit else ''}".strip()
        spread = "–" if std is None else f"{std:.2g}"
        rows.append([f"<code>{_esc(p['name'])}</code>", _esc(value_unit), nominal, value, deviation, spread, _esc(status)])
        classes.append("flag" if p["name"] in flagged else ("" if std is not None else "off"))
    return (
        _table(["parameter", "unit", "nominal", "calibrated", "deviation", "std", "status"], rows, numeric={2, 3, 4, 5}, row_classes=classes)
        + '<p class="small">Angles in degrees (stored in radians); a dimensionless scale\'s deviation in ppm. '
        "Highlighted: implausible deviations; grey: not estimated (kept at their start value).</p>"
    )


def _quantities(params) -> str:
    if not isinstance(params, dict):
        return _esc(params)
    shown = []
    for name, q in params.items():
        if isinstance(q, dict):  # a result file's cause
            q = Quantity(value=q.get("value"), std=q.get("std"), unit=q.get("unit", ""))
        if isinstance(q, Quantity) and q.value is not None:
            sd = f" ± {q.std:.2g}" if q.std is not None else ""
            shown.append(f"{_esc(name)} {q.value:.4g}{sd} {_esc(q.unit)}")
        elif isinstance(q, list):
            shown.append(f"{_esc(name)} {_esc(q[:8])}{' …' if len(q) > 8 else ''} ({len(q)})")
        else:
            shown.append(f"{_esc(name)} {_esc(q)}")
    return "; ".join(shown)


def _causes(doc: dict) -> str:
    causes = doc.get("causes")
    if not causes:
        return ""
    rows = [[_esc(c.get("label") or c.get("kind")), _quantities(c.get("params")), _esc(c.get("implausible") or "")] for c in causes]
    intro = "<h2>Causes in the model</h2><p>The calibration fitted an extended model: the geometric parameters and these causes.</p>"
    return intro + _table(["cause", "parameters", "implausible"], rows)


def _diagnosis_table(report: DiagnosisReport) -> str:
    rows = []
    for e in report.effects:
        # A structural cause's alternatives have their own column in the structure section.
        alike = "" if e.kind in STRUCTURAL else alike_words(e.significance)
        quantities = _quantities(e.params) + _esc(correlation_words(e.correlation) + alike + settling_words(e.after_long_moves))
        quantities += "".join(f", beside its {_esc(h.label)} ({_quantities(h.params)})" for h in e.with_harmonics)  # one claim of the joint
        rows.append([_esc(e.label), quantities, _fixed(e.rmse_before, 4), _fixed(e.rmse_after, 4)])
    several, b, f = report.several, report.baseline, report.final
    final = None if f is None else f.held_out(several)
    intro = (
        f"<p>{_esc(report.robot or '')}, {_esc(report.measurement or '')} data, {_esc(report.samples if report.samples is not None else '?')} samples"
        f"{' from ' + _esc(report.source) if report.source else ''}: geometric baseline held-out RMSE {_fixed(b.held_out(several), 4)} mm"
        f"{', final ' + _fixed(final, 4) + ' mm' if final is not None else ''}.</p>"
    )
    words = None if f is None else leftover_words(f.residuals)
    left = f"<p>What is left: {_esc(words)}.</p>" if words else ""
    found = [] if f is None else f.unexplained
    if found:
        share = [f"{u.share:.0%}" if u.share is not None else "?" for u in found]
        unexplained = [[_esc(u.label), _esc(s), _esc(u.reason)] for u, s in zip(found, share)]
        left += _table(["unexplained finding", "share of the error left", "refused because"], unexplained)
    if not rows:
        return intro + "<p>No cause beyond the geometric model is significant.</p>" + left
    return intro + _table(["effect", "parameters", "held-out RMSE before (mm)", "after (mm)"], rows, numeric={2, 3}) + left


#: Kinds that change how the data are read rather than add a smooth term.
STRUCTURAL = structure.KINDS + ("step",)


def _structure_section(report: DiagnosisReport) -> str:
    """The structural causes found (reading conventions, sensor steps) with the alternatives the
    data could not tell apart, and the structural hypotheses rejected."""
    found = [e for e in report.effects if e.kind in STRUCTURAL]
    tried = [r for r in report.rejected if r.kind in STRUCTURAL]
    if not found and not tried:
        return ""
    rows = [
        [_esc(e.label), _quantities(e.params), _esc(", ".join(map(str, (e.significance or {}).get("undetermined_between") or [])) or "none")] for e in found
    ]
    part = (
        "<h3>Structure</h3><p>How the controller reports its joints (a zero 90° away or re-mastered, a reversed sign, a joint read "
        "relative to another) and steps of the sensor's zero or the tracker's position: not small corrections but a different reading "
        "of the data, each judged by full re-fits.</p>"
    )
    if rows:
        part += _table(["found", "parameters", "alternatives the data cannot tell apart"], rows)
    if tried:
        part += _table(["rejected", "why"], [[_esc(r.label), _esc(r.reason)] for r in tried[:8]])
    return part


def _budget_section(report: DiagnosisReport) -> str:
    """The error budget (what the data's resolution explains) and the physical model's state."""
    f = report.final
    if f is None:
        return ""
    part = ""
    floor = f.floor
    if floor is not None and f.floor_mm is not None and f.rmse_heldout is not None:
        rows = [["final held-out RMSE", _fixed(f.rmse_heldout, 4)]]
        if f.rotation_rmse_heldout_deg is not None:
            rows.append(["final held-out orientation RMS (deg)", _fixed(f.rotation_rmse_heldout_deg, 4)])
        above = max(f.rmse_heldout - f.floor_mm, 0.0)
        rows += [
            ["floor from the joint readings' resolution", _fixed(floor.joints_mm, 4)],
            ["floor from the sensor's resolution and noise", _fixed(floor.sensor_mm, 4)],
            ["floor (both)", _fixed(f.floor_mm, 4)],
            ["unexplained above the floor", _fixed(above, 4)],
        ]
        if revisits := floor.revisits:
            rows += [
                [f"repeatability of one reading, measured at {revisits.pairs} revisited joint configurations", _fixed(revisits.repeatability_mm, 4)],
                ["final model's error shared by the revisits, beyond their noise (at least)", _fixed(revisits.systematic_mm, 4)],
            ]
        if f.explained is not None:
            rows.append(["share of the baseline's held-out mean square error above the floor explained", f"{f.explained:.0%}"])
        intro = f"<h3>Error budget</h3><p>How much of the remaining error the data's own resolution explains ({_esc(floor.note)}).</p>"
        part += intro + _table(["", "mm"], rows, numeric={1})
    prior = f.tolerance_prior
    if prior:
        if prior.accepted:
            unconstrained = _fixed(f.unconstrained(report.several), 4)
            part += (
                '<p class="note">Physical model: where the data leave the geometry undetermined it is held near nominal by a tolerance prior '
                f"(±{_esc(prior.sigma_mm)} mm, ±{_esc(prior.sigma_deg)}°); unconstrained held-out RMSE {unconstrained} mm.</p>"
            )
        else:
            tried = f"a tolerance prior (±{_esc(prior.sigma_mm)} mm, ±{_esc(prior.sigma_deg)}°) was tried"
            part += f'<p class="warn">No physical model: {tried}; {_esc(prior.reason)}.</p>'
    if f.implausible:
        flags = [flag.model_dump() for flag in f.implausible]
        part += '<p class="warn">Final model: ' + _esc(describe_implausible(flags, meaning=implausible_meaning(prior))) + ".</p>"
    return part


def _sessions_section(report: DiagnosisReport) -> str:
    """Per session of a multi-session diagnosis: what its own data show and what it keeps."""
    if not report.several:
        return ""
    own = report.model.sessions if report.model is not None and report.model.sessions is not None else []
    per_session = report.final.per_session if report.final is not None else []
    rows = []
    for i, s in enumerate(report.sessions):
        kept = own[i].causes if i < len(own) else []
        alone = "; ".join(e.label for e in s.diagnosis.effects) if s.diagnosis is not None else ""
        left_out = _fixed(per_session[i], 4) if i < len(per_session) else ""
        samples = "" if s.samples is None else str(s.samples)
        rows.append([str(i + 1), _esc(s.source or ""), samples, _esc(alone or "none"), _esc("; ".join(kept) or "none"), left_out])
    return (
        "<h3>Sessions</h3><p>Each session diagnosed on its own; a cause of the robot is kept only if it lowers the error of sessions it was not "
        "fitted on. Session terms (steps, drift, outliers, set-up) stay with their session.</p>"
        + _table(["session", "file", "samples", "found on its own", "keeps", "held-out RMSE (mm), left out"], rows, numeric={2, 5})
    )


def _figure(path: Path, caption: str) -> str:
    return f'<figure><img src="{_esc(path.name)}" alt="{_esc(caption)}"><figcaption>{_esc(caption)}</figcaption></figure>'


def report(result, out, data: Union[str, Path, Dataset, None] = None, diagnosis: Union[str, Path, dict, None] = None, angle_unit: Optional[str] = None) -> Path:
    """Writes the HTML report of a calibration result and its figures; returns the page's path.

    Parameters
    ----------
    result : str, Path or dict
        A result file (schema ``robocal.result/1``) or its document.
    out : str or Path
        Folder for ``index.html`` and the PNG figures (created if needed).
    data : str, Path or Dataset, optional
        The measurements (default: the file the result names, if it is on this machine).
    diagnosis : str, Path or dict, optional
        A ``robocal diagnose --json`` report to add (held-out RMSE per cause, table of causes).
    angle_unit : {"deg", "rad"}, optional
        Unit of the joint columns of a canonical ``data`` file (see :func:`robocal.data.load`).

    Returns
    -------
    Path
        ``out/index.html``.

    Raises
    ------
    InvalidParameterError
        The result or diagnose file is unreadable or malformed.
    DataError
        An explicitly given ``data`` file cannot be read.
    """
    robot, doc = load_result(result, corrector=True)
    implausible = checked_implausible(robot, doc)
    diag = None if diagnosis is None else load_diagnosis(diagnosis).check_robot(robot.name).needs_figures("report --diagnosis")
    d = _load_data(doc, data, angle_unit, robot)
    out = make_folder(out)
    meas = doc["measurement"]
    notes = list(d.notes)
    figures: list[str] = []

    ev = None
    if d.dataset is not None:
        # --data of a multi-session result's later session: at that session's own set-up (its held-out rows marked)
        own, fitted = (session_robot(robot, doc, d.session), result_sessions(doc)[d.session]) if d.session else (robot, None)
        ev = _evaluate(own, doc, d.dataset, d.same_file, fitted)
        recorded = _fitted(doc).get("sha256")
        if d.path is not None and not d.same_file:
            notes.append(
                "the measurement file is not the one calibrated on (its sha256 differs from the recorded one): held-out samples are not marked"
                if recorded
                else "the result records no sha256 of its data: held-out samples are not marked"
            )
        if ev.model.session_terms:
            notes.append(
                f"the figures show the robot's model as verify applies it: the terms of the calibration's own session ({'; '.join(ev.model.session_terms)}) "
                "are not applied, so the errors may exceed the metrics above"
            )
        if doc.get("method") == "rbf":
            notes.append("method rbf corrects the prediction with a network the result file does not hold: the figures show its geometric parameters only")
    # A multi-session result: every session whose file is at hand, each at its own set-up (its
    # figures, and its metrics checked against its own; the result's pool them all).
    others = []
    if ev is not None and data is None:
        for s, fitted in list(enumerate(result_sessions(doc)))[1:]:
            own = session_robot(robot, doc, s)
            d_s = _load_recorded(fitted, meas, own, f"session {s + 1} of the result")
            notes += d_s.notes
            if d_s.dataset is not None:
                others.append((s, _evaluate(own, doc, d_s.dataset, True, fitted), d_s.dataset))
    shown = [ev] + [e for _, e, _ in others] if ev is not None else []
    before, after = (np.concatenate([e.before for e in shown]), np.concatenate([e.after for e in shown])) if shown else (None, None)
    held = None if ev is None or ev.held_out is None else np.concatenate([e.held_out for e in shown])
    paths_residuals = residual_figures(before, after, held, len(ev.model.carried), meas, out) if ev is not None else []
    if paths_residuals:
        before_rms, after_rms = rms(before), rms(after)
        of = f" of {len(shown)} sessions, in session order, each at its own set-up" if others else ""
        figures.append(
            _figure(
                paths_residuals[0],
                f"Per-sample error on all {len(after)} samples{of}: RMSE {before_rms:.4g} mm with the nominal kinematics "
                f"(measurement set-up refitted) and {after_rms:.4g} mm calibrated"
                + (" (geometry and joint causes, the model robocal verify applies)." if ev.model.carried else "."),
            )
        )
        figures.append(
            _figure(
                paths_residuals[1],
                "The same errors in the order of the measurement file"
                + (", held-out samples marked with crosses." if held is not None and held.any() else "."),
            )
        )
    p = parameter_figure(doc, out)
    if p is not None:
        figures.append(
            _figure(
                p,
                f"Deviation from nominal of the {len(estimated(doc))} estimated joint parameters with ±2 std error bars (red: beyond 2 std); "
                "base, tool and sensor parameters, fitted from scratch, are in the table below.",
            )
        )
    else:
        figures.append(
            '<p class="note">No joint parameter has a standard deviation in the result file, so there is no figure of the deviations (see the table below).</p>'
        )
    p = convergence_figure(doc, out)
    if p is not None:
        figures.append(_figure(p, "Cost ½‖r‖² of the training residuals after each iteration of the solver."))
    p = identifiability_figure(ev.singular, ev.n_cols, out) if ev is not None else None
    if p is not None:
        kappa = condition_number(ev.singular)
        figures.append(
            _figure(
                p,
                f"Singular values of the identification Jacobian at the calibrated parameters, columns scaled to unit norm: condition number {kappa:.4g} "
                "(large values mean weakly determined parameter combinations).",
            )
        )
    diag_html = ""
    if diag is not None:
        p = diagnosis_figure(diag, out / "diagnosis.png")
        joint_maps = [e for e in diag.effects if e.kind == "joint_map" and e.curve is not None]
        caption = (
            "Joint map of joint {}: the correction of its angle against its reading (beyond the range it was fitted on its correction fades out within a few knot spacings), "
            "with ±2 standard deviations."
        )
        maps = [_figure(map_figure(e, out / f"map_joint{e.joint}.png"), caption.format(e.joint)) for e in joint_maps]
        chart = _figure(p, "Held-out RMSE of the geometric baseline and after each diagnosed cause is added (cross-validated by robocal diagnose).")
        sections = [_diagnosis_table(diag), "".join(maps), _structure_section(diag), _budget_section(diag), _sessions_section(diag)]
        diag_html = "<h2>Diagnosis</h2>" + chart + "".join(sections)

    for n in notes:
        logger.info("report: %s", n)
    title = f"robocal calibration report: {doc.get('robot', '')}"
    note_html = "".join(f'<p class="note">{_esc(n[0].upper() + n[1:])}.</p>' for n in notes)
    page = f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{_esc(title)}</title>
<style>{_CSS}</style>
</head>
<body>
<h1>{_esc(title)}</h1>
<p class="verdict"><strong>Verdict: {_esc(verdict(doc)[0])}</strong>: {_esc(verdict(doc)[1])}.</p>
{_header(doc, d)}
<h2>Accuracy</h2>
{_metrics(doc, *checked_metrics(doc, None if d.session else ev, d.dataset, others))}
{_remastering(doc)}
{_monitoring(doc)}
{"" if ev is None else "<h2>Acceptance (ISO 9283)</h2>" + _acceptance_section(ev, out, several=len(result_sessions(doc)) > 1, session=d.session)}
<h2>Plausibility</h2>
{_implausible(*implausible)}
<h2>Figures</h2>
{note_html}
{"".join(figures)}
{diag_html}
{_causes(doc)}
<h2>Parameters not estimated</h2>
{_fixed_params(doc)}
<h2>Parameters</h2>
{_parameters(doc, implausible[0])}
</body>
</html>
"""
    return write_text(out / "index.html", page)
