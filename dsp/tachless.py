"""Tach-less shaft angle: once-per-revolution pulse times from the gear-mesh line alone.

Records without a tachometer (e.g. the SpectraQuest gearbox data) still carry the shaft's angle
in the phase of the gear-mesh vibration: the mesh harmonic ``h`` of a shaft with ``Z`` teeth
goes through ``h·Z`` cycles per revolution. This module

1. finds the shaft speed from the amplitude spectrum (:func:`estimate_shaft_hz`: a harmonic
   comb over line *prominences*; :func:`mesh_line_hz`: the mesh line at ``h·Z × shaft``),
2. estimates the tooth count from the lines (:func:`estimate_mesh_order`),
3. isolates the mesh harmonic with a narrow band-pass, takes its analytic signal (one-sided
   FFT), unwraps the phase, divides it by ``h·Z`` → shaft angle, and interpolates the times at
   which that angle passes ``2π·n`` (:func:`tachless_shaft_angle`,
   :func:`shaft_pulse_times_from_mesh`).
4. for a speed that swings by tens of per cent within the record (``follow_drift``): tracks the
   speed frame by frame on the whole mesh comb (:func:`comb_shaft_cycles` — one harmonic
   sweeping ±20 % crosses its neighbours' search windows, the comb does not), reads the line's
   remaining phase in a band around that track, and accepts a line that stands out *along*
   the track (:func:`dechirped_prominence_db`) although smeared over hundreds of bins of the
   whole record's spectrum.

Frame. A synthetic pulse is placed where the mesh phase is a whole number of mesh periods, so
two records of the same rig are in the same frame up to a whole number of mesh periods (which
tooth, which revolution of the hunting period) — the origin is otherwise arbitrary, unlike a
tach mark. Periodic phase modulation of the mesh (eccentricity, a damaged tooth) is the same at
every revolution and only moves that origin; a narrow band (default ±0.3 shaft orders) keeps
out the gear-order sidebands, whose phase pattern would otherwise repeat only per hunting
period. Speed changes slower than the band half-width (0.3 × shaft speed) are tracked.

Refusals (:class:`TachlessError`, a ``ValueError`` whose ``str()`` is the reason): no
prominent mesh line near the expected frequency, or a band that is not clean (its envelope
almost vanishes somewhere, or the unwrapped phase goes backwards / the implied speed leaves
±25 % of the mean): then the phase would slip and the averages would be smeared.

The spectrum tools (steps 1–2 and the mesh line) live in :mod:`dsp.meshspectrum` and are
re-exported here. Everything here is pure: arrays in, arrays and a frozen dataclass out.

Examples
--------
>>> import numpy as np
>>> fs, shaft_hz, teeth = 10_000.0, 25.0, 32
>>> t = np.arange(int(4 * fs)) / fs
>>> angle = 2 * np.pi * shaft_hz * t + 0.02 * np.sin(2 * np.pi * 1.3 * t)   # wobbling speed
>>> x = np.cos(teeth * angle) + 0.3 * np.cos(2 * teeth * angle + 1.0)
>>> x = x + 0.2 * np.random.default_rng(0).standard_normal(t.size)
>>> pulses = shaft_pulse_times_from_mesh(x, fs, teeth, approx_shaft_hz=24.0)
>>> rev = np.interp(pulses, t, angle) / (2 * np.pi)     # true shaft angle at each pulse
>>> bool(np.ptp(rev - np.round(rev - rev[0]) - rev[0]) < 0.002)   # same angle every time
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dsp.meshspectrum import (
    COMB_CAP_NP,
    DB_PER_NEPER,
    MIN_LINE_PROMINENCE_DB,
    TachlessError,
    _checked_signal,
    estimate_mesh_order,
    estimate_pair_speed,
    estimate_shaft_hz,
    line_prominence,
    mesh_line_hz,
)
from dsp.meshtrack import MAX_COMB_HARMONICS, comb_shaft_cycles, mesh_ridge_cycles

__all__ = [
    "MIN_LINE_PROMINENCE_DB",
    "ShaftAngleEstimate",
    "TachlessError",
    "agreeing_harmonics",
    "comb_shaft_cycles",
    "comb_speed_hz",
    "dechirped_prominence_db",
    "estimate_mesh_order",
    "estimate_pair_speed",
    "estimate_shaft_hz",
    "line_prominence",
    "mesh_line_hz",
    "mesh_ridge_cycles",
    "shaft_pulse_times_from_mesh",
    "tachless_shaft_angle",
]

FloatArray = NDArray[np.float64]

MIN_ENVELOPE_RATIO = 0.05
"""The band's envelope may not drop below this fraction of its median (phase slip)."""
MAX_SPEED_DEVIATION = 0.25
"""The speed implied by the phase must stay within ±25 % of its mean."""
EDGE_REVOLUTIONS_PER_INVERSE_BAND = 1.5
"""Pulses closer than ``1.5 / bandwidth_orders`` revolutions to either end of the record are
dropped: there the circular band-pass sees the wrap-around."""


