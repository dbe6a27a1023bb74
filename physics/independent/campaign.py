"""Campaigns of the independent generator: day plans, in-memory records, a campaign folder.

:func:`campaign_days` (pure) turns a base model into one model per day: the same gears every
day, day-to-day load and speed changes, a spall from ``onset_day`` whose depth follows
``depths_um`` (e.g. 4 → 8 → 15 → 25 µm), an optional gain step and glitchy days.
:func:`generate_campaign` yields the records in memory; :func:`write_campaign` writes a
gearwatch campaign folder (``campaign.toml`` through :func:`ingest.manifest.dump_manifest`,
``records/dayNN.<wav|h5|tdms>``) plus ``truth.json`` with every parameter of every day.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from physics.independent.generator import IndependentRecord, campaign_for, generate_record
from physics.independent.model import IndependentModel, Spall, model_to_dict, validate_model

RECORD_SUFFIX = {"wav": ".wav", "hdf5": ".h5", "tdms": ".tdms"}


@dataclass(frozen=True)
class CampaignDay:
    day: int
    """1-based day number."""
    model: IndependentModel
    seed: int
    """Seed of this day's record (noise, initial angle, speed shape, artefacts)."""
    changes: dict[str, Any] = field(default_factory=dict)
    """What differs from the base model today (load/speed factor, gain, spall depth, glitches)."""


def campaign_days(
    base: IndependentModel,
    days: int = 8,
    *,
    onset_day: int | None = 5,
    spall: Spall | None = None,
    depths_um: Sequence[float] = (4.0, 8.0, 15.0, 25.0),
    extents: Sequence[float] | None = None,
    face_fractions: Sequence[float] | None = None,
    load_jitter: float = 0.0,
    speed_jitter: float = 0.0,
    stiffness_jitter: float = 0.0,
    noise_jitter: float = 0.0,
    gain_step_day: int | None = None,
    gain_step_factor: float = 2.0,
    glitch_days: Sequence[int] = (),
    glitches_per_day: int = 1,
    seed: int = 0,
) -> list[CampaignDay]:
    """Per-day models of a campaign (no simulation).

    Parameters
    ----------
    base
        The rig and gears (its own spalls are replaced by the campaign's).
    days
        Number of daily records.
    onset_day
        First day with the spall (1-based); None: a healthy campaign.
    spall
        Template of the spall (tooth, extent, position, face fraction); default: pinion tooth
        ``Z1 // 2 + 1``, extent 0.3, face 0.3. Its depth is replaced by ``depths_um``.
    depths_um
        Depth on the onset day, the next day, …; the last value holds afterwards.
    extents, face_fractions
        Optional extent along the path of contact and face fraction per day after onset (same
        rule). Note: once a pit is deeper than the local contact approach (a few µm) its depth
        hardly matters; a real pit grows in area too, which these give.
    load_jitter, speed_jitter, stiffness_jitter, noise_jitter
        Day-to-day factors of the load, the speed, the mesh stiffness (oil and tooth
        temperature) and the noise ratio, drawn uniformly in ``1 ± jitter``.
    gain_step_day
        From this day on the sensor gain is multiplied by ``gain_step_factor``.
    glitch_days
        Days whose record gets ``glitches_per_day`` glitch samples.
    seed
        Day-to-day draws and the records' seeds follow from it.
    """
    if days < 1:
        raise ValueError("days must be ≥ 1")
    if onset_day is not None and not 1 <= onset_day <= days:
        raise ValueError(f"onset_day must be within 1..{days}")
    if not depths_um:
        raise ValueError("depths_um needs at least one depth")
    validate_model(base)
    template = spall or Spall(tooth=base.geometry.pinion_teeth // 2 + 1, extent_fraction=0.3,
                              face_fraction=0.3)
    rng = np.random.default_rng(seed)
    plans = []
    for day in range(1, days + 1):
        load_factor = float(1 + rng.uniform(-load_jitter, load_jitter))
        speed_factor = float(1 + rng.uniform(-speed_jitter, speed_jitter))
        record_seed = int(rng.integers(0, 2**31 - 1))
        stiffness_factor = float(1 + rng.uniform(-stiffness_jitter, stiffness_jitter))
        noise_factor = float(1 + rng.uniform(-noise_jitter, noise_jitter))
        changes: dict[str, Any] = {
            "load_factor": load_factor,
            "speed_factor": speed_factor,
            "stiffness_factor": stiffness_factor,
            "noise_factor": noise_factor,
        }
        spalls: tuple[Spall, ...] = ()
        if onset_day is not None and day >= onset_day:
            k = day - onset_day
            depth = float(depths_um[min(k, len(depths_um) - 1)])
            sp = dataclasses.replace(template, depth_um=depth)
            if extents:
                sp = dataclasses.replace(sp, extent_fraction=float(extents[min(k, len(extents) - 1)]))
            if face_fractions:
                sp = dataclasses.replace(
                    sp, face_fraction=float(face_fractions[min(k, len(face_fractions) - 1)])
                )
            spalls = (sp,)
            changes["spall_depth_um"] = depth
            changes["spall_extent_fraction"] = sp.extent_fraction
            changes["spall_face_fraction"] = sp.face_fraction
        gain = base.acquisition.gain
        if gain_step_day is not None and day >= gain_step_day:
            gain *= gain_step_factor
        changes["gain"] = gain
        artefacts = base.artefacts
        if day in glitch_days:
            artefacts = dataclasses.replace(artefacts, glitches=artefacts.glitches + glitches_per_day)
            changes["glitches"] = artefacts.glitches
        model = base.replace(
            spalls=spalls,
            operating=dataclasses.replace(
                base.operating,
                speed_rpm=base.operating.speed_rpm * speed_factor,
                load_torque_nm=base.operating.load_torque_nm * load_factor,
            ),
            stiffness=dataclasses.replace(
                base.stiffness,
                peak_n_per_m_per_mm=base.stiffness.peak_n_per_m_per_mm * stiffness_factor,
            ),
            acquisition=dataclasses.replace(
                base.acquisition,
                gain=gain,
                noise_to_signal=base.acquisition.noise_to_signal * noise_factor,
            ),
            artefacts=artefacts,
        )
        validate_model(model)
        plans.append(CampaignDay(day=day, model=model, seed=record_seed, changes=changes))
    return plans


