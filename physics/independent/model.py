"""Parameters of the independent line-of-action gear-pair generator (plain frozen dataclasses).

Every parameter has a physical meaning and a default; :func:`validate_model` refuses
impossible values with a message naming the field; :func:`model_to_dict` /
:func:`model_from_dict` round-trip a model through JSON-compatible dicts (the truth sidecar).
See ``docs/independent-simulator.md`` for the equations.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Literal

Wheel = Literal["pinion", "gear"]


class IndependentModelError(ValueError):
    """A parameter of the independent generator is out of its range."""


@dataclass(frozen=True)
class PairGeometry:
    pinion_teeth: int = 20
    gear_teeth: int = 21
    module_mm: float = 5.0
    pressure_angle_deg: float = 20.0
    face_width_mm: float = 20.0
    addendum_coefficient: float = 1.0
    """Tip radius = (z/2 + addendum) · module, both wheels; sets the contact ratio when
    ``contact_ratio`` is None."""
    contact_ratio: float | None = None
    """Given directly (the path of contact is then ``contact_ratio`` base pitches, split by
    ``approach_fraction`` around the pitch point); None: from the involute geometry."""
    approach_fraction: float = 0.5
    """Share of the path of contact before the pitch point (only with ``contact_ratio`` given)."""
    rim_density_kg_m3: float = 7850.0
    inertia_factor: float = 1.6
    """Each wheel's polar inertia relative to a solid steel disc of its pitch radius and face
    width (hub, shaft, couplings)."""


@dataclass(frozen=True)
class PairStiffness:
    """Stiffness of ONE tooth pair along its own path of contact (ξ from 0 at the start of
    contact, pinion root / gear tip, to 1 at the end, pinion tip):
    ``k(ξ) = k_peak · b · (1 − curvature·(2ξ−1)² + skew·(2ξ−1))`` (Weber/ISO-like shape,
    stiffest mid-path)."""

    peak_n_per_m_per_mm: float = 1.5e7
    """Peak single-pair stiffness per mm of face width (ISO 6336's c' ≈ 14 N/(mm·µm))."""
    curvature: float = 0.45
    skew: float = 0.05
    damping_ratio: float = 0.06
    """Viscous damping of the mesh mode (fraction of critical)."""
    engagement_fraction: float = 0.04
    """Length (fraction of the path) over which a pair's stiffness rises from 0 at the start of
    contact and falls to 0 at its end (sin² taper): the gradual engagement of real teeth
    (deflected neighbours, corner contact) instead of a step."""
    shaft_stiffness_n_per_m: float = 2.5e7
    """Torsional stiffness of the shafts to the (large) motor and load inertias, reflected onto
    the line of action: it makes the mesh force follow the static TE at low frequency."""
    contact_compliance_share: float = 0.3
    """Share h of a pair's compliance that is local (Hertzian) contact, in series with the
    tooth bending/foundation share 1 − h that a pit does not change: a pit of depth d on a face
    fraction w unloads that fraction once the local approach falls short of d (see docs)."""


@dataclass(frozen=True)
class ToothErrors:
    """Manufacturing deviations (material removed along the line of action is positive)."""

    pinion_index_um: tuple[float, ...] = ()
    """Per pinion tooth (1..Z1): position deviation of the flank; empty = none."""
    gear_index_um: tuple[float, ...] = ()
    pinion_profile_slope_um: tuple[float, ...] = ()
    """Per pinion tooth: profile slope deviation, tip minus root over the path of contact."""
    gear_profile_slope_um: tuple[float, ...] = ()
    profile_crowning_um: float = 0.0
    """Common profile barrelling: extra removal ``c·(2ξ−1)²`` on every pair."""
    pinion_tip_relief_um: float = 0.0
    gear_tip_relief_um: float = 0.0
    tip_relief_length_fraction: float = 0.25
    """Length of the relief at each end of the path of contact, fraction of the path."""
    tip_relief_exponent: float = 1.0
    pinion_eccentricity_um: float = 0.0
    pinion_eccentricity_phase_deg: float = 0.0
    """Pinion angle after the tach mark at which the pinion's centre offset points along the
    line of action (maximum approach)."""
    gear_eccentricity_um: float = 0.0
    gear_eccentricity_phase_deg: float = 0.0
    """Gear angle (0 when gear tooth 1 is on the pitch point) of the maximum approach."""


@dataclass(frozen=True)
class Spall:
    """A partial-face, partial-profile pit: a fraction of the face loses ``depth_um`` of
    material over part of the path of contact, with sloped walls."""

    tooth: int
    depth_um: float = 10.0
    extent_fraction: float = 0.3
    """Length along the tooth's path of contact, fraction of the path (0.1–0.6 typical)."""
    centre_fraction: float = 0.4
    """Centre along the pitted wheel's own path of contact, from its root end (0) to its tip
    end (1): for the pinion 0 is the start of contact, for the gear the end."""
    face_fraction: float = 0.3
    """Share of the face width that is pitted."""
    wall_fraction: float = 0.2
    """Share of the extent over which the depth ramps up at each wall (cosine)."""
    wheel: Wheel = "pinion"


