/*! @tactorbelt/jspsych-plugin-tactile 0.1.0 (MIT); built by web/scripts/build.mjs from web/packages/jspsych-plugin-tactile: do not edit */
var __defProp = Object.defineProperty;
var __defNormalProp = (obj, key, value) => key in obj ? __defProp(obj, key, { enumerable: true, configurable: true, writable: true, value }) : obj[key] = value;
var __publicField = (obj, key, value) => __defNormalProp(obj, typeof key !== "symbol" ? key + "" : key, value);

// packages/jspsych-plugin-tactile/src/index.js
import { ParameterType } from "jspsych";

// packages/bridge-client/src/index.js
var SHARED = /* @__PURE__ */ Symbol.for("tactorbelt.bridge");
var BridgeError = class extends Error {
  constructor(message, { code = null, reply = null } = {}) {
    super(message);
    this.name = "BridgeError";
    this.code = code;
    this.reply = reply;
  }
};
function getBridge() {
  const client = globalThis[SHARED];
  if (!client) {
    throw new BridgeError("no tactorbelt bridge connection: call TactorbeltBridge.connect() first");
  }
  return client;
}

// packages/jspsych-plugin-tactile/src/index.js
var info = {
  name: "tactorbelt-tactile",
  version: "0.1.0",
  parameters: {
    /** The schedule's trial (index into the welcome's schedule): its target and condition. */
    index: { type: ParameterType.INT, default: null },
    /** A target of the study's layout (with condition), when no index is given. */
    target: { type: ParameterType.INT, default: null },
    /** An angle in degrees (0 = navel, clockwise from above), when no index or target. */
    angle_deg: { type: ParameterType.FLOAT, default: null },
    /** static | dynamic (with target or angle_deg). */
    condition: { type: ParameterType.STRING, default: "static" },
    /** Raw amplitudes in 0..1, one per tactor (with duration_ms). */
    amplitudes: { type: ParameterType.FLOAT, array: true, default: [] },
    duration_ms: { type: ParameterType.FLOAT, default: null },
    /** Shown while the trial runs. */
    stimulus_html: { type: ParameterType.HTML_STRING, default: "" },
    /** Time after the onset before the trial ends (0: at the onset; the belt plays on). */
    post_onset_ms: { type: ParameterType.INT, default: 0 },
    /** Stop the motors when the trial ends (otherwise the next trial, e.g. the response, does). */
    stop_on_finish: { type: ParameterType.BOOL, default: false },
    /** A BridgeClient; default: the page's shared connection. */
    bridge: { type: ParameterType.OBJECT, default: null }
  },
  data: {
    index: { type: ParameterType.INT },
    target: { type: ParameterType.INT },
    angle_deg: { type: ParameterType.FLOAT },
    condition: { type: ParameterType.STRING },
    /** The belt's onset on the page clock (performance.now(), ms). */
    onset_ms: { type: ParameterType.FLOAT },
    /** The onset on the skin (with the calibration's latencies), or null. */
    skin_onset_ms: { type: ParameterType.FLOAT },
    /** device (the belt stamped it) or host (the bridge's clock). */
    onset_source: { type: ParameterType.STRING },
    /** The uncertainty of onset_ms as the bridge reports it. */
    onset_uncertainty_ms: { type: ParameterType.FLOAT },
    clock_offset_ms: { type: ParameterType.FLOAT },
    clock_uncertainty_ms: { type: ParameterType.FLOAT },
    clock_rtt_ms: { type: ParameterType.FLOAT },
    duration_ms: { type: ParameterType.FLOAT },
    /** The play request's id (a trial message names it). */
    play_id: { type: ParameterType.INT },
    /** Page clock when the play request left and when its reply came. */
    request_ms: { type: ParameterType.FLOAT },
    reply_ms: { type: ParameterType.FLOAT },
    /** The stimulus as the bridge played it. */
    stimulus: { type: ParameterType.OBJECT },
    /** Set when the play failed (the bridge's error or a closed connection); no onset then. */
    error: { type: ParameterType.STRING }
  }
};
function playRequest(trial) {
  if (trial.index != null) return { index: trial.index };
  if (trial.target != null) return { target: trial.target, condition: trial.condition };
  if (trial.angle_deg != null) return { angle_deg: trial.angle_deg, condition: trial.condition };
  if (trial.amplitudes != null && trial.amplitudes.length > 0) {
    return { amplitudes: Array.from(trial.amplitudes), duration_ms: trial.duration_ms };
  }
  throw new Error("tactorbelt-tactile: give index, target, angle_deg or amplitudes");
}
var TactilePlugin = class {
  constructor(jsPsych) {
    this.jsPsych = jsPsych;
  }
  trial(display_element, trial) {
    display_element.innerHTML = trial.stimulus_html ?? "";
    this._play(display_element, trial).catch((err) => {
      display_element.innerHTML = "";
      this.jsPsych.finishTrial({
        index: trial.index ?? null,
        onset_ms: null,
        error: String(err?.message ?? err)
      });
    });
  }
  async _play(display_element, trial) {
    const bridge = trial.bridge ?? getBridge();
    const request = playRequest(trial);
    const played = await bridge.play(request);
    if (trial.post_onset_ms > 0) {
      const wait = played.onset_ms + trial.post_onset_ms - bridge.now();
      if (wait > 0) await new Promise((r) => setTimeout(r, wait));
    }
    if (trial.stop_on_finish) await bridge.stop();
    const clock = bridge.clock ?? {};
    const stim = played.stimulus ?? {};
    const data = {
      index: trial.index ?? stim.index ?? null,
      target: stim.target ?? trial.target ?? null,
      angle_deg: stim.angle_deg ?? trial.angle_deg ?? null,
      condition: stim.condition ?? (request.amplitudes ? null : trial.condition),
      onset_ms: played.onset_ms,
      skin_onset_ms: played.skin_onset_ms ?? null,
      onset_source: played.onset_source,
      onset_uncertainty_ms: played.uncertainty_ms ?? null,
      clock_offset_ms: clock.offset_ms ?? null,
      clock_uncertainty_ms: clock.uncertainty_ms ?? null,
      clock_rtt_ms: clock.rtt_ms ?? null,
      duration_ms: played.duration_ms ?? null,
      play_id: played.id,
      request_ms: played.request_ms,
      reply_ms: played.reply_ms,
      stimulus: stim
    };
    display_element.innerHTML = "";
    this.jsPsych.finishTrial(data);
  }
};
__publicField(TactilePlugin, "info", info);
var index_default = TactilePlugin;
export {
  index_default as default,
  playRequest
};
