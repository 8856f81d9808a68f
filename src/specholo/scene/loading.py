"""Loading 3D models: triangle meshes and point clouds.

Meshes come from OBJ, STL, PLY, OFF, GLB and GLTF files (via trimesh; a scene of
several meshes is baked into one), and are kept, cleaned, by their bytes
(:mod:`specholo.scene.cache`): trimesh is imported only for a file not read
before. Point clouds come from PLY files with vertices
but no faces, from ``.xyz`` text files (``x y z`` per line, further columns
ignored) and from ``.csv`` files (columns x, y, z; an optional header names them
in any order). Every problem with a file raises :class:`SpecholoError` with a
one-line message that names the file.
"""

from __future__ import annotations

import contextlib
import csv
import io
import logging
import math
import os
import stat
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from specholo._memory import available_memory as available_memory
from specholo._memory import format_bytes as format_bytes
from specholo.errors import SpecholoError
from specholo.readback import all_finite, check_fits, one_line, open_file, read_bytes, within
from specholo.scene import cache, cleaning, readers
from specholo.scene.mesh import PLY_TYPES, Mesh, read_ply

MESH_FORMATS = (".obj", ".stl", ".ply", ".off", ".glb", ".gltf")
CLOUD_FORMATS = (".ply", ".xyz", ".csv")
FORMATS = tuple(sorted(set(MESH_FORMATS) | set(CLOUD_FORMATS)))

# Faces smaller than this fraction of the squared bounding-box diagonal have no
# usable area (collinear or repeated vertices up to rounding).
_DEGENERATE_AREA = 1e-14

# Peak memory per face and per vertex of a mesh through loading (trimesh's
# parsing, merging and normal fixing) and the design's occlusion tests, bytes.
# Measured: a 327,680-face sphere adds ~230 MB to loading and ~120 MB more to a
# design; rounded up.
BYTES_PER_FACE = 1000
BYTES_PER_VERTEX = 200
# Peak memory of loading per byte of file, bytes: the file is held in memory
# while it is parsed; text is split into Python strings, binary data is viewed
# in place (and checked against its declared counts). Measured on a
# 327,680-face sphere: OBJ 22x (with the mesh processing), XYZ 11x.
_LOAD_BYTES_PER_FILE_BYTE = {"mesh text": 24.0, "cloud text": 12.0, "binary": 3.0}
# How much of a PLY header is searched for ``end_header``.
_MAX_HEADER = 1 << 20
# Sizes of PLY property types, bytes.
_PLY_SIZES = {name: np.dtype(t).itemsize for name, t in PLY_TYPES.items()}
# Characters str.splitlines breaks lines at (trimesh splits ASCII PLY data this way).
_LINE_BREAKS = ("\n", "\r", "\x0b", "\x0c", "\x1c", "\x1d", "\x1e", "\x85", "\u2028", "\u2029")


@dataclass(frozen=True, eq=False)
class Model:
    """A loaded model: a triangle mesh, or a point cloud.

    Attributes:
        mesh: the triangle mesh, or None for a point cloud.
        points: (n, 3) float64 points in the model's units: the mesh vertices,
            or the cloud's points.
    """

    mesh: Mesh | None
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


# ---------------------------------------------------------------- memory


def mesh_memory(n_vertices: int, n_faces: int) -> int:
    """Bytes a mesh of that size needs through loading and the design (an estimate)."""
    return int(n_vertices) * BYTES_PER_VERTEX + int(n_faces) * BYTES_PER_FACE


def _refuse_unless_fits(p: Path, what: str, need: int) -> None:
    """Raise if ``need`` bytes exceed the memory available."""
    room = available_memory()
    if room is not None and need > room:
        raise SpecholoError(
            f"{p}: {what} would need ~{format_bytes(need)} of memory; "
            f"this machine has {format_bytes(room)} available")


