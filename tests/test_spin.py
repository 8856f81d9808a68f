"""Turning plates: closed grooves checked by the simulator over the whole turn."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from test_gcode import check_canon, needs_rs274, run_rs274

from specholo.jobs.spin.design import SpinConfig, design_spin, write_spin
from specholo.optics.stereo import triangulate
from specholo.setup import Machining, Tool
from specholo.simulation.spinning import find_spin_glints, verify_spinning
from specholo.toolpaths.spinning import (
    RELIEF_ANGLE,
    SpinSetup,
    design_spinning,
    max_wall_tilt,
    relief_grooves,
    rotate_z,
)
from specholo_cli.cli import main

BUNNY = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"
TOOL = Tool(0.25, 0.08)


def _points(n: int, rng: np.random.Generator, rad: float = 30.0, depth: float = 15.0
            ) -> np.ndarray:
    r = rad * np.sqrt(rng.uniform(0, 1, n))
    a = rng.uniform(0, 2 * np.pi, n)
    z = rng.uniform(-depth, depth, n)
    z = np.where(np.abs(z) < 1.0, np.sign(z + 1e-9) * 1.0, z)
    return np.stack([r * np.cos(a), r * np.sin(a), z], axis=1)


def test_far_viewer_gets_exact_circles() -> None:
    """Eyes far away, light on the axis: the groove is the circle of radius
    |z| cot(elevation) about the stipple's foot, and both eyes triangulate the
    stipple at every plate angle."""
    rng = np.random.default_rng(1)
    pts = _points(40, rng)
    setup = SpinSetup(distance=2e6, ipd=64.0 * 2e6 / 600.0, walls="one")
    d = design_spinning(pts, setup, TOOL)
    v = d.grooves.vertices.reshape(len(pts), -1, 2)
    centre = v[:, :-1].mean(axis=1)
    radius = np.linalg.norm(v[:, :-1] - centre[:, None], axis=2)
    np.testing.assert_allclose(centre, pts[:, :2], atol=1e-3)
    e = setup.world_eyes()[0]  # both eyes make the same angle with the plate
    cot = math.hypot(e[0], e[1]) / e[2]
    np.testing.assert_allclose(radius, np.abs(pts[:, 2:3]) * cot * np.ones_like(radius),
                               rtol=1e-4)
    reps = verify_spinning(d, TOOL, np.arange(0, 360, 15.0))
    assert max(r.p95_mm for r in reps) < 0.02
    assert min(r.visibility for r in reps) == 1.0
    assert sum(r.stray for r in reps) == 0


def test_finite_distance_error_small_and_falls_with_distance() -> None:
    rng = np.random.default_rng(2)
    pts = _points(150, rng)
    worst = []
    for dist in (600.0, 1500.0):
        d = design_spinning(pts, SpinSetup(distance=dist), TOOL)
        reps = verify_spinning(d, TOOL, np.arange(0, 360, 20.0))
        assert min(r.visibility for r in reps) == 1.0
        worst.append(max(r.p95_mm for r in reps))
    assert worst[0] < 1.0
    assert worst[1] < 0.5 * worst[0]


def test_glint_lies_on_the_sightline_and_mirrors_light_into_eye() -> None:
    """Each serving glint sits where the groove's tangent is perpendicular to the
    half vector, close to the eye's sightline through the stipple."""
    rng = np.random.default_rng(3)
    pts = _points(60, rng)
    setup = SpinSetup(distance=900.0)
    d = design_spinning(pts, setup, TOOL)
    for phi in np.radians([0.0, 100.0, 230.0]):
        eye = setup.eyes(np.array([phi]))[0, 0]
        gl = find_spin_glints(d, eye, TOOL)
        assert len(gl.point) == len(pts)
        p = pts[gl.stipple]
        # sightline crossing for this eye
        t = eye[2] / (eye[2] - p[:, 2])
        cross = eye + (p - eye) * t[:, None]
        assert np.percentile(np.linalg.norm(gl.point - cross, axis=1), 95) < 0.6
        # the ball wall there: its normal is h (the tilt is within the wall); the
        # reflected light goes to the eye
        h = setup.half_vectors(gl.point, np.broadcast_to(eye, gl.point.shape))
        n = h / np.linalg.norm(h, axis=1, keepdims=True)
        light = np.array([0.0, 0.0, 1.0])
        out = 2 * (n @ light)[:, None] * n - light
        to_eye = eye - gl.point
        to_eye /= np.linalg.norm(to_eye, axis=1, keepdims=True)
        np.testing.assert_allclose(out, to_eye, atol=1e-9)
        assert np.all(np.arctan2(np.hypot(n[:, 0], n[:, 1]), n[:, 2]) <= max_wall_tilt(TOOL))


