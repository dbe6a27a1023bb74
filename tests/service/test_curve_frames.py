"""The curves of a tach-less campaign: in the pair's tooth frame, or unnumbered when refused.

A tach-less record's stored curves (pinion average, difference, MCI) are in the campaign's tooth
frame, where tooth 1 sits at 0° when the campaign's reference is itself tach-less, not at the
manifest's ``tooth1_pitch_angle_deg``. Drawn against the manifest's sectors as stored, the MCI well
of a spalled tooth sat under another tooth's label in the dashboard (seed 10411 of
``physics.independent.random_campaign`` replayed without its tach: the well under tooth 38 of the
alarm, the red sector 135° away). On SQLite and PostgreSQL.
"""

from __future__ import annotations

import dataclasses
import datetime as dt

import pytest

from gearwatch.floor.results import TOOTH1_ANGLE_KEY, RecordAnalysis
from tests.service.conftest import Api
from tests.storage.factories import analysis, campaign_config, store_accepted

T0 = dt.datetime(2026, 3, 1, 8, 0, tzinfo=dt.UTC)
SAMPLES = 1280  # the factory's curves: 20 teeth × 64
MANIFEST_TOOTH1_DEG = 9.0  # campaign_config's: 9° = 32 samples


def _tachless(base: RecordAnalysis, kind: str) -> RecordAnalysis:
    """The factory's analysis as a tach-less record placed in the campaign frame (tooth 1 at 0°)
    or refused (no tooth numbers, no angle kept)."""
    channel = base.channels[0]
    stats = dict(channel.baseline_stats)
    if kind == "campaign":
        stats[TOOTH1_ANGLE_KEY] = 0.0
    channel = dataclasses.replace(
        channel, baseline_stats=stats, teeth=channel.teeth if kind == "campaign" else [])
    quality = dataclasses.replace(
        base.quality, angle_source="none" if kind == "none" else "mesh_phase",
        tooth_frames={"acc": {"kind": kind, "reference_frame": "mesh_phase"}})
    return dataclasses.replace(base, channels=[channel], quality=quality)


def _seed(api: Api, kinds: list[str]) -> list[int]:
    from storage.repositories import CampaignRepository, RecordRepository

    ids = []
    with api.session() as session:
        stored = CampaignRepository(session).ensure(campaign_config("camp-t", "rig-t"))
        records = RecordRepository(session)
        for day, kind in enumerate(kinds):
            sha = f"tachless-{day}".encode().hex().ljust(64, "0")[:64]
            record = store_accepted(
                records, stored, _tachless(analysis(sha256=sha, curve_length=SAMPLES), kind),
                taken_at=T0 + dt.timedelta(days=day), file_name=f"day{day}.wav", label=f"day {day}")
            ids.append(record.id)
        session.commit()
    return ids


def test_a_placed_tachless_record_is_drawn_in_the_pairs_tooth_frame(api: Api) -> None:
    placed, _, _, refused = _seed(api, ["campaign", "campaign", "campaign", "refused"])
    body = api.get(f"/api/v1/records/{placed}/curves?band=true").json()
    shift = round(MANIFEST_TOOTH1_DEG / 360 * SAMPLES)
    # the factory's MCI is cos(angle)/3 with its maximum at tooth 1 (sample 0 of the campaign
    # frame): in the pair's frame tooth 1 is at 9°, and so is the maximum
    mci = body["curves"]["mci"]
    assert max(range(SAMPLES), key=lambda i: mci[i]) == shift
    assert mci[shift] == pytest.approx(1 / 3, rel=1e-6)
    # the pinion average turns with it (sin(20·angle): a quarter of a mesh period later, its peak)
    assert body["curves"]["pinion_average"][shift + 16] == pytest.approx(1.0, abs=1e-6)
    assert {s["tooth"] for s in body["sectors"]} == set(range(1, 21))
    assert body["tooth_frame"] == "campaign"
    assert body["turned_deg"] == pytest.approx(MANIFEST_TOOTH1_DEG)
    # the band: the three placed records, each turned the same way; the refused one left out
    band = body["baseline_band"]
    assert band["records"] == 3
    assert band["lower"][shift] == pytest.approx(1 / 3, rel=1e-6) == band["upper"][shift]

    unnumbered = api.get(f"/api/v1/records/{refused}/curves").json()
    assert unnumbered["tooth_frame"] == "refused" and unnumbered["sectors"] == []
    assert unnumbered["turned_deg"] == 0.0
    assert unnumbered["curves"]["mci"][0] == pytest.approx(1 / 3, rel=1e-6)  # as stored


