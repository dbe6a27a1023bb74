"""Refresh the dashboard screenshots in ``docs/`` from a gearwatch database.

    .venv/bin/python docs/tools/dashboard_screenshots.py --db sqlite:///gearwatch-demo/gearwatch.db

Serves the database on a loopback port, opens the dashboard in headless Debian Chromium
(``/usr/bin/chromium``) through Playwright, and writes ``docs/dashboard.png`` (as opened: the
rig overview, the heat map, the worst tooth's MCI curve and trend, the alarm list) and
``docs/dashboard-whole-record.png`` (a whole-record alarm clicked, its acknowledgement form
open, the last record overlaid on the first).
"""

from __future__ import annotations

import argparse
import socket
import threading
import time
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1]
ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run"]


def main() -> None:
    import uvicorn
    from playwright.sync_api import sync_playwright

    from gearwatch.floor.settings import Settings
    from gearwatch.usecases.keys import issue_api_key
    from service.app import create_app
    from storage.db import open_database, session_scope

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--db", required=True)
    parser.add_argument("--out-dir", type=Path, default=DOCS)
    args = parser.parse_args()
    engine, factory = open_database(args.db)
    with session_scope(factory) as session:
        key = issue_api_key(session, name="screenshots", role="operator")[1]
    engine.dispose()
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    server = uvicorn.Server(uvicorn.Config(
        create_app(Settings(database_url=args.db, auto_migrate=False)),
        host="127.0.0.1", port=port, log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    while not server.started:
        time.sleep(0.05)
    try:
        with sync_playwright() as playwright:
            browser = playwright.chromium.launch(executable_path="/usr/bin/chromium", args=ARGS)
            page = browser.new_page(viewport={"width": 1400, "height": 1100})
            page.goto(f"http://127.0.0.1:{port}/#key={key}")
            page.wait_for_selector("body[data-ready='true']", timeout=60_000)
            page.screenshot(path=str(args.out_dir / "dashboard.png"), full_page=True)
            whole = page.locator("#alarms tbody tr[data-tooth='whole']")
            if whole.count():
                whole.first.locator("button.ack").click()
                page.wait_for_selector("#trend[data-tooth='whole']")
                page.fill("#ack-comment", "raw kurtosis follows the spall; bearing checked: fine")
                first = page.locator("#compare option").nth(1).get_attribute("value")
                page.select_option("#compare", first)
                page.wait_for_selector("#curve[data-compare]:not([data-compare=''])")
                page.screenshot(path=str(args.out_dir / "dashboard-whole-record.png"),
                                full_page=True)
            browser.close()
    finally:
        server.should_exit = True
        thread.join(10)


if __name__ == "__main__":
    main()
