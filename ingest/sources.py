"""Record-file readers: one registry keyed by file suffix.

Every reader is an object with ``suffixes`` (lower-case, with the dot, e.g.
``(".csv", ".csv.gz")``) and ``read(path, campaign) -> RecordData``. Readers register
themselves with :func:`register_reader` (usable as a class decorator); the built-in
readers live in :mod:`ingest.readers` (one module per format) and the CAN log readers
in :mod:`ingest.can`; both packages are imported the first time a reader is looked up.

:func:`read_record` is the one entry point the pipeline uses: it picks the reader by
the longest matching suffix, turns any library failure into
:class:`gearwatch.floor.errors.RecordFormatError` naming the file, and checks that the
reader returned exactly the channels the manifest declares.

Example
-------
>>> from pathlib import Path
>>> reader_for(Path("day01.CSV.GZ")).suffixes
('.csv', '.csv.gz')
"""

from __future__ import annotations

import hashlib
import importlib
import math
import threading
from pathlib import Path
from typing import Protocol, TypeVar, runtime_checkable

import numpy as np

from gearwatch.floor.campaign import Campaign, RecordData
from gearwatch.floor.errors import GearwatchError, RecordFormatError

__all__ = [
    "RecordReader",
    "declared_channel_names",
    "file_sha256",
    "read_record",
    "reader_for",
    "register_reader",
    "registered_suffixes",
]


@runtime_checkable
class RecordReader(Protocol):
    """Reads one record file into :class:`RecordData`.

    ``read`` returns exactly the channels the campaign declares (accelerometers and the
    tachometer), each a 1-D floating-point array (float32 or float64, possibly a
    read-only memory-mapped view of the file); a ``pulse_times`` tachometer is the
    array of pulse times in seconds, of its own length. It raises
    :class:`gearwatch.floor.errors.RecordFormatError` naming the file (and channel).
    """

    suffixes: tuple[str, ...]

    def read(self, path: Path, campaign: Campaign) -> RecordData: ...


ReaderT = TypeVar("ReaderT")

_registry: dict[str, RecordReader] = {}
_builtins_loaded = False
_builtins_lock = threading.Lock()

# Packages whose modules register readers; a missing optional package is skipped.
_READER_PACKAGES = ("ingest.readers", "ingest.can")

_BUILTIN_READER_MODULES: dict[str, str] = {
    ".wav": "ingest.readers.wav",
    ".csv": "ingest.readers.csv",
    ".csv.gz": "ingest.readers.csv",
    ".npz": "ingest.readers.npz",
    ".h5": "ingest.readers.hdf5",
    ".hdf5": "ingest.readers.hdf5",
    ".hdf": "ingest.readers.hdf5",
    ".tdms": "ingest.readers.tdms",
    ".mat": "ingest.readers.mat",
}
"""Which built-in module registers a suffix, so that reading one file imports only its reader's
library (h5py, nptdms, scipy.io.matlab and python-can are a large part of a short command's
start-up). ``tests/ingest/test_readers_registry.py`` checks it against the readers' own
``suffixes``; a suffix not listed (CAN logs, plug-ins) loads every built-in reader."""


def register_reader(reader: ReaderT) -> ReaderT:
    """Register a reader (an instance, or a class instantiated without arguments).

    Returns its argument unchanged, so it works as a class decorator::

        @register_reader
        class WavReader:
            suffixes = (".wav",)
            def read(self, path, campaign): ...

    A suffix already taken by a reader of another class raises ``ValueError``;
    registering the same class again (a module reload) replaces the old instance.
    """
    instance = reader() if isinstance(reader, type) else reader
    if not isinstance(instance, RecordReader):
        raise TypeError(f"{reader!r} is not a RecordReader (needs `suffixes` and `read`)")
    suffixes = tuple(instance.suffixes)
    if not suffixes:
        raise ValueError(f"{reader!r} declares no suffixes")
    for suffix in suffixes:
        if not suffix.startswith(".") or suffix != suffix.lower():
            raise ValueError(f"reader suffix {suffix!r} must be lower-case and start with '.'")
        existing = _registry.get(suffix)
        if existing is not None and _qualified_name(existing) != _qualified_name(instance):
            raise ValueError(
                f"suffix {suffix!r} is already handled by {_qualified_name(existing)}"
            )
    for suffix in suffixes:
        _registry[suffix] = instance
    return reader


def _qualified_name(reader: object) -> str:
    cls = type(reader)
    return f"{cls.__module__}.{cls.__qualname__}"


def _load_builtin_readers() -> None:
    global _builtins_loaded
    if _builtins_loaded:
        return
    with _builtins_lock:
        if _builtins_loaded:
            return
        for package in _READER_PACKAGES:
            try:
                module = importlib.import_module(package)
            except ModuleNotFoundError as error:
                # Only the package itself may be absent; a broken import inside it is a bug.
                if error.name != package:
                    raise
                continue
            for folder in getattr(module, "__path__", ()):
                for entry in sorted(Path(folder).glob("[!_]*.py")):
                    importlib.import_module(f"{package}.{entry.stem}")
        _builtins_loaded = True


