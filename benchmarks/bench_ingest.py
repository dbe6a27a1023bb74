"""Ingest throughput end to end: record file → read → pipeline → SQLite, per format; CAN FD via the bus.

Run: ``.venv/bin/python benchmarks/bench_ingest.py [--records 4] [--seconds 10] [--repeat 2]``

The simulator writes a campaign of ``--records`` daily records of ``--seconds`` each (20 kHz,
one accelerometer + a TTL tachometer, spall from the third record on). The same samples are
written in every file format the readers know (WAV float32 as the simulator writes it, WAV
16-bit PCM as a DAQ writes it, HDF5, TDMS, MAT v5, CSV.gz, BLF = the rig's CAN frames), each
with its own manifest, and every format is replayed with :func:`replay_campaign` (the per-record
job: keep the raw file, read, pipeline, store results, evaluate alarms; one transaction per
record) into a fresh SQLite database.

* real-time factor = record seconds / wall seconds of the whole replay (best of ``--repeat``);
* read ms = :func:`ingest.sources.read_record` alone, per record (the format-dependent part);
* CPU % = process CPU time / wall time (the machine is shared: wall time is noisy).

CAN FD: the PCM records are played by the rig emulator (``speed=0``) onto the python-can
``virtual`` bus; a listener thread assembles them live; the main thread writes each as the
CAN log ``gearwatch listen-can`` writes and runs the same job into a fresh SQLite database.
Frames/s = protocol frames sent / wall seconds from the first frame to the last commit. For
scale, the rig sends 20 kHz / 30 samples per frame = 667 frames/s per waveform channel.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import gzip
import queue
import statistics
import tempfile
import threading
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import scipy.io
import scipy.io.wavfile

from gearwatch.floor.campaign import Campaign, RecordData, RecordEntry
from gearwatch.usecases.replay import replay_campaign
from ingest.manifest import dump_manifest, load_manifest
from ingest.sources import read_record
from storage.db import open_database, session_scope
from storage.raw_store import RawStore

PCM_FULL_SCALE = {"acc": 64.0, "tach": 8.0}
"""DAQ input ranges (m/s², V) of the 16-bit PCM records."""


def write_wav_float32(path: Path, record: RecordData, names: list[str]) -> None:
    data = np.column_stack([np.asarray(record.channels[n], dtype=np.float32) for n in names])
    scipy.io.wavfile.write(path, round(record.sample_rate_hz), data)


def write_wav_pcm16(path: Path, record: RecordData, names: list[str]) -> None:
    columns = []
    for name in names:
        counts = np.rint(np.asarray(record.channels[name], np.float64) / PCM_FULL_SCALE[name] * 32768)
        if np.abs(counts).max() > 32766:
            raise SystemExit(f"{name}: beyond the PCM full scale {PCM_FULL_SCALE[name]}")
        columns.append(counts.astype(np.int16))
    scipy.io.wavfile.write(path, round(record.sample_rate_hz), np.column_stack(columns))


def write_hdf5_or_tdms(path: Path, record: RecordData, names: list[str]) -> None:
    from physics.recordio import write_record

    write_record(path, {n: np.asarray(record.channels[n], np.float64) for n in names},
                 record.sample_rate_hz)


def write_mat(path: Path, record: RecordData, names: list[str]) -> None:
    variables: dict[str, Any] = {n: np.asarray(record.channels[n], np.float64).reshape(-1, 1)
                                 for n in names}
    variables["fs"] = np.array([[record.sample_rate_hz]])
    scipy.io.savemat(path, variables)


def write_csv_gz(path: Path, record: RecordData, names: list[str]) -> None:
    data = np.column_stack([np.asarray(record.channels[n], np.float64) for n in names])
    with gzip.open(path, "wt", encoding="utf-8", compresslevel=6) as stream:
        stream.write(",".join(names) + "\n")
        np.savetxt(stream, data, delimiter=",", fmt="%.9g")


def write_blf(path: Path, record: RecordData, names: list[str], campaign: Campaign) -> None:
    from ingest.can.emulator import record_frames
    from ingest.can.logs import write_can_log

    tach = campaign.tachometer
    assert tach is not None
    frames = record_frames(record, record_id=1, tach_channel=tach.channel, tach_kind="pulses",
                           pulses_per_rev=tach.pulses_per_rev, tach_shaft=tach.shaft)
    write_can_log(path, [m for _, m in frames])


@dataclasses.dataclass
class Format:
    label: str
    suffix: str
    write: Callable[[Path, RecordData, list[str]], None]
    source: str = "float"
    """Which samples: ``float`` (the simulator's float32) or ``pcm`` (16-bit counts)."""


def formats(campaign: Campaign) -> list[Format]:
    return [
        Format("WAV float32", ".wav", write_wav_float32),
        Format("WAV PCM16", ".wav", write_wav_pcm16),
        Format("HDF5", ".h5", write_hdf5_or_tdms),
        Format("TDMS", ".tdms", write_hdf5_or_tdms),
        Format("MAT v5", ".mat", write_mat),
        Format("CSV.gz", ".csv.gz", write_csv_gz),
        Format("BLF (CAN)", ".blf", lambda p, r, n: write_blf(p, r, n, campaign), source="pcm"),
    ]


def campaign_in_format(base: Campaign, records: list[RecordData], fmt: Format,
                       folder: Path) -> Path:
    """The campaign's records written in ``fmt`` with a manifest listing them."""
    folder.mkdir(parents=True)
    names = [c.name for c in base.channels]
    entries = []
    for entry, record in zip(base.records, records, strict=True):
        file_name = Path(entry.file).name.split(".")[0] + fmt.suffix
        fmt.write(folder / file_name, record, names)
        entries.append(RecordEntry(file_name, entry.taken_at, entry.label))
    config = dataclasses.replace(base, records=tuple(entries), root=folder)
    manifest = folder / "campaign.toml"
    manifest.write_text(dump_manifest(config), encoding="utf-8")
    return manifest


def pcm_record(record: RecordData) -> RecordData:
    """The samples a 16-bit DAQ delivers (what the WAV reader returns for PCM)."""
    channels = {
        name: (np.rint(np.asarray(v, np.float64) / PCM_FULL_SCALE[name] * 32768)
               .astype(np.float32) / np.float32(32768))
        for name, v in record.channels.items()
    }
    return RecordData(channels, record.sample_rate_hz, record.source, dict(record.metadata))


def timed(function: Callable[[], Any]) -> tuple[float, float, Any]:
    """(wall s, CPU s, result)."""
    wall, cpu = time.perf_counter(), time.process_time()
    result = function()
    return time.perf_counter() - wall, time.process_time() - cpu, result


def bench_format(manifest: Path, work: Path, repeat: int) -> dict[str, float]:
    campaign = load_manifest(manifest)
    best: tuple[float, float] | None = None
    for attempt in range(repeat):
        engine, factory = open_database(f"sqlite:///{work / f'{attempt}.db'}")
        try:
            store = RawStore(work / f"raw{attempt}")
            wall, cpu, summary = timed(
                functools.partial(replay_campaign, manifest, factory, store, progress=False))
        finally:
            engine.dispose()
        accepted = summary.outcomes.get("accepted", 0)
        if accepted != len(campaign.records):
            raise SystemExit(f"{manifest}: {summary.outcomes} {summary.rejected}")
        if best is None or wall < best[0]:
            best = (wall, cpu)
    assert best is not None
    reads = []
    for entry in campaign.records:
        start = time.perf_counter()
        record = read_record(campaign.record_path(entry), campaign)
        for samples in record.channels.values():
            np.asarray(samples, dtype=np.float64)  # touch the data (memory-mapped readers)
        reads.append(time.perf_counter() - start)
    size = sum(campaign.record_path(e).stat().st_size for e in campaign.records)
    return {"wall_s": best[0], "cpu_s": best[1], "read_ms": 1e3 * statistics.median(reads),
            "mb_per_record": size / len(campaign.records) / 1e6}


def bench_can(campaign: Campaign, records: list[RecordData], work: Path) -> dict[str, float]:
    """Emulator → virtual bus → live assembly → CAN log → job → SQLite."""
    from gearwatch.cli.commands.listen_can import save
    from gearwatch.usecases.ingest_file import process_file
    from ingest.can.assembler import AssembledRecord, RecordAssembler
    from ingest.can.emulator import emulate
    from ingest.can.live import listen, open_bus

    tach = campaign.tachometer
    assert tach is not None
    channel = f"bench-ingest-{uuid.uuid4().hex}"
    sender, receiver = open_bus("virtual", channel), open_bus("virtual", channel)
    engine, factory = open_database(f"sqlite:///{work / 'can.db'}")
    store = RawStore(work / "raw-can")
    out = work / "can-records"
    out.mkdir()
    closed: queue.Queue[AssembledRecord | None] = queue.Queue()
    stop = threading.Event()
    stats: dict[str, Any] = {}

    def run_listener() -> None:
        try:
            stats["assembler"] = listen(
                receiver, closed.put, stop_event=stop, max_records=len(records),
                assembler=RecordAssembler(source="bench", keep_accepted_raw_frames=True),
                idle_timeout_s=60.0)
        finally:
            closed.put(None)

    def run_emulator() -> None:
        stats["emulator"] = emulate(sender, records, speed=0, tach_channel=tach.channel,
                                    tach_kind="pulses", pulses_per_rev=tach.pulses_per_rev,
                                    tach_shaft=tach.shaft)

    wall, cpu = time.perf_counter(), time.process_time()
    threads = [threading.Thread(target=run_listener), threading.Thread(target=run_emulator)]
    for thread in threads:
        thread.start()
    outcomes = []
    try:
        index = 0
        while (assembled := closed.get(timeout=300)) is not None:
            if not assembled.accepted:
                raise SystemExit(f"CAN record rejected: {assembled.reason}")
            index += 1
            path = save(assembled, out, "blf", index)
            with session_scope(factory) as session:
                outcomes.append(process_file(session, path, campaign, raw_store=store,
                                             label=assembled.metadata.get("label", "")).outcome)
    finally:
        stop.set()
        for thread in threads:
            thread.join()
        sender.shutdown()
        receiver.shutdown()
        engine.dispose()
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    if outcomes != ["accepted"] * len(records):
        raise SystemExit(f"CAN ingest: {outcomes}")
    emulated = stats["emulator"]
    return {"wall_s": wall, "cpu_s": cpu, "frames": emulated.frames,
            "send_s": emulated.elapsed_s}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--records", type=int, default=4, help="daily records (default 4)")
    parser.add_argument("--seconds", type=float, default=10.0, help="record length (default 10)")
    parser.add_argument("--repeat", type=int, default=2, help="replays per format (best kept)")
    parser.add_argument("--seed", type=int, default=3)
    args = parser.parse_args()

    from physics.campaign import write_campaign

    with tempfile.TemporaryDirectory(prefix="bench-ingest-") as tmp:
        work = Path(tmp)
        start = time.perf_counter()
        base_manifest = write_campaign(work / "sim", days=args.records, seconds=args.seconds,
                                       onset_day=min(3, args.records), seed=args.seed)
        base = load_manifest(base_manifest)
        simulated = [read_record(base.record_path(e), base) for e in base.records]
        pcm = [pcm_record(r) for r in simulated]
        record_s = sum(next(iter(r.channels.values())).size / r.sample_rate_hz for r in simulated)
        print(f"{args.records} simulated records of {args.seconds:g} s at "
              f"{simulated[0].sample_rate_hz:g} Hz ({', '.join(simulated[0].channels)}), "
              f"{record_s:g} record seconds; simulated in {time.perf_counter() - start:.1f} s")
        # Warm-up (imports, numba compilation, page cache) outside the timings.
        warm = campaign_in_format(base, simulated, formats(base)[0], work / "warm-up")
        bench_format(warm, warm.parent, 1)
        print()
        print("file ingest into SQLite (replay_campaign: keep raw file, read, pipeline, store, "
              f"alarms; best of {args.repeat})")
        print(f"{'format':<12} {'MB/record':>9} {'read ms':>8} {'wall s':>7} {'CPU %':>6} "
              f"{'real-time factor':>16}")
        for fmt in formats(base):
            manifest = campaign_in_format(base, pcm if fmt.source == "pcm" else simulated, fmt,
                                          work / fmt.label.replace(" ", "_").replace("(", "")
                                          .replace(")", ""))
            result = bench_format(manifest, manifest.parent, args.repeat)
            print(f"{fmt.label:<12} {result['mb_per_record']:>9.2f} {result['read_ms']:>8.1f} "
                  f"{result['wall_s']:>7.2f} {100 * result['cpu_s'] / result['wall_s']:>6.0f} "
                  f"{record_s / result['wall_s']:>16.1f}")

        entries = sorted(base.records, key=lambda e: e.taken_at)
        for record, entry in zip(pcm, entries, strict=True):
            record.metadata.update(taken_at=entry.taken_at, label=entry.label)
        can = bench_can(base, pcm, work)
        print()
        print("CAN FD end to end (emulator speed=0 → virtual bus → live assembly → BLF → job "
              "→ SQLite)")
        print(f"{'frames':>8} {'wall s':>7} {'CPU %':>6} {'frames/s':>9} "
              f"{'send-only frames/s':>18} {'real-time factor':>16}")
        print(f"{can['frames']:>8} {can['wall_s']:>7.2f} {100 * can['cpu_s'] / can['wall_s']:>6.0f} "
              f"{can['frames'] / can['wall_s']:>9.0f} {can['frames'] / can['send_s']:>18.0f} "
              f"{record_s / can['wall_s']:>16.1f}")


if __name__ == "__main__":
    main()
