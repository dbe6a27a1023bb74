"""Independent gear-pair truth generator: one line-of-action DOF, per-pair stiffness, modal path.

The model (equations in ``docs/independent-simulator.md``):

1. **Kinematics.** The pinion angle θ(t) integrates a speed with slow drift; the mesh
   position in base pitches is ``s = Z1 (θ − φ1)/2π + e1 cos(θ − ψ1)/pb`` (φ1 = tooth 1's pitch
   angle after the tach mark). Pair q (pinion tooth ``q mod Z1 + 1``, gear tooth
   ``q mod Z2 + 1``) sits ``x_q = s − q`` pitches after the pitch point and is in contact for
   ``x_start ≤ x_q ≤ x_end`` (``x_end − x_start`` = contact ratio); ξ_q ∈ [0, 1] is its
   position along its own path of contact.
2. **Loaded static transmission error.** Each pair is one, two or three parallel springs (the
   intact face and the pitted face fractions) of stiffness ``k(ξ)·share`` (a Weber/ISO-like
   parabola per pair, times a crack's loss) and clearance ``e_j(ξ)`` (index + profile slope +
   crowning + tip relief + spall depth). The static approach δ solves
   ``Σ k_j max(δ − e_j, 0) = F`` exactly (piecewise linear, vectorised over samples), so
   contact loss in a spall or a relief is exact under the actual load; the kinematic
   eccentricity term is subtracted: ``x_s = δ − e_ecc``.
3. **Dynamics**, linear time-invariant about the loaded mean stiffness k̄, excited by the
   loaded static TE (the classic STE-excitation model), solved in the frequency domain:
   ``m ẍ + c (ẋ − ẋ_s) + k̄ (x − x_s) + k_sh x = f_fr`` (k_sh: the shafts to the large motor
   and load inertias) and mesh force ``N = F + f_fr − m ẍ − k_sh x``.
4. **Path**: modal sums (complex residues), a pure delay, sensor direction mixing with a
   cross-line path driven by sliding friction; a linear-phase anti-alias roll-off and exact
   band-limited decimation; then gain, sensor noise at a ratio to the signal RMS, glitches,
   dropouts, clipping.

Everything is vectorised numpy; a record is deterministic from ``(model, seed)``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from physics.independent.model import (
    IndependentModel,
    IndependentModelError,
    Mode,
    model_to_dict,
    validate_model,
)

FloatArray = NDArray[np.float64]

KINEMATICS_BLOCK = 1 << 20
"""Internal samples per block of the kinematics (bounds memory for long records)."""
CHUNK_SAMPLES = 1 << 16
"""Internal samples per chunk of the static solve (bounds memory: ~9 springs × chunk)."""
_FAR = 1.0
"""Clearance (m) given to springs out of contact: never reached by any approach."""
_MIN_SHAPE = 0.05
"""Floor of the per-pair stiffness shape (the parabola must stay positive)."""


@dataclass(frozen=True)
class PairDerived:
    """Quantities derived from the geometry (SI units)."""

    pinion_base_radius_m: float
    gear_base_radius_m: float
    base_pitch_m: float
    pressure_angle_rad: float
    contact_ratio: float
    path_start_pitches: float
    """Start of contact relative to the pitch point, in base pitches (negative)."""
    path_end_pitches: float
    pitch_point_m: float
    """T1P: pitch point from the pinion's base-circle tangency point."""
    line_of_action_m: float
    """T1T2 = a sin α."""
    pinion_mass_kg: float
    """Equivalent mass on the line of action, J1/rb1²."""
    gear_mass_kg: float
    face_width_m: float

    @property
    def mesh_mass_kg(self) -> float:
        return self.pinion_mass_kg * self.gear_mass_kg / (self.pinion_mass_kg + self.gear_mass_kg)

    @property
    def pitch_fraction(self) -> float:
        """ξ of the pitch point on a pair's path of contact."""
        return -self.path_start_pitches / self.contact_ratio


