"""Service test fixtures: the app on SQLite AND PostgreSQL, API keys of every role, seed data.

The database fixtures (``db_url``: a migrated SQLite temp file and a throw-away PostgreSQL
schema per session) come from :mod:`tests.storage.dbfixtures`; every test that uses ``api``
runs once per backend, on emptied tables.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx
import pytest
import sqlalchemy as sa
from fastapi import FastAPI
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session, sessionmaker

from tests.storage.dbfixtures import (  # noqa: F401
    _postgres_schema,
    db_engine_migrated,
    db_url,
    delete_all_rows,
)

ROLES = ("viewer", "operator", "admin")
SPALL_TOOTH = 16


@dataclass
class Api:
    """A test client with one key per role and a session factory on the same database."""

    app: FastAPI
    client: TestClient
    keys: dict[str, str]
    session_factory: sessionmaker[Session]
    raw_store: Path
    backend: str

    def headers(self, role: str | None) -> dict[str, str]:
        return {} if role is None else {"Authorization": f"Bearer {self.keys[role]}"}

    def get(self, path: str, role: str | None = "viewer", **kwargs: Any) -> httpx.Response:
        return self.client.get(path, headers=self.headers(role), **kwargs)

    def session(self) -> Session:
        return self.session_factory()


@pytest.fixture(scope="session")
def service_app(
    db_url: str,  # noqa: F811
    db_engine_migrated: sa.Engine,  # noqa: F811
    tmp_path_factory: pytest.TempPathFactory,
) -> Iterator[tuple[FastAPI, TestClient, Path]]:
    """One app per backend and session (the schema is already at the alembic head)."""
    from gearwatch.floor.settings import Settings
    from service.app import create_app

    raw_store = tmp_path_factory.mktemp("raw-store")
    settings = Settings(
        database_url=db_url,
        raw_store=raw_store,
        auto_migrate=False,
        trend_cache_seconds=0.0,
        upload_dir=tmp_path_factory.mktemp("uploads"),
    )
    app = create_app(settings)
    with TestClient(app, raise_server_exceptions=False) as client:
        yield app, client, raw_store


@pytest.fixture
def api(
    service_app: tuple[FastAPI, TestClient, Path],
    db_engine_migrated: sa.Engine,  # noqa: F811
) -> Iterator[Api]:
    """Empty tables, a fresh key per role."""
    from gearwatch.usecases.keys import issue_api_key
    from storage.db import session_factory, session_scope

    app, client, raw_store = service_app
    delete_all_rows(db_engine_migrated)
    factory = session_factory(db_engine_migrated)
    keys: dict[str, str] = {}
    with session_scope(factory) as session:
        for role in ROLES:
            keys[role] = issue_api_key(session, name=f"{role} key", role=role)[1]
    yield Api(app, client, keys, factory, raw_store, db_engine_migrated.dialect.name)


@pytest.fixture(scope="session")
def simulated_campaign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 12-day simulated campaign (3 s records), spall on pinion tooth 16 from day 10."""
    from gearwatch.cli.main import main

    out = tmp_path_factory.mktemp("campaign") / "sim"
    args = ["simulate-campaign", str(out), "--days", "12", "--seconds", "3", "--seed", "3"]
    args += ["--spall-tooth", str(SPALL_TOOTH), "--onset-day", "10"]
    assert main(args) == 0
    return out


@dataclass
class Replayed:
    """The simulated campaign replayed by a separate ``gearwatch replay`` process into a SQLite
    database, with GEARWATCH_ALARM_WEBHOOK_URL pointing at a local listener."""

    db_url: str
    raw_store: Path
    received: list[dict[str, Any]]
    replay_stderr: str


@pytest.fixture(scope="session")
def replayed_campaign(
    simulated_campaign: Path, tmp_path_factory: pytest.TempPathFactory
) -> Replayed:
    import os
    import subprocess
    import sys

    from tests.service.webhook_listener import WebhookListener

    folder = tmp_path_factory.mktemp("replayed")
    url = f"sqlite:///{folder / 'gearwatch.db'}"
    raw_store = folder / "raw"
    with WebhookListener() as listener:
        env = {**os.environ, "GEARWATCH_ALARM_WEBHOOK_URL": listener.url,
               "GEARWATCH_DASHBOARD_URL": "http://dashboard.test/"}
        done = subprocess.run(
            [sys.executable, "-m", "gearwatch", "replay", str(simulated_campaign), "--db", url,
             "--raw-store", str(raw_store), "--no-progress"],
            env=env, capture_output=True, text=True, timeout=900, check=False,
        )
        assert done.returncode == 0, done.stderr
        received = list(listener.received)
    return Replayed(url, raw_store, received, done.stderr)
