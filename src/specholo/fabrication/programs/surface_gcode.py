"""G-code for grooves on curved hosts: 3-axis with a vertical tool, and 4-axis
with a rotary A axis for a cylinder; and the limits the safety check
(:mod:`specholo.fabrication.check`, the one every program passes) holds them to.

3-axis: a ball is round, so a vertical ball-end tool whose centre sits at
C = c + (R - d) N cuts the same groove as one held along the local normal N,
as long as its shank clears the surface; that holds while the surface tilts
less than asin(1 - d / R) from vertical. Samples beyond that reach are left out
(and counted). The program moves the tool tip, R below the centre; rapids go
at the safe height above the host's highest point, wherever the grooves are.
X and Y are the host's frame; Z = 0 is a point of the host a maker can touch
off on (:func:`program_zero`): where its front crosses the axis (X0 Y0), or,
for a host with no surface there (panels with a gap at the axis, a host set
back behind its frame's origin), its highest point.

4-axis (cylinder only): the cylinder's axis lies along the machine's X, the A
axis turns it (degrees), and the tool stays over the axis, so it always cuts
along the local normal. Z is zero at the top of the cylinder's surface: the tip
goes to Z = -d.

Every program's header says what it was made for: units, origin, the tool and
its depth, the host and the stock under its surface. On a plane host the
limits are a flat plate's, and the header names them (``check`` lines,
:meth:`~specholo.fabrication.check.Limits.header`) so that ``specholo check
PROGRAM`` reads them back with no options. On a curved host the limits follow
the host's surface, which no header line can name: the header says so.

All numbers are written with '.' as the decimal point whatever the locale.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from specholo.errors import SpecholoError
from specholo.fabrication.check import Limits, Stock, check_program, tool_kind
from specholo.fabrication.plate import STOCK_THICKNESS, Plate
from specholo.fabrication.programs.program import Emitter, GcodeOptions
from specholo.hosts.surfaces import Cylinder, HeightField, Host, MeshHost, Panels, Plane, Sphere
from specholo.setup import Machining, Tool
from specholo.toolpaths.conforming import ConformingGrooves

#: Blank border around the grooves of an unbounded plane host, mm (as a flat
#: design's plate when no size is given).
PLANE_MARGIN = 5.0
#: Allowance on a cut's depth below a curved host, mm: the tip follows the
#: surface in straight moves between samples whose ends are rounded to 0.1 um,
#: and a vertical ball on a concave slope reaches a little below the depth.
SURFACE_TOLERANCE = 2e-3


def reach_tilt(tool: Tool) -> float:
    """Steepest surface tilt (radians) a vertical tool reaches without its shank
    touching the surface beside the groove."""
    return math.asin(max(0.0, 1.0 - tool.depth / tool.radius))


@dataclass(frozen=True)
class SurfaceProgram:
    """A written program and its figures.

    Attributes:
        text: the G-code.
        paths: number of grooves cut.
        dropped_samples: samples beyond the 3-axis reach, left out.
        cut_length: length of cutting moves, mm (3-axis, tool tip) or of the
            grooves (4-axis).
    """

    text: str
    paths: int
    dropped_samples: int
    cut_length: float


def _short(v: float) -> str:
    """A length for a comment: up to 4 decimals, no trailing zeros."""
    s = f"{v:.4f}".rstrip("0").rstrip(".")
    return "0" if s in ("", "-0") else s


def _head(em: Emitter, host: Host, tool: Tool, axes: int, thickness: float, limits: Limits,
          safe: float) -> list[str]:
    """The program's head: what it cuts, with what, on what, and its limits where
    a header can name them; then the emitter's set-up, rising to ``safe``."""
    if axes == 4:
        origin = ("origin: X along the cylinder's axis from its middle, A turns it "
                  "in degrees, Z = 0 at the top of its surface")
    elif isinstance(host, Plane):
        origin = "origin: plate centre; X right, Y up, Z = 0 on the plate surface"
    else:
        zero, on_axis = program_zero(host)
        shift = em.short(float(zero[2]))
        if on_axis:
            where = "where the host's front crosses the axis" + (
                "" if shift == "0" else f", Z{shift} in that frame")
        else:
            where = (f"at the host's highest point X{em.short(float(zero[0]))} "
                     f"Y{em.short(float(zero[1]))}, Z{shift} in that frame: its front does not "
                     "cross the axis")
        origin = ("origin: the host's frame, as hologram.json's host says; X right, Y up, "
                  "Z = 0 " + where)
    unit = em.unit
    body = [f"tool: ball end, round tip radius {em.short(tool.radius)} {unit}, groove width "
            f"{em.short(tool.width)} {unit}",
            f"depth: {em.short(tool.depth)} {unit} below the surface"]
    header = limits.header()
    plate = None
    if header:
        plate = Plate(limits.stock.x0, limits.stock.y0, limits.stock.x1, limits.stock.y1,
                      thickness)
    else:
        body += [f"host: {_describe(host)}, {em.short(thickness)} {unit} of material under its "
                 "surface",
                 "limits: not in this header: they follow the host's curved surface, which "
                 "no header line can name; the program passed them when it was written "
                 "as hologram.json's gcode.check records"]
    return em.head(f"specholo: grooves on a {host.kind} host, {axes}-axis", body, header,
                   plate, None, origin, safe)


