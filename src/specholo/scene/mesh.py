"""A triangle mesh as the design uses it: vertices, faces and what follows from them.

The design needs a model's triangles, their areas and outward normals, its
size, a PLY to keep beside the grooves and, for occlusion, the arrays an
embree scene is built from. :class:`Mesh` holds just that, with numpy alone:
importing trimesh (and with it scipy and networkx) takes longer than a small
design. Its figures are computed as trimesh computes them, operation for
operation, so a design is the same whichever type holds the model;
:meth:`Mesh.to_trimesh` gives a trimesh for what only trimesh does (rays
without embree, surface sampling of a turning model, other export formats).
"""

from __future__ import annotations

import functools
import io
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from specholo.errors import SpecholoError

if TYPE_CHECKING:
    import trimesh

#: Below this a cross product's length is zero (trimesh's ``util.TOL_ZERO``).
TOL_ZERO = 1e-13
#: The PLY header's comment line.
PLY_COMMENT = b"comment specholo model"
#: PLY property types -> numpy little-endian dtypes.
PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "<i2",
              "int16": "<i2", "ushort": "<u2", "uint16": "<u2", "int": "<i4", "int32": "<i4",
              "uint": "<u4", "uint32": "<u4", "float": "<f4", "float32": "<f4",
              "double": "<f8", "float64": "<f8"}


class Mesh:
    """A triangle mesh whose arrays do not change.

    Attributes:
        vertices: (n, 3) float64 vertex positions, read-only.
        faces: (m, 3) int64 vertex indices, counter-clockwise seen from the
            outer side, read-only.
    """

    def __init__(self, vertices: Any, faces: Any) -> None:
        v = np.array(vertices, dtype=np.float64)
        f = np.array(faces, dtype=np.int64)
        if v.ndim != 2 or v.shape[1] != 3:
            raise SpecholoError(f"mesh vertices must have shape (n, 3), got {v.shape}")
        if f.ndim != 2 or f.shape[1] != 3:
            raise SpecholoError(f"mesh faces must have shape (m, 3), got {f.shape}")
        if f.size and (f.min() < 0 or f.max() >= len(v)):
            raise SpecholoError("mesh face indices out of range")
        v.flags.writeable = False
        f.flags.writeable = False
        self.vertices = v
        self.faces = f

    def __repr__(self) -> str:
        return f"Mesh({len(self.vertices)} vertices, {len(self.faces)} faces)"

    # The arrays never change, so identity is the mesh's key (a scene built
    # for it stays valid); the cached figures are computed once.

    @functools.cached_property
    def triangles(self) -> np.ndarray:
        """(m, 3, 3) the faces' corners."""
        return self.vertices[self.faces]

    @functools.cached_property
    def triangles_cross(self) -> np.ndarray:
        """(m, 3) (b - a) x (c - b) of each face: twice its area along its normal."""
        t = self.triangles
        vectors = t[:, 1:, :] - t[:, :2, :]
        return np.cross(vectors[:, 0], vectors[:, 1])

    @functools.cached_property
    def face_normals(self) -> np.ndarray:
        """(m, 3) unit normals, zero for a face of no area."""
        if len(self.faces) == 0:
            return np.zeros((0, 3))
        c = self.triangles_cross
        norm = np.sqrt(np.dot(c * c, [1.0, 1.0, 1.0]))
        valid = norm > TOL_ZERO
        norm[valid] **= -1
        unit = c * norm.reshape((-1, 1))
        out = np.zeros((len(c), 3))
        out[valid] = unit[valid]
        return out

    @functools.cached_property
    def area_faces(self) -> np.ndarray:
        """(m,) face areas."""
        c = self.triangles_cross
        return np.sqrt((c**2).sum(axis=1)) / 2.0

    @functools.cached_property
    def area(self) -> float:
        """The surface's area."""
        return float(self.area_faces.sum())

    @functools.cached_property
    def bounds(self) -> np.ndarray:
        """(2, 3) lowest and highest corner of the box about the vertices the faces use."""
        used = self.vertices[np.unique(self.faces)] if len(self.faces) else self.vertices
        if len(used) == 0:
            return np.zeros((2, 3))
        return np.array([used.min(axis=0), used.max(axis=0)])

    @functools.cached_property
    def scale(self) -> float:
        """The bounding box's diagonal (1 for a mesh of no extent)."""
        extents = np.ptp(self.bounds, axis=0)
        scale = float((extents**2).sum() ** 0.5)
        return scale if scale >= TOL_ZERO else 1.0

    @functools.cached_property
    def _trimesh(self) -> trimesh.Trimesh:
        import trimesh

        return trimesh.Trimesh(vertices=self.vertices.copy(), faces=self.faces.copy(),
                               process=False)

    def to_trimesh(self) -> trimesh.Trimesh:
        """The same mesh as a trimesh (one, kept: do not change it)."""
        return self._trimesh

    @property
    def ray(self) -> Any:
        """trimesh's ray queries of this mesh (for occlusion without embree)."""
        return self._trimesh.ray

    def export(self, file_obj: str | os.PathLike[str] | None = None,
               file_type: str = "ply") -> bytes:
        """The mesh as a binary little-endian PLY (float64 vertices, int32 faces).

        Args:
            file_obj: a path to write as well, or None.
            file_type: "ply" (other formats through :meth:`to_trimesh`).

        Returns:
            The file's bytes.
        """
        if file_type != "ply":
            raise SpecholoError(f"a mesh is written as PLY, not {file_type!r}")
        data = ply_bytes(self.vertices, self.faces)
        if file_obj is not None:
            Path(file_obj).write_bytes(data)
        return data


