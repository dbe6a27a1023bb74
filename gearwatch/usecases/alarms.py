"""Alarm evaluation of one accepted record: the glue between :mod:`detection.alarms` and the
database. Queries go through the repositories; nothing here commits.

Each enabled rule of the record's rig is applied to every (channel, tooth) value of the
record's result version (tooth 0 for whole-record metrics). Baselines, alarm states and
transitions are a function of the set of accepted records ordered by ``(taken_at, sha256)``,
whatever order the records arrive in (two workers, a late upload): a record newer than a track
advances it by one step; an older one replays the track (:func:`replay_tracks`). Re-ingestion
and re-evaluation therefore never double-count.
"""

from __future__ import annotations

import datetime as dt
import logging
import math
from collections import defaultdict
from dataclasses import dataclass, field

import sqlalchemy as sa
from sqlalchemy.orm import Session

from detection.alarms import (
    RECORD_RELATIVE_INDICATORS,
    RULE_SETTING_NAMES,
    Evaluation,
    RuleSettings,
    TrackState,
    acknowledge,
    pooled_spread,
    step,
)
from gearwatch.floor.results import HISTORY_TOOTH_INDICATORS
from storage.models import (
    Alarm,
    AlarmEvent,
    AlarmRule,
    AlarmTrack,
    Record,
    RecordMetric,
    ResultVersion,
    Rig,
    ToothIndicator,
    utcnow,
)
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
    """``warning``, ``alarm`` or ``cleared``; ``withdrawn`` when a late record's replay no longer
    raises an alarm that was raised before (the alarm is deleted)."""
    opened: bool
    value: float
    score: float
    evidence: str = "level"
    """What raised it (:attr:`detection.alarms.Transition.evidence`)."""


