"""Alarm logic on hand-made sequences: baseline, direction, persistence, hysteresis, ack."""

from __future__ import annotations

import json
import math
import statistics

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from detection.alarms import (
    INDICATOR_DIRECTIONS,
    RuleSettings,
    TrackState,
    acknowledge,
    indicator_direction,
    learn_baseline,
    pooled_spread,
    run,
    step,
)
from gearwatch.floor.defaults import MAD_TO_SIGMA
from gearwatch.floor.results import METRIC_NAMES, STORED_TOOTH_INDICATORS

# Baseline of [10, 10, 10, 10] → centre 10, MAD 0, spread = floor = 5 % of 10 = 0.5.
BASE = [10.0, 10.0, 10.0, 10.0]
SPREAD = 0.5


def v(score: float) -> float:
    """The value that lies ``score`` baseline units above the BASE centre."""
    return 10.0 + score * SPREAD


def rule(**overrides: float) -> RuleSettings:
    settings: dict = {
        "indicator": "mci_depth",
        "baseline_records": 4,
        "warning_level": 4.0,
        "alarm_level": 8.0,
        "clear_level": 2.0,
        "persistence": 3,
    }
    settings.update(overrides)
    return RuleSettings(**settings)


# -- baseline --------------------------------------------------------------------------------
def test_baseline_is_median_and_scaled_mad_against_statistics_module() -> None:
    values = [3.0, 7.0, 1.0, 4.0, 100.0, 5.0, 6.0]
    centre = statistics.median(values)
    mad = statistics.median(abs(x - centre) for x in values)
    baseline = learn_baseline(values, spread_floor_fraction=0.0)
    assert baseline.centre == centre == 5.0
    # scipy's scale="normal" is 1/Φ⁻¹(3/4) = 1.4826022…, 1.5e-6 relative above 1.4826.
    assert baseline.spread == pytest.approx(1.4826 * mad, rel=2e-6)
    assert baseline.count == 7


def test_scaled_mad_estimates_gaussian_sigma() -> None:
    samples = np.random.default_rng(7).normal(3.0, 2.0, 40_000)
    baseline = learn_baseline(samples.tolist(), spread_floor_fraction=0.0)
    assert baseline.spread == pytest.approx(2.0, rel=0.03)
    assert MAD_TO_SIGMA == pytest.approx(1 / 0.6744897501960817, rel=1e-4)


def test_spread_floor_relative_and_absolute() -> None:
    assert learn_baseline([2.0, 2.0, 2.0]).spread == pytest.approx(0.1)
    assert learn_baseline([0.0, 0.0, 0.0], spread_floor_abs=1e-3).spread == 1e-3
    # A real spread above the floor is kept.
    assert learn_baseline([1.0, 2.0, 3.0]).spread == pytest.approx(1.4826, rel=2e-6)


def test_baseline_ignores_non_finite_and_refuses_empty() -> None:
    assert learn_baseline([1.0, math.nan, 3.0, math.inf]).centre == 2.0
    with pytest.raises(ValueError):
        learn_baseline([math.nan])


def test_directions_cover_every_indicator_and_larger_is_worse() -> None:
    assert set(INDICATOR_DIRECTIONS) == set(STORED_TOOTH_INDICATORS) | set(METRIC_NAMES)
    assert indicator_direction("mci_depth") == "higher_is_worse"
    with pytest.raises(ValueError, match="unknown indicator"):
        indicator_direction("nonsense")


def test_score_sign_follows_direction() -> None:
    high = learn_baseline(BASE, direction="higher_is_worse")
    low = learn_baseline(BASE, direction="lower_is_worse")
    assert high.score(12.0) == pytest.approx(4.0)
    assert low.score(12.0) == pytest.approx(-4.0)
    assert low.score(8.0) == pytest.approx(4.0)


def test_lower_is_worse_rule_alarms_on_a_drop() -> None:
    falling = RuleSettings("custom", baseline_records=4, persistence=2,
                           direction="lower_is_worse")
    states, _ = run([*BASE, 5.0, 5.0], falling)
    assert states[-1] == "alarm"
    rising_states, _ = run([*BASE, 15.0, 15.0], falling)
    assert rising_states[-1] is None