def pair_derived(model: IndependentModel) -> PairDerived:
    """Base radii, contact path and equivalent masses of ``model``'s pair.

    Raises
    ------
    IndependentModelError
        The pair interferes (contact would start below the pinion's base circle).
    """
    g = model.geometry
    m = g.module_mm * 1e-3
    alpha = math.radians(g.pressure_angle_deg)
    z1, z2 = g.pinion_teeth, g.gear_teeth
    r1, r2 = m * z1 / 2, m * z2 / 2
    rb1, rb2 = r1 * math.cos(alpha), r2 * math.cos(alpha)
    pb = math.pi * m * math.cos(alpha)
    centre = r1 + r2
    t1p = rb1 * math.tan(alpha)
    if g.contact_ratio is None:
        ra1 = r1 + g.addendum_coefficient * m
        ra2 = r2 + g.addendum_coefficient * m
        t1e = math.sqrt(ra1**2 - rb1**2)
        t1a = centre * math.sin(alpha) - math.sqrt(ra2**2 - rb2**2)
        eps = (t1e - t1a) / pb
        start = (t1a - t1p) / pb
    else:
        eps = float(g.contact_ratio)
        start = -g.approach_fraction * eps
        t1a = t1p + start * pb
    if t1a <= 0:
        raise IndependentModelError(
            f"geometry: contact would start {t1a * 1e3:.2f} mm before the pinion's base circle "
            "(interference: fewer addendum, more pinion teeth or a smaller contact ratio)"
        )
    if not 1.0 < eps < 2.9:
        raise IndependentModelError(f"geometry: contact ratio {eps:.3f} outside (1, 2.9)")
    b = g.face_width_mm * 1e-3
    disc = math.pi * g.rim_density_kg_m3 * b / 2 * g.inertia_factor
    j1, j2 = disc * r1**4, disc * r2**4
    return PairDerived(
        pinion_base_radius_m=rb1,
        gear_base_radius_m=rb2,
        base_pitch_m=pb,
        pressure_angle_rad=alpha,
        contact_ratio=eps,
        path_start_pitches=start,
        path_end_pitches=start + eps,
        pitch_point_m=t1p,
        line_of_action_m=centre * math.sin(alpha),
        pinion_mass_kg=j1 / rb1**2,
        gear_mass_kg=j2 / rb2**2,
        face_width_m=b,
    )


@dataclass
class IndependentRecord:
    """One generated record: channels (name → samples), the rate, and the full truth."""

    channels: dict[str, FloatArray]
    sample_rate_hz: float
    truth: dict[str, Any]
    static_te_m: FloatArray = field(repr=False, default_factory=lambda: np.zeros(0))
    """Loaded static transmission error at the output rate (diagnostics)."""
    pinion_angle_rad: FloatArray = field(repr=False, default_factory=lambda: np.zeros(0))
    """Pinion angle after the tach mark at each output sample (may exceed 2π)."""

    def record_data(self) -> Any:
        """The record as gearwatch's :class:`gearwatch.floor.campaign.RecordData`."""
        from gearwatch.floor.campaign import RecordData

        return RecordData(
            channels=dict(self.channels),
            sample_rate_hz=self.sample_rate_hz,
            source=f"independent seed {self.truth['seed']}",
        )

    def campaign(self, campaign_id: str = "independent") -> Any:
        """A one-rig manifest (:class:`gearwatch.floor.campaign.Campaign`) describing this record."""
        return campaign_for(self.truth, campaign_id=campaign_id)


def campaign_for(
    truth: dict[str, Any], campaign_id: str = "independent", records: tuple[Any, ...] = ()
) -> Any:
    """gearwatch's manifest object for records generated with ``truth['model']``'s rig."""
    from gearwatch.floor.campaign import Campaign, ChannelConfig, RigConfig, TachometerConfig

    model = truth["model"]
    tach = model["tachometer"]
    channels = [ChannelConfig(model["acquisition"]["accelerometer_name"], "accelerometer", "m/s^2")]
    tachometer = None
    if tach["present"]:
        channels.append(ChannelConfig(tach["name"], "tachometer", "V"))
        tachometer = TachometerConfig(channel=tach["name"], kind="pulses", shaft="pinion",
                                      pulses_per_rev=1)
    return Campaign(
        id=campaign_id,
        description="independent line-of-action generator (physics.independent)",
        rig=RigConfig(
            id="independent-rig",
            pinion_teeth=model["geometry"]["pinion_teeth"],
            gear_teeth=model["geometry"]["gear_teeth"],
            tooth1_pitch_angle_deg=float(tach["tooth1_pitch_angle_deg"]),
            # Without a tachometer the operator still knows the rig's nominal speed.
            nominal_pinion_rpm=None if tach["present"] else float(model["operating"]["speed_rpm"]),
        ),
        sample_rate_hz=float(model["acquisition"]["sample_rate_hz"]),
        tachometer=tachometer,
        channels=tuple(channels),
        records=records,
    )


# --- per-pair stiffness and clearances ---------------------------------------------------------


def pair_stiffness_shape(
    xi: FloatArray, curvature: float, skew: float, engagement: float = 0.0
) -> FloatArray:
    """Relative single-pair stiffness along its path of contact (1 at the peak of the parabola).

    ``(1 − curvature·(2ξ−1)² + skew·(2ξ−1)) · T(ξ/eng) · T((1−ξ)/eng)``, the parabola floored at
    0.05, ``T(u) = sin²(π/2 · min(u, 1))`` the engagement taper; ξ = 0 start of contact (pinion
    root), 1 end (pinion tip).

    Examples
    --------
    >>> pair_stiffness_shape(np.array([0.0, 0.5, 1.0]), 0.4, 0.0)
    array([0.6, 1. , 0.6])
    >>> pair_stiffness_shape(np.array([0.0, 0.01, 0.5]), 0.4, 0.0, engagement=0.02).round(3)
    array([0.   , 0.308, 1.   ])
    """
    u = 2.0 * xi - 1.0
    shape = np.maximum(1.0 - curvature * u * u + skew * u, _MIN_SHAPE)
    if engagement > 0:
        rise = np.sin(0.5 * np.pi * np.clip(xi / engagement, 0.0, 1.0)) ** 2
        fall = np.sin(0.5 * np.pi * np.clip((1.0 - xi) / engagement, 0.0, 1.0)) ** 2
        shape = shape * rise * fall
    return shape


