"""Detection benchmark: how early, on which tooth, and how often falsely each method alarms.

Run: ``nice -n 10 .venv/bin/python benchmarks/bench_detection.py [--quick] [--part tune|held-out]
[--generator project|independent|both] [--workers 2]``.

What runs
---------
The **same per-record pipeline and alarm evaluation as the replay path, in-process**:
:func:`gearwatch.usecases.analyze.analyze_record` on every daily record (no file, no database), then
:func:`detection.alarms.step` per (rule, tooth) in day order exactly as
:func:`storage.evaluation.evaluate_record` does. The database/REST layers add nothing to the
detection and would cost minutes per campaign on a loaded 2-core machine.

Evaluation set
--------------
Each campaign is drawn from its seed (fixed seed ranges, below): pinion teeth 13–80 and a random
ratio (gear teeth 1.05–3.5× the pinion's), contact ratio 1.3–2.0 (pressure angle and addendum
solved for it), noise 0.3–3× the clean signal's rms, slow speed drift within a record (±4 %; the
independent generator draws its own, 0–20 %), day-to-day load ±10 % and speed ±5 %, a sensor gain
step (×0.5–2) from a random day on, glitch samples (1–3 samples at ±20× rms in 30 % of records),
structural modes drawn per campaign (a second mode always present), sensor direction (line of
action, or off the line with sliding friction), 7 daily records, onset on day 4 or 5 for spalled
campaigns, the spall starting at 3–6 µm and doubling each day up to 25 µm, its extent 0.1–0.6 of
the path of contact. Records hold ≥ 30 pinion revolutions (mesh frequency 300–700 Hz;
``--revolutions N`` for the record-length study below). Generated records are cached under
``/tmp/gw-eval/`` as npz.

Parts (never mixed; even seeds spalled, odd healthy): ``tune`` = seeds 0–59 and ``tune-2`` =
60–159, used while choosing the rule settings; ``held-out`` = 10000–10199, ``held-out-2`` =
20000–20199, ``held-out-3`` = 30000–30199, ``held-out-4`` = 40000–40199, ``held-out-5`` =
50000–50199, ``held-out-6`` = 60000–60199, ``held-out-7`` = 70000–70199, ``held-out-8`` =
80000–80199, ``held-out-9`` = 90000–90199, ``held-out-10`` = 100000–100199 (its first 60 seeds
spent at 150 revolutions) and ``held-out-11`` = 110000–110199 (spent at 30 revolutions, in two
halves), each run for a report once and then spent (see
below which version each one measured; the ``held-out`` and ``held-out-2`` reports used their
first 100 seeds, ``--limit 100``). ``--quick`` takes the first 12 campaigns of the part.

Methods (rule settings in :func:`_methods`): the new per-tooth detector ``tooth change``
(:mod:`dsp.toothchange`, the ``change`` rule of :data:`detection.default_rules.DEFAULT_RULES`,
computed from the days' averages exactly as :mod:`gearwatch.usecases.tooth_change` does from the
database); the per-tooth ``score`` (MCI evidence in its own standard errors, with its rule);
today's MCI rule (``mci_depth``, 0.1 Np floor, warning 4, persistence 2 — with its 8-record
baseline it could never alarm in 7 days, so it gets 3); FM4, NA4, kurtosis of the average, raw
kurtosis and per-tooth difference energy with the whole-record statistic (short-campaign
baseline + CUSUM: the classic metrics get the same statistics as the per-tooth ones, so the
comparison is of evidence, not of alarm logic), each with its default rule's settings; NA4 as
the database stores it (divided by the earlier records' mean residual variance, rebuilt from each
day's ``baseline_stats``: ``NA4 (stored, disabled)``) beside the residual's kurtosis (NA4 of the
record alone, the default rule since 2026-11-28); and ``every enabled default rule`` — what an
operator of a new rig gets, per tooth and whole record together. "Earlier than every classic
metric" compares with FM4, the residual's kurtosis, kurtosis and raw kurtosis (difference energy
alarms in nearly every healthy campaign: its first alarms are not detections).

Tried 2026-12-08 (offline, ``tune`` + ``tune-2`` of the independent generator, the ``change``
rule alone; not adopted): a **reference predicted at the record's speed** — per order, the mean
of the reference records plus a slope in the day's relative speed fitted over them (least squares,
shrunk by 0.002 or not, smoothed over ±4 or ±16 orders), so that what a ±5 % speed change does to
the path would not count as change. By the day after onset 11 → 11 of 30 (``tune``) and 19 →
17–18 of 50 (``tune-2``), healthy campaigns alarmed 0 → 0–2 of 30 and 0 → 0 of 50. Three to
eight reference records cannot fit a slope per order well enough; the day's speed is not what
holds the independent generator's spalls under the threshold (the spalled tooth's ``change`` the
day after onset: median 3.2, against a 99th percentile of 3.8 for the highest tooth of a healthy
day, 366 healthy days; ``tune`` + ``tune-2``).

Measured 2026-11-29 (fourth session): **the whole-record rules' CUSUM waits longer** (h = 5 for
FM4, the residual's kurtosis and the kurtosis of the average; raw kurtosis keeps h = 3.5;
:mod:`detection.default_rules` has the study). The per-tooth rules are unchanged. Every healthy
campaign's whole-record alarm on ``tune`` + ``tune-2`` had come from the CUSUM. Chosen there
(offline, from the stored per-record values), then checked on ``held-out-9`` (seeds
90000–90199, never used for a whole-record rule) and the unspent half of ``held-out-11`` (seeds
110100–110199), each run once; the rules before and after on the same stored values, "every
enabled default rule" (what an operator gets):

    part                 generator      healthy alarmed    onset day      by +1
    held-out-9           project        12 → 7 of 100      100 → 100      100 → 100
                         independent     6 → 3 of 100       16 → 16        35 → 33
    held-out-11 (2nd)    project         0 → 0 of 50        48 → 48        48 → 48
                         independent     1 → 1 of 50         5 → 5         12 → 12

The classic rows of the tables below (FM4, the residual's kurtosis, kurtosis, raw kurtosis)
are scored with each rule's default settings, so from this revision on they alarm a little later
than in the tables measured before it: FM4 alone by the day after onset on ``held-out-9``, 99 → 99
of 100 (project) and 14 → 11 (independent). Comparisons of "per-tooth rules against the best
classic metric" made before and after it are not like for like.

The second half of ``held-out-11`` had never been run: it also holds out the ``change`` score of
the third session below (cube root, pooled unit), unchanged since. Per-tooth rules, run once::

    held-out-11, seeds 110100–110199   ≤onset   ≤+1   ≤+2   never   exact   healthy w/ FA
    project                             94%     96%   98%     2%     94%      0/50
    independent                         10%     24%   66%    24%     66%      0/50

On the independent half no method saw more by the day after onset ("per-tooth rules or a
classic metric": 24 %, all of it the per-tooth rules'); the per-tooth rules were later than the
best classic metric in 6 % of the spalled campaigns.

Measured 2026-11-29 (third session): **the ``change`` score in the cube root of the energy**
(:mod:`dsp.toothchange`, step 5: a χ² is close to normal in its cube root for any degrees of
freedom, in its log only for many — a fast rig sampled at 10× its mesh frequency has ~10 per
sector, and a warning at 5 asked it for nearly twice the energy its noise calls for), its unit pooled
with the reference records' when the record's own is smaller, and the loudness discount (step 6)
measured from the quieter half of the teeth. Chosen offline on ``tune`` + ``tune-2`` (numbers in
the module docstring). Then run once on a part generated after that choice, ``held-out-11``
(seeds 110000–110099, 30 revolutions), with the previous ``change`` (``95cc41c``, recomputed from
the same runs' saved averages) and this one, the rest of the table unchanged::

    held-out-11, per-tooth rules     ≤onset    ≤+1   never  exact  FA/1k  healthy w/ FA  later than best classic
    independent  previous             16%      30%    44%    46%   0.77      0/50               16%
                 this                 20%      38%    32%    54%   1.09      0/50                6%
    project      previous             88%      98%     2%    96%   3.21      0/50                8%
                 this                 96%      98%     0%    98%   3.77      0/50                2%

    independent, this revision (full table)
    method                    ≤onset    ≤+1    ≤+2  never median  exact   only   FA/1k healthy w/ FA
    tooth change (new)           20%    38%    56%    32%    1.0    54%    42%    1.06      0/50
    per-tooth score               4%     8%    14%    86%    1.0    12%    10%    0.06      0/50
    non-sync power                4%     8%    18%    78%    2.0    12%     8%    0.64      0/50
    per-tooth rules              20%    38%    56%    32%    1.0    54%    42%    1.09      0/50
    FM4                          10%    24%    46%    42%    2.0   nan%   nan%    0.00      0/50
    residual kurtosis            10%    26%    46%    40%    2.0   nan%   nan%    0.00      0/50
    kurtosis                      2%     4%    10%    86%    2.0   nan%   nan%    1.88      1/50
    raw kurtosis                  0%     6%     8%    86%    2.0   nan%   nan%    0.00      0/50
    every enabled default rule   20%    42%    58%    30%    1.0   nan%   nan%    1.88      1/50
    per-tooth rules earlier than every classic metric: 32%; same day or earlier: 94%; later: 6%
    per-tooth rules or a classic metric: by the day after onset 42 %, ever 70 %; per-tooth rules
    by the day after onset in 90 % of those seen by then

The FA/1k that rose counts openings on other teeth of spalled campaigns (mostly after onset, as
the spall grows to 25 µm); no healthy campaign alarmed per tooth on either generator. The last
line is new in the report: on the independent generator at 30 revolutions, 30 % of the spalled
campaigns are seen by *no* method within the 7 days, and 58 % by none by the day after onset —
the issue's 95 % is not there to be found in these records by any metric this project has. On
``tune`` (independent) those unseen campaigns are mostly rigs whose mesh frequency is above 1 kHz
(records of ~1 s, 11 samples per mesh period at 20 kHz). Also tried on ``tune`` (offline) and not
adopted: predictive deconvolution of the change signal (a prediction-error filter of order 4–32
from its own autocorrelation, to undo a ringing path's minimum-phase part before the sector
energy: by the day after onset 11 → 13–18 of 30, but 5–10 of 30 healthy campaigns alarmed; with
the filter shrunk towards identity, 8–10 of 30), the sector lag set per rig from the generator's
*true* path delay (an oracle: 8–11 of 30, no gain — the pure delay is not what misplaces the
energy), a rule on a tooth that leads two days running at ≥ 2–3.5 (no earlier detection), and an
Eckart weighting of the orders by the reference signature's spectrum (22 → 27 of 80 on ``tune`` +
``tune-2``, fewer right teeth: 38 of 49 → 35 of 48; the cube root gave more; on top of the cube
root, 2 healthy project campaigns alarmed). With the cube root, on ``tune`` + ``tune-2`` (30 of
80 by the day after onset): sectors two pitches wide, 29 and the right tooth far less often; the
central half or three quarters of each sector, 21 and 27; ``nonsync_z`` added to the score
(weights 0.5 and 1), 30 and 26, with 4 healthy campaigns alarmed at 1. A per-tooth average of
the residual locked in *time* to each tooth's mesh instant (to recover a ring that a drifting
speed smears in angle), tried on 12 ``tune`` campaigns: the spalled tooth stood out only on the
last day in 2 of 6, healthy records reached 3–20.

Measured 2026-11-29 (later session): **a drifting speed within a record delays the per-tooth
alarms**, and a witness for it. On 24 stress campaigns of ``physics.independent.random_campaign``
(seeds 9936–9959, 10-s records, whose speed drifts by 0–20 % — up to a 45 % range — within each
record), the per-tooth alarm came 1–2 days after FM4 / the residual's kurtosis in three spalled
campaigns, all with a large in-record drift (34 %, 18 %, 21 % ranges); the same campaigns with the
drift set to 0 (same rig, days and noise) alarmed per tooth on days 4, 5, 6 instead of 6, 7, 6.
The benchmark's own independent part says the same by drift bin (``tune`` + ``tune-2``, 30
revolutions; per-tooth rules by the day after onset): drift < 7 % 41 % (29 spalled), 7–14 % 12 %
(26), ≥ 14 % 28 % (25); ``tune`` at ``--revolutions 150``: 70 %, 18 %, 56 % (10, 11, 9 spalled).

A ring in time lands at other angles in every revolution when the speed drifts, so the average
loses it; its power stays in the revolutions about the average. ``nonsync_z``
(:mod:`dsp.nonsync`) stores that power per tooth sector as a robust z over the record's teeth
(known answers: ``tests/dsp/test_nonsync.py``, ``tests/gearwatch/test_nonsync_drift.py``). Its
rule (``score``'s settings, spread floor 0.7; chosen on the stress seeds above and on ``tune`` /
``tune-2``: no healthy campaign of 148 alarmed, the first per-tooth alarm a day earlier in 2 of 16
spalled stress campaigns) was then run once on 40 fresh stress campaigns (seeds 9960–9999, 14
healthy, 26 spalled): no healthy campaign alarmed; it brought two first per-tooth alarms forward
by a day (9968, 9995) but on teeth 7–8 and 4–6 pitches after the spalled one, and added late-tooth
alarms beside right ones in two more (9964, 9992) — the average keeps a long ring's first cycles,
what it loses peaks later. The rule is therefore **created disabled**; the indicator is stored.
At ``--revolutions 150`` (``tune``, independent): ``non-sync power`` alone 3 % / 17 % by onset /
+1, no healthy alarm, no detection the other per-tooth rules lacked.

``held-out-10`` (seeds 100000–100059, generated after every choice above, run once; independent
generator, ``--revolutions 150 --limit 60``), the operator's rules with ``nonsync_z`` off::

    method                    ≤onset    ≤+1    ≤+2  never median  exact   only   FA/1k healthy w/ FA
    tooth change (new)           27%    40%    53%    40%    1.0    47%    33%    1.29      1/30
    per-tooth score               3%    13%    23%    70%    2.0    27%    17%    0.40      1/30
    non-sync power                3%    13%    27%    57%    2.0    27%    27%    0.55      0/30
    per-tooth rules              27%    43%    57%    37%    1.0    47%    33%    1.59      2/30
    FM4                           7%    30%    50%    40%    1.5   nan%   nan%    0.00      0/30
    residual kurtosis            10%    23%    47%    43%    2.0   nan%   nan%    0.00      0/30
    kurtosis                      3%     3%     7%    80%    3.0   nan%   nan%    0.00      0/30
    raw kurtosis                  0%     3%     7%    83%    3.0   nan%   nan%    0.00      0/30
    every enabled default rule   27%    43%    70%    30%    1.0   nan%   nan%    9.52      2/30
    per-tooth rules earlier than every classic metric: 37%; same day or earlier: 87%; later: 13%

(``tune`` at 150 revolutions, for comparison: per-tooth rules 23 % / 47 %, right tooth 60 %, no
healthy campaign alarmed; FM4 13 % / 27 %.) The issue's targets are not met at 150 revolutions
either; the per-tooth rules are as early as the best classic metric or earlier in 87 % of the
spalled campaigns.

Also tried on ``tune`` (offline, on the saved per-day values) and not adopted: a joint rule on a
tooth whose ``change`` and ``score`` both stand above a level (their minimum ≥ 3: no detection
added on either generator; their sum ≥ 4: 1 of 30 healthy alarmed for 1 detection); the change
rule's CUSUM over k = 1–2.5, h = 2–8 (every setting that detected earlier than today's raised a
healthy alarm on one of the generators — k = 2, h = 2: one more onset-day detection of 30 on the
project's, one healthy campaign alarmed of 30 on the independent one — and the others detected no
earlier); naming a tooth on the day a whole-record rule opens (the ``change``
leader when ≥ 2–3.5 and 1–2× the runner-up: at most one detection added at the price of a healthy
alarm).

Measured 2026-11-29. **Kept:** ``raw_kurtosis`` is the mean of the record's 16 time spans'
kurtoses (:func:`gearwatch.usecases.signal_checks._raw_metrics`; chosen on stress campaigns of
``physics.independent.random_campaign``, held out on others). **Tried and reverted:** the
per-tooth ``change`` also scoring runs of 2 and 4 consecutive sectors, each run's score given to
its loudest tooth, less 0.5 per doubling of the width (a path that rings spreads a spall's
transient over the next sectors). Offline on every day's pinion average computed as here (the
``change`` rule alone; campaigns per generator; "by +1" = alarmed by the day after onset):

    ``change`` rule alone              independent: by +1, exact, healthy w/ FA   project: onset, healthy w/ FA
    tune + tune-2 (0–159), one tooth   22 / 80, 45, 0 / 80                      75 / 80, 0 / 80
      … runs of 1, 2, 4                25 / 80, 48, 0 / 80                      75 / 80, 0 / 80
    held-out-8 (80000–80199), 30 rev   27 / 100, 57, 1 / 100                    91 / 100, 3 / 100
      … runs of 1, 2, 4                35 / 100, 55, 2 / 100                    96 / 100, 4 / 100
      … runs only on wheels ≥ 8 runs   (chosen on all of the above: 360 campaigns, 57 v 49 by +1
                                        of 180, healthy 1 v 1; project 168 v 166, healthy 3 v 3)
    held-out-9 (90000–90199), 30 rev   29 / 100, 57, 0 / 100                    89 / 100, 2 / 100
      … runs on wheels ≥ 8 runs        31 / 100, 61, 1 / 100                    90 / 100, 6 / 100

On the part generated after the last choice (``held-out-9``) the runs bought 2 and 1 earlier
detections in 100 for 1 and 4 more healthy campaigns alarmed: reverted. What the runs see is
real — the spalled tooth's energy does spread over the next sectors on rigs with many teeth —
but the best of several widths is also a larger number under noise, and the rule's CUSUM adds up
every excess over 2.5.

``held-out-8`` at 30 revolutions (seeds 80000–80199; its first 40 / 20 seeds had been spent at 300
revolutions only) was run through this benchmark with the previous code (``647cb4c``, a worktree
on ``PYTHONPATH``) and with the runs of teeth and the span-mean raw kurtosis together, same cached
records: raw kurtosis's healthy campaigns with an alarm 3 → 3 (project) and 5 → 2
(independent), detections by the day after onset 72 → 73 % and 1 → 2 %. ``held-out-9``, run
with the previous code and with this revision (the span-mean raw kurtosis alone):

    held-out-9, 30 rev, previous → this       project                      independent
    raw kurtosis ≤onset / ≤+1; healthy w/ FA   65 / 80 → 63 / 80 %; 3 → 4     1 / 1 → 0 / 0 %; 3 → 2
    every enabled default rule ≤+1; healthy    100 → 100 %; 11 → 12 of 100   32 → 31 %; 6 → 6 of 100
    per-tooth rules (unchanged)               98 / 100 % ≤onset / ≤+1, exact 96 %, 2 / 100 healthy
                                              independent 11 / 29 %, exact 51 %, 0 / 100 healthy

    this revision, full table (project, then independent)
    method                    ≤onset    ≤+1    ≤+2  never median  exact   only   FA/1k healthy w/ FA
    tooth change (new)           89%    93%    97%     3%    0.0    94%    22%    2.62      2/100
    per-tooth score              76%    88%    94%     3%    0.0    93%    84%    0.58      0/100
    both per-tooth rules         98%   100%   100%     0%    0.0    96%    23%    3.08      2/100
    FM4                          96%    99%   100%     0%    0.0   nan%   nan%    1.90      2/100
    residual kurtosis            97%    99%   100%     0%    0.0   nan%   nan%    5.71      6/100
    kurtosis                     70%    86%    88%    10%    0.0   nan%   nan%    1.90      2/100
    raw kurtosis                 63%    80%    85%    13%    0.0   nan%   nan%    3.81      4/100
    every enabled default rule   99%   100%   100%     0%    0.0   nan%   nan%   15.24     12/100
    tooth change (new)           11%    29%    51%    41%    2.0    51%    41%    0.94      0/100
    per-tooth score               0%     5%    13%    79%    2.0    20%    19%    0.03      0/100
    both per-tooth rules         11%    29%    51%    41%    2.0    51%    41%    0.96      0/100
    FM4                           4%    14%    39%    50%    2.0   nan%   nan%    1.91      2/100
    residual kurtosis             4%    17%    41%    51%    2.0   nan%   nan%    1.91      2/100
    kurtosis                      0%     0%     3%    82%    3.0   nan%   nan%    0.95      1/100
    raw kurtosis                  0%     0%     5%    88%    3.0   nan%   nan%    2.86      2/100
    every enabled default rule   11%    31%    56%    36%    2.0   nan%   nan%    7.63      6/100

What it says: the span-mean raw kurtosis is a wash on the benchmark's 30-revolution records
(held-out-8 and -9 together: healthy campaigns with a raw-kurtosis alarm 6 → 7 of 200 on the
project simulator, 8 → 4 of 200 on the independent one), and removes the false alarms that a speed
swept through a resonance raises (the stress campaigns). On held-out-9 the operator's view alarms
in 12 (project) and 6 (independent) of 100 healthy campaigns — mostly the whole-record rules
(residual kurtosis alone 6 on the project simulator); the per-tooth rules in 2 and 0. The issue's
targets stay unmet on the independent simulator (29 % by the day after onset) and for false alarms.

Measured 2026-11-28 (a later session), the ``score`` rule with the teeth's pooled day-to-day
spread (:func:`detection.alarms.pooled_spread`; ``--no-pooled-spread`` scores the same saved
results without it). Long records (``--revolutions 300``), ``held-out-8`` (seeds 80000–80039,
generated fresh; independent 80000–80019), healthy campaigns with an alarm of the per-tooth
rules, and their detections by the day after onset, without → with::

    project, 20 spalled + 20 healthy          healthy w/ FA   by onset + 1
    per-tooth score                             4/20 → 0/20    100 → 95 %
    both per-tooth rules                        4/20 → 0/20    100 → 100 %
    every enabled default rule                  4/20 → 0/20    100 → 100 %
    independent, 10 + 10
    per-tooth score                             0/10 → 0/10     20 → 10 %
    both per-tooth rules                        1/10 → 1/10     70 → 70 %

At 30 revolutions (``held-out-7``, seeds 70100–70199, 50 + 50 per generator) nothing an operator
sees moved: both per-tooth rules 2/50 and 1/50 healthy alarmed both ways (the ``change``
rule's), 100 % and 32 % by the day after onset both ways. The development parts and the study:
:data:`detection.default_rules.DEFAULT_RULES`' note "Long records".

Measured 2026-11-28 (third session), ``held-out-6`` (seeds 60000–60199, generated fresh), what
an operator gets. Two changes: a lone ADC spike (one sample ~13 σ from its neighbours, which stay
close together) is now a glitch, bridged before the raw metrics (:func:`dsp.robust.find_spikes`;
chosen from the physics of band-limited signals, no seed looked at but two of ``held-out-4``);
and the whole-record default rules (:data:`detection.default_rules.WHOLE_RECORD_RULE`'s note:
chosen on this part's project campaigns, checked once on its independent ones). Before that,
the benchmark had scored NA4 as ``analyze_record`` returns it without history, i.e. the
residual's kurtosis, not as stored. Run with the previous code (``a769613``) and with this
revision on the same records; "healthy w/ FA" of every enabled default rule is the figure that
matters to an operator::

    held-out-6                                project: previous → now       independent: previous → now
    raw kurtosis, healthy w/ FA               71 → 1                        14 → 3
    NA4 as stored (rule now disabled)         30                            24–25
    kurtosis of the average                   11 → 1                        9 → 1
    FM4                                       2 → 0                         5 → 2
    residual kurtosis (the new NA4 rule)      – → 0                         – → 1
    both per-tooth rules                      1 → 1                         0 → 0
    every enabled default rule, healthy w/ FA 79 → 3                        47 → 6
      … spalled, first alarm ≤ onset / ≤ +1   99 % / 99 % → 97 % / 98 %     38 % / 55 % → 20 % / 31 %

    this revision, independent generator, held-out-6
    method                    ≤onset    ≤+1    ≤+2  never median  exact   only   FA/1k healthy w/ FA
    tooth change (new)           17%    29%    45%    49%    1.0    45%    35%    0.92      0/100
    per-tooth score               3%     7%    15%    75%    2.0    20%    20%    0.13      0/100
    both per-tooth rules         17%    29%    45%    48%    1.0    45%    35%    1.03      0/100
    FM4                           8%    16%    43%    50%    2.0   nan%   nan%    1.91      2/100
    residual kurtosis             6%    18%    39%    49%    2.0   nan%   nan%    0.96      1/100
    NA4 (stored, disabled)       22%    36%    52%    36%    1.0   nan%   nan%   28.68     25/100
    kurtosis                      0%     1%     7%    77%    3.0   nan%   nan%    0.96      1/100
    raw kurtosis                  1%     2%     6%    81%    3.0   nan%   nan%    3.82      3/100
    every enabled default rule   20%    31%    52%    40%    1.0   nan%   nan%    7.65      6/100
    both per-tooth rules earlier than every classic metric: 24%; same day or earlier: 85%; later: 15%

    this revision, project simulator, held-out-6
    tooth change (new)           91%    96%    96%     4%    0.0    91%    17%    2.68      0/100
    per-tooth score              67%    85%    90%     9%    0.0    77%    63%    0.88      1/100
    both per-tooth rules         93%    98%    98%     2%    0.0    93%    15%    3.32      1/100
    FM4                          89%    92%    95%     4%    0.0   nan%   nan%    0.96      0/100
    residual kurtosis            91%    93%    95%     4%    0.0   nan%   nan%    0.96      0/100
    NA4 (stored, disabled)       88%    90%    94%     6%    0.0   nan%   nan%   31.55     30/100
    kurtosis                     63%    86%    87%    13%    0.0   nan%   nan%    0.96      1/100
    raw kurtosis                 46%    71%    81%    18%    0.0   nan%   nan%    0.96      1/100
    every enabled default rule   97%    98%    98%     2%    0.0   nan%   nan%    5.74      3/100
    both per-tooth rules earlier than every classic metric: 5%; same day or earlier: 96%; later: 4%

What it says. The per-tooth rules did not change (the same openings on every campaign); the
operator's false alarms came from the whole-record rules — raw kurtosis lifted by single spikes
the range test let through (a 20 σ sample in a 60 000-sample record adds 2.7 to it), the stored
NA4 jumping by the gain⁴ at a gain step, the average's kurtosis moved by a day's operating point.
With both changes, 3 and 6 healthy campaigns of 100 alarm on anything (target: 0 — not met), and
an operator loses the early whole-record alarms that came, in spalled and healthy campaigns
alike, from rules that alarmed in half of the healthy ones. The per-tooth targets are as before:
met on the project simulator for earliness and the tooth (onset day 93 %, by the next 98 %, right
tooth 93 % — the tooth short of 95 % on this part), not on the independent one (17 % / 29 %).

Measured 2026-11-28, 2-core machine, after two choices made on ``tune`` + ``tune-2`` only (seeds
0–159, offline on every day's stored pinion average): the change **weights each order by the
inverse of its scatter among the reference records** (:func:`dsp.toothchange.order_weights`), and
the ``score`` rule became the strict companion of ``change`` (warning 5, CUSUM k = 3;
:data:`detection.default_rules.DEFAULT_RULES`). ``held-out-4`` (seeds 40000–40199) was generated
after both were fixed and run once with them — the part to read — and once with the previous
code (``8c244ca``) on the same records::

    project simulator, held-out-4, this revision (never looked at while choosing)
    method                    ≤onset    ≤+1    ≤+2  never median  exact   only   FA/1k healthy w/ FA
    tooth change (new)           87%    94%    95%     4%    0.0    95%    27%    2.65      0/100
    per-tooth score              59%    83%    89%    10%    0.0    81%    70%    0.74      2/100
    both per-tooth rules         97%   100%   100%     0%    0.0    99%    26%    3.19      2/100
    today's MCI rule              0%    66%    84%    16%    1.0    81%    71%    0.29      0/100
    FM4                          93%    97%    97%     2%    0.0   nan%   nan%    1.92      2/100
    NA4                          93%    99%    99%     1%    0.0   nan%   nan%    2.88      3/100
    kurtosis                     67%    84%    91%     8%    0.0   nan%   nan%    5.75      6/100
    raw kurtosis                 37%    52%    63%    34%    0.0   nan%   nan%   78.62     67/100
    diff energy                  99%   100%   100%     0%    0.0    39%     3%   14.17     98/100
    both per-tooth rules earlier than every classic metric: 4% of spalled campaigns; on the same day or earlier: 98%; later than the best classic one: 2%

    project simulator, held-out-4, previous code (8c244ca), same records
    tooth change (new)           78%    86%    89%    11%    0.0    80%    23%    2.77      5/100
    per-tooth score              69%    93%    94%     5%    0.0    84%    64%    1.11      4/100
    both per-tooth rules         95%   100%   100%     0%    0.0    90%    25%    3.62      9/100

    independent generator, held-out-4, this revision (never looked at while choosing)
    method                    ≤onset    ≤+1    ≤+2  never median  exact   only   FA/1k healthy w/ FA
    tooth change (new)            9%    19%    34%    49%    2.0    45%    35%    0.72      1/100
    per-tooth score               1%     2%     9%    87%    2.0    11%    11%    0.03      0/100
    both per-tooth rules          9%    20%    34%    49%    2.0    45%    35%    0.73      1/100
    today's MCI rule              0%     1%     2%    91%    3.0     6%     6%    0.05      0/100
    FM4                           7%    20%    40%    42%    2.0   nan%   nan%    0.00      0/100
    NA4                           6%    16%    38%    44%    2.0   nan%   nan%    4.79      5/100
    kurtosis                      3%     8%    12%    78%    2.0   nan%   nan%    6.71      7/100
    raw kurtosis                  5%    12%    15%    79%    1.0   nan%   nan%   16.30     17/100
    diff energy                  83%   100%   100%     0%    0.0    17%    11%   22.06     97/100
    both per-tooth rules earlier than every classic metric: 13% of spalled campaigns; on the same day or earlier: 65%; later than the best classic one: 35%

    independent generator, held-out-4, previous code (8c244ca), same records
    tooth change (new)           11%    22%    41%    46%    2.0    45%    39%    0.90      1/100
    per-tooth score               1%     7%    14%    76%    2.0    18%    17%    0.12      1/100
    both per-tooth rules         11%    23%    42%    44%    2.0    45%    39%    0.97      2/100

What it says. On the project's simulator the revision names the spalled tooth on the first alarm
day in 99 % of spalled campaigns (was 90 %; target ≥ 95 %: met), alarms on the onset day in 97 %
and by the next in 100 % (targets met), and alarmed 2 of 100 healthy campaigns (was 9; both on
``score``; ``change`` alone none, was 5; target 0: not met). On the independent generator it is
slightly **later** than the previous code: the change alone alarmed later in 18 campaigns and
earlier in 9 (same day in 73); by the day after onset 20 % (was 23 %), by the second day 34 %
(was 42 %); one healthy campaign alarmed (was 2). On ``tune`` + ``tune-2`` the same comparison
showed no loss there (by the second day 52 → 54 %). Why: that generator's pit is heard through
the path's resonance, in the same orders where the days' load and speed scatter the reference
(seed 40178: on the onset day 49 % and on the last day 82 % of the change's power lies in the
eighth of the orders that holds 47 % of the reference scatter; seed 40018: 75 % on the last day in
two eighths that hold 36 %), so weighting those orders down weakens the pit with the nuisance;
the project's pit is an impact whose change reaches orders the nuisance leaves quiet. Over all
360 campaigns per generator measured (tune, tune-2, held-out-4), the revision is +8 points by the
day after onset and +12 on the right tooth on the project generator, −3 and −3 by the first and
second day after onset on the independent one. "Earlier than every classic metric" stays 4 % /
13 % (FM4 and NA4 alarm on the onset day too on the project generator; on the independent one
every method is late). The issue's targets are met on the project's simulator for earliness and
the exact tooth, not for false alarms, and not on the independent generator.

A second part, ``held-out-5`` (seeds 50000–50199), generated after everything above and run once
with this revision and once with the previous code on the same records (nothing was changed
after it)::

    project simulator, held-out-5
    method                    ≤onset    ≤+1    ≤+2  never median  exact   only   FA/1k healthy w/ FA
    tooth change (new)           93%    97%    98%     2%    0.0    94%    20%    2.78      1/100
    per-tooth score              70%    84%    90%     9%    0.0    84%    67%    0.79      0/100
    both per-tooth rules         97%   100%   100%     0%    0.0    96%    17%    3.33      1/100
    FM4                          90%    96%    97%     3%    0.0   nan%   nan%    1.90      2/100
    NA4                          93%    98%    98%     2%    0.0   nan%   nan%    1.90      2/100
    previous code: change        85%    90%    93%     7%    0.0    87%    27%    2.73      8/100
    previous code: both          99%    99%   100%     0%    0.0    94%    31%    3.60     10/100

    independent generator, held-out-5 (1 record rejected)
    tooth change (new)           14%    25%    41%    47%    2.0    42%    34%    0.92      0/100
    per-tooth score               0%     4%     5%    92%    1.5     7%     7%    0.03      0/100
    both per-tooth rules         14%    26%    42%    47%    2.0    42%    34%    0.95      0/100
    FM4                           6%    13%    41%    45%    2.0   nan%   nan%    6.67      6/100
    NA4                           6%    13%    39%    45%    2.0   nan%   nan%    3.81      4/100
    previous code: change        14%    23%    41%    44%    2.0    40%    29%    0.94      0/100
    previous code: both          14%    25%    44%    42%    2.0    39%    29%    1.06      0/100

Paired per campaign (the ``change`` rule's first alarm): project later in 2, earlier in 12;
independent later in 13, earlier in 10 (on held-out-4: 3 / 18 and 18 / 9). So the project's
gain holds on both held-out parts (healthy campaigns alarmed 9 → 2 and 10 → 1 of 100, right tooth
90 → 99 % and 94 → 96 %); on the independent generator the loss of held-out-4 does not repeat
(by the day after onset 25 → 26 %, by the second day 44 → 42 %, right tooth 39 → 42 %), and there
the per-tooth rules are now as early as FM4 or earlier (by the day after: 26 % against 13 %).

Looked at on ``held-out-4`` *after* it was run (so that part is no longer unseen for these), and
not adopted (figures for the ``change`` rule alone): a partial weighting ``scatter^(−p/2)`` — p = 0.5 kept the independent generator
where it was (11 / 22 / 40 %) but took only part of the project's gain (onset day 84 %, by the
next 90 %, right tooth 85 %, 1 healthy of 100); p = 0.75 in between. An Eckart weighting (the
reference's own tooth-specific spectrum over the scatter): project worse than the previous code
(69 % / 80 %, right tooth 75 %, 6 healthy), independent 9 / 22 / 48 %. The larger of the white
and the Eckart scores per tooth: project 88 / 94 %, right tooth 92 %, 6 healthy; independent
13 / 27 / 50 %, 1 healthy.

Re-run 2026-11-28 (second session) on both parts, unchanged code: every figure above came out the
same. Then, with both parts spent, the three healthy-campaign alarms of the project generator were
looked at: two are ``score`` alarms raised by its CUSUM (seeds 40027 tooth 21 on day 4, score 9.6;
40091 teeth 2 and 24 on days 5 and 6, scores 6.2–9.1) while ``change`` was below 2 on those teeth
on the opening day; the third
is a ``change`` alarm (50153, tooth 8 at 5.2 on its first scored day). Dropping a ``score`` opening
when the same day's ``change`` on the tooth and its neighbours stays below 2 (offline, on the saved
per-day values) leaves 1 of 200 healthy campaigns alarmed instead of 3, with the same detections
(97 / 100 / 100 %, right tooth 98 %) on the project generator and no change on the independent
one (12 / 23 / 38 %, 44 %, 1 of 200). Not built: dropping an opening leaves the track in an
alarm state nobody sees, and holding it back instead would let seed 40027 open a day later (its
``change`` is 2.5 on day 5) — what the rule should mean needs its own study, and ``change`` values
are rewritten when a late record arrives, so the gate would need the ``score`` tracks replayed
with them to keep the outcome independent of arrival order.

Measured 2026-11-27 (second session), 2-core machine, after the revision chosen on ``tune`` and
``tune-2`` (the change's 3 reference records and loudness step, :mod:`dsp.toothchange`; the
score's baseline centre never below 0, :data:`detection.alarms.RECORD_RELATIVE_INDICATORS`;
"both per-tooth rules" added: what an operator gets). ``held-out-3`` (seeds 30000–30199) was
generated and run once, after that, never before — the part to read::

    project simulator, held-out-3 (never looked at while choosing)
    method                    ≤onset    ≤+1    ≤+2  never median  exact   only   FA/1k healthy w/ FA
    tooth change (new)           86%    92%    95%     4%    0.0    89%    31%    2.71      3/100
    per-tooth score              74%    93%    96%     4%    0.0    84%    71%    1.03      2/100
    both per-tooth rules         96%    99%   100%     0%    0.0    92%    35%    3.41      5/100
    today's MCI rule              0%    72%    87%    12%    1.0    88%    78%    0.28      0/100
    FM4                          95%    99%   100%     0%    0.0   nan%   nan%    2.87      3/100
    NA4                          96%    99%   100%     0%    0.0   nan%   nan%    4.78      5/100
    kurtosis                     66%    84%    89%     9%    0.0   nan%   nan%    8.61      8/100
    raw kurtosis                 51%    67%    76%    22%    0.0   nan%   nan%   72.73     64/100
    diff energy                  99%   100%   100%     0%    0.0    39%     1%   13.90     99/100
    both per-tooth rules earlier than every classic metric: 2% of spalled campaigns; on the same day or earlier: 96%; later than the best classic one: 4%

    both per-tooth rules per condition (spalled: ≤onset / ≤+1 / exact; healthy: FA campaigns)
      contact ratio  1.3–1.6          spalled  49: 100% / 100% /  96%   healthy  43: 2 with FA
      contact ratio  1.6–2.0          spalled  51:  92% /  98% /  88%   healthy  57: 3 with FA
      noise/signal   0.3–1            spalled  48:  98% / 100% /  90%   healthy  48: 4 with FA
      noise/signal   1–3              spalled  52:  94% /  98% /  94%   healthy  52: 1 with FA
      pinion teeth   13–30            spalled  20:  80% /  95% /  85%   healthy  28: 1 with FA
      pinion teeth   31–80            spalled  80: 100% / 100% /  94%   healthy  72: 4 with FA
      sensor         line_of_action   spalled  60:  95% /  98% /  90%   healthy  72: 5 with FA
      sensor         off_line         spalled  40:  98% / 100% /  95%   healthy  28: 0 with FA
      spall extent   <0.35 path       spalled  58:  97% /  98% /  93%   healthy   0: 0 with FA
      spall extent   healthy          spalled   0:   0% /   0% /   0%   healthy 100: 5 with FA
      spall extent   ≥0.35 path       spalled  42:  95% / 100% /  90%   healthy   0: 0 with FA

    independent generator, held-out-3 (never looked at while choosing)
    method                    ≤onset    ≤+1    ≤+2  never median  exact   only   FA/1k healthy w/ FA
    tooth change (new)            9%    27%    47%    39%    2.0    48%    37%    1.05      1/100
    per-tooth score               1%     7%    20%    74%    2.0    23%    21%    0.13      2/100
    both per-tooth rules          9%    28%    48%    38%    2.0    50%    38%    1.16      3/100
    today's MCI rule              0%     0%     3%    91%    3.0     7%     7%    0.06      0/100
    FM4                           7%    23%    44%    38%    2.0   nan%   nan%    5.74      5/100
    NA4                           5%    24%    44%    39%    2.0   nan%   nan%    3.83      3/100
    kurtosis                      1%     4%    15%    70%    2.5   nan%   nan%    2.87      3/100
    raw kurtosis                  0%     6%    14%    78%    2.0   nan%   nan%   22.01     20/100
    diff energy                  87%    95%    98%     2%    0.0    18%    10%   21.53     99/100
    both per-tooth rules earlier than every classic metric: 18% of spalled campaigns; on the same day or earlier: 75%; later than the best classic one: 25%

    both per-tooth rules per condition (spalled: ≤onset / ≤+1 / exact; healthy: FA campaigns)
      contact ratio  1.3–1.6          spalled  59:   8% /  29% /  46%   healthy  47: 3 with FA
      contact ratio  1.6–2.0          spalled  41:  10% /  27% /  56%   healthy  53: 0 with FA
      noise/signal   0.3–1            spalled  45:  13% /  33% /  51%   healthy  49: 1 with FA
      noise/signal   1–3              spalled  55:   5% /  24% /  49%   healthy  51: 2 with FA
      pinion teeth   13–30            spalled  34:  21% /  38% /  71%   healthy  29: 1 with FA
      pinion teeth   31–80            spalled  66:   3% /  23% /  39%   healthy  71: 2 with FA
      sensor         angled           spalled 100:   9% /  28% /  50%   healthy 100: 3 with FA
      spall extent   <0.35 path       spalled 100:   9% /  28% /  50%   healthy   0: 0 with FA
      spall extent   healthy          spalled   0:   0% /   0% /   0%   healthy 100: 3 with FA

The same revision on ``held-out-2`` (seeds 20000–20099, the first session's held-out part,
not used for any choice of this revision), against the first session's numbers on those seeds
(tables below)::

    project simulator, held-out-2, this revision
    method                    ≤onset    ≤+1    ≤+2  never median  exact   only   FA/1k healthy w/ FA
    tooth change (new)           82%    88%    94%     6%    0.0    90%    30%    2.81      1/50
    per-tooth score              70%    94%    94%     2%    0.0    86%    66%    1.30      4/50
    both per-tooth rules         90%    96%   100%     0%    0.0    94%    32%    3.79      5/50
    FM4                          90%    96%   100%     0%    0.0   nan%   nan%    5.71      3/50
    NA4                          92%    98%   100%     0%    0.0   nan%   nan%    7.62      4/50
    both per-tooth rules earlier than every classic metric: 4% of spalled campaigns; on the same day or earlier: 92%; later than the best classic one: 8%

    independent generator, held-out-2, this revision
    method                    ≤onset    ≤+1    ≤+2  never median  exact   only   FA/1k healthy w/ FA
    tooth change (new)           18%    38%    52%    40%    1.0    38%    28%    1.27      1/50
    per-tooth score               2%     4%    24%    72%    2.0    16%    14%    0.37      2/50
    both per-tooth rules         18%    40%    54%    38%    1.0    38%    28%    1.55      3/50
    FM4                          10%    38%    50%    40%    1.0   nan%   nan%    1.90      1/50
    NA4                           4%    40%    54%    34%    1.0   nan%   nan%    0.00      0/50
    both per-tooth rules earlier than every classic metric: 16% of spalled campaigns; on the same day or earlier: 76%; later than the best classic one: 24%

On the same seeds the change alone went 78 → 82 % on the onset day (project), exact 92 → 90 %,
healthy campaigns alarmed 2 → 1 of 50; the score, with its centre at 0, lost onset-day
detections (80 → 70 %) for one healthy campaign fewer (5 → 4); both rules together: 90 % on the
onset day, 96 % by the next, right tooth 94 %, 5 of 50 healthy alarmed. Independent: the change
unchanged (18 % / 38 %, 1 of 50), the score with fewer false alarms (4 → 2 of 50) and fewer
detections (12 → 4 % by the next day).

The earlier version (change with 2 reference records and no loudness step, score centre free) on
the parts below, for comparison; its choices were made on ``tune``, then ``held-out`` was looked
at once and the method revised, and ``held-out-2`` was run once after that.

Measured 2026-11-27 (first session), 2-core machine. The change detector was built on ``tune`` (seeds 0–59, both
generators); its first version was then run once on ``held-out`` (10000–10099), whose healthy
campaigns showed warnings on teeth whose signatures move with load (7 of 50 on the project
generator); the signature projection and the warning level 5 were then chosen on ``tune`` again,
and ``held-out-2`` (20000–20099) was run once, after that, never before — the part to read::

    project simulator, held-out-2 (never looked at while choosing)
    method                    ≤onset    ≤+1    ≤+2  never median  exact   only   FA/1k healthy w/ FA
    tooth change (new)           78%    86%    94%     6%    0.0    92%    34%    2.78      2/50
    per-tooth score              80%    96%    98%     0%    0.0    82%    56%    2.15      5/50
    today's MCI rule              0%    70%    82%    12%    1.0    88%    78%    0.28      0/50
    FM4                          90%    96%   100%     0%    0.0   nan%   nan%    5.71      3/50
    NA4                          92%    98%   100%     0%    0.0   nan%   nan%    7.62      4/50
    kurtosis                     66%    94%    96%     4%    0.0   nan%   nan%   13.33      6/50
    raw kurtosis                 36%    64%    66%    34%    0.0   nan%   nan%   70.48     31/50
    diff energy                 100%   100%   100%     0%    0.0    58%     8%   14.32     48/50
    new detector earlier than every classic metric: 2% of spalled campaigns; later than the best classic one: 18%

    independent generator, held-out-2 (never looked at while choosing)
    method                    ≤onset    ≤+1    ≤+2  never median  exact   only   FA/1k healthy w/ FA
    tooth change (new)           18%    38%    52%    40%    1.0    38%    30%    1.21      1/50
    per-tooth score               4%    12%    32%    64%    2.0    16%    12%    0.65      4/50
    today's MCI rule              0%     2%     6%    88%    2.5     8%     8%    0.09      0/50
    FM4                          10%    38%    50%    40%    1.0   nan%   nan%    1.90      1/50
    NA4                           4%    40%    54%    34%    1.0   nan%   nan%    0.00      0/50
    kurtosis                      4%     6%    24%    66%    2.0   nan%   nan%    0.00      0/50
    raw kurtosis                  6%     8%    16%    72%    2.0   nan%   nan%   15.24      6/50
    diff energy                  86%    96%   100%     0%    0.0    20%     8%   20.82     49/50
    new detector earlier than every classic metric: 14% of spalled campaigns; later than the best classic one: 24%

    project simulator, held-out (looked at once, with the first version)
    method                    ≤onset    ≤+1    ≤+2  never median  exact   only   FA/1k healthy w/ FA
    tooth change (new)           84%    84%    88%    12%    0.0    80%    26%    3.10      4/50
    per-tooth score              86%    96%    96%     4%    0.0    76%    48%    2.29      6/50
    today's MCI rule              0%    82%    88%    12%    1.0    86%    76%    0.32      0/50
    FM4                          92%    98%    98%     2%    0.0   nan%   nan%    9.54      5/50
    NA4                          90%   100%   100%     0%    0.0   nan%   nan%    7.63      4/50
    kurtosis                     74%    90%    92%     8%    0.0   nan%   nan%   11.45      6/50
    raw kurtosis                 58%    66%    72%    26%    0.0   nan%   nan%   85.88     39/50
    diff energy                  98%    98%    98%     2%    0.0    42%     4%   13.49     49/50
    new detector earlier than every classic metric: 2% of spalled campaigns; later than the best classic one: 16%

    independent generator, held-out (looked at once, with the first version)
    method                    ≤onset    ≤+1    ≤+2  never median  exact   only   FA/1k healthy w/ FA
    tooth change (new)           10%    28%    48%    36%    2.0    48%    30%    1.16      0/50
    per-tooth score               4%    18%    36%    50%    2.0    22%    20%    0.96      2/50
    today's MCI rule              0%     0%     8%    82%    3.0    10%     8%    0.17      0/50
    FM4                          10%    28%    54%    32%    2.0   nan%   nan%    3.82      1/50
    NA4                           8%    24%    60%    28%    2.0   nan%   nan%    7.63      4/50
    kurtosis                      0%     6%    20%    58%    3.0   nan%   nan%    7.63      3/50
    raw kurtosis                  0%     4%    14%    82%    2.0   nan%   nan%   17.18      8/50
    diff energy                  88%    96%    98%     0%    0.0    24%     8%   21.56     47/50
    new detector earlier than every classic metric: 18% of spalled campaigns; later than the best classic one: 40%

    project simulator, tune
    method                    ≤onset    ≤+1    ≤+2  never median  exact   only   FA/1k healthy w/ FA
    tooth change (new)           83%    93%    93%     7%    0.0    87%    27%    2.60      0/30
    per-tooth score              87%   100%   100%     0%    0.0    90%    77%    1.54      0/30
    today's MCI rule              0%    73%    90%    10%    1.0    87%    73%    0.37      0/30
    FM4                          93%   100%   100%     0%    0.0   nan%   nan%    0.00      0/30
    NA4                          93%   100%   100%     0%    0.0   nan%   nan%    0.00      0/30
    kurtosis                     77%    90%    93%     7%    0.0   nan%   nan%    6.33      1/30
    raw kurtosis                 53%    77%    90%    10%    0.0   nan%   nan%   56.96     15/30
    diff energy                 100%   100%   100%     0%    0.0    47%     3%   13.39     29/30
    new detector earlier than every classic metric: 0% of spalled campaigns; later than the best classic one: 17%

    independent generator, tune
    method                    ≤onset    ≤+1    ≤+2  never median  exact   only   FA/1k healthy w/ FA
    tooth change (new)           27%    33%    43%    50%    0.0    47%    33%    0.82      0/30
    per-tooth score               3%    13%    30%    63%    2.0    23%    17%    0.67      3/30
    today's MCI rule              0%     0%     3%    87%    3.0     3%     3%    0.14      0/30
    FM4                          10%    23%    47%    40%    2.0   nan%   nan%    6.33      2/30
    NA4                          10%    23%    43%    43%    2.0   nan%   nan%    9.49      3/30
    kurtosis                      0%     3%    23%    63%    2.0   nan%   nan%    0.00      0/30
    raw kurtosis                  0%     3%    10%    80%    2.5   nan%   nan%   15.82      4/30
    diff energy                 100%   100%   100%     0%    0.0    13%     7%   22.46     29/30
    new detector earlier than every classic metric: 20% of spalled campaigns; later than the best classic one: 30%

What it says (held-out-3). The issue's targets are NOT met. On the project's simulator the
per-tooth rules together alarm on the spall's first day in 96 % of spalled campaigns and by the
next day in 99 % (targets ≥ 50 % and ≥ 95 %: met), name the spalled tooth in 92 % (target ≥ 95 %),
and alarmed 5 of 100 healthy campaigns (target 0) — FM4 and NA4 are as early and as often wrong
(3 and 5 of 100) and name no tooth; "earlier than every classic metric" is 2 % because those
alarm on the onset day too (same day or earlier: 96 %, later: 4 %). On the independent generator
(30-revolution records, noise up to 3× the signal, pits on 10–30 % of the face) every method is
late: the per-tooth rules 9 % on the onset day, 28 % by the day after, 38 % never, the right
tooth in 50 %, 3 of 100 healthy alarmed — FM4 7 % / 23 % / 38 % never, 5 of 100; small pinions
(13–30 teeth) 21 % / 38 %, right tooth 71 %. Against the first session's held-out-2 (same
simulators, other seeds): project onset day 78 → 86 % for the change alone and 96 % for both
rules; healthy campaigns alarmed 2/50 (change) and 5/50 (score) then, 3/100 and 2/100 now.

The first session's reading (held-out-2): The issue's targets are NOT met. On the held-out-2 part the change detector names
the spalled tooth on the first alarm day in 92 % (project) and 38 % (independent) of spalled
campaigns — on the independent generator no other method names a tooth that often (the MCI score:
16 %) — with 2 and 1 healthy campaigns of 50 alarmed (target 0; score: 5 and 4). It alarms on the
onset day in 78 % / 18 % of campaigns (targets ≥ 50 %), by the day after in 86 % / 38 % (target
≥ 95 %). FM4 and NA4 see this simulator's spall earlier (90–92 % on the onset day) but say nothing
about the tooth; on the independent generator the change detector is as early as the best of them
(onset day 18 % vs 10 %, by the day after 38 % vs 38–40 %). The independent generator's records
hold ~30 revolutions at noise up to 3× the signal and its pits start on 10–30 % of the face: on
many campaigns the spall's change in the average stays below the average's own noise until it is
~25 µm (measured with noise-free twins: an onset-day pit gave 0.6–5 noise units in its sector at
90–170 revolutions). The remaining healthy-campaign alarms are on low-noise rigs (noise 0.3–0.5×
the signal), where what is left of the day's load and speed change in a tooth's signature after
the projection is of the order of the noise.

Tried on ``tune`` (independent generator, 30 spalled + 30 healthy) and not adopted, 2026-11-27
(the current detector: onset day 27 %, by the day after 33 %, never 50 %, exact 47 %, 0/30 healthy
alarmed): weighting the change spectrum before the sector energies — by the inverse noise
estimated from the reference days' scatter (by the day after 47–53 %, but 20/30 healthy
alarmed), an Eckart filter ``√S/N`` or a Wiener weight with the signal spectrum from the
reference's tooth-specific orders (17–37 %, 9–12/30 healthy alarmed); AR pre-whitening of the
change (orders 8–32, fitted on the reference signature, to undo a ringing path; 17–23 %, 0–1/30);
projecting out the reference days' own deviations as well (30 %); sector sums over 2–4 teeth
(27–33 %); per-campaign *oracle* lags 0–6 pitches raised few campaigns; averages of the raw
signal AR-prewhitened in time (order 32, filter fitted on the first day and kept: a path that
rings in hertz, not in orders; 10 % / 23 %). Why so little moves: on noise-free twins of the same
days (same rig and seed, the pit removed), the pit's change holds 0.2–0.35 × a noisy day's median
sector energy on the onset day of several campaigns (seeds 0, 8, 58) and stays below the noise at
23 µm on seed 0; on seed 58 (a ringing path) it spreads over ≥ 8 sectors after the tooth, 12–15 %
of it in the strongest. Nor is the record's noise the whole limit: the same 40 campaigns (seeds
0–39) with 120 revolutions per record instead of 30 (``--revolutions 120``, 4× the averaging)
gave the change detector 30 % / 50 % / never 40 % (onset day / by the day after) against 35 % /
40 % / never 50 % at 30 revolutions, and FM4 20 % / 40 % against 15 % / 30 %: what the day-to-day
load, speed and stiffness changes do to every tooth's own signature through a resonant path is
of the size of these pits' change, and averaging longer does not remove it.

Tried on ``tune`` + ``tune-2`` (seeds 0–159, 80 spalled + 80 healthy per generator) and not
adopted, 2026-11-27 (fifth session), offline on the stored pinion averages of every day (the
``change`` rule alone; today's detector: independent ≤ onset 16 %, ≤ +1 31 %, right tooth 46 %,
1/80 healthy alarmed; project 82 % / 90 % / 90 %, 0/80):

* **A smooth complex gain between the day and the reference** (the day's non-shared orders
  fitted as G(o)·reference with G a running least-squares ratio over ±1…±5 orders, with and
  without a ridge toward 1; a speed change moves a resonant path's response by more than its
  bandwidth, so the order-domain path changes from day to day): the healthy campaigns' highest
  score fell a little (95th percentile 4.1 → 3.5–4.0) but so did the spalled tooth's (onset + 1
  median 3.3 → 2.0–2.9); no setting raised detections at a matched false-alarm rate.
* **Each tooth's own volatility from the reference days** (leave-one-out changes of the
  reference records, per tooth, relative to the median tooth; the day's energy divided by it):
  with the warning at 4, independent ≤ + 1 31 → 41 % at 1/80 healthy alarmed, but on the
  project generator two healthy campaigns reached 6.3–7.2 (before: ≤ 4.4). The gain came from
  the record's spread over its teeth shrinking once volatile teeth were discounted, which also
  lifted teeth that moved for the first time; with the spread taken before the discount, the
  gain is gone (independent ≤ + 1 29 % at zero false alarms, as today).
* **Naming the first tooth of a burst** (a run of adjacent teeth above z = 2–4 gives its peak
  to its first tooth: a ringing path spreads a pit's change over the following sectors, and of
  the 91 independent detections at z ≥ 5 on these seeds, 17 named k + 1): onset + 1 right
  tooth 57 → 44–54 %. Teeth *before* the spalled one are often in the run too — a pit centred
  0.3–0.6 of the way along a path of contact 1.3–2 pitches long starts its change anywhere from
  half a pitch before the tooth's pitch angle to a pitch after it — so the run's start is no
  better a tooth than its peak.
* **A lag that grows with the mesh frequency** (the sector centred ``0.5 + τ·f_mesh`` pitches
  after the pitch angle, τ = 0.1–0.3 ms: a path's delay and ringing are in seconds, so at a high
  mesh frequency they span more pitches; also 0.75 and ``0.4 + τ·f_mesh`` with τ = 0.2 ms): the
  right tooth among days scoring ≥ 5 went 76 % → 62–77 % (independent) and 98 % → 77–98 %
  (project); onset + 1 top tooth 57 % → 40–52 %. The constant half pitch stays.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

CACHE = Path("/tmp/gw-eval")
REVOLUTIONS = int(os.environ.get("GW_BENCH_REVOLUTIONS", "30"))
"""Pinion revolutions per record (``--revolutions``; an environment variable so that the worker
processes see it): 30 is the evaluation set; more is the record-length study."""
POOLED_SPREAD = True
"""Score record-relative per-tooth rules with the pooled spread of the teeth (``--no-pooled-spread``)."""
DAYS = 7
PARTS = {
    "tune": range(0, 60),
    "tune-2": range(60, 160),
    "held-out": range(10000, 10200),
    "held-out-2": range(20000, 20200),
    "held-out-3": range(30000, 30200),
    "held-out-4": range(40000, 40200),
    "held-out-5": range(50000, 50200),
    "held-out-6": range(60000, 60200),
    "held-out-7": range(70000, 70200),
    "held-out-8": range(80000, 80200),
    "held-out-9": range(90000, 90200),
    "held-out-10": range(100000, 100200),
    "held-out-11": range(110000, 110200),
}
"""``held-out-2``: a second held-out range, first run after the change detector's revision that
followed a look at ``held-out`` (so that one part stays unseen while the method was changed).
``tune-2`` (seeds 60–159, second session): more healthy campaigns to study false alarms with, used
while choosing the revision that followed ``held-out-2``; ``held-out-3`` was first run after it."""
GLITCH_LEVEL = 20.0


def _parameters() -> Any:
    from gearwatch.floor.results import AnalysisParameters

    return AnalysisParameters()  # the defaults: exactly what the replay path runs


PARAMETERS = _parameters()


@dataclass(frozen=True)
class CampaignSpec:
    seed: int
    spalled: bool
    pinion_teeth: int
    gear_teeth: int
    contact_ratio: float
    noise_factor: float
    gain_step_day: int
    gain_factor: float
    direction: str
    onset_day: int | None
    spall_tooth: int | None
    spall_depth0_um: float
    spall_extent_fraction: float
    modes: tuple[tuple[float, float, float], ...]
    mesh_hz: float

    def condition(self) -> dict[str, str]:
        """Bins of the conditions, for the per-condition rows."""
        return {
            "contact ratio": "1.3–1.6" if self.contact_ratio < 1.6 else "1.6–2.0",
            "pinion teeth": "13–30" if self.pinion_teeth <= 30 else "31–80",
            "noise/signal": "0.3–1" if self.noise_factor < 1.0 else "1–3",
            "spall extent": (
                "<0.35 path" if self.spall_extent_fraction < 0.35 else "≥0.35 path"
            ) if self.spalled else "healthy",
            "sensor": self.direction,
        }


def draw_spec(seed: int) -> CampaignSpec:
    rng = np.random.default_rng([seed, 7919])
    spalled = seed % 2 == 0
    z1 = int(rng.integers(13, 81))
    z2 = max(z1 + 1, round(z1 * rng.uniform(1.05, 3.5)))
    z2 = min(z2, 160)
    onset = int(rng.integers(4, 6)) if spalled else None
    modes = (
        (float(rng.uniform(1500, 3500)), float(rng.uniform(0.02, 0.06)), float(rng.uniform(0.003, 0.01))),
        (float(rng.uniform(3500, 7500)), float(rng.uniform(0.02, 0.06)), float(rng.uniform(0.003, 0.01))),
    )
    return CampaignSpec(
        seed=seed,
        spalled=spalled,
        pinion_teeth=z1,
        gear_teeth=z2,
        contact_ratio=float(rng.uniform(1.3, 2.0)),
        noise_factor=float(np.exp(rng.uniform(np.log(0.3), np.log(3.0)))),
        gain_step_day=int(rng.integers(2, DAYS + 1)),
        gain_factor=float(np.exp(rng.uniform(np.log(0.5), np.log(2.0)))),
        direction="line_of_action" if rng.uniform() < 0.7 else "off_line",
        onset_day=onset,
        spall_tooth=int(rng.integers(1, z1 + 1)) if spalled else None,
        spall_depth0_um=float(rng.uniform(3.0, 6.0)),
        spall_extent_fraction=float(rng.uniform(0.1, 0.6)),
        modes=modes,
        mesh_hz=float(rng.uniform(300, 700)),
    )


# ---------------------------------------------------------------- project simulator


def _project_geometry(z1: int, z2: int, contact_ratio: float) -> tuple[float, float, float]:
    """(pressure angle, addendum coefficient, achieved contact ratio) closest to the target."""
    from physics.config import GearPairModel, Geometry
    from physics.simulator import model_geometry

    best: tuple[float, float, float, float] | None = None
    for pressure in np.arange(14.5, 28.01, 0.5):
        for addendum in np.arange(0.6, 1.41, 0.05):
            try:
                model = GearPairModel(geometry=Geometry(
                    pinion_teeth=z1, gear_teeth=z2, pressure_angle_deg=float(pressure),
                    addendum_coefficient=float(addendum), dedendum_coefficient=float(addendum) + 0.25,
                    module_mm=200.0 / z1,
                ))
                achieved = model_geometry(model).contact_ratio
            except ValueError:
                continue
            error = abs(achieved - contact_ratio)
            if best is None or error < best[0]:
                best = (error, float(pressure), float(addendum), float(achieved))
    assert best is not None
    return best[1], best[2], best[3]


def project_campaign(spec: CampaignSpec) -> Iterator[tuple[dict[str, np.ndarray], float, float, dict[str, Any]]]:
    """Yield (channels, sample rate, tooth1 angle, truth) per day from the project's simulator."""
    from physics.config import (
        Deviations,
        GearPairModel,
        Geometry,
        Mesh,
        Sensor,
        Spall,
        StructuralMode,
        WheelBody,
    )
    from physics.simulator import model_geometry, simulate

    rng = np.random.default_rng([spec.seed, 104729])
    pressure, addendum, _achieved = _project_geometry(spec.pinion_teeth, spec.gear_teeth, spec.contact_ratio)
    geometry = Geometry(
        pinion_teeth=spec.pinion_teeth, gear_teeth=spec.gear_teeth, pressure_angle_deg=pressure,
        addendum_coefficient=addendum, dedendum_coefficient=addendum + 0.25,
        module_mm=200.0 / spec.pinion_teeth,
    )
    off_line = spec.direction == "off_line"
    base = GearPairModel(
        geometry=geometry,
        mesh=Mesh(friction_coefficient=0.06 if off_line else 0.0),
        pinion=WheelBody(bearing_radial_stiffness_ratio=0.6 if off_line else 1.0,
                         bearing_principal_axis_deg=30.0 if off_line else 0.0),
    )
    path_mm = model_geometry(base).path_length_m * 1e3
    rpm = spec.mesh_hz * 60.0 / spec.pinion_teeth
    seconds = max(1.0, REVOLUTIONS * 60.0 / rpm + 0.1)
    pitch = np.round(rng.normal(0.0, 0.25, spec.pinion_teeth), 3)
    gear_pitch = np.round(rng.normal(0.0, 0.25, spec.gear_teeth), 3)
    deviations = Deviations(
        pinion_tip_relief_um=6.0, pinion_tip_relief_length_mm=0.2 * path_mm,
        gear_tip_relief_um=6.0, gear_tip_relief_length_mm=0.2 * path_mm,
        pinion_pitch_errors_um=[float(v) for v in pitch],
        gear_pitch_errors_um=[float(v) for v in gear_pitch],
        pinion_eccentricity_um=float(rng.uniform(3, 12)),
        pinion_eccentricity_phase_deg=float(rng.uniform(0, 360)),
        gear_eccentricity_um=float(rng.uniform(3, 12)),
        gear_eccentricity_phase_deg=float(rng.uniform(0, 360)),
    )
    modes = [StructuralMode(f, z, g) for f, z, g in spec.modes]
    sensor = Sensor(name="acc", direction="off_line" if off_line else "line_of_action",
                    noise_rms_m_s2=0.0, modes=modes)
    base = base.replace(deviations=deviations, sensors=[sensor])
    base = base.replace(operating=dataclasses.replace(base.operating, speed_rpm=rpm))
    clean = simulate(base, seconds=min(seconds, 0.5), seed=None)
    signal_rms = float(np.std(clean.channels["acc"]))
    noise = spec.noise_factor * signal_rms
    depth = spec.spall_depth0_um
    for day in range(1, DAYS + 1):
        load = 200.0 * float(np.clip(1 + rng.normal(0, 0.05), 0.9, 1.1))
        speed = rpm * float(np.clip(1 + rng.normal(0, 0.025), 0.95, 1.05))
        drift = float(rng.uniform(-0.04, 0.04))
        spalls = []
        truth: dict[str, Any] = {"day": day, "spall_depth_um": 0.0}
        if spec.spalled and spec.onset_day is not None and day >= spec.onset_day:
            k = day - spec.onset_day
            d = min(depth * 2.0**k, 25.0)
            extent = spec.spall_extent_fraction * path_mm
            spalls = [Spall(tooth=int(spec.spall_tooth or 1), depth_um=d, profile_start_mm=-0.6 * extent,
                            profile_extent_mm=extent, face_start_mm=0.25 * geometry.face_width_mm,
                            face_width_mm=0.5 * geometry.face_width_mm)]
            truth["spall_depth_um"] = d
        model = base.replace(
            operating=dataclasses.replace(base.operating, speed_rpm=speed, load_torque_nm=load,
                                          speed_drift_fraction=drift),
            deviations=dataclasses.replace(deviations, spalls=spalls),
            sensors=[dataclasses.replace(sensor, noise_rms_m_s2=noise)],
        )
        result = simulate(model, seconds=seconds, seed=int(rng.integers(0, 2**31 - 1)))
        channels = {name: np.asarray(v, dtype=np.float64) for name, v in result.channels.items()}
        yield channels, result.sample_rate_hz, float(result.tooth1_pitch_angle_deg % 360.0), truth


