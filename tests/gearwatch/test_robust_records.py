"""Real-recording defects through the whole chain: glitches, dropouts, clipped bursts, speed drift,
and the data-quality score (known-answer synthetic records, dsp.synthetic)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dsp.synthetic import SyntheticRecord, synthetic_gear_record
from dsp.tach import analyze_tachometer, pulse_times_from_waveform
from gearwatch.floor.campaign import Campaign, ChannelConfig, RecordData
from gearwatch.floor.errors import RecordRejected
from gearwatch.floor.results import RecordAnalysis
from gearwatch.usecases.analyze import analyze_record
from tests.gearwatch.test_pipeline import campaign_for, record_of

SPALL_TOOTH = 16


@pytest.fixture(scope="module")
def spalled() -> SyntheticRecord:
    return synthetic_gear_record(
        duration_s=3.0, spall_tooth=SPALL_TOOTH, spall_depth=0.1, tooth1_pitch_angle_deg=337.4,
        seed=4,
    )


@pytest.fixture(scope="module")
def clean(spalled: SyntheticRecord) -> RecordAnalysis:
    return analyze(spalled, spalled.acceleration)


def analyze(synthetic: SyntheticRecord, acc: np.ndarray) -> RecordAnalysis:
    return analyze_record(record_of(synthetic, acc), campaign_for(synthetic), input_sha256="0" * 64)


def depths(analysis: RecordAnalysis) -> np.ndarray:
    return np.array([t.mci_depth for t in analysis.channels[0].teeth])


def assert_spall_kept(analysis: RecordAnalysis, clean: RecordAnalysis) -> None:
    """The spalled tooth is still the worst, no other tooth has a well, the spall's depth holds."""
    d, d0 = depths(analysis), depths(clean)
    assert analysis.channels[0].worst_tooth == SPALL_TOOTH
    others = np.delete(d, SPALL_TOOTH - 1)
    assert others.max() < 0.15  # the clean record's other teeth: < 0.06 Np; before: 1.4-28 Np
    assert d[SPALL_TOOTH - 1] == pytest.approx(d0[SPALL_TOOTH - 1], abs=0.1)


@pytest.mark.parametrize("value", [3e38, 1e30, -1e30, np.nan])
def test_one_glitch_sample_does_not_make_a_well(
    spalled: SyntheticRecord, clean: RecordAnalysis, value: float
) -> None:
    acc = spalled.acceleration.copy()
    acc[30_123] = value  # before: teeth 11-12 wells of 17-27 Np, the spall not the worst
    analysis = analyze(spalled, acc)
    assert_spall_kept(analysis, clean)
    assert analysis.quality.glitch_samples == 1
    assert analysis.quality.rejected_revolutions == 1
    assert np.isfinite(analysis.channels[0].metrics["raw_kurtosis"])
    assert analysis.channels[0].metrics["raw_kurtosis"] == pytest.approx(
        clean.channels[0].metrics["raw_kurtosis"], rel=0.01
    )


def test_a_lone_spike_inside_the_signal_range_is_a_glitch(
    spalled: SyntheticRecord, clean: RecordAnalysis
) -> None:
    acc = spalled.acceleration.copy()
    acc[30_123] += 8.0  # inside the sample bounds (~±19); before: a 1.3 Np well on tooth 12
    analysis = analyze(spalled, acc)
    assert_spall_kept(analysis, clean)
    assert analysis.quality.glitch_samples == 1  # an isolated spike (dsp.robust.find_spikes)
    assert analysis.quality.rejected_revolutions == 1
    # the raw kurtosis is the clean record's: the spike is bridged before the moments
    assert analysis.channels[0].metrics["raw_kurtosis"] == pytest.approx(
        clean.channels[0].metrics["raw_kurtosis"], rel=1e-3)


@pytest.mark.parametrize(("spikes", "glitches"), [(3, 3), (20, 0)])
def test_many_lone_spikes_are_the_record_s_own(
    spalled: SyntheticRecord, spikes: int, glitches: int
) -> None:
    # a 3-s record may hold 8 lone spikes as glitches (dsp.robust.max_spikes); 20 are its own
    acc = spalled.acceleration.copy()
    where = np.linspace(5_000, 55_000, spikes).astype(int)
    acc[where] += 8.0
    analysis = analyze(spalled, acc)
    assert analysis.quality.glitch_samples == glitches


