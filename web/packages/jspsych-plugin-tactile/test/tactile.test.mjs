import { test, before } from "node:test";
import assert from "node:assert/strict";
import { readFileSync } from "node:fs";
import { installDom, startJsPsych } from "../../../test-support/dom.mjs";
import { fakeBridge } from "../../../test-support/fake-bridge.mjs";
import { connect } from "@tactorbelt/bridge-client";

let TactilePlugin, playRequest;
before(async () => {
  installDom();
  ({ default: TactilePlugin, playRequest } = await import("../src/index.js"));
});

test("info follows jsPsych's plugin conventions", async () => {
  const { ParameterType } = await import("jspsych");
  const { info } = TactilePlugin;
  assert.equal(info.name, "tactorbelt-tactile");
  const meta = JSON.parse(readFileSync(new URL("../package.json", import.meta.url), "utf8"));
  assert.equal(info.version, meta.version); // the data's plugin_version is the package's
  assert.equal(info.parameters.index.type, ParameterType.INT);
  assert.equal(info.parameters.amplitudes.array, true);
  for (const field of ["onset_ms", "skin_onset_ms", "onset_source", "clock_offset_ms", "clock_uncertainty_ms"]) {
    assert.ok(info.data[field], field);
  }
});

test("a trial plays the schedule's stimulus and records the onset and the clock", async () => {
  const { WebSocket, state } = fakeBridge({ onsetMs: 1234.5, clockOffset: -3.25 });
  await connect({ url: "ws://x/ws", participant: "P01", WebSocket });
  const { jsPsych, finished } = await startJsPsych([{ type: TactilePlugin, index: 1 }]);
  await finished;
  const [data] = jsPsych.data.get().values();
  const play = state.sent.find((m) => m.type === "play");
  assert.equal(play.index, 1);
  assert.equal(data.onset_ms, 1234.5);
  assert.equal(data.skin_onset_ms, 1234.5 + 12);
  assert.equal(data.onset_source, "device");
  assert.equal(data.onset_uncertainty_ms, 0.2);
  assert.equal(data.clock_offset_ms, -3.25);
  assert.equal(data.clock_uncertainty_ms, 0.05);
  assert.equal(data.play_id, play.id);
  assert.equal(data.target, 5);
  assert.equal(data.condition, "static");
  assert.ok(data.reply_ms >= data.request_ms);
  assert.equal(state.stops, 0); // the belt plays on into the response screen
});

test("stop_on_finish turns the motors off at the trial's end", async () => {
  const { WebSocket, state } = fakeBridge();
  await connect({ url: "ws://x/ws", participant: "P01", WebSocket });
  const { finished } = await startJsPsych([{ type: TactilePlugin, target: 2, condition: "dynamic", stop_on_finish: true }]);
  await finished;
  assert.equal(state.stops, 1);
  assert.deepEqual(state.sent.find((m) => m.type === "play").condition, "dynamic");
});

test("the four kinds of play request", () => {
  assert.deepEqual(playRequest({ index: 3 }), { index: 3 });
  assert.deepEqual(playRequest({ target: 4, condition: "dynamic" }), { target: 4, condition: "dynamic" });
  assert.deepEqual(playRequest({ angle_deg: 12.5, condition: "static" }), { angle_deg: 12.5, condition: "static" });
  assert.deepEqual(playRequest({ amplitudes: [0, 1, 0, 0, 0, 0], duration_ms: 200 }),
                   { amplitudes: [0, 1, 0, 0, 0, 0], duration_ms: 200 });
  assert.throws(() => playRequest({}), /index, target, angle_deg or amplitudes/);
});

test("a play the bridge refuses ends the trial with the error and no onset", async () => {
  const { WebSocket, state } = fakeBridge();
  await connect({ url: "ws://x/ws", participant: "P01", WebSocket });
  state.errorOn.add("play");
  const { jsPsych, finished } = await startJsPsych([{ type: TactilePlugin, index: 0 }]);
  await finished;
  const [data] = jsPsych.data.get().values();
  assert.equal(data.onset_ms, null);
  assert.match(data.error, /refused play/);
});
