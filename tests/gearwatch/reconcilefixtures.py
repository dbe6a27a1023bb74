"""A short simulated record with a known pinion eccentricity, stored like any uploaded record,
for the reconciliation job, REST and worker tests.

Fast on purpose: 3 s at 3000 rpm and 8 kHz (7 hunting periods of a 20/21 pair), fitted with
16 samples per mesh below 2 kHz, one mechanism, one finding and a 4× coarser integrator step
in the fitting simulations.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import tomli_w
from sqlalchemy.orm import Session

ECCENTRICITY_UM = 3.0
ECCENTRICITY_PHASE_DEG = 40.0
SPEED_RPM = 3000.0
SAMPLE_RATE_HZ = 8000.0
SECONDS = 3.0
RECORD = "ecc.wav"
GARBAGE = "garbage.wav"
FAST_OPTIONS: dict[str, Any] = {
    "samples_per_mesh": 16,
    "max_frequency_hz": 2000.0,
    "mechanisms": ["pinion_eccentricity"],
    "max_findings": 1,
    "forward_oversampling": 4,
}


def base_model() -> Any:
    """The rig as configured (ideal geometry) at the record's speed and sample rate."""
    from physics.reconcile.scenarios import default_base

    base = default_base()
    return base.replace(
        operating=dataclasses.replace(base.operating, speed_rpm=SPEED_RPM),
        acquisition=dataclasses.replace(base.acquisition, sample_rate_hz=SAMPLE_RATE_HZ),
    )


def write_campaign(
    root: Path, *, campaign_id: str = "recon", rig_id: str = "rig-r", seed: int = 5
) -> Path:
    """``root/campaign.toml`` with :data:`RECORD` (the truth: the base with a pinion
    eccentricity of :data:`ECCENTRICITY_UM`) and :data:`GARBAGE` (not a WAV file)."""
    from physics.campaign import manifest_dict
    from physics.recordio import write_record
    from physics.simulator import simulate

    root.mkdir(parents=True, exist_ok=True)
    base = base_model()
    truth = base.replace(deviations=dataclasses.replace(
        base.deviations, pinion_eccentricity_um=ECCENTRICITY_UM,
        pinion_eccentricity_phase_deg=ECCENTRICITY_PHASE_DEG,
    ))
    result = simulate(truth, seconds=SECONDS, seed=seed)
    write_record(root / RECORD, result.channels, result.sample_rate_hz)
    (root / GARBAGE).write_bytes(b"RIFF but not a wave file at all " * 8)
    entries = [
        {"file": RECORD, "taken_at": "2026-03-01T09:00:00Z", "label": "eccentric"},
        {"file": GARBAGE, "taken_at": "2026-03-02T09:00:00Z", "label": "garbage"},
    ]
    manifest = manifest_dict(base, entries, campaign_id, "reconciliation test", rig_id)
    path = root / "campaign.toml"
    path.write_text(tomli_w.dumps(manifest), encoding="utf-8")
    return path


def ingest(session: Session, manifest: Path, raw_store: Any) -> dict[str, int]:
    """Store every record of the manifest (the job commits); file name → record id."""
    from gearwatch.usecases.ingest_file import process_file
    from ingest.manifest import load_manifest

    campaign = load_manifest(manifest)
    ids = {}
    for entry in campaign.records:
        job = process_file(session, campaign.record_path(entry), campaign, raw_store=raw_store)
        ids[entry.file] = job.record_id
    session.commit()
    return ids
