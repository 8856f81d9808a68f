"""Compiled inner loops of the striped construction (numba, parallel over runs).

Each run (a stipple's view interval) is a short sequential walk along the
azimuth, so this is the one place a loop must stay; it runs compiled, one run
per iteration of a parallel loop. ``packed`` holds the setup as floats:
[D, eye height, light x, y, z, point light (0/1), ball radius R, ball-centre
height R - d, max step, max chord]; for a point light, (x, y, z) is its
position, else its direction.
"""

from __future__ import annotations

import math
from typing import cast

import numpy as np

from specholo._compiling import kernel
from specholo._threads import chunked
from specholo.toolpaths.arcs import _biarc
from specholo.toolpaths.grooves import measure_paths

_NEAR_EDGE = 1e-12
_SNAP = 0.02  # a step ending within this share of w from the edge ends its stripe
#: Radians a stripe begun at a grid azimuth starts before it: enough to close
#: the rounding's gap between one stripe's last glint and the next one's
#: first (under 1e-7 rad; the glint moves about 1e-5 mm along the groove in
#: 1e-6 rad), so that an eye exactly on the grid azimuth sees the stipple;
#: within it an eye sees both stripes' glints, so it is kept as small as that
#: allows (at 1e-4 rad, a head 0.003 deg from such an azimuth saw every
#: stipple of its period twice).
_OVERLAP = 1e-6
_MAX_ITERATIONS = 64  # most fixed-point steps for the wall normal
_CONVERGED = 1e-10  # mm: the wall glint's estimated remaining error at the last step
#: The setup's floats (see above) as a tuple: passed down the inlined helpers by
#: value, where an array is reference-counted (atomically) at every call.
Params = tuple[float, float, float, float, float, float, float, float, float, float]
Vec = tuple[float, float, float]
#: A solve: x, band centre, h (unnormalised), n, dx/dtheta, dc/dtheta, dx/dy,
#: dc/dy, dn/dtheta, dn/dy, dh/dy (theta and y the walk's variables).
Solved = tuple[float, float, Vec, Vec, float, float, float, float, Vec, Vec, Vec]
# Reordered and fused floating point (~12% faster walks; samples move by
# ~1e-7 mm). Not "nnan"/"ninf": the walk tests for non-finite values.
_FAST = {"contract", "arcp", "nsz", "reassoc", "afn"}
_ZERO = (0.0, 0.0, 0.0)
#: Fewest runs per thread worth a thread's start (a run's walk takes microseconds).
_GRAIN = 64
_UP = (0.0, 0.0, 1.0)
#: Fixed-point steps of :func:`solve` from a first guess and from a near one,
#: as numpy integers: a plain int constant is a literal to numba, and each
#: literal compiles the solve once more (about 1.5 s each on a first run).
FIRST_STEPS = cast(int, np.int64(4))
NEAR_STEPS = cast(int, np.int64(1))


@kernel(fastmath=_FAST, inline="always", helper=True)
def _unpacked(packed: np.ndarray) -> Params:
    """The setup's floats out of their array."""
    return (packed[0], packed[1], packed[2], packed[3], packed[4], packed[5], packed[6],
            packed[7], packed[8], packed[9])


@kernel(fastmath=_FAST, inline="always", helper=True)
def _along(a: Vec, s: float, b: Vec) -> Vec:
    """a + s b."""
    return a[0] + s * b[0], a[1] + s * b[1], a[2] + s * b[2]


@kernel(fastmath=_FAST, inline="always", helper=True)
def _apart(a: Vec, b: Vec) -> float:
    """|a - b| in the 1-norm."""
    return abs(a[0] - b[0]) + abs(a[1] - b[1]) + abs(a[2] - b[2])


@kernel(fastmath=_FAST, inline="always")
def _unit(vx: float, vy: float, vz: float, v_t: Vec, v_y: Vec) -> tuple[Vec, Vec, Vec]:
    """v / |v| and its two derivatives, from v's (v_t, v_y).

    d(v / |v|) = (dv - u (u . dv)) / |v| with u = v / |v|: one root and one
    division serve the value and both derivatives.
    """
    inv = 1.0 / math.sqrt(vx * vx + vy * vy + vz * vz)
    ux, uy, uz = vx * inv, vy * inv, vz * inv
    a = ux * v_t[0] + uy * v_t[1] + uz * v_t[2]
    b = ux * v_y[0] + uy * v_y[1] + uz * v_y[2]
    return ((ux, uy, uz),
            ((v_t[0] - ux * a) * inv, (v_t[1] - uy * a) * inv, (v_t[2] - uz * a) * inv),
            ((v_y[0] - ux * b) * inv, (v_y[1] - uy * b) * inv, (v_y[2] - uz * b) * inv))


