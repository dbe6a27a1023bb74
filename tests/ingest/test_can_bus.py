"""Emulator → real python-can bus → listen/assembler, on ``virtual`` and ``udp_multicast`` (loopback)."""

from __future__ import annotations

import random
import threading
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

import can
import numpy as np
import pytest
import scipy.io

from gearwatch.floor.campaign import RecordData
from gearwatch.floor.errors import InputError
from ingest.can import protocol as p
from ingest.can.assembler import AssembledRecord, RecordAssembler
from ingest.can.emulator import emulate, record_frames
from ingest.can.live import listen, open_bus
from tests.ingest.can_flow import random_group, windowed
from tests.ingest.test_can_assembler import assert_same_record, make_record


def _virtual_pair() -> tuple[can.BusABC, can.BusABC]:
    channel = f"gearwatch-test-{uuid.uuid4().hex}"
    return open_bus("virtual", channel), open_bus("virtual", channel)


def _udp_pair() -> tuple[can.BusABC, can.BusABC]:
    port = random.randint(42_000, 48_000)
    group = random_group()
    try:
        return open_bus("udp_multicast", group, port=port), open_bus(
            "udp_multicast", group, port=port
        )
    except InputError as error:  # pragma: no cover - depends on the sandbox
        pytest.skip(f"udp_multicast not available here: {error}")


@pytest.fixture(params=["virtual", "udp_multicast"])
def buses(request: pytest.FixtureRequest) -> Iterator[tuple[can.BusABC, can.BusABC]]:
    """A sender and a receiver; on ``udp_multicast`` the sender keeps at most a window of
    frames in flight (:mod:`tests.ingest.can_flow`), so a slow receiver loses nothing."""
    sender, receiver = _virtual_pair() if request.param == "virtual" else _udp_pair()
    try:
        yield windowed(sender, receiver) if request.param == "udp_multicast" else (sender, receiver)
    finally:
        sender.shutdown()
        receiver.shutdown()


IDLE_S = 120.0
"""The listener's idle timeout: it normally stops after the expected records; this only bounds
a hang (a short one would end the listener early when the sender thread is slow to start)."""


class Listener:
    """``listen`` in a background thread, collecting the records."""

    def __init__(self, bus: can.BusABC, expected: int) -> None:
        self.records: list[AssembledRecord] = []
        self.stop = threading.Event()
        self.expected = expected
        self.thread = threading.Thread(target=self._run, args=(bus,), daemon=True)
        self.thread.start()

    def _run(self, bus: can.BusABC) -> None:
        self.stats = listen(bus, self._on_record, stop_event=self.stop, idle_timeout_s=IDLE_S)

    def _on_record(self, record: AssembledRecord) -> None:
        self.records.append(record)
        if len(self.records) >= self.expected:
            self.stop.set()

    def join(self) -> list[AssembledRecord]:
        self.thread.join(timeout=60)
        assert not self.thread.is_alive()
        return self.records


# UDP sockets drop datagrams when flooded: the emulator's rate cap is its flow control there
# (the tests' window, tests.ingest.can_flow, makes it lossless on a loaded machine too).
RATE_CAP = {"virtual": None, "udp_multicast": 4_000.0}


def _rate(sender: can.BusABC) -> float | None:
    bus = getattr(sender, "bus", sender)  # the windowed wrapper
    return RATE_CAP["udp_multicast" if "udp" in type(bus).__name__.lower() else "virtual"]


def test_emulator_to_bus_to_assembler_gives_back_the_records(
    buses: tuple[can.BusABC, can.BusABC],
) -> None:
    sender, receiver = buses
    sent = [make_record(4_000, seed=s) for s in range(2)]
    listener = Listener(receiver, expected=2)
    stats = emulate(
        sender,
        sent,
        speed=0,
        first_record_id=70,
        max_frames_per_s=_rate(sender),
        tach_channel="tach",
        tach_kind="pulse_times",
        pulses_per_rev=2,
    )
    records = listener.join()
    assert [r.status for r in records] == ["accepted", "accepted"], [r.reason for r in records]
    for got, expected, record_id in zip(records, sent, (70, 71), strict=True):
        assert got.record is not None
        assert_same_record(got.record, expected)
        assert got.metadata["can_record_id"] == str(record_id)
    assert stats.frames == sum(len(record_frames(r, record_id=1, tach_channel="tach", tach_kind="pulse_times")) for r in sent)
    assert listener.stats.records_accepted == 2


def _play(bus: can.BusABC, frames: list[can.Message], rate: float | None) -> None:
    for index, msg in enumerate(frames):
        bus.send(msg)
        if rate and index % 50 == 49:
            time.sleep(50 / rate)


def test_gap_on_the_bus_is_rejected_with_sequence_numbers_and_raw_frames(
    buses: tuple[can.BusABC, can.BusABC],
) -> None:
    sender, receiver = buses
    frames = [m for _, m in record_frames(make_record(3_000), record_id=5, tach_channel="tach", tach_kind="pulse_times")]
    acc1 = [i for i, m in enumerate(frames) if m.arbitration_id == p.SAMPLE_BLOCK_ID and m.data[2] == 0]
    lost = acc1[17]
    sent = frames[:lost] + frames[lost + 1 :]
    listener = Listener(receiver, expected=1)
    _play(sender, sent, _rate(sender))
    (record,) = listener.join()
    assert record.status == "rejected" and record.record is None
    assert record.reason is not None and "channel 0 ('acc1')" in record.reason
    assert "sequence number(s) 17 missing (1 frame(s))" in record.reason
    assert [bytes(m.data) for m in record.raw_frames] == [bytes(m.data) for m in sent]


