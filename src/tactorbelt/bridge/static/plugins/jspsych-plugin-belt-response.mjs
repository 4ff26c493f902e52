/*! @tactorbelt/jspsych-plugin-belt-response 0.1.0 (MIT); built by web/scripts/build.mjs from web/packages/jspsych-plugin-belt-response: do not edit */
var __defProp = Object.defineProperty;
var __defNormalProp = (obj, key, value) => key in obj ? __defProp(obj, key, { enumerable: true, configurable: true, writable: true, value }) : obj[key] = value;
var __publicField = (obj, key, value) => __defNormalProp(obj, typeof key !== "symbol" ? key + "" : key, value);

// packages/jspsych-plugin-belt-response/src/index.js
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
function nearestTarget(targets, angleDeg) {
  let best = null;
  let bestD = Infinity;
  for (const t of targets) {
    const d = Math.abs(((t.angle_deg - angleDeg) % 360 + 540) % 360 - 180);
    if (d < bestD) {
      bestD = d;
      best = t;
    }
  }
  return best;
}

// packages/jspsych-plugin-belt-response/src/index.js
var info = {
  name: "tactorbelt-belt-response",
  version: "0.1.0",
  parameters: {
    /** The targets: [{target: K, angle_deg: A}], as the study's layout numbers them. */
    targets: { type: ParameterType.COMPLEX, array: true, default: void 0 },
    /** The schedule's trial this answers (sent in the trial message with the last play's id;
     *  the bridge checks that play was this trial's stimulus); null: nothing is stored. */
    index: { type: ParameterType.INT, default: null },
    /** A target drawn highlighted (training: its location is shown). */
    highlight_target: { type: ParameterType.INT, default: null },
    prompt: { type: ParameterType.HTML_STRING, default: "" },
    /** Width over height of the ellipse (the window's 1.25). */
    aspect: { type: ParameterType.FLOAT, default: 1.25 },
    /** Width of the ellipse in px; null: fits the window. */
    width_px: { type: ParameterType.INT, default: null },
    /** A click on the ellipse away from a target answers with the nearest target. */
    ellipse_answers: { type: ParameterType.BOOL, default: true },
    /** Gamepad stick: deflection (0..1) that answers; it must first rest under half of it. */
    gamepad_threshold: { type: ParameterType.FLOAT, default: 0.9 },
    /** No answer this long after the screen appears: the trial ends unanswered (null: waits). */
    trial_duration: { type: ParameterType.INT, default: null },
    /** Turn the motors off at the answer (the paper's stimulus stops at acquisition); with
     *  an index the trial message does it (the bridge stores the moment the stimulus ended). */
    stop_stimulus: { type: ParameterType.BOOL, default: true },
    /** A BridgeClient; default: the page's shared connection. */
    bridge: { type: ParameterType.OBJECT, default: null }
  },
  data: {
    index: { type: ParameterType.INT },
    /** The stimulus' target (from the play this answers), or null. */
    target: { type: ParameterType.INT },
    /** The answered target K, null when unanswered. */
    response: { type: ParameterType.INT },
    response_angle_deg: { type: ParameterType.FLOAT },
    /** ms from the screen's appearance (jsPsych's convention). */
    rt: { type: ParameterType.FLOAT },
    /** ms from the stimulus onset on the page clock (stored as the trial's response time). */
    rt_ms: { type: ParameterType.FLOAT },
    /** mouse | touch | pen | gamepad, null when unanswered. */
    device: { type: ParameterType.STRING },
    /** The page clock at the answer. */
    response_ms: { type: ParameterType.FLOAT },
    play_id: { type: ParameterType.INT },
    /** The bridge stored the trial. */
    stored: { type: ParameterType.BOOL },
    error: { type: ParameterType.STRING }
  }
};
var COLORS = {
  background: "#1e2028",
  fill: "#2a2d36",
  line: "#bec2cc",
  target: "#8a90a0",
  highlight: "#f0c040",
  chosen: "#60c070"
};
function ellipsePoint(angleDeg) {
  const r = angleDeg * Math.PI / 180;
  return { x: 0.5 + 0.5 * Math.sin(r), y: 0.5 - 0.5 * Math.cos(r) };
}
function pointAngle(fx, fy) {
  const a = Math.atan2(fx - 0.5, 0.5 - fy) * 180 / Math.PI;
  return (a % 360 + 360) % 360;
}
function stickAngle(x, y, threshold) {
  const r = Math.hypot(x, y);
  if (!(r >= threshold)) return null;
  return { angle_deg: (Math.atan2(x, -y) * 180 / Math.PI % 360 + 360) % 360, r };
}
var BeltResponsePlugin = class {
  constructor(jsPsych) {
    this.jsPsych = jsPsych;
  }
  trial(display_element, trial) {
    const bridge = trial.bridge ?? safeBridge();
    const now = bridge ? () => bridge.now() : () => performance.now();
    const targets = trial.targets ?? [];
    const win = display_element.ownerDocument.defaultView;
    const width = trial.width_px ?? Math.round(Math.min(700, 0.8 * (win.innerWidth || 800), 0.6 * (win.innerHeight || 600) * trial.aspect));
    const height = Math.round(width / trial.aspect);
    const dot = Math.max(14, Math.round(width / 22));
    const parts = [
      `<div class="tactorbelt-response" style="position:relative;width:${width}px;height:${height}px;margin:${dot * 3.5}px auto ${dot * 2}px;touch-action:none;user-select:none">`,
      `<div class="tactorbelt-ellipse" style="position:absolute;inset:0;border-radius:50%;background:${COLORS.fill};border:3px solid ${COLORS.line};box-sizing:border-box"></div>`,
      `<div class="tactorbelt-front" style="position:absolute;left:50%;top:-${dot * 2.4}px;transform:translateX(-50%);font-size:14px;color:${COLORS.line}">front</div>`
    ];
    for (const t of targets) {
      const p = ellipsePoint(t.angle_deg);
      const color = t.target === trial.highlight_target ? COLORS.highlight : COLORS.target;
      parts.push(
        `<div class="tactorbelt-target" role="button" aria-label="target ${t.target}" data-target="${t.target}" data-angle="${t.angle_deg}" style="position:absolute;left:${(p.x * 100).toFixed(3)}%;top:${(p.y * 100).toFixed(3)}%;width:${dot}px;height:${dot}px;border-radius:50%;transform:translate(-50%,-50%);cursor:pointer;background:${color}"></div>`
      );
    }
    parts.push("</div>");
    if (trial.prompt) parts.push(`<div class="tactorbelt-prompt">${trial.prompt}</div>`);
    display_element.innerHTML = parts.join("");
    const box = display_element.querySelector(".tactorbelt-response");
    const shownMs = now();
    const lastPlay = bridge?.lastPlay ?? null;
    const playedIndex = lastPlay?.request?.index;
    const play = lastPlay && (trial.index == null || playedIndex == null || playedIndex === trial.index) ? lastPlay : null;
    let done = false;
    let rafId = null;
    let timer = null;
    const cleanup = () => {
      box.removeEventListener("pointerdown", onPointer);
      box.removeEventListener("click", onPointer);
      if (rafId != null) win.cancelAnimationFrame?.(rafId);
      if (timer != null) clearTimeout(timer);
    };
    const answer = (target, angleDeg, device, atMs) => {
      if (done) return;
      done = true;
      cleanup();
      if (target != null) {
        const el = box.querySelector(`[data-target="${target}"]`);
        if (el) el.style.background = COLORS.chosen;
      }
      const rtFromOnset = target == null || play == null ? null : atMs - play.onset_ms;
      const data = {
        index: trial.index,
        target: play?.stimulus?.target ?? null,
        response: target,
        response_angle_deg: angleDeg,
        rt: target == null ? null : atMs - shownMs,
        rt_ms: rtFromOnset,
        device,
        response_ms: target == null ? null : atMs,
        play_id: play?.id ?? null,
        stored: false
      };
      this._send(bridge, trial, data).then(
        () => this._finish(display_element, data),
        (err) => {
          data.error = String(err?.message ?? err);
          this._finish(display_element, data);
        }
      );
    };
    const onPointer = (ev) => {
      const at = eventTime(ev, now);
      const el = ev.target?.closest?.("[data-target]");
      const device = ev.pointerType || "mouse";
      if (el) {
        answer(Number(el.dataset.target), Number(el.dataset.angle), device, at);
        return;
      }
      if (!trial.ellipse_answers || targets.length === 0) return;
      const rect = box.getBoundingClientRect();
      if (!(rect.width > 0 && rect.height > 0)) return;
      const fx = (ev.clientX - rect.left) / rect.width;
      const fy = (ev.clientY - rect.top) / rect.height;
      if ((fx - 0.5) ** 2 + (fy - 0.5) ** 2 > 0.25 * 1.2) return;
      const angle = pointAngle(fx, fy);
      answer(nearestTarget(targets, angle).target, angle, device, at);
    };
    box.addEventListener("pointerdown", onPointer);
    box.addEventListener("click", onPointer);
    const nav = win.navigator;
    if (typeof nav?.getGamepads === "function" && typeof win.requestAnimationFrame === "function") {
      let armed = false;
      const poll = () => {
        if (done) return;
        for (const pad of nav.getGamepads() ?? []) {
          if (!pad || pad.axes.length < 2) continue;
          const [x, y] = pad.axes;
          if (Math.hypot(x, y) < trial.gamepad_threshold / 2) armed = true;
          const hit = armed ? stickAngle(x, y, trial.gamepad_threshold) : null;
          if (hit && targets.length) {
            answer(nearestTarget(targets, hit.angle_deg).target, hit.angle_deg, "gamepad", now());
            return;
          }
        }
        rafId = win.requestAnimationFrame(poll);
      };
      rafId = win.requestAnimationFrame(poll);
    }
    if (trial.trial_duration != null) {
      timer = setTimeout(() => answer(null, null, null, now()), trial.trial_duration);
    }
  }
  async _send(bridge, trial, data) {
    if (!bridge) return;
    if (trial.index == null) {
      if (trial.stop_stimulus) await bridge.stop();
      return;
    }
    const response = {
      target: data.response,
      angle_deg: data.response_angle_deg,
      rt_ms: data.rt_ms,
      device: data.device
    };
    await bridge.trial(trial.index, response, data.play_id);
    data.stored = true;
  }
  _finish(display_element, data) {
    display_element.innerHTML = "";
    this.jsPsych.finishTrial(data);
  }
};
__publicField(BeltResponsePlugin, "info", info);
function safeBridge() {
  try {
    return getBridge();
  } catch {
    return null;
  }
}
function eventTime(ev, now) {
  const t = now();
  const s = ev.timeStamp;
  return typeof s === "number" && s > 0 && s <= t && t - s < 1e3 ? s : t;
}
var index_default = BeltResponsePlugin;
export {
  index_default as default,
  ellipsePoint,
  pointAngle,
  stickAngle
};
