"""The simulator's whole configuration: one TOML file, written and read back losslessly.

Every section is a frozen dataclass with defaults for a CETIM-like 20/21 spur pair (the
seed's rig). :func:`model_to_toml` / :func:`model_from_toml` convert to and from TOML
text; :func:`model_from_dict` rejects unknown keys and wrong types with a message naming
the key. Lengths carry their unit in the name (``_mm``, ``_um``, ``_m``); angles ``_deg``.

Examples
--------
>>> from physics.config import GearPairModel, model_to_toml, model_from_toml
>>> model = GearPairModel()
>>> model_from_toml(model_to_toml(model)) == model
True
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
import types
import typing
from dataclasses import dataclass, field
from typing import Any, Literal

import tomli_w

Wheel = Literal["pinion", "gear"]
DofSet = Literal["full", "torsional"]
StiffnessProfile = Literal["constant", "linear", "parabolic"]
ForceDirection = Literal["line_of_action", "off_line_of_action"]


class ModelConfigError(ValueError):
    """A model file or dictionary has an unknown key, a wrong type or an impossible value."""


@dataclass(frozen=True)
class Geometry:
    """Standard (unshifted) involute spur pair."""

    module_mm: float = 10.0
    pinion_teeth: int = 20
    gear_teeth: int = 21
    pressure_angle_deg: float = 20.0
    face_width_mm: float = 20.0
    addendum_coefficient: float = 1.0
    """Addendum = coefficient × module."""
    dedendum_coefficient: float = 1.25
    """Dedendum = coefficient × module (checked against the active profile)."""


@dataclass(frozen=True)
class Mesh:
    stiffness_per_length_n_per_m2: float = 1.4e10
    """Mesh stiffness per unit contact length (ISO 6336 single stiffness c' ≈ 14 N/(mm·µm))."""
    damping_ratio: float = 0.05
    """Mesh-mode damping ratio; applied as damping proportional to the loaded mesh stiffness."""
    friction_coefficient: float = 0.0
    """Coulomb coefficient μ of sliding friction at the contact (0: frictionless, as before).

    The friction force μ·N acts perpendicular to the line of action, reverses at the pitch
    point, and has a moment about each wheel's axis (arm: distance from that wheel's
    tangency point on the base circle to the contact)."""
    stiffness_profile: StiffnessProfile = "constant"
    """Variation of the stiffness per unit length along the path of contact (ξ = −1 at its
    start, +1 at its end): ``"linear"`` k'(1 + a ξ), ``"parabolic"`` k'(1 − a (ξ² − 1/3));
    both average to k' over the path, so the mean mesh stiffness is unchanged."""
    stiffness_profile_variation: float = 0.0
    """The coefficient ``a`` of ``stiffness_profile`` (k' must stay > 0 along the path)."""
    contact_loss: bool = True
    """Teeth separate when the approach is lost (unit-step contact, as always). False: a
    linearised mesh — every contact-line piece in the geometric contact zone keeps its
    stiffness even when separated (tension allowed), the usual simplification of linear
    simulators; it cannot show loss of contact at light load or near resonance."""


@dataclass(frozen=True)
class WheelBody:
    """A rigid cylinder on its bearings: six degrees of freedom."""

    mass_kg: float = 4.93
    polar_inertia_kg_m2: float = 0.0247
    tilt_inertia_kg_m2: float = 0.0126
    bearing_radial_stiffness_n_per_m: float = 1.0e9
    bearing_axial_stiffness_n_per_m: float = 5.0e8
    bearing_tilt_stiffness_nm_per_rad: float = 1.0e7
    bearing_damping_ratio: float = 0.05
    bearing_radial_stiffness_ratio: float = 1.0
    """Anisotropic support: radial stiffness along the second principal axis divided by
    ``bearing_radial_stiffness_n_per_m`` (along the first). 1: isotropic (as before)."""
    bearing_principal_axis_deg: float = 0.0
    """Angle from the line of action to the first principal axis, towards the off-line
    direction. Away from 0° and 90° an anisotropic support couples the two radial directions."""


def _default_gear_body() -> WheelBody:
    return WheelBody(mass_kg=5.44, polar_inertia_kg_m2=0.0300, tilt_inertia_kg_m2=0.0152)


@dataclass(frozen=True)
class Drive:
    """Motor and load inertias behind torsionally flexible shafts, with a speed-controlled motor."""

    motor_inertia_kg_m2: float = 0.05
    load_inertia_kg_m2: float = 0.08
    input_shaft_stiffness_nm_per_rad: float = 5.0e4
    output_shaft_stiffness_nm_per_rad: float = 5.0e4
    shaft_damping_ratio: float = 0.05
    speed_control_time_constant_s: float = 0.05
    """Proportional speed loop of the motor: time constant of the whole train's speed error."""


@dataclass(frozen=True)
class Operating:
    speed_rpm: float = 1000.0
    """Nominal pinion speed."""
    load_torque_nm: float = 200.0
    """Mean load torque on the gear (output) shaft."""
    speed_drift_fraction: float = 0.0
    """Linear drift of the speed reference over the record, end minus start, relative to nominal."""
    speed_fluctuation_fraction: float = 0.0
    """Amplitude of a sinusoidal fluctuation of the speed reference, relative to nominal."""
    speed_fluctuation_hz: float = 0.5
    """Frequency of that fluctuation when ``speed_fluctuation_order`` is 0 (not synchronous)."""
    speed_fluctuation_order: int = 0
    """0: the fluctuation is at ``speed_fluctuation_hz``. n ≥ 1: it is locked to the pinion
    shaft, n cycles per pinion revolution (motor cogging, a cardan joint):
    ω_ref = Ω (1 + fraction · cos(n θ_pinion + phase)), θ_pinion = 0 at the tach mark."""
    speed_fluctuation_phase_deg: float = 0.0
    load_fluctuation_fraction: float = 0.0
    """Amplitude of a load-torque fluctuation locked to the output shaft angle, relative to mean."""
    load_fluctuation_order: int = 1
    """Cycles of the load fluctuation per output-shaft revolution."""
    load_fluctuation_phase_deg: float = 0.0


@dataclass(frozen=True)
class Spall:
    """A parallelepiped cavity: depth, extent along the profile (on the base plane), width on the face."""

    wheel: Wheel = "pinion"
    tooth: int = 16
    """1-based tooth number (tooth 1 of the pinion passes the pitch point at ``tooth1_pitch_angle_deg``)."""
    depth_um: float = 15.0
    profile_start_mm: float = -2.3
    """Start along the path of contact, relative to the pitch point (negative: before it)."""
    profile_extent_mm: float = 4.6
    face_start_mm: float = 0.0
    """Start across the face, from the face edge."""
    face_width_mm: float = 2.0


@dataclass(frozen=True)
class Crack:
    """A root crack: the cracked tooth's mesh stiffness is reduced over its whole mesh."""

    wheel: Wheel = "pinion"
    tooth: int = 16
    stiffness_loss_fraction: float = 0.2


@dataclass(frozen=True)
class Deviations:
    pinion_tip_relief_um: float = 0.0
    pinion_tip_relief_length_mm: float = 0.0
    """Length of the relief along the path of contact, from the pinion tip."""
    gear_tip_relief_um: float = 0.0
    gear_tip_relief_length_mm: float = 0.0
    tip_relief_exponent: float = 1.0
    """1: linear relief, 2: parabolic."""
    pinion_pitch_errors_um: list[float] = field(default_factory=list)
    """Per-tooth index (position) errors along the line of action; empty = none, else one per tooth."""
    gear_pitch_errors_um: list[float] = field(default_factory=list)
    pinion_eccentricity_um: float = 0.0
    pinion_eccentricity_phase_deg: float = 0.0
    gear_eccentricity_um: float = 0.0
    gear_eccentricity_phase_deg: float = 0.0
    spalls: list[Spall] = field(default_factory=list)
    cracks: list[Crack] = field(default_factory=list)


@dataclass(frozen=True)
class StructuralMode:
    """One transfer-path mode: a(s) = gain · s²/(s² + 2ζωs + ω²) · F_bearing(s)."""

    frequency_hz: float = 3000.0
    damping_ratio: float = 0.03
    gain_m_s2_per_n: float = 0.01


def _default_modes() -> list[StructuralMode]:
    return [
        StructuralMode(frequency_hz=2200.0, damping_ratio=0.04, gain_m_s2_per_n=0.004),
        StructuralMode(frequency_hz=4600.0, damping_ratio=0.03, gain_m_s2_per_n=0.008),
        StructuralMode(frequency_hz=6900.0, damping_ratio=0.05, gain_m_s2_per_n=0.003),
    ]


@dataclass(frozen=True)
class Sensor:
    name: str = "acc"
    source: Wheel = "pinion"
    """Which wheel's bearing force drives this sensor."""
    direction: ForceDirection = "line_of_action"
    """Component of that bearing force: along the line of action, or perpendicular to it in
    the plane of the wheels (where sliding friction and support anisotropy show)."""
    noise_rms_m_s2: float = 0.05
    modes: list[StructuralMode] = field(default_factory=_default_modes)


def _default_sensors() -> list[Sensor]:
    return [Sensor()]


@dataclass(frozen=True)
class Tachometer:
    name: str = "tach"
    shaft: Wheel = "pinion"
    pulses_per_rev: int = 1
    tooth1_pitch_angle_deg: float = 337.4
    """Pinion angle after the pinion reference mark at which pinion tooth 1 passes the pitch point."""
    high_v: float = 5.0
    duty_fraction: float = 0.1
    """Fraction of the pulse period the TTL level stays high."""


@dataclass(frozen=True)
class Acquisition:
    sample_rate_hz: float = 20000.0
    oversampling: int = 16
    """Integrator steps per output sample."""
    anti_alias_cutoff_fraction: float = 0.4
    """Cutoff of the anti-alias low-pass as a fraction of the output rate."""
    anti_alias_order: int = 8
    warmup_s: float = 0.2
    """Simulated then discarded, so that the start transient has decayed."""


@dataclass(frozen=True)
class GearPairModel:
    """The whole simulator input; see ``docs/simulator.md``."""

    dofs: DofSet = "full"
    """``"full"``: six DOF per wheel (Velex & Maatar); ``"torsional"``: bearings rigid."""
    geometry: Geometry = field(default_factory=Geometry)
    mesh: Mesh = field(default_factory=Mesh)
    pinion: WheelBody = field(default_factory=WheelBody)
    gear: WheelBody = field(default_factory=_default_gear_body)
    drive: Drive = field(default_factory=Drive)
    operating: Operating = field(default_factory=Operating)
    deviations: Deviations = field(default_factory=Deviations)
    sensors: list[Sensor] = field(default_factory=_default_sensors)
    tachometer: Tachometer = field(default_factory=Tachometer)
    acquisition: Acquisition = field(default_factory=Acquisition)

    def replace(self, **changes: Any) -> GearPairModel:
        return dataclasses.replace(self, **changes)


def model_to_dict(model: Any) -> dict[str, Any]:
    """Plain dictionary of a configuration dataclass (lists of tables kept)."""
    return dataclasses.asdict(model)


def _convert(value: Any, hint: Any, where: str) -> Any:
    origin = typing.get_origin(hint)
    if dataclasses.is_dataclass(hint) and isinstance(hint, type):
        if not isinstance(value, dict):
            raise ModelConfigError(f"{where}: expected a table, got {type(value).__name__}")
        return _build(hint, value, where)
    if origin is list:
        (item_hint,) = typing.get_args(hint)
        if not isinstance(value, list):
            raise ModelConfigError(f"{where}: expected a list, got {type(value).__name__}")
        return [_convert(v, item_hint, f"{where}[{i}]") for i, v in enumerate(value)]
    if origin is Literal:
        allowed = typing.get_args(hint)
        if value not in allowed:
            raise ModelConfigError(f"{where}: must be one of {', '.join(map(repr, allowed))}")
        return value
    if origin in (typing.Union, types.UnionType):
        raise ModelConfigError(f"{where}: unsupported type")  # pragma: no cover
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ModelConfigError(f"{where}: expected a number, got {type(value).__name__}")
        if not math.isfinite(value):
            raise ModelConfigError(f"{where}: must be finite")
        return float(value)
    if hint is bool:
        if not isinstance(value, bool):
            raise ModelConfigError(f"{where}: expected true or false, got {type(value).__name__}")
        return value
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ModelConfigError(f"{where}: expected an integer, got {type(value).__name__}")
        return value
    if hint is str:
        if not isinstance(value, str):
            raise ModelConfigError(f"{where}: expected a string, got {type(value).__name__}")
        return value
    raise ModelConfigError(f"{where}: unsupported type {hint!r}")  # pragma: no cover


def _build(cls: type, data: dict[str, Any], where: str) -> Any:
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls)]
    unknown = sorted(set(data) - set(names))
    if unknown:
        prefix = f"{where}." if where else ""
        raise ModelConfigError(f"unknown key(s): {', '.join(prefix + k for k in unknown)}")
    kwargs = {}
    for name in names:
        if name in data:
            kwargs[name] = _convert(data[name], hints[name], f"{where}.{name}" if where else name)
    return cls(**kwargs)


