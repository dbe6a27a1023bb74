"""Trend endpoint under 100 concurrent clients, on SQLite and PostgreSQL (issue 5).

A rig with 365 accepted records × 20 teeth is stored through the repositories and the service
runs as ``gearwatch serve`` (one uvicorn worker, loopback). Clients ask for
``GET /api/v1/rigs/{rig}/trends?indicator=mci_depth`` (the records × teeth matrix, ~165 KB).

The server is pinned to CPU 0 and the load generator to CPU 1 (``taskset``), so the numbers
mean "one core serves this" and the load generator does not steal the server's CPU. The load
generators are separate processes:

* ``build``: in-process time to build one uncached answer (trend query + JSON), median of 20;
* ``cold``: first HTTP answers of 6 distinct (indicator, channel) cache keys, one at a time;
* ``poll``: realistic dashboards. Every client (one keep-alive connection each) asks once per
  ``--period`` seconds on a fixed schedule with a random phase (clients are spread evenly,
  not fired in the same instant). A raw-socket asyncio client in its own process; each
  connection first gets one unmeasured answer, parsed and checked (later answers are checked
  by length: parsing 165 KB inside the measured window would delay the other clients' reads).
  A request that has to wait for its client's previous answer is timed from its scheduled
  instant (no coordinated omission);
* ``poll etag``: the same, sending ``If-None-Match`` with the last ETag (a browser's
  revalidation: 304 without a body while the data is unchanged);
* ``poll gzip``: the same with ``Accept-Encoding: gzip`` (only if the server compresses);
* ``saturate``: closed loop, every client asks again as soon as it has its answer — ``wrk``
  (C, one thread; ``apt-get install wrk``) if installed, else the asyncio client without pause.
  Its latency is bounded by Little's law: p50 ≈ clients / throughput.

``server CPU ms/req`` is the server process's CPU time (user + system, from ``/proc``) divided
by the requests of the scenario: the cost of one answer, whatever the machine's load.
``server p99 (own)`` is the bucket of the server's own duration histogram (``/metrics``, from
the moment uvicorn hands the request to the app until the answer is written) that holds 99 %
of the scenario's trend requests: what the clients see beyond it is queueing and scheduling.

    .venv/bin/python benchmarks/bench_trends.py [--clients 100] [--seconds 10] [--period 1.0]
        [--backends sqlite,postgresql] [--workers 1] [--no-pin] [--nice -10]
"""

from __future__ import annotations

import argparse
import asyncio
import datetime as dt
import gzip
import json
import os
import random
import secrets
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

RECORDS = 365
TEETH = 20
RIG = "rig-bench"
DEFAULT_POSTGRES_URL = "postgresql+psycopg://postgres@127.0.0.1:5432/test"
TREND_PATH = f"/api/v1/rigs/{RIG}/trends?indicator=mci_depth"
SERVER_CPU = "0"
LOAD_CPU = "1"


def seed(url: str) -> str:
    """365 accepted records × 20 teeth on one rig; returns a viewer key."""
    from gearwatch.floor.campaign import Campaign, ChannelConfig, RigConfig, TachometerConfig
    from gearwatch.floor.results import (
        ChannelAnalysis,
        Provenance,
        Quality,
        RecordAnalysis,
        ToothResult,
    )
    from gearwatch.usecases.keys import issue_api_key
    from storage.db import open_database, session_scope
    from storage.repositories import CampaignRepository, RecordRepository

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
        key = issue_api_key(session, name="bench", role="viewer")[1]
    engine.dispose()
    return key


def build_times_ms(url: str, repeats: int = 20) -> list[float]:
    """In-process time to build one uncached trend answer (query + matrix + JSON bytes)."""
    from service.convert import rig_by_name
    from service.routers.rigs import trend_json
    from storage.db import open_database

    engine, factory = open_database(url)
    times = []
    with factory() as session:
        rig = rig_by_name(session, RIG)
        for _ in range(repeats):
            started = time.perf_counter()
            trend_json(session, rig, "mci_depth", None, None)
            times.append((time.perf_counter() - started) * 1000)
            session.rollback()
    engine.dispose()
    return times


# -- the server ------------------------------------------------------------------------------


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


NICENESS = 0
"""``--nice``: scheduling priority of the server and the load generator (negative: root)."""


def pinned(command: list[str], cpu: str, pin: bool) -> list[str]:
    command = ["taskset", "-c", cpu, *command] if pin else command
    return ["nice", "-n", str(NICENESS), *command] if NICENESS else command


