// A WebSocket class that plays the bridge's side of protocol v1 in memory, for the packages'
// unit tests (the real bridge is tested in a real browser: tests/test_browser.py).
export function fakeBridge({ refuse = null, pings = 4, onsetMs = 1000, clockOffset = 2.5 } = {}) {
  const state = { sent: [], sockets: [], trials: [], stops: 0, errorOn: new Set() };

  class FakeSocket {
    constructor(url) {
      this.url = url;
      this.readyState = 0;
      state.sockets.push(this);
      setTimeout(() => {
        if (refuse) {
          this.readyState = 3;
          this.onclose?.({ code: refuse.code, reason: refuse.reason });
          return;
        }
        this.readyState = 1;
        this.onopen?.({});
      }, 0);
    }
    _reply(obj) {
      setTimeout(() => this.onmessage?.({ data: JSON.stringify(obj) }), 0);
    }
    send(text) {
      const msg = JSON.parse(text);
      state.sent.push(msg);
      if (state.errorOn.has(msg.type)) {
        this._reply({ type: "error", id: msg.id ?? null, error: `refused ${msg.type}` });
        return;
      }
      switch (msg.type) {
        case "hello":
          this._helloId = msg.id;
          this._pongs = 0;
          for (let k = 0; k < pings; k++) this._reply({ type: "ping", seq: k });
          break;
        case "pong":
          this._pongs += 1;
          if (this._pongs === pings && this._helloId != null) {
            const id = this._helloId;
            this._helloId = null;
            this._reply({
              type: "welcome", id, session_id: 7, resumed: false, heartbeat_ms: 1000,
              clock: { offset_ms: clockOffset, uncertainty_ms: 0.05, rtt_ms: 0.1, pings },
              schedule: [
                { index: 0, block: "training", condition: "static", target: 3, angle_deg: 45, training: true },
                { index: 1, block: "static", condition: "static", target: 5, angle_deg: 75, training: false },
              ],
              done: [],
            });
          }
          break;
        case "play": {
          const stimulus = msg.amplitudes
            ? { amplitudes: msg.amplitudes, duration_ms: msg.duration_ms }
            : { index: msg.index ?? null, target: msg.target ?? 5, condition: msg.condition ?? "static", angle_deg: 75 };
          this._reply({
            type: "played", id: msg.id, onset_ms: onsetMs, onset_source: "device",
            skin_onset_ms: onsetMs + 12, uncertainty_ms: 0.2, duration_ms: 10000, stimulus,
          });
          break;
        }
        case "stop":
          state.stops += 1;
          this._reply({ type: "stopped", id: msg.id });
          break;
        case "trial":
          state.trials.push(msg);
          this._reply({ type: "stored", id: msg.id, index: msg.index });
          break;
        case "status":
          this._reply({ type: "status", id: msg.id, belt: { url: "sim:", tactors: 6, connected: true }, session_id: 7 });
          break;
        case "end":
          this._reply({ type: "ended", id: msg.id });
          break;
        default:
          this._reply({ type: "error", id: msg.id ?? null, error: `unknown message type ${msg.type}` });
      }
    }
    close(code = 1000, reason = "") {
      this.readyState = 3;
      setTimeout(() => this.onclose?.({ code, reason }), 0);
    }
  }
  return { WebSocket: FakeSocket, state };
}
