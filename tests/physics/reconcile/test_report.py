"""The reconciliation HTML report: one sentence of conclusion, readable tables, no JSON dump,
escaped strings, and an order spectrum zoomed to its content. Results are built by hand on a
small synthetic hunting spectrum (no simulation): what is checked is the page, not the fit."""

from __future__ import annotations

import re

import numpy as np
import pytest

from physics.config import GearPairModel
from physics.reconcile.observables import HuntingSpectrum
from physics.reconcile.report import (
    conclusion,
    content_order_limits,
    describe_finding,
    html_report,
    parameter_unit,
)
from physics.reconcile.results import Finding, ReconciliationResult

PINION, GEAR, SPR = 20, 21, 160
REVS = GEAR  # lcm(20, 21) / 20 pinion revolutions per hunting period


def _spectrum() -> tuple[HuntingSpectrum, np.ndarray]:
    """Noise at −100 dB everywhere, mesh harmonics 1 and 2 (pinion orders 20 and 40) and a
    pinion 1× line at −40 dB; the fit band covers orders 0–70."""
    n = REVS * SPR
    bins = n // 2 + 1
    rng = np.random.default_rng(3)
    variance = np.full(bins, 1e-10)
    target = (rng.standard_normal(bins) + 1j * rng.standard_normal(bins)) * np.sqrt(variance / 2)
    for order in (1, 20, 40):
        target[order * REVS] = 0.01
    used = np.zeros(bins, bool)
    used[1 : 70 * REVS] = True
    spec = HuntingSpectrum(
        mean=target, variance=variance, used=used, segment_spectra=target[None, :], pinion_teeth=PINION,
        gear_teeth=GEAR, revs_per_hunt=REVS, samples_per_rev=SPR, speed_rpm=600.0, segments=4,
        pinion_average=np.zeros(SPR),
    )
    return spec, target


ECCENTRICITY = Finding(
    mechanism="pinion_eccentricity", wheel="pinion", tooth=None,
    parameters={"amplitude_um": 2.1, "phase_deg": 40.0},
    ci95={"amplitude_um": [1.8, 2.4], "phase_deg": [35.0, 45.0]},
    evidence={"delta_bic": -850.0, "p_value": 1e-30, "delta_chi2": 880.0}, chi2_dof_after=1.01,
)
SPALL = Finding(
    mechanism="tooth_spall", wheel="pinion", tooth=16, parameters={"depth_um": 32.0},
    ci95={"depth_um": [30.0, 34.0]}, evidence={"delta_bic": -9e5, "p_value": 0.0, "delta_chi2": 9e5},
    chi2_dof_after=7083.0, model_form="defect on pinion tooth 16; spall-like; its shape is not captured",
)
FINAL = {"chi2_dof": 1.01, "chi2_dof_bounds": [0.98, 1.02], "misfit": 0.001, "excess_explained": 0.99,
         "dof": 20000, "remaining": []}


def _result(status: str, findings: list[Finding], final: dict, model_form: dict | None = None,
            **changes: object) -> ReconciliationResult:
    spec, target = _spectrum()
    base = target.copy()
    base[1 * REVS] = 0.0
    fields: dict = dict(
        status=status,
        baseline={"mechanisms": [], "chi2_dof": 95.0, "misfit": 0.2, "dof": 20000},
        mismatches=[{"domain": "order", "class": "pinion_1x", "orders": [1], "share": 0.9},
                    {"domain": "angle", "wheel": "pinion", "teeth": [16], "angle_deg": [279.0, 297.0], "share": 0.05}],
        findings=findings, unresolved=[], final=final, updated_model=GearPairModel(),
        calibrated_base_model=GearPairModel(), spectrum=spec, target=target,
        weights_variance=spec.variance, base_prediction=base, final_prediction=target * 0.99,
        model_form=model_form or {},
    )
    fields.update(changes)
    return ReconciliationResult(**fields)


def test_conclusion_explained() -> None:
    sentence = conclusion(_result("explained", [ECCENTRICITY], FINAL).to_json())
    assert sentence == "Explained: pinion eccentricity 2.1 µm (1.8–2.4) on the pinion; nothing left."


def test_conclusion_partly_explained_names_the_defect_and_what_is_left() -> None:
    final = dict(FINAL, chi2_dof=7083.0)
    model_form = {"defects": [{"place": "pinion tooth 16", "like": "tooth_spall", "members": [],
                               "reasons": ["several mechanisms on one tooth"],
                               "residual": {"chi2_dof": 7083.0}, "message": SPALL.model_form}],
                  "compensating": True}
    sentence = conclusion(_result("partly_explained", [SPALL], final, model_form).to_json())
    assert sentence.startswith("Partly explained: defect on pinion tooth 16, spall-like; its shape is not captured")
    assert "χ²/dof 7083 left" in sentence and sentence.endswith(".")


