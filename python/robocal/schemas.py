"""Strict schemas of the files robocal reads as documents: robot files and result files.

pydantic models in strict mode: an unknown key, a value of the wrong type (``"hayati": "no"``,
``"a": true``, ``"value": "250"``) or a value outside its domain (``"kind": "spherical"``, a
non-finite number) is an error — nothing is coerced or dropped silently. :func:`validate` turns
pydantic's error into one :class:`~robocal.exceptions.InvalidParameterError` naming the file, the
joint or parameter and the key.

pydantic (rather than jsonschema, also installed) because the models are typed Python that the
readers use directly, strict mode rejects the coercions listed above by construction, and each
error carries the location as a tuple that is turned into words here.
"""

from __future__ import annotations

from typing import Annotated, Any, List, Literal, Optional, Union

from pydantic import BaseModel, ConfigDict, Discriminator, Field, Tag, ValidationError, ValidationInfo, field_validator
from pydantic_core import PydanticCustomError

from .exceptions import InvalidParameterError

_STRICT = ConfigDict(strict=True, extra="forbid", allow_inf_nan=False)
_OPEN = ConfigDict(strict=True, extra="allow")  # results may hold NaN (an undetermined std)

Pair = List[float]


class JointSpec(BaseModel):
    """One joint of a robot document: DH / MDH values (lengths mm, angles in the document's
    ``units.angle``), limits (the angle unit; mm if prismatic)."""

    model_config = _STRICT
    alpha: float
    a: float
    d: float
    theta: float
    beta: float = 0.0
    limits: Optional[Pair] = Field(default=None, min_length=2, max_length=2)  # None: ±180 deg (±180 mm if prismatic), in any angle unit
    hayati: bool = False
    kind: Literal["revolute", "prismatic"] = "revolute"
    convention: Optional[Literal["dh", "mdh"]] = None


class FrameSpec(BaseModel):
    """The base or tool frame ``Tx(x) Ty(y) Tz(z) Rz(rz) Ry(ry) Rx(rx)``: mm and the angle unit."""

    model_config = _STRICT
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    rx: float = 0.0
    ry: float = 0.0
    rz: float = 0.0


class SensorSpec(BaseModel):
    """The cable sensor's nominal set-up: anchor (mm), zero offset (mm) and scale."""

    model_config = _STRICT
    anchor_x: float = 0.0
    anchor_y: float = 0.0
    anchor_z: float = 0.0
    cable_offset: float = 0.0
    cable_scale: float = 1.0


class LinkMassSpec(BaseModel):
    """One link's mass (kg, > 0) and optional centre of mass (mm, ``[x, y, z]`` in the link's own
    DH frame; absent: the midpoint of the link's DH frame origins)."""

    model_config = _STRICT
    mass_kg: float = Field(gt=0)
    com_mm: Optional[Annotated[List[float], Field(min_length=3, max_length=3)]] = None


class MassesSpec(BaseModel):
    """A robot's masses for gravity torques: one link per joint, the rated payload (kg, for
    reference) and the default joint compliance (rad/(N·m))."""

    model_config = _STRICT
    links: List[LinkMassSpec] = Field(min_length=1)
    rated_payload_kg: float = Field(default=0.0, ge=0)
    compliance_rad_per_Nm: Optional[float] = Field(default=None, gt=0)


class Units(BaseModel):
    model_config = _STRICT
    length: Literal["mm"] = "mm"
    angle: Literal["deg", "rad"] = "deg"


class RobotSpec(BaseModel):
    """A robot document (schema ``robocal.robot/1``): a robot file (JSON or YAML) and the result
    file's ``robot_model``. Every key but ``joints`` (and their DH values) is optional, so robot
    files written before the schema had a name still read."""

    model_config = _STRICT
    schema_: Optional[Literal["robocal.robot/1"]] = Field(default=None, alias="schema")
    name: Optional[str] = None
    description: Optional[str] = None
    units: Units = Units()
    convention: Literal["dh", "mdh"] = "dh"
    joints: List[JointSpec] = Field(min_length=1)
    base: FrameSpec = FrameSpec()
    tool: FrameSpec = FrameSpec()
    sensor: SensorSpec = SensorSpec()
    masses: Optional[MassesSpec] = None

    @field_validator("masses")
    @classmethod
    def _one_link_per_joint(cls, masses: Optional[MassesSpec], info: ValidationInfo) -> Optional[MassesSpec]:
        joints = info.data.get("joints")
        if masses is not None and joints is not None and len(masses.links) != len(joints):
            raise PydanticCustomError("link_count", f"key 'links' has {len(masses.links)} entries; expected one per joint ({len(joints)})")
        return masses


class ResultRobotSpec(RobotSpec):
    """A result file's ``robot_model``: the robot document of the nominal robot, plus ``nominal``,
    the same values as a parameter vector (the form ``robocal.result/1`` files always had)."""

    nominal: Optional[List[float]] = None


class ModelJoint(BaseModel):
    model_config = _STRICT
    convention: Literal["dh", "mdh"]
    kind: Literal["revolute", "prismatic"]
    hayati: bool
    limits: Pair = Field(min_length=2, max_length=2)


class RobotModel(BaseModel):
    """The ``robot_model`` of result files written before the robot schema: joints without
    values and the nominal vector (limits in rad)."""

    model_config = _STRICT
    name: str
    joints: List[ModelJoint] = Field(min_length=1)
    nominal: List[float]


