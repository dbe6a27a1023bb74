"""Alarms: list, detail with history, acknowledgement."""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, Path, Query, Response

from service import schemas
from service.convert import Names, alarm_event_out, alarm_out, rig_by_name
from service.deps import CurrentKey, DbSession, OperatorKey
from service.exports import CSV_MEDIA_TYPE, alarms_csv
from service.routers.common import Limit, Offset, RigFilter, errors
from storage.repositories import AlarmRepository, AuditRepository

router = APIRouter(prefix="/api/v1/alarms", tags=["alarms"])

AlarmId = Annotated[int, Path(ge=1, le=2**31 - 1, description="Alarm id.", examples=[3])]


@router.get(
    "",
    response_model=schemas.AlarmList,
    summary="List alarms, newest first (those raised by one record: highest score first)",
    description="`raised_at` is the `taken_at` of the record that raised the alarm. "
    "`open=true` keeps alarms that are not cleared. `tooth` is null for a whole-record "
    "indicator. `format=csv` answers text/csv.",
    responses={200: {"content": {"text/csv": {}}}, **errors(401, 404, 422)},
)
def list_alarms(
    db: DbSession,
    _caller: CurrentKey,
    rig_id: RigFilter = None,
    state: Annotated[schemas.AlarmState | None, Query(description="Only this state.")] = None,
    open_only: Annotated[
        bool, Query(alias="open", description="Only alarms that are not cleared.")
    ] = False,
    limit: Limit = 100,
    offset: Offset = 0,
    format: Annotated[
        Literal["json", "csv"], Query(description="`csv`: one row per alarm (text/csv).")
    ] = "json",
) -> schemas.AlarmList | Response:
    rig_pk = None if rig_id is None else rig_by_name(db, rig_id).id
    rows = AlarmRepository(db).list(
        rig_id=rig_pk, state=state, open_only=open_only, limit=limit, offset=offset
    )
    names = Names(db)
    items = [alarm_out(a, names) for a in rows]
    if format == "csv":
        name = f"alarms-{rig_id}.csv" if rig_id else "alarms.csv"
        return Response(
            alarms_csv(items),
            media_type=CSV_MEDIA_TYPE,
            headers={"Content-Disposition": f'attachment; filename="{name}"'},
        )
    return schemas.AlarmList(items=items)


@router.get(
    "/{alarm_id}",
    response_model=schemas.AlarmDetail,
    summary="One alarm with its state history",
    responses=errors(401, 404, 422),
)
def get_alarm(alarm_id: AlarmId, db: DbSession, _caller: CurrentKey) -> schemas.AlarmDetail:
    alarms = AlarmRepository(db)
    alarm = alarms.get(alarm_id)
    return schemas.AlarmDetail(
        **alarm_out(alarm, Names(db)).model_dump(),
        history=[alarm_event_out(e) for e in alarms.history(alarm_id)],
    )


@router.post(
    "/{alarm_id}/ack",
    response_model=schemas.AlarmDetail,
    summary="Acknowledge an open alarm (operator)",
    description="Records who (the key's name), when and the comment in the alarm's history and "
    "the audit log. A cleared or already acknowledged alarm answers 409. An acknowledged "
    "warning that escalates to alarm needs a new acknowledgement.",
    responses=errors(401, 403, 404, 409, 422),
)
def acknowledge(
    alarm_id: AlarmId,
    db: DbSession,
    caller: OperatorKey,
    body: schemas.AckIn | None = None,
) -> schemas.AlarmDetail:
    comment = body.comment if body is not None else ""
    alarms = AlarmRepository(db)
    alarm = alarms.acknowledge(alarm_id, who=caller.who, comment=comment)
    AuditRepository(db).add(
        who=caller.who,
        action="alarm.ack",
        target=f"alarm:{alarm_id}",
        details={"comment": comment, "tooth": alarm.tooth, "indicator": alarm.indicator},
    )
    db.commit()
    return schemas.AlarmDetail(
        **alarm_out(alarm, Names(db)).model_dump(),
        history=[alarm_event_out(e) for e in alarms.history(alarm_id)],
    )
