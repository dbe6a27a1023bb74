"""REST API behaviour on SQLite and PostgreSQL: auth and roles, known-answer trends, alarms,
acknowledgement, rules, records, curves, uploads, error bodies, audit log."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import pytest

from tests.service.conftest import Api
from tests.service.seed import TEETH, Seeded, healthy_depth, seed_campaign, spall_depth


@pytest.fixture
def seeded(api: Api) -> Seeded:
    with api.session() as session:
        data = seed_campaign(session)
        session.commit()
    return data


def error_of(response: Any, status: int) -> dict[str, Any]:
    """Assert a JSON error body with that status; return its ``error`` object."""
    assert response.status_code == status, response.text
    assert response.headers["content-type"].startswith("application/json")
    body = response.json()
    assert set(body) == {"error"}
    assert isinstance(body["error"]["code"], str) and body["error"]["message"]
    return body["error"]


def api_operations(api: Api) -> list[tuple[str, str]]:
    """(method, path with ids filled in) of every operation in the OpenAPI document."""
    operations = []
    for path, item in api.app.openapi()["paths"].items():
        concrete = re.sub(r"\{[^}]+\}", "1", path)
        for method in item:
            operations.append((method.upper(), concrete))
    return operations


# -- authentication and roles -------------------------------------------------------------


def test_health_is_the_only_anonymous_endpoint(api: Api) -> None:
    response = api.client.get("/health")
    assert response.status_code == 200
    assert response.json()["status"] == "ok" and response.json()["database"] == "ok"
    checked = 0
    for method, path in api_operations(api):
        if path == "/health":
            continue
        response = api.client.request(method, path)
        error = error_of(response, 401)
        assert error["code"] == "unauthorized"
        assert response.headers.get("www-authenticate") == "Bearer"
        checked += 1
    assert checked >= 20


@pytest.mark.parametrize(
    "authorization",
    ["Bearer gw_00000000_nope", "Bearer not-a-key", "Basic dXNlcjpwYXNz", "Bearer "],
)
def test_unknown_or_malformed_keys_are_refused(api: Api, authorization: str) -> None:
    response = api.client.get("/api/v1/rigs", headers={"Authorization": authorization})
    error_of(response, 401)


def test_a_revoked_key_is_refused(api: Api) -> None:
    assert api.get("/api/v1/me", "viewer").status_code == 200
    keys = api.get("/api/v1/keys", "admin").json()["items"]
    viewer = next(k for k in keys if k["role"] == "viewer")
    revoked = api.client.delete(f"/api/v1/keys/{viewer['id']}", headers=api.headers("admin"))
    assert revoked.status_code == 200 and revoked.json()["revoked_at"]
    error_of(api.get("/api/v1/me", "viewer"), 401)


def test_every_write_refuses_a_viewer_key(api: Api) -> None:
    writes = [(m, p) for m, p in api_operations(api) if m in {"POST", "PUT", "PATCH", "DELETE"}]
    assert len(writes) >= 7
    for method, path in writes:
        response = api.client.request(method, path, headers=api.headers("viewer"), json={})
        assert error_of(response, 403)["code"] == "forbidden", (method, path)


def test_admin_endpoints_refuse_an_operator(api: Api) -> None:
    error_of(api.get("/api/v1/keys", "operator"), 403)
    error_of(api.get("/api/v1/audit", "operator"), 403)
    response = api.client.post(
        "/api/v1/keys", json={"role": "viewer"}, headers=api.headers("operator")
    )
    error_of(response, 403)


def test_me_reports_the_key_role(api: Api) -> None:
    for role in ("viewer", "operator", "admin"):
        me = api.get("/api/v1/me", role).json()
        assert me["role"] == role and me["name"] == f"{role} key"
        assert api.keys[role].split("_")[1] == me["prefix"]


def test_keys_created_through_the_api_work_and_are_stored_hashed(api: Api) -> None:
    response = api.client.post(
        "/api/v1/keys", json={"role": "operator", "name": "rig PC"}, headers=api.headers("admin")
    )
    assert response.status_code == 201
    created = response.json()
    me = api.client.get("/api/v1/me", headers={"Authorization": f"Bearer {created['key']}"})
    assert me.json() == {"prefix": created["prefix"], "name": "rig PC", "role": "operator"}
    listing = api.get("/api/v1/keys", "admin").json()["items"]
    assert all("key" not in item for item in listing)
    from storage.models import ApiKey

    with api.session() as session:
        rows = session.query(ApiKey).all()
        assert all(created["key"] not in (r.key_sha256, r.name, r.prefix) for r in rows)
    audit = api.get("/api/v1/audit", "admin").json()["items"]
    assert audit[0]["action"] == "key.create" and audit[0]["target"] == f"key:{created['prefix']}"


# -- rigs and trends ------------------------------------------------------------------------


def test_rigs(api: Api, seeded: Seeded) -> None:
    rigs = api.get("/api/v1/rigs").json()["items"]
    assert [r["rig_id"] for r in rigs] == ["rig-a"]
    rig = api.get("/api/v1/rigs/rig-a").json()
    assert rig["pinion_teeth"] == TEETH and rig["campaigns"] == ["camp-a"]
    assert rig["records"] == len(seeded.record_ids) + 1
    assert error_of(api.get("/api/v1/rigs/rig-x"), 404)["code"] == "not_found"


def test_trend_of_every_tooth_is_records_by_teeth_with_the_stored_values(
    api: Api, seeded: Seeded
) -> None:
    trend = api.get("/api/v1/rigs/rig-a/trends?indicator=mci_depth").json()
    assert trend["teeth"] == list(range(1, TEETH + 1))
    assert [r["record_id"] for r in trend["records"]] == seeded.record_ids  # rejected left out
    assert len(trend["values"]) == len(seeded.record_ids)
    for day, row in enumerate(trend["values"]):
        assert len(row) == TEETH
        for tooth, value in enumerate(row, start=1):
            assert value == pytest.approx(seeded.depths[day][tooth], rel=1e-12)
    assert trend["values"][-1][seeded.spall_tooth - 1] == pytest.approx(
        spall_depth(13, seeded.onset_day)
    )
    assert trend["records"][3]["taken_at"] == seeded.taken_at[3].isoformat().replace("+00:00", "Z")


def test_trend_of_one_tooth(api: Api, seeded: Seeded) -> None:
    trend = api.get("/api/v1/rigs/rig-a/trends?indicator=mci_depth&tooth=3").json()
    assert trend["teeth"] == [3]
    assert [row[0] for row in trend["values"]] == pytest.approx(
        [healthy_depth(3, d) for d in range(len(seeded.record_ids))]
    )


def test_trend_of_another_indicator_and_bad_parameters(api: Api, seeded: Seeded) -> None:
    trend = api.get("/api/v1/rigs/rig-a/trends?indicator=diff_energy&tooth=4").json()
    assert trend["values"][0][0] == pytest.approx(1.04)  # factory: 1 + 0.01·tooth
    error_of(api.get("/api/v1/rigs/rig-a/trends?indicator=bogus"), 422)
    error_of(api.get("/api/v1/rigs/rig-a/trends?tooth=0"), 422)
    error_of(api.get("/api/v1/rigs/rig-a/trends?tooth=abc"), 422)
    error_of(api.get("/api/v1/rigs/nope/trends"), 404)


# -- alarms ---------------------------------------------------------------------------------


def test_alarm_list_shows_the_spalled_tooth_raised_at_the_raising_records_time(
    api: Api, seeded: Seeded
) -> None:
    body = api.get("/api/v1/alarms?rig_id=rig-a").json()
    items = [a for a in body["items"] if a["indicator"] == "mci_depth"]
    assert len(items) == 1
    alarm = items[0]
    assert {"id", "rig_id", "tooth", "indicator", "state", "record_id", "raised_at"} <= set(alarm)
    assert alarm["rig_id"] == "rig-a" and alarm["tooth"] == seeded.spall_tooth
    assert alarm["state"] == "alarm"
    # persistence 3: the third record beyond the levels raises it
    raising_day = seeded.onset_day + 2
    assert alarm["record_id"] == seeded.record_ids[raising_day]
    assert alarm["raised_at"] == seeded.taken_at[raising_day].isoformat().replace("+00:00", "Z")
    assert api.get("/api/v1/alarms?state=cleared").json()["items"] == []
    assert len(api.get("/api/v1/alarms?state=alarm&rig_id=rig-a").json()["items"]) >= 1
    error_of(api.get("/api/v1/alarms?state=bogus"), 422)
    error_of(api.get("/api/v1/alarms?rig_id=nope"), 404)


def test_acknowledge_records_who_when_comment_history_and_audit(api: Api, seeded: Seeded) -> None:
    alarm = next(
        a
        for a in api.get("/api/v1/alarms?rig_id=rig-a").json()["items"]
        if a["indicator"] == "mci_depth"
    )
    url = f"/api/v1/alarms/{alarm['id']}/ack"
    error_of(api.client.post(url, json={"comment": "x"}, headers=api.headers("viewer")), 403)
    response = api.client.post(
        url, json={"comment": "pitting seen on tooth 7"}, headers=api.headers("operator")
    )
    assert response.status_code == 200, response.text
    acked = response.json()
    assert acked["state"] == "acknowledged"
    assert acked["acknowledged_by"].startswith("operator key")
    assert acked["ack_comment"] == "pitting seen on tooth 7" and acked["acknowledged_at"]
    states = [e["state"] for e in acked["history"]]
    assert states[-1] == "acknowledged" and "alarm" in states
    assert acked["history"][-1]["who"] == acked["acknowledged_by"]
    again = api.client.post(url, json={}, headers=api.headers("operator"))
    assert error_of(again, 409)["code"] == "conflict"
    audit = api.get("/api/v1/audit?action=alarm.ack", "admin").json()["items"]
    assert len(audit) == 1 and audit[0]["target"] == f"alarm:{alarm['id']}"
    assert audit[0]["details"]["comment"] == "pitting seen on tooth 7"
    detail = api.get(f"/api/v1/alarms/{alarm['id']}").json()
    assert detail["state"] == "acknowledged"
    error_of(api.client.post("/api/v1/alarms/999999/ack", headers=api.headers("operator")), 404)


def test_alarm_levels_say_where_each_tooth_stands(api: Api, seeded: Seeded) -> None:
    """The levels a trend draws are the rule's own: the spalled tooth's baseline is the one its
    alarm was raised against, and every level is centre + level × spread."""
    body = api.get("/api/v1/rigs/rig-a/alarm-levels?indicator=mci_depth").json()
    assert body["campaign"] == "camp-a" and body["rule"]["indicator"] == "mci_depth"
    assert body["pooled_spread"] is None  # not a record-relative rule
    items = {item["tooth"]: item for item in body["items"]}
    assert sorted(items) == list(range(1, 21))
    rule = body["rule"]
    for item in items.values():
        assert item["warning"] == pytest.approx(item["centre"] + rule["warning_level"] * item["spread"])
        assert item["alarm"] == pytest.approx(item["centre"] + rule["alarm_level"] * item["spread"])
        assert item["baseline_records"] == rule["baseline_records"]
    alarm = next(a for a in api.get("/api/v1/alarms?rig_id=rig-a").json()["items"]
                 if a["indicator"] == "mci_depth" and a["tooth"] == seeded.spall_tooth)
    spalled = items[seeded.spall_tooth]
    assert spalled["state"] == alarm["state"] == "alarm"
    assert spalled["centre"] == pytest.approx(alarm["baseline_centre"])
    assert spalled["spread"] == pytest.approx(alarm["baseline_spread"])
    assert all(item["state"] is None for tooth, item in items.items() if tooth != seeded.spall_tooth)
    same = api.get("/api/v1/rigs/rig-a/alarm-levels?indicator=mci_depth&campaign=camp-a").json()
    assert same == body
    error_of(api.get("/api/v1/rigs/rig-a/alarm-levels?indicator=mci_depth&campaign=nope"), 404)
    error_of(api.get("/api/v1/rigs/rig-a/alarm-levels?indicator=mci_depth&channel=nope"), 404)
    error_of(api.get("/api/v1/rigs/rig-a/alarm-levels?indicator=bogus"), 422)
    error_of(api.get("/api/v1/rigs/rig-a/alarm-levels?indicator=mci_depth", None), 401)


def test_operators_change_alarm_rules(api: Api, seeded: Seeded) -> None:
    rules = api.get("/api/v1/rigs/rig-a/alarm-rules").json()["items"]
    assert {r["indicator"] for r in rules} >= {"mci_depth"}
    new = {
        "indicator": "mci_depth",
        "baseline_records": 5,
        "warning_level": 3.0,
        "alarm_level": 6.0,
        "clear_level": 1.5,
        "persistence": 2,
        "enabled": True,
    }
    url = "/api/v1/rigs/rig-a/alarm-rules/mci_depth"
    op = api.headers("operator")
    error_of(api.client.put(url, json=new, headers=api.headers("viewer")), 403)
    response = api.client.put(url, json=new, headers=api.headers("operator"))
    assert response.status_code == 200, response.text
    stored = next(
        r
        for r in api.get("/api/v1/rigs/rig-a/alarm-rules").json()["items"]
        if r["indicator"] == "mci_depth"
    )
    assert {k: stored[k] for k in new} == new
    bad = dict(new, clear_level=4.0)  # clear must be below warning
    error_of(api.client.put(url, json=bad, headers=api.headers("operator")), 422)
    mismatch = api.client.put(
        "/api/v1/rigs/rig-a/alarm-rules/kurtosis", json=new, headers=api.headers("operator")
    )
    error_of(mismatch, 422)
    added = api.client.put(
        "/api/v1/rigs/rig-a/alarm-rules/diff_energy",
        json={"indicator": "diff_energy"},
        headers=api.headers("operator"),
    )
    from storage.models import AlarmRule

    default_persistence = AlarmRule.__table__.c.persistence.default.arg
    assert added.status_code == 200 and added.json()["persistence"] == default_persistence
    partial = api.client.put(url, json={"indicator": "mci_depth", "persistence": 4}, headers=op)
    assert partial.json()["persistence"] == 4 and partial.json()["baseline_records"] == 5
    # against the stored clear level 1.5, a warning level of 1.0 breaks the order
    clash = api.client.put(url, json={"indicator": "mci_depth", "warning_level": 1.0}, headers=op)
    error_of(clash, 422)
    deleted = api.client.delete(
        "/api/v1/rigs/rig-a/alarm-rules/diff_energy", headers=api.headers("operator")
    )
    assert deleted.status_code == 204
    actions = [e["action"] for e in api.get("/api/v1/audit", "admin").json()["items"]]
    assert actions[:4] == [
        "alarm_rule.delete",
        "alarm_rule.put",
        "alarm_rule.put",
        "alarm_rule.put",
    ]


# -- records, results, curves ---------------------------------------------------------------


def test_records_list_and_detail(api: Api, seeded: Seeded) -> None:
    body = api.get("/api/v1/records?rig_id=rig-a&limit=5").json()
    assert body["total"] == len(seeded.record_ids) + 1 and len(body["items"]) == 5
    assert [r["id"] for r in body["items"]] == seeded.record_ids[:5]
    rejected = api.get("/api/v1/records?status=rejected").json()["items"]
    assert [r["id"] for r in rejected] == [seeded.rejected_id]
    assert rejected[0]["reason"] == "too few revolutions: 3 < 20"
    since = seeded.taken_at[12].isoformat()
    later = api.get("/api/v1/records", params={"since": since, "status": "accepted"}).json()
    assert [r["id"] for r in later["items"]] == seeded.record_ids[12:]
    error_of(api.get("/api/v1/records?since=2026-03-01T00:00:00"), 422)  # no time zone
    detail = api.get(f"/api/v1/records/{seeded.record_ids[0]}").json()
    assert detail["status"] == "accepted" and detail["campaign_id"] == "camp-a"
    channel = detail["current_result"]["channels"][0]
    assert channel["channel"] == "acc" and len(channel["teeth"]) == TEETH
    assert channel["teeth"][6]["mci_depth"] == pytest.approx(healthy_depth(7, 0))
    assert channel["metrics"]["kurtosis"] == 3.0
    assert set(channel["curves"]) == {"pinion_average", "mci"}
    results = api.get(f"/api/v1/records/{seeded.record_ids[0]}/results").json()["items"]
    assert len(results) == 1 and results[0]["is_current"]
    error_of(api.get("/api/v1/records/999999"), 404)
    error_of(api.get("/api/v1/records/0"), 422)


def test_curves_with_sectors_and_baseline_band(api: Api, seeded: Seeded) -> None:
    record_id = seeded.record_ids[-1]
    body = api.get(f"/api/v1/records/{record_id}/curves?names=mci&band=true").json()
    mci = body["curves"]["mci"]
    assert list(body["curves"]) == ["mci"] and len(mci) == body["samples_per_rev"] == 1280
    # the factory's curve: cos(angle)/3 in float32
    assert mci[0] == pytest.approx(1 / 3, rel=1e-6)
    assert mci[320] == pytest.approx(math.cos(math.pi / 2) / 3, abs=1e-6)
    sectors = body["sectors"]
    assert {s["tooth"] for s in sectors} == set(range(1, TEETH + 1))
    assert sum(s["end_deg"] - s["start_deg"] for s in sectors) == pytest.approx(360.0)
    tooth1 = [s for s in sectors if s["tooth"] == 1]
    assert len(tooth1) == 1 and tooth1[0]["start_deg"] == pytest.approx(0.0)  # 9° ± 9°
    band = body["baseline_band"]
    assert band["records"] == 10  # the mci_depth rule's baseline size
    # every baseline curve is identical: the band collapses onto the curve
    assert band["lower"][0] == pytest.approx(1 / 3, rel=1e-6) == band["upper"][0]
    no_band = api.get(f"/api/v1/records/{record_id}/curves").json()
    assert no_band["baseline_band"] is None and set(no_band["curves"]) == {"pinion_average", "mci"}
    error_of(api.get(f"/api/v1/records/{record_id}/curves?channel=nope"), 404)
    error_of(api.get(f"/api/v1/records/{record_id}/curves?names=bogus"), 422)
    error_of(api.get(f"/api/v1/records/{seeded.rejected_id}/curves"), 404)


# -- uploads and campaigns ------------------------------------------------------------------

MANIFEST = {
    "campaign": {"id": "upload-test", "description": "uploads"},
    "rig": {"id": "rig-u", "pinion_teeth": 20, "gear_teeth": 21, "tooth1_pitch_angle_deg": 0.0},
    "acquisition": {"sample_rate_hz": 20000},
    "tachometer": {"channel": "tach", "kind": "pulses", "shaft": "pinion", "pulses_per_rev": 1},
    "channels": [
        {"name": "acc", "kind": "accelerometer", "unit": "g"},
        {"name": "tach", "kind": "tachometer", "unit": "V"},
    ],
}


def test_create_campaign_then_upload_a_bad_record_is_kept_as_rejected(api: Api) -> None:
    operator = api.headers("operator")
    created = api.client.post("/api/v1/campaigns", json=MANIFEST, headers=operator)
    assert created.status_code == 201, created.text
    assert created.json()["rig_id"] == "rig-u"
    assert api.client.post("/api/v1/campaigns", json=MANIFEST, headers=operator).status_code == 200
    bad_manifest = {**MANIFEST, "rig": {"id": "rig-u", "pinion_teeth": "twenty"}}
    error = error_of(api.client.post("/api/v1/campaigns", json=bad_manifest, headers=operator), 422)
    assert "pinion_teeth" in error["message"]

    url = "/api/v1/campaigns/upload-test/records"
    form = {"entry": '{"taken_at": "2026-03-05T10:00:00+01:00", "label": "day 5"}'}
    files = {"file": ("day05.wav", b"RIFF-not-really-a-wav")}
    first = api.client.post(url, files=files, data=form, headers=operator)
    assert first.status_code == 201, first.text
    job = first.json()
    assert job["outcome"] == "rejected" and job["record"]["status"] == "rejected"
    assert job["record"]["reason"] and job["record"]["taken_at"] == "2026-03-05T09:00:00Z"
    assert job["record"]["file_name"] == "day05.wav" and job["record"]["label"] == "day 5"
    kept = list(api.raw_store.rglob(f"{job['record']['sha256']}*"))
    assert len(kept) == 1 and kept[0].read_bytes() == b"RIFF-not-really-a-wav"
    again = api.client.post(url, files=files, data=form, headers=operator)
    assert again.status_code == 200 and again.json()["outcome"] == "unchanged"
    assert again.json()["record"]["id"] == job["record"]["id"]
    audit = api.get("/api/v1/audit?action=record.upload", "admin").json()["items"]
    assert len(audit) == 2

    error_of(api.client.post(url, files=files, data={"entry": "{"}, headers=operator), 422)
    no_zone = {"entry": '{"taken_at": "2026-03-05T10:00:00"}'}
    error_of(api.client.post(url, files=files, data=no_zone, headers=operator), 422)
    error_of(api.client.post(url, data=form, headers=operator), 422)  # no file
    empty = {"file": ("e.wav", b"")}
    error_of(api.client.post(url, files=empty, data=form, headers=operator), 422)
    unknown = api.client.post(
        "/api/v1/campaigns/nope/records", files=files, data=form, headers=operator
    )
    error_of(unknown, 404)


def test_reprocess_validates_parameters(api: Api, seeded: Seeded) -> None:
    operator = api.headers("operator")
    url = f"/api/v1/records/{seeded.record_ids[0]}/reprocess"
    error_of(api.client.post(url, json={"parameters": {"bogus": 1}}, headers=operator), 422)
    error_of(
        api.client.post(url, json={"parameters": {"samples_per_mesh": 2}}, headers=operator), 422
    )
    # the seeded records have no raw file: a clear 404, not a crash
    missing = api.client.post(url, json={"parameters": {"samples_per_mesh": 32}}, headers=operator)
    assert "raw file" in error_of(missing, 404)["message"]


# -- errors ---------------------------------------------------------------------------------


def test_bad_requests_get_json_error_bodies(api: Api) -> None:
    operator = api.headers("operator")
    error_of(api.client.get("/api/v1/nothing-here", headers=operator), 404)
    error_of(api.client.patch("/api/v1/rigs", headers=operator), 405)
    broken_json = api.client.post(
        "/api/v1/keys",
        content=b"{not json",
        headers={**api.headers("admin"), "Content-Type": "application/json"},
    )
    assert error_of(broken_json, 422)["code"] == "invalid_request"
    error_of(api.client.get("/api/v1/records?limit=0", headers=operator), 422)
    error_of(api.client.get("/api/v1/records?limit=1001", headers=operator), 422)
    error_of(api.client.get("/api/v1/alarms/99999999999", headers=operator), 422)


def test_metrics_in_prometheus_text_format(api: Api, seeded: Seeded) -> None:
    error_of(api.client.get("/metrics"), 401)
    api.get("/api/v1/rigs")
    response = api.get("/metrics")
    assert response.status_code == 200
    assert response.headers["content-type"].startswith("text/plain; version=0.0.4")
    text = response.text
    sample = re.compile(r'^[a-zA-Z_:][a-zA-Z0-9_:]*(\{([a-z_]+="[^"]*",?)*\})? -?[0-9.e+-]+$')
    for line in text.splitlines():
        assert line.startswith("# ") or sample.match(line), line
    assert 'gearwatch_records{status="accepted"} 14' in text
    assert 'gearwatch_records{status="rejected"} 1' in text
    assert re.search(
        r'gearwatch_http_requests_total\{method="GET",route="/api/v1/rigs",status="200"\} [1-9]',
        text,
    )
    assert "gearwatch_open_alarms" in text


def test_openapi_is_complete(api: Api) -> None:
    spec = api.app.openapi()
    assert spec["components"]["securitySchemes"]["HTTPBearer"]["scheme"] == "bearer"
    required = {
        ("get", "/api/v1/rigs/{rig_id}/trends"),
        ("get", "/api/v1/alarms"),
        ("post", "/api/v1/alarms/{alarm_id}/ack"),
        ("get", "/health"),
        ("get", "/metrics"),
        ("post", "/api/v1/campaigns/{campaign_id}/records"),
        ("post", "/api/v1/records/{record_id}/reprocess"),
        ("get", "/api/v1/records/{record_id}/curves"),
        ("put", "/api/v1/rigs/{rig_id}/alarm-rules/{indicator}"),
    }
    present = {(m, p) for p, item in spec["paths"].items() for m in item}
    assert required <= present
    for path, item in spec["paths"].items():
        for method, operation in item.items():
            assert operation.get("summary"), (method, path)
            if path != "/health":
                assert "401" in operation["responses"], (method, path)
    text = str(spec)
    assert "'examples'" in text or "'example'" in text


def test_upload_with_workers_keeps_the_file_and_queues_the_job(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    """GEARWATCH_JOB_RUNNER=broker: 202, the raw file kept in the shared store, one message
    whose arguments, run by the worker's job function, ingest the record."""
    from fastapi.testclient import TestClient

    from gearwatch.usecases import job_queue
    from service.app import create_app
    from service.routers import records

    sent: list[tuple[str, str, dict[str, Any]]] = []

    def fake_enqueue(campaign: str, path: str, **options: Any) -> str:
        sent.append((campaign, path, options))
        return "message-1"

    monkeypatch.setattr(records, "enqueue_record", fake_enqueue)
    operator = api.headers("operator")
    assert api.client.post("/api/v1/campaigns", json=MANIFEST, headers=operator).status_code == 201
    settings = api.app.state.settings.model_copy(update={"job_runner": "broker"})
    with TestClient(create_app(settings)) as client:
        response = client.post(
            "/api/v1/campaigns/upload-test/records",
            files={"file": ("day07.wav", b"queued bytes")},
            data={"entry": '{"taken_at": "2026-03-07T08:00:00Z", "label": "day 7"}'},
            headers=operator,
        )
    assert response.status_code == 202, response.text
    body = response.json()
    assert body["outcome"] == "queued" and body["message_id"] == "message-1"
    assert body["record"] is None
    [(campaign, path, options)] = sent
    assert campaign == "upload-test" and Path(path).read_bytes() == b"queued bytes"
    assert Path(path).name.startswith(body["sha256"]) and Path(path).is_relative_to(api.raw_store)
    assert options["taken_at"] == "2026-03-07T08:00:00+00:00" and options["label"] == "day 7"

    done = job_queue.run_job(campaign, path, **options)
    assert done["status"] == "rejected"  # not a real WAV, but stored with its reason
    records = api.get("/api/v1/records?campaign_id=upload-test").json()["items"]
    assert [(r["sha256"], r["file_name"], r["label"]) for r in records] == [
        (body["sha256"], "day07.wav", "day 7")
    ]


