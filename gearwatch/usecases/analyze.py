"""The per-record chain: tachometer → shaft angle → synchronous averages → MCI and metrics.

This is the one place that strings the pure numerical core (:mod:`dsp`) together
for a record and a campaign manifest. It does no I/O beyond :func:`analyze_file`
reading the file it is given, and it never touches a database. Its steps live beside it:
:mod:`~gearwatch.usecases.signal_checks` (a channel's checks and raw metrics),
:mod:`~gearwatch.usecases.shaft_angle` (tachometer or mesh phase),
:mod:`~gearwatch.usecases.angle_averages` (the synchronous averages, block by block) and
:mod:`~gearwatch.usecases.tachless` (the tooth frame without a tach); their public names are
importable from here too.

Quality checks that refuse a record raise :class:`gearwatch.floor.errors.RecordRejected`
with a one-line reason; the caller stores the record as rejected.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dsp.mci import moving_cepstrum_integral
from dsp.metrics import crest_factor, envelope_variance, gear_metrics, kurtosis, peak, rms
from dsp.nonsync import per_tooth_nonsync_z
from dsp.quality import quality_score, sync_to_noise_db
from dsp.shaftperiod import MODULI as PERIOD_MODULI
from dsp.shaftperiod import PeriodCheck, check_shaft_period
from dsp.tach import TachAnalysis
from dsp.teeth import (
    per_tooth_difference_stats,
    per_tooth_evidence,
    tooth_pitch_angles_deg,
)
from dsp.toothframe import circular_shift
from dsp.toothscore import (
    evidence_standard_error,
    leave_one_out_averages,
    standout_threshold,
    standout_tooth,
    tooth_scores,
)
from dsp.tsa import difference_signal, regular_signal, residual_signal
from gearwatch.floor.campaign import Campaign, ChannelConfig, RecordData
from gearwatch.floor.errors import RecordFormatError, RecordRejected
from gearwatch.floor.results import (
    TOOTH1_ANGLE_KEY,
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
from gearwatch.usecases.angle_averages import (
    AngleAverages,
    angle_averages,
    gear_revolutions_from_pinion_grid,
)
from gearwatch.usecases.shaft_angle import (
    NOMINAL_SPEED,
    TRUSTED_SPEEDS,
    ShaftAngle,
    record_shaft_angle,
)
from gearwatch.usecases.signal_checks import (
    CLIPPING_MIN_RUN,
    MAX_ABS_SAMPLE,
    MAX_DEFECTIVE_FRACTION,
    ScannedSignal,
    checked_signal,
    clipped_fraction,
)
from gearwatch.usecases.tachless import (
    FramePlacement as _FramePlacement,
)
from gearwatch.usecases.tachless import (
    PlacedAverages,
    place_in_tooth_frame,
    tach_frame_fingerprints,
    unsteady_angle,
)

__all__ = [
    "BLOCK_SAMPLES",
    "CLIPPING_MIN_RUN",
    "MAX_ABS_SAMPLE",
    "MAX_DEFECTIVE_FRACTION",
    "MAX_REJECTED_REVOLUTION_FRACTION",
    "SAMPLE_RATE_TOLERANCE",
    "Baselines",
    "analyze_file",
    "analyze_record",
    "clipped_fraction",
    "gear_revolutions_from_pinion_grid",
]

MAX_REJECTED_REVOLUTION_FRACTION = 0.5
"""A channel that needs more than this fraction of its pinion revolutions dropped is refused: what
is left would not be a typical average (a sensor clipped on every mesh peak ends up here)."""
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
    # every channel's checks before any heavy work: a bad channel is left out (with its reason),
    # the record is refused only when every channel is
    scans, refused = _checked_channels(record, accelerometers, block_samples, params)
    shaft = record_shaft_angle(record, campaign, params, sample_rate_hz, block_samples, scans,
                               campaign_speed_rpm=_campaign_speed_rpm(tooth_frames))
    if isinstance(shaft, str):
        return _raw_metrics_only(shaft, scans, campaign, params, input_sha256, refused)
    tach, pinion_per_tach_rev = shaft.tach, shaft.pinion_per_tach_rev
    try:
        channels = _analyzed_channels(
            scans, sample_rate_hz, shaft, campaign, params, has_teeth, baselines, block_samples,
            tooth_frames, input_sha256, refused,
        )
    except RecordRejected as error:
        if shaft.source == "tachometer":
            raise
        # Without a tach the record keeps its whole-record metrics (trends go on) when the
        # mesh-phase angle leaves too little for the averages (e.g. revolutions rejected as
        # outliers on a short record whose speed swings): the reason says so.
        return _raw_metrics_only(
            f"mesh-phase angle: {' '.join(str(error).split())}", scans, campaign, params,
            input_sha256, refused,
        )
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
        refused_channels=refused,
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



def _campaign_speed_rpm(tooth_frames: Mapping[str, ToothFrameReference] | None) -> float | None:
    """The campaign's learned pinion speed (:attr:`ToothFrameReference.speed_rpm`): the first
    channel's reference that has one (every channel's comes from the same records)."""
    for reference in (tooth_frames or {}).values():
        if reference.speed_rpm is not None:
            return reference.speed_rpm
    return None


def _checked_channels(
    record: RecordData,
    accelerometers: Sequence[ChannelConfig],
    block_samples: int,
    params: AnalysisParameters,
) -> tuple[dict[str, ScannedSignal], dict[str, str]]:
    """Each accelerometer channel's checks (:func:`checked_signal`): the channels that pass, and
    the reasons of those that do not. Every channel refused refuses the record (the first one's
    reason); a missing channel (a format error) always does."""
    scans: dict[str, ScannedSignal] = {}
    refused: dict[str, str] = {}
    first_error: RecordRejected | None = None
    for channel in accelerometers:
        try:
            scans[channel.name] = checked_signal(record, channel.name, block_samples, params)
        except RecordRejected as error:
            refused[channel.name] = str(error)
            first_error = first_error or error
    if not scans:
        assert first_error is not None
        raise first_error
    return scans, refused

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
            "tachometer": _tach_parameters(campaign),
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



def _tach_parameters(campaign: Campaign) -> dict[str, Any] | None:
    """The tachometer's settings in a result's provenance; the default ``edge`` ("rising") left
    out, so results stored before the setting existed keep their parameters."""
    if campaign.tachometer is None:
        return None
    settings = dataclasses.asdict(campaign.tachometer)
    if settings["edge"] == "rising":
        del settings["edge"]
    return settings


def _analyzed_channels(
    scans: Mapping[str, ScannedSignal],
    sample_rate_hz: float,
    shaft: ShaftAngle,
    campaign: Campaign,
    params: AnalysisParameters,
    has_teeth: bool,
    baselines: Mapping[str, Baselines],
    block_samples: int,
    tooth_frames: Mapping[str, ToothFrameReference] | None,
    input_sha256: str,
    refused: dict[str, str],
) -> list[ChannelAnalysis]:
    """Every accelerometer channel that passed its checks through the angle-domain chain
    (:func:`_analyze_channel`). A channel the chain refuses (too many revolutions rejected, too
    few left) joins ``refused``; when every channel is refused the first one's reason refuses
    the record."""
    tach, pinion_per_tach_rev = shaft.tach, shaft.pinion_per_tach_rev
    channels: list[ChannelAnalysis] = []
    first_error: RecordRejected | None = None
    for name, signal in scans.items():
        placement = None if shaft.source == "tachometer" else _FramePlacement(
            reference=None if tooth_frames is None else tooth_frames.get(name),
            campaign_mode=tooth_frames is not None,
            record_sha256=input_sha256,
            # a speed that did not come from the hint alone: the revolutions must confirm it
            check_period=(shaft.tachless or {}).get("speed_from", NOMINAL_SPEED) not in TRUSTED_SPEEDS,
            unsteady_angle=unsteady_angle(shaft.tachless or {}),
        )
        try:
            channels.append(_analyze_channel(
                name=name, signal=signal, sample_rate_hz=sample_rate_hz, tach=tach,
                campaign=campaign, params=params, has_teeth=has_teeth,
                pinion_per_tach_rev=pinion_per_tach_rev,
                baselines=baselines.get(name, Baselines()), block_samples=block_samples,
                tach_on_pinion=shaft.tach_on_pinion, frame_placement=placement,
            ))
        except RecordRejected as error:
            refused[name] = str(error)
            first_error = first_error or error
    if not channels:
        assert first_error is not None
        raise first_error
    return channels


def _raw_metrics_only(
    reason: str,
    scans: Mapping[str, ScannedSignal],
    campaign: Campaign,
    params: AnalysisParameters,
    input_sha256: str,
    refused: dict[str, str],
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
    per_channel = [scan.defects.counts() for scan in scans.values()]
    repairs = {kind: sum(counts[kind] for counts in per_channel) for kind in per_channel[0]}
    quality = Quality(
        tach_repairs=[], speed_variation=0.0, speed_min_rpm=0.0, speed_max_rpm=0.0,
        clipped_fraction=max(scan.clipped_fraction for scan in scans.values()),
        angle_source="none",
        tach_failure=reason,
        per_tooth=reason,
        tooth_frames={c.channel: c.tooth_frame for c in channels},
        # the repairs are counted although no average uses them: the record's data quality
        glitch_samples=repairs["glitch_samples"],
        dropout_samples=repairs["dropout_samples"],
        clipped_samples=repairs["clipped_samples"],
        refused_channels=refused,
    )
    return RecordAnalysis(
        channels=channels, quality=quality,
        provenance=_provenance(campaign, params, input_sha256),
        speed_rpm=0.0, revolutions=0, samples_per_rev=0,
    )


def _analyze_channel(
    *,
    name: str,
    signal: ScannedSignal,
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
    """One accelerometer channel: its synchronous averages (checked), their quality, then the
    whole-shaft metrics (no tooth counts) or the tooth frame, the MCI and the per-tooth results."""
    rig = campaign.rig
    pinion_spr, gear_spr, hunting_tach_revs = _grids(campaign, params, has_teeth, tach_on_pinion)
    check_period = has_teeth and frame_placement is not None and frame_placement.check_period
    angle = _checked_averages(
        name, signal, sample_rate_hz, tach, params, pinion_spr, gear_spr, pinion_per_tach_rev,
        hunting_tach_revs, block_samples, period_moduli=PERIOD_MODULI if check_period else (),
    )
    quality = _channel_quality(angle, tach, signal)
    curves: dict[str, np.ndarray] = {
        "pinion_average": angle.pinion_average.astype(np.float32),
        "speed_rpm": (tach.rev_speed_rpm * pinion_per_tach_rev).astype(np.float32),
    }
    speed_rpm = float(tach.mean_rpm * pinion_per_tach_rev)
    if not has_teeth:
        return _whole_shaft_channel(name, angle, signal, speed_rpm, pinion_spr, curves, quality)

    assert rig.pinion_teeth is not None and rig.gear_teeth is not None
    pinion_teeth = rig.pinion_teeth
    period = None
    if check_period and frame_placement is not None and angle.pinion_period_sums is not None:
        period = check_shaft_period(angle.pinion_period_sums, angle.gear_period_sums,
                                    rig.pinion_teeth, rig.gear_teeth)
        if period.refusal and not frame_placement.refusal:
            frame_placement = dataclasses.replace(
                frame_placement, refusal=f"tooth frame refused: {period.refusal}")
    placed = _in_tooth_frame(angle, rig.pinion_teeth, rig.gear_teeth, rig.tooth1_pitch_angle_deg,
                             frame_placement)
    if period is not None:
        placed.tooth_frame["period_check"] = _period_check_json(period)
    average = placed.pinion_average
    tooth1_pitch_angle_deg, tooth_frame = placed.tooth1_pitch_angle_deg, placed.tooth_frame
    if frame_placement is not None:
        curves["pinion_average"] = average.astype(np.float32)
    regular = regular_signal(average, pinion_teeth, sidebands=params.difference_sidebands)
    residual = residual_signal(average, pinion_teeth)
    difference = difference_signal(average, pinion_teeth, sidebands=params.difference_sidebands)

    window = params.mci_window_samples or params.samples_per_mesh
    mci = moving_cepstrum_integral(
        average, window, form=params.mci_form, median_width=params.mci_median_width
    )
    teeth, scores = _tooth_results(
        angle, mci.filtered, difference, pinion_teeth, tooth1_pitch_angle_deg, window, params,
        placed.pinion_delay_samples,
    )
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
    metrics = {key: float(value) for key, value in average_metrics.items()} | signal.raw_metrics
    curves.update(
        {
            "gear_average": placed.gear_average.astype(np.float32),
            "difference": difference.astype(np.float32),
            "mci_raw": mci.raw.astype(np.float32),
            "mci": mci.filtered.astype(np.float32),
        }
    )
    return ChannelAnalysis(
        channel=name,
        revolutions=angle.pinion_revolutions,
        gear_revolutions=angle.gear_revolutions,
        speed_rpm=speed_rpm,
        samples_per_rev=pinion_spr,
        metrics=metrics,
        # a refused tooth frame: the numbers would name the wrong teeth in the campaign's trends
        teeth=[] if per_tooth_refused else teeth,
        worst_tooth=(
            None if per_tooth_refused else standout_tooth(scores, standout_threshold(pinion_teeth))
        ),
        curves=curves,
        quality=quality,
        baseline_stats=_baseline_stats(residual, average, pinion_teeth, baselines) | (
            {} if per_tooth_refused else {TOOTH1_ANGLE_KEY: float(tooth1_pitch_angle_deg)}
        ),
        tooth_frame=tooth_frame,
        frame_fingerprints=placed.fingerprints,
    )


def _grids(
    campaign: Campaign, params: AnalysisParameters, has_teeth: bool, tach_on_pinion: bool
) -> tuple[int, int, int]:
    """Samples per pinion and per gear revolution, and the tach-shaft revolutions after which
    both wheels are back on their starting teeth (1 without tooth counts)."""
    rig = campaign.rig
    if not has_teeth:
        return params.samples_per_rev_without_teeth, params.samples_per_rev_without_teeth, 1
    assert rig.pinion_teeth is not None and rig.gear_teeth is not None
    common = math.gcd(rig.pinion_teeth, rig.gear_teeth)
    return (
        rig.pinion_teeth * params.samples_per_mesh,
        rig.gear_teeth * params.samples_per_mesh,
        (rig.gear_teeth if tach_on_pinion else rig.pinion_teeth) // common,
    )


def _period_check_json(check: PeriodCheck) -> dict[str, Any]:
    """The speed check of a spectrum-speed record for ``tooth_frame.period_check``: per prime,
    how far the average's orders off its multiples stand above noise and how much the residue
    classes differ (standard errors), and on which wheel that was tested; per factor 2–16
    dividing the pinion's teeth, the strongest line where the mesh would sit were the angle that
    much too fast, against the strongest mesh harmonic (:func:`dsp.shaftperiod.mesh_family_ratio`)."""

    def finite(values: Mapping[int, float], digits: int) -> dict[str, float | None]:
        return {str(m): round(v, digits) if math.isfinite(v) else None for m, v in values.items()}

    return {
        "confirmed": not check.refusal,
        "unfolded_z": finite(check.unfolded, 2),
        "residue_z": finite(check.residue, 2),
        "mesh_family_ratio": finite(check.mesh_family, 4),
        "unfolded_share": finite(check.unfolded_share, 4),
        "residue_wheel": {str(m): w for m, w in check.residue_wheel.items()},
    }


def _checked_averages(
    name: str,
    signal: ScannedSignal,
    sample_rate_hz: float,
    tach: TachAnalysis,
    params: AnalysisParameters,
    pinion_spr: int,
    gear_spr: int,
    pinion_per_tach_rev: float,
    hunting_tach_revs: int,
    block_samples: int,
    period_moduli: tuple[int, ...] = (),
) -> AngleAverages:
    """The channel's synchronous averages, refused when too many revolutions had to be dropped
    or too few are left."""
    try:
        angle = angle_averages(
            signal.samples, sample_rate_hz, tach.pulse_times_s, tach.pulses_per_rev, pinion_spr,
            gear_spr, pinion_per_tach_rev, hunting_tach_revs, block_samples,
            signal.defects, params.revolution_outlier_factor,
            tach_gaps_s=np.asarray(tach.bridged_spans_s, dtype=np.float64).reshape(-1, 2),
            period_moduli=period_moduli,
        )
    except ValueError as error:  # e.g. pulse times outside the record: tach and signal disagree
        raise RecordRejected(f"channel {name!r}: cannot resample to shaft angle: {error}") from error
    revolutions = angle.pinion_revolutions
    rejected = angle.rejected_defective + angle.rejected_outliers + angle.rejected_tach_gaps
    counts = signal.defects.counts()
    if rejected > MAX_REJECTED_REVOLUTION_FRACTION * (revolutions + rejected):
        what = ", ".join(f"{n} {k.removesuffix('_samples')}" for k, n in counts.items() if n)
        cause = (
            "the sensor is clipped" if counts["clipped_samples"] * 2 > sum(counts.values())
            else f"defective samples ({what})" if angle.rejected_defective
            else "the tachometer's bridged stretches" if angle.rejected_tach_gaps
            else "non-repeating content"
        )
        gaps = f", {angle.rejected_tach_gaps} in bridged tach stretches" if angle.rejected_tach_gaps else ""
        raise RecordRejected(
            f"channel {name!r}: {rejected} of {revolutions + rejected} pinion revolutions rejected "
            f"({angle.rejected_defective} with defective samples, {angle.rejected_outliers} "
            f"outliers{gaps}): {cause}"
        )
    if revolutions < params.min_revolutions:
        raise RecordRejected(
            f"only {revolutions} whole pinion revolutions (minimum {params.min_revolutions})"
            + (f"; {rejected} rejected" if rejected else "")
        )
    return angle


def _channel_quality(angle: AngleAverages, tach: TachAnalysis, signal: ScannedSignal) -> ChannelQuality:
    """The channel's data-quality score and what went into it (:func:`dsp.quality.quality_score`)."""
    revolutions = angle.pinion_revolutions
    rejected = angle.rejected_defective + angle.rejected_outliers + angle.rejected_tach_gaps
    snr_db = sync_to_noise_db(float(np.var(angle.pinion_average)), angle.residual_power, revolutions)
    score = quality_score(
        revolutions=revolutions,
        sync_to_noise_db=snr_db,
        speed_variation=tach.speed_variation,
        tach_repairs=len(tach.repairs),
        rejected_revolutions=rejected,
    )
    return ChannelQuality(
        score=score.score,
        score_components=score.components(),
        sync_to_noise_db=snr_db,
        rejected_revolutions=rejected,
        rejected_defective_revolutions=angle.rejected_defective,
        rejected_outlier_revolutions=angle.rejected_outliers,
        rejected_tach_gap_revolutions=angle.rejected_tach_gaps,
        **signal.defects.counts(),
    )


