/* gearwatch dashboard: plain JavaScript over the REST API, charts by the vendored uPlot.
 * The API key is kept in sessionStorage (or given once as #key=... in the URL) and sent as
 * "Authorization: Bearer <key>"; the page itself holds no data.
 *
 * Rules this page keeps so that it cannot mislead:
 * - switching rig, indicator or record resets every panel that depends on it first
 *   (no chart of the previous rig stays on screen while the next one loads);
 * - the heat map's colours span the full range of the values shown, with a colour bar;
 * - whole-record indicators are their own trend, never "tooth 0";
 * - the rig's current gear pair is shown unless an earlier campaign is chosen, and the titles
 *   then name that campaign (tooth 5 of one pinion is not tooth 5 of another);
 * - every value carries its unit, every record its label and date. */
"use strict";

const KEY_STORAGE = "gearwatch.apiKey";
const el = (id) => document.getElementById(id);
const state = {
  key: null, me: null, rig: null, campaign: "", campaigns: [], indicator: null, indicators: [],
  overview: [],
  trend: null, levels: null, alarms: [], rules: [], records: [], record: null, compare: null, tooth: null,
  curvePlot: null, trendPlot: null, alarmDetail: null, generation: 0,
};

function message(text) { el("message").textContent = text || ""; }

async function api(path, options = {}) {
  const headers = Object.assign({ "Authorization": "Bearer " + state.key }, options.headers || {});
  const response = await fetch("api/v1" + path, Object.assign({}, options, { headers }));
  if (response.status === 401) { forgetKey(); throw new Error("the API key was refused"); }
  if (options.raw) {
    if (!response.ok) throw new Error(response.statusText);
    return response;
  }
  const body = await response.json().catch(() => null);
  if (!response.ok) {
    const why = body && body.error ? body.error.message : response.statusText;
    throw new Error(why);
  }
  return body;
}

function forgetKey() {
  sessionStorage.removeItem(KEY_STORAGE);
  state.key = null;
  el("login").hidden = false; el("controls").hidden = true; el("panels").hidden = true;
}

/* ---------- formatting ---------- */
const rigPath = () => `/rigs/${encodeURIComponent(state.rig)}`;
/* The trend's query: the indicator, and the campaign when one is chosen (else the current pair). */
function trendQuery(indicator) {
  const campaign = state.campaign ? `&campaign=${encodeURIComponent(state.campaign)}` : "";
  return `${rigPath()}/trends?indicator=${encodeURIComponent(indicator)}${campaign}`;
}
const inCampaign = () => (state.campaign ? ` — campaign ${state.campaign}` : "");
/* An alarm belongs on the views when no campaign is chosen, or it is of the chosen one. */
const ofShownCampaign = (alarm) => !state.campaign || alarm.campaign_id === state.campaign;
function info(name) {
  return state.indicators.find((i) => i.name === name) || { name, scope: "tooth", title: name, unit: "" };
}
function isWhole(name) { return info(name).scope === "record"; }
function date(iso) { return iso ? iso.slice(0, 16).replace("T", " ") : ""; }
function day(iso) { return iso ? iso.slice(0, 10) : ""; }
function recordName(label, takenAt) { return `${label || "(no label)"} — ${date(takenAt)}`; }
function withUnit(value, unit) {
  if (value === null || value === undefined || !Number.isFinite(value)) return "—";
  const text = Math.abs(value) >= 1000 || (Math.abs(value) < 0.01 && value !== 0) ? value.toExponential(2) : value.toPrecision(3);
  return unit ? `${text} ${unit}` : text;
}
function unitOf(trend) { return trend && trend.unit ? trend.unit : ""; }
function where(alarm) { return alarm.tooth === null ? "whole record" : `tooth ${alarm.tooth}`; }
function recordById(id) { return state.records.find((r) => r.id === id); }

/* ---------- colour scale (viridis) ---------- */
const VIRIDIS = ["#440154", "#482878", "#3e4989", "#31688e", "#26828e", "#1f9e89", "#35b779", "#6ece58", "#b5de2b", "#fde725"];
function colour(t) {
  if (!Number.isFinite(t)) return "#dddddd";
  const x = Math.min(1, Math.max(0, t)) * (VIRIDIS.length - 1);
  const i = Math.min(VIRIDIS.length - 2, Math.floor(x)), f = x - i;
  const a = VIRIDIS[i], b = VIRIDIS[i + 1];
  const mix = (k) => Math.round(parseInt(a.substr(k, 2), 16) * (1 - f) + parseInt(b.substr(k, 2), 16) * f);
  return `rgb(${mix(1)},${mix(3)},${mix(5)})`;
}

