"""Records: upload (multipart) into a campaign, list, details, result versions, re-process,
curves with tooth sectors and the baseline band."""

from __future__ import annotations

import re
import tempfile
from pathlib import Path
from typing import Annotated

import numpy as np
from fastapi import APIRouter, Query, Request, Response
from fastapi.concurrency import run_in_threadpool
from pydantic import ValidationError
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from gearwatch.floor.errors import BrokerUnavailable, DuplicateRecord, InputError, NotFound
from gearwatch.floor.results import AnalysisParameters
from gearwatch.floor.settings import Settings
from gearwatch.usecases.ingest_file import (
    JobResult,
    campaign_config,
    process_file,
    record_suffix,
    reprocess_record,
)
from gearwatch.usecases.job_queue import INTEGRITY_RETRIES, enqueue_record, is_broker_unavailable
from ingest.sources import file_sha256
from service import schemas
from service.convert import (
    Names,
    campaign_by_name,
    finite_list,
    record_out,
    result_out,
    rig_by_name,
)
from service.deps import Caller, CurrentKey, DbSession, OperatorKey, SettingsDep
from service.queries import mci_baseline_band, relative_to_median, tooth_sectors
from service.routers.common import (
    CampaignFilter,
    CampaignName,
    ChannelFilter,
    Limit,
    Offset,
    RecordId,
    RigFilter,
    errors,
)
from service.upload import (
    UPLOAD_REQUEST_BODY,
    ReceivedUpload,
    check_declared_length,
    receive_upload,
)
from storage.operator_queries import ANGLE_CURVES, curve_frame, in_pair_frame
from storage.raw_store import RawStore
from storage.repositories import (
    AuditRepository,
    RecordRepository,
    RigRepository,
    gear_pair,
    rig_gear_pair,
)

router = APIRouter(prefix="/api/v1", tags=["records"])

_UNSAFE = re.compile(r"[^A-Za-z0-9._+-]")


def _job_out(db: Session, job: object) -> schemas.JobOut:
    assert isinstance(job, JobResult)
    record = RecordRepository(db).get(job.record_id)
    return schemas.JobOut(
        record=record_out(record, Names(db)),
        outcome=job.outcome,
        result_id=job.result_id,
        alarm_changes=len(job.alarm_changes),
        sha256=job.sha256,
    )


@router.get(
    "/records",
    response_model=schemas.RecordList,
    summary="List records, oldest first",
    responses=errors(401, 404, 422),
)
def list_records(
    db: DbSession,
    _caller: CurrentKey,
    rig_id: RigFilter = None,
    campaign_id: CampaignFilter = None,
    status: schemas.RecordStatus | None = None,
    since: Annotated[
        schemas.UtcDatetime | None, Query(description="taken_at ≥ since (with time zone)")
    ] = None,
    until: Annotated[
        schemas.UtcDatetime | None, Query(description="taken_at < until (with time zone)")
    ] = None,
    limit: Limit = 100,
    offset: Offset = 0,
) -> schemas.RecordList:
    filters = {
        "rig_id": None if rig_id is None else rig_by_name(db, rig_id).id,
        "campaign_id": None if campaign_id is None else campaign_by_name(db, campaign_id).id,
        "status": status,
        "since": since,
        "until": until,
    }
    records = RecordRepository(db)
    names = Names(db)
    rows = records.list(**filters, limit=limit, offset=offset)  # type: ignore[arg-type]
    return schemas.RecordList(
        items=[record_out(r, names) for r in rows],
        total=records.count(**filters),  # type: ignore[arg-type]
        limit=limit,
        offset=offset,
    )


