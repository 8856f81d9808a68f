"""Cutting order: arrange the grooves so the tool spends less time in the air.

The tool starts above the origin (plate centre), cuts the paths one after the
other and does not come back. Each path may be cut in either direction, so the
problem is an open travelling-salesman tour over paths with two ends each.

It is solved in two steps, both compiled (numba):

1. A nearest-neighbour tour from the origin: a kd-tree over the path ends that
   keeps, under each node, a count of the ends still unvisited and their
   bounding box, so a search skips the emptied parts of the plate and a step
   costs about O(log n).
2. An improvement pass of 2-opt and Or-opt moves (a run of 1-3 paths moved
   elsewhere, either way round) tried only toward the k nearest ends of each
   end, with a work queue of the paths whose neighbourhood changed ("don't look
   bits"). The open tour is closed through a free end whose distance to every
   point is 0, so a move may reverse either side of the cycle: the shorter one
   is reversed, and moves that would shift more than ``max_shift`` paths are
   skipped, which bounds the cost of a move on 10^6 paths.

Reversing a path reverses its vertices and moves each bulge to the arc's other
end with its sign flipped: the same arcs, cut the other way.
"""

from __future__ import annotations

import contextlib
import math
import os
import tempfile
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from specholo._compiling import kernel
from specholo._threads import chunked
from specholo.errors import SpecholoError
from specholo.toolpaths.grooves import Grooves

#: Gains below this (mm) are taken as rounding noise, so the passes end.
_EPS = 1e-7
_LEAF = 8


@dataclass(frozen=True)
class OrderStats:
    """How much air travel an ordering saved.

    Attributes:
        paths: number of paths (dots included).
        travel_before_mm: XY rapid travel in the given order, mm: from the
            origin to the first path, then from each path's end to the next
            path's start.
        travel_after_mm: the same in the new order, mm.
        reversed: paths cut backwards in the new order.
    """

    paths: int
    travel_before_mm: float
    travel_after_mm: float
    reversed: int


def path_ends(grooves: Grooves) -> tuple[np.ndarray, np.ndarray]:
    """First and last vertex of every path.

    Returns:
        starts (n, 2) and ends (n, 2), mm (equal for dots).
    """
    offsets = np.asarray(grooves.offsets, dtype=np.int64)
    verts = np.asarray(grooves.vertices, dtype=float).reshape(-1, 2)
    return verts[offsets[:-1]], verts[offsets[1:] - 1]


#: Paths whose air travel is summed at a time: the temporaries of a million-stipple
#: design (38 million paths) would otherwise take gigabytes (a block's are ~100 MB).
HOPS = 1 << 20


def travel_length(starts: np.ndarray, ends: np.ndarray) -> float:
    """XY air travel of cutting paths in the given order from the origin, mm.

    Args:
        starts: (n, 2) first point of each path as cut.
        ends: (n, 2) last point of each path as cut.
    """
    n = len(starts)
    return sum((float(hop_lengths(starts, ends, lo, min(lo + HOPS, n)).sum())
                for lo in range(0, n, HOPS)), 0.0)


def hop_lengths(starts: np.ndarray, ends: np.ndarray, lo: int, hi: int) -> np.ndarray:
    """Air travel (hi - lo,) onto the lo-th .. (hi - 1)-th path of (starts, ends)
    (n, 2), mm; the first path leaves from the origin."""
    prev = ends[lo - 1:lo] if lo else np.zeros((1, 2))
    return np.linalg.norm(starts[lo:hi] - np.vstack([prev, ends[lo:hi - 1]]), axis=1)


def _travel(verts: np.ndarray, offsets: np.ndarray, order: np.ndarray | None = None,
            flip: np.ndarray | None = None) -> float:
    """:func:`travel_length` of the paths of (verts, offsets) cut in ``order``,
    flipped where ``flip`` is set (default: as given), :data:`HOPS` paths at a
    time: the path ends are gathered a block at a time, never all at once."""
    n = len(offsets) - 1 if order is None else len(order)
    total, prev = 0.0, np.zeros((1, 2))
    for lo in range(0, n, HOPS):
        hi = min(lo + HOPS, n)
        p = np.arange(lo, hi) if order is None else order[lo:hi]
        a, b = verts[offsets[p]], verts[offsets[p + 1] - 1]
        if flip is not None:
            f = flip[lo:hi, None]
            a, b = np.where(f, b, a), np.where(f, a, b)
        total += float(np.linalg.norm(a - np.vstack([prev, b[:-1]]), axis=1).sum())
        prev = b[-1:]
    return total


