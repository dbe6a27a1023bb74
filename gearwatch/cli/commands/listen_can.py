"""``gearwatch listen-can --interface socketcan --channel can0 --out DIR``: live CAN FD ingest.

Each record closed on the bus is written to ``DIR`` (accepted) or ``DIR/rejected`` (with
its raw frames and the reason), and listed in ``DIR/records.jsonl``.
"""

from __future__ import annotations

import argparse
from typing import Any

FORMATS = ("blf", "log", "asc", "npz")


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "listen-can",
        help="live ingest: assemble records from a CAN FD bus into record files",
        description=(
            "Listen to a CAN FD bus speaking the gearwatch rig protocol "
            "(ingest/can/gearwatch.dbc) and write every record to OUT: an accepted record as "
            "a CAN log of its frames (BLF by default, readable by every gearwatch command) or "
            "as NPZ; a rejected record (sequence gap, lost control frame, aborted) as a CAN "
            "log of the frames received in OUT/rejected with the reason. OUT/records.jsonl "
            "lists every record (file, status, reason, metadata). Stops on Ctrl-C, after "
            "--max-records or after --idle-timeout seconds without frames."
        ),
    )
    parser.add_argument("--interface", default="socketcan", help="python-can interface (default socketcan)")
    parser.add_argument("--channel", default="can0", help="bus channel (default can0)")
    parser.add_argument("--out", required=True, help="output folder (created)")
    parser.add_argument(
        "--format", choices=FORMATS, default="blf", help="file format of accepted records (default blf)"
    )
    parser.add_argument("--max-records", type=int, default=None, help="stop after this many records")
    parser.add_argument(
        "--idle-timeout", type=float, default=None, help="stop after this many seconds without frames"
    )
    parser.add_argument(
        "--bus-option",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="extra python-can bus argument (repeatable), e.g. port=43113",
    )
    parser.set_defaults(func=run)


def record_stem(record: Any) -> str:
    record_id = record.metadata.get("can_record_id", "unknown")
    start = record.metadata.get("can_start_time", "")[:19].replace(":", "").replace("-", "")
    return f"record-{record_id}-{start}" if start else f"record-{record_id}"


def save(record: Any, out: Any, file_format: str, index: int) -> Any:
    """Write one assembled record; return the path written."""
    import numpy as np

    if not record.accepted:
        folder = out / "rejected"
        folder.mkdir(exist_ok=True)
        path = folder / f"{index:05d}-{record_stem(record)}.blf"
        record.write_raw(path)
        return path
    path = out / f"{index:05d}-{record_stem(record)}.{file_format}"
    if file_format == "npz":
        data = record.record
        np.savez(path, sample_rate_hz=np.float64(data.sample_rate_hz), **data.channels)
    else:
        record.write_raw(path)
    return path


def run(args: argparse.Namespace) -> int:
    import json
    import signal
    import threading
    from pathlib import Path

    from gearwatch.cli.shared import bus_options
    from gearwatch.floor.errors import InputError
    from ingest.can.assembler import AssembledRecord, RecordAssembler
    from ingest.can.live import listen, open_bus

    if args.max_records is not None and args.max_records < 1:
        raise InputError("--max-records must be >= 1")
    out = Path(args.out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise InputError(f"{out}: cannot create the output folder: {error}") from error
    bus = open_bus(args.interface, args.channel, **bus_options(args.bus_option))
    stop = threading.Event()
    if threading.current_thread() is threading.main_thread():
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, lambda *_: stop.set())
    assembler = RecordAssembler(
        source=f"{args.interface}:{args.channel}",
        keep_accepted_raw_frames=args.format != "npz",
    )
    counts = {"accepted": 0, "rejected": 0}
    index_path = out / "records.jsonl"

    def on_record(record: AssembledRecord) -> None:
        counts[record.status] += 1
        path = save(record, out, args.format, counts["accepted"] + counts["rejected"])
        entry = {
            "file": str(path.relative_to(out)),
            "status": record.status,
            "reason": record.reason,
            "frames": len(record.raw_frames),
            "metadata": record.metadata,
        }
        with index_path.open("a", encoding="utf-8") as index:
            index.write(json.dumps(entry, ensure_ascii=False) + "\n")
        detail = record.reason if record.reason else f"{len(record.record.channels) if record.record else 0} channels"
        print(f"{record.status}: {path} ({detail})", flush=True)

    try:
        stats = listen(
            bus,
            on_record,
            stop_event=stop,
            assembler=assembler,
            max_records=args.max_records,
            idle_timeout_s=args.idle_timeout,
        )
    finally:
        bus.shutdown()
    print(
        f"{counts['accepted']} accepted, {counts['rejected']} rejected; {stats.frames} frames, "
        f"{stats.duplicates_dropped} duplicates dropped, {stats.foreign_frames} foreign frames",
        flush=True,
    )
    return 0
