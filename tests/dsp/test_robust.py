"""Defective samples and revolutions (dsp.robust) on known-answer signals."""

from __future__ import annotations

import numpy as np
import pytest

from dsp.robust import (
    SampleDefects,
    dropout_run_length,
    equal_runs,
    find_sample_defects,
    find_spikes,
    glitch_limits,
    max_spikes,
    repair_spans,
    revolution_outliers,
    revolutions_overlapping,
    spike_threshold,
    spread_block_starts,
)


def noise(n: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).standard_normal(n)


def test_gaussian_noise_has_no_defects() -> None:
    # 2 M samples of N(0, 1): the glitch bounds are ~±34 σ, no float repeats, extremes touched once
    x = noise(2_000_000)
    lo, hi = glitch_limits(x)
    assert 25 < -lo < 45 and 25 < hi < 45
    defects = find_sample_defects(x, limits=(lo, hi))
    assert defects.counts() == {"glitch_samples": 0, "dropout_samples": 0, "clipped_samples": 0}


def test_gaussian_noise_has_no_spike() -> None:
    # 2 M samples of N(0, 1): the spike threshold is ~6.5 σ from the neighbours' median
    x = noise(2_000_000, seed=1)
    threshold = spike_threshold(x)
    assert 5.5 < threshold < 7.5
    assert find_spikes(x, threshold).size == 0


@pytest.mark.parametrize(("height", "found"), [(20.0, True), (14.0, True), (10.0, True), (5.0, False)])
def test_a_lone_sample_in_noise_is_a_spike_from_about_10_sigma(height: float, found: bool) -> None:
    # the threshold is ~6.5 σ; the isolation test (16 neighbours spanning ~3 σ < 0.35 × the
    # distance) asks for about 9 σ in Gaussian noise
    x = noise(50_000, seed=2)
    x[[7_000, 31_000]] += np.array([height, -height]) - x[[7_000, 31_000]]
    spikes = find_spikes(x, spike_threshold(x))
    assert spikes.tolist() == ([7_000, 31_000] if found else [])
    defects = find_sample_defects(x, limits=glitch_limits(x), spikes=spikes)
    assert defects.counts()["glitch_samples"] == (2 if found else 0)


@pytest.mark.parametrize("cycles_per_sample", [0.05, 0.17, 0.25, 0.33, 0.4, 0.45])
def test_a_ringing_impact_is_not_a_spike(cycles_per_sample: float) -> None:
    # an impact through a resonance (damping 2 %), 40 σ high, starting in one sample from quiet:
    # the samples after its peak ring at comparable heights
    x = noise(20_000, seed=3)
    n = np.arange(2_000)
    x[10_000:12_000] += 40.0 * np.exp(-0.02 * 2 * np.pi * cycles_per_sample * n) * np.cos(
        2 * np.pi * cycles_per_sample * n)
    assert find_spikes(x, spike_threshold(x)).size == 0


def test_a_band_limited_impulse_is_not_a_spike() -> None:
    # the narrowest pulse an anti-alias filter passes (a sinc cut at 0.4 fs), 40 σ high: its
    # neighbours span 0.42 of its height
    x = noise(20_000, seed=5)
    n = np.arange(-50, 51)
    x[9_950:10_051] += 40.0 * np.sinc(0.8 * n) / np.sinc(0.0)
    assert find_spikes(x, spike_threshold(x)).size == 0


def test_many_lone_spikes_are_the_record_s_own() -> None:
    # the allowance: a record with more lone spikes than max_spikes keeps them (see
    # gearwatch.usecases.signal_checks); the detector itself finds every one
    assert max_spikes(100_000) == 8 and max_spikes(1_000_000) == 50
    x = noise(100_000, seed=4)
    where = np.arange(500, 100_000, 2_000)  # 50: fewer than 0.1 %, below the quantile
    x[where] = 25.0
    assert find_spikes(x, spike_threshold(x)).tolist() == where.tolist()
    assert find_spikes(x, float("inf")).size == 0
    assert spike_threshold(x, 0.0) == float("inf")