def start_server(url: str, workers: int, pin: bool) -> tuple[subprocess.Popen[bytes], int]:
    import httpx

    port = free_port()
    command = [sys.executable, "-m", "gearwatch", "serve", "--port", str(port), "--db", url]
    command += ["--workers", str(workers), "--log-level", "warning"]
    # taskset execs the command: the process id is the server's
    process = subprocess.Popen(pinned(command, SERVER_CPU, pin))
    for _ in range(600):
        try:
            if httpx.get(f"http://127.0.0.1:{port}/health", timeout=1).status_code == 200:
                return process, port
        except httpx.HTTPError:
            pass
        time.sleep(0.05)
    process.terminate()
    raise RuntimeError("the server did not start")


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of ``pid`` and its descendants (uvicorn workers), from /proc."""
    ticks = os.sysconf("SC_CLK_TCK")
    parents: dict[int, int] = {}
    used: dict[int, float] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        parents[int(entry.name)] = int(fields[1])
        used[int(entry.name)] = (int(fields[11]) + int(fields[12])) / ticks
    total, todo = 0.0, [pid]
    while todo:
        current = todo.pop()
        total += used.get(current, 0.0)
        todo += [child for child, parent in parents.items() if parent == current]
    return total


# -- the load generators (separate processes) ------------------------------------------------


async def _read_response(reader: asyncio.StreamReader) -> tuple[int, dict[str, str], bytes]:
    head = await reader.readuntil(b"\r\n\r\n")
    lines = head.decode("latin-1").split("\r\n")
    status = int(lines[0].split()[1])
    headers = {}
    for line in lines[1:]:
        name, _, value = line.partition(":")
        if name:
            headers[name.strip().lower()] = value.strip()
    if headers.get("transfer-encoding", "").lower() == "chunked":
        body = b""
        while True:
            size = int((await reader.readuntil(b"\r\n")).split(b";")[0], 16)
            body += await reader.readexactly(size + 2)
            if size == 0:
                break
            body = body[:-2]
    else:
        body = await reader.readexactly(int(headers.get("content-length", "0")))
    return status, headers, body


def _valid_trend(headers: dict[str, str], body: bytes) -> bool:
    if headers.get("content-encoding") == "gzip":
        body = gzip.decompress(body)
    answer = json.loads(body)
    return len(answer["records"]) == RECORDS and len(answer["values"][0]) == TEETH


async def _clients(options: dict[str, Any]) -> dict[str, Any]:
    """``clients`` keep-alive connections, each asking every ``period`` s (0: closed loop)."""
    port, clients, seconds = options["port"], options["clients"], options["seconds"]
    period = options["period"]
    request = f"GET {TREND_PATH} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n"
    request += f"Authorization: Bearer {options['key']}\r\n"
    if options["gzip"]:
        request += "Accept-Encoding: gzip\r\n"
    loop = asyncio.get_running_loop()
    # A read buffer larger than an answer: the default (64 KiB) pauses the socket mid-answer.
    connections = [
        await asyncio.open_connection("127.0.0.1", port, limit=1 << 20) for _ in range(clients)
    ]
    etags: list[str | None] = []
    for reader, writer in connections:  # one unmeasured answer each, parsed and checked
        writer.write((request + "\r\n").encode())
        status, headers, body = await _read_response(reader)
        if status != 200 or not _valid_trend(headers, body):
            raise RuntimeError(f"unexpected first answer: {status} {body[:200]!r}")
        etags.append(headers.get("etag"))
    latencies: list[float] = []
    statuses: dict[int, int] = {}
    errors = 0
    body_bytes = 0
    begin = loop.time() + 0.1
    end = begin + seconds

    async def client(index: int) -> None:
        nonlocal errors, body_bytes
        reader, writer = connections[index]
        rng = random.Random(index)
        phase = rng.uniform(0, period)
        etag = etags[index]
        expected_length = None
        free_at = 0.0  # when this client's previous answer arrived
        scheduled = begin + phase
        while True:
            if period:
                if scheduled >= end:
                    break
                if scheduled > loop.time():
                    await asyncio.sleep(scheduled - loop.time())
            else:
                scheduled = loop.time()
                if scheduled >= end:
                    break
            sent = loop.time()
            extra = f"If-None-Match: {etag}\r\n" if options["etag"] and etag else ""
            writer.write((request + extra + "\r\n").encode())
            try:
                status, headers, body = await _read_response(reader)
            except (OSError, asyncio.IncompleteReadError):
                errors += 1  # the server closed the connection: this client stops
                return
            done = loop.time()
            # Waiting for the previous answer past the scheduled instant counts; the client's
            # own wake-up lag does not.
            latencies.append(done - (scheduled if free_at > scheduled else sent))
            free_at = done
            statuses[status] = statuses.get(status, 0) + 1
            body_bytes += len(body)
            if status == 200:
                etag = headers.get("etag")
                # the first answer was parsed; the same data gives the same length
                expected_length = expected_length or len(body)
                errors += len(body) != expected_length
            elif not (status == 304 and options["etag"]):
                errors += 1
            scheduled += period

    await asyncio.gather(*(client(i) for i in range(clients)))
    wall = loop.time() - begin
    for _, writer in connections:
        writer.close()
    return {
        "latencies_ms": [1000 * x for x in latencies],
        "errors": errors,
        "wall_s": wall,
        "statuses": statuses,
        "body_bytes": body_bytes,
    }


def run_load_client(options: dict[str, Any], pin: bool) -> dict[str, Any]:
    command = [sys.executable, __file__, "--load-client", json.dumps(options)]
    done = subprocess.run(pinned(command, LOAD_CPU, pin), capture_output=True, check=True)
    result: dict[str, Any] = json.loads(done.stdout)
    return result


def run_wrk(
    port: int, key: str, clients: int, seconds: float, pin: bool, gzip_wanted: bool
) -> dict[str, Any]:
    encoding = 'wrk.headers["Accept-Encoding"] = "gzip"' if gzip_wanted else ""
    script = f"""
