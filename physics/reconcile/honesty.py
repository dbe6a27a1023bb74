"""Model-form honesty: findings that compensate for each other are one defect the catalogue
cannot shape, and intervals must widen with the misfit they leave.

Forward selection keeps adding catalogue mechanisms while the misfit drops. When the truth is a
defect whose *shape* the catalogue lacks (a partial-face spall from another simulator), the
misfit left by the right mechanism at the right place is explained further by companions at
the same place — a crack and an index error on the spalled tooth, a second spall — each with a
narrow interval. This module recognises such groups and reports one defect with its place, what
it is most like, and the residual the catalogue could not explain:

* **same place**: two or more one-tooth findings on one tooth;
* **same order class** (pinion 1×: runout and shaft-locked speed fluctuation; gear 1×: runout
  and load fluctuation; mesh harmonics only: tip relief, friction on the line of action) when
  their parameters are strongly correlated in the joint fit or one sits at the edge of its
  physical range;
* **any pair** whose parameters are correlated beyond :data:`COMPENSATION_CORRELATION` in the
  joint fit (they trade the same residual).

Intervals (:func:`robust_covariance`) are the larger of the model-based covariance inflated
by χ²/dof and a cluster-robust ("sandwich") covariance whose clusters are the hunting bins
around each pinion order: model-form error leaves residuals that are correlated across the
sidebands a mechanism excites, and the sandwich then widens exactly the parameters whose
signature sits where the misfit is, where a global χ²/dof factor spreads it thin.

Examples
--------
>>> f = [{"mechanism": "tooth_spall", "wheel": "pinion", "tooth": 16, "parameters": {"depth_um": 32.0},
...       "evidence": {"delta_chi2": 9e5}},
...      {"mechanism": "tooth_crack", "wheel": "pinion", "tooth": 16,
...       "parameters": {"stiffness_loss_fraction": 0.83}, "evidence": {"delta_chi2": 2e5}}]
>>> groups = compensation_groups(f, np.eye(2))
>>> groups
[[0, 1]]
>>> d = describe_defect(f, groups[0], {"chi2_dof": 1550.0, "chi2_dof_bounds": [0.98, 1.02]}, [])
>>> d["message"]
'defect on pinion tooth 16; spall-like; its shape is not captured: tooth_spall depth_um 32, tooth_crack stiffness_loss_fraction 0.83 together leave χ²/dof 1550 (bounds 0.98–1.02)'
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

TOOTH_MECHANISMS = frozenset({"index_error", "tooth_spall", "tooth_crack"})

COMPENSATION_CORRELATION = 0.9
"""Two findings whose parameters correlate beyond this in the joint fit trade one residual."""

CLASS_CORRELATION = 0.5
"""Within one order class a weaker correlation already means compensation."""

LIKE = {
    "tooth_spall": "spall-like",
    "tooth_crack": "crack-like",
    "index_error": "index-error-like",
    "pinion_eccentricity": "pinion-runout-like",
    "gear_eccentricity": "gear-runout-like",
    "speed_fluctuation": "speed-fluctuation-like",
    "load_fluctuation": "load-fluctuation-like",
    "profile_modification": "profile-like",
    "sliding_friction": "friction-like",
    "structural_mode": "transfer-path-like",
    "contact_loss": "contact-loss-like",
}

PLAUSIBLE: dict[tuple[str, str], tuple[float, float]] = {
    ("tooth_spall", "depth_um"): (0.0, 55.0),
    ("tooth_crack", "stiffness_loss_fraction"): (0.0, 0.6),
    ("index_error", "error_um"): (-40.0, 40.0),
    ("pinion_eccentricity", "amplitude_um"): (0.0, 80.0),
    ("gear_eccentricity", "amplitude_um"): (0.0, 80.0),
    ("profile_modification", "pinion_tip_relief_um"): (-40.0, 60.0),
    ("profile_modification", "gear_tip_relief_um"): (-40.0, 60.0),
    ("sliding_friction", "friction_coefficient"): (0.0, 0.2),
    ("load_fluctuation", "fraction"): (0.0, 0.3),
    ("speed_fluctuation", "fraction"): (0.0, 0.05),
    ("structural_mode", "damping_ratio"): (0.004, 0.3),
}
"""Physical range of a fitted parameter: a finding outside it (or at its edge) is a sign that
the mechanism is absorbing misfit it does not cause (a 0.83 stiffness loss is a broken tooth,
not a crack; the spall bound of 60 µm is where depth stops being identifiable)."""


def order_class(finding: dict[str, Any]) -> str | None:
    """The order class a (non one-tooth) mechanism's signature lives in, if shared with others."""
    name = finding["mechanism"]
    order = finding.get("order")
    if name == "pinion_eccentricity" or (name == "speed_fluctuation" and order in (None, 1)):
        return "pinion_1x"
    if name == "gear_eccentricity" or (name == "load_fluctuation" and order in (None, 1)):
        return "gear_1x"
    if name in ("profile_modification", "sliding_friction", "contact_loss"):
        return "mesh_harmonics"
    return None


