"""The cut simulation: height field, glints on it, verification and STL."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import trimesh

from specholo.errors import SpecholoError
from specholo.setup import Light, Setup, Tool, Viewer
from specholo.simulation.cut import (
    CutCells,
    ToolProfile,
    agreement,
    as_profile,
    cut_design,
    cut_surface,
    find_cut_glints,
    verify_cut,
    write_stl,
)
from specholo.simulation.glints import Engraved, find_glints
from specholo.simulation.verify import verify
from specholo.toolpaths.grooves import Grooves

TOOL = Tool(0.25, 0.08)
SUN = Light(math.radians(45.0))


def ball(r: np.ndarray, tool: Tool = TOOL) -> np.ndarray:
    """Analytic cross-section of a ball-end groove (0 outside)."""
    R = tool.radius
    z = -tool.depth + R - np.sqrt(np.maximum(R * R - r * r, 0.0))
    return np.where(np.abs(r) < R, np.minimum(z, 0.0), 0.0)


def one_path(vertices: list[list[float]], bulges: list[float]) -> Grooves:
    return Grooves(np.array(vertices, dtype=float), np.array(bulges, dtype=float),
                   np.array([0, len(vertices)]), np.array([7]))


def test_straight_groove_cross_section_is_the_ball() -> None:
    g = one_path([[-2.0, 0.0], [2.0, 0.0]], [0.0, 0.0])
    hf = cut_surface(g, TOOL, TOOL.depth, bounds=np.array([[-3.0, -1.0], [3.0, 1.0]]),
                     resolution=0.01)
    inner = np.abs(hf.x) < 1.5  # away from the caps
    section = hf.z[:, inner]
    expect = ball(hf.y)[:, None]
    assert np.abs(section - expect).max() < 1e-6
    assert np.all(hf.labels[:, inner][expect[:, 0] < 0] == 0)
    assert np.all(hf.labels[np.broadcast_to(expect, hf.z.shape) == 0] <= 0)
    # The caps are the ball about the path's ends.
    r = np.hypot(*np.meshgrid(hf.x - 2.0, hf.y))
    beyond = np.broadcast_to(hf.x > 2.0, hf.z.shape)
    assert np.abs(hf.z[beyond] - ball(r)[beyond]).max() < 1e-6


def test_arc_groove_depth_along_centreline() -> None:
    # A quarter circle of radius 5 about the origin, counter-clockwise.
    g = one_path([[5.0, 0.0], [0.0, 5.0]], [math.tan(math.pi / 8), 0.0])
    res = 0.02
    hf = cut_surface(g, TOOL, TOOL.depth, resolution=res)
    a = np.linspace(0.05, 0.5 * math.pi - 0.05, 200)
    line = 5.0 * np.stack([np.cos(a), np.sin(a)], axis=1)
    z, normal = hf.surface(line)
    assert np.allclose(z, -TOOL.depth, atol=1e-9)
    assert np.allclose(normal[:, 2], 1.0, atol=1e-9)
    # Samples next to the centreline lie at most a sample's half diagonal off it.
    ij = np.rint((line - hf.origin) / res).astype(int)
    sampled = hf.z[ij[:, 1], ij[:, 0]]
    assert np.all(sampled >= -TOOL.depth - 1e-6)
    assert np.all(sampled <= ball(np.array([res * math.sqrt(0.5)]))[0] + 1e-6)


def test_deepest_cut_labels_crossings_and_dots() -> None:
    g = Grooves(np.array([[-1.0, 0.0], [1.0, 0.0], [0.0, -1.0], [0.0, 1.0], [0.6, 0.5]]),
                np.zeros(5), np.array([0, 2, 4, 5]), np.array([3, 5, 9]))
    deep = Tool(0.25, 0.12)
    hf = cut_surface(g, deep, deep.depth, resolution=0.01)
    assert hf.z.dtype == np.float32 and hf.labels.dtype == np.int32
    assert set(np.unique(hf.labels)) == {-1, 0, 1, 2}
    # Dot: a spherical dimple about its point.
    xy = np.stack(np.meshgrid(hf.x, hf.y), axis=-1)
    r = np.linalg.norm(xy - [0.6, 0.5], axis=-1)
    near = r < 0.1
    assert np.all(hf.labels[near] == 2)
    assert np.abs(hf.z[near] - ball(r[near], deep)).max() < 1e-6
    # Each sample holds the lower of the two crossing grooves.
    on_x = np.abs(xy[..., 0]) < 0.3
    both = np.minimum(ball(np.abs(xy[..., 1]), deep), ball(np.abs(xy[..., 0]), deep))
    assert np.abs(hf.z[on_x & (np.abs(xy[..., 1]) < 0.3)]
                  - both[on_x & (np.abs(xy[..., 1]) < 0.3)]).max() < 1e-6
    first = ball(np.abs(xy[..., 1]), deep) < ball(np.abs(xy[..., 0]), deep) - 1e-6
    assert np.all(hf.labels[first & on_x] == 0)


def test_profiles_other_than_a_ball() -> None:
    vbit = ToolProfile.vbit(math.radians(90.0), tip_flat=0.04, reach=0.5)
    # (a Hermite table rounds the tip flat's edge over one table step)
    assert vbit(np.array([0.0, 0.02, 0.12])) == pytest.approx([0.0, 0.0, 0.1], abs=1e-5)
    g = one_path([[-1.0, 0.0], [1.0, 0.0]], [0.0, 0.0])
    hf = cut_surface(g, vbit, 0.1, resolution=0.01)
    col = hf.z[:, np.argmin(np.abs(hf.x))]
    expect = np.minimum(np.maximum(np.abs(hf.y) - 0.02, 0.0) - 0.1, 0.0)
    assert np.abs(col - expect).max() < 1e-5
    # A callable, a measured table and a ball all describe the same tool.
    R = TOOL.radius
    for profile in (as_profile(lambda r: R - np.sqrt(np.maximum(R * R - r * r, 0.0)), TOOL.depth),
                    ToolProfile.from_samples(np.linspace(0, 0.24, 400),
                                             R - np.sqrt(R * R - np.linspace(0, 0.24, 400) ** 2)),
                    as_profile(TOOL, TOOL.depth)):
        assert profile.cut_radius(TOOL.depth) == pytest.approx(0.5 * TOOL.width, abs=1e-6)
        r = np.linspace(0, 0.2, 9)
        assert profile(r) == pytest.approx(R - np.sqrt(R * R - r * r), abs=1e-6)


def test_cutters_give_their_profiles() -> None:
    tools = pytest.importorskip("specholo.optics.cutters")
    for cutter in (tools.BallEnd(0.25), tools.RoundCone(), tools.VBit(math.radians(60.0), 0.02),
                   tools.Laser(0.1)):
        profile = as_profile(cutter, 0.08)
        r = np.linspace(0.0, profile.cut_radius(0.08), 7)
        expect = cutter.height(r, 0.08) if isinstance(cutter, tools.Laser) else cutter.height(r)
        assert profile(r) == pytest.approx(expect, abs=1e-9)


def test_bad_input_names_the_value() -> None:
    g = one_path([[0.0, 0.0], [1.0, 0.0]], [0.0, 0.0])
    with pytest.raises(SpecholoError, match="resolution"):
        cut_surface(g, TOOL, 0.08, resolution=0.0)
    with pytest.raises(SpecholoError, match="depth"):
        cut_surface(g, TOOL, -1.0)
    with pytest.raises(SpecholoError, match="bounds"):
        cut_surface(g, TOOL, 0.08, bounds=np.array([[1.0, 0.0], [0.0, 1.0]]))
    with pytest.raises(SpecholoError, match="too large"):
        cut_surface(g, TOOL, 0.08, bounds=np.array([[-1e3, -1e3], [1e3, 1e3]]),
                    resolution=1e-3)
    with pytest.raises(SpecholoError, match="profile"):
        ToolProfile.from_samples(np.array([0.0, 1.0, 0.5]), np.array([0.0, 1.0, 2.0]))


def _glinting_arc() -> tuple[Grooves, np.ndarray]:
    """A gently curved groove along x (radius 40 mm) that glints for an eye in front."""
    sweep = 1.0 / 40.0
    g = one_path([[-0.5, 0.0], [0.5, 0.0]], [math.tan(sweep / 4), 0.0])
    return g, np.array([3.0, 0.0, 600.0])


def test_glint_matches_ideal_groove_and_reflects_into_the_eye() -> None:
    g, eye = _glinting_arc()
    res = 0.005
    hf = cut_surface(g, TOOL, TOOL.depth, resolution=res)
    found = find_cut_glints(CutCells.build(hf), eye, SUN)
    ideal = find_glints(Engraved.from_grooves(g, TOOL), eye, SUN)
    assert len(ideal.path) == 1
    assert len(found.glints.path) == 1 and not found.cap[0]
    point = found.glints.point[0]
    assert np.linalg.norm(point - ideal.point[0]) < 1e-4
    assert found.coverage[0] == pytest.approx(1.0, abs=0.02)
    # Forward: the light reflected by the height field's own normal (central
    # differences, interpolated to the glint) reaches the eye.
    gy, gx = np.gradient(hf.z.astype(float), res)
    f = (point[:2] - hf.origin) / res
    i, j = np.floor(f).astype(int)
    u, v = f - [i, j]

    def interp(a: np.ndarray) -> float:
        return float((1 - u) * (1 - v) * a[j, i] + u * (1 - v) * a[j, i + 1]
                     + (1 - u) * v * a[j + 1, i] + u * v * a[j + 1, i + 1])

    for normal in (np.array([-interp(gx), -interp(gy), 1.0]), hf.surface(point[:2])[1][0]):
        n = normal / np.linalg.norm(normal)
        light = SUN.direction
        out = 2.0 * np.dot(n, light) * n - light
        to_eye = (eye - point) / np.linalg.norm(eye - point)
        angle = math.degrees(math.acos(min(1.0, float(np.dot(out, to_eye)))))
        assert angle < 0.1, angle


def test_caps_are_faint_and_kept_apart() -> None:
    g, eye = _glinting_arc()
    hf = cut_surface(g, TOOL, TOOL.depth, resolution=0.01)
    cells = CutCells.build(hf)
    found = find_cut_glints(cells, eye, SUN, caps=True)
    assert found.cap.sum() >= 1 and (~found.cap).sum() == 1
    assert found.brightness[found.cap].max() < 0.05 * found.brightness[~found.cap].min()
    assert len(found.designed().path) == 1
    assert len(find_cut_glints(cells, eye, SUN).glints.path) == 1


def test_overcut_wall_does_not_glint() -> None:
    g, eye = _glinting_arc()
    ideal = find_glints(Engraved.from_grooves(g, TOOL), eye, SUN).point[0]
    # A deeper groove of another path across the glint removes that wall.
    cross = Grooves(np.array([[ideal[0], -1.0], [ideal[0], 1.0]]), np.zeros(2),
                    np.array([0, 2]), np.array([8]))
    both = Grooves.concatenate([g, cross])
    hf = cut_surface(both, TOOL, TOOL.depth, resolution=0.01)
    found = find_cut_glints(CutCells.build(hf), eye, SUN)
    assert 0 not in found.glints.path


# A 0.025 mm tip at 0.01 mm: the groove spans a few samples (as 0.02 mm did for 0.05 mm).
@pytest.mark.parametrize("resolution", [0.01])
def test_cut_verification_agrees_with_ideal_grooves(small_design: Path,
                                                    resolution: float) -> None:
    from specholo.jobs.flat.folder import load_design

    loaded = load_design(small_design, from_gcode=True)
    setup = loaded.config.setup()
    az = np.radians([-40.0, 0.0, 40.0])
    hf = cut_design(loaded, resolution=resolution)
    assert hf.depth == loaded.config.depth
    cut = verify_cut(hf, loaded.points, setup, azimuths=az)
    ideal = verify(loaded.grooves, loaded.points, setup, azimuths=az)
    for row, c, i in zip(agreement(ideal, cut), cut, ideal, strict=True):
        assert c.stipples_seen == i.stipples_seen
        assert abs(row["p95_error"]) < 0.1, row
        assert abs(row["median_error"]) < 0.1, row
        # Other grooves cut some walls away; the cut plate never shows more.
        assert c.visibility <= i.visibility + 0.02
        assert c.visibility > 0.5 * i.visibility


def test_stl_is_a_watertight_plate(tmp_path: Path) -> None:
    g, _ = _glinting_arc()
    plate = np.array([[-2.0, -1.0], [2.0, 1.5]])
    hf = cut_surface(g, TOOL, TOOL.depth, bounds=plate, resolution=0.01)
    out = tmp_path / "plate.stl"
    mesh = write_stl(out, hf, thickness=3.0)
    assert mesh.is_watertight and mesh.is_winding_consistent
    back = trimesh.load(out)
    assert back.is_watertight
    assert np.allclose(back.bounds, [[-2.0, -1.0, -3.0], [2.0, 1.5, 0.0]], atol=1e-6)
    removed = 4.0 * 2.5 * 3.0 - back.volume
    assert 0.0 < removed < 1.1 * 0.0202 * 1.0 + 0.01  # groove cross-section x length + caps
    # A decimated crop keeps its bounds.
    small = write_stl(tmp_path / "crop.stl", hf, 3.0, region=np.array([[-1, -0.5], [1, 0.5]]),
                      max_faces=2000)
    assert small.is_watertight and len(small.faces) <= 2000 + 4 * 60
    assert np.allclose(small.bounds, [[-1.0, -0.5, -3.0], [1.0, 0.5, 0.0]], atol=1e-6)
    with pytest.raises(SpecholoError, match="thickness"):
        write_stl(tmp_path / "thin.stl", hf, thickness=0.05)
    assert not (tmp_path / "thin.stl").exists()


def test_gcode_round_trip_cuts_the_same_plate(tmp_path: Path) -> None:
    from specholo.fabrication.programs.gcode import write_gcode
    from specholo.fabrication.programs.gcode_reader import read_gcode
    from specholo.setup import Machining

    g = Grooves(np.array([[0.0, 0.0], [1.0, 0.2], [2.0, 0.1], [0.5, 1.0], [1.5, 1.2]]),
                np.array([0.05, -0.02, 0.0, 0.3, 0.0]), np.array([0, 3, 5]),
                np.array([1, 2]))
    write_gcode(tmp_path / "g.ngc", g, TOOL, Machining())
    back = read_gcode(tmp_path / "g.ngc")
    bounds = np.array([[-0.5, -0.5], [2.5, 1.7]])
    a = cut_surface(g, TOOL, TOOL.depth, bounds=bounds, resolution=0.01)
    b = cut_surface(back, TOOL, TOOL.depth, bounds=bounds, resolution=0.01)
    assert np.abs(a.z - b.z).max() < 1e-4
    assert np.array_equal(a.labels, b.labels)


def test_verify_cut_covers_the_view_range() -> None:
    g, _ = _glinting_arc()
    hf = cut_surface(g, TOOL, TOOL.depth, resolution=0.01)
    setup = Setup(light=SUN, viewer=Viewer(half_range=math.radians(10.0)), tool=TOOL)
    reports = verify_cut(hf, np.array([[0.0, 0.0, -40.0]]), setup)
    assert len(reports) == 5 and all(r.stipples_seen == 1 for r in reports)


def test_cut_in_chunks_is_the_same_plate(small_design: Path,
                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """A program cut a run of paths at a time: the same field, labels, walls and glints."""
    import specholo.simulation.cut as cut_module
    from specholo.jobs.flat.folder import load_design

    loaded = load_design(small_design)
    grooves, setup = loaded.grooves, loaded.config.setup()
    whole = cut_surface(grooves, setup.tool, setup.tool.depth, resolution=0.02)
    monkeypatch.setattr(cut_module, "CHUNK_VERTICES", max(len(grooves.vertices) // 7, 2))
    monkeypatch.setattr(cut_module, "CHUNK_FROM", 0)
    parts = cut_surface(grooves, setup.tool, setup.tool.depth, resolution=0.02)
    # Seven chunks; only moves that cut some sample deepest are kept (stripes
    # placed out of each other's way may leave no move wholly cut over).
    assert len(parts.program) <= len(whole.program)
    assert np.array_equal(parts.z, whole.z)
    assert np.array_equal(parts.labels, whole.labels)
    cut = whole.moves >= 0
    assert np.array_equal(parts.moves >= 0, cut)
    assert np.array_equal(parts.program.geo[parts.moves[cut]], whole.program.geo[whole.moves[cut]])
    rng = np.random.default_rng(5)
    lo, hi = whole.bounds
    xy = rng.uniform(lo, hi, size=(2000, 2))
    for a, b in zip(parts.surface(xy), whole.surface(xy), strict=True):
        assert np.array_equal(a, b)
    eye = np.array([300.0, setup.viewer.height, setup.viewer.eye_radius])
    ga = find_cut_glints(parts, eye, setup.light).glints
    gb = find_cut_glints(whole, eye, setup.light).glints
    assert len(gb.path) > 0
    assert np.array_equal(ga.path, gb.path) and np.array_equal(ga.point, gb.point)


def test_default_bounds_hold_arcs_bulging_past_their_ends() -> None:
    """A semicircle's far side, 1 mm beyond its ends' box, is cut into the field."""
    g = one_path([[-1.0, 0.0], [1.0, 0.0]], [1.0, 0.0])  # counter-clockwise: through y = -1
    hf = cut_surface(g, TOOL, TOOL.depth, resolution=0.01)
    z, _ = hf.surface(np.array([[0.0, -1.0], [0.0, 1.0]]))
    assert z[0] == pytest.approx(-TOOL.depth, abs=1e-6)
    assert z[1] == 0.0  # the near side of the chord is not cut
