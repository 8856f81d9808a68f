"""Loading 3D models: triangle meshes and point clouds.

Meshes come from OBJ, STL, PLY, OFF, GLB and GLTF files (via trimesh; a scene of
several meshes is baked into one). Point clouds come from PLY files with vertices
but no faces, from ``.xyz`` text files (``x y z`` per line, further columns
ignored) and from ``.csv`` files (columns x, y, z; an optional header names them
in any order). Every problem with a file raises :class:`SpecholoError` with a
one-line message that names the file.
"""

from __future__ import annotations

import csv
import io
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from specholo.errors import SpecholoError

MESH_FORMATS = (".obj", ".stl", ".ply", ".off", ".glb", ".gltf")
CLOUD_FORMATS = (".ply", ".xyz", ".csv")
FORMATS = tuple(sorted(set(MESH_FORMATS) | set(CLOUD_FORMATS)))

# Faces smaller than this fraction of the squared bounding-box diagonal have no
# usable area (collinear or repeated vertices up to rounding).
_DEGENERATE_AREA = 1e-14


@dataclass(frozen=True, eq=False)
class Model:
    """A loaded model: a triangle mesh, or a point cloud.

    Attributes:
        mesh: the triangle mesh, or None for a point cloud.
        points: (n, 3) float64 points in the model's units: the mesh vertices,
            or the cloud's points.
    """

    mesh: trimesh.Trimesh | None
    points: np.ndarray

    @property
    def is_mesh(self) -> bool:
        """True for a triangle mesh, False for a point cloud."""
        return self.mesh is not None


def _one_line(exc: BaseException) -> str:
    """An exception as one short line, for embedding in a SpecholoError."""
    text = " ".join(str(exc).split())
    # A bare KeyError or FileNotFoundError message is just a name: say what it is.
    if not text or not isinstance(exc, ValueError):
        text = f"{type(exc).__name__}: {text}" if text else type(exc).__name__
    return text if len(text) <= 200 else text[:197] + "..."


def load_model(path: str | os.PathLike[str]) -> Model:
    """Load a mesh or point cloud from a file.

    Degenerate (zero-area) faces and vertices no face uses are dropped quietly;
    duplicate vertices are merged and face winding is made consistent.

    Args:
        path: the model file; its extension picks the format.

    Returns:
        The model, with ``points`` (n, 3) float64.

    Raises:
        SpecholoError: the file is missing, a directory, of an unknown format,
            empty, unreadable, has no points or faces, or has NaN or infinite
            coordinates.
    """
    p = Path(path)
    if not p.exists():
        raise SpecholoError(f"{p}: no such file")
    if p.is_dir():
        raise SpecholoError(f"{p}: is a directory, not a model file")
    ext = p.suffix.lower()
    if ext not in FORMATS:
        raise SpecholoError(
            f"{p}: unknown model format {ext or '(no extension)'!r}; "
            f"expected one of {', '.join(FORMATS)}"
        )
    try:
        size = p.stat().st_size
    except OSError as exc:
        raise SpecholoError(f"{p}: cannot read: {_one_line(exc)}") from exc
    if size == 0:
        raise SpecholoError(f"{p}: file is empty")

    if ext == ".xyz":
        return _cloud(p, _read_xyz(p))
    if ext == ".csv":
        return _cloud(p, _read_csv(p))
    return _read_with_trimesh(p, ext)


def _read_with_trimesh(p: Path, ext: str) -> Model:
    """Load a mesh format (or a face-less PLY) with trimesh."""
    fmt = ext[1:].upper()
    try:
        # process=False: trimesh's processing would silently drop NaN vertices,
        # which must be reported instead.
        loaded = trimesh.load(str(p), file_type=ext[1:], process=False)
    except Exception as exc:  # trimesh raises anything from KeyError to JSON errors
        raise SpecholoError(f"{p}: cannot read {fmt} file: {_one_line(exc)}") from exc

    try:
        parts = loaded.dump() if isinstance(loaded, trimesh.Scene) else [loaded]
        meshes = [g for g in parts if isinstance(g, trimesh.Trimesh) and len(g.faces) > 0]
        clouds = [
            np.asarray(g.vertices, dtype=np.float64).reshape(-1, 3)
            for g in parts
            if isinstance(g, trimesh.PointCloud | trimesh.Trimesh) and len(g.vertices) > 0
        ]
        if not meshes:
            if ext == ".ply" and clouds:
                return _cloud(p, np.concatenate(clouds))
            raise SpecholoError(
                f"{p}: no faces in {fmt} file"
                + (" (point clouds must be .ply, .xyz or .csv)" if clouds else "")
            )
        vertices = np.concatenate([np.asarray(g.vertices, dtype=np.float64) for g in meshes])
        # Offset each part's face indices past the vertices of the parts before it.
        base = np.cumsum([0] + [len(g.vertices) for g in meshes[:-1]])
        faces = np.concatenate(
            [np.asarray(g.faces, dtype=np.int64) + b for g, b in zip(meshes, base, strict=True)]
        )
    except SpecholoError:
        raise
    except Exception as exc:
        raise SpecholoError(f"{p}: cannot read {fmt} file: {_one_line(exc)}") from exc
    return _clean_mesh(p, vertices, faces)


