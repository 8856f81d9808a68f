"""The studio shows what will be cut: the grooves it sends are the design's
(every vertex to the micrometre, every arc within the stated tolerance), with
the plate and marks its files have, only to the run's secret; in a browser the
plate view draws them inside the plate and zooms about the pointer to a single
stipple's strokes, the 3D view turns without touching the pose, and each eye's
glints are the design's for its own azimuth."""

from __future__ import annotations

import base64
import gzip
import io
import json
import math
import re
import threading
import time
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from specholo.fabrication.plate import Plate
from specholo.jobs.flat.folder import DesignConfig
from specholo.scene.loading import load_model
from specholo.studio import cut
from specholo.studio.cut import ROUNDING, TOLERANCE, design_grooves, polylines
from specholo.studio.preview import fast_preview
from specholo.studio.server import StudioServer, make_server
from specholo.toolpaths.grooves import Grooves

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"
#: Farthest a sent point may lie from where it stands for: half a micrometre in
#: x and in y.
ROUNDED = math.sqrt(2) * 0.5 * ROUNDING + 1e-9
SETTINGS = {"stipples": 150, "size": 50, "center_z": -30, "rotate_y": 20}


# ---------------------------------------------------------------- the polylines
def arc_points(p0: np.ndarray, p1: np.ndarray, bulge: float, n: int) -> np.ndarray:
    """n points along the arc from p0 to p1 of this bulge (the DXF convention:
    sweep 4 atan(bulge), counter-clockwise for bulge > 0), from the geometry of
    the circle, not the studio's code."""
    if abs(bulge) < 1e-9:  # bows less than a nanometre a mm of chord: its chord
        return p0 + np.linspace(0, 1, n)[:, None] * (p1 - p0)
    sweep = 4 * math.atan(bulge)
    chord = np.linalg.norm(p1 - p0)
    radius = chord / (2 * math.sin(abs(sweep) / 2))
    mid, along = (p0 + p1) / 2, (p1 - p0) / chord
    left = np.array([-along[1], along[0]])
    # the centre lies left of the chord for a counter-clockwise arc under a half
    # turn, right of it for one over a half turn (cos(sweep / 2) < 0)
    centre = mid + left * radius * math.cos(sweep / 2) * math.copysign(1.0, bulge)
    a0 = math.atan2(*(p0 - centre)[::-1])
    t = a0 + sweep * np.linspace(0, 1, n)
    return centre + radius * np.column_stack([np.cos(t), np.sin(t)])


