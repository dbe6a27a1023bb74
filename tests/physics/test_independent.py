"""The independent line-of-action generator: closed forms, conventions, artefacts, campaign files."""

from __future__ import annotations

import dataclasses
import itertools
import json
import math

import numpy as np
import pytest

from dsp.tach import pulse_times_from_waveform
from physics.independent import (
    Acquisition,
    Artefacts,
    Crack,
    IndependentModel,
    IndependentModelError,
    Mode,
    Operating,
    PairGeometry,
    PairStiffness,
    Spall,
    Tachometer,
    ToothErrors,
    TransferPath,
    campaign_days,
    generate_record,
    model_from_dict,
    model_to_dict,
    pair_derived,
    random_model,
    write_campaign,
)
from physics.independent.generator import modal_response, solve_static_mesh

SHORT = Acquisition(seconds=2.0, noise_to_signal=0.0)


def flat_model(**changes: object) -> IndependentModel:
    """Ideal teeth, constant pair stiffness: closed forms hold."""
    base = IndependentModel(
        geometry=PairGeometry(contact_ratio=1.4),
        stiffness=PairStiffness(curvature=0.0, skew=0.0),
        acquisition=SHORT,
    )
    return dataclasses.replace(base, **changes)  # type: ignore[arg-type]


def static_at(model: IndependentModel, positions: np.ndarray, force: float) -> np.ndarray:
    derived = pair_derived(model)
    return solve_static_mesh(model, derived, positions, np.zeros_like(positions), force).approach_m


def test_static_approach_is_force_over_pairs_in_contact() -> None:
    model = flat_model()
    k = model.stiffness.peak_n_per_m_per_mm * model.geometry.face_width_mm
    # Contact ratio 1.4 split evenly: double contact within ±0.2 pitch of a pair change.
    single = np.array([0.0, 0.1, -0.25])  # one pair near the pitch point
    double = np.array([0.5, 0.45, 0.62])
    assert np.allclose(static_at(model, single, 3000.0), 3000.0 / k, rtol=1e-12)
    assert np.allclose(static_at(model, double, 3000.0), 3000.0 / (2 * k), rtol=1e-12)


def test_deep_pit_leaves_the_series_stiffness_of_the_intact_face() -> None:
    h, w = 0.3, 0.4
    model = flat_model(
        stiffness=PairStiffness(curvature=0.0, skew=0.0, contact_compliance_share=h),
        spalls=(Spall(tooth=1, depth_um=200.0, extent_fraction=0.4, centre_fraction=0.5,
                      face_fraction=w, wall_fraction=0.0),),
    )
    k = model.stiffness.peak_n_per_m_per_mm * model.geometry.face_width_mm
    intact = k / ((1 - h) + h / (1 - w))
    approach = static_at(model, np.array([0.0, 0.05]), 2500.0)  # tooth 1 alone, in its pit
    assert np.allclose(approach, 2500.0 / intact, rtol=1e-12)
    # A shallow pit under a large load: the pitted face is loaded again (slope back to k).
    shallow = dataclasses.replace(model, spalls=(dataclasses.replace(model.spalls[0], depth_um=0.5),))
    d = 0.5e-6 * (1 + (1 - w) * (1 - h) / h)
    f_break = intact * d
    force = 4 * f_break
    expected = d + (force - f_break) / k
    assert static_at(shallow, np.array([0.0]), force)[0] == pytest.approx(expected, rel=1e-12)


def test_crack_and_index_error_on_one_tooth() -> None:
    model = flat_model(cracks=(Crack(tooth=3, stiffness_loss_fraction=0.5),))
    k = model.stiffness.peak_n_per_m_per_mm * model.geometry.face_width_mm
    # Pair q = 2 carries pinion tooth 3: at s = 2 it is alone on the pitch point.
    assert static_at(model, np.array([2.0]), 1000.0)[0] == pytest.approx(1000.0 / (0.5 * k))
    assert static_at(model, np.array([3.0]), 1000.0)[0] == pytest.approx(1000.0 / k)
    index = [0.0] * 20
    index[4] = 2.0
    shifted = flat_model(errors=ToothErrors(pinion_index_um=tuple(index)))
    assert static_at(shifted, np.array([4.0]), 1000.0)[0] == pytest.approx(2e-6 + 1000.0 / k)


