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
