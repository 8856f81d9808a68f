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

import numba as nb
import numpy as np

from specholo.toolpaths.arcs import _biarc

_DTHETA = 1e-6  # forward-difference steps for the toolpath's derivatives (rad, mm)
_DY = 1e-3
_NEAR_EDGE = 1e-12
_SNAP = 0.02  # a step ending within this share of w from the edge ends its stripe
_MAX_ITERATIONS = 64  # most fixed-point steps for the wall normal
_CONVERGED = 1e-10  # mm: the wall glint's estimated remaining error at the last step
#: The setup's floats (see above) as a tuple: passed down the inlined helpers by
#: value, where an array is reference-counted (atomically) at every call.
Params = tuple[float, float, float, float, float, float, float, float, float, float]
# Reordered and fused floating point (~12% faster walks; samples move by
# ~1e-7 mm). Not "nnan"/"ninf": the walk tests for non-finite values.
_FAST = {"contract", "arcp", "nsz", "reassoc", "afn"}


@nb.njit(fastmath=_FAST, cache=True, inline="always")
def _unpacked(packed: np.ndarray) -> Params:
    """The setup's floats out of their array."""
    return (packed[0], packed[1], packed[2], packed[3], packed[4], packed[5], packed[6],
            packed[7], packed[8], packed[9])


@nb.njit(fastmath=_FAST, cache=True, inline="always")
def _h(gx: float, gy: float, gz: float, ex: float, ey: float, ez: float,
       params: Params) -> tuple[float, float, float]:
    """Normality vector (the half vector) at glint g for an eye e."""
    ux, uy, uz = ex - gx, ey - gy, ez - gz
    inv = 1.0 / math.sqrt(ux * ux + uy * uy + uz * uz)
    lx, ly, lz = params[2], params[3], params[4]
    if params[5] > 0.5:
        lx, ly, lz = lx - gx, ly - gy, lz - gz
        linv = 1.0 / math.sqrt(lx * lx + ly * ly + lz * lz)
        lx, ly, lz = lx * linv, ly * linv, lz * linv
    return lx + ux * inv, ly + uy * inv, lz + uz * inv


@nb.njit(fastmath=_FAST, cache=True, inline="always")
def target(theta: float, y: float, px: float, py: float, pz: float, params: Params,
           nx: float, ny: float, nz: float,
           iterations: int) -> tuple[float, float, float, float, float, float, float, float]:
    """Toolpath x, band centre and h for the eye at theta, toolpath height y.

    The glint sits on the ball-end wall at g = c - R n (c the ball centre, R - d
    above the plate, n = h/|h|); g is put on the sightline at its own depth. n
    is found by fixed-point steps from a first guess (h turns by ~R / distance
    per step, so each step gains ~3 digits).

    Returns:
        x, centre (u = y - centre is the glint's offset from the sightline),
        hx, hy, hz, and the converged n.
    """
    d, ey, r, zc = params[0], params[1], params[6], params[7]
    ex, ez = d * math.sin(theta), d * math.cos(theta)
    inv_dz = 1.0 / (ez - pz)
    # At least ``iterations`` steps; a ball large against the distances (a
    # coarse tool, a wide laser trough) converges slowly and takes more.
    for k in range(_MAX_ITERATIONS):
        gx, gy, gz, _ = _wall_point(y, px, py, ex, ey, ez, inv_dz, r, zc, ny, nz)
        hx, hy, hz = _h(gx, gy, gz, ex, ey, ez, params)
        inv = 1.0 / math.sqrt(hx * hx + hy * hy + hz * hz)
        change = abs(hx * inv - nx) + abs(hy * inv - ny) + abs(hz * inv - nz)
        nx, ny, nz = hx * inv, hy * inv, hz * inv
        # The steps contract by about R / D: what is left to move is about
        # change * R / D of the normal, r times that at the wall.
        if k + 1 >= iterations and not change * r * r / d > _CONVERGED:
            break
    # h is the last step's: its direction is n, within ~change R / D of the
    # converged one, as close as another evaluation would bring it.
    gx, gy, gz, line_y = _wall_point(y, px, py, ex, ey, ez, inv_dz, r, zc, ny, nz)
    return gx + r * nx, line_y + r * ny, hx, hy, hz, nx, ny, nz