@dataclass(frozen=True)
class Crack:
    """A root crack: the tooth's pair stiffness is reduced by ``stiffness_loss_fraction``
    while that tooth is in contact."""

    tooth: int
    stiffness_loss_fraction: float = 0.1
    wheel: Wheel = "pinion"


@dataclass(frozen=True)
class Mode:
    """One structural mode of the path: acceleration per newton
    ``s²·(R/(s−p) + R̄/(s−p̄))``, ``p = −ζω + iω√(1−ζ²)``, ``R = g·e^{iφ}/(2iω_d)``
    (φ = 0: the classic ``g s²/(s² + 2ζωs + ω²)``; φ ≠ 0: a non-collocated / non-proportionally
    damped mode whose resonance has its own phase)."""

    frequency_hz: float
    damping_ratio: float = 0.03
    gain_m_s2_per_n: float = 0.005
    phase_deg: float = 0.0


def _default_line_modes() -> tuple[Mode, ...]:
    return (
        Mode(620.0, 0.05, 0.003, 20.0),
        Mode(1850.0, 0.035, 0.004, 0.0),
        Mode(3900.0, 0.025, 0.007, 30.0),
        Mode(7300.0, 0.045, 0.003, -40.0),
    )


def _default_cross_modes() -> tuple[Mode, ...]:
    return (Mode(2600.0, 0.03, 0.005, 0.0), Mode(5400.0, 0.04, 0.004, 60.0))


@dataclass(frozen=True)
class TransferPath:
    """Housing response: modes driven by the mesh force (along the line of action) and a
    second set driven by the force across it (friction + ``cross_coupling`` × mesh force);
    the sensor reads ``cos β · line + sin β · cross`` after a pure delay."""

    line_modes: tuple[Mode, ...] = field(default_factory=_default_line_modes)
    cross_modes: tuple[Mode, ...] = field(default_factory=_default_cross_modes)
    cross_coupling: float = 0.3
    sensor_angle_deg: float = 0.0
    """β: 0 = along the line of action, 90 = across it."""
    delay_s: float = 1.5e-4
    """Pure delay (wave travel + the ADC's linear-phase filter)."""


