"""A sensor gain step in a healthy campaign, through the real chain and the default rules.

The gain doubles from the fifth of eight daily records. NA4 as stored divides by the running
mean residual variance of the earlier records, so it jumps by 2⁴ = 16 there (the fourth moment
scales with the gain⁴, the earlier records' variance not at all); its rule
is created disabled (:mod:`detection.default_rules`). The enabled whole-record rules are on
ratios of one record's own moments (FM4, the residual's kurtosis, the kurtosis of the average and
of the raw signal), which a gain cancels: none of them, nor a per-tooth rule, may open an alarm.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import numpy as np
import pytest
import scipy.io.wavfile

from dsp.synthetic import synthetic_gear_record
from gearwatch.usecases.ingest_file import process_file
from ingest.manifest import load_manifest
from storage.raw_store import RawStore
from storage.repositories import (
    AlarmRepository,
    AlarmRuleRepository,
    RecordRepository,
    TrendRepository,
)
from tests.storage import dbfixtures

_postgres_schema = dbfixtures._postgres_schema
db_url = dbfixtures.db_url
db_engine_migrated = dbfixtures.db_engine_migrated
db_engine = dbfixtures.db_engine
db_session = dbfixtures.db_session

DAYS = 8
GAIN_STEP_DAY = 5
GAIN = 2.0


def _campaign(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    entries = []
    for day in range(1, DAYS + 1):
        record = synthetic_gear_record(duration_s=10.0, noise_rms=0.05, tooth1_pitch_angle_deg=337.4,
                                       seed=100 + day)
        gain = GAIN if day >= GAIN_STEP_DAY else 1.0
        channels = np.column_stack([gain * record.acceleration, record.tach_waveform])
        scipy.io.wavfile.write(folder / f"day{day:02d}.wav", int(record.sample_rate_hz),
                               channels.astype(np.float32))
        taken = dt.datetime(2026, 3, day, 9, tzinfo=dt.UTC).isoformat()
        entries.append(f'    {{ file = "day{day:02d}.wav", taken_at = "{taken}" }},')
    manifest = folder / "campaign.toml"
    manifest.write_text(
        "records = [\n" + "\n".join(entries) + "\n]\n\n"
        '[campaign]\nid = "gain-step"\n\n'
        '[rig]\nid = "gain-rig"\npinion_teeth = 20\ngear_teeth = 21\ntooth1_pitch_angle_deg = 337.4\n\n'
        '[tachometer]\nchannel = "tach"\n\n'
        '[[channels]]\nname = "acc"\nkind = "accelerometer"\n\n'
        '[[channels]]\nname = "tach"\nkind = "tachometer"\n',
        encoding="utf-8",
    )
    return manifest


@pytest.mark.xdist_group("gain-step")
def test_a_gain_step_opens_no_default_alarm(db_session, tmp_path) -> None:
    campaign = load_manifest(_campaign(tmp_path / "camp"))
    store = RawStore(tmp_path / "raw-store")
    for entry in campaign.records:
        result = process_file(db_session, campaign.record_path(entry), campaign, raw_store=store)
        db_session.commit()
        assert result.status == "accepted", result
    rig_id = RecordRepository(db_session).get(result.record_id).rig_id
    trends = TrendRepository(db_session)

    def metric(name: str) -> np.ndarray:
        points = trends.metric_trend(rig_id, name)
        return np.array([p.value for p in points])

    # what the gain does to each: the stored NA4 jumps on the step day, the ratios do not move
    na4, residual_kurtosis = metric("na4"), metric("residual_kurtosis")
    step = GAIN_STEP_DAY - 1
    # NA4 = residual kurtosis × (own residual variance / earlier records' mean)²: that ratio moves
    # by ±20 % from day to day here, and by the gain² on the step day
    ratio = na4 / residual_kurtosis
    assert np.all((ratio[:step] > 0.5) & (ratio[:step] < 2.0))
    assert ratio[step] > GAIN**4 / 2
    for name in ("fm4", "residual_kurtosis", "kurtosis", "raw_kurtosis"):
        values = metric(name)
        assert values[step] == pytest.approx(np.median(values[:step]), rel=0.15), name

    opened = [(a.indicator, a.tooth) for a in AlarmRepository(db_session).list(rig_id=rig_id)]
    assert opened == []
    rules = {r.indicator: r for r in AlarmRuleRepository(db_session).list(rig_id)}
    assert not rules["na4"].enabled
