"""``gearwatch watch DIR``: ingest record files dropped into a folder (polling).

``DIR/campaign.toml`` describes the campaign; record files anywhere under ``DIR`` with a suffix
a reader knows are ingested through the per-record job once their size and modification time
stopped changing between two polls (a file still being copied is left for the next poll).
Hidden files and ``*.part``/``*.tmp`` are ignored. The manifest is re-read on every poll, so a
``[[records]]`` entry added with the file gives it its ``taken_at``; a file the manifest does
not list takes the reader's timestamp, else its modification time.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from pathlib import Path
from typing import Any

from gearwatch.cli.shared import (
    add_common_arguments,
    database_url,
    manifest_path,
    parameters_from_args,
    raw_store_root,
)


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "watch",
        help="ingest record files dropped into a folder (polling)",
        description=(
            "Watch DIR (with its campaign.toml) and ingest every new record file through "
            "the per-record job: keep the raw file, analyse, store, evaluate alarms. "
            "Stop with Ctrl-C."
        ),
    )
    parser.add_argument("folder", metavar="DIR", help="folder with campaign.toml and records")
    parser.add_argument("--interval", type=float, default=5.0,
                        help="seconds between polls (default 5)")
    parser.add_argument("--once", action="store_true",
                        help="ingest what is there now and exit (no settling wait)")
    add_common_arguments(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from gearwatch.floor.errors import InputError, ManifestError
    from gearwatch.usecases.replay import open_alarm_lines
    from gearwatch.usecases.watch import FolderWatcher
    from storage.db import open_database
    from storage.raw_store import RawStore

    folder = Path(args.folder)
    if not folder.is_dir():
        raise InputError(f"{folder}: not a directory")
    manifest_path(folder)
    if not args.interval > 0:
        raise InputError("--interval must be positive")
    params = parameters_from_args(args)
    engine, factory = open_database(database_url(args))
    store = RawStore(raw_store_root(args))
    watcher = FolderWatcher(folder, factory, store, params)
    if not args.once:
        print(f"watching {folder} every {args.interval:g} s (Ctrl-C to stop)", file=sys.stderr)
    # Stop between polls on Ctrl-C or SIGTERM (docker stop, systemd), whatever the inherited
    # disposition: a watcher started in the background of a non-interactive shell inherits
    # SIGINT *ignored*, and Python then never raises KeyboardInterrupt.
    stop = threading.Event()

    def on_signal(*_: object) -> None:
        if stop.is_set():  # asked twice: do not wait for the file being ingested
            raise KeyboardInterrupt
        stop.set()

    if threading.current_thread() is threading.main_thread():
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, on_signal)
    try:
        while not stop.is_set():
            try:
                done = watcher.poll(settle=not args.once)
            except ManifestError as error:
                if args.once:
                    raise
                # A manifest being edited must not stop a long-running watcher.
                print(f"gearwatch: warning: {error} (retrying)", file=sys.stderr, flush=True)
                done = []
            for path, result in done:
                line = f"{path.relative_to(folder)}: {result.outcome}"
                if result.reason:
                    line += f" ({result.reason})"
                if result.alarm_changes:
                    line += f", {len(result.alarm_changes)} alarm change(s)"
                print(line, flush=True)
            if args.once:
                break
            stop.wait(args.interval)
        if stop.is_set():
            print("stopped", file=sys.stderr)
    except KeyboardInterrupt:  # a second Ctrl-C while a file was being ingested
        print("stopped", file=sys.stderr)
    finally:
        names = _rig_and_campaign(folder)
        lines, others = open_alarm_lines(factory, *names) if names else ([], 0)
        engine.dispose()
    counts = ", ".join(f"{n} {k}" for k, n in sorted(watcher.counts.items())) or "nothing new"
    print(f"ingested: {counts}; alarms raised: {watcher.alarms_raised}; "
          f"open in this campaign: {len(lines)}")
    for line in lines:
        print(f"  {line}")
    if names and others:
        print(f"  (and {others} open in the rig's other campaigns: "
              f"gearwatch alarms --rig {names[0]} --open)")
    return 0


def _rig_and_campaign(folder: Path) -> tuple[str, str] | None:
    from gearwatch.floor.errors import InputError
    from ingest.manifest import load_manifest

    try:
        campaign = load_manifest(folder / "campaign.toml", check_files=False)
    except InputError:
        return None
    return campaign.rig.id, campaign.id
