"""The operator's REST views on SQLite and PostgreSQL: trends of every indicator (whole-record
ones with a null tooth), units and record labels, CSV exports, the rig overview, webhooks and
the notification outbox."""

from __future__ import annotations

import csv
import datetime as dt
import io

import pytest

from tests.service.conftest import Api
from tests.service.seed import TEETH, Seeded, seed_campaign
from tests.storage.factories import analysis, campaign_config, store_accepted

KURTOSIS_JUMP_DAY = 8


@pytest.fixture
def seeded(api: Api) -> Seeded:
    with api.session() as session:
        data = seed_campaign(session)
        session.commit()
    return data


def seed_kurtosis_rig(api: Api, days: int = 12) -> list[int]:
    """A rig whose whole-record kurtosis jumps from 3 to 10 on day 8 (default kurtosis rule:
    scored from the 3rd record, CUSUM → an alarm on day 8 itself)."""
    from gearwatch.usecases.alarms import evaluate_record
    from storage.repositories import AlarmRuleRepository, CampaignRepository, RecordRepository

    ids = []
    with api.session() as session:
        stored = CampaignRepository(session).ensure(campaign_config("camp-k", "rig-k"))
        AlarmRuleRepository(session).ensure_defaults(stored.rig_id)
        records = RecordRepository(session)
        t0 = dt.datetime(2026, 4, 1, 8, tzinfo=dt.UTC)
        for day in range(days):
            sha = f"k{day}".encode().hex().ljust(64, "0")
            record = records.add(
                stored, sha256=sha, file_name=f"k{day}.wav", raw_location="/nonexistent",
                taken_at=t0 + dt.timedelta(days=day), label=f"run {day}",
            )
            kurtosis = 3.0 + 0.01 * (day % 3) if day < KURTOSIS_JUMP_DAY else 10.0
            result_analysis = analysis(sha256=sha, kurtosis=kurtosis)
            records.mark_accepted(record, result_analysis)
            evaluate_record(session, record, records.add_result(record, result_analysis))
            ids.append(record.id)
        session.commit()
    return ids


def test_a_whole_record_indicator_has_a_trend_with_a_null_tooth_and_record_labels(api: Api) -> None:
    ids = seed_kurtosis_rig(api)
    answer = api.get("/api/v1/rigs/rig-k/trends?indicator=kurtosis")
    assert answer.status_code == 200, answer.text
    trend = answer.json()
    assert trend["scope"] == "record" and trend["teeth"] == [None]
    assert trend["unit"] == ""  # kurtosis is dimensionless
    assert [r["record_id"] for r in trend["records"]] == ids
    assert [r["label"] for r in trend["records"]][:2] == ["run 0", "run 1"]
    values = [row[0] for row in trend["values"]]
    assert values[KURTOSIS_JUMP_DAY:] == [10.0] * (len(ids) - KURTOSIS_JUMP_DAY)
    assert values[0] == pytest.approx(3.0)
    # units follow the channel for amplitude metrics; the MCI depth is in nepers
    assert api.get("/api/v1/rigs/rig-k/trends?indicator=rms").json()["unit"] == "g"
    assert api.get("/api/v1/rigs/rig-k/trends?indicator=mci_depth").json()["unit"] == "Np"
    for name in ("fm4", "na4", "raw_kurtosis", "er"):
        assert api.get(f"/api/v1/rigs/rig-k/trends?indicator={name}").status_code == 200
    # a tooth of a whole-record indicator, or an unknown indicator, is the caller's error
    assert api.get("/api/v1/rigs/rig-k/trends?indicator=fm4&tooth=3").status_code == 422
    assert api.get("/api/v1/rigs/rig-k/trends?indicator=nope").status_code == 422


def test_a_whole_record_alarm_has_a_null_tooth_never_tooth_0(api: Api) -> None:
    seed_kurtosis_rig(api)
    items = api.get("/api/v1/alarms?rig_id=rig-k").json()["items"]
    kurtosis = [a for a in items if a["indicator"] == "kurtosis"]
    assert len(kurtosis) == 1, items
    alarm = kurtosis[0]
    assert alarm["tooth"] is None
    assert alarm["record_label"] == f"run {KURTOSIS_JUMP_DAY}"  # CUSUM: on the jump itself
    assert alarm["campaign_id"] == "camp-k"
    detail = api.get(f"/api/v1/alarms/{alarm['id']}").json()
    assert detail["tooth"] is None