def _per_tooth(values: tuple[float, ...], teeth: int, scale: float = 1.0) -> FloatArray:
    if not values:
        return np.zeros(teeth)
    return np.asarray(values, dtype=np.float64) * scale


def _spall_tables(model: IndependentModel, wheel: str, teeth: int) -> dict[str, FloatArray]:
    tables = {k: np.zeros(teeth) for k in ("depth", "lo", "hi", "face")}
    tables["wall"] = np.ones(teeth)
    for sp in model.spalls:
        if sp.wheel != wheel:
            continue
        i = sp.tooth - 1
        # Extent along the wheel's own path from its root: ξ for the pinion, 1 − ξ for the gear
        # (the caller passes the gear's coordinate).
        tables["depth"][i] = sp.depth_um * 1e-6
        tables["lo"][i] = sp.centre_fraction - sp.extent_fraction / 2
        tables["hi"][i] = sp.centre_fraction + sp.extent_fraction / 2
        tables["wall"][i] = max(sp.wall_fraction * sp.extent_fraction, 1e-9)
        tables["face"][i] = sp.face_fraction
    return tables


def _spall_depth(xi: FloatArray, tooth: NDArray[np.int64], table: dict[str, FloatArray]) -> FloatArray:
    """Depth (m) of the spall of ``tooth`` at ξ: flat bottom, cosine walls."""
    lo, hi, wall = table["lo"][tooth], table["hi"][tooth], table["wall"][tooth]
    rise = np.clip((xi - lo) / wall, 0.0, 1.0)
    fall = np.clip((hi - xi) / wall, 0.0, 1.0)
    ramp = np.minimum(rise, fall)
    return table["depth"][tooth] * 0.5 * (1.0 - np.cos(np.pi * ramp))


def _relief(xi: FloatArray, model: IndependentModel) -> FloatArray:
    e = model.errors
    length = e.tip_relief_length_fraction
    pinion_tip = np.clip((xi - (1.0 - length)) / length, 0.0, 1.0) ** e.tip_relief_exponent
    gear_tip = np.clip((length - xi) / length, 0.0, 1.0) ** e.tip_relief_exponent
    return (e.pinion_tip_relief_um * pinion_tip + e.gear_tip_relief_um * gear_tip) * 1e-6


@dataclass(frozen=True)
class _StaticSolution:
    approach_m: FloatArray
    loaded_stiffness_n_per_m: FloatArray
    friction_cross_n: FloatArray
    """Sliding-friction force across the line of action, per unit μ."""
    friction_line_n: FloatArray
    """Equivalent extra force on the line-of-action DOF from the friction moments, per unit μ."""
    contact_pairs: FloatArray
    """Number of pairs carrying load."""


