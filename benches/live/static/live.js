// tablebench live view: follows the run's event stream (server-sent events) and draws it. Read-only: this
// page sends nothing but GET requests. After a dropped connection the browser reconnects by itself and the
// server continues after the last event id it saw (Last-Event-ID), so nothing is missed or drawn twice.
"use strict";

const S = {
  run: null, steps: new Map(), current: null, bins: { lo: [], hi: [], binS: 1 }, params: [],
  history: { t: [], values: [], u: [] }, selected: 0, finished: false, lastId: 0, dirty: false,
};
const $ = (id) => document.getElementById(id);
const COLORS = ["#c0392b", "#27ae60", "#2e64b8"];

function fmtTime(s) {
  if (s === null || s === undefined || !isFinite(s)) return "—";
  s = Math.max(0, Math.round(s));
  const h = Math.floor(s / 3600), m = Math.floor((s % 3600) / 60), sec = s % 60;
  return `${h}:${String(m).padStart(2, "0")}:${String(sec).padStart(2, "0")}`;
}

// Value and its uncertainty printed to the uncertainty's second significant digit (GUM 7.2.6).
function decimalsFor(u) {
  if (u === null || u === undefined || !isFinite(u) || u <= 0) return 4;
  return Math.max(0, Math.min(12, 1 - Math.floor(Math.log10(u))));
}
function fmtPair(v, u) {
  if (v === null || v === undefined) return ["—", "—"];
  const d = decimalsFor(u);
  return [Number(v).toFixed(d), (u === null || u === undefined) ? "—" : Number(u).toFixed(d)];
}

function cell(tr, text, cls) {
  const td = document.createElement("td");
  td.textContent = text;
  if (cls) td.className = cls;
  tr.appendChild(td);
  return td;
}

// ---- plots -------------------------------------------------------------------------------------------------
let plots = {};
function makeBandPlot(el, title, unit, names) {
  const series = [{ label: "bench time (s)" }];
  const bands = [];
  names.forEach((n, i) => {
    series.push({ label: `${n} min`, stroke: COLORS[i], width: 1 });
    series.push({ label: `${n} max`, stroke: COLORS[i], width: 1, fill: COLORS[i] + "33" });
    bands.push({ series: [2 * i + 2, 2 * i + 1], fill: COLORS[i] + "33" });
  });
  const opts = {
    title: `${title} (${unit})`, width: Math.max(el.clientWidth, 300), height: 180, series, bands,
    scales: { x: { time: false } }, legend: { show: true, live: false },
    axes: [{ label: "bench time (s)" }, { label: unit, size: 70 }],
  };
  return new uPlot(opts, [[], ...names.flatMap(() => [[], []])], el);
}

function makeConvergencePlot(el) {
  const opts = {
    title: "convergence of the selected parameter (value and ±1σ)", width: Math.max(el.clientWidth, 300),
    height: 170, scales: { x: { time: false } }, legend: { show: true, live: false },
    series: [{ label: "bench time (s)" }, { label: "value", stroke: "#2e64b8", width: 2 },
      { label: "−1σ", stroke: "#2e64b8aa", dash: [4, 4] }, { label: "+1σ", stroke: "#2e64b8aa", dash: [4, 4] }],
    axes: [{ label: "bench time (s)" }, { size: 80 }],
  };
  return new uPlot(opts, [[], [], [], []], el);
}

function ensurePlots() {
  if (plots.accel || !S.run) return;
  const units = S.run.channel_units || ["", "", "", "", "", ""];
  plots.accel = makeBandPlot($("plot-accel"), "specific force", units[0], ["x", "y", "z"]);
  plots.gyro = makeBandPlot($("plot-gyro"), "angular rate", units[3], ["x", "y", "z"]);
  if (S.params.length) plots.conv = makeConvergencePlot($("plot-convergence"));
}