def test_plain_grooves_show_the_mirror_twin() -> None:
    """Both walls kept: every stipple also shows, at the same time, its mirror
    image through the plate (far viewer, where the twin is exact)."""
    rng = np.random.default_rng(4)
    pts = _points(30, rng)
    setup = SpinSetup(distance=2e6, ipd=64.0 * 2e6 / 600.0, walls="both")
    d = design_spinning(pts, setup, TOOL)
    eyes = setup.eyes(np.array([0.7]))[:, 0]
    g = [find_spin_glints(d, e, TOOL) for e in eyes]
    for gl in g:
        assert (~gl.serving).sum() == len(pts)
    twins = []
    for gl in g:
        order = np.argsort(gl.stipple[~gl.serving])
        twins.append(gl.point[~gl.serving][order])
    p = triangulate(np.broadcast_to(eyes[0], twins[0].shape), twins[0],
                    np.broadcast_to(eyes[1], twins[1].shape), twins[1])[0]
    mirror = pts * np.array([1.0, 1.0, -1.0])
    np.testing.assert_allclose(p, mirror, atol=0.05)
    reps = verify_spinning(d, TOOL, np.array([0.0, 90.0]))
    assert all(r.stray == 2 * len(pts) for r in reps)
    # the relief cut removes them
    reps = verify_spinning(d, TOOL, np.array([0.0, 90.0]), walls="one")
    assert all(r.stray == 0 for r in reps)


def test_relief_cut_leaves_no_serving_tilt_on_the_other_wall() -> None:
    """Across the other wall, the union of ball groove and V relief keeps only
    tilts below the relief tilt (the floor) or steeper than the V's face."""
    rng = np.random.default_rng(5)
    d = design_spinning(_points(10, rng), SpinSetup(), TOOL)
    relief, depth = relief_grooves(d, TOOL)
    assert relief.n_paths == d.grooves.n_paths
    r, dd = TOOL.radius, TOOL.depth
    half = math.sqrt(2 * r * dd - dd * dd)
    # offset of each relief vertex from its groove vertex is the half width
    np.testing.assert_allclose(np.linalg.norm(relief.vertices - d.grooves.vertices, axis=1),
                               half, rtol=1e-9)
    u = np.linspace(0.0, 2 * half, 20001)
    ball = np.where(u <= half, -dd + r - np.sqrt(np.maximum(r * r - u * u, 0)), 0.0)
    vee = -depth + np.abs(u - half) / math.tan(0.5 * RELIEF_ANGLE)
    surf = np.minimum(ball, np.minimum(vee, 0.0))
    tilt = np.degrees(np.arctan(np.abs(np.gradient(surf, u))))
    lo, hi = (math.degrees(t) for t in d.tilts)
    served = (tilt >= lo - 0.5) & (tilt <= hi + 0.5)
    assert not served.any()
    assert math.degrees(d.relief_tilt) < lo


@needs_rs274
def test_gcode_parses_and_cuts_the_grooves(tmp_path: Path) -> None:
    cfg = SpinConfig(stipples=120, setup=SpinSetup(), tool=TOOL)
    job = design_spin(BUNNY, cfg, np.random.default_rng(0))
    summary = write_spin(job, tmp_path / "out", step_deg=30.0, frames=0)
    assert summary["stray"] == 0
    check_canon(run_rs274(tmp_path / "out" / "hologram.gcode"), job.design.grooves, TOOL,
                Machining())
    relief, depth = relief_grooves(job.design, TOOL)
    check_canon(run_rs274(tmp_path / "out" / "relief.gcode"), relief,
                Tool(max(depth, TOOL.radius), depth), Machining())


def test_occlusion_crops_hidden_views() -> None:
    cfg = SpinConfig(stipples=300, setup=SpinSetup(), tool=TOOL)
    job = design_spin(BUNNY, cfg, np.random.default_rng(0))
    g = job.design.grooves
    closed = np.linalg.norm(g.vertices[g.offsets[1:] - 1] - g.vertices[g.offsets[:-1]],
                            axis=1) < 1e-9
    assert (~closed).sum() > 0 and closed.sum() > 0
    from specholo.jobs.spin.design import verify_spin

    reps = verify_spin(job, 15.0)
    assert sum(r.stray for r in reps) == 0
    assert min(r.visibility for r in reps) > 0.8
    assert max(r.p95_mm for r in reps) < 1.0


def test_cli_writes_a_verified_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                      ) -> None:
    out = tmp_path / "spin"
    rc = main(["spin", str(BUNNY), "--out", str(out), "--stipples", "150",
               "--frames", "4", "--step", "30"])
    assert rc == 0
    meta = json.loads((out / "hologram.json").read_text())
    ver = json.loads((out / "verify.json").read_text())
    assert meta["design"] == "spin" and len(ver["angles"]) == 12
    assert ver["summary"]["stray"] == 0
    assert (out / "preview.gif").stat().st_size > 0
    assert (out / "relief.gcode").exists()