def _describe(host: Host) -> str:
    """The host in a few words, for a comment: its kind and size."""
    seen = host.describe()
    sizes = [f"{k} {_short(seen[k])} mm" for k in ("radius", "width", "height")
             if isinstance(seen.get(k), int | float)]
    return ", ".join([host.kind, *sizes])


def write_surface_gcode(grooves: ConformingGrooves, host: Host, tool: Tool,
                        machining: Machining, axes: int = 3,
                        thickness: float = STOCK_THICKNESS,
                        options: GcodeOptions | None = None) -> SurfaceProgram:
    """Write the grooves as G-code, through the one emitter
    (:class:`~specholo.fabrication.programs.program.Emitter`).

    Args:
        grooves: the grooves (centreline samples with host normals).
        host: their host.
        tool: the ball model (radius, depth).
        machining: feeds, safe height, spindle.
        axes: 3, or 4 for a cylinder on a rotary axis.
        thickness: the material under the host's surface, mm (the header names it).
        options: dialect and units (a mill's: the tool moves in Z); default GRBL in mm.

    Returns:
        The program.

    Raises:
        SpecholoError: 4 axes for a host that is not a cylinder, or a laser dialect.
    """
    if axes not in (3, 4):
        raise SpecholoError(f"axes must be 3 or 4, got {axes}")
    if axes == 4 and not isinstance(host, Cylinder):
        raise SpecholoError("4-axis output is for a cylinder host (a rotary A axis)")
    em = Emitter(options or GcodeOptions(), machining)
    em.require_mill("a program on a curved host")
    limits = surface_limits(grooves, host, tool, machining, axes, thickness)
    paths = 0
    dropped = 0
    length = 0.0
    body: list[str] = []
    if axes == 3:
        # machine Z is the host's z less the program's zero: the rapids clear the
        # host's highest point by the safe height whatever its height in the frame
        shift = np.array([0.0, 0.0, program_zero(host)[0][2]])
        safe = host_top(host) - shift[2] + machining.safe_z
        limit = math.cos(reach_tilt(tool))
        for path in np.split(np.arange(len(grooves.point)),
                             np.flatnonzero(np.diff(grooves.stripe)) + 1):
            if path.size < 2:
                continue
            ok = grooves.normal[path, 2] >= limit
            dropped += int((~ok).sum())
            # Cut the runs of reachable samples, each a groove of its own.
            runs = np.split(path, np.flatnonzero(np.diff(ok.astype(int))) + 1)
            for run in runs:
                if run.size < 2 or grooves.normal[run[0], 2] < limit:
                    continue
                tip = (grooves.point[run] + (tool.radius - tool.depth) * grooves.normal[run]
                       - np.array([0.0, 0.0, tool.radius]) - shift)
                body += em.polyline(tip, f"stipple {int(grooves.stipple[run[0]])}", safe)
                length += float(np.linalg.norm(np.diff(tip, axis=0), axis=1).sum())
                paths += 1
    else:
        assert isinstance(host, Cylinder)
        safe = machining.safe_z
        for path in np.split(np.arange(len(grooves.point)),
                             np.flatnonzero(np.diff(grooves.stripe)) + 1):
            if path.size < 2:
                continue
            p = grooves.point[path]
            a = np.degrees(np.unwrap(host.angle(p)))
            body += em.rotary(p[:, 1], a, tool.depth, f"stipple {int(grooves.stipple[path[0]])}")
            length += float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())
            paths += 1
    lines = _head(em, host, tool, axes, thickness, limits, safe) + body + em.tail()
    return SurfaceProgram("\n".join(lines) + "\n", paths, dropped, length)