@dataclass(frozen=True)
class Operating:
    speed_rpm: float = 1000.0
    """Pinion mean speed."""
    load_torque_nm: float = 200.0
    """Torque on the gear shaft."""
    speed_drift_fraction: float = 0.0
    """Largest relative deviation of the speed from ``speed_rpm`` within the record (slow,
    smooth; its shape is drawn from the seed: a ramp plus a slow swell)."""
    friction_coefficient: float = 0.0
    """Coulomb sliding friction (sign reverses at the pitch point)."""
    speed_fluctuation_fraction: float = 0.0
    """Speed fluctuation locked to the pinion angle: ``Ω(1 + f cos(nθ + φ))`` (a cardan joint,
    motor cogging); synchronous, so it survives the angle-domain average."""
    speed_fluctuation_order: int = 1
    speed_fluctuation_phase_deg: float = 0.0
    load_fluctuation_fraction: float = 0.0
    """Relative amplitude of a load fluctuation locked to the gear shaft (a coupling, a cam)."""
    load_fluctuation_order: int = 1
    """Cycles per gear revolution."""
    load_fluctuation_phase_deg: float = 0.0
    """Phase against the gear angle (0 when gear tooth 1 is on the pitch point)."""
    bearing_impact_order: float = 0.0
    """Non-synchronous impacts (a rolling-bearing defect) per pinion revolution, e.g. 3.58;
    0: none. Each impact is a unit force impulse through the same path as the mesh force."""
    bearing_impact_to_signal: float = 0.0
    """RMS of the impacts' response relative to the gear signal's RMS."""
    bearing_slip: float = 0.01
    """Random relative jitter of each impact interval (rolling elements slip)."""


@dataclass(frozen=True)
class Tachometer:
    present: bool = True
    name: str = "tach"
    tooth1_pitch_angle_deg: float = 123.0
    """Pinion angle after the tach reference (rising) edge at which pinion tooth 1 is on the
    pitch point; tooth k follows (k−1)·360/Z1 later (gearwatch's manifest meaning)."""
    high_v: float = 5.0
    duty_fraction: float = 0.2
    rise_time_s: float = 2.0e-5
    noise_v: float = 0.01


@dataclass(frozen=True)
class Artefacts:
    glitches: int = 0
    """Single huge samples at random places, of random sign."""
    glitch_value: float | None = None
    """Absolute glitch magnitude (e.g. 3e38, a corrupted float); None: ``glitch_peak_ratio`` ×
    the clean record's peak (an ADC spike)."""
    glitch_peak_ratio: float = 20.0
    dropouts: int = 0
    """Short runs of zeros (a connector, a DAQ buffer underrun)."""
    dropout_s: float = 0.02
    clip_fraction_of_peak: float | None = None
    """Clip the accelerometer at this fraction of its peak (None: no clipping)."""
    hum_hz: float = 50.0
    """Mains hum (non-synchronous): fundamental and its 2nd and 3rd harmonics (½, ¼ amplitude)."""
    hum_to_signal: float = 0.0
    """Hum RMS relative to the clean signal's RMS (0: none)."""


@dataclass(frozen=True)
class Acquisition:
    sample_rate_hz: float = 20000.0
    seconds: float = 12.0
    oversampling: int = 4
    """Internal rate = oversampling × sample rate (mesh events are evaluated there)."""
    noise_to_signal: float = 0.3
    """White sensor noise RMS relative to the clean accelerometer signal's RMS."""
    noise_rms_m_s2: float | None = None
    """Absolute noise RMS instead of the ratio (e.g. a reference and a faulty record with the
    same noise); None: use ``noise_to_signal``."""
    gain: float = 1.0
    """Sensor/amplifier gain (gain steps between days)."""
    accelerometer_name: str = "acc"
    anti_alias_pass_fraction: float = 0.4
    """The anti-alias roll-off starts at this fraction of the output rate and is complete at
    0.5 (raised cosine, linear phase)."""
    padding_s: float = 0.15
    """Simulated before and after the record and discarded (transients of the FFT solve)."""


