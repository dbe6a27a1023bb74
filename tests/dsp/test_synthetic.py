"""Known-answer synthetic records: the model is what it says, and the resampled-and-averaged
estimate converges to the stated true averages."""

from __future__ import annotations

import numpy as np
import pytest

from dsp.angle import angle_resample
from dsp.synthetic import synthetic_gear_record
from dsp.tach import analyze_tachometer
from dsp.tsa import synchronous_average

SPR = 1280  # 20 teeth × 64


@pytest.fixture(scope="module")
def spalled():
    # 2.7 s at 1000 rpm: > 42 pinion revolutions (2 hunting periods of 20/21).
    return synthetic_gear_record(duration_s=2.7, spall_tooth=16, noise_rms=0.0, seed=11)


def test_true_pinion_average_matches_estimate(spalled) -> None:
    rec = spalled
    revs = angle_resample(rec.acceleration, rec.sample_rate_hz, rec.pulse_times_s, 1, SPR)
    estimate = synchronous_average(revs[:42])
    truth = rec.true_pinion_average(SPR)
    # Tolerance: noise-free and over whole hunting periods, so the only errors are the phase
    # model (cubic spline through 1 pulse/rev of a ±1 % speed fluctuation, ~1e-9 rev) and the
    # quintic-spline interpolation of content tapered to zero by 6 kHz = 0.3 fs (relative error
    # ~2e-6 at 0.1 fs, where the mode is). Measured RMS ~2e-6 on a signal of RMS ~0.8; 2e-5
    # leaves a factor 10 and still fails for a 0.01-sample misalignment (1.1e-3).
    assert np.sqrt(np.mean((estimate - truth) ** 2)) < 2e-5
    assert truth.std() > 0.5


@pytest.mark.parametrize("n_revs", [10, 33])
def test_finite_average_includes_the_gear_leftover(spalled, n_revs: int) -> None:
    # Over a number of revolutions that is not a multiple of 21 the gear component does not
    # cancel; true_pinion_average(spr, n_revs) is the exact finite average (leftover included).
    rec = spalled
    revs = angle_resample(rec.acceleration, rec.sample_rate_hz, rec.pulse_times_s, 1, SPR)
    estimate = synchronous_average(revs[:n_revs])
    rms = lambda e: float(np.sqrt(np.mean(e**2)))  # noqa: E731
    assert rms(estimate - rec.true_pinion_average(SPR, n_revs)) < 2e-5
    assert rms(estimate - rec.true_pinion_average(SPR)) > 1e-2  # the leftover is real
    gear_revs = angle_resample(
        rec.acceleration, rec.sample_rate_hz, rec.pulse_times_s, 1, 21 * 64, shaft_ratio=20 / 21
    )
    gear_estimate = synchronous_average(gear_revs[:n_revs])
    assert rms(gear_estimate - rec.true_gear_average(21 * 64, n_revs)) < 2e-5
    assert rms(gear_estimate - rec.true_gear_average(21 * 64)) > 1e-3


def test_true_gear_average_matches_estimate(spalled) -> None:
    rec = spalled
    revs = angle_resample(
        rec.acceleration, rec.sample_rate_hz, rec.pulse_times_s, 1, 21 * 64, shaft_ratio=20 / 21
    )
    estimate = synchronous_average(revs[:40])  # 40 gear revs = 2 hunting periods
    truth = rec.true_gear_average(21 * 64)
    assert np.sqrt(np.mean((estimate - truth) ** 2)) < 2e-5
    # The spall is pinion-periodic: only its orders that are multiples of 20 (= gear orders
    # multiple of 21) reach the gear average, a small part of it (measured RMS 0.005).
    healthy = synthetic_gear_record(duration_s=0.1, spall_tooth=None, seed=11)
    assert np.sqrt(np.mean((truth - healthy.true_gear_average(21 * 64)) ** 2)) < 0.01


