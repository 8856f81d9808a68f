"""Physics of the designs: forward ray traces, closed forms, signs, properties."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from specholo.hosts.flat import sightline_crossing
from specholo.optics.foliation import hyperbola_slope, hyperbola_y
from specholo.optics.normality import reflect, unit
from specholo.optics.stereo import triangulate
from specholo.setup import Light, Setup, Tool, Viewer
from specholo.simulation.glints import Engraved, find_glints
from specholo.toolpaths.arcs import biarc
from specholo.toolpaths.common import make_runs
from specholo.toolpaths.striped import StripeOptions, design_striped

WIDE_TOOL = Tool(radius=1.0, depth=1.0)  # walls offer every tilt: isolate the tangent condition


def _design(points: np.ndarray, setup: Setup, band: float = 0.2, refusable: bool = False,
            spacing: float = 0.0):
    # A fixed band (no spacing) by default: these tests bound the error by the band.
    r = setup.viewer.design_range
    n = len(points)
    runs = make_runs(points, np.arange(n), np.full(n, -r), np.full(n, r))
    grooves, dropped = design_striped(runs, setup, StripeOptions(band=band, spacing=spacing))
    if refusable:
        # Light nearly in the eyes' plane makes grooves run vertically: refused.
        assume(dropped.size == 0)
    assert dropped.size == 0
    return grooves


def _wall_normal_trace(eng: Engraved, glints, eye: np.ndarray, light: Light) -> np.ndarray:
    """Reflect the light off the groove wall at each glint; return the angle to the eye.

    The wall of a groove cut by a ball of radius R is the envelope of the ball:
    at a point g its normal points to the ball centre c (on the toolpath, R - d
    above the plate) whose contact circle, perpendicular to the path, holds g.
    """
    tool = eng.tool
    angles = []
    for path, g in zip(glints.path, glints.point, strict=True):
        best = None
        u = np.linspace(0, 1, 4001)
        for i in np.flatnonzero(eng.path == path):
            pts, t = eng.at(np.full(u.size, i), u)
            c3 = pts + np.array([0.0, 0.0, tool.radius - tool.depth])
            rel = c3 - g
            f = np.abs(rel[:, 0] * t[:, 0] + rel[:, 1] * t[:, 1])
            j = int(np.argmin(f))
            if best is None or f[j] < best[0]:
                best = (f[j], rel[j])
        assert best is not None
        rel = best[1]
        assert abs(np.linalg.norm(rel) - tool.radius) < 1e-3  # g is on the cut wall
        n = rel / np.linalg.norm(rel)
        incoming = -light.towards(g[None])[0]
        out = reflect(incoming[None], n[None])[0]
        angles.append(math.acos(min(1.0, float(out @ unit(eye - g)))))
    return np.array(angles)


def _sightline_at(eye: np.ndarray, p: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Points (k, 3) of the lines from eye through p (k, 3) at depths z (k,)."""
    tau = (eye[2] - z) / (eye[2] - p[:, 2])
    return eye + tau[:, None] * (p - eye)


def test_forward_trace_reaches_the_eye_on_the_sightline():
    setup = Setup(tool=WIDE_TOOL)
    p = np.array([[5.0, 8.0, -40.0], [-12.0, -3.0, -65.0], [3.0, 2.0, 25.0]])
    eng = Engraved.from_grooves(_design(p, setup), setup.tool)
    for deg in (-44.0, -20.0, 0.0, 17.0, 44.0):
        eye = setup.viewer.eye(np.array([math.radians(deg)]))[0]
        g = find_glints(eng, eye, setup.light)
        assert sorted(set(g.stipple.tolist())) == [0, 1, 2]
        # The reflected ray leaves the wall toward the eye (forward trace).
        assert _wall_normal_trace(eng, g, eye, setup.light).max() < 2e-3
        # The glint is on the eye's sightline through its point: x exact, y within the band.
        s = _sightline_at(eye, p[g.stipple], g.point[:, 2])
        assert np.abs(g.point[:, 0] - s[:, 0]).max() < 0.01
        assert np.abs(g.point[:, 1] - s[:, 1]).max() <= 0.2 * 1.05