@dataclass(frozen=True)
class IndependentModel:
    geometry: PairGeometry = field(default_factory=PairGeometry)
    stiffness: PairStiffness = field(default_factory=PairStiffness)
    errors: ToothErrors = field(default_factory=ToothErrors)
    spalls: tuple[Spall, ...] = ()
    cracks: tuple[Crack, ...] = ()
    path: TransferPath = field(default_factory=TransferPath)
    operating: Operating = field(default_factory=Operating)
    tachometer: Tachometer = field(default_factory=Tachometer)
    acquisition: Acquisition = field(default_factory=Acquisition)
    artefacts: Artefacts = field(default_factory=Artefacts)
    dynamics: Literal["linear", "nonlinear"] = "linear"
    """``linear``: LTI about the mean loaded stiffness, excited by the loaded static TE
    (frequency domain, default); ``nonlinear``: the same DOF time-stepped with the per-sample
    springs (parametric excitation, dynamic loss of contact; numba)."""

    def replace(self, **changes: Any) -> IndependentModel:
        return dataclasses.replace(self, **changes)


def _fail(where: str, message: str) -> None:
    raise IndependentModelError(f"{where}: {message}")


def _finite(where: str, value: float) -> None:
    if not math.isfinite(value):
        _fail(where, f"must be finite, got {value!r}")


