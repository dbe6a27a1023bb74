"""The per-record chain on known-answer synthetic records (dsp.synthetic)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dsp.angle import angle_resample
from dsp.synthetic import SyntheticRecord, synthetic_gear_record
from gearwatch.floor.campaign import (
    Campaign,
    ChannelConfig,
    RecordData,
    RigConfig,
    TachometerConfig,
)
from gearwatch.floor.errors import RecordFormatError, RecordRejected
from gearwatch.floor.results import METRIC_NAMES, AnalysisParameters
from gearwatch.usecases.analyze import (
    Baselines,
    analyze_record,
    clipped_fraction,
    gear_revolutions_from_pinion_grid,
)
from gearwatch.usecases.signal_checks import RAW_KURTOSIS_SPANS, checked_signal, kurtosis_span_edges

TOOTH1_DEG = 337.4


def campaign_for(
    synthetic: SyntheticRecord, *, teeth: bool = True, kind: str = "pulses"
) -> Campaign:
    return Campaign(
        id="test",
        description="",
        rig=RigConfig(
            id="rig",
            pinion_teeth=synthetic.pinion_teeth if teeth else None,
            gear_teeth=synthetic.gear_teeth if teeth else None,
            tooth1_pitch_angle_deg=synthetic.tooth1_pitch_angle_deg,
        ),
        sample_rate_hz=synthetic.sample_rate_hz,
        tachometer=TachometerConfig(
            channel="tach",
            kind=kind,  # type: ignore[arg-type]
            shaft=synthetic.tach_shaft,
            pulses_per_rev=synthetic.pulses_per_rev,
        ),
        channels=(ChannelConfig("acc", "accelerometer"), ChannelConfig("tach", "tachometer")),
    )


def record_of(synthetic: SyntheticRecord, acc: np.ndarray | None = None) -> RecordData:
    return RecordData(
        channels={
            "acc": synthetic.acceleration if acc is None else acc,
            "tach": synthetic.tach_waveform,
        },
        sample_rate_hz=synthetic.sample_rate_hz,
        source="synthetic",
    )


@pytest.fixture(scope="module")
def spalled() -> SyntheticRecord:
    return synthetic_gear_record(
        duration_s=3.0, spall_tooth=16, spall_depth=0.1, tooth1_pitch_angle_deg=TOOTH1_DEG, seed=4
    )


@pytest.mark.parametrize(
    ("spall_tooth", "tach_shaft", "pulses_per_rev"),
    [(16, "pinion", 1), (3, "gear", 1), (9, "pinion", 4), (20, "gear", 2)],
)
def test_worst_tooth_is_the_spalled_one(spall_tooth: int, tach_shaft: str, pulses_per_rev: int) -> None:
    synthetic = synthetic_gear_record(
        duration_s=3.0,
        spall_tooth=spall_tooth,
        spall_depth=0.1,
        tooth1_pitch_angle_deg=TOOTH1_DEG,
        tach_shaft=tach_shaft,  # type: ignore[arg-type]
        pulses_per_rev=pulses_per_rev,
        seed=spall_tooth,
    )
    analysis = analyze_record(record_of(synthetic), campaign_for(synthetic), input_sha256="a" * 64)
    channel = analysis.channels[0]
    assert channel.worst_tooth == spall_tooth
    depths = np.array([t.mci_depth for t in channel.teeth])
    # The well (one mesh period wide, delayed by the transfer path) may spill into the next
    # tooth's sector; every tooth that is not a neighbour stays far shallower.
    neighbours = {(spall_tooth - 2) % 20, spall_tooth - 1, spall_tooth % 20}
    others = np.delete(depths, sorted(neighbours))
    assert depths[spall_tooth - 1] > 3 * np.max(others)  # negative depths are humps, not wells
    assert [t.tooth for t in channel.teeth] == list(range(1, 21))


def test_healthy_record_shows_no_deep_well() -> None:
    healthy = synthetic_gear_record(duration_s=3.0, tooth1_pitch_angle_deg=TOOTH1_DEG, seed=4)
    spalled = synthetic_gear_record(
        duration_s=3.0, spall_tooth=16, spall_depth=0.1, tooth1_pitch_angle_deg=TOOTH1_DEG, seed=4
    )
    depth = {}
    for name, synthetic in (("healthy", healthy), ("spalled", spalled)):
        channel = analyze_record(
            record_of(synthetic), campaign_for(synthetic), input_sha256="a" * 64
        ).channels[0]
        depth[name] = max(t.mci_depth for t in channel.teeth)
    assert depth["spalled"] > 4 * depth["healthy"]


def test_result_shape_metrics_curves_and_provenance(spalled: SyntheticRecord) -> None:
    params = AnalysisParameters(mci_form="literal")
    analysis = analyze_record(
        record_of(spalled), campaign_for(spalled), params, input_sha256="b" * 64
    )
    channel = analysis.channels[0]
    assert list(channel.metrics) == list(METRIC_NAMES)
    assert all(np.isfinite(v) for v in channel.metrics.values())
    assert channel.samples_per_rev == 20 * 64
    assert channel.curves["pinion_average"].shape == (1280,)
    assert channel.curves["gear_average"].shape == (21 * 64,)
    assert channel.curves["mci"].dtype == np.float32
    # 3 s at 1000 rpm ≈ 50 revolutions; the first pulse comes within one revolution.
    assert 45 <= analysis.revolutions <= 50
    assert abs(analysis.speed_rpm - 1000.0) < 15.0
    assert analysis.provenance.input_sha256 == "b" * 64
    assert analysis.provenance.parameters["mci_form"] == "literal"
    assert analysis.provenance.parameters["pinion_teeth"] == 20
    assert analysis.provenance.code_version
    as_json = analysis.to_json()
    assert {"revolutions", "speed_rpm", "samples_per_rev", "teeth", "worst_tooth", "metrics",
            "quality", "provenance"} <= set(as_json)


def test_gear_average_from_the_pinion_grid_equals_a_second_resampling(
    spalled: SyntheticRecord,
) -> None:
    fs = spalled.sample_rate_hz
    pulses = spalled.pulse_times_s
    pinion_revs = angle_resample(spalled.acceleration, fs, pulses, 1, 20 * 64)
    direct = angle_resample(spalled.acceleration, fs, pulses, 1, 21 * 64, shaft_ratio=20 / 21)
    regrouped = gear_revolutions_from_pinion_grid(pinion_revs, 21 * 64)
    rows = min(direct.shape[0], regrouped.shape[0])
    assert rows >= direct.shape[0] - 1
    scale = np.sqrt(np.mean(direct**2))
    assert np.max(np.abs(direct[:rows] - regrouped[:rows])) < 1e-6 * scale


def test_gear_shaft_component_lands_in_the_gear_average_only(spalled: SyntheticRecord) -> None:
    channel = analyze_record(
        record_of(spalled), campaign_for(spalled), input_sha256="c" * 64
    ).channels[0]
    gear_truth = spalled.true_gear_average(21 * 64)
    error = channel.curves["gear_average"] - gear_truth
    assert np.sqrt(np.mean(error**2)) < 0.1 * np.sqrt(np.mean(gear_truth**2))


def test_without_tooth_counts_per_tooth_results_are_omitted(spalled: SyntheticRecord) -> None:
    analysis = analyze_record(
        record_of(spalled), campaign_for(spalled, teeth=False), input_sha256="d" * 64
    )
    channel = analysis.channels[0]
    assert channel.teeth == [] and channel.worst_tooth is None
    assert set(channel.metrics) == {"rms", "peak", "crest", "kurtosis", "raw_rms", "raw_kurtosis"}
    assert channel.samples_per_rev == AnalysisParameters().samples_per_rev_without_teeth


def test_pulse_time_tachometer(spalled: SyntheticRecord) -> None:
    record = RecordData(
        {"acc": spalled.acceleration, "tach": spalled.pulse_times_s}, spalled.sample_rate_hz
    )
    channel = analyze_record(
        record, campaign_for(spalled, kind="pulse_times"), input_sha256="e" * 64
    ).channels[0]
    assert channel.worst_tooth == 16


def test_raw_signal_metrics_against_scipy(spalled: SyntheticRecord) -> None:
    import scipy.stats

    channel = analyze_record(
        record_of(spalled), campaign_for(spalled), input_sha256="f" * 64
    ).channels[0]
    x = spalled.acceleration
    edges = kurtosis_span_edges(x.size)
    assert 1 < edges.size - 1 <= RAW_KURTOSIS_SPANS  # a 3-s record: 14 spans of 4096+ samples
    spans = np.split(x, edges[1:-1])
    assert channel.metrics["raw_kurtosis"] == pytest.approx(
        np.average([scipy.stats.kurtosis(span, fisher=False) for span in spans],
                   weights=[span.size for span in spans]))
    assert channel.metrics["raw_rms"] == pytest.approx(np.std(x))


def test_raw_kurtosis_does_not_see_a_level_that_drifts_along_the_record() -> None:
    """A speed sweeping through a resonance makes the vibration's level rise and fall within the
    record; the whole record's kurtosis then rises (a mix of Gaussians of different variance),
    each span's does not. An impulse every revolution raises both."""
    import scipy.stats

    rng = np.random.default_rng(11)
    n = 200_000
    level = 1.0 + 0.8 * np.exp(-(((np.arange(n) - 0.6 * n) / (0.12 * n)) ** 2))  # a resonance passed
    swept = rng.normal(size=n) * level
    impulsive = rng.normal(size=n)
    impulsive[::400] += 8.0 * rng.choice([-1.0, 1.0], size=impulsive[::400].size)

    def raw_kurtosis(x: np.ndarray) -> float:
        return checked_signal(RecordData({"acc": x}, 20_000.0), "acc", 1 << 16,
                              AnalysisParameters()).raw_metrics["raw_kurtosis"]

    assert scipy.stats.kurtosis(swept, fisher=False) > 3.4  # the whole record's is lifted
    assert raw_kurtosis(swept) == pytest.approx(3.0, abs=0.1)
    assert raw_kurtosis(impulsive) == pytest.approx(scipy.stats.kurtosis(impulsive, fisher=False), rel=0.05)
    assert raw_kurtosis(impulsive) > 4.0