def generate_campaign(plan: Sequence[CampaignDay]) -> Iterator[IndependentRecord]:
    """The records of ``plan``, one per day, in memory (each with its truth)."""
    for day in plan:
        record = generate_record(day.model, seed=day.seed)
        record.truth["day"] = day.day
        record.truth["changes"] = day.changes
        yield record


def write_campaign(
    out_dir: str | Path,
    plan: Sequence[CampaignDay],
    *,
    campaign_id: str = "independent",
    record_format: str = "wav",
    start: str = "2026-03-01T09:00:00Z",
    description: str | None = None,
) -> Path:
    """Simulate ``plan`` and write a gearwatch campaign folder; returns ``campaign.toml``'s path.

    Writes ``records/dayNN<suffix>``, ``campaign.toml`` (through
    :func:`ingest.manifest.dump_manifest`) and ``truth.json`` (every day's parameters and
    derived values). Every day must share the rig (tooth counts, tach, rate, channels).
    """
    from gearwatch.floor.campaign import RecordEntry
    from ingest.manifest import dump_manifest
    from physics.recordio import write_record

    if record_format not in RECORD_SUFFIX:
        raise ValueError(f"record format must be one of {', '.join(RECORD_SUFFIX)}")
    if not plan:
        raise ValueError("the plan has no day")
    rig = _rig_key(plan[0].model)
    for day in plan:
        if _rig_key(day.model) != rig:
            raise ValueError(f"day {day.day}: the rig (teeth, tach, rate, channels) differs from day 1")
    out = Path(out_dir)
    start_time = dt.datetime.fromisoformat(start.replace("Z", "+00:00"))
    entries = []
    truths = []
    for record, day in zip(generate_campaign(plan), plan, strict=True):
        rel = f"records/day{day.day:02d}{RECORD_SUFFIX[record_format]}"
        write_record(out / rel, record.channels, record.sample_rate_hz)
        taken = start_time + dt.timedelta(days=day.day - 1)
        entries.append(
            RecordEntry(file=rel, taken_at=taken.strftime("%Y-%m-%dT%H:%M:%SZ"), label=f"day {day.day}")
        )
        truths.append({"file": rel, **record.truth})
    first = truths[0]
    campaign = campaign_for(first, campaign_id=campaign_id, records=tuple(entries))
    if description is not None:
        campaign = dataclasses.replace(campaign, description=description)
    path = out / "campaign.toml"
    path.write_text(dump_manifest(campaign), encoding="utf-8")
    (out / "truth.json").write_text(
        json.dumps({"campaign_id": campaign_id, "base_model": model_to_dict(plan[0].model),
                    "days": truths}, indent=1),
        encoding="utf-8",
    )
    return path


def _rig_key(model: IndependentModel) -> tuple[Any, ...]:
    t = model.tachometer
    return (
        model.geometry.pinion_teeth,
        model.geometry.gear_teeth,
        t.present,
        t.name,
        t.tooth1_pitch_angle_deg,
        model.acquisition.sample_rate_hz,
        model.acquisition.accelerometer_name,
    )
