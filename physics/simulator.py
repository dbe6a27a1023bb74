"""Gear-pair dynamic simulator (Velex & Maatar 1996 as used by El Badaoui et al. 2001).

Two rigid cylinders with six degrees of freedom each (``dofs="full"``) or with rigid bearings
(``dofs="torsional"``, the reduced model), a motor inertia and a load inertia behind
torsionally flexible shafts, elemental mesh stiffnesses along the contact lines on the base
plane, normal deviations, contact loss. The mesh position follows the actual pinion
rotation (plus its eccentricity), not a nominal Ωt. The integrator runs ``oversampling``
times faster than the output rate; the accelerometer is the bearing force through
structural modes, low-passed (anti-alias) on the fine grid and only then decimated.
Optional (issue 6): Coulomb sliding friction at the contact, anisotropic wheel supports, a
mesh stiffness profile along the path of contact, sensors on the bearing force across the
line of action, a speed fluctuation locked to a pinion-shaft order, and a linearised mesh
without contact loss (``Mesh.contact_loss = False``).

Examples
--------
>>> from physics.config import GearPairModel, Acquisition
>>> from physics.simulator import simulate
>>> model = GearPairModel(acquisition=Acquisition(warmup_s=0.05))
>>> result = simulate(model, seconds=0.2, seed=1)
>>> sorted(result.channels)
['acc', 'tach']
>>> result.channels["acc"].shape
(4000,)
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
from scipy import signal

from physics import kernel
from physics.config import GearPairModel, StructuralMode, WheelBody, validate_model
from physics.geometry import SpurGeometry, spur_geometry


class SimulationError(ValueError):
    """The simulation left the model's domain (e.g. the drive could not hold the speed)."""


def model_geometry(model: GearPairModel) -> SpurGeometry:
    g = model.geometry
    return spur_geometry(
        module_mm=g.module_mm,
        pinion_teeth=g.pinion_teeth,
        gear_teeth=g.gear_teeth,
        pressure_angle_deg=g.pressure_angle_deg,
        face_width_mm=g.face_width_mm,
        addendum_coefficient=g.addendum_coefficient,
        dedendum_coefficient=g.dedendum_coefficient,
    )


def mean_mesh_stiffness_n_per_m(model: GearPairModel) -> float:
    """Time-averaged mesh stiffness of perfect teeth: k' · face width · contact ratio."""
    geo = model_geometry(model)
    return model.mesh.stiffness_per_length_n_per_m2 * geo.face_width_m * geo.contact_ratio


def mesh_mode_frequency_hz(model: GearPairModel, stiffness_n_per_m: float | None = None) -> float:
    """Closed-form natural frequency of the torsional mesh mode, f = √(k / m_eq) / 2π.

    ``m_eq = 1 / (rb1²/J1 + rb2²/J2)``: the two wheels against each other through the
    mesh, shafts and bearings neglected. ``stiffness_n_per_m`` defaults to the mean mesh
    stiffness.

    Examples
    --------
    >>> from physics.config import GearPairModel
    >>> round(mesh_mode_frequency_hz(GearPairModel()))
    2750
    """
    geo = model_geometry(model)
    k = mean_mesh_stiffness_n_per_m(model) if stiffness_n_per_m is None else stiffness_n_per_m
    inv_m = (
        geo.pinion_base_radius_m**2 / model.pinion.polar_inertia_kg_m2
        + geo.gear_base_radius_m**2 / model.gear.polar_inertia_kg_m2
    )
    return math.sqrt(k * inv_m) / (2 * math.pi)


def static_transmission_error_m(model: GearPairModel, pairs_in_contact: int) -> float:
    """Closed-form static transmission error of perfect teeth under the model's mean load.

    Measured as rb1·θ1 − rb2·θ2: the mesh deflection F / (k' · b · pairs), plus, for the
    full model, the bearing deflections along the line of action F/k_b1 + F/k_b2, with
    F = T_load / rb2.

    Examples
    --------
    >>> from physics.config import GearPairModel
    >>> round(static_transmission_error_m(GearPairModel(dofs="torsional"), 1) * 1e6, 3)
    7.239
    """
    geo = model_geometry(model)
    force = model.operating.load_torque_nm / geo.gear_base_radius_m
    te = force / (model.mesh.stiffness_per_length_n_per_m2 * geo.face_width_m * pairs_in_contact)
    if model.dofs == "full":
        for body in (model.pinion, model.gear):
            if body.bearing_radial_stiffness_ratio == 1.0:
                te += force / body.bearing_radial_stiffness_n_per_m
            else:
                # Anisotropic support: the line-of-action compliance of the 2×2 block.
                stiffness, _ = bearing_radial_matrices(body)
                te += force * float(np.linalg.inv(stiffness)[0, 0])
    return te


