import { test } from "node:test";
import assert from "node:assert/strict";
import { BridgeClient, BridgeError, bridgeUrl, connect, getBridge, nearestTarget } from "../src/index.js";
import { fakeBridge } from "../../../test-support/fake-bridge.mjs";

test("hello answers every handshake ping with the page clock and keeps the welcome", async () => {
  const { WebSocket, state } = fakeBridge({ pings: 5 });
  let t = 100;
  const client = await connect({ url: "ws://x/ws?token=T", participant: "P01", WebSocket, now: () => (t += 1) });
  const pongs = state.sent.filter((m) => m.type === "pong");
  assert.equal(pongs.length, 5);
  assert.deepEqual(pongs.map((p) => p.seq), [0, 1, 2, 3, 4]);
  assert.ok(pongs.every((p) => typeof p.t_page_ms === "number" && p.t_page_ms > 100));
  const hello = state.sent.find((m) => m.type === "hello");
  assert.equal(hello.participant, "P01");
  assert.equal(typeof hello.id, "number");
  assert.equal(client.welcome.session_id, 7);
  assert.equal(client.clock.offset_ms, 2.5);
  assert.equal(client.schedule.length, 2);
  assert.equal(getBridge(), client); // the shared connection the plugins use
});

test("a play resolves with the onset, the play id and the page times of request and reply", async () => {
  const { WebSocket, state } = fakeBridge();
  const client = await connect({ url: "ws://x/ws", participant: "P01", WebSocket });
  const played = await client.play({ index: 1 });
  const req = state.sent.find((m) => m.type === "play");
  assert.deepEqual({ ...req, id: 0 }, { type: "play", index: 1, id: 0 });
  assert.equal(played.id, req.id);
  assert.equal(played.onset_ms, 1000);
  assert.ok(played.reply_ms >= played.request_ms);
  assert.equal(client.lastPlay, played);
});

test("an error reply rejects that request only; the connection stays usable", async () => {
  const { WebSocket, state } = fakeBridge();
  const client = await connect({ url: "ws://x/ws", participant: "P01", WebSocket });
  state.errorOn.add("trial");
  await assert.rejects(client.trial(0, { target: 1 }), (e) => e instanceof BridgeError && /refused trial/.test(e.message));
  state.errorOn.clear();
  const stored = await client.trial(0, { target: 1 }, 3);
  assert.equal(stored.type, "stored");
  assert.equal(state.trials[0].play_id, 3);
});

test("a refused connection (1008) rejects open with the close code", async () => {
  const { WebSocket } = fakeBridge({ refuse: { code: 1008, reason: "bad token" } });
  const client = new BridgeClient({ url: "ws://x/ws", WebSocket });
  await assert.rejects(client.open(), (e) => e.code === 1008 && /bad token/.test(e.message));
});

test("a connection that closes rejects the requests still waiting", async () => {
  const { WebSocket, state } = fakeBridge();
  const client = await connect({ url: "ws://x/ws", participant: "P01", WebSocket });
  const sock = state.sockets.at(-1);
  sock.send = () => {}; // the bridge goes silent
  const pending = client.status();
  sock.close(1011, "bridge stopped");
  await assert.rejects(pending, (e) => e.code === 1011);
  assert.throws(() => client._send({ type: "stop" }), BridgeError);
});

test("bridgeUrl and nearestTarget", () => {
  assert.equal(bridgeUrl("a b", { protocol: "http:", host: "127.0.0.1:8765" }), "ws://127.0.0.1:8765/ws?token=a%20b");
  assert.equal(bridgeUrl("T", { protocol: "https:", host: "lab.example:1" }), "wss://lab.example:1/ws?token=T");
  const targets = [0, 90, 180, 270].map((a, k) => ({ target: k + 1, angle_deg: a }));
  assert.equal(nearestTarget(targets, 350).target, 1);
  assert.equal(nearestTarget(targets, 100).target, 2);
  assert.equal(nearestTarget(targets, 226).target, 4);
});
