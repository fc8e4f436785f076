// aatest station page: one websocket for live events and commands, fetch() for lists.
"use strict";
const $ = (id) => document.getElementById(id);
const state = { steps: new Map(), startedMs: null, plots: null, received: 0, runName: null,
  procedures: new Map(), log: [], runState: "", tableLive: null, tablePoints: 0 };
// polled table readings kept per step plot; beyond this every second one is dropped
const TABLE_LIVE_MAX = 4000;
// run states in which a run holds the rig: Start is disabled, Abort offered
const BUSY = new Set(["starting", "running", "waiting for the operator", "analysing"]);
const ABORTABLE = new Set(["starting", "running", "waiting for the operator"]);
let socket = null;

function send(msg) {
  msg.operator = $("operator").value || undefined;
  socket.send(JSON.stringify(msg));
}

function cell(row, text) { const td = document.createElement("td"); td.textContent = text ?? "—"; row.appendChild(td); return td; }
function fmtTime(s) { s = Math.max(0, Math.round(s)); const h = Math.floor(s / 3600), m = Math.floor(s % 3600 / 60); return `${h}:${String(m).padStart(2, "0")}:${String(s % 60).padStart(2, "0")}`; }

// Procedures by title and description, grouped (shipped, the lab's, uploaded); the value sent
// is the station's id, never a path.
async function loadProcedures() {
  const doc = await (await fetch("/api/procedures")).json();
  const select = $("procedure"), chosen = select.value;
  select.innerHTML = ""; state.procedures.clear();
  const groups = new Map();
  for (const p of doc.procedures) {
    state.procedures.set(p.id, p);
    if (!groups.has(p.group)) { const g = document.createElement("optgroup"); g.label = p.group; groups.set(p.group, g); select.appendChild(g); }
    const o = document.createElement("option"); o.value = p.id;
    o.textContent = p.ok ? p.title : `${p.title} (does not load)`;
    o.title = p.description || ""; groups.get(p.group).appendChild(o);
  }
  if (chosen && state.procedures.has(chosen)) select.value = chosen;
  $("models").innerHTML = "";
  for (const m of doc.models || []) { const o = document.createElement("option"); o.value = m; $("models").appendChild(o); }
  $("signing").textContent = doc.signing && doc.signing.signed
    ? `reports signed (key ${doc.signing.fingerprint.slice(0, 16)}…)` : "reports unsigned: no signing key configured";
  describeProcedure();
}

function describeProcedure() {
  const p = state.procedures.get($("procedure").value);
  $("procedure-description").textContent = p ? (p.description || "(no description)") : "";
  if (p && p.model) $("model").placeholder = p.model;
  if (p && p.serial && p.serial !== "unknown") $("serial").placeholder = `${p.serial} (the procedure's)`;
  else $("serial").placeholder = "scan or type, then Enter";
}

let validations = 0;
async function validate() {
  const id = $("procedure").value, mine = ++validations;
  const doc = await (await fetch("/api/validate?id=" + encodeURIComponent(id))).json();
  if (mine !== validations) return;  // a later request superseded this one
  showValidation(doc, id);
}

// An uploaded file is sent as text with its name (never a path); the station validates it like
// a file on disk and keeps it only when valid, under the id it answers with.
async function upload() {
  const file = $("upload").files[0];
  if (!file) return;
  const mine = ++validations;
  $("upload-state").textContent = `uploading ${file.name}…`;
  const response = await fetch("/api/upload?name=" + encodeURIComponent(file.name),
    { method: "POST", headers: { "Content-Type": "application/x-yaml" }, body: await file.text() });
  const doc = await response.json();
  if (mine !== validations) return;
  $("upload").value = "";
  if (doc.ok) {
    await loadProcedures();
    $("procedure").value = doc.id;
    $("upload-state").textContent = `${doc.name}: valid, listed as ${doc.id}`;
  } else {
    $("upload-state").textContent = `${doc.name || file.name}: not valid, not kept`;
  }
  showValidation(doc, doc.id || `rejected/${doc.name || file.name}`);
}

function showValidation(doc, id) {
  $("plan").dataset.procedure = id;
  $("problems").innerHTML = "";
  const body = $("plan").querySelector("tbody");
  body.innerHTML = "";
  for (const p of doc.problems || []) { const li = document.createElement("li"); li.textContent = p; $("problems").appendChild(li); }
  for (const s of doc.steps || []) { const tr = body.insertRow(); cell(tr, s.id); cell(tr, s.motion); cell(tr, s.lab_duration_s.toFixed(1)); cell(tr, s.prompt || ""); }
}

