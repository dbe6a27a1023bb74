"""CAN FD ingest throughput: frames/s sustained with zero loss, on one core.

Run: ``.venv/bin/python benchmarks/bench_can.py [--seconds 10] [--channels 4]``

A record of N accelerometer channels at 20 kHz (+ a pulse-time tachometer) is turned
into the rig protocol's frames by the emulator, then

* decode+assemble only: frames fed to :class:`RecordAssembler` from memory;
* cantools per frame: what decoding every SampleBlock with cantools alone would cost;
* over the ``virtual`` bus: emulator thread → python-can virtual bus → ``listen``;
* over ``udp_multicast`` (loopback): same, as fast as possible and with rate caps.

"zero loss" means the record came back *accepted* (no sequence gap, counts in
RecordStop matched). The process is pinned to one CPU, so sender and receiver share
one core. Real-time factor = frames/s ÷ the rig's rate (20 kHz / 30 samples per frame
= 667 frames/s per channel).
"""

from __future__ import annotations

import argparse
import os
import statistics
import threading
import time
import uuid

import numpy as np

from gearwatch.floor.campaign import RecordData
from ingest.can import protocol as p
from ingest.can.assembler import AssembledRecord, RecordAssembler
from ingest.can.emulator import emulate, record_frames
from ingest.can.live import listen, open_bus

FS_HZ = 20_000.0
TARGET_FPS = 20_000.0


def make_record(seconds: float, channels: int) -> RecordData:
    n = int(seconds * FS_HZ)
    rng = np.random.default_rng(0)
    data = {f"acc{i}": rng.standard_normal(n) for i in range(channels)}
    data["tach"] = np.arange(1, int(seconds * 30)) / 30.0
    return RecordData(data, FS_HZ, metadata={"taken_at": "2026-01-01T00:00:00+00:00"})




def bench_assemble(frames: list, repeats: int) -> tuple[float, bool]:
    rates = []
    ok = True
    for _ in range(repeats):
        assembler = RecordAssembler()
        feed = assembler.feed
        start = time.perf_counter()
        out: list[AssembledRecord] = []
        for msg in frames:
            closed = feed(msg)
            if closed:
                out.extend(closed)
        elapsed = time.perf_counter() - start
        ok = ok and len(out) == 1 and out[0].accepted
        rates.append(len(frames) / elapsed)
    return statistics.median(rates), ok


def bench_cantools(frames: list, limit: int = 3_000) -> float:
    db = p.load_dbc()
    blocks = [m for m in frames if m.arbitration_id == p.SAMPLE_BLOCK_ID][:limit]
    start = time.perf_counter()
    for msg in blocks:
        db.decode_message(msg.arbitration_id, msg.data)
    return len(blocks) / (time.perf_counter() - start)


def bench_bus(
    interface: str, channel: str, record: RecordData, max_fps: float | None, **bus_options: object
) -> tuple[float, bool, str]:
    sender = open_bus(interface, channel, **bus_options)
    receiver = open_bus(interface, channel, **bus_options)
    got: list[AssembledRecord] = []
    stop = threading.Event()
    times: dict[str, float] = {}

    def on_record(record: AssembledRecord) -> None:
        times["end"] = time.perf_counter()
        got.append(record)
        stop.set()

    def send() -> None:
        time.sleep(0.05)
        times["start"] = time.perf_counter()
        stats = emulate(
            sender,
            record,
            speed=0,
            max_frames_per_s=max_fps,
            tach_channel="tach",
            tach_kind="pulse_times",
        )
        times["frames"] = stats.frames

    thread = threading.Thread(target=send)
    thread.start()
    try:
        listen(receiver, on_record, stop_event=stop, idle_timeout_s=3.0)
    finally:
        thread.join()
        sender.shutdown()
        receiver.shutdown()
    if not got or "end" not in times:
        return 0.0, False, "no record closed"
    rate = times["frames"] / (times["end"] - times["start"])
    return rate, got[0].accepted, got[0].reason or ""


