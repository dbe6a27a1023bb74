"""What gearwatch keeps: raw record files, per-tooth results, alarms, API keys, the audit log.

* :mod:`storage.models` — SQLAlchemy 2 models (schema owned by ``alembic/versions``);
* :mod:`storage.db` — engine and session factory for a URL (SQLite: WAL + foreign keys),
  ``migrate`` (= ``alembic upgrade head``), ``session_scope`` (the caller commits);
* :mod:`storage.repositories` — every query, one module per aggregate over a generic
  ``Repository`` base: ``RigRepository``, ``CampaignRepository`` (rigs), ``RecordRepository``
  (records), ``TrendRepository`` (trends), ``ReconciliationRepository``,
  ``AlarmRuleRepository``, ``AlarmRepository`` (alarms), ``ApiKeyRepository`` (keys),
  ``AuditRepository`` (audit) — they flush, never commit;
* :mod:`storage.raw_store` — the content-addressed raw file store.

Storage imports only the floor (:mod:`gearwatch.floor`) and :mod:`detection`; the use-cases that
tie it to the pipeline and the alarm rules are in :mod:`gearwatch.usecases` (``ingest_file``,
``alarms``).
"""
