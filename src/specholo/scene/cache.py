"""Models read before: each mesh file's cleaned mesh, kept by the file's content.

Reading a mesh file with trimesh, merging its vertices and making its winding
consistent takes about a second, most of it importing trimesh and scipy, which
is most of a small design's time. The cleaned mesh is kept as a binary PLY
named by a hash of the file's bytes and format, in ``$SPECHOLO_CACHE_DIR`` (or
``$XDG_CACHE_HOME/specholo``, ``~/.cache/specholo``); the same bytes read again
give the same mesh without trimesh. Entries are written whole (renamed into
place), and one that cannot be read is read from the file again; a cache that
cannot be written is not used. ``SPECHOLO_CACHE_DIR=`` (empty) turns it off.
The cache keeps the models used last: an entry read is marked as used, and
past :data:`MAX_ENTRIES` entries or :data:`MAX_BYTES` the longest unused go.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import tempfile
from pathlib import Path

import numpy as np

from specholo import __version__
from specholo.errors import SpecholoError
from specholo.scene.mesh import Mesh, ply_bytes, read_ply

#: Changes whenever loading would clean a file differently.
LOADER_VERSION = 1
#: Largest entry read back, bytes (a larger file is read with trimesh again).
MAX_ENTRY = 1 << 30
#: Most entries, and most bytes of them, the cache keeps.
MAX_ENTRIES = 256
MAX_BYTES = 2 << 30


def cache_dir() -> Path | None:
    """Where models are kept, or None when the cache is turned off."""
    env = os.environ.get("SPECHOLO_CACHE_DIR")
    if env is not None:
        return Path(env) if env else None
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "specholo"


def _entry(data: bytes, ext: str) -> Path | None:
    where = cache_dir()
    if where is None:
        return None
    h = hashlib.sha256()
    h.update(f"{__version__}/{LOADER_VERSION}/{ext}/".encode())
    h.update(data)
    return where / "models" / f"{h.hexdigest()}.ply"


def kept(data: bytes, ext: str) -> Mesh | None:
    """The mesh kept for a file of these bytes and extension, or None."""
    path = _entry(data, ext)
    if path is None:
        return None
    try:
        with open(path, "rb") as fh:
            raw = fh.read(MAX_ENTRY + 1)
    except OSError:
        return None
    if len(raw) > MAX_ENTRY:
        return None
    got = read_ply(raw)
    if got is None:
        return None
    vertices, faces = got
    if len(faces) == 0 or not np.isfinite(vertices).all():
        return None
    try:
        mesh = Mesh(vertices, faces)
    except SpecholoError:  # (faces that do not index the vertices)
        return None
    with contextlib.suppress(OSError):
        os.utime(path)  # used now: the last to go
    return mesh


def keep(data: bytes, ext: str, mesh: Mesh) -> None:
    """Keep a file's cleaned mesh (quietly not, when the cache cannot be written)."""
    path = _entry(data, ext)
    if path is None:
        return
    with contextlib.suppress(OSError):
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=".", suffix=".tmp", dir=path.parent)
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(ply_bytes(mesh.vertices, mesh.faces))
            os.replace(tmp, path)
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            raise
        _trim(path.parent)


def _trim(folder: Path) -> None:
    """Remove the longest unused entries past MAX_ENTRIES or MAX_BYTES."""
    entries = []
    for p in folder.glob("*.ply"):
        with contextlib.suppress(OSError):
            st = p.stat()
            entries.append((st.st_mtime, st.st_size, p))
    entries.sort(reverse=True)  # the last used first
    total = 0
    for k, (_, size, p) in enumerate(entries):
        total += size
        if k >= MAX_ENTRIES or total > MAX_BYTES:
            with contextlib.suppress(OSError):
                p.unlink()