def test_contact_ratio_from_the_involute_geometry() -> None:
    derived = pair_derived(IndependentModel(geometry=PairGeometry(module_mm=10, pinion_teeth=20,
                                                                   gear_teeth=21)))
    assert derived.contact_ratio == pytest.approx(1.563, abs=1e-3)  # the textbook 20/21 pair
    with pytest.raises(IndependentModelError, match="interference"):
        pair_derived(IndependentModel(geometry=PairGeometry(pinion_teeth=13, contact_ratio=2.0,
                                                            approach_fraction=0.7)))


def test_modal_response_with_zero_phase_is_the_classic_mode() -> None:
    f = np.linspace(10.0, 9000.0, 50)
    mode = Mode(3000.0, 0.04, 0.007, 0.0)
    s = 2j * np.pi * f
    w = 2 * np.pi * 3000.0
    classic = 0.007 * s**2 / (s**2 + 2 * 0.04 * w * s + w**2)
    assert np.allclose(modal_response((mode,), f), classic, rtol=1e-10)


def test_same_seed_same_record_and_seeds_differ() -> None:
    model = flat_model(acquisition=dataclasses.replace(SHORT, noise_to_signal=0.5))
    a, b = generate_record(model, seed=3), generate_record(model, seed=3)
    for name in a.channels:
        assert np.array_equal(a.channels[name], b.channels[name])
    c = generate_record(model, seed=4)
    assert not np.array_equal(a.channels["acc"], c.channels["acc"])


def test_tach_edges_are_the_pinion_reference_and_the_pit_sits_on_its_tooth() -> None:
    """The manifest meaning: tooth k is on the pitch point (k−1)·360/Z1 after
    ``tooth1_pitch_angle_deg`` past the tach's rising edge, as gearwatch's own dsp finds it."""
    tooth, z1 = 6, 20
    geometry = PairGeometry(contact_ratio=1.3)
    pitch = 0.5  # approach fraction 0.5: the pitch point is mid-path
    pit = Spall(tooth=tooth, depth_um=30.0, extent_fraction=0.2, centre_fraction=pitch,
                face_fraction=0.6)
    tach = Tachometer(tooth1_pitch_angle_deg=250.0)
    healthy = flat_model(geometry=geometry, tachometer=tach,
                         operating=Operating(speed_drift_fraction=0.1))
    spalled = dataclasses.replace(healthy, spalls=(pit,))
    a, b = generate_record(healthy, seed=2), generate_record(spalled, seed=2)
    edges = pulse_times_from_waveform(a.channels["tach"], a.sample_rate_hz)
    assert len(edges) >= 30
    angle_at_edges = np.interp(edges, np.arange(a.pinion_angle_rad.size) / a.sample_rate_hz,
                               a.pinion_angle_rad)
    wrapped = (angle_at_edges + np.pi) % (2 * np.pi) - np.pi
    assert np.max(np.abs(wrapped)) < 2e-3  # edges where the pinion passes its mark
    bump = b.static_te_m - a.static_te_m
    assert np.max(bump) > 1e-6
    angle = np.degrees(a.pinion_angle_rad) % 360.0
    expected = (250.0 + (tooth - 1) * 360.0 / z1) % 360.0
    offset = (angle - expected + 180.0) % 360.0 - 180.0
    weight = np.clip(bump, 0, None)
    centroid = np.sum(weight * offset) / np.sum(weight)
    assert abs(centroid) < 0.05 * 360.0 / z1
    assert np.all(weight[np.abs(offset) > 360.0 / z1] == 0)  # nothing outside ±1 pitch


