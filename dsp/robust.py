"""Defective samples and defective revolutions: what real recordings add to a clean signal.

A synchronous average is a plain mean, so one non-physical sample (a 3e38 glitch from a
corrupted transfer, a stretch of zeros from a dropout, a clipped burst) moves it by the
sample's error divided by the number of revolutions — and the anti-alias filter spreads a huge
one over the whole record. The MCI then sees a deep "well" where the glitch landed. Two
complementary defences, both pure (arrays in, arrays out):

1. **Sample level, before resampling** (:func:`find_sample_defects`, :func:`repair_spans`):
   stretches that no accelerometer produces are found and bridged by a straight line between
   their good neighbours, so the filter and the interpolator never see them:

   - *glitch*: a sample outside the record's robust range widened ``range_factor`` times —
     ``[q_lo − f·(q_hi − q_lo), q_hi + f·(q_hi − q_lo)]`` with ``q_lo, q_hi`` the 0.1 % and
     99.9 % quantiles (:func:`glitch_limits`); with ``f = 5`` that is about 34 σ for Gaussian
     noise and 11 amplitudes for a sine;
   - *glitch* too: an isolated spike (:func:`find_spikes`), one sample at least
     ``spike_factor`` quantile ranges (1: about 6.5 σ) from the median of its eight neighbours
     on either side while they span less than 0.35 of that distance. A vibration signal that
     went through an anti-alias filter rings over several samples — an oscillation below
     0.45 fs comes back near its peak height within eight samples, and the narrowest pulse the
     filter passes (a sinc) has neighbours spanning 0.4 of its height — so a lone sample is
     not data. An ADC spike 20 σ high is inside the range test's limits,
     yet it raises the raw kurtosis of a 60 000-sample record by 2.7 (the project simulator's
     healthy campaigns with such spikes alarmed on raw kurtosis in 67 and 71 of 100 on two
     parts of benchmarks/bench_detection.py; 1 of 100 once spikes were glitches). A record with more candidates than :func:`max_spikes` allows holds
     them as its own character, and they are left alone;
   - *clipped*: a run of at least ``clip_min_run`` (3) equal samples at the channel's extreme
     value (a saturated sensor or ADC holds it; a healthy analogue signal touches it once);
   - *dropout*: a run of at least ``dropout_min_run`` (8) exactly equal samples elsewhere — a
     DAQ that delivered zeros or held its last value. Sampled analogue noise never repeats a
     float value 8 times in a row; coarsely quantised data does, so the run is lengthened until
     chance repeats are rare (:func:`dropout_run_length`).

   The revolutions that overlap a bridged stretch are then dropped from the average
   (:func:`revolutions_overlapping`): the bridge is not data.

2. **Revolution level, after resampling** (:func:`revolution_outliers`): a spall repeats in
   every revolution, a glitch does not. Each revolution's residual against the per-angle median
   of the revolutions is a mix of noise and non-synchronous content; a revolution whose residual
   peak or energy is ``outlier_factor`` times the median over revolutions holds something the
   others do not (a glitch too small for the sample test, an impact from outside the gearbox)
   and is dropped. The per-angle median contains the spall, so the spall never makes its own
   revolution an outlier.

Examples
--------
>>> import numpy as np
>>> x = np.sin(np.arange(2000) / 7.0)
>>> x[500] = 3e38                                   # a glitch
>>> x[900:920] = 0.0                                # a dropout
>>> defects = find_sample_defects(x, limits=glitch_limits(x))
>>> defects.counts()
{'glitch_samples': 1, 'dropout_samples': 20, 'clipped_samples': 0}
>>> fixed = repair_spans(x, defects.spans())
>>> bool(np.max(np.abs(fixed)) <= 1.0)
True
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gearwatch.floor.defaults import GLITCH_RANGE_FACTOR, REVOLUTION_OUTLIER_FACTOR, SPIKE_FACTOR

__all__ = [
    "CLIP_MIN_RUN",
    "DROPOUT_MIN_RUN",
    "GLITCH_RANGE_FACTOR",
    "REVOLUTION_OUTLIER_FACTOR",
    "SampleDefects",
    "dropout_run_length",
    "equal_runs",
    "find_sample_defects",
    "find_spikes",
    "glitch_limits",
    "max_spikes",
    "repair_spans",
    "revolution_outliers",
    "revolutions_overlapping",
    "spike_threshold",
    "spread_block_starts",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

CLIP_MIN_RUN = 3
"""Consecutive samples at the channel's extreme value that count as a clipped stretch."""
DROPOUT_MIN_RUN = 8
"""Consecutive exactly equal samples (not at an extreme) that count as a dropout."""
OUTLIER_FLOOR = 0.02
"""A revolution's residual peak (energy) below this fraction of the typical revolution's peak
(this fraction squared of its power) is never an outlier, whatever the other revolutions do."""
MIN_REVOLUTIONS_FOR_OUTLIER_TEST = 5
"""Fewer revolutions than this: no revolution-level test (a median of 4 is not a reference)."""
MEDIAN_REVOLUTIONS = 129
"""At most this many revolutions, evenly spaced, form :func:`revolution_outliers`' per-angle
median (the reference the revolutions are compared with)."""
SPIKE_NEIGHBOURS = 8
"""A spike is compared with this many samples on each side."""
SPIKE_ISOLATION = 0.35
"""A spike's neighbours span less than this fraction of its distance from their median."""
SPIKES_PER_SAMPLE = 5e-5
"""More isolated spikes than this fraction of a record's samples (and more than
:data:`MIN_SPIKES_ALLOWED`) are the record's own impulses, not glitches: none is removed."""
MIN_SPIKES_ALLOWED = 8
QUANTILE_SAMPLES = 65_536
"""Samples (64 blocks, :func:`spread_block_starts`) from which :func:`glitch_limits` estimates
the quantiles of a longer signal."""
SAMPLED_BLOCKS = 64
"""Blocks of consecutive samples that represent a long signal (:func:`spread_block_starts`)."""
_GOLDEN_FRACTION = 0.6180339887498949