def host_top(host: Host) -> float:
    """The height of the host's highest point, mm: the 3-axis safe height is
    measured from it (a rapid clears every part of the host, not only the grooves)."""
    return float(_highest(host)[2])


def _highest(host: Host) -> np.ndarray:
    """(3,) the host's highest point in its frame, mm (one of them, where several
    are as high)."""
    if isinstance(host, Plane | Cylinder | Sphere):
        return np.zeros(3)  # their front passes through the origin, at their top
    if isinstance(host, HeightField):
        # the bicubic spline may rise between its samples: it is read on a grid
        # four times finer too
        x = np.linspace(host.x[0], host.x[-1], 4 * len(host.x))
        y = np.linspace(host.y[0], host.y[-1], 4 * len(host.y))
        xx, yy = np.meshgrid(x, y)
        between = _vertical_hits(host, xx.ravel(), yy.ravel(), float(host.z.max()))
        row, col = np.unravel_index(int(np.argmax(host.z)), host.z.shape)
        if np.isnan(between).all() or host.z[row, col] >= np.nanmax(between):
            return np.array([host.x[col], host.y[row], host.z[row, col]], dtype=float)
        k = int(np.nanargmax(between))
        return np.array([xx.ravel()[k], yy.ravel()[k], between[k]], dtype=float)
    if isinstance(host, MeshHost):
        vertices = np.asarray(host.mesh.vertices, dtype=float)
        return vertices[int(np.argmax(vertices[:, 2]))]
    if isinstance(host, Panels):
        corners = _panel_corners(host)
        return corners[int(np.argmax(corners[:, 2]))]
    raise SpecholoError(f"no highest point known for a {host.kind} host")


def program_zero(host: Host) -> tuple[np.ndarray, bool]:
    """Where a 3-axis program on a curved host has Z = 0, and whether that is at
    X0 Y0: (3,) a point of the host in its frame, mm.

    A maker touches Z off on the host itself, so the zero is on it: where the
    host's first surface lies straight under the frame's origin (every host of
    one piece passes through the origin, and there Z = 0 is its frame's z = 0);
    where nothing lies there (panels with a gap at the axis, or set back
    behind the origin), its highest point. Either way the highest point is
    at or above Z = 0, so the safe height above it is a height above the zero,
    as every program's safe height is (``check.Limits``).
    """
    if isinstance(host, Plane | Cylinder | Sphere):
        return np.zeros(3), True  # their front passes through the origin, at their top
    top = _highest(host)
    under = _vertical_hits(host, np.zeros(1), np.zeros(1), float(top[2]))[0]
    if np.isfinite(under):
        return np.array([0.0, 0.0, min(float(under), float(top[2]))]), True
    return top, False


def _panel_corners(host: Panels) -> np.ndarray:
    """(4 k, 3) corners of a panels host's panels, mm."""
    corners = []
    for p in host.panels:
        c, right, up, _ = p.frame()
        for sx, sy in ((-1, -1), (-1, 1), (1, -1), (1, 1)):
            corners.append(c + 0.5 * sx * p.width * right + 0.5 * sy * p.height * up)
    return np.array(corners)


