"""The per-record chain: tachometer → shaft angle → synchronous averages → MCI and metrics.

This is the one place that strings the pure numerical core (:mod:`dsp`) together
for a record and a campaign manifest. It does no I/O beyond :func:`analyze_file`
reading the file it is given, and it never touches a database.

Quality checks that refuse a record raise :class:`gearwatch.errors.RecordRejected`
with a one-line reason; the caller stores the record as rejected.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dsp.angle import angle_resample
from dsp.mci import moving_cepstrum_integral
from dsp.metrics import crest_factor, envelope_variance, gear_metrics, kurtosis, peak, rms
from dsp.tach import TachAnalysis, TachometerError, analyze_tachometer, pulse_times_from_waveform
from dsp.teeth import (
    per_tooth_difference_stats,
    per_tooth_well_depth,
    tooth_pitch_angles_deg,
    worst_tooth,
)
from dsp.tsa import difference_signal, regular_signal, residual_signal, synchronous_average
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

    tach = _analyze_tach(record, campaign, params, sample_rate_hz)
    rig = campaign.rig
    pinion_teeth, gear_teeth = rig.pinion_teeth, rig.gear_teeth
    has_teeth = bool(pinion_teeth and gear_teeth)
    pinion_per_tach_rev = _pinion_revs_per_tach_rev(campaign)

    accelerometers = campaign.accelerometer_channels
    if not accelerometers:
        raise RecordFormatError("the manifest declares no accelerometer channel")
    channels = [
        _analyze_channel(
            name=channel.name,
            signal=_checked_signal(record, channel.name),
            sample_rate_hz=sample_rate_hz,
            tach=tach,
            campaign=campaign,
            params=params,
            has_teeth=has_teeth,
            pinion_per_tach_rev=pinion_per_tach_rev,
            baselines=baselines.get(channel.name, Baselines()),
        )
        for channel in accelerometers
    ]
    pinion_rpm = tach.mean_rpm * pinion_per_tach_rev
    quality = Quality(
        tach_repairs=[TachRepairNote(kind=r.kind, time_s=float(r.time_s)) for r in tach.repairs],
        speed_variation=float(tach.speed_variation),
        speed_min_rpm=float(tach.min_rpm * pinion_per_tach_rev),
        speed_max_rpm=float(tach.max_rpm * pinion_per_tach_rev),
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
    record: RecordData, campaign: Campaign, params: AnalysisParameters, sample_rate_hz: float
) -> TachAnalysis:
    config = campaign.tachometer
    if config is None:
        raise RecordRejected(
            "the manifest has no [tachometer]: synchronous averaging needs a once-per-revolution reference"
        )
    raw = np.asarray(record.channel(config.channel), dtype=np.float64)
    if not np.all(np.isfinite(raw)):
        raise RecordRejected(f"tachometer channel {config.channel!r} contains NaN or inf samples")
    try:
        if config.kind == "pulses":
            pulse_times_s = pulse_times_from_waveform(raw, sample_rate_hz)
        else:
            pulse_times_s = raw
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


def _checked_signal(record: RecordData, name: str) -> np.ndarray:
    signal = np.asarray(record.channel(name), dtype=np.float64)
    if signal.ndim != 1 or signal.size == 0:
        raise RecordFormatError(f"channel {name!r} must be a non-empty 1-D signal")
    # max/min propagate NaN and show inf: one pass each instead of a full isfinite() scan
    top, bottom = float(signal.max()), float(signal.min())
    if not (np.isfinite(top) and np.isfinite(bottom)):
        bad = int(np.count_nonzero(~np.isfinite(signal)))
        raise RecordRejected(f"channel {name!r} contains {bad} NaN or inf samples")
    clipped = clipped_fraction(signal, extremes=(bottom, top))
    if clipped > MAX_CLIPPED_FRACTION:
        raise RecordRejected(
            f"channel {name!r} is clipped: {clipped:.2%} of samples sit at the sensor's extreme value"
        )
    return signal


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


def _raw_signal_metrics(signal: np.ndarray) -> dict[str, float]:
    """RMS and kurtosis of the raw time signal about its mean (what the averages remove too)."""
    centred = signal - signal.mean()
    return {"raw_rms": float(rms(centred)), "raw_kurtosis": float(kurtosis(centred))}


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


def _analyze_channel(
    *,
    name: str,
    signal: np.ndarray,
    sample_rate_hz: float,
    tach: TachAnalysis,
    campaign: Campaign,
    params: AnalysisParameters,
    has_teeth: bool,
    pinion_per_tach_rev: float,
    baselines: Baselines,
) -> ChannelAnalysis:
    rig = campaign.rig
    ppr = tach.pulses_per_rev
    pulse_times_s = tach.pulse_times_s
    if has_teeth:
        assert rig.pinion_teeth is not None and rig.gear_teeth is not None
        pinion_spr = rig.pinion_teeth * params.samples_per_mesh
        gear_spr = rig.gear_teeth * params.samples_per_mesh
    else:
        pinion_spr = gear_spr = params.samples_per_rev_without_teeth

    try:
        pinion_revs = angle_resample(
            signal, sample_rate_hz, pulse_times_s, ppr, pinion_spr, shaft_ratio=pinion_per_tach_rev
        )
    except ValueError as error:  # e.g. pulse times outside the record: tach and signal disagree
        raise RecordRejected(f"channel {name!r}: cannot resample to shaft angle: {error}") from error
    revolutions = int(pinion_revs.shape[-2])
    if revolutions < params.min_revolutions:
        raise RecordRejected(
            f"only {revolutions} whole pinion revolutions (minimum {params.min_revolutions})"
        )
    average = synchronous_average(pinion_revs)
    curves: dict[str, np.ndarray] = {
        "pinion_average": average.astype(np.float32),
        "speed_rpm": (tach.rev_speed_rpm * pinion_per_tach_rev).astype(np.float32),
    }

    raw_metrics = _raw_signal_metrics(signal)
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
    gear_revs = gear_revolutions_from_pinion_grid(pinion_revs, gear_spr)
    gear_average = synchronous_average(gear_revs)
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
        gear_revolutions=int(gear_revs.shape[-2]),
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
