"""The robot document (schema ``robocal.robot/1``): one shape for robot files (JSON or YAML,
:func:`robocal.write_robot` / :func:`robocal.robot`) and the result file's ``robot_model``.

Keys (docs/data-format.md, "Robot files"): ``schema``, ``name``, ``description``, ``units``
(``length`` ``mm``; ``angle`` ``deg``, the default, or ``rad``), ``convention`` (the joints'
default), ``joints`` (``convention, kind, alpha, a, d, theta, beta, hayati, limits``), ``base``
and ``tool`` (``x, y, z, rx, ry, rz``: ``Tx Ty Tz Rz Ry Rx``), ``sensor`` (``anchor_x,
anchor_y, anchor_z, cable_offset, cable_scale``) and ``masses`` (``links``: ``mass_kg`` and
``com_mm`` per joint, ``rated_payload_kg``, ``compliance_rad_per_Nm``: the robot's
:class:`robocal.serial_robot.MassModel`, written only when the robot has its own). Only ``joints`` and their ``alpha, a, d, theta``
are required, so hand-written files stay short and the files written before this schema read.
:func:`write_robot_file` writes every key, angles in rad by default: ``read_robot_file(write_robot_file(r))``
gives ``r`` back bit for bit (in degrees the conversion may move a value by one unit in the last
place). The export table (:mod:`robocal.robot_table`) holds the same fields, one row per joint.
"""

from __future__ import annotations

import functools
import json
import math
import os
from collections.abc import Hashable
from pathlib import Path

import numpy as np

from .exceptions import InvalidParameterError, RobocalError
from .files import read_regular
from .outputs import write_json, write_text
from .serial_robot import Joint, MassModel, Robot

SCHEMA = "robocal.robot/1"
#: The result file's schema (:mod:`robocal.results`): :func:`read_robot_file` reads its calibrated robot.
RESULT_SCHEMA = "robocal.result/1"
FRAME_KEYS = ("x", "y", "z", "rx", "ry", "rz")
SENSOR_KEYS = ("anchor_x", "anchor_y", "anchor_z", "cable_offset", "cable_scale")


def robot_document(robot: Robot, degrees: bool = False) -> dict:
    """Every field of ``robot`` as a robot document (lengths mm; angles rad, or deg when ``degrees``)."""
    angle = math.degrees if degrees else float
    p = robot.params
    joints = []
    for j, joint in enumerate(robot.joints):
        alpha, a, d, theta, beta = (float(v) for v in p[5 * j : 5 * j + 5])
        limit = angle if joint.kind == "revolute" else float
        joints.append(
            {
                "convention": joint.convention,
                "kind": joint.kind,
                "alpha": angle(alpha),
                "a": a,
                "d": d,
                "theta": angle(theta),
                "beta": angle(beta),
                "hayati": bool(joint.hayati),
                "limits": [limit(float(v)) for v in joint.limits],
            }
        )

    def frame(prefix: str) -> dict:
        start = robot.index(f"{prefix}_x")
        return {k: (angle if k.startswith("r") else float)(float(v)) for k, v in zip(FRAME_KEYS, p[start : start + 6])}

    doc = {
        "schema": SCHEMA,
        "name": robot.name,
        "units": {"length": "mm", "angle": "deg" if degrees else "rad"},
        "joints": joints,
        "base": frame("base"),
        "tool": frame("tool"),
        "sensor": {k: float(p[robot.index(k)]) for k in SENSOR_KEYS},
    }
    if robot.mass_model is not None:
        doc["masses"] = masses_document(robot.mass_model)
    return doc


def masses_document(model: MassModel) -> dict:
    """A robot document's ``masses`` section: kg, mm (centres of mass in the link's DH frame) and rad/(N·m)."""
    centres = model.centres_of_mass or (None,) * len(model.link_masses)
    links = [{"mass_kg": m} if c is None else {"mass_kg": m, "com_mm": list(c)} for m, c in zip(model.link_masses, centres)]
    doc = {"links": links, "rated_payload_kg": model.rated_payload}
    if model.compliance is not None:
        doc["compliance_rad_per_Nm"] = model.compliance
    return doc


