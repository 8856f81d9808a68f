"""Curved hosts, motion and animation: physical checks of `specholo compose`."""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from specholo.errors import SpecholoError
from specholo.fabrication.programs.surface_gcode import check_surface_program, write_surface_gcode
from specholo.hosts.surfaces import Cylinder, HeightField, MeshHost, Panel, Panels, Plane, Sphere
from specholo.jobs.composition.design import (
    design_composition,
    parse_composition,
    verify_composition,
)
from specholo.simulation.conforming import find_conforming_glints, summarise
from specholo_cli.cli import main

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"


def _comp(host: str, mode: str = "walk", extra: str = "", scenes: str | None = None,
          stipples: int = 60):
    scenes = scenes if scenes is not None else (
        f'[[scene]]\nmodel = "{BUNNY}"\nsize = 30\ncenter_z = -25\n')
    text = (f'mode = "{mode}"\nstipples = {stipples}\nseed = 5\n{extra}\n'
            f'[host]\n{host}\n[viewer]\nrange = 25\n[light]\nelevation = 45\nstop = 60\n'
            f'{scenes}')
    return parse_composition(text, ROOT)


@pytest.mark.parametrize("host", [Plane(), Cylinder(30, 60), Sphere(40),
                                  HeightField.from_function(
                                      lambda x, y: 3 * np.sin(x / 15) * np.cos(y / 20)
                                      - 0.0, 80, 80, 1.0)])
def test_rays_meet_the_host_on_its_surface_with_outward_normals(host) -> None:
    rng = np.random.default_rng(0)
    origins = np.column_stack([rng.uniform(-20, 20, 200), rng.uniform(-20, 20, 200),
                               np.full(200, 500.0)])
    targets = np.column_stack([rng.uniform(-10, 10, 200), rng.uniform(-10, 10, 200),
                               np.full(200, -20.0)])
    hit = host.intersect(origins, targets - origins)
    assert hit.valid.all()
    on = host.project(hit.point)
    assert np.abs(on - hit.point).max() < 1e-6
    # Outward: toward the eye's side, and unit length.
    assert np.allclose(np.linalg.norm(hit.normal, axis=1), 1.0)
    assert (np.sum(hit.normal * (origins - hit.point), axis=1) > 0).all()
    # The hit lies on the ray.
    d = hit.point - origins
    u = (targets - origins) / np.linalg.norm(targets - origins, axis=1, keepdims=True)
    assert np.abs(np.linalg.norm(np.cross(d, u), axis=1)).max() < 1e-6


def test_a_mesh_host_agrees_with_the_sphere_it_tessellates() -> None:
    sphere = Sphere(40)
    mesh = trimesh.creation.icosphere(subdivisions=5, radius=40)
    mesh.apply_translation([0, 0, -40])
    host = MeshHost(mesh)
    rng = np.random.default_rng(1)
    o = np.column_stack([rng.uniform(-15, 15, 100), rng.uniform(-15, 15, 100),
                         np.full(100, 300.0)])
    d = np.array([0.0, 0.0, -1.0]) + rng.normal(0, 0.02, (100, 3))
    a, b = host.intersect(o, d), sphere.intersect(o, d)
    assert a.valid.all() and b.valid.all()
    assert np.abs(a.point - b.point).max() < 0.02  # the tessellation's sag
    assert np.degrees(np.arccos(np.clip(np.sum(a.normal * b.normal, axis=1), -1, 1))).max() < 0.5


def test_panels_take_the_nearest_panel_and_name_it() -> None:
    host = Panels([Panel((-30, 0, 0), (0.2, 0, 1), 50, 60),
                   Panel((30, 0, 0), (-0.2, 0, 1), 50, 60)])
    hit = host.intersect(np.array([[-30, 0, 400], [30, 0, 400], [0, 0, 400]]),
                         np.array([[0, 0, -1.0]] * 3))
    # The third ray passes through the gap between the panels.
    assert list(hit.valid) == [True, True, False]
    assert list(hit.part[:2]) == [0, 1]
    assert np.allclose(host.project(hit.point[:2]), hit.point[:2])
    assert np.allclose(host.normal(hit.point[:2]), hit.normal[:2])


