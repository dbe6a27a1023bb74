"""Distributed path throughput: records per second with 1, 2 and 4 Dramatiq worker processes
on PostgreSQL + RabbitMQ, and what that means for a lab of rigs.

Run (needs the services)::

    nice -n 10 .venv/bin/python benchmarks/bench_workers.py [--records 24] [--seconds 10]
        [--db postgresql+psycopg://postgres@127.0.0.1:5432/test]
        [--broker amqp://guest:guest@127.0.0.1:5672/]

Each configuration gets a schema and a queue of its own (dropped afterwards). The workers are
started and given time to connect before the clock starts; the clock stops when every record
has a stored result. Records: a 2-channel WAV (accelerometer + once-per-rev tach) of
``--seconds`` at 20 kHz, the real signal chain (pulses → angle resampling → averages → MCI).
The lab figure: rigs × records per hour ÷ 3600 = the records per second needed.
"""

from __future__ import annotations

import argparse
import datetime as dt
import os
import secrets
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import scipy.io.wavfile
import sqlalchemy as sa

REPO = Path(__file__).resolve().parents[1]
RATE_HZ = 20_000


def write_campaign(folder: Path, records: int, seconds: float) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(1)
    n = int(seconds * RATE_HZ)
    t = np.arange(n) / RATE_HZ
    entries = []
    for day in range(records):
        shaft_hz = 25.0
        acc = (np.sin(2 * np.pi * 20 * shaft_hz * t) + 0.3 * rng.standard_normal(n)).astype(
            np.float32)
        tach = ((np.sin(2 * np.pi * shaft_hz * t) > 0.99) * 5.0).astype(np.float32)
        name = f"day{day:03d}.wav"
        scipy.io.wavfile.write(folder / name, RATE_HZ, np.column_stack([acc, tach]))
        taken = dt.datetime(2026, 1, 1, tzinfo=dt.UTC) + dt.timedelta(minutes=10 * day)
        entries.append(f'[[records]]\nfile = "{name}"\ntaken_at = "{taken.isoformat()}"\n')
    (folder / "campaign.toml").write_text(
        '[campaign]\nid = "bench-workers"\n\n[rig]\nid = "bench-rig"\npinion_teeth = 20\n'
        'gear_teeth = 21\n\n[acquisition]\nsample_rate_hz = 20000\n\n[tachometer]\n'
        'channel = "tach"\n\n[[channels]]\nname = "acc"\nkind = "accelerometer"\n\n'
        '[[channels]]\nname = "tach"\nkind = "tachometer"\n\n' + "\n".join(entries)
    )
    return folder / "campaign.toml"


def run(workers: int, manifest: Path, db_url: str, broker_url: str, tmp: Path) -> float:
    import dramatiq
    import pika
    from dramatiq.brokers.rabbitmq import RabbitmqBroker

    from ingest.manifest import load_manifest
    from storage.db import open_database, session_scope
    from storage.repositories import CampaignRepository

    schema = f"gw_bench_{secrets.token_hex(5)}"
    admin = sa.create_engine(db_url, isolation_level="AUTOCOMMIT")
    with admin.connect() as connection:
        connection.execute(sa.text(f'CREATE SCHEMA "{schema}"'))
    url = sa.engine.make_url(db_url).update_query_dict(
        {"options": f"-csearch_path={schema}"}).render_as_string(hide_password=False)
    queue = f"gw_bench_{secrets.token_hex(5)}"
    processes = []
    try:
        engine, factory = open_database(url)
        campaign = load_manifest(manifest)
        with session_scope(factory) as session:
            CampaignRepository(session).ensure(campaign)
        env = {**os.environ, "GEARWATCH_QUEUE": queue, "GEARWATCH_BROKER_URL": broker_url,
               "GEARWATCH_DATABASE_URL": url, "GEARWATCH_RAW_STORE": str(tmp / f"raw{workers}")}
        for index in range(workers):
            log = open(tmp / f"w{workers}-{index}.log", "wb")  # lives with the process
            processes.append(subprocess.Popen(
                [sys.executable, "-m", "dramatiq", "gearwatch.worker", "--processes", "1",
                 "--threads", "1", "--path", str(REPO)],
                cwd=REPO, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True))
        broker = RabbitmqBroker(url=broker_url)
        broker.declare_queue(queue)
        time.sleep(8.0)  # workers import and connect
        started = time.perf_counter()
        for entry in campaign.records:
            broker.enqueue(dramatiq.Message(
                queue_name=queue, actor_name="process_record",
                args=(campaign.id, str(campaign.record_path(entry))),
                kwargs={"taken_at": entry.taken_at}, options={}))
        while True:
            with engine.connect() as connection:
                done = connection.execute(sa.text(
                    "SELECT count(*) FROM result_versions")).scalar() or 0
                rejected = connection.execute(sa.text(
                    "SELECT count(*) FROM records WHERE status = 'rejected'")).scalar() or 0
            if done + rejected >= len(campaign.records):
                break
            if time.perf_counter() - started > 1800:
                raise RuntimeError("timed out")
            time.sleep(0.1)
        elapsed = time.perf_counter() - started
        if rejected:
            print(f"  ({rejected} rejected)")
        engine.dispose()
        broker.close()
        return len(campaign.records) / elapsed
    finally:
        for process in processes:
            try:
                os.killpg(process.pid, signal.SIGTERM)
                process.wait(timeout=60)
            except ProcessLookupError:
                pass
        connection = pika.BlockingConnection(pika.URLParameters(broker_url))
        channel = connection.channel()
        for name in (queue, f"{queue}.DQ", f"{queue}.XQ"):
            channel.queue_delete(name)
        connection.close()
        with admin.connect() as connection:
            connection.execute(sa.text(f'DROP SCHEMA IF EXISTS "{schema}" CASCADE'))
        admin.dispose()


def main() -> None:
    import tempfile

    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--records", type=int, default=24)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2, 4])
    parser.add_argument("--db", default="postgresql+psycopg://postgres@127.0.0.1:5432/test")
    parser.add_argument("--broker", default="amqp://guest:guest@127.0.0.1:5672/")
    parser.add_argument("--rigs", type=int, default=50)
    parser.add_argument("--every-minutes", type=float, default=10.0)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        tmp = Path(folder)
        manifest = write_campaign(tmp / "campaign", args.records, args.seconds)
        print(f"{args.records} records of {args.seconds:g} s at {RATE_HZ} Hz, "
              f"{os.cpu_count()} CPU(s), load average {os.getloadavg()[0]:.1f}")
        print(f"{'workers':>8} {'records/s':>10} {'s/record':>9}")
        rates = {}
        for workers in args.workers:
            rates[workers] = run(workers, manifest, args.db, args.broker, tmp)
            print(f"{workers:>8} {rates[workers]:>10.2f} {1 / rates[workers]:>9.2f}")
    needed = args.rigs * 60.0 / args.every_minutes / 3600.0
    best = max(rates.values())
    print(f"lab: {args.rigs} rigs x one {args.seconds:g} s record every {args.every_minutes:g} min"
          f" = {needed:.3f} records/s needed; best measured {best:.2f} records/s = "
          f"{best / needed:.0f}x headroom")


if __name__ == "__main__":
    main()
