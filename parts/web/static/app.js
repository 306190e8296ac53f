// Car controller page. Plain JavaScript, no build step, no external files.
//
// Talks to the car over Socket.IO (protocol v5 on Engine.IO v4, WebSocket transport only) with the
// small client below. The protocol is described in parts/web/protocol.py.
"use strict";

// ---------------------------------------------------------------------------------------------
// Minimal Socket.IO client: connect with auth, events, acknowledgements, binary attachments.
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

// ---------------------------------------------------------------------------------------------
const $ = (id) => document.getElementById(id);
const clamp = (v, lo, hi) => Math.min(hi, Math.max(lo, v));
const fmt = (v, d = 2) => (v === null || v === undefined ? "–" : Number(v).toFixed(d));
const MODES = ["user", "local_angle", "local"];
const TICK_MS = 50;            // drive messages (and dead-man heartbeat) at 20 Hz
const STEER_RATE = 4.0;        // keyboard steering ramp, full scale per second
const STEER_RETURN = 6.0;      // keyboard steering return to centre, per second
const DEADZONE = 0.08;         // gamepad stick dead zone

const params = new URLSearchParams(location.search);
const stats = { frames: 0, sent: 0, rejected: 0, role: "none", connected: false, state: null,
  lastError: null, angle: 0, throttle: 0 };
window.webStats = stats;  // read by the tests and the benchmark

const input = {
  keys: new Set(),
  steer: 0,                   // keyboard steering after the ramp
  pad: { active: false, x: 0, y: 0 },
  source: "keyboard",         // the input used last decides the command
  gamepadButtons: [],
};
let state = null;             // latest "state" message
let role = "none";
let lastTick = performance.now();

const sock = new SioClient(params.get("token") ? { token: params.get("token") } : {});

function setRole(r) {
  role = r;
  stats.role = r;
  $("role").textContent = r;
  $("role").className = "badge" + (r === "driver" ? " driver" : "");
  $("take").hidden = r === "driver" || !sock.connected;
  document.body.classList.toggle("viewer", r !== "driver");
}

function notice(text) {
  $("notice").textContent = text || "";
  $("notice").hidden = !text;
}

function send(event, data) {
  sock.emit(event, data, (res) => {
    if (res && res.ok === false) { stats.rejected++; stats.lastError = res.error; console.warn(res.error); }
  });
}

function setSetting(obj) { if (role === "driver") send("set", obj); }

// -- connection ---------------------------------------------------------------------------------
sock.on("connect", () => {
  stats.connected = true;
  $("conn").textContent = "connected"; $("conn").className = "badge good";
  notice("");
});
sock.on("connect_error", (msg) => { notice(msg); stats.lastError = msg; });
sock.on("disconnect", () => {
  stats.connected = false;
  $("conn").textContent = "disconnected"; $("conn").className = "badge bad";
  setRole("none");
  setTimeout(() => sock.open(), 1000);  // the car may have restarted: try again
});
sock.on("hello", (h) => {
  setRole(h.role);
  deadmanS = h.deadman_s;
  $("speedlimit").max = h.max_speed_limit;
  fillModels(h.models);
  onState(h.state);
});
sock.on("roles", (r) => setRole(r.driver === sock.id ? "driver" : "viewer"));
sock.on("state", onState);

// -- camera: draw each frame, then acknowledge it so the car sends the next (latest) one ------
const cam = $("cam");
const ctx = cam.getContext("2d");
let fpsCount = 0;
sock.on("frame", (buf, ack) => {
  const done = () => { if (ack) ack(true); };
  createImageBitmap(new Blob([buf], { type: "image/jpeg" })).then((bmp) => {
    if (cam.width !== bmp.width || cam.height !== bmp.height) { cam.width = bmp.width; cam.height = bmp.height; }
    ctx.drawImage(bmp, 0, 0);
    bmp.close();
    stats.frames++; fpsCount++;
    done();
  }).catch(done);
});
setInterval(() => { $("fps").textContent = fpsCount; fpsCount = 0; }, 1000);

