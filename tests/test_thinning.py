"""Thinning a crowded plate: every cut that removes a glint is found, and the
stipples left uncut are those whose grooves take more glints than they show."""

from __future__ import annotations

import json
import math

import numpy as np

from specholo.jobs.flat.folder import DesignConfig, design
from specholo.simulation.survival import (
    EyeGlints,
    conflicts,
    survivors,
    verify_as_cut,
)
from specholo.simulation.thinning import thin
from specholo.simulation.verify import view_azimuths
from tests.test_survival import BALL, DEPTH, grooves, wall_point

R = BALL.radius


def test_conflicts_name_every_cut_that_removes_a_glint_and_only_those() -> None:
    """Glints along groove A (stipple 0); B (stipple 1) crosses it at x = 0 and C
    (stipple 2) at x = 2. A glint is in a pair with B or C exactly when that
    groove's ball passes within R of it, and survives exactly when in no pair."""
    tilt = math.radians(20.0)
    xs = np.linspace(-1.0, 3.0, 81)
    pts = np.stack([wall_point(tilt) + [x, 0.0, 0.0] for x in xs])
    g = grooves(([[-5.0, 0.0], [5.0, 0.0]], [0.0, 0.0]),
                ([[0.0, -5.0], [0.0, 5.0]], [0.0, 0.0]),
                ([[2.0, -5.0], [2.0, 5.0]], [0.0, 0.0]))
    point, path = conflicts(g, pts, np.zeros(len(pts), dtype=np.int64), BALL, DEPTH)
    centre_z = R - DEPTH
    for x_line, q in ((0.0, 1), (2.0, 2)):
        dist = np.hypot(pts[:, 0] - x_line, pts[:, 2] - centre_z)
        mine = np.sort(point[path == q])
        assert np.array_equal(mine, np.flatnonzero(dist < R)), q
        assert mine.size > 0
    assert not np.any(path == 0)  # a groove never removes its own glints
    kept = survivors(g, pts, np.zeros(len(pts), dtype=np.int64), BALL, DEPTH)
    assert np.array_equal(kept, ~np.isin(np.arange(len(pts)), point))


def _eye_glints(points: list[np.ndarray], paths: list[int], stipples: list[int],
                azimuths: int) -> EyeGlints:
    """The same glints for the left and the right eye of every azimuth."""
    pts = np.stack(points)
    k = azimuths
    eye = (np.zeros(3), np.zeros(3))
    return EyeGlints(np.zeros(k), [eye] * k, np.full(2 * k, len(pts), dtype=np.int64),
                     np.tile(pts, (2 * k, 1)), np.tile(np.array(paths), 2 * k),
                     np.tile(np.array(stipples), 2 * k))


def test_the_groove_crossing_two_others_glints_is_left_uncut() -> None:
    """Stipples 0 and 1 run along y = 0 and y = 1; stipple 2 runs across both at
    x = 0, where all three have their glints. As cut every glint is inside
    another cut and no stipple shows; without stipple 2's groove, 0 and 1 both
    show in every view, so thinning leaves 2 (and only 2) uncut."""
    tilt = math.radians(20.0)
    on_a = wall_point(tilt)
    on_b = on_a + [0.0, 1.0, 0.0]
    # On C's wall (along y), near where A crosses it.
    on_c = np.array([R * math.sin(tilt), 0.0, on_a[2]])
    g = grooves(([[-3.0, 0.0], [3.0, 0.0]], [0.0, 0.0]),
                ([[-3.0, 1.0], [3.0, 1.0]], [0.0, 0.0]),
                ([[0.0, -3.0], [0.0, 4.0]], [0.0, 0.0]))
    k = 3
    gl = _eye_glints([on_a, on_b, on_c], [0, 1, 2], [0, 1, 2], k)
    seen = np.ones((k, 3), dtype=bool)
    assert not survivors(g, gl.point, gl.path, BALL, DEPTH).any()
    th = thin(g, gl, seen, BALL, DEPTH)
    assert th.keep.tolist() == [True, True, False]
    assert th.left_uncut.tolist() == [2]
    assert (th.shown_all, th.shown) == (0, 2 * k)
    # What the kept stipples show is what their grooves alone leave.
    alone = g.take(np.array([0, 1]))
    mine = gl.stipple < 2
    assert np.array_equal(th.alive[mine], survivors(alone, gl.point[mine], gl.path[mine],
                                                    BALL, DEPTH))
    assert not th.alive[~mine].any()


def test_grooves_that_cost_nothing_are_all_cut() -> None:
    """Two grooves that cross away from every glint: nothing to gain, all kept."""
    tilt = math.radians(20.0)
    g = grooves(([[-3.0, 0.0], [3.0, 0.0]], [0.0, 0.0]), ([[2.0, -3.0], [2.0, 3.0]], [0.0, 0.0]))
    on_b = np.array([2.0 + R * math.sin(tilt), -2.0, wall_point(tilt)[2]])
    gl = _eye_glints([wall_point(tilt), on_b], [0, 1], [0, 1], 2)
    th = thin(g, gl, np.ones((2, 2), dtype=bool), BALL, DEPTH)
    assert th.keep.all() and th.shown == th.shown_all == 4


