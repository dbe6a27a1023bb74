"""``gearwatch replay CAMPAIGN_DIR [--db URL] [--params FILE]``: ingest a whole campaign.

Every record of the manifest goes through the per-record job (:mod:`gearwatch.jobs`) in the
order the records were taken, each in its own transaction, with a progress bar on stderr and a
summary on stdout. Replaying again changes nothing; new parameters add result versions.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

PARAMETER_FLAGS = {
    "mci_form": "--mci-form",
    "samples_per_mesh": "--samples-per-mesh",
    "min_revolutions": "--min-revolutions",
    "max_speed_variation": "--max-speed-variation",
}


def add_common_arguments(parser: argparse.ArgumentParser) -> None:
    """Database, raw store and analysis parameter options shared by ``replay`` and ``watch``."""
    parser.add_argument(
        "--db",
        metavar="URL",
        help="SQLAlchemy database URL (default: $GEARWATCH_DATABASE_URL, else "
        "sqlite:///gearwatch.db in the working directory); migrated automatically",
    )
    parser.add_argument(
        "--raw-store",
        metavar="DIR",
        help="content-addressed raw file store (default: $GEARWATCH_RAW_STORE, else ./raw-store)",
    )
    add_parameter_arguments(parser)
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def add_parameter_arguments(parser: argparse.ArgumentParser) -> None:
    """Analysis parameter options (``--params FILE`` and the individual flags), shared by every
    command that runs the chain; read back with :func:`parameters_from_args`."""
    parser.add_argument(
        "--params",
        metavar="FILE",
        help="analysis parameters as a JSON or TOML table (names as in AnalysisParameters)",
    )
    parser.add_argument("--mci-form", choices=("robust", "literal"), default=None,
                        help="MCI form: robust (default, localises on zero-mean averages) or the "
                        "seed's literal form")
    parser.add_argument("--samples-per-mesh", type=int, default=None, help="default 64")
    parser.add_argument("--min-revolutions", type=int, default=None, help="default 20")
    parser.add_argument("--max-speed-variation", type=float, default=None,
                        help="relative, default 0.10")


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "replay",
        help="ingest a campaign record by record into the database",
        description=(
            "Ingest every record of a campaign (CAMPAIGN_DIR/campaign.toml) in the order they "
            "were taken: keep the raw file, analyse it, store per-tooth results and evaluate "
            "the alarm rules. Records already ingested with the same parameters are left "
            "alone; rejected records are stored with their reason."
        ),
    )
    parser.add_argument("campaign", metavar="CAMPAIGN_DIR",
                        help="campaign folder with campaign.toml (or the manifest itself)")
    parser.add_argument(
        "--reevaluate-alarms",
        action="store_true",
        help="afterwards, recompute the rig's alarms from the current results (after "
        "re-processing with new parameters; acknowledgements of the old alarms are lost)",
    )
    add_common_arguments(parser)
    parser.set_defaults(func=run)


def manifest_path(location: str | Path) -> Path:
    from gearwatch.errors import InputError

    path = Path(location)
    if path.is_dir():
        path = path / "campaign.toml"
    if not path.is_file():
        raise InputError(f"{path}: no campaign manifest (campaign.toml) found")
    return path


def parameters_from_args(args: argparse.Namespace) -> Any:
    """``--params FILE`` overlaid with the individual flags."""
    from gearwatch.errors import InputError
    from gearwatch.results import AnalysisParameters

    values: dict[str, Any] = {}
    if getattr(args, "params", None):
        path = Path(args.params)
        try:
            text = path.read_text(encoding="utf-8")
            if path.suffix.lower() == ".toml":
                import tomllib

                values = dict(tomllib.loads(text))
            else:
                values = dict(json.loads(text))
        except (OSError, ValueError) as error:
            raise InputError(f"{path}: cannot read parameters: {error}") from None
    for name in PARAMETER_FLAGS:
        flag_value = getattr(args, name, None)
        if flag_value is not None:
            values[name] = flag_value
    try:
        params = AnalysisParameters.from_dict(values)
    except (TypeError, ValueError) as error:
        raise InputError(f"invalid analysis parameters: {error}") from None
    if params.samples_per_mesh < 8:
        raise InputError("samples_per_mesh must be at least 8")
    return params


def database_url(args: argparse.Namespace) -> str:
    from service.settings import Settings

    return str(args.db or Settings().database_url)


def raw_store_root(args: argparse.Namespace) -> Path:
    from service.settings import Settings

    return Path(args.raw_store) if args.raw_store else Path(Settings().raw_store)


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
            f"{len(self.open_alarms)} open"
        )
        out.extend(f"  {line}" for line in self.open_alarms)
        return out


def replay_campaign(
    manifest: str | Path,
    session_factory: Any,
    raw_store: Any,
    params: Any = None,
    *,
    analyzer: Callable[..., Any] | None = None,
    progress: bool = True,
    only: Sequence[str] | None = None,
    reevaluate_alarms: bool = False,
) -> ReplaySummary:
    """Ingest every record of the manifest (those named in ``only``, when given), oldest first,
    one transaction per record; with ``reevaluate_alarms``, then recompute the rig's alarms from
    the current results (:func:`storage.evaluation.reevaluate_rig`, one transaction)."""
    from tqdm import tqdm

    from gearwatch.jobs import parse_taken_at, process_file
    from ingest.manifest import load_manifest
    from storage.db import session_scope

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
        from storage.evaluation import reevaluate_rig
        from storage.repositories import AuditRepository, RigRepository

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
    summary.open_alarms = open_alarm_lines(session_factory, campaign.rig.id)
    return summary


def open_alarm_lines(session_factory: Any, rig_name: str) -> list[str]:
    from storage.db import session_scope
    from storage.repositories import AlarmRepository, RigRepository

    with session_scope(session_factory) as session:
        rig = RigRepository(session).get_by_name(rig_name)
        if rig is None:
            return []
        lines = []
        for alarm in AlarmRepository(session).list(rig_id=rig.id, open_only=True, limit=None):
            where = f"tooth {alarm.tooth}" if alarm.tooth else "whole record"
            lines.append(
                f"#{alarm.id} {alarm.state:<12} {alarm.indicator} {where} on {alarm.channel.name}, "
                f"raised {alarm.raised_at:%Y-%m-%d %H:%M} UTC, last {alarm.last_score:+.1f} "
                "baseline units"
            )
        return lines


def run(args: argparse.Namespace) -> int:
    from storage.db import open_database
    from storage.raw_store import RawStore

    manifest = manifest_path(args.campaign)
    params = parameters_from_args(args)
    engine, factory = open_database(database_url(args))
    try:
        summary = replay_campaign(
            manifest, factory, RawStore(raw_store_root(args)), params,
            progress=not args.no_progress, reevaluate_alarms=args.reevaluate_alarms,
        )
    finally:
        engine.dispose()
    print("\n".join(summary.lines()))
    return 1 if summary.internal_errors else 0
