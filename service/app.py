"""The FastAPI application factory."""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any

from fastapi import FastAPI
from fastapi.staticfiles import StaticFiles
from sqlalchemy.engine import make_url

from gearwatch.floor.settings import Settings, get_settings
from gearwatch.floor.version import package_version
from service.errors import install_error_handlers
from service.metrics import MetricsMiddleware, RequestMetrics
from service.queries import ResponseCache
from service.schemas import ErrorBody
from service.security import SecurityHeadersMiddleware
from storage.db import create_db_engine, migrate, session_factory

STATIC_DIR = Path(__file__).resolve().parent / "static"

DESCRIPTION = """\
Per-tooth condition monitoring of gearbox test rigs: records, their per-tooth moving cepstrum
integral (MCI) and classic gear metrics, trends and alarms.

**Authentication**: every endpoint except `GET /health` needs an API key sent as
`Authorization: Bearer <key>` (create one with `gearwatch keys create --role viewer|operator|admin`).
Viewers read; operators also upload, re-process, acknowledge alarms and change alarm rules;
admins also manage keys and read the audit log.

**Errors**: every 4xx/5xx body is `{"error": {"code": ..., "message": ..., "details": ...}}`.
"""

OPENAPI_TAGS = [
    {"name": "health", "description": "Liveness and Prometheus metrics."},
    {"name": "rigs", "description": "Test rigs and their per-tooth trends."},
    {"name": "campaigns", "description": "Campaigns (a manifest: rig, channels, tachometer)."},
    {"name": "records", "description": "Record files: upload, re-process, results, curves."},
    {
        "name": "reconciliations",
        "description": "Physics reconciliation of a stored record: simulator vs recording, the "
        "missing physics named and fitted (issue 6).",
    },
    {"name": "alarms", "description": "Alarms, their history, acknowledgement and rules."},
    {"name": "notifications", "description": "Alarm webhooks, the notification outbox and "
     "every delivery attempt."},
    {"name": "admin", "description": "API keys and the audit log (admin role)."},
]


def create_app(settings: Settings | None = None) -> FastAPI:
    """Build the application: database, routers, error mapping, metrics, dashboard.

    The database is opened (and migrated when ``settings.auto_migrate``) at start-up,
    so creating the app is cheap and has no side effects.
    """
    from service import (
        routers,  # here: service.routers.dashboard imports STATIC_DIR from this module
    )

    settings = settings or get_settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        # More pooled connections than request threads (anyio's default limiter: 40), so a
        # request never waits on a connection held by another one queued behind it.
        engine = create_db_engine(settings.database_url, **_pool_options(settings.database_url))
        if settings.auto_migrate:
            migrate(engine)
        factory = session_factory(engine)
        app.state.engine = engine
        app.state.session_factory = factory
        if settings.job_runner == "inline":
            from service.inline_jobs import resume_interrupted
            from storage.raw_store import RawStore

            resume_interrupted(factory, RawStore(settings.raw_store))
        try:
            yield
        finally:
            engine.dispose()

    app = FastAPI(
        title="gearwatch",
        version=package_version(),
        description=DESCRIPTION,
        openapi_tags=OPENAPI_TAGS,
        lifespan=lifespan,
        openapi_url="/openapi.json" if settings.api_docs else None,
        responses={
            401: {"description": "Missing or unknown API key", "model": _error_model()},
            422: {"description": "Invalid request", "model": _error_model()},
        },
    )
    app.state.settings = settings
    app.state.metrics = RequestMetrics()
    app.state.trend_cache = ResponseCache()
    install_error_handlers(app)
    app.add_middleware(MetricsMiddleware, metrics=app.state.metrics)
    app.add_middleware(SecurityHeadersMiddleware)
    for router in routers.ALL:
        app.include_router(router)
    app.mount("/static", StaticFiles(directory=STATIC_DIR), name="static")
    return app


def _pool_options(url: str) -> dict[str, Any]:
    parsed = make_url(url)
    if parsed.get_backend_name() == "sqlite" and parsed.database in (None, "", ":memory:"):
        return {}  # one in-memory database per connection: no pool to size
    return {"pool_size": 10, "max_overflow": 40}


def _error_model() -> type:
    return ErrorBody
