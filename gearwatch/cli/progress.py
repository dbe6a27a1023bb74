"""Stage progress on stderr for long commands whose inner steps report nothing (tqdm).

Shows which stage runs, how many are done and the elapsed time, refreshed twice a second, so a
command that works for minutes never looks hung. Disabled (no output) with ``enabled=False``.
"""

from __future__ import annotations

import sys
import threading
from collections.abc import Sequence
from types import TracebackType
from typing import Any

REFRESH_S = 0.5


class StageProgress:
    def __init__(self, description: str, stages: Sequence[str], *, enabled: bool = True) -> None:
        self.description = description
        self.stages = list(stages)
        self.enabled = enabled
        self.bar: Any = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._done = 0

    def __enter__(self) -> StageProgress:
        if self.enabled:
            from tqdm import tqdm

            self.bar = tqdm(
                total=len(self.stages), desc=self.description, file=sys.stderr, leave=True,
                bar_format="{desc}: {n_fmt}/{total_fmt} stages |{bar:20}| {postfix} [{elapsed}]",
                dynamic_ncols=True,
            )
            self._thread = threading.Thread(target=self._tick, daemon=True)
            self._thread.start()
        return self

    def _tick(self) -> None:
        while not self._stop.wait(REFRESH_S):
            if self.bar is not None:
                self.bar.refresh()

    def stage(self, name: str) -> None:
        """Start stage ``name`` (the previous one counts as done)."""
        if self.bar is None:
            return
        if name in self.stages:
            done = self.stages.index(name)
            if done > self._done:
                self.bar.update(done - self._done)
                self._done = done
        self.bar.set_postfix_str(name)

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        if self.bar is not None:
            if exc_type is None:
                self.bar.update(len(self.stages) - self._done)
                self.bar.set_postfix_str("done")
            self.bar.close()
