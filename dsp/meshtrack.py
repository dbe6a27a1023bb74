"""Tracking a drifting mesh line or the whole mesh comb over a record (no tachometer).

A speed that drifts within a record moves a mesh line by tens of bins; these tools follow it
frame by frame and return its cycles (or the shaft's revolutions) at every sample, for
:func:`dsp.tachless.tachless_shaft_angle` to heterodyne with:

* :func:`mesh_ridge_cycles` — one line, its largest bin per frame, a polynomial through them;
* :func:`comb_shaft_cycles` — the shaft speed from the whole comb of mesh harmonics, frame by
  frame, with the frames that disagree with the best continuous path set aside when that
  explains the frames better (:func:`_continuous_ridge`).

Pure: arrays in, arrays out; re-exported by :mod:`dsp.tachless`.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dsp.meshspectrum import COMB_CAP_NP, TachlessError, _checked_signal, line_prominence

__all__ = [
    "MAX_COMB_FRAME_S",
    "MAX_COMB_HARMONICS",
    "MAX_RIDGE_CELLS",
    "MAX_SPEED_SLEW_PER_S",
    "comb_shaft_cycles",
    "mesh_ridge_cycles",
]

FloatArray = NDArray[np.float64]


MAX_COMB_HARMONICS = 8
"""Mesh harmonics summed by :func:`comb_shaft_cycles` (those below 0.45 fs)."""

MAX_COMB_FRAME_S = 4.0
"""Longest default frame of :func:`comb_shaft_cycles`: its candidate speeds are spaced by half a
bin at the highest harmonic, so their number grows with the frame."""


def comb_shaft_cycles(
    signal: ArrayLike,
    sample_rate_hz: float,
    mesh_order: int,
    approx_shaft_hz: float,
    *,
    search_fraction: float = 0.2,
    window_s: float | None = None,
) -> FloatArray:
    """Shaft revolutions at every sample, from a speed tracked frame by frame on the mesh comb.

    In each Hann frame (half-overlapping; ``window_s`` defaults to 1/24 of the record, at most
    :data:`MAX_COMB_FRAME_S`, at least 60 mesh periods) every candidate shaft speed within ±``search_fraction`` of
    ``approx_shaft_hz`` scores the summed log-prominence (:func:`dsp.meshspectrum.line_prominence`
    of the frame, negative parts and above 40 dB cut) of its mesh harmonics ``h × mesh_order``,
    ``h`` = 1…:data:`MAX_COMB_HARMONICS` below 0.45 fs; the best speed of each frame goes
    through a robust polynomial fit (:func:`_robust_ridge`: frames far off it dropped), and the
    kept frames are joined by a monotone cubic, integrated from 0. One harmonic drifting by
    tens of per cent crosses into its neighbours' search windows; the comb as a whole does not.
    When some frames' best speeds lie off the path through the frames' scores with the highest
    total whose speed changes by at most :data:`MAX_SPEED_SLEW_PER_S` of ``approx_shaft_hz`` per
    second (:func:`_continuous_ridge`), the track is also made without them, and of the two the
    one along which the frames' comb scores sum higher (each frame's score at the track's mean
    speed over it) is returned: at the end of a sweep, where the lines fade into the anti-alias
    filter's edge, two frames whose best was another line had pulled the polynomial off the
    sweep, which then dropped the right frames around them (an independent-simulator record
    whose speed rose 47 % in 12 s: 77 teeth off at its end).

    Examples
    --------
    A 20-tooth mesh (harmonics 1–3) whose shaft swings from 16 to 19 Hz and back in 12 s:

    >>> import numpy as np
    >>> fs = 8000.0
    >>> t = np.arange(int(12 * fs)) / fs
    >>> shaft_hz = 17.5 - 1.5 * np.cos(2 * np.pi * t / 12)
    >>> revs = np.cumsum(shaft_hz) / fs
    >>> x = sum(np.cos(2 * np.pi * h * 20 * revs) / h for h in (1, 2, 3))
    >>> x = x + 0.5 * np.random.default_rng(0).standard_normal(t.size)
    >>> est = comb_shaft_cycles(x, fs, 20, 17.5)
    >>> error_hz = np.abs(np.gradient(est, 1 / fs) - shaft_hz)[8000:-8000]   # 1 s from each end
    >>> bool(error_hz.max() < 0.1)
    True
    """
    x = _checked_signal(signal, sample_rate_hz)
    duration_s = x.size / sample_rate_hz
    mesh_hz = mesh_order * approx_shaft_hz
    if window_s is None:
        # Short frames: a speed swinging by tens of per cent moves within a long frame, and the
        # band that follows the track is only ±0.3 shaft orders wide at the harmonic. At most
        # MAX_COMB_FRAME_S on a long record (the candidate grid grows with the frame).
        window_s = max(min(duration_s / 24.0, MAX_COMB_FRAME_S), 60.0 / mesh_hz)
    frame, starts = _half_overlapping_frames(x.size, sample_rate_hz, window_s)
    bin_hz = sample_rate_hz / frame
    harmonics = np.arange(1, MAX_COMB_HARMONICS + 1)
    harmonics = harmonics[harmonics * mesh_hz * (1 + search_fraction) < 0.45 * sample_rate_hz]
    if harmonics.size == 0:
        raise TachlessError(f"no mesh harmonic below 0.45 fs at about {approx_shaft_hz:.6g} Hz")
    step = bin_hz / (2.0 * harmonics[-1] * mesh_order)
    speeds = np.arange(approx_shaft_hz * (1 - search_fraction), approx_shaft_hz * (1 + search_fraction), step)
    bins = np.rint(np.outer(speeds, harmonics * mesh_order) / bin_hz).astype(np.int64)
    # Candidates pooled into at most MAX_RIDGE_CELLS cells per frame (each cell's best kept), so
    # that the path search holds frames × cells numbers however long the record.
    pool = -(-speeds.size // MAX_RIDGE_CELLS)
    cells = -(-speeds.size // pool)
    cell_scores = np.empty((starts.size, cells))
    cell_best = np.empty((starts.size, cells), dtype=np.intp)
    for row, start in enumerate(starts):
        prominence = np.clip(line_prominence(x[start : start + frame], sample_rate_hz)[0], 0.0, COMB_CAP_NP)
        score = np.full(cells * pool, -np.inf)
        score[: speeds.size] = prominence[bins].sum(axis=1)
        by_cell = score.reshape(cells, pool)
        cell_best[row] = np.arange(cells) * pool + np.argmax(by_cell, axis=1)
        cell_scores[row] = by_cell.max(axis=1)
    hop_s = float(starts[1] - starts[0]) / sample_rate_hz if starts.size > 1 else duration_s
    max_step = math.ceil(MAX_SPEED_SLEW_PER_S * approx_shaft_hz * hop_s / (step * pool))
    own = np.argmax(cell_scores, axis=1)
    peaks = speeds[cell_best[np.arange(starts.size), own]]
    times = np.asarray((starts + frame / 2) / sample_rate_hz, dtype=np.float64)
    t = np.arange(x.size) / sample_rate_hz
    every_frame = _joined_track(times, peaks, t)
    # Frames whose own best is off the best continuous path are another line or noise. Left
    # out, they give a second track; the one whose frames score higher along it is kept (a weak
    # line's path wanders through noise, and there the frames' own bests did better).
    on_path = np.abs(own - _continuous_ridge(cell_scores, max_step)) <= 1
    if on_path.all() or on_path.sum() < 4:
        return every_frame
    path_frames = _joined_track(times[on_path], peaks[on_path], t)
    if np.max(np.abs(path_frames - every_frame)) * mesh_order < TRACKS_ALIKE_TEETH:
        return every_frame

    def along(cycles: FloatArray) -> float:
        """The frames' comb scores at the track's mean speed over each frame, summed."""
        speed = (cycles[np.minimum(starts + frame, x.size - 1)] - cycles[starts]) / (frame / sample_rate_hz)
        cell = np.clip(np.rint((speed - speeds[0]) / step).astype(np.intp) // pool, 0, cells - 1)
        return float(cell_scores[np.arange(starts.size), cell].sum())

    return path_frames if along(path_frames) > along(every_frame) else every_frame


def _joined_track(times: FloatArray, peaks: FloatArray, t: FloatArray) -> FloatArray:
    """Revolutions at the times ``t`` from the frames' speeds ``peaks`` at ``times``: the frames
    :func:`_robust_ridge` keeps joined by a monotone cubic, integrated from 0."""
    from scipy.interpolate import PchipInterpolator  # only without a tachometer

    if peaks.size < 4:
        return np.asarray(float(np.median(peaks)) * t, dtype=np.float64)
    fit, keep = _robust_ridge(times, peaks)
    if keep.sum() < 4:
        return np.asarray(fit.integ()(t) - fit.integ()(0.0), dtype=np.float64)
    revolutions = PchipInterpolator(times[keep], peaks[keep], extrapolate=True).antiderivative()
    return np.asarray(revolutions(t) - revolutions(0.0), dtype=np.float64)


TRACKS_ALIKE_TEETH = 0.25
"""Two comb tracks that never part by more than a quarter of a tooth are the same track."""
MAX_RIDGE_CELLS = 4096
"""Candidate speeds per frame that :func:`comb_shaft_cycles`' path search holds at most (more are
pooled, each cell keeping its best): a 12-s record has about 3000, an hour-long one's 4-s frames
ten times more."""
MAX_SPEED_SLEW_PER_S = 0.25
"""Fastest speed change :func:`comb_shaft_cycles` follows, as a fraction of the speed per second
(a 20 % swell that completes 1.5 cycles in a 12-s record changes by 16 % per second at most)."""


def _sliding_max(values: FloatArray, half_width: int) -> FloatArray:
    """``out[i] = max(values[i − half_width … i + half_width])`` (clipped at the ends), in O(n)
    (van Herk / Gil & Werman: running maxima within blocks of the window's length, forwards and
    backwards)."""
    n = values.size
    if half_width <= 0:
        return values.copy()
    if 2 * half_width + 1 >= 2 * n:
        return np.full(n, values.max())
    width = 2 * half_width + 1
    padded = np.full(-(-(n + 2 * half_width) // width) * width, -np.inf)
    padded[half_width : half_width + n] = values
    blocks = padded.reshape(-1, width)
    forward = np.maximum.accumulate(blocks, axis=1).reshape(-1)
    backward = np.maximum.accumulate(blocks[:, ::-1], axis=1)[:, ::-1].reshape(-1)
    return np.maximum(backward[:n], forward[width - 1 : width - 1 + n])


def _continuous_ridge(scores: FloatArray, max_step: int) -> NDArray[np.intp]:
    """Per frame (row of ``scores``), the candidate on the path of highest total score whose
    candidate index changes by at most ``max_step`` from one frame to the next (Viterbi with a
    hard step limit). A frame whose own best is another line, far from its neighbours', is
    bridged by the path through its lower score where the line is.

    Examples
    --------
    >>> scores = np.array([[0, 5, 1, 0, 0], [0, 4, 1, 0, 0], [0, 1, 2, 0, 6], [0, 1, 3, 1, 0]], float)
    >>> _continuous_ridge(scores, 1).tolist()
    [1, 1, 2, 2]
    """
    totals = [np.asarray(scores[0], dtype=np.float64)]
    for row in scores[1:]:
        totals.append(row + _sliding_max(totals[-1], max_step))
    path = [int(np.argmax(totals[-1]))]
    for total in totals[-2::-1]:
        low = max(0, path[-1] - max_step)
        path.append(low + int(np.argmax(total[low : path[-1] + max_step + 1])))
    return np.asarray(path[::-1], dtype=np.intp)


def mesh_ridge_cycles(
    signal: ArrayLike,
    sample_rate_hz: float,
    line_hz: float,
    *,
    search_fraction: float = 0.05,
    window_s: float | None = None,
) -> FloatArray:
    """Cycles of a drifting spectral line at every sample: its tracked frequency, integrated.

    The line is located in Hann-windowed frames (half-overlapping; ``window_s`` defaults to
    1/8 of the record, at least 60 cycles of the line), by the largest bin within ±``search_fraction`` of ``line_hz`` refined by a parabola through the
    log-amplitudes; a polynomial in time (degree up to 5, fewer for few frames) is fitted to those
    frequencies and integrated from 0. Smooth: it carries the drift and slow speed changes; what is
    faster is left to the caller's narrow band.

    Examples
    --------
    >>> import numpy as np
    >>> fs = 8000.0
    >>> t = np.arange(int(4 * fs)) / fs
    >>> cycles = 500.0 * t + 0.5 * 20.0 * t**2          # 500 Hz drifting to 580 Hz
    >>> x = np.cos(2 * np.pi * cycles)
    >>> c = mesh_ridge_cycles(x, fs, 540.0, search_fraction=0.15)
    >>> bool(np.max(np.abs(np.diff(c - cycles))) < 1e-4)       # same frequency at every sample
    True
    """
    import scipy.fft  # only without a tachometer: not on the tach path's imports

    x = _checked_signal(signal, sample_rate_hz)
    duration_s = x.size / sample_rate_hz
    if window_s is None:
        window_s = max(duration_s / 8.0, 60.0 / line_hz)
    frame, starts = _half_overlapping_frames(x.size, sample_rate_hz, window_s)
    window = np.hanning(frame)
    freq = np.fft.rfftfreq(frame, d=1.0 / sample_rate_hz)
    lo = max(1, int(np.searchsorted(freq, line_hz * (1 - search_fraction))))
    hi = min(freq.size - 2, int(np.searchsorted(freq, line_hz * (1 + search_fraction))))
    if hi <= lo:
        raise TachlessError(f"the line near {line_hz:.6g} Hz cannot be tracked in {window_s:.3g} s frames")
    centres, peaks = [], []
    for start in starts:
        spectrum = np.abs(scipy.fft.rfft(x[start : start + frame] * window))
        b = lo + int(np.argmax(spectrum[lo : hi + 1]))
        y0, y1, y2 = np.log(spectrum[b - 1 : b + 2] + 1e-300)
        denominator = y0 - 2.0 * y1 + y2
        offset = 0.5 * (y0 - y2) / denominator if denominator < 0 else 0.0
        peaks.append((b + offset) * freq[1])
        centres.append((start + frame / 2) / sample_rate_hz)
    t = np.arange(x.size) / sample_rate_hz
    if len(peaks) < 3:
        return np.asarray(float(np.median(peaks)) * t, dtype=np.float64)
    degree = min(5, len(peaks) // 3)
    fit = np.polynomial.Polynomial.fit(np.asarray(centres), np.asarray(peaks), degree)
    return np.asarray(fit.integ()(t) - fit.integ()(0.0), dtype=np.float64)


def _half_overlapping_frames(n_samples: int, sample_rate_hz: float, window_s: float) -> tuple[int, NDArray[np.int64]]:
    """Frame length (samples, at least 64, at most the record) and the starts of half-overlapping
    frames of about ``window_s``."""
    frame = min(n_samples, max(64, int(window_s * sample_rate_hz)))
    return frame, np.arange(0, n_samples - frame + 1, max(1, frame // 2))


def _robust_ridge(centres: FloatArray, peaks: FloatArray) -> tuple[np.polynomial.Polynomial, NDArray[np.bool_]]:
    """Polynomial (degree ≤ 5, fewer for few frames) through the frames' peak values, twice
    dropping frames more than 3 robust spreads (at least 0.2 % of the median) off the fit; and
    the frames kept. A frame whose maximum was a noise bin or another line is dropped."""
    keep = np.ones(peaks.size, dtype=bool)
    fit = np.polynomial.Polynomial.fit(centres, peaks, min(5, peaks.size // 3))
    for _ in range(2):
        residual = peaks - fit(centres)
        spread = max(3.0 * 1.4826 * float(np.median(np.abs(residual[keep]))), 0.002 * float(np.median(peaks)))
        inliers = keep & (np.abs(residual) <= spread)
        if inliers.sum() < 3 or inliers.sum() == keep.sum():
            break
        keep = inliers
        fit = np.polynomial.Polynomial.fit(centres[keep], peaks[keep], min(5, int(keep.sum()) // 3))
    return fit, keep
