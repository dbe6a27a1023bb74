"""The per-tooth change through the whole per-record chain on records of the independent
generator (``physics.independent``: one line-of-action DOF, per-pair stiffness, partial-face pits,
a modal transfer path with delay — a simulator that differs in kind from the one the method was
first built on), at contact ratios 1.4 and 1.9, with day-to-day load ±10 % and speed ±5 %: the
healthy days name no tooth, the spalled days name the spalled one."""

from __future__ import annotations

import numpy as np
import pytest

from detection.default_rules import CHANGE_RULE
from dsp.toothchange import campaign_change_scores
from gearwatch.usecases.analyze import analyze_record
from physics.independent import Spall, campaign_days, generate_record, random_model

WARNING = float(CHANGE_RULE["warning_level"])
CUSUM_ALLOWANCE = float(CHANGE_RULE["cusum_reference"])


@pytest.mark.parametrize(
    ("seed", "contact_ratio", "pinion_teeth", "gear_teeth", "tooth"),
    [(3, 1.4, 23, 37, 9), (5, 1.9, 41, 67, 30)],
)
def test_the_change_names_the_spalled_tooth_and_no_healthy_one(
    seed: int, contact_ratio: float, pinion_teeth: int, gear_teeth: int, tooth: int
) -> None:
    base = random_model(seed, contact_ratio=contact_ratio, pinion_teeth=pinion_teeth,
                        gear_teeth=gear_teeth, noise_to_signal=0.5, speed_drift_fraction=0.05,
                        seconds=4.0, dynamics="linear")
    plan = campaign_days(base, days=5, onset_day=4, spall=Spall(tooth=tooth), depths_um=(10, 20),
                         extents=(0.3, 0.4), face_fractions=(0.5, 0.6), load_jitter=0.1,
                         speed_jitter=0.05, seed=seed)
    averages, angles = [], []
    for day in plan:
        record = generate_record(day.model, seed=day.seed)
        channel = analyze_record(record.record_data(), record.campaign(),
                                 input_sha256="0" * 64).channels[0]
        averages.append(np.asarray(channel.curves["pinion_average"], dtype=np.float64))
        angles.append(float(channel.baseline_stats["tooth1_pitch_angle_deg"]))
    # two reference records (the default waits for three): the localisation on these geometries
    # is what is tested here, on the campaigns this test was written with
    scores = campaign_change_scores(averages, angles, pinion_teeth, min_reference_records=2)
    assert scores[0] is None and scores[1] is None
    assert scores[2] is not None and float(np.max(scores[2])) < WARNING, np.round(scores[2], 1)
    day4, day5 = scores[3], scores[4]
    assert day4 is not None and day5 is not None
    # 10 µm on day 4: the spalled tooth leads and at least feeds the rule's CUSUM
    assert int(np.argmax(day4)) + 1 == tooth, np.round(day4, 1)
    assert float(day4[tooth - 1]) > CUSUM_ALLOWANCE
    # 20 µm over 0.4 of the path on day 5: the spalled tooth is above the warning level; at
    # contact ratio 1.9 the next tooth may rise as high (a wide pit is in mesh with both)
    assert float(day5[tooth - 1]) > WARNING, np.round(day5, 1)
    assert int(np.argmax(day5)) + 1 in (tooth, tooth % pinion_teeth + 1), np.round(day5, 1)
