"""SQLAlchemy 2 models of everything gearwatch keeps: rigs, campaigns, records, results, alarms.

The schema is owned by alembic (``alembic/versions``); ``tests/storage`` checks that the alembic
head and these models agree. Enumerations are short strings guarded by CHECK constraints (no
database enum types, so SQLite and PostgreSQL migrate the same way). Timestamps are stored with
time zone and always come back as aware UTC datetimes (:class:`UTCDateTime`), on SQLite too.

Curves are float32 arrays stored as raw little-endian bytes (``LargeBinary``), never JSON.
Per-tooth indicators carry a copy of the record's rig, ``taken_at`` and the result version's
``is_current`` flag, so that a trend (rig × indicator × tooth over time) is one range scan of
:data:`TREND_INDEX_NAME` with no join.
"""

from __future__ import annotations

import datetime as dt
import functools
from typing import Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship

RECORD_STATUSES = ("accepted", "rejected", "pending")
ALARM_STATES = ("warning", "alarm", "acknowledged", "cleared")
ALARM_SEVERITIES = ("warning", "alarm")
ROLES = ("viewer", "operator", "admin")
RECONCILIATION_STATUSES = ("queued", "running", "done", "failed")
TREND_INDEX_NAME = "ix_tooth_indicators_trend"

NAMING_CONVENTION = {
    "ix": "ix_%(table_name)s_%(column_0_N_name)s",
    "uq": "uq_%(table_name)s_%(column_0_N_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}


_ZERO = dt.timedelta(0)


@functools.lru_cache(maxsize=8192)
def _parse_sqlite_utc_text(value: str) -> dt.datetime:
    return dt.datetime.fromisoformat(value).replace(tzinfo=dt.UTC)


def _parse_sqlite_utc(value: str | None) -> dt.datetime | None:
    return None if value is None else _parse_sqlite_utc_text(value)


def utcnow() -> dt.datetime:
    return dt.datetime.now(dt.UTC)


class UTCDateTime(sa.types.TypeDecorator[dt.datetime]):
    """A timezone-aware timestamp, stored in UTC, returned as an aware UTC datetime.

    SQLite has no time zone type and hands back naive datetimes; PostgreSQL keeps the zone.
    Naive datetimes are refused on the way in: a time without a zone is ambiguous.
    """

    impl = sa.DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value: dt.datetime | None, dialect: sa.Dialect) -> Any:
        if value is None:
            return None
        if value.tzinfo is None:
            raise ValueError(f"naive datetime {value.isoformat()} (a time zone is required)")
        value = value.astimezone(dt.UTC)
        if dialect.name == "sqlite":
            return value.replace(tzinfo=None)
        return value

    def process_result_value(self, value: Any, dialect: sa.Dialect) -> dt.datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            return value.replace(tzinfo=dt.UTC)
        if value.utcoffset() == _ZERO:
            return value
        return value.astimezone(dt.UTC)

    def result_processor(self, dialect: sa.Dialect, coltype: Any) -> Any:
        if dialect.name != "sqlite":
            return super().result_processor(dialect, coltype)

        # SQLite hands back ISO text; fromisoformat (C) is several times faster than the
        # generic regex parser, and a trend repeats each record's time once per tooth.
        return _parse_sqlite_utc


def float32_bytes(values: np.ndarray) -> bytes:
    """Little-endian float32 bytes of a 1-D array (the curve storage format)."""
    return np.ascontiguousarray(np.asarray(values, dtype="<f4").ravel()).tobytes()


def float32_array(data: bytes) -> np.ndarray:
    """Inverse of :func:`float32_bytes` (a fresh, writable array)."""
    return np.frombuffer(data, dtype="<f4").astype(np.float32)


class Base(DeclarativeBase):
    metadata = sa.MetaData(naming_convention=NAMING_CONVENTION)


def _check_in(column: str, values: tuple[str, ...], name: str) -> sa.CheckConstraint:
    allowed = ", ".join(f"'{v}'" for v in values)
    return sa.CheckConstraint(f"{column} IN ({allowed})", name=name)


