"""End to end: a simulated campaign (spall on pinion tooth 16) is replayed into the database,
the service runs under uvicorn, and headless Chromium drives the dashboard: the heat map and the
alarm list show the alarmed tooth, both charts render, an operator acknowledges the alarm.
A screenshot per backend goes to ``test-artifacts/``."""

from __future__ import annotations

import shutil
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.conftest import service_unavailable
from tests.service.conftest import SPALL_TOOTH, Api

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
ARTIFACTS = Path(__file__).resolve().parents[2] / "test-artifacts"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture
def live_server(api: Api) -> Iterator[str]:
    """The service under uvicorn on a free loopback port, on the test's database."""
    import uvicorn

    from service.app import create_app

    port = _free_port()
    app = create_app(api.app.state.settings)
    server = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=port, log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    for _ in range(200):
        if server.started:
            break
        time.sleep(0.05)
    assert server.started, "uvicorn did not start"
    yield f"http://127.0.0.1:{port}"
    server.should_exit = True
    thread.join(10)


@pytest.mark.browser
@pytest.mark.slow
def test_dashboard_shows_the_alarmed_tooth_after_a_replayed_campaign(
    api: Api, simulated_campaign: Path, live_server: str, tmp_path: Path
) -> None:
    if shutil.which("chromium") is None and not Path(CHROMIUM).exists():
        service_unavailable("Chromium", f"{CHROMIUM} not installed (apt-get install chromium)")
    from playwright.sync_api import sync_playwright

    from gearwatch.cli import main

    url = api.app.state.settings.database_url
    replay = ["replay", str(simulated_campaign), "--db", url, "--raw-store", str(tmp_path / "raw")]
    assert main([*replay, "--no-progress"]) == 0

    alarms = api.get(f"/api/v1/alarms?rig_id={_rig(api)}").json()["items"]
    alarmed = {a["tooth"] for a in alarms if a["indicator"] == "mci_depth"}
    assert SPALL_TOOTH in alarmed, alarms  # the pipeline and alarm rules found the spall

    ARTIFACTS.mkdir(exist_ok=True)
    problems: list[str] = []
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 1100})
            page.on("pageerror", lambda error: problems.append(f"page error: {error}"))
            page.on(
                "console",
                lambda m: problems.append(f"console: {m.text}") if m.type == "error" else None,
            )
            page.goto(f"{live_server}/#key={api.keys['operator']}")
            page.wait_for_selector("body[data-ready='true']", timeout=30_000)

            text = page.inner_text("#alarmed-teeth")
            assert f"tooth {SPALL_TOOTH} (alarm)" in text, text
            marked = page.get_attribute("#heatmap", "data-alarmed-teeth") or ""
            assert str(SPALL_TOOTH) in marked.split(","), marked
            row = page.locator(f"#alarms tbody tr[data-tooth='{SPALL_TOOTH}']")
            assert row.count() == 1
            assert "alarm" in row.inner_text()
            # the MCI curve (20 tooth sectors, baseline band) and the tooth trend are drawn
            assert page.locator("#curve .uplot").count() == 1
            assert page.get_attribute("#curve", "data-sectors") == "20"
            assert page.locator("#trend .uplot").count() == 1
            assert page.inner_text("#trend-title").startswith(f"{SPALL_TOOTH} ")
            assert page.get_attribute("#trend", "data-levels") == "true"  # baseline + levels
            page.screenshot(path=str(ARTIFACTS / f"dashboard-{api.backend}.png"), full_page=True)

            # an operator acknowledges it from the list
            page.once("dialog", lambda dialog: dialog.accept("spall confirmed by borescope"))
            row.locator("button.ack").click()
            page.wait_for_selector(
                f"#alarms tbody tr[data-tooth='{SPALL_TOOTH}']", state="detached", timeout=10_000
            )
            page.select_option("#alarm-state", "acknowledged")
            acked = page.locator(f"#alarms tbody tr[data-tooth='{SPALL_TOOTH}']")
            assert "spall confirmed by borescope" in acked.inner_text()
        finally:
            browser.close()
    assert not problems, problems
    stored = [a for a in api.get("/api/v1/alarms?state=acknowledged").json()["items"]]
    assert [a["tooth"] for a in stored if a["indicator"] == "mci_depth"] == [SPALL_TOOTH]
    assert stored[0]["acknowledged_by"].startswith("operator key")


def _rig(api: Api) -> str:
    rigs = api.get("/api/v1/rigs").json()["items"]
    assert len(rigs) == 1
    return str(rigs[0]["rig_id"])