@dataclass(frozen=True)
class ShaftAngleEstimate:
    """Synthetic once-per-revolution pulses and how they were obtained.

    Attributes
    ----------
    pulse_times_s : ndarray
        Times (s) at which the estimated shaft angle passes ``2π·n`` (n = 0, 1, …): the first
        pulse is the angle origin; each pulse sits at a whole mesh period of the mesh phase.
    mean_shaft_hz : float
        Mean shaft speed between the first and last pulse (Hz).
    mesh_line_hz : float
        The mesh harmonic's spectral line (Hz) around which the band-pass was centred.
    line_prominence_db : float
        Height of that line above the local median of the amplitude spectrum (dB).
    min_envelope_ratio : float
        Smallest envelope of the band signal / its median over the kept span.
    speed_variation : float
        ``(max − min) / mean`` of the per-revolution speed.
    mesh_order : int
        Teeth on the shaft (the mesh order used).
    harmonic : int
        Mesh harmonic demodulated.
    """

    pulse_times_s: FloatArray
    mean_shaft_hz: float
    mesh_line_hz: float
    line_prominence_db: float
    min_envelope_ratio: float
    speed_variation: float
    mesh_order: int
    harmonic: int


# --------------------------------------------------------------------------- shaft angle


def tachless_shaft_angle(
    signal: ArrayLike,
    sample_rate_hz: float,
    mesh_order: int,
    *,
    approx_shaft_hz: float | None = None,
    harmonic: int = 1,
    bandwidth_orders: float = 0.3,
    offset_mesh_periods: int = 0,
    search_fraction: float = 0.05,
    track_speed: bool = False,
    follow_drift: bool = False,
    shaft_cycles: ArrayLike | None = None,
) -> ShaftAngleEstimate:
    """Shaft angle from the phase of one mesh harmonic; synthetic once-per-rev pulses.

    Parameters
    ----------
    signal : array_like
        1-D vibration signal (accelerometer).
    sample_rate_hz : float
        Sampling rate. Only ratios matter: with ``sample_rate_hz = 1`` times are in samples.
    mesh_order : int
        Teeth on the shaft whose angle is wanted.
    approx_shaft_hz : float, optional
        Rough shaft speed (±``search_fraction``); default: :func:`estimate_shaft_hz` over
        ``[20 / duration, 0.45 fs / (harmonic × mesh_order)]``. Give it when you can: the comb
        needs lines at the shaft's own orders (sidebands, runout) — a pure mesh tone has none —
        and with two shafts in the spectrum it may lock on the other one (on SpectraQuest it
        often finds the 80-tooth shaft, 0.4 × the 32-tooth one).
    harmonic : int
        Mesh harmonic to demodulate (pick the cleanest, usually the strongest).
    bandwidth_orders : float
        Half-width of the band-pass in shaft orders (raised-cosine edges over the outer 30 %),
        below ``mesh_order / 2``. It must hold the speed fluctuation's FM spread, about
        ``harmonic × mesh_order × (peak speed deviation fraction)`` orders plus the fluctuation
        rate in orders: a low harmonic needs the narrowest band. Lines inside it whose pattern does not repeat every
        revolution (gear-order sidebands) add a revolution-to-revolution angle jitter; speed
        changes faster than ``bandwidth_orders × shaft speed`` are not tracked.
    offset_mesh_periods : int
        Move the angle origin by this many mesh periods (aligning two records of one rig).
    search_fraction : float
        Relative search half-width for the mesh line around the expectation.
    track_speed : bool
        Follow a drifting speed: the mesh line's frequency is first tracked over short
        windows (:func:`mesh_ridge_cycles`), and the band is taken around that moving line
        (heterodyne with the tracked phase, then the low-pass of ``bandwidth_orders``) instead
        of around a fixed frequency. Without it the speed may change by at most about
        ``bandwidth_orders / (harmonic × mesh_order)`` over the record (0.4 % for 80 teeth).
    follow_drift : bool
        With ``track_speed``: the speed is tracked frame by frame on the whole mesh comb
        (:func:`comb_shaft_cycles`) instead of on the one line, and the line must stand
        :data:`MIN_LINE_PROMINENCE_DB` above the floor along that track
        (:func:`dechirped_prominence_db`) rather than in the whole record's spectrum, where a
        speed drifting by tens of per cent smears it over many bins and across its neighbours'
        search windows. Its phase can be noisier than that of a line that stands out in the
        whole record: callers try it when no such line works.
    shaft_cycles : array_like, optional
        With ``follow_drift``: the tracked shaft revolutions at every sample, when the caller
        has them already (:func:`comb_shaft_cycles` with the same arguments).

    Returns
    -------
    ShaftAngleEstimate

    Raises
    ------
    TachlessError
        No mesh line, or the band is not clean (see the module docstring), or fewer than two
        revolutions remain after the edges are dropped.

    Examples
    --------
    >>> import numpy as np
    >>> fs = 5_000.0
    >>> t = np.arange(int(3 * fs)) / fs
    >>> x = np.cos(2 * np.pi * 20 * 30.0 * t) + 0.05 * np.random.default_rng(0).standard_normal(t.size)
    >>> est = tachless_shaft_angle(x, fs, 20, approx_shaft_hz=30.0)
    >>> round(est.mean_shaft_hz, 3), bool(np.allclose(np.diff(est.pulse_times_s), 1 / 30.0, atol=2e-5))
    (30.0, True)
    """
    x = _checked_signal(signal, sample_rate_hz)
    if int(mesh_order) != mesh_order or mesh_order < 1:
        raise TachlessError(f"mesh_order must be a positive integer, got {mesh_order}")
    if int(harmonic) != harmonic or harmonic < 1:
        raise TachlessError(f"harmonic must be a positive integer, got {harmonic}")
    if not 0 < bandwidth_orders < mesh_order / 2:
        raise TachlessError(
            f"bandwidth_orders must be in (0, mesh_order/2 = {mesh_order / 2}), got {bandwidth_orders}"
        )
    duration_s = x.size / sample_rate_hz
    if approx_shaft_hz is None:
        approx_shaft_hz = _shaft_from_mesh_comb(x, sample_rate_hz, mesh_order, harmonic, duration_s)
    cycles_per_rev = harmonic * mesh_order
    if track_speed and follow_drift:
        # The speed tracked on the whole mesh comb, frame by frame: a drift of tens of per
        # cent moves one harmonic across its neighbours' search windows; the comb does not.
        if shaft_cycles is None:
            shaft_cycles = comb_shaft_cycles(
                x, sample_rate_hz, mesh_order, approx_shaft_hz, search_fraction=search_fraction
            )
        ridge_cycles = cycles_per_rev * np.asarray(shaft_cycles, dtype=np.float64)
        line_hz = float(ridge_cycles[-1] / duration_s)
        ridge_cycles = _refined_ridge(x, sample_rate_hz, ridge_cycles, line_hz / cycles_per_rev)
        prominence_db = dechirped_prominence_db(x, ridge_cycles)
        if prominence_db < MIN_LINE_PROMINENCE_DB:
            raise TachlessError(
                f"no mesh line along the tracked speed (harmonic {harmonic} of order {mesh_order}, "
                f"{line_hz:.6g} Hz on average): it stands {prominence_db:.1f} dB above the floor, "
                f"{MIN_LINE_PROMINENCE_DB:.0f} dB needed"
            )
    else:
        line_hz, prominence_db = mesh_line_hz(
            x, sample_rate_hz, mesh_order, approx_shaft_hz, harmonic=harmonic, search_fraction=search_fraction
        )
        # Centre the band on the power centroid around the peak: a speed fluctuation spreads
        # the line into FM sidebands, and the tallest of them need not be the carrier.
        line_hz = _power_centroid_hz(x, sample_rate_hz, line_hz, bandwidth_orders * line_hz / cycles_per_rev)
        ridge_cycles = (mesh_ridge_cycles(x, sample_rate_hz, line_hz, search_fraction=search_fraction)
                        if track_speed else np.zeros(x.size))
    shaft_hz = line_hz / cycles_per_rev
    if track_speed:
        band = _analytic_band(
            x * np.exp(-2j * np.pi * ridge_cycles), sample_rate_hz, 0.0, bandwidth_orders * shaft_hz,
            two_sided=True,
        )
    else:
        band = _analytic_band(x, sample_rate_hz, line_hz, bandwidth_orders * shaft_hz)

    # Keep the span unaffected by the circular filter's wrap-around.
    edge = math.ceil(EDGE_REVOLUTIONS_PER_INVERSE_BAND / bandwidth_orders * sample_rate_hz / shaft_hz)
    if x.size - 2 * edge < 2 * sample_rate_hz / shaft_hz:
        raise TachlessError(
            f"the record ({duration_s:.3g} s) is too short: less than two revolutions remain after "
            f"dropping {edge} samples at each end (band-pass edges)"
        )
    kept = band[edge : x.size - edge]
    kept_ridge = ridge_cycles[edge : x.size - edge]
    envelope = np.abs(kept)
    envelope_ratio = float(envelope.min() / np.median(envelope))
    if envelope_ratio < MIN_ENVELOPE_RATIO:
        raise TachlessError(
            f"the band around {line_hz:.6g} Hz is not clean: its envelope drops to "
            f"{envelope_ratio:.3f} of its median (a phase slip); try another harmonic or a narrower band"
        )
    # Mesh phase in mesh periods (cycles of the fundamental), increasing with time.
    mesh_phase = (np.unwrap(np.angle(kept)) / (2.0 * np.pi) + kept_ridge) / harmonic
    if np.min(np.diff(mesh_phase)) <= 0.0:
        raise TachlessError(
            f"the band around {line_hz:.6g} Hz is not clean: its phase does not advance steadily "
            "(instantaneous speed outside the plausible range)"
        )
    # Pulses where the mesh phase is a whole number of mesh periods, one per revolution.
    first = math.ceil(mesh_phase[0]) + int(offset_mesh_periods) % mesh_order
    if first - mesh_phase[0] >= mesh_order:
        first -= mesh_order
    levels = np.arange(first, mesh_phase[-1], mesh_order, dtype=np.float64)
    if levels.size < 3:
        raise TachlessError("fewer than two whole revolutions in the usable span")
    index = np.searchsorted(mesh_phase, levels) - 1
    index = np.clip(index, 0, mesh_phase.size - 2)
    fraction = (levels - mesh_phase[index]) / (mesh_phase[index + 1] - mesh_phase[index])
    pulse_times_s = (edge + index + fraction) / sample_rate_hz
    rev_hz = 1.0 / np.diff(pulse_times_s)
    mean_hz = float((pulse_times_s.size - 1) / (pulse_times_s[-1] - pulse_times_s[0]))
    variation = float((rev_hz.max() - rev_hz.min()) / mean_hz)
    if variation > 2 * MAX_SPEED_DEVIATION:
        raise TachlessError(
            f"the band around {line_hz:.6g} Hz is not clean: the per-revolution speed varies by "
            f"{100 * variation:.0f} % (over {200 * MAX_SPEED_DEVIATION:.0f} %)"
        )
    return ShaftAngleEstimate(
        pulse_times_s=np.asarray(pulse_times_s, dtype=np.float64),
        mean_shaft_hz=mean_hz,
        mesh_line_hz=float(line_hz),
        line_prominence_db=prominence_db,
        min_envelope_ratio=envelope_ratio,
        speed_variation=variation,
        mesh_order=int(mesh_order),
        harmonic=int(harmonic),
    )


