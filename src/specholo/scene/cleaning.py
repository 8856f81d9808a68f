"""A raw mesh made fit to design on, as trimesh would make it, with numpy alone.

The steps are trimesh's (``merge_vertices``, dropping faces of no area,
``remove_unreferenced_vertices``, ``fix_normals(multibody=True)``), done
operation for operation so that the mesh is the same, vertex for vertex:

- vertices whose coordinates agree to 8 decimals (of the unit box the mesh
  is scaled into) are one, the first of them kept, in order of first use;
- faces of no area (below a share of the squared diagonal) go, and the
  vertices no face uses;
- every closed body, watertight and consistently wound, whose volume is
  negative is turned inside out, so face normals point out of the solid.

A mesh whose winding is not consistent (two faces sharing an edge in the
same direction) needs trimesh's walk over the faces to make it so:
:func:`clean` returns None and the caller hands it to trimesh.
"""

from __future__ import annotations

import numpy as np

from specholo.errors import SpecholoError
from specholo.scene.mesh import Mesh

#: Decimals of the unit box to which vertices are merged (trimesh's tol.merge).
MERGE_DIGITS = 8


def clean(unit: np.ndarray, faces: np.ndarray,
          degenerate: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The cleaned mesh, or None when its winding needs trimesh.

    Args:
        unit: (n, 3) vertices scaled into the unit box, every one used by a face.
        faces: (m, 3) vertex indices.
        degenerate: faces with less area than this times the squared
            diagonal of the merged vertices' box are dropped.

    Raises:
        SpecholoError: every face has no area.
    """
    vertices, faces = _merged(unit, faces)
    diag2 = float(np.sum(np.ptp(vertices, axis=0) ** 2))
    keep = Mesh(vertices, faces).area_faces > degenerate * diag2
    if not keep.any():
        raise SpecholoError("every face of the mesh is degenerate (zero area)")
    faces = faces[keep]
    used = np.zeros(len(vertices), dtype=bool)
    used[faces] = True
    if not used.all():
        inverse = np.zeros(len(vertices), dtype=np.int64)
        inverse[used] = np.arange(int(used.sum()))
        faces = inverse[faces]
        vertices = vertices[used]
    edges = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    pairs = _shared_edges(np.sort(edges, axis=1))
    if not _wound(edges, pairs):
        return None
    return vertices, _outward(vertices, faces, edges, pairs)


def _merged(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vertices equal to MERGE_DIGITS decimals made one (the first kept, in order)."""
    key = np.ascontiguousarray((vertices * (10**MERGE_DIGITS)).round().astype(np.int64))
    rows = key.view(np.dtype((np.void, key.dtype.itemsize * 3))).ravel()
    _, index, inverse = np.unique(rows, return_index=True, return_inverse=True)
    order = index.argsort()
    first = index[order]
    rank = order.argsort()[inverse.ravel()]
    return vertices[first], rank[faces.reshape(-1)].reshape(-1, 3)


def _shared_edges(edges_sorted: np.ndarray) -> np.ndarray:
    """(k, 2) indices of the edge pairs that occur exactly twice (as trimesh's
    ``group_rows(require_count=2)``)."""
    rows = np.ascontiguousarray(edges_sorted).view(
        np.dtype((np.void, edges_sorted.dtype.itemsize * 2))).ravel()
    order = np.argsort(rows, kind="stable")
    ranked = rows[order]
    start = np.flatnonzero(np.concatenate([[True], ranked[1:] != ranked[:-1]]))
    count = np.diff(np.concatenate([start, [len(rows)]]))
    twice = start[count == 2]
    return np.stack([order[twice], order[twice + 1]], axis=1)


def _wound(edges: np.ndarray, pairs: np.ndarray) -> bool:
    """Whether every edge two faces share runs opposite ways in them."""
    a, b = edges[pairs[:, 0]], edges[pairs[:, 1]]
    return bool(np.all(a[:, 1] == b[:, 0]))


def _outward(vertices: np.ndarray, faces: np.ndarray, edges: np.ndarray,
             pairs: np.ndarray) -> np.ndarray:
    """The faces with every closed body of negative volume turned inside out."""
    adjacent = pairs // 3  # (k, 2) faces sharing an edge
    if len(adjacent) == 0:
        return faces
    label = _components(len(faces), adjacent)
    mesh = Mesh(vertices, faces)
    t, cross = mesh.triangles, mesh.triangles_cross
    f1 = t[:, 0, :] + t[:, 1, :] + t[:, 2, :]
    flip = np.zeros(len(faces), dtype=bool)
    joined = np.zeros(len(faces), dtype=bool)
    joined[adjacent.ravel()] = True  # (a face sharing no edge is in no body)
    for body in np.unique(label[joined]):
        members = np.flatnonzero((label == body) & joined)
        if len(members) < 4:
            continue
        own = edges.reshape(-1, 3, 2)[members].reshape(-1, 2)
        own_pairs = _shared_edges(np.sort(own, axis=1))
        if len(own_pairs) * 2 != len(own) or not _wound(own, own_pairs):
            continue  # not closed: flipping could only make it worse
        volume = (cross[members, 0] * f1[members, 0]).sum() / 6.0
        if volume < 0.0:
            flip[members] = True
    if flip.any():
        faces = faces.copy()
        faces[flip] = np.fliplr(faces[flip])
    return faces


def _components(n: int, pairs: np.ndarray) -> np.ndarray:
    """(n,) a label per node, equal within each connected component of ``pairs``."""
    label = np.arange(n)
    if len(pairs) == 0:
        return label
    a, b = pairs[:, 0], pairs[:, 1]
    while True:
        # Hook each edge's larger root onto the smaller, then jump to roots.
        la, lb = label[a], label[b]
        lo, hi = np.minimum(la, lb), np.maximum(la, lb)
        if np.array_equal(lo, hi):
            return label
        np.minimum.at(label, hi, lo)
        while True:
            up = label[label]
            if np.array_equal(up, label):
                break
            label = up
