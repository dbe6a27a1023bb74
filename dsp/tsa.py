"""Time-synchronous average and the classical regular, residual and difference signals.

The synchronous average of a shaft (McFadden 1987; Braun 1975) is the mean, sample by sample,
of whole revolutions of that shaft on a uniform angle grid (:func:`dsp.angle.angle_resample`).
Everything not periodic in that shaft's angle tends to zero as revolutions are added: with a
20-tooth pinion and a 21-tooth gear, a component periodic in the gear angle sits at pinion orders
``20 m / 21`` and cancels exactly from a pinion average over a multiple of 21 pinion revolutions
(the hunting period), approximately otherwise. Average per pinion revolution to study the pinion,
per gear revolution to study the gear.

Order-domain filters. An average of ``N`` samples per revolution has DFT bin ``k`` = shaft order
``k`` (cycles per revolution), ``0 <= k <= N // 2``. With ``Z`` teeth on the averaged shaft, the
mesh harmonics are the orders ``h·Z`` (``h = 1, 2, …``). The three classical signals are exact
projections in the order domain (each zeroes a set of DFT bins and keeps the rest unchanged):

- **regular signal** (Stewart 1977's "regular meshing components"; Lebold, McClintic, Campbell,
  Byington & Maynard 2000): the orders ``{ |h·Z + s| : h >= 0, -S <= s <= S }`` where ``S`` =
  ``sidebands``, i.e. the mean (order 0), the first ``S`` shaft orders (sidebands of order 0),
  every mesh harmonic ``h·Z`` and its ``S`` sidebands on either side. Everything else is zeroed.
- **difference signal** (Stewart 1977, used by FM4, M6A, M8A; Lebold et al. 2000: the average
  minus the regular meshing components): the average with exactly the regular orders zeroed.
  ``regular_signal + difference_signal == average``.
- **residual signal** (McFadden 1987 "Examination of a technique for the early detection of
  failure in gears by signal processing of the time domain average of the meshing vibration",
  MSSP 1(2); used by NA4): the average with the mean and the mesh harmonics ``h·Z`` (``h >= 1``)
  zeroed and their sidebands kept. Lebold et al. 2000 also remove "the shaft frequency and its
  harmonics": pass ``shaft_orders=M`` to zero shaft orders ``1..M`` as well (default 0).

Orders above ``N // 2`` do not exist in an ``N``-sample average and are ignored.

Examples
--------
>>> import numpy as np
>>> angle = np.arange(1280) / 1280
>>> avg = np.cos(2 * np.pi * 20 * angle) + 0.1 * np.cos(2 * np.pi * 21 * angle) \\
...     + 0.01 * np.cos(2 * np.pi * 7 * angle)
>>> d = difference_signal(avg, teeth=20)                   # mesh and ±1 sidebands removed
>>> bool(np.allclose(d, 0.01 * np.cos(2 * np.pi * 7 * angle)))
True
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "difference_signal",
    "mesh_orders",
    "regular_orders",
    "regular_signal",
    "residual_orders",
    "residual_signal",
    "synchronous_average",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def synchronous_average(revs: ArrayLike, *, axis: int = -2) -> FloatArray:
    """Mean over whole revolutions (the time-synchronous average).

    Parameters
    ----------
    revs : array_like
        Revolutions on a common angle grid, e.g. ``(..., n_revs, samples_per_rev)`` from
        :func:`dsp.angle.angle_resample`.
    axis : int
        Revolution axis (default -2).

    Returns
    -------
    ndarray
        ``revs`` averaged along ``axis`` (that axis removed).

    Examples
    --------
    >>> synchronous_average([[1.0, 2.0], [3.0, 6.0]])
    array([2., 4.])
    """
    r = np.asarray(revs, dtype=np.float64)
    if r.ndim < 2:
        raise ValueError(f"need at least 2-D revolutions, got shape {r.shape}")
    if r.shape[axis] < 1:
        raise ValueError("cannot average zero revolutions")
    return np.asarray(np.mean(r, axis=axis), dtype=np.float64)


def _check(n_samples: int, teeth: int, sidebands: int) -> None:
    if int(teeth) != teeth or teeth < 1:
        raise ValueError(f"teeth must be a positive integer, got {teeth}")
    if teeth > n_samples // 2:
        raise ValueError(
            f"the mesh order {teeth} is above the Nyquist order {n_samples // 2} of a "
            f"{n_samples}-sample average"
        )
    if int(sidebands) != sidebands or sidebands < 0:
        raise ValueError(f"sidebands must be a non-negative integer, got {sidebands}")
    if 2 * sidebands >= teeth:
        raise ValueError(
            f"{sidebands} sidebands on each side of every mesh harmonic of a {teeth}-tooth "
            "shaft would cover every order"
        )


def mesh_orders(n_samples: int, teeth: int) -> IntArray:
    """Mesh-harmonic orders ``h·teeth`` (``h >= 1``) up to the Nyquist order ``n_samples // 2``.

    Examples
    --------
    >>> mesh_orders(64, 10)
    array([10, 20, 30])
    """
    _check(n_samples, teeth, 0)
    return np.arange(teeth, n_samples // 2 + 1, teeth, dtype=np.int64)


def regular_orders(n_samples: int, teeth: int, sidebands: int = 1) -> IntArray:
    """Orders kept by :func:`regular_signal` (and zeroed by :func:`difference_signal`).

    ``{ |h·teeth + s| : h >= 0, |s| <= sidebands } ∩ [0, n_samples // 2]``, sorted.

    Examples
    --------
    >>> regular_orders(64, 10, sidebands=1)
    array([ 0,  1,  9, 10, 11, 19, 20, 21, 29, 30, 31])
    """
    _check(n_samples, teeth, sidebands)
    nyquist = n_samples // 2
    centres = np.arange(0, nyquist + sidebands + 1, teeth)
    orders = np.abs(centres[:, np.newaxis] + np.arange(-sidebands, sidebands + 1)).ravel()
    return np.unique(orders[orders <= nyquist]).astype(np.int64)


def residual_orders(n_samples: int, teeth: int, shaft_orders: int = 0) -> IntArray:
    """Orders zeroed by :func:`residual_signal`: 0, ``1..shaft_orders`` and every ``h·teeth``.

    Examples
    --------
    >>> residual_orders(64, 10)
    array([ 0, 10, 20, 30])
    """
    _check(n_samples, teeth, 0)
    if int(shaft_orders) != shaft_orders or shaft_orders < 0:
        raise ValueError(f"shaft_orders must be a non-negative integer, got {shaft_orders}")
    low = np.arange(0, min(shaft_orders, n_samples // 2) + 1)
    return np.unique(np.concatenate([low, mesh_orders(n_samples, teeth)])).astype(np.int64)


def _keep_orders(average: ArrayLike, orders: IntArray, keep: bool, axis: int) -> FloatArray:
    """Zero either the listed DFT bins (``keep=False``) or all the others (``keep=True``)."""
    x = np.moveaxis(np.asarray(average, dtype=np.float64), axis, -1)
    n = x.shape[-1]
    spectrum = np.fft.rfft(x, axis=-1)
    mask = np.zeros(n // 2 + 1, dtype=bool)
    mask[orders] = True
    spectrum[..., ~mask if keep else mask] = 0.0
    out = np.fft.irfft(spectrum, n=n, axis=-1)
    return np.moveaxis(np.asarray(out, dtype=np.float64), -1, axis)


def regular_signal(
    average: ArrayLike, teeth: int, *, sidebands: int = 1, axis: int = -1
) -> FloatArray:
    """Regular meshing components of a synchronous average (orders of :func:`regular_orders`).

    Parameters
    ----------
    average : array_like
        Synchronous average(s), one revolution along ``axis``.
    teeth : int
        Teeth on the averaged shaft's gear (mesh order).
    sidebands : int
        Shaft-order sidebands kept on each side of every mesh harmonic (and shaft orders
        ``1..sidebands``); must be below ``teeth / 2``.
    axis : int
        Angle axis.

    Returns
    -------
    ndarray
        Same shape as ``average``.

    Examples
    --------
    >>> import numpy as np
    >>> a = np.cos(2 * np.pi * 10 * np.arange(64) / 64) + np.cos(2 * np.pi * 5 * np.arange(64) / 64)
    >>> bool(np.allclose(regular_signal(a, 10), np.cos(2 * np.pi * 10 * np.arange(64) / 64)))
    True
    """
    a = np.asarray(average, dtype=np.float64)
    orders = regular_orders(a.shape[axis], teeth, sidebands)
    return _keep_orders(a, orders, keep=True, axis=axis)


def difference_signal(
    average: ArrayLike, teeth: int, *, sidebands: int = 1, axis: int = -1
) -> FloatArray:
    """Average minus its regular signal: the orders of :func:`regular_orders` zeroed.

    Parameters are those of :func:`regular_signal`.

    Examples
    --------
    >>> import numpy as np
    >>> a = np.cos(2 * np.pi * 10 * np.arange(64) / 64) + np.cos(2 * np.pi * 5 * np.arange(64) / 64)
    >>> bool(np.allclose(difference_signal(a, 10), np.cos(2 * np.pi * 5 * np.arange(64) / 64)))
    True
    """
    a = np.asarray(average, dtype=np.float64)
    orders = regular_orders(a.shape[axis], teeth, sidebands)
    return _keep_orders(a, orders, keep=False, axis=axis)


def residual_signal(
    average: ArrayLike, teeth: int, *, axis: int = -1, shaft_orders: int = 0
) -> FloatArray:
    """Average with its mean and mesh harmonics removed (orders of :func:`residual_orders`).

    Parameters
    ----------
    average : array_like
        Synchronous average(s), one revolution along ``axis``.
    teeth : int
        Teeth on the averaged shaft's gear (mesh order).
    axis : int
        Angle axis.
    shaft_orders : int
        Also zero shaft orders ``1..shaft_orders`` (Lebold et al. 2000's variant); default 0
        (McFadden 1987: mesh harmonics only; their sidebands stay).

    Examples
    --------
    >>> import numpy as np
    >>> k = np.arange(64) / 64
    >>> a = 2.0 + np.cos(2 * np.pi * 10 * k) + np.cos(2 * np.pi * 11 * k)
    >>> bool(np.allclose(residual_signal(a, 10), np.cos(2 * np.pi * 11 * k)))
    True
    """
    a = np.asarray(average, dtype=np.float64)
    orders = residual_orders(a.shape[axis], teeth, shaft_orders)
    return _keep_orders(a, orders, keep=False, axis=axis)
