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


@nb.njit(cache=True, parallel=True)
def arc_glints(cand: np.ndarray, start: np.ndarray, end: np.ndarray, centre: np.ndarray,
               radius: np.ndarray, start_angle: np.ndarray, sweep: np.ndarray,
               direction: np.ndarray, tool_radius: float, depth: float, max_tilt: float,
               eye: np.ndarray, light: np.ndarray, point: bool,
               iterations: int) -> tuple[np.ndarray, np.ndarray]:
    """Glints on candidate arcs.

    Args:
        cand: (m,) arc indices to test.
        start, end, centre, radius, start_angle, sweep, direction: arc geometry
            as in :class:`~specholo.simulation.glints.Engraved`.
        tool_radius, depth: the ball-end tool.
        max_tilt: the walls' largest tilt, radians.
        eye: (3,) eye position.
        light: (3,) sun direction, or point light position when ``point``.
        point: whether the light is a point.
        iterations: regula falsi steps.

    Returns:
        ok (m,) whether arc cand[j] glints, and points (m, 3) where.
    """
    m = cand.size
    ok = np.zeros(m, np.bool_)
    pts = np.zeros((m, 3))
    cz = tool_radius - depth
    cos_tilt = math.cos(max_tilt)
    for j in nb.prange(m):
        i = cand[j]
        # Screen on the toolpath: the wall shifts h by only ~R / distance radians.
        px, py, tx, ty = _at(i, 0.0, start, end, centre, radius, start_angle, sweep, direction)
        hx, hy, hz = _h(px, py, 0.0, eye, light, point)
        s0 = hx * tx + hy * ty
        tol = SCREEN * math.sqrt(hx * hx + hy * hy + hz * hz)
        px, py, tx, ty = _at(i, 1.0, start, end, centre, radius, start_angle, sweep, direction)
        hx, hy, hz = _h(px, py, 0.0, eye, light, point)
        s1 = hx * tx + hy * ty
        if s0 * s1 > 0.0 and min(abs(s0), abs(s1)) >= tol:
            continue
        px, py, tx, ty = _at(i, 0.0, start, end, centre, radius, start_angle, sweep, direction)
        _, _, _, hx, hy, hz = _wall(px, py, tool_radius, cz, eye, light, point)
        fa = hx * tx + hy * ty
        px, py, tx, ty = _at(i, 1.0, start, end, centre, radius, start_angle, sweep, direction)
        _, _, _, hx, hy, hz = _wall(px, py, tool_radius, cz, eye, light, point)
        fb = hx * tx + hy * ty
        # A root exactly on a shared vertex belongs to the arc that starts there.
        if not (fa == 0.0 or fa * fb < 0.0):
            continue
        a, b, side, u = 0.0, 1.0, 0.0, 0.0
        for _ in range(iterations):
            u = a if fa == fb else (a * fb - b * fa) / (fb - fa)
            px, py, tx, ty = _at(i, u, start, end, centre, radius, start_angle, sweep,
                                 direction)
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
        px, py, tx, ty = _at(i, u, start, end, centre, radius, start_angle, sweep, direction)
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
