"""Which glints survive the cuts: constructed crossings against the tools' exact
geometry, every tool against its own height profile, and the plate as the
height-field simulation cuts it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from specholo.errors import SpecholoError
from specholo.optics.cutters import BallEnd, Laser, RoundCone, VBit
from specholo.setup import Light, Setup, Tool
from specholo.simulation.cut import cut_surface, verify_cut
from specholo.simulation.glints import Engraved, find_glints
from specholo.simulation.survival import (
    EPS,
    on_real_wall,
    removal_radius,
    survivors,
    verify_as_cut,
)
from specholo.toolpaths.grooves import Grooves

BALL = BallEnd(0.25)
DEPTH = 0.08
CENTRE_Z = BALL.radius - DEPTH  # height of the ball centres above the plate


def grooves(*paths: tuple[list[list[float]], list[float]],
            stipples: list[int] | None = None) -> Grooves:
    """Grooves of the given (vertices, bulges) paths, stipple i for path i unless given."""
    vertices = np.array([v for p in paths for v in p[0]], dtype=float).reshape(-1, 2)
    bulges = np.array([b for p in paths for b in p[1]], dtype=float)
    offsets = np.concatenate([[0], np.cumsum([len(p[0]) for p in paths])]).astype(np.int64)
    ids = np.arange(len(paths)) if stipples is None else np.array(stipples)
    return Grooves(vertices, bulges, offsets, ids.astype(np.int64))


def wall_point(tilt: float, side: float = 1.0) -> np.ndarray:
    """The point of the wall of a ball groove along the x axis whose normal is
    tilted ``tilt`` toward -y (side 1, on the +y wall) or +y (side -1)."""
    R = BALL.radius
    return np.array([0.0, side * R * math.sin(tilt), CENTRE_Z - R * math.cos(tilt)])


def line(through: np.ndarray, angle: float, half: float = 5.0) -> tuple[list[list[float]],
                                                                       list[float]]:
    d = np.array([math.cos(angle), math.sin(angle)])
    return [list(through - half * d), list(through + half * d)], [0.0, 0.0]


GROOVE_A = ([[-5.0, 0.0], [5.0, 0.0]], [0.0, 0.0])


@pytest.mark.parametrize("angle_deg", [90.0, 30.0, 1.0])
@pytest.mark.parametrize("tilt_deg", [5.0, 20.0, 35.0])
def test_a_crossing_ball_removes_the_glint_within_its_radius(angle_deg: float,
                                                             tilt_deg: float) -> None:
    """A glint on A's wall is gone when B's ball centres pass within R of it in 3D."""
    p = wall_point(math.radians(tilt_deg))
    a = math.radians(angle_deg)
    normal = np.array([-math.sin(a), math.cos(a)])  # B's plan normal, away from A's axis
    if normal[1] < 0:
        normal = -normal
    for distance, kept in ((BALL.radius - 1e-4, False), (BALL.radius + 1e-4, True)):
        plan = math.sqrt(distance**2 - (p[2] - CENTRE_Z) ** 2)
        b = line(p[:2] + plan * normal, a)
        got = survivors(grooves(GROOVE_A, b), p[None], np.array([0]), BALL, DEPTH)
        assert got[0] == kept, (distance, plan)


@pytest.mark.parametrize("separation", [0.05, 0.2, 0.3, 0.4, 0.45, 0.6])
def test_parallel_grooves_remove_the_near_wall_only(separation: float) -> None:
    """B alongside A, `separation` apart: the glints of A's wall facing B are gone
    exactly where B's ball reaches them; the far wall keeps all of its own."""
    R = BALL.radius
    tilts = np.radians(np.linspace(0.5, 36.0, 80))
    pts = np.concatenate([np.stack([wall_point(t, side) for t in tilts])
                          for side in (1.0, -1.0)])
    b = ([[-5.0, separation], [5.0, separation]], [0.0, 0.0])
    got = survivors(grooves(GROOVE_A, b), pts, np.zeros(len(pts), np.int64), BALL, DEPTH)
    dist = np.hypot(pts[:, 1] - separation, pts[:, 2] - CENTRE_Z)  # to B's line of centres
    clear = np.abs(dist - R) > 1e-9
    assert clear.sum() > 150
    assert np.array_equal(got[clear], (dist >= R)[clear])
    far = pts[:, 1] < 0
    if separation >= 2 * R * math.sin(math.radians(36.0)):
        assert got[far].all()  # the far wall is out of B's reach


