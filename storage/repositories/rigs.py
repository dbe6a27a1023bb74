"""Rigs and campaigns (with their channels), created or updated from a manifest.

A rig is the test machine; a campaign runs one gear pair on it. Successive campaigns may mount
different pairs (other tooth counts, another tooth-1 angle): the rig row holds the pair of the
manifest it last saw, each campaign keeps its own in its stored manifest (:func:`gear_pair`),
and the rig's per-tooth views cover the campaigns of its current pair
(:meth:`RigRepository.current_pair_campaign_ids`) — tooth 5 of one pair is not tooth 5 of the
next.
"""

from __future__ import annotations

import builtins
import dataclasses
from collections.abc import Mapping
from typing import Any, NamedTuple

import sqlalchemy as sa

from gearwatch.floor.campaign import Campaign as CampaignConfig
from gearwatch.floor.campaign import RigConfig
from gearwatch.floor.errors import Conflict, NotFound
from storage.models import (
    Campaign,
    Channel,
    Rig,
)
from storage.repositories.base import Repository, json_safe


class GearPair(NamedTuple):
    """The gear pair a campaign ran: what per-tooth numbers of its records refer to."""

    pinion_teeth: int | None
    gear_teeth: int | None
    tooth1_pitch_angle_deg: float


def gear_pair(manifest: Mapping[str, Any] | None) -> GearPair | None:
    """The gear pair in a campaign's stored manifest (:attr:`Campaign.manifest`; None: a
    manifest without one)."""
    rig = (manifest or {}).get("rig")
    if not isinstance(rig, dict):
        return None
    return GearPair(rig.get("pinion_teeth"), rig.get("gear_teeth"),
                    float(rig.get("tooth1_pitch_angle_deg") or 0.0))


def ran_pair(manifest: Mapping[str, Any] | None, pair: GearPair) -> bool:
    """Whether the campaign of this stored manifest ran ``pair`` (one naming no pair counts as
    having run it: its records have nothing else to be compared with)."""
    return gear_pair(manifest) in (None, pair)


def rig_gear_pair(rig: Rig) -> GearPair:
    """The gear pair the rig row holds (its latest manifest's)."""
    return GearPair(rig.pinion_teeth, rig.gear_teeth, float(rig.tooth1_pitch_angle_deg))


class RigRepository(Repository[Rig]):
    model = Rig
    noun = "rig"

    def get_by_name(self, name: str) -> Rig | None:
        return self.session.scalar(sa.select(Rig).where(Rig.name == name))

    def list(self) -> builtins.list[Rig]:
        return list(self.session.scalars(sa.select(Rig).order_by(Rig.name)))

    def ensure(self, config: RigConfig) -> Rig:
        """The rig named ``config.id``, created or brought up to date with the manifest."""
        rig = self.get_by_name(config.id)
        if rig is None:
            rig = Rig(name=config.id)
            self.session.add(rig)
        rig.pinion_teeth = config.pinion_teeth
        rig.gear_teeth = config.gear_teeth
        rig.tooth1_pitch_angle_deg = float(config.tooth1_pitch_angle_deg)
        self.session.flush()
        return rig

    def pair_campaign_ids(self, rig: Rig, pair: GearPair) -> builtins.list[int]:
        """The rig's campaigns that ran ``pair``, and those whose manifest names no pair."""
        campaigns = self.session.scalars(sa.select(Campaign).where(Campaign.rig_id == rig.id))
        return sorted(c.id for c in campaigns if ran_pair(c.manifest, pair))

    def current_pair_campaign_ids(self, rig: Rig) -> builtins.list[int]:
        """The rig's campaigns that ran its current gear pair (module docstring)."""
        return self.pair_campaign_ids(rig, rig_gear_pair(rig))


class CampaignRepository(Repository[Campaign]):
    model = Campaign
    noun = "campaign"

    def get_by_name(self, name: str) -> Campaign | None:
        return self.session.scalar(sa.select(Campaign).where(Campaign.name == name))

    def list(self, rig_id: int | None = None) -> builtins.list[Campaign]:
        query = sa.select(Campaign).order_by(Campaign.name)
        if rig_id is not None:
            query = query.where(Campaign.rig_id == rig_id)
        return list(self.session.scalars(query))

    def ensure(self, config: CampaignConfig) -> Campaign:
        """The campaign named ``config.id`` with its rig and channels, created or updated.

        A campaign cannot move to another rig (:class:`Conflict`).
        """
        rig = RigRepository(self.session).ensure(config.rig)
        campaign = self.get_by_name(config.id)
        if campaign is None:
            campaign = Campaign(name=config.id, rig_id=rig.id)
            self.session.add(campaign)
        elif campaign.rig_id != rig.id:
            raise Conflict(
                f"campaign {config.id!r} belongs to rig {campaign.rig.name!r}, not {rig.name!r}"
            )
        campaign.description = config.description
        campaign.manifest = json_safe(
            {
                "rig": dataclasses.asdict(config.rig),
                "sample_rate_hz": config.sample_rate_hz,
                "tachometer": (
                    None if config.tachometer is None else dataclasses.asdict(config.tachometer)
                ),
                "channels": [dataclasses.asdict(c) for c in config.channels],
                "root": str(config.root),
            }
        )
        self.session.flush()
        existing = {c.name: c for c in self.channels(campaign.id)}
        for channel in config.channels:
            row = existing.get(channel.name)
            if row is None:
                self.session.add(
                    Channel(
                        campaign_id=campaign.id,
                        name=channel.name,
                        kind=channel.kind,
                        unit=channel.unit,
                    )
                )
            else:
                row.kind, row.unit = channel.kind, channel.unit
        self.session.flush()
        return campaign

    def channels(self, campaign_id: int) -> builtins.list[Channel]:
        query = sa.select(Channel).where(Channel.campaign_id == campaign_id).order_by(Channel.id)
        return list(self.session.scalars(query))

    def channel(self, campaign_id: int, name: str) -> Channel:
        row = self.session.scalar(
            sa.select(Channel).where(Channel.campaign_id == campaign_id, Channel.name == name)
        )
        if row is None:
            raise NotFound(f"channel {name!r} not found in campaign {campaign_id}")
        return row