@router.post(
    "/campaigns/{campaign_id}/records",
    response_model=schemas.JobOut,
    status_code=201,
    summary="Upload a record file with its manifest entry (operator)",
    description="Multipart form: `file` (the record, in any format the readers know: .wav, "
    ".csv, .csv.gz, .npz, .h5, .tdms, .mat, …) and `entry`, the record's manifest entry as "
    'JSON (`{"taken_at": "2026-03-02T08:00:00Z", "label": "day 2"}`). The raw file is kept '
    "first, then analysed; a file that fails the quality checks is stored as `rejected` "
    "with its reason (still 201). The same file again changes nothing (200, `unchanged`). "
    "With `GEARWATCH_JOB_RUNNER=broker` the raw file is kept and its job queued for the "
    "Dramatiq workers (202, `queued`).",
    openapi_extra={"requestBody": UPLOAD_REQUEST_BODY},
    responses={
        200: {"model": schemas.JobOut, "description": "Already ingested"},
        202: {"model": schemas.JobOut, "description": "Queued for the workers"},
        **errors(401, 403, 404, 413, 422),
    },
)
async def upload_record(
    campaign_id: CampaignName,
    request: Request,
    response: Response,
    db: DbSession,
    settings: SettingsDep,
    caller: OperatorKey,
) -> schemas.JobOut:
    # The body is read here, after the key and role dependencies: see service.upload.
    check_declared_length(request, settings.max_upload_bytes)
    folder = settings.spool_dir()
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=folder, prefix="upload-") as spool:
        received = await receive_upload(request, Path(spool), settings.max_upload_bytes)
        return await run_in_threadpool(
            _ingest_upload, campaign_id, received, response, db, settings, caller
        )


def _ingest_upload(
    campaign_id: str,
    received: ReceivedUpload,
    response: Response,
    db: Session,
    settings: Settings,
    caller: Caller,
) -> schemas.JobOut:
    entry = received.fields.get("entry")
    if received.path is None or entry is None:
        missing = "file" if received.path is None else "entry"
        raise InputError(f"the upload has no {missing!r} part")
    if received.size == 0:
        raise InputError("the uploaded file is empty")
    try:
        record_entry = schemas.RecordEntryIn.model_validate_json(entry)
    except ValidationError as error:
        first = error.errors()[0]
        where = ".".join(str(p) for p in first.get("loc", ())) or "entry"
        raise InputError(f"entry: {where}: {first.get('msg', 'invalid')}") from None
    stored = campaign_by_name(db, campaign_id)
    file_name = record_entry.file or Path(received.filename).name or "record"
    spooled = received.path
    wanted = spooled.with_name(_UNSAFE.sub("_", Path(file_name).name)[-100:] or "record")
    if wanted != spooled:
        spooled = spooled.rename(wanted)
    if settings.job_runner == "broker":
        response.status_code = 202
        return _enqueue(db, stored.name, spooled, record_entry, file_name, settings, caller)
    config = campaign_config(stored)
    for attempt in range(INTEGRITY_RETRIES + 1):
        try:
            job = process_file(
                db,
                spooled,
                config,
                raw_store=RawStore(settings.raw_store),
                taken_at=record_entry.taken_at,
                label=record_entry.label,
                file_name=file_name,
            )
            AuditRepository(db).add(
                who=caller.who,
                action="record.upload",
                target=f"record:{job.record_id}",
                details={"campaign": stored.name, "file": file_name, "outcome": job.outcome},
            )
            db.commit()
            break
        except (IntegrityError, DuplicateRecord):
            # The same file uploaded at the same moment by another request won the insert
            # (PostgreSQL: the unique index; SQLite: the insert sees the other's commit): run
            # again, and find it stored, so every backend answers 200 `unchanged` as for a
            # later upload.
            db.rollback()
            if attempt == INTEGRITY_RETRIES:
                raise
    if job.outcome in ("unchanged", "reprocessed"):
        response.status_code = 200
    return _job_out(db, job)


