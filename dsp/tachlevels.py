"""Edges of a tachometer waveform whose levels drift: a Schmitt trigger that follows them.

:func:`dsp.tach.pulse_times_from_waveform` decides at fixed levels taken from the whole record.
A proximity probe's gap voltage drifts with temperature, an AC-coupled input's baseline follows
the pulse train, a sensor working loose fades: once the drift is a third of the pulse height,
fixed levels miss edges over whole stretches (measured on a 5-V TTL with a slow sine drift:
±1.5 V lost 66 of 333 revolutions to bridged stretches, ±2 V made the tach unusable). Here the
levels are those of the waveform's own neighbourhood: the running maximum and minimum over
:data:`LEVEL_WINDOW_PERIODS` pulse periods, smoothed over the same window; the waveform is put on
that local scale (mid-level 0, swing 1) and read by the same Schmitt trigger at ±0.2. Where the
local swing falls below :data:`DEAD_SWING_FRACTION` of the record's typical one (no pulses: a
dead stretch) no edge is read, so the stretch is a gap for :mod:`dsp.tachgaps`.

:func:`gearwatch.usecases.shaft_angle` uses it only when the fixed levels left a tach that had to
be bridged or refused, so a sound tach is read exactly as before.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import maximum_filter1d, minimum_filter1d, uniform_filter1d

from dsp.robust import SAMPLED_BLOCKS, spread_block_starts
from dsp.tach import TachometerError, pulse_times_from_waveform_blocks

FloatArray = NDArray[np.float64]

LEVEL_WINDOW_PERIODS = 2.5
"""Pulse periods over which the local levels are taken: every window holds a whole pulse, so both
levels are in it."""

DEAD_SWING_FRACTION = 0.25
"""A neighbourhood whose swing is below this share of the record's typical swing (its 90th
percentile) holds no pulse: nothing is read there."""

RELATIVE_HYSTERESIS = 0.4
"""Full width of the Schmitt band on the local scale (swing 1): ±0.2 about the local mid-level,
the middle of :func:`dsp.tach.schmitt_settings`' 40–60 %."""


def pulse_times_tracking_levels(
    signal: ArrayLike,
    sample_rate_hz: float,
    period_s: float,
    *,
    block_samples: int = 1 << 20,
    edge: Literal["rising", "falling"] = "rising",
) -> FloatArray:
    """Edge times of a tach waveform read against its local levels (module docstring).

    Parameters
    ----------
    signal : array_like
        1-D tachometer waveform (it may be memory-mapped: read a block at a time).
    sample_rate_hz : float
    period_s : float
        A rough pulse period (the median interval of a first reading will do): it sets the
        window of the local levels.
    block_samples : int
        Samples converted to float64 at a time; neighbouring blocks overlap by two windows.
    edge : {"rising", "falling"}

    Returns
    -------
    ndarray
        Edge times in seconds from the first sample, increasing.

    Examples
    --------
    A TTL whose baseline drifts by ±2.5 V, half its height, over the record: fixed levels read
    little of it, the local ones every edge.

    >>> n = np.arange(200_000)
    >>> ttl = 5.0 * (n % 1000 < 250) + 2.5 * np.sin(2 * np.pi * n / 200_000)
    >>> true = np.arange(1, 200) * 1000 / 10_000
    >>> from dsp.tach import pulse_times_from_waveform
    >>> int(pulse_times_from_waveform(ttl, 10_000.0).size) < 150
    True
    >>> found = pulse_times_tracking_levels(ttl, 10_000.0, 0.1)
    >>> found.size, bool(np.allclose(found, true, atol=1e-4))
    (199, True)
    """
    x = np.asarray(signal).ravel()
    if not (np.isfinite(period_s) and period_s > 0):
        raise TachometerError(f"pulse period must be positive, got {period_s}")
    window = max(3, round(LEVEL_WINDOW_PERIODS * period_s * sample_rate_hz))
    typical = _typical_swing(x, window)
    if typical <= 0:
        return np.empty(0)
    rail = -0.5 if edge == "rising" else 0.5

    def on_local_scale(block: FloatArray) -> FloatArray:
        if not np.all(np.isfinite(block)):  # the running levels would hide them
            raise TachometerError("tachometer waveform contains NaN or infinite samples")
        return _on_local_scale(block, window, typical, rail)

    return pulse_times_from_waveform_blocks(
        x, sample_rate_hz, block_samples=block_samples, overlap_samples=2 * window + 16,
        edge=edge, levels=(0.0, RELATIVE_HYSTERESIS), transform=on_local_scale,
    )


def _local_levels(segment: FloatArray, window: int) -> tuple[FloatArray, FloatArray]:
    """Smoothed running (low, high) levels of a segment."""
    high = uniform_filter1d(maximum_filter1d(segment, window, mode="nearest"), window, mode="nearest")
    low = uniform_filter1d(minimum_filter1d(segment, window, mode="nearest"), window, mode="nearest")
    return low, high


def _typical_swing(x: NDArray[np.generic], window: int) -> float:
    """90th percentile of the local swing, from up to 64 stretches of 8 windows spread over the
    record (:func:`dsp.robust.spread_block_starts`: the same record gives the same value)."""
    span = min(x.size, 8 * window)
    starts = [0] if x.size <= SAMPLED_BLOCKS * span else spread_block_starts(x.size, span)
    swings = []
    for s in starts:
        low, high = _local_levels(np.asarray(x[s : s + span], dtype=np.float64), window)
        swings.append(high - low)
    return float(np.percentile(np.concatenate(swings), 90))


def _on_local_scale(segment: FloatArray, window: int, typical: float, rail: float) -> FloatArray:
    """The segment with its local mid-level at 0 and its local swing 1; dead stretches held at
    ``rail`` (the level before the marking edge), where no edge is read."""
    low, high = _local_levels(segment, window)
    swing = high - low
    alive = swing >= DEAD_SWING_FRACTION * typical
    scaled = np.full(segment.size, rail)
    scaled[alive] = (segment[alive] - 0.5 * (low[alive] + high[alive])) / swing[alive]
    return scaled