_EMPTY_SPANS = np.empty((0, 2), dtype=np.int64)


@dataclass(frozen=True)
class SampleDefects:
    """Defective stretches of a signal, each an ``(n, 2)`` int array of ``[start, stop)`` spans.

    Spans of different kinds do not overlap (a sample is a glitch, clipped or a dropout, in that
    order of precedence); spans of one kind are sorted and disjoint.
    """

    glitch: IntArray
    dropout: IntArray
    clipped: IntArray

    def counts(self) -> dict[str, int]:
        """Samples in each kind of stretch: ``glitch_samples``, ``dropout_samples``, ``clipped_samples``."""
        return {
            f"{name}_samples": int(np.sum(spans[:, 1] - spans[:, 0])) if spans.size else 0
            for name, spans in (
                ("glitch", self.glitch), ("dropout", self.dropout), ("clipped", self.clipped)
            )
        }

    def spans(self) -> IntArray:
        """All defective spans, sorted by start (kinds merged)."""
        merged = np.concatenate([self.glitch, self.dropout, self.clipped])
        return merged[np.argsort(merged[:, 0], kind="stable")] if merged.size else _EMPTY_SPANS

    def shifted(self, offset: int) -> SampleDefects:
        """The same spans with ``offset`` added (block index → record index)."""
        return SampleDefects(self.glitch + offset, self.dropout + offset, self.clipped + offset)

    @staticmethod
    def concatenate(parts: list[SampleDefects]) -> SampleDefects:
        """Spans of consecutive blocks joined (each part already in record indices)."""
        if not parts:
            return SampleDefects(_EMPTY_SPANS, _EMPTY_SPANS, _EMPTY_SPANS)
        return SampleDefects(
            np.concatenate([p.glitch for p in parts]).reshape(-1, 2),
            np.concatenate([p.dropout for p in parts]).reshape(-1, 2),
            np.concatenate([p.clipped for p in parts]).reshape(-1, 2),
        )


