"""The ``change`` indicator: each tooth's waveform against the campaign's earlier records.

:mod:`dsp.toothchange` scores a record's pinion average against the mean of the campaign's
first accepted records (its reference); the score of a record therefore depends on the
records taken before it, like NA4's running baseline (:mod:`gearwatch.usecases.running_baselines`).
:func:`refresh_tooth_change` recomputes, after each accepted record, the ``change`` values of
every accepted record of the campaign from the stored averages in ``taken_at`` order, and
writes only what differs: in order, only the new record's values are written; a record that
arrives late rewrites those of the records after it. The record that arrives *last* in
``taken_at`` order (a live rig's every record) is scored from the campaign's first records alone
once they hold a complete reference (:func:`dsp.toothchange.campaign_change_state`): its cost does
not grow with the campaign (a rig recording every 10 minutes has thousands of records). The same
computation re-scores those first records; if their stored values differ (stored by a version of
gearwatch whose statistic differed), the whole campaign is recomputed instead, once. The alarm evaluation that follows
(:func:`gearwatch.usecases.alarms.evaluate_record`) replays the tracks of a late record, so the
``change`` alarms are a function of the set of accepted records, whatever order they arrived in.

A record enters the computation with its stored ``pinion_average`` curve and the tooth-1 pitch
angle its analysis used (``baseline_stats["tooth1_pitch_angle_deg"]``; a tach-less record placed
in the campaign's frame has the frame's angle). Records without it (analysed before the angle
was kept, a refused tooth frame, no tooth counts) are left out. Nothing here commits.
"""

from __future__ import annotations

import logging
import math
from collections import defaultdict

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session

from dsp.toothchange import DEFAULT_REFERENCE_RECORDS, campaign_change_scores, campaign_change_state
from gearwatch.floor.results import HISTORY_TOOTH_INDICATORS, TOOTH1_ANGLE_KEY
from storage.models import (
    Campaign,
    ChannelResult,
    Curve,
    ToothIndicator,
    float32_array,
)
from storage.repositories import RecordRepository, gear_pair, rig_gear_pair

logger = logging.getLogger(__name__)

(INDICATOR,) = HISTORY_TOOTH_INDICATORS  # "change", the one history indicator
RELATIVE_TOLERANCE = 1e-9
"""Stored values this close to the recomputed ones are kept (float32 curves, summation order)."""


def refresh_tooth_change(session: Session, campaign_id: int, record_id: int | None = None) -> int:
    """Bring the stored ``change`` values of the campaign's accepted records (current result
    versions) in line with their ``taken_at`` order; returns how many rows were written or removed.

    ``record_id``: the record just stored. When it is the last in ``taken_at`` order, only its
    own values can change, and they are computed from the campaign's first records (module
    docstring); otherwise, or without it, every record is recomputed.
    The caller holds the rig's lock (:func:`gearwatch.usecases.running_baselines.lock_rig`)."""
    campaign = session.get(Campaign, campaign_id)
    if campaign is None:
        return 0
    # the pair this campaign ran: the rig may carry another one since (storage.repositories.rigs)
    pinion_teeth = (gear_pair(campaign.manifest) or rig_gear_pair(campaign.rig)).pinion_teeth
    if not pinion_teeth:
        return 0
    by_channel: dict[int, list[tuple[ChannelResult, int, int, object]]] = defaultdict(list)
    for channel_result, row_record_id, _, rig_id, taken_at in RecordRepository(
        session
    ).current_channel_results(campaign_id):
        by_channel[channel_result.channel_id].append(
            (channel_result, row_record_id, rig_id, taken_at))
    written = 0
    for channel_id, rows in by_channel.items():
        appended = None
        if record_id is not None and rows[-1][1] == record_id:
            appended = _refresh_last(session, int(pinion_teeth), channel_id, rows)
        written += (appended if appended is not None
                    else _refresh_channel(session, int(pinion_teeth), channel_id, rows))
    if written:
        logger.info("campaign %s: %s per-tooth change value(s) written", campaign_id, written)
    session.flush()
    return written


def _averages(
    session: Session, pinion_teeth: int, channel_id: int,
    rows: list[tuple[ChannelResult, int, int, object]],
) -> tuple[list[np.ndarray | None], list[float]]:
    """The stored pinion averages (None where unusable) and tooth-1 angles of ``rows``."""
    curves = dict(session.execute(
        sa.select(Curve.result_id, Curve.data).where(
            Curve.result_id.in_([row[0].result_id for row in rows]), Curve.channel_id == channel_id,
            Curve.name == "pinion_average")
    ).all())
    averages: list[np.ndarray | None] = []
    angles: list[float] = []
    for channel_result, *_ in rows:
        angle = (channel_result.baseline_stats or {}).get(TOOTH1_ANGLE_KEY)
        data = curves.get(channel_result.result_id)
        samples = 0 if data is None else len(data) // 4
        if (isinstance(angle, int | float) and math.isfinite(angle) and data is not None
                and samples % pinion_teeth == 0 and samples >= 2 * pinion_teeth):
            averages.append(float32_array(data).astype(np.float64))
            angles.append(float(angle))
        else:
            averages.append(None)
            angles.append(0.0)
    return averages, angles


