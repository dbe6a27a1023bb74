"""Classic whole-revolution gear metrics, 1-D or batched along ``axis``.

Definitions follow Lebold, McClintic, Campbell, Byington & Maynard (2000), "Review of vibration
analysis methods for gearbox diagnostics and prognostics", Proc. 54th MFPT meeting, pp. 623–634,
and, for NA4 and NB4, Zakrajsek, Townsend & Decker (1993), NASA TM-105950, and Zakrajsek,
Handschuh & Decker (1994), NASA TM-106467 (Decker's NA4 with the averaged-variance denominator).

Each metric is defined on a specific signal and takes that signal as its argument; the caller
(the pipeline) computes them with :mod:`dsp.tsa`:

- ``average``: the time-synchronous average (TSA) of one revolution of the shaft, exactly one
  revolution long, so that DFT bin ``k`` is shaft order ``k`` and the mesh harmonics of a gear
  with ``teeth`` teeth are bins ``n·teeth``;
- ``regular``: the mesh harmonics (and their first-order sidebands) of the TSA;
- ``residual``: the TSA with the shaft orders and mesh harmonics removed (NA4);
- ``difference``: the TSA with the regular signal removed (FM4, M6A, M8A, energy ratio).

Conventions
-----------
- Moments are population moments (``1/N``, ``ddof=0``), as in the sources' sums.
- Kurtosis is the normalised fourth moment ``m4/m2²``: 3 for a Gaussian signal, 1.5 for a sine,
  1 for a square wave. It is *not* the excess kurtosis.
- Undefined ratios: when a denominator is zero (a constant or all-zero signal, no mesh harmonic
  content, a zero baseline) the metric is ``0.0``; it is never NaN nor infinite. "Zero" allows
  for rounding: a variance below ``(64·eps·max|x|)²`` counts as zero, so a constant signal whose
  computed deviations are rounding noise is treated as constant.
- Inputs must be finite (``ValueError`` otherwise): a NaN record is rejected upstream, and a
  metric that silently propagated NaN would hide it.
- A 1-D input gives a Python ``float``; a batched input gives an array of the leading shape.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatOrArray = float | NDArray[np.float64]

_EPS = float(np.finfo(np.float64).eps)
_ZERO_VARIANCE_REL = 64.0 * _EPS
"""A standard deviation below this fraction of the signal's peak is rounding noise (= zero)."""
_ZERO_HARMONICS_REL = 1e-12
"""A mesh-harmonic amplitude sum below this fraction of the signal's peak is FFT rounding noise."""

__all__ = [
    "crest_factor",
    "energy_ratio",
    "envelope_variance",
    "fm0",
    "fm4",
    "gear_metrics",
    "kurtosis",
    "m6a",
    "m8a",
    "mesh_band_envelope",
    "na4",
    "nb4",
    "peak",
    "rms",
]


# --------------------------------------------------------------------------------------------
# helpers


def _as_last_axis(x: ArrayLike, axis: int, name: str = "x") -> NDArray[np.float64]:
    """Float64 view with ``axis`` moved last; refuse scalars, empty and non-finite input."""
    values = np.asarray(x, dtype=np.float64)
    if values.ndim == 0:
        raise ValueError(f"{name} must be an array with at least one axis, got a scalar")
    values = np.moveaxis(values, axis, -1)
    if values.shape[-1] == 0:
        raise ValueError(f"{name} is empty along the metric axis")
    if not np.all(np.isfinite(values)):
        raise ValueError(f"{name} contains NaN or infinite values")
    return values


def _out(values: NDArray[np.float64]) -> FloatOrArray:
    """A Python float for a 0-d result, else the array itself."""
    return float(values) if values.ndim == 0 else values


def _ratio_or_zero(
    numerator: NDArray[np.float64], denominator: NDArray[np.float64], is_zero: NDArray[np.bool_]
) -> NDArray[np.float64]:
    """``numerator / denominator`` with ``0.0`` where ``is_zero`` (no division is attempted)."""
    numerator, denominator, is_zero = np.broadcast_arrays(numerator, denominator, is_zero)
    result = np.zeros(numerator.shape, dtype=np.float64)
    np.divide(numerator, denominator, out=result, where=~is_zero)
    return result


