"""Compiled streak search: each candidate arc walked along, its wall sampled where
the normal comes within the lobe's reach of h (see :mod:`specholo.simulation.streaks`).

The walk steps along the toolpath. Far from any glint it strides over what
cannot come near: psi changes along the groove no faster than the tangent
turns (1 / radius) plus h turns (twice the step over the eye's or light's
distance each), so a stride of (|psi| - reach) over that rate cannot jump a
streak. Near one it takes steps of at most ``step`` mm, and a quarter of the
lobe's width in psi, so that a gap another groove cuts and a streak's end are
both resolved.
"""

from __future__ import annotations

import math

import numpy as np

from specholo._compiling import kernel
from specholo._threads import chunked
from specholo.simulation._glint_kernel import _at_row, _h

#: Fixed-point steps placing a sample on the groove's wall: h moves by about
#: R / distance (4e-5 rad for the default tip at 600 mm) from the toolpath to
#: the wall, and by that squared from one step to the next.
WALL_STEPS = 1
#: Fewest arcs per thread worth a thread's start.
_GRAIN = 1024
#: Shortest step along a groove, mm.
MIN_STEP = 1e-5
#: The lobe's width as a share of its reach, for the step near a streak.
TAIL_WIDTH = 5.0


@kernel(helper=True)
def _sample(geo: np.ndarray, i: int, u: float, tool_radius: float, cz: float, eye: np.ndarray,
            light: np.ndarray, point: bool) -> tuple[float, float, float, float, float, float]:
    """Wall point (x, y, z), psi, light factor k and the wall normal's z at
    parameter u of row i: the wall normal is h's part across the groove."""
    px, py, tx, ty = _at_row(geo, i, u)
    gx, gy, gz = px, py, 0.0
    nz = 1.0
    hx, hy, hz = 0.0, 0.0, 1.0
    for _ in range(WALL_STEPS + 1):
        hx, hy, hz = _h(gx, gy, gz, eye, light, point)
        along = hx * tx + hy * ty
        nx, ny, nz = hx - along * tx, hy - along * ty, hz
        m = math.sqrt(nx * nx + ny * ny + nz * nz)
        nx, ny, nz = nx / m, ny / m, nz / m
        gx, gy, gz = px - tool_radius * nx, py - tool_radius * ny, cz - tool_radius * nz
    hn = math.sqrt(hx * hx + hy * hy + hz * hz)
    c = (hx * tx + hy * ty) / hn
    psi = math.asin(min(1.0, max(-1.0, c)))
    # k = |P_l P_h t| / |l + v|: how fast psi follows the light's direction.
    ax, ay, az = tx - c * hx / hn, ty - c * hy / hn, -c * hz / hn
    if point:
        lx, ly, lz = light[0] - gx, light[1] - gy, light[2] - gz
        ln = math.sqrt(lx * lx + ly * ly + lz * lz)
        lx, ly, lz = lx / ln, ly / ln, lz / ln
    else:
        lx, ly, lz = light[0], light[1], light[2]
    d = ax * lx + ay * ly + az * lz
    bx, by, bz = ax - d * lx, ay - d * ly, az - d * lz
    k = math.sqrt(bx * bx + by * by + bz * bz) / hn
    return gx, gy, gz, psi, k, nz


