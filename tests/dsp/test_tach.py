"""Tachometer: edge times, pulse repair, speed statistics and refusals, on known-answer signals."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import erf

from dsp.synthetic import synthetic_gear_record
from dsp.tach import (
    PulseRepair,
    TachometerError,
    analyze_tachometer,
    pulse_times_from_waveform,
    repair_pulse_times,
    shaft_ratios,
    waveform_levels,
)
from dsp.tachgaps import MAX_BRIDGED_FRACTION, bridge_unexplained

FS = 20_000.0


def trapezoid_train(edge_samples: np.ndarray, ramp_samples: float, high_samples: float, n: int):
    """0..1 pulse train: linear ramps of the given width, mid-level exactly at each edge."""
    i = np.arange(n, dtype=float)
    x = np.zeros(n)
    for e in edge_samples:
        up = np.clip((i - e) / ramp_samples + 0.5, 0, 1)
        down = np.clip(0.5 - (i - e - high_samples) / ramp_samples, 0, 1)
        x = np.maximum(x, up * down)
    return x


@pytest.mark.parametrize("ramp_samples", [2.0, 3.0, 12.0])
def test_ttl_edges_exact_to_sub_sample(ramp_samples: float) -> None:
    # Fast ramps are timed by the bracketing pair, slow ones by the in-band fit: both exact on
    # a linear ramp at least 2 samples wide (then both bracketing samples lie on the ramp), at
    # arbitrary fractional positions.
    rng = np.random.default_rng(1)
    edges = np.cumsum(rng.uniform(180.0, 220.0, 40)) + 50.3
    x = 5.0 * trapezoid_train(edges, ramp_samples, 60.0, int(edges[-1]) + 200)
    found = pulse_times_from_waveform(x, FS) * FS
    assert found.size == edges.size
    np.testing.assert_allclose(found, edges, atol=1e-9)


def test_falling_edges() -> None:
    edges = np.arange(30) * 200.0 + 100.37
    x = trapezoid_train(edges, 2.0, 50.0, 6200)
    falling = pulse_times_from_waveform(x, FS, edge="falling") * FS
    np.testing.assert_allclose(falling, edges + 50.0, atol=1e-9)


def test_synthetic_ttl_edges_match_true_pulse_times() -> None:
    rec = synthetic_gear_record(duration_s=1.5, pulses_per_rev=3, noise_rms=0.0)
    found = pulse_times_from_waveform(rec.tach_waveform, rec.sample_rate_hz)
    assert found.size == rec.pulse_times_s.size
    assert np.max(np.abs(found - rec.pulse_times_s)) * FS < 1e-6


def noisy_analogue(
    edges: np.ndarray, n: int, width_samples: float, noise: float, seed: int, high: float = 80.0
):
    """Smooth (erf-shaped) pulses plus white noise; each rising edge crosses 0.5 at ``edges``
    (the pulses are long enough for the edges not to overlap)."""
    i = np.arange(n, dtype=float)
    x = np.zeros(n)
    for e in edges:
        x += 0.5 * (erf((i - e) / width_samples) - erf((i - e - high) / width_samples))
    return x + noise * np.random.default_rng(seed).standard_normal(n)


def test_noisy_analogue_edges_sub_sample_with_hysteresis() -> None:
    edges = np.arange(1, 200) * 160.0 + np.random.default_rng(2).uniform(0, 1, 199)
    noise = 0.03
    x = noisy_analogue(edges, 32_200, width_samples=6.0, noise=noise, seed=3)
    found = pulse_times_from_waveform(x, FS) * FS
    assert found.size == edges.size  # hysteresis: no chatter, no lost edge
    error = found - edges
    # Noise / edge slope is 0.03 / (1 / (6 √π)) ≈ 0.32 samples: the error of one threshold
    # crossing. The fit through the in-band samples averages it down (measured 0.16). No bias.
    assert np.sqrt(np.mean(error**2)) < 0.2
    assert abs(np.mean(error)) < 0.05


def test_without_hysteresis_noise_makes_extra_edges() -> None:
    # Slow noisy edges: the default band gives exactly one edge each, a zero-width band chatters.
    edges = np.arange(1, 100) * 320.0
    x = noisy_analogue(edges, 32_200, width_samples=30.0, noise=0.03, seed=3, high=160.0)
    found = pulse_times_from_waveform(x, FS) * FS
    assert found.size == edges.size
    assert np.sqrt(np.mean((found - edges) ** 2)) < 0.5
    chattering = pulse_times_from_waveform(x, FS, threshold=0.5, hysteresis=0.0)
    assert chattering.size > edges.size + 20


def test_waveform_levels_ignore_spikes_and_estimate_noise() -> None:
    rng = np.random.default_rng(4)
    x = np.where((np.arange(100_000) % 400) < 100, 5.0, 0.2) + 0.05 * rng.standard_normal(100_000)
    x[::5000] = 40.0  # rare spikes
    low, high, noise = waveform_levels(x)
    assert low == pytest.approx(0.2, abs=0.01)
    assert high == pytest.approx(5.0, abs=0.01)
    assert noise == pytest.approx(0.05, rel=0.1)


def test_constant_or_bad_waveform() -> None:
    assert pulse_times_from_waveform(np.ones(1000), FS).size == 0
    with pytest.raises(TachometerError, match="NaN"):
        pulse_times_from_waveform(np.array([0.0, np.nan, 1.0]), FS)
    with pytest.raises(TachometerError, match="1-D"):
        pulse_times_from_waveform(np.zeros((2, 10)), FS)


# --------------------------------------------------------------------------- repair


def speed_ramp_pulses(n: int, period_s: float = 0.06, drift: float = 0.002) -> np.ndarray:
    """Pulse times with a slowly shrinking period (a gentle run-up)."""
    periods = period_s * (1.0 - drift * np.arange(n - 1) / n)
    return np.concatenate([[0.013], 0.013 + np.cumsum(periods)])


def test_missing_pulse_repaired_and_reported() -> None:
    truth = speed_ramp_pulses(60)
    t = np.delete(truth, 23)
    repaired, repairs = repair_pulse_times(t)
    assert repairs == (PulseRepair("missing", 23, repairs[0].time_s),)
    np.testing.assert_allclose(repaired, truth, atol=1e-6)  # midpoint of a near-uniform gap
    assert repairs[0].time_s == pytest.approx(truth[23], abs=1e-6)


@pytest.mark.parametrize("fraction", [0.5, 0.37, 0.02, 0.95])
def test_extra_pulse_removed_and_reported(fraction: float) -> None:
    truth = speed_ramp_pulses(60)
    spurious = truth[30] + fraction * (truth[31] - truth[30])
    t = np.sort(np.append(truth, spurious))
    repaired, repairs = repair_pulse_times(t)
    assert len(repairs) == 1 and repairs[0].kind == "extra"
    if 0.1 < fraction < 0.9:
        # A spurious pulse inside the period: exactly that pulse is removed.
        np.testing.assert_array_equal(repaired, truth)
        assert repairs[0] == PulseRepair("extra", 31, spurious)
    else:
        # A bounce next to a real pulse: removing either one leaves a timing error of at most
        # that small fraction of a period.
        np.testing.assert_allclose(repaired, truth, atol=min(fraction, 1 - fraction) * 0.06 + 1e-12)
        assert repairs[0].index in (30, 31, 32)


def test_missing_and_extra_together_and_at_edges() -> None:
    truth = speed_ramp_pulses(80)
    t = np.delete(truth, [10, 50])
    t = np.sort(np.append(t, [truth[70] + 0.4 * 0.06, truth[0] - 0.5 * 0.06 + 0.02]))
    repaired, repairs = repair_pulse_times(t)
    kinds = sorted(r.kind for r in repairs)
    assert kinds == ["extra", "extra", "missing", "missing"]
    assert [r.time_s for r in repairs] == sorted(r.time_s for r in repairs)
    np.testing.assert_allclose(repaired, truth, atol=2e-5)


def test_clean_train_untouched() -> None:
    truth = speed_ramp_pulses(50)
    repaired, repairs = repair_pulse_times(truth)
    assert repairs == ()
    np.testing.assert_array_equal(repaired, truth)


# --------------------------------------------------------------------------- analysis


def test_speed_statistics_known_profile() -> None:
    rev_periods = 60.0 / np.array([1000.0, 1010.0, 990.0, 1005.0] * 6)
    rev_times = np.concatenate([[0.5], 0.5 + np.cumsum(rev_periods)])
    # 4 equally spaced pulses per revolution.
    pulses = np.interp(np.arange(4 * 24 + 1) / 4.0, np.arange(25), rev_times)
    tach = analyze_tachometer(pulses, pulses_per_rev=4)
    assert tach.whole_revolutions == 24
    np.testing.assert_allclose(tach.rev_times_s, rev_times)
    np.testing.assert_allclose(tach.rev_speed_rpm, 60.0 / rev_periods)
    assert tach.min_rpm == pytest.approx(990.0)
    assert tach.max_rpm == pytest.approx(1010.0)
    assert tach.mean_rpm == pytest.approx(1001.25)
    assert tach.speed_variation == pytest.approx(20.0 / 1001.25)
    assert tach.repairs == ()


def test_repairs_are_part_of_the_analysis() -> None:
    truth = np.arange(41) * 0.06
    tach = analyze_tachometer(np.delete(truth, 7), pulses_per_rev=1)
    assert [r.kind for r in tach.repairs] == ["missing"]
    assert tach.whole_revolutions == 40
    assert tach.mean_rpm == pytest.approx(1000.0)


@pytest.mark.parametrize("ppr", [1, 4])
def test_exactly_min_revolutions_passes_one_less_is_refused(ppr: int) -> None:
    pulses = np.arange(20 * ppr + 1) * 0.06 / ppr
    assert analyze_tachometer(pulses, ppr).whole_revolutions == 20
    with pytest.raises(TachometerError, match="only 19 whole revolutions"):
        analyze_tachometer(pulses[:-1], ppr)
    assert analyze_tachometer(pulses[: 5 * ppr + 1], ppr, min_revolutions=5).whole_revolutions == 5


def test_speed_variation_refused_and_boundary() -> None:
    speeds = np.linspace(1000.0, 1150.0, 30)  # run-up: (max - min)/mean = 150/1075
    pulses = np.concatenate([[0.0], np.cumsum(60.0 / speeds)])
    variation = 150.0 / np.mean(speeds)
    assert analyze_tachometer(pulses, 1).speed_variation == pytest.approx(variation)  # default 0.5
    with pytest.raises(TachometerError, match="speed varies too much"):
        analyze_tachometer(pulses, 1, max_speed_variation=0.10)
    assert analyze_tachometer(pulses, 1, max_speed_variation=variation + 1e-12).speed_variation == (
        pytest.approx(variation)
    )
    with pytest.raises(TachometerError, match="speed varies"):
        analyze_tachometer(pulses, 1, max_speed_variation=variation - 1e-9)
    # ±30 % over the record, slowly: (max - min)/mean ≈ 0.6 is refused by the default
    slow = 1000.0 * (1 + 0.3 * np.sin(np.linspace(0, 2 * np.pi, 400)))
    with pytest.raises(TachometerError, match="speed varies too much"):
        analyze_tachometer(np.concatenate([[0.0], np.cumsum(60.0 / slow)]), 1)


def test_speed_changing_too_fast_is_refused_with_that_reason() -> None:
    # a shaft braked to a stop: the period grows by 8 % per revolution, smoothly
    periods = 0.06 * 1.08 ** np.maximum(np.arange(80) - 40, 0)
    pulses = np.concatenate([[0.0], np.cumsum(periods)])
    with pytest.raises(TachometerError, match="speed changes too fast for order tracking"):
        analyze_tachometer(pulses, 1)
    # coasting down more gently (4 % per revolution) is trackable, but leaves 1000 → 217 rpm
    periods = 0.06 * 1.04 ** np.maximum(np.arange(80) - 40, 0)
    with pytest.raises(TachometerError, match="speed varies too much"):
        analyze_tachometer(np.concatenate([[0.0], np.cumsum(periods)]), 1)


def test_speed_range_refused() -> None:
    pulses = np.arange(41) * 0.06  # 1000 rpm
    with pytest.raises(TachometerError, match="outside the accepted range"):
        analyze_tachometer(pulses, 1, min_speed_rpm=1200.0)
    with pytest.raises(TachometerError, match="outside the accepted range"):
        analyze_tachometer(pulses, 1, max_speed_rpm=900.0)
    assert analyze_tachometer(pulses, 1, min_speed_rpm=999.0, max_speed_rpm=1001.0)


@pytest.mark.parametrize(
    ("pulses", "reason"),
    [
        (np.array([]), "no tachometer pulses"),
        (np.array([0.1, 0.2]), "too few tachometer pulses"),
        (np.array([0.1, 0.3, 0.2] + [0.4 + 0.1 * k for k in range(30)]), "not strictly increasing"),
        # a gap of 21 periods in 59: more than a quarter of the record cannot be bridged
        (np.delete(np.arange(60) * 0.06, range(10, 30)), "irregular tachometer.*cover 36%"),
    ],
)
def test_refusals_have_one_line_reasons(pulses: np.ndarray, reason: str) -> None:
    with pytest.raises(TachometerError, match=reason) as info:
        analyze_tachometer(pulses, 1)
    assert "\n" not in str(info.value)
    assert isinstance(info.value, ValueError)


def test_bad_pulses_per_rev() -> None:
    with pytest.raises(TachometerError, match="pulses per revolution"):
        analyze_tachometer(np.arange(30) * 0.1, 0)


def test_shaft_ratios() -> None:
    assert shaft_ratios("pinion", 20, 21) == (1.0, 20 / 21)
    assert shaft_ratios("gear", 20, 21) == (21 / 20, 1.0)
    with pytest.raises(ValueError, match="tach_shaft"):
        shaft_ratios("crank", 20, 21)  # type: ignore[arg-type]


def test_waveform_glitch_and_dropout_end_to_end() -> None:
    # A TTL with one pulse erased (dropout) and one narrow spurious pulse (glitch) mid-period:
    # both are detected as edges-or-not, then repaired and reported by the analysis.
    rec = synthetic_gear_record(duration_s=3.0, noise_rms=0.0, seed=9)
    w = rec.tach_waveform.copy()
    fs = rec.sample_rate_hz
    lost = rec.pulse_times_s[10]
    w[int(lost * fs) - 5 : int(lost * fs) + 400] = 0.0  # pulse 10 never rises
    glitch = 0.5 * (rec.pulse_times_s[30] + rec.pulse_times_s[31])
    w[int(glitch * fs) : int(glitch * fs) + 4] = 5.0
    tach = analyze_tachometer(pulse_times_from_waveform(w, fs), 1)
    assert sorted(r.kind for r in tach.repairs) == ["extra", "missing"]
    extra = next(r for r in tach.repairs if r.kind == "extra")
    assert extra.time_s == pytest.approx(glitch, abs=1.0 / fs)
    missing = next(r for r in tach.repairs if r.kind == "missing")
    assert missing.time_s == pytest.approx(lost, abs=5e-5)  # midpoint; measured 1.5e-5 s off
    np.testing.assert_allclose(tach.pulse_times_s, rec.pulse_times_s, atol=5e-5)
    assert tach.whole_revolutions == rec.pulse_times_s.size - 1


def test_magnetic_pickup_sine_edges() -> None:
    # An analogue sine (one per revolution, 1000 rpm) with noise: the threshold defaults to 0,
    # edges are the upward zero crossings. One noisy crossing would be off by noise/slope
    # = 0.05 / (2π·16.7/20000) ≈ 9.5 samples; the fit through the ~100 in-band samples brings
    # it near 1 sample (measured 1.2), about 1/1000 of a revolution. A common bias would come
    # from the threshold estimate (all 60000 samples here; from 64 × 1024 of them for records
    # over 65536 samples, measured |bias| <= 0.75 sample on this sine).
    f = 1000.0 / 60.0
    t = np.arange(60_000) / FS
    x = np.sin(2 * np.pi * f * t - 0.9) + 0.05 * np.random.default_rng(0).standard_normal(t.size)
    found = pulse_times_from_waveform(x, FS)
    truth = (np.arange(found.size) + 0.9 / (2 * np.pi)) / f
    error_samples = (found - truth) * FS
    assert found.size == 50
    assert np.sqrt(np.mean(error_samples**2)) < 2.0
    assert abs(np.mean(error_samples)) < 1.0


# ------------------------------------------------------------- stretches no single repair explains


def _steady(n: int = 80, period: float = 0.06) -> np.ndarray:
    return np.arange(n) * period


def test_a_burst_of_spurious_pulses_is_bridged_and_its_revolutions_named() -> None:
    # interference on the tach cable: 12 spurious pulses within two periods at 1.5 s
    t = _steady()
    rng = np.random.default_rng(4)
    burst = np.sort(rng.uniform(1.5, 1.62, 12))
    tach = analyze_tachometer(np.sort(np.concatenate([t, burst])), 1)
    np.testing.assert_allclose(tach.pulse_times_s, t, atol=1e-12)
    assert [r.kind for r in tach.repairs] == ["bridged"]  # the single repairs inside superseded
    (lo, hi), = tach.bridged_spans_s
    assert lo <= 1.5 - 0.06 + 1e-9 and hi >= 1.62 + 0.06 - 1e-9  # one period of margin each side
    assert hi - lo < 6 * 0.06
    assert tach.speed_variation == pytest.approx(0.0, abs=1e-9)


def test_a_gap_of_several_periods_is_bridged_with_the_right_count() -> None:
    t = _steady()
    tach = analyze_tachometer(np.delete(t, range(30, 35)), 1)  # 6 periods without a pulse
    np.testing.assert_allclose(tach.pulse_times_s, t, atol=1e-12)
    assert tach.whole_revolutions == t.size - 1
    assert [r.kind for r in tach.repairs] == ["bridged"]


def test_stretches_grouped_and_period_taken_around_them() -> None:
    # the speed rises 20 % over the record; two separate stretches, each bridged at its own period
    period = 0.06 / np.linspace(1.0, 1.2, 100)
    t = np.concatenate([[0.0], np.cumsum(period)])
    noisy = np.sort(np.concatenate([np.delete(t, [70, 71, 72, 73]), t[20] + [0.011, 0.013, 0.03]]))
    pulses, stretches = bridge_unexplained(noisy)
    assert len(stretches) == 2
    assert [s.intervals for s in stretches] == [1, 5]
    np.testing.assert_allclose(pulses[:70], t[:70], atol=1e-12)
    np.testing.assert_allclose(pulses, t, atol=0.002)  # inside the gap: even spacing, a guess


def test_bridging_refused_when_it_would_cover_too_much() -> None:
    t = _steady(100)
    covered = np.delete(t, range(20, 20 + int(MAX_BRIDGED_FRACTION * 100) + 2))
    with pytest.raises(TachometerError, match="cover"):
        analyze_tachometer(covered, 1)
    assert analyze_tachometer(np.delete(t, range(20, 30)), 1).whole_revolutions == 99


def test_several_pulses_per_revolution_need_a_whole_number_of_periods() -> None:
    t = _steady(400, 0.005)  # 20 pulses per revolution
    stretched = t.copy()
    stretched[205:] += 0.002  # a gap of 5.4 periods: bridging would shift every mark after it
    gap = np.delete(stretched, range(201, 205))
    with pytest.raises(TachometerError, match="not a whole number"):
        analyze_tachometer(gap, 20, min_revolutions=5)
    exact = analyze_tachometer(np.delete(t, range(201, 205)), 20, min_revolutions=5)  # 5 periods
    np.testing.assert_allclose(exact.pulse_times_s, t, atol=1e-12)
    # with one pulse per revolution the same stretch is bridged: every mark is the reference
    assert analyze_tachometer(gap[::20], 1, min_revolutions=5).whole_revolutions > 0


def test_an_estimated_pulse_train_is_not_bridged() -> None:
    with pytest.raises(TachometerError, match="irregular tachometer"):
        analyze_tachometer(np.delete(_steady(), range(30, 35)), 1, bridge=False)



@pytest.mark.parametrize("seed", range(24))
def test_a_faulty_tach_is_bridged_right_or_refused_never_miscounted(seed: int) -> None:
    """Random faults (interference, the signal held at 0 V, five spikes; 5–150 ms) on random
    trains (300–3000 rpm, 1–60 pulses per revolution): what is kept outside the bridged spans is
    the true pulses, and with several pulses per revolution never a miscount — or the tach is
    refused. (``benchmarks/bench_tach_faults.py`` counts the same on 300 cases.)"""
    rng = np.random.default_rng([seed, 77])
    ppr = int(rng.choice([1, 2, 4, 60]))
    rec = synthetic_gear_record(
        duration_s=4.0, noise_rms=0.0, seed=seed, pulses_per_rev=ppr,
        pinion_rpm=float(rng.uniform(300, 3000)), speed_fluctuation=float(rng.uniform(0, 0.05)),
    )
    w = rec.tach_waveform.copy()
    start, length = int(rng.uniform(0.3, 3.5) * FS), int(rng.uniform(0.005, 0.15) * FS)
    if seed % 3 == 0:
        w[start : start + length] += rng.normal(0, rng.uniform(1, 5), length)
    elif seed % 3 == 1:
        w[start : start + length] = 0.0
    else:
        for at in rng.integers(start, start + length, 5):
            w[at : at + 3] = 5.0
    truth = pulse_times_from_waveform(rec.tach_waveform, FS)
    try:
        tach = analyze_tachometer(pulse_times_from_waveform(w, FS), ppr, min_revolutions=5)
    except TachometerError as error:
        assert "irregular tachometer" in str(error)
        return
    kept = tach.pulse_times_s
    for lo, hi in tach.bridged_spans_s:
        kept = kept[(kept <= lo) | (kept >= hi)]
    error = np.min(np.abs(kept[:, None] - truth[None, :]), axis=1)
    assert error.max() <= 0.2 * np.median(np.diff(truth))  # a dropout's end may move an edge a little
    assert abs(tach.pulse_times_s.size - truth.size) <= (1 if ppr == 1 else 0)


def test_a_long_burst_on_a_fine_encoder_is_refused_not_counted_by_luck() -> None:
    """A 100-period burst on a 60-pulse encoder whose edges jitter by 2 % of a period: the local
    period is known to about 0.5 %, the speed may change by 1 %, so the count of periods in the
    burst is uncertain by about a period — whatever its fractional part, the bridge is refused
    (a miscount would shift every revolution mark after it). With one pulse per revolution the
    same train is bridged."""
    rng = np.random.default_rng(3)
    period = 1e-3
    t = np.cumsum(period * (1 + 0.02 * rng.standard_normal(3000)))
    burst = (t > 1.0) & (t < 1.1)
    noisy = np.sort(np.concatenate([t[~burst], rng.uniform(1.0, 1.1, 400)]))
    with pytest.raises(TachometerError, match="miscount would shift"):
        analyze_tachometer(noisy, 60, min_revolutions=5)
    assert analyze_tachometer(noisy, 1).bridged_spans_s