class Rig(Base):
    __tablename__ = "rigs"

    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(sa.String(200), unique=True)
    """The manifest's ``rig.id``."""
    pinion_teeth: Mapped[int | None]
    gear_teeth: Mapped[int | None]
    tooth1_pitch_angle_deg: Mapped[float] = mapped_column(default=0.0)
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime(), default=utcnow)

    campaigns: Mapped[list[Campaign]] = relationship(back_populates="rig")


class Campaign(Base):
    __tablename__ = "campaigns"

    id: Mapped[int] = mapped_column(primary_key=True)
    rig_id: Mapped[int] = mapped_column(sa.ForeignKey("rigs.id", ondelete="CASCADE"), index=True)
    name: Mapped[str] = mapped_column(sa.String(200), unique=True)
    """The manifest's campaign ``id``."""
    description: Mapped[str] = mapped_column(sa.Text, default="")
    manifest: Mapped[dict[str, Any]] = mapped_column(sa.JSON, default=dict)
    """The campaign settings as loaded (rig, tachometer, channels, sample rate)."""
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime(), default=utcnow)

    rig: Mapped[Rig] = relationship(back_populates="campaigns")
    channels: Mapped[list[Channel]] = relationship(
        back_populates="campaign", order_by="Channel.id", cascade="all, delete-orphan"
    )


