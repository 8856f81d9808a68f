"""Verification: what stereo eye pairs along the viewing arc actually see.

For each head azimuth, both eyes' glints are found on the engraved grooves,
each stipple's left and right glints are triangulated, and the apparent point
is compared with the stipple. Stipples hidden by the model should not glint.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np

from specholo.optics.stereo import triangulate
from specholo.setup import Setup
from specholo.simulation.glints import Engraved, Glints, find_glints
from specholo.toolpaths.grooves import Grooves

#: visible(points (n, 3), eyes (n, 3)) -> (n,) bool: is each point unoccluded from its eye.
VisibilityFn = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class ViewReport:
    """Figures for one head azimuth (lengths in mm).

    Attributes:
        azimuth: head azimuth in degrees.
        stipples_seen: stipples unoccluded for both eyes.
        median_error: median distance from apparent point to stipple.
        p95_error: 95th percentile of that distance.
        p95_depth_error: 95th percentile of the depth (z) part alone.
        max_error: the worst stipple's error.
        visibility: share of unoccluded stipples glinting for both eyes.
        false_glints: share of (occluded stipple, eye) pairs that glint.
    """

    azimuth: float
    stipples_seen: int
    median_error: float
    p95_error: float
    p95_depth_error: float
    max_error: float
    visibility: float
    false_glints: float


def view_azimuths(half_range: float, max_step: float = math.radians(5.0)) -> np.ndarray:
    """Evenly spaced head azimuths (radians) over +-half_range, at most max_step apart."""
    n = int(math.ceil(2.0 * half_range / max_step - 1e-9)) + 1
    return np.linspace(-half_range, half_range, max(n, 1))


def _ranges(stipple: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    count = np.bincount(stipple, minlength=n)
    return np.cumsum(count) - count, count


def stereo_errors(points: np.ndarray, left: Glints, right: Glints, eye_l: np.ndarray,
                  eye_r: np.ndarray, ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Apparent-point errors of the given stipples, which glint for both eyes.

    Each left glint is fused with the right glint of the same stipple whose
    sightline passes closest to its own (the stereo match); a stipple's error
    is the worst of its fused pairs.

    Args:
        points: (n, 3) all stipples.
        left, right: glints of each eye, sorted by stipple.
        eye_l, eye_r: (3,) eye positions.
        ids: (k,) stipple ids with glints for both eyes.

    Returns:
        error (k,) and signed depth error (k,) in mm.
    """
    n = len(points)
    start_r, count_r = _ranges(right.stipple, n)
    in_ids = np.zeros(n, dtype=bool)
    in_ids[ids] = True
    li = np.flatnonzero(in_ids[left.stipple])
    reps = count_r[left.stipple[li]]
    pair_l = np.repeat(li, reps)
    within = np.arange(pair_l.size) - np.repeat(np.cumsum(reps) - reps, reps)
    pair_r = start_r[left.stipple[pair_l]] + within
    k = pair_l.size
    if k == 0:
        return np.zeros(0), np.zeros(0)
    apparent, gap = triangulate(np.broadcast_to(eye_l, (k, 3)), left.point[pair_l],
                                np.broadcast_to(eye_r, (k, 3)), right.point[pair_r])
    stip = left.stipple[pair_l]
    delta = apparent - points[stip]
    err = np.linalg.norm(delta, axis=1)
    order = np.lexsort((gap, pair_l))
    best = order[np.r_[True, pair_l[order][1:] != pair_l[order][:-1]]]
    worst = np.full(n, -np.inf)
    np.maximum.at(worst, stip[best], err[best])
    depth = np.zeros(n)
    # Depth error of the worst pair per stipple.
    pick = best[np.isclose(err[best], worst[stip[best]])]
    depth[stip[pick]] = delta[pick, 2]
    return worst[ids], depth[ids]