def test_noise_ratio_gain_and_artefacts() -> None:
    base = flat_model(errors=ToothErrors(pinion_tip_relief_um=5, gear_tip_relief_um=5))
    clean = generate_record(base, seed=1)
    noisy_model = dataclasses.replace(
        base, acquisition=dataclasses.replace(SHORT, noise_to_signal=2.0, gain=3.0)
    )
    noisy = generate_record(noisy_model, seed=1)
    truth = noisy.truth["record"]
    assert truth["noise_rms_m_s2"] == pytest.approx(2.0 * truth["signal_rms_m_s2"])
    assert truth["signal_rms_m_s2"] == pytest.approx(clean.truth["record"]["signal_rms_m_s2"])
    residual = noisy.channels["acc"] / 3.0 - clean.channels["acc"]
    assert np.std(residual) == pytest.approx(truth["noise_rms_m_s2"], rel=0.02)
    fixed = dataclasses.replace(noisy_model, acquisition=dataclasses.replace(
        noisy_model.acquisition, noise_rms_m_s2=0.7))
    assert generate_record(fixed, seed=1).truth["record"]["noise_rms_m_s2"] == 0.7
    art = dataclasses.replace(
        noisy_model,
        artefacts=Artefacts(glitches=3, dropouts=2, dropout_s=0.01, clip_fraction_of_peak=0.5),
    )
    corrupted = generate_record(dataclasses.replace(
        art, artefacts=dataclasses.replace(art.artefacts, glitch_value=3e38)), seed=1)
    assert np.sum(np.abs(corrupted.channels["acc"]) == 3e38) == 3
    rec = generate_record(art, seed=1)
    acc = rec.channels["acc"]
    marks = rec.truth["record"]["artefacts"]
    spike = marks["glitch_value"]  # default: 20 × the clean peak (× gain)
    assert spike == pytest.approx(20 * 3.0 * np.max(np.abs(clean.channels["acc"])))
    assert sorted(np.flatnonzero(np.abs(acc) == spike).tolist()) == marks["glitch_samples"]
    for start in marks["dropout_starts"]:
        span = acc[start : start + marks["dropout_samples"]]
        assert np.all((span == 0) | (np.abs(span) == spike))
    level = marks["clip_level"]
    ordinary = np.abs(acc) < spike
    assert np.max(np.abs(acc[ordinary])) == pytest.approx(level)
    assert marks["clipped_samples"] > 0


def test_spectrum_has_mesh_harmonics_and_eccentricity_sidebands() -> None:
    model = IndependentModel(
        errors=ToothErrors(gear_eccentricity_um=15.0, pinion_tip_relief_um=6, gear_tip_relief_um=6),
        acquisition=Acquisition(seconds=4.2, noise_to_signal=0.2),
        operating=Operating(speed_rpm=1000.0),
        geometry=PairGeometry(pinion_teeth=20, gear_teeth=21),
    )
    rec = generate_record(model, seed=0)
    acc = rec.channels["acc"]
    spectrum = np.abs(np.fft.rfft(acc * np.hanning(acc.size)))
    freq = np.fft.rfftfreq(acc.size, 1 / rec.sample_rate_hz)

    def level(f: float) -> float:
        return float(np.max(spectrum[np.abs(freq - f) < 0.3]))

    mesh = 1000 / 60 * 20
    gear_hz = mesh / 21
    floor = float(np.median(spectrum))
    harmonics = np.array([level(h * mesh) for h in range(1, 16)])
    assert np.sum(harmonics > 10 * floor) >= 6  # mesh harmonics stand out (most near modes)
    for h in np.argsort(harmonics)[::-1][:3] + 1:
        side = min(level(h * mesh - gear_hz), level(h * mesh + gear_hz))
        between = level(h * mesh + 2.5 * gear_hz)  # no order there
        assert side > 5 * between  # the gear's eccentricity: sidebands at ±1 gear order