def test_quantised_sine_has_no_dropouts() -> None:
    # a 16-bit quantised tone at 1/20 of the sampling rate: consecutive samples differ by many LSB
    t = np.arange(200_000)
    x = np.round(30_000 * np.sin(2 * np.pi * t / 20.3)) / 32768
    defects = find_sample_defects(x, limits=glitch_limits(x))
    assert defects.counts()["dropout_samples"] == 0


@pytest.mark.parametrize("value", [3e38, 1e30, -1e30, np.nan, np.inf, -np.inf])
def test_glitch_sample_found_and_bridged(value: float) -> None:
    x = np.sin(np.arange(10_000) / 5.0) + 0.01 * noise(10_000)
    x[4321] = value
    defects = find_sample_defects(x, limits=glitch_limits(x))
    assert defects.glitch.tolist() == [[4321, 4322]]
    assert defects.counts()["glitch_samples"] == 1
    fixed = repair_spans(x, defects.spans())
    assert fixed[4321] == pytest.approx(0.5 * (x[4320] + x[4322]))
    assert np.all(np.isfinite(fixed)) and np.max(np.abs(fixed)) < 1.1


def test_dropout_and_clipped_burst_classified() -> None:
    x = np.sin(np.arange(10_000) / 5.0) + 0.01 * noise(10_000)
    x[2000:2100] = 0.0  # dropout: zeros
    x[5000:5050] = 0.37  # dropout: a held value
    top = x.max()
    x[7000:7010] = top + 0.2  # a clipped burst: the sensor holds its (new) extreme
    defects = find_sample_defects(x, limits=glitch_limits(x))
    assert defects.dropout.tolist() == [[2000, 2100], [5000, 5050]]
    assert defects.clipped.tolist() == [[7000, 7010]]
    assert defects.counts() == {"glitch_samples": 0, "dropout_samples": 150, "clipped_samples": 10}
    assert defects.spans()[:, 0].tolist() == [2000, 5000, 7000]


def test_short_runs_are_not_defects() -> None:
    x = np.sin(np.arange(1000) / 5.0)
    x[100:107] = 0.0  # 7 equal samples: below the dropout run
    x[500:502] = x.max()  # 2 at the extreme: below the clipping run
    defects = find_sample_defects(x, limits=glitch_limits(x))
    assert defects.counts() == {"glitch_samples": 0, "dropout_samples": 0, "clipped_samples": 0}


def test_block_spans_shift_and_concatenate() -> None:
    x = np.sin(np.arange(4000) / 5.0)
    x[[500, 2500]] = 1e9
    limits = glitch_limits(x)
    parts = [find_sample_defects(x[s : s + 2000], limits=limits).shifted(s) for s in (0, 2000)]
    joined = SampleDefects.concatenate(parts)
    assert joined.glitch.tolist() == find_sample_defects(x, limits=limits).glitch.tolist()
    assert SampleDefects.concatenate([]).counts()["glitch_samples"] == 0


def test_repair_spans_edges() -> None:
    assert repair_spans([9.0, 9.0, 1.0, 2.0], [[0, 2]]).tolist() == [1.0, 1.0, 1.0, 2.0]
    assert repair_spans([1.0, 2.0, 9.0], [[2, 3]]).tolist() == [1.0, 2.0, 2.0]
    assert repair_spans([1.0, 2.0], [[0, 2]]).tolist() == [0.0, 0.0]
    assert repair_spans([1.0, 2.0], np.empty((0, 2))).tolist() == [1.0, 2.0]


def test_equal_runs() -> None:
    assert equal_runs([0.0] * 5, 5).tolist() == [[0, 5]]
    assert equal_runs([0.0] * 4, 5).size == 0
    with pytest.raises(ValueError):
        equal_runs([0.0], 0)


def test_revolutions_overlapping() -> None:
    bounds = np.array([[0.0, 1.0], [1.0, 2.0], [2.0, 3.0], [3.0, 4.0]])
    assert revolutions_overlapping(bounds, [[2.5, 2.6]]).tolist() == [False, False, True, False]
    # a span across a boundary, and one widened by the margin into the next revolution
    assert revolutions_overlapping(bounds, [[0.9, 1.1]]).tolist() == [True, True, False, False]
    assert revolutions_overlapping(bounds, [[2.95, 2.96]], 0.1).tolist() == [
        False, False, True, True
    ]
    assert not revolutions_overlapping(bounds, np.empty((0, 2))).any()