@pytest.mark.parametrize("cutter", [BALL, RoundCone(0.025), VBit(math.radians(60.0), 0.01)])
def test_a_crossing_cut_shallower_than_the_glint_leaves_it(cutter: object) -> None:
    """B runs straight through a glint on A's wall. The glint sits at some depth
    below the surface; B cut shallower than that passes over it, B cut deeper
    takes it, and as deep as A it takes it as one depth does."""
    R = BALL.radius
    p = wall_point(math.radians(25.0))  # on a 0.25 mm ball's wall, DEPTH deep
    b = line(p[:2], math.radians(60.0))
    g = grooves(GROOVE_A, b)
    below = -p[2]  # the glint's depth under the surface
    assert 0.0 < below < DEPTH and R > 0
    for depth_b, kept in ((below - 1e-4, True), (below + 1e-4, False), (DEPTH, False)):
        got = survivors(g, p[None], np.array([0]), cutter, np.array([DEPTH, depth_b]))
        assert got[0] == kept, depth_b
    same = survivors(g, p[None], np.array([0]), cutter, DEPTH)
    assert np.array_equal(same, survivors(g, p[None], np.array([0]), cutter,
                                          np.array([DEPTH, DEPTH])))


def test_path_depths_move_each_glint_with_its_groove_and_drop_those_above_the_plate() -> None:
    """A design cut with every path at the design's depth gives the figures of
    one depth; a groove cut too shallow for a wall's tilt loses that glint."""
    from specholo.jobs.flat.folder import DesignConfig, design

    d = design("examples/bunny.obj", DesignConfig(size=20.0, center_z=-15.0, stipples=200,
                                                  seed=3), check_overlaps=False,
               expect_as_cut=False)
    setup, cutter, depth = d.config.setup(), d.config.cutter(), d.config.depth_mm
    az = np.radians([-30.0, 0.0, 30.0])
    n = d.grooves.n_paths
    one = verify_as_cut(d.grooves, d.points, setup, cutter, depth, azimuths=az)
    each = verify_as_cut(d.grooves, d.points, setup, cutter, depth, azimuths=az,
                         path_depths=np.full(n, depth))
    assert np.array_equal(one.surviving, each.surviving)
    # 0.5 um deep: a wall tilted more than 11 degrees would stand above the plate
    flat = verify_as_cut(d.grooves, d.points, setup, cutter, depth, azimuths=az,
                         path_depths=np.full(n, 0.0005))
    assert flat.surviving.sum() == 0 and one.surviving.sum() > 0
    with pytest.raises(SpecholoError, match="path depths"):
        verify_as_cut(d.grooves, d.points, setup, cutter, depth, azimuths=az,
                      path_depths=np.full(n + 1, depth))


def test_arcs_remove_what_their_ball_reaches_along_them_and_at_their_ends() -> None:
    """B a quarter circle of radius 3 about (0, 3): its ball centres lie on that
    circle, a plunge at each end; a point at 3D distance R -+ 1e-4 from them is
    removed or kept, inside the sweep or beside an end."""
    R = BALL.radius
    p = wall_point(math.radians(25.0))
    dz = p[2] - CENTRE_Z
    centre = np.array([0.0, 3.0])
    for distance, kept in ((R - 1e-4, False), (R + 1e-4, True)):
        plan = math.sqrt(distance**2 - dz**2)
        # p on B's circle's outside, in the middle of the arc's angles
        for phi, rho in ((-0.3, 3.0), (-0.5, 3.0)):
            c = p[:2] - (rho + plan) * np.array([math.cos(phi), math.sin(phi)])
            ends = c + rho * np.array([[math.cos(phi - 0.6), math.sin(phi - 0.6)],
                                       [math.cos(phi + 0.6), math.sin(phi + 0.6)]])
            b = ([list(ends[0]), list(ends[1])], [math.tan(1.2 / 4.0), 0.0])
            got = survivors(grooves(GROOVE_A, b), p[None], np.array([0]), BALL, DEPTH)
            assert got[0] == kept
        # beyond B's end: only its end's ball can reach p
        end = p[:2] + np.array([0.0, plan])
        start = end + np.array([-3.0, 3.0])  # B arrives from the upper left, bulging away
        b = ([list(start), list(end)], [-0.3, 0.0])
        got = survivors(grooves(GROOVE_A, b), p[None], np.array([0]), BALL, DEPTH)
        assert got[0] == kept
    del centre


