/* Trainer console: a single page over the console's JSON API (vehicle/app/console/api.py).
   Pages are hash routes; live job events arrive over Server-Sent Events (/api/events). */
"use strict";

// ---------------------------------------------------------------------------------------------
// Small helpers
// ---------------------------------------------------------------------------------------------
const $ = (sel, root = document) => root.querySelector(sel);
const main = $("#main");

/** Children without null/false/undefined, arrays flattened (DOM methods would print "null"). */
function nodes(children) {
  return children.flat(Infinity).filter(c => c !== null && c !== undefined && c !== false)
    .map(c => (c instanceof Node ? c : document.createTextNode(String(c))));
}
function show(...children) { main.replaceChildren(...nodes(children)); }

/** h("div", {class: "x", onclick: f}, child, "text", [children]) -> Element */
function h(tag, attrs, ...children) {
  const el = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (v === null || v === undefined || v === false) continue;
    if (k.startsWith("on")) el.addEventListener(k.slice(2), v);
    else if (k === "class") el.className = v;
    else if (k === "html") el.innerHTML = v;
    else if (k === "value" && (tag === "input" || tag === "textarea" || tag === "select")) el.value = v;
    else if (k === "checked" || k === "disabled" || k === "selected" || k === "hidden") el[k] = !!v;
    else el.setAttribute(k, v === true ? "" : v);
  }
  el.append(...nodes(children));
  return el;
}

class ApiError extends Error {
  constructor(status, body) {
    super((body && body.error) || `HTTP ${status}`);
    this.status = status; this.field = body && body.field; this.errors = (body && body.errors) || {};
  }
}

async function api(method, path, body) {
  const opts = { method, headers: {}, credentials: "same-origin" };
  if (body !== undefined) { opts.headers["Content-Type"] = "application/json"; opts.body = JSON.stringify(body); }
  const resp = await fetch(path, opts);
  const type = resp.headers.get("Content-Type") || "";
  const data = type.includes("application/json") ? await resp.json() : null;
  if (!resp.ok) throw new ApiError(resp.status, data);
  return data;
}

function toast(text, bad = false) {
  const t = $("#toast");
  t.textContent = text; t.className = "toast" + (bad ? " bad" : ""); t.hidden = false;
  clearTimeout(toast.timer);
  toast.timer = setTimeout(() => { t.hidden = true; }, bad ? 6000 : 3000);
}

/** A confirmation dialog; resolves true when the user confirms. */
function confirmDialog(title, body, okText = "Confirm", danger = true) {
  const dlg = $("#modal");
  $("#modal-title").textContent = title;
  const b = $("#modal-body"); b.replaceChildren(...[].concat(body).map(x => typeof x === "string" ? h("p", {}, x) : x));
  const ok = $("#modal-ok"); ok.textContent = okText; ok.className = danger ? "danger" : "primary";
  return new Promise(resolve => {
    dlg.onclose = () => resolve(dlg.returnValue === "ok");
    dlg.returnValue = "";
    dlg.showModal();
  });
}

const fmt = {
  num(v, d = 3) { return v === null || v === undefined || Number.isNaN(v) ? "–" : Number(v).toFixed(d); },
  int(v) { return v === null || v === undefined ? "–" : Number(v).toLocaleString(); },
  bytes(b) { if (b == null) return "–"; const u = ["B", "KB", "MB", "GB"]; let i = 0; while (b >= 1000 && i < 3) { b /= 1000; i++; } return `${b.toFixed(i ? 1 : 0)} ${u[i]}`; },
  dur(s) { if (s == null) return "–"; s = Math.round(s); const m = Math.floor(s / 60), r = s % 60; return m ? `${m} min ${r} s` : `${r} s`; },
  eta(s) { if (s == null) return "–"; s = Math.round(s); const hr = Math.floor(s / 3600), m = Math.floor(s % 3600 / 60), r = s % 60;
    return hr ? `${hr} h ${m} min` : m ? `${m} min ${r} s` : `${r} s`; },
  when(iso) { if (!iso) return "–"; const d = new Date(iso); return d.toLocaleString(); },
  pct(v) { return v === null || v === undefined ? "–" : `${Number(v).toFixed(1)} %`; },
  /** a share 0..1 (an evaluation's completion: the asked laps driven) as "50 %" */
  share(v) { return v === null || v === undefined ? "–" : `${(100 * Number(v)).toFixed(0)} %`; },
  /** "1 lap", "2 laps", "1,200 records" */
  n(count, word) { return `${fmt.int(count)} ${word}${Number(count) === 1 ? "" : "s"}`; },
};

/** On a phone, table rows read as cards: every cell gets its column's name as a label. */
function cardify(table) {
  const names = [...table.querySelectorAll("thead th")].map(th => th.textContent);
  table.classList.add("cardify");
  table.querySelectorAll("tbody tr").forEach(tr => [...tr.children].forEach((td, i) => { if (names[i]) td.dataset.label = names[i]; }));
  return table;
}

function statusPill(s) { return h("span", { class: `status ${s}` }, s); }

function fieldError(form, name, message) {
  const err = form.querySelector(`[data-err="${name}"]`);
  const input = form.querySelector(`[name="${name}"]`);
  if (err) err.textContent = message || "";
  if (input) input.classList.toggle("invalid", !!message);
}

function showErrors(form, e) {
  if (!form._clearsErrors) {  // a field's error goes as soon as the user changes the field
    form._clearsErrors = true;
    form.addEventListener("input", ev => { if (ev.target.name) fieldError(form, ev.target.name, ""); });
  }
  form.querySelectorAll("[data-err]").forEach(x => { x.textContent = ""; });
  form.querySelectorAll(".invalid").forEach(x => x.classList.remove("invalid"));
  const errors = Object.assign({}, e.errors || {});
  if (e.field) errors[e.field] = e.message;
  let shown = false;
  for (const [k, v] of Object.entries(errors)) {
    if (form.querySelector(`[data-err="${k}"]`)) { fieldError(form, k, v); shown = true; }
  }
  const general = form.querySelector('[data-err="_form"]');
  if (!shown || (!Object.keys(errors).length && general)) {
    if (general) general.textContent = e.message; else toast(e.message, true);
  }
}

function field(label, input, name, help) {
  return h("label", { class: "field" }, h("span", { class: "name" }, label), input,
    help ? h("div", { class: "help" }, help) : null, h("div", { class: "err", "data-err": name }));
}

// ---------------------------------------------------------------------------------------------
// Charts (uPlot, served from the package)
// ---------------------------------------------------------------------------------------------
const COLORS = { loss: "#1f6feb", val: "#d9480f", running: "rgba(31,111,235,0.35)", angle: "#1f6feb", throttle: "#2f9e44", bar: "#5b7bd5" };

function chartWidth(el) { return Math.max(200, Math.floor(el.getBoundingClientRect().width || el.parentNode.clientWidth || 600)); }

/** A chart that follows its container's width. */
function makeChart(el, opts, data) {
  const u = new uPlot(Object.assign({ width: chartWidth(el), height: opts.height || 240 }, opts), data, el);
  // resize on the next frame: resizing inside the observer's callback can make the browser report
  // "ResizeObserver loop completed with undelivered notifications" as a page error
  let pending = 0;
  const ro = new ResizeObserver(() => {
    cancelAnimationFrame(pending);
    pending = requestAnimationFrame(() => { const w = chartWidth(el); if (Math.abs(w - u.width) > 2) u.setSize({ width: w, height: u.height }); });
  });
  ro.observe(el);
  u._ro = ro;
  el._uplot = u;  // tests and the console's own code read the chart's data from its element
  return u;
}

/** The loss chart: per-epoch loss and val_loss; with ``batches`` ([fractional epoch, running loss]
    of a run) also the running loss, so the curve moves within a long epoch. */
function lossChart(el, epochs, height = 260, batches = null) {
  const series = [{ label: "epoch", value: (u, v) => v == null ? "--" : fmt.num(v, 2) },
    { label: "loss", stroke: COLORS.loss, width: 2, spanGaps: true, points: { show: true, size: 5 } },
    { label: "val_loss", stroke: COLORS.val, width: 2, spanGaps: true, points: { show: true, size: 5 } }];
  if (batches) series.push({ label: "running loss", stroke: COLORS.running, width: 1, spanGaps: true, points: { show: false } });
  return makeChart(el, {
    height, scales: { x: { time: false } }, legend: { live: true },
    axes: [{ label: "epoch", incrs: [1, 2, 5, 10, 20, 50, 100, 200, 500] }, { label: "loss", size: 60 }],
    series,
  }, lossData(epochs, batches));
}

function lossData(epochs, batches = null) {
  if (!batches) return [epochs.map(e => e.epoch), epochs.map(e => e.train_loss), epochs.map(e => e.val_loss)];
  // one x axis for both: the epochs' ends (whole numbers) and the batches (fractions), in order
  const rows = new Map();
  const row = x => { if (!rows.has(x)) rows.set(x, [x, null, null, null]); return rows.get(x); };
  for (const e of epochs) { const r = row(e.epoch); r[1] = e.train_loss; r[2] = e.val_loss; }
  for (const [x, loss] of batches) { const r = row(x); if (r[3] === null) r[3] = loss; }
  const sorted = [...rows.values()].sort((a, b) => a[0] - b[0]);
  return [0, 1, 2, 3].map(i => sorted.map(r => r[i]));
}

function histogramChart(el, counts, small = true) {
  const n = counts.length, xs = counts.map((_, i) => -1 + (2 * i + 1) / n);
  const bars = uPlot.paths.bars({ size: [0.92, 100] });
  if (small) {
    return new uPlot({ width: 130, height: 46, legend: { show: false }, cursor: { show: false },
      scales: { x: { time: false, range: [-1, 1] }, y: { range: (u, lo, hi) => [0, Math.max(1, hi)] } },
      axes: [{ show: false }, { show: false }],
      series: [{}, { fill: COLORS.bar, stroke: COLORS.bar, paths: bars, points: { show: false } }] }, [xs, counts], el);
  }
  return makeChart(el, {
    height: 200,
    legend: { show: !small }, cursor: { show: !small }, scales: { x: { time: false, range: [-1, 1] }, y: { range: (u, lo, hi) => [0, Math.max(1, hi)] } },
    axes: small ? [{ show: false }, { show: false }] : [{ label: "steering" }, { label: "records", size: 60 }],
    series: [{ label: "steering" }, { label: "records", fill: COLORS.bar, stroke: COLORS.bar, paths: bars, points: { show: false } }],
  }, [xs, counts]);
}

