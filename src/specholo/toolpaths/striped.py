"""The exact striped design: horizontal parallax at finite light and eye distances.

For each stipple p and eye azimuth theta, the groove point c(theta) keeps x on
the sightline crossing x_s(theta) and y follows the glint condition
    c'(theta) . h(c, e(theta)) = 0,
so the eye at theta sees its glint at c(theta), horizontally exact. The
vertical offset u = y - y_s(theta) drifts; when it leaves the band |u| <= w a
stripe ends and the next starts at the band's other edge (Brand's striping),
so the vertical error never exceeds w. Samples carry exact tangents and are
joined by biarcs, so the engraved grooves keep the tangents the glints need.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from specholo.errors import SpecholoError
from specholo.setup import Light, Setup
from specholo.toolpaths.arcs import arc_chain
from specholo.toolpaths.common import Runs, dots_for, split_near_plate
from specholo.toolpaths.grooves import Grooves


@dataclass(frozen=True)
class StripeOptions:
    """Resolution of the striped construction.

    Attributes:
        band: half-height w of the band about the sightline crossings, mm.
        max_step: largest azimuth step between samples, radians.
        max_chord: largest horizontal distance between samples, mm.
        min_light_tilt: smallest |h_y| / |h| accepted; below it grooves would run
            vertically and could not follow the eyes' horizontal motion.
    """

    band: float = 0.2
    max_step: float = math.radians(0.5)
    max_chord: float = 0.5
    min_light_tilt: float = 0.05

    def __post_init__(self) -> None:
        if not (math.isfinite(self.band) and self.band > 0):
            raise SpecholoError(f"band must be a positive number of mm, got {self.band}")


class _Field:
    """The glint-condition slope field, component-wise for speed.

    The tool is a ball of radius R whose centre runs R - d above the plate; the
    glint sits on the groove wall at g = c - R h/|h|, off the toolpath c. So the
    field places the *glint* on the sightline (at the glint's own depth) and
    moves the toolpath by R h/|h| to put it there; the band bounds g's
    vertical offset from the sightline.
    """

    _DTHETA = 1e-7  # forward-difference step for the toolpath's theta-derivative

    def __init__(self, setup: Setup) -> None:
        self.viewer = setup.viewer
        self.light = setup.light
        self.radius = setup.tool.radius
        self.centre_z = setup.tool.radius - setup.tool.depth

    def _target(self, theta: np.ndarray, y: np.ndarray,
                p: np.ndarray) -> tuple[np.ndarray, ...]:
        """Toolpath x, band centre y and normality vector for eyes at theta.

        Args:
            theta: (k,) azimuths. y: (k,) toolpath heights. p: (k, 3) points.

        Returns:
            x (k,), band centre (k,) such that u = y - centre, and h components at
            the glint.
        """
        v, light, r = self.viewer, self.light, self.radius
        ex, ey, ez = v.distance * np.sin(theta), v.height, v.distance * np.cos(theta)
        px, py, pz = p[:, 0], p[:, 1], p[:, 2]
        inv_dz = 1.0 / (ez - pz)
        gx = ex + ez * inv_dz * (px - ex)  # start on the plate crossing
        gz = np.zeros_like(gx)
        gy = y
        for _ in range(3):
            hx, hy, hz = self._h(gx, gy, gz, ex, ey, ez, light)
            inv = 1.0 / np.sqrt(hx * hx + hy * hy + hz * hz)
            nx, ny, nz = hx * inv, hy * inv, hz * inv
            gz = self.centre_z - r * nz
            tau = (ez - gz) * inv_dz  # sightline point at the glint's depth
            gx = ex + tau * (px - ex)
            line_y = ey + tau * (py - ey)
            gy = y - r * ny
        hx, hy, hz = self._h(gx, gy, gz, ex, ey, ez, light)
        return gx + r * nx, line_y + r * ny, hx, hy, hz

    @staticmethod
    def _h(gx: np.ndarray, gy: np.ndarray, gz: np.ndarray, ex: np.ndarray, ey: float,
           ez: np.ndarray, light: Light) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ux, uy, uz = ex - gx, ey - gy, ez - gz
        inv = 1.0 / np.sqrt(ux * ux + uy * uy + uz * uz)
        if light.distance is None:
            lx, ly, lz = light.direction
            return lx + ux * inv, ly + uy * inv, lz + uz * inv
        lp = light.distance * light.direction
        vx, vy, vz = lp[0] - gx, lp[1] - gy, lp[2] - gz
        linv = 1.0 / np.sqrt(vx * vx + vy * vy + vz * vz)
        return vx * linv + ux * inv, vy * linv + uy * inv, vz * linv + uz * inv

    def __call__(self, theta: np.ndarray, y: np.ndarray,
                 p: np.ndarray) -> tuple[Any, ...]:
        """Slope and targets of the toolpath at (theta, y).

        Args:
            theta: (k,) azimuths. y: (k,) toolpath heights. p: (k, 3) points.

        Returns:
            dy/dtheta, band centre, toolpath x, dx/dtheta, d(band centre)/dtheta,
            each (k,), and the normality vector (hx, hy, hz) at the glint.
        """
        x, centre, hx, hy, hz = self._target(theta, y, p)
        x2, centre2, *_ = self._target(theta + self._DTHETA, y, p)
        dx = (x2 - x) / self._DTHETA
        dcentre = (centre2 - centre) / self._DTHETA
        dy = -dx * hx / hy
        return dy, centre, x, dx, dcentre, (hx, hy, hz)


def _start_offsets(field: _Field, runs: Runs, w: float,
                   opts: StripeOptions) -> tuple[np.ndarray, np.ndarray]:
    """Initial offsets u0 and a validity mask for each run.

    A coarse pass integrates u' with the groove on the crossings; the start offset
    then puts u = 0 at the apex (the view where u' = 0, usually straight on), or
    centres the whole run in the band when it fits in one stripe.
    """
    k = 33
    frac = np.linspace(0.0, 1.0, k)
    th = runs.start[:, None] + (runs.end - runs.start)[:, None] * frac
    pts = np.repeat(runs.point, k, axis=0)
    _, sy, *_ = field(th.ravel(), np.zeros(th.size), pts)
    dy, _, _, _, dsy, (hx, hy, hz) = field(th.ravel(), sy, pts)
    du = (dy - dsy).reshape(-1, k)
    hy = np.abs(hy) / np.sqrt(hx * hx + hy * hy + hz * hz)
    valid = hy.reshape(-1, k).min(axis=1) >= opts.min_light_tilt
    du = np.where(np.isfinite(du), du, 0.0)
    dth = np.diff(th, axis=1)
    u = np.concatenate([np.zeros((len(runs), 1)),
                        np.cumsum(0.5 * (du[:, 1:] + du[:, :-1]) * dth, axis=1)], axis=1)
    lo, hi = u.min(axis=1), u.max(axis=1)
    apex = np.argmin(np.abs(du), axis=1)
    interior = (apex > 0) & (apex < k - 1)
    u_apex = u[np.arange(len(runs)), apex]
    wrapped = np.mod(-u_apex + w, 2 * w) - w
    edge = -w * np.sign(u[:, -1]) * (1.0 - 1e-9)
    u0 = np.where(interior, wrapped, edge)
    u0 = np.where(hi - lo <= 2 * w * 0.999, -0.5 * (hi + lo), u0)
    return u0, valid


def _integrate(field: _Field, runs: Runs, u0: np.ndarray, w: float,
               opts: StripeOptions) -> tuple[np.ndarray, ...]:
    """Follow every run through its azimuth interval, striping at the band edges.

    Returns:
        run (m,), theta (m,), y (m,), stripe (m,) for all samples, ordered by run
        then by travel.
    """
    n = len(runs)
    theta = runs.start.copy()
    _, sy, *_ = field(theta, np.zeros(n), runs.point)
    y = sy + u0
    stripe = np.zeros(n, dtype=np.int64)
    rec: list[tuple[np.ndarray, ...]] = [(np.arange(n), theta.copy(), y.copy(), stripe.copy())]
    active = np.flatnonzero(runs.end - theta > 1e-12)

    def heun(th: np.ndarray, yy: np.ndarray, p: np.ndarray, k1: np.ndarray,
             dth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        k2, sy2, *_ = field(th + dth, yy + dth * k1, p)
        y1 = yy + 0.5 * dth * (k1 + k2)
        return y1, y1 - sy2

    while active.size:
        th, yy, p = theta[active], y[active], runs.point[active]
        k1, sy0, _, dsx, dsy, _ = field(th, yy, p)
        u_start = yy - sy0
        dth = np.minimum(runs.end[active] - th, opts.max_step)
        dth = np.minimum(dth, opts.max_chord / np.maximum(np.abs(dsx), 1e-12))
        # |du| <= 2w per step: a step can cross at most one band edge.
        dth = np.minimum(dth, 2.0 * w / np.maximum(np.abs(k1 - dsy), 1e-12))
        y1, u1 = heun(th, yy, p, k1, dth)
        edge = np.where(u1 > w, w, np.where(u1 < -w, -w, 0.0))
        cross = np.flatnonzero(edge)
        if cross.size:
            # Secant on the step length so the stripe ends on the band edge.
            a_t, a_u = np.zeros(cross.size), u_start[cross]
            b_t, b_u = dth[cross], u1[cross]
            e = edge[cross]
            for _ in range(2):
                t_new = a_t + (e - a_u) * (b_t - a_t) / (b_u - a_u)
                y_new, u_new = heun(th[cross], yy[cross], p[cross], k1[cross], t_new)
                inside = np.abs(u_new) <= w
                a_t = np.where(inside, t_new, a_t)
                a_u = np.where(inside, u_new, a_u)
                b_t = np.where(inside, b_t, t_new)
                b_u = np.where(inside, b_u, u_new)
            dth[cross] = t_new
            y1[cross] = y_new
        th1 = th + dth
        theta[active] = th1
        y[active] = y1
        rec.append((active.copy(), th1, y1.copy(), stripe[active].copy()))
        if cross.size:
            idx = active[cross]
            _, sy_c, *_ = field(th1[cross], y1[cross], p[cross])
            stripe[idx] += 1
            y[idx] = sy_c - edge[cross]
            rec.append((idx, th1[cross], y[idx].copy(), stripe[idx].copy()))
        active = active[runs.end[active] - theta[active] > 1e-12]

    run = np.concatenate([r[0] for r in rec])
    order = np.argsort(run, kind="stable")
    return tuple(np.concatenate([r[i] for r in rec])[order] for i in range(4))


def design_striped(runs: Runs, setup: Setup, opts: StripeOptions | None = None,
                   near_plate: float | None = None) -> tuple[Grooves, np.ndarray]:
    """Striped grooves serving every run's azimuth interval.

    Args:
        runs: the (stipple, interval) pairs to serve.
        setup: light, viewer and tool.
        opts: construction options.
        near_plate: points with |p_z| at most this many mm become dimples;
            default half the groove width.

    Returns:
        The grooves, and the ids of stipples that could not be designed (light
        in the eyes' plane).
    """
    opts = opts or StripeOptions()
    w = opts.band
    if near_plate is None:
        near_plate = 0.5 * setup.tool.width
    far, near = split_near_plate(runs, near_plate)
    field = _Field(setup)
    if len(far) == 0:
        return dots_for(near, setup), np.zeros(0, dtype=np.int64)
    u0, valid = _start_offsets(field, far, w, opts)
    dropped = np.unique(far.stipple[~valid])
    far = far.take(valid)
    u0 = u0[valid]
    if len(far) == 0:
        return dots_for(near, setup), dropped
    run, theta, y, stripe = _integrate(field, far, u0, w, opts)
    p = far.point[run]
    dy, _, x, dsx, _, _ = field(theta, y, p)
    tangent = np.stack([dsx, dy], axis=1)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    pts = np.stack([x, y], axis=1)
    breaks = np.ones(len(run), dtype=bool)
    breaks[1:] = (run[1:] != run[:-1]) | (stripe[1:] != stripe[:-1])
    # A sliver step (a band edge met just before the run's end) leaves two samples
    # a micron apart: keep the later one so biarcs never join near-coincident points.
    close = np.zeros(len(run), dtype=bool)
    close[:-1] = ~breaks[1:] & (np.linalg.norm(np.diff(pts, axis=0), axis=1) < 1e-3)
    close &= ~breaks  # never drop a stripe's first sample
    keep_sample = ~close
    run, stripe, pts, tangent, breaks = (run[keep_sample], stripe[keep_sample],
                                         pts[keep_sample], tangent[keep_sample],
                                         breaks[keep_sample])
    # A stripe of one sample (a band edge met exactly at the end) has no length.
    path_id = np.cumsum(breaks) - 1
    sizes = np.bincount(path_id)
    keep = sizes[path_id] >= 2
    pts, tangent, breaks, run = pts[keep], tangent[keep], breaks[keep], run[keep]
    vertices, bulges, offsets = arc_chain(pts, tangent, breaks)
    grooves = Grooves(vertices, bulges, offsets, far.stipple[run[breaks]])
    return Grooves.concatenate([grooves, dots_for(near, setup)]), dropped