def _whole_shaft_channel(
    name: str,
    angle: AngleAverages,
    signal: ScannedSignal,
    speed_rpm: float,
    samples_per_rev: int,
    curves: dict[str, np.ndarray],
    quality: ChannelQuality,
) -> ChannelAnalysis:
    """Without tooth counts: the shaft-synchronous average's metrics and the raw ones."""
    average = angle.pinion_average
    return ChannelAnalysis(
        channel=name,
        revolutions=angle.pinion_revolutions,
        gear_revolutions=angle.pinion_revolutions,
        speed_rpm=speed_rpm,
        samples_per_rev=samples_per_rev,
        metrics={
            "rms": float(rms(average)),
            "peak": float(peak(average)),
            "crest": float(crest_factor(average)),
            "kurtosis": float(kurtosis(average)),
            **signal.raw_metrics,
        },
        curves=curves,
        quality=quality,
    )


def _in_tooth_frame(
    angle: AngleAverages,
    pinion_teeth: int,
    gear_teeth: int,
    tach_tooth1_pitch_angle_deg: float,
    frame_placement: _FramePlacement | None,
) -> PlacedAverages:
    """The averages in the tooth frame: the tach's as they are (with their fingerprints, which
    found a mixed campaign's frame), a tach-less record's moved into the campaign's frame or
    refused (:func:`place_in_tooth_frame`)."""
    if frame_placement is None:
        return PlacedAverages(
            angle.pinion_average, angle.gear_average, tach_tooth1_pitch_angle_deg,
            {"kind": "tachometer"},
            tach_frame_fingerprints(angle.pinion_average, angle.gear_average, pinion_teeth,
                                    gear_teeth),
            0.0,
        )
    placed = place_in_tooth_frame(
        angle.pinion_average, angle.gear_average, pinion_teeth, gear_teeth, frame_placement,
        tach_tooth1_pitch_angle_deg=tach_tooth1_pitch_angle_deg,
    )
    if placed.tooth_frame.get("kind") == "campaign":
        # how the record's own average was moved into the campaign frame (samples of delay)
        placed.tooth_frame["pinion_delay_samples"] = round(float(placed.pinion_delay_samples), 3)
    return placed


