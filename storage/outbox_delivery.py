"""Delivery of the alarm notification outbox (:mod:`storage.outbox`) to webhooks.

Whichever process commits an alarm state change delivers it: a commit that queued
notifications calls :func:`kick`, which starts (once per engine and process) a background
thread that POSTs every due notification as JSON, logs each attempt, and retries a failure
after 1, 2, 4 … s (at most :data:`MAX_BACKOFF_S`) up to :data:`MAX_ATTEMPTS` attempts. The
thread ends when nothing is pending; at interpreter exit a short-lived command (``gearwatch
replay``) waits up to ``GEARWATCH_NOTIFY_DRAIN_SECONDS`` (default 30) for the deliveries that
are still due. Whatever is left stays ``pending`` in the database and is delivered by the next
process that delivers (the service, a worker, the next command that changes an alarm).
"""

from __future__ import annotations

import atexit
import datetime as dt
import json
import logging
import os
import smtplib
import threading
import time
import urllib.error
import urllib.request
from dataclasses import dataclass
from email.message import EmailMessage
from typing import Any
from urllib.parse import unquote, urlsplit

import sqlalchemy as sa

logger = logging.getLogger(__name__)

MAX_ATTEMPTS = 6
"""Attempts before a notification is ``failed`` (1 + 2 + 4 + 8 + 16 s of back-off)."""
FIRST_BACKOFF_S = 1.0
MAX_BACKOFF_S = 300.0
TIMEOUT_S = 10.0
DRAIN_ENV = "GEARWATCH_NOTIFY_DRAIN_SECONDS"
DEFAULT_DRAIN_S = 30.0
USER_AGENT = "gearwatch-alarm-webhook/1"


def backoff_s(attempts: int) -> float:
    """Delay before the next attempt after ``attempts`` failed ones.

    >>> [backoff_s(n) for n in (1, 2, 3, 10)]
    [1.0, 2.0, 4.0, 300.0]
    """
    return float(min(MAX_BACKOFF_S, FIRST_BACKOFF_S * 2 ** (attempts - 1)))


@dataclass(frozen=True)
class PostOutcome:
    delivered: bool
    status_code: int | None
    error: str
    duration_ms: float


SMTP_URL_ENV = "GEARWATCH_SMTP_URL"
"""``smtp://[user:password@]host[:port]`` (``smtp+starttls://`` upgrades the connection,
``smtps://`` is TLS from the start); default ``smtp://127.0.0.1:25``."""
SMTP_FROM_ENV = "GEARWATCH_SMTP_FROM"
DEFAULT_SMTP_FROM = "gearwatch@localhost"


def mail_subject(payload: dict[str, Any]) -> str:
    where = "whole record" if payload.get("tooth") is None else f"tooth {payload['tooth']}"
    return (f"[gearwatch] {payload.get('rig_id')} {where} {payload.get('indicator')}: "
            f"{payload.get('state')}")


def mail_body(payload: dict[str, Any]) -> str:
    lines = [mail_subject(payload).removeprefix("[gearwatch] "), ""]
    for key in ("rig_id", "campaign_id", "channel", "indicator", "tooth", "state", "severity",
                "raised_at", "changed_at", "record_id", "record_label", "value", "unit", "score",
                "who", "comment"):
        value = payload.get(key)
        if value is not None and value != "":
            lines.append(f"{key:>13}: {value}")
    lines += ["", f"Dashboard: {payload.get('dashboard_url')}"]
    return "\n".join(lines) + "\n"


