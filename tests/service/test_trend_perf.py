"""The fast trend path answers exactly what the plain one did, and its cache stays correct.

The reference answer is built independently: the row-by-row points of
``TrendRepository.trend`` arranged into records × teeth and validated by the pydantic
``TrendOut`` model (the original implementation). The data has two accelerometer channels
(created in the opposite of name order), a record missing two teeth, two records taken at the
same instant, a re-analysed record, records stored out of time order and a rejected record.
Every test runs on SQLite and PostgreSQL.
"""

from __future__ import annotations

import datetime as dt
import gzip
import json
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest
import sqlalchemy as sa
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session

from tests.service.conftest import Api
from tests.storage.factories import analysis, campaign_config

T0 = dt.datetime(2025, 6, 1, 8, 0, tzinfo=dt.UTC)
TEETH = 20
RIG = "rig-perf"
CHANNELS = ("acc2", "acc1")  # created in this order: "first by name" is acc1


def depth(day: int, tooth: int) -> float:
    return round(0.1 + 0.001 * day + 0.0001 * tooth, 6) + 1e-9 / 3  # full float precision


def seed(session: Session, *, rig: str = RIG, pinion_teeth: int | None = TEETH) -> list[int]:
    """Days 0–5 stored in the order 3, 0, 1, 5, 2, 4; day 2 lacks teeth 19 and 20, day 4 is
    taken at the same instant as day 5, day 1 is re-analysed; one rejected record."""
    from storage.repositories import CampaignRepository, RecordRepository

    campaign = CampaignRepository(session).ensure(
        campaign_config(f"camp-{rig}", rig, pinion_teeth=pinion_teeth, accelerometers=CHANNELS)
    )
    records = RecordRepository(session)
    ids = {}
    for day in (3, 0, 1, 5, 2, 4):
        taken_at = T0 + dt.timedelta(days=min(day, 4))
        sha = f"{rig}-{day}".encode().hex().ljust(64, "0")[:64]
        record = records.add(
            campaign, sha256=sha, file_name=f"d{day}.wav", raw_location="/x", taken_at=taken_at
        )
        teeth = 18 if day == 2 else TEETH
        depths = {t: depth(day, t) for t in range(1, TEETH + 1)}
        result = analysis(sha256=sha, teeth=teeth, mci_depth=depths, channels=CHANNELS)
        records.mark_accepted(record, result)
        records.add_result(record, result)
        if day == 1:  # re-analysed: the second version's values are the current ones
            again = analysis(
                sha256=sha,
                teeth=TEETH,
                mci_depth={t: 5.0 + t for t in range(1, TEETH + 1)},
                channels=CHANNELS,
                parameters={"samples_per_mesh": 32},
            )
            records.add_result(record, again)
        ids[day] = record.id
    rejected = records.add(
        campaign, sha256="f" * 64, file_name="bad.wav", raw_location="/x", taken_at=T0
    )
    records.mark_rejected(rejected, "too short")
    session.flush()
    return [ids[day] for day in range(6)]


