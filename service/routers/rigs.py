"""Rigs, per-tooth trends and the rigs' alarm rules."""

from __future__ import annotations

import dataclasses
import gzip
import hashlib
from dataclasses import dataclass
from typing import Annotated, Literal

from fastapi import APIRouter, Path, Query, Request, Response
from sqlalchemy.orm import Session
from starlette.concurrency import run_in_threadpool

from gearwatch.floor.errors import InputError, NotFound
from gearwatch.floor.results import STORED_TOOTH_INDICATORS
from gearwatch.floor.settings import Settings
from gearwatch.usecases.alarm_levels import rule_levels
from service import schemas
from service.convert import rig_by_name, rig_out, rule_out
from service.deps import CurrentKey, DbSession, OperatorKey
from service.exports import CSV_MEDIA_TYPE, check_indicator, trend_answer, trend_csv_from_json
from service.queries import ResponseCache, trend_version
from service.routers.common import CampaignFilter, ChannelFilter, RigName, errors
from storage.models import Rig
from storage.operator_queries import OperatorQueries
from storage.repositories import (
    AlarmRuleRepository,
    AuditRepository,
    RigRepository,
    rig_gear_pair,
)

router = APIRouter(prefix="/api/v1/rigs", tags=["rigs"])

IndicatorName = Annotated[
    schemas.AlarmIndicatorName,
    Path(description="Indicator the rule watches.", examples=["mci_depth"]),
]


@router.get("", response_model=schemas.RigList, summary="List rigs", responses=errors(401))
def list_rigs(db: DbSession, _caller: CurrentKey) -> schemas.RigList:
    return schemas.RigList(items=[rig_out(db, rig) for rig in RigRepository(db).list()])


@router.get(
    "/{rig_id}", response_model=schemas.RigOut, summary="One rig", responses=errors(401, 404)
)
def get_rig(rig_id: RigName, db: DbSession, _caller: CurrentKey) -> schemas.RigOut:
    return rig_out(db, rig_by_name(db, rig_id))


@router.get(
    "/{rig_id}/trends",
    response_model=schemas.TrendOut,
    summary="Any indicator over the rig's accepted records (records × teeth)",
    description="The current result version of every accepted record, in `taken_at` order. "
    "Without `tooth` every pinion tooth is returned; `values[i][j]` belongs to `records[i]` "
    "and `teeth[j]`. With several accelerometer channels, `channel` chooses one (default: the "
    "first by name). `campaign` restricts the trend to one campaign of the rig, numbered by "
    "the gear pair it ran (default: every campaign of the rig's current pair). Answers carry an `ETag` (`If-None-Match` gives 304 while the rig's data "
    "is unchanged) and are gzip-compressed for clients that send `Accept-Encoding: gzip`.",
    responses={
        200: {"content": {"text/csv": {}}},
        304: {"description": "Not modified (If-None-Match matched the ETag)"},
        **errors(401, 404, 422),
    },
)
async def trends(
    rig_id: RigName,
    request: Request,
    db: DbSession,
    _caller: CurrentKey,
    indicator: Annotated[
        str,
        Query(
            min_length=1,
            max_length=64,
            pattern=r"^[a-z0-9_]+$",
            description="Any stored indicator: per tooth (mci_depth, diff_energy, "
            "diff_kurtosis …) or whole record (rms, kurtosis, fm4, na4, raw_kurtosis …).",
        ),
    ] = "mci_depth",
    tooth: Annotated[
        int | None, Query(ge=1, le=10_000, description="One pinion tooth (1-based).")
    ] = None,
    channel: ChannelFilter = None,
    campaign: CampaignFilter = None,
    format: Annotated[
        Literal["json", "csv"],
        Query(description="`csv`: one row per record (id, time, label), one column per tooth."),
    ] = "json",
) -> Response:
    # Trends only change when indicator rows are added. The serialized answer (plain and
    # gzip) is kept per (rig, indicator, tooth, channel) and served straight from memory while
    # the rig's data version, checked at most every ``trend_cache_seconds``, is unchanged: a
    # dashboard's poll then costs no database query, no thread and no serialization here.
    # (Settings read directly: a synchronous dependency would cost a thread hop.)

    check_indicator(indicator)
    settings: Settings = request.app.state.settings
    cache: ResponseCache[CachedTrend] = request.app.state.trend_cache
    key = (rig_id, indicator, tooth, channel, campaign)
    version = cache.group_version(rig_id, settings.trend_cache_seconds)
    answer = cache.get(key, version) if version is not None else None
    if answer is None:
        answer = await run_in_threadpool(_load_trend, db, cache, key)
    if format == "csv":
        return Response(
            trend_csv_from_json(answer.body),
            media_type=CSV_MEDIA_TYPE,
            headers={"Content-Disposition": f'attachment; filename="{rig_id}-{indicator}.csv"'},
        )
    gzipped = _accepts_gzip(request.headers.get("accept-encoding", ""))
    etag = answer.etag_gzip if gzipped else answer.etag
    headers = {"ETag": etag, "Vary": "Accept-Encoding"}
    if _matches(request.headers.get("if-none-match"), answer):
        return Response(status_code=304, headers=headers)
    if gzipped:
        headers["Content-Encoding"] = "gzip"
        return Response(answer.body_gzip, media_type="application/json", headers=headers)
    return Response(answer.body, media_type="application/json", headers=headers)


