"""A tooth event that rings in time, under a drifting speed: the non-synchronous power keeps it.

Known answer: a 4 kHz mode (ζ 0.03) rung once per revolution as pinion tooth 7 of 20 passes its
pitch point, on a mesh tone and white noise. At a steady speed the ring sits at the same angle
every revolution — the average keeps it and the non-synchronous power of tooth 7 is ordinary;
with the speed ramping ±5 % or ±15 % over the record the ring's cycles fall at other angles in
every revolution, and the power about the average stands out on tooth 7 (:mod:`dsp.nonsync`).
"""

from __future__ import annotations

import numpy as np
import pytest

from gearwatch.floor.campaign import (
    Campaign,
    ChannelConfig,
    RecordData,
    RigConfig,
    TachometerConfig,
)
from gearwatch.floor.results import AnalysisParameters
from gearwatch.usecases.analyze import analyze_record

TEETH = 20
RUNG_TOOTH = 7
SAMPLE_RATE_HZ = 20_000.0


def ringing_record(drift: float, seconds: float = 6.0, seed: int = 0) -> RecordData:
    """Speed ramping linearly from (1 − drift) to (1 + drift) × 1000 rpm; a TTL tach on the pinion."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * SAMPLE_RATE_HZ)) / SAMPLE_RATE_HZ
    rev_hz = 1000.0 / 60.0 * (1.0 + drift * (2.0 * t / seconds - 1.0))
    theta = 0.3 + np.concatenate([[0.0], np.cumsum((rev_hz[1:] + rev_hz[:-1]) / 2) / SAMPLE_RATE_HZ])
    x = np.cos(2 * np.pi * TEETH * theta) + rng.normal(0.0, 0.5, t.size)
    omega, zeta = 2 * np.pi * 4000.0, 0.03
    tau = np.arange(200) / SAMPLE_RATE_HZ
    ring = np.exp(-zeta * omega * tau) * np.sin(omega * np.sqrt(1 - zeta**2) * tau)
    for passing in np.arange(np.ceil(theta[0]), np.floor(theta[-1])) + (RUNG_TOOTH - 1) / TEETH:
        i = int(np.searchsorted(theta, passing))
        n = min(ring.size, t.size - i)
        x[i : i + n] += ring[:n]
    tach = np.where(theta % 1.0 < 0.25, 5.0, 0.0)
    return RecordData({"acc": x, "tach": tach}, SAMPLE_RATE_HZ, source="ringing")


CAMPAIGN = Campaign(
    id="ringing", description="", sample_rate_hz=SAMPLE_RATE_HZ,
    rig=RigConfig(id="rig", pinion_teeth=TEETH, gear_teeth=TEETH + 1, tooth1_pitch_angle_deg=0.0),
    tachometer=TachometerConfig(channel="tach"),
    channels=(ChannelConfig("acc", "accelerometer"), ChannelConfig("tach", "tachometer")),
)


def nonsync_z(drift: float) -> np.ndarray:
    analysis = analyze_record(ringing_record(drift), CAMPAIGN, AnalysisParameters(),
                              input_sha256="0" * 64)
    return np.array([tooth.nonsync_z for tooth in analysis.channels[0].teeth])


def test_steady_speed_keeps_the_ring_in_the_average() -> None:
    z = nonsync_z(0.0)
    assert abs(z[RUNG_TOOTH - 1]) < 3.0


@pytest.mark.parametrize("drift", [0.05, 0.15])
def test_drifting_speed_moves_the_ring_into_the_nonsync_power(drift: float) -> None:
    z = nonsync_z(drift)
    assert int(np.argmax(z)) == RUNG_TOOTH - 1
    assert z[RUNG_TOOTH - 1] > 6.0
    assert np.max(np.delete(z, RUNG_TOOTH - 1)) < 3.0