def distance_to_polyline(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Each point's distance (k,) to the polyline (m, 2)."""
    if len(line) == 1:
        return np.linalg.norm(points - line[0], axis=1)
    a, b = line[:-1], line[1:]
    d = b - a
    length = np.maximum((d * d).sum(axis=1), 1e-300)
    t = np.clip(((points[:, None, :] - a[None]) * d[None]).sum(axis=2) / length, 0, 1)
    near = a[None] + t[..., None] * d[None]
    return np.linalg.norm(points[:, None, :] - near, axis=2).min(axis=1)


def check_polylines(grooves: Grooves, xy: np.ndarray, offsets: np.ndarray, stipple: np.ndarray,
                    slack: float) -> int:
    """Every path's polyline holds its vertices, in order, within ``slack``; the
    points between two of them lie on that arc; every point of every arc lies
    within TOLERANCE (+ slack) of the polyline. Returns the points inserted."""
    v, b, o = grooves.vertices, grooves.bulges, grooves.offsets
    assert len(offsets) == grooves.n_paths + 1
    np.testing.assert_array_equal(stipple, grooves.stipple)
    inserted = 0
    for q in range(grooves.n_paths):
        line = xy[offsets[q]:offsets[q + 1]]
        verts = v[o[q]:o[q + 1]]
        # the vertices, in order: where each stands in the polyline
        at, j = [], 0
        for p in verts:
            while j < len(line) and np.linalg.norm(line[j] - p) > slack:
                j += 1
            assert j < len(line), (q, p)
            at.append(j)
            j += 1
        assert at[0] == 0 and at[-1] == len(line) - 1
        for i in range(len(verts) - 1):
            piece = line[at[i]:at[i + 1] + 1]
            inserted += len(piece) - 2
            bulge = float(b[o[q] + i])
            true = arc_points(verts[i], verts[i + 1], bulge, 200)
            assert distance_to_polyline(true, piece).max() <= TOLERANCE + slack, (q, i, bulge)
            # and the polyline does not wander off the arc either
            assert distance_to_polyline(piece, true).max() <= slack + 1e-3 * np.linalg.norm(
                verts[i + 1] - verts[i]) + 1e-9
    return inserted


def test_arcs_become_chords_within_the_tolerance(groove_example: Grooves):
    """Arcs of 270 and 180 degrees, both ways, a straight segment and a dot: the
    vertices stay exactly, the arcs' new points lie on them, and no point of an
    arc is farther than the tolerance from its chords; an arc is cut into no
    more pieces than that needs."""
    xy, offsets = polylines(groove_example)
    inserted = check_polylines(groove_example, xy, offsets, groove_example.stipple, 1e-12)
    assert inserted > 100  # the big arcs are many chords; the straight one is one
    # fewest pieces: one less and a piece's middle is farther than the tolerance
    v, b = groove_example.vertices, groove_example.bulges
    for i in (0, 1, 5, 6):
        sweep = abs(4 * math.atan(b[i]))
        chord = np.linalg.norm(v[i + 1] - v[i])
        radius = chord / (2 * math.sin(sweep / 2))
        n = int(cut.arc_pieces(np.array([chord]), np.array([b[i]]))[0])
        assert radius * (1 - math.cos(sweep / (2 * n))) <= TOLERANCE
        assert radius * (1 - math.cos(sweep / (2 * (n - 1)))) > TOLERANCE
    assert cut.arc_pieces(np.array([10.0]), np.array([0.0]))[0] == 1


@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_any_grooves_become_polylines_within_the_tolerance(
        data: st.DataObject, grooves_strategy: Callable[..., st.SearchStrategy[Grooves]]):
    grooves = data.draw(grooves_strategy(max_paths=4, max_arcs=4, max_bulge=3.0))
    xy, offsets = polylines(grooves)
    check_polylines(grooves, xy, offsets, grooves.stipple, 1e-9)


# ---------------------------------------------------------------- the endpoint
@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[StudioServer]:
    s = make_server(BUNNY, tmp_path_factory.mktemp("studio-out"), 0)
    threading.Thread(target=s.serve_forever, daemon=True).start()
    yield s
    s.shutdown()
    s.server_close()
    s.studio.runner.wait(60)


def request(server: StudioServer, path: str, body: Any = None,
            headers: dict[str, str] | None = None) -> tuple[int, Any, Any]:
    """(status, JSON or bytes, headers) of one request with the run's secret."""
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(server.origin + path, data=data,
                                 headers={"X-Specholo-Token": server.token, **(headers or {})})
    try:
        with urllib.request.urlopen(req, timeout=60) as reply:
            code, raw, hdrs = reply.status, reply.read(), reply.headers
    except urllib.error.HTTPError as exc:
        code, raw, hdrs = exc.code, exc.read(), exc.headers
    if hdrs["Content-Type"] == "application/json" and hdrs["Content-Encoding"] != "gzip":
        return code, json.loads(raw), hdrs
    return code, raw, hdrs


def designed(server: StudioServer, settings: dict[str, Any]) -> Path:
    """The folder of an exact design of these settings, made through the server."""
    code, got, _ = request(server, "/api/design", {"settings": settings})
    assert code == 202, got
    server.studio.runner.wait(120)
    code, st_, _ = request(server, "/api/design")
    assert st_["state"] == "done", st_
    return Path(st_["folder"])


def test_the_grooves_sent_are_the_designs(server: StudioServer):
    code, got, _ = request(server, "/api/design/grooves")
    assert code == 400 and "no finished design" in got["error"]
    folder = designed(server, SETTINGS)
    code, got, hdrs = request(server, "/api/design/grooves")
    assert code == 200, got
    grooves = Grooves.load(folder / "grooves.npz")
    xy = np.reshape(got["xy"], (-1, 2))
    # sent to the micrometre, and compact: no more digits than that
    assert np.allclose(xy * 1000, np.rint(xy * 1000), atol=1e-6)
    assert got["decimated"] is None and got["paths"] == grooves.n_paths
    assert got["tolerance_mm"] == TOLERANCE
    check_polylines(grooves, xy, np.asarray(got["offsets"]), np.asarray(got["stipple"]),
                    ROUNDED)
    # the plate and marks of the design's files
    info = json.loads((folder / "hologram.json").read_text())
    plate = Plate.from_corners(np.array(info["plate"]["plate_mm"]))
    sent = got["plate"]
    assert sent["corners_mm"] == info["plate"]["plate_mm"]
    assert sent["width_mm"] == plate.width and sent["height_mm"] == plate.height
    np.testing.assert_array_equal(sent["marks_mm"], plate.marks())
    assert sent["mark_arm_mm"] == plate.mark_arm and sent["mark_radius_mm"] == plate.mark_radius
    # as the drawing has them (SVG: y down)
    svg = (folder / "hologram.svg").read_text()
    start = re.search(r'inkscape:label="\d+ PLATE"', svg)
    assert start is not None
    layer = svg[start.start():svg.index("</g>", start.start())]
    rect = re.search(r'<rect x="([-\d.]+)" y="([-\d.]+)" width="([\d.]+)" height="([\d.]+)"',
                     layer)
    assert rect is not None
    x, y, width, height = map(float, rect.groups())
    assert [[x, -y - height], [x + width, -y]] == sent["corners_mm"]
    circles = re.findall(r'<circle cx="([-\d.]+)" cy="([-\d.]+)" r="([\d.]+)"/>', layer)
    centres = [(float(cx), -float(cy)) for cx, cy, r in circles
               if float(r) == sent["mark_radius_mm"]]
    assert sorted(centres) == sorted(map(tuple, sent["marks_mm"]))
    assert got["groove_width_mm"] == info["tool"]["groove_width_mm"]
    assert got["settings"]["stipples"] == 150
    # gzipped for a client that takes it, the same JSON
    code, raw, hdrs = request(server, "/api/design/grooves", headers={"Accept-Encoding": "gzip"})
    assert code == 200 and hdrs["Content-Encoding"] == "gzip"
    assert json.loads(gzip.decompress(raw)) == got
    code, raw, hdrs = request(server, "/api/design/grooves",
                              headers={"Accept-Encoding": "gzip;q=0, br"})
    assert hdrs["Content-Encoding"] is None and raw == got



def test_a_design_seen_done_is_drawn_while_the_next_one_runs(server: StudioServer):
    """A page that saw a design done asks for its grooves by the folder the
    status named: it gets them even once the next design has started (the race
    a quick slider makes), and no folder this studio did not design into."""
    state = server.studio.design_status()
    folder = Path(state["folder"]) if state["state"] == "done" else designed(server, SETTINGS)
    asked = "/api/design/grooves?folder=" + urllib.parse.quote(str(folder))
    code, before, _ = request(server, asked)
    assert code == 200 and before["folder"] == str(folder)
    code, got, _ = request(server, "/api/design", {"settings": {**SETTINGS, "stipples": 160}})
    assert code == 202 and server.studio.design_status()["state"] == "running"
    code, during, _ = request(server, asked)
    assert code == 200 and during == before
    # the bare route is still the open model's finished design only
    code, bare, _ = request(server, "/api/design/grooves")
    assert code == 400 and "no finished design" in bare["error"]
    server.studio.runner.wait(120)
    # a path the studio did not design into is not read, however it is spelled
    for other in (folder.parent, folder / "..", ROOT / "examples", "/etc"):
        code, got, _ = request(server, "/api/design/grooves?folder="
                               + urllib.parse.quote(str(other)))
        assert code == 400 and "no finished design of this studio" in got["error"], other
    designed(server, SETTINGS)


def test_the_grooves_need_the_runs_secret(server: StudioServer):
    for hdrs in ({}, {"X-Specholo-Token": ""}, {"X-Specholo-Token": server.token[:-1]}):
        req = urllib.request.Request(server.origin + "/api/design/grooves", headers=hdrs)
        with pytest.raises(urllib.error.HTTPError) as err:
            urllib.request.urlopen(req, timeout=10)
        assert err.value.code == 403 and err.value.headers["Connection"] == "close"
        assert "secret" in json.loads(err.value.read())["error"]
    # the page's script holds no secret and needs none
    with urllib.request.urlopen(server.origin + "/plate_view.js", timeout=10) as reply:
        assert reply.status == 200 and server.token.encode() not in reply.read()
        assert reply.headers["Content-Type"].startswith("text/javascript")


def test_over_the_cap_every_kth_stipple_is_sent_whole(server: StudioServer,
                                                      monkeypatch: pytest.MonkeyPatch):
    folder = designed(server, SETTINGS) if server.studio.design_status()["state"] != "done" \
        else Path(server.studio.design_status()["folder"])
    whole = design_grooves(folder)
    everything = len(whole["xy"]) // 2
    cap = everything // 3
    part = design_grooves(folder, max_points=cap)
    d = part["decimated"]
    assert len(part["xy"]) // 2 == d["points_drawn"] <= cap
    assert d["points_all"] == everything and d["max_points"] == cap and d["stride"] >= 3
    cut_ids = np.unique(whole["stipple"])
    kept = cut_ids[::d["stride"]]
    assert sorted(set(part["stipple"])) == kept.tolist() == sorted(set(kept.tolist()))
    assert d["stipples_drawn"] == len(kept) and d["stipples_cut"] == len(cut_ids)

    def paths_of(g: dict[str, Any], ids: set[int]) -> list[tuple[int, list[float]]]:
        o, xy = g["offsets"], g["xy"]
        return [(s, xy[2 * o[q]:2 * o[q + 1]]) for q, s in enumerate(g["stipple"]) if s in ids]

    assert paths_of(part, set(kept.tolist())) == paths_of(whole, set(kept.tolist()))
    # the server keeps to its cap, and says so
    monkeypatch.setattr(cut, "MAX_POINTS", cap)
    code, got, _ = request(server, "/api/design/grooves")
    assert code == 200 and got["decimated"] == d


def test_the_preview_plate_is_the_designs_within_a_millimetre(server: StudioServer):
    """Before a design the page draws the plate the design would fit: centred,
    whole millimetres, within 1 mm of the design's; a given plate is that plate."""
    state = server.studio.design_status()
    info = json.loads((Path(state["folder"]) / "hologram.json").read_text()) \
        if state["state"] == "done" else {"settings": {}}
    if any(info["settings"].get(k) != v for k, v in SETTINGS.items()):
        info = json.loads((designed(server, SETTINGS) / "hologram.json").read_text())
    code, got, _ = request(server, "/api/preview", {"settings": SETTINGS})
    assert code == 200, got
    plate = got["plate"]
    assert plate["given"] is False
    corners = np.array(plate["corners_mm"])
    np.testing.assert_array_equal(corners[0], -corners[1])
    np.testing.assert_array_equal(2 * corners[1], np.round(2 * corners[1]))
    np.testing.assert_allclose(corners, info["plate"]["plate_mm"], atol=0.5)
    np.testing.assert_array_equal(plate["marks_mm"], Plate.from_corners(corners).marks())
    code, got, _ = request(server, "/api/preview", {"settings": {
        **SETTINGS, "plate_width": 120, "plate_height": 90}})
    assert code == 200, got
    assert got["plate"]["given"] is True
    assert got["plate"]["corners_mm"] == [[-60, -45], [60, 45]]


# ---------------------------------------------------------------- in a browser
def stipple_points(grooves: Grooves, stipple: int) -> np.ndarray:
    """The vertices of a stipple's paths (k, 2)."""
    return np.concatenate([grooves.vertices[grooves.offsets[p]:grooves.offsets[p + 1]]
                           for p in np.flatnonzero(grooves.stipple == stipple)])


def _page(server: StudioServer, browser: Any) -> tuple[Any, Any, list[str]]:
    context = browser.new_context(bypass_csp=True, viewport={"width": 1400, "height": 1500})
    page = context.new_page()
    errors: list[str] = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(server.url)
    page.wait_for_function("window.studio && window.studio.previews() > 0 && "
                           "!window.studio.busy()", timeout=30_000)
    return context, page, errors


def _settings(page: Any, values: dict[str, float]) -> None:
    # a slider as the maker moves it; the turn, as a drag on the model sets it
    for k, v in values.items():
        page.evaluate("([k, v]) => { const e = document.getElementById(k); "
                      "if (e) { e.value = v; e.dispatchEvent(new Event('input')); } "
                      "else { setSetting(k, v); changed(); } }", [k, v])
    page.wait_for_function("!window.studio.busy()", timeout=30_000)


def _drawn(page: Any) -> None:
    """Wait for the views' next frame."""
    page.wait_for_function("!window.studioCut.pending()")


def _pixels(page: Any, canvas: str) -> np.ndarray:
    """The canvas's pixels (h, w, 3), as drawn."""
    from PIL import Image

    url = page.evaluate(f"document.getElementById('{canvas}').toDataURL('image/png')")
    img = Image.open(io.BytesIO(base64.b64decode(url.split(",", 1)[1]))).convert("RGB")
    return np.asarray(img).astype(int)


def _rect(page: Any) -> tuple[float, float, float, float]:
    """The plate's outline on the plate canvas, px: left, top, right, bottom."""
    (x0, y0), (x1, y1) = page.evaluate("window.studioCut.plate().corners_mm")
    left, top = page.evaluate(f"window.studioCut.toScreen({x0}, {y1})")
    right, bottom = page.evaluate(f"window.studioCut.toScreen({x1}, {y0})")
    return left, top, right, bottom


def test_the_plate_view_draws_the_grooves_and_zooms_to_a_stipple(server: StudioServer,
                                                                 browser: Any):
    context, page, errors = _page(server, browser)
    assert page.evaluate("window.studioCut.grooves()") is None or \
        page.evaluate("window.studioCut.grooves().stale")
    _settings(page, SETTINGS)
    # the page follows the settings with an exact design, then draws its grooves
    page.wait_for_function("window.studio.exact() && window.studio.exact().current && "
                           "!window.studioCut.loading() && window.studioCut.grooves() && "
                           "!window.studioCut.grooves().stale", timeout=120_000)
    folder = Path(server.studio.design_status()["folder"])
    info = json.loads((folder / "hologram.json").read_text())
    assert page.evaluate("window.studioCut.plate().corners_mm") == info["plate"]["plate_mm"]
    w, h = (np.subtract(*info["plate"]["plate_mm"][::-1])).tolist()
    assert page.inner_text("#plate-info").startswith(f"plate {w:g} \u00d7 {h:g} mm")
    # the grooves alone: inside the outline, nothing outside it
    page.uncheck("#show-glints")
    page.uncheck("#show-marks")
    _drawn(page)
    px = _pixels(page, "plate")
    left, top, right, bottom = _rect(page)
    rows, cols = np.mgrid[0:px.shape[0], 0:px.shape[1]]
    outside = (cols < left - 2) | (cols > right + 2) | (rows < top - 2) | (rows > bottom + 2)
    inside = (cols > left + 2) & (cols < right - 2) & (rows > top + 2) & (rows < bottom - 2)
    assert outside.sum() > 10_000 and (px[outside] == 0).all()
    fill = np.array([0x1D, 0x21, 0x26])  # the plate's own colour
    lit = inside & (np.abs(px - fill).sum(axis=2) > 60)
    assert lit.sum() > 2000, lit.sum()
    # where the design's grooves are: their extent, on this canvas's scale
    k = page.evaluate("window.studioCut.view().k")
    (gx0, gy0), (gx1, gy1) = info["plate"]["groove_extent_mm"]
    ex0, ey1 = page.evaluate(f"window.studioCut.toScreen({gx0}, {gy0})")
    ex1, ey0 = page.evaluate(f"window.studioCut.toScreen({gx1}, {gy1})")
    ys, xs = np.nonzero(lit)
    reach = 2 + 0.5 * max(1.0, info["tool"]["groove_width_mm"] * k)
    for got, want in ((xs.min(), ex0), (xs.max(), ex1), (ys.min(), ey0), (ys.max(), ey1)):
        assert abs(got - want) <= reach + 1, (got, want)

    # point at a stroke of a stipple near the middle: it names its stipple
    grooves = Grooves.load(folder / "grooves.npz")
    (px0, py0), (px1, py1) = info["plate"]["plate_mm"]
    box = page.locator("#plate").bounding_box()
    named = mid = None
    for s_ in sorted(set(grooves.stipple.tolist()), key=lambda i: np.ptp(
            stipple_points(grooves, i), axis=0).max()):
        mine = stipple_points(grooves, s_)
        if (np.ptp(mine, axis=0).max() * k < 8 or np.abs(mine[:, 0]).max() > (px1 - px0) / 4
                or np.abs(mine[:, 1]).max() > (py1 - py0) / 4):
            continue
        paths = np.flatnonzero(grooves.stipple == s_)
        q = int(paths[np.argmax(np.diff(grooves.offsets)[paths])])
        at = grooves.vertices[grooves.offsets[q]:grooves.offsets[q + 1]]
        mid = at[len(at) // 2]
        near = {int(grooves.stipple[p]) for p in range(grooves.n_paths) if distance_to_polyline(
            mid[None], grooves.vertices[grooves.offsets[p]:grooves.offsets[p + 1]])[0] < 0.01}
        if near == {s_}:
            named = s_
            break
    assert named is not None and mid is not None
    sx, sy = page.evaluate(f"window.studioCut.toScreen({mid[0]}, {mid[1]})")
    # the pointer lands on whole pixels of the page: where it is on the canvas
    ux, uy = round(box["x"] + 1 + sx), round(box["y"] + 1 + sy)
    cursor = np.array([ux - box["x"] - 1, uy - box["y"] - 1])
    page.mouse.move(ux, uy)
    _drawn(page)
    assert page.evaluate("window.studioCut.hovered()") == named
    page.mouse.down()
    page.mouse.up()
    _drawn(page)
    assert page.evaluate("window.studioCut.picked()") == named
    paths = int((grooves.stipple == named).sum())
    assert page.inner_text("#cut-stipple").startswith(
        f"stipple {named}: {paths} path{'' if paths == 1 else 's'}")

    def picked_box() -> np.ndarray:
        px = _pixels(page, "plate")
        # the picked stipple's yellow, and what blends it mostly
        ys, xs = np.nonzero((px[..., 0] - px[..., 2] > 100) & (px[..., 1] - px[..., 2] > 80))
        assert len(xs) > 0
        return np.array([xs.min(), ys.min(), xs.max(), ys.max()], dtype=float)

    extent = np.ptp(stipple_points(grooves, named), axis=0).max()
    before = picked_box()
    # the wheel zooms about the pointer: the point under it stays, a stroke spans more pixels
    zoom = min(8.0, 120 / (extent * k))
    notches = max(1, math.floor(math.log(zoom) / (0.0015 * 300)))
    for _ in range(notches):
        page.mouse.wheel(0, -300)
        page.wait_for_function("!window.studioCut.pending()")
    time.sleep(0.2)
    _drawn(page)
    k2 = page.evaluate("window.studioCut.view().k")
    assert k2 == pytest.approx(k * math.exp(0.0015 * 300 * notches), rel=1e-6)
    f = k2 / k
    np.testing.assert_allclose(page.evaluate(f"window.studioCut.toScreen({mid[0]}, {mid[1]})"),
                               cursor + f * (np.array([sx, sy]) - cursor), atol=1e-6)
    after = picked_box()
    width = info["tool"]["groove_width_mm"]
    for i in (0, 1):  # its strokes' spread in x and y, less the line's own width
        spread0 = before[i + 2] - before[i] - max(2, width * k)
        spread1 = after[i + 2] - after[i] - max(2, width * k2)
        if spread0 > 10:
            assert spread1 == pytest.approx(spread0 * k2 / k, abs=4 + k2 / k * 2), (i, before,
                                                                                       after)
    assert after[2] - after[0] > 2 * (before[2] - before[0])
    # a drag pans: the plate moves with the pointer
    mx, my = round(box["x"] + 240), round(box["y"] + 240)
    here = np.array(page.evaluate(f"window.studioCut.toScreen({mid[0]}, {mid[1]})"))
    page.mouse.move(mx, my)
    page.mouse.down()
    page.mouse.move(mx + 50, my - 30, steps=5)
    page.mouse.up()
    _drawn(page)
    np.testing.assert_allclose(page.evaluate(f"window.studioCut.toScreen({mid[0]}, {mid[1]})"),
                               here + [50, -30], atol=1e-6)
    assert page.evaluate("window.studioCut.picked()") == named  # a drag is no click
    context.close()
    assert errors == []


def test_the_3d_view_turns_and_each_eye_sees_its_own_glints(
        server: StudioServer, browser: Any, monkeypatch: pytest.MonkeyPatch):
    if server.studio.design_status()["state"] != "done":
        designed(server, SETTINGS)
    # over the cap, the page draws every k-th stipple's grooves and says so
    monkeypatch.setattr(cut, "MAX_POINTS", 2000)
    context, page, errors = _page(server, browser)
    # no design to arrive while the view is compared: none is started, and one
    # the page started before it was told (a slow machine) is done and drawn
    page.uncheck("#follow")
    server.studio.runner.wait(120)
    page.wait_for_function("!document.getElementById('design').disabled && "
                           "!window.studioCut.loading()", timeout=30_000)
    decimated = page.evaluate("window.studioCut.grooves().decimated")
    assert decimated["points_drawn"] <= 2000 < decimated["points_all"]
    assert f"only every {decimated['stride']}" in page.inner_text("#plate-note")
    assert f"{decimated['stipples_drawn']} of {decimated['stipples_cut']} stipples" in \
        page.inner_text("#plate-note")
    _settings(page, {**SETTINGS, "stipples": 200})
    _drawn(page)
    pose = page.evaluate("window.studio.settings()")
    asked = page.evaluate("window.studio.previews()")
    camera = page.evaluate("window.studioCut.camera()")
    first = _pixels(page, "view3d")
    assert (first.sum(axis=2) > 0).sum() > 500
    # a drag turns the view, not the model
    box = page.locator("#view3d").bounding_box()
    cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    page.mouse.move(cx, cy)
    page.mouse.down()
    page.mouse.move(cx + 80, cy + 20, steps=8)
    page.mouse.up()
    _drawn(page)
    turned = page.evaluate("window.studioCut.camera()")
    assert turned["yaw"] == pytest.approx(camera["yaw"] - 40)
    assert turned["pitch"] == pytest.approx(camera["pitch"] + 10)
    second = _pixels(page, "view3d")
    assert (np.abs(second - first).sum(axis=2) > 0).sum() > 500
    assert page.evaluate("window.studio.settings()") == pose
    assert page.evaluate("window.studio.previews()") == asked
    # double-click: the first view again, pixel for pixel
    page.mouse.dblclick(cx, cy)
    _drawn(page)
    assert page.evaluate("window.studioCut.camera()") == camera
    np.testing.assert_array_equal(_pixels(page, "view3d"), first)

    # each eye's glints: the design's, at the head's azimuth -/+ the eye's half angle
    page.evaluate("(() => { const e = document.getElementById('azimuth'); e.value = 12; "
                  "e.dispatchEvent(new Event('input')); })()")
    _drawn(page)
    eyes = page.evaluate("window.studioCut.eyeGlints()")
    settings_ = page.evaluate("window.studio.settings()")
    config = DesignConfig.from_dict({k: settings_[k] for k in (
        "size", "center_z", "up", "rotate_x", "rotate_y", "offset_x", "offset_y",
        "light_elevation", "view_range", "view_distance", "stipples", "seed")})
    pv = fast_preview(load_model(BUNNY), config)
    viewer = pv.viewer
    head = math.radians(12.0)
    left, right = viewer.stereo(np.array([head]))
    half = viewer.eye_half_angle
    np.testing.assert_allclose(left[0], viewer.eye(np.array([head - half]))[0], atol=1e-9)
    np.testing.assert_allclose(right[0], viewer.eye(np.array([head + half]))[0], atol=1e-9)
    assert left[0][0] < right[0][0]  # the left eye is the one to the left (-x)
    assert eyes["half"] == pytest.approx(math.degrees(half))
    for side, az in (("left", head - half), ("right", head + half)):
        ids, glints = pv.glints(az)
        shown = eyes[side]
        assert [g["id"] for g in shown] == ids.tolist() and len(ids) > 20
        np.testing.assert_allclose([[g["x"], g["y"]] for g in shown], glints, atol=2e-3)
    assert "the left eye (red) sees" in page.inner_text("#plate-note")

    # the walk: the head goes across the range and back, and stops when told
    rng = settings_["view_range"]
    page.click("#walk")
    # the azimuth each frame for a second (the page's own clock: a busy machine
    # cannot stretch it), well within the walk's first half
    seen = page.evaluate("""async () => {
        const out = [], t0 = performance.now();
        while (performance.now() - t0 < 1000) {
          await new Promise((r) => requestAnimationFrame(r));
          out.push(window.studio.azimuth());
        }
        return out; }""")
    assert page.evaluate("window.studioCut.walking()")
    assert all(-rng <= a <= rng for a in seen) and seen[0] < -rng / 2
    assert all(b >= a for a, b in zip(seen, seen[1:], strict=False)) and seen[-1] > seen[0] + 5
    page.click("#walk")
    assert not page.evaluate("window.studioCut.walking()")
    still = page.evaluate("window.studio.azimuth()")
    time.sleep(0.3)
    assert page.evaluate("window.studio.azimuth()") == still
    context.close()
    assert errors == []