def _impair(spec: CampaignSpec, day: int, channels: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Gain step and glitch samples, applied to the accelerometer after generation."""
    rng = np.random.default_rng([spec.seed, day, 31337])
    acc = channels["acc"].copy()
    if day >= spec.gain_step_day:
        acc *= spec.gain_factor
    if rng.uniform() < 0.3:
        rms = float(np.std(acc))
        for index in rng.integers(0, acc.size, int(rng.integers(1, 4))):
            acc[index] = float(rng.choice([-1.0, 1.0])) * GLITCH_LEVEL * rms
    return {**channels, "acc": acc}


def independent_campaign(spec: CampaignSpec) -> Iterator[tuple[dict[str, np.ndarray], float, float, dict[str, Any]]]:
    """The same, from engineer indep's generator (``physics.independent.random_campaign``).

    Its own randomised conditions (docs/independent-simulator.md: contact ratio 1.3–2.0, 13–80
    teeth, ratio 1–3.5, noise 0.3–3×, drift up to 20 %, load ±10 %, speed ±5 %, gain step in half
    the campaigns, 3e38 glitches on ~15 % of the days, 2–4 line modes with delay, sensor angle);
    the spall's tooth, onset (forced to day 4 or 5 like the project's part) and growth are its
    own. ``spec.spalled`` False gives its healthy twin. Records hold ~30 pinion revolutions.
    """
    from physics.independent import generate_record, random_campaign, random_model

    rpm = random_model(spec.seed).operating.speed_rpm
    seconds = float(np.clip(REVOLUTIONS * 60.0 / rpm + 0.1, 1.0, 6.5 * REVOLUTIONS / 30))
    plan = random_campaign(spec.seed, days=DAYS, spalled=spec.spalled,
                           onset_day=spec.onset_day or 4, seconds=seconds)
    for day in plan:
        record = generate_record(day.model, seed=day.seed)
        truth = dict(day.changes)
        derived = record.truth.get("derived", {})
        spall = day.model.spalls[0] if day.model.spalls else None
        truth.update({
            "day": day.day,
            "spall_depth_um": float(spall.depth_um) if spall else 0.0,
            "spec": {
                "pinion_teeth": int(day.model.geometry.pinion_teeth),
                "gear_teeth": int(day.model.geometry.gear_teeth),
                "contact_ratio": float(derived.get("contact_ratio", day.model.geometry.contact_ratio or 0.0)),
                "noise_factor": float(day.model.acquisition.noise_to_signal),
                "spall_tooth": int(spall.tooth) if spall else None,
            },
        })
        campaign = record.campaign()
        yield ({k: np.asarray(v, dtype=np.float64) for k, v in record.channels.items()},
               float(record.sample_rate_hz), float(campaign.rig.tooth1_pitch_angle_deg),
               json.loads(json.dumps(truth, default=float)))


GENERATORS: dict[str, Callable[[CampaignSpec], Iterator[Any]]] = {
    "project": project_campaign,
    "independent": independent_campaign,
}


def campaign_records(generator: str, spec: CampaignSpec) -> list[tuple[dict[str, np.ndarray], float, float, dict[str, Any]]]:
    """Every day of a campaign, from the npz cache when there (generated otherwise)."""
    folder = CACHE / (generator if REVOLUTIONS == 30 else f"{generator}-{REVOLUTIONS}rev")
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"seed{spec.seed}.npz"
    if path.exists():
        data = np.load(path, allow_pickle=False)
        meta = json.loads(str(data["meta"]))
        return [
            ({name: data[f"d{day}_{name}"] for name in meta["channels"]}, meta["fs"][day - 1],
             meta["tooth1"][day - 1], meta["truth"][day - 1])
            for day in range(1, DAYS + 1)
        ]
    days = list(GENERATORS[generator](spec))
    arrays: dict[str, Any] = {}
    for day, (channels, _, _, _) in enumerate(days, start=1):
        for name, values in channels.items():
            arrays[f"d{day}_{name}"] = values.astype(np.float32) if name == "acc" else values
    meta = {"channels": list(days[0][0]), "fs": [d[1] for d in days], "tooth1": [d[2] for d in days],
            "truth": [d[3] for d in days]}
    np.savez(path, meta=json.dumps(meta), **arrays)
    return days


# ---------------------------------------------------------------- analysis and alarms


def analyse_campaign(generator: str, spec: CampaignSpec) -> dict[str, Any]:
    """Per-day per-tooth and whole-record values of one campaign (pipeline in-process)."""
    from dsp.toothchange import campaign_change_scores
    from gearwatch.floor.campaign import (
        Campaign,
        ChannelConfig,
        RecordData,
        RigConfig,
        TachometerConfig,
    )
    from gearwatch.floor.errors import RecordRejected
    from gearwatch.usecases.analyze import analyze_record

    days = campaign_records(generator, spec)
    if generator == "independent":
        # the generator drew its own rig: describe the campaign by it (spalled days carry the tooth)
        drawn = dict(days[-1][3]["spec"])
        if not spec.spalled:
            drawn["spall_tooth"] = None
        spec = dataclasses.replace(spec, direction="angled", gain_step_day=DAYS + 1,
                                   spall_extent_fraction=0.2, **drawn)
    out: dict[str, Any] = {"spec": dataclasses.asdict(spec), "days": []}
    averages: list[np.ndarray | None] = []  # for the change indicator, as refresh_tooth_change
    angles: list[float] = []
    for day, (channels, fs, tooth1, truth) in enumerate(days, start=1):
        campaign = Campaign(
            id="bench", description="", sample_rate_hz=fs,
            rig=RigConfig(id="rig", pinion_teeth=spec.pinion_teeth, gear_teeth=spec.gear_teeth,
                          tooth1_pitch_angle_deg=tooth1),
            tachometer=TachometerConfig(channel="tach"),
            channels=(ChannelConfig("acc", "accelerometer"), ChannelConfig("tach", "tachometer")),
        )
        if generator == "project":  # the independent generator has its own artefacts
            channels = _impair(spec, day, channels)
        record = RecordData(channels=channels, sample_rate_hz=fs)
        try:
            analysis = analyze_record(record, campaign, PARAMETERS, input_sha256="0" * 64)
        except RecordRejected as error:
            out["days"].append({"day": day, "rejected": str(error), "truth": truth})
            continue
        channel = analysis.channels[0]
        angle = channel.baseline_stats.get("tooth1_pitch_angle_deg")
        averages.append(None if angle is None else
                        np.asarray(channel.curves["pinion_average"], dtype=np.float64))
        angles.append(0.0 if angle is None else float(angle))
        out["days"].append({
            "day": day,
            "truth": truth,
            "teeth": {name: [getattr(t, name) for t in channel.teeth]
                      for name in ("mci_depth", "mci_depth_se", "score", "diff_energy", "nonsync_z")},
            "metrics": channel.metrics,
            "baseline_stats": channel.baseline_stats,
            "worst_tooth": channel.worst_tooth,
        })
    # the change indicator: the stored averages of the accepted days in taken_at order, exactly
    # what gearwatch.usecases.tooth_change computes from the database (float32 curves there too)
    changes = campaign_change_scores(averages, angles, spec.pinion_teeth)
    for day_result, scores in zip([d for d in out["days"] if "rejected" not in d], changes, strict=True):
        day_result["teeth"]["change"] = (
            [math.nan] * spec.pinion_teeth if scores is None else [float(v) for v in scores])
    return out


def _job(args: tuple[str, int]) -> dict[str, Any]:
    generator, seed = args
    spec = draw_spec(seed)
    start = time.process_time()
    try:
        result = analyse_campaign(generator, spec)
    except Exception as error:  # a generator refusing a drawn geometry: counted, not fatal
        return {"spec": dataclasses.asdict(spec), "error": f"{type(error).__name__}: {error}",
                "days": [], "cpu_s": time.process_time() - start}
    result["cpu_s"] = time.process_time() - start
    return result


def _generate(args: tuple[str, int]) -> None:
    generator, seed = args
    try:
        campaign_records(generator, draw_spec(seed))
    except Exception as error:
        print(f"seed {seed}: {type(error).__name__}: {error}", file=sys.stderr)


NEW_METHOD = "per-tooth rules"
"""The per-tooth detector an operator gets: the default per-tooth rules that are created enabled,
together (``change`` and ``score``; ``nonsync_z`` would join them if its rule were enabled). Until
2026-11-29 the table called them "both per-tooth rules"."""
CLASSIC_METHODS = ("FM4", "residual kurtosis", "kurtosis", "raw kurtosis")
"""Whole-record classics the new detector is compared with (diff energy, per tooth with the
whole-record statistic, alarms in almost every healthy campaign: its first alarms are not detections)."""
METHODS: dict[str, tuple[str, bool, dict[str, Any]]] = {}
"""name → (indicator, per tooth, RuleSettings keyword arguments); filled by :func:`_methods`."""


def _default_rule(indicator: str) -> dict[str, Any]:
    """The default rule's settings (the ``enabled`` flag is storage's, not the rule's)."""
    from detection.default_rules import DEFAULT_RULES

    return {k: v for k, v in DEFAULT_RULES[indicator].items() if k != "enabled"}


