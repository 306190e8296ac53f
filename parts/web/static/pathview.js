// The driver page's path view (path follow): a small top-down map of the recorded path, the car's
// pose with its uncertainty, the target point, and the path buttons. Plain JavaScript, no build step,
// loaded before app.js, which feeds it: setPath() with each "path" message, update() with each
// state message's telemetry.path (null on a car without path follow: the view stays hidden).
// Frame: the path's local metric frame, x to the right, y up (the contract's x east, y north).
"use strict";

const PATH_COLORS = {            // on --map (#0f1215): each >= 3:1 (WCAG 1.4.11, graphics)
  map: "#0f1215", grid: "#262c33", path: "#e8eaed", start: "#1fbf6b", car: "#4d9bff",
  carLost: "#ff6b6b", target: "#f0a020", std: "rgba(77, 155, 255, 0.18)", text: "#e8eaed",
};
const PATH_MIN_SPAN_M = 2.0;     // the map never shows less than 2 m across (a single point)
const PATH_MARGIN_PX = 14;       // room round the drawing (the car's triangle, the target ring)
const CLEAR_CONFIRM_MS = 3000;   // Clear asks for a second press within this time
const PATH_STATE_TEXT = { empty: "no path", recording: "recording", ready: "ready", following: "following",
  done: "done (end of path)", lost: "lost: pose not trustworthy" };

class PathView {
  // els: {section, canvas, state, info, record, buttons (NodeList of [data-path]), note};
  // command(name, onError): sends a path button to the car
  constructor(els, command) {
    this.els = els;
    this.command = command;
    this.path = null;            // the last "path" message: {version, xy: [x0, y0, ...], points, step}
    this.t = null;               // the last telemetry.path
    this.enabled = false;
    this.clearArmed = 0;         // timer of Clear's confirmation, 0 when not asked
    this.drawn = null;           // what the last draw put where (read by the tests), canvas pixels
    this.ctx = els.canvas.getContext("2d");
    new ResizeObserver(() => this.draw()).observe(els.canvas);
    els.record.onclick = () => this.press("record");
    for (const b of els.buttons) b.onclick = () => this.press(b.dataset.path);
  }

  press(name) {
    if (!this.enabled) return;
    if (name === "clear" && !this.clearArmed) {  // a recorded, unsaved path is not lost by one slip
      this.armClear(true);
      return;
    }
    if (name === "clear") this.armClear(false);
    this.note("");
    this.command(name, (e) => this.note(e));
  }

  armClear(on) {
    const b = [...this.els.buttons].find((x) => x.dataset.path === "clear");
    clearTimeout(this.clearArmed);
    this.clearArmed = on ? setTimeout(() => this.armClear(false), CLEAR_CONFIRM_MS) : 0;
    b.textContent = on ? "Clear? Press again" : "Clear";
    b.classList.toggle("confirm", on);
  }

  note(text) {
    this.els.note.textContent = text || "";
    clearTimeout(this.noteTimer);
    if (text) this.noteTimer = setTimeout(() => { this.els.note.textContent = ""; }, 8000);
  }

  setEnabled(on) {
    this.enabled = on;
    this.els.record.disabled = !on;
    for (const b of this.els.buttons) b.disabled = !on;
    if (!on && this.clearArmed) this.armClear(false);
  }

  setPath(msg) {
    this.path = msg;
    this.draw();
  }

  update(t) {
    this.t = t;
    this.els.section.hidden = t === null && this.path === null;
    document.body.classList.toggle("haspath", !this.els.section.hidden);  // the desktop layout makes room
    if (this.els.section.hidden) return;
    const state = t && t.state;
    const label = state ? PATH_STATE_TEXT[state] || state : "–";
    if (this.els.state.textContent !== label) this.els.state.textContent = label;  // a live region: on change only
    this.els.state.className = "pathstate " + (state || "");
    const rec = state === "recording";
    // a toggle: its name stays, aria-pressed and its colour say whether it records
    this.els.record.setAttribute("aria-pressed", String(rec));
    this.els.record.classList.toggle("on", rec);
    this.draw();
  }

  // the path's points as [[x, y], ...]
  points() {
    const xy = (this.path && this.path.xy) || [];
    const out = [];
    for (let i = 0; i + 1 < xy.length; i += 2) out.push([xy[i], xy[i + 1]]);
    return out;
  }

  describe(pts) {
    const t = this.t || {};
    let length = 0;
    for (let i = 1; i < pts.length; i++) length += Math.hypot(pts[i][0] - pts[i - 1][0], pts[i][1] - pts[i - 1][1]);
    const n = this.path ? this.path.points : 0;
    const parts = [n ? `${n} points, ${length.toFixed(1)} m` : "no path"];
    if (t.x !== null && t.x !== undefined) {
      const heading = t.angle === null ? "" : `, heading ${Math.round(t.angle * 180 / Math.PI)}°`;
      parts.push(`car at ${t.x.toFixed(2)}, ${t.y.toFixed(2)} m${heading}`
        + (t.std === null ? "" : ` ±${t.std.toFixed(2)} m`) + (t.source ? ` (${t.source})` : "")
        + (t.ok === false ? " — pose lost" : ""));
    }
    if (t.cte !== null && t.cte !== undefined) parts.push(`cross-track ${t.cte >= 0 ? "+" : ""}${t.cte.toFixed(2)} m`);
    if (t.target) parts.push(`target ${t.target[0].toFixed(2)}, ${t.target[1].toFixed(2)} m`);
    return parts;
  }

