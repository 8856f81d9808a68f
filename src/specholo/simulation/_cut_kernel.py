"""Compiled parts of the cut simulation (numba).

The sweep rasterises every move's neighbourhood into a height field, parallel
over bands of rows: each band owns its rows, so no two threads write one cell,
and within a band moves are applied in program order, which makes the labels
independent of the thread count. The glint search runs Newton's method on the
analytic surface of the move that cut each cell, parallel over paths.

Moves are rows of ``geo`` (see the column constants) with a ``kind``: a straight
segment, a circular arc, or a point (a plunge). Profiles are cubic Hermite
tables on a uniform grid of distances from the tool axis.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from specholo._compiling import kernel

# Columns of ``geo``. A move's unit direction and length are not stored: they
# follow from its ends (:func:`chord`), and a kept table is a field's worth of rows.
SX, SY, EX, EY, CX, CY, RHO, SWEEP = range(8)
N_GEO = 8
# Move kinds.
LINE, ARC, POINT = 0, 1, 2
# Move flags: the path starts / ends at this move (a cap, left by plunge and
# retract), or the tangent jumps at this move's start / end (a corner).
OPEN_START, OPEN_END, CORNER_START, CORNER_END = 1, 2, 4, 8
# How a cell's surface is modelled: the swept body of a segment or arc
# (extended past its ends), a sphere left at a point (dots and corners), or
# the cap at a path's end.
BODY, SPHERE, CAP = 0, 1, 2
#: Clusters kept per path and eye.
MAX_CLUSTERS = 8


@kernel()
def chord(geo: np.ndarray, m: int) -> tuple[float, float, float]:
    """Unit direction (x, y) and length of move m's chord; (0, 0, 0) when it has none."""
    cx, cy = geo[m, EX] - geo[m, SX], geo[m, EY] - geo[m, SY]
    length = math.sqrt(cx * cx + cy * cy)
    if not length > 0.0:
        return 0.0, 0.0, 0.0
    return cx / length, cy / length, length


@kernel()
def profile(r: float, step: float, height: np.ndarray,
            slope: np.ndarray) -> tuple[float, float, float]:
    """Profile height, slope and curvature at distance r from the axis.

    Cubic Hermite on the table; past its end, the last tangent line.
    """
    n = height.size - 1
    t = r / step
    if t >= n:
        return height[n] + slope[n] * (r - n * step), slope[n], 0.0
    i = int(t)
    u = t - i
    h0, h1 = height[i], height[i + 1]
    m0, m1 = slope[i] * step, slope[i + 1] * step
    u2 = u * u
    u3 = u2 * u
    p = (2 * u3 - 3 * u2 + 1) * h0 + (u3 - 2 * u2 + u) * m0 + (3 * u2 - 2 * u3) * h1 \
        + (u3 - u2) * m1
    dp = ((6 * u2 - 6 * u) * h0 + (3 * u2 - 4 * u + 1) * m0 + (6 * u - 6 * u2) * h1
          + (3 * u2 - 2 * u) * m1) / step
    ddp = ((12 * u - 6) * h0 + (6 * u - 4) * m0 + (6 - 12 * u) * h1
           + (6 * u - 2) * m1) / (step * step)
    return p, dp, ddp


@kernel(helper=True)
def _inside_arc(vx: float, vy: float, geo: np.ndarray, m: int) -> bool:
    """Whether direction v from the arc's centre lies within its sweep."""
    cx, cy = geo[m, CX], geo[m, CY]
    ax, ay = geo[m, SX] - cx, geo[m, SY] - cy
    bx, by = geo[m, EX] - cx, geo[m, EY] - cy
    sw = geo[m, SWEEP]
    sg = 1.0 if sw > 0.0 else -1.0
    c1 = sg * (ax * vy - ay * vx)
    c2 = sg * (vx * by - vy * bx)
    if abs(sw) <= math.pi:
        return c1 >= 0.0 and c2 >= 0.0
    # Over half a turn: outside only within the (short) complementary arc.
    return not (c1 < 0.0 and c2 < 0.0)


