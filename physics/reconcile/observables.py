"""The reconciliation observable: the complex hunting-period order spectrum and its noise.

A record is resampled onto the pinion angle (:func:`dsp.angle.angle_resample`) and cut into
whole hunting periods (``lcm(Z1, Z2) / Z1`` pinion revolutions: 21 for 20/21), so pinion
orders, gear orders and tooth-pair combinations are all resolved. Each segment's spectrum
``X_s(k) = FFT(segment)/N`` is taken; the observable is their mean ``Y(k)`` and the noise
variance of that mean is estimated from the scatter between segments,
``v(k) = Σ_s |X_s(k) − Y(k)|² / (S (S − 1))``, pooled over neighbouring bins (the segment
count is small, the noise spectrum is smooth) — never assumed. ``2 |r(k)|² / v(k)`` of a
residual ``r`` is then χ² with two degrees of freedom per bin when the model is right.

Hunting bin ``k`` is ``k / revs_per_hunt`` pinion orders; mesh harmonics are multiples of
``lcm(Z1, Z2)``, pinion orders multiples of ``revs_per_hunt``, gear orders multiples of
``lcm / Z2``; the rest are hunting-only (pinion-tooth × gear-tooth) orders.

Examples
--------
>>> import numpy as np
>>> fs, f_rev = 20_000.0, 1000 / 60
>>> t = np.arange(int(6 * fs)) / fs
>>> x = np.cos(2 * np.pi * 20 * f_rev * t) + 0.01 * np.random.default_rng(0).standard_normal(t.size)
>>> pulses = np.arange(0.0, 5.99, 1 / f_rev)
>>> spec = hunting_spectrum(x, fs, pulses, 1, pinion_teeth=20, gear_teeth=21, samples_per_mesh=16)
>>> spec.revs_per_hunt, spec.segments
(21, 4)
>>> k = 420   # mesh harmonic 1: bin lcm(20, 21)
>>> round(float(abs(spec.mean[k])) * 2, 3)
1.0
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dsp.angle import angle_resample
from gearwatch.floor.defaults import SAMPLES_PER_MESH

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

ORDER_CLASSES = ("mesh", "pinion_sideband", "gear_sideband", "hunting_only")


@dataclass(frozen=True)
class HuntingSpectrum:
    """Mean complex spectrum of the hunting-period averages and the variance of that mean.

    ``mean`` and ``variance`` cover bins ``0 .. n_bins − 1`` (one-sided); ``used`` marks the
    bins the fit uses (1 .. the band limit). ``segment_spectra`` keeps each segment's spectrum
    (for odd/even checks and the reference-relative mode).
    """

    mean: ComplexArray
    variance: FloatArray
    used: NDArray[np.bool_]
    segment_spectra: ComplexArray
    pinion_teeth: int
    gear_teeth: int
    revs_per_hunt: int
    samples_per_rev: int
    speed_rpm: float
    segments: int
    pinion_average: FloatArray
    """Pinion synchronous average (one revolution), for the MCI plots."""

    @property
    def n_bins(self) -> int:
        return int(self.mean.shape[-1])

    @property
    def mesh_bin(self) -> int:
        return math.lcm(self.pinion_teeth, self.gear_teeth)

    @property
    def bin_frequency_hz(self) -> FloatArray:
        """Frequency of each bin at the record's mean speed."""
        hunt_hz = self.speed_rpm / 60.0 / self.revs_per_hunt
        return np.asarray(np.arange(self.n_bins) * hunt_hz, dtype=np.float64)

    @property
    def pinion_orders(self) -> FloatArray:
        return np.arange(self.n_bins) / self.revs_per_hunt

    def order_class(self) -> NDArray[np.str_]:
        """Periodicity class of every bin (see module docstring)."""
        return order_classes(self.n_bins, self.pinion_teeth, self.gear_teeth)


