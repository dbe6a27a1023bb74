"""The campaign report of one rig, as a PDF (matplotlib's PdfPages) or a self-contained HTML
page (Jinja2 template, plots embedded as PNG): what a test engineer takes to a meeting.

Contents: a summary with provenance; the tooth × record heat map (the per-tooth ``score``
when stored, else the MCI depth); each alarmed tooth's (or whole-record indicator's) trend
with its baseline, levels, alarms and acknowledgements; the MCI curves of the first and last
days and of each alarm day against the healthy band; the classic metrics; data quality per
record; every record's raw file sha256, code version and parameter set.

Reads the database only (through the repositories); :func:`collect` gathers, :func:`write`
renders.
"""

from __future__ import annotations

import base64
import datetime as dt
import io
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from gearwatch.floor.errors import InputError, NotFound
from gearwatch.floor.indicators import indicator_info, indicator_unit
from gearwatch.floor.version import code_version
from storage.operator_queries import (
    OperatorQueries,
    mci_band,
    mci_in_pair_frame,
    relative_to_median,
    tooth_sector_list,
)
from storage.repositories import (
    AlarmRepository,
    AlarmRuleRepository,
    CampaignRepository,
    RecordRepository,
    RigRepository,
    TrendRepository,
)

if TYPE_CHECKING:
    from sqlalchemy.orm import Session

    from storage.models import Rig

TEMPLATES = Path(__file__).resolve().parent / "templates"
CLASSIC_METRICS = ("rms", "kurtosis", "crest", "fm0", "fm4", "na4", "residual_kurtosis", "nb4", "m6a",
                   "m8a", "er", "raw_rms", "raw_kurtosis")  # fmt: skip
TABLE_ROWS_PER_PAGE = 28


@dataclass
class RecordRow:
    record_id: int
    label: str
    taken_at: dt.datetime
    campaign: str
    status: str
    reason: str
    file_name: str
    sha256: str
    speed_rpm: float | None
    speed_variation: float | None
    tach_repairs: int | None
    quality_score: float | None
    code_version: str
    parameters_sha256: str
    mci_form: str
    angle: str = "tach"
    """Where the shaft angle came from and, without a tach, which tooth frame the record's
    tooth numbers are in (:func:`angle_and_frame`)."""


def angle_and_frame(quality: dict[str, Any]) -> str:
    """One line for the report: the record's shaft angle and tooth frame (issue 11).

    The dashboard says the same (``frameText`` in ``service/static/dashboard.js``).

    Examples
    --------
    >>> angle_and_frame({"angle_source": "tachometer"})
    'tach'
    >>> angle_and_frame({"angle_source": "mesh_phase", "tooth_frames": {"a1": {"kind": "campaign",
    ...     "reference_frame": "mesh_phase", "pinion": {"separation_z": 2.04,
    ...     "confirmed_by_sector_pattern": True}}}})
    "mesh phase; campaign's tach-less frame (2.0 SE + tooth energy pattern)"
    >>> angle_and_frame({"angle_source": "mesh_phase", "tooth_frames": {"a1": {"kind": "campaign",
    ...     "reference_frame": "mesh_phase", "pinion": {"separation_z": 3.61, "left_out_sectors": [4, 5, 6, 7]}}}})
    "mesh phase; campaign's tach-less frame (3.6 SE without 4 loud teeth)"
    >>> angle_and_frame({"angle_source": "mesh_phase", "tooth_frames": {
    ...     "a1": {"kind": "refused"}, "a2": {"kind": "campaign", "reference_frame": "mesh_phase"}}})
    "mesh phase; campaign's tach-less frame on 1 of 2 channels (not on a1)"
    """
    source = quality.get("angle_source", "tachometer")
    if source == "none":
        return "no angle: whole-record metrics only"
    if source != "mesh_phase":
        return "tach"
    frames = quality.get("tooth_frames") or {}
    if not isinstance(frames, dict):
        frames = {}
    if len(frames) > 1:  # several accelerometers: each channel is framed on its own
        aligned = [name for name, f in frames.items() if f.get("kind") == "campaign"]
        refused = [name for name, f in frames.items() if f.get("kind") != "campaign"]
        anchor = ("tach days' numbering" if any(frames[n].get("reference_frame") == "tachometer" for n in aligned)
                  else "campaign's tach-less frame")
        if aligned and all(frames[n].get("founds_reference") for n in aligned):
            return f"mesh phase; {anchor} (founds it on {len(aligned)} of {len(frames)} channels)"
        return (f"mesh phase; {anchor} on {len(aligned)} of {len(frames)} channels"
                + (f" (not on {', '.join(refused)})" if refused else ""))
    frame: dict[str, Any] = next(iter(frames.values()), {})
    kind = frame.get("kind")
    if kind == "refused":
        return "mesh phase; tooth frame refused: no per-tooth values"
    if kind == "own":
        return "mesh phase; the record's own frame"
    anchor = "tach days' numbering" if frame.get("reference_frame") == "tachometer" else "campaign's tach-less frame"
    if frame.get("founds_reference"):
        return f"mesh phase; {anchor} (founds it)"
    pinion = frame.get("pinion") or {}
    z = pinion.get("separation_z")
    support = " + tooth energy pattern" if pinion.get("confirmed_by_sector_pattern") else ""
    if pinion.get("left_out_sectors"):
        support += f" without {len(pinion['left_out_sectors'])} loud teeth"
    return f"mesh phase; {anchor}" + (f" ({float(z):.1f} SE{support})" if isinstance(z, int | float) else "")


