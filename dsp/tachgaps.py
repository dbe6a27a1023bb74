"""Stretches of a tachometer pulse train that no single repair explains: found and bridged.

A burst of interference on the tach cable adds many pulses within a few periods; a loose
connector loses several in a row; a dropout that ends inside a pulse moves an edge.
:func:`dsp.tach.repair_pulse_times` puts right one missing or one extra pulse, not these. Here
(:func:`bridge_unexplained`) such a stretch is found against a period that bursts and gaps cannot
pull (:func:`burst_proof_period`), its ends are put on the train's own phase, and its pulses are
replaced by evenly spaced ones. The angle inside is then a guess, so
:func:`dsp.tach.analyze_tachometer` names the time spans whose revolutions must not be averaged,
and refuses bridges it cannot trust (:func:`bridge_problem`).

Measured on 300 faulty tachs never looked at while this was made
(``benchmarks/bench_tach_faults.py``): the train came out right in 245 (32 without bridging), a
pulse more than 0.1 ms off or a miscount in 2 (19), refused in 43 (242).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gearwatch.floor.defaults import MAD_TO_SIGMA

FloatArray = NDArray[np.float64]

LOCAL_PERIOD_WINDOW = 9
"""Intervals in the running median that gives the local pulse period (robust to 2 bad intervals)."""

SMOOTH_STEP_LIMIT = 0.25
"""A pulse train whose period never changes by more than this from one pulse to the next has no
lost or spurious pulse (those change it by 50-100 %): its irregularity is the speed itself."""

MAX_BRIDGED_FRACTION = 0.25
"""Largest share of a record's pulse train that bridged stretches (:func:`bridge_unexplained`) may
cover; beyond it the tachometer is refused as irregular (its signal is mostly interference)."""

BRIDGE_MERGE_INTERVALS = 3
"""Unexplained intervals at most this many intervals apart belong to one stretch: inside a burst
of interference some intervals happen to look regular."""

SPEED_CHANGE_ALLOWANCE = 0.01
"""Relative change of the speed allowed for within a bridged stretch when its periods are counted
(:attr:`BridgedStretch.count_uncertainty`)."""


@dataclass(frozen=True)
class BridgedStretch:
    """A stretch of a pulse train that :func:`bridge_unexplained` replaced.

    Attributes
    ----------
    index : int
        Index (in the input) of the last trusted pulse before the stretch.
    start_s, stop_s : float
        The trusted pulses at its two ends (s).
    local_period_s : float
        Median of the regular intervals around it.
    periods : float
        Its duration in local periods; ``round(periods)`` intervals were put in its place.
        With more than one pulse per revolution :func:`dsp.tach.analyze_tachometer` keeps the
        bridge only when the count is sure: ``|periods − round(periods)| + 2·count_uncertainty ≤ 0.5``
        (otherwise every revolution mark after it could be a fraction of a revolution off; with
        one pulse per revolution every mark is the reference itself, and a miscount only
        mislabels the bridged revolutions, which are not averaged).
    count_uncertainty : float
        Standard uncertainty of ``periods`` (periods): the local period's own (the train's jitter
        over the intervals it was taken from) and a speed change of
        :data:`SPEED_CHANGE_ALLOWANCE` over the stretch, times its length.
    """

    index: int
    start_s: float
    stop_s: float
    local_period_s: float
    periods: float
    count_uncertainty: float = 0.0

    @property
    def intervals(self) -> int:
        return max(1, round(self.periods))


def bridge_unexplained(
    pulse_times_s: ArrayLike, *, tolerance: float = 0.3
) -> tuple[FloatArray, tuple[BridgedStretch, ...]]:
    """Replace the stretches of a pulse train that no single repair explains by even pulses.

    A burst of interference on the tach cable adds several pulses within one period, a loose
    connector loses several in a row: :func:`dsp.tach.repair_pulse_times` explains one missing or
    one extra pulse, not these (and inside a burst it may keep a spurious pulse and drop the true
    one). Here the intervals off their local period by more than ``tolerance`` are grouped into
    stretches (:data:`BRIDGE_MERGE_INTERVALS` apart at most). A stretch that one missing or one
    extra pulse explains is left for :func:`dsp.tach.repair_pulse_times`. Of each other one,
    the pulses between its last trusted pulse before and its first trusted pulse after
    (:func:`_phase_consistent_ends`) are removed, and ``round(duration / local period)`` even
    intervals are put in their place. The local period here is not the running median of
    :func:`dsp.tach.repair_pulse_times`, which a burst of many spurious pulses takes over, but
    :func:`burst_proof_period`. The speed inside a stretch is then a guess: callers
    must not average the revolutions it touches (:func:`dsp.tach.analyze_tachometer` says which).

    Parameters
    ----------
    pulse_times_s : array_like
        Increasing pulse times (s) as the edges were found (before
        :func:`dsp.tach.repair_pulse_times`, which then puts right the lone missing and extra
        pulses left here).
    tolerance : float
        Relative tolerance on the period, as for :func:`dsp.tach.repair_pulse_times`.

    Returns
    -------
    pulses : ndarray
        The pulse train with every stretch bridged (the input when nothing was unexplained).
    stretches : tuple of BridgedStretch
        In time order.

    Raises
    ------
    ValueError
        Pulse times that are not a strictly increasing 1-D sequence.

    Examples
    --------
    Three spurious pulses within one period at 1.2 s, and pulses 20–22 lost:

    >>> import numpy as np
    >>> t = np.arange(40) * 0.1
    >>> noisy = np.sort(np.concatenate([np.delete(t, [20, 21, 22]), [1.23, 1.26, 1.27]]))
    >>> pulses, stretches = bridge_unexplained(noisy)
    >>> bool(np.allclose(pulses, t)), [(round(s.start_s, 2), s.intervals) for s in stretches]
    (True, [(1.2, 1), (1.9, 4)])
    """
    t = np.asarray(pulse_times_s, dtype=np.float64)
    if t.ndim != 1 or (t.size > 1 and not np.all(np.diff(t) > 0)):
        raise ValueError("pulse times must be a 1-D strictly increasing sequence")
    if t.size < 4:
        return t.copy(), ()
    intervals = np.diff(t)
    mids = 0.5 * (t[:-1] + t[1:])
    period = burst_proof_period(intervals, mids)
    if period is None:
        return t.copy(), ()  # no plausible period anywhere: nothing to bridge by
    irregular = unexplained_intervals(intervals / period, intervals, tolerance)
    bad = np.flatnonzero(irregular)
    if not bad.size:
        return t.copy(), ()
    groups: list[list[int]] = [[int(bad[0]), int(bad[0])]]
    for i in bad[1:]:
        if i - groups[-1][1] <= BRIDGE_MERGE_INTERVALS:
            groups[-1][1] = int(i)
        else:
            groups.append([int(i), int(i)])
    pieces: list[FloatArray] = []
    stretches: list[BridgedStretch] = []
    kept_from = 0
    ratio = intervals / period
    jitter = _jitter(ratio)
    for first, last in groups:
        if _one_pulse_explains(ratio, first, last, tolerance, jitter):
            continue  # a lone missing or extra pulse: dsp.tach.repair_pulse_times puts it right
        if last < kept_from:
            continue  # swallowed by the stretch before, whose end moved out over it
        first = max(first, kept_from)  # never reach back into the stretch before
        first, last = _phase_consistent_ends(t, first, last, mids, period, kept_from)
        start, stop = float(t[first]), float(t[last + 1])
        local, beside = _period_beside(intervals, irregular, first, last)
        if local is None:
            local = float(np.interp(0.5 * (start + stop), mids, period))
        cycles = (stop - start) / local
        uncertainty = cycles * (jitter / np.sqrt(max(beside, 1)) + SPEED_CHANGE_ALLOWANCE)
        stretch = BridgedStretch(first, start, stop, local, cycles, uncertainty)
        stretches.append(stretch)
        n = stretch.intervals
        pieces.append(t[kept_from : first + 1])
        pieces.append(start + (stop - start) * np.arange(1, n) / n)
        kept_from = last + 1
    pieces.append(t[kept_from:])
    return np.concatenate(pieces), tuple(stretches)



EDGE_REACH = 2
"""Pulses by which :func:`bridge_unexplained` may move a stretch's end outwards to land on the
pulse train's own phase (:func:`_phase_consistent_ends`)."""

