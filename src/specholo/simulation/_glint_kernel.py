"""Compiled glint search on groove arcs (numba, on threads over chunks of candidate arcs).

The same physics as the numpy description in :mod:`specholo.simulation.glints`:
screen h . t at an arc's ends on the toolpath, then bracket the root of h . t on
the groove wall and refine it by Illinois regula falsi. One pass per arc keeps
every intermediate in registers instead of a dozen (k, 3) temporaries per step.
"""

from __future__ import annotations

import math

import numpy as np

from specholo._compiling import kernel
from specholo._sort import stable_argsort
from specholo._threads import chunked

#: Screen tolerance: an end within this fraction of |h| of a root is kept.
SCREEN = 0.01
#: h . t within this fraction of |h| of 0 at an arc's end is a root on its
#: vertex (the rounding of h . t is ~1e-16 |h|; a root 1e-12 along an arc is
#: a picometre from its end).
ON_VERTEX = 1e-12
#: Fixed-point steps placing the glint on the groove wall (see wall_glint).
WALL_STEPS = 3
#: Joins turning less than this (radians) are smooth: a tangent-continuous join
#: has the same h . t on both sides, so it cannot glint as a corner (it would
#: only double the glint of the arc that starts there).
SMOOTH = 1e-9
#: Fewest arcs per thread worth a thread's start (a few microseconds).
_GRAIN = 2048


@kernel()
def _h(gx: float, gy: float, gz: float, eye: np.ndarray, light: np.ndarray,
       point: bool) -> tuple[float, float, float]:
    """Normality vector u(light - g) + u(eye - g) (not normalised)."""
    if point:
        ax, ay, az = light[0] - gx, light[1] - gy, light[2] - gz
        n = math.sqrt(ax * ax + ay * ay + az * az)
        ax, ay, az = ax / n, ay / n, az / n
    else:
        ax, ay, az = light[0], light[1], light[2]
    bx, by, bz = eye[0] - gx, eye[1] - gy, eye[2] - gz
    m = math.sqrt(bx * bx + by * by + bz * bz)
    return ax + bx / m, ay + by / m, az + bz / m


@kernel(helper=True)
def _wall(px: float, py: float, radius: float, cz: float, eye: np.ndarray,
          light: np.ndarray, point: bool) -> tuple[float, float, float, float, float, float]:
    """Glint point on the ball-end wall about toolpath point p, and h there."""
    gx, gy, gz = px, py, 0.0
    for _ in range(WALL_STEPS):
        hx, hy, hz = _h(gx, gy, gz, eye, light, point)
        n = math.sqrt(hx * hx + hy * hy + hz * hz)
        gx, gy, gz = px - radius * hx / n, py - radius * hy / n, cz - radius * hz / n
    hx, hy, hz = _h(gx, gy, gz, eye, light, point)
    return gx, gy, gz, hx, hy, hz


@kernel(helper=True)
def _wall_shift(px: float, py: float, reach: float, eye: np.ndarray, light: np.ndarray,
                point: bool) -> float:
    """A bound on how much h . t can change between toolpath point p and any
    wall point within ``reach`` of it (what :func:`_wall` moves it by at most).

    A unit vector u(a) moves by at most 2 |a - b| / |a| when a becomes b, and
    h sums the unit vectors to the eye and to a point light; t is a unit
    vector. The bound is doubled and padded far beyond rounding.
    """
    bx, by, bz = eye[0] - px, eye[1] - py, eye[2]
    shift = 2.0 * reach / math.sqrt(bx * bx + by * by + bz * bz)
    if point:
        ax, ay, az = light[0] - px, light[1] - py, light[2]
        shift += 2.0 * reach / math.sqrt(ax * ax + ay * ay + az * az)
    return 2.0 * shift + 1e-12


@kernel(helper=True)
def _tilt_ok(hx: float, hy: float, hz: float, cos_tilt: float) -> bool:
    return hz >= cos_tilt * math.sqrt(hx * hx + hy * hy + hz * hz)