def spread_block_starts(size: int, block: int, count: int = SAMPLED_BLOCKS) -> IntArray:
    """Starts of ``count`` blocks of ``block`` consecutive samples that represent a signal of
    ``size`` samples (``size > block``): one block in each of ``count`` equal stretches, at a
    fraction ``k·φ mod 1`` into stretch ``k``.

    Deterministic (the same record gives the same estimates), spread over the whole record, and
    irregularly spaced, so a periodic signal is not sampled at one phase. (Until 2026-11-28 the
    starts were drawn by ``numpy.random`` with a fixed seed; importing it cost every
    ``gearwatch analyze`` 10 ms.)

    Examples
    --------
    >>> spread_block_starts(10_000, 100, 4).tolist()
    [0, 4004, 5534, 9538]
    """
    stretch = (size - block) / count
    k = np.arange(count)
    return ((k + (k * _GOLDEN_FRACTION) % 1.0) * stretch).astype(np.intp)


def _sampled(signal: ArrayLike) -> list[FloatArray]:
    """The signal, or for a long one :data:`SAMPLED_BLOCKS` blocks of 1024 consecutive samples
    (:func:`spread_block_starts`)."""
    # reshape, not ravel: a channel of an interleaved file is a strided view, which ravel copies whole
    x = np.asarray(signal).reshape(-1)
    if x.size <= QUANTILE_SAMPLES:
        return [np.asarray(x, dtype=np.float64)]
    block = QUANTILE_SAMPLES // SAMPLED_BLOCKS
    starts = spread_block_starts(x.size, block)
    return list(np.asarray(x[starts[:, np.newaxis] + np.arange(block)], dtype=np.float64))


def dropout_run_length(signal: ArrayLike, minimum: int = DROPOUT_MIN_RUN) -> int:
    """Shortest run of equal samples that counts as a dropout in this signal.

    ``minimum`` (8) for a finely sampled analogue signal. A coarsely quantised one repeats values
    by itself: with ``p`` the fraction of consecutive equal pairs (estimated as in
    :func:`glitch_limits`), a run of ``L`` happens by chance about ``n·p^(L−1)`` times in ``n``
    samples, so ``L`` is raised until that is below 0.01 (treating pairs as independent). A
    signal that is mostly repeats (``p > 0.9``) gets no dropout detection (returns its length + 1).

    Examples
    --------
    >>> import numpy as np
    >>> dropout_run_length(np.random.default_rng(0).standard_normal(1000))
    8
    >>> coarse = np.round(np.sin(np.arange(100_000) / 40.0) * 3)   # ±3 counts
    >>> dropout_run_length(coarse) > 8
    True
    """
    n = int(np.asarray(signal).size)
    blocks = _sampled(signal)
    pairs = sum(max(b.size - 1, 0) for b in blocks)
    if pairs == 0:
        return minimum
    p = sum(int(np.count_nonzero(np.diff(b) == 0)) for b in blocks) / pairs
    if p == 0:
        return minimum
    if p > 0.9:
        return n + 1
    needed = 1 + int(np.ceil(np.log(0.01 / max(n, 1)) / np.log(p)))
    return max(minimum, needed)


def glitch_limits(
    signal: ArrayLike, range_factor: float = GLITCH_RANGE_FACTOR
) -> tuple[float, float]:
    """Bounds outside which a sample is a glitch: the 0.1–99.9 % range widened ``range_factor``×.

    A signal longer than 65536 samples is represented by 64 blocks of 1024 consecutive samples
    spread over the record (:func:`spread_block_starts`), so the cost is about a millisecond on an hour of data and a
    memory-mapped signal is not read whole. Non-finite samples are ignored. A constant signal
    gives the degenerate range ``(value, value)``; an empty or all non-finite one ``(-inf, inf)``.

    Examples
    --------
    >>> import numpy as np
    >>> glitch_limits(np.linspace(-1.0, 1.0, 1001))
    (-10.978, 10.978)
    """
    if not range_factor > 0:
        raise ValueError(f"range_factor must be positive, got {range_factor}")
    values = np.concatenate(_sampled(signal))
    values = values[np.isfinite(values)]
    if values.size == 0:
        return -np.inf, np.inf
    q_lo, q_hi = (float(v) for v in np.percentile(values, [0.1, 99.9]))
    width = q_hi - q_lo
    return round(q_lo - range_factor * width, 12), round(q_hi + range_factor * width, 12)