EDGE_MOVE_COST = 0.02
"""What moving a stretch's end by one pulse costs, in periods of phase misfit
(:func:`_phase_consistent_ends`): true pulses on both ends fit to about 0.01 period at a steady
speed, a spurious end pulse by chance to anything up to 0.5."""

SIMPLE_REPAIR_TOLERANCE = 0.05
"""An irregular stretch is left to :func:`repair_pulse_times` only when one missing pulse (an
interval of two periods) or one extra pulse (two intervals making one) explains it to this many
periods: a looser fit (a dropout that also displaced the next edge, a spurious pulse next to
the true one) is bridged instead, at the cost of its revolutions."""


DISPLACED_MIN_DEVIATION = 0.05
"""A pulse moved off its place by at least this share of a period (an edge cut short by a dropout
that ends inside a pulse, interference on an edge) — and by :data:`JITTER_MULTIPLE` times the
train's own jitter — makes two neighbouring intervals one long and one short, each within the
repair tolerance: :func:`unexplained_intervals` finds it when the intervals around the pair stay within a
third of that."""

JITTER_MULTIPLE = 6.0
"""Multiples of a pulse train's own interval jitter (:func:`_jitter`: edge timing noise, a fine
encoder sampled coarsely) below which a displaced pulse or a loose single repair is not told
apart from it."""


