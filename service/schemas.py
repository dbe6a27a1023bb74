"""Request and response bodies of the REST API (pydantic), with OpenAPI examples.

Public identifiers: a rig is named by its manifest ``rig.id`` (``rig_id`` in paths and
bodies), a campaign by its manifest ``id``; records, results and alarms by integers.
"""

from __future__ import annotations

import datetime as dt
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, AwareDatetime, BaseModel, ConfigDict, Field, model_validator

from gearwatch.floor.defaults import (
    GLITCH_RANGE_FACTOR,
    MAX_SAMPLES_PER_MESH,
    MAX_SPEED_VARIATION,
    MIN_SAMPLES_PER_MESH,
    RECONCILE_MAX_FINDINGS,
    REVOLUTION_OUTLIER_FACTOR,
    SAMPLES_PER_MESH,
    SPIKE_FACTOR,
)
from gearwatch.floor.results import METRIC_NAMES, STORED_TOOTH_INDICATORS

Role = Literal["viewer", "operator", "admin"]
AlarmState = Literal["warning", "alarm", "acknowledged", "cleared"]
RecordStatus = Literal["accepted", "rejected", "pending"]
ToothIndicatorName = Literal[
    "mci_depth", "diff_energy", "diff_kurtosis", "mci_depth_se", "score", "nonsync_z", "change"
]
AlarmIndicatorName = Literal[
    "mci_depth", "diff_energy", "diff_kurtosis", "mci_depth_se", "score", "nonsync_z", "change",
    "rms", "peak", "crest", "kurtosis", "fm0", "fm4", "na4", "residual_kurtosis", "nb4", "m6a", "m8a",
    "er", "raw_rms", "raw_kurtosis",
]  # fmt: skip
CurveName = Literal["pinion_average", "gear_average", "difference", "mci_raw", "mci", "speed_rpm"]

assert set(ToothIndicatorName.__args__) == set(STORED_TOOTH_INDICATORS)  # type: ignore[attr-defined]
assert set(AlarmIndicatorName.__args__) == set(STORED_TOOTH_INDICATORS) | set(METRIC_NAMES)  # type: ignore[attr-defined]

TIMESTAMP_EXAMPLE = "2026-03-02T08:00:00Z"

NO_CONTROL_CHARACTERS = r"^[^\x00-\x1f\x7f]*$"
"""Names and comments are printable text (PostgreSQL refuses NUL in text)."""
NAME_PATTERN = r"^[^\x00-\x1f\x7f/]+$"


def _to_utc(value: dt.datetime) -> dt.datetime:
    try:
        utc = value.astimezone(dt.UTC)
    except OverflowError:
        raise ValueError("timestamp out of range") from None
    if not 1900 <= utc.year <= 9000:
        raise ValueError("timestamp out of range (years 1900 to 9000)")
    return utc


