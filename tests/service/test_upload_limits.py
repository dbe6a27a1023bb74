"""Issue 12 item 1: an upload is authenticated and authorised before its body is read, its
size limit is enforced while it streams, and its bytes go only to the upload folder.

Under a real uvicorn server on a loopback port, with raw sockets so the client can stop
sending when the server answers (an HTTP library would insist on sending the whole body)."""

from __future__ import annotations

import json
import select
import socket
import tempfile
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.service.conftest import Api

LIMIT = 1 << 20
BIG = 64 << 20
"""What a hostile client claims (or tries) to send: 64 × the limit."""
BOUNDARY = "gearwatchboundary"


@dataclass
class Live:
    host: str
    port: int
    spool: Path
    system_temp: Path


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture
def live(api: Api, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Live]:
    import uvicorn

    from service.app import create_app

    system_temp = tmp_path / "system-temp"
    system_temp.mkdir()
    # Everything that would spool to "the system temp folder" in this process lands here.
    monkeypatch.setattr(tempfile, "tempdir", str(system_temp))
    spool = tmp_path / "uploads"
    settings = api.app.state.settings.model_copy(
        update={"upload_dir": spool, "max_upload_bytes": LIMIT}
    )
    port = _free_port()
    server = uvicorn.Server(
        uvicorn.Config(create_app(settings), host="127.0.0.1", port=port, log_level="warning")
    )
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 300  # a bound on a hang on a loaded box, not a speed limit
    while not server.started and thread.is_alive() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert server.started, "uvicorn did not start"
    yield Live("127.0.0.1", port, spool, system_temp)
    server.should_exit = True
    thread.join(10)


def _files_under(folder: Path) -> list[Path]:
    return [p for p in folder.rglob("*") if p.is_file()] if folder.exists() else []


def _head(key: str | None, *, content_length: int | None) -> bytes:
    lines = [
        "POST /api/v1/campaigns/upload-test/records HTTP/1.1",
        "Host: 127.0.0.1",
        f"Content-Type: multipart/form-data; boundary={BOUNDARY}",
    ]
    if key is not None:
        lines.append(f"Authorization: Bearer {key}")
    if content_length is None:
        lines.append("Transfer-Encoding: chunked")
    else:
        lines.append(f"Content-Length: {content_length}")
    return ("\r\n".join(lines) + "\r\n\r\n").encode()


def _form_start() -> bytes:
    entry = json.dumps({"taken_at": "2026-03-13T09:00:00Z"})
    return (
        f"--{BOUNDARY}\r\nContent-Disposition: form-data; name=\"entry\"\r\n\r\n{entry}\r\n"
        f"--{BOUNDARY}\r\nContent-Disposition: form-data; name=\"file\"; filename=\"big.wav\"\r\n"
        "Content-Type: application/octet-stream\r\n\r\n"
    ).encode()


def _post(live: Live, key: str | None, *, declare_length: bool) -> tuple[int, int]:
    """Start a BIG upload and keep sending until the server answers; (status, bytes sent)."""
    chunk = b"\0" * (64 << 10)
    sent = 0
    with socket.create_connection((live.host, live.port), timeout=120) as conn:
        conn.sendall(_head(key, content_length=BIG if declare_length else None))
        body = _form_start()
        try:
            while sent < BIG:
                readable, _, _ = select.select([conn], [], [], 0)
                if readable:
                    break
                piece = body + chunk
                body = b""
                if not declare_length:
                    piece = f"{len(piece):x}\r\n".encode() + piece + b"\r\n"
                conn.sendall(piece)
                sent += len(piece)
        except (BrokenPipeError, ConnectionResetError):
            pass  # the server answered and closed: what we want
        conn.settimeout(120)
        answer = b""
        while b"\r\n" not in answer:
            more = conn.recv(4096)
            if not more:
                break
            answer += more
    status = int(answer.split(b" ", 2)[1])
    return status, sent


