"""Ingest over CAN FD: the rig protocol (``gearwatch.dbc``), live assembly, emulator, CAN logs.

=================  =================================================================
module             content
=================  =================================================================
``protocol``       frame ids, DBC loading, encoders, numpy fast decode of SampleBlock
``assembler``      :class:`RecordAssembler` frames → :class:`AssembledRecord`
``emulator``       :func:`record_frames`, :func:`emulate`: play records onto a bus
``live``           :func:`open_bus`, :func:`listen`: live ingest with a callback
``logs``           BLF / ASC / candump ``.log`` readers (registered) and writer
=================  =================================================================

Importing this package registers the CAN log readers with :mod:`ingest.sources`.
"""

from __future__ import annotations

from ingest.can.assembler import AssembledRecord, AssemblerStats, RecordAssembler
from ingest.can.emulator import EmulationStats, emulate, record_frames
from ingest.can.live import listen, open_bus
from ingest.can.logs import (
    CanLogReader,
    iter_can_log,
    read_can_log,
    read_can_log_records,
    write_can_log,
)
from ingest.can.protocol import load_dbc

__all__ = [
    "AssembledRecord",
    "AssemblerStats",
    "CanLogReader",
    "EmulationStats",
    "RecordAssembler",
    "emulate",
    "iter_can_log",
    "listen",
    "load_dbc",
    "open_bus",
    "read_can_log",
    "read_can_log_records",
    "record_frames",
    "write_can_log",
]