def test_construction_matches_closed_form_hyperbola_far_away():
    # Eyes and sun at (nearly) infinity, one stripe wide enough for the whole range.
    a = math.radians(40.0)
    # A fine tool: the closed form describes the glint locus of an ideal thin groove.
    setup = Setup(light=Light(a), viewer=Viewer(distance=1e7, ipd=64.0,
                                                 half_range=math.radians(40.0)),
                  tool=Tool(radius=1e-3, depth=1e-3))
    p = np.array([[4.0, 0.0, -30.0], [0.0, 0.0, 20.0]])
    grooves = _design(p, setup, band=100.0)
    for j in range(grooves.n_paths):
        v = grooves.vertices[grooves.offsets[j]:grooves.offsets[j + 1]]
        pj = p[grooves.stipple[j]][None].repeat(len(v), 0)
        y_closed = hyperbola_y(v[:, 0], pj[:, :2], pj[:, 2], a)
        offset = v[:, 1] - y_closed
        # Microns over a hyperbola several mm tall: the integration's (Heun) own error.
        assert np.ptp(offset) < 5e-3, "the construction drifts from the closed form"
        assert np.ptp(y_closed) > 2.0
        assert np.ptp(v[:, 0]) > 20.0


def test_hyperbola_sign():
    a = math.radians(45.0)
    p = np.array([[0.0, 0.0, -40.0]])
    for theta in np.radians([-40.0, -10.0, 10.0, 40.0]):
        x = -p[0, 2] * math.tan(theta)  # far-eye sightline crossing
        slope = hyperbola_slope(np.array([x]), p[:, :2], p[:, 2], a)[0]
        # Glint condition for eye and sun at infinity: (1, slope) ⟂ (sin theta, cos a).
        assert abs(math.sin(theta) + slope * math.cos(a)) < 1e-12
    # Behind the plate the hyperbola opens downward (the paper's eq. 4 sign would flip it).
    y = hyperbola_y(np.array([-20.0, 0.0, 20.0]), p[[0, 0, 0], :2], p[[0, 0, 0], 2], a)
    assert y[0] < y[1] and y[2] < y[1]
    slope_eq4 = -slope
    assert abs(math.sin(theta) + slope_eq4 * math.cos(a)) > 0.1


def test_biarc_matches_end_tangents():
    rng = np.random.default_rng(3)
    p0 = rng.normal(size=(50, 2))
    p1 = p0 + rng.uniform(0.5, 2.0, size=(50, 1)) * np.array([1.0, 0.0])
    ang0 = rng.uniform(-0.6, 0.6, 50)
    ang1 = rng.uniform(-0.6, 0.6, 50)
    t0 = np.stack([np.cos(ang0), np.sin(ang0)], 1)
    t1 = np.stack([np.cos(ang1), np.sin(ang1)], 1)
    joint, b1, b2 = biarc(p0, t0, p1, t1)
    # End tangent of arc 1 equals start tangent of arc 2 (continuity), and ends match.
    chord1, chord2 = joint - p0, p1 - joint
    a1 = np.arctan2(chord1[:, 1], chord1[:, 0])
    a2 = np.arctan2(chord2[:, 1], chord2[:, 0])
    sweep1, sweep2 = 4 * np.arctan(b1), 4 * np.arctan(b2)
    np.testing.assert_allclose(np.angle(np.exp(1j * (a1 - sweep1 / 2 - ang0))), 0, atol=1e-9)
    np.testing.assert_allclose(np.angle(np.exp(1j * (a1 + sweep1 / 2 - (a2 - sweep2 / 2)))), 0,
                               atol=1e-9)
    np.testing.assert_allclose(np.angle(np.exp(1j * (a2 + sweep2 / 2 - ang1))), 0, atol=1e-9)


@settings(max_examples=25, deadline=None)
@given(
    elevation=st.floats(15.0, 75.0),
    light_distance=st.one_of(st.none(), st.floats(400.0, 3000.0)),
    distance=st.floats(350.0, 2000.0),
    eye_height=st.floats(-100.0, 100.0),
    px=st.floats(-30.0, 30.0), py=st.floats(-30.0, 30.0),
    pz=st.one_of(st.floats(-90.0, -3.0), st.floats(3.0, 60.0)),
    view=st.floats(-1.0, 1.0),
)
def test_property_glints_triangulate_to_the_point(elevation, light_distance, distance,
                                                  eye_height, px, py, pz, view):
    setup = Setup(light=Light(math.radians(elevation), light_distance),
                  viewer=Viewer(distance, eye_height, math.radians(40.0), 64.0), tool=WIDE_TOOL)
    p = np.array([[px, py, pz]])
    eng = Engraved.from_grooves(_design(p, setup, band=0.2, refusable=True), setup.tool)
    theta = view * setup.viewer.half_range
    left, right = setup.viewer.stereo(np.array([theta]))
    gl = find_glints(eng, left[0], setup.light)
    gr = find_glints(eng, right[0], setup.light)
    assert len(gl.point) >= 1 and len(gr.point) >= 1
    for eye, g in ((left[0], gl), (right[0], gr)):
        s = _sightline_at(eye, p[[0] * len(g.point)], g.point[:, 2])
        assert np.abs(g.point[:, 0] - s[:, 0]).max() < 0.01
        assert np.abs(g.point[:, 1] - s[:, 1]).max() < 0.25
    k = len(gl.point) * len(gr.point)
    il, ir = np.meshgrid(np.arange(len(gl.point)), np.arange(len(gr.point)))
    apparent, _ = triangulate(np.broadcast_to(left[0], (k, 3)), gl.point[il.ravel()],
                              np.broadcast_to(right[0], (k, 3)), gr.point[ir.ravel()])
    err = np.linalg.norm(apparent - p, axis=1).min()
    assert err < 0.35


