"""Per-tooth localisation on one pinion revolution.

Angle convention (``/work/shared/docs/mci-notes.md`` §4): ``tooth1_pitch_angle_deg`` is the
pinion angle after the tachometer reference edge at which pinion tooth 1 passes the pitch
point; tooth ``k`` (1-based) passes it ``(k − 1)·360/Z1`` degrees later. Sample ``i`` of a
revolution of ``N`` samples sits at ``360·i/N`` degrees. The *sector* of tooth ``k`` is its
pitch angle ± half a pitch, half-open ``[p_k − 180/Z1, p_k + 180/Z1)`` so that every angle
belongs to exactly one tooth.

Transfer-path delay: the accelerometer sees a tooth's event *after* the tooth passes the pitch
point (structural modes ring, acquisition anti-alias filters delay), so the MCI well and the
difference-signal burst sit after the pitch angle. The sector's half pitch absorbs a small
delay; a larger one is given as ``transfer_delay_deg`` (default 0, the plain convention above),
which centres every sector on ``pitch angle + transfer_delay_deg``. It is a time delay of the
rig's transfer path and acquisition chain, so in degrees it grows with speed:
``transfer_delay_deg = 360 · delay_s · shaft_speed_rpm / 60``. Measured on the project's gear-pair
simulator (default model, ~1000 rpm, 20 teeth): the contact-length change of a spalled tooth is
centred on its pitch angle (−0.2 samples of 64 per pitch) but the accelerometer's change and the
robust MCI well are centred ≈ +31…33 samples (≈ 1.47 ms, 8.8°) later — right on the sector
edge: with ``transfer_delay_deg = 0`` the spalled tooth won in 7 of 8 simulated campaigns
(the miss went to the next tooth), with 4.5° or 8.7° in 8 of 8.

Per-tooth indicators
--------------------
``mci_depth`` (:func:`per_tooth_mci_depth`)
    ``median(MCI over the revolution) − mean(MCI over the sector)``, in nepers. The median is
    the healthy level of a curve that is flat except for wells (a well covers ≈ W of the
    revolution's Z1·W samples, so it cannot move the median); subtracting it removes the
    curve's arbitrary offset, so depths are comparable across days, channels and gains. The
    sector *mean* rather than its minimum: the median filter gives the well a flat bottom
    about one pitch wide, which usually straddles two sectors, so the minimum ties between the
    spalled tooth and a neighbour; the mean ranks first the sector holding most of the well,
    i.e. its centre (notes §4), and averages noise. Measured on the campaign of
    :mod:`dsp.mci` (robust MCI, noise 0.01, 100 cases): worst tooth right in 93 % of cases
    with the minimum (every miss a tie with the next tooth), 100 % with the mean; the mean
    was at least as good in all 24 cells of the table. A well exactly one sector wide and
    centred on the pitch angle has depth equal to the well's depth. Deepest = worst tooth.
``mci_depth`` as reported by gearwatch (:func:`per_tooth_well_depth`)
    The sector depth above, capped by the fall of the curve at the tooth's event
    (:func:`per_tooth_well_onset_depth`), so that the ringing tail of one tooth's well is not
    reported as a well on the next teeth (measurements in its docstring).
``diff_energy``, ``diff_kurtosis`` (:func:`per_tooth_difference_stats`)
    The classic evidence in the same sector of the difference signal: mean square relative to
    the revolution's mean square (1 = an average tooth), and the kurtosis (4th standardised
    moment about the sector's mean, 3 for Gaussian samples).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dsp.peaks import local_maxima


def _checked_teeth(pinion_teeth: int) -> int:
    teeth = int(pinion_teeth)
    if teeth < 1:
        raise ValueError(f"pinion_teeth must be positive, got {pinion_teeth}")
    return teeth


def tooth_pitch_angles_deg(pinion_teeth: int, tooth1_pitch_angle_deg: float) -> NDArray[np.float64]:
    """Pitch-point angle of every pinion tooth, in degrees within ``[0, 360)``.

    Parameters
    ----------
    pinion_teeth : int
        Number of pinion teeth ``Z1``.
    tooth1_pitch_angle_deg : float
        Angle after the tach reference edge at which tooth 1 passes the pitch point.

    Returns
    -------
    ndarray of float64, shape (Z1,)
        Entry ``k − 1`` is tooth ``k``'s pitch angle.

    Examples
    --------
    >>> tooth_pitch_angles_deg(4, 100.0)
    array([100., 190., 280.,  10.])
    """
    teeth = _checked_teeth(pinion_teeth)
    return np.mod(float(tooth1_pitch_angle_deg) + 360.0 * np.arange(teeth) / teeth, 360.0)


def _tooth_index(
    angle_deg: NDArray[np.float64], teeth: int, tooth1_pitch_angle_deg: float
) -> NDArray[np.int64]:
    # position within the revolution measured from the start of tooth 1's sector, in pitches
    pitches = np.mod(angle_deg - float(tooth1_pitch_angle_deg) + 180.0 / teeth, 360.0) * (
        teeth / 360.0
    )
    # np.mod can return 360.0 for tiny negative inputs: fold that back to tooth 1
    return np.floor(pitches).astype(np.int64) % teeth


def tooth_at_angle(
    angle_deg: float,
    pinion_teeth: int,
    tooth1_pitch_angle_deg: float,
    *,
    transfer_delay_deg: float = 0.0,
) -> int:
    """1-based pinion tooth whose sector (pitch angle ± half a pitch) holds ``angle_deg``.

    Parameters
    ----------
    angle_deg : float
        Pinion angle after the tach reference edge, degrees (any value; taken modulo 360).
    pinion_teeth : int
        Number of pinion teeth ``Z1``.
    tooth1_pitch_angle_deg : float
        Angle at which tooth 1 passes the pitch point.
    transfer_delay_deg : float
        Sectors are centred on ``pitch angle + transfer_delay_deg`` (module docstring).

    Returns
    -------
    int
        Tooth number in ``1 … Z1``.

    Examples
    --------
    >>> tooth_at_angle(247.0, 20, 0.0)   # 247° / 18° per tooth ≈ 13.7 → tooth 15's sector
    15
    """
    teeth = _checked_teeth(pinion_teeth)
    centre_deg = float(tooth1_pitch_angle_deg) + float(transfer_delay_deg)
    index = _tooth_index(np.asarray(float(angle_deg)), teeth, centre_deg)
    return int(index) + 1


def tooth_sector_masks(
    samples_per_rev: int,
    pinion_teeth: int,
    tooth1_pitch_angle_deg: float,
    *,
    transfer_delay_deg: float = 0.0,
) -> NDArray[np.bool_]:
    """Boolean sector of every tooth over one revolution of ``samples_per_rev`` samples.

    Parameters
    ----------
    samples_per_rev : int
        Samples in one pinion revolution; sample ``i`` is at ``360·i/samples_per_rev`` degrees.
    pinion_teeth : int
        Number of pinion teeth ``Z1``.
    tooth1_pitch_angle_deg : float
        Angle at which tooth 1 passes the pitch point.
    transfer_delay_deg : float
        Sectors are centred on ``pitch angle + transfer_delay_deg`` (module docstring).

    Returns
    -------
    ndarray of bool, shape (Z1, samples_per_rev)
        Row ``k − 1`` is tooth ``k``'s sector; every sample is in exactly one row.

    Examples
    --------
    >>> tooth_sector_masks(8, 4, 0.0).astype(int)
    array([[1, 0, 0, 0, 0, 0, 0, 1],
           [0, 1, 1, 0, 0, 0, 0, 0],
           [0, 0, 0, 1, 1, 0, 0, 0],
           [0, 0, 0, 0, 0, 1, 1, 0]])
    """
    teeth = _checked_teeth(pinion_teeth)
    samples = int(samples_per_rev)
    if samples < teeth:
        raise ValueError(f"samples_per_rev ({samples}) must be at least pinion_teeth ({teeth})")
    angles = 360.0 * np.arange(samples) / samples
    owner = _tooth_index(angles, teeth, float(tooth1_pitch_angle_deg) + float(transfer_delay_deg))
    masks: NDArray[np.bool_] = owner[np.newaxis, :] == np.arange(teeth)[:, np.newaxis]
    return masks


def per_tooth_mci_depth(
    mci_filtered: ArrayLike,
    pinion_teeth: int,
    tooth1_pitch_angle_deg: float,
    *,
    axis: int = -1,
    transfer_delay_deg: float = 0.0,
) -> NDArray[np.float64]:
    """MCI well depth per tooth: revolution median minus the sector's mean, in nepers.

    Parameters
    ----------
    mci_filtered : array_like of float
        Median-filtered MCI over one revolution (value ``i`` = window centred on sample ``i``,
        see :mod:`dsp.mci`), along ``axis``; any leading/trailing batch axes.
    pinion_teeth : int
        Number of pinion teeth ``Z1``.
    tooth1_pitch_angle_deg : float
        Angle at which tooth 1 passes the pitch point.
    axis : int
        Axis of the revolution.
    transfer_delay_deg : float
        Sectors are centred on ``pitch angle + transfer_delay_deg`` (module docstring).

    Returns
    -------
    ndarray of float64, shape (..., Z1)
        Depth of tooth ``k`` at index ``k − 1`` (the revolution axis is replaced by a last
        axis of teeth). Positive = below the healthy level; slightly negative for a sector
        above the median.

    Examples
    --------
    >>> import numpy as np
    >>> curve = np.zeros(80)
    >>> curve[32:48] = -1.5                    # a well filling tooth 3's sector (144–216°)
    >>> per_tooth_mci_depth(curve, 5, 36.0)
    array([0. , 0. , 1.5, 0. , 0. ])
    """
    curves = np.moveaxis(np.asarray(mci_filtered, dtype=np.float64), axis, -1)
    masks = tooth_sector_masks(
        curves.shape[-1],
        pinion_teeth,
        tooth1_pitch_angle_deg,
        transfer_delay_deg=transfer_delay_deg,
    )
    level = np.median(curves, axis=-1, keepdims=True)
    sector_mean = curves @ (masks / masks.sum(axis=-1, keepdims=True)).T
    depths: NDArray[np.float64] = level - sector_mean
    return depths


def per_tooth_well_onset_depth(
    mci_filtered: ArrayLike,
    pinion_teeth: int,
    tooth1_pitch_angle_deg: float,
    *,
    window_samples: int,
    edge_half_width_samples: int | None = None,
    axis: int = -1,
) -> NDArray[np.float64]:
    """MCI well depth per tooth, each well given to the tooth at its leading edge, in nepers.

    The seed's well is flat-bottomed and starts when the centred MCI window first reaches the
    spall, i.e. ``W/2`` samples *before* the event (:mod:`dsp.mci`, window convention). Its
    trailing side is not a clean image of the spall: the transfer path's modes ring after the
    impact, so on a real path (and on the project's simulator) the well recovers over a pitch
    or more and its centre sits up to half a pitch late — the well then fills two or three
    sectors and :func:`per_tooth_mci_depth` shares one spall between the spalled tooth and
    its successors (three neighbours alarmed for one spall on a simulated campaign). The
    leading edge is not delayed by ringing. So:

    ``drop[i] = MCI[i − W/2 − h] − MCI[i − W/2 + h]``

    is the fall of the curve across ``2h`` samples around the point ``W/2`` before sample ``i``
    — a well whose leading edge is at ``e`` gives ``drop ≈ depth`` for ``i`` within ``h`` of
    ``e + W/2``, the event — and a tooth's depth is the largest ``drop`` in its sector
    (``≥ 0`` in practice: a sector with no falling edge scores about zero or below, and the
    rising side of a well scores negative). Like the sector depth it is a difference of the
    curve with itself, so it is free of the amplitude and offset (comparable across days).

    Parameters
    ----------
    mci_filtered : array_like of float
        Median-filtered MCI over one revolution (value ``i`` = window centred on sample ``i``).
    pinion_teeth : int
        Number of pinion teeth ``Z1``.
    tooth1_pitch_angle_deg : float
        Angle at which tooth 1 passes the pitch point.
    window_samples : int
        The MCI window ``W`` the curve was computed with.
    edge_half_width_samples : int, optional
        ``h``; default ``W // 4``.
    axis : int
        Axis of the revolution.

    Returns
    -------
    ndarray of float64, shape (..., Z1)
        Depth of tooth ``k`` at index ``k − 1``.

    Examples
    --------
    >>> import numpy as np
    >>> curve = np.zeros(80)
    >>> curve[36:60] = -1.5    # a well whose edge is W/2 = 8 samples before tooth 3 (144°)
    >>> per_tooth_well_onset_depth(curve, 5, 36.0, window_samples=16).round(2)
    array([0. , 0. , 1.5, 0. , 0. ])
    """
    curves = np.moveaxis(np.asarray(mci_filtered, dtype=np.float64), axis, -1)
    window = int(window_samples)
    if window < 2:
        raise ValueError(f"window_samples must be at least 2, got {window_samples}")
    half = max(1, window // 4) if edge_half_width_samples is None else int(edge_half_width_samples)
    if half < 1:
        raise ValueError("edge_half_width_samples must be at least 1")
    lead = window // 2
    # drop[i] = curve[i - lead - half] - curve[i - lead + half]  (circular)
    drop = np.roll(curves, lead + half, axis=-1) - np.roll(curves, lead - half, axis=-1)
    samples = curves.shape[-1]
    owner = np.argmax(tooth_sector_masks(samples, pinion_teeth, tooth1_pitch_angle_deg), axis=0)
    flat = drop.reshape(-1, samples)
    depths = np.zeros((flat.shape[0], int(pinion_teeth)))
    for row, values in zip(depths, flat, strict=True):
        # Each falling edge goes to the one tooth that holds its peak (the middle of a plateau),
        # not to every sector its shoulders reach. Circular: pad by a revolution on each side.
        padded = np.concatenate((values, values, values))
        peaks = local_maxima(padded)
        peaks = peaks[(peaks >= samples) & (peaks < 2 * samples)] - samples
        row[:] = 0.0
        np.maximum.at(row, owner[peaks], values[peaks])
    depths = depths.reshape((*drop.shape[:-1], int(pinion_teeth)))
    return np.asarray(depths, dtype=np.float64)


def per_tooth_well_depth(
    mci_filtered: ArrayLike,
    pinion_teeth: int,
    tooth1_pitch_angle_deg: float,
    *,
    window_samples: int,
    axis: int = -1,
) -> NDArray[np.float64]:
    """The per-tooth ``mci_depth`` gearwatch reports: ``max(0, min(sector depth, leading-edge drop))``.

    A tooth scores only when its sector is deep (:func:`per_tooth_mci_depth`) *and* a well
    starts there (:func:`per_tooth_well_onset_depth`, ``h = W/4``): the spalled tooth has
    both; the teeth after it, inside the ringing tail of its well, are deep but have no
    falling edge; the tooth before it has at most part of the edge and little depth. The
    minimum of two estimates of the same depth is also a little less noisy on healthy teeth.

    Measured (worst tooth = spalled tooth; ``contrast`` = median over cases of the runner-up's
    depth over the spalled tooth's):

    * project simulator (``physics.simulate``, default 6-DOF model with three structural modes,
      3 s at 1000 rpm, spalls 5 and 15 µm deep, 2–6 mm long, on teeth 1, 3, …, 19; 20 records):
      sector mean 15/20 (contrast 0.98: the ringing tail makes the next tooth tie),
      leading edge 20/20 (0.25), this minimum 20/20 (0.34);
    * the random synthetic averages of :mod:`dsp.mci` (short ringing), 200 cases per cell,
      low-SNR cells (noise, spall amplitude, AM) where the forms differ: sector mean / leading
      edge / this minimum = 88/77/85 % (0.03, 0.1, 0), 70/62/73 % (0.1, 0.3, 0),
      87/72/84 % (0.3, 1.0, 0), 82/69/79 % (0.1, 0.3, 0.3); 100 % for all three at higher SNR.

    Examples
    --------
    >>> import numpy as np
    >>> curve = np.zeros(80)
    >>> curve[36:64] = -1.5    # a well starting W/2 before tooth 3, ringing on into tooth 4
    >>> per_tooth_mci_depth(curve, 5, 36.0).round(2)
    array([0.  , 0.  , 1.12, 1.5 , 0.  ])
    >>> per_tooth_well_depth(curve, 5, 36.0, window_samples=16).round(2)
    array([0.  , 0.  , 1.12, 0.  , 0.  ])
    """
    sector = per_tooth_mci_depth(mci_filtered, pinion_teeth, tooth1_pitch_angle_deg, axis=axis)
    onset = per_tooth_well_onset_depth(
        mci_filtered, pinion_teeth, tooth1_pitch_angle_deg, window_samples=window_samples, axis=axis
    )
    # A sector above the revolution's median is a hump, not a well: depth 0, not negative, so
    # that a healthy tooth's trend sits at 0 whatever the shape of the healthy curve.
    return np.maximum(tooth_evidence(sector, onset), 0.0)


def tooth_evidence(sector_depth: ArrayLike, onset_depth: ArrayLike) -> NDArray[np.float64]:
    """Unclipped per-tooth MCI evidence: ``min(sector depth, leading-edge drop)``, nepers.

    :func:`per_tooth_well_depth` before its clipping at zero: it varies smoothly with noise on
    a healthy tooth, which the jackknife standard error of :mod:`dsp.toothscore` needs.

    Examples
    --------
    >>> tooth_evidence([0.5, -0.2, 1.0], [0.3, 0.1, 1.4])
    array([ 0.3, -0.2,  1. ])
    """
    evidence: NDArray[np.float64] = np.minimum(
        np.asarray(sector_depth, dtype=np.float64), np.asarray(onset_depth, dtype=np.float64)
    )
    return evidence


def per_tooth_evidence(
    mci_filtered: ArrayLike,
    pinion_teeth: int,
    tooth1_pitch_angle_deg: float,
    *,
    window_samples: int,
    axis: int = -1,
) -> NDArray[np.float64]:
    """:func:`tooth_evidence` of MCI curve(s): :func:`per_tooth_well_depth` without the clipping.

    Examples
    --------
    >>> import numpy as np
    >>> curve = np.zeros(80)
    >>> curve[36:64] = -1.5
    >>> per_tooth_evidence(curve, 5, 36.0, window_samples=16).round(2)
    array([0.  , 0.  , 1.12, 0.  , 0.  ])
    """
    sector = per_tooth_mci_depth(mci_filtered, pinion_teeth, tooth1_pitch_angle_deg, axis=axis)
    onset = per_tooth_well_onset_depth(
        mci_filtered, pinion_teeth, tooth1_pitch_angle_deg, window_samples=window_samples, axis=axis
    )
    return tooth_evidence(sector, onset)


def per_tooth_difference_stats(
    difference: ArrayLike,
    pinion_teeth: int,
    tooth1_pitch_angle_deg: float,
    *,
    axis: int = -1,
    transfer_delay_deg: float = 0.0,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Energy and kurtosis of the difference signal in each tooth's sector.

    Parameters
    ----------
    difference : array_like of float
        Difference signal (average minus mesh harmonics and their sidebands) over one
        revolution along ``axis``.
    pinion_teeth : int
        Number of pinion teeth ``Z1``.
    tooth1_pitch_angle_deg : float
        Angle at which tooth 1 passes the pitch point.
    axis : int
        Axis of the revolution.
    transfer_delay_deg : float
        Sectors are centred on ``pitch angle + transfer_delay_deg`` (module docstring).

    Returns
    -------
    energy : ndarray of float64, shape (..., Z1)
        Sector mean square over the revolution's mean square (1 = an average tooth; all ones
        for an identically zero signal).
    kurtosis : ndarray of float64, shape (..., Z1)
        ``E[(x − x̄)⁴]/E[(x − x̄)²]²`` within the sector (Pearson, 3 for Gaussian samples);
        0 for a constant sector, where it is undefined.

    Examples
    --------
    >>> import numpy as np
    >>> d = np.tile([1.0, -1.0], 40)
    >>> d[44] = 10.0                           # an impulse in tooth 3's sector
    >>> energy, kurt = per_tooth_difference_stats(d, 5, 36.0)
    >>> int(np.argmax(energy)) + 1, int(np.argmax(kurt)) + 1
    (3, 3)
    """
    signals = np.moveaxis(np.asarray(difference, dtype=np.float64), axis, -1)
    masks = tooth_sector_masks(
        signals.shape[-1],
        pinion_teeth,
        tooth1_pitch_angle_deg,
        transfer_delay_deg=transfer_delay_deg,
    )
    counts = masks.sum(axis=-1)
    weights = masks / counts[:, np.newaxis]  # (Z1, N): averaging over each sector
    sector_mean = signals @ weights.T
    sector_mean_square = (signals**2) @ weights.T
    overall_mean_square = np.mean(signals**2, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        energy = np.where(overall_mean_square > 0, sector_mean_square / overall_mean_square, 1.0)
    # central moments per sector: deviations of every sample from its own sector's mean
    own_mean = sector_mean @ masks.astype(np.float64)
    deviation = signals - own_mean
    second = (deviation**2) @ weights.T
    fourth = (deviation**4) @ weights.T
    # a sector whose spread is at rounding level is constant: kurtosis undefined → 0
    constant = second <= 1e-28 * np.maximum(sector_mean_square, np.finfo(np.float64).tiny)
    with np.errstate(invalid="ignore", divide="ignore"):
        kurtosis = np.where(constant, 0.0, fourth / np.where(constant, 1.0, second) ** 2)
    return np.asarray(energy, dtype=np.float64), np.asarray(kurtosis, dtype=np.float64)


def worst_tooth(depths: ArrayLike) -> int:
    """1-based tooth with the deepest MCI well.

    Parameters
    ----------
    depths : array_like of float, shape (Z1,)
        Output of :func:`per_tooth_mci_depth` for one curve.

    Returns
    -------
    int
        Tooth number in ``1 … Z1`` (the first one on ties); NaN entries are ignored.

    Examples
    --------
    >>> worst_tooth([0.1, 0.9, 0.3])
    2
    """
    values = np.asarray(depths, dtype=np.float64)
    if values.ndim != 1 or values.size == 0:
        raise ValueError(f"depths must be a non-empty 1-D array, got shape {values.shape}")
    if np.all(np.isnan(values)):
        raise ValueError("every depth is NaN")
    return int(np.nanargmax(values)) + 1
