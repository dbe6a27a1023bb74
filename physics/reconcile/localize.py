"""Where a whitened residual concentrates: order class, tooth and angle sector, frequency band.

Non-synchronous content (bearings, another shaft, electrical lines) never reaches the
hunting-period mean: it is in the scatter between segments. :func:`nonsynchronous_mismatch`
finds bands where that scatter stands above its own broadband floor — content the simulator
(synchronous physics plus white sensor noise) cannot produce.

All inputs are arrays on the hunting-period grid of :mod:`physics.reconcile.observables`.
``chi2`` is the per-bin ``2 |r(k)|² / v(k)`` (2 expected per bin); shares are of the excess
``Σ max(χ²_k − 2, 0)``, so pure noise has no share to give.

Examples
--------
>>> import numpy as np
>>> chi2 = np.full(900, 2.0); chi2[[420, 441]] = [50.0, 20.0]
>>> used = np.ones(900, bool); used[0] = False
>>> [(m["class"], round(m["share"], 2)) for m in order_mismatches(chi2, used, 20, 21)][:2]
[('mesh', 0.73), ('pinion_sideband', 0.27)]
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from physics.reconcile.observables import ORDER_CLASSES, order_classes, revs_per_hunting_period

FloatArray = NDArray[np.float64]


def excess(chi2: FloatArray, used: NDArray[np.bool_]) -> FloatArray:
    out = np.where(used, np.maximum(chi2 - 2.0, 0.0), 0.0)
    return np.asarray(out, dtype=np.float64)


def order_mismatches(
    chi2: FloatArray, used: NDArray[np.bool_], pinion_teeth: int, gear_teeth: int, top_orders: int = 4
) -> list[dict[str, Any]]:
    """Excess χ² share per periodicity class, largest first, with the strongest orders of each."""
    ex = excess(chi2, used)
    total = float(ex.sum())
    if total <= 0:
        return []
    classes = order_classes(chi2.size, pinion_teeth, gear_teeth)
    per_hunt = revs_per_hunting_period(pinion_teeth, gear_teeth)
    out: list[dict[str, Any]] = []
    for name in ORDER_CLASSES:
        mask = classes == name
        share = float(ex[mask].sum()) / total
        if share <= 0:
            continue
        idx = np.flatnonzero(mask)
        best = idx[np.argsort(ex[idx])[::-1][:top_orders]]
        orders = sorted(round(float(k) / per_hunt, 3) for k in best if ex[k] > 0)
        out.append({"domain": "order", "class": name, "orders": orders, "share": share})
    out.sort(key=lambda m: -float(m["share"]))
    return out


def frequency_mismatch(
    chi2: FloatArray, used: NDArray[np.bool_], frequency_hz: FloatArray, band_hz: float = 250.0
) -> dict[str, Any] | None:
    """The contiguous band (multiples of ``band_hz``) holding the most excess χ², grown while
    neighbours hold at least a quarter of the peak band's excess."""
    ex = excess(chi2, used)
    total = float(ex.sum())
    if total <= 0:
        return None
    band = np.floor(frequency_hz / band_hz).astype(int)
    n_bands = int(band[used].max()) + 1
    per_band = np.bincount(band[used], weights=ex[used], minlength=n_bands)
    peak = int(np.argmax(per_band))
    lo = hi = peak
    while lo > 0 and per_band[lo - 1] >= 0.25 * per_band[peak]:
        lo -= 1
    while hi < n_bands - 1 and per_band[hi + 1] >= 0.25 * per_band[peak]:
        hi += 1
    share = float(per_band[lo : hi + 1].sum()) / total
    return {"domain": "frequency", "band_hz": [lo * band_hz, (hi + 1) * band_hz], "share": share}