def solve_static_mesh(
    model: IndependentModel,
    derived: PairDerived,
    mesh_position: FloatArray,
    start_shift_pitches: FloatArray,
    force_n: float | FloatArray,
    on_chunk: Callable[..., None] | None = None,
) -> _StaticSolution:
    """Loaded static approach along the line of action at each mesh position.

    Parameters
    ----------
    mesh_position
        ``s`` in base pitches (pair q is ``s − q`` pitches after the pitch point).
    start_shift_pitches
        Shift of the start of contact (centre-distance change), same shape.
    force_n
        Normal mesh force to carry (a scalar or one value per position).
    on_chunk
        Called after each chunk as ``on_chunk(lo, hi, ks, es, approach, force, friction_line)``
        with the chunk's springs (stiffness and clearance per sample; out of contact: k = 0),
        for the nonlinear time stepping.
    """
    # Long function: one loop over chunks of mesh positions whose springs are built and handed
    # on chunk by chunk (``on_chunk``), so that a long record's memory stays bounded.
    force_all = np.broadcast_to(np.asarray(force_n, dtype=np.float64), mesh_position.shape)
    g = model.geometry
    z1, z2 = g.pinion_teeth, g.gear_teeth
    n_cand = math.ceil(derived.contact_ratio) + 1
    st = model.stiffness
    e = model.errors
    k_pair = st.peak_n_per_m_per_mm * g.face_width_mm
    idx_p = _per_tooth(e.pinion_index_um, z1, 1e-6)
    idx_g = _per_tooth(e.gear_index_um, z2, 1e-6)
    slope_p = _per_tooth(e.pinion_profile_slope_um, z1, 1e-6)
    slope_g = _per_tooth(e.gear_profile_slope_um, z2, 1e-6)
    crack_p = np.ones(z1)
    crack_g = np.ones(z2)
    for cr in model.cracks:
        (crack_p if cr.wheel == "pinion" else crack_g)[cr.tooth - 1] *= 1 - cr.stiffness_loss_fraction
    sp_p = _spall_tables(model, "pinion", z1)
    sp_g = _spall_tables(model, "gear", z2)
    pinion_pits = bool(np.any(sp_p["depth"] > 0))
    gear_pits = bool(np.any(sp_g["depth"] > 0))
    xi_pitch = derived.pitch_fraction
    out_len = mesh_position.size
    approach = np.empty(out_len)
    stiffness = np.empty(out_len)
    fr_cross = np.empty(out_len)
    fr_line = np.empty(out_len)
    pairs = np.empty(out_len)
    m1, m2 = derived.pinion_mass_kg, derived.gear_mass_kg
    rb1, rb2 = derived.pinion_base_radius_m, derived.gear_base_radius_m
    j = np.arange(n_cand)
    for lo in range(0, out_len, CHUNK_SAMPLES):
        hi = min(lo + CHUNK_SAMPLES, out_len)
        s = mesh_position[lo:hi, None]
        x_start = derived.path_start_pitches + start_shift_pitches[lo:hi, None]
        q = np.floor(s - x_start).astype(np.int64) - j[None, :]
        x_q = s - q
        length = derived.path_end_pitches - x_start
        xi = (x_q - x_start) / length
        inside = (xi >= 0.0) & (xi <= 1.0)
        tp = np.mod(q, z1)
        tg = np.mod(q, z2)
        k = (
            k_pair
            * pair_stiffness_shape(xi, st.curvature, st.skew, st.engagement_fraction)
            * crack_p[tp]
            * crack_g[tg]
        )
        k = np.where(inside, k, 0.0)
        clearance = (
            idx_p[tp]
            + idx_g[tg]
            + slope_p[tp] * (xi - xi_pitch)
            + slope_g[tg] * (xi_pitch - xi)
            + e.profile_crowning_um * 1e-6 * (2 * xi - 1) ** 2
            + _relief(xi, model)
        )
        # A pit removes local contact on a face fraction w; the tooth's bending share (1 − h)
        # is in series with the local contact (h) over the whole face. The pair is then two
        # springs: the intact face in series with the bending, from clearance e, and the
        # increment that the pitted face adds once its local approach exceeds the depth d,
        # from clearance e + d·(1 + (1 − w)(1 − h)/h) (closed form of the series law).
        h = st.contact_compliance_share
        face_p = sp_p["face"][tp]
        face_g = np.minimum(sp_g["face"][tg], 1.0 - face_p)
        face = face_p + face_g
        intact = 1.0 / ((1.0 - h) + h / np.maximum(1.0 - face, 1e-6))
        amplify = 1.0 + (1.0 - face) * (1.0 - h) / h
        split_p = np.where(face > 0, face_p / np.maximum(face, 1e-12), 0.0)
        shares: list[FloatArray | float] = [intact]
        extra: list[FloatArray | float] = [0.0]
        # Pit springs only for a wheel that has a pit (fewer springs: faster sort).
        if pinion_pits:
            shares.append((1.0 - intact) * split_p)
            extra.append(_spall_depth(xi, tp, sp_p) * amplify)
        if gear_pits:
            shares.append((1.0 - intact) * (1.0 - split_p))
            extra.append(_spall_depth(1.0 - xi, tg, sp_g) * amplify)
        ks = np.concatenate([k * sh for sh in shares], axis=1)
        es = np.concatenate([clearance + ex for ex in extra], axis=1)
        es = np.where(ks > 0, es, _FAR)
        order = np.argsort(es, axis=1)
        k_sorted = np.take_along_axis(ks, order, axis=1)
        e_sorted = np.take_along_axis(es, order, axis=1)
        k_cum = np.cumsum(k_sorted, axis=1)
        ke_cum = np.cumsum(k_sorted * e_sorted, axis=1)
        # Force needed to reach breakpoint m with the springs before it: K_{m−1} e_m − KE_{m−1}.
        need = np.zeros_like(e_sorted)
        need[:, 1:] = k_cum[:, :-1] * e_sorted[:, 1:] - ke_cum[:, :-1]
        force = force_all[lo:hi]
        active = np.sum(need < force[:, None], axis=1)  # ≥ 1: need[:, 0] = 0
        row = np.arange(hi - lo)
        k_act = k_cum[row, active - 1]
        if np.any(k_act <= 0):
            raise IndependentModelError("no tooth pair in contact (contact ratio below 1?)")
        delta = (force + ke_cum[row, active - 1]) / k_act
        approach[lo:hi] = delta
        stiffness[lo:hi] = k_act
        load_parts = ks * np.maximum(delta[:, None] - es, 0.0)
        n_pair = load_parts.reshape(hi - lo, len(shares), n_cand).sum(axis=1)
        pairs[lo:hi] = np.sum(n_pair > 0, axis=1)
        # Sliding reverses at the pitch point: s_q = sign(x_q) (−1 approach, +1 recess).
        sign = np.sign(x_q)
        u = derived.pitch_point_m + x_q * derived.base_pitch_m
        fr_cross[lo:hi] = np.sum(sign * n_pair, axis=1)
        # Friction moments (pinion arm u, gear arm T1T2 − u) seen by the relative LOA DOF.
        lever = (u / rb1) * (m2 / (m1 + m2)) + ((derived.line_of_action_m - u) / rb2) * (
            m1 / (m1 + m2)
        )
        fr_line[lo:hi] = -np.sum(sign * n_pair * lever, axis=1)
        if on_chunk is not None:
            on_chunk(lo, hi, ks, es, delta, force, fr_line[lo:hi])
    return _StaticSolution(approach, stiffness, fr_cross, fr_line, pairs)