  draw() {
    const { canvas } = this.els;
    if (this.els.section.hidden) return;
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(canvas.clientWidth * dpr)), h = Math.max(1, Math.round(canvas.clientHeight * dpr));
    if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
    const ctx = this.ctx, t = this.t || {}, pts = this.points();
    const pose = t.x !== null && t.x !== undefined ? [t.x, t.y] : null;
    // auto-fit: the path, the car and the target, centred, the same scale on both axes
    const all = pts.concat(pose ? [pose] : [], t.target ? [t.target] : []);
    let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
    for (const [x, y] of all) { x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, y); y1 = Math.max(y1, y); }
    if (!all.length) { x0 = y0 = -1; x1 = y1 = 1; }
    const m = PATH_MARGIN_PX * dpr;
    const span = Math.max(PATH_MIN_SPAN_M, x1 - x0, y1 - y0);
    const scale = Math.min((w - 2 * m) / Math.max(span, x1 - x0), (h - 2 * m) / Math.max(span, y1 - y0));
    const cx = (x0 + x1) / 2, cy = (y0 + y1) / 2;
    const toPx = (x, y) => [w / 2 + (x - cx) * scale, h / 2 - (y - cy) * scale];
    this.toPx = toPx;
    ctx.fillStyle = PATH_COLORS.map;
    ctx.fillRect(0, 0, w, h);
    const drawn = { version: this.path ? this.path.version : null, points: pts.length, scale, car: null,
      heading: null, target: null, stdPx: null, bar: null, dpr };
    // the path, its start marked
    if (pts.length) {
      ctx.strokeStyle = PATH_COLORS.path; ctx.lineWidth = 2 * dpr; ctx.lineJoin = "round"; ctx.lineCap = "round";
      ctx.beginPath();
      pts.forEach(([x, y], i) => { const [px, py] = toPx(x, y); if (i) ctx.lineTo(px, py); else ctx.moveTo(px, py); });
      ctx.stroke();
      const [sx, sy] = toPx(pts[0][0], pts[0][1]);
      ctx.fillStyle = PATH_COLORS.start; ctx.beginPath(); ctx.arc(sx, sy, 4 * dpr, 0, 2 * Math.PI); ctx.fill();
    }
    // the target point, and the line the car steers along to it
    if (t.target) {
      const [tx, ty] = toPx(t.target[0], t.target[1]);
      if (pose) {
        const [px, py] = toPx(pose[0], pose[1]);
        ctx.strokeStyle = PATH_COLORS.target; ctx.lineWidth = 1 * dpr; ctx.setLineDash([4 * dpr, 4 * dpr]);
        ctx.beginPath(); ctx.moveTo(px, py); ctx.lineTo(tx, ty); ctx.stroke(); ctx.setLineDash([]);
      }
      ctx.strokeStyle = PATH_COLORS.target; ctx.lineWidth = 2.5 * dpr;
      ctx.beginPath(); ctx.arc(tx, ty, 5 * dpr, 0, 2 * Math.PI); ctx.stroke();
      drawn.target = [tx, ty];
    }
    // the car: its 1-sigma circle, then an oriented triangle (dashed and red when the pose is lost)
    if (pose) {
      const [px, py] = toPx(pose[0], pose[1]);
      if (t.std !== null && t.std > 0) {
        const r = t.std * scale;
        ctx.fillStyle = PATH_COLORS.std; ctx.strokeStyle = PATH_COLORS.car; ctx.lineWidth = 1 * dpr;
        ctx.beginPath(); ctx.arc(px, py, r, 0, 2 * Math.PI); ctx.fill(); ctx.stroke();
        drawn.stdPx = r;
      }
      const a = t.angle, len = 9 * dpr;
      const tip = (da, l) => [px + Math.cos(a + da) * l, py - Math.sin(a + da) * l];  // y up on the map
      const lost = t.ok === false;
      ctx.fillStyle = lost ? PATH_COLORS.carLost : PATH_COLORS.car;
      ctx.strokeStyle = "#ffffff"; ctx.lineWidth = 1.5 * dpr;
      if (lost) ctx.setLineDash([3 * dpr, 2 * dpr]);
      ctx.beginPath();
      if (a === null || a === undefined) ctx.arc(px, py, len * 0.7, 0, 2 * Math.PI);  // heading unknown: a dot
      else { ctx.moveTo(...tip(0, len * 1.4)); ctx.lineTo(...tip(2.5, len)); ctx.lineTo(...tip(-2.5, len)); ctx.closePath(); }
      ctx.fill(); ctx.stroke(); ctx.setLineDash([]);
      drawn.car = [px, py]; drawn.heading = a === undefined ? null : a;
    }
    // a metre scale bar: 1, 2 or 5 times a power of ten, about a quarter of the width
    const target = (w / 4) / scale, p = Math.pow(10, Math.floor(Math.log10(target)));
    const bar = [1, 2, 5, 10].map((k) => k * p).reduce((b, v) => (Math.abs(v - target) < Math.abs(b - target) ? v : b));
    const bx = m, by = h - m * 0.6, bw = bar * scale;
    ctx.strokeStyle = PATH_COLORS.text; ctx.lineWidth = 2 * dpr;
    ctx.beginPath(); ctx.moveTo(bx, by - 4 * dpr); ctx.lineTo(bx, by); ctx.lineTo(bx + bw, by); ctx.lineTo(bx + bw, by - 4 * dpr); ctx.stroke();
    ctx.fillStyle = PATH_COLORS.text; ctx.font = `${11 * dpr}px system-ui, sans-serif`;
    ctx.fillText(bar >= 1 ? `${+bar.toFixed(0)} m` : `${Math.round(bar * 100)} cm`, bx + bw + 4 * dpr, by);
    drawn.bar = bar;
    this.drawn = drawn;
    // the same in words, for a screen reader and beside the map
    const words = this.describe(pts);
    this.els.info.textContent = words.slice(1).join(" · ") || "no pose";
    canvas.setAttribute("aria-label", "Map of the path: " + words.join("; "));
  }
}
