"""The per-record chain: tachometer → shaft angle → synchronous averages → MCI and metrics.

This is the one place that strings the pure numerical core (:mod:`dsp`) together
for a record and a campaign manifest. It does no I/O beyond :func:`analyze_file`
reading the file it is given, and it never touches a database.

Quality checks that refuse a record raise :class:`gearwatch.floor.errors.RecordRejected`
with a one-line reason; the caller stores the record as rejected.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from dsp.angle import angle_grid_times, angle_resample
from dsp.mci import moving_cepstrum_integral
from dsp.metrics import (
    crest_factor,
    envelope_variance,
    extremes_and_moment_sums,
    gear_metrics,
    kurtosis,
    peak,
    rms,
)
from dsp.quality import quality_score, sync_to_noise_db
from dsp.robust import (
    CLIP_MIN_RUN,
    SampleDefects,
    dropout_run_length,
    find_sample_defects,
    glitch_limits,
    repair_spans,
    revolution_outliers,
    revolutions_overlapping,
)
from dsp.tach import (
    RecordOutOfTachLimits,
    TachAnalysis,
    TachometerError,
    analyze_tachometer,
    pulse_times_from_waveform,
    pulse_times_from_waveform_blocks,
)
from dsp.teeth import (
    per_tooth_difference_stats,
    per_tooth_evidence,
    tooth_pitch_angles_deg,
)
from dsp.toothframe import circular_shift
from dsp.toothscore import (
    JACKKNIFE_GROUPS,
    evidence_standard_error,
    leave_one_out_averages,
    standout_threshold,
    standout_tooth,
    tooth_scores,
)
from dsp.tsa import difference_signal, regular_signal, residual_signal
from gearwatch.floor.campaign import Campaign, RecordData
from gearwatch.floor.errors import RecordFormatError, RecordRejected
from gearwatch.floor.results import (
    AnalysisParameters,
    ChannelAnalysis,
    ChannelQuality,
    Provenance,
    Quality,
    RecordAnalysis,
    TachRepairNote,
    ToothFrameReference,
    ToothResult,
)
from gearwatch.floor.version import code_version
from gearwatch.usecases.tachless import (
    NO_HINT_REFUSAL,
    mesh_phase_angle,
    place_in_tooth_frame,
    tach_frame_fingerprints,
)
from gearwatch.usecases.tachless import (
    FramePlacement as _FramePlacement,
)

CLIPPING_MIN_RUN = CLIP_MIN_RUN
"""Consecutive samples at the channel's extreme value that count as a clipped stretch."""
MAX_DEFECTIVE_FRACTION = 0.05
"""A channel with more of its samples defective (glitches, dropouts, clipped stretches) is refused
outright; fewer are bridged and the revolutions they touch dropped."""
MAX_REJECTED_REVOLUTION_FRACTION = 0.5
"""A channel that needs more than this fraction of its pinion revolutions dropped is refused: what
is left would not be a typical average (a sensor clipped on every mesh peak ends up here)."""
MAX_ABS_SAMPLE = 1e12
"""Largest sample magnitude a record may hold (any unit): a 32-bit ADC counts to 2.1e9, no
sensor reads 1e12 m/s² or V. Beyond it fourth moments overflow float64 and averages overflow the
float32 curves. In the tachometer channel such a value is a corrupt file and the record is
rejected with that reason; in an accelerometer channel it is a glitch (always, whatever the
record's range), bridged and counted like any other (:mod:`dsp.robust`)."""
SAMPLE_RATE_TOLERANCE = 1e-3
"""Relative difference between a record's own sample rate and the manifest's that is refused."""
BLOCK_SAMPLES = 1 << 20
"""Longer records are processed in blocks of about this many samples (≈ 52 s at 20 kHz, 21 s at
50 kHz), so that an hour-long record needs a few blocks of memory (~0.1 GB), not several copies
of itself. Shorter records are one block, processed whole."""


@dataclass(frozen=True)
class Baselines:
    """Running baselines passed in explicitly (never hidden in call order).

    ``na4_residual_variance`` and ``nb4_envelope_variance`` are the means of
    :attr:`ChannelAnalysis.baseline_stats` over the earlier records of the run;
    ``None`` makes NA4/NB4 use this record's own variance.
    """

    na4_residual_variance: float | None = None
    nb4_envelope_variance: float | None = None


def analyze_file(
    path: str | Path,
    campaign: Campaign,
    params: AnalysisParameters | None = None,
    baselines: dict[str, Baselines] | None = None,
    tooth_frames: Mapping[str, ToothFrameReference] | None = None,
) -> RecordAnalysis:
    """Read a record file through the reader registry and run :func:`analyze_record` on it."""
    from ingest.sources import file_sha256, read_record

    record = read_record(path, campaign)
    return analyze_record(
        record, campaign, params, input_sha256=file_sha256(path), baselines=baselines,
        tooth_frames=tooth_frames,
    )


