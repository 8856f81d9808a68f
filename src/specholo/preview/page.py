"""An interactive, self-contained web page of a design's glints (WebGL2).

The page recomputes every glint on the GPU for the current eye and light with
the physics of :func:`~specholo.simulation.glints.find_glints`: one vertex per
groove arc solves h(g) . t = 0 on the groove wall by regula falsi in the arc's
own parameter and emits a point sprite where the glint projects, exactly as
:class:`~specholo.preview.render.Camera` would project it. Dragging moves the
viewpoint (shift+drag moves the light's elevation).

Most arcs turn by a few milliradians. These *narrow* arcs are shipped
quantized, 12 bytes each (see :class:`PageArcs`), sorted by plate cell and
tangent angle. Every frame the page's script keeps, per cell, the arcs whose
tangents come near the one a glint there needs (a margin bounds how far that
direction moves within the cell), screens them on h . t at their ends, and
draws the rest - about one arc per glint - with one indexed draw. The few wide
arcs, the arcs at corners, the corners and the dimples are shipped in float32
in the plate frame and always drawn. The arrays are gzipped and base64 encoded
into the page, which inflates them before its first frame.

A software rasterizer (SwiftShader, llvmpipe: WebGL without a GPU) spends about
a microsecond on every point it draws, far more than the arithmetic, and more
compositing a WebGL canvas than a 2D one. There the page's workers (one per core,
each on every other row of cells) cull and solve the arcs with the shader's steps
in float64 and add up the sprites' spots from a table of lone sprites the GPU drew
once; the page draws plate and sums on a 2D canvas, while the workers go on to
the next frame. ``?splat=0`` or ``?splat=1`` in the page's URL forces either way,
``?workers=N`` sets the number of workers (0: none, the page's own thread).

A plate given as a height field (a ridged design) has no arcs: its page holds
the glints one eye sees from a grid of views, found beforehand with the
physics of ``verify`` (:class:`FieldViews`), and ``page_field.js`` draws the
view nearest the pointer's on a 2D canvas.
"""

from __future__ import annotations

import base64
import gzip
import html
import json
import math
import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from specholo.errors import SpecholoError
from specholo.setup import Setup
from specholo.toolpaths.grooves import Grooves, Segments

#: Turn value marking an arc with no corner after it; any |turn| <= pi is real.
NO_CORNER = 100.0
#: Drag sensitivity, degrees per CSS pixel.
DEGREES_PER_PIXEL = 0.2
#: Largest |azimuth| and |elevation| the page lets the eye reach, degrees.
AZIMUTH_LIMIT = 80.0
ELEVATION_LIMIT = 60.0
#: Junctions turning less than this (radians) are smooth: both arcs get the same
#: quantized tangent there. Above it they are corners, shipped with their arcs in float32.
JOIN_TURN = 1e-5
#: Half-turn (radians) above which an arc is always drawn, as ArcIndex.WIDE.
WIDE = 0.01
#: Tangent angles mod pi are stored in steps of pi / ANGLE_STEPS (uint16).
ANGLE_STEPS = 65536
ANGLE_STEP = math.pi / ANGLE_STEPS
#: Side of the square plate cells the page culls narrow arcs by, mm.
CELL = 1.0
#: Regula falsi steps per bracketed narrow arc: h . t is nearly linear along a
#: narrow arc, so one secant step lands within ~0.01 um and two within 1 nm.
ITERATIONS = 2
#: Regula falsi steps for the wide arcs and the arcs at corners (as in find_glints).
WIDE_ITERATIONS = 12
#: Width and height the default field of view is fitted for (any canvas keeps that fov).
FRAME_SIZE = (800, 600)
#: Extra reach (mm) per cell, for float32 rounding in the page.
REACH_SLACK = 1e-3
#: gzip level of the embedded arrays (higher levels gain ~3% for twice the time).
GZIP_LEVEL = 4

_JS_PATH = Path(__file__).with_name("page.js")
#: Spacing of the precomputed views of a height-field page, degrees.
FIELD_VIEW_STEP = 2.0
#: Most views a height-field page precomputes.
MAX_FIELD_VIEWS = 20_000
_FIELD_JS_PATH = Path(__file__).with_name("page_field.js")


def _wrap_half(a: np.ndarray) -> np.ndarray:
    """Angles folded to [-pi/2, pi/2)."""
    return (a + 0.5 * math.pi) % math.pi - 0.5 * math.pi


