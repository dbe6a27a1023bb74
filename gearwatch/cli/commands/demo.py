"""``gearwatch demo``: the main job on a fresh machine, SQLite and nothing else.

Simulate a 12-day CETIM-style campaign (a spall appears on pinion tooth 16 on day 10), replay it
into a SQLite database with a progress bar, print the last day's per-tooth table and the alarms,
create an operator API key, then serve the REST API and the dashboard and print their URL.
Everything lives in one folder (default ``./gearwatch-demo``); running again reuses it.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "demo",
        help="simulate a campaign, replay it, serve the dashboard (SQLite, no other service)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--dir", default="gearwatch-demo", help="demo folder (default ./gearwatch-demo)")
    parser.add_argument("--days", type=int, default=12, help="days to simulate (default 12)")
    parser.add_argument("--spall-tooth", type=int, default=16, help="spalled pinion tooth (default 16)")
    parser.add_argument("--onset-day", type=int, default=10, help="day the spall appears (default 10)")
    parser.add_argument("--seed", type=int, default=1, help="simulation seed (default 1)")
    parser.add_argument("--host", default="127.0.0.1", help="address to serve on (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=8000, help="port to serve on (default 8000)")
    parser.add_argument(
        "--no-serve", action="store_true", help="stop after the replay (print the key, do not serve)"
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import sys

    from gearwatch.cli.shared import print_report, serve_api
    from gearwatch.floor.errors import GearwatchError, InputError
    from gearwatch.usecases.analyze import analyze_file
    from gearwatch.usecases.keys import create_api_key
    from gearwatch.usecases.replay import replay_into_database
    from gearwatch.usecases.simulated_campaign import write_simulated_campaign
    from ingest.manifest import load_manifest

    folder = Path(args.dir).resolve()
    campaign_dir = folder / "campaign"
    database_url = f"sqlite:///{folder / 'gearwatch.db'}"
    raw_store = folder / "raw-store"
    folder.mkdir(parents=True, exist_ok=True)

    def progress(day: int, days: int) -> None:
        print(f"day {day}/{days}", file=sys.stderr)

    if (campaign_dir / "campaign.toml").is_file():
        print(f"== reusing the simulated campaign in {campaign_dir}")
    else:
        print(
            f"\n== simulating a {args.days}-day campaign (spall on tooth {args.spall_tooth} "
            f"from day {args.onset_day})", flush=True,
        )
        written = write_simulated_campaign(
            campaign_dir, days=args.days, spall_tooth=args.spall_tooth,
            onset_day=args.onset_day, seed=args.seed, progress=progress,
        )
        print(f"wrote {written}")
    print("\n== replaying it into " + database_url, flush=True)
    summary = replay_into_database(campaign_dir / "campaign.toml", database_url, raw_store)
    print("\n".join(summary.lines()))
    if summary.internal_errors:
        raise GearwatchError("demo step 'replaying it into the database' failed (exit 1)")

    last_record = _last_record(campaign_dir)
    print(f"\n== per-tooth results of the last day ({last_record.name})", flush=True)
    print_report(analyze_file(last_record, load_manifest(campaign_dir / "campaign.toml")))

    key = create_api_key(database_url, role="operator", name="demo", who="demo")
    url = f"http://{args.host}:{args.port}/"
    print("\n== dashboard and API")
    print(f"dashboard: {url}#key={key}")
    print(f"API docs:  {url}docs")
    print(f"API key (operator; paste it into the dashboard): {key}")
    print(f'try:       curl -H "Authorization: Bearer {key}" '
          f"'{url}api/v1/alarms?state=alarm'")
    if args.no_serve:
        return 0
    if not 0 < args.port < 65536:
        raise InputError(f"--port {args.port}: not a TCP port")
    os.environ["GEARWATCH_DATABASE_URL"] = database_url
    os.environ["GEARWATCH_RAW_STORE"] = str(raw_store)
    print("serving; Ctrl-C to stop", flush=True)
    serve_api(args.host, args.port, database_url=database_url)
    return 0


def _last_record(campaign_dir: Path) -> Path:
    from ingest.manifest import load_manifest

    campaign = load_manifest(campaign_dir / "campaign.toml")
    entry = max(campaign.records, key=lambda e: e.taken_at)
    return campaign.record_path(entry)
