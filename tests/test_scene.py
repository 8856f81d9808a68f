"""Tests of model loading, placement and stippling."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from specholo.errors import SpecholoError
from specholo.scene.loading import Model, load_model
from specholo.scene.placement import UP_AXES, orientation, place
from specholo.scene.stippling import Stipples, stipple

BUNNY = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"
BOX_EXTENTS = (1.0, 2.0, 3.0)


def _box() -> trimesh.Trimesh:
    return trimesh.creation.box(extents=BOX_EXTENTS)


def _assert_is_box(model: Model) -> None:
    assert model.is_mesh and model.mesh is not None
    assert len(model.mesh.faces) == 12
    assert model.points.shape == (8, 3)
    np.testing.assert_allclose(np.ptp(model.points, axis=0), BOX_EXTENTS)
    # Outward normals: a closed mesh with positive volume.
    assert model.mesh.to_trimesh().is_watertight
    assert model.mesh.to_trimesh().volume == pytest.approx(np.prod(BOX_EXTENTS))


@pytest.fixture(scope="module")
def bunny() -> Model:
    return place(load_model(BUNNY), 60.0, -20.0)


# ---------------------------------------------------------------- loading


@pytest.mark.parametrize("ext", ["obj", "stl", "ply", "off", "glb"])
def test_load_mesh_formats(tmp_path: Path, ext: str) -> None:
    path = tmp_path / f"box.{ext}"
    _box().export(path)
    _assert_is_box(load_model(path))


def test_load_uppercase_extension_and_str_path(tmp_path: Path) -> None:
    path = tmp_path / "BOX.OBJ"
    _box().export(path, file_type="obj")
    _assert_is_box(load_model(str(path)))


def test_load_glb_scene_is_concatenated(tmp_path: Path) -> None:
    a = _box()
    b = _box()
    b.apply_translation([10.0, 0.0, 0.0])
    path = tmp_path / "two.glb"
    trimesh.Scene([a, b]).export(path)
    model = load_model(path)
    assert model.mesh is not None
    assert len(model.mesh.faces) == 24
    assert len(model.points) == 16
    np.testing.assert_allclose(model.points.min(axis=0), [-0.5, -1.0, -1.5])
    np.testing.assert_allclose(model.points.max(axis=0), [10.5, 1.0, 1.5])


def test_load_drops_degenerate_faces_and_unused_vertices(tmp_path: Path) -> None:
    box = _box()
    # Vertex 8 lies midway between vertices 0 and 6; vertex 9 is never used.
    v = np.vstack([box.vertices, 0.5 * (box.vertices[0] + box.vertices[6]), [5.0, 5.0, 5.0]])
    # A face with a repeated vertex, and one on three collinear points.
    extra = np.array([[0, 0, 1], [0, 6, 8]])
    mesh = trimesh.Trimesh(vertices=v, faces=np.vstack([box.faces, extra]), process=False)
    path = tmp_path / "dirty.obj"
    mesh.export(path)
    _assert_is_box(load_model(path))


def test_load_stl_merges_vertices(tmp_path: Path) -> None:
    # STL stores three vertices per face; the loaded mesh must be connected.
    path = tmp_path / "box.stl"
    _box().export(path)
    model = load_model(path)
    assert model.mesh is not None and model.mesh.to_trimesh().is_watertight


def test_load_ply_cloud(tmp_path: Path) -> None:
    pts = np.random.default_rng(0).normal(size=(50, 3))
    path = tmp_path / "cloud.ply"
    trimesh.PointCloud(pts).export(path)
    model = load_model(path)
    assert not model.is_mesh and model.mesh is None
    np.testing.assert_allclose(np.sort(model.points, axis=0), np.sort(pts, axis=0), atol=1e-6)


def test_load_xyz_cloud(tmp_path: Path) -> None:
    path = tmp_path / "cloud.xyz"
    path.write_text("# a comment\n1 2 3\n\n4.5 5 6 255 0 0\n  -7e1\t8 9\n")
    model = load_model(path)
    assert not model.is_mesh
    np.testing.assert_array_equal(model.points, [[1, 2, 3], [4.5, 5, 6], [-70, 8, 9]])


def test_load_csv_with_header_in_any_order(tmp_path: Path) -> None:
    path = tmp_path / "cloud.csv"
    path.write_text("Z, id, x ,Y\n3,0,1,2\n6,1,4,5\n")
    model = load_model(path)
    np.testing.assert_array_equal(model.points, [[1, 2, 3], [4, 5, 6]])


def test_load_csv_without_header(tmp_path: Path) -> None:
    path = tmp_path / "cloud.csv"
    path.write_text("1,2,3\n4,5,6,extra\n")
    np.testing.assert_array_equal(load_model(path).points, [[1, 2, 3], [4, 5, 6]])


def _write(tmp_path: Path, name: str, content: str | bytes) -> Path:
    path = tmp_path / name
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    return path


BAD_FILES: dict[str, tuple[str, str | bytes, str]] = {
    # id: (file name, content, expected fragment of the message)
    "empty": ("empty.obj", "", "empty"),
    "unknown_ext": ("model.blend", "data", "unknown model format"),
    "junk_obj": ("junk.obj", "hello\nworld\n", "no faces"),
    "junk_ply": ("junk.ply", "hello\nworld\n", "cannot read"),
    "junk_off": ("junk.off", "hello\nworld\n", "cannot read"),
    "junk_glb": ("junk.glb", b"\x00\x01garbage" * 10, "cannot read"),
    "junk_stl": ("junk.stl", b"\x00" * 40, "no faces"),
    "vertices_only_obj": ("pts.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n", "no faces"),
    "nan_obj": ("nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", "NaN"),
    "inf_obj": ("inf.obj", "v 0 0 0\nv inf 0 0\nv 0 1 0\nf 1 2 3\n", "NaN or infinite"),
    "degenerate_obj": ("flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", "degenerate"),
    "nan_xyz": ("nan.xyz", "1 2 3\nnan 1 1\n", "NaN"),
    "short_xyz": ("short.xyz", "1 2 3\n4 5\n", "line 2"),
    "text_xyz": ("text.xyz", "1 2 3\na b c\n", "line 2"),
    "comments_only_xyz": ("none.xyz", "# nothing\n\n", "no points"),
    "binary_xyz": ("bin.xyz", b"\xff\xfe\x00\x81", "not a text file"),
    "inf_csv": ("inf.csv", "x,y,z\n1,2,inf\n", "infinite"),
    "header_only_csv": ("head.csv", "x,y,z\n", "no points"),
    "bad_header_csv": ("head.csv", "x,y,w\n1,2,3\n", "lacks column"),
    "short_csv": ("short.csv", "1,2,3\n4,5\n", "line 2"),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_load_bad_file_gives_one_line_error(tmp_path: Path, case: str) -> None:
    name, content, fragment = BAD_FILES[case]
    path = _write(tmp_path, name, content)
    with pytest.raises(SpecholoError) as info:
        load_model(path)
    message = str(info.value)
    assert "\n" not in message
    assert name in message
    assert fragment in message


def test_load_missing_file_and_directory(tmp_path: Path) -> None:
    for path, fragment in [(tmp_path / "nope.obj", "no such file"), (tmp_path, "directory")]:
        with pytest.raises(SpecholoError, match=fragment) as info:
            load_model(path)
        assert "\n" not in str(info.value)


def test_load_truncated_files(tmp_path: Path) -> None:
    for ext in ["stl", "ply", "glb"]:
        good = tmp_path / f"good.{ext}"
        _box().export(good)
        bad = _write(tmp_path, f"cut.{ext}", good.read_bytes()[: good.stat().st_size // 2])
        with pytest.raises(SpecholoError) as info:
            load_model(bad)
        assert "\n" not in str(info.value) and "cut." in str(info.value)


def test_load_bunny() -> None:
    model = load_model(BUNNY)
    assert model.mesh is not None
    tm = model.mesh.to_trimesh()
    assert tm.is_watertight and tm.volume > 0
    assert len(model.mesh.faces) == 3674


# ---------------------------------------------------------------- placement


@settings(max_examples=40, deadline=None)
@given(
    extents=st.tuples(*[st.floats(0.01, 100.0)] * 3),
    shift=st.tuples(*[st.floats(-1e3, 1e3)] * 3),
    rotate=st.booleans(),
    seed=st.integers(0, 2**32 - 1),
    size=st.floats(0.1, 500.0),
    center_z=st.floats(-500.0, 500.0),
    cloud=st.booleans(),
)
def test_place_bbox(
    extents: tuple[float, float, float],
    shift: tuple[float, float, float],
    rotate: bool,
    seed: int,
    size: float,
    center_z: float,
    cloud: bool,
) -> None:
    mesh = trimesh.creation.icosphere(subdivisions=1)
    mesh.apply_scale(extents)
    if rotate:
        mesh.apply_transform(trimesh.transformations.random_rotation_matrix(rand=_rand3(seed)))
    mesh.apply_translation(shift)
    model = Model(mesh=None, points=mesh.vertices.copy()) if cloud else Model(mesh, mesh.vertices)
    placed = place(model, size, center_z)
    lo, hi = placed.points.min(axis=0), placed.points.max(axis=0)
    assert np.max(hi - lo) == pytest.approx(size, rel=1e-9)
    np.testing.assert_allclose(0.5 * (lo + hi), [0.0, 0.0, center_z], atol=1e-9 * (1 + size))
    # Uniform scale: proportions are kept.
    ratio = (hi - lo) / np.ptp(mesh.vertices, axis=0)
    # Thin sides lose relative precision when moved far (here up to ~1e-9).
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-6)
    if not cloud:
        assert placed.mesh is not None
        np.testing.assert_array_equal(placed.mesh.faces, mesh.faces)
        np.testing.assert_allclose(placed.mesh.face_normals, mesh.face_normals, atol=1e-9)
    # The input is left alone.
    assert np.max(np.ptp(model.points, axis=0)) == pytest.approx(np.max(np.ptp(mesh.vertices, 0)))


def _rand3(seed: int) -> np.ndarray:
    return np.random.default_rng(seed).random(3)


@pytest.mark.parametrize(
    ("size", "center_z", "fragment"),
    [
        (0.0, 0.0, "size"),
        (-5.0, 0.0, "size"),
        (math.nan, 0.0, "size"),
        (math.inf, 0.0, "size"),
        (10.0, math.nan, "centre z"),
        (10.0, -math.inf, "centre z"),
    ],
)
def test_place_bad_arguments(size: float, center_z: float, fragment: str) -> None:
    model = Model(mesh=None, points=np.eye(3))
    with pytest.raises(SpecholoError, match=fragment):
        place(model, size, center_z)


@pytest.mark.parametrize("points", [np.zeros((1, 3)), np.full((5, 3), 2.5)])
def test_place_zero_extent(points: np.ndarray) -> None:
    with pytest.raises(SpecholoError, match="zero extent"):
        place(Model(mesh=None, points=points), 10.0, 0.0)


# ---------------------------------------------------------------- stippling


def _min_distance(points: np.ndarray) -> float:
    return float(cKDTree(points).query(points, k=2)[0][:, 1].min())


@pytest.mark.parametrize("count", [1, 7, 500, 3000])
def test_stipple_count_on_surface(bunny: Model, count: int) -> None:
    s = stipple(bunny, np.random.default_rng(1), count=count)
    assert isinstance(s, Stipples)
    assert s.points.shape == (count, 3) and len(s) == count
    assert s.normals is not None and s.normals.shape == (count, 3)
    np.testing.assert_allclose(np.linalg.norm(s.normals, axis=1), 1.0)
    assert bunny.mesh is not None
    _, dist, tri = trimesh.proximity.closest_point(bunny.mesh.to_trimesh(), s.points)
    assert dist.max() < 1e-9
    # Each normal is the normal of a face the point lies on (the nearest face,
    # up to points on shared edges, where both faces are at distance 0).
    agree = np.einsum("ij,ij->i", s.normals, bunny.mesh.face_normals[tri]) > 1 - 1e-9
    assert agree.mean() > 0.99


def test_surface_samples_lie_on_their_faces_uniformly_by_area(bunny: Model) -> None:
    from scipy.stats import chisquare

    from specholo.scene._sample_kernel import sample_surface

    mesh = bunny.mesh
    assert mesh is not None
    n = 200_000
    pts, face = sample_surface(mesh.vertices, mesh.faces, mesh.area_faces, n,
                               np.random.default_rng(4))
    # On its own triangle: barycentric coordinates in [0, 1] and in its plane.
    bary = trimesh.triangles.points_to_barycentric(mesh.triangles[face], pts)
    assert bary.min() > -1e-9 and bary.max() < 1 + 1e-9
    # Uniform over the area: faces hit in proportion to their area (big faces
    # pooled so each expects >= 20), and within a triangle the corner weights
    # average 1/3.
    expected = n * mesh.area_faces / mesh.area
    order = np.argsort(expected)
    key = np.empty(len(order), dtype=np.int64)
    key[order] = np.searchsorted(np.arange(20.0, n, 20.0), np.cumsum(expected[order]))
    observed = np.bincount(key[face], minlength=key.max() + 1)
    wanted = np.bincount(key, weights=expected, minlength=key.max() + 1)
    keep = wanted > 0
    assert chisquare(observed[keep], wanted[keep]).pvalue > 1e-4
    np.testing.assert_allclose(bary.mean(axis=0), 1 / 3, atol=0.005)
    # The same draws and arithmetic as trimesh's sampler: the same points.
    ref, ref_face = trimesh.sample.sample_surface(mesh.to_trimesh(), 1000,
                                                  seed=np.random.default_rng(9))
    ours, our_face = sample_surface(mesh.vertices, mesh.faces, mesh.area_faces, 1000,
                                    np.random.default_rng(9))
    np.testing.assert_array_equal(our_face, ref_face)
    np.testing.assert_array_equal(ours, ref)


def test_stipple_normals_on_box() -> None:
    box = _box()
    s = stipple(Model(box, box.vertices), np.random.default_rng(3), count=400)
    half = 0.5 * np.array(BOX_EXTENTS)
    assert s.normals is not None
    # A point on face x = +half[0] has normal +x, and so on.
    on = np.abs(np.abs(s.points) - half) < 1e-9
    axis = np.argmax(np.abs(s.normals), axis=1)
    assert on[np.arange(len(s)), axis].all()
    sign = np.sign(s.points[np.arange(len(s)), axis])
    np.testing.assert_allclose(s.normals[np.arange(len(s)), axis], sign)


def test_stipple_is_blue_noise(bunny: Model) -> None:
    n = 2000
    s = stipple(bunny, np.random.default_rng(2), count=n)
    assert bunny.mesh is not None
    uniform, _ = trimesh.sample.sample_surface(bunny.mesh.to_trimesh(), n,
                                               seed=np.random.default_rng(2))
    spacing = math.sqrt(bunny.mesh.area / n)
    # Poisson-disk: no two stipples much closer than the mean spacing, while
    # uniform samples of the same size clump.
    assert _min_distance(s.points) > 0.6 * spacing
    assert _min_distance(s.points) > 10 * _min_distance(np.asarray(uniform))


def test_stipple_deterministic(bunny: Model) -> None:
    a = stipple(bunny, np.random.default_rng(42), count=800)
    b = stipple(bunny, np.random.default_rng(42), count=800)
    c = stipple(bunny, np.random.default_rng(43), count=800)
    np.testing.assert_array_equal(a.points, b.points)
    assert a.normals is not None and b.normals is not None
    np.testing.assert_array_equal(a.normals, b.normals)
    assert not np.array_equal(np.sort(a.points, axis=0), np.sort(c.points, axis=0))


def test_stipple_spacing_covers_surface(bunny: Model) -> None:
    spacing = 2.0
    s = stipple(bunny, np.random.default_rng(5), spacing=spacing)
    assert _min_distance(s.points) >= spacing
    # Maximal: every part of the surface has a stipple nearby.
    assert bunny.mesh is not None
    probe, _ = trimesh.sample.sample_surface(bunny.mesh.to_trimesh(), 5000,
                                             seed=np.random.default_rng(9))
    gap = cKDTree(s.points).query(np.asarray(probe))[0]
    assert gap.max() < 2.0 * spacing


@settings(max_examples=25, deadline=None)
@given(count=st.integers(1, 400), seed=st.integers(0, 2**32 - 1))
def test_stipple_count_exact_on_box(count: int, seed: int) -> None:
    box = _box()
    s = stipple(Model(box, box.vertices), np.random.default_rng(seed), count=count)
    assert len(s) == count
    half = 0.5 * np.array(BOX_EXTENTS)
    # On the box surface: inside the box, on one of its faces.
    assert (np.abs(s.points) <= half + 1e-9).all()
    assert np.isclose(np.max(np.abs(s.points) / half, axis=1), 1.0).all()
    if count > 1:
        assert _min_distance(s.points) > 0.5 * math.sqrt(box.area / count)


def test_stipple_point_cloud(bunny: Model) -> None:
    cloud = Model(mesh=None, points=bunny.points)
    s = stipple(cloud, np.random.default_rng(0), count=300)
    assert s.normals is None and len(s) == 300
    # A subset of the cloud, spread out.
    idx = cKDTree(cloud.points).query(s.points)[0]
    assert idx.max() == 0.0
    assert _min_distance(s.points) > 3 * _min_distance(cloud.points)


def test_stipple_point_cloud_too_small() -> None:
    pts = np.random.default_rng(0).random((30, 3))
    s = stipple(Model(mesh=None, points=pts), np.random.default_rng(0), count=100)
    assert len(s) == 30
    np.testing.assert_array_equal(np.sort(s.points, axis=0), np.sort(pts, axis=0))


def test_stipple_point_cloud_spacing() -> None:
    pts = np.random.default_rng(0).random((5000, 3))
    pts[:, 2] = 0.0
    s = stipple(Model(mesh=None, points=pts), np.random.default_rng(0), spacing=0.05)
    assert _min_distance(s.points) >= 0.05
    assert cKDTree(s.points).query(pts)[0].max() < 0.1


@pytest.mark.parametrize(
    ("kwargs", "fragment"),
    [
        ({}, "exactly one"),
        ({"count": 10, "spacing": 1.0}, "exactly one"),
        ({"count": 0}, "count"),
        ({"count": -4}, "count"),
        ({"count": 2.5}, "count"),
        ({"count": True}, "count"),
        ({"spacing": 0.0}, "spacing"),
        ({"spacing": -1.0}, "spacing"),
        ({"spacing": math.nan}, "spacing"),
        ({"spacing": math.inf}, "spacing"),
        ({"spacing": 1e-6}, "too small"),
    ],
)
def test_stipple_bad_arguments(bunny: Model, kwargs: dict[str, float], fragment: str) -> None:
    with pytest.raises(SpecholoError, match=fragment):
        stipple(bunny, np.random.default_rng(0), **kwargs)  # type: ignore[arg-type]


@pytest.mark.parametrize("grid", [False, True])
def test_disk_sets_are_the_greedy_pass_in_priority_order(grid: bool) -> None:
    """Each candidate is kept iff no higher-ranked kept one is within r (a pair at
    exactly r conflicts), also for points on the cubes' faces and at distance r."""
    from specholo.scene.stippling import _DiskSets

    rng = np.random.default_rng(7)
    r = 0.25
    if grid:  # lattice points: many pairs at exactly r, many points on cube faces
        pts = rng.integers(0, 12, size=(1500, 3)) * (r / 2)
    else:
        pts = rng.random((1500, 3)) * [4.0, 3.0, 0.5]
    priority = rng.permutation(len(pts))
    got = _DiskSets(pts, priority).independent_set(r)
    kept: list[int] = []
    for i in np.argsort(-priority):
        if not kept or np.sqrt(((pts[kept] - pts[i]) ** 2).sum(axis=1)).min() > r:
            kept.append(int(i))
    np.testing.assert_array_equal(got, np.sort(kept))