def test_speed_drift_is_within_the_stated_fraction() -> None:
    model = flat_model(operating=Operating(speed_drift_fraction=0.2))
    rec = generate_record(model, seed=5)
    edges = pulse_times_from_waveform(rec.channels["tach"], rec.sample_rate_hz)
    rpm = 60.0 / np.diff(edges)
    assert np.max(np.abs(rpm / 1000.0 - 1)) <= 0.2 + 1e-3
    assert np.max(rpm) - np.min(rpm) > 0.05 * 1000.0  # it does drift


def test_model_round_trips_and_validation_names_the_field() -> None:
    model = random_model(7)
    assert model_from_dict(json.loads(json.dumps(model_to_dict(model)))) == model
    with pytest.raises(IndependentModelError, match=r"spalls\[0\]\.tooth"):
        generate_record(model.replace(spalls=(Spall(tooth=999),)))
    with pytest.raises(IndependentModelError, match="unknown keys"):
        model_from_dict({**model_to_dict(model), "colour": 1})
    with pytest.raises(IndependentModelError, match=r"path\.line_modes"):
        generate_record(model.replace(path=TransferPath(line_modes=(Mode(-1.0),))))


def test_random_models_generate_over_the_stated_ranges() -> None:
    for seed in range(6):
        model = random_model(seed, contact_ratio=1.3 + 0.14 * seed)
        model = model.replace(acquisition=dataclasses.replace(model.acquisition, seconds=0.5))
        rec = generate_record(model, seed=seed)
        assert rec.truth["derived"]["contact_ratio"] == pytest.approx(1.3 + 0.14 * seed)
        assert np.all(np.isfinite(rec.channels["acc"]))
        assert 13 <= model.geometry.pinion_teeth <= 80
        assert rec.truth["derived"]["mesh_frequency_hz"] <= 2000.0 + 1e-9


def test_campaign_folder_reads_back_through_ingest(tmp_path) -> None:  # type: ignore[no-untyped-def]
    from ingest.manifest import load_manifest
    from ingest.sources import read_record

    base = flat_model(acquisition=Acquisition(seconds=1.0))
    plan = campaign_days(base, days=4, onset_day=3, depths_um=(4.0, 8.0), load_jitter=0.1,
                         speed_jitter=0.05, gain_step_day=4, glitch_days=(2,), seed=1)
    assert [d.changes.get("spall_depth_um") for d in plan] == [None, None, 4.0, 8.0]
    assert [d.changes["gain"] for d in plan] == [1.0, 1.0, 1.0, 2.0]
    path = write_campaign(tmp_path / "c", plan, campaign_id="indep-test")
    campaign = load_manifest(path)
    assert campaign.rig.pinion_teeth == 20
    assert campaign.rig.tooth1_pitch_angle_deg == base.tachometer.tooth1_pitch_angle_deg
    assert campaign.tachometer is not None and len(campaign.records) == 4
    record = read_record(campaign.record_path(campaign.records[1]), campaign)
    truth = json.loads((tmp_path / "c" / "truth.json").read_text())
    spike = truth["days"][1]["record"]["artefacts"]["glitch_value"]
    assert np.sum(np.abs(record.channel("acc")) >= 0.999 * spike) == 1  # float32 in the WAV
    assert [d["changes"]["gain"] for d in truth["days"]] == [1.0, 1.0, 1.0, 2.0]
    assert truth["days"][3]["model"]["spalls"][0]["depth_um"] == 8.0
    no_tach = base.replace(tachometer=Tachometer(present=False))
    path = write_campaign(tmp_path / "n", campaign_days(no_tach, days=1, onset_day=None),
                          record_format="hdf5")
    campaign = load_manifest(path)
    assert campaign.tachometer is None
    assert [c.name for c in campaign.channels] == ["acc"]


