"""Known-answer tests of the per-tooth change (dsp.toothchange): where a new transient is
named, what does not count as change (gain, load on the mesh harmonics, noise), and how often
pure noise crosses the default rule's warning level."""

from __future__ import annotations

import numpy as np
import pytest

from detection.default_rules import CHANGE_RULE
from dsp.toothchange import (
    REFERENCE_ADMIT_SCORE,
    campaign_change_scores,
    change_scores,
    gain_free_spectrum,
    log_energy_scores,
    order_weights,
    relative_spread_of,
    tooth_change_energy,
)

SAMPLES_PER_MESH = 64
WARNING = float(CHANGE_RULE["warning_level"])


def gear(teeth: int, seed: int) -> np.ndarray:
    """One pinion revolution: three mesh harmonics plus a fixed per-tooth signature (pitch
    errors through a ringing path), the same every day."""
    rng = np.random.default_rng(seed)
    n = teeth * SAMPLES_PER_MESH
    phase = 2 * np.pi * teeth * np.arange(n) / n
    mesh = np.cos(phase) + 0.4 * np.cos(2 * phase + 0.5) + 0.2 * np.cos(3 * phase + 1.0)
    signature = np.repeat(rng.normal(0.0, 0.05, teeth), SAMPLES_PER_MESH)
    kernel = np.exp(-np.arange(48) / 12.0) * np.cos(2 * np.pi * np.arange(48) / 16.0)
    ringing = np.real(np.fft.ifft(np.fft.fft(signature) * np.fft.fft(kernel, n)))
    return mesh + ringing


def transient(teeth: int, tooth: int, amplitude: float, tooth1_deg: float = 0.0) -> np.ndarray:
    """A decaying burst starting at the tooth's pitch angle (a spall's impact)."""
    n = teeth * SAMPLES_PER_MESH
    start = round((tooth1_deg + (tooth - 1) * 360.0 / teeth) / 360.0 * n)
    burst = np.zeros(n)
    t = np.arange(SAMPLES_PER_MESH)
    burst[:SAMPLES_PER_MESH] = amplitude * np.exp(-t / 20.0) * np.sin(2 * np.pi * t / 12.0)
    return np.roll(burst, start)


