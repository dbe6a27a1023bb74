"""The per-record job on SQLite and PostgreSQL: keep raw → read → analyse → store → alarms."""

from __future__ import annotations

import datetime as dt
import hashlib

import pytest
import sqlalchemy as sa
from sqlalchemy.orm import Session

from gearwatch.floor.results import TOOTH_INDICATORS, AnalysisParameters
from gearwatch.usecases.ingest_file import (
    parse_taken_at,
    process_file,
    record_suffix,
    reprocess_record,
)
from storage.models import Base
from storage.raw_store import RawStore
from storage.repositories import (
    AlarmRepository,
    AlarmRuleRepository,
    RecordRepository,
    TrendRepository,
)
from tests.gearwatch.jobfixtures import FakeAnalyzer, make_campaign, write_record
from tests.storage import dbfixtures
from tests.storage.factories import T0

# The database fixtures (SQLite and PostgreSQL), shared with tests/storage.
_postgres_schema = dbfixtures._postgres_schema
db_url = dbfixtures.db_url
db_engine_migrated = dbfixtures.db_engine_migrated
db_engine = dbfixtures.db_engine
db_session = dbfixtures.db_session


def row_counts(session: Session) -> dict[str, int]:
    return {
        table.name: int(session.execute(sa.select(sa.func.count()).select_from(table)).scalar())
        for table in Base.metadata.sorted_tables
    }


@pytest.fixture
def store(tmp_path) -> RawStore:
    return RawStore(tmp_path / "raw-store")


def test_accepted_record_keeps_raw_file_and_stores_results(db_session, store, tmp_path) -> None:
    campaign = make_campaign(tmp_path / "camp", [1.0])
    path = campaign.record_path(campaign.records[0])
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    analyzer = FakeAnalyzer()
    result = process_file(db_session, path, campaign, raw_store=store, analyzer=analyzer)
    db_session.commit()
    assert (result.outcome, result.status, result.sha256) == ("accepted", "accepted", digest)
    kept = store.root / digest[:2] / f"{digest}.wav"
    assert kept.read_bytes() == path.read_bytes()
    # The chain read the kept copy, not the original.
    assert analyzer.calls[0]["source"] == str(kept) and analyzer.calls[0]["sha256"] == digest
    record = RecordRepository(db_session).get(result.record_id)
    assert record.raw_location == str(kept) and record.file_name == "day00.wav"
    assert record.taken_at == T0 and record.label == "day 0" and record.size_bytes > 0
    assert record.revolutions == 40 and record.quality["speed_min_rpm"] == 1490.0
    trend = TrendRepository(db_session).trend(record.rig_id, "mci_depth", tooth=1)
    assert [p.value for p in trend] == [pytest.approx(1.0, abs=1e-3)]
    # A new rig gets the default alarm rules.
    assert {r.indicator for r in AlarmRuleRepository(db_session).list(record.rig_id)} == {
        "mci_depth", "score", "change", "nonsync_z", "fm4", "na4", "residual_kurtosis", "kurtosis",
        "raw_kurtosis"}


def test_ingesting_the_same_file_again_changes_nothing(db_session, store, tmp_path) -> None:
    campaign = make_campaign(tmp_path / "camp", [1.0, 1.0], flat=(1,))
    analyzer = FakeAnalyzer()
    for entry in campaign.records:
        process_file(db_session, campaign.record_path(entry), campaign, raw_store=store,
                     analyzer=analyzer)
    db_session.commit()
    before = row_counts(db_session)
    calls = len(analyzer.calls)
    again = [
        process_file(db_session, campaign.record_path(e), campaign, raw_store=store,
                     analyzer=analyzer)
        for e in campaign.records
    ]
    db_session.commit()
    assert [r.outcome for r in again] == ["unchanged", "unchanged"]
    assert [r.status for r in again] == ["accepted", "rejected"]
    assert row_counts(db_session) == before
    assert len(analyzer.calls) == calls  # not even analysed again