def _jitter(ratio: FloatArray) -> float:
    """Robust standard deviation of the intervals about their local period (a share of it)."""
    return float(MAD_TO_SIGMA * np.median(np.abs(ratio - 1.0)))


def unexplained_intervals(ratio: FloatArray, intervals: FloatArray, tolerance: float) -> NDArray[np.bool_]:
    """Intervals (``ratio`` = interval / local period) that no smooth speed explains.

    In a run of intervals off the local period by more than ``tolerance`` that a step of more
    than :data:`SMOOTH_STEP_LIMIT` between neighbouring intervals touches (a run-up or a stop
    changes the period smoothly: that is the speed, which the caller judges), or one of a pair
    around a displaced pulse (:data:`DISPLACED_MIN_DEVIATION`).
    """
    steps = np.abs(np.diff(intervals)) / intervals[:-1]
    rough = np.zeros(ratio.size, dtype=bool)
    rough[1:] |= steps > SMOOTH_STEP_LIMIT
    rough[:-1] |= steps > SMOOTH_STEP_LIMIT
    off = np.abs(ratio - 1.0) > tolerance
    # a run of intervals off the period is unexplained as a whole when a rough step touches it
    # (inside a burst, spurious edges can come evenly spaced: smooth among themselves)
    edges = np.diff(np.concatenate([[0], off.astype(np.int8), [0]]))
    out = np.zeros(ratio.size, dtype=bool)
    for start, stop in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True):
        if rough[start:stop].any():
            out[start:stop] = True
    deviation = ratio - 1.0
    if deviation.size >= 4:
        d0, d1 = deviation[1:-2], deviation[2:-1]
        quiet = np.fmax(np.abs(deviation[:-3]), np.abs(deviation[3:]))
        size = np.fmin(np.abs(d0), np.abs(d1))
        least = max(DISPLACED_MIN_DEVIATION, JITTER_MULTIPLE * _jitter(ratio))
        displaced = ((d0 * d1 < 0) & (size >= least)
                     & (np.abs(d0 + d1) <= 0.5 * size) & (quiet <= size / 3))
        out[1:-2] |= displaced
        out[2:-1] |= displaced
    return out


def _one_pulse_explains(
    ratio: FloatArray, first: int, last: int, tolerance: float, jitter: float
) -> bool:
    """Irregular intervals ``first … last`` (in local periods) that one missing pulse (one
    interval of two periods) or one extra pulse (two short intervals making one) explain to
    :data:`SIMPLE_REPAIR_TOLERANCE`, or :data:`JITTER_MULTIPLE` times the train's ``jitter``."""
    loose = max(SIMPLE_REPAIR_TOLERANCE, JITTER_MULTIPLE * jitter)
    if last == first:
        return abs(ratio[first] - 2.0) <= loose
    if last == first + 1:
        return bool(ratio[first] < 1.0 - tolerance and ratio[last] < 1.0 - tolerance
                    and abs(ratio[first] + ratio[last] - 1.0) <= loose)
    return False


def _period_beside(
    intervals: FloatArray, irregular: NDArray[np.bool_], first: int, last: int
) -> tuple[float | None, int]:
    """Median of the regular intervals next to a stretch (:data:`LOCAL_PERIOD_WINDOW` on each
    side): what counts its periods. A burst's own edges can fall in the plausible range and pull
    a chunk's median (:func:`burst_proof_period`) down; the intervals beside it cannot. With
    the number of intervals it was taken from (``None, 0`` when there are none)."""
    regular = np.flatnonzero(~irregular)
    beside = np.concatenate([regular[regular < first][-LOCAL_PERIOD_WINDOW:],
                             regular[regular > last][:LOCAL_PERIOD_WINDOW]])
    return (float(np.median(intervals[beside])) if beside.size else None), int(beside.size)