// -- state → page -------------------------------------------------------------------------------
function onState(s) {
  state = s;
  stats.state = s;
  const c = s.command, t = s.telemetry;
  if (s.driver !== undefined && sock.id) setRole(s.driver === sock.id ? "driver" : "viewer");
  const angle = t.angle !== null ? t.angle : c.angle;
  const throttle = t.throttle !== null ? t.throttle : c.user_throttle;
  $("wheel").style.transform = `rotate(${clamp(angle, -1, 1) * 90}deg)`;
  $("angle").textContent = fmt(angle);
  $("throttle").textContent = fmt(throttle);
  const bar = $("throttlebar"), h = Math.abs(clamp(throttle, -1, 1)) * 50;
  bar.style.height = h + "%";
  bar.style.top = throttle >= 0 ? (50 - h) + "%" : "50%";
  bar.classList.toggle("reverse", throttle < 0);
  $("speed").textContent = fmt(t.speed, 1);
  $("rate").textContent = fmt(t.loop_rate_hz, 1);
  $("overruns").textContent = t.loop_overruns === null ? "–" : t.loop_overruns;
  $("records").textContent = t.num_records === null ? "–" : t.num_records;
  const piloting = c.mode !== "user" || t.pilot_angle !== null;
  $("pilot").classList.toggle("idle", !piloting);
  $("pmodel").textContent = t.pilot_model || "–";
  $("pangle").textContent = fmt(t.pilot_angle);
  $("pthrottle").textContent = fmt(t.pilot_throttle);
  for (const b of document.querySelectorAll("[data-mode]")) b.classList.toggle("on", b.dataset.mode === c.mode);
  $("record").classList.toggle("on", c.recording);
  $("record").textContent = c.recording ? "■ Recording" : "● Record";
  const estop = c.estop || t.estop === true;
  $("estop").classList.toggle("latched", estop);
  $("estop").textContent = estop ? "STOPPED — release" : "STOP";
  if (document.activeElement !== $("maxthrottle")) $("maxthrottle").value = c.max_throttle;
  $("maxthrottle-v").textContent = fmt(c.max_throttle);
  $("constant").checked = c.constant_throttle;
  $("nolimit").checked = c.speed_limit === null;
  if (c.speed_limit !== null && document.activeElement !== $("speedlimit")) $("speedlimit").value = c.speed_limit;
  $("speedlimit-v").textContent = c.speed_limit === null ? "none" : fmt(c.speed_limit, 1) + " m/s";
  if (s.deadman_trips !== trips) {  // the car stopped itself: say why
    if (trips !== null) {
      notice(`Dead-man stop: no control message for over ${deadmanS} s, so throttle 0 and user mode`);
      setTimeout(() => { if ($("notice").textContent.startsWith("Dead-man")) notice(""); }, 4000);
    }
    trips = s.deadman_trips;
  }
  $("behaviorrow").hidden = t.behavior === null;  // a car without behaviours has no lanes to show
  $("behavior").textContent = t.behavior === null ? "–" : t.behavior.replace(/_/g, " ");
  if (c.estop) notice("Emergency stop latched: press the STOP button again to release");
  else if ($("notice").textContent.startsWith("Emergency")) notice("");
}
let trips = null;
let deadmanS = 0.5;

function fillModels(models) {
  const sel = $("model");
  sel.innerHTML = "";
  if (!models.length) { sel.add(new Option("(no models in the models folder)", "")); return; }
  for (const m of models) sel.add(new Option(m, m));
}

// -- controls -----------------------------------------------------------------------------------
$("take").onclick = () => sock.emit("take_control", undefined, (res) => { if (res && res.ok) setRole("driver"); });
for (const b of document.querySelectorAll("[data-mode]")) b.onclick = () => setSetting({ mode: b.dataset.mode });
$("record").onclick = () => state && setSetting({ recording: !state.command.recording });
$("maxthrottle").oninput = () => setSetting({ max_throttle: Number($("maxthrottle").value) });
$("constant").onchange = () => setSetting({ constant_throttle: $("constant").checked });
$("speedlimit").oninput = () => { if (Number($("speedlimit").value) > 0) setSetting({ speed_limit: Number($("speedlimit").value) }); };
$("nolimit").onchange = () => setSetting({ speed_limit: $("nolimit").checked ? null : Math.max(0.1, Number($("speedlimit").value)) });
$("load").onclick = () => { if ($("model").value) setSetting({ model: $("model").value }); };
$("model").onfocus = () => sock.emit("models", undefined, (res) => {
  if (res && res.ok) { const cur = $("model").value; fillModels(res.models); $("model").value = cur; }
});
$("behaviornext").onclick = () => { if (role === "driver") send("behavior", { step: 1 }); };
$("estop").onclick = () => {
  const latched = state && (state.command.estop);
  stopNow();
  send("estop", { on: !latched });
};

function stopNow() {
  input.keys.clear(); input.steer = 0; input.pad = { active: false, x: 0, y: 0 };
  placeKnob(0, 0);
}

function cycleMode() {
  if (!state) return;
  setSetting({ mode: MODES[(MODES.indexOf(state.command.mode) + 1) % MODES.length] });
}

// keyboard
const DRIVE_KEYS = { ArrowUp: "up", KeyW: "up", ArrowDown: "down", KeyS: "down",
  ArrowLeft: "left", KeyA: "left", ArrowRight: "right", KeyD: "right" };