# ---------------------------------------------------------------- orientation


def _column() -> Model:
    """A CAD-style z-up column: 10 x 4 x 40 model units, its front face at -y."""
    mesh = trimesh.creation.box(extents=(10.0, 4.0, 40.0))
    return Model(mesh=mesh, points=np.asarray(mesh.vertices, dtype=float))


@pytest.mark.parametrize("up", sorted(UP_AXES))
def test_up_axis_goes_to_the_plate_s_up(up: str) -> None:
    r = orientation(up)
    assert np.allclose(r @ r.T, np.eye(3)) and np.linalg.det(r) == pytest.approx(1.0)
    axis = np.zeros(3)
    axis["xyz".index(up[-1])] = -1.0 if up.startswith("-") else 1.0
    assert np.allclose(axis @ r, [0.0, 1.0, 0.0])


def test_a_z_up_model_stands_up_facing_the_viewer() -> None:
    placed = place(_column(), 60.0, -40.0, orientation("z"))
    ext = np.ptp(placed.points, axis=0)
    # its 40 units of height run up the plate, scaled to 60 mm; its 4-unit depth
    # runs toward the viewer
    assert ext == pytest.approx([15.0, 60.0, 6.0])
    # the model's front (-y) face now faces the viewer (+z), and every face still
    # points out of the solid (a proper rotation keeps the winding)
    mesh = placed.mesh.to_trimesh()
    front = mesh.face_normals[:, 2] > 0.99
    assert np.allclose(mesh.triangles_center[front, 2], -40.0 + 3.0)
    assert mesh.is_winding_consistent and mesh.volume > 0


