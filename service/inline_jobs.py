"""Reconciliations run by the API process itself (``GEARWATCH_JOB_RUNNER=inline``), bounded.

A reconciliation takes minutes and hundreds of MB. Run as plain background tasks, eight queued
by a fuzzer took 1.5 GB and 166 % CPU inside the API process. Here at most
:data:`MAX_RUNNING` run at once (the others wait their turn, off the event loop), at most
:data:`MAX_WAITING` may wait (more is 503 with Retry-After: start workers with
``GEARWATCH_JOB_RUNNER=broker``), and at start-up the reconciliations left ``queued`` or
``running`` by a process that stopped are run again (:func:`resume_interrupted`).
"""

from __future__ import annotations

import logging
import threading
from typing import Any

import sqlalchemy as sa

from gearwatch.floor.errors import ServiceUnavailable
from gearwatch.usecases.reconcile import run_reconciliation
from storage.db import session_scope
from storage.models import Reconciliation

logger = logging.getLogger(__name__)

MAX_RUNNING = 1
MAX_WAITING = 8

_slots = threading.BoundedSemaphore(MAX_RUNNING)
_waiting = 0
_waiting_lock = threading.Lock()


class ReconciliationQueueFull(ServiceUnavailable):
    code = "reconciliation_queue_full"
    retry_after_seconds = 120


def reserve() -> None:
    """Count one more waiting reconciliation, or refuse (503) when the queue is full."""
    global _waiting
    with _waiting_lock:
        if _waiting >= MAX_WAITING:
            raise ReconciliationQueueFull(
                f"{MAX_WAITING} reconciliations are already waiting in the API process: try "
                "later, or run them on workers (GEARWATCH_JOB_RUNNER=broker)"
            )
        _waiting += 1


def release() -> None:
    """Give back a reservation that will not run (the request failed after :func:`reserve`)."""
    global _waiting
    with _waiting_lock:
        _waiting = max(0, _waiting - 1)


def run_reserved(session_factory: Any, raw_store: Any, reconciliation_id: int) -> None:
    """Run one reserved reconciliation when a slot is free (called in a worker thread)."""
    global _waiting

    try:
        with _slots:
            with _waiting_lock:
                _waiting -= 1
            run_reconciliation(session_factory, raw_store, reconciliation_id)
    except Exception:  # the job records its own failures; this is a last resort for the log
        logger.exception("reconciliation %s failed in the API process", reconciliation_id)


def resume_interrupted(session_factory: Any, raw_store: Any) -> list[int]:
    """Start, in a background thread, the reconciliations a stopped process left ``queued``
    or ``running``; returns their ids."""
    with session_scope(session_factory) as session:
        ids = list(session.scalars(
            sa.select(Reconciliation.id)
            .where(Reconciliation.status.in_(("queued", "running")))
            .order_by(Reconciliation.id)
        ))
    if ids:
        logger.warning("resuming %d interrupted reconciliation(s): %s", len(ids), ids)

        def run_all() -> None:
            for reconciliation_id in ids:
                try:
                    reserve()
                except ReconciliationQueueFull:
                    logger.warning("reconciliation %s stays queued: queue full", reconciliation_id)
                    continue
                run_reserved(session_factory, raw_store, reconciliation_id)

        threading.Thread(target=run_all, name="resume-reconciliations", daemon=True).start()
    return ids
