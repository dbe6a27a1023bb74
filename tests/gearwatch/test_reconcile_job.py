"""The reconciliation job on SQLite and PostgreSQL: a stored record's kept raw file and its
campaign → :func:`physics.reconcile.reconcile` → JSON, HTML report and updated model stored."""

from __future__ import annotations

from pathlib import Path

import pytest
import sqlalchemy as sa

from gearwatch.floor.errors import InputError, NotFound
from gearwatch.usecases.reconcile import ReconcileRequest, create_reconciliation, run_reconciliation
from storage.db import session_factory
from storage.raw_store import RawStore
from storage.repositories import ReconciliationRepository
from tests.gearwatch import reconcilefixtures as fx
from tests.storage import dbfixtures

_postgres_schema = dbfixtures._postgres_schema
db_url = dbfixtures.db_url
db_engine_migrated = dbfixtures.db_engine_migrated
db_engine = dbfixtures.db_engine

FAST = ReconcileRequest(
    samples_per_mesh=fx.FAST_OPTIONS["samples_per_mesh"],
    max_frequency_hz=fx.FAST_OPTIONS["max_frequency_hz"],
    mechanisms=tuple(fx.FAST_OPTIONS["mechanisms"]),
    max_findings=fx.FAST_OPTIONS["max_findings"],
    forward_oversampling=fx.FAST_OPTIONS["forward_oversampling"],
)