def test_noise_averages_down_as_expected() -> None:
    noise = 0.2
    rec = synthetic_gear_record(duration_s=4.0, spall_tooth=3, noise_rms=noise, seed=4)
    revs = angle_resample(rec.acceleration, rec.sample_rate_hz, rec.pulse_times_s, 1, SPR)[:63]
    error = synchronous_average(revs) - rec.true_pinion_average(SPR)
    # White noise interpolated to the grid keeps (most of) its variance and averages as 1/√n:
    # expected RMS ≈ 0.2/√63 = 0.025 (the RMS over 1280 nearly independent samples scatters by
    # ~2 %); bounds [0.5, 1.2] × that.
    expected = noise / np.sqrt(63)
    assert 0.5 * expected < np.sqrt(np.mean(error**2)) < 1.2 * expected


def test_acceleration_is_the_stated_angle_domain_model() -> None:
    rec = synthetic_gear_record(duration_s=0.8, noise_rms=0.0, tooth1_pitch_angle_deg=5.0, seed=3)
    t = np.arange(rec.acceleration.size) / rec.sample_rate_hz
    theta = rec.pinion_angle_rev(t)
    gamma = theta * 20 / 21
    expected = (
        1.0 * np.cos(2 * np.pi * 20 * (theta - 5 / 360))
        + 0.5 * np.cos(2 * np.pi * 40 * (theta - 5 / 360))
        + 0.25 * np.cos(2 * np.pi * 60 * (theta - 5 / 360))
        + 0.3 * np.cos(2 * np.pi * gamma + 0.7)
    )
    np.testing.assert_allclose(rec.acceleration, expected, atol=1e-9)


def test_speed_profile_and_pulses() -> None:
    rec = synthetic_gear_record(duration_s=10.0, speed_fluctuation=0.01, seed=8)
    theta_at_pulses = rec.pinion_angle_rev(rec.pulse_times_s)
    np.testing.assert_allclose(theta_at_pulses, np.arange(rec.pulse_times_s.size), atol=1e-9)
    assert rec.pinion_angle_rev(np.array([0.0]))[0] < 0 < rec.pulse_times_s[0]
    tach = analyze_tachometer(rec.pulse_times_s, 1)
    # f(t) = f0 (1 + 0.01 sin(2πt/5)) over two periods: per-revolution speeds span ≈ ±1 %.
    assert tach.speed_variation == pytest.approx(0.02, rel=0.05)
    assert tach.mean_rpm == pytest.approx(1000.0, rel=2e-3)
    # TTL: 0/5 V, exactly 2.5 V at each rising edge (midpoint of the 2-sample ramp).
    assert set(np.unique(rec.tach_waveform[rec.tach_waveform % 5 == 0])) == {0.0, 5.0}
    n = rec.pulse_times_s * rec.sample_rate_hz
    i = np.floor(n).astype(int)
    at_edge = rec.tach_waveform[i] + (n - i) * (rec.tach_waveform[i + 1] - rec.tach_waveform[i])
    np.testing.assert_allclose(at_edge, 2.5, atol=1e-9)


def test_tach_on_gear_with_two_pulses_per_rev() -> None:
    rec = synthetic_gear_record(
        duration_s=2.7, tach_shaft="gear", pulses_per_rev=2, spall_tooth=9, noise_rms=0.0, seed=6
    )
    gear_angle = rec.pinion_angle_rev(rec.pulse_times_s) * 20 / 21
    np.testing.assert_allclose(gear_angle * 2, np.arange(gear_angle.size), atol=1e-9)
    assert rec.pinion_ratio == pytest.approx(21 / 20)
    revs = angle_resample(
        rec.acceleration,
        rec.sample_rate_hz,
        rec.pulse_times_s,
        2,
        SPR,
        shaft_ratio=rec.pinion_ratio,
    )
    estimate = synchronous_average(revs[:42])
    assert np.sqrt(np.mean((estimate - rec.true_pinion_average(SPR)) ** 2)) < 2e-5


