// specholo studio: the page talks only to the server that sent it (same origin).
// Plate frame, mm: x right, y up, z toward the viewer; the plate is z = 0.
"use strict";

const $ = (id) => document.getElementById(id);
const SLIDERS = ["size", "center_z", "offset_x", "offset_y", "light_elevation", "view_range",
                 "view_distance", "stipples"];
const S = {settings: {}, azimuth: 0, preview: null, model: null, modelId: 0, span: 80,
           asked: 0, inFlight: false, dirty: false, glintDraws: 0, lastGlints: [],
           // The exact design: the settings it was asked for (their JSON), whether
           // one runs, whether the current settings wait for it, the last one done.
           designing: null, running: false, pending: false, done: null, followTimer: 0,
           // The quick figures from a sample design: for which settings, and
           // whether one is being made.
           estimate: null, estimating: false, estimateTimer: 0};
//: How long the settings stay still before the sample design estimates them, ms.
const ESTIMATE_MS = 250;
//: How long the settings stay still before the exact design follows them, ms.
const FOLLOW_MS = 1200;
//: This run's secret, from the address the studio printed (?token=...): every
//: API request carries it. Kept for this tab, so reloading the address without
//: it still works, and taken out of the address bar (nothing shows or keeps it).
const TOKEN = (() => {
  const url = new URL(location.href);
  const given = url.searchParams.get("token");
  if (given) {
    sessionStorage.setItem("specholo-token", given);
    url.searchParams.delete("token");
    history.replaceState(null, "", url.pathname + url.search + url.hash);
  }
  return given || sessionStorage.getItem("specholo-token") || "";
})();

function showError(text) { $("error").textContent = text ? "error: " + text : ""; }

// The views of what will be cut (plate_view.js) follow the page through these:
// "preview", "azimuth" and "design" (with the design's status).
function notify(what, detail) {
  document.dispatchEvent(new CustomEvent("studio:" + what, {detail}));
}

async function call(method, url, body, headers) {
  // Every answer is JSON with "error" on failure: one line for the page.
  const opts = {method, headers: Object.assign({"X-Specholo-Token": TOKEN}, headers || {})};
  if (body !== undefined) {
    opts.body = body instanceof Blob ? body : JSON.stringify(body);
    if (!(body instanceof Blob)) opts.headers["Content-Type"] = "application/json";
  }
  let reply;
  try {
    reply = await fetch(url, opts);
  } catch (e) {
    throw new Error("the studio server does not answer (was it stopped?)");
  }
  const data = await reply.json().catch(() => ({error: "bad answer from the server"}));
  if (data.error) throw new Error(data.error);
  return data;
}

// ---------------------------------------------------------------- settings
function wrap(a) { return ((a + 180) % 360 + 360) % 360 - 180; }

function setSetting(key, value) {
  S.settings[key] = value;
  const el = $(key);
  if (el && el.type === "range") {
    el.value = value;
    el.parentElement.querySelector("output").textContent = (+value).toFixed(
      key === "stipples" ? 0 : Number.isInteger(+value) ? 0 : 1);
  } else if (el) {
    el.value = value;
  }
  $("rotate-out").textContent = `x ${(+S.settings.rotate_x).toFixed(0)}\u00b0, ` +
    `y ${(+S.settings.rotate_y).toFixed(0)}\u00b0`;
}

function setAzimuth(a) {
  const range = +S.settings.view_range;
  S.azimuth = Math.max(-range, Math.min(range, a));
  const el = $("azimuth");
  el.min = -range; el.max = range; el.value = S.azimuth;
  el.parentElement.querySelector("output").textContent = S.azimuth.toFixed(1);
  $("azimuth-out").textContent = S.azimuth.toFixed(1);
  drawGlints();
  notify("azimuth");
}

function sent() {
  // What the server designs from: the design's option names; a blank is null,
  // the command's default.
  const s = {};
  for (const k of [...SLIDERS, "up", "rotate_x", "rotate_y", "seed", ...moreKeys()])
    s[k] = S.settings[k] === undefined ? null : S.settings[k];
  s.stipples = Math.round(s.stipples);
  // a target visibility chooses the count itself
  if (s.visibility !== null) s.stipples = null;
  return s;
}

