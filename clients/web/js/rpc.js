// WebSocket client for rheod's /rpc bridge onto the rheo.v1 gRPC API.
//
// Envelope (JSON text messages):
//   open      {"id": N, "method": "rheo.v1.Service/Method", "request": {...}}
//   open bidi {"id": N, "method": "...", "stream": true}, then {"id": N, "write": {...}},
//             half-close {"id": N, "end": true}
//   cancel    {"id": N, "cancel": true}
//   token     {"auth": "TOKEN"}: sent first on every connection; the daemon checks it on each call
//   replies   {"id": N, "message": {...}} (any number), then {"id": N, "status": {code, name, message}}
//
// Messages use the protobuf JSON mapping: lowerCamelCase names, enums as strings, 64-bit
// integers as strings, bytes as base64.

/** gRPC status codes the studio reacts to. */
export const Code = Object.freeze({
  OK: 0,
  CANCELLED: 1,
  UNKNOWN: 2,
  INVALID_ARGUMENT: 3,
  DEADLINE_EXCEEDED: 4,
  NOT_FOUND: 5,
  RESOURCE_EXHAUSTED: 8,
  PERMISSION_DENIED: 7,
  FAILED_PRECONDITION: 9,
  UNIMPLEMENTED: 12,
  UNAVAILABLE: 14,
  UNAUTHENTICATED: 16,
});

/** A call that ended with a non-OK status; `message` is meant for people, shown verbatim. */
export class RpcError extends Error {
  constructor(status) {
    super(status.message || status.name || `status ${status.code}`);
    this.code = status.code;
    this.codeName = status.name || '';
  }
}

/**
 * One connection to the daemon, kept open: on a drop it reconnects with exponential backoff
 * (0.25 s doubling to 5 s) and reopens every subscription made with `subscribe`. Calls in flight
 * when the connection drops fail with UNAVAILABLE.
 *
 * Events (EventTarget): "state" with detail {state: "connecting"|"open"|"reconnecting"},
 * "open" after every (re)connection.
 */
export class Rpc extends EventTarget {
  constructor(url, token = '') {
    super();
    this.url = url;
    this.token = token;
    this.state = 'connecting';
    this.ws = null;
    this.nextId = 1;
    this.calls = new Map(); // id -> {onMessage, onStatus}
    this.subscriptions = new Set();
    this.backoffMs = 250;
    this.openWaiters = [];
    this.connects = 0;
    this.connect();
  }

  /** Uses `token` for every call from now on (this connection and the next ones). */
  setToken(token) {
    this.token = token;
    if (this.ws && this.ws.readyState === WebSocket.OPEN) this.ws.send(JSON.stringify({ auth: token }));
  }

  get connected() {
    return this.state === 'open';
  }

  setState(state) {
    if (state === this.state) return;
    this.state = state;
    this.dispatchEvent(new CustomEvent('state', { detail: { state } }));
  }

  connect() {
    const ws = new WebSocket(this.url);
    this.ws = ws;
    ws.onopen = () => {
      if (this.token) ws.send(JSON.stringify({ auth: this.token }));
      this.backoffMs = 250;
      this.connects += 1;
      this.setState('open');
      for (const w of this.openWaiters.splice(0)) w.resolve();
      for (const sub of this.subscriptions) sub.start();
      this.dispatchEvent(new Event('open'));
    };
    ws.onmessage = (ev) => this.onMessage(ev.data);
    ws.onclose = () => {
      if (this.ws !== ws) return;
      this.ws = null;
      // Every call on this connection is gone; subscriptions restart on the next one.
      const calls = [...this.calls.values()];
      this.calls.clear();
      for (const c of calls) c.onStatus({ code: Code.UNAVAILABLE, name: 'UNAVAILABLE', message: 'connection lost' }, true);
      this.setState('reconnecting');
      const delay = this.backoffMs;
      this.backoffMs = Math.min(this.backoffMs * 2, 5000);
      setTimeout(() => this.connect(), delay);
    };
    ws.onerror = () => {}; // onclose follows and handles it
  }

  onMessage(data) {
    if (typeof data !== 'string') return; // binary replies are not requested by the studio
    let m;
    try {
      m = JSON.parse(data);
    } catch {
      console.warn('rpc: unparsable message', data.slice(0, 200));
      return;
    }
    const c = this.calls.get(m.id);
    if (!c) {
      if (m.status && m.status.code !== 0) console.warn('rpc: status for unknown call', m);
      return;
    }
    if (m.message !== undefined) c.onMessage(m.message);
    if (m.status !== undefined) {
      this.calls.delete(m.id);
      c.onStatus(m.status, false);
    }
  }

