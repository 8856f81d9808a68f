// specholo studio: what will be cut. A 3D view of the placed model behind the
// plate, and the plate itself with the exact design's grooves, its registration
// marks and the glints each eye sees. Plate frame, mm: x right, y up, z toward
// the viewer; the plate is z = 0.
//
// Loaded before studio.js, whose state (S) and helpers (call, sent, glintsAt,
// setAzimuth) it reads only when the page tells it something changed
// ("studio:preview", "studio:azimuth", "studio:design" events): it keeps its own
// names to itself, so the two files cannot overwrite each other's functions.
"use strict";

(() => {
  //: The 3D view's camera when the page opens (and on a double-click): turned
  //: enough that the depth of the model behind the plate shows.
  const CAMERA = {yaw: -35, pitch: 20, zoom: 1};
  //: Degrees the camera turns for a pixel of drag (the pose drag's own rate).
  const TURN = 0.5;
  //: A walk along the viewing arc, there and back, ms.
  const WALK_MS = 8000;
  //: Pixels the pointer may move and still click (select a stroke), not pan.
  const CLICK_PX = 4;
  //: How near a stroke the pointer names it, px.
  const HIT_PX = 6;
  //: Deepest zoom of the plate view, px per mm (a 0.1 mm stroke is 500 px long).
  const MAX_ZOOM = 5000;
  //: Paths stroked at a time: one path of a whole design's 130,000 strokes,
  //: round-ended and see-through, is outlined as one shape, 0.2 s on the CPU
  //: (9-18 s on a GPU canvas without a GPU); in 500s it takes 0.05 s.
  const BATCH = 500;
  const LEFT = "#ff4d4d", RIGHT = "#33d6ff", PICK = "#ffd400";

  const C = {
    grooves: null,  // the finished design's grooves, as typed arrays (see take)
    gkey: "",       // which design they are: model, folder, when it finished
    cam: Object.assign({}, CAMERA),
    view: null,     // the plate view: centre (cx, cy) mm and k px per mm
    viewPlate: "",  // the plate the view was fitted to
    hover: -1, picked: -1,  // stipple ids
    walk: 0, frame: 0, draws3d: 0, drawsPlate: 0,
    ms: null,       // how long the last drawing took, ms: each view and the words
    cache: {},      // each view's drawing of what does not move with the eyes
  };
  const el = (id) => document.getElementById(id);
  // Drawn on the CPU: a GPU canvas without a GPU (SwiftShader, a headless or
  // remote browser) took 9 s to show a design's 130,000 strokes, which the
  // CPU draws in some 60 ms.
  const context = (c) => c.getContext("2d", {willReadFrequently: true});
  const rad = (d) => d * Math.PI / 180;

  // ------------------------------------------------------------ the design's grooves
  function take(g, key) {
    const n = g.paths, xy = Float64Array.from(g.xy), off = Int32Array.from(g.offsets);
    const st = Int32Array.from(g.stipple), box = new Float64Array(4 * n);
    for (let q = 0; q < n; q++) {
      let x0 = Infinity, y0 = Infinity, x1 = -Infinity, y1 = -Infinity;
      for (let i = off[q]; i < off[q + 1]; i++) {
        const x = xy[2 * i], y = xy[2 * i + 1];
        if (x < x0) x0 = x; if (x > x1) x1 = x; if (y < y0) y0 = y; if (y > y1) y1 = y;
      }
      box[4 * q] = x0; box[4 * q + 1] = y0; box[4 * q + 2] = x1; box[4 * q + 3] = y1;
    }
    // each stipple's paths together, to draw and measure one stipple at once
    const order = Int32Array.from({length: n}, (_, i) => i).sort((a, b) => st[a] - st[b]);
    const spans = new Map();
    for (let i = 0; i < n;) {
      let j = i;
      while (j < n && st[order[j]] === st[order[i]]) j++;
      spans.set(st[order[i]], [i, j]);
      i = j;
    }
    return {n, xy, off, st, box, order, spans, key, plate: g.plate, width: g.groove_width_mm,
            settings: g.settings, decimated: g.decimated, modelId: g.model_id,
            length: g.groove_length_mm, points: xy.length / 2};
  }

  async function load(key, folder) {
    C.gkey = key;
    let g;
    try {
      // by the folder the status named: a design started since does not take it away
      g = await call("GET", "/api/design/grooves?folder=" + encodeURIComponent(folder));
    } catch (e) {
      if (C.gkey === key) C.gkey = "";
      showError(e.message);
      return;
    }
    if (C.gkey !== key) return;  // another design (or model) since
    C.grooves = take(g, key);
    C.picked = C.hover = -1;
    redraw();
  }

  function onDesign(st) {
    if (C.grooves && C.grooves.modelId !== S.modelId) clear();
    if (st.state === "idle") clear();
    if (st.state !== "done" || st.model_id !== S.modelId) return;
    const key = `${st.model_id}|${st.folder}|${st.seconds}`;
    if (key !== C.gkey) load(key, st.folder);
  }

  function clear() {
    if (!C.grooves && !C.gkey) return;
    C.grooves = null; C.gkey = ""; C.picked = C.hover = -1;
    redraw();
  }

  function stale() {
    // The grooves are the last exact design's: are they of the settings shown?
    const g = C.grooves;
    if (!g) return false;
    for (const [k, v] of Object.entries(sent())) {
      if (v === null) continue;  // a blank: the command's default, as the design took it
      const w = g.settings[k];
      if (typeof v === "number" ? !(Math.abs(v - w) <= 1e-9) : String(v) !== String(w))
        return true;
    }
    return false;
  }

  function plate() {
    // The exact design's plate once there is one; before, the preview's.
    if (C.grooves) return C.grooves.plate;
    return S.preview ? S.preview.plate : null;
  }

  // ------------------------------------------------------------ the eyes
  function eyeGlints() {
    // The left and right eyes sit ipd/2 either side of the head, on the eyes'
    // circle: their azimuths are the head's -/+ the half angle.
    const p = S.preview;
    if (!p) return {head: S.azimuth, left: [], right: [], half: 0};
    const half = p.eye.eye_half_angle_deg;
    return {head: S.azimuth, half, left: glintsAt(S.azimuth - half),
            right: glintsAt(S.azimuth + half)};
  }

  function walk() {
    if (C.walk) { stopWalk(); return; }
    const t0 = performance.now();
    const step = (now) => {
      const range = +S.settings.view_range, u = (now - t0) / WALK_MS;
      if (u >= 1) { setAzimuth(-range); stopWalk(); return; }
      setAzimuth(-range + 2 * range * (u < 0.5 ? 2 * u : 2 - 2 * u));
      C.walk = requestAnimationFrame(step);
    };
    C.walk = requestAnimationFrame(step);
    el("walk").textContent = "Stop";
  }

  function stopWalk() {
    if (C.walk) cancelAnimationFrame(C.walk);
    C.walk = 0;
    el("walk").textContent = "Walk";
  }

  // ------------------------------------------------------------ drawing
  function redraw() {
    // One drawing a frame, however many changes asked for it.
    if (C.frame) return;
    C.frame = requestAnimationFrame(() => {
      C.frame = 0;
      const t0 = performance.now();
      draw3d();
      const t1 = performance.now();
      drawPlate();
      const t2 = performance.now();
      describe();
      C.ms = {view3d: t1 - t0, plate: t2 - t1, words: performance.now() - t2};
    });
  }

  function camera(W, H, R) {
    // Orbit: turn the world by -yaw about y, then by pitch about x; a mild
    // perspective from 4 R away.
    const cy = Math.cos(rad(C.cam.yaw)), sy = Math.sin(rad(C.cam.yaw));
    const cp = Math.cos(rad(C.cam.pitch)), sp = Math.sin(rad(C.cam.pitch));
    const k = 0.42 * Math.min(W, H) / R * C.cam.zoom, dist = 4 * R;
    const turn = (x, y, z) => {
      const x1 = x * cy - z * sy, z1 = x * sy + z * cy;
      return [x1, y * cp - z1 * sp, y * sp + z1 * cp];
    };
    const project = (x, y, z) => {
      const [x2, y2, z2] = turn(x, y, z), f = dist / (dist - z2);
      return [W / 2 + k * f * x2, H / 2 - k * f * y2];
    };
    // the camera is on the viewer's side of the plate when its direction has z > 0
    return {project, turn, front: cy * cp > 0};
  }

  function cached(slot, key, W, H, paint) {
    // What does not move with the eyes is drawn once and copied: a walk redraws
    // only the glints and sightlines over it.
    let kept = C.cache[slot];
    if (!kept || kept.key !== key) {
      const canvas = kept ? kept.canvas : document.createElement("canvas");
      canvas.width = W; canvas.height = H;
      paint(context(canvas));
      C.cache[slot] = kept = {canvas, key};
    }
    return kept.canvas;
  }

  function draw3d() {
    const c = el("view3d"), g = context(c), W = c.width, H = c.height;
    C.draws3d += 1;
    const p = S.preview, pl = plate();
    if (!p) { g.fillStyle = "#000"; g.fillRect(0, 0, W, H); return; }
    // The scene's reach from the origin, in 20 mm steps: the scale holds still
    // while the view turns and while the pose is dragged.
    let R = 10;
    for (let i = 0; i < p.stipples; i++)
      R = Math.max(R, Math.hypot(p.points[3 * i], p.points[3 * i + 1], p.points[3 * i + 2]));
    if (pl) for (const [x, y] of pl.corners_mm) R = Math.max(R, Math.hypot(x, y));
    R = Math.ceil(R / 20) * 20;
    const {project, turn, front} = camera(W, H, R);
    const G = C.grooves;
    const key = JSON.stringify([C.cam, R, W, H, S.asked, pl, G ? G.key : "", G ? stale() : 0]);
    g.drawImage(cached("view3d", key, W, H, (h) => scene3d(h, p, pl, R, project, turn, front)),
                0, 0);
    drawPicked3d(g, project);
    // towards the eyes: the head's azimuth, from the plate's centre
    const t = rad(S.azimuth), D = p.eye.distance, y = p.eye.height;
    const n = Math.hypot(D, y), [ox, oy] = project(0, 0, 0);
    const [ex, ey] = project(1.15 * R * D * Math.sin(t) / n, 1.15 * R * y / n,
                             1.15 * R * D * Math.cos(t) / n);
    g.strokeStyle = "#8a8"; g.setLineDash([4, 4]); g.beginPath();
    g.moveTo(ox, oy); g.lineTo(ex, ey); g.stroke(); g.setLineDash([]);
    g.fillStyle = "#8a8"; g.font = "11px sans-serif";
    g.fillText(`eyes ${S.azimuth.toFixed(1)}\u00b0`, ex + 4, ey);
  }

  function scene3d(g, p, pl, R, project, turn, front) {
    const W = g.canvas.width, H = g.canvas.height;
    g.fillStyle = "#000"; g.fillRect(0, 0, W, H);
    const seen = new Uint8Array(p.stipples);
    for (const s of p.runs.stipple) seen[s] = 1;
    const dots = (behind) => {
      for (const pass of [0, 1]) {
        for (let i = 0; i < p.stipples; i++) {
          const z = p.points[3 * i + 2];
          if (seen[i] !== pass || (z < 0) !== behind) continue;
          g.fillStyle = !seen[i] ? "#555" : z < 0 ? "#4af" : "#fa4";
          const [x, y] = project(p.points[3 * i], p.points[3 * i + 1], z);
          g.fillRect(x - 1, y - 1, 2, 2);
        }
      }
    };
    // painter's order: the far side of the plate, the plate, the near side
    dots(front);
    if (pl) drawPlate3d(g, project, pl);
    dots(!front);
    // which way is which
    g.font = "11px sans-serif";
    for (const [v, col, name] of [[[1, 0, 0], "#e66", "x"], [[0, 1, 0], "#6e6", "y"],
                                  [[0, 0, 1], "#69f", "z"]]) {
      const [x2, y2] = turn(...v);
      g.strokeStyle = col; g.beginPath(); g.moveTo(36, H - 36);
      g.lineTo(36 + 22 * x2, H - 36 - 22 * y2); g.stroke();
      g.fillStyle = col; g.fillText(name, 38 + 26 * x2, H - 33 - 26 * y2);
    }
    g.fillStyle = "#666";
    g.fillText(`turned ${C.cam.yaw.toFixed(0)}\u00b0, tilted ${C.cam.pitch.toFixed(0)}\u00b0` +
               ` \u00b7 \u00b1${R} mm`, 6, 14);
  }

  function drawPlate3d(g, project, pl) {
    const [[x0, y0], [x1, y1]] = pl.corners_mm;
    const corner = [[x0, y0], [x1, y0], [x1, y1], [x0, y1]].map(([x, y]) => project(x, y, 0));
    g.beginPath();
    corner.forEach(([x, y], i) => (i ? g.lineTo(x, y) : g.moveTo(x, y)));
    g.closePath();
    g.fillStyle = "rgba(160, 170, 185, 0.2)"; g.fill();
    g.strokeStyle = C.grooves ? "#aab" : "#778"; g.setLineDash(C.grooves || pl.given ? [] : [5, 4]);
    g.stroke(); g.setLineDash([]);
    marks(g, pl, (x, y) => project(x, y, 0), "#7a8");
    const G = C.grooves;
    if (G) {
      // each path as its chord: at this scale a stroke is a pixel or two
      g.strokeStyle = stale() ? "rgba(150, 150, 150, 0.5)" : "rgba(225, 230, 240, 0.7)";
      g.beginPath();
      for (let q = 0; q < G.n; q++) {
        const a = G.off[q], b = G.off[q + 1] - 1;
        const [sx, sy] = project(G.xy[2 * a], G.xy[2 * a + 1], 0);
        const [tx, ty] = project(G.xy[2 * b], G.xy[2 * b + 1], 0);
        g.moveTo(sx, sy); g.lineTo(tx + (a === b ? 0.5 : 0), ty);
        if (q % BATCH === BATCH - 1) { g.stroke(); g.beginPath(); }
      }
      g.stroke();
    }
    // under the lower-left corner, clear of the model floating over the plate
    const [lx, ly] = corner[0];
    g.fillStyle = "#aab"; g.font = "11px sans-serif";
    g.fillText(`plate ${size(pl)}`, lx + 3, ly + 14);
  }

  function drawPicked3d(g, project) {
    // The stipple named on the plate, and the sightlines from it through its
    // glints to each eye that sees it.
    const p = S.preview, id = C.picked >= 0 ? C.picked : C.hover;
    if (!p || id < 0 || id >= p.stipples || stale()) return;
    const P = [p.points[3 * id], p.points[3 * id + 1], p.points[3 * id + 2]];
    const [px, py] = project(...P);
    const eyes = eyeGlints();
    for (const [list, col] of [[eyes.left, LEFT], [eyes.right, RIGHT]]) {
      const q = list.find((o) => o.id === id);
      if (!q) continue;
      const [qx, qy] = project(q.x, q.y, 0);
      g.strokeStyle = col; g.beginPath(); g.moveTo(px, py); g.lineTo(qx, qy); g.stroke();
    }
    g.strokeStyle = PICK; g.beginPath(); g.arc(px, py, 5, 0, 2 * Math.PI); g.stroke();
  }

  function marks(g, pl, at, colour) {
    // As the SVG and DXF draw them: a crosshair and a circle round its centre.
    g.strokeStyle = colour; g.lineWidth = 1;
    const arm = pl.mark_arm_mm, r = pl.mark_radius_mm;
    for (const [x, y] of pl.marks_mm) {
      g.beginPath();
      g.moveTo(...at(x - arm, y)); g.lineTo(...at(x + arm, y));
      g.moveTo(...at(x, y - arm)); g.lineTo(...at(x, y + arm));
      for (let i = 0; i <= 32; i++) {
        const a = 2 * Math.PI * i / 32, [u, v] = at(x + r * Math.cos(a), y + r * Math.sin(a));
        if (i) g.lineTo(u, v); else g.moveTo(u, v);
      }
      g.stroke();
    }
  }

  function size(pl) {
    const f = (v) => (Math.round(v * 10) / 10).toString();
    return `${f(pl.width_mm)} \u00d7 ${f(pl.height_mm)} mm`;
  }

  // ------------------------------------------------------------ the plate view
  function fitView(force) {
    const pl = plate(), c = el("plate");
    if (!pl) return;
    const id = JSON.stringify(pl.corners_mm);
    if (!force && C.view && C.viewPlate === id) return;
    const [[x0, y0], [x1, y1]] = pl.corners_mm;
    C.view = {cx: (x0 + x1) / 2, cy: (y0 + y1) / 2,
              k: 0.94 * Math.min(c.width / (x1 - x0), c.height / (y1 - y0))};
    C.fitK = C.view.k;
    C.viewPlate = id;
  }

  function toScreen(x, y) {
    const c = el("plate"), v = C.view;
    return [c.width / 2 + v.k * (x - v.cx), c.height / 2 - v.k * (y - v.cy)];
  }

  function toMM(sx, sy) {
    const c = el("plate"), v = C.view;
    return [v.cx + (sx - c.width / 2) / v.k, v.cy - (sy - c.height / 2) / v.k];
  }

  function drawPlate() {
    const c = el("plate"), g = context(c), W = c.width, H = c.height;
    C.drawsPlate += 1;
    const pl = plate();
    if (!pl) { g.fillStyle = "#000"; g.fillRect(0, 0, W, H); return; }
    fitView(false);
    const v = C.view, k = v.k, ox = W / 2 - k * v.cx, oy = H / 2 + k * v.cy;
    const G = C.grooves, id = C.picked >= 0 ? C.picked : C.hover;
    const key = JSON.stringify([v, W, H, pl, G ? G.key : "", G ? stale() : 0, id,
                                el("show-grooves").checked, el("show-marks").checked]);
    g.drawImage(cached("plate", key, W, H, (h) => platePaint(h, pl, ox, oy, k, id)), 0, 0);
    if (el("show-glints").checked) {
      const eyes = eyeGlints();
      for (const [list, col] of [[eyes.left, LEFT], [eyes.right, RIGHT]]) {
        g.fillStyle = col; g.beginPath();
        for (const q of list) {
          const sx = ox + k * q.x, sy = oy - k * q.y;
          g.moveTo(sx + 2.2, sy); g.arc(sx, sy, 2.2, 0, 2 * Math.PI);
        }
        g.fill();
      }
    }
    scaleBar(k);
  }

  function platePaint(g, pl, ox, oy, k, id) {
    const W = g.canvas.width, H = g.canvas.height;
    g.fillStyle = "#000"; g.fillRect(0, 0, W, H);
    const [[x0, y0], [x1, y1]] = pl.corners_mm;
    const [ax, ay] = toScreen(x0, y1), [bx, by] = toScreen(x1, y0);
    g.fillStyle = "#1d2126"; g.fillRect(ax, ay, bx - ax, by - ay);
    const G = C.grooves;
    if (G && el("show-grooves").checked) {
      g.lineCap = "round"; g.lineJoin = "round";
      g.strokeStyle = stale() ? "rgba(150, 150, 150, 0.55)" : "rgba(215, 222, 235, 0.9)";
      g.lineWidth = Math.max(1, G.width * k);
      strokes(g, G, ox, oy, k, null);
      if (id >= 0 && G.spans.has(id)) {
        g.strokeStyle = PICK; g.lineWidth = Math.max(2, G.width * k);
        strokes(g, G, ox, oy, k, G.spans.get(id));
      }
    }
    if (el("show-marks").checked) marks(g, pl, (x, y) => [ox + k * x, oy - k * y], "#7a8");
    g.strokeStyle = C.grooves || pl.given ? "#9aa" : "#778";
    g.setLineDash(C.grooves || pl.given ? [] : [6, 4]);
    g.lineWidth = 1; g.strokeRect(ax, ay, bx - ax, by - ay); g.setLineDash([]);
  }

  function strokes(g, G, ox, oy, k, span) {
    // The paths in view (all, or one stipple's), each a polyline of the
    // design's vertices; a dot (a plunge) is a round cap.
    const c = el("plate"), pad = G.width + 2 / k;
    const [vx0, vy1] = toMM(0, 0), [vx1, vy0] = toMM(c.width, c.height);
    const box = G.box, xy = G.xy, off = G.off;
    const from = span ? span[0] : 0, to = span ? span[1] : G.n;
    let drawn = 0;
    g.beginPath();
    for (let j = from; j < to; j++) {
      const q = span ? G.order[j] : j;
      if (box[4 * q] > vx1 + pad || box[4 * q + 2] < vx0 - pad ||
          box[4 * q + 1] > vy1 + pad || box[4 * q + 3] < vy0 - pad) continue;
      const a = off[q], b = off[q + 1];
      g.moveTo(ox + k * xy[2 * a], oy - k * xy[2 * a + 1]);
      if (b - a === 1) g.lineTo(ox + k * xy[2 * a] + 0.01, oy - k * xy[2 * a + 1]);
      for (let i = a + 1; i < b; i++) g.lineTo(ox + k * xy[2 * i], oy - k * xy[2 * i + 1]);
      if (++drawn % BATCH === 0) { g.stroke(); g.beginPath(); }
    }
    g.stroke();
  }

  function scaleBar(k) {
    // A round length of some 60-150 px, outside the canvas's own pixels.
    const want = 100 / k, step = Math.pow(10, Math.floor(Math.log10(want)));
    const mm = [1, 2, 5, 10].map((m) => m * step).find((m) => m * k >= 60) || 10 * step;
    const bar = el("plate-scale");
    bar.style.width = `${Math.round(mm * k)}px`;
    bar.firstElementChild.textContent = mm >= 1 ? `${+mm.toFixed(0)} mm` :
      `${+(mm * 1000).toFixed(0)} \u00b5m`;
  }

  function hit(sx, sy) {
    // The stipple whose stroke passes nearest the pointer (within HIT_PX), or -1.
    const G = C.grooves;
    if (!G || !C.view || !el("show-grooves").checked) return -1;
    const [mx, my] = toMM(sx, sy), r = HIT_PX / C.view.k + G.width / 2;
    let best = r * r, found = -1;
    for (let q = 0; q < G.n; q++) {
      const b = 4 * q;
      if (G.box[b] > mx + r || G.box[b + 2] < mx - r || G.box[b + 1] > my + r ||
          G.box[b + 3] < my - r) continue;
      for (let i = G.off[q]; i < G.off[q + 1]; i++) {
        const ax = G.xy[2 * i], ay = G.xy[2 * i + 1];
        const last = i + 1 >= G.off[q + 1];
        const bx = last ? ax : G.xy[2 * i + 2], by = last ? ay : G.xy[2 * i + 3];
        const dx = bx - ax, dy = by - ay, L = dx * dx + dy * dy;
        const t = L > 0 ? Math.max(0, Math.min(1, ((mx - ax) * dx + (my - ay) * dy) / L)) : 0;
        const ex = ax + t * dx - mx, ey = ay + t * dy - my, d = ex * ex + ey * ey;
        if (d < best) { best = d; found = G.st[q]; }
        if (last) break;
      }
    }
    return found;
  }

  function stippleText(id) {
    const G = C.grooves, [a, b] = G.spans.get(id);
    let length = 0;
    for (let j = a; j < b; j++) {
      const q = G.order[j];
      for (let i = G.off[q]; i + 1 < G.off[q + 1]; i++)
        length += Math.hypot(G.xy[2 * i + 2] - G.xy[2 * i], G.xy[2 * i + 3] - G.xy[2 * i + 1]);
    }
    let text = `stipple ${id}: ${b - a} path${b - a === 1 ? "" : "s"}, ` +
      `${length.toFixed(2)} mm of groove`;
    const p = S.preview;
    if (p && !stale()) {
      const views = [];
      for (let r = 0; r < p.runs.stipple.length; r++)
        if (p.runs.stipple[r] === id)
          views.push(`${p.runs.start[r].toFixed(1)}\u00b0 to ${p.runs.end[r].toFixed(1)}\u00b0`);
      text += views.length ? `; seen by an eye from ${views.join(", ")}` : "";
    }
    return text;
  }

  function describe() {
    const pl = plate(), G = C.grooves;
    const info = el("plate-info"), note = el("plate-note"), who = el("cut-stipple");
    if (!pl) { info.textContent = ""; note.textContent = ""; who.textContent = ""; return; }
    const what = G ? "the exact design's plate" : pl.given ? "the plate the settings give" :
      "the plate the design would fit (an estimate until it is designed, within 1 mm)";
    info.textContent = `plate ${size(pl)}: ${what}`;
    const lines = [];
    if (!G) {
      lines.push("no exact design yet: its grooves are drawn once one is made");
    } else {
      lines.push(`${G.n.toLocaleString()} paths, ${(G.length / 1000).toFixed(2)} m of groove ` +
                 `(width ${(1000 * G.width).toFixed(0)} \u00b5m)`);
      const d = G.decimated;
      if (d) lines.push(`only every ${d.stride}${d.stride === 2 ? "nd" : d.stride === 3 ? "rd" :
        "th"} stipple's grooves are drawn: ${d.stipples_drawn.toLocaleString()} of ` +
        `${d.stipples_cut.toLocaleString()} stipples, ${d.points_drawn.toLocaleString()} of ` +
        `${d.points_all.toLocaleString()} points (the studio sends at most ` +
        `${d.max_points.toLocaleString()}; the folder's SVG has them all)`);
      if (stale()) lines.push("the grooves (grey) are of the last exact design: the settings " +
                              "have changed since");
    }
    const eyes = eyeGlints();
    lines.push(`head at ${eyes.head.toFixed(1)}\u00b0: the left eye (red) sees ` +
               `${eyes.left.length} glints, the right eye (cyan) ${eyes.right.length}`);
    note.textContent = lines.join(". ") + ".";
    const id = C.picked >= 0 ? C.picked : C.hover;
    who.textContent = G && id >= 0 && G.spans.has(id) ?
      stippleText(id) + (C.picked >= 0 ? " (click elsewhere to let go)" : "") : "";
  }

  // ------------------------------------------------------------ input
  function bindOrbit() {
    const c = el("view3d");
    let drag = null;
    c.addEventListener("pointerdown", (ev) => {
      drag = {x: ev.clientX, y: ev.clientY};
      c.setPointerCapture(ev.pointerId);
    });
    c.addEventListener("pointermove", (ev) => {
      if (!drag) return;
      C.cam.yaw = ((C.cam.yaw - TURN * (ev.clientX - drag.x)) % 360 + 540) % 360 - 180;
      C.cam.pitch = Math.max(-89, Math.min(89, C.cam.pitch + TURN * (ev.clientY - drag.y)));
      drag = {x: ev.clientX, y: ev.clientY};
      redraw();
    });
    const end = () => { drag = null; };
    c.addEventListener("pointerup", end);
    c.addEventListener("pointercancel", end);
    c.addEventListener("dblclick", () => { C.cam = Object.assign({}, CAMERA); redraw(); });
    c.addEventListener("wheel", (ev) => {
      ev.preventDefault();
      C.cam.zoom = Math.max(0.3, Math.min(20, C.cam.zoom * Math.exp(-0.0015 * ev.deltaY)));
      redraw();
    }, {passive: false});
  }

  function bindPlate() {
    const c = el("plate");
    let drag = null;
    const at = (ev) => {
      // canvas pixels: inside the border, at the canvas's own resolution
      const r = c.getBoundingClientRect();
      return [(ev.clientX - r.left - c.clientLeft) * c.width / c.clientWidth,
              (ev.clientY - r.top - c.clientTop) * c.height / c.clientHeight];
    };
    c.addEventListener("wheel", (ev) => {
      ev.preventDefault();
      if (!C.view) return;
      // about the pointer: the point under it stays under it
      const [sx, sy] = at(ev), [mx, my] = toMM(sx, sy);
      C.view.k = Math.max(C.fitK / 2, Math.min(MAX_ZOOM, C.view.k * Math.exp(-0.0015 * ev.deltaY)));
      C.view.cx = mx - (sx - c.width / 2) / C.view.k;
      C.view.cy = my + (sy - c.height / 2) / C.view.k;
      redraw();
    }, {passive: false});
    c.addEventListener("pointerdown", (ev) => {
      const [sx, sy] = at(ev);
      drag = {sx, sy, x: sx, y: sy, moved: false};
      c.setPointerCapture(ev.pointerId);
    });
    c.addEventListener("pointermove", (ev) => {
      const [sx, sy] = at(ev);
      if (drag && C.view) {
        drag.moved = drag.moved || Math.hypot(sx - drag.sx, sy - drag.sy) > CLICK_PX;
        if (drag.moved) {
          C.view.cx -= (sx - drag.x) / C.view.k;
          C.view.cy += (sy - drag.y) / C.view.k;
          drag.x = sx; drag.y = sy;
          redraw();
        }
        return;
      }
      const id = hit(sx, sy);
      if (id !== C.hover) { C.hover = id; redraw(); }
    });
    c.addEventListener("pointerup", (ev) => {
      if (drag && !drag.moved) {
        const [sx, sy] = at(ev);
        C.picked = hit(sx, sy);
        redraw();
      }
      drag = null;
    });
    c.addEventListener("pointercancel", () => { drag = null; });
    c.addEventListener("pointerleave", () => {
      if (!drag && C.hover >= 0) { C.hover = -1; redraw(); }
    });
    c.addEventListener("dblclick", () => { fitView(true); redraw(); });
    for (const id of ["show-grooves", "show-glints", "show-marks"])
      el(id).addEventListener("change", redraw);
    el("walk").addEventListener("click", walk);
    // the maker takes the azimuth back: the walk stops
    el("azimuth").addEventListener("input", stopWalk);
    el("glints").addEventListener("mousemove", stopWalk);
  }

  document.addEventListener("studio:preview", redraw);
  document.addEventListener("studio:azimuth", redraw);
  document.addEventListener("studio:design", (ev) => onDesign(ev.detail));
  bindOrbit();
  bindPlate();

  // For tests and the curious: what these views hold and drew.
  window.studioCut = {
    camera: () => Object.assign({}, C.cam),
    draws3d: () => C.draws3d,
    drawsPlate: () => C.drawsPlate,
    grooves: () => C.grooves && {paths: C.grooves.n, points: C.grooves.points,
                                 plate: C.grooves.plate, decimated: C.grooves.decimated,
                                 width: C.grooves.width, stale: stale()},
    view: () => C.view && Object.assign({}, C.view),
    toScreen: (x, y) => toScreen(x, y),
    plate: () => plate(),
    hovered: () => C.hover,
    picked: () => C.picked,
    eyeGlints: () => eyeGlints(),
    walking: () => C.walk !== 0,
    pending: () => C.frame !== 0,
    ms: () => C.ms && Object.assign({}, C.ms),
    // a design's grooves asked for and not yet here
    loading: () => C.gkey !== "" && !(C.grooves && C.grooves.key === C.gkey),
  };
})();
