"""Result types of the per-record pipeline, shared by the CLI, storage and the service.

Everything here is plain data: numbers, strings and numpy arrays. ``to_json()``
gives the ``gearwatch analyze --json`` shape.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from gearwatch.floor.defaults import (
    GLITCH_RANGE_FACTOR,
    MAX_SPEED_VARIATION,
    MIN_REVOLUTIONS,
    REVOLUTION_OUTLIER_FACTOR,
    SAMPLES_PER_MESH,
    SAMPLES_PER_REV_WITHOUT_TEETH,
    SPIKE_FACTOR,
)

MciForm = Literal["robust", "literal"]

AVERAGE_METRIC_NAMES = (
    "rms", "peak", "crest", "kurtosis", "fm0", "fm4", "na4", "residual_kurtosis", "nb4", "m6a", "m8a",
    "er",
)
"""The classic gear metrics of the pinion synchronous average (:func:`dsp.metrics.gear_metrics`)."""
RAW_METRIC_NAMES = ("raw_rms", "raw_kurtosis")
"""Overall metrics of the raw time signal about its mean."""
METRIC_NAMES = AVERAGE_METRIC_NAMES + RAW_METRIC_NAMES
"""Names of the whole-record metrics, in the order they are reported: the classic gear metrics of
the pinion synchronous average, then ``raw_rms`` and ``raw_kurtosis`` of the raw time signal about
its mean — the overall indicators that also see what the averages remove (non-synchronous faults
such as bearings)."""

TOOTH_INDICATORS = (
    "mci_depth", "diff_energy", "diff_kurtosis", "mci_depth_se", "score", "nonsync_z",
)
"""Per-tooth indicators of one record's analysis, each stored as record × tooth × indicator."""

HISTORY_TOOTH_INDICATORS = ("change",)
"""Per-tooth indicators computed from the campaign's accepted records in ``taken_at`` order, not
from one record alone (``change``: :mod:`dsp.toothchange`, the tooth's waveform against the
campaign's reference records); stored like :data:`TOOTH_INDICATORS` once the campaign has
enough records, and recomputed when a record arrives out of order."""

STORED_TOOTH_INDICATORS = TOOTH_INDICATORS + HISTORY_TOOTH_INDICATORS
"""Every per-tooth indicator a trend or an alarm rule can name."""

TOOTH1_ANGLE_KEY = "tooth1_pitch_angle_deg"
"""Key of a channel's ``baseline_stats`` holding tooth 1's pitch angle in that record's stored
angle-domain curves (the pinion average, the difference signal, the MCI): the manifest's angle
with a tachometer, the campaign frame's without one (0° when the campaign's reference is a
tach-less record). Absent when the record's teeth are not numbered (a refused tooth frame, no
shaft angle, no tooth counts)."""


