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
#: Stripe placements (see :class:`StripeOptions`).
PLACEMENTS = ("auto", "avoid", "phase", "lock")
#: "auto": most plan samples (by the runs' estimate, see :func:`_plan_estimate`)
#: placed by "avoid"; a larger design is placed by "phase", which takes seconds
#: where the placement would take many minutes (the README example has 8e6
#: plan samples at 2,000 stipples, 3.4e7 at 8,000, placed in about 35 s on
#: two cores, and each costs more as the grooves crowd).
AUTO_MAX_PLAN_SAMPLES = 40_000_000
#: "auto": largest wall radius, in glint reaches (R sin of the steepest wall),
#: placed by "avoid"; the round tools of every default are under 1.5.
AVOID_MAX_RADIUS_OVER_OFFSET = 20.0
#: Memory of the plan per sample, bytes: each placed sample is a point of two
#: indexes (32 bytes each), and an index doubling holds old and new at once.
PLAN_BYTES_PER_SAMPLE = 3 * 2 * 32
#: Widest stripe spacing, as a share of the band's half-height w, at which
#: stripes are placed among the leaves; wider grooves keep one family a width apart.
AVOID_MAX_SPACING = 0.5
#: "lock": shortest stripe a grid azimuth ends, mm (a shorter one runs on to
#: the next: where the glint barely moves along its path, a stripe per
#: period would be a sliver the chaining drops, and a view would lose it).
LOCK_MIN_LENGTH = 4 * MIN_SPACING
#: "lock": the band's edge, which ends a stripe drifting faster than its
#: run's mean, as a multiple of the band (the avoiding plan's leaves span as
#: many bands, as finely spaced). On the README scene at 500 stipples, under
#: the sun: 1 ends most stripes at the edge, out of step between the eyes
#: (worst p95 error 2.5 mm, as "phase"); 2 still many (2.7 mm planned); 3
#: leaves the grid to end nearly all (1.2 mm in the walk, 1.4 mm planned),
#: the vertical error up to 3 bands.
LOCK_SLACK = 3
#: "lock": the grid's origin, in eye half-angles a: the stripes of every
#: period end at origin + (j + 1/2) period, so the eyes of the head straight
#: on, and of every head a whole number of eye separations 2a from it, see
#: each stipple mid-stripe, as far from its ends as it can be; the heads
#: whose eyes meet the ends all at once sit at odd multiples of half a period.
LOCK_ORIGIN = 1.0
#: A band this wide never ends a stripe: the walk of one planned stripe.
_ONE_STRIPE = 1e9


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
        placement: "avoid" to place the stipples' stripes in turn, each among the
            band's leaves out of the way of the grooves placed before it
            (:mod:`._avoid_kernel`); "phase" for one family of stripes per run,
            its band phase set at the apex (every stipple designed alone);
            "auto" for "avoid" where its plan fits in memory and in
            :data:`AUTO_MAX_PLAN_SAMPLES`, else "phase"; "lock" for what
            "auto" would do with every stipple's stripes ending together, at
            azimuths a whole fraction of the eyes' separation apart
            (:func:`lock_periods`), so both eyes see each stipple at the same
            point of its stripes.
        leaves: "avoid": leaves to choose from per band height 2 w.
        jump_cost: "avoid": what a new stripe costs, in plan samples of groove
            lost to a crossing (a jump's ends are short and each junction is a
            place two stripes hand over).
        plan_step: "avoid": largest x step between the plan's samples, mm.
        plan_margin: "avoid": added to every destruction radius, mm.
    """

    band: float = 0.2
    max_step: float = math.radians(0.5)
    max_chord: float = 0.5
    min_light_tilt: float = 0.05
    spacing: float | None = None
    placement: str = "auto"
    leaves: int = 8
    jump_cost: float = 4.0
    plan_step: float = 0.015
    plan_margin: float = 0.003

    def __post_init__(self) -> None:
        if not (math.isfinite(self.band) and self.band > 0):
            raise SpecholoError(f"band must be a positive number of mm, got {self.band}")
        if self.spacing is not None and not (math.isfinite(self.spacing) and self.spacing >= 0):
            raise SpecholoError(f"stripe spacing must be >= 0 mm, got {self.spacing}")
        if self.placement not in PLACEMENTS:
            raise SpecholoError(f"placement must be one of {', '.join(PLACEMENTS)}, "
                                f"got {self.placement!r}")
        if not (isinstance(self.leaves, int) and 2 <= self.leaves <= 64):
            raise SpecholoError(f"leaves must be an integer in [2, 64], got {self.leaves}")


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


class _Scratch:
    """The walk's slot arrays, kept from chunk to chunk (fresh pages are slow to fault)."""

    def __init__(self) -> None:
        self.size = 0

    def take(self, m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """stripe (m,), point (m, 2), tangent (m, 2) and keep (m,) slots."""
        if m > self.size:
            self.size = m
            self.stripe = np.empty(m, dtype=np.int64)
            self.point, self.tangent = np.empty((m, 2)), np.empty((m, 2))
            self.keep = np.empty(m, dtype=np.uint8)
        return self.stripe[:m], self.point[:m], self.tangent[:m], self.keep[:m]


def lock_periods(runs: Runs, params: np.ndarray, setup: Setup, w: float) -> np.ndarray:
    """Each run's period of stripe ends for "lock" placement, radians (r,).

    The eyes of a head are 2 a apart in azimuth (a the viewer's eye half-angle);
    a run's stripes end every 2 a / m, m the fewest whole parts in which the
    run's mean band drift over 2 a fits the band's height 2 w. Every stipple's
    ends then fall on azimuths common to both eyes' views, so where one eye
    sees a stipple's glint near a stripe's end (its streak cut short, the next
    stripe's end lit), the other eye does too, at the same place on its
    stripe; a run drifting faster than its mean still ends at the band's
    edge. A run whose stripes would outlast the eyes' separation anyway (its
    mean drift over 2 a under 2 w) gets 0, no grid: ending them each 2 a
    would only add strokes.
    """
    lock = 2.0 * setup.viewer.eye_half_angle
    drift = kernel.drifts(runs.start, runs.end, np.ascontiguousarray(runs.point), params, w)
    parts = np.ceil(drift * lock / (2.0 * w))
    return np.where(parts >= 2.0, lock / np.maximum(parts, 1.0), 0.0)


def _grid_steps(runs: Runs, period: np.ndarray) -> np.ndarray:
    """Grid azimuths in each run's interval, at most (r,) (0 without a grid)."""
    ends = np.divide(runs.end - runs.start, period, out=np.zeros(len(period)),
                     where=period > 0)
    return ends.astype(np.int64) + (period > 0)


def _integrate(runs: Runs, params: np.ndarray, u0: np.ndarray, cap: np.ndarray,
               w: float, spacing: float, scratch: _Scratch,
               period: np.ndarray | None = None,
               eye_half: float = 0.0) -> tuple[np.ndarray, ...]:
    """Samples of every run, in travel order.

    Returns:
        offsets (r,) and count (r,): run r's samples are slots offsets[r] ..
        offsets[r] + count[r] - 1 of stripe (slots,), point (slots, 2) and
        tangent (slots, 2) (unnormalised); and keep (slots,), scratch for
        :func:`kernel.chain_counts`.

    Raises:
        SpecholoError: when a run needs far more samples than its bound (the
            walk does not settle: the glint condition is ill-conditioned there).
    """
    pending = np.arange(len(runs))
    parts: list[tuple[np.ndarray, ...]] = []
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
        if not parts:
            stripe, point, tangent, keep = scratch.take(m)
        else:  # a retry's slots: the first pass's are still in use
            stripe, point, tangent = np.empty(m, dtype=np.int64), np.empty((m, 2)), np.empty((m, 2))
        count = kernel.integrate(runs.start[pending], runs.end[pending],
                                 np.ascontiguousarray(runs.point[pending]), u0[pending],
                                 params, w, spacing, offsets, stripe, point, tangent,
                                 None if period is None else period[pending],
                                 LOCK_MIN_LENGTH, LOCK_ORIGIN * eye_half, LOCK_SLACK)
        parts.append((pending, offsets, count, stripe, point, tangent))
        # Runs whose bound was too small go again with room to spare.
        cap[pending[count < 0]] *= 4
        pending = pending[count < 0]
    if len(parts) == 1:
        return offsets[:-1], count, stripe, point, tangent, keep
    # Gather every run's finished slots, in run order, into one dense set.
    sizes = np.zeros(len(runs), dtype=np.int64)
    where = np.zeros(len(runs), dtype=np.int64)
    part_of = np.zeros(len(runs), dtype=np.int64)
    for k, (ids, offs, cnt, *_) in enumerate(parts):
        done = cnt >= 0
        sizes[ids[done]], where[ids[done]], part_of[ids[done]] = cnt[done], offs[:-1][done], k
    dense = np.concatenate([[0], np.cumsum(sizes)])[:-1]
    total = int(sizes.sum())
    out = [np.empty(total, dtype=np.int64), np.empty((total, 2)), np.empty((total, 2))]
    for k, part in enumerate(parts):
        sel = np.flatnonzero(part_of == k)
        n_sel = sizes[sel]
        rank = np.arange(int(n_sel.sum())) - np.repeat(np.cumsum(n_sel) - n_sel, n_sel)
        dst = np.repeat(dense[sel], n_sel) + rank
        src = np.repeat(where[sel], n_sel) + rank
        for o, arr in zip(out, part[3:], strict=True):
            o[dst] = arr[src]
    return dense, sizes, out[0], out[1], out[2], np.empty(total, dtype=np.uint8)


def _plan_estimate(runs: Runs, setup: Setup, opts: StripeOptions) -> tuple[np.ndarray, int]:
    """Each run's bound on its plan samples (a leaf's walk), and the plan's likely samples.

    The plan's samples are plan_step apart in x or max_step apart in azimuth;
    the glints stray from the sightline crossings by the wall offset, < R.
    The u steps are bounded too (2% of w each): the bound has room for u
    drifting by about as much as x moves; on the README example it drifts
    about a quarter of that (the estimate's 20 steps per band over 75).
    """
    from specholo.hosts.flat import sightline_crossing

    v = setup.viewer
    ends = [sightline_crossing(v.eye(t), runs.point)[:, 0] for t in (runs.start, runs.end)]
    span_x = np.abs(ends[1] - ends[0]) + 2.0 * setup.tool.radius
    span = runs.end - runs.start
    likely = span / opts.max_step + span_x / opts.plan_step + 20.0 * span_x / opts.band
    sample_cap = (span / opts.max_step + 1.5 * span_x / opts.plan_step
                  + 75.0 * (span_x + 1.0) / opts.band + 64).astype(np.int64)
    return sample_cap, int(likely.sum())


def _plan_memory(sample_cap: np.ndarray, likely: int) -> str | None:
    """Why the plan would not fit in memory (None: it fits).

    What it holds: the two indexes of placed samples (about the likely count,
    with room to double), their hash tables, and one run's leaf at a time.
    """
    from specholo.scene.loading import available_memory, format_bytes
    from specholo.toolpaths._avoid_kernel import table_bits

    need = (likely * PLAN_BYTES_PER_SAMPLE + 16 * (1 << table_bits(likely))
            + 160 * int(sample_cap.max(initial=0)))
    room = available_memory()
    if room is not None and need > room:
        return (f"avoid would need ~{format_bytes(need)} of memory "
                f"({format_bytes(room)} available)")
    return None


def _avoid_refusal(sample_cap: np.ndarray, likely: int, setup: Setup) -> str | None:
    """Why "auto" places the stripes by phase rather than avoid (None: it need not)."""
    tool = setup.tool
    offset = tool.radius * math.sin(tool.max_tilt)
    if tool.radius > AVOID_MAX_RADIUS_OVER_OFFSET * offset:
        # The plan looks for a view's glint R sin(tilt) from the centreline,
        # in cells as wide as the walls' own reach: a nearly flat trough (a
        # laser barely deeper than nothing) would have each search scan
        # (R / offset)^2 cells, and its walls serve almost no view anyway.
        return (f"the walls reach {offset:.2g} mm from the centreline, under "
                f"1/{AVOID_MAX_RADIUS_OVER_OFFSET:g} of the {tool.radius:.2g} mm wall radius")
    if likely > AUTO_MAX_PLAN_SAMPLES:
        return (f"avoid would take ~{likely:.2g} plan samples (over "
                f"{AUTO_MAX_PLAN_SAMPLES:.2g})")
    return _plan_memory(sample_cap, likely)


def _plan(runs: Runs, params: np.ndarray, setup: Setup, opts: StripeOptions,
          spacing: float, sample_cap: np.ndarray, likely: int,
          growth: int = MAX_GROWTH,
          period: np.ndarray | None = None) -> tuple[Runs, np.ndarray, np.ndarray]:
    """The stripes of every run, placed in turn out of each other's way
    (:func:`._avoid_kernel.place`).

    Args:
        sample_cap, likely: each run's bound on its plan samples, and the plan's
            likely samples (:func:`_plan_estimate`).
        growth: most times a run's bound may grow before the plan is refused.
        period: (r,) "lock": each run's grid period (:func:`lock_periods`),
            where its stripes end wherever they can; None for none.

    Returns:
        One run per stripe (its stipple, point and azimuth interval), its u0 at
        the start, and its bound on the walk's samples.
    """
    from specholo.toolpaths import _avoid_kernel

    first = sample_cap.copy()
    # "lock": the leaves span the slack's bands, as finely spaced, so a stripe
    # can last until the grid ends it.
    slack = 1 if period is None else LOCK_SLACK
    band, leaves = slack * opts.band, slack * opts.leaves
    while True:
        why = _plan_memory(sample_cap, likely)
        if why is not None:
            raise SpecholoError(f"--placement avoid: {why}; use --placement phase or auto")
        run, a, b, u0, dx, bad = _avoid_kernel.place(
            runs.start, runs.end, np.ascontiguousarray(runs.point), params, band, spacing,
            leaves, opts.plan_step, opts.jump_cost, opts.plan_margin, sample_cap,
            2.0 * MIN_SPACING, _avoid_kernel.table_bits(likely),
            setup.tool.radius * math.sin(setup.tool.max_tilt), period=period,
            origin=LOCK_ORIGIN * setup.viewer.eye_half_angle, slack=slack)
        # A run whose u drifts far faster than x (eyes high above the stipples)
        # outgrows the estimate: the plan starts again with room for it.
        if bad < 0 or sample_cap[bad] >= growth * first[bad]:
            break
        sample_cap[bad] *= 4
    if bad >= 0:
        x, y, z = (float(q) for q in runs.point[bad])
        raise SpecholoError(f"the striped plan for the stipple at ({x:.3g}, {y:.3g}, {z:.3g}) mm "
                            "does not settle: its glints leave the sightline crossings")
    stripes = Runs(runs.stipple[run], runs.point[run], a, b)
    cap = ((b - a) / opts.max_step + dx / opts.max_chord + 70).astype(np.int64)
    return stripes, u0, cap


def design_striped(runs: Runs, setup: Setup, opts: StripeOptions | None = None,
                   near_plate: float | None = None,
                   info: dict[str, str] | None = None) -> tuple[Grooves, np.ndarray]:
    """Striped grooves serving every run's azimuth interval.

    Args:
        runs: the (stipple, interval) pairs to serve.
        setup: light, viewer and tool.
        opts: construction options.
        near_plate: points with |p_z| at most this many mm become dimples;
            default half the groove width.
        info: if given, gets "placement", the placement used ("avoid",
            "phase" or "lock"), and where "auto" or "lock" fell back to the
            phase walk, "fallback": why.

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
    # A groove wide against the band leaves no two leaves a width apart to jump
    # between (the phase walk widens its band there instead).
    lockstep = opts.placement == "lock"
    # "lock" ends the stripes on a grid of azimuths, in the plan where "auto"
    # would plan, else in the phase walk.
    period = lock_periods(far, params, setup, w) if lockstep else None
    used = "phase"
    if opts.placement != "phase" and spacing <= AVOID_MAX_SPACING * w:
        sample_cap, likely = _plan_estimate(far, setup, opts)
        if period is not None:  # a plan sample on every grid azimuth
            sample_cap = sample_cap + _grid_steps(far, period)
        why = (_avoid_refusal(sample_cap, likely, setup) if opts.placement in ("auto", "lock")
               else None)
        planned = None
        if why is None:
            try:
                # "auto" lets a run's bound grow once: a plan far beyond its
                # estimate (eyes far above the plate) would take minutes.
                planned = _plan(far, params, setup, opts, spacing, sample_cap, likely,
                                MAX_GROWTH if opts.placement == "avoid" else 4, period)
            except SpecholoError as exc:
                if opts.placement == "avoid":
                    raise
                # "auto" never fails where the phase walk would not.
                planned, why = None, str(exc)
        if planned is not None:
            # Every planned stripe is walked alone, on its own leaf, never
            # ending early (the plan put its ends on the grid).
            far, u0, cap = planned
            w, spacing, used, period = _ONE_STRIPE, 0.0, "avoid", None
        elif info is not None and why is not None:
            info["fallback"] = why
    if period is not None:
        # The phase walk ends the stripes on the grid itself.
        cap = cap + 3 * _grid_steps(far, period) + 6
    if info is not None:
        info["placement"] = "lock" if lockstep else used
    out = GroovesBuilder()
    # Each taken sample is at most two vertices and each kept stripe has two or
    # more samples; unused room is never touched, so it takes no memory.
    total = int(cap.sum())
    out.reserve(2 * total + len(near), total // 2 + len(near))
    scratch = _Scratch()
    # Chunks end at run boundaries and keep run order: the same grooves as one walk.
    bounds = np.searchsorted(np.cumsum(cap), np.arange(CHUNK_SAMPLES, total, CHUNK_SAMPLES))
    for idx in np.split(np.arange(len(far)), np.unique(bounds)):
        if len(idx) == 0:
            continue
        chain_samples(out, _integrate(far.take(idx), params, u0[idx], cap[idx], w, spacing,
                                      scratch, None if period is None else period[idx],
                                      setup.viewer.eye_half_angle),
                      far.stipple[idx])
    out.add(dots_for(near, setup))
    return out.build(), dropped


def chain_samples(out: GroovesBuilder, samples: tuple[np.ndarray, ...],
                  ids: np.ndarray) -> None:
    """Add to ``out`` the biarc chains through runs' walked samples.

    Args:
        out: the grooves being built.
        samples: offsets (r,), count (r,), stripe (slots,), point (slots, 2),
            tangent (slots, 2) and keep (slots,), as :func:`_integrate` gives them.
        ids: (r,) each run's stipple.
    """
    offsets, count, stripe, pts, tangent, keep = samples
    kept, paths = kernel.chain_counts(offsets, count, stripe, pts, MIN_SPACING, keep)
    n_vertices = 2 * kept - paths
    path_base = np.cumsum(paths) - paths
    base, v, b, o, s = out.extend(int(n_vertices.sum()), int(paths.sum()))
    # Run r's vertices start at vertex_base[r] of the part, its paths' offsets
    # count from the first vertex of the whole.
    vertex_base = np.cumsum(n_vertices) - n_vertices
    box, length = np.empty((len(ids), 4)), np.empty(len(ids))
    kernel.chain_fill(offsets, count, stripe, pts, tangent, keep, ids,
                      vertex_base, path_base, base, v, b, o, s, box, length)
    # The extent and length, found on the way, spare a pass over the grooves.
    out.note(np.array([box[:, 0].min(), box[:, 1].min(), box[:, 2].max(),
                       box[:, 3].max()]), float(length.sum()))
