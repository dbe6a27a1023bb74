"""The dashboard in a real browser (headless Debian Chromium driven by Playwright), one test
per interaction, on one database: the simulated campaign (spall on pinion tooth 16 from day 10)
replayed by ``gearwatch replay``, a second rig seeded with a spall on tooth 7, and a third whose
whole-record kurtosis jumps. The service runs under uvicorn on a loopback port.

Screenshots go to ``test-artifacts/``. Without Chromium the tests skip locally and fail under
CI (``CI`` set).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import re
import shutil
import socket
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa

from tests.conftest import service_unavailable
from tests.service.conftest import SPALL_TOOTH, Replayed

pytestmark = [pytest.mark.browser, pytest.mark.slow]

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
ARTIFACTS = Path(__file__).resolve().parents[2] / "test-artifacts"
VIEWPORT = {"width": 1400, "height": 1100}
SIM_RIG = "rig-1"
SEEDED_SPALL_TOOTH = 7
KURTOSIS_JUMP_DAY = 8
TOOTHLESS_RECORDS = 6
PAIRS = (("pair-20", 20, 3), ("pair-17", 17, 2))  # (campaign, pinion teeth, records), in order
OLD_PAIR_ALARM_TOOTH = 18  # an open alarm on the earlier pair's pinion, beyond the current one's teeth


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class Site:
    url: str
    keys: dict[str, str]
    sim_rig: str


def _seed_other_rigs(factory: Any) -> None:
    from gearwatch.usecases.alarms import evaluate_record
    from storage.db import session_scope
    from storage.models import ToothIndicator
    from storage.repositories import (
        AlarmRepository,
        AlarmRuleRepository,
        CampaignRepository,
        RecordRepository,
    )
    from tests.service.seed import seed_campaign
    from tests.storage.factories import analysis, campaign_config

    with session_scope(factory) as session:
        seed_campaign(session, rig="rig-a", campaign="camp-a", spall_tooth=SEEDED_SPALL_TOOTH)
        stored = CampaignRepository(session).ensure(campaign_config("camp-k", "rig-k"))
        AlarmRuleRepository(session).ensure_defaults(stored.rig_id)
        records = RecordRepository(session)
        t0 = dt.datetime(2026, 4, 1, 8, tzinfo=dt.UTC)
        for day in range(12):
            sha = f"k{day}".encode().hex().ljust(64, "0")
            record = records.add(
                stored, sha256=sha, file_name=f"k{day}.wav", raw_location="/nonexistent",
                taken_at=t0 + dt.timedelta(days=day), label=f"run {day}",
            )
            kurtosis = 3.0 + 0.01 * (day % 3) if day < KURTOSIS_JUMP_DAY else 10.0
            result_analysis = analysis(sha256=sha, kurtosis=kurtosis, mci_depth=0.1)
            records.mark_accepted(record, result_analysis)
            evaluate_record(session, record, records.add_result(record, result_analysis))
        # a rig without tooth counts (like the real wind-turbine campaign)
        toothless = CampaignRepository(session).ensure(
            campaign_config("camp-w", "rig-w", pinion_teeth=None, gear_teeth=None)
        )
        for day in range(TOOTHLESS_RECORDS):
            sha = f"w{day}".encode().hex().ljust(64, "0")
            record = records.add(
                toothless, sha256=sha, file_name=f"w{day}.mat", raw_location="/nonexistent",
                taken_at=t0 + dt.timedelta(days=day), label=f"turbine {day}",
            )
            result_analysis = analysis(sha256=sha, teeth=0)
            records.mark_accepted(record, result_analysis)
            records.add_result(record, result_analysis)
        # a rig without a tach, two accelerometers: one framed in the campaign, one refused
        tachless = CampaignRepository(session).ensure(campaign_config("camp-t", "rig-t"))
        sha = b"t0".hex().ljust(64, "0")
        record = records.add(tachless, sha256=sha, file_name="t0.wav", raw_location="/nonexistent",
                             taken_at=t0, label="no tach")
        result_analysis = analysis(sha256=sha, channels=("a1", "a2"))
        result_analysis = dataclasses.replace(result_analysis, quality=dataclasses.replace(
            result_analysis.quality, angle_source="mesh_phase", tooth_frames={
                "a1": {"kind": "refused", "reason": "tooth frame refused: ambiguous tooth frame"},
                "a2": {"kind": "campaign", "reference_frame": "mesh_phase",
                       "pinion": {"separation_z": 2.1, "confirmed_by_sector_pattern": True}},
            }))
        records.mark_accepted(record, result_analysis)
        records.add_result(record, result_analysis)
        # a rig whose 20-tooth pinion was replaced by a 17-tooth one: two gear pairs
        day = 0
        last_of_pair = {}
        for name, teeth, count in PAIRS:
            pair = CampaignRepository(session).ensure(
                campaign_config(name, "rig-p", pinion_teeth=teeth, gear_teeth=43))
            for _ in range(count):
                sha = f"{name}{day}".encode().hex().ljust(64, "0")[:64]
                record = records.add(pair, sha256=sha, file_name=f"{name}-{day}.wav",
                                     raw_location="/nonexistent",
                                     taken_at=t0 + dt.timedelta(days=day), label=f"{name} {day}")
                result_analysis = analysis(sha256=sha, teeth=teeth, curve_length=64 * teeth)
                records.mark_accepted(record, result_analysis)
                records.add_result(record, result_analysis)
                last_of_pair[name] = record
                day += 1
        # an alarm still open on the earlier pinion's tooth 18, which the current one does not have
        old_record = last_of_pair[PAIRS[0][0]]
        depth_rule = next(rule for rule in AlarmRuleRepository(session).ensure_defaults(
            old_record.rig_id) if rule.indicator == "mci_depth")
        AlarmRepository(session).open(
            rule=depth_rule, tooth=OLD_PAIR_ALARM_TOOTH, severity="alarm", record=old_record,
            channel_id=session.scalar(sa.select(ToothIndicator.channel_id).where(
                ToothIndicator.record_id == old_record.id).limit(1)),
            value=0.9, score=7.5, baseline_centre=0.15, baseline_spread=0.1, evidence="level")


@pytest.fixture(scope="module")
def site(replayed_campaign: Replayed) -> Iterator[Site]:
    import uvicorn

    from gearwatch.floor.settings import Settings
    from gearwatch.usecases.keys import issue_api_key
    from service.app import create_app
    from storage.db import open_database, session_scope
    from storage.repositories import RigRepository

    if shutil.which("chromium") is None and not Path(CHROMIUM).exists():
        service_unavailable("Chromium", f"{CHROMIUM} not installed (apt-get install chromium)")
    engine, factory = open_database(replayed_campaign.db_url, auto_migrate=False)
    with session_scope(factory) as session:
        sim_rig = RigRepository(session).list()[0].name
    _seed_other_rigs(factory)
    keys = {}
    with session_scope(factory) as session:
        for role in ("viewer", "operator"):
            keys[role] = issue_api_key(session, name=f"{role} key", role=role)[1]
    engine.dispose()
    settings = Settings(
        database_url=replayed_campaign.db_url,
        raw_store=replayed_campaign.raw_store,
        auto_migrate=False,
        trend_cache_seconds=0.0,
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
    try:
        yield Site(f"http://127.0.0.1:{port}", keys, sim_rig)
    finally:
        server.should_exit = True
        thread.join(10)


@pytest.fixture(scope="module")
def browser(site: Site) -> Iterator[Any]:
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        chromium = playwright.chromium.launch(
            executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS
        )
        try:
            yield chromium
        finally:
            chromium.close()


@pytest.fixture
def page(browser: Any, site: Site, request: pytest.FixtureRequest) -> Iterator[Any]:
    """A fresh page logged in as an operator, the dashboard ready; page errors fail the test."""
    context = browser.new_context(viewport=VIEWPORT, accept_downloads=True)
    context.set_default_timeout(120_000)  # every wait is for a condition; this bounds a hang
    page = context.new_page()
    problems: list[str] = []
    page.on("pageerror", lambda error: problems.append(f"page error: {error}"))
    page.on(
        "console", lambda m: problems.append(f"console: {m.text}") if m.type == "error" else None
    )
    page.goto(f"{site.url}/#key={site.keys['operator']}&rig={site.sim_rig}")
    page.wait_for_selector("body[data-ready='true']", timeout=120_000)
    yield page
    ARTIFACTS.mkdir(exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / f"dashboard-{request.node.name}.png"), full_page=True)
    context.close()
    assert not problems, problems


def _ready_after(page: Any, action: Any) -> None:
    page.evaluate("delete document.body.dataset.ready")
    action()
    page.wait_for_selector("body[data-ready='true']", timeout=120_000)


def _api(page: Any, site: Site, path: str) -> Any:
    return page.evaluate(
        """async ([path, key]) => (await fetch(path, {headers: {Authorization: "Bearer " + key}})).json()""",
        [path, site.keys["operator"]],
    )


def test_opening_shows_every_rig_and_the_spalled_tooth_with_units_and_dates(
    page: Any, site: Site
) -> None:
    rows = page.locator("#overview tbody tr")
    assert sorted(rows.nth(i).get_attribute("data-rig") for i in range(rows.count())) == sorted(
        [site.sim_rig, "rig-a", "rig-k", "rig-p", "rig-t", "rig-w"]
    )
    sim = page.locator(f"#overview tbody tr[data-rig='{site.sim_rig}']").inner_text()
    assert f"tooth {SPALL_TOOTH}" in sim and "alarm" in sim and "day 12" in sim
    assert f"Open alarms: tooth {SPALL_TOOTH}" in page.inner_text("#alarmed-teeth")
    assert str(SPALL_TOOTH) in (page.get_attribute("#heatmap", "data-alarmed-teeth") or "")
    # the replayed rig's results hold the per-tooth score (issue 10): its heat map is the score's
    assert "(baseline units)" in page.inner_text("#heatmap-title")
    # the colour scale spans every value shown: the spalled tooth is the top of the bar
    trend = _api(page, site, f"/api/v1/rigs/{site.sim_rig}/trends?indicator=score")
    values = [v for row in trend["values"] for v in row if v is not None]
    assert float(page.get_attribute("#heatmap", "data-max")) == pytest.approx(max(values))
    assert float(page.get_attribute("#heatmap", "data-min")) == pytest.approx(min(values))
    assert page.inner_text("#trend-title") == f"tooth {SPALL_TOOTH} — per-tooth score (baseline units)"
    assert page.get_attribute("#trend", "data-levels") == "true"
    # the levels drawn are the rule's own (its learned baseline and, for the score, the pooled spread)
    levels = _api(page, site, f"/api/v1/rigs/{site.sim_rig}/alarm-levels?indicator=score")
    warning = next(t["warning"] for t in levels["items"] if t["tooth"] == SPALL_TOOTH)
    assert float(page.get_attribute("#trend", "data-warning") or "nan") == pytest.approx(warning)
    assert levels["pooled_spread"] is not None  # and the legend says what the spread is floored at
    assert "pooled over the teeth" in page.inner_text("#trend-legend")
    assert page.get_attribute("#curve", "data-sectors") == "20"
    assert page.inner_text("#curve-title").startswith("day 12 — ")


def test_switching_rig_resets_every_panel_to_the_new_rig(page: Any, site: Site) -> None:
    _ready_after(page, lambda: page.select_option("#rig", "rig-a"))
    assert page.inner_text("#trend-title") == f"tooth {SEEDED_SPALL_TOOTH} — MCI depth (Np)"
    assert page.inner_text("#curve-title").startswith("day 13 — ")
    marked = (page.get_attribute("#heatmap", "data-alarmed-teeth") or "").split(",")
    assert str(SEEDED_SPALL_TOOTH) in marked and str(SPALL_TOOTH) not in marked
    alarm_teeth = page.locator("#alarms tbody tr[data-alarm-id]")
    teeth = {alarm_teeth.nth(i).get_attribute("data-tooth") for i in range(alarm_teeth.count())}
    assert str(SPALL_TOOTH) not in teeth or SPALL_TOOTH == SEEDED_SPALL_TOOTH
    assert page.locator("#overview tr.selected").get_attribute("data-rig") == "rig-a"


def test_clicking_a_whole_record_alarm_shows_the_whole_record_trend_not_tooth_0(
    page: Any, site: Site
) -> None:
    _ready_after(page, lambda: page.click("#overview tbody tr[data-rig='rig-k']"))
    row = page.locator("#alarms tbody tr[data-indicator='kurtosis']")
    assert row.count() == 1
    assert "whole record" in row.inner_text() and "tooth 0" not in row.inner_text()
    row.click()
    page.wait_for_selector("#trend[data-tooth='whole']", timeout=120_000)
    assert page.input_value("#indicator") == "kurtosis"
    assert page.inner_text("#trend-title").startswith("whole record — kurtosis")
    assert page.get_attribute("#heatmap", "data-alarmed-teeth") == "whole"
    history = page.inner_text("#alarm-history")
    assert re.search(r"alarm by run \d+", history), history


def test_choosing_a_whole_record_indicator_draws_its_own_trend_and_heat_map(
    page: Any, site: Site
) -> None:
    page.select_option("#indicator", "raw_kurtosis")
    page.wait_for_selector("#trend[data-tooth='whole']", timeout=120_000)
    assert page.inner_text("#heatmap-title").startswith("kurtosis of the raw signal")
    assert page.get_attribute("#heatmap", "data-records") == "12"
    assert "tooth" not in page.inner_text("#trend-title")


def test_clicking_a_heat_map_cell_selects_its_record_and_tooth(page: Any, site: Site) -> None:
    box = page.locator("#heatmap").bounding_box()
    canvas_w, canvas_h = 1100, 360
    left, top, right, bottom = 64, 22, 110, 56
    cw, ch = (canvas_w - left - right) / 12, (canvas_h - top - bottom) / 20
    x = (left + 2.5 * cw) * box["width"] / canvas_w  # the third record
    y = (top + 4.5 * ch) * box["height"] / canvas_h  # tooth 5
    page.mouse.click(box["x"] + x, box["y"] + y)
    # selectors, not wait_for_function: the page's Content-Security-Policy forbids eval
    page.wait_for_selector("#trend[data-tooth='5']", timeout=120_000)
    page.wait_for_selector("#curve[data-record]", timeout=120_000)
    assert page.inner_text("#curve-title").startswith("day 3 — ")
    assert page.inner_text("#trend-title") == "tooth 5 — per-tooth score (baseline units)"


def test_overlaying_a_second_record_draws_both_curves(page: Any, site: Site) -> None:
    first = page.locator("#compare option").nth(1)
    page.select_option("#compare", first.get_attribute("value"))
    page.wait_for_selector("#curve[data-compare]:not([data-compare=''])", timeout=120_000)
    legend = page.inner_text("#curve .u-legend")
    assert "day 12" in legend and "day 1" in legend and "baseline" in legend


def test_acknowledging_with_a_comment_shows_it_in_the_history(page: Any, site: Site) -> None:
    row = page.locator(f"#alarms tbody tr[data-tooth='{SPALL_TOOTH}'][data-indicator='mci_depth']")
    row.locator("button.ack").click()
    page.fill("#ack-comment", "borescope: spall on tooth 16")
    page.click("#ack-submit")
    page.wait_for_selector("#alarm-history li:has-text('borescope')", timeout=120_000)
    history = page.inner_text("#alarm-history")
    assert "acknowledged" in history and "operator key" in history
    assert "acknowledged" in page.locator(
        f"#alarms tbody tr[data-tooth='{SPALL_TOOTH}'][data-indicator='mci_depth']"
    ).inner_text()


def test_no_open_alarm_is_not_written_in_alarm_red(page: Any, site: Site) -> None:
    page.select_option("#indicator", "diff_energy")
    page.wait_for_selector("#alarmed-teeth.no-alarm", timeout=120_000)
    colour = page.eval_on_selector("#alarmed-teeth", "e => getComputedStyle(e).color")
    assert colour != "rgb(176, 0, 32)", colour
    assert page.inner_text("#alarmed-teeth").startswith("No open alarm")


def test_the_acknowledge_button_is_not_clipped_at_1400_px(page: Any, site: Site) -> None:
    buttons = page.locator("#alarms button.ack")
    assert buttons.count() >= 1
    panel = page.locator("#alarms-panel").bounding_box()
    for i in range(buttons.count()):
        box = buttons.nth(i).bounding_box()
        assert box["x"] >= panel["x"] and box["x"] + box["width"] <= panel["x"] + panel["width"]
        assert box["x"] + box["width"] <= VIEWPORT["width"]


def test_exporting_the_trend_downloads_a_csv_with_units(page: Any, site: Site) -> None:
    with page.expect_download() as download_info:
        page.click("#trend-csv")
    path = download_info.value.path()
    text = Path(path).read_text()
    header = text.splitlines()[0]
    assert header.startswith("record_id,taken_at,label,channel,score tooth 1 [baseline units]")
    assert len(text.splitlines()) == 1 + 12


def test_a_rig_without_tooth_counts_shows_its_whole_record_indicators_not_the_previous_rig(
    page: Any, site: Site
) -> None:
    _ready_after(page, lambda: page.click("#overview tbody tr[data-rig='rig-w']"))
    assert page.input_value("#indicator") == "raw_kurtosis"
    assert "no tooth counts" in page.inner_text("#message")
    assert page.get_attribute("#heatmap", "data-records") == str(TOOTHLESS_RECORDS)
    assert page.get_attribute("#trend", "data-tooth") == "whole"
    assert page.inner_text("#curve-title").startswith(f"turbine {TOOTHLESS_RECORDS - 1} — ")
    assert page.get_attribute("#curve", "data-sectors") == "0"
    # every record has the same value here: said so, not drawn as a dark-to-yellow range
    assert "every value is" in page.inner_text("#heatmap-legend")
    assert page.locator("#alarms tbody tr[data-alarm-id]").count() == 0


def test_a_tachless_rig_says_on_which_channels_its_tooth_numbers_hold(page: Any, site: Site) -> None:
    # one accelerometer framed in the campaign, the other refused: the first channel alone
    # ("refused") would hide that the second one's tooth numbers hold
    row = page.locator("#overview tbody tr[data-rig='rig-t']").inner_text()
    assert ("angle from the mesh phase; teeth in the campaign's tach-less frame on 1 of 2 "
            "channels (not on a1)") in row
    assert "tach repair" not in row  # no tach: the synthetic pulses' repair list is not shown


def test_an_earlier_gear_pair_is_shown_by_choosing_its_campaign(page: Any, site: Site) -> None:
    """The rig's current pair by default; an earlier campaign on request, its own teeth and
    records, and every title and the exported file saying which campaign it is."""
    (old, old_teeth, old_records), (_new, new_teeth, _new_records) = PAIRS
    _ready_after(page, lambda: page.click("#overview tbody tr[data-rig='rig-p']"))
    assert page.input_value("#campaign") == ""
    assert f"× {new_teeth} teeth" in page.inner_text("#heatmap-legend")
    assert "campaign" not in page.inner_text("#heatmap-title")
    options = page.locator("#campaign option").all_inner_texts()
    assert options[0] == "current gear pair"
    assert any(o.startswith(f"{old} ({old_teeth}/43 teeth) — ") for o in options), options
    _ready_after(page, lambda: page.select_option("#campaign", old))
    assert f"{old_records} accepted records × {old_teeth} teeth" in page.inner_text(
        "#heatmap-legend")
    assert page.inner_text("#heatmap-title").endswith(f"— campaign {old}")
    assert page.inner_text("#trend-title").endswith(f"— campaign {old}")
    records = page.locator("#record option").all_inner_texts()
    assert len(records) == old_records and all(r.startswith(old) for r in records), records
    with page.expect_download() as download_info:
        page.click("#trend-csv")
    assert old in download_info.value.suggested_filename
    text = Path(download_info.value.path()).read_text()
    assert len(text.splitlines()) == 1 + old_records
    assert f"tooth {old_teeth} " in text.splitlines()[0]
    # another rig forgets the choice
    _ready_after(page, lambda: page.click("#overview tbody tr[data-rig='rig-a']"))
    assert page.input_value("#campaign") == ""


def test_an_alarm_of_an_earlier_gear_pair_opens_on_that_pair(page: Any, site: Site) -> None:
    """Clicked while the current pair is shown, an alarm raised on an earlier pair's record
    shows that campaign and its tooth (tooth 18 of the 20-tooth pinion, not of the 17-tooth)."""
    old, old_teeth, _records = PAIRS[0]
    _ready_after(page, lambda: page.click("#overview tbody tr[data-rig='rig-p']"))
    assert page.input_value("#campaign") == ""
    row = page.locator(f"#alarms tbody tr[data-tooth='{OLD_PAIR_ALARM_TOOTH}']")
    _ready_after(page, row.click)
    assert page.input_value("#campaign") == old
    assert f"× {old_teeth} teeth" in page.inner_text("#heatmap-legend")
    page.wait_for_selector(f"#trend[data-tooth='{OLD_PAIR_ALARM_TOOTH}']")
    assert page.inner_text("#trend-title").startswith(f"tooth {OLD_PAIR_ALARM_TOOTH} — ")
    assert page.inner_text("#trend-title").endswith(f"— campaign {old}")