def test_known_indicator_direction_cannot_be_overridden() -> None:
    assert RuleSettings("mci_depth", direction="lower_is_worse").direction == "higher_is_worse"


# -- learning ----------------------------------------------------------------------------------
def test_no_alarm_while_learning_even_for_huge_values() -> None:
    states, transitions = run([1e9, 1e9, 1e9], rule())
    assert states == [None, None, None]
    assert all(not t for t in transitions)


def test_baseline_is_learned_from_first_n_values_only() -> None:
    state = TrackState()
    for value in [*BASE, v(1), v(1), v(1)]:
        state = step(state, value, rule()).state
    assert state.baseline is not None
    assert state.baseline.centre == 10.0 and state.baseline.count == 4
    assert state.baseline_values == tuple(BASE)


# -- persistence -----------------------------------------------------------------------------
def test_warning_opens_exactly_at_the_kth_consecutive_record() -> None:
    states, transitions = run([*BASE, v(5), v(5), v(5)], rule())
    assert states == [None] * 6 + ["warning"]
    assert [(t.kind, t.opened) for t in transitions[6]] == [("warning", True)]
    assert transitions[6][0].score == pytest.approx(5.0)


def test_one_record_below_the_level_resets_persistence() -> None:
    values = [*BASE, v(5), v(5), v(3), v(5), v(5)]
    states, _ = run(values, rule())
    assert all(s is None for s in states)
    states, _ = run([*values, v(5)], rule())
    assert states[-1] == "warning"


def test_k_records_beyond_alarm_level_open_an_alarm_directly() -> None:
    states, transitions = run([*BASE, v(9), v(9), v(9)], rule())
    assert states[-1] == "alarm"
    assert [(t.kind, t.opened) for t in transitions[-1]] == [("alarm", True)]


def test_warning_escalates_after_k_records_beyond_alarm_level() -> None:
    # Two beyond warning, then alarm-level values: warning opens at the 3rd excursion
    # (only 1 beyond alarm so far), escalation needs 3 consecutive beyond alarm.
    values = [*BASE, v(5), v(5), v(9), v(9), v(9)]
    states, transitions = run(values, rule())
    assert states[4:] == [None, None, "warning", "warning", "alarm"]
    assert [(t.kind, t.opened) for t in transitions[-1]] == [("alarm", False)]


def test_persistence_one_reacts_on_the_first_record() -> None:
    states, _ = run([*BASE, v(4.5)], rule(persistence=1))
    assert states[-1] == "warning"


def test_level_is_strictly_beyond() -> None:
    states, _ = run([*BASE, v(4.0), v(4.0), v(4.0)], rule())
    assert states[-1] is None


# -- hysteresis ------------------------------------------------------------------------------
def test_values_between_clear_and_warning_keep_the_alarm_open() -> None:
    values = [*BASE, v(5), v(5), v(5)] + [v(3)] * 20
    states, _ = run(values, rule())
    assert states[-1] == "warning"


def test_clears_after_k_records_below_clear_level() -> None:
    values = [*BASE, v(5), v(5), v(5), v(1), v(1), v(3), v(1), v(1), v(1)]
    states, transitions = run(values, rule())
    # v(3) interrupted the first run of two: clearing needs three in a row again.
    assert states[7:] == ["warning", "warning", "warning", "warning", "warning", None]
    assert [(t.kind, t.opened) for t in transitions[-1]] == [("cleared", False)]


def test_a_new_excursion_after_clearing_opens_a_new_alarm() -> None:
    values = [*BASE, v(5), v(5), v(5), v(0), v(0), v(0), v(5), v(5), v(5)]
    states, transitions = run(values, rule())
    assert states[-1] == "warning"
    opened = [i for i, ts in enumerate(transitions) for t in ts if t.opened]
    assert opened == [6, 12]