def reference(
    session: Session, rig_name: str, indicator: str, tooth: int | None, channel: str | None
) -> dict[str, Any]:
    """The original implementation: points one by one, then the validated pydantic model."""
    import sqlalchemy as sa

    from gearwatch.floor.indicators import indicator_info, indicator_unit
    from service import schemas
    from storage.models import Channel, Record
    from storage.repositories import RigRepository, TrendRepository

    rig = RigRepository(session).get_by_name(rig_name)
    assert rig is not None
    points = TrendRepository(session).trend(rig.id, indicator, tooth, channel=channel)
    # records taken at the same instant: the lower record id first (the order is otherwise free)
    points.sort(key=lambda p: (p.taken_at, p.record_id))
    if channel is None and points:
        channel = min(p.channel for p in points)
        points = [p for p in points if p.channel == channel]
    if tooth is not None:
        teeth = [tooth]
    elif rig.pinion_teeth:
        teeth = list(range(1, rig.pinion_teeth + 1))
    else:
        teeth = sorted({p.tooth for p in points})
    records: list[dict[str, Any]] = []
    values: list[list[float | None]] = []
    row_of: dict[int, int] = {}
    for point in points:
        if point.record_id not in row_of:
            row_of[point.record_id] = len(records)
            label = session.get(Record, point.record_id).label  # type: ignore[union-attr]
            records.append(
                {"record_id": point.record_id, "taken_at": point.taken_at, "label": label}
            )
            values.append([None] * len(teeth))
        if point.tooth in teeth:
            values[row_of[point.record_id]][teeth.index(point.tooth)] = point.value
    units = {c.name: c.unit for c in session.scalars(sa.select(Channel))}
    model = schemas.TrendOut(
        rig_id=rig.name,
        indicator=indicator,
        title=indicator_info(indicator).title,
        scope="tooth",
        unit=indicator_unit(indicator, units.get(channel or "", "")) if points else
        indicator_unit(indicator, ""),
        channel=channel,
        teeth=teeth,
        records=records,  # type: ignore[arg-type]
        values=values,
    )
    answer: dict[str, Any] = json.loads(model.model_dump_json())
    return answer


@pytest.fixture
def days(api: Api) -> list[int]:
    with api.session() as session:
        ids = seed(session)
        session.commit()
    return ids


def trend_url(query: str, rig: str = RIG) -> str:
    return f"/api/v1/rigs/{rig}/trends?{query}"


@pytest.mark.parametrize(
    ("indicator", "tooth", "channel"),
    [
        ("mci_depth", None, None),
        ("diff_energy", None, "acc2"),
        ("mci_depth", 5, None),
        ("mci_depth", 19, "acc1"),
        ("diff_kurtosis", 20, None),
        ("mci_depth", None, "nope"),
    ],
)
def test_answer_equals_the_validated_reference(
    api: Api, days: list[int], indicator: str, tooth: int | None, channel: str | None
) -> None:
    query = f"indicator={indicator}" + (f"&tooth={tooth}" if tooth else "")
    query += f"&channel={channel}" if channel else ""
    response = api.get(trend_url(query))
    assert response.status_code == 200, response.text
    with api.session() as session:
        assert response.json() == reference(session, RIG, indicator, tooth, channel)


def test_known_answer_order_gaps_and_current_versions(api: Api, days: list[int]) -> None:
    trend = api.get(trend_url("indicator=mci_depth")).json()
    assert trend["channel"] == "acc1" and trend["teeth"] == list(range(1, TEETH + 1))
    # time order; days 4 and 5 share an instant: the lower record id (day 5, stored first)
    assert [r["record_id"] for r in trend["records"]] == [days[d] for d in (0, 1, 2, 3, 5, 4)]
    assert trend["records"][4]["taken_at"] == "2025-06-05T08:00:00Z"
    assert trend["values"][0][6] == depth(0, 7)  # every digit survives
    assert trend["values"][1] == [5.0 + t for t in range(1, TEETH + 1)]  # re-analysed day 1
    assert trend["values"][2][17:] == [depth(2, 18), None, None]  # day 2 lacks teeth 19, 20


def test_rig_without_tooth_count_gives_the_teeth_found(api: Api) -> None:
    with api.session() as session:
        seed(session, rig="rig-none", pinion_teeth=None)
        session.commit()
    trend = api.get(trend_url("indicator=mci_depth", "rig-none")).json()
    assert trend["teeth"] == list(range(1, TEETH + 1))
    with api.session() as session:
        assert trend == reference(session, "rig-none", "mci_depth", None, None)


