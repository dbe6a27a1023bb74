"""Request and response bodies of the REST API (pydantic), with OpenAPI examples.

Public identifiers: a rig is named by its manifest ``rig.id`` (``rig_id`` in paths and
bodies), a campaign by its manifest ``id``; records, results and alarms by integers.
"""

from __future__ import annotations

import datetime as dt
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from gearwatch.results import METRIC_NAMES, TOOTH_INDICATORS

Role = Literal["viewer", "operator", "admin"]
AlarmState = Literal["warning", "alarm", "acknowledged", "cleared"]
RecordStatus = Literal["accepted", "rejected", "pending"]
ToothIndicatorName = Literal["mci_depth", "diff_energy", "diff_kurtosis"]
AlarmIndicatorName = Literal[
    "mci_depth", "diff_energy", "diff_kurtosis",
    "rms", "peak", "crest", "kurtosis", "fm0", "fm4", "na4", "nb4", "m6a", "m8a", "er",
]  # fmt: skip
CurveName = Literal["pinion_average", "gear_average", "difference", "mci_raw", "mci", "speed_rpm"]

assert set(ToothIndicatorName.__args__) == set(TOOTH_INDICATORS)  # type: ignore[attr-defined]
assert set(AlarmIndicatorName.__args__) == set(TOOTH_INDICATORS) | set(METRIC_NAMES)  # type: ignore[attr-defined]

TIMESTAMP_EXAMPLE = "2026-03-02T08:00:00Z"


class ErrorDetail(BaseModel):
    code: str = Field(examples=["not_found"])
    message: str = Field(examples=["rig 'rig-x' not found"])
    details: Any = None


class ErrorBody(BaseModel):
    """Every 4xx/5xx answer has this body."""

    error: ErrorDetail


class Health(BaseModel):
    status: Literal["ok", "degraded"] = Field(examples=["ok"])
    database: Literal["ok", "unreachable"] = Field(examples=["ok"])
    version: str = Field(examples=["0.1.0"])


class Me(BaseModel):
    prefix: str = Field(examples=["3f9a1c2b"])
    name: str = Field(examples=["night shift"])
    role: Role


class ApiKeyCreate(BaseModel):
    model_config = ConfigDict(extra="forbid")
    role: Role = Field(examples=["operator"])
    name: str = Field(default="", max_length=200, examples=["rig hall PC"])


class ApiKeyOut(BaseModel):
    id: int
    prefix: str
    name: str
    role: Role
    created_at: dt.datetime
    last_used_at: dt.datetime | None = None
    revoked_at: dt.datetime | None = None


class ApiKeyCreated(ApiKeyOut):
    key: str = Field(
        description="The key itself: shown once, only its hash is kept.",
        examples=["gw_3f9a1c2b_Jq0c…"],
    )


class ApiKeyList(BaseModel):
    items: list[ApiKeyOut]


class RigOut(BaseModel):
    rig_id: str = Field(examples=["rig-a"])
    pinion_teeth: int | None = Field(examples=[20])
    gear_teeth: int | None = Field(examples=[31])
    tooth1_pitch_angle_deg: float = Field(examples=[0.0])
    campaigns: list[str] = Field(default_factory=list, examples=[["fatigue-2026-03"]])
    records: int = Field(default=0, description="Records of every status.", examples=[12])


class RigList(BaseModel):
    items: list[RigOut]


class ChannelOut(BaseModel):
    name: str = Field(examples=["acc1"])
    kind: Literal["accelerometer", "tachometer"]
    unit: str = Field(default="", examples=["g"])


class CampaignOut(BaseModel):
    campaign_id: str = Field(examples=["fatigue-2026-03"])
    rig_id: str = Field(examples=["rig-a"])
    description: str = ""
    channels: list[ChannelOut] = Field(default_factory=list)
    manifest: dict[str, Any] = Field(default_factory=dict)
    created_at: dt.datetime


class CampaignList(BaseModel):
    items: list[CampaignOut]


class RecordEntryIn(BaseModel):
    """The manifest entry of an uploaded record (``[[records]]`` in ``campaign.toml``)."""

    model_config = ConfigDict(extra="forbid")
    taken_at: dt.datetime = Field(
        description="When the record was taken (ISO 8601 with a time zone).",
        examples=[TIMESTAMP_EXAMPLE],
    )
    label: str = Field(default="", max_length=200, examples=["day 3"])
    file: str | None = Field(
        default=None,
        max_length=500,
        description="File name as written in the manifest (default: the uploaded file's name).",
        examples=["day03.csv.gz"],
    )


class RecordOut(BaseModel):
    id: int = Field(examples=[42])
    rig_id: str = Field(examples=["rig-a"])
    campaign_id: str = Field(examples=["fatigue-2026-03"])
    file_name: str = Field(examples=["day03.csv.gz"])
    sha256: str
    size_bytes: int
    taken_at: dt.datetime = Field(examples=[TIMESTAMP_EXAMPLE])
    label: str = ""
    status: RecordStatus
    reason: str = Field(default="", description="Why the record was rejected.")
    speed_rpm: float | None = None
    speed_variation: float | None = None
    revolutions: int | None = None
    processed_at: dt.datetime | None = None


class RecordList(BaseModel):
    items: list[RecordOut]
    total: int
    limit: int
    offset: int


class ToothOut(BaseModel):
    tooth: int = Field(examples=[7])
    mci_depth: float | None = None
    diff_energy: float | None = None
    diff_kurtosis: float | None = None