class Channel(Base):
    __tablename__ = "channels"
    __table_args__ = (
        sa.UniqueConstraint("campaign_id", "name"),
        _check_in("kind", ("accelerometer", "tachometer"), "kind"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    campaign_id: Mapped[int] = mapped_column(sa.ForeignKey("campaigns.id", ondelete="CASCADE"))
    name: Mapped[str] = mapped_column(sa.String(200))
    kind: Mapped[str] = mapped_column(sa.String(16))
    unit: Mapped[str] = mapped_column(sa.String(32), default="")

    campaign: Mapped[Campaign] = relationship(back_populates="channels")


class Record(Base):
    """One raw record file: where it is kept, when it was taken, whether it passed the checks."""

    __tablename__ = "records"
    __table_args__ = (
        sa.UniqueConstraint("campaign_id", "sha256"),
        sa.Index("ix_records_rig_id_taken_at", "rig_id", "taken_at"),
        sa.Index("ix_records_campaign_id_taken_at", "campaign_id", "taken_at"),
        _check_in("status", RECORD_STATUSES, "status"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    campaign_id: Mapped[int] = mapped_column(sa.ForeignKey("campaigns.id", ondelete="CASCADE"))
    rig_id: Mapped[int] = mapped_column(sa.ForeignKey("rigs.id", ondelete="CASCADE"))
    sha256: Mapped[str] = mapped_column(sa.String(64), index=True)
    file_name: Mapped[str] = mapped_column(sa.String(500))
    """Original file name (as written in the manifest, or as dropped/uploaded)."""
    raw_location: Mapped[str] = mapped_column(sa.String(1000))
    """Path of the kept raw file in the content-addressed raw store."""
    size_bytes: Mapped[int] = mapped_column(sa.BigInteger, default=0)
    taken_at: Mapped[dt.datetime] = mapped_column(UTCDateTime())
    label: Mapped[str] = mapped_column(sa.String(200), default="")
    status: Mapped[str] = mapped_column(sa.String(16), default="pending")
    reason: Mapped[str] = mapped_column(sa.Text, default="")
    """Why the record was rejected (empty when accepted)."""
    speed_rpm: Mapped[float | None]
    speed_min_rpm: Mapped[float | None]
    speed_max_rpm: Mapped[float | None]
    speed_variation: Mapped[float | None]
    revolutions: Mapped[int | None]
    quality: Mapped[dict[str, Any]] = mapped_column(sa.JSON, default=dict)
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime(), default=utcnow)
    processed_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime())

    campaign: Mapped[Campaign] = relationship()
    results: Mapped[list[ResultVersion]] = relationship(
        back_populates="record", order_by="ResultVersion.id", cascade="all, delete-orphan"
    )


class ResultVersion(Base):
    """One analysis of one record with one parameter set. A record keeps every version;
    the newest one (``is_current``) is the one trends and alarms use."""

    __tablename__ = "result_versions"
    __table_args__ = (sa.UniqueConstraint("record_id", "parameters_sha256"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    record_id: Mapped[int] = mapped_column(
        sa.ForeignKey("records.id", ondelete="CASCADE"), index=True
    )
    parameters: Mapped[dict[str, Any]] = mapped_column(sa.JSON)
    parameters_sha256: Mapped[str] = mapped_column(sa.String(64))
    """sha256 of the canonical JSON of ``parameters``: the same parameters give the same version."""
    code_version: Mapped[str] = mapped_column(sa.String(100))
    is_current: Mapped[bool] = mapped_column(default=True)
    speed_rpm: Mapped[float]
    revolutions: Mapped[int]
    samples_per_rev: Mapped[int]
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime(), default=utcnow)
    quality_score: Mapped[float | None]
    """Data-quality score in [0, 1] of this analysis (``quality.score``; NULL for results stored
    before it existed). Alarm statistics weight the record's evidence by it."""
    quality: Mapped[dict[str, Any]] = mapped_column(sa.JSON, default=dict, server_default="{}")
    """The record-level quality of this analysis (:class:`gearwatch.floor.results.Quality`)."""

    record: Mapped[Record] = relationship(back_populates="results")
    channels: Mapped[list[ChannelResult]] = relationship(
        order_by="ChannelResult.id", cascade="all, delete-orphan"
    )


class ChannelResult(Base):
    """Per-channel summary of one result version."""

    __tablename__ = "channel_results"
    __table_args__ = (sa.UniqueConstraint("result_id", "channel_id"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    result_id: Mapped[int] = mapped_column(sa.ForeignKey("result_versions.id", ondelete="CASCADE"))
    channel_id: Mapped[int] = mapped_column(sa.ForeignKey("channels.id", ondelete="CASCADE"))
    revolutions: Mapped[int]
    gear_revolutions: Mapped[int]
    speed_rpm: Mapped[float]
    samples_per_rev: Mapped[int]
    worst_tooth: Mapped[int | None]
    baseline_stats: Mapped[dict[str, Any]] = mapped_column(sa.JSON, default=dict)
    """The record's contribution to running baselines (``residual_variance``, ``envelope_variance``)."""
    quality: Mapped[dict[str, Any]] = mapped_column(sa.JSON, default=dict, server_default="{}")
    """This channel's data quality (:class:`gearwatch.floor.results.ChannelQuality`)."""

    channel: Mapped[Channel] = relationship()


class Curve(Base):
    __tablename__ = "curves"
    __table_args__ = (sa.UniqueConstraint("result_id", "channel_id", "name"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    result_id: Mapped[int] = mapped_column(sa.ForeignKey("result_versions.id", ondelete="CASCADE"))
    channel_id: Mapped[int] = mapped_column(sa.ForeignKey("channels.id", ondelete="CASCADE"))
    name: Mapped[str] = mapped_column(sa.String(64))
    length: Mapped[int]
    data: Mapped[bytes] = mapped_column(sa.LargeBinary)
    """Little-endian float32 values (:func:`float32_bytes`)."""

    def values(self) -> np.ndarray:
        return float32_array(self.data)


class ToothIndicator(Base):
    """result × channel × tooth × indicator → value, with the record's rig and time for trends."""

    __tablename__ = "tooth_indicators"
    __table_args__ = (
        sa.UniqueConstraint("result_id", "channel_id", "tooth", "indicator"),
        sa.Index(TREND_INDEX_NAME, "rig_id", "indicator", "tooth", "taken_at"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    result_id: Mapped[int] = mapped_column(sa.ForeignKey("result_versions.id", ondelete="CASCADE"))
    channel_id: Mapped[int] = mapped_column(sa.ForeignKey("channels.id", ondelete="CASCADE"))
    record_id: Mapped[int] = mapped_column(
        sa.ForeignKey("records.id", ondelete="CASCADE"), index=True
    )
    rig_id: Mapped[int] = mapped_column(sa.ForeignKey("rigs.id", ondelete="CASCADE"))
    taken_at: Mapped[dt.datetime] = mapped_column(UTCDateTime())
    tooth: Mapped[int]
    indicator: Mapped[str] = mapped_column(sa.String(32))
    value: Mapped[float]
    is_current: Mapped[bool] = mapped_column(default=True)
    """Copy of the result version's flag, so that a trend needs no join."""


class RecordMetric(Base):
    """result × channel × metric → value (whole-revolution metrics)."""

    __tablename__ = "record_metrics"
    __table_args__ = (
        sa.UniqueConstraint("result_id", "channel_id", "metric"),
        sa.Index("ix_record_metrics_trend", "rig_id", "metric", "taken_at"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    result_id: Mapped[int] = mapped_column(sa.ForeignKey("result_versions.id", ondelete="CASCADE"))
    channel_id: Mapped[int] = mapped_column(sa.ForeignKey("channels.id", ondelete="CASCADE"))
    record_id: Mapped[int] = mapped_column(
        sa.ForeignKey("records.id", ondelete="CASCADE"), index=True
    )
    rig_id: Mapped[int] = mapped_column(sa.ForeignKey("rigs.id", ondelete="CASCADE"))
    taken_at: Mapped[dt.datetime] = mapped_column(UTCDateTime())
    metric: Mapped[str] = mapped_column(sa.String(32))
    value: Mapped[float]
    is_current: Mapped[bool] = mapped_column(default=True)


class Reconciliation(Base):
    """One physics reconciliation of a stored record (issue 6): simulator configuration vs
    recording, run by a job; its input configuration, options, result JSON, HTML report and
    the updated configuration. The record's ``sha256`` is the provenance of the input data."""

    __tablename__ = "reconciliations"
    __table_args__ = (_check_in("status", RECONCILIATION_STATUSES, "status"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    record_id: Mapped[int] = mapped_column(
        sa.ForeignKey("records.id", ondelete="CASCADE"), index=True
    )
    reference_record_id: Mapped[int | None] = mapped_column(
        sa.ForeignKey("records.id", ondelete="SET NULL")
    )
    """A healthy record of the same rig whose residual is known model-form error."""
    status: Mapped[str] = mapped_column(sa.String(16), default="queued")
    options: Mapped[dict[str, Any]] = mapped_column(sa.JSON, default=dict)
    """samples_per_mesh, max_frequency_hz, max_findings, mechanisms, channel, forward_oversampling."""
    model_toml: Mapped[str | None] = mapped_column(sa.Text)
    """The simulator configuration used as the base; the rig's default model (filled in by the
    job, which knows the record's sample rate) when the request gave none."""
    result: Mapped[dict[str, Any] | None] = mapped_column(sa.JSON)
    """The issue-6 JSON (``ReconciliationResult.to_json()``) once done."""
    report_html: Mapped[str | None] = mapped_column(sa.Text)
    updated_model_toml: Mapped[str | None] = mapped_column(sa.Text)
    error: Mapped[str] = mapped_column(sa.Text, default="")
    """Why the reconciliation failed (empty otherwise)."""
    code_version: Mapped[str] = mapped_column(sa.String(100))
    """The code that created the request, then the code that ran it."""
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime(), default=utcnow)
    started_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime())
    finished_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime())

    record: Mapped[Record] = relationship(foreign_keys=[record_id])
    reference_record: Mapped[Record | None] = relationship(foreign_keys=[reference_record_id])


class ToothFrameReference(Base):
    """A campaign's tooth-frame reference per accelerometer channel (issue 11).

    Rigs without a tachometer have no absolute tooth 1: each tach-less record is aligned to this
    fingerprint (:mod:`dsp.toothframe`, :mod:`gearwatch.usecases.tachless`). ``frame`` is
    ``tachometer`` when it came from tach records (a mixed campaign keeps the tach's frame),
    ``mesh_phase`` when from the first accepted tach-less record. Fingerprints are float32
    bytes (:func:`float32_bytes`)."""

    __tablename__ = "tooth_frame_references"
    __table_args__ = (
        sa.UniqueConstraint("campaign_id", "channel"),
        _check_in("frame", ("tachometer", "mesh_phase"), "frame"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    campaign_id: Mapped[int] = mapped_column(sa.ForeignKey("campaigns.id", ondelete="CASCADE"))
    channel: Mapped[str] = mapped_column(sa.String(200))
    frame: Mapped[str] = mapped_column(sa.String(16))
    record_sha256: Mapped[str] = mapped_column(sa.String(64))
    """The record that founded the frame (its sha256: the provenance of every tooth number)."""
    records: Mapped[int] = mapped_column(default=1)
    """Records averaged into the fingerprints."""
    pinion_position: Mapped[float] = mapped_column(default=0.0)
    pinion_fingerprint: Mapped[bytes] = mapped_column(sa.LargeBinary)
    gear_fingerprint: Mapped[bytes | None] = mapped_column(sa.LargeBinary)
    speed_rpm: Mapped[float | None] = mapped_column(sa.Double)
    """Pinion speed of the latest record numbered in the frame (the next tach-less record's hint)."""
    updated_at: Mapped[dt.datetime] = mapped_column(UTCDateTime(), default=utcnow, onupdate=utcnow)


class AlarmRule(Base):
    """Per rig and indicator: baseline size, levels in baseline units, persistence, hysteresis.

    Indicators are per tooth (:data:`gearwatch.floor.results.TOOTH_INDICATORS`) or whole-record
    metrics (:data:`gearwatch.floor.results.METRIC_NAMES`, tracked as tooth 0). See
    :mod:`detection.alarms` for the semantics.
    """

    __tablename__ = "alarm_rules"
    __table_args__ = (sa.UniqueConstraint("rig_id", "indicator"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    rig_id: Mapped[int] = mapped_column(sa.ForeignKey("rigs.id", ondelete="CASCADE"))
    indicator: Mapped[str] = mapped_column(sa.String(32))
    baseline_records: Mapped[int] = mapped_column(default=8)
    warning_level: Mapped[float] = mapped_column(default=4.0)
    alarm_level: Mapped[float] = mapped_column(default=8.0)
    clear_level: Mapped[float] = mapped_column(default=2.0)
    """Hysteresis: an open alarm clears only after ``persistence`` records below this level."""
    persistence: Mapped[int] = mapped_column(default=2)
    spread_floor_fraction: Mapped[float] = mapped_column(default=0.05)
    spread_floor_abs: Mapped[float] = mapped_column(default=1e-9)
    min_baseline_records: Mapped[int | None] = mapped_column(default=None)
    """Scoring starts after this many records, the baseline grows to ``baseline_records``
    (short campaigns); NULL: a fixed baseline of ``baseline_records``."""
    cusum_reference: Mapped[float | None] = mapped_column(default=None)
    """CUSUM allowance k (baseline units); NULL with ``cusum_limit``: no sequential test."""
    cusum_limit: Mapped[float | None] = mapped_column(default=None)
    """CUSUM decision limit h (baseline units)."""
    enabled: Mapped[bool] = mapped_column(default=True)
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime(), default=utcnow)
    updated_at: Mapped[dt.datetime] = mapped_column(UTCDateTime(), default=utcnow)


class AlarmTrack(Base):
    """Evaluation state of one rule on one channel and tooth (baseline, persistence counters)."""

    __tablename__ = "alarm_tracks"
    __table_args__ = (sa.UniqueConstraint("rule_id", "channel_id", "tooth"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    rule_id: Mapped[int] = mapped_column(sa.ForeignKey("alarm_rules.id", ondelete="CASCADE"))
    channel_id: Mapped[int] = mapped_column(sa.ForeignKey("channels.id", ondelete="CASCADE"))
    tooth: Mapped[int]
    state: Mapped[dict[str, Any]] = mapped_column(sa.JSON)
    """:meth:`detection.alarms.TrackState.to_dict`."""
    last_taken_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime())
    updated_at: Mapped[dt.datetime] = mapped_column(UTCDateTime(), default=utcnow)


class Alarm(Base):
    __tablename__ = "alarms"
    __table_args__ = (
        sa.Index("ix_alarms_rig_id_state", "rig_id", "state"),
        _check_in("state", ALARM_STATES, "state"),
        _check_in("severity", ALARM_SEVERITIES, "severity"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    rig_id: Mapped[int] = mapped_column(sa.ForeignKey("rigs.id", ondelete="CASCADE"))
    rule_id: Mapped[int | None] = mapped_column(
        sa.ForeignKey("alarm_rules.id", ondelete="SET NULL")
    )
    channel_id: Mapped[int] = mapped_column(sa.ForeignKey("channels.id", ondelete="CASCADE"))
    tooth: Mapped[int]
    """Pinion tooth (1-based); 0 for a whole-record metric."""
    indicator: Mapped[str] = mapped_column(sa.String(32))
    state: Mapped[str] = mapped_column(sa.String(16))
    severity: Mapped[str] = mapped_column(sa.String(16))
    """Highest level reached so far (``warning`` or ``alarm``)."""
    raised_at: Mapped[dt.datetime] = mapped_column(UTCDateTime())
    """``taken_at`` of the record that raised the alarm."""
    raised_record_id: Mapped[int | None] = mapped_column(
        sa.ForeignKey("records.id", ondelete="SET NULL")
    )
    last_value: Mapped[float]
    last_score: Mapped[float]
    """Last value in baseline units (positive = worse)."""
    baseline_centre: Mapped[float]
    baseline_spread: Mapped[float]
    evidence: Mapped[str | None] = mapped_column(sa.String(16), default=None)
    """What raised the alarm: ``level`` or ``cusum`` (:attr:`detection.alarms.Transition.evidence`);
    NULL for alarms raised before it was recorded."""
    acknowledged_by: Mapped[str | None] = mapped_column(sa.String(200))
    acknowledged_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime())
    ack_comment: Mapped[str | None] = mapped_column(sa.Text)
    cleared_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime())
    updated_at: Mapped[dt.datetime] = mapped_column(UTCDateTime(), default=utcnow)

    channel: Mapped[Channel] = relationship()
    history: Mapped[list[AlarmEvent]] = relationship(
        back_populates="alarm", order_by="AlarmEvent.id", cascade="all, delete-orphan"
    )

    @property
    def is_open(self) -> bool:
        return self.state != "cleared"


class AlarmEvent(Base):
    """One state change of an alarm (its history)."""

    __tablename__ = "alarm_events"
    __table_args__ = (_check_in("state", ALARM_STATES, "state"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    alarm_id: Mapped[int] = mapped_column(
        sa.ForeignKey("alarms.id", ondelete="CASCADE"), index=True
    )
    state: Mapped[str] = mapped_column(sa.String(16))
    at: Mapped[dt.datetime] = mapped_column(UTCDateTime())
    """The record's ``taken_at`` for evaluation changes; wall-clock time for acknowledgements."""
    record_id: Mapped[int | None] = mapped_column(sa.ForeignKey("records.id", ondelete="SET NULL"))
    value: Mapped[float | None]
    score: Mapped[float | None]
    who: Mapped[str | None] = mapped_column(sa.String(200))
    comment: Mapped[str | None] = mapped_column(sa.Text)

    alarm: Mapped[Alarm] = relationship(back_populates="history")


class ApiKey(Base):
    """An API key: ``gw_<prefix>_<secret>``; only sha256 of the whole key is kept."""

    __tablename__ = "api_keys"
    __table_args__ = (_check_in("role", ROLES, "role"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    prefix: Mapped[str] = mapped_column(sa.String(32), unique=True)
    key_sha256: Mapped[str] = mapped_column(sa.String(64))
    name: Mapped[str] = mapped_column(sa.String(200))
    role: Mapped[str] = mapped_column(sa.String(16))
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime(), default=utcnow)
    last_used_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime())
    revoked_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime())


class AuditEntry(Base):
    __tablename__ = "audit_log"
    __table_args__ = (sa.Index("ix_audit_log_at", "at"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    who: Mapped[str] = mapped_column(sa.String(200))
    action: Mapped[str] = mapped_column(sa.String(100))
    target: Mapped[str] = mapped_column(sa.String(300), default="")
    at: Mapped[dt.datetime] = mapped_column(UTCDateTime(), default=utcnow)
    details: Mapped[dict[str, Any]] = mapped_column(sa.JSON, default=dict)


NOTIFICATION_STATUSES = ("pending", "delivered", "failed")


class AlarmWebhook(Base):
    """A rig's webhook: every alarm state change of the rig is POSTed to ``url`` as JSON
    (besides the global ``GEARWATCH_ALARM_WEBHOOK_URL``)."""

    __tablename__ = "alarm_webhooks"
    __table_args__ = (sa.UniqueConstraint("rig_id", "url"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    rig_id: Mapped[int] = mapped_column(sa.ForeignKey("rigs.id", ondelete="CASCADE"), index=True)
    url: Mapped[str] = mapped_column(sa.String(2000))
    description: Mapped[str] = mapped_column(sa.String(200), default="")
    enabled: Mapped[bool] = mapped_column(default=True)
    created_by: Mapped[str] = mapped_column(sa.String(200), default="")
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime(), default=utcnow)


class AlarmNotification(Base):
    """The outbox: one alarm state change for one destination, written in the same transaction
    as the change, then delivered (with retries and back-off) by the process that made it."""

    __tablename__ = "alarm_notifications"
    __table_args__ = (
        sa.Index("ix_alarm_notifications_status_next_attempt_at", "status", "next_attempt_at"),
        _check_in("status", NOTIFICATION_STATUSES, "status"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    rig_id: Mapped[int] = mapped_column(sa.ForeignKey("rigs.id", ondelete="CASCADE"), index=True)
    alarm_id: Mapped[int | None] = mapped_column(
        sa.ForeignKey("alarms.id", ondelete="SET NULL"), index=True
    )
    webhook_id: Mapped[int | None] = mapped_column(
        sa.ForeignKey("alarm_webhooks.id", ondelete="SET NULL")
    )
    """``None`` for the global webhook."""
    url: Mapped[str] = mapped_column(sa.String(2000))
    payload: Mapped[dict[str, Any]] = mapped_column(sa.JSON)
    status: Mapped[str] = mapped_column(sa.String(16), default="pending")
    attempts: Mapped[int] = mapped_column(default=0)
    next_attempt_at: Mapped[dt.datetime] = mapped_column(UTCDateTime(), default=utcnow)
    last_error: Mapped[str] = mapped_column(sa.Text, default="")
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime(), default=utcnow)
    delivered_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime())


class NotificationAttempt(Base):
    """One delivery attempt of a notification: when, the HTTP status or the error."""

    __tablename__ = "notification_attempts"

    id: Mapped[int] = mapped_column(primary_key=True)
    notification_id: Mapped[int] = mapped_column(
        sa.ForeignKey("alarm_notifications.id", ondelete="CASCADE"), index=True
    )
    at: Mapped[dt.datetime] = mapped_column(UTCDateTime(), default=utcnow)
    status_code: Mapped[int | None]
    error: Mapped[str] = mapped_column(sa.Text, default="")
    duration_ms: Mapped[float] = mapped_column(default=0.0)
