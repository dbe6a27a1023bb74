"""The ``change`` indicator in the database: stored per tooth once a campaign has its reference
records, a function of the accepted records ordered by ``taken_at`` whatever order they arrive
in (a late record rewrites the values after it), and alarmed on the tooth that changed."""

from __future__ import annotations

import datetime as dt
import random

import numpy as np
import pytest
import sqlalchemy as sa
from sqlalchemy.orm import Session

from detection.default_rules import CHANGE_RULE
from dsp.toothchange import DEFAULT_REFERENCE_RECORDS, campaign_change_state
from gearwatch.usecases.alarms import evaluate_record
from gearwatch.usecases.running_baselines import lock_rig
from gearwatch.usecases.tooth_change import refresh_tooth_change
from storage.models import Campaign, ToothIndicator
from storage.repositories import (
    AlarmRepository,
    AlarmRuleRepository,
    CampaignRepository,
    RecordRepository,
)
from tests.dsp.test_toothchange import campaign as simulated_days
from tests.storage.evaluation_snapshot import evaluation_snapshot
from tests.storage.factories import T0, analysis, campaign_config

TEETH = 20
DAYS = 9
SPALL_TOOTH, ONSET = 7, 6
TOOTH1_DEG = 9.0  # campaign_config's rig


def _ingest(session: Session, tag: str, order: list[int], *, days: int = DAYS,
            onset: int = ONSET, new_rig: bool = True) -> int:
    campaign = CampaignRepository(session).ensure(campaign_config(f"camp-{tag}", f"rig-{tag}"))
    if new_rig:
        AlarmRuleRepository(session).create(campaign.rig_id, "change", **CHANGE_RULE)
    session.commit()
    averages = simulated_days(TEETH, days, noise=0.02, seed=3, spall=(SPALL_TOOTH, onset, 0.12),
                              tooth1_deg=TOOTH1_DEG)
    records = RecordRepository(session)
    for index in order:
        sha256 = f"{index:04x}".ljust(63, "0") + tag
        record = records.add(campaign, sha256=sha256, file_name=f"r{index}.wav",
                             raw_location=f"/raw/{sha256}.wav",
                             taken_at=T0 + dt.timedelta(days=index))
        result_analysis = analysis(sha256=sha256, teeth=TEETH, curve_length=TEETH * 64,
                                   baseline_stats={"tooth1_pitch_angle_deg": TOOTH1_DEG})
        result_analysis.channels[0].curves["pinion_average"] = averages[index].astype(np.float32)
        records.mark_accepted(record, result_analysis)
        result = records.add_result(record, result_analysis)
        lock_rig(session, record.rig_id)
        refresh_tooth_change(session, record.campaign_id, record.id)  # as ingest_file does
        evaluate_record(session, record, result)
        session.commit()
    return campaign.rig_id


