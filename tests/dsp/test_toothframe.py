"""Tooth-frame alignment without a tachometer (:mod:`dsp.toothframe`): shifted, ambiguous, no match, spall."""

from __future__ import annotations

import numpy as np
import pytest

from dsp.toothframe import (
    MIN_CONFIRMED_SEPARATION_Z,
    MIN_SECTOR_PATTERN_Z,
    MIN_SEPARATION_Z,
    align_fingerprint,
    circular_shift,
    frame_delay_samples,
    loud_sectors,
    mesh_phase_position,
    resample_periodic,
    sector_pattern_z,
    shift_separation_z,
    tooth_energy_pattern,
    tooth_fingerprint,
)

TEETH, SPM = 29, 32
N = TEETH * SPM


def gear_average(seed: int = 0, pattern_seed: int = 7, noise: float = 0.02) -> np.ndarray:
    """Mesh harmonics + a smooth per-tooth pattern (the fingerprint) + runout + noise, tach frame."""
    n = np.arange(N)
    teeth = np.random.default_rng(pattern_seed).normal(0.0, 0.3, TEETH)
    pattern = np.convolve(np.tile(np.repeat(teeth, SPM), 3), np.hanning(SPM) / np.hanning(SPM).sum(), "same")[N : 2 * N]
    mesh = np.cos(2 * np.pi * TEETH * (n - 3.3) / N) + 0.4 * np.cos(4 * np.pi * TEETH * n / N + 1.0)
    runout = 0.3 * np.cos(2 * np.pi * n / N + 0.5)
    return mesh * (1 + runout) + pattern + noise * np.random.default_rng(seed).standard_normal(N)


def test_fractional_shift_is_exact_and_invertible() -> None:
    spectrum = np.fft.rfft(gear_average())
    spectrum[-1] = 0.0  # exact for a band-limited average (the Nyquist bin has no phase to move)
    x = np.fft.irfft(spectrum, n=N)
    assert np.allclose(circular_shift(circular_shift(x, 17.25), -17.25), x, atol=1e-9)
    assert np.array_equal(circular_shift(x, 3), np.roll(x, 3))
    assert np.allclose(resample_periodic(resample_periodic(x, 2 * N), N), x, atol=1e-9)


@pytest.mark.parametrize("shift_teeth, fraction", [(0, 0.0), (5, 0.3), (28, 0.71), (13, 0.5)])
def test_a_shifted_record_is_brought_back_into_the_reference_frame(shift_teeth: int, fraction: float) -> None:
    reference = gear_average(seed=1)
    # another day: same gear, other noise, origin moved by whole teeth plus a fraction of a mesh period
    record = circular_shift(gear_average(seed=2), (shift_teeth + fraction) * SPM)
    alignment = align_fingerprint(tooth_fingerprint(record, TEETH), tooth_fingerprint(reference, TEETH), TEETH)
    assert alignment.refusal == ""
    assert alignment.separation_z >= MIN_SEPARATION_Z
    # into the reference's own (tach) frame: where its mesh harmonic peaks
    delay = frame_delay_samples(record, TEETH, alignment.delay_samples, mesh_phase_position(reference, TEETH))
    back = circular_shift(record, delay)
    assert np.corrcoef(back, reference)[0, 1] > 0.99
    assert np.max(np.abs(back - gear_average(seed=2))) < 0.2  # the same samples, not a neighbour tooth


def test_a_growing_spall_does_not_move_the_frame() -> None:
    reference = gear_average(seed=1)
    spalled = gear_average(seed=3)
    spalled[10 * SPM : 10 * SPM + 20] += 8.0 * np.hanning(20)  # one tooth, far louder than the pattern
    record = circular_shift(spalled, 17 * SPM)
    alignment = align_fingerprint(tooth_fingerprint(record, TEETH), tooth_fingerprint(reference, TEETH), TEETH)
    assert (alignment.shift_teeth, alignment.refusal) == (17, "")


def ringing_spall(start_sample: int, amplitude: float = 8.0) -> np.ndarray:
    """An impact that rings for about three teeth through the transfer path."""
    t = (np.arange(N) - start_sample) % N
    return np.where(t < 3 * SPM, amplitude * np.exp(-t / 12) * np.sin(2 * np.pi * t / 9), 0.0)


