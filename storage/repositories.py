"""Every database query of gearwatch, grouped by entity.

Repositories take a :class:`~sqlalchemy.orm.Session`, add and query, and ``flush`` — they never
commit. The caller (a request handler, a job, a CLI command) owns the transaction, typically
with :func:`storage.db.session_scope`.

Missing rows raise :class:`gearwatch.errors.NotFound`; a state change that is not allowed
(e.g. acknowledging a cleared alarm) raises :class:`gearwatch.errors.Conflict`.
"""

from __future__ import annotations

import builtins
import dataclasses
import datetime as dt
import hashlib
import hmac
import json
import math
import secrets
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session, selectinload

from gearwatch.errors import Conflict, InputError, NotFound
from gearwatch.results import METRIC_NAMES, TOOTH_INDICATORS, RecordAnalysis
from ingest.types import Campaign as CampaignConfig
from ingest.types import RigConfig
from storage.models import (
    ALARM_STATES,
    RECORD_STATUSES,
    ROLES,
    Alarm,
    AlarmEvent,
    AlarmRule,
    AlarmTrack,
    ApiKey,
    AuditEntry,
    Campaign,
    Channel,
    ChannelResult,
    Curve,
    Reconciliation,
    Record,
    RecordMetric,
    ResultVersion,
    Rig,
    ToothIndicator,
    float32_array,
    float32_bytes,
    utcnow,
)

ALARM_INDICATORS = TOOTH_INDICATORS + METRIC_NAMES
"""Indicators an alarm rule can watch: per tooth, or whole-record metrics (tooth 0)."""


