"""Gear-pair simulator against closed forms, kinematics, and its own reduced model."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest

from physics.config import (
    Acquisition,
    Crack,
    Deviations,
    Drive,
    GearPairModel,
    Mesh,
    Operating,
    Sensor,
    Spall,
    Tachometer,
    WheelBody,
)
from physics.simulator import (
    SimulationError,
    mesh_mode_frequency_hz,
    model_geometry,
    simulate,
    static_transmission_error_m,
)

QUIET = [Sensor(noise_rms_m_s2=0.0)]


def exact_angle_average(
    angle_rad: np.ndarray, x: np.ndarray, samples_per_rev: int = 1280
) -> np.ndarray:
    """Reference synchronous average on the simulator's own pinion angle (no tach)."""
    first = math.ceil(angle_rad[0] / (2 * math.pi))
    revs = int(angle_rad[-1] // (2 * math.pi)) - first
    grid = (first + np.arange(revs * samples_per_rev) / samples_per_rev) * 2 * math.pi
    return np.interp(grid, angle_rad, x).reshape(revs, samples_per_rev).mean(axis=0)


def slow_model(dofs: str = "torsional", **changes: Any) -> GearPairModel:
    """Quasi-static operation: 5 rpm, a mesh period (0.6 s) is far longer than any mode."""
    model = GearPairModel(
        dofs=dofs,  # type: ignore[arg-type]
        operating=Operating(speed_rpm=5.0),
        sensors=QUIET,
        acquisition=Acquisition(sample_rate_hz=2000, oversampling=8, warmup_s=0.3),
    )
    return dataclasses.replace(model, **changes)


@pytest.mark.parametrize("dofs", ["torsional", "full"])
def test_static_transmission_error_matches_closed_form(dofs: str) -> None:
    model = slow_model(dofs)
    result = simulate(model, seconds=0.7)
    b = model_geometry(model).face_width_m
    length, te = result.contact_length_m, result.transmission_error_m
    for pairs in (1, 2):
        zone = np.abs(length - pairs * b) < 1e-9
        assert zone.sum() > 200
        expected = static_transmission_error_m(model, pairs)
        assert np.median(te[zone]) == pytest.approx(expected, rel=1e-3)
        # Away from the switching transients the TE sits on the closed form.
        assert np.mean(np.abs(te[zone] / expected - 1) < 5e-3) > 0.8
    # Mean mesh force balances the load torque.
    force = model.operating.load_torque_nm / model_geometry(model).gear_base_radius_m
    assert np.mean(result.mesh_force_n) == pytest.approx(force, rel=1e-3)


def zero_crossing_frequency_hz(x: np.ndarray, sample_rate_hz: float) -> float:
    x = x - x.mean()
    sign = np.signbit(x)
    i = np.nonzero(sign[1:] != sign[:-1])[0]
    t = i + x[i] / (x[i] - x[i + 1])
    return (t.size - 1) / 2 / ((t[-1] - t[0]) / sample_rate_hz)


def free_mesh_vibration(dofs: str, **changes: Any) -> tuple[GearPairModel, np.ndarray, float]:
    """Free vibration about a slightly wrong start (mean instead of local stiffness)."""
    model = GearPairModel(
        dofs=dofs,  # type: ignore[arg-type]
        operating=Operating(speed_rpm=0.01),
        mesh=Mesh(damping_ratio=0.0),
        drive=Drive(
            input_shaft_stiffness_nm_per_rad=100.0, output_shaft_stiffness_nm_per_rad=100.0
        ),
        sensors=QUIET,
        acquisition=Acquisition(sample_rate_hz=100_000, oversampling=4, warmup_s=0.001),
    )
    model = dataclasses.replace(model, **changes)
    result = simulate(model, seconds=0.05)
    pairs = round(float(result.contact_length_m.mean()) / model_geometry(model).face_width_m)
    return model, result.transmission_error_m, float(pairs)


def test_mesh_mode_frequency_matches_closed_form() -> None:
    model, te, pairs = free_mesh_vibration("torsional")
    k_local = model.mesh.stiffness_per_length_n_per_m2 * model_geometry(model).face_width_m * pairs
    measured = zero_crossing_frequency_hz(te, 100_000)
    assert measured == pytest.approx(mesh_mode_frequency_hz(model, k_local), rel=2e-3)


def test_full_model_mesh_mode_matches_an_independent_eigen_analysis() -> None:
    # Bearings soft enough to move the mesh mode clearly; same frequency from a hand-built
    # 4-DOF eigenproblem (θ1, θ2, x1, x2; shafts negligible, tilt not excited by a centred load).
    body = WheelBody(bearing_radial_stiffness_n_per_m=3e8, bearing_damping_ratio=0.0)
    gear = dataclasses.replace(
        body, mass_kg=5.44, polar_inertia_kg_m2=0.03, tilt_inertia_kg_m2=0.0152
    )
    model, te, pairs = free_mesh_vibration("full", pinion=body, gear=gear)
    geo = model_geometry(model)
    k = model.mesh.stiffness_per_length_n_per_m2 * geo.face_width_m * pairs
    v = np.array([geo.pinion_base_radius_m, -geo.gear_base_radius_m, 1.0, -1.0])
    stiffness = k * np.outer(v, v) + np.diag([0, 0, 3e8, 3e8])
    mass = np.diag([0.0247, 0.03, 4.93, 5.44])
    eig = np.sort(np.sqrt(np.abs(np.linalg.eigvals(np.linalg.solve(mass, stiffness))))) / (
        2 * math.pi
    )
    measured = zero_crossing_frequency_hz(te, 100_000)
    # TE = rb1θ1 − rb2θ2 rings mostly at the highest (mesh-dominated) mode.
    assert measured == pytest.approx(eig[-1], rel=5e-3)
    # The bearings couple in: the torsional closed form no longer holds for this pair.
    assert abs(measured / mesh_mode_frequency_hz(model, k) - 1) > 0.02


def test_reduced_model_equals_full_model_with_rigid_bearings() -> None:
    stiff = WheelBody(bearing_radial_stiffness_n_per_m=1e12, bearing_tilt_stiffness_nm_per_rad=1e11)
    gear = dataclasses.replace(
        stiff, mass_kg=5.44, polar_inertia_kg_m2=0.03, tilt_inertia_kg_m2=0.0152
    )
    spall = Deviations(spalls=[Spall(tooth=16, face_width_mm=6.0, depth_um=15.0)])
    base = GearPairModel(sensors=QUIET, deviations=spall, pinion=stiff, gear=gear)
    full = simulate(base, seconds=0.6)
    reduced = simulate(base.replace(dofs="torsional"), seconds=0.6)
    avg_full = exact_angle_average(full.pinion_angle_rad, full.channels["acc"])
    avg_red = exact_angle_average(reduced.pinion_angle_rad, reduced.channels["acc"])
    assert np.linalg.norm(avg_full - avg_red) / np.linalg.norm(avg_red) < 0.01
    # …and with the default (compliant) bearings the full model differs: the reduction matters.
    compliant = simulate(GearPairModel(sensors=QUIET, deviations=spall), seconds=0.6)
    avg_c = exact_angle_average(compliant.pinion_angle_rad, compliant.channels["acc"])
    assert np.linalg.norm(avg_c - avg_red) / np.linalg.norm(avg_red) > 0.05


def test_unexcited_dofs_stay_at_rest() -> None:
    model = GearPairModel(
        sensors=QUIET,
        deviations=Deviations(spalls=[Spall(tooth=3, face_width_mm=5.0, face_start_mm=1.0)]),
    )
    a = simulate(model, seconds=0.1)
    b = simulate(model, seconds=0.1, keep_unexcited_dofs=True)
    np.testing.assert_allclose(a.channels["acc"], b.channels["acc"], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(a.transmission_error_m, b.transmission_error_m, rtol=1e-9)


def test_halving_the_step_changes_the_average_by_less_than_one_percent() -> None:
    spall = Deviations(spalls=[Spall(tooth=16, face_width_mm=6.0)])
    base = GearPairModel(sensors=QUIET, deviations=spall)
    assert base.acquisition.oversampling == 16
    averages = []
    for oversampling in (16, 32):
        model = base.replace(acquisition=Acquisition(oversampling=oversampling))
        result = simulate(model, seconds=0.7)
        averages.append(exact_angle_average(result.pinion_angle_rad, result.channels["acc"]))
    change = np.linalg.norm(averages[0] - averages[1]) / np.linalg.norm(averages[1])
    print(f"TSA change when halving the step: {change:.4f}")
    assert change < 0.01


def test_spall_deeper_than_the_deflection_loses_contact_at_tooth_angle() -> None:
    # Half the face spalled, 30 µm deep (static deflection ≈ 7 µm), within the single-contact
    # zone: that half carries no load, so the loaded length is b/2 and the TE doubles
    # (closed form), centred on tooth 5's pitch angle.
    spall = Spall(tooth=5, depth_um=30.0, profile_start_mm=-4.0, profile_extent_mm=8.0,
                  face_start_mm=0.0, face_width_mm=10.0)  # fmt: skip
    model = slow_model(deviations=Deviations(spalls=[spall]))
    result = simulate(model, seconds=2.0)
    b = model_geometry(model).face_width_m
    half = np.abs(result.contact_length_m - b / 2) < 1e-9
    assert half.sum() > 100
    te = result.transmission_error_m[half]
    # Median: the sudden softening rings the shaft modes for a while.
    assert np.median(te) == pytest.approx(2 * static_transmission_error_m(model, 1), rel=2e-3)
    angles = np.degrees(result.pinion_angle_rad[half]) % 360
    expected = (model.tachometer.tooth1_pitch_angle_deg + 4 * 18.0) % 360
    assert np.mean(angles) == pytest.approx(expected, abs=0.05)
    # A linearised model would keep the full length loaded: check it really dropped.
    assert result.contact_length_m.min() == pytest.approx(b / 2, abs=1e-9)


def test_crack_softens_its_tooth_only() -> None:
    model = slow_model(deviations=Deviations(cracks=[Crack(tooth=5, stiffness_loss_fraction=0.5)]))
    model = model.replace(operating=Operating(speed_rpm=20.0))
    result = simulate(model, seconds=3.2)
    single = static_transmission_error_m(model, 1)
    angle = np.degrees(result.pinion_angle_rad) % 360
    pitch5 = (model.tachometer.tooth1_pitch_angle_deg + 4 * 18.0) % 360
    at_tooth5 = np.abs(angle - pitch5) < 0.3
    pitch6 = (pitch5 + 18.0) % 360
    at_tooth6 = np.abs(angle - pitch6) < 0.3
    assert np.median(result.transmission_error_m[at_tooth5]) == pytest.approx(2 * single, rel=5e-3)
    assert np.median(result.transmission_error_m[at_tooth6]) == pytest.approx(single, rel=5e-3)


def switching_angle_deviation_rad(model: GearPairModel) -> tuple[np.ndarray, np.ndarray]:
    """Pinion angles where a pair leaves contact, minus the regular base-pitch grid."""
    result = simulate(model, seconds=1.05)
    b = model_geometry(model).face_width_m
    length = result.contact_length_m
    # Falling crossings of 1.5·b (2 → 1 pairs), interpolated.
    above = length > 1.5 * b
    i = np.nonzero(above[:-1] & ~above[1:])[0]
    frac = (length[i] - 1.5 * b) / (length[i] - length[i + 1])
    theta = result.pinion_angle_rad[i] + frac * (
        result.pinion_angle_rad[i + 1] - result.pinion_angle_rad[i]
    )
    pitch = 2 * math.pi / model.geometry.pinion_teeth
    grid = theta[0] + pitch * np.round((theta - theta[0]) / pitch)
    deviation = theta - grid
    return theta, deviation - deviation.mean()


def test_eccentricity_moves_the_mesh_but_a_load_fluctuation_does_not() -> None:
    # Kinematics: the mesh follows the actual rotation plus the base-circle offset, so the
    # instants of pair change are phase modulated by E/rb1 at once per revolution; a load
    # fluctuation at the same order changes the deflection only (AM), never the mesh phase.
    fast = Acquisition(sample_rate_hz=200_000, oversampling=2, warmup_s=0.01)
    base = GearPairModel(dofs="torsional", sensors=QUIET, acquisition=fast,
                         operating=Operating(speed_rpm=60.0))  # fmt: skip
    ecc_um = 50.0
    eccentric = base.replace(
        deviations=Deviations(pinion_eccentricity_um=ecc_um, pinion_eccentricity_phase_deg=30.0)
    )
    theta, deviation = switching_angle_deviation_rad(eccentric)
    rb1 = model_geometry(base).pinion_base_radius_m
    fit = np.linalg.lstsq(np.column_stack([np.cos(theta), np.sin(theta)]), deviation, rcond=None)[0]
    assert math.hypot(*fit) == pytest.approx(ecc_um * 1e-6 / rb1, rel=0.05)
    # The 1× TE component is the eccentricity itself (geometric, load independent).
    # A 10 % load fluctuation at once per output revolution (a stiff speed loop keeps the
    # speed within a few per cent at this low speed).
    loaded = base.replace(
        operating=Operating(
            speed_rpm=60.0, load_fluctuation_fraction=0.1, load_fluctuation_order=1
        ),
        drive=Drive(speed_control_time_constant_s=0.005),
    )
    _, deviation_load = switching_angle_deviation_rad(loaded)
    assert np.max(np.abs(deviation_load)) < 0.05 * ecc_um * 1e-6 / rb1


def test_eccentricity_appears_in_the_transmission_error() -> None:
    model = GearPairModel(
        dofs="torsional",
        sensors=QUIET,
        operating=Operating(speed_rpm=60.0),
        deviations=Deviations(gear_eccentricity_um=20.0, gear_eccentricity_phase_deg=0.0),
        acquisition=Acquisition(sample_rate_hz=5000, oversampling=8, warmup_s=0.1),
    )
    result = simulate(model, seconds=2.2)
    theta2 = result.gear_angle_rad
    te = result.transmission_error_m
    fit = np.linalg.lstsq(
        np.column_stack([np.cos(theta2), np.sin(theta2), np.ones_like(te)]), te, rcond=None
    )[0]
    # δ = TE + e1 − e2 stays ≈ F/k, so TE carries +E2·cos(θ2 + φ2).
    assert fit[0] == pytest.approx(20e-6, rel=0.05)
    assert abs(fit[1]) < 1e-6


def test_tachometer_edges_follow_the_shaft_and_tooth1_convention() -> None:
    model = GearPairModel(
        sensors=QUIET,
        tachometer=Tachometer(pulses_per_rev=2, tooth1_pitch_angle_deg=100.0),
        operating=Operating(
            speed_rpm=1200.0, speed_fluctuation_fraction=0.02, speed_fluctuation_hz=3.0
        ),
    )
    result = simulate(model, seconds=0.5)
    edges = result.tach_pulse_times_s
    angle_at_edges = np.interp(edges, result.time_s, result.pinion_angle_rad)
    phase = angle_at_edges / math.pi  # 2 pulses per rev: edges at multiples of π
    assert np.max(np.abs(phase - np.round(phase))) < 1e-3
    wave = result.channels["tach"]
    assert wave.min() == 0.0 and wave.max() == 5.0
    # Mid-level crossings of the TTL waveform are the edges, well within a sample.
    up = np.nonzero((wave[:-1] < 2.5) & (wave[1:] >= 2.5))[0]
    t_up = (up + (2.5 - wave[up]) / (wave[up + 1] - wave[up])) / result.sample_rate_hz
    assert t_up.size == edges.size
    np.testing.assert_allclose(t_up, edges, atol=0.05 / result.sample_rate_hz)


def test_speed_drift_follows_the_reference() -> None:
    model = GearPairModel(
        sensors=QUIET, operating=Operating(speed_rpm=1000.0, speed_drift_fraction=0.05)
    )
    result = simulate(model, seconds=1.0)
    edges = result.tach_pulse_times_s
    rpm = 60.0 / np.diff(edges)
    assert rpm[0] == pytest.approx(1000.0, rel=0.01)
    assert rpm[-1] == pytest.approx(1050.0 * (1 - 0.05 * 0.05 / 0.95), rel=0.01)


def test_same_seed_same_record_and_noise_level() -> None:
    model = GearPairModel(sensors=[Sensor(noise_rms_m_s2=0.5)])
    a = simulate(model, seconds=0.2, seed=3)
    b = simulate(model, seconds=0.2, seed=3)
    c = simulate(model, seconds=0.2, seed=4)
    np.testing.assert_array_equal(a.channels["acc"], b.channels["acc"])
    assert np.std(a.channels["acc"] - c.channels["acc"]) == pytest.approx(
        0.5 * math.sqrt(2), rel=0.05
    )


def test_contact_set_always_settles() -> None:
    spall = Deviations(spalls=[Spall(tooth=16, face_width_mm=8.0, depth_um=40.0)],
                       pinion_tip_relief_um=10.0, pinion_tip_relief_length_mm=5.0)  # fmt: skip
    result = simulate(GearPairModel(sensors=QUIET, deviations=spall), seconds=0.3)
    assert result.unsettled_contact_steps == 0
    b = model_geometry(GearPairModel()).face_width_m
    # The spalled strip (8 mm) was out of contact while it crossed the single-contact zone.
    assert result.contact_length_m.min() == pytest.approx(b - 8e-3, abs=2e-4)


@pytest.mark.parametrize(
    ("shaft", "pulses_per_rev"), [("pinion", 1), ("pinion", 3), ("gear", 1), ("gear", 2)]
)
def test_first_tach_edge_of_a_record_is_the_pinion_reference(
    shaft: str, pulses_per_rev: int
) -> None:
    # The pipeline measures the pinion angle from a record's first tach edge: that edge must
    # be where the pinion passes its mark, whatever the shaft and the pulses per revolution.
    model = GearPairModel(
        sensors=QUIET,
        tachometer=Tachometer(shaft=shaft, pulses_per_rev=pulses_per_rev),  # type: ignore[arg-type]
        acquisition=Acquisition(warmup_s=0.13),
    )
    result = simulate(model, seconds=0.3)
    first = result.tach_pulse_times_s[0]
    assert 0 < first < 0.1 * 60 / model.operating.speed_rpm * 21 / 20
    angle = float(np.interp(first, result.time_s, result.pinion_angle_rad))
    assert abs(math.remainder(angle, 2 * math.pi)) < 1e-3
    assert result.tooth1_pitch_angle_deg == pytest.approx(337.4, abs=0.06)
    if shaft == "gear":
        gear_angle = np.interp(result.tach_pulse_times_s, result.time_s, result.gear_angle_rad)
        steps = np.diff(gear_angle) * pulses_per_rev / (2 * math.pi)
        np.testing.assert_allclose(steps, 1.0, atol=1e-6)


def test_a_drive_that_cannot_hold_the_speed_is_refused() -> None:
    # 30 % load fluctuation at 60 rpm against a slow speed loop: the pinion would reverse,
    # outside a driving-flank model, so the simulator says so instead of returning garbage.
    model = GearPairModel(
        dofs="torsional",
        sensors=QUIET,
        operating=Operating(speed_rpm=60.0, load_fluctuation_fraction=0.3),
        acquisition=Acquisition(sample_rate_hz=5000, oversampling=4, warmup_s=0.01),
    )
    with pytest.raises(SimulationError, match="turned backwards"):
        simulate(model, seconds=1.0)
