"""Real, power and complex cepstra, 1-D or batched along ``axis``.

Definitions follow El Badaoui et al., MSSP 2001 (the seed paper), §3:

- real cepstrum (seed eq. 15): ``c = IDFT(ln|DFT(x)|)``;
- power cepstrum (seed eq. 13, Bogert-Healy-Tukey): ``IDFT(ln|DFT(x)|²)²``, which is exactly
  ``4·c²`` with ``c`` the real cepstrum. It is non-negative, so the sign property the moving
  cepstrum integral relies on ("the power cepstrum of W'' is strictly negative", eq. 19–20) is
  a property of the *real* cepstrum: the seed uses "power cepstrum" loosely for eq. 15;
- complex cepstrum (seed eq. 14): ``IDFT(ln|X| + i·arg X)`` with the phase unwrapped and its
  linear part removed, reported as ``ndelay`` exactly like MATLAB ``cceps``/``icceps``.

Zero-magnitude bins: ``ln 0 = −inf`` would poison every quefrency. Every magnitude is floored
at ``floor_rel × max|X|`` (the maximum over the same transform, i.e. per batch row) and never
below ``√tiny ≈ 1.5e-154`` (``tiny`` the smallest normal double, as the floor is applied to
``|X|²``), so an all-zero input gives a finite cepstrum (``c[0] ≈ −354``, the rest 0). The default floor, ``1e-10`` (−200 dB), lies far below any measured
spectrum yet far above FFT rounding noise (~1e-15 relative), so an exact spectral zero is
replaced by a deterministic value and not by rounding noise. Alternatively, move zeros off the
unit circle with :func:`exponential_weighting` (``x[n]·rⁿ``, ``r < 1``), as the seed's eq. 18
analysis needs for the second derivative of a rectangular window.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

DEFAULT_FLOOR_REL = 1e-10
"""Default magnitude floor, relative to the largest magnitude of the same spectrum (−200 dB)."""

_TINY = float(np.finfo(np.float64).tiny)


def _transform_length(n_samples: int, n_fft: int | None) -> int:
    length = n_samples if n_fft is None else int(n_fft)
    if length < 1:
        raise ValueError(f"n_fft must be positive, got {length}")
    if n_samples < 1:
        raise ValueError("the input is empty along the transform axis")
    return length


def floored_log_magnitude(
    spectrum: NDArray[np.complexfloating], floor_rel: float
) -> NDArray[np.float64]:
    """``ln max(|X|, floor_rel·max|X|, tiny)`` along the last axis.

    Parameters
    ----------
    spectrum : ndarray of complex
        DFT values; the floor is taken relative to the maximum along the last axis.
    floor_rel : float
        Relative magnitude floor, ``0 <= floor_rel < 1``.

    Returns
    -------
    ndarray of float64
        Natural log of the floored magnitude, always finite.

    Examples
    --------
    >>> import numpy as np
    >>> floored_log_magnitude(np.array([1.0 + 0j, 0.0]), 1e-10).round(3)
    array([  0.   , -23.026])
    """
    if not 0.0 <= floor_rel < 1.0:
        raise ValueError(f"floor_rel must be in [0, 1), got {floor_rel}")
    # work on |X|² to avoid one sqrt per bin; ln|X| = ½·ln|X|²
    power = spectrum.real**2 + spectrum.imag**2
    floor = np.maximum((floor_rel**2) * power.max(axis=-1, keepdims=True), _TINY)
    return 0.5 * np.log(np.maximum(power, floor))


def real_cepstrum(
    x: ArrayLike,
    *,
    axis: int = -1,
    n_fft: int | None = None,
    floor_rel: float = DEFAULT_FLOOR_REL,
) -> NDArray[np.float64]:
    """Real cepstrum ``c[n] = IDFT(ln|DFT(x)|)[n]`` (seed eq. 15) along ``axis``.

    Parameters
    ----------
    x : array_like of float
        Signal(s); transformed along ``axis``.
    axis : int
        Axis of the samples.
    n_fft : int, optional
        DFT length (zero-padded or truncated like :func:`numpy.fft.fft`); default the length.
    floor_rel : float
        Magnitude floor relative to the spectrum's maximum (see the module docstring).

    Returns
    -------
    ndarray of float64
        Same shape as ``x`` except ``n_fft`` samples along ``axis``. Never NaN or inf for
        finite input. ``Σₙ c[n] = ln|X[0]|`` and ``c[0] = mean_k ln|X[k]|``.

    Examples
    --------
    >>> import numpy as np
    >>> c = real_cepstrum(np.r_[1.0, 0.5, np.zeros(62)])   # echo g = 0.5, τ = 1 (eq. 17)
    >>> bool(np.isclose(c[1], 0.5 / 2)) and bool(np.isclose(c[2], -(0.5**2) / 4))
    True
    """
    samples = np.moveaxis(np.asarray(x), axis, -1)
    length = _transform_length(samples.shape[-1], n_fft)
    if np.iscomplexobj(samples):
        log_magnitude = floored_log_magnitude(np.fft.fft(samples, n=length, axis=-1), floor_rel)
        ceps = np.fft.ifft(log_magnitude, axis=-1).real
    else:
        spectrum = np.fft.rfft(samples.astype(np.float64, copy=False), n=length, axis=-1)
        ceps = np.fft.irfft(floored_log_magnitude(spectrum, floor_rel), n=length, axis=-1)
    return np.moveaxis(ceps, -1, axis)


def power_cepstrum(
    x: ArrayLike,
    *,
    axis: int = -1,
    n_fft: int | None = None,
    floor_rel: float = DEFAULT_FLOOR_REL,
) -> NDArray[np.float64]:
    """Power cepstrum ``|IDFT(ln|DFT(x)|²)|²`` (seed eq. 13), equal to ``4·real_cepstrum(x)²``.

    The "power spectrum of the logarithm of the power spectrum" (Bogert, Healy & Tukey 1963).
    It is non-negative; the sign information the MCI uses lives in :func:`real_cepstrum`.

    Parameters
    ----------
    x : array_like of float
        Signal(s); transformed along ``axis``.
    axis : int
        Axis of the samples.
    n_fft : int, optional
        DFT length; default the length along ``axis``.
    floor_rel : float
        Magnitude floor relative to the spectrum's maximum.

    Returns
    -------
    ndarray of float64
        Same shape as :func:`real_cepstrum` would return.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.r_[1.0, 0.5, np.zeros(6)]
    >>> bool(np.allclose(power_cepstrum(x), 4 * real_cepstrum(x) ** 2))
    True
    """
    # ln|X|² = 2·ln|X| and the IDFT is linear, so IDFT(ln|X|²) = 2c exactly
    return 4.0 * real_cepstrum(x, axis=axis, n_fft=n_fft, floor_rel=floor_rel) ** 2


def _linear_phase_ramp(length: int) -> NDArray[np.float64]:
    # ω_k = 2πk/n; for even n this is MATLAB rcunwrap's π·k/(n/2)
    return 2.0 * np.pi * np.arange(length) / length


def _linear_phase_delay(unwrapped_phase: NDArray[np.float64]) -> NDArray[np.int64]:
    """Integer ``ndelay`` with ``phase ≈ ndelay·ω + (odd residual)``, from the bins around π."""
    length = unwrapped_phase.shape[-1]
    if length % 2 == 0:
        # the residual phase of a real signal is odd about π, so it vanishes at the π bin
        at_pi = unwrapped_phase[..., length // 2]
    else:
        # no π bin: the residual cancels between the two bins symmetric about π
        below, above = (length - 1) // 2, (length + 1) // 2 % length
        at_pi = 0.5 * (unwrapped_phase[..., below] + unwrapped_phase[..., above])
    return np.rint(at_pi / np.pi).astype(np.int64)


def complex_cepstrum(
    x: ArrayLike,
    *,
    axis: int = -1,
    n_fft: int | None = None,
    floor_rel: float = DEFAULT_FLOOR_REL,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Complex cepstrum (seed eq. 14) with unwrapped phase, like MATLAB ``cceps``.

    The phase of the DFT is unwrapped along the frequency axis; its linear part is removed by
    rounding the unwrapped phase at ω = π to a multiple of π, ``ndelay``, and subtracting
    ``ndelay·ω_k`` (``ω_k = 2πk/n``). A signal delayed by ``d`` samples (circularly) reports
    ``ndelay = −d``; :func:`inverse_complex_cepstrum` puts the delay back. For even ``n`` this
    is exactly MATLAB's ``cceps``. For odd ``n`` (no bin at π) the phase at π is the mean of the
    two bins around it and the ramp is still ``ndelay·ω_k``, which keeps the log spectrum
    Hermitian and the transform exactly invertible (MATLAB's odd-``n`` ramp,
    ``2πk·ndelay/(n + 1)``, does not).

    As in MATLAB, a signal whose DFT at 0 is negative (``Σx < 0``) starts its phase at π; the
    cepstrum (real part) then cannot hold that sign and the inverse is not exact. Negate such
    an input first and keep the sign aside.

    Parameters
    ----------
    x : array_like of float
        Real signal(s); transformed along ``axis``.
    axis : int
        Axis of the samples.
    n_fft : int, optional
        DFT length; default the length along ``axis``.
    floor_rel : float
        Magnitude floor relative to the spectrum's maximum (the phase of a zero bin is 0).

    Returns
    -------
    ceps : ndarray of float64
        Complex cepstrum (real-valued for real input), ``n_fft`` samples along ``axis``.
    ndelay : ndarray of int64
        Linear-phase delay removed, shape of ``x`` without ``axis`` (0-d for 1-D input).

    Examples
    --------
    >>> import numpy as np
    >>> x = np.r_[1.0, 0.5, np.zeros(62)]          # minimum phase: x̂[1] = g, x̂[2] = −g²/2
    >>> ceps, ndelay = complex_cepstrum(x)
    >>> bool(np.isclose(ceps[1], 0.5)) and bool(np.isclose(ceps[2], -0.125)), int(ndelay)
    (True, 0)
    """
    samples = np.moveaxis(np.asarray(x, dtype=np.float64), axis, -1)
    length = _transform_length(samples.shape[-1], n_fft)
    spectrum = np.fft.fft(samples, n=length, axis=-1)
    phase = np.unwrap(np.angle(spectrum), axis=-1)
    ndelay = _linear_phase_delay(phase)
    phase = phase - ndelay[..., np.newaxis] * _linear_phase_ramp(length)
    log_spectrum = floored_log_magnitude(spectrum, floor_rel) + 1j * phase
    ceps = np.fft.ifft(log_spectrum, axis=-1).real
    return np.moveaxis(ceps, -1, axis), np.asarray(ndelay)


