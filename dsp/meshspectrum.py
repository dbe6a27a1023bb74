"""Mesh-line spectrum tools for the tach-less shaft angle: line prominence, speed and tooth count.

The lower half of :mod:`dsp.tachless` (which re-exports everything here): where in the amplitude
spectrum the gear-mesh line family is, before any phase is demodulated.

* :func:`line_prominence` — every bin's height above the local median (nepers);
* :func:`estimate_shaft_hz` — a shaft speed from the comb of its lines;
* :func:`estimate_mesh_order` — the tooth count whose harmonics carry the strongest lines;
* :func:`estimate_pair_speed` — the pinion speed of a pair with known tooth counts;
* :func:`mesh_line_hz` — the mesh harmonic's line near its expected frequency.

Refusals are :class:`TachlessError` (a ``ValueError`` whose ``str()`` is the reason). Pure:
arrays in, numbers out.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "COMB_CAP_NP",
    "COMB_THRESHOLD_NP",
    "DB_PER_NEPER",
    "MIN_LINE_PROMINENCE_DB",
    "TachlessError",
    "estimate_mesh_order",
    "estimate_pair_speed",
    "estimate_shaft_hz",
    "line_prominence",
    "mesh_line_hz",
]

FloatArray = NDArray[np.float64]

DB_PER_NEPER = 20.0 / math.log(10.0)
"""Decibels in one neper of amplitude: line prominences are natural-log amplitude ratios."""
MIN_LINE_PROMINENCE_DB = 15.0
"""A mesh line must stand this far above the local median of the amplitude spectrum."""
COMB_THRESHOLD_NP = math.log(3.0)
"""Comb scores count a harmonic's log-prominence above ln 3 (9.5 dB); a noise bin (Rayleigh
amplitude) exceeds it with probability ~0.2 % (~0.6 % for the best of 3 bins)."""
SHAFT_TOOTH_COST_NP = 0.05
"""Each harmonic of a shaft comb costs 0.05 Np: a sub-multiple of the true speed finds the same
lines with more teeth, so it scores lower; white noise scores below zero."""
MESH_TOOTH_COST_NP = 1.0
"""Each harmonic of a mesh-order comb costs 1 Np: a mesh harmonic is a strong line (≥ 20 dB, 3 Np,
above the floor), and a divisor of the tooth count pays for twice the teeth."""
COMB_CAP_NP = math.log(100.0)
"""Each harmonic's contribution is capped at 40 dB so one huge line cannot carry a comb."""

class TachlessError(ValueError):
    """The vibration signal cannot give a shaft angle; ``str()`` is the reason."""



def _checked_signal(signal: ArrayLike, sample_rate_hz: float) -> FloatArray:
    x = np.asarray(signal, dtype=np.float64)
    if x.ndim != 1:
        raise TachlessError(f"the signal must be 1-D, got shape {x.shape}")
    if x.size < 64:
        raise TachlessError(f"the signal has {x.size} samples, too short for a shaft angle")
    if not np.all(np.isfinite(x)):
        raise TachlessError("the signal contains NaN or infinite samples")
    if not math.isfinite(sample_rate_hz) or sample_rate_hz <= 0:
        raise TachlessError(f"sample_rate_hz must be positive, got {sample_rate_hz}")
    return x - float(np.mean(x))


def line_prominence(signal: ArrayLike, sample_rate_hz: float) -> tuple[FloatArray, FloatArray]:
    """Log-prominence of every bin of the Hann amplitude spectrum, and the bin frequencies.

    Prominence = ``ln|X(f)| − median of ln|X|`` over a running window of ±0.5 % of the bins
    (at least ±50): nepers above the local noise floor; lines stand out, a smooth noise floor
    is ~0 (a Rayleigh bin scatters by about ±0.6 Np).

    Returns
    -------
    prominence_np, frequency_hz : ndarray
        One value per one-sided DFT bin.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(20_000) / 10_000.0
    >>> x = np.sin(2 * np.pi * 1234.0 * t) + 0.01 * np.random.default_rng(1).standard_normal(t.size)
    >>> p, f = line_prominence(x, 10_000.0)
    >>> float(f[np.argmax(p)]), bool(p.max() > np.log(1000))
    (1234.0, True)
    """
    # only without a tachometer: kept off the tach path's imports (scipy costs ~0.3 s to load)
    import scipy.fft
    from scipy import ndimage

    x = _checked_signal(signal, sample_rate_hz)
    spectrum = np.abs(scipy.fft.rfft(x * np.hanning(x.size)))
    log_amplitude = np.log(np.maximum(spectrum, 1e-300 + 1e-12 * float(spectrum.max())))
    half = max(50, int(0.005 * spectrum.size))
    floor = ndimage.median_filter(log_amplitude, size=2 * half + 1, mode="nearest")
    frequency_hz = np.asarray(np.fft.rfftfreq(x.size, d=1.0 / sample_rate_hz), dtype=np.float64)
    return np.asarray(log_amplitude - floor, dtype=np.float64), frequency_hz


