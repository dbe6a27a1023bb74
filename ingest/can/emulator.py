"""Rig emulator: play records onto a CAN FD bus with the rig's protocol.

:func:`record_frames` turns a :class:`~gearwatch.floor.campaign.RecordData` into the frame sequence a
rig would send, each frame stamped with the time (after the record's first sample) at
which the rig has its data: a ``SampleBlock`` when its 30th sample is acquired, a
``TachEdges`` frame at its last edge. :func:`emulate` sends those frames on a python-can
bus at real speed (``speed=1``), accelerated (``speed=10``) or as fast as possible
(``speed=0``) with flow control: a full transmit queue is waited out, never dropped.

Waveforms travel as int16 counts per channel. Samples that already are whole counts of a
power-of-two count size (what a DAQ gives: PCM WAV reads as ``count / 32768``) or of a count
size given in ``count_scales`` are sent as those counts, bit-exactly
(:func:`ingest.can.protocol.exact_counts`); any other waveform is quantised over its range
(:func:`ingest.can.protocol.quantise`: error at most half a count, ``(max - min) / 131064``).
Pulse times travel in 1 ns ticks.
"""

from __future__ import annotations

import datetime as dt
import json
import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

import can
import numpy as np

from gearwatch.floor.campaign import Campaign, RecordData
from ingest.can import protocol as p

TACH_FRAME_MAX_SPAN_S = 0.05
"""A rig flushes its tach edges at least every 50 ms, so a TachEdges frame spans at most this."""


@dataclass
class EmulationStats:
    records: int = 0
    frames: int = 0
    send_retries: int = 0
    """Times a send found the transmit queue full and waited (flow control)."""
    elapsed_s: float = 0.0

    @property
    def frames_per_s(self) -> float:
        return self.frames / self.elapsed_s if self.elapsed_s > 0 else float("inf")


def channel_kinds_for(
    record: RecordData,
    tach_channel: str | None = None,
    tach_kind: str = "pulses",
) -> dict[str, str]:
    """Protocol channel kinds: from the record's ``can_channel_kinds`` metadata if present,
    else ``tach_channel`` as tachometer (``tach_kind`` ``"pulses"`` or ``"pulse_times"``) and
    every other channel an accelerometer."""
    if "can_channel_kinds" in record.metadata and tach_channel is None:
        kinds = json.loads(record.metadata["can_channel_kinds"])
        if set(kinds) == set(record.channels):
            return {str(k): str(v) for k, v in kinds.items()}
    if tach_channel is not None and tach_channel not in record.channels:
        raise ValueError(f"tachometer channel {tach_channel!r} not in the record")
    if tach_kind not in ("pulses", "pulse_times"):
        raise ValueError(f"tachometer kind {tach_kind!r}: expected 'pulses' or 'pulse_times'")
    tach = "tachometer_pulse_times" if tach_kind == "pulse_times" else "tachometer_waveform"
    return {name: tach if name == tach_channel else "accelerometer" for name in record.channels}


def _start_time_us(record: RecordData, start_time: dt.datetime | None) -> int:
    if start_time is None:
        text = record.metadata.get("taken_at") or record.metadata.get("can_start_time")
        if text:
            try:
                start_time = dt.datetime.fromisoformat(text)
            except ValueError:
                start_time = None
    if start_time is None:
        start_time = dt.datetime.now(dt.UTC)
    if start_time.tzinfo is None:
        start_time = start_time.replace(tzinfo=dt.UTC)
    delta = start_time - dt.datetime(1970, 1, 1, tzinfo=dt.UTC)
    return (delta.days * 86_400 + delta.seconds) * 1_000_000 + delta.microseconds


