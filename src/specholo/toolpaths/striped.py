"""The exact striped design: horizontal parallax at finite light and eye distances.

For each stipple p and eye azimuth theta (eyes on the circle where real eyes
are), the toolpath c(theta) is followed so that
    c'(theta) . h(g, e(theta)) = 0,
where g is the glint on the ball-end groove's wall, R h/|h| from the toolpath.
The toolpath's x is chosen so that g lies on the eye's sightline through p
(horizontally exact); g's vertical offset u from the sightline drifts, and when
it leaves the band |u| <= w the stripe ends and the next starts at the band's
other edge (Brand's striping), so the vertical error never exceeds w. Samples
carry exact tangents and are joined by biarcs, so the engraved grooves keep the
tangents the glints need. The walk itself is compiled (:mod:`._stripe_kernel`).
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
#: Extra stripe spacing over the groove width, as a fraction: the spacing is set
#: where stripes hand over, and the paths' curvature brings them a little closer.
SPACING_CLEARANCE = 0.02


@dataclass(frozen=True)
class StripeOptions:
    """Resolution of the striped construction.

    Attributes:
        band: half-height w of the band about the sightline crossings, mm.
        max_step: largest azimuth step between samples, radians.
        max_chord: largest horizontal distance between samples, mm.
        min_light_tilt: smallest |h_y| / |h| accepted; below it grooves would run
            vertically and could not follow the eyes' horizontal motion.
        spacing: closest two stripes of one stipple may be, centreline to
            centreline, mm; None for the groove width (the paper's condition for
            grooves that do not cut into each other), 0 for a fixed band.
    """

    band: float = 0.2
    max_step: float = math.radians(0.5)
    max_chord: float = 0.5
    min_light_tilt: float = 0.05
    spacing: float | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.band) and self.band > 0):
            raise SpecholoError(f"band must be a positive number of mm, got {self.band}")
        if self.spacing is not None and not (math.isfinite(self.spacing) and self.spacing >= 0):
            raise SpecholoError(f"stripe spacing must be >= 0 mm, got {self.spacing}")


def _params(setup: Setup, opts: StripeOptions) -> np.ndarray:
    """The setup packed for the compiled kernel (see :mod:`._stripe_kernel`)."""
    light, viewer, tool = setup.light, setup.viewer, setup.tool
    point = light.distance is not None
    lvec = light.distance * light.direction if light.distance is not None else light.direction
    return np.array([viewer.eye_radius, viewer.height, *lvec, float(point), tool.radius,
                     tool.radius - tool.depth, opts.max_step, opts.max_chord])


def _integrate(runs: Runs, params: np.ndarray, u0: np.ndarray, cap: np.ndarray,
               w: float, spacing: float) -> tuple[np.ndarray, ...]:
    """Samples of every run, in travel order.

    Returns:
        run (m,), stripe (m,), point (m, 2) and unit tangent (m, 2).
    """
    pending = np.arange(len(runs))
    parts = []
    while pending.size:
        offsets = np.concatenate([[0], np.cumsum(cap[pending])]).astype(np.int64)
        m = int(offsets[-1])
        stripe = np.empty(m, dtype=np.int64)
        point, tangent = np.empty((m, 2)), np.empty((m, 2))
        count = kernel.integrate(runs.start[pending], runs.end[pending],
                                 np.ascontiguousarray(runs.point[pending]), u0[pending],
                                 params, w, spacing, offsets, stripe, point, tangent)
        parts.append(kernel.compact(offsets, count, pending, stripe, point, tangent))
        # Runs whose bound was too small go again with room to spare.
        cap[pending[count < 0]] *= 4
        pending = pending[count < 0]
    if len(parts) == 1:
        return parts[0]
    run = np.concatenate([p[0] for p in parts])
    order = np.argsort(run, kind="stable")
    return tuple(np.concatenate([p[i] for p in parts])[order] for i in range(4))


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
    far, near = split_near_plate(runs, setup, near_plate)
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
    spacing = setup.tool.width * (1 + SPACING_CLEARANCE) if opts.spacing is None else opts.spacing
    run, stripe, pts, tangent = _integrate(far, params, u0, cap, w, spacing)
    keep, breaks = kernel.tidy(run, stripe, pts, MIN_SPACING)
    pts, tangent, breaks, run = pts[keep], tangent[keep], breaks[keep], run[keep]
    vertices, bulges, offsets = arc_chain(pts, tangent, breaks)
    grooves = Grooves(vertices, bulges, offsets, far.stipple[run[breaks]])
    return Grooves.concatenate([grooves, dots_for(near, setup)]), dropped
