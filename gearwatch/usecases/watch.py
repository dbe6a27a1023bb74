"""Watch a campaign folder: ingest the record files dropped into it once they settled.

``DIR/campaign.toml`` describes the campaign; record files anywhere under ``DIR`` with a suffix
a reader knows are ingested through the per-record job once their size and modification time
stopped changing between two polls (a file still being copied is left for the next poll).
Hidden files and ``*.part``/``*.tmp`` are ignored. The manifest is re-read on every poll, so a
``[[records]]`` entry added with the file gives it its ``taken_at``; a file the manifest does
not list takes the reader's timestamp, else its modification time.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from gearwatch.usecases.ingest_file import process_file
from ingest.manifest import load_manifest
from ingest.sources import registered_suffixes
from storage.db import session_scope

if TYPE_CHECKING:
    from sqlalchemy.orm import Session, sessionmaker

    from gearwatch.floor.results import AnalysisParameters
    from gearwatch.usecases.ingest_file import JobResult
    from storage.raw_store import RawStore

IGNORED_SUFFIXES = (".part", ".tmp", ".partial", ".crdownload")



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

    def __init__(self, folder: Path, session_factory: sessionmaker[Session], raw_store: RawStore,
                 params: AnalysisParameters | None, *, analyzer: Any = None) -> None:
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

    def poll(self, *, settle: bool = True) -> list[tuple[Path, JobResult]]:
        """One pass; returns (file, job result) for every file ingested in it."""
        campaign = load_manifest(self.folder / "campaign.toml", check_files=False)
        done: list[tuple[Path, JobResult]] = []
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