@kernel(fastmath=_FAST, inline="always", helper=True)
def _wall(y: float, px: float, py: float, ex: float, ey: float, ez: float, inv_dz: float,
          dinv_dz: float, r: float, zc: float, n: Vec, n_t: Vec,
          n_y: Vec) -> tuple[Vec, Vec, Vec, float, float, float]:
    """The wall glint g = c - R n for normal n, put on the sightline at its own
    depth, with its derivatives in theta and y (n's given).

    Returns:
        g, dg/dtheta, dg/dy, and the sightline's height at g's depth with its
        two derivatives.
    """
    gz = zc - r * n[2]
    q = ez - gz
    tau = q * inv_dz
    # e moves as (ez, 0, -ex) in theta; y moves g's height directly.
    tau_t = (r * n_t[2] - ex) * inv_dz + q * dinv_dz
    tau_y = r * n_y[2] * inv_dz
    ax, ay = px - ex, py - ey
    return ((ex + tau * ax, y - r * n[1], gz),
            (ez * (1.0 - tau) + tau_t * ax, -r * n_t[1], -r * n_t[2]),
            (tau_y * ax, 1.0 - r * n_y[1], -r * n_y[2]),
            ey + tau * ay, tau_t * ay, tau_y * ay)


@kernel(fastmath=_FAST, inline="always")
def _half(g: Vec, g_t: Vec, g_y: Vec, ex: float, ey: float, ez: float,
          params: Params) -> tuple[Vec, Vec, Vec]:
    """Normality vector (the half vector) at glint g and its two derivatives."""
    v, v_t, v_y = _unit(ex - g[0], ey - g[1], ez - g[2],
                        (ez - g_t[0], -g_t[1], -ex - g_t[2]), (-g_y[0], -g_y[1], -g_y[2]))
    lv, l_t, l_y = (params[2], params[3], params[4]), _ZERO, _ZERO
    if params[5] > 0.5:
        lv, l_t, l_y = _unit(params[2] - g[0], params[3] - g[1], params[4] - g[2],
                             (-g_t[0], -g_t[1], -g_t[2]), (-g_y[0], -g_y[1], -g_y[2]))
    return ((lv[0] + v[0], lv[1] + v[1], lv[2] + v[2]),
            (l_t[0] + v_t[0], l_t[1] + v_t[1], l_t[2] + v_t[2]),
            (l_y[0] + v_y[0], l_y[1] + v_y[1], l_y[2] + v_y[2]))


@kernel(fastmath=_FAST)
def solve(theta: float, y: float, px: float, py: float, pz: float, params: Params, n: Vec,
          n_t: Vec, n_y: Vec, iterations: int) -> Solved:
    """Toolpath x, band centre and h for the eye at theta, toolpath height y,
    with their derivatives in theta and y.

    The glint sits on the ball-end wall at g = c - R n (c the ball centre, R - d
    above the plate, n = h/|h|); g is put on the sightline at its own depth. n
    is found by fixed-point steps from a first guess (h turns by ~R / distance
    per step, so each step gains ~3 digits); its derivatives ride along
    (forward mode), from guesses of their own, and converge as fast.
    Compiled on its own: LLVM inlines it anyway, and the walk compiles in a
    fraction of the time.

    Returns:
        :data:`Solved` (u = y - centre is the glint's offset from the sightline).
    """
    d, ey, r, zc = params[0], params[1], params[6], params[7]
    ex, ez = d * math.sin(theta), d * math.cos(theta)
    inv_dz = 1.0 / (ez - pz)
    dinv_dz = ex * inv_dz * inv_dz
    h = h_t = h_y = _ZERO
    # At least ``iterations`` steps; a ball large against the distances (a
    # coarse tool, a wide laser trough) converges slowly and takes more.
    for k in range(_MAX_ITERATIONS):
        g, g_t, g_y, _, _, _ = _wall(y, px, py, ex, ey, ez, inv_dz, dinv_dz, r, zc, n, n_t, n_y)
        h, h_t, h_y = _half(g, g_t, g_y, ex, ey, ez, params)
        m, m_t, m_y = _unit(h[0], h[1], h[2], h_t, h_y)
        change = _apart(m, n)
        n, n_t, n_y = m, m_t, m_y
        # The steps contract by about R / D: what is left to move is about
        # change * R / D of the normal, r times that at the wall.
        if k + 1 >= iterations and not change * r * r / d > _CONVERGED:
            break
    # h is the last step's: its direction is n, within ~change R / D of the
    # converged one, as close as another evaluation would bring it.
    g, g_t, g_y, line, line_t, line_y = _wall(y, px, py, ex, ey, ez, inv_dz, dinv_dz, r, zc,
                                              n, n_t, n_y)
    return (g[0] + r * n[0], line + r * n[1], h, n, g_t[0] + r * n_t[0], line_t + r * n_t[1],
            g_y[0] + r * n_y[0], line_y + r * n_y[1], n_t, n_y, h_y)