def test_a_short_burst_inside_the_signal_range_is_caught_by_the_revolution_test(
    spalled: SyntheticRecord, clean: RecordAnalysis
) -> None:
    acc = spalled.acceleration.copy()
    acc[30_123:30_126] += 8.0  # three samples: not a lone spike, and inside the sample bounds
    analysis = analyze(spalled, acc)
    assert_spall_kept(analysis, clean)
    assert analysis.quality.glitch_samples == 0
    assert analysis.channels[0].quality is not None
    assert analysis.channels[0].quality.rejected_outlier_revolutions == 1


@pytest.mark.parametrize(("length", "value"), [(200, 0.0), (2000, 0.0), (300, 0.4)])
def test_a_short_dropout(
    spalled: SyntheticRecord, clean: RecordAnalysis, length: int, value: float
) -> None:
    acc = spalled.acceleration.copy()
    acc[30_000 : 30_000 + length] = value  # zeros, or a held value (0.1 s at most)
    analysis = analyze(spalled, acc)
    assert_spall_kept(analysis, clean)
    assert analysis.quality.dropout_samples == length
    revolution_samples = spalled.sample_rate_hz * 60 / 1000
    assert analysis.quality.rejected_revolutions <= 2 + length / revolution_samples


def test_a_long_dropout_loses_its_revolutions_not_the_record() -> None:
    """A sensor disconnected for a quarter of the record (a held zero): the revolutions around it
    are averaged and the raw metrics are those of the samples outside it. Before, more than 5 %
    of defective samples refused the whole record."""
    synthetic = synthetic_gear_record(
        duration_s=6.0, spall_tooth=SPALL_TOOTH, spall_depth=0.1, tooth1_pitch_angle_deg=337.4,
        seed=5,
    )
    whole = analyze(synthetic, synthetic.acceleration)
    acc = synthetic.acceleration.copy()
    acc[40_000:70_000] = 0.0  # 1.5 s of 6 s: 25 of 100 revolutions
    analysis = analyze(synthetic, acc)
    channel = analysis.channels[0]
    assert channel.worst_tooth == SPALL_TOOTH
    assert analysis.quality.dropout_samples == 30_000
    assert channel.quality is not None
    assert 25 <= channel.quality.rejected_defective_revolutions <= 28
    for name in ("raw_rms", "raw_kurtosis"):
        assert channel.metrics[name] == pytest.approx(whole.channels[0].metrics[name], rel=0.02)


