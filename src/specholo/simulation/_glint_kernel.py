"""Compiled glint search on groove arcs (numba, parallel over candidate arcs).

The same physics as the numpy description in :mod:`specholo.simulation.glints`:
screen h . t at an arc's ends on the toolpath, then bracket the root of h . t on
the groove wall and refine it by Illinois regula falsi. One pass per arc keeps
every intermediate in registers instead of a dozen (k, 3) temporaries per step.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

#: Screen tolerance: an end within this fraction of |h| of a root is kept.
SCREEN = 0.01
#: Fixed-point steps placing the glint on the groove wall (see wall_glint).
WALL_STEPS = 3
#: Joins turning less than this (radians) are smooth: a tangent-continuous join
#: has the same h . t on both sides, so it cannot glint as a corner (it would
#: only double the glint of the arc that starts there).
SMOOTH = 1e-9


@nb.njit(cache=True, inline="always")
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


@nb.njit(cache=True, inline="always")
def _at(i: int, u: float, start: np.ndarray, end: np.ndarray, centre: np.ndarray,
        radius: np.ndarray, start_angle: np.ndarray, sweep: np.ndarray,
        direction: np.ndarray) -> tuple[float, float, float, float]:
    """Point and unit tangent at parameter u of arc i."""
    r = radius[i]
    if r > 0.0:
        ang = start_angle[i] + u * sweep[i]
        c, s = math.cos(ang), math.sin(ang)
        sg = 1.0 if sweep[i] > 0.0 else (-1.0 if sweep[i] < 0.0 else 0.0)
        return centre[i, 0] + r * c, centre[i, 1] + r * s, -sg * s, sg * c
    return (start[i, 0] + u * (end[i, 0] - start[i, 0]),
            start[i, 1] + u * (end[i, 1] - start[i, 1]), direction[i, 0], direction[i, 1])


@nb.njit(cache=True, inline="always")
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


@nb.njit(cache=True, inline="always")
def _tilt_ok(hx: float, hy: float, hz: float, cos_tilt: float) -> bool:
    return hz >= cos_tilt * math.sqrt(hx * hx + hy * hy + hz * hz)


@nb.njit(cache=True, inline="always")
def _at_row(geo: np.ndarray, i: int, u: float) -> tuple[float, float, float, float]:
    """Point and unit tangent at parameter u of packed row i (see :func:`pack`)."""
    r = geo[i, 2]
    if r > 0.0:
        sweep = geo[i, 4]
        ang = geo[i, 3] + u * sweep
        c, s = math.cos(ang), math.sin(ang)
        sg = 1.0 if sweep > 0.0 else (-1.0 if sweep < 0.0 else 0.0)
        return geo[i, 0] + r * c, geo[i, 1] + r * s, -sg * s, sg * c
    return (geo[i, 0] + u * (geo[i, 3] - geo[i, 0]), geo[i, 1] + u * (geo[i, 4] - geo[i, 1]),
            geo[i, 5], geo[i, 6])


@nb.njit(cache=True, parallel=True)
def arc_glints(rows: np.ndarray, geo: np.ndarray, tool_radius: float, depth: float,
               max_tilt: float, eye: np.ndarray, light: np.ndarray, point: bool,
               iterations: int) -> tuple[np.ndarray, np.ndarray]:
    """Glints on candidate arcs.

    Args:
        rows: (m,) rows of ``geo`` to test, ascending (contiguous runs stream
            from memory).
        geo: (k, 7) packed arc geometry (see :func:`pack`).
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
    cz = tool_radius - depth
    cos_tilt = math.cos(max_tilt)
    for j in nb.prange(m):
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
        _, _, _, hx, hy, hz = _wall(px, py, tool_radius, cz, eye, light, point)
        fa = hx * tx + hy * ty
        _, _, _, hx, hy, hz = _wall(qx, qy, tool_radius, cz, eye, light, point)
        fb = hx * rx + hy * ry
        # A root exactly on a shared vertex belongs to the arc that starts there.
        if not (fa == 0.0 or fa * fb < 0.0):
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
    return ok, pts


