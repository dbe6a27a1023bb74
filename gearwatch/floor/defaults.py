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

SPIKE_FACTOR = 1.0
"""A single sample that stands this many 0.1–99.9 % quantile ranges away from the median of its
16 neighbours, while they stay close together, is a glitch (an isolated spike: about 6.5 σ for
Gaussian noise — where the neighbours' closeness asks for about 9 σ — and 2 amplitudes for a
sine); 0 turns the test off.

1.0 since 2026-11-29 (was 2.0): a gear signal's quantile range is wide (its peaks are many times
its RMS), and at 2 ranges the test missed 39 of the 254 spikes of 20 × the RMS that the detection
benchmark's project generator inserts (``benchmarks/bench_detection.py``, seeds 0–59) and 10 of
the 165 glitch days of its independent generator (seeds 0–159). A missed spike is not bridged: it
stays in the raw metrics and in the revolutions it touches. Chosen on seeds 0–59 (project) and 0–159
(independent): 215 → 252 of 254 spikes found, glitch days of the independent generator 155 → 157
of 165, no other sample flagged in their 1,540 records nor in the real wind-turbine (10) and
SpectraQuest (80 channel-records) data. Held out (``held-out-9``, seeds 90000–90199, 1,400 records
per generator): 706 → 824 of 830 spikes and 187 → 196 of 204 glitch days found, no other sample
flagged; the alarms of every default rule on that part did not change (healthy campaigns
alarmed 7 and 3 of 100, spalled ones by the day after onset 100 and 33 of 100, before and after).
The isolation test (:data:`dsp.robust.SPIKE_ISOLATION`) is unchanged, so a band-limited impulse
is still not a spike — and neither is one spike ``held-out-9`` holds whose neighbours span 0.42 of
its height (seed 90049, day 7: it lifts a healthy record's raw kurtosis from 3.8 to 6.4 and opens
a raw-kurtosis alarm; a glitch and a band-limited impulse look alike there)."""

REVOLUTION_OUTLIER_FACTOR = 4.0
"""A revolution whose residual peak or residual energy exceeds this multiple of the median over
the revolutions is dropped from the average."""

MAD_TO_SIGMA = 1.4826
"""1.4826·MAD estimates the standard deviation of Gaussian data (1/Φ⁻¹(3/4))."""

RECONCILE_MAX_FINDINGS = 4
"""Findings a reconciliation accepts at most (forward selection stops there)."""
