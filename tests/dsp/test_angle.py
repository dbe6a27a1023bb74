"""Angle resampling: known angle-domain content under a varying speed, CubicSpline comparison,
angle-domain anti-aliasing, shaft ratio, batching."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from dsp.angle import (
    angle_grid_times,
    angle_lowpass,
    angle_resample,
    angle_resample_shafts,
    samples_per_revolution,
)

FS = 20_000.0


class RunUp:
    """Shaft angle θ(t) = θ0 + f0 t + c t²/2 (revolutions): a linear speed ramp."""

    def __init__(self, f0_hz: float, rate_hz_per_s: float, theta0_rev: float) -> None:
        self.f0, self.c, self.theta0 = f0_hz, rate_hz_per_s, theta0_rev

    def angle(self, t: np.ndarray) -> np.ndarray:
        return self.theta0 + self.f0 * t + 0.5 * self.c * t**2

    def time_at(self, angle_rev: np.ndarray) -> np.ndarray:
        # Positive root of θ0 + f0 t + c t²/2 = angle.
        a, b, c = 0.5 * self.c, self.f0, self.theta0 - angle_rev
        return (-b + np.sqrt(b * b - 4 * a * c)) / (2 * a)


ORDERS = {20: (1.0, 0.0), 47: (0.5, 0.3), 140: (0.2, -1.1)}  # order: (amplitude, phase)


def angle_content(angle_rev: np.ndarray) -> np.ndarray:
    return sum(a * np.cos(2 * np.pi * k * angle_rev + p) for k, (a, p) in ORDERS.items())


def run_up_record(duration_s: float = 3.0, pulses_per_rev: int = 1):
    # 900 -> 1100 rpm in 3 s (a chirp of every order), reference pulse 0.31 rev after t = 0.
    shaft = RunUp(15.0, 20.0 / 9.0, -0.31)
    t = np.arange(round(duration_s * FS)) / FS
    last = int(np.floor(shaft.angle(t[-1]) * pulses_per_rev))
    pulses = shaft.time_at(np.arange(last + 1) / pulses_per_rev)
    return t, shaft, angle_content(shaft.angle(t)), pulses


def test_chirp_recovers_angle_domain_content() -> None:
    _, _, x, pulses = run_up_record()
    revs = angle_resample(x, FS, pulses, 1, 2048)
    assert revs.shape == (pulses.size - 1, 2048)
    expected = angle_content(np.arange(2048) / 2048)
    error = revs - expected
    # Two error sources, both measured: the cubic-spline phase model through 1 pulse/rev under
    # acceleration (~1e-8 rev inside, up to ~4e-7 rev in the two end revolutions at each end,
    # where the not-a-knot end conditions act; × ~500 rad/rev of signal slope) and the quintic
    # interpolation of order 140 at up to 2.6 kHz (≤ 1.5e-5). Signal amplitude ~1.7.
    assert np.sqrt(np.mean(error**2)) < 2e-5
    assert np.max(np.abs(error[2:-2])) < 3e-5
    assert np.max(np.abs(error)) < 3e-4


def test_interpolation_at_least_as_accurate_as_cubic_spline() -> None:
    # Same grid times for both; truth = the analytic signal at those times, so only the
    # interpolator is compared. Orders up to 140 at ≤ 18.3 rev/s: up to 2.6 kHz = 0.13 fs.
    t, shaft, x, pulses = run_up_record()
    times = angle_grid_times(pulses, 1, 2048)
    truth = angle_content(shaft.angle(times))
    ours = angle_resample(x, FS, pulses, 1, 2048)
    spline = CubicSpline(t, x)(times)
    ours_rms = np.sqrt(np.mean((ours - truth) ** 2))
    spline_rms = np.sqrt(np.mean((spline - truth) ** 2))
    assert ours_rms < 0.1 * spline_rms  # measured ratio ~0.01
    assert spline_rms > 1e-6  # the comparison is not between two zeros


def test_pulses_per_rev_and_phase_model() -> None:
    _, _, x, pulses = run_up_record(pulses_per_rev=4)
    revs = angle_resample(x, FS, pulses, 4, 1024 * 2)
    assert revs.shape[0] == (pulses.size - 1) // 4
    expected = np.broadcast_to(angle_content(np.arange(2048) / 2048), revs.shape)
    # 4 pulses/rev: the phase model error drops ~4^4 times; interpolation error remains.
    np.testing.assert_allclose(revs, expected, atol=3e-5)


def test_angle_zero_is_the_first_pulse() -> None:
    shaft = RunUp(16.0, 0.0 + 1e-9, -0.4)
    t = np.arange(40_000) / FS
    x = np.cos(2 * np.pi * shaft.angle(t))  # peak at every whole revolution after the pulse
    pulses = shaft.time_at(np.arange(31.0))
    revs = angle_resample(x, FS, pulses, 1, 1280)
    assert np.all(np.argmax(revs, axis=1) == 0)
    assert np.allclose(revs[:, 0], 1.0, atol=1e-9)


def test_shaft_ratio_tach_on_gear() -> None:
    # Tach on a 21-tooth gear, 2 pulses per gear rev; target is the 20-tooth pinion.
    pinion = RunUp(16.0, 1.0, -0.2)
    t = np.arange(60_000) / FS
    x = np.cos(2 * np.pi * 20 * pinion.angle(t)) + 0.3 * np.sin(2 * np.pi * 3 * pinion.angle(t))
    gear_angle_at_pulses = np.arange(0, int(pinion.angle(t[-1]) * 20 / 21 * 2)) / 2
    pulses = pinion.time_at(gear_angle_at_pulses * 21 / 20)
    revs = angle_resample(x, FS, pulses, 2, 1280, shaft_ratio=21 / 20)
    assert revs.shape[0] == int((pulses.size - 1) / 2 * 21 / 20)
    k = np.arange(1280) / 1280
    expected = np.cos(2 * np.pi * 20 * k) + 0.3 * np.sin(2 * np.pi * 3 * k)
    np.testing.assert_allclose(revs, np.broadcast_to(expected, revs.shape), atol=1e-5)


def test_anti_aliasing_in_the_angle_domain() -> None:
    # Constant 1000 rpm; 256 samples/rev -> 4267 Hz angular sampling < 20 kHz, angular Nyquist
    # order 128. Order 200 (3.3 kHz) would alias to order 56 without the low-pass.
    f_rev = 1000.0 / 60.0
    t = np.arange(60_000) / FS
    angle = f_rev * t - 0.25
    x = np.cos(2 * np.pi * 30 * angle) + np.cos(2 * np.pi * 200 * angle)
    pulses = (np.arange(int(angle[-1]) + 1) + 0.25) / f_rev
    revs = angle_resample(x, FS, pulses, 1, 256)
    spectrum = np.abs(np.fft.rfft(revs.mean(axis=0))) * 2 / 256
    assert spectrum[30] == pytest.approx(1.0, abs=1e-3)
    assert spectrum[56] < 1e-3
    # Without the filter (the straightforward CubicSpline at the grid times) it aliases fully.
    naive = CubicSpline(t, x)(angle_grid_times(pulses, 1, 256)).mean(axis=0)
    assert np.abs(np.fft.rfft(naive))[56] * 2 / 256 > 0.5


@pytest.mark.parametrize(("samples_per_rev", "filtered"), [(1280, False), (1024, True)])
def test_filter_only_when_angular_rate_below_time_rate(
    samples_per_rev: int, filtered: bool
) -> None:
    # 1000 rpm ± 0.5 %: 1280/rev samples at ≥ 21.2 kHz > 20 kHz (no filter, the signal is only
    # interpolated); 1024/rev at ≤ 17.1 kHz < 20 kHz (low-passed at half the lowest rate first).
    from scipy import ndimage

    shaft = RunUp(1000.0 / 60.0, 0.05, -0.5)
    t = np.arange(40_000) / FS
    x = np.random.default_rng(3).standard_normal(t.size)  # content at every frequency
    pulses = shaft.time_at(np.arange(int(shaft.angle(t[-1])) + 1.0))
    out = angle_resample(x, FS, pulses, 1, samples_per_rev)
    source = x
    if filtered:
        lowest_rate_hz = samples_per_rev / np.max(np.diff(pulses))
        source = angle_lowpass(x, FS, 0.5 * lowest_rate_hz)
    times = angle_grid_times(pulses, 1, samples_per_rev)
    expected = ndimage.map_coordinates(source, [times.ravel() * FS], order=5, mode="mirror")
    np.testing.assert_allclose(out.ravel(), expected, atol=1e-10)


def test_lowpass_response() -> None:
    # fs 1 kHz, cutoff 200 Hz: pass band to 160 Hz, roll-off width 40 Hz (25 samples).
    t = np.arange(8000) / 1000.0
    tone = lambda f: np.sin(2 * np.pi * f * t)  # noqa: E731
    passed = angle_lowpass(tone(50.0), 1000.0, 200.0) - tone(50.0)
    stopped = angle_lowpass(tone(230.0), 1000.0, 200.0)
    assert np.max(np.abs(passed[300:-300])) < 1e-6
    assert np.max(np.abs(stopped[1000:-1000])) < 1e-6
    # The ends (even reflection): approximate within a few roll-off periods only.
    assert np.max(np.abs(passed[100:-100])) < 1e-3
    assert np.max(np.abs(stopped[100:-100])) < 1e-3


def test_batched_axes_match_single_channel() -> None:
    _, _, x, pulses = run_up_record(duration_s=1.5)
    stacked = np.stack([x, 2 * x, -x])
    single = angle_resample(x, FS, pulses, 1, 512)
    out_last = angle_resample(stacked, FS, pulses, 1, 512)
    out_first = angle_resample(stacked.T, FS, pulses, 1, 512, axis=0)
    assert out_last.shape == (3, *single.shape)
    np.testing.assert_allclose(out_last[1], 2 * single, atol=1e-12)
    np.testing.assert_allclose(out_first, out_last, atol=1e-12)


def test_only_whole_revolutions_inside_the_record() -> None:
    _, _, x, pulses = run_up_record(duration_s=2.0)
    # Pulses beyond the end of the signal: revolutions needing samples past the end are dropped.
    revs = angle_resample(x[: x.size // 2], FS, pulses, 1, 256)
    assert np.all(angle_grid_times(pulses, 1, 256)[: revs.shape[0]] <= (x.size // 2 - 1) / FS)
    assert revs.shape[0] == int(np.sum(pulses <= (x.size // 2 - 1) / FS)) - 1


def test_errors() -> None:
    x = np.zeros(1000)
    with pytest.raises(ValueError, match="outside the record"):
        angle_resample(x, FS, [-0.01, 0.01, 0.02], 1, 64)
    with pytest.raises(ValueError, match="less than one whole revolution"):
        angle_resample(x, FS, [0.001, 0.002], 2, 64)
    with pytest.raises(ValueError, match="strictly increasing"):
        angle_resample(x, FS, [0.01, 0.01, 0.02], 1, 64)
    assert samples_per_revolution(20) == 1280
    assert samples_per_revolution(21, 32) == 672


def test_quintic_kernels_match_scipy_ndimage() -> None:
    # Independent implementation of the same interpolant (prefilter + evaluation), including
    # positions at and next to both ends, where the mirror boundary acts.
    from scipy import ndimage

    from dsp.splines import bspline5_at, bspline5_prefilter

    rng = np.random.default_rng(7)
    x = rng.standard_normal((2, 5000))
    positions = np.concatenate([[0.0, 0.3, 1.7, 4998.2, 4999.0], rng.uniform(0, 4999, 2000)])
    coefficients = x.copy()
    bspline5_prefilter(coefficients)
    for row in range(2):
        ref_coefficients = ndimage.spline_filter1d(x[row], order=5, mode="mirror")
        np.testing.assert_allclose(coefficients[row], ref_coefficients, atol=1e-12)
        out = np.empty(positions.size)
        bspline5_at(coefficients[row], positions, out)
        ref = ndimage.map_coordinates(
            ref_coefficients, [positions], order=5, mode="mirror", prefilter=False
        )
        np.testing.assert_allclose(out, ref, atol=1e-12)
        np.testing.assert_allclose(out[[0, 4]], x[row, [0, 4999]], atol=1e-12)  # interpolates


@pytest.mark.parametrize("n", [2, 7, 60, 1001, 100_003])
def test_prefilter_all_lengths(n: int) -> None:
    # Short records take the single-chain path, long ones the 4 interleaved chains.
    from scipy import ndimage

    from dsp.splines import bspline5_prefilter

    x = np.random.default_rng(n).standard_normal((1, n))
    c = x.copy()
    bspline5_prefilter(c)
    ref = ndimage.spline_filter1d(x[0], order=5, mode="mirror")
    np.testing.assert_allclose(c[0], ref, atol=1e-12 * max(1.0, np.abs(ref).max()))


def test_violent_speed_change_falls_back_to_monotone_phase_model() -> None:
    # A 50× speed jump: the not-a-knot spline through (angle, time) overshoots and would put grid
    # times out of order; the monotone PCHIP model is used instead.
    pulses = np.cumsum([0, 1, 1, 1, 1, 0.02, 0.02, 0.02, 0.02])
    angles = np.linspace(0, 8, 8001)
    assert np.any(np.diff(CubicSpline(np.arange(9.0), pulses)(angles)) <= 0)
    times = angle_grid_times(pulses, 1, 1000)
    assert times.shape == (8, 1000)
    assert np.all(np.diff(times.ravel()) > 0)
    np.testing.assert_allclose(times[:, 0], pulses[:-1])  # still through every pulse


def test_several_shafts_at_once_equal_separate_calls() -> None:
    # Pinion (no filter), gear (no filter, shares the prefilter) and a coarse grid that needs
    # the anti-alias filter (its own prefiltered copy).
    _, _, x, pulses = run_up_record(duration_s=2.0)
    targets = [(1280, 1.0), (1344, 20 / 21), (256, 1.0)]
    together = angle_resample_shafts(np.stack([x, -x]), FS, pulses, 1, targets)
    for (spr, ratio), out in zip(targets, together, strict=True):
        alone = angle_resample(np.stack([x, -x]), FS, pulses, 1, spr, shaft_ratio=ratio)
        np.testing.assert_array_equal(out, alone)


def test_anti_alias_band_follows_the_lowest_speed_under_20_percent_drift() -> None:
    """±20 % slow drift (a chirp in time): the cutoff is set by the lowest speed, so an order above
    the angle grid's Nyquist order leaves no alias at any speed, and an order below
    0.4 × samples_per_rev × min/max speed passes untouched at every speed."""
    fs, f0, a, period = 20_000.0, 1000 / 60, 0.2, 6.0
    t = np.arange(int(6.0 * fs)) / fs

    def angle(time: np.ndarray) -> np.ndarray:  # ∫ f0 (1 + a sin(2π t / T)) dt, revolutions
        return f0 * (time - a * period / (2 * np.pi) * (np.cos(2 * np.pi * time / period) - 1))

    fine = np.arange(int(6.0 * fs * 8)) / (8 * fs)
    pulses = np.interp(np.arange(1, int(angle(fine[-1]))), angle(fine), fine)
    spr, kept, above = 64, 16, 39  # 16 < 0.4·64·0.8/1.2 = 17.1; 39 > 32 (would alias to 25)
    theta = angle(t)
    x = np.cos(2 * np.pi * kept * theta) + np.cos(2 * np.pi * above * theta)
    revs = angle_resample(x, fs, pulses, 1, spr)
    spectrum = np.abs(np.fft.rfft(revs, axis=1)) / (spr / 2)
    # the kept order in every revolution, at full amplitude; nothing anywhere else
    assert np.max(np.abs(spectrum[:, kept] - 1.0)) < 1e-6  # measured 1e-8
    others = np.delete(spectrum, kept, axis=1)
    assert np.max(others) < 3e-4  # includes the alias order 25; measured 3e-5
    # the price: order 24 (above 0.4·64·min/max) is cut in the fastest revolutions
    fast = angle_resample(np.cos(2 * np.pi * 24 * theta), fs, pulses, 1, spr)
    gain = np.abs(np.fft.rfft(fast, axis=1)[:, 24]) / (spr / 2)
    assert gain.min() < 0.01 and gain.max() > 0.99


@pytest.mark.parametrize(
    ("pulses_per_rev", "samples_per_rev", "shaft_ratio", "uniform_path"),
    [
        (1, 1280, 1.0, True),  # tach on the pinion: 1280 grid steps per pulse interval
        (1, 1344, 20 / 21, True),  # the gear, tach on the pinion: 1280 again
        (4, 1280, 1.0, True),  # 320 per interval
        (3, 1280, 1.0, False),  # 426.67 per interval: the general path
        (1, 1280, 21 / 20, True),  # the pinion, tach on the gear: 1344
    ],
)
def test_grid_times_equal_scipy_cubic_spline_on_both_paths(
    pulses_per_rev: int, samples_per_rev: int, shaft_ratio: float, uniform_path: bool
) -> None:
    # The phase model is scipy's not-a-knot CubicSpline through (tach angle, pulse time); the
    # uniform-breaks product and the general per-point evaluation must both give it.
    from dsp.splines import _whole_points_per_piece

    _, _, _, pulses = run_up_record(pulses_per_rev=pulses_per_rev, duration_s=2.0)
    tach_angle = np.arange(pulses.size) / pulses_per_rev
    step = 1.0 / (samples_per_rev * shaft_ratio)
    assert bool(_whole_points_per_piece(tach_angle, step)) is uniform_path
    times = angle_grid_times(pulses, pulses_per_rev, samples_per_rev, shaft_ratio=shaft_ratio)
    assert times.shape[0] >= 5
    expected = CubicSpline(tach_angle, pulses)(np.arange(times.size) * step)
    np.testing.assert_allclose(times.ravel(), expected, rtol=0, atol=1e-12)