@kernel()
def locate(geo: np.ndarray, kind: np.ndarray, m: int, px: float,
           py: float) -> tuple[float, int]:
    """Distance from p to move m, and where its closest point is.

    Returns:
        distance, and 0 (inside the move), 1 (its start, or the point of a
        plunge) or 2 (its end).
    """
    k = kind[m]
    sx, sy = geo[m, SX], geo[m, SY]
    if k == POINT:
        return math.sqrt((px - sx) ** 2 + (py - sy) ** 2), 1
    if k == LINE:
        dx, dy, length = chord(geo, m)
        t = (px - sx) * dx + (py - sy) * dy
        if t <= 0.0:
            return math.sqrt((px - sx) ** 2 + (py - sy) ** 2), 1
        if t >= length:
            return math.sqrt((px - geo[m, EX]) ** 2 + (py - geo[m, EY]) ** 2), 2
        return abs((px - sx) * dy - (py - sy) * dx), 0
    vx, vy = px - geo[m, CX], py - geo[m, CY]
    if _inside_arc(vx, vy, geo, m):
        return abs(math.sqrt(vx * vx + vy * vy) - geo[m, RHO]), 0
    d0 = math.sqrt((px - sx) ** 2 + (py - sy) ** 2)
    d1 = math.sqrt((px - geo[m, EX]) ** 2 + (py - geo[m, EY]) ** 2)
    return (d0, 1) if d0 <= d1 else (d1, 2)


@kernel(helper=True)
def _clip(k: float, c: float, lo: float, hi: float, a: float, b: float) -> tuple[float, float]:
    """Intersect [a, b] with the x where lo <= k x + c <= hi."""
    if k > 1e-12 or k < -1e-12:
        u, v = (lo - c) / k, (hi - c) / k
        if u > v:
            u, v = v, u
        return max(a, u), min(b, v)
    if lo <= c <= hi:
        return a, b
    return 1.0, 0.0


@kernel(parallel=True)
def sweep(geo: np.ndarray, kind: np.ndarray, box: np.ndarray, shape: np.ndarray,
          band_ptr: np.ndarray, band_moves: np.ndarray, band_rows: int, x0: float, y0: float,
          res: float, depth: float, r_cut: float, step: float, height: np.ndarray,
          slope: np.ndarray, base: int, z: np.ndarray, move: np.ndarray) -> None:
    """Cut every move into the height field z (ny, nx), recording the deepest move.

    Each move visits, row by row, only the columns inside its ``shape``: a
    rectangle along its chord (ax, ay, dx, dy, along lo, along hi, half width),
    or a disc (kind 1: centre ax, ay, radius in the half width column), or its
    whole box (kind 2).

    Args:
        geo, kind: the moves.
        box: (k, 4) column and row ranges i0, i1, j0, j1 (inclusive) each move may cut.
        shape: (k, 8) the region each move may cut (see above; kind in column 7).
        band_ptr: (b + 1,) CSR offsets of the moves touching each band of rows.
        band_moves: moves of each band, in program order.
        band_rows: rows per band.
        x0, y0, res: position of sample [0, 0] and the spacing, mm.
        depth: tip depth below the plate, mm.
        r_cut: distance from the toolpath beyond which the tool is above the plate.
        step, height, slope: the profile table.
        base: number of the first move (moves are recorded as base + row).
        z: (ny, nx) float32 heights, updated in place (start at 0).
        move: (ny, nx) int32 deepest move per cell, updated in place (start at -1).
    """
    ny = z.shape[0]
    for b in nb.prange(band_ptr.size - 1):
        lo = b * band_rows
        hi = min(lo + band_rows, ny) - 1
        for q in range(band_ptr[b], band_ptr[b + 1]):
            m = band_moves[q]
            ax, ay, dx, dy = shape[m, 0], shape[m, 1], shape[m, 2], shape[m, 3]
            w, form = shape[m, 6], shape[m, 7]
            for j in range(max(box[m, 2], lo), min(box[m, 3], hi) + 1):
                y = y0 + j * res
                xa, xb = x0 + box[m, 0] * res, x0 + box[m, 1] * res
                if form == 0.0:
                    # along = dx x + dy (y - ay) - dx ax; across = -dy x + dx (y - ay) + dy ax
                    xa, xb = _clip(dx, dy * (y - ay) - dx * ax, shape[m, 4], shape[m, 5],
                                   xa, xb)
                    xa, xb = _clip(-dy, dx * (y - ay) + dy * ax, -w, w, xa, xb)
                elif form == 1.0:
                    e = w * w - (y - ay) * (y - ay)
                    if e < 0.0:
                        continue
                    e = math.sqrt(e)
                    xa, xb = max(xa, ax - e), min(xb, ax + e)
                if xb < xa:
                    continue
                i0 = max(box[m, 0], int(math.ceil((xa - x0) / res)))
                i1 = min(box[m, 1], int(math.floor((xb - x0) / res)))
                _sweep_row(geo, kind, m, i0, i1, j, x0, y, res, depth, r_cut, step, height,
                           slope, base, z, move)