def shaft_pulse_times_from_mesh(
    signal: ArrayLike,
    sample_rate_hz: float,
    mesh_order: int,
    approx_shaft_hz: float | None = None,
    harmonic: int = 1,
    bandwidth_orders: float = 0.3,
    *,
    offset_mesh_periods: int = 0,
) -> FloatArray:
    """Synthetic once-per-revolution pulse times (s) from the mesh phase.

    The pulse times of :func:`tachless_shaft_angle` (see there for the parameters); use them
    as a tachometer with ``pulses_per_rev = 1`` on the shaft with ``mesh_order`` teeth.

    Examples
    --------
    >>> import numpy as np
    >>> fs = 5_000.0
    >>> t = np.arange(int(2 * fs)) / fs
    >>> x = np.cos(2 * np.pi * 20 * 30.0 * t)
    >>> p = shaft_pulse_times_from_mesh(x, fs, 20, approx_shaft_hz=30.0)
    >>> bool(np.allclose(np.diff(p), 1 / 30.0, atol=1e-6))
    True
    """
    return tachless_shaft_angle(
        signal,
        sample_rate_hz,
        mesh_order,
        approx_shaft_hz=approx_shaft_hz,
        harmonic=harmonic,
        bandwidth_orders=bandwidth_orders,
        offset_mesh_periods=offset_mesh_periods,
    ).pulse_times_s