def stiffness_profile_factor(model: GearPairModel, position_m: np.ndarray) -> np.ndarray:
    """Stiffness-per-length factor at positions on the line of action (from T1); mean 1.

    Examples
    --------
    >>> from physics.config import GearPairModel, Mesh
    >>> model = GearPairModel(mesh=Mesh(stiffness_profile="linear",
    ...                                 stiffness_profile_variation=0.2))
    >>> geo = model_geometry(model)
    >>> [round(float(f), 3) for f in stiffness_profile_factor(
    ...     model, np.array([geo.path_start_m, geo.path_end_m]))]
    [0.8, 1.2]
    """
    geo = model_geometry(model)
    a = model.mesh.stiffness_profile_variation
    start, end = geo.path_start_m, geo.path_end_m
    xi = np.clip((2 * np.asarray(position_m, dtype=float) - start - end) / (end - start), -1, 1)
    if model.mesh.stiffness_profile == "linear":
        return 1.0 + a * xi
    if model.mesh.stiffness_profile == "parabolic":
        return 1.0 - a * (xi**2 - 1.0 / 3.0)
    return np.ones_like(xi)


def quasi_static_input_torque_nm(model: GearPairModel, n_positions: int = 256) -> np.ndarray:
    """Pinion torque that balances the load over one mesh cycle, with sliding friction.

    Perfect teeth, rigid bodies, slow rotation: the pairs in contact share the load in
    proportion to their stiffness (same approach δ); the gear's balance
    Σ N_q (rb2 + μ s_q (T1T2 − u_q)) = T gives the loads, and the pinion torque is
    Σ N_q (rb1 + μ s_q u_q), s_q = sign(u_q − u_pitch). Positions of the first pair are
    ``n_positions`` points across one base pitch from the start of contact. Without
    friction it is T·rb1/rb2 everywhere.

    Examples
    --------
    >>> from physics.config import GearPairModel, Mesh
    >>> torque = quasi_static_input_torque_nm(GearPairModel(mesh=Mesh(friction_coefficient=0.1)))
    >>> round(float(torque.mean() / (200 * 20 / 21)), 3)  # > 1: the friction loss
    1.02
    """
    geo = model_geometry(model)
    mu = model.mesh.friction_coefficient
    rb1, rb2, pb = geo.pinion_base_radius_m, geo.gear_base_radius_m, geo.base_pitch_m
    t1t2 = geo.line_of_action_length_m
    first = geo.path_start_m + pb * (np.arange(n_positions) + 0.5) / n_positions
    u = first[:, None] + pb * np.arange(math.ceil(geo.contact_ratio) + 1)[None, :]
    share = np.where(u <= geo.path_end_m, stiffness_profile_factor(model, u), 0.0)
    slide = np.sign(u - geo.pitch_point_m)
    delta = model.operating.load_torque_nm / np.sum(share * (rb2 + mu * slide * (t1t2 - u)), axis=1)
    loads = share * delta[:, None]
    return np.asarray(np.sum(loads * (rb1 + mu * slide * u), axis=1))


def bearing_radial_matrices(body: WheelBody) -> tuple[np.ndarray, np.ndarray]:
    """Radial stiffness and damping of a wheel's support in (line of action, off-line) axes.

    Principal stiffnesses k and ratio·k along axes turned by ``bearing_principal_axis_deg``
    from the line of action; each principal direction has the damping 2ζ√(k m).

    Examples
    --------
    >>> from physics.config import WheelBody
    >>> k, c = bearing_radial_matrices(WheelBody(bearing_radial_stiffness_ratio=0.5,
    ...                                          bearing_principal_axis_deg=90.0))
    >>> [round(float(v) / 1e9, 3) for v in np.diag(k)]
    [0.5, 1.0]
    """
    k1 = body.bearing_radial_stiffness_n_per_m
    k2 = k1 * body.bearing_radial_stiffness_ratio
    angle = math.radians(body.bearing_principal_axis_deg)
    axes = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
    # Exact zeros off the diagonal at 0° and 90° (cos 90° is not exactly 0 in floating point).
    axes[np.abs(axes) < 1e-15] = 0.0
    zeta, m = body.bearing_damping_ratio, body.mass_kg
    stiffness = axes @ np.diag([k1, k2]) @ axes.T
    damping = axes @ np.diag([2 * zeta * math.sqrt(k1 * m), 2 * zeta * math.sqrt(k2 * m)]) @ axes.T
    return stiffness, damping


