"""Assemble the rig's CAN FD frames into records, checking for gaps and duplicates.

:class:`RecordAssembler` is fed one :class:`can.Message` at a time (live bus or log
file) and returns an :class:`AssembledRecord` whenever a record closes. A record
with a missing frame (sequence-counter gap, missing control frame, counts in
``RecordStop`` not matching) is *rejected* with a reason naming what is missing and
keeps its raw frames; it is never stitched. Exact duplicate frames are dropped and
counted; two different frames with the same sequence number reject the record.

The hot path (``SampleBlock`` frames) only appends the frame to the open record;
decoding happens once per record with :func:`~ingest.can.protocol.decode_sample_blocks`.
"""

from __future__ import annotations

import datetime as dt
import json
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import can
import numpy as np

from gearwatch.floor.campaign import RecordData
from ingest.can import protocol as p

Status = Literal["accepted", "rejected"]
MAX_LISTED_RANGES = 8


@dataclass
class AssembledRecord:
    """One record closed by the assembler: accepted with its data, or rejected with a reason."""

    record: RecordData | None
    """The record's data; ``None`` when rejected."""
    status: Status
    reason: str | None
    """Why the record was rejected (``None`` when accepted)."""
    raw_frames: list[can.Message]
    """Every frame of the record as received, duplicates included (for storage of rejects)."""
    metadata: dict[str, str] = field(default_factory=dict)
    """What is known about the record even when rejected: record id, start time, counts."""

    @property
    def accepted(self) -> bool:
        return self.status == "accepted"

    def write_raw(self, path: str | Path) -> Path:
        """Write :attr:`raw_frames` to a BLF, ASC or candump ``.log`` file (by suffix)."""
        from ingest.can.logs import write_can_log

        return write_can_log(path, self.raw_frames)


@dataclass
class AssemblerStats:
    """Counters over the assembler's life."""

    frames: int = 0
    protocol_frames: int = 0
    foreign_frames: int = 0
    """Frames with ids outside the protocol, error and remote frames (ignored)."""
    duplicates_dropped: int = 0
    records_accepted: int = 0
    records_rejected: int = 0


class _RecordRejected(Exception):
    pass


@dataclass
class _OpenRecord:
    header: p.RecordHeader
    header_bytes: bytes
    frames: list[can.Message]
    frame_count: int = 1
    blocks: list[bytes | bytearray] = field(default_factory=list)
    channels: dict[int, p.ChannelDescription] = field(default_factory=dict)
    meta_chunks: dict[int, bytes] = field(default_factory=dict)
    meta_chunk_count: int | None = None
    tach: list[dict[str, Any]] = field(default_factory=list)
    duplicates: int = 0
    problems: list[str] = field(default_factory=list)


def _ranges(numbers: np.ndarray) -> str:
    """``[3, 4, 5, 9]`` → ``"3-5, 9"`` (at most MAX_LISTED_RANGES ranges)."""
    numbers = np.unique(numbers)
    if numbers.size == 0:
        return "none"
    breaks = np.flatnonzero(np.diff(numbers) != 1) + 1
    parts = []
    for run in np.split(numbers, breaks)[:MAX_LISTED_RANGES]:
        parts.append(f"{run[0]}" if run.size == 1 else f"{run[0]}-{run[-1]}")
    more = len(breaks) + 1 - MAX_LISTED_RANGES
    return ", ".join(parts) + (f" and {more} more range(s)" if more > 0 else "")


def _start_time_text(start_time_us: int) -> str:
    """ISO 8601 of the RecordStart time, or ``"invalid (<µs>)"`` for a time past year 9999 (a
    corrupt frame must reject its record with a reason, not stop the receiver)."""
    try:
        start = dt.datetime.fromtimestamp(start_time_us / 1e6, tz=dt.UTC)
    except (ValueError, OverflowError, OSError):
        return f"invalid ({start_time_us} µs)"
    return start.isoformat(timespec="microseconds")


