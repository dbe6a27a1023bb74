"""The fuzz harness's shared pieces: example counts, a per-input time limit, and the table of
outcomes printed at the end of a long run.

CI runs each target briefly (``FUZZ_EXAMPLES`` inputs, derandomized: the same inputs on every
run). The long run is a command::

    GEARWATCH_FUZZ_EXAMPLES=5000 .venv/bin/pytest -q -s tests/fuzz

and prints, per target, the inputs tried, the results (a record read, a record rejected with
its reason, a 2xx answer), the clean errors (a ``GearwatchError``), the
crashes (any other exception), the hangs (an input over :data:`HANG_SECONDS`) and the peak
RSS of the process. Crashes fail the test; a crasher that was fixed is kept as a regression
test in ``test_fuzz_regressions.py``.
"""

from __future__ import annotations

import os
import resource
import signal
import sys
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import pytest
from hypothesis import HealthCheck, settings

from gearwatch.floor.errors import GearwatchError

LONG_RUN = "GEARWATCH_FUZZ_EXAMPLES" in os.environ
FUZZ_EXAMPLES = int(os.environ.get("GEARWATCH_FUZZ_EXAMPLES", "25"))
HANG_SECONDS = 120
"""A hang is an input that never ends; the bound is generous so that a slow input on a loaded
2-core CI box (inputs take well under a second alone) is not reported as one."""

FUZZ_SETTINGS = settings(
    max_examples=FUZZ_EXAMPLES,
    derandomize=not LONG_RUN,
    deadline=None,
    database=None,
    suppress_health_check=list(HealthCheck),
)

TABLE: dict[str, Counter[str]] = {}


class Hang(Exception):
    """An input took more than :data:`HANG_SECONDS`."""


@contextmanager
def time_limit(seconds: int = HANG_SECONDS) -> Iterator[None]:
    def expire(_signum: int, _frame: Any) -> None:
        raise Hang(f"over {seconds} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def run_input(target: str, call: Callable[[], object]) -> None:
    """Run one fuzz input: a result or a clean error (a ``GearwatchError``, a 4xx) passes; a hang or any other exception is
    counted and raised (hypothesis then shrinks it to a small crasher)."""
    counts = TABLE.setdefault(target, Counter())
    counts["inputs"] += 1
    try:
        with time_limit():
            call()
    except GearwatchError:
        counts["clean errors"] += 1
    except Hang:
        counts["hangs"] += 1
        raise
    except Exception:
        counts["crashes"] += 1
        raise
    else:
        counts["results"] += 1


def peak_rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


@pytest.fixture(scope="session", autouse=True)
def fuzz_table() -> Iterator[None]:
    yield
    if not TABLE:
        return
    lines = [f"{'target':<22}{'inputs':>8}{'results':>9}{'clean errors':>14}{'crashes':>9}"
             f"{'hangs':>7}"]
    for target, counts in sorted(TABLE.items()):
        lines.append(f"{target:<22}{counts['inputs']:>8}{counts['results']:>9}"
                     f"{counts['clean errors']:>14}{counts['crashes']:>9}{counts['hangs']:>7}")
    lines.append(f"peak RSS of the process: {peak_rss_mib():.0f} MiB")
    if LONG_RUN:
        print("\n" + "\n".join(lines), file=sys.__stdout__)