def _shaft_from_mesh_comb(
    x: FloatArray, sample_rate_hz: float, mesh_order: int, harmonic: int, duration_s: float
) -> float:
    """Shaft speed when none is given: comb search up to the highest speed whose mesh line fits."""
    max_shaft_hz = 0.45 * sample_rate_hz / (harmonic * mesh_order)
    min_shaft_hz = min(20.0 / duration_s, 0.5 * max_shaft_hz)
    return estimate_shaft_hz(x, sample_rate_hz, min_shaft_hz=min_shaft_hz, max_shaft_hz=max_shaft_hz)


def _power_centroid_hz(x: FloatArray, sample_rate_hz: float, centre_hz: float, half_width_hz: float) -> float:
    """Power-weighted mean frequency of ``x`` within ``centre ± half_width``."""
    import scipy.fft  # only without a tachometer: not on the tach path's imports

    power = np.abs(scipy.fft.rfft(x * np.hanning(x.size))) ** 2
    freq = np.fft.rfftfreq(x.size, d=1.0 / sample_rate_hz)
    inside = np.abs(freq - centre_hz) <= half_width_hz
    if not np.any(inside) or power[inside].sum() <= 0.0:
        return centre_hz
    return float(np.sum(freq[inside] * power[inside]) / np.sum(power[inside]))


