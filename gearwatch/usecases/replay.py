"""Replay a campaign: every record of its manifest through the per-record job
(:mod:`gearwatch.usecases.ingest_file`) in the order the records were taken, each in its own
transaction. Replaying again changes nothing; new parameters add result versions.
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tqdm import tqdm

from gearwatch.usecases.alarms import reevaluate_rig
from gearwatch.usecases.ingest_file import parse_taken_at, process_file
from ingest.manifest import load_manifest
from storage.db import open_database, session_scope
from storage.raw_store import RawStore
from storage.repositories import (
    AlarmRepository,
    AuditRepository,
    CampaignRepository,
    RigRepository,
)

if TYPE_CHECKING:
    from sqlalchemy.orm import Session, sessionmaker

    from gearwatch.floor.results import AnalysisParameters


@dataclasses.dataclass
class ReplaySummary:
    campaign: str
    rig: str
    outcomes: dict[str, int] = dataclasses.field(default_factory=dict)
    """Count per job outcome: accepted, rejected, unchanged, reprocessed."""
    rejected: list[tuple[str, str]] = dataclasses.field(default_factory=list)
    """(file, reason) of records rejected in this run."""
    alarms_raised: int = 0
    alarm_changes: int = 0
    internal_errors: int = 0
    open_alarms: list[str] = dataclasses.field(default_factory=list)
    """The campaign's open alarms, one line each."""
    other_open_alarms: int = 0
    """Open alarms of the rig's other campaigns (an earlier gear pair, another test)."""
    reevaluated: bool = False
    """The rig's alarms were recomputed from the current results after the ingestion."""

    def lines(self) -> list[str]:
        counts = ", ".join(f"{n} {outcome}" for outcome, n in sorted(self.outcomes.items()))
        total = sum(self.outcomes.values())
        out = [f"campaign {self.campaign} (rig {self.rig}): {total} record(s): {counts or 'none'}"]
        for file_name, reason in self.rejected:
            out.append(f"  rejected {file_name}: {reason}")
        out.append(
            f"alarms{' (re-evaluated from the current results)' if self.reevaluated else ''}: "
            f"{self.alarms_raised} raised, {self.alarm_changes} state change(s); "
            f"{len(self.open_alarms)} open in this campaign"
        )
        out.extend(f"  {line}" for line in self.open_alarms)
        if self.other_open_alarms:
            out.append(f"  (and {self.other_open_alarms} open in the rig's other campaigns: "
                       f"gearwatch alarms --rig {self.rig} --open)")
        return out


def replay_campaign(
    manifest: str | Path,
    session_factory: sessionmaker[Session],
    raw_store: RawStore,
    params: AnalysisParameters | None = None,
    *,
    analyzer: Callable[..., Any] | None = None,
    progress: bool = True,
    only: Sequence[str] | None = None,
    reevaluate_alarms: bool = False,
) -> ReplaySummary:
    """Ingest every record of the manifest (those named in ``only``, when given), oldest first,
    one transaction per record; with ``reevaluate_alarms``, then recompute the rig's alarms from
    the current results (:func:`gearwatch.usecases.alarms.reevaluate_rig`, one transaction)."""
    campaign = load_manifest(manifest, check_files=False)
    entries = sorted(campaign.records, key=lambda e: parse_taken_at(e.taken_at))
    if only is not None:
        wanted = set(only)
        entries = [e for e in entries if e.file in wanted]
    summary = ReplaySummary(campaign.id, campaign.rig.id)
    bar = tqdm(entries, desc=f"replay {campaign.id}", unit="record", file=sys.stderr,
               disable=not progress, dynamic_ncols=True)
    for entry in bar:
        path = campaign.record_path(entry)
        changes: tuple[Any, ...] = ()
        with session_scope(session_factory) as session:
            if not path.is_file():
                outcome, reason = "rejected", f"{entry.file}: file not found"
            else:
                result = process_file(session, path, campaign, raw_store=raw_store,
                                      params=params, analyzer=analyzer)
                outcome, reason, changes = result.outcome, result.reason, result.alarm_changes
        summary.outcomes[outcome] = summary.outcomes.get(outcome, 0) + 1
        if outcome == "rejected":
            summary.rejected.append((entry.file, reason))
            if reason.startswith("internal error"):
                summary.internal_errors += 1
        summary.alarm_changes += len(changes)
        summary.alarms_raised += sum(1 for c in changes if c.opened)
        bar.set_postfix(
            accepted=summary.outcomes.get("accepted", 0),
            rejected=summary.outcomes.get("rejected", 0),
            alarms=summary.alarms_raised,
        )
    bar.close()
    if reevaluate_alarms:
        with session_scope(session_factory) as session:
            rig = RigRepository(session).get_by_name(campaign.rig.id)
            if rig is not None:
                changes = tuple(reevaluate_rig(session, rig.id))
                summary.reevaluated = True
                summary.alarms_raised = sum(1 for c in changes if c.opened)
                summary.alarm_changes = len(changes)
                AuditRepository(session).add(
                    "gearwatch replay", "alarms.reevaluate", f"rig:{rig.name}",
                    {"alarm_changes": len(changes)},
                )
    summary.open_alarms, summary.other_open_alarms = open_alarm_lines(
        session_factory, campaign.rig.id, campaign.id)
    return summary


def open_alarm_lines(
    session_factory: sessionmaker[Session], rig_name: str, campaign_name: str
) -> tuple[list[str], int]:
    """The campaign's open alarms, one line each, and how many the rig's other campaigns hold
    (a replay's summary speaks of the campaign it replayed)."""
    with session_scope(session_factory) as session:
        rig = RigRepository(session).get_by_name(rig_name)
        stored = CampaignRepository(session).get_by_name(campaign_name)
        if rig is None or stored is None:
            return [], 0
        alarms = AlarmRepository(session)
        lines = []
        for alarm in alarms.list(rig_id=rig.id, open_only=True, limit=None, campaign_id=stored.id):
            where = f"tooth {alarm.tooth}" if alarm.tooth else "whole record"
            lines.append(
                f"#{alarm.id} {alarm.state:<12} {alarm.indicator} {where} on {alarm.channel.name}, "
                f"raised {alarm.raised_at:%Y-%m-%d %H:%M} UTC, last {alarm.last_score:+.1f} "
                "baseline units"
            )
        return lines, alarms.count(rig_id=rig.id, open_only=True) - len(lines)




def replay_into_database(
    manifest: str | Path,
    database_url: str,
    raw_store_root: str | Path,
    params: AnalysisParameters | None = None,
    *,
    progress: bool = True,
    reevaluate_alarms: bool = False,
) -> ReplaySummary:
    """:func:`replay_campaign` into the database at ``database_url`` (migrated first) with the
    raw store at ``raw_store_root``."""
    engine, factory = open_database(database_url)
    try:
        return replay_campaign(
            manifest, factory, RawStore(raw_store_root), params,
            progress=progress, reevaluate_alarms=reevaluate_alarms,
        )
    finally:
        engine.dispose()
