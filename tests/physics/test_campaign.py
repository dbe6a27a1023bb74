"""Campaign generator: ingest-format directory, determinism, formats read back by ingest."""

from __future__ import annotations

import hashlib
import tomllib
from pathlib import Path

import numpy as np
import pytest

from ingest.manifest import load_manifest
from ingest.sources import read_record
from physics.campaign import campaign_plan, write_campaign
from physics.config import model_from_toml
from physics.recordio import RecordWriteError, write_record
from physics.simulator import simulate


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_plan_same_gears_daily_variation_and_growing_spall() -> None:
    plan = campaign_plan(days=6, spall_tooth=7, onset_day=4, seed=5)
    first = plan[0].model.deviations
    for day in plan:
        dev = day.model.deviations
        assert dev.pinion_pitch_errors_um == first.pinion_pitch_errors_um
        assert dev.gear_eccentricity_um == first.gear_eccentricity_um
    assert [len(d.model.deviations.spalls) for d in plan] == [0, 0, 0, 1, 1, 1]
    spalls = [d.model.deviations.spalls[0] for d in plan[3:]]
    assert all(s.tooth == 7 and s.wheel == "pinion" for s in spalls)
    assert spalls[0].depth_um < spalls[1].depth_um < spalls[2].depth_um
    assert spalls[0].face_width_mm < spalls[1].face_width_mm < spalls[2].face_width_mm
    loads = {d.model.operating.load_torque_nm for d in plan}
    speeds = {d.model.operating.speed_rpm for d in plan}
    stiffness = {d.model.mesh.stiffness_per_length_n_per_m2 for d in plan}
    assert len(loads) == len(speeds) == len(stiffness) == 6
    assert campaign_plan(days=6, spall_tooth=7, onset_day=4, seed=5) == plan
    assert campaign_plan(days=6, spall_tooth=7, onset_day=4, seed=6) != plan
    healthy = campaign_plan(days=3, spall_tooth=None, seed=5)
    assert all(not d.model.deviations.spalls for d in healthy)


@pytest.mark.parametrize("record_format", ["wav", "hdf5", "tdms"])
def test_campaign_directory_reads_back_through_ingest(tmp_path: Path, record_format: str) -> None:
    manifest_path = write_campaign(
        tmp_path / "c", days=2, onset_day=2, seed=3, record_format=record_format, seconds=0.3
    )
    raw = tomllib.loads(manifest_path.read_text())
    assert set(raw) == {"campaign", "rig", "acquisition", "tachometer", "channels", "records"}
    assert set(raw["rig"]) == {"id", "pinion_teeth", "gear_teeth", "tooth1_pitch_angle_deg"}
    assert set(raw["tachometer"]) == {"channel", "kind", "shaft", "pulses_per_rev"}
    campaign = load_manifest(manifest_path)
    assert campaign.rig.pinion_teeth == 20 and campaign.rig.gear_teeth == 21
    assert [c.name for c in campaign.channels] == ["acc", "tach"]
    assert [r.taken_at for r in campaign.records] == [
        "2026-03-01T09:00:00Z",
        "2026-03-02T09:00:00Z",
    ]
    plan = campaign_plan(days=2, onset_day=2, seed=3)
    for entry, day in zip(campaign.records, plan, strict=True):
        record = read_record(campaign.record_path(entry), campaign)
        assert record.sample_rate_hz == 20000.0
        expected = simulate(day.model, seconds=0.3, seed=day.seed)
        tol = 1e-6 if record_format == "wav" else 0.0  # WAV stores float32
        for name in ("acc", "tach"):
            np.testing.assert_allclose(
                record.channel(name), expected.channels[name], rtol=tol, atol=tol * 10
            )
        # The per-day model is written beside the records, exactly.
        model_file = manifest_path.parent / "models" / f"day{day.day:02d}.toml"
        assert model_from_toml(model_file.read_text()) == day.model


def test_same_seed_same_files(tmp_path: Path) -> None:
    a = write_campaign(tmp_path / "a", days=2, onset_day=2, seed=9, seconds=0.2)
    b = write_campaign(tmp_path / "b", days=2, onset_day=2, seed=9, seconds=0.2)
    c = write_campaign(tmp_path / "c", days=2, onset_day=2, seed=10, seconds=0.2)
    for name in ("records/day01.wav", "records/day02.wav", "campaign.toml"):
        assert digest(a.parent / name) == digest(b.parent / name)
    assert digest(a.parent / "records/day01.wav") != digest(c.parent / "records/day01.wav")


def test_record_writer_refuses_bad_input(tmp_path: Path) -> None:
    with pytest.raises(RecordWriteError, match="unknown record format"):
        write_record(tmp_path / "x.mp3", {"a": np.zeros(3)}, 100.0)
    with pytest.raises(RecordWriteError, match="equal length"):
        write_record(tmp_path / "x.wav", {"a": np.zeros(3), "b": np.zeros(4)}, 100.0)
    with pytest.raises(RecordWriteError, match="integer sample rate"):
        write_record(tmp_path / "x.wav", {"a": np.zeros(3)}, 100.5)


def test_every_record_puts_tooth_1_where_the_manifest_says(tmp_path: Path) -> None:
    # Speeds vary from day to day, yet each record's first tach edge is the pinion reference.
    for day in campaign_plan(days=4, seed=11):
        result = simulate(day.model, seconds=0.2, seed=day.seed)
        assert result.tooth1_pitch_angle_deg == pytest.approx(337.4, abs=0.05)
