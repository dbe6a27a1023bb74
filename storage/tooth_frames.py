"""The campaign's tooth-frame references (issue 11): loaded before a tach-less record, saved after.

Kept apart from :mod:`storage.repositories` (a separate table, a separate concern). See
:class:`storage.models.ToothFrameReference` and :mod:`gearwatch.usecases.tachless`.
"""

from __future__ import annotations

import sqlalchemy as sa
from sqlalchemy.orm import Session

from gearwatch.floor.results import ToothFrameReference as Reference
from storage.models import ToothFrameReference, float32_array, float32_bytes

__all__ = ["ToothFrameRepository"]


class ToothFrameRepository:
    def __init__(self, session: Session) -> None:
        self.session = session

    def _rows(self, campaign_id: int) -> dict[str, ToothFrameReference]:
        query = sa.select(ToothFrameReference).where(ToothFrameReference.campaign_id == campaign_id)
        return {row.channel: row for row in self.session.scalars(query)}

    def references(self, campaign_id: int) -> dict[str, Reference]:
        """Channel name → the campaign's reference (channels without one are absent)."""
        return {
            name: Reference(
                frame="tachometer" if row.frame == "tachometer" else "mesh_phase",
                record_sha256=row.record_sha256,
                pinion_fingerprint=float32_array(row.pinion_fingerprint).astype("float64"),
                pinion_position=float(row.pinion_position),
                gear_fingerprint=(None if row.gear_fingerprint is None
                                  else float32_array(row.gear_fingerprint).astype("float64")),
                records=int(row.records),
                speed_rpm=None if row.speed_rpm is None else float(row.speed_rpm),
            )
            for name, row in self._rows(campaign_id).items()
        }

    def save(self, campaign_id: int, channel: str, reference: Reference) -> None:
        """Store (create or replace) a channel's reference, e.g. after
        :func:`gearwatch.usecases.tachless.fold_reference`."""
        row = self._rows(campaign_id).get(channel)
        if row is None:
            row = ToothFrameReference(campaign_id=campaign_id, channel=channel)
            self.session.add(row)
        row.frame = reference.frame
        row.record_sha256 = reference.record_sha256
        row.records = reference.records
        row.pinion_position = float(reference.pinion_position)
        row.pinion_fingerprint = float32_bytes(reference.pinion_fingerprint)
        row.gear_fingerprint = (None if reference.gear_fingerprint is None
                                else float32_bytes(reference.gear_fingerprint))
        row.speed_rpm = None if reference.speed_rpm is None else float(reference.speed_rpm)
        self.session.flush()