@kernel(helper=True)
def _at_row(geo: np.ndarray, i: int, u: float) -> tuple[float, float, float, float]:
    """Point and unit tangent at parameter u of packed row i (see :func:`index_arcs`)."""
    r = geo[i, 2]
    if r > 0.0:
        sweep = geo[i, 4]
        ang = geo[i, 3] + u * sweep
        c, s = math.cos(ang), math.sin(ang)
        sg = 1.0 if sweep > 0.0 else (-1.0 if sweep < 0.0 else 0.0)
        return geo[i, 0] + r * c, geo[i, 1] + r * s, -sg * s, sg * c
    return (geo[i, 0] + u * (geo[i, 3] - geo[i, 0]), geo[i, 1] + u * (geo[i, 4] - geo[i, 1]),
            geo[i, 5], geo[i, 6])


def arc_glints(rows: np.ndarray, geo: np.ndarray, tool_radius: float, depth: float,
               max_tilt: float, eye: np.ndarray, light: np.ndarray, point: bool,
               iterations: int) -> tuple[np.ndarray, np.ndarray]:
    """Glints on candidate arcs.

    Args:
        rows: (m,) rows of ``geo`` to test, ascending (contiguous runs stream
            from memory).
        geo: (k, 7) packed arc geometry (see :func:`index_arcs`).
        tool_radius, depth: the ball-end tool.
        max_tilt: the walls' largest tilt, radians.
        eye: (3,) eye position.
        light: (3,) sun direction, or point light position when ``point``.
        point: whether the light is a point.
        iterations: regula falsi steps.

    Returns:
        ok (m,) whether row rows[j] glints, and points (m, 3) where.
    """
    m = rows.size
    ok = np.zeros(m, np.bool_)
    pts = np.empty((m, 3))
    chunked(_arc_glints, 0, m, rows, geo, tool_radius, depth, max_tilt, eye, light, point,
            iterations, ok, pts, grain=_GRAIN)
    return ok, pts


@kernel(nogil=True)
def _arc_glints(lo: int, hi: int, rows: np.ndarray, geo: np.ndarray, tool_radius: float,
                depth: float, max_tilt: float, eye: np.ndarray, light: np.ndarray,
                point: bool, iterations: int, ok: np.ndarray, pts: np.ndarray) -> None:
    """:func:`arc_glints` of rows[lo:hi] into ok and pts."""
    cz = tool_radius - depth
    cos_tilt = math.cos(max_tilt)
    reach = abs(cz) + tool_radius
    for j in range(lo, hi):
        i = rows[j]
        # Screen on the toolpath: the wall shifts h by only ~R / distance radians.
        px, py, tx, ty = _at_row(geo, i, 0.0)
        hx, hy, hz = _h(px, py, 0.0, eye, light, point)
        s0 = hx * tx + hy * ty
        tol = SCREEN * math.sqrt(hx * hx + hy * hy + hz * hz)
        qx, qy, rx, ry = _at_row(geo, i, 1.0)
        hx, hy, hz = _h(qx, qy, 0.0, eye, light, point)
        s1 = hx * rx + hy * ry
        if s0 * s1 > 0.0 and min(abs(s0), abs(s1)) >= tol:
            continue
        # Most arcs passing the screen still cannot bracket a root: if h . t
        # keeps its sign at both ends by more than the wall can change it, the
        # test below fails anyway, so skip the six h evaluations it costs.
        if s0 * s1 > 0.0 and abs(s0) > _wall_shift(px, py, reach, eye, light, point) and abs(
                s1) > _wall_shift(qx, qy, reach, eye, light, point):
            continue
        _, _, _, hx, hy, hz = _wall(px, py, tool_radius, cz, eye, light, point)
        fa = hx * tx + hy * ty
        _, _, _, hx, hy, hz = _wall(qx, qy, tool_radius, cz, eye, light, point)
        fb = hx * rx + hy * ry
        # A root on a shared vertex belongs to the arc that starts there. The two
        # arcs work h . t out there each their own way, a rounding apart: an
        # exact zero could be a hair off it with opposite signs, and both would
        # let the root go (a symmetric groove seen straight on did).
        near = ON_VERTEX * math.sqrt(hx * hx + hy * hy + hz * hz)
        if abs(fb) <= near < abs(fa) or not (abs(fa) <= near or fa * fb < 0.0):
            continue
        a, b, side, u = 0.0, 1.0, 0.0, 0.0
        for _ in range(iterations):
            u = a if fa == fb else (a * fb - b * fa) / (fb - fa)
            px, py, tx, ty = _at_row(geo, i, u)
            _, _, _, hx, hy, hz = _wall(px, py, tool_radius, cz, eye, light, point)
            fu = hx * tx + hy * ty
            if fa * fu > 0.0:
                a, fa = u, fu
                if side > 0.0:
                    fb *= 0.5  # Illinois: keep the stale end moving
                side = 1.0
            else:
                b, fb = u, fu
                if side < 0.0:
                    fa *= 0.5
                side = -1.0
        u = min(max(u, 0.0), 1.0)
        px, py, tx, ty = _at_row(geo, i, u)
        gx, gy, gz, hx, hy, hz = _wall(px, py, tool_radius, cz, eye, light, point)
        if _tilt_ok(hx, hy, hz, cos_tilt):
            ok[j] = True
            pts[j, 0], pts[j, 1], pts[j, 2] = gx, gy, gz


