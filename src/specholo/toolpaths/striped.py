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

import numpy as np

from specholo.errors import SpecholoError
from specholo.setup import Setup
from specholo.toolpaths import _stripe_kernel as kernel
from specholo.toolpaths.arcs import arc_chain
from specholo.toolpaths.common import Runs, dots_for, split_near_plate
from specholo.toolpaths.grooves import Grooves

#: Closest two samples of one stripe may be, mm.
MIN_SPACING = 0.02


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


def _params(setup: Setup, opts: StripeOptions) -> np.ndarray:
    """The setup packed for the compiled kernel (see :mod:`._stripe_kernel`)."""
    light, viewer, tool = setup.light, setup.viewer, setup.tool
    point = light.distance is not None
    lvec = light.distance * light.direction if light.distance is not None else light.direction
    return np.array([viewer.eye_radius, viewer.height, *lvec, float(point), tool.radius,
                     tool.radius - tool.depth, opts.max_step, opts.max_chord])


def _integrate(runs: Runs, params: np.ndarray, u0: np.ndarray, cap: np.ndarray,
               w: float) -> tuple[np.ndarray, ...]:
    """Samples of every run, in travel order.

    Returns:
        run (m,), stripe (m,), point (m, 2) and unit tangent (m, 2).
    """
    pending = np.arange(len(runs))
    parts = []
    while pending.size:
        offsets = np.concatenate([[0], np.cumsum(cap[pending])]).astype(np.int64)
        m = int(offsets[-1])
        theta, y, x = np.empty(m), np.empty(m), np.empty(m)
        stripe = np.empty(m, dtype=np.int64)
        tangent = np.empty((m, 2))
        count = kernel.integrate(runs.start[pending], runs.end[pending],
                                 np.ascontiguousarray(runs.point[pending]), u0[pending],
                                 params, w, offsets, theta, y, stripe, x, tangent)
        done = count >= 0
        idx = np.flatnonzero(done)
        n_done = count[idx]
        keep = np.repeat(offsets[:-1][idx] - (np.cumsum(n_done) - n_done), n_done) + np.arange(
            n_done.sum())
        parts.append((np.repeat(pending[idx], n_done), stripe[keep],
                      np.stack([x[keep], y[keep]], axis=1), tangent[keep]))
        # Runs whose bound was too small go again with room to spare.
        cap[pending[~done]] *= 4
        pending = pending[~done]
    if len(parts) == 1:
        run, stripe, pts, tangent = parts[0]
    else:
        run = np.concatenate([p[0] for p in parts])
        order = np.argsort(run, kind="stable")
        run, stripe, pts, tangent = (np.concatenate([p[i] for p in parts])[order]
                                     for i in range(4))
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    return run, stripe, pts, tangent


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
    if len(far) == 0:
        return dots_for(near, setup), np.zeros(0, dtype=np.int64)
    params = _params(setup, opts)
    pts3 = np.ascontiguousarray(far.point)
    u0, valid, cap = kernel.start_offsets(far.start, far.end, pts3, params, w,
                                          opts.min_light_tilt)
    dropped = np.unique(far.stipple[~valid])
    far = far.take(valid)
    u0, cap = u0[valid], cap[valid]
    if len(far) == 0:
        return dots_for(near, setup), dropped
    run, stripe, pts, tangent = _integrate(far, params, u0, cap, w)
    breaks = np.ones(len(run), dtype=bool)
    breaks[1:] = (run[1:] != run[:-1]) | (stripe[1:] != stripe[:-1])
    # Samples closer than MIN_SPACING would give arcs so short that rounding
    # their ends to the G-code's grid turns them visibly: keep the later one.
    close = np.zeros(len(run), dtype=bool)
    close[:-1] = ~breaks[1:] & (np.linalg.norm(np.diff(pts, axis=0), axis=1) < MIN_SPACING)
    close &= ~breaks  # never drop a stripe's first sample
    keep_sample = ~close
    run, stripe, pts, tangent, breaks = (run[keep_sample], stripe[keep_sample],
                                         pts[keep_sample], tangent[keep_sample],
                                         breaks[keep_sample])
    # A stripe shorter than MIN_SPACING (a band edge met right at a run's end)
    # serves a sliver of views with a sliver of groove: drop it.
    path_id = np.cumsum(breaks) - 1
    first = np.flatnonzero(breaks)
    last = np.r_[first[1:], len(breaks)] - 1
    span = np.linalg.norm(pts[last] - pts[first], axis=1)
    keep = (span >= MIN_SPACING)[path_id]
    pts, tangent, breaks, run = pts[keep], tangent[keep], breaks[keep], run[keep]
    vertices, bulges, offsets = arc_chain(pts, tangent, breaks)
    grooves = Grooves(vertices, bulges, offsets, far.stipple[run[breaks]])
    return Grooves.concatenate([grooves, dots_for(near, setup)]), dropped