@kernel(helper=True)
def _sweep_row(geo: np.ndarray, kind: np.ndarray, m: int, i0: int, i1: int, j: int,
               x0: float, y: float, res: float, depth: float, r_cut: float, step: float,
               height: np.ndarray, slope: np.ndarray, base: int, z: np.ndarray,
               move: np.ndarray) -> None:
    """Cut samples i0..i1 of row j (at height y) with move m (the sweep's inner loop)."""
    k = kind[m]
    sx, sy, ex, ey = geo[m, SX], geo[m, SY], geo[m, EX], geo[m, EY]
    # Per-move constants in registers: the loop below runs ~10^8 times.
    cx, cy, rho, sw = geo[m, CX], geo[m, CY], geo[m, RHO], geo[m, SWEEP]
    dx, dy, length = chord(geo, m)
    sg = 1.0 if sw > 0.0 else -1.0
    ax, ay, bx, by = sx - cx, sy - cy, ex - cx, ey - cy
    wide = abs(sw) > math.pi
    n = height.size - 1
    inv = 1.0 / step
    for i in range(i0, i1 + 1):
        px = x0 + i * res
        if k == ARC:
            vx, vy = px - cx, y - cy
            c1 = sg * (ax * vy - ay * vx)
            c2 = sg * (vx * by - vy * bx)
            inside = (c1 >= 0.0 and c2 >= 0.0) if not wide else not (c1 < 0.0 and c2 < 0.0)
            if inside:
                r = abs(math.sqrt(vx * vx + vy * vy) - rho)
            else:
                r = math.sqrt(min((px - sx) ** 2 + (y - sy) ** 2, (px - ex) ** 2 + (y - ey) ** 2))
        elif k == LINE:
            t = (px - sx) * dx + (y - sy) * dy
            if t <= 0.0:
                r = math.sqrt((px - sx) ** 2 + (y - sy) ** 2)
            elif t >= length:
                r = math.sqrt((px - ex) ** 2 + (y - ey) ** 2)
            else:
                r = abs((px - sx) * dy - (y - sy) * dx)
        else:
            r = math.sqrt((px - sx) ** 2 + (y - sy) ** 2)
        if r >= r_cut:
            continue
        t = r * inv
        if t >= n:
            v = height[n] + slope[n] * (r - n * step)
        else:
            q = int(t)
            u = t - q
            u2 = u * u
            u3 = u2 * u
            v = ((2 * u3 - 3 * u2 + 1) * height[q] + (u3 - 2 * u2 + u) * step * slope[q]
                 + (3 * u2 - 2 * u3) * height[q + 1] + (u3 - u2) * step * slope[q + 1])
        v -= depth
        if v < z[j, i]:
            z[j, i] = v
            move[j, i] = base + m