@dataclass
class AlarmRow:
    id: int
    indicator: str
    title: str
    tooth: int | None
    channel: str
    state: str
    severity: str
    raised_at: dt.datetime
    record_label: str
    last_value: float
    unit: str
    last_score: float
    baseline_centre: float
    baseline_spread: float
    warning_level: float | None
    alarm_level: float | None
    history: list[dict[str, Any]] = field(default_factory=list)


@dataclass
class TrendSeries:
    key: str
    """``tooth 16 — MCI depth`` or ``whole record — kurtosis``."""
    indicator: str
    tooth: int | None
    unit: str
    taken_at: list[dt.datetime]
    values: list[float]
    alarms: list[AlarmRow]


@dataclass
class CurveSet:
    sectors: list[tuple[int, float, float]]
    band: tuple[list[float], list[float]] | None
    band_records: int
    curves: list[tuple[str, list[float]]]
    """(record name, MCI minus its median)."""
    tachless: bool = False
    """Some curves came from a tach-less record, turned from the campaign's tooth frame into the
    pair's: the angle axis has no tach edge to refer to."""


@dataclass
class ReportData:
    rig: str
    pinion_teeth: int | None
    campaigns: list[tuple[str, str]]
    generated_at: dt.datetime
    code_version: str
    records: list[RecordRow]
    heat_indicator: str
    heat_title: str
    heat_unit: str
    heat_teeth: list[int]
    heat_times: list[dt.datetime]
    heat_values: np.ndarray
    alarms: list[AlarmRow]
    trends: list[TrendSeries]
    metrics: dict[str, tuple[list[dt.datetime], list[float], str]]
    curves: CurveSet | None

    @property
    def accepted(self) -> int:
        return sum(r.status == "accepted" for r in self.records)

    @property
    def rejected(self) -> int:
        return sum(r.status == "rejected" for r in self.records)

    @property
    def mesh_phase_records(self) -> int:
        """Accepted records whose shaft angle came from the mesh phase (no tach)."""
        return sum(r.angle.startswith("mesh phase") for r in self.records)


def record_name(label: str, taken_at: dt.datetime) -> str:
    return f"{label or '(no label)'} — {taken_at:%Y-%m-%d %H:%M}"