@pytest.mark.parametrize("host", ['kind = "cylinder"\nradius = 35\nheight = 60',
                                  'kind = "sphere"\nradius = 60'])
def test_curved_host_glints_triangulate_to_their_points(host: str) -> None:
    d = design_composition(_comp(host))
    reports = verify_composition(d, math.radians(12.5))
    s = summarise(reports)
    assert s["worst_p95_error"] < 0.35          # the band is 0.2 mm across the sightline
    assert s["worst_p95_depth_error"] < 0.05
    assert s["min_visibility"] > 0.95
    assert s["max_stray"] == 0.0


def test_glints_on_a_cylinder_reflect_the_light_into_the_eye() -> None:
    comp = _comp('kind = "cylinder"\nradius = 35\nheight = 60')
    d = design_composition(comp)
    tool = comp.tool
    pos = comp.motion.positions(math.radians(10))[1]
    light = np.array(pos.light)
    g = find_conforming_glints(d.grooves, comp.host, pos.eyes[0], light, False, tool)
    assert len(g.point) > 20
    # The ball's centre for each glint: the groove point nearest it, lifted.
    from scipy.spatial import cKDTree

    near = cKDTree(d.grooves.point).query(g.point)[1]
    s, t = d.grooves.point[near], d.grooves.tangent[near]
    # The centreline point abreast of the glint (the wall is perpendicular to t).
    c = comp.host.project(s + np.sum((g.point - s) * t, axis=1)[:, None] * t)
    centre = c + (tool.radius - tool.depth) * comp.host.normal(c)
    # The glint lies on the ball's surface, and the wall normal there (toward
    # the ball centre) mirrors the sun into the eye.
    wall = centre - g.point
    r = np.linalg.norm(wall, axis=1)
    n = wall / r[:, None]
    out = -light + 2 * np.sum(light * n, axis=1)[:, None] * n
    to_eye = pos.eyes[0] - g.point
    to_eye /= np.linalg.norm(to_eye, axis=1, keepdims=True)
    angle = np.degrees(np.arccos(np.clip(np.sum(out * to_eye, axis=1), -1, 1)))
    assert np.median(np.abs(r - tool.radius)) < 2e-3
    assert np.percentile(angle, 90) < 0.5


def test_a_moving_light_shows_a_turning_scene_to_a_still_viewer() -> None:
    scenes = f'[[scene]]\nmodel = "{BUNNY}"\nsize = 30\ncenter_z = -25\nturn = 0.5\n'
    d = design_composition(_comp('kind = "plane"', "light", scenes=scenes))
    s = summarise(verify_composition(d, math.radians(7.5)))
    assert s["worst_p95_error"] < 0.3
    assert s["max_stray"] == 0.0


def test_viewpoint_keyed_scenes_hand_over_without_ghosts() -> None:
    scenes = (f'[[scene]]\nmodel = "{BUNNY}"\nsize = 30\ncenter_z = -25\nto = 0\n'
              f'[[scene]]\nmodel = "{BUNNY}"\nsize = 30\ncenter_z = -45\nfrom = 0\n')
    d = design_composition(_comp('kind = "plane"', scenes=scenes, stipples=50))
    reports = verify_composition(d, math.radians(5))
    by = {round(r.position): r for r in reports}
    # Each side shows its own scene, at its own depth, and nothing of the other.
    for az in (-20, -10, 10, 20):
        assert by[az].shown > 10 and by[az].p95_error < 0.35 and by[az].stray == 0.0
    # A head straddling the hand-over sees a different scene in each eye: no
    # stipple is shown to both.
    assert by[0].shown == 0


