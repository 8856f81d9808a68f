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
from specholo.toolpaths.grooves import Grooves, GroovesBuilder

#: Closest two samples of one stripe may be, mm.
MIN_SPACING = 0.02
#: Extra stripe spacing over the groove width, as a fraction: the spacing is set
#: where stripes hand over, and the paths' curvature brings them a little closer.
SPACING_CLEARANCE = 0.02
#: Memory per sample of the walk's bound, bytes: the walk goes chunk by chunk,
#: so what stays is the grooves (two vertices of 24 bytes per sample taken,
#: about half the bound) and the files written from them.
BYTES_PER_SAMPLE = 40
#: Most samples of one design's walk (about 4 times a 1,000,000-stipple design).
MAX_SAMPLES = 2_000_000_000
#: Samples (by the runs' bounds) walked at a time: the walk's own arrays stay
#: a few hundred MB however large the design.
CHUNK_SAMPLES = 4_000_000
#: Most times a run's sample bound may grow (by 4 each time) before it is
#: refused, over the coarse pass's bound or MIN_BOUND, whichever is larger.
MAX_GROWTH = 4**4
MIN_BOUND = 1024


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


def at_light(points: np.ndarray, setup: Setup) -> np.ndarray:
    """Which points (n, 3) sit at a point light, within half a groove width.

    The eye would see such a point where the light itself is: every sightline
    through it meets the light, and the only optic showing it is a sphere about
    the light, reflecting each eye's own line of sight back (no groove of a
    flat plate). These stipples are dropped.
    """
    light = setup.light.position
    if light is None or len(points) == 0:
        return np.zeros(len(points), dtype=bool)
    tol = max(0.5 * setup.tool.width, 1e-9 * float(np.linalg.norm(light)))
    return np.linalg.norm(np.asarray(points, dtype=float) - light, axis=-1) <= tol


def check_work(cap: np.ndarray, setup: Setup, w: float) -> None:
    """Refuse a walk whose samples would not fit in memory, before it starts.

    Args:
        cap: (r,) bound on each run's samples (from the coarse pass).
        setup: the setup (named in the message).
        w: band half-height, mm.

    Raises:
        SpecholoError: e.g. "the striped design would need ~2.1e+09 groove
            samples (~530 GB of memory; 20 GB available) with band 0.001 mm...".
    """
    from specholo.scene.loading import available_memory, format_bytes

    samples = int(cap.sum())
    need = samples * BYTES_PER_SAMPLE
    room = available_memory()
    if samples > MAX_SAMPLES or (room is not None and need > room):
        v = setup.viewer
        have = "" if room is None else f"; {format_bytes(room)} available"
        raise SpecholoError(
            f"the striped design would need ~{samples:.2g} groove samples "
            f"(~{format_bytes(need)} of memory{have}) with band {w:g} mm, view range "
            f"+-{math.degrees(v.half_range):g} deg and eye height {v.height:g} mm: use a wider "
            "--band, a narrower --view-range, a lower --eye-height or fewer stipples")


def _integrate(runs: Runs, params: np.ndarray, u0: np.ndarray, cap: np.ndarray,
               w: float, spacing: float) -> tuple[np.ndarray, ...]:
    """Samples of every run, in travel order.

    Returns:
        run (m,), stripe (m,), point (m, 2) and unit tangent (m, 2).

    Raises:
        SpecholoError: when a run needs far more samples than its bound (the
            walk does not settle: the glint condition is ill-conditioned there).
    """
    pending = np.arange(len(runs))
    parts = []
    first = cap.copy()
    while pending.size:
        bound = MAX_GROWTH * np.maximum(first[pending], MIN_BOUND)
        if np.any(cap[pending] > bound) or int(cap[pending].sum()) > MAX_SAMPLES:
            i = int(pending[np.argmax(cap[pending] / bound)])
            x, y, z = (float(v) for v in runs.point[i])
            r, d = params[6], params[0]
            raise SpecholoError(
                f"the striped walk for the stipple at ({x:.3g}, {y:.3g}, {z:.3g}) mm does not "
                f"settle (more than {int(cap[i]):,} samples): the groove's round wall (radius "
                f"{r:g} mm, from the tool radius, spot and depth) is too coarse for eyes {d:g} mm "
                "away, or the light grazes the eyes' plane there")
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
        The grooves, and the ids of stipples that could not be designed: the
        light in the eyes' plane there (a groove would run vertically and could
        not follow the eyes' horizontal motion), or the stipple at a point
        light (:func:`at_light`).
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
    valid &= ~at_light(pts3, setup)
    dropped = np.unique(far.stipple[~valid])
    far = far.take(valid)
    u0, cap = u0[valid], cap[valid]
    if len(far) == 0:
        return dots_for(near, setup), dropped
    check_work(cap, setup, w)
    spacing = setup.tool.width * (1 + SPACING_CLEARANCE) if opts.spacing is None else opts.spacing
    out = GroovesBuilder()
    # Chunks end at run boundaries and keep run order: the same grooves as one walk.
    bounds = np.searchsorted(np.cumsum(cap), np.arange(CHUNK_SAMPLES, int(cap.sum()),
                                                       CHUNK_SAMPLES))
    for idx in np.split(np.arange(len(far)), np.unique(bounds)):
        if len(idx) == 0:
            continue
        run, stripe, pts, tangent = _integrate(far.take(idx), params, u0[idx], cap[idx], w,
                                               spacing)
        keep, breaks = kernel.tidy(run, stripe, pts, MIN_SPACING)
        pts, tangent, breaks, run = pts[keep], tangent[keep], breaks[keep], run[keep]
        vertices, bulges, offsets = arc_chain(pts, tangent, breaks)
        out.add(Grooves(vertices, bulges, offsets, far.stipple[idx][run[breaks]]))
    out.add(dots_for(near, setup))
    return out.build(), dropped