def test_a_path_does_not_remove_its_own_glints_but_the_same_stipple_does() -> None:
    p = wall_point(math.radians(20.0))
    across = line(np.array([0.0, 0.0]), 0.5 * math.pi)
    own = survivors(grooves(GROOVE_A), p[None], np.array([0]), BALL, DEPTH)
    assert own[0]
    # another path of the same stipple crossing at p
    same = survivors(grooves(GROOVE_A, across, stipples=[3, 3]), p[None], np.array([0]), BALL,
                     DEPTH)
    assert not same[0]
    # a second path retracing A exactly cuts nothing more of its walls
    retrace = survivors(grooves(GROOVE_A, GROOVE_A), p[None], np.array([0]), BALL, DEPTH)
    assert retrace[0]


def test_a_dimple_removes_within_its_ball() -> None:
    R = BALL.radius
    p = wall_point(math.radians(30.0))
    plan = math.sqrt((R - 1e-4) ** 2 - (p[2] - CENTRE_Z) ** 2)
    for reach, kept in ((plan, False), (math.sqrt((R + 1e-4) ** 2 - (p[2] - CENTRE_Z) ** 2),
                                        True)):
        dot = ([list(p[:2] + np.array([reach, 0.0]))], [0.0])
        assert survivors(grooves(GROOVE_A, dot), p[None], np.array([0]), BALL, DEPTH)[0] == kept


def _arc_points(start: np.ndarray, end: np.ndarray, bulge: float, n: int) -> np.ndarray:
    """n points (n, 2) along an arc given by its ends and bulge, through its centre."""
    sweep = 4.0 * math.atan(bulge)
    chord = end - start
    length = float(np.hypot(*chord))
    if abs(bulge) < 1e-12:
        return start + np.linspace(0.0, 1.0, n)[:, None] * chord
    k = (1.0 - bulge * bulge) / (4.0 * bulge)
    centre = 0.5 * (start + end) + k * np.array([-chord[1], chord[0]])
    radius = length * (1.0 + bulge * bulge) / (4.0 * abs(bulge))
    a0 = math.atan2(*(start - centre)[::-1])
    a = a0 + np.linspace(0.0, sweep, n)
    return centre + radius * np.stack([np.cos(a), np.sin(a)], axis=1)


def _exact_distance(p: np.ndarray, start: np.ndarray, end: np.ndarray, bulge: float) -> float:
    """Distance from p (2,) to an arc, by its centre and angles (independent of the module's)."""
    if abs(bulge) < 1e-12:
        d = end - start
        t = np.clip(np.dot(p - start, d) / np.dot(d, d), 0.0, 1.0)
        return float(np.hypot(*(p - start - t * d)))
    chord = end - start
    k = (1.0 - bulge * bulge) / (4.0 * bulge)
    centre = 0.5 * (start + end) + k * np.array([-chord[1], chord[0]])
    radius = float(np.hypot(*chord)) * (1.0 + bulge * bulge) / (4.0 * abs(bulge))
    sweep = 4.0 * math.atan(bulge)
    a0 = math.atan2(*(start - centre)[::-1])
    a = math.atan2(*(p - centre)[::-1])
    rel = (a - a0) % (2 * math.pi) if sweep > 0 else (a0 - a) % (2 * math.pi)
    if rel <= abs(sweep):
        return abs(float(np.hypot(*(p - centre))) - radius)
    return float(min(np.hypot(*(p - start)), np.hypot(*(p - end))))


