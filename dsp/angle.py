"""Computed order tracking: resample a time signal onto a uniform shaft-angle grid.

Method (what :func:`angle_resample` does, in order):

1. **Phase model.** Pulse ``k`` of the tachometer is at tach-shaft angle ``k / pulses_per_rev``
   revolutions; the first pulse (the reference edge) is angle 0. A cubic spline (not-a-knot)
   through the points (angle, pulse time) gives the time at any angle, so only the grid times are
   interpolated from the pulses, never the raw signal. If the spline is not strictly increasing
   over the grid (a violent speed change between pulses) a monotone PCHIP is used instead.
2. **Grid.** The target shaft turns ``shaft_ratio`` revolutions per tach-shaft revolution. Its
   grid is ``samples_per_rev`` equally spaced angles per revolution, from angle 0, over the whole
   target-shaft revolutions that lie inside both the pulse span (no extrapolation) and the record.
3. **Anti-aliasing in the angle domain.** The grid samples the signal at
   ``samples_per_rev × target-shaft speed`` samples per second. When that rate, at the *lowest*
   speed between two pulses, is below the time sampling rate, the signal is first low-passed by a
   zero-phase FFT filter: gain 1 up to 80 % of the lowest angular Nyquist frequency
   (``0.5 × samples_per_rev × min speed``), a raised-cosine roll-off to gain 0 at that Nyquist
   frequency, 0 above. The record is extended by even reflection at both ends during filtering so
   that the circular FFT does not wrap the end onto the start. Otherwise no filter is applied.
4. **Interpolation.** The signal is interpolated at the grid times by a cardinal quintic
   B-spline (degree-5 spline through every sample: a recursive prefilter then a 6-tap local
   evaluation, :func:`scipy.ndimage.spline_filter1d` and :func:`scipy.ndimage.map_coordinates`,
   mirror boundary). It is O(n), about ten times faster than a global
   :class:`scipy.interpolate.CubicSpline` of the record, and more accurate at every frequency
   (for a tone at 0.1 × the sampling rate: 2e-6 vs 2e-4 RMS error relative to its amplitude).

References: Fyfe & Munck 1997, "Analysis of computed order tracking", MSSP 11(2); McFadden 1987,
"A revised model for the extraction of periodic waveforms by time domain averaging", MSSP 1(1).

Examples
--------
>>> import numpy as np
>>> fs = 10_000.0
>>> t = np.arange(20_000) / fs
>>> pulses = np.arange(0.01, 1.99, 0.05)       # 1200 rpm, 1 pulse/rev
>>> x = np.cos(2 * np.pi * 5 * (t - 0.01) / 0.05)   # order 5 of the shaft
>>> revs = angle_resample(x, fs, pulses, 1, 64)
>>> revs.shape
(39, 64)
>>> bool(np.allclose(revs[3], np.cos(2 * np.pi * 5 * np.arange(64) / 64), atol=1e-4))
True
"""

from __future__ import annotations

import numpy as np
import scipy.fft
from numpy.typing import ArrayLike, NDArray
from scipy import ndimage
from scipy.interpolate import CubicSpline, PchipInterpolator

__all__ = [
    "DEFAULT_SAMPLES_PER_MESH",
    "INTERPOLATION_ORDER",
    "angle_grid_times",
    "angle_lowpass",
    "angle_resample",
    "samples_per_revolution",
]

FloatArray = NDArray[np.float64]

DEFAULT_SAMPLES_PER_MESH = 64
"""Samples per mesh period (El Badaoui et al. 2001 use 64, with a 64-sample MCI window)."""

INTERPOLATION_ORDER = 5
"""Degree of the cardinal B-spline used to interpolate the signal at the grid times."""

PASSBAND_FRACTION = 0.8
"""Anti-alias filter: gain 1 up to this fraction of the lowest angular Nyquist frequency."""

_ANGLE_EPS = 1e-9
"""Revolutions; absorbs rounding when the pulse span is an exact whole number of revolutions."""


def samples_per_revolution(teeth: int, samples_per_mesh: int = DEFAULT_SAMPLES_PER_MESH) -> int:
    """Samples per shaft revolution = teeth × samples per mesh period.

    Examples
    --------
    >>> samples_per_revolution(20)
    1280
    """
    if teeth < 1 or samples_per_mesh < 1:
        raise ValueError(
            f"teeth and samples_per_mesh must be >= 1, got {teeth}, {samples_per_mesh}"
        )
    return int(teeth) * int(samples_per_mesh)


def _check_pulses(pulse_times_s: ArrayLike, pulses_per_rev: int) -> FloatArray:
    t = np.asarray(pulse_times_s, dtype=np.float64)
    if t.ndim != 1 or t.size < 2:
        raise ValueError(f"need a 1-D array of at least 2 pulse times, got shape {t.shape}")
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ValueError("pulse times must be finite and strictly increasing")
    if int(pulses_per_rev) != pulses_per_rev or pulses_per_rev < 1:
        raise ValueError(f"pulses_per_rev must be a positive integer, got {pulses_per_rev}")
    return t


