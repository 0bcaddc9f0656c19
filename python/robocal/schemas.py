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

from typing import Any, List, Literal, Optional

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from .exceptions import InvalidParameterError

_STRICT = ConfigDict(strict=True, extra="forbid", allow_inf_nan=False)
_OPEN = ConfigDict(strict=True, extra="allow")  # results may hold NaN (an undetermined std)

Pair = List[float]


class JointSpec(BaseModel):
    """One joint of a robot file: DH values in deg / mm, limits in deg (mm if prismatic)."""

    model_config = _STRICT
    alpha: float
    a: float
    d: float
    theta: float
    limits: Pair = Field(default=[-180.0, 180.0], min_length=2, max_length=2)
    hayati: bool = False
    kind: Literal["revolute", "prismatic"] = "revolute"


class RobotSpec(BaseModel):
    """A robot file (JSON or YAML)."""

    model_config = _STRICT
    name: Optional[str] = None
    description: Optional[str] = None
    convention: Literal["dh", "mdh"] = "dh"
    joints: List[JointSpec] = Field(min_length=1)


class ModelJoint(BaseModel):
    model_config = _STRICT
    convention: Literal["dh", "mdh"]
    kind: Literal["revolute", "prismatic"]
    hayati: bool
    limits: Pair = Field(min_length=2, max_length=2)


class RobotModel(BaseModel):
    model_config = _STRICT
    name: str
    joints: List[ModelJoint] = Field(min_length=1)
    nominal: List[float]


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


class ResultSpec(BaseModel):
    """The keys of a result file (``robocal.result/1``) that robocal reads back; others are kept."""

    model_config = _OPEN
    robot: Optional[str] = None
    measurement: Literal["cable", "position", "pose"]
    method: Optional[str] = None
    robot_model: RobotModel
    parameters: List[Parameter]
    implausible: List[Implausible] = []
    metrics: dict[str, Optional[Metrics]] = {}
    fixed: dict[str, str] = {}
    causes: List[dict] = []
    convergence: dict[str, Any] = {}
    dataset: Optional[Provenance] = None


def _where(loc: tuple, document: str) -> str:
    """``('joints', 2, 'hayatti')`` as ``joint 3, key 'hayatti'``."""
    words, i = [], 0
    while i < len(loc):
        key = loc[i]
        if key in ("joints", "parameters", "implausible") and i + 1 < len(loc) and isinstance(loc[i + 1], int):
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
        got = "" if e["type"] in ("missing", "extra_forbidden") else f"; got {repr(e.get('input'))[:60]}"
        what = "unknown key" if e["type"] == "extra_forbidden" else e["msg"][0].lower() + e["msg"][1:]
        if e["type"] == "extra_forbidden" and model is RobotSpec:
            what += f" (allowed: {', '.join(JointSpec.model_fields if len(e['loc']) > 2 else RobotSpec.model_fields)})"
        more = f" (and {exc.error_count() - 1} more problems)" if exc.error_count() > 1 else ""
        raise InvalidParameterError(f"{where}: {_where(e['loc'], 'the top level')}: {what}{got}{more}") from None