function renderSteps() {
  const list = $("steps");
  list.innerHTML = "";
  let remaining = 0;
  for (const s of state.steps.values()) {
    const li = document.createElement("li");
    li.dataset.state = s.state; li.dataset.id = s.id;
    li.textContent = `${s.id} — ${s.motion} [${s.state}]`;
    list.appendChild(li);
    if (s.state !== "done") remaining += s.lab_duration_s;
  }
  $("remaining").textContent = fmtTime(remaining);
}

// Tick labels that keep small values readable (a table at rest moves by 1e-4°; the default
// labels round that to "0").
function ticks(u, splits) {
  return splits.map((v) => v == null ? "" : v === 0 ? "0"
    : Math.abs(v) >= 1e-2 && Math.abs(v) < 1e5 ? String(+v.toPrecision(4)) : v.toExponential(1));
}

function makePlots(sensors, axis) {
  for (const id of ["plot-table", "plot-daq"]) $(id).innerHTML = "";
  const width = Math.min(900, window.innerWidth - 60);
  const table = new uPlot({ title: `table log (${axis} axis estimate, delivered by the controller)`, width, height: 180,
    scales: { x: { time: false } },
    series: [{ label: "t s" }, { label: "position °", stroke: "#1f3a5f", scale: "deg" },
             { label: "accel °/s²", stroke: "#d08b00", scale: "acc" }],
    axes: [{}, { scale: "deg", values: ticks, size: 60 }, { scale: "acc", side: 1, values: ticks, size: 60 }] },
    [[], [], []], $("plot-table"));
  const colours = ["#2a7a2a", "#a11", "#5a2a9a", "#0a7f8f", "#8f5a0a"];
  const daq = new uPlot({ title: "sensor channels (V)", width, height: 180, scales: { x: { time: false } },
    series: [{ label: "t s" }, ...sensors.map((c, i) => ({ label: c, stroke: colours[i % colours.length] }))],
    axes: [{}, { values: ticks, size: 60 }] },
    [[], ...sensors.map(() => [])], $("plot-daq"));
  state.plots = { table, daq, axis, sensors, tdata: [[], [], []], ddata: [[], ...sensors.map(() => [])] };
}

function addSamples(msg) {
  const p = state.plots; if (!p) return;
  const tk = [`${p.axis}_position_deg`, `${p.axis}_accel_dps2`];
  if (msg.table && msg.table.t) { p.tdata[0].push(...msg.table.t); tk.forEach((k, i) => p.tdata[i + 1].push(...(msg.table[k] || msg.table.t.map(() => null)))); p.table.setData(p.tdata); }
  if (msg.daq && msg.daq.t) {
    p.ddata[0].push(...msg.daq.t); p.sensors.forEach((c, i) => p.ddata[i + 1].push(...msg.daq[c])); p.daq.setData(p.ddata);
    state.received += msg.daq.t.length;
  }
  $("sample-count").textContent = String(state.received);
  state.log.push({ type: "samples", id: msg.id, live: !!msg.live, received: state.received });
}

// The table's position and rate from its status, polled while the step runs: one plot per
// step, on the table's clock (or the station's, for a controller that reports no clock).
function makeTableLive(id, axis, clock) {
  $("plot-table-live").innerHTML = "";
  const width = Math.min(900, window.innerWidth - 60);
  const plot = new uPlot({ title: `table now (${axis} axis, polled status)`, width, height: 160,
    scales: { x: { time: false } },
    series: [{ label: clock === "host" ? "t s (station clock)" : "t s (table clock)" },
             { label: "position °", stroke: "#1f3a5f", scale: "deg" },
             { label: "rate °/s", stroke: "#a11", scale: "rate" }],
    axes: [{}, { scale: "deg", values: ticks, size: 60 }, { scale: "rate", side: 1, values: ticks, size: 60 }] },
    [[], [], []], $("plot-table-live"));
  state.tableLive = { id, axis, plot, data: [[], [], []] };
}

function addTablePoint(msg) {
  let p = state.tableLive;
  if (!p || p.id !== msg.id || p.axis !== msg.axis) { makeTableLive(msg.id, msg.axis, msg.clock); p = state.tableLive; }
  p.data[0].push(msg.t); p.data[1].push(msg.position_deg); p.data[2].push(msg.rate_dps);
  if (p.data[0].length > TABLE_LIVE_MAX) p.data = p.data.map((s) => s.filter((_, i) => i % 2 === 0));
  p.plot.setData(p.data);
  state.tablePoints += 1;
  $("table-live-count").textContent = String(state.tablePoints);
  $("table-now").textContent = `${msg.position_deg.toFixed(4)} °, ${msg.rate_dps.toFixed(4)} °/s`;
  const note = $("table-live-note"); note.dataset.live = "yes";
  note.textContent = `Table of ${msg.id}: position and rate from its status, polled while the step runs.`;
  state.log.push({ type: "table_live", id: msg.id, points: state.tablePoints });
}

