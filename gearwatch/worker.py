"""The worker door: Dramatiq actors that run the per-record job and the physics reconciliation
of stored records (:mod:`gearwatch.usecases.job_queue`, which also queues them).

Start workers with::

    dramatiq gearwatch.worker --processes 2 --threads 1

Importing this module makes the RabbitMQ broker of ``GEARWATCH_BROKER_URL`` Dramatiq's global
broker and declares the actors on it: that is what the ``dramatiq`` command loads it for. Nothing
else imports it (the service queues jobs through :mod:`gearwatch.usecases.job_queue`).
"""

from __future__ import annotations

import logging
from typing import Any

import dramatiq

from gearwatch.floor.errors import DatabaseUnavailable
from gearwatch.usecases import job_queue
from storage.db import database_unavailable

logger = logging.getLogger(__name__)

broker = job_queue.broker()


@dramatiq.actor(
    actor_name=job_queue.ACTOR_NAME, queue_name=job_queue.queue_name(), max_retries=5,
    broker=broker,
)
def process_record(campaign: str, path: str, **options: Any) -> None:
    """Dramatiq actor: :func:`~gearwatch.usecases.job_queue.run_job` with the message's arguments.

    A database that cannot be reached or went away mid-job is one warning line and a retry
    (Dramatiq's backoff and ``max_retries``), not a traceback; the job is idempotent, so a retry
    of a job whose commit did reach the database finds its record and changes nothing."""
    try:
        outcome = job_queue.run_job(campaign, path, **options)
    except Exception as error:
        unavailable = database_unavailable(error)
        if not isinstance(unavailable, DatabaseUnavailable):
            raise
        reason = " ".join(str(getattr(error, "orig", None) or error).split())[:300]
        logger.warning("%s: database unavailable (%s); the job is retried", path, reason)
        raise dramatiq.Retry(f"database unavailable ({reason})") from None
    logger.info("%s: %s", path, outcome)


@dramatiq.actor(
    actor_name=job_queue.RECONCILE_ACTOR_NAME, queue_name=job_queue.queue_name(), max_retries=3,
    time_limit=job_queue.RECONCILE_TIME_LIMIT_MS, broker=broker,
)
def reconcile_record(reconciliation_id: int, **options: Any) -> None:
    """Dramatiq actor: :func:`~gearwatch.usecases.job_queue.run_reconciliation_job` (physics
    reconciliation of a stored record).

    Idempotent: a finished reconciliation is left alone; one left ``running`` by a worker that
    died is run again."""
    status = job_queue.run_reconciliation_job(reconciliation_id, **options)
    logger.info("reconciliation %s: %s", reconciliation_id, status)
