"""The interactive page: its GPU glints land where the Python simulation puts them."""

from __future__ import annotations

import io
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from specholo.jobs.flat.folder import load_design
from specholo.jobs.page import write_page
from specholo.preview.page import ANGLE_STEP, ANGLE_STEPS, CELL, PageArcs, build_page
from specholo.preview.render import Camera
from specholo.setup import Light, Tool
from specholo.simulation.glints import Engraved, find_glints

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"
W, H = 800, 600
HUD = 28  # the angle bar above the canvas, CSS px

@pytest.fixture(scope="module")
def folder(small_design: Path) -> Path:
    return small_design


def spots(image: np.ndarray, threshold: float = 60.0) -> np.ndarray:
    """Sub-pixel centres (n, 2) (column, row) of the bright spots in a grey image."""
    from scipy import ndimage

    img = image.astype(float)
    peak = (img == ndimage.maximum_filter(img, size=5)) & (img > threshold)
    rows, cols = np.nonzero(peak)
    pad = np.pad(img, 2)
    out = []
    for r, c in zip(rows.tolist(), cols.tolist(), strict=True):
        win = pad[r:r + 5, c:c + 5] - np.median(img)
        win = np.clip(win, 0.0, None)
        total = win.sum()
        dy, dx = np.mgrid[-2:3, -2:3]
        centre = [c + (win * dx).sum() / total, r + (win * dy).sum() / total]
        # A saturated spot has a flat top: its tied maxima give the same centre.
        if all(math.dist(centre, o) > 1.0 for o in out):
            out.append(centre)
    return np.array(out).reshape(-1, 2)


def _compare(page: Any, eng: Engraved) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """Spots on the canvas, Python glint pixels and their stipples, and the page's view."""
    from PIL import Image

    view = page.evaluate("window.specholo.getView()")
    shot = page.locator("#view").screenshot()
    found = spots(np.asarray(Image.open(io.BytesIO(shot)).convert("L")))
    w, h = view["width"], view["height"]
    cam = Camera(math.radians(view["azimuth"]), math.radians(view["elevation"]),
                 view["distance"], math.radians(view["fov"]), w, h, view["eyeHeight"])
    g = find_glints(eng, cam.position(), Light(math.radians(view["light"]),
                                               view["lightDistance"]))
    pix, _, ok = cam.project(g.point)
    inside = ok & (pix[:, 0] > 3) & (pix[:, 0] < w - 4) & (pix[:, 1] > 3) & (pix[:, 1] < h - 4)
    return found, pix[inside], g.stipple[inside], view


# numpy ports of page.js for the narrow arcs: the shader's decoding and solve, and
# the script's culling; they must follow page.js step by step.


def _decode(pa: PageArcs) -> tuple[np.ndarray, ...]:
    """End points P0, P1, end tangents T0, T1 and bow (k, 2) of the rows, as the shader."""
    t = pa.table.astype(np.int64)
    p0 = pa.origin + t[:, 0:2] * pa.scale
    p1 = pa.origin + t[:, 2:4] * pa.scale
    q0, q1 = t[:, 4], t[:, 5]
    dq = ((q1 - q0 + 32768) & 65535) - 32768
    u0 = np.stack([np.cos(q0 * ANGLE_STEP), np.sin(q0 * ANGLE_STEP)], axis=1)
    u1 = np.stack([np.cos(q1 * ANGLE_STEP), np.sin(q1 * ANGLE_STEP)], axis=1)
    u1 *= np.where(q0 + dq == q1, 1.0, -1.0)[:, None]
    c = p1 - p0
    sgn = np.where(np.sum(c * (u0 + u1), axis=1) >= 0, 1.0, -1.0)[:, None]
    bow = (-0.5 * dq * ANGLE_STEP)[:, None] * np.stack([-c[:, 1], c[:, 0]], axis=1)
    return p0, p1, sgn * u0, sgn * u1, bow


def _point_at(p0: np.ndarray, p1: np.ndarray, bow: np.ndarray, u: np.ndarray) -> np.ndarray:
    u = u[:, None]
    return p0 + u * (p1 - p0) + (u - u * u) * bow


def _lift(p: np.ndarray, z: float = 0.0) -> np.ndarray:
    return np.concatenate([p, np.full((len(p), 1), z)], axis=1)


