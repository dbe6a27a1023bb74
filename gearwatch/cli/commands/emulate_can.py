"""``gearwatch emulate-can [RECORD ...] --campaign campaign.toml --interface virtual --channel rig``.

Plays record files (any format the reader registry reads) onto a CAN FD bus with the rig
protocol of ``ingest/can/gearwatch.dbc``, like a test rig would.
"""

from __future__ import annotations

import argparse
from typing import Any


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "emulate-can",
        help="play record files onto a CAN FD bus like a test rig (rig emulator)",
        description=(
            "Play record files onto a CAN FD bus with the gearwatch rig protocol "
            "(ingest/can/gearwatch.dbc). Without RECORD arguments the campaign's records are "
            "played in manifest order, each stamped with its taken_at time. Channel kinds, "
            "tachometer and pulses per revolution come from the campaign manifest."
        ),
    )
    parser.add_argument("records", nargs="*", help="record files (default: the campaign's records)")
    parser.add_argument("--campaign", required=True, help="campaign manifest (campaign.toml)")
    parser.add_argument(
        "--interface", default="virtual", help="python-can interface: socketcan, virtual, udp_multicast …"
    )
    parser.add_argument("--channel", default="gearwatch", help="bus channel (can0, a virtual name, a multicast group)")
    parser.add_argument(
        "--speed",
        type=float,
        default=1.0,
        help="1 = real time (default), 10 = ten times faster, 0 = as fast as the bus takes frames",
    )
    parser.add_argument(
        "--max-fps", type=float, default=None, help="cap on frames per second (flow control for UDP)"
    )
    parser.add_argument("--record-id", type=int, default=1, help="record id of the first record (default 1)")
    parser.add_argument("--repeat", type=int, default=1, help="play the list this many times (default 1)")
    parser.add_argument(
        "--bus-option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="extra python-can bus argument (repeatable), e.g. port=43113 or bitrate=1000000",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import datetime as dt
    from pathlib import Path

    from gearwatch.cli.shared import bus_options
    from gearwatch.floor.errors import InputError
    from ingest.can.emulator import emulate
    from ingest.can.live import open_bus
    from ingest.manifest import load_manifest
    from ingest.sources import read_record

    if args.speed < 0:
        raise InputError("--speed must be >= 0")
    if args.repeat < 1:
        raise InputError("--repeat must be >= 1")
    if not 0 <= args.record_id < 2**32:
        raise InputError("--record-id must be in 0 .. 2**32 - 1")
    campaign = load_manifest(args.campaign, check_files=not args.records)
    plays: list[tuple[Path, dt.datetime | None, dict[str, str]]] = []
    if args.records:
        plays = [(Path(path), None, {}) for path in args.records]
    else:
        for entry in campaign.records:
            try:
                taken_at: dt.datetime | None = dt.datetime.fromisoformat(entry.taken_at)
            except ValueError:
                taken_at = None
            extra = {"taken_at": entry.taken_at, "label": entry.label}
            plays.append((campaign.record_path(entry), taken_at, extra))
    if not plays:
        raise InputError(f"{args.campaign}: the campaign lists no records and none were given")
    tach = campaign.tachometer
    units = {c.name: c.unit for c in campaign.channels}
    kinds: dict[str, str] = {}
    for channel in campaign.channels:
        if tach is not None and channel.name == tach.channel:
            kinds[channel.name] = (
                "tachometer_pulse_times" if tach.kind == "pulse_times" else "tachometer_waveform"
            )
        else:
            kinds[channel.name] = "accelerometer"
    bus = open_bus(args.interface, args.channel, **bus_options(args.bus_option))
    record_id = args.record_id
    try:
        for _ in range(args.repeat):
            for path, taken_at, extra in plays:
                record = read_record(path, campaign)
                record.metadata.update({k: v for k, v in extra.items() if v})
                try:
                    stats = emulate(
                        bus,
                        record,
                        speed=args.speed,
                        first_record_id=record_id % 2**32,
                        max_frames_per_s=args.max_fps,
                        channel_kinds=kinds,
                        pulses_per_rev=tach.pulses_per_rev if tach is not None else 1,
                        tach_shaft=tach.shaft if tach is not None else "pinion",
                        units=units,
                        start_time=taken_at,
                    )
                except ValueError as error:
                    raise InputError(f"{path}: cannot send on CAN: {error}") from error
                print(
                    f"record {record_id}: {path.name} → {stats.frames} frames in "
                    f"{stats.elapsed_s:.3f} s ({stats.frames_per_s:,.0f} frames/s)",
                    flush=True,
                )
                record_id += 1
    finally:
        bus.shutdown()
    return 0
