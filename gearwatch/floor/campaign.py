"""Plain data types shared by every ingest source, the pipeline and storage.

A campaign manifest (``campaign.toml``, format in README) is parsed by
:func:`ingest.manifest.load_manifest` into :class:`Campaign`; every record file
or CAN stream is read into :class:`RecordData`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

TachKind = Literal["pulses", "pulse_times"]
Shaft = Literal["pinion", "gear"]
TachEdge = Literal["rising", "falling"]
ChannelKind = Literal["accelerometer", "tachometer"]


@dataclass(frozen=True)
class RigConfig:
    id: str
    pinion_teeth: int | None = None
    """Without tooth counts the per-tooth results are omitted and the rest kept."""
    gear_teeth: int | None = None
    tooth1_pitch_angle_deg: float = 0.0
    """Pinion angle after the tach reference edge (:attr:`TachometerConfig.edge`) at which pinion
    tooth 1 passes the pitch point."""
    nominal_pinion_rpm: float | None = None
    """Optional speed hint (±20 %) for the tach-less shaft angle (:mod:`gearwatch.usecases.tachless`)."""


@dataclass(frozen=True)
class TachometerConfig:
    channel: str
    kind: TachKind = "pulses"
    shaft: Shaft = "pinion"
    pulses_per_rev: int = 1
    edge: TachEdge = "rising"
    """The edge of a ``pulses`` waveform that marks a revolution — and that
    ``tooth1_pitch_angle_deg`` is measured from: ``rising`` (a reflective tape or a key under an
    optical or proximity sensor), ``falling`` (a notch under a proximity probe, or inverted
    logic, gives a pulse that goes low first)."""


@dataclass(frozen=True)
class ChannelConfig:
    name: str
    kind: ChannelKind
    unit: str = ""


@dataclass(frozen=True)
class RecordEntry:
    file: str
    """Path relative to the manifest's folder, as written in the manifest."""
    taken_at: str
    """ISO 8601 timestamp with time zone."""
    label: str = ""


@dataclass(frozen=True)
class Campaign:
    id: str
    description: str
    rig: RigConfig
    sample_rate_hz: float | None
    """Used when a record file does not carry its own rate."""
    tachometer: TachometerConfig | None
    """None when the manifest has no ``[tachometer]``: the shaft angle then comes from the mesh
    phase when the tooth counts are known (:mod:`gearwatch.usecases.tachless`)."""
    channels: tuple[ChannelConfig, ...]
    records: tuple[RecordEntry, ...] = ()
    root: Path = field(default=Path("."))
    """Folder of the manifest; record paths are relative to it."""

    @property
    def accelerometer_channels(self) -> tuple[ChannelConfig, ...]:
        return tuple(c for c in self.channels if c.kind == "accelerometer")

    def record_path(self, entry: RecordEntry) -> Path:
        return self.root / entry.file


@dataclass
class RecordData:
    """One record as read from a file or assembled from CAN frames.

    ``channels`` maps a channel name to its samples (1-D float64 for a waveform;
    for a ``pulse_times`` tachometer the pulse times in seconds). File readers may return
    float32 and READ-ONLY memory-mapped views (large records): convert one channel at a
    time with ``np.asarray(x, dtype=np.float64)``, never modify in place. ``sample_rate_hz``
    is the waveform rate: the file's own when it carries one, else the manifest's.
    """

    channels: dict[str, np.ndarray]
    sample_rate_hz: float
    source: str = ""
    """File path or bus description, for messages."""
    metadata: dict[str, str] = field(default_factory=dict)

    def channel(self, name: str) -> np.ndarray:
        try:
            return self.channels[name]
        except KeyError:
            known = ", ".join(sorted(self.channels)) or "none"
            from gearwatch.floor.errors import RecordFormatError

            raise RecordFormatError(
                f"{self.source or 'record'}: channel {name!r} not found (channels: {known})"
            ) from None