@pytest.mark.parametrize(("contact_ratio", "teeth", "tooth"), [(1.4, (20, 21), 7), (1.9, (17, 43), 12)])
def test_gearwatch_pipeline_puts_a_plain_spall_on_its_tooth(
    contact_ratio: float, teeth: tuple[int, int], tooth: int
) -> None:
    from gearwatch.usecases.analyze import analyze_record

    z1, z2 = teeth
    model = IndependentModel(
        geometry=PairGeometry(pinion_teeth=z1, gear_teeth=z2, contact_ratio=contact_ratio),
        errors=ToothErrors(pinion_tip_relief_um=5, gear_tip_relief_um=5),
        spalls=(Spall(tooth=tooth, depth_um=20.0, extent_fraction=0.35, face_fraction=0.6,
                      centre_fraction=0.5),),
        path=TransferPath(delay_s=5e-5),
        acquisition=Acquisition(seconds=6.0, noise_to_signal=0.1),
        tachometer=Tachometer(tooth1_pitch_angle_deg=math.degrees(1.0)),
    )
    rec = generate_record(model, seed=11)
    analysis = analyze_record(rec.record_data(), rec.campaign(), input_sha256="0" * 64)
    assert analysis.channels[0].worst_tooth == tooth


def test_load_fluctuation_follows_the_gear_and_hum_is_not_synchronous() -> None:
    model = flat_model(
        operating=Operating(load_fluctuation_fraction=0.2, load_fluctuation_order=2),
        artefacts=Artefacts(hum_to_signal=0.5, hum_hz=50.0),
        acquisition=Acquisition(seconds=4.0, noise_to_signal=0.0),
    )
    k = model.stiffness.peak_n_per_m_per_mm * model.geometry.face_width_mm
    rec = generate_record(model, seed=3)
    force = rec.truth["derived"]["normal_force_n"]
    # Single contact (pair at the pitch point): the approach is the local load over k.
    s = 20 * (rec.pinion_angle_rad - math.radians(model.tachometer.tooth1_pitch_angle_deg)) / (2 * np.pi)
    single = np.abs(s - np.round(s)) < 0.1
    gear_angle = 2 * np.pi * s / 21
    expected = force * (1 + 0.2 * np.cos(2 * gear_angle)) / k
    assert np.allclose(rec.static_te_m[single], expected[single], rtol=1e-9)
    acc = rec.channels["acc"]
    spectrum = np.abs(np.fft.rfft(acc))
    freq = np.fft.rfftfreq(acc.size, 1 / rec.sample_rate_hz)
    hum = np.max(spectrum[np.abs(freq - 50.0) < 0.5])
    assert hum > 20 * np.median(spectrum)
    assert rec.truth["record"]["artefacts"]["hum_rms_m_s2"] == pytest.approx(
        0.5 * rec.truth["record"]["signal_rms_m_s2"]
    )


@pytest.mark.parametrize(
    "name", ["physics.independent.generator", "physics.independent.model",
             "physics.independent.campaign", "physics.independent.scenarios"]
)
def test_docstring_examples(name: str) -> None:
    import doctest
    import importlib

    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS)
    assert result.failed == 0


def test_internal_rate_converges() -> None:
    """Oversampling 4 (default) against 16: the record within 3 % (engagement taper: no steps)."""
    model = random_model(5, contact_ratio=1.6, pinion_teeth=20, gear_teeth=21,
                         noise_to_signal=0.0, speed_drift_fraction=0.0, seconds=1.0)
    model = model.replace(spalls=(Spall(tooth=4, depth_um=15, face_fraction=0.4, extent_fraction=0.3),))
    records = {
        os_: generate_record(model.replace(acquisition=dataclasses.replace(
            model.acquisition, oversampling=os_)), seed=1).channels["acc"]
        for os_ in (4, 16)
    }
    change = np.linalg.norm(records[4] - records[16]) / np.linalg.norm(records[16])
    assert change < 0.03


