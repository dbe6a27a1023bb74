"""The per-record chain: tachometer → shaft angle → synchronous averages → MCI and metrics.

This is the one place that strings the pure numerical core (:mod:`dsp`) together
for a record and a campaign manifest. It does no I/O beyond :func:`analyze_file`
reading the file it is given, and it never touches a database.

Quality checks that refuse a record raise :class:`gearwatch.errors.RecordRejected`
with a one-line reason; the caller stores the record as rejected.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dsp.angle import angle_resample
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
from dsp.tach import (
    TachAnalysis,
    TachometerError,
    analyze_tachometer,
    pulse_times_from_waveform,
    pulse_times_from_waveform_blocks,
)
from dsp.teeth import (
    per_tooth_difference_stats,
    per_tooth_well_depth,
    tooth_pitch_angles_deg,
    worst_tooth,
)
from dsp.tsa import difference_signal, regular_signal, residual_signal
from gearwatch.errors import RecordFormatError, RecordRejected
from gearwatch.results import (
    AnalysisParameters,
    ChannelAnalysis,
    Provenance,
    Quality,
    RecordAnalysis,
    TachRepairNote,
    ToothResult,
)
from gearwatch.version import code_version
from ingest.types import Campaign, RecordData

CLIPPING_MIN_RUN = 3
"""Consecutive samples at the channel's extreme value that count as a clipped stretch."""
MAX_CLIPPED_FRACTION = 1e-3
"""A channel with more of its samples in clipped stretches than this is refused."""
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
) -> RecordAnalysis:
    """Read a record file through the reader registry and run :func:`analyze_record` on it."""
    from ingest.sources import file_sha256, read_record

    record = read_record(path, campaign)
    return analyze_record(
        record, campaign, params, input_sha256=file_sha256(path), baselines=baselines
    )


def analyze_record(
    record: RecordData,
    campaign: Campaign,
    params: AnalysisParameters | None = None,
    *,
    input_sha256: str,
    baselines: dict[str, Baselines] | None = None,
    block_samples: int = BLOCK_SAMPLES,
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

    tach = _analyze_tach(record, campaign, params, sample_rate_hz, block_samples)
    rig = campaign.rig
    pinion_teeth, gear_teeth = rig.pinion_teeth, rig.gear_teeth
    has_teeth = bool(pinion_teeth and gear_teeth)
    pinion_per_tach_rev = _pinion_revs_per_tach_rev(campaign)

    accelerometers = campaign.accelerometer_channels
    if not accelerometers:
        raise RecordFormatError("the manifest declares no accelerometer channel")
    # every channel's checks before any heavy work: a bad channel rejects the record at once
    scans = {channel.name: _checked_signal(record, channel.name, block_samples)
             for channel in accelerometers}
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
    )
    provenance = Provenance(
        input_sha256=input_sha256,
        code_version=code_version(),
        parameters={
            **params.to_dict(),
            "pinion_teeth": pinion_teeth,
            "gear_teeth": gear_teeth,
            "tooth1_pitch_angle_deg": rig.tooth1_pitch_angle_deg,
            "tachometer": dataclasses.asdict(campaign.tachometer) if campaign.tachometer else None,
        },
    )
    first = channels[0]
    return RecordAnalysis(
        channels=channels,
        quality=quality,
        provenance=provenance,
        speed_rpm=float(pinion_rpm),
        revolutions=first.revolutions,
        samples_per_rev=first.samples_per_rev,
    )


def _pinion_revs_per_tach_rev(campaign: Campaign) -> float:
    """Pinion revolutions per revolution of the shaft that carries the tachometer."""
    rig = campaign.rig
    shaft = campaign.tachometer.shaft if campaign.tachometer else "pinion"
    if not (rig.pinion_teeth and rig.gear_teeth):
        # Without tooth counts only the tach shaft itself can be averaged; call it the pinion.
        return 1.0
    return 1.0 if shaft == "pinion" else rig.gear_teeth / rig.pinion_teeth


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
    except TachometerError as error:
        raise RecordRejected(f"tachometer: {error}") from error


