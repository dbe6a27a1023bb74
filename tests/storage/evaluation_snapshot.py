"""What the alarm evaluation stored for a rig, comparable across rigs and databases."""

from __future__ import annotations

from typing import Any

from sqlalchemy.orm import Session

from storage.models import AlarmEvent
from storage.repositories import AlarmRepository, AlarmRuleRepository, RecordRepository


def evaluation_snapshot(session: Session, rig_id: int, *, digits: int | None = None) -> dict[str, Any]:
    """Tracks (baselines and counters), alarms and their histories of one rig, without ids
    and wall-clock times; records are named by their sha256's first 12 characters.
    ``digits`` rounds values to that many significant digits (results from other processes)."""

    def number(value: float | None) -> float | None:
        if value is None or digits is None:
            return value
        return float(f"{value:.{digits}g}")

    def state(data: Any) -> Any:
        if isinstance(data, dict):
            return {k: state(v) for k, v in sorted(data.items())}
        if isinstance(data, list | tuple):
            return [state(v) for v in data]
        return number(data) if isinstance(data, float) else data

    sha_by_record = {
        r.id: r.sha256[:12] for r in RecordRepository(session).list(rig_id=rig_id, limit=None)
    }
    rules = AlarmRuleRepository(session)
    tracks = sorted(
        (rule.indicator, t.tooth, repr(state(t.state)), t.last_taken_at)
        for rule in rules.list(rig_id)
        for t in rules.tracks(rule.id)
    )
    alarms_repo = AlarmRepository(session)

    def event(e: AlarmEvent) -> tuple[Any, ...]:
        return (e.state, e.at, sha_by_record.get(e.record_id or 0), number(e.value),
                number(e.score))

    alarms = [
        (
            a.indicator, a.tooth, a.state, a.severity, a.raised_at,
            sha_by_record.get(a.raised_record_id or 0), a.cleared_at, number(a.last_value),
            number(a.last_score), number(a.baseline_centre), number(a.baseline_spread),
            a.evidence, [event(e) for e in alarms_repo.history(a.id)],
        )
        for a in sorted(alarms_repo.list(rig_id=rig_id, limit=None),
                        key=lambda a: (a.indicator, a.tooth, a.raised_at))
    ]
    return {"tracks": tracks, "alarms": alarms}