def test_the_same_file_stored_by_another_session_during_analysis_is_found_on_retry(
    db_session, db_engine, store, tmp_path
) -> None:
    """The race behind 409s to concurrent identical uploads: while this ingestion analyses,
    another one stores and commits the same content. The insert must raise ``DuplicateRecord``
    (not a bare ``Conflict``) so the caller's retry finds the stored record, ``unchanged``."""
    from gearwatch.floor.errors import DuplicateRecord
    from storage.db import session_factory
    from storage.repositories import CampaignRepository

    campaign = make_campaign(tmp_path / "camp", [1.0])
    path = campaign.record_path(campaign.records[0])
    # The campaign exists already (as for an upload): this session holds no write lock while
    # it analyses, which SQLite needs for the rival's commit to go through.
    CampaignRepository(db_session).ensure(campaign)
    db_session.commit()

    class _RivalCommitsFirst(FakeAnalyzer):
        def __call__(self, *args, **kwargs):  # type: ignore[no-untyped-def]
            with session_factory(db_engine)() as rival:
                process_file(rival, path, campaign, raw_store=store, analyzer=FakeAnalyzer())
                rival.commit()
            return super().__call__(*args, **kwargs)

    with pytest.raises(DuplicateRecord):
        process_file(db_session, path, campaign, raw_store=store, analyzer=_RivalCommitsFirst())
    db_session.rollback()
    retried = process_file(db_session, path, campaign, raw_store=store, analyzer=FakeAnalyzer())
    assert (retried.outcome, retried.status) == ("unchanged", "accepted")
    assert RecordRepository(db_session).count() == 1


def test_new_parameters_add_a_result_version_and_keep_the_old(db_session, store,
                                                               tmp_path) -> None:
    campaign = make_campaign(tmp_path / "camp", [1.0])
    path = campaign.record_path(campaign.records[0])
    first = process_file(db_session, path, campaign, raw_store=store, analyzer=FakeAnalyzer())
    literal = AnalysisParameters(mci_form="literal")
    second = process_file(db_session, path, campaign, raw_store=store, params=literal,
                          analyzer=FakeAnalyzer())
    third = process_file(db_session, path, campaign, raw_store=store, params=literal,
                         analyzer=FakeAnalyzer())
    db_session.commit()
    assert (second.outcome, third.outcome) == ("reprocessed", "unchanged")
    versions = RecordRepository(db_session).results(first.record_id)
    assert [v.parameters["mci_form"] for v in versions] == ["robust", "literal"]
    assert [v.is_current for v in versions] == [False, True]
    assert second.result_id == versions[1].id and second.alarm_changes == ()


def test_bad_input_is_stored_rejected_and_the_job_goes_on(db_session, store, tmp_path) -> None:
    campaign = make_campaign(tmp_path / "camp", [1.0, 1.0, 1.0], flat=(1,), truncated=(0,))
    results = [
        process_file(db_session, campaign.record_path(e), campaign, raw_store=store,
                     analyzer=FakeAnalyzer())
        for e in campaign.records
    ]
    db_session.commit()
    assert [r.status for r in results] == ["rejected", "rejected", "accepted"]
    assert "truncated" in results[0].reason
    assert results[1].reason == "tachometer: no pulses found"
    records = RecordRepository(db_session)
    bad = records.get(results[0].record_id)
    assert bad.status == "rejected" and bad.quality["error"] == "RecordFormatError"
    assert records.results(bad.id) == []
    assert store.contains(bad.sha256, ".wav")  # kept even though unreadable


def test_internal_errors_are_retried_on_the_next_ingestion(db_session, store, tmp_path) -> None:
    campaign = make_campaign(tmp_path / "camp", [1.0])
    path = write_record(campaign.record_path(campaign.records[0]), 1.0, first_sample=123.0)
    failed = process_file(db_session, path, campaign, raw_store=store, analyzer=FakeAnalyzer())
    assert failed.status == "rejected" and failed.reason.startswith("internal error: ZeroDivision")

    def healthy(*args):  # type: ignore[no-untyped-def]
        record = args[0]
        record.channels["acc"] = record.channels["acc"].copy()
        record.channels["acc"][0] = 0.0
        return FakeAnalyzer()(*args)

    retried = process_file(db_session, path, campaign, raw_store=store, analyzer=healthy)
    assert (retried.record_id, retried.status) == (failed.record_id, "accepted")


