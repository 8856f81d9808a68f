"""Glints as streaks: a light of real size on a surface of real gloss.

Each glint spreads along its groove over the stretch where the wall's normal
stays within the lobe of h: as long as the lobe's width times the wall's
radius along the groove, as bright in all as the point glint, cut short by a
stripe's end (whose light then spills onto the end for the views past it)
and cut through, not lost, where another groove crosses it.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from specholo.errors import SpecholoError
from specholo.optics.normality import normality
from specholo.optics.spread import GLOSS, SUN, Spread
from specholo.setup import Light, Setup, Tool, Viewer
from specholo.simulation.glints import Engraved, find_glints
from specholo.simulation.streak_verify import verify_streaks
from specholo.simulation.streaks import ACUITY, false_glints, find_streaks
from specholo.simulation.survival import verify_as_cut
from specholo.toolpaths.grooves import Grooves

TOOL = Tool(0.025, 0.011)
LIGHT = Light(math.radians(45.0))
VIEWER = Viewer()
RHO = 20.0
#: the circle every test groove lies on: centre above, grooves along its bottom
CENTRE = np.array([0.0, RHO])


def _circle_arc(x0: float, x1: float, centre: np.ndarray = CENTRE, rho: float = RHO
         ) -> tuple[np.ndarray, float]:
    """Ends (2, 2) and bulge of the arc of the circle below its centre from x0 to x1."""
    a0 = math.atan2(-math.sqrt(rho**2 - x0**2), x0)
    a1 = math.atan2(-math.sqrt(rho**2 - x1**2), x1)
    ends = centre + rho * np.array([[math.cos(a0), math.sin(a0)], [math.cos(a1), math.sin(a1)]])
    return ends, math.tan((a1 - a0) / 4.0)


def _grooves(*arcs: tuple[np.ndarray, float]) -> Grooves:
    vertices = np.concatenate([a[0] for a in arcs])
    bulges = np.concatenate([[a[1], 0.0] for a in arcs])
    return Grooves(vertices, bulges, np.arange(0, 2 * len(arcs) + 1, 2),
                   np.arange(len(arcs)))


def _eye(azimuth_deg: float = 0.0) -> np.ndarray:
    return VIEWER.eye(np.radians([azimuth_deg]))[0]


def _point_glint(eye: np.ndarray) -> tuple[np.ndarray, float]:
    """Where the long test arc glints for ``eye``, and how bright (point model)."""
    gl = find_glints(Engraved.from_grooves(_grooves(_circle_arc(-6.0, 6.0)), TOOL), eye, LIGHT)
    assert gl.brightness is not None and len(gl.path) == 1
    return gl.point[0], float(gl.brightness[0])


@pytest.mark.parametrize("azimuth", [-5.0, 0.0, 4.0])
def test_a_streak_of_a_point_light_on_a_mirror_is_the_point_glint(azimuth: float) -> None:
    rng = np.random.default_rng(3)
    arcs = [_circle_arc(-8.0, 8.0, CENTRE + [x, y], RHO + r)
            for x, y, r in zip(rng.uniform(-3, 3, 12), rng.uniform(-5, 5, 12),
                               rng.uniform(-5, 30, 12), strict=True)]
    eng = Engraved.from_grooves(_grooves(*arcs), TOOL)
    eye = _eye(azimuth)
    point = find_glints(eng, eye, LIGHT)
    st = find_streaks(eng, eye, LIGHT, Spread(1e-7, 1e-7))
    gl = st.glints()
    assert point.brightness is not None and gl.brightness is not None
    assert len(point.path) >= 3 and np.array_equal(np.sort(point.path), np.sort(gl.path))
    a, b = np.argsort(point.path), np.argsort(gl.path)
    assert np.allclose(point.point[a], gl.point[b], atol=1e-5)
    # the lobe integrates to one: the streak is as bright as the point glint; the
    # point figure R rho / sin(tilt) leaves out h's own turn along the groove
    # (about 1 / (|l + v| D) against the wall's sin(tilt) / rho: up to 15% on
    # these radii of 15 to 50 mm)
    assert np.allclose(gl.brightness[b], point.brightness[a], rtol=0.15)
    assert len(st.spills().path) == 0


@pytest.mark.parametrize("alpha", [0.003, 0.01])
def test_a_streaks_length_is_the_lobe_times_the_walls_radius_along_it(alpha: float) -> None:
    eye = _eye()
    at, bright = _point_glint(eye)
    eng = Engraved.from_grooves(_grooves(_circle_arc(-6.0, 6.0)), TOOL)
    st = find_streaks(eng, eye, LIGHT, Spread(0.0, alpha))
    assert st.count == 1 and st.designed[0]
    # the wall's radius along the groove (psi turns by 1 / rho_wall per mm), from
    # the streak's whole brightness R rho_wall; the point figure is within 6%
    rho_wall = st.brightness[0] / TOOL.radius
    assert st.brightness[0] == pytest.approx(bright, rel=0.06)
    fwhm = 2.0 * math.sqrt(2.0 * math.log(2.0)) * (alpha / math.sqrt(2.0)) * rho_wall
    density = st.weight / st.length
    lit = st.length[density >= 0.5 * density.max()].sum()
    assert lit == pytest.approx(fwhm, rel=0.05)
    # a symmetric lobe keeps the streak's centre on the point glint
    assert np.linalg.norm(st.centre[0] - at) < 0.05 * fwhm


def test_a_bigger_light_makes_a_longer_streak_as_bright_in_all() -> None:
    eye = _eye(10.0)
    eng = Engraved.from_grooves(_grooves(_circle_arc(-6.0, 6.0)), TOOL)
    lengths, totals = [], []
    for size in (0.0, 0.5 * SUN, SUN, 2.0 * SUN):
        st = find_streaks(eng, eye, LIGHT, Spread(size, GLOSS["mirror"]))
        assert st.count == 1
        density = st.weight / st.length
        lengths.append(st.length[density >= 0.5 * density.max()].sum())
        totals.append(st.brightness[0])
    assert all(b > a for a, b in zip(lengths, lengths[1:], strict=False))
    assert np.allclose(totals, totals[0], rtol=0.02)


def test_a_stripe_ending_short_of_its_glint_spills_light_onto_its_end() -> None:
    eye = _eye()
    at, bright = _point_glint(eye)
    spread = Spread(SUN, GLOSS["mirror"])
    rho_wall = bright / TOOL.radius
    past = 0.03  # mm: the stripe stops this far before its glint
    # stipple 0's stripe ends short of its glint; stipple 1 glints 1 mm below
    stub = _circle_arc(at[0] - 2.0, at[0] - past)
    other = _circle_arc(-6.0, 6.0, CENTRE - [0.0, 1.0])
    eng = Engraved.from_grooves(_grooves(stub, other), TOOL)
    assert list(find_glints(eng, eye, LIGHT).stipple) == [1]  # no point glint on the stub
    st = find_streaks(eng, eye, LIGHT, spread)
    # (the stripes' end caps are spills of a point each, apart from this)
    spill = np.flatnonzero(~st.designed & (st.extent > 0))
    assert len(spill) == 1 and st.stipple[spill[0]] == 0
    # its light lies along the stripe's last tenth of a millimetre or so (the
    # lobe's tail past the end, a streak's length from it)
    end = stub[0][1]
    assert np.linalg.norm(st.centre[spill[0], :2] - end) < 0.15
    assert st.centre[spill[0], 0] < end[0]
    share = st.brightness[spill[0]] / bright
    assert 0.05 < share < 0.5
    # it is a false glint: bright, and more than 0.25 mm from the designed glint
    found = false_glints(st, st.glints().image())
    assert len(found) == 1 and np.linalg.norm(found[0, :2] - end) < 0.15
    # a stripe ending far from its glint throws no light there
    far = Engraved.from_grooves(_grooves(_circle_arc(at[0] - 2.0, at[0] - 0.05 * rho_wall), other),
                                TOOL)
    assert len(false_glints(find_streaks(far, eye, LIGHT, spread), st.glints())) == 0


def _flipped(arc: tuple[np.ndarray, float]) -> tuple[np.ndarray, float]:
    """The arc mirrored across the x axis: curved the other way about its glint."""
    ends, bulge = arc
    return ends * [1.0, -1.0], -bulge


def test_a_stripes_ends_glint_as_caps_of_its_ball_where_they_face_h() -> None:
    eye = _eye()
    spread = Spread(SUN, GLOSS["mirror"])
    # curved one way, h leans out of both ends of the stripe: no cap glints;
    # curved the other, back into the groove at both, where the ball's cap
    # offers every normal that does (the stripe's ends 0.05 mm from its glint,
    # nearer than the eye resolves: a cap farther off is never seen)
    for arc, caps in ((_circle_arc(-0.05, 0.05), 0), (_flipped(_circle_arc(-0.05, 0.05)), 2)):
        eng = Engraved.from_grooves(_grooves(arc), TOOL)
        st = find_streaks(eng, eye, LIGHT, spread)
        cap = np.flatnonzero(~st.designed & (st.extent == 0))
        assert len(cap) == caps
        for r in cap:
            g = st.point[st.run == r][0]
            ends, _ = arc
            end = ends[np.argmin(np.linalg.norm(ends - g[:2], axis=1))]
            ball = np.array([*end, TOOL.radius - TOOL.depth])
            assert np.linalg.norm(ball - g) == pytest.approx(TOOL.radius, abs=1e-9)
            h = normality(g[None], LIGHT, eye)[0]
            normal = (ball - g) / TOOL.radius
            assert np.degrees(np.arccos(min(1.0, normal @ (h / np.linalg.norm(h))))) < 1e-3
            # on the cap past the stripe's end, as bright as a dot of the ball
            assert np.linalg.norm(g[:2] - end) < np.linalg.norm(g[:2] - ends.mean(axis=0))
            assert st.brightness[r] == pytest.approx(TOOL.radius**2)


def test_a_cap_nearer_its_streak_than_the_eye_resolves_joins_its_spot() -> None:
    eye = _eye()
    spread = Spread(SUN, GLOSS["mirror"])
    reach = ACUITY * np.linalg.norm(_point_glint(eye)[0] - eye)
    for half, joined in ((0.05, True), (0.1, True), (2.0, False)):
        eng = Engraved.from_grooves(_grooves(_flipped(_circle_arc(-half, half))), TOOL)
        st = find_streaks(eng, eye, LIGHT, spread)
        assert st.designed.sum() == 1
        # the caps farther from the streak than the eye resolves never show
        assert st.count == (3 if joined else 1)
        seen = st.gather(ACUITY * np.linalg.norm(st.centre - eye, axis=1))
        assert seen.count == 1
        if joined:  # one spot, as bright as all three, at their joint centre
            assert seen.brightness[0] == pytest.approx(st.brightness.sum())
            centre = (st.brightness[:, None] * st.centre).sum(axis=0) / st.brightness.sum()
            assert np.allclose(seen.centre[0], centre, atol=1e-9)
            assert np.linalg.norm(st.centre[~st.designed] - st.centre[st.designed], axis=1).max() \
                <= reach


def test_a_cut_through_a_streak_leaves_a_gap_not_a_lost_glint() -> None:
    left, right = (e[0] for e in VIEWER.stereo(np.array([0.0])))
    at, _ = _point_glint(left)
    stripe = _circle_arc(-6.0, 6.0)
    # a straight groove across it through the left eye's point glint
    cross = (np.array([[at[0], at[1] - 1.0], [at[0], at[1] + 1.0]]), 0.0)
    grooves = _grooves(stripe, cross)
    points = np.array([[0.0, 0.0, -40.0], [at[0], at[1], 0.0]])
    setup = Setup(light=LIGHT, viewer=VIEWER, tool=TOOL)
    az = np.array([0.0])
    # the point model loses stipple 0: the cross takes the left eye's glint
    as_cut = verify_as_cut(grooves, points, setup, TOOL, TOOL.depth, azimuths=az)
    assert as_cut.surviving[0, 0] < as_cut.glints[0, 0]
    spread = Spread(SUN, GLOSS["mirror"])
    ideal = verify_streaks(grooves, points, setup, spread, azimuths=az)[0]
    cut = verify_streaks(grooves, points, setup, spread, azimuths=az,
                         cut=(TOOL, TOOL.depth))[0]
    # the streak still shows in both eyes: the gap takes only the piece it crosses
    eng = Engraved.from_grooves(grooves, TOOL)
    whole = find_streaks(eng, left, LIGHT, spread)
    mine = whole.path == 0
    assert ideal.visibility == cut.visibility
    from specholo.simulation.survival import survivors

    cells = whole.run
    keep = survivors(grooves, whole.point, whole.path[cells], TOOL, TOOL.depth)
    gapped = whole.cut(keep)
    share = gapped.brightness[mine][0] / whole.brightness[mine][0]
    assert 0.3 < share < 0.97
    # and its centre moves by less than the streak is long
    shift = np.linalg.norm(gapped.centre[mine][0] - whole.centre[mine][0])
    assert 0.0 < shift < 0.1


@pytest.mark.parametrize(("rho", "glints"), [(4.0, 1), (20.0, 2)])
def test_a_crossing_parts_a_long_streak_into_two_glints_an_eye_sees_apart(rho: float,
                                                                           glints: int) -> None:
    from specholo.simulation.streak_verify import cut_streaks, eye_streaks
    from specholo.simulation.streaks import ACUITY

    left = VIEWER.stereo(np.array([0.0]))[0][0]
    stripe = _circle_arc(-3.0, 3.0, np.array([0.0, rho]), rho)
    at = find_glints(Engraved.from_grooves(_grooves(stripe), TOOL), left, LIGHT).point[0]
    # a straight groove across the stripe through the left eye's point glint
    cross = (np.array([[at[0], at[1] - 1.0], [at[0], at[1] + 1.0]]), 0.0)
    grooves = _grooves(stripe, cross)
    setup = Setup(light=LIGHT, viewer=VIEWER, tool=TOOL)
    found = eye_streaks(grooves, 2, setup, Spread(SUN, GLOSS["mirror"]), np.array([0.0]))
    cut = cut_streaks(found, grooves, setup, TOOL, TOOL.depth)
    assert np.sum(found.streaks[0].glints().path == 0) == 1
    parts = cut.streaks[0].glints()
    mine = parts.path == 0
    # The streak is as long as the lobe times the stripe's radius, and the
    # pieces either side of the gap about half that apart: on the tighter
    # stripe nearer than the eye resolves (one spot), on the wider farther
    # (two, one each side of the crossing, sharing the streak's light).
    reach = ACUITY * float(np.linalg.norm(left - at))
    extent = found.streaks[0].extent[found.streaks[0].path == 0][0]
    assert (extent > 2.0 * reach) == (glints == 2)
    assert np.sum(mine) == glints
    if glints == 2:
        a, b = parts.point[mine]
        assert np.linalg.norm(a - b) > reach
        assert (a[0] - at[0]) * (b[0] - at[0]) < 0.0
        assert parts.brightness is not None
        total = cut.streaks[0].brightness[cut.streaks[0].path == 0].sum()
        assert math.isclose(parts.brightness[mine].sum(), total, rel_tol=1e-9)


def test_spread_options_are_checked_in_one_line() -> None:
    assert Spread.of(None, None) is None
    assert Spread.of(0.53, "mirror") == Spread(SUN, 0.003)
    assert Spread.of(None, "0.02") == Spread(0.0, 0.02)
    for bad in (("shiny",), ("-1",), ("nan",)):
        with pytest.raises(SpecholoError, match="roughness"):
            Spread.of(0.5, bad[0])
    with pytest.raises(SpecholoError, match="light size"):
        Spread.of(-0.1, None)
    with pytest.raises(SpecholoError, match="light size"):
        Spread.of(float("inf"), None)


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "specholo_cli.cli", *args], text=True,
                          capture_output=True, check=False)


def test_verify_under_the_sun_on_a_mirror_writes_streak_figures(small_design: Path,
                                                                 tmp_path: Path) -> None:
    import shutil

    folder = tmp_path / "holo"
    shutil.copytree(small_design, folder)
    run = _cli("verify", str(folder), "--step", "5", "--light-size", "0.53",
               "--roughness", "mirror", "--cut")
    assert run.returncode == 0, run.stderr
    assert "false glints from stripe ends" in run.stdout
    for name in ("verify.json", "verify_cut.json"):
        got = json.loads((folder / name).read_text())
        assert got["light"] == {"light_size": pytest.approx(0.53), "roughness": 0.003}
        rows = got["azimuths"]
        assert all(r["streak_length"] > 0.01 and r["end_spills"] >= 0 for r in rows)
        assert "max_end_spills" in got["summary"]


@pytest.mark.parametrize(("args", "said"), [
    (["--roughness", "shiny"], "roughness 'shiny' is neither a number nor one of"),
    (["--light-size", "-2"], "light size must be in"),
    (["--light-size", "0.5", "--cut", "--cut-method", "field"], "--cut-method survival"),
])
def test_bad_spread_options_are_one_line_and_write_nothing(small_design: Path, tmp_path: Path,
                                                           args: list[str], said: str) -> None:
    import shutil

    folder = tmp_path / "holo"
    shutil.copytree(small_design, folder)
    before = {p.name: p.stat().st_mtime_ns for p in folder.iterdir()}
    run = _cli("verify", str(folder), *args)
    assert run.returncode != 0
    assert said in run.stderr and "Traceback" not in run.stderr
    assert len(run.stderr.strip().splitlines()) == 1
    assert {p.name: p.stat().st_mtime_ns for p in folder.iterdir()} == before


def test_a_still_under_a_real_light_draws_the_streaks_and_their_spills(small_design: Path,
                                                                       tmp_path: Path) -> None:
    from PIL import Image
    from scipy import ndimage

    from specholo.jobs import job_of
    from specholo.simulation.streaks import false_glints, find_streaks

    def spots(*extra: str) -> tuple[np.ndarray, int]:
        out = tmp_path / f"still{len(extra)}.png"
        run = _cli("render", str(small_design), "--width", "1024", "--height", "1024",
                   "--out", str(out), *extra)
        assert run.returncode == 0, run.stderr
        grey = np.asarray(Image.open(out).convert("L"), dtype=float)
        lit = grey > 0.5 * grey.max()
        return lit, int(ndimage.label(lit)[1])

    _, points = spots()
    lit, streaks = spots("--light-size", "0.53", "--roughness", "mirror")
    # the point glints, and as many again where stripe ends spill light
    source = job_of(small_design).picture_source(small_design)
    eye = source.setup.viewer.eye(np.array([0.0]))[0]
    st = find_streaks(source.engraved(), eye, source.setup.light, Spread(SUN, 0.003))
    spilled = len(false_glints(st, st.glints().image()))
    assert spilled > 0
    assert streaks > points + 0.5 * spilled


def test_a_light_size_is_for_grooves() -> None:
    from specholo_cli.app import _lighting

    class Field:
        title = "a ridged design"

    with pytest.raises(SpecholoError, match="for flat-plate designs"):
        _lighting(Field(), None, 0.53)
    with pytest.raises(SpecholoError, match="perfect mirror"):
        _lighting(Field(), "0", None)
    source, lobe = _lighting(Field(), "polished", None)  # the gloss alone sizes the spots
    assert lobe == pytest.approx(0.01 / math.sqrt(2.0))


def test_the_design_names_the_light_that_gives_its_sharpest_image(small_design: Path) -> None:
    record = json.loads((small_design / "hologram.json").read_text())
    light = record["light_to_use"]
    trials = light["trials"]
    assert [t["size_deg"] for t in trials] == sorted((t["size_deg"] for t in trials),
                                                      reverse=True)
    best_p95 = min(t["p95_mm"] for t in trials)
    sharp = [t for t in trials if t["p95_mm"] <= 1.1 * best_p95]
    best_spills = min(t["spills_per_100"] for t in sharp)
    chosen = next(t for t in trials if t["size_deg"] == light["size_deg"])
    # the largest light within a tenth of the sharpest image and, among
    # those, of the fewest false glints
    assert chosen["p95_mm"] <= 1.1 * best_p95
    assert chosen["spills_per_100"] <= 1.1 * best_spills + 1.0
    larger = [t for t in trials if t["size_deg"] > light["size_deg"]]
    assert all(t["p95_mm"] > 1.1 * best_p95 or t["spills_per_100"] > 1.1 * best_spills + 1.0
               for t in larger)
    # a smaller light never blurs the plate more (beyond the sample's noise)
    assert trials[-1]["p95_mm"] <= 1.05 * trials[0]["p95_mm"]
    assert f"{light['size_deg']:g} deg across" in light["lamp"]


def test_a_plate_verified_a_few_views_at_a_time_gives_the_same_figures(small_design: Path
                                                                        ) -> None:
    from specholo.jobs.flat.folder import load_design
    from specholo.simulation.streak_verify import verify_streaks_both

    loaded = load_design(small_design)
    setup = loaded.config.setup()
    az = np.radians([-30.0, -10.0, 0.0, 25.0])
    cut = (loaded.config.cutter(), loaded.config.depth_mm)
    spread = Spread(SUN, GLOSS["mirror"])
    whole = verify_streaks_both(loaded.grooves, loaded.points, setup, spread, azimuths=az,
                                cut=cut)
    # a budget of one cell: one azimuth a batch, the grooves searched four times
    parts = verify_streaks_both(loaded.grooves, loaded.points, setup, spread, azimuths=az,
                                cut=cut, budget=1)
    assert whole == parts
    assert whole[1] is not None and len(whole[1]) == len(az)


def test_the_light_to_use_names_the_sun_when_it_is_as_good() -> None:
    """A design sharpest under a light as large as the sun's is told it may use
    the sun; a smaller light is a lamp, sized at 3 m or at the design's light."""
    from specholo.simulation.lighting import _lamp

    assert _lamp(0.53, None).startswith("the sun, or a small lamp")
    assert "27.8 mm across at 3 m" in _lamp(0.53, None)
    assert "sun" not in _lamp(0.25, None)
    assert _lamp(0.25, 500.0) == "a lamp at most 2.2 mm across at the design's 500 mm"
