// Read an aatest recording with the official TypeScript MCAP reader, as a viewer would.
//
// Usage: node read_recording.mjs RECORDING.mcap SUMMARY.json
//
// Every record is read with @mcap/core's stream reader, which validates the CRC of every
// chunk and of the data section; chunks are zstd (fzstd). The protobuf schema embedded in
// the file (a FileDescriptorSet) is loaded with protobufjs and every message decoded with it.
// The per-topic message counts, per-step sample counts and the first and last physical value
// of every channel (code * quantum + offset in float64, codes summed when stored as
// differences; v3 codes are packed fixed-width integers, v2 varints — as the format says) must equal the
// JSON summary written by Python (tests/engine/test_recording.py). Exit 0 when they do, else
// 1 with the first difference on stderr.
import { readFileSync } from "node:fs";
import { McapStreamReader } from "@mcap/core";
import { decompress } from "fzstd";
import protobuf from "protobufjs";
import "protobufjs/ext/descriptor/index.js";

const [recordingPath, summaryPath] = process.argv.slice(2);
const expected = JSON.parse(readFileSync(summaryPath, "utf8"));

const reader = new McapStreamReader({
  validateCrcs: true,
  decompressHandlers: {
    zstd: (data, size) => {
      const out = decompress(data);
      if (BigInt(out.length) !== size) throw new Error(`zstd chunk: ${out.length} != ${size}`);
      return out;
    },
  },
});
reader.append(readFileSync(recordingPath));

const schemas = new Map();
const channels = new Map();
const got = { messages: {}, steps: {} };

// The integer codes of a channel: v3 `packed` little-endian integers of `width` bytes (as byte
// planes when `shuffled`), or v2 varint `codes`.
function codesOf(channel) {
  const packed = channel.packed;
  if (!packed || packed.length === 0) return channel.codes.map(Number);
  const width = channel.width;
  const n = packed.length / width;
  let bytes = packed;
  if (channel.shuffled) {
    bytes = new Uint8Array(packed.length);
    for (let plane = 0; plane < width; plane++) {
      for (let i = 0; i < n; i++) bytes[i * width + plane] = packed[plane * n + i];
    }
  }
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const read = {
    1: (i) => view.getInt8(i),
    2: (i) => view.getInt16(i * 2, true),
    4: (i) => view.getInt32(i * 4, true),
    8: (i) => Number(view.getBigInt64(i * 8, true)),
  }[width];
  if (!read) throw new Error(`channel ${channel.name}: packed width ${width}`);
  return Array.from({ length: n }, (_, i) => read(i));
}

function physical(channel) {
  const codes = codesOf(channel);
  if (codes.length > 0) {
    let code = 0;
    return codes.map((stored) => {
      code = channel.delta ? code + stored : stored;
      return code * channel.quantum + channel.offset;
    });
  }
  return channel.values;
}

function onMessage(record) {
  const channel = channels.get(record.channelId);
  if (channel.topic.startsWith("/preview/")) return; // plotted views: plot_preview.mjs
  const type = schemas.get(channel.schemaId);
  const block = type.toObject(type.decode(record.data), { longs: Number, defaults: true, arrays: true });
  got.messages[channel.topic] = (got.messages[channel.topic] ?? 0) + 1;
  const step = (got.steps[`${block.step_id}${channel.topic}`] ??= { samples: 0, first: {}, last: {} });
  step.samples += block.time.values.length + codesOf(block.time).length;
  for (const ch of [block.time, ...block.channels]) {
    const values = physical(ch);
    if (values.length === 0) continue;
    if (!(ch.name in step.first)) step.first[ch.name] = values[0];
    step.last[ch.name] = values[values.length - 1];
  }
}

let record;
while ((record = reader.nextRecord())) {
  if (record.type === "Schema") {
    if (record.encoding !== "protobuf") throw new Error(`schema encoding ${record.encoding}`);
    const set = protobuf.descriptor.FileDescriptorSet.decode(record.data);
    schemas.set(record.id, protobuf.Root.fromDescriptor(set).lookupType(record.name));
  } else if (record.type === "Channel") {
    channels.set(record.id, record);
  } else if (record.type === "Message") {
    onMessage(record);
  }
}
if (!reader.done()) throw new Error("recording ends before its footer");

function differences(want, have, path) {
  if (typeof want !== "object" || want === null) {
    return want === have ? [] : [`${path}: expected ${want}, got ${have}`];
  }
  if (typeof have !== "object" || have === null) return [`${path}: expected an object, got ${have}`];
  const keys = new Set([...Object.keys(want), ...Object.keys(have)]);
  return [...keys].flatMap((k) => differences(want[k], have[k], `${path}.${k}`));
}

const found = differences(expected, got, "summary");
if (found.length) {
  console.error(found.slice(0, 10).join("\n"));
  process.exit(1);
}
const total = Object.values(got.messages).reduce((sum, n) => sum + n, 0);
console.log(`ok: ${total} messages, ${Object.keys(got.steps).length} step logs, CRCs valid`);