def _wrap_turn(a: np.ndarray) -> np.ndarray:
    """Angles folded to [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def quantize_angle(a: np.ndarray) -> np.ndarray:
    """Directions mod pi as whole angle steps.

    Args:
        a: (k,) angles in radians, any branch.

    Returns:
        (k,) int32 nearest multiples of :data:`ANGLE_STEP` to a mod pi, in
        [0, ANGLE_STEPS).
    """
    q = np.mod(a, math.pi)
    q *= 1.0 / ANGLE_STEP
    np.rint(q, out=q)
    out = q.astype(np.int32)
    out[out >= ANGLE_STEPS] -= ANGLE_STEPS
    return out


#: Arcs processed at once while building the page (bounds the temporaries).
_CHUNK = 1 << 20


@dataclass(frozen=True)
class _Columns:
    """Geometry of consecutive arcs as (k,) float64 columns, tangents snapped
    at smooth junctions.

    Attributes:
        xs, ys, xe, ye: start and end points, mm.
        theta: start tangent angle (of the arc's own direction), radians.
        arc_len: arc length, mm.
        sweep: signed turn from the start to the end tangent (snapped), radians.
        raw_sweep: the arc's own signed sweep, radians.
        turn: turn to the next arc's start at a corner, else NO_CORNER.
        q_start, q_end: int32 quantized tangent angles mod pi at the ends
            (:func:`quantize_angle`), equal on both sides of a smooth junction.
        at_corner: True where a corner precedes or follows the arc.
    """

    xs: np.ndarray
    ys: np.ndarray
    xe: np.ndarray
    ye: np.ndarray
    theta: np.ndarray
    arc_len: np.ndarray
    sweep: np.ndarray
    raw_sweep: np.ndarray
    turn: np.ndarray
    q_start: np.ndarray
    q_end: np.ndarray
    at_corner: np.ndarray

    @classmethod
    def of(cls, xs: np.ndarray, ys: np.ndarray, xe: np.ndarray, ye: np.ndarray,
           bulge: np.ndarray, same: np.ndarray) -> _Columns:
        """Columns of k consecutive arcs.

        Args:
            xs, ys, xe, ye: (k,) start and end points, mm.
            bulge: (k,) bulges.
            same: (k - 1,) True where arc i + 1 continues arc i's path.
        """
        k = len(xs)
        cx, cy = xe - xs, ye - ys
        sweep = 4.0 * np.arctan(bulge)
        half = 0.5 * sweep
        # Arc length from the chord: sin(x)/x by its series where small (exact
        # to 1e-15 there), else directly.
        h2 = half * half
        sinc = 1.0 - h2 / 6.0 * (1.0 - h2 / 20.0)
        big = np.flatnonzero(np.abs(half) > 0.01)
        sinc[big] = np.sin(half[big]) / half[big]
        arc_len = np.sqrt(cx * cx + cy * cy) / sinc
        theta0 = np.arctan2(cy, cx) - half
        theta1 = theta0 + sweep
        smooth = np.zeros(k, dtype=bool)
        corner = np.zeros(k, dtype=bool)
        turn = np.full(k, NO_CORNER)
        if k > 1:
            d = _wrap_turn(theta0[1:] - theta1[:-1])
            smooth[:-1] = same & (np.abs(d) <= JOIN_TURN)
            corner[:-1] = same & ~smooth[:-1]
            turn[:-1][corner[:-1]] = d[corner[:-1]]
        q_start = quantize_angle(theta0)
        q_end = quantize_angle(theta1)
        q_end[:-1][smooth[:-1]] = q_start[1:][smooth[:-1]]
        # The float rows take the shared quantized tangent at smooth junctions
        # too, so they meet their narrow neighbours' tangents (to float32 rounding).
        i = np.flatnonzero(smooth)
        theta1[i] += _wrap_half(q_end[i] * ANGLE_STEP - theta1[i])
        theta0[i + 1] += _wrap_half(q_start[i + 1] * ANGLE_STEP - theta0[i + 1])
        at_corner = corner.copy()
        at_corner[1:] |= corner[:-1]
        return cls(xs, ys, xe, ye, theta0, arc_len, theta1 - theta0, sweep, turn,
                   q_start, q_end, at_corner)

    @classmethod
    def of_segments(cls, seg: Segments) -> _Columns:
        """Columns of all arcs of :meth:`Grooves.segments`."""
        f = np.ascontiguousarray
        return cls.of(f(seg.start[:, 0], dtype=float), f(seg.start[:, 1], dtype=float),
                      f(seg.end[:, 0], dtype=float), f(seg.end[:, 1], dtype=float),
                      f(seg.bulge, dtype=float), seg.path[1:] == seg.path[:-1])

    def rows(self, idx: np.ndarray | slice = slice(None)) -> np.ndarray:
        """float32 rows (m, 6) as :func:`arc_table` of arcs idx."""
        cols = (self.xs, self.ys, self.theta, self.arc_len, self.sweep, self.turn)
        out = np.empty((len(self.xs[idx]), 6), dtype=np.float32)
        for j, c in enumerate(cols):
            out[:, j] = c[idx]
        return out


def arc_table(grooves: Grooves) -> tuple[np.ndarray, np.ndarray]:
    """The grooves as the page's float32 vertex data (used for the always-drawn arcs).

    Args:
        grooves: the grooves.

    Returns:
        arcs (k, 6) float32 rows (start x, start y, start tangent angle, length,
        signed sweep, turn to the next arc's start tangent or :data:`NO_CORNER`),
        and dimples (q, 2) float32 positions, all in mm and radians. At smooth
        junctions (turn <= :data:`JOIN_TURN`) both arcs take the quantized
        tangent of :class:`PageArcs`.
    """
    dots, _ = grooves.dots()
    return (_Columns.of_segments(grooves.segments()).rows(),
            np.asarray(dots, dtype=np.float32).reshape(-1, 2))


@dataclass(frozen=True)
class PageArcs:
    """The grooves as the page draws them.

    Narrow arcs (half-turn <= :data:`WIDE`, not at a corner) are quantized rows
    ``x0, y0, x1, y1, q0, q1`` (uint16): the end points in units of ``scale``
    from ``origin``, and the tangent angles mod pi there in steps of
    :data:`ANGLE_STEP`. Each is oriented so its tangent turns counter-clockwise,
    by ``(q1 - q0) mod 2**16`` steps; the chord tells which of the two directions
    a tangent angle mod pi is. Arcs that share a junction store the same point
    and the same tangent step there, so the page evaluates the same glint
    condition on both sides of it. The rows are sorted by plate cell (squares of
    side :data:`CELL`, by chord midpoint), then by q0.

    Attributes:
        table: (k, 6) uint16 narrow arcs.
        arc: (k,) index of each row in ``grooves.segments()``.
        origin: (2,) plate point of table coordinates (0, 0), mm.
        scale: mm per coordinate unit.
        shape: (nx, ny) cells; cell ``iy * nx + ix`` has its lower-left corner
            at ``origin + CELL * (ix, iy)``.
        cell_start: (nx * ny + 1,) first row of each cell.
        cell_reach: (nx * ny,) how far (mm) from its cell's centre the points
            of the cell's arcs lie.
        cell_sweep: (nx * ny,) largest tangent turn of the cell's arcs, radians.
        wide: (w, 6) float32 rows (as :func:`arc_table`) of the arcs always drawn.
        wide_arc: (w,) their indices in ``grooves.segments()``.
        corners: (c, 6) float32 rows of the arcs a corner follows.
        dots: (q, 2) float32 dimples, mm.
    """

    table: np.ndarray
    arc: np.ndarray
    origin: np.ndarray
    scale: float
    shape: tuple[int, int]
    cell_start: np.ndarray
    cell_reach: np.ndarray
    cell_sweep: np.ndarray
    wide: np.ndarray
    wide_arc: np.ndarray
    corners: np.ndarray
    dots: np.ndarray

    @classmethod
    def build(cls, grooves: Grooves) -> PageArcs:
        """Split, quantize and sort the arcs of grooves.

        Args:
            grooves: the grooves; arcs are numbered as in ``grooves.segments()``.

        Returns:
            The page's arcs.
        """
        v = np.asarray(grooves.vertices, dtype=float)
        vx, vy = np.ascontiguousarray(v[:, 0]), np.ascontiguousarray(v[:, 1])
        bulges = np.asarray(grooves.bulges, dtype=float)
        # Arc i runs from vertex first[i] to the next one, as in Grooves.segments.
        last = np.zeros(len(v), dtype=bool)
        last[grooves.offsets[1:] - 1] = True
        first = np.flatnonzero(~last)
        k = len(first)
        if k:
            used = np.zeros(len(v), dtype=bool)
            used[first] = True
            used[first + 1] = True
            origin = np.array([vx[used].min(), vy[used].min()])
            extent = max(vx[used].max() - origin[0], vy[used].max() - origin[1])
        else:
            origin, extent = np.zeros(2), 0.0
        scale = max(float(extent), 1e-6) / 65535.0
        parts = []
        for i in range(0, k, _CHUNK):
            j = min(i + _CHUNK, k)
            # One arc more on each side, for the junctions at the chunk's ends.
            a, b = max(i - 1, 0), min(j + 1, k)
            f = first[a:b]
            c = _Columns.of(vx[f], vy[f], vx[f + 1], vy[f + 1], bulges[f], np.diff(f) == 1)
            parts.append(_quantize(c, slice(i - a, j - a), origin, scale, i))
        if not parts:
            e = np.zeros(0)
            parts.append(_quantize(_Columns.of(e, e, e, e, e, np.zeros(0, dtype=bool)),
                                   slice(0, 0), origin, scale, 0))
        col = {name: np.concatenate([p[name] for p in parts]) for name in parts[0]}
        del parts

        ix, iy = col.pop("ix"), col.pop("iy")
        nx = int(ix.max()) + 1 if len(ix) else 1
        ny = int(iy.max()) + 1 if len(iy) else 1
        cell = iy.astype(np.int64) * nx + ix
        del ix, iy
        order = _sort_by_cell(cell, col["q0"], nx * ny)
        cell = cell[order]
        counts = np.bincount(cell, minlength=nx * ny)
        cell_start = np.concatenate([[0], np.cumsum(counts)])
        full = np.flatnonzero(counts)
        cell_reach = np.zeros(nx * ny)
        cell_sweep = np.zeros(nx * ny)
        if len(full):
            cell_reach[full] = np.maximum.reduceat(col["reach"][order], cell_start[full])
            cell_reach[full] += REACH_SLACK
            cell_sweep[full] = np.maximum.reduceat(col["dq"][order], cell_start[full])
            cell_sweep[full] *= ANGLE_STEP
        table = np.empty((len(order), 6), dtype=np.uint16)
        for j, name in enumerate(("x0", "y0", "x1", "y1", "q0", "q1")):
            table[:, j] = col[name][order]
        wide = col["wide"].reshape(-1, 6)
        dots, _ = grooves.dots()
        return cls(table, col["arc"][order], origin, scale, (nx, ny),
                   cell_start.astype(np.uint32), cell_reach, cell_sweep, wide,
                   col["wide_arc"], wide[np.abs(wide[:, 5]) < NO_CORNER],
                   np.asarray(dots, dtype=np.float32).reshape(-1, 2))

    def blocks(self) -> dict[str, bytes]:
        """The arrays as the page embeds them, before gzip.

        The narrow table goes column by column, as differences where those are
        small (x1 - x0, y1 - y0, q1 - q0, and q0 minus the previous row's q0,
        all mod 2**16), each column's low bytes before its high bytes: that
        gzips to about half the size of the plain rows.

        Returns:
            Name -> little-endian bytes: x0, y0, dx, dy, q0, dq (2 k bytes
            each), cellStart (uint32), cells (float32 reach and sweep per
            cell), wide, corners (float32 rows of 6) and dots (float32 pairs).
        """
        t = self.table
        prev = np.concatenate([np.zeros(1, dtype=np.uint16), t[:-1, 4]])
        # uint16 differences wrap mod 2**16.
        columns = {"x0": t[:, 0], "y0": t[:, 1], "dx": t[:, 2] - t[:, 0],
                   "dy": t[:, 3] - t[:, 1], "q0": t[:, 4] - prev, "dq": t[:, 5] - t[:, 4]}
        out = {name: _byte_planes(v) for name, v in columns.items()}
        out["cellStart"] = self.cell_start.astype("<u4").tobytes()
        cells = np.stack([self.cell_reach, self.cell_sweep], axis=1)
        out["cells"] = cells.astype("<f4").tobytes()
        out["wide"] = self.wide.astype("<f4").tobytes()
        out["corners"] = self.corners.astype("<f4").tobytes()
        out["dots"] = self.dots.astype("<f4").tobytes()
        return out


def _quantize(c: _Columns, keep: slice, origin: np.ndarray, scale: float,
              base: int) -> dict[str, np.ndarray]:
    """The narrow rows and the float rows of arcs ``keep`` of c (numbered from base).

    Returns:
        arc (m,) indices, x0, y0, x1, y1, q0, q1 (m,) uint16, dq (m,) int32,
        ix, iy (m,) cells and reach (m,) mm (see :class:`PageArcs`) of the
        narrow arcs; wide (6 w,) float32 rows and wide_arc (w,) of the others.
    """
    xs, ys, xe, ye = c.xs[keep], c.ys[keep], c.xe[keep], c.ye[keep]
    q_start, q_end = c.q_start[keep], c.q_end[keep]
    # Orient each arc so its tangent turns counter-clockwise: q1 = q0 + dq.
    dq = q_end - q_start
    dq += ANGLE_STEPS // 2
    dq &= ANGLE_STEPS - 1
    dq -= ANGLE_STEPS // 2
    rev = dq < 0
    q0 = np.where(rev, q_end, q_start)
    dq = np.abs(dq)
    ok = (np.abs(c.raw_sweep[keep]) <= 2.0 * WIDE) & ~c.at_corner[keep]

    def grid(start: np.ndarray, o: float) -> np.ndarray:
        g = (start - o) * (1.0 / scale)
        np.rint(g, out=g)
        np.clip(g, 0, 65535, out=g)
        return g.astype(np.int32)

    x0, x1 = grid(np.where(rev, xe, xs), origin[0]), grid(np.where(rev, xs, xe), origin[0])
    y0, y1 = grid(np.where(rev, ye, ys), origin[1]), grid(np.where(rev, ys, ye), origin[1])
    # The page takes the start direction (q0 or q0 + pi) the chord points
    # along; only arcs where that is their real direction stay narrow.
    chx = (x1 - x0) * scale
    chy = (y1 - y0) * scale
    mid_angle = (q0 + 0.5 * dq) * ANGLE_STEP
    forward = chx * np.cos(mid_angle) + chy * np.sin(mid_angle) >= 0
    theta = c.theta[keep] + np.where(rev, c.sweep[keep] + math.pi, 0.0)
    ok &= forward == (np.cos(theta - q0 * ANGLE_STEP) > 0)
    ok &= (chx != 0) | (chy != 0)
    sel = np.flatnonzero(ok)
    # Cells by chord midpoint. A minor arc lies within the circle on its chord
    # (Thales): every point of it is within half the chord of the chord's midpoint.
    mx = 0.5 * (x0[sel] + x1[sel]) * scale
    my = 0.5 * (y0[sel] + y1[sel]) * scale
    ix = np.floor(mx / CELL).astype(np.int32)
    iy = np.floor(my / CELL).astype(np.int32)
    ex = mx - (ix + 0.5) * CELL
    ey = my - (iy + 0.5) * CELL
    chx, chy = chx[sel], chy[sel]
    reach = np.sqrt(ex * ex + ey * ey) + 0.5 * np.sqrt(chx * chx + chy * chy)
    dq = dq[sel]
    q0 = q0[sel]
    other = np.flatnonzero(~ok)
    rows = c.rows(np.arange(keep.start, keep.stop)[other])
    u16 = np.uint16
    return {"arc": sel + base, "x0": x0[sel].astype(u16), "y0": y0[sel].astype(u16),
            "x1": x1[sel].astype(u16), "y1": y1[sel].astype(u16), "q0": q0.astype(u16),
            "q1": ((q0 + dq) & (ANGLE_STEPS - 1)).astype(u16), "dq": dq, "ix": ix, "iy": iy,
            "reach": reach, "wide": rows.ravel(), "wide_arc": other + base}


def _sort_by_cell(cell: np.ndarray, q0: np.ndarray, cells: int) -> np.ndarray:
    """Order (k,) sorting rows by cell, then q0 (uint16)."""
    if cells <= 65536:
        # Two stable 16-bit sorts (radix sorts in numpy): much faster than one on int64.
        o = np.argsort(q0, kind="stable")
        return o[np.argsort(cell[o].astype(np.uint16), kind="stable")]
    return np.argsort(cell * ANGLE_STEPS + q0)


def _byte_planes(v: np.ndarray) -> bytes:
    """uint16 values as all low bytes, then all high bytes."""
    b = np.ascontiguousarray(v, dtype="<u2").view(np.uint8).reshape(-1, 2)
    return b[:, 0].tobytes() + b[:, 1].tobytes()


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
        "wideIterations": WIDE_ITERATIONS,
        "noCorner": NO_CORNER,
        "viewRange": math.degrees(setup.viewer.half_range),
    }


def pack_blocks(blocks: dict[str, bytes],
                level: int = GZIP_LEVEL) -> tuple[str, list[dict[str, Any]]]:
    """Gzip each block and base64 the lot.

    Args:
        blocks: name -> bytes.
        level: gzip compression level.

    Returns:
        The base64 text, and per block its name, offset and length (bytes) in
        the decoded text.
    """
    names = list(blocks)
    # zlib releases the GIL: the blocks compress in parallel.
    with ThreadPoolExecutor(max_workers=min(len(names), os.cpu_count() or 1) or 1) as pool:
        packed = list(pool.map(lambda n: gzip.compress(blocks[n], level, mtime=0), names))
    index, offset = [], 0
    for name, data in zip(names, packed, strict=True):
        index.append({"name": name, "offset": offset, "length": len(data)})
        offset += len(data)
    return base64.b64encode(b"".join(packed)).decode("ascii"), index


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
    arcs = PageArcs.build(grooves)
    data, index = pack_blocks(arcs.blocks())
    meta = page_meta(setup, grooves, title)
    meta["counts"] = {"arcs": len(arcs.table) + len(arcs.wide), "narrow": len(arcs.table),
                      "wide": len(arcs.wide), "corners": len(arcs.corners),
                      "dots": len(arcs.dots)}
    meta["grid"] = {"origin": arcs.origin.tolist(), "scale": arcs.scale, "cell": CELL,
                    "nx": arcs.shape[0], "ny": arcs.shape[1], "angleSteps": ANGLE_STEPS}
    meta["blocks"] = index
    meta["size"] = list(size) if size is not None else None
    return _html(title, meta, data, _JS_PATH.read_text(encoding="utf-8"),
                 "drag: move the eye &middot; shift+drag: move the light")


def _html(title: str, meta: dict[str, Any], data: str, script: str, help_html: str) -> str:
    """The page: a bar of angles and help, the canvas, the metadata and the data
    inline, then the script."""
    # "<" escaped so the JSON cannot close its script element.
    meta_json = json.dumps(meta).replace("<", "\\u003c")
    return (
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n"
        "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
        f"<title>{html.escape(title)}</title>\n<style>{_CSS}</style></head>\n<body>\n"
        "<div id=\"hud\"><span id=\"angles\">loading...</span>"
        f"<span id=\"help\">{help_html}</span></div>\n"
        "<canvas id=\"view\"></canvas>\n<div id=\"message\" hidden></div>\n"
        f"<script type=\"application/json\" id=\"meta\">{meta_json}</script>\n"
        f"<script type=\"text/plain\" id=\"data\">{data}</script>\n"
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


# ---------------------------------------------------------------------------
# Glints precomputed per view: height fields (ridged designs), and any kind's
# glints along its motion (a turning plate, a moving light, a curved host)


@dataclass(frozen=True)
class FieldViews:
    """The glints one eye sees for a grid of views: on a height field, or any
    kind's along its motion (:meth:`collect`).

    The eye of view (i, j, k) is where a :class:`~specholo.preview.render.Camera`
    at azimuth ``azimuths[i]`` and elevation ``elevations[j]`` sits at
    ``distance`` from (0, eye height, 0), the motion at ``states[k]``; views are
    numbered ``(i * len(elevations) + j) * max(len(states), 1) + k``. Glint
    positions are quantized to uint16 steps of ``scale`` from ``origin``.

    Attributes:
        azimuths, elevations: (na,), (ne,) view angles, degrees.
        states: (ns,) the motion's states, degrees; empty where the glints take
            none (the motion is the eye's own azimuth).
        start: (na * ne * max(ns, 1) + 1,) first glint of each view.
        points: (g, 3) glint positions, mm (as found).
        table: (g, 3) uint16 quantized positions.
        origin: (3,) position of table value 0, mm.
        scale: (3,) mm per table step.
    """

    azimuths: np.ndarray
    elevations: np.ndarray
    start: np.ndarray
    points: np.ndarray
    table: np.ndarray
    origin: np.ndarray
    scale: np.ndarray
    states: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @classmethod
    def build(cls, field: Any, setup: Setup, azimuths: np.ndarray, elevations: np.ndarray,
              distance: float | None = None, progress: Any = None) -> FieldViews:
        """Find the glints of every view of a height field.

        Args:
            field: the labelled plate (``HeightMap``).
            setup: the design's setup (light, viewer).
            azimuths, elevations: view angles, degrees.
            distance: the eye's distance from (0, eye height, 0), mm; default the
                design's eyes' (``setup.viewer.eye_radius``).
            progress: called with (views done, views) after each view, or None.
        """
        from specholo.preview.render import field_plate
        from specholo.simulation.heightfield import SlopeIndex, find_field_glints

        index = SlopeIndex.build(field)
        plate = field_plate(field)
        # x, y over the plate, z over the shell
        lo = np.array([plate[0, 0], plate[0, 1], -2.0 * max(float(-np.min(field.z)), 1e-6)])
        hi = np.array([plate[1, 0], plate[1, 1], 0.0])
        return cls.collect(
            lambda eye, state: find_field_glints(index, eye, setup.light).glints.point,
            setup, azimuths, elevations, (), distance, progress, np.stack([lo, hi]))

    @classmethod
    def collect(cls, glints: Callable[[np.ndarray, float | None], np.ndarray], setup: Setup,
                azimuths: Any, elevations: Any, states: Any = (),
                distance: float | None = None, progress: Any = None,
                box: np.ndarray | None = None) -> FieldViews:
        """Find the glints of every view with a kind's own finder.

        Args:
            glints: the glint points (m, 3) an eye (3,) sees with the motion at a
                state (radians; None where ``states`` is empty).
            setup: the viewer (its eyes' circle and height).
            azimuths, elevations: view angles, degrees.
            states: the motion's states, degrees (empty: none).
            distance: the eye's distance from (0, eye height, 0), mm; default the
                design's eyes' (``setup.viewer.eye_radius``).
            progress: called with (views done, views) after each view, or None.
            box: (2, 3) the corners the quantization spans, mm; default the
                glints' own extent.
        """
        from specholo.preview.render import Camera

        az = np.asarray(azimuths, dtype=float).reshape(-1)
        el = np.asarray(elevations, dtype=float).reshape(-1)
        st = np.asarray(states, dtype=float).reshape(-1)
        d = setup.viewer.eye_radius if distance is None else float(distance)
        found = []
        each: list[float | None] = [math.radians(s) for s in st] if len(st) else [None]
        total = len(az) * len(el) * len(each)
        for a in az:
            for e in el:
                eye = Camera(math.radians(a), math.radians(e), d, 1.0, 2, 2,
                             setup.viewer.height).position()
                for s in each:
                    found.append(np.asarray(glints(eye, s), dtype=float).reshape(-1, 3))
                    if progress is not None:
                        progress(len(found), total)
        counts = np.array([len(f) for f in found], dtype=np.int64)
        start = np.concatenate([[0], np.cumsum(counts)]).astype(np.uint32)
        points = np.concatenate(found) if found else np.zeros((0, 3))
        if box is None:
            lo = points.min(axis=0) if len(points) else np.zeros(3)
            hi = points.max(axis=0) if len(points) else np.zeros(3)
        else:
            lo, hi = np.asarray(box, dtype=float)
        # a flat extent (glints all at z = 0) still needs a step
        scale = np.maximum(hi - lo, 1e-6) / 65535.0
        q = np.rint((points - lo) / scale) if len(points) else np.zeros((0, 3))
        table = np.clip(q, 0, 65535).astype(np.uint16)
        return cls(az, el, start, points, table, lo, scale, st)

    def view(self, i: int, j: int, k: int = 0) -> np.ndarray:
        """The glints (g, 3) as found of view (azimuth i, elevation j, state k), mm."""
        n = (i * len(self.elevations) + j) * max(len(self.states), 1) + k
        return self.points[int(self.start[n]):int(self.start[n + 1])]

    def decoded(self) -> np.ndarray:
        """(g, 3) positions as the page has them, mm."""
        return self.origin + self.table.astype(float) * self.scale

    def blocks(self) -> dict[str, bytes]:
        """The arrays as the page embeds them, before gzip: ``start`` (uint32) and
        ``x``, ``y``, ``z`` (uint16, low bytes then high bytes)."""
        out = {"start": self.start.astype("<u4").tobytes()}
        for k, name in enumerate(("x", "y", "z")):
            out[name] = _byte_planes(self.table[:, k])
        return out


def field_page_views(setup: Setup, elevation_range: float,
                     step: float = FIELD_VIEW_STEP) -> tuple[np.ndarray, np.ndarray]:
    """The views (degrees) a height-field page precomputes: the design's azimuth
    and elevation ranges, at most ``step`` apart.

    Args:
        setup: the design's setup (its viewer's azimuth range).
        elevation_range: the design's elevation range, degrees.
        step: largest spacing, degrees.
    """
    from specholo.simulation.verify import view_azimuths

    check_view_step(step)
    az = np.degrees(view_azimuths(setup.viewer.half_range, math.radians(step)))
    el = np.degrees(view_azimuths(math.radians(elevation_range), math.radians(step)))
    check_view_count(len(az) * len(el))
    return az, el


def check_view_step(step: float) -> None:
    """Refuse a spacing of a page's views outside [0.1, 10] degrees."""
    if not (math.isfinite(step) and 0.1 <= step <= 10.0):
        raise SpecholoError(f"view step must be in [0.1, 10] degrees, got {step:g}")


def check_view_count(views: int) -> None:
    """Refuse more views than a page holds (:data:`MAX_FIELD_VIEWS`)."""
    if views > MAX_FIELD_VIEWS:
        raise SpecholoError(f"{views} views are too many (at most "
                            f"{MAX_FIELD_VIEWS}): use a larger step")


def build_field_page(views: FieldViews, field: Any, setup: Setup, title: str = "specholo",
                     size: tuple[int, int] | None = None) -> str:
    """The page of a plate given as a height field, as one HTML string
    (:func:`build_views_page` with the field's plate).

    Args:
        views: the precomputed views.
        field: the plate (``HeightMap``), for its outline.
        setup: the design's setup (light, viewer).
        title: page title.
        size: fixed canvas (width, height) in CSS pixels, or None to fill the window.
    """
    from specholo.preview.render import field_plate

    return build_views_page(views, setup, field_plate(field), title, size)


@dataclass(frozen=True)
class PageMotion:
    """What a page's views move along besides the eye (a plate's turn, a light).

    Attributes:
        name: in words ("plate angle").
        low, high: its range, degrees.
        closed: a whole turn (high wraps onto low).
        start: the state the page opens at, degrees.
    """

    name: str
    low: float
    high: float
    closed: bool
    start: float


def build_views_page(views: FieldViews, setup: Setup, plate: np.ndarray,
                     title: str = "specholo", size: tuple[int, int] | None = None,
                     motion: PageMotion | None = None, shapes: list[Any] | None = None,
                     frame_azimuths: tuple[float, ...] | None = None,
                     start: tuple[float, float] = (0.0, 0.0)) -> str:
    """The page of glints precomputed per view, as one HTML string.

    The page draws the view nearest the pointer's (and, along a motion, the
    state nearest the slider's): the plate in perspective and a spot at each
    glint, with the camera of :class:`~specholo.preview.render.Camera`.

    Args:
        views: the precomputed views.
        setup: the design's setup (light, viewer).
        plate: (2, 2) the corners the default field of view frames, mm; drawn
            as the plate where ``shapes`` is None.
        title: page title.
        size: fixed canvas (width, height) in CSS pixels, or None to fill the window.
        motion: what the views' states are, or None where they have none.
        shapes: per state along a motion, else per azimuth (or one for all),
            what to draw under the glints:
            ``{"plate": [[x, y], ...] or None, "lines": [[[x, y, z], ...], ...]}``
            (mm); None: ``plate`` as the plate.
        frame_azimuths: azimuths (radians) the default field of view frames;
            default the viewer's range.
        start: the azimuth and elevation the page opens at, degrees.
    """
    from specholo.preview.render import plate_camera

    half = setup.viewer.half_range
    frame = (-half, half) if frame_azimuths is None else frame_azimuths
    fov = plate_camera(setup, plate, width=FRAME_SIZE[0], height=FRAME_SIZE[1],
                       frame_azimuths=frame).fov
    data, index = pack_blocks(views.blocks())
    step = float(np.max(np.diff(views.azimuths))) if len(views.azimuths) > 1 else 0.0
    if len(views.elevations) > 1:
        step = max(step, float(np.max(np.diff(views.elevations))))
    meta: dict[str, Any] = {
        "mode": "field",
        "title": title,
        "light": {"elevation": math.degrees(setup.light.elevation),
                  "distance": setup.light.distance},
        "camera": {"distance": setup.viewer.eye_radius, "eyeHeight": setup.viewer.height,
                   "fov": math.degrees(fov)},
        "plate": np.asarray(plate, dtype=float).tolist(),
        "views": {"azimuths": views.azimuths.tolist(), "elevations": views.elevations.tolist(),
                  "step": step},
        "counts": {"views": len(views.start) - 1, "glints": len(views.table)},
        "quant": {"origin": views.origin.tolist(), "scale": views.scale.tolist()},
        "limits": {"azimuth": AZIMUTH_LIMIT, "elevation": ELEVATION_LIMIT,
                   "degreesPerPixel": DEGREES_PER_PIXEL},
        "blocks": index,
        "size": list(size) if size is not None else None,
    }
    help_html = f"drag: move the eye (views every {step:g}&deg;)"
    if start != (0.0, 0.0):
        meta["start"] = {"azimuth": start[0], "elevation": start[1]}
    if shapes is not None:
        meta["shapes"] = shapes
    if motion is not None and len(views.states):
        meta["views"]["states"] = views.states.tolist()
        meta["motion"] = {"name": motion.name, "low": motion.low, "high": motion.high,
                          "closed": motion.closed, "start": motion.start}
        every = float(np.max(np.diff(views.states))) if len(views.states) > 1 else 0.0
        help_html = (f"drag: {html.escape(motion.name)} (every {every:g}&deg;) &middot; "
                     "shift+drag: move the eye")
    return _html(title, meta, data, _FIELD_JS_PATH.read_text(encoding="utf-8"), help_html)
