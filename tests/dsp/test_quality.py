"""The data-quality score (dsp.quality): known values and ordering."""

from __future__ import annotations

import math

import pytest

from dsp.quality import SNR_FLOOR_DB, quality_score, sync_to_noise_db


def test_sync_to_noise_known_values() -> None:
    # average power = synchronous + noise/N: 1 + 4/100 → P_sync = 1, P_res = 4 → −6.02 dB
    assert sync_to_noise_db(1.04, 4.0, 100) == pytest.approx(10 * math.log10(0.25))
    assert sync_to_noise_db(0.01, 4.0, 100) == SNR_FLOOR_DB  # all of the average is noise
    assert sync_to_noise_db(1.0, 0.0, 10) == 200.0  # noise-free
    with pytest.raises(ValueError):
        sync_to_noise_db(1.0, 1.0, 0)


def test_ideal_record_scores_near_one_and_factors_multiply() -> None:
    q = quality_score(revolutions=300, sync_to_noise_db=20.0, speed_variation=0.0,
                      tach_repairs=0, rejected_revolutions=0)
    assert q.score > 0.99
    product = math.prod(q.components().values())
    assert q.score == pytest.approx(product)
    assert all(0 < v <= 1 for v in q.components().values())


def test_each_defect_lowers_the_score() -> None:
    clean = dict(revolutions=100, sync_to_noise_db=0.0, speed_variation=0.02,
                 tach_repairs=0, rejected_revolutions=0)
    base = quality_score(**clean).score  # type: ignore[arg-type]
    worse = [
        {"revolutions": 20},
        {"sync_to_noise_db": -20.0},
        {"speed_variation": 0.4},
        {"tach_repairs": 5},
        {"rejected_revolutions": 30},
    ]
    for change in worse:
        assert quality_score(**(clean | change)).score < base, change  # type: ignore[arg-type]
    # the documented anchors
    assert quality_score(**(clean | {"speed_variation": 0.4})).speed == pytest.approx(0.5)  # type: ignore[arg-type]
    assert quality_score(**(clean | {"rejected_revolutions": 100})).rejections == 0.5  # type: ignore[arg-type]


def test_bad_arguments() -> None:
    with pytest.raises(ValueError):
        quality_score(revolutions=0, sync_to_noise_db=0.0, speed_variation=0.0,
                      tach_repairs=0, rejected_revolutions=0)
