"""The reconciliations table and its repository on SQLite and PostgreSQL."""

from __future__ import annotations

import datetime as dt
import math

import pytest
import sqlalchemy as sa
from sqlalchemy.orm import Session

from gearwatch.floor.errors import NotFound
from storage.models import Reconciliation, Record
from storage.repositories import CampaignRepository, ReconciliationRepository, RecordRepository
from tests.storage.factories import T0, campaign_config


def two_records(session: Session) -> tuple[Record, Record]:
    campaign = CampaignRepository(session).ensure(campaign_config())
    records = RecordRepository(session)
    return tuple(  # type: ignore[return-value]
        records.add(campaign, sha256=c * 64, file_name=f"{c}.wav", raw_location=f"/raw/{c}.wav",
                    taken_at=T0 + dt.timedelta(days=i))
        for i, c in enumerate("ab")
    )


def test_queued_running_done_with_json_result_and_text(db_session: Session) -> None:
    record, reference = two_records(db_session)
    rows = ReconciliationRepository(db_session)
    options = {"samples_per_mesh": 16, "max_frequency_hz": None, "mechanisms": ["tooth_spall"]}
    row = rows.add(record, options=options, code_version="1.0+gabc", reference=reference)
    db_session.commit()
    assert (row.status, row.error, row.model_toml, row.started_at) == ("queued", "", None, None)

    rows.set_progress(row.id, "calibration", 0.5)  # not running yet: nothing stored
    assert row.result is None
    assert rows.start(row, "1.0+gdef") is True
    assert row.status == "running" and row.code_version == "1.0+gdef" and row.started_at
    rows.set_progress(row.id, "reference: selection", 0.123456)
    db_session.commit()
    assert row.result == {"progress": {"stage": "reference: selection", "fraction": 0.1235}}
    result = {"status": "explained", "final": {"chi2_dof": 1.01, "misfit": math.nan},
              "findings": [{"mechanism": "tooth_spall", "tooth": 5}]}
    rows.finish(row, model_toml="[geometry]\n", result=result, report_html="<!doctype html>",
                updated_model_toml="[deviations]\n")
    db_session.commit()
    db_session.expunge_all()

    back = ReconciliationRepository(db_session).get(row.id)
    assert back.status == "done" and back.finished_at is not None
    assert back.started_at is not None and back.started_at <= back.finished_at
    # NaN is not JSON (PostgreSQL refuses it): stored as null.
    assert back.result == {**result, "final": {"chi2_dof": 1.01, "misfit": None}}
    assert back.options == options
    assert (back.model_toml, back.report_html, back.updated_model_toml) == (
        "[geometry]\n", "<!doctype html>", "[deviations]\n")
    assert back.record.sha256 == "a" * 64 and back.reference_record is not None
    assert back.reference_record.sha256 == "b" * 64
    # A finished row is not started again (a message delivered twice).
    assert ReconciliationRepository(db_session).start(back, "2.0") is False
    assert back.status == "done" and back.code_version == "1.0+gdef"


def test_failed_keeps_the_reason_and_a_restart_clears_it(db_session: Session) -> None:
    record, _ = two_records(db_session)
    rows = ReconciliationRepository(db_session)
    row = rows.add(record, options={}, code_version="1")
    rows.start(row, "1")
    rows.fail(row, "rec.wav: no tach pulses", model_toml="[m]\n")
    db_session.commit()
    assert (row.status, row.error, row.model_toml) == ("failed", "rec.wav: no tach pulses", "[m]\n")
    assert row.finished_at is not None and row.result is None
    row.status = "running"  # left so by a worker that died
    assert rows.start(row, "1") is True and row.error == ""


def test_list_is_newest_first_per_record_and_unknown_ids_are_not_found(db_session: Session) -> None:
    record, other = two_records(db_session)
    rows = ReconciliationRepository(db_session)
    first = rows.add(record, options={}, code_version="1")
    rows.add(other, options={}, code_version="1")
    second = rows.add(record, options={}, code_version="1")
    second.created_at = first.created_at + dt.timedelta(seconds=1)
    db_session.commit()
    assert [r.id for r in rows.list_for_record(record.id)] == [second.id, first.id]
    with pytest.raises(NotFound, match="reconciliation 999999 not found"):
        rows.get(999_999)


def test_deleting_records_cascades_and_unsets_the_reference(db_session: Session) -> None:
    record, reference = two_records(db_session)
    rows = ReconciliationRepository(db_session)
    kept = rows.add(reference, options={}, code_version="1")
    referencing = rows.add(record, options={}, code_version="1", reference=reference)
    other_way = rows.add(reference, options={}, code_version="1", reference=record)
    db_session.commit()
    ids = (kept.id, referencing.id, other_way.id)
    db_session.execute(sa.delete(Record).where(Record.id == record.id))
    db_session.commit()
    db_session.expunge_all()
    left = {r.id: r.reference_record_id for r in db_session.scalars(sa.select(Reconciliation))}
    assert left == {ids[0]: None, ids[2]: None}


def test_status_is_checked_by_the_database(db_session: Session) -> None:
    record, _ = two_records(db_session)
    row = ReconciliationRepository(db_session).add(record, options={}, code_version="1")
    db_session.commit()
    row.status = "paused"
    with pytest.raises(sa.exc.IntegrityError):
        db_session.commit()