# -- acknowledgement ---------------------------------------------------------------------------
def test_ack_keeps_warning_quiet_then_escalation_re_alarms_then_ack_again() -> None:
    values = [*BASE, v(5), v(5), v(5), v(6), v(6), v(9), v(9), v(9), v(9), v(1), v(1), v(1)]
    states, transitions = run(values, rule(), acknowledge_after=[6, 12])
    assert states[6:] == [
        "acknowledged",  # warning acknowledged
        "acknowledged",
        "acknowledged",  # still warning level: stays acknowledged
        "acknowledged",
        "acknowledged",
        "alarm",  # 3 records beyond alarm: re-escalated, needs a new ack
        "acknowledged",
        "acknowledged",  # the new ack survives while it clears ...
        "acknowledged",
        None,  # ... and the alarm clears after 3 records below the clear level
    ]
    kinds = [(i, t.kind) for i, ts in enumerate(transitions) for t in ts]
    assert kinds == [(6, "warning"), (11, "alarm"), (15, "cleared")]


def test_acknowledged_alarm_stays_acknowledged_when_values_grow() -> None:
    values = [*BASE, v(9), v(9), v(9), v(50), v(90), v(500)]
    states, transitions = run(values, rule(), acknowledge_after=[6])
    assert states[6:] == ["acknowledged"] * 4
    assert not any(transitions[7:])


def test_acknowledge_needs_an_open_unacknowledged_alarm() -> None:
    with pytest.raises(ValueError, match="no open alarm"):
        acknowledge(TrackState())
    state = TrackState(level="warning")
    with pytest.raises(ValueError, match="already"):
        acknowledge(acknowledge(state))


# -- odds and ends -----------------------------------------------------------------------------
def test_non_finite_values_change_nothing() -> None:
    values = [*BASE[:2], math.nan, *BASE[2:], v(5), math.nan, v(5), math.inf, v(5)]
    states, _ = run(values, rule())
    assert states[-1] == "warning"  # NaN did not reset persistence, nor count in the baseline
    result = step(TrackState(), math.nan, rule())
    assert result.state == TrackState() and result.score is None


def test_state_round_trips_through_json() -> None:
    state = TrackState()
    for value in [*BASE, v(5), v(5), v(5), v(9)]:
        state = step(state, value, rule()).state
    state = acknowledge(state)
    again = TrackState.from_dict(json.loads(json.dumps(state.to_dict())))
    assert again == state


@pytest.mark.parametrize(
    "overrides",
    [
        {"baseline_records": 0},
        {"persistence": 0},
        {"clear_level": 5.0},  # not below warning
        {"warning_level": 9.0},  # above alarm
        {"spread_floor_abs": 0.0},
    ],
)
def test_invalid_rules_are_refused(overrides: dict) -> None:
    with pytest.raises(ValueError):
        rule(**overrides)


@settings(max_examples=200, deadline=None)
@given(
    scores=st.lists(st.floats(-5, 15, allow_nan=False), min_size=0, max_size=40),
    persistence=st.integers(1, 4),
)
def test_transitions_obey_persistence_and_hysteresis(scores: list[float], persistence: int) -> None:
    """Independent check of every transition against the score history."""
    settings_ = rule(persistence=persistence)
    values = [*BASE, *(v(s) for s in scores)]
    states, transitions = run(values, settings_)
    history = [(v(s) - 10.0) / SPREAD for s in scores]  # the scores the track sees
    previous: str | None = None
    for index, (state, ts) in enumerate(zip(states[4:], transitions[4:], strict=True)):
        window = history[max(0, index - persistence + 1): index + 1]
        full = len(window) == persistence
        for t in ts:
            if t.kind == "warning":
                assert full and all(s > 4.0 for s in window) and previous is None
            elif t.kind == "alarm":
                assert full and all(s > 8.0 for s in window) and previous in (None, "warning")
            else:
                assert full and all(s < 2.0 for s in window) and previous is not None
        if not ts:
            assert state == previous
        previous = state