CROWDED = dict(size=20.0, center_z=-15.0, stipples=1200, placement="phase")


def test_a_crowded_design_is_thinned_and_shows_more_as_cut() -> None:
    """On a crowded 20 mm bunny the design leaves uncut the stipples thinning
    picks: the thinned plate as cut (checked again by the survival test on the
    grooves it keeps) shows more stipples in both eyes than the plate with
    every stipple cut, and the stipples left uncut have no path."""
    whole = design("examples/bunny.obj", DesignConfig(**CROWDED, thin="off"))
    thinned = design("examples/bunny.obj", DesignConfig(**CROWDED))
    assert whole.thinned is None and thinned.thinned is not None
    gone = thinned.thinned
    assert len(gone) > 0 and not np.isin(gone, thinned.grooves.stipple).any()
    assert np.isin(gone, whole.grooves.stipple).all()
    assert thinned.coverage.thinned == len(gone)

    def points(d: object) -> float:
        return float(np.mean([r.visibility * r.stipples_seen for r in d.as_cut.reports]))

    assert points(thinned) > 1.02 * points(whole)
    t = thinned.thinning
    assert t["stereo_points_thinned"] == points(thinned)
    assert t["stereo_points_all_cut"] == points(whole)
    setup = thinned.config.setup()
    az = view_azimuths(setup.viewer.half_range, math.radians(5.0))
    again = verify_as_cut(thinned.grooves, thinned.points, setup, thinned.config.cutter(),
                          thinned.config.depth_mm, azimuths=az)
    assert np.array_equal(again.surviving, thinned.as_cut.surviving)


def test_a_sparse_design_keeps_every_stipple() -> None:
    """Where thinning would gain under 2% of the stereo points, auto cuts them all."""
    cfg = dict(size=40.0, center_z=-20.0, stipples=150)
    auto = design("examples/bunny.obj", DesignConfig(**cfg))
    off = design("examples/bunny.obj", DesignConfig(**cfg, thin="off"))
    assert auto.thinned is None
    assert np.array_equal(auto.grooves.vertices, off.grooves.vertices)
    assert auto.thinning is not None and not auto.thinning["thinned"]


def test_the_folder_and_the_report_say_which_stipples_were_left_uncut(tmp_path, capsys) -> None:
    """`specholo design` on the crowded bunny: the summary says how many it left
    uncut and what the plate shows with and without them; hologram.json lists
    them, the written grooves and G-code hold none of their paths, and the
    report page names them. `--thin off` cuts every stipple."""
    from specholo.toolpaths.grooves import Grooves
    from specholo_cli.cli import main

    base = ["design", "examples/bunny.obj", "--size", "20", "--center-z", "-15",
            "--stipples", "1200", "--placement", "phase", "--formats", "gcode"]
    out = tmp_path / "thin"
    assert main([*base, "--out", str(out)]) == 0
    said = capsys.readouterr().out
    info = json.loads((out / "hologram.json").read_text())
    gone = info["stats"]["thinned_stipples"]
    assert gone and info["stats"]["thinning"]["thinned"]
    line = next(ln for ln in said.splitlines() if ln.startswith("thinned: "))
    assert line.startswith(f"thinned: {len(gone)} of ")
    t = info["stats"]["thinning"]
    assert f"shows {t['stereo_points_thinned']:.0f} stipples" in line
    assert t["stereo_points_thinned"] > t["stereo_points_all_cut"]
    assert not np.isin(gone, Grooves.load(str(out / "grooves.npz")).stipple).any()
    assert info["stats"]["paths"] == Grooves.load(str(out / "grooves.npz")).n_paths
    assert main(["report", str(out)]) == 0
    capsys.readouterr()
    assert f"{len(gone):,} stipples whose glints" in (out / "report.html").read_text()
    whole = tmp_path / "whole"
    assert main([*base, "--out", str(whole), "--thin", "off"]) == 0
    assert "thinned:" not in capsys.readouterr().out
    info = json.loads((whole / "hologram.json").read_text())
    assert info["stats"]["thinned_stipples"] == [] and info["stats"]["thinning"] is None
    assert info["stats"]["paths"] > Grooves.load(str(out / "grooves.npz")).n_paths


def test_verify_says_the_stipples_left_uncut_count_as_not_shown(tmp_path, capsys) -> None:
    """`specholo verify` on a thinned folder says how many stipples the design
    left uncut, which its figures count as not shown."""
    from specholo_cli.cli import main

    out = tmp_path / "thin"
    assert main(["design", "examples/bunny.obj", "--size", "20", "--center-z", "-15",
                 "--stipples", "1200", "--placement", "phase", "--formats", "gcode",
                 "--out", str(out)]) == 0
    capsys.readouterr()
    gone = json.loads((out / "hologram.json").read_text())["stats"]["thinned_stipples"]
    assert main(["verify", str(out)]) == 0
    said = capsys.readouterr().out
    assert (f"{len(gone)} stipples were left uncut by thinning (their glints would be cut "
            "away) and count as not shown") in said
