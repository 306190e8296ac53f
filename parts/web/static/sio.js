// Minimal Socket.IO client for the car controller page (app.js): protocol v5 on Engine.IO v4,
// WebSocket transport only: connect with auth, events, acknowledgements, binary attachments.
// Plain JavaScript, no build step.
"use strict";

class SioClient {
  constructor(auth) {
    this.auth = auth;
    this.handlers = {};
    this.acks = new Map();
    this.nextAck = 1;
    this.ws = null;
    this.connected = false;
    this.id = null;
    this.pending = null;  // a binary event waiting for its attachments
  }
  on(event, fn) { this.handlers[event] = fn; return this; }
  _fire(event, ...args) { const fn = this.handlers[event]; if (fn) fn(...args); }
  open() {
    const proto = location.protocol === "https:" ? "wss" : "ws";
    const ws = new WebSocket(`${proto}://${location.host}/socket.io/?EIO=4&transport=websocket`);
    ws.binaryType = "arraybuffer";
    ws.onmessage = (ev) => this._onMessage(ev.data);
    ws.onclose = () => {
      const was = this.connected;
      this.connected = false;
      this.ws = null;
      this.acks.clear();
      this._fire("disconnect", was);
    };
    this.ws = ws;
  }
  close() { if (this.ws) this.ws.close(); }
  _send(text) { if (this.ws && this.ws.readyState === 1) this.ws.send(text); }
  _onMessage(data) {
    if (typeof data !== "string") {  // binary attachment of the pending event
      const p = this.pending;
      if (!p) return;
      p.buffers.push(data);
      if (p.buffers.length === p.count) { this.pending = null; this._dispatch(p.packet, p.buffers); }
      return;
    }
    const eio = data[0];
    if (eio === "0") { this._send("40" + JSON.stringify(this.auth)); }   // engine.io open
    else if (eio === "2") { this._send("3"); }                           // ping → pong
    else if (eio === "4") { this._onPacket(data.slice(1)); }
    else if (eio === "1") { this.close(); }
  }
  _onPacket(s) {
    const type = Number(s[0]);
    let i = 1, count = 0, id = null;
    if (type === 5 || type === 6) {
      const dash = s.indexOf("-", i);
      count = Number(s.slice(i, dash));
      i = dash + 1;
    }
    if (s[i] === "/") { const comma = s.indexOf(",", i); i = comma < 0 ? s.length : comma + 1; }
    let j = i;
    while (j < s.length && s[j] >= "0" && s[j] <= "9") j++;
    if (j > i) id = Number(s.slice(i, j));
    const data = j < s.length ? JSON.parse(s.slice(j)) : undefined;
    const packet = { type, id, data };
    if (count > 0) { this.pending = { packet, count, buffers: [] }; return; }
    this._dispatch(packet, []);
  }
  _dispatch(p, buffers) {
    const fill = (v) => {
      if (v && typeof v === "object") {
        if (v._placeholder === true && typeof v.num === "number") return buffers[v.num];
        for (const k of Object.keys(v)) v[k] = fill(v[k]);
      }
      return v;
    };
    if (p.type === 0) { this.connected = true; this.id = p.data && p.data.sid; this._fire("connect"); }
    else if (p.type === 4) { this._fire("connect_error", (p.data && p.data.message) || "refused"); }
    else if (p.type === 1) { this.close(); }
    else if (p.type === 2 || p.type === 5) {
      const [event, ...args] = fill(p.data);
      const fn = this.handlers[event];
      const ack = p.id === null ? null : (...res) => this._send("43" + p.id + JSON.stringify(res));
      if (fn) fn(...args, ack); else if (ack) ack();
    } else if (p.type === 3 || p.type === 6) {
      const cb = this.acks.get(p.id);
      this.acks.delete(p.id);
      if (cb) cb(...fill(p.data || []));
    }
  }
  emit(event, data, cb) {
    if (!this.connected) return false;
    let id = "";
    if (cb) { id = String(this.nextAck++); this.acks.set(Number(id), cb); }
    const args = data === undefined ? [event] : [event, data];
    this._send("42" + id + JSON.stringify(args));
    return true;
  }
}