def _tach_groups(times_s: np.ndarray) -> list[int]:
    """Edge counts per TachEdges frame: at most 8 edges spanning at most 50 ms."""
    sizes: list[int] = []
    start = 0
    n = times_s.size
    while start < n:
        stop = start + 1
        while (
            stop < n
            and stop - start < p.EDGES_PER_FRAME
            and times_s[stop] - times_s[start] <= TACH_FRAME_MAX_SPAN_S
        ):
            stop += 1
        sizes.append(stop - start)
        start = stop
    return sizes


def record_frames(
    record: RecordData,
    *,
    record_id: int,
    channel_kinds: Mapping[str, str] | None = None,
    tach_channel: str | None = None,
    tach_kind: str = "pulses",
    pulses_per_rev: int = 1,
    tach_shaft: str = "pinion",
    units: Mapping[str, str] | None = None,
    start_time: dt.datetime | None = None,
    aborted: bool = False,
    count_scales: Mapping[str, float] | None = None,
) -> list[tuple[float, can.Message]]:
    """The frames a rig sends for ``record``, each with its send time in seconds.

    Parameters
    ----------
    record : RecordData
        Waveform channels of equal length at ``record.sample_rate_hz``; a pulse-time channel
        holds edge times in seconds (>= 0) after the first sample.
    record_id : int
        Record number (0 .. 2**32 - 1).
    channel_kinds : mapping, optional
        Protocol kind per channel name (``accelerometer``, ``tachometer_waveform``,
        ``tachometer_pulse_times``, ``waveform``); default from :func:`channel_kinds_for`.
    tach_channel, tach_kind
        Used when ``channel_kinds`` is not given.
    pulses_per_rev, tach_shaft
        Sent in ``RecordStart`` (the revolution counter of ``TachEdges`` uses the former).
    units : mapping, optional
        Unit per channel name (up to 8 bytes).
    start_time : datetime, optional
        Time of the first sample; default the record's ``taken_at`` metadata, else now.
    aborted : bool
        Send ``RecordStop`` with reason "aborted" (the receiver rejects the record).
    count_scales : mapping, optional
        Count size (physical units per count) per waveform channel name, e.g. the ADC's LSB:
        the channel's samples must be whole multiples of it within int16 and are sent
        bit-exactly (``ValueError`` otherwise). Channels not named here are sent exactly when
        they are whole counts of a power of two, else quantised over their range.

    Returns
    -------
    list of (time_s, can.Message)
        Sorted by time: ``RecordStart``, ``ChannelInfo``, ``RecordMeta`` at ``t < 0``, then
        data frames, then ``RecordStop``.

    Examples
    --------
    >>> record = RecordData({"acc": np.zeros(61)}, sample_rate_hz=1000.0)
    >>> [f"{m.arbitration_id:03X}" for _, m in record_frames(record, record_id=5)]
    ['0E0', '0E1', '0E2', '0C0', '0C0', '0C0', '0E3']
    """
    kinds = dict(channel_kinds) if channel_kinds is not None else channel_kinds_for(
        record, tach_channel, tach_kind
    )
    names = list(record.channels)
    if len(names) > 254:
        raise ValueError(f"{len(names)} channels: the protocol carries at most 254")
    unknown = set(kinds) ^ set(names)
    if unknown:
        raise ValueError(f"channel kinds do not match the channels: {sorted(unknown)}")
    if not record.sample_rate_hz > 0:
        raise ValueError(f"sample rate {record.sample_rate_hz} Hz")
    units = units or {}
    metadata = {k: v for k, v in record.metadata.items() if not k.startswith("can_")}
    metadata_bytes, meta_payloads = p.encode_metadata(record_id, metadata)
    tach_ids = [i for i, n in enumerate(names) if kinds[n].startswith("tachometer")]
    header = p.RecordHeader(
        record_id=record_id,
        protocol_version=p.PROTOCOL_VERSION,
        channel_count=len(names),
        pulses_per_rev=pulses_per_rev,
        sample_rate_hz=float(record.sample_rate_hz),
        start_time_us=_start_time_us(record, start_time),
        tach_channel_id=tach_ids[0] if tach_ids else p.NO_TACH_CHANNEL,
        tach_shaft=tach_shaft,
        metadata_bytes=metadata_bytes,
    )
    times: list[np.ndarray] = [np.array([-3.0])]
    ids: list[int] = [p.RECORD_START_ID]
    payloads: list[bytes] = [header.encode()]
    block_frames = tach_frames = tach_edges = samples = 0
    data_times: list[np.ndarray] = []
    data_payloads: list[bytes] = []
    data_ids: list[int] = []
    end_s = 0.0
    for channel_id, name in enumerate(names):
        values = np.asarray(record.channels[name], dtype=np.float64).reshape(-1)
        kind = kinds[name]
        if kind == "tachometer_pulse_times":
            if values.size and (not np.all(np.isfinite(values)) or values.min() < 0):
                raise ValueError(f"pulse times of {name!r} must be finite and >= 0")
            if np.any(np.diff(values) < 0):
                raise ValueError(f"pulse times of {name!r} are not sorted")
            ticks = np.rint(values * 1e9).astype(np.int64)
            if ticks.size and ticks.max() > p.MAX_EDGE_TICKS:
                raise ValueError(f"pulse times of {name!r} exceed the 48-bit ns range (78 h)")
            groups = _tach_groups(values)
            frames = p.encode_tach_frames(ticks, channel_id, pulses_per_rev, groups)
            last = np.cumsum(groups) - 1
            data_times.append(values[last] if frames else np.zeros(0))
            scale, offset = 1.0, 0.0
            tach_frames += len(frames)
            tach_edges += values.size
            data_ids.extend([p.TACH_EDGES_ID] * len(frames))
            if values.size:
                end_s = max(end_s, float(values[-1]))
        else:
            counts, scale, offset = _waveform_counts(name, values, (count_scales or {}).get(name))
            frames = p.encode_sample_blocks(counts, channel_id)
            sample_end = np.minimum(
                (np.arange(len(frames)) + 1) * p.SAMPLES_PER_BLOCK, values.size
            )
            data_times.append(sample_end / record.sample_rate_hz)
            block_frames += len(frames)
            samples += values.size
            data_ids.extend([p.SAMPLE_BLOCK_ID] * len(frames))
            end_s = max(end_s, values.size / record.sample_rate_hz)
        data_payloads.extend(frames)
        info = p.ChannelDescription(
            record_id, channel_id, kind, name, units.get(name, ""), scale, offset
        )
        times.append(np.array([-2.0]))
        ids.append(p.CHANNEL_INFO_ID)
        payloads.append(info.encode())
    times.append(np.full(len(meta_payloads), -1.0))
    ids.extend([p.RECORD_META_ID] * len(meta_payloads))
    payloads.extend(meta_payloads)
    times.extend(data_times)
    ids.extend(data_ids)
    payloads.extend(data_payloads)
    stop = p.RecordStopInfo(record_id, block_frames, tach_frames, tach_edges, samples, aborted)
    times.append(np.array([end_s]))
    ids.append(p.RECORD_STOP_ID)
    payloads.append(stop.encode())
    all_times = np.concatenate(times)
    order = np.argsort(all_times, kind="stable")  # ties keep start < info < meta < data < stop
    send_times = np.maximum(all_times[order], 0.0).tolist()
    return [
        (t, p.fd_message(ids[i], payloads[i], timestamp=t))
        for t, i in zip(send_times, order.tolist(), strict=True)
    ]


