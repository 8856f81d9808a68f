// Interactive glints of a specular hologram, recomputed on the GPU every frame.
// Physics and camera mirror specholo.simulation.glints.find_glints and
// specholo.preview.render.Camera; the data format is specholo.preview.page.PageArcs.
// On a GPU each narrow glint is a point sprite. A software rasterizer (SwiftShader,
// llvmpipe) spends about a microsecond on every point it draws, whatever its size,
// and more compositing a WebGL canvas than drawing a frame: there workers solve the
// arcs with the shader's steps and add up the sprites' spots, and the page draws the
// frame on a 2D canvas (startLanes(), present()).
"use strict";
(function () {
  const meta = JSON.parse(document.getElementById("meta").textContent);
  const canvas = document.getElementById("view");
  const anglesEl = document.getElementById("angles");
  const messageEl = document.getElementById("message");
  const params = new URLSearchParams(window.location.search);
  const DEG = Math.PI / 180;
  const STEPS = meta.grid.angleSteps;
  // ?cull=0 draws every narrow arc (to check that culling loses no glint).
  const culling = params.get("cull") !== "0";
  // Whether the glints' spots are added up in the script (set once WebGL is up).
  let splatting = false;

  const state = {
    azimuth: 0, elevation: 0, light: meta.light.elevation,
    dirty: true, spin: false, frames: [], drawMs: [], drawn: [], cullMs: [], lastDrawn: 0,
    lastCullMs: 0, last: null, spinFrame: 0,
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
        narrow: meta.counts.narrow, wide: meta.counts.wide,
        corners: meta.counts.corners, dots: meta.counts.dots,
        drawn: state.lastDrawn, culling, mode: splatting ? "splat" : "sprites",
      };
    },
    // Intervals between drawn frames (ms), CPU+GPU time of each draw when syncing,
    // the arcs drawn (narrow ones kept by culling, plus the wide ones) and the time
    // culling took (ms) per frame.
    frameTimes() { return state.frames.slice(); },
    drawTimes() { return state.drawMs.slice(); },
    drawnArcs() { return state.drawn.slice(); },
    cullTimes() { return state.cullMs.slice(); },
    spin(on, sync) {
      state.spin = !!on; state.sync = !!sync; state.frames = []; state.drawMs = [];
      state.drawn = []; state.cullMs = []; state.last = null; state.dirty = true;
      state.spinFrame = 0;
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
  // Glint spots: Gaussian of this many CSS pixels, in this colour.
  const SIGMA = 1.1, GLINT_COLOR = [1.0, 0.96, 0.88];
  const BACKGROUND = [0.02, 0.022, 0.027], PLATE_COLOR = [0.06, 0.065, 0.075];
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
    canvas.style.width = cssW + "px";
    canvas.style.height = cssH + "px";
    canvas.width = Math.round(cssW * dpr());
    canvas.height = Math.round(cssH * dpr());
    state.dirty = true;
  }

  // The canvas is only redrawn when the view changes; the compositor keeps the last
  // frame, so the drawing buffer need not be kept (which costs a copy per frame).
  const glOptions = { antialias: false, alpha: false, preserveDrawingBuffer: false };
  const probe = document.createElement("canvas").getContext("webgl2", glOptions);
  if (!probe) {
    fail("This page needs WebGL2, which this browser does not offer (or has disabled). "
         + "Try a current Chrome, Firefox or Safari with hardware acceleration on.");
    return;
  }
  // Splat on a software rasterizer (?splat=1 or ?splat=0 forces either way).
  let rendererName = String(probe.getParameter(probe.RENDERER));
  if (/^WebKit/.test(rendererName)) {  // masked (Chrome, Safari)
    const info = probe.getExtension("WEBGL_debug_renderer_info");
    if (info) rendererName = String(probe.getParameter(info.UNMASKED_RENDERER_WEBGL));
  }
  const softwareGL = /SwiftShader|llvmpipe|softpipe|Software/i.test(rendererName);
  splatting = params.has("splat") ? params.get("splat") === "1" : softwareGL;
  // Splatting draws whole frames in the script onto a 2D canvas: there compositing a
  // WebGL canvas costs more than the frame itself. Its WebGL context, never shown,
  // only draws the spot table once.
  let gl = probe, ctx2d = null;
  if (splatting) {
    ctx2d = canvas.getContext("2d", { alpha: false });
  } else {
    const lose = probe.getExtension("WEBGL_lose_context");
    if (lose) lose.loseContext();
    gl = canvas.getContext("webgl2", glOptions);
  }
  if (!gl || (splatting && !ctx2d)) {
    fail("Could not set up the canvas.");
    return;
  }

  // The page's arrays: one base64 text of gzipped blocks (see page.py pack_blocks).
  async function loadBlocks() {
    const el = document.getElementById("data");
    const text = el.textContent.trim();
    el.remove();  // the text is over a byte per arc: let it go once decoded
    let bytes;
    if (typeof Uint8Array.fromBase64 === "function") {
      bytes = Uint8Array.fromBase64(text);
    } else {
      const bin = atob(text);
      bytes = new Uint8Array(bin.length);
      for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    }
    const out = {};
    await Promise.all(meta.blocks.map(async (b) => {
      const gz = new Blob([bytes.subarray(b.offset, b.offset + b.length)]);
      const stream = gz.stream().pipeThrough(new DecompressionStream("gzip"));
      out[b.name] = new Uint8Array(await new Response(stream).arrayBuffer());
    }));
    return out;
  }
  const floats = (u8) => new Float32Array(u8.buffer, u8.byteOffset, u8.byteLength / 4);

  // Narrow rows x0, y0, x1, y1, q0, q1 (uint16) from their columns: low bytes
  // then high bytes, x1 - x0, y1 - y0, q1 - q0 and q0's steps stored mod 2^16;
  // split into `shares` by plate row of cells (row iy to share iy % shares: each
  // share then has about as many glints, whatever the view). Per share, its rows and
  // cellStart (the cells of other shares empty).
  function narrowRows(blocks, shares) {
    const X = blocks.x0, Y = blocks.y0, DX = blocks.dx, DY = blocks.dy;
    const Q = blocks.q0, DQ = blocks.dq;
    const n = counts.narrow, nx = meta.grid.nx;
    const start = new Uint32Array(blocks.cellStart.buffer, 0,
                                  blocks.cellStart.byteLength / 4);
    const nc = start.length - 1;
    const out = Array.from({ length: shares }, () => ({
      rows: null, cellStart: new Uint32Array(nc + 1), size: 0,
    }));
    for (let c = 0; c < nc; c++) {
      for (const share of out) share.cellStart[c] = share.size;
      out[Math.floor(c / nx) % shares].size += start[c + 1] - start[c];
    }
    for (const share of out) {
      share.cellStart[nc] = share.size;
      share.rows = new Uint16Array(6 * share.size);
    }
    let q = 0;
    for (let c = 0; c < nc; c++) {
      const { rows, cellStart } = out[Math.floor(c / nx) % shares];
      for (let i = start[c], j = 6 * cellStart[c]; i < start[c + 1]; i++, j += 6) {
        const x = X[i] | (X[n + i] << 8), y = Y[i] | (Y[n + i] << 8);
        q = (q + (Q[i] | (Q[n + i] << 8))) & 0xffff;
        rows[j] = x;
        rows[j + 1] = y;
        rows[j + 2] = x + (DX[i] | (DX[n + i] << 8));  // Uint16Array stores wrap mod 2^16
        rows[j + 3] = y + (DY[i] | (DY[n + i] << 8));
        rows[j + 4] = q;
        rows[j + 5] = q + (DQ[i] | (DQ[n + i] << 8));
      }
    }
    return out;
  }

  const glintVS = (narrow, iterations) => `#version 300 es
precision highp float;
precision highp int;
#define NARROW ${narrow ? 1 : 0}
#define POINT_LIGHT ${meta.light.distance ? 1 : 0}
#define ITERATIONS ${iterations}
#if NARROW
layout(location = 2) in uvec4 a_ends;  // x0, y0, x1, y1 in grid units
layout(location = 3) in uvec2 a_tan;   // tangent angles mod pi at the ends, q0 and q1 steps
#else
layout(location = 0) in vec2 a_p;      // arc start or dimple centre, mm (plate frame)
layout(location = 1) in vec4 a_arc;    // start tangent angle, length, signed sweep, turn
#endif
uniform int u_mode;                    // float rows: 0 arcs, 1 corners, 2 dimples
uniform vec3 u_eye;
uniform vec3 u_light;                  // sun direction, or point light position
uniform float u_R;                     // ball radius
uniform float u_cz;                    // ball centre height R - d
uniform float u_cosTilt;               // cos(max wall tilt)
uniform vec3 u_right, u_up, u_fwd;     // camera basis
uniform vec2 u_proj;                   // focal / half-size, x and y
uniform float u_size;
uniform float u_noCorner;
uniform vec3 u_grid;                   // narrow rows: origin (mm) and mm per grid unit

const float STEP = 3.14159265358979 / ${STEPS}.0;  // radians per angle step

vec3 hAt(vec3 g) {
#if POINT_LIGHT
  return normalize(u_light - g) + normalize(u_eye - g);
#else
  return u_light + normalize(u_eye - g);
#endif
}
// The wall point whose normal (toward the ball centre) is h, from h at the toolpath
// point p: one step of wall_glint's fixed point. h changes by ~R / distance between
// steps, so this is within ~1e-4 mm of the fixed point.
vec3 wallFrom(vec2 p, vec3 h) { return vec3(p, u_cz) - u_R * normalize(h); }
vec3 wallPoint(vec2 p) { return wallFrom(p, hAt(vec3(p, 0.0))); }
vec2 dir(float a) { return vec2(cos(a), sin(a)); }
bool tiltOk(vec3 h) { return h.z >= u_cosTilt * length(h); }

void emit(vec3 g) {
  vec3 q = g - u_eye;
  float z = dot(u_fwd, q);
  if (z <= 1e-6) return;
  gl_Position = vec4(dot(u_right, q) * u_proj.x, dot(u_up, q) * u_proj.y, 0.0, z);
  gl_PointSize = u_size;
}

// The arc being solved: end points and unit tangents there.
vec2 P0, P1, T0, T1;
#if NARROW
// A narrow arc turns by at most 0.02 rad: its point at chord parameter u is
// P0 + u C + u (1 - u) BOW to ~L sweep^3 (1e-8 mm), and the direction mix(T0, T1, u)
// turns evenly to ~sweep^3; h . t only needs a direction, not a unit vector.
vec2 BOW;
vec2 pointAt(float u) { return P0 + u * (P1 - P0) + (u - u * u) * BOW; }
vec2 tangentAt(float u) { return mix(T0, T1, u); }
#else
float A0, SW, LEN;
float sinc(float x) { return abs(x) > 1e-4 ? sin(x) / x : 1.0 - x * x / 6.0; }
// Point at parameter u in [0, 1], from the start (stable for any sweep).
vec2 pointAt(float u) {
  float half_ = 0.5 * u * SW;
  return P0 + (u * LEN * sinc(half_)) * dir(A0 + half_);
}
vec2 tangentAt(float u) { return dir(A0 + u * SW); }
#endif

void solveArc() {
  // Screen on the toolpath first (the wall moves h by only ~R / distance).
  vec3 h0 = hAt(vec3(P0, 0.0)), h1 = hAt(vec3(P1, 0.0));
  float s0 = dot(h0.xy, T0), s1 = dot(h1.xy, T1);
  if (s0 * s1 > 0.0 && min(abs(s0), abs(s1)) >= 0.01 * length(h0)) return;
  // The ends are evaluated from the end points alone, exactly as a joined arc
  // evaluates them: a root is bracketed by exactly one of the two arcs.
  vec3 g0 = wallFrom(P0, h0), g1 = wallFrom(P1, h1);
  float f0 = dot(hAt(g0).xy, T0), f1 = dot(hAt(g1).xy, T1);
  // A root exactly on an arc's start counts, as in find_glints.
  if (!(f0 == 0.0 || f0 * f1 < 0.0)) return;
  // The wall offset R h/|h| turns by ~(arc length) / distance along the arc:
  // interpolate it between the ends instead of solving for it at every step.
  vec3 w0 = g0 - vec3(P0, 0.0), w1 = g1 - vec3(P1, 0.0);
  float a = 0.0, b = 1.0, fa = f0, fb = f1, side = 0.0, u = 0.0;
  for (int i = 0; i < ITERATIONS; ++i) {
    u = fa == fb ? a : (a * fb - b * fa) / (fb - fa);
    float fu = dot(hAt(vec3(pointAt(u), 0.0) + mix(w0, w1, u)).xy, tangentAt(u));
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
  vec3 g = vec3(pointAt(u), 0.0) + mix(w0, w1, u);
  if (tiltOk(hAt(g))) emit(g);
}

void main() {
  gl_Position = vec4(2.0, 2.0, 2.0, 1.0);  // off-screen unless a glint is emitted
  gl_PointSize = 1.0;
#if NARROW
  P0 = u_grid.xy + vec2(a_ends.xy) * u_grid.z;
  P1 = u_grid.xy + vec2(a_ends.zw) * u_grid.z;
  int q0 = int(a_tan.x), q1 = int(a_tan.y);
  int dq = ((q1 - q0 + 32768) & 65535) - 32768;
  // The end directions as the joined arcs compute them (from q0 and q1 alone);
  // q0 + dq is q1 or q1 +- pi, and the stored angles are mod pi: the chord
  // says which way the arc runs.
  T0 = dir(float(q0) * STEP);
  T1 = (q0 + dq == q1 ? 1.0 : -1.0) * dir(float(q1) * STEP);
  vec2 c = P1 - P0;
  float sgn = dot(c, T0 + T1) >= 0.0 ? 1.0 : -1.0;
  T0 *= sgn;
  T1 *= sgn;
  BOW = (-0.5 * float(dq) * STEP) * vec2(-c.y, c.x);
  solveArc();
#else
  if (u_mode == 2) {
    vec3 g = wallPoint(a_p);
    if (tiltOk(hAt(g))) emit(g);
    return;
  }
  P0 = a_p;
  A0 = a_arc.x; LEN = a_arc.y; SW = a_arc.z;
  P1 = pointAt(1.0);
  T0 = dir(A0);
  T1 = dir(A0 + SW);
  if (u_mode == 0) { solveArc(); return; }
  // Corner after this arc: the ball sweeps every direction between the two tangents.
  if (a_arc.w >= u_noCorner) return;
  vec2 tn = dir(A0 + SW + a_arc.w);
  vec3 h0 = hAt(vec3(P1, 0.0));
  float e0 = dot(h0.xy, T1);
  if (e0 * dot(h0.xy, tn) > 0.0 && abs(e0) >= 0.01 * length(h0)) return;  // cheap screen
  vec3 g = wallFrom(P1, h0);
  vec3 h = hAt(g);
  if (dot(h.xy, T1) * dot(h.xy, tn) < 0.0 && tiltOk(h)) emit(g);
#endif
}`;

  // Only emitted glints reach the rasterizer (the others are clipped away): a
  // Gaussian spot each.
  const SPRITE_FS = `#version 300 es
precision highp float;
uniform float u_size;
uniform float u_gauss;                 // -1 / (2 sigma^2 ln 2), per pixel^2
out vec4 color;
void main() {
  vec2 d = (gl_PointCoord - 0.5) * u_size;
  color = vec4(exp2(dot(d, d) * u_gauss) * vec3(${GLINT_COLOR.join(", ")}), 1.0);
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
void main() { color = vec4(${PLATE_COLOR.join(", ")}, 1.0); }`;
  // Lone sprites at window positions a_w (pixels) on a framebuffer u_fb pixels square.
  const CALIBRATE_VS = `#version 300 es
layout(location = 0) in vec2 a_w;
uniform float u_fb;
uniform float u_size;
void main() {
  gl_Position = vec4(a_w / u_fb * 2.0 - 1.0, 0.0, 1.0);
  gl_PointSize = u_size;
}`;

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

  // --- The glint search of the narrow arcs (and, splatting, of all) ------------------
  // Self-contained: the page's workers run it from its source text. data: the narrow
  // rows (uint16 x0, y0, x1, y1, q0, q1) of some cells, cellStart (the rows of cell c
  // are [cellStart[c], cellStart[c + 1])), cells (each cell's reach and sweep), and
  // for splatting the float rows (wide, corners, dots) and the spot table.
  function glintSearch(meta, data) {
    const { rows, cellStart, cells } = data;
    const STEPS = meta.grid.angleSteps, STEP = Math.PI / STEPS;
    // Added to the culling's bounds on angles (radians) and on h . t for the shader's
    // float32 rounding (~1e-6).
    const SLACK = 1e-5;
    const BUCKET_SHIFT = 10, BUCKETS = STEPS >> BUCKET_SHIFT;
    // Unit vectors of the angle steps (tangent directions mod pi).
    const COS = new Float64Array(STEPS), SIN = new Float64Array(STEPS);
    for (let q = 0; q < STEPS; q++) { COS[q] = Math.cos(q * STEP); SIN[q] = Math.sin(q * STEP); }
    // buckets[c * (BUCKETS + 1) + b]: first row of cell c with q0 >= b << BUCKET_SHIFT.
    const nc = cellStart.length - 1;
    const buckets = new Uint32Array(nc * (BUCKETS + 1));
    for (let c = 0; c < nc; c++) {
      let i = cellStart[c];
      const i1 = cellStart[c + 1];
      for (let b = 0; b <= BUCKETS; b++) {
        const v = b << BUCKET_SHIFT;
        while (i < i1 && rows[6 * i + 4] < v) i++;
        buckets[c * (BUCKETS + 1) + b] = i;
      }
    }
    let indices = new Uint32Array(1 << 16);

    // The narrow arcs that may glint. A glint of an arc sits on the groove wall within
    // WALL of its toolpath point (|(0, 0, R - d) - R h/|h|| for any h above the plate),
    // so within rho = (the cell's reach) + WALL of its cell's centre c. Both unit vectors
    // of h = l + e move by at most rho / (distance - rho) between c and there: h at the
    // glint is within `margin` of h at c, and h_xy turns by at most asin(margin / |h_xy|).
    // Window: rows are sorted by start angle q0 within each cell and an arc's tangents
    // span [q0, q0 + its sweep], so the arcs with a tangent that close to perpendicular
    // to h_xy at c have q0 in a window reaching back by the cell's largest sweep.
    // Screens, in turn (the shader finds a glint only where h . t on the wall changes
    // sign between the arc's ends, or is 0 at its start):
    // - h at c: |h . t| is least at an end of the arc's tangents unless it changes sign
    //   between them; one sign and more than `margin` at both ends, and no h near
    //   enough is perpendicular to any of them.
    // - h . t at the ends, as the shader has it, to first order about c: the shader's
    //   wall point moved by the wall offset at c instead, and h linear in the point
    //   (each unit vector u = (p - x) / |p - x| by its gradient -(I - u u^T) / |p - x|).
    //   Second order: |D^2 u| <= 6 / r^2 bounds the rest by 3 rho^2 / (r - rho)^2; the
    //   wall point moves by at most R * 2 margin / (2 |h| - margin), which moves h by
    //   that over (r - rho). One sign and more than those at both ends: no glint.
    // A cell whose h at c tilts from the plate normal by more than the wall allows plus
    // asin(margin / |h|) has no glint at all.
    const R = meta.tool.radius, CZ = meta.tool.radius - meta.tool.depth;
    const WALL = Math.hypot(R, CZ), TILT = meta.tool.maxTilt;
    const pointLight = !!meta.light.distance;

    // The cell's constants for screen(): its centre c (cx, cy), h there (hx, hy, hz),
    // the unit vectors toward the eye (ex, ey, ez) and the light (lx, ly, lz) and one
    // over their distances (ie, il; il = 0 for a sun), the wall offset at c (wx, wy, wz),
    // and the bounds on h . t's moves (margin, lin).
    const cellK = {
      cx: 0, cy: 0, hx: 0, hy: 0, hz: 0, ex: 0, ey: 0, ez: 0, ie: 0, lx: 0, ly: 0, lz: 0,
      il: 0, wx: 0, wy: 0, wz: 0, margin: 0, lin: 0,
    };

    // Screen rows [i0, i1), appending the kept ones to indices from n; returns the new n.
    function screen(i0, i1, n, k) {
      const { scale: sc, origin: [ox, oy] } = meta.grid;
      const { hx, hy, ex, ey, ez, ie, lx, ly, lz, il, margin, lin } = k;
      // The wall points as offsets d from c: the table's coordinates plus these.
      const bx = ox - k.cx + k.wx, by = oy - k.cy + k.wy, dz = k.wz;
      for (let i = i0, j = 6 * i0; i < i1; i++, j += 6) {
        const q0 = rows[j + 4], q1 = rows[j + 5];
        // q0 + sweep past pi: the end tangent is -dir(q1). A sign common to both
        // ends changes no test below.
        const flip = q0 + (((q1 - q0 + 32768) & 65535) - 32768) === q1 ? 1 : -1;
        const t0x = COS[q0], t0y = SIN[q0], t1x = flip * COS[q1], t1y = flip * SIN[q1];
        const c0 = hx * t0x + hy * t0y, c1 = hx * t1x + hy * t1y;
        if (c0 * c1 > 0 && Math.min(Math.abs(c0), Math.abs(c1)) > margin) continue;
        const d0x = bx + rows[j] * sc, d0y = by + rows[j + 1] * sc;
        const d1x = bx + rows[j + 2] * sc, d1y = by + rows[j + 3] * sc;
        // h . t - ((d . t) - (u . d)(u . t)) / r for each unit vector u.
        let f0 = c0 - (d0x * t0x + d0y * t0y - (ex * d0x + ey * d0y + ez * dz)
                       * (ex * t0x + ey * t0y)) * ie;
        let f1 = c1 - (d1x * t1x + d1y * t1y - (ex * d1x + ey * d1y + ez * dz)
                       * (ex * t1x + ey * t1y)) * ie;
        if (il) {
          f0 -= (d0x * t0x + d0y * t0y - (lx * d0x + ly * d0y + lz * dz) * (lx * t0x + ly * t0y)) * il;
          f1 -= (d1x * t1x + d1y * t1y - (lx * d1x + ly * d1y + lz * dz) * (lx * t1x + ly * t1y)) * il;
        }
        if (f0 * f1 > 0 && Math.min(Math.abs(f0), Math.abs(f1)) > lin) continue;
        indices[n++] = i;
      }
      return n;
    }

    // First row of cell c with q0 >= v (v in [0, STEPS]): the bucket table narrows the
    // search to the rows of one bucket of angles.
    function lowerBound(c, v) {
      if (v >= STEPS) return cellStart[c + 1];
      const k = c * (BUCKETS + 1) + (v >> BUCKET_SHIFT);
      let lo = buckets[k], hi = buckets[k + 1];
      while (lo < hi) {
        const m = (lo + hi) >>> 1;
        if (rows[6 * m + 4] < v) lo = m + 1; else hi = m;
      }
      return lo;
    }

    // The narrow rows that may glint, into indices; returns their number.
    function cull(eye, light) {
      const { nx, ny, cell: size } = meta.grid;
      const [ox, oy] = meta.grid.origin;
      const k = cellK;
      let n = 0;
      const take = (i0, i1) => {
        if (n + i1 - i0 > indices.length) {
          const grown = new Uint32Array(Math.max(2 * indices.length, n + i1 - i0));
          grown.set(indices.subarray(0, n));
          indices = grown;
        }
        n = screen(i0, i1, n, k);
      };
      const takeKeys = (c, a, b) => take(lowerBound(c, a), lowerBound(c, b + 1));
      for (let iy = 0; iy < ny; iy++) {
        const y = oy + (iy + 0.5) * size;
        for (let ix = 0; ix < nx; ix++) {
          const c = iy * nx + ix;
          const i0 = cellStart[c], i1 = cellStart[c + 1];
          if (i0 === i1) continue;
          const x = ox + (ix + 0.5) * size;
          k.cx = x; k.cy = y;
          const rho = cells[2 * c] + WALL, sweep = cells[2 * c + 1];
          let ax = eye[0] - x, ay = eye[1] - y, az = eye[2];
          const de = Math.sqrt(ax * ax + ay * ay + az * az);
          k.ex = ax / de; k.ey = ay / de; k.ez = az / de; k.ie = 1 / de;
          let margin = rho / (de - rho), lin = 3 * rho * rho / ((de - rho) * (de - rho));
          let lip = 1 / (de - rho);  // how much h moves per mm the wall point moves
          let near = de <= rho;
          if (pointLight) {
            ax = light[0] - x; ay = light[1] - y; az = light[2];
            const dl = Math.sqrt(ax * ax + ay * ay + az * az);
            k.lx = ax / dl; k.ly = ay / dl; k.lz = az / dl; k.il = 1 / dl;
            margin += rho / (dl - rho);
            lin += 3 * rho * rho / ((dl - rho) * (dl - rho));
            lip += 1 / (dl - rho);
            near = near || dl <= rho;
          } else {
            k.lx = light[0]; k.ly = light[1]; k.lz = light[2]; k.il = 0;
          }
          k.hx = k.ex + k.lx; k.hy = k.ey + k.ly; k.hz = k.ez + k.lz;
          const h = Math.sqrt(k.hx * k.hx + k.hy * k.hy + k.hz * k.hz);
          k.wx = -R * k.hx / h; k.wy = -R * k.hy / h; k.wz = CZ - R * k.hz / h;
          lin += R * 2 * margin / (2 * h - margin) * lip + SLACK;
          k.margin = margin + SLACK;
          k.lin = near || !(margin < h) ? Infinity : lin;
          if (near) { k.margin = Infinity; take(i0, i1); continue; }
          // The shader keeps glints whose h tilts by at most maxTilt from the normal.
          if (margin < h && Math.acos(k.hz / h) > TILT + Math.asin(margin / h) + SLACK) continue;
          const hxy = Math.sqrt(k.hx * k.hx + k.hy * k.hy);
          if (!(margin < hxy)) { take(i0, i1); continue; }
          const delta = Math.asin(margin / hxy) + SLACK;
          const want = Math.atan2(k.hy, k.hx) + 0.5 * Math.PI;  // t perpendicular to h_xy
          const lo = want - delta - sweep, hi = want + delta;
          if (hi - lo >= Math.PI) { take(i0, i1); continue; }
          let qlo = Math.floor(lo / STEP), qhi = Math.ceil(hi / STEP);
          const wrap = Math.floor(qlo / STEPS) * STEPS;  // angles are mod pi
          qlo -= wrap; qhi -= wrap;
          if (qhi < STEPS) {
            takeKeys(c, qlo, qhi);
          } else {
            takeKeys(c, qlo, STEPS - 1);
            takeKeys(c, 0, qhi - STEPS);
          }
        }
      }
      return n;
    }


    // --- The shader's solver (glintVS), in float64 --------------------------------
    // A glint lands within float32 rounding of the shader's (1/16 px, or a little
    // more along a nearly straight groove). Per frame: the eye, the sun's direction
    // or the light's position, pl = 1 for a point light, the camera, and the
    // viewport transform (half-size in subpixels, hw and hh).
    const cosTilt = Math.cos(TILT);
    let ex = 0, ey = 0, ez = 0, lx = 0, ly = 0, lz = 0, pl = 0;
    let rx = 0, ry = 0, rz = 0, ux = 0, uy = 0, uz = 0, fx = 0, fy = 0, fz = 0;
    let pjx = 0, pjy = 0, hw = 0, hh = 0, sub = 1;
    // h = e / |e| + l s_l at g: one over the eye's distance, and the light's scale
    // (one over its distance, or 1 for a sun). The solver spells h out in place:
    // functions writing it somewhere cost twice the time.
    const eyeScale = (x, y, z) => 1 / Math.sqrt((ex - x) ** 2 + (ey - y) ** 2 + (ez - z) ** 2);
    const lightScale = (x, y, z) => (pl ? 1 / Math.sqrt((lx - x) ** 2 + (ly - y) ** 2
                                                         + (lz - z) ** 2) : 1);

    // The spots' sums (RGBA words, bytes saturating) and the rectangle they touch
    // (x0, y0, x1, y1, inclusive; empty when x1 < x0), in window pixels (y up).
    let sums = null, width = 0, height = 0, box = [0, 0, -1, -1];
    let table = data.table;
    // The sprites' centres found (x, y pairs, in subpixels) and how many.
    let spots = new Int32Array(1 << 17), found = 0;

    // The glint at g: its sprite's centre as the rasterizer places it (the viewport
    // transform in its order, half-size + clip / w * half-size, rounded to its
    // subpixel grid).
    function emit(gx, gy, gz) {
      const qx = gx - ex, qy = gy - ey, qz = gz - ez;
      const z = fx * qx + fy * qy + fz * qz;
      if (z <= 1e-6) return;
      const cx = (rx * qx + ry * qy + rz * qz) * pjx, cy = (ux * qx + uy * qy + uz * qz) * pjy;
      const sx = Math.round(hw + cx * (1 / z) * hw), sy = Math.round(hh + cy * (1 / z) * hh);
      if (!(Math.abs(sx) < 1e9 && Math.abs(sy) < 1e9)) return;  // far off
      if (2 * found + 2 > spots.length) {
        const grown = new Int32Array(2 * spots.length);
        grown.set(spots);
        spots = grown;
      }
      spots[2 * found] = sx;
      spots[2 * found + 1] = sy;
      found++;
    }

    // Add the table's spot for each sprite found, for its place in its pixel.
    // Pixels are RGBA words; each byte adds up saturating at 255, as blending does:
    // the low 7 bits of each byte add without carrying into the next byte, and a byte
    // overflows where both high bits are set, or either is and the low bits carried.
    function addSpots() {
      const W = width, H = height, S = sub;
      const { size, ox, oy, rgba } = table;
      let bx0 = box[0], by0 = box[1], bx1 = box[2], by1 = box[3];
      for (let i = 0; i < found; i++) {
        const sx = spots[2 * i], sy = spots[2 * i + 1];
        const px = Math.floor(sx / S), py = Math.floor(sy / S);
        const k = (sy - py * S) * S + (sx - px * S);
        const x0 = px + ox[k], y0 = py + oy[k];
        // The part on the canvas (a sprite is clipped to it).
        const i0 = x0 < 0 ? -x0 : 0, i1 = x0 + size > W ? W - x0 : size;
        const j0 = y0 < 0 ? -y0 : 0, j1 = y0 + size > H ? H - y0 : size;
        if (i0 >= i1 || j0 >= j1) continue;
        if (x0 + i0 < bx0) bx0 = x0 + i0;
        if (x0 + i1 - 1 > bx1) bx1 = x0 + i1 - 1;
        if (y0 + j0 < by0) by0 = y0 + j0;
        if (y0 + j1 - 1 > by1) by1 = y0 + j1 - 1;
        for (let j = j0, t0 = size * (size * k + j0), a0 = (y0 + j0) * W + x0; j < j1;
          j++, t0 += size, a0 += W) {
          for (let c = i0; c < i1; c++) {
            const u = sums[a0 + c], v = rgba[t0 + c];
            const low = (u & 0x7f7f7f7f) + (v & 0x7f7f7f7f), high = (u | v) & 0x80808080;
            const over = ((u & v) | (low & high)) & 0x80808080;
            sums[a0 + c] = (low ^ high) | ((over >>> 7) * 0xff);
          }
        }
      }
      box = [bx0, by0, bx1, by1];
      found = 0;
    }

    // The arc to solve: from p0 to p1 with unit tangents t0, t1 there, then a narrow
    // arc's bow (its point at u is p0 + u c + u (1 - u) bow, its direction
    // mix(t0, t1, u)), else its start angle, signed sweep and length. A typed array:
    // doubles passed to a function, or kept in a closure, are boxed.
    const arc = new Float64Array(13);
    // The shader's solveArc().
    function solveArc(narrow, iterations) {
      const p0x = arc[0], p0y = arc[1], p1x = arc[2], p1y = arc[3];
      const t0x = arc[4], t0y = arc[5], t1x = arc[6], t1y = arc[7];
      const bowx = arc[8], bowy = arc[9], a0 = arc[10], sw = arc[11], len = arc[12];
      // Screen on the toolpath first (the wall moves h by only ~R / distance).
      let se = eyeScale(p0x, p0y, 0), sl = lightScale(p0x, p0y, 0);
      const h0x = (ex - p0x) * se + (lx - pl * p0x) * sl;
      const h0y = (ey - p0y) * se + (ly - pl * p0y) * sl, h0z = ez * se + lz * sl;
      se = eyeScale(p1x, p1y, 0); sl = lightScale(p1x, p1y, 0);
      const h1x = (ex - p1x) * se + (lx - pl * p1x) * sl;
      const h1y = (ey - p1y) * se + (ly - pl * p1y) * sl, h1z = ez * se + lz * sl;
      const s0 = h0x * t0x + h0y * t0y, s1 = h1x * t1x + h1y * t1y;
      const n0 = Math.sqrt(h0x * h0x + h0y * h0y + h0z * h0z);
      if (s0 * s1 > 0 && Math.min(Math.abs(s0), Math.abs(s1)) >= 0.01 * n0) return;
      // The wall offsets w = (0, 0, cz) - R h / |h| at the ends, from the end points
      // alone, exactly as a joined arc evaluates them; interpolated along the arc.
      const k0 = R / n0, k1 = R / Math.sqrt(h1x * h1x + h1y * h1y + h1z * h1z);
      const w0x = -k0 * h0x, w0y = -k0 * h0y, w0z = CZ - k0 * h0z;
      const w1x = -k1 * h1x, w1y = -k1 * h1y, w1z = CZ - k1 * h1z;
      let gx = p0x + w0x, gy = p0y + w0y, gz = w0z;
      se = eyeScale(gx, gy, gz); sl = lightScale(gx, gy, gz);
      const f0 = ((ex - gx) * se + (lx - pl * gx) * sl) * t0x
        + ((ey - gy) * se + (ly - pl * gy) * sl) * t0y;
      gx = p1x + w1x; gy = p1y + w1y; gz = w1z;
      se = eyeScale(gx, gy, gz); sl = lightScale(gx, gy, gz);
      const f1 = ((ex - gx) * se + (lx - pl * gx) * sl) * t1x
        + ((ey - gy) * se + (ly - pl * gy) * sl) * t1y;
      // A root exactly on an arc's start counts, as in find_glints.
      if (!(f0 === 0 || f0 * f1 < 0)) return;
      let a = 0, b = 1, fa = f0, fb = f1, side = 0, u = 0;
      for (let i = 0; ; ++i) {
        if (i < iterations) u = fa === fb ? a : (a * fb - b * fa) / (fb - fa);
        else u = Math.min(1, Math.max(0, u));
        if (narrow) {
          const bow = u - u * u;
          gx = p0x + u * (p1x - p0x) + bow * bowx;
          gy = p0y + u * (p1y - p0y) + bow * bowy;
        } else {
          const half = 0.5 * u * sw;
          const r = u * len * (Math.abs(half) > 1e-4 ? Math.sin(half) / half
            : 1 - half * half / 6);
          gx = p0x + r * Math.cos(a0 + half);
          gy = p0y + r * Math.sin(a0 + half);
        }
        gx += w0x + u * (w1x - w0x);
        gy += w0y + u * (w1y - w0y);
        gz = w0z + u * (w1z - w0z);
        se = eyeScale(gx, gy, gz); sl = lightScale(gx, gy, gz);
        const hx = (ex - gx) * se + (lx - pl * gx) * sl;
        const hy = (ey - gy) * se + (ly - pl * gy) * sl;
        if (i === iterations) {
          const hz = (ez - gz) * se + (lz - pl * gz) * sl;
          if (hz >= cosTilt * Math.sqrt(hx * hx + hy * hy + hz * hz)) emit(gx, gy, gz);
          return;
        }
        const fu = narrow ? hx * (t0x + u * (t1x - t0x)) + hy * (t0y + u * (t1y - t0y))
          : hx * Math.cos(a0 + u * sw) + hy * Math.sin(a0 + u * sw);
        if (fa * fu > 0) {
          a = u; fa = fu;
          if (side > 0) fb *= 0.5;  // Illinois: keep the stale end moving
          side = 1;
        } else {
          b = u; fb = fu;
          if (side < 0) fa *= 0.5;
          side = -1;
        }
      }
    }

    // Narrow row i, decoded as the shader decodes it.
    const GX = meta.grid.origin[0], GY = meta.grid.origin[1], GS = meta.grid.scale;
    function solveNarrow(i) {
      const j = 6 * i;
      const p0x = GX + rows[j] * GS, p0y = GY + rows[j + 1] * GS;
      const p1x = GX + rows[j + 2] * GS, p1y = GY + rows[j + 3] * GS;
      const q0 = rows[j + 4], q1 = rows[j + 5];
      const dq = ((q1 - q0 + 32768) & 65535) - 32768;
      const flip = q0 + dq === q1 ? 1 : -1;
      const cx = p1x - p0x, cy = p1y - p0y;
      const t0x = COS[q0], t0y = SIN[q0], t1x = flip * COS[q1], t1y = flip * SIN[q1];
      const sgn = cx * (t0x + t1x) + cy * (t0y + t1y) >= 0 ? 1 : -1;
      const bow = -0.5 * dq * STEP;
      arc[0] = p0x; arc[1] = p0y; arc[2] = p1x; arc[3] = p1y;
      arc[4] = sgn * t0x; arc[5] = sgn * t0y; arc[6] = sgn * t1x; arc[7] = sgn * t1y;
      arc[8] = -bow * cy; arc[9] = bow * cx;
      solveArc(true, meta.iterations);
    }

    // The float rows: wide arcs (mode 0), corners after arcs (1) and dimples (2).
    function solveFloat(rows6, mode) {
      const step = mode === 2 ? 2 : 6;
      for (let j = 0; j < rows6.length; j += step) {
        if (mode === 2) {
          const px = rows6[j], py = rows6[j + 1];
          let se = eyeScale(px, py, 0), sl = lightScale(px, py, 0);
          let hx = (ex - px) * se + (lx - pl * px) * sl, hy = (ey - py) * se + (ly - pl * py) * sl;
          let hz = ez * se + lz * sl;
          const k = R / Math.sqrt(hx * hx + hy * hy + hz * hz);
          const gx = px - k * hx, gy = py - k * hy, gz = CZ - k * hz;
          se = eyeScale(gx, gy, gz); sl = lightScale(gx, gy, gz);
          hx = (ex - gx) * se + (lx - pl * gx) * sl; hy = (ey - gy) * se + (ly - pl * gy) * sl;
          hz = (ez - gz) * se + (lz - pl * gz) * sl;
          if (hz >= cosTilt * Math.sqrt(hx * hx + hy * hy + hz * hz)) emit(gx, gy, gz);
          continue;
        }
        const p0x = rows6[j], p0y = rows6[j + 1], a0 = rows6[j + 2], len = rows6[j + 3];
        const sw = rows6[j + 4], half = 0.5 * sw;
        const r = len * (Math.abs(half) > 1e-4 ? Math.sin(half) / half : 1 - half * half / 6);
        const p1x = p0x + r * Math.cos(a0 + half), p1y = p0y + r * Math.sin(a0 + half);
        const t1x = Math.cos(a0 + sw), t1y = Math.sin(a0 + sw);
        if (mode === 0) {
          arc.set([p0x, p0y, p1x, p1y, Math.cos(a0), Math.sin(a0), t1x, t1y, 0, 0, a0, sw, len]);
          solveArc(false, meta.wideIterations);
          continue;
        }
        // Corner after this arc: the ball sweeps every direction between the two tangents.
        const turn = rows6[j + 5];
        if (turn >= meta.noCorner) continue;
        const tnx = Math.cos(a0 + sw + turn), tny = Math.sin(a0 + sw + turn);
        let se = eyeScale(p1x, p1y, 0), sl = lightScale(p1x, p1y, 0);
        let hx = (ex - p1x) * se + (lx - pl * p1x) * sl;
        let hy = (ey - p1y) * se + (ly - pl * p1y) * sl, hz = ez * se + lz * sl;
        const e0 = hx * t1x + hy * t1y, n0 = Math.sqrt(hx * hx + hy * hy + hz * hz);
        if (e0 * (hx * tnx + hy * tny) > 0 && Math.abs(e0) >= 0.01 * n0) continue;  // cheap screen
        const gx = p1x - R / n0 * hx, gy = p1y - R / n0 * hy, gz = CZ - R / n0 * hz;
        se = eyeScale(gx, gy, gz); sl = lightScale(gx, gy, gz);
        hx = (ex - gx) * se + (lx - pl * gx) * sl; hy = (ey - gy) * se + (ly - pl * gy) * sl;
        hz = (ez - gz) * se + (lz - pl * gz) * sl;
        if ((hx * t1x + hy * t1y) * (hx * tnx + hy * tny) < 0
            && hz >= cosTilt * Math.sqrt(hx * hx + hy * hy + hz * hz)) emit(gx, gy, gz);
      }
    }

    return {
      cull,
      kept: () => indices,
      setTable(t) { table = t; },
      // Splat job = { eye, light, right, up, fwd, proj, width, height, sub, culling,
      // sums (a buffer to reuse, or null) }: the spots of this share of the glints.
      splat(job) {
        const t0 = performance.now();
        [ex, ey, ez] = job.eye;
        [lx, ly, lz] = job.light;
        pl = pointLight ? 1 : 0;
        [rx, ry, rz] = job.right; [ux, uy, uz] = job.up; [fx, fy, fz] = job.fwd;
        [pjx, pjy] = job.proj;
        width = job.width; height = job.height; sub = job.sub;
        hw = 0.5 * width * sub; hh = 0.5 * height * sub;
        sums = job.sums && job.sums.length === width * height ? job.sums
          : new Uint32Array(width * height);
        box = [width, height, -1, -1];
        let n = rows.length / 6, cullMs = 0;
        if (job.culling) {
          n = cull(job.eye, job.light);
          cullMs = performance.now() - t0;
          for (let j = 0; j < n; j++) solveNarrow(indices[j]);
        } else {
          for (let i = 0; i < n; i++) solveNarrow(i);
        }
        addSpots();
        solveFloat(data.wide, 0);
        solveFloat(data.corners, 1);
        solveFloat(data.dots, 2);
        addSpots();
        const out = { sums, box, drawn: n, cullMs,
                      ms: performance.now() - t0 };
        sums = null;
        return out;
      },
    };
  }

  const counts = meta.counts;
  let floatProg, narrowProg, plate, narrowVao, wideVao, cornerVao, dotVao, plateVao;
  let calibrateProg;
  let indexBuffer, indexCapacity = 0;
  // The culling of the sprites (not splatting).
  let search = null;
  try {
    if (splatting) {
      calibrateProg = program(CALIBRATE_VS, SPRITE_FS);
    } else {
      floatProg = program(glintVS(false, meta.wideIterations), SPRITE_FS);
      narrowProg = program(glintVS(true, meta.iterations), SPRITE_FS);
      plate = program(PLATE_VS, PLATE_FS);
    }
  } catch (err) {
    fail("Could not set up WebGL2: " + err.message);
    console.error(err);
    return;
  }

  function upload(blocks) {
    const [{ rows, cellStart }] = narrowRows(blocks, 1);
    search = glintSearch(meta, { rows, cellStart, cells: floats(blocks.cells) });
    // The narrow rows (uint16 x0, y0, x1, y1, q0, q1), drawn by the indices culling keeps.
    narrowVao = gl.createVertexArray();
    gl.bindVertexArray(narrowVao);
    gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
    gl.bufferData(gl.ARRAY_BUFFER, rows, gl.STATIC_DRAW);
    gl.enableVertexAttribArray(2);
    gl.vertexAttribIPointer(2, 4, gl.UNSIGNED_SHORT, 12, 0);
    gl.enableVertexAttribArray(3);
    gl.vertexAttribIPointer(3, 2, gl.UNSIGNED_SHORT, 12, 8);
    indexBuffer = gl.createBuffer();
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, indexBuffer);
    const floatVao = (data) => {
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
    wideVao = floatVao(floats(blocks.wide));
    cornerVao = floatVao(floats(blocks.corners));
    dotVao = gl.createVertexArray();
    gl.bindVertexArray(dotVao);
    gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
    gl.bufferData(gl.ARRAY_BUFFER, floats(blocks.dots), gl.STATIC_DRAW);
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

  // A glint's spot: a Gaussian of SIGMA CSS px on a square of spotSize() pixels,
  // cut where it falls below ~4% of its peak.
  function spotSize() { return 2 * Math.ceil(2 * dpr()) + 1; }
  function setSpot(L) {
    const sigma = SIGMA * dpr();
    gl.uniform1f(L.u_size, spotSize());
    gl.uniform1f(L.u_gauss, -1 / (2 * sigma * sigma * Math.LN2));
  }

  function setGlint(p, cam, light) {
    const L = p.loc;
    gl.useProgram(p.prog);
    setCamera(L, cam);
    gl.uniform3fv(L.u_light, light);
    gl.uniform1f(L.u_R, meta.tool.radius);
    gl.uniform1f(L.u_cz, meta.tool.radius - meta.tool.depth);
    gl.uniform1f(L.u_cosTilt, Math.cos(meta.tool.maxTilt));
    setSpot(L);
    if (L.u_noCorner) gl.uniform1f(L.u_noCorner, meta.noCorner);
    if (L.u_grid) {
      gl.uniform3f(L.u_grid, meta.grid.origin[0], meta.grid.origin[1], meta.grid.scale);
    }
  }

  function drawPlate(cam) {
    gl.disable(gl.BLEND);
    gl.clearColor(...BACKGROUND, 1);
    gl.clear(gl.COLOR_BUFFER_BIT);
    gl.useProgram(plate.prog);
    setCamera(plate.loc, cam);
    gl.bindVertexArray(plateVao);
    gl.drawArrays(gl.TRIANGLE_FAN, 0, 4);
    gl.bindVertexArray(null);
  }

  // --- Splatting (software rasterizers) -------------------------------------------
  // A lone glint's spot depends only on where its sprite's centre falls within a pixel,
  // on the rasterizer's grid of SUB steps a pixel (glintSearch rounds it so).
  // spotTable holds the spot for each of those places as the GPU itself draws a sprite
  // there (drawn once and read back), so that adding them up here gives what additive
  // blending of the sprites gives, to the bit: 8-bit values, clamped when drawn.
  const SUB = 2 ** clamp(gl.getParameter(gl.SUBPIXEL_BITS), 0, 4);
  // { size, ox, oy (per place: first pixel from the centre's), rgba (size^2 per place) }
  let spotTable = null;

  // The table of the current sprites in windows of size x size pixels, or null if a
  // sprite covers more.
  function calibrate(size) {
    const cell = size + 4, lead = 2 + Math.ceil(size / 2);
    let fb = 1;
    while (fb < SUB * cell) fb *= 2;  // a power of two: exact window positions
    const tex = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, tex);
    gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA8, fb, fb);
    const frame = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, frame);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, tex, 0);
    const at = new Float32Array(2 * SUB * SUB);
    for (let ky = 0; ky < SUB; ky++) {
      for (let kx = 0; kx < SUB; kx++) {
        at[2 * (ky * SUB + kx)] = kx * cell + lead + kx / SUB;
        at[2 * (ky * SUB + kx) + 1] = ky * cell + lead + ky / SUB;
      }
    }
    const vao = gl.createVertexArray(), buffer = gl.createBuffer();
    gl.bindVertexArray(vao);
    gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
    gl.bufferData(gl.ARRAY_BUFFER, at, gl.STATIC_DRAW);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 2, gl.FLOAT, false, 8, 0);
    gl.viewport(0, 0, fb, fb);
    gl.clearColor(0, 0, 0, 0);
    gl.clear(gl.COLOR_BUFFER_BIT);
    gl.enable(gl.BLEND);
    gl.blendFunc(gl.ONE, gl.ONE);
    const L = calibrateProg.loc;
    gl.useProgram(calibrateProg.prog);
    gl.uniform1f(L.u_fb, fb);
    setSpot(L);
    gl.drawArrays(gl.POINTS, 0, SUB * SUB);
    const px = new Uint8Array(4 * fb * fb);
    gl.readPixels(0, 0, fb, fb, gl.RGBA, gl.UNSIGNED_BYTE, px);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.bindVertexArray(null);
    gl.deleteVertexArray(vao);
    gl.deleteBuffer(buffer);
    gl.deleteFramebuffer(frame);
    gl.deleteTexture(tex);
    const places = SUB * SUB;
    const ox = new Int32Array(places), oy = new Int32Array(places);
    const rgba = new Uint32Array(size * size * places);  // RGBA bytes, alpha 0
    const bytes = new Uint8Array(rgba.buffer);
    for (let ky = 0; ky < SUB; ky++) {
      for (let kx = 0; kx < SUB; kx++) {
        // The covered pixels of this cell, from the centre's pixel (lead, lead).
        let x0 = cell, x1 = -1, y0 = cell, y1 = -1;
        for (let y = 0; y < cell; y++) {
          for (let x = 0; x < cell; x++) {
            const a = 4 * ((ky * cell + y) * fb + kx * cell + x);
            if (px[a] | px[a + 1] | px[a + 2]) {
              x0 = Math.min(x0, x); x1 = Math.max(x1, x);
              y0 = Math.min(y0, y); y1 = Math.max(y1, y);
            }
          }
        }
        if (x1 < 0 || x1 - x0 >= size || y1 - y0 >= size) return null;
        // Start the size x size window at the covered pixels (ends rounding to 0 are
        // all the same as uncovered ones).
        x0 = Math.min(x0, cell - size); y0 = Math.min(y0, cell - size);
        const k = ky * SUB + kx;
        ox[k] = x0 - lead;
        oy[k] = y0 - lead;
        for (let y = 0, t = 4 * size * size * k; y < size; y++) {
          for (let x = 0; x < size; x++, t += 4) {
            const a = 4 * ((ky * cell + y0 + y) * fb + kx * cell + x0 + x);
            bytes[t] = px[a]; bytes[t + 1] = px[a + 1]; bytes[t + 2] = px[a + 2];
          }
        }
      }
    }
    return { size, ox, oy, rgba };
  }


  // The table for the current sprite size; true if it changed.
  function updateTable() {
    if (spotTable && spotTable.sprite === spotSize()) return false;
    spotTable = null;
    // A sprite covers at most one pixel more a side than its size.
    for (let size = spotSize(); !spotTable && size <= spotSize() + 2; size++) {
      spotTable = calibrate(size);
    }
    if (!spotTable) throw new Error("the rasterizer draws no sprite");
    spotTable.sprite = spotSize();
    return true;
  }

  // Splatting runs glintSearch in lanes, each on a share of the cells: workers (as
  // many as the cores, at most 4; ?workers=N sets how many, 0 runs it in the page).
  // A frame is a job for every lane: the view, and a buffer for the lane to fill with
  // its spots. The next job runs while a finished frame waits for the display.
  const WORKER_SOURCE = `"use strict";
const glintSearch = ${glintSearch};
let search = null;
onmessage = (ev) => {
  const m = ev.data;
  if (m.data) search = glintSearch(m.meta, m.data);
  if (m.table) search.setTable(m.table);
  if (m.job) {
    const r = search.splat(m.job);
    postMessage(r, [r.sums.buffer]);
  }
};`;
  // lanes: { post(message, transfer) }; free[k]: lane k's idle buffers; pending: lanes
  // still on the current job; ready: the newest finished frame not yet shown.
  const pool = { lanes: [], free: [], results: [], pending: 0, job: null, ready: null };

  function startLanes(blocks) {
    const asked = params.has("workers") ? Math.max(0, Math.floor(+params.get("workers")) || 0)
      : clamp(navigator.hardwareConcurrency || 2, 1, 4);
    let url = null;
    if (asked && typeof Worker === "function") {
      url = URL.createObjectURL(new Blob([WORKER_SOURCE], { type: "text/javascript" }));
    }
    updateTable();
    const cells = floats(blocks.cells);
    const none = new Float32Array(0);
    narrowRows(blocks, Math.max(asked, 1)).forEach(({ rows, cellStart }, k) => {
      // The float rows are few: the first lane takes them all.
      const data = {
        rows, cellStart, cells, table: spotTable, wide: k ? none : floats(blocks.wide),
        corners: k ? none : floats(blocks.corners), dots: k ? none : floats(blocks.dots),
      };
      pool.free.push([]);
      const done = (r) => laneDone(k, r);
      if (url) {
        const worker = new Worker(url);
        worker.onmessage = (ev) => done(ev.data);
        worker.onerror = (ev) => {
          fail("The page's worker failed: " + ev.message);
          console.error(ev.message);
        };
        worker.postMessage({ meta, data }, [rows.buffer, cellStart.buffer]);
        pool.lanes.push({ post: (m, transfer) => worker.postMessage(m, transfer) });
      } else {
        const local = glintSearch(meta, data);
        pool.lanes.push({
          post(m) {
            if (m.table) local.setTable(m.table);
            if (m.job) {
              const r = local.splat(m.job);
              Promise.resolve(r).then(done);
            }
          },
        });
      }
    });
  }

  function postJob() {
    if (state.spin) spinView();
    if (updateTable()) for (const lane of pool.lanes) lane.post({ table: spotTable });
    const cam = camera(), light = lightVector();
    const W = canvas.width, H = canvas.height;
    state.dirty = false;
    pool.job = { cam, W, H, azimuth: state.azimuth, elevation: state.elevation,
                 light: state.light, t0: performance.now() };
    pool.pending = pool.lanes.length;
    pool.lanes.forEach((lane, k) => {
      const sums = pool.free[k].pop() || null;
      const job = { eye: cam.eye, light, right: cam.right, up: cam.up, fwd: cam.fwd,
                    proj: cam.proj, width: W, height: H, sub: SUB, culling, sums };
      lane.post({ job }, sums ? [sums.buffer] : []);
    });
  }

  function laneDone(k, r) {
    pool.results[k] = r;
    if (--pool.pending) return;
    const job = pool.job;
    job.results = pool.results.slice();
    job.ms = performance.now() - job.t0;
    const waiting = pool.ready !== null;
    if (waiting) releaseFrame(pool.ready, false);  // never shown: this one is newer
    pool.ready = job;
    if (!waiting && (state.dirty || state.spin)) postJob();
  }

  // Give a frame's buffers back to their lanes, cleared (cleared: compose() did).
  function releaseFrame(job, cleared) {
    job.results.forEach((r, k) => {
      if (!cleared) {
        const [x0, y0, x1, y1] = r.box;
        for (let y = y0; y <= y1; y++) r.sums.fill(0, y * job.W + x0, y * job.W + x1 + 1);
      }
      pool.free[k].push(r.sums);
    });
  }

  // The rows of the plate's pixels: in window row y (pixel centres at y + 0.5, y up),
  // pixels [span[2 y], span[2 y + 1]) are the plate's. The rasterizer's rule: the
  // corners snapped to its subpixel grid, pixel centres on a left edge in.
  let plateSpan = new Int32Array(0);
  function plateSpans(cam, W, H) {
    if (plateSpan.length !== 2 * H) plateSpan = new Int32Array(2 * H);
    plateSpan.fill(0);
    const [[x0, y0], [x1, y1]] = meta.plate;
    // Clip space (x, y, w) of the corners, the polygon cut at w = 1e-6 (the
    // rasterizer clips at w = 0; nothing of the plate comes that close to the eye).
    const clip = [[x0, y0], [x1, y0], [x1, y1], [x0, y1]].map(([x, y]) => {
      const qx = x - cam.eye[0], qy = y - cam.eye[1], qz = -cam.eye[2];
      const dot = (v) => v[0] * qx + v[1] * qy + v[2] * qz;
      return [dot(cam.right) * cam.proj[0], dot(cam.up) * cam.proj[1], dot(cam.fwd)];
    });
    const poly = [];
    for (let i = 0; i < 4; i++) {
      const a = clip[i], b = clip[(i + 1) % 4], eps = 1e-6;
      if (a[2] > eps) poly.push(a);
      if ((a[2] > eps) !== (b[2] > eps)) {
        const t = (eps - a[2]) / (b[2] - a[2]);
        poly.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), eps]);
      }
    }
    const snap = (v) => Math.round(v * SUB) / SUB;
    const win = poly.map(([x, y, w]) => [snap(0.5 * W + x / w * 0.5 * W),
                                         snap(0.5 * H + y / w * 0.5 * H)]);
    for (let y = 0; y < H; y++) {
      const yc = y + 0.5;
      let lo = Infinity, hi = -Infinity;
      for (let i = 0; i < win.length; i++) {
        const [ax, ay] = win[i], [bx, by] = win[(i + 1) % win.length];
        if (ay === by || yc < Math.min(ay, by) || yc >= Math.max(ay, by)) continue;
        const x = ax + (yc - ay) * (bx - ax) / (by - ay);
        lo = Math.min(lo, x);
        hi = Math.max(hi, x);
      }
      if (!(lo < hi)) continue;
      plateSpan[2 * y] = clamp(Math.ceil(lo - 0.5), 0, W);
      plateSpan[2 * y + 1] = clamp(Math.ceil(hi - 0.5), 0, W);
    }
  }


  // Show a finished frame: background, plate and the lanes' sums over it (saturating,
  // as blending them is), rows flipped to the image's top-down order; the sums are
  // cleared for their next frame.
  let image = null;
  function present(job) {
    const { W, H } = job;
    if (!image || image.width !== W || image.height !== H) image = new ImageData(W, H);
    const out = new Uint32Array(image.data.buffer);
    const word = (c) => ((255 << 24) | (Math.round(c[2] * 255) << 16)
                         | (Math.round(c[1] * 255) << 8) | Math.round(c[0] * 255)) >>> 0;
    const back = word(BACKGROUND), plateWord = word(PLATE_COLOR);
    plateSpans(job.cam, W, H);
    for (let y = 0; y < H; y++) {
      const row = (H - 1 - y) * W, xa = plateSpan[2 * y], xb = plateSpan[2 * y + 1];
      out.fill(back, row, row + xa);
      out.fill(plateWord, row + xa, row + xb);
      out.fill(back, row + xb, row + W);
      for (const { sums, box: [x0, y0, x1, y1] } of job.results) {
        if (y < y0 || y > y1) continue;
        for (let x = x0, a = y * W + x0, o = row + x0; x <= x1; x++, a++, o++) {
          const v = sums[a];
          if (!v) continue;
          const u = out[o];
          const low = (u & 0x7f7f7f7f) + (v & 0x7f7f7f7f), high = (u | v) & 0x80808080;
          const over = ((u & v) | (low & high)) & 0x80808080;
          out[o] = (low ^ high) | ((over >>> 7) * 0xff);
          sums[a] = 0;
        }
      }
    }
    ctx2d.putImageData(image, 0, 0);
    releaseFrame(job, true);
    state.lastDrawn = counts.wide;
    state.lastCullMs = 0;
    for (const r of job.results) {
      state.lastDrawn += r.drawn;
      state.lastCullMs = Math.max(state.lastCullMs, r.cullMs);
    }
    showAngles(job.azimuth, job.elevation, job.light);
  }

  // The narrow glints as point sprites.
  function drawSprites(cam, light) {
    setGlint(narrowProg, cam, light);
    gl.bindVertexArray(narrowVao);
    if (!culling) {
      if (counts.narrow) gl.drawArrays(gl.POINTS, 0, counts.narrow);
      state.lastDrawn += counts.narrow;
    } else {
      const t0 = performance.now();
      const n = search.cull(cam.eye, light), indices = search.kept();
      state.lastCullMs = performance.now() - t0;
      if (n > indexCapacity) {
        indexCapacity = indices.length;
        gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, indexCapacity * 4, gl.DYNAMIC_DRAW);
      }
      if (n) {
        gl.bufferSubData(gl.ELEMENT_ARRAY_BUFFER, 0, indices, 0, n);
        gl.drawElements(gl.POINTS, n, gl.UNSIGNED_INT, 0);
      }
      state.lastDrawn += n;
    }
  }

  // The glints, additively over the plate.
  function drawGlints(cam, light) {
    gl.enable(gl.BLEND);
    gl.blendFunc(gl.ONE, gl.ONE);  // overlapping glints add up, like light
    drawSprites(cam, light);

    const L = floatProg.loc;
    setGlint(floatProg, cam, light);
    gl.bindVertexArray(wideVao);
    gl.uniform1i(L.u_mode, 0);
    if (counts.wide) gl.drawArrays(gl.POINTS, 0, counts.wide);
    gl.bindVertexArray(cornerVao);
    gl.uniform1i(L.u_mode, 1);
    if (counts.corners) gl.drawArrays(gl.POINTS, 0, counts.corners);
    gl.bindVertexArray(dotVao);
    gl.uniform1i(L.u_mode, 2);
    if (counts.dots) gl.drawArrays(gl.POINTS, 0, counts.dots);
    gl.bindVertexArray(null);
  }

  // The sun's direction, or the point light's position.
  function lightVector() {
    const a = state.light * DEG, dist = meta.light.distance;
    const dir = [0, Math.cos(a), Math.sin(a)];
    return dist ? dir.map((v) => v * dist) : dir;
  }

  // While the view keeps moving the angles are shown ten times a second: new text
  // every frame costs the browser a style, layout and paint pass of the page.
  let anglesShown = -Infinity;
  function showAngles(azimuth, elevation, light) {
    const now = performance.now();
    if ((state.dirty || state.spin || pool.pending) && now - anglesShown < 100) return;
    anglesShown = now;
    const sign = (v) => (v >= 0 ? "+" : "\u2212") + Math.abs(v).toFixed(1) + "\u00b0";
    anglesEl.textContent = `azimuth ${sign(azimuth)}   elevation ${sign(elevation)}`
      + `   light ${light.toFixed(1)}\u00b0`;
  }

  function draw() {
    const cam = camera(), light = lightVector();
    state.lastDrawn = counts.wide;
    gl.viewport(0, 0, canvas.width, canvas.height);
    gl.disable(gl.DEPTH_TEST);
    drawPlate(cam);
    drawGlints(cam, light);
    showAngles(state.azimuth, state.elevation, state.light);
  }

  // Keep the view changing so every frame recomputes every glint; the views follow
  // the frame count (as if at 30 frames/s) so every run sees the same ones.
  function spinView() {
    const t = state.spinFrame++ / 30;
    setView(meta.viewRange * Math.sin(0.7 * t), 5 * Math.sin(0.31 * t));
  }

  function record(now, ms) {
    if (!state.spin) return;
    state.drawMs.push(ms);
    state.drawn.push(state.lastDrawn);
    state.cullMs.push(state.lastCullMs);
    if (state.last !== null) state.frames.push(now - state.last);
    state.last = now;
  }

  function frame(now) {
    if (splatting) {
      const job = pool.ready;
      if (job) {
        pool.ready = null;
        if (job.W === canvas.width && job.H === canvas.height) {
          present(job);
          hook.ready = true;
          record(now, job.ms);
        } else {
          releaseFrame(job, false);
        }
      }
      if ((state.dirty || state.spin) && !pool.pending) postJob();
    } else {
      if (state.spin) spinView();
      if (state.dirty) {
        state.dirty = false;
        const t0 = performance.now();
        draw();
        if (state.sync) gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(4));
        record(now, performance.now() - t0);
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
  loadBlocks().then((blocks) => {
    if (splatting) {
      startLanes(blocks);  // ready once the first frame is shown
      state.dirty = true;
    } else {
      upload(blocks);
      draw();
      state.dirty = false;
      hook.ready = true;
    }
    window.requestAnimationFrame(frame);
  }).catch((err) => {
    fail("Could not load the page's data: " + err.message);
    console.error(err);
  });
})();