def angle_grid_times(
    pulse_times_s: ArrayLike,
    pulses_per_rev: int,
    samples_per_rev: int,
    *,
    shaft_ratio: float = 1.0,
    record_duration_s: float | None = None,
) -> FloatArray:
    """Times at which the target shaft passes each angle of a uniform grid.

    Parameters
    ----------
    pulse_times_s : array_like
        Tachometer pulse times (s), strictly increasing; the first is angle 0.
    pulses_per_rev : int
        Pulses per tach-shaft revolution (equally spaced in angle).
    samples_per_rev : int
        Grid points per target-shaft revolution.
    shaft_ratio : float
        Target-shaft revolutions per tach-shaft revolution.
    record_duration_s : float, optional
        Keep only revolutions whose grid times are all ``<= record_duration_s``.

    Returns
    -------
    ndarray, shape (n_revs, samples_per_rev)
        Grid times (s) of the whole target-shaft revolutions available.

    Examples
    --------
    >>> angle_grid_times([0.0, 1.0, 2.0], 1, 4)
    array([[0.  , 0.25, 0.5 , 0.75],
           [1.  , 1.25, 1.5 , 1.75]])
    """
    t = _check_pulses(pulse_times_s, pulses_per_rev)
    if int(samples_per_rev) != samples_per_rev or samples_per_rev < 2:
        raise ValueError(f"samples_per_rev must be an integer >= 2, got {samples_per_rev}")
    if not np.isfinite(shaft_ratio) or shaft_ratio <= 0:
        raise ValueError(f"shaft_ratio must be positive, got {shaft_ratio}")
    samples_per_rev = int(samples_per_rev)
    tach_angle_rev = np.arange(t.size) / pulses_per_rev
    n_revs = int(np.floor(shaft_ratio * tach_angle_rev[-1] + _ANGLE_EPS))
    if n_revs < 1:
        return np.empty((0, samples_per_rev))
    # Tach-shaft angle of every grid point; clip the last one onto the span against rounding.
    grid_tach_angle = np.arange(n_revs * samples_per_rev) / (samples_per_rev * shaft_ratio)
    np.minimum(grid_tach_angle, tach_angle_rev[-1], out=grid_tach_angle)
    times = CubicSpline(tach_angle_rev, t)(grid_tach_angle)
    if np.any(np.diff(times) <= 0):
        times = PchipInterpolator(tach_angle_rev, t)(grid_tach_angle)
    times = times.reshape(n_revs, samples_per_rev)
    if record_duration_s is not None:
        inside = np.all(times <= record_duration_s, axis=1)
        times = times[: int(np.argmin(inside)) if not inside.all() else n_revs]
    return np.asarray(times, dtype=np.float64)


def angle_lowpass(
    signal: ArrayLike, sample_rate_hz: float, cutoff_hz: float, *, axis: int = -1
) -> FloatArray:
    """Zero-phase FFT low-pass used as the angle-domain anti-alias filter.

    Gain 1 below ``PASSBAND_FRACTION × cutoff_hz``, raised-cosine roll-off to exactly 0 at
    ``cutoff_hz``, 0 above. The signal is extended by even reflection (by up to 20 periods of
    the roll-off width, at most the record length) before filtering and cropped afterwards, so
    the FFT's circularity does not wrap the end onto the start; within about one period of the
    roll-off width of either end the output is approximate.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(4000) / 1000.0
    >>> x = np.sin(2 * np.pi * 50 * t) + np.sin(2 * np.pi * 300 * t)
    >>> y = angle_lowpass(x, 1000.0, cutoff_hz=200.0)
    >>> bool(np.allclose(y[500:-500], np.sin(2 * np.pi * 50 * t[500:-500]), atol=1e-3))
    True
    """
    x = np.moveaxis(np.asarray(signal, dtype=np.float64), axis, -1)
    n = x.shape[-1]
    pass_hz = PASSBAND_FRACTION * cutoff_hz
    transition_hz = cutoff_hz - pass_hz
    pad = min(n - 1, int(np.ceil(20.0 * sample_rate_hz / transition_hz)))
    widths = [(0, 0)] * (x.ndim - 1) + [(pad, pad)]
    # Even reflection keeps the value continuous at the ends without adding a local offset
    # (odd reflection would turn out-of-band content at the last sample into a step).
    padded = np.pad(x, widths, mode="reflect") if pad > 0 else x
    n_fft = scipy.fft.next_fast_len(padded.shape[-1], real=True)
    freqs = np.fft.rfftfreq(n_fft, d=1.0 / sample_rate_hz)
    gain = np.clip((cutoff_hz - freqs) / transition_hz, 0.0, 1.0)
    gain = 0.5 - 0.5 * np.cos(np.pi * gain)  # raised cosine: 1 in the pass band, 0 in the stop band
    spectrum = scipy.fft.rfft(padded, n=n_fft, axis=-1)
    filtered = scipy.fft.irfft(spectrum * gain, n=n_fft, axis=-1)[..., pad : pad + n]
    return np.moveaxis(np.asarray(filtered, dtype=np.float64), -1, axis)