@dataclass(frozen=True)
class AnalysisParameters:
    """Every parameter of the per-record chain. Stored with each result version."""

    samples_per_mesh: int = SAMPLES_PER_MESH
    """Samples per mesh period; samples per pinion revolution = pinion teeth × this (seed: 64)."""
    samples_per_rev_without_teeth: int = SAMPLES_PER_REV_WITHOUT_TEETH
    """Samples per revolution when the rig has no tooth counts."""
    mci_form: MciForm = "robust"
    """``"robust"`` localises on zero-mean (AC-coupled) averages; ``"literal"`` is the seed's definition."""
    mci_window_samples: int | None = None
    """MCI window; default one mesh period (= samples_per_mesh)."""
    mci_median_width: int | None = None
    """Median filter width; default 2·W − 1 (seed §3.2)."""
    max_speed_variation: float = MAX_SPEED_VARIATION
    """Refuse a record whose (max − min)/mean of the per-revolution speed exceeds this (order
    tracking follows slow drift; the average then mixes operating points, see the quality score)."""
    min_revolutions: int = MIN_REVOLUTIONS
    """Refuse a record with fewer whole revolutions of the tach shaft."""
    min_speed_rpm: float = 1.0
    max_speed_rpm: float = 100_000.0
    difference_sidebands: int = 1
    """Sidebands (in shaft orders) around each mesh harmonic removed for the difference signal."""
    glitch_range_factor: float = GLITCH_RANGE_FACTOR
    """A sample beyond the 0.1–99.9 % quantile range widened this many times is a glitch
    (:func:`dsp.robust.glitch_limits`)."""
    spike_factor: float = SPIKE_FACTOR
    """An isolated sample this many 0.1–99.9 % quantile ranges from its neighbours' median is a
    glitch (:func:`dsp.robust.find_spikes`); 0: no spike test."""
    revolution_outlier_factor: float = REVOLUTION_OUTLIER_FACTOR
    """A revolution whose residual peak or energy exceeds this multiple of the median over the
    revolutions is left out of the average (:func:`dsp.robust.revolution_outliers`)."""

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
    mci_depth_se: float = float("nan")
    """Standard error of this tooth's MCI evidence from the record itself, nepers: delete-a-group
    jackknife over 8 interleaved groups of revolutions (:mod:`dsp.toothscore`)."""
    score: float = float("nan")
    """How far this tooth's MCI evidence stands above the median tooth of the same record, in
    its own standard errors (dimensionless; about N(0, 1) on a healthy record; effects common to
    all teeth — load, speed, gain, temperature — cancel). Its history is watched by the ``score``
    alarm rule (:mod:`detection.alarms`)."""
    nonsync_z: float = float("nan")
    """How far the non-synchronous power in this tooth's sector (the revolutions' power about
    their average) stands above the record's typical tooth, in robust standard deviations over
    the teeth (dimensionless; 0 = the median tooth). A spall's ringing that a drifting speed
    smears out of the average stays here (:mod:`dsp.nonsync`)."""

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
    quality: ChannelQuality | None = None
    """Data quality of this channel (rejections, defective samples, score)."""
    baseline_stats: dict[str, float] = field(default_factory=dict)
    """This record's contribution to running baselines: ``residual_variance`` (NA4) and
    ``envelope_variance`` (NB4). The caller averages them over earlier records and passes the
    result back in explicitly (:func:`gearwatch.usecases.analyze.analyze_record`)."""
    tooth_frame: dict[str, Any] = field(default_factory=dict)
    """Which frame the tooth numbers are in (``kind``: ``tachometer``, ``campaign``, ``own``,
    ``refused`` or ``none``) and how it was found (:func:`gearwatch.usecases.tachless.place_in_tooth_frame`)."""
    frame_fingerprints: dict[str, np.ndarray] = field(default_factory=dict)
    """``pinion`` (and ``gear``) tooth fingerprints of this record *in the campaign frame*
    (:mod:`dsp.toothframe`), for the caller to found or refine the campaign's reference."""


