// Decode every message of an MCAP file with Foxglove's own readers, the way Foxglove opens a bag:
// @mcap/core's McapIndexedReader (summary, chunk indexes; it checks the summary CRC and each chunk's
// CRC), chunks decompressed with @foxglove/wasm-zstd, each channel's ros2msg schema parsed with
// @foxglove/rosmsg and its CDR messages read with @foxglove/rosmsg2-serialization's MessageReader.
// A second pass reads the whole file with McapStreamReader (chunk CRCs again, record by record).
//
// Usage: node decode_bag.mjs FILE.mcap  ->  one JSON object on stdout:
//   {messages, decoded, counts: {topic: n}, failures: [..], start_ns, end_ns, first_log_ns, last_log_ns,
//    chunks, chunks_with_crc, metadata: {name: {key: value}}, clock: {first_sec, last_sec, matches_log_time},
//    stream_messages}
// Run by tests/system/test_foxglove_decode.py (which installs the packages from package-lock.json).
import { open } from "node:fs/promises";
import { McapIndexedReader, McapStreamReader } from "@mcap/core";
import { parse } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";
import zstd from "@foxglove/wasm-zstd";

const path = process.argv[2];
await zstd.isLoaded;
const decompressHandlers = { zstd: (buffer, decompressedSize) => zstd.decompress(buffer, Number(decompressedSize)) };

const fh = await open(path, "r");
const size = BigInt((await fh.stat()).size);
const readable = {
  size: async () => size,
  read: async (offset, length) => {
    const buf = new Uint8Array(Number(length));
    await fh.read(buf, 0, Number(length), Number(offset));
    return buf;
  },
};
const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers });

const readers = new Map();
for (const [id, channel] of reader.channelsById) {
  const schema = reader.schemasById.get(channel.schemaId);
  if (channel.messageEncoding !== "cdr" || schema?.encoding !== "ros2msg") {
    throw new Error(`channel ${channel.topic}: ${channel.messageEncoding}/${schema?.encoding}, not cdr/ros2msg`);
  }
  const defs = parse(new TextDecoder().decode(schema.data), { ros2: true });
  readers.set(id, new MessageReader(defs));
}

const counts = {};
const failures = [];
let messages = 0;
let decoded = 0;
let firstLog = null;
let lastLog = null;
const clock = { first_sec: null, last_sec: null, matches_log_time: true };
for await (const msg of reader.readMessages()) {
  messages++;
  const topic = reader.channelsById.get(msg.channelId).topic;
  counts[topic] = (counts[topic] ?? 0) + 1;
  if (firstLog === null) firstLog = msg.logTime;
  lastLog = msg.logTime;
  try {
    const value = readers.get(msg.channelId).readMessage(msg.data);
    decoded++;
    if (topic === "/clock") {
      const ns = BigInt(value.clock.sec) * 1000000000n + BigInt(value.clock.nanosec);
      if (ns !== msg.logTime) clock.matches_log_time = false;
      if (clock.first_sec === null) clock.first_sec = value.clock.sec;
      clock.last_sec = value.clock.sec;
    }
  } catch (err) {
    if (failures.length < 10) failures.push(`${topic} at ${msg.logTime}: ${err}`);
  }
}

const metadata = {};
for await (const m of reader.readMetadata()) {
  metadata[m.name] = Object.fromEntries(m.metadata);
}

const chunks = reader.chunkIndexes.length;
let chunksWithCrc = 0;
for (const idx of reader.chunkIndexes) {
  const head = await readable.read(idx.chunkStartOffset + 9n + 24n, 4n);
  if (new DataView(head.buffer).getUint32(0, true) !== 0) chunksWithCrc++;
}

// the whole file once more, as a stream (every record, chunk CRCs checked)
const stream = new McapStreamReader({ decompressHandlers, validateCrcs: true });
const bytes = new Uint8Array(Number(size));
await fh.read(bytes, 0, bytes.length, 0);
await fh.close();
stream.append(bytes);
let streamMessages = 0;
for (let rec; (rec = stream.nextRecord()); ) {
  if (rec.type === "Message") streamMessages++;
}
if (!stream.done()) throw new Error("stream reader did not reach the end of the file");

console.log(JSON.stringify({
  messages,
  decoded,
  counts,
  failures,
  start_ns: String(reader.statistics?.messageStartTime),
  end_ns: String(reader.statistics?.messageEndTime),
  first_log_ns: String(firstLog),
  last_log_ns: String(lastLog),
  chunks,
  chunks_with_crc: chunksWithCrc,
  metadata,
  clock,
  stream_messages: streamMessages,
}));
