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
    import datetime as dt
    import sys
    from pathlib import Path

    from gearwatch.commands.simulate import load_model
    from gearwatch.errors import InputError
    from physics.campaign import write_campaign

    out = Path(args.out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a directory")
    if out.is_dir() and any(out.iterdir()) and not args.force:
        raise InputError(f"{out}: directory is not empty (use --force)")
    if args.days < 1:
        raise InputError("--days must be ≥ 1")
    if not args.seconds > 0:
        raise InputError("--seconds must be > 0")
    if not 1 <= args.onset_day:
        raise InputError("--onset-day must be ≥ 1")
    try:
        dt.datetime.fromisoformat(args.start.replace("Z", "+00:00"))
    except ValueError:
        raise InputError(f"--start: not an ISO 8601 timestamp: {args.start!r}") from None
    model = load_model(args.model)
    teeth = model.geometry.pinion_teeth
    if not args.no_spall and not 1 <= args.spall_tooth <= teeth:
        raise InputError(f"--spall-tooth must be within 1..{teeth}")

    def progress(day: int, days: int) -> None:
        print(f"day {day}/{days}", file=sys.stderr)

    try:
        path = write_campaign(
            out,
            days=args.days,
            spall_tooth=None if args.no_spall else args.spall_tooth,
            onset_day=args.onset_day,
            seed=args.seed,
            record_format=args.format,
            seconds=args.seconds,
            campaign_id=args.campaign_id,
            start=args.start,
            base_model=model,
            progress=progress,
        )
    except ValueError as error:  # SimulationError and bad lengths: input, not a bug
        raise InputError(str(error)) from None
    print(f"wrote {path}")
    return 0