/* ---------- resetting (rig, indicator or record switches) ---------- */
function resetCurve() {
  if (state.curvePlot) { state.curvePlot.destroy(); state.curvePlot = null; }
  el("curve").innerHTML = ""; el("curve-title").textContent = "—"; el("curve-legend").textContent = "";
  delete el("curve").dataset.sectors; delete el("curve").dataset.record; delete el("curve").dataset.compare;
}
function resetTrend() {
  if (state.trendPlot) { state.trendPlot.destroy(); state.trendPlot = null; }
  el("trend").innerHTML = ""; el("trend-title").textContent = "—"; el("trend-legend").textContent = "";
  delete el("trend").dataset.levels; delete el("trend").dataset.tooth; delete el("trend").dataset.warning;
}
function resetHeatmap(text) {
  const canvas = el("heatmap");
  canvas.getContext("2d").clearRect(0, 0, canvas.width, canvas.height);
  el("heatmap-title").textContent = "—"; el("heatmap-legend").textContent = text || "";
  el("alarmed-teeth").textContent = ""; el("alarmed-teeth").className = "";
  canvas.dataset.alarmedTeeth = ""; delete canvas.dataset.min; delete canvas.dataset.max;
  canvas.onclick = null;
}
function resetAll() {
  state.generation += 1;
  state.trend = null; state.levels = null; state.record = null; state.compare = null; state.tooth = null;
  state.alarms = []; state.records = []; state.alarmDetail = null;
  resetHeatmap("loading…"); resetCurve(); resetTrend();
  el("record").innerHTML = ""; el("compare").innerHTML = '<option value="">—</option>';
  el("alarms").querySelector("tbody").innerHTML = "";
  el("alarm-detail").hidden = true;
  delete document.body.dataset.ready;
}

/* ---------- rig overview ---------- */
function sparkline(canvas, values) {
  const ctx = canvas.getContext("2d"), w = canvas.width, h = canvas.height;
  ctx.clearRect(0, 0, w, h);
  const finite = values.filter(Number.isFinite);
  if (finite.length < 2) return;
  const lo = Math.min(...finite), hi = Math.max(...finite), span = hi - lo || 1;
  ctx.strokeStyle = "#1f5fbf"; ctx.lineWidth = 1.5; ctx.beginPath();
  values.forEach((v, i) => {
    if (!Number.isFinite(v)) return;
    const x = 2 + (i * (w - 4)) / (values.length - 1), y = h - 2 - ((v - lo) * (h - 4)) / span;
    if (i === 0) ctx.moveTo(x, y); else ctx.lineTo(x, y);
  });
  ctx.stroke();
}

/* Without a tachometer the tooth numbers are the campaign's own frame (issue 11): say which. */
function frameText(q) {
  if (q.angle_source === "none") return "no shaft angle: whole-record metrics only";
  if (q.angle_source !== "mesh_phase") return "";
  const frames = q.tooth_frames || {};
  const names = Object.keys(frames);
  if (names.length > 1) {  // each accelerometer is framed on its own (the report says the same)
    const aligned = names.filter((n) => frames[n].kind === "campaign");
    const others = names.filter((n) => frames[n].kind !== "campaign");
    const anchored = aligned.some((n) => frames[n].reference_frame === "tachometer")
      ? "the tach days' numbering" : "the campaign's tach-less frame";
    const not = others.length ? ` (not on ${others.join(", ")})` : "";
    return `angle from the mesh phase; teeth in ${anchored} on ${aligned.length} of ${names.length} channels${not}`;
  }
  const f = frames[names[0]] || {};
  if (f.kind === "refused") return "angle from the mesh phase; tooth numbers refused (frame not found)";
  if (f.kind === "own") return "angle from the mesh phase; tooth numbers in the record's own frame";
  const anchor = f.reference_frame === "tachometer" ? "the tach days' numbering" : "the campaign's tach-less frame";
  const z = f.pinion && Number.isFinite(f.pinion.separation_z)
    ? `, ${f.pinion.separation_z.toFixed(1)} SE clear${f.pinion.confirmed_by_sector_pattern ? " + tooth energy pattern" : ""}`
      + ((f.pinion.left_out_sectors || []).length ? ` without ${f.pinion.left_out_sectors.length} loud teeth` : "") : "";
  return `angle from the mesh phase; teeth in ${anchor}${f.founds_reference ? " (founds it)" : z}`;
}

function qualityText(last) {
  if (!last) return "";
  if (last.status !== "accepted") return `${last.status}${last.reason ? ": " + last.reason : ""}`;
  const q = last.quality || {};
  const parts = [];
  if (Number.isFinite(last.quality_score)) parts.push(`score ${last.quality_score.toFixed(2)}`);
  // no shaft angle (no tach, no mesh line): the stored speed is a placeholder 0, not a measurement
  if (Number.isFinite(q.speed_variation) && q.angle_source !== "none") parts.push(`speed variation ${(100 * q.speed_variation).toFixed(1)} %`);
  // synthetic pulses from the mesh phase are not a tach: their (empty) repair list says nothing
  const tach = !q.angle_source || q.angle_source === "tachometer";
  if (tach && Array.isArray(q.tach_repairs)) parts.push(`${q.tach_repairs.length} tach repair(s)`);
  if (Number.isFinite(q.clipped_fraction) && q.clipped_fraction > 0) parts.push(`clipped ${(100 * q.clipped_fraction).toFixed(2)} %`);
  const frame = frameText(q);
  if (frame) parts.push(frame);
  return parts.join(", ");
}

