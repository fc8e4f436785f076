// aatest station page: one websocket for live events and commands, fetch() for lists.
"use strict";
const $ = (id) => document.getElementById(id);
const state = { steps: new Map(), startedMs: null, plots: null, received: 0, runName: null };
let socket = null;

function send(msg) {
  msg.operator = $("operator").value || undefined;
  socket.send(JSON.stringify(msg));
}

function cell(row, text) { const td = document.createElement("td"); td.textContent = text ?? "—"; row.appendChild(td); return td; }
function fmtTime(s) { s = Math.max(0, Math.round(s)); const h = Math.floor(s / 3600), m = Math.floor(s % 3600 / 60); return `${h}:${String(m).padStart(2, "0")}:${String(s % 60).padStart(2, "0")}`; }
function num(x, digits = 5) { return (x === null || x === undefined) ? "—" : Number(x).toPrecision(digits); }

async function loadProcedures() {
  const doc = await (await fetch("/api/procedures")).json();
  const select = $("procedure");
  select.innerHTML = "";
  for (const id of doc.procedures) { const o = document.createElement("option"); o.value = o.textContent = id; select.appendChild(o); }
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

function makePlots(sensors, axis) {
  for (const id of ["plot-table", "plot-daq"]) $(id).innerHTML = "";
  const width = Math.min(900, window.innerWidth - 60);
  const table = new uPlot({ title: `table (${axis} axis estimate)`, width, height: 180,
    scales: { x: { time: false } },
    series: [{ label: "t s" }, { label: "position °", stroke: "#1f3a5f", scale: "deg" },
             { label: "accel °/s²", stroke: "#d08b00", scale: "acc" }],
    axes: [{}, { scale: "deg" }, { scale: "acc", side: 1 }] }, [[], [], []], $("plot-table"));
  const colours = ["#2a7a2a", "#a11", "#5a2a9a", "#0a7f8f", "#8f5a0a"];
  const daq = new uPlot({ title: "sensor channels (V)", width, height: 180, scales: { x: { time: false } },
    series: [{ label: "t s" }, ...sensors.map((c, i) => ({ label: c, stroke: colours[i % colours.length] }))] },
    [[], ...sensors.map(() => [])], $("plot-daq"));
  state.plots = { table, daq, axis, sensors, tdata: [[], [], []], ddata: [[], ...sensors.map(() => [])] };
}

function addSamples(msg) {
  const p = state.plots; if (!p) return;
  const tk = [`${p.axis}_position_deg`, `${p.axis}_accel_dps2`];
  p.tdata[0].push(...msg.table.t); tk.forEach((k, i) => p.tdata[i + 1].push(...(msg.table[k] || [])));
  p.ddata[0].push(...msg.daq.t); p.sensors.forEach((c, i) => p.ddata[i + 1].push(...msg.daq[c]));
  p.table.setData(p.tdata); p.daq.setData(p.ddata);
  state.received += msg.daq.t.length;
  $("sample-count").textContent = String(state.received);
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

function showResult(msg) {
  $("result").hidden = false;
  const v = $("verdict"); v.className = "verdict " + (msg.overall || "none");
  v.textContent = "Verdict: " + (msg.overall || "none").toUpperCase();
  v.title = msg.judged_by === "certificate" ? "judged as on the calibration certificate" : "from results.json";
  const body = $("verdicts").querySelector("tbody"); body.innerHTML = "";
  for (const r of msg.verdicts || []) {
    // name, unit symbol and significant digits from the quantity registry (aatest.results.quantities)
    const tr = body.insertRow(); cell(tr, r.quantity); cell(tr, r.channel); cell(tr, `${num(r.value, r.digits)} ${r.unit}`);
    cell(tr, `${num(r.expanded_uncertainty, 2)} ${r.unit}`); cell(tr, `${num(r.limit, r.digits)} ${r.unit}`); cell(tr, r.verdict);
  }
  $("links").innerHTML = "";
  for (const f of ["report.html", "report.pdf", "results.json"]) {
    const a = document.createElement("a"); a.href = `/runs/${encodeURIComponent(msg.name)}/${f}`; a.textContent = f; a.target = "_blank";
    $("links").appendChild(a); $("links").appendChild(document.createTextNode(" "));
  }
  loadHistory();
}

function setRunState(text) { $("run-state").textContent = text; }

function onEvent(msg) {
  switch (msg.type) {
    case "role":
      document.body.classList.toggle("watching", msg.role !== "control");
      $("role").textContent = msg.role === "control" ? "you control the rig" : "watching (another page controls)";
      break;
    case "snapshot":
      if (msg.run && msg.run.name) { $("live").hidden = false; $("run-name").textContent = msg.run.name; setRunState(msg.run.state || ""); }
      state.steps = new Map(msg.steps.map((s) => [s.id, s])); renderSteps(); showPrompt(msg.prompt);
      break;
    case "run_dir":
      $("live").hidden = false; $("result").hidden = true; $("stopped").hidden = true;
      state.runName = msg.name; $("run-name").textContent = msg.name; setRunState("starting");
      state.startedMs = Date.now(); state.received = 0; $("sample-count").textContent = "0";
      break;
    case "run_started":
      state.steps = new Map(msg.steps.map((s) => [s.id, s])); renderSteps(); setRunState("running");
      break;
    case "step":
      if (state.steps.has(msg.id)) state.steps.get(msg.id).state = msg.state;
      if (msg.state === "running") { $("current").textContent = msg.id; $("motion").textContent = msg.motion; }
      renderSteps();
      break;
    case "plot_reset": makePlots(msg.sensors, msg.axis); $("plot-label").textContent = `Live plots of ${msg.id}: ${msg.label}.`; break;
    case "samples": addSamples(msg); break;
    case "prompt": showPrompt(msg); setRunState("waiting for the operator"); break;
    case "prompt_answered": showPrompt(null); setRunState("running"); break;
    case "analysing": setRunState("analysing"); break;
    case "stopped":
      if (msg.exit_code === undefined) break;  // the engine's notice; the final one carries the exit code
      setRunState("stopped"); showPrompt(null); state.startedMs = null;
      $("stopped").hidden = false; $("stopped-text").textContent = msg.reason;
      $("resume").hidden = !msg.resumable; loadHistory();
      break;
    case "finished": setRunState("finished"); state.startedMs = null; showResult(msg); break;
    case "error": alert(msg.message); break;
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
    cell(tr, label); cell(tr, r.procedure); cell(tr, r.finished ? "finished" : "stopped"); cell(tr, r.overall || "—");
    const files = cell(tr, "");
    for (const f of r.files) { const a = document.createElement("a"); a.href = `/runs/${encodeURIComponent(r.name)}/${f}`; a.textContent = f; a.target = "_blank"; files.appendChild(a); files.appendChild(document.createTextNode(" ")); }
    const act = cell(tr, "");
    if (!r.finished) { const b = document.createElement("button"); b.textContent = "Resume"; b.className = "control resume-run";
      b.onclick = () => send({ type: "resume", run: r.name }); act.appendChild(b); }
  }
}

function connect() {
  socket = new WebSocket(`${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws`);
  socket.onmessage = (e) => onEvent(JSON.parse(e.data));
  socket.onclose = () => { $("role").textContent = "disconnected"; setTimeout(connect, 1000); };
}

$("validate").onclick = validate;
$("upload").onchange = upload;
$("start").onclick = () => send({ type: "start", procedure: $("procedure").value });
$("abort").onclick = () => send({ type: "abort" });
$("continue").onclick = () => send({ type: "answer", step: $("continue").dataset.step });
$("resume").onclick = () => send({ type: "resume", run: state.runName || $("run-name").textContent });
$("refresh").onclick = loadHistory;
setInterval(() => { if (state.startedMs) $("elapsed").textContent = fmtTime((Date.now() - state.startedMs) / 1000); }, 500);
loadProcedures().then(validate); loadHistory(); connect();
