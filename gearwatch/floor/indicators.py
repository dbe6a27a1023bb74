"""What each stored indicator is: per tooth or whole record, its unit, a short title.

One place for the operator-facing facts about indicators, used by the REST API (trends, CSV
exports, alarms), the command line, the campaign report and the dashboard (through the API).
Units of amplitude indicators follow the accelerometer channel's unit (``m/s^2``, ``g`` …):
:func:`indicator_unit` turns the template into the unit of one channel.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from gearwatch.floor.results import METRIC_NAMES, STORED_TOOTH_INDICATORS

Scope = Literal["tooth", "record"]

CHANNEL_UNIT = "{unit}"
"""Template of a unit that is the channel's (e.g. RMS in m/s²)."""
CHANNEL_UNIT_SQUARED = "({unit})^2"
BASELINE_UNITS = "baseline units"
"""Scores: robust spreads above the baseline centre."""


@dataclass(frozen=True)
class IndicatorInfo:
    name: str
    scope: Scope
    title: str
    unit_template: str
    """``""`` for dimensionless values, else a unit, possibly with ``{unit}`` (the channel's)."""


_INFO: dict[str, tuple[str, str]] = {
    # per tooth
    "mci_depth": ("MCI depth", "Np"),
    "diff_energy": ("difference-signal energy", CHANNEL_UNIT_SQUARED),
    "diff_kurtosis": ("difference-signal kurtosis", ""),
    "score": ("per-tooth score", BASELINE_UNITS),
    "nonsync_z": ("non-synchronous power against the record's teeth", BASELINE_UNITS),
    "change": ("change against the tooth's own history", "noise units"),
    "mci_depth_se": ("MCI depth standard error", "Np"),
    # whole record
    "rms": ("RMS of the pinion average", CHANNEL_UNIT),
    "peak": ("peak of the pinion average", CHANNEL_UNIT),
    "crest": ("crest factor", ""),
    "kurtosis": ("kurtosis of the pinion average", ""),
    "fm0": ("FM0", ""),
    "fm4": ("FM4", ""),
    "na4": ("NA4", ""),
    "residual_kurtosis": ("kurtosis of the residual (NA4 of the record alone)", ""),
    "nb4": ("NB4", ""),
    "m6a": ("M6A", ""),
    "m8a": ("M8A", ""),
    "er": ("energy ratio", ""),
    "raw_rms": ("RMS of the raw signal", CHANNEL_UNIT),
    "raw_kurtosis": ("kurtosis of the raw signal", ""),
}


def tooth_indicators() -> tuple[str, ...]:
    """Per-tooth indicators gearwatch stores (:data:`gearwatch.floor.results.STORED_TOOTH_INDICATORS`)."""
    return tuple(STORED_TOOTH_INDICATORS)


def record_indicators() -> tuple[str, ...]:
    """Whole-record indicators (:data:`gearwatch.floor.results.METRIC_NAMES`)."""
    return tuple(METRIC_NAMES)


def all_indicators() -> tuple[str, ...]:
    return tooth_indicators() + record_indicators()


def indicator_info(name: str) -> IndicatorInfo:
    """Scope, title and unit template of a stored indicator (``ValueError`` if unknown)."""
    if name in STORED_TOOTH_INDICATORS:
        scope: Scope = "tooth"
    elif name in METRIC_NAMES:
        scope = "record"
    else:
        raise ValueError(
            f"unknown indicator {name!r} (known: {', '.join(all_indicators())})"
        )
    title, unit = _INFO.get(name, (name, ""))
    return IndicatorInfo(name=name, scope=scope, title=title, unit_template=unit)


def indicator_unit(name: str, channel_unit: str | None) -> str:
    """The unit of ``name`` on a channel measured in ``channel_unit`` (``""``: dimensionless).

    >>> indicator_unit("mci_depth", "g"), indicator_unit("rms", "m/s^2"), indicator_unit("fm4", "g")
    ('Np', 'm/s^2', '')
    >>> indicator_unit("rms", "")
    'channel unit'
    """
    template = indicator_info(name).unit_template
    if "{unit}" not in template:
        return template
    return template.format(unit=channel_unit or "channel unit")
