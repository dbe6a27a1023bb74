"""Alarm logic per rig, channel, tooth and indicator: baseline, levels, persistence, hysteresis.

Pure: values in, states and transitions out; no database. :mod:`gearwatch.usecases.alarms` keeps one
:class:`TrackState` per (rule, channel, tooth) and applies :func:`step` to every accepted
record in the order the records were taken.

Semantics (all levels in *baseline units*: how many robust spreads a value lies on the worse
side of the baseline centre, see :class:`Baseline`):

* **Baseline** — learned from the first ``baseline_records`` finite values of the track
  (accepted records only: rejected ones never reach :func:`step`). Centre = median, spread =
  1.4826·MAD (the standard deviation for Gaussian data) with a floor
  ``max(spread_floor_fraction·|centre|, spread_floor_abs)`` so that a perfectly steady
  baseline (MAD = 0, e.g. noise-free simulations) does not turn every wiggle into an alarm.
  No alarm can be raised while the baseline is being learned.
* **Direction** — :data:`INDICATOR_DIRECTIONS`. For every indicator gearwatch computes a
  LARGER value is worse: ``mci_depth`` (a deeper MCI well under a cracked or spalled tooth),
  ``diff_energy`` and ``diff_kurtosis`` (energy and impulsiveness of the difference signal in
  the tooth's sector) and the whole-record metrics (rms, peak, crest, kurtosis, FM0, FM4, NA4,
  NB4, M6A, M8A, ER all grow with damage). A ``lower_is_worse`` direction is supported for
  indicators that fall with damage.
* **Short campaigns** — with ``min_baseline_records`` (m) set below ``baseline_records`` (n),
  scoring starts after m records against the baseline of the records so far, and each later
  record that scores below ``clear_level`` with the CUSUM at rest joins the baseline until it
  holds n (a record that looks abnormal — or the first small step of a growing fault — is
  never learned as normal). A spread learned from few records is
  widened by the small-sample factor ``t_{0.975, c−1}/1.96`` (``c`` records; Student's t), so
  that 3 repeatable records do not make every wiggle count. ``min_baseline_records = None``
  keeps the fixed baseline of n records.
* **Sequential test (CUSUM)** — with ``cusum_reference`` (k) and ``cusum_limit`` (h) set, each
  scored record also updates Page's one-sided CUSUM ``S ← max(0, S + score − k)`` (score in
  baseline units); ``S > h`` opens (or escalates to) an ``alarm`` without waiting for
  persistence, since ``S`` already accumulates over records. A small, persistent, growing
  change thus alarms before any single record reaches the level. ``S`` restarts at 0 when the
  alarm clears. Each transition says which evidence raised it (:attr:`Transition.evidence`:
  ``"level"`` or ``"cusum"``).
* **Persistence** — an alarm opens when ``persistence`` (K) consecutive records score above
  ``warning_level`` (state ``warning``) or above ``alarm_level`` (state ``alarm``); an open
  warning escalates to ``alarm`` after K consecutive records above ``alarm_level``. One record
  below a level resets its counter. ``raised_at`` is the time of the K-th record.
* **Hysteresis** — an open alarm clears only after K consecutive records score below
  ``clear_level`` (< ``warning_level``); values between the two levels keep it open.
* **Acknowledgement** — an operator acknowledges an open alarm (state ``acknowledged``; the
  severity reached is kept). An acknowledged *warning* that later escalates to *alarm* becomes
  ``alarm`` again and must be acknowledged again; an acknowledged alarm stays acknowledged until
  it clears. After clearing, a new excursion opens a new alarm.
* A non-finite value (NaN, ±inf) is ignored: it changes no counter.
* **Self-referenced indicators** (:data:`SELF_REFERENCED_INDICATORS`, e.g. ``change``) are
  already in noise units against the track's own history: their baseline is fixed at centre 0,
  spread 1, and every value is scored.
* **Record-relative indicators** (:data:`RECORD_RELATIVE_INDICATORS`, e.g. ``score``) compare a
  tooth with the other teeth of the same record, 0 being the typical tooth: their baseline
  centre is never taken below 0. A tooth that stood below the others and became as loud as
  them (a load change) has not become worse than a typical tooth.
  Their spread is never taken below the channel's teeth's pooled day-to-day spread
  (:func:`pooled_spread`, passed to :func:`step` by the caller, which sees every tooth): on long
  records a healthy tooth's score moves by several of the record's standard errors from day to
  day, which the tooth's own few baseline records rarely show.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np

Direction = Literal["higher_is_worse", "lower_is_worse"]
Level = Literal["normal", "warning", "alarm"]
TransitionKind = Literal["warning", "alarm", "cleared"]

INDICATOR_DIRECTIONS: dict[str, Direction] = {
    # per tooth
    "mci_depth": "higher_is_worse",
    "diff_energy": "higher_is_worse",
    "diff_kurtosis": "higher_is_worse",
    # whole record
    "rms": "higher_is_worse",
    "peak": "higher_is_worse",
    "crest": "higher_is_worse",
    "kurtosis": "higher_is_worse",
    "fm0": "higher_is_worse",
    "fm4": "higher_is_worse",
    "na4": "higher_is_worse",
    "residual_kurtosis": "higher_is_worse",
    "nb4": "higher_is_worse",
    "m6a": "higher_is_worse",
    "m8a": "higher_is_worse",
    "er": "higher_is_worse",
    "raw_rms": "higher_is_worse",
    "raw_kurtosis": "higher_is_worse",
    # per tooth, in standard errors of the record (dsp.toothscore)
    "score": "higher_is_worse",
    "mci_depth_se": "higher_is_worse",
    # per tooth, the revolutions' power about the average against the record's teeth (dsp.nonsync)
    "nonsync_z": "higher_is_worse",
    # per tooth, against the tooth's own earlier waveform (dsp.toothchange)
    "change": "higher_is_worse",
}
"""Which way is worse for each indicator gearwatch computes."""

SELF_REFERENCED_INDICATORS: frozenset[str] = frozenset({"change"})
"""Indicators that are already a comparison with the track's own history, in noise units
(:mod:`dsp.toothchange`: the tooth's waveform against the campaign's reference records, as a
robust z over the record's teeth). Their baseline is fixed — centre 0, spread 1 — and scoring
starts with the first value: learning a second baseline from the first change scores would
only delay the first alarm by ``min_baseline_records`` and measure noise against noise."""


RECORD_RELATIVE_INDICATORS: frozenset[str] = frozenset({"score", "nonsync_z"})
"""Indicators that compare a tooth with the other teeth of the same record (:mod:`dsp.toothscore`,
:mod:`dsp.nonsync`: 0 is the record's typical tooth). Their baseline centre is never below 0: on ``tune-2`` of
``benchmarks/bench_detection.py`` (project generator, 50 healthy campaigns) 3 of the 5 healthy
campaigns with a ``score`` alarm were teeth scoring −4…−6 on their baseline days that rose to
about 0 on a load change; with the centre at 0 none of those alarmed, for onset-day detections
44 → 42 of 50 (the ``change`` rule, alarming beside it, caught both)."""


def indicator_direction(indicator: str) -> Direction:
    """The direction of ``indicator`` (``ValueError`` for an unknown indicator).

    >>> indicator_direction("mci_depth")
    'higher_is_worse'
    """
    try:
        return INDICATOR_DIRECTIONS[indicator]
    except KeyError:
        known = ", ".join(INDICATOR_DIRECTIONS)
        raise ValueError(f"unknown indicator {indicator!r} (known: {known})") from None


RULE_SETTING_NAMES = (
    "baseline_records",
    "warning_level",
    "alarm_level",
    "clear_level",
    "persistence",
    "spread_floor_fraction",
    "spread_floor_abs",
    "min_baseline_records",
    "cusum_reference",
    "cusum_limit",
)
"""The settings of :class:`RuleSettings` that a stored rule carries and an operator may change
(the indicator names the rule; the direction follows from it): storage, the use-case and the REST
schema copy exactly these."""


@dataclass(frozen=True)
class RuleSettings:
    """Settings of one alarm rule (levels in baseline units, see the module docstring).

    >>> RuleSettings("mci_depth", baseline_records=5, persistence=2).direction
    'higher_is_worse'
    """

    indicator: str
    baseline_records: int = 8
    warning_level: float = 4.0
    alarm_level: float = 8.0
    clear_level: float = 2.0
    persistence: int = 2
    spread_floor_fraction: float = 0.05
    spread_floor_abs: float = 1e-9
    direction: Direction = field(default="higher_is_worse")
    min_baseline_records: int | None = None
    """Start scoring after this many records (``None``: after ``baseline_records``)."""
    cusum_reference: float | None = None
    """CUSUM allowance k in baseline units (``None``: no sequential test)."""
    cusum_limit: float | None = None
    """CUSUM decision limit h in baseline units."""

    def __post_init__(self) -> None:
        if self.indicator in INDICATOR_DIRECTIONS and self.direction != (
            expected := INDICATOR_DIRECTIONS[self.indicator]
        ):
            object.__setattr__(self, "direction", expected)
        if self.baseline_records < 1:
            raise ValueError(f"baseline_records must be >= 1, got {self.baseline_records}")
        if self.persistence < 1:
            raise ValueError(f"persistence must be >= 1, got {self.persistence}")
        if not (self.clear_level < self.warning_level <= self.alarm_level):
            raise ValueError(
                "levels must satisfy clear_level < warning_level <= alarm_level, got "
                f"{self.clear_level}, {self.warning_level}, {self.alarm_level}"
            )
        if self.spread_floor_fraction < 0 or self.spread_floor_abs <= 0:
            raise ValueError("spread floors must be >= 0 (fraction) and > 0 (absolute)")
        if self.min_baseline_records is not None and not (
            1 <= self.min_baseline_records <= self.baseline_records
        ):
            raise ValueError(
                "min_baseline_records must be between 1 and baseline_records, got "
                f"{self.min_baseline_records}"
            )
        if (self.cusum_reference is None) != (self.cusum_limit is None):
            raise ValueError("cusum_reference and cusum_limit are set together or not at all")
        if self.cusum_limit is not None and (
            self.cusum_limit <= 0 or self.cusum_reference is None or self.cusum_reference < 0
        ):
            raise ValueError("cusum_limit must be > 0 and cusum_reference >= 0")

    @property
    def first_scored_record(self) -> int:
        """Records collected before scoring starts."""
        if self.min_baseline_records is None:
            return self.baseline_records
        return self.min_baseline_records


@dataclass(frozen=True)
class Baseline:
    """Robust centre and spread of the first records of a track.

    >>> b = learn_baseline([1.0, 1.1, 0.9, 1.0, 1.2])
    >>> round(b.centre, 3), round(b.spread, 4)
    (1.0, 0.1483)
    >>> round(b.score(1.5), 2)
    3.37
    """

    centre: float
    spread: float
    count: int
    direction: Direction = "higher_is_worse"

    def score(self, value: float) -> float:
        """``value`` in baseline units, positive on the worse side."""
        signed = value - self.centre if self.direction == "higher_is_worse" else self.centre - value
        return signed / self.spread

    def value_at(self, score: float) -> float:
        """The value that lies ``score`` baseline units on the worse side (:meth:`score`'s inverse).

        >>> Baseline(1.0, 0.5, 5).value_at(4.0), Baseline(1.0, 0.5, 5, "lower_is_worse").value_at(4.0)
        (3.0, -1.0)
        """
        sign = 1.0 if self.direction == "higher_is_worse" else -1.0
        return self.centre + sign * score * self.spread

    def floored(self, spread_floor: float | None) -> Baseline:
        """The baseline scored with a spread never below ``spread_floor`` (``None``: itself)."""
        if spread_floor is None or spread_floor <= self.spread:
            return self
        return replace(self, spread=spread_floor)


@functools.lru_cache(maxsize=256)
def small_sample_factor(count: int) -> float:
    """``t_{0.975, c−1} / 1.96``: how much wider a spread learned from ``c`` records is taken.

    >>> round(small_sample_factor(3), 2), round(small_sample_factor(8), 2)
    (2.2, 1.21)
    """
    from scipy import stats  # here, not at the top: see learn_baseline

    return float(stats.t.ppf(0.975, max(count, 2) - 1) / stats.norm.ppf(0.975))


def learn_baseline(
    values: Iterable[float],
    *,
    spread_floor_fraction: float = 0.05,
    spread_floor_abs: float = 1e-9,
    direction: Direction = "higher_is_worse",
    widen_small_samples: bool = False,
) -> Baseline:
    """Median and floored 1.4826·MAD of the finite ``values``.

    The floor is ``max(spread_floor_fraction·|median|, spread_floor_abs)``. With
    ``widen_small_samples`` the MAD spread is first multiplied by :func:`small_sample_factor`.

    >>> learn_baseline([2.0, 2.0, 2.0]).spread  # MAD = 0: the floor, 5 % of the centre
    0.1
    """
    array = np.asarray([v for v in values if math.isfinite(v)], dtype=np.float64)
    if array.size == 0:
        raise ValueError("a baseline needs at least one finite value")
    centre = float(np.median(array))
    floor = max(spread_floor_fraction * abs(centre), spread_floor_abs)
    # scipy.stats is imported here, not at the top: it takes ~0.6 s, and storage (so every CLI
    # command that reads the database, and the service) imports this module
    from scipy import stats

    spread = float(stats.median_abs_deviation(array, scale="normal"))
    if widen_small_samples:
        spread *= small_sample_factor(int(array.size))
    return Baseline(centre, max(spread, floor), int(array.size), direction)


@dataclass(frozen=True)
class TrackState:
    """Everything :func:`step` needs to remember about one track between records."""

    baseline_values: tuple[float, ...] = ()
    """Values collected while the baseline is being learned."""
    baseline: Baseline | None = None
    level: Level = "normal"
    """Severity of the open alarm, ``normal`` when none is open."""
    acknowledged: bool = False
    above_warning: int = 0
    """Consecutive records above the warning level."""
    above_alarm: int = 0
    below_clear: int = 0
    cusum: float = 0.0
    """Page's CUSUM of the scores (stays 0 when the rule has no sequential test)."""

    @property
    def alarm_state(self) -> str | None:
        """The state an alarm row shows (``None`` when no alarm is open)."""
        if self.level == "normal":
            return None
        return "acknowledged" if self.acknowledged else self.level

    def to_dict(self) -> dict[str, Any]:
        baseline = None
        if self.baseline is not None:
            baseline = {
                "centre": self.baseline.centre,
                "spread": self.baseline.spread,
                "count": self.baseline.count,
                "direction": self.baseline.direction,
            }
        return {
            "baseline_values": list(self.baseline_values),
            "baseline": baseline,
            "level": self.level,
            "acknowledged": self.acknowledged,
            "above_warning": self.above_warning,
            "above_alarm": self.above_alarm,
            "below_clear": self.below_clear,
            "cusum": self.cusum,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TrackState:
        baseline = data.get("baseline")
        return cls(
            baseline_values=tuple(float(v) for v in data.get("baseline_values", ())),
            baseline=Baseline(**baseline) if baseline else None,
            level=data.get("level", "normal"),
            acknowledged=bool(data.get("acknowledged", False)),
            above_warning=int(data.get("above_warning", 0)),
            above_alarm=int(data.get("above_alarm", 0)),
            below_clear=int(data.get("below_clear", 0)),
            cusum=float(data.get("cusum", 0.0)),
        )


@dataclass(frozen=True)
class Transition:
    """A change of the track's alarm: ``opened`` is True when a new alarm starts here."""

    kind: TransitionKind
    opened: bool
    value: float
    score: float
    evidence: str = "level"
    """What raised it: ``"level"`` (records above a level for ``persistence`` records) or
    ``"cusum"`` (the sequential test); ``"level"`` for a clearing."""


@dataclass(frozen=True)
class Evaluation:
    state: TrackState
    score: float | None
    """The value in baseline units (``None`` while learning or for a non-finite value)."""
    transitions: tuple[Transition, ...] = ()
    spread: float | None = None
    """The spread the score was computed with: the track's own, or the ``pooled_floor`` where
    that is larger (``None`` when not scored)."""


def pooled_spread(value_sets: Iterable[Sequence[float]], min_tracks: int = 3) -> float | None:
    """How much one track's values move from record to record, pooled over tracks of the same
    kind (the teeth of one channel): a robust standard deviation about each track's own mean.

    Each track with ``n ≥ 2`` finite values gives its sample variance ``s²`` on ``n − 1`` degrees
    of freedom, divided by the median of ``χ²(n − 1)/(n − 1)`` so that it is unbiased in the
    median; the result is the square root of the median over tracks, so a few tracks that move
    more (a tooth with a manufacturing well, a tooth already failing) do not set it. ``None``
    with fewer than ``min_tracks`` such tracks.

    >>> round(pooled_spread([[0.0, 2.0], [1.0, 3.0], [5.0, 7.0], [0.0, 20.0]]), 1)
    2.1
    >>> pooled_spread([[1.0], [2.0, 3.0]]) is None
    True
    """
    normalised: list[float] = []
    for values in value_sets:
        array = np.asarray(values, dtype=float)
        array = array[np.isfinite(array)]
        if array.size < 2:
            continue
        dof = array.size - 1
        normalised.append(float(np.var(array, ddof=1)) / _chi2_median_over_dof(dof))
    if len(normalised) < min_tracks:
        return None
    return math.sqrt(float(np.median(normalised)))


@functools.lru_cache(maxsize=256)
def _chi2_median_over_dof(dof: int) -> float:
    """The median of ``χ²(dof)/dof``: a sample variance's median in units of the true one."""
    from scipy import stats  # here, not at the top: see learn_baseline

    return float(stats.chi2.ppf(0.5, dof)) / dof


def step(
    state: TrackState, value: float, rule: RuleSettings, pooled_floor: float | None = None
) -> Evaluation:
    """Feed one accepted record's value to a track.

    ``pooled_floor`` (record-relative indicators: :func:`pooled_spread` of the channel's tracks
    before this record) is a further floor of the spread the value is scored against: a
    tooth's own few baseline records cannot see how much a healthy tooth's score moves from day
    to day, its channel's teeth together can. The stored baseline is the track's own.

    >>> rule = RuleSettings("mci_depth", baseline_records=3, persistence=2)
    >>> state = TrackState()
    >>> for v in [1.0, 1.0, 1.0, 2.0, 2.0]:
    ...     result = step(state, v, rule)
    ...     state = result.state
    >>> state.level, [t.kind for t in result.transitions]
    ('alarm', ['alarm'])
    """
    if not math.isfinite(value):
        return Evaluation(state, None)
    if state.baseline is None and rule.indicator in SELF_REFERENCED_INDICATORS:
        state = replace(state, baseline=Baseline(0.0, 1.0, 0, rule.direction))
    if state.baseline is None:
        collected = (*state.baseline_values, float(value))
        if len(collected) < rule.first_scored_record:
            return Evaluation(replace(state, baseline_values=collected), None)
        return Evaluation(replace(state, **_grown_baseline(state.baseline_values, value, rule)), None)

    baseline = state.baseline.floored(pooled_floor)
    score = baseline.score(value)
    cusum = state.cusum
    if rule.cusum_reference is not None:
        cusum = max(0.0, cusum + score - rule.cusum_reference)
    cusum_fired = rule.cusum_limit is not None and cusum > rule.cusum_limit
    above_alarm = state.above_alarm + 1 if score > rule.alarm_level else 0
    above_warning = state.above_warning + 1 if score > rule.warning_level else 0
    below_clear = state.below_clear + 1 if score < rule.clear_level else 0
    level, acknowledged = state.level, state.acknowledged
    transitions: list[Transition] = []
    k = rule.persistence
    if level == "normal":
        if above_alarm >= k:
            level = "alarm"
            transitions.append(Transition("alarm", True, value, score))
        elif cusum_fired:
            level = "alarm"
            transitions.append(Transition("alarm", True, value, score, "cusum"))
        elif above_warning >= k:
            level = "warning"
            transitions.append(Transition("warning", True, value, score))
    elif below_clear >= k:
        level, acknowledged, cusum = "normal", False, 0.0
        transitions.append(Transition("cleared", False, value, score))
    elif level == "warning" and (above_alarm >= k or cusum_fired):
        # Escalation: an acknowledged warning needs a new acknowledgement as an alarm.
        level, acknowledged = "alarm", False
        evidence = "level" if above_alarm >= k else "cusum"
        transitions.append(Transition("alarm", False, value, score, evidence))
    new_state = replace(
        state,
        level=level,
        acknowledged=acknowledged,
        above_warning=above_warning,
        above_alarm=above_alarm,
        below_clear=below_clear,
        cusum=cusum,
    )
    if (
        rule.indicator not in SELF_REFERENCED_INDICATORS
        and len(state.baseline_values) < rule.baseline_records
        and level == "normal"
        and score < rule.clear_level
        and cusum == 0.0
    ):
        # short campaigns: an early record that looks normal joins the baseline
        new_state = replace(new_state, **_grown_baseline(state.baseline_values, value, rule))
    return Evaluation(new_state, score, tuple(transitions), baseline.spread)


def _grown_baseline(
    values: tuple[float, ...], value: float, rule: RuleSettings
) -> dict[str, Any]:
    collected = (*values, float(value))
    baseline = learn_baseline(
        collected,
        spread_floor_fraction=rule.spread_floor_fraction,
        spread_floor_abs=rule.spread_floor_abs,
        direction=rule.direction,
        widen_small_samples=rule.min_baseline_records is not None,
    )
    if rule.indicator in RECORD_RELATIVE_INDICATORS and baseline.centre < 0:
        baseline = replace(baseline, centre=0.0)
    return {"baseline_values": collected, "baseline": baseline}


def acknowledge(state: TrackState) -> TrackState:
    """The state after an operator acknowledged the open alarm (``ValueError`` if none is open
    or it is already acknowledged)."""
    if state.level == "normal":
        raise ValueError("no open alarm to acknowledge")
    if state.acknowledged:
        raise ValueError("the alarm is already acknowledged")
    return replace(state, acknowledged=True)


def run(
    values: Sequence[float], rule: RuleSettings, acknowledge_after: Iterable[int] = ()
) -> tuple[list[str | None], list[list[Transition]]]:
    """Feed a whole sequence; acknowledge right after the records whose indices are given.

    Returns the alarm state after every record (``None`` = no open alarm) and its transitions.
    Meant for tests, notebooks and explaining a rule.

    >>> states, _ = run([1, 1, 1, 9, 9, 9, 1, 1], RuleSettings("kurtosis", 3, persistence=2),
    ...                 acknowledge_after=[4])
    >>> states
    [None, None, None, None, 'acknowledged', 'acknowledged', 'acknowledged', None]
    """
    acks = set(acknowledge_after)
    state = TrackState()
    states: list[str | None] = []
    transitions: list[list[Transition]] = []
    for index, value in enumerate(values):
        result = step(state, float(value), rule)
        state = result.state
        if index in acks:
            state = acknowledge(state)
        states.append(state.alarm_state)
        transitions.append(list(result.transitions))
    return states, transitions
