"""Tools: groove sections from tool profiles, the views they serve, machinable stripings."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from specholo.errors import SpecholoError
from specholo.optics.cutters import (
    BallEnd,
    Laser,
    RoundCone,
    Scriber,
    VBit,
    check_views,
    make_cutter,
)
from specholo.setup import Light, Setup, Tool, Viewer
from specholo.toolpaths.common import make_runs
from specholo.toolpaths.grooves import Grooves
from specholo.toolpaths.overlap import groove_overlaps
from specholo.toolpaths.striped import StripeOptions, design_striped

BUNNY = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"
CUTTERS = [BallEnd(0.25), RoundCone(0.1, math.radians(90)), Scriber(), VBit(math.radians(60)),
           VBit(math.radians(90), 0.05), Laser(0.1)]


def _profile(cutter, depth: float) -> tuple[np.ndarray, np.ndarray]:
    """Groove cross-section (offset, height above the bottom) from the tool's profile."""
    r = np.linspace(0.0, 2.0, 400001)
    h = cutter.height(r, depth) if isinstance(cutter, Laser) else cutter.height(r)
    keep = np.isfinite(h) & (h <= depth)
    return r[keep], h[keep]


@pytest.mark.parametrize("cutter", CUTTERS, ids=lambda c: c.describe())
@pytest.mark.parametrize("depth", [0.02, 0.08])
def test_section_matches_the_swept_profile(cutter, depth):
    # The walls' tilts and the width follow from the profile the tool sweeps.
    r, h = _profile(cutter, depth)
    slope = np.degrees(np.arctan(np.gradient(h, r)))
    sec = cutter.section(depth)
    assert math.degrees(sec.max_tilt) == pytest.approx(slope.max(), abs=0.05)
    if isinstance(cutter, Laser):
        assert sec.width == cutter.spot  # 1/e^2 width, the trough never quite ends
    else:
        assert sec.width == pytest.approx(2.0 * r.max(), abs=2e-5)
    # Every tilt the walls show is one the section offers (a V-bit's edge at its
    # flat is a line: it offers the tilts in between over no width at all).
    if isinstance(cutter, VBit):
        slope = slope[np.abs(r - 0.5 * cutter.tip_flat) > 1e-4]
    assert sec.covers(np.radians(slope), tolerance=math.radians(0.05)).all()


def test_ball_model_is_the_tool_itself_and_vbit_offers_one_tilt():
    assert BallEnd(0.25).model(0.08) == Tool(0.25, 0.08)
    sec = VBit(math.radians(60)).section(0.1)
    assert sec.covers(np.radians([60.0])).all()
    assert not sec.covers(np.radians([30.0, 59.0, 61.0])).any()
    # A round cone cut past its sphere offers every tilt up to its flank.
    deep = RoundCone(0.1, math.radians(90)).section(0.2)
    assert math.degrees(deep.max_tilt) == pytest.approx(45.0)


def test_needed_tilt_straight_on_is_half_the_light_zenith_angle():
    # Eye far straight ahead, sun at elevation a: h bisects (0, cos a, sin a) and +z.
    setup = Setup(light=Light(math.radians(40.0)), viewer=Viewer(distance=1e7))
    p = np.array([[0.0, 0.0, -20.0]])
    need = 0.5 * (90.0 - 40.0)
    for depth, lost in ((0.25 * (1 - math.cos(math.radians(need - 0.5))), 1.0),
                        (0.25 * (1 - math.cos(math.radians(need + 0.5))), 0.0)):
        v = check_views(BallEnd(0.25), depth, p, np.array([0]), np.array([0.0]),
                        np.array([0.0]), setup.light, setup.viewer)
        assert math.degrees(v.needed[1]) == pytest.approx(need, abs=1e-3)
        assert v.lost == lost
        assert (v.suggestion == "") == (lost == 0)


