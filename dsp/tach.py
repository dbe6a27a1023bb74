"""Tachometer processing: edge times, pulse repair, speed profile and record acceptance.

A tachometer gives one pulse per mark on a shaft (``pulses_per_rev`` marks, assumed equally
spaced in angle). This module turns a tach waveform (TTL or noisy analogue) into sub-sample edge
times, repairs an isolated missing or extra pulse, and decides whether a record is usable for
synchronous averaging: enough whole revolutions, speed inside a range, speed steady enough.

Everything here is pure: arrays in, arrays and frozen dataclasses out. A refusal raises
:class:`TachometerError`, whose ``str()`` is a one-line reason meant for an operator.

Examples
--------
>>> import numpy as np
>>> from dsp.tach import analyze_tachometer
>>> pulses = np.arange(41) * 0.06          # 1000 rpm, one pulse per revolution
>>> tach = analyze_tachometer(pulses, pulses_per_rev=1)
>>> round(tach.mean_rpm, 6), tach.whole_revolutions
(1000.0, 40)
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dsp.robust import SAMPLED_BLOCKS, spread_block_starts
from dsp.tachgaps import (
    LOCAL_PERIOD_WINDOW,
    SMOOTH_STEP_LIMIT,
    BridgedStretch,
    bridge_problem,
    bridge_unexplained,
    burst_proof_period,
    unexplained_intervals,
)
from gearwatch.floor.defaults import MAD_TO_SIGMA, MAX_SPEED_VARIATION

__all__ = [
    "DEFAULT_MAX_SPEED_VARIATION",
    "PulseRepair",
    "TachAnalysis",
    "TachometerError",
    "analyze_tachometer",
    "bridge_unexplained",
    "pulse_times_from_waveform",
    "repair_pulse_times",
    "shaft_ratios",
    "waveform_levels",
]

FloatArray = NDArray[np.float64]

DEFAULT_MAX_SPEED_VARIATION = MAX_SPEED_VARIATION
"""Largest accepted (max − min)/mean of the per-revolution speed within a record
(:data:`gearwatch.floor.defaults.MAX_SPEED_VARIATION`)."""

MIN_FIT_SAMPLES = 3
"""An edge with at least this many samples inside the hysteresis band is timed by a straight-line
least-squares fit through them (averages noise); a faster edge by linear interpolation between the
two samples that bracket the threshold (exact for a linear ramp)."""


class TachometerError(ValueError):
    """The tachometer signal cannot support synchronous averaging; ``str()`` is the reason."""


class RecordOutOfTachLimits(TachometerError):
    """The pulses are sound and measured the record itself failing: too few whole revolutions,
    a speed outside the accepted range, or a speed that varies too much. Another angle source
    (the mesh phase) would measure the same, so callers refuse the record rather than fall back."""


@dataclass(frozen=True)
class PulseRepair:
    """One repair made to a pulse train.

    Attributes
    ----------
    kind : {"missing", "extra", "bridged"}
        ``"missing"``: a pulse was inserted in an interval ≈ 2× the local period.
        ``"extra"``: a pulse splitting one period into two short intervals was removed.
        ``"bridged"``: a stretch no single repair explains (a burst of interference, a gap) was
        replaced by evenly spaced pulses (:func:`dsp.tachgaps.bridge_unexplained`); its revolutions are not
        averaged (:attr:`TachAnalysis.bridged_spans_s`).
    index : int
        Position in the *input* sequence: for ``"extra"`` the index of the removed pulse, for
        ``"missing"`` the index of the input pulse before which the new pulse was inserted, for
        ``"bridged"`` the index of the last trusted pulse before the stretch.
    time_s : float
        Time of the removed or inserted pulse, or of the stretch's start (s).
    """

    kind: Literal["missing", "extra", "bridged"]
    index: int
    time_s: float


@dataclass(frozen=True)
class TachAnalysis:
    """Repaired pulse train of an accepted record and its speed profile.

    Attributes
    ----------
    pulse_times_s : ndarray
        Repaired pulse times (s).
    pulses_per_rev : int
        Pulses per revolution of the tach shaft.
    repairs : tuple of PulseRepair
        Every repair made, in time order.
    rev_times_s : ndarray
        Time of every ``pulses_per_rev``-th pulse, starting at the first (reference) pulse;
        ``whole_revolutions + 1`` values.
    rev_speed_rpm : ndarray
        Speed of the tach shaft over each whole revolution (rpm), ``whole_revolutions`` values.
    mean_rpm, min_rpm, max_rpm : float
        Mean, minimum and maximum of ``rev_speed_rpm``.
    speed_variation : float
        ``(max_rpm - min_rpm) / mean_rpm``, like the three before over the revolutions outside
        ``bridged_spans_s``.
    whole_revolutions : int
        Whole revolutions of the tach shaft between the first and the last revolution mark.
    bridged_spans_s : tuple of (float, float)
        Time spans (s) whose angle rests on bridged pulses (each stretch widened by one local
        period on both sides, where the phase model still feels the bridge): the revolutions
        that overlap one must not be averaged. Empty for a sound pulse train.
    """

    pulse_times_s: FloatArray
    pulses_per_rev: int
    repairs: tuple[PulseRepair, ...]
    rev_times_s: FloatArray
    rev_speed_rpm: FloatArray
    mean_rpm: float
    min_rpm: float
    max_rpm: float
    speed_variation: float
    whole_revolutions: int
    bridged_spans_s: tuple[tuple[float, float], ...] = ()


def shaft_ratios(
    tach_shaft: Literal["pinion", "gear"], pinion_teeth: int, gear_teeth: int
) -> tuple[float, float]:
    """Pinion and gear revolutions per revolution of the tach shaft.

    These are the ``shaft_ratio`` arguments of :func:`dsp.angle.angle_resample` for the pinion
    and the gear grids, and the factors from the tach-shaft speed to each shaft's speed.

    Examples
    --------
    >>> shaft_ratios("pinion", 20, 21)
    (1.0, 0.9523809523809523)
    >>> shaft_ratios("gear", 20, 21)
    (1.05, 1.0)
    """
    if pinion_teeth < 1 or gear_teeth < 1:
        raise ValueError(f"tooth counts must be >= 1, got {pinion_teeth}, {gear_teeth}")
    if tach_shaft == "pinion":
        return 1.0, pinion_teeth / gear_teeth
    if tach_shaft == "gear":
        return gear_teeth / pinion_teeth, 1.0
    raise ValueError(f"tach_shaft must be 'pinion' or 'gear', got {tach_shaft!r}")


# --------------------------------------------------------------------------- edge detection


LEVEL_SAMPLES = 65_536
"""Samples (64 blocks, :func:`dsp.robust.spread_block_starts`) from which
:func:`waveform_levels` estimates the levels and the noise of a longer waveform."""


def waveform_levels(signal: ArrayLike) -> tuple[float, float, float]:
    """Robust low and high state levels of a two-level waveform, and its noise RMS.

    The waveform is split at the midpoint of its 0.1 % and 99.9 % quantiles (so a few spikes
    do not move it); each level is the median of the samples on its side. The noise RMS is
    1.4826 × the median absolute first difference / √2 (edges are rare, so they do not bias it).
    A waveform longer than 65536 samples is represented by 64 blocks of 1024 consecutive samples
    starting at random positions drawn with a fixed seed: unlike a regular stride this cannot
    alias with the pulse period, and it keeps the cost to about a millisecond. (For a slow,
    noisy sine the threshold then differs from the full-data one by ~0.3 sample of edge time.)

    Parameters
    ----------
    signal : array_like
        1-D tachometer waveform.

    Returns
    -------
    low_level, high_level, noise_rms : float

    Examples
    --------
    >>> import numpy as np
    >>> ttl = np.tile([0.0] * 30 + [5.0] * 10, 20)
    >>> waveform_levels(ttl)
    (0.0, 5.0, 0.0)
    """
    x = np.asarray(signal).ravel()  # no float64 copy of a long (memory-mapped) waveform
    if x.size == 0:
        raise TachometerError("empty tachometer waveform")
    if x.size > LEVEL_SAMPLES:
        # contiguous blocks: cache-friendly; irregularly spaced: their phases cannot alias
        block = LEVEL_SAMPLES // SAMPLED_BLOCKS
        starts = spread_block_starts(x.size, block)
        blocks = np.asarray(x[starts[:, np.newaxis] + np.arange(block)], dtype=np.float64)
        values = blocks.ravel()
        steps = np.diff(blocks, axis=1).ravel()
    else:
        values = np.asarray(x, dtype=np.float64)
        steps = np.diff(values)
    lo_extreme, hi_extreme = np.percentile(values, [0.1, 99.9])
    mid = 0.5 * (lo_extreme + hi_extreme)
    below = values[values < mid]
    above = values[values >= mid]
    low_level = float(np.median(below)) if below.size else float(mid)
    high_level = float(np.median(above)) if above.size else float(mid)
    noise_rms = float(MAD_TO_SIGMA * np.median(np.abs(steps)) / np.sqrt(2.0)) if steps.size else 0.0
    return low_level, high_level, noise_rms


def _schmitt_flips(
    x: FloatArray, lower: float, upper: float
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Low-to-high flips of a Schmitt trigger: (last sample below ``lower``, first above ``upper``).

    The state starts unknown, so an edge in progress at the first sample is not a flip. The
    trigger is high after a sample above ``upper``, low after one below ``lower`` (below wins when
    both), unchanged in between; so a flip is the first sample of a run above ``upper`` whose
    latest sample below ``lower`` comes after the run before it (vectorised: no per-sample loop).
    """
    low = x < lower
    high = x > upper
    high &= ~low
    ends_low = np.flatnonzero(low[:-1] & ~low[1:])  # last sample of each run below
    if low[-1]:
        ends_low = np.append(ends_low, x.size - 1)
    starts_high = np.flatnonzero(~high[:-1] & high[1:]) + 1  # first sample of each run above
    if high[0]:
        starts_high = np.concatenate(([0], starts_high))
    # the latest sample above before a start is the end of the run above before it
    ends_high = np.flatnonzero(high[:-1] & ~high[1:])
    k_low = np.searchsorted(ends_low, starts_high) - 1  # latest run below ending before the start
    k_high = np.searchsorted(ends_high, starts_high) - 1
    last_low = np.append(ends_low, -1)[k_low]  # index −1: no such run (−1)
    last_high = np.append(ends_high, -1)[k_high]
    flips = (last_low >= 0) & (last_low > last_high)
    return last_low[flips].astype(np.int64), starts_high[flips].astype(np.int64)