def test_rejected_record_is_retried_only_with_other_parameters(db_session, store,
                                                               tmp_path) -> None:
    campaign = make_campaign(tmp_path / "camp", [1.0], flat=(0,))
    path = campaign.record_path(campaign.records[0])
    analyzer = FakeAnalyzer()
    process_file(db_session, path, campaign, raw_store=store, analyzer=analyzer)
    process_file(db_session, path, campaign, raw_store=store, analyzer=analyzer)
    assert len(analyzer.calls) == 1
    process_file(db_session, path, campaign, raw_store=store, analyzer=analyzer,
                 params=AnalysisParameters(min_revolutions=5))
    assert len(analyzer.calls) == 2


def test_running_baselines_come_from_earlier_accepted_records(db_session, store,
                                                              tmp_path) -> None:
    campaign = make_campaign(tmp_path / "camp", [1.0, 3.0, 2.0])
    analyzer = FakeAnalyzer()
    for entry in campaign.records:
        process_file(db_session, campaign.record_path(entry), campaign, raw_store=store,
                     analyzer=analyzer)
    seen = [call["baselines"]["acc"].get("residual_variance") for call in analyzer.calls]
    assert seen == [None, pytest.approx(1.0, abs=1e-3), pytest.approx(2.0, abs=1e-3)]


def test_alarm_raised_by_the_record_that_completes_persistence(db_session, store,
                                                               tmp_path) -> None:
    amplitudes = [1.0] * 8 + [2.0, 2.0, 2.0, 2.0]
    campaign = make_campaign(tmp_path / "camp", amplitudes, flat=(9,))
    outcomes = [
        process_file(db_session, campaign.record_path(e), campaign, raw_store=store,
                     analyzer=FakeAnalyzer())
        for e in campaign.records
    ]
    db_session.commit()
    # Defaults: 8 baseline records, persistence 2; day 9 is rejected and does not count.
    raised = [i for i, o in enumerate(outcomes) if o.alarm_changes]
    assert raised == [10]
    assert {(c.indicator, c.state, c.opened) for c in outcomes[10].alarm_changes} == {
        ("mci_depth", "alarm", True)}
    assert len(outcomes[10].alarm_changes) == 20  # every tooth (the stand-in is uniform)
    alarm = AlarmRepository(db_session).list(limit=1)[0]
    assert alarm.raised_at == T0 + dt.timedelta(days=10)


def test_rejected_records_never_raise_alarms(db_session, store, tmp_path) -> None:
    campaign = make_campaign(tmp_path / "camp", [1.0] * 8 + [50.0] * 4, flat=(8, 9, 10, 11))
    for entry in campaign.records:
        process_file(db_session, campaign.record_path(entry), campaign, raw_store=store,
                     analyzer=FakeAnalyzer())
    db_session.commit()
    assert AlarmRepository(db_session).count() == 0


def test_reprocess_from_the_raw_store_after_the_original_is_gone(db_session, store,
                                                                 tmp_path) -> None:
    campaign = make_campaign(tmp_path / "camp", [1.0])
    path = campaign.record_path(campaign.records[0])
    first = process_file(db_session, path, campaign, raw_store=store, analyzer=FakeAnalyzer())
    db_session.commit()
    path.unlink()
    again = reprocess_record(db_session, first.record_id, AnalysisParameters(samples_per_mesh=32),
                             analyzer=FakeAnalyzer())
    same = reprocess_record(db_session, first.record_id, AnalysisParameters(samples_per_mesh=32),
                            analyzer=FakeAnalyzer())
    assert (again.outcome, same.outcome) == ("reprocessed", "unchanged")
    assert len(RecordRepository(db_session).results(first.record_id)) == 2


class _RejectsLiteral(FakeAnalyzer):
    def __call__(self, record, campaign, params, input_sha256, baselines):  # type: ignore[no-untyped-def]
        if params.mci_form == "literal":
            from gearwatch.floor.errors import RecordRejected

            raise RecordRejected("literal MCI refused for this record")
        return super().__call__(record, campaign, params, input_sha256, baselines)


