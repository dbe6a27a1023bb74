"""A tooth frame that holds from day to day without a tachometer.

Without a once-per-revolution mark, a synchronous average built on the mesh phase
(:mod:`dsp.tachless`) starts at an arbitrary tooth: two records of one rig differ by a whole
number of mesh periods (and, between a tach record and a tach-less one, by a fraction of a mesh
period too). The tooth-specific content of a real gear — pitch errors, runout, profile
differences — is the same every day, so it is a *fingerprint*: the shift that lines up the
fingerprints of two days is the shift between their tooth numberings.

This module

1. puts an average in a *canonical* position: moved by the fraction of a mesh period that
   brings the first mesh harmonic's maximum to sample 0 (:func:`mesh_phase_position`); two
   canonical averages of one wheel then differ by whole mesh periods only;
2. extracts the fingerprint (:func:`tooth_fingerprint`): the canonical average without order 0
   and the mesh harmonics, sectors with an outlying energy (a spall) damped to the median
   sector energy so that one damaged tooth cannot dominate the match, unit RMS (the mesh
   waveform removed is estimated with the loud sectors weighted down, so a spall stays in
   its own sectors);
3. finds the whole-tooth shift between two fingerprints by circular cross-correlation and
   refuses when it is not clear (:func:`align_fingerprint`): the best correlation must reach
   :data:`MIN_CORRELATION` and fit better than every other whole-tooth shift by
   :data:`MIN_SEPARATION_Z` standard errors (:func:`shift_separation_z`) — or by
   :data:`MIN_CONFIRMED_SEPARATION_Z` when a second, largely independent piece of evidence
   points to the same shift: the pattern of how much each tooth deviates
   (:func:`tooth_energy_pattern`, :func:`sector_pattern_z`);
4. can leave the record's loudest tooth and its ringing out of both tests
   (:func:`loud_sectors`, ``align_fingerprint(..., left_out_sectors=…)``): the caller's second
   attempt on a refused day, when a grown spall reshapes its own sectors.

Everything here is pure: arrays in, arrays and frozen dataclasses out. Shifts are *delays*:
``circular_shift(x, d)[n] = x[n − d]`` (fractional ``d`` by the Fourier shift theorem, exact for
a periodic, band-limited average).

Examples
--------
>>> import numpy as np
>>> rng = np.random.default_rng(0)
>>> teeth, spm = 17, 32
>>> n = np.arange(teeth * spm)
>>> pattern = np.repeat(rng.normal(0, 0.2, teeth), spm)           # per-tooth signature
>>> day1 = np.cos(2 * np.pi * teeth * n / n.size) + pattern
>>> day2 = np.roll(day1, 5 * spm) + rng.normal(0, 0.05, n.size)    # 5 teeth later, noisy
>>> a = align_fingerprint(tooth_fingerprint(day2, teeth), tooth_fingerprint(day1, teeth), teeth)
>>> a.shift_teeth, a.refusal
(5, '')
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "MIN_CONFIRMED_SEPARATION_Z",
    "MIN_CORRELATION",
    "MIN_SECTOR_PATTERN_Z",
    "MIN_SEPARATION_Z",
    "SECTOR_PATTERN_LEAD",
    "FrameAlignment",
    "align_fingerprint",
    "circular_shift",
    "loud_sectors",
    "mesh_phase_position",
    "resample_periodic",
    "sector_pattern_z",
    "shift_separation_z",
    "tooth_energy_pattern",
    "tooth_fingerprint",
]

FloatArray = NDArray[np.float64]

MIN_CORRELATION = 0.15
"""The best whole-tooth shift must correlate at least this well with the reference."""
MIN_SEPARATION_Z = 3.5
"""…and fit better than every other whole-tooth shift by this many standard errors
(:func:`shift_separation_z`); otherwise the frame is refused."""
MIN_CONFIRMED_SEPARATION_Z = 1.5
"""…or by this many, when the per-tooth energy pattern confirms the shift (its best whole-tooth
shift is the same one, standing :data:`MIN_SECTOR_PATTERN_Z` or more above the others).