@dataclass(frozen=True)
class _ScannedSignal:
    """A channel that passed the checks, with its raw-signal metrics and clipped fraction."""

    samples: np.ndarray
    """The channel as read (possibly float32, possibly memory-mapped): convert per block."""
    raw_metrics: dict[str, float]
    clipped_fraction: float


def _checked_signal(record: RecordData, name: str, block_samples: int) -> _ScannedSignal:
    """Refuse NaN/inf and clipping; compute ``raw_rms`` and ``raw_kurtosis``; block by block.

    Moments are accumulated in one pass per block (:func:`dsp.metrics.extremes_and_moment_sums`)
    about the mean of the first samples (numerically safe for a signal whose mean does not
    wander by many standard deviations). A clipped run split by a block boundary
    counts as two runs (at most a few samples per boundary of a 4-million-sample block).
    """
    samples = record.channel(name)
    if samples.ndim != 1 or samples.size == 0:
        raise RecordFormatError(f"channel {name!r} must be a non-empty 1-D signal")
    starts = range(0, samples.size, block_samples)
    top, bottom = -np.inf, np.inf
    # moments about a value near the mean, so that the sums do not cancel
    shift = float(np.mean(np.asarray(samples[:1024], dtype=np.float64)))
    sums = np.zeros(4)
    for start in starts:
        block = np.asarray(samples[start : start + block_samples], dtype=np.float64)
        block_top, block_bottom, block_sums = extremes_and_moment_sums(block, shift)
        if not (np.isfinite(block_top) and np.isfinite(block_bottom)):
            bad = sum(
                int(np.count_nonzero(~np.isfinite(np.asarray(samples[i : i + block_samples]))))
                for i in starts
            )
            raise RecordRejected(f"channel {name!r} contains {bad} NaN or inf samples")
        top, bottom = max(top, block_top), min(bottom, block_bottom)
        sums += block_sums
    if len(starts) == 1:
        clipped = clipped_fraction(block, extremes=(bottom, top))
    else:
        clipped = sum(
            clipped_fraction(
                np.asarray(samples[i : i + block_samples], dtype=np.float64),
                extremes=(bottom, top),
            )
            * min(block_samples, samples.size - i)
            for i in starts
        ) / samples.size
    if clipped > MAX_CLIPPED_FRACTION:
        raise RecordRejected(
            f"channel {name!r} is clipped: {clipped:.2%} of samples sit at the sensor's extreme value"
        )
    return _ScannedSignal(samples, _raw_moments_metrics(sums / samples.size), clipped)


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
    gear_average: np.ndarray
    gear_revolutions: int


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
    """
    whole_tach_revs = (pulse_times_s.size - 1) // pulses_per_rev
    seconds_per_tach_rev = (pulse_times_s[-1] - pulse_times_s[0]) / max(
        (pulse_times_s.size - 1) / pulses_per_rev, 1e-12
    )
    samples_per_hunting = hunting_tach_revs * seconds_per_tach_rev * sample_rate_hz
    block_tach_revs = hunting_tach_revs * max(1, int(block_samples // max(samples_per_hunting, 1)))
    pinion_sum = np.zeros(pinion_spr)
    gear_sum = np.zeros(gear_spr)
    pinion_count = gear_count = 0
    if whole_tach_revs <= block_tach_revs + hunting_tach_revs:
        plan = [(0, whole_tach_revs, True)]
    else:
        edges = list(range(0, whole_tach_revs, block_tach_revs))
        plan = [(r0, min(r0 + block_tach_revs, whole_tach_revs), r0 == edges[-1]) for r0 in edges]
    for first_rev, end_rev, last in plan:
        if len(plan) == 1:
            block = np.asarray(samples, dtype=np.float64)
            block_pulses, skip_pinion_revs = pulse_times_s, 0
        else:
            context_rev = max(0, first_rev - hunting_tach_revs)
            first_pulse = context_rev * pulses_per_rev
            last_pulse = min(pulse_times_s.size - 1, (end_rev + hunting_tach_revs) * pulses_per_rev)
            start = max(0, int(np.floor(pulse_times_s[first_pulse] * sample_rate_hz)) - 16)
            stop = min(samples.size, int(np.ceil(pulse_times_s[last_pulse] * sample_rate_hz)) + 16)
            block = np.asarray(samples[start:stop], dtype=np.float64)
            block_pulses = pulse_times_s[first_pulse : last_pulse + 1] - start / sample_rate_hz
            skip_pinion_revs = round((first_rev - context_rev) * pinion_per_tach_rev)
        revs = angle_resample(
            block, sample_rate_hz, block_pulses, pulses_per_rev, pinion_spr,
            shaft_ratio=pinion_per_tach_rev,
        )
        keep = None if last else round((end_rev - first_rev) * pinion_per_tach_rev)
        revs = revs[skip_pinion_revs:][:keep]
        pinion_sum += revs.sum(axis=0)
        pinion_count += revs.shape[0]
        gear_revs = gear_revolutions_from_pinion_grid(revs, gear_spr)
        gear_sum += gear_revs.sum(axis=0)
        gear_count += gear_revs.shape[0]
    return _AngleAverages(
        pinion_sum / max(pinion_count, 1), pinion_count, gear_sum / max(gear_count, 1), gear_count
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
        tach_on_pinion = campaign.tachometer is None or campaign.tachometer.shaft == "pinion"
        hunting_tach_revs = (rig.gear_teeth if tach_on_pinion else rig.pinion_teeth) // common
    else:
        pinion_spr = gear_spr = params.samples_per_rev_without_teeth
        hunting_tach_revs = 1
    try:
        angle = _angle_averages(
            signal.samples, sample_rate_hz, pulse_times_s, ppr, pinion_spr, gear_spr,
            pinion_per_tach_rev, hunting_tach_revs, block_samples,
        )
    except ValueError as error:  # e.g. pulse times outside the record: tach and signal disagree
        raise RecordRejected(f"channel {name!r}: cannot resample to shaft angle: {error}") from error
    revolutions = angle.pinion_revolutions
    if revolutions < params.min_revolutions:
        raise RecordRejected(
            f"only {revolutions} whole pinion revolutions (minimum {params.min_revolutions})"
        )
    average = angle.pinion_average
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
        )

    assert rig.pinion_teeth is not None and rig.gear_teeth is not None
    pinion_teeth = rig.pinion_teeth
    gear_average = angle.gear_average
    regular = regular_signal(average, pinion_teeth, sidebands=params.difference_sidebands)
    residual = residual_signal(average, pinion_teeth)
    difference = difference_signal(average, pinion_teeth, sidebands=params.difference_sidebands)

    window = params.mci_window_samples or params.samples_per_mesh
    mci = moving_cepstrum_integral(
        average, window, form=params.mci_form, median_width=params.mci_median_width
    )
    depths = per_tooth_well_depth(
        mci.filtered, pinion_teeth, rig.tooth1_pitch_angle_deg, window_samples=window
    )
    energy, sector_kurtosis = per_tooth_difference_stats(
        difference, pinion_teeth, rig.tooth1_pitch_angle_deg
    )
    pitch_angles = tooth_pitch_angles_deg(pinion_teeth, rig.tooth1_pitch_angle_deg)
    teeth = [
        ToothResult(
            tooth=k + 1,
            pitch_angle_deg=float(pitch_angles[k]),
            mci_depth=float(depths[k]),
            diff_energy=float(energy[k]),
            diff_kurtosis=float(sector_kurtosis[k]),
        )
        for k in range(pinion_teeth)
    ]
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
        teeth=teeth,
        worst_tooth=int(worst_tooth(depths)),
        curves=curves,
        baseline_stats={
            "residual_variance": float(np.var(residual)),
            "envelope_variance": float(envelope_variance(average, pinion_teeth)),
        },
    )
