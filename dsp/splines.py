"""The spline kernels of :mod:`dsp.angle`, in vectorised numpy.

* :func:`bspline5_prefilter` and :func:`bspline5_at`: the cardinal quintic B-spline that
  interpolates the signal (Unser 1999; the result equals :func:`scipy.ndimage.map_coordinates`
  with ``order=5, mode="mirror"`` to about 1e-14 of the signal's scale);
* :func:`not_a_knot_slopes` and :func:`piecewise_cubic_uniform`: the phase model, the cubic spline
  through the tach pulses (the same piecewise polynomial as :class:`scipy.interpolate.CubicSpline`
  with its default not-a-knot ends, to rounding) evaluated on the uniform angle grid.

Why numpy and not numba or scipy: ``gearwatch analyze`` is one short process per record, and
importing numba, loading its cached kernels (numba's ``ensure_blas`` imports scipy's base too) and
importing ``scipy.interpolate`` cost about 0.8 s of CPU, more than the whole chain; these kernels
cost about 30 ms per million samples more than numba's did (50 against 17 ms for a 60 s, 20 kHz
record; ``benchmarks/bench_chain.py``). No BLAS call either (``@`` on these sizes starts BLAS's
threads, whose spinning cost more CPU than the product): ``np.einsum`` sums the products.

The recursions of the prefilter are latency-bound one sample after the other; here the signal is
cut into chains of :data:`CHAIN` samples that run side by side, one numpy operation advancing every
chain by one sample. Each chain starts from its exact initial value, the pole's impulse response
summed over the ``horizon`` samples before (causal) or after (anti-causal) it, where
``|z|**horizon < 1e-17``: the same scheme as a single chain, to rounding.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "bspline5_at",
    "bspline5_prefilter",
    "hermite_coefficients",
    "not_a_knot_slopes",
    "piecewise_cubic_uniform",
]

FloatArray = NDArray[np.float64]

# Poles of the quintic B-spline interpolation prefilter (Unser 1999, table I).
_POLE_1 = -0.43057534709997379
_POLE_2 = -0.043096288203264653
_GAIN = (1 - _POLE_1) * (1 - 1 / _POLE_1) * (1 - _POLE_2) * (1 - 1 / _POLE_2)

CHAIN = 64
"""Samples per chain of the vectorised prefilter recursions: at least the longer pole's horizon
(47 samples), and short enough that a record gives thousands of chains per numpy operation."""
_TRANSPOSE_TILE = 512
"""Chains per tile when the record is transposed to and from the chain-major layout (in cache)."""
_EVAL_CHUNK = 65_536
"""Grid points per chunk of :func:`bspline5_at` (its temporaries stay in the CPU cache)."""


def _horizon(z: float) -> int:
    return int(np.ceil(np.log(1e-17) / np.log(abs(z))))


def _pole_pass_scalar(c: list[float], z: float, gain: float) -> None:
    """One pole, causal then anti-causal, one chain in plain Python (rows of 2 … 127 samples)."""
    n = len(c)
    horizon = _horizon(z)
    period = 2 * n - 2
    zk, acc = 1.0, 0.0
    for k in range(horizon):
        m = k % period  # index into the mirror-extended record
        acc += zk * c[m if m < n else period - m]
        zk *= z
    c[0] = gain * acc
    for i in range(1, n):
        c[i] = gain * c[i] + z * c[i - 1]
    c[n - 1] = (z / (z * z - 1.0)) * (c[n - 1] + z * c[n - 2])
    for i in range(n - 2, -1, -1):
        c[i] = z * (c[i + 1] - c[i])


def _pole_pass_chains(t: FloatArray, tail: list[float], z: float, gain: float) -> None:
    """One pole, causal then anti-causal, in place, on the chain-major layout.

    ``t[i, j]`` is sample ``j·CHAIN + i`` of the record; ``tail`` holds the last samples that do
    not fill a chain (fewer than :data:`CHAIN`), run one by one after (causal) or before
    (anti-causal) the chains, from their exact neighbours.
    """
    length, chains = t.shape
    horizon = _horizon(z)
    rows = list(t)
    step = np.empty(chains)
    # causal y[i] = gain·x[i] + z·y[i-1]; chain 0 starts from the mirror-boundary sum
    start = np.empty(chains)
    # (einsum, not @: a BLAS call would start BLAS's threads, which then spin)
    start[0] = np.einsum("k,k->", z ** np.arange(horizon), t[:horizon, 0])
    start[1:] = t[0, 1:] + np.einsum(
        "k,kj->j", z ** np.arange(horizon - 1, 0, -1), t[length - horizon + 1 :, :-1]
    )
    if gain != 1.0:
        t *= gain
    t[0] = gain * start
    previous = rows[0]
    for row in rows[1:]:
        np.multiply(previous, z, out=step)
        row += step
        previous = row
    y = float(t[-1, -1])
    for j in range(len(tail)):
        y = gain * tail[j] + z * y
        tail[j] = y
    # anti-causal y[i] = z·(y[i+1] − u[i]); the record's last sample from the mirror formula
    end = np.empty(chains)
    end[:-1] = -(z * t[-1, :-1] + np.einsum("k,kj->j", z ** np.arange(2, horizon + 1), t[: horizon - 1, 1:]))
    last = float(t[-1, -1])
    if tail:
        n_tail = len(tail)
        before = tail[-2] if n_tail >= 2 else last
        tail[-1] = (z / (z * z - 1.0)) * (tail[-1] + z * before)
        for j in range(n_tail - 2, -1, -1):
            tail[j] = z * (tail[j + 1] - tail[j])
        end[-1] = z * (tail[0] - last)
    else:
        end[-1] = (z / (z * z - 1.0)) * (last + z * float(t[-2, -1]))
    t[-1] = end
    following = rows[-1]
    for row in rows[-2::-1]:
        np.subtract(following, row, out=row)
        row *= z
        following = row


def bspline5_prefilter(rows: FloatArray) -> None:
    """Quintic B-spline interpolation coefficients of each row, in place (mirror boundary).

    Examples
    --------
    >>> x = np.array([[0.0, 1.0, 0.0, -1.0, 0.0, 1.0, 0.0]])
    >>> c = x.copy()
    >>> bspline5_prefilter(c)
    >>> out = np.empty(7)
    >>> bspline5_at(c[0], np.arange(7.0), out)
    >>> bool(np.allclose(out, x[0]))
    True
    """
    for r in range(rows.shape[0]):
        row = rows[r]
        n = row.size
        chains = n // CHAIN
        if chains < 2:
            values = [float(v) for v in row]
            _pole_pass_scalar(values, _POLE_1, _GAIN)
            _pole_pass_scalar(values, _POLE_2, 1.0)
            row[:] = values
            continue
        whole = chains * CHAIN
        by_chain = row[:whole].reshape(chains, CHAIN)
        t = np.empty((CHAIN, chains))
        for j in range(0, chains, _TRANSPOSE_TILE):
            t[:, j : j + _TRANSPOSE_TILE] = by_chain[j : j + _TRANSPOSE_TILE].T
        tail = [float(v) for v in row[whole:]]
        _pole_pass_chains(t, tail, _POLE_1, _GAIN)
        _pole_pass_chains(t, tail, _POLE_2, 1.0)
        for j in range(0, chains, _TRANSPOSE_TILE):
            by_chain[j : j + _TRANSPOSE_TILE] = t[:, j : j + _TRANSPOSE_TILE].T
        row[whole:] = tail


def _mirrored(c: FloatArray, first: int, stop: int) -> FloatArray:
    """``c`` at indices ``first … stop−1``, mirrored at both ends (clamped for short records)."""
    n = c.size
    if first >= 0 and stop <= n:
        return c[first:stop]
    index = np.abs(np.arange(first, stop))
    index = np.where(index > n - 1, 2 * (n - 1) - index, index)
    return c[np.clip(index, 0, n - 1)]


def _power_coefficients(e: FloatArray) -> list[FloatArray]:
    """120 × the coefficients of ``w⁰ … w⁵`` of the spline on ``[i, i+1)``, for every ``i``.

    ``e[k]`` is coefficient ``i0 + k − 2``; the result has ``e.size − 5`` entries. The weights of
    the six coefficients ``i−2 … i+3`` are the quintic B-spline's pieces, polynomials in the
    fraction ``w`` (Thévenaz, Blu & Unser 2000), gathered here per power of ``w`` so that a grid
    point costs one Horner scheme. (Written with forward differences it takes fewer operations
    but measured 1.6× slower: ``np.diff`` allocates every difference.)
    """
    m2, m1, c0, p1, p2, p3 = (e[k : e.size - 5 + k] for k in range(6))
    s2, s1 = m2 + p2, m1 + p1
    t2, t1 = p2 - m2, p1 - m1
    return [
        s2 + 26.0 * s1 + 66.0 * c0,
        5.0 * t2 + 50.0 * t1,
        10.0 * s2 + 20.0 * s1 - 60.0 * c0,
        10.0 * t2 - 20.0 * t1,
        5.0 * s2 - 20.0 * s1 + 30.0 * c0,
        (p3 - m2) + 5.0 * (m1 - p2) + 10.0 * (p1 - c0),
    ]


def bspline5_at(c: FloatArray, positions: FloatArray, out: FloatArray, scale: float = 1.0) -> None:
    """Evaluate the quintic spline with coefficients ``c`` at fractional sample positions
    ``scale × positions`` (``scale`` = the sampling rate when ``positions`` are times), into ``out``.

    Positions are taken a chunk at a time and the polynomial coefficients formed for the stretch
    of ``c`` the chunk reaches: short for increasing positions (a time grid), the whole of ``c``
    for scattered ones. ``out`` must be contiguous.
    """
    flat = positions.reshape(-1)
    target = out.reshape(-1)  # a view: ``out`` is contiguous
    for s in range(0, flat.size, _EVAL_CHUNK):
        p = flat[s : s + _EVAL_CHUNK] * scale
        floor = np.floor(p)
        w = p - floor
        i = floor.astype(np.intp)
        first = int(i.min())
        coefficients = _power_coefficients(_mirrored(c, first - 2, int(i.max()) + 4))
        k = i - first
        acc = coefficients[5].take(k)
        for power in (4, 3, 2, 1, 0):
            acc *= w
            acc += coefficients[power].take(k)
        acc *= 1.0 / 120.0
        target[s : s + _EVAL_CHUNK] = acc


def not_a_knot_slopes(x: FloatArray, y: FloatArray) -> FloatArray:
    """First derivatives at the knots of the not-a-knot cubic spline through ``(x, y)``.

    The tridiagonal system of :class:`scipy.interpolate.CubicSpline` (de Boor 1978), solved by
    the Thomas algorithm in plain Python floats (a record has about a thousand pulses per block).
    Two points give the line, three the parabola, as scipy does.
    """
    n = x.size
    dx = np.diff(x)
    slope = np.diff(y) / dx
    if n == 2:
        return np.array([slope[0], slope[0]])
    if n == 3:  # both not-a-knot conditions coincide: the parabola through the three points
        d0, d1 = float(dx[0]), float(dx[1])
        a = np.array([[1.0, 1.0, 0.0], [d1, 2 * (d0 + d1), d0], [0.0, 1.0, 1.0]])
        b = np.array([2 * slope[0], 3 * (d0 * slope[1] + d1 * slope[0]), 2 * slope[1]])
        return np.linalg.solve(a, b)
    h = dx.tolist()
    m = slope.tolist()
    lower = [0.0] * n  # coefficient of s[i-1] in row i
    diagonal = [0.0] * n
    upper = [0.0] * n  # coefficient of s[i+1] in row i
    rhs = [0.0] * n
    for i in range(1, n - 1):
        lower[i], diagonal[i], upper[i] = h[i], 2 * (h[i - 1] + h[i]), h[i - 1]
        rhs[i] = 3 * (h[i] * m[i - 1] + h[i - 1] * m[i])
    d = float(x[2] - x[0])
    diagonal[0], upper[0] = h[1], d
    rhs[0] = ((h[0] + 2 * d) * h[1] * m[0] + h[0] ** 2 * m[1]) / d
    d = float(x[-1] - x[-3])
    lower[n - 1], diagonal[n - 1] = d, h[-2]
    rhs[n - 1] = (h[-1] ** 2 * m[-2] + (2 * d + h[-1]) * h[-2] * m[-1]) / d
    for i in range(1, n):  # forward elimination
        factor = lower[i] / diagonal[i - 1]
        diagonal[i] -= factor * upper[i - 1]
        rhs[i] -= factor * rhs[i - 1]
    s = [0.0] * n
    s[n - 1] = rhs[n - 1] / diagonal[n - 1]
    for i in range(n - 2, -1, -1):
        s[i] = (rhs[i] - upper[i] * s[i + 1]) / diagonal[i]
    return np.array(s)


def hermite_coefficients(x: FloatArray, y: FloatArray, slopes: FloatArray) -> FloatArray:
    """``(4, n−1)`` power coefficients of the cubic Hermite pieces (highest power first), as
    :class:`scipy.interpolate.CubicHermiteSpline` stores them in ``c``."""
    dx = np.diff(x)
    slope = np.diff(y) / dx
    t = (slopes[:-1] + slopes[1:] - 2 * slope) / dx
    return np.stack([t / dx, (slope - slopes[:-1]) / dx - t, slopes[:-1], y[:-1]])


def _whole_points_per_piece(breaks: FloatArray, step: float) -> int:
    """Grid steps per piece when the breaks are uniform, start at 0 and hold a whole number of
    steps each (to 1e-9 of a step); else 0."""
    if breaks.size < 2 or breaks[0] != 0.0:
        return 0
    width = (breaks[-1] - breaks[0]) / (breaks.size - 1)
    per_piece = round(width / step)
    if per_piece < 1 or abs(width / step - per_piece) > 1e-9:
        return 0
    if np.max(np.abs(breaks - np.arange(breaks.size) * width)) > 1e-9 * step:
        return 0
    return int(per_piece)


def piecewise_cubic_uniform(
    breaks: FloatArray, coefficients: FloatArray, step: float, n_points: int
) -> tuple[FloatArray, bool]:
    """Evaluate a piecewise cubic (``coefficients`` as scipy's PPoly ``c``) at
    ``min(q·step, breaks[-1])``, q = 0 … n_points − 1, and whether the values strictly increase.

    Examples
    --------
    >>> values, increasing = piecewise_cubic_uniform(
    ...     np.array([0.0, 1.0, 2.0]), np.array([[0.0, 0.0], [0.0, 0.0], [1.0, 1.0], [0.0, 1.0]]),
    ...     0.5, 5)
    >>> values.tolist(), increasing
    ([0.0, 0.5, 1.0, 1.5, 2.0], True)
    """
    per_piece = _whole_points_per_piece(breaks, step)
    if per_piece and -(-n_points // per_piece) <= breaks.size - 1:
        # Uniform breaks every ``per_piece`` grid steps (the phase model's tach angles): point
        # j of piece k sits at u = j·step in it, so every piece shares the powers of u and the
        # values are one product (no per-point piece lookup, no repeated coefficients; 4–5×
        # faster). A point is the same as below to rounding (1e-13 s of a 300 s record).
        pieces = -(-n_points // per_piece)
        u = np.arange(per_piece) * step
        powers = np.stack([u**3, u**2, u, np.ones(per_piece)])
        values = np.einsum("ki,kj->ij", coefficients[:, :pieces], powers).reshape(-1)[:n_points]
        increasing = bool(n_points == 0 or np.all(values[1:] > values[:-1]))
        return np.asarray(values, dtype=np.float64), increasing
    x = np.arange(n_points) * step
    np.minimum(x, breaks[-1], out=x)
    # piece k holds the points from the first one at or past breaks[k] (the last piece: the rest)
    firsts = np.searchsorted(x, breaks[1:-1], side="left")
    counts = np.diff(np.concatenate(([0], firsts, [n_points])))
    values = x - np.repeat(breaks[:-1], counts)
    d = values.copy()
    values *= np.repeat(coefficients[0], counts)
    for power in (1, 2):
        values += np.repeat(coefficients[power], counts)
        values *= d
    values += np.repeat(coefficients[3], counts)
    increasing = bool(n_points == 0 or np.all(values[1:] > values[:-1]))
    return np.asarray(values, dtype=np.float64), increasing
