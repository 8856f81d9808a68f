"""Compiled set-up of the occlusion rays (numba, on threads over chunks of rays).

Ray k joins point i to eye j: i = j = k when every point has its own eye
(``grid`` 0), or i = k // grid, j = k % grid when every point is seen from the
same ``grid`` eyes (the azimuth grid), so the grid's rays are never spelt out.
The rays are written in the single-precision frame of the mesh's ray scene,
exactly as trimesh's embree wrapper writes them, so the hits are the same.
"""

from __future__ import annotations

import math

import numpy as np

from specholo._compiling import kernel
from specholo._threads import chunked


@kernel(helper=True)
def _pair(k: int, grid: int) -> tuple[np.int64, np.int64]:
    q = np.int64(k)  # an unsigned index: int64 // uint64 would be a float
    if grid > 0:
        return q // grid, q % grid
    return q, q


def _c_order(*arrays: np.ndarray) -> list[np.ndarray]:
    """The arrays in C order (copied only when not): numba compiles a kernel
    anew for each memory layout it is handed, and the design's eyes are C-ordered
    where verify's come transposed, which cost verify two compiles on a first run."""
    return [np.ascontiguousarray(a) for a in arrays]


#: Fewest rays per thread worth a thread's start.
_GRAIN = 4096


def facing(points: np.ndarray, normals: np.ndarray, eyes: np.ndarray, grid: int,
           n_rays: int) -> np.ndarray:
    """(n_rays,) True where the eye is on the outer side of the point's face."""
    out = np.empty(n_rays, dtype=np.bool_)
    points, normals, eyes = _c_order(points, normals, eyes)
    chunked(_facing, 0, n_rays, points, normals, eyes, grid, out, grain=_GRAIN)
    return out


@kernel(nogil=True)
def _facing(lo: int, hi: int, points: np.ndarray, normals: np.ndarray, eyes: np.ndarray,
            grid: int, out: np.ndarray) -> None:
    """:func:`facing` of rays lo .. hi - 1."""
    for k in range(lo, hi):
        i, j = _pair(k, grid)
        dx = eyes[j, 0] - points[i, 0]
        dy = eyes[j, 1] - points[i, 1]
        dz = eyes[j, 2] - points[i, 2]
        out[k] = normals[i, 0] * dx + normals[i, 1] * dy + normals[i, 2] * dz > 0.0


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
    points, normals, eyes = _c_order(points, normals, eyes)
    chunked(_rays, 0, k, points, normals, eyes, grid, idx, offset, origin, scale, o32, d32,
            grain=_GRAIN)
    return o32, d32


@kernel(nogil=True)
def _rays(lo: int, hi: int, points: np.ndarray, normals: np.ndarray, eyes: np.ndarray,
          grid: int, idx: np.ndarray, offset: float, origin: np.ndarray, scale: float,
          o32: np.ndarray, d32: np.ndarray) -> None:
    """:func:`rays` of rays idx[lo:hi]."""
    for q in range(lo, hi):
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
