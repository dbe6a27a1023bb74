"""Physics reconciliations of stored records (issue 6 over REST): request, list, result, HTML
report and updated simulator configuration."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any

from fastapi import APIRouter, BackgroundTasks, Path, Request
from fastapi.responses import HTMLResponse, Response
from sqlalchemy.orm import Session

from gearwatch.floor.errors import Conflict
from gearwatch.floor.settings import Settings
from gearwatch.usecases.job_queue import enqueue_reconciliation
from gearwatch.usecases.reconcile import ReconcileRequest
from gearwatch.usecases.reconcile import create_reconciliation as create
from service import schemas
from service.deps import CurrentKey, DbSession, OperatorKey, SettingsDep
from service.inline_jobs import release, reserve, run_reserved
from service.routers.common import MAX_ID, RecordId, errors
from storage.raw_store import RawStore
from storage.repositories import AuditRepository, ReconciliationRepository, RecordRepository

if TYPE_CHECKING:
    from storage.models import Reconciliation

router = APIRouter(prefix="/api/v1", tags=["reconciliations"])

ReconciliationId = Annotated[
    int, Path(ge=1, le=MAX_ID, description="Reconciliation id.", examples=[7])
]
PREFIX = "/api/v1"


def _out(row: Reconciliation, *, details: bool = False) -> schemas.ReconciliationOut:
    url = f"{PREFIX}/reconciliations/{row.id}"
    base: dict[str, Any] = {
        "id": row.id,
        "record_id": row.record_id,
        "reference_record_id": row.reference_record_id,
        "status": row.status,
        "options": row.options or {},
        "provenance": schemas.ReconciliationProvenance(
            raw_sha256=row.record.sha256,
            reference_raw_sha256=None if row.reference_record is None
            else row.reference_record.sha256,
            code_version=row.code_version,
        ),
        "outcome": (row.result or {}).get("status") if row.status == "done" else None,
        "progress": _progress(row),
        "error": (row.error or None) if row.status == "failed" else None,
        "created_at": row.created_at,
        "started_at": row.started_at,
        "finished_at": row.finished_at,
        "links": schemas.ReconciliationLinks(
            self=url,
            record=f"{PREFIX}/records/{row.record_id}",
            report=f"{url}/report",
            model=f"{url}/model",
        ),
    }
    if not details:
        return schemas.ReconciliationOut(**base)
    return schemas.ReconciliationDetail(
        **base,
        result=row.result if row.status == "done" else None,
        model_toml=row.model_toml,
    )


def _progress(row: Reconciliation) -> schemas.ReconciliationProgress | None:
    if row.status == "done":
        return schemas.ReconciliationProgress(stage="done", fraction=1.0)
    if row.status == "queued":
        return schemas.ReconciliationProgress(stage="queued", fraction=0.0)
    stored = (row.result or {}).get("progress") if row.status == "running" else None
    if not isinstance(stored, dict):
        return None
    return schemas.ReconciliationProgress(stage=str(stored.get("stage", "")),
                                          fraction=float(stored.get("fraction", 0.0)))


@router.post(
    "/records/{record_id}/reconciliations",
    response_model=schemas.ReconciliationOut,
    status_code=202,
    summary="Reconcile the simulator with a stored record (operator)",
    description="Locates the mismatch between the simulator configuration (`model_toml`, "
    "default: the rig's default model) and the record, names and fits the missing physics "
    "from the mechanism catalogue, and reports the fit before and after (issue 6, "
    "docs/reconciliation.md). Checked up front (404 unknown record or reference; 422 a "
    "reference of another rig or the record itself, a model that does not parse or has other "
    "tooth counts than the rig, unknown mechanisms, a rig without tooth counts, a campaign "
    "without a pinion tachometer, an unknown channel), then queued: on the Dramatiq workers "
    "with `GEARWATCH_JOB_RUNNER=broker`, else in the service after the response. Poll "
    "`links.self`.",
    responses=errors(401, 403, 404, 422),
)
def create_reconciliation(
    record_id: RecordId,
    body: schemas.ReconciliationIn,
    background: BackgroundTasks,
    http_request: Request,
    db: DbSession,
    settings: SettingsDep,
    caller: OperatorKey,
) -> schemas.ReconciliationOut:
    request = ReconcileRequest(
        model_toml=body.model_toml,
        reference_record_id=body.reference_record_id,
        channel=body.channel,
        mechanisms=None if body.mechanisms is None else tuple(body.mechanisms),
        samples_per_mesh=body.samples_per_mesh,
        max_frequency_hz=body.max_frequency_hz,
        max_findings=body.max_findings,
        forward_oversampling=body.forward_oversampling,
    )
    inline = settings.job_runner != "broker"
    if inline:
        # Bounded in this process: one runs at a time, a few may wait; more is 503.

        reserve()
    try:
        row = create(db, record_id, request, raw_store=RawStore(settings.raw_store))
    except BaseException:
        if inline:
            release()
        raise
    AuditRepository(db).add(
        who=caller.who,
        action="reconciliation.create",
        target=f"record:{record_id}",
        details={"reconciliation": row.id, "options": row.options,
                 "reference_record_id": row.reference_record_id,
                 "model": "given" if row.model_toml is not None else "rig default"},
    )
    db.commit()
    out = _out(row)
    _enqueue(row.id, settings, background, http_request)
    return out


def _enqueue(
    reconciliation_id: int, settings: Settings, background: BackgroundTasks, request: Request
) -> None:
    """On the workers' queue with ``job_runner=broker``; else in this process once the
    response is sent (a reconciliation takes minutes: never inside the request)."""
    if settings.job_runner == "broker":
        enqueue_reconciliation(
            reconciliation_id,
            database_url=settings.database_url,
            raw_store=str(settings.raw_store),
        )
        return

    background.add_task(
        run_reserved,
        request.app.state.session_factory,
        RawStore(settings.raw_store),
        reconciliation_id,
    )


@router.get(
    "/records/{record_id}/reconciliations",
    response_model=schemas.ReconciliationList,
    summary="Reconciliations of a record, newest first",
    responses=errors(401, 404, 422),
)
def list_reconciliations(
    record_id: RecordId, db: DbSession, _caller: CurrentKey
) -> schemas.ReconciliationList:
    RecordRepository(db).get(record_id)
    rows = ReconciliationRepository(db).list_for_record(record_id)
    return schemas.ReconciliationList(items=[_out(r) for r in rows])


@router.get(
    "/reconciliations/{reconciliation_id}",
    response_model=schemas.ReconciliationDetail,
    summary="One reconciliation: status, options, provenance, result JSON or error",
    responses=errors(401, 404, 422),
)
def get_reconciliation(
    reconciliation_id: ReconciliationId, db: DbSession, _caller: CurrentKey
) -> schemas.ReconciliationOut:
    return _out(ReconciliationRepository(db).get(reconciliation_id), details=True)


def _finished(db: Session, reconciliation_id: int) -> Reconciliation:
    row = ReconciliationRepository(db).get(reconciliation_id)
    if row.status != "done":
        reason = f": {row.error}" if row.status == "failed" and row.error else ""
        raise Conflict(f"reconciliation {reconciliation_id} is {row.status}{reason}")
    return row


@router.get(
    "/reconciliations/{reconciliation_id}/report",
    response_class=HTMLResponse,
    summary="The HTML report (order spectrum, angle residual and MCI before and after)",
    responses={200: {"content": {"text/html": {}}}, **errors(401, 404, 409, 422)},
)
def get_report(
    reconciliation_id: ReconciliationId, db: DbSession, _caller: CurrentKey
) -> HTMLResponse:
    row = _finished(db, reconciliation_id)
    return HTMLResponse(row.report_html or "")


@router.get(
    "/reconciliations/{reconciliation_id}/model",
    response_class=Response,
    summary="The updated simulator configuration (TOML): the calibrated base with the "
    "accepted findings added",
    responses={200: {"content": {"application/toml": {}}}, **errors(401, 404, 409, 422)},
)
def get_model(reconciliation_id: ReconciliationId, db: DbSession, _caller: CurrentKey) -> Response:
    row = _finished(db, reconciliation_id)
    return Response(
        row.updated_model_toml or "",
        media_type="application/toml",
        headers={
            "Content-Disposition": f'attachment; filename="reconciliation-{reconciliation_id}.toml"'
        },
    )
