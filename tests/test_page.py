"""The interactive page: its GPU glints land where the Python simulation puts them."""

from __future__ import annotations

import io
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from specholo.pipeline import load_design
from specholo.preview.page import build_page, write_page
from specholo.preview.render import Camera
from specholo.setup import Light
from specholo.simulation.glints import Engraved, find_glints

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--headless=new", "--no-sandbox", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--no-first-run",
    "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
]
W, H = 800, 600
HUD = 28  # the angle bar above the canvas, CSS px

@pytest.fixture(scope="module")
def folder(small_design: Path) -> Path:
    return small_design


@pytest.fixture(scope="module")
def browser() -> Any:
    if not Path(CHROMIUM).exists():
        pytest.skip("Chromium not installed at /usr/bin/chromium")
    sync_api = pytest.importorskip("playwright.sync_api")
    with sync_api.sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield b
        b.close()


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
        assert np.abs(tq - t).max() < 1e-5


def test_page_is_self_contained(folder: Path) -> None:
    loaded = load_design(folder)
    text = build_page(loaded.grooves, loaded.config.setup())
    assert "http://" not in text and "https://" not in text
    assert "<script src" not in text and "<link" not in text


def test_page_glints_match_python(folder: Path, browser: Any) -> None:
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
    url = page_file.resolve().as_uri()
    page.goto(url)
    page.wait_for_function("window.specholo && (window.specholo.ready || window.specholo.error)")
    assert page.evaluate("window.specholo.error") is None
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
    assert all(u == url or u.startswith("data:") for u in requests), requests
    page.close()
    assert time.perf_counter() - t_start < 60


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
