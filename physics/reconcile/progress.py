"""Progress of a reconciliation: which stage it is in and how far along, for people waiting.

A reconciliation of a long record with a reference takes minutes; :func:`reconcile
<physics.reconcile.method.reconcile>` reports ``(stage, fraction)`` through a callback so that
the CLI can draw a bar on stderr (:func:`tqdm_progress`) and the REST job can store it in the
reconciliation's status. :class:`Progress` maps each stage's own 0…1 onto its share of the
whole run (nested: the reference's reconciliation is a span of its record's).

Examples
--------
>>> seen = []
>>> p = Progress(lambda stage, fraction: seen.append((stage, round(fraction, 2))))
>>> p.report("calibration", 0.5)
>>> ref = p.span(0.0, 0.4, "reference: ")
>>> ref.report("selection", 1.0)
>>> seen
[('calibration', 0.5), ('reference: selection', 0.4)]
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from typing import Any

ProgressCallback = Callable[[str, float], None]
"""Called with a stage name and the fraction of the whole run done (0 … 1, non-decreasing)."""

STAGE_SHARES = {
    "observable": (0.0, 0.03),
    "calibration": (0.03, 0.25),
    "selection": (0.25, 0.93),
    "intervals": (0.93, 1.0),
}
"""Share of a reconciliation (without reference) each stage takes, measured on the speed
benchmark's records (selection dominates: one simulation per scanned candidate and refit)."""

REFERENCE_SHARE = 0.4
"""With a reference: the reference's own reconciliation takes this first share of the run."""


class Progress:
    """A span ``[start, stop]`` of the whole run, reporting to ``callback`` (None: silent)."""

    def __init__(
        self,
        callback: ProgressCallback | None,
        start: float = 0.0,
        stop: float = 1.0,
        prefix: str = "",
    ) -> None:
        self.callback = callback
        self.start = start
        self.stop = stop
        self.prefix = prefix
        self._last = start

    def report(self, stage: str, fraction: float) -> None:
        """``fraction`` (0 … 1) of this span done, now in ``stage``; never goes backwards."""
        if self.callback is None:
            return
        value = self.start + (self.stop - self.start) * min(1.0, max(0.0, fraction))
        self._last = max(self._last, value)
        self.callback(self.prefix + stage, self._last)

    def stage(self, stage: str, fraction: float) -> None:
        """``fraction`` (0 … 1) through one of :data:`STAGE_SHARES`."""
        lo, hi = STAGE_SHARES[stage]
        self.report(stage, lo + (hi - lo) * min(1.0, max(0.0, fraction)))

    def span(self, start: float, stop: float, prefix: str = "") -> Progress:
        """The sub-span ``[start, stop]`` (fractions of this span)."""
        width = self.stop - self.start
        return Progress(self.callback, self.start + width * start, self.start + width * stop, self.prefix + prefix)


def tqdm_progress(description: str = "reconcile", file: Any = None) -> tuple[ProgressCallback, Callable[[], None]]:
    """A callback drawing a tqdm bar (percent of the run, stage in the postfix) on stderr.

    Returns ``(callback, close)``.
    """
    from tqdm import tqdm

    bar = tqdm(total=100, desc=description, unit="%", file=file or sys.stderr, mininterval=1.0,
               bar_format="{desc}: {percentage:3.0f}%|{bar}| {elapsed} {postfix}")

    def callback(stage: str, fraction: float) -> None:
        target = round(100.0 * fraction, 1)
        bar.set_postfix_str(stage, refresh=False)
        if target > bar.n:
            bar.update(target - bar.n)  # redraws at most once per ``mininterval``

    return callback, bar.close


class StageTicker:
    """Advances a stage's share with every simulation (most of a run's time), approaching the
    end of the current window ``[lo, hi]`` of that stage without reaching it: a long run is
    seen to be alive, and where it is.

    Examples
    --------
    >>> seen = []
    >>> t = StageTicker(Progress(lambda s, f: seen.append((s, round(f, 3)))))
    >>> t.enter("calibration", 0.0, 1.0, simulations=0)
    >>> t(40)
    >>> seen[-1]
    ('calibration', 0.169)
    """

    def __init__(self, progress: Progress, scale: float = 40.0) -> None:
        self.progress = progress
        self.scale = scale
        self.stage_name = "calibration"
        self.lo, self.hi, self.start = 0.0, 1.0, 0

    def enter(self, stage: str, lo: float, hi: float, simulations: int) -> None:
        self.stage_name, self.lo, self.hi, self.start = stage, lo, hi, simulations
        self.progress.stage(stage, lo)

    def __call__(self, simulations: int) -> None:
        done = 1.0 - math.exp(-(simulations - self.start) / self.scale)
        self.progress.stage(self.stage_name, self.lo + (self.hi - self.lo) * done)