function tableLiveOff(reason) {
  const note = $("table-live-note"); note.dataset.live = "no"; note.textContent = `Live table: ${reason}.`;
}

function showPrompt(msg) {
  if (!msg) { $("prompt").hidden = true; return; }
  $("prompt").hidden = false;
  $("prompt-step").textContent = msg.id;
  $("prompt-text").textContent = msg.instruction;
  const body = $("prompt-sensors").querySelector("tbody"); body.innerHTML = "";
  for (const s of msg.sensors) { const tr = body.insertRow(); cell(tr, s.channel); cell(tr, s.axis); cell(tr, s.orientation); }
  $("continue").dataset.step = msg.id;
}

function fileLinks(parent, name, files) {
  parent.innerHTML = "";
  for (const f of files || []) {  // only the files on disk: no PDF link when none was printed
    const a = document.createElement("a"); a.href = `/runs/${encodeURIComponent(name)}/${f}`; a.textContent = f; a.target = "_blank";
    parent.appendChild(a); parent.appendChild(document.createTextNode(" "));
  }
}

function showResult(msg) {
  $("result").hidden = false;
  const v = $("verdict"); v.className = "verdict " + (msg.overall || "none");
  v.textContent = "Verdict: " + (msg.overall || "none").toUpperCase()
    + (msg.simulation ? " — " + msg.simulation : "");
  v.title = msg.signed ? "signed report" : "unsigned report";
  const body = $("verdicts").querySelector("tbody"); body.innerHTML = "";
  for (const r of msg.verdicts || []) {
    // the quantity's name and unit from the registry, value ± U rounded as on the certificate
    const tr = body.insertRow(); cell(tr, r.quantity); cell(tr, r.channel); cell(tr, r.measured);
    cell(tr, r.limit_text); cell(tr, r.rule); cell(tr, r.verdict);
  }
  fileLinks($("links"), msg.name, msg.files);
  if (msg.notice) notify(msg.notice);
  loadHistory();
}

function notify(text) { $("notice").hidden = false; $("notice-text").textContent = text; }
function dismiss() { $("notice").hidden = true; }

function setControls() {
  const busy = BUSY.has(state.runState), abortable = ABORTABLE.has(state.runState);
  $("start").disabled = busy;
  $("abort").hidden = !abortable; $("abort").disabled = !abortable;
  for (const b of document.querySelectorAll("button.resume-run, #resume")) b.disabled = busy;
}

function setRunState(text) { state.runState = text; $("run-state").textContent = text; setControls(); }

function showUnit(model, serial) {
  $("run-unit").textContent = `${model || ""} ${serial || ""}`.trim();
  $("unit-link").href = "/units/" + encodeURIComponent(serial || "");
}

function onEvent(msg) {
  switch (msg.type) {
    case "role":
      document.body.classList.toggle("watching", msg.role !== "control");
      $("role").textContent = msg.role === "control" ? "you control the rig" : "watching (another page controls)";
      break;
    case "snapshot":
      if (msg.run && msg.run.name) {
        $("live").hidden = false; $("run-name").textContent = msg.run.name; state.runName = msg.run.name;
        showUnit(msg.run.model, msg.run.serial);
        setRunState({ run_dir: "starting", analysing: "analysing" }[msg.run.state] || msg.run.state || "");
        if (msg.run.state === "finished") showResult(msg.run);
        if (msg.run.table_status) tableLiveOff(msg.run.table_status);
      }
      state.steps = new Map(msg.steps.map((s) => [s.id, s])); renderSteps(); showPrompt(msg.prompt);
      break;
    case "run_dir":
      $("live").hidden = false; $("result").hidden = true; $("stopped").hidden = true;
      state.runName = msg.name; $("run-name").textContent = msg.name; setRunState("starting");
      showUnit(msg.model, msg.serial); state.log = []; state.steps = new Map(); renderSteps();
      $("current").textContent = "—"; $("motion").textContent = "";
      state.startedMs = Date.now(); state.received = 0; $("sample-count").textContent = "0";
      state.tablePoints = 0; state.tableLive = null; $("table-live-count").textContent = "0";
      $("plot-table-live").innerHTML = ""; $("table-now").textContent = "—";
      break;
    case "run_started":
      state.steps = new Map(msg.steps.map((s) => [s.id, s])); renderSteps(); setRunState("running");
      break;
    case "step":
      if (state.steps.has(msg.id)) state.steps.get(msg.id).state = msg.state;
      if (msg.state === "running") { $("current").textContent = msg.id; $("motion").textContent = msg.motion; }
      state.log.push({ type: "step", id: msg.id, state: msg.state, received: state.received });
      renderSteps();
      break;
    case "plot_reset":
      makePlots(msg.sensors, msg.axis); $("plot-label").textContent = `Plots of ${msg.id}: ${msg.label}.`;
      $("plot-label").dataset.live = msg.live ? "yes" : "no"; break;
    case "samples": addSamples(msg); break;
    case "table_live": addTablePoint(msg); break;
    case "table_live_off": tableLiveOff(msg.reason); break;
    case "prompt": showPrompt(msg); setRunState("waiting for the operator"); break;
    case "prompt_answered": showPrompt(null); setRunState("running"); break;
    case "analysing": setRunState("analysing"); break;
    case "stopped":
      if (msg.exit_code === undefined) break;  // the engine's notice; the final one carries the exit code
      setRunState("stopped"); showPrompt(null); state.startedMs = null;
      $("stopped").hidden = false; $("stopped-text").textContent = msg.reason;
      $("resume").hidden = !msg.resumable; loadHistory(); $("start").focus();
      break;
    case "finished": setRunState("finished"); state.startedMs = null; showResult(msg); $("verdict").focus(); break;
    case "error": notify(msg.message); break;
  }
}

