"""Cepstra against the seed's closed forms (El Badaoui et al. 2001, eq. 16–24) and identities."""

from __future__ import annotations

import numpy as np
import pytest

from dsp.cepstrum import (
    DEFAULT_FLOOR_REL,
    complex_cepstrum,
    exponential_weighting,
    inverse_complex_cepstrum,
    power_cepstrum,
    real_cepstrum,
)
from tests.dsp.mci_signals import (
    echo_cepstrum_closed_form,
    echo_term,
    rectangular_window_second_derivative,
)


@pytest.mark.parametrize(
    ("length", "delay", "gain"),
    [
        (256, 10, 0.5),
        (256, 10, -0.9),
        (256, 10, 0.99),
        (256, 100, 0.8),
        (64, 7, -0.6),
        (255, 40, 0.7),
    ],
)
def test_echo_term_matches_eq17_with_aliasing(length: int, delay: int, gain: float) -> None:
    # delay 100 on 256 samples: k = 3 lands on 300 mod 256 = 44, k = 5 on 500 mod 256 = 244
    ceps = real_cepstrum(echo_term(length, delay, gain))
    expected = echo_cepstrum_closed_form(length, delay, gain, terms=3000)
    np.testing.assert_allclose(ceps, expected, rtol=0, atol=1e-13)


def test_echo_term_cepstrum_is_a_decreasing_alternating_comb() -> None:
    # seed Fig. 3: period τ = 10, alternating, decreasing; 250 = 25τ keeps aliases on the comb
    ceps = real_cepstrum(echo_term(250, 10, 0.6))
    peaks = ceps[10:70:10]
    assert np.all(np.sign(peaks) == np.tile([1.0, -1.0], 3))
    assert np.all(np.diff(np.abs(peaks)) < 0)
    off_comb = np.delete(ceps[1:], np.arange(9, 249, 10))
    assert np.max(np.abs(off_comb)) < 1e-13


def test_second_derivative_of_rectangular_window_is_strictly_negative_eq18_20() -> None:
    # notes §3: exponential weighting r = 0.95 moves the spectral zeros off the unit circle
    r, width, length, amplitude = 0.95, 10, 256, 2.5
    pattern = rectangular_window_second_derivative(length, width, amplitude)
    ceps = real_cepstrum(exponential_weighting(pattern, r))
    assert np.all(ceps[1:] < 0)
    # closed form: A · e_{1,−r} * e_{N,−r^N}, so ln A at 0 plus two negative echo series
    expected = echo_cepstrum_closed_form(length, 1, -r, terms=5000) + echo_cepstrum_closed_form(
        length, width, -(r**width), terms=5000
    )
    expected[0] += np.log(amplitude)
    np.testing.assert_allclose(ceps, expected, rtol=0, atol=1e-12)


def test_unweighted_second_derivative_has_exact_zeros_and_stays_finite() -> None:
    # zeros of (1 − e^{−iω})(1 − e^{−iωN}) on the 256-grid: k = 0 and k = 128 (N = 10)
    pattern = rectangular_window_second_derivative(256, 10)
    spectrum = np.abs(np.fft.fft(pattern))
    assert spectrum[0] < 1e-12 and spectrum[128] < 1e-12
    ceps = real_cepstrum(pattern)
    assert np.all(np.isfinite(ceps))
    floored = np.maximum(spectrum, DEFAULT_FLOOR_REL * spectrum.max())
    np.testing.assert_allclose(ceps[0], np.mean(np.log(floored)), rtol=1e-12)


def test_rectangular_window_matches_eq21_24() -> None:
    # weighted window A·rⁿ, n < N = A(1 − r^N z^{−N})/(1 − r z^{−1}) exactly on any DFT grid,
    # so c = ln A·δ + ceps(e_{N,−r^N}) − ceps(e_{1,−r}); r → 1 gives the seed's eq. 23
    r, width, length, amplitude = 0.95, 12, 512, 0.3
    window = np.zeros(length)
    window[:width] = amplitude
    ceps = real_cepstrum(exponential_weighting(window, r))
    expected = echo_cepstrum_closed_form(length, width, -(r**width), terms=5000) - (
        echo_cepstrum_closed_form(length, 1, -r, terms=20000)
    )
    expected[0] += np.log(amplitude)
    np.testing.assert_allclose(ceps, expected, rtol=0, atol=1e-12)
    # eq. 24's shape: ln A at 0, positive ~1/(2|k|) terms, negative at multiples of N
    assert np.isclose(ceps[0], np.log(amplitude))
    n = np.arange(1, 4 * width)
    positive = ceps[n[n % width != 0]]
    assert np.all(positive > 0)
    assert np.all(ceps[[width, 2 * width, 3 * width]] < 0)