def test_a_ringing_spall_stays_in_its_own_tooth_sectors() -> None:
    # the mesh waveform is every tooth's share: taken as the mean over all sectors it would
    # carry 1/teeth of the impact into every other sector (0.96 correlation there, measured)
    healthy = gear_average(seed=2)
    spalled = healthy + ringing_spall(11 * SPM + 5)
    away = np.ones(TEETH, dtype=bool)
    away[10:15] = False
    a = tooth_fingerprint(spalled, TEETH).reshape(TEETH, SPM)[away]
    b = tooth_fingerprint(healthy, TEETH).reshape(TEETH, SPM)[away]
    assert np.corrcoef(a.ravel(), b.ravel())[0, 1] > 0.995
    # the loudest sector and its ringing (one before, two after) are what a retry leaves out
    assert np.flatnonzero(loud_sectors(spalled, TEETH)).tolist() == [10, 11, 12, 13]
    assert not loud_sectors(np.cos(2 * np.pi * TEETH * np.arange(N) / N), TEETH).any()


def test_left_out_sectors_have_no_say_in_either_test() -> None:
    reference = tooth_fingerprint(gear_average(seed=1), TEETH)
    record = tooth_fingerprint(circular_shift(gear_average(seed=2, noise=0.2), 7 * SPM), TEETH)
    left_out = np.zeros(TEETH, dtype=bool)
    left_out[[3, 4, 5, 6]] = True
    garbled = record.copy()
    garbled[3 * SPM : 7 * SPM] = np.random.default_rng(5).normal(0.0, 5.0, 4 * SPM)
    clean = align_fingerprint(record, reference, TEETH, left_out_sectors=left_out)
    other = align_fingerprint(garbled, reference, TEETH, left_out_sectors=left_out)
    assert (clean.shift_teeth, other.shift_teeth) == (7, 7)
    assert other.left_out_sectors == (3, 4, 5, 6)
    assert other.separation_z == pytest.approx(clean.separation_z, rel=1e-9)
    assert other.sector_pattern_z == pytest.approx(clean.sector_pattern_z, rel=1e-9)
    # garbage where nothing is left out does have its say
    assert align_fingerprint(garbled, reference, TEETH).separation_z < 0.5 * clean.separation_z


def test_with_the_loud_tooth_left_out_a_growing_spall_no_longer_weakens_the_energy_pattern() -> None:
    # plain: the spalled sectors' energy votes, and the louder the spall the less the pattern
    # supports the right shift (measured 2.8 → 0.0 here); left out, it stays at 2.5
    reference = tooth_fingerprint(gear_average(seed=1), TEETH)
    healthy = circular_shift(gear_average(seed=4, noise=0.3), 7 * SPM)
    plain, left_out = [], []
    for amplitude in (4.0, 16.0):
        spalled = healthy + ringing_spall(11 * SPM + 5, amplitude)
        fingerprint = tooth_fingerprint(spalled, TEETH)
        plain.append(align_fingerprint(fingerprint, reference, TEETH).sector_pattern_z)
        left_out.append(align_fingerprint(fingerprint, reference, TEETH,
                                          left_out_sectors=loud_sectors(spalled, TEETH)).sector_pattern_z)
    assert plain[1] < plain[0] - 1.0
    assert left_out[0] > 2.0 and left_out[1] == pytest.approx(left_out[0], abs=0.1)


def test_the_masked_separation_over_every_sample_is_the_plain_one() -> None:
    rng = np.random.default_rng(3)
    reference = rng.normal(size=20 * SPM)
    record = np.roll(reference, 5 * SPM) + 0.5 * rng.normal(size=reference.size)
    others = [4 * SPM, 6 * SPM + 3, 15 * SPM]
    plain = shift_separation_z(record, reference, 5 * SPM, others, 20)
    masked = shift_separation_z(record, reference, 5 * SPM, others, 20, keep=np.ones(reference.size, dtype=bool))
    np.testing.assert_allclose(masked, plain, rtol=1e-9)