def test_trend_answers_are_cached_until_the_rig_gets_new_results(api: Api, seeded: Seeded) -> None:
    import datetime as dt

    from storage.repositories import CampaignRepository, RecordRepository
    from tests.storage.factories import analysis

    url = "/api/v1/rigs/rig-a/trends?indicator=mci_depth"
    first = api.get(url)
    etag = first.headers["etag"]
    assert api.get(url).content == first.content
    not_modified = api.client.get(url, headers={**api.headers("viewer"), "If-None-Match": etag})
    assert not_modified.status_code == 304
    other = api.get(url + "&tooth=2").headers["etag"]
    assert other != etag

    with api.session() as session:
        records = RecordRepository(session)
        campaign = CampaignRepository(session).get_by_name("camp-a")
        assert campaign is not None
        record = records.add(
            campaign,
            sha256="e" * 64,
            file_name="late.wav",
            raw_location="/nonexistent/late.wav",
            taken_at=seeded.taken_at[-1] + dt.timedelta(days=1),
        )
        late = analysis(sha256="e" * 64, teeth=20, mci_depth=0.5)
        records.mark_accepted(record, late)
        records.add_result(record, late)
        session.commit()
    changed = api.client.get(url, headers={**api.headers("viewer"), "If-None-Match": etag})
    assert changed.status_code == 200 and changed.headers["etag"] != etag
    trend = changed.json()
    assert len(trend["records"]) == len(seeded.record_ids) + 1
    assert trend["values"][-1] == [0.5] * 20