def test_spall_coefficients_match_a_time_domain_construction() -> None:
    # Independent construction of the seed's signature: W'' * h = h'(θ-θa) - h'(θ-θb), sampled on
    # a fine grid, FFT, same taper. Compares with the closed-form coefficients of the record.
    kwargs = dict(duration_s=0.05, noise_rms=0.0, gear_order_amplitude=0.0, seed=0)
    spalled = synthetic_gear_record(spall_tooth=4, tooth1_pitch_angle_deg=10.0, **kwargs)
    healthy = synthetic_gear_record(spall_tooth=None, tooth1_pitch_angle_deg=10.0, **kwargs)
    spall = spalled.pinion_coefficients - healthy.pinion_coefficients

    f_rev = 1000.0 / 60.0
    omega_n = 2 * np.pi * 2400.0 / f_rev
    alpha, beta = 0.05 * omega_n, omega_n * np.sqrt(1 - 0.05**2)
    centre = (10.0 + 3 * 18.0) / 360.0
    half_width = 2.8125 / 2 / 360.0
    m = 2**18
    theta = np.arange(m) / m

    def h_prime(tau: np.ndarray) -> np.ndarray:
        tau = np.mod(tau, 1.0)  # periodised; the ring has decayed by e^-45 after one rev
        return np.exp(-alpha * tau) * (beta * np.cos(beta * tau) - alpha * np.sin(beta * tau))

    y = (
        0.3
        / omega_n
        * (h_prime(theta - centre + half_width) - h_prime(theta - centre - half_width))
    )
    orders = np.arange(spall.size)
    dft = 2 * np.fft.rfft(y)[: spall.size] / m
    taper = 0.5 + 0.5 * np.cos(np.pi * np.clip((orders - 180) / 180, 0, 1))  # 6 kHz = order 360
    reference = dft * taper
    reference[0] = 0
    scale = np.abs(reference).max()
    # Sampling the jumps of h' on the fine grid aliases into the DFT: measured 1.1e-3 of the
    # largest coefficient with 2**16 points, 1.0e-4 with 2**18 (so it is discretisation).
    assert np.abs(spall - reference).max() < 5e-4 * scale
    assert scale > 1e-3  # not comparing zeros
    # The signature's spectrum peaks at the structural mode (2.4 kHz = order 144).
    assert abs(int(np.argmax(np.abs(spall))) - 144) <= 6


def test_spall_is_at_the_tooth_pitch_angle() -> None:
    rec = synthetic_gear_record(duration_s=0.05, spall_tooth=16, tooth1_pitch_angle_deg=7.0)
    healthy = synthetic_gear_record(duration_s=0.05, spall_tooth=None, tooth1_pitch_angle_deg=7.0)
    assert rec.spall_pitch_angle_deg == pytest.approx(7.0 + 15 * 18.0)
    spall = rec.true_pinion_average(SPR) - healthy.true_pinion_average(SPR)
    angle_deg = np.arange(SPR) * 360 / SPR
    onset = angle_deg[np.argmax(np.abs(spall) > 0.1 * np.abs(spall).max())]
    # The ring starts at the window's leading edge (pitch angle - width/2), a little earlier
    # because of the band limit's smoothing.
    assert rec.spall_pitch_angle_deg - 2.8125 / 2 - 1.0 < onset <= rec.spall_pitch_angle_deg
    assert np.abs(spall).max() == pytest.approx(0.3, rel=0.35)


def test_reproducible_and_seeded() -> None:
    a = synthetic_gear_record(duration_s=0.2, seed=1)
    b = synthetic_gear_record(duration_s=0.2, seed=1)
    c = synthetic_gear_record(duration_s=0.2, seed=2)
    np.testing.assert_array_equal(a.acceleration, b.acceleration)
    assert not np.array_equal(a.acceleration, c.acceleration)
    assert a.parameters["seed"] == 1 and a.parameters["duration_s"] == 0.2
    assert a.parameters["mesh_harmonic_amplitudes"] == (1.0, 0.5, 0.25)
    rebuilt = synthetic_gear_record(**a.parameters)
    np.testing.assert_array_equal(rebuilt.acceleration, a.acceleration)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(bandwidth_hz=9950.0), "Nyquist"),
        (dict(spall_tooth=0), "spall_tooth"),
        (dict(tach_shaft="crank"), "tach_shaft"),
        (dict(speed_fluctuation=0.6), "speed_fluctuation"),
    ],
)
def test_bad_parameters(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        synthetic_gear_record(duration_s=0.1, **kwargs)