function redraw() {
  if (!S.dirty) return;
  S.dirty = false;
  ensurePlots();
  if (!plots.accel) return;
  const n = S.bins.lo.length, x = new Array(n);
  for (let i = 0; i < n; i++) x[i] = (i + 0.5) * S.bins.binS;
  for (const [key, off] of [["accel", 0], ["gyro", 3]]) {
    const data = [x];
    for (let c = 0; c < 3; c++) {
      data.push(S.bins.lo.map((r) => r[off + c]));
      data.push(S.bins.hi.map((r) => r[off + c]));
    }
    plots[key].setData(data);
  }
  if (plots.conv && S.history.t.length) {
    const k = S.selected;
    const v = S.history.values.map((r) => r[k]), u = S.history.u.map((r) => r[k]);
    // null: not identified yet at that update (a gap, never a number)
    const lo = v.map((a, i) => (a === null || u[i] === null ? null : a - u[i]));
    const hi = v.map((a, i) => (a === null || u[i] === null ? null : a + u[i]));
    plots.conv.setData([S.history.t, v, lo, hi]);
    const los = lo.filter((a) => a !== null), his = hi.filter((a) => a !== null);
    if (los.length) plots.conv.setScale("y", { min: Math.min(...los), max: Math.max(...his) });
  }
}
setInterval(redraw, 400);

// ---- events ------------------------------------------------------------------------------------------------
function onRun(d) {
  S.run = d;
  S.params = d.parameters || [];
  $("run-title").textContent = `${d.procedure || "procedure"} on ${d.bench || "bench"}` +
    (d.run_folder ? ` — ${d.run_folder}` : "");
  const ol = $("steps");
  ol.innerHTML = "";
  S.steps.clear();
  for (const s of d.steps) {
    const li = document.createElement("li");
    li.textContent = s.name + (s.text ? ` — ${s.text}` : "");
    li.dataset.index = s.index;
    li.dataset.state = "pending";
    ol.appendChild(li);
    S.steps.set(s.index, li);
  }
  setStatus(d.status || "running");
  $("remaining").textContent = fmtTime(d.estimated_s);
  const tb = document.querySelector("#estimates tbody");
  tb.innerHTML = "";
  S.params.forEach((p, i) => {
    const tr = document.createElement("tr");
    tr.dataset.index = i;
    cell(tr, p.name); cell(tr, "—"); cell(tr, "—"); cell(tr, p.unit);
    tr.addEventListener("click", () => selectParam(i));
    tb.appendChild(tr);
  });
  if (S.params.length) selectParam(0);
  else $("estimates-note").textContent = "(this run has no live identification)";
  S.dirty = true;
}

function selectParam(i) {
  S.selected = i;
  document.querySelectorAll("#estimates tbody tr").forEach((tr) => tr.classList.toggle("selected", +tr.dataset.index === i));
  if (plots.conv) plots.conv.setTitle?.(`convergence of ${S.params[i].name} (${S.params[i].unit}; value and ±1σ)`);
  S.dirty = true;
}

function setStatus(state) {
  const el = $("status");
  el.dataset.state = state;
  el.textContent = state;
}

function onStep(d) {
  const li = S.steps.get(d.index);
  if (li) li.dataset.state = d.state;
  if (d.state === "running") {
    if (S.current !== null && S.current !== d.index) {
      const prev = S.steps.get(S.current);
      if (prev && prev.dataset.state === "running") prev.dataset.state = "complete";
    }
    S.current = d.index;
    $("current-step").textContent = d.name;
    if (li) li.scrollIntoView({ block: "nearest" });
  }
}

function onBins(d) {
  if (d.replace) { S.bins.lo = []; S.bins.hi = []; }
  S.bins.binS = d.bin_s;
  S.bins.lo.splice(d.start, d.lo.length, ...d.lo);
  S.bins.hi.splice(d.start, d.hi.length, ...d.hi);
  $("elapsed").textContent = fmtTime(d.bench_s);
  $("remaining").textContent = fmtTime(d.remaining_s);
  if (d.table) showTable(d.table);
  if (d.health) showHealth(d.health);
  S.dirty = true;
}

function showTable(t) {
  const tb = document.querySelector("#table-state tbody");
  tb.innerHTML = "";
  const axes = (S.run && S.run.axes) || ["outer", "middle", "inner"];
  axes.forEach((a, i) => {
    const tr = document.createElement("tr");
    cell(tr, a);
    cell(tr, t.angles[i] === null ? "—" : t.angles[i].toFixed(4));
    cell(tr, t.demand && t.demand.angles ? t.demand.angles[i].toFixed(4) : "—");
    cell(tr, t.rates[i] === null ? "—" : t.rates[i].toFixed(4));
    cell(tr, t.demand && t.demand.rates ? t.demand.rates[i].toFixed(4) : "—");
    tb.appendChild(tr);
  });
}