# --- transfer path -------------------------------------------------------------------------------


def modal_response(modes: tuple[Mode, ...], freq_hz: FloatArray) -> NDArray[np.complex128]:
    """Acceleration per newton of a sum of modes at ``freq_hz`` (see :class:`Mode`)."""
    s = 2j * np.pi * freq_hz
    total = np.zeros(freq_hz.shape, dtype=np.complex128)
    for m in modes:
        w = 2 * np.pi * m.frequency_hz
        wd = w * math.sqrt(1 - m.damping_ratio**2)
        p = complex(-m.damping_ratio * w, wd)
        r = m.gain_m_s2_per_n * np.exp(1j * math.radians(m.phase_deg)) / (2j * wd)
        total += s * s * (r / (s - p) + np.conj(r) / (s - np.conj(p)))
    return total


def _anti_alias(freq_hz: FloatArray, rate_hz: float, pass_fraction: float) -> FloatArray:
    lo, hi = pass_fraction * rate_hz, 0.5 * rate_hz
    ramp = np.clip((freq_hz - lo) / (hi - lo), 0.0, 1.0)
    return 0.5 * (1.0 + np.cos(np.pi * ramp))


# --- speed and tach ------------------------------------------------------------------------------


def _speed_shape(rng: np.random.Generator, u: FloatArray) -> tuple[FloatArray, dict[str, float]]:
    """A slow, smooth relative speed profile on u ∈ [0, 1] (record time), max |·| = 1."""
    ramp = rng.uniform(-1.0, 1.0)
    swell = rng.uniform(-1.0, 1.0)
    cycles = rng.uniform(0.3, 1.5)
    phase = rng.uniform(0, 2 * np.pi)
    uu = np.clip(u, 0.0, 1.0)
    shape = ramp * (2 * uu - 1) + swell * np.sin(2 * np.pi * cycles * uu + phase)
    grid = np.linspace(0.0, 1.0, 2001)
    peak = np.max(np.abs(ramp * (2 * grid - 1) + swell * np.sin(2 * np.pi * cycles * grid + phase)))
    return shape / max(peak, 1e-12), {
        "ramp": ramp, "swell": swell, "swell_cycles": cycles, "swell_phase_rad": phase,
    }


def tach_waveform(
    angle_rad: FloatArray, speed_hz: FloatArray, high_v: float, duty: float, rise_s: float
) -> FloatArray:
    """TTL once-per-rev: rising edge (mid-level) where the angle crosses a multiple of 2π.

    Edges are linear ramps of ``rise_s`` centred on the crossing, so a mid-level threshold
    recovers the crossing exactly; high for ``duty`` of a revolution.
    """
    turns = angle_rad / (2 * np.pi)
    frac = turns - np.floor(turns)
    period = 1.0 / speed_hz
    since_rise = ((frac + 0.5) % 1.0) - 0.5
    since_fall = ((frac - duty + 0.5) % 1.0) - 0.5
    level = np.minimum(since_rise * period / rise_s + 0.5, 0.5 - since_fall * period / rise_s)
    return high_v * np.clip(level, 0.0, 1.0)


# --- the record ----------------------------------------------------------------------------------