@kernel(fastmath=_FAST, inline="always", helper=True)
def _moved(s: Solved, dy: float) -> Solved:
    """A solve carried to dy higher at the same theta, to first order.

    x, the centre and h depend on y only through the wall normal and the
    glint's own height (~1 / D per mm), so over the ~dtheta^2 between a Heun
    step's predictor and its end this is exact to ~(dy / D)^2.
    """
    return (s[0] + s[6] * dy, s[1] + s[7] * dy, _along(s[2], dy, s[10]), _along(s[3], dy, s[9]),
            s[4], s[5], s[6], s[7], s[8], s[9], s[10])


@kernel(fastmath=_FAST, inline="always", helper=True)
def _slopes(s: Solved) -> tuple[float, float, float]:
    """dy/dtheta of the path, and dx/dtheta and d centre/dtheta along it.

    The wall offset makes x depend on y too: (x', y') . h = 0 with
    x' = x_t + x_y y' gives the path's true direction.
    """
    dy = _path_slope(s[4], s[6], s[2][0], s[2][1])
    return dy, s[4] + s[6] * dy, s[5] + s[7] * dy


@kernel(fastmath=_FAST, inline="always")
def target(theta: float, y: float, px: float, py: float, pz: float, params: Params) -> Solved:
    """:func:`solve` from the plate normal (four steps reach ~1e-10 mm)."""
    return solve(theta, y, px, py, pz, params, _UP, _ZERO, _ZERO, FIRST_STEPS)


@kernel(fastmath=_FAST, inline="always", helper=True)
def _path_slope(x_th: float, x_y: float, hx: float, hy: float) -> float:
    """dy/dtheta of the path with (x', y') . h = 0 and x' = x_th + x_y y'."""
    return -x_th * hx / (hy + x_y * hx)