def _count_full_recomputes(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Count the campaign-wide recomputations (``_refresh_channel``) from now on, in ``[0]``."""
    from gearwatch.usecases import tooth_change

    counter = [0]
    real = tooth_change._refresh_channel

    def counting(*args, **kwargs):  # type: ignore[no-untyped-def]
        counter[0] += 1
        return real(*args, **kwargs)

    monkeypatch.setattr(tooth_change, "_refresh_channel", counting)
    return counter


def _stored_changes(session: Session, rig_id: int) -> dict[tuple[dt.datetime, int], float]:
    rows = session.execute(
        sa.select(ToothIndicator.taken_at, ToothIndicator.tooth, ToothIndicator.value)
        .where(ToothIndicator.rig_id == rig_id, ToothIndicator.indicator == "change")
    ).all()
    return {(taken_at, tooth): value for taken_at, tooth, value in rows}


@pytest.mark.parametrize("seed", [1, 2])
def test_change_values_and_alarms_do_not_depend_on_arrival_order(
    db_session: Session, seed: int
) -> None:
    sequential = _ingest(db_session, "a", list(range(DAYS)))
    order = list(range(DAYS))
    random.Random(seed).shuffle(order)
    assert order != sorted(order)
    shuffled = _ingest(db_session, "b", order)

    expected = _stored_changes(db_session, sequential)
    # the first two records are the reference: no change values for them
    assert len(expected) == (DAYS - 3) * TEETH  # from the 4th record on
    got = _stored_changes(db_session, shuffled)
    assert got.keys() == expected.keys()
    for key, value in expected.items():
        assert got[key] == pytest.approx(value, rel=1e-9, abs=1e-9), key
    assert evaluation_snapshot(db_session, shuffled) == evaluation_snapshot(db_session, sequential)

    # the spalled tooth, and only it, is alarmed, from the onset record on
    alarms = AlarmRepository(db_session).list(rig_id=sequential)
    assert {a.tooth for a in alarms} == {SPALL_TOOTH}
    first = min(a.raised_at for a in alarms)
    assert first == T0 + dt.timedelta(days=ONSET - 1)


def test_a_record_arriving_last_is_scored_from_the_reference_alone_and_equals_a_full_recompute(
    db_session: Session, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A live rig's records arrive in order: once the campaign's first records hold a complete
    reference (8 admitted), each new one is scored without recomputing the campaign — and the
    stored values are exactly those of a full recomputation, in order and shuffled."""
    days, onset = 20, 16
    full_recomputes = _count_full_recomputes(monkeypatch)
    sequential = _ingest(db_session, "c", list(range(days)), days=days, onset=onset)
    # the records up to the 8th admitted one recompute (no complete reference before them; a
    # healthy record that scores above the admission level is not admitted), the later ones do not
    averages = simulated_days(TEETH, days, noise=0.02, seed=3, spall=(SPALL_TOOTH, onset, 0.12),
                              tooth1_deg=TOOTH1_DEG)
    _, admitted = campaign_change_state([a.astype(np.float32) for a in averages],
                                        [TOOTH1_DEG] * days, TEETH)
    assert len(admitted) == DEFAULT_REFERENCE_RECORDS and admitted[-1] < onset - 1
    assert full_recomputes[0] == admitted[-1] + 1
    campaign_id = db_session.execute(
        sa.select(Campaign.id).where(Campaign.rig_id == sequential)).scalar_one()
    written = refresh_tooth_change(db_session, campaign_id)
    assert full_recomputes[0] == admitted[-1] + 2, "the refresh without a record id recomputes the campaign"
    assert written == 0  # and changes nothing

    order = list(range(days))
    random.Random(5).shuffle(order)
    shuffled = _ingest(db_session, "d", order, days=days, onset=onset)
    expected, got = _stored_changes(db_session, sequential), _stored_changes(db_session, shuffled)
    assert len(expected) == (days - 3) * TEETH and got.keys() == expected.keys()
    for key, value in expected.items():
        assert got[key] == pytest.approx(value, rel=1e-9, abs=1e-9), key
    assert {a.tooth for a in AlarmRepository(db_session).list(rig_id=sequential)} == {SPALL_TOOTH}


def test_values_an_earlier_version_stored_are_recomputed_when_the_next_record_arrives(
    db_session: Session, monkeypatch: pytest.MonkeyPatch
) -> None:
    """After an upgrade that changed the statistic, the campaign's stored values are not left in
    the old scale beside the new record's: the first records, re-scored with the new one, differ
    from what is stored, and the whole campaign is recomputed once."""
    days, onset = 20, 16
    rig_id = _ingest(db_session, "e", list(range(days - 1)), days=days, onset=onset)
    before = _stored_changes(db_session, rig_id)
    old_scale = {key: 0.5 * value for key, value in before.items()}  # another version's values
    db_session.execute(sa.update(ToothIndicator).where(
        ToothIndicator.rig_id == rig_id, ToothIndicator.indicator == "change"
    ).values(value=ToothIndicator.value * 0.5))
    db_session.commit()
    assert _stored_changes(db_session, rig_id) == pytest.approx(old_scale)

    full_recomputes = _count_full_recomputes(monkeypatch)
    _ingest(db_session, "e", [days - 1], days=days, onset=onset, new_rig=False)
    assert full_recomputes[0] == 1
    after = _stored_changes(db_session, rig_id)
    assert len(after) == len(before) + TEETH
    for key, value in before.items():
        assert after[key] == pytest.approx(value, rel=1e-9, abs=1e-9), key
