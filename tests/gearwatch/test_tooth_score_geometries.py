"""Per-tooth score through the whole per-record chain on simulated pairs of other geometries.

Contact ratios 1.4 and 1.9 (the issue's failing cases on another simulator), a 17/43 pair, a
spall narrower and one wider than a mesh period: the score names the spalled tooth, and a
healthy record names no tooth (``worst_tooth`` is ``None``).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from gearwatch.floor.campaign import RecordData
from gearwatch.usecases.analyze import analyze_record
from ingest.manifest import parse_manifest
from physics.campaign import manifest_dict
from physics.config import Deviations, GearPairModel, Geometry, Operating, Sensor, Spall
from physics.simulator import model_geometry, simulate

MESH_HZ = 500.0


def pair(teeth: tuple[int, int], pressure_deg: float, addendum: float) -> GearPairModel:
    geometry = Geometry(
        pinion_teeth=teeth[0], gear_teeth=teeth[1], pressure_angle_deg=pressure_deg,
        addendum_coefficient=addendum, dedendum_coefficient=addendum + 0.25,
        module_mm=200.0 / teeth[0],
    )
    return GearPairModel(
        geometry=geometry,
        operating=Operating(speed_rpm=MESH_HZ * 60.0 / teeth[0]),
        deviations=Deviations(pinion_tip_relief_um=6.0, pinion_tip_relief_length_mm=2.0,
                              gear_tip_relief_um=6.0, gear_tip_relief_length_mm=2.0),
        sensors=[Sensor(noise_rms_m_s2=0.5)],
    )


def analyse(model: GearPairModel, seed: int) -> tuple[int | None, np.ndarray]:
    seconds = 24.0 * 60.0 / model.operating.speed_rpm
    result = simulate(model, seconds=seconds, seed=seed)
    manifest = manifest_dict(model, [{"file": "r.wav", "taken_at": "2026-03-01T09:00:00Z"}], "c", "")
    campaign = parse_manifest(manifest, root=Path("."), check_files=False)
    record = RecordData(channels=result.channels, sample_rate_hz=result.sample_rate_hz)
    channel = analyze_record(record, campaign, input_sha256="0" * 64).channels[0]
    return channel.worst_tooth, np.array([t.score for t in channel.teeth])


@pytest.mark.parametrize(
    ("teeth", "pressure_deg", "addendum", "contact_ratio", "extent_fraction", "tooth"),
    [
        ((20, 21), 25.0, 1.0, 1.41, 0.15, 7),   # contact ratio 1.4, narrow spall
        ((20, 21), 20.0, 1.15, 1.76, 0.6, 12),  # wide spall: longer than a mesh period
        ((80, 81), 25.0, 1.2, 1.88, 0.3, 33),   # contact ratio 1.9, 80 teeth
        ((17, 43), 20.0, 1.0, 1.62, 0.3, 9),    # 17/43 (once named tooth k + 1)
    ],
)
def test_the_spalled_tooth_stands_out(
    teeth: tuple[int, int], pressure_deg: float, addendum: float, contact_ratio: float,
    extent_fraction: float, tooth: int,
) -> None:
    model = pair(teeth, pressure_deg, addendum)
    geometry = model_geometry(model)
    assert geometry.contact_ratio == pytest.approx(contact_ratio, abs=0.02)
    extent_mm = extent_fraction * geometry.path_length_m * 1e3
    spall = Spall(tooth=tooth, depth_um=5.0, profile_start_mm=-0.6 * extent_mm,
                  profile_extent_mm=extent_mm, face_start_mm=5.0, face_width_mm=10.0)
    spalled = model.replace(deviations=dataclasses.replace(model.deviations, spalls=[spall]))
    worst, scores = analyse(spalled, seed=3)
    assert worst == tooth, f"scores {np.round(scores, 1)}"


def test_a_healthy_record_names_no_tooth() -> None:
    worst, scores = analyse(pair((20, 21), 20.0, 1.0), seed=4)
    assert worst is None, f"scores {np.round(scores, 1)}"
