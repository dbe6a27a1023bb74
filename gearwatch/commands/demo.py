"""``gearwatch demo``: the main job on a fresh machine, SQLite and nothing else.

Simulate a 12-day CETIM-style campaign (a spall appears on pinion tooth 16 on day 10), replay it
into a SQLite database with a progress bar, print the last day's per-tooth table and the alarms,
create an operator API key, then serve the REST API and the dashboard and print their URL.
Everything lives in one folder (default ``./gearwatch-demo``); running again reuses it.
"""

from __future__ import annotations

import argparse
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
    import os

    from gearwatch.cli import main as cli_main
    from gearwatch.commands.keys import create_api_key
    from gearwatch.errors import GearwatchError, InputError

    folder = Path(args.dir).resolve()
    campaign_dir = folder / "campaign"
    database_url = f"sqlite:///{folder / 'gearwatch.db'}"
    raw_store = folder / "raw-store"
    folder.mkdir(parents=True, exist_ok=True)

    def step(title: str, argv: list[str]) -> None:
        print(f"\n== {title}", flush=True)
        code = cli_main(argv)
        if code != 0:
            raise GearwatchError(f"demo step '{title}' failed (exit {code})")

    if (campaign_dir / "campaign.toml").is_file():
        print(f"== reusing the simulated campaign in {campaign_dir}")
    else:
        step(
            f"simulating a {args.days}-day campaign (spall on tooth {args.spall_tooth} "
            f"from day {args.onset_day})",
            ["simulate-campaign", str(campaign_dir), "--days", str(args.days),
             "--spall-tooth", str(args.spall_tooth), "--onset-day", str(args.onset_day),
             "--seed", str(args.seed)],
        )
    step("replaying it into " + database_url,
         ["replay", str(campaign_dir), "--db", database_url, "--raw-store", str(raw_store)])

    last_record = _last_record(campaign_dir)
    step(f"per-tooth results of the last day ({last_record.name})",
         ["analyze", str(last_record), "--campaign", str(campaign_dir / "campaign.toml")])

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
    return cli_main(["serve", "--host", args.host, "--port", str(args.port), "--db", database_url])


def _last_record(campaign_dir: Path) -> Path:
    from ingest.manifest import load_manifest

    campaign = load_manifest(campaign_dir / "campaign.toml")
    entry = max(campaign.records, key=lambda e: e.taken_at)
    return campaign.record_path(entry)