def test_failed_reprocess_keeps_the_accepted_record_and_its_current_result(db_session, store,
                                                                           tmp_path) -> None:
    campaign = make_campaign(tmp_path / "camp", [1.0])
    path = campaign.record_path(campaign.records[0])
    first = process_file(db_session, path, campaign, raw_store=store, analyzer=_RejectsLiteral())
    db_session.commit()
    failed = reprocess_record(db_session, first.record_id, AnalysisParameters(mci_form="literal"),
                              analyzer=_RejectsLiteral())
    db_session.commit()
    assert (failed.outcome, failed.status, failed.result_id) == ("rejected", "accepted", first.result_id)
    assert "literal MCI refused" in failed.reason and "current result is kept" in failed.reason
    records = RecordRepository(db_session)
    record = records.get(first.record_id)
    assert (record.status, record.reason) == ("accepted", "")
    assert records.current_result(record.id).id == first.result_id  # type: ignore[union-attr]
    assert len(records.results(record.id)) == 1
    # The same through ingestion with the refused parameters (replay with other options).
    again = process_file(db_session, path, campaign, raw_store=store,
                         params=AnalysisParameters(mci_form="literal"), analyzer=_RejectsLiteral())
    assert (again.outcome, again.status) == ("rejected", "accepted")


def test_file_outside_the_manifest_takes_its_modification_time(db_session, store,
                                                               tmp_path) -> None:
    campaign = make_campaign(tmp_path / "camp", [1.0])
    dropped = write_record(tmp_path / "camp" / "dropped.wav", 1.5)
    import os

    stamp = (T0 + dt.timedelta(days=30)).timestamp()
    os.utime(dropped, (stamp, stamp))
    result = process_file(db_session, dropped, campaign, raw_store=store, analyzer=FakeAnalyzer())
    record = RecordRepository(db_session).get(result.record_id)
    assert record.taken_at == T0 + dt.timedelta(days=30) and record.label == ""


def test_helpers() -> None:
    assert record_suffix("a/B.WAV") == ".wav"
    assert parse_taken_at("2024-03-01T10:00:00+02:00") == dt.datetime(2024, 3, 1, 8, tzinfo=dt.UTC)
    assert parse_taken_at("2024-03-01T08:00:00Z") == T0
    from gearwatch.floor.errors import InputError

    with pytest.raises(InputError):
        parse_taken_at("2024-03-01T08:00:00")
    with pytest.raises(InputError):
        parse_taken_at("yesterday")


# -- Dramatiq workers over RabbitMQ --------------------------------------------------------------
def broker_url() -> str:
    import os

    return os.environ.get("GEARWATCH_TEST_BROKER_URL", "amqp://guest:guest@127.0.0.1:5672/")


def _require_broker() -> None:
    import pika

    try:
        connection = pika.BlockingConnection(pika.URLParameters(broker_url()))
        connection.close()
    except Exception as error:  # any failure to connect means "not reachable"
        from tests.conftest import service_unavailable

        service_unavailable("RabbitMQ", f"{broker_url()}: {type(error).__name__}: {error}")


def _start_worker(env: dict[str, str], log_path):  # type: ignore[no-untyped-def]
    import subprocess
    import sys
    from pathlib import Path

    repo = Path(__file__).resolve().parents[2]
    with open(log_path, "wb") as log:
        return subprocess.Popen(
            [sys.executable, "-m", "dramatiq", "gearwatch.worker", "--processes", "1",
             "--threads", "1", "--path", str(repo)],
            cwd=repo, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
        )


def _stop(process, sig) -> None:  # type: ignore[no-untyped-def]
    import os

    try:
        os.killpg(process.pid, sig)
    except ProcessLookupError:
        return
    try:
        process.wait(timeout=120)  # a graceful stop finishes (and acks) the current job
    except Exception:
        import signal

        os.killpg(process.pid, signal.SIGKILL)
        process.wait(timeout=30)