// ---------------------------------------------------------------- more settings
// Each control of #more is a `specholo design` option by its id: a number
// (blank: the default), a choice (the first entry: the default) or a flag.
function moreKeys() {
  return [...document.querySelectorAll("#more [data-setting]")].map((el) => el.id);
}

function setupMore(st) {
  // The command's bounds and choices, as the server states them.
  for (const el of document.querySelectorAll("#more [data-setting]")) {
    const k = el.id, kind = el.dataset.setting, dflt = st.defaults[k];
    if (kind === "number") {
      const b = st.bounds[k];
      if (b) { el.min = b[0]; el.max = b[1]; el.title += ` [${b[0]}, ${b[1]}] ${b[2]}`; }
      el.placeholder = dflt === null || dflt === undefined ? "default" : dflt;
    } else if (kind === "choice") {
      el.innerHTML = "";
      const none = document.createElement("option");
      none.value = ""; none.textContent = dflt === null || dflt === undefined ?
        "default" : `${dflt} (default)`;
      el.appendChild(none);
      for (const v of st.choices[k]) {
        if (v === dflt) continue;
        const o = document.createElement("option");
        o.value = o.textContent = v; el.appendChild(o);
      }
    }
  }
}

function showMore() {
  for (const el of document.querySelectorAll("#more [data-setting]")) {
    const v = S.settings[el.id];
    if (el.dataset.setting === "flag") el.checked = !!v;
    else el.value = v === null || v === undefined ? "" : v;
  }
}

function bindMore() {
  for (const el of document.querySelectorAll("#more [data-setting]")) {
    el.addEventListener("change", () => {
      const kind = el.dataset.setting;
      S.settings[el.id] = kind === "flag" ? el.checked :
        el.value === "" ? null : kind === "number" ? +el.value : el.value;
      changed();
    });
  }
  $("copy-command").addEventListener("click", () => {
    navigator.clipboard?.writeText($("command").textContent);
  });
}

// The settings stay in this browser, for this model: a reload (or the studio
// started again on the same model) picks up where the maker left off.
const SAVED = "specholo-studio-settings";

function saveSettings() {
  if (!S.model) return;
  try {
    localStorage.setItem(SAVED, JSON.stringify({model: S.model, settings: S.settings}));
  } catch (e) { /* storage full or refused: the page works without it */ }
}

function savedSettings(model) {
  try {
    const saved = JSON.parse(localStorage.getItem(SAVED) || "null");
    return saved && saved.model === model ? saved.settings : null;
  } catch (e) {
    return null;
  }
}

// ---------------------------------------------------------------- preview
function changed() { S.dirty = true; saveSettings(); if (!S.inFlight) askPreview(); }

async function askPreview() {
  if (!S.model) return;
  S.dirty = false; S.inFlight = true;
  const t0 = performance.now();
  try {
    S.preview = await call("POST", "/api/preview", {settings: sent()});
    S.preview.ms = performance.now() - t0;
    S.asked += 1;
    $("command").textContent = S.preview.command;
    showError("");
  } catch (e) {
    showError(e.message);
  }
  S.inFlight = false;
  fit(); drawModel(); drawGlints(); showEstimates();
  notify("preview");
  if (S.dirty) askPreview(); else { follow(); askEstimate(); }
}

function askEstimate() {
  // The sample design's figures, once the settings rest a moment; one at a
  // time, the latest settings asked again when it is done.
  clearTimeout(S.estimateTimer);
  S.estimateTimer = setTimeout(async () => {
    S.estimateTimer = 0;
    const k = key(), model = S.modelId;
    if (S.estimating || (S.estimate && S.estimate.key === k) || !S.model) return;
    S.estimating = true; showEstimates();
    let figures;
    try {
      figures = await call("POST", "/api/estimate", {settings: JSON.parse(k)});
    } catch (e) {
      figures = {why: e.message};
    }
    S.estimating = false;
    // (an estimate of the model the page had when it asked, or none)
    if (model === S.modelId) S.estimate = {key: k, figures};
    showEstimates();
    if (!S.estimate || S.estimate.key !== key()) askEstimate();
  }, ESTIMATE_MS);
}