def test_upload_a_real_record_then_reprocess_adds_a_result_version(
    api: Api, simulated_campaign: Path
) -> None:
    """Through the real chain: a simulated day is uploaded and analysed; re-processing with
    other parameters adds a version and keeps the old one; the same parameters change nothing."""
    import tomllib

    manifest = tomllib.loads((simulated_campaign / "campaign.toml").read_text())
    entry = manifest.pop("records")[0]
    operator = api.headers("operator")
    created = api.client.post("/api/v1/campaigns", json=manifest, headers=operator)
    assert created.status_code == 201, created.text
    campaign = created.json()["campaign_id"]
    record_file = simulated_campaign / entry["file"]
    form = {"entry": f'{{"taken_at": "{entry["taken_at"]}", "label": "{entry["label"]}"}}'}
    with open(record_file, "rb") as stream:
        files = {"file": (record_file.name, stream.read())}
    uploaded = api.client.post(
        f"/api/v1/campaigns/{campaign}/records", files=files, data=form, headers=operator
    )
    assert uploaded.status_code == 201, uploaded.text
    job = uploaded.json()
    assert job["outcome"] == "accepted", job["record"]["reason"]
    record_id = job["record"]["id"]
    detail = api.get(f"/api/v1/records/{record_id}").json()
    assert detail["revolutions"] >= 20 and len(detail["current_result"]["channels"][0]["teeth"]) > 0
    assert detail["tooth_frame"] == {"kind": "tachometer"}  # with a tach nothing changes (issue 11)
    # the data-quality score travels with the record, its result and each channel
    assert 0.0 < detail["quality_score"] <= 1.0
    assert detail["quality"]["score"] == detail["quality_score"]
    assert detail["current_result"]["quality_score"] == detail["quality_score"]
    assert detail["current_result"]["channels"][0]["quality"]["score"] == detail["quality_score"]
    assert detail["current_result"]["quality"]["rejected_revolutions"] == 0
    first_result = detail["current_result"]["id"]

    url = f"/api/v1/records/{record_id}/reprocess"
    body = {"parameters": {"samples_per_mesh": 32}}
    again = api.client.post(url, json=body, headers=operator)
    assert again.status_code == 200, again.text
    assert again.json()["outcome"] == "reprocessed" and again.json()["result_id"] != first_result
    results = api.get(f"/api/v1/records/{record_id}/results").json()["items"]
    assert [r["is_current"] for r in results] == [False, True]
    assert results[1]["parameters"]["samples_per_mesh"] == 32
    assert results[1]["samples_per_rev"] * 2 == results[0]["samples_per_rev"]
    curves = api.get(f"/api/v1/records/{record_id}/curves?names=mci").json()
    assert curves["result_id"] == results[1]["id"]
    assert len(curves["curves"]["mci"]) == results[1]["samples_per_rev"]
    old = api.get(f"/api/v1/records/{record_id}/curves?names=mci&result_id={first_result}").json()
    assert len(old["curves"]["mci"]) == results[0]["samples_per_rev"]
    same = api.client.post(url, json=body, headers=operator)
    assert same.json()["outcome"] == "unchanged"
    assert len(api.get(f"/api/v1/records/{record_id}/results").json()["items"]) == 2


def test_text_the_database_cannot_store_is_a_4xx(api: Api) -> None:
    """PostgreSQL refuses NUL in text: a manifest carrying one is refused, never a 500."""
    manifest = {**MANIFEST, "campaign": {"id": "nul\u0000campaign", "description": "x"}}
    response = api.client.post("/api/v1/campaigns", json=manifest, headers=api.headers("operator"))
    assert 400 <= response.status_code < 500, response.text
    error_of(response, response.status_code)


def test_only_data_free_pages_are_served_without_a_key(api: Api) -> None:
    """Besides /health: the dashboard shell, its static files and the API description."""
    from fastapi.testclient import TestClient

    from service.app import create_app

    page = api.client.get("/")
    assert page.status_code == 200 and "uPlot.iife.min.js" in page.text
    assert api.client.get("/static/vendor/uPlot.iife.min.js").status_code == 200
    assert api.client.get("/static/vendor/uPlot.LICENSE").status_code == 200
    assert api.client.get("/openapi.json").status_code == 200
    settings = api.app.state.settings.model_copy(update={"api_docs": False})
    with TestClient(create_app(settings)) as locked:
        for path in ("/openapi.json", "/docs", "/redoc"):
            assert locked.get(path).status_code == 404
