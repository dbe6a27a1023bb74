"""Pinion and gear synchronous averages of one channel, resampled to shaft angle block by block.

Part of the per-record chain (:mod:`gearwatch.usecases.analyze`): :func:`angle_averages` bridges
the defective stretches, resamples the record one block of whole hunting periods at a time
(:func:`dsp.angle.angle_resample`), drops the revolutions that touch a defect or are outliers, and
accumulates the averages, the non-synchronous power and the jackknife group sums.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dsp.angle import angle_grid_times, angle_resample
from dsp.robust import (
    SampleDefects,
    repair_spans,
    revolution_outliers,
    revolutions_overlapping,
)
from dsp.shaftperiod import PeriodSums, PeriodSumsAccumulator
from dsp.toothscore import JACKKNIFE_GROUPS, revolution_group_sums


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


def _gear_revolutions_kept(
    revs: np.ndarray, accepted: np.ndarray, gear_spr: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The block's gear revolutions (:func:`gear_revolutions_from_pinion_grid`), which of them
    are kept (none of their samples in a dropped pinion revolution) and the kept ones (no copy
    when every pinion revolution was kept)."""
    gear_revs = gear_revolutions_from_pinion_grid(revs, gear_spr)
    if accepted.all():
        return gear_revs, np.ones(gear_revs.shape[0], dtype=bool), gear_revs
    sample_ok = np.repeat(accepted, revs.shape[1])[: gear_revs.size].reshape(gear_revs.shape)
    gear_accepted = np.all(sample_ok, axis=1)
    return gear_revs, gear_accepted, gear_revs[gear_accepted]


@dataclass(frozen=True)
class AngleAverages:
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
    pinion_nonsync_power: np.ndarray
    """Per pinion angle, the power of the accepted revolutions about the average,
    ``Σ_i (rev_i − avg)² / (N − 1)`` (NaN with fewer than two): the energy a drifting speed
    smears out of the average (:mod:`dsp.nonsync`)."""
    rejected_tach_gaps: int = 0
    """Pinion revolutions dropped because their angle rests on bridged tach pulses
    (:attr:`dsp.tach.TachAnalysis.bridged_spans_s`)."""
    pinion_period_sums: PeriodSums | None = None
    """With ``period_moduli``: what :func:`dsp.shaftperiod.check_shaft_period` needs of the
    accepted pinion revolutions (a tach-less angle whose speed came from the spectrum)."""
    gear_period_sums: PeriodSums | None = None


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