def _clean_mesh(p: Path, vertices: np.ndarray, faces: np.ndarray) -> Model:
    """Validate and tidy a raw mesh: finite, indices in range, no degenerate faces."""
    if len(vertices) == 0 or len(faces) == 0:
        raise SpecholoError(f"{p}: mesh has no faces")
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.min() < 0 or faces.max() >= len(vertices):
        raise SpecholoError(f"{p}: corrupt mesh: face indices out of range")
    used = np.unique(faces)
    if not np.isfinite(vertices[used]).all():
        raise SpecholoError(f"{p}: mesh has NaN or infinite vertex coordinates")
    try:
        mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
        # Unused vertices may hold NaN; drop them before anything hashes them.
        mesh.remove_unreferenced_vertices()
        mesh.merge_vertices()
        diag2 = float(np.sum(np.ptp(mesh.vertices, axis=0) ** 2))
        keep = mesh.area_faces > _DEGENERATE_AREA * diag2
        if not keep.any():
            raise SpecholoError(f"{p}: every face of the mesh is degenerate (zero area)")
        mesh.update_faces(keep)
        mesh.remove_unreferenced_vertices()
        # Consistent winding (and outward, for closed meshes) so face normals
        # tell the outer side of the surface.
        mesh.fix_normals(multibody=True)
    except SpecholoError:
        raise
    except Exception as exc:
        raise SpecholoError(f"{p}: cannot process mesh: {_one_line(exc)}") from exc
    return Model(mesh=mesh, points=np.asarray(mesh.vertices, dtype=np.float64))


def _cloud(p: Path, points: np.ndarray) -> Model:
    """Validate a point cloud."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(points) == 0:
        raise SpecholoError(f"{p}: no points in file")
    if not np.isfinite(points).all():
        raise SpecholoError(f"{p}: point cloud has NaN or infinite coordinates")
    return Model(mesh=None, points=points)


def _read_text(p: Path) -> str:
    try:
        return p.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise SpecholoError(f"{p}: not a text file (cannot decode as UTF-8)") from exc
    except OSError as exc:
        raise SpecholoError(f"{p}: cannot read: {_one_line(exc)}") from exc


def _parse_rows(p: Path, rows: list[tuple[int, list[str]]]) -> np.ndarray:
    """Parse (line number, three fields) rows into (n, 3) floats, naming the bad line."""
    if not rows:
        raise SpecholoError(f"{p}: no points in file")
    try:
        return np.array([[float(v) for v in fields] for _, fields in rows], dtype=np.float64)
    except ValueError:
        pass
    # Slow path only to locate the offending line for the message.
    for line_no, fields in rows:
        try:
            [float(v) for v in fields]
        except ValueError as exc:
            raise SpecholoError(
                f"{p}: line {line_no}: cannot parse coordinates {' '.join(fields)!r}"
            ) from exc
    raise SpecholoError(f"{p}: cannot parse coordinates")  # pragma: no cover


def _read_xyz(p: Path) -> np.ndarray:
    """Points (n, 3) of a whitespace-separated ``x y z [...]`` text file."""
    rows: list[tuple[int, list[str]]] = []
    for line_no, line in enumerate(_read_text(p).splitlines(), start=1):
        fields = line.replace(",", " ").split()
        if not fields or fields[0].startswith("#"):
            continue
        if len(fields) < 3:
            raise SpecholoError(f"{p}: line {line_no}: expected x y z, got {line.strip()!r}")
        rows.append((line_no, fields[:3]))
    return _parse_rows(p, rows)


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _read_csv(p: Path) -> np.ndarray:
    """Points (n, 3) of a CSV file with x, y, z columns and an optional header."""
    try:
        table = [
            (i, [c.strip() for c in row])
            for i, row in enumerate(csv.reader(io.StringIO(_read_text(p))), start=1)
            if any(c.strip() for c in row)
        ]
    except csv.Error as exc:
        raise SpecholoError(f"{p}: corrupt CSV: {_one_line(exc)}") from exc
    if not table:
        raise SpecholoError(f"{p}: no points in file")
    columns = [0, 1, 2]
    first = table[0][1]
    if not all(_is_number(c) for c in first[:3]):
        names = [c.lower() for c in first]
        missing = [n for n in ("x", "y", "z") if n not in names]
        if missing:
            raise SpecholoError(
                f"{p}: CSV header {','.join(first)!r} lacks column(s) {', '.join(missing)}"
            )
        columns = [names.index(n) for n in ("x", "y", "z")]
        table = table[1:]
    need = max(columns) + 1
    rows: list[tuple[int, list[str]]] = []
    for line_no, row in table:
        if len(row) < need:
            raise SpecholoError(f"{p}: line {line_no}: expected {need} columns, got {len(row)}")
        rows.append((line_no, [row[c] for c in columns]))
    return _parse_rows(p, rows)