def start_offsets(start: np.ndarray, end: np.ndarray, pts: np.ndarray, packed: np.ndarray,
                  w: float, min_light_tilt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Initial band offset, validity and a sample-count bound for each run.

    A coarse pass integrates u' along the run; the offset puts u = 0 at the apex
    (where u' = 0, usually straight on), or centres a run that fits in one stripe.

    Returns:
        u0 (r,), valid (r,) and capacity (r,) (an upper bound on samples).
    """
    n = start.size
    u0 = np.zeros(n)
    valid = np.ones(n, dtype=np.bool_)
    cap = np.zeros(n, dtype=np.int64)
    chunked(_start_offsets, 0, n, start, end, pts, packed, w, min_light_tilt, u0, valid, cap,
            grain=_GRAIN)
    return u0, valid, cap


@kernel(fastmath=_FAST, nogil=True)
def _start_offsets(lo: int, hi: int, start: np.ndarray, end: np.ndarray, pts: np.ndarray,
                   packed: np.ndarray, w: float, min_light_tilt: float, u0: np.ndarray,
                   valid: np.ndarray, cap: np.ndarray) -> None:
    """:func:`start_offsets` of runs lo .. hi - 1."""
    params = _unpacked(packed)
    for i in range(lo, hi):
        u0[i], valid[i], cap[i], _ = _offset(start[i], end[i], pts[i, 0], pts[i, 1], pts[i, 2],
                                             params, w, min_light_tilt)


def drifts(start: np.ndarray, end: np.ndarray, pts: np.ndarray, packed: np.ndarray,
           w: float) -> np.ndarray:
    """Each run's mean |u'| over its interval (mm of band drift per radian of
    azimuth), from the coarse pass of :func:`start_offsets`."""
    n = start.size
    out = np.zeros(n)
    chunked(_drifts, 0, n, start, end, pts, packed, w, out, grain=_GRAIN)
    return out


@kernel(fastmath=_FAST, nogil=True)
def _drifts(lo: int, hi: int, start: np.ndarray, end: np.ndarray, pts: np.ndarray,
            packed: np.ndarray, w: float, out: np.ndarray) -> None:
    """:func:`drifts` of runs lo .. hi - 1."""
    params = _unpacked(packed)
    for i in range(lo, hi):
        total = _offset(start[i], end[i], pts[i, 0], pts[i, 1], pts[i, 2], params, w, 0.0)[3]
        out[i] = total / max(end[i] - start[i], 1e-12)


@kernel(fastmath=_FAST, helper=True)
def _offset(th0: float, th_end: float, px: float, py: float, pz: float, params: Params,
            w: float, min_light_tilt: float) -> tuple[float, bool, int, float]:
    """One run of :func:`start_offsets`: u0, validity, capacity and the total
    |u| drift over the run (mm)."""
    k = 33
    valid = True
    u = 0.0
    lo = hi = 0.0
    total = 0.0
    best = math.inf
    u_apex = 0.0
    apex = 0
    prev_du = 0.0
    prev_th = th0
    x_first = x_last = 0.0
    # u' is taken on the band's centre. The first sample finds it from y = 0;
    # the others solve at the last one's centre, from its wall normal and
    # derivatives (the same convergence test ends it), and carry the solve to
    # their own centre, a step of ~dc/dtheta dtheta away (:func:`_moved`).
    sol = target(th0, 0.0, px, py, pz, params)
    y = 0.0
    for j in range(k):
        th = th0 + (th_end - th0) * j / (k - 1)
        if j > 0:
            y = sol[1]
            sol = solve(th, y, px, py, pz, params, _along(sol[3], th - prev_th, sol[8]), sol[8],
                        sol[9], NEAR_STEPS)
        sol = _moved(sol, sol[1] - y)
        if j == 0:
            y = sol[1]
            sol = solve(th, y, px, py, pz, params, sol[3], sol[8], sol[9], NEAR_STEPS)
        x, h = sol[0], sol[2]
        dy, _, dc = _slopes(sol)
        if abs(h[1]) / math.sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]) < min_light_tilt:
            valid = False
        du = dy - dc
        if not math.isfinite(du):
            du = 0.0
        if j == 0:
            x_first = x
        else:
            step = 0.5 * (du + prev_du) * (th - prev_th)
            u += step
            total += abs(step)
        x_last = x
        lo = min(lo, u)
        hi = max(hi, u)
        if abs(du) < best:
            best = abs(du)
            apex = j
            u_apex = u
        prev_du = du
        prev_th = th
    if hi - lo <= 2.0 * w * 0.999:
        u_first = -0.5 * (hi + lo)
    elif 0 < apex < k - 1:
        u_first = ((-u_apex + w) % (2.0 * w)) - w
    else:
        u_first = -w * math.copysign(1.0, u) * (1.0 - 1e-9)
    span = th_end - th0
    cap = 3 * (int(total / (2.0 * w)) + 2) + int(span / params[8]) \
        + int(abs(x_last - x_first) / params[9]) + 64
    return u_first, valid, cap, total


@kernel(fastmath=_FAST, inline="always", helper=True)
def _heun(th: float, y: float, k1: float, dth: float, px: float, py: float, pz: float,
          params: Params, s: Solved) -> tuple[float, float, Solved]:
    """A Heun step from the solve ``s`` at (th, y) with slope k1.

    The end is solved at the predictor's height and carried to the step's
    end y1 (:func:`_moved`), where the walk goes on from it: one solve per
    step.

    Returns:
        y1, u there, and the solve there.
    """
    y_p = y + dth * k1
    n, n_t, n_y = s[3], s[8], s[9]
    e = solve(th + dth, y_p, px, py, pz, params, _along(n, dth, _along(n_t, k1, n_y)), n_t,
              n_y, NEAR_STEPS)
    y1 = y + 0.5 * dth * (k1 + _slopes(e)[0])
    e = _moved(e, y1 - y_p)
    return y1, y1 - e[1], e


@kernel(fastmath=_FAST, inline="always", helper=True)
def _put(s: Solved, slot: int, point_out: np.ndarray,
         tangent_out: np.ndarray) -> tuple[float, float, float]:
    """Write a sample's x and direction from its solve; returns :func:`_slopes`."""
    k1, dx, dc = _slopes(s)
    point_out[slot, 0], tangent_out[slot, 0], tangent_out[slot, 1] = s[0], dx, k1
    return k1, dx, dc


def integrate(start: np.ndarray, end: np.ndarray, pts: np.ndarray, u0: np.ndarray,
              packed: np.ndarray, w: float, spacing: float, offsets: np.ndarray,
              stripe_out: np.ndarray, point_out: np.ndarray, tangent_out: np.ndarray,
              period: np.ndarray | None = None, min_length: float = 0.0,
              origin: float = 0.0, slack: float = 1.0) -> np.ndarray:
    """Walk every run through its interval, striping where |u| reaches the band edge.

    Samples of run r go to slots offsets[r] .. offsets[r + 1] - 1: stripe
    number, toolpath point (x, y) and the path's direction there (unnormalised).
    Where the paths are steep the band widens so that consecutive stripes'
    centrelines stay ``spacing`` apart: a groove never cuts into its neighbour.

    ``period`` (r,), where positive, also ends run r's stripes at the
    azimuths origin + (j + 1/2) period (see :func:`_walk`), its band ``slack``
    times as wide; ``min_length``: shortest stripe, mm, such an azimuth ends.

    Returns:
        (r,) number of samples written per run, or -1 where the slots ran out.
    """
    n = start.size
    count = np.zeros(n, dtype=np.int64)
    grid = np.zeros(n) if period is None else np.ascontiguousarray(period, dtype=np.float64)
    chunked(_integrate, 0, n, start, end, pts, u0, packed, w, spacing, offsets, stripe_out,
            point_out, tangent_out, count, grid, min_length, origin, slack, grain=_GRAIN)
    return count


@kernel(fastmath=_FAST, nogil=True)
def _integrate(lo: int, hi: int, start: np.ndarray, end: np.ndarray, pts: np.ndarray,
               u0: np.ndarray, packed: np.ndarray, w: float, spacing: float,
               offsets: np.ndarray, stripe_out: np.ndarray, point_out: np.ndarray,
               tangent_out: np.ndarray, count: np.ndarray, period: np.ndarray,
               min_length: float, origin: float, slack: float) -> None:
    """:func:`integrate` of runs lo .. hi - 1."""
    params = _unpacked(packed)
    for i in range(lo, hi):
        count[i] = _walk(start[i], end[i], pts[i, 0], pts[i, 1], pts[i, 2], u0[i], params, w,
                         spacing, offsets[i], offsets[i + 1], stripe_out, point_out,
                         tangent_out, period[i], min_length, origin, slack)


@kernel(fastmath=_FAST, inline="always", helper=True)
def _next_grid(th: float, period: float, origin: float) -> float:
    """The first azimuth origin + (j + 1/2) period beyond th (inf without a period)."""
    if period <= 0.0:
        return math.inf
    g = origin + (math.floor((th - origin) / period - 0.5) + 1.5) * period
    # th on a grid azimuth (within rounding) is past it
    return g if g - th > 1e-9 * period else g + period


@kernel(fastmath=_FAST)
def _walk(th0: float, th_end: float, px: float, py: float, pz: float, u0: float,
          params: Params, w: float, spacing: float, first: int, stop: int,
          stripe_out: np.ndarray, point_out: np.ndarray, tangent_out: np.ndarray,
          period: float, min_length: float, origin: float, slack: float) -> int:
    """One run of :func:`integrate`, from theta ``th0`` to ``th_end`` into slots
    ``first`` .. ``stop`` - 1.

    With a ``period``, a stripe also ends at each azimuth origin + (j + 1/2)
    period (common to every run of that period) where it is at least ``min_length`` long and the
    next stripe, started so that its band offset runs symmetrically about
    zero over the coming period, lies a groove apart; the band's edge still
    ends a stripe that drifts faster. Both eyes of a head are a whole number
    of periods apart, so they see every stipple at the same point of its
    stripes' cycle.

    Returns:
        the number of samples written, or -1 where the slots ran out.
    """
    max_step, max_chord = params[8], params[9]
    if period > 0.0:
        w = w * slack  # the grid, not the band, ends most of its stripes
    k = first
    th = th0
    s0 = target(th, 0.0, px, py, pz, params)
    c = s0[1]
    grid = _next_grid(th, period, origin)
    if period > 0.0:
        # The first stripe centred on its stretch to the first grid azimuth.
        k0, _, dc0 = _slopes(s0)
        u0 = -0.5 * (k0 - dc0) * (min(grid, th_end) - th)
        u0 = max(-(1.0 - _SNAP) * w, min((1.0 - _SNAP) * w, u0))
    y = c + u0
    stripe = 0
    length = 0.0  # of the stripe so far, mm
    point_out[k, 1], stripe_out[k] = y, stripe
    k += 1
    # Each solve starts from the wall normal of the last, nearby, and its
    # derivatives (a step or two instead of four; the same convergence test
    # ends it).
    sol = solve(th, y, px, py, pz, params, _UP, _ZERO, _ZERO, FIRST_STEPS)
    while th_end - th > _NEAR_EDGE:
        if k + 2 > stop:
            k = -1
            break
        k1, dx, dc = _put(sol, k - 1, point_out, tangent_out)
        u_start = y - sol[1]
        # Neighbouring stripes of one stipple are the band's height 2 wb apart
        # vertically, so wb |cos(slope)| >= spacing / 2 keeps their grooves apart.
        # (Squares compared first: the root is seldom needed.)
        wb, half, ax = w, 0.5 * spacing, max(abs(dx), 1e-12)
        if half * half * (dx * dx + k1 * k1) > w * w * ax * ax:
            wb = half * math.sqrt(dx * dx + k1 * k1) / ax
        # A stripe starts at the edge of the band where the last one ended;
        # where the band has narrowed since, it is never outside its own band
        # (it would end at once, over and over, and the walk never finish).
        wb = max(wb, abs(u_start))
        longest = min(max_step, max_chord / max(abs(dx), 1e-12))
        # |du| <= 2w per step: a step can cross at most one band edge.
        dth = min(longest, 2.0 * w / max(abs(k1 - dc), 1e-12))
        # A step that would cross the band's edge is aimed at the middle of the
        # snap zone short of it instead: it ends the stripe there, no secant.
        du = k1 - dc
        u_aim = math.copysign((1.0 - 0.5 * _SNAP) * wb, du)
        aimed = du != 0.0 and 0.0 < (u_aim - u_start) / du < dth
        if aimed:
            dth = (u_aim - u_start) / du
        # Never leave a sliver of the run for a last, tiny step.
        if th_end - th < 1.25 * dth:
            dth = th_end - th
            aimed = False
        at_grid = grid < th_end and th + dth >= grid
        if at_grid:
            dth = grid - th
            aimed = False
        y1, u1, sol1 = _heun(th, y, k1, dth, px, py, pz, params, sol)
        grow = 0.0
        if aimed and abs(u1) <= (1.0 - _SNAP) * wb and u1 != u_start:
            grow = (u_aim - u_start) / (u1 - u_start)
        if grow > 1.0:
            # Short of the snap zone (u curves): one secant step on the aim
            # (within the step limits; it stays inside the band), rather
            # than a sliver of a step to the edge next. A u that turned
            # back (grow <= 1) is left to the next step.
            dth = min(dth * grow, longest)
            if th_end - th < 1.25 * dth:
                dth = th_end - th
            if grid < th_end and th + dth >= grid:
                dth, at_grid = grid - th, True
            y1, u1, sol1 = _heun(th, y, k1, dth, px, py, pz, params, sol)
        edge = 0.0
        if u1 > wb:
            edge = wb
        elif u1 < -wb:
            edge = -wb
        elif at_grid:
            pass  # the grid azimuth decides below
        elif abs(u1) > (1.0 - _SNAP) * wb and th_end - th - dth > _NEAR_EDGE:
            # Ending next to the edge would force a sliver of a step next:
            # the stripe ends here instead.
            edge = math.copysign(wb, u1)
            u1 = edge
        if edge != 0.0 and u1 != edge:
            # Secant on the step length so the stripe ends on the band edge.
            a_t, a_u, b_t, b_u = 0.0, u_start, dth, u1
            t_new = dth
            for _ in range(2):
                t_new = a_t + (edge - a_u) * (b_t - a_t) / (b_u - a_u)
                y1, u_new, sol1 = _heun(th, y, k1, t_new, px, py, pz, params, sol)
                if abs(u_new) <= wb:
                    a_t, a_u = t_new, u_new
                else:
                    b_t, b_u = t_new, u_new
            dth = t_new
            at_grid = False
        length += math.hypot(sol1[0] - sol[0], y1 - y)
        th += dth
        y = y1
        sol = sol1
        point_out[k, 1], stripe_out[k] = y, stripe
        k += 1
        restart = False  # at a grid azimuth, at u_next
        u_next = 0.0
        if at_grid:
            grid = _next_grid(th, period, origin)
            if edge == 0.0 and length >= min_length:
                # Centred on the coming period, within the band; kept only
                # where it starts a groove apart from this stripe's end.
                k2, dx2, dc2 = _slopes(sol)
                u_next = -0.5 * (k2 - dc2) * period
                u_next = max(-(1.0 - _SNAP) * wb, min((1.0 - _SNAP) * wb, u_next))
                apart = abs(u_next - u1) * abs(dx2)
                if apart * apart >= spacing * spacing * (dx2 * dx2 + k2 * k2) and apart > 0.0:
                    restart = True
        if edge != 0.0 or restart:
            # The stripe's end sample: its own point and direction.
            _put(sol, k - 1, point_out, tangent_out)
            stripe += 1
            length = 0.0
            # The next stripe starts the band's height away (or, at a grid
            # azimuth, at u_next): solved there, from this solve carried over.
            y_new = sol[1] + u_next if restart else sol[1] - edge
            m = _moved(sol, y_new - y)
            if restart:
                # Begun a hair before the grid azimuth: the two stripes' glints
                # overlap there, where every stipple hands over at once (an eye
                # on that azimuth, as at a head azimuth of 0 with an odd number
                # of periods to the eyes' separation, would otherwise fall in
                # the rounding's gap between one stripe's end and the next).
                th -= _OVERLAP
            sol = solve(th, y_new, px, py, pz, params, m[3], m[8], m[9], NEAR_STEPS)
            y = y_new
            point_out[k, 1], stripe_out[k] = y, stripe
            k += 1
    if k > 0:
        _put(sol, k - 1, point_out, tangent_out)
    return -1 if k < 0 else k - first


def chain_counts(offsets: np.ndarray, count: np.ndarray, stripe: np.ndarray, point: np.ndarray,
                 min_spacing: float, keep: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Which samples each run keeps once slivers are gone.

    Arcs shorter than ``min_spacing`` would be turned visibly by rounding their
    ends to the G-code's grid, and a stripe that short end to end (a band edge
    met right at a run's end) serves a sliver of views.

    Samples of run r are slots offsets[r] .. offsets[r] + count[r] - 1 (count
    >= 0). A stripe's first sample always stays; a sample closer than
    ``min_spacing`` to the next one of its stripe goes; a stripe shorter than
    ``min_spacing`` end to end goes whole.

    Returns:
        kept samples (r,) and kept stripes (r,) per run; ``keep`` (slots) is
        set to 1 at kept samples.
    """
    n = count.size
    kept = np.zeros(n, dtype=np.int64)
    paths = np.zeros(n, dtype=np.int64)
    chunked(_chain_counts, 0, n, offsets, count, stripe, point, min_spacing, keep, kept, paths,
            grain=_GRAIN)
    return kept, paths


@kernel(fastmath=_FAST, nogil=True)
def _chain_counts(lo: int, hi: int, offsets: np.ndarray, count: np.ndarray, stripe: np.ndarray,
                  point: np.ndarray, min_spacing: float, keep: np.ndarray, kept: np.ndarray,
                  paths: np.ndarray) -> None:
    """:func:`chain_counts` of runs lo .. hi - 1."""
    for r in range(lo, hi):
        a0 = offsets[r]
        stop = a0 + count[r]
        a = a0
        while a < stop:
            b = a + 1
            while b < stop and stripe[b] == stripe[a]:
                b += 1
            # The stripe is slots a .. b - 1.
            dx, dy = point[b - 1, 0] - point[a, 0], point[b - 1, 1] - point[a, 1]
            if dx * dx + dy * dy < min_spacing * min_spacing:
                for j in range(a, b):
                    keep[j] = 0
            else:
                keep[a] = 1
                k = 1
                for j in range(a + 1, b - 1):
                    dx, dy = point[j + 1, 0] - point[j, 0], point[j + 1, 1] - point[j, 1]
                    keep[j] = 1 if dx * dx + dy * dy >= min_spacing * min_spacing else 0
                    k += keep[j]
                if b - 1 > a:
                    keep[b - 1] = 1
                    k += 1
                kept[r] += k
                paths[r] += 1
            a = b


def chain_fill(offsets: np.ndarray, count: np.ndarray, stripe: np.ndarray, point: np.ndarray,
               tangent: np.ndarray, keep: np.ndarray, ids: np.ndarray, vertex_base: np.ndarray,
               path_base: np.ndarray, first_vertex: int, vertices: np.ndarray,
               bulges: np.ndarray, path_offsets: np.ndarray, path_ids: np.ndarray,
               box: np.ndarray, length: np.ndarray) -> None:
    """Biarc chains through each run's kept samples, straight into groove arrays.

    Each kept stripe of q samples becomes a path of 2q - 1 vertices (the
    samples and the biarcs' joints), as :func:`specholo.toolpaths.arcs.arc_chain`
    on the kept samples with unit tangents. Run r's paths start at vertex
    ``vertex_base[r]`` and path ``path_base[r]`` of these arrays and belong to
    stipple ``ids[r]``; their offsets count from ``first_vertex``, the
    arrays' first vertex in the whole. Run r's extent (lo_x, lo_y, hi_x, hi_y)
    goes to ``box[r]`` (r, 4) and its paths' total length to ``length[r]``,
    measured as :meth:`Grooves.measure` does while the run's arcs are in cache.
    """
    chunked(_chain_fill, 0, count.size, offsets, count, stripe, point, tangent, keep, ids,
            vertex_base, path_base, first_vertex, vertices, bulges, path_offsets, path_ids, box,
            length, grain=_GRAIN)


@kernel(fastmath=_FAST, nogil=True)
def _chain_fill(lo: int, hi: int, offsets: np.ndarray, count: np.ndarray, stripe: np.ndarray,
                point: np.ndarray, tangent: np.ndarray, keep: np.ndarray, ids: np.ndarray,
                vertex_base: np.ndarray, path_base: np.ndarray, first_vertex: int,
                vertices: np.ndarray, bulges: np.ndarray, path_offsets: np.ndarray,
                path_ids: np.ndarray, box: np.ndarray, length: np.ndarray) -> None:
    """:func:`chain_fill` of runs lo .. hi - 1."""
    for r in range(lo, hi):
        s = vertex_base[r]
        p = path_base[r]
        stop = offsets[r] + count[r]
        prev = -1  # the last kept sample of the current stripe
        for j in range(offsets[r], stop):
            if not keep[j]:
                continue
            tx, ty = tangent[j, 0], tangent[j, 1]
            norm = math.sqrt(tx * tx + ty * ty)
            tx, ty = tx / norm, ty / norm
            if prev >= 0 and stripe[prev] == stripe[j]:
                qx, qy = tangent[prev, 0], tangent[prev, 1]
                qn = math.sqrt(qx * qx + qy * qy)
                jx, jy, b1, b2 = _biarc(point[prev, 0], point[prev, 1], qx / qn, qy / qn,
                                        point[j, 0], point[j, 1], tx, ty)
                vertices[s, 0], vertices[s, 1] = jx, jy
                bulges[s - 1], bulges[s] = b1, b2
                s += 1
            else:
                if prev >= 0:
                    bulges[s - 1] = 0.0
                path_offsets[p], path_ids[p] = first_vertex + s, ids[r]
                p += 1
            vertices[s, 0], vertices[s, 1] = point[j, 0], point[j, 1]
            s += 1
            prev = j
        if prev >= 0:
            bulges[s - 1] = 0.0
        lo_x, lo_y, hi_x, hi_y, length[r] = measure_paths(
            vertices, bulges, path_offsets, first_vertex, path_base[r], p, s)
        box[r, 0], box[r, 1], box[r, 2], box[r, 3] = lo_x, lo_y, hi_x, hi_y