def angle_resample(
    signal: ArrayLike,
    sample_rate_hz: float,
    pulse_times_s: ArrayLike,
    pulses_per_rev: int,
    samples_per_rev: int,
    *,
    shaft_ratio: float = 1.0,
    axis: int = -1,
) -> FloatArray:
    """Resample a signal onto whole revolutions of a uniform shaft-angle grid.

    See the module docstring for the exact method (phase model, grid, anti-aliasing, quintic
    B-spline interpolation).

    Parameters
    ----------
    signal : array_like
        Time signal, sampled at ``sample_rate_hz`` along ``axis``; sample ``i`` is at ``i / fs``.
    sample_rate_hz : float
        Time sampling rate.
    pulse_times_s : array_like
        Repaired tachometer pulse times (s), strictly increasing, within the record. The first
        pulse is angle 0 of every shaft.
    pulses_per_rev : int
        Pulses per tach-shaft revolution.
    samples_per_rev : int
        Grid points per target-shaft revolution (pinion teeth × samples per mesh period).
    shaft_ratio : float
        Target-shaft revolutions per tach-shaft revolution: 1 for the tach shaft itself,
        ``gear_teeth / pinion_teeth`` for the pinion when the tach is on the gear,
        ``pinion_teeth / gear_teeth`` for the gear when it is on the pinion.
    axis : int
        Time axis of ``signal``.

    Returns
    -------
    ndarray, shape ``other_axes + (n_revs, samples_per_rev)``
        The signal at the grid angles, one row per whole target-shaft revolution; ``other_axes``
        are the axes of ``signal`` other than ``axis``, in order.

    Raises
    ------
    ValueError
        Bad parameters, pulses outside the record, or less than one whole revolution.

    Examples
    --------
    >>> import numpy as np
    >>> fs = 8000.0
    >>> t = np.arange(16000) / fs
    >>> x = np.sin(2 * np.pi * 21 * 20 * t)           # gear at 20 rev/s, gear order 21
    >>> pulses = np.arange(0, 1.99, 1 / 21)           # tach on the pinion (21 rev/s)
    >>> revs = angle_resample(x, fs, pulses, 1, 128, shaft_ratio=20 / 21)
    >>> revs.shape
    (39, 128)
    """
    if not np.isfinite(sample_rate_hz) or sample_rate_hz <= 0:
        raise ValueError(f"sample_rate_hz must be positive, got {sample_rate_hz}")
    x = np.moveaxis(np.asarray(signal, dtype=np.float64), axis, -1)
    n = x.shape[-1]
    if n < 2:
        raise ValueError("signal must have at least 2 samples along the time axis")
    t = _check_pulses(pulse_times_s, pulses_per_rev)
    duration_s = (n - 1) / sample_rate_hz
    if t[0] < 0 or t[0] > duration_s:
        raise ValueError(
            f"first pulse at {t[0]:.6g} s is outside the record [0, {duration_s:.6g}] s"
        )

    times = angle_grid_times(
        t, pulses_per_rev, samples_per_rev, shaft_ratio=shaft_ratio, record_duration_s=duration_s
    )
    n_revs = times.shape[0]
    if n_revs < 1:
        raise ValueError(
            "less than one whole revolution of the target shaft between the first pulse and the "
            "end of the record or of the pulses"
        )

    # Lowest angular sampling rate (samples/s) over the record, from the longest pulse interval.
    min_target_rev_per_s = shaft_ratio / (pulses_per_rev * float(np.max(np.diff(t))))
    min_angular_rate_hz = samples_per_rev * min_target_rev_per_s
    if min_angular_rate_hz < sample_rate_hz:
        x = angle_lowpass(x, sample_rate_hz, 0.5 * min_angular_rate_hz, axis=-1)

    coefficients = ndimage.spline_filter1d(
        x, order=INTERPOLATION_ORDER, axis=-1, mode="mirror", output=np.float64
    )
    positions = (times.ravel() * sample_rate_hz)[np.newaxis, :]
    rows = coefficients.reshape(-1, n)
    out = np.empty((rows.shape[0], positions.shape[1]))
    for row, out_row in zip(rows, out, strict=True):
        ndimage.map_coordinates(
            row,
            positions,
            output=out_row,
            order=INTERPOLATION_ORDER,
            mode="mirror",
            prefilter=False,
        )
    return out.reshape((*x.shape[:-1], n_revs, int(samples_per_rev)))