def test_explicit_na4_baseline_changes_na4_only(spalled: SyntheticRecord) -> None:
    own = analyze_record(record_of(spalled), campaign_for(spalled), input_sha256="f" * 64)
    variance = own.channels[0].baseline_stats["residual_variance"]
    halved = analyze_record(
        record_of(spalled),
        campaign_for(spalled),
        input_sha256="f" * 64,
        baselines={"acc": Baselines(na4_residual_variance=2 * variance)},
    )
    assert halved.channels[0].metrics["na4"] == pytest.approx(own.channels[0].metrics["na4"] / 4)
    assert halved.channels[0].metrics["fm4"] == own.channels[0].metrics["fm4"]


def test_a_few_nan_samples_are_bridged_many_are_refused(spalled: SyntheticRecord) -> None:
    acc = spalled.acceleration.copy()
    acc[1000] = np.nan
    acc[2000] = np.inf
    analysis = analyze_record(record_of(spalled, acc), campaign_for(spalled), input_sha256="0" * 64)
    assert analysis.quality.glitch_samples == 2
    assert analysis.channels[0].worst_tooth == 16
    acc[::10] = np.nan  # 10 % of the samples
    with pytest.raises(RecordRejected, match="defective samples"):
        analyze_record(record_of(spalled, acc), campaign_for(spalled), input_sha256="0" * 64)


