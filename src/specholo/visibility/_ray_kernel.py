"""Compiled set-up of the occlusion rays (numba, parallel over rays).

Ray k joins point i to eye j: i = j = k when every point has its own eye
(``grid`` 0), or i = k // grid, j = k % grid when every point is seen from the
same ``grid`` eyes (the azimuth grid), so the grid's rays are never spelt out.
The rays are written in the single-precision frame of the mesh's ray scene,
exactly as trimesh's embree wrapper writes them, so the hits are the same.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np


@nb.njit(cache=True, inline="always")
def _pair(k: int, grid: int) -> tuple[np.int64, np.int64]:
    q = np.int64(k)  # a prange index is unsigned: int64 // uint64 would be a float
    if grid > 0:
        return q // grid, q % grid
    return q, q


@nb.njit(cache=True, parallel=True)
def facing(points: np.ndarray, normals: np.ndarray, eyes: np.ndarray, grid: int,
           n_rays: int) -> np.ndarray:
    """(n_rays,) True where the eye is on the outer side of the point's face."""
    out = np.empty(n_rays, dtype=np.bool_)
    for k in nb.prange(n_rays):
        i, j = _pair(k, grid)
        dx = eyes[j, 0] - points[i, 0]
        dy = eyes[j, 1] - points[i, 1]
        dz = eyes[j, 2] - points[i, 2]
        out[k] = normals[i, 0] * dx + normals[i, 1] * dy + normals[i, 2] * dz > 0.0
    return out


@nb.njit(cache=True, parallel=True)
def rays(points: np.ndarray, normals: np.ndarray, eyes: np.ndarray, grid: int,
         idx: np.ndarray, offset: float, origin: np.ndarray,
         scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Origins (lifted ``offset`` off the face) and unit directions of rays ``idx``.

    Returns:
        origins (k, 3) and directions (k, 3), float32, in the scene's frame:
        (x - origin) * scale.
    """
    k = idx.size
    o32 = np.empty((k, 3), dtype=np.float32)
    d32 = np.empty((k, 3), dtype=np.float32)
    for q in nb.prange(k):
        i, j = _pair(idx[q], grid)
        ox = points[i, 0] + offset * normals[i, 0]
        oy = points[i, 1] + offset * normals[i, 1]
        oz = points[i, 2] + offset * normals[i, 2]
        tx, ty, tz = eyes[j, 0] - ox, eyes[j, 1] - oy, eyes[j, 2] - oz
        reach = math.sqrt(tx * tx + ty * ty + tz * tz)
        vx = np.float32(tx / reach)
        vy = np.float32(ty / reach)
        vz = np.float32(tz / reach)
        # trimesh re-normalises the single-precision direction in double.
        inv = 1.0 / math.sqrt(np.float64(vx * vx) + np.float64(vy * vy) + np.float64(vz * vz))
        d32[q, 0], d32[q, 1], d32[q, 2] = vx * inv, vy * inv, vz * inv
        # trimesh rounds the origin to single precision before moving it.
        o32[q, 0] = (np.float64(np.float32(ox)) - origin[0]) * scale
        o32[q, 1] = (np.float64(np.float32(oy)) - origin[1]) * scale
        o32[q, 2] = (np.float64(np.float32(oz)) - origin[2]) * scale
    return o32, d32
