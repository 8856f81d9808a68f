"""Compiled greedy Poisson-disk selection: one pass over the candidates in priority order.

A candidate is kept when no kept candidate lies within r. Kept points are
filed in a hash grid of cubes of side 2 r, so a point's disk reaches at most
the 8 cubes around its corner of its own cube, and each cube holds a few kept
points however the candidates clump: the pass is linear in the candidates.
The pass is bound by memory latency, so what it looks up is kept small: the
table grows with the cubes filed (not the candidates) and kept points are
copied next to each other in the order they are kept.
"""

from __future__ import annotations

import math

import numpy as np

from specholo._compiling import kernel

#: Bits per axis of a cube's packed number (three fit in an int64).
AXIS_BITS = 21
_AXIS = 1 << AXIS_BITS
_GOLDEN = -7046029254386353131  # 0x9E3779B97F4A7C15 as an int64 (2^64 / golden ratio)


@kernel(helper=True)
def _slot(table: np.ndarray, key: int) -> int:
    """Where cube ``key`` is filed in the table, or the empty slot it would take."""
    mask = table.shape[0] - 1
    h = ((key * _GOLDEN) >> 20) & mask  # Fibonacci hashing spreads the cubes
    while table[h, 0] != 0 and table[h, 0] != key:
        h = (h + 1) & mask
    return h


@kernel(helper=True)
def _grown(table: np.ndarray) -> np.ndarray:
    """The table at twice the size, every filed cube moved over."""
    new = np.zeros((2 * table.shape[0], 2), dtype=np.int64)
    for h in range(table.shape[0]):
        if table[h, 0] != 0:
            s = _slot(new, table[h, 0])
            new[s, 0], new[s, 1] = table[h, 0], table[h, 1]
    return new


@kernel()
def greedy_disk(points: np.ndarray, r: float, lo: np.ndarray, side: float) -> np.ndarray:
    """The greedy set: candidates in order, each kept if none kept is within r.

    Args:
        points: (n, 3) candidates, first chosen first.
        r: the least distance between kept points (a pair at exactly r conflicts).
        lo: (3,) a corner below every point.
        side: cube side, at least 2 r and at least the points' extent / 2^21.

    Returns:
        (n,) bool, True where kept.
    """
    n = points.shape[0]
    # Per filed cube: its packed number + 1 (0 where empty) and its last kept
    # point + 1 (0 for none), side by side so a probe reads one cache line.
    table = np.zeros((1 << 12, 2), dtype=np.int64)
    filed = 0
    # Kept points in the order kept, each with the one before it in its cube
    # (-1 for none) in the same row: one cache line per point visited.
    kept_xyz = np.empty((n, 4))
    m = 0
    kept = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        fx, fy, fz = (px - lo[0]) / side, (py - lo[1]) / side, (pz - lo[2]) / side
        cx = min(int(math.floor(fx)), _AXIS - 1)
        cy = min(int(math.floor(fy)), _AXIS - 1)
        cz = min(int(math.floor(fz)), _AXIS - 1)
        # The disk reaches the neighbour on the side of the cube's nearer face only.
        sx = -1 if fx - cx < 0.5 else 1
        sy = -1 if fy - cy < 0.5 else 1
        sz = -1 if fz - cz < 0.5 else 1
        clear = True
        for a in range(8):
            qx = cx + (sx if a & 1 else 0)
            qy = cy + (sy if a & 2 else 0)
            qz = cz + (sz if a & 4 else 0)
            if qx < 0 or qy < 0 or qz < 0 or qx >= _AXIS or qy >= _AXIS or qz >= _AXIS:
                continue
            j = table[_slot(table, ((qx << 42) | (qy << 21) | qz) + 1), 1] - 1
            while j >= 0:
                dx, dy, dz = px - kept_xyz[j, 0], py - kept_xyz[j, 1], pz - kept_xyz[j, 2]
                if math.sqrt(dx * dx + dy * dy + dz * dz) <= r:
                    clear = False
                    break
                j = int(kept_xyz[j, 3])
            if not clear:
                break
        if clear:
            kept[i] = True
            key = ((cx << 42) | (cy << 21) | cz) + 1
            h = _slot(table, key)
            if table[h, 0] == 0:
                filed += 1
                if 2 * filed > table.shape[0]:
                    table = _grown(table)
                    h = _slot(table, key)
                table[h, 0] = key
            kept_xyz[m, 0], kept_xyz[m, 1], kept_xyz[m, 2] = px, py, pz
            kept_xyz[m, 3] = table[h, 1] - 1
            table[h, 1] = m + 1
            m += 1
    return kept