def collect(session: Session, rig_name: str) -> ReportData:
    """Everything the report shows, read from the database."""
    rig = RigRepository(session).get_by_name(rig_name)
    if rig is None:
        known = ", ".join(r.name for r in RigRepository(session).list()) or "none"
        raise NotFound(f"rig {rig_name!r} not found (rigs: {known})")
    queries = OperatorQueries(session)
    rows = _record_rows(session, rig.id)
    heat_indicator = queries.heat_map_indicator(rig.id)
    matrix = TrendRepository(session).trend_matrix(
        rig.id, heat_indicator, None, pinion_teeth=rig.pinion_teeth
    )
    channel_unit = queries.channel_unit(rig.id, matrix.channel)
    alarms = _alarm_rows(session, rig.id, {r.record_id: r for r in rows})
    campaigns = [(c.name, c.description) for c in CampaignRepository(session).list(rig.id)]
    return ReportData(
        rig=rig.name, pinion_teeth=rig.pinion_teeth, campaigns=campaigns,
        generated_at=dt.datetime.now(dt.UTC).replace(microsecond=0),
        code_version=code_version(), records=rows, heat_indicator=heat_indicator,
        heat_title=indicator_info(heat_indicator).title,
        heat_unit=indicator_unit(heat_indicator, channel_unit), heat_teeth=list(matrix.teeth),
        heat_times=list(matrix.taken_at), heat_values=matrix.values, alarms=alarms,
        trends=_alarm_trends(session, rig, alarms), metrics=_classic_metrics(queries, rig.id),
        curves=_mci_curves(session, rig, matrix.channel, rows, alarms),
    )


def _record_rows(session: Session, rig_id: int) -> list[RecordRow]:
    """One row per record of the rig: status, provenance, speed, quality, angle and frame."""
    records_repo = RecordRepository(session)
    rows: list[RecordRow] = []
    for record in records_repo.list(rig_id=rig_id, limit=None):
        result = records_repo.current_result(record.id)
        quality = record.quality or {}
        score = quality.get("score")
        # no shaft angle (no tach, no mesh line): the stored speed is a placeholder 0, no measurement
        measured = quality.get("angle_source") != "none"
        rows.append(
            RecordRow(
                record_id=record.id, label=record.label, taken_at=record.taken_at,
                campaign=record.campaign.name, status=record.status, reason=record.reason,
                file_name=record.file_name, sha256=record.sha256,
                speed_rpm=record.speed_rpm if measured else None,
                speed_variation=record.speed_variation if measured else None,
                tach_repairs=(len(quality["tach_repairs"]) if "tach_repairs" in quality
                              and quality.get("angle_source", "tachometer") == "tachometer" else None),
                quality_score=float(score) if isinstance(score, int | float) else None,
                code_version=result.code_version if result else "",
                parameters_sha256=result.parameters_sha256 if result else "",
                mci_form=str((result.parameters or {}).get("mci_form", "")) if result else "",
                angle=angle_and_frame(quality) if record.status == "accepted" else "—",
            )
        )
    return rows


def _alarm_rows(session: Session, rig_id: int, by_id: dict[int, RecordRow]) -> list[AlarmRow]:
    """Every alarm of the rig, oldest first, with its rule's levels and its history."""
    rules = {r.indicator: r for r in AlarmRuleRepository(session).list(rig_id)}
    alarm_repo = AlarmRepository(session)
    alarms: list[AlarmRow] = []
    for alarm in sorted(alarm_repo.list(rig_id=rig_id, limit=None), key=lambda a: a.id):
        try:
            info = indicator_info(alarm.indicator)
            whole, title = info.scope == "record", info.title
            unit = indicator_unit(alarm.indicator, alarm.channel.unit)
        except ValueError:
            whole, title, unit = alarm.tooth == 0, alarm.indicator, ""
        raising = by_id.get(alarm.raised_record_id or -1)
        rule = rules.get(alarm.indicator)
        alarms.append(
            AlarmRow(
                id=alarm.id, indicator=alarm.indicator, title=title,
                tooth=None if whole or alarm.tooth == 0 else alarm.tooth,
                channel=alarm.channel.name, state=alarm.state, severity=alarm.severity,
                raised_at=alarm.raised_at, record_label=raising.label if raising else "",
                last_value=alarm.last_value, unit=unit, last_score=alarm.last_score,
                baseline_centre=alarm.baseline_centre, baseline_spread=alarm.baseline_spread,
                warning_level=rule.warning_level if rule else None,
                alarm_level=rule.alarm_level if rule else None,
                history=[
                    {"state": e.state, "at": e.at, "who": e.who or "", "comment": e.comment or "",
                     "record": record_name(by_id[e.record_id].label, by_id[e.record_id].taken_at)
                     if e.record_id in by_id else "", "score": e.score}
                    for e in alarm_repo.history(alarm.id)
                ],
            )
        )
    return alarms


