"""CAN log files (BLF, ASC, candump ``.log``) of the rig's protocol, read as records.

Reading goes through python-can's log readers and :class:`RecordAssembler`, so a log
is checked exactly like a live bus: a log with a lost frame is refused, naming the
missing sequence numbers. A log must hold exactly one record (``gearwatch listen-can``
writes one file per record); :func:`read_can_log_records` returns every record of a
longer log.
"""

from __future__ import annotations

import copy
from collections.abc import Iterable, Iterator
from pathlib import Path

import can

from gearwatch.floor.campaign import Campaign, RecordData
from gearwatch.floor.errors import RecordFormatError
from ingest.can.assembler import AssembledRecord, RecordAssembler
from ingest.readers._common import channel_not_found, is_pulse_times
from ingest.sources import declared_channel_names, register_reader

LOG_SUFFIXES = (".blf", ".asc", ".log")


def _suffix(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix not in LOG_SUFFIXES:
        raise RecordFormatError(f"{path}: not a CAN log (suffixes: {', '.join(LOG_SUFFIXES)})")
    return suffix


def iter_can_log(path: str | Path) -> Iterator[can.Message]:
    """Frames of a BLF, ASC or candump ``.log`` file, one at a time."""
    path = Path(path)
    suffix = _suffix(path)
    reader: Iterable[can.Message]
    if suffix == ".blf":
        reader = can.BLFReader(path)
    elif suffix == ".asc":
        reader = can.ASCReader(path)
    else:
        reader = can.CanutilsLogReader(path)
    with reader as frames:
        yield from frames


def write_can_log(path: str | Path, messages: Iterable[can.Message]) -> Path:
    """Write frames to a BLF, ASC or candump ``.log`` file chosen by the suffix."""
    path = Path(path)
    suffix = _suffix(path)
    writer: can.io.generic.MessageWriter
    if suffix == ".blf":
        writer = can.BLFWriter(path)
    elif suffix == ".asc":
        writer = can.ASCWriter(path)
    else:
        writer = can.CanutilsLogWriter(path, channel="can0")
    with writer:
        for msg in messages:
            writer.on_message_received(_loggable(msg))
    return path


def _loggable(msg: can.Message) -> can.Message:
    """The frame, with a bus channel name the writers cannot store as a number removed.

    BLF and ASC store the channel as a small integer taken from the trailing digits of
    the name: a virtual bus called ``rig-20250101`` would overflow it.
    """
    channel = can.util.channel2int(msg.channel)
    if msg.channel is None or (channel is not None and 0 <= channel <= 255):
        return msg
    copied = copy.copy(msg)
    copied.channel = None
    return copied


def read_can_log_records(path: str | Path, *, keep_raw_frames: bool = False) -> list[AssembledRecord]:
    """Every record of a CAN log, accepted or rejected (frames outside records reported too)."""
    assembler = RecordAssembler(source=str(path), keep_raw_frames=keep_raw_frames)
    records: list[AssembledRecord] = []
    for msg in iter_can_log(path):
        records.extend(assembler.feed(msg))
    records.extend(assembler.flush("the log ends before RecordStop"))
    return records


def read_can_log(path: str | Path) -> RecordData:
    """The single record of a CAN log; :class:`RecordFormatError` for none, several or a rejected one."""
    path = Path(path)
    try:
        records = read_can_log_records(path)
    except RecordFormatError:
        raise
    except Exception as error:
        raise RecordFormatError(
            f"{path}: cannot read as a CAN log: {type(error).__name__}: {error}"
        ) from error
    rejected = [r for r in records if not r.accepted]
    if rejected:
        raise RecordFormatError(f"{path}: {rejected[0].reason}")
    if not records:
        raise RecordFormatError(f"{path}: no record of the gearwatch CAN protocol in this log")
    if len(records) > 1:
        raise RecordFormatError(
            f"{path}: the log holds {len(records)} records; split it "
            "(ingest.can.logs.read_can_log_records reads them all)"
        )
    record = records[0].record
    assert record is not None
    record.source = str(path)
    return record


@register_reader
class CanLogReader:
    """BLF, ASC and candump ``.log`` files of the rig's CAN FD protocol."""

    suffixes = LOG_SUFFIXES

    def read(self, path: Path, campaign: Campaign) -> RecordData:
        record = read_can_log(path)
        kinds = _channel_kinds(record)
        channels = {}
        for name in declared_channel_names(campaign):
            if name not in record.channels:
                raise channel_not_found(path, name, record.channels)
            pulse_times = kinds.get(name) == "tachometer_pulse_times"
            if pulse_times != is_pulse_times(campaign, name):
                declared = "pulse_times" if is_pulse_times(campaign, name) else "a waveform"
                raise RecordFormatError(
                    f"{path}: channel {name!r} is {kinds.get(name)} on CAN but the manifest "
                    f"declares it {declared}"
                )
            channels[name] = record.channels[name]
        return RecordData(
            channels=channels,
            sample_rate_hz=record.sample_rate_hz,
            source=str(path),
            metadata={**record.metadata, "format": path.suffix.lower().lstrip(".")},
        )


def _channel_kinds(record: RecordData) -> dict[str, str]:
    import json

    kinds = json.loads(record.metadata.get("can_channel_kinds", "{}"))
    return {str(k): str(v) for k, v in kinds.items()}