wrk.headers["Authorization"] = "Bearer {key}"
{encoding}
done = function(summary, latency, requests)
  local e = summary.errors
  io.write(string.format('{{"requests": %d, "duration_us": %d, "errors": %d, "bytes": %d, '
    .. '"p50_us": %d, "p95_us": %d, "p99_us": %d, "max_us": %d}}\\n', summary.requests,
    summary.duration, e.connect + e.read + e.write + e.timeout + e.status, summary.bytes,
    latency:percentile(50), latency:percentile(95), latency:percentile(99), latency.max))
end
"""
    with tempfile.NamedTemporaryFile("w", suffix=".lua") as lua:
        lua.write(script)
        lua.flush()
        command = ["wrk", "-t1", f"-c{clients}", f"-d{seconds:g}s", "--timeout", "30s"]
        command += ["-s", lua.name, f"http://127.0.0.1:{port}{TREND_PATH}"]
        done = subprocess.run(pinned(command, LOAD_CPU, pin), capture_output=True, check=True)
    line = [x for x in done.stdout.decode().splitlines() if x.startswith("{")][-1]
    result: dict[str, Any] = json.loads(line)
    return result


# -- the table -------------------------------------------------------------------------------


@dataclass
class Row:
    backend: str
    scenario: str
    clients: int
    requests: int
    wall_s: float
    p50_ms: float
    p95_ms: float
    p99_ms: float
    max_ms: float
    errors: int
    server_ms: float | None = None
    """Server CPU time per request."""
    server_p99: str = "-"
    """The server's own p99 handling time, as the bucket of its duration histogram."""
    answer_kb: float | None = None

    @classmethod
    def of(cls, backend: str, scenario: str, clients: int, latencies_ms: list[float],
           errors: int, wall_s: float) -> Row:  # fmt: skip
        ms = np.asarray(latencies_ms)
        p50, p95, p99 = np.percentile(ms, [50, 95, 99])
        return cls(backend, scenario, clients, len(ms), wall_s, p50, p95, p99, ms.max(), errors)

    def line(self) -> str:
        server = f"{self.server_ms:.2f}" if self.server_ms is not None else "-"
        size = f"{self.answer_kb:.1f}" if self.answer_kb is not None else "-"
        rate = self.requests / self.wall_s if self.wall_s else 0.0
        return (
            f"| {self.backend:<10} | {self.scenario:<12} | {self.clients:>7} | {self.requests:>8} "
            f"| {rate:>7.0f} | {self.p50_ms:>7.1f} | {self.p95_ms:>7.1f} | {self.p99_ms:>7.1f} "
            f"| {self.max_ms:>7.1f} | {self.errors:>6} | {server:>10} | {self.server_p99:>9} "
            f"| {size:>7} |"
        )