UtcDatetime = Annotated[AwareDatetime, AfterValidator(_to_utc)]
"""An ISO 8601 timestamp WITH a time zone, converted to UTC."""


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
    name: str = Field(
        default="", max_length=200, pattern=NO_CONTROL_CHARACTERS, examples=["rig hall PC"]
    )


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
    taken_at: UtcDatetime = Field(
        description="When the record was taken (ISO 8601 with a time zone).",
        examples=[TIMESTAMP_EXAMPLE],
    )
    label: str = Field(
        default="", max_length=200, pattern=NO_CONTROL_CHARACTERS, examples=["day 3"]
    )
    file: str | None = Field(
        default=None,
        max_length=500,
        pattern=NAME_PATTERN,
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
    quality_score: float | None = Field(
        default=None,
        description="Data-quality score in [0, 1] of the current analysis (see `quality`): "
        "revolutions, synchronous-to-noise ratio, speed variation, tach repairs, rejections.",
    )
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
    mci_depth_se: float | None = Field(
        default=None, description="Standard error of the MCI evidence from the record itself (Np)."
    )
    score: float | None = Field(
        default=None,
        description="MCI evidence against the record's other teeth, in its own standard errors.",
    )


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
    quality: dict[str, Any] = Field(
        default_factory=dict,
        description="This channel's data quality: `score`, `score_components`, `sync_to_noise_db`, "
        "`rejected_revolutions`, `glitch_samples`, `dropout_samples`, `clipped_samples`.",
    )


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
    quality_score: float | None = Field(
        default=None, description="Data-quality score in [0, 1] (`quality.score`)."
    )
    quality: dict[str, Any] = Field(default_factory=dict)
    channels: list[ChannelResultOut] = Field(default_factory=list)


class ResultList(BaseModel):
    items: list[ResultOut]


class RecordDetail(RecordOut):
    quality: dict[str, Any] = Field(default_factory=dict)
    current_result: ResultOut | None = None
    tooth_frame: dict[str, Any] | None = Field(
        default=None,
        description=(
            "Which frame the per-tooth numbers are in (first accelerometer channel; every channel "
            "in quality.tooth_frames): kind 'tachometer' (tooth 1 from the tach and "
            "tooth1_pitch_angle_deg), 'campaign' (no tach: aligned to the campaign's reference "
            "record, with the correlation margin), 'refused' (alignment ambiguous: no per-tooth "
            "results), 'own' or 'none' (no shaft angle: whole-record raw metrics only)"
        ),
    )


class AnalysisParametersIn(BaseModel):
    """Analysis parameters (``gearwatch.floor.results.AnalysisParameters``); omitted ones keep their
    defaults. Bounds keep the analysis meaningful; anything outside is a 422."""

    model_config = ConfigDict(extra="forbid")
    samples_per_mesh: int = Field(
        default=SAMPLES_PER_MESH, ge=MIN_SAMPLES_PER_MESH, le=MAX_SAMPLES_PER_MESH, examples=[32]
    )
    samples_per_rev_without_teeth: int = Field(default=1024, ge=64, le=65536)
    mci_form: Literal["robust", "literal"] = "robust"
    mci_window_samples: int | None = Field(default=None, ge=2, le=65536)
    mci_median_width: int | None = Field(default=None, ge=1, le=131071)
    max_speed_variation: float = Field(default=MAX_SPEED_VARIATION, gt=0, le=10)
    glitch_range_factor: float = Field(default=GLITCH_RANGE_FACTOR, gt=0, le=1e6)
    spike_factor: float = Field(default=SPIKE_FACTOR, ge=0, le=1e6)
    revolution_outlier_factor: float = Field(default=REVOLUTION_OUTLIER_FACTOR, gt=1, le=1e6)
    min_revolutions: int = Field(default=20, ge=2, le=1_000_000)
    min_speed_rpm: float = Field(default=1.0, gt=0, le=1e6)
    max_speed_rpm: float = Field(default=100_000.0, gt=0, le=1e7)
    difference_sidebands: int = Field(default=1, ge=0, le=50)

    @model_validator(mode="after")
    def _speed_range(self) -> AnalysisParametersIn:
        if self.min_speed_rpm >= self.max_speed_rpm:
            raise ValueError("min_speed_rpm must be below max_speed_rpm")
        return self


class ReprocessIn(BaseModel):
    """Re-analyse a record's kept raw file with new parameters (a new result version)."""

    model_config = ConfigDict(extra="forbid")
    parameters: AnalysisParametersIn = Field(
        default_factory=AnalysisParametersIn,
        examples=[{"samples_per_mesh": 32, "mci_form": "literal"}],
    )


class JobOut(BaseModel):
    """What a per-record job did (or, with workers, that it was queued)."""

    record: RecordOut | None = Field(
        default=None, description="The stored record (absent while the job is queued)."
    )
    outcome: Literal["accepted", "rejected", "unchanged", "reprocessed", "queued"] = Field(
        description="accepted: analysed and stored; rejected: kept but failed the checks "
        "(see record.reason); unchanged: this file (and these parameters) were already "
        "processed; reprocessed: a new result version was added; queued: the raw file is kept "
        "and a worker will process it (GEARWATCH_JOB_RUNNER=broker).",
    )
    result_id: int | None = None
    alarm_changes: int = Field(default=0, description="Alarm state changes this record caused.")
    sha256: str | None = Field(default=None, description="sha256 of the uploaded file.")
    message_id: str | None = Field(default=None, description="Broker message id when queued.")


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
    tooth_frame: str = Field(
        default="tachometer",
        description="Where the record's analysis put the teeth: 'tachometer', 'campaign' (no "
        "tach: the campaign's tooth frame, turned here into the pair's), or 'refused' / 'none' "
        "(no tooth frame or no shaft angle: the teeth are not numbered and `sectors` is empty).",
    )
    turned_deg: float = Field(
        default=0.0,
        description="How far the angle-domain curves (pinion average, difference, MCI) were "
        "turned from the record's stored tooth frame into the pair's (0 with a tachometer).",
    )
    curves: dict[str, list[float | None]] = Field(
        description="float32 values; NaN travels as null."
    )
    sectors: list[ToothSector] = Field(
        default_factory=list, description="Pinion tooth sectors along the angle axis."
    )
    baseline_band: BaselineBand | None = None


class TrendPoint(BaseModel):
    record_id: int
    taken_at: dt.datetime
    label: str = Field(default="", description="The record's label (manifest or upload).")


class UnnumberedRecord(BaseModel):
    record_id: int
    taken_at: dt.datetime
    label: str = ""
    reason: str = Field(default="", description="Why its teeth are not numbered.")


class TrendOut(BaseModel):
    """``values[i][j]`` is the indicator of ``records[i]`` at ``teeth[j]`` (``null`` if absent).
    A whole-record indicator has one column whose tooth is ``null``."""

    rig_id: str = Field(examples=["rig-a"])
    indicator: str = Field(examples=["mci_depth"])
    title: str = Field(default="", examples=["MCI depth"])
    scope: Literal["tooth", "record"] = Field(
        default="tooth", description="Per pinion tooth, or one value per record."
    )
    unit: str = Field(
        default="", description="Unit of the values (empty: dimensionless).", examples=["Np"]
    )
    channel: str | None = Field(default=None, examples=["acc1"])
    campaign: str | None = Field(
        default=None,
        description="The campaign the trend was restricted to (null: the rig's current gear "
        "pair's campaigns).",
        examples=[None],
    )
    teeth: list[int | None] = Field(examples=[[1, 2, 3]])
    records: list[TrendPoint]
    values: list[list[float | None]] = Field(examples=[[[0.02, 0.03, 0.41]]])
    without_tooth_values: list[UnnumberedRecord] = Field(
        default_factory=list,
        description="A per-tooth trend's accepted records (same campaigns) that have no per-tooth "
        "values, with why: a tach-less record whose tooth frame was refused or that had no "
        "shaft angle keeps its whole-record metrics only.",
    )


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
    campaign_id: str | None = Field(default=None, examples=["fatigue-2026-03"])
    tooth: int | None = Field(
        examples=[7], description="Pinion tooth (1-based); null for a whole-record indicator."
    )
    indicator: str = Field(examples=["mci_depth"])
    unit: str = Field(default="", description="Unit of the values (empty: dimensionless).")
    state: AlarmState
    severity: Literal["warning", "alarm"]
    record_id: int | None = Field(description="The record that raised the alarm.")
    record_label: str = Field(default="", description="That record's label.")
    raised_at: dt.datetime = Field(
        description="``taken_at`` of the raising record.", examples=[TIMESTAMP_EXAMPLE]
    )
    last_value: float
    last_score: float = Field(description="Last value in baseline units (positive = worse).")
    baseline_centre: float
    baseline_spread: float = Field(
        description="The spread the raising score was computed with: the track's own baseline "
        "spread, or for `score` the channel's teeth's pooled day-to-day spread when that is larger."
    )
    evidence: str | None = Field(
        default=None, description="What raised the alarm: `level` or `cusum` (sequential test)."
    )
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
    comment: str = Field(
        default="",
        max_length=2000,
        pattern=r"^[^\x00]*$",
        examples=["inspected: pitting on tooth 7"],
    )


class AlarmRuleIn(BaseModel):
    """One rule; levels are in baseline units (robust spreads on the worse side of the baseline
    centre). An omitted setting keeps its current value (new rule: the storage default).
    Levels must satisfy clear_level < warning_level <= alarm_level."""

    model_config = ConfigDict(extra="forbid")
    indicator: AlarmIndicatorName = Field(examples=["mci_depth"])
    baseline_records: int | None = Field(default=None, ge=1, le=10_000, examples=[8])
    warning_level: float | None = Field(default=None, gt=0, le=1e6, examples=[4.0])
    alarm_level: float | None = Field(default=None, gt=0, le=1e6, examples=[8.0])
    clear_level: float | None = Field(default=None, ge=0, le=1e6, examples=[2.0])
    persistence: int | None = Field(default=None, ge=1, le=1000, examples=[2])
    spread_floor_fraction: float | None = Field(
        default=None, ge=0, le=100, description="Spread floor as a fraction of |centre|."
    )
    spread_floor_abs: float | None = Field(
        default=None, gt=0, le=1e9, description="Absolute spread floor (indicator's unit)."
    )
    min_baseline_records: int | None = Field(
        default=None, ge=1, le=10_000, description="Scoring starts after this many records."
    )
    cusum_reference: float | None = Field(
        default=None, ge=0, le=1e6, description="CUSUM allowance k (baseline units)."
    )
    cusum_limit: float | None = Field(
        default=None, gt=0, le=1e6, description="CUSUM decision limit h (baseline units)."
    )
    enabled: bool | None = None

    @model_validator(mode="after")
    def _levels_in_order(self) -> AlarmRuleIn:
        clear, warning, alarm = self.clear_level, self.warning_level, self.alarm_level
        if clear is not None and warning is not None and not clear < warning:
            raise ValueError("clear_level must be below warning_level")
        if warning is not None and alarm is not None and not warning <= alarm:
            raise ValueError("warning_level must not exceed alarm_level")
        return self


class AlarmRuleOut(BaseModel):
    indicator: str = Field(examples=["mci_depth"])
    baseline_records: int
    warning_level: float
    alarm_level: float
    clear_level: float
    persistence: int
    spread_floor_fraction: float
    spread_floor_abs: float
    min_baseline_records: int | None = None
    cusum_reference: float | None = None
    cusum_limit: float | None = None
    enabled: bool
    updated_at: dt.datetime | None = None


class AlarmRules(BaseModel):
    rig_id: str = Field(examples=["rig-a"])
    items: list[AlarmRuleOut]


class TrackLevelsOut(BaseModel):
    tooth: int | None = Field(description="Pinion tooth; null for a whole-record rule.", examples=[16])
    centre: float = Field(description="The baseline centre learned so far (indicator's unit).")
    spread: float = Field(description="The spread the next record is scored against: the "
                          "track's own, or for `score` the channel's pooled day-to-day spread "
                          "when that is larger.")
    warning: float = Field(description="Value above which (below, for a lower-is-worse "
                           "indicator) a record counts towards a warning.")
    alarm: float
    clear: float
    cusum: float = Field(description="The sequential test's sum now (alarm when it passes the "
                         "rule's `cusum_limit`).")
    state: Literal["warning", "alarm", "acknowledged"] | None = Field(
        description="The open alarm's state; null when none is open.")
    baseline_records: int = Field(description="Records the baseline has learned from.")


class AlarmLevelsOut(BaseModel):
    """Where each track of one rule stands: the levels the next record of the campaign's
    channel must pass. Tracks still learning their baseline are not listed."""

    rig_id: str = Field(examples=["rig-a"])
    indicator: str = Field(examples=["score"])
    campaign: str = Field(examples=["fatigue-2026-03"])
    channel: str = Field(examples=["acc1"])
    rule: AlarmRuleOut
    pooled_spread: float | None = Field(
        description="For `score`: how much the channel's healthy teeth move from record to "
        "record, pooled over the teeth (null for other rules, or before 3 teeth have 2 "
        "baseline records).")
    items: list[TrackLevelsOut]


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


ReconciliationStatus = Literal["queued", "running", "done", "failed"]
MechanismName = Annotated[str, Field(min_length=1, max_length=64, pattern=NAME_PATTERN)]


class ReconciliationIn(BaseModel):
    """A physics reconciliation of a stored record (issue 6; docs/reconciliation.md)."""

    model_config = ConfigDict(extra="forbid")
    model_toml: str | None = Field(
        default=None,
        max_length=1_000_000,
        pattern=r"^[^\x00]*$",
        description="Simulator configuration TOML (`gearwatch simulate --print-model`); its "
        "tooth counts must be the rig's. Default: the rig's default model.",
    )
    reference_record_id: int | None = Field(
        default=None,
        ge=1,
        le=2**31 - 1,
        description="A healthy record of the same rig: its residual is treated as known "
        "model-form error and only the change is explained.",
    )
    channel: str | None = Field(
        default=None,
        min_length=1,
        max_length=200,
        pattern=NAME_PATTERN,
        description="Accelerometer channel (default: the manifest's first).",
        examples=["acc1"],
    )
    mechanisms: list[MechanismName] | None = Field(
        default=None,
        max_length=32,
        description="Catalogue names to try (default: every fitted plug-in).",
        examples=[["pinion_eccentricity", "tooth_spall"]],
    )
    samples_per_mesh: int = Field(
        default=SAMPLES_PER_MESH, ge=MIN_SAMPLES_PER_MESH, le=MAX_SAMPLES_PER_MESH
    )
    max_frequency_hz: float | None = Field(
        default=None, gt=0, le=1e6, description="Highest frequency fitted (default 0.4 × fs)."
    )
    max_findings: int = Field(default=RECONCILE_MAX_FINDINGS, ge=0, le=16)
    forward_oversampling: int | None = Field(
        default=None,
        ge=1,
        le=256,
        description="Integrator steps per sample of the fitting simulations (default: the "
        "model's); coarser is faster.",
    )


class ReconciliationProvenance(BaseModel):
    raw_sha256: str = Field(description="sha256 of the record's raw file.")
    reference_raw_sha256: str | None = None
    code_version: str = Field(description="The code that ran it (that queued it, until then).")


class ReconciliationLinks(BaseModel):
    self: str
    record: str
    report: str
    model: str


class ReconciliationProgress(BaseModel):
    stage: str = Field(description="Where a reconciliation is: queued, reference: calibration, "
                       "calibration, selection, intervals, done …", examples=["selection"])
    fraction: float = Field(ge=0.0, le=1.0, description="Share of the run done (estimate).",
                            examples=[0.42])


class ReconciliationOut(BaseModel):
    id: int = Field(examples=[7])
    record_id: int = Field(examples=[42])
    reference_record_id: int | None = None
    status: ReconciliationStatus
    options: dict[str, Any] = Field(
        examples=[{"samples_per_mesh": 64, "max_frequency_hz": None, "max_findings": 4,
                   "mechanisms": None, "channel": "acc1", "forward_oversampling": None}]
    )
    provenance: ReconciliationProvenance
    outcome: str | None = Field(
        default=None,
        description="The result's status once done: explained, partly_explained, not_explained.",
    )
    error: str | None = Field(default=None, description="Why it failed.")
    progress: ReconciliationProgress | None = Field(
        default=None, description="Stage and fraction done (while running: updated every few "
        "seconds; none for a failed one)."
    )
    created_at: dt.datetime
    started_at: dt.datetime | None = None
    finished_at: dt.datetime | None = None
    links: ReconciliationLinks


class ReconciliationDetail(ReconciliationOut):
    result: dict[str, Any] | None = Field(
        default=None, description="The issue-6 JSON (status, baseline, mismatches, findings, "
        "unresolved, final) once done."
    )
    model_toml: str | None = Field(
        default=None, description="The simulator configuration used as the base."
    )


class ReconciliationList(BaseModel):
    items: list[ReconciliationOut]