@dataclass(frozen=True)
class ChannelQuality:
    """Data quality of one channel of a record (:mod:`dsp.quality`, :mod:`dsp.robust`)."""

    score: float
    """Data-quality score in [0, 1]: the product of ``score_components``. Weights the record's
    evidence in alarm statistics (1 = ideal; 0.5 ≈ a 20-revolution or a 10 dB record)."""
    score_components: dict[str, float]
    """Factors of the score: ``revolutions``, ``sync_to_noise``, ``speed``, ``repairs``, ``rejections``."""
    sync_to_noise_db: float
    """Synchronous power of the pinion average over the non-synchronous power per revolution (dB)."""
    rejected_revolutions: int
    """Pinion revolutions left out of the average (the two next and ``rejected_tach_gap_revolutions``)."""
    rejected_defective_revolutions: int
    """... because they overlap a glitch, dropout or clipped stretch."""
    rejected_outlier_revolutions: int
    """... because their residual peak or energy is an outlier among the revolutions."""
    glitch_samples: int
    """Non-finite samples and samples far outside the record's robust range, bridged."""
    dropout_samples: int
    """Samples in runs of >= 8 exactly equal values (zeros or a held value), bridged."""
    clipped_samples: int
    """Samples in runs of >= 3 at the channel's extreme value, bridged."""
    rejected_tach_gap_revolutions: int = 0
    """Pinion revolutions left out because their angle rests on bridged tach pulses (a burst of
    interference or a gap in the tach signal, :func:`dsp.tach.bridge_unexplained`); counted in
    ``rejected_revolutions``."""


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
    angle_source: Literal["tachometer", "mesh_phase", "none"] = "tachometer"
    """Where the shaft angle came from: the tach channel, the phase of a mesh harmonic
    (:mod:`dsp.tachless`), or nowhere (whole-record raw metrics only)."""
    tach_failure: str = ""
    """Why the tach channel was not used although the manifest declares one (dead, missing…)."""
    tachless: dict[str, Any] | None = None
    """With ``angle_source = "mesh_phase"``: channel, harmonic, mesh line (Hz), its prominence
    (dB), the band envelope's minimum / median, ``pulse_jitter_rev`` (scatter of the synthetic
    pulses about a smooth speed, in revolutions: the phase-noise figure) and the speed variation."""
    per_tooth: str = ""
    """Empty when per-tooth results are given; else why they are not (no angle, refused frame)."""
    tooth_frames: dict[str, dict[str, Any]] = field(default_factory=dict)
    """Per accelerometer channel, :attr:`ChannelAnalysis.tooth_frame`."""
    refused_channels: dict[str, str] = field(default_factory=dict)
    """Accelerometer channels left out of this record, each with its reason (a dead, clipped or
    corrupt sensor): the others are analysed. A record is refused only when every one is."""

    score: float | None = None
    """Data-quality score in [0, 1] of the record: its weakest channel's
    (:class:`ChannelQuality`). Alarm statistics weight the record's evidence by it."""
    score_components: dict[str, float] = field(default_factory=dict)
    sync_to_noise_db: float | None = None
    """Lowest over the channels."""
    revolutions: int | None = None
    """Pinion revolutions averaged (lowest over the channels)."""
    rejected_revolutions: int = 0
    """Pinion revolutions left out (most over the channels)."""
    glitch_samples: int = 0
    dropout_samples: int = 0
    clipped_samples: int = 0
    """Defective samples bridged, summed over the accelerometer channels."""

@dataclass(frozen=True)
class ToothFrameReference:
    """A campaign's tooth-frame reference for one accelerometer channel (see :mod:`dsp.toothframe`).

    Fingerprints are in the *campaign frame*; ``pinion_position`` is where the reference's
    first mesh harmonic peaks in that frame, in mesh periods ([0, 1)): 0 when the campaign
    frame is a tach-less record's canonical frame (``frame = "mesh_phase"``), the measured
    value when it is the tachometer's frame (``frame = "tachometer"``). The gear fingerprint
    is always canonical (the gear's frame is fixed by the reference record, tach or not).
    """

    frame: Literal["tachometer", "mesh_phase"]
    record_sha256: str
    pinion_fingerprint: np.ndarray
    pinion_position: float = 0.0
    gear_fingerprint: np.ndarray | None = None
    records: int = 1
    """How many records the fingerprints average (the first ones aligned with confidence)."""
    speed_rpm: float | None = None
    """The pinion speed of the latest record numbered in this frame (rpm; None: not known). A
    tach-less record of a rig without ``[rig] nominal_pinion_rpm`` looks for its mesh line near
    it (:func:`gearwatch.usecases.shaft_angle.record_shaft_angle`): the speed the campaign's own
    revolutions (or its tachometer) confirmed, instead of the spectrum's guess."""


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
                "tooth_frame": ch.tooth_frame,
                "quality": None if ch.quality is None else dataclasses.asdict(ch.quality),
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
        return finite_json(top)


def finite_json(value: Any) -> Any:
    """``value`` as strict JSON data: NaN and ±inf (which JSON cannot hold) become ``None``,
    numpy scalars and arrays plain Python.

    >>> finite_json({"a": [1.0, float("nan")], "b": np.float32(2.5), "c": float("inf")})
    {'a': [1.0, None], 'b': 2.5, 'c': None}
    """
    if isinstance(value, float):
        return value if np.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite_json(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [finite_json(v) for v in value]
    if isinstance(value, np.ndarray):
        return finite_json(value.tolist())
    if isinstance(value, np.generic):
        return finite_json(value.item())
    return value