def _alarm_trends(session: Session, rig: Rig, alarms: list[AlarmRow]) -> list[TrendSeries]:
    """The trend of each alarmed tooth (or whole-record indicator), once per indicator and tooth."""
    queries = OperatorQueries(session)
    trends: list[TrendSeries] = []
    seen: set[tuple[str, int | None]] = set()
    for row in alarms:
        key = (row.indicator, row.tooth)
        if key in seen:
            continue
        seen.add(key)
        if row.tooth is None:
            m = queries.metric_matrix(rig.id, row.indicator, channel=row.channel)
        else:
            m = TrendRepository(session).trend_matrix(
                rig.id, row.indicator, row.tooth, channel=row.channel,
                pinion_teeth=rig.pinion_teeth,
            )
        trends.append(
            TrendSeries(
                key=("whole record" if row.tooth is None else f"tooth {row.tooth}")
                + f" — {row.title}",
                indicator=row.indicator, tooth=row.tooth, unit=row.unit,
                taken_at=list(m.taken_at), values=[float(v) for v in m.values[:, 0]],
                alarms=[a for a in alarms if (a.indicator, a.tooth) == key],
            )
        )
    return trends


def _classic_metrics(
    queries: OperatorQueries, rig_id: int
) -> dict[str, tuple[list[dt.datetime], list[float], str]]:
    """Each classic whole-record metric the rig has: its times, values and unit."""
    metrics: dict[str, tuple[list[dt.datetime], list[float], str]] = {}
    for name in CLASSIC_METRICS:
        try:
            m = queries.metric_matrix(rig_id, name)
        except InputError:
            continue
        if m.record_ids:
            metrics[name] = (
                list(m.taken_at), [float(v) for v in m.values[:, 0]],
                indicator_unit(name, queries.channel_unit(rig_id, m.channel)),
            )
    return metrics


def _mci_curves(
    session: Session, rig: Rig, channel: str | None, rows: list[RecordRow], alarms: list[AlarmRow]
) -> CurveSet | None:
    """The MCI curves of the first and last accepted records and of each alarm day, against the
    healthy band (None without an accepted record or a per-tooth channel)."""
    accepted = [r for r in rows if r.status == "accepted"]
    if not accepted or channel is None:
        return None
    records_repo = RecordRepository(session)
    wanted: list[RecordRow] = [accepted[0]]
    alarm_days = {a.raised_at.date() for a in alarms}
    wanted += [r for r in accepted[1:-1] if r.taken_at.date() in alarm_days]
    if accepted[-1] is not accepted[0]:
        wanted.append(accepted[-1])
    pair_tooth1 = float(rig.tooth1_pitch_angle_deg)
    band = mci_band(session, rig.id, channel, relative=True, pair_tooth1_deg=pair_tooth1)
    found: list[tuple[str, list[float]]] = []
    tachless = False
    for day in wanted:
        result = records_repo.current_result(day.record_id)
        if result is None:
            continue
        # a tach-less record's curve is in the campaign's tooth frame: turned into the pair's,
        # where the sectors are drawn; one whose teeth are not numbered is left out
        frame, turned = mci_in_pair_frame(records_repo, result, channel, pair_tooth1)
        if turned is not None:
            tachless = tachless or frame.kind != "tachometer"
            found.append((record_name(day.label, day.taken_at), relative_to_median(turned).tolist()))
    if not found:
        return None
    return CurveSet(
        sectors=tooth_sector_list(rig.pinion_teeth, rig.tooth1_pitch_angle_deg),
        band=(band.lower.tolist(), band.upper.tolist()) if band else None,
        band_records=band.records if band else 0,
        curves=found,
        tachless=tachless,
    )


# ---------------------------------------------------------------------------------------------
# plots


def _figure(width: float = 10.0, height: float = 5.0) -> Any:
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), layout="constrained")


