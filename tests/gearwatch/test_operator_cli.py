"""``gearwatch report``, ``gearwatch alarms`` and ``gearwatch trends`` on a seeded SQLite
database (spall on pinion tooth 7 from day 10, 14 days, one rejected record)."""

from __future__ import annotations

import csv
import io
import json
import re
from pathlib import Path

import pytest

from gearwatch.cli.main import main
from tests.service.seed import Seeded, seed_campaign


@pytest.fixture(scope="module")
def seeded_db(tmp_path_factory: pytest.TempPathFactory) -> tuple[str, Seeded]:
    from storage.db import open_database, session_scope

    url = f"sqlite:///{tmp_path_factory.mktemp('operator-cli') / 'gw.db'}"
    engine, factory = open_database(url)
    with session_scope(factory) as session:
        seeded = seed_campaign(session)
    engine.dispose()
    return url, seeded


def test_report_writes_a_pdf_with_a_page_per_section(
    seeded_db: tuple[str, Seeded], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    url, seeded = seeded_db
    out = tmp_path / "campaign.pdf"
    assert main(["report", "--rig", seeded.rig, "--db", url, "--out", str(out)]) == 0
    data = out.read_bytes()
    assert data.startswith(b"%PDF")
    pages = len(re.findall(rb"/Type\s*/Page[^s]", data))
    # summary, heat map, the alarmed tooth's trend, MCI curves, metrics, quality, provenance
    assert pages >= 7, pages
    assert f"rig {seeded.rig}, {len(seeded.record_ids) + 1} records" in capsys.readouterr().err


def test_report_writes_a_self_contained_html_page(
    seeded_db: tuple[str, Seeded], tmp_path: Path
) -> None:
    url, seeded = seeded_db
    out = tmp_path / "campaign.html"
    assert main(["report", "--rig", seeded.rig, "--db", url, "--out", str(out)]) == 0
    html = out.read_text()
    assert html.count("data:image/png;base64,") >= 4
    assert f"open alarms on pinion tooth {seeded.spall_tooth}" in html
    assert f"Trend: tooth {seeded.spall_tooth} — MCI depth" in html
    assert "too few revolutions" in html  # data quality of the rejected record
    assert seeded.record_ids and "f" * 64 in html  # provenance: raw sha256


def test_report_refuses_an_unknown_rig_or_format(
    seeded_db: tuple[str, Seeded], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    url, _ = seeded_db
    assert main(["report", "--rig", "nope", "--db", url, "--out", str(tmp_path / "r.pdf")]) == 2
    assert "rig 'nope' not found" in capsys.readouterr().err
    assert main(["report", "--rig", "rig-a", "--db", url, "--out", str(tmp_path / "r.doc")]) == 2


def test_alarms_prints_a_table_csv_and_json(
    seeded_db: tuple[str, Seeded], capsys: pytest.CaptureFixture[str]
) -> None:
    url, seeded = seeded_db
    assert main(["alarms", "--db", url]) == 0
    table = capsys.readouterr().out
    assert f"tooth {seeded.spall_tooth}" in table and "mci_depth" in table
    assert main(["alarms", "--db", url, "--csv"]) == 0
    rows = list(csv.DictReader(io.StringIO(capsys.readouterr().out)))
    assert [r["where"] for r in rows if r["indicator"] == "mci_depth"] == [
        f"tooth {seeded.spall_tooth}"
    ]
    assert main(["alarms", "--db", url, "--json", "--rig", seeded.rig]) == 0
    items = json.loads(capsys.readouterr().out)["items"]
    assert {a["tooth"] for a in items if a["indicator"] == "mci_depth"} == {seeded.spall_tooth}


def test_trends_prints_a_table_csv_and_json(
    seeded_db: tuple[str, Seeded], capsys: pytest.CaptureFixture[str]
) -> None:
    url, seeded = seeded_db
    assert main(["trends", "--rig", seeded.rig, "--db", url, "--tooth", "7"]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0].startswith(f"{seeded.rig}: MCI depth [Np]")
    assert "day 13" in out
    assert main(["trends", "--rig", seeded.rig, "--db", url, "--csv"]) == 0
    rows = list(csv.reader(io.StringIO(capsys.readouterr().out)))
    assert rows[0][4] == "mci_depth tooth 1 [Np]" and len(rows) == 1 + len(seeded.record_ids)
    assert main(["trends", "--rig", seeded.rig, "--db", url, "--json",
                 "--indicator", "kurtosis"]) == 0
    trend = json.loads(capsys.readouterr().out)
    assert trend["teeth"] == [None] and trend["scope"] == "record"
    # one campaign, by name; a name the rig does not have is a clear error
    assert main(["trends", "--rig", seeded.rig, "--db", url, "--campaign", seeded.campaign,
                 "--tooth", "7"]) == 0
    assert out.splitlines()[1:] == capsys.readouterr().out.splitlines()[1:]
    assert main(["trends", "--rig", seeded.rig, "--db", url, "--campaign", "nowhere"]) != 0
    assert "campaign 'nowhere' not found" in capsys.readouterr().err
