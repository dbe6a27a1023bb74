"""Trend endpoint under concurrent clients, on SQLite and PostgreSQL.

A rig with 365 accepted records × 20 teeth is stored through the repositories, the service
runs as ``gearwatch serve`` (uvicorn, loopback), and 100 concurrent clients (one connection
each) ask for ``GET /api/v1/rigs/{rig}/trends?indicator=mci_depth`` (records × teeth):

* ``cold``: the first answer for each indicator (trend query + serialization, no cache);
* ``poll``: every client asks once per ``--think`` seconds (a dashboard refreshing), jittered;
* ``saturate``: every client asks again as soon as it has its answer (closed loop, no pause).

Latencies are measured by the clients (load generator on the same machine). Prints a table.

    .venv/bin/python benchmarks/bench_trends.py [--clients 100] [--seconds 10] [--think 1.0]
        [--backends sqlite,postgresql] [--workers 1]
"""

from __future__ import annotations

import argparse
import asyncio
import datetime as dt
import os
import random
import secrets
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

RECORDS = 365
TEETH = 20
RIG = "rig-bench"
DEFAULT_POSTGRES_URL = "postgresql+psycopg://postgres@127.0.0.1:5432/test"


def seed(url: str) -> str:
    """365 accepted records × 20 teeth on one rig; returns a viewer key."""
    from gearwatch.results import ChannelAnalysis, Provenance, Quality, RecordAnalysis, ToothResult
    from ingest.types import Campaign, ChannelConfig, RigConfig, TachometerConfig
    from storage.db import open_database, session_scope
    from storage.repositories import ApiKeyRepository, CampaignRepository, RecordRepository

    engine, factory = open_database(url)
    config = Campaign(
        id="bench",
        description="trend benchmark",
        rig=RigConfig(RIG, TEETH, TEETH + 1, 0.0),
        sample_rate_hz=20_000.0,
        tachometer=TachometerConfig("tach"),
        channels=(ChannelConfig("acc", "accelerometer"), ChannelConfig("tach", "tachometer")),
    )
    rng = np.random.default_rng(0)
    start = dt.datetime(2025, 1, 1, 8, tzinfo=dt.UTC)
    with session_scope(factory) as session:
        campaign = CampaignRepository(session).ensure(config)
        records = RecordRepository(session)
        for day in range(RECORDS):
            sha = f"{day:064x}"
            record = records.add(
                campaign,
                sha256=sha,
                file_name=f"day{day:03d}.wav",
                raw_location="/nonexistent",
                taken_at=start + dt.timedelta(days=day),
            )
            teeth = [
                ToothResult(t, (t - 1) * 360 / TEETH, *rng.normal([0.1, 1.0, 3.0], 0.01))
                for t in range(1, TEETH + 1)
            ]
            analysis = RecordAnalysis(
                [ChannelAnalysis("acc", 40, 38, 1500.0, 1280, {"rms": 1.0}, teeth)],
                Quality([], 0.01, 1490.0, 1510.0),
                Provenance(sha, "bench", {"samples_per_mesh": 64}),
                1500.0,
                40,
                1280,
            )
            records.mark_accepted(record, analysis)
            records.add_result(record, analysis)
        key = ApiKeyRepository(session).create(name="bench", role="viewer")[1]
    engine.dispose()
    return key


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def start_server(url: str, workers: int) -> tuple[subprocess.Popen[bytes], str]:
    import httpx

    port = free_port()
    command = [sys.executable, "-m", "gearwatch", "serve", "--port", str(port), "--db", url]
    command += ["--workers", str(workers), "--log-level", "warning"]
    process = subprocess.Popen(command)
    base = f"http://127.0.0.1:{port}"
    for _ in range(600):
        try:
            if httpx.get(f"{base}/health", timeout=1).status_code == 200:
                return process, base
        except httpx.HTTPError:
            pass
        time.sleep(0.05)
    process.terminate()
    raise RuntimeError("the server did not start")


async def run_clients(
    base: str, key: str, clients: int, seconds: float, think_s: float
) -> tuple[list[float], int, float]:
    import httpx

    url = f"{base}/api/v1/rigs/{RIG}/trends?indicator=mci_depth"
    headers = {"Authorization": f"Bearer {key}"}
    latencies: list[float] = []
    errors = 0
    deadline = time.perf_counter() + seconds

    async def client(index: int) -> None:
        nonlocal errors
        rng = random.Random(index)
        async with httpx.AsyncClient(headers=headers, timeout=30) as http:
            if think_s:
                await asyncio.sleep(rng.uniform(0, think_s))  # spread the first requests
            while time.perf_counter() < deadline:
                started = time.perf_counter()
                response = await http.get(url)
                elapsed = time.perf_counter() - started
                # parse one answer per client only: the load generator shares the CPUs
                if response.status_code != 200 or (
                    not latencies and len(response.json()["records"]) != RECORDS
                ):
                    errors += 1
                latencies.append(elapsed)
                if think_s:
                    await asyncio.sleep(max(0.0, think_s * rng.uniform(0.8, 1.2) - elapsed))

    began = time.perf_counter()
    await asyncio.gather(*(client(i) for i in range(clients)))
    return latencies, errors, time.perf_counter() - began


