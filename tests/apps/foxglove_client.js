// A Foxglove WebSocket client made by Foxglove (@foxglove/ws-protocol, with
// the `ws` WebSocket), as Foxglove Studio connects: subscribes to TOPIC on
// ws://127.0.0.1:PORT and prints, as one JSON line, the channel it was
// advertised as and the messages that came (their stamps and pose counts),
// once COUNT have come or the server closed. With JUNK=1 in the environment
// it first sends what no client should (not JSON, unknown channels, binary
// frames): the server must go on serving it. With GROWING=1, a path that
// holds as many poses as the last one kept is not counted: COUNT paths then
// show COUNT - 1 new keyframes, however fast the server sends.
// Usage: node foxglove_client.js MODULES_DIR PORT TOPIC COUNT
const path = require("path");
const [modules, port, topic, count] = process.argv.slice(2);
const { FoxgloveClient } = require(path.join(modules, "@foxglove/ws-protocol"));
const WebSocket = require(path.join(modules, "ws"));

const ws = new WebSocket(`ws://127.0.0.1:${port}`, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
const client = new FoxgloveClient({ ws });
const out = { serverInfo: null, channel: null, messages: [] };
let done = false;
function finish(code) {
  if (done) return;
  done = true;
  console.log(JSON.stringify(out));
  client.close();
  process.exit(code);
}
client.on("serverInfo", (info) => {
  out.serverInfo = info.name;
  if (process.env.JUNK === "1") {
    for (const junk of ["not json", "[]", '{"op":7}', '{"op":"subscribe"}',
                        '{"op":"subscribe","subscriptions":[{"id":1,"channelId":99999}]}',
                        '{"op":"subscribe","subscriptions":[{"id":-1,"channelId":1}]}',
                        '{"op":"unsubscribe","subscriptionIds":["x"]}', "x".repeat(100000)]) {
      ws.send(junk);
    }
    ws.send(new Uint8Array([1, 2, 3, 255]));
  }
});
client.on("advertise", (channels) => {
  const channel = channels.find((c) => c.topic === topic);
  if (!channel || out.channel) return;
  out.channel = { topic: channel.topic, encoding: channel.encoding, schemaName: channel.schemaName,
                  schemaIsJson: (() => { try { JSON.parse(channel.schema); return true; } catch { return false; } })() };
  client.subscribe(channel.id);
});
client.on("message", (event) => {
  const text = new TextDecoder().decode(
    new Uint8Array(event.data.buffer, event.data.byteOffset, event.data.byteLength));
  const message = JSON.parse(text);
  const summary = { stamp: Number(event.timestamp), frame_id: message.frame_id };
  if (message.poses) {  // foxglove.PosesInFrame
    const last = out.messages[out.messages.length - 1];
    if (process.env.GROWING === "1" && last && last.poses === message.poses.length) return;
    summary.poses = message.poses.length;
    summary.last = message.poses.length ? message.poses[message.poses.length - 1].position : null;
  }
  if (message.data !== undefined) {  // foxglove.PointCloud: whole points in its data
    const bytes = Buffer.from(message.data, "base64").length;
    summary.points = bytes / message.point_stride;
    summary.fields = message.fields.map((f) => `${f.name}:${f.offset}:${f.type}`).join(",");
  }
  if (message.entities) {  // foxglove.SceneUpdate
    const lines = message.entities[0].lines[0];
    summary.frame_id = message.entities[0].frame_id;
    summary.line_type = lines.type;
    summary.line_points = lines.points.length;
  }
  out.messages.push(summary);
  if (out.messages.length >= Number(count)) finish(0);
});
client.on("error", (e) => { out.error = String(e && e.message ? e.message : e); });
client.on("close", () => finish(out.messages.length > 0 ? 0 : 1));
setTimeout(() => finish(1), 120000);
