"""The per-tooth change of a campaign is refreshed with its own pinion's tooth count, also after
a later campaign mounted another pair on the same rig (the rig row then holds the new pair)."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import numpy as np
import pytest
import scipy.io.wavfile
import sqlalchemy as sa

from dsp.synthetic import synthetic_gear_record
from gearwatch.floor.campaign import RecordEntry
from gearwatch.usecases.ingest_file import process_file
from gearwatch.usecases.tooth_change import refresh_tooth_change
from ingest.manifest import dump_manifest, load_manifest
from storage.models import Record, ToothIndicator
from storage.raw_store import RawStore
from tests.storage import dbfixtures
from tests.storage.factories import campaign_config

_postgres_schema = dbfixtures._postgres_schema
db_url = dbfixtures.db_url
db_engine_migrated = dbfixtures.db_engine_migrated
db_engine = dbfixtures.db_engine
db_session = dbfixtures.db_session


def _campaign(folder: Path, name: str, pinion_teeth: int, gear_teeth: int, days: int) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    entries = []
    for day in range(1, days + 1):
        record = synthetic_gear_record(duration_s=4.0, noise_rms=0.05, pinion_teeth=pinion_teeth,
                                       gear_teeth=gear_teeth, seed=10 * pinion_teeth + day)
        scipy.io.wavfile.write(folder / f"day{day:02d}.wav", int(record.sample_rate_hz),
                               np.column_stack([record.acceleration, record.tach_waveform])
                               .astype(np.float32))
        taken = dt.datetime(2026, 3, day, 9, tzinfo=dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
        entries.append(RecordEntry(file=f"day{day:02d}.wav", taken_at=taken))
    config = campaign_config(name, "one-rig", pinion_teeth=pinion_teeth, gear_teeth=gear_teeth,
                             records=tuple(entries), root=folder)
    manifest = folder / "campaign.toml"
    manifest.write_text(dump_manifest(config), encoding="utf-8")
    return manifest


@pytest.mark.xdist_group("gear-pair-change")
def test_a_campaign_keeps_its_own_teeth_after_the_rig_gets_a_new_pair(db_session, tmp_path) -> None:
    store = RawStore(tmp_path / "raw-store")
    first = load_manifest(_campaign(tmp_path / "a", "pair-a", 20, 21, days=4))
    for entry in first.records:
        assert process_file(db_session, first.record_path(entry), first,
                            raw_store=store).status == "accepted"
        db_session.commit()
    second = load_manifest(_campaign(tmp_path / "b", "pair-b", 17, 43, days=1))
    result = process_file(db_session, second.record_path(second.records[0]), second, raw_store=store)
    db_session.commit()
    assert result.status == "accepted"
    campaign_a = db_session.scalar(sa.select(Record.campaign_id).where(Record.file_name == "day04.wav")
                                   .order_by(Record.id).limit(1))

    def change_teeth() -> list[int]:
        return sorted(db_session.scalars(
            sa.select(ToothIndicator.tooth).join(Record, Record.id == ToothIndicator.record_id)
            .where(Record.campaign_id == campaign_a, ToothIndicator.indicator == "change",
                   ToothIndicator.is_current.is_(True), sa.func.abs(ToothIndicator.value) < 1e300)))

    before = change_teeth()
    assert before == list(range(1, 21))  # the fourth record scored, one value per tooth
    assert refresh_tooth_change(db_session, campaign_a) == 0  # already in line: nothing rewritten
    db_session.commit()
    assert change_teeth() == before
