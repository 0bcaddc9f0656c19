"""Export a calibrated robot: a DH / MDH parameter table (CSV or JSON), a URDF for ROS, or
Universal Robots' kinematics file.

``robocal export RESULT --format {dh,mdh,urdf,ur-yaml} [--table-format {csv,json}] --out FILE`` reads a
calibration result file (schema ``robocal.result/1``, see :mod:`robocal.results`), writes the
calibrated kinematics in the asked form and then *checks* what it wrote: it reads the file back
with the reader ``robocal.robot`` uses for it (one URDF reader, :mod:`robocal.urdf`), and
compares the tool frame of what it read with the calibrated model's on random joint vectors
within the joint limits (:func:`roundtrip_check`). The command fails (exit
code 1) when the round trip is off by more than :data:`POSITION_TOL` (mm) or
:data:`ROTATION_TOL` (rad) — an export that does not reproduce the calibration is not written
off as done.

Parameter table (``--format dh`` or ``mdh``)
--------------------------------------------
One row per joint, then one row ``base`` and one row ``tool``; the columns (:data:`TABLE_COLUMNS`):

``frame``
    ``joint1`` … ``jointN``, ``base``, ``tool``.
``kind``, ``convention``, ``hayati``
    Joint rows only: ``revolute``/``prismatic``, ``dh``/``mdh``, ``true``/``false`` (the joint
    is flagged for Hayati's ``beta``).
``alpha_deg, a_mm, d_mm, theta_deg, beta_deg``
    Joint rows only. ``theta_deg`` is the joint's zero offset (the joint variable adds to it;
    to ``d_mm`` on a prismatic joint). ``beta_deg`` is Hayati's rotation about y; it is 0
    unless the calibration estimated it.
``lower, upper``
    Joint rows only: the joint range, deg (mm for a prismatic joint).
``x_mm, y_mm, z_mm, rx_deg, ry_deg, rz_deg``
    ``base`` and ``tool`` rows only, in robocal's frame convention
    ``Tx(x)·Ty(y)·Tz(z)·Rz(rz)·Ry(ry)·Rx(rx)``: a translation, then roll ``rx``, pitch ``ry``,
    yaw ``rz`` about the *fixed* axes — the same convention as URDF's ``rpy``. ``base`` places
    the chain in the measurement (world) frame, ``tool`` the tool frame on the flange.

Standard DH is ``Rz(theta+q)·Tz(d)·Tx(a)·Rx(alpha)·Ry(beta)`` per joint, modified DH (Craig)
``Rx(alpha)·Tx(a)·Ry(beta)·Rz(theta+q)·Tz(d)``; the tool pose is
``Base · Link_1(q_1) ⋯ Link_N(q_N) · Tool``. ``--format mdh`` converts with
:meth:`robocal.Robot.to_mdh`, which is exact for the tool frame (the last DH link's
``Tx(a_N)·Rx(alpha_N)·Ry(beta_N)`` moves into ``tool``, so the MDH *flange* frame differs).
Cells that do not apply are empty in CSV and ``null`` in JSON. Numbers are written with
Python's shortest round-trip representation (``repr``), so nothing is lost to formatting.

Load the CSV with pandas::

    df = pd.read_csv("robot_dh.csv", index_col="frame")
    joints = df.loc[df.index.str.startswith("joint"), ["alpha_deg", "a_mm", "d_mm", "theta_deg", "beta_deg"]]
    base = df.loc["base", ["x_mm", "y_mm", "z_mm", "rx_deg", "ry_deg", "rz_deg"]]

The JSON form is ``{"schema": "robocal.export.table/1", "robot": ..., "convention": ...,
"units": {...}, "frame_convention": ..., "rows": [...]}`` with the same rows
(``pd.DataFrame(doc["rows"])``). :func:`read_table` and :func:`robot_from_table` read either
back into a :class:`robocal.Robot`.

URDF (``--format urdf``)
------------------------
Links ``[world,] base_link, link1 … linkN, flange, tool0``; joints ``joint1 … jointN``
(``revolute``, or ``prismatic`` on a prismatic joint) about / along their local z axis, whose
``<origin xyz rpy>`` is the constant transform from the previous joint's moving frame to this
joint's axis frame: everything of the chain between the two joint variables, including this
joint's ``theta`` (``d`` when prismatic) offset, because URDF has no joint offset. So URDF
joint position = robocal joint value = the controller's reading, and the calibrated zero
offsets live in the origins. For standard DH, ``origin_j = Tz(d_{j-1})·Tx(a_{j-1})·
Rx(alpha_{j-1})·Ry(beta_{j-1})·Rz(theta_j)`` (``Base·Rz(theta_1)`` for joint 1 when there is
no ``world`` link). Fixed joints: ``world → base_link`` carries the base frame (only when it is
not the identity), ``link_N → flange`` the rest of the last link, ``flange → tool0`` the tool
frame. URDF units are metres and radians (robocal's are mm): positions are divided by 1000 and
written with ``repr``; ``rpy`` is the fixed-axis roll-pitch-yaw (``R = Rz(yaw)·Ry(pitch)·
Rx(roll)``). Links carry no inertia or geometry, and a joint's ``effort`` and ``velocity``
limits are not known from a calibration: they are written as 0 (override them, e.g. in
MoveIt's ``joint_limits.yaml``).

``robocal.robot(file)`` reads such a URDF back with its ``flange`` link as the flange frame
(``fkine(q)``) and ``tool0`` as the tool frame (``fkine(q, tool=True)``), as the exporting robot
has them. Reading it back — for the round-trip check too — needs yourdfpy (``pip install
'robocal[urdf]'``), the maintained URDF parser robocal reads every URDF with.

UR kinematics file (``--format ur-yaml``)
-----------------------------------------
The ``kinematics:`` YAML of Universal Robots' ``ur_description`` (``shoulder`` … ``wrist_3``,
each ``x y z roll pitch yaw`` in m and rad, and ``hash``), written at the controller's joint
readings (a ``joint_zero`` reading convention folded in), with the part after the last joint
that the file cannot hold reported as the pendant's TCP: see :mod:`robocal.ur_kinematics`. Its
round trip reads the file back into UR's chain and compares it with the calibrated robot in
``base_link`` (:func:`robocal.ur_kinematics.ur_reference`): the measurement set-up (``base``) is
not part of the robot.
"""