function renderOverview() {
  const body = el("overview").querySelector("tbody");
  body.innerHTML = "";
  for (const rig of state.overview) {
    const tr = document.createElement("tr");
    tr.dataset.rig = rig.rig_id;
    if (rig.rig_id === state.rig) tr.className = "selected";
    const cells = [];
    cells.push(rig.rig_id);
    const last = rig.last_record;
    cells.push(last ? recordName(last.label, last.taken_at) : "no record yet");
    const quality = document.createElement("span");
    if (last) {
      const badge = document.createElement("span");
      badge.className = "badge " + (last.status === "accepted" ? "ok" : "bad");
      badge.textContent = last.status;
      quality.appendChild(badge);
      quality.appendChild(document.createTextNode(" " + qualityText(last)));
    }
    cells.push(quality);
    const alarms = document.createElement("span");
    const counts = rig.open_alarms || {};
    const total = Object.values(counts).reduce((a, b) => a + b, 0);
    if (!total) { alarms.textContent = "none"; }
    for (const s of ["alarm", "warning", "acknowledged"]) {
      if (!counts[s]) continue;
      const badge = document.createElement("span");
      badge.className = "badge " + s; badge.textContent = `${counts[s]} ${s}`;
      alarms.appendChild(badge);
    }
    cells.push(alarms);
    const w = rig.worst_tooth;
    // the last record may have no per-tooth values (a tach-less day whose teeth were not numbered)
    const older = w && rig.last_record && w.record_id !== rig.last_record.record_id;
    cells.push(w ? `tooth ${w.tooth}: ${withUnit(w.value, w.unit)} (${info(w.indicator).title})`
      + (older ? ` — from ${w.record_label || "an earlier record"}; the last record has no per-tooth values` : "")
      : (rig.pinion_teeth ? "—" : "no tooth counts"));
    const canvas = document.createElement("canvas");
    canvas.className = "sparkline"; canvas.width = 160; canvas.height = 32;
    cells.push(canvas);
    for (const cell of cells) {
      const td = document.createElement("td");
      if (cell instanceof Node) td.appendChild(cell); else td.textContent = String(cell);
      tr.appendChild(td);
    }
    tr.onclick = () => { if (rig.rig_id !== state.rig) { el("rig").value = rig.rig_id; switchRig(rig.rig_id); } };
    body.appendChild(tr);
    sparkline(canvas, (rig.sparkline || []).map((v) => (v === null ? NaN : v)));
  }
}

/* ---------- heat map: tooth (rows) × record (columns) ---------- */
// accepted records a per-tooth trend leaves out: their teeth were not numbered (no tach, no frame)
function unnumberedNote(trend) {
  const without = trend.without_tooth_values || [];
  if (!without.length) return "";
  return `. ${without.length} more accepted record${without.length > 1 ? "s have" : " has"} no per-tooth values`
    + ` (teeth not numbered: ${without.map((r) => r.label || "#" + r.record_id).join(", ")}); whole-record metrics only`;
}
function openAlarmTeeth() {
  const teeth = new Map();
  for (const a of state.alarms) {
    if (a.indicator !== state.indicator || a.state === "cleared" || !ofShownCampaign(a)) continue;
    const key = a.tooth === null ? "whole" : a.tooth;
    if (teeth.get(key) !== "alarm") teeth.set(key, a.state === "acknowledged" ? (a.severity || "alarm") : a.state);
  }
  return teeth;
}