def test_a_tach_record_stored_before_the_angle_was_kept_stays_where_it_was(api: Api) -> None:
    from storage.repositories import CampaignRepository, RecordRepository

    with api.session() as session:
        stored = CampaignRepository(session).ensure(campaign_config("camp-old", "rig-old"))
        records = RecordRepository(session)
        # no angle kept, no tooth frame
        record = store_accepted(records, stored, analysis(sha256="a" * 64, curve_length=SAMPLES),
                                taken_at=T0, file_name="old.wav", label="old")
        session.commit()
        record_id = record.id
    body = api.get(f"/api/v1/records/{record_id}/curves").json()
    assert body["tooth_frame"] == "tachometer" and body["turned_deg"] == 0.0
    assert body["curves"]["mci"][0] == pytest.approx(1 / 3, rel=1e-6)
    assert len({s["tooth"] for s in body["sectors"]}) == 20


def test_the_frame_helpers_known_answers() -> None:
    """:func:`storage.operator_queries.curve_frame` and ``in_pair_frame``'s doctests."""
    import doctest

    import storage.operator_queries

    result = doctest.testmod(storage.operator_queries, optionflags=doctest.ELLIPSIS)
    assert result.failed == 0 and result.attempted >= 4


def test_the_report_draws_tachless_curves_in_the_pairs_frame_and_leaves_refused_ones_out(api: Api) -> None:
    from gearwatch.usecases.report import collect

    _seed(api, ["campaign", "campaign", "campaign", "refused"])
    with api.session() as session:
        data = collect(session, "rig-t")
    assert data.curves is not None and data.curves.tachless
    shift = round(MANIFEST_TOOTH1_DEG / 360 * SAMPLES)
    # first and last days are drawn: the refused last day is left out, the first is turned
    assert [name.split(" — ")[0] for name, _ in data.curves.curves] == ["day 0"]
    (_, mci), = data.curves.curves
    assert max(range(SAMPLES), key=lambda i: mci[i]) == shift
    assert data.curves.band_records == 3


def test_the_overview_says_which_record_the_worst_tooth_comes_from(api: Api) -> None:
    """The last record of a tach-less campaign may have no per-tooth values (its teeth were not
    numbered): the worst tooth shown is an earlier record's, and the overview says which."""
    ids = _seed(api, ["campaign", "campaign", "campaign", "refused"])
    rig = next(r for r in api.get("/api/v1/overview").json()["items"] if r["rig_id"] == "rig-t")
    assert rig["last_record"]["record_id"] == ids[-1]
    assert rig["worst_tooth"]["record_id"] == ids[2]
    assert rig["worst_tooth"]["record_label"] == "day 2"


def test_a_per_tooth_trend_names_the_records_whose_teeth_are_not_numbered(api: Api) -> None:
    ids = _seed(api, ["campaign", "refused", "campaign"])
    trend = api.get("/api/v1/rigs/rig-t/trends?indicator=mci_depth").json()
    assert [r["record_id"] for r in trend["records"]] == [ids[0], ids[2]]
    (without,) = trend["without_tooth_values"]
    assert without["record_id"] == ids[1] and without["label"] == "day 1"
    whole = api.get("/api/v1/rigs/rig-t/trends?indicator=kurtosis").json()
    assert len(whole["records"]) == 3 and whole["without_tooth_values"] == []


def test_a_record_without_a_shaft_angle_has_no_speed_rather_than_zero(api: Api) -> None:
    """No tach and no mesh line: the record keeps its whole-record metrics, and its speed is
    unknown (NULL in the database, null in the API, "—" in the report), not 0 rpm."""
    from gearwatch.usecases.report import collect

    ids = _seed(api, ["campaign", "none"])
    record = api.get(f"/api/v1/records/{ids[1]}").json()
    assert record["status"] == "accepted"
    assert record["speed_rpm"] is None and record["speed_variation"] is None
    assert api.get(f"/api/v1/records/{ids[0]}").json()["speed_rpm"] == pytest.approx(1500.0)
    with api.session() as session:
        rows = {row.record_id: row for row in collect(session, "rig-t").records}
    assert rows[ids[1]].speed_rpm is None and rows[ids[0]].speed_rpm == pytest.approx(1500.0)
