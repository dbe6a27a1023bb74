"""A record channel's checks before any heavy work: impossible magnitudes, defective samples, raw metrics.

Part of the per-record chain (:mod:`gearwatch.usecases.analyze`). :func:`checked_signal` scans an
accelerometer channel block by block: it finds the glitches, dropouts and clipped stretches
(:mod:`dsp.robust`), refuses a channel with too many of them, and computes the whole-record raw
metrics without them. Refusals raise :class:`gearwatch.floor.errors.RecordRejected` with a
one-line reason.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from dsp.metrics import extremes_and_moment_sums
from dsp.robust import (
    CLIP_MIN_RUN,
    SampleDefects,
    dropout_run_length,
    find_sample_defects,
    find_spikes,
    glitch_limits,
    max_spikes,
    spike_threshold,
)
from gearwatch.floor.campaign import RecordData
from gearwatch.floor.errors import RecordFormatError, RecordRejected
from gearwatch.floor.results import AnalysisParameters

CLIPPING_MIN_RUN = CLIP_MIN_RUN
"""Consecutive samples at the channel's extreme value that count as a clipped stretch."""
MAX_DEFECTIVE_FRACTION = 0.05
"""A channel with more of its samples glitched or clipped is refused outright (its acquisition is
broken, or its gain is wrong); fewer are bridged and the revolutions they touch dropped."""
MAX_DROPOUT_FRACTION = 0.5
"""Dropouts (runs of one held value: a sensor disconnected for a while) may take up to this share of
a channel. They are contiguous, so the record around them is sound: the revolutions they touch are
dropped and the usual revolution checks decide (too few left, or more than half dropped, refuses
the record with that reason). Before 2026-11-28 they counted towards the 5 % above, and a 3-s
dropout in a 20-s record refused the whole record."""
SCAN_BLOCK_SAMPLES = 1 << 18
""":func:`checked_signal` reads a channel in blocks of at most this many samples (2 MB as float64):
its dozen passes per block then stay in a core's cache. 1 M-sample blocks went to memory on every
pass: 0.055 → 0.037 s for a 300 s, 20 kHz channel, in a fresh ``gearwatch analyze`` process."""
RAW_KURTOSIS_SPANS = 16
"""``raw_kurtosis`` is the mean kurtosis of this many equal time spans of the record (:func:`_raw_metrics` says why)."""
RAW_KURTOSIS_MIN_SPAN_SAMPLES = 4096
"""…fewer spans when one would hold fewer samples (a sample kurtosis of a few hundred samples is biased low)."""
MAX_ABS_SAMPLE = 1e12
"""Largest sample magnitude a record may hold (any unit): a 32-bit ADC counts to 2.1e9, no
sensor reads 1e12 m/s² or V. Beyond it fourth moments overflow float64 and averages overflow the
float32 curves. In the tachometer channel such a value is a corrupt file and the record is
rejected with that reason; in an accelerometer channel it is a glitch (always, whatever the
record's range), bridged and counted like any other (:mod:`dsp.robust`)."""


def refuse_impossible_magnitudes(samples: np.ndarray, what: str, block_samples: int) -> None:
    """:class:`RecordRejected` when a finite sample exceeds :data:`MAX_ABS_SAMPLE` (NaN and
    inf have their own checks); block by block, at the stored dtype."""
    for start in range(0, samples.size, block_samples):
        block = np.asarray(samples[start : start + block_samples])
        if block.size == 0 or not np.issubdtype(block.dtype, np.number):
            continue
        if block.dtype.kind != "f" or np.isfinite(block).all():  # no copy in the usual case
            peak = max(abs(float(block.max())), abs(float(block.min())))
        else:
            magnitudes = np.abs(block[np.isfinite(block)])
            peak = float(magnitudes.max()) if magnitudes.size else 0.0
        if peak > MAX_ABS_SAMPLE:
            raise RecordRejected(
                f"{what} holds a sample of magnitude {peak:.3g}, beyond any sensor's range "
                f"(limit {MAX_ABS_SAMPLE:g}): a corrupt file"
            )


@dataclass(frozen=True)
class ScannedSignal:
    """A channel that passed the checks, with its raw-signal metrics and defective stretches."""

    samples: np.ndarray
    """The channel as read (possibly float32, possibly memory-mapped): convert per block."""
    raw_metrics: dict[str, float]
    clipped_fraction: float
    defects: SampleDefects
    """Glitches, dropouts and clipped stretches (record sample indices), bridged before
    resampling; the revolutions they touch are left out of the averages."""