def validate_model(model: IndependentModel) -> None:
    """Raise :class:`IndependentModelError` naming the first field out of range."""
    # Long function: a flat list of range checks, one per field, each naming its field.
    if model.dynamics not in ("linear", "nonlinear"):
        _fail("dynamics", f"must be linear or nonlinear, got {model.dynamics!r}")
    g = model.geometry
    if not 8 <= g.pinion_teeth <= 200:
        _fail("geometry.pinion_teeth", f"must be in 8..200, got {g.pinion_teeth}")
    if not 8 <= g.gear_teeth <= 400:
        _fail("geometry.gear_teeth", f"must be in 8..400, got {g.gear_teeth}")
    for name in ("module_mm", "face_width_mm", "rim_density_kg_m3", "inertia_factor"):
        value = getattr(g, name)
        _finite(f"geometry.{name}", value)
        if value <= 0:
            _fail(f"geometry.{name}", f"must be positive, got {value}")
    if not 10.0 <= g.pressure_angle_deg <= 30.0:
        _fail("geometry.pressure_angle_deg", f"must be in 10..30, got {g.pressure_angle_deg}")
    if g.contact_ratio is not None and not 1.05 <= g.contact_ratio <= 2.8:
        _fail("geometry.contact_ratio", f"must be in 1.05..2.8, got {g.contact_ratio}")
    if not 0.1 <= g.approach_fraction <= 0.9:
        _fail("geometry.approach_fraction", f"must be in 0.1..0.9, got {g.approach_fraction}")
    s = model.stiffness
    if s.peak_n_per_m_per_mm <= 0:
        _fail("stiffness.peak_n_per_m_per_mm", "must be positive")
    if not 0 <= s.curvature < 0.9 or abs(s.skew) > 0.3:
        _fail("stiffness", "curvature must be in [0, 0.9) and |skew| ≤ 0.3")
    if not 0 <= s.engagement_fraction <= 0.3:
        _fail("stiffness.engagement_fraction", "must be in 0..0.3")
    if not 0 <= s.shaft_stiffness_n_per_m < 1e12:
        _fail("stiffness.shaft_stiffness_n_per_m", "must be in [0, 1e12)")
    if not 0.05 <= s.contact_compliance_share <= 0.95:
        _fail("stiffness.contact_compliance_share", "must be in 0.05..0.95")
    if not 0 < s.damping_ratio < 0.5:
        _fail("stiffness.damping_ratio", f"must be in (0, 0.5), got {s.damping_ratio}")
    e = model.errors
    for name, teeth in (
        ("pinion_index_um", g.pinion_teeth),
        ("gear_index_um", g.gear_teeth),
        ("pinion_profile_slope_um", g.pinion_teeth),
        ("gear_profile_slope_um", g.gear_teeth),
    ):
        values = getattr(e, name)
        if values and len(values) != teeth:
            _fail(f"errors.{name}", f"needs {teeth} values (one per tooth), got {len(values)}")
        for v in values:
            _finite(f"errors.{name}", v)
    if not 0 < e.tip_relief_length_fraction <= 0.5:
        _fail("errors.tip_relief_length_fraction", "must be in (0, 0.5]")
    spalled: set[tuple[str, int]] = set()
    for i, sp in enumerate(model.spalls):
        where = f"spalls[{i}]"
        teeth = g.pinion_teeth if sp.wheel == "pinion" else g.gear_teeth
        if sp.wheel not in ("pinion", "gear"):
            _fail(f"{where}.wheel", f"must be pinion or gear, got {sp.wheel!r}")
        if not 1 <= sp.tooth <= teeth:
            _fail(f"{where}.tooth", f"must be in 1..{teeth}, got {sp.tooth}")
        if (sp.wheel, sp.tooth) in spalled:
            _fail(where, "one spall per tooth")
        spalled.add((sp.wheel, sp.tooth))
        if not 0 <= sp.depth_um <= 500:
            _fail(f"{where}.depth_um", f"must be in 0..500, got {sp.depth_um}")
        if not 0.01 <= sp.extent_fraction <= 1.0:
            _fail(f"{where}.extent_fraction", f"must be in 0.01..1, got {sp.extent_fraction}")
        if not 0 <= sp.centre_fraction <= 1:
            _fail(f"{where}.centre_fraction", "must be in 0..1")
        if not 0 < sp.face_fraction <= 1:
            _fail(f"{where}.face_fraction", "must be in (0, 1]")
        if not 0 <= sp.wall_fraction <= 0.5:
            _fail(f"{where}.wall_fraction", "must be in 0..0.5")
    for i, cr in enumerate(model.cracks):
        teeth = g.pinion_teeth if cr.wheel == "pinion" else g.gear_teeth
        if not 1 <= cr.tooth <= teeth:
            _fail(f"cracks[{i}].tooth", f"must be in 1..{teeth}, got {cr.tooth}")
        if not 0 <= cr.stiffness_loss_fraction < 1:
            _fail(f"cracks[{i}].stiffness_loss_fraction", "must be in [0, 1)")
    for name, modes in (("line_modes", model.path.line_modes), ("cross_modes", model.path.cross_modes)):
        for i, m in enumerate(modes):
            if not 0 < m.frequency_hz or not 0 < m.damping_ratio < 1:
                _fail(f"path.{name}[{i}]", "frequency must be positive and damping in (0, 1)")
    if model.path.delay_s < 0:
        _fail("path.delay_s", "must be ≥ 0")
    o = model.operating
    if not o.speed_rpm > 0:
        _fail("operating.speed_rpm", "must be positive")
    if not o.load_torque_nm > 0:
        _fail("operating.load_torque_nm", "must be positive (driving flanks only)")
    if not 0 <= o.speed_drift_fraction <= 0.5:
        _fail("operating.speed_drift_fraction", "must be in 0..0.5")
    if not 0 <= o.friction_coefficient <= 0.3:
        _fail("operating.friction_coefficient", "must be in 0..0.3")
    if o.bearing_impact_order < 0 or o.bearing_impact_to_signal < 0 or not 0 <= o.bearing_slip < 0.5:
        _fail("operating.bearing_impact", "order and ratio must be ≥ 0, slip in [0, 0.5)")
    if not 0 <= o.speed_fluctuation_fraction <= 0.05 or o.speed_fluctuation_order < 1:
        _fail("operating.speed_fluctuation", "fraction must be in [0, 0.05] and order ≥ 1")
    if not 0 <= o.load_fluctuation_fraction < 0.9 or o.load_fluctuation_order < 1:
        _fail("operating.load_fluctuation", "fraction must be in [0, 0.9) and order ≥ 1")
    t = model.tachometer
    if not 0 <= t.tooth1_pitch_angle_deg < 360:
        _fail("tachometer.tooth1_pitch_angle_deg", "must be in [0, 360)")
    if not 0.02 <= t.duty_fraction <= 0.45:
        _fail("tachometer.duty_fraction", "must be in 0.02..0.45")
    a = model.acquisition
    if not a.sample_rate_hz > 0 or not a.seconds > 0:
        _fail("acquisition", "sample rate and seconds must be positive")
    if not 1 <= a.oversampling <= 64:
        _fail("acquisition.oversampling", "must be in 1..64")
    if a.noise_rms_m_s2 is not None and not a.noise_rms_m_s2 >= 0:
        _fail("acquisition.noise_rms_m_s2", "must be ≥ 0")
    if a.noise_to_signal < 0 or not math.isfinite(a.gain) or a.gain <= 0:
        _fail("acquisition", "noise_to_signal must be ≥ 0 and gain positive")
    if not 0.2 <= a.anti_alias_pass_fraction < 0.5:
        _fail("acquisition.anti_alias_pass_fraction", "must be in [0.2, 0.5)")
    if a.accelerometer_name == t.name:
        _fail("acquisition.accelerometer_name", "must differ from the tachometer's name")
    r = model.artefacts
    if r.glitch_value is not None and not (math.isfinite(r.glitch_value) and r.glitch_value > 0):
        _fail("artefacts.glitch_value", "must be positive and finite")
    if not r.glitch_peak_ratio > 0:
        _fail("artefacts.glitch_peak_ratio", "must be positive")
    if r.glitches < 0 or r.dropouts < 0 or r.dropout_s <= 0:
        _fail("artefacts", "counts must be ≥ 0 and dropout_s positive")
    if r.hum_to_signal < 0 or r.hum_hz <= 0:
        _fail("artefacts.hum", "hum_to_signal must be ≥ 0 and hum_hz positive")
    if r.clip_fraction_of_peak is not None and not 0 < r.clip_fraction_of_peak <= 1:
        _fail("artefacts.clip_fraction_of_peak", "must be in (0, 1]")


