"""Dramatiq actors running the per-record job (and physics reconciliations of stored records,
:func:`reconcile_record`) on workers fed through RabbitMQ.

Start workers with the broker, database and raw store of the service::

    GEARWATCH_BROKER_URL=amqp://guest:guest@127.0.0.1:5672/ \\
    GEARWATCH_DATABASE_URL=postgresql+psycopg://... GEARWATCH_RAW_STORE=/srv/raw \\
    dramatiq gearwatch.worker --processes 2 --threads 1

and enqueue with :func:`enqueue_record`. Exactly-once results rest on three facts: RabbitMQ
acknowledges a message only after the actor returned (a worker that dies mid-job has its
message delivered to another worker); the job's database work is one transaction committed at
the end (a dead worker leaves nothing behind); and the job is idempotent on the file's sha256
with unique constraints behind it (a message delivered twice — the worker died after the commit
but before the acknowledgement — finds its record and changes nothing; two workers racing on
the same file collide on the constraint and the loser re-runs and finds it done).

The queue name is ``GEARWATCH_QUEUE`` (default ``gearwatch-records``), so that test runs can
use a queue of their own.
"""

from __future__ import annotations

import logging
import os
import threading
from typing import Any

import dramatiq
from dramatiq.brokers.rabbitmq import RabbitmqBroker

logger = logging.getLogger(__name__)

QUEUE_NAME = os.environ.get("GEARWATCH_QUEUE", "gearwatch-records")
ACTOR_NAME = "process_record"
RECONCILE_ACTOR_NAME = "reconcile_record"
RECONCILE_TIME_LIMIT_MS = 60 * 60 * 1000
"""A reconciliation runs minutes (the simulator is in the loop); Dramatiq's default limit is 10."""
INTEGRITY_RETRIES = 3


def _broker_url() -> str:
    from service.settings import Settings

    return Settings().broker_url


broker = RabbitmqBroker(url=_broker_url())
dramatiq.set_broker(broker)

_databases: dict[str, Any] = {}
_databases_lock = threading.Lock()


def _session_factory(url: str) -> Any:
    """One engine per database URL and process (migrated once)."""
    from storage.db import open_database

    with _databases_lock:
        if url not in _databases:
            _databases[url] = open_database(url)[1]
        return _databases[url]


def run_job(
    campaign: str,
    path: str,
    *,
    taken_at: str | None = None,
    label: str = "",
    file_name: str | None = None,
    params: dict[str, Any] | None = None,
    database_url: str | None = None,
    raw_store: str | None = None,
) -> dict[str, Any]:
    """The job one message asks for: ingest ``path`` into the stored campaign ``campaign``.

    Commits once, at the end. A unique-constraint collision (another worker ingested the same
    file, or created the same rig, at the same moment) is retried: the retry finds the other
    worker's rows and changes nothing.
    """
    import sqlalchemy.exc

    from gearwatch.jobs import campaign_config, process_file
    from gearwatch.results import AnalysisParameters
    from service.settings import Settings
    from storage.db import session_scope
    from storage.raw_store import RawStore
    from storage.repositories import CampaignRepository

    settings = Settings()
    factory = _session_factory(database_url or settings.database_url)
    store = RawStore(raw_store or settings.raw_store)
    analysis_params = AnalysisParameters.from_dict(params or {})
    for attempt in range(INTEGRITY_RETRIES + 1):
        try:
            with session_scope(factory) as session:
                stored = CampaignRepository(session).get_by_name(campaign)
                if stored is None:
                    from gearwatch.errors import NotFound

                    raise NotFound(f"campaign {campaign!r} is not in the database")
                result = process_file(
                    session, path, campaign_config(stored), raw_store=store,
                    params=analysis_params, taken_at=taken_at, label=label, file_name=file_name,
                )
            return {"record_id": result.record_id, "outcome": result.outcome,
                    "status": result.status, "reason": result.reason}
        except sqlalchemy.exc.IntegrityError:
            if attempt == INTEGRITY_RETRIES:
                raise
            logger.info("integrity conflict on %s (another worker?): retrying", path)
    raise AssertionError("unreachable")


@dramatiq.actor(actor_name=ACTOR_NAME, queue_name=QUEUE_NAME, max_retries=5)
def process_record(campaign: str, path: str, **options: Any) -> None:
    """Dramatiq actor: :func:`run_job` with the message's arguments."""
    outcome = run_job(campaign, path, **options)
    logger.info("%s: %s", path, outcome)


def enqueue_record(campaign: str, path: str, **options: Any) -> str:
    """Put one per-record job on the queue; returns the message id."""
    message = process_record.send(campaign, str(path), **options)
    return str(message.message_id)


def run_reconciliation_job(
    reconciliation_id: int, *, database_url: str | None = None, raw_store: str | None = None
) -> str:
    """The job a ``reconcile_record`` message asks for; returns the final status."""
    from gearwatch.reconcile_job import run_reconciliation
    from service.settings import Settings
    from storage.raw_store import RawStore

    settings = Settings()
    factory = _session_factory(database_url or settings.database_url)
    return run_reconciliation(factory, RawStore(raw_store or settings.raw_store), reconciliation_id)


@dramatiq.actor(
    actor_name=RECONCILE_ACTOR_NAME, queue_name=QUEUE_NAME, max_retries=3,
    time_limit=RECONCILE_TIME_LIMIT_MS,
)
def reconcile_record(reconciliation_id: int, **options: Any) -> None:
    """Dramatiq actor: :func:`run_reconciliation_job` (physics reconciliation of a stored record).

    Idempotent: a finished reconciliation is left alone; one left ``running`` by a worker that
    died is run again."""
    status = run_reconciliation_job(reconciliation_id, **options)
    logger.info("reconciliation %s: %s", reconciliation_id, status)


def enqueue_reconciliation(reconciliation_id: int, **options: Any) -> str:
    """Put one reconciliation job on the queue; returns the message id."""
    message = reconcile_record.send(int(reconciliation_id), **options)
    return str(message.message_id)
