"""Moving cepstrum integral: closed form vs the one-FFT-per-window oracle, conventions, forms."""

from __future__ import annotations

import numpy as np
import pytest

from dsp.cepstrum import real_cepstrum
from dsp.mci import (
    DEFAULT_MCI_FORM,
    MciResult,
    moving_cepstrum_integral,
    moving_cepstrum_integral_reference,
    window_log_terms,
)
from dsp.teeth import per_tooth_mci_depth, tooth_at_angle, worst_tooth
from tests.dsp.mci_signals import random_spalled_average, spalled_average


def mesh_signal(samples_per_rev: int, samples_per_mesh: int, phase: float = 0.3) -> np.ndarray:
    angle = 2 * np.pi * np.arange(samples_per_rev) / samples_per_mesh
    return np.cos(angle + phase) + 0.5 * np.cos(2 * angle + 2 * phase) + 0.2 * np.sin(3 * angle)


@pytest.mark.parametrize(
    ("revolution", "window"), [(1280, 64), (300, 31), (128, 2), (96, 96), (257, 40)]
)
def test_fast_literal_equals_one_fft_per_window_reference(revolution: int, window: int) -> None:
    rng = np.random.default_rng(revolution + window)
    average = rng.standard_normal(revolution) + 0.2
    fast = moving_cepstrum_integral(average, window, form="literal")
    reference = moving_cepstrum_integral_reference(average, window)
    np.testing.assert_allclose(fast.raw, reference.raw, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fast.filtered, reference.filtered, rtol=0, atol=1e-9)
    assert reference.form == "literal" and reference.median_width == 2 * window - 1


def test_reference_sums_the_cepstrum_of_the_centred_window() -> None:
    # independent of both implementations: cut window i by hand, sum its cepstrum from 1 on
    average = np.random.default_rng(1).standard_normal(200)
    window = 20
    raw = moving_cepstrum_integral_reference(average, window).raw
    for i in (0, 7, 99, 190, 199):
        segment = np.take(average, np.arange(i - 10, i + 10), mode="wrap")
        expected = np.fft.ifft(np.log(np.abs(np.fft.fft(segment)))).real[1:].sum()
        np.testing.assert_allclose(raw[i], expected, atol=1e-12)


def test_fast_literal_equals_reference_on_zero_mean_mesh_with_floored_window_sums() -> None:
    # one mesh period per window: Σ window is exactly 0 up to rounding, so ln|X[0]| is floored
    average = mesh_signal(640, 64) + 1e-3 * np.random.default_rng(2).standard_normal(640)
    average -= average.mean()
    fast = moving_cepstrum_integral(average, 64, form="literal")
    reference = moving_cepstrum_integral_reference(average, 64)
    np.testing.assert_allclose(fast.raw, reference.raw, rtol=0, atol=1e-6)
    assert np.all(np.isfinite(fast.raw))


def test_closed_form_terms_match_the_cepstrum_definition() -> None:
    average = np.random.default_rng(3).standard_normal(128)
    log_abs_sum, c0, log_norm = window_log_terms(average, 16)
    for i in (0, 50, 127):
        segment = np.take(average, np.arange(i - 8, i + 8), mode="wrap")
        ceps = real_cepstrum(segment)
        np.testing.assert_allclose(c0[i], ceps[0], atol=1e-12)
        np.testing.assert_allclose(log_abs_sum[i], ceps.sum(), atol=1e-12)  # Σ c = ln|X[0]|
        np.testing.assert_allclose(log_norm[i], np.log(np.linalg.norm(segment)), atol=1e-12)


