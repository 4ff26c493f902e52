// The browser bundles the bridge serves (src/tactorbelt/bridge/static), loaded as a page
// loads them: jsPsych's own bundle, then the plugins' script files, globals and all.
import { test } from "node:test";
import assert from "node:assert/strict";
import { readFileSync } from "node:fs";
import { JSDOM } from "jsdom";
import { fakeBridge } from "../test-support/fake-bridge.mjs";

const STATIC = new URL("../../src/tactorbelt/bridge/static/", import.meta.url);
const read = (path) => readFileSync(new URL(path, STATIC), "utf8");

function page() {
  const dom = new JSDOM("<!doctype html><body><div id='t'></div></body>", {
    runScripts: "outside-only", pretendToBeVisual: true, url: "http://127.0.0.1:8735/examples/paper.html",
  });
  for (const file of ["vendor/jspsych.js", "plugins/bridge-client.js",
                      "plugins/jspsych-plugin-tactile.js", "plugins/jspsych-plugin-belt-response.js"]) {
    dom.window.eval(read(file));
  }
  return dom.window;
}

test("the bundles define the globals a page uses", () => {
  const w = page();
  assert.equal(typeof w.initJsPsych, "function");
  assert.equal(w.jsPsychTactile.info.name, "tactorbelt-tactile");
  assert.equal(w.jsPsychBeltResponse.info.name, "tactorbelt-belt-response");
  assert.equal(w.jsPsychTactile.info.parameters.index.type, w.jsPsychModule.ParameterType.INT);
  assert.equal(typeof w.TactorbeltBridge.connect, "function");
  assert.equal(w.TactorbeltBridge.bridgeUrl("T"), "ws://127.0.0.1:8735/ws?token=T");
});

test("a timeline of the bundled plugins plays, shows the targets and stores the answer", async () => {
  const w = page();
  const { WebSocket, state } = fakeBridge();
  await w.TactorbeltBridge.connect({ url: "ws://x/ws", participant: "P01", WebSocket });
  const jsPsych = w.initJsPsych({ display_element: w.document.getElementById("t") });
  const targets = [0, 1, 2, 3].map((k) => ({ target: k, angle_deg: 90 * k }));
  const done = jsPsych.run([
    { type: w.jsPsychTactile, index: 1 },
    { type: w.jsPsychBeltResponse, index: 1, targets },
  ]);
  const t0 = Date.now();
  while (!w.document.querySelector("[data-target]") && Date.now() - t0 < 2000) {
    await new Promise((r) => setTimeout(r, 2));
  }
  w.document.querySelector('[data-target="2"]').dispatchEvent(new w.MouseEvent("click", { bubbles: true }));
  await done;
  const [stim, resp] = jsPsych.data.get().values();
  assert.equal(stim.onset_ms, 1000);
  assert.equal(resp.response, 2);
  assert.equal(state.trials[0].play_id, stim.play_id);
});
