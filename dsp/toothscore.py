"""Per-tooth evidence with its own uncertainty, and a dimensionless per-tooth score.

The MCI well depth of a tooth (:func:`dsp.teeth.per_tooth_well_depth`) is a number in nepers
whose noise level depends on the record: the revolutions averaged, the noise-to-mesh ratio, the
transfer path. A fixed threshold in nepers (the former 0.1 Np spread floor of the alarm rule)
is therefore too strict on a noisy record and too lax on a clean one. This module measures the
noise of the evidence *from the record itself* and expresses every tooth in units of it.

Standard error: delete-a-group jackknife
----------------------------------------
The revolutions of a record are dealt into ``K`` interleaved groups (revolution ``r`` → group
``r mod K``) whose sums the pipeline keeps. Leaving group ``j`` out gives an average of
``(K−1)/K`` of the revolutions, the evidence ``d₍ⱼ₎`` is computed on it exactly as on the full
average, and

    SE(d) = √((K−1)/K · Σⱼ (d₍ⱼ₎ − d̄)²)

(the delete-a-group jackknife, Efron 1982 / Quenouille). Unlike sub-averages of ``1/K`` of the
revolutions, the leave-one-out averages have almost the noise level of the full average, so the
non-linear MCI (a log-spectrum, a median filter, a maximum over a sector) is evaluated where it
is evaluated on the record, and the jackknife's bias for such statistics stays small. The jackknife is known to
overstate the SE of non-smooth statistics (medians, maxima), and it does here, by a stable
factor: on averages of a three-harmonic mesh signal plus white noise (13–80 teeth, 24–120
revolutions, noise 0.5–6× the mesh amplitude per revolution, 150–200 records per cell) the mean
jackknife SE (K = 8) over the actual standard deviation of the evidence across independent
records was 1.38–1.47 in all 14 cells (1.60 with K = 12). :func:`jackknife_standard_error`
returns the plain jackknife; :data:`JACKKNIFE_INFLATION` divides it out where the SE is used
(:func:`evidence_standard_error`). The evidence's SD on those records was 0.045–0.049 Np
whatever the noise level: the robust MCI is amplitude-free and its inter-harmonic bins are
noise-dominated, so a record's noise sets the *spread* of healthy wells, not their depth.

Evidence
--------
``evidence`` (:func:`tooth_evidence`) is the per-tooth MCI well depth *before* the clipping at
zero that :func:`dsp.teeth.per_tooth_well_depth` applies for display: ``min(sector depth,
leading-edge drop)``. Unclipped, it varies smoothly with noise on healthy teeth, which the
jackknife needs (a clipped value sits at 0 in most leave-one-out replicates and its SE
collapses).

Score
-----
``score_k = (e_k − median_j e_j) / max(SE_k, SE_pooled)``, dimensionless:

* ``e_k − median_j e_j`` compares the tooth with the other teeth of the *same record*: an effect
  that moves every tooth's evidence together (load, speed, sensor gain, temperature, a change
  of the transfer path) is removed. The MCI itself is amplitude-free, so a gain step cancels
  already; the median over teeth also removes a common deepening of all sectors.
* ``max(SE_k, SE_pooled)`` with ``SE_pooled = median_j SE_j``: the tooth's own SE (larger on a
  tooth whose well moves from group to group) but never less than the record's typical SE — a
  jackknife SE from ``K − 1`` degrees of freedom is itself noisy and a tooth with an
  accidentally small SE must not stand out for that reason.

A tooth's standing against its *own history* is the job of the alarm rule on ``score``
(:mod:`detection.alarms`): a tooth that is always a little deeper than the others (a
manufacturing feature, a structural well) has a steady score; its baseline absorbs it and the
rule reacts to the change.

``worst_tooth`` is ``None`` unless the highest score exceeds :func:`standout_threshold`, the
level that the highest of ``Z`` pure-noise scores exceeds with probability
:data:`DEFAULT_STANDOUT_FALSE_RATE` per record (measured, see its docstring).
"""

from __future__ import annotations

from statistics import NormalDist

import numpy as np
from numpy.typing import ArrayLike, NDArray

JACKKNIFE_GROUPS = 8
"""Groups of revolutions for the jackknife SE (revolution ``r`` → group ``r mod K``).

Eight leaves 7 degrees of freedom for the SE (its own relative error ≈ 1/√14 ≈ 27 %) at eight
extra MCI evaluations per channel (≈ 2 ms for an 80-tooth average); records have ≥ 20
revolutions, so each group holds at least 2."""

JACKKNIFE_INFLATION = 1.45
"""Measured ratio of the K = 8 jackknife SE of the evidence to its actual SD (module docstring)."""

DEFAULT_STANDOUT_FALSE_RATE = 0.01
"""Probability that a record of pure noise names a ``worst_tooth`` (per record and channel)."""

POOLED_SE_DEGREES_OF_FREEDOM = 21
"""Prior degrees of freedom ``d₀`` given to the record's pooled SE (:func:`moderated_standard_error`):
three times a tooth's own 7, i.e. a tooth's SE counts for a quarter."""