def _tooth_results(
    angle: AngleAverages,
    mci_filtered: np.ndarray,
    difference: np.ndarray,
    pinion_teeth: int,
    tooth1_pitch_angle_deg: float,
    window: int,
    params: AnalysisParameters,
    frame_delay: float,
) -> tuple[list[ToothResult], np.ndarray]:
    """Per tooth: the MCI evidence with its standard error and score, the difference signal's
    sector energy and kurtosis, the non-synchronous power's z; and the scores."""
    evidence, evidence_se, scores = _tooth_evidence(
        angle, mci_filtered, pinion_teeth, tooth1_pitch_angle_deg, window, params, frame_delay
    )
    depths = np.maximum(evidence, 0.0)  # the displayed well depth (dsp.teeth.per_tooth_well_depth)
    energy, sector_kurtosis = per_tooth_difference_stats(
        difference, pinion_teeth, tooth1_pitch_angle_deg
    )
    nonsync_z = per_tooth_nonsync_z(angle.pinion_nonsync_power, pinion_teeth,
                                    tooth1_pitch_angle_deg, frame_delay_samples=frame_delay)
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
            nonsync_z=float(nonsync_z[k]),
        )
        for k in range(pinion_teeth)
    ]
    return teeth, scores


def _tooth_evidence(
    angle: AngleAverages,
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


def _baseline_stats(
    residual: np.ndarray, average: np.ndarray, pinion_teeth: int, baselines: Baselines
) -> dict[str, float]:
    """This record's share of the NA4/NB4 running baselines, and the baselines its NA4 and NB4
    were divided by (``na4_baseline``, ``nb4_baseline``: the running means passed in, else the
    record's own variances), so that :mod:`gearwatch.usecases.running_baselines` can rescale
    them when a late record changes the baseline."""
    residual_variance = float(np.var(residual))
    envelope = float(envelope_variance(average, pinion_teeth))
    return {
        "residual_variance": residual_variance,
        "envelope_variance": envelope,
        "na4_baseline": (residual_variance if baselines.na4_residual_variance is None
                         else float(baselines.na4_residual_variance)),
        "nb4_baseline": (envelope if baselines.nb4_envelope_variance is None
                         else float(baselines.nb4_envelope_variance)),
    }
