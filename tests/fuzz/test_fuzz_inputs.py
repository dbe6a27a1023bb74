"""Fuzz targets (issue 12, harness): every reader, the manifest, the CAN assembler and the
upload route get valid inputs mutated by hypothesis (byte flips, truncations, inserted bytes,
header fields and declared sizes overwritten with extreme integers, extreme sample values).
Each input must give a result or a clean error (``GearwatchError``; 4xx over REST), never a
crash, a hang or a 5xx. See ``conftest.py`` for the long run."""

from __future__ import annotations

import dataclasses
import gzip
import io
import struct
import tomllib
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io
import scipy.io.wavfile
from hypothesis import given
from hypothesis import strategies as st
from nptdms import ChannelObject, TdmsWriter

from gearwatch.floor.errors import InputError
from ingest.sources import read_record
from tests.fuzz.conftest import FUZZ_SETTINGS, run_input
from tests.storage.factories import campaign_config

SAMPLES = 2000
RATE_HZ = 2000.0
CAMPAIGN = dataclasses.replace(campaign_config(), sample_rate_hz=RATE_HZ)
"""Channels ``acc`` (accelerometer) and ``tach`` (pulses)."""

EXTREMES = [0, 1, 2**7 - 1, 2**8, 2**15, 2**16 - 1, 2**31 - 1, 2**32 - 1, 2**40, 2**62, 2**63 - 1,
            2**64 - 1]


def _signals() -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(SAMPLES) / RATE_HZ
    return np.sin(2 * np.pi * 50 * t), (np.sin(2 * np.pi * 25 * t) > 0.95) * 5.0


def _wav(path: Path) -> None:
    acc, tach = _signals()
    scipy.io.wavfile.write(path, int(RATE_HZ), np.column_stack([acc, tach]).astype(np.float32))


def _csv(path: Path) -> None:
    acc, tach = _signals()
    text = "acc,tach\n" + "".join(f"{a:.6f},{b:.1f}\n" for a, b in zip(acc, tach, strict=True))
    if path.suffix == ".gz":
        path.write_bytes(gzip.compress(text.encode()))
    else:
        path.write_text(text)


def _npz(path: Path, compressed: bool) -> None:
    acc, tach = _signals()
    save = np.savez_compressed if compressed else np.savez
    save(path, acc=acc, tach=tach, sample_rate_hz=np.array(RATE_HZ))


def _hdf5(path: Path, chunked: bool) -> None:
    acc, tach = _signals()
    with h5py.File(path, "w") as file:
        options = {"chunks": (500,), "compression": "gzip"} if chunked else {}
        file.create_dataset("acc", data=acc, **options)
        file.create_dataset("tach", data=tach, **options)
        file.attrs["sample_rate_hz"] = RATE_HZ


def _tdms(path: Path) -> None:
    acc, tach = _signals()
    with TdmsWriter(path) as writer:
        for part in range(2):
            cut = slice(part * SAMPLES // 2, (part + 1) * SAMPLES // 2)
            writer.write_segment([
                ChannelObject("g", "acc", acc[cut], properties={"wf_increment": 1 / RATE_HZ}),
                ChannelObject("g", "tach", tach[cut]),
            ])


def _mat5(path: Path) -> None:
    acc, tach = _signals()
    scipy.io.savemat(path, {"acc": acc, "tach": tach, "fs": RATE_HZ}, do_compression=True)


def _mat73(path: Path) -> None:
    acc, tach = _signals()
    with h5py.File(path, "w", userblock_size=512) as file:
        for name, values in (("acc", acc), ("tach", tach)):
            dataset = file.create_dataset(name, data=values[None, :], chunks=(1, 500),
                                          compression="gzip")
            dataset.attrs["MATLAB_class"] = np.bytes_("double")


def _can_log(path: Path) -> None:
    from gearwatch.floor.campaign import RecordData
    from ingest.can.emulator import record_frames
    from ingest.can.logs import write_can_log

    acc, tach = _signals()
    record = RecordData(channels={"acc": acc, "tach": tach}, sample_rate_hz=RATE_HZ)
    frames = record_frames(record, record_id=1, tach_channel="tach")
    write_can_log(path, [message for _, message in frames])


FORMATS = {
    "wav": ("r.wav", _wav),
    "csv": ("r.csv", _csv),
    "csv.gz": ("r.csv.gz", _csv),
    "npz": ("r.npz", lambda p: _npz(p, False)),
    "npz-deflate": ("r.npz", lambda p: _npz(p, True)),
    "hdf5": ("r.h5", lambda p: _hdf5(p, False)),
    "hdf5-chunked": ("r.h5", lambda p: _hdf5(p, True)),
    "tdms": ("r.tdms", _tdms),
    "mat5": ("r.mat", _mat5),
    "mat73": ("r.mat", _mat73),
    "can-blf": ("r.blf", _can_log),
    "can-asc": ("r.asc", _can_log),
}


@pytest.fixture(scope="module")
def valid_files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[str, bytes]]:
    folder = tmp_path_factory.mktemp("fuzz-seeds")
    files = {}
    for fmt, (name, write) in FORMATS.items():
        path = folder / f"{fmt}-{name}"
        write(path)
        files[fmt] = (name, path.read_bytes())
    return files