function drawHeatmap() {
  const canvas = el("heatmap"), ctx = canvas.getContext("2d");
  const trend = state.trend;
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  const meta = info(state.indicator), unit = unitOf(trend);
  el("heatmap-title").textContent = `${meta.title}${unit ? " (" + unit + ")" : ""}${inCampaign()}`;
  const rig = state.overview.find((r) => r.rig_id === state.rig);
  if (!trend || !trend.records.length) {
    const hasRecords = rig && rig.accepted > 0;
    el("heatmap-legend").textContent = !hasRecords ? "no accepted records yet"
      : (meta.scope === "tooth" && rig && !rig.pinion_teeth ? "this rig has no tooth counts: choose a whole-record indicator"
        : `no values of ${meta.title} for this rig`);
    el("alarmed-teeth").textContent = ""; el("alarmed-teeth").className = "";
    return;
  }
  const nRec = trend.records.length, nRows = trend.teeth.length;
  const left = 64, top = 22, bottom = 56, right = 110;
  el("heatmap-kind").textContent = meta.scope === "record" ? "Whole record over time" : "Tooth × record";
  const width = canvas.width - left - right, height = canvas.height - top - bottom;
  const cw = width / nRec, ch = height / nRows;
  const finite = trend.values.flat().filter(Number.isFinite);
  // The full range of the values shown: a spalled tooth far above the others keeps its own colour.
  const lo = Math.min(...finite), hi = Math.max(...finite), span = hi - lo || 1;
  const constant = hi === lo; // one colour (the middle of the scale) for one value
  for (let r = 0; r < nRec; r++) {
    for (let t = 0; t < nRows; t++) {
      const v = trend.values[r][t];
      ctx.fillStyle = colour(v === null ? NaN : (constant ? 0.5 : (v - lo) / span));
      ctx.fillRect(left + r * cw, top + t * ch, Math.ceil(cw), Math.ceil(ch));
    }
  }
  const alarmed = openAlarmTeeth();
  ctx.font = "11px sans-serif"; ctx.textBaseline = "middle";
  const labelEvery = Math.max(1, Math.ceil(13 / ch));
  trend.teeth.forEach((tooth, t) => {
    const key = tooth === null ? "whole" : tooth;
    const y = top + (t + 0.5) * ch;
    if (alarmed.has(key)) {
      ctx.fillStyle = alarmed.get(key) === "warning" ? "#e69500" : "#b00020";
      ctx.fillRect(left - 8, top + t * ch, 6, Math.max(2, ch));
      ctx.strokeStyle = ctx.fillStyle; ctx.lineWidth = 2;
      ctx.strokeRect(left + 1, top + t * ch + 1, width - 2, Math.max(1, ch - 2));
    }
    if (t % labelEvery === 0 || alarmed.has(key) || tooth === state.tooth) {
      ctx.fillStyle = alarmed.has(key) ? "#b00020" : "#333";
      ctx.textAlign = "right";
      ctx.fillText(tooth === null ? "record" : String(tooth), left - 12, y);
    }
  });
  ctx.textAlign = "left";
  ctx.save(); ctx.translate(12, top + height / 2); ctx.rotate(-Math.PI / 2);
  ctx.textAlign = "center"; ctx.fillStyle = "#333";
  ctx.fillText(nRows === 1 && trend.teeth[0] === null ? "whole record" : "pinion tooth", 0, 0);
  ctx.restore();
  // selected record (column) and tooth (row)
  const r = trend.records.findIndex((x) => x.record_id === state.record);
  ctx.strokeStyle = "#ffffff"; ctx.lineWidth = 1.5;
  if (r >= 0) ctx.strokeRect(left + r * cw, top, cw, nRows * ch);
  const t = trend.teeth.indexOf(state.tooth);
  if (t >= 0 && nRows > 1) ctx.strokeRect(left, top + t * ch, width, ch);
  // time axis: record dates, as many as fit
  ctx.fillStyle = "#333"; ctx.textBaseline = "top"; ctx.textAlign = "center";
  const labelWidth = ctx.measureText("2026-03-01").width + 12;
  const step = Math.max(1, Math.ceil(labelWidth / cw));
  for (let i = 0; i < nRec; i += step) {
    const x = left + (i + 0.5) * cw;
    ctx.fillRect(x, top + height, 1, 4);
    ctx.fillText(day(trend.records[i].taken_at), x, top + height + 6);
  }
  ctx.fillText("record date (UTC)", left + width / 2, top + height + 26);
  // colour bar with its range and unit
  const bx = left + width + 24, bw = 14;
  for (let y = 0; y < height; y++) {
    ctx.fillStyle = colour(constant ? 0.5 : 1 - y / height);
    ctx.fillRect(bx, top + y, bw, 1);
  }
  ctx.strokeStyle = "#999"; ctx.lineWidth = 1; ctx.strokeRect(bx, top, bw, height);
  ctx.fillStyle = "#333"; ctx.textAlign = "left"; ctx.textBaseline = "middle";
  const ticks = constant ? [[0.5, lo]] : [[0, hi], [0.5, (lo + hi) / 2], [1, lo]];
  for (const [frac, v] of ticks) {
    ctx.fillText(withUnit(v, ""), bx + bw + 4, top + frac * height);
  }
  ctx.textBaseline = "bottom"; ctx.fillText(unit || "(no unit)", bx - 4, top - 10);
  canvas.dataset.min = String(lo); canvas.dataset.max = String(hi); canvas.dataset.records = String(nRec);
  el("heatmap-legend").textContent =
    `${nRec} accepted records × ${nRows === 1 && trend.teeth[0] === null ? "the whole record" : nRows + " teeth"}; ` +
    (constant ? `every value is ${withUnit(lo, unit)}`
      : `colour from ${withUnit(lo, unit)} (dark) to ${withUnit(hi, unit)} (yellow), the full range of the values shown`) +
    unnumberedNote(trend);
  const names = [...alarmed.entries()].sort((a, b) => (a[0] === "whole" ? -1 : a[0] - (b[0] === "whole" ? 0 : b[0])))
    .map(([k, s]) => `${k === "whole" ? "whole record" : "tooth " + k} (${s})`);
  const note = el("alarmed-teeth");
  note.textContent = names.length ? "Open alarms: " + names.join(", ") : `No open alarm on ${meta.title}`;
  note.className = names.length ? "has-alarm" : "no-alarm";
  canvas.dataset.alarmedTeeth = [...alarmed.keys()].join(",");
  canvas.onclick = (event) => {
    const box = canvas.getBoundingClientRect();
    const x = (event.clientX - box.left) * canvas.width / box.width;
    const y = (event.clientY - box.top) * canvas.height / box.height;
    const rr = Math.floor((x - left) / cw), tt = Math.floor((y - top) / ch);
    if (rr < 0 || rr >= nRec || tt < 0 || tt >= nRows) return;
    if (trend.teeth[tt] !== null) selectTooth(trend.teeth[tt]); else selectWhole();
    selectRecord(trend.records[rr].record_id);
  };
}

/* ---------- MCI curve with tooth sectors, the baseline band and a second record ---------- */

// the angle axis of the curves: the tach's, or (no tach) the campaign's tooth frame turned into the pair's
function numberedFrame(kind) {
  return !kind || kind === "tachometer" || kind === "campaign";
}
function angleAxisLabel(kind) {
  if (!kind || kind === "tachometer") return "pinion angle after the tach edge (deg)";
  if (kind === "campaign") return "pinion angle, the pair's tooth frame (deg; no tach: the campaign's frame)";
  return "pinion angle from this record's mesh phase (deg; teeth not numbered)";
}

function fillRecordSelects() {
  const accepted = state.records.filter((r) => r.status === "accepted");
  const rec = el("record"), cmp = el("compare");
  rec.innerHTML = ""; cmp.innerHTML = '<option value="">—</option>';
  for (const r of accepted) {
    for (const select of [rec, cmp]) {
      const option = document.createElement("option");
      option.value = String(r.id); option.textContent = recordName(r.label, r.taken_at);
      select.appendChild(option);
    }
  }
}

