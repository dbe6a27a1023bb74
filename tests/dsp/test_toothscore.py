"""Per-tooth evidence, its jackknife SE and the score on known-answer signals (dsp.toothscore)."""

from __future__ import annotations

import numpy as np
import pytest

from dsp.mci import moving_cepstrum_integral
from dsp.teeth import per_tooth_evidence
from dsp.toothscore import (
    evidence_standard_error,
    jackknife_standard_error,
    leave_one_out_averages,
    revolution_group_sums,
    standout_threshold,
    standout_tooth,
    tooth_scores,
)

SAMPLES_PER_MESH = 64


def mesh_revolutions(rng: np.random.Generator, teeth: int, revolutions: int, noise: float) -> np.ndarray:
    """Revolutions of a three-harmonic mesh signal plus white noise (``noise`` rms per sample)."""
    n = np.arange(teeth * SAMPLES_PER_MESH)
    phase = 2 * np.pi * n / SAMPLES_PER_MESH
    clean = np.cos(phase) + 0.5 * np.cos(2 * phase + 1.0) + 0.25 * np.cos(3 * phase + 2.0)
    return clean + noise * rng.standard_normal((revolutions, n.size))


def chain(revolutions: np.ndarray, teeth: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pipeline's per-tooth chain: evidence of the average, jackknife SE, score."""
    sums, counts = revolution_group_sums(revolutions)
    stack = np.vstack([revolutions.mean(axis=0), leave_one_out_averages(sums, counts)])
    curves = moving_cepstrum_integral(stack, SAMPLES_PER_MESH).filtered
    evidence = per_tooth_evidence(curves, teeth, 0.0, window_samples=SAMPLES_PER_MESH)
    se = evidence_standard_error(evidence[1:])
    return evidence[0], se, tooth_scores(evidence[0], se)


def test_jackknife_of_a_mean_is_the_textbook_standard_error() -> None:
    # For the mean, the delete-one jackknife SE equals s/√n exactly.
    x = np.random.default_rng(1).standard_normal(12)
    replicates = [(x.sum() - xi) / 11 for xi in x]
    assert float(jackknife_standard_error(replicates)) == pytest.approx(x.std(ddof=1) / np.sqrt(12))


def test_leave_one_out_averages_of_groups() -> None:
    revolutions = np.random.default_rng(2).standard_normal((10, 5))
    sums, counts = revolution_group_sums(revolutions, groups=4)
    loo = leave_one_out_averages(sums, counts)
    assert np.allclose(loo[1], np.delete(revolutions, [1, 5, 9], axis=0).mean(axis=0))


def test_group_sums_of_blocks_add_up_to_the_whole_record() -> None:
    # the pipeline accumulates the groups block by block (first = the block's first revolution)
    revolutions = np.random.default_rng(3).standard_normal((23, 7))
    whole_sums, whole_counts = revolution_group_sums(revolutions, groups=5)
    sums, counts = np.zeros((5, 7)), np.zeros(5, dtype=np.int64)
    for start, stop in ((0, 3), (3, 4), (4, 15), (15, 23)):
        s, c = revolution_group_sums(revolutions[start:stop], groups=5, first=start)
        sums += s
        counts += c
    assert np.allclose(sums, whole_sums) and np.array_equal(counts, whole_counts)
    for group in range(5):
        assert np.allclose(whole_sums[group], revolutions[group::5].sum(axis=0))


def test_score_false_alarm_rate_on_pure_noise() -> None:
    # Healthy mesh + white noise: a record names a worst tooth at most ~1 % of the time
    # (the threshold's design rate); 150 records, so ≤ 4 allows sampling error (P ≈ 0.02 at 1 %).
    rng = np.random.default_rng(10)
    teeth = 20
    threshold = standout_threshold(teeth)
    named, all_scores = 0, []
    for _ in range(150):
        _, _, scores = chain(mesh_revolutions(rng, teeth, 24, noise=2.0), teeth)
        named += standout_tooth(scores, threshold) is not None
        all_scores.append(scores)
    assert named <= 4
    # the scores are in standard-error units: their spread is about one (0.86 measured)
    assert 0.6 < float(np.std(all_scores)) < 1.2


def test_a_well_stands_out_at_the_records_noise_level() -> None:
    rng = np.random.default_rng(11)
    teeth = 20
    revolutions = mesh_revolutions(rng, teeth, 24, noise=0.5)
    # a spall-like transient (second derivative of a rectangle) under tooth 7, every revolution
    centre = 6 * SAMPLES_PER_MESH
    revolutions[:, centre - 4] += 1.5
    revolutions[:, centre + 4] -= 1.5
    _, _, scores = chain(revolutions, teeth)
    assert standout_tooth(scores, standout_threshold(teeth)) == 7


def test_a_glitch_sample_does_not_stand_out() -> None:
    # One sample at 1000× the rms in one revolution digs a deep well in the plain average, but
    # it sits in one jackknife group only: the tooth's SE is as large as its depth.
    rng = np.random.default_rng(12)
    teeth = 20
    revolutions = mesh_revolutions(rng, teeth, 24, noise=0.5)
    revolutions[5, 10 * SAMPLES_PER_MESH + 3] = 1000.0
    evidence, se, scores = chain(revolutions, teeth)
    assert evidence[10] > 10 * np.median(se)      # the plain evidence is fooled ...
    assert standout_tooth(scores, standout_threshold(teeth)) is None   # ... the score is not


def test_a_gain_step_changes_no_score() -> None:
    rng = np.random.default_rng(13)
    teeth = 13
    revolutions = mesh_revolutions(rng, teeth, 24, noise=1.0)
    revolutions[:, 3 * SAMPLES_PER_MESH] += 2.0
    _, se1, scores1 = chain(revolutions, teeth)
    _, se2, scores2 = chain(7.5 * revolutions, teeth)
    assert np.allclose(scores1, scores2, atol=1e-9)
    assert np.allclose(se1, se2, atol=1e-12)


def test_standout_threshold_grows_with_the_number_of_teeth() -> None:
    assert standout_threshold(13) < standout_threshold(20) < standout_threshold(80)
    assert standout_threshold(20, 0.05) < standout_threshold(20, 0.01)


def test_bad_inputs_are_refused() -> None:
    with pytest.raises(ValueError):
        leave_one_out_averages(np.ones((1, 4)), [1])
    with pytest.raises(ValueError):
        tooth_scores([1.0, 2.0], [1.0])
    with pytest.raises(ValueError):
        standout_threshold(0)
    assert standout_tooth([np.nan, np.nan], 1.0) is None