function showHealth(h) {
  const dl = $("health");
  dl.innerHTML = "";
  const rows = [["frames rejected", h.frames_rejected], ["frames dropped", h.frames_dropped],
    ["counter resets", h.resets], ["duplicates", h.duplicates], ["checksums", h.checksums]];
  if (S.timeBase) rows.push(["time base", S.timeBase]);
  for (const [k, v] of rows) {
    const dt = document.createElement("dt"); dt.textContent = k;
    const dd = document.createElement("dd"); dd.textContent = String(v);
    dl.appendChild(dt); dl.appendChild(dd);
  }
  const ul = $("link-events");
  ul.innerHTML = "";
  for (const e of h.link_events || []) {
    const li = document.createElement("li"); li.textContent = e; ul.appendChild(li);
  }
}

function onEstimates(d) {
  S.history.t.push(d.bench_s);
  S.history.values.push(d.values);
  S.history.u.push(d.u);
  const rows = document.querySelectorAll("#estimates tbody tr");
  rows.forEach((tr, i) => {
    const unseen = d.identified && d.identified[i] === false;  // the motion so far does not see it: no number
    const [v, u] = unseen ? ["not identified yet", "—"] : fmtPair(d.values[i], d.u[i]);
    tr.children[1].textContent = v;
    tr.children[2].textContent = u;
  });
  S.dirty = true;
}

function onEnd(d) {
  setStatus(d.status);
  if (d.status === "complete" && S.current !== null) {
    const li = S.steps.get(S.current);
    if (li && li.dataset.state === "running") li.dataset.state = "complete";
  }
  $("current-step").textContent = d.status === "complete" ? "finished" : `${d.status}: ${d.reason}`;
  $("remaining").textContent = fmtTime(0);
}

function onResult(d) {
  S.finished = true;
  $("result-panel").hidden = false;
  $("verdict").textContent = d.verdict || "no certificate";
  const links = $("result-links");
  links.innerHTML = "";
  for (const f of d.files || []) {
    const a = document.createElement("a");
    a.href = `files/${encodeURIComponent(f)}`; a.textContent = f; a.target = "_blank";
    links.appendChild(a); links.appendChild(document.createTextNode(" "));
  }
  $("result-note").textContent = d.u_meaning || "";
  if (d.time_base) {
    const tb = d.time_base;
    S.timeBase = JSON.stringify(tb);
  }
  const tbody = document.querySelector("#result tbody");
  tbody.innerHTML = "";
  for (const p of d.parameters || []) {
    const tr = document.createElement("tr");
    tr.dataset.name = p.name;
    const [v, u] = fmtPair(p.value, p.u);
    cell(tr, p.name); cell(tr, v, "value"); cell(tr, u, "u"); cell(tr, p.unit || "");
    cell(tr, p.identified ? "" : "not identified (not applied)", p.identified ? "" : "not-identified");
    tbody.appendChild(tr);
  }
  if (source) { source.close(); setConnection("finished"); }
}

const HANDLERS = { run: onRun, step: onStep, bins: onBins, estimates: onEstimates, end: onEnd, result: onResult };

// ---- the connection ----------------------------------------------------------------------------------------
let source = null;
function setConnection(state) {
  const el = $("connection");
  el.dataset.state = state;
  el.textContent = state === "reconnecting" ? "connection lost — reconnecting" : state;
}

function connect() {
  source = new EventSource(`events?last=${S.lastId}`);
  source.onopen = () => setConnection("connected");
  source.onerror = () => {
    if (S.finished) return;
    setConnection(source.readyState === EventSource.CLOSED ? "closed" : "reconnecting");
    if (source.readyState === EventSource.CLOSED) setTimeout(connect, 2000);
  };
  for (const [name, fn] of Object.entries(HANDLERS)) {
    source.addEventListener(name, (ev) => {
      const id = Number(ev.lastEventId);
      if (id && id <= S.lastId) return;  // already drawn (never twice)
      S.lastId = id || S.lastId;
      fn(JSON.parse(ev.data));
      $("connection").dataset.lastEvent = String(S.lastId);
    });
  }
}
window.addEventListener("resize", () => {
  for (const p of Object.values(plots)) p.setSize({ width: Math.max(p.root.parentElement.clientWidth, 300), height: p.height });
});
connect();
