"""Known-answer tests of the classic gear metrics (dsp.metrics).

References are independent of the implementation: values worked out by hand on tiny signals,
exact rational arithmetic (``fractions``) for the moment ratios, ``scipy.stats.kurtosis``
(``fisher=False``) and ``scipy.signal.hilbert`` as oracles.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
import scipy.signal
import scipy.stats

from dsp import metrics
from gearwatch.floor.results import AVERAGE_METRIC_NAMES

SPIKE = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 4.0]
ALTERNATING = [1.0, -1.0, 1.0, -1.0]


def exact_standardised_moment(samples: list[float], order: int) -> float:
    """``N^(k/2−1)·Σ(x−x̄)^k / (Σ(x−x̄)²)^(k/2)`` in exact rational arithmetic (k even)."""
    values = [Fraction(v) for v in samples]
    n = len(values)
    mean = sum(values, Fraction(0)) / n
    sum_k = sum(((v - mean) ** order for v in values), Fraction(0))
    sum_2 = sum(((v - mean) ** 2 for v in values), Fraction(0))
    half = order // 2
    return float(Fraction(n) ** (half - 1) * sum_k / sum_2**half)


def orders(n_samples: int) -> np.ndarray:
    return 2 * np.pi * np.arange(n_samples) / n_samples


# ------------------------------------------------------------------ rms, peak, crest, kurtosis


def test_alternating_signal_by_hand() -> None:
    assert metrics.rms(ALTERNATING) == 1.0
    assert metrics.peak(ALTERNATING) == 1.0
    assert metrics.crest_factor(ALTERNATING) == 1.0
    assert metrics.kurtosis(ALTERNATING) == 1.0
    assert metrics.m6a(ALTERNATING) == 1.0
    assert metrics.m8a(ALTERNATING) == 1.0


def test_single_spike_by_hand() -> None:
    # N = 8, one sample of 4: RMS = sqrt(16/8), crest = sqrt(N), kurtosis = (N² − 3N + 3)/(N − 1).
    assert metrics.rms(SPIKE) == pytest.approx(math.sqrt(2.0), rel=1e-15)
    assert metrics.peak(SPIKE) == 4.0
    assert metrics.crest_factor(SPIKE) == pytest.approx(math.sqrt(8.0), rel=1e-15)
    assert metrics.kurtosis(SPIKE) == pytest.approx(43.0 / 7.0, rel=1e-14)


def test_spike_higher_moments_match_exact_arithmetic() -> None:
    assert metrics.m6a(SPIKE) == pytest.approx(exact_standardised_moment(SPIKE, 6), rel=1e-13)
    assert metrics.m8a(SPIKE) == pytest.approx(exact_standardised_moment(SPIKE, 8), rel=1e-13)
    assert metrics.fm4(SPIKE) == pytest.approx(exact_standardised_moment(SPIKE, 4), rel=1e-13)
    # by hand, N = 8: deviations are −1/2 (7 times) and 7/2, m2 = 7/4, m6 = (7/64 + (7/2)⁶)/8
    assert metrics.m6a(SPIKE) == pytest.approx(((7 / 64) + (7 / 2) ** 6) / 8 / (7 / 4) ** 3, rel=1e-13)


def test_sine_over_whole_periods() -> None:
    x = np.cos(3 * orders(64))
    assert metrics.rms(x) == pytest.approx(1 / math.sqrt(2), rel=1e-14)
    assert metrics.peak(x) == pytest.approx(1.0, rel=1e-15)
    assert metrics.crest_factor(x) == pytest.approx(math.sqrt(2), rel=1e-14)
    assert metrics.kurtosis(x) == pytest.approx(1.5, rel=1e-13)
    assert metrics.m6a(x) == pytest.approx(2.5, rel=1e-13)  # E[cos⁶]/E[cos²]³ = (5/16)/(1/8)
    assert metrics.m8a(x) == pytest.approx(35 / 8, rel=1e-13)  # (35/128)/(1/16)


def test_kurtosis_matches_scipy_on_batched_data_along_any_axis() -> None:
    rng = np.random.default_rng(1)
    data = rng.standard_t(df=5, size=(3, 4, 257))
    expected = scipy.stats.kurtosis(data, axis=-1, fisher=False)
    np.testing.assert_allclose(metrics.kurtosis(data), expected, rtol=1e-12)
    moved = np.moveaxis(data, -1, 0)
    np.testing.assert_allclose(metrics.kurtosis(moved, axis=0), expected, rtol=1e-12)
    np.testing.assert_allclose(metrics.fm4(data), expected, rtol=1e-12)


def test_higher_moments_match_scipy_moment_ratios() -> None:
    rng = np.random.default_rng(2)
    data = rng.standard_normal((2, 300)) ** 3
    var = np.var(data, axis=-1)
    m6 = scipy.stats.moment(data, moment=6, axis=-1)
    m8 = scipy.stats.moment(data, moment=8, axis=-1)
    np.testing.assert_allclose(metrics.m6a(data), m6 / var**3, rtol=1e-10)
    np.testing.assert_allclose(metrics.m8a(data), m8 / var**4, rtol=1e-10)


def test_gaussian_reference_values() -> None:
    x = np.random.default_rng(3).standard_normal(2**17)
    assert metrics.kurtosis(x) == pytest.approx(3.0, abs=0.1)
    assert metrics.m6a(x) == pytest.approx(15.0, rel=0.1)
    assert metrics.m8a(x) == pytest.approx(105.0, rel=0.25)


def test_huge_values_do_not_overflow() -> None:
    square = 1e300 * np.array(ALTERNATING * 4)
    assert metrics.m8a(square) == pytest.approx(1.0, rel=1e-14)
    assert metrics.kurtosis(square) == pytest.approx(1.0, rel=1e-14)
    assert metrics.na4(1e150 * np.array(ALTERNATING), 1e300) == pytest.approx(1.0, rel=1e-14)


# ------------------------------------------------------------------ degenerate inputs


@pytest.mark.parametrize("value", [0.0, 0.1, -7.3, 1e200])
def test_constant_signals_give_zero_not_nan(value: float) -> None:
    x = np.full(64, value)
    result = metrics.gear_metrics(x, x, x, x, teeth=4)
    assert set(result) == set(AVERAGE_METRIC_NAMES)
    for name in ("kurtosis", "fm0", "fm4", "na4", "nb4", "m6a", "m8a"):
        assert result[name] == 0.0, name
    if value == 0.0:
        assert result["crest"] == 0.0
        assert result["er"] == 0.0
    else:
        assert result["crest"] == pytest.approx(1.0)
        assert result["er"] == pytest.approx(1.0)
    assert all(np.isfinite(v) for v in result.values())


def test_zero_baseline_and_zero_regular_give_zero() -> None:
    x = np.cos(5 * orders(64))
    assert metrics.na4(x, baseline_variance=0.0) == 0.0
    assert metrics.nb4(x, 5, baseline_variance=0.0) == 0.0
    assert metrics.energy_ratio(x, np.zeros(64)) == 0.0


def test_bad_inputs_raise_value_error() -> None:
    with pytest.raises(ValueError, match="NaN"):
        metrics.rms([1.0, float("nan")])
    with pytest.raises(ValueError, match="empty"):
        metrics.kurtosis(np.zeros((3, 0)))
    with pytest.raises(ValueError, match="scalar"):
        metrics.peak(1.0)
    with pytest.raises(ValueError, match="non-negative"):
        metrics.na4(ALTERNATING, baseline_variance=-1.0)
    with pytest.raises(ValueError, match="positive integer"):
        metrics.fm0(np.zeros(64), 0)
    with pytest.raises(ValueError, match="positive integer"):
        metrics.fm0(np.zeros(64), 2.5)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="not resolved"):
        metrics.fm0(np.zeros(64), 33)
    with pytest.raises(ValueError, match="not resolved"):
        metrics.nb4(np.zeros(64), 32)
    with pytest.raises(ValueError, match="band_orders"):
        metrics.nb4(np.ones(64), 4, band_orders=-1)


# ------------------------------------------------------------------ FM0


def test_fm0_pure_mesh_sine_is_two() -> None:
    assert metrics.fm0(np.cos(4 * orders(64)), 4) == pytest.approx(2.0, rel=1e-13)


def test_fm0_two_harmonics_by_hand() -> None:
    # cos u + 0.5 cos 2u: max 1.5 at u = 0, min −0.75 at cos u = −1/2 (sampled: 24 per mesh).
    u = 4 * orders(96)
    x = np.cos(u) + 0.5 * np.cos(2 * u + 0.0)
    assert metrics.fm0(x, 4) == pytest.approx(2.25 / 1.5, rel=1e-13)


def test_fm0_counts_the_nyquist_harmonic_once() -> None:
    x = np.array([1.0, -1.0] * 4)  # order 4 = Nyquist of 8 samples, amplitude 1
    assert metrics.fm0(x, 4) == pytest.approx(2.0, rel=1e-14)
    assert metrics.fm0(x, 2) == pytest.approx(2.0, rel=1e-14)  # harmonic n = 2 of 2 teeth


def test_fm0_non_mesh_content_raises_numerator_only() -> None:
    theta = orders(128)
    mesh = np.cos(8 * theta)
    shaft = 0.5 * np.sin(theta)
    assert metrics.fm0(mesh + shaft, 8) > metrics.fm0(mesh, 8) + 0.5
    assert metrics.fm0(shaft, 8) == 0.0  # no mesh harmonic at all: undefined, reported as 0


def test_fm0_batched_matches_loop() -> None:
    rng = np.random.default_rng(4)
    data = rng.standard_normal((2, 3, 120))
    batched = metrics.fm0(data, 6)
    assert isinstance(batched, np.ndarray) and batched.shape == (2, 3)
    for i in range(2):
        for j in range(3):
            assert batched[i, j] == pytest.approx(metrics.fm0(data[i, j], 6), rel=1e-14)
    np.testing.assert_allclose(metrics.fm0(data.T, 6, axis=0), batched.T, rtol=1e-14)


# ------------------------------------------------------------------ NA4


def decker_na4(records: list[np.ndarray]) -> float:
    """NA4 of the last record, written literally from the source's double sum."""
    current = records[-1]
    n = current.size
    numerator = n * np.sum((current - current.mean()) ** 4)
    denominator = np.mean([np.sum((r - r.mean()) ** 2) for r in records]) ** 2
    return float(numerator / denominator)