def _waveform_counts(
    name: str, values: np.ndarray, count_scale: float | None
) -> tuple[np.ndarray, float, float]:
    """Counts, scale and offset of one waveform: exact counts when there are, else quantised."""
    exact = p.exact_counts(values, count_scale)
    if exact is not None:
        counts, scale = exact
        return counts, scale, 0.0
    if count_scale is not None:
        raise ValueError(
            f"samples of {name!r} are not whole multiples of the count size {count_scale!r} "
            f"within int16 (|count| <= {p.MAX_COUNT})"
        )
    return p.quantise(values)


def send_with_flow_control(
    bus: can.BusABC, msg: can.Message, stats: EmulationStats, give_up_s: float = 5.0
) -> None:
    """Send, waiting while the transmit queue is full (ENOBUFS on socketcan) instead of dropping."""
    deadline = None
    delay = 1e-4
    while True:
        try:
            bus.send(msg, timeout=give_up_s)
            return
        except can.CanOperationError:
            now = time.perf_counter()
            deadline = deadline or now + give_up_s
            if now > deadline:
                raise
            stats.send_retries += 1
            time.sleep(delay)
            delay = min(delay * 2, 0.01)


def emulate(
    bus: can.BusABC,
    records: RecordData | Iterable[RecordData],
    *,
    speed: float = 1.0,
    first_record_id: int = 1,
    max_frames_per_s: float | None = None,
    pause_between_records_s: float = 0.0,
    channel_kinds: Mapping[str, str] | None = None,
    tach_channel: str | None = None,
    tach_kind: str = "pulses",
    pulses_per_rev: int = 1,
    tach_shaft: str = "pinion",
    units: Mapping[str, str] | None = None,
    start_time: dt.datetime | None = None,
    count_scales: Mapping[str, float] | None = None,
) -> EmulationStats:
    """Play records onto ``bus`` like a rig.

    Parameters
    ----------
    bus : can.BusABC
        Any python-can bus opened with ``fd=True`` (socketcan, virtual, udp_multicast ...).
    records : RecordData or iterable of RecordData
        Played one after the other with record ids ``first_record_id``, +1, ...
    speed : float
        1 = real time, 10 = ten times faster, 0 = as fast as the bus accepts frames.
    max_frames_per_s : float, optional
        Cap on the frame rate (flow control for receivers that drop when flooded, such as
        UDP multicast sockets).
    channel_kinds, tach_channel, tach_kind, pulses_per_rev, tach_shaft, units, start_time
        Passed to :func:`record_frames` for every record.
    count_scales
        Passed to :func:`record_frames` for every record.
    """
    if speed < 0:
        raise ValueError(f"speed {speed} < 0")
    if isinstance(records, RecordData):
        records = [records]
    stats = EmulationStats()
    began = time.perf_counter()
    for offset, record in enumerate(records):
        frames = record_frames(
            record,
            record_id=first_record_id + offset,
            channel_kinds=channel_kinds,
            tach_channel=tach_channel,
            tach_kind=tach_kind,
            pulses_per_rev=pulses_per_rev,
            tach_shaft=tach_shaft,
            units=units,
            start_time=start_time,
            count_scales=count_scales,
        )
        t0 = time.perf_counter()
        if speed == 0 and not max_frames_per_s:
            send = bus.send
            for _, msg in frames:  # tight loop: nothing to pace
                try:
                    send(msg)
                except can.CanOperationError:  # transmit queue full: wait, never drop
                    send_with_flow_control(bus, msg, stats)
        else:
            for index, (t_s, msg) in enumerate(frames):
                target = t0 + t_s / speed if speed > 0 else t0
                if max_frames_per_s:
                    target = max(target, t0 + index / max_frames_per_s)
                ahead = target - time.perf_counter()
                if ahead > 0.001:  # sleeping per frame costs more than a frame at these rates
                    time.sleep(ahead)
                send_with_flow_control(bus, msg, stats)
        stats.frames += len(frames)
        stats.records += 1
        if pause_between_records_s:
            time.sleep(pause_between_records_s)
    stats.elapsed_s = time.perf_counter() - began
    return stats


def load_records(
    paths: Iterable[str | Path], campaign: Campaign
) -> Iterable[RecordData]:
    """Read record files through the reader registry (any registered format), lazily."""
    from ingest.sources import read_record

    for path in paths:
        yield read_record(path, campaign)