def _peak_abs(values: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.asarray(np.max(np.abs(values), axis=-1), dtype=np.float64)


def _scaled_by_peak(values: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``values / max|values|`` and that peak (1 for an all-zero row): no overflow in powers."""
    peak_value = _peak_abs(values)
    peak_value = np.where(peak_value == 0.0, 1.0, peak_value)
    return values / peak_value[..., np.newaxis], peak_value


def _centred(values: NDArray[np.float64]) -> NDArray[np.float64]:
    return values - np.mean(values, axis=-1, keepdims=True)


def _scaled_deviations(values: NDArray[np.float64]) -> tuple[
    NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]
]:
    """Centred deviations scaled by the row's peak, that peak, and where the variance is zero.

    Deviations of a constant row are rounding noise: they are set to exactly 0.
    """
    scaled, peak_value = _scaled_by_peak(values)
    deviations = _centred(scaled)
    is_zero = np.mean(deviations * deviations, axis=-1) <= _ZERO_VARIANCE_REL**2
    deviations = np.where(is_zero[..., np.newaxis], 0.0, deviations)
    return deviations, peak_value, is_zero


def _standardised_moment(values: NDArray[np.float64], order: int) -> NDArray[np.float64]:
    """``m_order / m2^(order/2)`` along the last axis; ``0.0`` for a constant signal.

    The ratio is scale-free, so it is computed on the peak-scaled deviations (no overflow).
    """
    deviations, _, is_zero = _scaled_deviations(values)
    variance = np.where(is_zero, 1.0, np.mean(deviations * deviations, axis=-1))
    moment = np.mean(deviations**order, axis=-1) / variance ** (order // 2)
    return np.asarray(np.where(is_zero, 0.0, moment), dtype=np.float64)


def _baseline_normalised_fourth_moment(
    values: NDArray[np.float64], baseline_variance: ArrayLike | None
) -> NDArray[np.float64]:
    """``m4(values) / baseline_variance²``; the record's own variance when the baseline is None."""
    if baseline_variance is None:
        return _standardised_moment(values, 4)
    baseline = np.asarray(baseline_variance, dtype=np.float64)
    if not np.all(np.isfinite(baseline)) or np.any(baseline < 0.0):
        raise ValueError("baseline_variance must be finite and non-negative")
    deviations, peak_value, _ = _scaled_deviations(values)
    # m4/b² = mean(dev_scaled⁴)·(peak/√b)⁴; a baseline at the rounding level of this record's
    # scale is treated as zero, which also bounds peak/√b by 1/(64·eps).
    peak_to_baseline_std = np.zeros(np.broadcast_shapes(peak_value.shape, baseline.shape))
    baseline_std = np.sqrt(baseline)
    baseline_is_zero = baseline_std <= _ZERO_VARIANCE_REL * peak_value
    np.divide(peak_value, baseline_std, out=peak_to_baseline_std, where=~baseline_is_zero)
    moment = np.mean(deviations**4, axis=-1) * (peak_to_baseline_std * peak_to_baseline_std) ** 2
    return np.asarray(np.where(baseline_is_zero, 0.0, moment), dtype=np.float64)


def _rms(values: NDArray[np.float64]) -> NDArray[np.float64]:
    scaled, peak_value = _scaled_by_peak(values)
    return np.asarray(peak_value * np.sqrt(np.mean(scaled * scaled, axis=-1)), dtype=np.float64)


def _check_teeth(teeth: int, n_samples: int, *, strict_below_nyquist: bool) -> int:
    if isinstance(teeth, bool) or int(teeth) != teeth or int(teeth) < 1:
        raise ValueError(f"teeth must be a positive integer, got {teeth!r}")
    teeth = int(teeth)
    limit_ok = 2 * teeth < n_samples if strict_below_nyquist else 2 * teeth <= n_samples
    if not limit_ok:
        raise ValueError(
            f"the mesh order {teeth} is not resolved by {n_samples} samples per revolution "
            f"(needs more than {2 * teeth})"
        )
    return teeth


# --------------------------------------------------------------------------------------------
# statistics of one signal


def rms(x: ArrayLike, *, axis: int = -1) -> FloatOrArray:
    """Root mean square, ``RMS = sqrt((1/N)·Σ x²)`` (Lebold et al. 2000), mean not removed.

    Parameters
    ----------
    x : array_like
        Signal, batched over the leading axes.
    axis : int
        Axis along which the samples lie.

    Returns
    -------
    float or ndarray
        RMS, in the units of ``x``.

    Examples
    --------
    >>> rms([1.0, -1.0, 1.0, -1.0])
    1.0
    """
    return _out(_rms(_as_last_axis(x, axis)))


def peak(x: ArrayLike, *, axis: int = -1) -> FloatOrArray:
    """Zero-to-peak value ``max|x|`` (Lebold et al. 2000: ``x_0-pk``).

    Examples
    --------
    >>> peak([0.5, -2.0, 1.0])
    2.0
    """
    values = _as_last_axis(x, axis)
    return _out(_peak_abs(values))


def crest_factor(x: ArrayLike, *, axis: int = -1) -> FloatOrArray:
    """Crest factor ``CF = x_0-pk / RMS = max|x| / sqrt((1/N)·Σ x²)`` (Lebold et al. 2000).

    ``√2`` for a sine, 1 for a square wave, ``√N`` for a single spike in ``N`` samples; ``0.0``
    for an all-zero signal.

    Examples
    --------
    >>> crest_factor([0.0, 0.0, 0.0, 2.0])
    2.0
    """
    values = _as_last_axis(x, axis)
    peak_value = _peak_abs(values)
    return _out(_ratio_or_zero(peak_value, _rms(values), peak_value == 0.0))


def kurtosis(x: ArrayLike, *, axis: int = -1) -> FloatOrArray:
    """Normalised fourth moment ``K = N·Σ(x−x̄)⁴ / (Σ(x−x̄)²)²`` (Lebold et al. 2000).

    Equal to ``scipy.stats.kurtosis(x, fisher=False)``: 3 for Gaussian noise, 1.5 for a sine,
    1 for a square wave. Not the excess kurtosis. ``0.0`` for a constant signal.

    Examples
    --------
    >>> kurtosis([1.0, -1.0, 1.0, -1.0])
    1.0
    >>> round(kurtosis([0.0, 0.0, 0.0, 1.0]), 6)  # (N² − 3N + 3)/(N − 1) for one spike, N = 4
    2.333333
    """
    return _out(_standardised_moment(_as_last_axis(x, axis), 4))


# --------------------------------------------------------------------------------------------
# gear metrics


def fm0(average: ArrayLike, teeth: int, *, axis: int = -1) -> FloatOrArray:
    """Zero-order figure of merit ``FM0 = PPx / Σ_{n=1}^{H} P_n`` (Lebold et al. 2000; Stewart 1977).

    ``PPx = max(x) − min(x)`` is the peak-to-peak value of the TSA and ``P_n`` the amplitude of
    the ``n``-th mesh harmonic, shaft order ``n·teeth``, over all ``H`` harmonics up to the
    Nyquist order ``N/2`` (the sources sum "the meshing frequency and its harmonics"; the mean,
    ``n = 0``, is not a mesh harmonic and is left out). The amplitude is that of the sinusoid,
    ``P_n = 2|X[n·teeth]|/N`` (``|X|/N`` at the Nyquist bin), so a pure mesh sine gives FM0 = 2.
    ``0.0`` when the TSA has no mesh-harmonic content.

    Parameters
    ----------
    average : array_like
        TSA of exactly one revolution (bin ``k`` = shaft order ``k``), batched over leading axes.
    teeth : int
        Teeth of the gear on the averaged shaft; needs ``N >= 2·teeth`` samples.
    axis : int
        Axis of the samples.

    Examples
    --------
    >>> import numpy as np
    >>> n = np.arange(64)
    >>> round(fm0(np.cos(2 * np.pi * 4 * n / 64), teeth=4), 12)  # PP = 2, one harmonic of 1
    2.0
    """
    values = _as_last_axis(average, axis, "average")
    n_samples = values.shape[-1]
    teeth = _check_teeth(teeth, n_samples, strict_below_nyquist=False)
    spectrum = np.fft.rfft(values, axis=-1)
    harmonic_bins = np.arange(teeth, n_samples // 2 + 1, teeth)
    amplitudes = 2.0 * np.abs(spectrum[..., harmonic_bins]) / n_samples
    if n_samples % 2 == 0 and harmonic_bins[-1] == n_samples // 2:
        amplitudes[..., -1] /= 2.0  # the Nyquist bin holds the whole cosine, not half of it
    harmonic_sum = np.sum(amplitudes, axis=-1)
    peak_to_peak = np.max(values, axis=-1) - np.min(values, axis=-1)
    is_zero = harmonic_sum <= _ZERO_HARMONICS_REL * _peak_abs(values)
    return _out(_ratio_or_zero(peak_to_peak, harmonic_sum, is_zero))


def fm4(difference: ArrayLike, *, axis: int = -1) -> FloatOrArray:
    """``FM4 = N·Σ(d−d̄)⁴ / (Σ(d−d̄)²)²``: kurtosis of the difference signal (Lebold et al. 2000).

    ``0.0`` for a constant difference signal.

    Examples
    --------
    >>> fm4([1.0, -1.0, 1.0, -1.0])
    1.0
    """
    return _out(_standardised_moment(_as_last_axis(difference, axis, "difference"), 4))


def na4(
    residual: ArrayLike, baseline_variance: ArrayLike | None = None, *, axis: int = -1
) -> FloatOrArray:
    """NA4 of the residual signal (Zakrajsek et al. 1993; Decker's form, Lebold et al. 2000).

    ``NA4 = N·Σ_i(r_i − r̄)⁴ / { (1/M)·Σ_{j=1}^{M} Σ_i (r_ij − r̄_j)² }²``
    ``    = m4(r) / σ̄²``,

    where ``m4(r) = (1/N)·Σ(r_i − r̄)⁴`` is the current record's fourth central moment and
    ``σ̄² = (1/M)·Σ_j var(r_j)`` is the *baseline variance*: the mean of the population
    variances of the residuals of the ``M`` records of the run so far (the current one included).
    The caller keeps that running mean and passes it explicitly; nothing is remembered here.

    With ``baseline_variance=None`` the current record's own variance is used, so NA4 then
    equals the kurtosis of the residual (M = 1). A zero baseline gives ``0.0``.

    Parameters
    ----------
    residual : array_like
        Residual signal, batched over leading axes.
    baseline_variance : float or array_like, optional
        Mean residual variance of the run so far, in (units of the residual)²; broadcast
        against the leading shape. Must be finite and ``>= 0``.
    axis : int
        Axis of the samples.

    Examples
    --------
    >>> r = [1.0, -1.0, 1.0, -1.0]
    >>> na4(r)  # own variance: the kurtosis
    1.0
    >>> round(na4(r, baseline_variance=0.5), 12)  # m4 = 1, baseline² = 0.25
    4.0
    """
    values = _as_last_axis(residual, axis, "residual")
    return _out(_baseline_normalised_fourth_moment(values, baseline_variance))


def _mesh_band_bins(n_samples: int, teeth: int, band_orders: float | None) -> NDArray[np.intp]:
    """Positive-frequency bins ``k`` with ``|k − teeth| <= band_orders`` strictly below Nyquist."""
    teeth = _check_teeth(teeth, n_samples, strict_below_nyquist=True)
    half_width = (teeth - 1) // 2 if band_orders is None else band_orders
    if not np.isfinite(half_width) or half_width < 0:
        raise ValueError(f"band_orders must be finite and >= 0, got {band_orders!r}")
    lowest = max(1, int(np.ceil(teeth - half_width)))
    highest = min((n_samples - 1) // 2, int(np.floor(teeth + half_width)))
    return np.arange(lowest, highest + 1)


def mesh_band_envelope(
    average: ArrayLike, teeth: int, *, band_orders: float | None = None, axis: int = -1
) -> NDArray[np.float64]:
    """Hilbert envelope of the TSA band-passed around the mesh order, as used by NB4.

    The band keeps shaft orders ``k`` with ``|k − teeth| <= band_orders`` (default
    ``(teeth − 1) // 2``: every sideband closer to the mesh order than to its neighbours, so
    the band never reaches the shaft orders or the second mesh harmonic), clipped to
    ``1 <= k < N/2``. The filter is an ideal (brick-wall) filter in the order domain, exact for a
    periodic TSA, and the analytic signal is formed in the same step: ``z = IDFT(2·X·1_band)``,
    envelope ``|z|``. This is identical to ``abs(scipy.signal.hilbert(bandpassed))``.

    Returns
    -------
    ndarray of float64
        Envelope, same shape as ``average`` with the sample axis moved back to ``axis``.

    Examples
    --------
    >>> import numpy as np
    >>> n = np.arange(128)
    >>> x = (1 + 0.5 * np.cos(2 * np.pi * n / 128)) * np.cos(2 * np.pi * 8 * n / 128)
    >>> env = mesh_band_envelope(x, teeth=8)
    >>> bool(np.allclose(env, 1 + 0.5 * np.cos(2 * np.pi * n / 128)))
    True
    """
    values = _as_last_axis(average, axis, "average")
    n_samples = values.shape[-1]
    bins = _mesh_band_bins(n_samples, teeth, band_orders)
    spectrum = np.fft.fft(values, axis=-1)
    analytic_spectrum = np.zeros_like(spectrum)
    analytic_spectrum[..., bins] = 2.0 * spectrum[..., bins]
    envelope = np.abs(np.fft.ifft(analytic_spectrum, axis=-1))
    return np.moveaxis(envelope, -1, axis)


def envelope_variance(
    average: ArrayLike, teeth: int, *, band_orders: float | None = None, axis: int = -1
) -> FloatOrArray:
    """Population variance of the mesh-band envelope: one record's share of the NB4 baseline.

    The caller averages this over the records of the run so far and passes the mean back to
    :func:`nb4` as ``baseline_variance``. See :func:`mesh_band_envelope` for the band.

    Examples
    --------
    >>> import numpy as np
    >>> n = np.arange(128)
    >>> x = (1 + 0.5 * np.cos(2 * np.pi * n / 128)) * np.cos(2 * np.pi * 8 * n / 128)
    >>> round(envelope_variance(x, teeth=8), 12)  # variance of 0.5·cos = 0.125
    0.125
    """
    envelope = mesh_band_envelope(average, teeth, band_orders=band_orders, axis=axis)
    deviations, peak_value, _ = _scaled_deviations(np.moveaxis(envelope, axis, -1))
    # Variances of signals above ~1e154 overflow to inf (never NaN).
    with np.errstate(over="ignore"):
        variance = np.mean(deviations * deviations, axis=-1) * peak_value * peak_value
    return _out(np.asarray(variance, dtype=np.float64))


def nb4(
    average: ArrayLike,
    teeth: int,
    baseline_variance: ArrayLike | None = None,
    *,
    band_orders: float | None = None,
    axis: int = -1,
) -> FloatOrArray:
    """NB4: NA4's statistic on the envelope of the mesh band (Zakrajsek et al. 1994).

    ``NB4 = N·Σ_i(E_i − Ē)⁴ / { (1/M)·Σ_{j=1}^{M} Σ_i (E_ij − Ē_j)² }² = m4(E) / σ̄_E²``,

    where ``E = |b + i·H(b)|`` is the Hilbert envelope of the TSA band-passed about the mesh
    frequency (:func:`mesh_band_envelope`; default band ``±(teeth − 1)//2`` orders), and
    ``σ̄_E²`` the mean of :func:`envelope_variance` over the records of the run so far, passed in
    explicitly. With ``baseline_variance=None`` the record's own envelope variance is used, so
    NB4 then equals the kurtosis of the envelope. A zero baseline gives ``0.0``.

    Examples
    --------
    >>> import numpy as np
    >>> n = np.arange(128)
    >>> x = (1 + 0.5 * np.cos(2 * np.pi * n / 128)) * np.cos(2 * np.pi * 8 * n / 128)
    >>> round(nb4(x, teeth=8), 12)  # envelope 1 + 0.5·cos: kurtosis of a sine
    1.5
    """
    envelope = mesh_band_envelope(average, teeth, band_orders=band_orders, axis=axis)
    values = np.moveaxis(envelope, axis, -1)
    return _out(_baseline_normalised_fourth_moment(values, baseline_variance))


def m6a(difference: ArrayLike, *, axis: int = -1) -> FloatOrArray:
    """``M6A = N²·Σ(d−d̄)⁶ / (Σ(d−d̄)²)³`` on the difference signal (Martin 1989; Lebold et al. 2000).

    15 for a Gaussian signal, 1 for a square wave; ``0.0`` for a constant signal.

    Examples
    --------
    >>> m6a([1.0, -1.0, 1.0, -1.0])
    1.0
    """
    return _out(_standardised_moment(_as_last_axis(difference, axis, "difference"), 6))


def m8a(difference: ArrayLike, *, axis: int = -1) -> FloatOrArray:
    """``M8A = N³·Σ(d−d̄)⁸ / (Σ(d−d̄)²)⁴`` on the difference signal (Martin 1989; Lebold et al. 2000).

    105 for a Gaussian signal, 1 for a square wave; ``0.0`` for a constant signal.

    Examples
    --------
    >>> m8a([1.0, -1.0, 1.0, -1.0])
    1.0
    """
    return _out(_standardised_moment(_as_last_axis(difference, axis, "difference"), 8))


def energy_ratio(difference: ArrayLike, regular: ArrayLike, *, axis: int = -1) -> FloatOrArray:
    """Energy ratio ``ER = RMS(d) / RMS(r)`` (Swansson 1980; Lebold et al. 2000).

    ``d`` is the difference signal and ``r`` the regular meshing signal. ``0.0`` when the
    regular signal is all zero.

    Examples
    --------
    >>> energy_ratio([0.5, -0.5], [2.0, -2.0])
    0.25
    """
    d = _as_last_axis(difference, axis, "difference")
    r = _as_last_axis(regular, axis, "regular")
    rms_r = _rms(r)
    return _out(_ratio_or_zero(_rms(d), rms_r, rms_r == 0.0))


def gear_metrics(
    average: ArrayLike,
    residual: ArrayLike,
    difference: ArrayLike,
    regular: ArrayLike,
    teeth: int,
    *,
    na4_baseline_variance: ArrayLike | None = None,
    nb4_baseline_variance: ArrayLike | None = None,
) -> dict[str, FloatOrArray]:
    """All classic metrics of one record, keyed as :data:`gearwatch.floor.results.AVERAGE_METRIC_NAMES`.

    ``rms``, ``peak``, ``crest`` and ``kurtosis`` are those of the TSA ``average``; ``fm0`` and
    ``nb4`` use the TSA and ``teeth``; ``na4`` and ``residual_kurtosis`` (NA4 divided by the
    record's own residual variance: gain-free, see :data:`detection.default_rules.DEFAULT_RULES`)
    the residual; ``fm4``, ``m6a``, ``m8a`` the
    difference signal; ``er`` the difference and the regular signal. The baselines are passed
    through to :func:`na4` and :func:`nb4` (``None``: the record's own variance). All signals
    lie along the last axis; leading axes are batched.

    Examples
    --------
    >>> import numpy as np
    >>> n = np.arange(256)
    >>> regular = np.cos(2 * np.pi * 16 * n / 256)
    >>> difference = 0.1 * np.cos(2 * np.pi * 3 * n / 256)
    >>> m = gear_metrics(regular + difference, difference, difference, regular, teeth=16)
    >>> sorted(m)
    ['crest', 'er', 'fm0', 'fm4', 'kurtosis', 'm6a', 'm8a', 'na4', 'nb4', 'peak', 'residual_kurtosis', 'rms']
    >>> round(m["er"], 6)
    0.1
    """
    return {
        "rms": rms(average),
        "peak": peak(average),
        "crest": crest_factor(average),
        "kurtosis": kurtosis(average),
        "fm0": fm0(average, teeth),
        "fm4": fm4(difference),
        "na4": na4(residual, na4_baseline_variance),
        "residual_kurtosis": na4(residual),
        "nb4": nb4(average, teeth, nb4_baseline_variance),
        "m6a": m6a(difference),
        "m8a": m8a(difference),
        "er": energy_ratio(difference, regular),
    }


def extremes_and_moment_sums(
    x: ArrayLike, shift: float = 0.0
) -> tuple[float, float, np.ndarray]:
    """Max, min and ``[Σ(x−c), Σ(x−c)², Σ(x−c)³, Σ(x−c)⁴]`` of a 1-D signal in one pass.

    The building block of block-wise raw-signal statistics (RMS and kurtosis about the mean of a
    long record, read one block at a time). ``c`` (``shift``) should be close to the mean — e.g.
    the first block's — so the sums do not cancel. A NaN anywhere makes max and min NaN; an inf
    shows as an infinite extreme.

    Examples
    --------
    >>> top, bottom, sums = extremes_and_moment_sums(np.array([1.0, -1.0, 1.0, -1.0]))
    >>> top, bottom, sums.tolist()
    (1.0, -1.0, [0.0, 4.0, 0.0, 4.0])
    """
    values = np.asarray(x, dtype=np.float64).ravel()
    if values.size == 0:
        return -np.inf, np.inf, np.zeros(4)
    top, bottom = float(values.max()), float(values.min())  # NaN anywhere: both NaN
    y = values - shift
    y2 = y * y
    # einsum, not np.dot: BLAS would start its threads, which then spin on a 2-core machine
    sums = np.array([y.sum(), y2.sum(), np.einsum("i,i->", y2, y), np.einsum("i,i->", y2, y2)])
    return top, bottom, sums
