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
    """

    width: float
    neighbours: int
    closest_neighbours: float
    crossings: int
    crossed_length: float
    total_length: float

    def as_dict(self) -> dict[str, float]:
        """Plain numbers for JSON."""
        return {
            "width_mm": self.width, "neighbour_overlaps": self.neighbours,
            "closest_neighbours_mm": self.closest_neighbours, "crossings": self.crossings,
            "crossed_length_mm": self.crossed_length, "groove_length_mm": self.total_length,
        }


def sample_centrelines(grooves: Grooves,
                       step: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points along every path, at most ``step`` apart, each arc's ends included.

    Returns:
        points (s, 2), the path of each (s,) and the groove length each stands
        for (s,), in path order.
    """
    seg = grooves.segments()
    dots, dot_path = grooves.dots()
    if len(seg) == 0:
        return dots.reshape(-1, 2), dot_path, np.zeros(len(dot_path))
    length = seg.lengths()
    n = np.maximum(1, np.ceil(length / step).astype(np.int64))
    arc = np.repeat(np.arange(len(seg)), n)
    first = np.cumsum(n) - n
    u = (np.arange(int(n.sum())) - np.repeat(first, n)) / np.repeat(n, n)
    centre, radius, start_angle, sweep = seg.geometry()
    straight = ~np.isfinite(radius) | (np.abs(seg.bulge) < 1e-9)
    ang = start_angle[arc] + u * sweep[arc]
    on_arc = centre[arc] + radius[arc, None] * np.stack([np.cos(ang), np.sin(ang)], axis=1)
    on_line = seg.start[arc] + u[:, None] * (seg.end[arc] - seg.start[arc])
    pts = np.where(straight[arc, None], on_line, on_arc)
    # Each path's last vertex closes it.
    last = np.flatnonzero(np.r_[seg.path[1:] != seg.path[:-1], True])
    pts = np.concatenate([pts, seg.end[last], dots.reshape(-1, 2)])
    path = np.concatenate([seg.path[arc], seg.path[last], dot_path])
    share = np.concatenate([(length / n)[arc], np.zeros(len(last) + len(dot_path))])
    order = np.argsort(path, kind="stable")
    return pts[order], path[order], share[order]


@nb.njit(cache=True)
def _grid(pts: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int]:
    """Points bucketed by square cells: order, bucket starts, origin cell and grid shape."""
    n = pts.shape[0]
    x0, y0 = pts[:, 0].min(), pts[:, 1].min()
    nx = int((pts[:, 0].max() - x0) / cell) + 1
    ny = int((pts[:, 1].max() - y0) / cell) + 1
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
def _crossed(pts: np.ndarray, stipple: np.ndarray, width: float) -> np.ndarray:
    """Whether each point lies within ``width`` of another stipple's centreline."""
    n = pts.shape[0]
    out = np.zeros(n, np.bool_)
    if n == 0:
        return out
    order, start, key, nx, ny = _grid(pts, width)
    w2 = width * width
    for i in nb.prange(n):
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
        out[i] = found
    return out


@nb.njit(cache=True, parallel=True)
def _neighbour_gaps(pts: np.ndarray, first: np.ndarray, stipple: np.ndarray) -> np.ndarray:
    """Closest distance between each path's points and the next path's, when
    both draw the same stipple (inf otherwise)."""
    n_paths = first.size - 1
    gap = np.full(max(n_paths - 1, 0), np.inf)
    for p in nb.prange(n_paths - 1):
        if stipple[p] != stipple[p + 1]:
            continue
        best = np.inf
        for i in range(first[p], first[p + 1]):
            for j in range(first[p + 1], first[p + 2]):
                d = math.hypot(pts[j, 0] - pts[i, 0], pts[j, 1] - pts[i, 1])
                best = min(best, d)
        gap[p] = best
    return gap


@nb.njit(cache=True, parallel=True)
def _intersections(pts: np.ndarray, path: np.ndarray, stipple: np.ndarray,
                   cell: float) -> np.ndarray:
    """Per chord (point i to i + 1 of one path), how many later chords of other
    stipples' paths it crosses (each crossing counted once, on the earlier chord)."""
    n = pts.shape[0]
    out = np.zeros(n, np.int64)
    if n < 2:
        return out
    order, start, key, nx, ny = _grid(pts, cell)
    for i in nb.prange(n - 1):
        if path[i + 1] != path[i]:
            continue
        ax, ay = pts[i, 0], pts[i, 1]
        bx, by = pts[i + 1, 0], pts[i + 1, 1]
        cx, cy = key[i] // ny, key[i] % ny
        hits = 0
        for gx in range(max(cx - 1, 0), min(cx + 2, nx)):
            for gy in range(max(cy - 1, 0), min(cy + 2, ny)):
                c = gx * ny + gy
                for q in range(start[c], start[c + 1]):
                    j = order[q]
                    if j <= i or j + 1 >= n or path[j + 1] != path[j] \
                            or stipple[path[j]] == stipple[path[i]]:
                        continue
                    px, py = pts[j, 0], pts[j, 1]
                    qx, qy = pts[j + 1, 0], pts[j + 1, 1]
                    d1 = (bx - ax) * (py - ay) - (by - ay) * (px - ax)
                    d2 = (bx - ax) * (qy - ay) - (by - ay) * (qx - ax)
                    d3 = (qx - px) * (ay - py) - (qy - py) * (ax - px)
                    d4 = (qx - px) * (by - py) - (qy - py) * (bx - px)
                    # Half-open ends so a crossing at a shared sample counts once.
                    if ((d1 < 0.0 <= d2) or (d2 < 0.0 <= d1)) and \
                            ((d3 < 0.0 <= d4) or (d4 < 0.0 <= d3)):
                        hits += 1
        out[i] = hits
    return out


def groove_overlaps(grooves: Grooves, width: float, tolerance: float = 1e-3) -> Overlaps:
    """Measure where grooves of a given width cut into each other.

    Consecutive paths of one stipple are its neighbouring stripes (the only ones
    that meet: a stipple's stripes serve successive azimuths side by side).

    Args:
        grooves: the grooves (paths of one stipple consecutive, as designed).
        width: groove width at the plate surface, mm.
        tolerance: slack on the width, mm (the construction spaces stripes at
            exactly the width).

    Returns:
        The overlap figures.
    """
    if not (math.isfinite(width) and width > 0):
        raise ValueError(f"groove width must be positive, got {width}")
    step = width / SAMPLES_PER_WIDTH
    pts, path, share = sample_centrelines(grooves, step)
    total = float(grooves.segments().lengths().sum()) if grooves.n_paths else 0.0
    if len(pts) == 0:
        return Overlaps(width, 0, math.inf, 0, 0.0, total)
    stipple = np.asarray(grooves.stipple, dtype=np.int64)
    first = np.searchsorted(path, np.arange(grooves.n_paths + 1))
    gaps = _neighbour_gaps(pts, first, stipple)
    near = (gaps < width - tolerance) & (gaps > RETRACE)
    crossed = _crossed(pts, stipple[path], width - tolerance)
    # Chords are at most ``step`` long: two that cross start within 2 steps.
    hits = _intersections(pts, path, stipple, 2.0 * step)
    return Overlaps(
        width=width,
        neighbours=int(near.sum()),
        closest_neighbours=float(gaps[gaps > RETRACE].min(initial=math.inf)),
        crossings=int(hits.sum()),
        crossed_length=float(share[crossed].sum()),
        total_length=total,
    )
