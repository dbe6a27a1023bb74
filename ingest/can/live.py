"""Live ingest from a CAN FD bus: open a python-can bus and hand assembled records to a callback."""

from __future__ import annotations

import socket
import threading
from collections.abc import Callable
from typing import Any

import can

from ingest.can.assembler import AssembledRecord, AssemblerStats, RecordAssembler

UDP_RECEIVE_BUFFER_BYTES = 4 << 20
"""Socket receive buffer asked for on ``udp_multicast`` (the kernel caps it at net.core.rmem_max)."""


def open_bus(interface: str, channel: str, **options: Any) -> can.BusABC:
    """A python-can bus in CAN FD mode, e.g. ``open_bus("socketcan", "can0")``,
    ``open_bus("virtual", "rig")`` or ``open_bus("udp_multicast", "239.74.163.2")``.

    On ``udp_multicast`` the socket's receive buffer is enlarged: UDP drops datagrams when
    the receiver falls behind, and a larger buffer absorbs the bursts of a fast sender (the
    assembler still detects any loss). Raises :class:`gearwatch.floor.errors.InputError` when
    python-can cannot open the bus.
    """
    from gearwatch.floor.errors import InputError

    try:
        bus = can.Bus(interface=interface, channel=channel, fd=True, **options)
    except (can.CanError, ImportError, OSError, ValueError) as error:
        raise InputError(f"cannot open CAN bus {interface}:{channel}: {error}") from error
    if interface == "udp_multicast":
        sock = getattr(getattr(bus, "_multicast", None), "_socket", None)
        if isinstance(sock, socket.socket):
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, UDP_RECEIVE_BUFFER_BYTES)
    return bus


def listen(
    bus: can.BusABC,
    on_record: Callable[[AssembledRecord], None],
    *,
    stop_event: threading.Event,
    assembler: RecordAssembler | None = None,
    poll_timeout_s: float = 0.05,
    max_records: int | None = None,
    idle_timeout_s: float | None = None,
) -> AssemblerStats:
    """Receive frames until ``stop_event`` is set, calling ``on_record`` for each closed record.

    Parameters
    ----------
    bus : can.BusABC
        The bus to read (the caller opens and shuts it down).
    on_record : callable
        Called in this thread with every :class:`AssembledRecord` (accepted or rejected).
    stop_event : threading.Event
        Set it (from another thread or from ``on_record``) to stop; an open record is then
        reported rejected ("listening stopped before RecordStop").
    max_records : int, optional
        Stop by itself after this many records.
    idle_timeout_s : float, optional
        Stop by itself after this long without any frame.
    """
    assembler = assembler or RecordAssembler(source=f"{bus.channel_info}")
    records = 0
    recv = bus.recv
    feed = assembler.feed
    idle_s = 0.0
    while not stop_event.is_set():
        msg = recv(poll_timeout_s)
        if msg is None:
            idle_s += poll_timeout_s
            if idle_timeout_s is not None and idle_s >= idle_timeout_s:
                break
            continue
        idle_s = 0.0
        closed = feed(msg)
        for record in closed:
            on_record(record)
            records += 1
        if max_records is not None and records >= max_records:
            break
    for record in assembler.flush("listening stopped before RecordStop"):
        on_record(record)
    return assembler.stats