def model_from_dict(data: dict[str, Any]) -> GearPairModel:
    """Build and validate a model from a (TOML-parsed) dictionary; missing keys take defaults."""
    model: GearPairModel = _build(GearPairModel, data, "")
    validate_model(model)
    return model


def model_to_toml(model: GearPairModel) -> str:
    """TOML text of the model (every key written, so the file documents itself)."""
    return tomli_w.dumps(model_to_dict(model))


def model_from_toml(text: str) -> GearPairModel:
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise ModelConfigError(f"not valid TOML: {error}") from None
    return model_from_dict(data)


def validate_model(model: GearPairModel) -> None:
    """Raise :class:`ModelConfigError` naming the first impossible value."""
    g = model.geometry
    positive = {
        "geometry.module_mm": g.module_mm,
        "geometry.face_width_mm": g.face_width_mm,
        "mesh.stiffness_per_length_n_per_m2": model.mesh.stiffness_per_length_n_per_m2,
        "operating.speed_rpm": model.operating.speed_rpm,
        "acquisition.sample_rate_hz": model.acquisition.sample_rate_hz,
        "pinion.mass_kg": model.pinion.mass_kg,
        "pinion.polar_inertia_kg_m2": model.pinion.polar_inertia_kg_m2,
        "pinion.tilt_inertia_kg_m2": model.pinion.tilt_inertia_kg_m2,
        "gear.mass_kg": model.gear.mass_kg,
        "gear.polar_inertia_kg_m2": model.gear.polar_inertia_kg_m2,
        "gear.tilt_inertia_kg_m2": model.gear.tilt_inertia_kg_m2,
        "drive.motor_inertia_kg_m2": model.drive.motor_inertia_kg_m2,
        "drive.load_inertia_kg_m2": model.drive.load_inertia_kg_m2,
        "drive.speed_control_time_constant_s": model.drive.speed_control_time_constant_s,
    }
    for name, value in positive.items():
        if not value > 0:
            raise ModelConfigError(f"{name} must be > 0")
    if g.pinion_teeth < 5 or g.gear_teeth < 5:
        raise ModelConfigError("geometry.pinion_teeth and geometry.gear_teeth must be ≥ 5")
    if not 5.0 <= g.pressure_angle_deg <= 40.0:
        raise ModelConfigError("geometry.pressure_angle_deg must be within 5..40")
    mesh = model.mesh
    if not mesh.friction_coefficient >= 0:
        raise ModelConfigError("mesh.friction_coefficient must be ≥ 0")
    if model.operating.speed_fluctuation_order < 0:
        raise ModelConfigError("operating.speed_fluctuation_order must be ≥ 0")
    a = mesh.stiffness_profile_variation
    lowest = {
        "constant": 1.0,
        "linear": 1.0 - abs(a),
        "parabolic": min(1.0 + a / 3, 1.0 - 2 * a / 3),
    }
    if not lowest[mesh.stiffness_profile] > 0:
        raise ModelConfigError(
            "mesh.stiffness_profile_variation: the stiffness per length must stay > 0 "
            "(linear: |a| < 1; parabolic: −3 < a < 1.5)"
        )
    for label, body in (("pinion", model.pinion), ("gear", model.gear)):
        if not body.bearing_radial_stiffness_ratio > 0:
            raise ModelConfigError(f"{label}.bearing_radial_stiffness_ratio must be > 0")
    if model.acquisition.oversampling < 1:
        raise ModelConfigError("acquisition.oversampling must be ≥ 1")
    if not 0 < model.acquisition.anti_alias_cutoff_fraction < 0.5:
        raise ModelConfigError("acquisition.anti_alias_cutoff_fraction must be within (0, 0.5)")
    if model.tachometer.pulses_per_rev < 1:
        raise ModelConfigError("tachometer.pulses_per_rev must be ≥ 1")
    if not 0 < model.tachometer.duty_fraction < 1:
        raise ModelConfigError("tachometer.duty_fraction must be within (0, 1)")
    d = model.deviations
    for key, errors, teeth in (
        ("deviations.pinion_pitch_errors_um", d.pinion_pitch_errors_um, g.pinion_teeth),
        ("deviations.gear_pitch_errors_um", d.gear_pitch_errors_um, g.gear_teeth),
    ):
        if errors and len(errors) != teeth:
            raise ModelConfigError(f"{key} must be empty or have one value per tooth ({teeth})")
    for i, spall in enumerate(d.spalls):
        teeth = g.pinion_teeth if spall.wheel == "pinion" else g.gear_teeth
        if not 1 <= spall.tooth <= teeth:
            raise ModelConfigError(f"deviations.spalls[{i}].tooth must be within 1..{teeth}")
        if spall.profile_extent_mm < 0 or spall.face_width_mm < 0 or spall.depth_um < 0:
            raise ModelConfigError(f"deviations.spalls[{i}]: depth and extents must be ≥ 0")
    for i, crack in enumerate(d.cracks):
        teeth = g.pinion_teeth if crack.wheel == "pinion" else g.gear_teeth
        if not 1 <= crack.tooth <= teeth:
            raise ModelConfigError(f"deviations.cracks[{i}].tooth must be within 1..{teeth}")
        if not 0 <= crack.stiffness_loss_fraction < 1:
            raise ModelConfigError(
                f"deviations.cracks[{i}].stiffness_loss_fraction must be within [0, 1)"
            )
    if not model.sensors:
        raise ModelConfigError("sensors: at least one sensor is needed")
    names = [s.name for s in model.sensors] + [model.tachometer.name]
    if len(set(names)) != len(names):
        raise ModelConfigError("sensors and tachometer must have distinct names")