async function fetchCurve(recordId) {
  return api(`/records/${recordId}/curves?names=mci&band=true&relative=true`);
}

async function selectRecord(recordId, compareId) {
  const generation = state.generation;
  if (recordId !== state.record) compareId = compareId === undefined ? null : compareId;
  else if (compareId === undefined) compareId = state.compare;
  state.record = recordId; state.compare = compareId || null;
  resetCurve();
  el("record").value = String(recordId);
  el("compare").value = state.compare ? String(state.compare) : "";
  const rec = recordById(recordId);
  el("curve-title").textContent = rec ? recordName(rec.label, rec.taken_at) : `record ${recordId}`;
  drawHeatmap();
  let data, other = null;
  try {
    data = await fetchCurve(recordId);
    if (state.compare) other = await fetchCurve(state.compare);
  } catch (error) { message("curve: " + error.message); return; }
  if (generation !== state.generation || state.record !== recordId) return; // switched meanwhile
  const mci = data.curves.mci || [];
  const n = mci.length;
  const angle = Array.from({ length: n }, (_, i) => (360 * i) / n);
  const series = [{ label: "angle (deg)" }, { label: rec ? rec.label || "record" : "record", stroke: "#1f5fbf", width: 1.5 }];
  const columns = [angle, mci];
  const bands = [];
  if (other) {
    const o = other.curves.mci || [];
    const orec = recordById(state.compare);
    series.push({ label: orec ? orec.label || "compared" : "compared", stroke: "#e07b00", width: 1.2 });
    columns.push(o.length === n ? o : angle.map(() => null));
  }
  if (data.baseline_band) {
    const k = columns.length;
    series.push({ label: "baseline low", stroke: "#8a96a3", width: 1, dash: [4, 4] });
    series.push({ label: "baseline high", stroke: "#8a96a3", width: 1, dash: [4, 4] });
    columns.push(data.baseline_band.lower, data.baseline_band.upper);
    bands.push({ series: [k + 1, k], fill: "rgba(120,140,160,0.25)" });
  }
  const sectors = data.sectors || [];
  const highlight = state.tooth;
  const opts = {
    width: Math.min(900, el("curve").clientWidth || 700), height: 300, series, bands,
    scales: { x: { time: false } },
    axes: [{ label: angleAxisLabel(data.tooth_frame) }, { label: "MCI − its median (Np)" }],
    hooks: {
      drawClear: [(u) => {
        const ctx = u.ctx;
        ctx.save();
        ctx.font = `${10 * devicePixelRatio}px sans-serif`; ctx.textAlign = "center"; ctx.textBaseline = "top";
        const seen = new Set();
        sectors.forEach((s, i) => {
          const x0 = u.valToPos(s.start_deg, "x", true), x1 = u.valToPos(s.end_deg, "x", true);
          ctx.fillStyle = s.tooth === highlight ? "rgba(176,0,32,0.18)" : (s.tooth % 2 ? "rgba(0,0,0,0.05)" : "rgba(0,0,0,0)");
          ctx.fillRect(Math.min(x0, x1), u.bbox.top, Math.abs(x1 - x0), u.bbox.height);
          if (!seen.has(s.tooth) && Math.abs(x1 - x0) > 8 * devicePixelRatio) {
            seen.add(s.tooth);
            ctx.fillStyle = s.tooth === highlight ? "#b00020" : "#666";
            ctx.fillText(String(s.tooth), (x0 + x1) / 2, u.bbox.top + 2);
          }
        });
        ctx.restore();
      }],
    },
  };
  state.curvePlot = new uPlot(opts, columns, el("curve"));
  el("curve").dataset.sectors = String(new Set(sectors.map((s) => s.tooth)).size);
  el("curve").dataset.record = String(recordId);
  el("curve").dataset.compare = state.compare ? String(state.compare) : "";
  el("curve").dataset.toothFrame = data.tooth_frame || "tachometer";
  el("curve-legend").textContent = (numberedFrame(data.tooth_frame) ? "" : "This record's teeth are not numbered (no tachometer, and its tooth pattern did not place it in the campaign's frame): no tooth sectors. ")
    + (data.baseline_band ? `Grey band: the healthy range (median ± 3 robust SD) of the first ${data.baseline_band.records} accepted records; ` : "No baseline band yet (fewer than 3 accepted records); ")
    + "each curve is drawn relative to its own median, so a tooth whose sector leaves the band stands out."
    + (highlight ? ` Red sector: tooth ${highlight}.` : "");
}

/* ---------- one tooth's (or the whole record's) trend, with baseline and alarm levels ---------- */
function toothBaseline(tooth) {
  // The rule's own baseline and levels for this tooth, as it has learned them (alarm-levels);
  // none while the tooth's baseline is still being learned.
  const levels = state.levels && state.levels.items.find((t) => t.tooth === tooth);
  return levels ? { centre: levels.centre, warning: levels.warning, alarm: levels.alarm } : null;
}

