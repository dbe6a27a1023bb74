"""CETIM-style fatigue campaigns: one simulated record per day, then a spall that grows.

:func:`campaign_plan` (pure) draws the per-day models from a seed: the same gears every day
(pitch errors, eccentricities, tip relief drawn once), day-to-day variation of load, speed,
mesh stiffness (temperature) and sensor noise, and from ``onset_day`` on a spall on
``spall_tooth`` of the pinion that grows day by day. :func:`write_campaign` simulates the
days and writes a campaign directory in the ingest format: ``campaign.toml`` (exact keys
of the ingest manifest), ``records/dayNN.<wav|h5|tdms>`` and, for reconciliation,
``models/dayNN.toml`` (the exact model of each record).

Examples
--------
>>> from physics.campaign import campaign_plan
>>> plan = campaign_plan(days=3, spall_tooth=16, onset_day=3, seed=1)
>>> [len(day.model.deviations.spalls) for day in plan]
[0, 0, 1]
"""

from __future__ import annotations

import dataclasses
import datetime as dt
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from physics.config import GearPairModel, Mesh, Spall, model_to_toml, validate_model


@dataclass(frozen=True)
class DayPlan:
    day: int
    """1-based day number."""
    model: GearPairModel
    seed: int
    """Noise seed of this day's record."""
    temperature_c: float


@dataclass(frozen=True)
class SpallGrowth:
    """Spall size on day ``onset_day + k``: start size, then per-day growth (capped)."""

    depth_um: float = 15.0
    depth_growth_um_per_day: float = 5.0
    max_depth_um: float = 40.0
    face_width_fraction: float = 0.25
    face_width_growth_per_day: float = 1.5
    """Multiplicative growth of the face width per day."""
    max_face_width_fraction: float = 0.9
    profile_extent_mm: float = 3.5
    profile_growth_mm_per_day: float = 1.0
    max_profile_extent_mm: float = 9.0

    def spall(self, tooth: int, days_since_onset: int, face_width_mm: float) -> Spall:
        k = days_since_onset
        depth = min(self.depth_um + k * self.depth_growth_um_per_day, self.max_depth_um)
        fraction = min(
            self.face_width_fraction * self.face_width_growth_per_day**k,
            self.max_face_width_fraction,
        )
        extent = min(
            self.profile_extent_mm + k * self.profile_growth_mm_per_day,
            self.max_profile_extent_mm,
        )
        width = fraction * face_width_mm
        # Pitting starts near the pitch line, in the pinion dedendum.
        return Spall(
            wheel="pinion",
            tooth=tooth,
            depth_um=depth,
            profile_start_mm=-0.6 * extent,
            profile_extent_mm=extent,
            face_start_mm=0.5 * (face_width_mm - width),
            face_width_mm=width,
        )


def campaign_plan(
    days: int = 12,
    spall_tooth: int | None = 16,
    onset_day: int = 10,
    seed: int = 0,
    base_model: GearPairModel | None = None,
    growth: SpallGrowth | None = None,
    pitch_error_um: float = 0.25,
) -> list[DayPlan]:
    """Per-day models of a campaign (no simulation).

    Parameters
    ----------
    days
        Number of daily records.
    spall_tooth
        Pinion tooth that spalls (1-based), or None for a healthy campaign.
    onset_day
        First day with the spall (1-based); later days see it grow.
    seed
        Everything random (gear errors, daily variation, noise seeds) follows from it.
    base_model
        Model of day 1 before variation (default: the CETIM-like pair); its own
        deviations other than spalls are replaced by the campaign's gear errors.
    growth
        Spall size and growth law.
    pitch_error_um
        Standard deviation of the per-tooth index errors of both wheels (ground test gears).

    Returns
    -------
    list of DayPlan
    """
    if days < 1:
        raise ValueError("days must be ≥ 1")
    base = base_model or GearPairModel()
    growth = growth or SpallGrowth()
    geo = base.geometry
    if spall_tooth is not None and not 1 <= spall_tooth <= geo.pinion_teeth:
        raise ValueError(f"spall tooth must be within 1..{geo.pinion_teeth}")
    rng = np.random.default_rng(seed)
    # The same gears all campaign long: manufacturing errors drawn once.
    pinion_pitch = np.round(rng.normal(0.0, pitch_error_um, geo.pinion_teeth), 3)
    gear_pitch = np.round(rng.normal(0.0, pitch_error_um, geo.gear_teeth), 3)
    gears = dataclasses.replace(
        base.deviations,
        pinion_tip_relief_um=6.0,
        pinion_tip_relief_length_mm=4.0,
        gear_tip_relief_um=6.0,
        gear_tip_relief_length_mm=4.0,
        pinion_pitch_errors_um=[float(v) for v in pinion_pitch],
        gear_pitch_errors_um=[float(v) for v in gear_pitch],
        pinion_eccentricity_um=float(np.round(rng.uniform(5.0, 15.0), 3)),
        pinion_eccentricity_phase_deg=float(np.round(rng.uniform(0.0, 360.0), 3)),
        gear_eccentricity_um=float(np.round(rng.uniform(5.0, 15.0), 3)),
        gear_eccentricity_phase_deg=float(np.round(rng.uniform(0.0, 360.0), 3)),
        spalls=[],
    )
    plans = []
    for day in range(1, days + 1):
        temperature = float(np.round(45.0 + rng.normal(0.0, 4.0), 2))
        load = base.operating.load_torque_nm * float(np.clip(1 + rng.normal(0, 0.05), 0.8, 1.2))
        speed = base.operating.speed_rpm * float(np.clip(1 + rng.normal(0, 0.01), 0.97, 1.03))
        drift = float(rng.normal(0.0, 0.003))
        noise_factor = float(np.clip(1 + rng.normal(0, 0.15), 0.6, 1.5))
        # Warmer oil and teeth: a slightly softer mesh (≈ −0.1 %/°C around 45 °C).
        stiffness = base.mesh.stiffness_per_length_n_per_m2 * (1 - 0.001 * (temperature - 45.0))
        spalls: list[Spall] = []
        if spall_tooth is not None and day >= onset_day:
            spalls = [growth.spall(spall_tooth, day - onset_day, geo.face_width_mm)]
        model = base.replace(
            mesh=Mesh(
                stiffness_per_length_n_per_m2=round(stiffness, -3),
                damping_ratio=base.mesh.damping_ratio,
            ),
            operating=dataclasses.replace(
                base.operating,
                speed_rpm=round(speed, 3),
                load_torque_nm=round(load, 3),
                speed_drift_fraction=round(drift, 6),
                speed_fluctuation_fraction=0.002,
                speed_fluctuation_hz=0.7,
            ),
            deviations=dataclasses.replace(gears, spalls=spalls),
            sensors=[
                dataclasses.replace(s, noise_rms_m_s2=round(s.noise_rms_m_s2 * noise_factor, 6))
                for s in base.sensors
            ],
        )
        validate_model(model)
        plans.append(
            DayPlan(
                day=day,
                model=model,
                seed=int(rng.integers(0, 2**31 - 1)),
                temperature_c=temperature,
            )
        )
    return plans


