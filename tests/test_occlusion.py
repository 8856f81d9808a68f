"""Tests of occlusion: visibility of stipples and their visible azimuth intervals."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq

from specholo.errors import SpecholoError
from specholo.scene.loading import load_model
from specholo.scene.placement import place
from specholo.scene.stippling import stipple
from specholo.setup import Viewer
from specholo.visibility.occlusion import Intervals, visible, visible_intervals

BUNNY = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"
VIEWER = Viewer()  # D = 600 mm, eye height 0
R = VIEWER.design_range
EDGE_TOL = math.radians(0.05)

# Two boxes seen from the viewer (+z): a wide front box straddling the plate
# and a small back box hidden behind it when seen head-on.
FRONT_HALF = np.array([20.0, 20.0, 5.0])  # x in [-20, 20], z in [-5, 5]
BACK_CENTRE = np.array([0.0, 0.0, -40.0])
BACK_HALF = np.array([5.0, 5.0, 5.0])  # x in [-5, 5], z in [-45, -35]


@pytest.fixture(scope="module")
def two_boxes() -> trimesh.Trimesh:
    front = trimesh.creation.box(extents=2 * FRONT_HALF)
    back = trimesh.creation.box(extents=2 * BACK_HALF)
    back.apply_translation(BACK_CENTRE)
    both = trimesh.util.concatenate([front, back])
    assert isinstance(both, trimesh.Trimesh)
    return both


def _clear_corner(p: np.ndarray, corner_x: float, corner_z: float) -> float:
    """Azimuth at which the sight line from p (in the y = 0 plane) to the eye
    passes exactly through the front box's edge at (corner_x, corner_z)."""

    def f(theta: float) -> float:
        e = VIEWER.eye(np.array([theta]))[0]
        # x of the line p -> e at z = corner_z, minus the corner's x.
        return p[0] + (corner_z - p[2]) * (e[0] - p[0]) / (e[2] - p[2]) - corner_x

    return float(brentq(f, 0.0, R))


def test_back_box_front_face_hidden_then_visible(two_boxes: trimesh.Trimesh) -> None:
    # Centre of the back box's front face, facing the viewer: hidden behind the
    # front box until the sight line clears its back edge at x = +-20, z = -5.
    p = np.array([0.0, 0.0, BACK_CENTRE[2] + BACK_HALF[2]])
    theta_c = _clear_corner(p, FRONT_HALF[0], -FRONT_HALF[2])
    assert 0.3 < theta_c < 0.9 * R
    iv = visible_intervals(two_boxes, p[None], np.array([[0.0, 0.0, 1.0]]), VIEWER)
    rows = iv.for_stipple(0)
    assert rows.shape == (2, 2)
    assert rows[0, 0] == -R and rows[1, 1] == R
    assert abs(rows[0, 1] - -theta_c) < EDGE_TOL
    assert abs(rows[1, 0] - theta_c) < EDGE_TOL


def test_back_box_side_face_edge(two_boxes: trimesh.Trimesh) -> None:
    # Centre of the back box's right face (normal +x): faces the eye once
    # D sin(theta) > 5, but stays hidden until the sight line clears (20, -5).
    p = BACK_CENTRE + np.array([BACK_HALF[0], 0.0, 0.0])
    theta_c = _clear_corner(p, FRONT_HALF[0], -FRONT_HALF[2])
    assert theta_c > math.asin(BACK_HALF[0] / VIEWER.distance) + math.radians(5)
    iv = visible_intervals(two_boxes, p[None], np.array([[1.0, 0.0, 0.0]]), VIEWER)
    rows = iv.for_stipple(0)
    assert rows.shape == (1, 2)
    assert abs(rows[0, 0] - theta_c) < EDGE_TOL
    assert rows[0, 1] == R