def bench_virtual_receive(record_frames_list: list) -> tuple[float, float, bool]:
    """Send everything first (the virtual bus queues it), then time send and receive+assemble apart."""
    channel = f"bench-{uuid.uuid4().hex}"
    sender = open_bus("virtual", channel)
    receiver = open_bus("virtual", channel)
    try:
        start = time.perf_counter()
        for msg in record_frames_list:
            sender.send(msg)
        send_fps = len(record_frames_list) / (time.perf_counter() - start)
        got: list[AssembledRecord] = []
        stop = threading.Event()

        def on_record(record: AssembledRecord) -> None:
            got.append(record)
            stop.set()

        start = time.perf_counter()
        listen(receiver, on_record, stop_event=stop, idle_timeout_s=1.0)
        receive_fps = len(record_frames_list) / (time.perf_counter() - start)
    finally:
        sender.shutdown()
        receiver.shutdown()
    return send_fps, receive_fps, bool(got) and got[0].accepted


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="record length (default 10 s)")
    parser.add_argument("--channels", type=int, default=4, help="accelerometer channels (default 4)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-udp", action="store_true")
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    record = make_record(args.seconds, args.channels)
    start = time.perf_counter()
    sent = record_frames(record, record_id=1, tach_channel="tach", tach_kind="pulse_times")
    frames = [m for _, m in sent]
    encode_fps = len(frames) / (time.perf_counter() - start)
    real_time_fps = args.channels * FS_HZ / p.SAMPLES_PER_BLOCK
    print(
        f"record: {args.channels} channels x {args.seconds:g} s at {FS_HZ:g} Hz + tach -> "
        f"{len(frames):,} frames; rig real time = {real_time_fps:,.0f} frames/s; one CPU"
    )
    rows: list[tuple[str, float, str]] = []
    rows.append(("emulator encode (record_frames)", encode_fps, "-"))
    fps, ok = bench_assemble(frames, args.repeats)
    rows.append(("decode+assemble only (numpy fast path)", fps, "yes" if ok else "NO"))
    rows.append(("cantools decode per SampleBlock (reference)", bench_cantools(frames), "-"))
    send_fps, receive_fps, ok = bench_virtual_receive(frames)
    rows.append(("virtual bus: send only (python-can deepcopy)", send_fps, "-"))
    rows.append(("virtual bus: recv+assemble only (queued)", receive_fps, "yes" if ok else "NO"))
    fps, ok, why = bench_bus("virtual", f"bench-{uuid.uuid4().hex}", record, None)
    rows.append(("virtual bus: emulator -> listen, speed 0", fps, "yes" if ok else f"NO ({why})"))
    if not args.no_udp:
        for cap in (None, 40_000.0, 20_000.0, 10_000.0):
            fps, ok, why = bench_bus(
                "udp_multicast", "239.74.163.2", record, cap, port=43_000 + int(cap or 0) % 1000
            )
            label = f"udp_multicast loopback, cap {cap:,.0f}/s" if cap else "udp_multicast loopback, no cap"
            rows.append((label, fps, "yes" if ok else f"NO ({why[:60]})"))
    print()
    print(f"| {'path':<46} | {'frames/s':>10} | {'x target':>8} | {'x real time':>11} | zero loss |")
    print(f"|{'-' * 48}|{'-' * 12}|{'-' * 10}|{'-' * 13}|-----------|")
    for label, fps, ok_text in rows:
        print(
            f"| {label:<46} | {fps:>10,.0f} | {fps / TARGET_FPS:>8.2f} | "
            f"{fps / real_time_fps:>11.1f} | {ok_text} |"
        )
    print(f"\ntarget {TARGET_FPS:,.0f} frames/s; real time = {args.channels} x 667 frames/s")


if __name__ == "__main__":
    main()