def test_clipped_sensor_is_rejected(spalled: SyntheticRecord) -> None:
    acc = np.clip(spalled.acceleration, -1.0, 1.0)
    assert clipped_fraction(acc) > 0.01
    assert clipped_fraction(spalled.acceleration) == 0.0
    slightly = spalled.acceleration.copy()
    slightly[1000:1010] = slightly.max()  # one stretch of 10 samples: bridged and counted
    accepted = analyze_record(record_of(spalled, slightly), campaign_for(spalled),
                              input_sha256="0" * 64)
    assert accepted.quality.clipped_fraction == pytest.approx(10 / slightly.size)
    assert accepted.quality.clipped_samples == 10
    assert accepted.quality.rejected_revolutions == 1
    with pytest.raises(RecordRejected, match="clipped"):
        analyze_record(record_of(spalled, acc), campaign_for(spalled), input_sha256="0" * 64)


def test_too_few_revolutions_are_rejected() -> None:
    short = synthetic_gear_record(duration_s=0.9, seed=2)  # 15 revolutions at 1000 rpm
    with pytest.raises(RecordRejected, match="revolutions"):
        analyze_record(record_of(short), campaign_for(short), input_sha256="0" * 64)


def test_no_tach_pulses_fall_back_to_the_mesh_phase(spalled: SyntheticRecord) -> None:
    # issue 11: a dead tach no longer loses the record (tests/gearwatch/test_tachless.py)
    record = RecordData(
        {"acc": spalled.acceleration, "tach": np.zeros_like(spalled.tach_waveform)},
        spalled.sample_rate_hz,
    )
    analysis = analyze_record(record, campaign_for(spalled), input_sha256="0" * 64)
    assert "no tachometer pulses" in analysis.quality.tach_failure
    assert analysis.quality.angle_source in ("mesh_phase", "none")
    assert not analysis.channels[0].teeth  # no speed hint in this manifest: teeth refused
    assert analysis.channels[0].metrics["raw_rms"] > 0