@pytest.mark.parametrize("window", [64, 63])
def test_value_i_belongs_to_the_window_centred_on_sample_i(window: int) -> None:
    # a W-periodic background gives every window the same |X| (circular shifts), so the
    # curve is flat except where the window holds the added impulse (the robust form's
    # revolution-wide scale term moves the whole curve by one constant: remove it)
    revolution, event = 10 * window, 300
    background = mesh_signal(revolution, window)
    bumped = background.copy()
    bumped[event] += 0.7
    for form in ("robust", "literal"):
        flat = moving_cepstrum_integral(background, window, form=form, median_width=1).raw
        assert np.ptp(flat) < 1e-9
        raw = moving_cepstrum_integral(bumped, window, form=form, median_width=1).raw
        change = raw - flat
        changed = np.flatnonzero(np.abs(change - np.median(change)) > 1e-9)
        first = event - (window - 1 - window // 2)
        np.testing.assert_array_equal(changed, np.arange(first, event + window // 2 + 1))


def test_both_forms_are_amplitude_free() -> None:
    average = spalled_average(np.random.default_rng(4), spall_tooth=3).signal
    for form in ("robust", "literal"):
        base = moving_cepstrum_integral(average, 64, form=form)
        scaled = moving_cepstrum_integral(1e-4 * average, 64, form=form)
        np.testing.assert_allclose(scaled.raw, base.raw, rtol=0, atol=1e-9)


def test_robust_is_the_window_spectral_flatness_in_a_stationary_revolution() -> None:
    # robust = ln(√W·rms(revolution)) − c[0]; for a W-periodic average every window has the
    # revolution's rms, so it is −½·ln(GM/AM of |X[k]|²) of each window, ≥ 0
    average = mesh_signal(640, 64) + 0.05 * np.sin(2 * np.pi * 5 * np.arange(640) / 64)
    raw = moving_cepstrum_integral(average, 64, median_width=1).raw
    power = np.abs(np.fft.fft(average[:64])) ** 2
    power = np.maximum(power, 1e-20 * power.max())
    expected = -0.5 * np.log(np.exp(np.mean(np.log(power))) / np.mean(power))
    np.testing.assert_allclose(raw, expected, atol=1e-9)


def test_default_form_localises_a_spall_the_literal_form_misses() -> None:
    # notes §2: zero-mean average, spall on tooth 16 of 20 (pitch 270°); the literal MCI's
    # minimum sits where the moving window sum crosses zero, here near 50°
    assert DEFAULT_MCI_FORM == "robust"
    case = spalled_average(
        np.random.default_rng(0), spall_tooth=16, spall_amplitude=0.3, noise_rms=0.02
    )
    assert abs(case.signal.mean()) < 1e-12
    robust = moving_cepstrum_integral(case.signal, 64)
    literal = moving_cepstrum_integral(case.signal, 64, form="literal")
    assert robust.form == "robust" and literal.form == "literal"
    assert worst_tooth(per_tooth_mci_depth(robust.filtered, 20, 0.0)) == 16
    assert worst_tooth(per_tooth_mci_depth(literal.filtered, 20, 0.0)) != 16
    robust_minimum_deg = 360.0 * np.argmin(robust.filtered) / 1280
    literal_minimum_deg = 360.0 * np.argmin(literal.filtered) / 1280
    assert tooth_at_angle(robust_minimum_deg, 20, 0.0) == 16
    assert tooth_at_angle(literal_minimum_deg, 20, 0.0) != 16
    # the robust well is the seed's: centred on the event, ≈ one window wide, flat-bottomed
    well = robust.filtered < np.median(robust.filtered) - 0.5 * (
        np.median(robust.filtered) - robust.filtered.min()
    )
    centre = np.flatnonzero(well).mean()
    assert abs(centre - case.event_centre_sample) < 8
    assert 40 <= well.sum() <= 90


def test_literal_form_localises_when_the_window_sum_is_stable() -> None:
    # the seed's simulated accelerations evidently had a stable window sum: with a DC offset
    # the literal form is the paper's detector and finds the spall too
    case = spalled_average(
        np.random.default_rng(0), spall_tooth=16, spall_amplitude=0.3, noise_rms=0.02
    )
    literal = moving_cepstrum_integral(case.signal + 3.0, 64, form="literal")
    assert worst_tooth(per_tooth_mci_depth(literal.filtered, 20, 0.0)) == 16


def test_hit_rate_of_robust_and_literal_on_a_random_campaign() -> None:
    # 60 random zero-mean spalled averages (random tooth, pitch offset, width, resonance)
    rng = np.random.default_rng(2001)
    cases = [random_spalled_average(rng, noise_rms=0.03, spall_amplitude=0.3) for _ in range(60)]
    averages = np.stack([case.signal for case in cases])
    hits = {}
    for form in ("robust", "literal"):
        filtered = moving_cepstrum_integral(averages, 64, form=form).filtered
        hits[form] = np.mean(
            [
                worst_tooth(per_tooth_mci_depth(curve, 20, case.tooth1_pitch_angle_deg))
                == case.spall_tooth
                for curve, case in zip(filtered, cases, strict=True)
            ]
        )
    assert hits["robust"] >= 0.95
    assert hits["literal"] <= 0.5


def test_healthy_average_has_no_deep_well() -> None:
    healthy = spalled_average(np.random.default_rng(5), spall_tooth=1, spall_amplitude=0.0)
    spalled = spalled_average(np.random.default_rng(5), spall_tooth=1, spall_amplitude=0.3)
    healthy_depths = per_tooth_mci_depth(
        moving_cepstrum_integral(healthy.signal, 64).filtered, 20, 0.0
    )
    spalled_depths = per_tooth_mci_depth(
        moving_cepstrum_integral(spalled.signal, 64).filtered, 20, 0.0
    )
    assert spalled_depths.max() > 5 * healthy_depths.max()


def test_batched_and_axis_match_one_dimensional_calls() -> None:
    rng = np.random.default_rng(6)
    averages = rng.standard_normal((3, 2, 320))
    batched = moving_cepstrum_integral(averages, 32)
    along_first = moving_cepstrum_integral(np.moveaxis(averages, -1, 0), 32, axis=0)
    for i in range(3):
        for j in range(2):
            single = moving_cepstrum_integral(averages[i, j], 32)
            np.testing.assert_allclose(batched.raw[i, j], single.raw, atol=1e-12)
            np.testing.assert_allclose(batched.filtered[i, j], single.filtered, atol=1e-12)
            np.testing.assert_allclose(along_first.filtered[:, i, j], single.filtered, atol=1e-12)


def test_median_filter_is_circular_with_default_width_two_w_minus_one() -> None:
    average = np.random.default_rng(7).standard_normal(160)
    result = moving_cepstrum_integral(average, 16)
    assert result.median_width == 31 and result.window_samples == 16
    half = 15
    expected = [
        np.median(np.take(result.raw, np.arange(i - half, i + half + 1), mode="wrap"))
        for i in range(160)
    ]
    np.testing.assert_allclose(result.filtered, expected, atol=0)
    unfiltered = moving_cepstrum_integral(average, 16, median_width=1)
    np.testing.assert_array_equal(unfiltered.filtered, unfiltered.raw)


def test_result_is_a_frozen_record() -> None:
    result = moving_cepstrum_integral(np.random.default_rng(8).standard_normal(64), 8)
    assert isinstance(result, MciResult)
    with pytest.raises(AttributeError):
        result.form = "literal"  # type: ignore[misc]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"window_samples": 65}, "window_samples"),
        ({"window_samples": 1}, "window_samples"),
        ({"window_samples": 8, "median_width": 4}, "median_width"),
        ({"window_samples": 8, "form": "other"}, "form"),
    ],
)
def test_bad_parameters_raise_value_error(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        moving_cepstrum_integral(np.ones(64), **kwargs)  # type: ignore[arg-type]


def test_non_finite_average_raises() -> None:
    average = np.ones(64)
    average[3] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        moving_cepstrum_integral(average, 8)
    with pytest.raises(ValueError, match="1-D"):
        moving_cepstrum_integral_reference(np.ones((2, 64)), 8)


def test_all_zero_average_gives_finite_flat_curves() -> None:
    for form in ("robust", "literal"):
        result = moving_cepstrum_integral(np.zeros(128), 16, form=form)
        assert np.all(np.isfinite(result.filtered)) and np.ptp(result.filtered) == 0


@pytest.mark.parametrize("width", [1, 2, 5, 64, 127, 300])
def test_circular_median_equals_scipy_ndimage_wrap(width: int) -> None:
    """The numpy circular median (no scipy.ndimage import on the analyze path) gives exactly
    scipy.ndimage.median_filter(mode="wrap") values, ties and windows wider than a row included."""
    from scipy import ndimage

    from dsp.mci import _circular_median

    rng = np.random.default_rng(width)
    rows = np.round(rng.standard_normal((3, 257)), 1)  # rounded: many ties
    expected = np.stack([ndimage.median_filter(row, size=width, mode="wrap") for row in rows])
    np.testing.assert_array_equal(_circular_median(rows, width), expected)