def test_gcode_on_curved_hosts_passes_its_check_and_a_deeper_cut_does_not(tmp_path) -> None:
    comp = _comp('kind = "cylinder"\nradius = 35\nheight = 60', stipples=20)
    d = design_composition(comp)
    path = tmp_path / "p.ngc"
    for axes in (3, 4):
        prog = write_surface_gcode(d.grooves, comp.host, comp.tool, comp.machining, axes)
        path.write_text(prog.text)
        fig = check_surface_program(path, d.grooves, comp.host, comp.tool, comp.machining, axes)
        assert fig["cutting_moves"] > 100
        assert fig["deepest_cut_mm"] <= comp.tool.depth + 2e-3
        lines = prog.text.splitlines()
        k = next(i for i, ln in enumerate(lines) if ln.startswith("G1 X"))
        words = lines[k].split()
        if axes == 4:
            lines[k] = f"{lines[k]} Z{-3 * comp.tool.depth:.4f}"
        else:
            z = float(next(w for w in words if w.startswith("Z"))[1:])
            lines[k] = " ".join([*(w for w in words if not w.startswith("Z")),
                                 f"Z{z - 0.05:.4f}"])
        path.write_text("\n".join(lines) + "\n")
        with pytest.raises(SpecholoError, match="deeper"):
            check_surface_program(path, d.grooves, comp.host, comp.tool, comp.machining, axes)


@pytest.mark.skipif(shutil.which("rs274") is None, reason="LinuxCNC's rs274 not installed")
def test_four_axis_gcode_parses_in_linuxcnc(tmp_path: Path) -> None:
    comp = _comp('kind = "cylinder"\nradius = 35\nheight = 60', stipples=10)
    d = design_composition(comp)
    prog = write_surface_gcode(d.grooves, comp.host, comp.tool, comp.machining, 4)
    path = tmp_path / "cup.ngc"
    path.write_text(prog.text)
    run = subprocess.run(["rs274", "-g", str(path)], capture_output=True, text=True,
                         timeout=120, input="", env={**os.environ, "HOME": str(tmp_path)})
    assert run.returncode == 0, run.stdout[-500:] + run.stderr[-500:]
    feeds = [ln for ln in run.stdout.splitlines() if "STRAIGHT_FEED" in ln]
    assert len(feeds) > 50
    # The canonical moves carry the A axis the program turns.
    assert any("STRAIGHT_FEED" in ln for ln in feeds)


def test_compose_cli_writes_a_verified_folder(tmp_path: Path) -> None:
    text = (f'stipples = 30\n[host]\nkind = "cylinder"\nradius = 35\n[machining]\naxes = 4\n'
            f'[[scene]]\nmodel = "{BUNNY}"\nsize = 30\ncenter_z = -25\n')
    comp = tmp_path / "c.toml"
    comp.write_text(text)
    out = tmp_path / "out"
    assert main(["compose", str(comp), "--out", str(out), "--step", "15"]) == 0
    meta = json.loads((out / "hologram.json").read_text())
    assert meta["design"] == "composition" and meta["host"]["kind"] == "cylinder"
    ver = json.loads((out / "verify.json").read_text())
    assert ver["summary"]["worst_p95_error"] < 0.35
    assert main(["verify", str(out), "--step", "5"]) == 0


