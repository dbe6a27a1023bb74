"""The transfer path as a nuisance: a new structural mode only where the data shows its peak.

A transfer path multiplies every order by a smooth function of frequency. A path the
configuration was not built with (another housing, another simulator) leaves a misfit spread
over the whole band, and a catalogue ``structural_mode`` — a resonance with a free gain,
frequency and damping — can always absorb some of it wherever it is put: modes became the sink
for every kind of misfit. A mode is a *peak*: its own frequency band must carry more of the
residual's excess than its flanks. :func:`mode_peak_ratio` measures that on the residual before
the mode is added; :data:`MIN_PEAK_RATIO` is the acceptance line.

Examples
--------
>>> import numpy as np
>>> f = np.arange(1, 4001) * 2.0                  # 2 … 8000 Hz
>>> chi2 = np.full(f.size, 2.0)                  # a right model: χ² = 2 per bin
>>> chi2[(f > 2900) & (f < 3100)] = 40.0          # a peak at 3 kHz
>>> round(float(mode_peak_ratio(chi2, f, np.array([3000.0, 5000.0]), np.array([0.02, 0.02]))[0]), 1)
4.7
>>> float(mode_peak_ratio(chi2, f, np.array([5000.0]), np.array([0.02]))[0])
0.0
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

MIN_PEAK_RATIO = 2.0
"""A mode is scanned only where its band's mean excess χ² is at least this multiple of its
flanks' (and significant): otherwise its frequency is not identifiable in the data."""

MIN_PEAK_Z = 5.0
"""The band's excess must also stand this many standard deviations above χ² = 2 per bin."""


def mode_peak_ratio(
    chi2_per_bin: FloatArray,
    frequency_hz: FloatArray,
    mode_frequency_hz: FloatArray,
    damping_ratio: FloatArray,
) -> FloatArray:
    """Excess χ² per bin inside each mode's half-power band over that in its flanks.

    ``chi2_per_bin`` (2 per bin for a right model) on the fitted bins at ``frequency_hz``
    (ascending). The band of a mode at f with damping ζ is ``f (1 ± max(ζ, 0.005))``; its
    flanks reach to ``f (1 ± 4 max(ζ, 0.005))``. Returns, per mode, ``excess_band /
    max(excess_flanks, floor)`` where the floor is one standard deviation of the flanks' mean
    under the null; 0 where the band's excess is not significant (``MIN_PEAK_Z``) or the band
    holds no bin.
    """
    f = np.asarray(frequency_hz, dtype=np.float64)
    x = np.asarray(chi2_per_bin, dtype=np.float64) - 2.0
    c = np.concatenate(([0.0], np.cumsum(x)))
    f0 = np.asarray(mode_frequency_hz, dtype=np.float64)
    width = np.maximum(np.asarray(damping_ratio, dtype=np.float64), 0.005)

    def window(lo: FloatArray, hi: FloatArray) -> tuple[FloatArray, FloatArray]:
        i = np.searchsorted(f, lo, side="left")
        j = np.searchsorted(f, hi, side="right")
        return c[j] - c[i], (j - i).astype(np.float64)

    band_sum, band_n = window(f0 * (1 - width), f0 * (1 + width))
    outer_sum, outer_n = window(f0 * (1 - 4 * width), f0 * (1 + 4 * width))
    flank_sum, flank_n = outer_sum - band_sum, outer_n - band_n
    with np.errstate(divide="ignore", invalid="ignore"):
        band_mean = np.where(band_n > 0, band_sum / np.maximum(band_n, 1), 0.0)
        flank_mean = np.where(flank_n > 0, flank_sum / np.maximum(flank_n, 1), 0.0)
        # χ² with 2 dof has variance 4 per bin: the z of the band's excess, and the flanks'
        # mean known to ± 2/√n.
        z = band_sum / np.sqrt(4.0 * np.maximum(band_n, 1))
        floor = 2.0 / np.sqrt(np.maximum(flank_n, 1))
        ratio = band_mean / np.maximum(flank_mean, floor)
    ratio = np.where((band_n > 0) & (z >= MIN_PEAK_Z), ratio, 0.0)
    return np.asarray(ratio, dtype=np.float64)