def streak_cells(rows: np.ndarray, geo: np.ndarray, tool_radius: float, depth: float,
                 max_tilt: float, eye: np.ndarray, light: np.ndarray, point: bool,
                 beta: float, tail: float, step: float,
                 rate: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The lit stretches of the candidate arcs, as cells between walk nodes.

    Args:
        rows: (m,) rows of ``geo`` (see :func:`~specholo.simulation._glint_kernel.index_arcs`).
        geo: (k, 7) packed arc geometry.
        tool_radius, depth, max_tilt: the ball-end tool and its walls' largest tilt.
        eye: (3,) eye; light: (3,) sun direction or point light position (``point``).
        beta: the light's angular radius; tail: the gloss's reach in psi (radians).
        step: longest step near a streak, mm.
        rate: a bound on how fast h turns along the groove, rad/mm.

    Returns:
        cell_row (c,) the index into ``rows``; s (c, 2) arc length of the cell's
        ends along its arc, mm; f (c, 6): the cell's middle wall point (3),
        psi at its two ends (2) and the light factor k.
    """
    m = rows.size
    count = np.zeros(m, np.int64)
    empty_i = np.zeros(0, np.int64)
    empty_f = np.zeros((0, 2))
    empty_g = np.zeros((0, 6))
    args = (rows, geo, tool_radius, tool_radius - depth, math.cos(max_tilt), eye, light, point,
            beta, tail, step, rate)
    chunked(_walk, 0, m, *args, count, empty_i, empty_f, empty_g, False, grain=_GRAIN)
    start = np.zeros(m, np.int64)
    np.cumsum(count[:-1], out=start[1:])
    total = int(count.sum())
    cell_row = np.empty(total, np.int64)
    s = np.empty((total, 2))
    f = np.empty((total, 6))
    chunked(_walk, 0, m, *args, start, cell_row, s, f, True, grain=_GRAIN)
    return cell_row, s, f


@kernel(nogil=True)
def _walk(lo: int, hi: int, rows: np.ndarray, geo: np.ndarray, tool_radius: float, cz: float,
          cos_tilt: float, eye: np.ndarray, light: np.ndarray, point: bool, beta: float,
          tail: float, step: float, rate: float, at: np.ndarray, cell_row: np.ndarray,
          s_out: np.ndarray, f_out: np.ndarray, fill: bool) -> None:
    """:func:`streak_cells` of rows[lo:hi]: counts into ``at`` (``fill`` False),
    or cells written from ``at`` on (``fill`` True)."""
    for j in range(lo, hi):
        i = rows[j]
        r = geo[i, 2]
        if r > 0.0:
            length = abs(r * geo[i, 4])
            turn = 1.0 / r
        else:
            length = math.hypot(geo[i, 3] - geo[i, 0], geo[i, 4] - geo[i, 1])
            turn = 0.0
        w = at[j] if fill else 0
        if length <= 0.0:
            if not fill:
                at[j] = 0
            continue
        speed = turn + rate
        gx, gy, gz, psi, k, nz = _sample(geo, i, 0.0, tool_radius, cz, eye, light, point)
        s = 0.0
        while s < length:
            reach = k * beta + tail
            gap = abs(psi) - 2.0 * reach
            stride = gap > 0.0
            if stride and speed > 0.0:
                ds = gap / speed
            elif stride:
                break  # a straight groove under a fixed h: psi never changes
            else:
                ds = step
                if speed > 0.0:
                    ds = min(ds, 0.25 * max(reach / TAIL_WIDTH, 1e-9) / speed)
            ds = max(ds, MIN_STEP)
            s1 = min(s + ds, length)
            qx, qy, qz, psi1, k1, nz1 = _sample(geo, i, s1 / length, tool_radius, cz, eye,
                                                light, point)
            # A stride ends at least the reach short of a streak (it is dark).
            lit = not stride and (min(abs(psi), abs(psi1)) < max(k, k1) * beta + tail
                                  or psi * psi1 <= 0.0)
            if lit and min(nz, nz1) >= cos_tilt:
                if fill:
                    cell_row[w] = j
                    s_out[w, 0], s_out[w, 1] = s, s1
                    # the chord's middle: within ds^2 / (8 rho) of the wall's
                    f_out[w, 0], f_out[w, 1] = 0.5 * (gx + qx), 0.5 * (gy + qy)
                    f_out[w, 2] = 0.5 * (gz + qz)
                    f_out[w, 3], f_out[w, 4], f_out[w, 5] = psi, psi1, 0.5 * (k + k1)
                w += 1
            gx, gy, gz, psi, k, nz = qx, qy, qz, psi1, k1, nz1
            s = s1
        if not fill:
            at[j] = w



def within(ref: np.ndarray, query: np.ndarray, radius: float) -> np.ndarray:
    """(q,) whether each query point (q, 3) lies within ``radius`` of some
    reference point (r, 3)."""
    return nearest(ref, query, radius) >= 0


def nearest(ref: np.ndarray, query: np.ndarray, radius: float) -> np.ndarray:
    """(q,) the reference point (r, 3) nearest each query point (q, 3) within
    ``radius``, -1 where none is: the references sorted by x, each query looks
    through the strip of them within ``radius`` in x."""
    q = len(query)
    out = np.full(q, -1, np.int64)
    if q == 0 or len(ref) == 0:
        return out
    order = np.argsort(ref[:, 0], kind="stable")
    chunked(_nearest, 0, q, np.ascontiguousarray(ref[order]), np.ascontiguousarray(query),
            radius, out, grain=_GRAIN)
    return np.where(out >= 0, order[np.maximum(out, 0)], -1)


@kernel(nogil=True)
def _nearest(lo: int, hi: int, ref: np.ndarray, query: np.ndarray, radius: float,
             out: np.ndarray) -> None:
    xs = ref[:, 0]
    for j in range(lo, hi):
        x, y, z = query[j, 0], query[j, 1], query[j, 2]
        best = radius * radius
        i = np.searchsorted(xs, x - radius)
        while i < len(xs) and xs[i] <= x + radius:
            dx, dy, dz = xs[i] - x, ref[i, 1] - y, ref[i, 2] - z
            d = dx * dx + dy * dy + dz * dz
            if d <= best:
                best = d
                out[j] = i
            i += 1
