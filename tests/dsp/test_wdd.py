"""Tests of the W'' estimate (dsp.wdd): random decrement, Prony, end-to-end deconvolution.

Every reference is a signal built here from known parameters: sums of damped sinusoids for
Prony, white noise through a known single-degree-of-freedom filter for random decrement, and a
synthetic synchronous average (mesh harmonics + a known W'' through a known damped mode) for
the whole chain.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.signal

from dsp import wdd


def damped_sinusoids(
    n_samples: int, modes: list[tuple[float, float, float, float]]
) -> np.ndarray:
    """``Σ A·rⁿ·cos(2πfn + φ)`` for (f cycles/sample, ζ, A, φ), ``r = exp(−ζ·2πf/sqrt(1−ζ²))``."""
    n = np.arange(n_samples)
    total = np.zeros(n_samples)
    for frequency, zeta, amplitude, phase in modes:
        radius = pole_radius(frequency, zeta)
        total += amplitude * radius**n * np.cos(2 * np.pi * frequency * n + phase)
    return total


def pole_radius(frequency: float, zeta: float) -> float:
    return math.exp(-zeta * 2 * math.pi * frequency / math.sqrt(1 - zeta * zeta))


def sdof_impulse_response(n_samples: int, frequency: float, zeta: float) -> np.ndarray:
    """Impulse-invariant 1-DOF response ``rⁿ·sin(2πfn)`` (zero at n = 0, like e^{−σt}sin ω_d t)."""
    n = np.arange(n_samples)
    return pole_radius(frequency, zeta) ** n * np.sin(2 * np.pi * frequency * n)


def sdof_filter(noise: np.ndarray, frequency: float, zeta: float) -> np.ndarray:
    radius, theta = pole_radius(frequency, zeta), 2 * np.pi * frequency
    numerator = [0.0, radius * math.sin(theta)]
    denominator = [1.0, -2 * radius * math.cos(theta), radius * radius]
    return scipy.signal.lfilter(numerator, denominator, noise)


def correlation(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.corrcoef(a, b)[0, 1])


TWO_MODES = [(0.05, 0.02, 1.0, 0.3), (0.18, 0.05, 0.6, -1.0)]


# ------------------------------------------------------------------ Prony


def test_prony_recovers_two_modes_without_noise() -> None:
    h = damped_sinusoids(128, TWO_MODES)
    modes = wdd.prony(h, 2, samples_per_rev=1280)
    assert len(modes) == 2
    for mode, (frequency, zeta, amplitude, phase) in zip(modes, TWO_MODES, strict=True):
        assert mode.frequency_cycles_per_sample == pytest.approx(frequency, abs=1e-10)
        assert mode.frequency_orders == pytest.approx(frequency * 1280, abs=1e-7)
        assert mode.damping_ratio == pytest.approx(zeta, rel=1e-7)
        assert mode.amplitude == pytest.approx(amplitude, rel=1e-7)
        assert mode.phase_rad == pytest.approx(phase, abs=1e-7)
        assert mode.pole_radius == pytest.approx(pole_radius(frequency, zeta), rel=1e-10)
    np.testing.assert_allclose(wdd.mode_impulse_response(modes, 128), h, atol=1e-8)


def test_prony_with_small_noise() -> None:
    clean = damped_sinusoids(128, TWO_MODES)
    noisy = clean + 1e-3 * np.random.default_rng(11).standard_normal(128)  # ~ −55 dB
    modes = wdd.prony(noisy, 2)
    for mode, (frequency, zeta, amplitude, phase) in zip(modes, TWO_MODES, strict=True):
        assert mode.frequency_cycles_per_sample == pytest.approx(frequency, abs=2e-4)
        assert mode.damping_ratio == pytest.approx(zeta, rel=0.05)
        assert mode.amplitude == pytest.approx(amplitude, rel=0.02)
        assert mode.phase_rad == pytest.approx(phase, abs=0.02)
        assert math.isnan(mode.frequency_orders)  # samples_per_rev not given


def test_prony_real_poles() -> None:
    n = np.arange(40)
    (decay,) = wdd.prony(2.0 * 0.8**n, 1)
    assert decay.frequency_cycles_per_sample == 0.0
    assert decay.pole_radius == pytest.approx(0.8, rel=1e-10)
    assert decay.damping_ratio == 1.0
    assert decay.amplitude == pytest.approx(2.0, rel=1e-10)
    (alternating,) = wdd.prony(-1.5 * (-0.7) ** n, 1)
    assert alternating.frequency_cycles_per_sample == 0.5
    assert alternating.pole_radius == pytest.approx(0.7, rel=1e-10)
    assert abs(alternating.phase_rad) == pytest.approx(math.pi)
    np.testing.assert_allclose(
        wdd.mode_impulse_response((alternating,), 40), -1.5 * (-0.7) ** n, atol=1e-10
    )


def test_prony_rejects_bad_input() -> None:
    with pytest.raises(ValueError, match="zero"):
        wdd.prony(np.zeros(32), 1)
    with pytest.raises(ValueError, match="at least"):
        wdd.prony(np.ones(7), 2)
    with pytest.raises(ValueError, match="1-D"):
        wdd.prony(np.ones((2, 32)), 1)
    with pytest.raises(ValueError, match="positive integer"):
        wdd.prony(np.ones(32), 0)


def test_damped_mode_pole_radius_needs_decay_for_pure_decay() -> None:
    mode = wdd.DampedMode(0.0, 0.0, 1.0, 1.0, 0.0)
    with pytest.raises(ValueError, match="decay_nepers_per_sample"):
        _ = mode.pole_radius
    assert wdd.DampedMode(0.1, 12.8, 0.05, 1.0, 0.0).pole_radius == pytest.approx(
        pole_radius(0.1, 0.05), rel=1e-14
    )


# ------------------------------------------------------------------ random decrement


@pytest.mark.parametrize(
    ("frequency", "zeta", "trigger_level"),
    [(0.05, 0.03, None), (0.1, 0.05, None), (0.2, 0.02, 0.0), (0.02, 0.05, 1.0)],
)
def test_random_decrement_recovers_sdof_impulse_response(
    frequency: float, zeta: float, trigger_level: float | None
) -> None:
    noise = np.random.default_rng(12).standard_normal(2**16)
    response = sdof_filter(noise, frequency, zeta)
    segment = int(3 / (zeta * 2 * math.pi * frequency))  # three decay time constants
    signature = wdd.random_decrement(response, segment, trigger_level=trigger_level)
    truth = sdof_impulse_response(segment, frequency, zeta)
    assert signature.shape == (segment,)
    assert correlation(signature, truth) > 0.98
    # it is the impulse response, not the autocorrelation (free decay from a displacement)
    free_decay = damped_sinusoids(segment, [(frequency, zeta, 1.0, 0.0)])
    assert correlation(signature, truth) > correlation(signature, free_decay) + 0.05


def test_random_decrement_of_a_sine_is_a_sine() -> None:
    # up-crossings of +a and −a of A·sin: segments A·sin(ωτ ± φ0) average to A·cos φ0·sin(ωτ)
    n = np.arange(4096)
    omega = 2 * np.pi / 64
    signature = wdd.random_decrement(np.sin(omega * n), 64, trigger_level=0.5)
    expected = math.cos(math.asin(0.5)) * np.sin(omega * np.arange(64))
    np.testing.assert_allclose(signature, expected, atol=2e-3)


def test_random_decrement_rejects_bad_input() -> None:
    with pytest.raises(ValueError, match="never crosses"):
        wdd.random_decrement(np.ones(100), 10)
    with pytest.raises(ValueError, match="never crosses"):
        wdd.random_decrement(np.sin(np.arange(100.0)), 10, trigger_level=5.0)
    with pytest.raises(ValueError, match="at least"):
        wdd.random_decrement(np.ones(10), 10)
    with pytest.raises(ValueError, match="NaN"):
        wdd.random_decrement(np.array([0.0, np.nan, 1.0, 2.0]), 1)
    with pytest.raises(ValueError, match="1-D"):
        wdd.random_decrement(np.ones((3, 30)), 4)


# ------------------------------------------------------------------ W'' end to end

TEETH = 20
SAMPLES_PER_MESH = 64
N_REV = TEETH * SAMPLES_PER_MESH
SPALL_SAMPLES = 7
PATH_FREQUENCY, PATH_ZETA = 0.2, 0.1


def true_wdd(start: int) -> np.ndarray:
    """Seed eq. 18: W'' of a rectangular window = δ[n] − δ[n−1] − δ[n−N] + δ[n−N−1]."""
    w = np.zeros(N_REV)
    w[[start, start + 1, start + SPALL_SAMPLES, start + SPALL_SAMPLES + 1]] = [1, -1, -1, 1]
    return w


def synthetic_average(start: int, noise: float, seed: int = 0) -> np.ndarray:
    theta = 2 * np.pi * np.arange(N_REV) / N_REV
    mesh = sum(
        amplitude * np.cos(harmonic * TEETH * theta + phase)
        for harmonic, (amplitude, phase) in enumerate([(1.0, 0.3), (0.5, 1.0), (0.2, 2.0)], 1)
    )
    path = sdof_impulse_response(N_REV, PATH_FREQUENCY, PATH_ZETA)
    spall = np.fft.irfft(np.fft.rfft(true_wdd(start)) * np.fft.rfft(path), N_REV)
    return mesh + 0.3 * spall + noise * np.random.default_rng(seed).standard_normal(N_REV)


def best_regularised_wdd(start: int, regularisation: float) -> np.ndarray:
    """What the regularised division gives with the *true* path: the best any estimate can do."""
    spectrum = np.fft.rfft(true_wdd(start))
    spectrum[::TEETH] = 0.0
    path = np.fft.rfft(sdof_impulse_response(N_REV, PATH_FREQUENCY, PATH_ZETA))
    path /= np.max(np.abs(path))
    gain = np.abs(path) ** 2 / (np.abs(path) ** 2 + regularisation)
    return np.fft.irfft(spectrum * gain, N_REV)


@pytest.mark.parametrize("start", [500, 1100])
def test_estimate_wdd_noise_free(start: int) -> None:
    estimate = wdd.estimate_wdd(synthetic_average(start, noise=0.0), TEETH, n_modes=1)
    assert estimate.wdd.shape == (N_REV,)
    assert estimate.residual.shape == (N_REV,)
    assert estimate.impulse_response.shape == (SAMPLES_PER_MESH,)
    # the well is where the spall is: its entry (or exit) event, within a sample
    peak = int(np.argmax(np.abs(estimate.wdd)))
    assert start - 1 <= peak <= start + SPALL_SAMPLES + 2
    assert correlation(estimate.wdd, best_regularised_wdd(start, 1e-2)) > 0.95
    assert correlation(estimate.wdd, true_wdd(start)) > 0.8
    # the transfer path: the right mode, its impulse response shape
    (mode,) = estimate.modes
    assert mode.frequency_cycles_per_sample == pytest.approx(PATH_FREQUENCY, rel=0.05)
    assert mode.frequency_orders == pytest.approx(PATH_FREQUENCY * N_REV, rel=0.05)
    assert 0.05 < mode.damping_ratio < 0.15
    truth = sdof_impulse_response(SAMPLES_PER_MESH, PATH_FREQUENCY, PATH_ZETA)
    assert correlation(estimate.impulse_response, truth) > 0.9


def test_estimate_wdd_with_small_noise_and_two_modes() -> None:
    start = 700
    estimate = wdd.estimate_wdd(synthetic_average(start, noise=0.002, seed=3), TEETH)
    assert len(estimate.modes) == 2
    peak = int(np.argmax(np.abs(estimate.wdd)))
    assert start - 1 <= peak <= start + SPALL_SAMPLES + 2
    assert correlation(estimate.wdd, best_regularised_wdd(start, 1e-2)) > 0.8


def test_residual_has_no_mesh_harmonics_and_division_is_bounded() -> None:
    average = synthetic_average(300, noise=0.001)
    for regularisation in (1e-1, 1e-2, 1e-6):
        estimate = wdd.estimate_wdd(average, TEETH, n_modes=1, regularisation=regularisation)
        residual_spectrum = np.fft.rfft(estimate.residual)
        assert np.max(np.abs(residual_spectrum[::TEETH])) < 1e-10
        # |H|/(|H|² + λ) <= 1/(2√λ): no bin is amplified more than that
        gain = np.abs(np.fft.rfft(estimate.wdd)) / np.maximum(np.abs(residual_spectrum), 1e-300)
        keep = np.abs(residual_spectrum) > 1e-9
        assert np.all(gain[keep] <= 1 / (2 * math.sqrt(regularisation)) * (1 + 1e-9))
        assert np.all(np.isfinite(estimate.wdd))


def test_estimate_wdd_rejects_bad_input() -> None:
    theta = 2 * np.pi * np.arange(N_REV) / N_REV
    with pytest.raises(ValueError, match="besides the mesh"):
        wdd.estimate_wdd(np.cos(TEETH * theta), TEETH)
    average = synthetic_average(500, noise=0.0)
    with pytest.raises(ValueError, match="regularisation"):
        wdd.estimate_wdd(average, TEETH, regularisation=0.0)
    with pytest.raises(ValueError, match="segment_samples"):
        wdd.estimate_wdd(average, TEETH, n_modes=4, segment_samples=8)
    with pytest.raises(ValueError, match="resolve"):
        wdd.estimate_wdd(average, N_REV // 2)
    with pytest.raises(ValueError, match="1-D"):
        wdd.estimate_wdd(np.stack([average, average]), TEETH)


@pytest.mark.parametrize(("tooth", "spall_width_deg"), [(16, 2.8125), (5, 1.5)])
def test_estimate_wdd_on_a_simulated_spall(tooth: int, spall_width_deg: float) -> None:
    """dsp.synthetic's exact pinion average (20 teeth, mode 2400 Hz = 144 orders at 1000 rpm,
    ζ = 0.05) plus noise: W'' peaks on the spalled tooth's pitch angle, the mode is found."""
    from dsp.synthetic import synthetic_gear_record

    n_rev, teeth = 1280, 20
    record = synthetic_gear_record(
        duration_s=0.2, spall_tooth=tooth, spall_width_deg=spall_width_deg, seed=1
    )
    noise = 0.005 * np.random.default_rng(14).standard_normal(n_rev)
    average = record.true_pinion_average(n_rev) + noise
    estimate = wdd.estimate_wdd(average, teeth)
    peak_deg = int(np.argmax(np.abs(estimate.wdd))) * 360 / n_rev
    pitch_deg = (tooth - 1) * 360 / teeth
    assert abs((peak_deg - pitch_deg + 180) % 360 - 180) < 3.0  # half a tooth pitch is 9°
    dominant = max(estimate.modes, key=lambda mode: mode.amplitude)
    assert dominant.frequency_orders == pytest.approx(144.0, rel=0.06)
    assert 0.02 < dominant.damping_ratio < 0.08
