"""The design's own mesh type, its PLY and the cache of models read before."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import trimesh

from specholo.errors import SpecholoError
from specholo.scene import cache
from specholo.scene.loading import load_model, read_mesh
from specholo.scene.mesh import Mesh, ply_bytes, read_ply

BUNNY = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"


def _meshes() -> list[trimesh.Trimesh]:
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=7.0)
    sphere.apply_translation([1e3, -2e3, 5.0])
    loaded = trimesh.load(BUNNY, process=False)
    # A face of no area (its normal is zero) and a vertex no face uses.
    odd = trimesh.Trimesh(vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [9, 9, 9]],
                          faces=[[0, 1, 2], [0, 1, 3]], process=False)
    return [box, sphere, loaded, odd]


@pytest.mark.parametrize("which", range(4))
def test_figures_are_trimeshs_to_the_bit(which: int) -> None:
    ref = _meshes()[which]
    mesh = Mesh(ref.vertices, ref.faces)
    for name in ("triangles", "triangles_cross", "face_normals", "area_faces", "bounds"):
        got, want = getattr(mesh, name), np.asarray(getattr(ref, name))
        assert got.shape == want.shape and np.array_equal(got, want), name
    assert mesh.area == float(ref.area) and mesh.scale == float(ref.scale)
    # The arrays cannot be changed behind the cached figures' back.
    with pytest.raises(ValueError):
        mesh.vertices[0, 0] = 1.0


def test_ply_round_trip_and_trimesh_reads_it(tmp_path: Path) -> None:
    ref = _meshes()[2]
    mesh = Mesh(ref.vertices, ref.faces)
    data = mesh.export(tmp_path / "m.ply")
    assert (tmp_path / "m.ply").read_bytes() == data
    v, f = read_ply(data)  # type: ignore[misc]
    assert np.array_equal(v, mesh.vertices) and np.array_equal(f, mesh.faces)
    back = trimesh.load(tmp_path / "m.ply", process=False)
    assert np.array_equal(back.vertices, mesh.vertices) and np.array_equal(back.faces, mesh.faces)
    # A PLY trimesh wrote (float vertices, as older design folders hold) reads the same.
    old = tmp_path / "old.ply"
    ref.export(old)
    got = read_mesh(old)
    assert np.array_equal(got.vertices, ref.vertices.astype(np.float32).astype(np.float64))
    assert np.array_equal(got.faces, ref.faces)


def test_other_plys_are_left_to_trimesh(tmp_path: Path) -> None:
    ref = _meshes()[0]
    ascii_ply = ref.export(file_type="ply", encoding="ascii")
    assert read_ply(ascii_ply) is None
    (tmp_path / "a.ply").write_bytes(ascii_ply)
    assert np.array_equal(read_mesh(tmp_path / "a.ply").faces, ref.faces)
    # Cut short: not read here, and refused in one line by the reader that is.
    data = ply_bytes(ref.vertices, ref.faces)
    assert read_ply(data[:-5]) is None
    (tmp_path / "short.ply").write_bytes(data[:-5])
    with pytest.raises(SpecholoError):
        read_mesh(tmp_path / "short.ply")


def test_a_model_read_again_comes_from_the_cache(tmp_path: Path,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("SPECHOLO_CACHE_DIR", str(tmp_path / "cache"))
    first = load_model(BUNNY)
    entries = list((tmp_path / "cache" / "models").iterdir())
    assert len(entries) == 1
    again = load_model(BUNNY)
    assert np.array_equal(first.points, again.points)
    assert np.array_equal(first.mesh.faces, again.mesh.faces)  # type: ignore[union-attr]
    # A damaged entry is read from the file again (and kept anew).
    entries[0].write_bytes(b"ply\nnot really")
    third = load_model(BUNNY)
    assert np.array_equal(first.mesh.faces, third.mesh.faces)  # type: ignore[union-attr]
    assert read_ply(entries[0].read_bytes()) is not None
    # Off: nothing kept.
    monkeypatch.setenv("SPECHOLO_CACHE_DIR", "")
    assert cache.cache_dir() is None
    load_model(BUNNY)


def _imported(model: Path, cache_dir: Path) -> str:
    """Which of trimesh, networkx and scipy.spatial a 30-stipple design of
    ``model`` imports, in a fresh process (numba imports a little of scipy)."""
    env = {**os.environ, "SPECHOLO_CACHE_DIR": str(cache_dir), "SPECHOLO_NO_PRECOMPILE": "1"}
    script = textwrap.dedent(f"""
        import sys
        from specholo.jobs.flat.design import design
        from specholo.jobs.flat.settings import DesignConfig
        design({str(model)!r}, DesignConfig(size=60.0, center_z=-40.0, stipples=30))
        print(sorted(m for m in ("trimesh", "scipy.spatial", "networkx") if m in sys.modules))
    """)
    run = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                         text=True, check=True)
    return run.stdout.split("\n")[-2]


def test_a_design_of_an_obj_does_not_import_trimesh(tmp_path: Path) -> None:
    """trimesh and scipy.spatial take longer to import than a small design takes."""
    assert _imported(BUNNY, tmp_path / "cache") == "[]"


def test_a_model_read_before_is_read_without_trimesh(tmp_path: Path) -> None:
    ply = tmp_path / "bunny.ply"
    trimesh.load(BUNNY, process=False).export(ply)
    assert _imported(ply, tmp_path / "cache") == "['networkx', 'scipy.spatial', 'trimesh']"
    assert _imported(ply, tmp_path / "cache") == "[]"


def test_the_cache_keeps_the_models_used_last(tmp_path: Path,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("SPECHOLO_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(cache, "MAX_ENTRIES", 2)
    boxes, entries = [], []
    for k in range(3):
        path = tmp_path / f"box{k}.stl"
        trimesh.creation.box(extents=(1.0 + k, 2.0, 3.0)).export(path)
        boxes.append(path)
        entries.append(cache._entry(path.read_bytes(), ".stl"))
    load_model(boxes[0])
    load_model(boxes[1])
    for p, t in zip(entries[:2], (1000.0, 2000.0), strict=True):
        os.utime(p, (t, t))  # type: ignore[arg-type]
    load_model(boxes[0])  # read from the cache: used last now
    load_model(boxes[2])  # a third: the longest unused goes
    left = {p.name for p in (tmp_path / "cache" / "models").iterdir()}
    assert left == {entries[0].name, entries[2].name}  # type: ignore[union-attr]


# ---------------------------------------------------------------- reading and cleaning


def _raw_meshes() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Raw meshes, in the unit box and every vertex used, as loading hands them on."""
    rng = np.random.default_rng(4)
    out: dict[str, trimesh.Trimesh] = {}
    out["bunny"] = trimesh.load(BUNNY, process=False)
    out["knot"] = trimesh.load(BUNNY.parent / "knot.obj", process=False)
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    # The same box with every face's corners its own (merged back into 8).
    out["box unmerged"] = trimesh.Trimesh(box.triangles.reshape(-1, 3),
                                          np.arange(36).reshape(-1, 3), process=False)
    inverted = trimesh.creation.icosphere(subdivisions=2)
    inverted.invert()
    out["inside out"] = inverted
    out["two bodies, one inside out"] = trimesh.util.concatenate(
        [inverted, box.copy().apply_translation([4.0, 0.0, 0.0])])
    grid = trimesh.creation.box(extents=(1.0, 1.0, 1.0)).triangles[:4]  # an open piece
    out["open"] = trimesh.Trimesh(grid.reshape(-1, 3), np.arange(12).reshape(-1, 3),
                                  process=False)
    # Faces of no area, and corners that agree to 1e-12 (merged).
    soup = rng.random((30, 3, 3))
    soup[5, 2] = soup[5, 1]
    soup[7, 0] = soup[6, 0] + 1e-12
    out["soup"] = trimesh.Trimesh(soup.reshape(-1, 3), np.arange(90).reshape(-1, 3),
                                  process=False)
    flipped = box.copy()
    faces = flipped.faces.copy()
    faces[0] = faces[0][::-1]  # one face wound the other way
    out["wound both ways"] = trimesh.Trimesh(box.vertices, faces, process=False)
    raw = {}
    for name, m in out.items():
        v = np.asarray(m.vertices, dtype=np.float64)
        v = (v - v.min(axis=0)) / np.ptp(v, axis=0).max() / 2.0
        raw[name] = (v, np.asarray(m.faces, dtype=np.int64))
    return raw