def _methods() -> dict[str, tuple[str, bool, dict[str, Any]]]:
    from detection.default_rules import DEFAULT_RULES

    classic = _default_rule
    return {
        "tooth change (new)": ("change", True, dict(DEFAULT_RULES["change"])),
        "per-tooth score": ("score", True, dict(DEFAULT_RULES["score"])),
        "non-sync power": ("nonsync_z", True, classic("nonsync_z")),
        NEW_METHOD: (BOTH_PER_TOOTH, True, {}),
        "today's MCI rule": ("mci_depth", True, {"spread_floor_abs": 0.1, "baseline_records": 3}),
        "FM4": ("fm4", False, classic("fm4")),
        "residual kurtosis": ("residual_kurtosis", False, classic("residual_kurtosis")),
        "NA4 (stored, disabled)": (NA4_STORED, False, classic("na4")),
        "kurtosis": ("kurtosis", False, classic("kurtosis")),
        "raw kurtosis": ("raw_kurtosis", False, classic("raw_kurtosis")),
        "diff energy": ("diff_energy", True, classic("raw_kurtosis")),
        OPERATOR_VIEW: (OPERATOR_VIEW, False, {}),
    }


BOTH_PER_TOOTH = "change+score+nonsync"
"""What an operator of a rig with the default rules sees per tooth: the alarms of the ``change``,
``score`` and ``nonsync_z`` rules together (each when enabled by default). On a day several open
alarms on, the tooth named is the ``change`` rule's (it names the right tooth more often on both
generators), then the highest-scoring."""
PER_TOOTH_RULES = ("change", "score", "nonsync_z")
_NAMING_PRIORITY = 1e6
OPERATOR_VIEW = "every enabled default rule"
"""What an operator of a new rig gets: the openings of every rule of
:data:`detection.default_rules.DEFAULT_RULES` that is created enabled, per tooth and whole record
(the ``mci_depth`` rule with its stored settings: an 8-record baseline)."""


