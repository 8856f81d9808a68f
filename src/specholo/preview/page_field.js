// The glints of a plate given as a height field (a ridged design), one eye at a time.
// The glints of a grid of views are precomputed (specholo.preview.page.FieldViews,
// with the physics of specholo.simulation.heightfield.find_field_glints); the page
// draws the view nearest the pointer's with the camera of
// specholo.preview.render.Camera: a dark plate in perspective, a spot at each glint.
"use strict";
(function () {
  const meta = JSON.parse(document.getElementById("meta").textContent);
  const canvas = document.getElementById("view");
  const anglesEl = document.getElementById("angles");
  const messageEl = document.getElementById("message");
  const params = new URLSearchParams(window.location.search);
  const DEG = Math.PI / 180;
  const AZ = meta.views.azimuths, EL = meta.views.elevations;
  // Glint spots: Gaussian of this many CSS pixels, in this colour (as the GPU page).
  const SIGMA = 1.1, GLINT = [255, 245, 224];
  const BACKGROUND = "rgb(5, 6, 7)", PLATE = "rgb(15, 17, 19)";

  const state = { azimuth: 0, elevation: 0, view: 0, dirty: true };
  let start = null, xyz = null;
  const hook = {
    ready: false, error: null,
    setView(az, el) { setView(az, el); draw(); return hook.getView(); },
    getView() {
      const [ia, ie] = nearestView();
      return {
        mode: "field", azimuth: state.azimuth, elevation: state.elevation,
        viewAzimuth: AZ[ia], viewElevation: EL[ie], view: ia * EL.length + ie,
        distance: meta.camera.distance, eyeHeight: meta.camera.eyeHeight,
        fov: meta.camera.fov, width: canvas.width, height: canvas.height,
        glints: start ? start[ia * EL.length + ie + 1] - start[ia * EL.length + ie] : 0,
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
  function nearest(values, v) {
    let best = 0;
    for (let i = 1; i < values.length; i++) {
      if (Math.abs(values[i] - v) < Math.abs(values[best] - v)) best = i;
    }
    return best;
  }
  const nearestView = () => [nearest(AZ, state.azimuth), nearest(EL, state.elevation)];

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

  function draw() {
    if (!start) return;
    const [ia, ie] = nearestView();
    const view = ia * EL.length + ie;
    const project = camera(AZ[ia], EL[ie]);
    ctx.globalCompositeOperation = "source-over";
    ctx.fillStyle = BACKGROUND;
    ctx.fillRect(0, 0, canvas.width, canvas.height);
    const [[x0, y0], [x1, y1]] = meta.plate;
    const corners = [[x0, y0], [x1, y0], [x1, y1], [x0, y1]].map(([x, y]) => project(x, y, 0));
    if (corners.every((c) => c)) {
      ctx.fillStyle = PLATE;
      ctx.beginPath();
      corners.forEach(([u, v], k) => (k ? ctx.lineTo(u, v) : ctx.moveTo(u, v)));
      ctx.closePath();
      ctx.fill();
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
    anglesEl.textContent = `azimuth ${sign(state.azimuth)}   elevation ${sign(state.elevation)}`
      + `   shown: view ${sign(AZ[ia])}, ${sign(EL[ie])}`
      + `   ${start[view + 1] - start[view]} glints`;
  }

  function frame() {
    if (state.dirty) draw();
    window.requestAnimationFrame(frame);
  }

  let drag = null;
  canvas.addEventListener("pointerdown", (ev) => {
    drag = { x: ev.clientX, y: ev.clientY, az: state.azimuth, el: state.elevation };
    canvas.setPointerCapture(ev.pointerId);
    canvas.style.cursor = "grabbing";
  });
  canvas.addEventListener("pointermove", (ev) => {
    if (!drag) return;
    const k = meta.limits.degreesPerPixel;
    setView(drag.az + (ev.clientX - drag.x) * k, drag.el - (ev.clientY - drag.y) * k);
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
  setView(+params.get("az") || 0, +params.get("el") || 0);
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
