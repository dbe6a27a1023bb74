"""A campaign built through the repositories and the alarm evaluation, with known values.

Day ``d`` (0-based) of ``days`` has tooth depths ``healthy_depth(tooth, d)``; from
``onset_day`` on, ``spall_tooth`` gets ``spall_depth(d)``, far above its baseline, so the
``mci_depth`` rule :data:`MCI_RULE` (baseline 10 records, persistence 3) raises an alarm on day
``onset_day + 2``. One extra record is rejected.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field

from sqlalchemy.orm import Session

from tests.storage.factories import analysis, campaign_config

T0 = dt.datetime(2026, 3, 1, 8, 0, tzinfo=dt.UTC)
TEETH = 20
MCI_RULE = {
    "baseline_records": 10,
    "warning_level": 4.0,
    "alarm_level": 8.0,
    "clear_level": 2.0,
    "persistence": 3,
    "spread_floor_fraction": 0.05,
    "spread_floor_abs": 1e-6,
}


def healthy_depth(tooth: int, day: int) -> float:
    return 0.1 + 0.002 * ((tooth * 7 + day * 3) % 5)


def spall_depth(day: int, onset_day: int) -> float:
    return 0.3 + 0.1 * (day - onset_day)


@dataclass
class Seeded:
    rig: str
    campaign: str
    record_ids: list[int] = field(default_factory=list)
    """Accepted records in day order."""
    rejected_id: int = 0
    taken_at: list[dt.datetime] = field(default_factory=list)
    depths: list[dict[int, float]] = field(default_factory=list)
    spall_tooth: int = 7
    onset_day: int = 10


def seed_campaign(
    session: Session,
    *,
    rig: str = "rig-a",
    campaign: str = "camp-a",
    days: int = 14,
    spall_tooth: int = 7,
    onset_day: int = 10,
) -> Seeded:
    from gearwatch.usecases.alarms import evaluate_record
    from storage.repositories import AlarmRuleRepository, CampaignRepository, RecordRepository

    config = campaign_config(campaign, rig, pinion_teeth=TEETH)
    stored = CampaignRepository(session).ensure(config)
    rules = AlarmRuleRepository(session)
    rules.ensure_defaults(stored.rig_id)
    mci_rule = rules.get_for(stored.rig_id, "mci_depth")
    assert mci_rule is not None
    rules.update(mci_rule.id, **MCI_RULE)  # known settings, whatever the defaults become
    records = RecordRepository(session)
    seeded = Seeded(rig, campaign, spall_tooth=spall_tooth, onset_day=onset_day)
    for day in range(days):
        depths = {t: healthy_depth(t, day) for t in range(1, TEETH + 1)}
        if day >= onset_day:
            depths[spall_tooth] = spall_depth(day, onset_day)
        sha = f"{campaign}-{day}".encode().hex().ljust(64, "0")[:64]
        taken_at = T0 + dt.timedelta(days=day)
        record = records.add(
            stored,
            sha256=sha,
            file_name=f"day{day:02d}.wav",
            raw_location=f"/nonexistent/{sha}.wav",
            taken_at=taken_at,
            label=f"day {day}",
        )
        result_analysis = analysis(sha256=sha, teeth=TEETH, mci_depth=depths)
        records.mark_accepted(record, result_analysis)
        result = records.add_result(record, result_analysis)
        evaluate_record(session, record, result)
        seeded.record_ids.append(record.id)
        seeded.taken_at.append(taken_at)
        seeded.depths.append(depths)
    bad = records.add(
        stored,
        sha256="f" * 64,
        file_name="broken.wav",
        raw_location="/nonexistent/broken.wav",
        taken_at=T0 + dt.timedelta(days=days, hours=1),
    )
    records.mark_rejected(bad, "too few revolutions: 3 < 20")
    seeded.rejected_id = bad.id
    session.flush()
    return seeded
