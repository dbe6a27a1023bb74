"""NA4 and NB4 as a function of the campaign's accepted records ordered by ``taken_at``, not of
the order they arrived in.

NA4 (NB4) divides a record's fourth moment of the residual (of the mesh-band envelope) by the
*running baseline*: the mean residual (envelope) variance of the campaign's accepted records
taken before it (:func:`dsp.metrics.na4`; the record's own variance when there is none). The
analysis computes it with the records stored at that moment; with two workers, or a late
upload, a record taken earlier can arrive later and change the baseline of every record taken
after it. :func:`refresh_running_baselines` recomputes, after each accepted record, the
baseline of every accepted record of the campaign from the stored per-record variances, and
rescales the stored NA4/NB4 values whose baseline moved:
``NA4_new = NA4_old · (baseline_old / baseline_new)²`` (exact: the fourth moment does not
change; a zero baseline gives 0, as in :mod:`dsp.metrics`). The alarm evaluation that follows
(:func:`gearwatch.usecases.alarms.evaluate_record`) replays the tracks of a late record, so
NA4/NB4 alarms then follow the rescaled values.

Records stored before the analysis kept the baseline it used (``na4_baseline`` in
``baseline_stats``) are left as they are. Nothing here commits.
"""

from __future__ import annotations

import logging
import math
from collections import defaultdict
from dataclasses import dataclass
from typing import Any

import sqlalchemy as sa
from sqlalchemy.orm import Session

from storage.models import ChannelResult, RecordMetric, Rig
from storage.repositories import RecordRepository

logger = logging.getLogger(__name__)

RUNNING = (("na4", "residual_variance", "na4_baseline"),
           ("nb4", "envelope_variance", "nb4_baseline"))
"""(metric, the per-record variance its baseline averages, the baseline the value was divided by)."""
RELATIVE_TOLERANCE = 1e-12
"""Baselines this close are the same (summation order only): the stored value is kept."""


@dataclass
class _Row:
    channel_result: ChannelResult
    record_id: int
    result_id: int
    channel_id: int
    taken_at: Any


def lock_rig(session: Session, rig_id: int) -> None:
    """Wait for other transactions changing this rig's evaluation (the row lock that
    :func:`gearwatch.usecases.alarms.evaluate_record` takes too), then see what they committed."""
    session.flush()
    session.execute(sa.select(Rig.id).where(Rig.id == rig_id).with_for_update(key_share=True))
    session.expire_all()


def expected_baselines(
    points: list[tuple[Any, dict[str, Any]]], variance_key: str
) -> list[float | None]:
    """For ``(taken_at, baseline_stats)`` points in ``taken_at`` order: the mean of
    ``variance_key`` over the points taken strictly before each one, else its own value
    (``None`` when it has none).

    >>> expected_baselines([(1, {"v": 2.0}), (2, {"v": 4.0}), (2, {"v": 9.0}), (3, {"v": 1.0})], "v")
    [2.0, 2.0, 2.0, 5.0]
    """
    out: list[float | None] = []
    total, count = 0.0, 0
    index = 0
    while index < len(points):
        end = index
        while end < len(points) and points[end][0] == points[index][0]:
            end += 1
        group = points[index:end]
        for _, stats in group:
            own = _finite(stats.get(variance_key))
            out.append(total / count if count else own)
        for _, stats in group:  # records taken at the same moment do not count for each other
            own = _finite(stats.get(variance_key))
            if own is not None:
                total += own
                count += 1
        index = end
    return out


def _finite(value: Any) -> float | None:
    if isinstance(value, int | float) and math.isfinite(value):
        return float(value)
    return None


def rescaled(value: float, old_baseline: float, new_baseline: float) -> float:
    """A fourth moment divided by ``old_baseline²``, divided by ``new_baseline²`` instead.

    >>> rescaled(3.0, 2.0, 4.0)
    0.75
    >>> rescaled(3.0, 2.0, 0.0)
    0.0
    """
    if new_baseline <= 0.0:
        return 0.0
    return value * (old_baseline / new_baseline) ** 2


def refresh_running_baselines(session: Session, campaign_id: int) -> int:
    """Bring the stored NA4/NB4 of the campaign's accepted records (current result versions)
    in line with their ``taken_at``-ordered baselines; returns how many values changed.

    The caller holds the rig's lock (:func:`lock_rig`) so that two workers see each other's
    records; in ``taken_at`` order with nothing late, nothing changes."""
    by_channel: dict[int, list[_Row]] = defaultdict(list)
    for channel_result, record_id, result_id, _, taken_at in RecordRepository(
        session
    ).current_channel_results(campaign_id):
        by_channel[channel_result.channel_id].append(
            _Row(channel_result, record_id, result_id, channel_result.channel_id, taken_at))
    changed = 0
    for rows in by_channel.values():
        points = [(row.taken_at, dict(row.channel_result.baseline_stats or {})) for row in rows]
        for metric, variance_key, used_key in RUNNING:
            expected = expected_baselines(points, variance_key)
            for row, (_, stats), new in zip(rows, points, expected, strict=True):
                old = _finite(stats.get(used_key))
                if new is None or old is None or old <= 0.0:
                    continue  # analysed before baselines were kept, no variance, or NA4 = 0
                if math.isclose(old, new, rel_tol=RELATIVE_TOLERANCE, abs_tol=0.0):
                    continue
                changed += _rescale_metric(session, row, metric, old, new)
                stats[used_key] = new
                row.channel_result.baseline_stats = dict(stats)  # a new dict: a tracked change
    if changed:
        logger.info("campaign %s: %s NA4/NB4 value(s) rescaled to their taken_at-ordered "
                    "baselines (a record arrived out of order)", campaign_id, changed)
    session.flush()
    return changed


def _rescale_metric(session: Session, row: _Row, metric: str, old: float, new: float) -> int:
    stored = session.execute(
        sa.select(RecordMetric).where(
            RecordMetric.result_id == row.result_id, RecordMetric.channel_id == row.channel_id,
            RecordMetric.metric == metric)
    ).scalars().all()
    for item in stored:
        item.value = rescaled(float(item.value), old, new)
    return len(stored)
