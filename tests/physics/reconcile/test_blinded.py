"""A small blinded proof: scenarios drawn by the generator, graded by the separate scorer.

One scenario per class (the full-size run is ``benchmarks/bench_reconcile.py --blinded``).
The truth differs from the fitting model by the hidden physics and by model-form error
(finer integration step, base parameters perturbed within tolerance).

The ``occupied`` class (42 s of CPU; measured 6/6 right in the benchmark) and the
``out_of_catalogue`` class are not run here. The latter's one scenario took 244 s of CPU (forward
selection tries every mechanism before it gives up), more than the four others together, and
CI must stay under 15 minutes. That an effect the catalogue cannot shape is reported as not
explained is tested on a foreign spall shape in ``test_model_form.py`` and measured at scale by
the benchmark (6/6 flagged in its last run).
"""

from __future__ import annotations

import pytest

from physics.reconcile import reconcile
from physics.reconcile.scenarios import draw_scenarios, measured_of, score, score_table

from .conftest import fast_options

CLASSES = ["control", "below_raw_floor", "occupied", "gear_shaft"]
"""Drawn in this order (the draw of each class depends on the ones before it)."""
RUN = ("control", "below_raw_floor", "gear_shaft")
"""Reconciled here; ``occupied`` (42 s of CPU) is drawn but left to the benchmark, like
``out_of_catalogue``, to keep CI under 15 minutes."""


@pytest.fixture(scope="module")
def graded() -> list[dict[str, object]]:
    rows = []
    for scenario in draw_scenarios(CLASSES, per_class=1, seed=11):
        if scenario.klass not in RUN:
            continue
        result = reconcile(measured_of(scenario, seconds=5.0), scenario.fit_model, options=fast_options())
        rows.append(score(scenario, result.to_json()))
    print()
    print(score_table(rows))  # the table, for the log
    return rows


def _row(rows: list[dict[str, object]], klass: str) -> dict[str, object]:
    return next(r for r in rows if r["class"] == klass)


@pytest.mark.slow
def test_control_has_no_finding_and_is_explained(graded: list[dict[str, object]]) -> None:
    row = _row(graded, "control")
    assert row["false_finding"] is False
    assert row["status"] == "explained"


@pytest.mark.slow
@pytest.mark.parametrize("klass", ["below_raw_floor", "gear_shaft"])
def test_in_catalogue_mechanism_named_located_and_measured(graded: list[dict[str, object]], klass: str) -> None:
    row = _row(graded, klass)
    assert row["right_mechanism_and_place"] is True, row
    # One run each: the ≤ 10 % target is on the median over a set (benchmark); a single
    # near-floor run is held to 25 %.
    assert float(row["parameter_error"]) <= 0.25, row  # type: ignore[arg-type]
    assert row["status"] == "explained", row


def test_the_independent_truths_gear_teeth_are_scored_in_the_configurations_numbering() -> None:
    """Both simulators number gear teeth from their mesh origin; the project's record reaches its
    first tach edge after ``warmup_revolutions`` pinion revolutions (read here off a simulated
    record's pinion angle), the independent generator's after one (its record starts at a random
    angle in the first revolution). The scorer moves the truth's gear tooth by the difference:
    on the 20/21 rig at 1000 rpm, 3·20 ≡ −3 (mod 21), the offset every gear index error found
    had in the blinded run before this mapping."""
    import dataclasses
    import math

    import numpy as np

    from physics.independent import generate_record
    from physics.reconcile.scenarios import (
        INDEPENDENT_FIRST_EDGE_REVOLUTIONS,
        default_base,
        draw_independent,
        gear_tooth_in_configuration,
    )
    from physics.simulator import simulate, warmup_revolutions

    for rpm in (400.0, 1000.0, 3000.0):
        model = default_base().replace(
            operating=dataclasses.replace(default_base().operating, speed_rpm=rpm))
        record = simulate(model, seconds=0.3, seed=1)
        first = round(record.tach_pulse_times_s[0] * record.sample_rate_hz)
        assert warmup_revolutions(model) == round(record.pinion_angle_rad[first] / (2 * math.pi))
    scenario = draw_independent("indep_index_error", np.random.default_rng(2001), 2001, seconds=1.0)
    truth = generate_record(scenario.truth, seed=scenario.seed).truth
    assert math.ceil(truth["record"]["initial_pinion_angle_deg"] / 360.0) == INDEPENDENT_FIRST_EDGE_REVOLUTIONS
    z2 = scenario.fit_model.geometry.gear_teeth
    assert (scenario.fit_model.geometry.pinion_teeth, z2) == (20, 21)
    assert [gear_tooth_in_configuration(scenario, t, 1000.0) for t in (21, 5, 1)] == [18, 2, 19]


def test_a_gear_findings_tooth_in_the_records_frame_is_the_one_pinion_tooth_1_meets_first() -> None:
    """``tooth_in_record`` numbers gear teeth from the one pinion tooth 1 meets at the record's
    first revolution mark. Read off simulated records (the gear's angle at the first tach edge,
    in gear pitches from the mesh origin): at 400, 1000 and 3000 rpm the warm-up differs, so the
    configuration's tooth there differs, and it is the record's tooth 1 every time."""
    import dataclasses
    import math

    from physics.reconcile.results import ReconciliationResult
    from physics.reconcile.scenarios import default_base
    from physics.simulator import simulate

    met = set()
    for rpm in (400.0, 1000.0, 3000.0):
        model = default_base().replace(
            operating=dataclasses.replace(default_base().operating, speed_rpm=rpm))
        record = simulate(model, seconds=0.3, seed=1)
        first = round(record.tach_pulse_times_s[0] * record.sample_rate_hz)
        z2 = model.geometry.gear_teeth
        passed = round(abs(float(record.gear_angle_rad[first])) * z2 / (2 * math.pi))
        configuration_tooth = passed % z2 + 1
        met.add(configuration_tooth)
        result = ReconciliationResult.__new__(ReconciliationResult)
        result.calibrated_base_model = model
        result.spectrum = type("Spectrum", (), {"speed_rpm": rpm})()
        assert result.gear_tooth_in_record(configuration_tooth) == 1, rpm
        assert result.gear_tooth_in_record(configuration_tooth % z2 + 1) == 2, rpm
    assert len(met) > 1  # the configuration's numbering at the mark does move with the speed