def generate_record(model: IndependentModel, seed: int = 0) -> IndependentRecord:
    """Simulate one record of ``model``; deterministic from ``seed``.

    Returns
    -------
    IndependentRecord
        ``channels``: the accelerometer (m/s²) and, when ``model.tachometer.present``, the TTL
        tach (V), both at ``model.acquisition.sample_rate_hz``; ``truth``: every parameter
        (``truth['model']``) and derived value (contact ratio, mesh frequency, mesh mode,
        initial angle, speed range, artefact positions, noise and signal RMS, …).
    """
    # Long function: one record's stages in order (kinematics, static mesh, force spectrum, path,
    # artefacts, tach), drawing from six indexed random streams; the nested helpers share them.
    validate_model(model)
    derived = pair_derived(model)
    acq, op, g, tach = model.acquisition, model.operating, model.geometry, model.tachometer
    # Children are indexed: adding a stream at the end leaves the earlier ones unchanged.
    streams = np.random.SeedSequence(int(seed)).spawn(6)
    rng_angle, rng_speed, rng_noise, rng_artefact, rng_tach, rng_bearing = (
        np.random.default_rng(s) for s in streams
    )
    fs = float(acq.sample_rate_hz)
    os_ = int(acq.oversampling)
    fs_i = fs * os_
    n_out = round(acq.seconds * fs)
    pad_out = round(acq.padding_s * fs)
    n_tot = n_out + 2 * pad_out
    n_i = n_tot * os_
    # Speed: nominal × (1 + drift·shape(t/T)), integrated to the pinion angle.
    shape, shape_params = _speed_shape(
        rng_speed, (np.arange(n_i) - pad_out * os_) / fs_i / acq.seconds
    )
    f_rot = op.speed_rpm / 60.0 * (1.0 + op.speed_drift_fraction * shape)
    del shape
    theta0 = float(rng_angle.uniform(0.0, 2 * np.pi))

    def integrate(rate_hz: FloatArray) -> FloatArray:
        angle = np.concatenate([[0.0], np.cumsum(0.5 * (rate_hz[1:] + rate_hz[:-1]) / fs_i)])
        angle *= 2 * np.pi
        return angle + theta0 - angle[pad_out * os_]

    theta = integrate(f_rot)
    if op.speed_fluctuation_fraction > 0:
        # Locked to the pinion angle: evaluated on the angle without it, then integrated again
        # (first order in the fraction, ≤ a few %: the error is second order).
        f_rot = f_rot * (
            1.0
            + op.speed_fluctuation_fraction
            * np.cos(op.speed_fluctuation_order * theta + math.radians(op.speed_fluctuation_phase_deg))
        )
        theta = integrate(f_rot)
    phi1 = math.radians(tach.tooth1_pitch_angle_deg)
    e = model.errors
    pb = derived.base_pitch_m
    e1, e2 = e.pinion_eccentricity_um * 1e-6, e.gear_eccentricity_um * 1e-6
    force = op.load_torque_nm / derived.gear_base_radius_m

    def kinematics(angle: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Mesh position, start-of-contact shift, load and runout approach at pinion angles."""
        s_nominal = g.pinion_teeth * (angle - phi1) / (2 * np.pi)
        gear_angle = 2 * np.pi * s_nominal / g.gear_teeth  # 0: gear tooth 1 on the pitch point
        a1 = angle - math.radians(e.pinion_eccentricity_phase_deg)
        a2 = gear_angle - math.radians(e.gear_eccentricity_phase_deg)
        ecc = e1 * np.cos(a1) + e2 * np.cos(a2)
        # The pinion's involutes move with its centre: its offset along the line of action
        # moves every contact; the centre-distance change (offsets across it) shifts the
        # gear-tip end of the path.
        position = s_nominal + e1 * np.cos(a1) / pb
        shift = (e1 * np.sin(a1) + e2 * np.sin(a2)) / math.sin(derived.pressure_angle_rad) / pb
        load = force * (
            1.0
            + op.load_fluctuation_fraction
            * np.cos(op.load_fluctuation_order * gear_angle - math.radians(op.load_fluctuation_phase_deg))
        )
        return position, shift, load, ecc

    # Block by block (bounded memory for long records): only the loaded static TE, and the
    # friction forces when there is friction, are kept for the whole record.
    mu = op.friction_coefficient
    x_s = np.empty(n_i)
    friction_line = np.zeros(n_i) if mu > 0 else None
    friction_cross = np.zeros(n_i) if mu > 0 else None
    k_sum = 0.0
    min_pairs = 1 << 30
    for lo in range(0, n_i, KINEMATICS_BLOCK):
        hi = min(lo + KINEMATICS_BLOCK, n_i)
        position, shift, load, ecc = kinematics(theta[lo:hi])
        static = solve_static_mesh(model, derived, position, shift, load)
        x_s[lo:hi] = static.approach_m - ecc
        k_sum += float(np.sum(static.loaded_stiffness_n_per_m))
        min_pairs = min(min_pairs, int(np.min(static.contact_pairs)))
        if friction_line is not None and friction_cross is not None:
            friction_line[lo:hi] = static.friction_line_n
            friction_cross[lo:hi] = static.friction_cross_n
    k_mean = k_sum / n_i
    mass = derived.mesh_mass_kg
    damping = 2 * model.stiffness.damping_ratio * math.sqrt(k_mean * mass)
    # Only the bins below the output Nyquist survive the anti-alias filter and the decimation:
    # the dynamics and the path are evaluated there alone.
    kept = n_tot // 2 + 1
    freq: FloatArray = np.fft.rfftfreq(n_i, 1.0 / fs_i)[:kept].astype(np.float64)
    w = 2 * np.pi * freq
    k_shaft = model.stiffness.shaft_stiffness_n_per_m
    dyn = k_mean + k_shaft - mass * w**2 + 1j * w * damping

    def spectrum(x: FloatArray) -> NDArray[np.complex128]:
        return np.fft.rfft(x - np.mean(x))[:kept]

    separated = 0
    if model.dynamics == "nonlinear":
        from physics.independent.stepping import NonlinearStepper

        stepper = NonlinearStepper(n_i, 1.0 / fs_i, mass, damping, k_shaft, float(np.mean(x_s)))
        for lo in range(0, n_i, KINEMATICS_BLOCK):
            hi = min(lo + KINEMATICS_BLOCK, n_i)
            position, shift, load, ecc = kinematics(theta[lo:hi])

            def consume(clo: int, chi: int, ks: FloatArray, es: FloatArray, approach: FloatArray,
                        force_chunk: FloatArray, fr_line: FloatArray, base: int = lo,
                        ecc: FloatArray = ecc) -> None:
                stepper(base + clo, base + chi, ks, es, ecc[clo:chi], approach - ecc[clo:chi],
                        force_chunk, mu * fr_line)

            solve_static_mesh(model, derived, position, shift, load, on_chunk=consume)
        mesh_force_f = spectrum(stepper.mesh_force)
        separated = stepper.separated_samples
        del stepper
    else:
        xs_f = spectrum(x_s)
        fl_f = spectrum(mu * friction_line) if friction_line is not None else np.zeros(kept, complex)
        x_f = ((k_mean + 1j * w * damping) * xs_f + fl_f) / dyn
        # m ẍ + c (ẋ − ẋ_s) + k̄ (x − x_s) + k_sh x = f_fr; the mesh (bearing) force's dynamic
        # part is N = f_fr − m ẍ − k_sh x.
        mesh_force_f = fl_f + (mass * w**2 - k_shaft) * x_f
    path = model.path
    beta = math.radians(path.sensor_angle_deg)
    line_path = modal_response(path.line_modes, freq)
    cross_path = (
        modal_response(path.cross_modes, freq)
        if path.cross_modes and math.sin(beta) != 0.0
        else np.zeros(kept, complex)
    )
    shaping = np.exp(-1j * w * path.delay_s) * _anti_alias(freq, fs, acq.anti_alias_pass_fraction)

    def through_path(force_f: NDArray[np.complex128], cross: NDArray[np.complex128]) -> FloatArray:
        acc_f = math.cos(beta) * line_path * force_f
        acc_f = acc_f + math.sin(beta) * cross_path * (cross + path.cross_coupling * force_f)
        return np.fft.irfft(acc_f * shaping, n=n_tot) / os_

    cross_f = (
        spectrum(mu * friction_cross) if friction_cross is not None else np.zeros(kept, complex)
    )
    keep = slice(pad_out, pad_out + n_out)
    clean = through_path(mesh_force_f, cross_f)[keep]
    signal_rms = float(np.sqrt(np.mean(clean**2)))
    bearing_truth: dict[str, Any] = {}
    if op.bearing_impact_order > 0 and op.bearing_impact_to_signal > 0:
        # Impact angles: mean spacing 2π/order with a random walk of the intervals (slip).
        turns = theta / (2 * np.pi)
        count = int((turns[-1] - turns[0]) * op.bearing_impact_order) + 2
        gaps = (1 + op.bearing_slip * rng_bearing.standard_normal(count)) / op.bearing_impact_order
        marks = turns[0] + rng_bearing.uniform(0, 1) / op.bearing_impact_order + np.cumsum(gaps)
        marks = marks[marks < turns[-1]]
        where = np.interp(marks, turns, np.arange(n_i, dtype=np.float64))
        impulses = np.zeros(n_i)
        np.add.at(impulses, np.round(where).astype(np.int64), 1.0)
        impact = through_path(np.fft.rfft(impulses)[:kept], np.zeros(kept, complex))[keep]
        impact_rms = float(np.sqrt(np.mean(impact**2)))
        if impact_rms > 0:
            clean = clean + impact * (op.bearing_impact_to_signal * signal_rms / impact_rms)
        inside = (where >= pad_out * os_) & (where < (pad_out + n_out) * os_)
        bearing_truth = {
            "impacts": int(np.sum(inside)),
            "rms_m_s2": op.bearing_impact_to_signal * signal_rms,
        }
    noise_rms = acq.noise_to_signal * signal_rms if acq.noise_rms_m_s2 is None else acq.noise_rms_m_s2
    art = model.artefacts
    truth_art: dict[str, Any] = {}
    disturbance = rng_noise.normal(0.0, 1.0, n_out) * noise_rms
    if art.hum_to_signal > 0:
        t_out = np.arange(n_out) / fs
        hum = sum(
            (0.5 ** (h - 1)) * np.sin(2 * np.pi * h * art.hum_hz * t_out + rng_noise.uniform(0, 2 * np.pi))
            for h in (1, 2, 3)
            if h * art.hum_hz < fs / 2
        )
        hum_rms = float(np.sqrt(np.mean(np.square(hum))))
        disturbance = disturbance + np.asarray(hum) * (art.hum_to_signal * signal_rms / hum_rms)
        truth_art["hum_rms_m_s2"] = art.hum_to_signal * signal_rms
    measured = acq.gain * (clean + disturbance)
    if art.clip_fraction_of_peak is not None:
        level = art.clip_fraction_of_peak * float(np.max(np.abs(measured)))
        clipped = int(np.sum(np.abs(measured) > level))
        measured = np.clip(measured, -level, level)
        truth_art["clip_level"] = level
        truth_art["clipped_samples"] = clipped
    if art.dropouts:
        span = max(1, round(art.dropout_s * fs))
        starts = np.sort(rng_artefact.integers(0, max(1, n_out - span), art.dropouts))
        for s0 in starts:
            measured[s0 : s0 + span] = 0.0
        truth_art["dropout_starts"] = [int(v) for v in starts]
        truth_art["dropout_samples"] = span
    if art.glitches:
        where = np.sort(rng_artefact.choice(n_out, size=art.glitches, replace=False))
        signs = rng_artefact.choice([-1.0, 1.0], size=art.glitches)
        magnitude = (
            art.glitch_value
            if art.glitch_value is not None
            else art.glitch_peak_ratio * acq.gain * float(np.max(np.abs(clean)))
        )
        measured[where] = signs * magnitude
        truth_art["glitch_value"] = magnitude
        truth_art["glitch_samples"] = [int(v) for v in where]
    channels: dict[str, FloatArray] = {acq.accelerometer_name: measured}
    theta_out = theta[::os_][keep]
    speed_out = f_rot[::os_][keep]
    edges: list[float] = []
    if tach.present:
        wave = tach_waveform(theta_out, speed_out, tach.high_v, tach.duty_fraction, tach.rise_time_s)
        channels[tach.name] = wave + rng_tach.normal(0.0, tach.noise_v, n_out)
        turns = theta_out / (2 * np.pi)
        marks = np.arange(np.ceil(turns[0]), np.floor(turns[-1]) + 1)
        edges = [float(v) for v in np.interp(marks, turns, np.arange(n_out) / fs)]
    mesh_hz = op.speed_rpm / 60.0 * g.pinion_teeth
    truth = {
        "generator": "physics.independent",
        "seed": int(seed),
        "model": model_to_dict(model),
        "derived": {
            "contact_ratio": derived.contact_ratio,
            "pitch_fraction": derived.pitch_fraction,
            "base_pitch_mm": pb * 1e3,
            "pinion_base_radius_mm": derived.pinion_base_radius_m * 1e3,
            "gear_base_radius_mm": derived.gear_base_radius_m * 1e3,
            "mesh_mass_kg": mass,
            "mean_loaded_stiffness_n_per_m": k_mean,
            "mesh_mode_hz": math.sqrt((k_mean + k_shaft) / mass) / (2 * math.pi),
            "mesh_frequency_hz": mesh_hz,
            "normal_force_n": force,
            "static_te_rms_um": float(np.std(x_s[::os_][keep]) * 1e6),
            "min_pairs_in_contact": min_pairs,
            "dynamics": model.dynamics,
            "separated_fraction": separated / n_i,
        },
        "record": {
            "sample_rate_hz": fs,
            "samples": n_out,
            "initial_pinion_angle_deg": math.degrees(theta0),
            "speed_min_rpm": float(np.min(speed_out) * 60.0),
            "speed_max_rpm": float(np.max(speed_out) * 60.0),
            "speed_shape": shape_params,
            "tach_edges_s": edges[:3] + (["…"] if len(edges) > 3 else []),
            "tach_edge_count": len(edges),
            "signal_rms_m_s2": signal_rms,
            "noise_rms_m_s2": noise_rms,
            "gain": acq.gain,
            "artefacts": truth_art,
            "bearing_impacts": bearing_truth,
        },
        "tooth1_pitch_angle_deg": tach.tooth1_pitch_angle_deg,
        "spalled_teeth": [
            {"wheel": sp.wheel, "tooth": sp.tooth, "depth_um": sp.depth_um} for sp in model.spalls
        ],
    }
    return IndependentRecord(
        channels=channels,
        sample_rate_hz=fs,
        truth=truth,
        static_te_m=x_s[::os_][keep].copy(),
        pinion_angle_rad=theta_out.copy(),
    )
