"""Known-answer tests of the hunting-period observable and its noise estimate."""

from __future__ import annotations

import math

import numpy as np
import pytest

from physics.reconcile.localize import frequency_mismatch, order_mismatches, tooth_mismatch
from physics.reconcile.observables import (
    gear_frame_shift,
    hunting_spectrum,
    order_classes,
    pooled_variance,
    shift_revolutions,
)

FS = 20_000.0
F_REV = 1000.0 / 60.0


def _record(seconds: float, noise: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(int(seconds * FS)) / FS
    rng = np.random.default_rng(seed)
    # Pinion order 3, gear order 2 (= 40/21 pinion orders: hunting bin 40), mesh harmonic 1.
    x = (
        0.3 * np.cos(2 * np.pi * 3 * F_REV * t + 0.4)
        + 0.2 * np.cos(2 * np.pi * 2 * (20 / 21) * F_REV * t - 1.0)
        + 1.0 * np.cos(2 * np.pi * 20 * F_REV * t)
        + noise * rng.standard_normal(t.size)
    )
    pulses = np.arange(0.003, seconds - 0.01, 1 / F_REV)
    return x, pulses, t


def test_amplitudes_and_phases_at_their_hunting_bins() -> None:
    x, pulses, _ = _record(6.0, 0.0)
    spec = hunting_spectrum(x, FS, pulses, 1, pinion_teeth=20, gear_teeth=21, samples_per_mesh=16)
    assert spec.revs_per_hunt == 21
    # The first pulse is angle 0: phases are relative to t = 0.003 s.
    for k, amp, phase, order in ((63, 0.3, 0.4, 3.0), (40, 0.2, -1.0, 2 * 20 / 21), (420, 1.0, 0.0, 20.0)):
        expected_phase = phase + 2 * np.pi * order * F_REV * 0.003
        assert abs(spec.mean[k]) * 2 == pytest.approx(amp, rel=2e-3)
        assert np.angle(spec.mean[k] * np.exp(-1j * expected_phase)) == pytest.approx(0.0, abs=3e-3)
    assert spec.speed_rpm == pytest.approx(1000.0, rel=1e-9)
    classes = spec.order_class()
    assert (classes[63], classes[40], classes[420], classes[41]) == (
        "pinion_sideband", "gear_sideband", "mesh", "hunting_only",
    )


def test_noise_variance_of_the_mean_matches_white_noise_and_chi2_is_one() -> None:
    sigma = 0.2
    x, pulses, _ = _record(12.0, sigma, seed=4)
    spec = hunting_spectrum(x, FS, pulses, 1, pinion_teeth=20, gear_teeth=21, samples_per_mesh=16)
    clean, _, _ = _record(12.0, 0.0)
    spec0 = hunting_spectrum(clean, FS, pulses, 1, pinion_teeth=20, gear_teeth=21, samples_per_mesh=16)
    u = spec.used
    # White noise σ² per time sample: each angle sample is one interpolated time sample
    # (about the same variance), per bin E|X|² = σ²_angle / N, the mean of S segments ÷ S.
    n = spec.revs_per_hunt * spec.samples_per_rev
    expected = sigma**2 * (spec.samples_per_rev * F_REV / FS) / n / spec.segments
    assert float(np.median(spec.variance[u])) == pytest.approx(expected, rel=0.25)
    chi2 = 2 * np.abs(spec.mean[u] - spec0.mean[u]) ** 2 / spec.variance[u]
    dof = 2 * u.sum()
    assert abs(chi2.sum() / dof - 1.0) < 3 * math.sqrt(2 / dof) + 0.01


def test_pooled_variance_is_a_running_mean() -> None:
    v = np.arange(10.0)
    assert pooled_variance(v, 2)[5] == pytest.approx(5.0)
    assert pooled_variance(v, 0).tolist() == v.tolist()


def test_order_classes_split_the_hunting_grid_exactly() -> None:
    c = order_classes(421 * 3, 20, 21)
    k = np.arange(c.size)
    assert set(k[c == "mesh"] % 420) == {0}
    assert np.all((k[c == "pinion_sideband"] % 21 == 0) & (k[c == "pinion_sideband"] % 420 != 0))
    assert np.all((k[c == "gear_sideband"] % 20 == 0) & (k[c == "gear_sideband"] % 420 != 0))
    assert np.all((k[c == "hunting_only"] % 20 != 0) & (k[c == "hunting_only"] % 21 != 0))


def test_short_record_is_refused() -> None:
    x, pulses, _ = _record(0.5, 0.0)
    with pytest.raises(ValueError, match="hunting period"):
        hunting_spectrum(x, FS, pulses, 1, pinion_teeth=20, gear_teeth=21, samples_per_mesh=16)


def test_localisation_names_the_class_the_band_and_the_tooth() -> None:
    n = 2000
    chi2 = np.full(n, 2.0)
    used = np.ones(n, bool)
    used[0] = False
    chi2[[21 * 5, 21 * 7]] = 100.0
    orders = order_mismatches(chi2, used, 20, 21)
    assert orders[0]["class"] == "pinion_sideband" and orders[0]["orders"] == [5.0, 7.0]
    assert orders[0]["share"] == pytest.approx(1.0)
    f = np.arange(n, dtype=np.float64) * 10.0
    band = frequency_mismatch(chi2, used, f, band_hz=250.0)
    assert band is not None and band["band_hz"][0] <= 1050 < band["band_hz"][1]
    # A pulse at pinion tooth 7's pitch angle in every revolution of the hunting period.
    spr = 20 * 16
    rev = np.zeros(spr)
    tooth1 = 10.0
    rev[round((tooth1 + 6 * 18.0) / 360 * spr)] = 1.0
    located = tooth_mismatch(np.tile(rev, 21), 20, 21, spr, tooth1)
    pinion = next(m for m in located if m["wheel"] == "pinion")
    assert pinion["teeth"] == [7]
    assert pinion["angle_deg"] == [pytest.approx(109.0), pytest.approx(127.0)]  # 118° ± half a pitch


@pytest.mark.parametrize("late_revolutions", [0, 4, 13])
def test_gear_frame_of_a_later_start_is_found_and_undone(late_revolutions: int) -> None:
    """Two records of one rig whose first pinion pulses find the gear elsewhere."""
    import dataclasses

    from physics.config import GearPairModel
    from physics.simulator import simulate

    base = GearPairModel()
    rig = base.replace(deviations=dataclasses.replace(
        base.deviations, gear_eccentricity_um=3.0, gear_pitch_errors_um=[0.0] * 4 + [4.0] + [0.0] * 16))
    sim = simulate(rig, seconds=6.0, seed=2)
    x, pulses = sim.channels["acc"], sim.tach_pulse_times_s
    kw = dict(pinion_teeth=20, gear_teeth=21, samples_per_mesh=16, max_frequency_hz=3000.0)
    reference = hunting_spectrum(x, sim.sample_rate_hz, pulses, 1, **kw)
    # Another record (other sensor noise) whose analysis starts some revolutions later.
    other = simulate(rig, seconds=6.0, seed=3)
    later = hunting_spectrum(other.channels["acc"], other.sample_rate_hz,
                             other.tach_pulse_times_s[late_revolutions:], 1, max_segments=3, **kw)
    shift, match, evidence = gear_frame_shift(later, reference)
    assert shift == (-late_revolutions) % 21
    assert match > 0.9 and evidence > 100
    aligned = shift_revolutions(later, shift)
    gear_bins = reference.used & (np.arange(reference.n_bins) % 21 != 0)
    a, b = aligned.mean[gear_bins], reference.mean[gear_bins]
    assert abs(np.vdot(b, a)) / np.linalg.norm(a) / np.linalg.norm(b) > 0.95


def test_an_ideal_gear_gives_no_frame_to_align() -> None:
    t = np.arange(int(6.0 * FS)) / FS
    # Pinion-periodic content (every shift looks the same) and noise only.
    x = np.cos(2 * np.pi * 20 * F_REV * t) + 0.3 * np.cos(2 * np.pi * 3 * F_REV * t)
    pulses = np.arange(0.003, 6.0 - 0.01, 1 / F_REV)
    kw = dict(pinion_teeth=20, gear_teeth=21, samples_per_mesh=16)
    noisy = [x + 0.05 * np.random.default_rng(seed).standard_normal(t.size) for seed in (1, 2)]
    one = hunting_spectrum(noisy[0], FS, pulses, 1, **kw)
    other = hunting_spectrum(noisy[1], FS, pulses[5:], 1, **kw)
    assert gear_frame_shift(other, one) == (0, 0.0, 0.0)
