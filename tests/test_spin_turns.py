"""A view that circles the scene several times per plate turn: stipples sliding over
the turning scene on open grooves (the paper's 720-degree holograms)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import trimesh
from test_gcode import check_canon, needs_rs274, run_rs274

from specholo.jobs.spin.design import (
    SpinConfig,
    design_spin,
    load_spin_folder,
    verify_spin,
    write_spin,
)
from specholo.scene.loading import load_model
from specholo.scene.placement import place
from specholo.setup import Machining, Tool
from specholo.simulation.spinning import find_spin_glints, verify_spinning
from specholo.toolpaths.sliding import design_sliding, eye_gap, scene_angle, slide_tracks
from specholo.toolpaths.spinning import SpinSetup, crossings, rotate_z
from specholo_cli.cli import main

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
BUNNY = EXAMPLES / "bunny.obj"
KNOT = EXAMPLES / "knot.obj"
TOOL = Tool()


def _mesh(path: Path) -> trimesh.Trimesh:
    mesh = place(load_model(path), 40.0, 0.0).mesh
    assert mesh is not None
    return mesh.to_trimesh()


@pytest.fixture(scope="module")
def two_scenes() -> tuple[list[trimesh.Trimesh], object]:
    meshes = [_mesh(BUNNY), _mesh(KNOT)]
    tracks = slide_tracks(meshes, SpinSetup(), 2, 120, np.random.default_rng(3))
    return meshes, design_sliding(tracks, SpinSetup(), TOOL)


def test_tracks_lie_on_the_turning_scene_and_slide_along_sightlines(two_scenes) -> None:
    meshes, d = two_scenes
    t = d.tracks
    assert len(t) > 100
    n, k = t.alive.shape
    rows, cols = np.nonzero(t.alive)
    for s, mesh in enumerate(meshes):
        sel = t.scene[rows] == s
        # in the scene's own frame (turned back by (T - 1) phi) the point is on its surface
        u = rotate_z(t.position[rows[sel], cols[sel]], -scene_angle(2, t.phi[cols[sel]]))
        _, dist, _ = trimesh.proximity.closest_point(mesh, u[::7])
        assert np.percentile(dist, 99) < 1e-6
        # and not on the surface left unturned: the scene really turns under the plate
        _, far, _ = trimesh.proximity.closest_point(mesh, t.position[rows[sel], cols[sel]][::7])
        assert np.median(far) > 0.3
    # from one angle to the next a point moves along its sightline (the groove condition)
    mid = SpinSetup().world_eyes().mean(axis=0)
    both = t.alive[:, :-1] & t.alive[:, 1:]
    r, c = np.nonzero(both)
    step = t.position[r, c + 1] - t.position[r, c]
    eye = rotate_z(np.broadcast_to(mid, (len(c), 3)), -(t.phi[c] + 0.5 * (t.phi[1] - t.phi[0])))
    sight = eye - t.position[r, c]
    sight /= np.linalg.norm(sight, axis=1, keepdims=True)
    across = np.linalg.norm(step - (step * sight).sum(1, keepdims=True) * sight, axis=1)
    assert np.percentile(across, 99) < 1e-6
    assert np.percentile(np.linalg.norm(step, axis=1), 90) > 1e-3  # they do move


def test_each_scene_owns_its_half_turn_and_glints_lie_on_sightlines(two_scenes) -> None:
    _, d = two_scenes
    t = d.tracks
    shown = t.shown
    half = len(t.phi) // 2
    assert np.all(~shown[t.scene == 0][:, half + 1:-1])  # the bunny is not shown after 180
    assert np.all(~shown[t.scene == 1][:, 1:half - 1])   # nor the knot before it
    setup = d.setup
    for deg in (40.0, 130.0, 220.0, 310.0):
        phi = np.radians([deg])
        pos, live, meant = t.at(phi)
        eyes = setup.eyes(phi)
        for e in range(2):
            gl = find_spin_glints(d, eyes[e, 0], TOOL)
            s = gl.stipple[gl.serving]
            ok = live[s, 0]
            assert ok.mean() > 0.98
            # the glint is where this eye's sightline through the sliding point meets
            # the plate, and its tangent mirrors the light into the eye
            want = crossings(eyes[e, 0][None], pos[s[ok], 0])
            miss = np.linalg.norm(gl.point[gl.serving][ok, :2] - want[:, :2], axis=1)
            # (a least-squares compromise between the eyes at 600 mm, as for closed grooves)
            assert np.percentile(miss, 95) < 0.3
            x = gl.point[gl.serving]
            n = setup.half_vectors(x, np.broadcast_to(eyes[e, 0], x.shape))
            n /= np.linalg.norm(n, axis=1, keepdims=True)
            out = 2 * n[:, 2:3] * n - np.array([0.0, 0.0, 1.0])
            to_eye = eyes[e, 0] - x
            np.testing.assert_allclose(out, to_eye / np.linalg.norm(to_eye, axis=1,
                                                                    keepdims=True), atol=1e-9)


def test_verification_by_angle(two_scenes) -> None:
    _, d = two_scenes
    reps = verify_spinning(d, TOOL, np.arange(0.0, 360.0, 10.0))
    assert all(r.shown > 40 for r in reps)
    assert min(r.visibility for r in reps) > 0.97
    assert max(r.p95_mm for r in reps) < 0.8
    assert sum(r.stray for r in reps) < 0.03 * sum(r.shown for r in reps)


def test_error_falls_with_distance() -> None:
    mesh = _mesh(BUNNY)
    worst = []
    for dist in (600.0, 2000.0):
        setup = SpinSetup(distance=dist)
        t = slide_tracks([mesh], setup, 2, 80, np.random.default_rng(1))
        d = design_sliding(t, setup, TOOL)
        reps = verify_spinning(d, TOOL, np.arange(0.0, 360.0, 30.0))
        worst.append(max(r.p95_mm for r in reps))
    assert worst[1] < 0.6 * worst[0] and worst[0] < 0.8


def test_one_model_circles_continuously() -> None:
    """One model for both circuits: no hand-over, the same scene all the way round."""
    setup = SpinSetup()
    t = slide_tracks([_mesh(BUNNY)], setup, 2, 80, np.random.default_rng(2))
    d = design_sliding(t, setup, TOOL)
    assert set(np.unique(t.scene)) == {0}
    reps = verify_spinning(d, TOOL, np.arange(0.0, 360.0, 45.0))
    assert min(r.visibility for r in reps) > 0.97
    # some lives run across 0 degrees, where a hand-over would cut them
    assert (d.tracks.shown[:, 0] & d.tracks.shown[:, -1]).sum() > 5
    assert eye_gap(setup) == pytest.approx(2 * math.atan(32 / (600 * math.cos(math.pi / 4))))


@needs_rs274
def test_folder_gcode_parses_and_reverifies(tmp_path: Path) -> None:
    cfg = SpinConfig(stipples=60, turns=2, setup=SpinSetup(), tool=TOOL)
    job = design_spin([BUNNY, KNOT], cfg, np.random.default_rng(0))
    out = tmp_path / "out"
    summary = write_spin(job, out, step_deg=30.0, frames=0)
    check_canon(run_rs274(out / "hologram.gcode"), job.design.grooves, TOOL, Machining())
    again = load_spin_folder(out)
    reps = verify_spin(again, 30.0)
    assert max(r.p95_mm for r in reps) == pytest.approx(summary["worst_p95_mm"], abs=1e-12)
    meta = json.loads((out / "hologram.json").read_text())
    assert meta["sliding"]["scenes"] == 2 and meta["settings"]["turns"] == 2


def test_cli_two_models(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "spin"
    rc = main(["spin", str(BUNNY), str(KNOT), "--out", str(out), "--stipples", "60",
               "--frames", "2", "--step", "45"])
    assert rc == 0
    ver = json.loads((out / "verify.json").read_text())
    assert len(ver["angles"]) == 8 and ver["summary"]["lowest_visibility"] > 0.95
    assert "shown at once" in capsys.readouterr().out
    assert (out / "preview.gif").stat().st_size > 0


@pytest.mark.parametrize("models, args, message", [
    ([BUNNY, KNOT], ["--turns", "3"], "one per turn"),
    ([BUNNY, KNOT], ["--turns", "1"], "one model"),
    ([BUNNY], ["--turns", "9"], "turns"),
    ([EXAMPLES / "README.md"], ["--turns", "2"], ""),
])
def test_cli_bad_turns(tmp_path: Path, capsys: pytest.CaptureFixture[str], models: list[Path],
                       args: list[str], message: str) -> None:
    out = tmp_path / "spin"
    rc = main(["spin", *map(str, models), "--out", str(out), "--stipples", "30",
               "--frames", "0", *args])
    err = capsys.readouterr().err.strip()
    assert rc != 0 and message in err and len(err.splitlines()) == 1
    assert not out.exists()