function key() { return JSON.stringify(sent()); }

function follow() {
  // Once the settings rest, the exact design follows them: its as-cut
  // visibility and machining time join the preview's estimates.
  clearTimeout(S.followTimer);
  if (!$("follow").checked || !S.model) return;
  S.followTimer = setTimeout(() => {
    S.followTimer = 0;
    if (!S.dirty && !S.inFlight && (!S.done || S.done.key !== key()) && S.designing !== key())
      design();
  }, FOLLOW_MS);
  showEstimates();
}

function visibleAt(p, az) {
  // Stipples seen by the eye at azimuth az (degrees): their runs hold it.
  const r = p.runs, seen = new Uint8Array(p.stipples);
  for (let k = 0; k < r.stipple.length; k++)
    if (r.start[k] <= az && az <= r.end[k]) seen[r.stipple[k]] = 1;
  return seen;
}

function glintsAt(az) {
  // The crossing of the sightline eye -> stipple with the plate z = 0.
  const p = S.preview;
  if (!p) return [];
  const t = az * Math.PI / 180, R = p.eye.radius;
  const ex = R * Math.sin(t), ey = p.eye.height, ez = R * Math.cos(t);
  const seen = visibleAt(p, az), out = [];
  for (let i = 0; i < p.stipples; i++) {
    if (!seen[i]) continue;
    const px = p.points[3 * i], py = p.points[3 * i + 1], pz = p.points[3 * i + 2];
    const s = ez / (ez - pz);
    out.push({id: i, x: ex + s * (px - ex), y: ey + s * (py - ey)});
  }
  return out;
}

function fit() {
  // One scale for both canvases, in 20 mm steps so it holds still while dragging.
  const p = S.preview;
  if (!p) return;
  let m = 10;
  const range = p.eye.range_deg;
  for (let i = 0; i < p.stipples; i++) {
    const x = p.points[3 * i], y = p.points[3 * i + 1], z = p.points[3 * i + 2];
    const reach = Math.abs(z) * Math.tan(range * Math.PI / 180);
    m = Math.max(m, Math.abs(x) + reach, Math.abs(y));
  }
  S.span = Math.ceil(1.1 * m / 20) * 20;
}

function frame(canvas) {
  const g = canvas.getContext("2d"), w = canvas.width, h = canvas.height;
  g.fillStyle = "#000"; g.fillRect(0, 0, w, h);
  const k = 0.5 * Math.min(w, h) / S.span;
  g.strokeStyle = "#333"; g.beginPath();
  g.moveTo(w / 2, 0); g.lineTo(w / 2, h); g.moveTo(0, h / 2); g.lineTo(w, h / 2); g.stroke();
  g.fillStyle = "#666"; g.font = "11px sans-serif";
  g.fillText(`\u00b1${S.span} mm`, 6, 14);
  return {g, k, cx: w / 2, cy: h / 2};
}

function drawModel() {
  const {g, k, cx, cy} = frame($("model"));
  const p = S.preview;
  $("prompt").hidden = !!S.model;
  if (!p) return;
  const seen = new Uint8Array(p.stipples);
  for (const s of p.runs.stipple) seen[s] = 1;
  for (const pass of [0, 1]) {  // the unseen first, so the seen ones stay on top
    for (let i = 0; i < p.stipples; i++) {
      if (seen[i] !== pass) continue;
      const z = p.points[3 * i + 2];
      g.fillStyle = !seen[i] ? "#555" : z < 0 ? "#4af" : "#fa4";
      g.fillRect(cx + k * p.points[3 * i] - 1, cy - k * p.points[3 * i + 1] - 1, 2, 2);
    }
  }
}

function drawGlints() {
  const {g, k, cx, cy} = frame($("glints"));
  const found = glintsAt(S.azimuth);
  g.fillStyle = "#fff";
  for (const q of found) g.fillRect(cx + k * q.x - 1, cy - k * q.y - 1, 2.5, 2.5);
  g.fillStyle = "#999";
  g.fillText(`eye at ${S.azimuth.toFixed(1)}\u00b0: ${found.length} glints`, 6, 28);
  S.lastGlints = found; S.glintDraws += 1;
}