NA4_STORED = "na4 (running baseline)"
"""NA4 as the database stores it: the record's fourth moment of the residual over the squared mean
residual variance of the campaign's earlier records (:mod:`gearwatch.usecases.running_baselines`),
rebuilt here from each day's ``baseline_stats``. ``analyze_record`` without that history divides by
the record's own variance (``NA4, own record``: the kurtosis of the residual)."""


def _running_na4(result: dict[str, Any]) -> None:
    """Add :data:`NA4_STORED` to each accepted day's metrics (days saved without
    ``baseline_stats``: NaN, the method then never alarms)."""
    from gearwatch.usecases.running_baselines import expected_baselines

    days = [d for d in result["days"] if "rejected" not in d]
    points = [(d["day"], d.get("baseline_stats") or {}) for d in days]
    for day, (_, stats), baseline in zip(days, points, expected_baselines(points, "residual_variance"),
                                         strict=True):
        own = stats.get("residual_variance")
        if own is None or baseline is None:
            day["metrics"][NA4_STORED] = math.nan
            continue
        day["metrics"][NA4_STORED] = (
            day["metrics"]["na4"] * (own / baseline) ** 2 if baseline > 0 else 0.0)


def evaluate(result: dict[str, Any], indicator: str, per_tooth: bool, settings: dict[str, Any]) -> list[tuple[int, int, str, float]]:
    """Alarm openings (day, tooth, evidence, score in baseline units) of one method on one
    campaign (tooth 0: whole record)."""
    from detection.alarms import (
        RECORD_RELATIVE_INDICATORS,
        RuleSettings,
        TrackState,
        pooled_spread,
        step,
    )
    from detection.default_rules import DEFAULT_RULES
    from gearwatch.floor.results import STORED_TOOTH_INDICATORS

    if indicator == BOTH_PER_TOOTH:
        change = evaluate(result, "change", True, _default_rule("change"))
        others = [opening for name in PER_TOOTH_RULES[1:]
                  if DEFAULT_RULES[name].get("enabled", True) is not False
                  and all(name in day["teeth"] for day in result["days"] if "teeth" in day)
                  for opening in evaluate(result, name, True, _default_rule(name))]
        merged: dict[tuple[int, int], tuple[int, int, str, float]] = {}
        for opening in [(d, t, e, v + _NAMING_PRIORITY) for d, t, e, v in change] + others:
            key = opening[:2]  # one opening per tooth-day, whichever rule opened it
            if key not in merged or opening[3] > merged[key][3]:
                merged[key] = opening
        return sorted(merged.values())

    if indicator == OPERATOR_VIEW:
        openings = evaluate(result, BOTH_PER_TOOTH, True, {})
        for name, rule_settings in DEFAULT_RULES.items():
            if name in PER_TOOTH_RULES or rule_settings.get("enabled", True) is False:
                continue
            per_tooth_rule = name in STORED_TOOTH_INDICATORS
            openings += evaluate(result, name, per_tooth_rule, dict(rule_settings))
        return sorted(openings)
    if indicator == NA4_STORED:
        _running_na4(result)
    if indicator == "residual_kurtosis":  # results saved before the metric: NA4 without history
        for day in result["days"]:
            if "metrics" in day and indicator not in day["metrics"]:
                day["metrics"][indicator] = day["metrics"]["na4"]
    rule = RuleSettings(indicator, **settings)
    teeth = result["spec"]["pinion_teeth"] if per_tooth else 1
    states = [TrackState() for _ in range(teeth)]
    openings: list[tuple[int, int, str, float]] = []
    for day in result["days"]:
        if "rejected" in day:
            continue
        values = day["teeth"][indicator] if per_tooth else [day["metrics"][indicator]]
        pooled = None
        if POOLED_SPREAD and indicator in RECORD_RELATIVE_INDICATORS:
            pooled = pooled_spread(state.baseline_values for state in states)
        evaluations = [step(state, float(value), rule, pooled)
                       for state, value in zip(states, values, strict=True)]
        for index, evaluation in enumerate(evaluations):
            states[index] = evaluation.state
            for transition in evaluation.transitions:
                if transition.opened:
                    openings.append((day["day"], index + 1 if per_tooth else 0, transition.evidence,
                                     transition.score))
    return openings


