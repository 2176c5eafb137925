// Cross-check of dcl-slam's ROS 2 wire format against Foxglove's independent
// implementation (@foxglove/rosmsg2-serialization, the one Foxglove uses to
// read ROS 2 bags), with the ROS 2 Humble definitions of
// @foxglove/rosmsg-msgs-common.
//
// Usage: node ros2_crosscheck.js NODE_MODULES DIR
// DIR holds pairs NAME.cdr (our bytes) and NAME.json ({"type": "pkg/Type",
// "message": {...}}, the values we encoded). For each pair, Foxglove's reader
// must read our bytes to exactly those values, and its writer writes the
// values to NAME.foxglove.cdr for our decoder to read. Exits 1 on the first
// difference, naming the file and the field.
"use strict";
const fs = require("fs");
const path = require("path");

const [modules, dir] = process.argv.slice(2);
if (!modules || !dir) {
  console.error("usage: node ros2_crosscheck.js NODE_MODULES DIR");
  process.exit(2);
}
const load = (name) => require(path.join(path.resolve(modules), name));
const { MessageReader, MessageWriter } = load("@foxglove/rosmsg2-serialization");
const { ros2humble } = load("@foxglove/rosmsg-msgs-common");

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

/** Throws naming `where` when `actual` (Foxglove's) differs from `expected` (ours). */
function compare(actual, expected, where) {
  if (ArrayBuffer.isView(actual)) actual = Array.from(actual);
  if (Array.isArray(expected)) {
    if (!Array.isArray(actual) || actual.length !== expected.length) {
      throw new Error(`${where}: ${actual?.length} elements, we wrote ${expected.length}`);
    }
    expected.forEach((e, i) => compare(actual[i], e, `${where}[${i}]`));
    return;
  }
  if (expected !== null && typeof expected === "object") {
    for (const key of Object.keys(expected)) compare(actual?.[key], expected[key], `${where}.${key}`);
    return;
  }
  // Float32 fields come back as the float32 nearest to what we meant.
  if (actual === expected || (typeof expected === "number" && actual === Math.fround(expected))) {
    return;
  }
  throw new Error(`${where}: Foxglove reads ${JSON.stringify(actual)}, we wrote ${JSON.stringify(expected)}`);
}

let checked = 0;
for (const file of fs.readdirSync(dir).sort()) {
  if (!file.endsWith(".json")) continue;
  const name = file.slice(0, -".json".length);
  const { type, message } = JSON.parse(fs.readFileSync(path.join(dir, file), "utf8"));
  const defs = definitions(type);
  const ours = fs.readFileSync(path.join(dir, `${name}.cdr`));
  try {
    const reader = new MessageReader(defs);
    const read = reader.readMessage(ours);
    if (reader.lastReadHadTrailingBytes()) throw new Error(`${type}: bytes left after the message`);
    compare(read, message, type);
  } catch (e) {
    console.error(`${name}.cdr: ${e.message}`);
    process.exit(1);
  }
  const theirs = new MessageWriter(defs).writeMessage(message);
  fs.writeFileSync(path.join(dir, `${name}.foxglove.cdr`), theirs);
  console.log(`${name}: ${type}, ${ours.length} bytes read alike; ${theirs.length} bytes written`);
  ++checked;
}
if (checked === 0) {
  console.error(`no NAME.json in ${dir}`);
  process.exit(1);
}