def manifest_dict(
    model: GearPairModel,
    records: list[dict[str, str]],
    campaign_id: str,
    description: str,
    rig_id: str = "rig-1",
) -> dict[str, Any]:
    """The ingest manifest (exact keys) for records simulated with ``model``'s rig."""
    tach = model.tachometer
    channels = [{"name": s.name, "kind": "accelerometer", "unit": "m/s^2"} for s in model.sensors]
    channels.append({"name": tach.name, "kind": "tachometer", "unit": "V"})
    return {
        "campaign": {"id": campaign_id, "description": description},
        "rig": {
            "id": rig_id,
            "pinion_teeth": model.geometry.pinion_teeth,
            "gear_teeth": model.geometry.gear_teeth,
            "tooth1_pitch_angle_deg": float(tach.tooth1_pitch_angle_deg % 360.0),
        },
        "acquisition": {"sample_rate_hz": model.acquisition.sample_rate_hz},
        "tachometer": {
            "channel": tach.name,
            "kind": "pulses",
            "shaft": tach.shaft,
            "pulses_per_rev": tach.pulses_per_rev,
        },
        "channels": channels,
        "records": records,
    }


TOOTH1_TOLERANCE_DEG = 0.5
"""Largest disagreement tolerated between a record's tooth-1 angle and the manifest's."""

RECORD_SUFFIX = {"wav": ".wav", "hdf5": ".h5", "tdms": ".tdms"}


def write_campaign(
    out_dir: str | Path,
    days: int = 12,
    spall_tooth: int | None = 16,
    onset_day: int = 10,
    seed: int = 0,
    record_format: str = "wav",
    seconds: float = 12.0,
    campaign_id: str | None = None,
    start: str = "2026-03-01T09:00:00Z",
    base_model: GearPairModel | None = None,
    growth: SpallGrowth | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Path:
    """Simulate and write a campaign directory; returns the path of ``campaign.toml``.

    The same arguments give byte-identical record files.
    """
    from physics.recordio import write_record
    from physics.simulator import SimulationError, simulate

    if record_format not in RECORD_SUFFIX:
        raise ValueError(f"record format must be one of {', '.join(RECORD_SUFFIX)}")
    out = Path(out_dir)
    plans = campaign_plan(days, spall_tooth, onset_day, seed, base_model, growth)
    start_time = dt.datetime.fromisoformat(start.replace("Z", "+00:00"))
    records = []
    for plan in plans:
        name = f"day{plan.day:02d}"
        result = simulate(plan.model, seconds=seconds, seed=plan.seed)
        # One tooth-1 angle serves every record of the manifest: check this record agrees.
        drift = (
            result.tooth1_pitch_angle_deg - plans[0].model.tachometer.tooth1_pitch_angle_deg + 180
        ) % 360 - 180
        if abs(drift) > TOOTH1_TOLERANCE_DEG:
            raise SimulationError(
                f"day {plan.day}: tooth 1 sits {drift:+.2f}° from the manifest's "
                "tooth1_pitch_angle_deg after the record's first tach edge"
            )
        rel = f"records/{name}{RECORD_SUFFIX[record_format]}"
        write_record(out / rel, result.channels, result.sample_rate_hz)
        (out / "models").mkdir(parents=True, exist_ok=True)
        (out / "models" / f"{name}.toml").write_text(model_to_toml(plan.model), encoding="utf-8")
        taken = start_time + dt.timedelta(days=plan.day - 1)
        records.append(
            {
                "file": rel,
                "taken_at": taken.strftime("%Y-%m-%dT%H:%M:%SZ"),
                "label": f"day {plan.day}",
            }
        )
        if progress is not None:
            progress(plan.day, days)
    if spall_tooth is None:
        description = f"simulated spur pair fatigue test, {days} healthy days (seed {seed})"
    else:
        description = (
            f"simulated spur pair fatigue test: spall on pinion tooth {spall_tooth} "
            f"from day {onset_day} (seed {seed})"
        )
    manifest = manifest_dict(
        plans[0].model,
        records,
        campaign_id or f"sim-seed{seed}",
        description,
    )
    path = out / "campaign.toml"
    path.write_text(tomli_w.dumps(manifest), encoding="utf-8")
    return path
