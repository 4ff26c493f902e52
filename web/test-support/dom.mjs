// A jsdom window as the global browser environment for jsPsych under `node --test`.
import { JSDOM } from "jsdom";

export function installDom() {
  const dom = new JSDOM("<!doctype html><html><body></body></html>", {
    pretendToBeVisual: true, // requestAnimationFrame
    url: "http://127.0.0.1:8765/examples/paper.html?token=T",
  });
  const w = dom.window;
  for (const name of [
    "window", "document", "navigator", "HTMLElement", "Element", "Node", "Event",
    "MouseEvent", "KeyboardEvent", "CustomEvent", "getComputedStyle", "requestAnimationFrame",
    "cancelAnimationFrame", "location",
  ]) {
    Object.defineProperty(globalThis, name, { value: name === "window" ? w : w[name],
                                              configurable: true, writable: true });
  }
  return dom;
}

export async function startJsPsych(timeline) {
  const { initJsPsych } = await import("jspsych");
  const display = document.createElement("div");
  document.body.innerHTML = "";
  document.body.appendChild(display);
  const jsPsych = initJsPsych({ display_element: display });
  const finished = jsPsych.run(timeline);
  return { jsPsych, display, finished };
}

/** Resolves when cond() is true (polled), or rejects after ms. */
export async function until(cond, ms = 2000) {
  const t0 = Date.now();
  while (!cond()) {
    if (Date.now() - t0 > ms) throw new Error("timed out waiting");
    await new Promise((r) => setTimeout(r, 2));
  }
}
