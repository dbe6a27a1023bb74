"""Database fixtures: every storage test runs on SQLite (a temp file) AND PostgreSQL.

PostgreSQL comes from ``GEARWATCH_TEST_POSTGRES_URL`` (default
``postgresql+psycopg://postgres@127.0.0.1:5432/test``). Each test session gets its own schema
(``gw_test_<random>``, selected through ``search_path`` and dropped at the end) so parallel runs
never collide. The schema is built by ``alembic upgrade head`` (:func:`storage.db.migrate`),
once per backend and session; after every test all rows are deleted.

Import the fixtures into a test module with
``from tests.storage.dbfixtures import db_engine, db_session, db_url  # noqa: F401``.
"""

from __future__ import annotations

import os
import secrets
from collections.abc import Iterator
from pathlib import Path

import pytest
import sqlalchemy as sa
from sqlalchemy.orm import Session

from tests.conftest import service_unavailable

DEFAULT_POSTGRES_URL = "postgresql+psycopg://postgres@127.0.0.1:5432/test"
BACKENDS = ("sqlite", "postgresql")


def postgres_url() -> str:
    return os.environ.get("GEARWATCH_TEST_POSTGRES_URL", DEFAULT_POSTGRES_URL)


def with_search_path(url: str, schema: str) -> str:
    """``url`` with its connections' ``search_path`` set to ``schema``."""
    parsed = sa.engine.make_url(url)
    return parsed.update_query_dict({"options": f"-csearch_path={schema}"}).render_as_string(
        hide_password=False
    )


class _PostgresSchema:
    """A throw-away schema on the test server, created on first use."""

    def __init__(self) -> None:
        self.schema = f"gw_test_{secrets.token_hex(6)}"
        self.admin: sa.Engine | None = None
        self.error: str | None = None

    def url(self) -> str:
        if self.error is not None:
            service_unavailable("PostgreSQL", self.error)
        if self.admin is None:
            try:
                self.admin = sa.create_engine(postgres_url(), isolation_level="AUTOCOMMIT")
                with self.admin.connect() as connection:
                    connection.execute(sa.text(f'CREATE SCHEMA "{self.schema}"'))
            except Exception as error:  # any connection failure means "not reachable"
                self.admin = None
                self.error = f"{postgres_url()}: {type(error).__name__}: {error}"
                service_unavailable("PostgreSQL", self.error)
        return with_search_path(postgres_url(), self.schema)

    def drop(self) -> None:
        if self.admin is not None:
            with self.admin.connect() as connection:
                connection.execute(sa.text(f'DROP SCHEMA IF EXISTS "{self.schema}" CASCADE'))
            self.admin.dispose()


@pytest.fixture(scope="session")
def _postgres_schema() -> Iterator[_PostgresSchema]:
    schema = _PostgresSchema()
    yield schema
    schema.drop()


@pytest.fixture(scope="session", params=BACKENDS)
def db_url(
    request: pytest.FixtureRequest,
    tmp_path_factory: pytest.TempPathFactory,
    _postgres_schema: _PostgresSchema,
) -> str:
    """A migrated database URL, once per backend and test session."""
    if request.param == "sqlite":
        path: Path = tmp_path_factory.mktemp("sqlite") / "gearwatch.db"
        return f"sqlite:///{path}"
    return _postgres_schema.url()


@pytest.fixture(scope="session")
def db_engine_migrated(db_url: str) -> Iterator[sa.Engine]:
    from storage.db import create_db_engine, migrate

    engine = create_db_engine(db_url)
    migrate(engine)
    yield engine
    engine.dispose()


def delete_all_rows(engine: sa.Engine) -> None:
    from storage.models import Base

    with engine.begin() as connection:
        for table in reversed(Base.metadata.sorted_tables):
            connection.execute(table.delete())


@pytest.fixture
def db_engine(db_engine_migrated: sa.Engine) -> Iterator[sa.Engine]:
    """The backend's migrated engine; emptied after the test."""
    yield db_engine_migrated
    delete_all_rows(db_engine_migrated)


@pytest.fixture
def db_session(db_engine: sa.Engine) -> Iterator[Session]:
    """A session on the test database (the test commits or not; rows are deleted after)."""
    from storage.db import session_factory

    session = session_factory(db_engine)()
    try:
        yield session
    finally:
        session.rollback()
        session.close()
