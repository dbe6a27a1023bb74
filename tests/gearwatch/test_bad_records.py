"""Every kind of bad input becomes a stored record with status ``rejected`` and a clear reason,
and the replay goes on with the next record — real files, the real pipeline, both databases."""

from __future__ import annotations

import gzip
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.io
import scipy.io.wavfile
import tomli_w
from nptdms import ChannelObject, TdmsWriter
from sqlalchemy.orm import Session

from dsp.synthetic import synthetic_gear_record
from gearwatch.floor.results import AnalysisParameters
from gearwatch.usecases.replay import replay_campaign
from storage.raw_store import RawStore
from storage.repositories import CampaignRepository, RecordRepository
from tests.storage import dbfixtures

_postgres_schema = dbfixtures._postgres_schema
db_url = dbfixtures.db_url
db_engine_migrated = dbfixtures.db_engine_migrated
db_engine = dbfixtures.db_engine
db_session = dbfixtures.db_session

FS = 20_000


def good_signals(seconds: float = 2.5, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    synthetic = synthetic_gear_record(duration_s=seconds, seed=seed, tooth1_pitch_angle_deg=337.4)
    return synthetic.acceleration, synthetic.tach_waveform


def wav(path: Path, acc: np.ndarray, tach: np.ndarray, rate: int = FS) -> None:
    scipy.io.wavfile.write(path, rate, np.stack([acc, tach], axis=1).astype(np.float32))


def truncated(writer: Callable[[Path], None]) -> Callable[[Path], None]:
    def write(path: Path) -> None:
        writer(path)
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 2])

    return write


def write_npz(path: Path) -> None:
    acc, tach = good_signals()
    np.savez(path, acc=acc, tach=tach)


def write_h5(path: Path) -> None:
    acc, tach = good_signals()
    with h5py.File(path, "w") as f:
        f.attrs["sample_rate_hz"] = float(FS)
        f["acc"], f["tach"] = acc, tach


def write_mat(path: Path) -> None:
    acc, tach = good_signals()
    scipy.io.savemat(path, {"acc": acc, "tach": tach})


def write_tdms(path: Path) -> None:
    acc, tach = good_signals()
    props = {"wf_increment": 1.0 / FS}
    with TdmsWriter(path) as writer:
        writer.write_segment([ChannelObject("data", "acc", acc, properties=props),
                              ChannelObject("data", "tach", tach, properties=props)])


def write_csv_gz(path: Path) -> None:
    acc, tach = good_signals()
    with gzip.open(path, "wt") as f:
        f.write("acc,tach\n")
        np.savetxt(f, np.stack([acc, tach], axis=1), delimiter=",", fmt="%.6f")


def with_nan(path: Path) -> None:
    acc, tach = good_signals()
    acc[::10] = np.nan  # 10 % of the samples: more than can be bridged
    np.savez(path, acc=acc, tach=tach)


def with_a_few_nan(path: Path) -> None:
    acc, tach = good_signals()
    acc[5000:5010] = np.nan  # one short stretch: bridged, its revolution left out
    np.savez(path, acc=acc, tach=tach)


def clipped(path: Path) -> None:
    acc, tach = good_signals()
    wav(path, np.clip(acc, -0.8, 0.8), tach)


def wrong_rate(path: Path) -> None:
    acc, tach = good_signals()
    wav(path, acc, tach, rate=25_600)


def no_pulses(path: Path) -> None:
    acc, tach = good_signals()
    wav(path, acc, np.zeros_like(tach))


def one_missing_pulse(path: Path) -> None:
    acc, tach = good_signals(seed=2)
    pulse = np.flatnonzero(np.diff((tach > 2.5).astype(int)) == 1)[10]
    tach[pulse - 5 : pulse + 600] = 0.0  # the whole pulse (high for a quarter of 1200 samples)
    wav(path, acc, tach)


def tach_dropout(path: Path) -> None:
    acc, tach = good_signals(seed=3)
    pulses = np.flatnonzero(np.diff((tach > 2.5).astype(int)) == 1)
    tach[pulses[10] - 5 : pulses[14] - 5] = 0.0  # four pulses in a row lost
    wav(path, acc, tach)