def test_na4_by_hand() -> None:
    assert metrics.na4(ALTERNATING) == 1.0  # own variance: the kurtosis
    assert metrics.na4(ALTERNATING, baseline_variance=0.5) == pytest.approx(4.0, rel=1e-15)
    assert metrics.na4(ALTERNATING, baseline_variance=2.0) == pytest.approx(0.25, rel=1e-15)


def test_na4_without_baseline_is_the_kurtosis() -> None:
    r = np.random.default_rng(5).standard_normal((4, 200))
    np.testing.assert_allclose(
        metrics.na4(r), scipy.stats.kurtosis(r, axis=-1, fisher=False), rtol=1e-12
    )


def test_na4_running_baseline_matches_the_literal_formula() -> None:
    rng = np.random.default_rng(6)
    records = [(1.0 + 0.3 * day) * rng.standard_normal(256) for day in range(6)]
    variances: list[float] = []
    for day, residual in enumerate(records):
        variances.append(float(np.var(residual)))
        baseline = float(np.mean(variances))
        expected = decker_na4(records[: day + 1])
        assert metrics.na4(residual, baseline) == pytest.approx(expected, rel=1e-12)
    # a growing residual on a fixed baseline grows NA4 as amplitude⁴
    first = records[0]
    base = float(np.var(first))
    assert metrics.na4(2 * first, base) == pytest.approx(16 * metrics.kurtosis(first), rel=1e-12)