def checked_signal(
    record: RecordData, name: str, block_samples: int, params: AnalysisParameters
) -> ScannedSignal:
    """Find defective samples; compute ``raw_rms`` and ``raw_kurtosis`` without them; block by block.

    Pass 1 finds the glitches (non-finite samples and samples far outside the record's robust
    range, :func:`dsp.robust.glitch_limits`), counts the isolated spikes
    (:func:`dsp.robust.find_spikes`; more than :func:`dsp.robust.max_spikes` are the record's own
    impulses and stay) and takes the channel's extremes without either; pass 2 finds
    the clipped runs at those extremes and the dropouts, and accumulates the moments of the
    samples outside every defective stretch in one pass per block
    (:func:`dsp.metrics.extremes_and_moment_sums`) about the mean of the first good samples
    (numerically safe for a signal whose mean does not wander by many standard deviations); the
    stretches themselves are bridged later, before resampling
    (:func:`gearwatch.usecases.angle_averages.angle_averages`). Blocks hold at most
    :data:`SCAN_BLOCK_SAMPLES` samples; a run split by a block boundary counts as two, and a
    spike on a block's first or last sample is missed (a few samples per quarter-million). A channel
    with more than :data:`MAX_DEFECTIVE_FRACTION` of its samples glitched or clipped, or more than
    :data:`MAX_DROPOUT_FRACTION` in dropouts, is refused.
    """
    samples = record.channel(name)
    if samples.ndim != 1 or samples.size == 0:
        raise RecordFormatError(f"channel {name!r} must be a non-empty 1-D signal")
    block_samples = min(block_samples, SCAN_BLOCK_SAMPLES)
    starts = range(0, samples.size, block_samples)
    lo, hi = glitch_limits(samples, params.glitch_range_factor)
    limits = (max(lo, -MAX_ABS_SAMPLE), min(hi, MAX_ABS_SAMPLE))
    dropout_run = dropout_run_length(samples)
    spike_limit = spike_threshold(samples, params.spike_factor)
    top, bottom = -np.inf, np.inf  # the channel's extremes without its glitches and lone spikes
    spike_top, spike_bottom = -np.inf, np.inf
    block_spikes: list[np.ndarray] = []  # per block, found once and passed to pass 2
    for start in starts:
        block = np.asarray(samples[start : start + block_samples], dtype=np.float64)
        # the limits are finite, so the comparisons leave NaN and inf out too
        inside = (block >= limits[0]) & (block <= limits[1])
        lone = find_spikes(block, spike_limit)
        lone = lone[inside[lone]]
        block_spikes.append(lone)
        if lone.size:
            spike_top, spike_bottom = max(spike_top, float(block[lone].max())), min(spike_bottom, float(block[lone].min()))
            inside[lone] = False
        good = block if inside.all() else block[inside]
        if good.size:
            top, bottom = max(top, float(good.max())), min(bottom, float(good.min()))
    if sum(lone.size for lone in block_spikes) > max_spikes(samples.size):
        # the record's own impulses, not glitches: kept, and part of its extremes
        block_spikes = [lone[:0] for lone in block_spikes]
        top, bottom = max(top, spike_top), min(bottom, spike_bottom)
    if not np.isfinite(top):
        raise RecordRejected(f"channel {name!r} holds no valid sample (all NaN, inf or glitches)")
    if top == bottom:
        raise RecordRejected(f"channel {name!r} is constant ({top:g}): a dead or disconnected sensor")
    parts: list[SampleDefects] = []
    shift = None
    span_edges = kurtosis_span_edges(samples.size)
    span_sums = np.zeros((span_edges.size - 1, 4))
    span_samples = np.zeros(span_edges.size - 1)
    for start, spikes in zip(starts, block_spikes, strict=True):
        block = np.asarray(samples[start : start + block_samples], dtype=np.float64)
        defects = find_sample_defects(
            block, limits=limits, extremes=(bottom, top), dropout_min_run=dropout_run, spikes=spikes,
        )
        kept = _kept_mask(block.size, defects.spans())
        if shift is None:  # moments about a value near the mean: sums do not cancel
            first_good = block[:1024] if kept is None else block[kept][:1024]
            shift = float(np.mean(first_good)) if first_good.size else None
        # each time span's part of this block, summed on its own
        cuts = np.clip(span_edges - start, 0, block.size)
        for span, (lo, hi) in enumerate(pairwise(cuts.tolist())):
            if hi > lo:
                good = block[lo:hi] if kept is None else block[lo:hi][kept[lo:hi]]
                span_sums[span] += extremes_and_moment_sums(good, shift or 0.0)[2]
                span_samples[span] += good.size
        parts.append(defects.shifted(start))
    defects = SampleDefects.concatenate(parts)
    counts = defects.counts()
    defective = sum(counts.values())
    scattered = counts["glitch_samples"] + counts["clipped_samples"]
    if (scattered > MAX_DEFECTIVE_FRACTION * samples.size
            or counts["dropout_samples"] > MAX_DROPOUT_FRACTION * samples.size):
        what = ", ".join(f"{n} {k.removesuffix('_samples')}" for k, n in counts.items() if n)
        raise RecordRejected(
            f"channel {name!r} has {defective / samples.size:.2%} defective samples ({what}): "
            + ("the sensor is clipped" if counts["clipped_samples"] * 2 > defective
               else "the sensor is mostly disconnected" if counts["dropout_samples"] * 2 > defective
               else "the data are corrupt")
        )
    return ScannedSignal(
        samples,
        _raw_metrics(span_sums, span_samples),
        counts["clipped_samples"] / samples.size,
        defects,
    )


