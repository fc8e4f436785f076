// aatest station, the unit page: the history of one serial from the records store, and the
// trend of its key quantity (value with its expanded uncertainty band).
"use strict";
const $ = (id) => document.getElementById(id);
const serial = decodeURIComponent(location.pathname.replace(/^\/units\//, ""));

function cell(row, text) { const td = document.createElement("td"); td.textContent = text ?? "—"; row.appendChild(td); return td; }

function drawTrend(trend) {
  if (!trend || !trend.t_s.length) { $("trend").textContent = "no quantity recorded yet"; return; }
  $("trend-name").textContent = `— ${trend.name} ${trend.channel} (${trend.unit})`;
  const lo = trend.value.map((v, i) => trend.u[i] === null ? null : v - trend.u[i]);
  const hi = trend.value.map((v, i) => trend.u[i] === null ? null : v + trend.u[i]);
  const pad = 86400;  // a day either side, so a single calibration is inside the axis
  new uPlot({ width: Math.min(900, window.innerWidth - 60), height: 240,
    scales: { x: { time: true, range: (u, min, max) => [min - pad, max + pad] } },
    series: [{ label: "calibrated" },
             { label: `${trend.name} (${trend.unit})`, stroke: "#1f3a5f", points: { show: true, size: 8 } },
             { label: "value − U", stroke: "#999", dash: [4, 4] },
             { label: "value + U", stroke: "#999", dash: [4, 4] }] },
    [trend.t_s, trend.value, lo, hi], $("trend"));
}

async function load() {
  $("serial").textContent = serial;
  document.title = `aatest station · unit ${serial}`;
  const response = await fetch("/api/units/" + encodeURIComponent(serial));
  const doc = await response.json();
  if (!response.ok) { $("source").textContent = (doc.problems || []).join("; "); return; }
  $("source").textContent = `${doc.records.length} record(s) in ${doc.store}`;
  const body = $("records").querySelector("tbody");
  for (const r of doc.records) {
    const tr = body.insertRow(); tr.dataset.run = r.run || "";
    cell(tr, r.certificate_number); cell(tr, r.calibrated_utc.replace("+00:00", "Z"));
    cell(tr, r.procedure); cell(tr, r.model);
    cell(tr, r.kind).className = "kind-" + r.kind; cell(tr, r.overall);
    cell(tr, r.quantities.map((q) => `${q.name} ${q.channel}: ${q.text}`).join("; "));
    const files = cell(tr, "");
    for (const f of r.files) { const a = document.createElement("a"); a.href = `/runs/${encodeURIComponent(r.run)}/${f}`; a.textContent = f; files.appendChild(a); files.appendChild(document.createTextNode(" ")); }
  }
  drawTrend(doc.trend);
}
load();