def mass_model_from_spec(masses) -> MassModel:
    """The :class:`MassModel` of a validated :class:`robocal.schemas.MassesSpec`."""
    centres = tuple(None if link.com_mm is None else tuple(link.com_mm) for link in masses.links)
    return MassModel(
        tuple(link.mass_kg for link in masses.links),
        rated_payload=masses.rated_payload_kg,
        compliance=masses.compliance_rad_per_Nm,
        centres_of_mass=None if all(c is None for c in centres) else centres,
    )


def robot_from_spec(spec, name: str, where: str = "robot file") -> Robot:
    """The :class:`Robot` of a validated :class:`robocal.schemas.RobotSpec`; an error names
    ``where`` (the file), the joint or parameter, in the document's units."""
    to_rad = math.radians if spec.units.angle == "deg" else float
    joints, values = [], []
    for i, j in enumerate(spec.joints, start=1):
        kind = j.kind
        if j.limits is None:  # the default is ±180 deg also in a rad document (not ±180 rad)
            limits = (-math.pi, math.pi) if kind == "revolute" else (-180.0, 180.0)
        elif not j.limits[0] < j.limits[1]:  # here, not in Robot(): in the file's unit
            unit = "mm" if kind == "prismatic" else spec.units.angle
            raise InvalidParameterError(f"{where}: joint {i}, key 'limits': the lower limit must be below the upper; got {j.limits} ({unit})")
        else:
            limits = tuple(to_rad(v) if kind == "revolute" else float(v) for v in j.limits)
        joints.append(Joint(j.convention or spec.convention, kind, j.hayati, limits))
        values += [to_rad(j.alpha), j.a, j.d, to_rad(j.theta), to_rad(j.beta)]
    for frame in (spec.base, spec.tool):
        values += [to_rad(getattr(frame, k)) if k.startswith("r") else getattr(frame, k) for k in FRAME_KEYS]
    values += [getattr(spec.sensor, k) for k in SENSOR_KEYS]
    masses = None if spec.masses is None else mass_model_from_spec(spec.masses)
    return built(where, spec.name or name, joints, np.array(values, dtype=np.float64), masses)


def built(where: str, *args) -> Robot:
    """``Robot(*args)``, its error prefixed with ``where`` (the file it was read from)."""
    try:
        return Robot(*args)
    except RobocalError as exc:
        raise InvalidParameterError(f"{where}: {exc}") from None


def robot_from_model(model, where: str = "result file") -> Robot:
    """The nominal robot of a result's validated ``robot_model``: a robot document, or the older
    form (joints without values and the ``nominal`` vector); errors name ``where`` (the file)."""
    where = f"{where}: robot_model"
    if hasattr(model, "units"):
        robot = robot_from_spec(model, model.name or "robot", where)
        if model.nominal is not None and len(model.nominal) != robot.n_params:
            raise InvalidParameterError(
                f"{where} has {robot.n_joints} joints ({robot.n_params} parameters) but its key 'nominal' holds {len(model.nominal)} values"
            )
        return robot
    joints = [Joint(j.convention, j.kind, j.hayati, tuple(j.limits)) for j in model.joints]
    return built(where, model.name, joints, np.array(model.nominal, dtype=np.float64))


def not_a_result(where: str, why: str):
    raise InvalidParameterError(f"{where}: not a robocal result file ({why})")


