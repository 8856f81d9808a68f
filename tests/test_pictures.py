"""Every picture command draws every kind of design, and what it draws is that
kind's own physics: a spot where the camera projects each glint the kind's own
finder gives for that eye, frames that move as the glints move along the
design's motion, a page holding the finder's glints per view, a report naming
the kind's verified figures."""

from __future__ import annotations

import base64
import gzip
import html
import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial import cKDTree

from specholo.preview.render import Camera
from specholo_cli.cli import main

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"


def _example(name: str, stipples: int) -> str:
    """An example composition with fewer stipples, its model found from anywhere."""
    text = (ROOT / "examples" / name).read_text()
    text = re.sub(r"(?m)^stipples = \d+", f"stipples = {stipples}", text)
    return text.replace('model = "bunny.obj"', f'model = "{BUNNY.as_posix()}"')


LIGHT_COMPOSITION = (f'mode = "light"\nstipples = 30\nseed = 5\n[host]\nkind = "plane"\n'
                     f'[viewer]\nrange = 25\n[light]\nelevation = 45\nstop = 60\n'
                     f'[[scene]]\nmodel = "{BUNNY.as_posix()}"\nsize = 30\ncenter_z = -25\n'
                     'turn = 0.5\n')


def _run(argv: list[Any], capsys: pytest.CaptureFixture[str]) -> str:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert code == 0, (argv, err)
    return out


@pytest.fixture(scope="module")
def folders(tmp_path_factory: pytest.TempPathFactory, small_design: Path) -> dict[str, Path]:
    """A small folder of every kind (a second or two each)."""
    base = tmp_path_factory.mktemp("kinds")
    made = {"flat": small_design}
    for name, text in (("cup", _example("cup.toml", 30)),
                       ("animation", _example("animation.toml", 30)),
                       ("light", LIGHT_COMPOSITION)):
        toml = base / f"{name}.toml"
        toml.write_text(text)
        assert main(["compose", str(toml), "--out", str(base / name), "--frames", "0",
                     "--step", "15"]) == 0
        made[name] = base / name
    assert main(["spin", str(BUNNY), "--out", str(base / "spin"), "--stipples", "60",
                 "--frames", "0", "--step", "30"]) == 0
    assert main(["steady", str(BUNNY), "--out", str(base / "steady"), "--stipples", "30",
                 "--step", "2"]) == 0
    assert main(["design", str(BUNNY), "--out", str(base / "ridged"), "--method", "ridged",
                 "--stipples", "40", "--view-range", "8", "--elevation-range", "4",
                 "--raster", "0.05", "--formats", "png"]) == 0
    made.update(spin=base / "spin", steady=base / "steady", ridged=base / "ridged")
    return made


#: command -> (arguments after the folder, the file it writes in {tmp}).
COMMANDS: dict[str, tuple[list[str], str]] = {
    "render": (["--width", "64", "--height", "48", "--out", "{tmp}/render.png"], "render.png"),
    "stereo": (["--width", "48", "--height", "40", "--out", "{tmp}/stereo.png"], "stereo.png"),
    "animate": (["--frames", "3", "--width", "48", "--height", "40", "--out",
                 "{tmp}/motion.gif"], "motion.gif"),
    "report": ([], "report.html"),
    "view": (["--step", "5", "--out", "{tmp}/view.html"], "view.html"),
}
KINDS = ["flat", "ridged", "cup", "animation", "light", "spin", "steady"]


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("kind", KINDS)
def test_every_picture_command_serves_every_kind(folders: dict[str, Path], tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str],
                                                 kind: str, command: str) -> None:
    args, name = COMMANDS[command]
    folder = folders[kind]
    _run([command, folder, *(a.format(tmp=tmp_path) for a in args)], capsys)
    written = folder / name if command == "report" else tmp_path / name
    assert written.is_file()
    if written.suffix in (".png", ".gif"):
        from PIL import Image

        with Image.open(written) as im:  # a whole picture of the size asked for
            assert im.size[1] == int(args[args.index("--height") + 1])
            assert getattr(im, "n_frames", 1) == (3 if command == "animate" else 1)
    else:
        assert written.read_text().rstrip().endswith("</html>")


