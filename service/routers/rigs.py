"""Rigs, per-tooth trends and the rigs' alarm rules."""

from __future__ import annotations

import hashlib
from typing import Annotated

from fastapi import APIRouter, Path, Query, Request, Response
from sqlalchemy.orm import Session

from service import schemas
from service.convert import rig_by_name, rig_out, rule_out
from service.deps import CurrentKey, DbSession, OperatorKey, SettingsDep
from service.routers.common import RigName, errors
from storage.models import Rig

router = APIRouter(prefix="/api/v1/rigs", tags=["rigs"])

IndicatorName = Annotated[
    schemas.AlarmIndicatorName,
    Path(description="Indicator the rule watches.", examples=["mci_depth"]),
]


@router.get("", response_model=schemas.RigList, summary="List rigs", responses=errors(401))
def list_rigs(db: DbSession, _caller: CurrentKey) -> schemas.RigList:
    from storage.repositories import RigRepository

    return schemas.RigList(items=[rig_out(db, rig) for rig in RigRepository(db).list()])


@router.get(
    "/{rig_id}", response_model=schemas.RigOut, summary="One rig", responses=errors(401, 404)
)
def get_rig(rig_id: RigName, db: DbSession, _caller: CurrentKey) -> schemas.RigOut:
    return rig_out(db, rig_by_name(db, rig_id))


@router.get(
    "/{rig_id}/trends",
    response_model=schemas.TrendOut,
    summary="Per-tooth indicator over the rig's accepted records (records × teeth)",
    description="The current result version of every accepted record, in `taken_at` order. "
    "Without `tooth` every pinion tooth is returned; `values[i][j]` belongs to `records[i]` "
    "and `teeth[j]`. With several accelerometer channels, `channel` chooses one (default: the "
    "first by name).",
    responses={
        304: {"description": "Not modified (If-None-Match matched the ETag)"},
        **errors(401, 404, 422),
    },
)
def trends(
    rig_id: RigName,
    request: Request,
    db: DbSession,
    settings: SettingsDep,
    _caller: CurrentKey,
    indicator: Annotated[
        schemas.ToothIndicatorName, Query(description="Per-tooth indicator.")
    ] = "mci_depth",
    tooth: Annotated[
        int | None, Query(ge=1, le=10_000, description="One pinion tooth (1-based).")
    ] = None,
    channel: Annotated[
        str | None,
        Query(min_length=1, max_length=200, pattern=schemas.NAME_PATTERN, examples=["acc1"]),
    ] = None,
) -> Response:
    from service.queries import ResponseCache, trend_version

    rig = rig_by_name(db, rig_id)
    # Trends only change when indicator rows are added: the serialized answer is served again
    # while the rig's data fingerprint is unchanged (re-checked at most every
    # ``trend_cache_seconds``), and a client holding it gets 304.
    cache: ResponseCache = request.app.state.trend_cache
    cache_key = (rig.id, indicator, tooth, channel)
    fresh = cache.fresh(cache_key, settings.trend_cache_seconds)
    if fresh is not None:
        version, body = fresh
    else:
        version = trend_version(db, rig.id)
        cached = cache.get(cache_key, version)
        if cached is None:
            cached = _trend(db, rig, indicator, tooth, channel).model_dump_json().encode()
            cache.put(cache_key, version, cached)
        body = cached
    etag = _etag(rig.id, indicator, tooth, channel, version)
    if request.headers.get("if-none-match") == etag:
        return Response(status_code=304, headers={"ETag": etag})
    return Response(body, media_type="application/json", headers={"ETag": etag})


def _etag(*key: object) -> str:
    return '"' + hashlib.sha256(repr(key).encode()).hexdigest()[:32] + '"'