def reorder(grooves: Grooves, order: np.ndarray, flip: np.ndarray) -> Grooves:
    """Grooves with their paths permuted and some cut backwards.

    Args:
        grooves: n paths.
        order: (n,) old index of each new path.
        flip: (n,) bool, True where the new path is the old one reversed.

    Returns:
        The reordered grooves; stipple ids follow their paths.
    """
    order = np.ascontiguousarray(order, dtype=np.int64)
    flip = np.ascontiguousarray(flip, dtype=np.bool_)
    offsets = np.ascontiguousarray(grooves.offsets, dtype=np.int64)
    sizes = np.diff(offsets)[order]
    new_offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    vertices, bulges = _reordered(
        np.ascontiguousarray(grooves.vertices, dtype=float).reshape(-1, 2),
        np.ascontiguousarray(grooves.bulges, dtype=float), offsets, order, flip, new_offsets)
    return Grooves(vertices, bulges, new_offsets,
                   np.asarray(grooves.stipple, dtype=np.int64)[order])


#: Held while the neighbours are found on every thread, when tiles are toured
#: from two threads.
_PARALLEL = threading.Lock()

#: Grooves larger than this (bytes of vertices and bulges) are reordered in
#: place when asked: the new order is staged in a scratch file, so that only
#: one copy of the grooves is ever in memory (6 GB at a million stipples).
IN_PLACE_BYTES = 1 << 30
#: Paths gathered at a time when reordering in place (~40 MB of a striped
#: design's arcs), and values read back at a time.
_BLOCK_PATHS = 1 << 18
_READ_VALUES = 1 << 22


def reorder_in_place(grooves: Grooves, order: np.ndarray, flip: np.ndarray,
                     scratch: str | os.PathLike[str]) -> Grooves:
    """:func:`reorder` into the grooves' own arrays, staged in a scratch file.

    The reordered paths (vertices, bulges, offsets and stipple ids) are gathered
    a block at a time and written to temporary files in ``scratch``, then read
    back over the old order, so memory holds one copy of the grooves and a
    block. Grooves whose arrays cannot be
    written in place (read-only, not float64 or not contiguous) are copied
    (:func:`reorder`).

    Returns:
        The same grooves object, its paths now in the new order.
    """
    v, b = grooves.vertices, grooves.bulges
    arrays = (v, b, grooves.offsets, grooves.stipple)
    if not all(isinstance(a, np.ndarray) and a.flags.writeable and a.flags.c_contiguous
               for a in arrays) or v.dtype != np.float64 or b.dtype != np.float64 \
            or grooves.offsets.dtype != np.int64:
        return reorder(grooves, order, flip)
    order = np.ascontiguousarray(order, dtype=np.int64)
    flip = np.ascontiguousarray(flip, dtype=np.bool_)
    offsets, stipple = grooves.offsets, grooves.stipple
    with contextlib.ExitStack() as stack:
        files = [stack.enter_context(tempfile.TemporaryFile(dir=scratch)) for _ in range(4)]
        total = 0
        for lo in range(0, len(order), _BLOCK_PATHS):
            o, f = order[lo:lo + _BLOCK_PATHS], flip[lo:lo + _BLOCK_PATHS]
            starts = np.zeros(len(o) + 1, dtype=np.int64)
            np.cumsum(offsets[o + 1] - offsets[o], out=starts[1:])
            part_v, part_b = _reordered(v, b, offsets, o, f, starts)
            for fh, part in zip(files, (part_v, part_b, starts[:-1] + total, stipple[o]),
                                strict=True):
                part.tofile(fh)
            total += int(starts[-1])
            del part_v, part_b
        # Read back over the old order only now: every block gathered from it.
        for fh, a in zip(files, (v, b, offsets[:-1], stipple), strict=True):
            fh.seek(0)
            flat = a.reshape(-1)
            for lo in range(0, flat.size, _READ_VALUES):
                part = np.fromfile(fh, dtype=a.dtype, count=min(_READ_VALUES, flat.size - lo))
                if not len(part):
                    raise OSError(f"scratch file {fh.name} came back short")
                flat[lo:lo + len(part)] = part
    return grooves