def _phase_consistent_ends(
    t: FloatArray, first: int, last: int, mids: FloatArray, period: FloatArray, floor: int
) -> tuple[int, int]:
    """The stretch ``[first, last]`` (interval indices), its ends moved out by up to
    :data:`EDGE_REACH` pulses so that they lie a whole number of periods apart.

    The last spurious pulse of a burst can happen to lie about one period before the next true
    pulse: its interval then looks regular, and the stretch would end on it. True pulses on both
    sides are a whole number of periods apart (the speed holds over a few periods); a spurious
    end is not. The ends with the least phase misfit win, each pulse moved costing
    :data:`EDGE_MOVE_COST`.
    """
    best: tuple[float, int, int] | None = None
    for back in range(EDGE_REACH + 1):
        for ahead in range(EDGE_REACH + 1):
            a, b = first - back, last + ahead
            if a < floor or b + 1 >= t.size:
                continue
            local = float(np.interp(0.5 * (t[a] + t[b + 1]), mids, period))
            cycles = (t[b + 1] - t[a]) / local
            misfit = abs(cycles - round(cycles)) if cycles >= 0.5 else 1.0  # ends: two pulses
            cost = misfit + EDGE_MOVE_COST * (back + ahead)
            if best is None or cost < best[0]:
                best = (cost, a, b)
    return (best[1], best[2]) if best is not None else (first, last)


def burst_proof_period(intervals: FloatArray, mids: FloatArray) -> FloatArray | None:
    """The local pulse period at each interval's midpoint, robust to bursts and to gaps.

    ``P0``, the median interval weighted by duration, is the period that covers most of the
    record's time: a burst of many spurious pulses covers little of it, however many pulses it
    holds. Intervals within ``(P0/2, 2·P0)`` are plausible (the speed varies by at most half
    within an accepted record); the local period is the median of the plausible ones in each
    chunk of ``2·LOCAL_PERIOD_WINDOW·P0`` (at least 1/1000 of the record), interpolated linearly
    between the chunks' centres. ``None`` when no interval is plausible.
    """
    order = np.argsort(intervals, kind="stable")
    cumulative = np.cumsum(intervals[order])
    typical = float(intervals[order][np.searchsorted(cumulative, 0.5 * cumulative[-1])])
    plausible = (intervals > 0.5 * typical) & (intervals < 2.0 * typical)
    if not plausible.any():
        return None
    span = float(mids[-1] - mids[0])
    chunk = max(2 * LOCAL_PERIOD_WINDOW * typical, span / 1000.0)
    which = ((mids[plausible] - mids[0]) // chunk).astype(np.int64)
    values = intervals[plausible]
    by_chunk = np.lexsort((values, which))
    chunks, first, count = np.unique(which[by_chunk], return_index=True, return_counts=True)
    medians = values[by_chunk][first + count // 2]
    centres = mids[0] + (chunks + 0.5) * chunk
    return np.interp(mids, centres, medians)


def bridge_problem(
    stretches: tuple[BridgedStretch, ...], pulses: FloatArray, pulses_per_rev: int
) -> str | None:
    """Why the bridges cannot stand — they cover more than :data:`MAX_BRIDGED_FRACTION` of the
    record, or with several pulses per revolution the count of periods in one is not sure
    (:attr:`BridgedStretch.periods`) — or ``None`` when they can."""
    if not stretches:
        return None
    covered = sum(s.stop_s - s.start_s for s in stretches)
    duration = float(pulses[-1] - pulses[0])
    if covered > MAX_BRIDGED_FRACTION * duration:
        return (
            f"irregular tachometer: {len(stretches)} stretch(es) that no missing or extra pulse "
            f"explains (interference, gaps) cover {covered / duration:.0%} of the record "
            f"(at most {MAX_BRIDGED_FRACTION:.0%} is bridged)"
        )
    if pulses_per_rev > 1:
        for s in stretches:
            if abs(s.periods - round(s.periods)) + 2.0 * s.count_uncertainty > 0.5:
                return (
                    f"irregular tachometer: the stretch at {s.start_s:.6g} s that no missing or "
                    f"extra pulse explains lasts {s.periods:.2f} ± {s.count_uncertainty:.2f} periods,"
                    f" not a whole number, and with {pulses_per_rev} pulses per revolution a "
                    "miscount would shift every revolution mark after it"
                )
    return None