def test_docstring_examples_run() -> None:
    import doctest

    import detection.alarms

    outcome = doctest.testmod(detection.alarms)
    assert outcome.attempted >= 6 and outcome.failed == 0


# --- short-campaign baselines, the CUSUM and the default per-tooth score rule (issue 10) ---


def score_rule(**overrides: object) -> RuleSettings:
    from detection.default_rules import DEFAULT_RULES

    return RuleSettings("score", **{**DEFAULT_RULES["score"], **overrides})  # type: ignore[arg-type]


def test_short_campaign_scores_from_the_third_record_and_learns_only_normal_records() -> None:
    rule = RuleSettings("fm4", baseline_records=8, min_baseline_records=3, spread_floor_abs=0.1)
    state = TrackState()
    scores = []
    for value in [3.0, 3.1, 2.9, 3.05, 9.0]:
        result = step(state, value, rule)
        state, scores = result.state, [*scores, result.score]
    assert scores[:3] == [None, None, None] and scores[3] is not None
    assert state.baseline_values == (3.0, 3.1, 2.9, 3.05)   # 9.0 looked abnormal: not learned
    assert state.baseline is not None and state.baseline.count == 4


def test_small_samples_widen_the_spread() -> None:
    values = [1.0, 1.2, 0.9]
    plain = learn_baseline(values)
    widened = learn_baseline(values, widen_small_samples=True)
    assert widened.spread == pytest.approx(plain.spread * 2.2, rel=0.01)


def test_cusum_alarms_on_a_persistent_change_below_the_levels() -> None:
    rule = RuleSettings("score", baseline_records=3, warning_level=4.0, alarm_level=6.0,
                        spread_floor_abs=1.0, cusum_reference=1.0, cusum_limit=4.0)
    states, transitions = run([0.0, 0.0, 0.0, 3.0, 3.0, 3.0], rule)
    # scores 3, 3, 3 never reach the warning level; S = 2, 4, 6 crosses h = 4 on the third
    assert states == [None, None, None, None, None, "alarm"]
    assert [(t.kind, t.evidence) for t in transitions[5]] == [("alarm", "cusum")]


def test_cusum_restarts_when_the_alarm_clears() -> None:
    rule = RuleSettings("score", baseline_records=3, spread_floor_abs=1.0, persistence=1,
                        cusum_reference=1.0, cusum_limit=4.0)
    state = TrackState()
    for value in [0.0, 0.0, 0.0, 9.0, 9.0, 0.0]:
        state = step(state, value, rule).state
    assert state.level == "normal" and state.cusum == 0.0


def test_a_level_alarm_says_so() -> None:
    _, transitions = run([0.0, 0.0, 0.0, 9.0, 9.0], RuleSettings("score", 3, spread_floor_abs=1.0))
    assert [(t.kind, t.evidence) for t in transitions[4]] == [("alarm", "level")]


def test_cusum_settings_are_checked() -> None:
    with pytest.raises(ValueError):
        RuleSettings("score", cusum_reference=1.0)
    with pytest.raises(ValueError):
        RuleSettings("score", cusum_reference=1.0, cusum_limit=0.0)
    with pytest.raises(ValueError):
        RuleSettings("score", baseline_records=4, min_baseline_records=5)


def test_default_score_rule_false_alarm_rate_on_pure_noise() -> None:
    # A healthy tooth's score is ≈ N(0, 1) record to record (dsp.toothscore; 0.86 SD measured):
    # 3000 seven-record tracks of N(0, 1) scores (12,000 scored tooth-days, ≈ 37 campaigns of 80
    # teeth) open 1 alarm with this seed; the bound allows sampling error and states the rate:
    # at most 0.25 per 1,000 tooth-days on pure noise.
    rng = np.random.default_rng(5)
    rule = score_rule()
    opened = 0
    for values in rng.standard_normal((3000, 7)):
        _, transitions = run(values, rule)
        opened += sum(t.opened for ts in transitions for t in ts)
    assert opened <= 3


