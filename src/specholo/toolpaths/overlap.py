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

from specholo._compiling import kernel
from specholo._sort import stable_argsort
from specholo._threads import chunked
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
#: Longest part of an arc looked at on its own for the windows, mm: a longer
#: arc is sampled only where it passes one.
PIECE = 0.5
#: Most samples in the windows whose crossings are counted.
MAX_QUERIES = 15_000


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


def _sample_arcs(vertices: np.ndarray, bulges: np.ndarray, arcs: np.ndarray, path: np.ndarray,
                 step: float, dots: np.ndarray, dot_path: np.ndarray, u0: np.ndarray,
                 u1: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points along arcs in order, each path's end point included, then the dots.

    Args:
        vertices (m, 2), bulges (m,): the grooves' vertices.
        arcs (k,): the vertices starting the arcs sampled, and path (k,) their
            paths (a path's arcs consecutive).
        step: most distance between points, mm.
        dots (d,): vertices of dots, appended as they are, and dot_path (d,)
            their paths.
        u0 (k,), u1 (k,): the part of each arc sampled, as fractions of its
            sweep; both empty for whole arcs.

    Returns:
        points (s, 2), the path of each (s,) and the groove length each stands
        for (s,), the arcs' in order and then the dots (no length).
    """
    k = arcs.size
    count = np.empty(k, np.int64)
    length = np.empty(k)
    chunked(_arc_counts, 0, k, vertices, bulges, arcs, path, step, u0, u1, count, length,
            grain=1024)
    first = np.cumsum(count) - count
    total = int(first[-1] + count[-1]) if k else 0
    # Written once, dots included: fresh pages are slow to fault, so no second copy.
    pts = np.empty((total + dots.size, 2))
    owner = np.empty(total + dots.size, np.int64)
    share = np.zeros(total + dots.size)
    pts[total:] = vertices[dots]
    owner[total:] = dot_path
    chunked(_arc_points, 0, k, vertices, bulges, arcs, path, u0, u1, count, length, first,
            pts, owner, share, grain=1024)
    return pts, owner, share


@kernel(nogil=True)
def _arc_counts(lo: int, hi: int, vertices: np.ndarray, bulges: np.ndarray, arcs: np.ndarray,
                path: np.ndarray, step: float, u0: np.ndarray, u1: np.ndarray,
                count: np.ndarray, length: np.ndarray) -> None:
    """:func:`_sample_arcs`' points (count) and length of arcs lo .. hi - 1."""
    k = arcs.size
    whole = u0.size == 0
    for i in range(lo, hi):
        a = arcs[i]
        cx, cy = vertices[a + 1, 0] - vertices[a, 0], vertices[a + 1, 1] - vertices[a, 1]
        chord = math.sqrt(cx * cx + cy * cy)
        sweep = 4.0 * math.atan(abs(bulges[a]))
        length[i] = chord * sweep / (2.0 * math.sin(0.5 * sweep)) if sweep > 1e-12 else chord
        if not whole:
            length[i] *= u1[i] - u0[i]
        last = i == k - 1 or path[i + 1] != path[i]
        # Points of the arc, and its path's end point after the last arc.
        count[i] = max(1, int(math.ceil(length[i] / step))) + (1 if last else 0)


@kernel(nogil=True)
def _arc_points(i0: int, i1: int, vertices: np.ndarray, bulges: np.ndarray, arcs: np.ndarray,
                path: np.ndarray, u0: np.ndarray, u1: np.ndarray, count: np.ndarray,
                length: np.ndarray, first: np.ndarray, pts: np.ndarray, owner: np.ndarray,
                share: np.ndarray) -> None:
    """:func:`_sample_arcs`' points of arcs i0 .. i1 - 1, from first[i] on."""
    k = arcs.size
    whole = u0.size == 0
    for i in range(i0, i1):
        a = arcs[i]
        b = bulges[a]
        sx, sy, ex, ey = vertices[a, 0], vertices[a, 1], vertices[a + 1, 0], vertices[a + 1, 1]
        last = i == k - 1 or path[i + 1] != path[i]
        n = count[i] - (1 if last else 0)
        q = first[i]
        # A point on the arc from its chord: bulge b turns the chord by
        # 2 atan(b u)-ish; use the exact form via the sagitta of the sub-arc
        # (the arc's own constants found once, not per point).
        half = 2.0 * math.atan(b)  # half the sweep
        cx, cy = ex - sx, ey - sy
        c = math.sqrt(cx * cx + cy * cy)
        heading = math.atan2(cy, cx) - half
        sin_half = math.sin(half)
        lo, span = (0.0, 1.0) if whole else (u0[i], u1[i] - u0[i])
        for j in range(count[i]):
            u = j / n if whole else lo + span * j / n
            pts[q, 0], pts[q, 1] = _on_arc(sx, sy, cx, cy, b, c, heading, half, sin_half, u)
            owner[q] = path[i]
            share[q] = length[i] / n if j < n else 0.0
            q += 1


@kernel(helper=True)
def _on_arc(sx: float, sy: float, dx: float, dy: float, b: float, chord: float,
            heading: float, half: float, sin_half: float, u: float) -> tuple[float, float]:
    """The point a fraction u of the sweep along the arc from (sx, sy) with chord
    (dx, dy) of length ``chord`` and bulge b; half = 2 atan(b), heading = the
    chord's direction - half, sin_half = sin(half) (an arc's constants, found once)."""
    if abs(b) < 1e-9:
        return sx + u * dx, sy + u * dy
    # Rotate the chord direction by -half, walk the sub-arc's chord.
    ang = heading + u * half
    sub = chord * math.sin(u * half) / sin_half
    return sx + sub * math.cos(ang), sy + sub * math.sin(ang)


#: The parts of arcs :func:`_sample_arcs` takes for whole arcs.
_WHOLE = np.zeros(0)


def sample_centrelines(grooves: Grooves,
                       step: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points along every path, at most ``step`` apart, each arc's ends included.

    Returns:
        points (s, 2), the path of each (s,) and the groove length each stands
        for (s,), in path order.
    """
    f = np.ascontiguousarray
    arcs, path_of = grooves.arcs()
    dot_path = np.flatnonzero(grooves.is_dot)
    pts, path, share = _sample_arcs(f(grooves.vertices, dtype=float),
                                    f(grooves.bulges, dtype=float), arcs, path_of, step,
                                    np.asarray(grooves.offsets, dtype=np.int64)[dot_path],
                                    dot_path, _WHOLE, _WHOLE)
    if np.all(path[1:] >= path[:-1]):
        return pts, path, share
    order = np.argsort(path, kind="stable")
    return pts[order], path[order], share[order]


#: 2^64 over the golden ratio, as an int64: Fibonacci hashing spreads the cells.
_GOLDEN = -7046029254386353131
#: Bits for a cell's row in its packed number.
_ROW_BITS = 31


#: Most cells of the map of where queries are near (one byte each).
_MARKS = 1 << 24


@kernel()
def _buckets(pts: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                     int, float, float, float]:
    """Points bucketed by square cells, for finding those within ``reach`` of any place.

    The points (the few queried, spread over a whole plate) are hashed by cell, so
    the table is the size of the points whatever the plate's; cells are a little
    over ``reach`` across, so the points within reach of a place lie in the 3 x 3
    cells around its own (:func:`_run`). A coarse map marks where any lie, so
    most places need no look in the table (:func:`_marked`).

    Returns:
        order (n,): the points by cell; table (t, 3): per occupied cell its packed
        number + 1 (0 where empty) and its run [lo, hi) of ``order``; the map
        (mx, my) and how many cells a side of its cells spans; the origin x0, y0
        and the cell side.
    """
    n = pts.shape[0]
    # (Loops, not min and max of column views: those compile for seconds.)
    x0, y0, x1, y1 = np.inf, np.inf, -np.inf, -np.inf
    for i in range(n):
        x0, x1 = min(x0, pts[i, 0]), max(x1, pts[i, 0])
        y0, y1 = min(y0, pts[i, 1]), max(y1, pts[i, 1])
    wx, wy = x1 - x0, y1 - y0
    cell = max(reach * (1.0 + 1e-9), max(wx, wy) * (1.0 + 1e-9) / 2.0 ** (_ROW_BITS - 1),
               1e-300)
    key = np.empty(n, np.int64)
    for i in range(n):
        key[i] = (int((pts[i, 0] - x0) / cell) << _ROW_BITS) | int((pts[i, 1] - y0) / cell)
    order = stable_argsort(key)
    size = 16
    while size < 2 * n:
        size *= 2
    table = np.zeros((size, 3), np.int64)
    # The map spans cells -1 .. last + 1 (a place just off the points' box may
    # be near one), f cells a side per map cell.
    gx, gy = int(wx / cell) + 3, int(wy / cell) + 3
    f = 1
    while (gx // f + 1) * (gy // f + 1) > _MARKS:
        f += 1 + f // 4
    marks = np.zeros((gx // f + 1, gy // f + 1), np.uint8)
    lo = 0
    while lo < n:
        k = key[order[lo]]
        hi = lo + 1
        while hi < n and key[order[hi]] == k:
            hi += 1
        h = _slot(table, k + 1)
        table[h, 0], table[h, 1], table[h, 2] = k + 1, lo, hi
        cx, cy = k >> _ROW_BITS, k & ((1 << _ROW_BITS) - 1)
        for dx in range(3):
            for dy in range(3):
                marks[(cx + dx) // f, (cy + dy) // f] = 1
        lo = hi
    return order, table, marks, f, x0, y0, cell


@kernel(helper=True)
def _slot(table: np.ndarray, tag: int) -> int:
    """Where the cell numbered ``tag`` - 1 is filed, or the empty slot it would take."""
    mask = table.shape[0] - 1
    h = ((tag * _GOLDEN) >> 20) & mask
    while table[h, 0] != 0 and table[h, 0] != tag:
        h = (h + 1) & mask
    return h


@kernel(helper=True)
def _marked(marks: np.ndarray, f: int, gx: float, gy: float) -> bool:
    """Whether any bucketed point may lie in the 3 x 3 cells around cell (gx, gy)."""
    if gx < -1.0 or gy < -1.0:
        return False
    i, j = (int(gx) + 1) // f, (int(gy) + 1) // f
    return i < marks.shape[0] and j < marks.shape[1] and marks[i, j] != 0


@kernel()
def _run(table: np.ndarray, gx: float, gy: float) -> tuple[int, int]:
    """The run [lo, hi) of :func:`_buckets`' order in cell (gx, gy) (empty if none)."""
    if gx < 0.0 or gy < 0.0 or gx >= 2.0 ** (_ROW_BITS - 1) or gy >= 2.0 ** (_ROW_BITS - 1):
        return 0, 0
    h = _slot(table, ((int(gx) << _ROW_BITS) | int(gy)) + 1)
    return table[h, 1], table[h, 2]


def _blocks(n_query: int) -> int:
    """Blocks for :func:`_crossed` and :func:`_intersections`, each with its
    own (n_query,) tallies: a few per thread, within ~64 MB of tallies."""
    return max(1, min(4 * nb.get_num_threads(), (1 << 23) // max(n_query, 1)))


def _crossed(pts: np.ndarray, stipple: np.ndarray, width: float, query: np.ndarray,
             blocks: int) -> np.ndarray:
    """Whether each queried point lies within ``width`` of another stipple's centreline.

    The queries are few and the points many: the queries are bucketed, and every
    point looks up the queries around it, in ``blocks`` of points run on
    threads (:func:`~specholo._threads.chunked`), each with its own tallies.
    """
    n, n_query = pts.shape[0], query.size
    if n == 0 or n_query == 0:
        return np.zeros(n_query, np.bool_)
    order, table, marks, f, x0, y0, cell = _buckets(pts[query], width)
    # The queries copied out in bucket order, read one after another per cell.
    i = query[order]
    qx, qy = np.ascontiguousarray(pts[i, 0]), np.ascontiguousarray(pts[i, 1])
    own = np.ascontiguousarray(stipple[i], dtype=np.int64)
    found = np.zeros((blocks, n_query), np.bool_)
    chunked(_crossed_blocks, 0, blocks, pts, stipple, width * width, qx, qy, own, table,
            marks, f, x0, y0, cell, found)
    out = np.zeros(n_query, np.bool_)
    out[order] = found.any(axis=0)
    return out


@kernel(nogil=True)
def _crossed_blocks(lo: int, hi: int, pts: np.ndarray, stipple: np.ndarray, w2: float,
                    qx: np.ndarray, qy: np.ndarray, own: np.ndarray, table: np.ndarray,
                    marks: np.ndarray, f: int, x0: float, y0: float, cell: float,
                    found: np.ndarray) -> None:
    """:func:`_crossed`'s blocks lo .. hi - 1 of the points (of found.shape[0])."""
    n, blocks = pts.shape[0], found.shape[0]
    for blk in range(lo, hi):
        for j in range(blk * n // blocks, (blk + 1) * n // blocks):
            px, py, sj = pts[j, 0], pts[j, 1], stipple[j]
            gx, gy = math.floor((px - x0) / cell), math.floor((py - y0) / cell)
            if not _marked(marks, f, gx, gy):
                continue
            for a in range(9):
                lo_q, hi_q = _run(table, gx + float(a % 3 - 1), gy + float(a // 3 - 1))
                for q in range(lo_q, hi_q):
                    if not found[blk, q] and own[q] != sj:
                        dx, dy = px - qx[q], py - qy[q]
                        if dx * dx + dy * dy < w2:
                            found[blk, q] = True


@kernel()
def _budget(stipple: np.ndarray, n_pairs: int, min_pairs: int) -> int:
    """Sample pairs each pair of neighbouring paths may compare: the whole budget
    shared out, at least ``min_pairs``."""
    pairs_of = 0
    for p in range(n_pairs):
        if stipple[p] == stipple[p + 1]:
            pairs_of += 1
    return max(min_pairs, MAX_PAIRS // max(pairs_of, 1))


@kernel(helper=True)
def _gap(pts: np.ndarray, first: np.ndarray, p: int, budget: int) -> float:
    """Closest distance between path p's points and path p + 1's."""
    best = np.inf  # squared: one root per pair of paths
    # Two very long paths are compared on every few samples (bounded work).
    pairs = (first[p + 1] - first[p]) * (first[p + 2] - first[p + 1])
    stride = max(1, int(math.ceil(math.sqrt(pairs / budget))))
    for i in range(first[p], first[p + 1], stride):
        for j in range(first[p + 1], first[p + 2], stride):
            dx, dy = pts[j, 0] - pts[i, 0], pts[j, 1] - pts[i, 1]
            best = min(best, dx * dx + dy * dy)
    return math.sqrt(best)


@kernel(helper=True)
def _tally(pts: np.ndarray, first: np.ndarray, stipple: np.ndarray, p: int, budget: int,
           limit: float, near: np.ndarray, closest: np.ndarray, b: int) -> None:
    """Path p's gap to path p + 1, when both draw one stipple, into block b's count
    of gaps between :data:`RETRACE` and ``limit`` and its smallest beyond it."""
    if stipple[p] != stipple[p + 1]:
        return
    gap = _gap(pts, first, p, budget)
    if gap > RETRACE:
        closest[b] = min(closest[b], gap)
        if gap < limit:
            near[b] += 1


def _neighbour_gaps(pts: np.ndarray, first: np.ndarray, stipple: np.ndarray, limit: float,
                    min_pairs: int = MIN_PAIRS) -> tuple[int, float]:
    """Closest distance between each path's points and the next path's, when both
    draw the same stipple: how many of those gaps lie between :data:`RETRACE` and
    ``limit``, and the smallest beyond :data:`RETRACE` (inf if none).

    Counted in blocks of pairs, not kept per pair: a million stipples make ~4e7.
    """
    n_pairs = max(first.size - 2, 0)
    budget = _budget(stipple, n_pairs, min_pairs)
    blocks = min(n_pairs, 4096)
    near = np.zeros(blocks, np.int64)
    closest = np.full(blocks, np.inf)
    chunked(_gap_blocks, 0, blocks, pts, first, stipple, n_pairs, budget, limit, near, closest)
    return int(near.sum()), float(closest.min()) if blocks > 0 else math.inf


@kernel(nogil=True)
def _gap_blocks(lo: int, hi: int, pts: np.ndarray, first: np.ndarray, stipple: np.ndarray,
                n_pairs: int, budget: int, limit: float, near: np.ndarray,
                closest: np.ndarray) -> None:
    """:func:`_neighbour_gaps`' blocks lo .. hi - 1 (of near.size) of the pairs."""
    blocks = near.size
    for b in range(lo, hi):
        for p in range(b * n_pairs // blocks, (b + 1) * n_pairs // blocks):
            _tally(pts, first, stipple, p, budget, limit, near, closest, b)


def _scan(vertices: np.ndarray, bulges: np.ndarray, offsets: np.ndarray, stipple: np.ndarray,
          limit: float, chosen: np.ndarray, x0: float, y0: float, side: float,
          reach: float) -> tuple[int, float, np.ndarray]:
    """:func:`_neighbour_gaps` of the vertices (with no floor on the pairs'
    budget: the work stays bounded) and, in the same pass over the grooves,
    which paths may come within ``reach`` of a chosen window (n_paths,) (see
    :func:`_near_windows`)."""
    n_paths = offsets.size - 1
    n_pairs = max(n_paths - 1, 0)
    budget = _budget(stipple, n_pairs, 1)
    blocks = min(n_paths, 4096)
    near = np.zeros(blocks, np.int64)
    closest = np.full(blocks, np.inf)
    passes = np.zeros(n_paths, np.bool_)
    chunked(_scan_blocks, 0, blocks, vertices, bulges, offsets, stipple, n_pairs, budget, limit,
            chosen, x0, y0, side, reach, near, closest, passes)
    return int(near.sum()), float(closest.min()) if blocks > 0 else math.inf, passes


@kernel(nogil=True)
def _scan_blocks(lo: int, hi: int, vertices: np.ndarray, bulges: np.ndarray,
                 offsets: np.ndarray, stipple: np.ndarray, n_pairs: int, budget: int,
                 limit: float, chosen: np.ndarray, x0: float, y0: float, side: float,
                 reach: float, near: np.ndarray, closest: np.ndarray,
                 passes: np.ndarray) -> None:
    """:func:`_scan` of blocks lo .. hi - 1 (of near.size) of the paths."""
    n_paths, blocks = offsets.size - 1, near.size
    for b in range(lo, hi):
        for p in range(b * n_paths // blocks, (b + 1) * n_paths // blocks):
            passes[p] = _path_near(vertices, bulges, offsets[p], offsets[p + 1], chosen, x0,
                                   y0, side, reach)
            if p < n_pairs:
                _tally(vertices, offsets, stipple, p, budget, limit, near, closest, b)


def _intersections(pts: np.ndarray, path: np.ndarray, stipple: np.ndarray,
                   reach: float, query: np.ndarray, blocks: int) -> np.ndarray:
    """Per queried chord (point i to i + 1 of one path), how many chords of other
    stipples' paths it crosses.

    Chords are at most ``reach`` / 2 long, so two that cross start within reach
    of each other: the queried chords are bucketed by their start, and every
    chord looks up the queried ones starting around its own start, in
    ``blocks`` of chords run on threads, each with its own tallies.
    """
    n, n_query = pts.shape[0], query.size
    if n < 2 or n_query == 0:
        return np.zeros(n_query, np.int64)
    order, table, marks, f, x0, y0, cell = _buckets(pts[query], reach)
    chord, own = _query_chords(pts, path, stipple, query, order)
    hits = np.zeros((blocks, n_query), np.int64)
    chunked(_intersection_blocks, 0, blocks, pts, path, stipple, chord, own, table, marks, f,
            x0, y0, cell, hits)
    out = np.zeros(n_query, np.int64)
    out[order] = hits.sum(axis=0)
    return out


@kernel()
def _query_chords(pts: np.ndarray, path: np.ndarray, stipple: np.ndarray, query: np.ndarray,
                  order: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The queried chords copied out in bucket order (n_query, 4), read one after
    another per cell, and their stipples; one that ends its path is no chord (a
    stipple of -1)."""
    n, n_query = pts.shape[0], query.size
    chord = np.empty((n_query, 4))
    own = np.empty(n_query, np.int64)
    for q in range(n_query):
        i = query[order[q]]
        valid = i + 1 < n and path[i + 1] == path[i]
        own[q] = stipple[path[i]] if valid else -1
        chord[q, 0], chord[q, 1] = pts[i, 0], pts[i, 1]
        chord[q, 2], chord[q, 3] = pts[i + 1, 0] if valid else 0.0, pts[i + 1, 1] if valid else 0.0
    return chord, own


@kernel(nogil=True)
def _intersection_blocks(lo: int, hi: int, pts: np.ndarray, path: np.ndarray,
                         stipple: np.ndarray, chord: np.ndarray, own: np.ndarray,
                         table: np.ndarray, marks: np.ndarray, f: int, x0: float, y0: float,
                         cell: float, hits: np.ndarray) -> None:
    """:func:`_intersections`' blocks lo .. hi - 1 of the chords (of hits.shape[0])."""
    n, blocks = pts.shape[0], hits.shape[0]
    for blk in range(lo, hi):
        for j in range(blk * n // blocks, (blk + 1) * n // blocks):
            if j + 1 >= n or path[j + 1] != path[j]:
                continue
            px, py = pts[j, 0], pts[j, 1]
            qx, qy = pts[j + 1, 0], pts[j + 1, 1]
            gx, gy = math.floor((px - x0) / cell), math.floor((py - y0) / cell)
            if not _marked(marks, f, gx, gy):
                continue
            sj = stipple[path[j]]
            for a in range(9):
                lo_q, hi_q = _run(table, gx + float(a % 3 - 1), gy + float(a // 3 - 1))
                for q in range(lo_q, hi_q):
                    # Chords of the same stipple (the queried one among them) never count.
                    if own[q] == sj or own[q] < 0:
                        continue
                    ax, ay, bx, by = chord[q, 0], chord[q, 1], chord[q, 2], chord[q, 3]
                    d1 = (bx - ax) * (py - ay) - (by - ay) * (px - ax)
                    d2 = (bx - ax) * (qy - ay) - (by - ay) * (qx - ax)
                    d3 = (qx - px) * (ay - py) - (qy - py) * (ax - px)
                    d4 = (qx - px) * (by - py) - (qy - py) * (bx - px)
                    # Half-open ends so a crossing at a shared sample counts once.
                    if ((d1 < 0.0 <= d2) or (d2 < 0.0 <= d1)) and \
                            ((d3 < 0.0 <= d4) or (d4 < 0.0 <= d3)):
                        hits[blk, q] += 1


@kernel(helper=True)
def _path_near(vertices: np.ndarray, bulges: np.ndarray, a: int, b: int, chosen: np.ndarray,
               x0: float, y0: float, side: float, reach: float) -> bool:
    """Whether the path of vertices a .. b - 1 may come within ``reach`` of a chosen
    window: its box, padded by its largest sagitta (a bound: half the bulge times
    the chord's x and y legs). Most paths on a large plate pass no chosen window,
    and their arcs need no look (nor a flag per vertex)."""
    lo_x = hi_x = vertices[a, 0]
    lo_y = hi_y = vertices[a, 1]
    sag = 0.0
    for i in range(a + 1, b):
        x, y = vertices[i, 0], vertices[i, 1]
        lo_x, hi_x = min(lo_x, x), max(hi_x, x)
        lo_y, hi_y = min(lo_y, y), max(hi_y, y)
        sag = max(sag, 0.5 * abs(bulges[i - 1]) * (abs(x - vertices[i - 1, 0])
                                                   + abs(y - vertices[i - 1, 1])))
    return _touches(chosen, lo_x, lo_y, hi_x, hi_y, reach + sag, x0, y0, side)


@kernel()
def _near_windows(vertices: np.ndarray, bulges: np.ndarray, offsets: np.ndarray,
                  passes: np.ndarray, chosen: np.ndarray, x0: float, y0: float, side: float,
                  reach: float, piece: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The parts of arcs (and the dots) that come within ``reach`` of a chosen
    window (chosen[i, j]: the window at x0 + i side, y0 + j side), among the
    paths ``passes`` (n_paths,) flags (:func:`_path_near`).

    An arc longer than ``piece`` mm is looked at a piece of that length at a
    time, so a long groove (a classic arc's tens of mm) is sampled only where it
    passes a window, not whole for every window it passes.

    Returns:
        (q,) the vertices starting those arcs (or dots), in order, and (q,) u0
        and u1, the part of each arc, as fractions of its sweep (0 and 1 for a
        whole arc; one arc may give several parts).
    """
    near = np.flatnonzero(passes)
    cap = (offsets[near + 1] - offsets[near]).sum() + 16
    out = np.empty(cap, np.int64)
    u0, u1 = np.empty(cap), np.empty(cap)
    q = 0
    for k in range(near.size):
        a, b = offsets[near[k]], offsets[near[k] + 1]
        for i in range(a, max(b - 1, a + 1)):
            x1, y1 = vertices[i, 0], vertices[i, 1]
            x2, y2 = x1, y1
            if i + 1 < b:
                x2, y2 = vertices[i + 1, 0], vertices[i + 1, 1]
            dx, dy = x2 - x1, y2 - y1
            chord = math.sqrt(dx * dx + dy * dy)
            sweep = 4.0 * math.atan(abs(bulges[i])) if i + 1 < b else 0.0
            length = chord * sweep / (2.0 * math.sin(0.5 * sweep)) if sweep > 1e-12 else chord
            m = int(math.ceil(length / piece))
            if q + max(m, 1) > cap:  # room for this arc's parts
                cap = 2 * cap + m
                out, u0, u1 = _grown(out, q, cap), _grown(u0, q, cap), _grown(u1, q, cap)
            if m <= 1:
                # The arc stays within its sagitta of the chord.
                sag = 0.5 * abs(bulges[i]) * chord if i + 1 < b else 0.0
                if _touches(chosen, min(x1, x2), min(y1, y2), max(x1, x2), max(y1, y2),
                            reach + sag, x0, y0, side):
                    out[q], u0[q], u1[q] = i, 0.0, 1.0
                    q += 1
                continue
            # Pieces of sweep/m each, their ends on the arc as in _sample_arcs.
            half = 2.0 * math.atan(bulges[i])
            heading = math.atan2(dy, dx) - half
            sin_half = math.sin(half)
            sag = 0.5 * abs(math.tan(0.5 * half / m)) * length / m  # a piece's, at most
            open_part = False
            px, py = x1, y1
            for j in range(1, m + 1):
                u = j / m
                qx, qy = (x2, y2) if j == m else _on_arc(x1, y1, dx, dy, bulges[i], chord,
                                                          heading, half, sin_half, u)
                hit = _touches(chosen, min(px, qx), min(py, qy), max(px, qx), max(py, qy),
                               reach + sag, x0, y0, side)
                if hit and open_part:
                    u1[q - 1] = u
                elif hit:
                    out[q], u0[q], u1[q] = i, (j - 1) / m, u
                    q += 1
                open_part = hit
                px, py = qx, qy
    return out[:q].copy(), u0[:q].copy(), u1[:q].copy()


@kernel(helper=True)
def _grown(a: np.ndarray, n: int, size: int) -> np.ndarray:
    """A copy of a[:n] with room for ``size``."""
    out = np.empty(size, a.dtype)
    for i in range(n):  # (not out[:n] = a[:n]: slice setting compiles for seconds)
        out[i] = a[i]
    return out


@kernel(helper=True)
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


@kernel()
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


def _windows(width: float, step: float, total: float, lo: np.ndarray, hi: np.ndarray,
             rng: np.random.Generator) -> tuple[np.ndarray, int]:
    """The random windows a large design's crossings are counted in: chosen
    (nx, ny) over a grid of side :data:`WINDOW` from ``lo``, and how many."""
    nx, ny = (int(v) for v in np.ceil((hi - lo) / WINDOW).clip(1))
    area = (hi[0] - lo[0] + width) * (hi[1] - lo[1] + width)
    # Samples a window holds (with its margins), from the grooves' mean density.
    per_window = total / step / area * (WINDOW + 2.0 * width + step) ** 2
    k = int(min(nx * ny, max(MIN_WINDOWS, WINDOW_SAMPLES // max(per_window, 1.0))))
    flat = np.zeros(nx * ny, dtype=np.bool_)
    flat[rng.choice(nx * ny, k, replace=False)] = True
    return flat.reshape(nx, ny), k


def _windowed(grooves: Grooves, width: float, step: float, lo: np.ndarray,
              chosen: np.ndarray, k: int, passes: np.ndarray,
              rng: np.random.Generator) -> tuple[int, float]:
    """Crossings and crossed length of a large design, counted in random windows.

    Square windows of side :data:`WINDOW` are drawn at random from a grid over
    the grooves (:func:`_windows`: ``chosen``, k of them); every groove passing
    near one (``passes``, per path, from :func:`_scan`) is sampled at ``step``
    and checked in full there, and the counts are scaled by all windows over
    those drawn (an unbiased estimate, whatever the design's size). ``lo``: the
    grooves' lower corner.
    """
    nx, ny = chosen.shape
    f = np.ascontiguousarray
    verts, bulges = f(grooves.vertices, dtype=float), f(grooves.bulges, dtype=float)
    offsets = f(grooves.offsets, dtype=np.int64)
    near, u0, u1 = _near_windows(verts, bulges, offsets, passes, chosen, float(lo[0]),
                                 float(lo[1]), WINDOW, width + 2.0 * step, PIECE)
    path = np.searchsorted(offsets, near, side="right") - 1
    single = offsets[path + 1] - offsets[path] == 1
    arcs, dots = near[~single], near[single]
    u0, u1 = u0[~single], u1[~single]
    # Pieces: runs of consecutive arcs of one path (a path may pass two windows),
    # joined only where one arc's part runs to its end and the next from its start.
    piece = np.cumsum(np.concatenate([[True], (np.diff(arcs) != 1)
                                      | (np.diff(path[~single]) != 0)
                                      | (u1[:-1] < 1.0) | (u0[1:] > 0.0)])) - 1
    owner = np.concatenate([np.asarray(grooves.stipple)[path[~single]][
        np.flatnonzero(np.diff(np.concatenate([[-1], piece])))], grooves.stipple[path[single]]])
    pts, piece_of, share = _sample_arcs(verts, bulges, arcs, piece.astype(np.int64), step,
                                        dots, piece.max(initial=-1) + 1 + np.arange(len(dots)),
                                        u0, u1)
    if len(pts) == 0:
        return 0, 0.0
    query = _in_chosen(pts, chosen, float(lo[0]), float(lo[1]), WINDOW)
    scale = nx * ny / k
    if len(query) > MAX_QUERIES:
        scale *= len(query) / MAX_QUERIES
        query = np.sort(rng.choice(query, MAX_QUERIES, replace=False))
    stipple = owner.astype(np.int64)
    blocks = _blocks(len(query))
    crossed = _crossed(pts, stipple[piece_of], width, query, blocks)
    hits = _intersections(pts, piece_of.astype(np.int64), stipple, 2.0 * step, query, blocks)
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
    blocks = _blocks(len(query))
    crossed = _crossed(pts, stipple[path], width - tolerance, query, blocks)
    # Chords are at most ``step`` long: two that cross start within 2 steps.
    # Each crossing is seen from both chords.
    hits = _intersections(pts, path, stipple, 2.0 * step, query, blocks)
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
    rng = rng if rng is not None else np.random.default_rng(0)
    lo, hi = extent
    chosen, k = _windows(width - tolerance, step, total, lo, hi, rng)
    # One pass over the grooves for the neighbours' gaps and the windows' paths.
    near, closest, passes = _scan(
        f(grooves.vertices, dtype=float), f(grooves.bulges, dtype=float),
        f(grooves.offsets, dtype=np.int64), f(grooves.stipple, dtype=np.int64),
        width - tolerance, chosen, float(lo[0]), float(lo[1]), WINDOW,
        width - tolerance + 2.0 * step)
    area = float((hi[0] - lo[0] + width) * (hi[1] - lo[1] + width))
    crossings, crossed = _windowed(grooves, width - tolerance, step, lo, chosen, k, passes,
                                   rng)
    # An estimate: where nearly every groove is crossed it can come out above the whole.
    return Overlaps(width=width, neighbours=near, closest_neighbours=closest,
                    crossings=crossings, crossed_length=min(crossed, total), total_length=total,
                    coverage=total * width / area)