_SE_FLOOR_NP = 1e-6
"""Smallest SE used as a divisor (nepers): a noise-free simulated average has SE ≈ 0."""


def leave_one_out_averages(
    group_sums: ArrayLike, group_counts: ArrayLike
) -> NDArray[np.float64]:
    """Averages of all revolutions but one group's, one per group.

    Parameters
    ----------
    group_sums : array_like of float, shape (K, N)
        Sum of the revolutions of each group (``N`` samples per revolution).
    group_counts : array_like of int, shape (K,)
        Revolutions in each group; every group must hold at least one and at least two groups
        are needed.

    Returns
    -------
    ndarray of float64, shape (K, N)
        Row ``j`` is the average of every revolution not in group ``j``.

    Examples
    --------
    >>> leave_one_out_averages([[1.0, 2.0], [3.0, 4.0], [5.0, 0.0]], [1, 1, 1])
    array([[4., 2.],
           [3., 1.],
           [2., 3.]])
    """
    sums = np.asarray(group_sums, dtype=np.float64)
    counts = np.asarray(group_counts, dtype=np.float64)
    if sums.ndim != 2 or counts.shape != (sums.shape[0],):
        raise ValueError(
            f"group_sums must be (K, N) and group_counts (K,), got {sums.shape} and {counts.shape}"
        )
    if sums.shape[0] < 2 or np.any(counts < 1):
        raise ValueError("the jackknife needs at least two groups of at least one revolution")
    total = sums.sum(axis=0)
    out: NDArray[np.float64] = (total - sums) / (counts.sum() - counts)[:, np.newaxis]
    return out


def jackknife_standard_error(replicates: ArrayLike, axis: int = 0) -> NDArray[np.float64]:
    """Delete-a-group jackknife SE: ``√((K−1)/K · Σ (θ₍ⱼ₎ − θ̄)²)`` along ``axis``.

    Parameters
    ----------
    replicates : array_like of float
        The statistic computed on each of the ``K`` leave-one-group-out averages along ``axis``.
    axis : int
        Axis of the replicates (``K ≥ 2``).

    Returns
    -------
    ndarray of float64
        ``replicates`` without ``axis``.

    Examples
    --------
    >>> float(jackknife_standard_error([1.0, 2.0, 3.0]))    # √(2/3 · 2)
    1.1547005383792515
    """
    values = np.moveaxis(np.asarray(replicates, dtype=np.float64), axis, 0)
    groups = values.shape[0]
    if groups < 2:
        raise ValueError(f"the jackknife needs at least two replicates, got {groups}")
    spread = np.sum((values - values.mean(axis=0)) ** 2, axis=0)
    se: NDArray[np.float64] = np.sqrt((groups - 1) / groups * spread)
    return se


def evidence_standard_error(replicates: ArrayLike, axis: int = 0) -> NDArray[np.float64]:
    """SE of the per-tooth evidence: the jackknife SE over :data:`JACKKNIFE_INFLATION`.

    Examples
    --------
    >>> round(float(evidence_standard_error([1.0, 2.0, 3.0])), 3)
    0.796
    """
    se: NDArray[np.float64] = jackknife_standard_error(replicates, axis=axis) / JACKKNIFE_INFLATION
    return se


def moderated_standard_error(evidence_se: ArrayLike) -> NDArray[np.float64]:
    """Each tooth's SE shrunk towards the record's typical SE (empirical Bayes).

    ``SE_mod² = (d₀·SE_pooled² + d·SE_k²)/(d₀ + d)`` with ``d = K − 1`` degrees of freedom of a
    tooth's jackknife SE, ``SE_pooled = median_j SE_j`` and ``d₀ =``
    :data:`POOLED_SE_DEGREES_OF_FREEDOM` (the moderated t of Smyth 2004, "limma"). A jackknife
    SE from 8 groups has ~27 % relative sampling error, and on a tooth with a deep steady well
    (a manufacturing feature) it was seen to vary 5× from day to day on the same tooth; shrunk,
    it varies far less, while a tooth whose evidence truly jumps between groups (one glitch
    sample in one revolution) keeps an SE of the order of its evidence (√(7/28) of it).

    Examples
    --------
    >>> moderated_standard_error([0.1, 0.1, 0.1, 1.0]).round(3)
    array([0.1  , 0.1  , 0.1  , 0.507])
    """
    se = np.asarray(evidence_se, dtype=np.float64)
    pooled = np.nanmedian(se, axis=-1, keepdims=True)
    own = np.where(np.isfinite(se), se, pooled)
    d = JACKKNIFE_GROUPS - 1
    d0 = POOLED_SE_DEGREES_OF_FREEDOM
    moderated: NDArray[np.float64] = np.sqrt((d0 * pooled**2 + d * own**2) / (d0 + d))
    return moderated