def test_duplicate_on_the_bus_is_dropped_and_reported(buses: tuple[can.BusABC, can.BusABC]) -> None:
    sender, receiver = buses
    original = make_record(3_000)
    frames = [m for _, m in record_frames(original, record_id=6, tach_channel="tach", tach_kind="pulse_times")]
    frames.insert(40, frames[40])
    listener = Listener(receiver, expected=1)
    _play(sender, frames, _rate(sender))
    (record,) = listener.join()
    assert record.status == "accepted" and record.record is not None
    assert record.metadata["can_duplicates_dropped"] == "1"
    assert_same_record(record.record, original)


def test_real_time_playback_takes_the_record_duration() -> None:
    sender, receiver = _virtual_pair()
    try:
        record = make_record(2_000)  # 0.1 s at 20 kHz
        listener = Listener(receiver, expected=2)
        fast = emulate(sender, record, speed=0, tach_channel="tach", tach_kind="pulse_times")
        real = emulate(sender, record, speed=1, tach_channel="tach", tach_kind="pulse_times")
        records = listener.join()
    finally:
        sender.shutdown()
        receiver.shutdown()
    assert [r.status for r in records] == ["accepted", "accepted"]
    assert real.elapsed_s >= 0.1 * 0.95  # paced by the sample clock (a lower bound, not a limit)
    assert fast.frames == real.frames
    print(f"\nspeed 0: {fast.elapsed_s * 1e3:.1f} ms, speed 1: {real.elapsed_s * 1e3:.1f} ms for 0.1 s")


def test_open_bus_with_unknown_interface_is_an_input_error() -> None:
    with pytest.raises(InputError, match="cannot open CAN bus nosuch:can0"):
        open_bus("nosuch", "can0")


def test_listen_stops_on_the_event_and_rejects_the_open_record() -> None:
    sender, receiver = _virtual_pair()
    try:
        frames = [m for _, m in record_frames(make_record(1_000), record_id=9, tach_channel="tach", tach_kind="pulse_times")]
        for msg in frames[:-1]:  # no RecordStop
            sender.send(msg)
        stop = threading.Event()
        got: list[AssembledRecord] = []

        class StopWhenAllTaken(RecordAssembler):
            """Sets the stop event once every queued frame was fed (not after a delay, which
            a slow machine could exceed before the frames are read)."""

            fed = 0

            def feed(self, msg: can.Message) -> list[AssembledRecord]:
                closed = super().feed(msg)
                self.fed += 1
                if self.fed == len(frames) - 1:
                    stop.set()
                return closed

        listen(receiver, got.append, stop_event=stop, assembler=StopWhenAllTaken(source="t"),
               idle_timeout_s=IDLE_S)
    finally:
        sender.shutdown()
        receiver.shutdown()
    assert len(got) == 1 and got[0].status == "rejected"
    assert got[0].reason == "record 9: listening stopped before RecordStop"
    assert len(got[0].raw_frames) == len(frames) - 1
    assert np.all([m.arbitration_id in p.PROTOCOL_IDS for m in got[0].raw_frames])


WINDTURBINE = Path(__file__).resolve().parents[3] / "shared/data/real/windturbine-hss"


@pytest.mark.skipif(not WINDTURBINE.is_dir(), reason="shared real data not present")
def test_real_windturbine_record_over_the_virtual_bus() -> None:
    """3 s of real vibration at 97 656 Hz and its 187 tach pulse times, through the bus."""
    mat = scipy.io.loadmat(WINDTURBINE / "data-20130311T030024Z.mat")
    vibration = mat["vibration"].ravel().astype(np.float64)
    tach_s = mat["tach"].ravel().astype(np.float64)
    sent = RecordData({"vibration": vibration, "tach": tach_s}, sample_rate_hz=97_656.0)
    sender, receiver = _virtual_pair()
    try:
        listener = Listener(receiver, expected=1)
        stats = emulate(sender, sent, speed=0, tach_channel="tach", tach_kind="pulse_times")
        (result,) = listener.join()
    finally:
        sender.shutdown()
        receiver.shutdown()
    assert result.status == "accepted" and result.record is not None, result.reason
    got = result.record
    assert stats.frames > vibration.size / 30
    half_count = np.ptp(vibration) / (4 * p.MAX_COUNT)
    error = np.abs(got.channels["vibration"] - vibration)
    assert error.max() <= half_count * (1 + 1e-9)
    # int16 keeps the signal: quantisation noise 87 dB below it on this record (crest ~5)
    assert 20 * np.log10(np.std(vibration) / np.std(got.channels["vibration"] - vibration)) > 80
    np.testing.assert_allclose(got.channels["tach"], tach_s, rtol=0, atol=0.5e-9 + 1e-15)
    assert got.sample_rate_hz == 97_656.0