def test_front_box_side_face_facing_edge(two_boxes: trimesh.Trimesh) -> None:
    # Centre of the front box's right face: nothing occludes it, it turns
    # visible exactly when the eye passes to the outer side of its plane.
    p = np.array([FRONT_HALF[0], 0.0, 0.0])
    theta_c = math.asin(FRONT_HALF[0] / VIEWER.distance)
    iv = visible_intervals(two_boxes, p[None], np.array([[1.0, 0.0, 0.0]]), VIEWER)
    rows = iv.for_stipple(0)
    assert rows.shape == (1, 2)
    assert abs(rows[0, 0] - theta_c) < EDGE_TOL
    assert rows[0, 1] == R


def test_front_face_visible_everywhere_back_face_never(two_boxes: trimesh.Trimesh) -> None:
    points = np.array([[3.0, -2.0, FRONT_HALF[2]], [3.0, -2.0, -FRONT_HALF[2]]])
    normals = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    theta = np.linspace(-R, R, 50)
    for i in range(2):
        eyes = VIEWER.eye(theta)
        vis = visible(
            two_boxes,
            np.repeat(points[i : i + 1], 50, 0),
            np.repeat(normals[i : i + 1], 50, 0),
            eyes,
        )
        assert vis.all() if i == 0 else not vis.any()
    iv = visible_intervals(two_boxes, points, normals, VIEWER)
    np.testing.assert_array_equal(iv.stipple, [0])
    np.testing.assert_array_equal(iv.for_stipple(0), [[-R, R]])
    assert iv.for_stipple(1).shape == (0, 2)


def test_hits_beyond_the_eye_do_not_count(two_boxes: trimesh.Trimesh) -> None:
    # The back box's front face seen from an eye between the two boxes: the
    # front box lies on the ray but past the eye.
    p = np.array([[0.0, 0.0, -35.0]])
    n = np.array([[0.0, 0.0, 1.0]])
    assert visible(two_boxes, p, n, np.array([[0.0, 0.0, -20.0]]))[0]
    assert not visible(two_boxes, p, n, np.array([[0.0, 0.0, 600.0]]))[0]
    # One eye for all points broadcasts.
    assert visible(two_boxes, np.repeat(p, 3, 0), np.repeat(n, 3, 0), np.array([0, 0, -20.0])).all()


def test_point_cloud_always_visible() -> None:
    pts = np.random.default_rng(0).normal(size=(20, 3))
    assert visible(None, pts, None, VIEWER.eye(np.zeros(20))).all()
    iv = visible_intervals(None, pts, None, VIEWER)
    np.testing.assert_array_equal(iv.stipple, np.arange(20))
    np.testing.assert_array_equal(iv.start, -R)
    np.testing.assert_array_equal(iv.end, R)


def test_bunny_intervals_agree_with_direct_rays() -> None:
    model = place(load_model(BUNNY), 60.0, -20.0)
    s = stipple(model, np.random.default_rng(0), count=1500)
    assert model.mesh is not None and s.normals is not None
    iv = visible_intervals(model.mesh, s.points, s.normals, VIEWER)
    # Well formed: sorted by stipple then start, disjoint, inside the range.
    assert (iv.start < iv.end).all()
    assert (iv.start >= -R).all() and (iv.end <= R).all()
    same = iv.stipple[1:] == iv.stipple[:-1]
    assert (np.diff(iv.stipple) >= 0).all()
    assert (iv.start[1:][same] > iv.end[:-1][same]).all()
    # Some stipples are occluded somewhere, some seen all along the arc.
    full = (iv.start == -R) & (iv.end == R)
    assert 0 < full.sum() < len(s)
    # Membership matches a direct ray test at random azimuths (except within
    # features narrower than the 1-degree grid).
    rng = np.random.default_rng(1)
    ids = rng.integers(0, len(s), 20000)
    theta = rng.uniform(-R, R, len(ids))
    direct = visible(model.mesh, s.points[ids], s.normals[ids], VIEWER.eye(theta))
    assert (iv.contains(ids, theta) == direct).mean() > 0.995


