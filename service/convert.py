"""Database rows → response bodies, and name → row look-ups (through the repositories)."""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

from sqlalchemy.orm import Session

from detection.alarms import RULE_SETTING_NAMES
from gearwatch.floor.errors import NotFound
from service import schemas
from storage.models import Alarm, AlarmEvent, AlarmRule, Campaign, Record, ResultVersion, Rig
from storage.operator_queries import alarm_data
from storage.repositories import (
    CampaignRepository,
    RecordRepository,
    RigRepository,
)


def finite(value: float | None) -> float | None:
    """JSON has no NaN or infinity: they travel as ``null``."""
    if value is None or not math.isfinite(value):
        return None
    return float(value)


def finite_list(values: Iterable[float]) -> list[float | None]:
    return [v if math.isfinite(v) else None for v in (float(x) for x in values)]


def rig_by_name(session: Session, rig_id: str) -> Rig:
    rig = RigRepository(session).get_by_name(rig_id)
    if rig is None:
        raise NotFound(f"rig {rig_id!r} not found")
    return rig


def campaign_by_name(session: Session, campaign_id: str) -> Campaign:
    campaign = CampaignRepository(session).get_by_name(campaign_id)
    if campaign is None:
        raise NotFound(f"campaign {campaign_id!r} not found")
    return campaign


class Names:
    """Rig and campaign names by database id, loaded once per request."""

    def __init__(self, session: Session) -> None:
        self.session = session
        self._rigs: dict[int, str] | None = None
        self._campaigns: dict[int, str] | None = None

    def rig(self, rig_pk: int) -> str:
        if self._rigs is None:
            self._rigs = {r.id: r.name for r in RigRepository(self.session).list()}
        return self._rigs.get(rig_pk) or RigRepository(self.session).get(rig_pk).name

    def campaign(self, campaign_pk: int) -> str:
        if self._campaigns is None:
            self._campaigns = {c.id: c.name for c in CampaignRepository(self.session).list()}
        return (
            self._campaigns.get(campaign_pk)
            or CampaignRepository(self.session).get(campaign_pk).name
        )


def rig_out(session: Session, rig: Rig) -> schemas.RigOut:
    return schemas.RigOut(
        rig_id=rig.name,
        pinion_teeth=rig.pinion_teeth,
        gear_teeth=rig.gear_teeth,
        tooth1_pitch_angle_deg=rig.tooth1_pitch_angle_deg,
        campaigns=[c.name for c in CampaignRepository(session).list(rig.id)],
        records=RecordRepository(session).count(rig_id=rig.id),
    )


def campaign_out(session: Session, campaign: Campaign, names: Names) -> schemas.CampaignOut:
    channels = CampaignRepository(session).channels(campaign.id)
    return schemas.CampaignOut(
        campaign_id=campaign.name,
        rig_id=names.rig(campaign.rig_id),
        description=campaign.description,
        channels=[
            schemas.ChannelOut(name=c.name, kind=c.kind, unit=c.unit)  # type: ignore[arg-type]
            for c in channels
        ],
        manifest=campaign.manifest or {},
        created_at=campaign.created_at,
    )


def record_out(record: Record, names: Names) -> schemas.RecordOut:
    return schemas.RecordOut(
        id=record.id,
        rig_id=names.rig(record.rig_id),
        campaign_id=names.campaign(record.campaign_id),
        file_name=record.file_name,
        sha256=record.sha256,
        size_bytes=record.size_bytes,
        taken_at=record.taken_at,
        label=record.label,
        status=record.status,  # type: ignore[arg-type]
        reason=record.reason,
        speed_rpm=finite(record.speed_rpm),
        speed_variation=finite(record.speed_variation),
        revolutions=record.revolutions,
        quality_score=finite((record.quality or {}).get("score")),
        processed_at=record.processed_at,
    )


def result_out(session: Session, result: ResultVersion, *, details: bool) -> schemas.ResultOut:
    out = schemas.ResultOut(
        id=result.id,
        record_id=result.record_id,
        is_current=result.is_current,
        parameters=result.parameters,
        code_version=result.code_version,
        created_at=result.created_at,
        speed_rpm=result.speed_rpm,
        revolutions=result.revolutions,
        samples_per_rev=result.samples_per_rev,
        quality_score=finite(result.quality_score),
        quality=result.quality or {},
    )
    if not details:
        return out
    records = RecordRepository(session)
    teeth: dict[tuple[int, int], dict[str, Any]] = {}
    for row in records.tooth_indicators(result.id):
        teeth.setdefault((row.channel_id, row.tooth), {"tooth": row.tooth})[row.indicator] = finite(
            row.value
        )
    metrics: dict[int, dict[str, float]] = {}
    for metric in records.metrics(result.id):
        value = finite(metric.value)
        if value is not None:
            metrics.setdefault(metric.channel_id, {})[metric.metric] = value
    curve_names: dict[str, list[str]] = {}
    for channel, name, _length in records.curve_index(result.id):
        curve_names.setdefault(channel, []).append(name)
    for ch in records.channel_results(result.id):
        out.channels.append(
            schemas.ChannelResultOut(
                channel=ch.channel.name,
                revolutions=ch.revolutions,
                gear_revolutions=ch.gear_revolutions,
                speed_rpm=ch.speed_rpm,
                samples_per_rev=ch.samples_per_rev,
                worst_tooth=ch.worst_tooth,
                metrics=metrics.get(ch.channel_id, {}),
                teeth=[
                    schemas.ToothOut(**values)
                    for (channel_id, _), values in sorted(teeth.items())
                    if channel_id == ch.channel_id
                ],
                curves=curve_names.get(ch.channel.name, []),
                quality=ch.quality or {},
            )
        )
    return out


def alarm_out(alarm: Alarm, names: Names) -> schemas.AlarmOut:
    cache = names.__dict__.setdefault("_alarm_cache", {})
    return schemas.AlarmOut(**alarm_data(names.session, alarm, cache))


def alarm_event_out(event: AlarmEvent) -> schemas.AlarmEventOut:
    return schemas.AlarmEventOut(
        state=event.state,  # type: ignore[arg-type]
        at=event.at,
        record_id=event.record_id,
        value=finite(event.value),
        score=finite(event.score),
        who=event.who,
        comment=event.comment,
    )


def rule_out(rule: AlarmRule) -> schemas.AlarmRuleOut:
    return schemas.AlarmRuleOut(
        indicator=rule.indicator,
        enabled=rule.enabled,
        updated_at=rule.updated_at,
        **{name: getattr(rule, name) for name in RULE_SETTING_NAMES},
    )