def spike_threshold(signal: ArrayLike, factor: float = SPIKE_FACTOR) -> float:
    """Smallest distance from its neighbours' median at which a lone sample is a spike:
    ``factor`` × the 0.1–99.9 % quantile range (sampled as in :func:`glitch_limits`); ``inf``
    when ``factor`` is 0 (no spike test) or the signal has no finite sample.

    Examples
    --------
    >>> import numpy as np
    >>> spike_threshold(np.linspace(-1.0, 1.0, 1001))
    1.996
    """
    if factor < 0:
        raise ValueError(f"factor must be ≥ 0, got {factor}")
    values = np.concatenate(_sampled(signal))
    values = values[np.isfinite(values)]
    if factor == 0 or values.size == 0:
        return float("inf")
    q_lo, q_hi = (float(v) for v in np.percentile(values, [0.1, 99.9]))
    return round(factor * (q_hi - q_lo), 12)


def max_spikes(n_samples: int) -> int:
    """Most isolated spikes a record of ``n_samples`` may hold as glitches (see the module docstring)."""
    return max(MIN_SPIKES_ALLOWED, int(SPIKES_PER_SAMPLE * n_samples))


def find_spikes(signal: ArrayLike, threshold: float) -> IntArray:
    """Indices of isolated one-sample spikes (see the module docstring).

    Sample ``n`` is a spike when ``|x[n] − c| > threshold`` with ``c`` the median of its
    :data:`SPIKE_NEIGHBOURS` neighbours on either side, and those neighbours span less than
    :data:`SPIKE_ISOLATION` × ``|x[n] − c|``. The first and last sample of the signal are
    never spikes (a spike at a block boundary of a longer record is missed, as a run split there
    may be). Non-finite samples are left to the range test.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.sin(np.arange(400) / 5.0)
    >>> x[[100, 300]] = [9.0, 9.0]
    >>> x[199:202] = 9.0                          # three samples high: not one lone sample
    >>> find_spikes(x, threshold=4.0).tolist()
    [100, 300]
    """
    x = np.ascontiguousarray(signal, dtype=np.float64).ravel()
    if x.size < 3 or not np.isfinite(threshold):
        return np.empty(0, dtype=np.int64)
    # A spike differs from each immediate neighbour by more than (1 − isolation) × threshold:
    # a cheap pass, after which only a handful of candidates get the exact test.
    jump = np.abs(np.diff(x)) > (1.0 - SPIKE_ISOLATION) * threshold
    candidates = np.flatnonzero(jump[:-1] & jump[1:]) + 1
    if candidates.size == 0:
        return candidates.astype(np.int64)
    offsets = np.concatenate([np.arange(-SPIKE_NEIGHBOURS, 0), np.arange(1, SPIKE_NEIGHBOURS + 1)])
    neighbours = x[np.clip(candidates[:, np.newaxis] + offsets, 0, x.size - 1)]
    centre = np.median(neighbours, axis=1)
    distance = np.abs(x[candidates] - centre)
    # The neighbours' whole range, not their distance from the centre: at an impact's onset the
    # samples before it are quiet and those after it ring, and the median falls between the two;
    # and eight on each side, not one or two: an oscillation at fs/3 reads +1, −½, −½, +1, …
    spread = np.ptp(neighbours, axis=1)
    lone = (distance > threshold) & (spread < SPIKE_ISOLATION * distance)
    return candidates[lone].astype(np.int64)


