"""CSV and CSV.gz readers: round trip with the csv and gzip modules, bad input, the real SpectraQuest file."""

from __future__ import annotations

import csv
import gzip
import io
from pathlib import Path

import numpy as np
import pytest

from gearwatch.floor.errors import RecordFormatError
from ingest.sources import read_record
from tests.ingest.roundtrip import RoundTripBase, make_campaign

SPECTRAQUEST = Path(__file__).resolve().parents[3] / "shared/data/real/spectraquest-gfd"


def csv_text(channels: dict[str, np.ndarray], delimiter: str = ",") -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, delimiter=delimiter, lineterminator="\n")
    writer.writerow(list(channels))
    writer.writerows(zip(*(map(repr, x.tolist()) for x in channels.values()), strict=True))
    return buffer.getvalue()


class TestCsvRoundTrip(RoundTripBase):
    suffix = ".csv"
    rate_in_file = "never"
    supports_pulse_times = False
    atol = 0.0
    rtol = 0.0  # repr() of a float64 parses back exactly
    memory_test_samples = 50_000

    def write(self, path: Path, channels: dict[str, np.ndarray], sample_rate_hz: float | None) -> None:
        path.write_text(csv_text(channels), encoding="utf-8")


class TestCsvGzRoundTrip(TestCsvRoundTrip):
    suffix = ".csv.gz"

    def write(self, path: Path, channels: dict[str, np.ndarray], sample_rate_hz: float | None) -> None:
        with gzip.open(path, "wt", encoding="utf-8") as stream:
            stream.write(csv_text(channels))


def write_csv(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def campaign(tmp_path: Path, names: tuple[str, ...] = ("a", "b", "tach")):
    return make_campaign(tmp_path, names, sample_rate_hz=1000.0)


def test_semicolon_and_tab_delimiters_quotes_and_crlf(tmp_path: Path) -> None:
    for delimiter in (";", "\t"):
        path = write_csv(tmp_path / "d.csv", f'"a"{delimiter} b {delimiter}tach\r\n1{delimiter}2{delimiter}0\r\n')
        record = read_record(path, campaign(tmp_path))
        assert record.channels["b"].tolist() == [2.0]


def test_short_row_is_refused_with_row_number(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "short.csv", "a,b,tach\n1,2,0\n3,4\n5,6,0\n")
    with pytest.raises(RecordFormatError, match=r"short\.csv.*row"):
        read_record(path, campaign(tmp_path))


def test_text_in_a_cell_is_refused(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "text.csv", "a,b,tach\n1,2,0\n3,oops,0\n")
    with pytest.raises(RecordFormatError, match=r"text\.csv.*oops"):
        read_record(path, campaign(tmp_path))


def test_missing_final_newline_is_truncation(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "cut.csv", "a,b,tach\n1,2,0\n3,4,0.")
    with pytest.raises(RecordFormatError, match="truncated"):
        read_record(path, campaign(tmp_path))


def test_header_only_and_headerless_files(tmp_path: Path) -> None:
    with pytest.raises(RecordFormatError, match="no data rows"):
        read_record(write_csv(tmp_path / "h.csv", "a,b,tach\n"), campaign(tmp_path))
    with pytest.raises(RecordFormatError, match="looks like data"):
        read_record(write_csv(tmp_path / "n.csv", "1,2,3\n4,5,6\n"), campaign(tmp_path))


def test_extra_columns_are_ignored_and_not_returned(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "x.csv", "time,a,b,tach\n0,1,2,0\n0.001,3,4,5\n")
    record = read_record(path, campaign(tmp_path))
    assert record.channels["a"].tolist() == [1.0, 3.0]
    assert record.channels["tach"].tolist() == [0.0, 5.0]
    assert set(record.channels) == {"a", "b", "tach"}


@pytest.mark.skipif(not SPECTRAQUEST.is_dir(), reason="shared real data not present")
def test_real_spectraquest_file_without_tachometer(tmp_path: Path) -> None:
    names = ("a1", "a2", "a3", "a4")
    spectraquest = make_campaign(tmp_path, names, sample_rate_hz=12_800.0, tach_channel="none")
    assert spectraquest.tachometer is None
    record = read_record(SPECTRAQUEST / "h30hz0.csv.gz", spectraquest)
    assert list(record.channels) == list(names)
    assert record.channels["a1"][:2].tolist() == [4.63671, 1.9928]  # first rows of the file
    assert 88_000 <= record.channels["a4"].size <= 114_000
    assert record.sample_rate_hz == 12_800.0