MAX_COMB_CANDIDATES = 4001
"""Candidate speeds of :func:`comb_speed_hz` at most (each harmonic's prominence is max-pooled
over the grid step, so a coarser grid misses no line)."""

COMB_TIE_NP = 0.1
"""Comb scores (capped, in nepers) this close to the best are a tie, broken by the uncapped sum."""

NEIGHBOUR_FRACTION = 0.4
"""Around the comb's speed, mesh harmonic ``h`` is looked for within ``±NEIGHBOUR_FRACTION / h``
(relative): never nearer its neighbours ``h ± 1`` than 60 % of the way."""

HARMONIC_AGREEMENT = 0.01
"""Lines that stand :data:`MIN_LINE_PROMINENCE_DB` out in the whole record's spectrum are narrow,
so the speeds they imply as mesh harmonics agree to within a per cent
(:func:`agreeing_harmonics`); one that does not is another line (a fixed tone, the other shaft)."""


def comb_speed_hz(
    prominence: ArrayLike,
    frequency_hz: ArrayLike,
    mesh_order: int,
    approx_shaft_hz: float,
    *,
    search_fraction: float = 0.2,
) -> float:
    """The shaft speed within ±``search_fraction`` of ``approx_shaft_hz`` at which the mesh
    harmonics 1…:data:`MAX_COMB_HARMONICS` stand highest *together* in one spectrum.

    ``prominence`` and ``frequency_hz`` are :func:`dsp.meshspectrum.line_prominence` of the
    record; each harmonic's contribution is cut at 0 and at :data:`~dsp.meshspectrum.COMB_CAP_NP`
    as in :func:`comb_shaft_cycles`, and speeds within :data:`COMB_TIE_NP` of the best score go
    to the one whose lines are tallest uncapped.

    Why the comb and not each harmonic's tallest line: from harmonic 5 on, a ±20 % window holds
    the neighbouring harmonics (5 × 1.2 = 6), and the tallest line in it may be harmonic 6 — whose
    phase, read as harmonic 5's, runs the angle 6/5 too fast, the same way every day (measured:
    4 of 7 days of a 24/48-tooth campaign, aligned to each other and *wrong*). Every harmonic
    lines up at once only at the true speed (harmonic ``h`` is then looked for within
    ±:data:`NEIGHBOUR_FRACTION` / h of where it puts it).

    Examples
    --------
    Harmonic 6 of a 20-tooth mesh at 1000 rpm (2000 Hz) stands 30 × above harmonic 5; a speed
    hint 19 % high puts harmonic 5's expectation at 1983 Hz:

    >>> import numpy as np
    >>> from dsp.meshspectrum import line_prominence
    >>> fs = 8000.0
    >>> t = np.arange(int(4 * fs)) / fs
    >>> x = sum(a * np.cos(2 * np.pi * h * 20 * 16.667 * t) for h, a in [(1, .1), (2, .1), (5, .1), (6, 3)])
    >>> x = x + 0.05 * np.random.default_rng(0).standard_normal(t.size)
    >>> p, f = line_prominence(x, fs)
    >>> abs(comb_speed_hz(p, f, 20, 16.667 * 1.19) - 16.667) < 0.01   # not 16.667 × 6/5 = 20.0
    True
    """
    from scipy import ndimage  # only without a tachometer

    uncapped = np.maximum(np.asarray(prominence, dtype=np.float64), 0.0)
    p = np.minimum(uncapped, COMB_CAP_NP)
    freq = np.asarray(frequency_hz, dtype=np.float64)
    bin_hz = float(freq[1] - freq[0])
    mesh_hz = mesh_order * approx_shaft_hz
    nyquist_hz = float(freq[-1])
    harmonics = [h for h in range(1, MAX_COMB_HARMONICS + 1)
                 if h * mesh_hz * (1 + search_fraction) < 0.9 * nyquist_hz]  # below 0.45 fs
    if not harmonics:
        raise TachlessError(f"no mesh harmonic below 0.45 fs at about {approx_shaft_hz:.6g} Hz")
    fine_step = bin_hz / (2.0 * harmonics[-1] * mesh_order)
    span = 2.0 * search_fraction * approx_shaft_hz
    count = int(min(MAX_COMB_CANDIDATES, math.ceil(span / fine_step) + 1))
    speeds = np.linspace(approx_shaft_hz * (1 - search_fraction), approx_shaft_hz * (1 + search_fraction), count)
    step = speeds[1] - speeds[0] if count > 1 else 0.0
    score = np.zeros(count)
    height = np.zeros(count)
    for h in harmonics:
        reach = math.ceil(h * mesh_order * step / (2.0 * bin_hz))
        bins = np.clip(np.rint(speeds * h * mesh_order / bin_hz).astype(np.int64), 0, p.size - 1)
        for source, total in ((p, score), (uncapped, height)):
            pooled = ndimage.maximum_filter1d(source, 2 * reach + 1, mode="nearest") if reach > 0 else source
            total += pooled[bins]
    # Every candidate whose harmonics all hit lines at the cap scores the same: in a record with
    # a line at every shaft order (a spall's impulse train, little noise), speed × k / teeth
    # does. Among those, the mesh harmonics themselves are the tallest lines.
    tied = score >= float(score.max()) - COMB_TIE_NP
    return float(speeds[int(np.argmax(np.where(tied, height, -np.inf)))])