@nb.njit(cache=True, parallel=True)
def corner_glints(first: np.ndarray, start: np.ndarray, end: np.ndarray, centre: np.ndarray,
                  radius: np.ndarray, start_angle: np.ndarray, sweep: np.ndarray,
                  direction: np.ndarray, tool_radius: float, depth: float, max_tilt: float,
                  eye: np.ndarray, light: np.ndarray,
                  point: bool) -> tuple[np.ndarray, np.ndarray]:
    """Glints at the corners after arcs ``first`` (m,) (each joined to the next arc).

    The ball sweeps every direction between the two tangents, so the corner
    glints when h . t changes sign across it. Arguments as :func:`arc_glints`.

    Returns:
        ok (m,) and points (m, 3).
    """
    m = first.size
    ok = np.zeros(m, np.bool_)
    pts = np.zeros((m, 3))
    cz = tool_radius - depth
    cos_tilt = math.cos(max_tilt)
    for j in nb.prange(m):
        i = first[j]
        px, py, tx, ty = _at(i, 1.0, start, end, centre, radius, start_angle, sweep, direction)
        qx, qy, nx, ny = _at(i + 1, 0.0, start, end, centre, radius, start_angle, sweep,
                             direction)
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
    return ok, pts


@nb.njit(cache=True, parallel=True)
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
    for i in nb.prange(k):
        b = bulge[i]
        cx, cy = end[i, 0] - start[i, 0], end[i, 1] - start[i, 1]
        n = math.hypot(cx, cy)
        chord[i] = n
        direction[i, 0] = cx / n if n > 0.0 else cx
        direction[i, 1] = cy / n if n > 0.0 else cy
        r = n * (1.0 + b * b) / (4.0 * abs(b)) if b != 0.0 else math.inf
        if abs(b) < line_bulge or not math.isfinite(r):
            centre[i, 0], centre[i, 1] = start[i, 0], start[i, 1]
            radius[i] = 0.0
            sweep[i] = 0.0
            start_angle[i] = 0.0
            t_start[i] = math.atan2(direction[i, 1], direction[i, 0])
        else:
            offset = (1.0 - b * b) / (4.0 * b)
            # The centre lies off the chord's middle, to its left for b > 0.
            centre[i, 0] = 0.5 * (start[i, 0] + end[i, 0]) - cy * offset
            centre[i, 1] = 0.5 * (start[i, 1] + end[i, 1]) + cx * offset
            radius[i] = r
            sweep[i] = 4.0 * math.atan(b)
            start_angle[i] = math.atan2(start[i, 1] - centre[i, 1], start[i, 0] - centre[i, 0])
            t_start[i] = start_angle[i] + 0.5 * math.pi
        mid_tangent[i] = t_start[i] + 0.5 * sweep[i]
        turn[i] = 0.5 * abs(sweep[i])
    # A corner sweeps every direction between its arcs' tangents: arcs at a
    # corner wider than the index's margin are always tested.
    kinked = np.zeros(k, np.bool_)
    for i in nb.prange(k - 1):
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
    if k > 1:
        e = t_start[k - 1] - (t_start[k - 2] + sweep[k - 2])
        e = (e + 0.5 * math.pi) % math.pi - 0.5 * math.pi
        if path[k - 1] == path[k - 2] and abs(e) > wide:
            turn[k - 1] = math.inf
    return centre, radius, start_angle, sweep, direction, mid_tangent, turn, chord, kinked


@nb.njit(cache=True, parallel=True)
def sort_by_cell(cell: np.ndarray, angle: np.ndarray, n_cells: int) -> np.ndarray:
    """Order (m,) sorting by cell, then by angle: a counting sort over cells and
    one small sort per cell, the cells shared between cores."""
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
    for c in nb.prange(n_cells):
        lo, hi = first[c], first[c + 1]
        if hi - lo > 1:
            part = order[lo:hi]
            order[lo:hi] = part[np.argsort(angle[part], kind="mergesort")]
    return order