def angle_averages(
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
    tach_gaps_s: np.ndarray | None = None,
    period_moduli: tuple[int, ...] = (),
) -> AngleAverages:
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
    revolution. So is a pinion revolution that overlaps one of ``tach_gaps_s`` (time spans
    whose angle rests on bridged tach pulses; the signal there is sound and is not bridged).

    ``period_moduli`` (primes): also collect, per wheel, the sums by revolution number modulo
    each and every order's power (:class:`dsp.shaftperiod.PeriodSums`), to check that the
    revolutions are true ones.
    """
    whole_tach_revs = (pulse_times_s.size - 1) // pulses_per_rev
    seconds_per_tach_rev = (pulse_times_s[-1] - pulse_times_s[0]) / max(
        (pulse_times_s.size - 1) / pulses_per_rev, 1e-12
    )
    samples_per_hunting = hunting_tach_revs * seconds_per_tach_rev * sample_rate_hz
    block_tach_revs = hunting_tach_revs * max(1, int(block_samples // max(samples_per_hunting, 1)))
    pinion_sumsq = np.zeros(pinion_spr)
    gear_sum = np.zeros(gear_spr)
    pinion_count = gear_count = rejected_defective = rejected_outliers = rejected_gaps = 0
    spans = defects.spans()
    gaps_s = np.empty((0, 2)) if tach_gaps_s is None else np.asarray(tach_gaps_s, float).reshape(-1, 2)
    margin_s = 4.0 / sample_rate_hz  # the quintic spline's stencil reaches 3 samples
    # jackknife groups: accepted revolution r (counted over the record) goes to group r mod K
    group_sums = np.zeros((JACKKNIFE_GROUPS, pinion_spr))
    group_counts = np.zeros(JACKKNIFE_GROUPS, dtype=np.int64)
    pinion_period = PeriodSumsAccumulator(pinion_spr, period_moduli) if period_moduli else None
    gear_period = PeriodSumsAccumulator(gear_spr, period_moduli) if period_moduli else None
    gear_index = 0  # record number of the block's first gear revolution
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
        block = np.asarray(samples[start:stop], dtype=np.float64)
        if block_spans.size:  # (repair_spans copies; most blocks have nothing to bridge)
            block = repair_spans(block, block_spans)
        revs = angle_resample(
            block, sample_rate_hz, block_pulses, pulses_per_rev, pinion_spr,
            shaft_ratio=pinion_per_tach_rev,
        )
        bounds = _revolution_bounds_s(
            block_pulses, pulses_per_rev, pinion_per_tach_rev, (block.size - 1) / sample_rate_hz
        )[: revs.shape[0]]
        keep = None if last else round((end_rev - first_rev) * pinion_per_tach_rev)
        revs = revs[skip_pinion_revs:][:keep]
        own_bounds = bounds[skip_pinion_revs:][:keep]
        touched = revolutions_overlapping(own_bounds, block_spans / sample_rate_hz, margin_s)
        # a revolution with a defect counts as defective, else one in a tach gap as a gap
        in_gap = revolutions_overlapping(own_bounds, gaps_s - start / sample_rate_hz) & ~touched
        dropped = touched | in_gap
        # (the usual block drops nothing: then no copy of its revolutions is made)
        if dropped.any():
            outliers = np.zeros_like(dropped)
            outliers[~dropped] = revolution_outliers(revs[~dropped], outlier_factor)
        else:
            outliers = revolution_outliers(revs, outlier_factor)
        accepted = ~(dropped | outliers)
        rejected_defective += int(touched.sum())
        rejected_gaps += int(in_gap.sum())
        rejected_outliers += int(outliers.sum())
        good = revs if accepted.all() else revs[accepted]
        pinion_sumsq += np.einsum("ij,ij->j", good, good)
        sums, counts = revolution_group_sums(good, JACKKNIFE_GROUPS, pinion_count)
        group_sums += sums  # (and so the pinion sum)
        group_counts += counts
        pinion_count += good.shape[0]
        gear_revs, gear_accepted, gear_good = _gear_revolutions_kept(revs, accepted, gear_spr)
        if pinion_period is not None and gear_period is not None:
            first_index = 0 if len(plan) == 1 else round(first_rev * pinion_per_tach_rev)
            pinion_period.add(good, first_index + np.flatnonzero(accepted))
            gear_period.add(gear_good, gear_index + np.flatnonzero(gear_accepted))
        gear_index += gear_revs.shape[0]
        gear_sum += gear_good.sum(axis=0)
        gear_count += gear_good.shape[0]
    pinion_average = group_sums.sum(axis=0) / max(pinion_count, 1)
    nonsync_power = (
        np.clip(pinion_sumsq - pinion_count * pinion_average**2, 0.0, None) / (pinion_count - 1)
        if pinion_count > 1
        else np.full(pinion_spr, np.nan)
    )
    residual_power = float(np.mean(nonsync_power)) if pinion_count > 1 else 0.0
    return AngleAverages(
        pinion_average,
        pinion_count,
        gear_sum / max(gear_count, 1),
        gear_count,
        rejected_defective,
        rejected_outliers,
        residual_power,
        group_sums,
        group_counts,
        nonsync_power,
        rejected_gaps,
        None if pinion_period is None else pinion_period.result(),
        None if gear_period is None else gear_period.result(),
    )

