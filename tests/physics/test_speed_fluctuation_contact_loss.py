"""Simulator fields of the last catalogue plug-ins (issue 6): a speed fluctuation locked to a
pinion-shaft order, and a linearised mesh without contact loss (``Mesh.contact_loss``).
The defaults leave every record bit-identical (``test_extensions.py`` checks the digests)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from physics.config import (
    Acquisition,
    Drive,
    GearPairModel,
    Mesh,
    ModelConfigError,
    Operating,
    Sensor,
    model_from_dict,
    model_from_toml,
    model_to_toml,
)
from physics.simulator import simulate

QUIET = Sensor(noise_rms_m_s2=0.0)


def _linear(model: GearPairModel) -> GearPairModel:
    return model.replace(mesh=dataclasses.replace(model.mesh, contact_loss=False))


# --- speed fluctuation locked to a shaft order ----------------------------------------------


@pytest.mark.parametrize(("order", "phase_deg"), [(1, 60.0), (2, 200.0)])
def test_order_locked_speed_fluctuation_follows_the_pinion_angle(order: int, phase_deg: float) -> None:
    """A stiff speed loop at low speed: the pinion speed is the set-point
    Ω (1 + f cos(n θ + φ)) as a function of the pinion angle, the same in every revolution."""
    fraction = 0.01
    model = GearPairModel(
        dofs="torsional",
        operating=Operating(
            speed_rpm=300.0,
            speed_fluctuation_fraction=fraction,
            speed_fluctuation_order=order,
            speed_fluctuation_phase_deg=phase_deg,
        ),
        drive=Drive(speed_control_time_constant_s=0.002),
        sensors=[QUIET],
        acquisition=Acquisition(sample_rate_hz=5000.0, oversampling=4, warmup_s=0.2),
    )
    r = simulate(model, seconds=1.0, seed=None)
    theta = r.pinion_angle_rad
    speed = np.gradient(theta, 1.0 / r.sample_rate_hz)
    nominal = 300.0 * 2 * math.pi / 60
    design = np.stack([np.ones_like(theta), np.cos(order * theta), np.sin(order * theta)], axis=1)
    (mean, c, s), *_ = np.linalg.lstsq(design, speed / nominal - 1.0, rcond=None)
    # cos(nθ + φ) = cos φ cos nθ − sin φ sin nθ
    amplitude = math.hypot(c, s)
    phase = math.degrees(math.atan2(-s, c)) % 360.0
    assert amplitude == pytest.approx(fraction, rel=0.1)
    assert (phase - phase_deg + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=10.0)
    assert abs(mean) < 0.1 * fraction
    # Locked to the angle: what is left after the fitted sinusoid is small.
    left = speed / nominal - 1.0 - design @ np.array([mean, c, s])
    assert np.std(left) < 0.1 * fraction


def test_order_zero_keeps_the_hz_based_fluctuation() -> None:
    """Order 0 (default) is the time-based modulation: the phase field has no effect."""
    op = Operating(speed_fluctuation_fraction=0.01, speed_fluctuation_hz=3.0)
    base = GearPairModel(dofs="torsional", operating=op, sensors=[QUIET],
                         acquisition=Acquisition(warmup_s=0.05, oversampling=4))
    shifted = base.replace(operating=dataclasses.replace(op, speed_fluctuation_phase_deg=90.0))
    a = simulate(base, seconds=0.2, seed=None)
    b = simulate(shifted, seconds=0.2, seed=None)
    np.testing.assert_array_equal(a.pinion_angle_rad, b.pinion_angle_rad)
    locked = base.replace(operating=dataclasses.replace(op, speed_fluctuation_order=1))
    c = simulate(locked, seconds=0.2, seed=None)
    assert not np.array_equal(a.pinion_angle_rad, c.pinion_angle_rad)


# --- linearised mesh (no contact loss) ------------------------------------------------------

LIGHT_RESONANT = GearPairModel(
    operating=Operating(speed_rpm=4800.0, load_torque_nm=10.0),
    sensors=[QUIET],
    acquisition=Acquisition(warmup_s=0.2),
)
"""Mesh frequency 1600 Hz near the mesh-mode response, 10 N·m: the teeth separate."""


def test_light_load_near_resonance_loses_contact_and_the_linear_mesh_pulls() -> None:
    heaviside = simulate(LIGHT_RESONANT, seconds=0.25, seed=None)
    linear = simulate(_linear(LIGHT_RESONANT), seconds=0.25, seed=None)
    lost = float(np.mean(heaviside.contact_length_m == 0.0))
    assert lost > 0.05
    assert heaviside.mesh_force_n.min() >= 0.0
    # The linearised mesh never separates: its force goes into tension instead.
    assert linear.contact_length_m.min() > 0.0
    assert linear.mesh_force_n.min() < 0.0
    diff = heaviside.channels["acc"] - linear.channels["acc"]
    assert np.std(diff) > 0.1 * np.std(heaviside.channels["acc"])


def test_without_separation_the_two_meshes_agree() -> None:
    """High load, ideal teeth: every piece stays loaded, so the linearised mesh is the same model."""
    model = GearPairModel(operating=Operating(speed_rpm=2000.0, load_torque_nm=200.0), sensors=[QUIET],
                          acquisition=Acquisition(warmup_s=0.1))
    heaviside = simulate(model, seconds=0.2, seed=None)
    linear = simulate(_linear(model), seconds=0.2, seed=None)
    assert heaviside.contact_length_m.min() > 0.0
    scale = np.max(np.abs(heaviside.channels["acc"]))
    assert np.max(np.abs(heaviside.channels["acc"] - linear.channels["acc"])) < 1e-9 * scale
    np.testing.assert_allclose(linear.mesh_force_n, heaviside.mesh_force_n, rtol=1e-12)


# --- configuration --------------------------------------------------------------------------


def test_new_fields_round_trip_and_are_validated() -> None:
    model = GearPairModel(
        mesh=Mesh(contact_loss=False),
        operating=Operating(speed_fluctuation_order=2, speed_fluctuation_phase_deg=45.0),
    )
    text = model_to_toml(model)
    assert "contact_loss = false" in text and "speed_fluctuation_order = 2" in text
    assert model_from_toml(text) == model
    with pytest.raises(ModelConfigError, match=r"mesh\.contact_loss: expected true or false"):
        model_from_dict({"mesh": {"contact_loss": 1}})
    with pytest.raises(ModelConfigError, match=r"operating\.speed_fluctuation_order must be ≥ 0"):
        model_from_dict({"operating": {"speed_fluctuation_order": -1}})
    with pytest.raises(ModelConfigError, match=r"speed_fluctuation_order: expected an integer"):
        model_from_dict({"operating": {"speed_fluctuation_order": 1.5}})
