"""Experimental estimate of W'', the second derivative of the spall window (seed §3.3).

El Badaoui et al. (MSSP 2001, §3.3, eq. 25) model the accelerometer signal of a gear with a
spall as ``y = (W'' + e) * h``: the second derivative of the spall's windowing function ``W''``
plus the healthy meshing excitation ``e``, both convolved with the transfer-path impulse
response ``h``. They recover ``W''`` in four steps, which :func:`estimate_wdd` follows:

1. comb-filter the mesh harmonics out of the synchronous average (the residual: ``e`` is a line
   spectrum at the mesh harmonics, shaft orders ``n·teeth``);
2. estimate ``h`` from the residual by the random decrement technique (:func:`random_decrement`:
   "the white excitation is assured by the shock due to the spalling defect");
3. fit that estimate with Prony's method, a sum of damped sinusoids (:func:`prony`);
4. divide the residual's spectrum by the fitted frequency response and transform back.

Everything works on one revolution of a synchronous average, sampled uniformly in shaft angle:
"frequencies" are in cycles per sample, and, given the samples per revolution, in shaft orders.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "DampedMode",
    "WddEstimate",
    "estimate_wdd",
    "mode_impulse_response",
    "prony",
    "random_decrement",
]

_EMPTY_RESIDUAL_REL = 1e-12
"""A residual whose standard deviation is below this fraction of the average's peak is FFT
rounding noise: the average is made of mesh harmonics only."""
_REAL_ROOT_REL = 1e-9
"""A root whose imaginary part is below this fraction of its modulus is a real root."""


@dataclass(frozen=True)
class DampedMode:
    """One damped sinusoid ``amplitude · rⁿ · cos(2π·f·n + phase_rad)``, ``n`` in samples.

    ``r = exp(−ζ·ω_n)`` with ``ω_n = ω_d / sqrt(1 − ζ²)`` and ``ω_d = 2π·f`` (rad per sample):
    the sampled impulse response of a single-degree-of-freedom mode of damping ratio ``ζ``.
    A mode from a real root has ``f = 0`` (pure decay) or ``f = 0.5`` (alternating).
    """

    frequency_cycles_per_sample: float
    """Damped frequency ``f`` in cycles per sample, ``0 <= f <= 0.5``."""
    frequency_orders: float
    """The same frequency in shaft orders (``f · samples_per_rev``); NaN when not known."""
    damping_ratio: float
    """Damping ratio ``ζ`` (1 for a pure decay, negative for a growing oscillation)."""
    amplitude: float
    """Amplitude ``A >= 0`` at ``n = 0``, in the units of the fitted signal."""
    phase_rad: float
    """Phase ``φ`` in radians, in ``(−π, π]``."""
    decay_nepers_per_sample: float | None = None
    """``σ = ζ·ω_n = −ln r`` exactly as fitted. ``None``: derived from frequency and damping,
    which is impossible for a pure decay (``f = 0``, where ζ = 1 says nothing about ``r``)."""

    @property
    def pole_radius(self) -> float:
        """``r = exp(−σ)``, the per-sample decay factor."""
        if self.decay_nepers_per_sample is not None:
            return float(np.exp(-self.decay_nepers_per_sample))
        return _pole_radius(self.frequency_cycles_per_sample, self.damping_ratio)


@dataclass(frozen=True)
class WddEstimate:
    """Result of :func:`estimate_wdd`; all arrays are in samples of the revolution."""

    wdd: NDArray[np.float64]
    """Estimated W'' over one revolution (same length as the average)."""
    impulse_response: NDArray[np.float64]
    """Random-decrement estimate of the transfer-path impulse response (``segment_samples``)."""
    modes: tuple[DampedMode, ...]
    """Prony fit of ``impulse_response``, in ascending frequency."""
    residual: NDArray[np.float64]
    """The average with its mean and every mesh harmonic removed."""


def _pole_radius(frequency_cycles_per_sample: float, damping_ratio: float) -> float:
    """``exp(−ζ·ω_n)`` with ``ω_n = 2π·f / sqrt(1 − ζ²)``; needs ``f > 0`` and ``|ζ| < 1``."""
    if frequency_cycles_per_sample <= 0.0 or not -1.0 < damping_ratio < 1.0:
        raise ValueError(
            "the pole radius of a mode with f = 0 or |ζ| >= 1 needs decay_nepers_per_sample"
        )
    damped_rad = 2.0 * np.pi * frequency_cycles_per_sample
    natural_rad = damped_rad / np.sqrt(1.0 - damping_ratio * damping_ratio)
    return float(np.exp(-damping_ratio * natural_rad))


# --------------------------------------------------------------------------------------------
# random decrement


def _crossings(centred: NDArray[np.float64], level: float, last_start: int) -> tuple[
    NDArray[np.intp], NDArray[np.float64]
]:
    """Up-crossings of ``level``: sample ``i`` with ``x[i−1] < level <= x[i]``, ``i <= last_start``.

    Also returns the fraction ``f`` in ``(0, 1]`` of the linear-interpolated crossing instant
    ``i − 1 + f``.
    """
    below = centred[:-1] < level
    above = centred[1:] >= level
    after = np.flatnonzero(below & above) + 1
    after = after[after <= last_start]
    before_value = centred[after - 1]
    fraction = (level - before_value) / (centred[after] - before_value)
    return after, fraction


def _random_decrement(
    centred: NDArray[np.float64], segment_samples: int, level: float, circular: bool
) -> NDArray[np.float64]:
    n_samples = centred.size
    if circular:
        # One revolution of a periodic signal: a segment may run on into the next revolution.
        signal = np.concatenate([centred, centred[: segment_samples + 1]])
        last_start = n_samples
    else:
        signal = centred
        last_start = n_samples - segment_samples
    levels = {level, -level}  # one level when level == 0
    starts: list[NDArray[np.intp]] = []
    fractions: list[NDArray[np.float64]] = []
    for trigger in sorted(levels):
        after, fraction = _crossings(signal, trigger, last_start)
        starts.append(after)
        fractions.append(fraction)
    after = np.concatenate(starts)
    fraction = np.concatenate(fractions)
    if after.size == 0:
        raise ValueError("random decrement: the signal never crosses the trigger level")
    signature = np.empty(segment_samples, dtype=np.float64)
    for lag in range(segment_samples):
        # x(i − 1 + f + lag) by linear interpolation: sub-sample alignment of every segment.
        interpolated = (1.0 - fraction) * signal[after - 1 + lag] + fraction * signal[after + lag]
        signature[lag] = np.mean(interpolated)
    return signature


def random_decrement(
    x: ArrayLike, segment_samples: int, *, trigger_level: float | None = None
) -> NDArray[np.float64]:
    """Random decrement signature: the average of the segments that follow each level crossing.

    ``x`` is centred (its mean removed). A trigger is every *up*-crossing of ``+a`` and every
    up-crossing of ``−a``, with ``a = |trigger_level|`` (default: the standard deviation of
    ``x``); the crossing instant is located between samples by linear interpolation and the
    segment ``x(t_trigger + τ)``, ``τ = 0 … segment_samples − 1``, is read at that sub-sample
    instant (linear interpolation), so segments are aligned to a fraction of a sample.

    Why these triggers: for a zero-mean stationary Gaussian process with autocorrelation
    ``R(τ)``, ``E[x(t+τ) | x(t) = a, ẋ(t) > 0] = a·R(τ)/R(0) − c·R'(τ)`` with ``c > 0``
    (``x`` and ``ẋ`` are uncorrelated at the same instant; Vandiver et al. 1982). Averaging the
    up-crossings of ``+a`` and ``−a`` cancels the ``R`` term and leaves ``∝ −R'(τ)``, which for a
    single-degree-of-freedom system driven by white noise is exactly proportional to its impulse
    response ``e^{−ζω_nτ}·sin(ω_dτ)`` (the seed's use: "estimate the impulse response of a system
    excited by a white noise"). The level only selects which crossings count: a level near the
    standard deviation ignores low-amplitude stretches, where a periodic shock response is
    quiet and a segment would catch the next shock at a random lag. With several modes the
    signature still has every mode's frequency and damping, but not the modal amplitudes of ``h``.

    Parameters
    ----------
    x : array_like, 1-D
        Signal, at least ``segment_samples + 2`` samples long.
    segment_samples : int
        Length of the averaged segment (``>= 1``).
    trigger_level : float, optional
        ``a``, measured from the mean of ``x``, in the units of ``x``; ``0`` triggers on the
        up-crossings of the mean. Default: the standard deviation of ``x``.

    Returns
    -------
    ndarray of float64, shape (segment_samples,)
        The random decrement signature. It starts near 0 (the ``±a`` starts average out).

    Raises
    ------
    ValueError
        Bad sizes, non-finite input, or no crossing of the trigger level.

    Examples
    --------
    >>> import numpy as np, scipy.signal
    >>> r, theta = 0.97, 2 * np.pi * 0.05          # one mode: 0.05 cycles/sample, ζ ≈ 0.1
    >>> noise = np.random.default_rng(0).standard_normal(50_000)
    >>> y = scipy.signal.lfilter([0, r * np.sin(theta)], [1, -2 * r * np.cos(theta), r * r], noise)
    >>> signature = random_decrement(y, 100)
    >>> n = np.arange(100)
    >>> bool(np.corrcoef(signature, r**n * np.sin(theta * n))[0, 1] > 0.95)
    True
    """
    values = np.asarray(x, dtype=np.float64)
    if values.ndim != 1:
        raise ValueError(f"x must be 1-D, got shape {values.shape}")
    segment_samples = _positive_int(segment_samples, "segment_samples")
    if values.size < segment_samples + 2:
        raise ValueError(
            f"x has {values.size} samples; random decrement of {segment_samples} needs at least "
            f"{segment_samples + 2}"
        )
    if not np.all(np.isfinite(values)):
        raise ValueError("x contains NaN or infinite values")
    centred = values - values.mean()
    level = float(np.std(centred)) if trigger_level is None else abs(float(trigger_level))
    if not np.isfinite(level):
        raise ValueError(f"trigger_level must be finite, got {trigger_level!r}")
    return _random_decrement(centred, segment_samples, level, circular=False)


# --------------------------------------------------------------------------------------------
# Prony


def _positive_int(value: int, name: str) -> int:
    if isinstance(value, bool) or int(value) != value or int(value) < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def _prony_roots(h: NDArray[np.float64], model_order: int) -> NDArray[np.complex128]:
    """Signal poles by backward linear prediction with rank truncation (Kumaresan–Tufts 1982).

    Backward prediction ``h[n] = −Σ_{k=1}^{L} b_k·h[n+k]`` of high order ``L ≈ 3N/4`` solved by
    the SVD pseudo-inverse truncated to ``model_order`` singular values (noise suppression); the
    polynomial ``1 + Σ b_k·z^k`` then has the signal poles ``z_m`` as roots, and the ``L − p``
    extraneous roots of the minimum-norm solution lie *outside* the unit circle. Decaying modes
    (``|z_m| < 1``) are therefore the ``model_order`` smallest roots.
    """
    n_samples = h.size
    order = max(model_order, min(n_samples - model_order, (3 * n_samples) // 4))
    rows = n_samples - order
    prediction_matrix = np.lib.stride_tricks.sliding_window_view(h[1:], order)[:rows]
    u, singular, vt = np.linalg.svd(prediction_matrix, full_matrices=False)
    rank = int(np.count_nonzero(singular[:model_order] > singular[0] * 1e-13))
    if rank == 0:
        raise ValueError("prony: the signal is zero")
    coefficients = vt[:rank].T @ ((u[:, :rank].T @ -h[:rows]) / singular[:rank])
    # np.roots wants the highest power first: b_L z^L + … + b_1 z + 1.
    roots = np.roots(np.concatenate([coefficients[::-1], [1.0]]))
    return np.asarray(roots[np.argsort(np.abs(roots), kind="stable")], dtype=np.complex128)


def _select_modes(roots: NDArray[np.complex128], n_modes: int) -> list[complex]:
    """The ``n_modes`` smallest roots, a conjugate pair counting once (its upper member)."""
    selected: list[complex] = []
    for root in roots:
        if len(selected) == n_modes:
            break
        modulus = abs(root)
        if abs(root.imag) <= _REAL_ROOT_REL * modulus:
            selected.append(complex(root.real, 0.0))
        elif root.imag > 0:
            selected.append(complex(root))
    return selected


def _mode_basis(
    poles: list[complex], n_samples: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Real regression columns: ``rⁿcos(θn), −rⁿsin(θn)`` per complex pole, ``zⁿ`` per real one.

    Columns of a growing pole (``r > 1``, a spurious or extraneous root) are divided by
    ``r^(N−1)`` so they cannot overflow; the second array holds each column's divisor.
    """
    n = np.arange(n_samples)
    columns: list[NDArray[np.float64]] = []
    divisors: list[float] = []
    with np.errstate(under="ignore", over="ignore"):
        for pole in poles:
            log_radius = float(np.log(max(abs(pole), np.finfo(np.float64).tiny)))
            log_divisor = max(0.0, log_radius * (n_samples - 1))
            decay = np.exp(log_radius * n - log_divisor)
            divisor = float(np.exp(log_divisor))  # inf is harmless: the amplitude becomes 0
            if pole.imag == 0.0:
                columns.append(decay * np.where(pole.real < 0, (-1.0) ** n, 1.0))
                divisors.append(divisor)
            else:
                angle = np.angle(pole) * n
                columns.extend([decay * np.cos(angle), -decay * np.sin(angle)])
                divisors.extend([divisor, divisor])
    return np.column_stack(columns), np.asarray(divisors)


def _decay_nepers_per_sample(pole: complex) -> float:
    return float(-np.log(max(abs(pole), np.finfo(np.float64).tiny)))


def _damping_ratio(pole: complex) -> float:
    """``ζ = σ/ω_n`` with ``σ = −ln|z|`` and ``ω_n = sqrt(σ² + θ²)``, ``θ = |arg z|``."""
    decay_rate = _decay_nepers_per_sample(pole)
    damped_rad = abs(float(np.angle(pole)))  # π for a negative real pole
    if damped_rad == 0.0:
        return 1.0 if decay_rate >= 0 else -1.0
    return float(decay_rate / np.hypot(decay_rate, damped_rad))


def prony(
    h: ArrayLike, n_modes: int, *, samples_per_rev: int | None = None
) -> tuple[DampedMode, ...]:
    """Fit ``h[n] ≈ Σ_m A_m·r_mⁿ·cos(2π·f_m·n + φ_m)`` with Prony's method.

    Prony's method models a sequence as a sum of damped complex exponentials ``c_m·z_mⁿ``: the
    poles ``z_m`` are the roots of a linear-prediction polynomial, then the amplitudes follow by
    linear least squares. Plain Prony (prediction order = model order) is badly biased by noise;
    this is the modified, least-squares form of Kumaresan & Tufts (IEEE Trans. ASSP 30(6), 1982):
    a high-order backward prediction, SVD-truncated to the model order ``p = 2·n_modes``, whose
    signal roots are separated from the extraneous ones by the unit circle. A real ``h`` has
    conjugate pole pairs; each pair is one damped sinusoid (one mode). Amplitudes and phases come
    from a real least-squares fit of the chosen modes to the whole of ``h``.

    Only decaying modes are found reliably (``|z| < 1``); a growing or undamped component is
    confused with the extraneous roots.

    Parameters
    ----------
    h : array_like, 1-D
        The sequence to fit, e.g. an impulse response; at least ``4·n_modes`` samples.
    n_modes : int
        Number of modes (damped sinusoids) to return.
    samples_per_rev : int, optional
        Samples per shaft revolution, to express the frequencies in shaft orders too.

    Returns
    -------
    tuple of DampedMode
        ``n_modes`` modes (fewer if ``h`` has fewer independent components), sorted by frequency.

    Examples
    --------
    >>> import numpy as np
    >>> n = np.arange(64)
    >>> h = 0.9**n * np.cos(2 * np.pi * 0.1 * n + 0.5)
    >>> (mode,) = prony(h, 1, samples_per_rev=1024)
    >>> round(mode.frequency_cycles_per_sample, 6), round(mode.frequency_orders, 3)
    (0.1, 102.4)
    >>> round(mode.pole_radius, 6), round(mode.amplitude, 6), round(mode.phase_rad, 6)
    (0.9, 1.0, 0.5)
    """
    values = np.asarray(h, dtype=np.float64)
    if values.ndim != 1:
        raise ValueError(f"h must be 1-D, got shape {values.shape}")
    n_modes = _positive_int(n_modes, "n_modes")
    if values.size < 4 * n_modes:
        raise ValueError(f"h has {values.size} samples; {n_modes} modes need at least {4 * n_modes}")
    if not np.all(np.isfinite(values)):
        raise ValueError("h contains NaN or infinite values")
    if samples_per_rev is not None:
        samples_per_rev = _positive_int(samples_per_rev, "samples_per_rev")

    poles = _select_modes(_prony_roots(values, 2 * n_modes), n_modes)
    basis, divisors = _mode_basis(poles, values.size)
    coefficients, *_ = np.linalg.lstsq(basis, values, rcond=None)
    coefficients = coefficients / divisors

    modes: list[DampedMode] = []
    column = 0
    for pole in poles:
        if pole.imag == 0.0:
            # A real pole z: A·zⁿ = |A|·|z|ⁿ·cos(π·[z < 0]·n + π·[A < 0]).
            weight = float(coefficients[column])
            column += 1
            frequency = 0.5 if pole.real < 0 else 0.0
            amplitude, phase = abs(weight), (np.pi if weight < 0 else 0.0)
        else:
            # a·rⁿcos(θn) − b·rⁿsin(θn) = A·rⁿcos(θn + φ) with a = A·cos φ, b = A·sin φ.
            cos_part, sin_part = coefficients[column], coefficients[column + 1]
            column += 2
            frequency = float(np.angle(pole)) / (2.0 * np.pi)
            amplitude = float(np.hypot(cos_part, sin_part))
            phase = float(np.arctan2(sin_part, cos_part))
        orders = frequency * samples_per_rev if samples_per_rev is not None else float("nan")
        modes.append(
            DampedMode(
                frequency_cycles_per_sample=frequency,
                frequency_orders=orders,
                damping_ratio=_damping_ratio(pole),
                amplitude=amplitude,
                phase_rad=phase,
                decay_nepers_per_sample=_decay_nepers_per_sample(pole),
            )
        )
    return tuple(sorted(modes, key=lambda mode: mode.frequency_cycles_per_sample))


def _pole(mode: DampedMode) -> complex:
    radius = mode.pole_radius
    if mode.frequency_cycles_per_sample == 0.0:
        return complex(radius, 0.0)
    if mode.frequency_cycles_per_sample == 0.5:
        return complex(-radius, 0.0)
    return complex(radius * np.exp(2j * np.pi * mode.frequency_cycles_per_sample))


def mode_impulse_response(modes: tuple[DampedMode, ...], n_samples: int) -> NDArray[np.float64]:
    """``Σ_m A_m·r_mⁿ·cos(2π·f_m·n + φ_m)`` for ``n = 0 … n_samples − 1``.

    Examples
    --------
    >>> mode = DampedMode(0.25, float("nan"), 0.0, 2.0, 0.0)  # undamped, 4 samples per cycle
    >>> mode_impulse_response((mode,), 4).round(12).tolist()
    [2.0, 0.0, -2.0, -0.0]
    """
    n_samples = _positive_int(n_samples, "n_samples")
    n = np.arange(n_samples)
    response = np.zeros(n_samples, dtype=np.float64)
    with np.errstate(under="ignore"):
        for mode in modes:
            radius = mode.pole_radius
            angle = 2.0 * np.pi * mode.frequency_cycles_per_sample * n + mode.phase_rad
            response += mode.amplitude * np.power(radius, n) * np.cos(angle)
    return response


def _periodised_frequency_response(
    modes: tuple[DampedMode, ...], n_samples: int
) -> NDArray[np.complex128]:
    """rfft of the fitted impulse response folded onto one revolution, in closed form.

    A mode ``A·rⁿcos(θn + φ) = (c·zⁿ + c̄·z̄ⁿ)/2`` with ``c = A·e^{iφ}``; summed over all ``n >= 0``
    and wrapped onto ``N`` samples its DFT is ``(c/(1 − z·w_k) + c̄/(1 − z̄·w_k))/2`` with
    ``w_k = e^{−2πik/N}`` (exact for ``|z| < 1``, no truncation of the tail).
    """
    w = np.exp(-2j * np.pi * np.arange(n_samples // 2 + 1) / n_samples)
    response = np.zeros(w.size, dtype=np.complex128)
    for mode in modes:
        pole = _pole(mode)
        weight = mode.amplitude * np.exp(1j * mode.phase_rad)
        response += 0.5 * (weight / (1.0 - pole * w) + np.conj(weight) / (1.0 - np.conj(pole) * w))
    return response


# --------------------------------------------------------------------------------------------
# W''


def _mesh_comb_residual(average: NDArray[np.float64], teeth: int) -> NDArray[np.float64]:
    """The average with the mean and every mesh harmonic (orders ``n·teeth``) set to zero."""
    spectrum = np.fft.rfft(average)
    spectrum[::teeth] = 0.0
    return np.fft.irfft(spectrum, average.size)


def estimate_wdd(
    average: ArrayLike,
    teeth: int,
    *,
    n_modes: int = 2,
    segment_samples: int | None = None,
    regularisation: float = 1e-2,
) -> WddEstimate:
    """Estimate W'' over one revolution by deconvolving the transfer path (seed §3.3, eq. 25).

    1. Residual: the DFT bins of the mean and of every mesh harmonic (shaft orders ``n·teeth``)
       of the average are set to zero (an exact comb filter for one revolution).
    2. Transfer path: :func:`random_decrement` of the residual, circularly (the average is
       periodic, so a segment may run into the next revolution), triggered at up-crossings of
       ± its standard deviation, over ``segment_samples``.
    3. :func:`prony` fit of that estimate with ``n_modes`` modes. Modes that do not decay
       (``r >= 1``) are not a transfer path and are left out of the frequency response.
    4. The fitted frequency response ``H`` (the modes' impulse response folded onto one
       revolution, in closed form) is scaled to unit peak gain, and the residual's spectrum
       ``R`` is divided by it with Tikhonov (Wiener-type) regularisation::

           W''(k) = R(k)·H*(k) / (|H(k)|² + λ),   λ = regularisation,  max|H| = 1.

       Where ``|H|² >> λ`` this is ``R/H``; where the path transmits little it tends to 0
       instead of amplifying noise: the gain ``|H|/(|H|² + λ)`` never exceeds ``1/(2·√λ)``
       (5 for the default ``λ = 1e-2``, i.e. the band more than 20 dB below the resonance peak
       is attenuated). W'' is therefore band-limited to where the path transmits, and its scale
       is that of an excitation seen through a unit-peak-gain path.

    Accuracy (measured on synthetic averages, see ``tests/dsp/test_wdd.py``): the peak of
    ``|W''|`` falls on the spall's entry or exit edge, within a sample when the residual is
    clean. The mode's damping is biased when the spall is wide compared with the mode's period:
    random decrement segments that start inside the spall (between its two edges) are not free
    decays. With a 7-sample spall and a mode at 0.2 cycle/sample, ζ = 0.10 is estimated as
    0.07 and the frequency 3 % high; the W'' estimate is hardly affected (its correlation with
    the best regularised W'' computable from the *true* path stays 0.97).

    Parameters
    ----------
    average : array_like, 1-D
        Synchronous average of exactly one revolution of the shaft carrying ``teeth`` teeth.
    teeth : int
        Teeth of that gear (mesh order); ``2·teeth < len(average)``.
    n_modes : int
        Modes of the transfer path fitted by Prony.
    segment_samples : int, optional
        Random decrement segment length; default one mesh period ``N // teeth``, at least
        ``8·n_modes``, at most ``N // 2``.
    regularisation : float
        ``λ > 0`` above, relative to the unit peak of ``|H|²``.

    Returns
    -------
    WddEstimate

    Raises
    ------
    ValueError
        Bad parameters, a non-finite average, a residual without crossings, or no decaying mode.

    Examples
    --------
    >>> import numpy as np
    >>> n_samples, teeth = 1280, 20
    >>> n = np.arange(n_samples)
    >>> mesh = np.cos(2 * np.pi * teeth * n / n_samples)
    >>> wdd_true = np.zeros(n_samples)
    >>> wdd_true[[500, 501, 507, 508]] = [1.0, -1.0, -1.0, 1.0]  # spall of 7 samples at 500
    >>> r, theta = 0.88, 2 * np.pi * 0.2
    >>> path = np.fft.irfft(np.fft.rfft(wdd_true) * np.fft.rfft(r**n * np.sin(theta * n)), n_samples)
    >>> estimate = estimate_wdd(mesh + 0.3 * path, teeth, n_modes=1)
    >>> int(np.argmax(np.abs(estimate.wdd)))
    500
    >>> round(estimate.modes[0].frequency_cycles_per_sample, 2)
    0.21
    """
    values = np.asarray(average, dtype=np.float64)
    if values.ndim != 1:
        raise ValueError(f"average must be 1-D (one revolution), got shape {values.shape}")
    if not np.all(np.isfinite(values)):
        raise ValueError("average contains NaN or infinite values")
    n_samples = values.size
    teeth = _positive_int(teeth, "teeth")
    if 2 * teeth >= n_samples:
        raise ValueError(f"{n_samples} samples per revolution do not resolve mesh order {teeth}")
    n_modes = _positive_int(n_modes, "n_modes")
    if not (np.isfinite(regularisation) and regularisation > 0.0):
        raise ValueError(f"regularisation must be finite and > 0, got {regularisation!r}")
    if segment_samples is None:
        segment_samples = min(max(n_samples // teeth, 8 * n_modes), n_samples // 2)
    segment_samples = _positive_int(segment_samples, "segment_samples")
    if segment_samples < 4 * n_modes or segment_samples >= n_samples:
        raise ValueError(
            f"segment_samples must lie in [{4 * n_modes}, {n_samples}) for {n_modes} modes, "
            f"got {segment_samples}"
        )

    residual = _mesh_comb_residual(values, teeth)
    level = float(np.std(residual))
    if level <= _EMPTY_RESIDUAL_REL * float(np.max(np.abs(values))):
        raise ValueError("the average has no content besides the mesh harmonics")
    impulse_response = _random_decrement(residual, segment_samples, level, circular=True)
    modes = prony(impulse_response, n_modes, samples_per_rev=n_samples)

    decaying = tuple(mode for mode in modes if mode.pole_radius < 1.0)
    if not decaying:
        raise ValueError("no decaying mode in the random decrement signature: no transfer path")
    response = _periodised_frequency_response(decaying, n_samples)
    peak_gain = float(np.max(np.abs(response)))
    if not np.isfinite(peak_gain) or peak_gain == 0.0:
        raise ValueError("the fitted transfer path has no finite, non-zero gain")
    response /= peak_gain
    spectrum = np.fft.rfft(residual)
    wdd_spectrum = spectrum * np.conj(response) / (np.abs(response) ** 2 + regularisation)
    wdd = np.fft.irfft(wdd_spectrum, n_samples)
    return WddEstimate(wdd=wdd, impulse_response=impulse_response, modes=modes, residual=residual)