@pytest.mark.parametrize("args, message", [
    (["--view-elevation", "95"], "elevation"),
    (["--view-distance", "-3"], "distance"),
    (["--depth", "0.001"], "wall tilts"),
    (["--step", "0"], "step"),
])
def test_cli_bad_input(tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str],
                       message: str) -> None:
    out = tmp_path / "spin"
    rc = main(["spin", str(BUNNY), "--out", str(out), "--stipples", "50",
               "--frames", "0", *args])
    err = capsys.readouterr().err.strip()
    assert rc != 0 and message in err and len(err.splitlines()) == 1
    assert not out.exists()


def test_rotation_is_rigid_in_the_world() -> None:
    """The world-frame glint of a stipple at plate angle phi is where the turned
    stipple's sightline meets the turned plate (far viewer)."""
    rng = np.random.default_rng(6)
    pts = _points(5, rng)
    setup = SpinSetup(distance=2e6, ipd=64.0 * 2e6 / 600.0)
    d = design_spinning(pts, setup, TOOL)
    eye_w = setup.world_eyes()[0]
    for phi in (0.3, 2.0, 4.4):
        gl = find_spin_glints(d, rotate_z(eye_w, -phi), TOOL)
        world = rotate_z(gl.point, phi)
        p_w = rotate_z(pts[gl.stipple], phi)
        t = eye_w[2] / (eye_w[2] - p_w[:, 2])
        cross = eye_w + (p_w - eye_w) * t[:, None]
        np.testing.assert_allclose(world, cross, atol=0.01)


def test_stipple_on_the_plate_gets_a_dimple_seen_in_place() -> None:
    """A point on the plate's plane needs no disparity: a dimple, seen by both
    eyes at the point itself at every angle, beside ordinary grooves."""
    pts = np.array([[5.0, -3.0, 0.0], [10.0, 4.0, -6.0]])
    setup = SpinSetup()
    d = design_spinning(pts, setup, TOOL)
    assert d.grooves.is_dot.tolist() == [True, False]
    reps = verify_spinning(d, TOOL, np.arange(0, 360, 30.0))
    assert all(r.visibility == 1.0 and r.stray == 0 for r in reps)
    for phi in (0.0, 1.0):
        for eye in setup.eyes(np.array([phi]))[:, 0]:
            gl = find_spin_glints(d, eye, TOOL)
            dot = gl.point[gl.stipple == 0]
            np.testing.assert_allclose(dot, [[5.0, -3.0, 0.0]], atol=1e-12)


def test_folder_reverifies_and_refuses_what_it_cannot(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "spin"
    assert main(["spin", str(BUNNY), "--out", str(out), "--stipples", "120", "--frames", "0",
                 "--step", "15"]) == 0
    first = json.loads((out / "verify.json").read_text())["summary"]
    capsys.readouterr()
    assert main(["verify", str(out), "--step", "5"]) == 0
    again = json.loads((out / "verify.json").read_text())
    assert len(again["angles"]) == 72
    # the folder alone reproduces the design's figures (15 deg is every third angle)
    p95 = [a["p95_mm"] for a in again["angles"][::3]]
    assert max(p95) == pytest.approx(first["worst_p95_mm"], abs=1e-12)
    # --at is the plate's angle; a turning plate moves by more than the eye
    assert main(["render", str(out), "--at", "nan"]) != 0
    err = capsys.readouterr().err.strip()
    assert "--at" in err and len(err.splitlines()) == 1
    assert main(["animate", str(out), "--kind", "light"]) != 0
    err = capsys.readouterr().err.strip()
    assert "turning-plate" in err and len(err.splitlines()) == 1
    assert main(["verify", str(out), "--cut"]) != 0


def test_programs_name_the_drawing_it_writes_and_the_v_s_groove_width(tmp_path: Path) -> None:
    """A turning plate writes an SVG and no DXF: both programs' headers send a
    maker to the SVG's marks alone. The relief is cut by the V-bit: its header
    names the groove the V cuts (2 d tan(angle / 2) wide), not its tip model's."""
    from specholo.optics.cutters import VBit

    out = tmp_path / "spin"
    assert main(["spin", str(BUNNY), "--out", str(out), "--stipples", "8", "--frames", "0",
                 "--step", "45"]) == 0
    assert (out / "hologram.svg").is_file() and not list(out.glob("*.dxf"))
    for name in ("hologram.gcode", "relief.gcode"):
        head = [ln for ln in (out / name).read_text().splitlines() if ln.startswith("(")]
        marks = [ln for ln in head if ln.startswith("(plate marks:")]
        assert len(marks) == 1 and marks[0].endswith("layer PLATE of the SVG, not cut)")
        assert not any("DXF" in ln for ln in head)
    meta = json.loads((out / "hologram.json").read_text())
    depth = meta["relief"]["depth_mm"]
    head = (out / "relief.gcode").read_text().splitlines()
    tool = next(ln for ln in head if ln.startswith("(tool:"))
    width = float(tool.split("groove width ")[1].split(" mm")[0])
    vbit = VBit(RELIEF_ANGLE)
    assert width == pytest.approx(vbit.section(depth).width, abs=2e-5)
    assert width == pytest.approx(2 * depth * math.tan(0.5 * RELIEF_ANGLE), abs=2e-5)