def test_na4_batched_baseline_broadcasts() -> None:
    r = np.random.default_rng(7).standard_normal((3, 100))
    baselines = np.array([0.5, 1.0, 2.0])
    batched = metrics.na4(r, baselines)
    for i in range(3):
        assert batched[i] == pytest.approx(metrics.na4(r[i], baselines[i]), rel=1e-14)


# ------------------------------------------------------------------ NB4 and its envelope


def am_signal(n_samples: int, teeth: int, depth: float) -> np.ndarray:
    theta = orders(n_samples)
    return (1 + depth * np.cos(theta)) * np.cos(teeth * theta)


def test_envelope_of_am_mesh_is_the_modulation() -> None:
    x = am_signal(256, 16, 0.4)
    env = metrics.mesh_band_envelope(x, 16)
    np.testing.assert_allclose(env, 1 + 0.4 * np.cos(orders(256)), atol=1e-12)
    assert metrics.envelope_variance(x, 16) == pytest.approx(0.4**2 / 2, rel=1e-12)
    assert metrics.nb4(x, 16) == pytest.approx(1.5, rel=1e-12)  # sine envelope
    # with the variance of a baseline half as large, NB4 = m4/σ_b⁴ = 1.5·σ⁴/(σ²/2)² = 6
    assert metrics.nb4(x, 16, 0.4**2 / 4) == pytest.approx(6.0, rel=1e-12)


