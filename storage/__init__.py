"""What gearwatch keeps: raw record files, per-tooth results, alarms, API keys, the audit log.

* :mod:`storage.models` — SQLAlchemy 2 models (schema owned by ``alembic/versions``);
* :mod:`storage.db` — engine and session factory for a URL (SQLite: WAL + foreign keys),
  ``migrate`` (= ``alembic upgrade head``), ``session_scope`` (the caller commits);
* :mod:`storage.repositories` — every query: ``RigRepository``, ``CampaignRepository``,
  ``RecordRepository``, ``TrendRepository``, ``AlarmRuleRepository``, ``AlarmRepository``,
  ``ApiKeyRepository``, ``AuditRepository`` (they flush, never commit);
* :mod:`storage.evaluation` — runs the alarm rules (:mod:`detection.alarms`) on a record;
* :mod:`storage.raw_store` — the content-addressed raw file store.

The per-record job that ties them to the pipeline is :mod:`gearwatch.jobs`.
"""