def view_report(theta: float, points: np.ndarray, gl: Glints, gr: Glints, eye_l: np.ndarray,
                eye_r: np.ndarray, vis_l: np.ndarray, vis_r: np.ndarray) -> ViewReport:
    """The figures of one head from both eyes' glints, as :func:`verify` reports them.

    Args:
        theta: head azimuth, radians.
        points: (n, 3) all stipples.
        gl, gr: the left and right eye's glints, sorted by stipple.
        eye_l, eye_r: (3,) eye positions.
        vis_l, vis_r: (n,) whether each stipple is unoccluded from each eye.
    """
    n = len(points)
    # each stipple's image is its bright glints: the faint ones beside them are haze
    gl, gr = gl.image(), gr.image()
    lit_l = np.bincount(gl.stipple, minlength=n) > 0
    lit_r = np.bincount(gr.stipple, minlength=n) > 0
    seen = vis_l & vis_r
    both = np.flatnonzero(seen & lit_l & lit_r)
    if both.size:
        err, depth = stereo_errors(points, gl, gr, eye_l, eye_r, both)
    else:  # (stereo_errors needs at least one stipple)
        err = depth = np.zeros(0)
    hidden = int((~vis_l).sum() + (~vis_r).sum())
    false = int((~vis_l & lit_l).sum() + (~vis_r & lit_r).sum())
    return ViewReport(
        azimuth=math.degrees(theta),
        stipples_seen=int(seen.sum()),
        median_error=float(np.median(err)) if err.size else math.nan,
        p95_error=float(np.percentile(err, 95)) if err.size else math.nan,
        p95_depth_error=float(np.percentile(np.abs(depth), 95)) if err.size else math.nan,
        max_error=float(err.max()) if err.size else math.nan,
        visibility=float(both.size / seen.sum()) if seen.any() else math.nan,
        false_glints=float(false / hidden) if hidden else 0.0,
    )


#: Groove vertices simulated at once; bigger designs are verified in stipple
#: chunks, which gives the same figures (every glint belongs to one stipple).
#: Small chunks stay in the caches: at 10^5 stipples (24 million vertices)
#: chunks of 0.5 million verified 19 azimuths in 6.0 s and ~0 GB over the design,
#: chunks of 6 million in 8.8-11.5 s and 0.8-0.9 GB.
CHUNK_VERTICES = 500_000


def _chunks(grooves: Grooves, n: int, budget: int) -> list[tuple[int, int, np.ndarray]]:
    """Stipple ranges [lo, hi) with their paths, each holding about ``budget`` vertices."""
    per = np.bincount(grooves.stipple, weights=grooves.path_sizes, minlength=n) if n else \
        np.zeros(0)
    if n == 0 or per.sum() <= budget:
        return [(0, n, np.arange(grooves.n_paths))]
    edges = np.searchsorted(np.cumsum(per), np.arange(budget, per.sum(), budget))
    bounds = np.unique(np.concatenate([[0], edges + 1, [n]]).clip(0, n))
    order = np.argsort(grooves.stipple, kind="stable")
    cut = np.searchsorted(grooves.stipple[order], bounds)
    return [(int(bounds[i]), int(bounds[i + 1]), order[cut[i]:cut[i + 1]])
            for i in range(len(bounds) - 1)]