def parameters_sha256(parameters: dict[str, Any]) -> str:
    """sha256 of the canonical JSON of an analysis parameter set (identifies a result version)."""
    canonical = json.dumps(parameters, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(canonical.encode()).hexdigest()


def json_safe(value: Any) -> Any:
    """Plain JSON: NaN and infinities become ``None`` (PostgreSQL's json refuses them)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, np.generic):
        return json_safe(value.item())
    return value


def _get(session: Session, model: type[Any], key: int, what: str) -> Any:
    row = session.get(model, key)
    if row is None:
        raise NotFound(f"{what} {key} not found")
    return row


class RigRepository:
    def __init__(self, session: Session) -> None:
        self.session = session

    def get(self, rig_id: int) -> Rig:
        return _get(self.session, Rig, rig_id, "rig")

    def get_by_name(self, name: str) -> Rig | None:
        return self.session.scalar(sa.select(Rig).where(Rig.name == name))

    def list(self) -> builtins.list[Rig]:
        return list(self.session.scalars(sa.select(Rig).order_by(Rig.name)))

    def ensure(self, config: RigConfig) -> Rig:
        """The rig named ``config.id``, created or brought up to date with the manifest."""
        rig = self.get_by_name(config.id)
        if rig is None:
            rig = Rig(name=config.id)
            self.session.add(rig)
        rig.pinion_teeth = config.pinion_teeth
        rig.gear_teeth = config.gear_teeth
        rig.tooth1_pitch_angle_deg = float(config.tooth1_pitch_angle_deg)
        self.session.flush()
        return rig


class CampaignRepository:
    def __init__(self, session: Session) -> None:
        self.session = session

    def get(self, campaign_id: int) -> Campaign:
        return _get(self.session, Campaign, campaign_id, "campaign")

    def get_by_name(self, name: str) -> Campaign | None:
        return self.session.scalar(sa.select(Campaign).where(Campaign.name == name))

    def list(self, rig_id: int | None = None) -> builtins.list[Campaign]:
        query = sa.select(Campaign).order_by(Campaign.name)
        if rig_id is not None:
            query = query.where(Campaign.rig_id == rig_id)
        return list(self.session.scalars(query))

    def ensure(self, config: CampaignConfig) -> Campaign:
        """The campaign named ``config.id`` with its rig and channels, created or updated.

        A campaign cannot move to another rig (:class:`Conflict`).
        """
        rig = RigRepository(self.session).ensure(config.rig)
        campaign = self.get_by_name(config.id)
        if campaign is None:
            campaign = Campaign(name=config.id, rig_id=rig.id)
            self.session.add(campaign)
        elif campaign.rig_id != rig.id:
            raise Conflict(
                f"campaign {config.id!r} belongs to rig {campaign.rig.name!r}, not {rig.name!r}"
            )
        campaign.description = config.description
        campaign.manifest = json_safe(
            {
                "rig": dataclasses.asdict(config.rig),
                "sample_rate_hz": config.sample_rate_hz,
                "tachometer": (
                    None if config.tachometer is None else dataclasses.asdict(config.tachometer)
                ),
                "channels": [dataclasses.asdict(c) for c in config.channels],
                "root": str(config.root),
            }
        )
        self.session.flush()
        existing = {c.name: c for c in self.channels(campaign.id)}
        for channel in config.channels:
            row = existing.get(channel.name)
            if row is None:
                self.session.add(
                    Channel(
                        campaign_id=campaign.id,
                        name=channel.name,
                        kind=channel.kind,
                        unit=channel.unit,
                    )
                )
            else:
                row.kind, row.unit = channel.kind, channel.unit
        self.session.flush()
        return campaign

    def channels(self, campaign_id: int) -> builtins.list[Channel]:
        query = sa.select(Channel).where(Channel.campaign_id == campaign_id).order_by(Channel.id)
        return list(self.session.scalars(query))

    def channel(self, campaign_id: int, name: str) -> Channel:
        row = self.session.scalar(
            sa.select(Channel).where(Channel.campaign_id == campaign_id, Channel.name == name)
        )
        if row is None:
            raise NotFound(f"channel {name!r} not found in campaign {campaign_id}")
        return row


@dataclasses.dataclass(frozen=True)
class CurveData:
    channel: str
    name: str
    values: np.ndarray
    """float32"""


class RecordRepository:
    def __init__(self, session: Session) -> None:
        self.session = session

    # -- records --------------------------------------------------------------------------
    def get(self, record_id: int) -> Record:
        return _get(self.session, Record, record_id, "record")

    def get_by_sha256(self, campaign_id: int, sha256: str) -> Record | None:
        return self.session.scalar(
            sa.select(Record).where(Record.campaign_id == campaign_id, Record.sha256 == sha256)
        )

    def find_by_sha256(self, sha256: str) -> builtins.list[Record]:
        """Every record of that content, across campaigns (usually zero or one)."""
        return list(self.session.scalars(sa.select(Record).where(Record.sha256 == sha256)))

    def _filtered(
        self,
        query: sa.Select[Any],
        campaign_id: int | None,
        rig_id: int | None,
        status: str | None,
        since: dt.datetime | None,
        until: dt.datetime | None,
    ) -> sa.Select[Any]:
        if campaign_id is not None:
            query = query.where(Record.campaign_id == campaign_id)
        if rig_id is not None:
            query = query.where(Record.rig_id == rig_id)
        if status is not None:
            if status not in RECORD_STATUSES:
                raise InputError(f"unknown record status {status!r}")
            query = query.where(Record.status == status)
        if since is not None:
            query = query.where(Record.taken_at >= since)
        if until is not None:
            query = query.where(Record.taken_at < until)
        return query

    def list(
        self,
        *,
        campaign_id: int | None = None,
        rig_id: int | None = None,
        status: str | None = None,
        since: dt.datetime | None = None,
        until: dt.datetime | None = None,
        limit: int | None = 100,
        offset: int = 0,
        newest_first: bool = False,
    ) -> builtins.list[Record]:
        """Records filtered by campaign, rig, status and ``since <= taken_at < until``."""
        order = Record.taken_at.desc() if newest_first else Record.taken_at
        query = self._filtered(
            sa.select(Record), campaign_id, rig_id, status, since, until
        ).order_by(order, Record.id)
        if limit is not None:
            query = query.limit(limit)
        return list(self.session.scalars(query.offset(offset)))

    def count(
        self,
        *,
        campaign_id: int | None = None,
        rig_id: int | None = None,
        status: str | None = None,
        since: dt.datetime | None = None,
        until: dt.datetime | None = None,
    ) -> int:
        query = self._filtered(
            sa.select(sa.func.count(Record.id)), campaign_id, rig_id, status, since, until
        )
        return int(self.session.scalar(query) or 0)

    def status_counts(self, *, campaign_id: int | None = None) -> dict[str, int]:
        query = sa.select(Record.status, sa.func.count(Record.id)).group_by(Record.status)
        if campaign_id is not None:
            query = query.where(Record.campaign_id == campaign_id)
        counts = dict.fromkeys(RECORD_STATUSES, 0)
        counts.update({status: int(n) for status, n in self.session.execute(query)})
        return counts

    def add(
        self,
        campaign: Campaign,
        *,
        sha256: str,
        file_name: str,
        raw_location: str,
        taken_at: dt.datetime,
        size_bytes: int = 0,
        label: str = "",
    ) -> Record:
        """A new ``pending`` record (``Conflict`` when that content is already in the campaign)."""
        if self.get_by_sha256(campaign.id, sha256) is not None:
            raise Conflict(f"record {sha256[:12]}… is already in campaign {campaign.name!r}")
        record = Record(
            campaign_id=campaign.id,
            rig_id=campaign.rig_id,
            sha256=sha256,
            file_name=file_name,
            raw_location=raw_location,
            size_bytes=size_bytes,
            taken_at=taken_at,
            label=label,
            status="pending",
            reason="",
            quality={},
        )
        self.session.add(record)
        self.session.flush()
        return record

    def mark_rejected(self, record: Record, reason: str) -> Record:
        record.status = "rejected"
        record.reason = reason
        record.processed_at = utcnow()
        self.session.flush()
        return record

    def mark_accepted(self, record: Record, analysis: RecordAnalysis) -> Record:
        quality = analysis.quality
        record.status = "accepted"
        record.reason = ""
        record.speed_rpm = float(analysis.speed_rpm)
        record.speed_min_rpm = float(quality.speed_min_rpm)
        record.speed_max_rpm = float(quality.speed_max_rpm)
        record.speed_variation = float(quality.speed_variation)
        record.revolutions = int(analysis.revolutions)
        record.quality = json_safe(dataclasses.asdict(quality))
        record.processed_at = utcnow()
        self.session.flush()
        return record

    # -- result versions -----------------------------------------------------------------
    def results(self, record_id: int) -> builtins.list[ResultVersion]:
        """Every result version of a record, oldest first."""
        query = (
            sa.select(ResultVersion)
            .where(ResultVersion.record_id == record_id)
            .order_by(ResultVersion.id)
        )
        return list(self.session.scalars(query))

    def get_result(self, result_id: int) -> ResultVersion:
        return _get(self.session, ResultVersion, result_id, "result version")

    def current_result(self, record_id: int) -> ResultVersion | None:
        return self.session.scalar(
            sa.select(ResultVersion).where(
                ResultVersion.record_id == record_id, ResultVersion.is_current.is_(True)
            )
        )

    def result_for_parameters(
        self, record_id: int, parameters: dict[str, Any]
    ) -> ResultVersion | None:
        return self.session.scalar(
            sa.select(ResultVersion).where(
                ResultVersion.record_id == record_id,
                ResultVersion.parameters_sha256 == parameters_sha256(json_safe(parameters)),
            )
        )

    def add_result(self, record: Record, analysis: RecordAnalysis) -> ResultVersion:
        """Store one analysis as the record's new current result version.

        Earlier versions are kept (no longer current). The same parameters twice is a
        :class:`Conflict` — look it up with :meth:`result_for_parameters` first.
        """
        parameters = json_safe(dict(analysis.provenance.parameters))
        digest = parameters_sha256(parameters)
        if self.result_for_parameters(record.id, parameters) is not None:
            raise Conflict(f"record {record.id} already has a result for these parameters")
        self.session.execute(
            sa.update(ResultVersion)
            .where(ResultVersion.record_id == record.id)
            .values(is_current=False)
        )
        for model in (ToothIndicator, RecordMetric):  # bulk-inserted: never in the session
            self.session.execute(
                sa.update(model).where(model.record_id == record.id).values(is_current=False),
                execution_options={"synchronize_session": False},
            )
        result = ResultVersion(
            record_id=record.id,
            parameters=parameters,
            parameters_sha256=digest,
            code_version=analysis.provenance.code_version,
            is_current=True,
            speed_rpm=float(analysis.speed_rpm),
            revolutions=int(analysis.revolutions),
            samples_per_rev=int(analysis.samples_per_rev),
        )
        self.session.add(result)
        self.session.flush()
        channels = {c.name: c for c in CampaignRepository(self.session).channels(record.campaign_id)}
        indicator_rows: list[dict[str, Any]] = []
        metric_rows: list[dict[str, Any]] = []
        for ch in analysis.channels:
            channel = channels.get(ch.channel)
            if channel is None:
                channel = Channel(
                    campaign_id=record.campaign_id, name=ch.channel, kind="accelerometer", unit=""
                )
                self.session.add(channel)
                self.session.flush()
                channels[ch.channel] = channel
            self.session.add(
                ChannelResult(
                    result_id=result.id,
                    channel_id=channel.id,
                    revolutions=int(ch.revolutions),
                    gear_revolutions=int(ch.gear_revolutions),
                    speed_rpm=float(ch.speed_rpm),
                    samples_per_rev=int(ch.samples_per_rev),
                    worst_tooth=None if ch.worst_tooth is None else int(ch.worst_tooth),
                    baseline_stats=json_safe(dict(getattr(ch, "baseline_stats", {}) or {})),
                )
            )
            for name, values in ch.curves.items():
                data = float32_bytes(values)
                self.session.add(
                    Curve(
                        result_id=result.id,
                        channel_id=channel.id,
                        name=name,
                        length=len(data) // 4,
                        data=data,
                    )
                )
            common = {
                "result_id": result.id,
                "channel_id": channel.id,
                "record_id": record.id,
                "rig_id": record.rig_id,
                "taken_at": record.taken_at,
            }
            for tooth in ch.teeth:
                for indicator, value in tooth.indicators().items():
                    if math.isfinite(value):  # NaN has no place in a trend index
                        indicator_rows.append(
                            {**common, "tooth": int(tooth.tooth), "indicator": indicator,
                             "value": float(value)}
                        )
            for metric, value in ch.metrics.items():
                if math.isfinite(float(value)):
                    metric_rows.append({**common, "metric": metric, "value": float(value)})
        self.session.flush()
        if indicator_rows:
            self.session.execute(sa.insert(ToothIndicator), indicator_rows)
        if metric_rows:
            self.session.execute(sa.insert(RecordMetric), metric_rows)
        self.session.flush()
        return result

    def channel_results(self, result_id: int) -> builtins.list[ChannelResult]:
        query = (
            sa.select(ChannelResult)
            .where(ChannelResult.result_id == result_id)
            .options(selectinload(ChannelResult.channel))
            .order_by(ChannelResult.id)
        )
        return list(self.session.scalars(query))

    def curves(
        self,
        result_id: int,
        *,
        channel: str | None = None,
        names: Sequence[str] | None = None,
    ) -> builtins.list[CurveData]:
        """Curves of a result version as float32 arrays, optionally one channel / some names."""
        query = (
            sa.select(Channel.name, Curve.name, Curve.data)
            .join(Channel, Channel.id == Curve.channel_id)
            .where(Curve.result_id == result_id)
            .order_by(Curve.id)
        )
        if channel is not None:
            query = query.where(Channel.name == channel)
        if names is not None:
            query = query.where(Curve.name.in_(list(names)))
        return [
            CurveData(channel_name, curve_name, float32_array(data))
            for channel_name, curve_name, data in self.session.execute(query)
        ]

    def curve_index(self, result_id: int) -> builtins.list[tuple[str, str, int]]:
        """(channel, curve name, length) of every curve of a result version, without the data."""
        query = (
            sa.select(Channel.name, Curve.name, Curve.length)
            .join(Channel, Channel.id == Curve.channel_id)
            .where(Curve.result_id == result_id)
            .order_by(Curve.id)
        )
        return [(channel, name, int(length)) for channel, name, length in self.session.execute(query)]

    def tooth_indicators(self, result_id: int) -> builtins.list[ToothIndicator]:
        query = (
            sa.select(ToothIndicator)
            .where(ToothIndicator.result_id == result_id)
            .order_by(ToothIndicator.channel_id, ToothIndicator.tooth, ToothIndicator.indicator)
        )
        return list(self.session.scalars(query))

    def metrics(self, result_id: int) -> builtins.list[RecordMetric]:
        query = (
            sa.select(RecordMetric)
            .where(RecordMetric.result_id == result_id)
            .order_by(RecordMetric.channel_id, RecordMetric.metric)
        )
        return list(self.session.scalars(query))

    def mean_baseline_stats(
        self, campaign_id: int, channel: str, *, before: dt.datetime, limit: int | None = None
    ) -> dict[str, float]:
        """Mean of each ``baseline_stats`` entry over the campaign's accepted records taken
        before ``before`` (current result versions; the earliest ``limit`` records when given).

        This is what the pipeline needs for the NA4/NB4 running baselines.
        """
        query = (
            sa.select(ChannelResult.baseline_stats)
            .join(ResultVersion, ResultVersion.id == ChannelResult.result_id)
            .join(Record, Record.id == ResultVersion.record_id)
            .join(Channel, Channel.id == ChannelResult.channel_id)
            .where(
                Record.campaign_id == campaign_id,
                Record.status == "accepted",
                Record.taken_at < before,
                ResultVersion.is_current.is_(True),
                Channel.name == channel,
            )
            .order_by(Record.taken_at)
        )
        if limit is not None:
            query = query.limit(limit)
        sums: dict[str, float] = {}
        counts: dict[str, int] = {}
        for (stats,) in self.session.execute(query):
            for key, value in (stats or {}).items():
                if isinstance(value, int | float) and math.isfinite(value):
                    sums[key] = sums.get(key, 0.0) + float(value)
                    counts[key] = counts.get(key, 0) + 1
        return {key: sums[key] / counts[key] for key in sums}


class TrendPoint(NamedTuple):
    record_id: int
    taken_at: dt.datetime
    channel: str
    tooth: int
    """1-based pinion tooth; 0 for a whole-record metric."""
    value: float


class TrendMatrix(NamedTuple):
    """A per-tooth trend of one channel: ``values[i, j]`` belongs to ``record_ids[i]`` (taken
    at ``taken_at[i]``) and ``teeth[j]``; NaN where the record has no value for the tooth."""

    channel: str | None
    teeth: builtins.list[int]
    record_ids: builtins.list[int]
    taken_at: builtins.list[dt.datetime]
    values: np.ndarray


class TrendRepository:
    def __init__(self, session: Session) -> None:
        self.session = session

    def trend(
        self,
        rig_id: int,
        indicator: str,
        tooth: int | None = None,
        *,
        channel: str | None = None,
        since: dt.datetime | None = None,
        until: dt.datetime | None = None,
    ) -> builtins.list[TrendPoint]:
        """Per-tooth indicator over time (current result versions of accepted records), ordered
        by ``taken_at``, then channel (in creation order) and tooth. One query on the trend
        index, no join."""
        if indicator not in TOOTH_INDICATORS:
            raise InputError(
                f"unknown tooth indicator {indicator!r} (known: {', '.join(TOOTH_INDICATORS)})"
            )
        ti = ToothIndicator
        query = (
            sa.select(ti.record_id, ti.taken_at, ti.channel_id, ti.tooth, ti.value)
            .where(ti.rig_id == rig_id, ti.indicator == indicator, ti.is_current.is_(True))
            .order_by(ti.taken_at, ti.channel_id, ti.tooth)
        )
        return self._points(query, ti, rig_id, tooth, channel, since, until)

    def trend_matrix(
        self,
        rig_id: int,
        indicator: str,
        tooth: int | None = None,
        *,
        channel: str | None = None,
        pinion_teeth: int | None = None,
    ) -> TrendMatrix:
        """:meth:`trend` of one channel as a records × teeth matrix.

        Without ``channel``, the first channel by name that has values. Columns are
        ``[tooth]``, else teeth 1…``pinion_teeth``, else the teeth found; records are in
        ``taken_at`` order (then by id).

        A year of 20 teeth is 7300 cells: they are read in one query without timestamps or
        sorting (both cost more than the rest), no per-row objects; the rig's records, in time
        order from their index, give each record's row and time.
        """
        if indicator not in TOOTH_INDICATORS:
            raise InputError(
                f"unknown tooth indicator {indicator!r} (known: {', '.join(TOOTH_INDICATORS)})"
            )
        ti = ToothIndicator
        query = sa.select(ti.record_id, ti.channel_id, ti.tooth, ti.value).where(
            ti.rig_id == rig_id, ti.indicator == indicator, ti.is_current.is_(True)
        )
        names = self.channel_names(rig_id)
        if tooth is not None:
            query = query.where(ti.tooth == tooth)
        if channel is not None:
            query = query.where(ti.channel_id.in_([k for k, n in names.items() if n == channel]))
        cells = self.session.connection().execute(query).all()
        teeth = [tooth] if tooth is not None else list(range(1, (pinion_teeth or 0) + 1))
        if not cells:
            return TrendMatrix(channel, teeth, [], [], np.empty((0, len(teeth))))
        record_col, channel_col, tooth_col, value_col = zip(*cells, strict=True)
        if channel is None:
            channel = min(names[c] for c in set(channel_col))
        keep = np.isin(np.asarray(channel_col), [k for k, n in names.items() if n == channel])
        cell_records = np.asarray(record_col)[keep]
        tooth_numbers = np.asarray(tooth_col)[keep]
        values = np.asarray(value_col, dtype=np.float64)[keep]
        if not teeth:
            teeth = [int(t) for t in np.unique(tooth_numbers)]

        times = self.session.execute(
            sa.select(Record.id, Record.taken_at)
            .where(Record.rig_id == rig_id)
            .order_by(Record.taken_at, Record.id)
        ).all()
        ids_in_time_order = np.asarray([row[0] for row in times])
        by_id = np.argsort(ids_in_time_order)
        found = np.searchsorted(ids_in_time_order, cell_records, sorter=by_id)
        time_rank = by_id[np.minimum(found, len(by_id) - 1)]
        # A cell always has its record (same rig, foreign key); the check costs nothing.
        known = ids_in_time_order[time_rank] == cell_records
        ranks_used = np.unique(time_rank[known])
        row = np.searchsorted(ranks_used, time_rank)
        columns = np.asarray(teeth)
        column = np.minimum(np.searchsorted(columns, tooth_numbers), len(columns) - 1)
        known &= columns[column] == tooth_numbers
        matrix = np.full((len(ranks_used), len(teeth)), np.nan)
        matrix[row[known], column[known]] = values[known]
        return TrendMatrix(
            channel,
            teeth,
            [int(i) for i in ids_in_time_order[ranks_used]],
            [times[i][1] for i in ranks_used],
            matrix,
        )

    def _points(
        self,
        query: Any,
        model: type[ToothIndicator] | type[RecordMetric],
        rig_id: int,
        tooth: int | None,
        channel: str | None,
        since: dt.datetime | None,
        until: dt.datetime | None,
    ) -> builtins.list[TrendPoint]:
        # Channel names come from a small lookup rather than a join: a year of 20 teeth is
        # 7300 rows, and a per-row join doubles the query time on SQLite.
        names = self.channel_names(rig_id)
        if tooth is not None and model is ToothIndicator:
            query = query.where(ToothIndicator.tooth == tooth)
        if channel is not None:
            ids = [key for key, name in names.items() if name == channel]
            query = query.where(model.channel_id.in_(ids))
        if since is not None:
            query = query.where(model.taken_at >= since)
        if until is not None:
            query = query.where(model.taken_at < until)
        make = TrendPoint._make
        return [
            make((record_id, taken_at, names[channel_id], tooth_number, value))
            for record_id, taken_at, channel_id, tooth_number, value in (
                # Core rows fetched at once: no ORM loading overhead, no row-by-row fetch.
                self.session.connection().execute(query).all()
            )
        ]

    def channel_names(self, rig_id: int) -> dict[int, str]:
        """Channel id → name for every campaign of the rig."""
        query = (
            sa.select(Channel.id, Channel.name)
            .join(Campaign, Campaign.id == Channel.campaign_id)
            .where(Campaign.rig_id == rig_id)
        )
        return {channel_id: name for channel_id, name in self.session.execute(query)}

    def metric_trend(
        self,
        rig_id: int,
        metric: str,
        *,
        channel: str | None = None,
        since: dt.datetime | None = None,
        until: dt.datetime | None = None,
    ) -> builtins.list[TrendPoint]:
        """A whole-record metric over time (tooth 0 in every point)."""
        if metric not in METRIC_NAMES:
            raise InputError(f"unknown metric {metric!r} (known: {', '.join(METRIC_NAMES)})")
        rm = RecordMetric
        query = (
            sa.select(rm.record_id, rm.taken_at, rm.channel_id, sa.literal(0), rm.value)
            .where(rm.rig_id == rig_id, rm.metric == metric, rm.is_current.is_(True))
            .order_by(rm.taken_at, rm.channel_id)
        )
        return self._points(query, rm, rig_id, None, channel, since, until)


RULE_FIELDS = (
    "baseline_records",
    "warning_level",
    "alarm_level",
    "clear_level",
    "persistence",
    "spread_floor_fraction",
    "spread_floor_abs",
    "enabled",
)

DEFAULT_RULES: dict[str, dict[str, Any]] = {
    "mci_depth": {"spread_floor_abs": 0.1},
    "kurtosis": {"spread_floor_abs": 0.1},
    "raw_kurtosis": {"spread_floor_abs": 0.1},
}
"""Rules every new rig gets (:meth:`AlarmRuleRepository.ensure_defaults`): the MCI well depth
per tooth, the whole-record kurtosis of the average and of the raw signal (these work without
tooth counts; the raw one also sees non-synchronous faults such as bearings, which averaging
removes). Other
settings are the defaults of :class:`storage.models.AlarmRule`: 8 baseline records, warning 4,
alarm 8, clear 2 (baseline units), persistence 2. Absolute spread floors — 0.1 Np for the
well depth, 0.1 for kurtosis — are the smallest change that counts: a baseline learned from a
few very repeatable records (simulations; a quiet rig) otherwise turns a 0.2 Np change into
"8 baseline units". 0.1 Np is a 10 % change of the geometric-mean spectral magnitude of a mesh
period. On four simulated 12-day campaigns (seeds 2–5, spall on teeth 5, 11, 20, 1 from day
10) a 0.02 Np floor raised warnings or alarms on the tooth before the spalled one as well
(+0.2 Np from the edge of its well); with 0.1 Np only the spalled tooth is flagged: an alarm
on day 11 (two campaigns) or a warning on day 12 (two campaigns, smaller wells)."""


class ReconciliationRepository:
    """Physics reconciliations of stored records: queued → running → done | failed."""

    def __init__(self, session: Session) -> None:
        self.session = session

    def get(self, reconciliation_id: int) -> Reconciliation:
        return _get(self.session, Reconciliation, reconciliation_id, "reconciliation")

    def add(
        self,
        record: Record,
        *,
        options: dict[str, Any],
        code_version: str,
        model_toml: str | None = None,
        reference: Record | None = None,
    ) -> Reconciliation:
        """A queued reconciliation of ``record`` (``model_toml`` None: the rig's default model)."""
        row = Reconciliation(
            record_id=record.id,
            reference_record_id=None if reference is None else reference.id,
            status="queued",
            options=json_safe(options),
            model_toml=model_toml,
            code_version=code_version,
            created_at=utcnow(),
        )
        self.session.add(row)
        self.session.flush()
        return row

    def list_for_record(self, record_id: int) -> builtins.list[Reconciliation]:
        """Newest first."""
        query = (
            sa.select(Reconciliation)
            .where(Reconciliation.record_id == record_id)
            .order_by(Reconciliation.created_at.desc(), Reconciliation.id.desc())
        )
        return list(self.session.scalars(query))

    def start(self, row: Reconciliation, code_version: str) -> bool:
        """Mark ``row`` running with the code that runs it; False when it already finished
        (a message delivered twice). A ``running`` row is started again: its worker died."""
        if row.status in ("done", "failed"):
            return False
        row.status = "running"
        row.code_version = code_version
        row.started_at = utcnow()
        row.error = ""
        self.session.flush()
        return True

    def finish(
        self,
        row: Reconciliation,
        *,
        model_toml: str,
        result: dict[str, Any],
        report_html: str,
        updated_model_toml: str,
    ) -> Reconciliation:
        row.status = "done"
        row.model_toml = model_toml
        row.result = json_safe(result)
        row.report_html = report_html
        row.updated_model_toml = updated_model_toml
        row.error = ""
        row.finished_at = utcnow()
        self.session.flush()
        return row

    def fail(self, row: Reconciliation, reason: str, *, model_toml: str | None = None) -> Reconciliation:
        row.status = "failed"
        row.error = reason or "failed"
        if model_toml is not None:
            row.model_toml = model_toml
        row.finished_at = utcnow()
        self.session.flush()
        return row


class AlarmRuleRepository:
    def __init__(self, session: Session) -> None:
        self.session = session

    def get(self, rule_id: int) -> AlarmRule:
        return _get(self.session, AlarmRule, rule_id, "alarm rule")

    def list(self, rig_id: int | None = None, *, enabled_only: bool = False) -> builtins.list[AlarmRule]:
        query = sa.select(AlarmRule).order_by(AlarmRule.rig_id, AlarmRule.indicator)
        if rig_id is not None:
            query = query.where(AlarmRule.rig_id == rig_id)
        if enabled_only:
            query = query.where(AlarmRule.enabled.is_(True))
        return list(self.session.scalars(query))

    def get_for(self, rig_id: int, indicator: str) -> AlarmRule | None:
        return self.session.scalar(
            sa.select(AlarmRule).where(AlarmRule.rig_id == rig_id, AlarmRule.indicator == indicator)
        )

    @staticmethod
    def _validate(indicator: str, values: dict[str, Any]) -> None:
        from detection.alarms import RuleSettings

        if indicator not in ALARM_INDICATORS:
            raise InputError(
                f"unknown indicator {indicator!r} (known: {', '.join(ALARM_INDICATORS)})"
            )
        settings = {k: v for k, v in values.items() if k != "enabled"}
        try:
            RuleSettings(indicator=indicator, **settings)
        except (TypeError, ValueError) as error:
            raise InputError(f"invalid alarm rule: {error}") from None

    def create(self, rig_id: int, indicator: str, **settings: Any) -> AlarmRule:
        """A new rule; unspecified settings take the defaults of :class:`AlarmRule`."""
        RigRepository(self.session).get(rig_id)
        unknown = set(settings) - set(RULE_FIELDS)
        if unknown:
            raise InputError(f"unknown alarm rule field(s): {', '.join(sorted(unknown))}")
        if self.get_for(rig_id, indicator) is not None:
            raise Conflict(f"rig {rig_id} already has a rule for {indicator!r}")
        defaults = {
            column.name: column.default.arg
            for column in AlarmRule.__table__.columns
            if column.name in RULE_FIELDS
        }
        values = {**defaults, **settings}
        self._validate(indicator, values)
        rule = AlarmRule(rig_id=rig_id, indicator=indicator, **values)
        self.session.add(rule)
        self.session.flush()
        return rule

    def update(self, rule_id: int, **changes: Any) -> AlarmRule:
        """Change a rule. Levels and persistence apply from the next record on. A change of
        ``baseline_records`` or of a spread floor restarts the rule's baselines, and disabling
        the rule stops it: in both cases its tracks are reset and its open alarms are closed
        (state ``cleared``, with the reason in their history)."""
        rule = self.get(rule_id)
        unknown = set(changes) - set(RULE_FIELDS)
        if unknown:
            raise InputError(f"unknown alarm rule field(s): {', '.join(sorted(unknown))}")
        values = {name: getattr(rule, name) for name in RULE_FIELDS}
        values.update(changes)
        self._validate(rule.indicator, values)
        restart = any(
            name in changes and changes[name] != getattr(rule, name)
            for name in ("baseline_records", "spread_floor_fraction", "spread_floor_abs")
        )
        disabled = rule.enabled and changes.get("enabled") is False
        if restart or disabled:
            self.session.execute(sa.delete(AlarmTrack).where(AlarmTrack.rule_id == rule.id))
            self._close_open_alarms(
                rule, "rule disabled" if disabled else "baseline restarted by a rule change"
            )
        for name, value in changes.items():
            setattr(rule, name, value)
        rule.updated_at = utcnow()
        self.session.flush()
        return rule

    def delete(self, rule_id: int) -> None:
        """Delete a rule; its open alarms are closed (``cleared``, reason in the history) and
        every alarm of it is kept."""
        rule = self.get(rule_id)
        self._close_open_alarms(rule, "rule deleted")
        self.session.delete(rule)
        self.session.flush()

    def _close_open_alarms(self, rule: AlarmRule, reason: str) -> None:
        alarms = AlarmRepository(self.session)
        now = utcnow()
        for alarm in self.session.scalars(
            sa.select(Alarm).where(Alarm.rule_id == rule.id, Alarm.state != "cleared")
        ):
            alarm.cleared_at = now
            alarms.add_event(alarm, "cleared", at=now, who="system", comment=reason)

    def ensure_defaults(self, rig_id: int) -> builtins.list[AlarmRule]:
        """Create the :data:`DEFAULT_RULES` the rig does not have yet; returns all its rules."""
        for indicator, settings in DEFAULT_RULES.items():
            if self.get_for(rig_id, indicator) is None:
                self.create(rig_id, indicator, **settings)
        return self.list(rig_id)

    # -- evaluation state (used by storage.evaluation) ------------------------------------
    def reset_tracks(self, rule_id: int) -> None:
        self.session.execute(sa.delete(AlarmTrack).where(AlarmTrack.rule_id == rule_id))
        self.session.flush()

    def track(self, rule_id: int, channel_id: int, tooth: int) -> AlarmTrack | None:
        return self.session.scalar(
            sa.select(AlarmTrack).where(
                AlarmTrack.rule_id == rule_id,
                AlarmTrack.channel_id == channel_id,
                AlarmTrack.tooth == tooth,
            )
        )

    def tracks(self, rule_id: int) -> builtins.list[AlarmTrack]:
        query = sa.select(AlarmTrack).where(AlarmTrack.rule_id == rule_id)
        return list(self.session.scalars(query))

    def save_track(
        self,
        rule_id: int,
        channel_id: int,
        tooth: int,
        state: dict[str, Any],
        taken_at: dt.datetime,
        existing: AlarmTrack | None = None,
    ) -> AlarmTrack:
        track = existing if existing is not None else self.track(rule_id, channel_id, tooth)
        if track is None:
            track = AlarmTrack(rule_id=rule_id, channel_id=channel_id, tooth=tooth, state=state)
            self.session.add(track)
        track.state = json_safe(state)
        track.last_taken_at = taken_at
        track.updated_at = utcnow()
        return track


class AlarmRepository:
    def __init__(self, session: Session) -> None:
        self.session = session

    def get(self, alarm_id: int) -> Alarm:
        return _get(self.session, Alarm, alarm_id, "alarm")

    def list(
        self,
        *,
        rig_id: int | None = None,
        state: str | Sequence[str] | None = None,
        open_only: bool = False,
        limit: int | None = 100,
        offset: int = 0,
    ) -> builtins.list[Alarm]:
        """Alarms newest first, filtered by rig and state(s); ``open_only`` = not cleared."""
        query = sa.select(Alarm).options(selectinload(Alarm.channel))
        if rig_id is not None:
            query = query.where(Alarm.rig_id == rig_id)
        if state is not None:
            states = [state] if isinstance(state, str) else list(state)
            bad = set(states) - set(ALARM_STATES)
            if bad:
                raise InputError(f"unknown alarm state(s): {', '.join(sorted(bad))}")
            query = query.where(Alarm.state.in_(states))
        if open_only:
            query = query.where(Alarm.state != "cleared")
        query = query.order_by(Alarm.raised_at.desc(), Alarm.id.desc()).offset(offset)
        if limit is not None:
            query = query.limit(limit)
        return list(self.session.scalars(query))

    def count(self, *, rig_id: int | None = None, open_only: bool = False) -> int:
        query = sa.select(sa.func.count(Alarm.id))
        if rig_id is not None:
            query = query.where(Alarm.rig_id == rig_id)
        if open_only:
            query = query.where(Alarm.state != "cleared")
        return int(self.session.scalar(query) or 0)

    def open_for(self, rule_id: int, channel_id: int, tooth: int) -> Alarm | None:
        """The open (not cleared) alarm of one track, if any."""
        return self.session.scalar(
            sa.select(Alarm).where(
                Alarm.rule_id == rule_id,
                Alarm.channel_id == channel_id,
                Alarm.tooth == tooth,
                Alarm.state != "cleared",
            )
        )

    def delete_for_rule(self, rule_id: int) -> int:
        """Delete every alarm (and its history) of a rule; returns how many."""
        ids = list(self.session.scalars(sa.select(Alarm.id).where(Alarm.rule_id == rule_id)))
        if ids:
            self.session.execute(sa.delete(AlarmEvent).where(AlarmEvent.alarm_id.in_(ids)))
            self.session.execute(sa.delete(Alarm).where(Alarm.id.in_(ids)))
            self.session.expire_all()
        return len(ids)

    def history(self, alarm_id: int) -> builtins.list[AlarmEvent]:
        self.get(alarm_id)
        query = sa.select(AlarmEvent).where(AlarmEvent.alarm_id == alarm_id).order_by(AlarmEvent.id)
        return list(self.session.scalars(query))

    def open(
        self,
        *,
        rule: AlarmRule,
        channel_id: int,
        tooth: int,
        severity: str,
        record: Record,
        value: float,
        score: float,
        baseline_centre: float,
        baseline_spread: float,
    ) -> Alarm:
        """A new alarm raised by ``record`` (its ``taken_at`` is ``raised_at``), with history."""
        alarm = Alarm(
            rig_id=rule.rig_id,
            rule_id=rule.id,
            channel_id=channel_id,
            tooth=tooth,
            indicator=rule.indicator,
            state=severity,
            severity=severity,
            raised_at=record.taken_at,
            raised_record_id=record.id,
            last_value=value,
            last_score=score,
            baseline_centre=baseline_centre,
            baseline_spread=baseline_spread,
        )
        self.session.add(alarm)
        self.session.flush()
        self.add_event(alarm, severity, at=record.taken_at, record=record, value=value, score=score)
        return alarm

    def add_event(
        self,
        alarm: Alarm,
        state: str,
        *,
        at: dt.datetime,
        record: Record | None = None,
        value: float | None = None,
        score: float | None = None,
        who: str | None = None,
        comment: str | None = None,
    ) -> AlarmEvent:
        """Set the alarm's state and append it to the history."""
        alarm.state = state
        alarm.updated_at = utcnow()
        event = AlarmEvent(
            alarm_id=alarm.id,
            state=state,
            at=at,
            record_id=None if record is None else record.id,
            value=value,
            score=score,
            who=who,
            comment=comment,
        )
        self.session.add(event)
        self.session.flush()
        return event

    def acknowledge(
        self, alarm_id: int, *, who: str, comment: str = "", at: dt.datetime | None = None
    ) -> Alarm:
        """An operator acknowledges an open alarm (``Conflict`` if cleared or already
        acknowledged). The alarm's track remembers it, so only an escalation re-alarms."""
        from detection.alarms import TrackState, acknowledge

        alarm = self.get(alarm_id)
        if alarm.state == "cleared":
            raise Conflict(f"alarm {alarm_id} is cleared")
        if alarm.state == "acknowledged":
            raise Conflict(f"alarm {alarm_id} is already acknowledged")
        if not who:
            raise InputError("an acknowledgement needs the operator's name")
        at = at or utcnow()
        alarm.acknowledged_by = who
        alarm.acknowledged_at = at
        alarm.ack_comment = comment
        if alarm.rule_id is not None:
            rules = AlarmRuleRepository(self.session)
            track = rules.track(alarm.rule_id, alarm.channel_id, alarm.tooth)
            if track is not None:
                state = TrackState.from_dict(track.state)
                if state.level != "normal" and not state.acknowledged:
                    track.state = acknowledge(state).to_dict()
        self.add_event(alarm, "acknowledged", at=at, who=who, comment=comment)
        return alarm


API_KEY_PREFIX = "gw"


def _hash_key(plaintext: str) -> str:
    return hashlib.sha256(plaintext.encode()).hexdigest()


class ApiKeyRepository:
    """API keys look like ``gw_<prefix>_<secret>``; only the sha256 of the whole key is kept.
    The prefix (8 hex digits) finds the row, a constant-time comparison checks the hash."""

    def __init__(self, session: Session) -> None:
        self.session = session

    def create(self, name: str, role: str) -> tuple[ApiKey, str]:
        """A new key; returns the row and the plaintext key (shown once, never stored)."""
        if role not in ROLES:
            raise InputError(f"unknown role {role!r} (known: {', '.join(ROLES)})")
        prefix = secrets.token_hex(4)
        while self.session.scalar(sa.select(ApiKey.id).where(ApiKey.prefix == prefix)):
            prefix = secrets.token_hex(4)
        plaintext = f"{API_KEY_PREFIX}_{prefix}_{secrets.token_urlsafe(32)}"
        key = ApiKey(prefix=prefix, key_sha256=_hash_key(plaintext), name=name, role=role)
        self.session.add(key)
        self.session.flush()
        return key, plaintext

    def verify(self, plaintext: str, *, touch: bool = True) -> ApiKey | None:
        """The active key matching ``plaintext``, or ``None``; ``touch`` updates ``last_used_at``."""
        parts = plaintext.split("_", 2)
        if len(parts) != 3 or parts[0] != API_KEY_PREFIX:
            return None
        key = self.session.scalar(sa.select(ApiKey).where(ApiKey.prefix == parts[1]))
        if key is None or key.revoked_at is not None:
            return None
        if not hmac.compare_digest(key.key_sha256, _hash_key(plaintext)):
            return None
        if touch:
            key.last_used_at = utcnow()
            self.session.flush()
        return key

    def get(self, key_id: int) -> ApiKey:
        return _get(self.session, ApiKey, key_id, "API key")

    def list(self, *, include_revoked: bool = False) -> builtins.list[ApiKey]:
        query = sa.select(ApiKey).order_by(ApiKey.id)
        if not include_revoked:
            query = query.where(ApiKey.revoked_at.is_(None))
        return list(self.session.scalars(query))

    def revoke(self, key_id: int) -> ApiKey:
        key = self.get(key_id)
        if key.revoked_at is None:
            key.revoked_at = utcnow()
            self.session.flush()
        return key

    def set_role(self, key_id: int, role: str) -> ApiKey:
        if role not in ROLES:
            raise InputError(f"unknown role {role!r} (known: {', '.join(ROLES)})")
        key = self.get(key_id)
        key.role = role
        self.session.flush()
        return key

    def count(self) -> int:
        return int(self.session.scalar(sa.select(sa.func.count(ApiKey.id))) or 0)


class AuditRepository:
    def __init__(self, session: Session) -> None:
        self.session = session

    def add(
        self, who: str, action: str, target: str = "", details: dict[str, Any] | None = None
    ) -> AuditEntry:
        entry = AuditEntry(
            who=who, action=action, target=target, details=json_safe(details or {}), at=utcnow()
        )
        self.session.add(entry)
        self.session.flush()
        return entry

    def list(
        self,
        *,
        who: str | None = None,
        action: str | None = None,
        since: dt.datetime | None = None,
        limit: int | None = 100,
        offset: int = 0,
    ) -> builtins.list[AuditEntry]:
        """Newest first."""
        query = sa.select(AuditEntry)
        if who is not None:
            query = query.where(AuditEntry.who == who)
        if action is not None:
            query = query.where(AuditEntry.action == action)
        if since is not None:
            query = query.where(AuditEntry.at >= since)
        query = query.order_by(AuditEntry.at.desc(), AuditEntry.id.desc()).offset(offset)
        if limit is not None:
            query = query.limit(limit)
        return list(self.session.scalars(query))