class ChannelResultOut(BaseModel):
    channel: str = Field(examples=["acc1"])
    revolutions: int
    gear_revolutions: int
    speed_rpm: float
    samples_per_rev: int
    worst_tooth: int | None
    metrics: dict[str, float] = Field(examples=[{"rms": 0.12, "kurtosis": 3.1}])
    teeth: list[ToothOut]
    curves: list[str] = Field(examples=[["mci", "difference"]])


class ResultOut(BaseModel):
    id: int
    record_id: int
    is_current: bool
    parameters: dict[str, Any]
    code_version: str
    created_at: dt.datetime
    speed_rpm: float
    revolutions: int
    samples_per_rev: int
    channels: list[ChannelResultOut] = Field(default_factory=list)


class ResultList(BaseModel):
    items: list[ResultOut]


class RecordDetail(RecordOut):
    quality: dict[str, Any] = Field(default_factory=dict)
    current_result: ResultOut | None = None


class ReprocessIn(BaseModel):
    """New analysis parameters; omitted ones keep their defaults (``AnalysisParameters``)."""

    model_config = ConfigDict(extra="forbid")
    parameters: dict[str, Any] = Field(
        default_factory=dict,
        examples=[{"samples_per_mesh": 32, "mci_form": "literal"}],
    )


class UploadOut(BaseModel):
    record: RecordOut
    outcome: Literal["processed", "duplicate", "queued", "rejected"] = Field(
        description="processed: analysed now; duplicate: the same file was already ingested; "
        "queued: sent to the workers; rejected: kept but failed the checks (see reason).",
    )


class ToothSector(BaseModel):
    tooth: int
    start_deg: float
    end_deg: float


class BaselineBand(BaseModel):
    """Pointwise median ± 3·(1.4826·MAD) of the curve over the rig's first accepted records."""

    lower: list[float]
    upper: list[float]
    records: int = Field(description="How many records the band was learned from.")


class CurvesOut(BaseModel):
    record_id: int
    result_id: int
    channel: str
    samples_per_rev: int
    pinion_teeth: int | None
    tooth1_pitch_angle_deg: float
    curves: dict[str, list[float]]
    sectors: list[ToothSector] = Field(
        default_factory=list, description="Pinion tooth sectors along the angle axis."
    )
    baseline_band: BaselineBand | None = None


class TrendPoint(BaseModel):
    record_id: int
    taken_at: dt.datetime


class TrendOut(BaseModel):
    """``values[i][j]`` is the indicator of ``records[i]`` at ``teeth[j]`` (``null`` if absent)."""

    rig_id: str = Field(examples=["rig-a"])
    indicator: ToothIndicatorName
    channel: str | None = Field(default=None, examples=["acc1"])
    teeth: list[int] = Field(examples=[[1, 2, 3]])
    records: list[TrendPoint]
    values: list[list[float | None]] = Field(examples=[[[0.02, 0.03, 0.41]]])


class AlarmEventOut(BaseModel):
    state: AlarmState
    at: dt.datetime
    record_id: int | None = None
    value: float | None = None
    score: float | None = None
    who: str | None = None
    comment: str | None = None


class AlarmOut(BaseModel):
    id: int = Field(examples=[3])
    rig_id: str = Field(examples=["rig-a"])
    channel: str = Field(examples=["acc1"])
    tooth: int = Field(examples=[7], description="Pinion tooth (1-based); 0 for a record metric.")
    indicator: str = Field(examples=["mci_depth"])
    state: AlarmState
    severity: Literal["warning", "alarm"]
    record_id: int | None = Field(description="The record that raised the alarm.")
    raised_at: dt.datetime = Field(
        description="``taken_at`` of the raising record.", examples=[TIMESTAMP_EXAMPLE]
    )
    last_value: float
    last_score: float = Field(description="Last value in baseline units (positive = worse).")
    baseline_centre: float
    baseline_spread: float
    acknowledged_by: str | None = None
    acknowledged_at: dt.datetime | None = None
    ack_comment: str | None = None
    cleared_at: dt.datetime | None = None


class AlarmDetail(AlarmOut):
    history: list[AlarmEventOut] = Field(default_factory=list)


class AlarmList(BaseModel):
    items: list[AlarmOut]


class AckIn(BaseModel):
    model_config = ConfigDict(extra="forbid")
    comment: str = Field(default="", max_length=2000, examples=["inspected: pitting on tooth 7"])


class AlarmRuleIn(BaseModel):
    """One rule: levels are in baseline units (robust spreads above the baseline centre)."""

    model_config = ConfigDict(extra="forbid")
    indicator: AlarmIndicatorName = Field(examples=["mci_depth"])
    baseline_records: int = Field(default=10, ge=1, le=10_000, examples=[10])
    warning_level: float = Field(default=4.0, gt=0, le=1e6, examples=[4.0])
    alarm_level: float = Field(default=8.0, gt=0, le=1e6, examples=[8.0])
    clear_level: float = Field(default=2.0, ge=0, le=1e6, examples=[2.0])
    persistence: int = Field(default=3, ge=1, le=1000, examples=[3])
    enabled: bool = True


class AlarmRuleOut(AlarmRuleIn):
    updated_at: dt.datetime | None = None


class AlarmRules(BaseModel):
    rig_id: str = Field(examples=["rig-a"])
    items: list[AlarmRuleOut]


class AlarmRulesIn(BaseModel):
    model_config = ConfigDict(extra="forbid")
    items: list[AlarmRuleIn] = Field(max_length=64)


class AuditOut(BaseModel):
    id: int
    who: str
    action: str
    target: str
    at: dt.datetime
    details: dict[str, Any]


class AuditList(BaseModel):
    items: list[AuditOut]