def _create_campaign(api: Api) -> None:
    from tests.service.test_api import MANIFEST

    created = api.client.post(
        "/api/v1/campaigns", json=MANIFEST, headers=api.headers("operator")
    )
    assert created.status_code in (200, 201), created.text


@pytest.mark.parametrize("declare_length", [True, False], ids=["content-length", "chunked"])
def test_anonymous_and_viewer_uploads_are_refused_before_the_body_is_read(
    api: Api, live: Live, declare_length: bool
) -> None:
    _create_campaign(api)
    status, sent = _post(live, None, declare_length=declare_length)
    assert status == 401
    assert sent < BIG // 4, f"the server read {sent} bytes before refusing an anonymous upload"
    status, sent = _post(live, api.keys["viewer"], declare_length=declare_length)
    assert status == 403
    assert sent < BIG // 4
    assert _files_under(live.spool) == [] and _files_under(live.system_temp) == []


def test_an_over_limit_operator_upload_gets_413_early_and_leaves_nothing(
    api: Api, live: Live
) -> None:
    _create_campaign(api)
    # Content-Length over the limit: refused before a byte of the body is read.
    status, sent = _post(live, api.keys["operator"], declare_length=True)
    assert status == 413
    assert sent < BIG // 4
    # No Content-Length (chunked): refused as soon as the streamed file passes the limit.
    status, sent = _post(live, api.keys["operator"], declare_length=False)
    assert status == 413
    assert sent < BIG // 4, f"{sent} bytes sent before the 413"
    assert _files_under(live.spool) == [] and _files_under(live.system_temp) == []


def test_an_upload_within_the_limit_still_works_and_spools_only_in_the_upload_dir(
    api: Api, live: Live
) -> None:
    import httpx

    _create_campaign(api)
    form = {"entry": json.dumps({"taken_at": "2026-03-13T09:00:00Z", "label": "small"})}
    answer = httpx.post(
        f"http://{live.host}:{live.port}/api/v1/campaigns/upload-test/records",
        files={"file": ("day13.wav", b"RIFF not really a wav")},
        data=form,
        headers=api.headers("operator"),
        timeout=120,
    )
    assert answer.status_code == 201, answer.text
    assert answer.json()["record"]["status"] == "rejected"
    assert _files_under(live.system_temp) == []
    assert live.spool.is_dir() and _files_under(live.spool) == []  # spooled, then removed


def test_sixteen_identical_concurrent_uploads_give_the_same_answers_on_every_backend(
    api: Api, live: Live, tmp_path: Path
) -> None:
    """Issue 12 item 6: one 201 and fifteen 200 `unchanged`, one record, on SQLite and
    PostgreSQL alike (PostgreSQL used to answer 409 to the requests that lost the insert)."""
    from concurrent.futures import ThreadPoolExecutor

    import httpx

    from tests.gearwatch.jobfixtures import SAMPLE_RATE_HZ, write_record
    from tests.service.test_api import MANIFEST

    manifest = {**MANIFEST, "acquisition": {"sample_rate_hz": SAMPLE_RATE_HZ}}
    created = api.client.post("/api/v1/campaigns", json=manifest,
                              headers=api.headers("operator"))
    assert created.status_code == 201, created.text
    content = write_record(tmp_path / "day03.wav", 1.0).read_bytes()
    url = f"http://{live.host}:{live.port}/api/v1/campaigns/upload-test/records"
    form = {"entry": json.dumps({"taken_at": "2026-03-03T09:00:00Z", "label": "day 3"})}

    def upload(_: int) -> tuple[int, str]:
        answer = httpx.post(url, files={"file": ("day03.wav", content)}, data=form,
                            headers=api.headers("operator"), timeout=120)
        return answer.status_code, answer.json().get("outcome", answer.text)

    with ThreadPoolExecutor(16) as pool:
        answers = sorted(pool.map(upload, range(16)))
    assert answers == [(200, "unchanged")] * 15 + [(201, "accepted")], answers
    records = api.get("/api/v1/records?campaign_id=upload-test").json()
    assert records["total"] == 1