@kernel()
def group_cells(move: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Cut cells grouped by move (a counting sort of the flat move array).

    Returns:
        ptr (k + 1,) and cells (c,) flat indices, cells of move m at ptr[m]:ptr[m + 1].
    """
    flat = move.ravel()
    count = np.zeros(k + 1, np.int64)
    for f in range(flat.size):
        if flat[f] >= 0:
            count[flat[f] + 1] += 1
    ptr = np.cumsum(count)
    fill = ptr[:-1].copy()
    cells = np.empty(ptr[-1], np.int64)
    for f in range(flat.size):
        m = flat[f]
        if m >= 0:
            cells[fill[m]] = f
            fill[m] += 1
    return ptr, cells


@kernel()
def mode_of(geo: np.ndarray, kind: np.ndarray, flags: np.ndarray, m: int, px: float,
            py: float) -> tuple[int, float, float]:
    """How the surface at p is modelled, and the sphere's centre if it is one."""
    if kind[m] == POINT:
        return SPHERE, geo[m, SX], geo[m, SY]
    _, where = locate(geo, kind, m, px, py)
    if where == 1:
        if flags[m] & OPEN_START:
            return CAP, geo[m, SX], geo[m, SY]
        if flags[m] & CORNER_START:
            return SPHERE, geo[m, SX], geo[m, SY]
    elif where == 2:
        if flags[m] & OPEN_END:
            return CAP, geo[m, EX], geo[m, EY]
        if flags[m] & CORNER_END:
            return SPHERE, geo[m, EX], geo[m, EY]
    # Inside, or at a smooth joint, where the next move continues this one.
    return BODY, 0.0, 0.0


@kernel()
def surface(geo: np.ndarray, kind: np.ndarray, m: int, mode: int, qx: float, qy: float,
            px: float, py: float, depth: float, step: float, height: np.ndarray,
            slope: np.ndarray) -> tuple[float, float, float, float, float, float]:
    """Height, gradient and Hessian of move m's swept surface at p.

    A body is the move extended past its ends (a whole line or circle), so
    Newton's method can follow a glint across a joint; a sphere or cap is the
    tool's surface about q.

    Returns:
        z, z_x, z_y, z_xx, z_xy, z_yy.
    """
    if mode != BODY:
        vx, vy = px - qx, py - qy
        r = math.sqrt(vx * vx + vy * vy)
        p, dp, ddp = profile(r, step, height, slope)
        if r < 1e-12:
            return p - depth, 0.0, 0.0, ddp, 0.0, ddp
        ux, uy = vx / r, vy / r
        k = dp / r  # the level circles' curvature times the slope
        return (p - depth, dp * ux, dp * uy, ddp * ux * ux + k * uy * uy,
                (ddp - k) * ux * uy, ddp * uy * uy + k * ux * ux)
    if kind[m] == LINE:
        tx, ty, _ = chord(geo, m)
        nx, ny = -ty, tx
        s = (px - geo[m, SX]) * nx + (py - geo[m, SY]) * ny
        p, dp, ddp = profile(abs(s), step, height, slope)
        sg = 1.0 if s >= 0.0 else -1.0
        return p - depth, sg * dp * nx, sg * dp * ny, ddp * nx * nx, ddp * nx * ny, \
            ddp * ny * ny
    vx, vy = px - geo[m, CX], py - geo[m, CY]
    dist = math.sqrt(vx * vx + vy * vy)
    s = dist - geo[m, RHO]
    p, dp, ddp = profile(abs(s), step, height, slope)
    sg = 1.0 if s >= 0.0 else -1.0
    ux, uy = vx / dist, vy / dist
    k = sg * dp / dist  # distance to a circle curves along it
    return (p - depth, sg * dp * ux, sg * dp * uy, ddp * ux * ux + k * uy * uy,
            (ddp - k) * ux * uy, ddp * uy * uy + k * ux * ux)


@kernel(helper=True)
def _dslope(ax: float, ay: float, az: float, ia: float, bx: float, by: float, bz: float,
            ib: float, hx: float, hy: float, hz: float, gjx: float, gjy: float,
            gjz: float) -> tuple[float, float]:
    """Change of h's slope when g moves by (gjx, gjy, gjz); du/dg = -(I - u u^T) / distance."""
    pa = ax * gjx + ay * gjy + az * gjz
    pb = bx * gjx + by * gjy + bz * gjz
    dhx = -ia * (gjx - ax * pa) - ib * (gjx - bx * pb)
    dhy = -ia * (gjy - ay * pa) - ib * (gjy - by * pb)
    dhz = -ia * (gjz - az * pa) - ib * (gjz - bz * pb)
    return (dhx * hz - hx * dhz) / (hz * hz), (dhy * hz - hy * dhz) / (hz * hz)


@kernel()
def _half(gx: float, gy: float, gz: float, zx: float, zy: float, eye: np.ndarray,
          light: np.ndarray, point: bool) -> tuple[float, float, float, float, float, float]:
    """Slope of h = u(light - g) + u(eye - g), and its derivative along the surface.

    Returns:
        s_x, s_y (h_x / h_z, h_y / h_z) and ds_x/dx, ds_x/dy, ds_y/dx, ds_y/dy,
        g moving on the surface (dz = z_x dx + z_y dy).
    """
    bx, by, bz = eye[0] - gx, eye[1] - gy, eye[2] - gz
    db = math.sqrt(bx * bx + by * by + bz * bz)
    bx, by, bz = bx / db, by / db, bz / db
    if point:
        ax, ay, az = light[0] - gx, light[1] - gy, light[2] - gz
        da = math.sqrt(ax * ax + ay * ay + az * az)
        ax, ay, az = ax / da, ay / da, az / da
        ia = 1.0 / da
    else:
        ax, ay, az = light[0], light[1], light[2]
        ia = 0.0
    hx, hy, hz = ax + bx, ay + by, az + bz
    ib = 1.0 / db
    sxx, syx = _dslope(ax, ay, az, ia, bx, by, bz, ib, hx, hy, hz, 1.0, 0.0, zx)
    sxy, syy = _dslope(ax, ay, az, ia, bx, by, bz, ib, hx, hy, hz, 0.0, 1.0, zy)
    return hx / hz, hy / hz, sxx, sxy, syx, syy


@kernel(parallel=True)
def screen(geo: np.ndarray, kind: np.ndarray, flags: np.ndarray, depth: float, ext: float,
           tol: float, eye: np.ndarray, light: np.ndarray, point: bool) -> np.ndarray:
    """Moves whose body may glint for an eye (k,) bool.

    A body glints where h . t = 0; on the move extended by ``ext`` at both ends
    h . t must change sign, or come within ``tol`` |h| of zero at an end (h on
    the wall differs from h on the centreline by about the groove width over
    the distances to eye and light). Points and corners always pass.
    """
    k = kind.size
    ok = np.zeros(k, np.bool_)
    for m in nb.prange(k):
        if kind[m] == POINT or flags[m] & (CORNER_START | CORNER_END):
            ok[m] = True
            continue
        # An arc turning this much may hold two roots: never screened out.
        if kind[m] == ARC and abs(geo[m, SWEEP]) + 2.0 * ext / geo[m, RHO] > 0.5:
            ok[m] = True
            continue
        f0 = f1 = hn = 0.0
        for e in range(2):
            if kind[m] == LINE:
                tx, ty, length = chord(geo, m)
                s = -ext if e == 0 else length + ext
                px, py = geo[m, SX] + s * tx, geo[m, SY] + s * ty
            else:
                rho, sw = geo[m, RHO], geo[m, SWEEP]
                a0 = math.atan2(geo[m, SY] - geo[m, CY], geo[m, SX] - geo[m, CX])
                sg = 1.0 if sw > 0.0 else -1.0
                a = a0 - sg * ext / rho if e == 0 else a0 + sw + sg * ext / rho
                c, sn = math.cos(a), math.sin(a)
                px, py = geo[m, CX] + rho * c, geo[m, CY] + rho * sn
                tx, ty = -sg * sn, sg * c
            bx, by, bz = eye[0] - px, eye[1] - py, eye[2] + depth
            db = math.sqrt(bx * bx + by * by + bz * bz)
            if point:
                ax, ay, az = light[0] - px, light[1] - py, light[2] + depth
                da = math.sqrt(ax * ax + ay * ay + az * az)
                ax, ay, az = ax / da, ay / da, az / da
            else:
                ax, ay, az = light[0], light[1], light[2]
            hx, hy, hz = ax + bx / db, ay + by / db, az + bz / db
            if e == 0:
                f0 = hx * tx + hy * ty
            else:
                f1 = hx * tx + hy * ty
            hn = math.sqrt(hx * hx + hy * hy + hz * hz)
        if f0 * f1 <= 0.0 or min(abs(f0), abs(f1)) < tol * hn:
            ok[m] = True
    return ok


@kernel(parallel=True)
def glints(paths: np.ndarray, path_ptr: np.ndarray, body_ok: np.ndarray, caps: bool,
           cell_ptr: np.ndarray, cells: np.ndarray, nx: int, x0: float, y0: float,
           res: float, geo: np.ndarray, kind: np.ndarray, flags: np.ndarray, depth: float,
           step: float, height: np.ndarray, slope: np.ndarray, eye: np.ndarray,
           light: np.ndarray, point: bool, sigma: float, iterations: int, w_min: float,
           merge: float, residual: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Glint clusters of each path for one eye.

    Every cut cell of a path solves, by Newton's method on its own move's
    surface, where nearby the surface normal equals h, and votes for that point
    with weight exp(-d^2 / (2 sigma^2)), d its distance from the cell: a
    specular lobe whose angular width is the normal's change over sigma (mm)
    there. Votes for one point (within ``merge`` mm) form a cluster.

    Args:
        paths: (p,) paths to search.
        path_ptr: (n_paths + 1,) first move of each path.
        body_ok: (k,) moves whose body may glint (from :func:`screen`).
        caps: also search the caps at paths' ends.
        cell_ptr, cells: cut cells of each move (from :func:`group_cells`).
        nx, x0, y0, res: the grid.
        geo, kind, flags, depth, step, height, slope: moves and tool.
        eye, light, point: eye (3,), light direction or position (3,), whether a point.
        sigma: lobe width in mm of position.
        iterations: Newton steps.
        w_min: smallest vote counted.
        merge: votes closer than this (mm) to a cluster join it.
        residual: largest |slope of n - slope of h| of a converged vote.

    Returns:
        sums (p, MAX_CLUSTERS, 6): per cluster sum of w, w x, w y, w z, and
        w / |det J| (J the derivative of the slope mismatch, so 1 / |det J| is
        the reflecting area per unit of slope), and the number of votes;
        cap (p, MAX_CLUSTERS) whether the cluster lies on a cap;
        n (p,) clusters per path.
    """
    p_count = paths.size
    sums = np.zeros((p_count, MAX_CLUSTERS, 6))
    cap = np.zeros((p_count, MAX_CLUSTERS), np.bool_)
    n_clusters = np.zeros(p_count, np.int64)
    inv2s2 = 0.5 / (sigma * sigma)
    for q in nb.prange(p_count):
        path = paths[q]
        nc = 0
        for m in range(path_ptr[path], path_ptr[path + 1]):
            for c in range(cell_ptr[m], cell_ptr[m + 1]):
                f = cells[c]
                cx0 = x0 + (f % nx) * res
                cy0 = y0 + (f // nx) * res
                mode, qx, qy = mode_of(geo, kind, flags, m, cx0, cy0)
                if mode == CAP:
                    if not caps:
                        continue
                elif mode == BODY and not body_ok[m]:
                    continue
                px, py = cx0, cy0
                ok = True
                gz = 0.0
                det = 0.0
                for it in range(iterations + 1):
                    gz, zx, zy, hxx, hxy, hyy = surface(geo, kind, m, mode, qx, qy, px, py,
                                                        depth, step, height, slope)
                    sx, sy, d11, d12, d21, d22 = _half(px, py, gz, zx, zy, eye, light, point)
                    fx, fy = -zx - sx, -zy - sy
                    j11, j12, j21, j22 = -hxx - d11, -hxy - d12, -hxy - d21, -hyy - d22
                    det = j11 * j22 - j12 * j21
                    if it == iterations:
                        ok = fx * fx + fy * fy <= residual * residual
                        break
                    if det == 0.0:
                        ok = False
                        break
                    dx = -(j22 * fx - j12 * fy) / det
                    dy = -(-j21 * fx + j11 * fy) / det
                    # A step past the tool's reach left this move's neighbourhood.
                    if dx * dx + dy * dy > 1e4 * res * res:
                        ok = False
                        break
                    px += dx
                    py += dy
                if not ok or det == 0.0:
                    continue
                d2 = (px - cx0) ** 2 + (py - cy0) ** 2
                w = math.exp(-d2 * inv2s2)
                if w < w_min:
                    continue
                is_cap = mode == CAP
                best = -1
                for t in range(nc):
                    if cap[q, t] != is_cap:
                        continue
                    sw = sums[q, t, 0]
                    ex = sums[q, t, 1] / sw - px
                    ey = sums[q, t, 2] / sw - py
                    if ex * ex + ey * ey <= merge * merge:
                        best = t
                        break
                if best < 0:
                    if nc == MAX_CLUSTERS:
                        continue
                    best = nc
                    cap[q, best] = is_cap
                    nc += 1
                sums[q, best, 0] += w
                sums[q, best, 1] += w * px
                sums[q, best, 2] += w * py
                sums[q, best, 3] += w * gz
                sums[q, best, 4] += w / abs(det)
                sums[q, best, 5] += 1.0
        n_clusters[q] = nc
    return sums, cap, n_clusters


@kernel()
def profile_many(r: np.ndarray, step: float, height: np.ndarray,
                 slope: np.ndarray) -> np.ndarray:
    """Profile heights (n,) at distances r (n,)."""
    out = np.empty(r.size)
    for i in range(r.size):
        out[i] = profile(r[i], step, height, slope)[0]
    return out


@kernel()
def surface_at(xy: np.ndarray, moves: np.ndarray, geo: np.ndarray, kind: np.ndarray,
               flags: np.ndarray, depth: float, step: float, height: np.ndarray,
               slope: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Height (n,) and gradient (n, 2) of the given moves' surfaces at points xy (n, 2).

    A move of -1, or a surface above the plate, gives the plate (z = 0, flat).
    """
    n = xy.shape[0]
    z = np.zeros(n)
    grad = np.zeros((n, 2))
    for i in range(n):
        m = moves[i]
        if m < 0:
            continue
        mode, qx, qy = mode_of(geo, kind, flags, m, xy[i, 0], xy[i, 1])
        gz, zx, zy, _, _, _ = surface(geo, kind, m, mode, qx, qy, xy[i, 0], xy[i, 1], depth,
                                      step, height, slope)
        if gz < 0.0:
            z[i], grad[i, 0], grad[i, 1] = gz, zx, zy
    return z, grad
