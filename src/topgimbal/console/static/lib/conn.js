// WebSocket link to the console server: ops with ack/error promises, pushes to listeners,
// reconnect with back-off. The token (if the page was opened with one) rides on every request.

export const token = new URLSearchParams(location.search).get("token");

export function withToken(path) {
  if (!token) return path;
  return path + (path.includes("?") ? "&" : "?") + "token=" + encodeURIComponent(token);
}

export async function fetchJSON(path) {
  const headers = token ? { "X-Topgimbal-Token": token } : {};
  const r = await fetch(withToken(path), { headers, cache: "no-store" });
  if (!r.ok) throw new Error(`${path}: HTTP ${r.status}`);
  return r.json();
}

export class Conn {
  constructor({ onMessage, onState, timeoutMs = 8000 }) {
    this.onMessage = onMessage;
    this.onState = onState;
    this.timeoutMs = timeoutMs;
    this.pending = new Map();
    this.nextRef = 1;
    this.ws = null;
    this.backoff = 500;
    this.open();
  }

  open() {
    const proto = location.protocol === "https:" ? "wss:" : "ws:";
    const url = `${proto}//${location.host}${withToken(new URL("ws", location.href).pathname)}`;
    const ws = new WebSocket(url);
    this.ws = ws;
    this.onState("connecting");
    ws.onopen = () => { this.backoff = 500; this.onState("open"); };
    ws.onmessage = (ev) => {
      let msg;
      try { msg = JSON.parse(ev.data); } catch { return; }
      if ((msg.type === "ack" || msg.type === "error") && msg.ref != null && this.pending.has(msg.ref)) {
        const p = this.pending.get(msg.ref);
        this.pending.delete(msg.ref);
        clearTimeout(p.timer);
        if (msg.type === "ack") p.resolve(msg.result);
        else p.reject(Object.assign(new Error(msg.message), { kind: msg.kind, op: msg.op }));
        return;
      }
      this.onMessage(msg);
    };
    ws.onclose = () => {
      this.onState("closed");
      for (const [, p] of this.pending) {
        clearTimeout(p.timer);
        p.reject(Object.assign(new Error("connection to the console server lost"), { kind: "link" }));
      }
      this.pending.clear();
      setTimeout(() => this.open(), this.backoff);
      this.backoff = Math.min(this.backoff * 2, 8000);
    };
  }

  // Send an op; resolves with the ack's result, rejects with a readable Error.
  op(op, args = {}) {
    return new Promise((resolve, reject) => {
      if (!this.ws || this.ws.readyState !== WebSocket.OPEN) {
        reject(Object.assign(new Error("not connected to the console server"), { kind: "link" }));
        return;
      }
      const ref = this.nextRef++;
      const timer = setTimeout(() => {
        if (this.pending.delete(ref)) {
          reject(Object.assign(new Error(`no reply from the console server to ${op}`), { kind: "timeout" }));
        }
      }, this.timeoutMs);
      this.pending.set(ref, { resolve, reject, timer });
      this.ws.send(JSON.stringify({ ...args, op, ref }));
    });
  }
}