def _edge_crossings(
    x: FloatArray, start: NDArray[np.int64], stop: NDArray[np.int64], threshold: float
) -> FloatArray:
    """Fractional sample index where each edge crosses ``threshold``.

    ``start[i]`` is the last sample below the lower hysteresis level, ``stop[i]`` the first one
    above the upper level; samples strictly between them lie inside the hysteresis band. All
    edges at once: the samples of every edge are gathered into one array and summed per edge.
    """
    out = np.empty(start.size)
    if start.size == 0:
        return out
    # samples a … b−1 of every edge, edge after edge
    lengths = stop - start
    offsets = np.concatenate(([0], np.cumsum(lengths)[:-1]))
    local = np.arange(int(lengths.sum())) - np.repeat(offsets, lengths)  # j − a
    values = x[np.repeat(start, lengths) + local]
    # Least-squares line through the in-band samples (j = a+1 … b−1, t = j − a), then solve
    # line(t) = threshold: the sums over each edge's interior (its first sample, t = 0, left out).
    interior = lengths - 1
    inside = local > 0
    sx = np.add.reduceat(np.where(inside, values, 0.0), offsets)
    stx = np.add.reduceat(np.where(inside, local * values, 0.0), offsets)
    m = interior.astype(np.float64)
    st = m * (m + 1) / 2
    stt = m * (m + 1) * (2 * m + 1) / 6
    denom = m * stt - st * st
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = (m * stx - st * sx) / denom
        intercept = (sx - slope * st) / m
        fitted = start + np.minimum(np.maximum((threshold - intercept) / slope, 0.0), lengths)
    fit = (interior >= MIN_FIT_SAMPLES) & (slope > 0.0)
    # Fast edge (or a flat fit): last upward crossing of the threshold inside [a, b]: the last
    # sample j in a … b−1 at or below it (a when none), interpolated to j + 1.
    below = np.where((values <= threshold) | ~inside, local, 0)
    j = start + np.maximum.reduceat(below, offsets)
    x0, x1 = x[j], x[j + 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        frac = np.where(x1 != x0, (threshold - x0) / (x1 - x0), 0.5)
    interpolated = j + np.minimum(np.maximum(frac, 0.0), 1.0)
    out[:] = np.where(fit, fitted, interpolated)
    return out


def pulse_times_from_waveform(
    signal: ArrayLike,
    sample_rate_hz: float,
    *,
    threshold: float | None = None,
    hysteresis: float | None = None,
    edge: Literal["rising", "falling"] = "rising",
) -> FloatArray:
    """Edge times of a tachometer waveform, with hysteresis and sub-sample interpolation.

    A Schmitt trigger with levels ``threshold ± hysteresis/2`` finds each edge: an edge is
    counted when the waveform goes from below the lower level to above the upper level (for
    ``edge="falling"`` the other way), so noise smaller than the band cannot make extra edges.
    The edge *time* is where the waveform crosses ``threshold`` itself: a least-squares line
    through the samples inside the band when there are at least 3 of them (a slow, noisy edge),
    otherwise linear interpolation between the two samples bracketing the threshold (a fast TTL
    edge; exact for a linear ramp). An edge already in progress at the first sample is not
    reported, since its start is unknown.

    Parameters
    ----------
    signal : array_like
        1-D tachometer waveform (any units).
    sample_rate_hz : float
        Sampling rate of ``signal``.
    threshold : float, optional
        Decision level. Default: midway between the robust low and high levels
        (:func:`waveform_levels`).
    hysteresis : float, optional
        Full width of the Schmitt band. Default: 8 × the estimated noise RMS, at least 40 % and at
        most 60 % of the level difference (a wide band also puts more samples into the edge fit).
    edge : {"rising", "falling"}
        Which edge marks a pulse.

    Returns
    -------
    ndarray
        Edge times in seconds from the first sample, increasing. Empty if the waveform has no
        edge (for example a constant signal).

    Raises
    ------
    TachometerError
        Non-finite samples, a 2-D signal, or a bad parameter.

    Examples
    --------
    >>> import numpy as np
    >>> n = np.arange(1000)
    >>> ttl = 5.0 * np.clip(((n % 100) - 40.75) / 2 + 0.5, 0, 1)  # 2.5 V at sample 40.75 + 100 k
    >>> pulse_times_from_waveform(ttl, sample_rate_hz=1000.0)[:3]
    array([0.04075, 0.14075, 0.24075])
    """
    x = np.asarray(signal, dtype=np.float64)
    if x.ndim != 1:
        raise TachometerError(f"tachometer waveform must be 1-D, got shape {x.shape}")
    if not np.isfinite(sample_rate_hz) or sample_rate_hz <= 0:
        raise TachometerError(f"sample rate must be positive, got {sample_rate_hz}")
    if edge not in ("rising", "falling"):
        raise TachometerError(f"edge must be 'rising' or 'falling', got {edge!r}")
    if x.size < 2:
        return np.empty(0)
    if not np.all(np.isfinite(x)):
        raise TachometerError("tachometer waveform contains NaN or infinite samples")
    if hysteresis is not None and (not np.isfinite(hysteresis) or hysteresis < 0):
        raise TachometerError(f"hysteresis must be >= 0, got {hysteresis}")

    if threshold is None or hysteresis is None:
        settings = schmitt_settings(x)
        if settings is None:
            return np.empty(0)
        threshold = settings[0] if threshold is None else threshold
        hysteresis = settings[1] if hysteresis is None else hysteresis
    if edge == "falling":
        # A falling edge of x is a rising edge of -x.
        x = -x
        threshold = -threshold

    upper = threshold + 0.5 * hysteresis
    lower = threshold - 0.5 * hysteresis
    start, stop = _schmitt_flips(np.ascontiguousarray(x), float(lower), float(upper))
    crossings = _edge_crossings(x, start, stop, float(threshold))
    return np.asarray(crossings / float(sample_rate_hz), dtype=np.float64)


def schmitt_settings(signal: ArrayLike) -> tuple[float, float] | None:
    """Default ``(threshold, hysteresis)`` of :func:`pulse_times_from_waveform` for a waveform.

    Threshold midway between the levels of :func:`waveform_levels`; hysteresis 8 × the noise
    RMS, kept within 40–60 % of the swing. ``None`` for a waveform with no swing (no pulses).

    Examples
    --------
    >>> import numpy as np
    >>> schmitt_settings(np.tile([0.0] * 30 + [5.0] * 10, 20))
    (2.5, 2.0)
    """
    low_level, high_level, noise_rms = waveform_levels(signal)
    swing = high_level - low_level
    if swing <= 0:
        return None
    return 0.5 * (low_level + high_level), min(max(8.0 * noise_rms, 0.4 * swing), 0.6 * swing)


def pulse_times_from_waveform_blocks(
    signal: ArrayLike,
    sample_rate_hz: float,
    *,
    block_samples: int,
    overlap_samples: int = 1 << 16,
    edge: Literal["rising", "falling"] = "rising",
    levels: tuple[float, float] | None = None,
    transform: Callable[[FloatArray], FloatArray] | None = None,
) -> FloatArray:
    """:func:`pulse_times_from_waveform` on a long waveform, one block at a time.

    Only one block is converted to float64 at a time, so a memory-mapped hour of waveform needs
    a few blocks of memory. The Schmitt levels ``(threshold, hysteresis)`` are ``levels`` when
    given, else those of the whole waveform (:func:`schmitt_settings`, which samples it); a
    ``transform`` is applied to each block (with its overlap) before it is read (the local
    scale of :mod:`dsp.tachlevels`). Block ``b`` keeps the edges whose time falls in
    its own span; it looks ``overlap_samples`` back (so the trigger's state is settled, which
    needs at least one pulse period) and as far ahead (so an edge straddling its end is
    complete). The edges are then those of the whole waveform processed at once.

    Examples
    --------
    >>> import numpy as np
    >>> n = np.arange(100_000)
    >>> ttl = 5.0 * np.clip(((n % 1000) - 40.75) / 2 + 0.5, 0, 1)
    >>> whole = pulse_times_from_waveform(ttl, 1000.0)
    >>> bool(np.array_equal(pulse_times_from_waveform_blocks(ttl, 1000.0, block_samples=7000,
    ...      overlap_samples=2500), whole))
    True
    """
    x = np.asarray(signal).ravel()
    if block_samples < 1 or overlap_samples < 0:
        raise TachometerError("block_samples must be >= 1 and overlap_samples >= 0")
    settings = levels or schmitt_settings(x)
    if settings is None:
        return np.empty(0)
    threshold, hysteresis = settings
    times: list[FloatArray] = []
    for start in range(0, x.size, block_samples):
        stop = min(x.size, start + block_samples)
        first = max(0, start - overlap_samples)
        last = min(x.size, stop + overlap_samples)
        block = np.asarray(x[first:last], dtype=np.float64)
        if transform is not None:
            block = transform(block)
        edges = pulse_times_from_waveform(
            block, sample_rate_hz, threshold=threshold, hysteresis=hysteresis, edge=edge
        ) + first / float(sample_rate_hz)
        keep = (edges >= start / sample_rate_hz) & (edges < stop / sample_rate_hz)
        times.append(edges[keep])
    return np.concatenate(times) if times else np.empty(0)


# --------------------------------------------------------------------------- pulse repair


def _local_period(intervals: FloatArray) -> FloatArray:
    """Running median of the pulse intervals (robust to an isolated missing or extra pulse).

    Centred window of ``LOCAL_PERIOD_WINDOW`` intervals; near the ends the first or last full
    window is used (not edge replication, which would let an end outlier be its own median).
    """
    n = intervals.size
    if n < 3:
        return np.full(intervals.shape, float(np.median(intervals)))
    window = min(LOCAL_PERIOD_WINDOW, n)
    medians = np.median(np.lib.stride_tricks.sliding_window_view(intervals, window), axis=1)
    half = window // 2
    out = np.empty(n)
    out[half : half + medians.size] = medians
    out[:half] = medians[0]
    out[half + medians.size :] = medians[-1]
    return out


def _validate_pulse_times(pulse_times_s: ArrayLike) -> FloatArray:
    t = np.asarray(pulse_times_s, dtype=np.float64)
    if t.ndim != 1:
        raise TachometerError(f"pulse times must be 1-D, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise TachometerError("pulse times contain NaN or infinite values")
    if t.size > 1 and np.any(np.diff(t) <= 0):
        bad = int(np.flatnonzero(np.diff(t) <= 0)[0])
        raise TachometerError(
            f"pulse times are not strictly increasing (pulse {bad + 1} at {t[bad + 1]:.6g} s)"
        )
    return t


def repair_pulse_times(
    pulse_times_s: ArrayLike, *, tolerance: float = 0.3
) -> tuple[FloatArray, tuple[PulseRepair, ...]]:
    """Repair isolated missing and extra pulses in a pulse train.

    The local period ``P`` at each interval is the running median of 9 neighbouring intervals.
    With ``r = interval / P``:

    - an interval with ``|r/2 - 1| <= tolerance`` (≈ 2 periods) lost one pulse: a pulse is
      inserted at its midpoint;
    - a short interval (``r < 1 - tolerance``) that together with a neighbour makes one period
      (``|r_i + r_neighbour - 1| <= tolerance``) holds a spurious pulse: the pulse they share is
      removed (the pairing whose sum is closer to 1 wins; at the record ends, removing the
      outer pulse is a third hypothesis, chosen when the interval beyond is then closest to 1).

    Anything else (for example a gap of 3 periods) is left as it is; :func:`analyze_tachometer`
    refuses such a record. Pulses are assumed equally spaced in shaft angle.

    Parameters
    ----------
    pulse_times_s : array_like
        Increasing pulse times (s).
    tolerance : float
        Relative tolerance on the period, in (0, 0.5).

    Returns
    -------
    repaired : ndarray
        Repaired pulse times.
    repairs : tuple of PulseRepair
        What was done, in time order.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.delete(np.arange(30) * 0.1, 12)          # pulse 12 lost
    >>> repaired, repairs = repair_pulse_times(t)
    >>> repaired.size, repairs[0].kind, round(repairs[0].time_s, 9)
    (30, 'missing', 1.2)
    """
    if not 0.0 < tolerance < 0.5:
        raise TachometerError(f"repair tolerance must be in (0, 0.5), got {tolerance}")
    t = _validate_pulse_times(pulse_times_s)
    if t.size < 4:
        return t.copy(), ()
    intervals = np.diff(t)
    ratio = intervals / _local_period(intervals)
    n_int = intervals.size

    remove: set[int] = set()
    insert: list[tuple[int, float]] = []
    consumed = np.zeros(n_int, dtype=bool)
    for i in np.flatnonzero(np.abs(ratio - 1.0) > tolerance):
        if consumed[i]:
            continue
        r = ratio[i]
        if abs(r / 2.0 - 1.0) <= tolerance:
            insert.append((int(i) + 1, 0.5 * (t[i] + t[i + 1])))
            consumed[i] = True
            continue
        if r >= 1.0 - tolerance:
            continue  # long but not ≈ 2 periods: unexplained, left for the caller's check
        # Hypotheses: (deviation of the merged or remaining interval from 1, neighbour interval
        # consumed or -1, pulse to remove).
        candidates: list[tuple[float, int, int]] = []
        if i > 0 and not consumed[i - 1]:
            candidates.append((abs(r + ratio[i - 1] - 1.0), int(i) - 1, int(i)))
        if i + 1 < n_int and not consumed[i + 1]:
            candidates.append((abs(r + ratio[i + 1] - 1.0), int(i) + 1, int(i) + 1))
        if i == 0:  # the first pulse itself may be the spurious one
            candidates.append((abs(ratio[1] - 1.0), -1, 0))
        if i == n_int - 1:
            candidates.append((abs(ratio[i - 1] - 1.0), -1, n_int))
        candidates = [c for c in candidates if c[0] <= tolerance]
        if candidates:
            _, neighbour, pulse = min(candidates)
            remove.add(pulse)
            consumed[i] = True
            if neighbour >= 0:
                consumed[neighbour] = True

    repairs = [PulseRepair("extra", k, float(t[k])) for k in remove]
    repairs += [PulseRepair("missing", k, float(time_s)) for k, time_s in insert]
    repairs.sort(key=lambda rep: rep.time_s)
    keep = np.ones(t.size, dtype=bool)
    keep[list(remove)] = False
    repaired = np.concatenate([t[keep], np.array([time_s for _, time_s in insert])])
    repaired.sort()
    return repaired, tuple(repairs)


# --------------------------------------------------------------------------- analysis


def analyze_tachometer(
    pulse_times_s: ArrayLike,
    pulses_per_rev: int,
    *,
    max_speed_variation: float = DEFAULT_MAX_SPEED_VARIATION,
    min_revolutions: int = 20,
    min_speed_rpm: float = 1.0,
    max_speed_rpm: float = 100_000.0,
    repair_tolerance: float = 0.3,
    bridge: bool = True,
) -> TachAnalysis:
    """Repair a pulse train, measure the tach-shaft speed and accept or refuse the record.

    Steps: :func:`repair_pulse_times`; refuse a record whose intervals are still off the local
    period by more than ``repair_tolerance`` while every period is within
    :data:`SMOOTH_STEP_LIMIT` of the previous one (a speed that changes too fast for order
    tracking, which the reason then says); bridge the stretches one missing or extra pulse
    cannot explain (a burst of interference, a gap: :func:`dsp.tachgaps.bridge_unexplained`),
    refusing the tach when they cover more than :data:`dsp.tachgaps.MAX_BRIDGED_FRACTION` of it
    or, with several pulses per revolution, when the count of periods in one is not sure (with
    ``bridge`` False: refusing any such stretch); take
    every ``pulses_per_rev``-th pulse from the first as the revolution marks; refuse if fewer
    than ``min_revolutions`` whole revolutions, if any per-revolution speed is outside
    ``[min_speed_rpm, max_speed_rpm]``, or if ``(max - min) / mean`` of the per-revolution speed
    exceeds ``max_speed_variation``. The boundaries themselves pass.

    Parameters
    ----------
    pulse_times_s : array_like
        Increasing pulse times (s), e.g. from :func:`pulse_times_from_waveform`.
    pulses_per_rev : int
        Pulses per revolution of the tach shaft.
    max_speed_variation : float
        Largest accepted ``(max - min) / mean`` of the per-revolution speed.
    min_revolutions : int
        Fewest accepted whole revolutions of the tach shaft.
    min_speed_rpm, max_speed_rpm : float
        Accepted speed range of the tach shaft (every revolution must be inside).
    repair_tolerance : float
        Relative period tolerance for repairs and for the regularity check.
    bridge : bool
        Bridge unexplained stretches (True) or refuse the record (False: a pulse train that is
        itself an estimate, such as the mesh-phase angle's, is not patched).

    Returns
    -------
    TachAnalysis

    Raises
    ------
    TachometerError
        The record is refused; ``str()`` says why in one line.

    Examples
    --------
    >>> import numpy as np
    >>> pulses = np.arange(10) * 0.06
    >>> analyze_tachometer(pulses, 1)
    Traceback (most recent call last):
    ...
    dsp.tach.RecordOutOfTachLimits: only 9 whole revolutions of the tach shaft (10 pulses at 1 per revolution); at least 20 are required
    """
    if isinstance(pulses_per_rev, bool) or int(pulses_per_rev) != pulses_per_rev:
        raise TachometerError(f"pulses per revolution must be an integer, got {pulses_per_rev!r}")
    pulses_per_rev = int(pulses_per_rev)
    if pulses_per_rev < 1:
        raise TachometerError(f"pulses per revolution must be >= 1, got {pulses_per_rev}")
    if min_revolutions < 1:
        raise TachometerError(f"min_revolutions must be >= 1, got {min_revolutions}")
    if not max_speed_variation >= 0:
        raise TachometerError(f"max_speed_variation must be >= 0, got {max_speed_variation}")
    if not 0 <= min_speed_rpm < max_speed_rpm:
        raise TachometerError(
            f"speed range must satisfy 0 <= min < max, got [{min_speed_rpm}, {max_speed_rpm}] rpm"
        )

    t = _validate_pulse_times(pulse_times_s)
    if t.size == 0:
        raise TachometerError("no tachometer pulses found")
    if t.size < 3:
        raise TachometerError(f"too few tachometer pulses ({t.size}) to measure a speed")

    repaired, repairs, stretches = _sound_pulse_train(t, pulses_per_rev, repair_tolerance, bridge)
    rev_times = repaired[::pulses_per_rev]
    whole = rev_times.size - 1
    if whole < min_revolutions:
        raise RecordOutOfTachLimits(
            f"only {whole} whole revolutions of the tach shaft ({repaired.size} pulses at "
            f"{pulses_per_rev} per revolution); at least {min_revolutions} are required"
        )
    rev_speed = 60.0 / np.diff(rev_times)
    bridged_spans = tuple(
        (s.start_s - s.local_period_s, s.stop_s + s.local_period_s) for s in stretches
    )
    measured = _outside_spans(rev_speed, rev_times, bridged_spans)
    mean_rpm = float(np.mean(measured))
    min_rpm = float(np.min(measured))
    max_rpm = float(np.max(measured))
    if min_rpm < min_speed_rpm or max_rpm > max_speed_rpm:
        raise RecordOutOfTachLimits(
            f"tach-shaft speed {min_rpm:.6g}-{max_rpm:.6g} rpm is outside the accepted range "
            f"[{min_speed_rpm:g}, {max_speed_rpm:g}] rpm"
        )
    variation = (max_rpm - min_rpm) / mean_rpm
    if variation > max_speed_variation:
        raise RecordOutOfTachLimits(
            f"speed varies too much within the record: (max - min)/mean = {variation:.3f} "
            f"({min_rpm:.6g}-{max_rpm:.6g} rpm) exceeds {max_speed_variation:g}"
        )
    return TachAnalysis(
        pulse_times_s=repaired,
        pulses_per_rev=pulses_per_rev,
        repairs=repairs,
        rev_times_s=rev_times,
        rev_speed_rpm=rev_speed,
        mean_rpm=mean_rpm,
        min_rpm=min_rpm,
        max_rpm=max_rpm,
        speed_variation=float(variation),
        whole_revolutions=int(whole),
        bridged_spans_s=bridged_spans,
    )


def _sound_pulse_train(
    t: FloatArray, pulses_per_rev: int, tolerance: float, bridge: bool
) -> tuple[FloatArray, tuple[PulseRepair, ...], tuple[BridgedStretch, ...]]:
    """:func:`analyze_tachometer`'s repairs: the repaired pulses, the repairs, the bridges — or
    the refusal of a speed that changes too fast, or of a train still irregular."""
    repaired, repairs = repair_pulse_times(t, tolerance=tolerance)
    intervals = np.diff(repaired)
    deviation = intervals / _local_period(intervals) - 1.0
    irregular = np.flatnonzero(np.abs(deviation) > tolerance)
    if irregular.size:
        # Each interval within a few % of its neighbours, yet far from the running median: the
        # speed itself moves too fast (a run-up, a stop), not a lost or spurious pulse.
        steps = np.abs(np.diff(intervals) / intervals[:-1])
        if steps.size and float(np.max(steps)) <= SMOOTH_STEP_LIMIT:
            i = int(irregular[0])
            raise TachometerError(
                f"speed changes too fast for order tracking: the pulse period changes by up to "
                f"{float(np.max(steps)):.1%} per pulse and is {1 + deviation[i]:.2f}× its "
                f"{LOCAL_PERIOD_WINDOW}-pulse running median at {repaired[i]:.6g} s (accepted: "
                f"within {tolerance:.0%}, i.e. about {tolerance / 4:.0%} per pulse)"
            )
    stretches: tuple[BridgedStretch, ...] = ()
    if bridge:
        # bursts and gaps first, on the pulses as found (single repairs guess wrong inside a
        # burst); then the isolated missing and extra pulses, as before
        bridged, stretches = bridge_unexplained(t, tolerance=tolerance)
        if stretches:
            repaired, repairs = repair_pulse_times(bridged, tolerance=tolerance)
            repairs = tuple(sorted(
                repairs + tuple(PulseRepair("bridged", s.index, s.start_s) for s in stretches),
                key=lambda rep: rep.time_s,
            ))
        intervals = np.diff(repaired)
        deviation = intervals / _local_period(intervals) - 1.0
        unexplained = np.abs(deviation) > tolerance
        period = burst_proof_period(intervals, 0.5 * (repaired[:-1] + repaired[1:]))
        if period is not None:  # (None: nothing near a plausible period; the running median judges)
            unexplained |= unexplained_intervals(intervals / period, intervals, tolerance)
        irregular = np.flatnonzero(unexplained)
    if irregular.size:
        i = int(irregular[0])
        raise TachometerError(
            f"irregular tachometer: {irregular.size} pulse interval(s) not explained by one missing "
            f"or extra pulse, first at {repaired[i]:.6g} s ({1 + deviation[i]:.2f}× the local period)"
        )
    problem = bridge_problem(stretches, repaired, pulses_per_rev)
    if problem:
        raise TachometerError(problem)
    return repaired, repairs, stretches


def _outside_spans(
    rev_speed: FloatArray, rev_times: FloatArray, spans: tuple[tuple[float, float], ...]
) -> FloatArray:
    """The per-revolution speeds outside the bridged spans (all of them when every revolution is
    inside one): the speed inside a bridge is a guess, not a measurement."""
    if not spans:
        return rev_speed
    inside = np.zeros(rev_speed.size, dtype=bool)
    for lo, hi in spans:
        inside |= (rev_times[1:] > lo) & (rev_times[:-1] < hi)
    return rev_speed[~inside] if not inside.all() else rev_speed