def corner_glints(rows: np.ndarray, geo: np.ndarray, tool_radius: float, depth: float,
                  max_tilt: float, eye: np.ndarray, light: np.ndarray,
                  point: bool) -> tuple[np.ndarray, np.ndarray]:
    """Glints at corners: rows (m, 2) of ``geo`` holding each arc and the next
    arc of its path.

    The ball sweeps every direction between the two tangents, so the corner
    glints when h . t changes sign across it. Arguments as :func:`arc_glints`.

    Returns:
        ok (m,) and points (m, 3).
    """
    m = rows.shape[0]
    ok = np.zeros(m, np.bool_)
    pts = np.zeros((m, 3))
    chunked(_corner_glints, 0, m, rows, geo, tool_radius, depth, max_tilt, eye, light, point,
            ok, pts, grain=_GRAIN)
    return ok, pts


@kernel(nogil=True)
def _corner_glints(lo: int, hi: int, rows: np.ndarray, geo: np.ndarray, tool_radius: float,
                   depth: float, max_tilt: float, eye: np.ndarray, light: np.ndarray,
                   point: bool, ok: np.ndarray, pts: np.ndarray) -> None:
    """:func:`corner_glints` of rows[lo:hi] into ok and pts."""
    cz = tool_radius - depth
    cos_tilt = math.cos(max_tilt)
    for j in range(lo, hi):
        px, py, tx, ty = _at_row(geo, rows[j, 0], 1.0)
        qx, qy, nx, ny = _at_row(geo, rows[j, 1], 0.0)
        hx, hy, hz = _h(px, py, 0.0, eye, light, point)
        e1 = hx * tx + hy * ty
        hx2, hy2, _ = _h(qx, qy, 0.0, eye, light, point)
        e0 = hx2 * nx + hy2 * ny
        if e1 * e0 > 0.0 and abs(e1) >= SCREEN * math.sqrt(hx * hx + hy * hy + hz * hz):
            continue
        gx, gy, gz, hx, hy, hz = _wall(px, py, tool_radius, cz, eye, light, point)
        fe = hx * tx + hy * ty
        _, _, _, kx, ky, _ = _wall(qx, qy, tool_radius, cz, eye, light, point)
        fs = kx * nx + ky * ny
        if fe * fs < 0.0 and _tilt_ok(hx, hy, hz, cos_tilt):
            ok[j] = True
            pts[j, 0], pts[j, 1], pts[j, 2] = gx, gy, gz


@kernel(helper=True)
def _arc(sx: float, sy: float, ex: float, ey: float, b: float,
         line_bulge: float) -> tuple[float, float, float, float, float, float, float, float,
                                     float]:
    """One arc from its ends and bulge: centre x, y (the start for straight
    segments), radius (0: straight), start angle, sweep, chord direction x, y,
    chord length and the tangent's angle at the start."""
    cx, cy = ex - sx, ey - sy
    n = math.sqrt(cx * cx + cy * cy)
    dx = cx / n if n > 0.0 else cx
    dy = cy / n if n > 0.0 else cy
    r = n * (1.0 + b * b) / (4.0 * abs(b)) if b != 0.0 else math.inf
    if abs(b) < line_bulge or not math.isfinite(r):
        return sx, sy, 0.0, 0.0, 0.0, dx, dy, n, math.atan2(dy, dx)
    offset = (1.0 - b * b) / (4.0 * b)
    # The centre lies off the chord's middle, to its left for b > 0.
    ox = 0.5 * (sx + ex) - cy * offset
    oy = 0.5 * (sy + ey) + cx * offset
    a0 = math.atan2(sy - oy, sx - ox)
    return ox, oy, r, a0, 4.0 * math.atan(b), dx, dy, n, a0 + 0.5 * math.pi


