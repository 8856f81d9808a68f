// Interactive glints of a specular hologram, recomputed on the GPU every frame.
// Physics and camera mirror specholo.simulation.glints.find_glints and
// specholo.preview.render.Camera; see specholo/preview/page.py.
"use strict";
(function () {
  const meta = JSON.parse(document.getElementById("meta").textContent);
  const canvas = document.getElementById("view");
  const anglesEl = document.getElementById("angles");
  const messageEl = document.getElementById("message");
  const params = new URLSearchParams(window.location.search);
  const DEG = Math.PI / 180;

  const state = {
    azimuth: 0, elevation: 0, light: meta.light.elevation,
    dirty: true, spin: false, frames: [], drawMs: [], last: null,
  };
  const hook = {
    ready: false, error: null,
    setView(az, el) { setView(az, el); return hook.getView(); },
    setLight(deg) { setLight(deg); return hook.getView(); },
    getView() {
      return {
        azimuth: state.azimuth, elevation: state.elevation, light: state.light,
        lightDistance: meta.light.distance, distance: meta.camera.distance,
        eyeHeight: meta.camera.eyeHeight, fov: meta.camera.fov,
        width: canvas.width, height: canvas.height, arcs: meta.counts.arcs,
        corners: meta.counts.corners, dots: meta.counts.dots,
      };
    },
    // Intervals between drawn frames (ms), and CPU+GPU time of each draw when syncing.
    frameTimes() { return state.frames.slice(); },
    drawTimes() { return state.drawMs.slice(); },
    spin(on, sync) {
      state.spin = !!on; state.sync = !!sync; state.frames = []; state.drawMs = [];
      state.last = null; state.dirty = true;
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
  function setView(az, el) {
    state.azimuth = clamp(+az, -meta.limits.azimuth, meta.limits.azimuth);
    state.elevation = clamp(+el, -meta.limits.elevation, meta.limits.elevation);
    state.dirty = true;
  }
  function setLight(deg) {
    state.light = clamp(+deg, 1, 179);
    state.dirty = true;
  }

  // Canvas size: URL ?w=&h= first, then the page's fixed size, else the window.
  const fixedW = +params.get("w") || (meta.size ? meta.size[0] : 0);
  const fixedH = +params.get("h") || (meta.size ? meta.size[1] : 0);
  function resize() {
    const hud = document.getElementById("hud").offsetHeight;
    const cssW = fixedW || window.innerWidth;
    const cssH = fixedH || Math.max(1, window.innerHeight - hud);
    const dpr = window.devicePixelRatio || 1;
    canvas.style.width = cssW + "px";
    canvas.style.height = cssH + "px";
    canvas.width = Math.round(cssW * dpr);
    canvas.height = Math.round(cssH * dpr);
    state.dirty = true;
  }

  const gl = canvas.getContext("webgl2", { antialias: false, alpha: false,
                                            preserveDrawingBuffer: true });
  if (!gl) {
    fail("This page needs WebGL2, which this browser does not offer (or has disabled). "
         + "Try a current Chrome, Firefox or Safari with hardware acceleration on.");
    return;
  }

  function decode(id) {
    const text = document.getElementById(id).textContent.trim();
    let bytes;
    if (typeof Uint8Array.fromBase64 === "function") {
      bytes = Uint8Array.fromBase64(text);
    } else {
      const bin = atob(text);
      bytes = new Uint8Array(bin.length);
      for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    }
    return new Float32Array(bytes.buffer, bytes.byteOffset, bytes.byteLength / 4);
  }

  const GLINT_VS = `#version 300 es
precision highp float;
layout(location = 0) in vec2 a_p;    // arc start or dimple centre, mm (plate frame)
layout(location = 1) in vec4 a_arc;  // start tangent angle, length, signed sweep, turn
uniform int u_mode;                  // 0 arcs, 1 corners, 2 dimples
uniform vec3 u_eye;
uniform vec3 u_light;                // sun direction, or point light position
uniform bool u_pointLight;
uniform float u_R;                   // ball radius
uniform float u_cz;                  // ball centre height R - d
uniform float u_cosTilt;             // cos(max wall tilt)
uniform vec3 u_right, u_up, u_fwd;   // camera basis
uniform vec2 u_proj;                 // focal / half-size, x and y
uniform float u_size;
uniform float u_noCorner;
out float v_on;

vec3 hAt(vec3 g) {
  vec3 l = u_pointLight ? normalize(u_light - g) : u_light;
  return l + normalize(u_eye - g);
}
// The wall point whose normal (toward the ball centre) is h: fixed point as in wall_glint.
vec3 wallPoint(vec2 p) {
  vec3 c = vec3(p, u_cz);
  vec3 g = vec3(p, 0.0);
  for (int i = 0; i < 3; ++i) g = c - u_R * normalize(hAt(g));
  return g;
}
// Point at parameter u in [0, 1], from the start and the chord (stable for any sweep).
vec2 arcAt(float u) {
  float half_ = 0.5 * u * a_arc.z;
  float sinc = abs(half_) > 1e-4 ? sin(half_) / half_ : 1.0 - half_ * half_ / 6.0;
  float ang = a_arc.x + half_;
  return a_p + (u * a_arc.y * sinc) * vec2(cos(ang), sin(ang));
}
vec2 tangentAt(float u) {
  float a = a_arc.x + u * a_arc.z;
  return vec2(cos(a), sin(a));
}
float wallCond(float u) {
  vec3 g = wallPoint(arcAt(u));
  return dot(hAt(g).xy, tangentAt(u));
}
bool tiltOk(vec3 h) { return h.z >= u_cosTilt * length(h); }

void emit(vec3 g) {
  vec3 q = g - u_eye;
  float z = dot(u_fwd, q);
  if (z <= 1e-6) return;
  gl_Position = vec4(dot(u_right, q) * u_proj.x, dot(u_up, q) * u_proj.y, 0.0, z);
  gl_PointSize = u_size;
  v_on = 1.0;
}

void main() {
  gl_Position = vec4(2.0, 2.0, 2.0, 1.0);  // off-screen unless a glint is emitted
  gl_PointSize = 1.0;
  v_on = 0.0;
  if (u_mode == 2) {
    vec3 g = wallPoint(a_p);
    if (tiltOk(hAt(g))) emit(g);
    return;
  }
  if (u_mode == 1) {
    // Corner after this arc: the ball sweeps every direction between the two tangents.
    if (a_arc.w >= u_noCorner) return;
    vec2 p = arcAt(1.0);
    vec2 te = tangentAt(1.0);
    float an = a_arc.x + a_arc.z + a_arc.w;
    vec2 tn = vec2(cos(an), sin(an));
    vec3 h0 = hAt(vec3(p, 0.0));
    float e0 = dot(h0.xy, te);
    if (e0 * dot(h0.xy, tn) > 0.0 && abs(e0) >= 0.01 * length(h0)) return;  // cheap screen
    vec3 g = wallPoint(p);
    vec3 h = hAt(g);
    if (dot(h.xy, te) * dot(h.xy, tn) < 0.0 && tiltOk(h)) emit(g);
    return;
  }
  // Screen on the toolpath first (the wall moves h by only ~R / distance).
  vec3 hs = hAt(vec3(a_p, 0.0));
  float s0 = dot(hs.xy, tangentAt(0.0));
  float s1 = dot(hAt(vec3(arcAt(1.0), 0.0)).xy, tangentAt(1.0));
  if (s0 * s1 > 0.0 && min(abs(s0), abs(s1)) >= 0.01 * length(hs)) return;
  float f0 = wallCond(0.0);
  float f1 = wallCond(1.0);
  // A root exactly on a shared vertex belongs to the arc that starts there.
  if (!(f0 == 0.0 || f0 * f1 < 0.0)) return;
  float a = 0.0, b = 1.0, fa = f0, fb = f1, side = 0.0, u = 0.0;
  for (int i = 0; i < ${meta.iterations}; ++i) {
    u = fa == fb ? a : (a * fb - b * fa) / (fb - fa);
    float fu = wallCond(u);
    if (fa * fu > 0.0) {
      a = u; fa = fu;
      if (side > 0.0) fb *= 0.5;  // Illinois: keep the stale end moving
      side = 1.0;
    } else {
      b = u; fb = fu;
      if (side < 0.0) fa *= 0.5;
      side = -1.0;
    }
  }
  u = clamp(u, 0.0, 1.0);
  vec3 g = wallPoint(arcAt(u));
  if (tiltOk(hAt(g))) emit(g);
}`;

  const GLINT_FS = `#version 300 es
precision highp float;
in float v_on;
uniform float u_size;
uniform float u_sigma;
out vec4 color;
void main() {
  if (v_on < 0.5) discard;
  vec2 d = (gl_PointCoord - 0.5) * u_size;
  float w = exp(-dot(d, d) / (2.0 * u_sigma * u_sigma));
  color = vec4(w * vec3(1.0, 0.96, 0.88), 1.0);
}`;

  const PLATE_VS = `#version 300 es
precision highp float;
layout(location = 0) in vec2 a_p;
uniform vec3 u_eye, u_right, u_up, u_fwd;
uniform vec2 u_proj;
void main() {
  vec3 q = vec3(a_p, 0.0) - u_eye;
  gl_Position = vec4(dot(u_right, q) * u_proj.x, dot(u_up, q) * u_proj.y, 0.0, dot(u_fwd, q));
}`;
  const PLATE_FS = `#version 300 es
precision mediump float;
out vec4 color;
void main() { color = vec4(0.06, 0.065, 0.075, 1.0); }`;

  function program(vsText, fsText) {
    const prog = gl.createProgram();
    for (const [type, text] of [[gl.VERTEX_SHADER, vsText], [gl.FRAGMENT_SHADER, fsText]]) {
      const sh = gl.createShader(type);
      gl.shaderSource(sh, text);
      gl.compileShader(sh);
      if (!gl.getShaderParameter(sh, gl.COMPILE_STATUS)) {
        throw new Error("shader: " + gl.getShaderInfoLog(sh));
      }
      gl.attachShader(prog, sh);
    }
    gl.linkProgram(prog);
    if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) {
      throw new Error("program: " + gl.getProgramInfoLog(prog));
    }
    const loc = {};
    const n = gl.getProgramParameter(prog, gl.ACTIVE_UNIFORMS);
    for (let i = 0; i < n; i++) {
      const name = gl.getActiveUniform(prog, i).name;
      loc[name] = gl.getUniformLocation(prog, name);
    }
    return { prog, loc };
  }

  let glint, plate, arcVao, cornerVao, dotVao, plateVao;
  const arcCount = meta.counts.arcs, dotCount = meta.counts.dots;
  const cornerCount = meta.counts.corners;
  try {
    glint = program(GLINT_VS, GLINT_FS);
    plate = program(PLATE_VS, PLATE_FS);
    const arcs = decode("arcs");
    const dots = decode("dots");
    const arcVaoOf = (data) => {
      const vao = gl.createVertexArray();
      gl.bindVertexArray(vao);
      gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
      gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
      gl.enableVertexAttribArray(0);
      gl.vertexAttribPointer(0, 2, gl.FLOAT, false, 24, 0);
      gl.enableVertexAttribArray(1);
      gl.vertexAttribPointer(1, 4, gl.FLOAT, false, 24, 8);
      return vao;
    };
    arcVao = arcVaoOf(arcs);
    cornerVao = arcVaoOf(decode("corners"));
    dotVao = gl.createVertexArray();
    gl.bindVertexArray(dotVao);
    gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
    gl.bufferData(gl.ARRAY_BUFFER, dots, gl.STATIC_DRAW);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 2, gl.FLOAT, false, 8, 0);
    gl.vertexAttrib4f(1, 0, 0, 0, meta.noCorner);
    const [[x0, y0], [x1, y1]] = meta.plate;
    plateVao = gl.createVertexArray();
    gl.bindVertexArray(plateVao);
    gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
    gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([x0, y0, x1, y0, x1, y1, x0, y1]),
                  gl.STATIC_DRAW);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 2, gl.FLOAT, false, 8, 0);
    gl.bindVertexArray(null);
  } catch (err) {
    fail("Could not set up WebGL2: " + err.message);
    console.error(err);
    return;
  }

  // The camera of preview.render.Camera: on a sphere about (0, eyeHeight, 0),
  // looking at the plate centre; basis rows right, up, forward.
  function camera() {
    const az = state.azimuth * DEG, el = state.elevation * DEG, d = meta.camera.distance;
    const eye = [d * Math.cos(el) * Math.sin(az), meta.camera.eyeHeight + d * Math.sin(el),
                 d * Math.cos(el) * Math.cos(az)];
    const n = Math.hypot(eye[0], eye[1], eye[2]);
    const fwd = [-eye[0] / n, -eye[1] / n, -eye[2] / n];
    let right = [-fwd[2], 0, fwd[0]];  // fwd x (0, 1, 0)
    const rn = Math.hypot(right[0], right[2]);
    right = [right[0] / rn, 0, right[2] / rn];
    const up = [right[1] * fwd[2] - right[2] * fwd[1], right[2] * fwd[0] - right[0] * fwd[2],
                right[0] * fwd[1] - right[1] * fwd[0]];
    const t = Math.tan(0.5 * meta.camera.fov * DEG);
    // Pixel centres at integer + 0.5 in GL match Camera.project's (W - 1) / 2 centre.
    const proj = [canvas.height / (canvas.width * t), 1 / t];
    return { eye, right, up, fwd, proj };
  }

  function setCamera(loc, cam) {
    gl.uniform3fv(loc.u_eye, cam.eye);
    gl.uniform3fv(loc.u_right, cam.right);
    gl.uniform3fv(loc.u_up, cam.up);
    gl.uniform3fv(loc.u_fwd, cam.fwd);
    gl.uniform2fv(loc.u_proj, cam.proj);
  }

  function draw() {
    const cam = camera();
    gl.viewport(0, 0, canvas.width, canvas.height);
    gl.clearColor(0.02, 0.022, 0.027, 1);
    gl.clear(gl.COLOR_BUFFER_BIT);
    gl.disable(gl.DEPTH_TEST);
    gl.disable(gl.BLEND);
    gl.useProgram(plate.prog);
    setCamera(plate.loc, cam);
    gl.bindVertexArray(plateVao);
    gl.drawArrays(gl.TRIANGLE_FAN, 0, 4);

    const L = glint.loc;
    gl.useProgram(glint.prog);
    setCamera(L, cam);
    const a = state.light * DEG;
    const dir = [0, Math.cos(a), Math.sin(a)];
    const dist = meta.light.distance;
    gl.uniform3fv(L.u_light, dist ? dir.map((v) => v * dist) : dir);
    gl.uniform1i(L.u_pointLight, dist ? 1 : 0);
    gl.uniform1f(L.u_R, meta.tool.radius);
    gl.uniform1f(L.u_cz, meta.tool.radius - meta.tool.depth);
    gl.uniform1f(L.u_cosTilt, Math.cos(meta.tool.maxTilt));
    gl.uniform1f(L.u_noCorner, meta.noCorner);
    const dpr = window.devicePixelRatio || 1;
    gl.uniform1f(L.u_size, 2 * Math.ceil(2.5 * dpr) + 1);
    gl.uniform1f(L.u_sigma, 1.1 * dpr);
    gl.enable(gl.BLEND);
    gl.blendFunc(gl.ONE, gl.ONE);  // overlapping glints add up, like light
    gl.bindVertexArray(arcVao);
    gl.uniform1i(L.u_mode, 0);
    if (arcCount) gl.drawArrays(gl.POINTS, 0, arcCount);
    gl.bindVertexArray(cornerVao);
    gl.uniform1i(L.u_mode, 1);
    if (cornerCount) gl.drawArrays(gl.POINTS, 0, cornerCount);
    gl.bindVertexArray(dotVao);
    gl.uniform1i(L.u_mode, 2);
    if (dotCount) gl.drawArrays(gl.POINTS, 0, dotCount);
    gl.bindVertexArray(null);

    const sign = (v) => (v >= 0 ? "+" : "\u2212") + Math.abs(v).toFixed(1) + "\u00b0";
    anglesEl.textContent = `azimuth ${sign(state.azimuth)}   elevation ${sign(state.elevation)}`
      + `   light ${state.light.toFixed(1)}\u00b0`;
  }

  function frame(now) {
    if (state.spin) {
      // Keep the view changing so every frame recomputes every glint.
      const t = now / 1000;
      setView(meta.viewRange * Math.sin(0.7 * t), 5 * Math.sin(0.31 * t));
    }
    if (state.dirty) {
      state.dirty = false;
      const t0 = performance.now();
      draw();
      if (state.sync) gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(4));
      if (state.spin) {
        state.drawMs.push(performance.now() - t0);
        if (state.last !== null) state.frames.push(now - state.last);
        state.last = now;
      }
    }
    window.requestAnimationFrame(frame);
  }

  // Dragging moves the eye like moving your head (right = azimuth up, up = higher);
  // shift+drag raises or lowers the light.
  let drag = null;
  canvas.addEventListener("pointerdown", (ev) => {
    drag = { x: ev.clientX, y: ev.clientY, az: state.azimuth, el: state.elevation,
             light: state.light };
    canvas.setPointerCapture(ev.pointerId);
    canvas.style.cursor = "grabbing";
  });
  canvas.addEventListener("pointermove", (ev) => {
    if (!drag) return;
    const k = meta.limits.degreesPerPixel;
    const dx = ev.clientX - drag.x, dy = ev.clientY - drag.y;
    if (ev.shiftKey) {
      setLight(drag.light - dy * k);
    } else {
      setView(drag.az + dx * k, drag.el - dy * k);
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
  setView(+params.get("az") || 0, +params.get("el") || 0);
  if (params.has("light")) setLight(+params.get("light"));
  draw();
  state.dirty = false;
  hook.ready = true;
  window.requestAnimationFrame(frame);
})();