def test_wrong_sample_rate_is_rejected_as_speed_out_of_range(spalled: SyntheticRecord) -> None:
    record = dataclasses.replace(record_of(spalled), sample_rate_hz=spalled.sample_rate_hz * 1e3)
    campaign = dataclasses.replace(campaign_for(spalled), sample_rate_hz=None)
    params = AnalysisParameters(max_speed_rpm=20_000.0)
    with pytest.raises(RecordRejected, match="speed"):
        analyze_record(record, campaign, params, input_sha256="0" * 64)


def test_sample_rate_that_disagrees_with_the_manifest_is_rejected(spalled: SyntheticRecord) -> None:
    record = dataclasses.replace(record_of(spalled), sample_rate_hz=25_600.0)
    with pytest.raises(RecordRejected, match="25600 Hz differs from the manifest's"):
        analyze_record(record, campaign_for(spalled), input_sha256="0" * 64)


def test_missing_channel_is_a_format_error(spalled: SyntheticRecord) -> None:
    record = RecordData({"tach": spalled.tach_waveform}, spalled.sample_rate_hz, source="x.wav")
    with pytest.raises(RecordFormatError, match="'acc' not found"):
        analyze_record(record, campaign_for(spalled), input_sha256="0" * 64)


def test_manifest_without_tachometer_keeps_the_record(spalled: SyntheticRecord) -> None:
    campaign = dataclasses.replace(campaign_for(spalled), tachometer=None)
    analysis = analyze_record(record_of(spalled), campaign, input_sha256="0" * 64)
    assert analysis.quality.angle_source in ("mesh_phase", "none")
    assert analysis.quality.per_tooth  # why there are no per-tooth numbers
    assert analysis.channels[0].metrics["raw_rms"] > 0


@pytest.mark.parametrize(("tach_shaft", "pulses_per_rev"), [("pinion", 1), ("gear", 2)])
def test_block_by_block_processing_equals_whole_record(tach_shaft: str, pulses_per_rev: int) -> None:
    """A long record is processed in blocks of whole hunting periods with context on each side;
    the results must be those of processing it whole (here forced with tiny blocks)."""
    synthetic = synthetic_gear_record(
        duration_s=8.0, spall_tooth=7, spall_depth=0.1, tooth1_pitch_angle_deg=TOOTH1_DEG,
        tach_shaft=tach_shaft, pulses_per_rev=pulses_per_rev, seed=9,  # type: ignore[arg-type]
    )
    record, campaign = record_of(synthetic), campaign_for(synthetic)
    whole = analyze_record(record, campaign, input_sha256="0" * 64).channels[0]
    # ~1.3 s blocks: 6 blocks of one hunting period (21 pinion revolutions) each
    blocked = analyze_record(
        record, campaign, input_sha256="0" * 64, block_samples=25_000
    ).channels[0]
    assert blocked.revolutions == whole.revolutions
    assert blocked.gear_revolutions == whole.gear_revolutions
    for name in ("pinion_average", "gear_average", "mci"):
        scale = np.max(np.abs(whole.curves[name]))
        np.testing.assert_allclose(blocked.curves[name], whole.curves[name], atol=1e-6 * scale)
    for key, value in whole.metrics.items():
        assert blocked.metrics[key] == pytest.approx(value, rel=1e-6), key
    assert blocked.worst_tooth == whole.worst_tooth == 7