mutation = st.one_of(
    st.tuples(st.just("flip"), st.floats(0, 1), st.integers(0, 255)),
    st.tuples(st.just("truncate"), st.floats(0, 1), st.just(0)),
    st.tuples(st.just("insert"), st.floats(0, 1), st.binary(min_size=1, max_size=64)),
    st.tuples(st.just("u32"), st.floats(0, 1), st.sampled_from(EXTREMES)),
    st.tuples(st.just("u64"), st.floats(0, 1), st.sampled_from(EXTREMES)),
    st.tuples(st.just("f64"), st.floats(0, 1),
              st.sampled_from([1e300, -1e300, 1e80, float("nan"), float("inf"), 5e-324])),
)


def mutate(data: bytes, mutations: list[tuple[str, float, object]]) -> bytes:
    out = bytearray(data)
    for kind, where, value in mutations:
        if not out:
            break
        at = min(int(where * len(out)), len(out) - 1)
        if kind == "flip":
            out[at] ^= int(value) or 1  # type: ignore[call-overload]
        elif kind == "truncate":
            del out[at:]
        elif kind == "insert":
            out[at:at] = value  # type: ignore[assignment]
        elif kind == "u32":
            out[at : at + 4] = struct.pack("<I", int(value) % 2**32)  # type: ignore[call-overload]
        elif kind == "u64":
            out[at : at + 8] = struct.pack("<Q", int(value) % 2**64)  # type: ignore[call-overload]
        else:
            out[at : at + 8] = struct.pack("<d", float(value))  # type: ignore[arg-type]
    return bytes(out)


@pytest.mark.parametrize("fmt", list(FORMATS))
def test_readers_survive_mutated_files(fmt: str, valid_files: dict[str, tuple[str, bytes]],
                                       tmp_path_factory: pytest.TempPathFactory) -> None:
    name, seed = valid_files[fmt]
    folder = tmp_path_factory.mktemp(f"fuzz-{fmt}")
    path = folder / name
    path.write_bytes(seed)
    read_record(path, CAMPAIGN)  # the seed itself reads

    @FUZZ_SETTINGS
    @given(st.lists(mutation, min_size=1, max_size=4))
    def check(mutations: list[tuple[str, float, object]]) -> None:
        path.write_bytes(mutate(seed, mutations))
        run_input(f"reader {fmt}", lambda: read_record(path, CAMPAIGN))

    check()


MANIFEST = (Path(__file__).parents[1] / "ingest" / "test_manifest.py").read_text()
MANIFEST_SEED = MANIFEST[MANIFEST.index('README_EXAMPLE = """') + 20:].split('"""')[0].encode()


@FUZZ_SETTINGS
@given(st.lists(mutation, min_size=1, max_size=4))
def test_manifest_survives_mutations(mutations: list[tuple[str, float, object]]) -> None:
    from gearwatch.floor.errors import ManifestError
    from ingest.manifest import parse_manifest

    def parse() -> object:
        try:
            data = tomllib.loads(mutate(MANIFEST_SEED, mutations).decode("utf-8", "replace"))
        except tomllib.TOMLDecodeError as error:
            raise ManifestError(str(error)) from None
        return parse_manifest(data, root=Path("/nowhere"), check_files=False)

    run_input("manifest", parse)