def test_random_campaign_pairs_a_spalled_and_a_healthy_twin() -> None:
    from physics.independent import random_campaign

    spalled = random_campaign(11, days=8)
    healthy = random_campaign(11, days=8, spalled=False)
    assert spalled == random_campaign(11, days=8)
    pits = [d.model.spalls[0] for d in spalled if d.model.spalls]
    assert pits and not any(d.model.spalls for d in healthy)
    onset = 8 - len(pits) + 1
    assert 4 <= onset <= 8
    assert 3.0 <= pits[0].depth_um <= 6.0
    for a, b in itertools.pairwise(pits):  # doubles a day up to a 25–30 µm cap
        assert b.depth_um == pytest.approx(2 * a.depth_um, abs=2e-3) or b.depth_um >= 25.0
    assert len({p.tooth for p in pits}) == 1
    for s, h in zip(spalled, healthy, strict=True):  # same days apart from the pit
        assert s.changes["load_factor"] == h.changes["load_factor"] and s.seed == h.seed


def test_friction_drives_a_cross_sensor_in_proportion_to_mu() -> None:
    base = flat_model(errors=ToothErrors(pinion_tip_relief_um=6, gear_tip_relief_um=6),
                      acquisition=Acquisition(seconds=1.0, noise_to_signal=0.0),
                      path=TransferPath(sensor_angle_deg=90.0, cross_coupling=0.0))
    rms = [
        generate_record(base.replace(operating=Operating(friction_coefficient=mu)), seed=1)
        .truth["record"]["signal_rms_m_s2"]
        for mu in (0.0, 0.04, 0.08)
    ]
    assert rms[0] < 1e-9 * rms[1]  # across the line of action only friction (no coupling) shakes it
    assert rms[2] == pytest.approx(2 * rms[1], rel=1e-6)  # linear in μ (static pair loads)


def test_nonlinear_stepping_agrees_with_the_lti_solve_when_the_stiffness_is_constant() -> None:
    """ε = 2 with a flat pair stiffness and no taper: the mesh stiffness is constant, so the
    time-stepped model and the frequency-domain one solve the same linear equation."""
    index = tuple(float(v) for v in np.random.default_rng(1).normal(0, 1, 20))
    model = IndependentModel(
        geometry=PairGeometry(contact_ratio=2.0),
        stiffness=PairStiffness(curvature=0, skew=0, engagement_fraction=0),
        errors=ToothErrors(pinion_index_um=index),
        acquisition=Acquisition(seconds=0.5, noise_to_signal=0, oversampling=8),
        operating=Operating(speed_rpm=3000),
    )
    lin = generate_record(model, seed=1).channels["acc"]
    nonlin = generate_record(model.replace(dynamics="nonlinear"), seed=1).channels["acc"]
    assert np.linalg.norm(lin - nonlin) / np.linalg.norm(nonlin) < 0.06


def test_nonlinear_stepping_loses_contact_at_light_load_near_resonance() -> None:
    model = IndependentModel(
        errors=ToothErrors(pinion_tip_relief_um=10, gear_tip_relief_um=10),
        acquisition=Acquisition(seconds=0.3, noise_to_signal=0, oversampling=8),
        operating=Operating(speed_rpm=6000, load_torque_nm=5),
        dynamics="nonlinear",
    )
    assert generate_record(model, seed=1).truth["derived"]["separated_fraction"] > 0.05
    heavy = model.replace(operating=Operating(speed_rpm=1000, load_torque_nm=200))
    assert generate_record(heavy, seed=1).truth["derived"]["separated_fraction"] == 0.0


