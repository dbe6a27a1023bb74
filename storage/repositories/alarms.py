"""Alarm rules, alarms, their tracks and state history."""

from __future__ import annotations

import builtins
import datetime as dt
from collections.abc import Sequence
from typing import Any

import sqlalchemy as sa
from sqlalchemy.orm import selectinload

from detection.alarms import RULE_SETTING_NAMES, RuleSettings, TrackState, acknowledge
from detection.default_rules import DEFAULT_RULES
from gearwatch.floor.errors import Conflict, InputError
from gearwatch.floor.results import METRIC_NAMES, STORED_TOOTH_INDICATORS
from storage.models import (
    ALARM_STATES,
    Alarm,
    AlarmEvent,
    AlarmRule,
    AlarmTrack,
    Channel,
    Record,
    utcnow,
)
from storage.repositories.base import Repository, json_safe
from storage.repositories.rigs import RigRepository

ALARM_INDICATORS = STORED_TOOTH_INDICATORS + METRIC_NAMES
"""Indicators an alarm rule can watch: per tooth, or whole-record metrics (tooth 0)."""


RULE_FIELDS = (*RULE_SETTING_NAMES, "enabled")
"""What an operator may change on a stored rule."""


class AlarmRuleRepository(Repository[AlarmRule]):
    model = AlarmRule
    noun = "alarm rule"

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
            column.name: None if column.default is None else column.default.arg
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
            for name in (
                "baseline_records", "spread_floor_fraction", "spread_floor_abs",
                "min_baseline_records",
            )
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

    # -- evaluation state (used by gearwatch.usecases.alarms) ------------------------------------
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


class AlarmRepository(Repository[Alarm]):
    model = Alarm
    noun = "alarm"

    def list(
        self,
        *,
        rig_id: int | None = None,
        state: str | Sequence[str] | None = None,
        open_only: bool = False,
        limit: int | None = 100,
        offset: int = 0,
        campaign_id: int | None = None,
    ) -> builtins.list[Alarm]:
        """Alarms newest first, filtered by rig, campaign (through the alarm's channel) and
        state(s); ``open_only`` = not cleared. Alarms raised by the same record come highest
        score first: of the neighbouring teeth one spall alarms together, its own tooth
        leads."""
        query = sa.select(Alarm).options(selectinload(Alarm.channel))
        if rig_id is not None:
            query = query.where(Alarm.rig_id == rig_id)
        if campaign_id is not None:
            query = query.join(Channel, Alarm.channel_id == Channel.id).where(
                Channel.campaign_id == campaign_id)
        if state is not None:
            states = [state] if isinstance(state, str) else list(state)
            bad = set(states) - set(ALARM_STATES)
            if bad:
                raise InputError(f"unknown alarm state(s): {', '.join(sorted(bad))}")
            query = query.where(Alarm.state.in_(states))
        if open_only:
            query = query.where(Alarm.state != "cleared")
        query = query.order_by(Alarm.raised_at.desc(), Alarm.last_score.desc(), Alarm.id.desc()).offset(offset)
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
        evidence: str | None = None,
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
            evidence=evidence,
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