def _model_form(value) -> str:
    return "document" if isinstance(value, dict) and "units" in value else "vector"


AnyRobotModel = Annotated[Union[Annotated[ResultRobotSpec, Tag("document")], Annotated[RobotModel, Tag("vector")]], Discriminator(_model_form)]


class Parameter(BaseModel):
    model_config = _OPEN
    name: str
    unit: str
    nominal: float
    value: float
    std: Optional[float] = None
    deviation: Optional[float] = None


class Implausible(BaseModel):
    model_config = _OPEN
    name: str
    unit: str
    deviation: float
    limit: float


class Metrics(BaseModel):
    model_config = _OPEN
    rmse: Optional[float] = None
    mae: Optional[float] = None
    max: Optional[float] = None
    n: Optional[int] = None


class Provenance(BaseModel):
    model_config = _OPEN
    source: Optional[str] = None
    sha256: Optional[str] = None


class RemasteredJoint(BaseModel):
    """One joint of a re-mastering (:func:`robocal.remaster`): whether its zero moved, and by how much."""

    model_config = _OPEN
    joint: int = Field(ge=1)
    name: str
    unit: str
    status: Literal["moved", "held", "indistinguishable"]
    change: Optional[float] = None
    std: Optional[float] = None
    detectable_std: Optional[float] = None
    statistic: Optional[float] = None
    redundant_with: List[str] = []


class RemasterFit(BaseModel):
    model_config = _OPEN
    chi2: float
    dof: int
    p_value: Optional[float] = None


class RemasterReport(BaseModel):
    """The ``remaster`` key of a re-mastered result (``robocal calibrate NEW --prior RESULT``): the
    joints' verdicts, the test's threshold and noise, the new set-up and the points it was found on."""

    model_config = _OPEN
    joints: List[RemasteredJoint] = Field(min_length=1)
    alpha: float = Field(gt=0, lt=1)
    threshold: float
    noise_mm: float = Field(gt=0)
    noise_from: str
    result_error_counted: bool
    setup: dict[str, float]
    rmse: dict[str, float]
    fit: RemasterFit
    samples: int = Field(ge=1)
    data: Optional[str] = None
    sha256: Optional[str] = None
    fingerprint: Optional[dict] = None
    result: Optional[str] = None
    notes: List[str] = []


class ResultSpec(BaseModel):
    """The keys of a result file (``robocal.result/1``) that robocal reads back; others are kept."""

    model_config = _OPEN
    robot: Optional[str] = None
    measurement: Literal["cable", "position", "pose"]
    method: Optional[str] = None
    robot_model: AnyRobotModel
    parameters: List[Parameter]
    implausible: List[Implausible] = []
    metrics: dict[str, Optional[Metrics]] = {}
    fixed: dict[str, str] = {}
    causes: List[dict] = []
    convergence: dict[str, Any] = {}
    dataset: Optional[Provenance] = None
    remaster: Optional[RemasterReport] = None


def _where(loc: tuple, document: str) -> str:
    """``('joints', 2, 'hayatti')`` as ``joint 3, key 'hayatti'``."""
    words, i = [], 0
    loc = tuple(k for k in loc if k not in ("document", "vector"))  # the robot_model form's tag
    while i < len(loc):
        key = loc[i]
        if key in ("joints", "parameters", "implausible", "links", "effects", "sessions") and i + 1 < len(loc) and isinstance(loc[i + 1], int):
            words.append(f"{key.rstrip('s')} {loc[i + 1] + 1}")
            i += 2
        else:
            words.append(f"key {key!r}" if isinstance(key, str) else f"item {key + 1}")
            i += 1
    return ", ".join(words) or document


def validate(model: type[BaseModel], document, where: str) -> BaseModel:
    """``model.model_validate(document)``, or an error naming ``where`` (the file), the joint or
    parameter, the key, what was expected and (cut to a readable length) what was found."""
    try:
        return model.model_validate(document)
    except ValidationError as exc:
        errors = exc.errors(include_url=False)
        e = errors[0]
        if e["type"] == "missing":  # all keys missing at the same place, in one message
            keys = [str(x["loc"][-1]) for x in errors if x["type"] == "missing" and x["loc"][:-1] == e["loc"][:-1]]
            raise InvalidParameterError(f"{where}: {_where(e['loc'][:-1], 'the document')} lacks {', '.join(keys)}") from None
        got = "" if e["type"] in ("missing", "extra_forbidden", "link_count", "quantity") else f"; got {repr(e.get('input'))[:60]}"
        what = "unknown key" if e["type"] == "extra_forbidden" else e["msg"][0].lower() + e["msg"][1:]
        if e["type"] == "extra_forbidden" and model is RobotSpec:
            top = e["loc"][0] if len(e["loc"]) > 1 else None
            section = {"joints": JointSpec, "base": FrameSpec, "tool": FrameSpec, "sensor": SensorSpec, "units": Units, "masses": MassesSpec}.get(
                top, RobotSpec
            )
            if top == "masses" and len(e["loc"]) > 3:  # masses, links, i, key
                section = LinkMassSpec
            what += f" (allowed: {', '.join(f.alias or name for name, f in section.model_fields.items())})"
        more = f" (and {exc.error_count() - 1} more problems)" if exc.error_count() > 1 else ""
        raise InvalidParameterError(f"{where}: {_where(e['loc'], 'the top level')}: {what}{got}{more}") from None