def off_line_dofs_needed(model: GearPairModel) -> bool:
    """Whether y (perpendicular to the line of action) and rx can leave rest.

    A frictionless spur mesh loads only along the line of action; y is excited by sliding
    friction or by a support whose principal axes are oblique to the line of action
    (stiffness coupling x–y); rx only by friction (its moment about the line of action).
    """
    if model.mesh.friction_coefficient > 0:
        return True
    for body in (model.pinion, model.gear):
        if body.bearing_radial_stiffness_ratio != 1.0:
            k, c = bearing_radial_matrices(body)
            if k[0, 1] != 0.0 or c[0, 1] != 0.0:
                return True
    return False


@dataclass
class SimulationResult:
    """One simulated record. Waveforms are at ``sample_rate_hz``, starting after the warm-up."""

    sample_rate_hz: float
    channels: dict[str, np.ndarray]
    """Sensor channels (m/s²) in the model's order, then the tachometer (V)."""
    tach_pulse_times_s: np.ndarray
    """Exact rising-edge times of the tachometer (reference mark crossings)."""
    tooth1_pitch_angle_deg: float
    """Pinion angle after the record's first tach edge at which tooth 1 is on the pitch point.

    The record starts so that its first tach edge is the pinion's reference (for a gear-shaft
    tach, the gear's mark is placed so that one of its edges falls there too); this is the
    model's ``tooth1_pitch_angle_deg`` to within the warm-up's speed error (≪ 0.1°)."""
    pinion_angle_rad: np.ndarray
    gear_angle_rad: np.ndarray
    transmission_error_m: np.ndarray
    """rb1·θ1 − rb2·θ2 (includes bearing deflections along the line of action)."""
    mesh_force_n: np.ndarray
    contact_length_m: np.ndarray
    bearing_force_n: dict[str, np.ndarray] = field(default_factory=dict)
    """Force on the housing along the line of action, ``"pinion"`` and ``"gear"``."""
    bearing_force_off_line_n: dict[str, np.ndarray] = field(default_factory=dict)
    """Force on the housing perpendicular to the line of action (+y: from the line of action
    towards the pinion centre), ``"pinion"`` and ``"gear"``. Zero for a frictionless mesh on
    supports that do not couple the two radial directions."""
    friction_force_n: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """Total sliding-friction force on the gear along +y (on the pinion: its opposite)."""
    integration_step_s: float = 0.0
    max_contact_iterations: int = 0
    unsettled_contact_steps: int = 0
    """Steps whose contact set still changed after the iteration limit (should be ~0)."""

    @property
    def time_s(self) -> np.ndarray:
        n = self.pinion_angle_rad.shape[-1]
        return np.arange(n) / self.sample_rate_hz


@dataclass
class _Assembly:
    mass: np.ndarray
    stiffness: np.ndarray
    damping: np.ndarray
    v0: np.ndarray
    v1: np.ndarray
    dof_map: np.ndarray
    control_gain: float
    x_init: np.ndarray
    v_init: np.ndarray