function drawTrend(column, tooth) {
  resetTrend();
  const trend = state.trend;
  if (!trend || column < 0) return;
  const meta = info(state.indicator), unit = unitOf(trend);
  const what = tooth === null ? "whole record" : `tooth ${tooth}`;
  el("trend-title").textContent = `${what} — ${meta.title}${unit ? " (" + unit + ")" : ""}${inCampaign()}`;
  const xs = trend.records.map((r) => Date.parse(r.taken_at) / 1000);
  const ys = trend.values.map((row) => row[column]);
  const series = [{ label: "taken at (UTC)" }, { label: what, stroke: "#b00020", width: 1.5, points: { show: true, size: 5 } }];
  const columns = [xs, ys];
  const base = toothBaseline(tooth);
  if (base) {
    const flat = (v) => xs.map(() => v);
    series.push({ label: "baseline", stroke: "#607080", dash: [4, 4], points: { show: false } });
    columns.push(flat(base.centre));
    series.push({ label: "warning", stroke: "#e69500", dash: [6, 3], points: { show: false } });
    columns.push(flat(base.warning));
    series.push({ label: "alarm", stroke: "#b00020", dash: [2, 2], points: { show: false } });
    columns.push(flat(base.alarm));
  }
  const opts = {
    width: Math.min(900, el("trend").clientWidth || 700), height: 260, series,
    axes: [{}, { label: `${meta.title}${unit ? " (" + unit + ")" : ""}`, size: 70 }],
  };
  state.trendPlot = new uPlot(opts, columns, el("trend"));
  el("trend").dataset.levels = base ? "true" : "false";
  el("trend").dataset.warning = base ? String(base.warning) : "";
  el("trend").dataset.tooth = tooth === null ? "whole" : String(tooth);
  const pooled = base && state.levels.pooled_spread !== null
    ? ` The spread is never below how much this channel's teeth move from record to record (${withUnit(state.levels.pooled_spread, unit)}, pooled over the teeth).`
    : "";
  el("trend-legend").textContent = base
    ? "Dashed: the baseline the rule has learned for this tooth and the warning and alarm levels the next record must pass (a growing change alarms earlier, through the rule's CUSUM)." + pooled
    : "No baseline yet (the rule is still learning this tooth's usual level), or no enabled rule on this indicator.";
}

function selectTooth(tooth) {
  state.tooth = tooth;
  const trend = state.trend;
  drawTrend(trend ? trend.teeth.indexOf(tooth) : -1, tooth);
  drawHeatmap();
  if (state.record !== null && state.curvePlot) selectRecord(state.record, state.compare);
}

function selectWhole() {
  state.tooth = null;
  drawTrend(0, null);
}

/* ---------- alarm list, detail with history, acknowledgement ---------- */
function renderAlarms() {
  const filter = el("alarm-state").value;
  const body = el("alarms").querySelector("tbody");
  body.innerHTML = "";
  const canAck = state.me && state.me.role !== "viewer";
  let shown = 0;
  for (const a of state.alarms) {
    const open = a.state !== "cleared";
    if (filter === "" && !open) continue;
    if (filter !== "" && filter !== "all" && a.state !== filter) continue;
    shown += 1;
    const tr = document.createElement("tr");
    tr.className = "state-" + a.state + (state.alarmDetail === a.id ? " selected" : "");
    tr.dataset.alarmId = a.id; tr.dataset.tooth = a.tooth === null ? "whole" : a.tooth; tr.dataset.indicator = a.indicator;
    const ack = a.acknowledged_by ? `${a.acknowledged_by}, ${date(a.acknowledged_at)}: ${a.ack_comment || "(no comment)"}` : "";
    const cells = [a.id, where(a), info(a.indicator).title, a.state, recordName(a.record_label, a.raised_at),
      withUnit(a.last_value, a.unit), `${withUnit(a.last_score, "")} SD`, ack];
    for (const text of cells) {
      const td = document.createElement("td"); td.textContent = String(text); tr.appendChild(td);
    }
    const td = document.createElement("td"); td.className = "action";
    if ((a.state === "warning" || a.state === "alarm") && canAck) {
      const button = document.createElement("button");
      button.textContent = "Acknowledge…"; button.className = "ack"; button.type = "button";
      button.onclick = (event) => { event.stopPropagation(); showAlarm(a, true); };
      td.appendChild(button);
    }
    tr.appendChild(td);
    tr.onclick = () => showAlarm(a, false);
    body.appendChild(tr);
  }
  if (!shown) {
    const tr = document.createElement("tr"), td = document.createElement("td");
    td.colSpan = 9; td.textContent = "no alarm in this list"; tr.appendChild(td); body.appendChild(tr);
  }
}