def test_trend_matrix_known_answer(api: Api, days: list[int]) -> None:
    import numpy as np

    from storage.repositories import RigRepository, TrendRepository

    with api.session() as session:
        rig = RigRepository(session).get_by_name(RIG)
        assert rig is not None
        trends = TrendRepository(session)
        matrix = trends.trend_matrix(rig.id, "mci_depth", pinion_teeth=20)
        assert matrix.channel == "acc1" and matrix.values.shape == (6, 20)
        assert np.isnan(matrix.values[2, 18:]).all() and not np.isnan(matrix.values[3]).any()
        one = trends.trend_matrix(rig.id, "mci_depth", 19, channel="acc2", pinion_teeth=20)
        assert one.teeth == [19] and one.channel == "acc2"
        assert one.values[:, 0].tolist()[:2] == [depth(0, 19), 5.0 + 19]
        assert days[2] not in one.record_ids and len(one.record_ids) == 5  # day 2 lacks it
        empty = trends.trend_matrix(rig.id, "mci_depth", channel="nope", pinion_teeth=20)
        assert empty.values.shape == (0, 20) and empty.record_ids == []


# -- the cache, ETags and gzip ---------------------------------------------------------------


def test_gzip_answer_for_clients_that_ask_and_etags_per_encoding(api: Api, days: list[int]) -> None:
    url = trend_url("indicator=mci_depth")
    viewer = api.headers("viewer")
    plain = api.client.get(url, headers={**viewer, "Accept-Encoding": "identity"})
    assert "content-encoding" not in plain.headers
    assert plain.headers["vary"] == "Accept-Encoding"
    compressed = api.client.get(url, headers={**viewer, "Accept-Encoding": "br, gzip;q=0.5"})
    assert compressed.headers["content-encoding"] == "gzip"
    assert compressed.headers["vary"] == "Accept-Encoding"
    assert compressed.content == plain.content  # decoded by the client
    assert int(compressed.headers["content-length"]) < len(plain.content) / 2
    assert compressed.headers["etag"] != plain.headers["etag"]
    for tag in (plain.headers["etag"], "W/" + compressed.headers["etag"], '"x", *'):
        again = api.client.get(url, headers={**viewer, "If-None-Match": tag})
        assert again.status_code == 304 and again.content == b"", tag
    changed = api.client.get(url, headers={**viewer, "If-None-Match": '"other"'})
    assert changed.status_code == 200


@pytest.mark.parametrize(
    ("accept_encoding", "gzip_wanted"),
    [
        ("", False),
        ("identity", False),
        ("gzip", True),
        ("deflate, GZIP", True),
        ("gzip;q=0", False),
        ("gzip; q=0.8", True),
        ("*", True),
        ("*;q=0", False),
        ("gzip;q=x", False),
        ("br", False),
    ],
)
def test_accept_encoding(accept_encoding: str, gzip_wanted: bool) -> None:
    from service.routers.rigs import _accepts_gzip

    assert _accepts_gzip(accept_encoding) is gzip_wanted


@pytest.fixture
def cached_app(api: Api, tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Any, Api]]:
    """A second app on the same database that trusts its cache for an hour; it counts the
    SQL statements that read trend data or rigs."""
    from gearwatch.floor.settings import Settings
    from service.app import create_app

    engine = api.session_factory.kw["bind"]
    settings = Settings(
        database_url=engine.url.render_as_string(hide_password=False),
        raw_store=api.raw_store,
        auto_migrate=False,
        trend_cache_seconds=3600.0,
        upload_dir=tmp_path_factory.mktemp("uploads"),
    )
    app = create_app(settings)
    with TestClient(app, raise_server_exceptions=False) as client:
        app.state.statements = []
        sa.event.listen(
            app.state.engine,
            "before_cursor_execute",
            lambda _c, _cur, statement, *_: app.state.statements.append(statement),
        )
        yield client, api


