"""Hand-built campaigns and analyses for storage, job and replay tests."""

from __future__ import annotations

import datetime as dt
from pathlib import Path
from typing import Any

import numpy as np

from gearwatch.floor.campaign import (
    Campaign,
    ChannelConfig,
    RecordEntry,
    RigConfig,
    TachometerConfig,
)
from gearwatch.floor.results import (
    METRIC_NAMES,
    ChannelAnalysis,
    Provenance,
    Quality,
    RecordAnalysis,
    ToothResult,
)

T0 = dt.datetime(2024, 3, 1, 8, 0, tzinfo=dt.UTC)


def campaign_config(
    name: str = "camp-a",
    rig: str = "rig-1",
    *,
    pinion_teeth: int | None = 20,
    gear_teeth: int | None = 21,
    accelerometers: tuple[str, ...] = ("acc",),
    records: tuple[RecordEntry, ...] = (),
    root: Path = Path("."),
) -> Campaign:
    channels = tuple(ChannelConfig(a, "accelerometer", "g") for a in accelerometers)
    return Campaign(
        id=name,
        description=f"test campaign {name}",
        rig=RigConfig(rig, pinion_teeth, gear_teeth, 9.0),
        sample_rate_hz=None,
        tachometer=TachometerConfig("tach"),
        channels=(*channels, ChannelConfig("tach", "tachometer", "V")),
        records=records,
        root=root,
    )


def analysis(
    *,
    sha256: str = "0" * 64,
    teeth: int = 20,
    mci_depth: float | dict[int, float] = 0.1,
    score: dict[int, float] | None = None,
    kurtosis: float = 3.0,
    channels: tuple[str, ...] = ("acc",),
    parameters: dict[str, Any] | None = None,
    curve_length: int = 1280,
    baseline_stats: dict[str, float] | None = None,
) -> RecordAnalysis:
    """A plausible analysis: ``mci_depth`` for every tooth (or per tooth from a dict), and the
    per-tooth ``score`` when given (NaN otherwise, as for a record too short to score)."""
    result_channels = []
    for index, name in enumerate(channels):
        tooth_results = []
        for tooth in range(1, teeth + 1):
            depth = mci_depth.get(tooth, 0.1) if isinstance(mci_depth, dict) else mci_depth
            tooth_score = score.get(tooth, float("nan")) if score is not None else float("nan")
            tooth_results.append(
                ToothResult(tooth, 9.0 + (tooth - 1) * 18.0, depth, 1.0 + 0.01 * tooth, 3.0,
                            score=tooth_score)
            )
        metrics = {m: float(i + 1) for i, m in enumerate(METRIC_NAMES)}
        metrics["kurtosis"] = kurtosis
        angle = np.linspace(0.0, 2 * np.pi, curve_length, endpoint=False)
        result_channels.append(
            ChannelAnalysis(
                channel=name,
                revolutions=40,
                gear_revolutions=38,
                speed_rpm=1500.0 + index,
                samples_per_rev=curve_length,
                metrics=metrics,
                teeth=tooth_results,
                worst_tooth=1 if teeth else None,
                curves={
                    "pinion_average": np.sin(angle * 20).astype(np.float32),
                    "mci": (np.cos(angle) / 3).astype(np.float32),
                },
                baseline_stats=baseline_stats or {"residual_variance": 2.0,
                                                  "envelope_variance": 4.0},
            )
        )
    return RecordAnalysis(
        channels=result_channels,
        quality=Quality([], 0.012, 1490.0, 1508.0),
        provenance=Provenance(sha256, "0.1.0+gtest", parameters or {"samples_per_mesh": 64}),
        speed_rpm=1500.0,
        revolutions=40,
        samples_per_rev=curve_length,
    )


def store_accepted(
    records: Any, campaign: Any, result: RecordAnalysis, *, taken_at: dt.datetime,
    file_name: str, label: str = "", raw_location: str = "/nonexistent",
) -> Any:
    """Add a record to ``campaign`` through ``records`` (a RecordRepository), accept it with
    ``result`` and store that result; returns the record."""
    record = records.add(campaign, sha256=result.provenance.input_sha256, file_name=file_name,
                         raw_location=raw_location, taken_at=taken_at, label=label)
    records.mark_accepted(record, result)
    records.add_result(record, result)
    return record