def test_suggested_depth_serves_every_view():
    setup = Setup()
    rng = np.random.default_rng(3)
    p = np.column_stack([rng.uniform(-20, 20, 50), rng.uniform(-20, 20, 50),
                         rng.uniform(-60, -10, 50)])
    r = setup.viewer.design_range
    args = (p, np.arange(50), np.full(50, -r), np.full(50, r), setup.light, setup.viewer)
    shallow = check_views(BallEnd(0.25), 0.01, *args)
    assert shallow.lost > 0 and "deep" in shallow.suggestion
    depth = float(shallow.suggestion.split("at least ")[1].split(" mm")[0])
    assert check_views(BallEnd(0.25), depth, *args).lost == 0


def test_strict_refuses_a_tool_that_loses_views_and_names_a_fix():
    from specholo.jobs.flat.folder import DesignConfig, design

    with pytest.raises(SpecholoError, match="100.0% of views lost.*ball end"):
        design(BUNNY, DesignConfig(stipples=40, tool="vbit", strict=True))
    d = design(BUNNY, DesignConfig(stipples=40, tool="vbit"))  # without --strict: reported
    assert d.views is not None and d.views.lost == 1.0


@pytest.mark.parametrize("bad", [dict(kind="ball", radius=-1), dict(kind="vbit", angle_deg=180),
                                 dict(kind="laser", spot=0), dict(kind="saw"),
                                 dict(kind="vbit", tip_flat=-0.1)])
def test_bad_tools_are_refused_with_the_value(bad):
    kind = bad.pop("kind")
    with pytest.raises(SpecholoError):
        make_cutter(kind, **bad)


def test_ball_cannot_cut_deeper_than_its_radius():
    with pytest.raises(SpecholoError, match="exceeds the ball radius"):
        BallEnd(0.1).section(0.2)


def _lines(ys: list[float], stipples: list[int], x0: float = -2.0, x1: float = 2.0) -> Grooves:
    n = len(ys)
    v = np.array([[x, y] for y in ys for x in (x0, x1)])
    return Grooves(v, np.zeros(2 * n), np.arange(0, 2 * n + 1, 2), np.array(stipples))


def test_overlap_finds_neighbouring_stripes_closer_than_the_width():
    w = 0.37
    assert groove_overlaps(_lines([0.0, 0.3], [0, 0]), w).neighbours == 1
    assert groove_overlaps(_lines([0.0, 0.4], [0, 0]), w).neighbours == 0
    # A path resuming where the last ended retraces its groove: not an overlap.
    assert groove_overlaps(_lines([0.0, 0.001], [0, 0]), w).neighbours == 0


def test_crossing_of_two_stipples_is_counted_once_with_its_length():
    w = 0.37
    v = np.array([[-2.0, 0.0], [2.0, 0.0], [0.0, -2.0], [0.0, 2.0]])
    g = Grooves(v, np.zeros(4), np.array([0, 2, 4]), np.array([0, 1]))
    o = groove_overlaps(g, w)
    assert o.crossings == 1
    # Each groove lies within a width of the other over 2 w of its length.
    assert o.crossed_length == pytest.approx(4 * w, rel=0.15)
    assert groove_overlaps(_lines([0.0, 1.0], [0, 1]), w).crossings == 0


def test_striping_keeps_one_stipples_grooves_a_width_apart():
    # A wide groove on steep stripes (large azimuths): a fixed band would make
    # neighbouring stripes cut into each other; the construction widens it.
    setup = Setup(tool=Tool(0.5, 0.2))
    rng = np.random.default_rng(11)
    p = np.column_stack([rng.uniform(-20, 20, 40), rng.uniform(-20, 20, 40),
                         rng.uniform(-70, -20, 40)])
    r = setup.viewer.design_range
    runs = make_runs(p, np.arange(40), np.full(40, -r), np.full(40, r))
    width = setup.tool.width
    fixed, _ = design_striped(runs, setup, StripeOptions(band=0.2, spacing=0.0))
    assert groove_overlaps(fixed, width).neighbours > 0
    spaced, _ = design_striped(runs, setup, StripeOptions(band=0.2))
    o = groove_overlaps(spaced, width)
    assert o.neighbours == 0 and o.closest_neighbours >= width - 1e-3