def _load_reader_for(name: str) -> None:
    """Import the built-in reader of a lower-case file ``name`` (every one when unsure)."""
    if _builtins_loaded:
        return
    modules = {module for suffix, module in _BUILTIN_READER_MODULES.items() if name.endswith(suffix)}
    if not modules:
        _load_builtin_readers()
    for module in sorted(modules):
        importlib.import_module(module)


def registered_suffixes() -> tuple[str, ...]:
    """Every registered suffix, sorted (built-in readers included)."""
    _load_builtin_readers()
    return tuple(sorted(_registry))


def reader_for(path: str | Path) -> RecordReader:
    """The reader for ``path``, chosen by the longest registered suffix (case-insensitive).

    Raises :class:`RecordFormatError` when no reader handles the file's suffix.
    """
    name = Path(path).name.lower()
    _load_reader_for(name)
    matches = [suffix for suffix in _registry if name.endswith(suffix)]
    if not matches:
        known = ", ".join(sorted(_registry)) or "none"
        raise RecordFormatError(f"{path}: no reader for this file type (known suffixes: {known})")
    return _registry[max(matches, key=len)]


def declared_channel_names(campaign: Campaign) -> tuple[str, ...]:
    """Names a reader must return: the manifest's ``[[channels]]`` in order.

    ``[[channels]]`` holds the accelerometers and the tachometer (the manifest checks
    that ``[tachometer] channel`` is declared there).
    """
    return tuple(channel.name for channel in campaign.channels)


def read_record(path: str | Path, campaign: Campaign) -> RecordData:
    """Read one record file with the registered reader and check what it returned.

    Raises :class:`RecordFormatError` (message starts with the file path) for a missing,
    empty, truncated or corrupt file, a missing channel, a missing sample rate or
    waveform channels of unequal length. NaN and inf samples are passed through
    unchanged: the pipeline's quality checks reject them.
    """
    path = Path(path)
    if not path.is_file():
        raise RecordFormatError(f"{path}: file not found")
    if path.stat().st_size == 0:
        raise RecordFormatError(f"{path}: file is empty")
    reader = reader_for(path)
    try:
        record = reader.read(path, campaign)
    except GearwatchError:
        raise
    except MemoryError:
        raise
    except Exception as error:  # any library failure is a bad file, reported in one line
        raise RecordFormatError(
            f"{path}: cannot read as {'/'.join(reader.suffixes)}: "
            f"{type(error).__name__}: {error}"
        ) from error
    _check_record(path, record, campaign)
    return record


def _check_record(path: Path, record: RecordData, campaign: Campaign) -> None:
    expected = declared_channel_names(campaign)
    missing = [name for name in expected if name not in record.channels]
    if missing:
        raise RecordFormatError(f"{path}: channel(s) not found: {', '.join(missing)}")
    extra = [name for name in record.channels if name not in expected]
    if extra:  # a reader bug rather than a bad file, but never pass undeclared data on
        raise RecordFormatError(f"{path}: reader returned undeclared channel(s): {', '.join(extra)}")
    rate = record.sample_rate_hz
    if not (isinstance(rate, int | float) and math.isfinite(rate) and rate > 0):
        raise RecordFormatError(f"{path}: invalid sample rate {rate!r}")
    pulse_times_channel = (
        campaign.tachometer.channel
        if campaign.tachometer is not None and campaign.tachometer.kind == "pulse_times"
        else None
    )
    waveform_lengths: dict[str, int] = {}
    for name in expected:
        samples = record.channels[name]
        if not isinstance(samples, np.ndarray) or samples.ndim != 1:
            raise RecordFormatError(f"{path}: channel {name!r} is not a 1-D array")
        if not np.issubdtype(samples.dtype, np.floating):
            raise RecordFormatError(
                f"{path}: channel {name!r} has dtype {samples.dtype}, expected floating point"
            )
        if samples.size == 0:
            raise RecordFormatError(f"{path}: channel {name!r} is empty")
        if name != pulse_times_channel:
            waveform_lengths[name] = samples.size
    if len(set(waveform_lengths.values())) > 1:
        lengths = ", ".join(f"{name}={n}" for name, n in waveform_lengths.items())
        raise RecordFormatError(f"{path}: channels have different lengths ({lengths})")
    if not record.source:
        record.source = str(path)


def file_sha256(path: str | Path) -> str:
    """SHA-256 hex digest of a file, streamed through one reused buffer (constant memory:
    :func:`hashlib.file_digest`)."""
    with open(path, "rb") as stream:
        return hashlib.file_digest(stream, "sha256").hexdigest()
