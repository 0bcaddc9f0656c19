"""The diagnose report as a typed document: :func:`load_diagnosis`.

``robocal diagnose --json`` writes :meth:`Diagnosis.to_dict` (one session) or
:meth:`SessionsDiagnosis.to_dict` (several); ``calibrate --causes``, ``report --diagnosis`` and the
multi-session diagnosis read it back. :class:`DiagnosisReport` is what they read: the model
(``model.causes``, ``model.structure``, the tolerance prior, each session's own terms), the
held-out figures of the baseline and the final model, the causes found (``effects``) and refused
(``rejected``), and per session its own diagnosis.

pydantic models in strict mode, as the robot and result documents (:mod:`robocal.schemas`): a
value of the wrong type (``"joint": "2"``, ``"causes": "backlash joint 2"``) or a missing key a
reader needs (an effect without its ``kind``) is an :class:`~robocal.exceptions.InvalidParameterError`
naming the file and the key. Other keys are kept (``extra="allow"``): a report holds figures
(significance tests, residual verdicts) no reader needs, and reports written by earlier versions
lack some of the keys added since (``model.structure``, ``model.kinematic_prior``), which default.
The JSON is written by ``to_dict()``; the model only reads it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, List, Optional, Union

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, ValidationError, field_validator
from pydantic_core import PydanticCustomError

from .exceptions import InvalidParameterError
from .robot_file import load_document
from .schemas import Implausible, validate

_REPORT = ConfigDict(strict=True, extra="allow")


class Quantity(BaseModel):
    """A physical parameter of a cause: ``value`` ± ``std`` (None: not estimated) in ``unit``."""

    model_config = _REPORT
    value: Optional[float] = None
    std: Optional[float] = None
    unit: str = ""


def _typed_params(params: Optional[dict]) -> Optional[dict]:
    """A cause's ``params`` with every ``{value, std, unit}`` entry a :class:`Quantity`; other
    entries (an outliers entry's ``rows``, a threshold) as written."""
    if params is None:
        return None
    out = {}
    for name, q in params.items():
        if isinstance(q, dict):
            try:
                q = Quantity.model_validate(q)
            except ValidationError as exc:
                e = exc.errors(include_url=False)[0]
                where = ", ".join(f"key {k!r}" for k in e["loc"])
                raise PydanticCustomError(
                    "quantity", f"parameter {name!r}, {where}: {e['msg'][0].lower() + e['msg'][1:]}; got {e.get('input')!r:.60}"
                ) from None
        out[name] = q
    return out


class Curve(BaseModel):
    """A joint map's correction (deg) against its joint's reading (deg), with its std."""

    model_config = _REPORT
    angle_deg: List[float]
    value_deg: List[float]
    std_deg: Optional[List[float]] = None


class Effect(BaseModel):
    """A cause of the report, found (``effects``) or refused (``rejected``, with its ``reason``): its ``kind``,
    ``joint`` (1-based; None for the sensor, drift, outliers), ``label`` (what ``calibrate
    --causes`` takes) and physical ``params``, with the held-out RMSE before and after it was
    added — cross-validated within one session (``rmse_heldout_*``) or leave-one-session-out
    over several (``rmse_loso_*``, ``per_session_*``, ``found_in_sessions``)."""

    model_config = _REPORT
    kind: str
    label: str
    joint: Optional[int] = None
    params: Optional[dict[str, Any]] = None
    # one session: cross-validated
    rmse_heldout_before: Optional[float] = None
    rmse_heldout_after: Optional[float] = None
    # several sessions: leave-one-session-out, pooled and per session
    rmse_loso_before: Optional[float] = None
    rmse_loso_after: Optional[float] = None
    #: Pose data: the pooled leave-one-session-out RMS of what the fit minimises (position and
    #: orientation weighed as in the fit), the figure the selection compared.
    rmse_loso_judged_before: Optional[float] = None
    rmse_loso_judged_after: Optional[float] = None
    per_session_before: List[float] = []
    per_session_after: List[float] = []
    found_in_sessions: List[int] = []
    significance: Optional[dict[str, Any]] = None
    share_of_explained: Optional[float] = None
    #: A compliance's correlation with the others (label -> r); a hand-edited entry may hold anything.
    correlation: Optional[dict[str, Any]] = None
    #: An outliers entry's test of readings taken right after long joint moves.
    after_long_moves: Optional[dict[str, Any]] = None
    curve: Optional[Curve] = None
    #: A joint map's: the harmonics of its joint the model holds beside it, one claim with it.
    with_harmonics: List["Effect"] = []
    # a refused cause's
    reason: str = ""
    gain_mm: Optional[float] = None
    replaced_by: Optional[str] = None

    @field_validator("params")
    @classmethod
    def _quantities(cls, params: Optional[dict]) -> Optional[dict]:
        return _typed_params(params)

    @property
    def rmse_before(self) -> Optional[float]:
        """The held-out RMSE (mm) before this cause: leave-one-session-out if the report has it."""
        return self.rmse_loso_before if self.rmse_loso_before is not None else self.rmse_heldout_before

    @property
    def rmse_after(self) -> Optional[float]:
        """The held-out RMSE (mm) with this cause: leave-one-session-out if the report has it."""
        return self.rmse_loso_after if self.rmse_loso_after is not None else self.rmse_heldout_after


#: A cause tried and refused: an :class:`Effect` with why (``reason``), its screening gain
#: (``gain_mm``, none for a cause put in another's place) and the cause put in its place.
Rejected = Effect


class Floor(BaseModel):
    """The error floor the data's own resolution explains (mm)."""

    model_config = _REPORT
    joints_mm: Optional[float] = None
    sensor_mm: Optional[float] = None
    note: str = ""
    revisits: Optional[Revisits] = None


class Revisits(BaseModel):
    """The joint configurations measured twice: ``pairs`` of them, one reading's repeatability
    and the final model's error they share beyond it (mm)."""

    model_config = _REPORT
    pairs: int
    repeatability_mm: float
    systematic_mm: float


class TolerancePrior(BaseModel):
    """A manufacturing-tolerance prior on the kinematics, tried on the final model: kept or why not."""

    model_config = _REPORT
    accepted: bool
    sigma_mm: float
    sigma_deg: float
    reason: str = ""


class Unexplained(BaseModel):
    """A finding that would explain part of the error left but was refused."""

    model_config = _REPORT
    label: str
    share: Optional[float] = None
    params: Optional[dict[str, Any]] = None
    reason: str = ""

    @field_validator("params")
    @classmethod
    def _quantities(cls, params: Optional[dict]) -> Optional[dict]:
        return _typed_params(params)


class Covered(BaseModel):
    model_config = _REPORT
    samples: int
    rmse: Optional[float] = None


class Figures(BaseModel):
    """The ``baseline`` (geometric model) or ``final`` figures: held-out RMSE (mm) cross-validated
    within one session (``rmse_heldout``, ``rmse_heldout_blocked``) or leave-one-session-out
    (``rmse_loso``, ``per_session``), the kinematic parameters left implausible and, for the final
    model, its error budget, tolerance prior and what is left."""

    model_config = _REPORT
    rmse_heldout: Optional[float] = None
    rmse_heldout_blocked: Optional[float] = None
    per_session: List[float] = []
    rmse_loso: Optional[float] = None
    rmse_train: Optional[float] = None
    per_session_covered: List[Covered] = []
    rmse_heldout_unconstrained: Optional[float] = None
    rmse_loso_unconstrained: Optional[float] = None
    #: Pose data, several sessions: the final model's pooled RMS of what the fit minimises, the
    #: figure the refused causes were compared with.
    rmse_loso_judged: Optional[float] = None
    rotation_per_session_deg: List[float] = []
    rotation_rmse_heldout_deg: Optional[float] = None
    rotation_rmse_heldout_blocked_deg: Optional[float] = None
    rotation_rmse_loso_deg: Optional[float] = None
    implausible: List[Implausible] = []
    n_params: Optional[int] = Field(default=None, ge=0)
    folds: Optional[int] = Field(default=None, ge=2)
    floor_mm: Optional[float] = None
    floor: Optional[Floor] = None
    explained: Optional[float] = None
    tolerance_prior: Optional[TolerancePrior] = None
    structure_unexplained: Optional[dict[str, Any]] = None
    #: The residual verdict of :func:`~robocal.diagnosis.leftover.residual_verdict`.
    residuals: Optional[dict[str, Any]] = None
    unexplained: List[Unexplained] = []

    def held_out(self, several: bool) -> Optional[float]:
        """The held-out RMSE (mm): leave-one-session-out if ``several``, else cross-validated."""
        return self.rmse_loso if several else self.rmse_heldout

    def unconstrained(self, several: bool) -> Optional[float]:
        """The held-out RMSE (mm) of the final model without its tolerance prior."""
        return self.rmse_loso_unconstrained if several else self.rmse_heldout_unconstrained


class SessionTerms(BaseModel):
    """A session's own terms in a multi-session model (its steps, drift): labels."""

    model_config = _REPORT
    source: Optional[str] = None
    causes: List[str]


class ReportModel(BaseModel):
    """The diagnosed model: what ``calibrate --causes`` fits. ``causes`` and ``structure`` (the
    reading conventions) are labels; ``kinematic_prior`` the (mm, deg) of the final model's
    tolerance prior, if kept; ``sessions`` each session's own terms (several sessions)."""

    model_config = _REPORT
    causes: List[str]
    structure: List[str] = []
    kinematic_prior: Optional[Annotated[List[float], Field(min_length=2, max_length=2)]] = None
    free: List[str] = []
    parameters: dict[str, float] = {}
    sessions: Optional[List[SessionTerms]] = None


class SessionReport(BaseModel):
    """A session of a multi-session report: its file, samples and its own diagnosis."""

    model_config = _REPORT
    source: Optional[str] = None
    samples: Optional[int] = None
    diagnosis: Optional["DiagnosisReport"] = None


class DiagnosisReport(BaseModel):
    """A diagnose report (``robocal diagnose --json``), one session or several (``sessions``).

    No key is required of every report: ``calibrate --causes`` and ``plan`` need the ``model``
    (:meth:`needs_model`), the page and the summaries the held-out figures (:meth:`needs_figures`).
    A key that is there must have its type."""

    model_config = _REPORT
    robot: Optional[str] = None
    measurement: Optional[str] = None
    samples: Optional[int] = Field(default=None, ge=0)
    source: Optional[str] = None
    baseline: Optional[Figures] = None
    effects: List[Effect] = []
    rejected: List[Rejected] = []
    final: Optional[Figures] = None
    model: Optional[ReportModel] = None
    sessions: Optional[List[SessionReport]] = None
    time_s: Optional[float] = None
    #: How messages name the report: its file, or "diagnose report" for a document given as a dict.
    _where: str = PrivateAttr(default="diagnose report")

    @property
    def several(self) -> bool:
        """A report on several sessions (leave-one-session-out figures)."""
        return self.sessions is not None

    @property
    def held_key(self) -> str:
        """The name of the held-out RMSE: ``rmse_loso`` over several sessions, else ``rmse_heldout``."""
        return "rmse_loso" if self.several else "rmse_heldout"

    @property
    def structure(self) -> List[str]:
        """Labels of the reading conventions the model applies (none without a model)."""
        return list(self.model.structure) if self.model is not None else []

    @property
    def where(self) -> str:
        """How messages name the report: ``diagnose report FILE`` (or without a file, for a dict)."""
        return self._where

    def needs_model(self) -> ReportModel:
        """The report's ``model`` (what ``calibrate --causes`` fits and ``plan`` plans for), or an
        error naming the file."""
        if self.model is None:
            raise InvalidParameterError(f"{self.where} lacks key 'model': the diagnosed causes to fit are its model.causes")
        return self.model

    def check_robot(self, name: str) -> "DiagnosisReport":
        """The report, or an error naming the file if it is a diagnosis of another robot than
        ``name``: its causes name that robot's joints and were found on its data (a report that
        names no robot, written by hand, is taken as it is)."""
        if self.robot is not None and self.robot != name:
            raise InvalidParameterError(f"{self.where} is a diagnosis of robot {self.robot!r}, not of {name!r}: pass a diagnose report of {name!r}")
        return self

    def needs_figures(self, reader: str) -> "DiagnosisReport":
        """The report, or an error naming the file if it lacks the held-out figures ``reader``
        (what shows them) needs: the baseline's held-out RMSE, the effects, each with its
        held-out RMSE after it was added."""
        key, missing = self.held_key, None
        if self.baseline is None or getattr(self.baseline, key) is None:
            missing = f"key 'baseline', key {key!r}"
        elif "effects" not in self.model_fields_set:
            missing = "key 'effects'"
        else:
            missing = next((f"effect {i}, key '{key}_after'" for i, e in enumerate(self.effects, start=1) if e.rmse_after is None), None)
        if missing:
            several = " (several sessions)" if self.several else ""
            raise InvalidParameterError(f"{self.where} lacks {missing}{several}: {reader} takes the held-out figures of a `robocal diagnose --json` report")
        return self


Effect.model_rebuild()
SessionReport.model_rebuild()
Floor.model_rebuild()


def load_diagnosis(source: Union[str, Path, dict, DiagnosisReport]) -> DiagnosisReport:
    """The typed diagnose report of a ``robocal diagnose --json`` file or of its document (a dict,
    :meth:`Diagnosis.to_dict`); a :class:`DiagnosisReport` is returned as it is.

    Read through the documents' one loader (:func:`robocal.robot_file.load_document`: regular files
    only, up to the size limit, no key twice), then checked against :class:`DiagnosisReport`.

    Examples
    --------
    >>> report = load_diagnosis({"baseline": {"rmse_heldout": 0.1}, "effects": [], "model": {"causes": ["backlash joint 2"]}})
    >>> report.model.causes, report.baseline.rmse_heldout
    (['backlash joint 2'], 0.1)

    Raises
    ------
    InvalidParameterError
        Naming the file (or "diagnose report" for a dict) and what is wrong: unreadable, not JSON,
        a key missing or of the wrong type (``effect 2 lacks kind``).
    """
    if isinstance(source, DiagnosisReport):
        return source
    doc = load_document(source, "diagnose report", "diagnose report")
    where = "diagnose report" if isinstance(source, dict) else f"diagnose report {source}"
    report = validate(DiagnosisReport, doc, where)
    report._where = where
    return report
