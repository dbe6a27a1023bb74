"""Per-tooth non-synchronous power: what a drifting speed smears out of the synchronous average.

A spall's transient rings through the transfer path's modes, which ring in *time*. At a steady
speed the ringing sits at the same shaft angle every revolution and the synchronous average keeps
it. When the speed drifts within the record, a mode at ``f`` Hz rings at ``f/Ω`` cycles per
revolution, different in every revolution: the average keeps the first cycle or so and the rest
cancels — but every revolution still carries the transient's *energy* in the same tooth sector.
The per-angle power of the revolutions about their average,

    P(θ) = Σ_r (x_r(θ) − x̄(θ))² / (N − 1),

holds it: ``P`` is flat along the revolution for stationary noise and rises in the sector of a
tooth whose event varies from revolution to revolution.

Measured (2026-11-29) on campaigns of :func:`physics.independent.random_campaign`, 10-s records:
a pit on pinion tooth 9 of 23 (seed 9943, the speed drifting over a 34 % range within each
record) raised the tooth's ``change`` to 4.0 on the day after onset, short of an alarm; the same
campaign at a steady speed gave 6.9. On the drifting records the non-synchronous power of the
tooth's sector stood 4.1 robust standard deviations above the record's other teeth on that day
(healthy days: −1.0 … −0.4), the largest tooth every day after onset.

:func:`per_tooth_nonsync_z` is the indicator gearwatch stores (``nonsync_z``): the robust z of the
log sector power over the teeth of the same record (the statistic the ``change`` indicator used
until 2026-11-29, :func:`dsp.toothchange.log_energy_scores`; its rule was chosen on it), in the
sector the ``change`` uses — from the
pitch angle to one pitch after it (:data:`dsp.toothchange.DEFAULT_LAG_PITCH`).

Where it names the tooth: the average keeps a ring's first, still coherent cycles, so the power
it loses peaks where the ringing has decorrelated — on the spalled tooth's sector when the path
rings for about a mesh period, several teeth later when it rings for many (held-out stress
campaigns: a 710 Hz mode at ζ 0.019 on a 1539 Hz mesh put it 7–8 teeth late). This is why its
default alarm rule is created disabled (:data:`detection.default_rules.NONSYNC_RULE`).

Edge cases: fewer than two revolutions give no power (``P`` undefined): the caller passes NaN
and gets NaN; an identically zero ``P`` (a noise-free, steady record) gives 0 for every tooth.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dsp.teeth import tooth_sector_masks
from dsp.toothchange import DEFAULT_LAG_PITCH, log_energy_scores
from dsp.toothframe import circular_shift

__all__ = ["per_tooth_nonsync_power", "per_tooth_nonsync_z"]


def per_tooth_nonsync_power(
    nonsync_power: ArrayLike,
    pinion_teeth: int,
    tooth1_pitch_angle_deg: float,
    *,
    lag_pitch: float = DEFAULT_LAG_PITCH,
) -> NDArray[np.float64]:
    """Mean non-synchronous power of each tooth's sector over the revolution's mean (1 = typical).

    Parameters
    ----------
    nonsync_power : array_like of float, shape (N,)
        Per-angle power of the revolutions about their average over one pinion revolution, sample
        0 at the tooth frame's origin (the same grid as the pinion average).
    pinion_teeth : int
        Number of pinion teeth ``Z1`` (≥ 1).
    tooth1_pitch_angle_deg : float
        Angle at which tooth 1 passes the pitch point (:mod:`dsp.teeth`).
    lag_pitch : float
        Sectors are centred ``lag_pitch`` pitches after each pitch angle.

    Returns
    -------
    ndarray of float64, shape (Z1,)
        All ones for an identically zero power.

    Examples
    --------
    >>> power = np.ones(80)
    >>> power[44:48] = 11.0           # tooth 3's sector (tooth 1 at 0°, 5 teeth, lag ½ pitch)
    >>> per_tooth_nonsync_power(power, 5, 0.0).round(2).tolist()
    [0.67, 0.67, 2.33, 0.67, 0.67]
    """
    power = np.clip(np.asarray(nonsync_power, dtype=np.float64), 0.0, None)
    if power.ndim != 1:
        raise ValueError(f"nonsync_power must be one revolution (1-D), got shape {power.shape}")
    teeth = int(pinion_teeth)
    masks = tooth_sector_masks(
        power.size, teeth, tooth1_pitch_angle_deg,
        transfer_delay_deg=float(lag_pitch) * 360.0 / max(teeth, 1),
    )
    mean = float(np.mean(power))
    if mean <= 0.0:
        return np.ones(teeth)
    sector_mean: NDArray[np.float64] = (masks @ power) / masks.sum(axis=1) / mean
    return sector_mean


def per_tooth_nonsync_z(
    nonsync_power: ArrayLike,
    pinion_teeth: int,
    tooth1_pitch_angle_deg: float,
    *,
    lag_pitch: float = DEFAULT_LAG_PITCH,
    frame_delay_samples: float = 0.0,
) -> NDArray[np.float64]:
    """How far each tooth's sector power stands above the record's typical tooth, in robust
    standard deviations of the log sector powers over the teeth (0 = the median tooth).

    Effects that scale every tooth's power together — the sensor's gain, the noise level, a day's
    load or speed — cancel. NaN power (too few revolutions) gives NaN for every tooth; fewer than
    three teeth, zeros (no spread to measure against). ``frame_delay_samples``: the curve is first
    moved by the delay that moved the record's average into the tooth frame (a tach-less record,
    :func:`dsp.toothframe.circular_shift`).

    Examples
    --------
    A burst in tooth 3's sector whose phase changes every revolution leaves the average flat and
    the non-synchronous power high there:

    >>> rng = np.random.default_rng(0)
    >>> revolutions = rng.normal(0.0, 1.0, (200, 80))
    >>> revolutions[:, 44:48] += 3.0 * np.sin(rng.uniform(0, 2 * np.pi, (200, 1)) + np.arange(4))
    >>> power = revolutions.var(axis=0, ddof=1)
    >>> z = per_tooth_nonsync_z(power, 5, 0.0)
    >>> int(np.argmax(z)) + 1, bool(z[2] > 5), bool(np.all(np.abs(np.delete(z, 2)) < 3))
    (3, True, True)
    """
    power = np.asarray(nonsync_power, dtype=np.float64)
    teeth = int(pinion_teeth)
    if not np.all(np.isfinite(power)):
        return np.full(teeth, np.nan)
    if teeth < 3:
        return np.zeros(teeth)
    if frame_delay_samples:
        power = circular_shift(power, frame_delay_samples)
    energy = per_tooth_nonsync_power(power, teeth, tooth1_pitch_angle_deg, lag_pitch=lag_pitch)
    return np.asarray(log_energy_scores(energy), dtype=np.float64)
