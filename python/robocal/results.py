"""The calibration result file: a versioned JSON document that loads back into the same model.

``robocal calibrate --out result.json`` writes it (:func:`save_result`); :func:`load_result`
reads it back into a :class:`Robot` with the calibrated parameters — what ``compensate``,
``report`` and ``export`` start from. Keys (schema ``robocal.result/1``):

``schema``, ``robocal_version``
    What wrote it.
``robot``, ``robot_model``
    The robot's name and its definition: the nominal robot as a robot document (schema
    ``robocal.robot/1``, angles in rad: :mod:`robocal.robot_file`), plus ``nominal``, the same
    values as the parameter vector — enough to rebuild it without the catalog. Files written
    before the robot schema hold joints without values and ``nominal``; both forms read.
``measurement``, ``method``
``parameters``
    Every parameter: ``name, unit, nominal, value`` (= calibrated), ``deviation, std``
    (``std`` null where not estimated).
``free``, ``fixed``
    The estimated parameters and, for each one left out, why (identifiability).
``implausible``, ``causes``
    Kinematic parameters beyond 10 mm / 2 deg from nominal; the extended model's causes.
``metrics``, ``convergence``
    Eq. (28) metrics on training and held-out samples; the solver's record.
``dataset``
    Provenance: ``source`` file, its ``sha256``, ``rows_used`` (training), ``rows_held_out``
    and ``rows_excluded`` (with reasons), and the ``fingerprint`` of the training samples' content
    (:class:`~robocal.data.identity.Fingerprint`: ``verify`` recognises them in any order or encoding).
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Optional

import numpy as np

from ._robocal import __version__
from .data.identity import MAX_KEYS, Fingerprint
from .exceptions import InvalidParameterError
from .outputs import write_json
from .robot_file import RESULT_SCHEMA as SCHEMA
from .robot_file import calibrated_robot, load_document, read_document, robot_document
from .serial_robot import Robot


def robot_model(robot: Robot) -> dict:
    """The robot's definition: its robot document (angles in rad) and the nominal parameter vector."""
    return {**robot_document(robot), "nominal": [float(v) for v in robot.params]}


def file_sha256(path) -> Optional[str]:
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except (OSError, TypeError):
        return None


def recorded_path(source) -> Optional[str]:
    """A data file's path as results and reports record it: absolute, so that it is found from any
    folder; None for data given in memory."""
    return os.path.abspath(source) if source else None


def recorded_source(source) -> dict:
    """A data file as a result records it: :func:`recorded_path` and its SHA-256."""
    return {"source": recorded_path(source), "sha256": file_sha256(source) if source else None}


def recorded_data_files(paths) -> dict:
    """The training data files the result files among ``paths`` record (path -> the result's
    path), which an output must not replace: the result would no longer find its data. What is
    not a readable result records none."""
    out = {}
    for path in paths:
        if not isinstance(path, (str, os.PathLike)) or not str(path).endswith(".json") or not os.path.isfile(path):
            continue
        try:  # the one reader of documents: a file nested 100 000 deep ended in a RecursionError here
            doc = read_document(path, "result file")
        except InvalidParameterError:
            continue
        if not isinstance(doc, dict):
            continue
        provenance = [doc.get("dataset")] + (doc.get("sessions") if isinstance(doc.get("sessions"), list) else [])
        for entry in provenance:
            source = entry.get("source") if isinstance(entry, dict) else None
            if isinstance(source, str) and os.path.isfile(source):
                out[source] = str(path)
    return out


def training_fingerprint(train) -> Optional[dict]:
    """What a result records to recognise its training samples in any file (``verify``):
    :class:`~robocal.data.identity.Fingerprint` of ``train`` (a Dataset, or None)."""
    return None if train is None else Fingerprint.of(train, limit=MAX_KEYS).to_dict()


def result_document(core: dict, robot: Robot, train=None, test=None) -> dict:
    """The versioned result document around a calibration's ``core`` dict (method, parameters,
    metrics, ...): schema, version, the robot's definition, deviations and the provenance of
    the ``train`` and ``test`` Datasets (source file, hash, row numbers)."""
    doc = dict(core)
    for p in doc["parameters"]:
        p["deviation"] = p["value"] - p["nominal"]
    doc = {
        "schema": SCHEMA,
        "robocal_version": __version__,
        **doc,
        "robot_model": robot_model(robot),
        "dataset": {
            **recorded_source(train.source if train is not None else None),
            "rows_used": [int(r) for r in train.rows] if train is not None else None,
            "rows_held_out": [int(r) for r in test.rows] if test is not None else [],
            "rows_excluded": list(train.excluded) if train is not None else [],
            "fingerprint": training_fingerprint(train),
        },
    }
    return doc


def result_sessions(doc: dict) -> list[dict]:
    """The sessions of a multi-session result (each a provenance dict with its ``setup``), or none."""
    sessions = doc.get("sessions")
    return [s for s in sessions if isinstance(s, dict)] if isinstance(sessions, list) else []


def session_robot(robot: Robot, doc: dict, s: int) -> Robot:
    """The calibrated robot with session ``s``'s (0-based) own set-up: a multi-session result's
    ``parameters`` hold session 1's, each session's ``setup`` its own (name -> value, mm / rad)."""
    setup = result_sessions(doc)[s].get("setup") or {}
    valid = isinstance(setup, dict) and all(
        n in robot.param_names and isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) for n, v in setup.items()
    )
    if not valid:
        raise InvalidParameterError(
            f"result: key 'sessions', session {s + 1}, key 'setup' must map the robot's set-up parameters to finite numbers; got {setup!r:.80}"
        )
    params = robot.params.copy()
    for name, value in setup.items():
        params[robot.index(name)] = float(value)
    return Robot(robot.name, robot.joints, params, mass_model=robot.mass_model)


def unread_training(sessions: list[dict]) -> Optional[str]:
    """Why the training data of a result's ``sessions`` (each with ``source``, ``rows_used`` and
    ``sha256``, as a result records them) cannot be read again, or None."""
    for s in sessions:
        source, rows = s.get("source"), s.get("rows_used")
        if source is None or rows is None:
            return "the result names no training data file (it was calibrated on data in memory)"
        if not Path(source).is_file():
            return f"its training data {source} are not found"
        if s.get("sha256") and file_sha256(source) != s["sha256"]:
            return f"its training data {source} changed since the calibration (another SHA-256)"
    return None


def save_result(document: dict, path) -> Path:
    return write_json(path, document)


def load_result(source, *, corrector: bool = False) -> tuple[Robot, dict]:
    """The calibrated robot and the document of a result file (path or dict).

    ``corrector``: accept a result whose model is not all in its file, a corrector of the nominal
    model (method ``rbf``: its network is not written); only what shows the recorded figures does.

    Raises
    ------
    InvalidParameterError
        Naming the file and what is wrong with it (unreadable, not JSON, another schema,
        missing or malformed keys, a corrector unless ``corrector``).
    """
    doc = load_document(source, "robocal result file", "result")
    return calibrated_robot(doc, "result" if isinstance(source, dict) else str(source), corrector=corrector), doc
