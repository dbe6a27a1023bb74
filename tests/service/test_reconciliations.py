"""Physics reconciliation of a stored record over REST: request checks (4xx), the job in the
service (inline runner) and on a real Dramatiq worker over RabbitMQ, results, report, model."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Any

import pytest

from tests.gearwatch import reconcilefixtures as fx
from tests.service.conftest import Api

RECORDS = "/api/v1/records"


def error_of(response: Any, status: int) -> dict[str, Any]:
    assert response.status_code == status, response.text
    body = response.json()
    assert set(body) == {"error"} and body["error"]["message"]
    return dict(body["error"])


@pytest.fixture(scope="module")
def manifest(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return fx.write_campaign(tmp_path_factory.mktemp("reconcile-rest"))


@dataclasses.dataclass
class Stored:
    record: int
    garbage: int
    sha256: str
    other_rig: int
    no_teeth: int
    gear_tach: int
    no_tach: int


@pytest.fixture
def stored(api: Api, manifest: Path) -> Stored:
    """The eccentric record and a garbage one (same rig, kept raw files), and records of rigs
    and campaigns a reconciliation cannot use (their raw files are never reached)."""
    from gearwatch.floor.campaign import TachometerConfig
    from storage.raw_store import RawStore
    from storage.repositories import CampaignRepository, RecordRepository
    from tests.storage.factories import T0, campaign_config

    with api.session() as session:
        ids = fx.ingest(session, manifest, RawStore(api.raw_store))
        records = RecordRepository(session)
        sha256 = records.get(ids[fx.RECORD]).sha256
        others = {}
        configs = {
            "other_rig": campaign_config("camp-other", "rig-other", accelerometers=("acc1",)),
            "no_teeth": campaign_config("camp-nt", "rig-nt", pinion_teeth=None, gear_teeth=None),
            "gear_tach": dataclasses.replace(
                campaign_config("camp-gt", "rig-gt"), tachometer=TachometerConfig("tach", shaft="gear")),
            "no_tach": dataclasses.replace(campaign_config("camp-no", "rig-no"), tachometer=None),
        }
        for index, (name, config) in enumerate(configs.items()):
            campaign = CampaignRepository(session).ensure(config)
            others[name] = records.add(
                campaign, sha256=f"{index + 1:x}" * 64, file_name=f"{name}.wav",
                raw_location=f"/nonexistent/{name}.wav", taken_at=T0,
            ).id
        session.commit()
    return Stored(ids[fx.RECORD], ids[fx.GARBAGE], sha256, **others)


def post(api: Api, record_id: int, body: dict[str, Any], role: str = "operator") -> Any:
    return api.client.post(
        f"{RECORDS}/{record_id}/reconciliations", json=body, headers=api.headers(role)
    )


# One real reconciliation per backend in the suite: SQLite in tests/gearwatch/test_reconcile_job.py.
@pytest.mark.parametrize("db_url", ["postgresql"], indirect=True)
def test_reconciliation_runs_after_the_response_and_is_served(api: Api, stored: Stored) -> None:
    """Inline runner: 202 queued, then (the job runs once the response is sent) done, with the
    eccentricity found, its provenance, the HTML report and the updated model."""
    from physics.config import model_from_toml, model_to_toml

    model_toml = model_to_toml(fx.base_model())
    response = post(api, stored.record, {**fx.FAST_OPTIONS, "model_toml": model_toml})
    assert response.status_code == 202, response.text
    queued = response.json()
    assert queued["status"] == "queued" and queued["record_id"] == stored.record
    assert queued["progress"] == {"stage": "queued", "fraction": 0.0}
    assert queued["options"] == {**fx.FAST_OPTIONS, "channel": "acc"}
    assert queued["provenance"]["raw_sha256"] == stored.sha256
    url = queued["links"]["self"]
    assert url == f"/api/v1/reconciliations/{queued['id']}"
    assert queued["links"]["report"] == url + "/report" and queued["links"]["model"] == url + "/model"

    done = api.get(url).json()
    assert done["status"] == "done", done
    assert done["error"] is None and done["outcome"] == done["result"]["status"]
    assert done["progress"] == {"stage": "done", "fraction": 1.0}
    assert done["provenance"]["raw_sha256"] == stored.sha256
    assert done["provenance"]["code_version"] and done["model_toml"] == model_toml
    assert done["started_at"] <= done["finished_at"]
    [finding] = done["result"]["findings"]
    assert finding["mechanism"] == "pinion_eccentricity"
    assert finding["parameters"]["amplitude_um"] == pytest.approx(fx.ECCENTRICITY_UM, rel=0.2)
    assert {"baseline", "mismatches", "unresolved", "final"} <= set(done["result"])

    report = api.get(url + "/report")
    assert report.status_code == 200 and report.headers["content-type"].startswith("text/html")
    assert report.text.startswith("<!doctype html>")
    model = api.get(url + "/model")
    assert model.status_code == 200 and model.headers["content-type"].startswith("application/toml")
    updated = model_from_toml(model.text)
    assert updated.deviations.pinion_eccentricity_um == pytest.approx(fx.ECCENTRICITY_UM, rel=0.2)

    listed = api.get(f"{RECORDS}/{stored.record}/reconciliations").json()["items"]
    assert [(r["id"], r["status"]) for r in listed] == [(queued["id"], "done")]
    assert "result" not in listed[0]
    audit = api.get("/api/v1/audit?action=reconciliation.create", "admin").json()["items"]
    assert [a["target"] for a in audit] == [f"record:{stored.record}"]


def test_a_failed_reconciliation_shows_its_reason(api: Api, stored: Stored) -> None:
    # A garbage reference (same rig): the job cannot read it and says so.
    response = post(api, stored.record, {**fx.FAST_OPTIONS, "reference_record_id": stored.garbage})
    assert response.status_code == 202, response.text
    url = response.json()["links"]["self"]
    failed = api.get(url).json()
    assert failed["status"] == "failed" and failed["result"] is None
    assert fx.GARBAGE in failed["error"] and failed["reference_record_id"] == stored.garbage
    assert failed["provenance"]["reference_raw_sha256"]
    assert fx.GARBAGE in error_of(api.get(url + "/report"), 409)["message"]
    assert error_of(api.get(url + "/model"), 409)["code"] == "conflict"


def test_report_and_model_are_409_until_done_and_lists_are_newest_first(
    api: Api, stored: Stored
) -> None:
    from gearwatch.usecases.reconcile import ReconcileRequest, create_reconciliation
    from storage.raw_store import RawStore

    with api.session() as session:
        first = create_reconciliation(session, stored.record, ReconcileRequest(),
                                      raw_store=RawStore(api.raw_store)).id
        second = create_reconciliation(session, stored.record, ReconcileRequest(max_findings=1),
                                       raw_store=RawStore(api.raw_store)).id
        session.commit()
    listed = api.get(f"{RECORDS}/{stored.record}/reconciliations").json()["items"]
    assert [r["id"] for r in listed] == [second, first]
    assert {r["status"] for r in listed} == {"queued"}
    assert listed[1]["options"]["mechanisms"] is None and listed[0]["options"]["max_findings"] == 1
    for suffix in ("/report", "/model"):
        error = error_of(api.get(f"/api/v1/reconciliations/{first}{suffix}"), 409)
        assert error["code"] == "conflict" and "queued" in error["message"]
    detail = api.get(f"/api/v1/reconciliations/{first}").json()
    assert detail["status"] == "queued" and detail["result"] is None and detail["model_toml"] is None
    assert api.get(f"{RECORDS}/{stored.garbage}/reconciliations").json()["items"] == []


def test_requests_are_checked_up_front(api: Api, stored: Stored) -> None:
    from physics.config import GearPairModel, model_to_toml
    from physics.reconcile import CATALOGUE, MECHANISM_NAMES

    default = GearPairModel()
    other_teeth = default.replace(
        geometry=dataclasses.replace(default.geometry, pinion_teeth=23, gear_teeth=31))
    cases: list[tuple[int, dict[str, Any], int, str]] = [
        (999_999, {}, 404, "record 999999 not found"),
        (stored.record, {"reference_record_id": 999_999}, 404, "reference record 999999"),
        (stored.record, {"reference_record_id": stored.record}, 422, "another record"),
        (stored.record, {"reference_record_id": stored.other_rig}, 422, "another rig"),
        (stored.record, {"model_toml": "[geometry\npinion_teeth = "}, 422, "not valid TOML"),
        (stored.record, {"model_toml": "[geometry]\nmodule_mm = -2.0\n"}, 422, "model_toml"),
        (stored.record, {"model_toml": model_to_toml(other_teeth)}, 422,
         "tooth counts 23/31 differ from the rig's 20/21"),
        (stored.record, {"mechanisms": ["warp_drive", "pinion_eccentricity"]}, 422,
         "warp_drive"),
        (stored.record, {"mechanisms": []}, 422, "at least one"),
        (stored.record, {"channel": "tach"}, 422, "not an accelerometer channel"),
        (stored.record, {"samples_per_mesh": 4}, 422, "samples_per_mesh"),
        (stored.record, {"max_findings": -1}, 422, "max_findings"),
        (stored.record, {"max_frequency_hz": 0}, 422, "max_frequency_hz"),
        (stored.record, {"unknown": 1}, 422, "unknown"),
        (stored.no_teeth, {}, 422, "no tooth counts"),
        (stored.gear_tach, {}, 422, "on the gear shaft"),
        (stored.no_tach, {}, 422, "no tachometer"),
        (stored.other_rig, {}, 404, "raw file of record"),
    ]
    for record_id, body, status, message in cases:
        error = error_of(post(api, record_id, body), status)
        assert message in error["message"], (body, error)
    # Unknown mechanisms: the valid ones are listed; catalogue names without a fitted plug-in
    # are refused too.
    error = error_of(post(api, stored.record, {"mechanisms": ["warp_drive"]}), 422)
    assert f"(fitted: {', '.join(CATALOGUE)})" in error["message"]
    for name in (m for m in MECHANISM_NAMES if m not in CATALOGUE):
        assert name in error_of(post(api, stored.record, {"mechanisms": [name]}), 422)["message"]
    # Roles and unknown ids.
    error_of(post(api, stored.record, {}, role="viewer"), 403)
    error_of(api.client.post(f"{RECORDS}/{stored.record}/reconciliations", json={}), 401)
    error_of(api.get(f"{RECORDS}/999999/reconciliations"), 404)
    for suffix in ("", "/report", "/model"):
        error_of(api.get(f"/api/v1/reconciliations/999999{suffix}"), 404)
    # Nothing was stored by a refused request.
    assert api.get(f"{RECORDS}/{stored.record}/reconciliations").json()["items"] == []


# -- a real Dramatiq worker over RabbitMQ ----------------------------------------------------


@pytest.mark.broker
@pytest.mark.slow
@pytest.mark.parametrize("db_url", ["postgresql"], indirect=True)
def test_reconciliation_on_a_worker_over_rabbitmq(
    api: Api, stored: Stored, db_url: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """GEARWATCH_JOB_RUNNER=broker: the request queues a ``reconcile_record`` message on
    RabbitMQ, a Dramatiq worker process runs it on PostgreSQL, the API serves the result."""
    import os
    import secrets
    import signal

    import pika
    from fastapi.testclient import TestClient

    from service.app import create_app
    from tests.gearwatch.test_jobs import _require_broker, _start_worker, _stop, broker_url

    _require_broker()
    queue = f"gw_test_{secrets.token_hex(6)}"
    monkeypatch.setenv("GEARWATCH_QUEUE", queue)  # the queue the service sends to
    settings = api.app.state.settings.model_copy(update={"job_runner": "broker"})
    env = {**os.environ, "GEARWATCH_QUEUE": queue, "GEARWATCH_BROKER_URL": broker_url(),
           "NUMBA_NUM_THREADS": "1", "dramatiq_restart_delay": "0"}
    worker = _start_worker(env, tmp_path / "worker.log")
    try:
        with TestClient(create_app(settings)) as client:
            response = client.post(
                f"{RECORDS}/{stored.record}/reconciliations", json=fx.FAST_OPTIONS,
                headers=api.headers("operator"),
            )
            assert response.status_code == 202, response.text
            url = response.json()["links"]["self"]
            deadline = time.monotonic() + 900  # a bound on a hang, not a speed limit
            while (body := client.get(url, headers=api.headers("viewer")).json())["status"] in (
                "queued", "running"
            ):
                assert time.monotonic() < deadline, (tmp_path / "worker.log").read_text()[-3000:]
                assert worker.poll() is None, (tmp_path / "worker.log").read_text()[-3000:]
                time.sleep(0.5)
    finally:
        _stop(worker, signal.SIGTERM)
        connection = pika.BlockingConnection(pika.URLParameters(broker_url()))
        channel = connection.channel()
        left = channel.queue_declare(queue, passive=True).method.message_count
        for name in (queue, f"{queue}.DQ", f"{queue}.XQ"):
            channel.queue_delete(name)
        connection.close()
    assert body["status"] == "done", body
    assert left == 0
    [finding] = body["result"]["findings"]
    assert finding["mechanism"] == "pinion_eccentricity"
    assert finding["parameters"]["amplitude_um"] == pytest.approx(fx.ECCENTRICITY_UM, rel=0.2)
    assert body["provenance"]["raw_sha256"] == stored.sha256
    assert body["model_toml"] and "sample_rate_hz = 8000.0" in body["model_toml"]


# -- issue 12 item 8: inline reconciliations are bounded and resumed ---------------------------
@pytest.mark.parametrize("db_url", ["sqlite"], indirect=True)
def test_inline_reconciliations_beyond_the_queue_are_503(
    api: Api, stored: Stored, monkeypatch: pytest.MonkeyPatch
) -> None:
    from service import inline_jobs

    monkeypatch.setattr(inline_jobs, "_waiting", inline_jobs.MAX_WAITING)
    response = post(api, stored.record, {**fx.FAST_OPTIONS, "reference_record_id": stored.garbage})
    error = error_of(response, 503)
    assert error["code"] == "reconciliation_queue_full"
    assert response.headers["retry-after"].isdigit()
    assert api.get(f"{RECORDS}/{stored.record}/reconciliations").json()["items"] == []
    assert inline_jobs._waiting == inline_jobs.MAX_WAITING  # nothing reserved on a refusal


@pytest.mark.parametrize("db_url", ["sqlite"], indirect=True)
def test_an_interrupted_inline_reconciliation_is_picked_up_at_start(
    api: Api, stored: Stored
) -> None:
    """A row left ``running`` by an API process that stopped runs again when the service
    starts (here it fails fast: its reference is garbage)."""
    from fastapi.testclient import TestClient

    from gearwatch.usecases.reconcile import ReconcileRequest, create_reconciliation
    from service.app import create_app
    from storage.raw_store import RawStore

    with api.session() as session:
        row = create_reconciliation(
            session, stored.record,
            ReconcileRequest(reference_record_id=stored.garbage, **fx.FAST_OPTIONS),
            raw_store=RawStore(api.raw_store),
        )
        row.status = "running"
        session.commit()
        row_id = row.id
    with TestClient(create_app(api.app.state.settings)):
        deadline = time.monotonic() + 600  # a bound on a hang, not a speed limit
        while (status := api.get(f"/api/v1/reconciliations/{row_id}").json()["status"]) in (
            "queued", "running"
        ):
            assert time.monotonic() < deadline, status
            time.sleep(0.1)
    assert status == "failed"