@pytest.fixture(scope="module")
def manifest(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return fx.write_campaign(tmp_path_factory.mktemp("reconcile-job"))


@pytest.fixture
def stored(db_engine: sa.Engine, manifest: Path, tmp_path: Path) -> tuple[dict[str, int], RawStore]:
    store = RawStore(tmp_path / "raw-store")
    with session_factory(db_engine)() as session:
        return fx.ingest(session, manifest, store), store


# One real reconciliation per backend in the suite: here on SQLite; on PostgreSQL through the
# REST tests (tests/service/test_reconciliations.py: the service's runner and a Dramatiq worker).
@pytest.mark.parametrize("db_url", ["sqlite"], indirect=True)
def test_reconciliation_names_the_eccentricity_and_stores_json_report_and_model(
    db_engine: sa.Engine, stored: tuple[dict[str, int], RawStore]
) -> None:
    from physics.config import model_from_toml

    ids, store = stored
    factory = session_factory(db_engine)
    with factory() as session:
        row = create_reconciliation(session, ids[fx.RECORD], FAST, raw_store=store)
        session.commit()
        assert (row.status, row.model_toml, row.result) == ("queued", None, None)
    assert run_reconciliation(factory, store, row.id) == "done"

    with factory() as session:
        done = ReconciliationRepository(session).get(row.id)
        assert done.status == "done" and done.error == ""
        assert done.started_at is not None and done.finished_at is not None
        assert done.started_at <= done.finished_at
        assert done.code_version and done.record.sha256 == session.get(
            type(done.record), ids[fx.RECORD]).sha256
        result = done.result
        assert result is not None
        [finding] = result["findings"]
        assert finding["mechanism"] == "pinion_eccentricity" and finding["wheel"] == "pinion"
        assert finding["parameters"]["amplitude_um"] == pytest.approx(fx.ECCENTRICITY_UM, rel=0.2)
        assert result["status"] in ("explained", "partly_explained")
        assert result["final"]["chi2_dof"] < result["baseline"]["chi2_dof"]
        assert done.report_html is not None and done.report_html.startswith("<!doctype html>")
        # The base actually used: the rig's default model at the record's sample rate.
        used = model_from_toml(done.model_toml or "")
        assert used.acquisition.sample_rate_hz == fx.SAMPLE_RATE_HZ
        assert used.deviations.pinion_eccentricity_um == 0.0
        updated = model_from_toml(done.updated_model_toml or "")
        assert updated.deviations.pinion_eccentricity_um == pytest.approx(
            fx.ECCENTRICITY_UM, rel=0.2)


def test_unreadable_record_fails_with_its_reason_and_keeps_the_row(
    db_engine: sa.Engine, stored: tuple[dict[str, int], RawStore]
) -> None:
    ids, store = stored
    factory = session_factory(db_engine)
    with factory() as session:
        row = create_reconciliation(session, ids[fx.GARBAGE], FAST, raw_store=store)
        session.commit()
    assert run_reconciliation(factory, store, row.id) == "failed"
    with factory() as session:
        failed = ReconciliationRepository(session).get(row.id)
        assert failed.status == "failed" and failed.finished_at is not None
        # The reason names the operator's file, not its copy in the raw store.
        assert fx.GARBAGE in failed.error and str(store.root) not in failed.error
        assert failed.result is None and failed.report_html is None
        finished_at = failed.finished_at

    # Delivered again: a finished reconciliation is left alone.
    assert run_reconciliation(factory, store, row.id) == "failed"
    with factory() as session:
        again = ReconciliationRepository(session).get(row.id)
        assert again.finished_at == finished_at

        # Left running by a worker that died: run again (and fails again, with its reason).
        again.status = "running"
        session.commit()
    assert run_reconciliation(factory, store, row.id) == "failed"
    with factory() as session:
        rerun = ReconciliationRepository(session).get(row.id)
        assert rerun.status == "failed" and rerun.finished_at is not None
        assert rerun.finished_at > finished_at and fx.GARBAGE in rerun.error


def test_missing_raw_file_is_found_in_the_store_by_content_or_fails(
    db_engine: sa.Engine, stored: tuple[dict[str, int], RawStore], tmp_path: Path
) -> None:
    """A worker may mount the shared store elsewhere: the raw file is found by its sha256."""
    from gearwatch.usecases.reconcile import raw_path
    from storage.repositories import RecordRepository

    ids, store = stored
    factory = session_factory(db_engine)
    with factory() as session:
        record = RecordRepository(session).get(ids[fx.RECORD])
        kept = Path(record.raw_location)
        record.raw_location = str(tmp_path / "elsewhere" / kept.name)
        session.commit()
        assert raw_path(record, store) == kept
        assert raw_path(record, str(store.root)) == kept
        with pytest.raises(NotFound, match="raw file of record"):
            raw_path(record, RawStore(tmp_path / "empty-store"))
        with pytest.raises(NotFound, match="raw file of record"):
            create_reconciliation(session, record.id, FAST, raw_store=tmp_path / "empty-store")


def test_requests_are_checked_before_anything_is_stored(
    db_engine: sa.Engine, stored: tuple[dict[str, int], RawStore]
) -> None:
    from storage.models import Reconciliation

    ids, store = stored
    record = ids[fx.RECORD]
    with session_factory(db_engine)() as session:
        cases = [
            (ReconcileRequest(reference_record_id=record), "another record"),
            (ReconcileRequest(mechanisms=("warp_drive",)), "warp_drive.*pinion_eccentricity"),
            (ReconcileRequest(mechanisms=()), "at least one"),
            (ReconcileRequest(model_toml="[geometry\n"), "model_toml: not valid TOML"),
            (ReconcileRequest(channel="tach"), "not an accelerometer"),
            (ReconcileRequest(samples_per_mesh=4), "samples_per_mesh"),
            (ReconcileRequest(forward_oversampling=0), "forward_oversampling"),
        ]
        for request, message in cases:
            with pytest.raises(InputError, match=message):
                create_reconciliation(session, record, request, raw_store=store)
        with pytest.raises(NotFound, match="record 999999"):
            create_reconciliation(session, 999_999, FAST, raw_store=store)
        with pytest.raises(NotFound, match="reference record 999999"):
            create_reconciliation(
                session, record, ReconcileRequest(reference_record_id=999_999), raw_store=store)
        assert session.scalar(sa.select(sa.func.count()).select_from(Reconciliation)) == 0