def _peak_bins(prominence: FloatArray, lo_bin: int, hi_bin: int, count: int) -> NDArray[np.int64]:
    """The ``count`` most prominent local maxima in bins ``lo_bin .. hi_bin``."""
    lo_bin = max(1, lo_bin)
    hi_bin = min(prominence.size - 2, hi_bin)
    if hi_bin <= lo_bin:
        return np.empty(0, dtype=np.int64)
    seg = prominence[lo_bin : hi_bin + 1]
    left = prominence[lo_bin - 1 : hi_bin]
    right = prominence[lo_bin + 1 : hi_bin + 2]
    maxima = np.flatnonzero((seg >= left) & (seg > right)) + lo_bin
    best = maxima[np.argsort(prominence[maxima])[::-1][:count]]
    return np.asarray(best, dtype=np.int64)


def _refined_bin(prominence: FloatArray, b: int) -> float:
    """Sub-bin peak position by a parabola through the log-amplitude at b−1, b, b+1."""
    y0, y1, y2 = prominence[b - 1], prominence[b], prominence[b + 1]
    denominator = y0 - 2.0 * y1 + y2
    if denominator >= 0.0:
        return float(b)
    return float(b + 0.5 * (y0 - y2) / denominator)


def _comb_scores(
    prominence: FloatArray,
    bin_hz: float,
    shaft_hz: FloatArray,
    max_hz: float,
    max_orders: int,
    tooth_cost_np: float = 0.05,
    relative_tolerance: float = 0.0,
) -> FloatArray:
    """Σ_k max(0, min(prominence near k·f, cap) − threshold) − cost × teeth, per candidate f.

    "Near": within ±1 bin, or ±``relative_tolerance`` × k·f when that is wider.
    """
    scores = np.empty(shaft_hz.size)
    for i, f in enumerate(shaft_hz):
        k = np.arange(1, min(max_orders, int(max_hz / f)) + 1)
        centre = np.rint(k * f / bin_hz).astype(np.int64)
        keep = (centre >= 1) & (centre < prominence.size - 1)
        centre, k = centre[keep], k[keep]
        if centre.size == 0:
            scores[i] = -np.inf
            continue
        if relative_tolerance > 0.0:
            reach = np.maximum(1, np.ceil(relative_tolerance * k * f / bin_hz)).astype(np.int64)
            best = np.array(
                [prominence[max(0, c - r) : c + r + 1].max() for c, r in zip(centre, reach, strict=True)]
            )
        else:
            best = np.maximum(np.maximum(prominence[centre - 1], prominence[centre]), prominence[centre + 1])
        gain = np.clip(np.minimum(best, COMB_CAP_NP) - COMB_THRESHOLD_NP, 0.0, None)
        scores[i] = float(np.sum(gain) - tooth_cost_np * k.size)
    return scores