async function showAlarm(alarm, acknowledging) {
  // an alarm raised on a record the views do not show (an earlier gear pair): show its campaign
  // first, so that its tooth is that pinion's tooth
  const onShownRecords = state.trend && state.trend.records.some((r) => r.record_id === alarm.record_id);
  if (!onShownRecords && alarm.campaign_id && alarm.campaign_id !== state.campaign) {
    await switchRig(state.rig, alarm.campaign_id);
  }
  state.alarmDetail = alarm.id;
  const detail = await api(`/alarms/${alarm.id}`).catch((error) => { message(error.message); return null; });
  if (!detail) return;
  el("alarm-detail").hidden = false;
  el("alarm-detail-id").textContent = `${alarm.id} (${where(alarm)}, ${info(alarm.indicator).title})`;
  const list = el("alarm-history");
  list.innerHTML = "";
  for (const e of detail.history) {
    const li = document.createElement("li");
    const rec = e.record_id ? recordById(e.record_id) : null;
    let text = `${date(e.at)} ${e.state}`;
    if (rec) text += ` by ${recordName(rec.label, rec.taken_at)}`;
    if (e.value !== null && e.value !== undefined) text += `, value ${withUnit(e.value, alarm.unit)}`;
    if (e.score !== null && e.score !== undefined) text += `, ${withUnit(e.score, "")} SD`;
    if (e.who) text += ` — ${e.who}`;
    if (e.comment) text += `: “${e.comment}”`;
    li.textContent = text; list.appendChild(li);
  }
  el("ack-form").hidden = !acknowledging;
  el("ack-form").dataset.alarmId = String(alarm.id);
  if (acknowledging) { el("ack-comment").value = ""; el("ack-comment").focus(); }
  renderAlarms();
  // show what the alarm is about: its indicator, tooth and raising record
  if (alarm.indicator !== state.indicator) {
    el("indicator").value = alarm.indicator;
    await switchIndicator(alarm.indicator, false);
  }
  if (alarm.tooth === null) selectWhole(); else selectTooth(alarm.tooth);
  if (alarm.record_id && recordById(alarm.record_id)) await selectRecord(alarm.record_id);
}

async function acknowledge(event) {
  event.preventDefault();
  const id = Number(el("ack-form").dataset.alarmId);
  const comment = el("ack-comment").value;
  try {
    await api(`/alarms/${id}/ack`, { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify({ comment }) });
  } catch (error) { message("acknowledge: " + error.message); return; }
  await loadAlarms();
  const alarm = state.alarms.find((a) => a.id === id);
  if (alarm) await showAlarm(alarm, false);
  loadOverview();
}

async function loadAlarms() {
  const data = await api(`/alarms?rig_id=${encodeURIComponent(state.rig)}&limit=1000`);
  state.alarms = data.items;
  renderAlarms(); drawHeatmap();
}

/* ---------- CSV exports (fetched with the key, saved as a file) ---------- */
async function download(path, name) {
  try {
    const response = await api(path, { raw: true });
    const blob = await response.blob();
    const a = document.createElement("a");
    a.href = URL.createObjectURL(blob); a.download = name;
    document.body.appendChild(a); a.click(); a.remove();
    setTimeout(() => URL.revokeObjectURL(a.href), 10_000);
  } catch (error) { message("export: " + error.message); }
}

/* ---------- loading a rig, an indicator ---------- */
async function loadTrend() {
  state.trend = await api(trendQuery(state.indicator));
  state.levels = await loadLevels(state.indicator);
}

/* Where each tooth stands against the indicator's enabled rule (null without one). */
async function loadLevels(indicator) {
  if (!(state.rules || []).some((r) => r.indicator === indicator && r.enabled)) return null;
  const campaign = state.campaign ? `&campaign=${encodeURIComponent(state.campaign)}` : "";
  const channel = state.trend.channel ? `&channel=${encodeURIComponent(state.trend.channel)}` : "";
  return api(`${rigPath()}/alarm-levels?indicator=${encodeURIComponent(indicator)}${campaign}${channel}`)
    .catch(() => null);  // no accepted record yet: no levels to draw
}

/* The rig's campaigns, newest first, each with its pinion and gear teeth when its manifest has them. */
function fillCampaigns() {
  const select = el("campaign");
  select.innerHTML = '<option value="">current gear pair</option>';
  for (const c of state.campaigns) {
    const rig = (c.manifest && c.manifest.rig) || {};
    const teeth = rig.pinion_teeth ? ` (${rig.pinion_teeth}/${rig.gear_teeth} teeth)` : "";
    const option = document.createElement("option");
    option.value = c.campaign_id; option.textContent = `${c.campaign_id}${teeth} — ${day(c.created_at)}`;
    select.appendChild(option);
  }
  select.value = state.campaigns.some((c) => c.campaign_id === state.campaign) ? state.campaign : "";
}

function startingTooth() {
  const trend = state.trend;
  const open = state.alarms.filter((a) => a.indicator === state.indicator && a.tooth !== null && ofShownCampaign(a) && (a.state === "alarm" || a.state === "warning"));
  if (open.length) return open.reduce((a, b) => (b.last_score > a.last_score ? b : a)).tooth;
  const row = trend.values[trend.values.length - 1];
  let tooth = trend.teeth[0], best = -Infinity;
  row.forEach((v, i) => { if (v !== null && v > best) { best = v; tooth = trend.teeth[i]; } });
  return tooth;
}

async function switchIndicator(name, reselect = true) {
  state.indicator = name;
  state.generation += 1;
  resetTrend(); resetHeatmap("loading…");
  try { await loadTrend(); } catch (error) { message(error.message); return; }
  drawHeatmap();
  if (!reselect || !state.trend.records.length) return;
  if (isWhole(name)) selectWhole(); else selectTooth(startingTooth());
}

