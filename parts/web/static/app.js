// Car controller page. Plain JavaScript, no build step, no external files.
//
// Talks to the car over Socket.IO (protocol v5 on Engine.IO v4, WebSocket transport only) with the
// small client in sio.js (loaded first). The protocol is described in parts/web/protocol.py.
"use strict";

// ---------------------------------------------------------------------------------------------
const $ = (id) => document.getElementById(id);
const clamp = (v, lo, hi) => Math.min(hi, Math.max(lo, v));
const fmt = (v, d = 2) => (v === null || v === undefined ? "–" : Number(v).toFixed(d));
const MODES = ["user", "local_angle", "local"];
const TICK_MS = 50;            // drive messages (and dead-man heartbeat) at 20 Hz
const STEER_RATE = 4.0;        // keyboard steering ramp, full scale per second
const STEER_RETURN = 6.0;      // keyboard steering return to centre, per second
const DEADZONE = 0.08;         // gamepad stick dead zone
const STALE_S = 1.0;           // no news from the car's loop for this long: what is shown is old

const params = new URLSearchParams(location.search);
const stats = { frames: 0, sent: 0, rejected: 0, role: "none", connected: false, state: null,
  lastError: null, angle: 0, throttle: 0, stale: true, stops: 0, paths: 0, pathCommands: 0 };
window.webStats = stats;  // read by the tests and the benchmark

const input = {
  keys: new Set(),
  steer: 0,                   // keyboard steering after the ramp
  pad: { active: false, x: 0, y: 0, id: null },
  source: "keyboard",         // the input used last decides the command
  gamepadButtons: [],
};
let state = null;             // latest "state" message
let stateAt = 0;              // performance.now() when it came
let role = "none";
let refused = null;           // why the car refused this page (pairing token), or null
let lastTick = performance.now();
let pickedAt = -Infinity;     // when the user last chose in the model list (not synced meanwhile)
let modelError = "";          // the last refusal of a model choice
let modeError = "";           // the last refusal of a mode choice
let shownModelError = "";     // the model error on screen
let loadPressed = false;      // Load pressed here, its answer not yet shown: bring it into view
const NO_PILOT = "Auto steer and Full auto need a pilot, and this car has no pilot: start it with a model "
  + "(manage.py drive --model models/NAME.pt).";

const sock = new SioClient(params.get("token") ? { token: params.get("token") } : {});

// the path view (pathview.js): shown on a car with path follow; its buttons go to the car as
// path_command (the driver only, like every other control)
const pathView = new PathView({ section: $("pathview"), canvas: $("pathmap"), state: $("pathstate"),
  info: $("pathinfo"), record: $("pathrecord"), buttons: document.querySelectorAll("[data-path]"),
  note: $("path-note") }, (command, onError) => {
  if (role !== "driver") return;
  stats.pathCommands++;
  send("path_command", { command }, onError);
});
stats.pathView = pathView;

function setRole(r) {
  role = r;
  stats.role = r;
  $("role").textContent = r === "none" ? "–" : r;
  $("role").className = "badge" + (r === "driver" ? " driver" : "");
  // Take control keeps its place when hidden: the header never moves
  $("take").classList.toggle("reserved", r === "driver" || !sock.connected);
  document.body.classList.toggle("viewer", r !== "driver");
  $("watching").hidden = r !== "viewer";
  if (r !== "driver") placeKnob(0, 0);
  updateControls();
}

function notice(text) {
  $("notice").textContent = text || "";
  $("notice").hidden = !text;
}

// send a message; onReply(res) when the car answers (at once with null when not connected)
function send(event, data, onError, onReply) {
  const sent = sock.emit(event, data, (res) => {
    if (onReply) onReply(res);
    if (res && res.ok === false) {
      stats.rejected++; stats.lastError = res.error; console.warn(res.error);
      if (onError) onError(res.error);
    }
  });
  if (!sent && onReply) onReply(null);
}

// settings sent and not yet answered: the car's state messages already on their way still carry
// the old value, and must not undo what the user just clicked (a checkbox flipping back)
const pending = new Map();  // setting name -> messages in flight
function setSetting(obj, onError) {
  if (role !== "driver") return;
  const names = Object.keys(obj);
  for (const k of names) pending.set(k, (pending.get(k) || 0) + 1);
  send("set", obj, onError, () => {
    for (const k of names) { const n = (pending.get(k) || 1) - 1; if (n > 0) pending.set(k, n); else pending.delete(k); }
  });
}