def _unwrap_sequence(sequence: np.ndarray) -> np.ndarray:
    """Block indices from 16-bit sequence counters (consecutive frames differ by < 32768)."""
    s = sequence.astype(np.int64)
    if s.size == 0:
        return s
    steps = (np.diff(s) + SEQ_HALF) % p.SEQUENCE_MODULUS - SEQ_HALF
    first = s[0] if s[0] < SEQ_HALF else s[0] - p.SEQUENCE_MODULUS
    return np.concatenate(([first], first + np.cumsum(steps)))


SEQ_HALF = p.SEQUENCE_MODULUS // 2


def _check_sequence(
    sequence: np.ndarray, payload_rows: np.ndarray, what: str
) -> tuple[np.ndarray, int, int]:
    """Order of unique frames by sequence, number of exact duplicates dropped, frames out of order.

    Raises ``_RecordRejected`` naming the missing or conflicting sequence numbers.
    ``payload_rows`` holds one row of bytes per frame to tell duplicates from conflicts.
    """
    index = _unwrap_sequence(sequence)
    order = np.argsort(index, kind="stable")
    out_of_order = int(np.count_nonzero(np.diff(order) != 1)) if order.size > 1 else 0
    sorted_index = index[order]
    repeated = np.flatnonzero(np.diff(sorted_index) == 0) + 1
    if repeated.size:
        rows = payload_rows[order]
        conflicts = repeated[np.any(rows[repeated] != rows[repeated - 1], axis=-1)]
        if conflicts.size:
            numbers = sorted_index[conflicts] % p.SEQUENCE_MODULUS
            raise _RecordRejected(
                f"{what}: different frames with the same sequence number(s) {_ranges(numbers)}"
            )
    keep = np.ones(order.size, dtype=bool)
    keep[repeated] = False
    unique_index = sorted_index[keep]
    if unique_index.size and (unique_index[0] < 0 or unique_index[-1] != unique_index.size - 1):
        expected = np.arange(max(int(unique_index[-1]) + 1, 0))
        missing = np.setdiff1d(expected, unique_index)
        detail = (
            f"sequence number(s) {_ranges(missing % p.SEQUENCE_MODULUS)} missing "
            f"({missing.size} frame(s))"
            if missing.size
            else f"sequence starts at {int(unique_index[0]) % p.SEQUENCE_MODULUS}, not 0"
        )
        raise _RecordRejected(f"gap in {what}: {detail}")
    return order[keep], int(repeated.size), out_of_order


