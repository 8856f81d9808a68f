"""Where grooves come closer than a groove width: machinability of a design.

Two grooves whose centrelines are closer than the groove width cut into each
other. Within one stipple that destroys the wall a neighbouring stripe glints
on, so the striped construction keeps consecutive stripes a width apart (see
:class:`~specholo.toolpaths.striped.StripeOptions`), and this module checks it.
Between different stipples it cannot be avoided on a dense plate: both
grooves are cut, and where they cross the later cut removes a stretch of the
earlier one's walls, about a groove width long. The glints elsewhere on both
grooves are unaffected, so crossings are reported, not prevented.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from specholo.toolpaths.grooves import Grooves

#: Samples per groove width along each centreline.
SAMPLES_PER_WIDTH = 4
#: Paths of one stipple closer than this (mm) continue one groove.
RETRACE = 0.02
#: Most centreline samples the check takes over the whole design.
MAX_SAMPLES = 10_000_000
#: Most sample pairs compared between neighbouring paths over the whole design,
#: and the fewest any one pair of neighbours may use (past those the closest
#: distance is found on every few samples).
MAX_PAIRS = 200_000_000
MIN_PAIRS = 10_000
#: Side of the square windows a large design's crossings are counted in, mm.
WINDOW = 0.5
#: Centreline samples (at a quarter width) a large design's windows may hold
#: in all; and the fewest windows taken.
WINDOW_SAMPLES = 4_000_000
MIN_WINDOWS = 50
#: Most samples in the windows whose crossings are counted.
MAX_QUERIES = 50_000


@dataclass(frozen=True)
class Overlaps:
    """How much the grooves of a design cut into each other.

    Attributes:
        width: groove width the check used, mm.
        neighbours: pairs of consecutive paths of one stipple closer than the width
            (a path that resumes where the previous one ended, within
            :data:`RETRACE`, retraces the same groove and does not count).
        closest_neighbours: smallest centreline distance between consecutive
            paths of one stipple, mm (inf if no stipple has two paths).
        crossings: places where a groove's centreline crosses another stipple's.
        crossed_length: total groove length within a width of another stipple's
            groove (where the two cuts overlap), mm.
        total_length: total groove length, mm.
        coverage: groove area (length times width) over the area of the grooves'
            bounding box. A glint survives the other stipples' cuts only where
            none of them passes, so about exp(-coverage) of each eye's glints
            are left on the cut plate (random grooves; the cut simulation
            measures it).
    """

    width: float
    neighbours: int
    closest_neighbours: float
    crossings: int
    crossed_length: float
    total_length: float
    coverage: float = 0.0

    @property
    def surviving(self) -> float:
        """Expected share of one eye's glints not cut away by other grooves."""
        return math.exp(-self.coverage)

    def as_dict(self) -> dict[str, float]:
        """Plain numbers for JSON."""
        return {
            "width_mm": self.width, "neighbour_overlaps": self.neighbours,
            "closest_neighbours_mm": self.closest_neighbours, "crossings": self.crossings,
            "crossed_length_mm": self.crossed_length, "groove_length_mm": self.total_length,
            "coverage": self.coverage, "expected_surviving_glints": self.surviving,
        }


