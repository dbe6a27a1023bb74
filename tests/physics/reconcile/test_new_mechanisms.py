"""The last three catalogue plug-ins: sliding_friction, speed_fluctuation, contact_loss.

Each test hides one mechanism in a simulated record and checks that reconcile names it with
its parameter (or, for a control, that it does not). Records are short (2.5–3 s), the band
small and the scanned mechanisms restricted to the one under test and its declared confuser,
so that each reconciliation stays within a few tens of simulations.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from physics.config import Acquisition, GearPairModel, Operating, Sensor
from physics.reconcile import (
    CATALOGUE,
    CONFUSABLE,
    UNAVAILABLE,
    Candidate,
    MeasuredRecord,
    reconcile,
)
from physics.reconcile.fitter import _Fitter
from physics.reconcile.forward import ForwardSetup, channel_model
from physics.reconcile.observables import hunting_spectrum
from physics.simulator import simulate

from .conftest import fast_options


def _measured(model: GearPairModel, seconds: float, seed: int) -> MeasuredRecord:
    r = simulate(model, seconds=seconds, seed=seed)
    return MeasuredRecord(r.channels[model.sensors[0].name], r.sample_rate_hz, r.tach_pulse_times_s, 1)


def _model(speed_rpm: float = 1000.0, load_nm: float = 200.0, **changes: object) -> GearPairModel:
    model = GearPairModel(
        operating=Operating(speed_rpm=speed_rpm, load_torque_nm=load_nm), acquisition=Acquisition(warmup_s=0.2)
    )
    return dataclasses.replace(model, **changes)  # type: ignore[arg-type]


def _with(model: GearPairModel, section: str, **changes: object) -> GearPairModel:
    return model.replace(**{section: dataclasses.replace(getattr(model, section), **changes)})


# --- catalogue ------------------------------------------------------------------------------


def test_every_issue_name_is_a_fitted_plugin_and_new_pairs_are_declared() -> None:
    assert UNAVAILABLE == {}
    assert {"sliding_friction", "speed_fluctuation", "contact_loss"} <= set(CATALOGUE)
    assert frozenset({"profile_modification", "sliding_friction"}) in CONFUSABLE
    assert frozenset({"pinion_eccentricity", "speed_fluctuation"}) in CONFUSABLE


def test_new_plugins_put_their_physics_into_the_configuration() -> None:
    base = _model()
    m = CATALOGUE["sliding_friction"].apply(base, Candidate("sliding_friction"), {"friction_coefficient": 0.04})
    m = CATALOGUE["sliding_friction"].apply(m, Candidate("sliding_friction"), {"friction_coefficient": 0.03})
    assert m.mesh.friction_coefficient == pytest.approx(0.07)  # added to what is configured
    plugin = CATALOGUE["speed_fluctuation"]
    assert [c.order for c in plugin.candidates(base)] == [1, 2]
    m = plugin.apply(base, Candidate("speed_fluctuation", "pinion", order=2), {"fraction": 0.006, "phase_deg": 30.0})
    op = m.operating
    assert (op.speed_fluctuation_fraction, op.speed_fluctuation_order, op.speed_fluctuation_phase_deg) == (0.006, 2, 30.0)
    params = plugin.from_vector(np.array(plugin.to_vector({"fraction": 0.006, "phase_deg": 30.0})))
    assert params == pytest.approx({"fraction": 0.006, "phase_deg": 30.0})
    contact = CATALOGUE["contact_loss"]
    assert contact.candidates(base) == []  # the default mesh already loses contact
    linear = _with(base, "mesh", contact_loss=False)
    assert contact.candidates(linear) == [Candidate("contact_loss")]
    assert contact.apply(linear, Candidate("contact_loss"), {}).mesh.contact_loss is True
    assert contact.steps == () and contact.from_vector(np.zeros(0)) == {}


def test_forward_channels_keep_the_sensor_direction() -> None:
    model = _model(sensors=[Sensor(direction="off_line_of_action")])
    setup = ForwardSetup(speed_rpm=1000.0, pinion_teeth=20, gear_teeth=21, samples_per_mesh=16, n_bins=100)
    assert {s.direction for s in channel_model(model, setup).sensors} == {"off_line_of_action"}


# --- sliding friction -----------------------------------------------------------------------

FRICTION_OPTIONS = fast_options(
    samples_per_mesh=16, max_frequency_hz=2500.0, forward_oversampling=8, max_findings=1,
    mechanisms=("sliding_friction",),
)


def test_off_line_gains_are_anchored_to_the_configuration() -> None:
    """Off the line of action the signal is μ × gain: the configured gains carry the scale."""
    off = _model(sensors=[Sensor(name="off", direction="off_line_of_action")])
    rec = _measured(_with(off, "mesh", friction_coefficient=0.05), 2.0, seed=1)
    spec = hunting_spectrum(rec.signal, rec.sample_rate_hz, rec.pulse_times_s, 1, pinion_teeth=20,
                            gear_teeth=21, samples_per_mesh=16, max_frequency_hz=2500.0)
    fitter = _Fitter(spec, spec.mean, spec.variance, off, FRICTION_OPTIONS)
    configured = [m.gain_m_s2_per_n for m in off.sensors[0].modes]
    assert [g for g, _sigma in fitter.gain_prior] == configured
    # A frictionless base predicts exactly nothing there: the gains stay as configured.
    evaluation = fitter.evaluate(fitter.theta0([]), [])
    assert not np.any(evaluation.prediction)
    np.testing.assert_allclose(evaluation.gains, configured)
    np.testing.assert_allclose(evaluation.gain_prior, 0.0, atol=1e-12)
    # On the line of action the data fix the gains: no prior.
    assert _Fitter(spec, spec.mean, spec.variance, _model(), FRICTION_OPTIONS).gain_prior == []


@pytest.mark.slow
def test_sliding_friction_seen_off_the_line_of_action_is_found_with_its_coefficient() -> None:
    """An accelerometer across the line of action sees the friction force only: base μ = 0
    predicts nothing there; the gains are anchored to the configuration (off-line sensor), so
    μ is identifiable."""
    base = _model(sensors=[Sensor(name="off", direction="off_line_of_action")])
    truth = _with(base, "mesh", friction_coefficient=0.08)
    result = reconcile(_measured(truth, 3.0, seed=7), base, options=FRICTION_OPTIONS)
    data = result.to_json()
    assert [f["mechanism"] for f in data["findings"]] == ["sliding_friction"], data["findings"]
    mu = data["findings"][0]["parameters"]["friction_coefficient"]
    assert mu == pytest.approx(0.08, rel=0.1)
    assert data["findings"][0]["evidence"]["delta_bic"] < -100
    assert data["status"] == "explained", data["final"]
    assert data["catalogue_unavailable"] == {}
    assert data["not_scanned"]["contact_loss"] == "not requested"  # FRICTION_OPTIONS asks for friction only
    assert result.updated_model.mesh.friction_coefficient == pytest.approx(mu, rel=1e-3)


@pytest.mark.slow
def test_friction_on_a_line_of_action_sensor_only_on_request_and_no_false_finding() -> None:
    base = _model()
    record = _measured(base, 3.0, seed=11)
    scanned = reconcile(record, base, options=dataclasses.replace(FRICTION_OPTIONS, friction_on_line_of_action=True))
    data = scanned.to_json()
    assert data["findings"] == [], data["findings"]
    assert data["status"] == "explained", data["final"]
    default = reconcile(record, base, options=FRICTION_OPTIONS)
    assert default.candidates_scored == [] and default.to_json()["findings"] == []
    # Scanning friction took its simulation (a negative linearised μ is then not scored).
    assert scanned.simulations == default.simulations + 1


# --- speed fluctuation ----------------------------------------------------------------------


@pytest.mark.slow
def test_speed_fluctuation_at_the_pinion_order_is_found_not_taken_for_a_runout() -> None:
    """A 0.8 % set-point fluctuation once per pinion revolution: its phase modulation of the
    mesh looks like a pinion runout's; both are refitted and the speed fluctuation (with the
    AM of its inertial torques) wins. (At 2000 rpm the AM is weaker: the runout fits as well
    and the pair comes out unresolved.)"""
    base = _model(speed_rpm=1000.0)
    truth = _with(base, "operating", speed_fluctuation_fraction=0.008, speed_fluctuation_order=1,
                  speed_fluctuation_phase_deg=60.0)
    options = fast_options(samples_per_mesh=16, max_frequency_hz=2500.0, max_findings=1,
                           mechanisms=("pinion_eccentricity", "speed_fluctuation"))
    data = reconcile(_measured(truth, 3.0, seed=3), base, options=options).to_json()
    found = data["findings"]
    assert [(f["mechanism"], f.get("order")) for f in found] == [("speed_fluctuation", 1)], found
    params = found[0]["parameters"]
    assert params["fraction"] == pytest.approx(0.008, rel=0.1)
    assert (params["phase_deg"] - 60.0 + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=10.0)
    assert data["status"] == "explained", data["final"]


# --- contact loss ---------------------------------------------------------------------------

CONTACT_OPTIONS = fast_options(samples_per_mesh=16, max_frequency_hz=4000.0, max_findings=1,
                               mechanisms=("contact_loss",))


@pytest.mark.slow
def test_contact_loss_found_at_light_load_near_resonance_on_a_linear_base() -> None:
    """4800 rpm (mesh 1600 Hz, on the mesh-mode response), 10 N·m: the teeth separate for a
    quarter of the time; the configuration's linearised mesh cannot follow."""
    truth = _model(speed_rpm=4800.0, load_nm=10.0)
    base = _with(truth, "mesh", contact_loss=False)
    check = simulate(truth, seconds=0.3, seed=None)
    assert np.mean(check.contact_length_m == 0.0) > 0.05  # the truth does lose contact
    result = reconcile(_measured(truth, 2.0, seed=5), base, options=CONTACT_OPTIONS)
    data = result.to_json()
    assert [f["mechanism"] for f in data["findings"]] == ["contact_loss"], data["findings"]
    finding = data["findings"][0]
    assert finding["evidence"]["delta_bic"] < -100
    assert finding["parameters"]["loss_of_contact_fraction"] > 0.05
    assert finding["parameters"]["min_contact_length_mm"] == 0.0
    assert data["baseline"]["chi2_dof"] > 2 * data["final"]["chi2_dof"]
    assert result.updated_model.mesh.contact_loss is True


@pytest.mark.slow
def test_no_contact_loss_finding_at_high_load() -> None:
    truth = _model(speed_rpm=2000.0, load_nm=200.0)
    assert simulate(truth, seconds=0.2, seed=None).contact_length_m.min() > 0.0
    base = _with(truth, "mesh", contact_loss=False)
    data = reconcile(_measured(truth, 2.5, seed=9), base, options=CONTACT_OPTIONS).to_json()
    assert data["findings"] == [], data["findings"]
    assert data["status"] == "explained", data["final"]


def test_speed_fluctuation_is_scanned_only_when_asked() -> None:
    """One pulse per revolution at one speed: a shaft-locked speed fluctuation is scanned only on
    request, and the JSON says why (``not_scanned``)."""
    from physics.reconcile import DEFAULT_MECHANISMS, NOT_SCANNED_BY_DEFAULT, ReconcileOptions

    assert "speed_fluctuation" not in ReconcileOptions().mechanisms
    assert set(DEFAULT_MECHANISMS) | set(NOT_SCANNED_BY_DEFAULT) == set(CATALOGUE)
    assert "pinion runout" in NOT_SCANNED_BY_DEFAULT["speed_fluctuation"]