def report(results: list[dict[str, Any]]) -> str:
    methods = _methods()
    lines: list[str] = []
    failed = [r for r in results if "error" in r]
    for r in failed:
        lines.append(f"seed {r['spec']['seed']} not generated: {r['error']}")
    results = [r for r in results if "error" not in r]
    spalled = [r for r in results if r["spec"]["spalled"]]
    healthy = [r for r in results if not r["spec"]["spalled"]]
    rejected = sum("rejected" in d for r in results for d in r["days"])
    lines.append(f"{len(spalled)} spalled + {len(healthy)} healthy campaigns, {DAYS} days each; "
                 f"{rejected} rejected records")
    first_days: dict[str, list[float]] = {}
    header = (f"{'method':24s} {'≤onset':>7s} {'≤+1':>6s} {'≤+2':>6s} {'never':>6s} "
              f"{'median':>6s} {'exact':>6s} {'only':>6s} {'FA/1k':>7s} {'healthy w/ FA':>13s}")
    lines.append(header)
    for name, (indicator, per_tooth, settings) in methods.items():
        rel: list[float] = []
        exact = strict = 0
        false_count = 0
        exposure = 0
        healthy_with_fa = 0
        for r in results:
            spec = r["spec"]
            openings = evaluate(r, indicator, per_tooth, settings)
            units = spec["pinion_teeth"] if per_tooth else 1
            scored_days = sum("rejected" not in d for d in r["days"])
            onset = spec["onset_day"]
            if spec["spalled"]:
                exposure += units * (onset - 1) + (units - 1) * (DAYS - onset + 1) if per_tooth else onset - 1
                right = [o for o in openings if o[0] >= onset and (not per_tooth or o[1] == spec["spall_tooth"])]
                false_count += len([o for o in openings if o not in right])
                any_after = [o for o in openings if o[0] >= onset]
                if any_after:
                    first = min(o[0] for o in any_after)
                    rel.append(first - onset)
                    first_day = [o for o in any_after if o[0] == first]
                    if per_tooth and max(first_day, key=lambda o: o[3])[1] == spec["spall_tooth"]:
                        exact += 1
                    if per_tooth and {o[1] for o in first_day} == {spec["spall_tooth"]}:
                        strict += 1
                else:
                    rel.append(math.inf)
            else:
                exposure += units * scored_days
                false_count += len(openings)
                healthy_with_fa += bool(openings)
        first_days[name] = rel
        arr = np.asarray(rel)
        n = max(arr.size, 1)
        finite = arr[np.isfinite(arr)]
        lines.append(
            f"{name:24s} {np.mean(arr <= 0):7.0%} {np.mean(arr <= 1):6.0%} {np.mean(arr <= 2):6.0%} "
            f"{np.mean(~np.isfinite(arr)):6.0%} {np.median(finite) if finite.size else math.nan:6.1f} "
            f"{(exact / n if per_tooth else math.nan):6.0%} {(strict / n if per_tooth else math.nan):6.0%} "
            f"{1000 * false_count / max(exposure, 1):7.2f} "
            f"{healthy_with_fa:6d}/{len(healthy):<6d}"
        )
    new = np.asarray(first_days[NEW_METHOD])
    classic = np.vstack([first_days[m] for m in methods if m in CLASSIC_METHODS])
    best_classic = classic.min(axis=0)
    earlier = np.mean((new < best_classic) | (~np.isfinite(best_classic) & np.isfinite(new)))
    later = np.mean(new > best_classic)
    same_or_earlier = np.mean(new <= best_classic)
    lines.append(f"{NEW_METHOD} earlier than every classic metric: {earlier:.0%} of spalled campaigns; "
                 f"on the same day or earlier: {same_or_earlier:.0%}; later than the best classic one: "
                 f"{later:.0%}")
    # what the records let any of them see: the part of the gap to the targets that is there to find
    seen = np.minimum(new, best_classic)
    caught = f"{np.mean(new[seen <= 1] <= 1):.0%}" if np.any(seen <= 1) else "none"
    lines.append(f"{NEW_METHOD} or a classic metric: by the day after onset {np.mean(seen <= 1):.0%} "
                 f"of spalled campaigns, ever {np.mean(np.isfinite(seen)):.0%}; {NEW_METHOD} by the "
                 f"day after onset in {caught} of those seen by then")
    lines.append("first alarm day relative to onset = first day ≥ onset on which the method opened "
                 "any alarm (warning or alarm); exact = the highest-scoring alarm opened that day is "
                 "on the spalled tooth; only = that day's alarms are on the spalled tooth alone; "
                 "FA/1k = alarms opened on healthy tooth-days (per-tooth: healthy campaigns, days "
                 "before onset, other teeth) or record-days (whole-record) per 1,000; healthy w/ FA "
                 "= healthy campaigns with any alarm opened")
    # per condition, the new detector
    lines.append("")
    lines.append(f"{NEW_METHOD} per condition (spalled: ≤onset / ≤+1 / exact; healthy: FA campaigns)")
    indicator, per_tooth, settings = methods[NEW_METHOD]
    def condition(r: dict[str, Any]) -> dict[str, str]:
        return CampaignSpec(**r["spec"]).condition()

    keys = sorted({k for r in results for k in condition(r)})
    for key in keys:
        bins: dict[str, list[dict[str, Any]]] = {}
        for r in results:
            bins.setdefault(condition(r)[key], []).append(r)
        for value, members in sorted(bins.items()):
            sp = [m for m in members if m["spec"]["spalled"]]
            he = [m for m in members if not m["spec"]["spalled"]]
            rels, ex = [], 0
            for m in sp:
                openings = evaluate(m, indicator, per_tooth, settings)
                after = [o for o in openings if o[0] >= m["spec"]["onset_day"]]
                first = min((o[0] for o in after), default=None)
                rels.append(math.inf if first is None else first - m["spec"]["onset_day"])
                ex += first is not None and max((o for o in after if o[0] == first), key=lambda o: o[3])[1] == m["spec"]["spall_tooth"]
            fa = sum(bool(evaluate(m, indicator, per_tooth, settings)) for m in he)
            r_arr = np.asarray(rels) if rels else np.asarray([math.nan])
            lines.append(f"  {key:14s} {value:16s} spalled {len(sp):3d}: {np.mean(r_arr <= 0):4.0%} / "
                         f"{np.mean(r_arr <= 1):4.0%} / {ex / max(len(sp), 1):4.0%}   healthy {len(he):3d}: {fa} with FA")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--part", choices=list(PARTS), default="tune")
    parser.add_argument("--generator", choices=["project", "independent", "both"], default="project")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--limit", type=int, default=None, help="first N campaigns of the part")
    parser.add_argument("--skip", type=int, default=0,
                        help="leave out the part's first N campaigns (spent by an earlier report)")
    parser.add_argument("--revolutions", type=int, default=None,
                        help="pinion revolutions per record (default 30: the evaluation set)")
    parser.add_argument("--generate-only", action="store_true",
                        help="only generate and cache the records (no analysis, no table)")
    parser.add_argument("--from-results", action="store_true",
                        help="re-evaluate the alarm rules on the saved per-record results")
    parser.add_argument("--no-pooled-spread", action="store_true",
                        help="score per-tooth rules without the teeth's pooled day-to-day spread "
                             "(the rule as it was before the pooled spread, for comparison)")
    args = parser.parse_args()
    if args.no_pooled_spread:
        global POOLED_SPREAD
        POOLED_SPREAD = False
    if args.revolutions is not None:
        global REVOLUTIONS
        REVOLUTIONS = args.revolutions
        os.environ["GW_BENCH_REVOLUTIONS"] = str(args.revolutions)  # for spawned workers too
    seeds = list(PARTS[args.part])
    seeds = seeds[args.skip:]
    if args.quick:
        seeds = seeds[:12]
    if args.limit:
        seeds = seeds[: args.limit]
    generators = ["project", "independent"] if args.generator == "both" else [args.generator]
    for generator in generators:
        if generator not in GENERATORS:
            print(f"generator {generator!r} not available", file=sys.stderr)
            continue
        start = time.perf_counter()
        saved = CACHE / f"results-{generator}-{args.part}-{REVOLUTIONS}rev.json"
        jobs = [(generator, seed) for seed in seeds]
        if args.generate_only:
            with ProcessPoolExecutor(args.workers) as pool:
                list(pool.map(_generate, jobs))
            print(f"generated {len(jobs)} campaigns in {time.perf_counter() - start:.0f} s")
            continue
        if args.from_results:
            results = [r for r in json.loads(saved.read_text()) if r["spec"]["seed"] in set(seeds)]
            if generator == "project":
                for r in results:
                    r["spec"] = dataclasses.asdict(draw_spec(r["spec"]["seed"]))
        elif args.workers > 1:
            with ProcessPoolExecutor(args.workers) as pool:
                results = list(pool.map(_job, jobs))
        else:
            results = [_job(job) for job in jobs]
        if not args.from_results:
            saved.write_text(json.dumps(results, default=float))
        print(f"== generator {generator}, part {args.part} (seeds {seeds[0]}–{seeds[-1]}), "
              f"{time.perf_counter() - start:.0f} s wall, "
              f"{sum(r['cpu_s'] for r in results):.0f} s CPU in workers")
        print(report(results))


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    main()
