// An independent reader of mimunav's logs: Foxglove's own MCAP and ROS 2 stack (@mcap/core,
// @foxglove/rosmsg, @foxglove/rosmsg2-serialization, fzstd), the code Foxglove Studio reads
// MCAP with. Used by tests/test_mcap_independent.py as an oracle; it shares no code with
// mimunav.
//
//   node read_mcap.js LOG.mcap  ->  JSON lines on stdout: first
//   {stream: {records: {record type: count}, done},           every record, CRCs checked
//    statistics, channels: [{topic, schema, encoding}], metadata: {name: {key: value}},
//    attachments: [{name, media_type, size}]}                  through the summary's indexes
//   then a line per message, in log-time order: {topic, log_time, publish_time, sequence,
//   message}. uint64/int64 as decimal strings, typed arrays as arrays, float64 as JSON
//   numbers (shortest round trip: the same double in Python).
"use strict";
const fs = require("fs");
const { McapIndexedReader, McapStreamReader } = require("@mcap/core");
const { parse } = require("@foxglove/rosmsg");
const { MessageReader } = require("@foxglove/rosmsg2-serialization");
const fzstd = require("fzstd");

const decompressHandlers = {
  zstd: (data, size) => fzstd.decompress(data, new Uint8Array(Number(size))),
};

function plain(value) {
  if (typeof value === "bigint") return value.toString();
  if (ArrayBuffer.isView(value)) return Array.from(value, plain);
  if (Array.isArray(value)) return value.map(plain);
  if (value && typeof value === "object") {
    const out = {};
    for (const [k, v] of Object.entries(value)) out[k] = plain(v);
    return out;
  }
  return value;
}

async function main(path) {
  const bytes = fs.readFileSync(path);
  const stream = new McapStreamReader({ decompressHandlers, validateCrcs: true });
  stream.append(bytes);
  const records = {};
  for (let r; (r = stream.nextRecord()); ) records[r.type] = (records[r.type] || 0) + 1;

  const readable = {
    size: async () => BigInt(bytes.length),
    read: async (offset, size) => bytes.subarray(Number(offset), Number(offset + size)),
  };
  const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers });
  const decoders = new Map();
  const channels = [];
  for (const [id, ch] of reader.channelsById) {
    const schema = reader.schemasById.get(ch.schemaId);
    if (schema.encoding !== "ros2msg" || ch.messageEncoding !== "cdr") {
      throw new Error(`channel ${ch.topic}: ${schema.encoding}/${ch.messageEncoding}`);
    }
    decoders.set(id, new MessageReader(parse(new TextDecoder().decode(schema.data),
                                             { ros2: true })));
    channels.push({ topic: ch.topic, schema: schema.name, encoding: ch.messageEncoding });
  }
  const metadata = {};
  for await (const md of reader.readMetadata()) metadata[md.name] = Object.fromEntries(md.metadata);
  const attachments = [];
  for await (const a of reader.readAttachments({ validateCrcs: true })) {
    attachments.push({ name: a.name, media_type: a.mediaType, size: a.data.length });
  }
  const st = reader.statistics;
  const out = fs.openSync("/dev/stdout", "w");
  fs.writeSync(out, JSON.stringify({
    stream: { records, done: stream.done() },
    statistics: st && plain({ message_count: st.messageCount, channel_count: st.channelCount,
                              chunk_count: st.chunkCount, message_start_time: st.messageStartTime,
                              message_end_time: st.messageEndTime,
                              channel_message_counts: Object.fromEntries(
                                [...st.channelMessageCounts].map(([k, v]) =>
                                  [reader.channelsById.get(k).topic, v])) }),
    channels, metadata, attachments,
  }) + "\n");
  let lines = [];
  for await (const m of reader.readMessages({ validateCrcs: true })) {
    lines.push(JSON.stringify({
      topic: reader.channelsById.get(m.channelId).topic, log_time: m.logTime.toString(),
      publish_time: m.publishTime.toString(), sequence: m.sequence,
      message: plain(decoders.get(m.channelId).readMessage(m.data)),
    }));
    if (lines.length === 10000) {
      fs.writeSync(out, lines.join("\n") + "\n");
      lines = [];
    }
  }
  if (lines.length) fs.writeSync(out, lines.join("\n") + "\n");
}

main(process.argv[2]).catch((err) => {
  process.stderr.write(`${err.stack || err}\n`);
  process.exit(1);
});