def test_envelope_matches_scipy_hilbert_of_the_band_passed_signal() -> None:
    rng = np.random.default_rng(8)
    n, teeth, band = 512, 20, 6
    x = rng.standard_normal(n)
    spectrum = np.fft.rfft(x)
    k = np.arange(spectrum.size)
    spectrum[np.abs(k - teeth) > band] = 0.0
    band_passed = np.fft.irfft(spectrum, n)
    expected = np.abs(scipy.signal.hilbert(band_passed))
    got = metrics.mesh_band_envelope(x, teeth, band_orders=band)
    np.testing.assert_allclose(got, expected, atol=1e-12)


def test_default_band_excludes_shaft_orders_and_second_mesh_harmonic() -> None:
    theta = orders(256)
    carrier = np.cos(16 * theta)
    outside = carrier + 0.5 * np.cos(theta) + 0.5 * np.cos(32 * theta) + 0.3 * np.cos(24 * theta)
    # order 24 is |24 − 16| = 8 > (16 − 1)//2 = 7: outside the default band, inside ±8
    assert metrics.envelope_variance(outside, 16) == 0.0
    assert metrics.nb4(outside, 16) == 0.0
    assert metrics.envelope_variance(outside, 16, band_orders=8) > 0.01


def test_nb4_running_baseline_and_batch() -> None:
    records = np.stack([am_signal(128, 8, depth) for depth in (0.1, 0.2, 0.3)])
    variances = metrics.envelope_variance(records, 8)
    assert isinstance(variances, np.ndarray)
    np.testing.assert_allclose(variances, np.array([0.1, 0.2, 0.3]) ** 2 / 2, rtol=1e-12)
    baseline = float(np.mean(variances))
    envelope = 1 + 0.3 * np.cos(orders(128))
    expected = np.mean((envelope - envelope.mean()) ** 4) / baseline**2
    assert metrics.nb4(records[2], 8, baseline) == pytest.approx(expected, rel=1e-12)
    np.testing.assert_allclose(
        metrics.nb4(records.T, 8, axis=0), [metrics.nb4(r, 8) for r in records], rtol=1e-14
    )


# ------------------------------------------------------------------ energy ratio, gear_metrics


def test_energy_ratio_by_hand() -> None:
    assert metrics.energy_ratio([0.5, -0.5], [2.0, -2.0]) == 0.25
    theta = orders(64)
    assert metrics.energy_ratio(0.2 * np.sin(3 * theta), np.cos(8 * theta)) == pytest.approx(0.2)


def test_gear_metrics_keys_and_values() -> None:
    rng = np.random.default_rng(9)
    theta = orders(240)
    regular = np.cos(12 * theta) + 0.3 * np.cos(24 * theta)
    difference = 0.05 * rng.standard_normal(240)
    difference[100] += 1.0
    residual = difference + 0.1 * np.cos(theta)
    average = regular + residual
    result = metrics.gear_metrics(
        average, residual, difference, regular, 12, na4_baseline_variance=0.02,
        nb4_baseline_variance=0.01,
    )
    assert tuple(result) == AVERAGE_METRIC_NAMES
    assert result["rms"] == metrics.rms(average)
    assert result["peak"] == metrics.peak(average)
    assert result["crest"] == metrics.crest_factor(average)
    assert result["kurtosis"] == metrics.kurtosis(average)
    assert result["fm0"] == metrics.fm0(average, 12)
    assert result["fm4"] == metrics.fm4(difference)
    assert result["na4"] == metrics.na4(residual, 0.02)
    assert result["nb4"] == metrics.nb4(average, 12, 0.01)
    assert result["m6a"] == metrics.m6a(difference)
    assert result["m8a"] == metrics.m8a(difference)
    assert result["er"] == metrics.energy_ratio(difference, regular)
    assert all(isinstance(v, float) for v in result.values())
    # the spike in the difference signal is what FM4 is for
    assert result["fm4"] > 10.0