async function switchRig(name, campaign = "") {
  const otherRig = name !== state.rig;
  state.rig = name; state.campaign = campaign;
  if (otherRig) { state.campaigns = []; fillCampaigns(); }  // not the previous rig's while loading
  resetAll();
  renderOverview();
  message("");
  const generation = state.generation;
  const rig = state.overview.find((r) => r.rig_id === name);
  if (rig && rig.worst_tooth && state.indicator === "score" && rig.worst_tooth.indicator !== "score") {
    // this rig's results hold no score (stored before it existed, or by other tools)
    state.indicator = rig.worst_tooth.indicator; el("indicator").value = state.indicator;
  }
  if (rig && !rig.pinion_teeth && !isWhole(state.indicator)) {
    state.indicator = "raw_kurtosis"; el("indicator").value = state.indicator;
    message(`rig ${name} has no tooth counts: showing a whole-record indicator (${info(state.indicator).title})`);
  }
  try {
    state.campaigns = (await api(`/campaigns?rig_id=${encodeURIComponent(name)}`)).items
      .sort((a, b) => b.created_at.localeCompare(a.created_at));
    if (!state.campaigns.some((c) => c.campaign_id === state.campaign)) state.campaign = "";
    fillCampaigns();
    state.rules = (await api(`${rigPath()}/alarm-rules`)).items;
    const ofCampaign = state.campaign ? `&campaign_id=${encodeURIComponent(state.campaign)}` : "";
    state.records = (await api(`/records?rig_id=${encodeURIComponent(name)}${ofCampaign}&limit=1000`)).items
      .sort((a, b) => a.taken_at.localeCompare(b.taken_at));
    await loadTrend();
    if (generation !== state.generation) return;
    fillRecordSelects();
    await loadAlarms();
  } catch (error) { message(error.message); resetHeatmap(error.message); return; }
  if (generation !== state.generation) return;
  const trend = state.trend;
  drawHeatmap();
  if (trend.records.length) {
    if (isWhole(state.indicator)) selectWhole(); else selectTooth(startingTooth());
    await selectRecord(trend.records[trend.records.length - 1].record_id);
  }
  if (generation === state.generation) document.body.dataset.ready = "true";
}

async function loadOverview() {
  state.overview = (await api("/overview")).items;
  renderOverview();
}

function fillIndicators() {
  const select = el("indicator");
  select.innerHTML = "";
  for (const [scope, title] of [["tooth", "per tooth"], ["record", "whole record"]]) {
    const group = document.createElement("optgroup");
    group.label = title;
    for (const i of state.indicators.filter((x) => x.scope === scope)) {
      const option = document.createElement("option");
      option.value = i.name; option.textContent = i.title;
      group.appendChild(option);
    }
    select.appendChild(group);
  }
}

async function start() {
  try { state.me = await api("/me"); }
  catch (error) { message(error.message); return; }
  el("login").hidden = true; el("controls").hidden = false; el("panels").hidden = false;
  el("role").textContent = `${state.me.name || "key " + state.me.prefix} (${state.me.role})`;
  state.indicators = (await api("/indicators")).items;
  fillIndicators();
  await loadOverview();
  // The per-tooth score when the rigs' stored results hold one, else the MCI depth.
  const scored = state.overview.some((r) => r.worst_tooth && r.worst_tooth.indicator === "score");
  state.indicator = scored ? "score" : "mci_depth";
  el("indicator").value = state.indicator;
  const select = el("rig");
  select.innerHTML = "";
  for (const rig of state.overview) {
    const option = document.createElement("option");
    option.value = rig.rig_id; option.textContent = rig.rig_id; select.appendChild(option);
  }
  if (!state.overview.length) { message("no rig yet: replay or upload a campaign"); return; }
  const fragment = new URLSearchParams(window.location.hash.slice(1));
  const wanted = fragment.get("rig");
  const rig = state.overview.find((r) => r.rig_id === wanted) || state.overview[0];
  select.value = rig.rig_id;
  await switchRig(rig.rig_id, rig.rig_id === wanted ? fragment.get("campaign") || "" : "");
  const alarmId = Number(fragment.get("alarm"));
  const alarm = state.alarms.find((a) => a.id === alarmId);
  if (alarm) await showAlarm(alarm, false);
}

function init() {
  const fragment = new URLSearchParams(window.location.hash.slice(1));
  if (fragment.get("key")) {
    sessionStorage.setItem(KEY_STORAGE, fragment.get("key"));
    fragment.delete("key");
    const rest = fragment.toString();
    history.replaceState(null, "", window.location.pathname + window.location.search + (rest ? "#" + rest : ""));
  }
  state.key = sessionStorage.getItem(KEY_STORAGE);
  el("login").onsubmit = (event) => {
    event.preventDefault();
    state.key = el("api-key").value.trim();
    sessionStorage.setItem(KEY_STORAGE, state.key);
    start();
  };
  el("logout").onclick = forgetKey;
  el("rig").onchange = () => switchRig(el("rig").value);
  el("campaign").onchange = () => switchRig(state.rig, el("campaign").value);
  el("indicator").onchange = () => switchIndicator(el("indicator").value);
  el("record").onchange = () => selectRecord(Number(el("record").value), null);
  el("compare").onchange = () => selectRecord(state.record, el("compare").value ? Number(el("compare").value) : null);
  el("alarm-state").onchange = renderAlarms;
  el("ack-form").onsubmit = acknowledge;
  el("ack-cancel").onclick = () => { el("ack-form").hidden = true; };
  el("trend-csv").onclick = () => download(`${trendQuery(state.indicator)}&format=csv`,
    `${state.rig}${state.campaign ? "-" + state.campaign : ""}-${state.indicator}.csv`);
  el("alarms-csv").onclick = () => download(`/alarms?rig_id=${encodeURIComponent(state.rig)}&limit=1000&format=csv`, `alarms-${state.rig}.csv`);
  if (state.key) start(); else forgetKey();
}

init();
