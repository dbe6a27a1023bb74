"""Result types of the per-record pipeline, shared by the CLI, storage and the service.

Everything here is plain data: numbers, strings and numpy arrays. ``to_json()``
gives the ``gearwatch analyze --json`` shape.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

MciForm = Literal["robust", "literal"]

AVERAGE_METRIC_NAMES = (
    "rms", "peak", "crest", "kurtosis", "fm0", "fm4", "na4", "nb4", "m6a", "m8a", "er",
)
"""The classic gear metrics of the pinion synchronous average (:func:`dsp.metrics.gear_metrics`)."""
RAW_METRIC_NAMES = ("raw_rms", "raw_kurtosis")
"""Overall metrics of the raw time signal about its mean."""
METRIC_NAMES = AVERAGE_METRIC_NAMES + RAW_METRIC_NAMES
"""Names of the whole-record metrics, in the order they are reported: the classic gear metrics of
the pinion synchronous average, then ``raw_rms`` and ``raw_kurtosis`` of the raw time signal about
its mean — the overall indicators that also see what the averages remove (non-synchronous faults
such as bearings)."""

TOOTH_INDICATORS = ("mci_depth", "diff_energy", "diff_kurtosis")
"""Per-tooth indicators, each stored as record × tooth × indicator."""


@dataclass(frozen=True)
class AnalysisParameters:
    """Every parameter of the per-record chain. Stored with each result version."""

    samples_per_mesh: int = 64
    """Samples per mesh period; samples per pinion revolution = pinion teeth × this (seed: 64)."""
    samples_per_rev_without_teeth: int = 1024
    """Samples per revolution when the rig has no tooth counts."""
    mci_form: MciForm = "robust"
    """``"robust"`` localises on zero-mean (AC-coupled) averages; ``"literal"`` is the seed's definition."""
    mci_window_samples: int | None = None
    """MCI window; default one mesh period (= samples_per_mesh)."""
    mci_median_width: int | None = None
    """Median filter width; default 2·W − 1 (seed §3.2)."""
    max_speed_variation: float = 0.10
    """Refuse a record whose (max − min)/mean of the per-revolution speed exceeds this."""
    min_revolutions: int = 20
    """Refuse a record with fewer whole revolutions of the tach shaft."""
    min_speed_rpm: float = 1.0
    max_speed_rpm: float = 100_000.0
    difference_sidebands: int = 1
    """Sidebands (in shaft orders) around each mesh harmonic removed for the difference signal."""

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> AnalysisParameters:
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = set(data) - names
        if unknown:
            raise ValueError(f"unknown analysis parameter(s): {', '.join(sorted(unknown))}")
        return cls(**data)


@dataclass(frozen=True)
class ToothResult:
    tooth: int
    """1-based pinion tooth number (tooth 1 at ``tooth1_pitch_angle_deg``)."""
    pitch_angle_deg: float
    """Pinion angle after the tach reference edge at which this tooth passes the pitch point."""
    mci_depth: float
    """MCI well depth of this tooth in nepers: the median-filtered MCI's median minus its mean
    over the tooth's sector, capped by the fall of the curve where a well starting at this tooth
    would begin (:func:`dsp.teeth.per_tooth_well_depth`). Amplitude-free: comparable across days."""
    diff_energy: float
    """Energy of the difference signal in this tooth's sector, relative to the mean sector energy."""
    diff_kurtosis: float
    """Kurtosis of the difference signal within this tooth's sector."""

    def indicators(self) -> dict[str, float]:
        return {name: float(getattr(self, name)) for name in TOOTH_INDICATORS}


@dataclass
class ChannelAnalysis:
    """Result of the chain for one accelerometer channel of one record."""

    channel: str
    revolutions: int
    """Whole pinion revolutions averaged."""
    gear_revolutions: int
    speed_rpm: float
    """Mean pinion speed."""
    samples_per_rev: int
    metrics: dict[str, float]
    """Whole-record metrics named in :data:`METRIC_NAMES`; without tooth counts only ``rms``,
    ``peak``, ``crest``, ``kurtosis``, ``raw_rms`` and ``raw_kurtosis`` (the others need the mesh
    order)."""
    teeth: list[ToothResult] = field(default_factory=list)
    worst_tooth: int | None = None
    curves: dict[str, np.ndarray] = field(default_factory=dict)
    """float32 arrays: ``pinion_average``, ``gear_average``, ``difference``, ``mci_raw``, ``mci``, ``speed_rpm``."""
    baseline_stats: dict[str, float] = field(default_factory=dict)
    """This record's contribution to running baselines: ``residual_variance`` (NA4) and
    ``envelope_variance`` (NB4). The caller averages them over earlier records and passes the
    result back in explicitly (:func:`gearwatch.pipeline.analyze_record`)."""


@dataclass(frozen=True)
class TachRepairNote:
    kind: str
    time_s: float


@dataclass
class Quality:
    tach_repairs: list[TachRepairNote]
    speed_variation: float
    """(max − min)/mean of the per-revolution speed of the tach shaft."""
    speed_min_rpm: float
    speed_max_rpm: float
    clipped_fraction: float = 0.0


@dataclass(frozen=True)
class Provenance:
    input_sha256: str
    code_version: str
    parameters: dict[str, Any]


@dataclass
class RecordAnalysis:
    channels: list[ChannelAnalysis]
    quality: Quality
    provenance: Provenance
    speed_rpm: float
    revolutions: int
    samples_per_rev: int

    def to_json(self, curves: bool = False) -> dict[str, Any]:
        """The ``gearwatch analyze --json`` object; the first accelerometer channel is also flattened to the top."""
        first = self.channels[0]

        def channel_json(ch: ChannelAnalysis) -> dict[str, Any]:
            out: dict[str, Any] = {
                "channel": ch.channel,
                "revolutions": ch.revolutions,
                "gear_revolutions": ch.gear_revolutions,
                "speed_rpm": ch.speed_rpm,
                "samples_per_rev": ch.samples_per_rev,
                "teeth": [dataclasses.asdict(t) for t in ch.teeth],
                "worst_tooth": ch.worst_tooth,
                "metrics": ch.metrics,
            }
            if curves:
                out["curves"] = {k: v.tolist() for k, v in ch.curves.items()}
            return out

        top = channel_json(first)
        top.update(
            {
                "revolutions": self.revolutions,
                "speed_rpm": self.speed_rpm,
                "samples_per_rev": self.samples_per_rev,
                "channels": [channel_json(ch) for ch in self.channels],
                "quality": dataclasses.asdict(self.quality),
                "provenance": dataclasses.asdict(self.provenance),
            }
        )
        return top