def _assemble(
    model: GearPairModel, geo: SpurGeometry, speed_rad_s: float, keep_unexcited: bool = False
) -> _Assembly:
    """Mass, stiffness, damping matrices, structure vectors and the static initial state.

    DOFs: motor, θ1, θ2, load, then for the full model per wheel x (along the line of
    action), y, z, rx, ry. For a spur pair without friction the mesh force lies along x
    and its moment about the centre is about z (torque) and y (tilt, from the axial
    position of the load): y, z and rx are never excited and stay exactly at rest, so
    they are dropped from the integration unless ``keep_unexcited`` (a test checks that
    keeping them changes nothing). Sliding friction (force along y, moment about x) or an
    oblique anisotropic support excites y and rx: they are kept then
    (:func:`off_line_dofs_needed`); z stays unexcited (a spur mesh has no axial force).
    """
    pin, gear, drive = model.pinion, model.gear, model.drive
    rb1, rb2 = geo.pinion_base_radius_m, geo.gear_base_radius_m
    full = model.dofs == "full"
    if keep_unexcited:
        wheel_dofs: tuple[str, ...] = ("x", "y", "z", "rx", "ry")
    elif off_line_dofs_needed(model):
        wheel_dofs = ("x", "y", "rx", "ry")
    else:
        wheel_dofs = ("x", "ry")
    n = 4 + (2 * len(wheel_dofs) if full else 0)
    mass = np.zeros(n)
    mass[:4] = [
        drive.motor_inertia_kg_m2,
        pin.polar_inertia_kg_m2,
        gear.polar_inertia_kg_m2,
        drive.load_inertia_kg_m2,
    ]
    stiffness = np.zeros((n, n))
    damping = np.zeros((n, n))

    def couple(i: int, j: int, k: float, c: float) -> None:
        for mat, value in ((stiffness, k), (damping, c)):
            mat[i, i] += value
            mat[j, j] += value
            mat[i, j] -= value
            mat[j, i] -= value

    for (i, j), k_shaft in (
        ((0, 1), drive.input_shaft_stiffness_nm_per_rad),
        ((2, 3), drive.output_shaft_stiffness_nm_per_rad),
    ):
        j_eq = mass[i] * mass[j] / (mass[i] + mass[j])
        couple(i, j, k_shaft, 2 * drive.shaft_damping_ratio * math.sqrt(k_shaft * j_eq))
    ratio = rb1 / rb2
    j_total = mass[0] + mass[1] + (mass[2] + mass[3]) * ratio**2
    control_gain = j_total / drive.speed_control_time_constant_s
    damping[0, 0] += control_gain

    v0 = np.zeros(n)
    v1 = np.zeros(n)
    v0[1], v0[2] = rb1, -rb2
    dof_map = np.full(kernel.N_DOF_MAP, -1, dtype=np.int64)
    dof_map[kernel.D_MOTOR] = 0
    dof_map[kernel.D_PINION_ROT] = 1
    dof_map[kernel.D_GEAR_ROT] = 2
    dof_map[kernel.D_LOAD] = 3
    force = model.operating.load_torque_nm / rb2
    x_init = np.zeros(n)
    if full:
        for w, (body, sign) in enumerate(((pin, 1.0), (gear, -1.0))):
            base = 4 + w * len(wheel_dofs)
            for offset, name in enumerate(wheel_dofs):
                i = base + offset
                if name in ("x", "y"):
                    m, k = body.mass_kg, body.bearing_radial_stiffness_n_per_m
                elif name == "z":
                    m, k = body.mass_kg, body.bearing_axial_stiffness_n_per_m
                else:
                    m, k = body.tilt_inertia_kg_m2, body.bearing_tilt_stiffness_nm_per_rad
                mass[i] = m
                stiffness[i, i] = k
                damping[i, i] = 2 * body.bearing_damping_ratio * math.sqrt(k * m)
                if name == "x":
                    v0[i] = sign  # translation along the line of action
                    # Static bearing deflection: each wheel pushed away from the other.
                    x_init[i] = -sign * force / k
                    dof_map[kernel.D_PINION_X if w == 0 else kernel.D_GEAR_X] = i
                elif name == "y":
                    dof_map[kernel.D_PINION_Y if w == 0 else kernel.D_GEAR_Y] = i
                elif name == "rx":
                    dof_map[kernel.D_PINION_RX if w == 0 else kernel.D_GEAR_RX] = i
                elif name == "ry":
                    v1[i] = sign  # tilt: a point at axial z moves z·ry along the line of action
            if body.bearing_radial_stiffness_ratio != 1.0:
                # Anisotropic support: the full radial block in (x, y), static deflection
                # from its compliance (y is at rest only if the block is diagonal).
                k_block, c_block = bearing_radial_matrices(body)
                ix = base + wheel_dofs.index("x")
                idx = [ix, base + wheel_dofs.index("y")] if "y" in wheel_dofs else [ix]
                n_r = len(idx)
                stiffness[np.ix_(idx, idx)] = k_block[:n_r, :n_r]
                damping[np.ix_(idx, idx)] = c_block[:n_r, :n_r]
                x_init[idx] = -sign * force * np.linalg.inv(k_block)[:n_r, 0]
    mesh_deflection = force / mean_mesh_stiffness_n_per_m(model)
    translation = float(v0[4:] @ x_init[4:]) if full else 0.0
    x_init[2] = -(mesh_deflection - translation) / rb2
    x_init[0] = force * rb1 / drive.input_shaft_stiffness_nm_per_rad
    x_init[3] = x_init[2] - model.operating.load_torque_nm / drive.output_shaft_stiffness_nm_per_rad
    v_init = np.zeros(n)
    v_init[:2] = speed_rad_s
    v_init[2:4] = speed_rad_s * ratio
    return _Assembly(mass, stiffness, damping, v0, v1, dof_map, control_gain, x_init, v_init)