def at_edge(finding: dict[str, Any], margin: float = 0.02) -> list[str]:
    """Parameters of ``finding`` outside (or within ``margin`` of the edge of) :data:`PLAUSIBLE`."""
    out = []
    for key, value in finding["parameters"].items():
        rng = PLAUSIBLE.get((finding["mechanism"], key))
        if rng is None:
            continue
        lo, hi = rng
        width = hi - lo
        if (value <= lo + margin * width and lo != 0.0) or value >= hi - margin * width:
            out.append(key)
    return out


NEIGHBOUR_TEETH = 2
"""When the result is not explained, one-tooth findings this close on one wheel are one
defect's footprint: a defect wider than the catalogue's spreads its misfit onto the pairs in
contact with it (a contact ratio below 2 keeps two teeth either side in play)."""


def compensation_groups(
    findings: list[dict[str, Any]], correlation: FloatArray, explained: bool = True,
    teeth: dict[str, int] | None = None,
) -> list[list[int]]:
    """Indices of findings that compensate for each other (groups of two or more).

    ``correlation[i, j]`` is the largest absolute correlation between any parameter of finding
    ``i`` and any of finding ``j`` in the joint fit (the diagonal is ignored). When not
    ``explained``, one-tooth findings within :data:`NEIGHBOUR_TEETH` of each other on one wheel
    (``teeth``: tooth count per wheel, for the wrap-around) are grouped too.
    """
    n = len(findings)
    parent = list(range(n))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    def link(i: int, j: int) -> None:
        parent[root(i)] = root(j)

    for i in range(n):
        for j in range(i + 1, n):
            a, b = findings[i], findings[j]
            corr = float(abs(correlation[i, j])) if correlation.size else 0.0
            same_tooth = (
                a["mechanism"] in TOOTH_MECHANISMS
                and b["mechanism"] in TOOTH_MECHANISMS
                and a.get("wheel") == b.get("wheel")
                and a.get("tooth") == b.get("tooth")
            )
            if not same_tooth and not explained and a["mechanism"] in TOOTH_MECHANISMS \
                    and b["mechanism"] in TOOTH_MECHANISMS and a.get("wheel") == b.get("wheel"):
                z = (teeth or {}).get(str(a.get("wheel")), 10**6)
                gap = abs(int(a["tooth"]) - int(b["tooth"])) % z
                same_tooth = min(gap, z - gap) <= NEIGHBOUR_TEETH
            same_class = order_class(a) is not None and order_class(a) == order_class(b)
            edge = bool(at_edge(a) or at_edge(b))
            if same_tooth or (same_class and (corr >= CLASS_CORRELATION or edge)) or corr >= COMPENSATION_CORRELATION:
                link(i, j)
    groups: dict[int, list[int]] = {}
    for i in range(n):
        groups.setdefault(root(i), []).append(i)
    return [g for g in groups.values() if len(g) > 1]


def _fmt(v: float) -> str:
    return f"{v:.3g}" if abs(v) < 1000 else f"{v:.0f}"