def verify(grooves: Grooves, points: np.ndarray, setup: Setup,
           visible: VisibilityFn | None = None,
           azimuths: np.ndarray | None = None,
           chunk_vertices: int = CHUNK_VERTICES) -> list[ViewReport]:
    """Simulate stereo eye pairs along the arc and measure what they see.

    Args:
        grooves: the engraved grooves.
        points: (n, 3) stipple points the grooves should show.
        setup: light, viewer and tool.
        visible: occlusion test; None means every stipple is unoccluded.
        azimuths: head azimuths in radians; default every <= 5 degrees over the range.
        chunk_vertices: groove vertices simulated at once (memory grows with it).

    Returns:
        One report per azimuth.
    """
    points = np.asarray(points, dtype=float)
    n = len(points)
    if azimuths is None:
        azimuths = view_azimuths(setup.viewer.half_range)
    k = len(azimuths)
    errs: list[list[np.ndarray]] = [[] for _ in range(k)]
    depths: list[list[np.ndarray]] = [[] for _ in range(k)]
    counts = np.zeros((k, 4), dtype=np.int64)  # seen, both, hidden, false
    eyes = [setup.viewer.stereo(np.array([theta])) for theta in azimuths]
    # occlusion for every stipple first (2 k n booleans): the test sees all points
    shown = np.ones((k, 2, n), dtype=bool)
    if visible is not None and n:
        for j, (eyes_l, eyes_r) in enumerate(eyes):
            shown[j, 0] = visible(points, np.broadcast_to(eyes_l[0], (n, 3)))
            shown[j, 1] = visible(points, np.broadcast_to(eyes_r[0], (n, 3)))
    for lo, hi, paths in _chunks(grooves, n, chunk_vertices):
        part = grooves.take(paths) if len(paths) != grooves.n_paths else grooves
        if lo:
            part = Grooves(part.vertices, part.bulges, part.offsets, part.stipple - lo)
        pts = points[lo:hi]
        m = hi - lo
        eng = Engraved.from_grooves(part, setup.tool)
        for j, (eyes_l, eyes_r) in enumerate(eyes):
            eye_l, eye_r = eyes_l[0], eyes_r[0]
            # each stipple's image is its bright glints (a plate verified in chunks
            # takes the typical brightness of each chunk's thousands of stipples)
            gl = find_glints(eng, eye_l, setup.light).image()
            gr = find_glints(eng, eye_r, setup.light).image()
            vis_l, vis_r = shown[j, 0, lo:hi], shown[j, 1, lo:hi]
            lit_l = np.bincount(gl.stipple, minlength=m) > 0
            lit_r = np.bincount(gr.stipple, minlength=m) > 0
            seen = vis_l & vis_r
            both = np.flatnonzero(seen & lit_l & lit_r)
            err, depth = stereo_errors(pts, gl, gr, eye_l, eye_r, both)
            errs[j].append(err)
            depths[j].append(depth)
            counts[j] += (int(seen.sum()), both.size, int((~vis_l).sum() + (~vis_r).sum()),
                          int((~vis_l & lit_l).sum() + (~vis_r & lit_r).sum()))
        del eng
    reports = []
    for j, theta in enumerate(azimuths):
        err = np.concatenate(errs[j]) if errs[j] else np.zeros(0)
        depth = np.concatenate(depths[j]) if depths[j] else np.zeros(0)
        n_seen, n_both, hidden, false = (int(v) for v in counts[j])
        reports.append(ViewReport(
            azimuth=math.degrees(theta),
            stipples_seen=n_seen,
            median_error=float(np.median(err)) if err.size else math.nan,
            p95_error=float(np.percentile(err, 95)) if err.size else math.nan,
            p95_depth_error=float(np.percentile(np.abs(depth), 95)) if err.size else math.nan,
            max_error=float(err.max()) if err.size else math.nan,
            visibility=float(n_both / n_seen) if n_seen else math.nan,
            false_glints=float(false / hidden) if hidden else 0.0,
        ))
    return reports


def summarise(reports: list[ViewReport]) -> dict[str, float]:
    """Worst figures over all azimuths."""
    def worst(key: str, fn: Callable[[list[float]], float]) -> float:
        vals = [getattr(r, key) for r in reports if not math.isnan(getattr(r, key))]
        return float(fn(vals)) if vals else math.nan

    return {
        "worst_p95_error": worst("p95_error", max),
        "worst_median_error": worst("median_error", max),
        "worst_p95_depth_error": worst("p95_depth_error", max),
        "worst_max_error": worst("max_error", max),
        "min_visibility": worst("visibility", min),
        "max_false_glints": worst("false_glints", max),
    }


def reports_to_dicts(reports: list[ViewReport]) -> list[dict[str, float]]:
    """Plain dictionaries for JSON."""
    return [asdict(r) for r in reports]