def host_extent(host: Host, grooves: ConformingGrooves) -> tuple[float, float, float, float]:
    """x0, y0, x1, y1 (mm): where a vertical tool may cut a host, seen from above.

    The host's own extent; an unbounded plane's is its grooves' plus
    :data:`PLANE_MARGIN` (as a flat design's plate)."""
    if isinstance(host, Plane):
        w, h = host.width, host.height
        if math.isfinite(w) and math.isfinite(h):
            return -0.5 * w, -0.5 * h, 0.5 * w, 0.5 * h
        p = grooves.point[:, :2] if len(grooves.point) else np.zeros((1, 2))
        lo, hi = p.min(axis=0) - PLANE_MARGIN, p.max(axis=0) + PLANE_MARGIN
        x0 = -0.5 * w if math.isfinite(w) else float(lo[0])
        x1 = 0.5 * w if math.isfinite(w) else float(hi[0])
        y0 = -0.5 * h if math.isfinite(h) else float(lo[1])
        y1 = 0.5 * h if math.isfinite(h) else float(hi[1])
        return x0, y0, x1, y1
    if isinstance(host, Cylinder):
        return -host.radius, -0.5 * host.height, host.radius, 0.5 * host.height
    if isinstance(host, Sphere):
        return -host.radius, -host.radius, host.radius, host.radius
    if isinstance(host, HeightField):
        return float(host.x[0]), float(host.y[0]), float(host.x[-1]), float(host.y[-1])
    if isinstance(host, MeshHost):
        (x0, y0, _), (x1, y1, _) = np.asarray(host.mesh.bounds, dtype=float)
        return float(x0), float(y0), float(x1), float(y1)
    if isinstance(host, Panels):
        c = _panel_corners(host)
        return float(c[:, 0].min()), float(c[:, 1].min()), float(c[:, 0].max()), \
            float(c[:, 1].max())
    raise SpecholoError(f"no extent known for a {host.kind} host")


def _surface_under(host: Host, x: np.ndarray, y: np.ndarray, top: float,
                   reach: float) -> np.ndarray:
    """Height (n,) of the host's surface under vertical-tool tips at x, y (n,), mm.

    Straight down, the host's first surface. A groove at the host's edge puts the
    tip beyond the edge (up to R - d across from where the ball meets the
    surface): there the surface is extended to the tip by its tangent planes at
    the points straight down from a ring of radius ``reach`` about it (the
    highest of them, so the depth is not understated); NaN where the ring finds
    no surface either.
    """
    h = _vertical_hits(host, x, y, top)
    miss = np.flatnonzero(np.isnan(h))
    if len(miss) and reach > 0:
        px, py = np.asarray(x, dtype=float).ravel()[miss], np.asarray(y, dtype=float).ravel()[miss]
        turn = np.linspace(0.0, 2.0 * math.pi, _RING, endpoint=False)
        rx = (px[:, None] + reach * np.cos(turn)).ravel()
        ry = (py[:, None] + reach * np.sin(turn)).ravel()
        rz = _vertical_hits(host, rx, ry, top)
        ext = np.full(len(rz), np.nan)
        hit = np.flatnonzero(~np.isnan(rz))
        if len(hit):
            n = host.normal(np.stack([rx[hit], ry[hit], rz[hit]], axis=1))
            with np.errstate(invalid="ignore", divide="ignore"):
                ext[hit] = rz[hit] - (n[:, 0] * (np.repeat(px, _RING)[hit] - rx[hit])
                                      + n[:, 1] * (np.repeat(py, _RING)[hit] - ry[hit])) / n[:, 2]
        ring = ext.reshape(len(miss), _RING)
        found = ~np.isnan(ring).all(axis=1)
        h[miss[found]] = np.nanmax(ring[found], axis=1)
    return h


#: Points on the ring about a tip beyond a host's edge (:func:`_surface_under`).
_RING = 12


def _vertical_hits(host: Host, x: np.ndarray, y: np.ndarray, top: float) -> np.ndarray:
    """Height (n,) of the host's first surface met straight down from above each
    x, y (n,), mm; NaN where there is none."""
    x, y = np.asarray(x, dtype=float).ravel(), np.asarray(y, dtype=float).ravel()
    if not len(x):
        return np.zeros(0)
    origins = np.stack([x, y, np.full(len(x), top + 1.0)], axis=1)
    hit = host.intersect(origins, np.array([0.0, 0.0, -1.0]))
    return np.where(hit.valid, hit.point[:, 2], np.nan)


