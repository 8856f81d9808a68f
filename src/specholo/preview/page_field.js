// Glints precomputed per view, one eye at a time: a plate given as a height field
// (a ridged design), or any kind's glints along its motion (a turning plate, a
// moving light, a curved host). The glints of a grid of views are found beforehand
// (specholo.preview.page.FieldViews, with each kind's own glint finder); the page
// draws the view nearest the pointer's, and the motion's state nearest the
// slider's, with the camera of specholo.preview.render.Camera: a dark plate (or
// a host's edges) in perspective, a spot at each glint.
"use strict";
(function () {
  const meta = JSON.parse(document.getElementById("meta").textContent);
  const canvas = document.getElementById("view");
  const anglesEl = document.getElementById("angles");
  const messageEl = document.getElementById("message");
  const params = new URLSearchParams(window.location.search);
  const DEG = Math.PI / 180;
  const AZ = meta.views.azimuths, EL = meta.views.elevations;
  // The motion's states (degrees), if the glints move with more than the eye.
  const ST = meta.views.states || [];
  const NS = Math.max(ST.length, 1);
  const MOTION = ST.length ? meta.motion : null;
  const LINE = "rgb(46, 50, 58)";
  // Glint spots: Gaussian of this many CSS pixels, in this colour (as the GPU page).
  const SIGMA = 1.1, GLINT = [255, 245, 224];
  const BACKGROUND = "rgb(5, 6, 7)", PLATE = "rgb(15, 17, 19)";

  const state = { azimuth: 0, elevation: 0, motion: MOTION ? MOTION.start : 0, view: 0,
                  dirty: true };
  let start = null, xyz = null;
  const hook = {
    ready: false, error: null,
    setView(az, el, st) {
      setView(az, el);
      if (st !== undefined) setMotion(st);
      draw();
      return hook.getView();
    },
    getView() {
      const [ia, ie, is] = nearestView();
      const view = (ia * EL.length + ie) * NS + is;
      return {
        mode: "field", azimuth: state.azimuth, elevation: state.elevation,
        viewAzimuth: AZ[ia], viewElevation: EL[ie], view: view,
        motion: MOTION ? state.motion : null, viewState: MOTION ? ST[is] : null,
        distance: meta.camera.distance, eyeHeight: meta.camera.eyeHeight,
        fov: meta.camera.fov, width: canvas.width, height: canvas.height,
        glints: start ? start[view + 1] - start[view] : 0,
        views: meta.counts.views,
      };
    },
  };
  window.specholo = hook;

  function fail(text) {
    hook.error = text;
    messageEl.textContent = text;
    messageEl.hidden = false;
    anglesEl.textContent = "";
  }

  const clamp = (v, lo, hi) => Math.min(hi, Math.max(lo, v));
  const dpr = () => window.devicePixelRatio || 1;
  function setView(az, el) {
    state.azimuth = clamp(+az, -meta.limits.azimuth, meta.limits.azimuth);
    state.elevation = clamp(+el, -meta.limits.elevation, meta.limits.elevation);
    state.dirty = true;
  }
  // A closed motion (a whole turn) wraps: 359 degrees is next to 0.
  const period = MOTION && MOTION.closed ? MOTION.high - MOTION.low : 0;
  function setMotion(v) {
    v = +v;
    if (!MOTION || !Number.isFinite(v)) return;
    state.motion = period ? MOTION.low + (((v - MOTION.low) % period) + period) % period
      : clamp(v, MOTION.low, MOTION.high);
    state.dirty = true;
  }
  function gap(a, b, wrap) {
    const d = Math.abs(a - b);
    return wrap ? Math.min(d, wrap - d) : d;
  }
  function nearest(values, v, wrap) {
    let best = 0;
    for (let i = 1; i < values.length; i++) {
      if (gap(values[i], v, wrap) < gap(values[best], v, wrap)) best = i;
    }
    return best;
  }
  const nearestView = () => [nearest(AZ, state.azimuth, 0), nearest(EL, state.elevation, 0),
                             MOTION ? nearest(ST, state.motion, period) : 0];

  const fixedW = +params.get("w") || (meta.size ? meta.size[0] : 0);
  const fixedH = +params.get("h") || (meta.size ? meta.size[1] : 0);
  function resize() {
    const hud = document.getElementById("hud").offsetHeight;
    const cssW = fixedW || window.innerWidth;
    const cssH = fixedH || Math.max(1, window.innerHeight - hud);
    canvas.style.width = cssW + "px";
    canvas.style.height = cssH + "px";
    canvas.width = Math.round(cssW * dpr());
    canvas.height = Math.round(cssH * dpr());
    state.dirty = true;
  }

  const ctx = canvas.getContext("2d", { alpha: false });
  if (!ctx) {
    fail("This page needs a 2D canvas, which this browser does not offer.");
    return;
  }

  // The page's arrays: one base64 text of gzipped blocks (see page.py pack_blocks).
  async function loadBlocks() {
    const el = document.getElementById("data");
    const text = el.textContent.trim();
    el.remove();
    const bin = atob(text);
    const bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    const out = {};
    await Promise.all(meta.blocks.map(async (b) => {
      const gz = new Blob([bytes.subarray(b.offset, b.offset + b.length)]);
      const stream = gz.stream().pipeThrough(new DecompressionStream("gzip"));
      out[b.name] = new Uint8Array(await new Response(stream).arrayBuffer());
    }));
    return out;
  }

  // Glint positions (mm) from their uint16 columns: low bytes, then high bytes.
  function decode(blocks) {
    const u8 = blocks.start;
    start = new Uint32Array(u8.buffer, u8.byteOffset, u8.byteLength / 4);
    const n = meta.counts.glints;
    xyz = new Float64Array(3 * n);
    ["x", "y", "z"].forEach((name, k) => {
      const b = blocks[name], o = meta.quant.origin[k], s = meta.quant.scale[k];
      for (let i = 0; i < n; i++) xyz[3 * i + k] = o + (b[i] | (b[n + i] << 8)) * s;
    });
  }

  // The camera of preview.render.Camera at the shown view: on a sphere about
  // (0, eyeHeight, 0), looking at the plate centre; basis rows right, up, forward.
  function camera(azDeg, elDeg) {
    const az = azDeg * DEG, el = elDeg * DEG, d = meta.camera.distance;
    const eye = [d * Math.cos(el) * Math.sin(az), meta.camera.eyeHeight + d * Math.sin(el),
                 d * Math.cos(el) * Math.cos(az)];
    const n = Math.hypot(eye[0], eye[1], eye[2]);
    const fwd = [-eye[0] / n, -eye[1] / n, -eye[2] / n];
    const rn = Math.hypot(fwd[2], fwd[0]);
    const right = [-fwd[2] / rn, 0, fwd[0] / rn];  // fwd x (0, 1, 0)
    const up = [right[1] * fwd[2] - right[2] * fwd[1], right[2] * fwd[0] - right[0] * fwd[2],
                right[0] * fwd[1] - right[1] * fwd[0]];
    // Camera.project's focal length; canvas pixel centres sit at integer + 0.5.
    const f = 0.5 * canvas.height / Math.tan(0.5 * meta.camera.fov * DEG);
    return (x, y, z) => {
      const qx = x - eye[0], qy = y - eye[1], qz = z - eye[2];
      const depth = fwd[0] * qx + fwd[1] * qy + fwd[2] * qz;
      if (depth <= 1e-9) return null;
      return [0.5 * canvas.width + f * (right[0] * qx + right[1] * qy + right[2] * qz) / depth,
              0.5 * canvas.height - f * (up[0] * qx + up[1] * qy + up[2] * qz) / depth];
    };
  }

  // One Gaussian spot, drawn once and stamped at every glint.
  let sprite = null, spriteFor = 0;
  function spot() {
    if (sprite && spriteFor === dpr()) return sprite;
    const sigma = SIGMA * dpr(), r = Math.ceil(3 * sigma), size = 2 * r + 1;
    sprite = document.createElement("canvas");
    sprite.width = sprite.height = size;
    const sctx = sprite.getContext("2d");
    const img = sctx.createImageData(size, size);
    for (let j = 0; j < size; j++) {
      for (let i = 0; i < size; i++) {
        const dx = i + 0.5 - 0.5 * size, dy = j + 0.5 - 0.5 * size;
        const w = Math.exp(-(dx * dx + dy * dy) / (2 * sigma * sigma));
        const k = 4 * (j * size + i);
        img.data[k] = GLINT[0] * w; img.data[k + 1] = GLINT[1] * w;
        img.data[k + 2] = GLINT[2] * w; img.data[k + 3] = 255;
      }
    }
    sctx.putImageData(img, 0, 0);
    spriteFor = dpr();
    return sprite;
  }

  // What lies under the glints at a state: the plate (a polygon at z = 0, or none
  // on a curved host) and faint lines (a host's edges, a turning plate's mark).
  function shapeOf(ia, is) {
    if (!meta.shapes) {
      const [[x0, y0], [x1, y1]] = meta.plate;
      return { plate: [[x0, y0], [x1, y0], [x1, y1], [x0, y1]], lines: [] };
    }
    // one for all views, or one per state along a motion, or per azimuth without one
    return meta.shapes[meta.shapes.length === 1 ? 0 : (MOTION ? is : ia)];
  }

  function draw() {
    if (!start) return;
    const [ia, ie, is] = nearestView();
    const view = (ia * EL.length + ie) * NS + is;
    const project = camera(AZ[ia], EL[ie]);
    ctx.globalCompositeOperation = "source-over";
    ctx.fillStyle = BACKGROUND;
    ctx.fillRect(0, 0, canvas.width, canvas.height);
    const shape = shapeOf(ia, is);
    const corners = shape.plate ? shape.plate.map(([x, y]) => project(x, y, 0)) : [];
    if (corners.length && corners.every((c) => c)) {
      ctx.fillStyle = PLATE;
      ctx.beginPath();
      corners.forEach(([u, v], k) => (k ? ctx.lineTo(u, v) : ctx.moveTo(u, v)));
      ctx.closePath();
      ctx.fill();
    }
    ctx.strokeStyle = LINE;
    ctx.lineWidth = dpr();
    for (const line of shape.lines) {
      ctx.beginPath();
      let open = false;
      for (const [x, y, z] of line) {
        const p = project(x, y, z);
        if (!p) { open = false; continue; }
        if (open) ctx.lineTo(p[0], p[1]); else ctx.moveTo(p[0], p[1]);
        open = true;
      }
      ctx.stroke();
    }
    ctx.globalCompositeOperation = "lighter";  // overlapping glints add up, like light
    const s = spot(), half = 0.5 * s.width;
    for (let g = start[view]; g < start[view + 1]; g++) {
      const p = project(xyz[3 * g], xyz[3 * g + 1], xyz[3 * g + 2]);
      if (p) ctx.drawImage(s, p[0] - half, p[1] - half);
    }
    state.view = view;
    state.dirty = false;
    const sign = (v) => (v >= 0 ? "+" : "\u2212") + Math.abs(v).toFixed(1) + "\u00b0";
    const along = MOTION ? `   ${MOTION.name} ${ST[is].toFixed(1)}\u00b0` : "";
    anglesEl.textContent = `azimuth ${sign(state.azimuth)}   elevation ${sign(state.elevation)}`
      + `   shown: view ${sign(AZ[ia])}, ${sign(EL[ie])}${along}`
      + `   ${start[view + 1] - start[view]} glints`;
  }

  function frame() {
    if (state.dirty) draw();
    window.requestAnimationFrame(frame);
  }

  let drag = null;
  canvas.addEventListener("pointerdown", (ev) => {
    drag = { x: ev.clientX, y: ev.clientY, az: state.azimuth, el: state.elevation,
             motion: state.motion, eye: !MOTION || ev.shiftKey };
    canvas.setPointerCapture(ev.pointerId);
    canvas.style.cursor = "grabbing";
  });
  canvas.addEventListener("pointermove", (ev) => {
    if (!drag) return;
    const k = meta.limits.degreesPerPixel;
    if (drag.eye) {
      setView(drag.az + (ev.clientX - drag.x) * k, drag.el - (ev.clientY - drag.y) * k);
    } else {
      // Along the motion: its whole range over 600 CSS pixels of drag.
      setMotion(drag.motion + (ev.clientX - drag.x) * (MOTION.high - MOTION.low) / 600);
    }
  });
  const release = (ev) => {
    if (!drag) return;
    drag = null;
    if (canvas.hasPointerCapture(ev.pointerId)) canvas.releasePointerCapture(ev.pointerId);
    canvas.style.cursor = "";
  };
  canvas.addEventListener("pointerup", release);
  canvas.addEventListener("pointercancel", release);
  window.addEventListener("resize", resize);

  resize();
  const opening = meta.start || { azimuth: 0, elevation: 0 };
  setView(params.has("az") ? +params.get("az") : opening.azimuth,
          params.has("el") ? +params.get("el") : opening.elevation);
  if (params.has("at")) setMotion(+params.get("at"));
  loadBlocks().then((blocks) => {
    decode(blocks);
    draw();
    hook.ready = true;
    window.requestAnimationFrame(frame);
  }).catch((err) => {
    fail("Could not load the page's data: " + err.message);
    console.error(err);
  });
})();
