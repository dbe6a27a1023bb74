"""Queries behind the operator's views: whole-record trends, record labels, the rig overview.

Like the other repositories: takes a session, never commits. Kept apart from
:mod:`storage.repositories` so that the operator's views grow without touching the core.
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import sqlalchemy as sa
from sqlalchemy.orm import Session

from gearwatch.floor.defaults import MAD_TO_SIGMA
from gearwatch.floor.errors import InputError, NotFound
from gearwatch.floor.indicators import all_indicators, indicator_info, indicator_unit
from gearwatch.floor.results import METRIC_NAMES, TOOTH1_ANGLE_KEY
from storage.models import Alarm, Campaign, Channel, Record, RecordMetric, Rig, ToothIndicator
from storage.repositories import (
    AlarmRepository,
    AlarmRuleRepository,
    CampaignRepository,
    RecordRepository,
    RigRepository,
    TrendMatrix,
    TrendRepository,
    gear_pair,
    rig_gear_pair,
)


@dataclass(frozen=True)
class RecordInfo:
    record_id: int
    taken_at: dt.datetime
    label: str
    status: str
    campaign: str
    quality: dict[str, Any]


class OperatorQueries:
    def __init__(self, session: Session) -> None:
        self.session = session

    def heat_map_indicator(self, rig_id: int) -> str:
        """The per-tooth ``score`` when the rig's stored results hold one, else ``mci_depth``
        (results stored before the score existed, or written by other tools)."""
        has_score = self.session.scalar(
            sa.select(ToothIndicator.id)
            .where(
                ToothIndicator.rig_id == rig_id,
                ToothIndicator.indicator == "score",
                # a finite value: results stored without a score hold NaN (NULL on SQLite),
                # and on PostgreSQL NaN sorts above every number
                ToothIndicator.value < 1e300,
            )
            .limit(1)
        )
        return "score" if has_score is not None else "mci_depth"

    # -- whole-record trends --------------------------------------------------------------
    def metric_matrix(
        self, rig_id: int, metric: str, *, channel: str | None = None,
        campaign_id: int | None = None,
    ) -> TrendMatrix:
        """A whole-record metric of one channel over the rig's accepted records (current
        result versions) as a records × 1 matrix; ``teeth`` is ``[0]`` (the whole record).

        Without ``channel``, the first channel by name that has values. The records of the
        rig's current gear pair, or of ``campaign_id`` alone (:meth:`channel_names`).
        """
        if metric not in METRIC_NAMES:
            raise InputError(f"unknown metric {metric!r} (known: {', '.join(METRIC_NAMES)})")
        rm = RecordMetric
        names = self.channel_names(rig_id, campaign_id)
        rows = self.session.execute(
            sa.select(rm.record_id, rm.taken_at, rm.channel_id, rm.value)
            .where(rm.rig_id == rig_id, rm.metric == metric, rm.is_current.is_(True))
            .order_by(rm.taken_at, rm.record_id)
        ).all()
        rows = [row for row in rows if row[2] in names]
        if channel is None and rows:
            channel = min(names[row[2]] for row in rows)
        rows = [row for row in rows if names[row[2]] == channel]
        return TrendMatrix(
            channel,
            [0],
            [int(r[0]) for r in rows],
            [r[1] for r in rows],
            np.asarray([[float(r[3])] for r in rows], dtype=np.float64).reshape(len(rows), 1),
        )

    def metric_version(self, rig_id: int) -> tuple[int, int]:
        """(highest row id, row count) of the rig's whole-record metric rows: changes whenever
        a whole-record trend can change (rows are only added, or deleted with their record)."""
        rm = RecordMetric
        row = self.session.execute(
            sa.select(sa.func.max(rm.id), sa.func.count()).where(rm.rig_id == rig_id)
        ).one()
        return int(row[0] or 0), int(row[1] or 0)

    def channel_names(self, rig_id: int, campaign_id: int | None = None) -> dict[int, str]:
        """The channels a rig's views cover: those of its current gear pair's campaigns, or of
        ``campaign_id`` alone."""
        return TrendRepository(self.session).channel_names(rig_id, campaign_id)

    def channel_unit(self, rig_id: int, channel: str | None) -> str:
        """The unit of a rig's channel as declared in its campaign manifest (``""`` if none)."""
        if channel is None:
            return ""
        unit = self.session.scalar(
            sa.select(Channel.unit)
            .join(Campaign, Campaign.id == Channel.campaign_id)
            .where(Campaign.rig_id == rig_id, Channel.name == channel)
            .order_by(Channel.id)
            .limit(1)
        )
        return unit or ""

    # -- records ---------------------------------------------------------------------------
    def records(self, rig_id: int) -> dict[int, RecordInfo]:
        """Every record of the rig by id: time, label, status, campaign, data quality."""
        query = (
            sa.select(
                Record.id, Record.taken_at, Record.label, Record.status, Campaign.name,
                Record.quality,
            )
            .join(Campaign, Campaign.id == Record.campaign_id)
            .where(Record.rig_id == rig_id)
            .order_by(Record.taken_at, Record.id)
        )
        return {
            int(i): RecordInfo(int(i), t, label or "", status, campaign, dict(quality or {}))
            for i, t, label, status, campaign, quality in self.session.execute(query)
        }

    def rig_record_labels(self, rig_id: int) -> dict[int, str]:
        """Record id → label for every record of the rig (one indexed query, Core rows)."""
        rows = self.session.connection().execute(
            sa.select(Record.id, Record.label).where(Record.rig_id == rig_id)
        )
        return {int(i): label or "" for i, label in rows}

    def last_record(self, rig_id: int) -> Record | None:
        return self.session.scalar(
            sa.select(Record)
            .where(Record.rig_id == rig_id)
            .order_by(Record.taken_at.desc(), Record.id.desc())
            .limit(1)
        )

    def open_alarm_counts(self, rig_id: int) -> dict[str, int]:
        query = (
            sa.select(Alarm.state, sa.func.count(Alarm.id))
            .where(Alarm.rig_id == rig_id, Alarm.state != "cleared")
            .group_by(Alarm.state)
        )
        return {str(state): int(n) for state, n in self.session.execute(query)}

    def tooth_values_of_record(
        self, record_id: int, indicator: str
    ) -> list[tuple[int, int, float]]:
        """(channel_id, tooth, value) of one record's current result for one indicator."""
        ti = ToothIndicator
        query = sa.select(ti.channel_id, ti.tooth, ti.value).where(
            ti.record_id == record_id, ti.indicator == indicator, ti.is_current.is_(True)
        )
        return [(int(c), int(t), float(v)) for c, t, v in self.session.execute(query)]


