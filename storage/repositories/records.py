"""Records and their result versions, per-tooth values, metrics and curves."""

from __future__ import annotations

import builtins
import dataclasses
import datetime as dt
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import selectinload

from gearwatch.floor.errors import Conflict, DuplicateRecord, InputError
from gearwatch.floor.results import RecordAnalysis
from storage.models import (
    RECORD_STATUSES,
    Campaign,
    Channel,
    ChannelResult,
    Curve,
    Record,
    RecordMetric,
    ResultVersion,
    ToothIndicator,
    float32_array,
    float32_bytes,
    utcnow,
)
from storage.repositories.base import Repository, _get, json_safe, parameters_sha256
from storage.repositories.rigs import CampaignRepository


@dataclasses.dataclass(frozen=True)
class CurveData:
    channel: str
    name: str
    values: np.ndarray
    """float32"""


class RecordRepository(Repository[Record]):
    model = Record
    noun = "record"

    # -- records --------------------------------------------------------------------------
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
        """A new ``pending`` record (``DuplicateRecord`` when that content is already in the
        campaign)."""
        if self.get_by_sha256(campaign.id, sha256) is not None:
            raise DuplicateRecord(f"record {sha256[:12]}… is already in campaign {campaign.name!r}")
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
        # no shaft angle at all (no tach, no mesh line): whole-record metrics only, and no speed
        # was measured — NULL, not the analysis' placeholder 0
        measured = quality.angle_source != "none"
        record.speed_rpm = float(analysis.speed_rpm) if measured else None
        record.speed_min_rpm = float(quality.speed_min_rpm) if measured else None
        record.speed_max_rpm = float(quality.speed_max_rpm) if measured else None
        record.speed_variation = float(quality.speed_variation) if measured else None
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
            quality_score=analysis.quality.score,
            quality=json_safe(dataclasses.asdict(analysis.quality)),
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
                    quality=json_safe(dataclasses.asdict(ch.quality) if ch.quality else {}),
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

    def current_channel_results(
        self, campaign_id: int
    ) -> builtins.list[tuple[ChannelResult, int, int, int, dt.datetime]]:
        """``(channel result, record id, result id, rig id, taken_at)`` of the campaign's accepted
        records' current result versions, by channel, then ``taken_at`` (ties: record id) — the
        order every value computed from a campaign's history follows."""
        query = (
            sa.select(ChannelResult, Record.id, ResultVersion.id, Record.rig_id, Record.taken_at)
            .join(ResultVersion, ResultVersion.id == ChannelResult.result_id)
            .join(Record, Record.id == ResultVersion.record_id)
            .where(Record.campaign_id == campaign_id, Record.status == "accepted",
                   ResultVersion.is_current.is_(True))
            .order_by(ChannelResult.channel_id, Record.taken_at, Record.id)
        )
        return [tuple(row) for row in self.session.execute(query)]  # type: ignore[misc]

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
