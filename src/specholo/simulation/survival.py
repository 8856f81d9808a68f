"""Which designed glints survive the cutting, found from the grooves themselves.

Every groove is the volume a rotationally symmetric tool sweeps, its tip at
z = -depth, along the path's centreline (arcs by bulge; a dot is one plunge).
A designed glint is a point p on its own groove's wall. Cutting only ever
removes material, so after all the cuts the surface at p is still that wall,
with the wall's normal, exactly when p is not strictly inside any other cut's
swept tool, whatever order the cuts were made in.

The tool at centreline point c holds every point above its cutting surface,
z > -depth + height(|p_xy - c_xy|) (``height`` rising with the distance from
its axis). So the sweep of a path reaches deepest under p where its centreline
passes closest to p in plan, and p is gone iff some other path passes within
its *removal radius* r(p): the distance at which the tool's surface has risen
to p's height above the tip (:func:`removal_radius`). For a ball that is the
point's distance from the other path's line of ball centres being under R.

The test is exact for the point. On a wall cut away its glint may still
appear on the other cut's wall nearby, with the same normal, only when the two
centrelines nearly coincide (a retraced groove); the designed grooves keep a
stipple's stripes a groove width apart, so this is left out.

:func:`survivors` tests every glint against every other path at once: the
glints are sorted into a grid, and each path's arcs are streamed once, in
pieces no longer than a cell, each piece visiting only the cells within the
largest removal radius of it. :func:`verify_as_cut` finds each eye's glints on
the ideal grooves as :func:`~specholo.simulation.verify.verify` does, keeps
the survivors, and reports the same figures per head azimuth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from specholo._compiling import kernel
from specholo._threads import chunked
from specholo.errors import SpecholoError
from specholo.optics.cutters import TILT_TOLERANCE, BallEnd, Laser, RoundCone, VBit
from specholo.optics.normality import normality
from specholo.setup import Setup, Tool
from specholo.simulation.glints import Engraved, Glints, find_glints
from specholo.simulation.verify import (
    CHUNK_VERTICES,
    ViewReport,
    VisibilityFn,
    _chunks,
    view_azimuths,
    view_report,
)
from specholo.toolpaths.grooves import Grooves

#: A point counts as inside another cut when it lies more than this above the
#: cut's surface, mm: a wall another path retraces exactly is not removed by it.
EPS = 1e-9
#: Bulges below this are straight segments (as the glint search takes them).
LINE_BULGE = 1e-9
#: A sweep's per-path depths: each glint's z (g,), each path's depth (n_paths,)
#: and the tool's profile (:func:`_profile`); three empty arrays for one depth.
CutDepths = tuple[np.ndarray, np.ndarray, np.ndarray]
#: What a sweep does with a glint it holds: ``(mode, at, dest)``. MARK sets
#: its ``removed`` flag; COUNT adds one to ``at[path]``; FILL writes the
#: glint's index at ``dest[at[path]]`` and moves ``at[path]`` on. Each path
#: writes only its own entries, so threads over chunks of paths never race.
Hits = tuple[int, np.ndarray, np.ndarray]
MARK, COUNT, FILL = 0, 1, 2
#: Grid cells per glint at most (a sparse design on a wide plate gets larger cells).
CELLS_PER_GLINT = 4
#: Smallest grid cell, mm.
MIN_CELL = 0.02
#: Most pieces an arc is visited in (an arc metres long on a fine grid).
MAX_PIECES = 1 << 16
#: Batches of paths between which the glints already removed leave the grid,
#: and the fewest paths in a batch (each batch re-sorts the glints standing).
#: At 10^5 stipples (24 million arcs) 16 batches take 7.9 s against 12.9 s for one.
BATCHES = 16
MIN_BATCH = 250_000


# ---------------------------------------------------------------------------
# The tool: how close another cut must pass to remove a wall point


def _profile(cutter: Any) -> np.ndarray:
    """The tool's removal radius in closed form, whatever the cut's depth: (R,
    h_j, r_j, t) with r(lift) = sqrt(lift (2R - lift)) up to h_j, then
    r_j + (lift - h_j) t (a ball stops at its radius, a round cone goes on
    along its flank, a V-bit is all flank from its tip flat). A laser's trough
    scales with its depth and has no such profile."""
    if isinstance(cutter, Tool | BallEnd):
        R = float(cutter.radius)
        return np.array([R, R, R, 0.0])
    if isinstance(cutter, RoundCone):
        R, half = float(cutter.tip_radius), 0.5 * float(cutter.angle)
        return np.array([R, R * (1.0 - math.sin(half)), R * math.cos(half), math.tan(half)])
    if isinstance(cutter, VBit):
        return np.array([0.0, 0.0, 0.5 * float(cutter.tip_flat),
                         math.tan(0.5 * float(cutter.angle))])
    raise SpecholoError(f"no removal radius, whatever the depth, for the tool {cutter!r}")


def removal_radius(cutter: Any, depth: float, lift: np.ndarray) -> np.ndarray:
    """Plan distance within which another cut's centreline removes wall points.

    A point ``lift`` mm above the tip plane (z + depth) is strictly inside the
    body of a tool whose axis passes at plan distance r iff
    height(r) < lift - :data:`EPS`; height grows with r, so that is r below the
    radius returned here.

    Args:
        cutter: a :mod:`~specholo.optics.cutters` cutter, or the ball model
            :class:`~specholo.setup.Tool` (its own depth is then the cut's).
        depth: groove depth, mm (the tip runs at z = -depth).
        lift: (g,) heights of the points above the tip plane, mm.

    Returns:
        (g,) removal radii, mm (0: no cut at this depth reaches the point).
    """
    z = np.asarray(lift, dtype=float) - EPS
    up = np.maximum(z, 0.0)
    if isinstance(cutter, Laser):
        # depth (1 - exp(-2 r^2 / w0^2)) = lift; the trough's tails are cut off
        # three waists out (the height there is within 2e-8 of the depth).
        w0 = 0.5 * float(cutter.spot)
        frac = np.minimum(up / depth, 1.0 - 1e-12)
        r = np.minimum(w0 * np.sqrt(-0.5 * np.log1p(-frac)), 3.0 * w0)
    else:
        R, hj, rj, t = _profile(cutter)
        c = np.minimum(up, hj)
        r = np.where(up <= hj, np.sqrt(c * (2.0 * R - c)), rj + (up - hj) * t)
    return np.where(z > 0.0, r, 0.0)


@kernel(helper=True)
def _removal_at(lift: float, profile: np.ndarray) -> float:
    """:func:`_profile`'s removal radius at ``lift`` mm above the cutting tip."""
    up = lift - EPS
    if up <= 0.0:
        return 0.0
    R, hj = profile[0], profile[1]
    if up <= hj:
        return math.sqrt(up * (2.0 * R - up))
    return profile[2] + (up - hj) * profile[3]


def _exact_model(cutter: Any, depth: float) -> bool:
    """Whether the ball model's wall is the real tool's wherever a glint sits."""
    if isinstance(cutter, Tool | BallEnd):
        return True
    if isinstance(cutter, RoundCone):
        half = 0.5 * float(cutter.angle)
        return depth <= float(cutter.tip_radius) * (1.0 - math.sin(half))
    return False


def _wall_offset(cutter: Any, depth: float, tilt: np.ndarray) -> np.ndarray:
    """Plan distance from the axis (g,) where the real tool's wall has each tilt (g,).

    A flat facet (a V-bit's or cone's flank) offers its tilt over its whole
    width: its middle stands for it. A laser trough's inner slope is solved
    for by bisection.
    """
    if isinstance(cutter, RoundCone):
        R, half = float(cutter.tip_radius), 0.5 * float(cutter.angle)
        rj, hj = R * math.cos(half), R * (1.0 - math.sin(half))
        rim = rj + max(depth - hj, 0.0) * math.tan(half)
        flank = 0.5 * math.pi - half
        return np.where(tilt < flank - TILT_TOLERANCE, R * np.sin(tilt), 0.5 * (rj + rim))
    if isinstance(cutter, VBit):
        flat = 0.5 * float(cutter.tip_flat)
        rim = flat + depth * math.tan(0.5 * float(cutter.angle))
        floor = tilt < 0.25 * (math.pi - float(cutter.angle))  # nearer the floor's tilt 0
        return np.where(floor & (flat > 0.0), 0.5 * flat, 0.5 * (flat + rim))
    if isinstance(cutter, Laser):
        w0 = 0.5 * float(cutter.spot)
        want = np.tan(tilt)
        lo, hi = np.zeros_like(want), np.full_like(want, 0.5 * w0)  # slope rises to w0 / 2
        for _ in range(50):
            mid = 0.5 * (lo + hi)
            slope = 4.0 * depth * mid / (w0 * w0) * np.exp(-2.0 * mid * mid / (w0 * w0))
            lo, hi = np.where(slope < want, mid, lo), np.where(slope < want, hi, mid)
        return 0.5 * (lo + hi)
    raise SpecholoError(f"no wall offset for the tool {cutter!r}")


def _cutter_height(cutter: Any, depth: float, r: np.ndarray) -> np.ndarray:
    if isinstance(cutter, Laser):
        return cutter.height(r, depth=depth)
    return np.asarray(cutter.height(r), dtype=float)


def on_real_wall(glints: Glints, model: Tool, cutter: Any, depth: float, light: Any,
                 eye: np.ndarray) -> np.ndarray:
    """The glints (g, 3) moved from the ball model's wall onto the real tool's.

    For a ball and a round tip cut within its sphere the model is the tool and
    the points are returned as they are. Otherwise (a V-bit, a laser trough,
    a drag tip cut into its cone) each point moves across its groove, along
    the plan direction of h, to where the real wall has h's tilt, and to that
    wall's height.

    Args:
        glints: an eye's glints on the model's walls.
        model: the ball model they were found on (its radius places the toolpath).
        cutter: the real tool; depth: the groove depth, mm.
        light, eye: the light and the (3,) eye.
    """
    p = glints.point
    if _exact_model(cutter, depth) or len(p) == 0:
        return p
    h = normality(p, light, eye)
    h = h / np.linalg.norm(h, axis=1, keepdims=True)
    centre = p[:, :2] + model.radius * h[:, :2]  # g = c - R h on the model's ball
    plan = np.hypot(h[:, 0], h[:, 1])
    tilt = np.arctan2(plan, h[:, 2])
    rho = _wall_offset(cutter, depth, tilt)
    with np.errstate(invalid="ignore", divide="ignore"):
        toward = np.where(plan[:, None] > 0.0, h[:, :2] / plan[:, None], 0.0)
    xy = centre - rho[:, None] * toward
    return np.column_stack([xy, -depth + _cutter_height(cutter, depth, rho)])


# ---------------------------------------------------------------------------
# Compiled: every glint against every other path


@kernel(helper=True)
def _arc_distance(px: float, py: float, ax: float, ay: float, bx: float, by: float,
                  bulge: float) -> float:
    """Plan distance from p to the arc from a to b of the given bulge, mm.

    Worked in the chord's frame, never through the centre's coordinates, so a
    nearly straight arc (a centre metres away) keeps its precision: the power
    of p about the circle over |p - c| + radius is p's distance to the circle.
    """
    dx, dy = bx - ax, by - ay
    chord = math.sqrt(dx * dx + dy * dy)
    if chord == 0.0:
        ex, ey = px - ax, py - ay
        return math.sqrt(ex * ex + ey * ey)
    tx, ty = dx / chord, dy / chord
    mx, my = px - 0.5 * (ax + bx), py - 0.5 * (ay + by)
    u = mx * tx + my * ty  # along the chord from its middle
    v = -mx * ty + my * tx  # to its left
    half = 0.5 * chord
    if abs(bulge) < LINE_BULGE:
        w = abs(u) - half
        return math.sqrt(w * w + v * v) if w > 0.0 else abs(v)
    k = chord * (1.0 - bulge * bulge) / (4.0 * bulge)  # the centre: k to the chord's left
    radius = chord * (1.0 + bulge * bulge) / (4.0 * abs(bulge))
    # p's side of the rays from the centre through a and through b, signed with
    # the sweep: within the arc's angles iff inside both (minor arc) or either
    # (major arc).
    s = 1.0 if bulge > 0.0 else -1.0
    ca = s * (k * (u + half) - half * v)
    cb = s * (k * (half - u) - half * v)
    inside = (ca >= 0.0 and cb >= 0.0) if abs(bulge) <= 1.0 else (ca >= 0.0 or cb >= 0.0)
    if inside:
        power = u * u + v * v - half * half - 2.0 * v * k
        w = v - k
        return abs(power) / (math.sqrt(u * u + w * w) + radius)
    ex, ey = px - ax, py - ay
    fx, fy = px - bx, py - by
    return math.sqrt(min(ex * ex + ey * ey, fx * fx + fy * fy))


# Not inline="always": numba would type and compile it again at each of
# _sweep's three calls (seconds on a first run), and a call per box costs
# nothing beside the cells it scans.
@kernel(helper=True)
def _visit(lo_x: float, lo_y: float, hi_x: float, hi_y: float, path: int, ax: float,
           ay: float, bx: float, by: float, bulge: float, qx: np.ndarray, qy: np.ndarray,
           qr: np.ndarray, qpath: np.ndarray, ptr: np.ndarray, x0: float, y0: float,
           size: float, nx: int, ny: int, removed: np.ndarray, cut: CutDepths,
           hits: Hits) -> None:
    """Mark the glints in the cells under the box that the arc (a, b, bulge) removes.

    ``cut``: (qz, depths, profile) where the paths' depths differ (each glint's
    removal radius then depends on the path cutting), else three empty arrays
    and each glint's radius is ``qr``. ``hits``: (mode, at, dest), see :data:`Hits`."""
    qz, depths, profile = cut
    i0 = max(int(math.floor((lo_x - x0) / size)), 0)
    i1 = min(int(math.floor((hi_x - x0) / size)), nx - 1)
    j0 = max(int(math.floor((lo_y - y0) / size)), 0)
    j1 = min(int(math.floor((hi_y - y0) / size)), ny - 1)
    for i in range(i0, i1 + 1):
        for c in range(i * ny + j0, i * ny + j1 + 1):
            for g in range(ptr[c], ptr[c + 1]):
                if removed[g] or qpath[g] == path:
                    continue
                r = qr[g] if depths.size == 0 else _removal_at(qz[g] + depths[path], profile)
                x, y = qx[g], qy[g]
                if x < lo_x or x > hi_x or y < lo_y or y > hi_y:
                    continue
                if _arc_distance(x, y, ax, ay, bx, by, bulge) < r:
                    mode, at, dest = hits
                    if mode == MARK:
                        removed[g] = True
                    else:
                        if mode == FILL:
                            dest[at[path]] = g
                        at[path] += 1


@kernel(nogil=True)
def _sweep(first: int, stop: int, vertices: np.ndarray, bulges: np.ndarray,
           offsets: np.ndarray, qx: np.ndarray, qy: np.ndarray, qr: np.ndarray, qpath: np.ndarray,
           ptr: np.ndarray, x0: float, y0: float, size: float, nx: int, ny: int, reach: float,
           removed: np.ndarray, cut: CutDepths, hits: Hits) -> None:
    """Mark every glint (sorted by grid cell) that the sweep of one of paths
    first .. stop - 1, not its own, holds (or count or list them: ``hits``).

    Each arc is visited in pieces of at most ``size`` along it: a piece's box,
    grown by its sagitta and by ``reach`` (the largest removal radius), covers
    every glint the piece can remove, and the test itself is against the whole
    arc. A flag is only ever set, so threads racing on one agree: run over
    chunks of the paths on threads (:func:`~specholo._threads.chunked`).
    """
    for q in range(first, stop):
        a, b = offsets[q], offsets[q + 1]
        if b - a == 1:  # a dot: one plunge
            vx, vy = vertices[a, 0], vertices[a, 1]
            _visit(vx - reach, vy - reach, vx + reach, vy + reach, q, vx, vy, vx, vy, 0.0,
                   qx, qy, qr, qpath, ptr, x0, y0, size, nx, ny, removed, cut, hits)
            continue
        for i in range(a, b - 1):
            ax, ay = vertices[i, 0], vertices[i, 1]
            bx, by = vertices[i + 1, 0], vertices[i + 1, 1]
            beta = bulges[i]
            dx, dy = bx - ax, by - ay
            chord = math.sqrt(dx * dx + dy * dy)
            t = abs(beta)
            sweep = 4.0 * math.atan(beta)
            length = chord if t < LINE_BULGE else chord * math.atan(t) * (1.0 + t * t) / t
            # (Longer pieces past the cap only widen their boxes: still every
            # glint within reach, in more cells.)
            pieces = max(1, int(min(math.ceil(length / size), MAX_PIECES)))
            if pieces == 1:
                pad = 0.5 * chord * t + reach  # the sagitta bounds the bulge
                _visit(min(ax, bx) - pad, min(ay, by) - pad, max(ax, bx) + pad,
                       max(ay, by) + pad, q, ax, ay, bx, by, beta, qx, qy, qr, qpath, ptr,
                       x0, y0, size, nx, ny, removed, cut, hits)
                continue
            # Piece ends from the start along the chord of each partial sweep,
            # 2 rho sin(phi / 2) long and turned phi / 2 from the start tangent.
            theta = math.atan2(dy, dx) - 0.5 * sweep
            rho = chord * (1.0 + t * t) / (4.0 * t) if t >= LINE_BULGE else 0.0
            step = sweep / pieces
            sag = rho * (1.0 - math.cos(0.5 * step)) if t >= LINE_BULGE else 0.0
            pad = sag + reach
            sx, sy = ax, ay
            for m in range(1, pieces + 1):
                if m == pieces:
                    ex, ey = bx, by
                elif t < LINE_BULGE:
                    ex, ey = ax + dx * m / pieces, ay + dy * m / pieces
                else:
                    phi = step * m
                    ln = 2.0 * rho * abs(math.sin(0.5 * phi))
                    ex = ax + ln * math.cos(theta + 0.5 * phi)
                    ey = ay + ln * math.sin(theta + 0.5 * phi)
                _visit(min(sx, ex) - pad, min(sy, ey) - pad, max(sx, ex) + pad,
                       max(sy, ey) + pad, q, ax, ay, bx, by, beta, qx, qy, qr, qpath, ptr,
                       x0, y0, size, nx, ny, removed, cut, hits)
                sx, sy = ex, ey


_NONE_INT = np.zeros(0, dtype=np.int64)


class _Grid:
    """Glints sorted into cells a few removal radii wide, and the sweep over them."""

    def __init__(self, grooves: Grooves, points: np.ndarray, radius: np.ndarray,
                 path: np.ndarray) -> None:
        g = len(points)
        self.reach = reach = float(radius.max())
        lo, hi = points[:, :2].min(axis=0) - reach, points[:, :2].max(axis=0) + reach
        # Cells a few removal radii wide: a piece of arc then visits a handful of
        # cells holding few glints it cannot reach. Larger when the glints are
        # sparse on a wide plate, so the grid stays a few cells per glint.
        size = max(4.0 * reach, MIN_CELL)
        span = hi - lo
        size = max(size, math.sqrt(float(span[0] * span[1]) / (CELLS_PER_GLINT * g + 1024)),
                   float(span.max()) / 65536.0)
        self.nx, self.ny = (int(v) for v in np.floor(span / size).astype(np.int64) + 1)
        ij = np.floor((points[:, :2] - lo) / size).astype(np.int64)
        self.cell = ij[:, 0] * self.ny + ij[:, 1]
        self.lo, self.size = lo, size
        f = np.ascontiguousarray
        self.points, self.radius = points, radius
        self.path = np.asarray(path, dtype=np.int64)
        self.vertices = f(grooves.vertices, dtype=float)
        self.bulges = f(grooves.bulges, dtype=float)
        self.offsets = f(grooves.offsets, dtype=np.int64)

    def sweep(self, glints: np.ndarray, first: int, stop: int, cut: CutDepths,
              hits: Hits) -> tuple[np.ndarray, np.ndarray]:
        """Sweep paths first .. stop - 1 over the given glints (indices).

        Returns:
            The glints in the order the sweep saw them (what ``hits`` lists),
            and which of them it marked removed.
        """
        f = np.ascontiguousarray
        ptr, order = _by_cell(self.cell[glints], self.nx * self.ny)
        live = glints[order]
        removed = np.zeros(len(live), dtype=np.bool_)
        chunked(_sweep, first, stop, self.vertices, self.bulges, self.offsets,
                f(self.points[live, 0]), f(self.points[live, 1]), f(self.radius[live]),
                f(self.path[live]), ptr, float(self.lo[0]), float(self.lo[1]),
                float(self.size), self.nx, self.ny, self.reach, removed,
                cut if cut[1].size == 0 else (f(cut[0][live]), cut[1], cut[2]), hits)
        return live, removed


@kernel()
def _by_cell(cell: np.ndarray, cells: int) -> tuple[np.ndarray, np.ndarray]:
    """Counting sort: ptr (cells + 1,) and the items (g,) in cell order (stable)."""
    count = np.zeros(cells + 1, np.int64)
    for c in cell:
        count[c + 1] += 1
    for c in range(cells):
        count[c + 1] += count[c]
    order = np.empty(cell.size, np.int64)
    at = count[:-1].copy()
    for g in range(cell.size):
        order[at[cell[g]]] = g
        at[cell[g]] += 1
    return count, order


def survivors(grooves: Grooves, points: np.ndarray, path: np.ndarray, cutter: Any,
              depth: float | np.ndarray) -> np.ndarray:
    """Which wall points survive the cuts of every other path.

    Args:
        grooves: all grooves cut into the plate.
        points: (g, 3) points on the walls, mm (a glint on its own groove's wall).
        path: (g,) the path whose wall each point is on (its own cut is not tested).
        cutter: the tool (see :func:`removal_radius`).
        depth: groove depth, mm; or (n_paths,) the depth each path is cut to
            (not for a laser, whose trough's shape goes with its depth).

    Returns:
        (g,) True where no other path's swept tool holds the point.

    Raises:
        SpecholoError: per-path depths of the wrong shape, or for a laser.
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    g = len(points)
    if g == 0 or grooves.n_paths == 0:
        return np.ones(g, dtype=bool)
    none = np.zeros(0)
    cut: CutDepths = (none, none, none)
    depths = np.asarray(depth, dtype=float)
    if depths.ndim == 0:
        radius = removal_radius(cutter, float(depths), points[:, 2] + float(depths))
    else:
        if depths.shape != (grooves.n_paths,) or not np.all(np.isfinite(depths)):
            raise SpecholoError(f"path depths must be {grooves.n_paths} finite numbers, got "
                                f"shape {depths.shape}")
        profile = _profile(cutter)
        cut = (np.ascontiguousarray(points[:, 2]), np.ascontiguousarray(depths), profile)
        # each glint's radius under the deepest cut bounds its radius under any
        top = float(depths.max())
        radius = removal_radius(cutter, top, points[:, 2] + top)
    reach = float(radius.max())
    if reach <= 0.0:
        return np.ones(g, dtype=bool)
    grid = _Grid(grooves, points, radius, path)
    # The paths a batch at a time, the grid rebuilt of the glints still standing
    # in between: on a dense plate most are gone after the first batches, and
    # later arcs no longer wade through them (the pairs tested would otherwise
    # grow as the square of the stipples).
    alive = np.arange(g)
    n_paths = grooves.n_paths
    batch = max(-(-n_paths // BATCHES), MIN_BATCH)
    for first in range(0, n_paths, batch):
        stop = min(first + batch, n_paths)
        live, removed = grid.sweep(alive, first, stop, cut, (MARK, _NONE_INT, _NONE_INT))
        alive = live[~removed]
        if alive.size == 0:
            break
    keep = np.zeros(g, dtype=bool)
    keep[alive] = True
    return keep


def conflicts(grooves: Grooves, points: np.ndarray, path: np.ndarray, cutter: Any,
              depth: float) -> tuple[np.ndarray, np.ndarray]:
    """Every (wall point, other path) pair where the path's cut removes the point.

    What :func:`survivors` decides for each point, with every path that
    decides it: a point survives exactly when it is in no pair.

    Args:
        grooves, points, path, cutter: as for :func:`survivors`.
        depth: groove depth, mm.

    Returns:
        point (m,) and path (m,): the pairs, sorted by point, then path.
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    none = np.zeros(0, dtype=np.int64)
    if len(points) == 0 or grooves.n_paths == 0:
        return none, none
    radius = removal_radius(cutter, float(depth), points[:, 2] + float(depth))
    if float(radius.max()) <= 0.0:
        return none, none
    grid = _Grid(grooves, points, radius, path)
    empty = np.zeros(0)
    n_paths = grooves.n_paths
    # Counted first, then listed: each path writes its own slice.
    count = np.zeros(n_paths, dtype=np.int64)
    grid.sweep(np.arange(len(points)), 0, n_paths, (empty, empty, empty),
               (COUNT, count, none))
    start = np.concatenate([[0], np.cumsum(count)]).astype(np.int64)
    dest = np.empty(int(start[-1]), dtype=np.int64)
    live, _ = grid.sweep(np.arange(len(points)), 0, n_paths, (empty, empty, empty),
                         (FILL, start[:-1].copy(), dest))
    point = live[dest]
    by = np.repeat(np.arange(n_paths, dtype=np.int64), count)
    order = np.lexsort((by, point))
    point, by = point[order], by[order]
    # A point near where two arcs (or two pieces of one) meet is found by each.
    first = np.ones(len(point), dtype=bool)
    first[1:] = (point[1:] != point[:-1]) | (by[1:] != by[:-1])
    return point[first], by[first]


# ---------------------------------------------------------------------------
# Verification of the plate as cut


@dataclass(frozen=True)
class AsCut:
    """What each head sees on the plate as cut.

    Attributes:
        reports: per head azimuth, the figures of
            :func:`~specholo.simulation.verify.verify` on the surviving glints.
        glints: (k, 2) designed glints of the left and right eye per azimuth.
        surviving: (k, 2) how many of them survive the other cuts.
    """

    reports: list[ViewReport]
    glints: np.ndarray
    surviving: np.ndarray

    @property
    def stereo_visibility(self) -> np.ndarray:
        """(k,) share of the stipples seen by both eyes that glint in both, per azimuth."""
        return np.array([r.visibility for r in self.reports], dtype=float)

    def mean_and_lowest(self) -> tuple[float, float, float] | None:
        """Mean and lowest stereo visibility over the azimuths, and the azimuth
        (degrees) of the lowest; None when no azimuth sees a stipple."""
        vis = self.stereo_visibility
        ok = np.flatnonzero(~np.isnan(vis))
        if ok.size == 0:
            return None
        low = int(ok[np.argmin(vis[ok])])
        return float(vis[ok].mean()), float(vis[low]), float(self.reports[low].azimuth)

    def describe(self) -> str:
        """One sentence: the share of the stipples both eyes see on the cut plate."""
        figures = self.mean_and_lowest()
        if figures is None:
            return ""
        mean, low, at = figures
        return (f"as cut, about {mean:.0%} of the stipples show in both eyes at any view "
                f"(lowest {low:.0%} at {at:+.0f} deg)")


@dataclass(frozen=True)
class EyeGlints:
    """Every eye's designed glints on the ideal grooves, eye after eye.

    Attributes:
        azimuths: (k,) head azimuths, radians.
        eyes: per azimuth, the (left, right) eye positions, (3,) each.
        sizes: (2 k,) glints of the left then right eye of each azimuth, in order.
        point: (m, 3) where each glint sits on its real wall, mm.
        path: (m,) the path it is on; stipple: (m,) the stipple it shows.
        brightness: (m,) how bright it is (:attr:`~specholo.simulation.glints.Glints.brightness`).
    """

    azimuths: np.ndarray
    eyes: list[tuple[np.ndarray, np.ndarray]]
    sizes: np.ndarray
    point: np.ndarray
    path: np.ndarray
    stipple: np.ndarray
    brightness: np.ndarray | None = None

    @property
    def slot(self) -> np.ndarray:
        """(m,) each glint's eye: 2 j for the left eye of azimuth j, 2 j + 1 the right."""
        return np.repeat(np.arange(len(self.sizes), dtype=np.int64), self.sizes)

    def seen_by(self, points: np.ndarray, visible: VisibilityFn | None) -> np.ndarray:
        """(2 k, n) whether each eye (in :attr:`slot` order) sees each stipple past the model."""
        n = len(points)
        seen = np.ones((len(self.sizes), n), dtype=bool)
        if visible is None or n == 0:
            return seen
        for j, pair in enumerate(self.eyes):
            for side, eye in enumerate(pair):
                seen[2 * j + side] = visible(points, np.broadcast_to(eye, (n, 3)))
        return seen


def eye_glints(grooves: Grooves, points: np.ndarray, setup: Setup, cutter: Any,
               depth: float, azimuths: np.ndarray,
               chunk_vertices: int = CHUNK_VERTICES) -> EyeGlints:
    """Each eye's designed glints, found on the ideal grooves as
    :func:`~specholo.simulation.verify.verify` finds them, on the real walls."""
    n = len(points)
    eyes = [tuple(e[0] for e in setup.viewer.stereo(np.array([theta]))) for theta in azimuths]
    k = len(azimuths)
    # Every eye's glints first (a few per stipple and eye): the survival test
    # then streams the grooves once for all of them.
    found: list[list[Glints]] = [[] for _ in range(2 * k)]
    for _, _, paths in _chunks(grooves, n, chunk_vertices):
        part = grooves.take(paths) if len(paths) != grooves.n_paths else grooves
        eng = Engraved.from_grooves(part, setup.tool)
        for j, pair in enumerate(eyes):
            for side, eye in enumerate(pair):
                gl = find_glints(eng, eye, setup.light)
                point = on_real_wall(gl, setup.tool, cutter, depth, setup.light, eye)
                found[2 * j + side].append(Glints(paths[gl.path], gl.stipple, point,
                                                  gl.brightness))
        del eng
    per_eye = [_join(parts) for parts in found]
    return EyeGlints(np.asarray(azimuths, dtype=float), eyes,  # type: ignore[arg-type]
                     np.array([len(gl.path) for gl in per_eye], dtype=np.int64),
                     np.concatenate([gl.point for gl in per_eye]).reshape(-1, 3),
                     np.concatenate([gl.path for gl in per_eye]).astype(np.int64),
                     np.concatenate([gl.stipple for gl in per_eye]).astype(np.int64),
                     np.concatenate([_brightness(gl) for gl in per_eye]))


def as_cut_report(glints: EyeGlints, keep: np.ndarray, points: np.ndarray,
                  seen: np.ndarray) -> AsCut:
    """The figures per azimuth of the glints kept (``keep``, (m,)), as
    :func:`~specholo.simulation.verify.verify` gives them for all; ``seen``
    is :meth:`EyeGlints.seen_by`."""
    k = len(glints.azimuths)
    bounds = np.concatenate([[0], np.cumsum(glints.sizes)])
    reports = []
    counts = np.zeros((k, 2), dtype=np.int64)
    for j, theta in enumerate(glints.azimuths):
        side = []
        for s in (0, 1):
            sl = slice(bounds[2 * j + s], bounds[2 * j + s + 1])
            m = keep[sl]
            side.append(Glints(glints.path[sl][m], glints.stipple[sl][m], glints.point[sl][m],
                               None if glints.brightness is None else glints.brightness[sl][m]))
            counts[j, s] = int(m.sum())
        eye_l, eye_r = glints.eyes[j]
        reports.append(view_report(float(theta), points, side[0], side[1], eye_l, eye_r,
                                   seen[2 * j], seen[2 * j + 1]))
    return AsCut(reports, glints.sizes.reshape(k, 2), counts)


def verify_as_cut(grooves: Grooves, points: np.ndarray, setup: Setup, cutter: Any,
                  depth: float, visible: VisibilityFn | None = None,
                  azimuths: np.ndarray | None = None,
                  chunk_vertices: int = CHUNK_VERTICES,
                  path_depths: np.ndarray | None = None) -> AsCut:
    """:func:`~specholo.simulation.verify.verify` on the plate as cut.

    Each eye's designed glints are found on the ideal grooves, those some other
    path's cut removes are dropped (:func:`survivors`), and the rest are
    measured as the ideal verification measures all of them, with the same
    denominator (the stipples unoccluded for both eyes).

    Args:
        grooves: the grooves cut.
        points: (n, 3) stipple points the grooves should show.
        setup: light and viewer, and the ball model the glints are found on.
        cutter: the real tool; depth: the groove depth, mm.
        visible: occlusion test; None means every stipple is unoccluded.
        azimuths: head azimuths in radians; default every <= 5 degrees over the range.
        chunk_vertices: groove vertices searched for glints at once (memory grows with it).
        path_depths: (n_paths,) the depth each path is really cut to, mm, where
            it strays from ``depth`` (a machine's Z, a drag spring's force):
            each glint moves down or up with its groove, and one whose wall
            would stand above the plate is gone.

    Returns:
        Per azimuth, the reports and the glint counts.
    """
    points = np.asarray(points, dtype=float)
    if azimuths is None:
        azimuths = view_azimuths(setup.viewer.half_range)
    gl = eye_glints(grooves, points, setup, cutter, depth, azimuths, chunk_vertices)
    at, on = gl.point, gl.path
    if path_depths is None:
        keep = survivors(grooves, at, on, cutter, depth)
    else:
        cut_to = np.asarray(path_depths, dtype=float)
        if cut_to.shape != (grooves.n_paths,):
            raise SpecholoError(f"path depths must be {grooves.n_paths} numbers, got shape "
                                f"{cut_to.shape}")
        lift = at[:, 2] + depth  # the glint's height above its own groove's tip
        moved = np.column_stack([at[:, :2], lift - cut_to[on]])
        keep = survivors(grooves, moved, on, cutter, cut_to) & (lift <= cut_to[on])
    return as_cut_report(gl, keep, points, gl.seen_by(points, visible))


def _join(parts: list[Glints]) -> Glints:
    """One eye's glints from the stipple chunks (which come in stipple order)."""
    if not parts:
        return Glints(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)),
                      np.zeros(0))
    return Glints(np.concatenate([p.path for p in parts]),
                  np.concatenate([p.stipple for p in parts]),
                  np.concatenate([p.point for p in parts]),
                  np.concatenate([_brightness(p) for p in parts]))


def _brightness(glints: Glints) -> np.ndarray:
    """(g,) the glints' brightness, or ones where it is unknown (all alike)."""
    return glints.brightness if glints.brightness is not None else np.ones(len(glints.path))