@nb.njit(cache=True, parallel=True)
def pack(layout: np.ndarray, start: np.ndarray, end: np.ndarray, centre: np.ndarray,
         radius: np.ndarray, start_angle: np.ndarray, sweep: np.ndarray,
         direction: np.ndarray) -> np.ndarray:
    """Arc geometry in index order, one 56-byte row per arc, so a cell's
    candidates are read from memory in one run instead of one miss per array.

    Args:
        layout: (n,) arc of each row.
        start, end, centre, radius, start_angle, sweep, direction: as
            :func:`prepare` gives them, one entry per arc.

    Returns:
        (n, 7) rows: centre x, y, radius, start angle, sweep for arcs; start
        x, y, 0, end x, y, direction x, y for straight segments.
    """
    n = layout.size
    geo = np.zeros((n, 7))
    for p in nb.prange(n):
        i = layout[p]
        if radius[i] > 0.0:
            geo[p, 0], geo[p, 1] = centre[i, 0], centre[i, 1]
            geo[p, 2], geo[p, 3], geo[p, 4] = radius[i], start_angle[i], sweep[i]
        else:
            geo[p, 0], geo[p, 1] = start[i, 0], start[i, 1]
            geo[p, 3], geo[p, 4] = end[i, 0], end[i, 1]
            geo[p, 5], geo[p, 6] = direction[i, 0], direction[i, 1]
    return geo


@nb.njit(cache=True, parallel=True)
def cell_keys(mid: np.ndarray, tangent: np.ndarray, narrow: np.ndarray, origin: np.ndarray,
              size: float) -> tuple[np.ndarray, np.ndarray, int, int]:
    """Grid cell and tangent angle mod pi of arcs ``narrow`` (n,), with the
    grid's columns and rows (cells of ``size`` mm from ``origin``)."""
    n = narrow.size
    ix = np.empty(n, np.int64)
    cell = np.empty(n, np.int64)
    angle = np.empty(n)
    for j in nb.prange(n):
        i = narrow[j]
        ix[j] = np.int64(math.floor((mid[i, 0] - origin[0]) / size))
        cell[j] = np.int64(math.floor((mid[i, 1] - origin[1]) / size))
        # numpy's float mod: fmod, then shifted into [0, pi).
        a = np.fmod(tangent[i], math.pi)
        if a != 0.0:
            if a < 0.0:
                a += math.pi
        else:
            a = 0.0
        angle[j] = a
    nx = 1
    ny = 1
    if n:
        nx = int(ix.max()) + 1
        ny = int(cell.max()) + 1
    for j in nb.prange(n):
        cell[j] += ix[j] * ny
    return cell, angle, nx, ny


@nb.njit(cache=True, parallel=True)
def sorted_keys(cell: np.ndarray, angle: np.ndarray,
                order: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Keys cell * 4 + angle in ``order`` (m,), and the distinct cells."""
    m = order.size
    keys = np.empty(m)
    first = np.zeros(m, np.bool_)
    for p in nb.prange(m):
        c = cell[order[p]]
        keys[p] = c * 4.0 + angle[order[p]]
        first[p] = p == 0 or cell[order[p - 1]] != c
    cells = np.empty(first.sum(), np.int64)
    q = 0
    for p in range(m):
        if first[p]:
            cells[q] = cell[order[p]]
            q += 1
    return keys, cells


@nb.njit(cache=True)
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
        o = np.argsort(lo)
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


@nb.njit(cache=True, parallel=True)
def expand(starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """All rows of the ranges [starts, ends) (r,), in order."""
    r = starts.size
    at = np.zeros(r + 1, np.int64)
    for t in range(r):
        at[t + 1] = at[t] + ends[t] - starts[t]
    rows = np.empty(at[r], np.int64)
    for t in nb.prange(r):
        for q in range(ends[t] - starts[t]):
            rows[at[t] + q] = starts[t] + q
    return rows