def model_to_dict(model: IndependentModel) -> dict[str, Any]:
    """JSON-compatible dict of every parameter (tuples become lists)."""
    return dataclasses.asdict(model)


def _build(cls: Any, data: Any) -> Any:
    label = str(getattr(cls, "__name__", "table"))
    if not isinstance(data, dict):
        raise IndependentModelError(f"{label}: expected a table, got {type(data).__name__}")
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = set(data) - names
    if unknown:
        raise IndependentModelError(f"{label}: unknown keys {sorted(unknown)}")
    kwargs: dict[str, Any] = {}
    hints: dict[tuple[Any, str], Any] = {
        (IndependentModel, "geometry"): PairGeometry,
        (IndependentModel, "stiffness"): PairStiffness,
        (IndependentModel, "errors"): ToothErrors,
        (IndependentModel, "path"): TransferPath,
        (IndependentModel, "operating"): Operating,
        (IndependentModel, "tachometer"): Tachometer,
        (IndependentModel, "acquisition"): Acquisition,
        (IndependentModel, "artefacts"): Artefacts,
    }
    items: dict[tuple[Any, str], Any] = {
        (IndependentModel, "spalls"): Spall,
        (IndependentModel, "cracks"): Crack,
        (TransferPath, "line_modes"): Mode,
        (TransferPath, "cross_modes"): Mode,
    }
    for key, value in data.items():
        if (cls, key) in hints:
            kwargs[key] = _build(hints[(cls, key)], value)
        elif (cls, key) in items:
            kwargs[key] = tuple(_build(items[(cls, key)], v) for v in value)
        elif isinstance(value, list):
            kwargs[key] = tuple(value)
        else:
            kwargs[key] = value
    return cls(**kwargs)


def model_from_dict(data: dict[str, Any]) -> IndependentModel:
    """Inverse of :func:`model_to_dict` (validated)."""
    model = _build(IndependentModel, data)
    assert isinstance(model, IndependentModel)
    validate_model(model)
    return model
