"""CSV records (``.csv`` and gzip-compressed ``.csv.gz``): one column per channel, named in the header.

The first line holds the channel names (``,`` ``;`` or tab separated, optional quotes);
every following line one sample per column. The rate comes from the manifest's
``[acquisition] sample_rate_hz`` (a CSV file carries none). Values are parsed as
float64 with numpy's C parser, streaming from the (decompressed) text; ``nan`` and
``inf`` are kept. Every row must have the header's number of fields and the file must
end with a newline: a last line without one is what an interrupted write leaves, so
it is refused as truncated rather than silently read with a cut-off number.
"""

from __future__ import annotations

import gzip
import io
import warnings
import zlib
from pathlib import Path
from typing import IO, Any, BinaryIO, cast

import numpy as np

from gearwatch.floor.campaign import Campaign, RecordData
from gearwatch.floor.errors import RecordFormatError
from ingest.readers._common import (
    channel_not_found,
    is_pulse_times,
    max_channel_bytes,
    resolve_sample_rate,
)
from ingest.sources import declared_channel_names, register_reader

_DELIMITERS = (",", ";", "\t")


class _TailTrackingRaw(io.RawIOBase):
    """Binary stream proxy remembering the last byte read (to detect a missing final newline)
    and refusing more than ``limit`` bytes of text (a gzip bomb decompresses without end)."""

    def __init__(self, inner: BinaryIO, path: Path, limit: int) -> None:
        self._inner = inner
        self.last_byte = b""
        self.path = path
        self.limit = limit
        self.total = 0

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: Any) -> int:
        data = self._inner.read(len(buffer))
        count = len(data)
        self.total += count
        if self.total > self.limit:
            raise RecordFormatError(
                f"{self.path}: more than {self.limit} bytes of CSV text, the ceiling for one "
                "record (GEARWATCH_MAX_CHANNEL_BYTES)"
            )
        buffer[:count] = data
        if count:
            self.last_byte = data[-1:]
        return count

    def close(self) -> None:
        self._inner.close()
        super().close()


@register_reader
class CsvReader:
    suffixes = (".csv", ".csv.gz")

    def read(self, path: Path, campaign: Campaign) -> RecordData:
        names = declared_channel_names(campaign)
        for name in names:
            if is_pulse_times(campaign, name):
                raise RecordFormatError(
                    f"{path}: a CSV file holds equal-length columns only; tachometer {name!r} "
                    "cannot be kind 'pulse_times'"
                )
        rate_hz = resolve_sample_rate(path, None, campaign, "CSV files carry no rate")
        compressed = path.name.lower().endswith(".gz")
        try:
            binary = cast(BinaryIO, gzip.open(path, "rb") if compressed else open(path, "rb"))
            tail = _TailTrackingRaw(binary, path, max_channel_bytes())
            with io.TextIOWrapper(io.BufferedReader(tail), encoding="utf-8-sig") as stream:
                header, delimiter = _read_header(path, stream)
                columns = {}
                for name in names:
                    if name not in header:
                        raise channel_not_found(path, name, header)
                    columns[name] = header.index(name)
                with warnings.catch_warnings():
                    # A header-only file is reported below as "no data rows".
                    warnings.filterwarnings("ignore", message=".*input contained no data")
                    table = np.loadtxt(
                        stream,
                        delimiter=delimiter,
                        dtype=np.float64,
                        ndmin=2,
                        comments=None,
                        encoding=None,
                    )
        except (EOFError, gzip.BadGzipFile, zlib.error) as error:
            raise RecordFormatError(f"{path}: truncated or corrupt gzip data: {error}") from None
        except UnicodeDecodeError as error:
            raise RecordFormatError(f"{path}: not a text CSV file ({error.reason})") from None
        except ValueError as error:
            # numpy names the row and column; its rows count from the first data line.
            raise RecordFormatError(f"{path}: bad CSV data: {error}") from None
        if table.shape[0] == 0:
            raise RecordFormatError(f"{path}: the CSV file has a header but no data rows")
        if tail.last_byte not in (b"\n", b"\r"):
            raise RecordFormatError(
                f"{path}: the last line has no newline: the file looks truncated "
                "(if it is complete, end it with a newline)"
            )
        if table.shape[1] != len(header):
            raise RecordFormatError(
                f"{path}: the header names {len(header)} columns but the rows have {table.shape[1]}"
            )
        if len(set(columns.values())) == table.shape[1]:
            # Every column is a channel: hand out views, no second copy.
            channels = {name: table[:, index] for name, index in columns.items()}
        else:
            channels = {name: np.ascontiguousarray(table[:, index]) for name, index in columns.items()}
            del table
        return RecordData(
            channels=channels,
            sample_rate_hz=rate_hz,
            source=str(path),
            metadata={"format": "csv.gz" if compressed else "csv"},
        )


def _read_header(path: Path, stream: IO[str]) -> tuple[list[str], str]:
    line = stream.readline()
    if not line.strip():
        raise RecordFormatError(f"{path}: the CSV file has no header line with channel names")
    line = line.rstrip("\r\n")
    delimiter = max(_DELIMITERS, key=line.count)
    if line.count(delimiter) == 0:
        delimiter = ","
    names = [field.strip().strip('"').strip("'").strip() for field in line.split(delimiter)]
    if any(not name for name in names):
        raise RecordFormatError(f"{path}: the CSV header has an empty column name: {line!r}")
    duplicates = sorted({name for name in names if names.count(name) > 1})
    if duplicates:
        raise RecordFormatError(f"{path}: the CSV header repeats column(s) {', '.join(duplicates)}")
    try:
        float(names[0])
    except ValueError:
        return names, delimiter
    raise RecordFormatError(
        f"{path}: the first line looks like data, not a header with channel names: {line[:80]!r}"
    )