// -- connection ---------------------------------------------------------------------------------
function setConn(text, cls) { $("conn").textContent = text; $("conn").className = "badge " + cls; }
function setOnline(online) {
  document.body.classList.toggle("offline", !online);
  document.body.classList.toggle("refused", !!refused);
  $("pair").hidden = !refused;
  $("estop").setAttribute("aria-disabled", String(!online));
}
sock.on("connect", () => {
  stats.connected = true;
  refused = null;
  setConn("connected", "good");
  setOnline(true);
  notice("");
});
sock.on("connect_error", (msg) => {
  refused = msg;
  stats.lastError = msg;
  setConn("refused", "bad");
  setOnline(false);
  notice(msg.charAt(0).toUpperCase() + msg.slice(1) + ", or enter the token above");
});
// a refused page is given a field for the token: the page opens again with it in its address
$("token").value = params.get("token") || "";
$("pair").addEventListener("submit", (e) => {
  e.preventDefault();
  params.set("token", $("token").value.trim());
  location.search = "?" + params.toString();
});
sock.on("disconnect", () => {
  stats.connected = false;
  setOnline(false);
  pending.clear();  // no reply comes for what was in flight
  pathView.setPath(null);  // sent again on connect: the car may have restarted with another path
  if (!refused) setConn("disconnected — retrying", "bad");
  setRole("none");
  updateStale();
  // the car may have restarted: try again (slowly after a refusal: the URL needs its token)
  setTimeout(() => sock.open(), refused ? 5000 : 1000);
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
sock.on("path", (p) => { stats.paths++; pathView.setPath(p); });

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

// -- stale: grey what the car no longer confirms -------------------------------------------------
function updateStale() {
  const age = state && typeof state.age_s === "number" ? state.age_s : 0;
  const stale = !sock.connected || !state || (performance.now() - stateAt) / 1000 > STALE_S || age > STALE_S;
  stats.stale = stale;
  document.body.classList.toggle("stale", stale);
}
setInterval(updateStale, 250);

// -- state → page -------------------------------------------------------------------------------
function onState(s) {
  state = s;
  stateAt = performance.now();
  stats.state = s;
  updateStale();
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
  // sensors: a stale one is shown as such (its values read None); the obstacle stop when it acts
  const sensors = Object.entries(t.sensors || {});
  $("sensors").hidden = sensors.length === 0 && t.obstacle_stop === null;
  $("sensors").textContent = sensors.map(([k, ok]) => k + (ok ? " ok" : " STALE")).join(" · ")
    + (t.obstacle_stop ? ` · OBSTACLE ${t.obstacle_distance === null ? "(blind)" : fmt(t.obstacle_distance, 2) + " m"}: braking` : "");
  $("rate").textContent = fmt(t.loop_rate_hz, 1);
  $("overruns").textContent = t.loop_overruns === null ? "–" : t.loop_overruns;
  $("records").textContent = t.num_records === null ? "–" : t.num_records;
  // the pilot's outputs are live only in the loops it runs (a pilot mode)
  $("pilot").classList.toggle("idle", t.pilot_active !== true);
  $("pmodel").textContent = t.pilot_model || "none";
  $("pangle").textContent = fmt(t.pilot_angle);
  $("pthrottle").textContent = fmt(t.pilot_throttle);
  const simulated = t.sim_cte !== null || t.sim_laps !== null;
  $("sim").hidden = !simulated;
  if (simulated) {
    $("cte").textContent = t.sim_cte === null ? "–" : (t.sim_cte >= 0 ? "+" : "") + t.sim_cte.toFixed(2) + " m";
    $("cte").classList.toggle("offroad", t.sim_off_track === true);
    $("laps").textContent = t.sim_laps === null ? "–" : t.sim_laps;
    $("offtrack").textContent = t.off_track_events;
  }
  // the car's own gamepad (when it has one): whether it can drive or stop the car
  $("cargamepad").hidden = t.car_gamepad === null;
  if (t.car_gamepad !== null) {
    $("cargamepad").textContent = "car pad " + t.car_gamepad;
    $("cargamepad").className = "badge " + (t.car_gamepad === "connected" ? "good" : "bad");
  }
  for (const b of document.querySelectorAll("[data-mode]")) {
    b.classList.toggle("on", b.dataset.mode === c.mode);
    b.setAttribute("aria-pressed", String(b.dataset.mode === c.mode));
  }
  $("record").classList.toggle("on", c.recording);
  $("record").textContent = c.recording ? "■ Recording" : "● Record";
  const estop = c.estop || t.estop === true;
  $("estop").classList.toggle("latched", estop);
  // only the driving browser can release the stop: a watcher's STOP never offers it
  $("estop").textContent = !estop ? "STOP" : role === "driver" ? "STOPPED — release" : "STOPPED";
  if (document.activeElement !== $("maxthrottle")) $("maxthrottle").value = c.max_throttle;
  $("maxthrottle-v").textContent = fmt(c.max_throttle);
  if (!pending.has("constant_throttle")) $("constant").checked = c.constant_throttle;
  if (!pending.has("speed_limit")) $("nolimit").checked = c.speed_limit === null;
  if (c.speed_limit !== null && document.activeElement !== $("speedlimit")) $("speedlimit").value = c.speed_limit;
  $("speedlimit").setAttribute("aria-valuetext", $("nolimit").checked ? "no limit" : $("speedlimit").value + " m/s");
  $("speedlimit-v").textContent = c.speed_limit === null ? "none" : fmt(c.speed_limit, 1) + " m/s";
  $("speedlimit-note").textContent = t.speed === null && t.loops > 0
    ? "needs a measured speed (simulator, wheel encoder, GPS or VESC): none on this car, or its sensor is stale"
    : "caps the car's speed in every mode, human or pilot; a slower car is not sped up";
  syncModel(t);
  updateControls();
  if (s.deadman_trips !== trips) {  // the car stopped itself: say why
    if (trips !== null) {
      notice(`Dead-man stop: no control message for over ${deadmanS} s, so throttle 0 and user mode`);
      setTimeout(() => { if ($("notice").textContent.startsWith("Dead-man")) notice(""); }, 4000);
    }
    trips = s.deadman_trips;
  }
  if (s.notice && s.notice !== linkNotice) notice(s.notice);  // the paired laptop switched the pilot: say so
  linkNotice = s.notice || null;
  pathView.update(t.path === undefined ? null : t.path);
  $("behaviorrow").hidden = t.behavior === null;  // a car without behaviours has no lanes to show
  $("behavior").textContent = t.behavior === null ? "–" : t.behavior.replace(/_/g, " ");
  if (c.estop && role === "driver") notice("Emergency stop latched: press the STOP button again to release");
  else if (c.estop) notice(VIEWER_LATCHED);
  else if ($("notice").textContent.startsWith("Emergency")) notice("");
}
let trips = null;
let linkNotice = null;
let deadmanS = 0.5;
const VIEWER_LATCHED = "Emergency stop latched: only the driving browser can release it (press Take control to drive)";

// a message on the page; a command in it ("manage.py drive --model ...") is kept on one line
function showText(el, text) {
  if (el.textContent === text) return;
  el.textContent = "";
  const parts = text.split(/(manage\.py [^)]*)/);
  parts.forEach((part, i) => {
    if (i % 2 === 0) { el.append(part); return; }
    const cmd = document.createElement("code");
    cmd.textContent = part;
    el.append(cmd);
  });
}

// whether the car has no pilot (a pilot reports its model, or has written its angle)
function noPilot(t) { return !!t && t.loops > 0 && t.pilot_model === null && t.pilot_angle === null; }

// what this page may touch: a watcher nothing but STOP; while STOP is latched nothing that moves
// the car or records; the speed limit only where the car measures its speed
function updateControls() {
  const driver = role === "driver";
  const c = state ? state.command : null, t = state ? state.telemetry : null;
  const latched = !!(c && c.estop);
  const pilotless = noPilot(t);
  for (const b of document.querySelectorAll("[data-mode]")) {
    b.disabled = !driver || (b.dataset.mode !== "user" && (latched || pilotless));
  }
  showText($("mode-note"), modeError || (pilotless ? NO_PILOT : ""));
  document.body.classList.toggle("modenote", !!$("mode-note").textContent);  // a phone held sideways makes room
  $("record").disabled = !driver || latched;
  $("constant").disabled = !driver || latched;
  $("maxthrottle").disabled = !driver;
  const speed = !t || t.speed !== null || t.loops === 0;
  $("speedlimit").disabled = !driver || !speed || $("nolimit").checked;
  $("speedlimit").classList.toggle("unset", $("nolimit").checked);  // no limit: no position shown
  $("nolimit").disabled = !driver || !speed;
  $("model").disabled = !driver;
  $("load").disabled = !driver || !$("model").value;
  $("behaviornext").disabled = !driver;
  pathView.setEnabled(driver);
}

function fillModels(models) {
  const sel = $("model");
  const cur = sel.value;
  sel.innerHTML = "";
  // nothing is preselected: the first entry says so (a file shown would look loaded)
  sel.add(new Option(models.length ? "(choose a model)" : "(no models in the models folder)", ""));
  for (const m of models) sel.add(new Option(m, m));
  sel.value = models.includes(cur) ? cur : "";
}

// the list shows the model driving, unless the user is choosing; errors come from the car
function syncModel(t) {
  const sel = $("model");
  const choosing = document.activeElement === sel || performance.now() - pickedAt < 5000;
  const running = t.pilot_model || "";
  if (!choosing && sel.value !== running) {
    if (![...sel.options].some((o) => o.value === running)) sel.add(new Option(running, running));
    sel.value = running;
  }
  const error = modelError || (t.pilot_error ? loadError(t.pilot_error) : "");
  showText($("model-error"), error);
  // the answer to this page's Load where the eye is (never a scroll on opening the page: the
  // joystick and STOP come first)
  if (loadPressed && error && error !== shownModelError) {
    $("model-error").scrollIntoView({ block: "nearest" });
    loadPressed = false;
  }
  shownModelError = error;
}

// the car's "PATH: why" for a model it did not load, in plain words, the file named once
function loadError(text) {
  const i = text.indexOf(": ");
  if (i < 0) return text;
  const path = text.slice(0, i), name = path.split(/[\\/]/).pop();
  let why = text.slice(i + 2);
  if (why.startsWith(path + ": ")) why = why.slice(path.length + 2);
  return `Could not load ${name}: ${why.split(path).join(name)}`;
}

// -- controls -----------------------------------------------------------------------------------
$("take").onclick = () => sock.emit("take_control", undefined, (res) => { if (res && res.ok) setRole("driver"); });
$("watch-take").onclick = $("take").onclick;
let modeErrorTimer = 0;
function setMode(mode) {
  modeError = "";
  setSetting({ mode }, (e) => {  // refused (no pilot, STOP latched): said beside the buttons
    modeError = e; updateControls();
    clearTimeout(modeErrorTimer);
    modeErrorTimer = setTimeout(() => { modeError = ""; updateControls(); }, 8000);
  });
}
for (const b of document.querySelectorAll("[data-mode]")) b.onclick = () => setMode(b.dataset.mode);
$("record").onclick = () => state && setSetting({ recording: !state.command.recording });
$("maxthrottle").oninput = () => setSetting({ max_throttle: Number($("maxthrottle").value) });
$("constant").onchange = () => setSetting({ constant_throttle: $("constant").checked });
const speedError = (e) => { $("speedlimit-note").textContent = e; };
$("speedlimit").oninput = () => {
  if (Number($("speedlimit").value) > 0) setSetting({ speed_limit: Number($("speedlimit").value) }, speedError);
};
$("nolimit").onchange = () => {
  updateControls();  // the slider shows a position only while a limit is chosen
  setSetting({ speed_limit: $("nolimit").checked ? null : Math.max(0.1, Number($("speedlimit").value)) }, speedError);
};
$("model").onchange = () => { pickedAt = performance.now(); updateControls(); };
$("load").onclick = () => {
  const name = $("model").value;
  if (!name) return;
  modelError = "";
  loadPressed = true;
  pickedAt = -Infinity;  // from now on the list follows the model driving again
  setSetting({ model: name }, (e) => { modelError = e; if (state) syncModel(state.telemetry); });
};
$("model").onfocus = () => sock.emit("models", undefined, (res) => { if (res && res.ok) fillModels(res.models); });
$("behaviornext").onclick = () => { if (role === "driver") send("behavior", { step: 1 }); };

// The emergency stop acts on the first touch of any finger (pointerdown), also while another
// finger holds the joystick: a multi-touch tap makes no click. A click then only comes from the
// keyboard (Enter on the focused button: detail 0); a pointer's own click is ignored. Pressed
// again, it releases the stop: only in the driving browser (a watcher's STOP only ever stops).
function pressStop() {
  const latched = state && state.command.estop;
  if (latched && role !== "driver") { emergencyStop(); notice(VIEWER_LATCHED); return; }
  stats.stops++;
  stopNow();
  send("estop", { on: !latched });
  if (!latched && state) state.command.estop = true;  // until the car confirms: no second toggle
}

// Esc (and a gamepad's B): latch the emergency stop
function emergencyStop() {
  stats.stops++;
  stopNow(); input.source = "keyboard";
  send("estop", { on: true });
  if (state) state.command.estop = true;
}

// Space: throttle to neutral, user mode, constant throttle off (the car's own state, not the page's);
// in a watching browser, whose only stop is STOP, it latches the emergency stop
function spaceStop() {
  if (role !== "driver") { emergencyStop(); return; }
  stats.stops++;
  stopNow(); input.source = "keyboard";
  setSetting({ mode: "user", constant_throttle: false });
  tick();
}
$("estop").addEventListener("pointerdown", (e) => { e.preventDefault(); pressStop(); });
$("estop").addEventListener("click", (e) => { if (e.detail === 0) pressStop(); });

function stopNow() {
  input.keys.clear(); input.steer = 0; input.pad = { active: false, x: 0, y: 0, id: null };
  placeKnob(0, 0);
}

function cycleMode() {
  if (!state) return;
  setMode(MODES[(MODES.indexOf(state.command.mode) + 1) % MODES.length]);
}

// keyboard
const DRIVE_KEYS = { ArrowUp: "up", KeyW: "up", ArrowDown: "down", KeyS: "down",
  ArrowLeft: "left", KeyA: "left", ArrowRight: "right", KeyD: "right" };
const TEXT_INPUTS = new Set(["text", "password", "search", "email", "url", "tel", "number"]);
const typing = (t) => !!t && ((t.tagName === "INPUT" && TEXT_INPUTS.has(t.type)) || t.tagName === "TEXTAREA"
  || t.isContentEditable);
// The stop keys act whatever has focus, and never reach the focused control (Space would toggle a
// checkbox or press a button). The arrows drive and never move a focused slider or list; the
// letters are shortcuts everywhere but in a text field (the pairing token), which keeps its typing.
// Enter and Tab keep their meaning (press the focused button, next control). Captured first, so
// that no control sees a key the page uses.
window.addEventListener("keydown", (e) => {
  if (e.code === "Space" || e.code === "Escape") {
    e.preventDefault();
    if (e.code === "Escape") { emergencyStop(); tick(); } else spaceStop();
    return;
  }
  if (e.ctrlKey || e.metaKey || e.altKey || typing(e.target)) return;
  if (DRIVE_KEYS[e.code]) {
    e.preventDefault();
    input.keys.add(DRIVE_KEYS[e.code]);
    input.source = "keyboard";
    tick();  // send at once: key press to car without waiting for the next tick
    return;
  }
  const shortcut = {
    KeyR: () => $("record").onclick(),
    KeyM: cycleMode,
    KeyL: () => $("behaviornext").onclick(),
    KeyC: () => setSetting({ constant_throttle: !(state && state.command.constant_throttle) }),
  }[e.code] || { "+": () => setSetting({ max_throttle: clamp(((state && state.command.max_throttle) || 0) + 0.05, 0, 1) }),
    "=": () => setSetting({ max_throttle: clamp(((state && state.command.max_throttle) || 0) + 0.05, 0, 1) }),
    "-": () => setSetting({ max_throttle: clamp(((state && state.command.max_throttle) || 0) - 0.05, 0, 1) }) }[e.key];
  if (!shortcut) return;
  e.preventDefault();  // a list's type-ahead, a slider's keys
  if (!e.repeat) shortcut();
}, true);
window.addEventListener("keyup", (e) => {
  if (e.code === "Space") e.preventDefault();  // a focused button or checkbox acts on Space's keyup
  if (DRIVE_KEYS[e.code]) { input.keys.delete(DRIVE_KEYS[e.code]); tick(); }
}, true);
// leaving the page releases every control at once: keys, joystick (the browser may never tell
// the page that a held finger or button went up while it was hidden)
window.addEventListener("blur", () => { input.keys.clear(); });
document.addEventListener("visibilitychange", () => {
  if (document.visibilityState === "hidden") { stopNow(); input.source = "keyboard"; tick(); }
});

// virtual joystick (pointer events: mouse, touch and pen); one pointer holds it
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
  input.pad = { active: true, x, y, id: e.pointerId };
  input.source = "pad";
  placeKnob(x, y);
}
pad.addEventListener("pointerdown", (e) => {
  if (role !== "driver") return;  // a watcher's joystick drives nothing
  if (input.pad.active && input.pad.id !== e.pointerId) return;  // a second finger on the pad
  pad.setPointerCapture(e.pointerId); padMove(e); tick();
});
pad.addEventListener("pointermove", (e) => { if (input.pad.active && input.pad.id === e.pointerId) padMove(e); });
const padUp = (e) => {
  if (input.pad.id !== null && e.pointerId !== input.pad.id) return;
  input.pad = { active: false, x: 0, y: 0, id: null }; placeKnob(0, 0); tick();
};
pad.addEventListener("pointerup", padUp);
pad.addEventListener("pointercancel", padUp);

