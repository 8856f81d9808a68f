"""Compiled uniform sampling of a triangle mesh's surface.

The same draws and arithmetic as ``trimesh.sample.sample_surface`` (so the same
points from the same generator), without its (n, 2, 3) temporaries: at four
million candidates those cost more than the draws.
"""

from __future__ import annotations

import numpy as np

from specholo._compiling import kernel


@kernel()
def _points(vertices: np.ndarray, faces: np.ndarray, face: np.ndarray,
            lengths: np.ndarray) -> np.ndarray:
    """(n, 3) points: face[i]'s first corner plus its two edges times lengths[i]
    (a pair summing over 1 folded back into the triangle)."""
    n = face.size
    out = np.empty((n, 3))
    for i in range(n):
        a, b = lengths[i, 0], lengths[i, 1]
        if a + b > 1.0:
            a, b = abs(a - 1.0), abs(b - 1.0)
        f0, f1, f2 = faces[face[i], 0], faces[face[i], 1], faces[face[i], 2]
        for k in range(3):
            o = vertices[f0, k]
            out[i, k] = ((vertices[f1, k] - o) * a + (vertices[f2, k] - o) * b) + o
    return out


def sample_surface(vertices: np.ndarray, faces: np.ndarray, areas: np.ndarray, count: int,
                   rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``count`` points uniform over the triangles' area.

    Args:
        vertices: (v, 3) float.
        faces: (f, 3) int vertex indices.
        areas: (f,) triangle areas (the weights).
        count: how many points.
        rng: the draws (two calls, as trimesh makes them).

    Returns:
        points (count, 3) and the face of each (count,) int64.
    """
    weight_cum = np.cumsum(areas)
    face = np.searchsorted(weight_cum, rng.random(count) * weight_cum[-1]).astype(np.int64)
    lengths = rng.random((count, 2))
    return _points(np.ascontiguousarray(vertices, dtype=np.float64),
                   np.ascontiguousarray(faces, dtype=np.int64), face, lengths), face