def calibrated_robot(doc: dict, where: str, corrector: bool = False) -> Robot:
    """The calibrated robot of a result document: its ``robot_model`` with every parameter at its
    calibrated ``value``. ``corrector``: accept a corrector of the nominal model (method ``rbf``),
    whose network the document does not hold.

    Raises
    ------
    InvalidParameterError
        Naming ``where`` (the file) and what is wrong: another schema, missing or malformed keys,
        a parameter missing or not finite, a corrector unless ``corrector``.
    """
    if not isinstance(doc, dict):
        not_a_result(where, "the top level is not an object")
    if doc.get("schema") != RESULT_SCHEMA:
        not_a_result(where, f"schema {doc.get('schema')!r}, expected {RESULT_SCHEMA!r}")
    from .schemas import ResultSpec, validate  # pydantic loads only when a document is read

    spec = validate(ResultSpec, doc, where)
    robot = robot_from_model(spec.robot_model, where)
    names = [p.name for p in spec.parameters]
    twice = sorted({n for n in names if names.count(n) > 1}) if len(set(names)) < len(names) else []
    if twice:
        not_a_result(where, f"parameters {twice[:5]} appear more than once in key 'parameters'")
    calibrated = dict(zip(names, (p.value for p in spec.parameters)))
    unknown = [n for n in names if n not in robot.param_names]
    if unknown:  # a parameter of another robot (or a typo): the file does not describe one model
        joints = len({n[len("alpha") :] for n in names if n.startswith("alpha")})
        count = f"; the parameters hold {joints} joints" if joints != robot.n_joints else ""
        not_a_result(where, f"parameters {unknown[:5]} are not parameters of its robot_model ({robot.n_joints} joints){count}")
    missing = [n for n in robot.param_names if n not in calibrated]
    if missing:
        not_a_result(where, f"parameters lack {missing[:5]}")
    units = {p.name: p.unit for p in spec.parameters}
    # The values are read in the robot's units whatever the key says: a hand-edited 'deg' would be taken as rad.
    other = [(n, u) for n, u in zip(robot.param_names, robot.param_units) if units[n] != u]
    if other:
        (name, unit), *_ = other
        not_a_result(where, f"parameter {name} has unit {units[name]!r}; a result file holds it in {unit!r}")
    values = np.array([calibrated[n] for n in robot.param_names])
    if not np.all(np.isfinite(values)):
        not_a_result(where, f"the value of {robot.param_names[int(np.flatnonzero(~np.isfinite(values))[0])]} is not finite")
    if doc.get("corrector") and not corrector:
        # Its robot is the nominal one: verify, export, compensate, a robot file ... would apply that under the result's name.
        raise InvalidParameterError(
            f"{where}: a result of method {doc.get('method')!r}, a corrector of the nominal model whose correction the file "
            "does not hold: applied to new data it is the nominal robot; calibrate with a method that identifies the "
            "parameters (`robocal report` shows its recorded figures)"
        )
    return built(where, robot.name, robot.joints, values, robot.mass_model)


#: Deepest nesting of lists and objects a document may have. robocal's documents are at most
#: ~8 deep; a deeper one is corrupt, and Python's parsers and validators recurse on nesting
#: (100 000 brackets would end in a RecursionError).
MAX_DEPTH = 64


class DuplicateKeyError(ValueError):
    """A JSON or YAML object holds the same key twice (the parsers would keep the last silently)."""

    def __init__(self, key):
        super().__init__(key)
        self.key = key


def _unique_object(pairs: list) -> dict:
    """json's ``object_pairs_hook``: the object, or a :class:`DuplicateKeyError`."""
    doc = {}
    for key, value in pairs:
        if key in doc:
            raise DuplicateKeyError(key)
        doc[key] = value
    return doc


@functools.cache
def _yaml_loader():
    """``yaml.SafeLoader`` that refuses a key given twice in one mapping (a ``<<`` merge may
    still override merged keys, as YAML intends)."""
    import yaml

    class UniqueKeyLoader(yaml.SafeLoader):
        def construct_mapping(self, node, deep=False):
            seen = set()
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=True)
                if not isinstance(key, Hashable):
                    continue  # the base constructor refuses it with its own message
                if key in seen:
                    raise DuplicateKeyError(key)
                seen.add(key)
            return super().construct_mapping(node, deep)

    return UniqueKeyLoader


def nesting_depth(doc, limit: int = MAX_DEPTH) -> int:
    """How deeply lists and objects nest in ``doc`` (a scalar: 0), counted without recursion
    and up to ``limit + 1``."""
    deepest, stack = 0, [(doc, 1)]
    while stack:
        node, depth = stack.pop()
        children = node.values() if isinstance(node, dict) else node if isinstance(node, (list, tuple)) else None
        if children is None:
            continue
        deepest = max(deepest, depth)
        if deepest > limit:
            break
        stack.extend((child, depth + 1) for child in children)
    return deepest


def check_nesting(doc, where: str, what: str) -> None:
    """An :class:`InvalidParameterError` naming ``where`` when ``doc`` nests deeper than :data:`MAX_DEPTH`."""
    if nesting_depth(doc) > MAX_DEPTH:
        raise InvalidParameterError(f"{where}: not a {what}: lists or objects nested more than {MAX_DEPTH} levels deep")