def test_an_ambiguous_pattern_is_refused_with_the_margin() -> None:
    # a pattern that repeats after half a revolution of a 28-tooth wheel: two shifts fit equally
    teeth = 28
    n = np.arange(teeth * SPM)
    half = np.random.default_rng(4).normal(0.0, 0.3, teeth // 2)
    pattern = np.repeat(np.tile(half, 2), SPM)
    average = np.cos(2 * np.pi * teeth * n / n.size) + pattern
    other = np.roll(average, 3 * SPM) + 0.01 * np.random.default_rng(5).standard_normal(n.size)
    alignment = align_fingerprint(tooth_fingerprint(other, teeth), tooth_fingerprint(average, teeth), teeth)
    assert alignment.shift_teeth is None
    assert alignment.refusal.startswith("ambiguous tooth frame")
    assert "standard errors" in alignment.refusal and alignment.separation_z < MIN_SEPARATION_Z
    assert "margin" in alignment.refusal and alignment.margin < 0.05  # the two halves fit alike


def test_a_refusal_says_whether_the_energy_pattern_confirmed_the_shift() -> None:
    """The refusal names the bar that was missed: a confirming energy pattern is not reported as
    one below its level (the message read "stands at 4.2 < 2.5")."""
    record = np.roll(gear_average(), 5 * SPM) + 0.02 * np.random.default_rng(9).standard_normal(N)
    fingerprint, reference = tooth_fingerprint(record, TEETH), tooth_fingerprint(gear_average(), TEETH)
    confirmed = align_fingerprint(fingerprint, reference, TEETH, min_separation_z=1e9,
                                  min_confirmed_separation_z=1e9, min_sector_pattern_z=0.0)
    assert confirmed.shift_teeth is None and confirmed.sector_pattern_z > 0.0
    assert f"which it has ({confirmed.sector_pattern_z:.1f} ≥ 0)" in confirmed.refusal
    unconfirmed = align_fingerprint(fingerprint, reference, TEETH, min_separation_z=1e9,
                                    min_confirmed_separation_z=1e9, min_sector_pattern_z=1e9)
    assert f"which stands at {unconfirmed.sector_pattern_z:.1f} < 1e+09" in unconfirmed.refusal


def smooth_average(seed: int, noise: float, teeth: int = 61) -> np.ndarray:
    """A wheel whose tooth pattern is mostly smooth (runout, a slow index error: orders 1–3)
    with a small tooth-to-tooth part: neighbouring shifts correlate almost as well."""
    n = np.arange(teeth * SPM)
    rng = np.random.default_rng(11)
    smooth = sum(rng.normal(0, 0.3) * np.cos(2 * np.pi * k * n / n.size + rng.uniform(0, 6)) for k in (1, 2, 3))
    fine = np.convolve(np.tile(np.repeat(rng.normal(0, 0.05, teeth), SPM), 3), np.hanning(SPM) / SPM * 2, "same")
    mesh = np.cos(2 * np.pi * teeth * n / n.size)
    return mesh + smooth + fine[n.size : 2 * n.size] + noise * np.random.default_rng(seed).standard_normal(n.size)


def test_a_smooth_pattern_is_placed_by_the_orders_that_tell_neighbours_apart() -> None:
    # neighbouring shifts correlate within a few hundredths (the old margin rule of 0.20 refused
    # this), but the tooth-to-tooth orders stand well clear of the noise: the right tooth, accepted
    teeth = 61
    reference = smooth_average(seed=1, noise=0.02, teeth=teeth)
    record = circular_shift(smooth_average(seed=2, noise=0.02, teeth=teeth), 23 * SPM)
    alignment = align_fingerprint(tooth_fingerprint(record, teeth), tooth_fingerprint(reference, teeth), teeth)
    assert alignment.margin < 0.05
    assert (alignment.shift_teeth, alignment.refusal) == (23, "")
    assert alignment.separation_z >= MIN_SEPARATION_Z


def test_a_smooth_pattern_in_heavy_noise_is_refused_not_guessed() -> None:
    # the same wheel with the tooth-to-tooth part buried: refused for every noise draw (the best
    # candidate is sometimes the neighbour, tooth 24)
    teeth = 61
    reference = smooth_average(seed=1, noise=0.02, teeth=teeth)
    for seed in range(3, 8):
        record = circular_shift(smooth_average(seed=seed, noise=1.5, teeth=teeth), 23 * SPM)
        alignment = align_fingerprint(tooth_fingerprint(record, teeth), tooth_fingerprint(reference, teeth), teeth)
        assert alignment.shift_teeth is None and alignment.refusal, (seed, alignment)


def dispersed_day(seed: int, shift_teeth: int, phase_turn_rad: float, noise: float, teeth: int = 41) -> np.ndarray:
    """A wheel whose teeth deviate by very different amounts (log-normal), seen through a path
    whose phase turns with the square of the order by ``phase_turn_rad`` at an eighth of the
    band (another day's speed moves a resonance: the waveform inside each sector changes, how much
    each tooth deviates does not), moved by ``shift_teeth`` + 0.3 teeth, plus noise."""
    n_samples = teeth * SPM
    rng = np.random.default_rng(99)
    amplitude = rng.lognormal(0.0, 1.0, teeth)
    wave = np.fft.rfft(rng.normal(size=n_samples))
    wave[n_samples // 8 :] = 0.0
    pattern = np.fft.irfft(wave, n=n_samples) * np.repeat(amplitude, SPM)
    n = np.arange(n_samples)
    x = np.cos(2 * np.pi * teeth * n / n_samples) + 0.5 * pattern / np.std(pattern)
    orders = np.arange(n_samples // 2 + 1)
    x = np.fft.irfft(np.fft.rfft(x) * np.exp(1j * phase_turn_rad * (orders / (n_samples / 8)) ** 2), n=n_samples)
    x = circular_shift(x, (shift_teeth + 0.3) * SPM)
    return x + noise * np.random.default_rng(seed).standard_normal(n_samples)


def test_a_path_that_turns_the_phase_is_placed_when_the_tooth_energy_pattern_confirms() -> None:
    # the waveform match falls below 3.5 standard errors (the candidate is still the right
    # shift); the per-tooth energy pattern points to the same shift, and that accepts it
    teeth = 41
    reference = tooth_fingerprint(dispersed_day(1, 0, 0.0, 0.05), teeth)
    accepted = 0
    for seed in range(2, 8):
        record = tooth_fingerprint(dispersed_day(seed, 17, 12.0, 0.3), teeth)
        alignment = align_fingerprint(record, reference, teeth)
        assert alignment.candidate_teeth == 17 and alignment.separation_z < MIN_SEPARATION_Z
        strict = align_fingerprint(record, reference, teeth, min_sector_pattern_z=np.inf)
        assert strict.shift_teeth is None and "energy pattern" in strict.refusal
        if alignment.shift_teeth is not None:
            accepted += 1
            assert alignment.shift_teeth == 17 and alignment.confirmed_by_sector_pattern
            assert alignment.separation_z >= MIN_CONFIRMED_SEPARATION_Z
            assert alignment.sector_pattern_z >= MIN_SECTOR_PATTERN_Z
    assert accepted >= 4  # measured: 5 of the 6 draws
    # an angle read along a sweeping speed gets no second witness: the same records are refused
    for seed in range(2, 8):
        record = tooth_fingerprint(dispersed_day(seed, 17, 12.0, 0.3), teeth)
        swept = align_fingerprint(record, reference, teeth, no_confirmation_reason="the speed swept 12 %")
        assert swept.shift_teeth is None and not swept.confirmed_by_sector_pattern
        assert "no confirmation by the per-tooth energy pattern: the speed swept 12 %" in swept.refusal


def test_the_tooth_energy_pattern_supports_the_right_shift_only() -> None:
    teeth = 41
    reference = tooth_fingerprint(dispersed_day(1, 0, 0.0, 0.05), teeth)
    record = tooth_fingerprint(dispersed_day(2, 17, 0.0, 0.05), teeth)
    delay = align_fingerprint(record, reference, teeth).delay_samples
    assert sector_pattern_z(record, reference, teeth, delay, 17) > 4
    for wrong in (16, 18, 3):
        assert sector_pattern_z(record, reference, teeth, delay + (wrong - 17) * SPM, wrong) == 0.0
    # a wheel whose teeth all deviate alike has no pattern: it confirms nothing
    flat = np.tile(np.sin(2 * np.pi * np.arange(SPM) / SPM), teeth)
    assert not np.any(tooth_energy_pattern(flat, teeth))
    assert sector_pattern_z(flat, flat, teeth, 0, 0) == 0.0


def test_separation_of_a_perfect_fit_is_large_and_of_noise_small() -> None:
    rng = np.random.default_rng(3)
    reference = rng.normal(size=20 * SPM)
    record = np.roll(reference, 5 * SPM) + 0.1 * rng.normal(size=reference.size)
    assert shift_separation_z(record, reference, 5 * SPM, [4 * SPM, 6 * SPM, 15 * SPM], 20).min() > 10
    noise = rng.normal(size=reference.size)
    assert np.all(shift_separation_z(noise, reference, 0, [SPM, 2 * SPM], 20) < 4)


def test_another_gear_or_pure_noise_is_refused_not_aligned() -> None:
    reference = gear_average(seed=1, pattern_seed=7)
    other_gear = gear_average(seed=2, pattern_seed=8, noise=0.0)
    alignment = align_fingerprint(tooth_fingerprint(other_gear, TEETH), tooth_fingerprint(reference, TEETH), TEETH)
    assert alignment.shift_teeth is None and alignment.refusal
    perfect = np.cos(2 * np.pi * TEETH * np.arange(N) / N)
    assert "perfectly regular" in align_fingerprint(tooth_fingerprint(perfect, TEETH),
                                                    tooth_fingerprint(reference, TEETH), TEETH).refusal


def test_bad_input_is_a_clear_error() -> None:
    with pytest.raises(ValueError, match="whole number"):
        tooth_fingerprint(np.zeros(100), TEETH)
    with pytest.raises(ValueError, match="NaN"):
        tooth_fingerprint(np.full(N, np.nan), TEETH)