def tach_interference(path: Path) -> None:
    acc, tach = good_signals(seed=5)
    pulses = np.flatnonzero(np.diff((tach > 2.5).astype(int)) == 1)
    for a, b in zip(pulses[:-1:2], pulses[1::2], strict=False):  # two spikes in every other period
        for at in (a + (b - a) // 2, a + 3 * (b - a) // 4):
            tach[at : at + 4] = 5.0
    wav(path, acc, tach)


def too_few_revolutions(path: Path) -> None:
    acc, tach = good_signals(seconds=0.9)
    wav(path, acc, tach)


def good(path: Path) -> None:
    acc, tach = good_signals(seed=4)
    wav(path, acc, tach)


# file name → (writer, expected status, words the stored reason must contain)
CASES: dict[str, tuple[Callable[[Path], None], str, str]] = {
    "truncated.wav": (truncated(good), "rejected", "truncated.wav"),
    "truncated.npz": (truncated(write_npz), "rejected", "truncated.npz"),
    "truncated.h5": (truncated(write_h5), "rejected", "truncated.h5"),
    "truncated.mat": (truncated(write_mat), "rejected", "truncated.mat"),
    "truncated.tdms": (truncated(write_tdms), "rejected", "truncated.tdms"),
    "truncated.csv.gz": (truncated(write_csv_gz), "rejected", "truncated.csv.gz"),
    "garbage.wav": (lambda p: p.write_bytes(b"RIFF\x10\x00\x00\x00WAVEfmt garbage"), "rejected",
                    "garbage.wav"),
    "nan.npz": (with_nan, "rejected", "10.00% defective samples"),
    "nan-burst.npz": (with_a_few_nan, "accepted", ""),
    "clipped.wav": (clipped, "rejected", "clipped"),
    "wrong-rate.wav": (wrong_rate, "rejected", "25600 Hz differs from the manifest"),
    # a dead or broken tach no longer loses the record: angle from the mesh phase (issue 11)
    "no-pulses.wav": (no_pulses, "accepted", "no tachometer pulses"),
    # four pulses lost in a row: bridged, the revolutions it touches left out (not a tach failure)
    "tach-dropout.wav": (tach_dropout, "accepted", ""),
    "tach-interference.wav": (tach_interference, "accepted", "irregular tachometer"),
    "short.wav": (too_few_revolutions, "rejected", "revolutions"),
    "one-missing-pulse.wav": (one_missing_pulse, "accepted", ""),
    "good.wav": (good, "accepted", ""),
}


@pytest.fixture
def bad_campaign(tmp_path: Path) -> Path:
    folder = tmp_path / "campaign"
    (folder / "records").mkdir(parents=True)
    entries = []
    for day, (name, (writer, _, _)) in enumerate(CASES.items(), start=1):
        writer(folder / "records" / name)
        entries.append({"file": f"records/{name}", "taken_at": f"2026-03-{day:02d}T09:00:00Z"})
    manifest = {
        "campaign": {"id": "bad-input", "description": "every kind of bad record"},
        "rig": {"id": "rig-bad", "pinion_teeth": 20, "gear_teeth": 21,
                "tooth1_pitch_angle_deg": 337.4},
        "acquisition": {"sample_rate_hz": FS},
        "tachometer": {"channel": "tach", "kind": "pulses", "shaft": "pinion", "pulses_per_rev": 1},
        "channels": [{"name": "acc", "kind": "accelerometer"}, {"name": "tach", "kind": "tachometer"}],
        "records": entries,
    }
    (folder / "campaign.toml").write_text(tomli_w.dumps(manifest))
    return folder


def test_every_bad_record_is_stored_rejected_with_its_reason_and_the_replay_goes_on(
    db_session: Session, bad_campaign: Path, tmp_path: Path
) -> None:
    def factory() -> Session:
        return db_session

    store = RawStore(tmp_path / "raw")
    summary = replay_campaign(bad_campaign / "campaign.toml", factory, store, progress=False)
    assert summary.internal_errors == 0
    campaign = CampaignRepository(db_session).get_by_name("bad-input")
    assert campaign is not None
    stored = {r.file_name: r for r in RecordRepository(db_session).list(campaign_id=campaign.id)}
    assert set(stored) == set(CASES)
    for name, (_, status, words) in CASES.items():
        record = stored[name]
        assert record.status == status, (name, record.reason)
        if status == "rejected":
            assert record.reason and words in record.reason, (name, record.reason)
            assert "\n" not in record.reason and "Traceback" not in record.reason
            assert store.contains(record.sha256, "".join(Path(name).suffixes))  # raw kept
        elif words:  # accepted without its tach: the quality says why
            assert words in record.quality["tach_failure"], (name, record.quality)
    repaired = stored["one-missing-pulse.wav"]
    assert [r["kind"] for r in repaired.quality["tach_repairs"]] == ["missing"]
    bridged = stored["tach-dropout.wav"]
    assert [r["kind"] for r in bridged.quality["tach_repairs"]] == ["bridged"]
    assert bridged.quality["angle_source"] == "tachometer" and not bridged.quality["tach_failure"]
    (channel,) = RecordRepository(db_session).results(bridged.id)[-1].channels
    assert 5 <= channel.quality["rejected_tach_gap_revolutions"] <= 9  # 5 periods + 1 each side


def test_speed_out_of_range_is_rejected(db_session: Session, bad_campaign: Path,
                                        tmp_path: Path) -> None:
    def factory() -> Session:
        return db_session

    replay_campaign(bad_campaign / "campaign.toml", factory, RawStore(tmp_path / "raw"),
                    AnalysisParameters(max_speed_rpm=500.0), progress=False,
                    only=["records/good.wav"])
    campaign = CampaignRepository(db_session).get_by_name("bad-input")
    assert campaign is not None
    (record,) = RecordRepository(db_session).list(campaign_id=campaign.id)
    assert record.status == "rejected" and "speed" in (record.reason or "")
