"""Test-side flow control for lossy buses (``udp_multicast``): the sender waits, every
``window`` frames, until the receiver has taken every frame sent so far.

UDP drops datagrams when the receiving thread falls behind for longer than its socket buffer
lasts, which on a loaded machine is a matter of scheduling, not of gearwatch. The product
detects such a loss (the record is rejected with the missing sequence numbers, tested
elsewhere); tests that check the frames arrive *intact* need a lossless link, and a rate cap is
only a timing assumption. With at most ``window`` frames in flight (64 CAN FD datagrams, well
under the kernel's default 208 KiB receive buffer) nothing can be dropped however slow the
receiver is.
"""

from __future__ import annotations

import random
import threading
import time
from typing import Any, cast

import can

WINDOW_FRAMES = 64
WAIT_S = 120.0
"""A bound on a hang (a frame really lost), not a speed requirement: after it the sender goes
on and the assembler reports the loss."""


def random_group() -> str:
    """A multicast group of its own, so that concurrent test runs on one machine (same port by
    chance) do not hear each other's frames."""
    return f"239.74.{random.randint(0, 255)}.{random.randint(1, 254)}"


class _Link:
    def __init__(self) -> None:
        self.condition = threading.Condition()
        self.received = 0


class CountingReceiver:
    """Receiving side: a bus whose :meth:`recv` counts the frames taken."""

    def __init__(self, bus: can.BusABC, link: _Link) -> None:
        self.bus = bus
        self._link = link
        self.channel_info = bus.channel_info

    def recv(self, timeout: float | None = None) -> can.Message | None:
        msg = self.bus.recv(timeout)
        if msg is not None:
            with self._link.condition:
                self._link.received += 1
                self._link.condition.notify_all()
        return msg

    def __getattr__(self, name: str) -> Any:
        return getattr(self.bus, name)


class WindowedSender:
    """Sending side: :meth:`send` blocks every ``window`` frames until all were received."""

    def __init__(self, bus: can.BusABC, link: _Link, window: int) -> None:
        self.bus = bus
        self._link = link
        self._window = window
        self.sent = 0
        self.channel_info = bus.channel_info

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.bus.send(msg, timeout)
        self.sent += 1
        if self.sent % self._window == 0:
            self.wait_received()

    def wait_received(self) -> bool:
        """Wait until every frame sent so far was received (``False`` after :data:`WAIT_S`)."""
        end = time.monotonic() + WAIT_S
        with self._link.condition:
            while self._link.received < self.sent:
                left = end - time.monotonic()
                if left <= 0:
                    return False
                self._link.condition.wait(min(left, 0.5))
        return True

    def __getattr__(self, name: str) -> Any:
        return getattr(self.bus, name)


def windowed(
    sender: can.BusABC, receiver: can.BusABC, window: int = WINDOW_FRAMES
) -> tuple[can.BusABC, can.BusABC]:
    """``(sender, receiver)`` wrapped so that at most ``window`` frames are in flight; the
    wrappers stand in for the buses (``emulate`` sends, ``listen`` receives); shut down the
    original buses."""
    link = _Link()
    return (cast(can.BusABC, WindowedSender(sender, link, window)),
            cast(can.BusABC, CountingReceiver(receiver, link)))
