"""Defaults used by more than one room, each defined once (the rooms import them from here).

A default used by a single module stays in that module; this file holds the ones that the
command line, the REST schemas, the pipeline, the reconciliation and the numerical core must
agree on.
"""

from __future__ import annotations

SAMPLES_PER_MESH = 64
"""Samples per mesh period of the angle-resampled averages (El Badaoui et al. 2001 use 64,
with a 64-sample MCI window); samples per pinion revolution = pinion teeth × this."""

MIN_SAMPLES_PER_MESH = 8
"""Fewer samples per mesh period cannot resolve the mesh harmonics the MCI and the
reconciliation need; every entry point refuses them."""

MAX_SAMPLES_PER_MESH = 1024
"""Upper bound accepted over REST (memory of the averages grows with it)."""

SAMPLES_PER_REV_WITHOUT_TEETH = 1024
"""Samples per revolution when the rig declares no tooth counts."""

MIN_REVOLUTIONS = 20
"""A record with fewer whole revolutions of the tach shaft is refused."""

MAX_SPEED_VARIATION = 0.5
"""Largest accepted (max − min)/mean of the per-revolution speed within a record. Order tracking
resamples slow drift exactly (±20 % drift is (max − min)/mean = 0.4); beyond about ±25 % the
average mixes operating points too far apart to be one condition of the machine, and the
anti-alias band (set by the lowest speed) cuts the orders of the fastest revolutions."""

GLITCH_RANGE_FACTOR = 5.0
"""A sample beyond the 0.1–99.9 % quantile range widened this many times on each side is a glitch."""

SPIKE_FACTOR = 2.0
"""A single sample that stands this many 0.1–99.9 % quantile ranges away from the median of its
four neighbours, while they stay close to that median, is a glitch (an isolated spike: about
13 σ for Gaussian noise, 4 amplitudes for a sine); 0 turns the test off."""

REVOLUTION_OUTLIER_FACTOR = 4.0
"""A revolution whose residual peak or residual energy exceeds this multiple of the median over
the revolutions is dropped from the average."""

MAD_TO_SIGMA = 1.4826
"""1.4826·MAD estimates the standard deviation of Gaussian data (1/Φ⁻¹(3/4))."""

RECONCILE_MAX_FINDINGS = 4
"""Findings a reconciliation accepts at most (forward selection stops there)."""