def _equal_runs(x: FloatArray, min_run: int) -> IntArray:
    """Spans of the runs of at least ``min_run`` equal consecutive samples (NaN equals nothing)."""
    if x.size == 0:
        return _EMPTY_SPANS
    if min_run <= 1:  # every sample is in a run
        starts = np.flatnonzero(np.concatenate(([True], x[1:] != x[:-1])))
        spans = np.stack([starts, np.append(starts[1:], x.size)], axis=1).astype(np.int64)
    else:
        # runs of equal neighbouring pairs [a, b) are runs of equal samples [a, b + 1)
        spans = _true_spans(x[1:] == x[:-1])
        spans = spans + np.array([0, 1], dtype=np.int64) if spans.size else spans
    return spans[spans[:, 1] - spans[:, 0] >= min_run]


def equal_runs(signal: ArrayLike, min_run: int) -> IntArray:
    """``[start, stop)`` spans of runs of at least ``min_run`` exactly equal consecutive samples.

    Examples
    --------
    >>> equal_runs([1.0, 2.0, 2.0, 2.0, 3.0, 0.0, 0.0], 2)
    array([[1, 4],
           [5, 7]])
    """
    if int(min_run) != min_run or min_run < 1:
        raise ValueError(f"min_run must be a positive integer, got {min_run}")
    x = np.ascontiguousarray(signal, dtype=np.float64).ravel()
    return _equal_runs(x, int(min_run))


def _true_spans(mask: BoolArray) -> IntArray:
    """``[start, stop)`` spans of the True runs of a boolean mask."""
    if not mask.any():
        return _EMPTY_SPANS
    edges = np.diff(np.concatenate(([0], mask.view(np.int8), [0])))
    return np.stack([np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)], axis=1).astype(
        np.int64
    )


def find_sample_defects(
    signal: ArrayLike,
    *,
    limits: tuple[float, float],
    extremes: tuple[float, float] | None = None,
    clip_min_run: int = CLIP_MIN_RUN,
    dropout_min_run: int = DROPOUT_MIN_RUN,
    spikes: ArrayLike = (),
) -> SampleDefects:
    """Glitches, clipped stretches and dropouts of a 1-D signal (see the module docstring).

    Parameters
    ----------
    signal : array_like
        1-D samples (a block of a longer record is fine: pass the record's ``limits`` and
        ``extremes``; a run split by a block boundary is then found in two parts, and a part
        shorter than the minimum run is missed).
    limits : (float, float)
        Glitch bounds, from :func:`glitch_limits` of the whole record. Non-finite samples are
        glitches too.
    extremes : (float, float), optional
        The channel's (min, max) *without* its glitches; default: those of ``signal``.
    clip_min_run, dropout_min_run : int
        Shortest clipped run at an extreme, shortest run of equal samples elsewhere.
    spikes : array_like of int
        Indices of isolated spikes (:func:`find_spikes` with the whole record's
        :func:`spike_threshold`), glitches too; default none.

    Returns
    -------
    SampleDefects

    Examples
    --------
    >>> import numpy as np
    >>> x = np.array([0.0, 1.0, 1.0, 1.0, 0.3, -0.5, 99.0, 0.2])
    >>> d = find_sample_defects(x, limits=(-5.0, 5.0))
    >>> d.glitch.tolist(), d.clipped.tolist()
    ([[6, 7]], [[1, 4]])
    """
    x = np.ascontiguousarray(signal, dtype=np.float64).ravel()
    lo, hi = limits
    bad = ~((x >= lo) & (x <= hi))  # NaN too
    if not (np.isfinite(lo) and np.isfinite(hi)):  # then inf may lie within the limits
        bad |= ~np.isfinite(x)
    bad[np.asarray(spikes, dtype=np.int64)] = True
    glitch = _true_spans(bad)
    if extremes is None:
        good = x[~bad]
        extremes = (float(good.min()), float(good.max())) if good.size else (0.0, 0.0)
    bottom, top = extremes
    runs = _equal_runs(x, min(clip_min_run, dropout_min_run))
    if runs.size:
        values = x[runs[:, 0]]
        lengths = runs[:, 1] - runs[:, 0]
        at_extreme = ((values == top) | (values == bottom)) & (top > bottom)
        finite = np.isfinite(values) & (values >= lo) & (values <= hi)
        clipped = runs[at_extreme & finite & (lengths >= clip_min_run)]
        dropout = runs[~at_extreme & finite & (lengths >= dropout_min_run)]
    else:
        clipped = dropout = _EMPTY_SPANS
    return SampleDefects(glitch, dropout.reshape(-1, 2), clipped.reshape(-1, 2))