def heatmap_figure(data: ReportData) -> Any:
    import matplotlib.dates as mdates

    fig = _figure(10, 5.2)
    ax = fig.add_subplot()
    if not data.heat_times or not data.heat_teeth:
        ax.text(0.5, 0.5, "no per-tooth values (no accepted record, or no tooth counts)",
                ha="center", va="center", transform=ax.transAxes)
        ax.set_axis_off()
        return fig
    times = mdates.date2num(data.heat_times)
    step = float(np.median(np.diff(times))) if len(times) > 1 else 1.0
    edges = np.concatenate([times - step / 2, [times[-1] + step / 2]])
    teeth = np.asarray(data.heat_teeth, dtype=float)
    tooth_edges = np.concatenate([teeth - 0.5, [teeth[-1] + 0.5]])
    values = np.ma.masked_invalid(data.heat_values.T)
    # The full range of the values: a spalled tooth keeps its own colour (no clipping).
    mesh = ax.pcolormesh(edges, tooth_edges, values, cmap="viridis", shading="flat")
    bar = fig.colorbar(mesh, ax=ax)
    bar.set_label(f"{data.heat_title} ({data.heat_unit})" if data.heat_unit else data.heat_title)
    ax.set_ylim(tooth_edges[-1], tooth_edges[0])
    ax.grid(False)
    ax.set_yticks(teeth if len(teeth) <= 40 else teeth[:: math.ceil(len(teeth) / 40)])
    ax.tick_params(axis="y", labelsize=7)
    ax.set_ylabel("pinion tooth")
    ax.xaxis.set_major_formatter(mdates.DateFormatter("%Y-%m-%d"))
    fig.autofmt_xdate()
    ax.set_xlabel("record date (UTC)")
    alarmed = sorted({a.tooth for a in data.alarms if a.tooth is not None
                      and a.indicator == data.heat_indicator})
    for tooth in alarmed:
        ax.annotate(f"tooth {tooth}", xy=(edges[-1], tooth), xytext=(4, 0),
                    textcoords="offset points", va="center", color="#b00020", fontsize=8,
                    annotation_clip=False)
    ax.set_title(f"{data.rig}: {data.heat_title} per tooth and record")
    return fig


def trend_figure(series: TrendSeries) -> Any:
    import matplotlib.dates as mdates

    fig = _figure(10, 3.8)
    ax = fig.add_subplot()
    ax.plot(series.taken_at, series.values, "o-", color="#b00020", ms=3, lw=1.2,
            label=series.key)
    if series.alarms:
        first = series.alarms[0]
        centre, spread = first.baseline_centre, first.baseline_spread
        ax.axhline(centre, color="#607080", ls="--", lw=1, label="baseline")
        if first.warning_level is not None and first.alarm_level is not None:
            ax.axhline(centre + first.warning_level * spread, color="#e69500", ls="--", lw=1,
                       label="warning level")
            ax.axhline(centre + first.alarm_level * spread, color="#b00020", ls=":", lw=1,
                       label="alarm level")
        for alarm in series.alarms:
            for event in alarm.history:
                colour = {"warning": "#e69500", "alarm": "#b00020", "acknowledged": "#4a5fc1",
                          "cleared": "#2d6a3e"}.get(event["state"], "#333")
                ax.axvline(event["at"], color=colour, lw=0.8, alpha=0.6)
                ax.annotate(event["state"], xy=(event["at"], 1.0), xycoords=("data", "axes fraction"),
                            rotation=90, va="top", ha="right", fontsize=7, color=colour)
    ax.xaxis.set_major_formatter(mdates.DateFormatter("%m-%d"))
    ax.set_xlabel("record date (UTC)")
    ax.set_ylabel(series.unit or "(dimensionless)")
    ax.set_title(series.key + (f" ({series.unit})" if series.unit else ""))
    ax.legend(fontsize=7, loc="upper left")
    ax.grid(alpha=0.3)
    return fig