def test_a_per_tooth_trend_exports_as_csv_with_labels_dates_and_units(
    api: Api, seeded: Seeded
) -> None:
    answer = api.get("/api/v1/rigs/rig-a/trends?indicator=mci_depth&format=csv")
    assert answer.status_code == 200, answer.text
    assert answer.headers["content-type"].startswith("text/csv")
    rows = list(csv.reader(io.StringIO(answer.text)))
    header, body = rows[0], rows[1:]
    assert header[:4] == ["record_id", "taken_at", "label", "channel"]
    assert header[4] == "mci_depth tooth 1 [Np]" and len(header) == 4 + TEETH
    assert [int(r[0]) for r in body] == seeded.record_ids
    assert body[0][2] == "day 0"
    spall_column = 3 + seeded.spall_tooth
    assert float(body[-1][spall_column]) == pytest.approx(
        seeded.depths[-1][seeded.spall_tooth], rel=1e-6
    )
    one = api.get("/api/v1/rigs/rig-a/trends?indicator=mci_depth&tooth=7&format=csv").text
    assert one.splitlines()[0].endswith("mci_depth tooth 7 [Np]")


def test_the_alarm_list_exports_as_csv(api: Api, seeded: Seeded) -> None:
    seed_kurtosis_rig(api)
    answer = api.get("/api/v1/alarms?format=csv")
    assert answer.status_code == 200
    assert answer.headers["content-type"].startswith("text/csv")
    rows = list(csv.DictReader(io.StringIO(answer.text)))
    by_indicator = {(r["rig_id"], r["indicator"]): r for r in rows}
    spall = by_indicator[("rig-a", "mci_depth")]
    assert spall["tooth"] == str(seeded.spall_tooth) and spall["unit"] == "Np"
    assert spall["record_label"].startswith("day ")
    whole = by_indicator[("rig-k", "kurtosis")]
    assert whole["tooth"] == ""  # a whole-record alarm has no tooth


def test_the_overview_shows_every_rig_last_record_alarms_and_worst_tooth(
    api: Api, seeded: Seeded
) -> None:
    seed_kurtosis_rig(api)
    items = {r["rig_id"]: r for r in api.get("/api/v1/overview").json()["items"]}
    assert set(items) == {"rig-a", "rig-k"}
    rig = items["rig-a"]
    assert rig["last_record"]["status"] == "rejected"  # the seed's last record is broken
    assert "too few revolutions" in rig["last_record"]["reason"]
    assert rig["open_alarms"].get("alarm", 0) + rig["open_alarms"].get("warning", 0) >= 1
    worst = rig["worst_tooth"]
    assert worst["tooth"] == seeded.spall_tooth and worst["record_id"] == seeded.record_ids[-1]
    assert worst["unit"] in ("Np", "baseline units")
    assert len(rig["sparkline"]) == len(seeded.record_ids)
    assert items["rig-k"]["open_alarms"] == {"alarm": 1}
    indicators = {i["name"]: i for i in api.get("/api/v1/indicators").json()["items"]}
    assert indicators["raw_kurtosis"]["scope"] == "record"
    assert indicators["mci_depth"]["unit"] == "Np"