def _corners(t_start: np.ndarray, sweep: np.ndarray, path: np.ndarray, wide: float,
             turn: np.ndarray) -> np.ndarray:
    """Whether the path turns at the end of each arc (k,); sets ``turn`` to
    infinity for arcs at a corner wider than ``wide``."""
    kinked = np.zeros(t_start.size, np.bool_)
    chunked(_corners_of, 0, t_start.size, t_start, sweep, path, wide, turn, kinked,
            grain=_GRAIN)
    return kinked


@kernel(nogil=True)
def _corners_of(lo: int, hi: int, t_start: np.ndarray, sweep: np.ndarray, path: np.ndarray,
                wide: float, turn: np.ndarray, kinked: np.ndarray) -> None:
    """:func:`_corners` of arcs lo .. hi - 1 (each writes only its own kinked
    and turn)."""
    # A corner sweeps every direction between its arcs' tangents: arcs at a
    # corner wider than the index's margin are always tested.
    k = t_start.size
    for i in range(lo, hi):
        corner = False
        if i < k - 1:
            d = t_start[i + 1] - (t_start[i] + sweep[i])
            d = (d + 0.5 * math.pi) % math.pi - 0.5 * math.pi
            kinked[i] = path[i + 1] == path[i] and abs(d) > SMOOTH
            corner = path[i + 1] == path[i] and abs(d) > wide
        prev = False
        if i > 0:
            e = t_start[i] - (t_start[i - 1] + sweep[i - 1])
            e = (e + 0.5 * math.pi) % math.pi - 0.5 * math.pi
            prev = path[i] == path[i - 1] and abs(e) > wide
        if corner or prev:
            turn[i] = math.inf


def prepare(start: np.ndarray, end: np.ndarray, bulge: np.ndarray, path: np.ndarray,
            line_bulge: float, wide: float) -> tuple[np.ndarray, ...]:
    """Per-arc geometry for glint finding, in one pass.

    Args:
        start, end: (k, 2) arc end points.
        bulge: (k,) bulges; |bulge| < line_bulge counts as straight.
        path: (k,) path of each arc.
        wide: half-turn above which a corner's arcs are always tested.

    Returns:
        centre (k, 2) (start point for straight segments), radius (0 for straight),
        start_angle, sweep, direction (k, 2) of the chord, mid-arc tangent angle,
        half turn (infinite next to a corner), chord length (k,), and whether the
        path turns at the end of each arc (k,) (a corner of any size).
    """
    k = bulge.size
    centre = np.empty((k, 2))
    radius = np.empty(k)
    start_angle = np.empty(k)
    sweep = np.empty(k)
    direction = np.empty((k, 2))
    mid_tangent = np.empty(k)
    turn = np.empty(k)
    chord = np.empty(k)
    t_start = np.empty(k)
    chunked(_prepare, 0, k, start, end, bulge, line_bulge, centre, radius, start_angle, sweep,
            direction, mid_tangent, turn, chord, t_start, grain=_GRAIN)
    kinked = _corners(t_start, sweep, path, wide, turn)
    return centre, radius, start_angle, sweep, direction, mid_tangent, turn, chord, kinked


@kernel(nogil=True)
def _prepare(lo: int, hi: int, start: np.ndarray, end: np.ndarray, bulge: np.ndarray,
             line_bulge: float, centre: np.ndarray, radius: np.ndarray,
             start_angle: np.ndarray, sweep: np.ndarray, direction: np.ndarray,
             mid_tangent: np.ndarray, turn: np.ndarray, chord: np.ndarray,
             t_start: np.ndarray) -> None:
    """:func:`prepare` of arcs lo .. hi - 1, before the corners."""
    for i in range(lo, hi):
        (centre[i, 0], centre[i, 1], radius[i], start_angle[i], sweep[i], direction[i, 0],
         direction[i, 1], chord[i], t_start[i]) = _arc(start[i, 0], start[i, 1], end[i, 0],
                                                        end[i, 1], bulge[i], line_bulge)
        mid_tangent[i] = t_start[i] + 0.5 * sweep[i]
        turn[i] = 0.5 * abs(sweep[i])