def _trend(
    db: Session, rig: Rig, indicator: str, tooth: int | None, channel: str | None
) -> schemas.TrendOut:
    from storage.repositories import TrendRepository

    points = TrendRepository(db).trend(rig.id, indicator, tooth, channel=channel)
    if channel is None and points:
        channel = min(p.channel for p in points)
        points = [p for p in points if p.channel == channel]
    if tooth is not None:
        teeth = [tooth]
    elif rig.pinion_teeth:
        teeth = list(range(1, rig.pinion_teeth + 1))
    else:
        teeth = sorted({p.tooth for p in points})
    column = {t: j for j, t in enumerate(teeth)}
    records: list[schemas.TrendPoint] = []
    values: list[list[float | None]] = []
    row_of: dict[int, int] = {}
    for point in points:
        row = row_of.get(point.record_id)
        if row is None:
            row = row_of[point.record_id] = len(records)
            records.append(schemas.TrendPoint(record_id=point.record_id, taken_at=point.taken_at))
            values.append([None] * len(teeth))
        j = column.get(point.tooth)
        if j is not None:
            values[row][j] = point.value
    return schemas.TrendOut(
        rig_id=rig.name,
        indicator=indicator,  # type: ignore[arg-type]
        channel=channel,
        teeth=teeth,
        records=records,
        values=values,
    )


@router.get(
    "/{rig_id}/alarm-rules",
    response_model=schemas.AlarmRules,
    summary="The rig's alarm rules",
    responses=errors(401, 404),
)
def get_rules(rig_id: RigName, db: DbSession, _caller: CurrentKey) -> schemas.AlarmRules:
    from storage.repositories import AlarmRuleRepository

    rig = rig_by_name(db, rig_id)
    rules = AlarmRuleRepository(db).list(rig.id)
    return schemas.AlarmRules(rig_id=rig.name, items=[rule_out(r) for r in rules])


@router.put(
    "/{rig_id}/alarm-rules/{indicator}",
    response_model=schemas.AlarmRuleOut,
    summary="Create or change one alarm rule (operator)",
    description="Levels are in baseline units. A new `baseline_records` restarts the rule's "
    "baselines; other changes apply from the next record on. The change is audited.",
    responses=errors(401, 403, 404, 422),
)
def put_rule(
    rig_id: RigName,
    indicator: IndicatorName,
    body: schemas.AlarmRuleIn,
    db: DbSession,
    caller: OperatorKey,
) -> schemas.AlarmRuleOut:
    from gearwatch.errors import InputError
    from storage.repositories import AlarmRuleRepository, AuditRepository

    if body.indicator != indicator:
        raise InputError(
            f"the body's indicator {body.indicator!r} differs from the path's {indicator!r}"
        )
    rig = rig_by_name(db, rig_id)
    rules = AlarmRuleRepository(db)
    settings = body.model_dump(exclude={"indicator"}, exclude_none=True)
    existing = rules.get_for(rig.id, indicator)
    if existing is None:
        rule = rules.create(rig.id, indicator, **settings)
    else:
        rule = rules.update(existing.id, **settings)
    AuditRepository(db).add(
        who=caller.who,
        action="alarm_rule.put",
        target=f"rig:{rig.name}/rule:{indicator}",
        details=settings,
    )
    db.commit()
    return rule_out(rule)


@router.delete(
    "/{rig_id}/alarm-rules/{indicator}",
    status_code=204,
    summary="Delete one alarm rule (operator)",
    responses=errors(401, 403, 404),
)
def delete_rule(
    rig_id: RigName, indicator: IndicatorName, db: DbSession, caller: OperatorKey
) -> Response:
    from gearwatch.errors import NotFound
    from storage.repositories import AlarmRuleRepository, AuditRepository

    rig = rig_by_name(db, rig_id)
    rules = AlarmRuleRepository(db)
    rule = rules.get_for(rig.id, indicator)
    if rule is None:
        raise NotFound(f"rig {rig.name!r} has no rule for {indicator!r}")
    rules.delete(rule.id)
    AuditRepository(db).add(
        who=caller.who, action="alarm_rule.delete", target=f"rig:{rig.name}/rule:{indicator}"
    )
    db.commit()
    return Response(status_code=204)