@pytest.mark.broker
@pytest.mark.slow
@pytest.mark.parametrize("db_url", ["postgresql"], indirect=True)
def test_two_workers_one_killed_mid_job_every_record_exactly_once(
    db_url: str, db_engine: sa.Engine, tmp_path
) -> None:
    """50 records, 2 Dramatiq worker processes, one SIGKILLed inside a job: every record is
    processed exactly once (one record row, one result version) and nothing is left queued.

    PostgreSQL only: workers are the production set-up (the job itself runs on SQLite in every
    other test here), and pg_stat_activity shows when worker 0 is inside its job transaction.
    """
    import os
    import secrets
    import signal
    import time

    import dramatiq
    import pika
    from dramatiq.brokers.rabbitmq import RabbitmqBroker

    from storage.db import session_factory, session_scope
    from storage.models import Record, ResultVersion, ToothIndicator
    from storage.repositories import CampaignRepository

    _require_broker()
    n_records = 50
    # 60 s at 2 kHz per record: each job takes a good fraction of a second, so a worker spends
    # most of its time inside a job and the kill lands in one.
    campaign = make_campaign(tmp_path / "camp", [1.0 + 0.01 * i for i in range(n_records)],
                             n_samples=120_000)
    factory = session_factory(db_engine)
    with session_scope(factory) as session:
        CampaignRepository(session).ensure(campaign)

    queue = f"gw_test_{secrets.token_hex(6)}"
    env = {
        **os.environ,
        "GEARWATCH_QUEUE": queue,
        "GEARWATCH_BROKER_URL": broker_url(),
        "GEARWATCH_DATABASE_URL": db_url,
        "GEARWATCH_RAW_STORE": str(tmp_path / "raw-store"),
        "dramatiq_restart_delay": "0",
    }
    broker = RabbitmqBroker(url=broker_url())
    broker.declare_queue(queue)
    for entry in campaign.records:
        broker.enqueue(dramatiq.Message(
            queue_name=queue, actor_name="process_record",
            args=(campaign.id, str(campaign.record_path(entry))),
            kwargs={"taken_at": entry.taken_at, "label": entry.label}, options={},
        ))
    workers = []
    for index in range(2):
        # Name each worker's connections, to see when worker 0 is inside a job.
        url = sa.engine.make_url(db_url).update_query_dict(
            {"application_name": f"{queue}_w{index}"}).render_as_string(hide_password=False)
        workers.append(_start_worker({**env, "GEARWATCH_DATABASE_URL": url},
                                     tmp_path / f"worker{index}.log"))

    def worker0_inside_a_job() -> bool:
        """Worker 0 holds an open transaction: the job's (it spans the whole job)."""
        with db_engine.connect() as connection:
            return bool(connection.execute(
                sa.text("SELECT count(*) FROM pg_stat_activity WHERE application_name = :name "
                        "AND xact_start IS NOT NULL"), {"name": f"{queue}_w0"}).scalar())

    def count(model) -> int:  # type: ignore[no-untyped-def]
        with session_scope(factory) as session:
            return int(session.scalar(sa.select(sa.func.count()).select_from(model)) or 0)

    try:
        deadline = time.monotonic() + 900  # a bound on a hang on a loaded box, not a speed limit
        while count(Record) < 5 or not worker0_inside_a_job():
            assert time.monotonic() < deadline, (tmp_path / "worker0.log").read_text()[-3000:]
            assert all(w.poll() is None for w in workers), "a worker exited on its own"
            time.sleep(0.05)
        killed_at = count(Record)
        _stop(workers[0], signal.SIGKILL)
        while count(ResultVersion) < n_records:
            assert time.monotonic() < deadline, (tmp_path / "worker1.log").read_text()[-3000:]
            assert workers[1].poll() is None, (tmp_path / "worker1.log").read_text()[-3000:]
            time.sleep(0.1)
        time.sleep(1.0)  # a duplicate delivery, if any, would show up now
    finally:
        for worker in workers:
            _stop(worker, signal.SIGTERM)
        connection = pika.BlockingConnection(pika.URLParameters(broker_url()))
        channel = connection.channel()
        left = channel.queue_declare(queue, passive=True).method.message_count
        for name in (queue, f"{queue}.DQ", f"{queue}.XQ"):
            channel.queue_delete(name)
        connection.close()
        broker.close()

    assert killed_at < n_records and left == 0
    with session_scope(factory) as session:
        per_record = session.execute(
            sa.select(Record.file_name, Record.status, sa.func.count(ResultVersion.id))
            .join(ResultVersion, ResultVersion.record_id == Record.id, isouter=True)
            .group_by(Record.id, Record.file_name, Record.status)
        ).all()
        assert len(per_record) == n_records
        assert sorted(name for name, _, _ in per_record) == [
            f"day{d:02d}.wav" for d in range(n_records)]
        assert {(status, versions) for _, status, versions in per_record} == {("accepted", 1)}
        indicators = session.scalar(  # the per-record ones (history indicators follow order)
            sa.select(sa.func.count()).select_from(ToothIndicator)
            .where(ToothIndicator.indicator.in_(TOOTH_INDICATORS)))
        assert indicators == n_records * 20 * len(TOOTH_INDICATORS)