@FUZZ_SETTINGS
@given(st.data())
def test_can_assembler_survives_mutated_frames(data: st.DataObject) -> None:
    from gearwatch.floor.campaign import RecordData
    from ingest.can.assembler import RecordAssembler
    from ingest.can.emulator import record_frames

    acc, tach = _signals()
    record = RecordData(channels={"acc": acc[:600], "tach": tach[:600]}, sample_rate_hz=RATE_HZ)
    frames = [m for _, m in record_frames(record, record_id=7, tach_channel="tach")]
    for _ in range(data.draw(st.integers(1, 4))):
        index = data.draw(st.integers(0, len(frames) - 1))
        action = data.draw(st.sampled_from(["drop", "duplicate", "swap", "mutate"]))
        if action == "drop":
            del frames[index]
        elif action == "duplicate":
            frames.insert(index, frames[index])
        elif action == "swap" and index + 1 < len(frames):
            frames[index], frames[index + 1] = frames[index + 1], frames[index]
        elif action == "mutate":
            message = frames[index]
            payload = mutate(bytes(message.data), data.draw(st.lists(mutation, min_size=1,
                                                                   max_size=2)))
            frames[index] = type(message)(arbitration_id=message.arbitration_id,
                                          data=payload[:64], is_fd=True,
                                          is_extended_id=False, bitrate_switch=True)
        if not frames:
            break

    def assemble() -> object:
        assembler = RecordAssembler(source="fuzz")
        out = []
        for message in frames:
            out.extend(assembler.feed(message))
        out.extend(assembler.flush("end of fuzz input"))
        return out

    run_input("can assembler", assemble)


@pytest.fixture(scope="module")
def upload_app(tmp_path_factory: pytest.TempPathFactory):  # type: ignore[no-untyped-def]
    from fastapi.testclient import TestClient

    from gearwatch.floor.settings import Settings
    from gearwatch.usecases.keys import issue_api_key
    from service.app import create_app
    from storage.db import open_database, session_scope
    from tests.service.test_api import MANIFEST as API_MANIFEST

    folder = tmp_path_factory.mktemp("fuzz-upload")
    url = f"sqlite:///{folder / 'db.sqlite'}"
    _, factory = open_database(url)
    with session_scope(factory) as session:
        key = issue_api_key(session, name="fuzz", role="operator")[1]
    settings = Settings(database_url=url, raw_store=folder / "raw", upload_dir=folder / "up",
                        max_upload_bytes=1 << 20)
    with TestClient(create_app(settings), raise_server_exceptions=False) as client:
        headers = {"Authorization": f"Bearer {key}"}
        assert client.post("/api/v1/campaigns", json=API_MANIFEST,
                           headers=headers).status_code == 201
        yield client, headers


def _multipart(entry: bytes, content: bytes) -> tuple[bytes, str]:
    boundary = "fuzzboundary"
    body = io.BytesIO()
    body.write(f"--{boundary}\r\nContent-Disposition: form-data; name=\"entry\"\r\n\r\n".encode())
    body.write(entry + b"\r\n")
    body.write(f"--{boundary}\r\nContent-Disposition: form-data; name=\"file\"; "
               "filename=\"r.wav\"\r\nContent-Type: application/octet-stream\r\n\r\n".encode())
    body.write(content + f"\r\n--{boundary}--\r\n".encode())
    return body.getvalue(), f"multipart/form-data; boundary={boundary}"


@FUZZ_SETTINGS
@given(st.lists(mutation, min_size=1, max_size=4), st.booleans())
def test_upload_route_survives_mutated_forms(upload_app, mutations, mutate_record) -> None:  # type: ignore[no-untyped-def]
    client, headers = upload_app
    buffer = io.BytesIO()
    _wav_to(buffer)
    body, content_type = _multipart(b'{"taken_at": "2026-03-02T08:00:00Z"}', buffer.getvalue())
    if mutate_record:
        start = body.index(b"RIFF")
        body = body[:start] + mutate(body[start:-40], mutations) + body[-40:]
    else:
        body = mutate(body, mutations)

    def post() -> object:
        answer = client.post("/api/v1/campaigns/upload-test/records", content=body,
                             headers={**headers, "Content-Type": content_type})
        assert answer.status_code < 500, answer.text
        if answer.status_code >= 400:
            raise InputError(answer.text)  # a clean refusal
        return answer

    run_input("upload route", post)


def _wav_to(stream: io.BytesIO) -> None:
    acc, tach = _signals()
    scipy.io.wavfile.write(stream, int(RATE_HZ), np.column_stack([acc, tach]).astype(np.float32))
