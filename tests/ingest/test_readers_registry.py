"""The reader registry (ingest.sources): suffix lookup, registration rules, the safety net of
read_record around readers, the checks on what a reader returns, and the streamed SHA-256."""

from __future__ import annotations

import hashlib
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

import ingest.sources as sources
from gearwatch.floor.campaign import Campaign, RecordData
from gearwatch.floor.errors import RecordFormatError
from ingest.sources import (
    RecordReader,
    file_sha256,
    read_record,
    reader_for,
    register_reader,
    registered_suffixes,
)
from tests.ingest.roundtrip import make_campaign


@pytest.fixture
def scratch_registry() -> Iterator[None]:
    """Readers registered by a test are removed afterwards."""
    before = dict(sources._registry)
    yield
    sources._registry.clear()
    sources._registry.update(before)


class FixedReader:
    """Returns whatever it is given, to exercise read_record's checks."""

    suffixes: tuple[str, ...] = (".gwtest",)

    def __init__(self, channels: dict[str, np.ndarray] | None = None, rate: float = 100.0) -> None:
        self.channels = channels or {}
        self.rate = rate

    def read(self, path: Path, campaign: Campaign) -> RecordData:
        return RecordData(channels=self.channels, sample_rate_hz=self.rate)


def test_every_required_format_is_registered() -> None:
    for suffix in (".wav", ".csv", ".csv.gz", ".npz", ".h5", ".hdf5", ".tdms", ".mat"):
        assert suffix in registered_suffixes()
        assert isinstance(reader_for(Path(f"x{suffix}")), RecordReader)


def test_the_suffix_index_names_the_module_of_each_builtin_reader() -> None:
    """Reading a file imports only its reader when the index says which: the index must agree
    with the readers' own ``suffixes``."""
    registered_suffixes()  # every built-in reader
    for suffix, module in sources._BUILTIN_READER_MODULES.items():
        assert type(sources._registry[suffix]).__module__ == module, suffix
    for suffix, reader in sources._registry.items():
        if type(reader).__module__.startswith("ingest.readers."):
            assert sources._BUILTIN_READER_MODULES[suffix] == type(reader).__module__


def test_longest_suffix_wins_and_case_is_ignored() -> None:
    assert ".csv.gz" in reader_for(Path("/d/Day01.CSV.GZ")).suffixes
    assert reader_for(Path("a.tar.csv")) is reader_for(Path("b.csv"))


def test_unknown_suffix_lists_the_known_ones() -> None:
    with pytest.raises(RecordFormatError, match=r"notes\.docx: no reader.*\.wav"):
        reader_for(Path("notes.docx"))


def test_register_instance_or_class_and_conflicts(scratch_registry: None) -> None:
    instance = FixedReader()
    assert register_reader(instance) is instance
    assert reader_for(Path("x.gwtest")) is instance

    @register_reader
    class Decorated(FixedReader):
        suffixes = (".gwtest2", ".gw.test")

    assert isinstance(Decorated, type)  # the decorator hands the class back
    assert isinstance(reader_for(Path("y.GW.TEST")), Decorated)

    class Other(FixedReader):
        pass

    with pytest.raises(ValueError, match=r"'\.gwtest' is already handled by .*FixedReader"):
        register_reader(Other)  # another class on a taken suffix
    assert reader_for(Path("x.gwtest")) is instance  # and nothing changed
    again = FixedReader()
    register_reader(again)  # the same class again (a module reload) replaces
    assert reader_for(Path("x.gwtest")) is again
    with pytest.raises(ValueError, match="lower-case"):
        register_reader(type("Upper", (FixedReader,), {"suffixes": (".GW",)}))
    with pytest.raises(TypeError, match="not a RecordReader"):
        register_reader(object())


def test_missing_and_empty_files(tmp_path: Path) -> None:
    campaign = make_campaign(tmp_path, ("acc1", "tach"), sample_rate_hz=10.0)
    with pytest.raises(RecordFormatError, match=r"absent\.wav: file not found"):
        read_record(tmp_path / "absent.wav", campaign)
    (tmp_path / "empty.npz").write_bytes(b"")
    with pytest.raises(RecordFormatError, match=r"empty\.npz: file is empty"):
        read_record(tmp_path / "empty.npz", campaign)


def test_a_raw_library_error_becomes_one_line_naming_the_file(
    tmp_path: Path, scratch_registry: None
) -> None:
    class Exploding(FixedReader):
        def read(self, path: Path, campaign: Campaign) -> RecordData:
            raise KeyError("internal detail")

    register_reader(Exploding())
    path = tmp_path / "r.gwtest"
    path.write_bytes(b"x")
    with pytest.raises(RecordFormatError, match=r"r\.gwtest: cannot read as \.gwtest: KeyError"):
        read_record(path, make_campaign(tmp_path, ("acc1", "tach"), sample_rate_hz=10.0))


@pytest.mark.parametrize(
    ("channels", "rate", "message"),
    [
        ({"acc1": np.zeros(4)}, 10.0, r"channel\(s\) not found: tach"),
        ({"acc1": np.zeros(4), "tach": np.zeros(4), "x": np.zeros(4)}, 10.0, "undeclared channel"),
        ({"acc1": np.zeros(4), "tach": np.zeros(3)}, 10.0, r"different lengths \(acc1=4, tach=3\)"),
        ({"acc1": np.zeros((4, 1)), "tach": np.zeros(4)}, 10.0, "'acc1' is not a 1-D array"),
        ({"acc1": np.zeros(4, dtype=int), "tach": np.zeros(4)}, 10.0, "expected floating point"),
        ({"acc1": np.zeros(0), "tach": np.zeros(0)}, 10.0, "'acc1' is empty"),
        ({"acc1": np.zeros(4), "tach": np.zeros(4)}, float("nan"), "invalid sample rate"),
        ({"acc1": np.zeros(4), "tach": np.zeros(4)}, 0.0, "invalid sample rate"),
    ],
)
def test_what_a_reader_returns_is_checked(
    tmp_path: Path, scratch_registry: None, channels: dict[str, np.ndarray], rate: float, message: str
) -> None:
    register_reader(FixedReader(channels, rate))
    path = tmp_path / "r.gwtest"
    path.write_bytes(b"x")
    with pytest.raises(RecordFormatError, match=message):
        read_record(path, make_campaign(tmp_path, ("acc1", "tach"), sample_rate_hz=10.0))


def test_pulse_times_tachometer_has_its_own_length(tmp_path: Path, scratch_registry: None) -> None:
    register_reader(FixedReader({"acc1": np.zeros(40), "tach": np.array([0.1, 0.2, 0.3])}))
    path = tmp_path / "r.gwtest"
    path.write_bytes(b"x")
    campaign = make_campaign(tmp_path, ("acc1", "tach"), sample_rate_hz=10.0, tach_kind="pulse_times")
    record = read_record(path, campaign)
    assert record.source == str(path)  # filled in when the reader left it empty
    assert record.channels["tach"].size == 3


def test_file_sha256_is_streamed_and_matches_hashlib(tmp_path: Path) -> None:
    path = tmp_path / "blob.bin"
    # several of file_digest's 256 KiB buffers and a short last one
    content = np.random.default_rng(3).integers(0, 256, 3 * 2**18 + 17, dtype=np.uint8).tobytes()
    path.write_bytes(content)
    expected = hashlib.sha256(content).hexdigest()
    assert file_sha256(path) == expected
    assert file_sha256(str(path)) == expected
    path.write_bytes(content[:-1])
    assert file_sha256(path) != expected