def cold(base: str, key: str) -> list[float]:
    import httpx

    times = []
    with httpx.Client(headers={"Authorization": f"Bearer {key}"}, timeout=30) as http:
        for indicator in ("mci_depth", "diff_energy", "diff_kurtosis"):
            started = time.perf_counter()
            response = http.get(f"{base}/api/v1/rigs/{RIG}/trends?indicator={indicator}")
            times.append(time.perf_counter() - started)
            assert response.status_code == 200 and len(response.json()["records"]) == RECORDS
    return times


def row(backend: str, scenario: str, clients: int, latencies: list[float], errors: int,
        wall_s: float) -> str:  # fmt: skip
    ms = np.asarray(latencies) * 1000
    p50, p95, p99 = np.percentile(ms, [50, 95, 99])
    return (
        f"| {backend:<10} | {scenario:<9} | {clients:>7} | {len(ms):>8} | {len(ms) / wall_s:>8.0f} "
        f"| {p50:>7.1f} | {p95:>7.1f} | {p99:>7.1f} | {ms.max():>7.1f} | {errors:>6} |"
    )


def bench_backend(backend: str, url: str, args: argparse.Namespace) -> list[str]:
    started = time.perf_counter()
    key = seed(url)
    print(f"{backend}: seeded {RECORDS}×{TEETH} in {time.perf_counter() - started:.1f} s",
          file=sys.stderr)  # fmt: skip
    process, base = start_server(url, args.workers)
    try:
        cold_times = cold(base, key)
        rows = [row(backend, "cold", 1, cold_times, 0, sum(cold_times))]
        latencies, errors, wall = asyncio.run(
            run_clients(base, key, args.clients, args.seconds, args.think)
        )
        rows.append(row(backend, f"poll {args.think:g}s", args.clients, latencies, errors, wall))
        latencies, errors, wall = asyncio.run(
            run_clients(base, key, args.clients, min(args.seconds, 5.0), 0.0)
        )
        rows.append(row(backend, "saturate", args.clients, latencies, errors, wall))
        return rows
    finally:
        process.terminate()
        process.wait(30)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--clients", type=int, default=100)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--think", type=float, default=1.0, help="poll period per client (s)")
    parser.add_argument("--workers", type=int, default=1, help="uvicorn worker processes")
    parser.add_argument("--backends", default="sqlite,postgresql")
    args = parser.parse_args()

    import sqlalchemy as sa

    rows: list[str] = []
    with tempfile.TemporaryDirectory() as folder:
        for backend in args.backends.split(","):
            if backend == "sqlite":
                rows += bench_backend(backend, f"sqlite:///{Path(folder) / 'bench.db'}", args)
                continue
            admin_url = os.environ.get("GEARWATCH_TEST_POSTGRES_URL", DEFAULT_POSTGRES_URL)
            schema = f"gw_bench_{secrets.token_hex(4)}"
            admin = sa.create_engine(admin_url, isolation_level="AUTOCOMMIT")
            with admin.connect() as connection:
                connection.execute(sa.text(f'CREATE SCHEMA "{schema}"'))
            url = (
                sa.engine.make_url(admin_url)
                .update_query_dict({"options": f"-csearch_path={schema}"})
                .render_as_string(hide_password=False)
            )
            try:
                rows += bench_backend(backend, url, args)
            finally:
                with admin.connect() as connection:
                    connection.execute(sa.text(f'DROP SCHEMA "{schema}" CASCADE'))
                admin.dispose()
    print(f"trend endpoint, {RECORDS} records × {TEETH} teeth, uvicorn workers: {args.workers}, "
          f"{os.cpu_count()} CPUs (shared with the load generator)")  # fmt: skip
    print("| backend    | scenario  | clients | requests |    req/s |  p50 ms |  p95 ms "
          "|  p99 ms |  max ms | errors |")  # fmt: skip
    print("|------------|-----------|---------|----------|----------|---------|---------"
          "|---------|---------|--------|")  # fmt: skip
    for line in rows:
        print(line)


if __name__ == "__main__":
    main()