def tooth_scores(evidence: ArrayLike, evidence_se: ArrayLike) -> NDArray[np.float64]:
    """Dimensionless per-tooth score: standing against the other teeth in SE units.

    Parameters
    ----------
    evidence : array_like of float, shape (..., Z)
        Per-tooth evidence (larger = worse), e.g. :func:`dsp.teeth.per_tooth_evidence`.
    evidence_se : array_like of float, shape (..., Z)
        Its standard error (e.g. :func:`evidence_standard_error`); NaN = unknown (the pooled SE
        is used).

    Returns
    -------
    ndarray of float64, shape (..., Z)
        ``(e_k − median_j e_j) / max(SE_mod,k, 1e-6)`` (:func:`moderated_standard_error`).
        About N(0, 1) (0.86 SD measured) for every tooth of a healthy record.

    Examples
    --------
    >>> tooth_scores([0.1, 0.0, 1.2, 0.05, -0.02], [0.1, 0.1, 0.2, 0.1, 0.1]).round(2)
    array([ 0.5 , -0.5 ,  8.69,  0.  , -0.7 ])
    """
    values = np.asarray(evidence, dtype=np.float64)
    se = np.asarray(evidence_se, dtype=np.float64)
    if values.shape != se.shape or values.ndim == 0 or values.shape[-1] == 0:
        raise ValueError(
            f"evidence and evidence_se must have the same non-empty shape, got {values.shape}"
            f" and {se.shape}"
        )
    centre = np.median(values, axis=-1, keepdims=True)
    divisor = np.fmax(moderated_standard_error(se), _SE_FLOOR_NP)
    scores: NDArray[np.float64] = (values - centre) / divisor
    return scores


def standout_threshold(
    pinion_teeth: int, false_rate: float = DEFAULT_STANDOUT_FALSE_RATE
) -> float:
    """Score the highest of ``Z`` healthy teeth exceeds with probability about ``false_rate``.

    The Šidák level for ``Z`` standard normal scores, ``Φ⁻¹((1 − α)^{1/Z})``. Measured on the
    mesh-plus-noise records of the module docstring (scores with :func:`evidence_standard_error`):
    the 99th percentile of the highest score was 2.4–3.2 against this level's 3.29 (Z = 20) and
    3.48 (Z = 40), so the real false rate is below ``false_rate`` (0 of 1000 records above it).

    Parameters
    ----------
    pinion_teeth : int
        Number of scores compared (``Z ≥ 1``).
    false_rate : float
        Per-record probability, in (0, 1).

    Returns
    -------
    float

    Examples
    --------
    >>> round(standout_threshold(20), 2)
    3.29
    """
    teeth = int(pinion_teeth)
    if teeth < 1 or not 0.0 < false_rate < 1.0:
        raise ValueError("pinion_teeth must be ≥ 1 and false_rate in (0, 1)")
    per_tooth = 1.0 - (1.0 - false_rate) ** (1.0 / teeth)
    # the standard library's inverse normal CDF: importing scipy.stats costs 0.6 s per process
    return float(NormalDist().inv_cdf(1.0 - per_tooth))


def standout_tooth(
    scores: ArrayLike, threshold: float
) -> int | None:
    """1-based tooth with the highest score if it exceeds ``threshold``, else ``None``.

    Examples
    --------
    >>> standout_tooth([0.3, 7.0, -1.0], 6.0), standout_tooth([0.3, 2.0, -1.0], 6.0)
    (2, None)
    """
    values = np.asarray(scores, dtype=np.float64)
    if values.ndim != 1 or values.size == 0:
        raise ValueError(f"scores must be a non-empty 1-D array, got shape {values.shape}")
    if not np.any(np.isfinite(values)):
        return None
    best = int(np.nanargmax(values))
    return best + 1 if values[best] > threshold else None


def revolution_group_sums(
    revolutions: ArrayLike, groups: int = JACKKNIFE_GROUPS, first: int = 0
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Sums and counts of the interleaved groups of revolutions (revolution ``r`` → ``(first + r) mod K``).

    Parameters
    ----------
    revolutions : array_like of float, shape (R, N)
        One revolution per row.
    groups : int
        ``K``.
    first : int
        The record's number of the first row (a block of a longer record).

    Returns
    -------
    sums : ndarray of float64, shape (K, N)
    counts : ndarray of int64, shape (K,)

    Examples
    --------
    >>> sums, counts = revolution_group_sums([[1.0], [2.0], [3.0]], groups=2)
    >>> sums.ravel().tolist(), counts.tolist()
    ([4.0, 2.0], [2, 1])
    >>> sums, counts = revolution_group_sums([[1.0], [2.0], [3.0]], groups=2, first=1)
    >>> sums.ravel().tolist(), counts.tolist()
    ([2.0, 4.0], [1, 2])
    """
    rows = np.asarray(revolutions, dtype=np.float64)
    if rows.ndim != 2:
        raise ValueError(f"revolutions must be (R, N), got shape {rows.shape}")
    groups = int(groups)
    sums = np.zeros((groups, rows.shape[1]))
    # one strided sum of rows per group: no copy of the revolutions (np.add.at row by row was
    # ~20× slower, a padded copy one more pass over them)
    for j in range(min(groups, rows.shape[0])):
        sums[(first + j) % groups] = rows[j::groups].sum(axis=0)
    counts = np.bincount((first + np.arange(rows.shape[0])) % groups, minlength=groups)
    return sums, counts.astype(np.int64)