def _enqueue(
    db: Session,
    campaign: str,
    spooled: Path,
    entry: schemas.RecordEntryIn,
    file_name: str,
    settings: Settings,
    caller: Caller,
) -> schemas.JobOut:
    """Keep the raw file (the store is shared with the workers), then queue its job."""
    sha256 = file_sha256(spooled)
    store = RawStore(settings.raw_store)
    suffix = record_suffix(spooled)
    already_kept = store.contains(sha256, suffix)
    kept = store.keep(spooled, sha256, suffix)
    try:
        message_id = enqueue_record(
            campaign,
            str(kept),
            taken_at=entry.taken_at.isoformat(),
            label=entry.label,
            file_name=file_name,
            database_url=settings.database_url,
            raw_store=str(settings.raw_store),
        )
    except Exception as error:  # dramatiq's ConnectionError and pika's errors: broker down
        if not is_broker_unavailable(error):
            raise
        if not already_kept:
            # No message will ever name this file: keep no orphan in the raw store.
            kept.unlink(missing_ok=True)
        raise BrokerUnavailable(
            "the job queue (message broker) is not available: nothing was kept, send the "
            "file again later"
        ) from None
    AuditRepository(db).add(
        who=caller.who,
        action="record.upload",
        target=f"sha256:{sha256}",
        details={"campaign": campaign, "file": file_name, "outcome": "queued"},
    )
    db.commit()
    return schemas.JobOut(outcome="queued", sha256=sha256, message_id=message_id)


@router.get(
    "/records/{record_id}",
    response_model=schemas.RecordDetail,
    summary="One record with its current result",
    responses=errors(401, 404, 422),
)
def get_record(record_id: RecordId, db: DbSession, _caller: CurrentKey) -> schemas.RecordDetail:
    records = RecordRepository(db)
    record = records.get(record_id)
    current = records.current_result(record.id)
    base = record_out(record, Names(db))
    return schemas.RecordDetail(
        **base.model_dump(),
        quality=record.quality or {},
        current_result=None if current is None else result_out(db, current, details=True),
        tooth_frame=next(iter(((record.quality or {}).get("tooth_frames") or {}).values()), None),
    )


@router.get(
    "/records/{record_id}/results",
    response_model=schemas.ResultList,
    summary="Every result version of a record, oldest first",
    responses=errors(401, 404, 422),
)
def list_results(record_id: RecordId, db: DbSession, _caller: CurrentKey) -> schemas.ResultList:
    records = RecordRepository(db)
    records.get(record_id)
    return schemas.ResultList(
        items=[result_out(db, r, details=True) for r in records.results(record_id)]
    )


@router.post(
    "/records/{record_id}/reprocess",
    response_model=schemas.JobOut,
    summary="Analyse a record again with new parameters (operator)",
    description="Reads the kept raw file again. New parameters add a result version (the old "
    "ones are kept, the new one becomes current); the same parameters change nothing. A "
    "re-analysis that fails answers outcome `rejected` with the reason and keeps the record "
    "accepted with its current result.",
    responses=errors(401, 403, 404, 422),
)
def reprocess(
    record_id: RecordId,
    body: schemas.ReprocessIn,
    db: DbSession,
    caller: OperatorKey,
) -> schemas.JobOut:
    RecordRepository(db).get(record_id)
    params = AnalysisParameters.from_dict(body.parameters.model_dump())
    job = reprocess_record(db, record_id, params)
    AuditRepository(db).add(
        who=caller.who,
        action="record.reprocess",
        target=f"record:{record_id}",
        details={"parameters": params.to_dict(), "outcome": job.outcome},
    )
    db.commit()
    return _job_out(db, job)


