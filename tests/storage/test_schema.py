"""The alembic head and the models agree; the engine sets SQLite up properly; types round-trip."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest
import sqlalchemy as sa
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory

from storage.db import alembic_config, create_db_engine, current_revision, migrate
from storage.models import TREND_INDEX_NAME, Base, Rig, float32_array, float32_bytes


def test_alembic_head_matches_the_models(db_engine: sa.Engine) -> None:
    with db_engine.connect() as connection:
        context = MigrationContext.configure(connection, opts={"compare_type": True})
        diff = compare_metadata(context, Base.metadata)
    assert diff == []


def test_database_is_at_the_single_head(db_engine: sa.Engine) -> None:
    heads = ScriptDirectory.from_config(alembic_config(db_engine)).get_heads()
    assert len(heads) == 1
    assert current_revision(db_engine) == heads[0]


def test_every_table_and_the_trend_index_exist(db_engine: sa.Engine) -> None:
    inspector = sa.inspect(db_engine)
    assert set(Base.metadata.tables) <= set(inspector.get_table_names())
    indexes = {ix["name"]: ix["column_names"] for ix in inspector.get_indexes("tooth_indicators")}
    assert indexes[TREND_INDEX_NAME] == ["rig_id", "indicator", "tooth", "taken_at"]


def test_downgrade_to_base_and_up_again(tmp_path) -> None:
    engine = create_db_engine(f"sqlite:///{tmp_path / 'down.db'}")
    migrate(engine)
    from alembic import command

    command.downgrade(alembic_config(engine), "base")
    assert "records" not in sa.inspect(engine).get_table_names()
    migrate(engine)
    assert "records" in sa.inspect(engine).get_table_names()
    engine.dispose()


def test_sqlite_connections_use_wal_and_foreign_keys(tmp_path) -> None:
    engine = create_db_engine(f"sqlite:///{tmp_path / 'sub' / 'x.db'}")
    with engine.connect() as connection:
        assert connection.exec_driver_sql("PRAGMA journal_mode").scalar() == "wal"
        assert connection.exec_driver_sql("PRAGMA foreign_keys").scalar() == 1
    engine.dispose()


def test_foreign_keys_are_enforced(db_engine: sa.Engine) -> None:
    from storage.models import Campaign

    with pytest.raises(sa.exc.IntegrityError), db_engine.begin() as connection:
        connection.execute(sa.insert(Campaign.__table__).values(
            rig_id=999_999, name="orphan", description="", manifest={},
            created_at=dt.datetime.now(dt.UTC)))


def test_timestamps_come_back_aware_utc(db_session) -> None:
    local = dt.datetime(2024, 5, 1, 12, 0, tzinfo=dt.timezone(dt.timedelta(hours=2)))
    db_session.add(Rig(name="tz", created_at=local))
    db_session.commit()
    db_session.expunge_all()
    rig = db_session.scalar(sa.select(Rig).where(Rig.name == "tz"))
    assert rig.created_at.tzinfo is not None and rig.created_at.utcoffset() == dt.timedelta(0)
    assert rig.created_at == local
    assert rig.created_at.hour == 10


def test_naive_timestamps_are_refused(db_session) -> None:
    db_session.add(Rig(name="naive", created_at=dt.datetime(2024, 1, 1)))
    with pytest.raises(sa.exc.StatementError, match="naive datetime"):
        db_session.flush()


def test_float32_bytes_round_trip() -> None:
    values = np.array([0.0, -1.5, 3.25, np.float32(1e-7)], dtype=np.float64)
    data = float32_bytes(values)
    assert len(data) == 16
    back = float32_array(data)
    assert back.dtype == np.float32
    np.testing.assert_array_equal(back, values.astype(np.float32))
    back[0] = 5.0  # a fresh writable array