def estimate_shaft_hz(
    signal: ArrayLike,
    sample_rate_hz: float,
    *,
    min_shaft_hz: float,
    max_shaft_hz: float,
    max_orders: int = 400,
) -> float:
    """Shaft speed (Hz) of a gear vibration signal from the comb of its spectral lines.

    Every strong spectral line ``p`` (the 30 most prominent peaks) proposes the shaft speeds
    ``p / m`` inside ``[min_shaft_hz, max_shaft_hz]`` (m = 1, 2, …); each proposal is scored by
    the comb of its harmonics up to ``max_orders`` and 0.45 × the sampling rate: the sum over
    harmonics of the capped log-prominence above ln 3, minus 0.05 Np per harmonic. A multiple
    of the true speed misses the lines between its teeth; a sub-multiple finds the same lines
    but pays for twice the teeth. The best proposal is refined on a fine grid around it.

    Parameters
    ----------
    signal : array_like
        1-D vibration signal.
    sample_rate_hz : float
        Sampling rate (any consistent unit: cycles per sample when it is 1).
    min_shaft_hz, max_shaft_hz : float
        Search range of the shaft speed.
    max_orders : int
        Highest shaft order used by the comb.

    Returns
    -------
    float
        Estimated shaft speed (Hz).

    Raises
    ------
    TachlessError
        No proposal scores above zero (no shaft-periodic lines: e.g. white noise).

    Examples
    --------
    >>> import numpy as np
    >>> fs = 10_000.0
    >>> t = np.arange(int(3 * fs)) / fs
    >>> x = sum(np.cos(2 * np.pi * k * 23.0 * t + k) for k in (1, 2, 31, 32, 33, 64))
    >>> x = x + 0.1 * np.random.default_rng(0).standard_normal(t.size)
    >>> round(estimate_shaft_hz(x, fs, min_shaft_hz=5.0, max_shaft_hz=100.0), 2)
    23.0
    """
    if not 0 < min_shaft_hz < max_shaft_hz:
        raise TachlessError(f"need 0 < min_shaft_hz < max_shaft_hz, got {min_shaft_hz}, {max_shaft_hz}")
    prominence, freq = line_prominence(signal, sample_rate_hz)
    bin_hz = float(freq[1])
    max_hz = 0.45 * sample_rate_hz
    peaks = _peak_bins(prominence, int(min_shaft_hz / bin_hz), int(max_hz / bin_hz), 30)
    proposals: list[float] = []
    divisors: list[int] = []
    for b in peaks:
        p_hz = _refined_bin(prominence, int(b)) * bin_hz
        m = np.arange(max(1, math.ceil(p_hz / max_shaft_hz)), math.floor(p_hz / min_shaft_hz) + 1)
        proposals.extend((p_hz / m).tolist())
        divisors.extend(m.tolist())
    if not proposals:
        raise TachlessError("no spectral line in the shaft-speed search range")
    candidates = np.asarray(proposals)
    scores = _comb_scores(prominence, bin_hz, candidates, max_hz, max_orders, SHAFT_TOOTH_COST_NP)
    best_index = int(np.argmax(scores))
    best = float(candidates[best_index])
    if not scores.max() > 0.0:
        raise TachlessError(
            "no shaft-periodic line structure in the spectrum (comb score "
            f"{scores.max():.1f} ≤ 0): the signal shows no shaft speed"
        )
    # Fine grid: ±1 bin at the proposing line (order m), in steps of ¼ bin at the highest
    # harmonic, so every tooth of the comb can land on its line.
    m_best = divisors[best_index]
    k_max = max(1, min(max_orders, int(max_hz / best)))
    n_fine = 2 * max(1, math.ceil(4 * k_max / m_best)) + 1
    fine = best + np.linspace(-1.0, 1.0, n_fine) * bin_hz / m_best
    fine_scores = _comb_scores(prominence, bin_hz, fine, max_hz, max_orders, SHAFT_TOOTH_COST_NP)
    return float(np.mean(fine[fine_scores == fine_scores.max()]))