@pytest.mark.parametrize(
    ("kwargs", "fragment"),
    [
        ({"step": 0.0}, "step"),
        ({"step": -1.0}, "step"),
        ({"step": math.nan}, "step"),
        ({"refine": -1}, "refinement"),
        ({"refine": 1.5}, "refinement"),
    ],
)
def test_visible_intervals_bad_arguments(
    two_boxes: trimesh.Trimesh, kwargs: dict[str, float], fragment: str
) -> None:
    p = np.zeros((1, 3))
    n = np.array([[0.0, 0.0, 1.0]])
    with pytest.raises(SpecholoError, match=fragment):
        visible_intervals(two_boxes, p, n, VIEWER, **kwargs)  # type: ignore[arg-type]


def test_mesh_needs_normals(two_boxes: trimesh.Trimesh) -> None:
    with pytest.raises(SpecholoError, match="normals"):
        visible(two_boxes, np.zeros((2, 3)), None, np.ones((2, 3)))
    with pytest.raises(SpecholoError, match="shape"):
        visible(two_boxes, np.zeros((2, 3)), np.ones((3, 3)), np.ones((2, 3)))


@st.composite
def _intervals(draw: st.DrawFn) -> Intervals:
    n_stipples = draw(st.integers(1, 6))
    ids, starts, ends = [], [], []
    for i in range(n_stipples):
        cuts = sorted(set(draw(st.lists(st.floats(-1.0, 1.0), max_size=8))))
        cuts = cuts[: len(cuts) // 2 * 2]
        for a, b in zip(cuts[::2], cuts[1::2], strict=True):
            ids.append(i)
            starts.append(a)
            ends.append(b)
    return Intervals(
        stipple=np.array(ids, dtype=np.int64),
        start=np.array(starts, dtype=float),
        end=np.array(ends, dtype=float),
    )


@settings(max_examples=60, deadline=None)
@given(
    iv=_intervals(),
    queries=st.lists(st.tuples(st.integers(0, 6), st.floats(-1.2, 1.2)), min_size=1, max_size=30),
)
def test_intervals_contains_matches_brute_force(
    iv: Intervals, queries: list[tuple[int, float]]
) -> None:
    ids = np.array([q[0] for q in queries])
    theta = np.array([q[1] for q in queries])
    # Query the interval ends exactly too: intervals are closed.
    if len(iv):
        ids = np.concatenate([ids, iv.stipple, iv.stipple])
        theta = np.concatenate([theta, iv.start, iv.end])
    expect = [
        any(a <= t <= b for a, b in iv.for_stipple(int(i))) for i, t in zip(ids, theta, strict=True)
    ]
    np.testing.assert_array_equal(iv.contains(ids, theta), expect)


def test_bulk_rays_hit_what_trimeshs_tracer_hits(monkeypatch: pytest.MonkeyPatch) -> None:
    """The rays set up in bulk for the mesh's embree scene give, to the bit, the
    intervals and visibility of trimesh's own ray tracer on the same rays."""
    from specholo.visibility import occlusion

    model = place(load_model(BUNNY), 60.0, -20.0)
    s = stipple(model, np.random.default_rng(4), count=3000)
    rng = np.random.default_rng(5)
    eyes = VIEWER.eye(rng.uniform(-R, R, len(s)))
    bulk_iv = visible_intervals(model.mesh, s.points, s.normals, VIEWER)
    bulk = visible(model.mesh, s.points, s.normals, eyes)
    monkeypatch.setattr(occlusion, "_HAVE_EMBREE", False)
    ref_iv = visible_intervals(model.mesh, s.points, s.normals, VIEWER)
    np.testing.assert_array_equal(bulk, visible(model.mesh, s.points, s.normals, eyes))
    assert 0.2 < bulk.mean() < 0.9
    for a, b in ((bulk_iv.stipple, ref_iv.stipple), (bulk_iv.start, ref_iv.start),
                 (bulk_iv.end, ref_iv.end)):
        np.testing.assert_array_equal(a, b)