# ---------------------------------------------------------------- loading


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """Keep trimesh's log records and numpy's warnings off the user's terminal.

    Bad input is reported once, as a SpecholoError; trimesh logs tracebacks
    (e.g. of a texture it cannot find) that Python would print on stderr.
    """
    log = logging.getLogger("trimesh")
    level = log.level
    log.setLevel(logging.CRITICAL + 1)
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            yield
    finally:
        log.setLevel(level)


def load_model(path: str | os.PathLike[str]) -> Model:
    """Load a mesh or point cloud from a file.

    Degenerate (zero-area) faces and vertices no face uses are dropped quietly;
    duplicate vertices are merged and face winding is made consistent.

    Args:
        path: the model file; its extension picks the format.

    Returns:
        The model, with ``points`` (n, 3) float64.

    Raises:
        SpecholoError: the file is missing, a directory or not a regular file,
            of an unknown format, empty, unreadable, corrupt (including header
            counts the file cannot hold), too large for the memory available,
            has no points or faces, or has NaN or infinite coordinates.
    """
    p = Path(path)
    try:
        info = os.stat(p)
    except (FileNotFoundError, NotADirectoryError) as exc:
        raise SpecholoError(f"{p}: no such file") from exc
    except (OSError, ValueError) as exc:  # ValueError: a NUL byte in the path
        raise SpecholoError(f"{p}: cannot read: {_one_line(exc)}") from exc
    if stat.S_ISDIR(info.st_mode):
        raise SpecholoError(f"{p}: is a directory, not a model file")
    ext = p.suffix.lower()
    if ext not in FORMATS:
        raise SpecholoError(
            f"{p}: unknown model format {ext or '(no extension)'!r}; "
            f"expected one of {', '.join(FORMATS)}"
        )
    if not stat.S_ISREG(info.st_mode):
        # A FIFO or device (/dev/zero) would never end.
        raise SpecholoError(f"{p}: not a regular file")
    size = info.st_size
    if size == 0:
        raise SpecholoError(f"{p}: file is empty")
    if ext in (".xyz", ".csv"):
        kind = "cloud text"
    elif ext in (".obj", ".off", ".gltf") or (ext in (".stl", ".ply") and _looks_like_text(p)):
        kind = "mesh text"
    else:
        kind = "binary"
    factor = _LOAD_BYTES_PER_FILE_BYTE[kind]
    _refuse_unless_fits(p, f"loading this {format_bytes(size)} file", int(size * factor))
    # The file as it was stat'ed: one swapped for a FIFO or device since is
    # refused rather than waited on, one grown since refused rather than cut.
    data = read_bytes(p, size)
    if not data:
        raise SpecholoError(f"{p}: file is empty")

    with _quiet():
        if ext == ".xyz":
            return _cloud(p, _read_xyz(p, _decode(p, data)))
        if ext == ".csv":
            return _cloud(p, _read_csv(p, _decode(p, data)))
        mesh = cache.kept(data, ext)
        if mesh is not None:
            return Model(mesh=mesh, points=mesh.vertices)
        raw = readers.read(ext, data)
        if raw is not None:
            model = _clean_mesh(p, *raw)
        else:
            model = _read_with_trimesh(p, ext, data)
        if model.mesh is not None:
            cache.keep(data, ext, model.mesh)
        return model


def _looks_like_text(p: Path) -> bool:
    """True for an ASCII STL or PLY (judged by the first bytes)."""
    try:
        with open_file(p) as fh:
            head = fh.read(512)
    except (OSError, SpecholoError):
        return False
    return head.lstrip()[:5].lower() == b"solid" or b"format ascii" in head


def _decode(p: Path, data: bytes) -> str:
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SpecholoError(f"{p}: not a text file (cannot decode as UTF-8)") from exc


def _as_text(data: bytes) -> bytes:
    """Text-format bytes as valid UTF-8: stray bytes (say in a comment) become U+FFFD.

    trimesh would otherwise guess the encoding with a package that may be missing
    (charset_normalizer), and report that import's failure instead of the file's.
    """
    try:
        data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("utf-8", errors="replace").encode("utf-8")
    return data


