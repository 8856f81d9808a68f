"""An interactive, self-contained web page of a design's glints (WebGL2).

The page recomputes every glint on the GPU for the current eye and light with
the physics of :func:`~specholo.simulation.glints.find_glints`: one vertex per
groove arc solves h(g) . t = 0 on the groove wall by regula falsi in the arc's
own parameter and emits a point sprite where the glint projects, exactly as
:class:`~specholo.preview.render.Camera` would project it. Dragging moves the
viewpoint (shift+drag moves the light's elevation).

Arcs are shipped in the plate frame, whose origin is the plate centre, so the
coordinates are small and float32 keeps them to about 10 nm. Each arc is stored
by its start point, start tangent angle, length and signed sweep, which covers
straight segments (sweep 0) without a huge radius or a far-away centre.
"""

from __future__ import annotations

import base64
import html
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from specholo.errors import SpecholoError
from specholo.fabrication.atomic import atomic_open
from specholo.setup import Setup
from specholo.toolpaths.grooves import Grooves

#: Turn value marking the last arc of a path (no corner after it); any |turn| <= pi is real.
NO_CORNER = 100.0
#: Drag sensitivity, degrees per CSS pixel.
DEGREES_PER_PIXEL = 0.2
#: Largest |azimuth| and |elevation| the page lets the eye reach, degrees.
AZIMUTH_LIMIT = 80.0
ELEVATION_LIMIT = 60.0
#: Corners turning less than this (radians) are tangent-continuous joins: float32
#: cannot tell h . t apart on their two sides, so they are not shipped as corners.
MIN_TURN = 1e-7
#: Regula falsi steps per bracketed arc (as in find_glints).
ITERATIONS = 12
#: Width and height the default field of view is fitted for (any canvas keeps that fov).
FRAME_SIZE = (800, 600)

_JS_PATH = Path(__file__).with_name("page.js")


def arc_table(grooves: Grooves) -> tuple[np.ndarray, np.ndarray]:
    """The grooves as the page's vertex data.

    Args:
        grooves: the grooves.

    Returns:
        arcs (k, 6) float32 rows (start x, start y, start tangent angle, length,
        signed sweep, turn to the next arc's start tangent or :data:`NO_CORNER`),
        and dimples (q, 2) float32 positions, all in mm and radians.
    """
    seg = grooves.segments()
    chord = seg.end - seg.start
    length = np.linalg.norm(chord, axis=1)
    sweep = 4.0 * np.arctan(seg.bulge)
    half = 0.5 * sweep
    # Arc length from the chord; sin(x)/x -> 1 for straight segments.
    with np.errstate(divide="ignore", invalid="ignore"):
        sinc = np.where(np.abs(half) > 1e-8, np.sin(half) / half, 1.0)
    arc_len = length / sinc
    theta0 = np.arctan2(chord[:, 1], chord[:, 0]) - half
    turn = np.full(len(seg), NO_CORNER)
    if len(seg) > 1:
        same = seg.path[1:] == seg.path[:-1]
        d = theta0[1:] - (theta0[:-1] + sweep[:-1])
        d = (d + math.pi) % (2.0 * math.pi) - math.pi
        turn[:-1] = np.where(same, d, NO_CORNER)
    arcs = np.stack([seg.start[:, 0], seg.start[:, 1], theta0, arc_len, sweep, turn], axis=1)
    dots, _ = grooves.dots()
    return arcs.astype(np.float32), np.asarray(dots, dtype=np.float32).reshape(-1, 2)


def page_fov(setup: Setup, grooves: Grooves) -> float:
    """Vertical field of view (radians) framing the plate across the viewing range."""
    from specholo.preview.render import design_camera

    half = setup.viewer.half_range
    cam = design_camera(setup, grooves, width=FRAME_SIZE[0], height=FRAME_SIZE[1],
                        frame_azimuths=(-half, half))
    return cam.fov