def analyze_record(
    record: RecordData,
    campaign: Campaign,
    params: AnalysisParameters | None = None,
    *,
    input_sha256: str,
    baselines: dict[str, Baselines] | None = None,
    block_samples: int = BLOCK_SAMPLES,
    tooth_frames: Mapping[str, ToothFrameReference] | None = None,
) -> RecordAnalysis:
    """Run the whole chain on one record; one :class:`ChannelAnalysis` per accelerometer channel.

    Parameters
    ----------
    record
        Samples as read from a file or assembled from CAN frames.
    campaign
        The manifest: tooth counts, ``tooth1_pitch_angle_deg``, tachometer set-up, channels.
    params
        Analysis parameters (stored with the result as its provenance).
    input_sha256
        sha256 of the raw file (or of the raw frames) the record came from.
    baselines
        Running NA4/NB4 baselines per accelerometer channel name.
    block_samples
        Records longer than this are processed block by block (:data:`BLOCK_SAMPLES`); the
        results agree with whole-record processing to rounding (tested).
    tooth_frames
        Only for records without a usable tachometer: the campaign's tooth-frame reference
        per channel (:func:`place_in_tooth_frame`). ``None``: the tooth numbers stay in the
        record's own frame (said so in ``tooth_frame``); a mapping without the channel: this
        record founds the campaign's frame; a refused alignment drops the per-tooth results.

    Raises
    ------
    RecordRejected
        The record fails a quality check (tachometer, speed, revolutions, NaN/inf, clipping).
    RecordFormatError
        A channel named by the manifest is missing.
    """
    params = params or AnalysisParameters()
    baselines = baselines or {}
    sample_rate_hz = float(record.sample_rate_hz)
    if not np.isfinite(sample_rate_hz) or sample_rate_hz <= 0:
        raise RecordFormatError(f"{record.source or 'record'}: invalid sample rate {sample_rate_hz!r}")
    declared = campaign.sample_rate_hz
    if declared and abs(sample_rate_hz - declared) > SAMPLE_RATE_TOLERANCE * declared:
        # A file carries its own rate; one that disagrees with the rig's DAQ set-up is a wrong
        # rate or a wrong manifest, and either would scale every speed and frequency silently.
        raise RecordRejected(
            f"sample rate {sample_rate_hz:g} Hz differs from the manifest's "
            f"[acquisition] sample_rate_hz = {declared:g} Hz"
        )

    rig = campaign.rig
    pinion_teeth, gear_teeth = rig.pinion_teeth, rig.gear_teeth
    has_teeth = bool(pinion_teeth and gear_teeth)
    accelerometers = campaign.accelerometer_channels
    if not accelerometers:
        raise RecordFormatError("the manifest declares no accelerometer channel")
    # every channel's checks before any heavy work: a bad channel rejects the record at once
    scans = {channel.name: _checked_signal(record, channel.name, block_samples, params)
             for channel in accelerometers}
    shaft = _shaft_angle(record, campaign, params, sample_rate_hz, block_samples, scans)
    if isinstance(shaft, str):
        return _raw_metrics_only(shaft, scans, campaign, params, input_sha256)
    tach, pinion_per_tach_rev = shaft.tach, shaft.pinion_per_tach_rev
    channels = [
        _analyze_channel(
            name=channel.name,
            signal=scans[channel.name],
            sample_rate_hz=sample_rate_hz,
            tach=tach,
            campaign=campaign,
            params=params,
            has_teeth=has_teeth,
            pinion_per_tach_rev=pinion_per_tach_rev,
            baselines=baselines.get(channel.name, Baselines()),
            block_samples=block_samples,
            tach_on_pinion=shaft.tach_on_pinion,
            frame_placement=(
                None if shaft.source == "tachometer"
                else _FramePlacement(
                    reference=None if tooth_frames is None else tooth_frames.get(channel.name),
                    campaign_mode=tooth_frames is not None,
                    record_sha256=input_sha256,
                    refusal=(NO_HINT_REFUSAL if (shaft.tachless or {}).get("speed_from") == "spectrum"
                             else ""),
                )
            ),
        )
        for channel in accelerometers
    ]
    pinion_rpm = tach.mean_rpm * pinion_per_tach_rev
    quality = Quality(
        tach_repairs=[TachRepairNote(kind=r.kind, time_s=float(r.time_s)) for r in tach.repairs],
        speed_variation=float(tach.speed_variation),
        speed_min_rpm=float(tach.min_rpm * pinion_per_tach_rev),
        speed_max_rpm=float(tach.max_rpm * pinion_per_tach_rev),
        clipped_fraction=max(scan.clipped_fraction for scan in scans.values()),
        angle_source=shaft.source,
        tach_failure=shaft.tach_failure,
        tachless=shaft.tachless,
        per_tooth=next((c.tooth_frame["reason"] for c in channels
                        if c.tooth_frame.get("kind") == "refused"), ""),
        tooth_frames={c.channel: c.tooth_frame for c in channels},
    )
    quality = _with_channel_quality(quality, channels)
    provenance = _provenance(campaign, params, input_sha256)
    first = channels[0]
    return RecordAnalysis(
        channels=channels,
        quality=quality,
        provenance=provenance,
        speed_rpm=float(pinion_rpm),
        revolutions=first.revolutions,
        samples_per_rev=first.samples_per_rev,
    )


def _provenance(
    campaign: Campaign, params: AnalysisParameters, input_sha256: str
) -> Provenance:
    rig = campaign.rig
    return Provenance(
        input_sha256=input_sha256,
        code_version=code_version(),
        parameters={
            **params.to_dict(),
            "pinion_teeth": rig.pinion_teeth,
            "gear_teeth": rig.gear_teeth,
            "tooth1_pitch_angle_deg": rig.tooth1_pitch_angle_deg,
            "tachometer": dataclasses.asdict(campaign.tachometer) if campaign.tachometer else None,
        },
    )


