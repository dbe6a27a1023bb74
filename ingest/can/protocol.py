"""The rig's CAN FD protocol (``gearwatch.dbc``): frame ids, layouts, encoders and the fast decoder.

Every frame is a 64-byte CAN FD frame with an 11-bit id, all signals little-endian:

==========  ===========  ==============================================================
id          message      content
==========  ===========  ==============================================================
``0x0A0``   TachEdges    up to 8 tachometer edge times (48-bit ns) + revolution counter
``0x0C0``   SampleBlock  30 int16 samples of one waveform channel + sequence, channel id
``0x0E0``   RecordStart  record id, sample rate, start time, channel count, pulses/rev
``0x0E1``   ChannelInfo  per channel: name, kind, scale factor, offset, unit
``0x0E2``   RecordMeta   record metadata as JSON text, 56 bytes per chunk
``0x0E3``   RecordStop   frame/edge/sample counts the receiver checks
==========  ===========  ==============================================================

The control frames (rare) are encoded and decoded with cantools from the DBC. The
``SampleBlock`` frames carry the bulk of the data; their layout is mirrored here as a
numpy structured dtype so that a whole record's blocks decode in one ``np.frombuffer``
call (tests check the fast path against cantools on the same frames).
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from importlib import resources
from typing import Any, Literal

import can
import cantools
import numpy as np
from cantools.database.can import Database

PROTOCOL_VERSION = 1
TACH_EDGES_ID = 0x0A0
SAMPLE_BLOCK_ID = 0x0C0
RECORD_START_ID = 0x0E0
CHANNEL_INFO_ID = 0x0E1
RECORD_META_ID = 0x0E2
RECORD_STOP_ID = 0x0E3
PROTOCOL_IDS = frozenset(
    {TACH_EDGES_ID, SAMPLE_BLOCK_ID, RECORD_START_ID, CHANNEL_INFO_ID, RECORD_META_ID, RECORD_STOP_ID}
)

FRAME_BYTES = 64
SAMPLES_PER_BLOCK = 30
EDGES_PER_FRAME = 8
META_BYTES_PER_CHUNK = 56
NAME_BYTES = 32
UNIT_BYTES = 8
SEQUENCE_MODULUS = 1 << 16
NO_VALUE_COUNT = -32768
"""int16 count that stands for NaN; -32767 and 32767 stand for -inf and +inf."""
NEG_INF_COUNT = -32767
POS_INF_COUNT = 32767
MAX_COUNT = 32766
"""Finite samples use the counts -32766..32766."""
NO_TACH_CHANNEL = 255
EDGE_TIME_TICK_S = 1e-9
MAX_EDGE_TICKS = (1 << 48) - 1

ChannelKind = Literal["accelerometer", "tachometer_waveform", "tachometer_pulse_times", "waveform"]
CHANNEL_KIND_CODES: dict[str, int] = {
    "accelerometer": 0,
    "tachometer_waveform": 1,
    "tachometer_pulse_times": 2,
    "waveform": 3,
}
CHANNEL_KINDS_BY_CODE: dict[int, str] = {code: kind for kind, code in CHANNEL_KIND_CODES.items()}
TACH_SHAFT_CODES: dict[str, int] = {"pinion": 0, "gear": 1}

SAMPLE_BLOCK_DTYPE = np.dtype(
    [
        ("sequence", "<u2"),
        ("channel_id", "u1"),
        ("sample_count", "u1"),
        ("samples", "<i2", (SAMPLES_PER_BLOCK,)),
    ]
)
"""Byte layout of a ``SampleBlock`` payload, identical to the DBC signals (64 bytes)."""
assert SAMPLE_BLOCK_DTYPE.itemsize == FRAME_BYTES


@functools.cache
def load_dbc() -> Database:
    """The project's DBC (``ingest/can/gearwatch.dbc``), parsed once.

    Examples
    --------
    >>> load_dbc().get_message_by_name("SampleBlock").frame_id == SAMPLE_BLOCK_ID
    True
    """
    text = resources.files("ingest.can").joinpath("gearwatch.dbc").read_text(encoding="utf-8")
    database = cantools.database.load_string(text, database_format="dbc")
    assert isinstance(database, Database)
    return database


def fd_message(arbitration_id: int, data: bytes, timestamp: float = 0.0) -> can.Message:
    """A 64-byte CAN FD frame (bit-rate switch on) with an 11-bit id."""
    return can.Message(
        arbitration_id=arbitration_id,
        data=data,
        is_extended_id=False,
        is_fd=True,
        bitrate_switch=True,
        timestamp=timestamp,
        check=False,
    )


def pack_text(text: bytes, size: int) -> list[int]:
    """Split ``text`` (at most ``size`` bytes, NUL padded) into little-endian uint64 signal values."""
    if len(text) > size:
        raise ValueError(f"text of {len(text)} bytes does not fit in {size} bytes")
    padded = text.ljust(size, b"\0")
    return [int.from_bytes(padded[i : i + 8], "little") for i in range(0, size, 8)]


def unpack_text(values: list[int]) -> bytes:
    """Inverse of :func:`pack_text` (trailing NULs removed)."""
    return b"".join(int(v).to_bytes(8, "little") for v in values).rstrip(b"\0")


def encode(name: str, signals: dict[str, Any]) -> bytes:
    """Encode one control frame with cantools (strict range checks)."""
    message = load_dbc().get_message_by_name(name)
    return bytes(message.encode(signals, scaling=False, padding=True, strict=True))


def decode(arbitration_id: int, data: bytes | bytearray) -> dict[str, Any]:
    """Decode one frame with cantools to raw (unscaled) signal values."""
    message = load_dbc().get_message_by_frame_id(arbitration_id)
    decoded = message.decode(bytes(data), decode_choices=False, scaling=False)
    assert isinstance(decoded, dict)
    return decoded


@dataclass(frozen=True)
class RecordHeader:
    """The decoded ``RecordStart`` frame."""

    record_id: int
    protocol_version: int
    channel_count: int
    pulses_per_rev: int
    sample_rate_hz: float
    start_time_us: int
    tach_channel_id: int
    tach_shaft: str
    metadata_bytes: int

    @classmethod
    def from_signals(cls, s: dict[str, Any]) -> RecordHeader:
        shafts = {code: shaft for shaft, code in TACH_SHAFT_CODES.items()}
        return cls(
            record_id=int(s["RecordId"]),
            protocol_version=int(s["ProtocolVersion"]),
            channel_count=int(s["ChannelCount"]),
            pulses_per_rev=int(s["PulsesPerRev"]),
            sample_rate_hz=float(s["SampleRate"]),
            start_time_us=int(s["StartTime"]),
            tach_channel_id=int(s["TachChannelId"]),
            tach_shaft=shafts.get(int(s["TachShaft"]), "pinion"),
            metadata_bytes=int(s["MetadataBytes"]),
        )

    def encode(self) -> bytes:
        return encode(
            "RecordStart",
            {
                "RecordId": self.record_id,
                "ProtocolVersion": self.protocol_version,
                "ChannelCount": self.channel_count,
                "PulsesPerRev": self.pulses_per_rev,
                "SampleRate": self.sample_rate_hz,
                "StartTime": self.start_time_us,
                "TachChannelId": self.tach_channel_id,
                "TachShaft": TACH_SHAFT_CODES[self.tach_shaft],
                "MetadataBytes": self.metadata_bytes,
            },
        )


@dataclass(frozen=True)
class ChannelDescription:
    """The decoded ``ChannelInfo`` frame."""

    record_id: int
    channel_id: int
    kind: str
    name: str
    unit: str
    scale: float
    offset: float

    @property
    def is_waveform(self) -> bool:
        return self.kind != "tachometer_pulse_times"

    @classmethod
    def from_signals(cls, s: dict[str, Any]) -> ChannelDescription:
        code = int(s["ChannelKind"])
        if code not in CHANNEL_KINDS_BY_CODE:
            raise ValueError(f"unknown channel kind code {code}")
        return cls(
            record_id=int(s["RecordId"]),
            channel_id=int(s["ChannelId"]),
            kind=CHANNEL_KINDS_BY_CODE[code],
            name=unpack_text([s[f"Name{k}"] for k in range(4)]).decode("utf-8", "replace"),
            unit=unpack_text([s["Unit"]]).decode("utf-8", "replace"),
            scale=float(s["Scale"]),
            offset=float(s["Offset"]),
        )

    def encode(self) -> bytes:
        name = pack_text(self.name.encode("utf-8"), NAME_BYTES)
        signals: dict[str, Any] = {
            "RecordId": self.record_id,
            "ChannelId": self.channel_id,
            "ChannelKind": CHANNEL_KIND_CODES[self.kind],
            "Scale": self.scale,
            "Offset": self.offset,
            "Unit": pack_text(self.unit.encode("utf-8"), UNIT_BYTES)[0],
        }
        signals.update({f"Name{k}": value for k, value in enumerate(name)})
        return encode("ChannelInfo", signals)


@dataclass(frozen=True)
class RecordStopInfo:
    """The decoded ``RecordStop`` frame."""

    record_id: int
    block_frame_count: int
    tach_frame_count: int
    tach_edge_count: int
    sample_count: int
    aborted: bool

    @classmethod
    def from_signals(cls, s: dict[str, Any]) -> RecordStopInfo:
        return cls(
            record_id=int(s["RecordId"]),
            block_frame_count=int(s["BlockFrameCount"]),
            tach_frame_count=int(s["TachFrameCount"]),
            tach_edge_count=int(s["TachEdgeCount"]),
            sample_count=int(s["SampleCount"]),
            aborted=int(s["StopReason"]) != 0,
        )

    def encode(self) -> bytes:
        return encode(
            "RecordStop",
            {
                "RecordId": self.record_id,
                "BlockFrameCount": self.block_frame_count,
                "TachFrameCount": self.tach_frame_count,
                "TachEdgeCount": self.tach_edge_count,
                "SampleCount": self.sample_count,
                "StopReason": 1 if self.aborted else 0,
            },
        )


def encode_metadata(record_id: int, metadata: dict[str, str]) -> tuple[int, list[bytes]]:
    """``RecordMeta`` payloads carrying ``metadata`` as JSON; returns (text bytes, payloads)."""
    text = json.dumps(metadata, ensure_ascii=False, sort_keys=True).encode("utf-8")
    if len(text) > 0xFFFF:
        raise ValueError(f"record metadata is {len(text)} bytes as JSON; the protocol carries 65535")
    chunk_count = max(1, -(-len(text) // META_BYTES_PER_CHUNK))
    payloads = []
    for index in range(chunk_count):
        chunk = text[index * META_BYTES_PER_CHUNK : (index + 1) * META_BYTES_PER_CHUNK]
        signals: dict[str, Any] = {
            "RecordId": record_id,
            "ChunkIndex": index,
            "ChunkCount": chunk_count,
        }
        signals.update(
            {f"Text{k}": v for k, v in enumerate(pack_text(chunk, META_BYTES_PER_CHUNK))}
        )
        payloads.append(encode("RecordMeta", signals))
    return len(text), payloads


def meta_chunk_text(signals: dict[str, Any]) -> bytes:
    """The 56 text bytes of one decoded ``RecordMeta`` frame (NUL padding kept)."""
    return b"".join(int(signals[f"Text{k}"]).to_bytes(8, "little") for k in range(7))


def encode_sample_blocks(counts: np.ndarray, channel_id: int) -> list[bytes]:
    """``SampleBlock`` payloads for one channel's int16 counts, sequence 0, 1, … (mod 65536).

    Examples
    --------
    >>> payloads = encode_sample_blocks(np.arange(31, dtype=np.int16), channel_id=2)
    >>> len(payloads), len(payloads[0])
    (2, 64)
    >>> decode_sample_blocks(b"".join(payloads))["sample_count"].tolist()
    [30, 1]
    """
    counts = np.asarray(counts, dtype=np.int16)
    block_count = -(-counts.size // SAMPLES_PER_BLOCK)
    blocks = np.zeros(block_count, dtype=SAMPLE_BLOCK_DTYPE)
    blocks["sequence"] = np.arange(block_count) % SEQUENCE_MODULUS
    blocks["channel_id"] = channel_id
    blocks["sample_count"] = SAMPLES_PER_BLOCK
    if block_count:
        blocks["sample_count"][-1] = counts.size - (block_count - 1) * SAMPLES_PER_BLOCK
    padded = np.zeros(block_count * SAMPLES_PER_BLOCK, dtype=np.int16)
    padded[: counts.size] = counts
    blocks["samples"] = padded.reshape(block_count, SAMPLES_PER_BLOCK)
    raw = blocks.tobytes()
    return [raw[i : i + FRAME_BYTES] for i in range(0, len(raw), FRAME_BYTES)]


def decode_sample_blocks(payloads: bytes) -> np.ndarray:
    """Decode concatenated 64-byte ``SampleBlock`` payloads in one call (the fast path).

    Returns a structured array with fields ``sequence``, ``channel_id``, ``sample_count``
    and ``samples`` (int16, shape ``(n, 30)``), equal to what cantools decodes frame by frame.
    """
    if len(payloads) % FRAME_BYTES:
        raise ValueError(f"{len(payloads)} bytes is not a whole number of {FRAME_BYTES}-byte blocks")
    return np.frombuffer(payloads, dtype=SAMPLE_BLOCK_DTYPE)


def encode_tach_frames(
    edge_ticks: np.ndarray, channel_id: int, pulses_per_rev: int, group_sizes: list[int]
) -> list[bytes]:
    """``TachEdges`` payloads: consecutive edges (ns ticks) split into frames of ``group_sizes``."""
    payloads = []
    first = 0
    for sequence, size in enumerate(group_sizes):
        if not 1 <= size <= EDGES_PER_FRAME:
            raise ValueError(f"a TachEdges frame carries 1..{EDGES_PER_FRAME} edges, not {size}")
        signals: dict[str, Any] = {
            "Sequence": sequence % SEQUENCE_MODULUS,
            "ChannelId": channel_id,
            "EdgeCount": size,
            "FirstEdgeIndex": first,
            "Revolution": first // max(pulses_per_rev, 1),
        }
        for k in range(EDGES_PER_FRAME):
            signals[f"EdgeTime{k}"] = int(edge_ticks[first + k]) if k < size else 0
        payloads.append(encode("TachEdges", signals))
        first += size
    if first != len(edge_ticks):
        raise ValueError("group sizes do not add up to the number of edges")
    return payloads


def quantise(values: np.ndarray) -> tuple[np.ndarray, float, float]:
    """int16 counts, scale and offset with ``values ≈ offset + scale * counts``.

    The counts -32766..32766 span [min, max] of the finite samples, so the error is at most
    ``scale / 2`` with ``scale = (max - min) / 65532``; NaN, -inf and +inf travel as the
    reserved counts -32768, -32767 and 32767 and come back unchanged.

    Examples
    --------
    >>> counts, scale, offset = quantise(np.array([-1.0, 0.0, 1.0, np.nan]))
    >>> counts.tolist(), scale == 2 / 65532, offset
    ([-32766, 0, 32766, -32768], True, 0.0)
    """
    values = np.asarray(values, dtype=np.float64)
    finite = np.isfinite(values)
    counts = np.full(values.shape, NO_VALUE_COUNT, dtype=np.int16)
    counts[values == np.inf] = POS_INF_COUNT
    counts[values == -np.inf] = NEG_INF_COUNT
    if not finite.any():
        return counts, 1.0, 0.0
    low = float(values[finite].min())
    high = float(values[finite].max())
    offset = 0.5 * (low + high)
    scale = (high - low) / (2 * MAX_COUNT) if high > low else 1.0
    scaled = np.rint((values[finite] - offset) / scale)
    counts[finite] = np.clip(scaled, -MAX_COUNT, MAX_COUNT).astype(np.int16)
    return counts, scale, offset


def exact_counts(values: np.ndarray, scale: float | None = None) -> tuple[np.ndarray, float] | None:
    """int16 counts with ``values == scale * counts`` exactly, or ``None`` when there are none.

    A DAQ delivers integer counts times a fixed count size: PCM WAV reads as
    ``count / 32768``, an ADC as ``count * LSB``. Such samples cross the bus bit-exactly
    when their counts are sent with that count size and offset 0, instead of being
    re-quantised over the channel's range (:func:`quantise`). Without ``scale``, the
    count size tried is the smallest power of two that keeps the largest finite sample
    within the finite counts ``-MAX_COUNT..MAX_COUNT``: power-of-two multiples of any
    coarser power-of-two count size are whole multiples of it too, and a finer one would
    need counts beyond int16. ``scale * count`` is then exact in float64 (a 16-bit integer
    times a power of two), so :func:`dequantise` gives the samples back bit for bit; with a
    given ``scale`` that is checked sample by sample. NaN and infinities travel as the
    reserved counts, as in :func:`quantise`.

    Examples
    --------
    >>> pcm = np.array([-32766, -1, 0, 3, 32766], dtype=np.int16)
    >>> samples = pcm.astype(np.float32) / np.float32(32768)  # what the WAV reader returns
    >>> counts, scale = exact_counts(samples)
    >>> counts.tolist(), scale == 2.0**-15
    ([-32766, -1, 0, 3, 32766], True)
    >>> bool((dequantise(counts, scale, 0.0) == samples).all())
    True
    >>> exact_counts(np.array([0.1, 0.2])) is None  # not whole multiples of a power of two
    True
    """
    values = np.asarray(values, dtype=np.float64)
    finite = np.isfinite(values)
    finite_values = values[finite]
    largest = float(np.abs(finite_values).max()) if finite_values.size else 0.0
    if scale is None:
        if largest == 0.0:
            scale = 1.0
        else:
            # frexp gives largest / MAX_COUNT = mantissa * 2**exponent, mantissa in [0.5, 1):
            # 2**exponent is the smallest power of two with largest / 2**exponent <= MAX_COUNT.
            mantissa, exponent = np.frexp(largest / MAX_COUNT)
            scale = float(np.ldexp(1.0, int(exponent) - 1 if mantissa == 0.5 else int(exponent)))
            if largest / scale > MAX_COUNT:  # the division above rounded down
                scale *= 2.0
    if not (np.isfinite(scale) and scale > 0) or largest / scale > MAX_COUNT:
        return None
    whole = np.rint(finite_values / scale)
    if not np.array_equal(whole * scale, finite_values):
        return None
    counts = np.full(values.shape, NO_VALUE_COUNT, dtype=np.int16)
    counts[values == np.inf] = POS_INF_COUNT
    counts[values == -np.inf] = NEG_INF_COUNT
    counts[finite] = whole.astype(np.int16)
    return counts, scale


def dequantise(counts: np.ndarray, scale: float, offset: float) -> np.ndarray:
    """float64 physical values of int16 counts; the reserved counts become NaN, -inf, +inf."""
    values = counts.astype(np.float64)
    values *= scale  # in place: one float64 array per channel, no temporaries
    values += offset
    values[counts == NO_VALUE_COUNT] = np.nan
    values[counts == NEG_INF_COUNT] = -np.inf
    values[counts == POS_INF_COUNT] = np.inf
    return values