window.addEventListener("keydown", (e) => {
  if (e.target && (e.target.tagName === "INPUT" || e.target.tagName === "SELECT") && !DRIVE_KEYS[e.code]) return;
  if (DRIVE_KEYS[e.code]) {
    e.preventDefault();
    input.keys.add(DRIVE_KEYS[e.code]);
    input.source = "keyboard";
    tick();  // send at once: key press to car without waiting for the next tick
  } else if (e.code === "Space") {
    e.preventDefault(); stopNow(); input.source = "keyboard";
    if (state && state.command.mode !== "user") setSetting({ mode: "user" });
    tick();
  } else if (e.code === "Escape") { stopNow(); send("estop", { on: true }); }
  else if (e.repeat) return;
  else if (e.code === "KeyR") $("record").onclick();
  else if (e.code === "KeyM") cycleMode();
  else if (e.code === "KeyL") $("behaviornext").onclick();
  else if (e.code === "KeyC") setSetting({ constant_throttle: !(state && state.command.constant_throttle) });
  else if (e.key === "+" || e.key === "=") setSetting({ max_throttle: clamp(((state && state.command.max_throttle) || 0) + 0.05, 0, 1) });
  else if (e.key === "-") setSetting({ max_throttle: clamp(((state && state.command.max_throttle) || 0) - 0.05, 0, 1) });
});
window.addEventListener("keyup", (e) => {
  if (DRIVE_KEYS[e.code]) { input.keys.delete(DRIVE_KEYS[e.code]); tick(); }
});
window.addEventListener("blur", () => { input.keys.clear(); });  // keys released while away

// virtual joystick (pointer events: mouse, touch and pen)
const pad = $("pad"), knob = $("knob");
function placeKnob(x, y) {
  knob.style.left = (35 + x * 35) + "%";
  knob.style.top = (35 + y * 35) + "%";
}
function padMove(e) {
  const r = pad.getBoundingClientRect();
  let x = ((e.clientX - r.left) / r.width) * 2 - 1, y = ((e.clientY - r.top) / r.height) * 2 - 1;
  const n = Math.hypot(x, y);
  if (n > 1) { x /= n; y /= n; }
  input.pad = { active: true, x, y };
  input.source = "pad";
  placeKnob(x, y);
}
pad.addEventListener("pointerdown", (e) => { pad.setPointerCapture(e.pointerId); padMove(e); tick(); });
pad.addEventListener("pointermove", (e) => { if (input.pad.active) padMove(e); });
const padUp = () => { input.pad = { active: false, x: 0, y: 0 }; placeKnob(0, 0); tick(); };
pad.addEventListener("pointerup", padUp);
pad.addEventListener("pointercancel", padUp);

// browser Gamepad API ("standard" mapping)
function readGamepad() {
  const pads = navigator.getGamepads ? navigator.getGamepads() : [];
  const gp = Array.from(pads).find((p) => p && p.connected);
  if (!gp) return null;
  const dz = (v) => (Math.abs(v) < DEADZONE ? 0 : v);
  const steer = dz(gp.axes[0] || 0);
  const rt = gp.buttons[7] ? gp.buttons[7].value : 0, lt = gp.buttons[6] ? gp.buttons[6].value : 0;
  const throttle = rt > 0.05 || lt > 0.05 ? rt - lt : -dz(gp.axes[3] || 0);
  const pressed = gp.buttons.map((b) => b.pressed);
  const edge = (i) => pressed[i] && !input.gamepadButtons[i];
  if (edge(1)) { stopNow(); send("estop", { on: true }); }   // B / circle
  if (edge(0)) $("record").onclick();                         // A / cross
  if (edge(3)) cycleMode();                                   // Y / triangle
  input.gamepadButtons = pressed;
  if (steer !== 0 || throttle !== 0) input.source = "gamepad";
  return { angle: steer, throttle };
}

// -- the drive tick: compute the command from the input used last and send it -------------------
function tick() {
  const now = performance.now();
  const dt = Math.min(0.2, (now - lastTick) / 1000);
  lastTick = now;
  const k = input.keys;
  const target = (k.has("right") ? 1 : 0) - (k.has("left") ? 1 : 0);
  const rate = target === 0 ? STEER_RETURN : STEER_RATE;
  const step = rate * Math.max(dt, 0.02);  // an immediate tick still moves the wheel
  input.steer = clamp(input.steer + clamp(target - input.steer, -step, step), -1, 1);
  const gp = readGamepad();
  let angle = 0, throttle = 0;
  if (input.source === "gamepad" && gp) { angle = gp.angle; throttle = gp.throttle; }
  else if (input.source === "pad" && input.pad.active) { angle = input.pad.x; throttle = -input.pad.y; }
  else { angle = input.steer; throttle = (k.has("up") ? 1 : 0) - (k.has("down") ? 1 : 0); }
  angle = Math.round(clamp(angle, -1, 1) * 1000) / 1000;
  throttle = Math.round(clamp(throttle, -1, 1) * 1000) / 1000;
  stats.angle = angle; stats.throttle = throttle;
  if (role === "driver" && sock.connected) {
    sock.emit("drive", { angle, throttle }, (res) => {
      if (res && res.ok === false) { stats.rejected++; stats.lastError = res.error; }
    });
    stats.sent++;
  }
}
setInterval(tick, TICK_MS);
sock.open();
