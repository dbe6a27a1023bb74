"""The seed's claim on simulated data, through the project's own signal core.

A spall produces a localised W''-like pattern at the spalled tooth's angle in the pinion
average, and the default MCI puts the worst tooth on the spalled one for a mid-size spall,
while healthy days of the same campaign show no such tooth.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dsp.angle import angle_resample
from dsp.tach import pulse_times_from_waveform
from dsp.tsa import synchronous_average
from gearwatch.floor.campaign import RecordData
from gearwatch.usecases.analyze import analyze_record
from ingest.manifest import parse_manifest
from physics.campaign import campaign_plan, manifest_dict
from physics.config import Deviations, GearPairModel, Sensor, Spall, Tachometer
from physics.simulator import SimulationResult, simulate

SAMPLES_PER_REV = 20 * 64


def pinion_average(result: SimulationResult) -> np.ndarray:
    fs = result.sample_rate_hz
    pulses = pulse_times_from_waveform(result.channels["tach"], fs)
    revs = angle_resample(result.channels["acc"], fs, pulses, 1, SAMPLES_PER_REV)
    return synchronous_average(revs)


def test_spall_signature_is_a_localised_w2_pattern_at_the_tooth_angle() -> None:
    model = GearPairModel(sensors=[Sensor(noise_rms_m_s2=0.0)])
    spall = Spall(tooth=16, depth_um=15.0, profile_start_mm=-2.1, profile_extent_mm=3.5,
                  face_start_mm=7.5, face_width_mm=5.0)  # fmt: skip
    healthy = pinion_average(simulate(model, seconds=3.0))
    spalled = pinion_average(
        simulate(model.replace(deviations=Deviations(spalls=[spall])), seconds=3.0)
    )
    diff = spalled - healthy
    angle = np.arange(SAMPLES_PER_REV) * 360.0 / SAMPLES_PER_REV
    pitch16 = (model.tachometer.tooth1_pitch_angle_deg + 15 * 18.0) % 360.0
    rel = (angle - pitch16 + 180.0) % 360.0 - 180.0
    energy = diff**2
    near = energy[np.abs(rel) <= 9.0].sum() / energy.sum()
    after = energy[(rel >= -9.0) & (rel <= 27.0)].sum() / energy.sum()
    print(f"energy within ±½ pitch of tooth 16: {near:.3f}; within [−½, +1½] pitch: {after:.3f}")
    assert near > 0.6
    assert after > 0.95
    assert abs(rel[np.argmax(np.abs(diff))]) < 9.0
    # A second derivative of a window: no mean, both signs with comparable extremes.
    assert abs(diff.mean()) < 0.02 * np.sqrt(np.mean(diff**2))
    assert 1 / 3 < -diff.min() / diff.max() < 3


@pytest.mark.slow
def test_default_mci_finds_the_spalled_tooth_and_not_on_healthy_days() -> None:
    plan = campaign_plan(days=5, spall_tooth=16, onset_day=4, seed=0)
    campaign = parse_manifest(
        manifest_dict(plan[0].model, [], "proof", "proof campaign"), root=Path(".")
    )
    depths = {}
    worst = {}
    for day in plan:
        result = simulate(day.model, seconds=4.0, seed=day.seed)
        record = RecordData(result.channels, result.sample_rate_hz, source=f"day {day.day}")
        channel = analyze_record(record, campaign, input_sha256="").channels[0]
        depths[day.day] = np.array([t.mci_depth for t in channel.teeth])
        worst[day.day] = channel.worst_tooth
        print(
            f"day {day.day}: worst tooth {channel.worst_tooth}, depths {np.round(depths[day.day], 2)}"
        )
    # Mid-size spall on the onset day (25 % of the face, 15 µm, 3.5 mm), and larger the next.
    assert worst[4] == 16 and worst[5] == 16
    assert depths[5][15] > depths[4][15] > 0.6
    for healthy in (1, 2, 3):
        assert worst[healthy] != 16
        assert depths[healthy][15] < 0.1
        assert depths[healthy].max() < 0.6 * depths[4][15]


@pytest.mark.parametrize(("shaft", "pulses_per_rev"), [("gear", 1), ("pinion", 3)])
def test_tooth_numbering_holds_for_any_tach_through_the_pipeline(
    shaft: str, pulses_per_rev: int
) -> None:
    # The manifest's tooth1_pitch_angle_deg is honoured whatever shaft carries the tach and
    # however many pulses it gives: the pipeline still names the spalled tooth.
    day = campaign_plan(days=2, spall_tooth=16, onset_day=2, seed=0)[1]
    model = day.model.replace(
        tachometer=Tachometer(shaft=shaft, pulses_per_rev=pulses_per_rev)  # type: ignore[arg-type]
    )
    campaign = parse_manifest(manifest_dict(model, [], "t", "t"), root=Path("."))
    assert campaign.tachometer is not None and campaign.tachometer.shaft == shaft
    result = simulate(model, seconds=4.0, seed=day.seed)
    record = RecordData(result.channels, result.sample_rate_hz)
    assert analyze_record(record, campaign, input_sha256="").channels[0].worst_tooth == 16