from __future__ import annotations

import csv
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from .causes import structure
from .causes.candidates import COMPENSABLE, JOINT_KINDS, joint_offsets
from .kernels import MAX_SAMPLES, as_count, seeded_rng
from .outputs import Staged, write_json, write_text
from .exceptions import InvalidParameterError
from .geometry import chain_ops, frame_params, frame_transform, rotation, so3_log
from .serial_robot import Robot
from .robot_table import TABLE_COLUMNS, TABLE_SCHEMA, export_table, frame_slice, read_table, robot_from_table
from .urdf import read_urdf, require_yourdfpy, robot_from_urdf
from .ur_kinematics import is_ur_yaml, read_ur_yaml, ur_kinematics, ur_reference, ur_yaml_text

FORMATS = ("dh", "mdh", "urdf", "ur-yaml")
TABLE_FORMATS = ("csv", "json")

#: Largest tool-position difference (mm) the round trip of an export may show.
POSITION_TOL = 1e-6
#: Largest tool-rotation difference (rad) the round trip of an export may show.
ROTATION_TOL = 1e-9


# ---------------------------------------------------------------------------------------------
# Parameter table
# ---------------------------------------------------------------------------------------------


def table_format_of(path, table_format: Optional[str]) -> str:
    """``table_format``, or the one the suffix of ``path`` says (``.json``: JSON, else CSV)."""
    path = Path(path)
    if table_format is None:
        return "json" if path.suffix.lower() == ".json" else "csv"
    if table_format not in TABLE_FORMATS:
        raise InvalidParameterError(f"`table_format` must be one of {TABLE_FORMATS}; got {table_format!r}")
    return table_format