def _random_design(rng: np.random.Generator, paths: int) -> Grooves:
    """Paths of 1-4 arcs (some long, turning up to 300 degrees) and dots in a 4 mm square."""
    parts = []
    for _ in range(paths):
        n = int(rng.integers(1, 5))
        if rng.random() < 0.1:
            n = 1
        v = np.cumsum(rng.normal(0.0, 0.6 if rng.random() < 0.8 else 3.0, (n, 2)), axis=0)
        v += rng.uniform(-2.0, 2.0, 2)
        b = rng.normal(0.0, 0.3, n)
        if rng.random() < 0.1:
            b = np.tan(rng.uniform(-1.0, 1.0, n) * 5.2 / 4.0)  # up to 300 degrees
        b[-1] = 0.0
        parts.append((v.tolist(), b.tolist()))
    return grooves(*parts)


@pytest.mark.parametrize("cutter,depth", [
    (BallEnd(0.25), 0.08), (RoundCone(0.05), 0.03), (VBit(math.radians(60.0), 0.02), 0.05),
    (Laser(0.1), 0.02)])
def test_every_tool_removes_exactly_what_its_profile_holds(cutter: object,
                                                          depth: float) -> None:
    """Random paths and wall points: a point is gone iff some other path passes
    where the tool's own height profile, tip at -depth, rises above it."""
    rng = np.random.default_rng(5)
    g = _random_design(rng, 60)
    m = 600
    pts = np.column_stack([rng.uniform(-3.0, 3.0, (m, 2)), rng.uniform(-depth, 0.0, m)])
    own = rng.integers(0, g.n_paths, m)
    got = survivors(g, pts, own, cutter, depth)
    height = (lambda r: cutter.height(r, depth=depth)) if isinstance(cutter, Laser) else \
        cutter.height  # type: ignore[attr-defined]
    # The distance from each point to each other path, exactly.
    best = np.full(m, np.inf)
    for q in range(g.n_paths):
        a, b = g.offsets[q], g.offsets[q + 1]
        for i in range(m):
            if own[i] == q:
                continue
            if b - a == 1:
                best[i] = min(best[i], float(np.hypot(*(pts[i, :2] - g.vertices[a]))))
            for j in range(a, b - 1):
                best[i] = min(best[i], _exact_distance(pts[i, :2], g.vertices[j],
                                                       g.vertices[j + 1], g.bulges[j]))
    above = pts[:, 2] - (-depth + np.asarray(height(best)))
    clear = np.abs(above - EPS) > 1e-7
    assert clear.mean() > 0.95
    assert 0.05 < (above > EPS)[clear].mean() < 0.95  # both outcomes are tested
    assert np.array_equal(got[clear], (above <= EPS)[clear])


def test_the_grid_finds_every_long_arc_far_from_its_ends() -> None:
    """A single long arc (a 40 mm circle's half) removes points along its whole
    length, not only near its ends or middle."""
    R = BALL.radius
    g = grooves(([[20.0, 0.0], [-20.0, 0.0]], [1.0, 0.0]), GROOVE_A)
    angles = np.linspace(0.05, math.pi - 0.05, 50)
    p = wall_point(math.radians(10.0))
    dz = p[2] - CENTRE_Z
    inside = math.sqrt((R - 1e-4) ** 2 - dz * dz)
    outside = math.sqrt((R + 1e-4) ** 2 - dz * dz)
    for plan, kept in ((inside, False), (outside, True)):
        xy = (20.0 + plan) * np.stack([np.cos(angles), np.sin(angles)], axis=1)
        pts = np.column_stack([xy, np.full(len(xy), p[2])])
        got = survivors(g, pts, np.ones(len(pts), np.int64), BALL, DEPTH)
        assert np.all(got == kept)


