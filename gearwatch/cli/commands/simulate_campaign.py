"""``gearwatch simulate-campaign OUT_DIR [--days 12 --spall-tooth 16 --onset-day 10 --seed N]``."""

from __future__ import annotations

import argparse
from typing import Any


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "simulate-campaign",
        help="simulate a CETIM-style campaign directory (campaign.toml + one record per day)",
        description=(
            "Simulate a fatigue campaign with the gear-pair model: healthy days with "
            "day-to-day variation of load, speed, temperature and noise, then a pinion "
            "spall from the onset day that grows. Writes OUT_DIR/campaign.toml (the ingest "
            "manifest), OUT_DIR/records/dayNN.* and OUT_DIR/models/dayNN.toml. "
            "The same arguments give the same files."
        ),
    )
    parser.add_argument("out_dir", help="campaign directory to create")
    parser.add_argument("--days", type=int, default=12, help="daily records (default 12)")
    parser.add_argument(
        "--spall-tooth", type=int, default=16, help="spalled pinion tooth (default 16)"
    )
    parser.add_argument("--no-spall", action="store_true", help="a healthy campaign")
    parser.add_argument(
        "--onset-day", type=int, default=10, help="first day with the spall (default 10)"
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of everything random")
    parser.add_argument(
        "--format", choices=("wav", "hdf5", "tdms"), default="wav", help="record format"
    )
    parser.add_argument("--seconds", type=float, default=12.0, help="record length (default 12)")
    parser.add_argument("--model", help="base model TOML (default: the CETIM-like pair)")
    parser.add_argument("--campaign-id", help="campaign id (default sim-seed<N>)")
    parser.add_argument(
        "--start", default="2026-03-01T09:00:00Z", help="timestamp of day 1 (ISO 8601, UTC)"
    )
    parser.add_argument("--force", action="store_true", help="write into a non-empty OUT_DIR")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import sys

    from gearwatch.usecases.simulated_campaign import write_simulated_campaign

    def progress(day: int, days: int) -> None:
        print(f"day {day}/{days}", file=sys.stderr)

    path = write_simulated_campaign(
        args.out_dir,
        days=args.days,
        spall_tooth=None if args.no_spall else args.spall_tooth,
        onset_day=args.onset_day,
        seed=args.seed,
        record_format=args.format,
        seconds=args.seconds,
        model=args.model,
        campaign_id=args.campaign_id,
        start=args.start,
        force=args.force,
        progress=progress,
    )
    print(f"wrote {path}")
    return 0