async function loadHistory() {
  const doc = await (await fetch("/api/runs")).json();
  const body = $("history").querySelector("tbody"); body.innerHTML = "";
  $("history-source").textContent = doc.source === "records"
    ? `Recent calibrations from the records store ${doc.store}` : "Recent runs in the runs directory";
  for (const r of doc.runs) {
    const tr = body.insertRow(); tr.dataset.run = r.name || "";
    const label = r.source === "records"
      ? [r.certificate_number, r.unit, r.calibrated_utc, r.operator].filter(Boolean).join(" · ") : r.name;
    const first = cell(tr, label);
    if (r.serial) {  // the unit's page: its history and trend
      const a = document.createElement("a"); a.href = "/units/" + encodeURIComponent(r.serial);
      a.textContent = r.source === "records" ? "unit history" : `unit ${r.serial}`; a.className = "unit-link";
      first.appendChild(document.createTextNode(" · ")); first.appendChild(a);
    }
    cell(tr, r.procedure); cell(tr, r.finished ? "finished" : "stopped"); cell(tr, r.overall || "—");
    const files = cell(tr, "");
    if (r.name) fileLinks(files, r.name, r.files);
    const act = cell(tr, "");
    if (!r.finished) { const b = document.createElement("button"); b.textContent = "Resume"; b.className = "control resume-run";
      b.disabled = BUSY.has(state.runState);
      b.onclick = () => send({ type: "resume", run: r.name }); act.appendChild(b); }
  }
}

function connect() {
  socket = new WebSocket(`${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws`);
  socket.onmessage = (e) => onEvent(JSON.parse(e.data));
  socket.onclose = () => { $("role").textContent = "disconnected"; setTimeout(connect, 1000); };
}

function start() {
  if ($("start").disabled) return;
  dismiss();
  send({ type: "start", procedure: $("procedure").value, serial: $("serial").value.trim(),
         model: $("model").value.trim(), pdf: $("pdf").checked });
}

// Keyboard: a barcode scanner types the serial and Enter, which moves on to the procedure;
// Enter on the procedure validates it and moves to Start; Escape dismisses a notice, and
// while a run holds the rig it brings the focus to Abort (Enter or Space then aborts).
function onKey(e) {
  if (e.key === "Escape") {
    if (!$("notice").hidden) { dismiss(); e.preventDefault(); return; }
    if (!$("abort").disabled) { $("abort").focus(); e.preventDefault(); }
    return;
  }
  if (e.key !== "Enter") return;
  if (e.target === $("serial") || e.target === $("model")) {
    e.preventDefault(); $("procedure").focus();
  } else if (e.target === $("procedure")) {
    e.preventDefault(); validate().then(() => $("start").focus());
  }
}

$("validate").onclick = validate;
$("procedure").onchange = () => { describeProcedure(); validate(); };
$("upload").onchange = upload;
$("start").onclick = start;
$("abort").onclick = () => send({ type: "abort" });
$("continue").onclick = () => send({ type: "answer", step: $("continue").dataset.step });
$("resume").onclick = () => send({ type: "resume", run: state.runName || $("run-name").textContent });
$("refresh").onclick = loadHistory;
$("notice-close").onclick = dismiss;
document.addEventListener("keydown", onKey);
setInterval(() => { if (state.startedMs) $("elapsed").textContent = fmtTime((Date.now() - state.startedMs) / 1000); }, 500);
setControls();
$("serial").focus();
// the first listing validates the chosen procedure, unless the operator acted meanwhile
const firstValidation = validations;
loadProcedures().then(() => { if (validations === firstValidation) validate(); });
loadHistory(); connect();