def estimate_mesh_order(
    signal: ArrayLike,
    sample_rate_hz: float,
    shaft_hz: float,
    *,
    min_order: int = 8,
    max_order: int = 200,
    relative_tolerance: float = 0.002,
) -> int:
    """Tooth count of the shaft: the integer order whose harmonics carry the strongest lines.

    Each order ``m`` in ``[min_order, max_order]`` is scored by the comb of its harmonics
    ``h·m`` (h = 1, 2, … below 0.45 × the sampling rate) as in :func:`estimate_shaft_hz` but
    at 1 Np per harmonic; the mesh order has a line at every harmonic, its multiples skip
    some, its divisors pay for twice the teeth, its neighbours fall on weaker sidebands or
    noise. The winner
    must lead the runner-up clearly (by 1 Np), otherwise the count is refused as ambiguous.

    Parameters
    ----------
    signal : array_like
        1-D vibration signal.
    sample_rate_hz : float
        Sampling rate.
    shaft_hz : float
        Shaft speed (e.g. from :func:`estimate_shaft_hz`).
    min_order, max_order : int
        Search range of the tooth count.
    relative_tolerance : float
        Each harmonic's line is looked for within ±this fraction of its expected frequency
        (the shaft speed's uncertainty and drift; the comb estimate is good to ~0.05 %).

    Returns
    -------
    int
        Estimated teeth on that shaft.

    Raises
    ------
    TachlessError
        No order has a positive comb score, or the best two are within 1 Np.

    Examples
    --------
    >>> import numpy as np
    >>> fs = 10_000.0
    >>> t = np.arange(int(3 * fs)) / fs
    >>> x = sum(a * np.cos(2 * np.pi * k * 25.0 * t + k) for a, k in
    ...         ((1, 32), (0.3, 31), (0.3, 33), (0.7, 64), (0.4, 96), (0.2, 128), (0.5, 6)))
    >>> x = x + 0.01 * np.random.default_rng(0).standard_normal(t.size)
    >>> estimate_mesh_order(x, fs, 25.0)
    32
    """
    if not 1 <= min_order <= max_order:
        raise TachlessError(f"need 1 <= min_order <= max_order, got {min_order}, {max_order}")
    prominence, freq = line_prominence(signal, sample_rate_hz)
    bin_hz = float(freq[1])
    max_hz = 0.45 * sample_rate_hz
    orders = np.arange(min_order, max_order + 1)
    orders = orders[orders * shaft_hz < max_hz]
    comb_hz = np.asarray(orders * shaft_hz, dtype=np.float64)
    if orders.size == 0:
        raise TachlessError("no tooth count in the search range has its mesh line below 0.45 × fs")
    # The comb of order m is the shaft comb of a shaft m times faster.
    scores = _comb_scores(
        prominence, bin_hz, comb_hz, max_hz, 10_000, MESH_TOOTH_COST_NP, relative_tolerance
    )
    ranking = np.argsort(scores)[::-1]
    best = int(orders[ranking[0]])
    if not scores[ranking[0]] > 0.0:
        raise TachlessError("no mesh line: no tooth count has prominent harmonics")
    if ranking.size > 1 and scores[ranking[0]] - scores[ranking[1]] < 1.0:
        raise TachlessError(
            f"tooth count ambiguous: orders {best} and {int(orders[ranking[1]])} score within 1 Np"
        )
    return best


def estimate_pair_speed(
    signal: ArrayLike,
    sample_rate_hz: float,
    pinion_teeth: int,
    gear_teeth: int,
    *,
    min_shaft_hz: float,
    harmonics: int = 4,
    peak_count: int = 20,
    relative_tolerance: float = 3e-4,
) -> float:
    """Pinion speed (Hz) of a gear pair with known tooth counts, from its mesh-line family.

    Each of the ``peak_count`` most prominent lines ``p`` proposes the mesh frequency
    ``F = p / h`` (h = 1 … ``harmonics``). A proposal scores, over its first ``harmonics``
    mesh harmonics ``h·F``, the capped log-prominence above ln 3 (:data:`COMB_THRESHOLD_NP`)
    of the harmonic and, at half weight, of its first two sidebands of *both* shafts
    (``h·F ± k·F/pinion_teeth`` and ``h·F ± k·F/gear_teeth``). Every proposal is scored on the
    same number of terms, so a sub-multiple of the mesh frequency (half its harmonics fall
    between the lines) and a stray line family (no sidebands where the tooth counts put them)
    lose. Weak where the mesh harmonics are weak: give a speed hint when you can
    (:func:`tachless_shaft_angle`'s ``approx_shaft_hz``); ``benchmarks/bench_tachless.py``
    measures both.

    Raises
    ------
    TachlessError
        No proposal scores above zero.

    Examples
    --------
    >>> import numpy as np
    >>> fs, f1, z1, z2 = 10_000.0, 23.0, 19, 47
    >>> t = np.arange(int(4 * fs)) / fs
    >>> angle = 2 * np.pi * f1 * t
    >>> x = sum(np.cos(h * z1 * angle) * (1 + 0.2 * np.cos(angle) + 0.2 * np.cos(angle * z1 / z2))
    ...         for h in (1, 2, 3))
    >>> x = x + 0.5 * np.random.default_rng(0).standard_normal(t.size)
    >>> round(estimate_pair_speed(x, fs, z1, z2, min_shaft_hz=2.0), 2)
    23.0
    """
    proposals, scores = pair_speed_scores(
        signal, sample_rate_hz, pinion_teeth, gear_teeth, min_shaft_hz=min_shaft_hz,
        harmonics=harmonics, peak_count=peak_count, relative_tolerance=relative_tolerance,
    )
    best = int(np.argmax(scores))
    if not scores[best] > 0.0:
        raise TachlessError(
            f"no mesh-line family of a {pinion_teeth}/{gear_teeth} pair in the spectrum "
            f"(best score {scores[best]:.1f} ≤ 0)"
        )
    return float(proposals[best] / pinion_teeth)


