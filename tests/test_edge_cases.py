"""Geometric edge cases, each with its physical outcome.

- A stipple on or very near the plate is a dimple that glints at its own xy for
  every eye.
- A stipple at a point light is dropped, with the reason.
- Directly under a point light above the plate, with the eyes level with the
  stipples, the light lies in the eyes' plane: dropped, with the reason; with
  the eyes higher the same stipples are designed and glint.
- A grazing light needs steeper walls than a drag tip has: the lost views are
  reported with a tool that serves them, and a deep ball does.
- Eyes at the very edge of the view range still see every stipple; past the
  range the grooves end.
- A plate smaller than the grooves (sightlines that would miss it) is refused in
  one line; a plate of exactly the size needed is accepted, arcs included.
- A model in front of the plate shows with reversed parallax and the same accuracy.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from specholo.errors import SpecholoError
from specholo.hosts.flat import sightline_crossing
from specholo.jobs.flat.folder import DesignConfig, design, drop_reasons, groove_extent
from specholo.optics.cutters import check_views
from specholo.simulation.glints import Engraved, find_glints
from specholo.simulation.verify import verify
from specholo.toolpaths.common import Runs
from specholo.toolpaths.striped import StripeOptions, at_light, design_striped
from specholo_cli.cli import main

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"


def _design(points: list[list[float]], **settings: object):  # type: ignore[no-untyped-def]
    setup = DesignConfig(**settings).setup()  # type: ignore[arg-type]
    pts = np.asarray(points, dtype=float)
    r = setup.viewer.design_range
    n = len(pts)
    runs = Runs(np.arange(n), pts, np.full(n, -r), np.full(n, r))
    grooves, dropped = design_striped(runs, setup, StripeOptions())
    return setup, pts, grooves, dropped


def _glints(setup, grooves, theta_deg: float):  # type: ignore[no-untyped-def]
    """Each eye's glints for a single eye at that azimuth on the eyes' circle."""
    eye = setup.viewer.eye(np.array([math.radians(theta_deg)]))[0]
    return eye, find_glints(Engraved.from_grooves(grooves, setup.tool), eye, setup.light)


AZIMUTHS = (-46.0, -30.0, -10.0, 0.0, 10.0, 30.0, 46.0)


# Half the default tip's groove width is 0.016 mm: a point within it is a dimple.
@pytest.mark.parametrize("z", [0.0, 1e-9, -1e-6, 0.012, -0.016])
def test_a_stipple_on_the_plate_is_a_dimple_glinting_at_its_xy_for_every_eye(z: float) -> None:
    setup, pts, grooves, dropped = _design([[4.0, -3.0, z]])
    assert len(dropped) == 0
    assert grooves.n_paths == 1 and bool(grooves.is_dot[0])  # a single plunge
    for theta in AZIMUTHS:
        _, g = _glints(setup, grooves, theta)
        assert len(g.stipple) >= 1, theta
        # Seen where the point is, from every eye: within the dimple's wall
        # offset turning with the eye (a few hundredths of a millimetre).
        off = np.linalg.norm(g.point[:, :2] - pts[0, :2], axis=1).min()
        assert off < 0.03, (theta, off)
    reports = verify(grooves, pts, setup)
    assert min(r.visibility for r in reports) == 1.0
    assert max(r.max_error for r in reports) < 0.1


def test_a_stipple_just_off_the_plate_is_a_groove_seen_at_its_place() -> None:
    setup, pts, grooves, _ = _design([[4.0, -3.0, 0.2]])
    assert not grooves.is_dot.any()
    reports = verify(grooves, pts, setup)
    assert min(r.visibility for r in reports) == 1.0
    assert max(r.max_error for r in reports) < 0.25


def test_a_stipple_at_the_point_light_is_dropped_with_the_reason() -> None:
    light = 200.0 * np.array([0.0, math.cos(math.radians(45)), math.sin(math.radians(45))])
    pts = [list(light), list(light + [0.0, 0.0, 0.01]), [0.0, 0.0, 20.0]]
    setup, pts_a, grooves, dropped = _design(pts, light_distance=200.0)
    assert at_light(pts_a, setup).tolist() == [True, True, False]
    assert dropped.tolist() == [0, 1]
    assert set(grooves.stipple.tolist()) == {2}
    reasons = drop_reasons(pts_a, dropped, setup)
    assert set(reasons) == {"0", "1"}
    assert all(r.startswith("at the light") for r in reasons.values())


def test_under_a_point_light_the_light_is_in_the_eyes_plane() -> None:
    pts = [[0.0, 0.0, -20.0], [0.0, 10.0, -20.0], [5.0, -5.0, 15.0]]
    setup, pts_a, grooves, dropped = _design(pts, light_elevation=90.0, light_distance=300.0)
    # Eyes level with the stipples, light straight above the plate centre: every
    # half vector is nearly horizontal, the groove would have to run vertically.
    assert dropped.tolist() == [0, 1, 2] and grooves.n_paths == 0
    assert all(r.startswith("light in the eyes' plane")
               for r in drop_reasons(pts_a, dropped, setup).values())
    # Eyes 150 mm higher: the same light and stipples are designed and glint.
    setup, pts_a, grooves, dropped = _design(pts, light_elevation=90.0, light_distance=300.0,
                                             eye_height=150.0)
    assert len(dropped) == 0
    reports = verify(grooves, pts_a, setup)
    assert min(r.visibility for r in reports) == 1.0
    assert max(r.p95_error for r in reports) < 0.25


def test_a_sun_straight_at_the_plate_drops_every_stipple_in_the_cli(tmp_path: Path,
                                                                    capsys) -> None:
    out = tmp_path / "holo"
    # No stipple is left with a groove: nothing to cut, so the design is refused.
    assert main(["design", str(BUNNY), "--out", str(out), "--stipples", "10",
                 "--light-elevation", "90"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: no stipple gets a groove"), err
    assert "could not be designed (5: light in the eyes' plane)" in err[0]
    assert not out.exists()


@pytest.mark.parametrize("elevation", [0.5, 1e-4])
def test_a_grazing_light_loses_views_on_a_drag_tip_and_a_deep_ball_serves_them(
        elevation: float) -> None:
    pts = [[0.0, 0.0, -20.0], [10.0, 5.0, -35.0]]
    setup, pts_a, grooves, dropped = _design(pts, light_elevation=elevation)
    assert len(dropped) == 0 and grooves.n_paths > 0
    cfg = DesignConfig(light_elevation=elevation)
    r = setup.viewer.design_range
    views = check_views(cfg.cutter(), cfg.depth_mm, pts_a, np.arange(2), np.full(2, -r),
                        np.full(2, r), setup.light, setup.viewer)
    assert views.lost == 1.0 and "ball" in views.suggestion
    # A glint needs h tilted up to about 62 degrees: the drag tip's walls stop at 40.
    assert verify(grooves, pts_a, setup)[0].visibility == 0.0
    setup, pts_a, grooves, _ = _design(pts, light_elevation=elevation, tool="ball", depth=0.25)
    reports = verify(grooves, pts_a, setup)
    assert min(r.visibility for r in reports) == 1.0
    assert max(r.p95_error for r in reports) < 0.25


def test_eyes_at_the_edge_of_the_view_range_see_every_stipple() -> None:
    pts = [[0.0, 0.0, -40.0], [20.0, 10.0, -60.0], [-15.0, -5.0, 25.0]]
    setup, pts_a, grooves, _ = _design(pts, view_range=30.0)
    edge = setup.viewer.half_range
    reports = verify(grooves, pts_a, setup, azimuths=np.array([-edge, edge]))
    assert [r.visibility for r in reports] == [1.0, 1.0]
    assert max(r.p95_error for r in reports) < 0.25
    # Well past the range (the heads' eyes beyond the designed circle) the
    # grooves have ended: nothing glints.
    far = edge + setup.viewer.eye_half_angle + math.radians(3.0)
    for theta in (-far, far):
        _, g = _glints(setup, grooves, math.degrees(theta))
        assert len(g.stipple) == 0


def test_a_plate_smaller_than_the_grooves_is_refused_and_the_exact_size_fits(
        tmp_path: Path, capsys) -> None:
    cfg = DesignConfig(stipples=30, method="arc")
    d = design(BUNNY, cfg, check_overlaps=False)
    width = cfg.cutter().section(d.config.depth_mm).width
    lo, hi = groove_extent(d.grooves)
    need = 2 * (np.maximum(np.abs(lo), np.abs(hi)) + 0.5 * width)
    # Arcs bulge past their end points: the plate must hold the arcs, not the chords.
    vlo, vhi = d.grooves.bounds()
    assert np.all(lo <= vlo) and np.all(hi >= vhi)
    small = ["--plate-width", f"{need[0] * 0.9:.4f}", "--plate-height", f"{need[1] + 1:.4f}"]
    out = tmp_path / "small"
    code = main(["design", str(BUNNY), "--out", str(out), "--stipples", "30",
                 "--method", "arc", *small])
    _, err = capsys.readouterr()
    assert code == 1 and err.startswith("error: plate width") and err.count("\n") == 1
    assert "smaller than the design" in err and not out.exists()
    exact = ["--plate-width", f"{need[0] + 1e-3:.4f}", "--plate-height",
             f"{need[1] + 1e-3:.4f}"]
    out = tmp_path / "exact"
    assert main(["design", str(BUNNY), "--out", str(out), "--stipples", "30",
                 "--method", "arc", *exact]) == 0, capsys.readouterr().err
    info = json.loads((out / "hologram.json").read_text())
    assert info["machining"]["safety_check"]["violations"] == 0


def test_a_model_in_front_of_the_plate_shows_with_reversed_parallax() -> None:
    front, behind = [0.0, 5.0, 30.0], [0.0, 5.0, -30.0]
    setup, pts, grooves, dropped = _design([front, behind])
    assert len(dropped) == 0
    xs = {0: [], 1: []}  # type: dict[int, list[float]]
    for theta in (-30.0, 30.0):
        eye, g = _glints(setup, grooves, theta)
        for i in (0, 1):
            m = g.stipple == i
            assert m.any()
            want = sightline_crossing(eye[None], pts[i][None])[0, :2]
            assert np.linalg.norm(g.point[m][:, :2] - want, axis=1).min() < 0.25
            xs[i].append(float(g.point[m][0, 0]))
    # Walking right, the glint of a point behind the plate moves right with the
    # eye (as through a window); the glint of a point in front moves left.
    assert xs[0][1] < xs[0][0] and xs[1][1] > xs[1][0]
    reports = verify(grooves, pts, setup)
    assert min(r.visibility for r in reports) == 1.0
    assert max(r.p95_error for r in reports) < 0.25


def test_a_model_reaching_toward_the_eyes_is_refused() -> None:
    with pytest.raises(SpecholoError, match="too close to the eyes"):
        design(BUNNY, DesignConfig(stipples=10, center_z=400.0, size=60.0))


def test_verification_in_stipple_chunks_gives_the_same_figures() -> None:
    """Large designs are verified a chunk of stipples at a time: every glint
    belongs to one stipple, so the figures must not change at all."""
    from specholo.visibility.occlusion import visible

    d = design(BUNNY, DesignConfig(stipples=300, seed=4))
    setup = d.config.setup()

    def vis(points: np.ndarray, eyes: np.ndarray) -> np.ndarray:
        return visible(d.model.mesh, points, d.normals, eyes)

    az = np.radians([-30.0, 0.0, 20.0])
    whole = verify(d.grooves, d.points, setup, vis, az)
    parts = verify(d.grooves, d.points, setup, vis, az, chunk_vertices=2_000)
    assert whole == parts
    assert whole[1].stipples_seen > 100 and whole[1].p95_error < 0.3


@pytest.mark.parametrize("room", [None, (0, 0), (5, 1), (10_000, 1_000)])
def test_grooves_built_in_parts_are_the_parts_end_to_end(room: tuple[int, int] | None) -> None:
    from specholo.toolpaths.grooves import Grooves, GroovesBuilder

    rng = np.random.default_rng(3)
    parts = []
    for n_paths in (3, 0, 1, 4):
        sizes = rng.integers(2, 6, n_paths)
        nv = int(sizes.sum())
        parts.append(Grooves(rng.normal(size=(nv, 2)), rng.normal(size=nv),
                             np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
                             rng.integers(0, 50, n_paths)))
    b = GroovesBuilder()
    if room is not None:
        b.reserve(*room)
    for k, part in enumerate(parts):
        if k % 2:  # written in place, as the striped walk does
            base, v, bu, o, s = b.extend(len(part.vertices), part.n_paths)
            v[:], bu[:], s[:] = part.vertices, part.bulges, part.stipple
            o[:] = part.offsets[:-1] + base
        else:
            b.add(part)
    g = b.build()
    np.testing.assert_array_equal(g.vertices, np.concatenate([p.vertices for p in parts]))
    np.testing.assert_array_equal(g.bulges, np.concatenate([p.bulges for p in parts]))
    np.testing.assert_array_equal(g.stipple, np.concatenate([p.stipple for p in parts]))
    base = np.cumsum([0] + [len(p.vertices) for p in parts])
    want = np.concatenate([[0]] + [p.offsets[1:] + base[k] for k, p in enumerate(parts)])
    np.testing.assert_array_equal(g.offsets, want)
    assert len(g.vertices) == g.offsets[-1] and g.vertices.flags.owndata


def test_measured_path_lengths_are_the_arcs_lengths() -> None:
    """One pass gives each path's arc length (flat arcs by a series, bulged ones by
    atan) and the extent; a half circle of radius 1 is pi long."""
    from specholo.toolpaths.grooves import Grooves

    rng = np.random.default_rng(11)
    sizes = rng.integers(1, 7, 300)
    nv = int(sizes.sum())
    # Bulges from straight to a half turn, many below the series' 1e-2.
    bulges = rng.choice([0.0, 1e-9, 3e-3, 9.9e-3, 1e-2, 0.3, 1.0, -0.7], nv) * rng.random(nv)
    g = Grooves(rng.normal(size=(nv, 2)), bulges,
                np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
                np.arange(len(sizes)))
    extent, lengths = g.measure()
    seg = g.segments()
    want = np.bincount(seg.path, weights=seg.lengths(), minlength=g.n_paths)
    np.testing.assert_allclose(lengths, want, rtol=1e-14, atol=0)
    np.testing.assert_array_equal(extent, g.extent())
    half = Grooves(np.array([[1.0, 0.0], [-1.0, 0.0]]), np.array([1.0, 0.0]),
                   np.array([0, 2]), np.array([0]))
    assert half.measure()[1][0] == pytest.approx(math.pi, rel=1e-15)
    np.testing.assert_allclose(half.extent(), [[-1.0, 0.0], [1.0, 1.0]], atol=1e-15)


def test_small_pages_turns_numpy_huge_pages_off_inside_only() -> None:
    """Groove storage is allocated without numpy's huge-page advice (its first
    touch is several times slower on machines that compact memory for it), and
    the setting is restored after, also when the block raises."""
    import numpy._core.multiarray as multiarray

    from specholo._pages import small_pages

    before = multiarray._get_madvise_hugepage()
    with small_pages():
        assert multiarray._get_madvise_hugepage() is False
    assert multiarray._get_madvise_hugepage() is before
    with pytest.raises(RuntimeError), small_pages():
        raise RuntimeError("boom")
    assert multiarray._get_madvise_hugepage() is before
