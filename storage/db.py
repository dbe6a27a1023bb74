"""Engine and session factory for a database URL, and schema migration to the alembic head.

The URL comes from the caller (the CLI's ``--db`` or the service settings'
``GEARWATCH_DATABASE_URL``); this module reads no settings itself. SQLite connections get
``journal_mode=WAL`` (readers do not block the writer), ``foreign_keys=ON`` and a busy timeout.

Only the caller commits: a request handler or a job opens ``session_scope(factory)`` and the
repositories inside it only flush.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import sqlalchemy as sa
import sqlalchemy.exc as sa_exc
from sqlalchemy.engine import make_url
from sqlalchemy.exc import ArgumentError
from sqlalchemy.orm import Session, sessionmaker

from gearwatch.floor.errors import DatabaseUnavailable, InputError

DEFAULT_DATABASE_URL = "sqlite:///gearwatch.db"
ALEMBIC_DIR = Path(__file__).resolve().parent.parent / "alembic"
"""The migration scripts (top-level ``alembic/`` of the source tree)."""


def _sqlite_on_connect(dbapi_connection: Any, _record: Any) -> None:
    cursor = dbapi_connection.cursor()
    try:
        cursor.execute("PRAGMA journal_mode=WAL")
        cursor.execute("PRAGMA foreign_keys=ON")
        cursor.execute("PRAGMA busy_timeout=30000")
    finally:
        cursor.close()


if TYPE_CHECKING:
    from gearwatch.floor.errors import GearwatchError


def create_db_engine(url: str, *, echo: bool = False, **kwargs: Any) -> sa.Engine:
    """An engine for ``url``; SQLite gets WAL, foreign keys and a busy timeout on every connection.

    A relative SQLite path is relative to the working directory; its folder is created.
    ``search_path`` in the URL query (PostgreSQL) selects a schema:
    ``postgresql+psycopg://u@h/db?options=-csearch_path%3Dmyschema``.
    """
    parsed = database_url(url)
    if parsed.get_backend_name() == "sqlite":
        database = parsed.database
        if database and database != ":memory:" and not database.startswith("file:"):
            Path(database).expanduser().resolve().parent.mkdir(parents=True, exist_ok=True)
        kwargs.setdefault("connect_args", {}).setdefault("timeout", 30)
        engine = sa.create_engine(parsed, echo=echo, **kwargs)
        sa.event.listen(engine, "connect", _sqlite_on_connect)
        return engine
    kwargs.setdefault("pool_pre_ping", True)
    kwargs.setdefault("connect_args", {}).setdefault("connect_timeout", 10)
    return sa.create_engine(parsed, echo=echo, **kwargs)


SUPPORTED_URLS = "sqlite:///path/to/file.db or postgresql://user@host:port/database"


def database_url(url: str) -> sa.URL:
    """``url`` parsed, with PostgreSQL's bare schemes (``postgres://``, ``postgresql://``, as
    Heroku-style and libpq URLs write them) on the installed psycopg 3 driver. Anything else
    gearwatch cannot open is an :class:`InputError` naming the scheme (password hidden)."""
    try:
        parsed = make_url(url)
    except ArgumentError:
        raise InputError(f"not a database URL: {url.split('@')[-1]!r} (use {SUPPORTED_URLS})") from None
    if parsed.drivername in ("postgres", "postgresql"):
        parsed = parsed.set(drivername="postgresql+psycopg")
    if parsed.get_backend_name() not in ("sqlite", "postgresql"):
        raise InputError(
            f"unsupported database {parsed.drivername!r} in "
            f"{parsed.render_as_string(hide_password=True)} (use {SUPPORTED_URLS})"
        )
    return parsed


def database_unavailable(error: Exception) -> GearwatchError | None:
    """A :class:`~gearwatch.floor.errors.DatabaseUnavailable` for an error that says the database
    cannot be reached or went away (else ``None``); its message is one line."""
    if isinstance(error, sa_exc.NoSuchModuleError | sa_exc.ArgumentError):
        return InputError(f"cannot open the database: {error} (use {SUPPORTED_URLS})")
    if not isinstance(error, sa_exc.OperationalError | sa_exc.InterfaceError |
                      sa_exc.TimeoutError):
        return None
    original = getattr(error, "orig", None) or error
    reason = " ".join(str(original).split())[:300]
    return DatabaseUnavailable(
        f"database unavailable ({reason}); nothing was half-written: run the command again "
        "to resume"
    )


def session_factory(engine: sa.Engine) -> sessionmaker[Session]:
    """Sessions that keep loaded objects usable after commit (``expire_on_commit=False``).

    Their alarm state changes queue webhook notifications in the same transaction
    (:mod:`storage.outbox`), delivered after the commit."""
    from storage import outbox  # here: outbox → outbox_delivery → db would be an import cycle

    factory = sessionmaker(bind=engine, expire_on_commit=False)
    outbox.install(factory)
    return factory


@contextlib.contextmanager
def session_scope(factory: sessionmaker[Session]) -> Iterator[Session]:
    """A session that commits when the block ends normally and rolls back on an exception."""
    session = factory()
    try:
        yield session
        session.commit()
    except BaseException:
        session.rollback()
        raise
    finally:
        session.close()


def alembic_config(engine_or_url: sa.Engine | str) -> Any:
    """An alembic ``Config`` for the migration scripts, bound to an engine or URL."""
    from alembic.config import Config  # alembic only where a migration runs

    config = Config()
    config.set_main_option("script_location", str(ALEMBIC_DIR))
    if isinstance(engine_or_url, sa.Engine):
        config.attributes["engine"] = engine_or_url
        config.set_main_option(
            "sqlalchemy.url",
            engine_or_url.url.render_as_string(hide_password=False).replace("%", "%%"),
        )
    else:
        config.set_main_option("sqlalchemy.url", engine_or_url.replace("%", "%%"))
    return config


def migrate(engine: sa.Engine, revision: str = "head") -> None:
    """Run ``alembic upgrade <revision>`` on ``engine`` (creates every table on an empty database)."""
    from alembic import command

    command.upgrade(alembic_config(engine), revision)


def current_revision(engine: sa.Engine) -> str | None:
    """The alembic revision the database is at (``None`` when never migrated)."""
    from alembic.runtime.migration import MigrationContext

    with engine.connect() as connection:
        return MigrationContext.configure(connection).get_current_revision()


def open_database(url: str, *, auto_migrate: bool = True) -> tuple[sa.Engine, sessionmaker[Session]]:
    """Engine and session factory for ``url``, migrated to the alembic head unless told not to."""
    engine = create_db_engine(url)
    if auto_migrate:
        migrate(engine)
    return engine, session_factory(engine)