def test_a_gear_pit_follows_the_gear_tooth_not_the_pinion_tooth() -> None:
    pit = Spall(tooth=5, wheel="gear", depth_um=100.0, extent_fraction=0.3, centre_fraction=0.5,
                face_fraction=0.5)
    model = flat_model(spalls=(pit,))
    k = model.stiffness.peak_n_per_m_per_mm * model.geometry.face_width_mm
    # pair q meets pinion tooth q mod 20 + 1 and gear tooth q mod 21 + 1
    approach = static_at(model, np.array([4.0, 25.0, 24.0, 3.0]), 1000.0)
    h = model.stiffness.contact_compliance_share
    pitted = 1000.0 / (k / ((1 - h) + h / 0.5))
    assert approach == pytest.approx([pitted, pitted, 1000.0 / k, 1000.0 / k], rel=1e-12)


def test_bearing_impacts_are_not_synchronous_with_the_pinion() -> None:
    base = flat_model(errors=ToothErrors(pinion_tip_relief_um=6, gear_tip_relief_um=6),
                      acquisition=Acquisition(seconds=3.0, noise_to_signal=0.0))
    with_impacts = base.replace(operating=Operating(bearing_impact_order=3.58,
                                                    bearing_impact_to_signal=1.0))
    a, b = generate_record(base, seed=4), generate_record(with_impacts, seed=4)
    diff = b.channels["acc"] - a.channels["acc"]
    signal = a.truth["record"]["signal_rms_m_s2"]
    assert np.std(diff) == pytest.approx(signal, rel=0.02)
    revs = a.pinion_angle_rad[-1] / (2 * np.pi) - a.pinion_angle_rad[0] / (2 * np.pi)
    assert b.truth["record"]["bearing_impacts"]["impacts"] == pytest.approx(3.58 * revs, abs=3)
    # Synchronous average over whole revolutions: the impacts wash out, the gear signal stays.
    grid = 2 * np.pi * (np.ceil(a.pinion_angle_rad[0] / (2 * np.pi)) + np.arange(0, 45, 1 / 512))
    avg = [np.interp(grid, a.pinion_angle_rad, x).reshape(45, 512).mean(axis=0)
           for x in (diff, a.channels["acc"])]
    assert np.std(avg[0]) < 0.3 * np.std(avg[1])


def test_speed_fluctuation_is_locked_to_the_pinion_angle() -> None:
    model = flat_model(operating=Operating(speed_fluctuation_fraction=0.01, speed_fluctuation_order=2,
                                           speed_fluctuation_phase_deg=30.0))
    rec = generate_record(model, seed=2)
    angle = rec.pinion_angle_rad
    speed = np.gradient(angle, 1 / rec.sample_rate_hz) / (2 * np.pi) * 60.0
    expected = 1000.0 * (1 + 0.01 * np.cos(2 * angle + math.radians(30.0)))
    assert np.max(np.abs(speed[5:-5] - expected[5:-5])) < 0.01 * 1000.0 * 0.05  # 5 % of it


def test_a_record_without_tachometer_is_analysed_with_the_nominal_speed_hint() -> None:
    """The manifest carries the rig's nominal speed instead of a [tachometer]; gearwatch's
    tachless chain analyses the record (a rig with runouts: shaft orders to lock on)."""
    from gearwatch.usecases.analyze import analyze_record

    model = random_model(2024, contact_ratio=1.6, pinion_teeth=20, gear_teeth=21,
                         noise_to_signal=0.5, speed_drift_fraction=0.0, seconds=6.0,
                         tachometer=False, dynamics="linear")
    rec = generate_record(model, seed=7)
    campaign = rec.campaign()
    assert "tach" not in rec.channels
    assert campaign.tachometer is None
    assert campaign.rig.nominal_pinion_rpm == model.operating.speed_rpm
    analysis = analyze_record(rec.record_data(), campaign, input_sha256="0" * 64)
    assert len(analysis.channels[0].teeth) == 20
    assert analysis.speed_rpm == pytest.approx(model.operating.speed_rpm, rel=0.05)