def test_default_depth_is_just_deep_enough_for_the_views_plus_the_allowance():
    from specholo.jobs.flat.folder import TILT_MARGIN, DesignConfig, design
    from specholo.jobs.flat.settings import DEPTH_ALLOWANCE

    d = design(BUNNY, DesignConfig(stipples=60), check_overlaps=False)
    assert d.views is not None and d.views.lost == 0
    tip = d.config.cutter()
    assert isinstance(tip, RoundCone)
    need = tip.tip_radius * (1 - math.cos(d.views.needed[1] + TILT_MARGIN))
    assert d.config.depth == pytest.approx(need + DEPTH_ALLOWANCE, abs=1e-3)
    assert d.config.depth >= need + DEPTH_ALLOWANCE


def test_cut_plate_keeps_about_exp_minus_coverage_of_the_glints():
    # Other stipples' grooves cut away glints at random: one eye keeps ~exp(-coverage).
    from specholo.jobs.flat.folder import DesignConfig, Loaded, design
    from specholo.simulation.cut import cut_design, find_cut_glints
    from specholo.simulation.glints import Engraved, find_glints

    d = design(BUNNY, DesignConfig(stipples=400, tool="ball"), check_overlaps=True)
    assert d.overlaps is not None
    loaded = Loaded(d.config, d.points, d.normals, d.grooves, d.model.mesh)
    field = cut_design(loaded, resolution=0.02)
    setup = d.config.setup()
    eng = Engraved.from_grooves(d.grooves, setup.tool)
    kept = []
    for deg in (-30.0, 0.0, 30.0):
        eye = setup.viewer.eye(np.array([math.radians(deg)]))[0]
        ideal = len(find_glints(eng, eye, setup.light).path)
        cut = len(find_cut_glints(field, eye, setup.light).designed().path)
        kept.append(cut / ideal)
    assert np.mean(kept) == pytest.approx(d.overlaps.surviving, abs=0.15)


def test_large_design_overlaps_estimated_in_windows_agree_with_the_full_count(monkeypatch):
    # Past MAX_SAMPLES the crossings are counted in random windows and scaled:
    # on a design small enough to count in full the two must agree.
    import specholo.toolpaths.overlap as overlap
    from specholo.jobs.flat.folder import DesignConfig, design

    # (a 0.05 mm tip within its sphere: its wider grooves cross more than a thousand times)
    d = design(BUNNY, DesignConfig(stipples=400, size=30.0, tool_radius=0.05, depth=0.012),
               check_overlaps=False)
    width = d.config.cutter().section(d.config.depth_mm).width
    full = groove_overlaps(d.grooves, width, sample=None)
    monkeypatch.setattr(overlap, "MAX_SAMPLES", 1000)
    monkeypatch.setattr(overlap, "MIN_WINDOWS", 400)
    monkeypatch.setattr(overlap, "MAX_QUERIES", 10**6)
    est = [groove_overlaps(d.grooves, width, rng=np.random.default_rng(s)) for s in range(3)]
    assert full.crossings > 1000
    for e in est:
        assert e.total_length == pytest.approx(full.total_length, rel=1e-9)
        assert e.neighbours == full.neighbours
        assert e.crossings == pytest.approx(full.crossings, rel=0.05)
        assert e.crossed_length == pytest.approx(full.crossed_length, rel=0.05)


def test_classic_arcs_estimated_in_windows_agree_with_the_full_count(monkeypatch):
    # A classic arc is tens of mm long: the windows sample only its parts near
    # them, and the estimate must still agree with the full count.
    import specholo.toolpaths.overlap as overlap
    from specholo.jobs.flat.folder import DesignConfig, design

    d = design(BUNNY, DesignConfig(stipples=400, size=30.0, method="arc"), check_overlaps=False)
    width = d.config.cutter().section(d.config.depth_mm).width
    lengths = d.grooves.segments().lengths()
    assert np.median(lengths) > 20 * overlap.PIECE
    full = groove_overlaps(d.grooves, width, sample=None)
    monkeypatch.setattr(overlap, "MAX_SAMPLES", 1000)
    monkeypatch.setattr(overlap, "MIN_WINDOWS", 400)
    monkeypatch.setattr(overlap, "MAX_QUERIES", 10**6)
    assert full.crossings > 1000
    for s in range(3):
        e = groove_overlaps(d.grooves, width, rng=np.random.default_rng(s))
        assert e.crossings == pytest.approx(full.crossings, rel=0.05)
        assert e.crossed_length == pytest.approx(full.crossed_length, rel=0.05)


