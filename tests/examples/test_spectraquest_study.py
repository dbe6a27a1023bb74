"""The SpectraQuest study's core on one real pair (0 % load): tach-less pulses, frame, tooth count.

The reconciliation itself is not run here (one pair takes 1-2 min on one core); the study
script runs it (docs/spectraquest-study.md). Skips only when the shared data are missing.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

STUDY_PATH = Path(__file__).resolve().parents[2] / "examples" / "spectraquest-gfd" / "reconcile_study.py"
REVOLUTIONS = 80
"""First ~80 revolutions (34 400 samples) of each record: 16 hunting periods of 32/80."""


def _study() -> ModuleType:
    spec = importlib.util.spec_from_file_location("spectraquest_reconcile_study", STUDY_PATH)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


study = _study()
pytestmark = pytest.mark.skipif(
    not (study.data_dir() / "h30hz0.csv.gz").is_file(),
    reason=f"SpectraQuest data not found under {study.data_dir()} (set GEARWATCH_SHARED_DIR)",
)


@pytest.fixture(scope="module")
def pair() -> tuple[np.ndarray, np.ndarray]:
    n = int(REVOLUTIONS * study.SAMPLES_PER_REV_README)
    return study.load_signal("b30hz0")[:n], study.load_signal("h30hz0")[:n]


def test_tachless_pulse_period_matches_readme(pair: tuple[np.ndarray, np.ndarray]) -> None:
    broken, healthy = pair
    result = study.study_pair(broken, healthy, record="b30hz0", reference="h30hz0", run_reconcile=False)
    fs = study.ASSUMED_SAMPLE_RATE_HZ
    for estimate in (result.record_pulses, result.reference_pulses):
        periods = np.diff(estimate.pulse_times_s) * fs
        assert estimate.pulse_times_s.size >= REVOLUTIONS - 15  # band-pass edges dropped
        # README: ~430 samples/rev at 0 % load; every revolution within 2 %.
        assert np.all(np.abs(periods / 430.0 - 1.0) < 0.02)
        assert estimate.line_prominence_db > 20.0
    assert 0 <= result.alignment.mesh_periods < 160
    assert set(result.indicators) == {"b30hz0", "h30hz0"}
    assert set(result.shaft_match) == {"pinion", "gear"}


def test_same_gearbox_matches_across_loads_broken_does_not() -> None:
    # The study's frame argument: two healthy records (0 and 10 % load) show the same
    # tooth-specific pattern on both shafts (measured 0.95 / 0.90); healthy vs broken at the
    # same load do not (0.28 / 0.18), so the broken records are not "healthy + one tooth".
    healthy0, healthy10, broken0 = (study.load_signal(n) for n in ("h30hz0", "h30hz10", "b30hz0"))
    p0, p10, pb = (study.tachless_pulses(x).pulse_times_s for x in (healthy0, healthy10, broken0))
    fs = study.ASSUMED_SAMPLE_RATE_HZ
    same = study.shaft_matches(healthy10, p10, healthy0, p0, fs)
    other = study.shaft_matches(broken0, pb, healthy0, p0, fs)
    for wheel in ("pinion", "gear"):
        assert same[wheel].correlation > 0.8
        assert same[wheel].correlation > same[wheel].runner_up + 0.3
        assert other[wheel].correlation < 0.5


def test_gear_tooth_count_from_sidebands() -> None:
    # The whole record (~200 revolutions): 80 and 81 teeth put the first gear sideband 0.005
    # orders apart, one bin of a 200-revolution spectrum.
    healthy = study.load_signal("h30hz0")
    estimate = study.tachless_pulses(healthy)
    shares = study.gear_teeth_scan(healthy, study.ASSUMED_SAMPLE_RATE_HZ, estimate.pulse_times_s)
    ranked = sorted(shares, key=shares.__getitem__, reverse=True)
    assert ranked[0] == 80  # the 0.4-order sidebands: 32/80
    assert shares[80] > 1.5 * shares[ranked[1]]