def spalled_revolutions(n_revs: int, noise_rms: float, seed: int = 0) -> np.ndarray:
    """A mesh tone with a spall-like ring on one tooth, repeated in every revolution, plus noise."""
    angle = np.arange(1280) / 1280
    mesh = np.cos(2 * np.pi * 20 * angle)
    ring = np.zeros(1280)
    ring[960:1000] = 0.3 * np.exp(-np.arange(40) / 8.0) * np.sin(np.arange(40) * 1.3)
    rng = np.random.default_rng(seed)
    return mesh + ring + noise_rms * rng.standard_normal((n_revs, 1280))


def test_no_outlier_on_noise_alone() -> None:
    # 2000 revolutions of Gaussian noise around a repeating signal: the factor-4 test never fires
    revs = spalled_revolutions(2000, 0.05)
    assert not revolution_outliers(revs).any()


def test_noise_free_revolutions_are_not_outliers() -> None:
    revs = spalled_revolutions(50, 0.0) + 1e-12 * noise(50 * 1280).reshape(50, 1280)
    assert not revolution_outliers(revs).any()


def test_spall_repeats_so_only_the_glitch_revolution_is_an_outlier() -> None:
    revs = spalled_revolutions(60, 0.05)
    revs[17, 300] += 2.0  # a glitch ~40 σ: under the sample bound of most records, not here
    revs[40, 600:700] += 0.5  # a burst of non-synchronous content: energy outlier
    assert np.flatnonzero(revolution_outliers(revs)).tolist() == [17, 40]


def test_outlier_edge_cases() -> None:
    assert not revolution_outliers(spalled_revolutions(4, 0.05)).any()  # too few to test
    with pytest.raises(ValueError):
        revolution_outliers(np.zeros(10))
    with pytest.raises(ValueError):
        revolution_outliers(np.zeros((10, 10)), outlier_factor=1.0)


def test_coarsely_quantised_signal_has_no_dropouts() -> None:
    # a ±2-count noisy signal repeats values by chance: the dropout run is lengthened to match
    x = np.round(2 * noise(1_000_000, seed=1))
    run = dropout_run_length(x)
    assert run > 8
    defects = find_sample_defects(x, limits=glitch_limits(x), dropout_min_run=run)
    assert defects.counts()["dropout_samples"] == 0
    x[5000:5100] = 0.5  # a held value no count takes: a real dropout is still found
    defects = find_sample_defects(x, limits=glitch_limits(x), dropout_min_run=run)
    assert defects.dropout.tolist() == [[5000, 5100]]


def test_a_gain_step_is_not_an_outlier() -> None:
    revs = spalled_revolutions(60, 0.05)
    revs[40:] = 3.0 * revs[40:] + 0.2  # the sensor's gain and offset change a third of the way
    assert not revolution_outliers(revs).any()
    revs[10, 100] += 3.0  # a glitch is still one
    assert np.flatnonzero(revolution_outliers(revs)).tolist() == [10]


@pytest.mark.parametrize("size", [65_537, 100_003, 6_000_000, 123_456_789])
def test_sampled_blocks_stay_inside_and_spread_over_the_record(size: int) -> None:
    block = 1024
    starts = spread_block_starts(size, block)
    assert starts.size == 64
    assert starts[0] >= 0 and starts[-1] + block <= size
    assert np.all(np.diff(starts) >= 0)
    # one block per 64th of the record: no stretch of two 64ths is left unsampled
    stretch = (size - block) / 64
    assert np.max(np.diff(np.concatenate(([0], starts, [size - block])))) < 2 * stretch


def test_sampled_blocks_do_not_lock_onto_a_periodic_signal() -> None:
    # equally spaced blocks of a signal whose period divides their spacing would all see the same
    # phase; the spread starts see every phase
    size, block = 6_400_000, 1024
    period = (size - block) / 64  # the spacing of an even 64-way split
    phases = (spread_block_starts(size, block) % period) / period
    assert np.ptp(phases) > 0.5