def pair_speed_scores(
    signal: ArrayLike,
    sample_rate_hz: float,
    pinion_teeth: int,
    gear_teeth: int,
    *,
    min_shaft_hz: float,
    harmonics: int = 4,
    peak_count: int = 20,
    relative_tolerance: float = 3e-4,
) -> tuple[FloatArray, FloatArray]:
    """Every proposed mesh frequency (Hz) of :func:`estimate_pair_speed` and its score.

    Raises
    ------
    TachlessError
        No spectral line in the mesh-frequency search range.
    """
    prominence, freq = line_prominence(signal, sample_rate_hz)
    bin_hz = float(freq[1])
    max_hz = 0.45 * sample_rate_hz
    low_hz = min_shaft_hz * pinion_teeth
    peaks = _peak_bins(prominence, int(low_hz / bin_hz), int(max_hz / bin_hz), peak_count)
    proposals = sorted({
        _refined_bin(prominence, int(b)) * bin_hz / h
        for b in peaks for h in range(1, harmonics + 1)
        if _refined_bin(prominence, int(b)) * bin_hz / h >= low_hz
    })
    if not proposals:
        raise TachlessError("no spectral line in the mesh-frequency search range")

    def height(f_hz: float) -> float:
        if not 0 < f_hz < max_hz:
            return 0.0
        c = round(f_hz / bin_hz)
        reach = max(2, math.ceil(relative_tolerance * f_hz / bin_hz))
        best = float(prominence[max(1, c - reach) : min(prominence.size - 1, c + reach + 1)].max(initial=0.0))
        return max(0.0, min(best, COMB_CAP_NP) - COMB_THRESHOLD_NP)

    scores = []
    for mesh_hz in proposals:
        score = 0.0
        for h in range(1, harmonics + 1):
            score += height(h * mesh_hz)
            for k in (1, 2):
                for teeth in (pinion_teeth, gear_teeth):
                    score += 0.5 * (height(h * mesh_hz + k * mesh_hz / teeth)
                                    + height(h * mesh_hz - k * mesh_hz / teeth))
        scores.append(score)
    return np.asarray(proposals, dtype=np.float64), np.asarray(scores, dtype=np.float64)


def mesh_line_hz(
    signal: ArrayLike,
    sample_rate_hz: float,
    mesh_order: int,
    approx_shaft_hz: float,
    *,
    harmonic: int = 1,
    search_fraction: float = 0.05,
) -> tuple[float, float]:
    """The mesh harmonic's spectral line near ``harmonic × mesh_order × approx_shaft_hz``.

    Returns
    -------
    line_hz, prominence_db : float
        Frequency of the most prominent peak within ±``search_fraction`` of the expectation
        (parabolic sub-bin refinement) and its height above the local median (dB).

    Raises
    ------
    TachlessError
        The expected line is above 0.45 × fs, or no peak there stands
        ``MIN_LINE_PROMINENCE_DB`` above the floor.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(30_000) / 10_000.0
    >>> x = np.cos(2 * np.pi * 800.0 * t) + 0.1 * np.random.default_rng(0).standard_normal(t.size)
    >>> line, db = mesh_line_hz(x, 10_000.0, 32, 24.0)
    >>> round(line, 1), bool(db > 30)
    (800.0, True)
    """
    expected_hz = harmonic * mesh_order * approx_shaft_hz
    if not 0 < expected_hz < 0.45 * sample_rate_hz:
        raise TachlessError(
            f"the expected mesh line ({expected_hz:.6g} Hz) is not below 0.45 × the sampling rate"
        )
    prominence, freq = line_prominence(signal, sample_rate_hz)
    bin_hz = float(freq[1])
    lo = int(expected_hz * (1 - search_fraction) / bin_hz)
    hi = math.ceil(expected_hz * (1 + search_fraction) / bin_hz)
    peaks = _peak_bins(prominence, lo, hi, 1)
    prominence_db = float(DB_PER_NEPER * prominence[peaks[0]]) if peaks.size else -math.inf
    if prominence_db < MIN_LINE_PROMINENCE_DB:
        raise TachlessError(
            f"no mesh line near {expected_hz:.6g} Hz (harmonic {harmonic} of order {mesh_order}): "
            f"the best peak stands {prominence_db:.1f} dB above the floor, "
            f"{MIN_LINE_PROMINENCE_DB:.0f} dB needed"
        )
    return _refined_bin(prominence, int(peaks[0])) * bin_hz, prominence_db