def _with_channel_quality(quality: Quality, channels: list[ChannelAnalysis]) -> Quality:
    """Record-level quality completed from the channels': the weakest channel's score and
    rejections, the defective samples summed over channels."""
    qualities = [ch.quality for ch in channels if ch.quality is not None]
    if not qualities:
        return quality
    weakest = min(qualities, key=lambda q: q.score)
    return dataclasses.replace(
        quality,
        score=weakest.score,
        score_components=dict(weakest.score_components),
        sync_to_noise_db=min(q.sync_to_noise_db for q in qualities),
        revolutions=min(ch.revolutions for ch in channels),
        rejected_revolutions=max(q.rejected_revolutions for q in qualities),
        glitch_samples=sum(q.glitch_samples for q in qualities),
        dropout_samples=sum(q.dropout_samples for q in qualities),
        clipped_samples=sum(q.clipped_samples for q in qualities),
    )


def _pinion_revs_per_tach_rev(campaign: Campaign) -> float:
    """Pinion revolutions per revolution of the shaft that carries the tachometer."""
    rig = campaign.rig
    shaft = campaign.tachometer.shaft if campaign.tachometer else "pinion"
    if not (rig.pinion_teeth and rig.gear_teeth):
        # Without tooth counts only the tach shaft itself can be averaged; call it the pinion.
        return 1.0
    return 1.0 if shaft == "pinion" else rig.gear_teeth / rig.pinion_teeth


@dataclass(frozen=True)
class _ShaftAngle:
    """The record's shaft angle: tach pulses, or synthetic pulses from the mesh phase."""

    tach: TachAnalysis
    pinion_per_tach_rev: float
    tach_on_pinion: bool
    source: Literal["tachometer", "mesh_phase"]
    tach_failure: str = ""
    tachless: dict[str, Any] | None = None


def _shaft_angle(
    record: RecordData,
    campaign: Campaign,
    params: AnalysisParameters,
    sample_rate_hz: float,
    block_samples: int,
    scans: Mapping[str, _ScannedSignal],
) -> _ShaftAngle | str:
    """The tach when it works; else the mesh phase when the tooth counts allow; else the reason.

    A dead, missing or unusable tach channel does not lose the record: the angle comes from
    the mesh phase instead (:func:`gearwatch.usecases.tachless.mesh_phase_angle`) and ``quality`` says why.
    """
    tach_failure = ""
    if campaign.tachometer is not None:
        try:
            return _ShaftAngle(
                tach=_analyze_tach(record, campaign, params, sample_rate_hz, block_samples),
                pinion_per_tach_rev=_pinion_revs_per_tach_rev(campaign),
                tach_on_pinion=campaign.tachometer.shaft == "pinion",
                source="tachometer",
            )
        except _RefusedWithAWorkingTach:
            raise
        except (RecordRejected, RecordFormatError) as error:
            tach_failure = " ".join(str(error).split())
    else:
        tach_failure = "the manifest has no [tachometer]"
    rig = campaign.rig
    if not (rig.pinion_teeth and rig.gear_teeth):
        return (
            f"no shaft angle: {tach_failure}, and without tooth counts ([rig] pinion_teeth, "
            "gear_teeth) the mesh phase cannot stand in for it"
        )
    mesh = mesh_phase_angle(
        {name: scan.samples for name, scan in scans.items()},
        sample_rate_hz, rig.pinion_teeth, rig.gear_teeth, params,
        nominal_pinion_rpm=rig.nominal_pinion_rpm,
    )
    if isinstance(mesh, str):
        return f"no shaft angle: {tach_failure}; mesh phase: {mesh}"
    return _ShaftAngle(
        tach=mesh.tach, pinion_per_tach_rev=1.0, tach_on_pinion=True, source="mesh_phase",
        tach_failure=tach_failure if campaign.tachometer is not None else "",
        tachless=mesh.summary,
    )


class _RefusedWithAWorkingTach(RecordRejected):
    """The tach measured the record itself failing (:class:`dsp.tach.RecordOutOfTachLimits`), or
    its channel holds impossible values (a broken acquisition, not a dead tach): the mesh phase
    would not rescue the record, so it is refused instead of analysed without the tach."""


def _raw_metrics_only(
    reason: str,
    scans: Mapping[str, _ScannedSignal],
    campaign: Campaign,
    params: AnalysisParameters,
    input_sha256: str,
) -> RecordAnalysis:
    """A record with no usable shaft angle keeps its whole-record raw metrics (trends go on).

    No revolutions, no averages, no per-tooth results; ``quality.angle_source`` is ``none``
    and ``quality.per_tooth`` says why. Speeds are 0: unknown, not measured.
    """
    channels = [
        ChannelAnalysis(
            channel=name, revolutions=0, gear_revolutions=0, speed_rpm=0.0, samples_per_rev=0,
            metrics=dict(scan.raw_metrics),
            tooth_frame={"kind": "none", "reason": reason},
        )
        for name, scan in scans.items()
    ]
    quality = Quality(
        tach_repairs=[], speed_variation=0.0, speed_min_rpm=0.0, speed_max_rpm=0.0,
        clipped_fraction=max(scan.clipped_fraction for scan in scans.values()),
        angle_source="none",
        tach_failure=reason,
        per_tooth=reason,
        tooth_frames={c.channel: c.tooth_frame for c in channels},
    )
    return RecordAnalysis(
        channels=channels, quality=quality,
        provenance=_provenance(campaign, params, input_sha256),
        speed_rpm=0.0, revolutions=0, samples_per_rev=0,
    )