def test_removal_radius_is_where_each_profile_reaches_the_point() -> None:
    for cutter, depth in ((BallEnd(0.25), 0.08), (RoundCone(0.05), 0.03),
                          (VBit(math.radians(60.0), 0.02), 0.05), (Laser(0.1), 0.02)):
        lift = np.linspace(0.001, depth, 40)
        r = removal_radius(cutter, depth, lift)
        h = cutter.height(r, depth=depth) if isinstance(cutter, Laser) else cutter.height(r)
        assert np.allclose(h, lift - EPS, atol=1e-9)
    # the ball model of a design removes as the ball it models
    lift = np.linspace(0.0, 0.012, 9)
    assert np.array_equal(removal_radius(Tool(0.05, 0.012), 0.012, lift),
                          removal_radius(BallEnd(0.05), 0.012, lift))
    # no cut at the same depth removes the bottom of a groove
    assert removal_radius(BALL, DEPTH, np.array([0.0]))[0] == 0.0


def test_glints_move_onto_a_v_bits_flank() -> None:
    """Glints found on the V-bit's round model sit on the real flank, where its
    surface is, halfway up."""
    cutter = VBit(math.radians(60.0))
    depth = 0.05
    model = cutter.model(depth)
    light = Light(math.radians(45.0))
    g = grooves(([[-5.0, 0.0], [5.0, 0.0]], [0.02, 0.0]))
    eye = np.array([0.0, 0.0, 600.0])
    found = find_glints(Engraved.from_grooves(g, model), eye, light)
    assert len(found.path)
    moved = on_real_wall(found, model, cutter, depth, light, eye)
    rim = depth * math.tan(0.5 * cutter.angle)
    dist = np.array([_exact_distance(q[:2], g.vertices[0], g.vertices[1], g.bulges[0])
                     for q in moved])
    assert np.allclose(dist, 0.5 * rim, rtol=1e-3)
    assert np.allclose(moved[:, 2], -depth + cutter.height(dist), atol=1e-9)


def test_survival_agrees_with_the_height_field_cut() -> None:
    """On a small random design dense enough to lose many glints (the paper's
    long hyperbolae on a 20 mm bunny), the stereo visibility of the glints that
    survive matches the simulated cut plate's at 5 um resolution within two
    points per view, and so do the errors."""
    from specholo.jobs.flat.folder import DesignConfig, design
    from specholo.visibility.occlusion import Intervals

    # A 0.05 mm tip: 5 um is a tenth of its radius.
    d = design("examples/bunny.obj", DesignConfig(size=20.0, center_z=-15.0, stipples=400,
                                                  seed=3, method="hyperbola", tool_radius=0.05),
               check_overlaps=False, expect_as_cut=False)
    setup: Setup = d.config.setup()
    seen_from = Intervals(d.runs.stipple, d.runs.start, d.runs.end)

    def vis(p: np.ndarray, eyes: np.ndarray) -> np.ndarray:
        return seen_from.contains(np.arange(len(p)), np.arctan2(eyes[:, 0], eyes[:, 2]))

    az = np.radians([-30.0, 0.0, 30.0])
    cutter = d.config.cutter()
    ideal = verify_as_cut(d.grooves, d.points, setup, cutter, d.config.depth_mm, vis, az)
    field = cut_surface(d.grooves, cutter, d.config.depth_mm, resolution=0.005)
    cut = verify_cut(field, d.points, setup, vis, azimuths=az)
    for a, b in zip(ideal.reports, cut, strict=True):
        assert a.visibility < 0.8  # the cuts do remove glints here
        assert abs(a.visibility - b.visibility) <= 0.02, (a, b)
        assert abs(a.p95_error - b.p95_error) < 0.01
    assert np.all(ideal.surviving < ideal.glints)


