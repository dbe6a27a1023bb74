"""``gearwatch keys`` and ``gearwatch serve``."""

from __future__ import annotations

import re
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from tests.service.conftest import Api

KEY_PATTERN = re.compile(r"^gw_[0-9a-f]{8}_[A-Za-z0-9_-]{20,}$")


def test_keys_create_prints_the_key_alone_and_it_works(
    api: Api, capsys: pytest.CaptureFixture[str]
) -> None:
    from gearwatch.cli.main import main

    url = api.app.state.settings.database_url
    assert main(["keys", "create", "--role", "operator", "--name", "night shift", "--db", url]) == 0
    out = capsys.readouterr().out
    assert out.endswith("\n") and out.count("\n") == 1
    key = out.strip()
    assert KEY_PATTERN.match(key), key
    me = api.client.get("/api/v1/me", headers={"Authorization": f"Bearer {key}"})
    assert me.json() == {"prefix": key.split("_")[1], "name": "night shift", "role": "operator"}
    audit = api.get("/api/v1/audit?action=key.create", "admin").json()["items"]
    assert audit[0]["who"] == "cli" and audit[0]["details"]["role"] == "operator"

    assert main(["keys", "list", "--db", url]) == 0
    listing = capsys.readouterr().out
    assert "night shift" in listing and key not in listing
    assert main(["keys", "revoke", key.split("_")[1], "--db", url]) == 0
    capsys.readouterr()
    revoked = api.client.get("/api/v1/me", headers={"Authorization": f"Bearer {key}"})
    assert revoked.status_code == 401
    assert main(["keys", "revoke", "ffffffff", "--db", url]) == 2
    assert "no active key" in capsys.readouterr().err


def test_keys_create_in_a_fresh_process_on_a_fresh_database(tmp_path: Path) -> None:
    """The whole stdout of the command is the key (migration logs stay off stdout)."""
    url = f"sqlite:///{tmp_path / 'fresh.db'}"
    done = subprocess.run(
        [sys.executable, "-m", "gearwatch", "keys", "create", "--role", "admin", "--db", url],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert KEY_PATTERN.match(done.stdout.rstrip("\n")) and done.stdout.count("\n") == 1
    bad = subprocess.run(
        [sys.executable, "-m", "gearwatch", "keys", "create", "--role", "root", "--db", url],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert bad.returncode != 0 and "Traceback" not in bad.stderr
    assert "invalid choice" in bad.stderr


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.mark.slow
def test_serve_runs_the_api_on_the_given_port_and_database(tmp_path: Path) -> None:
    port = _free_port()
    database = tmp_path / "served.db"
    command = [sys.executable, "-m", "gearwatch", "serve", "--port", str(port)]
    command += ["--db", f"sqlite:///{database}", "--log-level", "warning"]
    process = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
    )
    try:
        body = None
        deadline = time.monotonic() + 300  # a bound on a hang on a loaded box, not a speed limit
        while body is None:
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{port}/health", timeout=10) as r:
                    body = r.read().decode()
            except OSError:  # refused while starting, or slow to answer (URLError, timeouts)
                assert process.poll() is None, process.communicate()
                assert time.monotonic() < deadline, "gearwatch serve never answered /health"
                time.sleep(0.1)
        assert '"status":"ok"' in body.replace(" ", "")
        with pytest.raises(urllib.error.HTTPError) as refused:
            urllib.request.urlopen(f"http://127.0.0.1:{port}/api/v1/rigs", timeout=120)
        assert refused.value.code == 401
        assert database.is_file()  # --db was used, migrated at start-up
        assert not (tmp_path / "gearwatch.db").exists()
    finally:
        process.terminate()
        process.wait(timeout=120)


def test_serve_refuses_a_bad_port() -> None:
    from gearwatch.cli.main import main

    assert main(["serve", "--port", "70000"]) == 2