def agreeing_harmonics(line_hz: dict[int, float], standing: set[int]) -> set[int]:
    """The harmonics among ``standing`` whose lines (``line_hz[h]``, the peak found for mesh
    harmonic ``h``) imply, as ``line / h``, a speed within :data:`HARMONIC_AGREEMENT` of the
    median of those implied speeds; all of them when fewer than three stand out (no majority).

    On the real SpectraQuest records a fixed 5957-Hz tone, 37 dB high, stands 3.8 % above
    harmonic 6 of the 32-tooth wheel, inside its window; harmonics 1–4 agree on 29.87 Hz and the
    tone implies 31.03 Hz. Read as harmonic 6, a pure tone has no jitter and would win, and the
    angle would run 3.8 % fast.

    Examples
    --------
    >>> sorted(agreeing_harmonics({1: 956.0, 2: 1911.8, 3: 2867.8, 6: 5957.3}, {1, 2, 3, 6}))
    [1, 2, 3]
    """
    if len(standing) < 3:
        return set(standing)
    implied = {h: line_hz[h] / h for h in standing}
    centre = float(np.median(list(implied.values())))
    return {h for h, speed in implied.items() if abs(speed / centre - 1.0) <= HARMONIC_AGREEMENT}


REFINE_BAND_ORDERS = 1.0
"""Half-width (shaft orders) of the band in which a comb-tracked line's remaining phase is read."""

REFINE_SMOOTH_S = 0.5
"""That phase is averaged over this long: slower than the sidebands of either shaft inside the
band, faster than a slow speed swell."""


