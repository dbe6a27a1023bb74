"""Alarm evaluation of one accepted record: the glue between :mod:`detection.alarms` and the
database. Queries go through the repositories; nothing here commits.

Each enabled rule of the record's rig is applied to every (channel, tooth) value of the
record's result version (tooth 0 for whole-record metrics). Tracks advance in the order records
arrive; a record taken at or before a track's last evaluated record does not move that track
(re-ingestion and re-processing therefore never double-count; an out-of-order record is left
out of the alarm evaluation and reported in the log).
"""

from __future__ import annotations

import logging
from collections import defaultdict
from dataclasses import dataclass

from sqlalchemy.orm import Session

from detection.alarms import RuleSettings, TrackState, step
from storage.models import Alarm, AlarmRule, Record, ResultVersion, utcnow
from storage.repositories import AlarmRepository, AlarmRuleRepository, RecordRepository

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class AlarmChange:
    """One alarm state change caused by a record."""

    alarm_id: int
    rig_id: int
    channel_id: int
    tooth: int
    indicator: str
    state: str
    """``warning``, ``alarm`` or ``cleared``."""
    opened: bool
    value: float
    score: float


def rule_settings(rule: AlarmRule) -> RuleSettings:
    return RuleSettings(
        indicator=rule.indicator,
        baseline_records=rule.baseline_records,
        warning_level=rule.warning_level,
        alarm_level=rule.alarm_level,
        clear_level=rule.clear_level,
        persistence=rule.persistence,
        spread_floor_fraction=rule.spread_floor_fraction,
        spread_floor_abs=rule.spread_floor_abs,
    )


def _values(
    session: Session, result: ResultVersion
) -> dict[str, list[tuple[int, int, float]]]:
    """indicator → [(channel_id, tooth, value)] of one result version."""
    records = RecordRepository(session)
    values: dict[str, list[tuple[int, int, float]]] = defaultdict(list)
    for row in records.tooth_indicators(result.id):
        values[row.indicator].append((row.channel_id, row.tooth, row.value))
    for metric in records.metrics(result.id):
        values[metric.metric].append((metric.channel_id, 0, metric.value))
    return values


def evaluate_record(session: Session, record: Record, result: ResultVersion) -> list[AlarmChange]:
    """Advance every alarm track of the record's rig by this record; open, escalate and clear
    alarms accordingly. Records that are not ``accepted`` never raise alarms."""
    if record.status != "accepted":
        return []
    rules_repo = AlarmRuleRepository(session)
    alarms_repo = AlarmRepository(session)
    values = _values(session, result)
    changes: list[AlarmChange] = []
    for rule in rules_repo.list(record.rig_id, enabled_only=True):
        rule_values = values.get(rule.indicator)
        if not rule_values:
            continue
        settings = rule_settings(rule)
        tracks = {(t.channel_id, t.tooth): t for t in rules_repo.tracks(rule.id)}
        open_alarms: dict[tuple[int, int], Alarm] = {
            (a.channel_id, a.tooth): a
            for a in alarms_repo.list(rig_id=rule.rig_id, open_only=True, limit=None)
            if a.rule_id == rule.id
        }
        skipped = 0
        for channel_id, tooth, value in rule_values:
            track = tracks.get((channel_id, tooth))
            if track is not None and track.last_taken_at is not None:
                if record.taken_at <= track.last_taken_at:
                    skipped += 1
                    continue
            state = TrackState.from_dict(track.state) if track is not None else TrackState()
            evaluation = step(state, value, settings)
            alarm = open_alarms.get((channel_id, tooth))
            for transition in evaluation.transitions:
                if transition.opened:
                    assert evaluation.state.baseline is not None
                    alarm = alarms_repo.open(
                        rule=rule,
                        channel_id=channel_id,
                        tooth=tooth,
                        severity=transition.kind,
                        record=record,
                        value=transition.value,
                        score=transition.score,
                        baseline_centre=evaluation.state.baseline.centre,
                        baseline_spread=evaluation.state.baseline.spread,
                    )
                    open_alarms[(channel_id, tooth)] = alarm
                elif alarm is not None:
                    if transition.kind == "cleared":
                        alarm.cleared_at = record.taken_at
                    else:
                        alarm.severity = transition.kind
                    alarms_repo.add_event(
                        alarm,
                        transition.kind,
                        at=record.taken_at,
                        record=record,
                        value=transition.value,
                        score=transition.score,
                    )
                else:  # a track whose alarm row was deleted: start afresh
                    logger.warning("rule %s: no open alarm for channel %s tooth %s", rule.id,
                                   channel_id, tooth)
                    continue
                changes.append(
                    AlarmChange(
                        alarm_id=alarm.id,
                        rig_id=rule.rig_id,
                        channel_id=channel_id,
                        tooth=tooth,
                        indicator=rule.indicator,
                        state=transition.kind,
                        opened=transition.opened,
                        value=transition.value,
                        score=transition.score,
                    )
                )
            if alarm is not None and evaluation.score is not None:
                alarm.last_value = value
                alarm.last_score = evaluation.score
                alarm.updated_at = utcnow()
            rules_repo.save_track(
                rule.id, channel_id, tooth, evaluation.state.to_dict(), record.taken_at, track
            )
        if skipped:
            logger.warning(
                "record %s (taken %s) is not newer than the %s track(s) of rule %s (%s): "
                "left out of the alarm evaluation",
                record.id, record.taken_at.isoformat(), skipped, rule.id, rule.indicator,
            )
    session.flush()
    return changes


def reevaluate_rig(session: Session, rig_id: int) -> list[AlarmChange]:
    """Recompute the alarms of a rig's enabled rules from the stored results.

    The rules' tracks and alarms (with their history) are deleted, then the current result
    version of every accepted record is evaluated in ``taken_at`` order. Use it after
    re-processing records with new parameters, or after a rule change that should apply to the
    past. Acknowledgements of the deleted alarms are lost: the caller should write the audit
    log entry.
    """
    rules_repo = AlarmRuleRepository(session)
    alarms_repo = AlarmRepository(session)
    records_repo = RecordRepository(session)
    for rule in rules_repo.list(rig_id, enabled_only=True):
        rules_repo.reset_tracks(rule.id)
        alarms_repo.delete_for_rule(rule.id)
    changes: list[AlarmChange] = []
    for record in records_repo.list(rig_id=rig_id, status="accepted", limit=None):
        result = records_repo.current_result(record.id)
        if result is not None:
            changes.extend(evaluate_record(session, record, result))
    return changes