# Not inlined: LLVM still inlines it, and the walk's first compile takes half
# the time (94 s against 185 s here) at the same speed.
@nb.njit(fastmath=_FAST, cache=True)
def _nearby(theta: float, y: float, px: float, py: float, pz: float, params: Params,
            nx: float, ny: float, nz: float) -> tuple[float, float, float, float, float]:
    """Toolpath x, band centre and n next to a solved point, for difference quotients.

    One fixed-point step from that point's converged n: what is left (~R / D of
    the change in n, itself ~the step of the quotient) moves x by ~r R / D per
    unit step, below the forward difference's own truncation error.
    """
    d, ey, r, zc = params[0], params[1], params[6], params[7]
    ex, ez = d * math.sin(theta), d * math.cos(theta)
    inv_dz = 1.0 / (ez - pz)
    gx, gy, gz, _ = _wall_point(y, px, py, ex, ey, ez, inv_dz, r, zc, ny, nz)
    hx, hy, hz = _h(gx, gy, gz, ex, ey, ez, params)
    inv = 1.0 / math.sqrt(hx * hx + hy * hy + hz * hz)
    nx, ny, nz = hx * inv, hy * inv, hz * inv
    gx, gy, gz, line_y = _wall_point(y, px, py, ex, ey, ez, inv_dz, r, zc, ny, nz)
    return gx + r * nx, line_y + r * ny, nx, ny, nz


@nb.njit(fastmath=_FAST, cache=True, inline="always")
def _wall_point(y: float, px: float, py: float, ex: float, ey: float, ez: float,
                inv_dz: float, r: float, zc: float, ny: float,
                nz: float) -> tuple[float, float, float, float]:
    """The wall glint for normal n, put on the sightline at its own depth.

    Returns:
        g (x, y, z) and the sightline's height at that depth.
    """
    gz = zc - r * nz
    tau = (ez - gz) * inv_dz
    return ex + tau * (px - ex), y - r * ny, gz, ey + tau * (py - ey)


@nb.njit(fastmath=_FAST, cache=True, inline="always")
def _field(theta: float, y: float, px: float, py: float, pz: float, params: Params,
           nx: float, ny: float, nz: float, iterations: int) -> tuple[
               float, float, float, float, float, float, float, float, float, float, float]:
    """Slope of the toolpath and its targets at (theta, y), solved from the wall
    normal n with at least ``iterations`` steps (from the plate normal, four
    reach ~1e-10 mm).

    Returns:
        dy/dtheta, band centre, x, dx/dtheta, d centre/dtheta (derivatives along
        the path), hx, hy, hz, and the converged n (a guess for the next point
        of the walk).
    """
    return _field_xy(theta, y, px, py, pz, params, nx, ny, nz, iterations)[:11]


@nb.njit(fastmath=_FAST, cache=True, inline="always")
def _field_xy(theta: float, y: float, px: float, py: float, pz: float, params: Params,
              nx: float, ny: float, nz: float, iterations: int) -> tuple[
                  float, float, float, float, float, float, float, float, float, float, float,
                  float, float, float, float]:
    """:func:`_field`, then dx/dy at fixed theta and dn/dtheta along the path."""
    x, c, hx, hy, hz, nx, ny, nz = target(theta, y, px, py, pz, params, nx, ny, nz,
                                          iterations)
    # Forward differences, warm-started from the converged n: the solve's
    # residual is far below what the quotients can see.
    xa, ca, ax, ay, az = _nearby(theta + _DTHETA, y, px, py, pz, params, nx, ny, nz)
    xc, cc, cx, cy, cz = _nearby(theta, y + _DY, px, py, pz, params, nx, ny, nz)
    x_th, c_th = (xa - x) / _DTHETA, (ca - c) / _DTHETA
    x_y, c_y = (xc - x) / _DY, (cc - c) / _DY
    # The wall offset makes x depend on y too: solve (x', y') . h = 0 with
    # x' = x_th + x_y y' for the path's true direction.
    dy = _path_slope(x_th, x_y, hx, hy)
    # n moves along the path too (the steps from n are within ~R / D of the
    # solutions there): a first guess a step on.
    s_th, s_y = 1.0 / _DTHETA, dy / _DY
    return (dy, c, x, x_th + x_y * dy, c_th + c_y * dy, hx, hy, hz, nx, ny, nz, x_y,
            (ax - nx) * s_th + (cx - nx) * s_y, (ay - ny) * s_th + (cy - ny) * s_y,
            (az - nz) * s_th + (cz - nz) * s_y)


@nb.njit(fastmath=_FAST, cache=True, inline="always")
def _path_slope(x_th: float, x_y: float, hx: float, hy: float) -> float:
    """dy/dtheta of the path with (x', y') . h = 0 and x' = x_th + x_y y'."""
    slope = hx / hy
    return -x_th * slope / (1.0 + x_y * slope)


@nb.njit(fastmath=_FAST, cache=True, inline="always")
def _centre(theta: float, y: float, px: float, py: float, pz: float,
            params: Params) -> float:
    """Band centre alone (no derivatives needed)."""
    return target(theta, y, px, py, pz, params, 0.0, 0.0, 1.0, 4)[1]


