"""Content-addressed raw store."""

from __future__ import annotations

import hashlib
import os

import pytest

from gearwatch.floor.errors import InputError
from storage.raw_store import RawStore


def test_keep_copies_into_a_content_addressed_path(tmp_path) -> None:
    source = tmp_path / "day1.wav"
    source.write_bytes(b"RIFF" + bytes(range(256)) * 100)
    digest = hashlib.sha256(source.read_bytes()).hexdigest()
    store = RawStore(tmp_path / "store")
    kept = store.keep(source)
    assert kept == tmp_path / "store" / digest[:2] / f"{digest}.wav"
    assert kept.read_bytes() == source.read_bytes()
    assert not os.access(kept, os.W_OK) or os.geteuid() == 0  # read-only (root ignores modes)
    assert store.contains(digest, ".wav")
    # Keeping again is a no-op, with or without the digest.
    assert store.keep(source, digest) == kept
    assert store.keep(source) == kept
    assert [p.name for p in (tmp_path / "store").rglob("*") if p.is_file()] == [kept.name]


def test_keep_refuses_a_wrong_digest_and_leaves_nothing(tmp_path) -> None:
    source = tmp_path / "x.csv.gz"
    source.write_bytes(b"abc")
    store = RawStore(tmp_path / "store")
    with pytest.raises(InputError, match="changed"):
        store.keep(source, "0" * 64, ".csv.gz")
    assert [p for p in (tmp_path / "store").rglob("*") if p.is_file()] == []
    kept = store.keep(source, hashlib.sha256(b"abc").hexdigest(), ".csv.gz")
    assert kept.name.endswith(".csv.gz")


def test_keep_bytes_and_path_validation(tmp_path) -> None:
    store = RawStore(tmp_path)
    digest, path = store.keep_bytes(b"frames", ".blf")
    assert digest == hashlib.sha256(b"frames").hexdigest() and path.read_bytes() == b"frames"
    with pytest.raises(InputError):
        store.path_for("../../etc/passwd")
    with pytest.raises(InputError):
        store.path_for(digest, "/../x")
    copy = store.copy_out(digest, ".blf", tmp_path / "copy.blf")
    assert copy.read_bytes() == b"frames"


def test_locations_are_absolute(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    source = tmp_path / "r.wav"
    source.write_bytes(b"x")
    kept = RawStore("raw-store").keep(source)
    assert kept.is_absolute() and kept.is_relative_to(tmp_path / "raw-store")