def test_rotations_and_offset_on_the_plate() -> None:
    # a quarter turn about the viewer's axis lays the standing column on its side
    placed = place(_column(), 60.0, -40.0, orientation("z", (0.0, 0.0, math.pi / 2)),
                   offset=(12.0, -7.0))
    assert np.ptp(placed.points, axis=0) == pytest.approx([60.0, 15.0, 6.0])
    lo, hi = placed.points.min(axis=0), placed.points.max(axis=0)
    assert 0.5 * (lo + hi) == pytest.approx([12.0, -7.0, -40.0])


def test_bad_orientations_are_refused() -> None:
    with pytest.raises(SpecholoError, match="up must be one of"):
        orientation("w")
    with pytest.raises(SpecholoError, match="finite"):
        orientation("y", (0.0, math.nan, 0.0))


def test_the_axes_offered_agree() -> None:
    from specholo.jobs.plate_settings import UP_AXES as CONFIG_AXES
    from specholo_cli.app import _DESIGN_OPTIONS

    choice = next(kind for name, kind, _ in _DESIGN_OPTIONS if name == "up")
    assert set(CONFIG_AXES) == set(UP_AXES) == set(choice.choices)


def test_a_z_up_file_with_up_z_designs_the_y_up_model_s_plate(tmp_path: Path) -> None:
    """The bunny (y-up) written as a CAD file would hold it (z-up, front at -y) and
    designed with --up z gives the bunny's own grooves."""
    from specholo.jobs.flat.folder import DesignConfig, design

    bunny = trimesh.load(BUNNY, force="mesh")
    v = np.asarray(bunny.vertices)
    cad = trimesh.Trimesh(np.column_stack([v[:, 0], -v[:, 2], v[:, 1]]), bunny.faces,
                          process=False)
    path = tmp_path / "bunny_zup.obj"
    cad.export(path, digits=17)  # every digit of the bunny's own coordinates
    plain = design(BUNNY, DesignConfig(stipples=60, placement="phase"), check_overlaps=False,
                   expect_as_cut=False)
    turned = design(path, DesignConfig(stipples=60, placement="phase", up="z"),
                    check_overlaps=False, expect_as_cut=False)
    np.testing.assert_allclose(turned.points, plain.points, atol=1e-9)
    np.testing.assert_array_equal(turned.grooves.offsets, plain.grooves.offsets)
    np.testing.assert_allclose(turned.grooves.vertices, plain.grooves.vertices, atol=1e-6)