def curves_figure(curves: CurveSet, highlight: Sequence[int] = ()) -> Any:
    fig = _figure(10, 4.2)
    ax = fig.add_subplot()
    n = len(curves.curves[0][1])
    angle = 360.0 * np.arange(n) / n
    for tooth, start, end in curves.sectors:
        if tooth in highlight:
            ax.axvspan(start, end, color="#b00020", alpha=0.12, lw=0)
        elif tooth % 2:
            ax.axvspan(start, end, color="#000000", alpha=0.04, lw=0)
    labelled: set[int] = set()
    for tooth, start, end in curves.sectors:
        if tooth not in labelled and end - start > 3:
            labelled.add(tooth)
            ax.text((start + end) / 2, 1.01, str(tooth), transform=ax.get_xaxis_transform(),
                    ha="center", va="bottom", fontsize=6,
                    color="#b00020" if tooth in highlight else "#555")
    if curves.band is not None and len(curves.band[0]) == n:
        ax.fill_between(angle, curves.band[0], curves.band[1], color="#8a96a3", alpha=0.35,
                        label=f"healthy band ({curves.band_records} first records)")
    colours = ["#1f5fbf", "#e07b00", "#2d6a3e", "#8e44ad", "#b00020", "#16a085"]
    for i, (name, values) in enumerate(curves.curves):
        if len(values) == n:
            ax.plot(angle, values, lw=1.1, color=colours[i % len(colours)], label=name)
    ax.set_xlim(0, 360)
    ax.set_xlabel("pinion angle, the pair's tooth frame (deg; no tach: the campaign's frame turned into it)"
                  if curves.tachless else "pinion angle after the tach edge (deg)")
    ax.set_ylabel("MCI − its median (Np)")
    ax.set_title("MCI curves: first day, alarm days, last day", pad=14)
    ax.legend(fontsize=7, loc="lower right")
    return fig


def metrics_figure(metrics: dict[str, tuple[list[dt.datetime], list[float], str]]) -> Any:
    import matplotlib.dates as mdates

    names = list(metrics)
    cols = 4
    rows = max(1, math.ceil(len(names) / cols))
    fig = _figure(10, 1.9 * rows + 0.4)
    axes = fig.subplots(rows, cols, squeeze=False)
    for ax, name in zip(axes.flat, names, strict=False):
        times, values, unit = metrics[name]
        ax.plot(times, values, ".-", lw=0.8, ms=3, color="#1f5fbf")
        ax.set_title(f"{name}" + (f" ({unit})" if unit else ""), fontsize=8)
        ax.tick_params(labelsize=6)
        ax.xaxis.set_major_formatter(mdates.DateFormatter("%m-%d"))
    for ax in list(axes.flat)[len(names):]:
        ax.set_axis_off()
    return fig


def png_base64(fig: Any) -> str:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110)
    return base64.b64encode(buffer.getvalue()).decode()


# ---------------------------------------------------------------------------------------------
# output


def _environment() -> Any:
    import jinja2

    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(TEMPLATES),
        autoescape=jinja2.select_autoescape(["html", "j2"]),
        trim_blocks=True,
        lstrip_blocks=True,
    )
    env.filters["num"] = _num
    env.filters["when"] = lambda t: "" if t is None else f"{t:%Y-%m-%d %H:%M}"
    env.globals["record_name"] = record_name
    return env


def _num(value: float | None, digits: int = 3) -> str:
    if value is None or not math.isfinite(value):
        return "—"
    return f"{value:.{digits}g}"


def alarmed_teeth(data: ReportData) -> list[int]:
    return sorted({a.tooth for a in data.alarms if a.tooth is not None})


def conclusion(data: ReportData) -> str:
    """One sentence: what the campaign shows."""
    open_alarms = [a for a in data.alarms if a.state != "cleared"]
    teeth = sorted({a.tooth for a in open_alarms if a.tooth is not None})
    whole = sorted({a.title for a in open_alarms if a.tooth is None})
    if not open_alarms:
        return (f"No open alarm on {data.rig}: {data.accepted} accepted and {data.rejected} "
                "rejected records.")
    parts = []
    if teeth:
        parts.append("pinion tooth " + ", ".join(map(str, teeth)))
    if whole:
        parts.append("the whole-record " + ", ".join(whole))
    first = min(a.raised_at for a in open_alarms)
    return (f"{data.rig} has open alarms on {' and '.join(parts)} since {first:%Y-%m-%d}, "
            f"over {data.accepted} accepted and {data.rejected} rejected records.")