def surface_limits(grooves: ConformingGrooves, host: Host, tool: Tool, machining: Machining,
                   axes: int = 3, thickness: float = STOCK_THICKNESS) -> Limits:
    """What a host's program may do, from the composition's settings (mm).

    On a plane: a flat plate's limits (the surface Z = 0), which a header names:
    the tool tip inside the plane (or the grooves' extent and a border), every
    cut in X/Y at the groove's depth, no feed move in X/Y above the surface,
    rapids at the safe height.
    3 axes: the tool tip inside the host seen from above, no deeper than the
    groove below the surface under it (``Limits.surface``: the host's first
    surface straight down, extended a little past its edges), rapids at the
    safe height above the host's top; heights in the program's Z, which is
    zero at :func:`program_zero`.
    4 axes: the tip over the cylinder's axis (Y within half a groove) and along
    its length, no deeper than the groove below the top of the turning cylinder
    (Z = 0 there, however it turns), rapids at the safe height. Feeds and
    spindle as set; the tool is a mill if it spins, else a drag tip. The stock
    is ``thickness`` deep under the surface: no cut reaches it.
    """
    feeds = (min(machining.feed, machining.plunge), max(machining.feed, machining.plunge))
    spindle = (machining.spindle, machining.spindle)
    kind = tool_kind("ball", machining.spindle)
    if axes == 4:
        if not isinstance(host, Cylinder):
            raise SpecholoError("4-axis output is for a cylinder host (a rotary A axis)")
        r, half = host.radius, 0.5 * host.height
        y = 0.5 * tool.width

        def on_cylinder(x: np.ndarray, yy: np.ndarray) -> np.ndarray:
            x, yy = np.asarray(x, dtype=float), np.asarray(yy, dtype=float)
            with np.errstate(invalid="ignore"):
                z = np.sqrt(r * r - yy * yy) - r
            return np.where((np.abs(x) <= half) & (np.abs(yy) <= r), z, np.nan)

        return Limits(Stock(-half, -y, half, y, thickness), tool.depth, machining.safe_z,
                      feeds, spindle, kind, surface=on_cylinder, rotary=True,
                      tolerance=SURFACE_TOLERANCE)
    if isinstance(host, Plane):
        # the tip stays at the groove's depth along every groove and only plunges
        # and rises between them (hop_max 0: no feed move in X/Y above the plate)
        return Limits(Stock(*host_extent(host, grooves), thickness), tool.depth,
                      machining.safe_z, feeds, spindle, kind, hop_max=0.0,
                      groove_depth=tool.depth)
    top = host_top(host)
    zero = float(program_zero(host)[0][2])  # the program's Z is the host's z less this

    def under(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return _surface_under(host, x, y, top, tool.radius - tool.depth) - zero

    return Limits(Stock(*host_extent(host, grooves), thickness), tool.depth,
                  top - zero + machining.safe_z, feeds, spindle, kind, surface=under,
                  tolerance=SURFACE_TOLERANCE)


def check_surface_program(path: str | os.PathLike[str], grooves: ConformingGrooves, host: Host,
                          tool: Tool, machining: Machining, axes: int = 3,
                          thickness: float = STOCK_THICKNESS) -> dict[str, Any]:
    """Read a host's written program back through the safety check
    (:func:`surface_limits`).

    Returns:
        Figures: moves by kind, cutting moves, the deepest cut below the surface
        (mm) and the safe height (machine Z, mm).

    Raises:
        SpecholoError: on any violation, in one line.
    """
    limits = surface_limits(grooves, host, tool, machining, axes, thickness)
    report = check_program(path, limits)
    return {"moves": report.moves, "violations": 0, "cutting_moves": report.moves["cutting"],
            "deepest_cut_mm": report.deepest, "safe_z": limits.safe_z}