def repair_spans(signal: ArrayLike, spans: ArrayLike) -> FloatArray:
    """A float64 copy with each ``[start, stop)`` span bridged by a straight line.

    The line joins the last good sample before the span and the first good sample after it (a
    span at an end of the signal takes the one good neighbour's value; a signal that is all
    span becomes zeros). Spans must be sorted; adjacent or overlapping spans are bridged as one.

    Examples
    --------
    >>> repair_spans([0.0, 1.0, 9e9, 9e9, 4.0], [[2, 4]]).tolist()
    [0.0, 1.0, 2.0, 3.0, 4.0]
    """
    x = np.array(signal, dtype=np.float64).ravel()
    s = np.asarray(spans, dtype=np.int64).reshape(-1, 2)
    if s.size == 0:
        return x
    bad = np.zeros(x.size, dtype=bool)
    for start, stop in s:
        bad[max(start, 0) : min(stop, x.size)] = True
    good = np.flatnonzero(~bad)
    if good.size == 0:
        return np.zeros_like(x)
    where = np.flatnonzero(bad)
    x[where] = np.interp(where, good, x[good])
    return x


def revolutions_overlapping(
    revolution_bounds_s: ArrayLike, spans_s: ArrayLike, margin_s: float = 0.0
) -> BoolArray:
    """Which revolutions overlap any time span (each widened by ``margin_s`` on both sides).

    Parameters
    ----------
    revolution_bounds_s : array_like, shape (n_revs, 2)
        Start and end time of each revolution (s), starts increasing.
    spans_s : array_like, shape (m, 2)
        Defective time spans ``[start, stop]`` (s).
    margin_s : float
        Extra time on each side of a span (the interpolator's reach).

    Returns
    -------
    ndarray of bool, shape (n_revs,)

    Examples
    --------
    >>> revolutions_overlapping([[0.0, 1.0], [1.0, 2.0], [2.0, 3.0]], [[1.5, 1.6]]).tolist()
    [False, True, False]
    """
    bounds = np.asarray(revolution_bounds_s, dtype=np.float64).reshape(-1, 2)
    spans = np.asarray(spans_s, dtype=np.float64).reshape(-1, 2)
    out = np.zeros(bounds.shape[0], dtype=bool)
    if spans.size == 0 or bounds.size == 0:
        return out
    lo = spans[:, 0] - margin_s
    hi = spans[:, 1] + margin_s
    # a revolution [a, b] overlaps [lo, hi] when a <= hi and b >= lo
    first = np.searchsorted(bounds[:, 1], lo, side="left")
    last = np.searchsorted(bounds[:, 0], hi, side="right")
    for f, last_rev in zip(first, last, strict=True):
        out[f:last_rev] = True
    return out


def _median_of_rows(r: FloatArray) -> FloatArray:
    """``np.median(r, axis=0)``, partitioning the transposed copy along its contiguous axis
    (4× faster on a block of revolutions: a partition along axis 0 strides through memory)."""
    t = np.ascontiguousarray(r.T)
    half = t.shape[1] // 2
    if t.shape[1] % 2:
        return np.partition(t, half, axis=1)[:, half]
    middle = np.partition(t, (half - 1, half), axis=1)
    return (middle[:, half - 1] + middle[:, half]) / 2