def _h(g: np.ndarray, eye: np.ndarray, light: Light) -> np.ndarray:
    e = eye - g
    return light.towards(g) + e / np.linalg.norm(e, axis=1, keepdims=True)


def _shader_glints(pa: PageArcs, tool: Tool, eye: np.ndarray, light: Light,
                   iterations: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Rows (m,) on which the narrow-arc shader emits a glint, and the glints (m, 3)."""
    p0, p1, t0, t1, bow = _decode(pa)
    h0, h1 = _h(_lift(p0), eye, light), _h(_lift(p1), eye, light)
    s0, s1 = np.sum(h0[:, :2] * t0, axis=1), np.sum(h1[:, :2] * t1, axis=1)
    screened = (s0 * s1 > 0) & (np.minimum(abs(s0), abs(s1)) >= 0.01 * np.linalg.norm(h0, axis=1))
    cz = tool.radius - tool.depth
    g0 = _lift(p0, cz) - tool.radius * h0 / np.linalg.norm(h0, axis=1, keepdims=True)
    g1 = _lift(p1, cz) - tool.radius * h1 / np.linalg.norm(h1, axis=1, keepdims=True)
    f0 = np.sum(_h(g0, eye, light)[:, :2] * t0, axis=1)
    f1 = np.sum(_h(g1, eye, light)[:, :2] * t1, axis=1)
    i = np.flatnonzero(~screened & ((f0 == 0) | (f0 * f1 < 0)))
    w0, w1 = g0[i] - _lift(p0[i]), g1[i] - _lift(p1[i])

    def at(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        g = _lift(_point_at(p0[i], p1[i], bow[i], u)) + w0 + (w1 - w0) * u[:, None]
        t = t0[i] + (t1[i] - t0[i]) * u[:, None]
        return np.sum(_h(g, eye, light)[:, :2] * t, axis=1), g

    a, b, fa, fb = np.zeros(len(i)), np.ones(len(i)), f0[i], f1[i]
    side, u = np.zeros(len(i)), np.zeros(len(i))
    for _ in range(iterations):
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.where(fa == fb, a, (a * fb - b * fa) / (fb - fa))
        fu, _ = at(u)
        left = fa * fu > 0
        a, fa = np.where(left, u, a), np.where(left, fu, fa)
        b, fb = np.where(left, b, u), np.where(left, fb, fu)
        fb = np.where(left & (side > 0), 0.5 * fb, fb)
        fa = np.where(~left & (side < 0), 0.5 * fa, fa)
        side = np.where(left, 1.0, -1.0)
    _, g = at(np.clip(u, 0.0, 1.0))
    h = _h(g, eye, light)
    ok = h[:, 2] >= math.cos(tool.max_tilt) * np.linalg.norm(h, axis=1)
    return i[ok], g[ok]


def _culled(pa: PageArcs, tool: Tool, eye: np.ndarray, light: Light) -> np.ndarray:
    """Rows (m,) page.js keeps for an eye and light: its cell windows, then its screens."""
    slack = 1e-5  # SLACK
    nx, ny = pa.shape
    r, cz = tool.radius, tool.radius - tool.depth
    wall = math.hypot(r, cz)
    c = np.arange(nx * ny)
    x = pa.origin[0] + (c % nx + 0.5) * CELL
    y = pa.origin[1] + (c // nx + 0.5) * CELL
    rho, sweep = pa.cell_reach + wall, pa.cell_sweep
    centre = np.stack([x, y, np.zeros_like(x)], axis=1)
    de = np.linalg.norm(eye - centre, axis=1)
    ue = (eye - centre) / de[:, None]
    margin, lin, lip = rho / (de - rho), 3 * rho**2 / (de - rho) ** 2, 1 / (de - rho)
    near = de <= rho
    if light.distance is not None:
        dl = np.linalg.norm(light.position - centre, axis=1)
        ul, il = (light.position - centre) / dl[:, None], 1 / dl
        margin, lin = margin + rho / (dl - rho), lin + 3 * rho**2 / (dl - rho) ** 2
        lip, near = lip + 1 / (dl - rho), near | (dl <= rho)
    else:
        ul, il = np.broadcast_to(light.direction, centre.shape), np.zeros_like(x)
    hc = ue + ul
    hn = np.linalg.norm(hc, axis=1)
    w = np.array([0.0, 0.0, cz]) - r * hc / hn[:, None]
    lin = np.where(near | ~(margin < hn), np.inf,
                   lin + r * 2 * margin / (2 * hn - margin) * lip + slack)
    hxy = np.linalg.norm(hc[:, :2], axis=1)
    with np.errstate(invalid="ignore"):
        delta = np.arcsin(np.minimum(margin / hxy, 1.0)) + slack
    want = np.arctan2(hc[:, 1], hc[:, 0]) + 0.5 * np.pi
    lo, hi = want - delta - sweep, want + delta
    whole = near | ~(margin < hxy) | (hi - lo >= np.pi)
    with np.errstate(invalid="ignore"):
        tilted = ~near & (margin < hn) & (np.arccos(hc[:, 2] / hn) > tool.max_tilt
                                          + np.arcsin(np.minimum(margin / hn, 1.0)) + slack)
    margin = np.where(near, np.inf, margin + slack)
    qlo, qhi = np.floor(lo / ANGLE_STEP), np.ceil(hi / ANGLE_STEP)
    wrap = np.floor(qlo / ANGLE_STEPS) * ANGLE_STEPS
    qlo, qhi = qlo - wrap, qhi - wrap
    cell = np.repeat(c, np.diff(pa.cell_start.astype(np.int64)))
    q = pa.table[:, 4].astype(np.int64)
    a, b = qlo[cell], qhi[cell]
    window = whole[cell] | ((q >= a) & (q <= np.minimum(b, ANGLE_STEPS - 1)))
    window |= q <= b - ANGLE_STEPS
    window &= ~tilted[cell]
    p0, p1, t0, t1, _ = _decode(pa)

    def drop(d0: np.ndarray, d1: np.ndarray, bound: np.ndarray) -> np.ndarray:
        return (d0 * d1 > 0) & (np.minimum(abs(d0), abs(d1)) > bound[cell])

    def first_order(p: np.ndarray, t: np.ndarray) -> np.ndarray:
        # h . t at the wall point p + w(c), h linear about c.
        d = np.concatenate([p - centre[cell, :2] + w[cell, :2], w[cell, 2:]], axis=1)
        dt = np.sum(d[:, :2] * t, axis=1)
        out = np.sum(hc[cell, :2] * t, axis=1)
        for u, inv in ((ue[cell], 1 / de[cell]), (ul[cell], il[cell])):
            out -= (dt - np.sum(u * d, axis=1) * np.sum(u[:, :2] * t, axis=1)) * inv
        return out

    centre_test = drop(np.sum(hc[cell, :2] * t0, axis=1), np.sum(hc[cell, :2] * t1, axis=1),
                       margin)
    linear_test = drop(first_order(p0, t0), first_order(p1, t1), lin)
    return np.flatnonzero(window & ~centre_test & ~linear_test)


def _eye(azimuth: float, elevation: float, distance: float = 600.0) -> np.ndarray:
    return Camera(math.radians(azimuth), math.radians(elevation), distance, 0.5).position()


def test_arc_table_matches_engraved(folder: Path) -> None:
    from specholo.preview.page import arc_table

    loaded = load_design(folder)
    eng = Engraved.from_grooves(loaded.grooves, loaded.config.setup().tool)
    arcs, dots = arc_table(loaded.grooves)
    a = arcs.astype(float)
    assert len(a) == len(eng.path) and len(dots) == len(eng.dot_path)
    for u in (0.0, 0.4, 1.0):
        p, t = eng.at(np.arange(len(a)), np.full(len(a), u))
        half = 0.5 * u * a[:, 4]
        safe = np.where(half == 0, 1.0, half)
        sinc = np.where(np.abs(half) > 1e-8, np.sin(half) / safe, 1.0)
        ang = a[:, 2] + half
        q = a[:, :2] + (u * a[:, 3] * sinc)[:, None] * np.stack([np.cos(ang), np.sin(ang)], 1)
        tq = np.stack([np.cos(a[:, 2] + u * a[:, 4]), np.sin(a[:, 2] + u * a[:, 4])], 1)
        assert np.abs(q - p[:, :2]).max() < 1e-4  # float32 of coordinates < 100 mm
        # Smooth junctions share a tangent rounded to half an angle step (2.4e-5 rad).
        assert np.abs(tq - t).max() < 0.5 * ANGLE_STEP + 1e-6


def test_compact_arcs_decode_to_the_grooves(folder: Path) -> None:
    loaded = load_design(folder)
    grooves = loaded.grooves
    eng = Engraved.from_grooves(grooves, loaded.config.setup().tool)
    pa = PageArcs.build(grooves)
    k = len(eng.path)
    assert len(pa.table) + len(pa.wide) == k and len(pa.table) > 0.99 * k
    assert sorted(np.concatenate([pa.arc, pa.wide_arc]).tolist()) == list(range(k))
    p0, p1, t0, t1, bow = _decode(pa)
    # A row runs along its arc or against it (so that its tangent turns counter-clockwise).
    rev = np.linalg.norm(p0 - eng.start[pa.arc], axis=1) > np.linalg.norm(
        p0 - eng.end[pa.arc], axis=1)
    for u in (0.0, 0.25, 0.5, 0.8, 1.0):
        uu = np.full(len(p0), u)
        p, t = eng.at(pa.arc, np.where(rev, 1.0 - uu, uu))
        assert np.abs(_point_at(p0, p1, bow, uu) - p[:, :2]).max() < 2e-3  # mm
        tq = t0 + (t1 - t0) * u
        tq /= np.linalg.norm(tq, axis=1, keepdims=True)
        # The page's tangents point the row's way (along the arc's, or against it), to
        # half an angle step.
        assert np.all(np.sum(tq * t, axis=1) * np.where(rev, -1.0, 1.0) > 0.99)
        assert np.abs(tq[:, 0] * t[:, 1] - tq[:, 1] * t[:, 0]).max() < 0.5 * ANGLE_STEP + 1e-6
    # Joined arcs store the same junction point and tangent step there.
    row = np.full(k, -1)
    row[pa.arc] = np.arange(len(pa.arc))
    a = np.flatnonzero((eng.path[:-1] == eng.path[1:]) & (row[:-1] >= 0) & (row[1:] >= 0))
    ra, rb = row[a], row[a + 1]
    end_a = np.where(rev[ra, None], pa.table[ra][:, [0, 1, 4]], pa.table[ra][:, [2, 3, 5]])
    start_b = np.where(rev[rb, None], pa.table[rb][:, [2, 3, 5]], pa.table[rb][:, [0, 1, 4]])
    assert len(a) > 0.7 * k and np.array_equal(end_a, start_b)


@pytest.mark.parametrize("azimuth, elevation, distance, light", [
    (0.0, 0.0, 600.0, Light(math.radians(45.0))),
    (25.0, 6.0, 600.0, Light(math.radians(45.0))),
    (-35.0, -12.0, 600.0, Light(math.radians(30.0))),
    (10.0, 4.0, 350.0, Light(math.radians(70.0), 400.0)),
    (-5.0, 30.0, 600.0, Light(math.radians(60.0), 800.0)),
])
def test_culling_keeps_every_glint(folder: Path, azimuth: float, elevation: float,
                                   distance: float, light: Light) -> None:
    loaded = load_design(folder)
    tool = loaded.config.setup().tool
    pa = PageArcs.build(loaded.grooves)
    eye = _eye(azimuth, elevation, distance)
    glinting, points = _shader_glints(pa, tool, eye, light)
    kept = _culled(pa, tool, eye, light)
    assert len(glinting) > 20
    assert np.isin(glinting, kept).all()
    assert len(kept) < 0.05 * len(pa.table)
    # And the shader's glints are the simulation's (to the few that sit on a junction),
    # within a few um: quantized points (1 um) and tangents (2.4e-5 rad on radii of
    # tens of mm) move a glint along its groove by about that.
    eng = Engraved.from_grooves(loaded.grooves, tool)
    narrow = np.isin(eng.path, eng.path[pa.arc])
    g = find_glints(eng, eye, light)
    ref = g.point[np.isin(g.path, np.unique(eng.path[narrow]))]
    d = np.min(np.linalg.norm(ref[:, None, :] - points[None, :, :], axis=2), axis=1)
    assert abs(len(points) - len(ref)) <= 2 and (d < 5e-3).mean() > 0.98


def test_page_is_self_contained(folder: Path) -> None:
    loaded = load_design(folder)
    text = build_page(loaded.grooves, loaded.config.setup())
    assert "http://" not in text and "https://" not in text
    assert "<script src" not in text and "<link" not in text


# Software WebGL splats the glints solved in the page's script; ?splat=0 draws the
# GPU's sprites, solved in the shader.
@pytest.mark.parametrize("query, mode", [("", "splat"), ("?splat=0", "sprites")])
def test_page_glints_match_python(folder: Path, browser: Any, query: str, mode: str) -> None:
    from PIL import Image

    t_start = time.perf_counter()
    page_file = write_page(folder, size=(W, H))
    loaded = load_design(folder)
    setup = loaded.config.setup()
    eng = Engraved.from_grooves(loaded.grooves, setup.tool)

    page = browser.new_page(viewport={"width": W + 20, "height": H + HUD + 20},
                            device_scale_factor=1)
    console: list[tuple[str, str]] = []
    requests: list[str] = []
    page.on("console", lambda m: console.append((m.type, m.text)))
    page.on("pageerror", lambda e: console.append(("error", str(e))))
    page.on("request", lambda r: requests.append(r.url))
    url = page_file.resolve().as_uri() + query
    page.goto(url)
    page.wait_for_function("window.specholo && (window.specholo.ready || window.specholo.error)")
    assert page.evaluate("window.specholo.error") is None
    assert page.evaluate("window.specholo.getView().mode") == mode
    box = page.locator("#view").bounding_box()
    assert box is not None and (box["width"], box["height"]) == (W, H)
    cx, cy = box["x"] + W / 2, box["y"] + H / 2

    drags = [(100, 0), (-230, -40), (160, 70)]  # CSS px: right/left, up/down
    seen_views = []
    for dx, dy in drags:
        page.mouse.move(cx, cy)
        page.mouse.down()
        page.mouse.move(cx + dx, cy + dy, steps=8)
        page.mouse.up()
        page.wait_for_timeout(150)  # a frame or two
        view = page.evaluate("window.specholo.getView()")
        seen_views.append((view["azimuth"], view["elevation"]))
        assert (view["width"], view["height"]) == (W, H)
        shot = page.locator("#view").screenshot()
        grey = np.asarray(Image.open(io.BytesIO(shot)).convert("L"))
        found = spots(grey)

        cam = Camera(math.radians(view["azimuth"]), math.radians(view["elevation"]),
                     view["distance"], math.radians(view["fov"]), W, H, view["eyeHeight"])
        light = Light(math.radians(view["light"]), view["lightDistance"])
        g = find_glints(eng, cam.position(), light)
        pix, _, ok = cam.project(g.point)
        inside = ok & (pix[:, 0] > 3) & (pix[:, 0] < W - 4) & (pix[:, 1] > 3) & (pix[:, 1] < H - 4)
        pix, stipple = pix[inside], g.stipple[inside]
        assert len(found) and len(pix)
        dist = np.min(np.linalg.norm(pix[:, None, :] - found[None, :, :], axis=2), axis=1)
        near = dist <= 2.0
        matched = np.unique(stipple[near]).size
        print(f"view {view['azimuth']:+.1f} {view['elevation']:+.1f}: {matched} stipples, "
              f"{near.mean():.3f} of {len(pix)} glints within 2 px, "
              f"median {np.median(dist):.3f} px, p95 {np.percentile(dist, 95):.3f} px, "
              f"spots {len(found)}")
        assert matched >= 20, (view, matched, np.median(dist))
        assert near.mean() >= 0.95, (view, near.mean())
        # And the page shows nothing Python does not: every spot is a Python glint.
        back = np.min(np.linalg.norm(found[:, None, :] - pix[None, :, :], axis=2), axis=1)
        assert (back <= 2.0).mean() >= 0.95, (view, (back <= 2.0).mean())
    # The drags really moved the view, to three different places.
    assert len({(round(a, 3), round(e, 3)) for a, e in seen_views}) == 3
    assert abs(seen_views[0][0] - 20.0) < 1e-6 and seen_views[0][1] == 0
    hud = page.locator("#angles").inner_text()
    assert "azimuth" in hud and "elevation" in hud

    errors = [text for kind, text in console if kind == "error"]
    assert not errors, errors
    # Nothing from the network: the page itself, and its workers' script from memory.
    assert all(u == url or u.startswith(("data:", "blob:")) for u in requests), requests
    page.close()
    assert time.perf_counter() - t_start < 60


def test_page_culling_loses_no_glint(folder: Path, browser: Any) -> None:
    from PIL import Image

    page_file = write_page(folder, size=(W, H))
    shots: dict[str, list[np.ndarray]] = {}
    drawn: dict[str, list[int]] = {}
    for query in ("", "?cull=0"):
        page = browser.new_page(viewport={"width": W + 20, "height": H + HUD + 20},
                                device_scale_factor=1)
        page.goto(page_file.resolve().as_uri() + query)
        page.wait_for_function("window.specholo && window.specholo.ready")
        for az, el, light in [(0, 0, 45), (-22, 7, 45), (31, -9, 45), (12, 3, 75)]:
            page.evaluate(f"window.specholo.setView({az}, {el}); window.specholo.setLight({light})")
            page.wait_for_timeout(100)
            shot = page.locator("#view").screenshot()
            shots.setdefault(query, []).append(
                np.asarray(Image.open(io.BytesIO(shot)).convert("RGB"), dtype=int))
            drawn.setdefault(query, []).append(page.evaluate("window.specholo.getView().drawn"))
        page.close()
    narrow = len(PageArcs.build(load_design(folder).grooves).table)
    assert all(n >= narrow for n in drawn["?cull=0"])
    assert all(0 < n < 0.05 * narrow for n in drawn[""])
    for culled, full in zip(shots[""], shots["?cull=0"], strict=True):
        # The same glints, added up in another order.
        assert np.abs(culled - full).max() <= 2
        assert (culled > 100).sum() > 100


def test_page_says_when_webgl2_is_missing(folder: Path, browser: Any) -> None:
    page_file = write_page(folder, size=(320, 240))
    page = browser.new_page()
    # Pretend the browser has no WebGL2 context.
    page.add_init_script("""
      const orig = HTMLCanvasElement.prototype.getContext;
      HTMLCanvasElement.prototype.getContext = function (kind, ...rest) {
        return kind === 'webgl2' ? null : orig.call(this, kind, ...rest);
      };""")
    page.goto(page_file.resolve().as_uri())
    page.wait_for_function("window.specholo && window.specholo.error")
    assert "WebGL2" in page.locator("#message").inner_text()
    assert page.locator("#message").is_visible()
    page.close()


def test_page_dimples_and_corners_match_python(tmp_path: Path, browser: Any) -> None:
    from specholo.setup import Setup
    from specholo.toolpaths.grooves import Grooves

    # Dimples on a grid, and zigzags of straight segments whose corners glint.
    xs, ys = np.meshgrid(np.linspace(-20, 20, 6), np.linspace(-12, 12, 4))
    dots = np.stack([xs.ravel(), ys.ravel()], axis=1)
    zig = [np.array([[-15 + 1.5 * i, y + 0.6 * (i % 2)] for i in range(21)])
           for y in np.linspace(-18, 18, 5)]
    vertices = np.concatenate([dots, *zig])
    sizes = [1] * len(dots) + [len(z) for z in zig]
    grooves = Grooves(vertices, np.zeros(len(vertices)), np.concatenate([[0], np.cumsum(sizes)]),
                      np.arange(len(sizes)))
    setup = Setup()
    html = tmp_path / "synthetic.html"
    html.write_text(build_page(grooves, setup, size=(W, H)), encoding="utf-8")
    eng = Engraved.from_grooves(grooves, setup.tool)
    page = browser.new_page(viewport={"width": W + 20, "height": H + HUD + 20},
                            device_scale_factor=1)
    page.goto(html.resolve().as_uri())
    page.wait_for_function("window.specholo && window.specholo.ready")
    assert page.evaluate("window.specholo.getView().corners") > 0
    for az, el in [(0, 0), (-8, 5), (6, -3)]:
        page.evaluate(f"window.specholo.setView({az}, {el})")
        page.wait_for_timeout(100)
        found, pix, stipple, view = _compare(page, eng)
        assert len(pix) > 10 and len(found)
        dist = np.min(np.linalg.norm(pix[:, None, :] - found[None, :, :], axis=2), axis=1)
        back = np.min(np.linalg.norm(found[:, None, :] - pix[None, :, :], axis=2), axis=1)
        corners = np.isin(stipple, np.arange(len(dots), len(sizes)))
        assert corners.any()
        assert (dist <= 2.0).mean() >= 0.95, (view, dist)
        assert (back <= 2.0).mean() >= 0.95, (view, back)
    page.close()
