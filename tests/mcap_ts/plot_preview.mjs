// Decode an aatest recording's preview topics as a generic viewer would, and plot them.
//
// Usage: node plot_preview.mjs RECORDING.mcap OUT.json [OUT.html]
//
// Only @mcap/core (records, CRCs), fzstd (zstd chunks) and protobufjs (the FileDescriptorSet
// embedded in each schema) are used: no aatest code. Every message of a topic under
// `/preview/` is decoded into its named scalar fields; OUT.json holds, per topic, the message
// count, the log times (ns since 1970, as strings), the channel metadata and every field's
// values, for tests/engine/test_recording_preview.py to compare with the exact samples. With
// OUT.html, a page plotting every `_mean` field of each topic against the UTC log time with
// uPlot (its files inlined from node_modules) is written; Chromium takes its screenshot.
import { readFileSync, writeFileSync } from "node:fs";
import { createRequire } from "node:module";
import { McapStreamReader } from "@mcap/core";
import { decompress } from "fzstd";
import protobuf from "protobufjs";
import "protobufjs/ext/descriptor/index.js";

const [recordingPath, jsonPath, htmlPath] = process.argv.slice(2);
const reader = new McapStreamReader({
  validateCrcs: true,
  decompressHandlers: { zstd: (data) => decompress(data) },
});
reader.append(readFileSync(recordingPath));

const schemas = new Map();
const channels = new Map();
const topics = {};
let record;
while ((record = reader.nextRecord())) {
  if (record.type === "Schema") {
    const set = protobuf.descriptor.FileDescriptorSet.decode(record.data);
    schemas.set(record.id, protobuf.Root.fromDescriptor(set).lookupType(record.name));
  } else if (record.type === "Channel") {
    channels.set(record.id, record);
  } else if (record.type === "Message") {
    const channel = channels.get(record.channelId);
    if (!channel.topic.startsWith("/preview/")) continue;
    const type = schemas.get(channel.schemaId);
    const message = type.toObject(type.decode(record.data), { defaults: true });
    const topic = (topics[channel.topic] ??= {
      metadata: Object.fromEntries(channel.metadata), log_time_ns: [], fields: {},
    });
    topic.log_time_ns.push(record.logTime.toString());
    for (const [name, value] of Object.entries(message)) (topic.fields[name] ??= []).push(value);
  }
}
if (!reader.done()) throw new Error("recording ends before its footer");
writeFileSync(jsonPath, JSON.stringify(topics));

if (htmlPath) {
  const require = createRequire(import.meta.url);
  const uplotJs = readFileSync(require.resolve("uplot/dist/uPlot.iife.min.js"), "utf8");
  const uplotCss = readFileSync(require.resolve("uplot/dist/uPlot.min.css"), "utf8");
  const plots = Object.entries(topics).map(([name, topic]) => {
    const x = topic.log_time_ns.map((t) => Number(BigInt(t) / 1000000n) / 1000);
    const means = Object.keys(topic.fields).filter((f) => f.endsWith("_mean"));
    const units = JSON.parse(topic.metadata.units);
    return { name, data: [x, ...means.map((f) => topic.fields[f])],
             series: means.map((f) => `${f} [${units[f]}]`) };
  });
  writeFileSync(htmlPath, `<!doctype html><html><head><meta charset="utf-8">
<style>${uplotCss} body{font:13px sans-serif;margin:8px;background:#fff}</style>
<script>${uplotJs}</script></head><body><div id="plots"></div><script>
const plots = ${JSON.stringify(plots)};
const colours = ["#1f77b4","#d62728","#2ca02c","#9467bd","#ff7f0e","#8c564b","#17becf"];
for (const p of plots) {
  const opts = { title: p.name + " (UTC)", width: 1100, height: 330, tzDate: (ts) => uPlot.tzDate(new Date(ts * 1e3), "Etc/UTC"),
    series: [{}, ...p.series.map((label, i) => ({ label, stroke: colours[i % colours.length] }))] };
  new uPlot(opts, p.data, document.getElementById("plots"));
}
document.title = "rendered";
</script></body></html>`);
}
const counts = Object.entries(topics).map(([t, v]) => `${t}: ${v.log_time_ns.length}`);
console.log(`ok: ${counts.join(", ")}`);
