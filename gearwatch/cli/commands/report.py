"""``gearwatch report --rig RIG --out FILE.pdf|.html [--db URL]``: the campaign report."""

from __future__ import annotations

import argparse
from typing import Any


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "report",
        help="write a rig's campaign report (PDF or HTML)",
        description="Heat map, each alarmed tooth's trend with its alarms and "
        "acknowledgements, the MCI curves of the first and last days and of each alarm day, "
        "the classic metrics, data quality per record and provenance, as a PDF or a "
        "self-contained HTML page (by the suffix of --out).",
    )
    parser.add_argument("--rig", required=True, help="the rig's id (manifest rig.id)")
    parser.add_argument("--out", required=True, help="FILE.pdf or FILE.html")
    parser.add_argument("--db", metavar="URL", help="database URL (default: $GEARWATCH_DATABASE_URL)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import sys
    from pathlib import Path

    from gearwatch.cli.shared import database_url
    from gearwatch.usecases.report import write
    from storage.db import open_database, session_scope

    engine, factory = open_database(database_url(args))
    try:
        with session_scope(factory) as session:
            data = write(session, args.rig, Path(args.out))
    finally:
        engine.dispose()
    print(
        f"{args.out}: rig {data.rig}, {len(data.records)} records, {len(data.alarms)} alarms",
        file=sys.stderr,
    )
    return 0
