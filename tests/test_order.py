"""Cutting order (the same grooves with less air travel) and machining time."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from specholo.errors import SpecholoError
from specholo.fabrication.programs.gcode import write_gcode
from specholo.fabrication.programs.order import OrderStats, order_paths, reorder, travel_length
from specholo.fabrication.programs.timing import describe_machining, estimate_time, plain_duration
from specholo.setup import Machining, Tool
from specholo.toolpaths.grooves import Grooves


def path_keys(g: Grooves) -> list[tuple]:
    """Each path as (stipple, vertices, bulges) in the direction that sorts first."""
    keys = []
    for j in range(g.n_paths):
        v = g.vertices[g.offsets[j]:g.offsets[j + 1]]
        b = g.bulges[g.offsets[j]:g.offsets[j + 1]]
        forward = (tuple(map(tuple, v)), tuple(b))
        # the same arcs cut the other way: vertices reversed, each bulge moved to
        # the arc's other end and negated
        back = (tuple(map(tuple, v[::-1])), tuple(np.append(-b[:-1][::-1], 0.0)))
        keys.append((int(g.stipple[j]), *min(forward, back)))
    return sorted(keys)


def arc_keys(g: Grooves) -> list[tuple]:
    """Every arc as geometry: its ends in sorted order and its bulge going that way."""
    segs = g.segments()
    keys = []
    for k in range(len(segs)):
        a, b = tuple(segs.start[k]), tuple(segs.end[k])
        bulge = segs.bulge[k]
        if a > b:
            a, b, bulge = b, a, -bulge
        elif a == b:  # no chord, no direction
            bulge = abs(bulge)
        keys.append((a, b, bulge))
    dots = [tuple(p) for p in g.dots()[0]]
    return sorted(keys) + sorted(dots)


def travel(g: Grooves) -> float:
    return travel_length(g.vertices[g.offsets[:-1]], g.vertices[g.offsets[1:] - 1])


def check(g: Grooves, out: Grooves, stats: OrderStats) -> None:
    assert path_keys(out) == path_keys(g)
    assert arc_keys(out) == arc_keys(g)
    assert stats.paths == g.n_paths
    assert stats.travel_before_mm == pytest.approx(travel(g), rel=1e-12, abs=1e-9)
    assert stats.travel_after_mm == pytest.approx(travel(out), rel=1e-12, abs=1e-9)
    assert stats.travel_after_mm <= stats.travel_before_mm


@settings(max_examples=150, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_same_arcs_and_never_longer(grooves_strategy, data):
    g = data.draw(grooves_strategy(max_paths=14, max_arcs=4, max_bulge=3.0))
    out, stats = order_paths(g, neighbours=data.draw(st.integers(1, 10)),
                             max_shift=data.draw(st.sampled_from([0, 1, 3, 50_000])))
    check(g, out, stats)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 400))
def test_clustered_and_duplicate_ends(seed, n):
    # many paths sharing end points and dots on top of each other
    rng = np.random.default_rng(seed)
    grid = rng.integers(-3, 4, (n, 2)).astype(float)
    sizes = rng.integers(1, 4, n)
    verts = np.repeat(grid, sizes, axis=0) + rng.integers(-1, 2, (int(sizes.sum()), 2))
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    bulges = rng.choice([0.0, 0.5, -1.0], len(verts))
    bulges[offsets[1:] - 1] = 0.0
    g = Grooves(verts, bulges, offsets, rng.integers(0, 5, n))
    out, stats = order_paths(g)
    check(g, out, stats)


def test_reversing_keeps_each_arc():
    g = Grooves(np.array([[0.0, 0.0], [2.0, 0.0], [3.0, 1.0], [5.0, 5.0]]),
                np.array([1.0, -0.4, 0.0, 0.0]), np.array([0, 3, 4]), np.array([7, 8]))
    back = reorder(g, np.array([1, 0]), np.array([False, True]))
    np.testing.assert_array_equal(back.offsets, [0, 1, 4])
    np.testing.assert_array_equal(back.stipple, [8, 7])
    np.testing.assert_array_equal(back.vertices, [[5, 5], [3, 1], [2, 0], [0, 0]])
    np.testing.assert_array_equal(back.bulges, [0.0, 0.4, -1.0, 0.0])
    a, b = g.segments(), back.segments()
    ca, ra, sa, wa = a.geometry()
    cb, rb, sb, wb = b.geometry()
    # the same circles, swept the other way from the other end
    np.testing.assert_allclose(cb[::-1], ca)
    np.testing.assert_allclose(rb[::-1], ra)
    np.testing.assert_allclose(wb[::-1], -wa)
    np.testing.assert_allclose(b.lengths()[::-1], a.lengths())


def test_empty_and_single_path():
    out, stats = order_paths(Grooves.empty())
    assert out.n_paths == 0 and stats == OrderStats(0, 0.0, 0.0, 0)
    dot = Grooves(np.array([[3.0, 4.0]]), np.zeros(1), np.array([0, 1]), np.array([2]))
    out, stats = order_paths(dot)
    assert out is dot and stats == OrderStats(1, 5.0, 5.0, 0)
    # one groove is cut from its end nearer the origin
    line = Grooves(np.array([[10.0, 0.0], [1.0, 0.0]]), np.array([0.3, 0.0]),
                   np.array([0, 2]), np.array([4]))
    out, stats = order_paths(line)
    np.testing.assert_array_equal(out.vertices, [[1.0, 0.0], [10.0, 0.0]])
    np.testing.assert_array_equal(out.bulges, [-0.3, 0.0])
    assert stats == OrderStats(1, 10.0, 1.0, 1)


def test_a_row_of_strokes_is_cut_in_order():
    # strokes along a line, shuffled and some reversed: the best order cuts them
    # left to right, travelling only the gaps
    rng = np.random.default_rng(3)
    n = 200
    x = np.arange(n) * 2.0 + 1.0
    verts = np.stack([np.stack([x, np.zeros(n)], 1), np.stack([x + 1.0, np.zeros(n)], 1)], 1)
    flip = rng.random(n) < 0.5
    verts[flip] = verts[flip][:, ::-1]
    order = rng.permutation(n)
    g = Grooves(verts[order].reshape(-1, 2), np.zeros(2 * n), np.arange(0, 2 * n + 1, 2),
                order)
    out, stats = order_paths(g)
    check(g, out, stats)
    assert stats.travel_after_mm == pytest.approx(1.0 + (n - 1) * 1.0)
    np.testing.assert_array_equal(out.stipple, np.arange(n))


def test_improvement_beats_the_greedy_tour():
    rng = np.random.default_rng(11)
    n = 20_000
    start = rng.uniform(-100, 100, (n, 2))
    end = start + rng.normal(0, 1.0, (n, 2))
    g = Grooves(np.stack([start, end], 1).reshape(-1, 2), np.zeros(2 * n),
                np.arange(0, 2 * n + 1, 2), np.arange(n))
    greedy, s0 = order_paths(g, max_shift=0)
    out, s1 = order_paths(g)
    check(g, out, s1)
    assert s0.travel_before_mm == s1.travel_before_mm
    # a random order travels ~n * 104 mm; a good tour ~0.7 sqrt(n * area)
    assert s0.travel_after_mm < 0.02 * s0.travel_before_mm
    assert s1.travel_after_mm < 0.92 * s0.travel_after_mm
    assert s1.travel_after_mm < 1.0 * math.sqrt(n * 200.0**2)
    assert 0 < s1.reversed < n


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"neighbours": 0}, "neighbours must be at least 1, got 0"),
    ({"max_shift": -1}, "max shift must be >= 0, got -1"),
])
def test_rejects_bad_options(kwargs, message):
    g = Grooves(np.zeros((2, 2)), np.zeros(2), np.array([0, 1, 2]), np.array([0, 1]))
    with pytest.raises(SpecholoError, match=message):
        order_paths(g, **kwargs)


def test_rejects_bad_grooves():
    empty_path = Grooves(np.zeros((1, 2)), np.zeros(1), np.array([0, 0, 1]), np.array([0, 1]))
    with pytest.raises(SpecholoError, match="empty path"):
        order_paths(empty_path)
    nan = Grooves(np.array([[0.0, np.nan]]), np.zeros(1), np.array([0, 1]), np.array([0]))
    with pytest.raises(SpecholoError, match="non-finite"):
        order_paths(nan)


# ---------------------------------------------------------------------------
# machining time

A = 100.0  # mm/s^2
MILL = Machining(feed=600.0, plunge=100.0, safe_z=1.0, spindle=0.0)  # 10 and 5/3 mm/s
NO_HOPS = Machining(feed=600.0, plunge=100.0, safe_z=1.0, spindle=0.0, hop_max=0.0)


def one_groove(vertices, bulges=None, stipple=7) -> Grooves:
    v = np.asarray(vertices, dtype=float)
    b = np.zeros(len(v)) if bulges is None else np.asarray(bulges, dtype=float)
    return Grooves(v, b, np.array([0, len(v)]), np.array([stipple]))


def test_time_of_a_straight_cut():
    # 10 mm at 10 mm/s: 0.1 s to reach full speed over 0.5 mm, 0.1 s to stop
    # over 0.5 mm, 9 mm cruising: 1.1 s
    est = estimate_time(one_groove([[30.0, 0.0], [40.0, 0.0]]), 0.08, MILL, accel=A)
    assert est.cutting_s == pytest.approx(1.1)
    # 0.25 mm never reaches full speed: accelerate half way, brake: 2 sqrt(L / a)
    est = estimate_time(one_groove([[30.0, 0.0], [30.25, 0.0]]), 0.08, MILL, accel=A)
    assert est.cutting_s == pytest.approx(2 * math.sqrt(0.25 / A)) == pytest.approx(0.1)


def test_time_of_rapids_plunges_and_retracts():
    est = estimate_time(one_groove([[30.0, 0.0], [40.0, 0.0]]), 0.08, MILL, accel=A,
                        rapid=3000.0, dwell=2.0)
    # rapid 30 mm at 50 mm/s (25 mm to reach it and stop): 30 / 50 + 50 / 100;
    # retract 1.08 mm never reaches it: 2 sqrt(1.08 / 100)
    assert est.rapid_s == pytest.approx(0.6 + 0.5 + 2 * math.sqrt(1.08 / A))
    # plunge 1.08 mm at 5/3 mm/s: 1.08 / (5/3) + (5/3) / 100
    assert est.plunge_s == pytest.approx(1.08 * 0.6 + 5 / 3 / A)
    assert est.dwell_s == 2.0
    assert est.total_s == pytest.approx(est.cutting_s + est.rapid_s + est.plunge_s + 2.0)
    assert est.stipples == 1 and est.stipples_per_s == pytest.approx(1 / est.total_s)


@pytest.mark.parametrize("seconds, words", [
    (10, "under a minute"), (90, "2 min"), (3600, "1 h"), (8.1 * 3600, "8 h 6 min"),
    (49 * 3600, "2 days 1 h"), (float("nan"), "unknown")])
def test_durations_in_plain_words(seconds, words):
    assert plain_duration(seconds) == words


def test_machining_line_states_the_whole_job_and_its_parts():
    est = estimate_time(one_groove([[30.0, 0.0], [3030.0, 0.0]]), 0.08, MILL, accel=A)
    hours = {"estimated_hours": est.total_s / 3600, "cutting_hours": est.cutting_s / 3600,
             "rapid_hours": est.rapid_s / 3600, "plunge_hours": est.plunge_s / 3600}
    line = describe_machining(hours, MILL.feed)
    # 3 m at 600 mm/min is 5 min of cutting; the rest (seconds) is not itemised
    assert line == f"machining: about 5 min at {MILL.feed:g} mm/min (cutting 5 min)"


def test_time_through_junctions():
    # a straight line through a vertex does not slow down
    est = estimate_time(one_groove([[0.0, 0.0], [5.0, 0.0], [10.0, 0.0]]), 0.08, MILL, accel=A)
    assert est.cutting_s == pytest.approx(1.1)
    # a right angle: GRBL's junction speed v^2 = a delta cos(45) / (1 - cos(45))
    delta = 0.01
    v = math.sqrt(A * delta * math.cos(math.pi / 4) / (1 - math.cos(math.pi / 4)))
    est = estimate_time(one_groove([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]]), 0.08, MILL,
                        accel=A, junction_deviation=delta)
    brake = (10.0 - v) / A, (100.0 - v * v) / (2 * A)  # seconds, mm from 10 mm/s to v
    leg = 0.1 + (10.0 - 0.5 - brake[1]) / 10.0 + brake[0]
    assert est.cutting_s == pytest.approx(2 * leg)
    # turning back on itself stops dead: two separate 10 mm moves
    est = estimate_time(one_groove([[0.0, 0.0], [10.0, 0.0], [0.0, 0.0]]), 0.08, MILL, accel=A)
    assert est.cutting_s == pytest.approx(2 * 1.1)


def test_time_on_a_tight_arc():
    # a half circle of radius 1 mm: centripetal a r caps the speed at 10 mm/s
    # even at a feed of 20 mm/s; length pi
    fast = Machining(feed=1200.0, plunge=100.0, safe_z=1.0, spindle=0.0)
    est = estimate_time(one_groove([[0.0, 0.0], [2.0, 0.0]], [1.0, 0.0]), 0.08, fast, accel=A)
    assert est.cutting_s == pytest.approx(math.pi / 10 + 0.1)


def test_time_of_a_laser_and_of_nothing():
    g = Grooves.concatenate([one_groove([[30.0, 0.0], [40.0, 0.0]], stipple=1),
                             one_groove([[40.0, 0.0]], stipple=2),
                             one_groove([[40.0, 0.0]], stipple=2)])
    est = estimate_time(g, 0.08, MILL, accel=A, laser=True, dot_time=0.25)
    assert est.plunge_s == 0.0 and est.dwell_s == 0.5
    assert est.rapid_s == pytest.approx(1.1)  # no retracts; the dots are where the cut ends
    assert est.stipples == 2
    empty = estimate_time(Grooves.empty(), 0.08, MILL, dwell=2.0)
    assert empty.total_s == 0.0 and empty.stipples_per_s == 0.0


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"accel": 0.0}, "acceleration must be a finite number > 0, got 0"),
    ({"rapid": -5.0}, "rapid rate must be a finite number > 0, got -5"),
    ({"dwell": math.inf}, "dwell must be a finite number >= 0, got inf"),
])
def test_time_rejects_bad_values(kwargs, message):
    with pytest.raises(SpecholoError, match=re.escape(message)):
        estimate_time(one_groove([[0.0, 0.0], [1.0, 0.0]]), 0.08, MILL, **kwargs)


def test_ordering_saves_time():
    rng = np.random.default_rng(2)
    n = 500
    start = rng.uniform(-50, 50, (n, 2))
    g = Grooves(np.stack([start, start + rng.normal(0, 1, (n, 2))], 1).reshape(-1, 2),
                np.zeros(2 * n), np.arange(0, 2 * n + 1, 2), np.arange(n) // 2)
    out, _ = order_paths(g)
    before, after = estimate_time(g, 0.08, NO_HOPS), estimate_time(out, 0.08, NO_HOPS)
    assert after.rapid_s < 0.5 * before.rapid_s  # short hops are bound by the acceleration
    assert after.cutting_s == pytest.approx(before.cutting_s)
    assert after.plunge_s == pytest.approx(before.plunge_s)
    assert after.stipples == before.stipples == n // 2
    # the order also brings grooves within a hop of each other: fewer full plunges
    hopping = estimate_time(out, 0.08, MILL)
    assert hopping.hops > estimate_time(g, 0.08, MILL).hops
    assert hopping.plunge_s < after.plunge_s and hopping.total_s < after.total_s


def test_time_of_a_hop():
    # 10 mm cut, a hop of 1 mm (within 3 mm), another 10 mm cut
    g = Grooves.concatenate([one_groove([[0.0, 0.0], [10.0, 0.0]], stipple=1),
                             one_groove([[11.0, 0.0], [21.0, 0.0]], stipple=2)])
    est = estimate_time(g, 0.08, MILL, accel=A)
    assert est.hops == 1
    assert est.cutting_s == pytest.approx(2 * 1.1)
    # the hop: 1 mm at the feed, 10 mm/s, just reached halfway: 2 sqrt(1 / 100)
    assert est.hop_s == pytest.approx(0.2)
    # plunges from the safe height, 1.08 mm, and from the hop height, 0.11 mm,
    # both reaching 5/3 mm/s over 1/72 mm
    assert est.plunge_s == pytest.approx((1.08 + 0.11) * 0.6 + 2 * (5 / 3) / A)
    # no travel to the first groove (it starts at the origin); a retract of
    # 0.11 mm to the hop height and the last one of 1.08 mm, never at 50 mm/s
    assert est.rapid_s == pytest.approx(2 * math.sqrt(0.11 / A) + 2 * math.sqrt(1.08 / A))
    assert est.total_s == pytest.approx(est.cutting_s + est.hop_s + est.plunge_s + est.rapid_s)
    # without hops: a rapid of 1 mm and full retracts and plunges
    full = estimate_time(g, 0.08, NO_HOPS, accel=A)
    assert full.hops == 0 and full.hop_s == 0.0
    assert full.plunge_s == pytest.approx(2 * (1.08 * 0.6 + (5 / 3) / A))
    assert full.rapid_s == pytest.approx(2 * math.sqrt(1 / A) + 2 * 2 * math.sqrt(1.08 / A))
    # a laser never hops: it has no Z
    assert estimate_time(g, 0.08, MILL, accel=A, laser=True).hops == 0


def test_estimate_hops_where_the_writer_does(tmp_path):
    # the next groove at exactly the longest hop is hopped onto, a hair further is not
    g = Grooves.concatenate([one_groove([[0.0, 0.0], [2.0, 0.0]]),
                             one_groove([[5.0, 0.0], [6.0, 0.0]]),
                             one_groove([[9.0 + 1e-9, 0.0], [10.0, 0.0]]),
                             one_groove([[10.5, 0.0]])])
    est = estimate_time(g, 0.08, MILL)
    stats = write_gcode(tmp_path / "x.ngc", g, Tool(), MILL)
    lines = (tmp_path / "x.ngc").read_text().splitlines()
    hops = [ln for ln, before in zip(lines[1:], lines, strict=False)
            if before.startswith("(stipple") and ln.startswith("G1 X")]
    assert hops == ["G1 X5.00000 Y0.00000 F600.00000", "G1 X10.50000 Y0.00000 F600.00000"]
    assert est.hops == stats.hops == 2
    assert stats.hop_length_mm == pytest.approx(3.5)
    rnd = _random_strokes(6, 300)
    ordered, _ = order_paths(rnd)
    stats = write_gcode(tmp_path / "r.ngc", ordered, Tool(), MILL)
    assert stats.hops == estimate_time(ordered, 0.08, MILL).hops > 0


def _random_strokes(seed: int, n: int) -> Grooves:
    """n short arcs and dots scattered over a 100 mm plate, in random order."""
    rng = np.random.default_rng(seed)
    sizes = rng.integers(1, 5, n)
    start = rng.uniform(-50.0, 50.0, (n, 2))
    verts = np.repeat(start, sizes, axis=0) + rng.normal(0.0, 0.4, (int(sizes.sum()), 2))
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    bulges = rng.uniform(-0.5, 0.5, len(verts))
    bulges[offsets[1:] - 1] = 0.0
    return Grooves(verts, bulges, offsets, rng.integers(0, 50, n))


def test_a_large_plate_is_ordered_a_tile_at_a_time(monkeypatch):
    import specholo.fabrication.programs.order as order_module

    g = _random_strokes(3, 600)
    whole, whole_stats = order_paths(g)
    monkeypatch.setattr(order_module, "TILE_PATHS", 40)
    out, stats = order_paths(g)
    check(g, out, stats)
    # 15 tiles in a serpentine: far less travel than the given order, and within
    # a third of the tour over the whole plate at once.
    assert stats.travel_after_mm < 0.15 * stats.travel_before_mm
    assert stats.travel_after_mm < 1.35 * whole_stats.travel_after_mm


def test_large_grooves_are_reordered_in_place(monkeypatch, tmp_path):
    import specholo.fabrication.programs.order as order_module

    g = _random_strokes(4, 300)
    copy = Grooves(g.vertices.copy(), g.bulges.copy(), g.offsets.copy(), g.stipple.copy())
    expected, expected_stats = order_paths(copy)
    monkeypatch.setattr(order_module, "IN_PLACE_BYTES", 0)
    monkeypatch.setattr(order_module, "_BLOCK_PATHS", 2)
    monkeypatch.setattr(order_module, "_READ_VALUES", 7)
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    out, stats = order_paths(g, scratch=scratch)
    assert out is g and stats == expected_stats
    for name in ("vertices", "bulges", "offsets", "stipple"):
        assert np.array_equal(getattr(out, name), getattr(expected, name)), name
    check(copy, out, stats)
    assert list(scratch.iterdir()) == []  # the scratch files are gone
    # Arrays that cannot be written are copied, and left as they were.
    ro = Grooves(copy.vertices.copy(), copy.bulges.copy(), copy.offsets.copy(),
                 copy.stipple.copy())
    for a in (ro.vertices, ro.bulges, ro.offsets, ro.stipple):
        a.flags.writeable = False
    out2, _ = order_paths(ro, scratch=scratch)
    assert out2 is not ro and np.array_equal(ro.vertices, copy.vertices)
    assert np.array_equal(out2.vertices, expected.vertices)


def test_travel_and_time_summed_a_block_of_paths_at_a_time(monkeypatch):
    import specholo.fabrication.programs.order as order_module
    import specholo.fabrication.programs.timing as timing_module

    g = _random_strokes(5, 50)
    ordered, stats = order_paths(g)
    machining = Machining(feed=300.0, plunge=100.0, safe_z=1.0, spindle=0.0)
    whole = (travel(g), travel(ordered), estimate_time(g, 0.05, machining))
    for hops in (1, 3, 7):
        monkeypatch.setattr(order_module, "HOPS", hops)
        monkeypatch.setattr(timing_module, "HOPS", hops)
        assert travel(g) == pytest.approx(whole[0], rel=1e-13)
        assert order_module._travel(g.vertices, g.offsets, *_order_of(g, ordered)) == \
            pytest.approx(whole[1], rel=1e-13)
        estimate = estimate_time(g, 0.05, machining)
        assert estimate.rapid_s == pytest.approx(whole[2].rapid_s, rel=1e-13)
        assert estimate.total_s == pytest.approx(whole[2].total_s, rel=1e-13)
    assert stats.travel_after_mm == pytest.approx(whole[1], rel=1e-13)
    assert travel_length(np.zeros((0, 2)), np.zeros((0, 2))) == 0.0


def _order_of(g: Grooves, out: Grooves) -> tuple[np.ndarray, np.ndarray]:
    """Which path of g each path of out is, and whether it is cut backwards."""
    starts, ends = g.vertices[g.offsets[:-1]], g.vertices[g.offsets[1:] - 1]
    order, flip = [], []
    for j in range(out.n_paths):
        a, b = out.vertices[out.offsets[j]], out.vertices[out.offsets[j + 1] - 1]
        fwd = np.flatnonzero((starts == a).all(1) & (ends == b).all(1) & ~np.isin(
            np.arange(g.n_paths), order))
        if len(fwd):
            order.append(int(fwd[0]))
            flip.append(False)
        else:
            back = np.flatnonzero((starts == b).all(1) & (ends == a).all(1) & ~np.isin(
                np.arange(g.n_paths), order))
            order.append(int(back[0]))
            flip.append(True)
    return np.array(order), np.array(flip)
