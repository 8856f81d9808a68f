"""Compiled placement of striped grooves that keeps out of each other's way.

At each eye azimuth theta a stipple's glint may sit anywhere on the vertical
segment |u| <= w about the sightline crossing (u its offset from the
crossing): the striped paths are the leaves of a foliation, and any stretch
of any leaf inside the band is a valid stripe. Today's design takes one
family of leaves (one band phase). Here the stipples are placed in turn, and
each picks, azimuth by azimuth, the leaf whose glint no placed groove's sweep
contains and whose own sweep contains no placed glint, jumping between leaves
(a new stripe) where that saves more than a jump costs (a dynamic programme
over the azimuth samples and the leaves).

The destruction rule is exact for a round tip cutting every groove to one
depth d < R: a glint of tilt t sits at g = c - R n, R sin t from its own
centreline horizontally and at the height where any other cut of the same
depth is R sin t wide; so another groove destroys it exactly when its
centreline passes closer to g than g's own centreline does (|g - c|).

Leaves are taken to first order about one walked leaf: shifting the path by
dy at the same azimuth moves x by (dx/dy) dy and u by (1 - dc/dy) dy, exact to
~(dy / D)^2 (D the eye distance); the chosen stripes are then walked exactly
by :func:`specholo.toolpaths._stripe_kernel.integrate`.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from specholo._compiling import kernel
from specholo._threads import chunked
from specholo.toolpaths import _stripe_kernel as sk

#: Hash table sizes of the spatial index, as powers of two: about two slots a
#: point (few chains shared by two cells) from the plan's expected count.
MIN_TABLE_BITS = 16
MAX_TABLE_BITS = 26
#: Fewest points the index has room for at first (room for the plan's expected
#: points is made at once); it doubles if they are more, so it holds what the
#: placed stripes need, not the runs' worst-case bounds.
_FIRST_ROOM = 1 << 16
#: A cost too large to pay: a jump whose stripes would cut into each other.
_FORBIDDEN = 1e9
#: Cost of a sample at the band's edge over one on the sightline, in samples of
#: groove lost to a crossing.
_CENTRING = 0.005
#: "lock": what a jump off the grid costs over one on it, in leaves' worth of
#: samples of groove lost to a crossing (times the leaves per band).
_OFF_GRID = 4.0
#: "lock": what a grid hand-over costs per leaf spacing by which the new
#: stripe's glint is not the old one's mirrored about the sightline, in
#: samples of groove lost to a crossing.
_SYMMETRY = 1.0
#: Fewest plan samples a thread takes (a sample's costs take about a microsecond).
_GRAIN = 512
#: Cells of the coarse map of where anything is placed, in cells of the index:
#: a sample whose leaves' reach covers no marked cell costs its leaves nothing
#: but their centring (most samples of a sparse design: two searches per leaf
#: spared for a few reads).
_COARSE = 8


@kernel(helper=True)
def _leaf(th0: float, th1: float, px: float, py: float, pz: float, params: sk.Params,
          dx_target: float, du_target: float, delta: float, w: float, out: np.ndarray,
          period: float, origin: float) -> int:
    """Walk the leaf through the band's centre at th0 over [th0, th1], moved back
    by whole leaf spacings ``delta`` whenever it leaves the band |u| <= w (far
    from the band the first-order neighbours would stray).

    Samples are at most ``dx_target`` mm apart in x, ``du_target`` mm in u
    (so a leaf overshoots the band by at most that where it hands over) and
    the walk's largest azimuth step apart, and on every azimuth origin +
    (j + 1/2) ``period`` (none without a period). Row j of ``out`` gets theta,
    x, y, u, dx/dy, du/dy, the wall normal's n_x and n_y, the cosine of the
    path's slope, which leaf (in spacings from the first) the walk is on, and
    1 on a grid azimuth (else 0).

    Returns:
        the number of samples, or -1 when ``out`` is too short.
    """
    max_step = params[8]
    th = th0
    y = sk.target(th, 0.0, px, py, pz, params)[1]
    sol = sk.solve(th, y, px, py, pz, params, sk._UP, sk._ZERO, sk._ZERO, sk.FIRST_STEPS)
    k = 0
    shift = 0
    grid = sk._next_grid(th, period, origin)
    on_grid = 0.0
    while True:
        if k >= out.shape[0]:
            return -1
        k1, dx, dc = sk._slopes(sol)
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = th, sol[0], y, y - sol[1]
        out[k, 4], out[k, 5] = sol[6], 1.0 - sol[7]
        out[k, 6], out[k, 7] = sol[3][0], sol[3][1]
        out[k, 8] = abs(dx) / max(math.sqrt(dx * dx + k1 * k1), 1e-300)
        out[k, 9] = shift
        out[k, 10] = on_grid
        k += 1
        if th1 - th <= 1e-12:
            return k
        du = abs(k1 - dc)
        dth = min(max_step, dx_target / max(abs(dx), 1e-12))
        if math.isfinite(du):  # (as the stripe walk's coarse pass, a non-finite slope is flat)
            dth = min(dth, du_target / max(du, 1e-12))
        if th1 - th < 1.25 * dth:
            dth = th1 - th
        on_grid = 0.0
        if grid < th1 and th + dth >= grid:
            dth, on_grid = grid - th, 1.0
            grid = sk._next_grid(grid, period, origin)
        y1, u1, sol = sk._heun(th, y, k1, dth, px, py, pz, params, sol)
        th += dth
        if abs(u1) > w:
            q = int(round(u1 / delta))
            m = sk._moved(sol, -q * delta)
            y1 -= q * delta
            sol = sk.solve(th, y1, px, py, pz, params, m[3], m[8], m[9], sk.NEAR_STEPS)
            shift -= q  # a leaf keeps its index: it is q spacings higher on the new base
        y = y1


@kernel(inline="always", helper=True)
def _cell(x: float, y: float, h: float) -> tuple[int, int]:
    return int(math.floor(x / h)), int(math.floor(y / h))


def table_bits(points: int) -> int:
    """Hash table bits for an index expected to hold ``points`` points."""
    return min(max(int(points).bit_length() + 1, MIN_TABLE_BITS), MAX_TABLE_BITS)


@kernel(inline="always", helper=True)
def _slot(ix: int, iy: int, mask: int, side: int) -> int:
    """The cells wrapped onto the table as a square grid, row by row: a query's
    3 x 3 cells are three runs of neighbouring slots (a scattering hash puts
    each in a different page of memory, and finding them costs more than the
    points they hold), and two cells share a chain only a whole grid apart
    (2,048 cells of ~0.06 mm at the smallest table over 16 bits...)."""
    return (iy * side + ix) & mask


@kernel(inline="always", helper=True)
def _chain_near(i: int, x: float, y: float, reach: float, pts: np.ndarray) -> bool:
    while i >= 0:
        dx, dy = pts[i, 0] - x, pts[i, 1] - y
        r = reach + pts[i, 2]
        if dx * dx + dy * dy < r * r:
            return True
        i = int(pts[i, 3])
    return False


@kernel(helper=True)
def _near(x: float, y: float, reach: float, head: np.ndarray, pts: np.ndarray,
          h: float, side: int, r_max: float) -> bool:
    """Whether a stored point lies closer to (x, y) than ``reach`` plus its own radius.

    ``head`` holds each slot's first point plus one (0: no point). Row i of
    ``pts`` is x, y, radius and the next point of its chain (-1 at the
    end), together so that a step along a chain reads one place in memory; the
    cell of (x, y) goes first, where a point in reach is likeliest. The cells
    searched are those within ``reach`` plus the largest stored radius
    ``r_max``: the 3 x 3 about (x, y) while that is under the cell size ``h``.
    """
    mask = head.size - 1
    ix, iy = _cell(x, y, h)
    if _chain_near(head[_slot(ix, iy, mask, side)] - 1, x, y, reach, pts):
        return True
    if reach + r_max < h:  # (the common case, kept apart: a fixed loop is faster)
        for a in range(ix - 1, ix + 2):
            for b in range(iy - 1, iy + 2):
                if (a != ix or b != iy) and _chain_near(head[_slot(a, b, mask, side)] - 1, x, y,
                                                        reach, pts):
                    return True
        return False
    k = int(math.ceil((reach + r_max) / h))
    for a in range(ix - k, ix + k + 1):
        for b in range(iy - k, iy + k + 1):
            if (a != ix or b != iy) and _chain_near(head[_slot(a, b, mask, side)] - 1, x, y,
                                                    reach, pts):
                return True
    return False


@kernel(helper=True)
def _grown(pts: np.ndarray, n: int) -> np.ndarray:
    """The n points in twice the room, in the same rows (chains link rows).

    Copying the chains cell by cell, so that a query reads neighbouring rows,
    was tried: on the README design it cost 0.9 s of moving points about and
    the queries took no less time (4.2 s either way, on two cores).
    """
    out = np.empty((2 * pts.shape[0], 4))
    for i in range(n):  # (a loop, not a slice copy: that compiles for seconds)
        out[i, 0], out[i, 1], out[i, 2], out[i, 3] = pts[i, 0], pts[i, 1], pts[i, 2], pts[i, 3]
    return out


@kernel(helper=True)
def _insert(x: float, y: float, r: float, head: np.ndarray, pts: np.ndarray, n: int,
            h: float, side: int, occ: np.ndarray, hc: float) -> None:
    """Store point n (``pts`` has room for it) and mark its cell of the coarse map."""
    ix, iy = _cell(x, y, h)
    s = _slot(ix, iy, head.size - 1, side)
    pts[n, 0], pts[n, 1], pts[n, 2], pts[n, 3] = x, y, r, head[s] - 1
    head[s] = n + 1
    ix, iy = _cell(x, y, hc)
    occ[_slot(ix, iy, occ.size - 1, side)] = 1


@kernel(helper=True)
def _clear(x0: float, y0: float, x1: float, y1: float, occ: np.ndarray, hc: float,
           side: int) -> bool:
    """Whether no coarse cell meeting the box [x0, x1] x [y0, y1] is marked (two
    cells sharing a slot only make a box look less clear)."""
    mask = occ.size - 1
    ax, ay = _cell(x0, y0, hc)
    bx, by = _cell(x1, y1, hc)
    for a in range(ax, bx + 1):
        for b in range(ay, by + 1):
            if occ[_slot(a, b, mask, side)] != 0:
                return False
    return True


@kernel(nogil=True)
def _walk(r: int, start: np.ndarray, end: np.ndarray, pts: np.ndarray, packed: np.ndarray,
          w: float, leaves: int, dx_target: float, leaf: np.ndarray, period: np.ndarray,
          origin: float, slack: float) -> tuple[int, np.ndarray, np.ndarray]:
    """Run r's walked leaf into ``leaf`` (see :func:`_leaf`) and, at each of its
    samples, the lowest and highest leaf inside the band, in spacings from the
    walk's first leaf. A run without a grid period keeps to the middle
    1 / ``slack`` of the band (its own band, where ``w`` is widened for the
    gridded runs).

    Returns:
        the number of samples m (-1 when ``leaf`` is too short), lo (m,), hi (m,).
    """
    params = sk._unpacked(packed)
    delta = 2.0 * w / leaves
    width = leaves + 3
    if period[r] <= 0.0:
        w = w / slack
    w_eff = 0.98 * w  # the walked leaf strays ~(dy / D)^2 from the planned one
    # A hand-over (the old leaf kept to the new one's first sample) overshoots
    # the band by one u step at most: within w.
    du_target = w - w_eff
    m = _leaf(start[r], end[r], pts[r, 0], pts[r, 1], pts[r, 2], params, dx_target, du_target,
              delta, w, leaf, period[r], origin)
    lo = np.empty(max(m, 0), dtype=np.int64)
    hi = np.empty(max(m, 0), dtype=np.int64)
    for j in range(m):
        step = delta * leaf[j, 5]
        base = int(leaf[j, 9])
        lo[j] = base + int(math.ceil((-w_eff - leaf[j, 3]) / step))
        hi[j] = base + int(math.floor((w_eff - leaf[j, 3]) / step))
        if hi[j] < lo[j]:  # a band narrower than the leaf spacing: the nearest leaf
            lo[j] = hi[j] = base + int(round(-leaf[j, 3] / step))
        hi[j] = min(hi[j], lo[j] + width - 1)
    return m, lo, hi


@kernel(nogil=True)
def _costs(j0: int, j1: int, leaf: np.ndarray, lo: np.ndarray, hi: np.ndarray, w: float,
           delta: float, r_tip: float, margin: float, head_c: np.ndarray, cen: np.ndarray,
           head_g: np.ndarray, gli: np.ndarray, h: float, side: int, r_max_g: float,
           occ: np.ndarray, hc: float, here: np.ndarray) -> None:
    """What each leaf costs at samples [j0, j1) of a run, into ``here[j, L - lo[j]]``.

    The index of the placed grooves does not change while a run is chosen, so
    every sample's costs are independent of the others' (and of the choices):
    they are found on threads (:func:`specholo._threads.chunked`), then chosen
    among in one pass (:func:`_choose`).
    """
    # Every search below finds a point within this of one of the leaves' two
    # query points, or none (a glint's radius is at most r_max_g, a wall's
    # offset at most r_tip).
    reach = max(r_tip, r_max_g) + margin + 1e-9
    for j in range(j0, j1):
        x0, y0, dxdy = leaf[j, 1], leaf[j, 2], leaf[j, 4]
        nx, ny = leaf[j, 6], leaf[j, 7]
        rg = r_tip * math.sqrt(nx * nx + ny * ny)
        ca, cb = (lo[j] - leaf[j, 9]) * delta, (hi[j] - leaf[j, 9]) * delta
        xa, xb = x0 + dxdy * ca, x0 + dxdy * cb
        bx0 = min(xa, xb) - max(r_tip * nx, 0.0) - reach
        bx1 = max(xa, xb) - min(r_tip * nx, 0.0) + reach
        by0 = y0 + ca - max(r_tip * ny, 0.0) - reach
        by1 = y0 + cb - min(r_tip * ny, 0.0) + reach
        if _clear(bx0, by0, bx1, by1, occ, hc, side):
            for L in range(lo[j], hi[j] + 1):
                u = (leaf[j, 3] + (L - leaf[j, 9]) * delta * leaf[j, 5]) / w
                here[j, L - lo[j]] = _CENTRING * u * u
            continue
        for L in range(lo[j], hi[j] + 1):
            c = (L - leaf[j, 9]) * delta
            cx, cy = x0 + dxdy * c, y0 + c
            # Where nothing is in the way, the leaf nearer the sightline: a
            # smaller vertical error (a run that fits the band is centred).
            u = (leaf[j, 3] + c * leaf[j, 5]) / w
            cost = _CENTRING * u * u
            # Its own glint inside a placed groove's sweep, or its sweep over
            # a placed glint: a view lost either way.
            if _near(cx - r_tip * nx, cy - r_tip * ny, rg + margin, head_c, cen, h, side, 0.0):
                cost += 1.0
            if _near(cx, cy, margin, head_g, gli, h, side, r_max_g):
                cost += 1.0
            here[j, L - lo[j]] = cost


@kernel(nogil=True)
def _choose(r: int, pts: np.ndarray, packed: np.ndarray, leaf: np.ndarray, m: int,
            lo: np.ndarray, hi: np.ndarray, here: np.ndarray, back: np.ndarray, w: float,
            leaves: int, spacing: float, dx_target: float, jump_cost: float,
            min_length: float, head_c: np.ndarray, cen: np.ndarray, head_g: np.ndarray,
            gli: np.ndarray, n_c: int, h: float, side: int, r_max_g: float,
            occ: np.ndarray, hc: float, gridded: bool
            ) -> tuple[np.ndarray, np.ndarray, int, float, np.ndarray, np.ndarray, np.ndarray,
                       np.ndarray]:
    """Run r's stripes: the cheapest path through its leaves' costs ``here``
    (a dynamic programme over the samples), then stored in the index.

    Returns:
        the index's point arrays (grown when full), its point count and largest
        glint radius, and each chosen stripe's theta start, theta end, u0 at
        the start and x span.
    """
    params = sk._unpacked(packed)
    r_tip = params[6]
    px, py, pz = pts[r, 0], pts[r, 1], pts[r, 2]
    delta = 2.0 * w / leaves
    width = leaves + 3
    cost = np.full(width, np.inf)
    prev_cost = np.full(width, np.inf)
    pre_v, suf_v = np.empty(width), np.empty(width)
    pre_a = np.empty(width, dtype=np.int64)
    suf_a = np.empty(width, dtype=np.int64)
    p_lo, n_p, d_min = 0, 0, 1
    # (back[j] is written for every leaf in the band at j, all that is read.)
    for j in range(m):
        gap_scale = leaf[j, 5] * leaf[j, 8]
        # Costs count groove length, in plan steps: samples crowd where u
        # drifts fast, and a crossing costs the length it cuts away.
        j0, j1 = max(j - 1, 0), min(j + 1, m - 1)
        weight = abs(leaf[j1, 1] - leaf[j0, 1]) / max(j1 - j0, 1) / dx_target
        for s in range(width):
            cost[s] = np.inf
        # With a grid, a jump off it (where the leaf leaves the band sooner
        # than the next grid azimuth) costs as much as a crossing's loss of a
        # whole band of samples: the stripes end together wherever they can.
        # And a stripe kept across a grid azimuth costs as much: every stripe
        # then ends on each, so both eyes, a whole number of periods apart,
        # meet every stipple at the same point of a stripe.
        jc = jump_cost + (_OFF_GRID * leaves if gridded and leaf[j, 10] == 0.0 else 0.0)
        stay = _OFF_GRID * leaves if gridded and leaf[j, 10] != 0.0 else 0.0
        if j > 0:
            # A jump of d leaves may be made from the first d whose gap reaches
            # the spacing (gaps grow with d): the best jump into L comes from
            # the leaves at least that far below or above, kept as running
            # minima, the lower leaf on ties as a scan in order keeps it.
            p_lo, n_p = lo[j - 1], hi[j - 1] - lo[j - 1] + 1
            d_min = 1
            while d_min <= width and d_min * delta * gap_scale < spacing:
                d_min += 1
            for t in range(n_p):
                v = prev_cost[t] + jc
                if t == 0 or v < pre_v[t - 1]:
                    pre_v[t], pre_a[t] = v, t
                else:
                    pre_v[t], pre_a[t] = pre_v[t - 1], pre_a[t - 1]
            for t in range(n_p - 1, -1, -1):
                v = prev_cost[t] + jc
                if t == n_p - 1 or v <= suf_v[t + 1]:
                    suf_v[t], suf_a[t] = v, t
                else:
                    suf_v[t], suf_a[t] = suf_v[t + 1], suf_a[t + 1]
        for L in range(lo[j], hi[j] + 1):
            best, arg = np.inf, -(1 << 40)
            if j == 0:
                best, arg = 0.0, L
            else:
                t = L - d_min - p_lo  # the highest leaf far enough below
                if t >= 0 and stay == 0.0:
                    t = min(t, n_p - 1)
                    best, arg = pre_v[t], p_lo + pre_a[t]
                t = L - p_lo
                if 0 <= t < n_p and prev_cost[t] + stay < best:
                    best, arg = prev_cost[t] + stay, L
                t = max(L + d_min - p_lo, 0)  # the lowest leaf far enough above
                if t < n_p and suf_v[t] < best and stay == 0.0:
                    best, arg = suf_v[t], p_lo + suf_a[t]
                if stay != 0.0:
                    # On a grid azimuth every stipple hands over, both eyes
                    # alike: the new stripe's glint is best as far below the
                    # sightline as the old one's is above it, so that the two
                    # half streaks an eye sees there straddle its sightline.
                    # (Every pair of leaves: grid samples are few.)
                    u_l = leaf[j, 3] + (L - leaf[j, 9]) * delta * leaf[j, 5]
                    for Lp in range(lo[j - 1], hi[j - 1] + 1):
                        if Lp == L:
                            continue
                        if abs(L - Lp) * delta * gap_scale < spacing:
                            continue
                        u_p = leaf[j, 3] + (Lp - leaf[j, 9]) * delta * leaf[j, 5]
                        pc = prev_cost[Lp - lo[j - 1]] + jc + _SYMMETRY * abs(u_l + u_p) / delta
                        if pc < best:
                            best, arg = pc, Lp
                if best >= _FORBIDDEN:  # nowhere to come from but a forbidden jump
                    best, arg = np.inf, -(1 << 40)
                    for Lp in range(lo[j - 1], hi[j - 1] + 1):
                        pc = prev_cost[Lp - lo[j - 1]]
                        if Lp != L:
                            gap = abs(L - Lp) * delta * gap_scale
                            pc += jc if gap >= spacing else _FORBIDDEN
                        if pc < best:
                            best, arg = pc, Lp
            cost[L - lo[j]] = best + weight * here[j, L - lo[j]]
            back[j, L - lo[j]] = arg
        for s in range(width):
            prev_cost[s] = cost[s]
    # The cheapest last leaf, then back along the choices.
    L = lo[m - 1]
    for Lq in range(lo[m - 1], hi[m - 1] + 1):
        if prev_cost[Lq - lo[m - 1]] < prev_cost[L - lo[m - 1]]:
            L = Lq
    chosen = np.empty(m, dtype=np.int64)
    for j in range(m - 1, -1, -1):
        chosen[j] = L
        L = back[j, L - lo[j]]
    # A sliver of a stripe would be dropped as too short to cut (a gap in
    # the views): its samples stay on the leaf before it, a step or two past
    # the band at most (each sample moves u by under 2% of w).
    a = 0
    for j in range(1, m + 1):
        if j < m and chosen[j] == chosen[a]:
            continue
        b = min(j, m - 1)
        sliver = abs(leaf[b, 1] - leaf[a, 1]) < min_length
        if sliver and a > 0:
            for q in range(a, j):
                chosen[q] = chosen[a - 1]
        elif sliver and j < m:
            for q in range(a, j):
                chosen[q] = chosen[j]
        a = j
    # Stripes: a jump at j ends the old leaf at j too (no azimuth left unserved).
    # (Arrays, not lists: a list compiles for seconds on a first run.)
    stripes = 1
    for j in range(1, m):
        if chosen[j] != chosen[j - 1]:
            stripes += 1
    o_a, o_b, o_u, o_x = np.empty(stripes), np.empty(stripes), np.empty(stripes), np.empty(stripes)
    k = 0
    a = 0
    for j in range(1, m + 1):
        if j < m and chosen[j] == chosen[a]:
            continue
        b = min(j, m - 1)
        ya = leaf[a, 2] + (chosen[a] - leaf[a, 9]) * delta
        th_a = leaf[a, 0]
        u0 = ya - sk.target(th_a, 0.0, px, py, pz, params)[1]
        if a > 0 and leaf[a, 10] != 0.0:
            # Begun a hair before the grid azimuth where every stipple hands
            # over (see _stripe_kernel._OVERLAP).
            th_a -= sk._OVERLAP
        o_a[k], o_b[k], o_u[k], o_x[k] = th_a, leaf[b, 0], u0, abs(leaf[b, 1] - leaf[a, 1])
        k += 1
        # Room first (an array handed back from every insert costs its
        # reference counting at every point).
        while n_c + b - a + 1 > cen.shape[0]:
            cen, gli = _grown(cen, n_c), _grown(gli, n_c)
        for q in range(a, b + 1):
            c = (chosen[a] - leaf[q, 9]) * delta
            x0, y0, dxdy = leaf[q, 1], leaf[q, 2], leaf[q, 4]
            nx, ny = leaf[q, 6], leaf[q, 7]
            cx, cy = x0 + dxdy * c, y0 + c
            rg = r_tip * math.sqrt(nx * nx + ny * ny)
            r_max_g = max(r_max_g, rg)
            _insert(cx, cy, 0.0, head_c, cen, n_c, h, side, occ, hc)
            _insert(cx - r_tip * nx, cy - r_tip * ny, rg, head_g, gli, n_c, h, side, occ, hc)
            n_c += 1
        a = j
    return cen, gli, n_c, r_max_g, o_a, o_b, o_u, o_x


def place(start: np.ndarray, end: np.ndarray, pts: np.ndarray, packed: np.ndarray, w: float,
          spacing: float, leaves: int, dx_target: float, jump_cost: float, margin: float,
          sample_cap: np.ndarray, min_length: float, bits: int, max_offset: float,
          period: np.ndarray | None = None, origin: float = 0.0, slack: float = 1.0
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """Choose every run's stripes in turn, out of the way of those placed before.

    Args:
        start, end, pts: the runs' azimuth intervals (radians) and points (mm).
        packed: the setup (see :mod:`._stripe_kernel`).
        w: the band's half-height, mm.
        spacing: closest two stripes of one stipple may be where one hands over
            to the next, centreline to centreline, mm.
        leaves: leaves per band height 2 w (the choice at each azimuth).
        dx_target: largest x step between the plan's samples, mm.
        jump_cost: cost of a new stripe, in samples of groove lost to a crossing.
        margin: added to every destruction radius, mm (the plan's leaves are
            first-order and its samples discrete).
        sample_cap: (r,) most samples of each run's leaf.
        min_length: shortest stripe in x, mm.
        bits: the spatial index's hash table size (:func:`table_bits`).
        max_offset: the largest glint offset from its centreline the groove
            offers, R sin t for its steepest wall t, mm (glints needing more
            are still found, their queries searching more cells).
        period: (r,) where positive, the stripes of run r end together at
            the azimuths origin + (j + 1/2) period wherever they can ("lock"
            placement: a jump elsewhere costs :data:`_OFF_GRID` bands of
            samples more); None for none.
        slack: ``w`` over the band of a run without a grid period.

    Returns:
        run (s,), theta start (s,), theta end (s,), u0 (s,) at the start (as
        :func:`._stripe_kernel.integrate` takes it) and x span (s,) of each
        chosen stripe, in placement order; and the index of a run whose leaf
        outgrew its cap (-1 if none).
    """
    r_tip = float(packed[6])  # (sk.Params: the tip radius)
    # Cells as wide as the farthest reach a groove's walls offer: a query
    # searches 3 x 3 of them, little more than its reach.
    h = min(max_offset, r_tip) + 2.0 * margin
    r_max_g = 0.0  # the largest radius stored in the glints' index
    side = 1 << (bits // 2)  # the table's grid of cells (see _slot)
    # Each slot holds its chain's first point plus one, 0 for none: zeros come
    # from the system untouched, so only the slots the plate covers cost a
    # page (filling two tables of 2^25 slots with -1 took 0.6 s).
    head_c = np.zeros(1 << bits, dtype=np.int64)
    head_g = np.zeros(1 << bits, dtype=np.int64)
    # The coarse map, on the same grid of slots (a cell of it is _COARSE cells
    # of the index on a side, so it has room to spare).
    hc = _COARSE * h
    occ = np.zeros(1 << bits, dtype=np.uint8)
    # Room for the points the plan is expected to place (the table has about
    # two slots a point): untouched rows cost no memory, and doubling the
    # room (copying every point and faulting in the pages twice) is rare.
    room = max(_FIRST_ROOM, 1 << (bits - 1))
    cen = np.empty((room, 4))
    gli = np.empty((room, 4))
    n_c = 0
    delta = 2.0 * w / leaves
    width = leaves + 3
    # Runs' leaves, costs and choices in room kept from run to run; two leaves,
    # since the next run's is walked (on its own thread: walks do not read the
    # index) while this one's costs are found and chosen among.
    leaf_rooms = [np.empty((0, 11)), np.empty((0, 11))]
    grid = np.zeros(start.size) if period is None else np.ascontiguousarray(period, dtype=float)
    here_room = np.empty((0, width))
    back_room = np.empty((0, width), dtype=np.int64)
    out: list[tuple[int, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]] = []

    def placed(bad: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                  int]:
        if not out:
            return (np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0), np.zeros(0),
                    np.zeros(0), bad)
        run = np.concatenate([np.full(o[0].size, i, dtype=np.int64) for i, o in out])
        cols = [np.concatenate([o[k] for _, o in out]) for k in range(4)]
        return run, cols[0], cols[1], cols[2], cols[3], bad

    def walked(r: int) -> tuple[np.ndarray, int, np.ndarray, np.ndarray]:
        cap = int(sample_cap[r])
        if leaf_rooms[r % 2].shape[0] < cap:
            leaf_rooms[r % 2] = np.empty((max(cap, 2 * leaf_rooms[r % 2].shape[0]), 11))
        leaf = leaf_rooms[r % 2][:cap]
        m, lo, hi = _walk(r, start, end, pts, packed, w, leaves, dx_target, leaf, grid, origin,
                          slack)
        return leaf, m, lo, hi

    if start.size == 0:
        return placed(-1)
    with ThreadPoolExecutor(1, thread_name_prefix="specholo-walk") as ahead:
        following = ahead.submit(walked, 0)
        for r in range(start.size):
            leaf, m, lo, hi = following.result()
            if m < 0:
                return placed(r)
            if r + 1 < start.size:
                following = ahead.submit(walked, r + 1)
            if here_room.shape[0] < m:
                here_room = np.empty((max(m, 2 * here_room.shape[0]), width))
                back_room = np.empty((max(m, 2 * back_room.shape[0]), width), dtype=np.int64)
            here = here_room[:m]
            chunked(_costs, 0, m, leaf, lo, hi, w, delta, r_tip, margin, head_c, cen, head_g,
                    gli, h, side, r_max_g, occ, hc, here, grain=_GRAIN)
            cen, gli, n_c, r_max_g, a, b, u0, x = _choose(
                r, pts, packed, leaf, m, lo, hi, here, back_room, w, leaves, spacing,
                dx_target, jump_cost, min_length, head_c, cen, head_g, gli, n_c, h, side,
                r_max_g, occ, hc, bool(grid[r] > 0.0))
            out.append((r, (a, b, u0, x)))
    return placed(-1)
