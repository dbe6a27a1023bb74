"""Non-synchronous content: found in the scatter between hunting periods, where the mean cannot see it."""

from __future__ import annotations

import numpy as np
import pytest

from physics.reconcile.localize import nonsynchronous_mismatch
from physics.reconcile.observables import hunting_spectrum

FS_HZ = 20_000.0
SPEED_RPM = 1000.0


def _record(tone_hz: float | None, tone_amplitude: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Mesh tone (synchronous) + white noise (+ a tone locked to nothing), 4 hunting periods."""
    rng = np.random.default_rng(seed)
    rev_s = 60.0 / SPEED_RPM
    t = np.arange(int(4 * 21 * rev_s * FS_HZ + 0.2 * FS_HZ)) / FS_HZ
    signal = np.sin(2 * np.pi * 20 / rev_s * t) + 0.3 * rng.normal(size=t.size)
    if tone_hz is not None:
        signal += tone_amplitude * np.sin(2 * np.pi * tone_hz * t + 0.4)
    pulses = np.arange(0.0, t[-1], rev_s)
    return signal, pulses


def _located(signal: np.ndarray, pulses: np.ndarray) -> dict | None:
    hs = hunting_spectrum(signal, FS_HZ, pulses, 1, pinion_teeth=20, gear_teeth=21, samples_per_mesh=16,
                          max_frequency_hz=4000.0)
    return nonsynchronous_mismatch(hs.segment_spectra, hs.used, hs.bin_frequency_hz)


@pytest.mark.parametrize("tone_hz", [733.3, 2468.1])
def test_a_tone_locked_to_no_shaft_is_located_in_its_band(tone_hz: float) -> None:
    # 0.05 against 0.3 noise RMS: invisible in the raw record (-19 dB), obvious in the scatter.
    found = _located(*_record(tone_hz, 0.05, seed=3))
    assert found is not None
    assert found["band_hz"][0] <= tone_hz <= found["band_hz"][1]
    assert abs(found["peak_hz"] - tone_hz) < 2.0
    assert found["p_value"] < 1e-6


def test_noise_and_synchronous_content_only_give_nothing() -> None:
    assert all(_located(*_record(None, 0.0, seed=s)) is None for s in range(5))


def test_a_single_segment_cannot_show_scatter() -> None:
    seg = np.ones((1, 100), complex)
    assert nonsynchronous_mismatch(seg, np.ones(100, bool), np.arange(100.0)) is None
