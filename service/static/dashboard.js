/* gearwatch dashboard: plain JavaScript over the REST API, charts by the vendored uPlot.
 * The API key is kept in sessionStorage (or given once as #key=... in the URL) and sent as
 * "Authorization: Bearer <key>"; the page itself holds no data. */
"use strict";

const KEY_STORAGE = "gearwatch.apiKey";
const el = (id) => document.getElementById(id);
const state = {
  key: null, me: null, rig: null, indicator: "mci_depth",
  trend: null, alarms: [], rules: [], record: null, tooth: null,
  curvePlot: null, trendPlot: null,
};

function message(text) { el("message").textContent = text || ""; }

async function api(path, options = {}) {
  const headers = Object.assign({ "Authorization": "Bearer " + state.key }, options.headers || {});
  const response = await fetch("api/v1" + path, Object.assign({}, options, { headers }));
  if (response.status === 401) { forgetKey(); throw new Error("the API key was refused"); }
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

/* ---------- colour scale (viridis, 9 stops) ---------- */
const VIRIDIS = ["#440154", "#472d7b", "#3b528b", "#2c728e", "#21918c", "#28ae80", "#5ec962", "#addc30", "#fde725"];
function colour(t) {
  if (!Number.isFinite(t)) return "#dddddd";
  const x = Math.min(1, Math.max(0, t)) * (VIRIDIS.length - 1);
  return VIRIDIS[Math.round(x)];
}
function quantile(sorted, q) {
  if (!sorted.length) return NaN;
  const i = (sorted.length - 1) * q, lo = Math.floor(i), hi = Math.ceil(i);
  return sorted[lo] + (sorted[hi] - sorted[lo]) * (i - lo);
}

/* ---------- heat map: tooth (rows) × record (columns) ---------- */
function openAlarmTeeth() {
  const teeth = new Map();
  for (const a of state.alarms) {
    if (a.indicator !== state.indicator) continue;
    if (a.state === "alarm" || a.state === "warning" || a.state === "acknowledged") {
      const worst = teeth.get(a.tooth);
      if (worst !== "alarm") teeth.set(a.tooth, a.state);
    }
  }
  return teeth;
}

function drawHeatmap() {
  const canvas = el("heatmap"), ctx = canvas.getContext("2d");
  const trend = state.trend;
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  el("heatmap-title").textContent = state.indicator;
  if (!trend || !trend.records.length) {
    el("heatmap-legend").textContent = "no accepted records yet";
    el("alarmed-teeth").textContent = "";
    return;
  }
  const nRec = trend.records.length, nTeeth = trend.teeth.length;
  const left = 56, top = 8, bottom = 28, right = 8;
  const cw = (canvas.width - left - right) / nRec, ch = (canvas.height - top - bottom) / nTeeth;
  const finite = trend.values.flat().filter(Number.isFinite).sort((a, b) => a - b);
  const lo = quantile(finite, 0.02), hi = quantile(finite, 0.98);
  const span = hi - lo || 1;
  for (let r = 0; r < nRec; r++) {
    for (let t = 0; t < nTeeth; t++) {
      const v = trend.values[r][t];
      ctx.fillStyle = colour(v === null ? NaN : (v - lo) / span);
      ctx.fillRect(left + r * cw, top + t * ch, Math.ceil(cw), Math.ceil(ch));
    }
  }
  const alarmed = openAlarmTeeth();
  ctx.font = "11px sans-serif"; ctx.textBaseline = "middle";
  const labelEvery = Math.max(1, Math.ceil(12 / ch));
  trend.teeth.forEach((tooth, t) => {
    const y = top + (t + 0.5) * ch;
    if (alarmed.has(tooth)) {
      ctx.fillStyle = alarmed.get(tooth) === "warning" ? "#e69500" : "#b00020";
      ctx.fillRect(left - 8, top + t * ch, 6, Math.max(2, ch));
      ctx.strokeStyle = ctx.fillStyle; ctx.lineWidth = 2;
      ctx.strokeRect(left + 1, top + t * ch + 1, canvas.width - left - right - 2, Math.max(1, ch - 2));
    }
    if (t % labelEvery === 0 || alarmed.has(tooth)) {
      ctx.fillStyle = alarmed.has(tooth) ? "#b00020" : "#333";
      ctx.fillText(String(tooth), 8, y);
    }
  });
  if (state.record !== null) {
    const r = trend.records.findIndex((x) => x.record_id === state.record);
    if (r >= 0) { ctx.strokeStyle = "#fff"; ctx.lineWidth = 1; ctx.strokeRect(left + r * cw, top, cw, nTeeth * ch); }
  }
  ctx.fillStyle = "#333"; ctx.textBaseline = "top";
  ctx.fillText(trend.records[0].taken_at.slice(0, 10), left, canvas.height - bottom + 8);
  const last = trend.records[nRec - 1].taken_at.slice(0, 10);
  ctx.fillText(last, canvas.width - right - ctx.measureText(last).width, canvas.height - bottom + 8);
  el("heatmap-legend").textContent =
    `${nRec} records × ${nTeeth} teeth; colour from ${lo.toPrecision(3)} (dark) to ${hi.toPrecision(3)} (yellow)`;
  const names = [...alarmed.entries()].sort((a, b) => a[0] - b[0]).map(([tooth, s]) => `tooth ${tooth} (${s})`);
  el("alarmed-teeth").textContent = names.length ? "Alarmed: " + names.join(", ") : "No open alarm on this indicator";
  el("heatmap").dataset.alarmedTeeth = [...alarmed.keys()].join(",");
  canvas.onclick = (event) => {
    const box = canvas.getBoundingClientRect();
    const x = (event.clientX - box.left) * canvas.width / box.width;
    const y = (event.clientY - box.top) * canvas.height / box.height;
    const r = Math.floor((x - left) / cw), t = Math.floor((y - top) / ch);
    if (r < 0 || r >= nRec || t < 0 || t >= nTeeth) return;
    selectRecord(trend.records[r].record_id);
    selectTooth(trend.teeth[t]);
    drawHeatmap();
  };
}

/* ---------- MCI curve with tooth sectors and the baseline band ---------- */
async function selectRecord(recordId) {
  state.record = recordId;
  el("curve-title").textContent = "#" + recordId;
  let data;
  try { data = await api(`/records/${recordId}/curves?names=mci&band=true`); }
  catch (error) { message("curve: " + error.message); return; }
  const mci = data.curves.mci || [];
  const n = mci.length;
  const angle = Array.from({ length: n }, (_, i) => (360 * i) / n);
  const series = [{ label: "angle (deg)" }, { label: "MCI", stroke: "#1f5fbf", width: 1.5 }];
  const columns = [angle, mci];
  const bands = [];
  if (data.baseline_band) {
    series.push({ label: "baseline low", stroke: "#9aa5b1", dash: [4, 4] });
    series.push({ label: "baseline high", stroke: "#9aa5b1", dash: [4, 4] });
    columns.push(data.baseline_band.lower, data.baseline_band.upper);
    bands.push({ series: [3, 2], fill: "rgba(120,140,160,0.18)" });
  }
  const sectors = data.sectors || [];
  const highlight = state.tooth;
  const opts = {
    width: Math.min(860, el("curve").clientWidth || 860), height: 280, series, bands,
    scales: { x: { time: false } },
    axes: [{ label: "pinion angle after tach edge (deg)" }, { label: "MCI (Np)" }],
    hooks: {
      drawClear: [(u) => {
        const ctx = u.ctx;
        ctx.save();
        sectors.forEach((s, i) => {
          const x0 = u.valToPos(s.start_deg, "x", true), x1 = u.valToPos(s.end_deg, "x", true);
          ctx.fillStyle = s.tooth === highlight ? "rgba(176,0,32,0.15)" : (i % 2 ? "rgba(0,0,0,0.04)" : "rgba(0,0,0,0)");
          ctx.fillRect(Math.min(x0, x1), u.bbox.top, Math.abs(x1 - x0), u.bbox.height);
        });
        ctx.restore();
      }],
    },
  };
  if (state.curvePlot) state.curvePlot.destroy();
  el("curve").innerHTML = "";
  state.curvePlot = new uPlot(opts, columns, el("curve"));
  el("curve").dataset.sectors = String(new Set(sectors.map((s) => s.tooth)).size);
}

/* ---------- one tooth's trend, with its baseline and alarm levels ---------- */
function median(values) {
  const sorted = values.filter(Number.isFinite).sort((a, b) => a - b);
  return quantile(sorted, 0.5);
}

function toothBaseline(tooth, column) {
  // The stored alarm's baseline when there is one; else the rule's recipe on the first records.
  const rule = (state.rules || []).find((r) => r.indicator === state.indicator);
  const alarm = state.alarms.find((a) => a.indicator === state.indicator && a.tooth === tooth);
  if (alarm) return { centre: alarm.baseline_centre, spread: alarm.baseline_spread, rule };
  if (!rule) return null;
  const first = column.slice(0, rule.baseline_records).filter(Number.isFinite);
  if (first.length < rule.baseline_records) return null;
  const centre = median(first);
  const mad = median(first.map((v) => Math.abs(v - centre)));
  const spread = Math.max(1.4826 * mad, rule.spread_floor_fraction * Math.abs(centre), rule.spread_floor_abs);
  return { centre, spread, rule };
}

function selectTooth(tooth) {
  state.tooth = tooth;
  el("trend-title").textContent = `${tooth} (${state.indicator})`;
  const trend = state.trend;
  if (!trend) return;
  const t = trend.teeth.indexOf(tooth);
  if (t < 0) return;
  const xs = trend.records.map((r) => Date.parse(r.taken_at) / 1000);
  const ys = trend.values.map((row) => row[t]);
  const series = [{}, { label: `tooth ${tooth}`, stroke: "#b00020", width: 1.5, points: { show: true, size: 5 } }];
  const columns = [xs, ys];
  const base = toothBaseline(tooth, ys);
  if (base) {
    const flat = (v) => xs.map(() => v);
    series.push({ label: "baseline", stroke: "#607080", dash: [4, 4], points: { show: false } });
    columns.push(flat(base.centre));
    if (base.rule) {
      series.push({ label: "warning", stroke: "#e69500", dash: [6, 3], points: { show: false } });
      columns.push(flat(base.centre + base.rule.warning_level * base.spread));
      series.push({ label: "alarm", stroke: "#b00020", dash: [2, 2], points: { show: false } });
      columns.push(flat(base.centre + base.rule.alarm_level * base.spread));
    }
  }
  const opts = {
    width: Math.min(860, el("trend").clientWidth || 860), height: 240, series,
    axes: [{}, { label: state.indicator }],
  };
  if (state.trendPlot) state.trendPlot.destroy();
  el("trend").innerHTML = "";
  state.trendPlot = new uPlot(opts, columns, el("trend"));
  el("trend").dataset.levels = base && base.rule ? "true" : "false";
}

/* ---------- alarm list with acknowledgement ---------- */
function renderAlarms() {
  const filter = el("alarm-state").value;
  const body = el("alarms").querySelector("tbody");
  body.innerHTML = "";
  const canAck = state.me && state.me.role !== "viewer";
  for (const a of state.alarms) {
    const open = a.state === "warning" || a.state === "alarm";
    if (filter === "" && !open) continue;
    if (filter !== "" && filter !== "all" && a.state !== filter) continue;
    const tr = document.createElement("tr");
    tr.className = "state-" + a.state;
    tr.dataset.alarmId = a.id; tr.dataset.tooth = a.tooth;
    const ack = a.acknowledged_by ? `${a.acknowledged_by} ${(a.acknowledged_at || "").slice(0, 16)} ${a.ack_comment || ""}` : "";
    for (const text of [a.id, a.tooth, a.indicator, a.state, a.raised_at.slice(0, 16).replace("T", " "), a.record_id, ack]) {
      const td = document.createElement("td"); td.textContent = String(text); tr.appendChild(td);
    }
    const td = document.createElement("td");
    if (open && canAck) {
      const button = document.createElement("button");
      button.textContent = "Acknowledge"; button.className = "ack";
      button.onclick = async () => {
        const comment = window.prompt(`Comment for alarm ${a.id} (tooth ${a.tooth})`, "");
        if (comment === null) return;
        try { await api(`/alarms/${a.id}/ack`, { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify({ comment }) }); }
        catch (error) { message("acknowledge: " + error.message); return; }
        await loadAlarms();
      };
      td.appendChild(button);
    }
    tr.appendChild(td);
    tr.onclick = (event) => { if (event.target.tagName !== "BUTTON") { selectTooth(a.tooth); selectRecord(a.record_id); drawHeatmap(); } };
    body.appendChild(tr);
  }
}

async function loadAlarms() {
  const data = await api(`/alarms?rig_id=${encodeURIComponent(state.rig)}&limit=500`);
  state.alarms = data.items;
  renderAlarms(); drawHeatmap();
}

async function loadRig() {
  message("");
  try {
    state.rules = (await api(`/rigs/${encodeURIComponent(state.rig)}/alarm-rules`)).items;
    state.trend = await api(`/rigs/${encodeURIComponent(state.rig)}/trends?indicator=${state.indicator}`);
    await loadAlarms();
  } catch (error) { message(error.message); return; }
  const trend = state.trend;
  if (!trend.records.length) return;
  // Start on the open alarm furthest above its baseline, else on the last record and the highest tooth there.
  const open = state.alarms.filter((a) => a.indicator === state.indicator && (a.state === "alarm" || a.state === "warning"));
  const last = trend.records[trend.records.length - 1].record_id;
  let tooth = trend.teeth[0];
  if (open.length) tooth = open.reduce((a, b) => (b.last_score > a.last_score ? b : a)).tooth;
  else {
    const row = trend.values[trend.values.length - 1];
    let best = -Infinity;
    row.forEach((v, i) => { if (v !== null && v > best) { best = v; tooth = trend.teeth[i]; } });
  }
  selectTooth(tooth);
  await selectRecord(last);
  drawHeatmap();
  document.body.dataset.ready = "true";
}

async function start() {
  try { state.me = await api("/me"); }
  catch (error) { message(error.message); return; }
  el("login").hidden = true; el("controls").hidden = false; el("panels").hidden = false;
  el("role").textContent = `${state.me.name || "key " + state.me.prefix} (${state.me.role})`;
  const rigs = (await api("/rigs")).items;
  const select = el("rig");
  select.innerHTML = "";
  for (const rig of rigs) {
    const option = document.createElement("option");
    option.value = rig.rig_id; option.textContent = rig.rig_id; select.appendChild(option);
  }
  if (!rigs.length) { message("no rig yet: replay or upload a campaign"); return; }
  state.rig = rigs[0].rig_id;
  await loadRig();
}

function init() {
  const fragment = new URLSearchParams(window.location.hash.slice(1));
  if (fragment.get("key")) {
    sessionStorage.setItem(KEY_STORAGE, fragment.get("key"));
    history.replaceState(null, "", window.location.pathname + window.location.search);
  }
  state.key = sessionStorage.getItem(KEY_STORAGE);
  el("login").onsubmit = (event) => {
    event.preventDefault();
    state.key = el("api-key").value.trim();
    sessionStorage.setItem(KEY_STORAGE, state.key);
    start();
  };
  el("logout").onclick = forgetKey;
  el("rig").onchange = () => { state.rig = el("rig").value; loadRig(); };
  el("indicator").onchange = () => { state.indicator = el("indicator").value; loadRig(); };
  el("alarm-state").onchange = renderAlarms;
  if (state.key) start(); else forgetKey();
}

init();
