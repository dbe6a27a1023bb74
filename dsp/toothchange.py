"""Per-tooth change of the synchronous average against the tooth's own history.

A spall that starts on one tooth adds a small, deterministic transient to the pinion average
each time that tooth meshes. A per-record scalar (the MCI well depth, the sector energy of the
difference signal) compares the tooth with the *other teeth of the same record*, where every
tooth's manufacturing signature (pitch and profile errors, a ringing transfer path) is noise of
the same order as an early spall. Compared with the *same tooth's waveform on earlier days*,
those signatures cancel and the new transient stands alone: this module measures that.

Method
------
1. **Gain-free spectrum** (:func:`gain_free_spectrum`): the order spectrum of the average
   divided by the RMS of its mesh harmonics (orders ``h·Z1``), so a sensor gain step, a change
   of the transfer path's overall level or of the load's overall level cancels.
2. **Reference**: the mean gain-free spectrum of the campaign's earlier accepted records (the
   first :data:`DEFAULT_REFERENCE_RECORDS`, at least :data:`DEFAULT_MIN_REFERENCE_RECORDS`).
3. **Change signal** (:func:`change_signal`): this record minus the reference with the orders
   that *every* tooth shares removed — shaft orders ``0..2`` (eccentricity and runout, which
   follow load and mounting) and every mesh harmonic with ``±sidebands`` shaft orders (they move
   with the day's load and speed, and a transfer path that shifts with speed changes them for
   all teeth alike). What is left is tooth-specific change. Before that, each order of the
   record and of the reference is **weighted by the inverse of how much it scattered among the
   reference records** (:func:`order_weights`: noise, and what the days' load and speed did to
   the path, averaged over neighbouring orders): the orders where the gear's own content held
   still from day to day count most, as in a matched filter against coloured noise. Chosen on
   ``benchmarks/bench_detection.py``'s ``tune`` and ``tune-2`` parts (seeds 0–159, 80 spalled
   + 80 healthy campaigns per generator, the ``change`` rule alone, offline on the stored
   averages): project generator onset day 82 → 94 %, by the day after 90 → 99 %, right tooth
   90 → 99 %, healthy campaigns alarmed 0 → 0 of 80; independent generator 16 → 16 %, 31 →
   28 %, 46 → 48 %, 1 → 0 of 80. On the held-out part run afterwards (``held-out-4``) the
   project generator gained as much, and the independent generator lost a little (the pit it
   simulates is heard in the orders the days' load and speed scatter most; the benchmark's
   docstring has the tables). A floor on the scatter (:data:`WHITENING_FLOOR_FRACTION` of
   its mean) is needed: relative to the *median* order instead, the orders above the band,
   which hold almost nothing, got the largest weights, and 35 of 80 healthy independent
   campaigns alarmed, each on one tooth from the first scored day on.
4. **Per-tooth change energy** (:func:`tooth_change_energy`): the energy of the change signal
   in each tooth's sector, the sector centred :data:`DEFAULT_LAG_PITCH` pitches *after* the
   tooth's pitch angle (below), after removing, sector by sector, the least-squares part of the
   change that is the reference's own tooth-specific content scaled or slightly shifted (the
   reference's non-shared signal and its derivative: two of the sector's ~64 degrees of
   freedom). A tooth with a strong manufacturing signature changes that signature's *size and
   timing* with the day's load and speed; a spall adds a *new shape*. On the ``tune`` seeds
   (30 spalled + 30 healthy campaigns per generator) the projection raised onset-day detections
   from 24 to 25 (project generator, warning 5 vs 4.5 without it) and from 6 to 8 (independent),
   with no healthy campaign alarmed in either; without it, the first held-out part had 7 healthy
   campaigns of 50 with a warning at 4.5, several on teeth whose signatures moved with load.
5. **Score** (:func:`change_scores`): the robust z of the *cube root* of the energy over the
   teeth of the same record, ``(E_k^⅓ − median E^⅓) / (s · median E^⅓)``, with ``s`` the relative
   spread ``1.4826·MAD(E^⅓) / median(E^⅓)`` of this record, or the one pooled over its reference
   when that is larger (:func:`score_unit`). Under noise alone each sector energy is
   a scaled χ² with ``M`` degrees of freedom, about the sampling rate over the mesh frequency
   (the band's orders per pitch, twice): ~60 on a slow rig, ~10 on a fast one whose mesh
   frequency is 2 kHz at a 20 kHz sampling rate. The record's own spread over its teeth is the noise unit, so no
   noise model is assumed, and a change that moves all teeth together (a noisier day, a drift of
   the path) moves the median, not the score. **Why the cube root**: it makes a χ² close to
   normal for any ``M`` (Wilson & Hilferty 1931); the log, used until 2026-11-29, does so only
   for large ``M`` — its upper tail is compressed, and a warning at 5 asked a
   10-degree-of-freedom sector for 9.9 times its median energy where 5.3 times has the normal
   false-alarm rate of a 5 under noise (the cube root asks 5.5; at 60 degrees of freedom the
   three are 2.5, 2.2 and 2.2) (``tests/dsp/test_toothchange.py``: the share of pure-noise
   scores above 3 is the normal one for 10 and 60 degrees of freedom, the log's a third of it
   at 10). **Why pooled**: under noise the relative spread depends on ``M`` alone (the rig, the
   sampling, the analysis), not on the day's noise level, but 13 teeth give it with about 5
   degrees of freedom (the MAD's efficiency is 37 %): too few for a z of 5 to mean what it
   says. The reference records give it again, each scored against the others (leave-one-out);
   the median over those and this record is the pooled spread. It is used only when larger than
   the record's own: a day whose operating change moved many teeth' waveforms has a larger
   spread of its own, and that is the honest unit then. A record's scores stay a function of
   its reference and itself.

   Chosen on ``benchmarks/bench_detection.py``'s ``tune`` + ``tune-2`` parts (the ``change``
   rule alone, offline on the stored averages; 80 spalled + 80 healthy campaigns per generator),
   log → this: independent generator onset day 13 → 16, by the day after 22 → 30 of 80, right
   tooth among detections 38 of 49 → 46 of 56, healthy campaigns alarmed 0 → 0 of 80; project
   generator onset day 75 → 79, by the day after 79 → 80 of 80, healthy 0 → 0 of 80. The
   record's own spread alone: 31 of 80 by the day after, but 2 healthy independent campaigns
   alarmed (one a 13-tooth rig, two days at 5.3 and 5.1 on different teeth); the pooled spread
   alone: 3 of 50 healthy project campaigns (``tune-2``) alarmed through the CUSUM, on days
   whose own spread was well above their reference's; the log with the loudness discount of
   step 6 as revised with this: 23 of 80, 1 healthy campaign alarmed.
6. **Loud teeth change more** (``signature_energy``): a tooth with a strong manufacturing
   signature (an index error, a profile error) changes more with the day's load and speed than
   a quiet one, beyond the first-order part the projection removes. Each record says how much:
   ``β`` = the median, over the louder half of the teeth, of ``(E_k − E₀)/S_k`` (``S_k``
   the reference signature's energy in the sector, ``E₀`` the median energy of the quieter half;
   a median over half the teeth, so one spalled tooth cannot set it), and ``E_k`` is compared
   with ``E₀ + β·S_k``, what that tooth would show from the day's operating change alone. A
   quiet tooth is unaffected; a new transient on a loud tooth must exceed what its loudness
   explains. Chosen on ``tune-2`` (seeds 60–159, 50 healthy campaigns per generator,
   ``benchmarks/bench_detection.py``): the healthy campaigns with a change alarm fell from 2 to
   0 (project generator) and 1 to 0 (independent); onset-day detections 42 → 41 of 50 and 4 → 5
   of 50. On ``tune`` (seeds 0–59, 30 healthy each) it went 0 → 0 and 0 → 1 healthy campaigns
   alarmed. ``E₀`` was the median of *all* teeth until 2026-11-29: the loud half's own excess
   raised it and ``β`` came out too small, which the cube-root score (step 5) showed — in the
   known-answer test of 60 teeth whose change is ``0.3·S_k`` the loudest tooth scored 5.4
   against its loudness (2.2 now); on ``tune`` + ``tune-2`` one more onset-day detection (17 →
   18 of 80, independent), no healthy campaign alarmed on either generator.

The reference needs :data:`DEFAULT_MIN_REFERENCE_RECORDS` = 3 records (the fourth record is the
first scored): with 2, a reference sector that happened to be noisy showed as change on every
later day, and kept those days out of the reference (they scored above
:data:`REFERENCE_ADMIT_SCORE`), so it never improved — 2 of the 4 healthy ``tune-2`` campaigns
with a change alarm (project generator), none of the onset-day detections.

Why the sector lags half a pitch
--------------------------------
A tooth is in contact over ``ε`` (contact ratio) pitches around its pitch point, and the
accelerometer sees its transient through a path that delays and rings (structural modes, the
anti-alias filter). The change energy therefore sits after the pitch angle: on both simulators
of this project (``benchmarks/bench_detection.py``; the project's six-DOF model and the
independent one-DOF model with a modal path) the energy centre of a spall's change lies about
half a pitch after the pitch angle, and with sectors centred on the pitch angle the neighbour
``k + 1`` was named in about a third of the detections. Measured on the ``tune`` seeds (0–31) of the
independent generator, right tooth among detections: lag 0.25 → 6 of 8, 0.5 → 9 of 10, 0.75 →
8 of 9 (with one more false alarm). A rig whose path delay is far longer than half a pitch at its
mesh frequency needs ``lag_pitch`` set for it.

Measured again 2026-11-28 on 40 random rigs of the independent generator (seeds 100–139 of
``random_model``: 13–80 teeth, contact ratio 1.3–2.0, noise 0.5 × the signal, 4-s records,
load ±10 %, speed ±5 %; a pit of 10 µm on day 4 and 20 µm on day 5 on a random tooth; two
reference days): the highest tooth was the pitted one on 30 of 40 day-4 records and 35 of 40
day-5 records, every miss a neighbour (day 4: five −1, five +1; day 5: five +1); on 79 more
(seeds 140–219; one rig refused, 19 revolutions) 70 and 66 of 79 — day 4: two −1, four +1, one
+2, two +3; day 5: ten +1, one +2, one +4, one −11, the misses beyond a neighbour mostly on
records whose highest tooth stayed below the warning level (seed 216 named the tooth two after
the pitted one at 9.9). The misses do not follow the path's pure delay: rigs whose delay is under
0.15 of a mesh period named the pitted tooth on 52 and 55 of 65 records (day 4, day 5), those
with 0.15–0.67 on 48 and 46 of 54. A path mode
*on* the mesh frequency shifts it further: a 977 Hz mode with 4.5 % damping at a 969 Hz mesh
(80 teeth, seed 8) rings for about 1/(ζω) ≈ 3.6 ms, three and a half mesh periods, and both days
named the tooth two after the pitted one. Estimating the lag from the data (the issue's ask) is
not built: the reference records carry no timing mark of the path, and the change itself is
what is to be located.

Edge cases
----------
* Fewer reference records than ``min_reference_records``: no score (``None``), not a zero.
* An average with no mesh-harmonic energy (all zero): the gain is undefined, ``ValueError``.
* Averages of different lengths in one campaign (a change of ``samples_per_mesh``): the
  reference holds only records of this record's length.
* A spread of zero over the teeth (a noise-free simulation): the spread floor
  :data:`_MIN_RELATIVE_SPREAD` keeps the score finite.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dsp.teeth import tooth_sector_masks
from gearwatch.floor.defaults import MAD_TO_SIGMA

DEFAULT_REFERENCE_RECORDS = 8
"""Earlier records averaged into the reference (the first ones of the campaign)."""

DEFAULT_MIN_REFERENCE_RECORDS = 3
"""A record is scored once this many earlier records exist (the fourth record of a campaign;
module docstring)."""

REFERENCE_ADMIT_SCORE = 3.5
"""A scored record joins the reference (while it holds fewer than ``reference_records``) only if
no tooth scored above this: a growing fault must not become the reference it is measured
against. Under noise alone the highest of 80 scores passes 3.5 in about 2 % of records, so a
healthy record is seldom kept out, and then it only costs the reference one record."""

DEFAULT_LAG_PITCH = 0.5
"""Sector centre after the pitch angle, in pitches (module docstring)."""

SHARED_LOW_ORDERS = 2
"""Shaft orders ``0..2`` are removed from the change: they follow load and mounting for the
whole wheel."""

SHARED_SIDEBANDS = 1
"""Shaft-order sidebands removed on each side of every mesh harmonic."""

RESOLUTION_ENERGY_FRACTION = 1e-10
"""A sector's change energy is never taken below this fraction of the reference's mean sector
energy (an amplitude of 1e-5 of the signal): the stored averages are float32 (resolution ~1e-7),
so a smaller change is round-off, and identical noise-free records must score 0, not round-off
divided by a tiny spread."""

MIN_MESH_ENERGY_FRACTION = 1e-4
"""An average whose mesh harmonics hold less than this share of its energy (−40 dB) has no mesh
content to normalise by (a real gear's hold several per cent or more): round-off would set the gain."""

WHITENING_HALF_WIDTH = 16
"""Orders on each side over which the reference records' scatter is averaged before it weights
the change (:func:`order_weights`): three records leave each order two complex degrees of
freedom (four real ones); 33 orders give about a hundred and thirty."""

WHITENING_FLOOR_FRACTION = 0.1
"""No order's scatter is taken below this fraction of the mean scatter (:func:`order_weights`):
orders beyond the sensor's or the anti-alias filter's band hold next to nothing, and dividing by
next to nothing would let round-off and interpolation residue there outweigh the band the gear
is heard in."""

_MIN_RELATIVE_SPREAD = 1e-3
"""Smallest relative spread of ``E^⅓`` over the teeth used as the score's unit (about 3e-3 of
``ln E``)."""

_MIN_LOG_SPREAD = 1e-3
"""Smallest spread of ``ln E`` over the teeth (nepers) used as :func:`log_energy_scores`' unit."""


def gain_free_spectrum(average: ArrayLike, pinion_teeth: int) -> NDArray[np.complex128]:
    """Order spectrum of a pinion average divided by the RMS of its mesh harmonics.

    Parameters
    ----------
    average : array_like of float, shape (N,)
        One pinion revolution, ``N`` a multiple of ``pinion_teeth``.
    pinion_teeth : int
        ``Z1``; orders ``Z1, 2·Z1, …`` are the mesh harmonics.

    Returns
    -------
    ndarray of complex128, shape (N // 2 + 1,)

    Examples
    --------
    A gain of 3 cancels:

    >>> x = np.cos(2 * np.pi * 4 * np.arange(16) / 16) + 0.1 * np.cos(2 * np.pi * np.arange(16) / 16)
    >>> bool(np.allclose(gain_free_spectrum(3 * x, 4), gain_free_spectrum(x, 4)))
    True
    """
    values = np.asarray(average, dtype=np.float64)
    teeth = int(pinion_teeth)
    if values.ndim != 1 or teeth < 1 or values.size % teeth or values.size < 2 * teeth:
        raise ValueError(
            f"average must be one revolution of a multiple of pinion_teeth ({teeth}) samples,"
            f" at least two per tooth; got shape {values.shape}"
        )
    spectrum = np.fft.rfft(values)
    mesh_energy = float(np.sum(np.abs(spectrum[teeth::teeth]) ** 2))
    total_energy = float(np.sum(np.abs(spectrum[1:]) ** 2))
    if not np.isfinite(mesh_energy) or mesh_energy <= MIN_MESH_ENERGY_FRACTION * total_energy:
        raise ValueError("the average has no mesh-harmonic content to normalise by")
    out: NDArray[np.complex128] = spectrum / np.sqrt(mesh_energy)
    return out


def shared_orders_mask(bins: int, pinion_teeth: int) -> NDArray[np.bool_]:
    """Orders every tooth shares: ``0..SHARED_LOW_ORDERS`` and each mesh harmonic ± sidebands.

    Examples
    --------
    >>> shared_orders_mask(9, 4).astype(int)
    array([1, 1, 1, 1, 1, 1, 0, 1, 1])
    """
    orders = np.arange(int(bins))
    teeth = int(pinion_teeth)
    distance = np.abs((orders + teeth // 2) % teeth - teeth // 2)  # to the nearest mesh harmonic
    shared: NDArray[np.bool_] = (orders <= SHARED_LOW_ORDERS) | (
        (orders >= teeth - SHARED_SIDEBANDS) & (distance <= SHARED_SIDEBANDS)
    )
    return shared


def order_weights(reference_spectra: ArrayLike, pinion_teeth: int) -> NDArray[np.float64]:
    """Per-order weights ``1/σ_o`` from the reference records' scatter (module docstring, step 3).

    ``σ_o²`` is the mean squared deviation of the reference records' gain-free spectra from
    their mean at order ``o``, averaged over :data:`WHITENING_HALF_WIDTH` orders on each side
    (the shared orders, which the change leaves out, take no part) and never below
    :data:`WHITENING_FLOOR_FRACTION` of its mean. What scatters from one reference day to the
    next — noise, and what the day's load and speed do to the path — is weighted down; the
    orders that held still are weighted up. The weights have an RMS of 1 over the orders the
    change keeps; with no scatter at all (identical records) they are all 1.

    Parameters
    ----------
    reference_spectra : array_like of complex, shape (R, N // 2 + 1)
        The reference records' gain-free spectra (:func:`gain_free_spectrum`); with one record
        there is no scatter, and the weights are all 1.
    pinion_teeth : int

    Returns
    -------
    ndarray of float64, shape (N // 2 + 1,)

    Examples
    --------
    Orders 100–199 scatter twice as much as the others: they are weighted half as much.

    >>> rng = np.random.default_rng(0)
    >>> scatter = np.where((np.arange(257) >= 100) & (np.arange(257) < 200), 2.0, 1.0)
    >>> w = order_weights(rng.standard_normal((60, 257)) * scatter, 128)
    >>> bool(1.7 < w[50] / w[150] < 2.3)
    True
    >>> round(float(np.sqrt(np.mean(w[~shared_orders_mask(257, 128)] ** 2))), 6)
    1.0
    """
    spectra = np.asarray(reference_spectra, dtype=np.complex128)
    if spectra.ndim != 2 or spectra.shape[0] < 1:
        raise ValueError(f"need reference spectra of shape (R, bins), got shape {spectra.shape}")
    kept = ~shared_orders_mask(spectra.shape[1], pinion_teeth)
    ones = np.ones(spectra.shape[1])
    if spectra.shape[0] < 2 or not kept.any():
        return ones
    scatter = np.mean(np.abs(spectra - spectra.mean(axis=0)) ** 2, axis=0) * kept
    window = np.ones(2 * WHITENING_HALF_WIDTH + 1)
    centre = slice(WHITENING_HALF_WIDTH, WHITENING_HALF_WIDTH + scatter.size)  # any length
    counts = np.convolve(kept.astype(np.float64), window)[centre]
    smoothed = np.convolve(scatter, window)[centre] / np.fmax(counts, 1.0)
    level = float(np.mean(smoothed[kept]))
    if not np.isfinite(level) or level <= 0.0:
        return ones
    weights = 1.0 / np.sqrt(np.fmax(smoothed, WHITENING_FLOOR_FRACTION * level))
    out: NDArray[np.float64] = weights / np.sqrt(np.mean(weights[kept] ** 2))
    return out


def change_signal(
    spectrum: ArrayLike, reference: ArrayLike, pinion_teeth: int, samples_per_rev: int
) -> NDArray[np.float64]:
    """Tooth-specific change: ``spectrum − reference`` without the shared orders, over one rev.

    Parameters
    ----------
    spectrum, reference : array_like of complex, shape (N // 2 + 1,)
        Gain-free spectra (:func:`gain_free_spectrum`) of this record and of the reference.
    pinion_teeth : int
    samples_per_rev : int
        ``N``.

    Returns
    -------
    ndarray of float64, shape (N,)

    Examples
    --------
    A change at the mesh harmonic (shared by every tooth) is removed:

    >>> n, z = 32, 4
    >>> a = gain_free_spectrum(np.cos(2 * np.pi * 4 * np.arange(n) / n), z)
    >>> b = gain_free_spectrum(np.cos(2 * np.pi * 4 * np.arange(n) / n + 0.3), z)
    >>> float(np.abs(change_signal(b, a, z, n)).max()) < 1e-12
    True
    """
    difference = np.asarray(spectrum, dtype=np.complex128) - np.asarray(
        reference, dtype=np.complex128
    )
    difference[shared_orders_mask(difference.size, pinion_teeth)] = 0.0
    out: NDArray[np.float64] = np.fft.irfft(difference, int(samples_per_rev))
    return out


def tooth_change_energy(
    change: ArrayLike,
    pinion_teeth: int,
    tooth1_pitch_angle_deg: float,
    *,
    lag_pitch: float = DEFAULT_LAG_PITCH,
    signature: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Energy of the change signal in each tooth's sector (centred ``lag_pitch`` after it).

    Examples
    --------
    >>> change = np.zeros(16); change[9] = 1.0      # sample 9 of 16: 202.5°
    >>> int(np.argmax(tooth_change_energy(change, 4, 0.0, lag_pitch=0.5))) + 1   # 157.5° + lag
    3
    >>> int(np.argmax(tooth_change_energy(change, 4, 0.0, lag_pitch=0.0))) + 1
    3
    """
    values = np.asarray(change, dtype=np.float64)
    teeth = int(pinion_teeth)
    masks = tooth_sector_masks(
        values.size, teeth, tooth1_pitch_angle_deg,
        transfer_delay_deg=float(lag_pitch) * 360.0 / teeth,
    )
    if signature is None:
        energy: NDArray[np.float64] = masks.astype(np.float64) @ (values**2)
        return energy
    reference = np.asarray(signature, dtype=np.float64)
    components = np.stack([reference, np.gradient(reference)])  # scale and small shift
    energy = np.empty(teeth)
    for tooth, mask in enumerate(masks):
        basis = components[:, mask].T
        coefficients, *_ = np.linalg.lstsq(basis, values[mask], rcond=None)
        energy[tooth] = float(np.sum((values[mask] - basis @ coefficients) ** 2))
    return energy


def change_scores(
    energy: ArrayLike,
    signature_energy: ArrayLike | None = None,
    *,
    relative_spread: float | None = None,
) -> NDArray[np.float64]:
    """Robust z of ``E^⅓`` over the teeth of one record (module docstring, steps 5 and 6).

    Parameters
    ----------
    energy : array_like of float, shape (Z1,)
        Per-tooth change energy (:func:`tooth_change_energy`), positive.
    signature_energy : array_like of float, shape (Z1,), optional
        Per-tooth energy of the reference's own tooth-specific content in the same sectors.
        Given, each tooth's energy is first divided by what its loudness explains,
        ``(E₀ + β·S_k)/E₀`` (step 6).
    relative_spread : float, optional
        The unit: by default the record's own relative spread of ``E^⅓``
        (:func:`relative_spread_of`); :func:`campaign_change_state` passes :func:`score_unit`.

    Examples
    --------
    >>> change_scores([1.0, 1.1, 0.9, 1.0, 1.05, 0.95, 8.0]).round(1)
    array([ 0. ,  1.3, -1.4,  0. ,  0.7, -0.7, 39.8])

    Every tooth changed roughly in proportion to its loudness (``E ≈ 1 + 0.3·S``): the loud
    tooth 7 (signature 40) does not stand out against it; the same change on a quiet tooth does:

    >>> energy = [1.0, 1.3, 1.6, 1.1, 1.5, 0.9, 9.0, 1.05]
    >>> loudness = [0.1, 1.0, 4.0, 0.2, 2.0, 0.1, 40.0, 0.1]
    >>> round(float(change_scores(energy)[6]), 1), round(float(change_scores(energy, loudness)[6]), 1)
    (9.5, -0.7)
    >>> loudness[6] = 0.1
    >>> round(float(change_scores(energy, loudness)[6]), 1)
    60.0

    A pooled unit twice the record's own halves the scores:

    >>> own = relative_spread_of([1.0, 1.1, 0.9, 1.0, 1.05, 0.95, 8.0])
    >>> float(change_scores([1.0, 1.1, 0.9, 1.0, 1.05, 0.95, 8.0], relative_spread=2 * own)[6].round(1))
    19.9
    """
    roots = np.cbrt(_adjusted_energy(energy, signature_energy))
    centre = float(np.median(roots))
    spread = _relative_spread(roots, centre) if relative_spread is None else float(relative_spread)
    scores: NDArray[np.float64] = (roots - centre) / (max(spread, _MIN_RELATIVE_SPREAD) * centre)
    return scores


def relative_spread_of(energy: ArrayLike, signature_energy: ArrayLike | None = None) -> float:
    """``1.4826·MAD(E^⅓) / median(E^⅓)`` over the teeth of one record (after the loudness
    discount when ``signature_energy`` is given): the unit of :func:`change_scores`.

    Under noise alone it depends on the sector's degrees of freedom ``M`` only, about
    ``√(2/(9M)) / (1 − 2/(9M))`` (Wilson–Hilferty):

    >>> x = np.random.default_rng(0).chisquare(10, 20000)              # M = 10, any scale
    >>> round(relative_spread_of(x), 2), round(relative_spread_of(3 * x), 2), round(float(np.sqrt(2 / 90) / (1 - 2 / 90)), 2)
    (0.15, 0.15, 0.15)
    """
    roots = np.cbrt(_adjusted_energy(energy, signature_energy))
    return _relative_spread(roots, float(np.median(roots)))


def _relative_spread(roots: NDArray[np.float64], centre: float) -> float:
    return MAD_TO_SIGMA * float(np.median(np.abs(roots - centre))) / centre


def score_unit(own: float, reference_spreads: Sequence[float]) -> float:
    """The unit of a record's scores (module docstring, step 5): the median of its own relative
    spread and its reference records' (each scored against the others,
    :func:`relative_spread_of`), never below its own.

    >>> score_unit(0.12, [0.30, 0.14, 0.13]), score_unit(0.30, [0.12, 0.14, 0.13])
    (0.135, 0.3)
    """
    return max(float(own), float(np.median(np.asarray([own, *reference_spreads], dtype=np.float64))))


def log_energy_scores(energy: ArrayLike) -> NDArray[np.float64]:
    """Robust z of ``ln E`` over the teeth, ``(ln E_k − median ln E)/(1.4826·MAD ln E)``: the
    ``change`` score until 2026-11-29, kept for :mod:`dsp.nonsync` (whose rule was chosen on it).

    >>> log_energy_scores([1.0, 1.1, 0.9, 1.0, 1.05, 0.95, 8.0]).round(1)
    array([ 0. ,  1.3, -1.4,  0. ,  0.6, -0.7, 27.3])
    """
    logs = np.log(_adjusted_energy(energy, None))
    centre = float(np.median(logs))
    spread = max(MAD_TO_SIGMA * float(np.median(np.abs(logs - centre))), _MIN_LOG_SPREAD)
    scores: NDArray[np.float64] = (logs - centre) / spread
    return scores


def _adjusted_energy(energy: ArrayLike, signature_energy: ArrayLike | None) -> NDArray[np.float64]:
    """The energies, checked, floored above zero, and divided by what their tooth's loudness
    explains when ``signature_energy`` is given (step 6)."""
    values = np.asarray(energy, dtype=np.float64)
    if values.ndim != 1 or values.size < 3:
        raise ValueError(f"energy must be 1-D with at least three teeth, got {values.shape}")
    values = np.fmax(values, np.finfo(np.float64).tiny)
    if signature_energy is not None:
        values = values / _loudness_factor(values, np.asarray(signature_energy, np.float64))
    return values


def _loudness_factor(energy: NDArray[np.float64], signature: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(E₀ + β·S_k) / E₀`` per tooth (module docstring, step 6); ones when no tooth has a
    signature. ``E₀`` is the median energy of the quieter half of the teeth, ``β`` the median of
    ``(E_k − E₀)/S_k`` over the louder half."""
    if signature.shape != energy.shape:
        raise ValueError(f"signature_energy must have the shape of energy {energy.shape}")
    loud = (signature >= np.median(signature)) & (signature > 0)
    if not loud.any():
        return np.ones_like(energy)
    # the level of a tooth whose loudness explains little: with the median of all teeth
    # instead, the loud half's own excess entered it and β came out too small
    base = float(np.median(energy[~loud])) if (~loud).any() else float(np.median(energy))
    if base <= 0:
        return np.ones_like(energy)
    beta = max(0.0, float(np.median((energy[loud] - base) / signature[loud])))
    factor: NDArray[np.float64] = (base + beta * np.fmax(signature, 0.0)) / base
    return factor


def _sector_energies(
    spectrum: NDArray[np.complex128],
    reference_spectra: NDArray[np.complex128],
    weights: NDArray[np.float64],
    pinion_teeth: int,
    samples_per_rev: int,
    tooth1_pitch_angle_deg: float,
    lag_pitch: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One record's per-tooth change energy against the mean of ``reference_spectra`` (steps
    3–4, floored at :data:`RESOLUTION_ENERGY_FRACTION`) and the reference signature's energy in
    the same sectors (step 6)."""
    reference = reference_spectra.mean(axis=0) * weights
    change = change_signal(spectrum * weights, reference, pinion_teeth, samples_per_rev)
    signature = change_signal(  # the reference's own tooth-specific content
        reference, np.zeros_like(reference), pinion_teeth, samples_per_rev)
    energy = tooth_change_energy(
        change, pinion_teeth, tooth1_pitch_angle_deg, lag_pitch=lag_pitch, signature=signature)
    loudness = tooth_change_energy(signature, pinion_teeth, tooth1_pitch_angle_deg, lag_pitch=lag_pitch)
    reference_wave = np.fft.irfft(reference, samples_per_rev)
    floor = RESOLUTION_ENERGY_FRACTION * float(np.sum(reference_wave**2)) / pinion_teeth
    return np.fmax(energy, floor), loudness


def _usable_spectrum(average: ArrayLike, pinion_teeth: int) -> NDArray[np.complex128] | None:
    """:func:`gain_free_spectrum`, or ``None`` for an average it cannot normalise (no mesh
    content: a dead or disconnected sensor that day) — that record is left out, not the campaign."""
    try:
        return gain_free_spectrum(average, pinion_teeth)
    except ValueError:
        return None


def campaign_change_scores(
    averages: Sequence[ArrayLike | None],
    tooth1_pitch_angles_deg: Sequence[float],
    pinion_teeth: int,
    *,
    reference_records: int = DEFAULT_REFERENCE_RECORDS,
    min_reference_records: int = DEFAULT_MIN_REFERENCE_RECORDS,
    lag_pitch: float = DEFAULT_LAG_PITCH,
) -> list[NDArray[np.float64] | None]:
    """Per-tooth change scores of every record of a campaign, in ``taken_at`` order.

    A function of the ordered records alone (the same result whatever order they arrived in).

    Parameters
    ----------
    averages : sequence of (array_like of float or None)
        Each accepted record's pinion average in the campaign's tooth frame, in ``taken_at``
        order; ``None`` for a record without one (it is skipped and gets ``None``, as does an
        average without mesh-harmonic content, which cannot be put on the common gain).
    tooth1_pitch_angles_deg : sequence of float
        Tooth 1's pitch angle in each average.
    pinion_teeth : int
    reference_records, min_reference_records : int
        The reference is the mean of the first ``reference_records`` earlier records of the same
        length that were admitted (every record scored below :data:`REFERENCE_ADMIT_SCORE` on
        every tooth, or not scored); a record with fewer than ``min_reference_records`` of them
        gets ``None``.
    lag_pitch : float
        :func:`tooth_change_energy`.

    Returns
    -------
    list of (ndarray of float64, shape (Z1,)) or None

    Examples
    --------
    Five days of the same gear with noise; a transient on tooth 3 from day 4 on:

    >>> rng = np.random.default_rng(0)
    >>> z, n = 20, 1280
    >>> base = np.cos(2 * np.pi * z * np.arange(n) / n)
    >>> days = [base + 0.01 * rng.standard_normal(n) for _ in range(5)]
    >>> for day in days[3:]:
    ...     day[152:168] += 0.2                      # tooth 3 (pitch angle 36°) + half a pitch = 45°
    >>> scores = campaign_change_scores(days, [0.0] * 5, z)
    >>> scores[:2], [int(np.argmax(s)) + 1 for s in scores[3:]], bool(min(scores[3][2], scores[4][2]) > 6)
    ([None, None], [3, 3], True)
    """
    return campaign_change_state(
        averages, tooth1_pitch_angles_deg, pinion_teeth, reference_records=reference_records,
        min_reference_records=min_reference_records, lag_pitch=lag_pitch,
    )[0]


def campaign_change_state(
    averages: Sequence[ArrayLike | None],
    tooth1_pitch_angles_deg: Sequence[float],
    pinion_teeth: int,
    *,
    reference_records: int = DEFAULT_REFERENCE_RECORDS,
    min_reference_records: int = DEFAULT_MIN_REFERENCE_RECORDS,
    lag_pitch: float = DEFAULT_LAG_PITCH,
) -> tuple[list[NDArray[np.float64] | None], list[int]]:
    """:func:`campaign_change_scores` and the indices of the records admitted to the reference.

    A record's scores depend only on the records before it; once ``reference_records`` records
    of its length are admitted, no later record of that length is. So a record appended after a
    prefix that already holds a complete reference is scored exactly by scoring the prefix and
    it alone (what :mod:`gearwatch.usecases.tooth_change` does for the record that arrives last).

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> days = [np.cos(2 * np.pi * 8 * np.arange(256) / 256) + 0.01 * rng.standard_normal(256)
    ...         for _ in range(5)]
    >>> scores, admitted = campaign_change_state(days, [0.0] * 5, 8, reference_records=3)
    >>> admitted, [s is None for s in scores]
    ([0, 1, 2], [True, True, True, False, False])
    """
    if min_reference_records < 1 or reference_records < min_reference_records:
        raise ValueError("need 1 <= min_reference_records <= reference_records")
    if len(tooth1_pitch_angles_deg) != len(averages):
        raise ValueError("one tooth-1 angle per average")
    lengths = [0 if average is None else np.asarray(average).size for average in averages]
    spectra = [None if average is None else _usable_spectrum(average, pinion_teeth)
               for average in averages]
    out: list[NDArray[np.float64] | None] = []
    admitted: list[int] = []  # indices of the records in the reference, in taken_at order
    reference_spreads: dict[tuple[int, ...], list[float]] = {}  # leave-one-out, per reference
    for index, spectrum in enumerate(spectra):
        if spectrum is None:
            out.append(None)
            continue
        earlier = [i for i in admitted if lengths[i] == lengths[index]][:reference_records]
        scores: NDArray[np.float64] | None = None
        if len(earlier) >= min_reference_records:
            reference_spectra = np.array([s for i in earlier if (s := spectra[i]) is not None])
            weights = order_weights(reference_spectra, pinion_teeth)
            energy, loudness = _sector_energies(
                spectrum, reference_spectra, weights, pinion_teeth, lengths[index],
                tooth1_pitch_angles_deg[index], lag_pitch)
            key = tuple(earlier)  # the same reference for every later record, once complete
            if key not in reference_spreads:  # each reference record scored against the others
                reference_spreads[key] = [
                    relative_spread_of(*_sector_energies(
                        reference_spectra[position], np.delete(reference_spectra, position, axis=0),
                        weights, pinion_teeth, lengths[index], tooth1_pitch_angles_deg[i], lag_pitch))
                    for position, i in enumerate(earlier if len(earlier) > 1 else [])
                ]
            adjusted = _adjusted_energy(energy, loudness)
            unit = score_unit(relative_spread_of(adjusted), reference_spreads[key])
            scores = change_scores(adjusted, relative_spread=unit)
        if len(earlier) < reference_records and (
            scores is None or float(np.max(scores)) <= REFERENCE_ADMIT_SCORE
        ):
            admitted.append(index)
        out.append(scores)
    return out, admitted
