"""Issue 12 item 6: faults of the services gearwatch depends on surface as one clear line (CLI)
or a 503 with Retry-After (REST), lose nothing, leave nothing half-done, and a re-run resumes.

PostgreSQL going away is a TCP proxy this test owns, in front of the shared server (the
shared server itself is never stopped); RabbitMQ being down is a closed port."""

from __future__ import annotations

import os
import selectors
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import sqlalchemy as sa

from tests.gearwatch.jobfixtures import make_campaign
from tests.storage import dbfixtures


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])  # nobody listens once it is closed


def _gearwatch(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "gearwatch", *args], capture_output=True,
                          text=True, timeout=900, env=env)


@pytest.mark.parametrize("scheme", ["postgres", "postgresql", "postgresql+psycopg"])
def test_an_unreachable_database_is_one_line_and_exit_75(tmp_path: Path, scheme: str) -> None:
    make_campaign(tmp_path / "camp", [1.0])
    done = _gearwatch("replay", str(tmp_path / "camp"), "--no-progress",
                      "--db", f"{scheme}://nobody@127.0.0.1:{_closed_port()}/nowhere")
    assert done.returncode == 75, done.stderr
    assert done.stderr.startswith("gearwatch: error: database unavailable (")
    assert "run the command again to resume" in done.stderr
    assert len(done.stderr.splitlines()) == 1, done.stderr
    assert "NoSuchModuleError" not in done.stderr


def test_an_unsupported_database_url_is_named(tmp_path: Path) -> None:
    make_campaign(tmp_path / "camp", [1.0])
    done = _gearwatch("replay", str(tmp_path / "camp"), "--no-progress",
                      "--db", "mysql://user:secret@host/db")
    assert done.returncode == 2
    assert done.stderr.startswith("gearwatch: error: unsupported database 'mysql'")
    assert "secret" not in done.stderr and len(done.stderr.splitlines()) == 1