def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    return str(value)


def write_table(rows: Sequence[dict], path, table_format: Optional[str] = None, name: Optional[str] = None, notes: Sequence[str] = ()) -> Path:
    """Writes the rows of :func:`export_table` as CSV or JSON.

    Parameters
    ----------
    rows : sequence of dict
    path : str or Path
    table_format : {"csv", "json"}, optional
        By default from the suffix of ``path`` (``.json`` → JSON, anything else CSV).
    name : str, optional
        The robot's name, recorded in the JSON form.
    notes : sequence of str
        What the table does not carry (:func:`deliverable`): the JSON form's ``notes``; a CSV
        has no place for them.

    Returns
    -------
    Path
    """
    path = Path(path)
    fmt = table_format_of(path, table_format)
    if fmt == "csv":
        with Staged(path) as stage, stage.tmp.open("w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(TABLE_COLUMNS)
            for row in rows:
                writer.writerow([_cell(row.get(c)) for c in TABLE_COLUMNS])
    else:
        conventions = sorted({r["convention"] for r in rows if r.get("convention")})
        doc = {
            "schema": TABLE_SCHEMA,
            "robot": name,
            "convention": conventions[0] if len(conventions) == 1 else conventions,
            "units": {"length": "mm", "angle": "deg", "limits": "deg (revolute), mm (prismatic)"},
            "frame_convention": "Tx(x) Ty(y) Tz(z) Rz(rz) Ry(ry) Rx(rx)",
            "rows": [{c: row.get(c) for c in TABLE_COLUMNS} for row in rows],
            **({"notes": list(notes)} if notes else {}),
        }
        write_json(path, doc)
    return path


# ---------------------------------------------------------------------------------------------
# URDF
# ---------------------------------------------------------------------------------------------
def _elementary(rotation_op: bool, axis: int, value: float) -> np.ndarray:
    T = np.eye(4)
    if rotation_op:
        T[:3, :3] = rotation(axis, value)
    else:
        T[axis, 3] = value
    return T


def urdf_segments(robot: Robot) -> tuple[np.ndarray, list[np.ndarray], np.ndarray, np.ndarray]:
    """The chain regrouped around the joint variables, in mm and rad.

    ``Base · Link_1(q_1) ⋯ Link_N(q_N) · Tool = base · Π_j (origins[j] · Z_j(q_j)) · flange · tool``
    exactly, where ``Z_j`` is ``Rz(q_j)`` (``Tz(q_j)`` for a prismatic joint) and each origin
    holds everything of the chain between two joint variables, joint ``j``'s own offset
    (``Rz(theta_j)`` or ``Tz(d_j)``) last — ``Rz(theta+q) = Rz(theta)·Rz(q)``.

    Returns
    -------
    base : ndarray, shape (4, 4)
    origins : list of ndarray, shape (4, 4), one per joint
    flange : ndarray, shape (4, 4)
        What follows the last joint variable up to the flange.
    tool : ndarray, shape (4, 4)
    """
    ops, flange_end = chain_ops([j.convention for j in robot.joints], [j.kind for j in robot.joints])
    p = robot.params
    base = frame_transform(p[frame_slice(robot, "base")])
    tool = frame_transform(p[frame_slice(robot, "tool")])
    origins, pending = [], np.eye(4)
    for op in ops[6:flange_end]:  # the base's six ops come first
        pending = pending @ _elementary(op.rotation, op.axis, float(p[op.param]))
        if op.joint is not None:
            if op.axis != 2:  # every joint variable acts about / along local z in chain_ops
                raise InvalidParameterError(f"joint {op.joint + 1}: its variable does not act along z; URDF export needs it to")
            origins.append(pending)
            pending = np.eye(4)
    return base, origins, pending, tool


def _origin(parent: ET.Element, T: Optional[np.ndarray] = None, xyz_mm=None, rpy=None) -> None:
    xyz_mm = T[:3, 3] if xyz_mm is None else xyz_mm
    rpy = frame_params(T)[3:] if rpy is None else rpy  # URDF's rpy is robocal's rx, ry, rz
    ET.SubElement(parent, "origin", xyz=" ".join(repr(float(v) / 1000.0) for v in xyz_mm), rpy=" ".join(repr(float(v)) for v in rpy))


def _fixed_joint(root: ET.Element, name: str, parent: str, child: str, **origin) -> None:
    joint = ET.SubElement(root, "joint", name=name, type="fixed")
    ET.SubElement(joint, "parent", link=parent)
    ET.SubElement(joint, "child", link=child)
    _origin(joint, **origin)


def export_urdf(robot: Robot, name: Optional[str] = None, effort: float = 0.0, velocity: float = 0.0, notes: Sequence[str] = ()) -> str:
    """A URDF of the robot whose chain ``base_link → tool0`` reproduces its tool frame exactly.

    See the module docstring for the layout. Revolute joints become ``revolute`` URDF joints
    about z, prismatic joints ``prismatic`` joints along z (limits in metres).

    Parameters
    ----------
    robot : Robot
        DH, MDH or mixed; the calibrated robot of :func:`robocal.results.load_result`.
    name : str, optional
        The URDF robot name (default ``robot.name``).
    effort, velocity : float
        The ``<limit>`` attributes URDF requires; a calibration does not know them.
    notes : sequence of str
        What the file does not carry (:func:`deliverable`), written as comments.

    Returns
    -------
    str
        The URDF document (XML, UTF-8 declaration).
    """
    base, origins, flange, tool = urdf_segments(robot)
    p = robot.params
    root = ET.Element("robot", name=name or robot.name)
    comment = (
        " written by robocal export: calibrated kinematics. Lengths in m, angles in rad. Joint zero offsets are folded "
        "into the joint origins (joint position = robocal joint value). Links carry no inertia or geometry; effort and "
        "velocity limits are not known from a calibration. "
    )
    root.append(ET.Comment(comment))
    for note in notes:
        root.append(ET.Comment(" " + note.replace("--", "- -") + " "))  # "--" may not appear in an XML comment
    base_values = p[frame_slice(robot, "base")]
    links = (["world"] if np.any(base_values != 0.0) else []) + ["base_link"] + [f"link{j}" for j in range(1, robot.n_joints + 1)] + ["flange", "tool0"]
    for link in links:
        ET.SubElement(root, "link", name=link)
    if links[0] == "world":
        # robocal's base frame Tx Ty Tz Rz Ry Rx is URDF's xyz + rpy as it stands.
        _fixed_joint(root, "world-base_link", "world", "base_link", xyz_mm=base_values[:3], rpy=base_values[3:])
    parent = "base_link"
    for j, (joint, origin) in enumerate(zip(robot.joints, origins), start=1):
        el = ET.SubElement(root, "joint", name=f"joint{j}", type=joint.kind)
        ET.SubElement(el, "parent", link=parent)
        ET.SubElement(el, "child", link=f"link{j}")
        _origin(el, origin)
        ET.SubElement(el, "axis", xyz="0 0 1")
        scale = 1.0 if joint.kind == "revolute" else 1e-3
        lower, upper = (float(v) * scale for v in joint.limits)
        ET.SubElement(el, "limit", lower=repr(lower), upper=repr(upper), effort=repr(float(effort)), velocity=repr(float(velocity)))
        parent = f"link{j}"
    _fixed_joint(root, f"link{robot.n_joints}-flange", parent, "flange", T=flange)
    tool_values = p[frame_slice(robot, "tool")]
    _fixed_joint(root, "flange-tool0", "flange", "tool0", xyz_mm=tool_values[:3], rpy=tool_values[3:])
    ET.indent(root, space="  ")
    return '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


# ---------------------------------------------------------------------------------------------
# Round trip
# ---------------------------------------------------------------------------------------------
def _exported_robot(exported) -> tuple[Robot, str]:
    """The robot an export holds, read back by robocal's readers, and which form it is."""
    if isinstance(exported, (list, tuple)):
        return robot_from_table(exported), "table"
    if isinstance(exported, str) and exported.lstrip().startswith("<"):
        return robot_from_urdf(exported, where="the exported URDF"), "urdf"
    path = Path(exported)
    text = path.read_text()
    if text.lstrip().startswith("<"):
        return read_urdf(path), "urdf"
    if is_ur_yaml(text):
        return read_ur_yaml(path), "ur-yaml"
    return robot_from_table(read_table(path), source=path), "table"


def roundtrip_check(robot: Robot, exported, samples: int = 200, seed: int = 0, structures: Sequence = ()) -> dict:
    """How closely an export reproduces ``robot``'s tool frame.

    Draws ``samples`` joint vectors uniformly within the joint limits (seeded), computes the
    tool pose from the export alone and from ``robot.fkine(q, tool=True)``, and returns the
    largest differences. With reading conventions ``structures`` the export is read at the
    controller's readings of those angles (``structure.to_readings``), as it is meant to be.

    Parameters
    ----------
    robot : Robot
        The calibrated robot.
    exported : list of dict, str or Path
        Table rows (:func:`export_table`), URDF text, or the path of a written table (CSV /
        JSON), URDF or UR kinematics file. Either is read back into a :class:`Robot` by the reader
        ``robocal.robot`` uses for it: :func:`robocal.urdf.robot_from_urdf` (yourdfpy's parse,
        then the chain's DH form) or :func:`robot_from_table`; a UR kinematics file by
        :func:`robocal.ur_kinematics.read_ur_yaml` (UR's chain, in ``base_link``, at the
        controller's readings: compare it with :func:`robocal.ur_kinematics.ur_reference`).
    samples : int
    seed : int

    Returns
    -------
    dict
        ``max_position_error_mm``, ``max_rotation_error_rad`` (angle of ``R_robot^T R_export``),
        ``samples`` and ``representation`` (``table`` / ``urdf`` / ``ur-yaml``).
    """
    samples = as_count(samples, "samples", most=MAX_SAMPLES)
    rng = seeded_rng(seed)
    lo = np.array([j.limits[0] for j in robot.joints])
    hi = np.array([j.limits[1] for j in robot.joints])
    q = lo + (hi - lo) * rng.random((samples, robot.n_joints))
    want = robot.fkine(q, tool=True)
    exported_robot, representation = _exported_robot(exported)
    got = exported_robot.fkine(structure.to_readings(q, list(structures)), tool=True)
    pos = np.linalg.norm(got[:, :3, 3] - want[:, :3, 3], axis=1)
    rot = np.linalg.norm(so3_log(np.swapaxes(want[:, :3, :3], -1, -2) @ got[:, :3, :3]), axis=1)
    return {
        "max_position_error_mm": float(pos.max()),
        "max_rotation_error_rad": float(rot.max()),
        "samples": int(samples),
        "representation": representation,
    }


#: The suffixes :func:`robocal.robot` reads each export under (it tells the formats apart by
#: suffix; a table under .csv is told CSV or JSON by its content).
READ_BACK_SUFFIXES = {"urdf": (".urdf",), "csv": (".csv",), "json": (".json", ".csv")}


def suffix_note(fmt: str, out, table_format: Optional[str] = None) -> Optional[str]:
    """A note when ``out``'s suffix is not the one :func:`robocal.robot` reads this export by
    (``--format urdf --out e.csv``: the file is fine, but read back as a table it fails), else None."""
    form = "urdf" if fmt == "urdf" else table_format_of(Path(out), table_format)
    suffix = READ_BACK_SUFFIXES[form][0]
    if Path(out).suffix.lower() in READ_BACK_SUFFIXES[form]:
        return None
    what = "URDF" if form == "urdf" else f"a {form.upper()} table"
    return f"{out} holds {what} under another suffix; robocal reads a robot file by its suffix (--robot, robocal.robot): rename it to *{suffix} to read it back"


def export(robot: Robot, fmt: str, out, table_format: Optional[str] = None, name: Optional[str] = None, notes: Sequence[str] = ()) -> Path:
    """Writes ``robot`` in format ``fmt`` (``dh``, ``mdh``, ``urdf`` or ``ur-yaml``) to ``out``,
    with ``notes`` where the format has room for them. Its joint variables are the file's: a
    result's reading conventions are folded in before (:func:`deliverable`)."""
    if fmt not in FORMATS:
        raise InvalidParameterError(f"`format` must be one of {FORMATS}; got {fmt!r}")
    out = Path(out)
    if fmt == "ur-yaml":
        if table_format is not None:
            raise InvalidParameterError("--table-format applies to --format dh and mdh, not ur-yaml")
        return write_text(out, ur_yaml_text(ur_kinematics(robot, urdf_segments(robot)), robot_name=name or robot.name))
    if fmt == "urdf":
        if table_format is not None:
            raise InvalidParameterError("--table-format applies to --format dh and mdh, not urdf")
        return write_text(out, export_urdf(robot, name=name, notes=notes))
    return write_table(export_table(robot, fmt), out, table_format, name=name or robot.name, notes=notes)


def export_checked(
    robot: Robot,
    fmt: str,
    out,
    table_format: Optional[str] = None,
    name: Optional[str] = None,
    samples: int = 200,
    seed: int = 0,
    delivered: Optional["Deliverable"] = None,
) -> tuple[dict, list[str]]:
    """:func:`export` then :func:`roundtrip_check` of what it wrote: the check and the tolerances
    it breaks (then nothing is written).

    ``delivered`` (:func:`deliverable` of a result) writes its robot, at the controller's
    readings, with its notes, and checks it against its geometry at the model's angles; else
    ``robot`` is written as it is.
    The file is written to a temporary beside ``out`` and replaces it only once its round trip
    passes: a failed export never overwrites a previous good one. A ``ur-yaml`` file is checked
    against :func:`robocal.ur_kinematics.ur_reference` (the robot in ``base_link``).
    """
    samples = as_count(samples, "samples", most=MAX_SAMPLES)  # before anything is written
    if fmt == "urdf":
        require_yourdfpy("checking a URDF export (it is read back)")
    table_format = table_format_of(Path(out), table_format) if fmt in ("dh", "mdh") else table_format
    delivered = delivered or Deliverable(robot, robot, [], [])
    if fmt == "ur-yaml":
        turned = [s.label for s in delivered.structures if s.kind != "joint_zero"]
        if turned:  # a UR joint turns one way about its axis, read from its own zero
            raise InvalidParameterError(f"--format ur-yaml: UR's kinematics file cannot carry {', '.join(turned)}: a UR joint is read in its own direction")
    with Staged(out) as stage:
        export(delivered.written, fmt, stage.tmp, table_format=table_format, name=name, notes=delivered.notes)
        reference = ur_reference(delivered.geometry) if fmt == "ur-yaml" else delivered.geometry
        check = roundtrip_check(reference, stage.tmp, samples=samples, seed=seed, structures=delivered.structures)
        failed = []
        if not check["max_position_error_mm"] <= POSITION_TOL:
            failed.append(f"position error {check['max_position_error_mm']:.3g} mm > {POSITION_TOL:g} mm")
        if not check["max_rotation_error_rad"] <= ROTATION_TOL:
            failed.append(f"rotation error {check['max_rotation_error_rad']:.3g} rad > {ROTATION_TOL:g} rad")
        if failed:
            stage.discard()
    return check, failed


# ---------------------------------------------------------------------------------------------
# What a result delivers
# ---------------------------------------------------------------------------------------------
@dataclass
class Deliverable:
    """What an export of a result writes: ``written``, the robot whose joint variables are what
    the file's user feeds it (the controller's readings, unless asked for the model's angles);
    ``geometry``, the measured geometry at the model's angles, which the round trip holds it to;
    ``structures``, the reading conventions between the two; ``notes``, what the file does not
    carry and what that costs."""

    written: Robot
    geometry: Robot
    structures: list
    notes: list


#: Joint vectors within the limits on which a cause's effect at the tool is measured.
COST_SAMPLES = 500


def _geometry(robot: Robot, doc: dict) -> tuple[Robot, list[str]]:
    """The geometry an export of result ``doc`` carries and the notes on what it leaves out."""
    carried_by_joints = [c for c in doc.get("causes", []) if c.get("kind") in JOINT_KINDS]
    if not carried_by_joints:
        return robot, []
    labels = [str(c.get("label", c.get("kind"))) for c in carried_by_joints]
    notes = [f"not carried (a joint-by-joint geometry has no place for them): {', '.join(labels)}"]
    record = doc.get("geometry_only")
    if not isinstance(record, dict):  # a result written before calibrate fitted the geometry alone
        notes.append("the geometry is the extended fit's, fitted with those causes; calibrate again for the best geometry without them")
        offsets = joint_offsets(robot, carried_by_joints, kinds=COMPENSABLE)
        if offsets is not None:  # what leaving them out costs this geometry anywhere within the limits
            lower, upper = (np.array([j.limits[k] for j in robot.joints]) for k in (0, 1))
            q = lower + (upper - lower) * seeded_rng(0).random((COST_SAMPLES, robot.n_joints))
            moved = np.linalg.norm(robot.fkine(q + offsets(q), tool=True)[:, :3, 3] - robot.fkine(q, tool=True)[:, :3, 3], axis=1)
            notes.append(
                f"without them it is off by {np.sqrt(np.mean(moved**2)):.3g} mm RMS (at most {moved.max():.3g} mm) over {COST_SAMPLES} joint vectors within the limits"
            )
        return robot, notes
    values = np.asarray(record.get("parameters", []), dtype=np.float64)
    if values.shape != robot.params.shape or not np.all(np.isfinite(values)):
        raise InvalidParameterError(f"result: key 'geometry_only', key 'parameters' must be {robot.params.size} finite numbers; got {values.size}")
    what = "fitted again without them" if record.get("choice") == "refit" else "the extended fit's, without them"
    notes.append(f"the geometry is {what}: {record.get('why')}")
    held = record.get("held_out") or {}
    chosen, full = held.get(record.get("choice")), held.get("full_model")
    if chosen and full:
        notes.append(
            f"on the calibration's held-out samples it predicts at RMSE {chosen['rmse']:.4g} mm; the full model at {full['rmse']:.4g} mm (robocal compensate applies it)"
        )
    return Robot(robot.name, robot.joints, values, mass_model=robot.mass_model), notes


def deliverable(robot: Robot, doc: dict, angles: str = "readings") -> Deliverable:
    """What an export of the result ``doc`` (calibrated ``robot``, :func:`robocal.results.load_result`) writes.

    - **Geometry**: a result with joint causes (compliance, maps, ...) exports the geometry its
      ``geometry_only`` record chose (the best geometry without them, by the held-out samples),
      with notes naming the causes left out and their cost in mm.
    - **Readings**: with ``angles="readings"`` (default) the result's reading conventions are
      folded in (:func:`robocal.causes.structure.robot_at_readings`), so the file works at the
      controller's readings; ``"model"`` writes the model's angles and says so.
    """
    if angles not in ("readings", "model"):
        raise InvalidParameterError(f"`angles` must be 'readings' or 'model'; got {angles!r}")
    geometry, notes = _geometry(robot, doc)
    structures = structure.parse_all(doc.get("structure", []), robot.n_joints)
    if not structures:
        return Deliverable(geometry, geometry, [], notes)
    labels = ", ".join(s.label for s in structures)
    if angles == "model":
        return Deliverable(geometry, geometry, [], notes + [f"joint values are the model's angles, not the controller's readings ({labels})"])
    written = structure.robot_at_readings(geometry, structures)
    return Deliverable(written, geometry, structures, notes + [f"joint values are the controller's readings: {labels} folded into the joints"])
