"""Derived views the service computes from repository data (no SQL of its own)."""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from collections.abc import Sequence
from contextlib import AbstractContextManager
from typing import Generic, TypeVar

import sqlalchemy as sa
from sqlalchemy.orm import Session

from service import schemas
from storage.models import ToothIndicator

# One definition of the band, shared with the campaign report (re-exported here).
from storage.operator_queries import BAND_HALF_WIDTH_SIGMAS as BAND_HALF_WIDTH_SIGMAS
from storage.operator_queries import DEFAULT_BASELINE_RECORDS as DEFAULT_BASELINE_RECORDS
from storage.operator_queries import MIN_BAND_RECORDS as MIN_BAND_RECORDS
from storage.operator_queries import mci_band
from storage.operator_queries import relative_to_median as relative_to_median
from storage.operator_queries import robust_band as robust_band

BodyT = TypeVar("BodyT")


def tooth_sectors(
    pinion_teeth: int | None, tooth1_pitch_angle_deg: float
) -> list[schemas.ToothSector]:
    """Every pinion tooth's sector (pitch angle ± half a pitch) along 0–360°.

    Tooth ``k`` passes the pitch point at ``tooth1 + (k − 1)·360/Z`` degrees (as in
    :mod:`dsp.teeth`); a sector that straddles 0° is given as two pieces.
    """
    if not pinion_teeth:
        return []
    pitch_deg = 360.0 / pinion_teeth
    sectors: list[schemas.ToothSector] = []
    for tooth in range(1, pinion_teeth + 1):
        centre = (tooth1_pitch_angle_deg + (tooth - 1) * pitch_deg) % 360.0
        start, end = centre - pitch_deg / 2, centre + pitch_deg / 2
        if start < 0:
            sectors.append(schemas.ToothSector(tooth=tooth, start_deg=start + 360.0, end_deg=360.0))
            start = 0.0
        if end > 360.0:
            sectors.append(schemas.ToothSector(tooth=tooth, start_deg=0.0, end_deg=end - 360.0))
            end = 360.0
        sectors.append(schemas.ToothSector(tooth=tooth, start_deg=start, end_deg=end))
    return sorted(sectors, key=lambda s: s.start_deg)


def mci_baseline_band(
    session: Session, rig_pk: int, channel: str, *, relative: bool = False,
    campaign_ids: Sequence[int] | None = None, pair_tooth1_deg: float | None = None,
) -> schemas.BaselineBand | None:
    """The MCI band of a rig's channel (:func:`storage.operator_queries.mci_band`)."""
    band = mci_band(session, rig_pk, channel, relative=relative, campaign_ids=campaign_ids,
                    pair_tooth1_deg=pair_tooth1_deg)
    if band is None:
        return None
    return schemas.BaselineBand(
        lower=[float(v) for v in band.lower], upper=[float(v) for v in band.upper],
        records=band.records,
    )


def trend_version(session: Session, rig_pk: int) -> tuple[int, int]:
    """A cheap fingerprint of a rig's per-tooth indicator rows: (highest row id, row count).

    Rows are only added (a re-analysis adds new rows and marks the old ones as not current in
    the same transaction) or deleted with their record, so the fingerprint changes whenever a
    trend of the rig can change. Both aggregates are answered from the trend index. One indexed
    aggregate; used to serve cached trend responses.

    Requested from the storage layer as ``TrendRepository.version(rig_id)``; kept here until
    it exists there.
    """
    ti = ToothIndicator
    row = session.execute(
        sa.select(sa.func.max(ti.id), sa.func.count()).where(ti.rig_id == rig_pk)
    ).one()
    return int(row[0] or 0), int(row[1] or 0)


class ResponseCache(Generic[BodyT]):
    """A small thread-safe LRU of serialized responses, each tagged with the data version it
    was built from and when that version was last confirmed.

    It also keeps the last confirmed data version of each group (a rig): one database check
    per group and ``max_age_s`` then serves every cached answer of the group
    (:meth:`group_version`, :meth:`confirm`), and striped locks let concurrent misses of one
    key build its answer once (:meth:`build_lock`).
    """

    LOCK_STRIPES = 64

    def __init__(self, max_entries: int = 256) -> None:
        self._entries: OrderedDict[object, tuple[object, BodyT, float]] = OrderedDict()
        self._groups: dict[object, tuple[object, float]] = {}
        self._lock = threading.Lock()
        # A fixed set of locks (keys come from query parameters: a lock per key would grow).
        self._build_locks = [threading.Lock() for _ in range(self.LOCK_STRIPES)]
        self.max_entries = max_entries

    def fresh(self, key: object, max_age_s: float) -> tuple[object, BodyT] | None:
        """The entry if its version was confirmed less than ``max_age_s`` ago."""
        with self._lock:
            entry = self._entries.get(key)
            if entry is None or time.monotonic() - entry[2] >= max_age_s:
                return None
            self._entries.move_to_end(key)
            return entry[0], entry[1]

    def get(self, key: object, version: object) -> BodyT | None:
        """The body built from ``version`` (and mark it confirmed now), else ``None``."""
        with self._lock:
            entry = self._entries.get(key)
            if entry is None or entry[0] != version:
                return None
            self._entries[key] = (version, entry[1], time.monotonic())
            self._entries.move_to_end(key)
            return entry[1]

    def put(self, key: object, version: object, body: BodyT) -> None:
        with self._lock:
            self._entries[key] = (version, body, time.monotonic())
            self._entries.move_to_end(key)
            while len(self._entries) > self.max_entries:
                self._entries.popitem(last=False)

    def group_version(self, group: object, max_age_s: float) -> object | None:
        """The group's data version if it was confirmed less than ``max_age_s`` ago."""
        with self._lock:
            found = self._groups.get(group)
            if found is None or time.monotonic() - found[1] >= max_age_s:
                return None
            return found[0]

    def confirm(self, group: object, version: object) -> None:
        """Record ``version`` as the group's data version, confirmed now."""
        with self._lock:
            self._groups[group] = (version, time.monotonic())

    def build_lock(self, key: object) -> AbstractContextManager[bool]:
        """The lock to hold while building ``key``'s answer (shared with a few other keys)."""
        return self._build_locks[hash(key) % self.LOCK_STRIPES]
