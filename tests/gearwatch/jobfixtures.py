"""A small campaign on disk (WAV records + campaign.toml) and a stand-in analyzer.

The stand-in keeps job and replay tests independent of the signal chain: it reads the
accelerometer's RMS as every tooth's ``mci_depth`` (so a test controls the indicator through the
amplitude it writes), rejects a record whose tachometer is flat, and fails like a bug when the
accelerometer's first sample is exactly 123.0.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path
from typing import Any

import numpy as np
import scipy.io.wavfile

from gearwatch.floor.campaign import Campaign, RecordData, RecordEntry
from gearwatch.floor.errors import RecordRejected
from gearwatch.floor.results import AnalysisParameters, RecordAnalysis
from ingest.manifest import dump_manifest, load_manifest
from tests.storage.factories import T0, analysis, campaign_config

SAMPLE_RATE_HZ = 2000


def write_record(path: Path, amplitude: float, *, flat_tach: bool = False,
                 first_sample: float | None = None, phase_rad: float = 0.0,
                 n_samples: int = 4000) -> Path:
    """Two channels (acc, tach at 25 Hz); the acc RMS is ``amplitude`` (whole periods)."""
    n = n_samples
    t = np.arange(n) / SAMPLE_RATE_HZ
    acc = amplitude * np.sqrt(2) * np.sin(2 * np.pi * 50 * t + phase_rad)
    if first_sample is not None:
        acc[0] = first_sample
    tach = np.zeros(n) if flat_tach else (np.sin(2 * np.pi * 25 * t) > 0.95) * 5.0
    scipy.io.wavfile.write(path, SAMPLE_RATE_HZ, np.column_stack([acc, tach]).astype(np.float32))
    return path


def make_campaign(folder: Path, amplitudes: list[float], *, name: str = "camp-a",
                  rig: str = "rig-1", flat: tuple[int, ...] = (),
                  truncated: tuple[int, ...] = (), n_samples: int = 4000) -> Campaign:
    """``day<NN>.wav`` per amplitude, one day apart, and ``campaign.toml`` listing them."""
    folder.mkdir(parents=True, exist_ok=True)
    entries = []
    for day, amplitude in enumerate(amplitudes):
        # A different phase every day: equal amplitudes still make different files.
        path = write_record(folder / f"day{day:02d}.wav", amplitude, flat_tach=day in flat,
                            phase_rad=0.1 * day, n_samples=n_samples)
        if day in truncated:
            path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
        taken_at = (T0 + dt.timedelta(days=day)).isoformat()
        entries.append(RecordEntry(path.name, taken_at, f"day {day}"))
    config = campaign_config(name, rig, records=tuple(entries), root=folder)
    (folder / "campaign.toml").write_text(dump_manifest(config))
    return load_manifest(folder / "campaign.toml")


class FakeAnalyzer:
    """Stand-in for the pipeline (see the module docstring); records what it was given."""

    def __init__(self) -> None:
        self.calls: list[dict[str, Any]] = []

    def __call__(self, record: RecordData, campaign: Campaign, params: AnalysisParameters,
                 input_sha256: str, baselines: dict[str, dict[str, float]]) -> RecordAnalysis:
        self.calls.append({"source": record.source, "sha256": input_sha256,
                           "baselines": baselines, "params": params})
        acc = record.channel("acc")
        if float(acc[0]) == 123.0:
            raise ZeroDivisionError("a bug in the pipeline")
        if np.ptp(record.channel("tach")) == 0:
            raise RecordRejected("tachometer: no pulses found")
        depth = float(np.sqrt(np.mean(acc.astype(np.float64) ** 2)))
        parameters = {**params.to_dict(), "pinion_teeth": campaign.rig.pinion_teeth,
                      "gear_teeth": campaign.rig.gear_teeth,
                      "tooth1_pitch_angle_deg": campaign.rig.tooth1_pitch_angle_deg}
        return analysis(sha256=input_sha256, mci_depth=round(depth, 4), parameters=parameters,
                        baseline_stats={"residual_variance": depth, "envelope_variance": 1.0})