def _analyze_tach(
    record: RecordData,
    campaign: Campaign,
    params: AnalysisParameters,
    sample_rate_hz: float,
    block_samples: int,
) -> TachAnalysis:
    config = campaign.tachometer
    if config is None:
        raise RecordRejected(
            "the manifest has no [tachometer]: synchronous averaging needs a once-per-revolution reference"
        )
    raw = record.channel(config.channel)
    try:
        _refuse_impossible_magnitudes(raw, f"tachometer channel {config.channel!r}", block_samples)
    except RecordRejected as error:
        raise _RefusedWithAWorkingTach(str(error)) from error
    try:
        if config.kind == "pulses" and raw.size > block_samples:
            # NaN/inf are refused block by block inside
            pulse_times_s = pulse_times_from_waveform_blocks(
                raw, sample_rate_hz, block_samples=block_samples
            )
        else:
            raw = np.asarray(raw, dtype=np.float64)
            if not np.all(np.isfinite(raw)):
                raise RecordRejected(
                    f"tachometer channel {config.channel!r} contains NaN or inf samples"
                )
            pulse_times_s = (
                pulse_times_from_waveform(raw, sample_rate_hz) if config.kind == "pulses" else raw
            )
        return analyze_tachometer(
            pulse_times_s,
            config.pulses_per_rev,
            max_speed_variation=params.max_speed_variation,
            min_revolutions=params.min_revolutions,
            min_speed_rpm=params.min_speed_rpm,
            max_speed_rpm=params.max_speed_rpm,
        )
    except RecordOutOfTachLimits as error:
        raise _RefusedWithAWorkingTach(f"tachometer: {error}") from error
    except TachometerError as error:
        raise RecordRejected(f"tachometer: {error}") from error


def _refuse_impossible_magnitudes(samples: np.ndarray, what: str, block_samples: int) -> None:
    """:class:`RecordRejected` when a finite sample exceeds :data:`MAX_ABS_SAMPLE` (NaN and
    inf have their own checks); block by block, at the stored dtype."""
    for start in range(0, samples.size, block_samples):
        block = np.asarray(samples[start : start + block_samples])
        if block.size == 0 or not np.issubdtype(block.dtype, np.number):
            continue
        magnitudes = np.abs(block[np.isfinite(block)]) if block.dtype.kind == "f" else np.abs(block)
        peak = float(magnitudes.max()) if magnitudes.size else 0.0
        if peak > MAX_ABS_SAMPLE:
            raise RecordRejected(
                f"{what} holds a sample of magnitude {peak:.3g}, beyond any sensor's range "
                f"(limit {MAX_ABS_SAMPLE:g}): a corrupt file"
            )


@dataclass(frozen=True)
class _ScannedSignal:
    """A channel that passed the checks, with its raw-signal metrics and defective stretches."""

    samples: np.ndarray
    """The channel as read (possibly float32, possibly memory-mapped): convert per block."""
    raw_metrics: dict[str, float]
    clipped_fraction: float
    defects: SampleDefects
    """Glitches, dropouts and clipped stretches (record sample indices), bridged before
    resampling; the revolutions they touch are left out of the averages."""


def _checked_signal(
    record: RecordData, name: str, block_samples: int, params: AnalysisParameters
) -> _ScannedSignal:
    """Find defective samples; compute ``raw_rms`` and ``raw_kurtosis`` without them; block by block.

    Pass 1 finds the glitches (non-finite samples and samples far outside the record's robust
    range, :func:`dsp.robust.glitch_limits`) and the channel's extremes without them; pass 2 finds
    the clipped runs at those extremes and the dropouts, bridges every defective stretch
    (:func:`dsp.robust.repair_spans`) and accumulates the moments in one pass per block
    (:func:`dsp.metrics.extremes_and_moment_sums`) about the mean of the first good samples
    (numerically safe for a signal whose mean does not wander by many standard deviations). A run
    split by a block boundary counts as two (at most a few samples per 1-million-sample block).
    A channel with more than :data:`MAX_DEFECTIVE_FRACTION` of its samples defective is refused.
    """
    samples = record.channel(name)
    if samples.ndim != 1 or samples.size == 0:
        raise RecordFormatError(f"channel {name!r} must be a non-empty 1-D signal")
    starts = range(0, samples.size, block_samples)
    lo, hi = glitch_limits(samples, params.glitch_range_factor)
    limits = (max(lo, -MAX_ABS_SAMPLE), min(hi, MAX_ABS_SAMPLE))
    dropout_run = dropout_run_length(samples)
    top, bottom = -np.inf, np.inf
    for start in starts:
        block = np.asarray(samples[start : start + block_samples], dtype=np.float64)
        good = block[np.isfinite(block) & (block >= limits[0]) & (block <= limits[1])]
        if good.size:
            top, bottom = max(top, float(good.max())), min(bottom, float(good.min()))
    if not np.isfinite(top):
        raise RecordRejected(f"channel {name!r} holds no valid sample (all NaN, inf or glitches)")
    parts: list[SampleDefects] = []
    shift = None
    sums = np.zeros(4)
    for start in starts:
        block = np.asarray(samples[start : start + block_samples], dtype=np.float64)
        defects = find_sample_defects(
            block, limits=limits, extremes=(bottom, top), dropout_min_run=dropout_run
        )
        repaired = repair_spans(block, defects.spans())
        if shift is None:  # moments about a value near the mean, so that the sums do not cancel
            shift = float(np.mean(repaired[:1024]))
        sums += extremes_and_moment_sums(repaired, shift)[2]
        parts.append(defects.shifted(start))
    defects = SampleDefects.concatenate(parts)
    counts = defects.counts()
    defective = sum(counts.values())
    if defective > MAX_DEFECTIVE_FRACTION * samples.size:
        what = ", ".join(f"{n} {k.removesuffix('_samples')}" for k, n in counts.items() if n)
        raise RecordRejected(
            f"channel {name!r} has {defective / samples.size:.2%} defective samples ({what}): "
            + ("the sensor is clipped" if counts["clipped_samples"] * 2 > defective
               else "the data are corrupt")
        )
    return _ScannedSignal(
        samples,
        _raw_moments_metrics(sums / samples.size),
        counts["clipped_samples"] / samples.size,
        defects,
    )


