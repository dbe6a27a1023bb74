"""``gearwatch trends --rig RIG [--indicator NAME] [--tooth N] [--campaign NAME] [--csv | --json]``."""

from __future__ import annotations

import argparse
from typing import Any

from gearwatch.cli.tables import add_output_arguments


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "trends",
        help="print an indicator over a rig's accepted records (table, --csv or --json)",
        description="One row per accepted record (id, date, label), one column per tooth; a "
        "whole-record indicator (rms, kurtosis, fm4, na4, raw_kurtosis …) has one column. "
        "--json prints the REST API's trend answer.",
    )
    parser.add_argument("--rig", required=True, help="the rig's id")
    parser.add_argument("--indicator", default="mci_depth", help="default mci_depth")
    parser.add_argument("--tooth", type=int, help="one pinion tooth")
    parser.add_argument("--channel", help="accelerometer channel (default: the first)")
    parser.add_argument("--campaign", help="one campaign of the rig, numbered by the gear pair "
                        "it ran (default: every campaign of the rig's current pair)")
    add_output_arguments(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from gearwatch.cli.shared import database_url
    from gearwatch.cli.tables import csv_text, json_text, text_table
    from gearwatch.floor.errors import NotFound
    from storage.db import open_database, session_scope
    from storage.operator_queries import trend_data, trend_table
    from storage.repositories import RigRepository

    engine, factory = open_database(database_url(args))
    try:
        with session_scope(factory) as session:
            rig = RigRepository(session).get_by_name(args.rig)
            if rig is None:
                raise NotFound(f"rig {args.rig!r} not found")
            trend = trend_data(session, rig, args.indicator, args.tooth, args.channel,
                               args.campaign)
    finally:
        engine.dispose()
    for record in (*trend["records"], *trend["without_tooth_values"]):
        record["taken_at"] = record["taken_at"].isoformat().replace("+00:00", "Z")
    if args.json:
        print(json_text(trend))
        return 0
    if args.csv:
        header, rows = trend_table(trend)
        print(csv_text(header, rows), end="")
        return 0
    unit = f" [{trend['unit']}]" if trend["unit"] else ""
    teeth = ["whole record" if t is None else f"t{t}" for t in trend["teeth"]]
    rows = [
        [r["record_id"], r["taken_at"][:16].replace("T", " "), r["label"], *values]
        for r, values in zip(trend["records"], trend["values"], strict=True)
    ]
    scope = f", campaign {trend['campaign']}" if trend["campaign"] else ""
    print(f"{trend['rig_id']}: {trend['title']}{unit}, channel {trend['channel']}{scope}")
    print(text_table(["record", "taken at (UTC)", "label", *teeth], rows) if rows
          else "no accepted record")
    without = trend["without_tooth_values"]
    if without:
        print(f"{len(without)} accepted record(s) without per-tooth values (whole-record metrics only):")
        for record in without:
            print(f"  {record['record_id']}  {record['taken_at'][:16].replace('T', ' ')}  "
                  f"{record['label']}: {record['reason'] or 'no per-tooth values'}")
    return 0