def order_classes(n_bins: int, pinion_teeth: int, gear_teeth: int) -> NDArray[np.str_]:
    """Periodicity class (``ORDER_CLASSES``) of hunting bins ``0 .. n_bins − 1``.

    Examples
    --------
    >>> order_classes(43, 20, 21)[[0, 20, 21, 40, 42]].tolist()
    ['mesh', 'gear_sideband', 'pinion_sideband', 'gear_sideband', 'pinion_sideband']
    """
    lcm = math.lcm(pinion_teeth, gear_teeth)
    k = np.arange(n_bins)
    out = np.full(n_bins, "hunting_only", dtype="<U16")
    out[k % (lcm // gear_teeth) == 0] = "gear_sideband"
    out[k % (lcm // pinion_teeth) == 0] = "pinion_sideband"
    out[k % lcm == 0] = "mesh"
    return out


def revs_per_hunting_period(pinion_teeth: int, gear_teeth: int) -> int:
    """Pinion revolutions in one hunting period, ``lcm(Z1, Z2) / Z1``."""
    return math.lcm(pinion_teeth, gear_teeth) // pinion_teeth


def pooled_variance(raw_variance: ArrayLike, half_width_bins: int) -> FloatArray:
    """Running mean of a per-bin variance over ``±half_width_bins`` (edges: shorter windows).

    Examples
    --------
    >>> pooled_variance([1.0, 1.0, 4.0, 1.0, 1.0], 1).round(3).tolist()
    [1.0, 2.0, 2.0, 2.0, 1.0]
    """
    v = np.asarray(raw_variance, dtype=np.float64)
    if half_width_bins <= 0:
        return v.copy()
    c = np.concatenate(([0.0], np.cumsum(v)))
    idx = np.arange(v.size)
    lo = np.clip(idx - half_width_bins, 0, v.size)
    hi = np.clip(idx + half_width_bins + 1, 0, v.size)
    return np.asarray((c[hi] - c[lo]) / (hi - lo), dtype=np.float64)


def hunting_spectrum(
    signal: ArrayLike,
    sample_rate_hz: float,
    pulse_times_s: ArrayLike,
    pulses_per_rev: int,
    *,
    pinion_teeth: int,
    gear_teeth: int,
    samples_per_mesh: int = SAMPLES_PER_MESH,
    max_frequency_hz: float | None = None,
    pool_half_width_bins: int = 10,
    max_segments: int | None = None,
) -> HuntingSpectrum:
    """Hunting-period order spectrum of one accelerometer signal (pinion tachometer).

    Parameters
    ----------
    signal : array_like
        Accelerometer samples.
    sample_rate_hz : float
        Sampling rate.
    pulse_times_s : array_like
        Pinion tachometer pulse times (s); the first pulse is angle 0.
    pulses_per_rev : int
        Pulses per pinion revolution.
    pinion_teeth, gear_teeth : int
        Tooth counts.
    samples_per_mesh : int
        Angle samples per mesh period.
    max_frequency_hz : float, optional
        Highest bin used by the fit; default 0.4 × ``sample_rate_hz`` (the usual anti-alias
        pass band).
    pool_half_width_bins : int
        Half-width of the running mean pooling the per-bin segment variance.
    max_segments : int, optional
        Use at most this many hunting periods (from the first).

    Returns
    -------
    HuntingSpectrum
    """
    spr = pinion_teeth * samples_per_mesh
    revs = angle_resample(signal, sample_rate_hz, pulse_times_s, pulses_per_rev, spr)
    per_hunt = revs_per_hunting_period(pinion_teeth, gear_teeth)
    segments = revs.shape[0] // per_hunt
    if max_segments is not None:
        segments = min(segments, max_segments)
    if segments < 1:
        raise ValueError(
            f"the record holds {revs.shape[0]} pinion revolutions, less than one hunting period "
            f"({per_hunt})"
        )
    seg = revs[: segments * per_hunt].reshape(segments, per_hunt * spr)
    spectra = np.fft.rfft(seg, axis=-1) / seg.shape[-1]
    mean = spectra.mean(axis=0)
    if segments >= 2:
        raw = np.sum(np.abs(spectra - mean) ** 2, axis=0) / (segments * (segments - 1))
        # 1/v̂ is biased high for an estimate with ν degrees of freedom (E[1/v̂] = ν/((ν−2)v));
        # scale so that the mean χ² per bin is 2 when the model is right.
        nu = 2.0 * (segments - 1) * (2 * pool_half_width_bins + 1)
        variance = pooled_variance(raw, pool_half_width_bins) * (nu / (nu - 2.0) if nu > 2 else 1.0)
    else:
        variance = np.full(mean.shape, np.inf)
    pulses = np.asarray(pulse_times_s, dtype=np.float64)
    rev_marks = pulses[:: pulses_per_rev]
    n_rev_time = min(segments * per_hunt, rev_marks.size - 1)
    speed_rpm = 60.0 * n_rev_time / float(rev_marks[n_rev_time] - rev_marks[0])
    hunt_hz = speed_rpm / 60.0 / per_hunt
    f_max = 0.4 * sample_rate_hz if max_frequency_hz is None else max_frequency_hz
    k = np.arange(mean.size)
    used = (k >= 1) & (k * hunt_hz <= f_max) & (k < mean.size - 1) & np.isfinite(variance)
    return HuntingSpectrum(
        mean=mean,
        variance=variance,
        used=used,
        segment_spectra=spectra,
        pinion_teeth=pinion_teeth,
        gear_teeth=gear_teeth,
        revs_per_hunt=per_hunt,
        samples_per_rev=spr,
        speed_rpm=speed_rpm,
        segments=segments,
        pinion_average=np.asarray(revs[: segments * per_hunt].mean(axis=0), dtype=np.float64),
    )


def shift_revolutions(spectrum: HuntingSpectrum, revolutions: int) -> HuntingSpectrum:
    """The same record seen from ``revolutions`` pinion revolutions later (cyclic in the hunting period).

    A whole-revolution shift leaves every pinion order unchanged and turns the gear (and
    tooth-pair) content by that many pinion revolutions: bin ``k`` is multiplied by
    ``exp(2πi k m / R)`` (``R`` revolutions per hunting period). Variances are unchanged.

    Examples
    --------
    >>> import numpy as np
    >>> spr, R = 8, 21
    >>> x = np.cos(2 * np.pi * np.arange(R * spr) / (R * spr) * 20)   # gear order 1
    >>> hs = HuntingSpectrum(np.fft.rfft(x) / x.size, np.ones(x.size // 2 + 1), np.ones(x.size // 2 + 1, bool),
    ...                      (np.fft.rfft(x) / x.size)[None], 20, 21, R, spr, 1000.0, 1, np.zeros(spr))
    >>> moved = np.fft.irfft(shift_revolutions(hs, 3).mean, n=x.size) * x.size
    >>> bool(np.allclose(moved, np.roll(x, -3 * spr)))
    True
    """
    k = np.arange(spectrum.n_bins)
    phase = np.exp(2j * np.pi * k * (revolutions % spectrum.revs_per_hunt) / spectrum.revs_per_hunt)
    return dataclasses.replace(
        spectrum,
        mean=np.asarray(spectrum.mean * phase, dtype=np.complex128),
        segment_spectra=np.asarray(spectrum.segment_spectra * phase, dtype=np.complex128),
    )


def gear_frame_shift(
    spectrum: HuntingSpectrum, reference: HuntingSpectrum, min_reference_snr: float = 10.0
) -> tuple[int, float, float]:
    """Whole pinion revolutions that bring ``spectrum``'s gear frame onto ``reference``'s.

    With a pinion tachometer, a record's hunting period starts wherever the gear happened to
    be at its first pulse: two records of the same rig differ by a whole number of pinion
    revolutions in the gear's frame. Each shift is a hypothesis scored by the χ² of the
    difference ``Σ 2 |Y e^{iφ_m} − Y_ref|² / (v + v_ref)`` over the content that a shift moves
    (not at pinion orders) where the reference stands ``min_reference_snr`` (power, ≈ 10 dB)
    above its noise — thousands of noise-only bins would otherwise drown a few runout
    sidebands.

    Returns
    -------
    (revolutions, match, evidence)
        The shift for :func:`shift_revolutions`; the normalised correlation after it; and the
        χ² by which the runner-up shift is worse (twice the log odds: > 10 is odds above
        150 : 1 against every other shift). ``(0, 0.0, 0.0)`` without frame-carrying content.
    """
    n = min(spectrum.n_bins, reference.n_bins)
    revs = spectrum.revs_per_hunt
    k = np.arange(n)
    snr = np.zeros(n)
    ok = reference.used[:n] & np.isfinite(reference.variance[:n]) & (reference.variance[:n] > 0)
    ok &= np.isfinite(spectrum.variance[:n])
    snr[ok] = np.abs(reference.mean[:n][ok]) ** 2 / reference.variance[:n][ok]
    use = spectrum.used[:n] & ok & (k % revs != 0) & (snr > min_reference_snr)
    if revs <= 1 or np.count_nonzero(use) < 2:
        return 0, 0.0, 0.0
    v = spectrum.variance[:n][use] + reference.variance[:n][use]
    a = spectrum.mean[:n][use]
    b = reference.mean[:n][use]
    m = np.arange(revs)[:, None]
    moved = a[None, :] * np.exp(2j * np.pi * k[use][None, :] * m / revs)
    chi2 = np.sum(2.0 * np.abs(moved - b[None, :]) ** 2 / v[None, :], axis=1)
    order = np.argsort(chi2)
    best = int(order[0])
    match = float(np.real(np.vdot(b, moved[best])) / (np.linalg.norm(a) * np.linalg.norm(b)))
    return best, match, float(chi2[order[1]] - chi2[best])