def _raw_moments_metrics(shifted_means: np.ndarray) -> dict[str, float]:
    """``raw_rms`` (about the mean) and ``raw_kurtosis`` from E[y], E[y²], E[y³], E[y⁴] of y = x − c."""
    d, m2_raw, m3_raw, m4_raw = (float(v) for v in shifted_means)
    variance = max(m2_raw - d * d, 0.0)
    fourth = m4_raw - 4 * d * m3_raw + 6 * d * d * m2_raw - 3 * d**4
    kurt = fourth / variance**2 if variance > 0 and fourth > 0 else 0.0
    return {"raw_rms": float(np.sqrt(variance)), "raw_kurtosis": float(kurt)}


def clipped_fraction(
    signal: np.ndarray,
    min_run: int = CLIPPING_MIN_RUN,
    extremes: tuple[float, float] | None = None,
) -> float:
    """Fraction of samples in runs of ≥ ``min_run`` consecutive samples equal to the signal's max or min.

    A clipped sensor or a saturated ADC holds its extreme value; a healthy analogue signal
    touches its extreme once. ``extremes`` = (min, max) when the caller already has them.

    Examples
    --------
    >>> import numpy as np
    >>> clipped_fraction(np.array([0.0, 1.0, 1.0, 1.0, 0.5, -1.0, 0.0, 0.2]))
    0.375
    """
    if signal.size < min_run:
        return 0.0
    bottom, top = extremes if extremes is not None else (signal.min(), signal.max())
    if top == bottom:
        return 1.0  # a constant (dead or pegged) channel
    clipped = 0
    for value in (top, bottom):
        at = np.flatnonzero(signal == value)  # few samples unless the channel is clipped
        if at.size < min_run:
            continue
        breaks = np.flatnonzero(np.diff(at) != 1)
        lengths = np.diff(np.concatenate(([-1], breaks, [at.size - 1])))
        clipped += int(lengths[lengths >= min_run].sum())
    return clipped / signal.size


def gear_revolutions_from_pinion_grid(pinion_revs: np.ndarray, gear_samples_per_rev: int) -> np.ndarray:
    """Regroup pinion-angle samples into gear revolutions, without resampling again.

    With the same number of samples per mesh period on both wheels, a gear revolution of
    ``gear_teeth × samples_per_mesh`` samples spans exactly the same angle steps as the pinion grid
    (one step = 1/samples_per_mesh of a mesh period), and both grids start at the tach reference
    edge. So the gear's synchronous average is the pinion-grid series cut into gear revolutions:
    exactly what a second resampling would give, at half the cost. The incomplete last gear
    revolution is dropped.
    """
    flat = pinion_revs.reshape(-1)
    whole = flat.size // gear_samples_per_rev
    return flat[: whole * gear_samples_per_rev].reshape(whole, gear_samples_per_rev)


@dataclass(frozen=True)
class _AngleAverages:
    pinion_average: np.ndarray
    pinion_revolutions: int
    """Pinion revolutions in the average (after rejection)."""
    gear_average: np.ndarray
    gear_revolutions: int
    rejected_defective: int
    """Pinion revolutions dropped because they overlap a defective (bridged) stretch."""
    rejected_outliers: int
    """Pinion revolutions dropped by the outlier test (:func:`dsp.robust.revolution_outliers`)."""
    residual_power: float
    """Mean power of the accepted revolutions about the average (non-synchronous power per
    revolution), ``Σ_i mean((rev_i − avg)²) / (N − 1)``."""
    pinion_group_sums: np.ndarray
    """(JACKKNIFE_GROUPS, pinion_spr): sums of the accepted pinion revolutions r with
    r mod K = group (the jackknife SE of the tooth evidence, :mod:`dsp.toothscore`)."""
    pinion_group_counts: np.ndarray


def _revolution_bounds_s(
    pulses: np.ndarray, pulses_per_rev: int, shaft_ratio: float, duration_s: float
) -> np.ndarray:
    """Start and end time of each whole target-shaft revolution, on the same phase model as
    :func:`dsp.angle.angle_resample` (a coarse grid of 16 angles per revolution)."""
    times = angle_grid_times(
        pulses, pulses_per_rev, 16, shaft_ratio=shaft_ratio, record_duration_s=duration_s
    )
    if times.shape[0] == 0:
        return np.empty((0, 2))
    step = times[:, -1] - times[:, -2]
    return np.stack([times[:, 0], times[:, -1] + step], axis=1)