@kernel()
def arcs_of(offsets: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """The first vertex (k,) and path (k,) of every arc of paths ``offsets``
    over m vertices, numbered as :meth:`~specholo.toolpaths.grooves.Grooves.segments`
    numbers them (every vertex but a path's last starts one)."""
    n_paths = offsets.size - 1
    last = np.zeros(m, np.bool_)
    for p in range(n_paths):
        v = offsets[p + 1] - 1
        last[v + m if v < 0 else v] = True
    k = m - last.sum()
    first = np.empty(k, np.int64)
    path = np.empty(k, np.int64)
    q = 0
    for p in range(n_paths):
        for v in range(offsets[p], offsets[p + 1]):
            if not last[v]:
                first[q], path[q] = v, p
                q += 1
    return first, path


def index_arcs(vertices: np.ndarray, bulges: np.ndarray, first: np.ndarray, path: np.ndarray,
               line_bulge: float, wide: float, mid: np.ndarray,
               geo: np.ndarray) -> tuple[np.ndarray, ...]:
    """What :func:`prepare` gives the arc index, and the arcs' packed geometry,
    straight from the vertices.

    Args:
        vertices: (m, 2) and bulges (m,) of the grooves.
        first: (k,) first vertex of each arc; path (k,) its path (see :func:`arcs_of`).
        line_bulge, wide: as :func:`prepare`.
        mid: (k, 2) filled with the middle of each arc's chord.
        geo: (k, 7) filled with each arc's geometry: centre x, y, radius, start
            angle, sweep for arcs; start x, y, 0, end x, y, chord direction x, y
            for straight segments (and arcs of radius 0), as :func:`prepare`
            gives them.

    Returns:
        mid-arc tangent angle, half turn, chord length (k,) and whether the path
        turns at the end of each arc (k,).
    """
    k = first.size
    mid_tangent = np.empty(k)
    turn = np.empty(k)
    chord = np.empty(k)
    t_start = np.empty(k)
    sweep = np.empty(k)
    chunked(_index_arcs, 0, k, vertices, bulges, first, line_bulge, mid, geo, mid_tangent,
            turn, chord, t_start, sweep, grain=_GRAIN)
    kinked = _corners(t_start, sweep, path, wide, turn)
    return mid_tangent, turn, chord, kinked


@kernel(nogil=True)
def _index_arcs(lo: int, hi: int, vertices: np.ndarray, bulges: np.ndarray, first: np.ndarray,
                line_bulge: float, mid: np.ndarray, geo: np.ndarray, mid_tangent: np.ndarray,
                turn: np.ndarray, chord: np.ndarray, t_start: np.ndarray,
                sweep: np.ndarray) -> None:
    """:func:`index_arcs` of arcs lo .. hi - 1, before the corners."""
    for i in range(lo, hi):
        v = first[i]
        sx, sy, ex, ey = vertices[v, 0], vertices[v, 1], vertices[v + 1, 0], vertices[v + 1, 1]
        ox, oy, r, a0, sw, dx, dy, chord[i], t_start[i] = _arc(sx, sy, ex, ey, bulges[v],
                                                              line_bulge)
        if r > 0.0:
            geo[i, 0], geo[i, 1], geo[i, 2], geo[i, 3], geo[i, 4] = ox, oy, r, a0, sw
            geo[i, 5], geo[i, 6] = 0.0, 0.0
        else:
            geo[i, 0], geo[i, 1], geo[i, 2], geo[i, 3], geo[i, 4] = sx, sy, 0.0, ex, ey
            geo[i, 5], geo[i, 6] = dx, dy
        sweep[i] = sw
        mid[i, 0], mid[i, 1] = 0.5 * (sx + ex), 0.5 * (sy + ey)
        mid_tangent[i] = t_start[i] + 0.5 * sw
        turn[i] = 0.5 * abs(sw)


def extent(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lower-left and upper-right corners (2,) of points (k, 2), k > 0, as
    numpy's min and max along axis 0 give them (NaN if any coordinate is)."""
    k = xy.shape[0]
    chunks = min(k, 64)
    lo = np.empty((chunks, 2))
    hi = np.empty((chunks, 2))
    chunked(_extent, 0, chunks, xy, lo, hi)
    out_lo, out_hi = lo[0].copy(), hi[0].copy()
    for c in range(1, chunks):
        for d in range(2):
            if out_lo[d] == out_lo[d] and not lo[c, d] >= out_lo[d]:
                out_lo[d] = lo[c, d]
            if out_hi[d] == out_hi[d] and not hi[c, d] <= out_hi[d]:
                out_hi[d] = hi[c, d]
    return out_lo, out_hi


@kernel(nogil=True)
def _extent(first: int, stop: int, xy: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> None:
    """:func:`extent` of chunks first .. stop - 1 of lo.shape[0] into lo and hi."""
    k, chunks = xy.shape[0], lo.shape[0]
    for c in range(first, stop):
        a, b = c * k // chunks, (c + 1) * k // chunks
        for d in range(2):
            x0 = x1 = xy[a, d]
            for i in range(a + 1, b):
                x = xy[i, d]
                # "not >=" is also true for NaN, which then sticks.
                if x0 == x0 and not x >= x0:
                    x0 = x
                if x1 == x1 and not x <= x1:
                    x1 = x
            lo[c, d], hi[c, d] = x0, x1


def gather_rows(src: np.ndarray, rows: np.ndarray, out: np.ndarray) -> None:
    """out[p] = src[rows[p]] for (n,) rows of a (k, c) array."""
    chunked(_gather_rows, 0, rows.size, src, rows, out, grain=_GRAIN)


@kernel(nogil=True)
def _gather_rows(lo: int, hi: int, src: np.ndarray, rows: np.ndarray, out: np.ndarray) -> None:
    """:func:`gather_rows` of rows lo .. hi - 1."""
    c = src.shape[1]
    for p in range(lo, hi):
        i = rows[p]
        for q in range(c):
            out[p, q] = src[i, q]


def cell_keys(mid: np.ndarray, tangent: np.ndarray, narrow: np.ndarray, origin: np.ndarray,
              size: float) -> tuple[np.ndarray, np.ndarray, int, int]:
    """Grid cell and tangent angle mod pi of arcs ``narrow`` (n,), with the
    grid's columns and rows (cells of ``size`` mm from ``origin``)."""
    n = narrow.size
    ix = np.empty(n, np.int64)
    cell = np.empty(n, np.int64)
    angle = np.empty(n)
    chunked(_cell_keys, 0, n, mid, tangent, narrow, origin, size, ix, cell, angle,
            grain=_GRAIN)
    nx = ny = 1
    if n:
        nx = int(ix.max()) + 1
        ny = int(cell.max()) + 1
    cell += ix * ny
    return cell, angle, nx, ny


@kernel(nogil=True)
def _cell_keys(lo: int, hi: int, mid: np.ndarray, tangent: np.ndarray, narrow: np.ndarray,
               origin: np.ndarray, size: float, ix: np.ndarray, iy: np.ndarray,
               angle: np.ndarray) -> None:
    """:func:`cell_keys`' column, row and angle of arcs narrow[lo:hi]."""
    for j in range(lo, hi):
        i = narrow[j]
        ix[j] = np.int64(math.floor((mid[i, 0] - origin[0]) / size))
        iy[j] = np.int64(math.floor((mid[i, 1] - origin[1]) / size))
        # numpy's float mod: fmod, then shifted into [0, pi).
        a = np.fmod(tangent[i], math.pi)
        if a != 0.0:
            if a < 0.0:
                a += math.pi
        else:
            a = 0.0
        angle[j] = a


def sort_by_cell(cell: np.ndarray, angle: np.ndarray,
                 n_cells: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sort (m,) by cell, then by angle in [0, pi).

    A counting sort over cells, then in each cell (chunks of the cells on
    threads) a counting sort over as many angle buckets as the cell has arcs
    and a small sort per bucket: linear time however many arcs a cell holds.

    Returns:
        order (m,), keys (m,) cell * 4 + angle in that order, and the distinct
        cells ascending.
    """
    first, order = _by_cell(cell, n_cells)
    keys = np.empty(cell.size)
    chunked(_sort_cells, 0, n_cells, first, order, angle, keys, grain=64)
    cells = np.flatnonzero(first[1:] > first[:-1]).astype(np.int64)
    return order, keys, cells


@kernel()
def _by_cell(cell: np.ndarray, n_cells: int) -> tuple[np.ndarray, np.ndarray]:
    """Where each cell's items start (n_cells + 1,) and the items (m,) ordered by
    cell, in order within a cell (a counting sort)."""
    m = cell.size
    count = np.zeros(n_cells + 1, np.int64)
    for i in range(m):
        count[cell[i] + 1] += 1
    first = np.cumsum(count)
    fill = first[:-1].copy()
    order = np.empty(m, np.int64)
    for i in range(m):
        c = cell[i]
        order[fill[c]] = i
        fill[c] += 1
    return first, order


@kernel(nogil=True)
def _sort_cells(c0: int, c1: int, first: np.ndarray, order: np.ndarray, angle: np.ndarray,
                keys: np.ndarray) -> None:
    """:func:`sort_by_cell` within cells c0 .. c1 - 1: each rewrites only its own
    part of order and keys."""
    for c in range(c0, c1):
        lo, hi = first[c], first[c + 1]
        n = hi - lo
        if n == 0:
            continue
        part = order[lo:hi].copy()
        # (Loops, not fancy indexing: that compiles for seconds on a first run.)
        ang = np.empty(n)
        for t in range(n):
            ang[t] = angle[part[t]]
        scale = n / math.pi
        bucket = np.empty(n, np.int64)
        at = np.zeros(n + 1, np.int64)
        for t in range(n):
            # Monotone in the angle, so buckets in order sort the angles.
            q = n - 1
            if ang[t] >= 0.0:
                q = min(int(ang[t] * scale), n - 1)
            bucket[t] = q
            at[q + 1] += 1
        for q in range(n):
            at[q + 1] += at[q]
        put = at[:-1].copy()
        sa = np.empty(n)
        si = np.empty(n, np.int64)
        for t in range(n):
            q = bucket[t]
            sa[put[q]], si[put[q]] = ang[t], part[t]
            put[q] += 1
        for q in range(n):
            a, b = at[q], at[q + 1]
            if b - a > 32:
                o = stable_argsort(sa[a:b])
                ta, ti = np.empty(b - a), np.empty(b - a, np.int64)
                for t in range(b - a):
                    ta[t], ti[t] = sa[a + o[t]], si[a + o[t]]
                for t in range(b - a):  # (not sa[a:b] = ta: slice setting compiles for seconds)
                    sa[a + t], si[a + t] = ta[t], ti[t]
            else:
                for t in range(a + 1, b):
                    x, y = sa[t], si[t]
                    u = t - 1
                    while u >= a and sa[u] > x:
                        sa[u + 1], si[u + 1] = sa[u], si[u]
                        u -= 1
                    sa[u + 1], si[u + 1] = x, y
        for t in range(n):
            order[lo + t] = si[t]
            keys[lo + t] = c * 4.0 + sa[t]


@kernel()
def merge_ranges(i0: np.ndarray, i1: np.ndarray, tail0: int,
                 tail1: int) -> tuple[np.ndarray, np.ndarray]:
    """The union of row ranges [i0, i1) (r, c), each column one cell's (cells
    ascending, so a column's ranges follow the previous column's), and
    [tail0, tail1) after them all, as sorted disjoint ranges."""
    r, c = i0.shape
    starts = np.empty(r * c + 1, np.int64)
    ends = np.empty(r * c + 1, np.int64)
    q = 0
    for j in range(c):
        lo = i0[:, j].copy()
        hi = i1[:, j].copy()
        o = stable_argsort(lo)  # (numba's quicksort compiles for seconds; any order merges alike)
        for t in range(r):
            a, b = lo[o[t]], hi[o[t]]
            if b <= a:
                continue
            # Sorted by start throughout, so only the last range can meet this one.
            if q > 0 and a <= ends[q - 1]:
                if b > ends[q - 1]:
                    ends[q - 1] = b
            else:
                starts[q], ends[q] = a, b
                q += 1
    if tail1 > tail0:
        starts[q], ends[q] = tail0, tail1
        q += 1
    return starts[:q], ends[:q]


def expand(starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """All rows of the ranges [starts, ends) (r,), in order."""
    r = starts.size
    at = np.zeros(r + 1, np.int64)
    np.cumsum(ends - starts, out=at[1:])
    rows = np.empty(at[r], np.int64)
    chunked(_expand, 0, r, starts, ends, at, rows, grain=16)
    return rows


@kernel(nogil=True)
def _expand(lo: int, hi: int, starts: np.ndarray, ends: np.ndarray, at: np.ndarray,
            rows: np.ndarray) -> None:
    """:func:`expand` of ranges lo .. hi - 1."""
    for t in range(lo, hi):
        for q in range(ends[t] - starts[t]):
            rows[at[t] + q] = starts[t] + q
