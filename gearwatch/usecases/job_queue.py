"""The per-record job and the reconciliation job, run by Dramatiq workers fed through RabbitMQ,
and the functions that queue them.

The actors themselves live in the worker door (:mod:`gearwatch.worker`); this module sends their
messages by actor name (:func:`enqueue_record`, :func:`enqueue_reconciliation`) so that the
service queues jobs without importing the worker, and builds its broker only on first use (no
connection at import). Start workers with the broker, database and raw store of the service::

    GEARWATCH_BROKER_URL=amqp://guest:guest@127.0.0.1:5672/ \\
    GEARWATCH_DATABASE_URL=postgresql+psycopg://... GEARWATCH_RAW_STORE=/srv/raw \\
    dramatiq gearwatch.worker --processes 2 --threads 1

Exactly-once results rest on three facts: RabbitMQ
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

logger = logging.getLogger(__name__)

DEFAULT_QUEUE_NAME = "gearwatch-records"
ACTOR_NAME = "process_record"
RECONCILE_ACTOR_NAME = "reconcile_record"
RECONCILE_TIME_LIMIT_MS = 60 * 60 * 1000
"""A reconciliation runs minutes (the simulator is in the loop); Dramatiq's default limit is 10."""
INTEGRITY_RETRIES = 3


def queue_name() -> str:
    """The queue both actors listen on: ``GEARWATCH_QUEUE``, else ``gearwatch-records``."""
    return os.environ.get("GEARWATCH_QUEUE", DEFAULT_QUEUE_NAME)


_broker: dramatiq.Broker | None = None
_broker_lock = threading.Lock()


def broker() -> dramatiq.Broker:
    """The process's RabbitMQ broker (``GEARWATCH_BROKER_URL``), built on first use and made
    Dramatiq's global broker."""
    global _broker
    with _broker_lock:
        if _broker is None:
            from dramatiq.brokers.rabbitmq import RabbitmqBroker

            from gearwatch.floor.settings import Settings

            _broker = RabbitmqBroker(url=Settings().broker_url)
            dramatiq.set_broker(_broker)
        return _broker


def _send(actor_name: str, args: tuple[Any, ...], kwargs: dict[str, Any]) -> str:
    """What ``actor.send`` does, by the actor's name; returns the message id."""
    queue = queue_name()
    target = broker()
    target.declare_queue(queue)
    message = target.enqueue(dramatiq.Message(
        queue_name=queue, actor_name=actor_name, args=args, kwargs=kwargs, options={},
    ))
    return str(message.message_id)


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

    from gearwatch.floor.errors import DuplicateRecord
    from gearwatch.floor.results import AnalysisParameters
    from gearwatch.floor.settings import Settings
    from gearwatch.usecases.ingest_file import campaign_config, process_file
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
                    from gearwatch.floor.errors import NotFound

                    raise NotFound(f"campaign {campaign!r} is not in the database")
                result = process_file(
                    session, path, campaign_config(stored), raw_store=store,
                    params=analysis_params, taken_at=taken_at, label=label, file_name=file_name,
                )
            return {"record_id": result.record_id, "outcome": result.outcome,
                    "status": result.status, "reason": result.reason}
        except (sqlalchemy.exc.IntegrityError, DuplicateRecord):
            # Another worker stored the same content while this one analysed it: run again
            # and find it stored (outcome ``unchanged``).
            if attempt == INTEGRITY_RETRIES:
                raise
            logger.info("integrity conflict on %s (another worker?): retrying", path)
    raise AssertionError("unreachable")


def is_broker_unavailable(error: BaseException) -> bool:
    """True for the errors a send raises when RabbitMQ cannot be reached (after dramatiq's own
    retries): the caller answers "try again later" instead of failing."""
    import pika.exceptions
    from dramatiq.errors import ConnectionError as DramatiqConnectionError

    return isinstance(
        error, DramatiqConnectionError | pika.exceptions.AMQPError | ConnectionError | OSError
    )


def enqueue_record(campaign: str, path: str, **options: Any) -> str:
    """Put one per-record job on the queue; returns the message id."""
    return _send(ACTOR_NAME, (campaign, str(path)), options)


def run_reconciliation_job(
    reconciliation_id: int, *, database_url: str | None = None, raw_store: str | None = None
) -> str:
    """The job a ``reconcile_record`` message asks for; returns the final status."""
    from gearwatch.floor.settings import Settings
    from gearwatch.usecases.reconcile import run_reconciliation
    from storage.raw_store import RawStore

    settings = Settings()
    factory = _session_factory(database_url or settings.database_url)
    return run_reconciliation(factory, RawStore(raw_store or settings.raw_store), reconciliation_id)


def enqueue_reconciliation(reconciliation_id: int, **options: Any) -> str:
    """Put one reconciliation job on the queue; returns the message id."""
    return _send(RECONCILE_ACTOR_NAME, (int(reconciliation_id),), options)