def whitened_angle_residual(
    residual: NDArray[np.complex128], variance: FloatArray, used: NDArray[np.bool_], n_samples: int
) -> FloatArray:
    """Angle-domain whitened residual over one hunting period (``n_samples`` samples)."""
    spectrum = np.zeros(n_samples // 2 + 1, dtype=np.complex128)
    w = np.zeros_like(variance)
    w[used] = 1.0 / np.sqrt(variance[used])
    spectrum[: residual.size] = residual * w
    out: FloatArray = np.fft.irfft(spectrum, n=n_samples)
    return out


def tooth_mismatch(
    angle_residual: FloatArray,
    pinion_teeth: int,
    gear_teeth: int,
    samples_per_rev: int,
    tooth1_pitch_angle_deg: float,
) -> list[dict[str, Any]]:
    """Per-tooth energy of the pinion- and gear-folded whitened residual; strongest tooth each.

    The share is that tooth's energy in excess of the median tooth, relative to the energy
    of the whole hunting-period residual. Gear angles are relative to the gear's position at
    the record's first tachometer pulse.
    """
    per_hunt = revs_per_hunting_period(pinion_teeth, gear_teeth)
    total = float(np.sum(angle_residual**2))
    if total <= 0:
        return []
    out = []
    for wheel, teeth, revs in (
        ("pinion", pinion_teeth, per_hunt),
        ("gear", gear_teeth, per_hunt * pinion_teeth // gear_teeth),
    ):
        if angle_residual.size % revs:
            continue
        folded = angle_residual.reshape(revs, -1).mean(axis=0)
        n = folded.size
        pitch = n / teeth
        offset = tooth1_pitch_angle_deg / 360.0 * n if wheel == "pinion" else 0.0
        energies = np.zeros(teeth)
        idx = np.arange(n)
        for j in range(teeth):
            centre = offset + j * pitch
            d = (idx - centre + n / 2) % n - n / 2
            energies[j] = float(np.sum(folded[np.abs(d) <= pitch / 2] ** 2)) * revs
        j = int(np.argmax(energies))
        share = max(0.0, float(energies[j] - np.median(energies))) / total
        centre_deg = (offset + j * pitch) / n * 360.0
        half = 180.0 / teeth
        out.append(
            {
                "domain": "angle",
                "wheel": wheel,
                "teeth": [j + 1],
                "angle_deg": [round((centre_deg - half) % 360.0, 1), round((centre_deg + half) % 360.0, 1)],
                "share": share,
                "contrast": float(energies[j] / max(np.median(energies), 1e-300)),
            }
        )
    return out


def mismatches(
    residual: NDArray[np.complex128],
    variance: FloatArray,
    used: NDArray[np.bool_],
    frequency_hz: FloatArray,
    *,
    pinion_teeth: int,
    gear_teeth: int,
    samples_per_rev: int,
    tooth1_pitch_angle_deg: float,
    min_share: float = 0.05,
) -> list[dict[str, Any]]:
    """The JSON ``mismatches`` list: order classes, localised teeth, and the frequency band."""
    chi2 = np.zeros(residual.size)
    chi2[used] = 2.0 * np.abs(residual[used]) ** 2 / variance[used]
    out = [m for m in order_mismatches(chi2, used, pinion_teeth, gear_teeth) if m["share"] >= min_share]
    n_samples = revs_per_hunting_period(pinion_teeth, gear_teeth) * samples_per_rev
    angle = whitened_angle_residual(residual, variance, used, n_samples)
    for m in tooth_mismatch(angle, pinion_teeth, gear_teeth, samples_per_rev, tooth1_pitch_angle_deg):
        if m["share"] >= min_share and m["contrast"] >= 3.0:
            out.append(m)
    band = frequency_mismatch(chi2, used, frequency_hz)
    if band is not None:
        out.append(band)
    return out


def nonsynchronous_mismatch(
    segment_spectra: NDArray[np.complex128],
    used: NDArray[np.bool_],
    frequency_hz: FloatArray,
    *,
    band_hz: float = 50.0,
    floor_window_hz: float = 200.0,
    family_p_value: float = 1e-4,
) -> dict[str, Any] | None:
    """The band where the between-segment scatter stands significantly above its floor.

    Parameters
    ----------
    segment_spectra : ndarray, shape (segments, bins)
        Complex spectrum of each hunting-period segment.
    used : ndarray of bool
        Bins to consider.
    frequency_hz : ndarray
        Frequency of each bin.
    band_hz : float
        Width of the bands the significant bins are grouped into.
    floor_window_hz : float
        Width of the running median that estimates the broadband floor of the scatter (at
        least 101 bins). Narrow enough to follow the anti-alias roll-off, whose slope would
        otherwise pass for excess scatter.
    family_p_value : float
        Family-wise false-alarm probability over all the bins (Bonferroni): under a smooth
        floor each bin's scatter is a scaled χ² with ``2 (segments − 1)`` degrees of freedom.

    Returns
    -------
    dict or None
        ``{"domain": "non_synchronous", "band_hz": [lo, hi], "peak_hz", "excess_db", "share",
        "significant_bins", "p_value"}`` for the band holding the most significant excess —
        ``share`` is its scatter above the floor over all the scatter energy — or None when
        no bin is significant (or there are fewer than two segments).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> seg = rng.normal(size=(4, 4000)) + 1j * rng.normal(size=(4, 4000))
    >>> f = np.arange(4000) * 1.0
    >>> nonsynchronous_mismatch(seg, np.ones(4000, bool), f) is None   # white noise only
    True
    >>> seg[:, 1520] += 8.0 * np.exp(2j * np.pi * rng.uniform(size=4))  # a tone off the grid
    >>> m = nonsynchronous_mismatch(seg, np.ones(4000, bool), f)
    >>> m["band_hz"], m["peak_hz"]
    ([1500.0, 1550.0], 1520.0)
    """
    from scipy.ndimage import median_filter
    from scipy.stats import chi2 as chi2_dist
    from scipy.stats import f as f_dist

    spectra = np.asarray(segment_spectra)
    segments = spectra.shape[0]
    if segments < 2 or not np.any(used):
        return None
    scatter = np.sum(np.abs(spectra - spectra.mean(axis=0)) ** 2, axis=0) / (segments - 1)
    idx = np.flatnonzero(used)
    s = scatter[idx]
    f = np.asarray(frequency_hz, dtype=np.float64)[idx]
    df = float(np.median(np.diff(f))) if f.size > 1 else 1.0
    half = max(50, round(floor_window_hz / 2 / df))
    nu = 2 * (segments - 1)
    # The median of a scaled χ²_ν, turned into its mean; mirrored edges keep the floor unbiased.
    floor = median_filter(s, size=2 * half + 1, mode="mirror") * (nu / float(chi2_dist.ppf(0.5, nu)))
    ratio = np.where(floor > 0, s / np.where(floor > 0, floor, 1.0), 1.0)
    # The floor is itself an estimate (a median of 2·half + 1 bins, efficiency ≈ 2/π of a mean):
    # the ratio is F-distributed rather than χ²/ν, whose tail would be too light.
    p_bin = f_dist.sf(ratio, nu, nu * (2 * half + 1) * 2 / np.pi)
    significant = p_bin * s.size < family_p_value
    if not np.any(significant):
        return None
    band = np.floor(f / band_hz).astype(int)
    above = np.where(significant, np.maximum(s - floor, 0.0), 0.0)
    per_band = np.bincount(band, weights=above)
    best = int(np.argmax(per_band))
    in_band = (band == best) & significant
    peak = int(np.flatnonzero(in_band)[np.argmax(ratio[in_band])])
    return {
        "domain": "non_synchronous",
        "band_hz": [round(best * band_hz, 1), round((best + 1) * band_hz, 1)],
        "peak_hz": round(float(f[peak]), 1),
        "excess_db": round(float(10 * np.log10(ratio[peak])), 1),
        "share": float(per_band[best] / max(float(s.sum()), 1e-300)),
        "significant_bins": int(significant.sum()),
        "p_value": float(min(1.0, float(p_bin[significant].min()) * s.size)),
    }


def chi2_per_bin(residual: NDArray[np.complex128], variance: FloatArray, used: NDArray[np.bool_]) -> FloatArray:
    chi2 = np.zeros(residual.size)
    chi2[used] = 2.0 * np.abs(residual[used]) ** 2 / variance[used]
    return chi2
