"""A small, fast gear-record generator with a per-tooth fingerprint, for the tach-less tests.

Angle-domain model (pinion angle θ in revolutions, a drifting speed): three mesh harmonics, a
fixed per-tooth pattern (pitch errors: a smooth bump of random height under every tooth, the
same every day), a gear-order line, a spall on one pinion tooth from ``onset_day`` on (a decaying
ring that grows daily), white noise. Optional TTL tachometer on the pinion (one pulse per
revolution at θ = n + ``tach_offset``), or a dead (flat) one.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import tomli_w

FS = 10_000.0
PINION, GEAR = 23, 41
RPM = 900.0


def record(
    day: int,
    *,
    seconds: float = 3.0,
    spall_tooth: int = 7,
    onset_day: int = 99,
    noise: float = 0.3,
    start_rev: float = 0.0,
    tach: str = "none",
    seed: int = 0,
    harmonics: tuple[float, ...] = (1.0, 0.5, 0.25),
    pattern: float = 0.25,
) -> dict[str, np.ndarray]:
    """One day's record. ``harmonics``: the mesh harmonics' amplitudes (h = 1, 2, …); the
    per-tooth pattern (amplitude ``pattern``) modulates the strongest of them."""
    rng_gear = np.random.default_rng(1234)          # the same gears every day
    pitch = rng_gear.normal(0.0, 1.0, PINION)
    rng = np.random.default_rng(seed * 1000 + day)
    t = np.arange(int(seconds * FS)) / FS
    f0 = RPM / 60.0 * (1 + rng.uniform(-0.02, 0.02))
    drift = rng.uniform(-0.004, 0.004)
    theta = start_rev + f0 * (t + 0.5 * drift * t**2 / seconds)
    phase = 2 * np.pi * PINION * theta
    x = sum(a * np.cos((h + 1) * phase + (0.0, 0.4, 1.1, 0.7, 0.2, 1.5)[h % 6])
            for h, a in enumerate(harmonics))
    carrier = 1 + int(np.argmax(harmonics))
    position = (theta * PINION) % PINION                       # in teeth, tooth k centred on k - 1
    tooth = np.floor(position + 0.5).astype(int) % PINION
    within = position - np.round(position)                     # −0.5 … 0.5 around the tooth centre
    x += pattern * pitch[tooth] * np.exp(-(within / 0.25) ** 2) * np.sin(carrier * phase + 0.3)
    x += 0.3 * np.cos(2 * np.pi * theta * PINION / GEAR * 3 + 0.2)
    if day >= onset_day:
        depth = 5.0 * (1 + 0.5 * (day - onset_day))
        lag = (position - (spall_tooth - 1)) % PINION / PINION  # revolutions after the spall
        # a ring of a ~2 kHz structural mode (133 orders at 15 rev/s), decaying within a tooth
        x += depth * np.exp(-lag * 150.0) * np.sin(2 * np.pi * 133.0 * lag) * (lag < 0.05)
    x += noise * rng.standard_normal(t.size)
    out = {"acc": x.astype(np.float32), "sample_rate_hz": np.array(FS)}
    if tach != "none":
        level = ((theta % 1.0) < 0.25).astype(np.float32) * 5.0
        out["tach"] = level if tach == "ok" else np.zeros_like(level)
    return out


def write_campaign(
    folder: Path, days: int, *, onset_day: int = 99, tach_days: tuple[int, ...] = (),
    with_tach_channel: bool = False, spall_tooth: int = 7, seconds: float = 3.0,
    nominal_speed: bool = True,
) -> Path:
    """A campaign folder (NPZ records); returns the manifest path. ``nominal_speed=False``: the
    manifest has no ``[rig] nominal_pinion_rpm``."""
    folder.mkdir(parents=True, exist_ok=True)
    records = []
    for day in range(1, days + 1):
        tach = "none"
        if with_tach_channel:
            tach = "ok" if day in tach_days else "dead"
        data = record(day, seconds=seconds, spall_tooth=spall_tooth, onset_day=onset_day,
                      start_rev=0.37 * day, tach=tach)
        name = f"day{day:02d}.npz"
        np.savez(folder / name, **data)
        records.append({"file": name, "taken_at": f"2026-03-{day:02d}T09:00:00Z", "label": f"day {day}"})
    channels = [{"name": "acc", "kind": "accelerometer", "unit": "m/s^2"}]
    manifest: dict[str, object] = {
        "campaign": {"id": f"tachless-{folder.name}", "description": "tach-less test"},
        "rig": {"id": f"rig-{folder.name}", "pinion_teeth": PINION, "gear_teeth": GEAR,
                **({"nominal_pinion_rpm": RPM} if nominal_speed else {})},
        "acquisition": {"sample_rate_hz": FS},
        "channels": channels,
        "records": records,
    }
    if with_tach_channel:
        channels.append({"name": "tach", "kind": "tachometer", "unit": "V"})
        manifest["tachometer"] = {"channel": "tach"}
    path = folder / "campaign.toml"
    path.write_text(tomli_w.dumps(manifest), encoding="utf-8")
    return path