def rule_settings(rule: AlarmRule) -> RuleSettings:
    return RuleSettings(
        indicator=rule.indicator, **{name: getattr(rule, name) for name in RULE_SETTING_NAMES}
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
    """Bring every alarm track of the record's rig up to date with this record; open,
    escalate and clear alarms accordingly. Records that are not ``accepted`` never raise
    alarms.

    The outcome is a function of the SET of accepted records ordered by ``(taken_at,
    sha256)``, whatever order they arrive in: a record newer than a track advances it by one
    :func:`detection.alarms.step`; a record taken at or before a track's last record (a late
    arrival, a re-evaluation) replays that track from its first record (:func:`replay_tracks`),
    and the changes it returns say which alarms that replay opened, changed or withdrew.
    Evaluations of one rig are serialised by a row lock on the rig (PostgreSQL; SQLite
    serialises writers anyway), so two workers never advance a track from the same state.
    """
    if record.status != "accepted":
        return []
    _lock_rig(session, record.rig_id)
    rules_repo = AlarmRuleRepository(session)
    values = _values(session, result)
    changes: list[AlarmChange] = []
    for rule in rules_repo.list(record.rig_id, enabled_only=True):
        rule_values = values.get(rule.indicator)
        from_history = rule.indicator in HISTORY_TOOTH_INDICATORS
        if not rule_values and not from_history:
            continue
        tracks = {(t.channel_id, t.tooth): t for t in rules_repo.tracks(rule.id)}
        if from_history:
            # A late record may have rewritten the values of every record after it
            # (gearwatch.usecases.tooth_change), even when it has none of its own (a reference
            # record): every track it is not newer than is replayed.
            stale = {key for key, track in tracks.items()
                     if track.last_taken_at is not None and record.taken_at <= track.last_taken_at}
            if stale:
                keys = stale | {(channel_id, tooth) for channel_id, tooth, _ in rule_values or ()}
                changes.extend(replay_tracks(session, rule, keys))
                continue
        if not rule_values:
            continue
        late = {
            (channel_id, tooth)
            for channel_id, tooth, _ in rule_values
            if (track := tracks.get((channel_id, tooth))) is not None
            and track.last_taken_at is not None
            and record.taken_at <= track.last_taken_at
        }
        if late and rule.indicator in RECORD_RELATIVE_INDICATORS:
            # replay_tracks replays the whole channel (the pooled spread): none of it advances
            late_channels = {channel_id for channel_id, _ in late}
            late |= {(c, t) for c, t, _ in rule_values if c in late_channels}
        if late:
            logger.info(
                "record %s (taken %s) is not newer than %s track(s) of rule %s (%s): replaying them",
                record.id, record.taken_at.isoformat(), len(late), rule.id, rule.indicator,
            )
            changes.extend(replay_tracks(session, rule, late))
        fresh = [(c, t, v) for c, t, v in rule_values if (c, t) not in late]
        changes.extend(_advance(session, rule, record, fresh, tracks))
    session.flush()
    return changes


def _lock_rig(session: Session, rig_id: int) -> None:
    """Wait for other transactions evaluating this rig, then see what they committed."""
    session.flush()
    session.execute(
        sa.select(Rig.id).where(Rig.id == rig_id).with_for_update(key_share=True)
    )
    # Objects loaded before the lock may predate another worker's commit.
    session.expire_all()


def _advance(
    session: Session,
    rule: AlarmRule,
    record: Record,
    rule_values: list[tuple[int, int, float]],
    tracks: dict[tuple[int, int], AlarmTrack],
) -> list[AlarmChange]:
    """One :func:`step` of each (channel, tooth) track by a record newer than all of them."""
    rules_repo = AlarmRuleRepository(session)
    alarms_repo = AlarmRepository(session)
    settings = rule_settings(rule)
    open_alarms: dict[tuple[int, int], Alarm] = {
        (a.channel_id, a.tooth): a
        for a in alarms_repo.list(rig_id=rule.rig_id, open_only=True, limit=None)
        if a.rule_id == rule.id
    }
    states = {key: TrackState.from_dict(track.state) for key, track in tracks.items()}
    pooled = _pooled_spreads(rule, states)
    changes: list[AlarmChange] = []
    evaluations = [
        (channel_id, tooth, value,
         step(states.get((channel_id, tooth), TrackState()), value, settings, pooled.get(channel_id)))
        for channel_id, tooth, value in rule_values
    ]
    for channel_id, tooth, value, evaluation in _strongest_first(evaluations):
        track = tracks.get((channel_id, tooth))
        alarm = open_alarms.get((channel_id, tooth))
        for transition in evaluation.transitions:
            if transition.opened:
                assert evaluation.state.baseline is not None and evaluation.spread is not None
                alarm = alarms_repo.open(
                    rule=rule,
                    channel_id=channel_id,
                    tooth=tooth,
                    severity=transition.kind,
                    record=record,
                    value=transition.value,
                    score=transition.score,
                    baseline_centre=evaluation.state.baseline.centre,
                    baseline_spread=evaluation.spread,
                    evidence=transition.evidence,
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
            changes.append(_change(rule, alarm, transition.kind, transition.opened,
                                   transition.value, transition.score, transition.evidence))
        if alarm is not None and evaluation.score is not None:
            alarm.last_value = value
            alarm.last_score = evaluation.score
            alarm.updated_at = utcnow()
        rules_repo.save_track(
            rule.id, channel_id, tooth, evaluation.state.to_dict(), record.taken_at, track
        )
    return changes


def _strongest_first(
    evaluations: list[tuple[int, int, float, Evaluation]],
) -> list[tuple[int, int, float, Evaluation]]:
    """The tracks that open an alarm on this record, highest opening score first, then the rest
    in their order.

    A spall rings into the sectors after its tooth, so one record often opens a rule's alarm
    on two or three neighbouring teeth at once; the spalled tooth is the one that stands
    highest (``benchmarks/bench_detection.py`` scores the highest-scoring opening of the day).
    Opened in this order, the record's first alarm (lowest id, first notification, first in
    the alarm list among those raised by the record) is that tooth's.
    """
    def opening_score(item: tuple[int, int, float, Evaluation]) -> float:
        return max((t.score for t in item[3].transitions if t.opened), default=-math.inf)

    return sorted(evaluations, key=lambda item: -opening_score(item))


def _pooled_spreads(
    rule: AlarmRule, states: dict[tuple[int, int], TrackState]
) -> dict[int, float | None]:
    """channel → the pooled day-to-day spread of its tracks' baselines, for a record-relative
    rule (:func:`detection.alarms.pooled_spread`); empty for every other rule."""
    if rule.indicator not in RECORD_RELATIVE_INDICATORS:
        return {}
    by_channel: dict[int, list[tuple[float, ...]]] = defaultdict(list)
    for (channel_id, _tooth), state in states.items():
        by_channel[channel_id].append(state.baseline_values)
    return {channel_id: pooled_spread(sets) for channel_id, sets in by_channel.items()}


def _change(
    rule: AlarmRule, alarm: Alarm, state: str, opened: bool, value: float, score: float,
    evidence: str = "level",
) -> AlarmChange:
    return AlarmChange(
        alarm_id=alarm.id,
        rig_id=rule.rig_id,
        channel_id=alarm.channel_id,
        tooth=alarm.tooth,
        indicator=rule.indicator,
        state=state,
        opened=opened,
        value=value,
        score=score,
        evidence=evidence,
    )


@dataclass(frozen=True)
class _Point:
    """One accepted record's value on a track, in evaluation order."""

    taken_at: dt.datetime
    sha256: str
    record_id: int
    value: float


def _track_histories(
    session: Session, rule: AlarmRule, keys: set[tuple[int, int]]
) -> dict[tuple[int, int], list[_Point]]:
    """The values of ``rule``'s indicator on the given (channel, tooth) tracks over the rig's
    accepted records (current result versions), ordered by ``(taken_at, sha256)``."""
    histories: dict[tuple[int, int], list[_Point]] = {key: [] for key in keys}
    tooth_rows = session.execute(
        sa.select(ToothIndicator.channel_id, ToothIndicator.tooth, Record.taken_at,
                  Record.sha256, Record.id, ToothIndicator.value)
        .join(Record, Record.id == ToothIndicator.record_id)
        .where(ToothIndicator.rig_id == rule.rig_id, ToothIndicator.indicator == rule.indicator,
               ToothIndicator.is_current.is_(True), Record.status == "accepted")
    )
    metric_rows = session.execute(
        sa.select(RecordMetric.channel_id, sa.literal(0), Record.taken_at, Record.sha256,
                  Record.id, RecordMetric.value)
        .join(Record, Record.id == RecordMetric.record_id)
        .where(RecordMetric.rig_id == rule.rig_id, RecordMetric.metric == rule.indicator,
               RecordMetric.is_current.is_(True), Record.status == "accepted")
    )
    for rows in (tooth_rows, metric_rows):
        for channel_id, tooth, taken_at, sha256, record_id, value in rows:
            history = histories.get((channel_id, tooth))
            if history is not None:
                history.append(_Point(taken_at, sha256, record_id, float(value)))
    for history in histories.values():
        history.sort(key=lambda p: (p.taken_at, p.sha256))
    return histories


@dataclass
class _Episode:
    """One alarm as a replay sees it: from the transition that opened it to its clearing."""

    raised: _Point
    severity: str
    baseline_centre: float
    baseline_spread: float
    evidence: str = "level"
    """What opened it (:attr:`detection.alarms.Transition.evidence`)."""
    events: list[tuple[str, _Point, float, float, str]] = field(default_factory=list)
    """(kind, record, value, score, evidence) of every transition, the opening one first."""
    acknowledged_after: int | None = None
    """Record id after which the kept acknowledgement was applied."""
    last_value: float = 0.0
    last_score: float = 0.0
    cleared_at: dt.datetime | None = None
    acknowledged: bool = False


def _channel_keys(session: Session, rule: AlarmRule, channels: set[int]) -> set[tuple[int, int]]:
    """Every (channel, tooth) of the given channels with a current value of the rule's
    indicator on the rig."""
    rows = session.execute(
        sa.select(ToothIndicator.channel_id, ToothIndicator.tooth).distinct()
        .where(ToothIndicator.rig_id == rule.rig_id, ToothIndicator.indicator == rule.indicator,
               ToothIndicator.is_current.is_(True), ToothIndicator.channel_id.in_(channels))
    )
    return {(channel_id, tooth) for channel_id, tooth in rows}


def _replayed_pooled_spreads(
    rule: AlarmRule, settings: RuleSettings, histories: dict[tuple[int, int], list[_Point]]
) -> dict[tuple[int, int], float | None]:
    """(channel, record id) → the pooled spread each record of a record-relative rule is scored
    with: the channel's tracks stepped together in record order, as :func:`_advance` saw them
    (acknowledgements change no baseline, so they are left out). Empty for every other rule."""
    if rule.indicator not in RECORD_RELATIVE_INDICATORS:
        return {}
    by_channel: dict[int, dict[int, list[_Point]]] = defaultdict(dict)
    for (channel_id, tooth), history in histories.items():
        by_channel[channel_id][tooth] = history
    pooled: dict[tuple[int, int], float | None] = {}
    for channel_id, teeth in by_channel.items():
        timeline = sorted({(p.taken_at, p.sha256, p.record_id) for h in teeth.values() for p in h})
        values = {(tooth, p.record_id): p.value for tooth, h in teeth.items() for p in h}
        states = {tooth: TrackState() for tooth in teeth}
        for _taken_at, _sha256, record_id in timeline:
            spread = pooled_spread([s.baseline_values for s in states.values() if s.baseline_values])
            pooled[(channel_id, record_id)] = spread
            for tooth in teeth:
                if (value := values.get((tooth, record_id))) is not None:
                    states[tooth] = step(states[tooth], value, settings, spread).state
    return pooled


def _ack_position(alarm: Alarm) -> int | None:
    """The record of the last evaluation event before the alarm's acknowledgement."""
    last_record: int | None = None
    for event in sorted(alarm.history, key=lambda e: e.id):
        if event.state == "acknowledged":
            return last_record
        if event.record_id is not None:
            last_record = event.record_id
    return None


def replay_tracks(
    session: Session, rule: AlarmRule, keys: set[tuple[int, int]]
) -> list[AlarmChange]:
    """Recompute the given (channel, tooth) tracks of ``rule`` by replaying :func:`step` over
    the rig's accepted records in ``(taken_at, sha256)`` order, and rewrite their alarms.

    An alarm raised by the same record as before is kept (same id, its acknowledgement kept
    and re-applied after the same transition); its history is rebuilt. An alarm the replay
    no longer raises is deleted and reported with state ``withdrawn``. The returned changes
    are the transitions the stored history did not have yet, plus the withdrawn alarms."""
    rules_repo = AlarmRuleRepository(session)
    settings = rule_settings(rule)
    if rule.indicator in RECORD_RELATIVE_INDICATORS:
        # a tooth's scores depend on its channel's other teeth (the pooled spread): all replay
        keys = keys | _channel_keys(session, rule, {channel_id for channel_id, _ in keys})
    histories = _track_histories(session, rule, keys)
    pooled = _replayed_pooled_spreads(rule, settings, histories)
    old_alarms: dict[tuple[int, int], list[Alarm]] = defaultdict(list)
    for stored in session.scalars(
        sa.select(Alarm).where(Alarm.rule_id == rule.id).order_by(Alarm.id)
    ):
        if (stored.channel_id, stored.tooth) in keys:
            old_alarms[(stored.channel_id, stored.tooth)].append(stored)
    changes: list[AlarmChange] = []
    replayed_tracks: list[tuple[tuple[int, int], TrackState, list[_Episode]]] = []
    previous_by_key: dict[tuple[int, int], dict[int | None, Alarm]] = {}
    for key in sorted(keys):
        channel_id, tooth = key
        previous = previous_by_key[key] = {a.raised_record_id: a for a in old_alarms.get(key, [])}
        ack_after = {
            record_id: position
            for record_id, alarm in previous.items()
            if alarm.acknowledged_at is not None
            and (position := _ack_position(alarm)) is not None
        }
        state = TrackState()
        episodes: list[_Episode] = []
        episode: _Episode | None = None
        for point in histories[key]:
            evaluation = step(state, point.value, settings, pooled.get((channel_id, point.record_id)))
            state = evaluation.state
            for transition in evaluation.transitions:
                if transition.opened:
                    assert state.baseline is not None and evaluation.spread is not None
                    episode = _Episode(point, transition.kind, state.baseline.centre,
                                       evaluation.spread, transition.evidence)
                    episodes.append(episode)
                elif episode is None:
                    continue
                elif transition.kind == "cleared":
                    episode.cleared_at = point.taken_at
                else:
                    episode.severity = transition.kind
                episode.events.append((transition.kind, point, transition.value,
                                       transition.score, transition.evidence))
            if episode is not None and evaluation.score is not None:
                episode.last_value, episode.last_score = point.value, evaluation.score
            if (
                episode is not None
                and episode.cleared_at is None
                and ack_after.get(episode.raised.record_id) == point.record_id
                and state.level != "normal"
                and not state.acknowledged
            ):
                state = acknowledge(state)
                episode.acknowledged_after = point.record_id
            if episode is not None:
                episode.acknowledged = state.acknowledged and episode.cleared_at is None
            if episode is not None and episode.cleared_at is not None:
                episode = None
        replayed_tracks.append((key, state, episodes))
    # Written in the order a sequential evaluation opens them: by the raising record, and
    # within one record the strongest first (:func:`_strongest_first`).
    kept: set[int] = set()
    for key, replayed in sorted(
        ((key, episode) for key, _state, episodes in replayed_tracks for episode in episodes),
        key=lambda item: (item[1].raised.taken_at, item[1].raised.sha256, -item[1].events[0][3]),
    ):
        alarm = previous_by_key[key].get(replayed.raised.record_id)
        changes.extend(_write_episode(session, rule, key[0], key[1], replayed, alarm))
        if alarm is not None:
            kept.add(alarm.id)
    for key, state, _episodes in replayed_tracks:
        channel_id, tooth = key
        for stored in old_alarms.get(key, []):
            if stored.id not in kept:
                changes.append(_change(rule, stored, "withdrawn", False, stored.last_value,
                                       stored.last_score))
                session.delete(stored)
        history = histories[key]
        if history:
            rules_repo.save_track(rule.id, channel_id, tooth, state.to_dict(), history[-1].taken_at)
        else:  # no value left (a history indicator recomputed away): as if never evaluated
            session.execute(sa.delete(AlarmTrack).where(
                AlarmTrack.rule_id == rule.id, AlarmTrack.channel_id == channel_id,
                AlarmTrack.tooth == tooth))
    session.flush()
    return changes


def _write_episode(
    session: Session,
    rule: AlarmRule,
    channel_id: int,
    tooth: int,
    episode: _Episode,
    alarm: Alarm | None,
) -> list[AlarmChange]:
    """Store one replayed alarm (reusing ``alarm`` when the same record raised it before)."""
    old_events: list[tuple[str, int | None]] = []
    acknowledgement: AlarmEvent | None = None
    if alarm is None:
        alarm = Alarm(rig_id=rule.rig_id, rule_id=rule.id, channel_id=channel_id, tooth=tooth,
                      indicator=rule.indicator, state=episode.severity)
        session.add(alarm)
    else:
        for event in sorted(alarm.history, key=lambda e: e.id):
            if event.state == "acknowledged":
                acknowledgement = event
            else:
                old_events.append((event.state, event.record_id))
        alarm.history.clear()
        session.flush()
    alarm.raised_at = episode.raised.taken_at
    alarm.raised_record_id = episode.raised.record_id
    alarm.severity = episode.severity
    alarm.evidence = episode.evidence
    alarm.baseline_centre = episode.baseline_centre
    alarm.baseline_spread = episode.baseline_spread
    alarm.last_value, alarm.last_score = episode.last_value, episode.last_score
    alarm.cleared_at = episode.cleared_at
    if episode.acknowledged_after is None:
        alarm.acknowledged_by = alarm.acknowledged_at = alarm.ack_comment = None
    alarm.updated_at = utcnow()
    session.flush()
    history: list[AlarmEvent] = []
    changes: list[AlarmChange] = []
    for index, (kind, point, value, score, evidence) in enumerate(episode.events):
        history.append(AlarmEvent(alarm_id=alarm.id, state=kind, at=point.taken_at,
                                  record_id=point.record_id, value=value, score=score))
        if (kind, point.record_id) not in old_events:
            changes.append(_change(rule, alarm, kind, index == 0, value, score, evidence))
        if acknowledgement is not None and episode.acknowledged_after == point.record_id:
            history.append(AlarmEvent(alarm_id=alarm.id, state="acknowledged",
                                      at=acknowledgement.at, who=acknowledgement.who,
                                      comment=acknowledgement.comment))
    if (
        acknowledgement is not None
        and episode.acknowledged_after is not None
        and all(e.state != "acknowledged" for e in history)
    ):
        history.append(AlarmEvent(alarm_id=alarm.id, state="acknowledged", at=acknowledgement.at,
                                  who=acknowledgement.who, comment=acknowledgement.comment))
    session.add_all(history)
    if episode.cleared_at is not None:
        alarm.state = "cleared"
    elif episode.acknowledged:
        alarm.state = "acknowledged"
    else:
        alarm.state = episode.severity
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