class Proxy:
    """A TCP proxy on a loopback port to ``target``; :meth:`cut` drops every connection and
    stops listening (the database "goes away"); :meth:`start` listens again."""

    def __init__(self, target: tuple[str, int]) -> None:
        self.target = target
        self.port = _closed_port()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self._stop.clear()
        listener = socket.create_server(("127.0.0.1", self.port), reuse_port=False)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self._thread = threading.Thread(target=self._run, args=(listener,), daemon=True)
        self._thread.start()

    def cut(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(10)

    def _run(self, listener: socket.socket) -> None:
        selector = selectors.DefaultSelector()
        listener.setblocking(False)
        selector.register(listener, selectors.EVENT_READ, None)
        sockets: list[socket.socket] = [listener]
        while not self._stop.is_set():
            for key, _ in selector.select(timeout=0.05):
                if key.data is None:
                    client, _ = listener.accept()
                    upstream = socket.create_connection(self.target)
                    for one, other in ((client, upstream), (upstream, client)):
                        one.setblocking(False)
                        selector.register(one, selectors.EVENT_READ, other)
                        sockets.append(one)
                    continue
                source: socket.socket = key.fileobj  # type: ignore[assignment]
                try:
                    data = source.recv(65536)
                except OSError:
                    data = b""
                if data:
                    key.data.setblocking(True)
                    key.data.sendall(data)
                    key.data.setblocking(False)
                else:
                    for one in (source, key.data):
                        if one in sockets:
                            selector.unregister(one)
                            sockets.remove(one)
                            one.close()
        for one in sockets:
            one.close()
        selector.close()


@pytest.fixture
def postgres_schema_url() -> Iterator[str]:
    schema = dbfixtures._PostgresSchema()
    try:
        yield schema.url()
    finally:
        schema.drop()


@pytest.mark.slow
def test_postgresql_going_away_during_replay_then_a_rerun_resumes(
    tmp_path: Path, postgres_schema_url: str
) -> None:
    n_records = 8
    campaign = make_campaign(tmp_path / "camp", [1.0 + 0.01 * i for i in range(n_records)],
                             n_samples=40_000)
    direct = sa.engine.make_url(postgres_schema_url)
    proxy = Proxy((direct.host or "127.0.0.1", direct.port or 5432))
    proxy.start()
    through_proxy = direct.set(host="127.0.0.1", port=proxy.port).render_as_string(
        hide_password=False)
    engine = sa.create_engine(postgres_schema_url)

    def stored() -> int:
        try:
            with engine.connect() as connection:
                return int(connection.execute(sa.text("SELECT count(*) FROM records")).scalar()
                           or 0)
        except sa.exc.ProgrammingError:  # the schema is not migrated yet
            return 0

    env = {**os.environ, "GEARWATCH_RAW_STORE": str(tmp_path / "raw")}
    command = [sys.executable, "-m", "gearwatch", "replay", str(tmp_path / "camp"),
               "--no-progress", "--db", through_proxy]
    replay = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              env=env)
    deadline = time.monotonic() + 900  # bounds on a hang on a loaded box, not speed limits
    while stored() < 2:
        assert replay.poll() is None, replay.communicate()
        assert time.monotonic() < deadline
        time.sleep(0.05)
    # Hold the replay while the database goes away, so that it is cut mid-campaign however
    # fast the remaining records would have gone.
    replay.send_signal(signal.SIGSTOP)
    proxy.cut()
    replay.send_signal(signal.SIGCONT)
    _, err = replay.communicate(timeout=900)
    cut_at = stored()
    assert replay.returncode == 75, err
    assert err.startswith("gearwatch: error: database unavailable ("), err
    assert len(err.splitlines()) == 1, err
    assert cut_at < n_records

    proxy.start()
    again = subprocess.run(command, capture_output=True, text=True, env=env, timeout=900)
    proxy.cut()
    assert again.returncode == 0, again.stderr
    with engine.connect() as connection:
        rows = connection.execute(sa.text(
            "SELECT file_name, count(*) FROM records GROUP BY file_name")).all()
        results = connection.execute(sa.text("SELECT count(*) FROM result_versions")).scalar()
    engine.dispose()
    assert sorted(rows) == [(f"day{d:02d}.wav", 1) for d in range(n_records)]
    assert results == n_records
    assert len(campaign.records) == n_records


def test_an_upload_while_the_broker_is_down_is_503_and_keeps_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import pika
    from fastapi.testclient import TestClient

    import gearwatch.worker
    from gearwatch.floor.settings import Settings
    from gearwatch.usecases.keys import issue_api_key
    from service.app import create_app
    from storage.db import open_database, session_scope
    from tests.service.test_api import MANIFEST

    url = f"sqlite:///{tmp_path / 'db.sqlite'}"
    _, factory = open_database(url)
    with session_scope(factory) as session:
        key = issue_api_key(session, name="op", role="operator")[1]
    # The real broker object, pointed at a port nobody listens on.
    broker = gearwatch.worker.broker
    monkeypatch.setattr(broker, "parameters",
                        pika.URLParameters(f"amqp://guest:guest@127.0.0.1:{_closed_port()}/"))
    raw_store = tmp_path / "raw"
    settings = Settings(database_url=url, raw_store=raw_store, job_runner="broker",
                        upload_dir=tmp_path / "uploads")
    headers = {"Authorization": f"Bearer {key}"}
    with TestClient(create_app(settings), raise_server_exceptions=False) as client:
        assert client.post("/api/v1/campaigns", json=MANIFEST, headers=headers).status_code == 201
        answer = client.post(
            "/api/v1/campaigns/upload-test/records",
            files={"file": ("day07.wav", b"bytes that will not be queued")},
            data={"entry": '{"taken_at": "2026-03-07T08:00:00Z"}'},
            headers=headers,
        )
        records = client.get("/api/v1/records", headers=headers).json()["total"]
    assert answer.status_code == 503, answer.text
    assert answer.headers["retry-after"].isdigit()
    assert answer.json()["error"]["code"] == "broker_unavailable"
    assert [p for p in raw_store.rglob("*") if p.is_file()] == []
    assert records == 0


