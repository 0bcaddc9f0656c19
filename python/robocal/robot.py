"""Robots by name or file: the one loader that knows every robot format.

:func:`robot` gives a built-in robot by name or reads a robot file (JSON or YAML,
:mod:`robocal.robot_file`), an exported parameter table (:mod:`robocal.robot_table`) or a URDF
(:mod:`robocal.urdf`); :func:`write_robot` writes a robot file. The roboticstoolbox bridge is
:mod:`robocal.rtb`. A new robot file format is a module beside those, dispatched here.

The type itself, :class:`Robot` with its :class:`Joint` rows, lives below every format in
:mod:`robocal.serial_robot` and is re-exported here.
"""

from __future__ import annotations

from pathlib import Path

from . import robot_table
from .catalog import BUILTIN
from .exceptions import InvalidParameterError
from .robot_file import read_robot_file, write_robot_file
from .serial_robot import MEASUREMENTS, RESIDUAL_WIDTH, Joint, MassModel, Robot, setup_names, zero_names
from .urdf import read_urdf

__all__ = ["MEASUREMENTS", "RESIDUAL_WIDTH", "Joint", "MassModel", "Robot", "robot", "setup_names", "write_robot", "zero_names"]


def robot(name: str | Path) -> Robot:
    """A built-in robot by name (``hsr-jr680``, ``abb-irb120``, ``ur10``), a robot file (JSON or
    YAML, schema ``robocal.robot/1``: :func:`robocal.robot_file.read_robot_file`; a result file
    gives its calibrated robot), a parameter table ``robocal export --format dh|mdh`` wrote (CSV,
    or JSON with the table's schema: :mod:`robocal.robot_table`) or a URDF
    (:func:`robocal.urdf.read_urdf`, what ``export --format urdf`` writes too).

    A robot file holds ``joints`` (each ``alpha``, ``a``, ``d``, ``theta`` and optional ``beta``,
    ``convention``, ``kind``, ``hayati``, ``limits``) and optional ``name``, ``units`` (lengths
    mm; angles ``deg`` by default or ``rad``), ``convention`` (the joints' default, ``dh``),
    ``base``, ``tool`` (``x, y, z, rx, ry, rz``), ``sensor`` and ``masses``: docs/data-format.md.
    It is checked strictly (:class:`robocal.schemas.RobotSpec`): an unknown key, a wrong type or
    a bad value is an :class:`InvalidParameterError` naming the file, the joint and the key.
    """
    if not isinstance(name, (str, Path)):
        raise InvalidParameterError(f"`robot` must be a robot name or a .json/.yaml/.csv/.urdf file; got {type(name).__name__} {name!r}")
    if name in BUILTIN:
        return Robot.from_dh(name, BUILTIN[name]["dh"])
    suffix = Path(name).suffix.lower()
    if suffix == ".urdf":
        return read_urdf(name)
    if suffix in (".csv", ".json") and robot_table.is_table(name):
        return robot_table.robot_from_table(robot_table.read_table(name), name=Path(name).stem, source=name)
    if suffix in (".json", ".yaml", ".yml"):
        return read_robot_file(name)
    builtin = sorted(BUILTIN)
    raise InvalidParameterError(
        f"unknown robot {name!r}; built-in robots are {builtin} (or give a .json/.yaml robot or result file, an exported .csv/.json table or a .urdf)"
    )


def write_robot(robot: Robot, path: str | Path, *, degrees: bool = False) -> Path:
    """Writes every field of ``robot`` as a robot file (YAML for ``.yaml``/``.yml``, JSON
    otherwise) that :func:`robot` reads back exactly (angles in rad; ``degrees`` writes degrees,
    back to within one unit in the last place). Returns the path written."""
    return write_robot_file(robot, path, degrees)
