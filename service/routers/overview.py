"""The rig overview: every rig's last record and its data quality, open alarms, worst tooth."""

from __future__ import annotations

import math
from typing import Any, Literal

from fastapi import APIRouter
from pydantic import BaseModel, Field
from sqlalchemy.orm import Session

from gearwatch.floor.indicators import all_indicators, indicator_info, indicator_unit
from service.deps import CurrentKey, DbSession
from service.routers.common import errors
from storage.models import Rig
from storage.operator_queries import OperatorQueries
from storage.repositories import RigRepository, TrendRepository

router = APIRouter(prefix="/api/v1", tags=["rigs"])

SPARKLINE_RECORDS = 30
"""How many of the latest accepted records the overview's sparkline shows."""


class LastRecordOut(BaseModel):
    record_id: int
    label: str
    taken_at: str
    status: Literal["accepted", "rejected", "pending"]
    reason: str = ""
    quality_score: float | None = Field(
        default=None, description="The record's data-quality score in [0, 1], when computed."
    )
    quality: dict[str, Any] = Field(default_factory=dict)


class WorstToothOut(BaseModel):
    tooth: int
    indicator: str = Field(description="`score` when stored, else `mci_depth`.")
    value: float
    unit: str
    record_id: int = Field(
        description="The latest accepted record with per-tooth values: not the last record when "
        "that one has none (a tach-less record whose teeth could not be numbered, a refused "
        "record)."
    )
    record_label: str = ""


class RigOverviewOut(BaseModel):
    rig_id: str
    pinion_teeth: int | None
    records: int
    accepted: int
    last_record: LastRecordOut | None = None
    open_alarms: dict[str, int] = Field(
        description="Open alarms by state (warning, alarm, acknowledged)."
    )
    worst_tooth: WorstToothOut | None = None
    sparkline: list[float | None] = Field(
        default_factory=list,
        description="The worst tooth's indicator over the latest accepted records, oldest first.",
    )


class OverviewOut(BaseModel):
    items: list[RigOverviewOut]


def quality_score(quality: dict[str, Any]) -> float | None:
    score = quality.get("score") if isinstance(quality, dict) else None
    if isinstance(score, int | float) and math.isfinite(score):
        return float(score)
    return None


def rig_overview(db: Session, rig: Rig) -> RigOverviewOut:
    queries = OperatorQueries(db)
    records = queries.records(rig.id)
    accepted = [r for r in records.values() if r.status == "accepted"]
    last = queries.last_record(rig.id)
    last_out = None
    if last is not None:
        last_out = LastRecordOut(
            record_id=last.id,
            label=last.label,
            taken_at=last.taken_at.isoformat().replace("+00:00", "Z"),
            status=last.status,  # type: ignore[arg-type]
            reason=last.reason,
            quality_score=quality_score(last.quality or {}),
            quality=dict(last.quality or {}),
        )
    worst = None
    sparkline: list[float | None] = []
    indicator = queries.heat_map_indicator(rig.id)
    if rig.pinion_teeth:
        matrix = TrendRepository(db).trend_matrix(
            rig.id, indicator, None, pinion_teeth=rig.pinion_teeth
        )
        if matrix.record_ids:
            row = matrix.values[-1]
            if any(math.isfinite(v) for v in row):
                column = max(
                    (j for j in range(len(row)) if math.isfinite(row[j])), key=lambda j: row[j]
                )
                worst_record = records.get(matrix.record_ids[-1])
                worst = WorstToothOut(
                    tooth=matrix.teeth[column],
                    indicator=indicator,
                    value=float(row[column]),
                    unit=indicator_unit(indicator, queries.channel_unit(rig.id, matrix.channel)),
                    record_id=matrix.record_ids[-1],
                    record_label=worst_record.label if worst_record is not None else "",
                )
                sparkline = [
                    float(v) if math.isfinite(v) else None
                    for v in matrix.values[-SPARKLINE_RECORDS:, column]
                ]
    return RigOverviewOut(
        rig_id=rig.name,
        pinion_teeth=rig.pinion_teeth,
        records=len(records),
        accepted=len(accepted),
        last_record=last_out,
        open_alarms=queries.open_alarm_counts(rig.id),
        worst_tooth=worst,
        sparkline=sparkline,
    )


@router.get(
    "/overview",
    response_model=OverviewOut,
    summary="Every rig at a glance",
    description="Per rig: the last record (label, date, status, data quality), open alarms by "
    "state, the worst tooth of the last accepted record (by `score` when stored, else by MCI "
    "depth) and its values over the latest accepted records (a sparkline).",
    responses=errors(401),
)
def overview(db: DbSession, _caller: CurrentKey) -> OverviewOut:
    return OverviewOut(items=[rig_overview(db, rig) for rig in RigRepository(db).list()])


class IndicatorOut(BaseModel):
    name: str = Field(examples=["mci_depth"])
    scope: Literal["tooth", "record"]
    title: str = Field(examples=["MCI depth"])
    unit: str = Field(
        description="Unit; `{unit}` stands for the channel's unit.", examples=["Np"]
    )


class IndicatorList(BaseModel):
    items: list[IndicatorOut]


@router.get(
    "/indicators",
    response_model=IndicatorList,
    summary="Every stored indicator: per tooth or whole record, title, unit",
    responses=errors(401),
)
def indicators(_caller: CurrentKey) -> IndicatorList:
    items = []
    for name in all_indicators():
        info = indicator_info(name)
        items.append(
            IndicatorOut(name=name, scope=info.scope, title=info.title, unit=info.unit_template)
        )
    return IndicatorList(items=items)