def parse_document(text: str, where: str, what: str = "robot file", yaml_text: bool = False) -> object:
    """The parsed JSON (or YAML) ``text``, or an :class:`InvalidParameterError` naming ``where``
    (the file) and what is wrong: malformed, a key given twice in one object, nested deeper than
    :data:`MAX_DEPTH`. The one parser of every document robocal reads (robot files, results,
    parameter tables, diagnose reports)."""
    if yaml_text:
        import yaml

        parse, malformed, language = (lambda t: yaml.load(t, Loader=_yaml_loader())), yaml.YAMLError, "YAML"
    else:
        parse, malformed, language = (lambda t: json.loads(t, object_pairs_hook=_unique_object)), ValueError, "JSON"
    try:
        doc = parse(text)
    except DuplicateKeyError as exc:
        raise InvalidParameterError(f"{where}: key {exc.key!r} appears twice in one object: which value is meant cannot be guessed") from None
    except RecursionError:
        raise InvalidParameterError(f"{where}: not a {what}: lists or objects nested too deeply to read") from None
    except (UnicodeDecodeError, malformed) as exc:
        raise InvalidParameterError(f"{where}: not a {what} (invalid {language}: {str(exc)[:200]})") from None
    check_nesting(doc, where, what)
    return doc


def read_document(path, what: str = "robot file") -> object:
    """The parsed JSON or YAML (by suffix) of ``path`` (:func:`parse_document`), or an error naming
    the file; only a regular file is read (a FIFO or a device would block or never end), up to
    :data:`robocal.files.MAX_FILE_BYTES` (:func:`read_file`)."""
    path = Path(path)
    text = read_file(path, what)
    return parse_document(text, str(path), what, yaml_text=path.suffix.lower() in (".yaml", ".yml"))


def load_document(source, what: str, called: str) -> object:
    """The document ``source`` gives: the parsed file at a path (:func:`read_document`) or a
    document already loaded (a dict), which is checked as a file's would be (:func:`check_nesting`).
    ``what`` names the kind of file (``"robocal result file"``), ``called`` how messages name a
    document given as a dict (``"result"``).

    Raises
    ------
    InvalidParameterError
        For anything but a path or a dict, or naming the file (or ``called``) and what is wrong with it.
    """
    if isinstance(source, dict):
        check_nesting(source, called, what)
        return source
    if not isinstance(source, (str, os.PathLike)):
        raise InvalidParameterError(f"a {called} must be a {what} path or its document (dict); got {type(source).__name__} {source!r}")
    return read_document(source, what)


def read_file(path, what: str = "robot file") -> str:
    """The UTF-8 text of the ``what`` at ``path`` (:func:`robocal.files.read_regular`), a BOM dropped (an editor's, as
    the CSV reader drops it: JSON refused it), or an :class:`InvalidParameterError` naming the file and what is wrong
    with it."""
    data = read_regular(path, lambda problem: InvalidParameterError(f"{path}: {problem}"), what=what)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InvalidParameterError(f"{path}: not a {what} (not UTF-8 text: undecodable byte at offset {exc.start})") from None


def read_robot_file(path) -> Robot:
    """The robot of a robot file (JSON or YAML), of a result file (the calibrated robot) or of a
    result's ``robot_model`` section saved on its own.

    Checked strictly (:class:`robocal.schemas.RobotSpec`): an unknown key, a wrong type or a bad
    value is an :class:`InvalidParameterError` naming the file, the joint and the key.
    """
    path = Path(path)
    doc = read_document(path)
    if isinstance(doc, dict) and doc.get("schema") == RESULT_SCHEMA:
        return calibrated_robot(doc, str(path))
    from .schemas import RobotModel, RobotSpec, validate

    if isinstance(doc, dict) and "nominal" in doc and "units" not in doc:  # an older result's robot_model
        return robot_from_model(validate(RobotModel, doc, str(path)), str(path))
    if isinstance(doc, dict) and "nominal" in doc:
        doc = {k: v for k, v in doc.items() if k != "nominal"}  # a robot_model: its document is the robot
    return robot_from_spec(validate(RobotSpec, doc, str(path)), path.stem, str(path))


def write_robot_file(robot: Robot, path, degrees: bool = False) -> Path:
    """Writes :func:`robot_document` as YAML (``.yaml``/``.yml``) or JSON (anything else)."""
    path = Path(path)
    doc = robot_document(robot, degrees)
    if path.suffix.lower() in (".yaml", ".yml"):
        import yaml

        return write_text(path, yaml.safe_dump(doc, sort_keys=False))
    return write_json(path, doc)