def test_default_score_rule_alarms_on_a_growing_spall() -> None:
    # a tooth whose score jumps by 4 standard errors on the onset day, then doubles: an alarm
    # by the next day; from 3 standard errors, by the day after (the rule is the strict
    # companion of ``change``, which sees such a spall first: detection/default_rules.py)
    baseline = [0.3, -0.2, 0.5]
    states, _ = run([*baseline, 4.0, 8.0, 16.0], score_rule())
    assert states[3] is None and states[4] == "alarm"
    states, _ = run([*baseline, 3.0, 6.0, 12.0], score_rule())
    assert states[4] is None and states[5] == "alarm"


def test_wind_turbine_raw_kurtosis_alarms_on_the_first_risen_record() -> None:
    # raw_kurtosis of the 10 real records of examples/windturbine-hss as gearwatch computes
    # them (`gearwatch analyze`, rounded to 3 decimals): flat at ≈ 3.1 for five records, a
    # little up on the 6th, clearly up from the 7th. The default rule (scoring from the 3rd
    # record, CUSUM) alarms on the 7th — the fixed 8-record baseline could not before the 10th.
    from detection.default_rules import DEFAULT_RULES

    raw_kurtosis = [3.041, 3.007, 3.142, 3.097, 3.097, 3.381, 3.887, 3.938, 4.606, 5.437]
    states, _ = run(raw_kurtosis, RuleSettings("raw_kurtosis", **DEFAULT_RULES["raw_kurtosis"]))
    assert states.index("alarm") == 6



def test_fm4_rule_waits_out_two_ordinary_days_and_alarms_on_a_third() -> None:
    """The default FM4 rule's CUSUM (k = 1.5, h = 5): two records about three spreads up — an
    ordinary pair of operating days on the independent simulator — open nothing; a third does
    (3 × 1.8 > 5). With the former h = 3.5 the second record opened an alarm on a healthy rig
    (``detection/default_rules.py``)."""
    from detection.default_rules import DEFAULT_RULES

    settings = {k: v for k, v in DEFAULT_RULES["fm4"].items() if k != "enabled"}
    fm4 = RuleSettings("fm4", **settings)
    baseline = [3.0, 3.0, 3.0]  # spread = the 10 % floor = 0.3
    up = 3.0 + 3.3 * 0.3  # 3.3 spreads: below the warning (4) and its persistence
    states, _ = run([*baseline, up, up], fm4)
    assert states[-1] is None
    states, _ = run([*baseline, up, up, up], fm4)
    assert states[-2] is None and states[-1] == "alarm"
    former = RuleSettings("fm4", **{**settings, "cusum_limit": 3.5})
    assert run([*baseline, up, up], former)[0][-1] == "alarm"

def test_a_quiet_tooth_becoming_typical_is_not_an_alarm_standing_out_is() -> None:
    """``score`` is relative to the record's other teeth (0 = typical): its baseline centre is
    never below 0. The same values on an indicator without that rule would alarm."""
    quiet_then_typical = [-4.0, -5.0, -4.5, 0.3, 0.5, 0.2, 0.4]
    # at levels loose enough for the rise to count (warning 4, CUSUM k = 2; the default is stricter)
    looser = score_rule(warning_level=4.0, cusum_reference=2.0)
    states, _ = run(quiet_then_typical, looser)
    assert states[-1] is None and all(s is None for s in states)
    absolute = RuleSettings("mci_depth_se", **{  # same settings, an ordinary indicator
        k: v for k, v in looser.__dict__.items() if k not in ("indicator", "direction")})
    assert run(quiet_then_typical, absolute)[0][-1] is not None
    standing_out = [-4.0, -5.0, -4.5, 6.0, 7.0, 8.0]
    assert run(standing_out, score_rule())[0][-1] is not None


# -- pooled day-to-day spread (record-relative indicators) -----------------------------------


