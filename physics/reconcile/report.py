"""JSON and HTML report of a :class:`~physics.reconcile.method.ReconciliationResult`.

The HTML page is self-contained (figures as inline PNG): the order spectrum of the recording,
the calibrated base and the updated model; the whitened angle-domain residual over the
pinion revolution before and after; and the moving cepstrum integral (MCI) of the recording,
the base model and the updated model.
"""

from __future__ import annotations

import base64
import html
import io
import json
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dsp.mci import moving_cepstrum_integral
from physics.reconcile.localize import whitened_angle_residual
from physics.reconcile.method import ReconciliationResult


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
    ax.plot(orders[used], db(result.target[used]), lw=0.6, label="recording", color="k")
    ax.plot(orders[used], db(result.base_prediction[used]), lw=0.6, label="base (calibrated)", alpha=0.8)
    ax.plot(orders[used], db(result.final_prediction[used]), lw=0.6, label="updated model", alpha=0.8)
    ax.plot(orders[used], 10 * np.log10(result.weights_variance[used]), lw=0.6, label="noise of the average", color="0.6")
    ax.set_xlabel("pinion order")
    ax.set_ylabel("dB re 1 m/s²")
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
    ax.set_ylabel("whitened residual")
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
    ax.set_xlabel("pinion angle (deg)")
    ax.set_ylabel("MCI (Np)")
    ax.legend(fontsize=8)
    ax.set_title("Moving cepstrum integral of the pinion average")
    out["mci"] = _png(fig)
    plt.close(fig)
    return out


def html_report(result: ReconciliationResult, title: str = "gearwatch reconciliation") -> str:
    """A self-contained HTML page."""
    data = result.to_json()
    figs = figures(result)
    rows = "".join(
        f"<tr><td>{html.escape(f['mechanism'])}</td><td>{html.escape(str(f['wheel']))}</td>"
        f"<td>{f['tooth'] if f['tooth'] is not None else ''}</td>"
        f"<td>{html.escape(json.dumps(f['parameters']))}</td><td>{html.escape(json.dumps(f['ci95']))}</td>"
        f"<td>{f['evidence'].get('delta_bic')}</td><td>{f['chi2_dof_after']}</td></tr>"
        for f in data["findings"]
    ) or "<tr><td colspan=7>none</td></tr>"
    mism = "".join(f"<li>{html.escape(json.dumps(m))}</li>" for m in data["mismatches"]) or "<li>none</li>"
    unres = "".join(f"<li>{html.escape(json.dumps(u))}</li>" for u in data["unresolved"]) or "<li>none</li>"
    imgs = "".join(f'<h2>{html.escape(k.replace("_", " "))}</h2><img src="data:image/png;base64,{v}">' for k, v in figs.items())
    final = data["final"]
    return f"""<!doctype html><html><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>body{{font-family:sans-serif;max-width:1100px;margin:auto}}td,th{{border:1px solid #ccc;padding:3px 6px}}
table{{border-collapse:collapse}} .status{{font-size:1.4em;font-weight:bold}}</style></head><body>
<h1>{html.escape(title)}</h1>
<p class="status">status: {html.escape(data["status"])}</p>
<p>baseline χ²/dof {data["baseline"]["chi2_dof"]}, misfit {data["baseline"]["misfit"]} →
final χ²/dof {final["chi2_dof"]} (bounds {final["chi2_dof_bounds"]}), misfit {final["misfit"]},
excess explained {final["excess_explained"]}</p>
<h2>Mismatches (base)</h2><ul>{mism}</ul>
<h2>Findings</h2><table><tr><th>mechanism</th><th>wheel</th><th>tooth</th><th>parameters</th><th>95 % interval</th><th>ΔBIC</th><th>χ²/dof after</th></tr>{rows}</table>
<h2>Unresolved</h2><ul>{unres}</ul>
{imgs}
<h2>JSON</h2><pre>{html.escape(json.dumps(data, indent=1))}</pre>
</body></html>"""