@pytest.mark.broker
@pytest.mark.slow
def test_rabbitmq_going_away_during_worker_ingestion_loses_and_duplicates_nothing(
    tmp_path: Path, postgres_schema_url: str
) -> None:
    """A worker's connection to RabbitMQ is cut mid-ingestion (a proxy this test owns stops,
    then comes back): every record ends up stored exactly once and the queue empties."""
    import secrets
    import signal as signals

    import dramatiq
    import pika
    from dramatiq.brokers.rabbitmq import RabbitmqBroker

    from storage.db import open_database, session_scope
    from storage.repositories import CampaignRepository
    from tests.gearwatch.test_jobs import _require_broker, _start_worker, _stop, broker_url

    _require_broker()
    n_records = 12
    campaign = make_campaign(tmp_path / "camp", [1.0 + 0.01 * i for i in range(n_records)],
                             n_samples=40_000)
    engine, factory = open_database(postgres_schema_url)
    with session_scope(factory) as session:
        CampaignRepository(session).ensure(campaign)
    direct = pika.URLParameters(broker_url())
    proxy = Proxy((direct.host, direct.port))
    proxy.start()
    queue = f"gw_test_{secrets.token_hex(6)}"
    env = {**os.environ, "GEARWATCH_QUEUE": queue,
           "GEARWATCH_BROKER_URL": f"amqp://guest:guest@127.0.0.1:{proxy.port}/",
           "GEARWATCH_DATABASE_URL": postgres_schema_url,
           "GEARWATCH_RAW_STORE": str(tmp_path / "raw"), "dramatiq_restart_delay": "0"}
    broker = RabbitmqBroker(url=broker_url())
    broker.declare_queue(queue)
    for entry in campaign.records:
        broker.enqueue(dramatiq.Message(
            queue_name=queue, actor_name="process_record",
            args=(campaign.id, str(campaign.record_path(entry))),
            kwargs={"taken_at": entry.taken_at}, options={}))
    worker = _start_worker(env, tmp_path / "worker.log")

    def results() -> int:
        with engine.connect() as connection:
            return int(connection.execute(sa.text(
                "SELECT count(*) FROM result_versions")).scalar() or 0)

    try:
        deadline = time.monotonic() + 900  # a bound on a hang on a loaded box
        while results() < 3:
            assert time.monotonic() < deadline, (tmp_path / "worker.log").read_text()[-3000:]
            time.sleep(0.05)
        # Hold the worker while the broker goes away, so that it is cut mid-ingestion however
        # fast the remaining records would have gone; then let it run into the outage.
        os.killpg(worker.pid, signals.SIGSTOP)
        cut_at = results()
        proxy.cut()
        os.killpg(worker.pid, signals.SIGCONT)
        time.sleep(3.0)  # the length of the outage, not a synchronisation
        proxy.start()
        while results() < n_records:
            assert time.monotonic() < deadline, (tmp_path / "worker.log").read_text()[-3000:]
            time.sleep(0.2)
        time.sleep(2.0)  # a redelivered message, if any, is processed now
    finally:
        _stop(worker, signals.SIGTERM)
        proxy.cut()
        connection = pika.BlockingConnection(pika.URLParameters(broker_url()))
        channel = connection.channel()
        left = channel.queue_declare(queue, passive=True).method.message_count
        for name in (queue, f"{queue}.DQ", f"{queue}.XQ"):
            channel.queue_delete(name)
        connection.close()
        broker.close()
    assert cut_at < n_records and left == 0
    with engine.connect() as connection:
        rows = connection.execute(sa.text(
            "SELECT r.file_name, count(v.id) FROM records r JOIN result_versions v "
            "ON v.record_id = r.id GROUP BY r.file_name")).all()
    engine.dispose()
    assert sorted(rows) == [(f"day{d:02d}.wav", 1) for d in range(n_records)]