def test_dropouts_all_over_the_record_refuse_it_by_the_revolutions_they_leave(
    spalled: SyntheticRecord,
) -> None:
    acc = spalled.acceleration.copy()
    for start in range(500, acc.size - 100, 1200):  # a 100-sample dropout in every revolution
        acc[start : start + 100] = 0.0
    with pytest.raises(RecordRejected, match="pinion revolutions rejected"):
        analyze(spalled, acc)
    acc = spalled.acceleration.copy()
    acc[: acc.size * 6 // 10] = 0.0
    with pytest.raises(RecordRejected, match="mostly disconnected"):
        analyze(spalled, acc)


@pytest.mark.parametrize("fault", ["interference", "gap"])
def test_a_tach_burst_or_gap_costs_its_revolutions_not_the_tach(
    spalled: SyntheticRecord, fault: str
) -> None:
    """50 ms of interference on the tach cable (dozens of spurious edges), or 0.2 s without
    pulses: the stretch is bridged and the revolutions it touches are left out — the result is
    the one of the same record with those revolutions lost to an accelerometer dropout. Before,
    either fault made the whole tach unusable and the angle fell back to the mesh phase."""
    tach = spalled.tach_waveform.copy()
    if fault == "interference":
        tach[30_000:31_000] += np.random.default_rng(0).normal(0.0, 3.0, 1000)
    else:
        tach[30_000:34_000] = 0.0
    record = dataclasses.replace(record_of(spalled), channels={"acc": spalled.acceleration, "tach": tach})
    analysis = analyze_record(record, campaign_for(spalled), input_sha256="0" * 64)
    assert analysis.quality.angle_source == "tachometer"
    assert [r.kind for r in analysis.quality.tach_repairs] == ["bridged"]
    quality = analysis.channels[0].quality
    assert quality is not None and 2 <= quality.rejected_tach_gap_revolutions <= 9

    fs = spalled.sample_rate_hz
    (lo, hi), = analyze_tachometer(pulse_times_from_waveform(tach, fs), 1).bridged_spans_s
    acc = spalled.acceleration.copy()
    acc[int(lo * fs) : int(hi * fs) + 1] = 0.0  # the same revolutions lost the other way
    dropped = analyze(spalled, acc)
    # (the lost stretch's own revolutions may count one more or less: they are guesses, dropped)
    assert abs(analysis.channels[0].revolutions - dropped.channels[0].revolutions) <= 1
    assert analysis.channels[0].worst_tooth == dropped.channels[0].worst_tooth == SPALL_TOOTH
    # the revolution next to each end may be counted in one and not the other (its bounds come
    # from bridged pulses here, from true ones there): close, not equal
    d, d_dropped = depths(analysis), depths(dropped)
    assert d[SPALL_TOOTH - 1] == pytest.approx(d_dropped[SPALL_TOOTH - 1], abs=0.05)
    assert np.delete(d, SPALL_TOOTH - 1).max() < 0.1


def test_a_tach_whose_pulse_goes_low_is_read_on_its_falling_edge(
    spalled: SyntheticRecord, clean: RecordAnalysis
) -> None:
    """A notch under a proximity probe (or inverted logic) gives a pulse that goes low at the
    mark: ``edge = "falling"`` reads it there. On its rising edge the frame would start a
    quarter of a revolution (the pulse's width) late and the spall be given to another tooth."""
    inverted = 5.0 - spalled.tach_waveform
    record = dataclasses.replace(record_of(spalled), channels={"acc": spalled.acceleration, "tach": inverted})
    campaign = campaign_for(spalled)
    assert campaign.tachometer is not None
    falling = dataclasses.replace(campaign, tachometer=dataclasses.replace(campaign.tachometer, edge="falling"))
    analysis = analyze_record(record, falling, input_sha256="0" * 64)
    assert_spall_kept(analysis, clean)
    assert analysis.provenance.parameters["tachometer"]["edge"] == "falling"
    rising = analyze_record(record, campaign, input_sha256="0" * 64)
    assert rising.channels[0].worst_tooth != SPALL_TOOTH
    assert "edge" not in rising.provenance.parameters["tachometer"]  # the default: hashes kept


@pytest.mark.parametrize("fault", ["drift", "fade"])
def test_a_tach_whose_levels_drift_or_fade_is_read_against_its_local_levels(
    spalled: SyntheticRecord, clean: RecordAnalysis, fault: str
) -> None:
    """A proximity probe's gap voltage drifting by ±3 V on a 5-V pulse, or a pulse fading to
    30 % of its height: the fixed levels lose many of the edges; the tach is read again against
    its local levels (dsp.tachlevels) and (nearly) every revolution is kept."""
    t = np.arange(spalled.tach_waveform.size) / spalled.sample_rate_hz
    tach = (spalled.tach_waveform + 3.0 * np.sin(2 * np.pi * t / 3.0) if fault == "drift"
            else spalled.tach_waveform * np.linspace(1.0, 0.3, t.size))
    record = dataclasses.replace(record_of(spalled), channels={"acc": spalled.acceleration, "tach": tach})
    analysis = analyze_record(record, campaign_for(spalled), input_sha256="0" * 64)
    assert analysis.quality.angle_source == "tachometer"
    assert not analysis.quality.tach_repairs
    assert analysis.channels[0].revolutions >= clean.channels[0].revolutions - 1
    assert_spall_kept(analysis, clean)


def _two_accelerometers(spalled: SyntheticRecord, second: np.ndarray) -> tuple[RecordData, Campaign]:
    campaign = campaign_for(spalled)
    channels = (ChannelConfig("acc", "accelerometer"), ChannelConfig("acc2", "accelerometer"),
                ChannelConfig("tach", "tachometer"))
    record = dataclasses.replace(record_of(spalled), channels={
        "acc": spalled.acceleration, "acc2": second, "tach": spalled.tach_waveform})
    return record, dataclasses.replace(campaign, channels=channels)


@pytest.mark.parametrize(
    ("second", "reason"),
    [
        ("dead", "is constant (0): a dead or disconnected sensor"),
        ("clipped", "defective samples"),
        ("nan", "defective samples"),
    ],
)
def test_a_bad_second_sensor_is_left_out_not_the_record(
    spalled: SyntheticRecord, clean: RecordAnalysis, second: str, reason: str
) -> None:
    """One of two accelerometers dead, clipped on every peak or full of NaN: the record is kept
    with the good one, and the other is named with its reason. Before, it refused the record."""
    acc = spalled.acceleration
    bad = {"dead": np.zeros_like(acc), "clipped": np.clip(10 * acc, -1.0, 1.0),
           "nan": np.where(np.arange(acc.size) % 5 == 0, np.nan, acc)}[second]
    record, campaign = _two_accelerometers(spalled, bad)
    analysis = analyze_record(record, campaign, input_sha256="0" * 64)
    assert [c.channel for c in analysis.channels] == ["acc"]
    assert reason in analysis.quality.refused_channels["acc2"]
    assert_spall_kept(analysis, clean)
    both_bad = dataclasses.replace(record, channels={**record.channels, "acc": np.zeros_like(acc)})
    with pytest.raises(RecordRejected, match="'acc' is constant"):  # every channel bad: the first's reason
        analyze_record(both_bad, campaign, input_sha256="0" * 64)


def test_a_clipped_burst_is_handled_not_refused(
    spalled: SyntheticRecord, clean: RecordAnalysis
) -> None:
    acc = spalled.acceleration.copy()
    top = acc.max()
    acc[30_000:30_600] = np.clip(3 * acc[30_000:30_600], -top, top)  # 30 ms overdriven, held at top
    analysis = analyze(spalled, acc)
    assert_spall_kept(analysis, clean)
    assert analysis.quality.clipped_samples > 50
    assert 1 <= analysis.quality.rejected_revolutions <= 2


def test_defects_lower_the_quality_score(spalled: SyntheticRecord, clean: RecordAnalysis) -> None:
    acc = spalled.acceleration.copy()
    acc[30_000:32_000] = 0.0
    damaged = analyze(spalled, acc)
    assert clean.quality.score is not None and damaged.quality.score is not None
    assert damaged.quality.score < clean.quality.score


@pytest.mark.parametrize(("fluctuation", "tolerance"), [(0.15, 1e-4), (0.20, 1e-4)])
def test_slow_speed_drift_is_analysed_with_the_exact_average(
    fluctuation: float, tolerance: float
) -> None:
    """±15 % and ±20 % drift, one slow cycle in 6 s: analysed (before: refused above 10 %); the
    average equals the exact noise-free one to ``tolerance`` of its RMS."""
    drifting = synthetic_gear_record(
        duration_s=6.0, spall_tooth=SPALL_TOOTH, spall_depth=0.1, tooth1_pitch_angle_deg=337.4,
        speed_fluctuation=fluctuation, speed_fluctuation_period_s=6.0, noise_rms=0.0,
        gear_order_amplitude=0.0, seed=4,
    )
    analysis = analyze(drifting, drifting.acceleration)
    assert analysis.quality.speed_variation > 1.8 * fluctuation  # the whole swing is in the record
    average = analysis.channels[0].curves["pinion_average"].astype(np.float64)
    exact = drifting.true_pinion_average(average.size)
    error = np.sqrt(np.mean((average - exact) ** 2) / np.mean(exact**2))
    assert error < tolerance
    assert analysis.channels[0].worst_tooth == SPALL_TOOTH
    assert analysis.quality.rejected_revolutions == 0


def test_drift_with_noise_keeps_the_spall() -> None:
    drifting = synthetic_gear_record(
        duration_s=6.0, spall_tooth=SPALL_TOOTH, spall_depth=0.1, tooth1_pitch_angle_deg=337.4,
        speed_fluctuation=0.2, speed_fluctuation_period_s=6.0, seed=5,
    )
    analysis = analyze(drifting, drifting.acceleration)
    assert analysis.channels[0].worst_tooth == SPALL_TOOTH
    assert np.delete(depths(analysis), SPALL_TOOTH - 1).max() < 0.15


def test_what_order_tracking_cannot_handle_is_refused_with_the_reason() -> None:
    # ±35 % within 6 s: (max - min)/mean ≈ 0.7
    wide = synthetic_gear_record(
        duration_s=6.0, speed_fluctuation=0.35, speed_fluctuation_period_s=6.0,
        bandwidth_hz=5000.0, seed=1,
    )
    with pytest.raises(RecordRejected, match="speed varies too much"):
        analyze(wide, wide.acceleration)
    # ±20 % twice a second: the period moves ~15 % per revolution
    fast = synthetic_gear_record(
        duration_s=3.0, speed_fluctuation=0.2, speed_fluctuation_period_s=0.5, seed=1
    )
    # the tach cannot follow; the mesh phase (dsp.tachless) is tried, and when it cannot either
    # the record keeps its raw metrics without averages, the reason stated in quality
    analysis = analyze(fast, fast.acceleration)
    assert analysis.quality.angle_source == "none"
    assert "speed changes too fast for order tracking" in analysis.quality.tach_failure
    assert analysis.quality.score is None and not analysis.channels[0].teeth


def test_quality_score_orders_clean_noisy_and_short_records(clean: RecordAnalysis) -> None:
    long_clean = synthetic_gear_record(duration_s=8.0, spall_tooth=SPALL_TOOTH, seed=7)
    noisy = synthetic_gear_record(duration_s=3.0, spall_tooth=SPALL_TOOTH, noise_rms=3.0, seed=7)
    short = synthetic_gear_record(duration_s=1.5, spall_tooth=SPALL_TOOTH, seed=7)
    scores = {
        name: analyze(rec, rec.acceleration).quality.score
        for name, rec in (("long", long_clean), ("noisy", noisy), ("short", short))
    }
    scores["clean"] = clean.quality.score
    assert all(s is not None and 0 < s <= 1 for s in scores.values())
    assert scores["long"] > scores["clean"] > scores["short"]
    assert scores["clean"] > scores["noisy"]


def test_defects_are_handled_the_same_block_by_block() -> None:
    """A long record is processed in blocks; a glitch, a dropout across a block boundary and a
    clipped burst are bridged and their revolutions dropped exactly as in whole-record processing."""
    synthetic = synthetic_gear_record(
        duration_s=8.0, spall_tooth=7, spall_depth=0.1, tooth1_pitch_angle_deg=337.4, seed=9
    )
    acc = synthetic.acceleration.copy()
    acc[10_000] = 3e38
    acc[49_900:50_300] = 0.0  # spans the boundary of the 25 000-sample blocks' 2nd and 3rd
    top = acc[np.isfinite(acc) & (acc < 1e3)].max()
    acc[100_000:100_200] = np.clip(3 * acc[100_000:100_200], -top, top)
    record, campaign = record_of(synthetic, acc), campaign_for(synthetic)
    whole = analyze_record(record, campaign, input_sha256="0" * 64)
    blocked = analyze_record(record, campaign, input_sha256="0" * 64, block_samples=25_000)
    for analysis in (whole, blocked):
        q = analysis.channels[0].quality
        assert q is not None and q.rejected_defective_revolutions >= 3
        assert (q.glitch_samples, q.dropout_samples) == (1, 400)
        assert analysis.channels[0].worst_tooth == 7
    assert blocked.quality.rejected_revolutions == whole.quality.rejected_revolutions
    assert blocked.revolutions == whole.revolutions
    scale = np.max(np.abs(whole.channels[0].curves["pinion_average"]))
    np.testing.assert_allclose(
        blocked.channels[0].curves["pinion_average"], whole.channels[0].curves["pinion_average"],
        atol=1e-6 * scale,
    )


def test_a_gain_step_within_the_record_is_not_rejected(
    spalled: SyntheticRecord, clean: RecordAnalysis
) -> None:
    acc = spalled.acceleration.copy()
    acc[40_000:] *= 3.0  # the sensor's gain changes two thirds of the way: same content, louder
    analysis = analyze(spalled, acc)
    assert analysis.channels[0].worst_tooth == SPALL_TOOTH
    assert analysis.quality.rejected_revolutions <= 1  # at most the revolution holding the step