def _refresh_channel(
    session: Session,
    pinion_teeth: int,
    channel_id: int,
    rows: list[tuple[ChannelResult, int, int, object]],
) -> int:
    averages, angles = _averages(session, pinion_teeth, channel_id, rows)
    return _write(session, pinion_teeth, channel_id, rows,
                  campaign_change_scores(averages, angles, pinion_teeth))


def _refresh_last(
    session: Session,
    pinion_teeth: int,
    channel_id: int,
    rows: list[tuple[ChannelResult, int, int, object]],
) -> int | None:
    """Score the last record of ``rows`` from a prefix of the others (twice the reference's size,
    doubled as needed) that holds a complete reference of its average's length; ``None`` when no
    prefix does (then the whole campaign is recomputed)."""
    earlier = rows[:-1]
    (last_average,), (last_angle,) = _averages(session, pinion_teeth, channel_id, rows[-1:])
    if last_average is None:  # no score: nothing of anyone else changes either
        return _write(session, pinion_teeth, channel_id, rows[-1:], [None])
    prefix = min(len(earlier), 2 * DEFAULT_REFERENCE_RECORDS)
    while prefix >= DEFAULT_REFERENCE_RECORDS:
        averages, angles = _averages(session, pinion_teeth, channel_id, earlier[:prefix])
        scores, admitted = campaign_change_state(
            [*averages, last_average], [*angles, last_angle], pinion_teeth)
        complete = sum(1 for i in admitted
                       if i < prefix and (a := averages[i]) is not None
                       and a.size == last_average.size) >= DEFAULT_REFERENCE_RECORDS
        if complete:
            if not _agrees(session, pinion_teeth, channel_id, earlier[:prefix], scores[:-1]):
                return None  # the earlier records hold another version's values: recompute all
            return _write(session, pinion_teeth, channel_id, rows[-1:], scores[-1:])
        if prefix == len(earlier):
            return None
        prefix = min(len(earlier), 2 * prefix)
    return None


def _agrees(
    session: Session,
    pinion_teeth: int,
    channel_id: int,
    rows: list[tuple[ChannelResult, int, int, object]],
    scores: list[np.ndarray | None],
) -> bool:
    """Whether the stored ``change`` values of ``rows`` are ``scores``. They are, unless a
    version of gearwatch that computed the statistic otherwise stored them: the prefix's scores
    come free with the last record's, and a record's scores depend only on the records before it."""
    expected: dict[tuple[int, int], float] = {}
    for (channel_result, *_), values in zip(rows, scores, strict=True):
        for tooth in range(1, pinion_teeth + 1):
            value = None if values is None else float(values[tooth - 1])
            if value is not None and math.isfinite(value):
                expected[(channel_result.result_id, tooth)] = value
    stored = _stored(session, channel_id, [row[0].result_id for row in rows])
    return stored.keys() == expected.keys() and all(
        math.isclose(stored[key].value, value, rel_tol=RELATIVE_TOLERANCE, abs_tol=1e-12)
        for key, value in expected.items())


def _stored(session: Session, channel_id: int, result_ids: list[int]) -> dict[tuple[int, int], ToothIndicator]:
    """The stored ``change`` rows of these results on this channel, by (result id, tooth)."""
    return {
        (item.result_id, item.tooth): item
        for item in session.scalars(sa.select(ToothIndicator).where(
            ToothIndicator.result_id.in_(result_ids), ToothIndicator.channel_id == channel_id,
            ToothIndicator.indicator == INDICATOR))
    }


def _write(
    session: Session,
    pinion_teeth: int,
    channel_id: int,
    rows: list[tuple[ChannelResult, int, int, object]],
    scores: list[np.ndarray | None],
) -> int:
    """Store ``scores`` as the ``change`` rows of ``rows``, writing only what differs."""
    stored = _stored(session, channel_id, [row[0].result_id for row in rows])
    written = 0
    inserts: list[dict[str, object]] = []
    for (channel_result, record_id, rig_id, taken_at), values in zip(rows, scores, strict=True):
        result_id = channel_result.result_id
        for tooth in range(1, pinion_teeth + 1):
            row = stored.pop((result_id, tooth), None)
            value = None if values is None else float(values[tooth - 1])
            if value is None or not math.isfinite(value):
                if row is not None:
                    session.delete(row)
                    written += 1
                continue
            if row is None:
                inserts.append({"result_id": result_id, "channel_id": channel_id,
                                "record_id": record_id, "rig_id": rig_id, "taken_at": taken_at,
                                "tooth": tooth, "indicator": INDICATOR, "value": value})
            elif not math.isclose(row.value, value, rel_tol=RELATIVE_TOLERANCE, abs_tol=1e-12):
                row.value = value
                written += 1
    for row in stored.values():  # teeth beyond the rig's count (never expected): removed
        session.delete(row)
        written += 1
    if inserts:
        session.execute(sa.insert(ToothIndicator), inserts)
        written += len(inserts)
    return written
