// The page side of `tactorbelt serve`'s WebSocket protocol (docs/browser.md, protocol v1).
//
// One BridgeClient is one WebSocket to the bridge. It answers the bridge's pings at once
// (the clock handshake at hello and the heartbeat after it), matches replies to requests by
// their integer `id`, and keeps what the welcome said (session, clock offset, schedule).
// The jsPsych plugins find the page's connection through setBridge/getBridge, which keep it
// on globalThis under a registered symbol: the browser bundles each carry a copy of this
// module, and all copies see the same connection.

const SHARED = Symbol.for("tactorbelt.bridge");

/** An error reply of the bridge (`{"type":"error"}`), or a connection that closed. */
export class BridgeError extends Error {
  constructor(message, { code = null, reply = null } = {}) {
    super(message);
    this.name = "BridgeError";
    this.code = code;
    this.reply = reply;
  }
}

/** The bridge's WebSocket address for a page it served: ws(s)://same host/ws?token=T. */
export function bridgeUrl(token, location = globalThis.location) {
  const scheme = location.protocol === "https:" ? "wss:" : "ws:";
  const q = token == null ? "" : `?token=${encodeURIComponent(token)}`;
  return `${scheme}//${location.host}/ws${q}`;
}

function defaultNow() {
  return globalThis.performance.now();
}

export class BridgeClient {
  /**
   * @param {object} options
   * @param {string} options.url  ws://127.0.0.1:P/ws?token=T (see bridgeUrl)
   * @param {Function} [options.WebSocket]  constructor (default: the browser's)
   * @param {Function} [options.now]  the page clock (default: performance.now)
   * @param {number} [options.timeoutMs]  a request without a reply this long fails
   */
  constructor({ url, WebSocket = globalThis.WebSocket, now = defaultNow, timeoutMs = 15000 }) {
    this.url = url;
    this._WebSocket = WebSocket;
    this.now = now;
    this.timeoutMs = timeoutMs;
    this.ws = null;
    this.nextId = 1;
    this.pending = new Map();
    this.welcome = null;
    this.lastPlay = null;
    this.closed = null; // {code, reason} once the socket closed
    this.listeners = new Set();
  }

  /** Opens the socket; resolves when it is open, rejects with the close code if refused. */
  open() {
    return new Promise((resolve, reject) => {
      const ws = new this._WebSocket(this.url);
      this.ws = ws;
      let opened = false;
      ws.onopen = () => {
        opened = true;
        resolve(this);
      };
      ws.onmessage = (ev) => this._receive(ev.data);
      ws.onclose = (ev) => {
        this.closed = { code: ev.code, reason: ev.reason };
        const err = new BridgeError(
          `bridge connection closed (${ev.code}${ev.reason ? `: ${ev.reason}` : ""})`,
          { code: ev.code },
        );
        for (const p of this.pending.values()) {
          clearTimeout(p.timer);
          p.reject(err);
        }
        this.pending.clear();
        if (!opened) reject(err);
        for (const fn of this.listeners) fn({ type: "close", code: ev.code, reason: ev.reason });
      };
    });
  }

  /** Calls fn with every message the bridge sends (and {type:"close"} at the end). */
  subscribe(fn) {
    this.listeners.add(fn);
    return () => this.listeners.delete(fn);
  }

  _receive(text) {
    let msg;
    try {
      msg = JSON.parse(text);
    } catch {
      return;
    }
    if (msg === null || typeof msg !== "object") return;
    if (msg.type === "ping") {
      // answered before anything else: the handshake's offset rests on this stamp
      this._send({ type: "pong", seq: msg.seq, t_page_ms: this.now() });
    }
    if (msg.id != null && this.pending.has(msg.id)) {
      const p = this.pending.get(msg.id);
      this.pending.delete(msg.id);
      clearTimeout(p.timer);
      if (msg.type === "error") {
        p.reject(new BridgeError(String(msg.error), { reply: msg }));
      } else {
        p.resolve(msg);
      }
    }
    for (const fn of this.listeners) fn(msg);
  }

  _send(obj) {
    if (!this.ws || this.ws.readyState !== 1) {
      throw new BridgeError("bridge connection is not open", { code: this.closed?.code ?? null });
    }
    this.ws.send(JSON.stringify(obj));
  }

  /** Sends a request (an id is added) and resolves with the reply of the same id. */
  request(message) {
    const id = this.nextId++;
    return new Promise((resolve, reject) => {
      const timer = setTimeout(() => {
        if (this.pending.delete(id)) {
          reject(new BridgeError(`no reply from the bridge to ${message.type} within ${this.timeoutMs} ms`));
        }
      }, this.timeoutMs);
      this.pending.set(id, { resolve, reject, timer });
      try {
        this._send({ ...message, id });
      } catch (err) {
        clearTimeout(timer);
        this.pending.delete(id);
        reject(err);
      }
    });
  }

  /** hello: opens or resumes the participant's session; resolves with the welcome. */
  async hello({ participant, page = null, userAgent = globalThis.navigator?.userAgent ?? "" }) {
    const welcome = await this.request({
      type: "hello",
      participant: String(participant),
      user_agent: userAgent,
      page,
    });
    this.welcome = welcome;
    return welcome;
  }

  /** The handshake's clock: {offset_ms, uncertainty_ms, rtt_ms, pings} (null before hello). */
  get clock() {
    return this.welcome?.clock ?? null;
  }

  get schedule() {
    return this.welcome?.schedule ?? [];
  }

  /**
   * Plays a stimulus: {index}, {target, condition}, {angle_deg, condition} or
   * {amplitudes, duration_ms}. Resolves when the belt started it, with the `played` reply
   * plus `id` (the play id a trial message names), `request_ms` and `reply_ms` (page clock).
   */
  async play(stimulus) {
    const request_ms = this.now();
    const reply = await this.request({ type: "play", ...stimulus });
    const played = { ...reply, request_ms, reply_ms: this.now(), request: { ...stimulus } };
    this.lastPlay = played;
    return played;
  }

  stop() {
    return this.request({ type: "stop" });
  }

  status() {
    return this.request({ type: "status" });
  }

  /** Stores schedule trial `index` with its response; resolves with the `stored` reply. */
  trial(index, response, playId = null) {
    return this.request({ type: "trial", index, response, play_id: playId });
  }

  end(status = "completed") {
    return this.request({ type: "end", status });
  }

  close() {
    if (this.ws && this.ws.readyState <= 1) this.ws.close(1000, "page done");
  }
}

/** Opens the bridge connection, says hello, and makes it the page's shared connection. */
export async function connect({ url, participant, page = null, WebSocket, now, timeoutMs } = {}) {
  const client = new BridgeClient({ url, WebSocket, now, timeoutMs });
  await client.open();
  await client.hello({ participant, page });
  setBridge(client);
  return client;
}

export function setBridge(client) {
  globalThis[SHARED] = client;
}

/** The page's shared connection; throws when connect() has not been called. */
export function getBridge() {
  const client = globalThis[SHARED];
  if (!client) {
    throw new BridgeError("no tactorbelt bridge connection: call TactorbeltBridge.connect() first");
  }
  return client;
}

/** Which target of `targets` ({target, angle_deg}) is nearest to an angle (degrees). */
export function nearestTarget(targets, angleDeg) {
  let best = null;
  let bestD = Infinity;
  for (const t of targets) {
    const d = Math.abs(((((t.angle_deg - angleDeg) % 360) + 540) % 360) - 180);
    if (d < bestD) {
      bestD = d;
      best = t;
    }
  }
  return best;
}