@functools.lru_cache(maxsize=256)
def _mode_filter(mode: StructuralMode, fs_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Digital a/F = g·s²/(s² + 2ζωs + ω²), exact for a force linear between samples (FOH).

    Cached (read-only arrays): a reconciliation simulates the same modes hundreds of times and
    the matrix exponential of the discretisation cost a fifth of its time."""
    omega = 2 * math.pi * mode.frequency_hz
    b = [mode.gain_m_s2_per_n, 0.0, 0.0]
    a = [1.0, 2 * mode.damping_ratio * omega, omega**2]
    bz, az, _ = signal.cont2discrete((b, a), 1.0 / fs_hz, method="foh")
    out = np.asarray(bz, dtype=float).ravel(), np.asarray(az, dtype=float)
    for array in out:
        array.flags.writeable = False
    return out


MAX_WARMUP_STRETCH_S = 1.0
"""Longest extension of the warm-up used to start a record on the tach reference."""


def _start_margin(model: GearPairModel) -> float:
    """Pinion angle (rad) by which a record starts before its reference tach edge."""
    tach, geo = model.tachometer, model.geometry
    tach_per_pinion = 1.0 if tach.shaft == "pinion" else geo.pinion_teeth / geo.gear_teeth
    edge_spacing = 2 * math.pi / (tach.pulses_per_rev * tach_per_pinion)
    return 0.1 * min(edge_spacing, 2 * math.pi)


def warmup_revolutions(model: GearPairModel, speed_rpm: float | None = None) -> int | None:
    """Whole pinion revolutions from the mesh origin (pinion tooth 1 and gear tooth 1 together
    at the pitch point) to the record's first tach edge, or ``None`` for a shaft so slow that
    the warm-up is not stretched to a mark.

    Just after that edge pinion tooth 1 meets gear tooth ``(m·Z1 mod Z2) + 1``: the gear teeth
    of a configuration are numbered from the mesh origin, so which of them is in mesh at a
    record's first edge depends on the warm-up and the speed.

    >>> warmup_revolutions(GearPairModel())  # 1000 rpm, 0.2 s of warm-up: 3.3 revolutions
    4
    """
    rpm = model.operating.speed_rpm if speed_rpm is None else speed_rpm
    return _warmup_revolutions_at(model, rpm * 2 * math.pi / 60)


def _warmup_revolutions_at(model: GearPairModel, speed_rad_s: float) -> int | None:
    acq = model.acquisition
    margin = _start_margin(model)
    m = math.ceil((speed_rad_s * acq.warmup_s + margin) / (2 * math.pi))
    if (2 * math.pi * m - margin) / speed_rad_s > acq.warmup_s + MAX_WARMUP_STRETCH_S:
        return None
    return m


def _record_start(model: GearPairModel, speed_rad_s: float) -> tuple[int, float]:
    """Warm-up steps and tach-mark offset so the record's first tach edge is the reference.

    The pipeline counts revolutions from the first tach edge of a record and measures the
    pinion angle from it. The warm-up is stretched (by less than a revolution) so that the
    record starts just before the pinion passes its mark (angle 2πm, m =
    :func:`warmup_revolutions`); a gear-shaft mark is placed where the gear is at that instant.
    Returns (warm-up steps, mark offset in rad of the tach shaft).
    """
    acq, tach, geo = model.acquisition, model.tachometer, model.geometry
    tach_per_pinion = 1.0 if tach.shaft == "pinion" else geo.pinion_teeth / geo.gear_teeth
    m = _warmup_revolutions_at(model, speed_rad_s)
    if m is None:
        # Very slow shaft: keep the requested warm-up; the record's tooth-1 angle is then
        # reported as measured (SimulationResult.tooth1_pitch_angle_deg).
        return max(1, round(acq.warmup_s * acq.sample_rate_hz)) * acq.oversampling, 0.0
    start_angle = 2 * math.pi * m - _start_margin(model)
    warm_samples = max(1, math.floor(start_angle / speed_rad_s * acq.sample_rate_hz))
    offset = math.fmod(2 * math.pi * m * tach_per_pinion, 2 * math.pi / tach.pulses_per_rev)
    return warm_samples * acq.oversampling, offset


@functools.lru_cache(maxsize=32)
def _anti_alias_sos(order: int, cutoff_hz: float, fs_hz: float) -> np.ndarray:
    """Analog Butterworth low-pass discretised exactly for a force linear between samples.

    Discretising the analog filter (rather than designing a digital one at the integration
    rate) keeps the same filter whatever the oversampling, so step-halving checks measure
    the mechanics and not a change of filter.
    """
    z, p, k = signal.butter(order, 2 * math.pi * cutoff_hz, analog=True, output="zpk")
    a, b, c, d = signal.zpk2ss(z, p, k)
    ad, bd, cd, dd, _ = signal.cont2discrete((a, b, c, d), 1.0 / fs_hz, method="foh")
    zd, pd, kd = signal.ss2zpk(ad, bd, cd, dd)
    sos = np.asarray(signal.zpk2sos(zd, pd, kd), dtype=float)
    sos.flags.writeable = False  # cached
    return sos


def _tach_waveform(
    edges_s: np.ndarray,
    sample_times_s: np.ndarray,
    high_v: float,
    duty_fraction: float,
    rise_s: float,
) -> np.ndarray:
    """TTL pulses whose rising edges (mid-level) sit exactly at the reference crossings.

    Each edge is a linear ramp of ``rise_s`` centred on the crossing, so that a
    threshold at mid-level recovers the crossing time to well within a sample.
    """
    wave = np.zeros_like(sample_times_s)
    if edges_s.size == 0:
        return wave
    periods = np.diff(edges_s)
    last = periods[-1] if periods.size else np.inf
    falls = edges_s + duty_fraction * np.append(periods, last)

    def ramp(tau: np.ndarray) -> np.ndarray:
        return np.clip(0.5 + tau / rise_s, 0.0, 1.0)

    j = np.searchsorted(edges_s, sample_times_s + 0.5 * rise_s, side="right") - 1
    valid = j >= 0
    jj = np.clip(j, 0, None)
    wave[valid] = (
        high_v * (ramp(sample_times_s - edges_s[jj]) - ramp(sample_times_s - falls[jj]))[valid]
    )
    return wave


def simulate(
    model: GearPairModel,
    seconds: float = 12.0,
    seed: int | None = 0,
    *,
    keep_unexcited_dofs: bool = False,
) -> SimulationResult:
    """Simulate one record of ``seconds`` seconds (after the model's warm-up).

    Parameters
    ----------
    model
        Complete model (geometry, DOFs, deviations, sensors, tachometer, acquisition).
    seconds
        Recorded duration.
    seed
        Seed of the sensor noise; the same seed gives the same record.
    keep_unexcited_dofs
        Integrate all six DOF per wheel, including the three that a frictionless spur
        mesh never excites (slower, same result; for tests).

    Returns
    -------
    SimulationResult

    Examples
    --------
    >>> from physics.config import GearPairModel, Acquisition
    >>> r = simulate(GearPairModel(acquisition=Acquisition(warmup_s=0.05)), seconds=0.1)
    >>> round(float(r.tach_pulse_times_s[1] - r.tach_pulse_times_s[0]), 3)
    0.06
    """
    # Long function: flattens the model into the arrays the compiled integrator
    # (physics.kernel.integrate) takes, calls it and turns its output into channels; each stage
    # hands its arrays to the next, and a split would only pass them on.
    validate_model(model)
    if not seconds > 0:
        raise ValueError("seconds must be > 0")
    geo = model_geometry(model)
    acq, op, dev = model.acquisition, model.operating, model.deviations
    fs_out = acq.sample_rate_hz
    fs_int = fs_out * acq.oversampling
    h = 1.0 / fs_int
    speed = op.speed_rpm * 2 * math.pi / 60
    n_warm, tach_offset = _record_start(model, speed)
    n_rec = round(seconds * fs_out)
    if n_rec < 2:
        raise ValueError("seconds must cover at least two output samples")
    asm = _assemble(model, geo, speed, keep_unexcited_dofs)
    a_matrix = np.diag(asm.mass) * (4.0 / h**2) + asm.damping * (2.0 / h) + asm.stiffness
    a_inv = np.linalg.inv(a_matrix)

    rb1, rb2 = geo.pinion_base_radius_m, geo.gear_base_radius_m
    tooth1_rad = math.radians(model.tachometer.tooth1_pitch_angle_deg % 360.0)
    mesh_omega = 2 * math.pi * mesh_mode_frequency_hz(model)
    p = np.zeros(kernel.N_PARAMS)
    p[kernel.P_RB1], p[kernel.P_RB2], p[kernel.P_PB] = rb1, rb2, geo.base_pitch_m
    p[kernel.P_U0] = geo.pitch_point_m - rb1 * tooth1_rad
    p[kernel.P_START], p[kernel.P_END] = geo.path_start_m, geo.path_end_m
    p[kernel.P_KLEN] = model.mesh.stiffness_per_length_n_per_m2
    p[kernel.P_ETA] = 2 * model.mesh.damping_ratio / mesh_omega
    p[kernel.P_HALF_FACE] = geo.face_width_m / 2
    p[kernel.P_CA1] = dev.pinion_tip_relief_um * 1e-6
    p[kernel.P_LA1] = dev.pinion_tip_relief_length_mm * 1e-3
    p[kernel.P_CA2] = dev.gear_tip_relief_um * 1e-6
    p[kernel.P_LA2] = dev.gear_tip_relief_length_mm * 1e-3
    p[kernel.P_RELIEF_EXP] = dev.tip_relief_exponent
    p[kernel.P_ECC1] = dev.pinion_eccentricity_um * 1e-6
    p[kernel.P_PHI1] = math.radians(dev.pinion_eccentricity_phase_deg)
    p[kernel.P_ECC2] = dev.gear_eccentricity_um * 1e-6
    p[kernel.P_PHI2] = math.radians(dev.gear_eccentricity_phase_deg)
    if model.dofs == "full":
        ipx, igx = asm.dof_map[kernel.D_PINION_X], asm.dof_map[kernel.D_GEAR_X]
        p[kernel.P_KB1], p[kernel.P_CB1] = asm.stiffness[ipx, ipx], asm.damping[ipx, ipx]
        p[kernel.P_KB2], p[kernel.P_CB2] = asm.stiffness[igx, igx], asm.damping[igx, igx]
        ipy, igy = asm.dof_map[kernel.D_PINION_Y], asm.dof_map[kernel.D_GEAR_Y]
        if ipy >= 0:
            for ix, iy, (k_xy, c_xy, k_yy, c_yy) in (
                (ipx, ipy, (kernel.P_KXY1, kernel.P_CXY1, kernel.P_KYY1, kernel.P_CYY1)),
                (igx, igy, (kernel.P_KXY2, kernel.P_CXY2, kernel.P_KYY2, kernel.P_CYY2)),
            ):
                p[k_xy], p[c_xy] = asm.stiffness[ix, iy], asm.damping[ix, iy]
                p[k_yy], p[c_yy] = asm.stiffness[iy, iy], asm.damping[iy, iy]
    p[kernel.P_MU] = model.mesh.friction_coefficient
    p[kernel.P_PITCH_POINT] = geo.pitch_point_m
    p[kernel.P_T1T2] = geo.line_of_action_length_m
    p[kernel.P_KPROFILE] = {
        "constant": kernel.KPROFILE_CONSTANT,
        "linear": kernel.KPROFILE_LINEAR,
        "parabolic": kernel.KPROFILE_PARABOLIC,
    }[model.mesh.stiffness_profile]
    p[kernel.P_KPROFILE_A] = model.mesh.stiffness_profile_variation
    p[kernel.P_LOAD] = op.load_torque_nm
    p[kernel.P_LOAD_FLUCT] = op.load_fluctuation_fraction
    p[kernel.P_LOAD_ORDER] = float(op.load_fluctuation_order)
    p[kernel.P_LOAD_PHASE] = math.radians(op.load_fluctuation_phase_deg)

    z1, z2 = geo.pinion_teeth, geo.gear_teeth
    pitch1 = np.asarray(dev.pinion_pitch_errors_um or [0.0] * z1, dtype=float) * 1e-6
    pitch2 = np.asarray(dev.gear_pitch_errors_um or [0.0] * z2, dtype=float) * 1e-6
    kfac1, kfac2 = np.ones(z1), np.ones(z2)
    for crack in dev.cracks:
        target = kfac1 if crack.wheel == "pinion" else kfac2
        target[crack.tooth - 1] *= 1.0 - crack.stiffness_loss_fraction
    half = geo.face_width_m / 2
    spalls = dev.spalls
    defect_wheel = np.array([0 if s.wheel == "pinion" else 1 for s in spalls], dtype=np.int64)
    defect_tooth = np.array([s.tooth - 1 for s in spalls], dtype=np.int64)
    defect_u0 = np.array([geo.pitch_point_m + s.profile_start_mm * 1e-3 for s in spalls])
    defect_u1 = defect_u0 + np.array([s.profile_extent_mm * 1e-3 for s in spalls])
    defect_z0 = np.array([-half + s.face_start_mm * 1e-3 for s in spalls])
    defect_z1 = defect_z0 + np.array([s.face_width_mm * 1e-3 for s in spalls])
    defect_depth = np.array([s.depth_um * 1e-6 for s in spalls])

    p[kernel.P_SPEED] = speed
    p[kernel.P_DRIFT] = op.speed_drift_fraction
    p[kernel.P_FLUCT] = op.speed_fluctuation_fraction
    p[kernel.P_FLUCT_HZ] = op.speed_fluctuation_hz
    p[kernel.P_FLUCT_ORDER] = float(op.speed_fluctuation_order)
    p[kernel.P_FLUCT_PHASE] = math.radians(op.speed_fluctuation_phase_deg)
    p[kernel.P_LINEAR_MESH] = 0.0 if model.mesh.contact_loss else 1.0
    p[kernel.P_CONTROL_GAIN] = asm.control_gain
    p[kernel.P_TORQUE_FF] = op.load_torque_nm * rb1 / rb2
    if model.mesh.friction_coefficient > 0:
        # The drive holds the mean speed: its feed-forward covers the mean friction loss.
        p[kernel.P_TORQUE_FF] = quasi_static_input_torque_nm(model).mean()
    p[kernel.P_TACH_PPR] = float(model.tachometer.pulses_per_rev)
    p[kernel.P_TACH_OFFSET] = tach_offset

    sensors = model.sensors
    n_modes = max(1, max(len(s.modes) for s in sensors))
    mode_coef = np.zeros((len(sensors), n_modes, 5))
    for s_i, sensor in enumerate(sensors):
        for m_i, mode in enumerate(sensor.modes):
            bz, az = _mode_filter(mode, fs_int)
            mode_coef[s_i, m_i] = [
                bz[0] / az[0],
                bz[1] / az[0],
                bz[2] / az[0],
                az[1] / az[0],
                az[2] / az[0],
            ]
    sos = _anti_alias_sos(acq.anti_alias_order, acq.anti_alias_cutoff_fraction * fs_out, fs_int)
    anti_alias = np.ascontiguousarray(sos[:, [0, 1, 2, 4, 5]] / sos[:, [3]])
    # 0/1: pinion/gear along the line of action; 2/3: the same perpendicular to it.
    sensor_source = np.array(
        [
            (0 if s.source == "pinion" else 1) + (2 if s.direction == "off_line_of_action" else 0)
            for s in sensors
        ],
        dtype=np.int64,
    )

    duration = (n_warm + n_rec * acq.oversampling) * h
    max_speed = speed * (1 + abs(op.speed_drift_fraction) + abs(op.speed_fluctuation_fraction))
    max_edges = (
        int(1.5 * duration * max_speed / (2 * math.pi) * model.tachometer.pulses_per_rev) + 16
    )
    edges = np.zeros(max_edges)
    out = np.zeros((kernel.N_OUT, n_rec))
    sensor_out = np.zeros((len(sensors), n_rec))
    n_edges, iterations, unsettled = kernel.integrate(
        n_warm, n_rec, acq.oversampling, h, asm.mass, asm.stiffness, asm.damping, a_inv,
        asm.v0, asm.v1, asm.dof_map, p, z1, z2, pitch1, pitch2, kfac1, kfac2, defect_wheel,
        defect_tooth, defect_u0, defect_u1, defect_z0, defect_z1, defect_depth, sensor_source,
        mode_coef, anti_alias, model.tachometer.shaft == "gear", asm.x_init, asm.v_init, out,
        sensor_out, edges,
    )  # fmt: skip

    pinion_angle = out[kernel.OUT_PINION_ANGLE]
    # Vibration may make the angle wobble; turning back by a tooth pitch is a reversal.
    setback = np.maximum.accumulate(pinion_angle) - pinion_angle
    pitch_rad = 2 * math.pi / geo.pinion_teeth
    expected_travel = speed * (n_rec - 1) / fs_out
    travel = pinion_angle[-1] - pinion_angle[0]
    stalled = expected_travel > pitch_rad and travel < 0.2 * expected_travel
    if stalled or setback.max() > pitch_rad:
        raise SimulationError(
            "the pinion stopped or turned backwards: the speed loop cannot hold the speed "
            "against this load (raise operating.speed_rpm, lower the load fluctuation or "
            "shorten drive.speed_control_time_constant_s); the model has driving flanks only"
        )
    rng = np.random.default_rng(seed)
    channels: dict[str, np.ndarray] = {}
    for s_i, sensor in enumerate(sensors):
        channels[sensor.name] = sensor_out[s_i] + sensor.noise_rms_m_s2 * rng.standard_normal(n_rec)
    tach = model.tachometer
    record_times = np.arange(n_rec) / fs_out
    edges = edges[:n_edges]
    channels[tach.name] = _tach_waveform(
        edges, record_times, tach.high_v, tach.duty_fraction, rise_s=1.5 / fs_out
    )
    edges = edges[(edges >= 0) & (edges <= record_times[-1])]
    # Pinion angle at the record's first (reference) edge: 0 by construction, up to the
    # speed's departure from nominal during the warm-up; the exact value corrects tooth 1.
    tooth1 = model.tachometer.tooth1_pitch_angle_deg
    if edges.size:
        angle_at_edge = float(np.interp(edges[0], record_times, out[kernel.OUT_PINION_ANGLE]))
        tooth1 -= math.degrees(math.remainder(angle_at_edge, 2 * math.pi))
    return SimulationResult(
        sample_rate_hz=fs_out,
        channels=channels,
        tach_pulse_times_s=edges,
        tooth1_pitch_angle_deg=tooth1 % 360.0,
        pinion_angle_rad=out[kernel.OUT_PINION_ANGLE],
        gear_angle_rad=out[kernel.OUT_GEAR_ANGLE],
        transmission_error_m=out[kernel.OUT_TE],
        mesh_force_n=out[kernel.OUT_MESH_FORCE],
        contact_length_m=out[kernel.OUT_CONTACT_LENGTH],
        bearing_force_n={
            "pinion": out[kernel.OUT_BEARING_PINION],
            "gear": out[kernel.OUT_BEARING_GEAR],
        },
        bearing_force_off_line_n={
            "pinion": out[kernel.OUT_BEARING_PINION_OFF],
            "gear": out[kernel.OUT_BEARING_GEAR_OFF],
        },
        friction_force_n=out[kernel.OUT_FRICTION_FORCE],
        integration_step_s=h,
        max_contact_iterations=int(iterations),
        unsettled_contact_steps=int(unsettled),
    )