def test_light_in_the_eyes_plane_is_reported_not_designed():
    setup = Setup(light=Light(math.radians(90.0)))
    p = np.array([[0.0, 0.0, -30.0]])
    r = setup.viewer.design_range
    runs = make_runs(p, np.array([0]), np.array([-r]), np.array([r]))
    grooves, dropped = design_striped(runs, setup)
    assert dropped.tolist() == [0] and grooves.n_paths == 0


@pytest.mark.parametrize("pz", [0.0, 0.05, -0.1])
def test_points_on_the_plate_become_dimples_seen_in_place(pz):
    setup = Setup()
    p = np.array([[3.0, -2.0, pz]])
    eng = Engraved.from_grooves(_design(p, setup), setup.tool)
    assert eng.grooves.is_dot.all()
    left, right = setup.viewer.stereo(np.radians([20.0]))
    gl = find_glints(eng, left[0], setup.light)
    gr = find_glints(eng, right[0], setup.light)
    apparent, _ = triangulate(left, gl.point[:1], right, gr.point[:1])
    # Within the depth itself plus the wall offset's swing (R times the turn of h).
    assert np.linalg.norm(apparent[0] - p[0]) <= abs(pz) + 0.1


def test_grooves_stay_between_the_sightline_crossings():
    # Every arc of a stipple lies where its eyes' sightlines cross the plate:
    # no biarc may bulge far out (a wild arc would cut stray grooves).
    setup = Setup()
    rng = np.random.default_rng(7)
    p = np.column_stack([rng.uniform(-30, 30, 300), rng.uniform(-30, 30, 300),
                         rng.choice([-1.0, 1.0], 300) * rng.uniform(1.0, 70.0, 300)])
    grooves = _design(p, setup)
    eng = Engraved.from_grooves(grooves, setup.tool)
    r = setup.viewer.design_range
    eyes = setup.viewer.eye(np.array([-r, r]))
    lo = np.minimum(sightline_crossing(np.broadcast_to(eyes[0], p.shape), p),
                    sightline_crossing(np.broadcast_to(eyes[1], p.shape), p))
    hi = np.maximum(sightline_crossing(np.broadcast_to(eyes[0], p.shape), p),
                    sightline_crossing(np.broadcast_to(eyes[1], p.shape), p))
    stip = grooves.stipple[eng.path]
    for u in (0.0, 0.5, 1.0):
        pts, _ = eng.at(np.arange(len(eng.path)), np.full(len(eng.path), u))
        margin = 1.0  # band, wall offset and tool radius
        assert (pts[:, 0] >= lo[stip, 0] - margin).all()
        assert (pts[:, 0] <= hi[stip, 0] + margin).all()


def test_sample_buffers_that_overflow_are_retried_with_room():
    from specholo.toolpaths import _stripe_kernel as kernel
    from specholo.toolpaths.striped import _integrate, _params, _Scratch

    setup = Setup()
    opts = StripeOptions()
    p = np.array([[5.0, 8.0, -40.0], [-12.0, -3.0, -65.0], [3.0, 2.0, 25.0]])
    r = setup.viewer.design_range
    runs = make_runs(p, np.arange(3), np.full(3, -r), np.full(3, r))
    params = _params(setup, opts)
    u0, _, cap = kernel.start_offsets(runs.start, runs.end, runs.point, params, opts.band,
                                      opts.min_light_tilt)
    def samples(cap: np.ndarray) -> list[list[np.ndarray]]:
        offsets, count, *slots = _integrate(runs, params, u0, cap, opts.band,
                                            setup.tool.width, _Scratch())
        assert (count >= 0).all()
        return [[a[o:o + c] for a in slots[:3]] for o, c in zip(offsets, count, strict=True)]

    full = samples(cap.copy())
    # The first run fits; the others overflow and go again, more than once.
    tight = samples(np.array([cap[0], 2, 2], dtype=np.int64))
    assert [len(r[0]) for r in full] == [len(r[0]) for r in tight]
    assert min(len(r[0]) for r in full) > 8
    for a, b in zip(full, tight, strict=True):
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(x, y)