def test_sum_of_cepstrum_after_first_sample_is_log_dc_minus_c0_on_random_data() -> None:
    rng = np.random.default_rng(7)
    signals = rng.standard_normal((50, 64)) + rng.uniform(-1, 1, (50, 1))
    ceps = real_cepstrum(signals, axis=-1)
    log_dc = np.log(np.abs(signals.sum(axis=-1)))
    np.testing.assert_allclose(ceps[:, 1:].sum(axis=-1), log_dc - ceps[:, 0], rtol=0, atol=1e-12)
    # c[0] is the log of the geometric-mean magnitude
    np.testing.assert_allclose(
        ceps[:, 0], np.mean(np.log(np.abs(np.fft.fft(signals))), axis=-1), rtol=0, atol=1e-12
    )


def test_identity_holds_with_zero_padding() -> None:
    x = np.random.default_rng(8).standard_normal(40)
    ceps = real_cepstrum(x, n_fft=128)
    assert ceps.shape == (128,)
    np.testing.assert_allclose(ceps.sum(), np.log(abs(x.sum())), rtol=0, atol=1e-12)


def test_batched_axis_matches_one_dimensional_calls() -> None:
    x = np.random.default_rng(9).standard_normal((33, 3, 2))
    batched = real_cepstrum(x, axis=0)
    assert batched.shape == x.shape
    for i in range(3):
        for j in range(2):
            np.testing.assert_allclose(batched[:, i, j], real_cepstrum(x[:, i, j]), atol=1e-14)


def test_real_cepstrum_of_complex_input_uses_the_full_spectrum() -> None:
    x = np.random.default_rng(10).standard_normal(32) + 1j * np.random.default_rng(
        11
    ).standard_normal(32)
    expected = np.fft.ifft(np.log(np.abs(np.fft.fft(x)))).real
    np.testing.assert_allclose(real_cepstrum(x), expected, atol=1e-13)


