"""Forward model (simulator in the loop, closed-form transfer path) and the catalogue plug-ins."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from physics.config import GearPairModel, Spall
from physics.reconcile import CATALOGUE, MECHANISM_NAMES, UNAVAILABLE, Candidate
from physics.reconcile.forward import ForwardModel, ForwardSetup, mode_response, reconciled_modes
from physics.reconcile.observables import hunting_spectrum
from physics.reconcile.selection import _crt_shift, _shift_phase
from physics.simulator import simulate

ISSUE_NAMES = (
    "pinion_eccentricity", "gear_eccentricity", "index_error", "tooth_spall", "tooth_crack",
    "profile_modification", "structural_mode", "sliding_friction", "contact_loss",
    "load_fluctuation", "speed_fluctuation",
)


@pytest.fixture(scope="module")
def forward() -> ForwardModel:
    return ForwardModel(
        ForwardSetup(speed_rpm=1000.0, pinion_teeth=20, gear_teeth=21, samples_per_mesh=32, n_bins=4000)
    )


def test_mode_response_known_values() -> None:
    f = np.array([100.0, 3000.0, 1e6])
    h = mode_response(f, 3000.0, 0.05)
    assert abs(h[0]) == pytest.approx((100 / 3000) ** 2 / (1 - (100 / 3000) ** 2), rel=1e-3)
    assert abs(h[1]) == pytest.approx(1 / (2 * 0.05), rel=1e-9)
    assert abs(h[2]) == pytest.approx(1.0, rel=1e-4)


def test_prediction_equals_the_noise_free_simulated_average(base_model: GearPairModel, forward: ForwardModel) -> None:
    model = dataclasses.replace(base_model, sensors=[dataclasses.replace(base_model.sensors[0], noise_rms_m_s2=0.0)])
    rec = simulate(model, seconds=4.0, seed=None)
    spec = hunting_spectrum(rec.channels["acc"], rec.sample_rate_hz, rec.tach_pulse_times_s, 1,
                            pinion_teeth=20, gear_teeth=21, samples_per_mesh=32)
    channels = forward.mode_channels(model)
    gains = np.array([m.gain_m_s2_per_n for m in reconciled_modes(model, forward.setup)])
    pred = gains @ channels
    n = 4000
    err = np.linalg.norm(spec.mean[1:n] - pred[1:n]) / np.linalg.norm(spec.mean[1:n])
    assert err < 1e-3


def test_retuning_a_mode_in_closed_form_equals_resimulating(base_model: GearPairModel, forward: ForwardModel) -> None:
    channels = forward.mode_channels(base_model)
    modes = reconciled_modes(base_model, forward.setup)
    tuned = [(2300.0, 0.05)] + [(m.frequency_hz, m.damping_ratio) for m in modes[1:]]
    closed = forward.transfer_columns(channels, modes, tuned)[0]
    sensor = base_model.sensors[0]
    moved = dataclasses.replace(
        sensor, modes=[dataclasses.replace(modes[0], frequency_hz=2300.0, damping_ratio=0.05), *modes[1:]]
    )
    direct = forward.mode_channels(base_model.replace(sensors=[moved]))[0]
    err = np.linalg.norm(closed[1:] - direct[1:]) / np.linalg.norm(direct[1:])
    assert err < 5e-3
    # An extra mode through the first mode's channel equals a configured one at that frequency.
    extra = forward.transfer_columns(channels, modes, [(m.frequency_hz, m.damping_ratio) for m in modes],
                                     [(2300.0, 0.05)])[-1]
    assert np.linalg.norm(extra[1:] - direct[1:]) / np.linalg.norm(direct[1:]) < 5e-3


@pytest.mark.parametrize(("name", "wheel", "tooth"), [("index_error", "pinion", 5), ("tooth_crack", "gear", 9)])
def test_shifting_tooth_1_reproduces_another_tooth(
    base_model: GearPairModel, forward: ForwardModel, name: str, wheel: str, tooth: int
) -> None:
    plugin = CATALOGUE[name]
    params = plugin.from_vector(np.array(plugin.reference))
    base = forward.mode_channels(base_model)[1]
    d1 = forward.mode_channels(plugin.apply(base_model, Candidate(name, wheel, 1), params))[1] - base  # type: ignore[arg-type]
    dj = forward.mode_channels(plugin.apply(base_model, Candidate(name, wheel, tooth), params))[1] - base  # type: ignore[arg-type]
    shift = _crt_shift(tooth - 1, wheel, 20, 21)
    assert shift is not None
    est = d1 * _shift_phase(np.arange(d1.size, dtype=float), shift, 420)
    assert np.linalg.norm(est - dj) / np.linalg.norm(dj) < 0.01
    # The other direction is wrong: the test can fail.
    wrong = d1 * _shift_phase(np.arange(d1.size, dtype=float), -shift, 420)
    assert np.linalg.norm(wrong - dj) / np.linalg.norm(dj) > 0.5


def test_catalogue_names_are_the_issue_names_verbatim() -> None:
    assert set(ISSUE_NAMES) <= set(MECHANISM_NAMES)
    assert set(CATALOGUE) | set(UNAVAILABLE) == set(ISSUE_NAMES)


def test_plugins_put_their_physics_into_the_simulator_configuration(base_model: GearPairModel) -> None:
    m = CATALOGUE["gear_eccentricity"].apply(base_model, Candidate("gear_eccentricity", "gear"),
                                            {"amplitude_um": 4.0, "phase_deg": 90.0})
    assert m.deviations.gear_eccentricity_um == pytest.approx(4.0)
    # Phasor sum with what is already configured: +4 µm at 90° and −4 µm at 90° cancel.
    m2 = CATALOGUE["gear_eccentricity"].apply(m, Candidate("gear_eccentricity", "gear"),
                                             {"amplitude_um": 4.0, "phase_deg": 270.0})
    assert m2.deviations.gear_eccentricity_um == pytest.approx(0.0, abs=1e-9)
    m = CATALOGUE["index_error"].apply(base_model, Candidate("index_error", "gear", 3), {"error_um": 2.5})
    assert m.deviations.gear_pitch_errors_um[2] == 2.5 and sum(m.deviations.gear_pitch_errors_um) == 2.5
    m = CATALOGUE["tooth_spall"].apply(base_model, Candidate("tooth_spall", "pinion", 7), {"depth_um": 9.0})
    assert m.deviations.spalls == [Spall(wheel="pinion", tooth=7, depth_um=9.0)]
    m = CATALOGUE["tooth_crack"].apply(base_model, Candidate("tooth_crack", "pinion", 2), {"stiffness_loss_fraction": 0.3})
    assert m.deviations.cracks[0].stiffness_loss_fraction == 0.3 and m.deviations.cracks[0].tooth == 2
    m = CATALOGUE["profile_modification"].apply(base_model, Candidate("profile_modification"),
                                               {"pinion_tip_relief_um": 8.0, "gear_tip_relief_um": 4.0})
    assert (m.deviations.pinion_tip_relief_um, m.deviations.gear_tip_relief_um) == (8.0, 4.0)
    assert m.deviations.pinion_tip_relief_length_mm > 0
    m = CATALOGUE["load_fluctuation"].apply(base_model, Candidate("load_fluctuation", "gear", order=2),
                                           {"fraction": 0.05, "phase_deg": 10.0})
    assert (m.operating.load_fluctuation_fraction, m.operating.load_fluctuation_order) == (0.05, 2)
    m = CATALOGUE["structural_mode"].apply(base_model, Candidate("structural_mode"),
                                          {"frequency_hz": 5100.0, "damping_ratio": 0.02, "gain_m_s2_per_n": 0.001})
    assert m.sensors[0].modes[-1].frequency_hz == 5100.0
    for name, plugin in CATALOGUE.items():
        params = plugin.from_vector(np.array(plugin.to_vector(plugin.from_vector(np.array([1.5, 0.5][: len(plugin.steps)])))))
        again = plugin.from_vector(np.array(plugin.to_vector(params)))
        assert again == pytest.approx(params), name