// ---------------------------------------------------------------------------------------------
// Live events (Server-Sent Events): job progress for every page that shows jobs
// ---------------------------------------------------------------------------------------------
const live = {
  source: null, handlers: new Set(), jobs: [],
  start() {
    if (this.source) this.source.close();
    const es = new EventSource("api/events");
    this.source = es;
    es.onopen = () => $("#conn").classList.add("on");
    es.onerror = () => { $("#conn").classList.remove("on"); };
    es.onmessage = m => {
      let ev; try { ev = JSON.parse(m.data); } catch (e) { return; }
      if (ev.event === "hello") { this.jobs = ev.jobs; updateRunBadge(); }
      if (ev.event === "status" && ev.summary) {
        const i = this.jobs.findIndex(j => j.id === ev.job);
        if (i >= 0) this.jobs[i] = ev.summary; else this.jobs.unshift(ev.summary);
        updateRunBadge();
      }
      for (const f of this.handlers) { try { f(ev); } catch (e) { console.error(e); } }
    };
  },
  on(f) { this.handlers.add(f); return () => this.handlers.delete(f); },
};

function updateRunBadge() {
  const active = live.jobs.filter(j => j.status === "running" || j.status === "queued" || j.status === "cancelling").length;
  const b = $("#run-badge"); b.hidden = !active; b.textContent = active;
}

// ---------------------------------------------------------------------------------------------
// Router
// ---------------------------------------------------------------------------------------------
let info = null;          // /api/info, loaded once
let cleanup = [];         // functions to run when leaving a page