@pytest.mark.parametrize("name", list(_raw_meshes()))
def test_cleaning_is_trimeshs_vertex_for_vertex(name: str) -> None:
    from specholo.scene import cleaning
    from specholo.scene.loading import _DEGENERATE_AREA, clean_with_trimesh

    unit, faces = _raw_meshes()[name]
    want = clean_with_trimesh(unit, faces)
    got = cleaning.clean(unit, faces, _DEGENERATE_AREA)
    if name == "wound both ways":
        assert got is None  # left to trimesh's walk over the faces
        return
    assert got is not None
    assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
    if name in ("inside out", "two bodies, one inside out"):
        assert trimesh.Trimesh(*got, process=False).volume > 0  # outward now


def test_plain_obj_and_stl_read_as_trimesh_reads_them(tmp_path: Path) -> None:
    from specholo.scene import readers

    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    files = {"box.stl": box.export(file_type="stl"),
             "box_ascii.stl": box.export(file_type="stl_ascii").encode(),
             "box.obj": box.export(file_type="obj").encode(),
             "bunny.obj": BUNNY.read_bytes()}
    for name, data in files.items():
        ext = Path(name).suffix
        got = readers.read(ext, data)
        assert got is not None, name
        loaded = trimesh.load(trimesh.util.wrap_as_stream(data), file_type=ext[1:],
                              process=False)
        # trimesh keeps only the vertices faces use, in order: so does loading.
        used = np.unique(got[1])
        assert np.array_equal(got[0][used], loaded.vertices), name
        assert np.array_equal(np.searchsorted(used, got[1]), loaded.faces), name


@pytest.mark.parametrize("text", [
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 4 3\n",  # a polygon
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n",  # materials
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n",  # relative indices
    "v 0 0 0 1\nv 1 0 0 1\nv 0 1 0 1\nf 1 2 3\n",  # four coordinates
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 \\\n3\n",  # a continued line
])
def test_other_objs_are_left_to_trimesh(text: str, tmp_path: Path,
                                         monkeypatch: pytest.MonkeyPatch) -> None:
    from specholo.scene import readers

    assert readers.read(".obj", text.encode()) is None
    # ... which still reads them (the quad as two triangles).
    monkeypatch.setenv("SPECHOLO_CACHE_DIR", "")
    path = tmp_path / "m.obj"
    path.write_text(text)
    assert len(load_model(path).mesh.faces) >= 1  # type: ignore[union-attr]


def test_line_ends_as_trimesh_takes_them() -> None:
    from specholo.scene import readers

    lf = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
    got = readers.read(".obj", lf.replace(b"\n", b"\r\n"))
    want = readers.read(".obj", lf)
    assert got is not None and want is not None
    assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
    # Lines broken by a lone carriage return or a form feed: left to trimesh.
    assert readers.read(".obj", lf.replace(b"\n", b"\r")) is None
    assert readers.read(".obj", lf.replace(b"v 1", b"\x0cv 1")) is None