@router.get(
    "/records/{record_id}/curves",
    response_model=schemas.CurvesOut,
    summary="Curves of a record (one channel), with tooth sectors and the MCI baseline band",
    description="Curves are over one pinion revolution, sample `i` at `360·i/n` degrees in the "
    "gear pair's tooth frame (tooth 1 at `tooth1_pitch_angle_deg`): with a tachometer, after "
    "its reference edge; without one, the curves of the pinion average, the difference signal "
    "and the MCI are turned from the campaign's tooth frame into it (`turned_deg`). A record "
    "whose teeth are not numbered (`tooth_frame` `refused` or `none`: no tach and no tooth "
    "frame found) has its curves as stored and no tooth sectors. `band=true` adds the MCI "
    "baseline band: pointwise median ± 3·1.4826·MAD of the `mci` curve over the rig's first "
    "accepted records whose teeth are numbered (as many as the rig's `mci_depth` rule learns "
    "its baseline from, default 10), each in the pair's tooth frame.",
    responses=errors(401, 404, 422),
)
def curves(
    record_id: RecordId,
    db: DbSession,
    _caller: CurrentKey,
    names: Annotated[
        list[schemas.CurveName] | None, Query(description="Curves to return (default all).")
    ] = None,
    channel: ChannelFilter = None,
    result_id: Annotated[
        int | None, Query(ge=1, le=2**31 - 1, description="A result version (default current).")
    ] = None,
    band: Annotated[bool, Query(description="Add the MCI baseline band.")] = False,
    relative: Annotated[
        bool,
        Query(
            description="MCI curves (and the band's curves) minus their own median over the "
            "revolution: the reference of the per-tooth MCI depth. Day-to-day level changes "
            "then no longer move the whole curve away from the band."
        ),
    ] = False,
) -> schemas.CurvesOut:
    records = RecordRepository(db)
    record = records.get(record_id)
    if result_id is None:
        result = records.current_result(record.id)
        if result is None:
            raise NotFound(f"record {record_id} has no result ({record.status})")
    else:
        result = records.get_result(result_id)
        if result.record_id != record.id:
            raise NotFound(f"result version {result_id} is not a result of record {record_id}")
    channel_results = records.channel_results(result.id)
    if not channel_results:
        raise NotFound(f"result version {result.id} has no channel")
    if channel is None:
        channel = channel_results[0].channel.name
    elif channel not in {c.channel.name for c in channel_results}:
        raise NotFound(f"record {record_id} has no channel {channel!r}")
    chosen = next(c for c in channel_results if c.channel.name == channel)
    rigs = RigRepository(db)
    rig = rigs.get(record.rig_id)
    # the gear pair this record's campaign ran, which need not be the rig's current one
    pair = gear_pair(record.campaign.manifest) or rig_gear_pair(rig)
    frame = curve_frame(result.quality, chosen.baseline_stats, channel, pair.tooth1_pitch_angle_deg)
    own_tooth1 = frame.tooth1_pitch_angle_deg  # None: the record's teeth are not numbered
    turned = 0.0 if own_tooth1 is None else pair.tooth1_pitch_angle_deg - own_tooth1

    def shown(name: str, values: np.ndarray) -> list[float | None]:
        if own_tooth1 is not None and name in ANGLE_CURVES:
            values = in_pair_frame(values, own_tooth1, pair.tooth1_pitch_angle_deg)
        return finite_list(relative_to_median(values) if relative and name in ("mci", "mci_raw")
                           else values)

    data = {c.name: shown(c.name, c.values) for c in records.curves(result.id, channel=channel, names=names)}
    return schemas.CurvesOut(
        record_id=record.id,
        result_id=result.id,
        channel=channel,
        samples_per_rev=chosen.samples_per_rev,
        pinion_teeth=pair.pinion_teeth,
        tooth1_pitch_angle_deg=pair.tooth1_pitch_angle_deg,
        tooth_frame=frame.kind,
        turned_deg=round(turned % 360.0, 6),
        curves=data,
        sectors=[] if own_tooth1 is None else tooth_sectors(pair.pinion_teeth, pair.tooth1_pitch_angle_deg),
        baseline_band=mci_baseline_band(
            db, rig.id, channel, relative=relative, campaign_ids=rigs.pair_campaign_ids(rig, pair),
            pair_tooth1_deg=pair.tooth1_pitch_angle_deg,
        ) if band else None,
    )