@nb.njit(cache=True)
def _sample_arcs(start: np.ndarray, end: np.ndarray, bulge: np.ndarray, path: np.ndarray,
                 step: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points along arcs in order, each path's end point included (see below)."""
    k = bulge.size
    count = np.empty(k, np.int64)
    length = np.empty(k)
    for i in range(k):
        cx, cy = end[i, 0] - start[i, 0], end[i, 1] - start[i, 1]
        chord = math.sqrt(cx * cx + cy * cy)
        sweep = 4.0 * math.atan(abs(bulge[i]))
        length[i] = chord * sweep / (2.0 * math.sin(0.5 * sweep)) if sweep > 1e-12 else chord
        count[i] = max(1, int(math.ceil(length[i] / step)))
    last = np.empty(k, np.bool_)
    for i in range(k):
        last[i] = i == k - 1 or path[i + 1] != path[i]
    total = 0
    for i in range(k):
        total += count[i] + (1 if last[i] else 0)
    pts = np.empty((total, 2))
    owner = np.empty(total, np.int64)
    share = np.zeros(total)
    q = 0
    for i in range(k):
        b = bulge[i]
        sx, sy, ex, ey = start[i, 0], start[i, 1], end[i, 0], end[i, 1]
        n = count[i]
        for j in range(n + (1 if last[i] else 0)):
            u = j / n
            # A point on the arc from its chord: bulge b turns the chord by
            # 2 atan(b u)-ish; use the exact form via the sagitta of the sub-arc.
            half = 2.0 * math.atan(b)  # half the sweep
            if abs(b) < 1e-9:
                x, y = sx + u * (ex - sx), sy + u * (ey - sy)
            else:
                # Rotate the chord direction by -half, walk the sub-arc's chord.
                cx, cy = ex - sx, ey - sy
                c = math.sqrt(cx * cx + cy * cy)
                ang = math.atan2(cy, cx) - half + u * half
                sub = c * math.sin(u * half) / math.sin(half)
                x, y = sx + sub * math.cos(ang), sy + sub * math.sin(ang)
            pts[q, 0], pts[q, 1] = x, y
            owner[q] = path[i]
            share[q] = length[i] / n if j < n else 0.0
            q += 1
    return pts, owner, share


def sample_centrelines(grooves: Grooves,
                       step: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points along every path, at most ``step`` apart, each arc's ends included.

    Returns:
        points (s, 2), the path of each (s,) and the groove length each stands
        for (s,), in path order.
    """
    seg = grooves.segments()
    dots, dot_path = grooves.dots()
    pts, path, share = _sample_arcs(seg.start, seg.end, seg.bulge, seg.path, step)
    pts = np.concatenate([pts, dots.reshape(-1, 2)])
    path = np.concatenate([path, dot_path])
    share = np.concatenate([share, np.zeros(len(dot_path))])
    if np.all(path[1:] >= path[:-1]):
        return pts, path, share
    order = np.argsort(path, kind="stable")
    return pts[order], path[order], share[order]


@nb.njit(cache=True)
def _grid(pts: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int]:
    """Points bucketed by square cells: order, bucket starts, origin cell and grid shape."""
    n = pts.shape[0]
    x0, y0 = pts[:, 0].min(), pts[:, 1].min()
    wx, wy = pts[:, 0].max() - x0, pts[:, 1].max() - y0
    # Cells never outnumber the points by much: on a large plate with a fine
    # groove the grid would not fit in memory. Larger cells keep every
    # neighbour within one cell (only more points per cell).
    most = 4 * n + 1024
    if (wx / cell + 1.0) * (wy / cell + 1.0) > most:
        cell = max(cell, math.sqrt(wx * wy / most), (wx + wy) / most)
    nx = int(wx / cell) + 1
    ny = int(wy / cell) + 1
    key = np.empty(n, np.int64)
    for i in range(n):
        key[i] = int((pts[i, 0] - x0) / cell) * ny + int((pts[i, 1] - y0) / cell)
    count = np.zeros(nx * ny + 1, np.int64)
    for i in range(n):
        count[key[i] + 1] += 1
    start = np.cumsum(count)
    fill = start[:-1].copy()
    order = np.empty(n, np.int64)
    for i in range(n):
        order[fill[key[i]]] = i
        fill[key[i]] += 1
    return order, start, key, nx, ny


@nb.njit(cache=True, parallel=True)
def _crossed(pts: np.ndarray, stipple: np.ndarray, width: float,
             query: np.ndarray) -> np.ndarray:
    """Whether each queried point lies within ``width`` of another stipple's centreline."""
    n = pts.shape[0]
    out = np.zeros(query.size, np.bool_)
    if n == 0:
        return out
    order, start, key, nx, ny = _grid(pts, width)
    w2 = width * width
    for k in nb.prange(query.size):
        i = query[k]
        cx, cy = key[i] // ny, key[i] % ny
        found = False
        for gx in range(max(cx - 1, 0), min(cx + 2, nx)):
            for gy in range(max(cy - 1, 0), min(cy + 2, ny)):
                c = gx * ny + gy
                for q in range(start[c], start[c + 1]):
                    j = order[q]
                    if stipple[j] != stipple[i]:
                        dx, dy = pts[j, 0] - pts[i, 0], pts[j, 1] - pts[i, 1]
                        if dx * dx + dy * dy < w2:
                            found = True
                            break
                if found:
                    break
            if found:
                break
        out[k] = found
    return out


@nb.njit(cache=True, parallel=True)
def _neighbour_gaps(pts: np.ndarray, first: np.ndarray, stipple: np.ndarray, limit: float,
                    min_pairs: int = MIN_PAIRS) -> tuple[int, float]:
    """Closest distance between each path's points and the next path's, when both
    draw the same stipple: how many of those gaps lie between :data:`RETRACE` and
    ``limit``, and the smallest beyond :data:`RETRACE` (inf if none).

    Counted in blocks of pairs, not kept per pair: a million stipples make ~4e7.
    """
    n_pairs = max(first.size - 2, 0)
    # Every pair of neighbours gets its share of the budget, at least MIN_PAIRS.
    pairs_of = 0
    for p in range(n_pairs):
        if stipple[p] == stipple[p + 1]:
            pairs_of += 1
    budget = max(min_pairs, MAX_PAIRS // max(pairs_of, 1))
    blocks = min(n_pairs, 4096)
    near = np.zeros(blocks, np.int64)
    closest = np.full(blocks, np.inf)
    for b in nb.prange(blocks):
        for p in range(b * n_pairs // blocks, (b + 1) * n_pairs // blocks):
            if stipple[p] != stipple[p + 1]:
                continue
            best = np.inf  # squared: one root per pair of paths
            # Two very long paths are compared on every few samples (bounded work).
            pairs = (first[p + 1] - first[p]) * (first[p + 2] - first[p + 1])
            stride = max(1, int(math.ceil(math.sqrt(pairs / budget))))
            for i in range(first[p], first[p + 1], stride):
                for j in range(first[p + 1], first[p + 2], stride):
                    dx, dy = pts[j, 0] - pts[i, 0], pts[j, 1] - pts[i, 1]
                    best = min(best, dx * dx + dy * dy)
            gap = math.sqrt(best)
            if gap > RETRACE:
                closest[b] = min(closest[b], gap)
                if gap < limit:
                    near[b] += 1
    return int(near.sum()), float(closest.min()) if blocks > 0 else math.inf


@nb.njit(cache=True, parallel=True)
def _intersections(pts: np.ndarray, path: np.ndarray, stipple: np.ndarray,
                   cell: float, query: np.ndarray) -> np.ndarray:
    """Per queried chord (point i to i + 1 of one path), how many chords of other
    stipples' paths it crosses."""
    n = pts.shape[0]
    out = np.zeros(query.size, np.int64)
    if n < 2:
        return out
    order, start, key, nx, ny = _grid(pts, cell)
    # The chords copied out in cell order, so a query reads its cells' chords
    # one after another rather than gathering each from anywhere: a chord that
    # ends its path is left out (a sentinel stipple of -1).
    cx0 = np.empty(n)
    cy0 = np.empty(n)
    cx1 = np.empty(n)
    cy1 = np.empty(n)
    owner = np.empty(n, np.int64)
    for q in nb.prange(n):
        j = order[q]
        cx0[q], cy0[q] = pts[j, 0], pts[j, 1]
        if j + 1 < n and path[j + 1] == path[j]:
            cx1[q], cy1[q] = pts[j + 1, 0], pts[j + 1, 1]
            owner[q] = stipple[path[j]]
        else:
            cx1[q], cy1[q] = cx0[q], cy0[q]
            owner[q] = -1
    for k in nb.prange(query.size):
        i = query[k]
        if i + 1 >= n or path[i + 1] != path[i]:
            continue
        ax, ay = pts[i, 0], pts[i, 1]
        bx, by = pts[i + 1, 0], pts[i + 1, 1]
        own = stipple[path[i]]
        cx, cy = key[i] // ny, key[i] % ny
        hits = 0
        for gx in range(max(cx - 1, 0), min(cx + 2, nx)):
            # A column's cells are consecutive: one run of chords per column.
            lo_c = gx * ny + max(cy - 1, 0)
            hi_c = gx * ny + min(cy + 2, ny)
            for q in range(start[lo_c], start[hi_c]):
                # Chords of the same stipple (the queried one among them) never count.
                if owner[q] == own or owner[q] < 0:
                    continue
                px, py = cx0[q], cy0[q]
                qx, qy = cx1[q], cy1[q]
                d1 = (bx - ax) * (py - ay) - (by - ay) * (px - ax)
                d2 = (bx - ax) * (qy - ay) - (by - ay) * (qx - ax)
                d3 = (qx - px) * (ay - py) - (qy - py) * (ax - px)
                d4 = (qx - px) * (by - py) - (qy - py) * (bx - px)
                # Half-open ends so a crossing at a shared sample counts once.
                if ((d1 < 0.0 <= d2) or (d2 < 0.0 <= d1)) and \
                        ((d3 < 0.0 <= d4) or (d4 < 0.0 <= d3)):
                    hits += 1
        out[k] = hits
    return out


@nb.njit(cache=True, parallel=True)
def _in_windows(vertices: np.ndarray, bulges: np.ndarray, offsets: np.ndarray,
                chosen: np.ndarray, x0: float, y0: float, side: float,
                reach: float) -> np.ndarray:
    """(q,) indices, in order, of the vertices starting an arc (or a dot) that comes
    within ``reach`` of a chosen window (chosen[i, j]: the window at x0 + i side,
    y0 + j side)."""
    n_paths = offsets.size - 1
    # The path's box first, padded by its largest sagitta (a bound: half the
    # bulge times the chord's x and y legs): most paths on a large plate pass no
    # chosen window, and their arcs need no look (nor a flag per vertex).
    passes = np.zeros(n_paths, np.bool_)
    for j in nb.prange(n_paths):
        a, b = offsets[j], offsets[j + 1]
        lo_x = hi_x = vertices[a, 0]
        lo_y = hi_y = vertices[a, 1]
        sag = 0.0
        for i in range(a + 1, b):
            x, y = vertices[i, 0], vertices[i, 1]
            lo_x, hi_x = min(lo_x, x), max(hi_x, x)
            lo_y, hi_y = min(lo_y, y), max(hi_y, y)
            sag = max(sag, 0.5 * abs(bulges[i - 1]) * (abs(x - vertices[i - 1, 0])
                                                       + abs(y - vertices[i - 1, 1])))
        passes[j] = _touches(chosen, lo_x, lo_y, hi_x, hi_y, reach + sag, x0, y0, side)
    near = np.flatnonzero(passes)
    out = np.empty((offsets[near + 1] - offsets[near]).sum(), np.int64)
    q = 0
    for k in range(near.size):
        a, b = offsets[near[k]], offsets[near[k] + 1]
        for i in range(a, max(b - 1, a + 1)):
            x1, y1 = vertices[i, 0], vertices[i, 1]
            x2, y2 = x1, y1
            if i + 1 < b:
                x2, y2 = vertices[i + 1, 0], vertices[i + 1, 1]
            # The arc stays within its sagitta of the chord.
            dx, dy = x2 - x1, y2 - y1
            sag = 0.5 * abs(bulges[i]) * math.sqrt(dx * dx + dy * dy) if i + 1 < b else 0.0
            if _touches(chosen, min(x1, x2), min(y1, y2), max(x1, x2), max(y1, y2),
                        reach + sag, x0, y0, side):
                out[q] = i
                q += 1
    return out[:q].copy()


@nb.njit(cache=True, inline="always")
def _touches(chosen: np.ndarray, lo_x: float, lo_y: float, hi_x: float, hi_y: float,
             pad: float, x0: float, y0: float, side: float) -> bool:
    """Whether the box, grown by ``pad``, meets a chosen window."""
    nx, ny = chosen.shape
    lo_i = int(math.floor((lo_x - pad - x0) / side))
    hi_i = int(math.floor((hi_x + pad - x0) / side))
    lo_j = int(math.floor((lo_y - pad - y0) / side))
    hi_j = int(math.floor((hi_y + pad - y0) / side))
    for gi in range(max(lo_i, 0), min(hi_i, nx - 1) + 1):
        for gj in range(max(lo_j, 0), min(hi_j, ny - 1) + 1):
            if chosen[gi, gj]:
                return True
    return False


@nb.njit(cache=True)
def _in_chosen(pts: np.ndarray, chosen: np.ndarray, x0: float, y0: float,
               side: float) -> np.ndarray:
    """(q,) indices of the points inside a chosen window, in order."""
    nx, ny = chosen.shape
    out = np.empty(pts.shape[0], np.int64)
    q = 0
    for i in range(pts.shape[0]):
        gi = math.floor((pts[i, 0] - x0) / side)
        gj = math.floor((pts[i, 1] - y0) / side)
        if 0 <= gi < nx and 0 <= gj < ny and chosen[int(gi), int(gj)]:
            out[q] = i
            q += 1
    return out[:q].copy()


def _windowed(grooves: Grooves, width: float, step: float, total: float, lo: np.ndarray,
              hi: np.ndarray, rng: np.random.Generator) -> tuple[int, float]:
    """Crossings and crossed length of a large design, counted in random windows.

    Square windows of side :data:`WINDOW` are drawn at random from a grid over
    the grooves; every groove passing near one is sampled at ``step`` and
    checked in full there, and the counts are scaled by all windows over those
    drawn (an unbiased estimate, whatever the design's size). ``lo``, ``hi``:
    the grooves' extent.
    """
    nx, ny = (int(v) for v in np.ceil((hi - lo) / WINDOW).clip(1))
    area = (hi[0] - lo[0] + width) * (hi[1] - lo[1] + width)
    # Samples a window holds (with its margins), from the grooves' mean density.
    per_window = total / step / area * (WINDOW + 2.0 * width + step) ** 2
    k = int(min(nx * ny, max(MIN_WINDOWS, WINDOW_SAMPLES // max(per_window, 1.0))))
    flat = np.zeros(nx * ny, dtype=np.bool_)
    flat[rng.choice(nx * ny, k, replace=False)] = True
    chosen = flat.reshape(nx, ny)
    f = np.ascontiguousarray
    verts, bulges = f(grooves.vertices, dtype=float), f(grooves.bulges, dtype=float)
    offsets = f(grooves.offsets, dtype=np.int64)
    near = _in_windows(verts, bulges, offsets, chosen, float(lo[0]), float(lo[1]), WINDOW,
                       width + 2.0 * step)
    path = np.searchsorted(offsets, near, side="right") - 1
    single = offsets[path + 1] - offsets[path] == 1
    arcs, dots = near[~single], near[single]
    # Pieces: runs of consecutive arcs of one path (a path may pass two windows).
    piece = np.cumsum(np.concatenate([[True], (np.diff(arcs) != 1)
                                      | (np.diff(path[~single]) != 0)])) - 1
    owner = np.concatenate([np.asarray(grooves.stipple)[path[~single]][
        np.flatnonzero(np.diff(np.concatenate([[-1], piece])))], grooves.stipple[path[single]]])
    pts, piece_of, share = _sample_arcs(verts[arcs], verts[arcs + 1], bulges[arcs],
                                        piece.astype(np.int64), step)
    pts = np.concatenate([pts, verts[dots]])
    piece_of = np.concatenate([piece_of, piece.max(initial=-1) + 1 + np.arange(len(dots))])
    share = np.concatenate([share, np.zeros(len(dots))])
    if len(pts) == 0:
        return 0, 0.0
    query = _in_chosen(pts, chosen, float(lo[0]), float(lo[1]), WINDOW)
    scale = nx * ny / k
    if len(query) > MAX_QUERIES:
        scale *= len(query) / MAX_QUERIES
        query = np.sort(rng.choice(query, MAX_QUERIES, replace=False))
    stipple = owner.astype(np.int64)
    crossed = _crossed(pts, stipple[piece_of], width, query)
    hits = _intersections(pts, piece_of.astype(np.int64), stipple, 2.0 * step, query)
    return int(round(0.5 * scale * hits.sum())), float(scale * share[query][crossed].sum())


def groove_overlaps(grooves: Grooves, width: float, tolerance: float = 1e-3,
                    sample: int | None = 20_000,
                    rng: np.random.Generator | None = None,
                    extent: np.ndarray | None = None,
                    total_length: float | None = None) -> Overlaps:
    """Measure where grooves of a given width cut into each other.

    Consecutive paths of one stipple are its neighbouring stripes (the only ones
    that meet: a stipple's stripes serve successive azimuths side by side).

    Args:
        grooves: the grooves (paths of one stipple consecutive, as designed).
        width: groove width at the plate surface, mm.
        tolerance: slack on the width, mm (the construction spaces stripes at
            exactly the width).
        sample: on designs with more centreline samples than this, crossings
            and crossed length are estimated from this many random samples
            (the stipple's own stripes are always checked in full); None for all.
        rng: random generator for that sample; default seeded with 0.
        extent: (2, 2) the grooves' ``extent()``, if already known.
        total_length: the sum of the paths' lengths (``measure()``), if known.

    Returns:
        The overlap figures.
    """
    if not (math.isfinite(width) and width > 0):
        raise ValueError(f"groove width must be positive, got {width}")
    tolerance = min(tolerance, 0.25 * width)  # a groove finer than the slack itself
    if extent is None or total_length is None:
        extent, lengths = grooves.measure()
        total_length = float(lengths.sum())
        del lengths
    total = total_length
    fine = width / SAMPLES_PER_WIDTH
    if total / fine + len(grooves.vertices) > MAX_SAMPLES:
        return _large_overlaps(grooves, width, tolerance, total, fine, rng,
                               extent)
    step = fine
    pts, path, share = sample_centrelines(grooves, step)
    if len(pts) == 0:
        return Overlaps(width, 0, math.inf, 0, 0.0, total)
    stipple = np.asarray(grooves.stipple, dtype=np.int64)
    first = np.searchsorted(path, np.arange(grooves.n_paths + 1))
    near, closest = _neighbour_gaps(pts, first, stipple, width - tolerance)
    span = pts.max(axis=0) - pts.min(axis=0) + width
    area = float(span[0] * span[1])
    query = np.arange(len(pts))
    scale = 1.0
    if sample is not None and len(pts) > sample:
        rng = rng if rng is not None else np.random.default_rng(0)
        query = np.sort(rng.choice(len(pts), sample, replace=False))
        scale = len(pts) / sample
    crossed = _crossed(pts, stipple[path], width - tolerance, query)
    # Chords are at most ``step`` long: two that cross start within 2 steps.
    # Each crossing is seen from both chords.
    hits = _intersections(pts, path, stipple, 2.0 * step, query)
    return Overlaps(
        width=width,
        neighbours=near,
        closest_neighbours=closest,
        crossings=int(round(0.5 * scale * hits.sum())),
        crossed_length=float(scale * share[query][crossed].sum()),
        total_length=total,
        coverage=total * width / area,
    )


def _large_overlaps(grooves: Grooves, width: float, tolerance: float, total: float,
                    step: float, rng: np.random.Generator | None,
                    extent: np.ndarray) -> Overlaps:
    """:func:`groove_overlaps` for a design too large to sample whole.

    A stipple's neighbouring stripes are compared vertex to vertex (the
    vertices are a fraction of a width apart along the paths); crossings and
    crossed length are counted in random windows (:func:`_windowed`).
    """
    f = np.ascontiguousarray
    stipple = f(grooves.stipple, dtype=np.int64)
    # The pairs' budget is shared out with no floor: the work stays bounded.
    near, closest = _neighbour_gaps(f(grooves.vertices, dtype=float),
                                    f(grooves.offsets, dtype=np.int64), stipple,
                                    width - tolerance, 1)
    lo, hi = extent
    area = float((hi[0] - lo[0] + width) * (hi[1] - lo[1] + width))
    crossings, crossed = _windowed(grooves, width - tolerance, step, total, lo, hi,
                                   rng if rng is not None else np.random.default_rng(0))
    return Overlaps(width=width, neighbours=near, closest_neighbours=closest,
                    crossings=crossings, crossed_length=crossed, total_length=total,
                    coverage=total * width / area)