HEADER = (
    "| backend    | scenario     | clients | requests |   req/s |  p50 ms |  p95 ms |  p99 ms "
    "|  max ms | errors | server CPU | server p99 |  answer |\n"
    "|            |              |         |          |         |         |         |         "
    "|         |        |  ms/req    | (own)   ms |      KB |\n"
    "|------------|--------------|---------|----------|---------|---------|---------|---------"
    "|---------|--------|------------|------------|---------|"
)


def trend_histogram(port: int, key: str) -> np.ndarray:
    """Cumulative counts of the server's trend request durations per bucket (from /metrics)."""
    import httpx

    from service.metrics import DURATION_BUCKETS_S

    text = httpx.get(f"http://127.0.0.1:{port}/metrics", timeout=30,
                     headers={"Authorization": f"Bearer {key}"}).text  # fmt: skip
    counts = np.zeros(len(DURATION_BUCKETS_S) + 1)
    uppers = [repr(b) for b in DURATION_BUCKETS_S] + ["+Inf"]
    for line in text.splitlines():
        if line.startswith("gearwatch_http_request_duration_seconds_bucket{") and (
            'route="/api/v1/rigs/{rig_id}/trends"' in line
        ):
            upper = line.split('le="')[1].split('"')[0]
            counts[uppers.index(upper)] += float(line.rsplit(" ", 1)[1])
    return counts


def histogram_p99(counts: np.ndarray) -> str:
    """"≤ X" (ms): the smallest bucket of cumulative ``counts`` holding 99 % of the requests."""
    from service.metrics import DURATION_BUCKETS_S

    if counts[-1] == 0:
        return "-"
    index = int(np.argmax(counts >= 0.99 * counts[-1]))
    return f"≤ {DURATION_BUCKETS_S[index] * 1000:g}" if index < len(DURATION_BUCKETS_S) else "> 10 s"


class Measured:
    """Server CPU time and the server's duration histogram around one scenario."""

    def __init__(self, process: subprocess.Popen[bytes], port: int, key: str) -> None:
        self.process, self.port, self.key = process, port, key

    def __enter__(self) -> Measured:
        self.histogram = trend_histogram(self.port, self.key)
        self.cpu_s = cpu_seconds(self.process.pid)
        return self

    def __exit__(self, *_: object) -> None:
        self.cpu_s = cpu_seconds(self.process.pid) - self.cpu_s
        self.histogram = trend_histogram(self.port, self.key) - self.histogram

    def fill(self, row: Row) -> Row:
        row.server_ms = self.cpu_s * 1000 / max(row.requests, 1)
        row.server_p99 = histogram_p99(self.histogram)
        return row


def cold(port: int, key: str) -> list[float]:
    """Six uncached answers: every indicator, without and with an explicit channel."""
    import httpx

    times = []
    headers = {"Authorization": f"Bearer {key}"}
    with httpx.Client(headers=headers, timeout=30) as http:
        for channel in ("", "&channel=acc"):
            for indicator in ("mci_depth", "diff_energy", "diff_kurtosis"):
                url = f"http://127.0.0.1:{port}/api/v1/rigs/{RIG}/trends?indicator={indicator}"
                started = time.perf_counter()
                response = http.get(url + channel)
                times.append((time.perf_counter() - started) * 1000)
                assert response.status_code == 200, response.text
                assert len(response.json()["records"]) == RECORDS
    return times


def compresses(port: int, key: str) -> bool:
    import httpx

    headers = {"Authorization": f"Bearer {key}", "Accept-Encoding": "gzip"}
    response = httpx.get(f"http://127.0.0.1:{port}{TREND_PATH}", headers=headers, timeout=30)
    return response.headers.get("content-encoding") == "gzip"


