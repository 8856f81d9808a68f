"""SVG drawing of the grooves, in mm, for inspection, plotters and laser engravers.

The drawing shows the plate as the viewer sees it (from +z): SVG's y axis points
down, so a plate point (x, y) is drawn at (x, -y). One ``<path>`` per groove
strokes it with the groove's width; arcs are SVG elliptical arcs with equal
radii, so they are exact. Flipping y mirrors the turning sense: an arc turning
counter-clockwise on the plate (bulge > 0) turns towards negative angles in SVG
coordinates, which is sweep-flag 0. Dots are filled circles as wide as a groove.

Like the G-code writer, rows of text are built as byte tables (one row per
vertex) so no Python code runs per element.
"""

from __future__ import annotations

import os

import numpy as np

from specholo.fabrication.atomic import atomic_open
from specholo.fabrication.gcode import (
    TextRows,
    check_grooves,
    format_number,
    is_straight,
)
from specholo.setup import Tool
from specholo.toolpaths.grooves import Grooves, Segments

_CHUNK_ROWS = 1 << 16
# a drawing needs less than the G-code: 0.1 um
_DECIMALS = 4
_SCALE = 10**_DECIMALS
_RADIUS_DECIMALS = 8
_RADIUS_SCALE = 10**_RADIUS_DECIMALS
_INKSCAPE = "http://www.inkscape.org/namespaces/inkscape"


def arc_bounds(segments: Segments) -> np.ndarray:
    """Bounding box of arcs, counting where they bulge past their end points.

    Args:
        segments: k arcs.

    Returns:
        (2, 2) lower-left and upper-right corners in mm (zeros if k = 0).
    """
    if len(segments) == 0:
        return np.zeros((2, 2))
    pts = [segments.start, segments.end]
    arcs = ~is_straight(segments)
    if arcs.any():
        sub = Segments(segments.start[arcs], segments.end[arcs], segments.bulge[arcs],
                       segments.path[arcs])
        centre, radius, start, sweep = sub.geometry()
        lo = np.minimum(start, start + sweep)
        span = np.abs(sweep)
        for k in range(4):
            # the circle's extreme point in direction k * 90 degrees, where the arc passes it
            phi = k * 0.5 * np.pi
            inside = np.mod(phi - lo, 2.0 * np.pi) <= span
            d = np.array([np.cos(phi), np.sin(phi)])
            pts.append((centre + radius[:, None] * d)[inside])
    allpts = np.concatenate(pts)
    return np.stack([allpts.min(axis=0), allpts.max(axis=0)])


def write_svg(path: str | os.PathLike[str], grooves: Grooves, tool: Tool,
              margin: float = 5.0) -> None:
    """Write the grooves as an SVG drawing in mm, atomically.

    Args:
        path: destination ``.svg`` file.
        grooves: m vertices in n paths; dots become filled circles.
        tool: the groove width ``tool.width`` is the stroke width and dot diameter.
        margin: blank border around the grooves, mm.

    Raises:
        SpecholoError: if the grooves hold an empty path or non-finite numbers.
    """
    check_grooves(grooves)
    verts = np.asarray(grooves.vertices, dtype=float).reshape(-1, 2)
    m = len(verts)
    offsets = np.asarray(grooves.offsets, dtype=np.int64)
    sizes = np.diff(offsets)
    width = tool.width

    segs = grooves.segments()
    dots, _ = grooves.dots()
    extent = np.concatenate([dots] + ([arc_bounds(segs)] if len(segs) else []))
    if len(extent) == 0:
        extent = np.zeros((1, 2))
    box = np.stack([extent.min(axis=0), extent.max(axis=0)])
    pad = margin + 0.5 * width
    x0, x1 = box[0, 0] - pad, box[1, 0] + pad
    y0, y1 = -box[1, 1] - pad, -box[0, 1] + pad  # SVG y = -plate y
    w, h = x1 - x0, y1 - y0

    last = np.zeros(m, dtype=bool)
    last[offsets[1:] - 1] = True
    dot = np.repeat(sizes == 1, sizes)

    straight = is_straight(segs)
    arc_start = np.flatnonzero(~last)
    rows = arc_start + 1  # each arc is drawn on its end vertex's row
    kind = np.where(dot, 1, 0)  # 0 path start, 1 dot, 2 arc, 3 line
    kind[rows] = np.where(straight, 3, 2)
    arc = kind == 2
    qx = np.rint(verts[:, 0] * _SCALE).astype(np.int64)
    qy = np.rint(-verts[:, 1] * _SCALE).astype(np.int64)
    # An SVG arc is placed by its radius, and near a half circle its centre moves
    # by sqrt(2 r dr) for a radius error dr: take the radius that keeps the sweep
    # over the *rounded* chord, and write it finer than the coordinates.
    bent = rows[~straight]
    b = np.abs(segs.bulge[~straight])
    chord = np.hypot(qx[bent] - qx[bent - 1], qy[bent] - qy[bent - 1]) / _SCALE
    q_radius = np.zeros(m, dtype=np.int64)
    q_radius[bent] = np.rint(chord * (1.0 + b * b) / (4.0 * b) * _RADIUS_SCALE).astype(np.int64)
    large = np.zeros(m, dtype=np.int64)
    large[rows] = np.abs(segs.bulge) > 1.0  # sweeps over 180 degrees
    sweep = np.zeros(m, dtype=np.int64)
    sweep[rows] = segs.bulge < 0  # y flipped: counter-clockwise on the plate is flag 0

    def num(value: float) -> str:
        return format_number(value, _DECIMALS)

    head = (
        '<?xml version="1.0" encoding="UTF-8" standalone="no"?>\n'
        f'<svg xmlns="http://www.w3.org/2000/svg" xmlns:inkscape="{_INKSCAPE}" version="1.1"\n'
        f'     width="{num(w)}mm" height="{num(h)}mm"\n'
        f'     viewBox="{num(x0)} {num(y0)} '
        f'{num(w)} {num(h)}">\n'
        "<!-- specholo grooves; units mm; origin at the plate centre; "
        "plate y up = SVG -y -->\n"
        '<g id="grooves" inkscape:groupmode="layer" inkscape:label="grooves" fill="none"'
        f' stroke="#000000" stroke-width="{num(width)}" stroke-linecap="round"'
        ' stroke-linejoin="round">\n'
    )
    dot_end = f'" r="{num(0.5 * width)}" fill="#000000" stroke="none"/>\n'
    with atomic_open(path, "wb") as fh:
        fh.write(head.encode("ascii"))
        for lo in range(0, m, _CHUNK_ROWS):
            s = slice(lo, min(lo + _CHUNK_ROWS, m))
            t = TextRows(s.stop - s.start)
            t.choice(['<path d="M ', '<circle cx="', " A ", " L "], kind[s])
            a = arc[s]
            t.number(q_radius[s], _RADIUS_DECIMALS, a)
            t.text(" ", a)
            t.number(q_radius[s], _RADIUS_DECIMALS, a)
            t.text(" 0 ", a)
            t.choice(["", "0", "1"], np.where(a, 1 + large[s], 0))
            t.text(" ", a)
            t.choice(["", "0", "1"], np.where(a, 1 + sweep[s], 0))
            t.text(" ", a)
            t.number(qx[s], _DECIMALS)
            t.choice([" ", '" cy="'], dot[s].astype(np.int64))
            t.number(qy[s], _DECIMALS)
            t.choice(["", '"/>\n', dot_end], np.where(dot[s], 2, last[s].astype(np.int64)))
            fh.write(t.tobytes())
        fh.write(b"</g>\n</svg>\n")