# ---------------------------------------------------------------- stills


def spots(image: np.ndarray) -> np.ndarray:
    """Centres (k, 2) of an image's glint spots (as tests/test_render.py finds them)."""
    from test_render import spots as found

    return found(image)[0]


def _matches(found: np.ndarray, pixel: np.ndarray, tol: float = 1.5) -> None:
    """Every spot drawn is a glint's projection, and every glint apart from the
    others (more than 5 px) has its spot."""
    assert len(found) and len(pixel)
    d, _ = cKDTree(pixel).query(found)
    assert d.max() < tol, d.max()
    gap, _ = cKDTree(pixel).query(pixel, k=2)
    lone = pixel[gap[:, 1] > 5.0]
    d, _ = cKDTree(found).query(lone)
    assert len(lone) and d.max() < tol, d.max()


def _camera(folder: Path, azimuth: float | None, width: int, height: int) -> Camera:
    """The camera ``render`` places for those options (its framing is the
    source's; what is tested is where the kind's glints land in it)."""
    from specholo.jobs import job_of
    from specholo.preview.source import camera

    source = job_of(folder).picture_source(folder)
    return camera(source, None if azimuth is None else math.radians(azimuth), 0.0, None,
                  None, width, height)


def _render(folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
            *options: Any) -> np.ndarray:
    from PIL import Image

    out = tmp_path / "still.png"
    _run(["render", folder, "--width", 512, "--height", 384, "--out", out, *options], capsys)
    return np.asarray(Image.open(out).convert("RGB"))


def _conforming(folder: Path, eye: np.ndarray, elevation: float | None = None) -> np.ndarray:
    """A composition's glints for an eye, by its own finder and its own light."""
    from specholo.jobs.composition.design import load_composition_folder
    from specholo.setup import Light
    from specholo.simulation.conforming import find_conforming_glints

    d = load_composition_folder(folder)
    m = d.comp.motion
    light = Light(m.light_elevation if elevation is None else elevation, m.light_distance)
    point = light.position is not None
    vec = light.position if point else light.direction
    return find_conforming_glints(d.grooves, d.comp.host, eye, vec, point, d.comp.tool).point


@pytest.mark.parametrize("kind, azimuth", [("cup", 0.0), ("cup", 12.0), ("animation", -15.0),
                                           ("animation", 10.0)])
def test_a_composition_s_still_shows_its_glints(folders: dict[str, Path], tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str], kind: str,
                                                azimuth: float) -> None:
    image = _render(folders[kind], tmp_path, capsys, "--azimuth", azimuth)
    cam = _camera(folders[kind], azimuth, 512, 384)
    proj = cam.project(_conforming(folders[kind], cam.position()))
    assert proj.valid.all()
    _matches(spots(image), proj.pixel)