function parseHash() {
  const raw = location.hash.replace(/^#/, "") || "/";
  const [path, query] = raw.split("?");
  return { parts: path.split("/").filter(Boolean).map(decodeURIComponent), query: new URLSearchParams(query || "") };
}

async function route() {
  for (const f of cleanup) { try { f(); } catch (e) { console.error(e); } }
  cleanup = [];
  const { parts, query } = parseHash();
  document.querySelectorAll("nav a").forEach(a => a.classList.toggle("active", a.dataset.nav === (parts[0] || "")));
  show(h("p", { class: "muted" }, "Loading…"));
  try {
    if (!info) { info = await api("GET", "api/info"); $("#car-name").textContent = info.car_name; }
    const [a, b, c] = parts;
    if (!a) await pageHome();
    else if (a === "datasets" && !b) await pageDatasets();
    else if (a === "datasets" && b === "add") await pageAddDataset(query);
    else if (a === "datasets" && b === "import") await pageImport();
    else if (a === "datasets" && c === "edit") await pageEditDataset(b);
    else if (a === "datasets") await pageDataset(b);
    else if (a === "train") await pageTrain(query);
    else if (a === "runs" && !b) await pageRuns();
    else if (a === "runs") await pageRun(b);
    else if (a === "models" && !b) await pageModels();
    else if (a === "models" && c === "edit") await pageEditModel(b);
    else if (a === "models") await pageEditModel(b);
    else if (a === "leaderboard") await pageLeaderboard(query);
    else if (a === "cars") await pageCars();
    else show(h("h1", {}, "Not found"), h("p", {}, h("a", { href: "#/" }, "Home")));
  } catch (e) {
    show(h("h1", {}, "Something went wrong"), h("p", { class: "err" }, e.message),
      h("p", {}, h("a", { href: "#/" }, "Home")));
  }
  main.focus({ preventScroll: true });
}

function go(hash) { if (location.hash === hash) route(); else location.hash = hash; }

// ---------------------------------------------------------------------------------------------
// Home
// ---------------------------------------------------------------------------------------------
async function pageHome() {
  const [datasets, models] = await Promise.all([api("GET", "api/datasets"), api("GET", "api/models")]);
  const live_ = datasets.filter(d => !d.deleted);
  const records = live_.reduce((s, d) => s + ((d.stats && d.stats.records) || 0), 0);
  const running = live.jobs.find(j => j.status === "running" || j.status === "cancelling");
  show(
    h("h1", {}, `Trainer console · ${info.car_name}`),
    h("div", { class: "cards" },
      h("a", { class: "card", href: "#/datasets", id: "home-datasets" }, h("h2", {}, "Datasets"),
        h("p", {}, `${fmt.n(live_.length, "dataset")}, ${fmt.n(records, "record")}`), h("p", { class: "muted small" }, "Browse, label, clean and import recordings.")),
      h("a", { class: "card", href: "#/train", id: "home-train" }, h("h2", {}, "Train"),
        h("p", { class: "muted small" }, "The training wizard: model type, data, every hyper-parameter, augmentations.")),
      h("a", { class: "card", href: "#/models", id: "home-models" }, h("h2", {}, "Models"),
        h("p", {}, fmt.n(models.length, "model")), h("p", { class: "muted small" }, "Comments, curves, export, evaluation in the simulator.")),
      h("a", { class: "card", href: "#/leaderboard", id: "home-leaderboard" }, h("h2", {}, "Leaderboard"),
        h("p", { class: "muted small" }, "Your models ranked by how they drive on the same tracks."))),
    running ? h("div", { class: "card" }, h("div", { class: "spread" }, h("div", {}, "Running: ", h("a", { href: `#/runs/${running.id}` }, running.title)), statusPill(running.status))) : null,
    h("p", { class: "muted small" }, `Car folder ${info.car} · data ${info.data_path} · models database ${info.db}`));
}

// ---------------------------------------------------------------------------------------------
// Datasets
// ---------------------------------------------------------------------------------------------
function thumbs(d) {
  const st = d.stats;
  if (!st || !st.thumbnails.length) return h("span", { class: "muted small" }, st ? "no images" : "");
  return h("div", { class: "thumbs" }, st.thumbnails.map(i => h("img", { src: `api/datasets/${d.id}/images/${i}`, alt: `record ${i}`, loading: "lazy" })));
}

async function pageDatasets() {
  const datasets = await api("GET", "api/datasets");
  const liveSets = datasets.filter(d => !d.deleted), deleted = datasets.filter(d => d.deleted);
  const selected = new Set();
  const trainSel = h("button", { class: "primary", id: "train-selected", disabled: true,
    onclick: () => go(`#/train?datasets=${[...selected].join(",")}`) }, "Train on selected");
  const charts = [];
  const rows = liveSets.map(d => {
    const st = d.stats || {};
    const hist = h("div", { class: "hist" });
    if (d.stats) charts.push(() => histogramChart(hist, d.stats.histogram));
    const cb = h("input", { type: "checkbox", "aria-label": `select ${d.name}`, "data-select": d.id,
      disabled: !d.stats || !d.stats.records,
      onchange: e => { e.target.checked ? selected.add(d.id) : selected.delete(d.id); trainSel.disabled = !selected.size; } });
    return h("tr", { "data-dataset": d.name },
      h("td", {}, cb),
      h("td", {}, h("a", { href: `#/datasets/${d.id}`, class: "ds-name" }, d.name),
        d.in_data_folder ? null : h("div", { class: "muted small" }, d.path),
        d.error ? h("div", { class: "err" }, d.error) : null,
        d.models.length ? h("div", { class: "muted small" }, `${d.models.length} model${d.models.length > 1 ? "s" : ""}`) : null),
      h("td", { class: "ds-label" }, d.label || ""),
      h("td", { class: "num" }, fmt.int(st.records), st.deleted_records ? h("div", { class: "muted small" }, `${st.deleted_records} deleted`) : null),
      h("td", { class: "num" }, st.duration_s != null ? fmt.dur(st.duration_s) : "–"),
      h("td", { class: "num" }, st.sessions ?? "–"),
      h("td", { class: "num" }, fmt.bytes(st.size_bytes)),
      h("td", {}, thumbs(d)),
      h("td", {}, hist),
      h("td", { class: "ds-comment" }, d.comment || ""),
      h("td", { class: "actions-cell" },
        h("a", { class: "button small", href: `#/datasets/${d.id}/edit`, "data-action": "edit" }, "Edit"), " ",
        d.stats && d.stats.records ? h("a", { class: "button small", href: `#/train?datasets=${d.id}`, "data-action": "train" }, "Train") : null, " ",
        d.error && !d.stats ? h("button", { class: "small", "data-action": "forget", onclick: () => forgetDataset(d) }, "Remove from list")
          : h("button", { class: "small", "data-action": "delete", onclick: () => deleteDataset(d) }, "Delete")));
  });
  show(
    h("div", { class: "spread" }, h("h1", {}, "Datasets"),
      h("div", { class: "row" }, h("a", { class: "button", href: "#/datasets/add", id: "add-dataset" }, "Add dataset"),
        h("a", { class: "button", href: "#/datasets/import", id: "import-udacity" }, "Import Udacity recording"), trainSel)),
    liveSets.length ? h("div", { class: "table-wrap" }, cardify(h("table", { id: "datasets" },
      h("thead", {}, h("tr", {}, ["", "Name", "Track / label", "Records", "Duration", "Sessions", "Size", "Frames", "Steering", "Comment", ""]
        .map((t, i) => h("th", { class: [3, 4, 5, 6].includes(i) ? "num" : "" }, t)))),
      h("tbody", {}, rows))))
      : h("div", { class: "card" }, h("p", {}, "No datasets yet. Record with ", h("span", { class: "mono" }, "manage.py drive"),
        ", or add one here."), h("p", { class: "muted small" }, `Tubs in ${info.data_path} are listed automatically.`)),
    deleted.length ? h("div", {}, h("h2", {}, "Deleted"), h("p", { class: "muted small" },
      "Soft-deleted datasets: every record is marked deleted in the tub (training skips them). Restore them, or remove them from the disk."),
    h("div", { class: "table-wrap" }, h("table", { id: "deleted-datasets" }, h("tbody", {}, deleted.map(d => h("tr", { class: "deleted-row", "data-dataset": d.name },
      h("td", {}, d.name), h("td", { class: "muted small" }, `deleted ${fmt.when(d.deleted)}`),
      h("td", { class: "actions-cell" },
        h("button", { class: "small", "data-action": "restore", onclick: () => restoreDataset(d) }, "Restore"), " ",
        h("button", { class: "small danger", "data-action": "purge", onclick: () => purgeDataset(d) }, "Remove from disk")))))))) : null);
  charts.forEach(f => f());
}

async function deleteDataset(d) {
  const models = d.models.length ? [`${d.models.length} model(s) were trained on it; they keep working.`] : [];
  if (!await confirmDialog(`Delete ${d.name}?`, [`All ${fmt.int(d.stats ? d.stats.records : 0)} records of ${d.name} will be marked deleted: training skips them and it leaves this list. You can restore it from "Deleted" below until you remove it from the disk.`, ...models], "Delete")) return;
  try { await api("POST", `api/datasets/${d.id}/delete`); toast(`${d.name} deleted`); } catch (e) { toast(e.message, true); }
  go("#/datasets");
}

async function restoreDataset(d) {
  try { await api("POST", `api/datasets/${d.id}/restore`); toast(`${d.name} restored`); } catch (e) { toast(e.message, true); }
  go("#/datasets");
}

async function purgeDataset(d) {
  if (!await confirmDialog(`Remove ${d.name} from the disk?`, [`The folder ${d.path} and all its images are deleted for good. This cannot be undone.`], "Remove from disk")) return;
  try { await api("DELETE", `api/datasets/${d.id}`); toast(`${d.name} removed from the disk`); } catch (e) { toast(e.message, true); }
  go("#/datasets");
}

async function forgetDataset(d) {
  if (!await confirmDialog(`Remove ${d.name} from the list?`, [`Its folder ${d.path} is missing. The console forgets it; nothing on the disk changes.`], "Remove")) return;
  try { await api("POST", `api/datasets/${d.id}/forget`); } catch (e) { toast(e.message, true); }
  go("#/datasets");
}

function datasetNamesList(datasets) {
  return h("datalist", { id: "dataset-folders" }, datasets.map(d => h("option", { value: d.name })));
}

async function pageAddDataset(query) {
  const datasets = await api("GET", "api/datasets");
  const mode = query.get("mode") === "register" ? "register" : "create";
  const form = h("form", { class: "card", id: "add-form", novalidate: true });
  const isCreate = mode === "create";
  form.append(...nodes([
    h("div", { class: "choices", style: "margin-bottom:.8rem" },
      h("label", {}, h("input", { type: "radio", name: "mode", value: "create", checked: isCreate, onchange: () => go("#/datasets/add") }), "Folder in the data folder (new or existing)"),
      h("label", {}, h("input", { type: "radio", name: "mode", value: "register", checked: !isCreate, onchange: () => go("#/datasets/add?mode=register") }), "Existing tub anywhere (by path)")),
    isCreate ? field("Dataset folder name", h("input", { type: "text", name: "name", list: "dataset-folders", autocomplete: "off", placeholder: "e.g. oval_laps" }), "name",
      `A folder of ${info.data_path}. An existing tub is added as it is; a new name creates an empty tub to record into (vehicle sim record --tub, or DATA_PATH with AUTO_CREATE_NEW_TUB = False).`)
      : field("Path of a tub (or of a folder of tubs)", h("input", { type: "text", name: "path", placeholder: "/home/pi/old_car/data/tub_3" }), "path", "Relative paths start at the car folder."),
    datasetNamesList(datasets),
    field("Track / label", h("input", { type: "text", name: "label", placeholder: "e.g. 1, oval, right lane" }), "label", "Which track or driving style; free text."),
    field("Comment", h("textarea", { name: "comment" }), "comment"),
    h("div", { class: "err", "data-err": "_form" }),
    h("div", { class: "row" }, h("a", { class: "button", href: "#/datasets", id: "back" }, "Back"), h("button", { class: "primary", type: "submit", id: "submit" }, "Submit"))]));
  form.onsubmit = async e => {
    e.preventDefault();
    const fd = new FormData(form);
    const body = { action: mode, label: fd.get("label"), comment: fd.get("comment") };
    if (isCreate) body.name = fd.get("name"); else body.path = fd.get("path");
    try { await api("POST", "api/datasets", body); toast("Dataset added"); go("#/datasets"); } catch (err) { showErrors(form, err); }
  };
  show(h("h1", {}, "Add dataset"), form);
}

async function pageImport() {
  const form = h("form", { class: "card", id: "import-form", novalidate: true },
    field("Udacity recording", h("input", { type: "text", name: "source", placeholder: "/home/me/udacity/driving_log.csv" }), "source",
      "driving_log.csv of the Udacity simulator's training mode, or the folder holding it (IMG/ next to it). Left and right cameras are kept."),
    field("New dataset folder name", h("input", { type: "text", name: "name", placeholder: "udacity_track1" }), "name"),
    field("Track / label", h("input", { type: "text", name: "label" }), "label"),
    field("Comment", h("textarea", { name: "comment" }), "comment"),
    h("div", { class: "err", "data-err": "_form" }),
    h("div", { class: "row" }, h("a", { class: "button", href: "#/datasets" }, "Back"), h("button", { class: "primary", type: "submit" }, "Import")));
  form.onsubmit = async e => {
    e.preventDefault();
    const fd = new FormData(form), btn = form.querySelector("button[type=submit]");
    btn.disabled = true; btn.textContent = "Importing…";
    try {
      const d = await api("POST", "api/datasets/import-udacity", Object.fromEntries(fd));
      toast(`Imported ${fmt.int(d.stats && d.stats.records)} records`); go("#/datasets");
    } catch (err) { showErrors(form, err); btn.disabled = false; btn.textContent = "Import"; }
  };
  show(h("h1", {}, "Import a Udacity recording"), form);
}

async function pageEditDataset(id) {
  const [d, datasets] = await Promise.all([api("GET", `api/datasets/${id}`), api("GET", "api/datasets")]);
  const form = h("form", { class: "card", id: "edit-form", novalidate: true },
    field("Dataset folder name", h("input", { type: "text", name: "name", value: d.name, list: "dataset-folders", autocomplete: "off" }), "name", "Renaming renames the folder on the disk; models trained on it keep pointing at it."),
    datasetNamesList(datasets.filter(x => x.id !== d.id)),
    field("Track / label", h("input", { type: "text", name: "label", value: d.label || "" }), "label"),
    field("Comment", h("textarea", { name: "comment" }, d.comment || ""), "comment"),
    h("div", { class: "err", "data-err": "_form" }),
    h("div", { class: "row" }, h("a", { class: "button", href: "#/datasets", id: "back" }, "Back"), h("button", { class: "primary", type: "submit", id: "update" }, "Update")));
  form.onsubmit = async e => {
    e.preventDefault();
    const fd = new FormData(form);
    try { await api("PATCH", `api/datasets/${d.id}`, { name: fd.get("name"), label: fd.get("label"), comment: fd.get("comment") }); toast("Dataset updated"); go("#/datasets"); }
    catch (err) { showErrors(form, err); }
  };
  show(h("h1", {}, `Edit dataset ${d.name}`), form);
}

/** A tub's movie (WebM, made on the console's side the first time, kept while the tub is unchanged). */
function movieCard(d) {
  const slot = h("div", { class: "movie" });
  const button = h("button", { type: "button", id: "play-movie", onclick: () => {
    button.disabled = true; button.textContent = "Making the movie…";
    const video = h("video", { controls: true, autoplay: true, muted: true, playsinline: true, src: `api/datasets/${d.id}/movie` });
    video.addEventListener("loadeddata", () => { button.hidden = true; });
    video.addEventListener("error", async () => {
      let msg = "the movie cannot be played";
      try { await api("GET", `api/datasets/${d.id}/movie`); } catch (e) { msg = e.message; }
      slot.replaceChildren(h("p", { class: "err" }, msg)); button.hidden = true;
    });
    slot.replaceChildren(video);
  } }, "Play the movie");
  return h("div", { class: "card" }, h("h2", {}, "Movie"),
    h("p", { class: "muted small" }, "The frames with the recorded steering (green) and throttle; `vehicle tub movie --model M --salient` adds where a model looks."),
    button, slot);
}

async function pageDataset(id) {
  const [d, series] = await Promise.all([api("GET", `api/datasets/${id}`), api("GET", `api/datasets/${id}/series`).catch(() => null)]);
  const st = d.stats || {};
  const img = h("img", { alt: "frame", id: "frame-img" });
  const frameInfo = h("div", { id: "frame-info", class: "kv" });
  const chartEl = h("div", { class: "chart", id: "series-chart" });
  const histEl = h("div", { class: "chart" });
  const form = h("form", { class: "row", id: "range-form", novalidate: true },
    h("label", {}, "From record ", h("input", { type: "text", name: "start", size: 7, style: "width:7em", inputmode: "numeric" })),
    h("label", {}, "to ", h("input", { type: "text", name: "end", size: 7, style: "width:7em", inputmode: "numeric" })),
    h("button", { type: "button", class: "danger", id: "delete-range", onclick: () => markRange("delete") }, "Delete range"),
    h("button", { type: "button", id: "restore-range", onclick: () => markRange("restore") }, "Restore range"),
    h("span", { class: "err", "data-err": "start" }), h("span", { class: "err", "data-err": "end" }), h("span", { class: "err", "data-err": "_form" }));
  async function markRange(action) {
    const fd = new FormData(form);
    const start = parseInt(fd.get("start"), 10), end = parseInt(fd.get("end"), 10);
    if (Number.isNaN(start) || Number.isNaN(end)) { showErrors(form, { message: "give the first and the last record of the range (drag over the chart)", field: Number.isNaN(start) ? "start" : "end" }); return; }
    try {
      const out = await api("POST", `api/datasets/${d.id}/records`, { action, start, end });
      toast(action === "delete" ? `Records ${start}–${end} deleted` : `Records ${start}–${end} restored` + (out.kept_deleted.length ? ` (${out.kept_deleted.length} without values stay deleted)` : ""));
      route();
    } catch (err) { showErrors(form, err); }
  }
  let selectedIndex = null;
  async function showFrame(index) {
    if (index === null || index === undefined || index === selectedIndex) return;
    selectedIndex = index;
    img.src = `api/datasets/${d.id}/images/${index}`;
    try {
      const rec = await api("GET", `api/datasets/${d.id}/records/${index}`);
      if (selectedIndex !== index) return;
      frameInfo.replaceChildren(h("dt", {}, "record"), h("dd", {}, `${rec.index}${rec.deleted ? " (deleted)" : ""}`),
        ...Object.entries(rec.fields).filter(([k]) => !k.startsWith("cam/")).flatMap(([k, v]) => [h("dt", {}, k), h("dd", {}, typeof v === "number" ? +v.toFixed(4) : JSON.stringify(v))]));
    } catch (e) { frameInfo.textContent = e.message; }
  }
  show(
    h("div", { class: "spread" }, h("h1", {}, `Dataset ${d.name}`), h("div", { class: "row" },
      h("a", { class: "button", href: `#/datasets/${d.id}/edit` }, "Edit"),
      st.records ? h("a", { class: "button primary", href: `#/train?datasets=${d.id}` }, "Train on this") : null)),
    d.error ? h("p", { class: "err" }, d.error) : null,
    h("div", { class: "stats" },
      [["records", fmt.int(st.records)], ["deleted", fmt.int(st.deleted_records)], ["duration", fmt.dur(st.duration_s)], ["sessions", st.sessions ?? "–"],
        ["size", fmt.bytes(st.size_bytes)], ["track / label", d.label || "–"], ["mean steering", fmt.num(st.mean_angle, 3)]]
        .map(([k, v]) => h("div", { class: "stat" }, h("b", {}, v), h("span", {}, k)))),
    d.comment ? h("p", {}, d.comment) : null,
    h("p", { class: "muted small" }, d.path, st.inputs ? ` · fields: ${st.inputs.join(", ")}` : ""),
    h("div", { class: "card" }, h("h2", {}, "Steering and throttle over the records"),
      h("p", { class: "muted small" }, "Move over the chart to see the frames; drag to choose a range, then delete or restore it. Deleted records are shaded red."),
      chartEl, form),
    h("div", { class: "grid2" },
      h("div", { class: "card" }, h("h2", {}, "Frame"), h("div", { class: "frame-view" }, img, frameInfo)),
      h("div", { class: "card" }, h("h2", {}, "Steering histogram"), histEl)),
    st.records ? movieCard(d) : null);
  if (st.histogram) histogramChart(histEl, st.histogram, false);
  if (series && series.index.length) {
    const del = series.deleted.map(x => (x ? 1 : null));
    const u = makeChart(chartEl, {
      height: 260, scales: { x: { time: false }, y: { range: [-1.05, 1.05] }, del: { range: [0, 1] } },
      axes: [{ label: "record" }, { label: "value", size: 50 }],
      cursor: { drag: { x: true, y: false, setScale: false } },
      series: [{ label: "record" },
        { label: "steering", stroke: COLORS.angle, width: 1.5 },
        { label: "throttle", stroke: COLORS.throttle, width: 1.5 },
        { label: "deleted", scale: "del", fill: "rgba(207,34,46,0.18)", stroke: "rgba(207,34,46,0.35)", width: 0, paths: uPlot.paths.stepped({ align: 1 }), points: { show: false } }],
      hooks: {
        setSelect: [u => {
          if (u.select.width < 2) return;
          const a = Math.round(u.posToVal(u.select.left, "x")), b = Math.round(u.posToVal(u.select.left + u.select.width, "x"));
          form.elements.start.value = Math.max(0, a); form.elements.end.value = Math.max(0, b);
        }],
        setCursor: [u => { const i = u.cursor.idx; if (i != null && series.images) { clearTimeout(showFrame.t); showFrame.t = setTimeout(() => showFrame(series.index[i]), 60); } }],
      },
    }, [series.index, series.angle, series.throttle, del]);
    cleanup.push(() => u._ro.disconnect());
    const firstLive = series.index[series.deleted.indexOf(false)];
    if (series.images && firstLive !== undefined) showFrame(firstLive);
  } else {
    chartEl.replaceChildren(h("p", { class: "muted" }, "No records yet."));
  }
}

// ---------------------------------------------------------------------------------------------
// Training wizard
// ---------------------------------------------------------------------------------------------
function hpInput(p, value) {
  const name = p.name;
  if (p.kind === "bool") return h("select", { name, id: `hp-${name}` }, h("option", { value: "true", selected: value === true }, "on"), h("option", { value: "false", selected: value === false }, "off"));
  if (p.kind === "choice") return h("select", { name, id: `hp-${name}` }, p.choices.map(c => h("option", { value: c, selected: c === value }, c)));
  if (p.kind === "multi") return h("div", { class: "choices", id: `hp-${name}` }, p.choices.map(c =>
    h("label", {}, h("input", { type: "checkbox", name, value: c, checked: (value || []).includes(c) }), c)));
  const shown = value === null || value === undefined ? "" : String(value);
  return h("input", { type: "text", name, id: `hp-${name}`, value: shown, autocomplete: "off", spellcheck: "false",
    inputmode: p.kind === "device" ? "text" : "decimal", placeholder: p.optional ? "blank = all" : "" });
}

function hpField(p) {
  return h("label", { class: "field", "data-hp": p.name }, h("span", { class: "name" }, p.label), hpInput(p, p.default),
    h("div", { class: "help" }, `${p.help} ${p.rule[0].toUpperCase()}${p.rule.slice(1)}.`), h("div", { class: "err", "data-err": p.name }));
}

function hpValues(form) {
  const out = {};
  for (const p of info.hyperparams) {
    if (p.kind === "multi") out[p.name] = [...form.querySelectorAll(`input[name="${p.name}"]:checked`)].map(x => x.value);
    else { const el = form.elements[p.name]; if (el) out[p.name] = el.value; }
  }
  return out;
}

async function pageTrain(query) {
  const [datasets, models] = await Promise.all([api("GET", "api/datasets"), api("GET", "api/models")]);
  info = await api("GET", "api/info");  // the default model name changes after each training
  const chosen = new Set((query.get("datasets") || "").split(",").filter(Boolean).map(Number));
  const usable = datasets.filter(d => !d.deleted && d.stats && d.stats.records);
  const form = h("form", { id: "train-form", novalidate: true });
  const groups = {};
  for (const p of info.hyperparams) (groups[p.group] = groups[p.group] || []).push(p);
  const typeParam = info.hyperparams.find(p => p.name === "model_type");
  const typeWarn = h("div", { class: "warn", id: "type-warning" });
  const typeCards = h("div", { class: "types", id: "model-types" }, info.model_types.map(t =>
    h("label", { class: t.name === typeParam.default ? "checked" : "", "data-type": t.name },
      h("div", {}, h("input", { type: "radio", name: "model_type", value: t.name, checked: t.name === typeParam.default }), " ", h("b", {}, t.name)),
      h("div", { class: "small" }, t.doc), h("ul", {}, t.needs.map(n => h("li", {}, n))))));
  const dsList = h("div", { class: "choices", id: "train-datasets" }, usable.map(d =>
    h("label", {}, h("input", { type: "checkbox", name: "datasets", value: d.id, checked: chosen.has(d.id) }),
      `${d.name}`, h("span", { class: "muted small" }, ` (${fmt.int(d.stats.records)} rec${d.label ? ", " + d.label : ""})`))));
  const transferSel = h("select", { name: "transfer", id: "transfer" }, h("option", { value: "" }, "— none: start from random weights —"),
    models.filter(m => m.exists).map(m => h("option", { value: m.name }, `${m.name} (${m.type})`)));
  const preview = h("img", { id: "aug-preview", alt: "augmented frames", hidden: true });
  const previewNote = h("div", { class: "muted small", id: "aug-note" });
  let seed = 0;
  const augFields = (groups.Augmentation || []);
  const recipeSel = h("select", { name: "recipe", id: "recipe" }, h("option", { value: "" }, "— none: this car's settings —"),
    (info.recipes || []).map(r => h("option", { value: r.name }, `${r.name}: ${r.summary}`)));
  const recipeNote = h("div", { class: "muted small", id: "recipe-note" });
  form.append(...nodes([
    h("fieldset", {}, h("legend", {}, "0 · Recipe of a source document"),
      field("Recipe", recipeSel, "recipe", "Fills every field with the values a document states; its preprocessing travels with it. Change any field after choosing."),
      recipeNote),
    h("fieldset", {}, h("legend", {}, "1 · Model type"), typeCards, typeWarn, h("div", { class: "err", "data-err": "model_type" }),
      h("div", { class: "hp-grid" }, (groups.Model || []).filter(p => p.name !== "model_type").map(hpField))),
    h("fieldset", {}, h("legend", {}, "2 · Datasets"), usable.length ? dsList : h("p", {}, "No dataset with records: ", h("a", { href: "#/datasets" }, "add one first"), "."),
      h("div", { class: "err", "data-err": "datasets" })),
    h("fieldset", {}, h("legend", {}, "3 · Start from an existing model (transfer)"),
      field("Transfer from", transferSel, "transfer", "Fine-tune a model you trained before (Track Driver AI's model retraining): its type and preprocessing are kept, its weights are the start.")),
    [["Optimisation", 4], ["Data", 5]].map(([g, n]) => groups[g] ? h("fieldset", {}, h("legend", {}, `${n} · ${g}`),
      h("div", { class: "hp-grid" }, groups[g].map(hpField))) : null),
    h("fieldset", {}, h("legend", {}, "6 · Augmentation"),
      h("div", { class: "grid2" },
        h("div", {}, augFields.filter(p => p.name === "augmentations").map(hpField), h("div", { class: "hp-grid" }, augFields.filter(p => p.name !== "augmentations").map(hpField))),
        h("div", { class: "aug-preview" }, h("div", { class: "spread" }, h("b", {}, "Preview"), h("button", { type: "button", class: "small", id: "aug-shuffle", onclick: () => { seed++; refreshPreview(); } }, "Other draws")),
          h("p", { class: "muted small" }, "Each row: a frame of the chosen data, then augmented copies with their steering label."), preview, previewNote))),
    groups.Hardware ? h("fieldset", {}, h("legend", {}, "7 · Hardware"), h("div", { class: "hp-grid" }, groups.Hardware.map(hpField))) : null,
    h("fieldset", {}, h("legend", {}, "8 · The model"),
      h("div", { class: "grid2" }, field("Model name", h("input", { type: "text", name: "name", id: "model-name", value: info.default_model_name }), "name", `Saved as ${info.models_path}/NAME.pt`),
        field("Comment", h("textarea", { name: "comment", id: "model-comment" }), "comment"))),
    h("div", { class: "err", "data-err": "_form" }),
    h("div", { class: "row" }, h("a", { class: "button", href: "#/datasets" }, "Back"), h("button", { class: "primary", type: "submit", id: "start-training" }, "Start training"))]));

  function selectedDatasets() { return [...form.querySelectorAll('input[name="datasets"]:checked')].map(x => Number(x.value)); }
  function selectedType() { const r = form.querySelector('input[name="model_type"]:checked'); return r ? r.value : null; }

  function checkTypeNeeds() {
    const t = info.model_types.find(x => x.name === selectedType());
    form.querySelectorAll(".types label").forEach(l => l.classList.toggle("checked", l.dataset.type === selectedType()));
    const missing = [];
    if (t) for (const key of t.extra_inputs) for (const id of selectedDatasets()) {
      const d = datasets.find(x => x.id === id);
      if (d && d.stats && !d.stats.inputs.includes(key)) missing.push(`${d.name} has no ${key}`);
    }
    typeWarn.textContent = missing.length ? `${t.name} needs data the chosen datasets lack: ${missing.join("; ")}.` : "";
  }

  function refreshPreview() {
    const ids = selectedDatasets();
    if (!ids.length) { preview.hidden = true; preview.removeAttribute("src"); previewNote.textContent = "Choose a dataset to see augmented frames."; return; }
    const v = hpValues(form), q = new URLSearchParams({ datasets: ids.join(","), seed });
    q.set("augmentations", v.augmentations.join(","));
    for (const p of augFields) if (p.name !== "augmentations") q.set(p.name, v[p.name]);
    previewNote.textContent = v.augmentations.length ? "" : "No augmentation chosen: training uses the frames as recorded.";
    const src = `api/augment-preview?${q}`;
    fetch(src).then(async r => {
      if (!r.ok) { const b = await r.json().catch(() => ({})); preview.hidden = true; previewNote.textContent = b.error || "no preview"; return; }
      const blob = await r.blob(); if (preview.src.startsWith("blob:")) URL.revokeObjectURL(preview.src); preview.src = URL.createObjectURL(blob); preview.hidden = false;
    });
  }

  let validateTimer = null;
  function validateSoon() {
    clearTimeout(validateTimer);
    validateTimer = setTimeout(async () => {
      const hyper = hpValues(form); hyper.model_type = selectedType();
      try {
        const r = await api("POST", "api/train/validate", { hyper });
        for (const p of info.hyperparams) fieldError(form, p.name, r.errors[p.name]);
      } catch (e) { /* shown on submit */ }
    }, 250);
  }

  recipeSel.onchange = () => {
    const r = (info.recipes || []).find(x => x.name === recipeSel.value);
    for (const p of info.hyperparams) {
      if (p.name === "model_type") continue;
      const value = r && p.name in r.values ? r.values[p.name] : p.default;
      if (p.kind === "multi") form.querySelectorAll(`input[name="${p.name}"]`).forEach(c => { c.checked = (value || []).includes(c.value); });
      else if (form.elements[p.name]) form.elements[p.name].value = value === null || value === undefined ? "" : String(value);
    }
    const type = r ? r.model_type : info.hyperparams.find(p => p.name === "model_type").default;
    form.querySelectorAll('input[name="model_type"]').forEach(x => { x.checked = x.value === type; });
    recipeNote.textContent = r ? `${r.document}. Written for ${r.frames} frames; it also sets ${r.other_settings.join(", ")}.` : "";
    checkTypeNeeds(); validateSoon(); refreshPreview();
  };
  transferSel.onchange = () => {
    const m = models.find(x => x.name === transferSel.value);
    form.querySelectorAll('input[name="model_type"]').forEach(r => { r.disabled = !!m; if (m) r.checked = r.value === m.type; });
    checkTypeNeeds();
  };
  let previewTimer = null;
  form.addEventListener("input", e => {
    validateSoon();
    if (e.target.name === "datasets" || e.target.name === "model_type") checkTypeNeeds();
    if (e.target.name === "datasets" || augFields.some(p => p.name === e.target.name)) { clearTimeout(previewTimer); previewTimer = setTimeout(refreshPreview, 300); }
  });
  form.addEventListener("change", e => { if (e.target.type === "checkbox" || e.target.type === "radio" || e.target.tagName === "SELECT") form.dispatchEvent(new Event("input")); });
  form.onsubmit = async e => {
    e.preventDefault();
    const hyper = hpValues(form); hyper.model_type = selectedType();
    const fd = new FormData(form);
    const btn = $("#start-training"); btn.disabled = true;
    try {
      const job = await api("POST", "api/jobs/train", { datasets: selectedDatasets(), hyper, name: fd.get("name"), comment: fd.get("comment"), transfer: fd.get("transfer") || null, recipe: fd.get("recipe") || null });
      go(`#/runs/${job.id}`);
    } catch (err) {
      btn.disabled = false; showErrors(form, err);
      const first = form.querySelector(".err:not(:empty)"); if (first) first.scrollIntoView({ block: "center", behavior: "smooth" });
    }
  };
  show(h("h1", {}, "Training setup"), h("p", { class: "muted" }, "Every field starts at this car's setting (myconfig.py, else the default); the server checks each value with the same rules as ", h("span", { class: "mono" }, "vehicle train"), "."), form);
  checkTypeNeeds(); refreshPreview();
}

// ---------------------------------------------------------------------------------------------
// Runs (jobs)
// ---------------------------------------------------------------------------------------------
async function pageRuns() {
  const jobs = await api("GET", "api/jobs");
  const render = list => h("div", { class: "table-wrap" }, cardify(h("table", { id: "runs" },
    h("thead", {}, h("tr", {}, ["#", "Job", "Status", "Progress", "Queued", "Finished", ""].map(t => h("th", {}, t)))),
    h("tbody", {}, list.map(j => h("tr", { "data-job": j.id },
      h("td", {}, j.id), h("td", {}, h("a", { href: `#/runs/${j.id}` }, j.title), j.message ? h("div", { class: "muted small" }, j.message) : null),
      h("td", {}, statusPill(j.status)), h("td", { class: "small" }, progressText(j)),
      h("td", { class: "small" }, fmt.when(j.created)), h("td", { class: "small" }, fmt.when(j.finished)),
      h("td", {}, j.status === "queued" || j.status === "running" ? h("button", { class: "small", onclick: () => cancelJob(j) }, "Cancel") : null)))))));
  show(h("h1", {}, "Runs"), h("p", { class: "muted" }, "Trainings and evaluations run one at a time, each in its own worker process; the others wait in the queue."),
    jobs.length ? render(jobs) : h("p", {}, "Nothing yet: ", h("a", { href: "#/train" }, "train a model"), "."));
  cleanup.push(live.on(ev => { if (ev.event === "status") route(); }));
}

function progressText(j) {
  const p = j.progress;
  if (!p || j.status !== "running") return j.status === "done" && j.kind === "train" && j.result ? `${j.epochs_done} epochs` : "";
  if (p.event === "batch") return `epoch ${p.epoch}/${p.epochs}, batch ${p.batch}/${p.batches}`;
  if (p.event === "eval_progress" || p.event === "track") return `track ${p.index + 1}/${p.tracks}`;
  return "";
}

async function cancelJob(j) {
  const running = j.status === "running";
  if (!await confirmDialog(`Cancel ${j.title}?`, running ? ["The training stops after the current step. If an epoch has finished, the best model so far is kept and lands in the model manager; before that, no model is saved."] : ["It leaves the queue without running."], "Cancel the job")) return;
  try { await api("POST", `api/jobs/${j.id}/cancel`); toast("Cancelling…"); } catch (e) { toast(e.message, true); }
}

function logLine(l) {
  const t = l.time ? new Date(l.time * 1000).toLocaleTimeString() : "";
  return h("div", { class: l.level || "" }, h("span", { class: "t" }, `${t} `), l.level && l.level !== "INFO" ? `${l.level} ` : "", l.message);
}

async function pageRun(id) {
  let job = await api("GET", `api/jobs/${id}`);
  let seq = job.seq;
  const isTrain = job.kind === "train";
  const statusEl = h("span", { id: "run-status" }), msgEl = h("div", { class: "muted", id: "run-message" });
  const epochBar = h("div"), batchBar = h("div");
  const statEls = {}; const stat = (k, label) => { statEls[k] = h("b", { id: `stat-${k}` }, "–"); return h("div", { class: "stat" }, statEls[k], h("span", {}, label)); };
  const chartEl = h("div", { class: "chart", id: "loss-chart" });
  const logEl = h("div", { class: "log", id: "run-log" }, job.log.map(logLine));
  const cancelBtn = h("button", { id: "cancel-run", onclick: () => cancelJob(job) }, "Cancel");
  const finishBtn = h("a", { class: "button primary", id: "finish", href: isTrain ? "#/models" : `#/models/${encodeURIComponent(job.params.model)}` }, isTrain ? "Finish" : "See the model");
  const resultEl = h("div", { id: "run-result" });
  let chart = null;
  const params = job.params;
  const paramsView = isTrain ? h("details", {}, h("summary", {}, "Parameters"), h("dl", { class: "kv" },
    h("dt", {}, "datasets"), h("dd", {}, params.tubs.map(t => t.split("/").pop()).join(", ")),
    h("dt", {}, "model type"), h("dd", {}, params.model_type || "car default"),
    params.transfer_name ? [h("dt", {}, "transfer from"), h("dd", {}, params.transfer_name)] : null,
    Object.entries(params.hyper).flatMap(([k, v]) => [h("dt", {}, k), h("dd", {}, Array.isArray(v) ? v.join(", ") || "none" : String(v))])))
    : h("p", { class: "muted" }, `Tracks ${params.tracks.join(", ")}, ${fmt.n(params.laps, "lap")} each.`);
  const heading = h("h1", {}, isTrain ? "Training" : "Evaluation");

  function render() {
    statusEl.replaceChildren(statusPill(job.status), job.phase && job.status === "running" ? h("span", { class: "muted small" }, ` ${job.phase}`) : "");
    msgEl.textContent = job.message || "";
    const p = job.progress, done = ["done", "failed", "cancelled", "interrupted"].includes(job.status);
    cancelBtn.hidden = !(job.status === "running" || job.status === "queued");
    finishBtn.hidden = !done;
    heading.textContent = isTrain ? (done ? "Training result" : "Training") : (done ? "Evaluation result" : "Evaluation");
    const r = job.result;
    if (isTrain) {
      const epochs = (p && p.epochs) || job.info.epochs || (params.hyper.epochs ?? "?");
      const epochNow = p && p.event === "batch" ? p.epoch : job.epochs.length;
      statEls.epoch.textContent = `${job.epochs.length && done ? job.epochs.length : epochNow || 0} / ${epochs}`;
      statEls.batch.textContent = p && p.event === "batch" ? `${p.batch} / ${p.batches}` : "–";
      statEls.sps.textContent = p && p.samples_per_s ? Math.round(p.samples_per_s).toLocaleString() : "–";
      statEls.eta.textContent = job.status === "running" ? fmt.eta(job.eta_s) : "–";
      const best = job.epochs.filter(e => e.best).pop();
      statEls.best.textContent = best ? `${fmt.num(best.val_loss ?? best.train_loss, 5)} (epoch ${best.epoch})` : "–";
      statEls.loss.textContent = p && p.loss != null ? fmt.num(p.loss, 5) : "–";
      epochBar.style.width = `${Math.min(100, 100 * job.epochs.length / (Number(epochs) || 1))}%`;
      batchBar.style.width = p && p.event === "batch" ? `${100 * p.batch / p.batches}%` : done ? "100%" : "0";
      if (chart) chart.setData(lossData(job.epochs, job.batches));
    } else if (r && r.overall) {  // finished: the result's figures, not the last progress event's
      const tracks = params.tracks.length;
      statEls.track.textContent = `${tracks} / ${tracks}`;
      statEls.laps.textContent = `${r.overall.laps_completed ?? "–"} / ${params.laps * tracks}`;
      statEls.simtime.textContent = p && p.sim_time != null ? `${p.sim_time.toFixed(0)} s` : "–";
      epochBar.style.width = "100%";
    } else {
      statEls.track.textContent = p && p.tracks ? `${Math.min(p.index + 1, p.tracks)} / ${p.tracks}` : "–";
      statEls.laps.textContent = p && p.laps_target ? `${p.laps} / ${p.laps_target}` : "–";
      statEls.simtime.textContent = p && p.sim_time != null ? `${p.sim_time.toFixed(0)} s` : "–";
      epochBar.style.width = p && p.tracks ? `${100 * (p.index + (p.laps || 0) / (p.laps_target || 1)) / p.tracks}%` : done ? "100%" : "0";
    }
    resultEl.replaceChildren();
    if (r && isTrain) resultEl.append(h("div", { class: "card" }, h("h2", {}, job.status === "cancelled" ? "Cancelled: the best model so far was kept" : "Result"),
      h("p", {}, "Model ", h("a", { href: `#/models/${encodeURIComponent(r.model)}` }, r.model), ` saved (best epoch ${r.metrics.best_epoch} of ${r.metrics.epochs}, val_loss ${fmt.num(r.metrics.best_val_loss, 5)}).`)));
    if (!r && isTrain && job.status === "cancelled") resultEl.append(h("div", { class: "card" }, h("h2", {}, "Cancelled before the first epoch ended"),
      h("p", {}, "No model was saved.")));
    if (r && !isTrain) resultEl.append(evaluationCard({ id: r.evaluation_id, overall: r.overall, per_track: r.per_track, tracks: params.tracks, laps: params.laps, has_picture: true, created: job.finished }));
  }

  show(
    h("div", { class: "spread" }, heading, h("div", { class: "row" }, cancelBtn, finishBtn)),
    h("p", {}, h("b", {}, job.title), " ", statusEl), msgEl,
    h("div", { class: "card" },
      isTrain ? h("div", { class: "stats" }, stat("epoch", "epoch"), stat("batch", "batch"), stat("sps", "samples/s"), stat("eta", "time left (at most)"), stat("loss", "running loss"), stat("best", "best val_loss"))
        : h("div", { class: "stats" }, stat("track", "track"), stat("laps", "laps"), stat("simtime", "simulated time")),
      h("div", { class: "small muted", style: "margin-top:.6rem" }, isTrain ? "epochs" : "progress"), h("div", { class: "bar" }, epochBar),
      isTrain ? [h("div", { class: "small muted" }, "batches of this epoch"), h("div", { class: "bar" }, batchBar)] : null),
    resultEl,
    isTrain ? h("div", { class: "card" }, h("h2", {}, "Loss"), chartEl) : null,
    h("div", { class: "card" }, h("h2", {}, "Log"), logEl),
    paramsView);
  if (isTrain) { job.batches = job.batches || []; chart = lossChart(chartEl, job.epochs, 260, job.batches); cleanup.push(() => chart._ro.disconnect()); }
  logEl.scrollTop = logEl.scrollHeight;
  render();

  cleanup.push(live.on(async ev => {
    if (ev.event === "hello") {  // reconnected: reload the whole state, then go on with the events
      job = await api("GET", `api/jobs/${id}`); seq = job.seq;
      logEl.replaceChildren(...job.log.map(logLine)); render(); return;
    }
    if (ev.job !== job.id || ev.seq <= seq) return;
    seq = ev.seq;
    const stick = logEl.scrollTop + logEl.clientHeight >= logEl.scrollHeight - 20;
    switch (ev.event) {
      case "batch": case "eval_progress": case "track": job.progress = ev; if (ev.event === "batch") addBatchPoint(job, ev); break;
      case "epoch": job.epochs.push(ev); break;
      case "log": case "stderr": logEl.append(logLine(ev)); if (stick) logEl.scrollTop = logEl.scrollHeight; break;
      case "phase": job.phase = ev.phase; break;
      case "start": job.info = ev; break;
      case "result": job.result = ev; break;
      case "status": Object.assign(job, ev.summary); break;
    }
    if (ev.event === "batch") job.eta_s = etaOf(job, ev);
    render();
  }));
}

/** The running loss of a batch event as a chart point (as Job._add_batch_point on the server). */
function addBatchPoint(job, b) {
  if (!job.batches || b.loss == null || !b.batches) return;
  const x = b.epoch - 1 + b.batch / b.batches, last = job.batches[job.batches.length - 1];
  if (last && x <= last[0]) return;
  job.batches.push([x, b.loss]);
  if (job.batches.length > 1000) job.batches = job.batches.filter((_, i) => i % 2 === 0);
}

function etaOf(job, b) {
  const perBatch = b.samples / b.samples_per_s / b.batch;
  if (!isFinite(perBatch)) return null;
  const perEpoch = job.epochs.length ? job.epochs.reduce((s, e) => s + e.seconds, 0) / job.epochs.length : perBatch * b.batches;
  return Math.max(0, (b.batches - b.batch) * perBatch + (b.epochs - b.epoch) * perEpoch);
}

// ---------------------------------------------------------------------------------------------
// Models
// ---------------------------------------------------------------------------------------------
function paramSummary(p) {
  const keys = [["epochs", "epochs"], ["batch_size", "batch"], ["learning_rate", "lr"], ["train_test_split", "split"], ["train_samples", "samples"]];
  return keys.filter(([k]) => p[k] !== undefined && p[k] !== null).map(([k, l]) => h("span", { class: "pill" }, `${l} ${p[k]}`));
}

function augSummary(p) {
  const a = p.augmentations;
  if (!a || !a.names) return h("span", { class: "muted small" }, "–");
  if (!a.names.length) return h("span", { class: "muted small" }, "none");
  return a.names.map(n => h("span", { class: "pill" }, `${n} ${a[n + "_p"] !== undefined ? a[n + "_p"] : ""}`));
}

async function pageModels() {
  const models = await api("GET", "api/models");
  show(
    h("div", { class: "spread" }, h("h1", {}, "Models"), h("a", { class: "button primary", href: "#/train" }, "Train a model")),
    models.length ? h("div", { class: "table-wrap" }, cardify(h("table", { id: "models" },
      h("thead", {}, h("tr", {}, ["Name", "Type", "Origin datasets", "Parameters", "Augmentations", "Best val_loss", "Evaluation", "Comment", ""].map(t => h("th", {}, t)))),
      h("tbody", {}, models.map(m => {
        const ev = m.latest_evaluation;
        return h("tr", { "data-model": m.name },
          h("td", {}, h("a", { href: `#/models/${encodeURIComponent(m.name)}`, class: "model-name" }, m.name), m.exists ? null : h("div", { class: "err" }, "file missing"),
            h("div", { class: "muted small" }, fmt.when(m.created))),
          h("td", {}, m.type),
          h("td", { class: "small" }, m.dataset_names.join(", ") || "–"),
          h("td", {}, paramSummary(m.parameters)),
          h("td", {}, augSummary(m.parameters)),
          h("td", { class: "num" }, fmt.num(m.metrics.best_val_loss, 5), m.metrics.cancelled ? h("div", { class: "muted small" }, "cancelled run") : null),
          h("td", { class: "small" }, ev ? evalSummary(ev) : "–"),
          h("td", { class: "model-comment" }, m.comment || ""),
          h("td", { class: "actions-cell" }, h("a", { class: "button small", href: `#/models/${encodeURIComponent(m.name)}/edit`, "data-action": "edit" }, "Edit"), " ",
            h("button", { class: "small", "data-action": "delete", onclick: () => deleteModel(m) }, "Delete")));
      })))))
      : h("div", { class: "card" }, h("p", {}, "No models yet: ", h("a", { href: "#/train" }, "train one"), ".")));
}

async function deleteModel(m) {
  const box = h("input", { type: "checkbox", id: "delete-files" });  // files go only when the user says so
  if (!await confirmDialog(`Delete ${m.name}?`, [`${m.name} leaves the model database.`, h("label", {}, box, ` also delete ${m.name}.pt and its exports, loss plot and metrics from the disk`)], "Delete")) return;
  try { await api("DELETE", `api/models/${encodeURIComponent(m.name)}?files=${box.checked ? 1 : 0}`); toast(`${m.name} deleted`); } catch (e) { toast(e.message, true); }
  go("#/models");
}

/** An evaluation in one line: the score (what ranks it) and the share of the laps driven before
    autonomy, which alone reads 100 % for a car that stood still; older evaluations have no score. */
function evalSummary(ev) {
  const o = ev.overall || {};
  const parts = [];
  if (o.score != null) parts.push(h("b", {}, `score ${fmt.num(o.score, 1)}`));
  if (o.completion != null) parts.push(`driven ${fmt.share(o.completion)}`);
  parts.push(o.score != null ? `autonomy ${fmt.pct(o.autonomy)}` : h("b", {}, `autonomy ${fmt.pct(o.autonomy)}`));
  return [...parts.flatMap((p, k) => (k ? [" · ", p] : [p])), ` on ${ev.tracks.join(",")}`];
}

function evaluationCard(ev, i = 0) {
  const open = i === 0;
  const o = ev.overall || {};
  return h("div", { class: "card evaluation", "data-evaluation": ev.id },
    h("div", { class: "spread" }, h("h3", {}, `Tracks ${ev.tracks.join(", ")} · ${fmt.n(ev.laps, "lap")}`), h("span", { class: "muted small" }, fmt.when(ev.created))),
    h("div", { class: "stats" }, [["score", fmt.num(o.score, 1)], ["driven", fmt.share(o.completion)], ["autonomy", fmt.pct(o.autonomy)], ["laps completed", o.laps_completed ?? "–"], ["mean |CTE|", o.mean_abs_cte != null ? `${fmt.num(o.mean_abs_cte, 3)} m` : "–"],
      ["mean speed", o.mean_speed != null ? `${fmt.num(o.mean_speed, 2)} m/s` : "–"], ["off-track", o.interventions ?? "–"], ["best lap", o.best_lap_s != null ? `${fmt.num(o.best_lap_s, 1)} s` : "–"]]
      .map(([k, v]) => h("div", { class: "stat" }, h("b", {}, v), h("span", {}, k)))),
    ev.per_track && ev.per_track.length ? h("div", { class: "table-wrap", style: "margin-top:.6rem" }, h("table", {}, h("thead", {}, h("tr", {}, ["track", "score", "driven", "autonomy", "laps", "mean |CTE|", "speed", "off-track"].map(t => h("th", {}, t)))),
      h("tbody", {}, ev.per_track.map(t => h("tr", {}, h("td", {}, t.seed), h("td", {}, fmt.num(t.score, 1)), h("td", {}, fmt.share(t.completion)), h("td", {}, fmt.pct(t.autonomy)), h("td", {}, t.laps_completed), h("td", {}, fmt.num(t.mean_abs_cte, 3)), h("td", {}, fmt.num(t.mean_speed, 2)), h("td", {}, t.interventions)))))) : null,
    ev.has_picture ? h("img", { class: "eval-pic", src: `api/evaluations/${ev.id}/picture`, alt: "driven trajectories", loading: "lazy" }) : null,
    ev.settings && ev.settings.gallery ? galleryBox(ev, open) : null);
}

/** An evaluation's failure gallery: the frames before each intervention and worst-|CTE| moment,
    with the pilot's (orange) and the expert's (blue) steering and where the pilot looked. */
function galleryBox(ev, open) {
  const body = h("div", { class: "gallery-body" }, h("p", { class: "muted" }, "Loading…"));
  const box = h("details", { class: "gallery", "data-gallery": ev.id, open },
    h("summary", {}, "Failure gallery ", h("a", { href: `api/evaluations/${ev.id}/gallery/index.html`, target: "_blank", rel: "noopener" }, "(open as a page)")), body);
  let loaded = false;
  const load = async () => {
    if (loaded || !box.open) return;
    loaded = true;
    try { body.replaceChildren(...nodes([galleryView(await api("GET", `api/evaluations/${ev.id}/gallery`))])); }
    catch (e) { body.replaceChildren(h("p", { class: "err" }, e.message)); }
  };
  box.addEventListener("toggle", load);
  if (open) load();
  return box;
}

function steerBar(v, cls) {
  if (v === null || v === undefined) return null;
  const x = Math.max(-1, Math.min(1, v));
  return h("span", { class: cls, style: x < 0 ? `left:${50 + 50 * x}%;width:${-50 * x}%` : `left:50%;width:${50 * x}%` });
}

function galleryView(g) {
  const moments = g.tracks.flatMap(t => t.moments.map(m => ({ t, m })));
  if (!moments.length) return h("p", { class: "muted" }, "Nothing to show: no intervention and no worst-|CTE| moment.");
  const sign = v => (v === null || v === undefined ? "–" : (v >= 0 ? "+" : "") + v.toFixed(2));
  return moments.map(({ t, m }) => h("div", { class: `moment kind-${m.kind}` },
    h("h4", {}, `${m.kind === "intervention" ? "Intervention" : "Worst |CTE|"} ${m.number} · track ${t.seed} · ${t.theme} · draw ${t.randomize ?? "–"} · ${m.time_s} s · cte ${sign(m.cte)} m`),
    h("div", { class: "frames" }, m.frames.map(f => h("figure", {},
      h("img", { src: g.base + (Object.values(f.saliency)[0] || f.image), alt: `saliency ${f.t} s`, loading: "lazy" }),
      h("div", { class: "bar" }, steerBar(f.pilot.angle, "pilot"), steerBar(f.expert.angle, "expert")),
      h("figcaption", {}, `${sign(f.t)} s · pilot ${sign(f.pilot.angle)} · expert ${sign(f.expert.angle)}`))))));
}

/** Saliency of a model on a few frames of its datasets (made by a worker process, then kept). */
function saliencyCard(m) {
  const body = h("div", { id: "saliency" }, h("p", { class: "muted" }, "Computing where the model looks…"));
  (async () => {
    try {
      const s = await api("GET", `api/models/${encodeURIComponent(m.name)}/saliency`);
      const sign = v => (v === null || v === undefined ? "–" : (v >= 0 ? "+" : "") + (+v).toFixed(2));
      body.replaceChildren(h("div", { class: "saliency-grid" }, s.samples.map(x => h("figure", { class: "sample" },
        h("div", { class: "pics" }, h("img", { src: s.base + x.image, alt: "frame" }),
          ...Object.entries(x.steering).map(([k, f]) => h("img", { src: s.base + f, alt: `steering saliency (${k})` })),
          ...Object.entries(x.throttle).map(([k, f]) => h("img", { src: s.base + f, alt: `throttle saliency (${k})` }))),
        h("figcaption", {}, `${x.tub} #${x.index} · steering ${sign(x.prediction.angle)} (recorded ${sign(x.recorded.angle)}) · throttle ${sign(x.prediction.throttle)} (recorded ${sign(x.recorded.throttle)})`)))));
    } catch (e) { body.replaceChildren(h("p", { class: "err" }, e.message)); }
  })();
  return h("div", { class: "card" }, h("h2", {}, "Where it looks"),
    h("p", { class: "muted small" }, "Frames of its datasets; then the saliency of its steering and of its throttle (integrated gradients: brighter = more of the decision)."), body);
}

async function pageEditModel(name) {
  const m = await api("GET", `api/models/${encodeURIComponent(name)}`);
  const form = h("form", { class: "card", id: "edit-model-form", novalidate: true },
    field("Model name", h("input", { type: "text", name: "name", value: m.name }), "name", "Renaming renames the model file and its exports on the disk."),
    field("Comment", h("textarea", { name: "comment" }, m.comment || ""), "comment", "How it drives, what to try next."),
    h("div", { class: "err", "data-err": "_form" }),
    h("div", { class: "row" }, h("a", { class: "button", href: "#/models", id: "back" }, "Back"), h("button", { class: "primary", type: "submit", id: "update" }, "Update")));
  form.onsubmit = async e => {
    e.preventDefault();
    const fd = new FormData(form);
    try { await api("PATCH", `api/models/${encodeURIComponent(m.name)}`, { name: fd.get("name"), comment: fd.get("comment") }); toast("Model updated"); go("#/models"); }
    catch (err) { showErrors(form, err); }
  };
  const p = m.parameters || {};
  const curves = h("div", { class: "chart", id: "model-curves" });
  const evalForm = h("form", { class: "row", id: "evaluate-form", novalidate: true },
    h("label", {}, "Tracks ", h("input", { type: "text", name: "tracks", value: info.eval_tracks.join(", "), style: "width:11em" })),
    h("label", {}, "Laps ", h("input", { type: "text", name: "laps", value: info.eval_laps, style: "width:4em", inputmode: "numeric" })),
    h("button", { class: "primary", type: "submit", id: "evaluate", disabled: !m.exists }, "Evaluate in the simulator"),
    h("span", { class: "err", "data-err": "tracks" }), h("span", { class: "err", "data-err": "laps" }), h("span", { class: "err", "data-err": "model" }), h("span", { class: "err", "data-err": "_form" }));
  evalForm.onsubmit = async e => {
    e.preventDefault();
    const fd = new FormData(evalForm);
    try { const job = await api("POST", "api/jobs/evaluate", { model: m.name, tracks: fd.get("tracks"), laps: fd.get("laps") }); go(`#/runs/${job.id}`); }
    catch (err) { showErrors(evalForm, err); }
  };
  const exportBtn = fmtName => h("button", { type: "button", "data-export": fmtName, disabled: !m.exists, onclick: async ev => {
    const b = ev.target; b.disabled = true; b.textContent = "Exporting…";
    try { const r = await api("POST", `api/models/${encodeURIComponent(m.name)}/export`, { format: fmtName }); toast(`Wrote ${r.path}`); route(); }
    catch (err) { toast(err.message, true); b.disabled = false; b.textContent = `Export ${fmtName}`; }
  } }, `Export ${fmtName === "onnx" ? "ONNX" : "TorchScript"}`);
  const dl = (fmtName, label) => h("a", { class: "button small", href: `api/models/${encodeURIComponent(m.name)}/file?format=${fmtName}`, download: true }, label);
  show(
    h("h1", {}, `Model ${m.name}`),
    h("div", { class: "grid2" },
      h("div", {}, form,
        h("div", { class: "card" }, h("h2", {}, "Export"), h("div", { class: "row" }, exportBtn("onnx"), exportBtn("torchscript")),
          h("div", { class: "row", style: "margin-top:.6rem" }, dl("pt", "Download .pt"), m.files.onnx ? dl("onnx", "Download .onnx") : null, m.files.torchscript ? dl("torchscript", "Download .ts") : null))),
      h("div", { class: "card" }, h("h2", {}, "About"), h("dl", { class: "kv", id: "model-info" },
        h("dt", {}, "type"), h("dd", {}, m.type),
        h("dt", {}, "origin datasets"), h("dd", {}, m.dataset_links.length ? m.dataset_links.map((d, i) => [i ? ", " : "", d.id ? h("a", { href: `#/datasets/${d.id}` }, d.name) : d.name]) : "–"),
        h("dt", {}, "file"), h("dd", { class: "small" }, m.path, m.exists ? "" : " (missing)"),
        h("dt", {}, "created"), h("dd", {}, fmt.when(m.created)),
        m.transfer ? [h("dt", {}, "transfer from"), h("dd", {}, m.transfer)] : null,
        h("dt", {}, "best val_loss"), h("dd", {}, `${fmt.num(m.metrics.best_val_loss, 5)} (epoch ${m.metrics.best_epoch ?? "–"} of ${m.metrics.epochs ?? "–"})`),
        h("dt", {}, "parameters"), h("dd", {}, paramSummary(p), p.parameters ? h("span", { class: "pill" }, `${fmt.int(p.parameters)} weights`) : null),
        h("dt", {}, "augmentations"), h("dd", {}, augSummary(p))),
        h("details", {}, h("summary", {}, "All training parameters"), h("pre", { class: "small mono", style: "white-space:pre-wrap" }, JSON.stringify(p, null, 1))))),
    h("div", { class: "card" }, h("h2", {}, "Training curves"), m.metrics.train_loss ? curves : h("p", { class: "muted" }, "No curves stored.")),
    h("div", { class: "card" }, h("h2", {}, "Evaluate"), h("p", { class: "muted small" }, "Drives the model in the built-in simulator on the chosen tracks (use tracks it was not trained on) in a worker process; the result is stored in the model database and ranked on the leaderboard."), evalForm),
    m.exists ? saliencyCard(m) : null,
    h("h2", {}, "Evaluations"), m.evaluations.length ? m.evaluations.map((ev, i) => evaluationCard(ev, i)) : h("p", { class: "muted", id: "no-evaluations" }, "Not evaluated yet."));
  if (m.metrics.train_loss) {
    const epochs = m.metrics.train_loss.map((l, i) => ({ epoch: i + 1, train_loss: l, val_loss: (m.metrics.val_loss || [])[i] }));
    const u = lossChart(curves, epochs, 220); cleanup.push(() => u._ro.disconnect());
  }
}

// ---------------------------------------------------------------------------------------------
// Leaderboard
// ---------------------------------------------------------------------------------------------
async function pageLeaderboard(query) {
  const q = new URLSearchParams();
  if (query.get("tracks")) q.set("tracks", query.get("tracks"));
  if (query.get("laps")) q.set("laps", query.get("laps"));
  const lb = await api("GET", `api/leaderboard?${q}`);
  const sel = h("select", { id: "track-set", onchange: e => go(`#/leaderboard?${e.target.value}`) },
    lb.track_sets.map(s => h("option", { value: `tracks=${s.tracks.join(",")}&laps=${s.laps}`, selected: s.tracks.join(",") === lb.tracks.join(",") && (lb.laps == null || lb.laps === s.laps) },
      `tracks ${s.tracks.join(", ")} · ${fmt.n(s.laps, "lap")} (${fmt.n(s.models, "model")})`)));
  show(
    h("h1", {}, "Leaderboard"),
    // the order of parts/sim/metrics.py rank_key, which training/evaluation_db.py sorts by
    h("p", { class: "muted", id: "leaderboard-rank" }, "Models ranked by their latest evaluation on the same tracks: score first (autonomy × the share of the asked laps driven: a car that stood still scores 0, though its autonomy reads 100 %), then laps completed, then mean |cross-track error|, then speed. An evaluation without a score (older ones, the Udacity simulator's) ranks by its autonomy."),
    lb.track_sets.length ? h("div", { class: "row" }, "Track set ", sel) : null,
    lb.board.length ? h("div", { class: "table-wrap", style: "margin-top:.8rem" }, cardify(h("table", { id: "leaderboard" },
      h("thead", {}, h("tr", {}, ["#", "Model", "Score", "Driven", "Autonomy", "Laps", "Mean |CTE|", "Speed", "Off-track", "Evaluated"].map(t => h("th", {}, t)))),
      h("tbody", {}, lb.board.map((e, i) => h("tr", { class: `rank-${i + 1}`, "data-model": e.model },
        h("td", {}, i + 1), h("td", {}, h("a", { href: `#/models/${encodeURIComponent(e.model)}` }, e.model)),
        h("td", { class: "num" }, fmt.num(e.overall.score, 1)), h("td", { class: "num" }, fmt.share(e.overall.completion)),
        h("td", { class: "num" }, fmt.pct(e.overall.autonomy)), h("td", { class: "num" }, e.overall.laps_completed ?? "–"),
        h("td", { class: "num" }, e.overall.mean_abs_cte != null ? `${fmt.num(e.overall.mean_abs_cte, 3)} m` : "–"),
        h("td", { class: "num" }, e.overall.mean_speed != null ? `${fmt.num(e.overall.mean_speed, 2)} m/s` : "–"),
        h("td", { class: "num" }, e.overall.interventions ?? "–"), h("td", { class: "small" }, fmt.when(e.created))))))))
      : h("div", { class: "card" }, h("p", {}, "No evaluations on these tracks yet. Open a model in the ", h("a", { href: "#/models" }, "model manager"), " and press Evaluate.")));
}


// ---------------------------------------------------------------------------------------------
// Cars: pair with a car, watch it, pull its tubs, push and switch pilots (vehicle/app/console/cars.py)
// ---------------------------------------------------------------------------------------------
async function pageCars() {
  const [cars, models] = await Promise.all([api("GET", "api/cars"), api("GET", "api/models")]);
  const form = h("form", { id: "add-car", class: "card", onsubmit: async ev => {
    ev.preventDefault();
    const fd = new FormData(form);
    const btn = form.querySelector("button[type=submit]"); btn.disabled = true;
    try {
      const car = await api("POST", "api/cars", { address: fd.get("address"), token: fd.get("token"), name: fd.get("name") });
      toast(`Paired with ${car.name}`); route();
    } catch (e) { showErrors(form, e); } finally { btn.disabled = false; }
  } },
    h("h2", {}, "Add a car"),
    h("p", { class: "muted small" }, "The car prints its address and pairing token when it starts (manage.py drive with WEB_HOST = \"0.0.0.0\"); paste that URL, or the address and the token apart."),
    h("div", { class: "grid2" },
      field("Address", h("input", { type: "text", name: "address", placeholder: "http://192.168.1.20:8887/?token=…", autocomplete: "off", required: true }), "address"),
      field("Pairing token", h("input", { type: "text", name: "token", placeholder: "if not in the address", autocomplete: "off" }), "token")),
    field("Name", h("input", { type: "text", name: "name", placeholder: "the car's own name", maxlength: 63 }), "name"),
    h("div", { class: "err", "data-err": "_form" }),
    h("div", { class: "row" }, h("button", { type: "submit", class: "primary" }, "Pair"),
      h("button", { type: "button", id: "discover", onclick: () => discoverCars(form) }, "Find cars on this network")),
    h("div", { id: "found" }));
  show(h("h1", {}, "Cars"),
    cars.length ? h("div", { id: "cars" }, cars.map(c => carCard(c, models)))
      : h("div", { class: "card", id: "cars" }, h("p", {}, "No car yet: add one below.")),
    form);
  const timer = setInterval(() => cars.forEach(c => refreshCar(c.id)), 2000);
  cleanup.push(() => clearInterval(timer));
  cars.forEach(c => refreshCar(c.id));
}

async function discoverCars(form) {
  const out = $("#found"); out.replaceChildren(h("p", { class: "muted small" }, "Listening for cars for 2 s…"));
  try {
    const r = await api("GET", "api/cars/discover");
    if (r.error) { out.replaceChildren(h("p", { class: "muted small" }, r.error)); return; }
    out.replaceChildren(r.cars.length ? h("ul", {}, r.cars.map(c => h("li", { "data-found": c.url }, `${c.name} · ${c.url} `,
      c.known ? h("span", { class: "muted small" }, "(paired)") : h("button", { type: "button", class: "small", onclick: () => {
        form.querySelector('[name="address"]').value = c.url; form.querySelector('[name="name"]').value = c.name;
        form.querySelector('[name="token"]').focus();
      } }, "Use this address"))))
      : h("p", { class: "muted small" }, "No car announced itself (this network may block it): type the car's address."));
  } catch (e) { out.replaceChildren(h("p", { class: "err" }, e.message)); }
}

function carCard(c, models) {
  const modelSel = h("select", { name: "model", "aria-label": "model to push" },
    models.filter(m => m.exists).map(m => h("option", { value: m.name }, m.name)));
  const push = use => async () => {
    try {
      const r = await api("POST", `api/cars/${c.id}/push`, { model: modelSel.value, use });
      toast(use ? `${c.name} now drives ${r.model} (in user mode: choose a pilot mode on its page)` : `${r.model} is on ${c.name}`);
      refreshCar(c.id);
    } catch (e) { toast(e.message, true); }
  };
  return h("section", { class: "card car", "data-car": c.id },
    h("div", { class: "spread" }, h("h2", {}, c.name, " ", h("span", { class: "muted small mono" }, c.url)),
      h("button", { class: "small", "data-action": "remove", onclick: async () => {
        if (await confirmDialog(`Forget ${c.name}?`, "Pair again with its token to add it back.", "Forget")) {
          await api("DELETE", `api/cars/${c.id}`); route();
        }
      } }, "Forget")),
    h("div", { class: "err", "data-car-error": "" }),
    h("dl", { class: "carstatus" }, ["mode", "records", "loop", "battery", "pilot"].map(k =>
      h("div", {}, h("dt", {}, k), h("dd", { "data-field": k }, "–")))),
    h("p", { class: "notice", "data-field": "notice", hidden: true }),
    h("h3", {}, "Tubs"), h("div", { "data-tubs": "" }, h("p", { class: "muted small" }, "…")),
    h("div", { class: "row" }, h("button", { class: "primary", "data-action": "pull", onclick: () => startPull(c) }, "Pull new records")),
    h("div", { "data-pull": "", hidden: true }, h("div", { class: "bar", role: "progressbar", "aria-valuemin": 0, "aria-valuemax": 100 }, h("div")),
      h("p", { class: "small", "data-pull-text": "" })),
    h("h3", {}, "Pilots"),
    models.length ? h("div", { class: "row" }, modelSel, h("button", { "data-action": "push", onclick: push(false) }, "Push"),
      h("button", { class: "primary", "data-action": "push-use", onclick: push(true) }, "Push and switch to it"))
      : h("p", { class: "muted small" }, "No trained model yet: ", h("a", { href: "#/train" }, "train one"), "."),
    h("div", { "data-models": "" }));
}

async function refreshCar(id) {
  const card = document.querySelector(`.car[data-car="${id}"]`);
  if (!card) return;
  const set = (k, v) => { const el = card.querySelector(`[data-field="${k}"]`); if (el) el.textContent = v; };
  try {
    const r = await api("GET", `api/cars/${id}`);
    const s = r.status;
    card.querySelector("[data-car-error]").textContent = "";
    set("mode", s.mode + (s.estop ? " (emergency stop)" : "") + (s.recording ? " · recording" : ""));
    set("records", fmt.int(s.records));
    set("loop", s.loop_rate_hz == null ? "–" : `${fmt.num(s.loop_rate_hz, 1)} Hz · ${fmt.n(s.loop_overruns || 0, "overrun")}`);
    set("battery", s.battery_v == null ? "no sensor" : `${fmt.num(s.battery_v, 2)} V`);
    set("pilot", (s.pilot || "none") + (s.pilot_error ? ` (last switch failed: ${s.pilot_error})` : ""));
    const note = card.querySelector('[data-field="notice"]'); note.textContent = s.notice || ""; note.hidden = !s.notice;
    card.querySelector("[data-tubs]").replaceChildren(r.tubs.length ? cardify(h("table", {},
      h("thead", {}, h("tr", {}, ["Tub", "Records", "Size", "New for this laptop"].map(t => h("th", {}, t)))),
      h("tbody", {}, r.tubs.map(t => h("tr", { "data-tub": t.name }, h("td", {}, t.name, t.pulled ? h("div", { class: "muted small" }, `dataset ${t.folder}`) : null),
        h("td", { class: "num" }, fmt.int(t.records)), h("td", { class: "num" }, fmt.bytes(t.bytes)), h("td", { class: "num" }, fmt.int(t.new)))))))
      : h("p", { class: "muted small" }, "No tub on the car yet."));
    card.querySelector("[data-models]").replaceChildren(r.models.length ? h("ul", { class: "small" }, r.models.map(m =>
      h("li", { "data-car-model": m.name }, `${m.name} (${fmt.bytes(m.bytes)}) `, m.driving ? h("b", {}, "driving")
        : h("button", { class: "small", onclick: async () => {
          try { await api("POST", `api/cars/${id}/use`, { model: m.name }); toast(`${m.name} is the pilot (the car is in user mode)`); refreshCar(id); }
          catch (e) { toast(e.message, true); }
        } }, "Switch to it")))) : null);
    showPull(card, r.pull);
  } catch (e) { card.querySelector("[data-car-error]").textContent = e.message; }
}

function showPull(card, p) {
  const box = card.querySelector("[data-pull]");
  if (!p || p.state === "idle") { box.hidden = true; return; }
  box.hidden = false;
  const pct = p.total ? Math.round(100 * p.done / p.total) : (p.state === "done" ? 100 : 0);
  const bar = box.querySelector(".bar"); bar.setAttribute("aria-valuenow", pct); bar.firstChild.style.width = `${pct}%`;
  const text = p.state === "running" ? `Pulling ${p.tub || ""}: ${fmt.int(p.done)} of ${fmt.int(p.total)} records`
    : p.state === "failed" ? `Pull stopped: ${p.error}`
    : `Pulled: ${(p.pulled || []).map(x => `${fmt.n(x.received, "record")} into ${x.folder}`).join(", ") || "nothing new"}`;
  const t = box.querySelector("[data-pull-text]"); t.textContent = text; t.className = "small" + (p.state === "failed" ? " err" : "");
  card.querySelector('[data-action="pull"]').disabled = p.state === "running";
}

async function startPull(c) {
  const card = document.querySelector(`.car[data-car="${c.id}"]`);
  try { showPull(card, await api("POST", `api/cars/${c.id}/pull`)); } catch (e) { toast(e.message, true); return; }
  const timer = setInterval(async () => {
    if (!document.body.contains(card)) { clearInterval(timer); return; }
    try {
      const p = await api("GET", `api/cars/${c.id}/pull`);
      showPull(card, p);
      if (p.state !== "running") { clearInterval(timer); refreshCar(c.id); }
    } catch (e) { clearInterval(timer); toast(e.message, true); }
  }, 400);
  cleanup.push(() => clearInterval(timer));
}

// ---------------------------------------------------------------------------------------------
window.addEventListener("hashchange", route);
live.start();
route();
