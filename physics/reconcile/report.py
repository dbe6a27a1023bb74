"""JSON and HTML report of a :class:`~physics.reconcile.results.ReconciliationResult`.

The HTML page is self-contained (figures as inline PNG): the order spectrum of the recording,
the calibrated base and the updated model; the whitened angle-domain residual over the
pinion revolution before and after; and the moving cepstrum integral (MCI) of the recording,
the base model and the updated model. It opens with one sentence of conclusion, then tables
(findings with their 95 % intervals, mismatches, unresolved pairs, model-form defects);
the JSON stays the machine-readable form. Rendered from ``templates/reconcile.html.j2``.
"""

from __future__ import annotations

import base64
import io
import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dsp.mci import moving_cepstrum_integral
from physics.reconcile.honesty import LIKE
from physics.reconcile.localize import whitened_angle_residual
from physics.reconcile.results import ReconciliationResult

TEMPLATES = Path(__file__).resolve().parent / "templates"


def pinion_average_from_spectrum(spectrum: NDArray[np.complex128], revs_per_hunt: int, samples_per_rev: int) -> NDArray[np.float64]:
    """One pinion revolution of the pinion-periodic part of a hunting spectrum (``FFT/N`` scaled).

    Examples
    --------
    >>> import numpy as np
    >>> s = np.zeros(200, complex); s[21 * 3] = 0.5
    >>> x = pinion_average_from_spectrum(s, 21, 16)
    >>> bool(np.allclose(x, np.cos(2 * np.pi * 3 * np.arange(16) / 16)))
    True
    """
    bins = spectrum[::revs_per_hunt][: samples_per_rev // 2 + 1]
    full = np.zeros(samples_per_rev // 2 + 1, dtype=np.complex128)
    full[: bins.size] = bins
    return np.asarray(np.fft.irfft(full * samples_per_rev, n=samples_per_rev), dtype=np.float64)


def content_order_limits(
    orders: NDArray[np.float64],
    level_db: NDArray[np.float64],
    floor_db: NDArray[np.float64],
    above_db: float = 15.0,
    dynamic_range_db: float = 60.0,
    margin_fraction: float = 0.05,
) -> tuple[float, float]:
    """x-limits (pinion orders) of the order spectrum around its content.

    The content is every order whose level exceeds the noise floor by more than ``above_db``
    and lies within ``dynamic_range_db`` of the strongest order (a simulated or very clean
    record sits far above its floor everywhere; what a reader looks at is near the top); the
    limits span it with ``margin_fraction`` of its width (at least one order) on each side,
    the lower limit no lower than the first order shown. With no such order the whole range
    is returned. Non-finite levels are ignored. 15 dB: a noise-only bin whose power is
    exponentially distributed around the floor exceeds it by 15 dB with probability
    exp(−31.6), so not one of a record's ~10⁵ bins widens the view by chance.

    Examples
    --------
    >>> import numpy as np
    >>> o = np.arange(1, 471.0); floor = np.full(o.size, -100.0); level = floor.copy()
    >>> level[[19, 39, 59]] = -40.0      # orders 20, 40, 60
    >>> content_order_limits(o, level, floor)
    (18.0, 62.0)
    >>> level[39] = -10.0; level[300] = -80.0   # order 301: above the floor, 70 dB below the peak
    >>> content_order_limits(o, level, floor)
    (18.0, 62.0)
    >>> content_order_limits(o, floor, floor)
    (1.0, 470.0)
    """
    orders = np.asarray(orders, dtype=np.float64)
    if orders.size == 0:
        return (0.0, 1.0)
    level = np.asarray(level_db, dtype=np.float64)
    excess = level - np.asarray(floor_db, dtype=np.float64)
    finite = np.isfinite(excess) & np.isfinite(level)
    peak = float(level[finite].max()) if finite.any() else 0.0
    content = orders[finite & (excess > above_db) & (level > peak - dynamic_range_db)]
    if content.size == 0:
        return (float(orders.min()), float(orders.max()))
    lo, hi = float(content.min()), float(content.max())
    margin = max(1.0, margin_fraction * (hi - lo))
    return (max(float(orders.min()), lo - margin), min(float(orders.max()), hi + margin))


def _png(fig: Any) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    return base64.b64encode(buf.getvalue()).decode("ascii")


def figures(result: ReconciliationResult) -> dict[str, str]:
    """Base64 PNG figures, by name."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    spec = result.spectrum
    used = spec.used
    orders = spec.pinion_orders
    out: dict[str, str] = {}

    def db(x: NDArray[np.complex128]) -> NDArray[np.float64]:
        return np.asarray(20 * np.log10(np.maximum(np.abs(x), 1e-12)), dtype=np.float64)

    fig, ax = plt.subplots(figsize=(10, 3.6))
    ax.plot(orders[used], db(result.target[used]), lw=0.6, label="recording", color="k", zorder=3)
    ax.plot(orders[used], db(result.base_prediction[used]), lw=0.6, label="base (calibrated)", alpha=0.8)
    ax.plot(orders[used], db(result.final_prediction[used]), lw=0.6, label="updated model", alpha=0.8)
    ax.plot(orders[used], 10 * np.log10(result.weights_variance[used]), lw=0.6, label="noise of the average", color="0.6")
    lo, hi = content_order_limits(
        orders[used], db(result.target[used]), 10 * np.log10(np.maximum(result.weights_variance[used], 1e-300))
    )
    ax.set_xlim(lo, hi)
    # The models are exactly zero between their lines; clip the view at the recording's own
    # low end so those dips do not squeeze the content into the top of the plot.
    recording_db = db(result.target[used])
    finite = recording_db[np.isfinite(recording_db)]
    if finite.size:
        ax.set_ylim(float(np.percentile(finite, 1)) - 10.0, float(finite.max()) + 5.0)
    ax.set_xlabel("pinion order (cycles per pinion revolution)")
    ax.set_ylabel("level (dB re 1 m/s²)")
    ax.legend(fontsize=8, ncol=4)
    ax.set_title("Hunting-period order spectrum")
    out["order_spectrum"] = _png(fig)
    plt.close(fig)

    n = spec.revs_per_hunt * spec.samples_per_rev
    fig, ax = plt.subplots(figsize=(10, 3.2))
    angle = np.arange(spec.samples_per_rev) / spec.samples_per_rev * 360.0
    for label, pred in (("before (base)", result.base_prediction), ("after (updated)", result.final_prediction)):
        res = whitened_angle_residual(result.target - pred, result.weights_variance, used, n)
        ax.plot(angle, res.reshape(spec.revs_per_hunt, -1).mean(axis=0), lw=0.7, label=label)
    ax.set_xlabel("pinion angle after the tach reference (deg)")
    ax.set_ylabel("whitened residual (σ of the noise)")
    ax.legend(fontsize=8)
    ax.set_title("Angle-domain residual (pinion-periodic part)")
    out["angle_residual"] = _png(fig)
    plt.close(fig)

    spm = spec.samples_per_rev // spec.pinion_teeth
    fig, ax = plt.subplots(figsize=(10, 3.2))
    for label, spectrum in (
        ("recording", result.target),
        ("base model", result.base_prediction),
        ("updated model", result.final_prediction),
    ):
        avg = pinion_average_from_spectrum(spectrum, spec.revs_per_hunt, spec.samples_per_rev)
        mci = moving_cepstrum_integral(avg, spm).filtered
        ax.plot(angle, mci, lw=0.8, label=label)
    ax.set_xlabel("pinion angle after the tach reference (deg)")
    ax.set_ylabel("MCI (Np)")
    ax.legend(fontsize=8)
    ax.set_title("Moving cepstrum integral of the pinion average")
    out["mci"] = _png(fig)
    plt.close(fig)
    return out


def html_report(result: ReconciliationResult, title: str = "gearwatch reconciliation") -> str:
    """A self-contained HTML page: one sentence of conclusion, tables, figures (no JSON).

    The full JSON (:meth:`ReconciliationResult.to_json`) stays the machine-readable form
    (``gearwatch reconcile --json``, the REST result); this page is for people.
    """
    data = result.to_json()
    figs = figures(result)
    template = _environment().get_template("reconcile.html.j2")
    return str(
        template.render(
            title=title,
            conclusion=conclusion(data),
            data=data,
            findings=[_finding_row(f) for f in data["findings"]],
            mismatches=[_mismatch_row(m) for m in data["mismatches"]],
            remaining=[_mismatch_row(m) for m in data["final"].get("remaining", [])],
            unresolved=[_unresolved_row(u) for u in data["unresolved"]],
            defects=[_defect_row(d) for d in data["model_form"].get("defects", [])],
            rejected=_rejected_rows(result.candidates_scored, data["findings"]),
            figures=[(FIGURE_TITLES.get(name, name.replace("_", " ")), png) for name, png in figs.items()],
        )
    )


# ---------------------------------------------------------------------------------------------
# the conclusion sentence and the table rows

FIGURE_TITLES = {
    "order_spectrum": "Order spectrum: recording, base and updated model",
    "angle_residual": "Residual over the pinion revolution, before and after",
    "mci": "Moving cepstrum integral (MCI) of the pinion average",
}

STATUS_WORDS = {
    "explained": "Explained",
    "partly_explained": "Partly explained",
    "not_explained": "Not explained",
}

UNITS = {"um": "µm", "us": "µs", "deg": "°", "hz": "Hz", "fraction": "", "ratio": "", "pct": "%"}
"""Unit of a parameter from the suffix of its name (the catalogue names carry their units)."""


def parameter_unit(name: str) -> str:
    """Display unit of a catalogue parameter name (``amplitude_um`` → ``µm``; none → ``""``).

    Examples
    --------
    >>> parameter_unit("amplitude_um"), parameter_unit("phase_deg"), parameter_unit("fraction")
    ('µm', '°', '')
    """
    suffix = name.rsplit("_", 1)[-1].lower()
    return UNITS.get(suffix, "")


def parameter_label(name: str) -> str:
    """``amplitude_um`` → ``amplitude``; ``stiffness_loss_fraction`` → ``stiffness loss fraction``."""
    parts = name.split("_")
    if len(parts) > 1 and parts[-1].lower() in UNITS and parts[-1].lower() not in {"fraction", "ratio"}:
        parts = parts[:-1]
    return " ".join(parts)


def fmt(value: Any, digits: int = 3) -> str:
    """A number for people: ``digits`` significant digits, ``—`` for none/non-finite."""
    if value is None:
        return "—"
    if isinstance(value, bool) or not isinstance(value, int | float):
        return str(value)
    v = float(value)
    if not math.isfinite(v):
        return "—"
    if v != 0 and (abs(v) >= 1e5 or abs(v) < 1e-3):
        return f"{v:.1e}"
    text = f"{v:.{digits}g}"
    return text if "e" not in text else f"{v:.0f}"


def _value_with_interval(name: str, value: Any, ci: Any) -> str:
    unit = parameter_unit(name)
    text = fmt(value) + (f" {unit}" if unit and unit != "°" else unit)
    if ci and len(ci) == 2:
        text += f" ({fmt(ci[0])}–{fmt(ci[1])})"
    return text


def _place(f: dict[str, Any]) -> str:
    wheel, tooth = f.get("wheel"), f.get("tooth")
    if tooth is not None:
        place = f"on {wheel} tooth {tooth}" if wheel else f"on tooth {tooth}"
        if f.get("tooth_in_record") is not None:  # gear teeth: record_json's gear_tooth_frame
            place += f" (tooth {f['tooth_in_record']} in the record's frame)"
        return place
    return f"on the {wheel}" if wheel else ""


def _mechanism_name(f: dict[str, Any]) -> str:
    name = str(f["mechanism"]).replace("_", " ")
    wheel = f.get("wheel")
    if wheel and f.get("tooth") is None and not name.startswith(str(wheel)):
        name = f"{wheel} {name}"
    return name


def describe_finding(f: dict[str, Any]) -> str:
    """``pinion eccentricity 2.1 µm (1.8–2.4) on the pinion``: the lead parameter (phases left
    out: they say where, not how much) with its 95 % interval, and the place."""
    params = {k: v for k, v in (f.get("parameters") or {}).items() if not k.endswith("phase_deg")}
    ci = f.get("ci95") or {}
    text = _mechanism_name(f)
    if params:
        key = next(iter(params))
        label = parameter_label(key)
        value = _value_with_interval(key, params[key], ci.get(key))
        text += f" {value}" if label in {"amplitude", "depth", "error"} else f" {label} {value}"
    place = _place(f)
    return f"{text} {place}".strip()


def _remaining_where(final: dict[str, Any]) -> str:
    remaining = final.get("remaining") or []
    if not remaining:
        return ""
    return _mismatch_row(remaining[0])["where"]


def conclusion(data: dict[str, Any]) -> str:
    """One sentence from the status, the lead findings and the ``model_form`` block.

    Examples
    --------
    >>> f = {"mechanism": "pinion_eccentricity", "wheel": "pinion", "tooth": None,
    ...      "parameters": {"amplitude_um": 2.1, "phase_deg": 40.0},
    ...      "ci95": {"amplitude_um": [1.8, 2.4]}}
    >>> conclusion({"status": "explained", "findings": [f], "final": {"chi2_dof": 1.0},
    ...             "model_form": {}})
    'Explained: pinion eccentricity 2.1 µm (1.8–2.4) on the pinion; nothing left.'
    >>> conclusion({"status": "not_explained", "findings": [], "final": {"chi2_dof": 1.22},
    ...             "model_form": {"mesh_line_form_error": {"relative_rms": 0.45}}})
    "Not explained: no catalogue mechanism accounts for the mismatch (χ²/dof 1.22 left); the mesh model misses this record's mesh lines by 45%."
    """
    status = str(data.get("status", ""))
    head = STATUS_WORDS.get(status, status.replace("_", " ").capitalize() or "Unknown")
    findings = data.get("findings") or []
    final = data.get("final") or {}
    model_form = data.get("model_form") or {}
    defects = model_form.get("defects") or []
    left = fmt(final.get("chi2_dof"), 4)
    bounds = final.get("chi2_dof_bounds")
    expected = f", expected {fmt(bounds[0])}–{fmt(bounds[1])}" if bounds and len(bounds) == 2 else ""
    where = _remaining_where(final)
    rest = f"; most of the rest in {where}" if where else ""
    form_error = (model_form.get("mesh_line_form_error") or {}).get("relative_rms")
    if form_error:
        rest += f"; the mesh model misses this record's mesh lines by {form_error:.0%}"
    if status == "explained":
        what = "; ".join(describe_finding(f) for f in findings[:3]) or "the calibrated base model already matches the recording"
        return f"{head}: {what}; nothing left."
    if defects:
        shown = []
        for d in defects[:2]:
            like = LIKE.get(str(d.get("like")), str(d.get("like", "")).replace("_", " "))
            shown.append(f"defect on {d.get('place')}, {like}")
        others = [describe_finding(f) for f in findings if not f.get("model_form")][:2]
        also = ("; also " + "; ".join(others)) if others else ""
        return f"{head}: {'; '.join(shown)}; its shape is not captured (χ²/dof {left} left{expected}){also}."
    if findings:
        what = "; ".join(describe_finding(f) for f in findings[:3])
        return f"{head}: {what}; χ²/dof {left} left{expected}{rest}."
    return f"{head}: no catalogue mechanism accounts for the mismatch (χ²/dof {left} left{expected}){rest}."


def _finding_row(f: dict[str, Any]) -> dict[str, Any]:
    ci = f.get("ci95") or {}
    parameters = [
        {"name": parameter_label(k), "value": fmt(v), "unit": parameter_unit(k),
         "interval": f"{fmt(ci[k][0])} – {fmt(ci[k][1])}" if k in ci and len(ci[k]) == 2 else "—"}
        for k, v in (f.get("parameters") or {}).items()
    ]
    evidence = f.get("evidence") or {}
    return {
        "mechanism": str(f["mechanism"]).replace("_", " "),
        "wheel": f.get("wheel") or "—",
        "tooth": "—" if f.get("tooth") is None else (
            f["tooth"] if f.get("tooth_in_record") is None
            else f"{f['tooth']} (record: {f['tooth_in_record']})"),
        "order": f.get("order"),
        "parameters": parameters,
        "delta_bic": fmt(evidence.get("delta_bic"), 4),
        "p_value": fmt(evidence.get("p_value"), 2),
        "chi2_dof_after": fmt(f.get("chi2_dof_after"), 4),
        "model_form": f.get("model_form"),
    }


def _mismatch_row(m: dict[str, Any]) -> dict[str, Any]:
    domain = str(m.get("domain", ""))
    if domain == "order":
        orders = m.get("orders") or []
        shown = ", ".join(fmt(o) for o in orders[:6]) + (" …" if len(orders) > 6 else "")
        where = f"{str(m.get('class', '')).replace('_', ' ')}" + (f" (orders {shown})" if shown else "")
    elif domain == "angle":
        teeth = ", ".join(str(t) for t in m.get("teeth") or [])
        angle = m.get("angle_deg") or []
        where = f"{m.get('wheel')} tooth {teeth}" + (f" ({fmt(angle[0])}°–{fmt(angle[1])}°)" if len(angle) == 2 else "")
    elif "band_hz" in m:
        band = m.get("band_hz") or []
        where = f"{domain.replace('_', ' ')} band {fmt(band[0])}–{fmt(band[1])} Hz" if len(band) == 2 else domain
        if m.get("peak_hz") is not None:
            where += f", peak {fmt(m['peak_hz'])} Hz"
    else:
        where = domain.replace("_", " ")
    return {"domain": domain.replace("_", " "), "where": where, "share": _percent(m.get("share"))}


def _percent(share: Any) -> str:
    if not isinstance(share, int | float) or not math.isfinite(float(share)):
        return "—"
    return f"{100.0 * float(share):.0f} %"


def _unresolved_row(u: dict[str, Any]) -> dict[str, Any]:
    candidates = [str(c) for c in u.get("candidates") or []]
    bics = u.get("delta_bic") or []
    return {
        "candidates": " vs ".join(c.replace("_", " ") for c in candidates),
        "delta_bic": " vs ".join(fmt(b, 4) for b in bics),
        "separate_by": str(u.get("separate_by", "")),
    }


def _defect_row(d: dict[str, Any]) -> dict[str, Any]:
    residual = d.get("residual") or {}
    members = "; ".join(
        str(m.get("mechanism", "")).replace("_", " ") + " "
        + ", ".join(_value_with_interval(k, v, (m.get("ci95") or {}).get(k))
                    for k, v in (m.get("parameters") or {}).items() if not k.endswith("phase_deg"))
        for m in d.get("members") or []
    )
    return {
        "place": d.get("place", ""),
        "like": LIKE.get(str(d.get("like")), str(d.get("like", "")).replace("_", " ")),
        "members": members,
        "reasons": [str(r) for r in d.get("reasons") or []],
        "chi2_dof": fmt(residual.get("chi2_dof"), 4),
    }


def _finding_label(f: dict[str, Any]) -> str:
    parts = [str(f["mechanism"])]
    if f.get("wheel"):
        parts.append(str(f["wheel"]))
    if f.get("tooth") is not None:
        parts.append(f"tooth {f['tooth']}")
    if f.get("order") is not None:
        parts.append(f"order {f['order']}")
    return " ".join(parts)


def _rejected_rows(scored: list[dict[str, Any]], findings: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The best three candidates of each selection round, less those that became findings."""
    accepted = [_finding_label(f) for f in findings]
    rows = []
    for rnd in scored:
        for c in rnd.get("top", [])[:3]:
            label = str(c.get("candidate", ""))
            if any(label == a or label.startswith(a + " ") for a in accepted):
                continue
            rows.append({"round": rnd.get("round"), "candidate": label.replace("_", " "),
                         "delta_bic": fmt(c.get("delta_bic"), 4), "p_value": fmt(c.get("p_value"), 2)})
    return rows


def _environment() -> Any:
    import jinja2

    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(TEMPLATES),
        autoescape=jinja2.select_autoescape(["html", "j2"]),
        trim_blocks=True,
        lstrip_blocks=True,
    )
    env.filters["num"] = fmt
    return env