def test_conclusion_not_explained_points_at_the_rest() -> None:
    final = dict(FINAL, chi2_dof=42.5, remaining=[{"domain": "frequency", "band_hz": [1000.0, 1200.0], "share": 0.7}])
    sentence = conclusion(_result("not_explained", [], final).to_json())
    assert sentence.startswith("Not explained: no catalogue mechanism accounts for the mismatch (χ²/dof 42.5 left")
    assert "1000–1200 Hz" in sentence


def test_describe_finding_and_units() -> None:
    assert describe_finding(SPALL.to_json()) == "tooth spall 32 µm (30–34) on pinion tooth 16"
    assert parameter_unit("stiffness_loss_fraction") == "" and parameter_unit("delay_us") == "µs"


@pytest.fixture(scope="module")
def page() -> str:
    findings = [ECCENTRICITY, SPALL]
    unresolved = [{"candidates": ["index_error pinion tooth 16", "tooth_crack pinion tooth 16"],
                   "delta_bic": [-40.0, -37.0], "separate_by": "a record at another load"}]
    scored = [{"round": 1, "top": [{"candidate": "tooth_spall pinion tooth 16", "delta_bic": -9e5, "p_value": 0.0},
                                   {"candidate": "tooth_crack pinion tooth 16", "delta_bic": -8e5, "p_value": 0.0}]}]
    model_form = {"defects": [], "not_separable_here": {"sliding_friction": "needs a sensor <off> the line of action"},
                  "intervals": "95 % intervals: cluster-robust"}
    result = _result("partly_explained", findings, dict(FINAL, chi2_dof=3.2), model_form,
                     unresolved=unresolved, candidates_scored=scored)
    return html_report(result, title="reconcile <script>alert('x')</script> & rig")


def test_page_has_tables_and_no_json_dump(page: str) -> None:
    assert '{"' not in page and "&#34;" not in page and "{&#" not in page
    assert page.count("data:image/png;base64,") == 3
    first = page.index('id="conclusion"')
    assert first < page.index('id="findings"') < page.index("data:image/png")
    assert re.search(r'id="conclusion">Partly explained: ', page)
    for table in ("fit", "findings", "mismatches", "unresolved", "not-separable", "rejected"):
        assert f'id="{table}"' in page, table
    # Every finding is a row of the findings table, with its parameters and intervals.
    findings_table = page[page.index('id="findings"'): page.index("</table>", page.index('id="findings"'))]
    assert findings_table.count("<tr") == 1 + 3  # header + 2 rows of the eccentricity + 1 of the spall
    for text in ("pinion eccentricity", "tooth spall", "amplitude", "1.8 – 2.4", "depth", "30 – 34", "µm", "-850", "7083"):
        assert text in findings_table, text
    # The accepted candidate is not listed as rejected; the runner-up is.
    rejected = page[page.index('id="rejected"'):]
    assert "tooth crack pinion tooth 16" in rejected and "tooth spall pinion tooth 16" not in rejected


def test_page_escapes_hostile_strings(page: str) -> None:
    assert "<script>" not in page
    assert "&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt; &amp; rig" in page
    assert "&lt;off&gt;" in page


def test_spectrum_zoom_follows_the_content() -> None:
    spec, target = _spectrum()
    used = spec.used
    level = 20 * np.log10(np.abs(target[used]))
    floor = 10 * np.log10(spec.variance[used])
    lo, hi = content_order_limits(spec.pinion_orders[used], level, floor)
    assert 0 < lo < 1 and 40 < hi <= 43  # content at orders 1 … 40, not the band's 0 … 70
    # A clean record far above its floor everywhere: a line 65 dB below the peak (order 65)
    # does not widen the view; one 50 dB below it does.
    orders = spec.pinion_orders[used]
    clean = np.full(orders.size, -110.0)
    clean[np.isin(orders, [1.0, 20.0, 40.0])] = -40.0
    clean[orders == 65.0] = -105.0
    assert content_order_limits(orders, clean, np.full(orders.size, -200.0))[1] < 43
    clean[orders == 65.0] = -90.0
    assert content_order_limits(orders, clean, np.full(orders.size, -200.0))[1] > 65
    # Nothing above the floor: the whole band.
    assert content_order_limits(spec.pinion_orders[used], floor, floor) == (
        pytest.approx(spec.pinion_orders[used].min()), pytest.approx(spec.pinion_orders[used].max()))