def test_pooled_spread_estimates_the_within_track_sigma_without_bias() -> None:
    # 20 teeth × 3 baseline records (the default rule's first scored record), each tooth its own
    # mean, day-to-day SD 2.5: the median of 400 estimates lies within 5 % of 2.5
    rng = np.random.default_rng(11)
    estimates = [
        pooled_spread(rng.normal(rng.normal(0, 5, (20, 1)), 2.5, (20, 3)).tolist())
        for _ in range(400)
    ]
    assert np.median(estimates) == pytest.approx(2.5, rel=0.05)


def test_pooled_spread_is_not_set_by_a_few_restless_teeth() -> None:
    rng = np.random.default_rng(12)
    values = rng.normal(0.0, 1.0, (20, 5))
    values[:3] *= 10.0  # three teeth whose score moves ten times more (a well, a failing tooth)
    assert pooled_spread(values.tolist()) == pytest.approx(1.0, abs=0.35)
    assert pooled_spread(values[:2].tolist()) is None  # too few tracks to pool


def test_a_pooled_spread_larger_than_the_tracks_own_scores_with_it_and_keeps_the_baseline() -> None:
    state = TrackState()
    for value in (0.0, 0.1, -0.1):
        state = step(state, value, score_rule()).state
    assert state.baseline is not None
    own = step(state, 4.0, score_rule())
    pooled = step(state, 4.0, score_rule(), pooled_floor=4.0)
    assert own.spread == state.baseline.spread < 4.0
    assert pooled.spread == 4.0 and pooled.score == pytest.approx(1.0)
    # a value that scores as normal joins the baseline, which stays the track's own
    assert pooled.state.baseline is not None and pooled.state.baseline.spread < 4.0
    smaller = step(state, 4.0, score_rule(), pooled_floor=1e-3)
    assert smaller.score == own.score  # a floor, never a narrowing


def test_pooled_spread_keeps_long_record_scores_from_false_alarms() -> None:
    # Long records: a healthy tooth's score moves by ~2.5 of its record's standard errors from day
    # to day (benchmarks/bench_detection.py --revolutions 300 measured 2.2), which the rule's floor
    # of 1 does not see. 40 teeth × 80 seven-day campaigns, each tooth its own mean: scored with
    # the teeth's pooled spread, at most 0.5 alarms per 1,000 tooth-days; on its own baseline
    # alone, many more (the measured reason for pooling).
    rng = np.random.default_rng(13)
    rule = score_rule()
    campaigns, teeth = 80, 40
    opened = {True: 0, False: 0}
    for _campaign in range(campaigns):
        days = rng.normal(rng.normal(0.0, 1.0, (teeth, 1)), 2.5, (teeth, 7))
        for pooling in (True, False):
            states = [TrackState() for _ in range(teeth)]
            for day in range(7):
                spread = pooled_spread(s.baseline_values for s in states) if pooling else None
                for tooth in range(teeth):
                    evaluation = step(states[tooth], float(days[tooth, day]), rule, spread)
                    states[tooth] = evaluation.state
                    opened[pooling] += sum(t.opened for t in evaluation.transitions)
    tooth_days = campaigns * teeth * 4  # days 4–7 are scored
    assert opened[True] / tooth_days * 1000 <= 0.5
    assert opened[False] > 5 * max(opened[True], 1)


def test_the_stored_rule_settings_are_every_setting_of_a_rule() -> None:
    """Storage, the alarm use-case and the REST schema copy a rule's settings by
    ``RULE_SETTING_NAMES``: a setting added to ``RuleSettings`` without it would be silently
    dropped on the way from the database to the evaluation."""
    from dataclasses import fields

    from detection.alarms import RULE_SETTING_NAMES, RuleSettings
    from service.schemas import AlarmRuleOut
    from storage.models import AlarmRule

    settings = {f.name for f in fields(RuleSettings)} - {"indicator", "direction"}
    assert set(RULE_SETTING_NAMES) == settings
    columns = set(AlarmRule.__table__.columns.keys())
    assert set(RULE_SETTING_NAMES) <= columns, set(RULE_SETTING_NAMES) - columns
    assert set(RULE_SETTING_NAMES) <= set(AlarmRuleOut.model_fields)
