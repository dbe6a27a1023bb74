"""Synchronous averages per shaft and the regular / residual / difference signals, checked in
the order domain."""

from __future__ import annotations

import numpy as np
import pytest

from dsp.angle import angle_resample
from dsp.synthetic import synthetic_gear_record
from dsp.tach import pulse_times_from_waveform
from dsp.tsa import (
    difference_signal,
    regular_orders,
    regular_signal,
    residual_orders,
    residual_signal,
    synchronous_average,
)

N = 1280  # 20 teeth × 64 samples per mesh period
TEETH = 20


def every_order_average(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A revolution with every order 0..N/2 present (random complex amplitudes)."""
    rng = np.random.default_rng(seed)
    spectrum = rng.standard_normal(N // 2 + 1) + 1j * rng.standard_normal(N // 2 + 1)
    spectrum[0] = spectrum[0].real
    spectrum[-1] = spectrum[-1].real
    return np.fft.irfft(spectrum, n=N), spectrum


def expected_regular(teeth: int, sidebands: int) -> set[int]:
    """Independent enumeration of the regular orders: 0..S, and h·Z ± 0..S for h >= 1."""
    orders = set(range(sidebands + 1))
    h = 1
    while h * teeth - sidebands <= N // 2:
        orders.update(o for o in range(h * teeth - sidebands, h * teeth + sidebands + 1))
        h += 1
    return {o for o in orders if o <= N // 2}


def nonzero_orders(signal: np.ndarray) -> set[int]:
    return set(np.flatnonzero(np.abs(np.fft.rfft(signal)) > 1e-9).tolist())


@pytest.mark.parametrize("sidebands", [0, 1, 2, 3])
def test_regular_and_difference_split_orders_exactly(sidebands: int) -> None:
    avg, spectrum = every_order_average()
    regular = regular_signal(avg, TEETH, sidebands=sidebands)
    difference = difference_signal(avg, TEETH, sidebands=sidebands)
    kept = expected_regular(TEETH, sidebands)
    assert set(regular_orders(N, TEETH, sidebands).tolist()) == kept
    assert nonzero_orders(regular) == kept
    assert nonzero_orders(difference) == set(range(N // 2 + 1)) - kept
    # Kept orders are untouched, and the two parts add back to the average.
    k = sorted(kept)
    np.testing.assert_allclose(np.fft.rfft(regular)[k], spectrum[k], atol=1e-9)
    np.testing.assert_allclose(regular + difference, avg, atol=1e-12)


def test_regular_orders_listed_for_sidebands_1() -> None:
    orders = regular_orders(N, TEETH, 1)
    assert orders[:8].tolist() == [0, 1, 19, 20, 21, 39, 40, 41]
    assert orders[-2:].tolist() == [639, 640]  # 640 = 32 × 20, its upper sideband is beyond N/2


@pytest.mark.parametrize("shaft_orders", [0, 2])
def test_residual_removes_mean_and_mesh_harmonics_only(shaft_orders: int) -> None:
    avg, spectrum = every_order_average(1)
    residual = residual_signal(avg, TEETH, shaft_orders=shaft_orders)
    removed = {0, *range(1, shaft_orders + 1), *range(TEETH, N // 2 + 1, TEETH)}
    assert set(residual_orders(N, TEETH, shaft_orders).tolist()) == removed
    assert nonzero_orders(residual) == set(range(N // 2 + 1)) - removed
    sidebands = [19, 21, 41]
    np.testing.assert_allclose(np.fft.rfft(residual)[sidebands], spectrum[sidebands], atol=1e-9)


def test_axis_and_batch() -> None:
    a, _ = every_order_average(2)
    b, _ = every_order_average(3)
    stacked = np.stack([a, b], axis=1)  # angle axis 0
    out = difference_signal(stacked, TEETH, axis=0)
    np.testing.assert_allclose(out[:, 1], difference_signal(b, TEETH), atol=1e-12)
    np.testing.assert_allclose(synchronous_average(np.stack([a, b])), (a + b) / 2)
    np.testing.assert_allclose(synchronous_average(stacked, axis=1), (a + b) / 2)


def test_bad_parameters() -> None:
    avg, _ = every_order_average()
    with pytest.raises(ValueError, match="cover every order"):
        regular_signal(avg, TEETH, sidebands=10)
    with pytest.raises(ValueError, match="Nyquist"):
        residual_signal(avg[:32], 20)
    with pytest.raises(ValueError, match="zero revolutions"):
        synchronous_average(np.zeros((0, 16)))


# --------------------------------------------------------------------------- pinion vs gear


@pytest.fixture(scope="module")
def healthy_20_21():
    # Pinion 1000 rpm; 42 pinion revolutions = 2 hunting periods = 40 gear revolutions.
    # Gear-shaft component: gear order 1 (pinion order 20/21), amplitude 0.3, phase 0.7 rad.
    rec = synthetic_gear_record(duration_s=2.7, noise_rms=0.0, gear_order_amplitude=0.3, seed=5)
    pulses = pulse_times_from_waveform(rec.tach_waveform, rec.sample_rate_hz)
    return rec, pulses


def test_gear_component_leaves_the_pinion_average(healthy_20_21) -> None:
    rec, pulses = healthy_20_21
    revs = angle_resample(rec.acceleration, rec.sample_rate_hz, pulses, 1, 1280)
    assert revs.shape[0] >= 42
    pinion_avg = synchronous_average(revs[:42])
    orders = np.abs(np.fft.rfft(pinion_avg)) * 2 / 1280
    # Only the mesh harmonics 20, 40, 60 remain (amplitudes 1, 0.5, 0.25).
    np.testing.assert_allclose(orders[[20, 40, 60]], [1.0, 0.5, 0.25], atol=1e-4)
    others = np.delete(orders, [20, 40, 60])
    assert others.max() < 1e-4
    # Not a tautology: a single pinion revolution does contain it (leaks over many orders).
    single = np.abs(np.fft.rfft(revs[0])) * 2 / 1280
    assert np.delete(single, [20, 40, 60]).max() > 0.05


def test_gear_component_appears_in_the_gear_average(healthy_20_21) -> None:
    rec, pulses = healthy_20_21
    gear_revs = angle_resample(
        rec.acceleration, rec.sample_rate_hz, pulses, 1, 21 * 64, shaft_ratio=20 / 21
    )
    assert gear_revs.shape[0] >= 40
    gear_avg = synchronous_average(gear_revs[:40])
    spectrum = np.fft.rfft(gear_avg) * 2 / (21 * 64)
    assert abs(spectrum[1]) == pytest.approx(0.3, abs=1e-4)
    assert np.angle(spectrum[1]) == pytest.approx(0.7, abs=1e-3)
    # Mesh at gear order 21 and its harmonics; nothing else.
    np.testing.assert_allclose(np.abs(spectrum[[21, 42, 63]]), [1.0, 0.5, 0.25], atol=1e-4)
    assert np.abs(np.delete(spectrum, [1, 21, 42, 63])).max() < 1e-4


def test_difference_signal_of_a_spalled_pinion_keeps_the_spall() -> None:
    rec = synthetic_gear_record(duration_s=2.7, noise_rms=0.0, spall_tooth=7, seed=2)
    revs = angle_resample(rec.acceleration, rec.sample_rate_hz, rec.pulse_times_s, 1, 1280)
    avg = synchronous_average(revs[:42])
    diff = difference_signal(avg, 20)
    # The mesh is gone (it has only regular orders); what is left peaks in tooth 7's sector.
    peak_deg = np.argmax(np.abs(diff)) * 360 / 1280
    assert rec.spall_pitch_angle_deg is not None
    assert 0 <= peak_deg - (rec.spall_pitch_angle_deg - 18 / 2) < 18


@pytest.mark.parametrize(
    "module",
    ["dsp.tach", "dsp.angle", "dsp.tsa", "dsp.synthetic", "dsp.robust", "dsp.quality",
     "dsp.meshspectrum", "dsp.meshtrack", "dsp.tachless"],
)
def test_docstring_examples_run(module: str) -> None:
    import doctest
    import importlib

    result = doctest.testmod(importlib.import_module(module), optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0
    assert result.failed == 0
