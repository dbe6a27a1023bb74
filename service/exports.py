"""Trend answers of every indicator, and CSV exports of trends and alarm lists.

A trend of a per-tooth indicator is a records × teeth matrix; a trend of a whole-record
indicator is a records × 1 matrix whose only tooth is ``null`` (the whole record, never
"tooth 0"). Each record carries its label and date; the answer carries the indicator's unit.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Iterable, Sequence
from typing import Any

from sqlalchemy.orm import Session

from gearwatch.floor.errors import InputError
from gearwatch.floor.indicators import all_indicators
from service import schemas
from storage.models import Rig
from storage.operator_queries import trend_data, trend_table

CSV_MEDIA_TYPE = "text/csv; charset=utf-8"


def check_indicator(indicator: str) -> str:
    if indicator not in all_indicators():
        raise InputError(
            f"unknown indicator {indicator!r} (known: {', '.join(all_indicators())})"
        )
    return indicator


def trend_answer(
    db: Session, rig: Rig, indicator: str, tooth: int | None, channel: str | None,
    campaign: str | None = None,
) -> schemas.TrendOut:
    """The trend of any stored indicator (:func:`storage.operator_queries.trend_data`)."""
    data = trend_data(db, rig, indicator, tooth, channel, campaign)
    point = schemas.TrendPoint.model_construct
    data["records"] = [point(**r) for r in data["records"]]
    data["without_tooth_values"] = [schemas.UnnumberedRecord.model_construct(**r)
                                    for r in data["without_tooth_values"]]
    return schemas.TrendOut.model_construct(**data)


def _csv(header: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\r\n")
    writer.writerow(header)
    for row in rows:
        writer.writerow(["" if v is None else v for v in row])
    return out.getvalue()


def trend_csv_from_json(body: bytes) -> str:
    """CSV of a trend answer (:func:`storage.operator_queries.trend_table`): one row per record (id,
    time, label), one column per tooth (or one for a whole-record indicator); empty cells for
    missing values."""
    header, rows = trend_table(json.loads(body))
    return _csv(header, rows)


ALARM_CSV_COLUMNS = (
    "id", "rig_id", "campaign_id", "channel", "indicator", "tooth", "state", "severity",
    "raised_at", "record_id", "record_label", "last_value", "unit", "last_score",
    "baseline_centre", "baseline_spread", "acknowledged_by", "acknowledged_at", "ack_comment",
    "cleared_at",
)  # fmt: skip


def alarms_csv(items: Sequence[schemas.AlarmOut]) -> str:
    """CSV of an alarm list; ``tooth`` is empty for a whole-record alarm."""
    rows = []
    for alarm in items:
        data = alarm.model_dump(mode="json")
        rows.append([data.get(column) for column in ALARM_CSV_COLUMNS])
    return _csv(ALARM_CSV_COLUMNS, rows)