  /** Resolves once connected (immediately when already). */
  ready() {
    if (this.connected) return Promise.resolve();
    return new Promise((resolve, reject) => this.openWaiters.push({ resolve, reject }));
  }

  send(obj) {
    if (!this.ws || this.ws.readyState !== WebSocket.OPEN) return false;
    this.ws.send(JSON.stringify(obj));
    return true;
  }

  /**
   * Opens a call. Returns {id, cancel(), write(msg), end(), done} where `done` resolves with the
   * final OK status or rejects with an RpcError.
   */
  open(method, request, { onMessage = () => {}, bidi = false } = {}) {
    const id = this.nextId++;
    let settle;
    const done = new Promise((resolve, reject) => {
      settle = (status) => (status.code === 0 ? resolve(status) : reject(new RpcError(status)));
    });
    done.catch(() => {}); // callers that only cancel need not handle it
    this.calls.set(id, { onMessage, onStatus: (s) => settle(s) });
    const envelope = bidi ? { id, method, stream: true } : { id, method, request: request || {} };
    if (!this.send(envelope)) {
      this.calls.delete(id);
      settle({ code: Code.UNAVAILABLE, name: 'UNAVAILABLE', message: 'not connected to rheod' });
    }
    return {
      id,
      done,
      cancel: () => {
        if (this.calls.has(id)) this.send({ id, cancel: true });
      },
      write: (msg) => this.calls.has(id) && this.send({ id, write: msg }),
      end: () => this.calls.has(id) && this.send({ id, end: true }),
    };
  }

  /** Unary call: resolves with the response message. */
  async call(method, request = {}) {
    await this.ready();
    let reply;
    const h = this.open(method, request, { onMessage: (m) => (reply = m) });
    await h.done;
    return reply;
  }

  /** Server-streaming call collected in full: resolves with the array of messages. */
  async collect(method, request = {}) {
    await this.ready();
    const out = [];
    const h = this.open(method, request, { onMessage: (m) => out.push(m) });
    await h.done;
    return out;
  }

  /** Server-streaming call: `onMessage` per message; returns the handle (cancel(), done). */
  stream(method, request, onMessage) {
    return this.open(method, request, { onMessage });
  }

  /** Bidirectional call (DeviceService/ToolStream): write(msg), end(), cancel(), done. */
  bidi(method, onMessage) {
    return this.open(method, null, { onMessage, bidi: true });
  }

  /**
   * A stream that lives across reconnections (e.g. WatchFrames): opened now (or on connect) and
   * reopened after every reconnection. `onEnd(err)` is told when one incarnation ends other than
   * by a lost connection or unsubscribe. Returns {close()}.
   */
  subscribe(method, request, onMessage, onEnd = () => {}) {
    const sub = {
      handle: null,
      closed: false,
      start: () => {
        if (sub.closed) return;
        const h = this.stream(method, request, onMessage);
        sub.handle = h;
        h.done.then(
          () => !sub.closed && onEnd(null),
          (e) => !sub.closed && e.code !== Code.UNAVAILABLE && onEnd(e),
        );
      },
      close: () => {
        sub.closed = true;
        this.subscriptions.delete(sub);
        if (sub.handle) sub.handle.cancel();
      },
    };
    this.subscriptions.add(sub);
    if (this.connected) sub.start();
    return sub;
  }
}

/** URL of the daemon's /rpc endpoint next to the page. */
export function rpcUrl(loc = window.location) {
  const scheme = loc.protocol === 'https:' ? 'wss:' : 'ws:';
  return `${scheme}//${loc.host}/rpc`;
}

/** Base64 of bytes (Uint8Array), chunked so large pictures do not blow the argument limit. */
export function toBase64(bytes) {
  let s = '';
  for (let i = 0; i < bytes.length; i += 0x8000) s += String.fromCharCode.apply(null, bytes.subarray(i, i + 0x8000));
  return btoa(s);
}

/** Bytes of a base64 string. */
export function fromBase64(b64) {
  const s = atob(b64);
  const out = new Uint8Array(s.length);
  for (let i = 0; i < s.length; i++) out[i] = s.charCodeAt(i);
  return out;
}