def _reordered(vertices: np.ndarray, bulges: np.ndarray, offsets: np.ndarray,
               order: np.ndarray, flip: np.ndarray,
               new_offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and bulges of the paths ``order`` (new_offsets[-1] of them), written
    in place (no per-vertex index arrays: 10^8 vertices would need gigabytes of
    them); ``new_offsets`` (len(order) + 1,) are where each path starts."""
    out_v = np.empty((new_offsets[-1], 2))
    out_b = np.empty(new_offsets[-1])
    chunked(_reordered_paths, 0, order.size, vertices, bulges, offsets, order, flip,
            new_offsets, out_v, out_b, grain=1024)
    return out_v, out_b


@kernel(nogil=True)
def _reordered_paths(lo: int, hi: int, vertices: np.ndarray, bulges: np.ndarray,
                     offsets: np.ndarray, order: np.ndarray, flip: np.ndarray,
                     new_offsets: np.ndarray, out_v: np.ndarray, out_b: np.ndarray) -> None:
    """:func:`_reordered` of new paths lo .. hi - 1 into out_v and out_b."""
    for k in range(lo, hi):
        a, b, dst = offsets[order[k]], offsets[order[k] + 1], new_offsets[k]
        size = b - a
        for i in range(size):
            if flip[k]:
                # A reversed path's arc from new vertex i to i + 1 is the old arc
                # from old vertex b - 2 - i to b - 1 - i, cut the other way.
                j = b - 1 - i
                out_v[dst + i, 0], out_v[dst + i, 1] = vertices[j, 0], vertices[j, 1]
                out_b[dst + i] = -bulges[b - 2 - i] if i < size - 1 else 0.0
            else:
                out_v[dst + i, 0], out_v[dst + i, 1] = vertices[a + i, 0], vertices[a + i, 1]
                out_b[dst + i] = bulges[a + i]


# ---------------------------------------------------------------------------
# kd-tree with counts of live points


@kernel(helper=True)
def _select(key: np.ndarray, other: np.ndarray, perm: np.ndarray, lo: int, hi: int,
            k: int) -> None:
    """Quickselect on key[lo:hi] (moving other and perm along) so key[k] is the k-th smallest."""
    hi -= 1
    while hi > lo:
        mid = (lo + hi) >> 1
        a, b, c = key[lo], key[mid], key[hi]
        pivot = max(min(a, b), min(max(a, b), c))
        i, j = lo, hi
        while i <= j:
            while key[i] < pivot:
                i += 1
            while key[j] > pivot:
                j -= 1
            if i <= j:
                key[i], key[j] = key[j], key[i]
                other[i], other[j] = other[j], other[i]
                perm[i], perm[j] = perm[j], perm[i]
                i += 1
                j -= 1
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            return


@kernel(nogil=True)
def _build_tree(pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                          np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """Balanced kd-tree over pts (n, 2), nodes in heap order (children 2i+1, 2i+2).

    The points are stored in tree order, so a leaf's points are contiguous and
    nearby queries touch nearby memory (this matters once the points outgrow
    the caches).

    Returns:
        perm (n,) point at each position, xs and ys (n,) coordinates by
        position, lo and hi (nodes,) position range of each node, box (nodes, 4)
        bounds, count (nodes,) points below each node, leaf_at (n,) leaf
        holding each position, and the index of the first leaf.
    """
    n = len(pts)
    depth = 0
    while (n + (1 << depth) - 1) >> depth > _LEAF:
        depth += 1
    n_nodes = (1 << (depth + 1)) - 1
    first_leaf = (1 << depth) - 1
    perm = np.arange(n)
    xs, ys = np.empty(n), np.empty(n)
    for p in range(n):  # (a loop, not copies of column views: those compile for a second)
        xs[p], ys[p] = pts[p, 0], pts[p, 1]
    lo = np.zeros(n_nodes, dtype=np.int64)
    hi = np.zeros(n_nodes, dtype=np.int64)
    box = np.empty((n_nodes, 4))
    count = np.zeros(n_nodes, dtype=np.int64)
    leaf_at = np.empty(n, dtype=np.int64)
    hi[0] = n
    for node in range(n_nodes):
        a, b = lo[node], hi[node]
        count[node] = b - a
        x0 = y0 = np.inf
        x1 = y1 = -np.inf
        for p in range(a, b):
            x0 = min(x0, xs[p])
            x1 = max(x1, xs[p])
            y0 = min(y0, ys[p])
            y1 = max(y1, ys[p])
        box[node, 0], box[node, 1], box[node, 2], box[node, 3] = x0, y0, x1, y1
        if node >= first_leaf:
            for p in range(a, b):
                leaf_at[p] = node
            continue
        mid = (a + b) >> 1
        if b - a > 1:
            if x1 - x0 >= y1 - y0:
                _select(xs, ys, perm, a, b, mid)
            else:
                _select(ys, xs, perm, a, b, mid)
        lo[2 * node + 1], hi[2 * node + 1] = a, mid
        lo[2 * node + 2], hi[2 * node + 2] = mid, b
    return perm, xs, ys, lo, hi, box, count, leaf_at, first_leaf


@kernel(helper=True)
def _box_dist2(box: np.ndarray, node: int, x: float, y: float) -> float:
    dx = max(box[node, 0] - x, 0.0, x - box[node, 2])
    dy = max(box[node, 1] - y, 0.0, y - box[node, 3])
    return dx * dx + dy * dy


@kernel(helper=True)
def _push_children(box: np.ndarray, node: int, x: float, y: float, stack: np.ndarray,
                   top: int) -> int:
    """Push a node's two children on a search stack, the farther first so the
    nearer is searched first; returns the new top."""
    left = 2 * node + 1
    right = left + 1
    if _box_dist2(box, left, x, y) <= _box_dist2(box, right, x, y):
        stack[top] = right
        stack[top + 1] = left
    else:
        stack[top] = left
        stack[top + 1] = right
    return top + 2


@kernel(helper=True)
def _nearest_live(x: float, y: float, xs: np.ndarray, ys: np.ndarray, alive: np.ndarray,
                  lo: np.ndarray, hi: np.ndarray, box: np.ndarray, count: np.ndarray,
                  first_leaf: int, stack: np.ndarray) -> int:
    """Position (in tree order) of the live point nearest (x, y), -1 if none is left."""
    best = np.inf
    best_p = -1
    stack[0] = 0
    top = 1
    while top:
        top -= 1
        node = stack[top]
        if count[node] == 0 or _box_dist2(box, node, x, y) >= best:
            continue
        if node >= first_leaf:
            for p in range(lo[node], hi[node]):
                if alive[p]:
                    dx = xs[p] - x
                    dy = ys[p] - y
                    d = dx * dx + dy * dy
                    if d < best:
                        best = d
                        best_p = p
            continue
        top = _push_children(box, node, x, y, stack, top)
    return best_p


def _knn(pts: np.ndarray, out: np.ndarray, shift: int) -> None:
    """The k nearest other points of every point, nearest first.

    Args:
        pts: (n, 2) points.
        out: (n, k) filled with the indices into pts (plus ``shift``); k < n.
        shift: added to every index written.
    """
    perm, xs, ys, lo, hi, box, _, _, first_leaf = _build_tree(pts)
    # Queries in tree order, so each chunk of them stays in one region.
    chunked(_knn_of, 0, len(pts), perm, xs, ys, lo, hi, box, first_leaf, out, shift,
            grain=1024)


@kernel(nogil=True)
def _knn_of(q0: int, q1: int, perm: np.ndarray, xs: np.ndarray, ys: np.ndarray,
            lo: np.ndarray, hi: np.ndarray, box: np.ndarray, first_leaf: int, out: np.ndarray,
            shift: int) -> None:
    """:func:`_knn` of the points at tree positions q0 .. q1 - 1 (each writes
    only its own row of out)."""
    k = out.shape[1]
    best_d = np.empty(k)
    best_p = np.empty(k, dtype=np.int64)
    stack = np.empty(2 * 64 + 4, dtype=np.int64)
    for q in range(q0, q1):
        x, y = xs[q], ys[q]
        best_d[:] = np.inf
        best_p[:] = -1
        stack[0] = 0
        top = 1
        while top:
            top -= 1
            node = stack[top]
            if _box_dist2(box, node, x, y) >= best_d[k - 1]:
                continue
            if node >= first_leaf:
                for p in range(lo[node], hi[node]):
                    dx = xs[p] - x
                    dy = ys[p] - y
                    d = dx * dx + dy * dy
                    if p == q or d >= best_d[k - 1]:
                        continue
                    j = k - 1  # insertion into the sorted short list
                    while j > 0 and best_d[j - 1] > d:
                        best_d[j] = best_d[j - 1]
                        best_p[j] = best_p[j - 1]
                        j -= 1
                    best_d[j] = d
                    best_p[j] = p
                continue
            top = _push_children(box, node, x, y, stack, top)
        row = perm[q]
        for j in range(k):
            out[row, j] = perm[best_p[j]] + shift


@kernel(helper=True)
def _shrink_boxes(leaf: int, xs: np.ndarray, ys: np.ndarray, alive: np.ndarray, lo: np.ndarray,
                  hi: np.ndarray, box: np.ndarray, count: np.ndarray) -> None:
    """Fit the boxes from a leaf up to the root to the live points left under them.

    Without this a node keeps the box of all its points however few are left,
    and late searches, when the plate is mostly cut, cannot prune.
    """
    x0 = y0 = np.inf
    x1 = y1 = -np.inf
    for p in range(lo[leaf], hi[leaf]):
        if alive[p]:
            x0 = min(x0, xs[p])
            x1 = max(x1, xs[p])
            y0 = min(y0, ys[p])
            y1 = max(y1, ys[p])
    node = leaf
    while True:
        if x0 == box[node, 0] and y0 == box[node, 1] and x1 == box[node, 2] \
                and y1 == box[node, 3]:
            return  # unchanged here, so unchanged above
        box[node, 0], box[node, 1], box[node, 2], box[node, 3] = x0, y0, x1, y1
        if node == 0:
            return
        node = (node - 1) >> 1
        x0 = y0 = np.inf
        x1 = y1 = -np.inf
        for child in (2 * node + 1, 2 * node + 2):
            if count[child]:
                x0 = min(x0, box[child, 0])
                y0 = min(y0, box[child, 1])
                x1 = max(x1, box[child, 2])
                y1 = max(y1, box[child, 3])


@kernel(nogil=True)
def _nearest_neighbour_tour(ends: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Greedy tour from the origin over paths given by their ends.

    Args:
        ends: (2n, 2) start of path j at 2j, its end at 2j + 1.

    Returns:
        order (n,) path indices, flip (n,) bool (entered at its end).
    """
    n = len(ends) // 2
    perm, xs, ys, lo, hi, box, count, leaf_at, first_leaf = _build_tree(ends)
    where = np.empty(len(ends), dtype=np.int64)
    for p in range(len(ends)):
        where[perm[p]] = p
    alive = np.ones(len(ends), dtype=np.bool_)  # by position
    stack = np.empty(2 * 64 + 4, dtype=np.int64)
    order = np.empty(n, dtype=np.int64)
    flip = np.zeros(n, dtype=np.bool_)
    x = y = 0.0
    for k in range(n):
        e = perm[_nearest_live(x, y, xs, ys, alive, lo, hi, box, count, first_leaf, stack)]
        j = e >> 1
        order[k] = j
        flip[k] = (e & 1) == 1
        for i in (2 * j, 2 * j + 1):
            p = where[i]
            alive[p] = False
            node = leaf_at[p]
            while True:
                count[node] -= 1
                if node == 0:
                    break
                node = (node - 1) >> 1
            _shrink_boxes(leaf_at[p], xs, ys, alive, lo, hi, box, count)
        other = e ^ 1
        x, y = ends[other, 0], ends[other, 1]
    return order, flip


# ---------------------------------------------------------------------------
# 2-opt and Or-opt on the closed tour
#
# Node 0 closes the tour: its end 0 is the free end (distance 0 to anything),
# its end 1 the origin. Node v > 0 is path v - 1 with ends 2v (start) and
# 2v + 1 (end). A node flipped is entered at 2v + 1: entry(v) = 2v + flip[v],
# exit(v) = 2v + 1 - flip[v]; the tour's edges join exit(tour[p]) to
# entry(tour[p + 1]), cyclically.


@kernel(helper=True)
def _d(pts: np.ndarray, a: int, b: int) -> float:
    if a == 0 or b == 0:
        return 0.0
    dx = pts[a, 0] - pts[b, 0]
    dy = pts[a, 1] - pts[b, 1]
    return np.sqrt(dx * dx + dy * dy)


@kernel()
def _entry(flip: np.ndarray, v: int) -> int:
    return 2 * v + flip[v]


@kernel()
def _exit(flip: np.ndarray, v: int) -> int:
    return 2 * v + 1 - flip[v]


@kernel(helper=True)
def _reverse(tour: np.ndarray, pos: np.ndarray, flip: np.ndarray, i: int, j: int) -> None:
    """Reverse positions i..j (cyclic) of the tour, or the rest of it if that is shorter."""
    n = len(tour)
    size = (j - i) % n + 1
    if 2 * size > n:
        i, j = (j + 1) % n, (i - 1) % n
        size = n - size
    for k in range(size // 2):
        a = (i + k) % n
        b = (j - k) % n
        tour[a], tour[b] = tour[b], tour[a]
        pos[tour[a]] = a
        pos[tour[b]] = b
    for k in range(size):
        v = tour[(i + k) % n]
        flip[v] = 1 - flip[v]


@kernel(helper=True)
def _reverse_cost(n: int, i: int, j: int) -> int:
    size = (j - i) % n + 1
    return min(size, n - size)


@kernel(helper=True)
def _move_run(tour: np.ndarray, pos: np.ndarray, flip: np.ndarray, p: int, size: int,
              q: int, backwards: bool, shift_ahead: bool) -> None:
    """Move tour[p:p + size] (cyclic) to just after position q, maybe reversed."""
    n = len(tour)
    run = np.empty(size, dtype=np.int64)
    for k in range(size):
        run[k] = tour[(p + k) % n]
    if shift_ahead:  # the paths between the run and q move back
        m = (q - (p + size)) % n + 1
        for k in range(m):
            v = tour[(p + size + k) % n]
            tour[(p + k) % n] = v
            pos[v] = (p + k) % n
        at = p + m
    else:  # the paths between q and the run move forward
        m = (p - q - 2) % n + 1
        for k in range(m):
            v = tour[(p - 1 - k) % n]
            tour[(p + size - 1 - k) % n] = v
            pos[v] = (p + size - 1 - k) % n
        at = q + 1
    for k in range(size):
        v = run[size - 1 - k] if backwards else run[k]
        if backwards:
            flip[v] = 1 - flip[v]
        tour[(at + k) % n] = v
        pos[v] = (at + k) % n


@kernel(helper=True)
def _push(queue: np.ndarray, queued: np.ndarray, tail: int, count: int, v: int) -> tuple[int, int]:
    if not queued[v]:
        queued[v] = True
        queue[tail] = v
        tail = (tail + 1) % len(queue)
        count += 1
    return tail, count


@kernel(nogil=True)
def _improve(pts: np.ndarray, cand: np.ndarray, tour: np.ndarray, flip: np.ndarray,
             max_shift: int) -> int:
    """2-opt and Or-opt moves until no candidate move gains; returns the moves made.

    Args:
        pts: (2N, 2) end points (row 0, the free end, is unused).
        cand: (2N, k) candidate ends of each end, nearest first, -1 padded.
        tour: (N,) nodes in tour order (changed in place).
        flip: (N,) 0/1 orientation of each node (changed in place).
        max_shift: largest number of nodes a move may reverse or shift.
    """
    n = len(tour)
    if n < 4:
        return 0
    pos = np.empty(n, dtype=np.int64)
    for p in range(n):
        pos[tour[p]] = p
    queue = np.empty(n, dtype=np.int64)
    queued = np.ones(n, dtype=np.bool_)
    for p in range(n):
        queue[p] = tour[p]
    head = 0
    tail = 0 * n  # (an int64, not the literal 0, which _push would compile once more for)
    count = n
    moves = 0
    touched = np.empty(6, dtype=np.int64)
    # A gain must beat the rounding of the distances compared: on paths far
    # from the origin a fixed epsilon lets rounding noise pass for gains, and
    # moves undo each other forever. The move count is bounded all the same.
    extent = 0.0
    for q in range(pts.shape[0]):
        extent = max(extent, abs(pts[q, 0]), abs(pts[q, 1]))
    eps = max(_EPS, 1e-12 * extent)
    most = 100 * n + 10_000
    while count and moves < most:
        v = queue[head]
        head = (head + 1) % n
        count -= 1
        queued[v] = False
        improved = False
        n_touched = 0

        # 2-opt from each end of v: the new edge joins that end to a near end
        for side in range(2):
            if improved:
                break
            p = pos[v]
            if side == 0:
                a = _exit(flip, v)
                b = _entry(flip, tour[(p + 1) % n])
            else:
                a = _entry(flip, v)
                b = _exit(flip, tour[(p - 1) % n])
            dab = _d(pts, a, b)
            for c in cand[a]:
                if c < 0:
                    break
                dac = _d(pts, a, c)
                if dac >= dab - eps:
                    break
                w = c >> 1
                if w == v:
                    continue
                q = pos[w]
                if side == 0:
                    if c != _exit(flip, w):
                        continue
                    d = _entry(flip, tour[(q + 1) % n])
                    i, j = (p + 1) % n, q
                else:
                    if c != _entry(flip, w):
                        continue
                    d = _exit(flip, tour[(q - 1) % n])
                    i, j = q, (p - 1) % n
                gain = dab + _d(pts, c, d) - dac - _d(pts, b, d)
                if gain > eps and _reverse_cost(n, i, j) <= max_shift:
                    _reverse(tour, pos, flip, i, j)
                    touched[0], touched[1], touched[2], touched[3] = a, b, c, d
                    n_touched = 4
                    improved = True
                    break

        # Or-opt: move the run of 1-3 nodes starting at v next to a near end
        size = 1 + 0 * n  # (an int64: the literal 1 would compile _move_run once more)
        while not improved and size <= 3 and n >= size + 3:
            p = pos[v]
            last = tour[(p + size - 1) % n]
            s1 = _entry(flip, v)
            s2 = _exit(flip, last)
            x = _exit(flip, tour[(p - 1) % n])
            y = _entry(flip, tour[(p + size) % n])
            saved = _d(pts, x, s1) + _d(pts, s2, y) - _d(pts, x, y)
            if saved > eps:
                for from_end in range(2):
                    if improved:
                        break
                    s = s2 if from_end else s1
                    for c in cand[s]:
                        if c < 0 or _d(pts, s, c) >= saved - eps:
                            break
                        w = c >> 1
                        q = pos[w]
                        if (q - p) % n < size:
                            continue  # inside the run
                        if c == _exit(flip, w):  # insert after w
                            u = q
                            e = c
                            f = _entry(flip, tour[(q + 1) % n])
                        else:  # insert before w
                            u = (q - 1) % n
                            e = _exit(flip, tour[u])
                            f = c
                        if (u + 1 - p) % n < size or (u - p) % n < size:
                            continue  # the run already sits there
                        # the run's end s meets c: forwards when s1 meets an exit
                        # or s2 an entry, else backwards
                        backwards = (c == e) == (from_end == 1)
                        if backwards:
                            added = _d(pts, e, s2) + _d(pts, s1, f) - _d(pts, e, f)
                        else:
                            added = _d(pts, e, s1) + _d(pts, s2, f) - _d(pts, e, f)
                        if saved - added <= eps:
                            continue
                        ahead = (u - (p + size)) % n + 1
                        behind = n - size - ahead
                        if min(ahead, behind) > max_shift:
                            continue
                        _move_run(tour, pos, flip, p, size, u, backwards, ahead <= behind)
                        touched[0], touched[1], touched[2] = x, y, s1
                        touched[3], touched[4], touched[5] = s2, e, f
                        n_touched = 6
                        improved = True
                        break
            size += 1

        if improved:
            moves += 1
            tail, count = _push(queue, queued, tail, count, v)
            for k in range(n_touched):
                tail, count = _push(queue, queued, tail, count, touched[k] >> 1)
    return moves


@kernel(helper=True)
def _tour_length(pts: np.ndarray, tour: np.ndarray, flip: np.ndarray) -> float:
    n = len(tour)
    total = 0.0
    for p in range(n):
        total += _d(pts, _exit(flip, tour[p]), _entry(flip, tour[(p + 1) % n]))
    return total


def _improve_order(starts: np.ndarray, ends: np.ndarray, order: np.ndarray, flip: np.ndarray,
                   neighbours: int, max_shift: int) -> tuple[np.ndarray, np.ndarray]:
    """Run the improvement pass on an open tour (order, flip) of paths."""
    n = len(order)
    order = np.asarray(order, dtype=np.int64)
    flip = np.asarray(flip, dtype=bool)
    # nodes are numbered in the given tour order, each entered at its start, so
    # the pass reads memory mostly in sequence
    pts = np.zeros((2 * n + 2, 2))
    pts[2::2] = np.where(flip[:, None], ends[order], starts[order])
    pts[3::2] = np.where(flip[:, None], starts[order], ends[order])
    k = min(neighbours, 2 * n)
    # nearest first: the free end (distance 0) leads every list, then the k
    # nearest other ends (the origin among them)
    cand = np.empty((len(pts), k + 1), dtype=np.int64)
    cand[0] = -1
    cand[1:, 0] = 0
    with _PARALLEL:  # both cores already: one tile's neighbours at a time
        _knn(pts[1:], cand[1:, 1:], 1)
    tour = np.arange(n + 1)
    flips = np.zeros(n + 1, dtype=np.int64)  # by node, not by tour position
    _improve(pts, cand, tour, flips, max_shift)
    # open the cycle at node 0 and read it the way that leaves from the origin
    tour = np.roll(tour, -int(np.flatnonzero(tour == 0)[0]))
    if flips[0]:
        rest = tour[:0:-1]
        turned = flips[rest] == 0
    else:
        rest = tour[1:]
        turned = flips[rest] == 1
    return order[rest - 1], flip[rest - 1] ^ turned


#: Paths ordered together: past this many, the plate is cut into tiles of about
#: this many paths, visited in a serpentine, each ordered on its own
#: (:func:`_tiled_tour`; the ordering's memory stays two tiles', ~0.25 GB each).
TILE_PATHS = 500_000


def _tour(starts: np.ndarray, ends: np.ndarray, neighbours: int,
          max_shift: int) -> tuple[np.ndarray, np.ndarray]:
    """The nearest-neighbour tour from the origin, improved: (order, flip) (n,)."""
    n = len(starts)
    ends2 = np.empty((2 * n, 2))
    ends2[0::2] = starts
    ends2[1::2] = ends
    order, flip = _nearest_neighbour_tour(ends2)
    del ends2
    if max_shift:
        order, flip = _improve_order(starts, ends, order, flip, neighbours, max_shift)
    return order, flip


def _ends(verts: np.ndarray, offsets: np.ndarray,
          paths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """First and last vertex (k, 2) of the paths ``paths`` (k,)."""
    return verts[offsets[paths]], verts[offsets[paths + 1] - 1]


def _tiled_tour(verts: np.ndarray, offsets: np.ndarray, neighbours: int,
                max_shift: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_tour` a tile at a time (see :data:`TILE_PATHS`), two tiles at once.

    Paths go to the tile of their chord's midpoint, in rows of tiles about as
    tall as wide, taken left to right and right to left in turn. Each tile's tour
    leaves from the middle of the tile before it (the origin for the first), so
    the tiles are independent: the tours (compiled, free of the interpreter's
    lock) run on both cores. Path ends are gathered a block or a tile at a time,
    and the order is written over the tile sort, so past the grooves memory
    holds the order and two tiles' tours.
    """
    n = len(offsets) - 1
    blocks = [(lo, min(lo + HOPS, n)) for lo in range(0, n, HOPS)]

    def mids(lo: int, hi: int) -> np.ndarray:
        s, e = _ends(verts, offsets, np.arange(lo, hi))
        return 0.5 * (s + e)

    lo = np.full(2, np.inf)
    hi = np.full(2, -np.inf)
    for a, b in blocks:
        m = mids(a, b)
        lo, hi = np.minimum(lo, m.min(axis=0)), np.maximum(hi, m.max(axis=0))
    span = hi - lo + 1e-9
    tiles = math.ceil(n / TILE_PATHS)
    rows = max(1, round(math.sqrt(tiles * span[1] / span[0])))
    cols = max(1, math.ceil(tiles / rows))
    tile = np.empty(n, dtype=np.int32)
    sums = np.zeros((rows * cols, 2))
    for a, b in blocks:
        m = mids(a, b)
        r = np.minimum((rows * (m[:, 1] - lo[1]) / span[1]).astype(np.int64), rows - 1)
        c = np.minimum((cols * (m[:, 0] - lo[0]) / span[0]).astype(np.int64), cols - 1)
        t = r * cols + np.where(r % 2 == 1, cols - 1 - c, c)
        tile[a:b] = t
        for k in range(2):
            sums[:, k] += np.bincount(t, weights=m[:, k], minlength=rows * cols)
    bounds = np.concatenate([[0], np.cumsum(np.bincount(tile, minlength=rows * cols))])
    order = np.argsort(tile, kind="stable")  # by tile; each tile's tour is written over it
    del tile
    flip = np.empty(n, dtype=bool)
    filled = [t for t in range(rows * cols) if bounds[t] < bounds[t + 1]]
    entry = {filled[0]: np.zeros(2)}
    for before, t in zip(filled[:-1], filled[1:], strict=True):
        entry[t] = sums[before] / (bounds[before + 1] - bounds[before])

    def one(t: int) -> None:
        a, b = bounds[t], bounds[t + 1]
        idx = order[a:b].copy()
        s, e = _ends(verts, offsets, idx)
        # Measured from the entry, so the tour leaves from there.
        o, f = _tour(s - entry[t], e - entry[t], neighbours, max_shift)
        order[a:b], flip[a:b] = idx[o], f

    with ThreadPoolExecutor(2) as pool:
        list(pool.map(one, filled))
    return order, flip


def order_paths(grooves: Grooves, neighbours: int = 8, max_shift: int = 1000,
                scratch: str | os.PathLike[str] | None = None) -> tuple[Grooves, OrderStats]:
    """Reorder (and reverse) paths to shorten the air travel between them.

    A nearest-neighbour tour from the origin, improved by 2-opt and Or-opt
    moves toward each end's nearest ends. The result never travels further than
    the given order: if the tour does, the given order is improved instead.
    Past :data:`TILE_PATHS` paths the plate is ordered a tile at a time.

    Args:
        grooves: n paths; the tool starts above the origin.
        neighbours: candidate ends tried per end by the improvement pass.
        max_shift: largest number of paths one move may reverse or shift (bounds
            the time per move; 0 skips the improvement pass). On a design of 3e5
            paths, 1000 gives 3 % less travel than the greedy tour and 50 000
            gives 10 %, in several times the time; travel is a small share of
            the machining time either way.
        scratch: a folder for a scratch file: grooves larger than
            :data:`IN_PLACE_BYTES` are then reordered in their own arrays
            (:func:`reorder_in_place`, the given grooves change). None: a copy.

    Returns:
        The reordered grooves (same arcs, stipple ids following their paths)
        and the travel before and after.

    Raises:
        SpecholoError: if the grooves hold an empty path or non-finite vertices,
            or ``neighbours`` < 1 or ``max_shift`` < 0.
    """
    if neighbours < 1:
        raise SpecholoError(f"neighbours must be at least 1, got {neighbours}")
    if max_shift < 0:
        raise SpecholoError(f"max shift must be >= 0, got {max_shift}")
    if grooves.has_empty_path():
        raise SpecholoError("grooves contain an empty path")
    v = grooves.vertices
    if not all(np.isfinite(v[lo:lo + HOPS]).all() for lo in range(0, len(v), HOPS)):
        raise SpecholoError("grooves contain non-finite vertices")
    n = grooves.n_paths
    offsets = np.asarray(grooves.offsets, dtype=np.int64)
    verts = np.asarray(v, dtype=float).reshape(-1, 2)
    before = _travel(verts, offsets)
    large = scratch is not None and grooves.vertices.nbytes + grooves.bulges.nbytes \
        > IN_PLACE_BYTES

    def done(order: np.ndarray, flip: np.ndarray) -> Grooves:
        if large:
            assert scratch is not None
            return reorder_in_place(grooves, order, flip, scratch)
        return reorder(grooves, order, flip)

    if n < 2:
        s, e = _ends(verts, offsets, np.arange(n))
        if n == 1 and np.hypot(*e[0]) < np.hypot(*s[0]):
            out = done(np.zeros(1, dtype=np.int64), np.ones(1, dtype=bool))
            return out, OrderStats(1, before, travel_length(e, s), 1)
        return grooves, OrderStats(n, before, before, 0)

    if n > TILE_PATHS:
        order, flip = _tiled_tour(verts, offsets, neighbours, max_shift)
        after = _travel(verts, offsets, order, flip)
        if after > before:  # improving the given order would need the whole plate's memory
            return grooves, OrderStats(n, before, before, 0)
    else:
        starts, ends = _ends(verts, offsets, np.arange(n))
        order, flip = _tour(starts, ends, neighbours, max_shift)
        after = _travel(verts, offsets, order, flip)
        if after > before:
            order, flip = np.arange(n), np.zeros(n, dtype=bool)
            if max_shift:
                order, flip = _improve_order(starts, ends, order, flip, neighbours, max_shift)
            after = _travel(verts, offsets, order, flip)
            if after > before:  # only by rounding: keep the given order
                return grooves, OrderStats(n, before, before, 0)
        del starts, ends
    return done(order, flip), OrderStats(n, before, after, int(flip.sum()))