def inverse_complex_cepstrum(
    ceps: ArrayLike,
    ndelay: ArrayLike,
    *,
    axis: int = -1,
) -> NDArray[np.float64]:
    """Inverse of :func:`complex_cepstrum`, like MATLAB ``icceps``.

    Parameters
    ----------
    ceps : array_like of float
        Complex cepstrum (or cepstra) along ``axis``.
    ndelay : array_like of int
        Delay returned by :func:`complex_cepstrum`; broadcast against ``ceps`` without ``axis``.
    axis : int
        Axis of the quefrencies.

    Returns
    -------
    ndarray of float64
        The signal(s), same shape as ``ceps``.

    Examples
    --------
    >>> import numpy as np
    >>> x = np.array([0.0, 0.0, 1.0, -0.4, 0.1, 0.0])
    >>> ceps, ndelay = complex_cepstrum(x)
    >>> bool(np.allclose(inverse_complex_cepstrum(ceps, ndelay), x))
    True
    """
    quefrencies = np.moveaxis(np.asarray(ceps, dtype=np.float64), axis, -1)
    length = quefrencies.shape[-1]
    log_spectrum = np.fft.fft(quefrencies, axis=-1)
    delays = np.asarray(ndelay, dtype=np.float64)[..., np.newaxis]
    phase = log_spectrum.imag + delays * _linear_phase_ramp(length)
    signal = np.fft.ifft(np.exp(log_spectrum.real + 1j * phase), axis=-1).real
    return np.moveaxis(signal, -1, axis)


def exponential_weighting(x: ArrayLike, r: float, *, axis: int = -1) -> NDArray[np.float64]:
    """Return ``x[n]·rⁿ`` along ``axis``.

    Multiplying by ``rⁿ`` maps the z-transform zeros ``z₀`` to ``r·z₀``: with ``0 < r < 1``
    zeros on the unit circle (exact spectral nulls) move inside it, so ``ln|X|`` stays finite.
    An echo of gain ``g`` becomes an echo of gain ``g·r^τ``.

    Parameters
    ----------
    x : array_like of float
        Signal(s).
    r : float
        Weighting base, ``r > 0``.
    axis : int
        Axis of the samples.

    Returns
    -------
    ndarray of float64
        Weighted signal(s), same shape as ``x``.

    Examples
    --------
    >>> exponential_weighting([1.0, 1.0, 1.0], 0.5)
    array([1.  , 0.5 , 0.25])
    """
    if not r > 0:
        raise ValueError(f"r must be positive, got {r}")
    samples = np.moveaxis(np.asarray(x, dtype=np.float64), axis, -1)
    weighted = samples * float(r) ** np.arange(samples.shape[-1])
    return np.moveaxis(weighted, -1, axis)