@nb.njit(fastmath=_FAST, cache=True, parallel=True)
def start_offsets(start: np.ndarray, end: np.ndarray, pts: np.ndarray, packed: np.ndarray,
                  w: float, min_light_tilt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Initial band offset, validity and a sample-count bound for each run.

    A coarse pass integrates u' along the run; the offset puts u = 0 at the apex
    (where u' = 0, usually straight on), or centres a run that fits in one stripe.

    Returns:
        u0 (r,), valid (r,) and capacity (r,) (an upper bound on samples).
    """
    k = 33
    n = start.size
    params = _unpacked(packed)
    u0 = np.zeros(n)
    valid = np.ones(n, dtype=np.bool_)
    cap = np.zeros(n, dtype=np.int64)
    for i in nb.prange(n):
        px, py, pz = pts[i, 0], pts[i, 1], pts[i, 2]
        u = 0.0
        lo = hi = 0.0
        total = 0.0
        best = math.inf
        u_apex = 0.0
        apex = 0
        prev_du = 0.0
        prev_th = start[i]
        x_first = x_last = 0.0
        # Each solve starts from the last one's wall normal (the same convergence
        # test ends it), the first from the plate normal with four steps at least.
        nx, ny, nz, min_steps = 0.0, 0.0, 1.0, 4
        for j in range(k):
            th = start[i] + (end[i] - start[i]) * j / (k - 1)
            _, c, _, _, _, nx, ny, nz = target(th, 0.0, px, py, pz, params, nx, ny, nz,
                                               min_steps)
            dy, _, x, _, dc, hx, hy, hz, nx, ny, nz = _field(th, c, px, py, pz, params,
                                                             nx, ny, nz, 1)
            min_steps = 1
            if abs(hy) / math.sqrt(hx * hx + hy * hy + hz * hz) < min_light_tilt:
                valid[i] = False
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
            u0[i] = -0.5 * (hi + lo)
        elif 0 < apex < k - 1:
            u0[i] = ((-u_apex + w) % (2.0 * w)) - w
        else:
            u0[i] = -w * math.copysign(1.0, u) * (1.0 - 1e-9)
        span = end[i] - start[i]
        cap[i] = 3 * (int(total / (2.0 * w)) + 2) + int(span / params[8]) \
            + int(abs(x_last - x_first) / params[9]) + 64
    return u0, valid, cap


@nb.njit(fastmath=_FAST, cache=True, inline="always")
def _heun(th: float, y: float, k1: float, dth: float, px: float, py: float, pz: float,
          params: Params, nx: float, ny: float, nz: float, x_y: float,
          dn: tuple[float, float, float]) -> tuple[float, float, float, float, float]:
    """A Heun step from the wall normal n at (th, y), dn/dtheta along the path
    there: y, u and n at its end.

    The end's slope takes dx/dy from the start: it comes from the wall offset
    alone (~R / D) and moves by ~R / D over a step, so the slope moves by
    ~(R / D)^2 relative, far below the step's own error, and the
    difference quotient in y is saved. The samples' own directions are
    solved in full.
    """
    x, c2, hx, hy, _, nx, ny, nz = target(th + dth, y + dth * k1, px, py, pz, params,
                                          nx + dth * dn[0], ny + dth * dn[1],
                                          nz + dth * dn[2], 1)
    xa, _, _, _, _ = _nearby(th + dth + _DTHETA, y + dth * k1, px, py, pz, params, nx, ny, nz)
    k2 = _path_slope((xa - x) / _DTHETA, x_y, hx, hy)
    y1 = y + 0.5 * dth * (k1 + k2)
    return y1, y1 - c2, nx, ny, nz


@nb.njit(fastmath=_FAST, cache=True, parallel=True)
def integrate(start: np.ndarray, end: np.ndarray, pts: np.ndarray, u0: np.ndarray,
              packed: np.ndarray, w: float, spacing: float, offsets: np.ndarray,
              stripe_out: np.ndarray, point_out: np.ndarray,
              tangent_out: np.ndarray) -> np.ndarray:
    """Walk every run through its interval, striping where |u| reaches the band edge.

    Samples of run r go to slots offsets[r] .. offsets[r + 1] - 1: stripe
    number, toolpath point (x, y) and the path's direction there (unnormalised).
    Where the paths are steep the band widens so that consecutive stripes'
    centrelines stay ``spacing`` apart: a groove never cuts into its neighbour.

    Returns:
        (r,) number of samples written per run, or -1 where the slots ran out.
    """
    n = start.size
    params = _unpacked(packed)
    count = np.zeros(n, dtype=np.int64)
    max_step, max_chord = params[8], params[9]
    for i in nb.prange(n):
        px, py, pz = pts[i, 0], pts[i, 1], pts[i, 2]
        k, stop = offsets[i], offsets[i + 1]
        th = start[i]
        c = _centre(th, 0.0, px, py, pz, params)
        y = c + u0[i]
        stripe = 0
        point_out[k, 1], stripe_out[k] = y, stripe
        k += 1
        # Each solve starts from the wall normal of the last, nearby (a step
        # or two instead of four; the same convergence test ends it).
        nx, ny, nz, min_steps = 0.0, 0.0, 1.0, 4
        while end[i] - th > _NEAR_EDGE:
            if k + 2 > stop:
                k = -1
                break
            k1, c, x, dx, dc, _, _, _, nx, ny, nz, x_y, dnx, dny, dnz = _field_xy(
                th, y, px, py, pz, params, nx, ny, nz, min_steps)
            dn = (dnx, dny, dnz)
            min_steps = 1
            point_out[k - 1, 0], tangent_out[k - 1, 0], tangent_out[k - 1, 1] = x, dx, k1
            u_start = y - c
            # Neighbouring stripes of one stipple are the band's height 2 wb apart
            # vertically, so wb |cos(slope)| >= spacing / 2 keeps their grooves apart.
            wb = max(w, 0.5 * spacing * math.sqrt(dx * dx + k1 * k1) / max(abs(dx), 1e-12))
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
            if end[i] - th < 1.25 * dth:
                dth = end[i] - th
                aimed = False
            y1, u1, mx, my, mz = _heun(th, y, k1, dth, px, py, pz, params, nx, ny, nz, x_y, dn)
            grow = 0.0
            if aimed and abs(u1) <= (1.0 - _SNAP) * wb and u1 != u_start:
                grow = (u_aim - u_start) / (u1 - u_start)
            if grow > 1.0:
                # Short of the snap zone (u curves): one secant step on the aim
                # (within the step limits; it stays inside the band), rather
                # than a sliver of a step to the edge next. A u that turned
                # back (grow <= 1) is left to the next step.
                dth = min(dth * grow, longest)
                if end[i] - th < 1.25 * dth:
                    dth = end[i] - th
                y1, u1, mx, my, mz = _heun(th, y, k1, dth, px, py, pz, params, nx, ny, nz, x_y, dn)
            edge = 0.0
            if u1 > wb:
                edge = wb
            elif u1 < -wb:
                edge = -wb
            elif abs(u1) > (1.0 - _SNAP) * wb and end[i] - th - dth > _NEAR_EDGE:
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
                    y1, u_new, mx, my, mz = _heun(th, y, k1, t_new, px, py, pz, params,
                                                  nx, ny, nz, x_y, dn)
                    if abs(u_new) <= wb:
                        a_t, a_u = t_new, u_new
                    else:
                        b_t, b_u = t_new, u_new
                dth = t_new
            th += dth
            y = y1
            nx, ny, nz = mx, my, mz
            point_out[k, 1], stripe_out[k] = y, stripe
            k += 1
            if edge != 0.0:
                # The stripe's end sample: its own point and direction.
                dy_e, c, x_e, dx_e, _, _, _, _, nx, ny, nz = _field(th, y, px, py, pz, params,
                                                                    nx, ny, nz, 1)
                point_out[k - 1, 0], tangent_out[k - 1, 0], tangent_out[k - 1, 1] = x_e, dx_e, dy_e
                stripe += 1
                y = c - edge
                point_out[k, 1], stripe_out[k] = y, stripe
                k += 1
        if k > 0:
            dy_e, _, x_e, dx_e, _, _, _, _, _, _, _ = _field(th, y, px, py, pz, params,
                                                             nx, ny, nz, min_steps)
            point_out[k - 1, 0], tangent_out[k - 1, 0], tangent_out[k - 1, 1] = x_e, dx_e, dy_e
        count[i] = -1 if k < 0 else k - offsets[i]
    return count


@nb.njit(fastmath=_FAST, cache=True, parallel=True)
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
    for r in nb.prange(n):
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
    return kept, paths


@nb.njit(fastmath=_FAST, cache=True, parallel=True)
def chain_fill(offsets: np.ndarray, count: np.ndarray, stripe: np.ndarray, point: np.ndarray,
               tangent: np.ndarray, keep: np.ndarray, ids: np.ndarray, vertex_base: np.ndarray,
               path_base: np.ndarray, first_vertex: int, vertices: np.ndarray,
               bulges: np.ndarray, path_offsets: np.ndarray, path_ids: np.ndarray) -> None:
    """Biarc chains through each run's kept samples, straight into groove arrays.

    Each kept stripe of q samples becomes a path of 2q - 1 vertices (the
    samples and the biarcs' joints), as :func:`specholo.toolpaths.arcs.arc_chain`
    on the kept samples with unit tangents. Run r's paths start at vertex
    ``vertex_base[r]`` and path ``path_base[r]`` of these arrays and belong to
    stipple ``ids[r]``; their offsets count from ``first_vertex``, the
    arrays' first vertex in the whole.
    """
    n = count.size
    for r in nb.prange(n):
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
