"""Alarm notifications: a replay delivers the spalled tooth's alarm to a real local listener
(before the replay process exits); a failing listener is retried with back-off, every attempt
logged and visible over REST; acknowledgements notify too."""

from __future__ import annotations

import datetime as dt
import itertools
import socket
import time
from typing import Any

import pytest

from storage.outbox_delivery import backoff_s
from tests.service.conftest import SPALL_TOOTH, Api, Replayed
from tests.service.seed import Seeded, seed_campaign
from tests.service.webhook_listener import WebhookListener

SETTLE_S = 120.0
"""A bound on waiting for deliveries (retries included), not a speed requirement."""


def settled_notifications(api: Api, rig_id: str = "rig-a") -> list[dict[str, Any]]:
    """The rig's notifications once none is ``pending`` (delivered or failed, attempts logged).

    A receiver has the message before the delivering thread has written the answer to the
    outbox, so a test reads the outbox only after it has settled."""
    end = time.monotonic() + SETTLE_S
    while True:
        items: list[dict[str, Any]] = api.get(
            f"/api/v1/notifications?rig_id={rig_id}", role="operator").json()["items"]
        if items and all(n["status"] != "pending" for n in items):
            return items
        assert time.monotonic() < end, items
        time.sleep(0.05)


def test_a_replay_delivers_the_spalled_tooths_alarm_to_the_global_webhook(
    replayed_campaign: Replayed,
) -> None:
    received = replayed_campaign.received
    spall = [m for m in received if m["indicator"] == "mci_depth" and m["tooth"] == SPALL_TOOTH]
    assert spall, received
    first = spall[0]
    assert first["state"] in ("warning", "alarm")
    for key in ("rig_id", "campaign_id", "channel", "indicator", "tooth", "state", "raised_at",
                "record_id", "dashboard_url"):
        assert key in first and first[key] is not None, (key, first)
    assert first["dashboard_url"].startswith("http://dashboard.test/#rig=")
    assert first["dashboard_url"].endswith(f"&alarm={first['alarm_id']}")
    assert first["unit"] == "Np"
    # whole-record alarms, if any, carry a null tooth, never 0
    assert all(m["tooth"] != 0 for m in received)


def test_the_replayed_outbox_shows_every_delivery_with_its_attempts(
    replayed_campaign: Replayed,
) -> None:
    from storage.db import open_database, session_scope
    from storage.outbox import NotificationRepository

    engine, factory = open_database(replayed_campaign.db_url, auto_migrate=False)
    try:
        with session_scope(factory) as session:
            repo = NotificationRepository(session)
            rows = repo.list(limit=None)
            assert len(rows) == len(replayed_campaign.received)
            assert {r.status for r in rows} == {"delivered"}
            for row in rows:
                attempts = repo.attempts(row.id)
                assert len(attempts) == row.attempts == 1
                assert attempts[0].status_code == 204
    finally:
        engine.dispose()


def test_a_failing_webhook_is_retried_with_back_off_and_every_attempt_is_logged(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    with WebhookListener(fail_first=2) as listener:
        monkeypatch.setenv("GEARWATCH_ALARM_WEBHOOK_URL", listener.url)
        with api.session() as session:
            seeded: Seeded = seed_campaign(session)
            session.commit()  # the commit starts the delivery in this process
        assert listener.wait_for(
            lambda got: any(m["tooth"] == seeded.spall_tooth for m in got)
        ), "the alarm never arrived"
        # the listener has the body before the deliverer has logged the answer: wait for the log
        items = settled_notifications(api)
    assert listener.requests == len(listener.received) + 2
    assert api.get("/api/v1/notifications").status_code == 403  # URLs may hold tokens
    retried = [n for n in items if n["attempts"] > 1]
    assert len(retried) == 1  # the two failures hit the first notification sent
    log = retried[0]["attempt_log"]
    assert [a["status_code"] for a in log] == [500, 500, 204]
    assert log[0]["error"].startswith("HTTP 500")
    times = [dt.datetime.fromisoformat(a["at"]) for a in log]
    gaps = [(later - earlier).total_seconds() for earlier, later in itertools.pairwise(times)]
    # back-off: 1 s after the first failure, 2 s after the second (at least)
    assert gaps[0] >= 0.9 * backoff_s(1) and gaps[1] >= 0.9 * backoff_s(2), gaps
    assert retried[0]["status"] == "delivered"


def test_an_acknowledgement_is_a_state_change_that_notifies(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    with api.session() as session:
        seeded = seed_campaign(session)
        session.commit()
    with WebhookListener() as listener:
        created = api.client.post(
            "/api/v1/rigs/rig-a/webhooks", json={"url": listener.url},
            headers=api.headers("operator"),
        )
        assert created.status_code == 201
        alarm = next(
            a for a in api.get("/api/v1/alarms?rig_id=rig-a&open=true").json()["items"]
            if a["tooth"] == seeded.spall_tooth
        )
        ack = api.client.post(
            f"/api/v1/alarms/{alarm['id']}/ack", json={"comment": "borescope: spall"},
            headers=api.headers("operator"),
        )
        assert ack.status_code == 200
        assert listener.wait_for(lambda got: any(m["state"] == "acknowledged" for m in got))
    message = next(m for m in listener.received if m["state"] == "acknowledged")
    assert message["comment"] == "borescope: spall" and message["who"].startswith("operator")
    assert message["tooth"] == seeded.spall_tooth and message["rig_id"] == "rig-a"


def test_alarm_changes_are_e_mailed_through_a_real_smtp_server(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    aiosmtpd = pytest.importorskip("aiosmtpd.controller")
    from aiosmtpd.handlers import Message

    received: list[Any] = []

    class Keep(Message):  # type: ignore[misc]
        def handle_message(self, message: Any) -> None:
            received.append(message)

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    controller = aiosmtpd.Controller(Keep(), hostname="127.0.0.1", port=port)
    controller.start()
    try:
        monkeypatch.setenv("GEARWATCH_SMTP_URL", f"smtp://127.0.0.1:{port}")
        monkeypatch.setenv("GEARWATCH_SMTP_FROM", "gearwatch@rig-hall.test")
        monkeypatch.setenv("GEARWATCH_ALARM_EMAIL_TO", "shift@rig-hall.test")
        with api.session() as session:
            seeded = seed_campaign(session)
            session.commit()
        end = time.monotonic() + 60
        while not received and time.monotonic() < end:
            time.sleep(0.05)
        items = settled_notifications(api)
    finally:
        controller.stop()
    assert received, "no e-mail arrived"
    mail = received[0]
    assert mail["To"] == "shift@rig-hall.test" and mail["From"] == "gearwatch@rig-hall.test"
    assert mail["Subject"] == f"[gearwatch] rig-a tooth {seeded.spall_tooth} mci_depth: alarm"
    assert "Dashboard: http" in mail.get_payload()
    assert [n["url"] for n in items] == ["mailto:shift@rig-hall.test"]
    assert items[0]["status"] == "delivered" and items[0]["attempt_log"][0]["status_code"] == 250


def test_the_api_status_values_are_the_tables() -> None:
    """The REST model's statuses and the table's CHECK constraint name the same three."""
    from typing import get_args

    from service.routers.notifications import NotificationStatus
    from storage.models import NOTIFICATION_STATUSES

    assert get_args(NotificationStatus) == NOTIFICATION_STATUSES