def send_mail(address: str, payload: dict[str, Any], timeout_s: float = TIMEOUT_S) -> PostOutcome:
    """Send one alarm change to ``address`` through the SMTP server of ``GEARWATCH_SMTP_URL``."""
    server = urlsplit(os.environ.get(SMTP_URL_ENV, "").strip() or "smtp://127.0.0.1:25")
    message = EmailMessage()
    message["Subject"] = mail_subject(payload)
    message["From"] = os.environ.get(SMTP_FROM_ENV, "").strip() or DEFAULT_SMTP_FROM
    message["To"] = address
    message.set_content(mail_body(payload))
    start = time.perf_counter()
    try:
        if server.scheme not in ("smtp", "smtps", "smtp+starttls"):
            raise ValueError(f"{SMTP_URL_ENV}: unsupported scheme {server.scheme!r}")
        host = server.hostname or "127.0.0.1"
        tls = server.scheme == "smtps"
        client_class = smtplib.SMTP_SSL if tls else smtplib.SMTP
        with client_class(host, server.port or (465 if tls else 25), timeout=timeout_s) as smtp:
            if server.scheme == "smtp+starttls":
                smtp.starttls()
            if server.username:
                smtp.login(unquote(server.username), unquote(server.password or ""))
            smtp.send_message(message)
        return PostOutcome(True, 250, "", 1000 * (time.perf_counter() - start))
    except (smtplib.SMTPException, OSError, ValueError) as exc:
        code = getattr(exc, "smtp_code", None)
        return PostOutcome(False, code if isinstance(code, int) else None,
                           f"{type(exc).__name__}: {exc}", 1000 * (time.perf_counter() - start))


def deliver(url: str, payload: dict[str, Any]) -> PostOutcome:
    """One delivery attempt: ``mailto:`` by SMTP, anything else by an HTTP POST."""
    if url.startswith("mailto:"):
        return send_mail(url.removeprefix("mailto:"), payload)
    return post_json(url, payload)


def post_json(url: str, payload: dict[str, object], timeout_s: float = TIMEOUT_S) -> PostOutcome:
    """POST ``payload`` as JSON; any 2xx is a delivery, anything else an error to retry."""
    body = json.dumps(payload, allow_nan=False).encode()
    request = urllib.request.Request(
        url,
        data=body,
        method="POST",
        headers={"Content-Type": "application/json", "User-Agent": USER_AGENT},
    )
    start = time.perf_counter()
    try:
        with urllib.request.urlopen(request, timeout=timeout_s) as response:
            status = int(response.status)
        error = "" if 200 <= status < 300 else f"HTTP {status}"
        return PostOutcome(not error, status, error, 1000 * (time.perf_counter() - start))
    except urllib.error.HTTPError as exc:
        return PostOutcome(False, exc.code, f"HTTP {exc.code} {exc.reason}",
                           1000 * (time.perf_counter() - start))
    except (urllib.error.URLError, OSError, ValueError) as exc:
        reason = getattr(exc, "reason", exc)
        return PostOutcome(False, None, f"{type(exc).__name__}: {reason}",
                           1000 * (time.perf_counter() - start))


def deliver_due(engine: sa.Engine, now: dt.datetime | None = None) -> int:
    """One pass: attempt every due notification once; returns how many were attempted."""
    # here, not at the top: db → outbox → this module would be an import cycle
    from storage.db import session_factory, session_scope
    from storage.outbox import NotificationRepository

    factory = session_factory(engine)
    now = now or dt.datetime.now(dt.UTC)
    lease = now + dt.timedelta(seconds=2 * TIMEOUT_S)
    due = []
    with session_scope(factory) as session:
        repo = NotificationRepository(session)
        for n in repo.due(now):
            if repo.claim(n.id, n.next_attempt_at, lease):
                due.append((n.id, n.url, n.payload, n.attempts))
    for notification_id, url, payload, attempts in due:
        outcome = deliver(url, payload)
        at = dt.datetime.now(dt.UTC)
        done = attempts + 1
        retry_at = None
        if not outcome.delivered and done < MAX_ATTEMPTS:
            retry_at = at + dt.timedelta(seconds=backoff_s(done))
        with session_scope(factory) as session:
            repo = NotificationRepository(session)
            repo.record_attempt(
                repo.get(notification_id),
                at=at,
                status_code=outcome.status_code,
                error=outcome.error,
                duration_ms=outcome.duration_ms,
                delivered=outcome.delivered,
                retry_at=retry_at,
            )
        if outcome.delivered:
            logger.info("alarm notification %s delivered to %s", notification_id, url)
        else:
            logger.warning(
                "alarm notification %s to %s: attempt %s failed (%s)%s",
                notification_id, url, done, outcome.error,
                f"; retry in {backoff_s(done):.0f} s" if retry_at else "; giving up",
            )
    return len(due)