def test_gear_metrics_batched() -> None:
    rng = np.random.default_rng(10)
    signals = rng.standard_normal((4, 3, 96))
    result = metrics.gear_metrics(*signals, teeth=6)
    for name, value in result.items():
        assert isinstance(value, np.ndarray) and value.shape == (3,), name
    single = metrics.gear_metrics(*signals[:, 1], teeth=6)
    for name in AVERAGE_METRIC_NAMES:
        assert result[name][1] == pytest.approx(single[name], rel=1e-13), name


# ------------------------------------------------------------------ on a simulated campaign


def test_spall_raises_the_difference_signal_metrics_on_a_synthetic_campaign() -> None:
    """Healthy days then a growing spall on tooth 16 (dsp.synthetic's exact averages + noise).

    The NA4/NB4 baselines are the running means of the per-record variances, as the pipeline
    keeps them. FM4/M6A/NA4 stay near their Gaussian values while healthy and rise with the spall.
    """
    from dsp import tsa
    from dsp.synthetic import synthetic_gear_record

    n_rev, teeth = 1280, 20
    rng = np.random.default_rng(13)
    healthy = synthetic_gear_record(duration_s=0.2, seed=1).true_pinion_average(n_rev)
    residual_variances: list[float] = []
    envelope_variances: list[float] = []
    results = []
    for depth in (None, None, None, 0.2):
        average = healthy
        if depth is not None:
            record = synthetic_gear_record(duration_s=0.2, spall_tooth=16, spall_depth=depth, seed=1)
            average = record.true_pinion_average(n_rev)
        average = average + 0.01 * rng.standard_normal(n_rev)
        residual = tsa.residual_signal(average, teeth)
        residual_variances.append(float(np.var(residual)))
        envelope_variances.append(float(metrics.envelope_variance(average, teeth)))
        results.append(
            metrics.gear_metrics(
                average,
                residual,
                tsa.difference_signal(average, teeth),
                tsa.regular_signal(average, teeth),
                teeth,
                na4_baseline_variance=float(np.mean(residual_variances)),
                nb4_baseline_variance=float(np.mean(envelope_variances)),
            )
        )
    *healthy_days, spalled = results
    for day in healthy_days:
        assert 2.0 < day["fm4"] < 4.5 and 2.0 < day["na4"] < 4.5
    assert spalled["fm4"] > 10.0
    assert spalled["na4"] > 50.0
    assert spalled["m6a"] > 10 * max(day["m6a"] for day in healthy_days)
    assert spalled["nb4"] > max(day["nb4"] for day in healthy_days)
    assert spalled["er"] > 1.5 * max(day["er"] for day in healthy_days)
    # the TSA's own statistics barely move: the mesh dominates them
    assert spalled["kurtosis"] == pytest.approx(healthy_days[0]["kurtosis"], rel=0.02)


# ------------------------------------------------------------------ one-pass raw-signal statistics


@pytest.mark.parametrize("shift", [0.0, 3.0, -250.0])
def test_extremes_and_moment_sums_against_numpy(shift: float) -> None:
    x = 250.0 + np.random.default_rng(5).standard_normal(10_001) ** 3
    top, bottom, sums = metrics.extremes_and_moment_sums(x, shift)
    assert (top, bottom) == (x.max(), x.min())
    y = x - shift
    np.testing.assert_allclose(sums, [y.sum(), (y**2).sum(), (y**3).sum(), (y**4).sum()], rtol=1e-9)


def test_extremes_and_moment_sums_flag_nan_and_inf() -> None:
    x = np.zeros(100)
    x[37] = np.nan
    top, bottom, _ = metrics.extremes_and_moment_sums(x)
    assert np.isnan(top) and np.isnan(bottom)
    x[37] = -np.inf
    top, bottom, _ = metrics.extremes_and_moment_sums(x)
    assert top == 0.0 and bottom == -np.inf
