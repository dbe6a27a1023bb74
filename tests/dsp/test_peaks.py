"""dsp.peaks.local_maxima against scipy.signal.find_peaks (same process, exact indices)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import find_peaks

from dsp.peaks import local_maxima


@pytest.mark.parametrize("seed", range(20))
def test_same_peaks_as_scipy_on_signals_with_plateaus_and_nans(seed: int) -> None:
    rng = np.random.default_rng(seed)
    # Few distinct levels make many plateaus; a few NaNs and repeated edges too.
    x = rng.integers(0, 4, size=int(rng.integers(0, 400))).astype(float)
    if x.size and seed % 3 == 0:
        x[rng.integers(0, x.size, size=max(1, x.size // 50))] = np.nan
    np.testing.assert_array_equal(local_maxima(x), find_peaks(x)[0])


def test_smooth_signal_and_edge_cases() -> None:
    t = np.linspace(0, 10, 1001)
    x = np.sin(3 * t) + 0.2 * np.sin(17 * t)
    np.testing.assert_array_equal(local_maxima(x), find_peaks(x)[0])
    for short in ([], [1.0], [1.0, 2.0], [2.0, 2.0, 2.0], [0.0, 1.0, 1.0]):
        assert local_maxima(np.array(short)).size == 0
    np.testing.assert_array_equal(local_maxima(np.array([0.0, 1.0, 1.0, 0.0])), [1])
    with pytest.raises(ValueError):
        local_maxima(np.zeros((2, 3)))