class RecordAssembler:
    """Turn a stream of protocol frames into :class:`AssembledRecord` objects.

    Parameters
    ----------
    source : str
        Bus or file description, copied into ``RecordData.source``.
    keep_accepted_raw_frames : bool
        Keep ``raw_frames`` for accepted records too.
    keep_raw_frames : bool
        Keep the frames of open records so that a rejected record returns them (default).
        ``False`` saves memory when the frames are stored elsewhere (reading a log file).

    Examples
    --------
    >>> from ingest.can.emulator import record_frames
    >>> record = RecordData({"acc": np.linspace(-1.0, 1.0, 100)}, sample_rate_hz=1000.0)
    >>> assembler = RecordAssembler(source="doc")
    >>> out = [r for _, m in record_frames(record, record_id=1) for r in assembler.feed(m)]
    >>> out[0].status, out[0].record.channels["acc"].size
    ('accepted', 100)
    """

    def __init__(
        self,
        *,
        source: str = "can",
        keep_accepted_raw_frames: bool = False,
        keep_raw_frames: bool = True,
    ) -> None:
        self.source = source
        self.keep_raw_frames = keep_raw_frames
        self.keep_accepted_raw_frames = keep_accepted_raw_frames and keep_raw_frames
        self.stats = AssemblerStats()
        self._open: _OpenRecord | None = None
        self._orphans: list[can.Message] = []
        self._last_control: dict[int, bytes] = {}

    def feed(self, msg: can.Message) -> list[AssembledRecord]:
        """Take one frame; return the records it closes (usually none)."""
        open_record = self._open
        if (
            msg.arbitration_id == p.SAMPLE_BLOCK_ID
            and open_record is not None
            and not msg.is_extended_id
            and not msg.is_error_frame
        ):
            # hot path: decoded in bulk when the record closes
            self.stats.frames += 1
            self.stats.protocol_frames += 1
            open_record.frame_count += 1
            if self.keep_raw_frames:
                open_record.frames.append(msg)
            open_record.blocks.append(msg.data)
            return []
        return self._feed_other(msg)

    def feed_many(self, messages: Iterable[can.Message]) -> list[AssembledRecord]:
        """Feed every frame; return the records they close."""
        closed: list[AssembledRecord] = []
        for msg in messages:
            closed.extend(self.feed(msg))
        return closed

    def flush(self, why: str = "stream ended before RecordStop") -> list[AssembledRecord]:
        """End of stream: an open record is rejected with ``why``; stray frames are reported."""
        closed = self._close_orphans("frames outside any record (RecordStart lost?)")
        if self._open is not None:
            closed.append(self._reject(self._open, why))
            self._open = None
        return closed

    # -- slow path: control frames, tach frames, stray frames --------------------------------

    def _feed_other(self, msg: can.Message) -> list[AssembledRecord]:
        self.stats.frames += 1
        aid = msg.arbitration_id
        if (
            aid not in p.PROTOCOL_IDS
            or msg.is_extended_id
            or msg.is_error_frame
            or msg.is_remote_frame
        ):
            self.stats.foreign_frames += 1
            return []
        self.stats.protocol_frames += 1
        closed: list[AssembledRecord] = []
        if aid == p.RECORD_START_ID:
            return self._on_start(msg)
        open_record = self._open
        if open_record is None:
            if aid == p.RECORD_STOP_ID and self._last_control.get(aid) == bytes(msg.data):
                self.stats.duplicates_dropped += 1  # repeated stop of the record just closed
                return closed
            self._orphans.append(msg)
            if aid == p.RECORD_STOP_ID:
                record_id = self._try_decode(msg).get("RecordId", "?")
                closed.extend(
                    self._close_orphans(f"RecordStart of record {record_id} missing (lost frame?)")
                )
            return closed
        open_record.frame_count += 1
        if self.keep_raw_frames:
            open_record.frames.append(msg)
        if aid == p.SAMPLE_BLOCK_ID:
            open_record.blocks.append(msg.data)
            return closed
        if len(msg.data) != p.FRAME_BYTES:
            open_record.problems.append(f"frame 0x{aid:03X} with {len(msg.data)} data bytes, not 64")
            return closed
        signals = self._try_decode(msg)
        if aid == p.TACH_EDGES_ID:
            open_record.tach.append(signals)
        elif aid == p.CHANNEL_INFO_ID:
            self._on_channel_info(open_record, signals)
        elif aid == p.RECORD_META_ID:
            self._on_meta(open_record, signals)
        elif aid == p.RECORD_STOP_ID:
            self._last_control[aid] = bytes(msg.data)
            self._open = None
            closed.append(self._close(open_record, p.RecordStopInfo.from_signals(signals)))
        return closed

    @staticmethod
    def _try_decode(msg: can.Message) -> dict[str, Any]:
        try:
            return p.decode(msg.arbitration_id, msg.data)
        except Exception:
            return {}

    def _on_start(self, msg: can.Message) -> list[AssembledRecord]:
        closed = self._close_orphans("frames outside any record (RecordStart lost?)")
        data = bytes(msg.data)
        open_record = self._open
        if open_record is not None:
            if open_record.header_bytes == data:
                open_record.frame_count += 1
                if self.keep_raw_frames:
                    open_record.frames.append(msg)
                open_record.duplicates += 1
                self.stats.duplicates_dropped += 1
                return closed
            next_id = self._try_decode(msg).get("RecordId", "?")
            closed.append(
                self._reject(
                    open_record,
                    f"no RecordStop before RecordStart of record {next_id} "
                    "(RecordStop lost?)",
                )
            )
            self._open = None
        try:
            header = p.RecordHeader.from_signals(p.decode(msg.arbitration_id, msg.data))
        except Exception as error:
            self._orphans.append(msg)
            closed.extend(self._close_orphans(f"RecordStart cannot be decoded: {error}"))
            return closed
        self._open = _OpenRecord(
            header=header, header_bytes=data, frames=[msg] if self.keep_raw_frames else []
        )
        if header.protocol_version != p.PROTOCOL_VERSION:
            self._open.problems.append(
                f"protocol version {header.protocol_version}, expected {p.PROTOCOL_VERSION}"
            )
        return closed

    def _on_channel_info(self, record: _OpenRecord, signals: dict[str, Any]) -> None:
        try:
            info = p.ChannelDescription.from_signals(signals)
        except (KeyError, ValueError) as error:
            record.problems.append(f"bad ChannelInfo: {error}")
            return
        if info.record_id != record.header.record_id:
            record.problems.append(f"ChannelInfo of record {info.record_id}")
        known = record.channels.get(info.channel_id)
        if known is not None:
            if known == info:
                record.duplicates += 1
                self.stats.duplicates_dropped += 1
            else:
                record.problems.append(f"two different ChannelInfo for channel {info.channel_id}")
            return
        record.channels[info.channel_id] = info

    def _on_meta(self, record: _OpenRecord, signals: dict[str, Any]) -> None:
        index = int(signals.get("ChunkIndex", -1))
        text = p.meta_chunk_text(signals) if signals else b""
        if int(signals.get("RecordId", -1)) != record.header.record_id:
            record.problems.append(f"RecordMeta of record {signals.get('RecordId', '?')}")
            return
        record.meta_chunk_count = int(signals["ChunkCount"])
        if index in record.meta_chunks:
            if record.meta_chunks[index] == text:
                record.duplicates += 1
                self.stats.duplicates_dropped += 1
            else:
                record.problems.append(f"two different RecordMeta chunks {index}")
            return
        record.meta_chunks[index] = text

    # -- closing --------------------------------------------------------------------------

    def _close_orphans(self, reason: str) -> list[AssembledRecord]:
        if not self._orphans:
            return []
        frames, self._orphans = self._orphans, []
        self.stats.records_rejected += 1
        return [
            AssembledRecord(
                None,
                "rejected",
                f"{len(frames)} frame(s) without an open record: {reason}",
                frames,
                {"can_frames": str(len(frames))},
            )
        ]

    def _base_metadata(self, record: _OpenRecord) -> dict[str, str]:
        header = record.header
        return {
            "can_record_id": str(header.record_id),
            "can_start_time": _start_time_text(header.start_time_us),
            "can_frames": str(record.frame_count),
        }

    def _reject(self, record: _OpenRecord, reason: str) -> AssembledRecord:
        self.stats.records_rejected += 1
        metadata = self._base_metadata(record)
        metadata["can_duplicates_dropped"] = str(record.duplicates)
        return AssembledRecord(
            None,
            "rejected",
            f"record {record.header.record_id}: {reason}",
            record.frames,
            metadata,
        )

    def _close(self, record: _OpenRecord, stop: p.RecordStopInfo) -> AssembledRecord:
        try:
            data = self._assemble(record, stop)
        except _RecordRejected as error:
            return self._reject(record, str(error))
        self.stats.records_accepted += 1
        raw = record.frames if self.keep_accepted_raw_frames else []
        return AssembledRecord(data, "accepted", None, raw, dict(data.metadata))

    def _assemble(self, record: _OpenRecord, stop: p.RecordStopInfo) -> RecordData:
        header = record.header
        if stop.record_id != header.record_id:
            raise _RecordRejected(f"RecordStop of record {stop.record_id} closes it (frames lost?)")
        if stop.aborted:
            raise _RecordRejected("the rig aborted the record (RecordStop reason 'aborted')")
        if record.problems:
            raise _RecordRejected("; ".join(record.problems))
        missing_info = sorted(set(range(header.channel_count)) - set(record.channels))
        if missing_info:
            raise _RecordRejected(f"ChannelInfo missing for channel id(s) {missing_info}")
        if not header.sample_rate_hz > 0:
            raise _RecordRejected(f"sample rate {header.sample_rate_hz} Hz")
        metadata = self._metadata(record)

        waveforms, block_frames, samples = self._waveforms(record)
        pulse_times, tach_frames, edges = self._tach(record)
        for what, announced, received in (
            ("SampleBlock frames", stop.block_frame_count, block_frames),
            ("TachEdges frames", stop.tach_frame_count, tach_frames),
            ("tachometer edges", stop.tach_edge_count, edges),
            ("samples", stop.sample_count, samples),
        ):
            if announced != received:
                raise _RecordRejected(
                    f"RecordStop announces {announced} {what}, {received} received "
                    "(frames lost at the end of a channel)"
                )
        channels: dict[str, np.ndarray] = {}
        kinds: dict[str, str] = {}
        for channel_id in sorted(record.channels):
            info = record.channels[channel_id]
            if info.name in channels:
                raise _RecordRejected(f"two channels named {info.name!r}")
            channels[info.name] = (
                waveforms.get(channel_id, np.zeros(0))
                if info.is_waveform
                else pulse_times.get(channel_id, np.zeros(0))
            )
            kinds[info.name] = info.kind
        metadata.update(self._base_metadata(record))
        if metadata["can_start_time"].startswith("invalid"):
            raise _RecordRejected(f"RecordStart StartTime {header.start_time_us} µs is not a time")
        metadata["can_channel_kinds"] = json.dumps(kinds, sort_keys=True)
        metadata["can_pulses_per_rev"] = str(header.pulses_per_rev)
        metadata["can_tach_shaft"] = header.tach_shaft
        if header.tach_channel_id in record.channels:
            metadata["can_tach_channel"] = record.channels[header.tach_channel_id].name
        metadata["can_duplicates_dropped"] = str(record.duplicates)
        metadata.setdefault("taken_at", metadata["can_start_time"])
        return RecordData(
            channels=channels,
            sample_rate_hz=header.sample_rate_hz,
            source=f"{self.source} record {header.record_id}",
            metadata=metadata,
        )

    def _metadata(self, record: _OpenRecord) -> dict[str, str]:
        count = record.meta_chunk_count
        if record.header.metadata_bytes == 0 and not record.meta_chunks:
            return {}
        if count is None:
            raise _RecordRejected("RecordMeta frames missing")
        missing = sorted(set(range(count)) - set(record.meta_chunks))
        if missing:
            raise _RecordRejected(f"RecordMeta chunk(s) {missing} of {count} missing")
        text = b"".join(record.meta_chunks[i] for i in range(count))[: record.header.metadata_bytes]
        try:
            decoded = json.loads(text.decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as error:
            raise _RecordRejected(f"record metadata is not JSON: {error}") from None
        if not isinstance(decoded, dict):
            raise _RecordRejected("record metadata is not a JSON object")
        return {str(k): str(v) for k, v in decoded.items()}

    def _waveforms(self, record: _OpenRecord) -> tuple[dict[int, np.ndarray], int, int]:
        short = [len(b) for b in record.blocks if len(b) != p.FRAME_BYTES]
        if short:
            raise _RecordRejected(f"{len(short)} SampleBlock frame(s) with {short[0]} data bytes, not 64")
        payload = b"".join(record.blocks)
        record.blocks.clear()  # the joined copy is all that is needed from here on
        blocks = p.decode_sample_blocks(payload)
        rows = blocks.view(np.uint8).reshape(-1, p.FRAME_BYTES)
        waveforms: dict[int, np.ndarray] = {}
        frames = 0
        samples = 0
        for channel_id in np.unique(blocks["channel_id"]).tolist():
            info = record.channels.get(channel_id)
            if info is None or not info.is_waveform:
                raise _RecordRejected(f"SampleBlock frames for channel id {channel_id}, not a waveform channel")
            mine = np.flatnonzero(blocks["channel_id"] == channel_id)
            what = f"channel {channel_id} ({info.name!r}) SampleBlock frames"
            keep, duplicates, _ = _check_sequence(blocks["sequence"][mine], rows[mine], what)
            record.duplicates += duplicates
            self.stats.duplicates_dropped += duplicates
            ordered = blocks[mine[keep]]
            counts = ordered["sample_count"]
            if counts.size and (
                np.any(counts[:-1] != p.SAMPLES_PER_BLOCK) or not 1 <= counts[-1] <= p.SAMPLES_PER_BLOCK
            ):
                bad = np.flatnonzero(counts[:-1] != p.SAMPLES_PER_BLOCK)
                if bad.size == 0:  # only the last block is wrong
                    raise _RecordRejected(
                        f"{what}: the last block holds {int(counts[-1])} samples, expected "
                        f"1 to {p.SAMPLES_PER_BLOCK}"
                    )
                raise _RecordRejected(
                    f"{what}: short block inside the record at sequence "
                    f"{_ranges(ordered['sequence'][bad])}"
                )
            total = (counts.size - 1) * p.SAMPLES_PER_BLOCK + int(counts[-1])
            raw_counts = ordered["samples"].reshape(-1)[:total]
            del ordered
            waveforms[channel_id] = p.dequantise(raw_counts, info.scale, info.offset)
            frames += counts.size
            samples += total
        return waveforms, frames, samples

    def _tach(self, record: _OpenRecord) -> tuple[dict[int, np.ndarray], int, int]:
        times: dict[int, np.ndarray] = {}
        frames = 0
        edges = 0
        if not record.tach:
            return times, 0, 0
        if any(not s for s in record.tach):
            raise _RecordRejected("a TachEdges frame cannot be decoded")
        channel_ids = np.array([s["ChannelId"] for s in record.tach])
        edge_cols = [f"EdgeTime{k}" for k in range(p.EDGES_PER_FRAME)]
        fields = ["Sequence", "ChannelId", "EdgeCount", "FirstEdgeIndex", "Revolution", *edge_cols]
        table = np.array([[int(s[f]) for f in fields] for s in record.tach], dtype=np.int64)
        for channel_id in np.unique(channel_ids).tolist():
            info = record.channels.get(channel_id)
            if info is None or info.is_waveform:
                raise _RecordRejected(f"TachEdges frames for channel id {channel_id}, not a pulse-time channel")
            what = f"channel {channel_id} ({info.name!r}) TachEdges frames"
            mine = table[channel_ids == channel_id]
            keep, duplicates, _ = _check_sequence(mine[:, 0], mine, what)
            record.duplicates += duplicates
            self.stats.duplicates_dropped += duplicates
            ordered = mine[keep]
            count = ordered[:, 2]
            first = ordered[:, 3]
            if np.any(count < 1) or np.any(count > p.EDGES_PER_FRAME):
                raise _RecordRejected(f"{what}: edge count outside 1..{p.EDGES_PER_FRAME}")
            expected_first = np.concatenate(([0], np.cumsum(count)[:-1]))
            if np.any(first != expected_first):
                at = int(np.flatnonzero(first != expected_first)[0])
                raise _RecordRejected(
                    f"{what}: edge index {first[at]} where {expected_first[at]} was expected"
                )
            ppr = max(record.header.pulses_per_rev, 1)
            if np.any(ordered[:, 4] != first // ppr):
                raise _RecordRejected(f"{what}: revolution counter disagrees with the edge index")
            valid = np.arange(p.EDGES_PER_FRAME) < count[:, None]
            ticks = ordered[:, 5:][valid]
            times[channel_id] = ticks.astype(np.float64) * p.EDGE_TIME_TICK_S
            frames += ordered.shape[0]
            edges += ticks.size
        return times, frames, edges