def page_meta(setup: Setup, grooves: Grooves, title: str = "specholo") -> dict[str, Any]:
    """Everything but the arrays the page needs: setup, camera, plate and limits."""
    from specholo.preview.render import plate_bounds

    light = setup.light
    return {
        "title": title,
        "tool": {"radius": setup.tool.radius, "depth": setup.tool.depth,
                 "maxTilt": setup.tool.max_tilt},
        "light": {"elevation": math.degrees(light.elevation), "distance": light.distance},
        "camera": {"distance": setup.viewer.eye_radius, "eyeHeight": setup.viewer.height,
                   "fov": math.degrees(page_fov(setup, grooves))},
        "plate": plate_bounds(grooves).tolist(),
        "limits": {"azimuth": AZIMUTH_LIMIT, "elevation": ELEVATION_LIMIT,
                   "degreesPerPixel": DEGREES_PER_PIXEL},
        "iterations": ITERATIONS,
        "noCorner": NO_CORNER,
        "viewRange": math.degrees(setup.viewer.half_range),
    }


def _b64(a: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(a, dtype="<f4").tobytes()).decode("ascii")


def build_page(grooves: Grooves, setup: Setup, title: str = "specholo",
               size: tuple[int, int] | None = None) -> str:
    """The whole page as one HTML string (scripts and data inline, nothing fetched).

    Args:
        grooves: the grooves.
        setup: the design's setup (tool, light, viewer).
        title: page title.
        size: fixed canvas (width, height) in CSS pixels, or None to fill the
            window; the URL parameters ``w`` and ``h`` override it.
    """
    arcs, dots = arc_table(grooves)
    # Only real corners get a second vertex; biarc joins are smooth to ~1e-12 rad.
    corners = arcs[np.abs(arcs[:, 5]) < NO_CORNER]
    corners = corners[np.abs(corners[:, 5]) > MIN_TURN]
    meta = page_meta(setup, grooves, title)
    meta["counts"] = {"arcs": len(arcs), "corners": len(corners), "dots": len(dots)}
    meta["size"] = list(size) if size is not None else None
    # "<" escaped so the JSON cannot close its script element.
    meta_json = json.dumps(meta).replace("<", "\\u003c")
    script = _JS_PATH.read_text(encoding="utf-8")
    return (
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n"
        "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
        f"<title>{html.escape(title)}</title>\n<style>{_CSS}</style></head>\n<body>\n"
        "<div id=\"hud\"><span id=\"angles\">loading...</span>"
        "<span id=\"help\">drag: move the eye &middot; shift+drag: move the light</span></div>\n"
        "<canvas id=\"view\"></canvas>\n<div id=\"message\" hidden></div>\n"
        f"<script type=\"application/json\" id=\"meta\">{meta_json}</script>\n"
        f"<script type=\"text/plain\" id=\"arcs\">{_b64(arcs)}</script>\n"
        f"<script type=\"text/plain\" id=\"corners\">{_b64(corners)}</script>\n"
        f"<script type=\"text/plain\" id=\"dots\">{_b64(dots)}</script>\n"
        f"<script>\n{script}\n</script>\n</body></html>\n"
    )


_CSS = (
    "html,body{margin:0;padding:0;background:#08090b;color:#cfd3da;"
    "font:14px/1.4 system-ui,sans-serif;overflow:hidden}"
    "#hud{height:28px;display:flex;gap:2em;align-items:center;padding:0 10px;"
    "white-space:nowrap;font-variant-numeric:tabular-nums}"
    "#help{color:#7d838c}"
    "canvas{display:block;touch-action:none;cursor:grab}"
    "#message{position:absolute;top:40px;left:10px;right:10px;padding:1em;"
    "background:#3a1010;color:#fff;border-radius:4px}"
)


def write_page(folder: str | os.PathLike[str], out: str | os.PathLike[str] | None = None,
               size: tuple[int, int] | None = None) -> Path:
    """Write the interactive page of the design in ``folder``.

    Args:
        folder: a design folder written by ``specholo design``.
        out: the HTML file; default ``folder/view.html``.
        size: fixed canvas (width, height) in CSS pixels, or None to fill the window.

    Returns:
        The path written.
    """
    from specholo.pipeline import load_design

    loaded = load_design(folder)
    path = Path(folder) / "view.html" if out is None else Path(out)
    if path.suffix.lower() not in (".html", ".htm"):
        raise SpecholoError(f"page must be an .html file, got {path.name!r}")
    if not path.parent.is_dir():
        raise SpecholoError(f"folder {path.parent} does not exist")
    if size is not None and not all(0 < v <= 8192 for v in size):
        raise SpecholoError(f"canvas size must be in [1, 8192] pixels, got {size}")
    text = build_page(loaded.grooves, loaded.config.setup(),
                      f"specholo: {Path(folder).resolve().name}", size)
    with atomic_open(path) as fh:
        fh.write(text)
    return path
