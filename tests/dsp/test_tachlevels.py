"""A Schmitt trigger that follows a drifting tach's levels (dsp.tachlevels), on known-answer waveforms."""

from __future__ import annotations

import numpy as np
import pytest

from dsp.synthetic import synthetic_gear_record
from dsp.tach import pulse_times_from_waveform
from dsp.tachlevels import pulse_times_tracking_levels

FS = 20_000.0


@pytest.fixture(scope="module")
def record():
    return synthetic_gear_record(duration_s=8.0, noise_rms=0.0, seed=2)


def test_a_sound_tach_is_read_at_the_same_edges(record) -> None:
    fixed = pulse_times_from_waveform(record.tach_waveform, FS)
    tracked = pulse_times_tracking_levels(record.tach_waveform, FS, 0.06, block_samples=50_000)
    assert tracked.size == fixed.size
    np.testing.assert_allclose(tracked, fixed, atol=0.05 / FS)  # a twentieth of a sample


@pytest.mark.parametrize("edge", ["rising", "falling"])
def test_a_baseline_drifting_by_more_than_the_pulse_height_is_followed(record, edge: str) -> None:
    t = np.arange(record.tach_waveform.size) / FS
    drift = 6.0 * np.sin(2 * np.pi * 0.1 * t) + np.random.default_rng(1).normal(0, 0.2, t.size)
    tach = record.tach_waveform if edge == "rising" else 5.0 - record.tach_waveform
    truth = pulse_times_from_waveform(tach, FS, edge=edge)
    assert pulse_times_from_waveform(tach + drift, FS, edge=edge).size < 0.8 * truth.size
    found = pulse_times_tracking_levels(tach + drift, FS, 0.06, edge=edge)
    assert found.size == truth.size
    np.testing.assert_allclose(found, truth, atol=3 / FS)  # noise of 4 % of the swing on the edge


def test_a_dead_stretch_reads_no_edge(record) -> None:
    tach = record.tach_waveform.copy()
    tach[40_000:80_000] = 0.02 * np.random.default_rng(2).standard_normal(40_000)  # 2 s of noise
    found = pulse_times_tracking_levels(tach, FS, 0.06)
    assert not np.any((found > 2.0 + 0.07) & (found < 4.0))
    truth = pulse_times_from_waveform(record.tach_waveform, FS)
    outside = truth[(truth < 2.0) | (truth > 4.06)]
    assert np.all(np.min(np.abs(found[:, None] - outside[None, :]), axis=0) < 1 / FS)