def campaign(teeth: int, days: int, noise: float, seed: int,
             spall: tuple[int, int, float] | None = None, gains: dict[int, float] | None = None,
             tooth1_deg: float = 0.0, coloured: bool = False) -> list[np.ndarray]:
    """Daily averages: the gear, noise, and from ``spall[1]`` on a transient that doubles daily.

    ``coloured``: the noise is ten times louder above order N/6 (a resonance the path puts
    there) than below it, where the spall's burst (period 12 samples: order N/12) is; ``noise``
    is then the level of the loud band."""
    rng = np.random.default_rng(seed + 1000)
    base = gear(teeth, seed)
    shape = np.where(np.arange(base.size // 2 + 1) > base.size // 6, 1.0, 0.1)
    out = []
    for day in range(1, days + 1):
        white = rng.standard_normal(base.size)
        average = base + noise * (np.fft.irfft(np.fft.rfft(white) * shape, base.size)
                                  if coloured else white)
        if spall is not None and day >= spall[1]:
            # doubling each day, capped at half the mesh amplitude (a spall this size changes
            # the mesh harmonics themselves, which set the gain normalisation)
            amplitude = min(spall[2] * 2 ** (day - spall[1]), 0.5)
            average = average + transient(teeth, spall[0], amplitude, tooth1_deg)
        out.append(average * (gains or {}).get(day, 1.0))
    return out


@pytest.mark.parametrize(("teeth", "tooth"), [(13, 5), (20, 16), (43, 1), (80, 77)])
def test_a_new_transient_is_named_on_its_tooth_from_the_day_it_appears(
    teeth: int, tooth: int
) -> None:
    days = campaign(teeth, 7, noise=0.02, seed=teeth, spall=(tooth, 5, 0.12), tooth1_deg=33.0)
    scores = campaign_change_scores(days, [33.0] * 7, teeth)
    assert scores[0] is None and scores[1] is None and scores[2] is None  # 3 reference records
    assert float(np.max(scores[3])) < WARNING  # a healthy day: nothing stands out
    for day in (5, 6, 7):
        assert int(np.argmax(scores[day - 1])) + 1 == tooth
        assert float(np.max(scores[day - 1])) > WARNING


def test_a_gain_step_and_a_mesh_harmonic_change_are_not_a_change() -> None:
    teeth = 31
    days = campaign(teeth, 7, noise=0.02, seed=5, gains={5: 2.0, 6: 2.0, 7: 0.5})
    n = teeth * SAMPLES_PER_MESH
    phase = 2 * np.pi * teeth * np.arange(n) / n
    days[3] = days[3] + 0.3 * np.cos(phase + 0.2) + 0.1 * np.cos(2 * phase)  # load: the mesh
    scores = campaign_change_scores(days, [0.0] * 7, teeth)
    assert all(float(np.max(s)) < WARNING for s in scores[2:] if s is not None)


def test_a_spall_in_the_reference_days_is_not_learned_as_normal() -> None:
    """A record that stands out does not join the reference, so the change keeps growing."""
    teeth = 25
    days = campaign(teeth, 8, noise=0.02, seed=9, spall=(11, 4, 0.1))
    scores = campaign_change_scores(days, [0.0] * 8, teeth)
    tooth11 = [float(s[10]) for s in scores[3:] if s is not None]
    assert tooth11[0] < REFERENCE_ADMIT_SCORE < tooth11[1]  # day 4 joins the reference, 5 does not
    assert tooth11[2] > tooth11[1]  # measured against the healthy days, it keeps growing
    assert min(tooth11[1:]) > WARNING


def test_pure_noise_crosses_the_warning_level_in_under_one_percent_of_records() -> None:
    """The false-alarm rate of one record's highest tooth at the rule's warning level, with
    the record's own noise as the only difference from its reference (13, 20 and 80 teeth)."""
    crossings = records = 0
    for seed in range(150):
        for teeth in (13, 20, 80):
            days = campaign(teeth, 5, noise=0.05, seed=seed)
            for scores in campaign_change_scores(days, [0.0] * 5, teeth)[3:]:
                assert scores is not None
                records += 1
                crossings += float(np.max(scores)) > WARNING
    assert records == 900
    assert crossings / records < 0.01


@pytest.mark.parametrize("dof", [10, 60])
def test_the_score_has_the_normal_tail_whatever_the_sectors_degrees_of_freedom(dof: int) -> None:
    """Pure-noise sector energies (scaled χ² with ``dof`` degrees of freedom, 80 teeth, 5000
    records), scored with a pooled unit: the share of tooth scores above 3 is the normal
    distribution's (1.35e-3), for a fast rig's 10 degrees of freedom as for 60. The log score
    used before is three times too shy at 10 (a warning level meant one thing per rig)."""
    rng = np.random.default_rng(dof)
    energies = 7.0 * rng.chisquare(dof, (5000, 80))
    unit = float(np.median([relative_spread_of(e) for e in energies[:50]]))
    above = np.mean([change_scores(e, relative_spread=unit) > 3.0 for e in energies])
    assert 0.7 < above / 1.35e-3 < 2.0  # measured 1.5 (10), 1.1 (60)
    log_above = np.mean([log_energy_scores(e) > 3.0 for e in energies])
    if dof == 10:
        assert log_above / 1.35e-3 < 0.5  # measured 0.3


def test_edge_cases() -> None:
    with pytest.raises(ValueError, match="mesh-harmonic"):
        gain_free_spectrum(np.zeros(40), 10)
    with pytest.raises(ValueError, match="multiple of pinion_teeth"):
        gain_free_spectrum(np.ones(41), 10)
    with pytest.raises(ValueError, match="three teeth"):
        change_scores([1.0, 2.0])
    assert np.all(np.isfinite(change_scores(np.ones(10))))  # noise-free: spread floor
    # averages of another length (samples per mesh changed) are not compared with each other
    days = [*campaign(10, 3, 0.02, 1), np.repeat(campaign(10, 1, 0.02, 1)[0], 2)]
    assert campaign_change_scores(days, [0.0] * 4, 10)[3] is None
    assert campaign_change_scores([None, *days[:3]], [0.0] * 4, 10)[0] is None
    energy = tooth_change_energy(transient(20, 4, 1.0), 20, 0.0)
    assert int(np.argmax(energy)) + 1 == 4


def test_a_record_without_mesh_content_is_left_out_not_the_campaign() -> None:
    days = campaign(20, 6, noise=0.02, seed=2)
    days[2] = np.zeros_like(days[2])  # a dead sensor that day
    scores = campaign_change_scores(days, [0.0] * 6, 20)
    assert scores[2] is None
    assert scores[3] is None  # only two reference records before it
    assert scores[4] is not None and scores[5] is not None


def test_identical_noise_free_records_score_zero_not_round_off() -> None:
    days = [gear(30, 4).astype(np.float32).astype(np.float64) for _ in range(5)]
    for scores in campaign_change_scores(days, [0.0] * 5, 30)[3:]:
        assert scores is not None and np.allclose(scores, 0.0)


def test_an_average_without_mesh_harmonics_beyond_round_off_has_no_change() -> None:
    n = 20 * SAMPLES_PER_MESH
    shaft_only = np.sin(2 * np.pi * np.arange(n) / n) + 1e-9 * np.cos(2 * np.pi * 20 * np.arange(n) / n)
    with pytest.raises(ValueError, match="mesh-harmonic"):
        gain_free_spectrum(shaft_only, 20)
    assert campaign_change_scores([shaft_only] * 4, [0.0] * 4, 20) == [None] * 4


def test_a_change_in_proportion_to_loudness_is_discounted_a_change_on_a_quiet_tooth_is_not() -> None:
    """Known-answer energies: 60 teeth with χ²-like noise energies and log-normal loudness; the
    operating change adds ``0.3·S_k`` to every tooth. The loudest tooth, a plain robust-z outlier,
    is not one against its loudness; the same excess on a quiet tooth still is."""
    rng = np.random.default_rng(7)
    teeth = 60
    loudness = np.exp(rng.normal(0.0, 1.0, teeth))
    loudness[10] = 40.0
    noise = rng.chisquare(64, teeth) / 64
    energy = noise + 0.3 * loudness
    assert change_scores(energy)[10] > WARNING  # without the loudness: a false alarm
    scaled = change_scores(energy, loudness)
    assert float(np.max(scaled)) < WARNING
    quiet = int(np.argmin(loudness))
    energy[quiet] += 0.3 * 40.0
    assert int(np.argmax(change_scores(energy, loudness))) == quiet
    assert change_scores(energy, loudness)[quiet] > WARNING


def test_loudness_scaling_adds_no_false_alarms_on_noise() -> None:
    """Pure noise energies with random loudness (no operating change): the loudness-scaled
    highest tooth crosses the warning level in under 1 % of 2,000 records."""
    rng = np.random.default_rng(11)
    crossings = 0
    for _ in range(2000):
        teeth = int(rng.integers(13, 81))
        energy = rng.chisquare(64, teeth) / 64
        crossings += float(np.max(change_scores(energy, np.exp(rng.normal(0, 1.5, teeth))))) > WARNING
    assert crossings / 2000 < 0.01


@pytest.mark.parametrize("teeth", [20, 47])
def test_weighting_the_orders_finds_a_spall_that_coloured_noise_hides(
    teeth: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The orders are weighted by the inverse of their scatter among the reference records
    (``order_weights``): a spall heard where the noise is quiet stands out, where with every
    order weighted alike the loud band's noise buries it (median of 10 campaigns, onset day)."""
    import dsp.toothchange as toothchange

    def onset_day_scores() -> list[float]:
        days = (campaign(teeth, 6, 0.05, seed, (5, 5, 0.1), coloured=True) for seed in range(10))
        return [float(campaign_change_scores(d, [0.0] * 6, teeth)[4][4]) for d in days]

    weighted = float(np.median(onset_day_scores()))
    monkeypatch.setattr(toothchange, "order_weights",
                        lambda spectra, _teeth: np.ones(np.asarray(spectra).shape[1]))
    flat = float(np.median(onset_day_scores()))
    assert weighted > WARNING > 3.0 > flat  # measured: 9.8 / 2.4 (20 teeth), 9.9 / 1.7 (47)


def test_coloured_noise_alone_crosses_the_warning_level_in_under_one_percent_of_records() -> None:
    crossings = records = 0
    for seed in range(100):
        for teeth in (20, 80):
            days = campaign(teeth, 5, 0.05, seed, coloured=True)
            for scores in campaign_change_scores(days, [0.0] * 5, teeth)[3:]:
                assert scores is not None
                records += 1
                crossings += float(np.max(scores)) > WARNING
    assert records == 400
    assert crossings / records < 0.01  # measured: 2 of 400


def test_order_weights_edge_cases() -> None:
    # one reference record, or records without scatter: every order weighs 1
    spectrum = gain_free_spectrum(gear(10, 0), 10)
    assert np.array_equal(order_weights(spectrum[None, :], 10), np.ones(spectrum.size))
    assert np.array_equal(order_weights(np.stack([spectrum, spectrum]), 10), np.ones(spectrum.size))
    with pytest.raises(ValueError, match="shape"):
        order_weights(spectrum, 10)
    # fewer orders than the smoothing window: one weight per order all the same
    rng = np.random.default_rng(0)
    short = rng.standard_normal((4, 9)) + 1j * rng.standard_normal((4, 9))
    weights = order_weights(short, 3)
    assert weights.shape == (9,) and np.all(np.isfinite(weights)) and np.all(weights > 0)
