"""A record's data-quality score: how much its per-tooth evidence can be trusted, in [0, 1].

The score is a product of five factors, each in (0, 1], each 1 for an ideal record and falling
smoothly as one thing gets worse, so that one bad aspect cannot be hidden by good others:

- **revolutions** ``1 − exp(−N / REVOLUTIONS_SCALE)``, ``N`` = revolutions in the average:
  0.49 at 20, 0.81 at 50, 0.96 at 100. Besides the noise (next factor), few revolutions leave
  non-synchronous content (the other wheel, bearings) in the average.
- **synchronous-to-noise** ``s / (s + SNR_SCALE)`` with ``s`` the power ratio in the *average*:
  synchronous power ``P_sync`` over the noise left in the average, ``P_res / N``, where ``P_res``
  is the power of the revolutions about their average (the non-synchronous power per
  revolution) and ``P_sync = P_avg − P_res / N`` (the average's power minus its expected noise
  power). 0.5 at 10 dB, 0.91 at 20 dB, 0.99 at 30 dB.
- **speed** ``1 / (1 + (v / SPEED_VARIATION_SCALE)²)``, ``v`` = (max − min)/mean of the
  per-revolution speed: 0.94 at 0.1, 0.8 at 0.2, 0.5 at 0.4. Order tracking resamples a drifting
  record exactly, but the vibration itself changes with speed (resonances, load), so the average
  mixes operating points.
- **tach repairs** ``1 / (1 + REPAIR_WEIGHT · repairs / revolutions)``: one inserted or removed
  pulse per 100 revolutions gives 0.95.
- **rejections** ``1 − rejected / (accepted + rejected)`` over pinion revolutions: a record that
  needed a quarter of its revolutions dropped scores at most 0.75 (what is left may be clean,
  but the channel is having a bad day).

Example
-------
>>> round(quality_score(revolutions=100, sync_to_noise_db=0.0, speed_variation=0.02,
...                     tach_repairs=0, rejected_revolutions=0).score, 3)
0.874
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["QualityScore", "quality_score", "sync_to_noise_db"]

REVOLUTIONS_SCALE = 30.0
"""Revolutions at which the revolutions factor is 1 − 1/e (0.63)."""
SNR_SCALE = 10.0
"""Synchronous-to-noise power ratio *in the average* (10 dB) at which that factor is 0.5."""
SPEED_VARIATION_SCALE = 0.4
"""Speed variation (max − min)/mean at which the speed factor is 0.5 (±20 % drift)."""
REPAIR_WEIGHT = 5.0
"""Weight of tach repairs per revolution."""
SNR_FLOOR_DB = -60.0
"""Reported synchronous-to-noise ratio when the synchronous power is zero or below the noise's."""


@dataclass(frozen=True)
class QualityScore:
    """The score and its factors (each in (0, 1]; ``score`` is their product)."""

    score: float
    revolutions: float
    sync_to_noise: float
    speed: float
    repairs: float
    rejections: float

    def components(self) -> dict[str, float]:
        return {
            "revolutions": self.revolutions,
            "sync_to_noise": self.sync_to_noise,
            "speed": self.speed,
            "repairs": self.repairs,
            "rejections": self.rejections,
        }


def sync_to_noise_db(average_power: float, residual_power: float, revolutions: int) -> float:
    """Synchronous-to-noise ratio *per revolution* in dB: ``P_sync / P_res``.

    ``average_power`` is the mean square of the synchronous average about its mean,
    ``residual_power`` the mean square of the revolutions about the average (per revolution),
    ``revolutions`` the number averaged. ``P_sync = average_power − residual_power / N``; a
    non-positive ``P_sync`` gives :data:`SNR_FLOOR_DB`, a zero residual power ``+inf`` capped at
    200 dB (a noise-free synthetic record).

    Examples
    --------
    >>> round(sync_to_noise_db(1.01, 1.0, 100), 6)
    0.0
    """
    if revolutions < 1:
        raise ValueError(f"revolutions must be >= 1, got {revolutions}")
    sync = average_power - residual_power / revolutions
    if sync <= 0 or not math.isfinite(sync):
        return SNR_FLOOR_DB
    if residual_power <= 0:
        return 200.0
    return max(SNR_FLOOR_DB, min(200.0, 10.0 * math.log10(sync / residual_power)))


def quality_score(
    *,
    revolutions: int,
    sync_to_noise_db: float,
    speed_variation: float,
    tach_repairs: int,
    rejected_revolutions: int,
) -> QualityScore:
    """The data-quality score of a channel of a record (see the module docstring).

    Parameters
    ----------
    revolutions : int
        Pinion revolutions in the average (after rejection), >= 1.
    sync_to_noise_db : float
        Synchronous-to-noise ratio per revolution (:func:`sync_to_noise_db`).
    speed_variation : float
        (max − min)/mean of the per-revolution speed, >= 0.
    tach_repairs : int
        Pulses inserted or removed by the tach repair.
    rejected_revolutions : int
        Pinion revolutions dropped (defective samples or outliers).

    Returns
    -------
    QualityScore
    """
    if revolutions < 1 or tach_repairs < 0 or rejected_revolutions < 0 or speed_variation < 0:
        raise ValueError("counts must be non-negative, revolutions >= 1, speed_variation >= 0")
    f_revs = 1.0 - math.exp(-revolutions / REVOLUTIONS_SCALE)
    snr_in_average = revolutions * 10.0 ** (min(sync_to_noise_db, 200.0) / 10.0)
    f_snr = snr_in_average / (snr_in_average + SNR_SCALE)
    f_speed = 1.0 / (1.0 + (speed_variation / SPEED_VARIATION_SCALE) ** 2)
    f_repairs = 1.0 / (1.0 + REPAIR_WEIGHT * tach_repairs / revolutions)
    f_rejections = revolutions / (revolutions + rejected_revolutions)
    score = f_revs * f_snr * f_speed * f_repairs * f_rejections
    return QualityScore(
        score=float(score),
        revolutions=float(f_revs),
        sync_to_noise=float(f_snr),
        speed=float(f_speed),
        repairs=float(f_repairs),
        rejections=float(f_rejections),
    )