// browser Gamepad API ("standard" mapping)
let gamepadName = null;
function readGamepad() {
  const pads = navigator.getGamepads ? navigator.getGamepads() : [];
  const gp = Array.from(pads || []).find((p) => p && p.connected);
  const name = gp ? gp.id : null;
  if (name !== gamepadName) {
    gamepadName = name;
    $("gamepad").textContent = name ? "gamepad: " + name : "no gamepad";
    $("gamepad").className = "badge" + (name ? " good" : "");
    $("gamepad").title = name || "no gamepad connected to this computer or phone (press a button to wake one)";
  }
  if (!gp) return null;
  const dz = (v) => (Math.abs(v) < DEADZONE ? 0 : v);
  const steer = dz(gp.axes[0] || 0);
  const rt = gp.buttons[7] ? gp.buttons[7].value : 0, lt = gp.buttons[6] ? gp.buttons[6].value : 0;
  const throttle = rt > 0.05 || lt > 0.05 ? rt - lt : -dz(gp.axes[3] || 0);
  const pressed = gp.buttons.map((b) => b.pressed);
  const edge = (i) => pressed[i] && !input.gamepadButtons[i];
  if (edge(1)) emergencyStop();                               // B / circle
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
  if (document.visibilityState === "hidden") { /* a hidden page drives nothing */ }
  else if (input.source === "gamepad" && gp) { angle = gp.angle; throttle = gp.throttle; }
  else if (input.source === "pad" && input.pad.active) { angle = input.pad.x; throttle = -input.pad.y; }
  else { angle = input.steer; throttle = (k.has("up") ? 1 : 0) - (k.has("down") ? 1 : 0); }
  angle = Math.round(clamp(angle, -1, 1) * 1000) / 1000;
  throttle = Math.round(clamp(throttle, -1, 1) * 1000) / 1000;
  stats.angle = angle; stats.throttle = throttle;
  // the knob shows what is sent, whatever drives (keys, gamepad); a held finger places it itself
  if (!input.pad.active) {
    const n = Math.max(1, Math.hypot(angle, throttle));
    placeKnob(role === "driver" ? angle / n : 0, role === "driver" ? -throttle / n : 0);
  }
  if (role === "driver" && sock.connected) {
    sock.emit("drive", { angle, throttle }, (res) => {
      if (res && res.ok === false) { stats.rejected++; stats.lastError = res.error; }
    });
    stats.sent++;
  }
}
setInterval(tick, TICK_MS);
setRole("none");  // nothing may be touched until the car says who drives
sock.open();