def _refined_ridge(x: FloatArray, sample_rate_hz: float, ridge_cycles: FloatArray, shaft_hz: float) -> FloatArray:
    """``ridge_cycles`` plus the line's remaining phase: heterodyned by the ridge, the line is
    within a fraction of an order of 0 Hz; its phase in a ±:data:`REFINE_BAND_ORDERS` band,
    averaged over :data:`REFINE_SMOOTH_S`, is what the frame-wise track missed."""
    wide = _analytic_band(
        x * np.exp(-2j * np.pi * ridge_cycles), sample_rate_hz, 0.0, REFINE_BAND_ORDERS * shaft_hz,
        two_sided=True,
    )
    residual = np.unwrap(np.angle(wide)) / (2.0 * np.pi)
    n = max(1, min(residual.size // 4, int(REFINE_SMOOTH_S * sample_rate_hz)))
    padded = np.pad(residual, (n, n), mode="reflect", reflect_type="odd")
    # moving average by a running sum (a convolution with n taps cost 2.7 s on a 60-s record)
    running = np.concatenate(([0.0], np.cumsum(padded)))
    start = np.arange(residual.size) + n - n // 2
    smooth = (running[start + n] - running[start]) / n
    return np.asarray(ridge_cycles + smooth, dtype=np.float64)


def dechirped_prominence_db(signal: ArrayLike, ridge_cycles: ArrayLike) -> float:
    """Height (dB) of the line that follows ``ridge_cycles`` (its cycles at every sample) above
    the floor around it.

    The signal is heterodyned by the ridge's phase — a line that follows it becomes a line at
    0 Hz — and that line's height is measured as :func:`dsp.meshspectrum.line_prominence`
    does (Hann spectrum, log-amplitude above the median of the ±0.5 % (≥ 50) bins around it;
    the highest of the ±2 bins at 0 Hz). Where the ridge follows nothing, nothing adds up at
    0 Hz: the height stays at a noise bin's few dB.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(40_000) / 8000.0
    >>> cycles = 1000.0 * t + 10.0 * t**2
    >>> x = 0.2 * np.cos(2 * np.pi * cycles) + np.random.default_rng(0).standard_normal(t.size)
    >>> bool(dechirped_prominence_db(x, cycles) > 20), bool(dechirped_prominence_db(x, 1000.0 * t) < 15)
    (True, True)
    """
    import scipy.fft  # only without a tachometer: not on the tach path's imports

    x = np.asarray(signal, dtype=np.float64)
    baseband = x * np.exp(-2j * np.pi * np.asarray(ridge_cycles, dtype=np.float64)) * np.hanning(x.size)
    log_amplitude = np.log(np.abs(np.fft.fftshift(scipy.fft.fft(baseband))) + 1e-300)
    centre = x.size // 2
    half = max(50, int(0.005 * x.size))
    floor = float(np.median(log_amplitude[max(0, centre - half) : centre + half + 1]))
    peak = float(log_amplitude[centre - 2 : centre + 3].max())
    return DB_PER_NEPER * (peak - floor)


def _analytic_band(
    x: NDArray[Any], sample_rate_hz: float, centre_hz: float, half_width_hz: float,
    *, two_sided: bool = False,
) -> NDArray[np.complex128]:
    """Analytic signal of ``x`` band-passed to ``centre ± half_width`` (one-sided FFT mask,
    raised-cosine edges over the outer 30 % of each side). ``two_sided``: keep negative
    frequencies inside the band too (a complex, heterodyned ``x`` around 0 Hz)."""
    import scipy.fft  # only without a tachometer: not on the tach path's imports

    n = x.size
    n_fft = scipy.fft.next_fast_len(n)
    spectrum = scipy.fft.fft(x, n=n_fft)
    freq = np.fft.fftfreq(n_fft, d=1.0 / sample_rate_hz)
    distance = np.abs(freq - centre_hz) / half_width_hz  # 0 at the centre, 1 at the band edge
    flat = 0.7
    taper = np.clip((1.0 - distance) / (1.0 - flat), 0.0, 1.0)
    gain = 0.5 - 0.5 * np.cos(np.pi * taper)
    if not two_sided:
        gain[freq <= 0] = 0.0
    else:
        gain = gain / 2.0  # the caller's complex baseband: no one-sided doubling
    return np.asarray(scipy.fft.ifft(spectrum * 2.0 * gain)[:n], dtype=np.complex128)
