"""SVG drawing of the grooves, in mm, for inspection, plotters and laser engravers.

The drawing shows the plate as the viewer sees it (from +z): SVG's y axis points
down, so a plate point (x, y) is drawn at (x, -y). One ``<path>`` per groove
strokes it with the groove's width; arcs are SVG elliptical arcs with equal
radii, so they are exact. Flipping y mirrors the turning sense: an arc turning
counter-clockwise on the plate (bulge > 0) turns towards negative angles in SVG
coordinates, which is sweep-flag 0. Dots are filled circles as wide as a groove.

Grooves and dots go in separate layers, one pair per depth class (see
:func:`plan_layers`, shared with the DXF writer): Inkscape layer groups with
``id="layer<N>"`` and the label ``"<N> <NAME>"``. vpype's ``read`` numbers a
layer by the first run of digits in its label, so the label starts with the
layer number (a name like ``GROOVES_D0.080_R0.250`` alone would read as layer
0, i.e. 1, for every layer). Each layer has its own colour, which is also how
laser software such as LightBurn tells layers apart.

The plate (:mod:`~specholo.fabrication.plate`) has a layer of its own, ``PLATE``:
its outline and the registration marks (a crosshair and a circle inside each
corner and at the origin), hairlines in a colour no groove layer has. Its number
is :data:`PLATE_LAYER` unless the depth classes could reach it
(:func:`plate_layer_number`): vpype reads a label's number 0 as layer 1, so the
plate cannot take 0, and a number past every groove and dot layer never takes
one of theirs. The drawing's page holds the whole plate.

Like the G-code writer, it writes a chunk of paths at a time, one row of text
per vertex (:class:`~specholo.fabrication.exporting.TextRows`), so memory does not
grow with the drawing and no Python code runs per element.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from specholo._compiling import kernel
from specholo.errors import SpecholoError
from specholo.fabrication.atomic import atomic_open
from specholo.fabrication.exporting import (
    TextRows,
    check_grooves,
    drawn_extent,
    format_number,
    in_order,
    is_straight,
    path_chunks,
    slice_paths,
)
from specholo.fabrication.plate import Plate
from specholo.setup import Tool
from specholo.toolpaths.grooves import Grooves, Segments

_CHUNK_ROWS = 1 << 16
# a drawing needs less than the G-code: 0.1 um
_DECIMALS = 4
_SCALE = 10**_DECIMALS
_RADIUS_DECIMALS = 8
_RADIUS_SCALE = 10**_RADIUS_DECIMALS
_INKSCAPE = "http://www.inkscape.org/namespaces/inkscape"

#: Decimals of the depth and radius in layer names: depth classes are 1 um wide.
LAYER_DECIMALS = 3
#: Layer colours in order of layer number: (AutoCAD colour index, the same colour
#: as SVG ``#rrggbb``); they repeat from the 17th layer. ACI 7 is black on paper
#: (white on a dark CAD background). Dark shades come before lime, cyan and
#: yellow, which are faint on white.
LAYER_COLOURS: tuple[tuple[int, str], ...] = (
    (7, "#000000"), (1, "#FF0000"), (5, "#0000FF"), (94, "#007F00"), (6, "#FF00FF"),
    (30, "#FF7F00"), (134, "#007F7F"), (174, "#00007F"), (14, "#7F0000"), (214, "#7F007F"),
    (34, "#7F3F00"), (154, "#003F7F"), (3, "#00FF00"), (4, "#00FFFF"), (2, "#FFFF00"),
    (8, "#808080"),
)
#: Layer number of the plate's outline and registration marks: the layers of up
#: to 49 depth classes stay below it (a design has one), and it is the same for
#: every drawing, so that a plotter or laser setup can name it.
PLATE_LAYER = 99
#: Name of the plate's layer (SVG label after the number, DXF layer name).
PLATE_LAYER_NAME = "PLATE"
#: The plate layer's colour, one no groove or dot layer has: (ACI, SVG ``#rrggbb``).
PLATE_COLOUR = (140, "#00BFFF")
#: Stroke of the plate's outline and marks, mm: 0.001 inch, which laser drivers
#: read as a hairline (a vector line, not an area to fill).
PLATE_STROKE = 0.025


@dataclass(frozen=True)
class Layer:
    """One named layer of an exported drawing: the grooves or the dots of one depth.

    Attributes:
        number: layer number from 1, fixed by kind and depth class (grooves of
            class c are c + 1, dots are n_classes + c + 1), so it does not
            change when another layer happens to be empty.
        name: ``GROOVES_D<depth>_R<tool radius>`` or ``DOTS_...``, mm with 3 decimals.
        dots: True for a layer of dots (single plunges).
        depth: depth of the class, mm (the mean of its paths' depths, which
            agree to the 1 um of the name).
        width: groove (or dot) width at the plate surface for that depth, mm.
        aci: AutoCAD colour index of the layer.
        colour: the same colour as SVG ``#rrggbb``.
        paths: (k,) indices of the layer's paths, ascending.
        classes: depth classes of the drawing: no layer of it is numbered above
            2 * classes.
    """

    number: int
    name: str
    dots: bool
    depth: float
    width: float
    aci: int
    colour: str
    paths: np.ndarray
    classes: int = 1


def surface_width(radius: float, depth: float | np.ndarray) -> np.ndarray:
    """Width at the plate surface of a groove cut by a ball of ``radius`` to ``depth`` (mm)."""
    d = np.asarray(depth, dtype=float)
    return 2.0 * np.sqrt(np.maximum(radius * radius - (radius - d) ** 2, 0.0))


def plan_layers(grooves: Grooves, tool: Tool, depths: np.ndarray | None = None,
                cut: tuple[float, float] | None = None) -> list[Layer]:
    """Sort the paths into layers by kind (groove or dot) and depth class.

    Args:
        grooves: n paths.
        tool: the ball-end tool; its ``depth`` is every path's depth unless
            ``depths`` is given.
        depths: optional (n,) depth of each path, mm, each in (0, tool radius].
            Depths equal to 1 um (the precision of the layer names) share a layer.
        cut: (depth, width) mm of every groove as its tool cuts it, where the
            tool is not the ball ``tool`` models (a drag tip's cone reaches past
            its round tip): the layer's name and stroke width say the cut, not
            the model.

    Returns:
        The non-empty layers, by number: grooves of each depth class from the
        shallowest, then dots likewise.

    Raises:
        SpecholoError: if ``depths`` has the wrong shape or a depth out of range.
    """
    n = grooves.n_paths
    r = tool.radius
    scale = 10**LAYER_DECIMALS
    if depths is None:
        # One depth class: no per-path depths to sort (38 million paths at 10^6 stipples).
        depth, width = (tool.depth, None) if cut is None else cut
        return _layers(grooves, tool, np.rint([depth * scale]).astype(np.int64),
                       np.array([depth]), np.zeros(n, dtype=np.int8),
                       None if width is None else np.array([width]))
    d = np.asarray(depths, dtype=float)
    if d.shape != (n,):
        raise SpecholoError(f"depths must hold one depth per path ({n}), got shape {d.shape}")
    bad = ~((d > 0.0) & (d <= r))  # also catches NaN
    if bad.any():
        i = int(np.argmax(bad))
        raise SpecholoError(
            f"depth of path {i} must be in (0, tool radius {r:g}] mm, got {d[i]:g}")
    keys, cls = np.unique(np.rint(d * scale).astype(np.int64), return_inverse=True)
    count = np.bincount(cls, minlength=len(keys))
    mean = np.bincount(cls, weights=d, minlength=len(keys)) / np.maximum(count, 1)
    return _layers(grooves, tool, keys, mean, cls)


def _layers(grooves: Grooves, tool: Tool, keys: np.ndarray, mean: np.ndarray,
            cls: np.ndarray, widths: np.ndarray | None = None) -> list[Layer]:
    """Layers of paths by kind and depth class: class c (of ``cls`` (n,)) has the
    rounded depth keys[c] (um), the mean depth mean[c] (mm) and the width
    widths[c] (mm; default the ball's at that depth)."""
    scale = 10**LAYER_DECIMALS
    r = tool.radius
    if widths is None:
        widths = surface_width(r, mean)
    dot = grooves.is_dot
    radius = format_number(r, LAYER_DECIMALS)
    layers = []
    for kind, is_dot in enumerate((False, True)):
        for c, key in enumerate(keys):
            paths = np.flatnonzero((cls == c) & (dot == is_dot))
            if len(paths) == 0:
                continue
            number = kind * len(keys) + c + 1
            aci, colour = LAYER_COLOURS[(number - 1) % len(LAYER_COLOURS)]
            name = (f"{'DOTS' if is_dot else 'GROOVES'}_D{format_number(key / scale, 3)}"
                    f"_R{radius}")
            layers.append(Layer(number, name, is_dot, float(mean[c]), float(widths[c]), aci,
                                colour, paths, len(keys)))
    return layers


def plate_layer_number(layers: list[Layer]) -> int:
    """Number of the plate's layer: :data:`PLATE_LAYER`, or the first number past
    every groove and dot layer of the drawing's depth classes when those reach it
    (it depends on the classes, not on which of their layers are empty)."""
    classes = layers[0].classes if layers else 1
    return max(PLATE_LAYER, 2 * classes + 1)


def take_paths(grooves: Grooves, paths: np.ndarray) -> Grooves:
    """The given paths (k,) of the grooves, in that order, as grooves of their own."""
    return grooves.take(paths)


@kernel()
def _extremes_bounds(centre: np.ndarray, radius: np.ndarray, start: np.ndarray,
                     sweep: np.ndarray, phi: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """(2, 2) bounds of the circles' extreme points in the directions ``phi`` (4,)
    (unit vectors ``direction`` (4, 2)) that the arcs pass; +-inf if none."""
    box = np.empty((2, 2))
    box[0, :] = np.inf
    box[1, :] = -np.inf
    two_pi = 2.0 * np.pi
    for i in range(len(radius)):
        lo = min(start[i], start[i] + sweep[i])
        span = abs(sweep[i])
        for k in range(len(phi)):
            if (phi[k] - lo) % two_pi <= span:  # the modulo of np.mod
                for j in range(2):
                    v = centre[i, j] + radius[i] * direction[k, j]
                    box[0, j] = min(box[0, j], v)
                    box[1, j] = max(box[1, j], v)
    return box


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
        phi = np.arange(4) * 0.5 * np.pi
        box = _extremes_bounds(centre, radius, start, sweep, phi,
                               np.stack([np.cos(phi), np.sin(phi)], axis=1))
        if np.isfinite(box).all():  # its corners bound the extreme points
            pts.append(box)
    return _corners(pts)


def _corners(points: list[np.ndarray]) -> np.ndarray:
    """(2, 2) lowest and highest x and y of several (k, 2) arrays, not all empty.

    Column by column: numpy reduces an (k, 2) array along axis 0 several times
    slower."""
    points = [p for p in points if len(p)]
    return np.array([[min(float(p[:, j].min()) for p in points) for j in range(2)],
                     [max(float(p[:, j].max()) for p in points) for j in range(2)]])


def drawing_bounds(grooves: Grooves, half: float = 0.0) -> np.ndarray | None:
    """Bounding box of a drawing of the grooves, a chunk of paths at a time.

    Args:
        grooves: n paths.
        half: half the width of a dot, mm (dots reach that far round their plunge).

    Returns:
        (2, 2) lower-left and upper-right corners in mm of the arcs (see
        :func:`arc_bounds`) and the dots, or None if there is no vertex.
    """
    def box(a: int, b: int) -> np.ndarray | None:
        g = slice_paths(grooves, a, b)
        dots, _ = g.dots()
        segs = g.segments()
        parts = [dots - half, dots + half] + ([arc_bounds(segs)] if len(segs) else [])
        return _corners(parts) if any(len(p) for p in parts) else None

    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    for part in in_order(box, path_chunks(grooves, _CHUNK_ROWS)):
        if part is not None:
            lo = np.minimum(lo, part[0])
            hi = np.maximum(hi, part[1])
    return np.stack([lo, hi]) if np.isfinite(lo).all() else None


def _path_text(g: Grooves) -> bytes:
    """SVG ``<path>`` elements of the paths of ``g`` (none a dot)."""
    verts = np.asarray(g.vertices, dtype=float).reshape(-1, 2)
    m = len(verts)
    offsets = np.asarray(g.offsets, dtype=np.int64)
    segs = g.segments()
    last = np.zeros(m, dtype=bool)
    last[offsets[1:] - 1] = True
    straight = is_straight(segs)
    rows = np.flatnonzero(~last) + 1  # each arc is drawn on its end vertex's row
    kind = np.zeros(m, dtype=np.int64)  # 0 path start, 1 arc, 2 line
    kind[rows] = np.where(straight, 2, 1)
    arc = kind == 1
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

    t = TextRows(m)
    t.choice(['<path d="M ', " A ", " L "], kind)
    t.number(q_radius, _RADIUS_DECIMALS, arc)
    t.text(" ", arc)
    t.number(q_radius, _RADIUS_DECIMALS, arc)
    t.text(" 0 ", arc)
    t.choice(["", "0", "1"], np.where(arc, 1 + large, 0))
    t.text(" ", arc)
    t.choice(["", "0", "1"], np.where(arc, 1 + sweep, 0))
    t.text(" ", arc)
    t.number(qx, _DECIMALS)
    t.text(" ")
    t.number(qy, _DECIMALS)
    t.choice(["", '"/>\n'], last.astype(np.int64))
    return t.tobytes()


def _dot_text(g: Grooves, radius: str) -> bytes:
    """SVG ``<circle>`` elements of radius ``radius`` (text, mm) for the dots of ``g``."""
    dots, _ = g.dots()
    t = TextRows(len(dots))
    t.text('<circle cx="')
    t.number(np.rint(dots[:, 0] * _SCALE).astype(np.int64), _DECIMALS)
    t.text('" cy="')
    t.number(np.rint(-dots[:, 1] * _SCALE).astype(np.int64), _DECIMALS)
    t.text(f'" r="{radius}"/>\n')
    return t.tobytes()


def _plate_text(plate: Plate, number: int) -> bytes:
    """The plate's layer: its outline, then each registration mark as a crosshair
    and a circle (SVG y = -plate y)."""
    def num(value: float) -> str:
        return format_number(value, _DECIMALS)

    arm, r = plate.mark_arm, plate.mark_radius
    colour = PLATE_COLOUR[1]
    rows = [f'<g id="layer{number}" inkscape:groupmode="layer"'
            f' inkscape:label="{number} {PLATE_LAYER_NAME}" fill="none" stroke="{colour}"'
            f' stroke-width="{num(PLATE_STROKE)}">',
            f'<rect x="{num(plate.x0)}" y="{num(-plate.y1)}" width="{num(plate.width)}"'
            f' height="{num(plate.height)}"/>']
    for x, y in plate.marks():
        y = -y
        rows.append(f'<path d="M {num(x - arm)} {num(y)} L {num(x + arm)} {num(y)}'
                    f' M {num(x)} {num(y - arm)} L {num(x)} {num(y + arm)}"/>')
        rows.append(f'<circle cx="{num(x)}" cy="{num(y)}" r="{num(r)}"/>')
    rows.append("</g>\n")
    return "\n".join(rows).encode("ascii")


def write_svg(path: str | os.PathLike[str], grooves: Grooves, tool: Tool,
              margin: float = 5.0, depths: np.ndarray | None = None,
              plate: Plate | None = None, cut: tuple[float, float] | None = None) -> None:
    """Write the grooves as an SVG drawing in mm, atomically, a chunk of paths at a time.

    Args:
        path: destination ``.svg`` file.
        grooves: m vertices in n paths; dots become filled circles.
        tool: the groove width for each depth is the stroke width and dot diameter.
        margin: blank border around the grooves, mm.
        depths: optional (n,) depth of each path, mm; each depth class gets its
            own groove and dot layers (see :func:`plan_layers`).
        plate: the plate, drawn in its own layer with its registration marks;
            default the plate fitted to the grooves
            (:func:`~specholo.fabrication.plate.fit_plate`).
        cut: (depth, width) mm of the grooves as cut, as :func:`plan_layers`.

    Raises:
        SpecholoError: if the grooves hold an empty path or non-finite numbers,
            or ``depths`` is malformed.
    """
    check_grooves(grooves)
    margin = float(margin)
    if not (math.isfinite(margin) and margin >= 0.0):
        raise SpecholoError(f"SVG margin must be a finite number >= 0 mm, got {margin}")
    layers = plan_layers(grooves, tool, depths, cut)
    box = drawing_bounds(grooves)
    if box is None:
        box = np.zeros((2, 2))
    widest = max([layer.width for layer in layers] or [tool.width])
    if plate is None:
        plate = Plate.fitted(drawn_extent(grooves), widest)
    pad = margin + 0.5 * widest
    # the page holds the grooves with their border and the whole plate
    x0, x1 = min(box[0, 0] - pad, plate.x0), max(box[1, 0] + pad, plate.x1)
    y0, y1 = min(-box[1, 1] - pad, -plate.y1), max(-box[0, 1] + pad, -plate.y0)  # SVG y = -y
    w, h = x1 - x0, y1 - y0

    def num(value: float) -> str:
        return format_number(value, _DECIMALS)

    head = (
        '<?xml version="1.0" encoding="UTF-8" standalone="no"?>\n'
        f'<svg xmlns="http://www.w3.org/2000/svg" xmlns:inkscape="{_INKSCAPE}" version="1.1"\n'
        f'     width="{num(w)}mm" height="{num(h)}mm"\n'
        f'     viewBox="{num(x0)} {num(y0)} '
        f'{num(w)} {num(h)}">\n'
        "<!-- specholo grooves; units mm; origin at the plate centre; "
        "plate y up = SVG -y; layers GROOVES/DOTS_D<depth>_R<tool radius>, "
        f"{PLATE_LAYER_NAME}: plate {num(plate.width)} x {num(plate.height)} mm "
        "and registration marks -->\n"
    )
    with atomic_open(path, "wb") as fh:
        fh.write(head.encode("ascii"))
        for layer in layers:
            group = (f'<g id="layer{layer.number}" inkscape:groupmode="layer"'
                     f' inkscape:label="{layer.number} {layer.name}"')
            if layer.dots:
                group += f' fill="{layer.colour}" stroke="none">\n'
            else:
                group += (f' fill="none" stroke="{layer.colour}"'
                          f' stroke-width="{num(layer.width)}" stroke-linecap="round"'
                          ' stroke-linejoin="round">\n')
            fh.write(group.encode("ascii"))
            def text(a: int, b: int, layer: Layer = layer) -> bytes:
                g = take_paths(grooves, layer.paths[a:b])
                return _dot_text(g, num(0.5 * layer.width)) if layer.dots else _path_text(g)

            for chunk in in_order(text, path_chunks(grooves, _CHUNK_ROWS, layer.paths)):
                fh.write(chunk)
            fh.write(b"</g>\n")
        fh.write(_plate_text(plate, plate_layer_number(layers)))
        fh.write(b"</svg>\n")