def bench_backend(backend: str, url: str, args: argparse.Namespace) -> list[Row]:
    started = time.perf_counter()
    key = seed(url)
    print(f"{backend}: seeded {RECORDS}×{TEETH} in {time.perf_counter() - started:.1f} s",
          file=sys.stderr)  # fmt: skip
    build = build_times_ms(url)
    rows = [Row.of(backend, "build", 1, build, 0, sum(build) / 1000)]
    process, port = start_server(url, args.workers, args.pin)
    try:
        with Measured(process, port, key) as measured:
            cold_ms = cold(port, key)
        rows.append(measured.fill(Row.of(backend, "cold", 1, cold_ms, 0, sum(cold_ms) / 1000)))

        gzip_served = compresses(port, key)
        scenarios = [("poll", False, False), ("poll etag", True, False)]
        if gzip_served:
            scenarios.append(("poll gzip", False, True))
        for name, etag, gzip_wanted in scenarios:
            options = {"port": port, "key": key, "clients": args.clients, "etag": etag,
                       "seconds": args.seconds, "period": args.period, "gzip": gzip_wanted}  # fmt: skip
            with Measured(process, port, key) as measured:
                result = run_load_client(options, args.pin)
            row = Row.of(backend, f"{name} {args.period:g}s", args.clients,
                         result["latencies_ms"], result["errors"], result["wall_s"])  # fmt: skip
            row.answer_kb = result["body_bytes"] / max(row.requests, 1) / 1000
            rows.append(measured.fill(row))

        saturate_s = min(args.seconds, 5.0)
        if shutil.which("wrk"):
            saturations = [("saturate", False)] + ([("saturate gz", True)] if gzip_served else [])
            for name, gzip_wanted in saturations:
                with Measured(process, port, key) as measured:
                    found = run_wrk(port, key, args.clients, saturate_s, args.pin, gzip_wanted)
                us = [found[k] / 1000 for k in ("p50_us", "p95_us", "p99_us", "max_us")]
                row = Row(backend, name, args.clients, found["requests"],
                          found["duration_us"] / 1e6, *us, found["errors"])  # fmt: skip
                row.answer_kb = found["bytes"] / max(found["requests"], 1) / 1000  # + headers
                rows.append(measured.fill(row))
        else:
            options = {"port": port, "key": key, "clients": args.clients, "etag": False,
                       "seconds": saturate_s, "period": 0.0, "gzip": False}  # fmt: skip
            with Measured(process, port, key) as measured:
                result = run_load_client(options, args.pin)
            row = Row.of(backend, "saturate", args.clients, result["latencies_ms"],
                         result["errors"], result["wall_s"])  # fmt: skip
            row.answer_kb = result["body_bytes"] / max(row.requests, 1) / 1000
            rows.append(measured.fill(row))
        return rows
    finally:
        process.terminate()
        process.wait(30)


def environment(args: argparse.Namespace) -> str:
    import importlib.util

    def have(module: str) -> str:
        return "yes" if importlib.util.find_spec(module) else "no"

    load = os.getloadavg()
    pinning = (
        f"server on CPU {SERVER_CPU}, load generator on CPU {LOAD_CPU}"
        if args.pin
        else "not pinned (server and load generator share the CPUs)"
    )
    return (
        f"trend endpoint, {RECORDS} records × {TEETH} teeth, uvicorn workers: {args.workers}, "
        f"{os.cpu_count()} CPUs, {pinning}, niceness {args.nice}; "
        f"load average {load[0]:.1f} {load[1]:.1f} "
        f"{load[2]:.1f}; httptools {have('httptools')}, uvloop {have('uvloop')}, "
        f"orjson {have('orjson')}; saturate by {'wrk' if shutil.which('wrk') else 'asyncio'}"
    )


def main() -> None:
    if len(sys.argv) == 3 and sys.argv[1] == "--load-client":
        print(json.dumps(asyncio.run(_clients(json.loads(sys.argv[2])))))
        return
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--clients", type=int, default=100)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--period", type=float, default=1.0, help="poll period per client (s)")
    parser.add_argument("--workers", type=int, default=1, help="uvicorn worker processes")
    parser.add_argument("--backends", default="sqlite,postgresql")
    parser.add_argument("--no-pin", dest="pin", action="store_false",
                        help="do not pin the server and the load generator to CPUs 0 and 1")  # fmt: skip
    parser.add_argument("--nice", type=int, default=0,
                        help="run the server and the load generator at this niceness; -10 "
                        "(root) keeps other jobs on a shared machine from adding their "
                        "time slices to the latencies")  # fmt: skip
    args = parser.parse_args()
    args.pin = args.pin and bool(shutil.which("taskset")) and (os.cpu_count() or 1) >= 2
    global NICENESS
    NICENESS = args.nice

    import sqlalchemy as sa

    rows: list[Row] = []
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
    print(environment(args))
    print(HEADER)
    for row in rows:
        print(row.line())
    target = [r for r in rows if r.scenario.startswith("poll") and "etag" not in r.scenario]
    verdict = all(r.p99_ms <= 25.0 and r.errors == 0 for r in target)
    print(f"issue 5 (poll, p99 ≤ 25 ms, no errors, every backend): {'met' if verdict else 'NOT met'}")


if __name__ == "__main__":
    main()
