"""Issue 12 item 8: security headers on every answer and no ``server: uvicorn``, checked on
``gearwatch serve`` itself (a real uvicorn process)."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator

import httpx
import pytest


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    folder = tmp_path_factory.mktemp("serve")
    port = _free_port()
    env = {**os.environ, "GEARWATCH_DATABASE_URL": f"sqlite:///{folder / 'db.sqlite'}",
           "GEARWATCH_RAW_STORE": str(folder / "raw")}
    with open(folder / "serve.log", "wb") as log:
        process = subprocess.Popen(
            [sys.executable, "-m", "gearwatch", "serve", "--port", str(port),
             "--log-level", "warning"], env=env, stdout=log, stderr=subprocess.STDOUT,
            start_new_session=True,
        )
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 300  # a bound on a hang on a loaded box, not a speed limit
        while True:
            try:
                if httpx.get(f"{url}/health", timeout=10).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            assert process.poll() is None, (folder / "serve.log").read_text()
            assert time.monotonic() < deadline, (folder / "serve.log").read_text()
            time.sleep(0.1)
        yield url
    finally:
        os.killpg(process.pid, signal.SIGTERM)
        process.wait(timeout=120)


@pytest.mark.parametrize("path", ["/health", "/", "/static/dashboard.js", "/api/v1/records",
                                  "/openapi.json", "/nope"])
def test_every_answer_has_the_security_headers_and_no_server_header(served: str,
                                                                     path: str) -> None:
    answer = httpx.get(served + path, timeout=120)
    headers = answer.headers
    assert "server" not in headers
    assert headers["x-content-type-options"] == "nosniff"
    assert headers["x-frame-options"] == "DENY"
    assert headers["referrer-policy"] == "no-referrer"
    policy = headers["content-security-policy"]
    assert "default-src 'self'" in policy and "frame-ancestors 'none'" in policy
    assert "unsafe-inline" not in policy


def test_the_api_description_page_gets_the_policy_it_needs(served: str) -> None:
    answer = httpx.get(served + "/docs", timeout=120)
    assert answer.status_code == 200 and "server" not in answer.headers
    assert "https://cdn.jsdelivr.net" in answer.headers["content-security-policy"]
    assert "cdn.jsdelivr.net" in answer.text  # what the policy allows is what the page loads