def describe_defect(
    findings: list[dict[str, Any]],
    group: list[int],
    final: dict[str, Any],
    remaining: list[dict[str, Any]],
    correlation: FloatArray | None = None,
) -> dict[str, Any]:
    """One defect for a compensating group: place, what it is most like, the residual left.

    The lead is the member with the largest Δχ² of its own (its acceptance's evidence); the
    defect is "like" it. ``final`` is the result's ``final`` block, ``remaining`` its located
    remaining mismatches.
    """
    members = [findings[i] for i in group]
    lead = max(members, key=lambda f: float(f.get("evidence", {}).get("delta_chi2", 0.0)))
    teeth = {(f.get("wheel"), f.get("tooth")) for f in members if f["mechanism"] in TOOTH_MECHANISMS}
    if all(f["mechanism"] in TOOTH_MECHANISMS for f in members) and len({w for w, _t in teeth}) == 1:
        wheel, tooth = lead.get("wheel"), lead.get("tooth")
        place = f"{wheel} tooth {tooth}"
    else:
        wheel = lead.get("wheel")
        tooth = lead.get("tooth") if lead["mechanism"] in TOOTH_MECHANISMS else None
        place = f"{wheel} tooth {tooth}" if tooth is not None else (order_class(lead) or lead["mechanism"]).replace("_", " ")
        if wheel and tooth is None:
            place = f"{wheel} {place}" if not place.startswith(wheel) else place
    like = LIKE.get(lead["mechanism"], lead["mechanism"])
    reasons = []
    if len(teeth) == 1 and len(members) > 1:
        reasons.append("several mechanisms on one tooth")
    elif len(teeth) > 1 and len(members) > 1:
        reasons.append("one-tooth mechanisms on neighbouring teeth ("
                       + ", ".join(f"{w} {t}" for w, t in sorted(teeth, key=str)) + ")")
    classes = {order_class(f) for f in members} - {None}
    if len(classes) == 1 and len(members) > 1:
        reasons.append(f"several mechanisms in one order class ({next(iter(classes))})")
    edges = [f"{f['mechanism']} {k}" for f in members for k in at_edge(f)]
    if edges:
        reasons.append("at the edge of the physical range: " + ", ".join(edges))
    if correlation is not None and correlation.size and len(group) > 1:
        worst = max(float(abs(correlation[i, j])) for i in group for j in group if i != j)
        if worst >= CLASS_CORRELATION:
            reasons.append(f"parameters correlated up to {worst:.2f} in the joint fit")
    for f in members:
        for key, (a, b) in (f.get("ci95") or {}).items():
            rng = PLAUSIBLE.get((f["mechanism"], key))
            if rng is not None and b - a >= 0.5 * (rng[1] - rng[0]):
                reasons.append(f"{f['mechanism']} {key} not identifiable from this record "
                               f"(95 % interval {_fmt(a)}–{_fmt(b)})")
    parts = ", ".join(
        f"{f['mechanism']} " + " ".join(f"{k} {_fmt(float(v))}" for k, v in f["parameters"].items()
                                        if not k.endswith("phase_deg"))
        for f in members
    )
    lo, hi = final.get("chi2_dof_bounds", [math.nan, math.nan])
    message = (
        f"defect on {place}; {like}; its shape is not captured: {parts} together leave "
        f"χ²/dof {_fmt(float(final['chi2_dof']))} (bounds {lo:.3g}–{hi:.3g})"
    )
    if remaining:
        top = remaining[0]
        where = top.get("class") or top.get("band_hz") or top.get("tooth") or top.get("domain")
        message += f"; most of the rest in {top.get('domain')} {where}"
    return {
        "place": place,
        "wheel": wheel,
        "tooth": tooth,
        "like": lead["mechanism"],
        "lead": members.index(lead),
        "members": [
            {"mechanism": f["mechanism"], "wheel": f.get("wheel"), "tooth": f.get("tooth"),
             "parameters": f["parameters"], "ci95": f.get("ci95", {})}
            for f in members
        ],
        "reasons": reasons,
        "shape_captured": False,
        "residual": {"chi2_dof": final["chi2_dof"], "chi2_dof_bounds": final.get("chi2_dof_bounds"),
                     "remaining": remaining[:3]},
        "message": message,
    }


def pinion_order_clusters(used: NDArray[np.bool_], revs_per_hunt: int) -> NDArray[np.int64]:
    """Cluster label of each used bin (real and imaginary rows stacked, as whitened residuals):
    the hunting bins from half-way below a pinion order to half-way above it (its sidebands)."""
    k = np.flatnonzero(used)
    label = np.rint(k / revs_per_hunt).astype(np.int64)
    return np.concatenate([label, label])


