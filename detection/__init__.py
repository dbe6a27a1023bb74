"""State detection: baselines and alarm rules per rig, tooth and indicator (pure, no I/O).

See :mod:`detection.alarms` for the semantics (robust baseline, levels in baseline units,
persistence, hysteresis, acknowledgement).
"""

from detection.alarms import (
    INDICATOR_DIRECTIONS,
    RULE_SETTING_NAMES,
    Baseline,
    Evaluation,
    RuleSettings,
    TrackState,
    Transition,
    acknowledge,
    indicator_direction,
    learn_baseline,
    run,
    step,
)

__all__ = [
    "INDICATOR_DIRECTIONS",
    "RULE_SETTING_NAMES",
    "Baseline",
    "Evaluation",
    "RuleSettings",
    "TrackState",
    "Transition",
    "acknowledge",
    "indicator_direction",
    "learn_baseline",
    "run",
    "step",
]