def test_power_cepstrum_is_bogert_definition_and_four_times_real_squared() -> None:
    x = np.random.default_rng(12).standard_normal((4, 128))
    independent = np.abs(np.fft.ifft(np.log(np.abs(np.fft.fft(x, axis=-1)) ** 2), axis=-1)) ** 2
    np.testing.assert_allclose(power_cepstrum(x), independent, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(power_cepstrum(x), 4 * real_cepstrum(x) ** 2, rtol=1e-12)
    assert np.all(power_cepstrum(x) >= 0)


@pytest.mark.parametrize("zeros", [np.zeros(16), np.zeros((3, 8))])
def test_all_zero_input_gives_finite_cepstra(zeros: np.ndarray) -> None:
    ceps = real_cepstrum(zeros)
    assert np.all(np.isfinite(ceps))
    assert np.all(ceps[..., 1:] == 0)
    assert np.all(np.isfinite(power_cepstrum(zeros)))
    cc, ndelay = complex_cepstrum(zeros)
    assert np.all(np.isfinite(cc)) and ndelay.shape == zeros.shape[:-1]


def test_floor_is_relative_to_the_spectrum_maximum() -> None:
    x = np.zeros(64)
    x[0], x[1] = 1.0, -1.0  # one exact zero at DC
    for floor_rel in (1e-3, 1e-10):
        ceps = real_cepstrum(1e6 * x, floor_rel=floor_rel)
        spectrum = np.abs(np.fft.fft(1e6 * x))
        expected = np.mean(np.log(np.maximum(spectrum, floor_rel * spectrum.max())))
        np.testing.assert_allclose(ceps[0], expected, rtol=1e-12)
    with pytest.raises(ValueError, match="floor_rel"):
        real_cepstrum(x, floor_rel=1.5)


def test_complex_cepstrum_of_minimum_phase_echo_is_causal_closed_form() -> None:
    length, delay, gain = 256, 9, -0.8
    ceps, ndelay = complex_cepstrum(echo_term(length, delay, gain))
    assert int(ndelay) == 0
    expected = np.zeros(length)
    for k in range(1, 3000):
        expected[(k * delay) % length] += (-1.0) ** (k + 1) * gain**k / k
    np.testing.assert_allclose(ceps, expected, rtol=0, atol=1e-12)


def test_complex_cepstrum_of_maximum_phase_echo_reports_delay_like_cceps() -> None:
    # δ + 2δ[n−5] = 2·δ[n−5]·(1 + ½δ[n+5]): linear phase of 5 samples, anticausal echo series
    length, delay, gain = 128, 5, 2.0
    ceps, ndelay = complex_cepstrum(echo_term(length, delay, gain))
    assert int(ndelay) == -delay
    expected = np.zeros(length)
    expected[0] = np.log(gain)
    for k in range(1, 2000):
        expected[(-k * delay) % length] += (-1.0) ** (k + 1) * (1 / gain) ** k / k
    np.testing.assert_allclose(ceps, expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("length", [64, 65, 1, 2, 3, 128, 127])
def test_complex_cepstrum_round_trips_with_delays(length: int) -> None:
    rng = np.random.default_rng(length)
    for shift in (0, 1, 3, length // 2):
        x = np.roll(np.r_[1.0, 0.6 * rng.standard_normal(length - 1)], shift % length)
        x *= np.sign(x.sum())  # positive DC: the documented domain (as MATLAB's cceps)
        ceps, ndelay = complex_cepstrum(x)
        np.testing.assert_allclose(inverse_complex_cepstrum(ceps, ndelay), x, atol=1e-10)


@pytest.mark.parametrize("length", [16, 17])
def test_complex_cepstrum_delay_of_shifted_impulse(length: int) -> None:
    for shift in range(6):
        ceps, ndelay = complex_cepstrum(np.roll(np.r_[1.0, np.zeros(length - 1)], shift))
        assert int(ndelay) == -shift
        np.testing.assert_allclose(ceps, 0.0, atol=1e-14)


def test_complex_cepstrum_turns_convolution_into_addition() -> None:
    # two minimum-phase factors: cepstra add, delays add
    a = echo_term(256, 3, 0.5)
    b = echo_term(256, 11, -0.7)
    product = np.fft.irfft(np.fft.rfft(a) * np.fft.rfft(b), n=256)
    ca, _ = complex_cepstrum(a)
    cb, _ = complex_cepstrum(b)
    cab, ndelay = complex_cepstrum(product)
    assert int(ndelay) == 0
    np.testing.assert_allclose(cab, ca + cb, atol=1e-12)


def test_complex_cepstrum_batched_matches_one_dimensional() -> None:
    x = np.random.default_rng(3).standard_normal((4, 50))
    x *= np.sign(x.sum(axis=-1, keepdims=True))
    ceps, ndelay = complex_cepstrum(x.T, axis=0)
    assert ceps.shape == (50, 4) and ndelay.shape == (4,)
    for i in range(4):
        single, single_delay = complex_cepstrum(x[i])
        np.testing.assert_allclose(ceps[:, i], single, atol=1e-13)
        assert ndelay[i] == single_delay
    np.testing.assert_allclose(inverse_complex_cepstrum(ceps, ndelay, axis=0), x.T, atol=1e-10)


def test_exponential_weighting_moves_echo_gain_and_spectral_zeros() -> None:
    weighted = exponential_weighting(echo_term(32, 4, -1.0), 0.9)
    np.testing.assert_allclose(weighted, echo_term(32, 4, -(0.9**4)), atol=1e-15)
    assert np.min(np.abs(np.fft.fft(weighted))) > 0.3
    batched = exponential_weighting(np.ones((5, 2)), 0.5, axis=0)
    np.testing.assert_allclose(batched[:, 1], 0.5 ** np.arange(5))
    with pytest.raises(ValueError):
        exponential_weighting(np.ones(3), 0.0)