def seconds_until_next(engine: sa.Engine) -> float | None:
    """Seconds until the earliest pending notification is due (``None``: nothing pending)."""
    from storage.db import session_factory, session_scope
    from storage.outbox import NotificationRepository

    with session_scope(session_factory(engine)) as session:
        due_at = NotificationRepository(session).next_due_at()
    if due_at is None:
        return None
    return max(0.0, (due_at - dt.datetime.now(dt.UTC)).total_seconds())


def deliver_pending(engine: sa.Engine, *, deadline_s: float | None = None) -> None:
    """Deliver until nothing is pending (or ``deadline_s`` seconds have passed)."""
    end = None if deadline_s is None else time.monotonic() + deadline_s
    while True:
        deliver_due(engine)
        wait = seconds_until_next(engine)
        if wait is None:
            return
        if end is not None:
            left = end - time.monotonic()
            if left <= 0:
                return
            wait = min(wait, left)
        _WAKE.wait(timeout=max(0.05, wait))
        _WAKE.clear()


class _Deliverer:
    """The per-process background delivery thread of one database."""

    def __init__(self, engine: sa.Engine) -> None:
        self.engine = engine
        self.lock = threading.Lock()
        self.thread: threading.Thread | None = None
        self.running = False
        """Set under :attr:`lock` until the thread has decided to end (``is_alive`` stays true
        a little longer: a kick in that window would be lost)."""
        self.again = False

    def kick(self) -> None:
        with self.lock:
            if self.running:
                self.again = True
                _WAKE.set()
                return
            self.running = True
            self.again = False
            self.thread = threading.Thread(
                target=self._run, name="gearwatch-notify", daemon=True
            )
            self.thread.start()

    def _run(self) -> None:
        try:
            while True:
                try:
                    deliver_pending(self.engine)
                except Exception:  # a database hiccup must not kill the process's deliveries
                    logger.exception("alarm notification delivery failed; retrying later")
                    time.sleep(FIRST_BACKOFF_S)
                    continue
                with self.lock:
                    if not self.again:
                        self.running = False
                        return
                    self.again = False
        except BaseException:  # the thread dies: the next kick must start another one
            with self.lock:
                self.running = False
            raise

    def join(self, timeout_s: float) -> None:
        thread = self.thread
        if thread is not None:
            thread.join(timeout_s)


_WAKE = threading.Event()
_DELIVERERS: dict[int, _Deliverer] = {}
_REGISTRY_LOCK = threading.Lock()
_ATEXIT_REGISTERED = False


def kick(engine: sa.Engine) -> None:
    """Start delivering the outbox of ``engine``'s database in the background."""
    global _ATEXIT_REGISTERED
    with _REGISTRY_LOCK:
        deliverer = _DELIVERERS.get(id(engine))
        if deliverer is None or deliverer.engine is not engine:
            deliverer = _DELIVERERS[id(engine)] = _Deliverer(engine)
        if not _ATEXIT_REGISTERED:
            atexit.register(drain)
            _ATEXIT_REGISTERED = True
    deliverer.kick()


def drain(timeout_s: float | None = None) -> None:
    """Wait (bounded) for this process's deliveries; called at interpreter exit."""
    if timeout_s is None:
        try:
            timeout_s = float(os.environ.get(DRAIN_ENV, DEFAULT_DRAIN_S))
        except ValueError:
            timeout_s = DEFAULT_DRAIN_S
    end = time.monotonic() + timeout_s
    for deliverer in list(_DELIVERERS.values()):
        deliverer.join(max(0.0, end - time.monotonic()))