function row(table, name, value, note) {
  const tr = table.insertRow();
  tr.insertCell().textContent = name;
  const td = tr.insertCell(); td.textContent = value;
  if (note) { const n = tr.insertCell(); n.className = "note"; n.textContent = note; }
}

function showEstimates() {
  const t = $("estimates"); t.innerHTML = "";
  const p = S.preview;
  if (!p) return;
  const e = p.estimates;
  row(t, "stipples", p.stipples, "the design's own (same seed)");
  row(t, "hidden from every view", e.hidden, "exact: the design's occlusion");
  row(t, "groove length", `about ${(e.groove_length_mm / 1000).toFixed(2)} m`,
      "closed form: what the views need (exact grooves within ~1%)");
  row(t, "cutting time", `at least ${e.cutting_at_least}`,
      `lower bound at ${S.settings.feed} mm/min`);
  const d = S.done && S.done.key === key() ? S.done.summary : null;
  if (d) {
    const pct = (v) => v === null ? "\u2014" : `${Math.round(100 * v)}%`;
    row(t, "machining, whole job", `about ${d.machining}`,
        "the exact design's, for these settings");
    row(t, "as-cut visibility", `${pct(d.as_cut_mean)} mean, ${pct(d.as_cut_lowest)} lowest`,
        "the exact design's, for these settings: both eyes, the plate as cut");
  } else {
    const coming = S.followTimer || S.pending || S.designing === key();
    const q = S.estimate && S.estimate.key === key() ? S.estimate.figures : null;
    const pct = (v) => v === null ? "\u2014" : `${Math.round(100 * v)}%`;
    if (q && q.why === undefined) {
      const from = `estimate: the exact design of ${q.sample} of the ${q.of} stipples, ` +
        "a strip across the plate's middle at its full density" +
        (coming ? "; the exact design of these settings is on its way" : "");
      row(t, "machining, whole job", `about ${q.machining}`, from);
      row(t, "as-cut visibility",
          `about ${pct(q.as_cut_mean)} mean, ${pct(q.as_cut_lowest)} lowest`, from);
      row(t, "strokes", `about ${q.strokes.toLocaleString("en")}`, from);
    } else {
      const why = q ? q.why : coming ? "the exact design of these settings is on its way" :
        "the exact design's: press Design exactly (or keep it to the settings)";
      const wait = S.estimating || coming ? "updating\u2026" : "\u2014";
      row(t, "machining, whole job", wait, why);
      row(t, "as-cut visibility", wait, q || coming ? why : e.as_cut_why);
    }
  }
  row(t, "preview took", `${Math.round(p.ms)} ms`);
}

// ---------------------------------------------------------------- exact design
async function design() {
  showError("");
  // One design at a time: these settings wait for the running one.
  if (S.running) { S.pending = true; showEstimates(); return; }
  const k = key();
  S.designing = k; S.running = true; S.pending = false;
  // The last design's figures go at once: what shows next is this one's.
  showDesign({state: "running", stage: "starting"});
  try {
    await call("POST", "/api/design", {settings: JSON.parse(k)});
  } catch (e) {
    S.designing = null; S.running = false;
    showError(e.message);
    poll();  // a refusal: show the design that is running, or none
    return;
  }
  poll();
}

async function poll() {
  let st;
  try {
    st = await call("GET", "/api/design");
  } catch (e) {
    showError(e.message);
    return;
  }
  S.running = st.state === "running";
  if (!S.running && S.designing !== null) {
    // (the server reports another model's design as none: this check is the page's own)
    if (st.state === "done" && st.model_id === S.modelId)
      S.done = {key: S.designing, summary: st.summary};
    S.designing = null;
  }
  showDesign(st);
  showEstimates();
  if (S.running) { setTimeout(poll, 400); return; }
  // Settings that waited, or changed while it ran: their own design now.
  const stale = !S.done || S.done.key !== key();
  if (S.pending || ($("follow").checked && stale && S.model && !S.followTimer)) {
    S.pending = false;
    if (stale) design();
  }
}