@dataclass(frozen=True)
class CachedTrend:
    """One trend answer as sent: JSON bytes, their gzip, and the ETag of each."""

    etag: str
    etag_gzip: str
    body: bytes
    body_gzip: bytes


GZIP_LEVEL = 1
"""Compressed once per data version: level 1 is ten times faster than 6 on a 165 KB trend
(2 vs 19 ms) for a 7 % larger answer (71 vs 67 KB, from 165 KB)."""


def _load_trend(
    db: Session,
    cache: ResponseCache[CachedTrend],
    key: tuple[str, str, int | None, str | None, str | None],
) -> CachedTrend:
    """Check the rig's data version in the database; build the answer if it is not cached."""
    rig_name, indicator, tooth, channel, campaign = key
    rig = rig_by_name(db, rig_name)
    # The rig's gear pair is part of the version: its tooth count sets the columns of the
    # answer, and a new pair changes which campaigns the trend covers.
    version: tuple[object, ...] = (rig.id, *rig_gear_pair(rig), *trend_version(db, rig.id))
    if indicator not in STORED_TOOTH_INDICATORS:  # whole-record rows (rigs without teeth have no others)

        version += OperatorQueries(db).metric_version(rig.id)
    cache.confirm(rig_name, version)
    answer = cache.get(key, version)
    if answer is not None:
        return answer
    with cache.build_lock(key):  # concurrent misses of one key: built once
        answer = cache.get(key, version)
        if answer is None:
            body = trend_json(db, rig, indicator, tooth, channel, campaign)
            etag = _etag(key, version)
            answer = CachedTrend(
                etag=etag,
                etag_gzip=etag[:-1] + '-gzip"',  # another representation, another ETag
                body=body,
                body_gzip=gzip.compress(body, compresslevel=GZIP_LEVEL, mtime=0),
            )
            cache.put(key, version, answer)
    return answer


def _accepts_gzip(accept_encoding: str) -> bool:
    """Whether an ``Accept-Encoding`` value allows gzip (``gzip`` or ``*`` with q > 0)."""
    for item in accept_encoding.lower().split(","):
        coding, _, parameters = item.partition(";")
        if coding.strip() in ("gzip", "*"):
            quality = parameters.strip().removeprefix("q=")
            try:
                return not parameters.strip() or float(quality) > 0
            except ValueError:
                return False
    return False


def _matches(if_none_match: str | None, answer: CachedTrend) -> bool:
    """Whether ``If-None-Match`` names this answer (either encoding; weak tags compare too)."""
    if not if_none_match:
        return False
    tags = {tag.strip().removeprefix("W/") for tag in if_none_match.split(",")}
    return "*" in tags or answer.etag in tags or answer.etag_gzip in tags


def _etag(*key: object) -> str:
    return '"' + hashlib.sha256(repr(key).encode()).hexdigest()[:32] + '"'


def trend_json(
    db: Session, rig: Rig, indicator: str, tooth: int | None, channel: str | None,
    campaign: str | None = None,
) -> bytes:
    """The trend answer's JSON: one query into a records × teeth matrix, serialized without
    re-validation (the values come from the database; NaN and missing cells become null)."""
    return trend_answer(db, rig, indicator, tooth, channel, campaign).model_dump_json().encode()


@router.get(
    "/{rig_id}/alarm-rules",
    response_model=schemas.AlarmRules,
    summary="The rig's alarm rules",
    responses=errors(401, 404),
)
def get_rules(rig_id: RigName, db: DbSession, _caller: CurrentKey) -> schemas.AlarmRules:
    rig = rig_by_name(db, rig_id)
    rules = AlarmRuleRepository(db).list(rig.id)
    return schemas.AlarmRules(rig_id=rig.name, items=[rule_out(r) for r in rules])


@router.get(
    "/{rig_id}/alarm-levels",
    response_model=schemas.AlarmLevelsOut,
    summary="Where each tooth stands against one alarm rule: baseline, levels, CUSUM",
    description="The levels the next record must pass, per tooth (or the whole record), as "
    "the rule has learned them: for one campaign's channel (default: the campaign of the "
    "rig's newest accepted record and its first accelerometer by name). 404 when the rig has "
    "no such rule or no accepted record.",
    responses=errors(401, 404, 422),
)
def get_levels(
    rig_id: RigName,
    db: DbSession,
    _caller: CurrentKey,
    indicator: Annotated[schemas.AlarmIndicatorName, Query(examples=["score"])],
    campaign: CampaignFilter = None,
    channel: ChannelFilter = None,
) -> schemas.AlarmLevelsOut:
    rig = rig_by_name(db, rig_id)
    found = rule_levels(db, rig, indicator, campaign, channel)
    if found is None:
        raise NotFound(f"rig {rig.name!r} has no rule for {indicator!r} or no accepted record")
    return schemas.AlarmLevelsOut(
        rig_id=rig.name, indicator=indicator, campaign=found.campaign, channel=found.channel,
        rule=rule_out(found.rule), pooled_spread=found.pooled_spread,
        items=[schemas.TrackLevelsOut(**dataclasses.asdict(track)) for track in found.tracks],
    )


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
