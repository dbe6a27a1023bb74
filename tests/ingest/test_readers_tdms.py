"""TDMS reader: round trip with nptdms.TdmsWriter, channel lookup across groups, bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from nptdms import ChannelObject, TdmsWriter

from gearwatch.floor.errors import RecordFormatError
from ingest.sources import read_record
from tests.ingest.roundtrip import TACH_CHANNEL, RoundTripBase, make_campaign


class TestTdmsRoundTrip(RoundTripBase):
    suffix = ".tdms"
    atol = 0.0
    rtol = 0.0

    def write(self, path: Path, channels: dict[str, np.ndarray], sample_rate_hz: float | None) -> None:
        # Waveforms in one group, the tach in another: names are found in any group.
        objects = []
        for name, samples in channels.items():
            properties = {}
            if sample_rate_hz is not None and not (name == TACH_CHANNEL and samples.size < 100):
                properties["wf_increment"] = 1.0 / sample_rate_hz
            group = "tach" if name == TACH_CHANNEL else "vibration"
            objects.append(ChannelObject(group, name, samples, properties=properties))
        with TdmsWriter(path) as writer:
            writer.write_segment(objects)


class TestTdmsFloat32SegmentedRoundTrip(TestTdmsRoundTrip):
    """float32 data written in two segments (how a logger appends) come back whole, as float32."""

    atol = 1e-5
    rtol = 1e-6

    def write(self, path: Path, channels: dict[str, np.ndarray], sample_rate_hz: float | None) -> None:
        properties = {} if sample_rate_hz is None else {"wf_increment": 1.0 / sample_rate_hz}
        with TdmsWriter(path) as writer:
            halves = [
                {n: x[: x.size // 2] for n, x in channels.items()},
                {n: x[x.size // 2 :] for n, x in channels.items()},
            ]
            for half in halves:
                writer.write_segment(
                    [
                        ChannelObject("g", n, x.astype(np.float32), properties=properties)
                        for n, x in half.items()
                    ]
                )


def write_tdms(path: Path, objects: list[ChannelObject]) -> Path:
    with TdmsWriter(path) as writer:
        writer.write_segment(objects)
    return path


def test_same_name_in_two_groups_needs_group_path(tmp_path: Path) -> None:
    path = write_tdms(
        tmp_path / "two.tdms",
        [
            ChannelObject("left", "acc1", np.ones(8)),
            ChannelObject("right", "acc1", np.zeros(8)),
            ChannelObject("right", "tach", np.zeros(8)),
        ],
    )
    with pytest.raises(RecordFormatError, match=r"'acc1' is in several groups.*left/acc1"):
        read_record(path, make_campaign(tmp_path, ("acc1", "tach"), sample_rate_hz=10.0))
    record = read_record(path, make_campaign(tmp_path, ("left/acc1", "tach"), sample_rate_hz=10.0))
    assert record.channels["left/acc1"].tolist() == [1.0] * 8


def test_disagreeing_wf_increment_is_refused(tmp_path: Path) -> None:
    path = write_tdms(
        tmp_path / "rates.tdms",
        [
            ChannelObject("g", "acc1", np.ones(8), properties={"wf_increment": 1e-3}),
            ChannelObject("g", "tach", np.ones(8), properties={"wf_increment": 2e-3}),
        ],
    )
    with pytest.raises(RecordFormatError, match="different wf_increment"):
        read_record(path, make_campaign(tmp_path, ("acc1", "tach"), sample_rate_hz=10.0))


def test_string_channel_is_refused(tmp_path: Path) -> None:
    path = write_tdms(
        tmp_path / "text.tdms",
        [ChannelObject("g", "acc1", np.array(["a", "b"])), ChannelObject("g", "tach", np.ones(2))],
    )
    with pytest.raises(RecordFormatError, match="acc1"):
        read_record(path, make_campaign(tmp_path, ("acc1", "tach"), sample_rate_hz=10.0))