def add_day(api: Api, day: int, value: float) -> None:
    from storage.repositories import CampaignRepository, RecordRepository

    with api.session() as session:
        campaign = CampaignRepository(session).get_by_name(f"camp-{RIG}")
        assert campaign is not None
        sha = f"late-{day}".encode().hex().ljust(64, "0")[:64]
        records = RecordRepository(session)
        record = records.add(
            campaign,
            sha256=sha,
            file_name="late.wav",
            raw_location="/x",
            taken_at=T0 + dt.timedelta(days=day),
        )
        late = analysis(sha256=sha, teeth=TEETH, mci_depth=value, channels=CHANNELS)
        records.mark_accepted(record, late)
        records.add_result(record, late)
        session.commit()


def test_a_cached_answer_needs_no_trend_query_until_its_version_is_rechecked(
    cached_app: tuple[Any, Api], days: list[int]
) -> None:
    client, api = cached_app
    statements: list[str] = client.app.state.statements
    headers = api.headers("viewer")
    url = trend_url("indicator=mci_depth")

    def reads_trend_data() -> bool:
        found = any("tooth_indicators" in s or "FROM rigs" in s for s in statements)
        statements.clear()
        return found

    first = client.get(url, headers=headers)
    assert first.status_code == 200 and reads_trend_data()
    assert client.get(url, headers=headers).content == first.content
    assert not reads_trend_data()  # only the API key was read
    one_tooth = client.get(trend_url("indicator=mci_depth&tooth=3"), headers=headers)
    assert one_tooth.status_code == 200 and reads_trend_data()  # another key: built once
    assert client.get(trend_url("indicator=mci_depth", "nope"), headers=headers).status_code == 404
    statements.clear()

    add_day(api, 10, 0.5)
    stale = client.get(url, headers=headers)  # trusted for trend_cache_seconds: by design
    assert stale.content == first.content and not reads_trend_data()
    client.app.state.settings.trend_cache_seconds = 0.0  # the recheck is due
    fresh = client.get(url, headers=headers)
    assert fresh.headers["etag"] != first.headers["etag"] and reads_trend_data()
    assert fresh.json()["values"][-1] == [0.5] * TEETH


def test_a_new_tooth_count_changes_the_answer(api: Api, days: list[int]) -> None:
    from storage.models import Rig

    url = trend_url("indicator=mci_depth")
    assert len(api.get(url).json()["teeth"]) == TEETH
    with api.session() as session:
        session.execute(sa.update(Rig).where(Rig.name == RIG).values(pinion_teeth=18))
        session.commit()
    trend = api.get(url).json()
    assert trend["teeth"] == list(range(1, 19))
    with api.session() as session:
        assert trend == reference(session, RIG, "mci_depth", None, None)


def test_concurrent_misses_build_one_answer(
    api: Api, days: list[int], monkeypatch: pytest.MonkeyPatch
) -> None:
    from service import queries
    from service.routers import rigs

    built: list[int] = []
    real = rigs.trend_json

    def slow_build(*args: Any) -> bytes:
        built.append(1)
        time.sleep(0.05)  # let every thread arrive while the first one builds
        return real(*args)

    monkeypatch.setattr(rigs, "trend_json", slow_build)
    cache: queries.ResponseCache[rigs.CachedTrend] = queries.ResponseCache()
    key = (RIG, "mci_depth", None, None, None)
    answers: list[rigs.CachedTrend] = []

    def request() -> None:
        with api.session() as session:
            answers.append(rigs._load_trend(session, cache, key))

    threads = [threading.Thread(target=request) for _ in range(6)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(answers) == 6 and len(built) == 1
    assert all(a is answers[0] for a in answers)
    assert gzip.decompress(answers[0].body_gzip) == answers[0].body


def test_group_versions_expire() -> None:
    from service.queries import ResponseCache

    cache: ResponseCache[bytes] = ResponseCache()
    assert cache.group_version("rig", 10.0) is None
    cache.confirm("rig", (1, 2))
    assert cache.group_version("rig", 10.0) == (1, 2)
    assert cache.group_version("rig", 0.0) is None
    assert cache.group_version("other", 10.0) is None
    assert cache.build_lock(("a", 1)) is cache.build_lock(("a", 1))