def test_a_long_groove_is_sampled_only_where_it_passes_a_window():
    import specholo.toolpaths.overlap as overlap

    # A 20 mm arc (sweep 60 degrees) and one chosen window of side 0.5 mm on it.
    r, sweep = 20.0 / (math.pi / 3), math.pi / 3
    ends = r * np.array([[math.cos(-sweep / 2), math.sin(-sweep / 2)],
                         [math.cos(sweep / 2), math.sin(sweep / 2)]])
    v, b = ends, np.array([math.tan(sweep / 4), 0.0])
    chosen = np.zeros((100, 100), dtype=bool)
    chosen[50, 50] = True
    x0, y0 = r - 25.25, -25.25  # the window centred on (r, 0), the arc's midpoint
    reach = 0.1
    arcs, u0, u1 = overlap._near_windows(v, b, np.array([0, 2]), np.array([True]), chosen,
                                         x0, y0, overlap.WINDOW, reach, overlap.PIECE)
    assert list(arcs) == [0]
    part = (u1[0] - u0[0]) * 20.0
    assert overlap.WINDOW <= part <= overlap.WINDOW + 2 * (reach + overlap.PIECE) + 1e-9
    pts, _, share = overlap._sample_arcs(v, b, arcs, np.zeros(1, np.int64), 0.01,
                                         np.zeros(0, np.int64), np.zeros(0, np.int64), u0, u1)
    # The samples lie on the arc, by the window, and stand for the part's length.
    assert np.allclose(np.hypot(pts[:, 0], pts[:, 1]), r)
    assert np.all(np.abs(pts[:, 0] - r) < 0.01)
    assert np.abs(pts[:, 1]).max() <= 0.25 + reach + overlap.PIECE + 1e-9
    assert share.sum() == pytest.approx(part, rel=1e-9)


def test_a_design_states_what_survives_exactly_or_roughly():
    """The exact as-cut figure where the design finds it, the coverage's rough
    share where it leaves that to ``verify --cut``: never neither."""
    from specholo.jobs.flat.folder import DesignConfig, design

    exact = design(BUNNY, DesignConfig(stipples=60))
    assert exact.as_cut is not None and exact.overlaps is None
    rough = design(BUNNY, DesignConfig(stipples=60), expect_as_cut=False)
    assert rough.as_cut is None and rough.overlaps is not None
    assert 0.0 < rough.overlaps.surviving <= 1.0
    assert np.array_equal(exact.grooves.vertices, rough.grooves.vertices)


def test_the_automatic_depth_serves_every_view_the_cone_can():
    """At a 30 degree light the views need walls up to about 45.1 degrees, past the
    90 degree cone's 45 degree flank: the depth reaches the flank (not the tool's
    fallback), only the views past it are lost, and the warning names them and
    a cone that would serve them."""
    import math

    from specholo.jobs.flat.folder import DesignConfig, design
    from specholo.optics.cutters import RoundCone

    d = design(BUNNY, DesignConfig(stipples=500, size=60, center_z=-40, light_elevation=30,
                                   view_distance=600, view_range=45),
               expect_as_cut=False)
    cutter = d.config.cutter()
    assert isinstance(cutter, RoundCone)
    flank = 0.5 * math.pi - 0.5 * cutter.angle
    assert d.views is not None and d.views.needed[1] > flank  # the cone cannot serve all
    # The groove's walls reach the flank itself, with the machine's allowance.
    assert d.views.offered.max_tilt >= flank - 1e-9
    assert d.config.depth_mm >= cutter.tip_radius * (1 - math.cos(flank)) + 0.005 - 1e-9
    assert d.views.lost < 0.01
    words = d.views.lost_views()
    assert "eye azimuths" in words
    angle = int(words.split("at most ")[1].split(" degrees")[0])
    assert angle < 90 and 90 - 2 * math.degrees(d.views.needed[1] - flank) >= angle - 1
