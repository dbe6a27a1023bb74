"""Randomised rigs of the independent generator for evaluation sets.

:func:`random_model` draws a whole rig (geometry, stiffness law, gear errors, transfer path,
operating point, sensor) from a seed, within the ranges stated in its docstring; any of the
main quantities can be fixed by keyword. Healthy: add a spall with ``model.replace(spalls=…)``
or through :func:`physics.independent.campaign.campaign_days`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from physics.independent.campaign import CampaignDay, campaign_days
from physics.independent.model import (
    Acquisition,
    IndependentModel,
    Mode,
    Operating,
    PairGeometry,
    PairStiffness,
    Spall,
    Tachometer,
    ToothErrors,
    TransferPath,
    validate_model,
)

MAX_MESH_HZ = 2000.0
"""Mesh frequency ceiling of drawn operating points (≥ 5 mesh harmonics below 10 kHz)."""


def random_model(
    seed: int,
    *,
    contact_ratio: float | None = None,
    pinion_teeth: int | None = None,
    gear_teeth: int | None = None,
    noise_to_signal: float | None = None,
    speed_drift_fraction: float | None = None,
    sensor_angle_deg: float | None = None,
    tachometer: bool = True,
    seconds: float = 12.0,
    sample_rate_hz: float = 20000.0,
    dynamics: str | None = None,
) -> IndependentModel:
    """A rig drawn from ``seed`` (every argument left None is drawn).

    Ranges: contact ratio 1.3–2.0 (given directly; approach share 0.4–0.6, reduced when the
    pinion is too small for it), pinion 13–80 teeth, ratio 1–3.5, pressure angle 20 or 25°,
    module 2–8 mm, face 10–40 mm; pair stiffness 12–18 N/(mm·µm) per mm with curvature 0.3–0.6,
    skew ±0.1, mesh damping 3–8 %, shafts 2–15 % of the mesh stiffness, contact compliance share
    0.15–0.45; index errors σ 0.1–0.5 µm, profile slopes σ 0.2–1 µm,
    crowning 0–3 µm, tip relief 0–12 µm over 15–35 % of the path, eccentricities 2–15 µm;
    2–4 line modes (0.4–8.5 kHz log-uniform, ζ 1.5–6 %, gains log-uniform 1e-3–1e-2, phases ±60°),
    1–3 cross modes, delay 0–0.4 ms, sensor angle 0–60°, cross coupling 0.1–0.6;
    speed 300–3000 rpm with mesh ≤ 2 kHz, load 0.3–1 of a size-scaled nominal, drift 0–20 %,
    friction μ 0–0.08; noise 0.3–3× the signal RMS; tooth-1 angle anywhere; dynamics linear
    (oversampling 4) or nonlinear (time-stepped, oversampling 8), one or the other at random.
    """
    # Long function: the draws come from one stream in a fixed order (a seed names a rig); moved
    # into helpers they would be easy to reorder, which would silently change every seed's rig.
    rng = np.random.default_rng(seed)
    z1 = int(pinion_teeth if pinion_teeth is not None else rng.integers(13, 81))
    z2 = int(gear_teeth if gear_teeth is not None else max(z1, round(z1 * rng.uniform(1.0, 3.5))))
    eps = float(contact_ratio if contact_ratio is not None else rng.uniform(1.3, 2.0))
    alpha = float(rng.choice([20.0, 25.0]))
    # The approach part of the path must stay outside the pinion's base circle.
    room = z1 * math.tan(math.radians(alpha)) / (2 * math.pi * eps)
    approach = float(min(rng.uniform(0.4, 0.6), 0.85 * room))
    module = float(rng.uniform(2.0, 8.0))
    face = float(rng.uniform(10.0, 40.0))
    geometry = PairGeometry(
        pinion_teeth=z1, gear_teeth=z2, module_mm=round(module, 3), pressure_angle_deg=alpha,
        face_width_mm=round(face, 2), contact_ratio=eps, approach_fraction=approach,
        inertia_factor=float(rng.uniform(1.2, 3.0)),
    )
    stiffness = PairStiffness(
        peak_n_per_m_per_mm=float(rng.uniform(1.2e7, 1.8e7)),
        curvature=float(rng.uniform(0.3, 0.6)),
        skew=float(rng.uniform(-0.1, 0.1)),
        damping_ratio=float(rng.uniform(0.03, 0.08)),
        shaft_stiffness_n_per_m=float(rng.uniform(0.02, 0.15) * 1.5e7 * face * eps),
        contact_compliance_share=float(rng.uniform(0.15, 0.45)),
    )
    index_sigma = rng.uniform(0.1, 0.5)
    slope_sigma = rng.uniform(0.2, 1.0)
    errors = ToothErrors(
        pinion_index_um=tuple(float(v) for v in rng.normal(0, index_sigma, z1).round(4)),
        gear_index_um=tuple(float(v) for v in rng.normal(0, index_sigma, z2).round(4)),
        pinion_profile_slope_um=tuple(float(v) for v in rng.normal(0, slope_sigma, z1).round(4)),
        gear_profile_slope_um=tuple(float(v) for v in rng.normal(0, slope_sigma, z2).round(4)),
        profile_crowning_um=float(rng.uniform(0, 3)),
        pinion_tip_relief_um=float(rng.uniform(0, 12)),
        gear_tip_relief_um=float(rng.uniform(0, 12)),
        tip_relief_length_fraction=float(rng.uniform(0.15, 0.35)),
        tip_relief_exponent=float(rng.choice([1.0, 2.0])),
        pinion_eccentricity_um=float(rng.uniform(2, 15)),
        pinion_eccentricity_phase_deg=float(rng.uniform(0, 360)),
        gear_eccentricity_um=float(rng.uniform(2, 15)),
        gear_eccentricity_phase_deg=float(rng.uniform(0, 360)),
    )

    def modes(count: int) -> tuple[Mode, ...]:
        # Log-uniform frequencies: housings and shafts ring from a few hundred Hz up.
        return tuple(
            Mode(
                frequency_hz=float(10 ** rng.uniform(math.log10(400.0), math.log10(8500.0))),
                damping_ratio=float(rng.uniform(0.015, 0.06)),
                gain_m_s2_per_n=float(10 ** rng.uniform(-3, -2)),
                phase_deg=float(rng.uniform(-60, 60)),
            )
            for _ in range(count)
        )

    path = TransferPath(
        line_modes=modes(int(rng.integers(2, 5))),
        cross_modes=modes(int(rng.integers(1, 4))),
        cross_coupling=float(rng.uniform(0.1, 0.6)),
        sensor_angle_deg=float(sensor_angle_deg if sensor_angle_deg is not None else rng.uniform(0, 60)),
        delay_s=float(rng.uniform(0, 4e-4)),
    )
    max_rpm = min(3000.0, MAX_MESH_HZ * 60 / z1)
    speed = float(rng.uniform(min(300.0, 0.5 * max_rpm), max_rpm))
    # Nominal gear torque scaled with the pair's size (≈ 200 N·m for module 5, 21 teeth, 20 mm).
    r2 = module * 1e-3 * z2 / 2
    nominal = 200.0 * (r2 / 0.0525) * (face / 20.0) * (module / 5.0)
    operating = Operating(
        speed_rpm=speed,
        load_torque_nm=float(nominal * rng.uniform(0.3, 1.0)),
        speed_drift_fraction=float(
            speed_drift_fraction if speed_drift_fraction is not None else rng.uniform(0, 0.2)
        ),
        friction_coefficient=float(rng.uniform(0, 0.08)),
    )
    tooth1 = float(rng.uniform(0, 360))
    noise = float(
        noise_to_signal if noise_to_signal is not None
        else 10 ** rng.uniform(math.log10(0.3), math.log10(3))
    )
    # Drawn last so that the draws above are those of the first version for every seed.
    dyn = dynamics if dynamics is not None else str(rng.choice(["linear", "nonlinear"]))
    if dyn not in ("linear", "nonlinear"):
        raise ValueError(f"dynamics must be linear or nonlinear, got {dyn!r}")
    model = IndependentModel(
        dynamics="nonlinear" if dyn == "nonlinear" else "linear",
        geometry=geometry,
        stiffness=stiffness,
        errors=errors,
        path=path,
        operating=operating,
        tachometer=Tachometer(
            present=tachometer, tooth1_pitch_angle_deg=tooth1
        ),
        acquisition=Acquisition(
            sample_rate_hz=sample_rate_hz,
            seconds=seconds,
            oversampling=8 if dyn == "nonlinear" else 4,
            noise_to_signal=noise,
        ),
    )
    validate_model(model)
    return model


def random_campaign(
    seed: int,
    *,
    days: int = 8,
    spalled: bool = True,
    onset_day: int | None = None,
    tachometer: bool = True,
    seconds: float = 12.0,
    **rig: object,
) -> list[CampaignDay]:
    """A campaign on a :func:`random_model` rig with randomised day-to-day conditions.

    The rig is ``random_model(seed, tachometer=…, seconds=…, **rig)`` (e.g. ``contact_ratio=1.4``
    fixes it). Drawn from ``seed`` (a stream separate from the rig's): onset day (from the middle
    of the campaign to the last day, unless given), a pinion tooth, a pit that appears at 3–6 µm
    and doubles each day up to 25–30 µm, with face fraction 0.1–0.3 and extent 0.1–0.25 growing
    ×1.5 a day (caps 0.8 and 0.6), centred at 0.3–0.6 of the path; day-to-day load ±10 %, speed
    ±5 %, mesh stiffness ±2 %, noise ±20 %; a gain step (×0.5–2) on a random day in half of the
    campaigns; a glitch sample on ~15 % of the days (an ADC spike of 5–50× the record's peak, or
    in 1 campaign of 5 a corrupted 3e38). ``spalled=False``: the same without the pit.
    """
    base = random_model(seed, tachometer=tachometer, seconds=seconds, **rig)  # type: ignore[arg-type]
    rng = np.random.default_rng([int(seed), 7919])
    z1 = base.geometry.pinion_teeth
    onset = int(onset_day if onset_day is not None else rng.integers(max(2, days // 2), days + 1))
    depth0 = float(rng.uniform(3.0, 6.0))
    cap = float(rng.uniform(25.0, 30.0))
    later = max(days - onset + 1, 1)
    depths = [round(min(depth0 * 2**k, cap), 3) for k in range(later)]
    face0, extent0 = float(rng.uniform(0.1, 0.3)), float(rng.uniform(0.1, 0.25))
    faces = [round(min(face0 * 1.5**k, 0.8), 4) for k in range(later)]
    extents = [round(min(extent0 * 1.5**k, 0.6), 4) for k in range(later)]
    pit = Spall(tooth=int(rng.integers(1, z1 + 1)), centre_fraction=float(rng.uniform(0.3, 0.6)))
    gain_day = int(rng.integers(2, days + 1)) if rng.uniform() < 0.5 and days >= 2 else None
    gain_factor = float(2 ** rng.uniform(-1, 1))
    glitch_days = tuple(int(d) for d in np.flatnonzero(rng.uniform(size=days) < 0.15) + 1)
    plan_seed = int(rng.integers(0, 2**31 - 1))
    # Drawn after the first version's draws (same campaigns per seed otherwise).
    spike_ratio = float(10 ** rng.uniform(math.log10(5.0), math.log10(50.0)))
    corrupted = bool(rng.uniform() < 0.2)
    base = base.replace(artefacts=dataclasses.replace(
        base.artefacts,
        glitch_value=3.0e38 if corrupted else None,
        glitch_peak_ratio=spike_ratio,
    ))
    return campaign_days(
        base,
        days,
        onset_day=onset if spalled else None,
        spall=pit,
        depths_um=depths,
        extents=extents,
        face_fractions=faces,
        load_jitter=0.1,
        speed_jitter=0.05,
        stiffness_jitter=0.02,
        noise_jitter=0.2,
        gain_step_day=gain_day,
        gain_step_factor=gain_factor,
        glitch_days=glitch_days,
        seed=plan_seed,
    )
