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


def test_a_design_of_a_model_read_before_does_not_import_trimesh(tmp_path: Path) -> None:
    """trimesh and scipy.spatial take longer to import than a small design takes
    (numba imports a little of scipy itself)."""
    env = {**os.environ, "SPECHOLO_CACHE_DIR": str(tmp_path / "cache"),
           "SPECHOLO_NO_PRECOMPILE": "1"}
    script = textwrap.dedent(f"""
        import sys
        from specholo.flat import design
        from specholo.settings import DesignConfig
        design({str(BUNNY)!r}, DesignConfig(size=60.0, center_z=-40.0, stipples=30))
        print(sorted(m for m in ("trimesh", "scipy.spatial", "networkx") if m in sys.modules))
    """)
    runs = [subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                           text=True, check=True).stdout.split("\n")[-2] for _ in range(2)]
    assert runs[0] == "['networkx', 'scipy.spatial', 'trimesh']"
    assert runs[1] == "[]"


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
