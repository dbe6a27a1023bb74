from tests.storage.dbfixtures import (  # noqa: F401
    _postgres_schema,
    db_engine,
    db_engine_migrated,
    db_session,
    db_url,
)
