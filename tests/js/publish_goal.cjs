// Publishes one goal pose through `rover live-view` as the Foxglove app does: the official
// @foxglove/ws-protocol client advertises a goal_pose channel in JSON and sends one message.
// Usage: node publish_goal.cjs ws://HOST:PORT X Y  (exit 0 once sent)
const { FoxgloveClient } = require("@foxglove/ws-protocol");
const WebSocket = require("ws");

const [url, x, y] = process.argv.slice(2);
// The foxglove crate's server speaks version 1 of the protocol under the SDK's subprotocol name.
const client = new FoxgloveClient({ ws: new WebSocket(url, ["foxglove.sdk.v1"]) });
const fail = (why, code) => {
  console.error(why);
  process.exit(code);
};
setTimeout(() => fail("timed out before the goal was sent", 2), 20000);
client.on("error", (error) => fail(`error: ${error}`, 1));
client.on("serverInfo", (info) => {
  if (!info.capabilities.includes("clientPublish") || !(info.supportedEncodings ?? []).includes("json")) {
    fail(`the server does not take JSON from clients: ${JSON.stringify(info)}`, 3);
  }
  const channel = client.advertise({
    topic: "/goal_pose",
    encoding: "json",
    schemaName: "geometry_msgs/msg/PoseStamped",
  });
  const goal = {
    header: { stamp: { sec: 0, nsec: 0 }, frame_id: "map" },
    pose: { position: { x: Number(x), y: Number(y), z: 0 }, orientation: { x: 0, y: 0, z: 0, w: 1 } },
  };
  client.sendMessage(channel, new TextEncoder().encode(JSON.stringify(goal)));
  setTimeout(() => {
    console.log(`published a goal pose at (${x}, ${y})`);
    process.exit(0);
  }, 500);
});