function showDesign(st) {
  notify("design", st);
  $("design").disabled = st.state === "running";
  const secs = st.seconds !== undefined ? ` (${Math.round(st.seconds)} s)` : "";
  $("status").textContent = st.state === "idle" ? "" :
    st.state === "failed" ? `failed: ${st.error}` : `${st.stage}${secs}`;
  const t = $("result"); t.innerHTML = "";
  $("export").hidden = st.state !== "done";
  if (st.state !== "done") { showCompared([]); return; }
  const f = st.summary, pct = (v) => v === null ? "\u2014" : `${Math.round(100 * v)}%`;
  row(t, "as-cut visibility", `${pct(f.as_cut_mean)} mean, ${pct(f.as_cut_lowest)} lowest`);
  row(t, "machining", `about ${f.machining} (${f.machining_hours.toFixed(2)} h)`);
  row(t, "hidden stipples", `${f.hidden} of ${f.stipples}`);
  row(t, "groove length", `${(f.groove_length_mm / 1000).toFixed(2)} m, ${f.paths} paths`);
  if (f.light) row(t, "light to use", f.light);
  for (const w of f.warnings) row(t, "warning", w);
  $("folder").textContent = st.folder;
  showCompared(f.compared || []);
}

function showCompared(rows) {
  // Why exact is worth its strokes: the arcs' error away from the straight-on view.
  const body = $("compare").tBodies[0]; body.innerHTML = "";
  $("compare").hidden = rows.length === 0;
  const pct = (v) => v === null ? "\u2014" : `${Math.round(100 * v)}%`;
  for (const r of rows) {
    const tr = body.insertRow();
    for (const text of [r.label, r.strokes.toLocaleString("en"),
                        r.worst_p95_mm === null ? "\u2014" : `${r.worst_p95_mm.toFixed(2)} mm`,
                        pct(r.lowest_visibility),
                        `${pct(r.as_cut_mean)} / ${pct(r.as_cut_lowest)}`])
      tr.insertCell().textContent = text;
  }
}

// ---------------------------------------------------------------- input
function bindInputs() {
  for (const key of SLIDERS) {
    $(key).addEventListener("input", (ev) => {
      setSetting(key, +ev.target.value);
      if (key === "view_range") setAzimuth(S.azimuth);
      changed();
    });
  }
  $("up").addEventListener("change", (ev) => { setSetting("up", ev.target.value); changed(); });
  $("zip").addEventListener("click", () => download("/api/design.zip", "design.zip"));
  for (const b of document.querySelectorAll("button.file"))
    b.addEventListener("click", () => download(
      `/api/design/file?name=${encodeURIComponent(b.dataset.file)}`, b.dataset.file, b));
  bindMore();
  $("azimuth").addEventListener("input", (ev) => setAzimuth(+ev.target.value));
  $("reset").addEventListener("click", () => {
    for (const k of ["rotate_x", "rotate_y", "offset_x", "offset_y"]) setSetting(k, 0);
    changed();
  });
  $("design").addEventListener("click", design);
  $("follow").addEventListener("change", () => { follow(); showEstimates(); });
  $("file").addEventListener("change", async (ev) => {
    const file = ev.target.files[0];
    if (!file) return;
    try {
      const st = await call("POST", "/api/model", file,
                            {"X-Specholo-Name": encodeURIComponent(file.name)});
      setModel(st.model, st.model_id);
      showDesign(st.design);
      changed();
    } catch (e) {
      showError(e.message);
    }
    ev.target.value = "";
  });
  const model = $("model");
  let drag = null;
  model.addEventListener("pointerdown", (ev) => {
    drag = {x: ev.clientX, y: ev.clientY};
    model.setPointerCapture(ev.pointerId);
  });
  model.addEventListener("pointermove", (ev) => {
    if (!drag) return;
    const dx = ev.clientX - drag.x, dy = ev.clientY - drag.y;
    drag = {x: ev.clientX, y: ev.clientY};
    if (ev.shiftKey) {  // move on the plate, mm per pixel of the drawing
      const mm = S.span / (0.5 * model.width);
      setSetting("offset_x", Math.max(-150, Math.min(150, S.settings.offset_x + dx * mm)));
      setSetting("offset_y", Math.max(-150, Math.min(150, S.settings.offset_y - dy * mm)));
    } else {  // turn about the plate's y (across) and x (up and down) axes
      setSetting("rotate_y", wrap(S.settings.rotate_y + 0.5 * dx));
      setSetting("rotate_x", wrap(S.settings.rotate_x + 0.5 * dy));
    }
    changed();
  });
  const end = () => { drag = null; };
  model.addEventListener("pointerup", end);
  model.addEventListener("pointercancel", end);
  model.addEventListener("wheel", (ev) => {
    ev.preventDefault();
    setSetting("size", Math.max(5, Math.min(300, S.settings.size * Math.exp(-0.001 * ev.deltaY))));
    changed();
  }, {passive: false});
  $("glints").addEventListener("mousemove", (ev) => {
    const r = ev.target.getBoundingClientRect();
    setAzimuth((2 * (ev.clientX - r.left) / r.width - 1) * S.settings.view_range);
  });
}