def test_cutting_every_groove_deeper_removes_no_more_glints() -> None:
    """A glint tilted a on a round tip sits R (1 - cos a) above the tip, so a cut
    of the same depth removes it only within R sin a of its own centreline,
    however deep both are: a plate cut deeper throughout (three times the
    design's depth, far into the cone's flanks) keeps exactly the same
    glints, and the finer tip keeps more of them."""
    from specholo.jobs.flat.folder import DesignConfig, design

    az = np.radians([-30.0, 0.0, 30.0])
    kept = {}
    for radius in (0.025, 0.05):
        d = design("examples/bunny.obj", DesignConfig(size=20.0, center_z=-15.0, stipples=300,
                                                      seed=3, tool_radius=radius),
                   check_overlaps=False, expect_as_cut=False)
        setup, cutter, depth = d.config.setup(), d.config.cutter(), d.config.depth_mm
        shallow = verify_as_cut(d.grooves, d.points, setup, cutter, depth, azimuths=az)
        deep = verify_as_cut(d.grooves, d.points, setup, cutter, 3.0 * depth, azimuths=az)
        assert shallow.surviving.sum() < shallow.glints.sum()  # crossings remove glints here
        assert np.array_equal(shallow.surviving, deep.surviving)
        kept[radius] = shallow.surviving.sum() / shallow.glints.sum()
    assert kept[0.025] > kept[0.05]


def test_design_states_and_verify_checks_what_survives(tmp_path, capsys) -> None:
    """The design prints and records the stereo visibility it expects as cut;
    ``verify --cut`` finds it again on the G-code's grooves by default, never
    above the ideal grooves', and the height field stays one option away."""
    import json
    from pathlib import Path

    from specholo_cli.cli import main

    out = tmp_path / "holo"
    bunny = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"
    assert main(["design", str(bunny), "--out", str(out), "--stipples", "300",
                 "--tool", "ball"]) == 0
    said = capsys.readouterr().out
    expected = json.loads((out / "hologram.json").read_text())["expected"][
        "as_cut_stereo_visibility"]
    rows = expected["per_azimuth"]
    assert [r["azimuth_deg"] for r in rows] == pytest.approx(np.arange(-45.0, 46.0, 5.0))
    vis = np.array([r["visibility"] for r in rows])
    assert expected["mean"] == pytest.approx(vis.mean())
    assert expected["lowest"] == pytest.approx(vis.min()) and vis.max() < 0.9
    assert all(r["surviving"][s] < r["glints"][s] for r in rows for s in (0, 1))
    assert f"as cut, about {expected['mean']:.0%} of the stipples show in both eyes" in said

    assert main(["verify", str(out), "--cut"]) == 0
    capsys.readouterr()
    cut = json.loads((out / "verify_cut.json").read_text())
    ideal = json.loads((out / "verify.json").read_text())
    assert cut["cut_method"] == "survival" and cut["resolution_mm"] is None
    got = np.array([r["visibility"] for r in cut["azimuths"]])
    assert np.all(got <= np.array([r["visibility"] for r in ideal["azimuths"]]))
    assert np.abs(got - vis).max() < 0.05  # the G-code's grooves, rounded to 10 nm

    assert main(["verify", str(out), "--cut", "--resolution", "0.05"]) == 0
    capsys.readouterr()
    field = json.loads((out / "verify_cut.json").read_text())
    assert field["cut_method"] == "field" and field["resolution_mm"] == 0.05

    assert main(["verify", str(out), "--cut", "--cut-method", "survival", "--stl",
                 str(tmp_path / "plate.stl")]) != 0
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and "\n" not in err
    assert not (tmp_path / "plate.stl").exists()


def test_a_large_design_leaves_its_as_cut_figures_to_verify(tmp_path, capsys,
                                                             monkeypatch) -> None:
    """Over AS_CUT_MAX_STIPPLES the design says how to get the as-cut figures
    instead of finding them, and records why."""
    import json
    from pathlib import Path

    import specholo.jobs.flat.design as flat
    from specholo_cli.cli import main

    monkeypatch.setattr(flat, "AS_CUT_MAX_STIPPLES", 10)
    out = tmp_path / "holo"
    bunny = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"
    assert main(["design", str(bunny), "--out", str(out), "--stipples", "30"]) == 0
    said = capsys.readouterr().out
    assert "as cut: not estimated" in said and "specholo verify FOLDER --cut" in said
    expected = json.loads((out / "hologram.json").read_text())["expected"]
    assert expected["as_cut_stereo_visibility"] is None and "verify" in expected["why"]
