"""Trends: one indicator across a rig's records."""

from __future__ import annotations

import builtins
import datetime as dt
from typing import Any, NamedTuple

import numpy as np
import sqlalchemy as sa

from gearwatch.floor.errors import InputError
from gearwatch.floor.results import METRIC_NAMES, STORED_TOOTH_INDICATORS
from storage.models import (
    Campaign,
    Channel,
    Record,
    RecordMetric,
    Rig,
    ToothIndicator,
)
from storage.repositories.base import Repository
from storage.repositories.rigs import CampaignRepository, GearPair, ran_pair


class TrendPoint(NamedTuple):
    record_id: int
    taken_at: dt.datetime
    channel: str
    tooth: int
    """1-based pinion tooth; 0 for a whole-record metric."""
    value: float


class TrendMatrix(NamedTuple):
    """A per-tooth trend of one channel: ``values[i, j]`` belongs to ``record_ids[i]`` (taken
    at ``taken_at[i]``) and ``teeth[j]``; NaN where the record has no value for the tooth."""

    channel: str | None
    teeth: builtins.list[int]
    record_ids: builtins.list[int]
    taken_at: builtins.list[dt.datetime]
    values: np.ndarray


class TrendRepository(Repository[ToothIndicator]):
    """Per-tooth and whole-record values across records (read only)."""

    model = ToothIndicator
    noun = "tooth value"

    def trend(
        self,
        rig_id: int,
        indicator: str,
        tooth: int | None = None,
        *,
        channel: str | None = None,
        since: dt.datetime | None = None,
        until: dt.datetime | None = None,
    ) -> builtins.list[TrendPoint]:
        """Per-tooth indicator over time (current result versions of accepted records), ordered
        by ``taken_at``, then channel (in creation order) and tooth. One query on the trend
        index, no join."""
        if indicator not in STORED_TOOTH_INDICATORS:
            raise InputError(
                f"unknown tooth indicator {indicator!r} (known: {', '.join(STORED_TOOTH_INDICATORS)})"
            )
        ti = ToothIndicator
        query = (
            sa.select(ti.record_id, ti.taken_at, ti.channel_id, ti.tooth, ti.value)
            .where(ti.rig_id == rig_id, ti.indicator == indicator, ti.is_current.is_(True))
            .order_by(ti.taken_at, ti.channel_id, ti.tooth)
        )
        return self._points(query, ti, rig_id, tooth, channel, since, until)

    def trend_matrix(
        self,
        rig_id: int,
        indicator: str,
        tooth: int | None = None,
        *,
        channel: str | None = None,
        pinion_teeth: int | None = None,
        campaign_id: int | None = None,
    ) -> TrendMatrix:
        """:meth:`trend` of one channel as a records × teeth matrix.

        Without ``channel``, the first channel by name that has values. The records of the
        rig's current gear pair, or of ``campaign_id`` alone (:meth:`channel_names`). Columns are
        ``[tooth]``, else teeth 1…``pinion_teeth``, else the teeth found; records are in
        ``taken_at`` order (then by id).

        A year of 20 teeth is 7300 cells: they are read in one query without timestamps or
        sorting (both cost more than the rest), no per-row objects; the rig's records, in time
        order from their index, give each record's row and time.
        """
        if indicator not in STORED_TOOTH_INDICATORS:
            raise InputError(
                f"unknown tooth indicator {indicator!r} (known: {', '.join(STORED_TOOTH_INDICATORS)})"
            )
        ti = ToothIndicator
        query = sa.select(ti.record_id, ti.channel_id, ti.tooth, ti.value).where(
            ti.rig_id == rig_id, ti.indicator == indicator, ti.is_current.is_(True)
        )
        names = self.channel_names(rig_id, campaign_id)
        if tooth is not None:
            query = query.where(ti.tooth == tooth)
        query = query.where(
            ti.channel_id.in_([k for k, n in names.items() if channel is None or n == channel]))
        cells = self.session.connection().execute(query).all()
        teeth = [tooth] if tooth is not None else list(range(1, (pinion_teeth or 0) + 1))
        if not cells:
            return TrendMatrix(channel, teeth, [], [], np.empty((0, len(teeth))))
        record_col, channel_col, tooth_col, value_col = zip(*cells, strict=True)
        if channel is None:
            channel = min(names[c] for c in set(channel_col))
        keep = np.isin(np.asarray(channel_col), [k for k, n in names.items() if n == channel])
        cell_records = np.asarray(record_col)[keep]
        tooth_numbers = np.asarray(tooth_col)[keep]
        values = np.asarray(value_col, dtype=np.float64)[keep]
        if not teeth:
            teeth = [int(t) for t in np.unique(tooth_numbers)]

        times = self.session.execute(
            sa.select(Record.id, Record.taken_at)
            .where(Record.rig_id == rig_id)
            .order_by(Record.taken_at, Record.id)
        ).all()
        ids_in_time_order = np.asarray([row[0] for row in times])
        by_id = np.argsort(ids_in_time_order)
        found = np.searchsorted(ids_in_time_order, cell_records, sorter=by_id)
        time_rank = by_id[np.minimum(found, len(by_id) - 1)]
        # A cell always has its record (same rig, foreign key); the check costs nothing.
        known = ids_in_time_order[time_rank] == cell_records
        ranks_used = np.unique(time_rank[known])
        row = np.searchsorted(ranks_used, time_rank)
        columns = np.asarray(teeth)
        column = np.minimum(np.searchsorted(columns, tooth_numbers), len(columns) - 1)
        known &= columns[column] == tooth_numbers
        matrix = np.full((len(ranks_used), len(teeth)), np.nan)
        matrix[row[known], column[known]] = values[known]
        return TrendMatrix(
            channel,
            teeth,
            [int(i) for i in ids_in_time_order[ranks_used]],
            [times[i][1] for i in ranks_used],
            matrix,
        )

    def _points(
        self,
        query: Any,
        model: type[ToothIndicator] | type[RecordMetric],
        rig_id: int,
        tooth: int | None,
        channel: str | None,
        since: dt.datetime | None,
        until: dt.datetime | None,
    ) -> builtins.list[TrendPoint]:
        # Channel names come from a small lookup rather than a join: a year of 20 teeth is
        # 7300 rows, and a per-row join doubles the query time on SQLite.
        names = self.channel_names(rig_id)
        if tooth is not None and model is ToothIndicator:
            query = query.where(ToothIndicator.tooth == tooth)
        ids = [key for key, name in names.items() if channel is None or name == channel]
        query = query.where(model.channel_id.in_(ids))
        if since is not None:
            query = query.where(model.taken_at >= since)
        if until is not None:
            query = query.where(model.taken_at < until)
        make = TrendPoint._make
        return [
            make((record_id, taken_at, names[channel_id], tooth_number, value))
            for record_id, taken_at, channel_id, tooth_number, value in (
                # Core rows fetched at once: no ORM loading overhead, no row-by-row fetch.
                self.session.connection().execute(query).all()
            )
        ]

    def channel_names(self, rig_id: int, campaign_id: int | None = None) -> dict[int, str]:
        """Channel id → name for every campaign of the rig's current gear pair
        (:meth:`~storage.repositories.rigs.RigRepository.current_pair_campaign_ids`): the
        channels a rig's trends cover. With ``campaign_id``, that campaign's channels alone,
        whichever pair it ran (an earlier pair's history stays within reach)."""
        if campaign_id is not None:
            return {c.id: c.name for c in CampaignRepository(self.session).channels(campaign_id)}
        query = (
            sa.select(Channel.id, Channel.name, Campaign.manifest, Rig.pinion_teeth,
                      Rig.gear_teeth, Rig.tooth1_pitch_angle_deg)
            .join(Campaign, Campaign.id == Channel.campaign_id)
            .join(Rig, Rig.id == Campaign.rig_id)
            .where(Campaign.rig_id == rig_id)
        )  # one query: a trend's cost is its queries
        return {
            int(channel_id): str(name)
            for channel_id, name, manifest, pinion_teeth, gear_teeth, tooth1_deg
            in self.session.execute(query)
            if ran_pair(manifest, GearPair(pinion_teeth, gear_teeth, float(tooth1_deg)))
        }

    def metric_trend(
        self,
        rig_id: int,
        metric: str,
        *,
        channel: str | None = None,
        since: dt.datetime | None = None,
        until: dt.datetime | None = None,
    ) -> builtins.list[TrendPoint]:
        """A whole-record metric over time (tooth 0 in every point)."""
        if metric not in METRIC_NAMES:
            raise InputError(f"unknown metric {metric!r} (known: {', '.join(METRIC_NAMES)})")
        rm = RecordMetric
        query = (
            sa.select(rm.record_id, rm.taken_at, rm.channel_id, sa.literal(0), rm.value)
            .where(rm.rig_id == rig_id, rm.metric == metric, rm.is_current.is_(True))
            .order_by(rm.taken_at, rm.channel_id)
        )
        return self._points(query, rm, rig_id, None, channel, since, until)
