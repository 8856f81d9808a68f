"""OBJ and STL files read without trimesh, as most programs write them.

A plain OBJ (``v`` and triangle ``f`` lines, with any ``vt``, ``vn``, ``s``,
``o``, ``g`` and ``mtllib`` lines) and an STL, binary or of one ASCII solid,
are read here into the vertices and faces trimesh would give: the vertices in
the file's order and the faces in its order, each with its corners in the
file's order. Anything else (materials, polygons, negative or relative
indices, line continuations, a vertex with more or fewer than three
coordinates, several ASCII solids) returns None, and trimesh reads the file.
"""

from __future__ import annotations

import numpy as np

#: OBJ statements that change nothing of the triangles.
_IGNORED = frozenset({"vt", "vn", "s", "o", "g", "mtllib"})


def read(ext: str, data: bytes) -> tuple[np.ndarray, np.ndarray] | None:
    """Vertices (n, 3) float64 and faces (m, 3) int64 of a plain OBJ or STL, or None."""
    try:
        if ext == ".obj":
            return _obj(data)
        if ext == ".stl":
            return _stl(data)
    except (ValueError, UnicodeDecodeError, OverflowError):
        return None  # (trimesh reads it, or says what is wrong)
    return None


def _obj(data: bytes) -> tuple[np.ndarray, np.ndarray] | None:
    text = data.decode("utf-8").replace("\r\n", "\n")
    # Continued lines, and lines broken where trimesh would not break them.
    if "\\\n" in text or any(c in text for c in "\r\x0b\x0c\x1c\x1d\x1e\x85\u2028\u2029"):
        return None
    vertices: list[str] = []
    faces: list[str] = []
    for line in text.split("\n"):
        if not line or line[0] == "#":
            continue
        if line[0].isspace():
            if line.strip():
                return None  # (an indented statement: left to trimesh)
            continue
        key, _, rest = line.partition(" ")
        if key == "v":
            vertices.append(rest)
        elif key == "f":
            faces.append(rest)
        elif key not in _IGNORED:
            return None
    if not vertices or not faces:
        return None
    coords = [row.split() for row in vertices]
    if any(len(c) != 3 for c in coords):
        return None
    corners = [row.split() for row in faces]
    if any(len(c) != 3 for c in corners):
        return None
    v = np.array(coords, dtype=np.float64)
    f = np.array([[int(t.split("/", 1)[0]) for t in c] for c in corners], dtype=np.int64)
    if f.min() < 1 or f.max() > len(v):
        return None
    return v, f - 1


def _stl(data: bytes) -> tuple[np.ndarray, np.ndarray] | None:
    declared = int.from_bytes(data[80:84], "little") if len(data) >= 84 else -1
    if declared >= 0 and len(data) == 84 + 50 * declared:
        rows = np.frombuffer(data, dtype=np.dtype([("n", "<f4", (3,)), ("v", "<f4", (3, 3)),
                                                   ("a", "<u2")]), count=declared, offset=84)
        if declared == 0:
            return None
        v = rows["v"].reshape(-1, 3).astype(np.float64)
        return v, np.arange(len(v), dtype=np.int64).reshape(-1, 3)
    text = data.decode("utf-8")
    words = text.split()
    if not words or words[0].lower() != "solid" or text.lower().count("endsolid") != 1:
        return None
    lowered = [w.lower() for w in words]
    at = [i for i, w in enumerate(lowered) if w == "vertex"]
    if not at or len(at) % 3 or lowered.count("facet") != len(at) // 3:
        return None
    v = np.array([words[i + 1:i + 4] for i in at], dtype=np.float64)
    if v.shape != (len(at), 3):
        return None
    return v, np.arange(len(v), dtype=np.int64).reshape(-1, 3)