def render_html(data: ReportData) -> str:
    figures = {
        "heatmap": png_base64(heatmap_figure(data)),
        "trends": [(s, png_base64(trend_figure(s))) for s in data.trends],
        "curves": png_base64(curves_figure(data.curves, alarmed_teeth(data)))
        if data.curves else None,
        "metrics": png_base64(metrics_figure(data.metrics)) if data.metrics else None,
    }
    return str(_environment().get_template("report.html.j2").render(
        data=data, figures=figures, conclusion=conclusion(data)
    ))


def _text_page(pdf: Any, text: str) -> None:
    fig = _figure(8.27, 11.69)
    fig.text(0.06, 0.97, text, va="top", ha="left", family="monospace", fontsize=8.2,
             wrap=True)
    pdf.savefig(fig)


def _table_pages(pdf: Any, title: str, header: list[str], rows: list[list[str]],
                 widths: list[float]) -> None:
    for start in range(0, max(1, len(rows)), TABLE_ROWS_PER_PAGE):
        chunk = rows[start:start + TABLE_ROWS_PER_PAGE] or [["—"] * len(header)]
        fig = _figure(11.69, 8.27)
        ax = fig.add_subplot()
        ax.set_axis_off()
        ax.set_title(title + (" (continued)" if start else ""), loc="left")
        table = ax.table(cellText=chunk, colLabels=header, colWidths=widths, loc="upper left",
                         cellLoc="left")
        table.auto_set_font_size(False)
        table.set_fontsize(7)
        table.scale(1, 1.25)
        pdf.savefig(fig)


def write_pdf(data: ReportData, out: Path) -> None:
    from matplotlib.backends.backend_pdf import PdfPages

    summary = _environment().get_template("report_summary.txt.j2").render(
        data=data, conclusion=conclusion(data)
    )
    with PdfPages(out, metadata={"Title": f"gearwatch campaign report: {data.rig}",
                                 "Creator": f"gearwatch {data.code_version}"}) as pdf:
        _text_page(pdf, summary)
        pdf.savefig(heatmap_figure(data))
        for series in data.trends:
            pdf.savefig(trend_figure(series))
        if data.curves:
            pdf.savefig(curves_figure(data.curves, alarmed_teeth(data)))
        if data.metrics:
            pdf.savefig(metrics_figure(data.metrics))
        _table_pages(
            pdf, "Data quality per record",
            ["record", "campaign", "status", "speed (rpm)", "speed var.", "tach repairs",
             "quality", "angle / tooth frame", "reason"],
            [[record_name(r.label, r.taken_at), r.campaign, r.status, _num(r.speed_rpm, 5),
              "—" if r.speed_variation is None else f"{100 * r.speed_variation:.2f} %",
              "—" if r.tach_repairs is None else str(r.tach_repairs), _num(r.quality_score),
              r.angle[:44], r.reason[:44]] for r in data.records],
            [0.18, 0.1, 0.07, 0.07, 0.07, 0.06, 0.06, 0.2, 0.19],
        )
        _table_pages(
            pdf, "Provenance: raw file, code and parameters of every stored value",
            ["record", "file", "raw sha256", "code version", "parameters sha256", "MCI form"],
            [[record_name(r.label, r.taken_at), r.file_name[:28], r.sha256[:20] + "…",
              r.code_version, r.parameters_sha256[:16] + "…" if r.parameters_sha256 else "—",
              r.mci_form or "—"] for r in data.records],
            [0.2, 0.16, 0.2, 0.18, 0.16, 0.08],
        )


def write(session: Session, rig: str, out: Path) -> ReportData:
    """Collect and write the report; the format follows the suffix (``.pdf`` or ``.html``)."""
    suffix = out.suffix.lower()
    if suffix not in (".pdf", ".html", ".htm"):
        raise InputError(f"{out}: the report is written as .pdf or .html")
    data = collect(session, rig)
    out.parent.mkdir(parents=True, exist_ok=True)
    if suffix == ".pdf":
        write_pdf(data, out)
    else:
        out.write_text(render_html(data), encoding="utf-8")
    return data