# -- the MCI baseline band ----------------------------------------------------------------------
BAND_HALF_WIDTH_SIGMAS = 3.0
"""The band is centre ± 3 robust standard deviations (1.4826·MAD)."""
MIN_BAND_RECORDS = 3
"""Fewer baseline records than this give no band (a median of two is no baseline)."""
DEFAULT_BASELINE_RECORDS = 10


def relative_to_median(values: np.ndarray) -> np.ndarray:
    """A curve minus its median over the finite samples (unchanged when none is finite)."""
    values = np.asarray(values, dtype=np.float64)
    finite = np.isfinite(values)
    return values - np.median(values[finite]) if finite.any() else values


def robust_band(curves: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pointwise median ± 3·1.4826·MAD over the first axis of a (records, samples) array."""
    centre = np.median(curves, axis=0)
    spread = MAD_TO_SIGMA * np.median(np.abs(curves - centre), axis=0)
    return centre - BAND_HALF_WIDTH_SIGMAS * spread, centre + BAND_HALF_WIDTH_SIGMAS * spread


@dataclass(frozen=True)
class Band:
    lower: np.ndarray
    upper: np.ndarray
    records: int


ANGLE_CURVES = frozenset({"pinion_average", "difference", "mci_raw", "mci"})
"""Stored curves over one pinion revolution of their record's tooth frame (:func:`in_pair_frame`
turns them); the gear average (a gear revolution) and the speed profile (per revolution) are not."""


@dataclass(frozen=True)
class CurveFrame:
    """Where a record's angle-domain curves put the pinion's teeth."""

    kind: str
    """``tachometer``, ``campaign`` (no tach: the campaign's tooth frame), ``refused`` or ``none``
    (no tooth frame, no shaft angle: the teeth are not numbered), as the analysis stored it."""
    tooth1_pitch_angle_deg: float | None
    """Tooth 1's pitch angle in the stored curves; None when the teeth are not numbered."""


def curve_frame(
    quality: Mapping[str, Any] | None, baseline_stats: Mapping[str, Any] | None, channel: str,
    pair_tooth1_deg: float,
) -> CurveFrame:
    """The tooth frame of one channel's stored curves, from its result's ``quality`` and its
    ``baseline_stats`` (:data:`gearwatch.floor.results.TOOTH1_ANGLE_KEY`).

    A tach-less record's curves are in the campaign's frame, whose tooth 1 is not where the
    manifest's ``tooth1_pitch_angle_deg`` says (0° when the campaign's reference is itself
    tach-less). A result stored before the angle was kept is taken at the pair's angle when it
    came from a tachometer, and as unnumbered otherwise.

    >>> curve_frame({"tooth_frames": {"acc": {"kind": "campaign"}}}, {"tooth1_pitch_angle_deg": 0.0}, "acc", 223.2)
    CurveFrame(kind='campaign', tooth1_pitch_angle_deg=0.0)
    >>> curve_frame({"tooth_frames": {"acc": {"kind": "refused"}}}, {}, "acc", 223.2)
    CurveFrame(kind='refused', tooth1_pitch_angle_deg=None)
    >>> curve_frame({}, {}, "acc", 223.2)
    CurveFrame(kind='tachometer', tooth1_pitch_angle_deg=223.2)
    """
    frame = ((quality or {}).get("tooth_frames") or {}).get(channel) or {}
    kind = str(frame.get("kind") or "tachometer")  # stored before tooth frames existed: a tach
    angle = (baseline_stats or {}).get(TOOTH1_ANGLE_KEY)
    if angle is None and kind == "tachometer":
        angle = pair_tooth1_deg
    return CurveFrame(kind, None if angle is None else float(angle))


def in_pair_frame(values: np.ndarray, tooth1_deg: float, pair_tooth1_deg: float) -> np.ndarray:
    """A curve over one pinion revolution turned from its record's tooth frame (tooth 1 at
    ``tooth1_deg``) to the gear pair's (tooth 1 at ``pair_tooth1_deg``), to the nearest sample.

    >>> in_pair_frame(np.arange(8.0), 0.0, 90.0).tolist()   # tooth 1 moves from sample 0 to 2
    [6.0, 7.0, 0.0, 1.0, 2.0, 3.0, 4.0, 5.0]
    """
    values = np.asarray(values)
    if values.size == 0:
        return values
    shift = round((pair_tooth1_deg - tooth1_deg) / 360.0 * values.size) % values.size
    return np.roll(values, shift)


def mci_in_pair_frame(
    records: RecordRepository, result: Any, channel: str, pair_tooth1_deg: float,
) -> tuple[CurveFrame, np.ndarray | None]:
    """A result version's stored ``mci`` curve on ``channel`` turned into the pair's tooth frame
    (:func:`curve_frame`, :func:`in_pair_frame`), with the frame it was stored in; the curve is
    None when there is none or the record's teeth are not numbered."""
    stats = next((c.baseline_stats for c in records.channel_results(result.id)
                  if c.channel.name == channel), None)
    frame = curve_frame(result.quality, stats, channel, pair_tooth1_deg)
    found = records.curves(result.id, channel=channel, names=["mci"])
    if not found or frame.tooth1_pitch_angle_deg is None:
        return frame, None
    return frame, in_pair_frame(found[0].values.astype(np.float64),
                                frame.tooth1_pitch_angle_deg, pair_tooth1_deg)


def mci_band(
    session: Session, rig_pk: int, channel: str, *, relative: bool = False,
    campaign_ids: Sequence[int] | None = None, pair_tooth1_deg: float | None = None,
) -> Band | None:
    """The MCI band of a rig's channel over its first accepted records (current results).

    As many records as the rig's ``mci_depth`` rule learns its baseline from (default 10), of
    the ``campaign_ids`` (default: the campaigns of the rig's current gear pair,
    :meth:`~storage.repositories.RigRepository.current_pair_campaign_ids`), whose teeth are
    numbered (:func:`curve_frame`: a tach-less record whose tooth frame was refused is in no
    frame the others share), each curve turned into the pair's tooth frame (tooth 1 at
    ``pair_tooth1_deg``, default the rig's current pair's; :func:`in_pair_frame`). Only
    curves of the most common length take part (a re-analysis with other samples per
    revolution changes the length). ``None`` with fewer than :data:`MIN_BAND_RECORDS`.
    ``relative``: each curve minus its own median first (:func:`relative_to_median`).
    """
    rule = AlarmRuleRepository(session).get_for(rig_pk, "mci_depth")
    count = rule.baseline_records if rule is not None else DEFAULT_BASELINE_RECORDS
    rigs = RigRepository(session)
    if campaign_ids is None:
        campaign_ids = rigs.current_pair_campaign_ids(rigs.get(rig_pk))
    if pair_tooth1_deg is None:
        pair_tooth1_deg = rig_gear_pair(rigs.get(rig_pk)).tooth1_pitch_angle_deg
    records = RecordRepository(session)
    curves: list[np.ndarray] = []
    pair_records = session.scalars(
        sa.select(Record)
        .where(Record.rig_id == rig_pk, Record.status == "accepted",
               Record.campaign_id.in_(list(campaign_ids)))
        .order_by(Record.taken_at, Record.id)
        .limit(count)
    ).all()
    for record in pair_records:
        result = records.current_result(record.id)
        if result is None:
            continue
        _, values = mci_in_pair_frame(records, result, channel, pair_tooth1_deg)
        if values is not None:
            curves.append(relative_to_median(values) if relative else values)
    if not curves:
        return None
    lengths = [len(c) for c in curves]
    common = max(set(lengths), key=lengths.count)
    stack = np.stack([c for c in curves if len(c) == common])
    stack = stack[np.all(np.isfinite(stack), axis=1)]
    if len(stack) < MIN_BAND_RECORDS:
        return None
    lower, upper = robust_band(stack)
    return Band(lower, upper, len(stack))


def tooth_sector_list(
    pinion_teeth: int | None, tooth1_pitch_angle_deg: float
) -> list[tuple[int, float, float]]:
    """(tooth, start_deg, end_deg) of every pinion tooth's sector (pitch angle ± half a pitch)
    along 0–360°, sorted by start; a sector that straddles 0° is given as two pieces."""
    if not pinion_teeth:
        return []
    pitch_deg = 360.0 / pinion_teeth
    sectors: list[tuple[int, float, float]] = []
    for tooth in range(1, pinion_teeth + 1):
        centre = (tooth1_pitch_angle_deg + (tooth - 1) * pitch_deg) % 360.0
        start, end = centre - pitch_deg / 2, centre + pitch_deg / 2
        if start < 0:
            sectors.append((tooth, start + 360.0, 360.0))
            start = 0.0
        if end > 360.0:
            sectors.append((tooth, 0.0, end - 360.0))
            end = 360.0
        sectors.append((tooth, start, end))
    return sorted(sectors, key=lambda s: s[1])


# -- answers shared by the REST API, the command line, the report and the notebook --------------
def unnumbered_reason(quality: Mapping[str, Any], channel: str) -> str | None:
    """Why a record's teeth are not numbered on ``channel`` (its quality's tooth frame for that
    channel: ``refused`` or ``none``), or None when they are (or the record says nothing of it).

    >>> unnumbered_reason({"tooth_frames": {"acc": {"kind": "refused", "reason": "ambiguous"}}}, "acc")
    'ambiguous'
    >>> unnumbered_reason({"tooth_frames": {"acc": {"kind": "campaign"}}}, "acc") is None
    True
    """
    frame = (quality.get("tooth_frames") or {}).get(channel) or {}
    if frame.get("kind") not in ("refused", "none"):
        return None
    return str(frame.get("reason") or quality.get("per_tooth") or "teeth not numbered")


def trend_data(
    session: Session, rig: Any, indicator: str, tooth: int | None, channel: str | None,
    campaign: str | None = None,
) -> dict[str, Any]:
    """The trend of any stored indicator of a rig (the REST trend answer, as plain values):
    a records × teeth matrix; a whole-record indicator has one column whose tooth is ``None``
    (never 0). Records carry their label; the answer its unit and title.

    The records of the rig's current gear pair; with ``campaign`` (a name), that campaign's
    alone, numbered by the pair it ran (:mod:`storage.repositories.rigs`: tooth 5 of one
    pair is not tooth 5 of the next). :class:`NotFound` when the rig has no
    such campaign."""
    if indicator not in all_indicators():
        raise InputError(
            f"unknown indicator {indicator!r} (known: {', '.join(all_indicators())})"
        )
    info = indicator_info(indicator)
    queries = OperatorQueries(session)
    pinion_teeth = rig.pinion_teeth
    campaign_id = None
    if campaign is not None:
        found = CampaignRepository(session).get_by_name(campaign)
        if found is None or found.rig_id != rig.id:
            raise NotFound(f"campaign {campaign!r} not found on rig {rig.name!r}")
        campaign_id = found.id
        pinion_teeth = (gear_pair(found.manifest) or rig_gear_pair(rig)).pinion_teeth
    teeth: list[int | None]
    if info.scope == "tooth":
        matrix = TrendRepository(session).trend_matrix(
            rig.id, indicator, tooth, channel=channel, pinion_teeth=pinion_teeth,
            campaign_id=campaign_id,
        )
        teeth = list(matrix.teeth)
    else:
        if tooth is not None:
            raise InputError(f"{indicator!r} is a whole-record indicator: it has no tooth")
        matrix = queries.metric_matrix(rig.id, indicator, channel=channel, campaign_id=campaign_id)
        teeth = [None]
    labels = queries.rig_record_labels(rig.id) if matrix.record_ids else {}
    without: list[dict[str, Any]] = []
    if info.scope == "tooth" and matrix.channel is not None:
        # accepted records of the same campaigns whose teeth this channel could not number (a
        # tach-less record whose tooth frame was refused, or without a shaft angle): said so
        # rather than left out of the matrix in silence
        scope_ids = ([campaign_id] if campaign_id is not None
                     else RigRepository(session).current_pair_campaign_ids(rig))
        rows = session.execute(
            sa.select(Record.id, Record.taken_at, Record.label, Record.quality)
            .where(Record.rig_id == rig.id, Record.status == "accepted",
                   Record.campaign_id.in_(scope_ids))
            .order_by(Record.taken_at, Record.id)
        ).all()
        for record_id, taken_at, label, quality in rows:
            reason = unnumbered_reason(quality or {}, matrix.channel)
            if reason is not None:
                without.append({"record_id": record_id, "taken_at": taken_at,
                                "label": label or "", "reason": reason})
    return {
        "rig_id": rig.name,
        "indicator": indicator,
        "title": info.title,
        "scope": info.scope,
        "unit": indicator_unit(indicator, queries.channel_unit(rig.id, matrix.channel)),
        "channel": matrix.channel,
        "campaign": campaign,
        "teeth": teeth,
        "records": [
            {"record_id": i, "taken_at": t, "label": labels.get(i, "")}
            for i, t in zip(matrix.record_ids, matrix.taken_at, strict=True)
        ],
        "values": _cells(matrix.values),
        "without_tooth_values": without,
    }


def _cells(values: np.ndarray) -> list[list[float | None]]:
    """Rows of a matrix as lists, NaN as ``None`` (strict JSON); cheap when nothing is NaN."""
    rows: list[list[float | None]] = values.tolist()
    if np.isfinite(values).all():
        return rows
    missing = ~np.isfinite(values)
    for i, j in zip(*np.nonzero(missing), strict=True):
        rows[int(i)][int(j)] = None
    return rows


def _finite(value: float | None) -> float | None:
    return None if value is None or not np.isfinite(value) else float(value)


def alarm_data(session: Session, alarm: Alarm, cache: dict[str, Any] | None = None) -> dict[str, Any]:
    """One alarm as the operator sees it: rig and campaign names, channel, tooth (``None`` for a
    whole-record indicator — inside, those are tracked as tooth 0), unit, the raising record's
    label, values, acknowledgement."""
    cache = {} if cache is None else cache
    rigs = cache.setdefault("rigs", {})
    if alarm.rig_id not in rigs:
        rig = session.get(Rig, alarm.rig_id)
        rigs[alarm.rig_id] = rig.name if rig is not None else str(alarm.rig_id)
    records = cache.setdefault("records", {})
    if alarm.raised_record_id not in records:
        found = None
        if alarm.raised_record_id is not None:
            found = session.execute(
                sa.select(Record.label, Campaign.name)
                .join(Campaign, Campaign.id == Record.campaign_id)
                .where(Record.id == alarm.raised_record_id)
            ).first()
        records[alarm.raised_record_id] = ("", None) if found is None else (found[0], found[1])
    label, campaign = records[alarm.raised_record_id]
    try:
        whole = indicator_info(alarm.indicator).scope == "record"
        unit = indicator_unit(alarm.indicator, alarm.channel.unit)
    except ValueError:  # an indicator no longer computed: keep the alarm readable
        whole, unit = alarm.tooth == 0, ""
    return {
        "id": alarm.id,
        "rig_id": rigs[alarm.rig_id],
        "campaign_id": campaign,
        "channel": alarm.channel.name,
        "tooth": None if whole or alarm.tooth == 0 else alarm.tooth,
        "indicator": alarm.indicator,
        "unit": unit,
        "state": alarm.state,
        "severity": alarm.severity,
        "record_id": alarm.raised_record_id,
        "record_label": label,
        "raised_at": alarm.raised_at,
        "last_value": _finite(alarm.last_value) or 0.0,
        "last_score": _finite(alarm.last_score) or 0.0,
        "baseline_centre": _finite(alarm.baseline_centre) or 0.0,
        "baseline_spread": _finite(alarm.baseline_spread) or 0.0,
        "evidence": alarm.evidence,
        "acknowledged_by": alarm.acknowledged_by,
        "acknowledged_at": alarm.acknowledged_at,
        "ack_comment": alarm.ack_comment,
        "cleared_at": alarm.cleared_at,
    }


def alarm_list(
    session: Session,
    *,
    rig_name: str | None = None,
    state: str | None = None,
    open_only: bool = False,
    limit: int | None = 1000,
) -> list[dict[str, Any]]:
    """Alarms newest first (:func:`alarm_data`), optionally of one rig (``NotFound`` if
    unknown)."""
    rig_pk = None
    if rig_name is not None:
        rig = RigRepository(session).get_by_name(rig_name)
        if rig is None:
            raise NotFound(f"rig {rig_name!r} not found")
        rig_pk = rig.id
    rows = AlarmRepository(session).list(
        rig_id=rig_pk, state=state, open_only=open_only, limit=limit
    )
    cache: dict[str, Any] = {}
    return [alarm_data(session, a, cache) for a in rows]


def trend_table(trend: dict[str, Any]) -> tuple[list[str], list[list[Any]]]:
    """A trend answer as a table: one row per record (id, time, label, channel), one column
    per tooth (``<indicator> tooth N [unit]``), or one ``<indicator> whole record [unit]``
    column for a whole-record indicator; ``None`` for a missing value."""
    unit = trend.get("unit") or ""
    suffix = f" [{unit}]" if unit else ""
    indicator = trend["indicator"]
    columns = [
        f"{indicator} whole record{suffix}" if t is None else f"{indicator} tooth {t}{suffix}"
        for t in trend["teeth"]
    ]
    header = ["record_id", "taken_at", "label", "channel", *columns]
    rows = [
        [r["record_id"], r["taken_at"], r.get("label", ""), trend.get("channel") or "", *values]
        for r, values in zip(trend["records"], trend["values"], strict=True)
    ]
    return header, rows