def ply_bytes(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    """A binary little-endian PLY of (n, 3) vertices and (m, 3) triangles."""
    head = b"\n".join([
        b"ply", b"format binary_little_endian 1.0", PLY_COMMENT,
        b"element vertex %d" % len(vertices),
        b"property double x", b"property double y", b"property double z",
        b"element face %d" % len(faces),
        b"property list uchar int vertex_indices", b"end_header", b""])
    rows = np.empty(len(faces), dtype=[("n", "u1"), ("v", "<i4", (3,))])
    rows["n"] = 3
    rows["v"] = faces
    out = io.BytesIO()
    out.write(head)
    out.write(np.ascontiguousarray(vertices, dtype="<f8").tobytes())
    out.write(rows.tobytes())
    return out.getvalue()


def read_ply(data: bytes) -> tuple[np.ndarray, np.ndarray] | None:
    """Vertices (n, 3) float64 and faces (m, 3) int64 of a simple binary PLY.

    Reads a binary little-endian PLY whose only elements are ``vertex`` (x, y,
    z first, any scalar properties) and ``face`` (one list of triangles'
    indices), as specholo and trimesh write them. Returns None for any other
    PLY (or one whose data does not fit its header), for a reader that knows
    them all to read or refuse.
    """
    end = data.find(b"end_header\n", 0, 1 << 16)
    if not data.startswith(b"ply\n") or end < 0:
        return None
    lines = data[:end].decode("ascii", errors="replace").split("\n")
    if len(lines) < 2 or lines[1].split() != ["format", "binary_little_endian", "1.0"]:
        return None
    elements: list[tuple[str, int, list[list[str]]]] = []
    for line in lines[2:]:
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "element" and len(words) == 3 and words[2].isdigit():
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property" and elements:
            elements[-1][2].append(words[1:])
        else:
            return None
    if [e[0] for e in elements] != ["vertex", "face"]:
        return None
    (_, n_v, v_props), (_, n_f, f_props) = elements
    if ([p[-1] for p in v_props[:3]] != ["x", "y", "z"]
            or any(len(p) != 2 or p[0] not in PLY_TYPES for p in v_props)):
        return None
    if (len(f_props) != 1 or len(f_props[0]) != 4 or f_props[0][0] != "list"
            or f_props[0][1] not in PLY_TYPES or f_props[0][2] not in PLY_TYPES):
        return None
    v_type = np.dtype([(f"p{i}", PLY_TYPES[p[0]]) for i, p in enumerate(v_props)])
    count_t, index_t = np.dtype(PLY_TYPES[f_props[0][1]]), np.dtype(PLY_TYPES[f_props[0][2]])
    f_type = np.dtype([("n", count_t), ("v", index_t, (3,))])
    start = end + len(b"end_header\n")
    need = n_v * v_type.itemsize + n_f * f_type.itemsize
    if len(data) - start != need:
        return None
    rows = np.frombuffer(data, dtype=v_type, count=n_v, offset=start)
    vertices = np.stack([rows[f"p{i}"].astype(np.float64) for i in range(3)], axis=1)
    frows = np.frombuffer(data, dtype=f_type, count=n_f, offset=start + n_v * v_type.itemsize)
    if n_f and not np.all(frows["n"] == 3):
        return None
    return vertices, frows["v"].astype(np.int64)