def test_curves_relative_to_their_median_bring_the_band_to_the_curve(
    api: Api, seeded: Seeded
) -> None:
    record = seeded.record_ids[-1]
    answer = api.get(f"/api/v1/records/{record}/curves?names=mci&band=true&relative=true").json()
    mci = answer["curves"]["mci"]
    ordered = sorted(mci)
    assert abs(ordered[len(ordered) // 2]) < 1e-6  # the median is the reference
    band = answer["baseline_band"]
    assert band is not None and min(band["lower"]) <= 0 <= max(band["upper"])


def test_per_rig_webhooks_are_managed_over_rest_and_audited(api: Api, seeded: Seeded) -> None:
    url = "http://127.0.0.1:9/hook"
    assert api.client.post(
        "/api/v1/rigs/rig-a/webhooks", json={"url": url}, headers=api.headers("viewer")
    ).status_code == 403
    created = api.client.post(
        "/api/v1/rigs/rig-a/webhooks", json={"url": url, "description": "chat"},
        headers=api.headers("operator"),
    )
    assert created.status_code == 201, created.text
    hook = created.json()
    again = api.client.post(
        "/api/v1/rigs/rig-a/webhooks", json={"url": url}, headers=api.headers("operator")
    )
    assert again.status_code == 409
    bad = api.client.post(
        "/api/v1/rigs/rig-a/webhooks", json={"url": "ftp://x"}, headers=api.headers("operator")
    )
    assert bad.status_code == 422
    assert api.get("/api/v1/rigs/rig-a/webhooks").status_code == 403  # viewers: no URLs
    listed = api.get("/api/v1/rigs/rig-a/webhooks", role="operator").json()
    assert [h["url"] for h in listed["items"]] == [url]
    audit = api.get("/api/v1/audit?action=webhook.add", role="admin").json()["items"]
    assert audit and audit[0]["details"]["url"] == url
    gone = api.client.delete(
        f"/api/v1/rigs/rig-a/webhooks/{hook['id']}", headers=api.headers("operator")
    )
    assert gone.status_code == 204
    assert api.get("/api/v1/rigs/rig-a/webhooks", role="operator").json()["items"] == []


def _seed_pair(api: Api, campaign: str, teeth: int, day0: int, days: int) -> list[int]:
    """``days`` accepted records of a campaign on rig ``rig-p`` whose pinion has ``teeth``."""
    from storage.repositories import CampaignRepository, RecordRepository

    ids = []
    with api.session() as session:
        stored = CampaignRepository(session).ensure(
            campaign_config(campaign, "rig-p", pinion_teeth=teeth, gear_teeth=43))
        records = RecordRepository(session)
        for day in range(day0, day0 + days):
            sha = f"{campaign}{day}".encode().hex().ljust(64, "0")[:64]
            record = store_accepted(
                records, stored, analysis(sha256=sha, teeth=teeth, curve_length=64 * teeth),
                taken_at=dt.datetime(2026, 4, 1, 8, tzinfo=dt.UTC) + dt.timedelta(days=day),
                file_name=f"{campaign}{day}.wav",
            )
            ids.append(record.id)
        session.commit()
    return ids


def test_a_new_gear_pair_on_a_rig_starts_its_own_tooth_views(api: Api) -> None:
    """A rig runs one gear pair per campaign: after a 17-tooth pinion replaces a 20-tooth one,
    the rig's trends cover the 17-tooth campaign (tooth 5 of one pinion is not tooth 5 of the
    other), an older record keeps its own pinion's teeth, and replaying the older campaign's
    manifest brings its pair back."""
    first = _seed_pair(api, "pair-20", 20, 0, 3)
    assert api.get("/api/v1/rigs/rig-p/trends?indicator=mci_depth").json()["teeth"] == list(
        range(1, 21))
    second = _seed_pair(api, "pair-17", 17, 3, 2)
    for indicator in ("mci_depth", "kurtosis"):
        trend = api.get(f"/api/v1/rigs/rig-p/trends?indicator={indicator}").json()
        assert [r["record_id"] for r in trend["records"]] == second, indicator
        assert len(trend["values"][0]) == (17 if indicator == "mci_depth" else 1)
    assert api.get("/api/v1/rigs/rig-p").json()["pinion_teeth"] == 17
    curves = api.get(f"/api/v1/records/{first[0]}/curves?names=mci").json()
    assert curves["pinion_teeth"] == 20
    assert {s["tooth"] for s in curves["sectors"]} == set(range(1, 21))
    # the older campaign's manifest again (a replay with new parameters): its pair is current
    _seed_pair(api, "pair-20", 20, 5, 1)
    trend = api.get("/api/v1/rigs/rig-p/trends?indicator=mci_depth").json()
    assert trend["teeth"] == list(range(1, 21))
    assert [r["record_id"] for r in trend["records"]][:3] == first


def test_an_earlier_gear_pair_stays_within_reach_of_the_trend(api: Api) -> None:
    """``campaign=`` gives one campaign's trend numbered by the pair it ran, even when the rig
    has moved on to another pair; the default stays the current pair's; a campaign of another
    rig, or none, is 404; the cached answers of both scopes do not mix."""
    first = _seed_pair(api, "pair-20", 20, 0, 3)
    second = _seed_pair(api, "pair-17", 17, 3, 2)
    default = api.get("/api/v1/rigs/rig-p/trends?indicator=mci_depth").json()
    assert default["campaign"] is None and len(default["teeth"]) == 17
    for indicator, columns in (("mci_depth", 20), ("kurtosis", 1)):
        old = api.get(f"/api/v1/rigs/rig-p/trends?indicator={indicator}&campaign=pair-20").json()
        assert old["campaign"] == "pair-20"
        assert [r["record_id"] for r in old["records"]] == first, indicator
        assert len(old["teeth"]) == columns and len(old["values"][0]) == columns
    one_tooth = api.get("/api/v1/rigs/rig-p/trends?tooth=19&campaign=pair-20").json()
    assert one_tooth["teeth"] == [19] and len(one_tooth["values"]) == 3
    current = api.get("/api/v1/rigs/rig-p/trends?campaign=pair-17").json()
    assert [r["record_id"] for r in current["records"]] == second
    csv_text = api.client.get("/api/v1/rigs/rig-p/trends?campaign=pair-20&format=csv",
                              headers=api.headers("viewer")).text
    assert len(csv_text.strip().splitlines()) == 1 + len(first)
    assert api.get("/api/v1/rigs/rig-p/trends").json()["teeth"] == list(range(1, 18))
    with api.session() as session:  # a campaign of another rig
        from storage.repositories import CampaignRepository

        CampaignRepository(session).ensure(campaign_config("other", "rig-q", pinion_teeth=20))
        session.commit()
    for name in ("other", "nowhere"):
        missing = api.client.get(f"/api/v1/rigs/rig-p/trends?campaign={name}",
                                 headers=api.headers("viewer"))
        assert missing.status_code == 404 and name in missing.json()["error"]["message"]
    bad = api.client.get("/api/v1/rigs/rig-p/trends?campaign=a%2Fb", headers=api.headers("viewer"))
    assert bad.status_code == 422
