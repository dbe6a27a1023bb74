"""``gearwatch alarms [--rig RIG] [--state S | --open] [--csv | --json]``: the alarm list."""

from __future__ import annotations

import argparse
from typing import Any

from gearwatch.cli.tables import add_output_arguments

COLUMNS = ("id", "rig_id", "where", "indicator", "state", "severity", "raised_at",
           "record_label", "last_value", "unit", "last_score", "acknowledged_by", "ack_comment")  # fmt: skip


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "alarms",
        help="list alarms (table, --csv or --json)",
        description="Alarms newest first (those raised by one record: highest score first), as the "
        "REST API lists them: a whole-record alarm has "
        "no tooth (`where` says `whole record`).",
    )
    parser.add_argument("--rig", help="only this rig")
    state = parser.add_mutually_exclusive_group()
    state.add_argument("--state", choices=("warning", "alarm", "acknowledged", "cleared"))
    state.add_argument("--open", action="store_true", help="only alarms not cleared")
    parser.add_argument("--limit", type=int, default=1000)
    add_output_arguments(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from gearwatch.cli.shared import database_url
    from gearwatch.cli.tables import csv_text, json_text, text_table
    from storage.db import open_database, session_scope
    from storage.operator_queries import alarm_list

    engine, factory = open_database(database_url(args))
    try:
        with session_scope(factory) as session:
            items = alarm_list(session, rig_name=args.rig, state=args.state,
                               open_only=args.open, limit=args.limit)
    finally:
        engine.dispose()
    for item in items:
        for key in ("raised_at", "acknowledged_at", "cleared_at"):
            if item[key] is not None:
                item[key] = item[key].isoformat().replace("+00:00", "Z")
    if args.json:
        print(json_text({"items": items}))
        return 0
    for item in items:
        item["where"] = "whole record" if item["tooth"] is None else f"tooth {item['tooth']}"
        item["raised_at"] = item["raised_at"][:16].replace("T", " ")
    table = [[item.get(c) for c in COLUMNS] for item in items]
    if args.csv:
        print(csv_text(COLUMNS, table), end="")
    elif items:
        print(text_table(COLUMNS, table))
    else:
        print("no alarm")
    return 0
