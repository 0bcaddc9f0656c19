"""The calibration result file: a versioned JSON document that loads back into the same model.

``robocal calibrate --out result.json`` writes it (:func:`save_result`); :func:`load_result`
reads it back into a :class:`Robot` with the calibrated parameters — what ``compensate``,
``report`` and ``export`` start from. Keys (schema ``robocal.result/1``):

``schema``, ``robocal_version``
    What wrote it.
``robot``, ``robot_model``
    The robot's name and its definition: joints (``convention``, ``kind``, ``hayati``,
    ``limits`` in rad) and the nominal parameter vector — enough to rebuild it without the
    catalog.
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
    and ``rows_excluded`` (with reasons).
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Optional

import numpy as np

from ._robocal import __version__
from .exceptions import InvalidParameterError
from .outputs import write_json
from .robot import Joint, Robot

SCHEMA = "robocal.result/1"


def robot_model(robot: Robot) -> dict:
    """The robot's definition: joints and nominal parameters."""
    return {
        "name": robot.name,
        "joints": [{"convention": j.convention, "kind": j.kind, "hayati": j.hayati, "limits": [float(v) for v in j.limits]} for j in robot.joints],
        "nominal": [float(v) for v in robot.params],
    }


def file_sha256(path) -> Optional[str]:
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except (OSError, TypeError):
        return None


def result_document(core: dict, robot: Robot, train=None, test=None) -> dict:
    """The versioned result document around a calibration's ``core`` dict (method, parameters,
    metrics, ...): schema, version, the robot's definition, deviations and the provenance of
    the ``train`` and ``test`` Datasets (source file, hash, row numbers)."""
    doc = dict(core)
    for p in doc["parameters"]:
        p["deviation"] = p["value"] - p["nominal"]
    source = train.source if train is not None else None
    doc = {
        "schema": SCHEMA,
        "robocal_version": __version__,
        **doc,
        "robot_model": robot_model(robot),
        "dataset": {
            "source": source,
            "sha256": file_sha256(source) if source else None,
            "rows_used": [int(r) for r in train.rows] if train is not None else None,
            "rows_held_out": [int(r) for r in test.rows] if test is not None else [],
            "rows_excluded": list(train.excluded) if train is not None else [],
        },
    }
    return doc


def save_result(document: dict, path) -> Path:
    return write_json(path, document)


def _fail(where: str, why: str):
    raise InvalidParameterError(f"{where}: not a robocal result file ({why})")


def load_result(source) -> tuple[Robot, dict]:
    """The calibrated robot and the document of a result file (path or dict).

    Raises
    ------
    InvalidParameterError
        Naming the file and what is wrong with it (unreadable, not JSON, another schema,
        missing or malformed keys).
    """
    if not isinstance(source, (dict, str, os.PathLike)):
        raise InvalidParameterError(f"a result must be a result file path or its document (dict); got {type(source).__name__} {source!r}")
    where = str(source) if not isinstance(source, dict) else "result"
    if isinstance(source, dict):
        doc = source
    else:
        try:
            doc = json.loads(Path(source).read_text())
        except OSError as exc:
            raise InvalidParameterError(f"{where}: cannot read it ({exc.strerror or exc})") from None
        except ValueError as exc:
            _fail(where, f"invalid JSON: {exc}")
    if not isinstance(doc, dict):
        _fail(where, "the top level is not an object")
    if doc.get("schema") != SCHEMA:
        _fail(where, f"schema {doc.get('schema')!r}, expected {SCHEMA!r}")
    from .schemas import ResultSpec, validate  # pydantic loads only when a result is read

    spec = validate(ResultSpec, doc, where)
    model = spec.robot_model
    joints = [Joint(j.convention, j.kind, j.hayati, tuple(j.limits)) for j in model.joints]
    nominal = np.array(model.nominal, dtype=np.float64)
    calibrated = {p.name: p.value for p in spec.parameters}
    robot = Robot(model.name, joints, nominal)
    missing = [n for n in robot.param_names if n not in calibrated]
    if missing:
        _fail(where, f"parameters lack {missing[:5]}")
    values = np.array([calibrated[n] for n in robot.param_names])
    if not np.all(np.isfinite(values)):
        _fail(where, "a parameter value is not finite")
    return Robot(model.name, joints, values), doc