def _folder_resolver(p: Path) -> Any:
    """A resolver reading a glTF's external buffers only from regular files in
    the model's folder (a trimesh resolver: trimesh is imported on use)."""
    import trimesh

    class FolderResolver(trimesh.resolvers.FilePathResolver):  # type: ignore[misc]
        def get(self, name: str) -> bytes:
            path = self.absolute(name)  # raises ValueError for a path outside the folder
            if not path.is_file():  # missing, a folder, a FIFO or a device
                raise FileNotFoundError(f"buffer {name!r} is not a file beside the model")
            size = path.stat().st_size
            room = available_memory()
            if room is not None and 2 * size > room:
                raise MemoryError(f"buffer {name!r} of {format_bytes(size)} does not fit "
                                  "in memory")
            # As stat'ed: a FIFO swapped in since is refused, not waited on.
            return read_bytes(path, size)

    return FolderResolver(str(p))


def _read_with_trimesh(p: Path, ext: str, data: bytes) -> Model:
    """Load a mesh format (or a face-less PLY) with trimesh."""
    import trimesh

    fmt = ext[1:].upper()
    if ext == ".ply":
        _check_ply_header(p, data)
    elif ext == ".off":
        _check_off_header(p, data)
        data = _as_text(data)
    elif ext == ".stl":
        data = _check_stl(p, data)
    elif ext == ".obj":
        data = _as_text(data)
    try:
        # process=False: trimesh's processing would silently drop NaN vertices,
        # which must be reported instead. skip_materials: textures and material
        # files play no part (and could name any file).
        if ext == ".gltf":
            # The bytes already read, not the path: the file is not opened twice.
            loaded = trimesh.load(io.BytesIO(data), file_type="gltf", process=False,
                                  resolver=_folder_resolver(p), skip_materials=True)
        else:
            loaded = trimesh.load(io.BytesIO(data), file_type=ext[1:], process=False,
                                  skip_materials=True)
    except MemoryError as exc:
        raise SpecholoError(f"{p}: out of memory reading the {fmt} file") from exc
    except Exception as exc:  # trimesh raises anything from KeyError to JSON errors
        raise SpecholoError(f"{p}: cannot read {fmt} file: {_one_line(exc)}") from exc
    del data

    try:
        parts = loaded.dump() if isinstance(loaded, trimesh.Scene) else [loaded]
        meshes = [g for g in parts if isinstance(g, trimesh.Trimesh) and len(g.faces) > 0]
        clouds = [
            _xyz(p, g.vertices)
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
        vertices = np.concatenate([_xyz(p, g.vertices) for g in meshes])
        # Offset each part's face indices past the vertices of the parts before it.
        base = np.cumsum([0] + [len(g.vertices) for g in meshes[:-1]])
        faces = np.concatenate(
            [_faces(p, g.faces) + b for g, b in zip(meshes, base, strict=True)]
        )
    except SpecholoError:
        raise
    except MemoryError as exc:
        raise SpecholoError(f"{p}: out of memory reading the {fmt} file") from exc
    except Exception as exc:
        raise SpecholoError(f"{p}: cannot read {fmt} file: {_one_line(exc)}") from exc
    return _clean_mesh(p, vertices, faces)


def _xyz(p: Path, values: object) -> np.ndarray:
    """Vertex coordinates as (n, 3) float64; refuse 2D or 4D vertices."""
    v = np.asarray(values, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3:
        width = v.shape[1] if v.ndim == 2 else "?"
        raise SpecholoError(f"{p}: corrupt model: vertices have {width} coordinates, expected 3")
    return v


def _faces(p: Path, values: object) -> np.ndarray:
    """Faces as (m, 3) int64; refuse anything else."""
    f = np.asarray(values)
    if f.ndim != 2 or f.shape[1] != 3 or not np.issubdtype(f.dtype, np.integer):
        raise SpecholoError(f"{p}: corrupt mesh: faces are not triangles of vertex indices")
    return f.astype(np.int64)


def _check_ply_header(p: Path, data: bytes) -> None:
    """Refuse a PLY whose header declares more elements than the file holds or memory takes.

    trimesh reads an ASCII PLY leniently: with a vertex count too large it reads
    the face lines as vertices. Anything this check cannot make sense of is
    left to trimesh to report.
    """
    end = data.find(b"end_header", 0, _MAX_HEADER)
    if end < 0:
        return
    newline = data.find(b"\n", end)
    body_start = len(data) if newline < 0 else newline + 1
    lines = data[:end].decode("ascii", errors="replace").splitlines()
    if len(lines) < 2:
        return
    ascii_data = "ascii" in lines[1].lower()
    elements: list[tuple[str, int, int, int]] = []  # name, count, bytes, values per row
    for line in lines[2:]:
        words = line.split()
        if not words:
            continue
        if "element" in words[0]:
            if len(words) != 3:
                raise SpecholoError(f"{p}: corrupt PLY header: bad element line {line.strip()!r}")
            try:
                count = int(words[2])
            except ValueError as exc:
                raise SpecholoError(
                    f"{p}: corrupt PLY header: element count {words[2]!r} is not a number"
                ) from exc
            if count < 0:
                raise SpecholoError(f"{p}: corrupt PLY header: negative element count {count}")
            elements.append((words[1], count, 0, 0))
        elif "property" in words[0] and elements and len(words) >= 3:
            name, count, size, values = elements[-1]
            type_name = words[2] if "list" in words[1] else words[1]
            elements[-1] = (name, count, size + _PLY_SIZES.get(type_name, 0), values + 1)
    if not elements:
        return
    counts = ", ".join(f"{count} {name!r}" for name, count, _, _ in elements)
    held = len(data) - body_start
    if ascii_data:
        # One line per element; each value takes a digit and a separator.
        need = sum(count * 2 * values for _, count, _, values in elements)
        rows = sum(count for _, count, _, values in elements if values)
    else:
        need = sum(count * size for _, count, size, _ in elements)
        rows = 0
    if need > held:
        raise SpecholoError(
            f"{p}: corrupt PLY: the header declares {counts} elements, which need at least "
            f"{need} bytes, but the file holds {held} bytes after the header")
    if rows:
        text = data[body_start:].decode("utf-8", errors="replace").rstrip()
        lines_held = (sum(text.count(c) for c in _LINE_BREAKS) - text.count("\r\n") + 1
                      if text else 0)
        if lines_held < rows:
            raise SpecholoError(
                f"{p}: corrupt PLY: the header declares {counts} elements ({rows} lines) "
                f"but the file has {lines_held} lines of data")
    n_faces = sum(count for name, count, _, _ in elements if name == "face")
    n_vertices = sum(count for name, count, _, _ in elements if name == "vertex")
    _refuse_unless_fits(p, f"a mesh of {n_vertices} vertices and {n_faces} faces",
                        mesh_memory(n_vertices, n_faces))


def _check_off_header(p: Path, data: bytes) -> None:
    """Refuse an OFF whose counts the file cannot hold or memory cannot take."""
    head = data[:_MAX_HEADER].decode("utf-8", errors="replace")
    words: list[str] = []
    for line in head.splitlines():
        words += line.split("#", 1)[0].split()
        if len(words) >= 3:
            break
    if not words or not words[0].upper().endswith("OFF"):
        return
    try:
        n_vertices, n_faces = (int(w) for w in words[1:3])
    except ValueError:
        return
    if n_vertices < 0 or n_faces < 0:
        raise SpecholoError(
            f"{p}: corrupt OFF header: negative counts ({n_vertices} vertices, {n_faces} faces)")
    # A vertex line takes at least 6 bytes ("0 0 0\n"), a face line 2.
    need = 6 * n_vertices + 2 * n_faces
    if need > len(data):
        raise SpecholoError(
            f"{p}: corrupt OFF: the header declares {n_vertices} vertices and {n_faces} faces, "
            f"which need at least {need} bytes, but the file has {len(data)}")
    _refuse_unless_fits(p, f"a mesh of {n_vertices} vertices and {n_faces} faces",
                        mesh_memory(n_vertices, n_faces))


def _check_stl(p: Path, data: bytes) -> bytes:
    """Tell a binary STL from an ASCII one; refuse one that is neither.

    Returns:
        The bytes to parse: an ASCII STL made valid UTF-8.
    """
    declared = int.from_bytes(data[80:84], "little") if len(data) >= 84 else None
    if declared is not None and len(data) == 84 + 50 * declared:
        _refuse_unless_fits(p, f"a mesh of {declared} triangles",
                            mesh_memory(3 * declared, declared))
        return data
    if data.lstrip()[:5].lower() == b"solid":
        return _as_text(data)
    if declared is None:
        raise SpecholoError(f"{p}: no faces in STL file: not ASCII (no 'solid' line) and "
                            f"too short for a binary STL ({len(data)} bytes)")
    raise SpecholoError(
        f"{p}: no faces in STL file: not ASCII (no 'solid' line), and as a binary STL its "
        f"header declares {declared} triangles ({84 + 50 * declared} bytes) but the file "
        f"has {len(data)} bytes (truncated or corrupt)")


def _clean_mesh(p: Path, vertices: np.ndarray, faces: np.ndarray) -> Model:
    """Validate and tidy a raw mesh: finite, indices in range, no degenerate faces.

    The work is done on a copy scaled to a unit box (by powers of two), so that
    merging and the zero-area test are relative to the model's size, and
    coordinates such as 1e300 or 1e-300 neither overflow nor collapse.
    """
    if len(vertices) == 0 or len(faces) == 0:
        raise SpecholoError(f"{p}: mesh has no faces")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise SpecholoError(f"{p}: corrupt mesh: face indices out of range")
    # Unused vertices may hold NaN: keep only those the faces use.
    used, faces = np.unique(faces, return_inverse=True)
    faces = faces.reshape(-1, 3)
    vertices = vertices[used]
    if not np.isfinite(vertices).all():
        raise SpecholoError(f"{p}: mesh has NaN or infinite vertex coordinates")
    largest = float(np.max(np.abs(vertices)))
    if largest == 0.0:
        raise SpecholoError(f"{p}: every face of the mesh is degenerate (zero area)")
    k = math.frexp(largest)[1]
    w = np.ldexp(vertices, -k)  # |w| < 1, exact
    lo = w.min(axis=0)
    extent = float(np.max(w.max(axis=0) - lo))
    if not extent > 0:
        raise SpecholoError(f"{p}: every face of the mesh is degenerate (zero area)")
    e = math.frexp(extent)[1]
    unit = np.ldexp(w - lo, -e)  # in [0, 1]
    try:
        done = cleaning.clean(unit, faces, _DEGENERATE_AREA)
        if done is None:  # faces wound both ways: trimesh walks them into agreement
            done = clean_with_trimesh(unit, faces)
    except SpecholoError as exc:
        raise SpecholoError(f"{p}: {exc}") from exc
    except MemoryError as exc:
        raise SpecholoError(f"{p}: out of memory processing the mesh") from exc
    except Exception as exc:
        raise SpecholoError(f"{p}: cannot process mesh: {_one_line(exc)}") from exc
    restored = np.ldexp(np.ldexp(done[0], e) + lo, k)
    if not np.isfinite(restored).all():
        raise SpecholoError(f"{p}: vertex coordinates too large for floating point")
    cleaned = Mesh(restored, done[1])
    return Model(mesh=cleaned, points=cleaned.vertices)


def clean_with_trimesh(unit: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`specholo.scene.cleaning.clean` by trimesh's own steps (which also
    make an inconsistent winding consistent)."""
    import trimesh

    mesh = trimesh.Trimesh(vertices=unit, faces=faces, process=False)
    mesh.merge_vertices()
    diag2 = float(np.sum(np.ptp(mesh.vertices, axis=0) ** 2))
    keep = mesh.area_faces > _DEGENERATE_AREA * diag2
    if not keep.any():
        raise SpecholoError("every face of the mesh is degenerate (zero area)")
    mesh.update_faces(keep)
    mesh.remove_unreferenced_vertices()
    # Consistent winding (and outward, for closed meshes) so face normals
    # tell the outer side of the surface.
    mesh.fix_normals(multibody=True)
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)


def _cloud(p: Path, points: np.ndarray) -> Model:
    """Validate a point cloud."""
    if np.size(points) == 0:
        raise SpecholoError(f"{p}: no points in file")
    points = _xyz(p, points)
    if not np.isfinite(points).all():
        raise SpecholoError(f"{p}: point cloud has NaN or infinite coordinates")
    return Model(mesh=None, points=points)


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


def _read_xyz(p: Path, text: str) -> np.ndarray:
    """Points (n, 3) of a whitespace-separated ``x y z [...]`` text file."""
    rows: list[tuple[int, list[str]]] = []
    for line_no, line in enumerate(text.splitlines(), start=1):
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


def _read_csv(p: Path, text: str) -> np.ndarray:
    """Points (n, 3) of a CSV file with x, y, z columns and an optional header."""
    try:
        table = [
            (i, [c.strip() for c in row])
            for i, row in enumerate(csv.reader(io.StringIO(text)), start=1)
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


# ---------------------------------------------------------------- placed models

#: Largest placed model (model.ply) read, bytes: 2 GB of binary PLY is ~100
#: million faces, far more than a design's occlusion tests can hold.
MAX_MESH_BYTES = 2 << 30
# Memory that reading needs per byte of file: the file's bytes themselves, and
# trimesh's arrays beside them.
_MESH_BYTES_PER_FILE_BYTE = 3


def read_mesh(path: str | os.PathLike[str], what: str = "model") -> Mesh:
    """A placed model (a PLY a design wrote), exactly as written.

    Unlike :func:`specholo.scene.loading.load_model`, nothing is merged or
    dropped: the occlusion tests then see the mesh the design saw. The binary
    PLY a design writes is read directly; any other PLY with trimesh.

    Raises:
        SpecholoError: unreadable, too large, or not a mesh of finite vertices
            whose faces index them.
    """
    data = read_bytes(path, MAX_MESH_BYTES, what)
    check_fits(path, what, _MESH_BYTES_PER_FILE_BYTE * len(data))
    p = Path(path)
    got = read_ply(data)
    if got is not None:
        v, f = got
    else:
        mesh = _read_ply_with_trimesh(p, data, what)
        v, f = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    if v.ndim != 2 or v.shape[1] != 3 or not all_finite(v.astype(float, copy=False)):
        raise SpecholoError(f"{what} {os.fspath(path)}: vertices are not finite 3D points")
    if f.ndim != 2 or f.shape[1] != 3 or not np.issubdtype(f.dtype, np.integer) \
            or (f.size and not within(f, 0, len(v) - 1)):
        raise SpecholoError(f"{what} {os.fspath(path)}: faces do not index its vertices")
    return Mesh(v, f)


def _read_ply_with_trimesh(p: Path, data: bytes, what: str) -> Any:
    """A PLY's mesh, read by trimesh (any PLY it reads)."""
    import trimesh

    with _quiet():
        _check_ply_header(p, data)
        try:
            mesh = trimesh.load(io.BytesIO(data), file_type="ply", force="mesh",
                                process=False)
        except MemoryError as exc:
            raise SpecholoError(f"{what} {os.fspath(p)}: out of memory reading it") from exc
        except Exception as exc:  # trimesh raises anything from KeyError to struct.error
            raise SpecholoError(f"{what} {os.fspath(p)} is not a readable PLY mesh: "
                                f"{one_line(exc)}") from exc
    if not isinstance(mesh, trimesh.Trimesh):
        raise SpecholoError(f"{what} {os.fspath(p)} holds no triangle mesh")
    return mesh
