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
import sys
import time
from pathlib import Path
from typing import Any

IGNORED_SUFFIXES = (".part", ".tmp", ".partial", ".crdownload")


def register(subparsers: Any) -> None:
    from gearwatch.commands.replay import add_common_arguments

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


def candidate_files(folder: Path, suffixes: tuple[str, ...],
                    exclude: tuple[Path, ...] = ()) -> list[Path]:
    """Record files under ``folder`` a reader knows, oldest modification first; nothing under
    the ``exclude`` folders (the raw store may live inside the watched folder)."""
    excluded = tuple(e.resolve() for e in exclude)
    found = []
    for path in folder.rglob("*"):
        if any(path.resolve().is_relative_to(e) for e in excluded):
            continue
        name = path.name.lower()
        if name.startswith(".") or name.endswith(IGNORED_SUFFIXES) or not path.is_file():
            continue
        if any(part.startswith(".") for part in path.relative_to(folder).parts[:-1]):
            continue
        if name.endswith(suffixes):
            found.append(path)
    return sorted(found, key=lambda p: (p.stat().st_mtime_ns, str(p)))


class FolderWatcher:
    """Polls a folder; :meth:`poll` ingests the files that settled since the last poll."""

    def __init__(self, folder: Path, session_factory: Any, raw_store: Any, params: Any,
                 *, analyzer: Any = None) -> None:
        from ingest.sources import registered_suffixes

        self.folder = folder
        self.session_factory = session_factory
        self.raw_store = raw_store
        self.params = params
        self.analyzer = analyzer
        self.suffixes = tuple(s for s in registered_suffixes() if s != ".toml")
        self.seen: dict[Path, tuple[int, int]] = {}
        """Files already handled, with the (size, mtime) they had."""
        self.pending: dict[Path, tuple[int, int]] = {}
        self.counts: dict[str, int] = {}
        self.alarms_raised = 0

    def poll(self, *, settle: bool = True) -> list[tuple[Path, Any]]:
        """One pass; returns (file, job result) for every file ingested in it."""
        from gearwatch.jobs import process_file
        from ingest.manifest import load_manifest
        from storage.db import session_scope

        campaign = load_manifest(self.folder / "campaign.toml", check_files=False)
        done: list[tuple[Path, Any]] = []
        for path in candidate_files(self.folder, self.suffixes, (Path(self.raw_store.root),)):
            stat = path.stat()
            signature = (stat.st_size, stat.st_mtime_ns)
            if self.seen.get(path) == signature:
                continue
            if settle and self.pending.get(path) != signature:
                self.pending[path] = signature  # still changing, or seen for the first time
                continue
            self.pending.pop(path, None)
            with session_scope(self.session_factory) as session:
                result = process_file(session, path, campaign, raw_store=self.raw_store,
                                      params=self.params, analyzer=self.analyzer)
            self.seen[path] = signature
            self.counts[result.outcome] = self.counts.get(result.outcome, 0) + 1
            self.alarms_raised += sum(1 for c in result.alarm_changes if c.opened)
            done.append((path, result))
        return done


def run(args: argparse.Namespace) -> int:
    from gearwatch.commands.replay import (
        database_url,
        manifest_path,
        open_alarm_lines,
        parameters_from_args,
        raw_store_root,
    )
    from gearwatch.errors import InputError, ManifestError
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
    try:
        while True:
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
            time.sleep(args.interval)
    except KeyboardInterrupt:
        print("stopped", file=sys.stderr)
    finally:
        campaign_rig = _rig_name(folder)
        lines = open_alarm_lines(factory, campaign_rig) if campaign_rig else []
        engine.dispose()
    counts = ", ".join(f"{n} {k}" for k, n in sorted(watcher.counts.items())) or "nothing new"
    print(f"ingested: {counts}; alarms raised: {watcher.alarms_raised}; open: {len(lines)}")
    for line in lines:
        print(f"  {line}")
    return 0


def _rig_name(folder: Path) -> str | None:
    from gearwatch.errors import InputError
    from ingest.manifest import load_manifest

    try:
        return load_manifest(folder / "campaign.toml", check_files=False).rig.id
    except InputError:
        return None