def revolution_outliers(
    revolutions: ArrayLike, outlier_factor: float = REVOLUTION_OUTLIER_FACTOR
) -> BoolArray:
    """Revolutions holding something the others do not: ``True`` = drop from the average.

    Each revolution's residual is its difference from the per-angle median of all revolutions
    (the median keeps whatever repeats — mesh, spall — and ignores a minority of bad
    revolutions), each revolution first brought to the typical level (offset removed, RMS scaled
    to the median RMS over revolutions: a gain step within the record, or a load change that
    makes everything louder, is not an outlier). A revolution is an outlier when its residual
    peak ``max|r|`` or its residual
    energy ``mean(r²)`` exceeds ``outlier_factor`` times the median of that statistic over the
    revolutions. For Gaussian noise on 1280 samples per revolution the peak's spread over
    revolutions is about ±20 %, so a factor of 4 never fires on noise alone; a single sample
    ~15 noise σ away from the rest of its revolution does. A residual below
    :data:`OUTLIER_FLOOR` (2 %) of the typical revolution's peak (or 2 %² of its power) is never
    an outlier: it cannot move the average, and on a noise-free record the residual is only
    resampling rounding, whose scatter would otherwise decide. Fewer than
    :data:`MIN_REVOLUTIONS_FOR_OUTLIER_TEST` revolutions give no outlier.

    Parameters
    ----------
    revolutions : array_like, shape (n_revs, samples_per_rev)
        Revolutions on a common angle grid.
    outlier_factor : float
        Threshold, in multiples of the median statistic (> 1).

    Returns
    -------
    ndarray of bool, shape (n_revs,)

    Examples
    --------
    >>> import numpy as np
    >>> revs = np.sin(np.linspace(0, 2 * np.pi, 64)) + 0.01 * np.random.default_rng(0).standard_normal((30, 64))
    >>> revs[7, 20] += 1.0
    >>> np.flatnonzero(revolution_outliers(revs)).tolist()
    [7]
    """
    if not outlier_factor > 1:
        raise ValueError(f"outlier_factor must be > 1, got {outlier_factor}")
    r = np.asarray(revolutions, dtype=np.float64)
    if r.ndim != 2:
        raise ValueError(f"revolutions must be 2-D (n_revs, samples_per_rev), got {r.shape}")
    if r.shape[0] < MIN_REVOLUTIONS_FOR_OUTLIER_TEST:
        return np.zeros(r.shape[0], dtype=bool)
    # Each revolution is brought to the typical level before the comparison: its offset removed
    # and its RMS scaled to the median RMS, so a gain step or a louder load — everything, noise
    # included, scaled alike — is no outlier. (A least-squares gain against the median revolution
    # would be noise itself on records whose average is mostly noise, such as real ones.)
    normalised = r - np.mean(r, axis=1, keepdims=True)  # the offset removed (a new array)
    level = np.sqrt(np.einsum("ij,ij->i", normalised, normalised) / r.shape[1])
    typical_level = float(np.median(level))
    gains = level / typical_level if typical_level > 0 else np.ones(r.shape[0])
    normalised /= np.where(gains > 0, gains, 1.0)[:, np.newaxis]
    # the per-angle median of at most MEDIAN_REVOLUTIONS evenly spaced revolutions: a robust
    # reference as good as all of them (its noise adds ~1 % to every residual alike) at a fraction
    # of the partition's cost on long blocks
    stride = -(-normalised.shape[0] // MEDIAN_REVOLUTIONS)
    typical = _median_of_rows(normalised[::stride])
    residual = normalised
    residual -= typical  # in place: normalised is not needed any more
    peak = np.maximum(np.max(residual, axis=1), -np.min(residual, axis=1))  # max |r|, no |r| copy
    energy = np.einsum("ij,ij->i", residual, residual) / residual.shape[1]
    # Residuals far below the synchronous signal cannot move the average: noise-free records
    # (only resampling rounding in the residual) must not lose revolutions to its scatter.
    synchronous = typical - np.mean(typical)  # already zero-mean up to the median's rounding
    peak_floor = OUTLIER_FLOOR * np.max(np.abs(synchronous))
    energy_floor = OUTLIER_FLOOR**2 * np.mean(synchronous * synchronous)
    return ((peak > outlier_factor * np.median(peak)) & (peak > peak_floor)) | (
        (energy > outlier_factor * np.median(energy)) & (energy > energy_floor)
    )
