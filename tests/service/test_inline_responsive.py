"""Issue 12 item 8: a reconciliation run by the API process itself (inline runner) leaves the
API answering. A real ``gearwatch serve`` process on a real port: while the reconciliation is
``running``, health checks and authenticated reads keep being answered, then the job ends ``done``.

No speed limit is asserted: each request has a generous timeout (a bound on a hang), and what is
checked is that requests were *answered while the job was running* — an API whose event loop the
job blocked would answer none of them until the job ended."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any

from tests.gearwatch import reconcilefixtures as fx

REQUEST_TIMEOUT_S = 60.0
"""Per request: a bound on a hang on a loaded machine, not a speed limit."""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _gearwatch(*args: str, env: dict[str, str]) -> str:
    done = subprocess.run([sys.executable, "-m", "gearwatch", *args], capture_output=True,
                          text=True, timeout=900, env=env)
    assert done.returncode == 0, done.stderr
    return done.stdout


def _call(url: str, key: str | None = None, body: dict[str, Any] | None = None) -> Any:
    headers = {"Content-Type": "application/json"}
    if key:
        headers["Authorization"] = f"Bearer {key}"
    data = None if body is None else json.dumps(body).encode()
    request = urllib.request.Request(url, data=data, headers=headers,
                                     method="GET" if body is None else "POST")
    with urllib.request.urlopen(request, timeout=REQUEST_TIMEOUT_S) as response:
        return json.loads(response.read().decode())


def test_the_api_answers_while_an_inline_reconciliation_runs(tmp_path: Path) -> None:
    campaign = fx.write_campaign(tmp_path / "campaign").parent
    database = f"sqlite:///{tmp_path / 'served.db'}"
    raw_store = tmp_path / "raw"
    env = {**os.environ, "GEARWATCH_RAW_STORE": str(raw_store), "GEARWATCH_JOB_RUNNER": "inline"}
    _gearwatch("replay", str(campaign), "--db", database, "--raw-store", str(raw_store),
               "--no-progress", env=env)
    created = _gearwatch("keys", "create", "--role", "operator", "--name", "op", "--db", database,
                         env=env)
    key = created.strip()  # printed alone on stdout
    port = _free_port()
    base = f"http://127.0.0.1:{port}"
    server = subprocess.Popen(
        [sys.executable, "-m", "gearwatch", "serve", "--port", str(port), "--db", database,
         "--log-level", "warning"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path, env=env,
    )
    try:
        deadline = time.monotonic() + 600  # a bound on a hang, not a speed limit
        while True:
            try:
                _call(f"{base}/health")
                break
            except OSError:
                assert server.poll() is None, server.communicate()
                assert time.monotonic() < deadline, "gearwatch serve never answered /health"
                time.sleep(0.1)
        records = _call(f"{base}/api/v1/records?limit=10", key)["items"]
        record_id = next(r["id"] for r in records if r["status"] == "accepted")
        # every mechanism of the catalogue at a reduced resolution: seconds of work, not minutes
        options = {k: v for k, v in fx.FAST_OPTIONS.items() if k not in ("mechanisms", "max_findings")}
        queued = _call(f"{base}/api/v1/records/{record_id}/reconciliations", key, options)
        url = f"{base}{queued['links']['self']}"
        answered_while_running = 0
        statuses = []
        while (status := _call(url, key)["status"]) in ("queued", "running"):
            assert time.monotonic() < deadline, status
            statuses.append(status)
            if status == "running":
                assert _call(f"{base}/health")["status"] == "ok"
                assert _call(f"{base}/api/v1/rigs", key)["items"]
                if _call(url, key)["status"] == "running":  # still running after both answers
                    answered_while_running += 1
        assert status == "done", _call(url, key)
        assert answered_while_running >= 3, statuses
    finally:
        server.terminate()
        server.wait(timeout=120)
