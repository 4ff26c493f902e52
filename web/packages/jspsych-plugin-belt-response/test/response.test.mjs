import { test, before } from "node:test";
import assert from "node:assert/strict";
import { readFileSync } from "node:fs";
import { installDom, startJsPsych, until } from "../../../test-support/dom.mjs";
import { fakeBridge } from "../../../test-support/fake-bridge.mjs";
import { connect } from "@tactorbelt/bridge-client";

let Plugin, ellipsePoint, pointAngle, stickAngle;
before(async () => {
  installDom();
  ({ default: Plugin, ellipsePoint, pointAngle, stickAngle } = await import("../src/index.js"));
});

const TARGETS = Array.from({ length: 24 }, (_, k) => ({ target: k + 1, angle_deg: 15 * k }));

async function session() {
  const bridge = fakeBridge({ onsetMs: 50 });
  const client = await connect({ url: "ws://x/ws", participant: "P01", WebSocket: bridge.WebSocket });
  await client.play({ index: 1 });
  return { ...bridge, client };
}

async function screen(trial) {
  const run = await startJsPsych([{ type: Plugin, targets: TARGETS, index: 1, ...trial }]);
  await until(() => run.display.querySelector("[data-target]"));
  return run;
}

test("the screen has one element per target with data-target, on the ellipse", async () => {
  await session();
  const { display, jsPsych } = await screen({ highlight_target: 7 });
  const els = display.querySelectorAll("[data-target]");
  assert.deepEqual([...els].map((e) => Number(e.dataset.target)), TARGETS.map((t) => t.target));
  const front = display.querySelector('[data-target="1"]');
  assert.equal(parseFloat(front.style.left), 50);
  assert.equal(parseFloat(front.style.top), 0);
  const right = display.querySelector('[data-target="7"]'); // 90 deg: right of the torso
  assert.equal(parseFloat(right.style.left), 100);
  assert.notEqual(right.style.background, front.style.background); // highlighted
  jsPsych.abortExperiment();
});

test("a click on a target sends the trial (the bridge stops the stimulus) and records the answer", async () => {
  const { state } = await session();
  const { display, jsPsych, finished } = await screen({});
  display.querySelector('[data-target="6"]').dispatchEvent(new window.MouseEvent("click", { bubbles: true }));
  await finished;
  const [data] = jsPsych.data.get().values();
  assert.equal(state.stops, 0); // the trial message ends the stimulus, and stores when
  assert.equal(state.trials.length, 1);
  const sent = state.trials[0];
  assert.equal(sent.index, 1);
  assert.equal(sent.response.target, 6);
  assert.equal(sent.response.angle_deg, 75);
  assert.equal(sent.response.device, "mouse");
  assert.equal(sent.play_id, data.play_id);
  assert.equal(data.response, 6);
  assert.equal(data.target, 5);
  assert.equal(data.stored, true);
  assert.equal(typeof data.rt, "number");
  assert.equal(data.rt_ms, data.response_ms - 50); // from the onset on the page clock
  assert.equal(sent.response.rt_ms, data.rt_ms);
});

test("without an index nothing is stored; the answer stops the motors", async () => {
  const { state } = await session();
  const { display, jsPsych, finished } = await screen({ index: null });
  display.querySelector('[data-target="3"]').dispatchEvent(new window.MouseEvent("click", { bubbles: true }));
  await finished;
  assert.equal(state.stops, 1);
  assert.equal(state.trials.length, 0);
  assert.equal(jsPsych.data.get().values()[0].response, 3);
});

test("a play by target answers a schedule trial with its play id; another trial's play does not", async () => {
  const { state, client } = await session();
  await client.play({ target: 5, condition: "static" });
  let run = await screen({ index: 1 });
  run.display.querySelector('[data-target="5"]').dispatchEvent(new window.MouseEvent("click", { bubbles: true }));
  await run.finished;
  assert.equal(state.trials[0].play_id, client.lastPlay.id);
  assert.equal(typeof state.trials[0].response.rt_ms, "number");
  await client.play({ index: 0 });
  run = await screen({ index: 1 });
  run.display.querySelector('[data-target="5"]').dispatchEvent(new window.MouseEvent("click", { bubbles: true }));
  await run.finished;
  assert.equal(state.trials[1].play_id, null); // the bridge then refuses it: not played
  assert.equal(state.trials[1].response.rt_ms, null);
});

test("a touch answers with device touch", async () => {
  const { state } = await session();
  const { display, finished } = await screen({});
  const ev = new window.MouseEvent("pointerdown", { bubbles: true });
  Object.defineProperty(ev, "pointerType", { value: "touch" });
  display.querySelector('[data-target="13"]').dispatchEvent(ev);
  await finished;
  assert.equal(state.trials[0].response.device, "touch");
  assert.equal(state.trials[0].response.target, 13);
});

test("a gamepad's stick answers once it has rested at the centre", async () => {
  const { state } = await session();
  let axes = [0.95, 0]; // pushed before the screen: not an answer
  Object.defineProperty(window.navigator, "getGamepads", {
    value: () => [null, { axes, buttons: [] }], configurable: true,
  });
  try {
    const { finished } = await screen({});
    await new Promise((r) => setTimeout(r, 60));
    assert.equal(state.trials.length, 0);
    axes = [0, 0];
    await new Promise((r) => setTimeout(r, 60));
    axes = [0, 0.95]; // down: behind the participant (180 deg)
    await finished;
    const sent = state.trials[0];
    assert.equal(sent.response.device, "gamepad");
    assert.equal(sent.response.target, 13);
    assert.equal(sent.response.angle_deg, 180);
  } finally {
    delete window.navigator.getGamepads;
  }
});

test("no answer within trial_duration: the trial is sent unanswered", async () => {
  const { state } = await session();
  const { jsPsych, finished } = await screen({ trial_duration: 30 });
  await finished;
  const [data] = jsPsych.data.get().values();
  assert.equal(data.response, null);
  assert.equal(data.rt_ms, null);
  assert.equal(state.trials[0].response.target, null);
  assert.equal(data.stored, true);
});

test("a trial the bridge refuses is recorded with the error, not stored", async () => {
  const { state } = await session();
  state.errorOn.add("trial");
  const { display, jsPsych, finished } = await screen({});
  display.querySelector('[data-target="2"]').dispatchEvent(new window.MouseEvent("click", { bubbles: true }));
  await finished;
  const [data] = jsPsych.data.get().values();
  assert.equal(data.stored, false);
  assert.match(data.error, /refused trial/);
});

test("info follows jsPsych's plugin conventions", async () => {
  const { ParameterType } = await import("jspsych");
  const meta = JSON.parse(readFileSync(new URL("../package.json", import.meta.url), "utf8"));
  assert.equal(Plugin.info.name, "tactorbelt-belt-response");
  assert.equal(Plugin.info.version, meta.version);
  assert.equal(Plugin.info.parameters.targets.type, ParameterType.COMPLEX);
  for (const field of ["response", "response_angle_deg", "rt", "rt_ms", "device"]) {
    assert.ok(Plugin.info.data[field], field);
  }
});

test("geometry: angles and screen points agree (0 at the top, clockwise)", () => {
  for (const a of [0, 30, 90, 135, 200, 359]) {
    const p = ellipsePoint(a);
    assert.ok(Math.abs(pointAngle(p.x, p.y) - a) < 1e-9, String(a));
  }
  assert.equal(stickAngle(0.5, 0, 0.9), null);
  assert.ok(Math.abs(stickAngle(-1, 0, 0.9).angle_deg - 270) < 1e-9);
});
