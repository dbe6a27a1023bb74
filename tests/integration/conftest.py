"""Fixtures of the end-to-end tests: campaigns built once per session, fresh databases.

* :func:`pcm_campaign`: the simulator's 12-day campaign (spall on pinion tooth 16 from day 10),
  short records, rewritten as 16-bit PCM WAV with a fixed full scale per channel, as a DAQ
  records it. The manifest is kept as written by the simulator. Integer samples are what
  lets the CAN replay be compared bit for bit with the file replay.
* :func:`backend` / :func:`fresh_database`: every test runs on SQLite AND PostgreSQL; each call
  of ``fresh_database()`` gives a new, migrated, empty database (a temp SQLite file, or a new
  schema on the PostgreSQL server of ``GEARWATCH_TEST_POSTGRES_URL``, unreachable →
  :func:`tests.conftest.service_unavailable`, which fails under CI). The schema handling is
  :mod:`tests.storage.dbfixtures`'.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest
import scipy.io.wavfile
import sqlalchemy as sa
from sqlalchemy.orm import Session, sessionmaker

from tests.storage.dbfixtures import BACKENDS, _PostgresSchema

CAMPAIGN_SEED = 7
CAMPAIGN_DAYS = 12
SPALL_TOOTH = 16
SPALL_ONSET_DAY = 10
RECORD_SECONDS = 3.0
"""Short records (60 000 samples at 20 kHz, ~150 pinion revolutions): enough revolutions for
the synchronous average, fast enough to replay a whole campaign four times."""

PCM_FULL_SCALE = {"acc": 64.0, "tach": 8.0}
"""Full scale per channel (m/s², V): the DAQ's input ranges (the spalled last day peaks near
40 m/s²; the TTL tachometer is 0/5 V)."""
PCM_MAX_COUNT = 32766
"""Largest |count| written: the CAN protocol reserves -32768, -32767 and 32767."""


def to_pcm16(samples: np.ndarray, full_scale: float) -> np.ndarray:
    """int16 PCM counts of ``samples`` for an ADC whose ±full scale is ±32768 counts."""
    counts = np.rint(np.asarray(samples, dtype=np.float64) / full_scale * 32768.0)
    peak = float(np.abs(counts).max())
    if peak > PCM_MAX_COUNT:
        raise AssertionError(f"signal reaches {peak:.0f} counts: full scale {full_scale} too small")
    return counts.astype(np.int16)


def rewrite_as_pcm16(path: Path, channel_names: list[str]) -> None:
    """Replace a float WAV record by its 16-bit PCM version (same channels, same rate)."""
    rate_hz, data = scipy.io.wavfile.read(path)
    frames = np.asarray(data).reshape(data.shape[0], -1)
    pcm = np.column_stack(
        [to_pcm16(frames[:, i], PCM_FULL_SCALE[name]) for i, name in enumerate(channel_names)]
    )
    scipy.io.wavfile.write(path, rate_hz, pcm)


@pytest.fixture(scope="session")
def pcm_campaign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``campaign.toml`` of the simulated campaign with its records as 16-bit PCM WAV."""
    from ingest.manifest import load_manifest
    from physics.campaign import write_campaign

    folder = tmp_path_factory.mktemp("pcm-campaign")
    manifest = write_campaign(
        folder,
        days=CAMPAIGN_DAYS,
        spall_tooth=SPALL_TOOTH,
        onset_day=SPALL_ONSET_DAY,
        seed=CAMPAIGN_SEED,
        record_format="wav",
        seconds=RECORD_SECONDS,
    )
    campaign = load_manifest(manifest)
    names = [channel.name for channel in campaign.channels]
    assert set(names) == set(PCM_FULL_SCALE), names
    for entry in campaign.records:
        rewrite_as_pcm16(campaign.record_path(entry), names)
    return manifest


@dataclasses.dataclass
class Database:
    backend: str
    url: str
    engine: sa.Engine
    factory: sessionmaker[Session]


@pytest.fixture(scope="session", params=BACKENDS)
def backend(request: pytest.FixtureRequest) -> str:
    return str(request.param)


@pytest.fixture(scope="session")
def fresh_database(
    backend: str, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[Callable[[], Database]]:
    """``fresh_database()`` → a new migrated, empty database on the session's backend."""
    from storage.db import open_database

    schemas: list[_PostgresSchema] = []
    opened: list[Database] = []

    def make() -> Database:
        if backend == "sqlite":
            url = f"sqlite:///{tmp_path_factory.mktemp('sqlite') / 'gearwatch.db'}"
        else:
            schema = _PostgresSchema()
            schemas.append(schema)
            url = schema.url()  # skips (fails under CI) when the server is unreachable
        engine, factory = open_database(url)
        database = Database(backend, url, engine, factory)
        opened.append(database)
        return database

    yield make
    for database in opened:
        database.engine.dispose()
    for schema in schemas:
        schema.drop()
