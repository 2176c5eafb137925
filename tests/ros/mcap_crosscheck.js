// Cross-check of dcl-slam's ROS 2 bags (MCAP) against Foxglove's independent
// implementation: @mcap/core reads and writes the container, @foxglove/rosmsg
// parses the schemas' message definitions, @foxglove/rosmsg2-serialization
// reads and writes the CDR messages. @mcap/core brings no compressor, so
// chunks are (de)compressed by Debian's reference zstd and lz4 tools.
//
// Usage:
//   node mcap_crosscheck.js NODE_MODULES read FILE.mcap
//     reads FILE with the indexed reader and with the stream reader, decodes
//     every message by its channel's schema and prints
//     {"indexed": [...], "stream": [...]}, each message as
//     {"topic", "schema", "encoding", "log_time", "publish_time", "message"}.
//   node mcap_crosscheck.js NODE_MODULES write SPEC.json OUT.mcap
//     writes OUT from SPEC: {"compression": "" | "zstd" | "lz4", "chunked": bool,
//     "messages": [{"topic", "type" ("pkg/Type"), "log_time" (ns, a string),
//     "message"}]}, each type's schema the ROS 2 Humble definitions of
//     @foxglove/rosmsg-msgs-common as @foxglove/rosmsg prints them.
"use strict";
const fs = require("fs");
const path = require("path");
const { execFileSync } = require("child_process");

const [modules, mode, ...args] = process.argv.slice(2);
if (!modules || !["read", "write"].includes(mode)) {
  console.error("usage: node mcap_crosscheck.js NODE_MODULES read FILE | write SPEC OUT");
  process.exit(2);
}
const load = (name) => require(path.join(path.resolve(modules), name));
const { McapIndexedReader, McapStreamReader, McapWriter } = load("@mcap/core");
const { parse, stringify } = load("@foxglove/rosmsg");
const { MessageReader, MessageWriter } = load("@foxglove/rosmsg2-serialization");
const { ros2humble } = load("@foxglove/rosmsg-msgs-common");

const tool = (name, flags) => (data) => execFileSync(name, flags, { input: data, maxBuffer: 1 << 30 });
const decompressHandlers = {
  zstd: (data, size) => checkSize(tool("zstd", ["-d", "-c", "-q"])(data), size),
  lz4: (data, size) => checkSize(tool("lz4", ["-d", "-c", "-q"])(data), size),
};
const compressors = { zstd: tool("zstd", ["-c", "-q"]), lz4: tool("lz4", ["-c", "-q"]) };

function checkSize(bytes, size) {
  if (BigInt(bytes.length) !== size) throw new Error(`chunk: ${bytes.length} bytes, it says ${size}`);
  return bytes;
}

/** JSON of decoded values: typed arrays as arrays, 64-bit integers as strings. */
function plain(value) {
  if (typeof value === "bigint") return value.toString();
  if (ArrayBuffer.isView(value)) return Array.from(value);
  if (Array.isArray(value)) return value.map(plain);
  if (value !== null && typeof value === "object") {
    return Object.fromEntries(Object.entries(value).map(([k, v]) => [k, plain(v)]));
  }
  return value;
}

/** Decodes each message by its channel's schema, with one reader per schema. */
function decoder(schemasById, channelsById) {
  const readers = new Map();
  return (message) => {
    const channel = channelsById.get(message.channelId);
    const schema = schemasById.get(channel.schemaId);
    if (channel.messageEncoding !== "cdr" || schema.encoding !== "ros2msg") {
      throw new Error(`${channel.topic}: ${channel.messageEncoding} / ${schema.encoding}`);
    }
    if (!readers.has(schema.id)) {
      const text = new TextDecoder().decode(schema.data);
      readers.set(schema.id, new MessageReader(parse(text, { ros2: true })));
    }
    const reader = readers.get(schema.id);
    const value = reader.readMessage(message.data);
    if (reader.lastReadHadTrailingBytes()) throw new Error(`${channel.topic}: trailing bytes`);
    return {
      topic: channel.topic,
      schema: schema.name,
      encoding: channel.messageEncoding,
      log_time: message.logTime.toString(),
      publish_time: message.publishTime.toString(),
      message: plain(value),
    };
  };
}