@pytest.mark.parametrize("text, message", [
    ('colour = 1\n[[scene]]\nmodel = "x.obj"\n', "unknown key 'colour'"),
    ('[host]\nkind = "torus"\n[[scene]]\nmodel = "x.obj"\n', "unknown host kind"),
    ('[viewer]\ndistance = -5\n[[scene]]\nmodel = "x.obj"\n', "viewer.distance"),
    ('mode = "walk"\n', "at least one [[scene]]"),
    ('[[scene]]\nmodel = "missing.obj"\n', "missing.obj"),
])
def test_bad_compositions_fail_in_one_line_with_no_output(tmp_path: Path, capsys, text: str,
                                                          message: str) -> None:
    comp = tmp_path / "c.toml"
    comp.write_text(text)
    out = tmp_path / "out"
    assert main(["compose", str(comp), "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:") and message in err[0]
    assert not out.exists()


def test_a_numbered_sequence_shows_each_frame_over_its_share_of_the_walk(
        tmp_path: Path) -> None:
    mesh = trimesh.load(BUNNY, process=False)
    for i, angle in enumerate((0, 40, 80)):
        m = mesh.copy()
        m.apply_transform(trimesh.transformations.rotation_matrix(math.radians(angle),
                                                                  [0, 1, 0]))
        m.export(tmp_path / f"frame_{i:02d}.obj")
    text = ('stipples = 40\n[host]\nkind = "plane"\n[viewer]\nrange = 24\n'
            '[[scene]]\nframes = "frame_*.obj"\nsize = 30\ncenter_z = -25\n')
    comp = parse_composition(text, tmp_path)
    assert len(comp.scenes) == 3
    d = design_composition(comp)
    point = comp.motion.light_distance is not None
    for frame, azimuth in enumerate((-18, 0, 18)):
        pos = next(p for p in comp.motion.positions(math.radians(2))
                   if abs(math.degrees(p.tau) - azimuth) < 1e-6)
        for eye in pos.eyes:
            g = find_conforming_glints(d.grooves, comp.host, eye, pos.light, point, comp.tool)
            assert len(g.stipple) > 10
            # Only the frame keyed to this part of the walk glints.
            assert set((g.stipple // 40).tolist()) == {frame}


def test_a_host_that_no_sightline_meets_is_refused(tmp_path: Path, capsys) -> None:
    comp = tmp_path / "c.toml"
    # a 2 x 1 mm plane, the scene 300 mm to its side: every sightline passes it by
    comp.write_text(f'stipples = 10\n[host]\nkind = "plane"\nwidth = 2\nheight = 1\n'
                    f'[[scene]]\nmodel = "{BUNNY}"\nsize = 30\ncenter_z = -25\n'
                    'offset_x = 300\n')
    out = tmp_path / "out"
    assert main(["compose", str(comp), "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "misses the host" in err[0]
    assert not out.exists()


@settings(max_examples=8, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(kind=st.sampled_from(["cylinder", "sphere", "plane"]),
       radius=st.floats(30, 200), px=st.floats(-15, 15), py=st.floats(-15, 15),
       pz=st.floats(-60, 20), elevation=st.floats(20, 70),
       point_light=st.booleans())
def test_any_host_and_light_put_a_point_where_it_belongs(kind: str, radius: float, px: float,
                                                         py: float, pz: float,
                                                         elevation: float,
                                                         point_light: bool) -> None:
    """A single point, striped on a random host under a random light, glints for both
    eyes of every head and triangulates to within the band of the point: at most w
    (0.2 mm) across the sightline plus one state's overshoot at a hand-over, and
    well under the 0.5 mm of depth that stereo acuity resolves at 600 mm (0.1 mm
    here, for hosts as curved as a 30 mm cylinder with the point near its back)."""
    from specholo.scene.motion import MotionSpec
    from specholo.setup import Tool
    from specholo.simulation.verify import stereo_errors
    from specholo.toolpaths.conforming import ConformingOptions, design_family

    assume(abs(pz) > 2.0)  # off the host: a point on it is a dot, not a stripe
    host = {"cylinder": Cylinder(radius, 200), "sphere": Sphere(radius), "plane": Plane()}[kind]
    spec = MotionSpec(half_range=math.radians(20), light_elevation=math.radians(elevation),
                      light_distance=800.0 if point_light else None)
    fam = spec.families()[0]
    p = np.array([[px, py, pz]])
    # The point sits off the host on the viewer's side of it or behind: its
    # sightlines cross the host once on the way.
    hit = host.intersect(fam.eye, p - fam.eye)
    assume(hit.valid.all())
    tool = Tool(0.05, 0.02)
    targets = np.broadcast_to(p[:, None, :], (1, len(fam.tau), 3))
    g = design_family(host, fam.eye, fam.light, fam.baseline, fam.point_light, targets,
                      np.ones((1, len(fam.tau)), dtype=bool), tool, ConformingOptions(0.2))
    assume(g.stats["states_lost_to_tilt"] == 0 and g.stats["states_lost_to_steep_grooves"] == 0)
    for pos in spec.positions(math.radians(10)):
        gl = find_conforming_glints(g, host, pos.eyes[0], pos.light, fam.point_light, tool)
        gr = find_conforming_glints(g, host, pos.eyes[1], pos.light, fam.point_light, tool)
        assert len(gl.stipple) >= 1 and len(gr.stipple) >= 1
        err, depth = stereo_errors(p, gl, gr, pos.eyes[0], pos.eyes[1], np.array([0]))
        assert err[0] < 2 * 0.2 and abs(depth[0]) < 0.1


def test_a_scene_s_pose_turns_and_moves_it_on_the_plate(tmp_path: Path) -> None:
    from specholo.jobs.composition.design import prepare_scenes

    def points(extra: str) -> np.ndarray:
        text = (f'stipples = 30\n[[scene]]\nmodel = "{BUNNY}"\nsize = 30\ncenter_z = -25\n'
                + extra)
        return prepare_scenes(parse_composition(text, tmp_path))[0].points

    plain = points("")
    # up z then a quarter turn about x is the identity; the offset moves every point
    moved = points('up = "z"\nrotate_x = 90\noffset_x = 4\noffset_y = -3\n')
    np.testing.assert_allclose(moved - plain - [4.0, -3.0, 0.0], 0.0, atol=1e-9)
    with pytest.raises(SpecholoError, match="up must be one of"):
        points('up = "w"\n')


#: Panels tilted towards the middle, a folding screen set back behind the frame's
#: origin: [[host.panels]] entries of a composition.
_SET_BACK = ('[[host.panels]]\ncentre = [-26, 0, -12]\nnormal = [0.25, 0, 1]\nwidth = 50\n'
             'height = 60\n[[host.panels]]\ncentre = [26, 0, -12]\nnormal = [-0.25, 0, 1]\n'
             'width = 50\nheight = 60\n')
#: A third panel between them on the axis, the others moved out to leave it room
#: (seen from above no panel covers another: a vertical tool reaches each).
_THREE = (_SET_BACK.replace("[-26,", "[-37,").replace("[26,", "[37,")
          + '[[host.panels]]\ncentre = [0, 0, -9]\nnormal = [0, 0.2, 1]\nwidth = 20\n'
          'height = 60\n')


@pytest.mark.parametrize("panels, on_axis", [(_SET_BACK, False), (_THREE, True)],
                         ids=["two, gap at the axis", "three, the middle one on the axis"])
def test_tilted_panels_set_back_get_a_checked_program(tmp_path: Path, panels: str,
                                                      on_axis: bool) -> None:
    """Tilted panels wholly behind the frame's origin: the program is written and
    passes its check, Z = 0 on a point of the panels a maker can touch off on
    (under the axis, or the highest corner where a gap lies there), rapids the
    safe height above the highest corner, and every cut the depth into the
    panel under it."""
    comp = tmp_path / "panels.toml"
    comp.write_text(f'stipples = 20\nseed = 1\n[host]\nkind = "panels"\n{panels}'
                    f'[viewer]\nrange = 20\n[[scene]]\nmodel = "{BUNNY}"\nsize = 30\n'
                    'center_z = -25\n')
    out = tmp_path / "out"
    assert main(["compose", str(comp), "--out", str(out), "--step", "10"]) == 0
    meta = json.loads((out / "hologram.json").read_text())
    assert meta["gcode"]["check"]["violations"] == 0 and meta["gcode"]["paths"] > 0
    host = parse_composition(comp.read_text(), tmp_path).host
    corners = np.array([c + 0.5 * sx * p.width * r + 0.5 * sy * p.height * u
                        for p in host.panels for c, r, u, _ in [p.frame()]
                        for sx in (-1, 1) for sy in (-1, 1)])
    top = corners[:, 2].max()
    assert top < 0  # the whole host lies behind the frame's origin
    down = host.intersect(np.array([[0.0, 0.0, 100.0]]), np.array([0.0, 0.0, -1.0]))
    assert bool(down.valid[0]) == on_axis
    zero = float(down.point[0, 2]) if on_axis else top
    lines = (out / "hologram.gcode").read_text().splitlines()
    origin = next(ln for ln in lines if ln.startswith("(origin:"))
    assert ("crosses the axis" in origin) == on_axis
    assert ("highest point" in origin) != on_axis
    assert f"Z{zero:.5f}".rstrip("0").rstrip(".") + " in that frame" in origin
    # rapids at the safe height, 1 mm, above the highest corner
    assert next(ln for ln in lines if ln.startswith("G0 Z")) == f"G0 Z{top - zero + 1.0:.5f}"
    # each cut's tip lies the depth into the panel straight under it, at most
    cuts = np.array([[float(w[1:]) for w in ln.split()[1:4]] for ln in lines
                     if ln.startswith("G1 X")])
    under = host.intersect(cuts * [1, 1, 0] + [0, 0, 100.0], np.array([0.0, 0.0, -1.0]))
    assert under.valid.all()
    into = under.point[:, 2] - zero - cuts[:, 2]
    assert into.min() > -1e-3 and into.max() <= 0.02 + 2e-3


def _check_exit(args: list[str]) -> int:
    """``specholo check ...``'s exit status (a violation exits through SystemExit)."""
    try:
        return main(["check", *args])
    except SystemExit as exc:
        return int(exc.code or 0)


@pytest.mark.parametrize("axes", [4, 3])
def test_check_on_a_cup_s_program_says_where_its_limits_went(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], axes: int) -> None:
    """`specholo check` on a curved host's program has no limits to read: it says
    in one line that they follow the surface, that the program passed them when
    written (hologram.json's gcode.check, with its figures), and which options
    check it as a flat plate; those options run that check."""
    text = (ROOT / "examples" / "cup.toml").read_text()
    text = text.replace("stipples = 600", "stipples = 10").replace("axes = 4", f"axes = {axes}")
    text = text.replace('model = "bunny.obj"', f'model = "{BUNNY}"')
    comp = tmp_path / "cup.toml"
    comp.write_text(text)
    out = tmp_path / "cup"
    assert main(["compose", str(comp), "--out", str(out), "--step", "15"]) == 0
    capsys.readouterr()
    program = out / "hologram.gcode"
    assert _check_exit([str(program)]) == 1
    got = capsys.readouterr()
    err = got.err.strip().splitlines()
    assert len(err) == 1 and not got.out, got
    line = err[0]
    check = json.loads((out / "hologram.json").read_text())["gcode"]["check"]
    assert "follow the host's curved surface" in line and f"{axes}-axis" in line
    assert f"{out / 'hologram.json'} records that check (gcode.check: " in line
    assert f"{check['cutting_moves']} cutting moves" in line and "0 violations" in line
    assert "--plate-width, --plate-height and --max-depth check it as a flat plate" in line
    assert ("A turns" in line) == (axes == 4)
    # the options named check it as a flat plate: a report, not the refusal
    status = _check_exit([str(program), "--plate-width", "100", "--plate-height", "100",
                          "--max-depth", "0.02"])
    got = capsys.readouterr()
    assert "violation(s)" in got.out and "names no limits" not in got.err
    if axes == 4:  # a flat plate has no rotary axis: its A words are flagged
        assert status == 1 and "unsupported word A" in got.out
