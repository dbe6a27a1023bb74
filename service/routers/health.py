"""``/health`` (anonymous), ``/metrics`` (Prometheus) and ``/api/v1/me``."""

from __future__ import annotations

import sqlalchemy as sa
from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse, PlainTextResponse

from gearwatch.floor.version import package_version
from service import schemas
from service.deps import CurrentKey, DbSession
from service.metrics import gauge_lines
from service.routers.common import errors
from storage.repositories import AlarmRepository, RecordRepository

router = APIRouter()


@router.get(
    "/health",
    tags=["health"],
    response_model=schemas.Health,
    summary="Liveness and database reachability (no key needed)",
    responses={503: {"model": schemas.Health, "description": "The database is unreachable"}},
)
def health(request: Request) -> JSONResponse:
    database = "ok"
    try:
        with request.app.state.engine.connect() as connection:
            connection.execute(sa.text("SELECT 1"))
    except Exception:  # any failure means unreachable; the body says so
        database = "unreachable"
    body = schemas.Health(
        status="ok" if database == "ok" else "degraded",
        database=database,  # type: ignore[arg-type]
        version=package_version(),
    )
    return JSONResponse(body.model_dump(), status_code=200 if database == "ok" else 503)


@router.get(
    "/metrics",
    tags=["health"],
    response_class=PlainTextResponse,
    summary="Prometheus metrics (text format 0.0.4)",
    responses={
        200: {
            "content": {"text/plain": {"example": 'gearwatch_records{status="accepted"} 12\n'}},
            "description": "Request counters and histograms, record and alarm gauges.",
        },
        **errors(401),
    },
)
def metrics(request: Request, db: DbSession, _caller: CurrentKey) -> PlainTextResponse:
    text = request.app.state.metrics.render()
    counts = RecordRepository(db).status_counts()
    text += gauge_lines(
        "gearwatch_records", "Stored records by status.",
        [({"status": status}, float(n)) for status, n in sorted(counts.items())],
    )  # fmt: skip
    alarms = AlarmRepository(db)
    text += gauge_lines(
        "gearwatch_open_alarms",
        "Alarms that are not cleared.",
        [({}, float(alarms.count(open_only=True)))],
    )
    return PlainTextResponse(text, media_type="text/plain; version=0.0.4; charset=utf-8")


@router.get(
    "/api/v1/me",
    tags=["admin"],
    response_model=schemas.Me,
    summary="The calling key's name and role",
    responses=errors(401),
)
def me(caller: CurrentKey) -> schemas.Me:
    return schemas.Me(prefix=caller.prefix, name=caller.name, role=caller.role)  # type: ignore[arg-type]