async function readIndexed(bytes) {
  const readable = {
    size: async () => BigInt(bytes.length),
    read: async (offset, size) => bytes.subarray(Number(offset), Number(offset + size)),
  };
  const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers });
  const decode = decoder(reader.schemasById, reader.channelsById);
  const out = [];
  for await (const message of reader.readMessages({ validateCrcs: true })) out.push(decode(message));
  return out;
}

function readStream(bytes) {
  const stream = new McapStreamReader({ decompressHandlers, validateCrcs: true });
  stream.append(bytes);
  const schemas = new Map();
  const channels = new Map();
  const decode = decoder(schemas, channels);
  const out = [];
  for (let record; (record = stream.nextRecord()); ) {
    if (record.type === "Schema") schemas.set(record.id, record);
    if (record.type === "Channel") channels.set(record.id, record);
    if (record.type === "Message") out.push(decode(record));
  }
  if (!stream.done()) throw new Error("the stream reader did not reach the end of the file");
  return out;
}

/** The definition of `type` first, then those of every type it uses. */
function definitions(type) {
  const out = [];
  const seen = new Set();
  const visit = (name) => {
    if (seen.has(name)) return;
    seen.add(name);
    const def = ros2humble[name];
    if (!def) throw new Error(`no ROS 2 Humble definition of ${name}`);
    out.push(def);
    for (const field of def.definitions) {
      if (field.isComplex && !field.isConstant) visit(field.type);
    }
  };
  visit(type);
  return out;
}

async function write(spec, file) {
  const chunks = [];
  let position = 0n;
  const writable = {
    position: () => position,
    write: async (buffer) => {
      chunks.push(Buffer.from(buffer));
      position += BigInt(buffer.byteLength);
    },
  };
  const compress = compressors[spec.compression];
  const writer = new McapWriter({
    writable,
    useChunks: spec.chunked,
    chunkSize: 16 * 1024,
    compressChunk: compress
      ? (data) => ({ compression: spec.compression, compressedData: compress(data) })
      : undefined,
  });
  await writer.start({ profile: "ros2", library: "mcap_crosscheck.js" });
  const channels = new Map();
  const writers = new Map();
  for (const m of spec.messages) {
    if (!channels.has(m.topic)) {
      const defs = definitions(m.type);
      const schemaId = await writer.registerSchema({
        name: m.type.replace("/", "/msg/"),
        encoding: "ros2msg",
        data: new TextEncoder().encode(stringify(defs)),
      });
      channels.set(m.topic, await writer.registerChannel({
        topic: m.topic, schemaId, messageEncoding: "cdr", metadata: new Map(),
      }));
      writers.set(m.topic, new MessageWriter(defs));
    }
    const time = BigInt(m.log_time);
    await writer.addMessage({
      channelId: channels.get(m.topic),
      sequence: 0,
      logTime: time,
      publishTime: time,
      data: writers.get(m.topic).writeMessage(m.message),
    });
  }
  await writer.end();
  fs.writeFileSync(file, Buffer.concat(chunks));
}

async function main() {
  if (mode === "read") {
    const bytes = new Uint8Array(fs.readFileSync(args[0]));
    const result = { indexed: await readIndexed(bytes), stream: readStream(bytes) };
    process.stdout.write(JSON.stringify(result));
  } else {
    await write(JSON.parse(fs.readFileSync(args[0], "utf8")), args[1]);
  }
}

main().catch((e) => {
  console.error(`mcap_crosscheck.js ${mode}: ${e.stack ?? e}`);
  process.exit(1);
});
