"""Where each track of an alarm rule stands now: the levels the next record must pass.

A trend plot that draws a rule's warning and alarm levels must draw the rule's own: its
baseline as learned so far (from the 3rd record on for a short-campaign rule, widened for few
records, the ``score`` centre never below 0) and, for a record-relative rule, the channel's
pooled day-to-day spread (:func:`detection.alarms.pooled_spread`) — not a recipe re-derived in
the browser. Tracks belong to one campaign's channel (a new gear pair starts new tracks).
"""

from __future__ import annotations

from dataclasses import dataclass

from sqlalchemy.orm import Session

from detection.alarms import RECORD_RELATIVE_INDICATORS, TrackState, pooled_spread
from gearwatch.floor.errors import NotFound
from gearwatch.usecases.alarms import rule_settings
from storage.models import AlarmRule, Campaign, Channel, Rig
from storage.repositories import AlarmRuleRepository, CampaignRepository, RecordRepository


@dataclass(frozen=True)
class TrackLevels:
    """One tooth's (``None``: whole record) baseline and levels in the indicator's own unit."""

    tooth: int | None
    centre: float
    spread: float
    """The spread the next record is scored against (the track's own or the pooled one)."""
    warning: float
    alarm: float
    clear: float
    cusum: float
    state: str | None
    """The open alarm's state, ``None`` when none is open."""
    baseline_records: int


@dataclass(frozen=True)
class RuleLevels:
    rule: AlarmRule
    campaign: str
    channel: str
    pooled_spread: float | None
    tracks: list[TrackLevels]


def _campaign(session: Session, rig: Rig, campaign: str | None) -> Campaign | None:
    """The named campaign of the rig, or the campaign of its newest accepted record."""
    if campaign is not None:
        found = CampaignRepository(session).get_by_name(campaign)
        if found is None or found.rig_id != rig.id:
            raise NotFound(f"campaign {campaign!r} not found on rig {rig.name!r}")
        return found
    newest = RecordRepository(session).list(rig_id=rig.id, status="accepted", limit=1,
                                            newest_first=True)
    return newest[0].campaign if newest else None


def _channel(session: Session, campaign: Campaign, channel: str | None) -> Channel:
    """The named channel of the campaign, or its first accelerometer by name (as the trend)."""
    campaigns = CampaignRepository(session)
    if channel is not None:
        return campaigns.channel(campaign.id, channel)
    accelerometers = sorted((c for c in campaigns.channels(campaign.id) if c.kind == "accelerometer"),
                            key=lambda c: c.name)
    if not accelerometers:
        raise NotFound(f"campaign {campaign.name!r} has no accelerometer channel")
    return accelerometers[0]


def rule_levels(
    session: Session, rig: Rig, indicator: str, campaign: str | None = None,
    channel: str | None = None,
) -> RuleLevels | None:
    """The levels of every track of the rig's rule on ``indicator`` for one campaign's channel
    (default: the campaign of the newest accepted record, its first accelerometer); ``None``
    when the rig has no such rule or no accepted record. Tracks still learning their baseline
    are left out."""
    rules = AlarmRuleRepository(session)
    rule = rules.get_for(rig.id, indicator)
    chosen = _campaign(session, rig, campaign)
    if rule is None or chosen is None:
        return None
    found = _channel(session, chosen, channel)
    settings = rule_settings(rule)
    states = {track.tooth: TrackState.from_dict(track.state)
              for track in rules.tracks(rule.id) if track.channel_id == found.id}
    pooled = None
    if indicator in RECORD_RELATIVE_INDICATORS:
        pooled = pooled_spread(state.baseline_values for state in states.values())
    levels = []
    for tooth, state in sorted(states.items()):
        if state.baseline is None:
            continue
        baseline = state.baseline.floored(pooled)  # what step() scores the next record against
        levels.append(TrackLevels(
            tooth=tooth or None, centre=baseline.centre, spread=baseline.spread,
            warning=baseline.value_at(settings.warning_level),
            alarm=baseline.value_at(settings.alarm_level),
            clear=baseline.value_at(settings.clear_level),
            cusum=state.cusum, state=state.alarm_state,
            baseline_records=len(state.baseline_values),
        ))
    return RuleLevels(rule, chosen.name, found.name, pooled, levels)