def robust_covariance(
    jacobian: FloatArray,
    residual: FloatArray,
    prior_precision: FloatArray,
    clusters: NDArray[np.int64],
    chi2_scale: float,
) -> FloatArray:
    """Covariance of the fitted parameters honest about model-form error.

    ``jacobian`` (rows: whitened data; columns: parameters), ``residual`` (whitened, same
    rows), ``prior_precision`` (added to JᵀJ: the Gaussian priors of the nuisances), ``clusters``
    (a label per row: rows whose residuals may be correlated by model-form error). Returns the
    element-wise larger-variance choice between ``chi2_scale · A⁻¹`` (A = JᵀJ + prior) and the
    cluster-robust sandwich ``A⁻¹ (Σ_c g_c g_cᵀ) A⁻¹`` with ``g_c = J_cᵀ r_c``: where the model
    is right both agree on average; where the misfit sits on a parameter's own signature the
    sandwich is the wider.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> J = rng.standard_normal((4000, 1)); r = rng.standard_normal(4000)
    >>> cov = robust_covariance(J, r, np.zeros((1, 1)), np.arange(4000) // 20, 1.0)
    >>> 0.7 < float(cov[0, 0] * (J.T @ J)[0, 0]) < 1.4
    True
    """
    a = jacobian.T @ jacobian + prior_precision
    a_inv = np.linalg.pinv(a)
    model_based = a_inv * max(1.0, chi2_scale)
    order = np.argsort(clusters, kind="stable")
    labels = clusters[order]
    weighted = jacobian[order] * residual[order, None]
    starts = np.flatnonzero(np.r_[True, labels[1:] != labels[:-1]])
    g = np.add.reduceat(weighted, starts, axis=0)
    meat = g.T @ g
    sandwich = a_inv @ meat @ a_inv
    sd = np.sqrt(np.maximum(np.maximum(np.diag(model_based), np.diag(sandwich)), 0.0))
    # Keep the model-based correlation structure, widened to the larger standard deviation.
    d_mb = np.sqrt(np.maximum(np.diag(model_based), 1e-300))
    corr = model_based / np.outer(d_mb, d_mb)
    out: FloatArray = corr * np.outer(sd, sd)
    return out


def _remaining_on_tooth(remaining: list[dict[str, Any]], wheel: Any, tooth: Any) -> float:
    """Share of the remaining excess the angle-domain localisation puts on that tooth."""
    for m in remaining:
        if m.get("domain") == "angle" and m.get("wheel") == wheel and tooth in (m.get("teeth") or []):
            return float(m.get("share", 0.0))
    return 0.0


def assess(
    findings: list[dict[str, Any]],
    correlation: FloatArray,
    final: dict[str, Any],
    remaining: list[dict[str, Any]],
    explained: bool,
    teeth: dict[str, int] | None = None,
) -> tuple[list[int], dict[str, Any]]:
    """Which findings to keep as named mechanisms, and the ``model_form`` block of the JSON.

    Compensating groups (:func:`compensation_groups`) become one defect each; only its lead
    stays among the findings (marked), the members are listed in the defect. When the result
    is not explained, a lone one-tooth finding whose tooth still carries the remaining misfit
    (the angle-domain localisation of the final residual) is reported as a defect whose shape
    the catalogue does not capture, too.
    """
    groups = compensation_groups(findings, correlation, explained, teeth)
    defects = []
    keep = set(range(len(findings)))
    for group in groups:
        defect = describe_defect(findings, group, final, remaining, correlation)
        lead = group[defect["lead"]]
        defect["finding_index"] = lead
        defects.append(defect)
        keep -= set(group) - {lead}
    if not explained:
        grouped = {i for g in groups for i in g}
        for i, f in enumerate(findings):
            if i in grouped or f["mechanism"] not in TOOTH_MECHANISMS:
                continue
            share = _remaining_on_tooth(remaining, f.get("wheel"), f.get("tooth"))
            if share >= 0.3 or at_edge(f):
                defect = describe_defect(findings, [i], final, remaining)
                defect["reasons"].append(
                    f"{share:.0%} of the remaining misfit sits on this tooth" if share >= 0.3
                    else "parameter at the edge of its physical range"
                )
                defect["finding_index"] = i
                defects.append(defect)
    block = {
        "defects": defects,
        "compensating": bool(groups),
        "intervals": (
            "95 % intervals: the larger of the model-based covariance × max(1, χ²/dof) and a "
            "cluster-robust (sandwich) covariance over each pinion order's sidebands"
        ),
    }
    return sorted(keep), block


def block_correlation(covariance: FloatArray, blocks: list[tuple[int, int]]) -> FloatArray:
    """Largest absolute correlation between any parameter of block i and any of block j.

    ``blocks`` are ``(start, stop)`` index ranges of ``covariance``; empty blocks correlate 0.

    Examples
    --------
    >>> cov = np.array([[1.0, 0.95, 0.0], [0.95, 1.0, 0.0], [0.0, 0.0, 1.0]])
    >>> block_correlation(cov, [(0, 1), (1, 2), (2, 3)]).round(2).tolist()
    [[0.0, 0.95, 0.0], [0.95, 0.0, 0.0], [0.0, 0.0, 0.0]]
    """
    d = np.sqrt(np.maximum(np.diag(covariance), 1e-300))
    corr = np.abs(covariance / np.outer(d, d))
    n = len(blocks)
    out = np.zeros((n, n))
    for i, (a0, a1) in enumerate(blocks):
        for j, (b0, b1) in enumerate(blocks):
            if i != j and a1 > a0 and b1 > b0:
                out[i, j] = float(corr[a0:a1, b0:b1].max())
    return out
