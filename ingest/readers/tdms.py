"""TDMS records (NI LabVIEW), read with npTDMS: channels by name in any group.

A manifest name is a channel name looked up in every group (it must be unique), or
``group/channel``. The rate is ``1 / wf_increment`` of the waveform channels (they must
agree) when the property is present, else the manifest's. The file is opened in
streaming mode: only the declared channels' data are read, one channel at a time, at
their stored dtype. A last segment shorter than its header says (an interrupted
write, which npTDMS would read partially with a log warning) is refused as truncated.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from nptdms import TdmsFile

from gearwatch.floor.campaign import Campaign, RecordData
from gearwatch.floor.errors import RecordFormatError
from gearwatch.floor.logs import adopt_library_loggers
from ingest.readers._common import (
    as_channel,
    channel_not_found,
    is_pulse_times,
    resolve_sample_rate,
)
from ingest.sources import declared_channel_names, register_reader

adopt_library_loggers()  # nptdms attached a printing handler to each of its loggers at import

_TRUNCATION_HINTS = ("less data than expected", "not a multiple of the chunk size", "end of file")


class _WarningCollector(logging.Handler):
    def __init__(self) -> None:
        super().__init__(level=logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())


@contextmanager
def _collect_nptdms_warnings() -> Iterator[_WarningCollector]:
    logger = logging.getLogger("nptdms")
    collector = _WarningCollector()
    logger.addHandler(collector)
    try:
        yield collector
    finally:
        logger.removeHandler(collector)


@register_reader
class TdmsReader:
    suffixes = (".tdms",)

    def read(self, path: Path, campaign: Campaign) -> RecordData:
        channels: dict[str, np.ndarray] = {}
        increments: dict[str, float] = {}
        with _collect_nptdms_warnings() as warnings_seen:
            try:
                tdms = TdmsFile.open(path)
            except (ValueError, OSError, EOFError, KeyError, IndexError) as error:
                raise RecordFormatError(
                    f"{path}: not a readable TDMS file (truncated or corrupt): {error}"
                ) from None
            _refuse_truncation(path, warnings_seen.messages)
            with tdms:
                by_name = _channels_by_name(tdms)
                for name in declared_channel_names(campaign):
                    candidates = by_name.get(name, [])
                    if not candidates:
                        raise channel_not_found(path, name, by_name)
                    if len(candidates) > 1:
                        where = ", ".join(f"{c.group_name}/{c.name}" for c in candidates)
                        raise RecordFormatError(
                            f"{path}: channel {name!r} is in several groups ({where}): "
                            "name it as 'group/channel'"
                        )
                    channel = candidates[0]
                    try:
                        samples = channel[:]
                    except (ValueError, OSError, EOFError) as error:
                        raise RecordFormatError(
                            f"{path}: cannot read channel {name!r}: {error}"
                        ) from None
                    channels[name] = as_channel(path, name, samples)
                    increment = channel.properties.get("wf_increment")
                    if increment is not None and not is_pulse_times(campaign, name):
                        increments[name] = _seconds(path, name, increment)
            _refuse_truncation(path, warnings_seen.messages)
        rate_hz = resolve_sample_rate(
            path, _common_rate(path, increments), campaign, "channel property 'wf_increment'"
        )
        return RecordData(
            channels=channels, sample_rate_hz=rate_hz, source=str(path), metadata={"format": "tdms"}
        )


def _channels_by_name(tdms: TdmsFile) -> dict[str, list[Any]]:
    by_name: dict[str, list[Any]] = {}
    for group in tdms.groups():
        for channel in group.channels():
            by_name.setdefault(channel.name, []).append(channel)
            by_name.setdefault(f"{group.name}/{channel.name}", []).append(channel)
    return by_name


def _refuse_truncation(path: Path, messages: list[str]) -> None:
    for message in messages:
        if any(hint in message for hint in _TRUNCATION_HINTS):
            raise RecordFormatError(f"{path}: truncated TDMS file ({message})")


def _seconds(path: Path, name: str, increment: Any) -> float:
    try:
        value = float(increment)
    except (TypeError, ValueError):
        raise RecordFormatError(
            f"{path}: channel {name!r}: wf_increment is not a number: {increment!r}"
        ) from None
    if not (math.isfinite(value) and value > 0):
        raise RecordFormatError(f"{path}: channel {name!r}: wf_increment must be > 0, got {value!r}")
    return value


def _common_rate(path: Path, increments: dict[str, float]) -> float | None:
    if not increments:
        return None
    values = list(increments.values())
    if max(values) - min(values) > 1e-9 * max(values):
        listed = ", ".join(f"{name}={value:g} s" for name, value in increments.items())
        raise RecordFormatError(f"{path}: channels have different wf_increment ({listed})")
    return 1.0 / values[0]