function setModel(name, id) {
  if (id !== S.modelId) {
    // Another model: the last exact design, and the one on its way, and the
    // last estimate are not its.
    S.done = null; S.designing = null; S.pending = false; S.estimate = null;
  }
  S.model = name; S.modelId = id;
  $("model-name").textContent = name || "no model";
  $("prompt").hidden = !!name;
  showEstimates();
}

async function download(url, fallback, button) {
  // A plain link cannot carry the secret's header: the file is fetched with it,
  // then saved from memory.
  let reply;
  if (button) { button.disabled = true; button.dataset.label = button.textContent;
                button.textContent = "making\u2026"; }
  try {
    reply = await fetch(url, {headers: {"X-Specholo-Token": TOKEN}});
  } catch (e) {
    showError("the studio server does not answer (was it stopped?)");
    return;
  } finally {
    if (button) { button.disabled = false; button.textContent = button.dataset.label; }
  }
  if (!reply.ok) {
    const data = await reply.json().catch(() => ({error: "bad answer from the server"}));
    showError(data.error);
    return;
  }
  const name = (/filename="([^"]+)"/.exec(reply.headers.get("Content-Disposition") || "") ||
                [null, fallback])[1];
  const a = document.createElement("a");
  a.href = URL.createObjectURL(await reply.blob());
  a.download = name;
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(a.href), 10_000);
}

async function start() {
  bindInputs();
  if (!TOKEN) {
    showError("open the address `specholo studio` printed (it ends with ?token=...)");
    return;
  }
  try {
    const st = await call("GET", "/api/state");
    setupMore(st);
    // The options of #more start blank, the command's defaults (a holder or a
    // spindle the tool implies is the design's to choose), unless saved.
    const blank = Object.fromEntries(moreKeys().map((k) => [k, k === "fit" ? false : null]));
    const settings = Object.assign({}, st.settings, blank, savedSettings(st.model) || {});
    for (const [k, v] of Object.entries(settings)) setSetting(k, v);
    showMore();
    setAzimuth(0);
    setModel(st.model, st.model_id);
    showDesign(st.design);
    S.running = st.design.state === "running";  // (started before this page: not ours to follow)
    if (S.running) poll();
    drawModel();
    changed();
  } catch (e) {
    showError(e.message);
  }
}

// For tests and the curious: the page's state and what it drew.
window.studio = {
  settings: () => Object.assign({}, S.settings),
  glints: () => S.lastGlints.slice(),
  draws: () => S.glintDraws,
  previews: () => S.asked,
  busy: () => S.inFlight || S.dirty,
  // The settings the last finished exact design was made for, and its figures.
  exact: () => S.done && {settings: JSON.parse(S.done.key), summary: S.done.summary,
                          current: S.done.key === key()},
  azimuth: () => S.azimuth,
  command: () => $("command").textContent,
  // The sample design's figures for the current settings, or null.
  estimate: () => S.estimate && S.estimate.key === key() ? S.estimate.figures : null,
};
start();