def kurtosis_span_edges(samples: int) -> np.ndarray:
    """Sample indices that cut a record into the time spans of ``raw_kurtosis``.

    :data:`RAW_KURTOSIS_SPANS` equal spans (to a sample), fewer when a span
    would hold less than :data:`RAW_KURTOSIS_MIN_SPAN_SAMPLES` (one span for a short record).

    >>> kurtosis_span_edges(100_000).tolist()[:3], kurtosis_span_edges(10_000).tolist()
    ([0, 6250, 12500], [0, 5000, 10000])
    """
    spans = int(min(RAW_KURTOSIS_SPANS, max(samples // RAW_KURTOSIS_MIN_SPAN_SAMPLES, 1)))
    return np.asarray([round(k * samples / spans) for k in range(spans + 1)], dtype=np.int64)


def _kept_mask(size: int, spans: np.ndarray) -> np.ndarray | None:
    """True outside every ``[start, stop)`` defective span of a block (None: nothing defective)."""
    if not spans.size:
        return None
    marks = np.zeros(size + 1, dtype=np.int64)
    np.add.at(marks, spans[:, 0], 1)
    np.add.at(marks, spans[:, 1], -1)
    return np.asarray(np.cumsum(marks[:-1]) == 0)


def _central_moments(shifted_sums: np.ndarray, count: float) -> tuple[float, float]:
    """Variance and fourth central moment from Σy, Σy², Σy³, Σy⁴ of y = x − c over ``count`` samples."""
    d, m2_raw, m3_raw, m4_raw = (float(v) / max(count, 1.0) for v in shifted_sums)
    variance = max(m2_raw - d * d, 0.0)
    return variance, m4_raw - 4 * d * m3_raw + 6 * d * d * m2_raw - 3 * d**4


def _raw_metrics(span_sums: np.ndarray, span_samples: np.ndarray) -> dict[str, float]:
    """``raw_rms`` about the record's mean; ``raw_kurtosis`` the mean of the spans' own kurtoses
    (weighted by their samples left after the defective stretches).

    Why per span: a speed that drifts within the record sweeps the mesh harmonics through the
    transfer path's resonances, so the vibration's *level* rises and falls along the record, and a
    level that varies raises the kurtosis of the whole (a mixture of Gaussians of different
    variance is heavy-tailed) with no impulse in it. Each span is short enough for the level to
    hold still, and a fault's impulses, which come every revolution, are in every span. Measured
    on 24 independent campaigns of ``random_campaign`` (seeds 9848–9871, speed drift 0–20 % within
    a record): a tach-less healthy-until-day-7 campaign whose day-4 record swept 17 % had a whole-
    record kurtosis of 4.06 against 3.03–3.77 on its first days (an alarm three days before the
    spall) and 2.61 per span (on the 16 spalled ones, one alarm a day earlier, one two days
    later); the real wind-turbine campaign's values moved by 0.02 at most (it
    still alarms on record 7). Held out (seeds 9872–9911, generated after the choice, the default
    raw-kurtosis rule on 7 days): healthy campaigns alarmed 1 of 13 → 0, spalled campaigns
    alarmed 2 → 3 of 27 (one a day earlier, one new), none later. On the detection benchmark's
    30-revolution records (drift ≤ 4 % on the project simulator, 0–20 % on the independent
    one), a wash (``held-out-8`` and ``-9``: healthy campaigns alarmed 6 → 7 of 200 on the
    project simulator, 8 → 4 of 200 on the independent one; ``benchmarks/bench_detection.py``).
    """
    variance, _ = _central_moments(span_sums.sum(axis=0), float(span_samples.sum()))
    kurtoses, weights = [], []
    for sums, count in zip(span_sums, span_samples, strict=True):
        span_variance, fourth = _central_moments(sums, float(count))
        if count >= 4 and span_variance > 0 and fourth > 0:
            kurtoses.append(fourth / span_variance**2)
            weights.append(count)  # a span mostly bridged (a dropout) counts for its few samples
    return {"raw_rms": float(np.sqrt(variance)),
            "raw_kurtosis": float(np.average(kurtoses, weights=weights)) if kurtoses else 0.0}


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

