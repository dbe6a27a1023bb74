"""Local maxima of a 1-D signal, as :func:`scipy.signal.find_peaks` finds them without conditions.

Here rather than ``scipy.signal`` because importing ``scipy.signal`` (it imports ``scipy.stats``)
costs more than the whole per-record chain of a short record; the result is identical
(``tests/dsp/test_peaks.py`` compares them on random signals with plateaus).

Examples
--------
>>> import numpy as np
>>> local_maxima(np.array([0.0, 2.0, 1.0, 3.0, 3.0, 3.0, 0.0, 1.0]))
array([1, 4])
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["local_maxima"]


def local_maxima(x: ArrayLike) -> NDArray[np.intp]:
    """Indices of the local maxima of ``x``: ``find_peaks(x)[0]`` of :mod:`scipy.signal`.

    Parameters
    ----------
    x : array_like, 1-D
        The signal.

    Returns
    -------
    ndarray of intp
        Ascending indices. A flat peak (a plateau of equal values higher than both neighbours)
        is reported once, at its middle sample (the left one of the two middles for an even
        length). The first and last samples are never peaks, nor is a plateau that touches
        either end. NaN is never a peak and ends plateaus (it equals nothing).

    Raises
    ------
    ValueError
        If ``x`` is not 1-D.
    """
    values = np.asarray(x, dtype=np.float64)
    if values.ndim != 1:
        raise ValueError(f"x must be 1-D, got shape {values.shape}")
    n = values.size
    if n < 3:
        return np.zeros(0, dtype=np.intp)
    # Runs of equal values: [start, end] inclusive.
    change = values[1:] != values[:-1]
    starts = np.concatenate(([0], np.flatnonzero(change) + 1))
    ends = np.concatenate((starts[1:] - 1, [n - 1]))
    inner = (starts > 0) & (ends < n - 1)
    starts, ends = starts[inner], ends[inner]
    rising = values[starts - 1] < values[starts]
    falling = values[ends + 1] < values[ends]
    peak = rising & falling
    return ((starts[peak] + ends[peak]) // 2).astype(np.intp)