def _angle_averages(
    samples: np.ndarray,
    sample_rate_hz: float,
    pulse_times_s: np.ndarray,
    pulses_per_rev: int,
    pinion_spr: int,
    gear_spr: int,
    pinion_per_tach_rev: float,
    hunting_tach_revs: int,
    block_samples: int,
    defects: SampleDefects,
    outlier_factor: float,
) -> _AngleAverages:
    """Pinion and gear synchronous averages, the record resampled one block at a time.

    A record of at most ``block_samples`` (in tach revolutions' worth) is resampled whole.
    A longer one is cut into blocks of whole hunting periods (``hunting_tach_revs`` tach
    revolutions, after which both wheels are back at their starting teeth), so every block
    holds whole pinion AND whole gear revolutions on the common grid. Each block is resampled
    with one hunting period of context on each side — pulses for the phase model and signal for
    the interpolator and anti-alias filter — and only its own revolutions are kept, so block
    edges do not show; the sums of the revolutions are accumulated and the resampled record
    never exists whole.

    Robustness: the ``defects`` stretches are bridged before resampling, the pinion revolutions
    that overlap one (± the interpolator's reach) are dropped, and so are the outliers among the
    rest of the block (:func:`dsp.robust.revolution_outliers`, against the block's own per-angle
    median). A gear revolution is dropped when any of its samples lies in a dropped pinion
    revolution.
    """
    whole_tach_revs = (pulse_times_s.size - 1) // pulses_per_rev
    seconds_per_tach_rev = (pulse_times_s[-1] - pulse_times_s[0]) / max(
        (pulse_times_s.size - 1) / pulses_per_rev, 1e-12
    )
    samples_per_hunting = hunting_tach_revs * seconds_per_tach_rev * sample_rate_hz
    block_tach_revs = hunting_tach_revs * max(1, int(block_samples // max(samples_per_hunting, 1)))
    pinion_sum = np.zeros(pinion_spr)
    pinion_sumsq = np.zeros(pinion_spr)
    gear_sum = np.zeros(gear_spr)
    pinion_count = gear_count = rejected_defective = rejected_outliers = 0
    spans = defects.spans()
    margin_s = 4.0 / sample_rate_hz  # the quintic spline's stencil reaches 3 samples
    # jackknife groups: accepted revolution r (counted over the record) goes to group r mod K
    group_sums = np.zeros((JACKKNIFE_GROUPS, pinion_spr))
    group_counts = np.zeros(JACKKNIFE_GROUPS, dtype=np.int64)
    if whole_tach_revs <= block_tach_revs + hunting_tach_revs:
        plan = [(0, whole_tach_revs, True)]
    else:
        edges = list(range(0, whole_tach_revs, block_tach_revs))
        plan = [(r0, min(r0 + block_tach_revs, whole_tach_revs), r0 == edges[-1]) for r0 in edges]
    for first_rev, end_rev, last in plan:
        if len(plan) == 1:
            start, stop = 0, samples.size
            block_pulses, skip_pinion_revs = pulse_times_s, 0
        else:
            context_rev = max(0, first_rev - hunting_tach_revs)
            first_pulse = context_rev * pulses_per_rev
            last_pulse = min(pulse_times_s.size - 1, (end_rev + hunting_tach_revs) * pulses_per_rev)
            start = max(0, int(np.floor(pulse_times_s[first_pulse] * sample_rate_hz)) - 16)
            stop = min(samples.size, int(np.ceil(pulse_times_s[last_pulse] * sample_rate_hz)) + 16)
            block_pulses = pulse_times_s[first_pulse : last_pulse + 1] - start / sample_rate_hz
            skip_pinion_revs = round((first_rev - context_rev) * pinion_per_tach_rev)
        block_spans = spans[(spans[:, 1] > start) & (spans[:, 0] < stop)] - start
        block = repair_spans(np.asarray(samples[start:stop], dtype=np.float64), block_spans)
        revs = angle_resample(
            block, sample_rate_hz, block_pulses, pulses_per_rev, pinion_spr,
            shaft_ratio=pinion_per_tach_rev,
        )
        bounds = _revolution_bounds_s(
            block_pulses, pulses_per_rev, pinion_per_tach_rev, (block.size - 1) / sample_rate_hz
        )[: revs.shape[0]]
        keep = None if last else round((end_rev - first_rev) * pinion_per_tach_rev)
        revs = revs[skip_pinion_revs:][:keep]
        touched = revolutions_overlapping(
            bounds[skip_pinion_revs:][:keep], block_spans / sample_rate_hz, margin_s
        )
        outliers = np.zeros_like(touched)
        outliers[~touched] = revolution_outliers(revs[~touched], outlier_factor)
        accepted = ~(touched | outliers)
        rejected_defective += int(touched.sum())
        rejected_outliers += int(outliers.sum())
        good = revs[accepted]
        pinion_sum += good.sum(axis=0)
        pinion_sumsq += np.einsum("ij,ij->j", good, good)
        groups = (pinion_count + np.arange(good.shape[0])) % JACKKNIFE_GROUPS
        np.add.at(group_sums, groups, good)
        np.add.at(group_counts, groups, 1)
        pinion_count += good.shape[0]
        gear_revs = gear_revolutions_from_pinion_grid(revs, gear_spr)
        sample_ok = np.repeat(accepted, pinion_spr)[: gear_revs.size].reshape(gear_revs.shape)
        gear_good = gear_revs[sample_ok.all(axis=1)]
        gear_sum += gear_good.sum(axis=0)
        gear_count += gear_good.shape[0]
    pinion_average = pinion_sum / max(pinion_count, 1)
    residual_power = (
        float(np.mean(pinion_sumsq - pinion_count * pinion_average**2)) / (pinion_count - 1)
        if pinion_count > 1
        else 0.0
    )
    return _AngleAverages(
        pinion_average,
        pinion_count,
        gear_sum / max(gear_count, 1),
        gear_count,
        rejected_defective,
        rejected_outliers,
        max(residual_power, 0.0),
        group_sums,
        group_counts,
    )


def _analyze_channel(
    *,
    name: str,
    signal: _ScannedSignal,
    sample_rate_hz: float,
    tach: TachAnalysis,
    campaign: Campaign,
    params: AnalysisParameters,
    has_teeth: bool,
    pinion_per_tach_rev: float,
    baselines: Baselines,
    block_samples: int,
    tach_on_pinion: bool = True,
    frame_placement: _FramePlacement | None = None,
) -> ChannelAnalysis:
    rig = campaign.rig
    ppr = tach.pulses_per_rev
    pulse_times_s = tach.pulse_times_s
    if has_teeth:
        assert rig.pinion_teeth is not None and rig.gear_teeth is not None
        pinion_spr = rig.pinion_teeth * params.samples_per_mesh
        gear_spr = rig.gear_teeth * params.samples_per_mesh
        # tach-shaft revolutions after which both wheels are back on their starting teeth
        common = math.gcd(rig.pinion_teeth, rig.gear_teeth)
        hunting_tach_revs = (rig.gear_teeth if tach_on_pinion else rig.pinion_teeth) // common
    else:
        pinion_spr = gear_spr = params.samples_per_rev_without_teeth
        hunting_tach_revs = 1
    try:
        angle = _angle_averages(
            signal.samples, sample_rate_hz, pulse_times_s, ppr, pinion_spr, gear_spr,
            pinion_per_tach_rev, hunting_tach_revs, block_samples,
            signal.defects, params.revolution_outlier_factor,
        )
    except ValueError as error:  # e.g. pulse times outside the record: tach and signal disagree
        raise RecordRejected(f"channel {name!r}: cannot resample to shaft angle: {error}") from error
    revolutions = angle.pinion_revolutions
    rejected = angle.rejected_defective + angle.rejected_outliers
    counts = signal.defects.counts()
    if rejected > MAX_REJECTED_REVOLUTION_FRACTION * (revolutions + rejected):
        what = ", ".join(f"{n} {k.removesuffix('_samples')}" for k, n in counts.items() if n)
        cause = (
            "the sensor is clipped" if counts["clipped_samples"] * 2 > sum(counts.values())
            else f"defective samples ({what})" if angle.rejected_defective
            else "non-repeating content"
        )
        raise RecordRejected(
            f"channel {name!r}: {rejected} of {revolutions + rejected} pinion revolutions rejected "
            f"({angle.rejected_defective} with defective samples, {angle.rejected_outliers} "
            f"outliers): {cause}"
        )
    if revolutions < params.min_revolutions:
        raise RecordRejected(
            f"only {revolutions} whole pinion revolutions (minimum {params.min_revolutions})"
            + (f"; {rejected} rejected" if rejected else "")
        )
    average = angle.pinion_average
    snr_db = sync_to_noise_db(float(np.var(average)), angle.residual_power, revolutions)
    score = quality_score(
        revolutions=revolutions,
        sync_to_noise_db=snr_db,
        speed_variation=tach.speed_variation,
        tach_repairs=len(tach.repairs),
        rejected_revolutions=rejected,
    )
    quality = ChannelQuality(
        score=score.score,
        score_components=score.components(),
        sync_to_noise_db=snr_db,
        rejected_revolutions=rejected,
        rejected_defective_revolutions=angle.rejected_defective,
        rejected_outlier_revolutions=angle.rejected_outliers,
        **counts,
    )
    curves: dict[str, np.ndarray] = {
        "pinion_average": average.astype(np.float32),
        "speed_rpm": (tach.rev_speed_rpm * pinion_per_tach_rev).astype(np.float32),
    }

    raw_metrics = signal.raw_metrics
    if not has_teeth:
        metrics = {
            "rms": float(rms(average)),
            "peak": float(peak(average)),
            "crest": float(crest_factor(average)),
            "kurtosis": float(kurtosis(average)),
            **raw_metrics,
        }
        return ChannelAnalysis(
            channel=name,
            revolutions=revolutions,
            gear_revolutions=revolutions,
            speed_rpm=float(tach.mean_rpm * pinion_per_tach_rev),
            samples_per_rev=pinion_spr,
            metrics=metrics,
            curves=curves,
            quality=quality,
        )

    assert rig.pinion_teeth is not None and rig.gear_teeth is not None
    pinion_teeth = rig.pinion_teeth
    gear_average = angle.gear_average
    tooth1_pitch_angle_deg = rig.tooth1_pitch_angle_deg
    tooth_frame: dict[str, Any] = {"kind": "tachometer"}
    fingerprints: dict[str, np.ndarray] = {}
    frame_delay = 0.0  # the shift that placed the average in the tooth frame (tachless)
    if frame_placement is None:
        fingerprints = tach_frame_fingerprints(average, gear_average, pinion_teeth, rig.gear_teeth)
    else:
        placed = place_in_tooth_frame(
            average, gear_average, pinion_teeth, rig.gear_teeth, frame_placement,
            tach_tooth1_pitch_angle_deg=rig.tooth1_pitch_angle_deg,
        )
        average, gear_average = placed.pinion_average, placed.gear_average
        tooth1_pitch_angle_deg, tooth_frame = placed.tooth1_pitch_angle_deg, placed.tooth_frame
        fingerprints = placed.fingerprints
        frame_delay = placed.pinion_delay_samples
        curves["pinion_average"] = average.astype(np.float32)
    regular = regular_signal(average, pinion_teeth, sidebands=params.difference_sidebands)
    residual = residual_signal(average, pinion_teeth)
    difference = difference_signal(average, pinion_teeth, sidebands=params.difference_sidebands)

    window = params.mci_window_samples or params.samples_per_mesh
    mci = moving_cepstrum_integral(
        average, window, form=params.mci_form, median_width=params.mci_median_width
    )
    evidence, evidence_se, scores = _tooth_evidence(
        angle, mci.filtered, pinion_teeth, tooth1_pitch_angle_deg, window, params, frame_delay
    )
    depths = np.maximum(evidence, 0.0)  # the displayed well depth (dsp.teeth.per_tooth_well_depth)
    energy, sector_kurtosis = per_tooth_difference_stats(
        difference, pinion_teeth, tooth1_pitch_angle_deg
    )
    pitch_angles = tooth_pitch_angles_deg(pinion_teeth, tooth1_pitch_angle_deg)
    teeth = [
        ToothResult(
            tooth=k + 1,
            pitch_angle_deg=float(pitch_angles[k]),
            mci_depth=float(depths[k]),
            mci_depth_se=float(evidence_se[k]),
            score=float(scores[k]),
            diff_energy=float(energy[k]),
            diff_kurtosis=float(sector_kurtosis[k]),
        )
        for k in range(pinion_teeth)
    ]
    per_tooth_refused = tooth_frame.get("kind") == "refused"
    average_metrics = gear_metrics(
        average,
        residual,
        difference,
        regular,
        pinion_teeth,
        na4_baseline_variance=baselines.na4_residual_variance,
        nb4_baseline_variance=baselines.nb4_envelope_variance,
    )
    metrics = {key: float(value) for key, value in average_metrics.items()} | raw_metrics
    curves.update(
        {
            "gear_average": gear_average.astype(np.float32),
            "difference": difference.astype(np.float32),
            "mci_raw": mci.raw.astype(np.float32),
            "mci": mci.filtered.astype(np.float32),
        }
    )
    return ChannelAnalysis(
        channel=name,
        revolutions=revolutions,
        gear_revolutions=angle.gear_revolutions,
        speed_rpm=float(tach.mean_rpm * pinion_per_tach_rev),
        samples_per_rev=pinion_spr,
        metrics=metrics,
        # a refused tooth frame: the numbers would name the wrong teeth in the campaign's trends
        teeth=[] if per_tooth_refused else teeth,
        worst_tooth=(
            None if per_tooth_refused else standout_tooth(scores, standout_threshold(pinion_teeth))
        ),
        curves=curves,
        quality=quality,
        baseline_stats={
            "residual_variance": float(np.var(residual)),
            "envelope_variance": float(envelope_variance(average, pinion_teeth)),
        },
        tooth_frame=tooth_frame,
        frame_fingerprints=fingerprints,
    )


def _tooth_evidence(
    angle: _AngleAverages,
    mci_filtered: np.ndarray,
    pinion_teeth: int,
    tooth1_pitch_angle_deg: float,
    window: int,
    params: AnalysisParameters,
    frame_delay_samples: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-tooth MCI evidence, its jackknife SE and the score (:mod:`dsp.toothscore`).

    The evidence of the whole average is :func:`dsp.teeth.per_tooth_evidence` of the curve the
    record reports; the SE comes from the same chain on the leave-one-group-out averages, moved
    by the same ``frame_delay_samples`` as the average (a tooth frame placed without a
    tachometer). With fewer accepted revolutions than groups the SE is NaN and the score uses
    the SE floor.
    """
    evidence = per_tooth_evidence(
        mci_filtered, pinion_teeth, tooth1_pitch_angle_deg, window_samples=window
    )
    counts = angle.pinion_group_counts
    if np.any(counts == 0):
        se = np.full(pinion_teeth, np.nan)
    else:
        leave_one_out = leave_one_out_averages(angle.pinion_group_sums, counts)
        if frame_delay_samples:
            leave_one_out = np.stack(
                [circular_shift(row, frame_delay_samples) for row in leave_one_out]
            )
        replicates = moving_cepstrum_integral(
            leave_one_out, window, form=params.mci_form, median_width=params.mci_median_width
        )
        se = evidence_standard_error(
            per_tooth_evidence(
                replicates.filtered, pinion_teeth, tooth1_pitch_angle_deg, window_samples=window
            )
        )
    if not np.any(np.isfinite(se)):
        return evidence, se, np.full(pinion_teeth, np.nan)  # no SE, no score (nor worst tooth)
    return evidence, se, tooth_scores(evidence, se)