def test_a_turning_plate_s_still_is_its_left_eye_at_that_angle(
        folders: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from specholo.jobs.spin.design import load_spin_folder
    from specholo.simulation.spinning import find_spin_glints
    from specholo.toolpaths.spinning import rotate_z

    folder = folders["spin"]
    job = load_spin_folder(folder)
    setup = job.design.setup
    cam = _camera(folder, None, 512, 384)
    # the default camera is the design's left eye, where verify puts it
    np.testing.assert_allclose(cam.position(), setup.world_eyes()[0], atol=1e-9)
    for angle in (0.0, 40.0, 200.0):
        phi = math.radians(angle)
        image = _render(folder, tmp_path, capsys, "--at", angle)
        # verify's left eye on the turned plate, and its glints turned back into the world
        eye = setup.eyes(np.array([phi]))[0, 0]
        world = rotate_z(find_spin_glints(job.design, eye, job.config.tool).point, phi)
        _matches(spots(image), cam.project(world).pixel)


def test_a_steady_image_s_still_is_its_left_eye_under_that_light(
        folders: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from specholo.jobs.steady.design import load_steady_folder
    from specholo.simulation.steady import find_steady_glints

    folder = folders["steady"]
    design, config = load_steady_folder(folder)
    eye = design.setup.eyes()[0]
    cam = _camera(folder, None, 512, 384)
    np.testing.assert_allclose(cam.position(), eye, atol=1e-9)
    for elevation in (41.0, 45.0, 49.0):
        image = _render(folder, tmp_path, capsys, "--at", elevation)
        light = design.setup.light(math.radians(elevation))
        glints = find_steady_glints(design, eye, light, config.tool).point
        _matches(spots(image), cam.project(glints).pixel)


def test_a_moving_light_composition_s_still_is_its_left_eye(
        folders: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from specholo.jobs.composition.design import load_composition_folder

    folder = folders["light"]
    positions = load_composition_folder(folder).comp.motion.positions(math.radians(15.0))
    cam = _camera(folder, None, 512, 384)
    np.testing.assert_allclose(cam.position(), positions[0].eyes[0], atol=1e-9)
    image = _render(folder, tmp_path, capsys, "--at", 55)
    _matches(spots(image), cam.project(_conforming(folder, cam.position(),
                                                   math.radians(55.0))).pixel)


# ---------------------------------------------------------------- animations


def _gif_frames(path: Path) -> list[np.ndarray]:
    from PIL import Image, ImageSequence

    with Image.open(path) as im:
        return [np.asarray(f.convert("RGB")) for f in ImageSequence.Iterator(im)]


@pytest.mark.parametrize("kind", ["spin", "steady", "cup"])
def test_an_animation_moves_its_glints_along_the_motion(
        folders: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str],
        kind: str) -> None:
    """Each frame's spots are the glints the kind's finder gives at that frame's
    state (a plate angle, a light elevation, a head azimuth), so the frames differ."""
    from specholo.jobs import job_of
    from specholo.preview.motion import sweep
    from specholo.preview.source import camera

    folder = folders[kind]
    source = job_of(folder).picture_source(folder)
    out = tmp_path / "a.gif"
    _run(["animate", folder, "--frames", "4", "--width", "384", "--height", "288", "--out",
          out], capsys)
    shots = _gif_frames(out)
    assert len(shots) == 4
    assert all(not np.array_equal(shots[0], s) for s in shots[1:])
    m = source.motion
    if kind == "cup":  # the camera walks the viewing arc
        r = source.setup.viewer.half_range
        base = camera(source, 0.0, 0.0, None, None, 384, 288, frame_azimuths=(-r, r))
        cams = [Camera(float(a), 0.0, base.distance, base.fov, 384, 288, base.eye_height)
                for a in sweep(-r, r, 4)]
        points = [_conforming(folder, c.position()) for c in cams]
    else:  # the camera still at the left eye, the plate turning or the light moving
        cams = [camera(source, None, 0.0, None, None, 384, 288)] * 4
        states = m.sweep(4)
        assert (np.diff(states) != 0).all()
        if kind == "spin":
            from specholo.jobs.spin.design import load_spin_folder
            from specholo.simulation.spinning import find_spin_glints
            from specholo.toolpaths.spinning import rotate_z

            job = load_spin_folder(folder)
            eyes = job.design.setup.eyes(states)[0]
            points = [rotate_z(find_spin_glints(job.design, e, job.config.tool).point, p)
                      for e, p in zip(eyes, states, strict=True)]
        else:
            from specholo.jobs.steady.design import load_steady_folder
            from specholo.simulation.steady import find_steady_glints

            design, config = load_steady_folder(folder)
            points = [find_steady_glints(design, design.setup.eyes()[0],
                                         design.setup.light(s), config.tool).point
                      for s in states]
    for shot, cam, pts in zip(shots, cams, points, strict=True):
        _matches(spots(shot), cam.project(pts).pixel)


# ---------------------------------------------------------------- pages


def page_views(path: Path) -> tuple[dict[str, Any], np.ndarray, np.ndarray]:
    """A page's metadata, and its data block decoded: the first glint of each
    view (views + 1,) and every glint's position (g, 3), mm."""
    text = path.read_text()
    meta = json.loads(html.unescape(
        re.search(r'<script type="application/json" id="meta">(.*?)</script>', text,
                  re.S).group(1)))
    raw = base64.b64decode(re.search(r'<script type="text/plain" id="data">(.*?)</script>',
                                     text, re.S).group(1))
    blocks = {b["name"]: gzip.decompress(raw[b["offset"]:b["offset"] + b["length"]])
              for b in meta["blocks"]}
    start = np.frombuffer(blocks["start"], dtype="<u4")
    n = meta["counts"]["glints"]
    cols = []
    for k, name in enumerate("xyz"):
        b = np.frombuffer(blocks[name], dtype=np.uint8).astype(np.int64)
        q = b[:n] | (b[n:] << 8)
        cols.append(meta["quant"]["origin"][k] + q * meta["quant"]["scale"][k])
    return meta, start, np.stack(cols, axis=1).reshape(-1, 3)


@pytest.mark.parametrize("kind", ["spin", "steady", "cup", "light"])
def test_the_page_holds_the_finder_s_glints_per_view(
        folders: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str],
        kind: str) -> None:
    folder = folders[kind]
    page = tmp_path / "view.html"
    _run(["view", folder, "--step", "2", "--out", page], capsys)
    meta, start, xyz = page_views(page)
    az, el = meta["views"]["azimuths"], meta["views"]["elevations"]
    states = meta["views"].get("states", [])
    assert len(start) - 1 == len(az) * len(el) * max(len(states), 1)
    if kind in ("spin", "steady", "light"):
        # still eyes: the design's two, along the motion
        assert len(az) == 2 and len(states) > 3 and meta["motion"]["name"]
    else:  # the head walks: views over the viewing range
        assert not states and len(az) > 5
    cam = meta["camera"]
    checked = 0
    for i in (0, len(az) - 1):
        for k in ((0, len(states) // 2, len(states) - 1) if states else (0,)):
            view = (i * len(el)) * max(len(states), 1) + k
            got = xyz[start[view]:start[view + 1]]
            eye = Camera(math.radians(az[i]), 0.0, cam["distance"], 1.0, 2, 2,
                         cam["eyeHeight"]).position()
            state = math.radians(states[k]) if states else None
            want = _finder(kind, folder, eye, state)
            assert len(got) == len(want) > 0
            # the same glints, each to within the page's quantization
            d, _ = cKDTree(want).query(got)
            assert d.max() < np.linalg.norm(meta["quant"]["scale"]), d.max()
            checked += 1
    assert checked >= 2


def _finder(kind: str, folder: Path, eye: np.ndarray, state: float | None) -> np.ndarray:
    """The kind's own glints for an eye (world frame) at a state, radians."""
    if kind == "spin":
        from specholo.jobs.spin.design import load_spin_folder
        from specholo.simulation.spinning import find_spin_glints
        from specholo.toolpaths.spinning import rotate_z

        job = load_spin_folder(folder)
        assert state is not None
        return rotate_z(find_spin_glints(job.design, rotate_z(eye, -state),
                                         job.config.tool).point, state)
    if kind == "steady":
        from specholo.jobs.steady.design import load_steady_folder
        from specholo.simulation.steady import find_steady_glints

        design, config = load_steady_folder(folder)
        return find_steady_glints(design, eye, design.setup.light(state), config.tool).point
    return _conforming(folder, eye, state)


def test_a_turning_plate_s_page_shows_the_view_and_angle_nearest(
        folders: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str],
        browser: Any) -> None:
    """In the browser: the page draws, for the angle nearest the slider's, a spot
    where the camera projects each glint it holds."""
    import io

    from PIL import Image
    from test_page import HUD
    from test_page import spots as page_spots

    w, h = 480, 360
    page_file = tmp_path / "view.html"
    _run(["view", folders["spin"], "--step", "10", "--out", page_file, "--width", w,
          "--height", h], capsys)
    _, start, xyz = page_views(page_file)
    page = browser.new_page(viewport={"width": w + 20, "height": h + HUD + 20},
                            device_scale_factor=1)
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(page_file.as_uri())
    page.wait_for_function("window.specholo && (window.specholo.ready "
                           "|| window.specholo.error)")
    assert page.evaluate("window.specholo.error") is None
    seen = set()
    for az, angle in ((-4.0, 3.0), (4.0, 118.0), (-4.0, 248.0)):
        view = page.evaluate(f"window.specholo.setView({az}, 0, {angle})")
        # the nearest angle on the circle: 355 is nearest 0
        assert abs(view["viewState"] - angle) <= 5
        shot = page.locator("#view").screenshot()
        found = page_spots(np.asarray(Image.open(io.BytesIO(shot)).convert("L")))
        cam = Camera(math.radians(view["viewAzimuth"]), math.radians(view["viewElevation"]),
                     view["distance"], math.radians(view["fov"]), view["width"],
                     view["height"], view["eyeHeight"])
        pts = xyz[start[view["view"]]:start[view["view"] + 1]]
        pixel = cam.project(pts).pixel
        assert view["glints"] == len(pts) > 5
        d, _ = cKDTree(pixel).query(found)
        assert len(found) and d.max() < 1.0
        seen.add(view["view"])
    page.close()
    assert len(seen) == 3 and not errors


# ---------------------------------------------------------------- reports


@pytest.mark.parametrize("kind", ["cup", "light", "spin", "steady"])
def test_the_report_names_the_kind_s_verified_figures(
        folders: dict[str, Path], capsys: pytest.CaptureFixture[str], kind: str) -> None:
    folder = folders[kind]
    _run(["report", folder], capsys)
    page = (folder / "report.html").read_text()
    verify = json.loads((folder / "verify.json").read_text())
    assert "<script" not in page and "Not verified yet" not in page
    for key, value in verify["summary"].items():
        label = key.replace("_", " ")
        assert f"<th>{label}</th>" in page, key
        if isinstance(value, float):
            assert f"<td>{value:.3f}</td>" in page, key
    # a row per verified position, under its kind's own columns
    rows = verify[verify["rows"]]
    assert page.count("<tr><td>") == len(rows)
    for column in rows[0]:
        assert f"<th>{column.replace('_', ' ')}</th>" in page
    assert f"{verify['figures']['worst_p95_mm']:.3f} mm" in page


@pytest.mark.parametrize("kind, argv, says", [
    ("flat", ["render", "--at", "5"], "--azimuth"),
    ("cup", ["stereo", "--at", "5"], "--azimuth"),
    ("flat", ["animate", "--kind", "turn"], "turntable, light"),
    ("spin", ["animate", "--kind", "light"], "turn, turntable"),
    ("spin", ["animate", "--at", "30"], "--kind turntable"),
    ("steady", ["render", "--at", "190"], "light elevation"),
    ("light", ["render", "--at", "-5"], "light elevation"),
    ("spin", ["render", "--at", "inf"], "--at"),
    ("ridged", ["render", "--grooves"], "no grooves"),
    ("spin", ["view", "--step", "0.01"], "view step"),
])
def test_a_state_or_motion_a_kind_has_not_is_refused_in_one_line(
        folders: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str],
        kind: str, argv: list[str], says: str) -> None:
    folder = folders[kind]
    before = sorted(p.name for p in folder.iterdir())
    out = tmp_path / ("x.gif" if argv[0] == "animate" else
                      "x.html" if argv[0] == "view" else "x.png")
    code = main([argv[0], str(folder), *argv[1:], "--out", str(out)])
    err = capsys.readouterr().err
    assert code != 0 and err.startswith("error: ") and err.count("\n") == 1, err
    assert says in err, err
    assert sorted(p.name for p in folder.iterdir()) == before and not out.exists()