Why a second test: the waveform match is sharp but fragile — a day's speed or load moves the
transfer path's phase across the orders, and a phase that turns with frequency looks like a
fraction of a tooth's shift, so neighbouring shifts compete (on 4-s development records of
``benchmarks/bench_tachless.py``, the best whole-tooth shift was the right one on 128 of 137
days, but only 71 passed 3.5 standard errors). *How much* each tooth deviates does not depend on
that phase. Measured on the development dumps (seeds 1000–1019, both generators): 71 → 83–98
days aligned on the physics set and 53 → 53–63 on the independent one, none wrong, at thresholds
1.0–2.0 / 2.0–3.0; 1.5 / 2.5 is the middle of that range, not its best (with the lead of
:data:`SECTOR_PATTERN_LEAD`: 89 and 57). Held-out (seeds 9300–9319): 58 → 70 of 140 physics
days, none wrong by the tach's angle (docs/tachless.md). The caller withholds the confirmation
from an angle read along a sweeping speed (``no_confirmation_reason``): there it added wrong
days (docs/tachless.md)."""
MIN_SECTOR_PATTERN_Z = 2.5
"""The per-tooth energy pattern's correlation at the confirmed shift, in standard deviations of
its correlations at the other whole-tooth shifts (:func:`sector_pattern_z`)."""
SECTOR_PATTERN_LEAD = 0.5
"""…and the pattern must lead every other shift by this many of those standard deviations: two
shifts that fit alike (a pattern that repeats within a revolution) confirm nothing."""
SEARCH_REACH_TEETH = 0.25
"""Each whole-tooth shift is scored by the best correlation within this fraction of a tooth."""
OUTLIER_SECTOR_ENERGY_RATIO = 4.0
"""A tooth sector whose fingerprint energy exceeds this × the median sector energy is scaled
down to the median (a spall, a glitch): one tooth must not carry the match."""
LEFT_OUT_BEFORE = 1
"""Sectors before the loudest one that a second alignment attempt leaves out (:func:`loud_sectors`)."""
LEFT_OUT_AFTER = 2
"""…and after it: a ringing transfer path carries the impact into the next teeth."""
MAX_LEFT_OUT_FRACTION = 0.25
"""At most this fraction of the teeth is left out; otherwise nothing is."""


@dataclass(frozen=True)
class FrameAlignment:
    """Result of matching a record's fingerprint to a reference fingerprint.

    Attributes
    ----------
    shift_teeth : int or None
        Whole teeth ``k`` such that the record's canonical average, *advanced* by ``k`` mesh
        periods (``circular_shift(x, −k·spm)``), lines up with the reference; None when refused.
    correlation : float
        Correlation coefficient at the best shift (−1…1).
    runner_up : float
        Best correlation at any other whole-tooth shift.
    margin : float
        ``correlation − runner_up``.
    refusal : str
        Empty when the shift is accepted, else the reason.
    delay_samples : int
        The record's fingerprint is the reference's delayed by this many samples (the best
        sample shift, within a quarter tooth of ``shift_teeth`` teeth): the canonical positions of
        two noisy averages may differ by a fraction of a mesh period, and this absorbs it.
    separation_z : float
        How many standard errors the best shift's fit leads the closest competing whole-tooth
        shift by (:func:`shift_separation_z`); the noise comes from the residual of the fit.
    candidate_teeth : int
        The best whole-tooth shift, also when refused (for diagnostics only).
    sector_pattern_z : float
        The per-tooth energy pattern's support for ``candidate_teeth`` (:func:`sector_pattern_z`;
        0 when it points to another shift).
    confirmed_by_sector_pattern : bool
        True when the shift was accepted on :data:`MIN_CONFIRMED_SEPARATION_Z` with that
        pattern's confirmation rather than on :data:`MIN_SEPARATION_Z` alone.
    left_out_sectors : tuple of int
        The record's tooth sectors (canonical numbering) both tests left out (:func:`loud_sectors`).
    """

    shift_teeth: int | None
    correlation: float
    runner_up: float
    margin: float
    refusal: str = ""
    delay_samples: int = 0
    separation_z: float = 0.0
    candidate_teeth: int = 0
    sector_pattern_z: float = 0.0
    confirmed_by_sector_pattern: bool = False
    left_out_sectors: tuple[int, ...] = ()


def _checked(average: ArrayLike, teeth: int) -> FloatArray:
    x = np.asarray(average, dtype=np.float64)
    if x.ndim != 1:
        raise ValueError(f"the average must be 1-D, got shape {x.shape}")
    if int(teeth) != teeth or teeth < 2:
        raise ValueError(f"teeth must be an integer ≥ 2, got {teeth}")
    if x.size % teeth or x.size // teeth < 4:
        raise ValueError(
            f"the average ({x.size} samples) must hold a whole number (≥ 4) of samples per tooth of {teeth}"
        )
    if not np.all(np.isfinite(x)):
        raise ValueError("the average contains NaN or inf")
    return x


def circular_shift(x: ArrayLike, delay_samples: float) -> FloatArray:
    """``y[n] = x[n − delay]`` on a periodic signal; a fractional delay by a Fourier phase ramp.

    Examples
    --------
    >>> import numpy as np
    >>> circular_shift(np.array([1.0, 2.0, 3.0, 4.0]), 1).round(12).tolist()
    [4.0, 1.0, 2.0, 3.0]
    """
    values = np.asarray(x, dtype=np.float64)
    n = values.size
    if float(delay_samples).is_integer():
        return np.roll(values, int(delay_samples))
    spectrum = np.fft.rfft(values)
    orders = np.arange(spectrum.size)
    spectrum = spectrum * np.exp(-2j * np.pi * orders * float(delay_samples) / n)
    if n % 2 == 0:
        # the Nyquist bin of a real signal must stay real: keep its cosine part
        spectrum[-1] = spectrum[-1].real
    return np.asarray(np.fft.irfft(spectrum, n=n), dtype=np.float64)


def resample_periodic(x: ArrayLike, samples: int) -> FloatArray:
    """A periodic signal on another number of samples per period (Fourier truncation/zero-padding)."""
    values = np.asarray(x, dtype=np.float64)
    if values.size == samples:
        return values.copy()
    spectrum = np.fft.rfft(values)
    out = np.zeros(samples // 2 + 1, dtype=np.complex128)
    keep = min(spectrum.size, out.size)
    out[:keep] = spectrum[:keep]
    if samples % 2 == 0 and keep == out.size:
        out[-1] = out[-1].real
    return np.asarray(np.fft.irfft(out, n=samples) * samples / values.size, dtype=np.float64)


def mesh_phase_position(average: ArrayLike, teeth: int) -> float:
    """Where (in samples, ``[0, samples per tooth)``) the first mesh harmonic has its maximum.

    ``circular_shift(average, −position)`` is the *canonical* average: its first mesh harmonic
    peaks at sample 0, so canonical averages of one wheel differ by whole mesh periods.

    Examples
    --------
    >>> import numpy as np
    >>> n = np.arange(80)
    >>> round(mesh_phase_position(np.cos(2 * np.pi * 10 * (n - 3.25) / 80), 10), 6)
    3.25
    """
    x = _checked(average, teeth)
    coefficient = np.fft.rfft(x)[teeth]
    per_tooth = x.size / teeth
    return float((-np.angle(coefficient) / (2.0 * np.pi)) % 1.0 * per_tooth)


def _tooth_deviations(x: FloatArray, teeth: int) -> tuple[FloatArray, FloatArray]:
    """Each tooth sector of the canonical average minus the mesh waveform, and its energy.

    The mesh waveform (order 0 and every mesh harmonic: what every tooth shares) is the mean
    of the sectors, weighted down where a sector is loud (above
    :data:`OUTLIER_SECTOR_ENERGY_RATIO` × the median energy, weight ratio/its energy): the plain
    mean would carry 1/teeth of a spall's impact into every other sector, and a grown spall
    would then reshape the whole fingerprint. The weight falls smoothly, so a tooth near the
    threshold does not flip the fingerprint between days.
    """
    canonical = circular_shift(x, -mesh_phase_position(x, teeth))
    sectors = canonical.reshape(teeth, -1)
    deviations = sectors - sectors.mean(axis=0)
    energy = np.mean(deviations**2, axis=1)
    median = float(np.median(energy))
    loud = energy > OUTLIER_SECTOR_ENERGY_RATIO * median
    if median > 0.0 and loud.any():
        weight = np.minimum(1.0, OUTLIER_SECTOR_ENERGY_RATIO * median / energy)
        deviations = sectors - weight @ sectors / weight.sum()
        energy = np.mean(deviations**2, axis=1)
    return deviations, energy


def tooth_fingerprint(average: ArrayLike, teeth: int) -> FloatArray:
    """The tooth-specific pattern of a synchronous average, canonical, unit RMS.

    The average is moved to its canonical position (:func:`mesh_phase_position`), order 0 and
    every mesh harmonic are removed (they are the same for every tooth; estimated without the
    loud sectors' weight, :func:`_tooth_deviations`), and each tooth sector
    whose energy exceeds :data:`OUTLIER_SECTOR_ENERGY_RATIO` × the median sector energy is
    scaled down to the median: a spall that grows from day to day changes one sector, and must
    not outweigh the rest of the pattern. A fingerprint with no energy left (a perfectly
    regular average) is returned as zeros.

    Examples
    --------
    >>> import numpy as np
    >>> fp = tooth_fingerprint(np.cos(2 * np.pi * 8 * np.arange(64) / 64) + np.eye(64)[5], 8)
    >>> round(float(np.sqrt(np.mean(fp**2))), 6)
    1.0
    """
    x = _checked(average, teeth)
    sectors, energy = _tooth_deviations(x, teeth)
    median = float(np.median(energy))
    if median > 0.0:
        loud = energy > OUTLIER_SECTOR_ENERGY_RATIO * median
        sectors[loud] *= np.sqrt(median / energy[loud])[:, None]
    pattern = sectors.reshape(-1)
    rms = float(np.sqrt(np.mean(pattern**2)))
    # rounding residue of a perfectly regular average is no pattern
    regular = rms <= 1e-9 * float(np.sqrt(np.mean(x**2)))
    return np.asarray(np.zeros_like(pattern) if regular else pattern / rms, dtype=np.float64)


def loud_sectors(average: ArrayLike, teeth: int) -> NDArray[np.bool_]:
    """Tooth sectors of a canonical fingerprint to leave out of a second alignment attempt.

    The loudest sector, when its energy (before :func:`tooth_fingerprint` damps it) exceeds
    :data:`OUTLIER_SECTOR_ENERGY_RATIO` × the median sector energy, with
    :data:`LEFT_OUT_BEFORE` sector before and :data:`LEFT_OUT_AFTER` after it (a ringing
    transfer path carries a tooth's impact into the next sectors). Only the loudest: a spall is
    one tooth, and a healthy wheel's loud teeth are its fingerprint. All False when there is no
    such sector or when that would leave out more than :data:`MAX_LEFT_OUT_FRACTION` of the
    teeth (a wheel that small has too little pattern left).

    Examples
    --------
    >>> import numpy as np
    >>> x = np.cos(2 * np.pi * 16 * np.arange(128) / 128) + 0.01 * np.sin(np.arange(128))
    >>> x[42] += 3.0                                  # sector 5 of 16 (samples 40–47)
    >>> np.flatnonzero(loud_sectors(x, 16)).tolist()
    [4, 5, 6, 7]
    """
    x = _checked(average, teeth)
    _, energy = _tooth_deviations(x, teeth)
    median = float(np.median(energy))
    left_out = np.zeros(teeth, dtype=bool)
    # rounding residue of a perfectly regular average has no loud tooth
    if not median > 1e-18 * float(np.mean(x**2)):
        return left_out
    loudest = int(np.argmax(energy))
    if energy[loudest] > OUTLIER_SECTOR_ENERGY_RATIO * median:
        left_out[np.arange(loudest - LEFT_OUT_BEFORE, loudest + LEFT_OUT_AFTER + 1) % teeth] = True
    if left_out.sum() > MAX_LEFT_OUT_FRACTION * teeth:
        left_out[:] = False
    return left_out


def align_fingerprint(
    fingerprint: ArrayLike,
    reference: ArrayLike,
    teeth: int,
    *,
    min_correlation: float = MIN_CORRELATION,
    min_separation_z: float = MIN_SEPARATION_Z,
    min_confirmed_separation_z: float = MIN_CONFIRMED_SEPARATION_Z,
    min_sector_pattern_z: float = MIN_SECTOR_PATTERN_Z,
    no_confirmation_reason: str = "",
    left_out_sectors: ArrayLike | None = None,
) -> FrameAlignment:
    """Whole-tooth shift that lines a record's fingerprint up with the reference's.

    Circular cross-correlation over every sample shift; each whole-tooth shift ``k`` scores
    the best correlation within a quarter tooth of ``k`` teeth (``teeth`` candidates: the
    canonical positions of noisy averages may disagree by a fraction of a mesh period); the
    reference is resampled to the record's length when they differ. Refused (with the
    reason, ``shift_teeth`` None) when the best correlation is below ``min_correlation`` (the
    pattern is not the reference's: another gear, a re-assembly, too much noise) or leads
    every other whole-tooth shift by less than ``min_separation_z`` standard errors
    (:func:`shift_separation_z`; ambiguous: two teeth look alike, or the noise hides which) —
    unless it leads by ``min_confirmed_separation_z`` and the per-tooth energy pattern puts its
    own best shift at the same one, ``min_sector_pattern_z`` or more above the others
    (:func:`sector_pattern_z`; :data:`MIN_CONFIRMED_SEPARATION_Z` says why) and no
    ``no_confirmation_reason`` is given (the caller's reason not to lower the bar, e.g. a
    shaft angle read along a sweeping speed, which wanders by fractions of a tooth). The
    correlation margin over the runner-up is reported, not used: a smooth pattern (runout)
    correlates almost as well one tooth away, yet the orders that tell the two shifts apart may
    be well above the noise.

    Examples
    --------
    >>> import numpy as np
    >>> flat = np.zeros(64)
    >>> align_fingerprint(flat, flat, 8).refusal
    'no tooth pattern to align: the record or the reference average is perfectly regular'
    """
    fp = _checked(fingerprint, teeth)
    ref = resample_periodic(_checked(reference, teeth), fp.size)
    left_out = np.zeros(teeth, dtype=bool) if left_out_sectors is None else np.asarray(left_out_sectors, dtype=bool)
    keep = None if not left_out.any() else np.repeat(~left_out, fp.size // teeth)
    if keep is not None:
        fp = fp * keep
    norm = float(np.linalg.norm(fp) * np.linalg.norm(ref))
    if not norm > 0.0:
        return FrameAlignment(None, 0.0, 0.0, 0.0,
                              "no tooth pattern to align: the record or the reference average is perfectly regular")
    # c[s] = Σ_n fp[n + s]·ref[n]: fp delayed by d peaks at s = d
    full = np.fft.irfft(np.fft.rfft(fp) * np.conj(np.fft.rfft(ref)), n=fp.size) / norm
    per_tooth = fp.size // teeth
    # window k: shifts within a quarter tooth of k teeth (not half: a neighbour's window would
    # then reach the flank of the true peak and eat the margin)
    reach = int(SEARCH_REACH_TEETH * per_tooth)
    windows = np.roll(full, reach).reshape(teeth, per_tooth)[:, : 2 * reach + 1]
    candidates = windows.max(axis=1)
    order = np.argsort(candidates)[::-1]
    best, second = int(order[0]), int(order[1])
    delay = (best * per_tooth - reach + int(np.argmax(windows[best]))) % fp.size
    correlation, runner_up = float(candidates[best]), float(candidates[second])
    margin = correlation - runner_up
    others = [j for j in range(teeth) if j != best]
    other_delays = [(j * per_tooth - reach + int(np.argmax(windows[j]))) % fp.size for j in others]
    separations = (shift_separation_z(fp, ref, int(delay), other_delays, teeth, keep=keep)
                   if others else np.array([math.inf]))
    z = float(separations.min())
    sector_z = sector_pattern_z(fp, ref, teeth, int(delay), best, left_out=left_out)
    left_out_list = tuple(int(j) for j in np.flatnonzero(left_out))
    if correlation < min_correlation:
        return FrameAlignment(
            None, correlation, runner_up, margin,
            f"the tooth pattern does not match the reference: best correlation {correlation:.2f} "
            f"(shift {best} teeth) < {min_correlation:.2f}",
            delay_samples=int(delay), separation_z=z, candidate_teeth=best, sector_pattern_z=sector_z,
            left_out_sectors=left_out_list,
        )
    confirmed = (not no_confirmation_reason and z >= min_confirmed_separation_z
                 and sector_z >= min_sector_pattern_z)
    if z < min_separation_z and not confirmed:
        closest = others[int(np.argmin(separations))]
        other_rule = (
            f"no confirmation by the per-tooth energy pattern: {no_confirmation_reason}"
            if no_confirmation_reason
            else f"or < {min_confirmed_separation_z:g} with the per-tooth energy pattern's "
            + (f"confirmation, which stands at {sector_z:.1f} < {min_sector_pattern_z:g}"
               if sector_z < min_sector_pattern_z
               else f"confirmation, which it has ({sector_z:.1f} ≥ {min_sector_pattern_z:g})")
        )
        return FrameAlignment(
            None, correlation, runner_up, margin,
            f"ambiguous tooth frame: shift {best} teeth (correlation {correlation:.2f}) leads shift "
            f"{closest} by only {z:.1f} standard errors (< {min_separation_z:g}, {other_rule}; "
            f"correlation margin over the runner-up {margin:.2f})",
            delay_samples=int(delay), separation_z=z, candidate_teeth=best, sector_pattern_z=sector_z,
            left_out_sectors=left_out_list,
        )
    return FrameAlignment(best, correlation, runner_up, margin, delay_samples=int(delay),
                          separation_z=z, candidate_teeth=best, sector_pattern_z=sector_z,
                          confirmed_by_sector_pattern=z < min_separation_z,
                          left_out_sectors=left_out_list)


def tooth_energy_pattern(fingerprint: ArrayLike, teeth: int, left_out: ArrayLike | None = None) -> FloatArray:
    """How much each tooth sector of a fingerprint deviates: log mean square per sector,
    standardised (mean 0, standard deviation 1; zeros when every sector is alike). Sectors in
    ``left_out`` (boolean per tooth) are 0 — no vote — and the rest standardised without them.

    A whole-tooth shift of the record rolls this vector; a phase that turns with frequency (a
    transfer path seen at another speed) reshapes the waveform inside the sectors but moves
    little energy between them.

    Examples
    --------
    >>> import numpy as np
    >>> fp = np.repeat([1.0, 2.0, 1.0, 2.0], 8)
    >>> tooth_energy_pattern(fp, 4).round(6).tolist()
    [-1.0, 1.0, -1.0, 1.0]
    """
    x = _checked(fingerprint, teeth)
    energy = np.log(np.mean(x.reshape(teeth, -1) ** 2, axis=1) + 1e-300)
    kept = np.ones(teeth, dtype=bool) if left_out is None else ~np.asarray(left_out, dtype=bool)
    spread = float(np.std(energy[kept]))
    # sectors equal to rounding: no pattern (a tolerance, not 0: log of equal values may differ in the last bit)
    if not spread > 1e-9 * max(1.0, float(np.max(np.abs(energy[kept])))):
        return np.zeros(teeth)
    return np.asarray(np.where(kept, (energy - energy[kept].mean()) / spread, 0.0), dtype=np.float64)


def sector_pattern_z(
    fingerprint: ArrayLike, reference: ArrayLike, teeth: int, delay_samples: int, shift_teeth: int,
    *, left_out: ArrayLike | None = None,
) -> float:
    """Support of the per-tooth energy pattern for whole-tooth shift ``shift_teeth``.

    The record's fingerprint is first moved by the part of ``delay_samples`` beyond
    ``shift_teeth`` teeth, so that its sectors are the reference's ``shift_teeth`` teeth on; the
    correlation of the two :func:`tooth_energy_pattern` vectors is then taken at every whole-tooth
    shift. Returns how many standard deviations of the other shifts' correlations the one at
    ``shift_teeth`` stands above their mean — and 0 when it does not lead every other shift by
    :data:`SECTOR_PATTERN_LEAD` of those deviations (the pattern points elsewhere, or cannot
    tell two shifts apart). The other shifts' spread is the null:
    it carries the patterns' own smoothness (a ringing path spreads a tooth's deviation into
    the next sector), which a formula for independent sectors would not.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> reference = np.repeat(rng.lognormal(0, 0.5, 24), 16) * rng.choice([-1.0, 1.0], 384)
    >>> record = np.roll(reference, 5 * 16 + 3)            # 5 teeth and 3 samples later
    >>> bool(sector_pattern_z(record, reference, 24, 5 * 16 + 3, 5) > 4)
    True
    >>> sector_pattern_z(record, reference, 24, 6 * 16 + 3, 6)
    0.0
    """
    fp = _checked(fingerprint, teeth)
    ref = resample_periodic(_checked(reference, teeth), fp.size)
    n = fp.size
    per_tooth = n // teeth
    beyond = (int(delay_samples) - int(shift_teeth) * per_tooth + n // 2) % n - n // 2
    # the record's own left-out sectors have no vote
    record_pattern = tooth_energy_pattern(np.roll(fp, -beyond), teeth, left_out)
    reference_pattern = tooth_energy_pattern(ref, teeth)
    # scores[k] = mean_j record[j]·reference[j − k]: the record is the reference k teeth later
    scores = np.fft.irfft(np.fft.rfft(record_pattern) * np.conj(np.fft.rfft(reference_pattern)), n=teeth) / teeth
    k = int(shift_teeth) % teeth
    others = np.delete(scores, k)
    spread = float(np.std(others))
    if not spread > 0.0 or scores[k] - others.max() < SECTOR_PATTERN_LEAD * spread:
        return 0.0
    return float((scores[k] - others.mean()) / spread)


def shift_separation_z(
    fingerprint: ArrayLike, reference: ArrayLike, best_delay: int, other_delays: ArrayLike, teeth: int,
    *, keep: ArrayLike | None = None,
) -> FloatArray:
    """Standard errors by which ``best_delay`` fits the record better than each other delay.

    The record's fingerprint ``f`` is modelled as the reference ``r`` delayed by ``d`` and
    scaled, plus noise: ``f = α·r(· − d) + e``. For a competing delay ``d'``, the evidence for
    ``d`` is ``D = ⟨f, r(· − d) − r(· − d')⟩`` (the difference of the two fits' residual
    energies, over 2α); under the model its noise is ``⟨e, r(· − d) − r(· − d')⟩``, whose
    variance is the sum over orders of the noise power times the power of the difference
    ``|R_k|²·|e^{−iω_k d} − e^{−iω_k d'}|²``. The noise power per order is the residual's
    ``|F_k − α R_k e^{−iω_k d}|²``, smoothed over ``teeth`` neighbouring orders: it holds the
    record's noise, the reference's noise and whatever does not match (a growing spall), so a
    poor fit makes every separation small.

    Why this and not only the correlation margin: a smooth pattern (runout, a slow index
    error) correlates almost as well one tooth away, so the margin between neighbouring shifts
    is small — but so is its noise, since both fits share the smooth part. The separation
    weighs each order by how much it tells the two shifts apart.

    Returns
    -------
    ndarray
        One z per entry of ``other_delays`` (finite: the noise has a floor of 1e-12 of the
        record's power, so an exact copy of the reference gives a large number, not inf).

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(3)
    >>> ref = np.convolve(rng.normal(size=640), np.ones(40) / 40, mode="same")   # smooth pattern
    >>> rec = np.roll(ref, 96) + 0.02 * rng.normal(size=640)
    >>> z = shift_separation_z(rec, ref, 96, [64, 128, 320], 20)
    >>> bool(z.min() > 8)
    True
    """
    f = np.asarray(fingerprint, dtype=np.float64)
    r = resample_periodic(np.asarray(reference, dtype=np.float64), f.size)
    if keep is not None:
        return _masked_separation_z(f, r, best_delay, other_delays, teeth, np.asarray(keep, dtype=bool))
    n = f.size
    big_f, big_r = np.fft.rfft(f), np.fft.rfft(r)
    k = np.arange(big_f.size)
    weight = _rfft_weights(n)
    energy = float(np.sum(weight * np.abs(big_r) ** 2))
    if not energy > 0.0:
        return np.zeros(np.size(other_delays))
    at_best = big_r * np.exp(-2j * np.pi * k * best_delay / n)
    alpha = float(np.sum(weight * (big_f * np.conj(at_best)).real)) / energy
    residual = np.abs(big_f - alpha * at_best) ** 2
    noise = _smoothed_noise(residual, teeth, 1e-12 * float(np.mean(np.abs(big_f) ** 2)))
    z = []
    for other in np.atleast_1d(np.asarray(other_delays, dtype=np.float64)):
        difference = at_best - big_r * np.exp(-2j * np.pi * k * other / n)
        evidence = float(np.sum(weight * (big_f * np.conj(difference)).real))
        variance = float(np.sum(weight**2 * noise * np.abs(difference) ** 2) / 2.0)
        z.append(evidence / math.sqrt(variance) if variance > 0.0 else math.inf)
    return np.asarray(z, dtype=np.float64)


def _rfft_weights(n: int) -> FloatArray:
    """Parseval's weights of a real signal's rfft bins: ``Σ w·|X_k|² = n·Σ x²``."""
    weight = np.full(n // 2 + 1, 2.0)
    weight[0] = 1.0
    if n % 2 == 0:
        weight[-1] = 1.0
    return weight


def _smoothed_noise(power: FloatArray, teeth: int, floor: float) -> FloatArray:
    """Noise power per order: ``power`` smoothed over ``teeth`` neighbouring orders, plus a floor
    (1e-12 of the record's mean power per order: an exact copy gives a large, finite z)."""
    width = max(3, int(teeth) | 1)
    smooth = np.convolve(np.pad(power, width // 2, mode="reflect"), np.ones(width) / width, mode="valid")
    return np.asarray(smooth + floor + 1e-300, dtype=np.float64)


def _masked_separation_z(
    f: FloatArray, r: FloatArray, best_delay: int, other_delays: ArrayLike, teeth: int, keep: NDArray[np.bool_]
) -> FloatArray:
    """:func:`shift_separation_z` over the kept samples only (the rest left out of the fit).

    Each shifted reference is masked like the record, so the fits' residual energies differ by
    ``2α⟨f, g_d − g_d'⟩ − α²(‖g_d‖² − ‖g_d'‖²)`` (no longer the first term alone); the noise
    per order is the masked residual's, divided by the kept fraction.
    """
    n = f.size
    w = keep.astype(np.float64)
    fraction = float(w.mean())
    weight = _rfft_weights(n)
    g_best = w * circular_shift(r, int(best_delay))
    energy_best = float(g_best @ g_best)
    masked = w * f
    if not (energy_best > 0.0 and fraction > 0.0):
        return np.zeros(np.size(other_delays))
    alpha = float(masked @ g_best) / energy_best
    residual = np.abs(np.fft.rfft(masked - alpha * g_best)) ** 2 / fraction
    noise = _smoothed_noise(residual, teeth, 1e-12 * float(np.mean(np.abs(np.fft.rfft(masked)) ** 2)) / fraction)
    z = []
    for other in np.atleast_1d(np.asarray(other_delays, dtype=np.float64)):
        g_other = w * circular_shift(r, float(other))
        difference = g_best - g_other
        evidence = n * (float(masked @ difference) - 0.5 * alpha * (energy_best - float(g_other @ g_other)))
        variance = float(np.sum(weight**2 * noise * np.abs(np.fft.rfft(difference)) ** 2) / 2.0)
        z.append(evidence / math.sqrt(variance) if variance > 0.0 else math.inf)
    return np.asarray(z, dtype=np.float64)


def frame_delay_samples(
    average: ArrayLike, teeth: int, alignment_delay: float, reference_position: float
) -> float:
    """Delay (samples) that brings ``average`` into the reference's frame.

    Canonical (``−mesh_phase_position``), advanced by the alignment's delay
    (:attr:`FrameAlignment.delay_samples`), then moved to where the reference's own average had
    its mesh-harmonic maximum (``reference_position``, samples; 0 when the campaign frame is the
    reference's canonical frame). Wrapped to ``[0, N)``.
    """
    x = _checked(average, teeth)
    delay = -mesh_phase_position(x, teeth) - alignment_delay + reference_position
    return float(math.fmod(delay, x.size) % x.size)
