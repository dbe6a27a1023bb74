"""The per-process delivery thread of the alarm outbox never loses a kick, whatever the
interleaving (a commit that queues a notification while the thread is ending)."""

from __future__ import annotations

import threading
import time
from typing import Any

import pytest

WAIT_S = 60.0
"""A bound on a hang, not a speed requirement."""


def test_a_kick_while_the_delivery_thread_is_ending_starts_another_pass(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from storage import outbox_delivery

    passes: list[int] = []
    monkeypatch.setattr(outbox_delivery, "deliver_pending",
                        lambda engine, **kwargs: passes.append(1))
    deliverer = outbox_delivery._Deliverer(engine=object())  # type: ignore[arg-type]
    decided_to_end = threading.Event()
    release = threading.Event()
    real_run = deliverer._run

    def run_then_linger() -> None:
        real_run()
        decided_to_end.set()  # the thread has decided to end but is still alive
        release.wait(WAIT_S)

    deliverer._run = run_then_linger  # type: ignore[method-assign]
    try:
        deliverer.kick()
        assert decided_to_end.wait(WAIT_S)
        assert deliverer.thread is not None and deliverer.thread.is_alive()
        deliverer.kick()  # a notification committed now must still be delivered
        end = time.monotonic() + WAIT_S
        while len(passes) < 2 and time.monotonic() < end:
            time.sleep(0.01)
        assert len(passes) == 2, "the second kick was lost"
    finally:
        release.set()


@pytest.mark.filterwarnings("ignore::pytest.PytestUnhandledThreadExceptionWarning")
def test_a_thread_that_dies_does_not_block_later_kicks(monkeypatch: pytest.MonkeyPatch) -> None:
    from storage import outbox_delivery

    calls: list[int] = []

    def deliver_pending(engine: Any, **kwargs: Any) -> None:
        calls.append(1)
        if len(calls) == 1:
            raise SystemExit  # not an Exception: escapes the retry loop and ends the thread

    monkeypatch.setattr(outbox_delivery, "deliver_pending", deliver_pending)
    deliverer = outbox_delivery._Deliverer(engine=object())  # type: ignore[arg-type]
    deliverer.kick()
    deliverer.join(WAIT_S)
    deliverer.kick()
    deliverer.join(WAIT_S)
    assert len(calls) == 2
