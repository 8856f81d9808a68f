"""Rendered pictures: every glint where the glint physics puts it, and nothing else."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage
from scipy.spatial import cKDTree

from specholo.errors import SpecholoError
from specholo.jobs.flat.folder import Loaded, load_design
from specholo.preview.motion import light_sweep, sweep, turntable, write_animation
from specholo.preview.render import (
    Camera,
    design_camera,
    glint_pixels,
    luminance,
    render_still,
    save_png,
)
from specholo.preview.stereo import anaglyph, head_camera, side_by_side, stereo_cameras, stereo_pair
from specholo.setup import Tool
from specholo.simulation.glints import Engraved
from specholo_cli.cli import main

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"
SIZE = (1024, 512)


@pytest.fixture(scope="module")
def folder(small_design: Path) -> Path:
    return small_design


@pytest.fixture(scope="module")
def loaded(folder: Path) -> Loaded:
    return load_design(folder)


@pytest.fixture(scope="module")
def engraved(loaded: Loaded) -> Engraved:
    return Engraved.from_grooves(loaded.grooves, loaded.config.setup().tool)


def spots(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bright local maxima of an image: sub-pixel centres (k, 2) as (column, row), and
    their sizes (k,) as the number of pixels above half the spot's peak."""
    lum = luminance(image).astype(float)
    background = float(np.median(lum))
    peak = (lum == ndimage.maximum_filter(lum, size=5)) & (lum > background + 90)
    labels, n = ndimage.label(peak)
    seeds = np.rint(ndimage.center_of_mass(peak, labels, range(1, n + 1))).astype(int)
    centres, sizes = [], []
    for r, c in seeds.reshape(-1, 2):
        win = lum[r - 4:r + 5, c - 4:c + 5] - background
        core = np.clip(win[2:7, 2:7], 0, None)
        rr, cc = np.mgrid[-2:3, -2:3]
        centres.append([c + (core * cc).sum() / core.sum(), r + (core * rr).sum() / core.sum()])
        sizes.append(int((win > 0.5 * win.max()).sum()))
    return np.array(centres).reshape(-1, 2), np.array(sizes)


def separated(pixel: np.ndarray, gap: float = 5.0) -> np.ndarray:
    """Mask of points with no other point closer than gap pixels."""
    d, _ = cKDTree(pixel).query(pixel, k=2)
    return d[:, 1] > gap


@pytest.mark.parametrize("azimuth", [-20.0, 0.0, 25.0])
def test_spots_are_the_glints_for_that_camera(loaded: Loaded, engraved: Engraved,
                                               azimuth: float):
    setup = loaded.config.setup()
    cam = design_camera(setup, loaded.grooves, math.radians(azimuth), width=SIZE[0],
                        height=SIZE[1])
    glints = glint_pixels(loaded.grooves, setup, cam, engraved=engraved)
    assert glints.valid.all() and len(glints.pixel) > 30
    inside = ((glints.pixel > 5) & (glints.pixel < np.array(SIZE) - 5)).all(axis=1)
    assert inside.all()
    assert separated(glints.pixel).all()  # the tiny design's glints are > 4 spot widths apart

    found, _ = spots(render_still(loaded.grooves, setup, cam, engraved=engraved))
    # As many spots as glints, each within 1.5 px of its glint's projection.
    assert len(found) == len(glints.pixel)
    d, _ = cKDTree(glints.pixel).query(found)
    assert d.max() < 1.5
    d, _ = cKDTree(found).query(glints.pixel)
    assert d.max() < 1.5


def test_elevation_zero_camera_is_the_designs_eye(loaded: Loaded):
    setup = loaded.config.setup()
    theta = math.radians(17.0)
    cam = design_camera(setup, loaded.grooves, theta)
    assert np.allclose(cam.position(), setup.viewer.eye(np.array([theta]))[0])
    centre = cam.project(np.zeros((1, 3)))
    assert np.allclose(centre.pixel, [[(cam.width - 1) / 2, (cam.height - 1) / 2]])
    assert np.allclose(centre.depth, np.linalg.norm(cam.position()))
    same = Camera.at(cam.position(), cam.fov, cam.width, cam.height, cam.eye_height)
    assert np.allclose([same.azimuth, same.elevation, same.distance],
                       [cam.azimuth, cam.elevation, cam.distance])


def test_roughness_changes_spot_size_not_position(loaded: Loaded, engraved: Engraved):
    # Spots of a 0.37 mm groove are resolved at this scale (a fine tip's are points).
    setup = dataclasses.replace(loaded.config.setup(), tool=Tool(0.25, 0.08))
    cam = design_camera(setup, loaded.grooves, math.radians(-10.0), width=SIZE[0],
                        height=SIZE[1])
    smooth = render_still(loaded.grooves, setup, cam, math.radians(1.0), engraved=engraved)
    rough = render_still(loaded.grooves, setup, cam, math.radians(2.5), engraved=engraved)
    at_smooth, size_smooth = spots(smooth)
    at_rough, size_rough = spots(rough)
    glints = glint_pixels(loaded.grooves, setup, cam, engraved=engraved).pixel
    assert len(at_smooth) == len(at_rough) == len(glints) > 30
    # Both land on the glints; only wide spots' overlapping tails shift a centroid a little.
    for found in (at_smooth, at_rough):
        assert cKDTree(glints).query(found)[0].max() < 1.5
    d, j = cKDTree(at_rough).query(at_smooth)
    assert np.median(d) < 0.3
    assert len(set(j.tolist())) == len(j)
    assert np.median(size_rough[j] / size_smooth) > 3.0  # spot area ~ roughness^2
    peaks_smooth = luminance(smooth)[tuple(np.rint(at_smooth[:, ::-1]).astype(int).T)]
    peaks_rough = luminance(rough)[tuple(np.rint(at_rough[:, ::-1]).astype(int).T)]
    assert np.median(peaks_rough) < np.median(peaks_smooth)  # and dimmer


def test_overlays_leave_the_glints_in_place(loaded: Loaded, engraved: Engraved):
    setup = loaded.config.setup()
    cam = design_camera(setup, loaded.grooves, 0.3, width=SIZE[0], height=SIZE[1])
    plain = render_still(loaded.grooves, setup, cam, engraved=engraved)
    extra = render_still(loaded.grooves, setup, cam, grooves_overlay=True, ghost=loaded.mesh,
                         engraved=engraved)
    assert extra.shape == plain.shape == (SIZE[1], SIZE[0], 3) and extra.dtype == np.uint8
    assert (extra.astype(int) - plain).sum() > 0  # the overlays add faint light
    glints = glint_pixels(loaded.grooves, setup, cam, engraved=engraved).pixel
    for image in (plain, extra):
        found, _ = spots(image)
        assert len(found) == len(glints)
        assert cKDTree(glints).query(found)[0].max() < 1.5


def test_anaglyph_channels_are_the_eyes_luminance(loaded: Loaded, engraved: Engraved):
    setup = loaded.config.setup()
    head = head_camera(setup, loaded.grooves, math.radians(10.0), 256, 160)
    left_cam, right_cam = stereo_cameras(head, setup.viewer.ipd)
    assert np.linalg.norm(left_cam.position() - right_cam.position()) == pytest.approx(64.0)
    assert left_cam.position()[0] < right_cam.position()[0]
    assert left_cam.distance == pytest.approx(setup.viewer.eye_radius)
    left, right = stereo_pair(loaded.grooves, setup, head, engraved=engraved)
    assert not np.array_equal(left, right)
    ana = anaglyph(left, right)
    assert np.array_equal(ana[..., 0], luminance(left))
    assert np.array_equal(ana[..., 1], luminance(right))
    assert np.array_equal(ana[..., 2], luminance(right))
    par = side_by_side(left, right, "parallel", gap=4)
    cross = side_by_side(left, right, "cross")
    assert np.array_equal(par[:, :256], left) and np.array_equal(par[:, 260:], right)
    assert np.array_equal(cross[:, :256], right) and np.array_equal(cross[:, 256:], left)


def test_animations_have_the_requested_frames(loaded: Loaded, tmp_path: Path):
    import imageio.v3 as iio

    calls: list[tuple[int, int]] = []
    frames = turntable(loaded, 7, (65, 49), progress=lambda d, t: calls.append((d, t)))
    assert calls == [(i, 7) for i in range(1, 8)]
    assert len(frames) == 7 and frames[0].shape == (49, 65, 3)
    assert not np.array_equal(frames[0], frames[3])  # the view moves
    write_animation(frames, tmp_path / "t.gif", fps=12)
    write_animation(frames, tmp_path / "t.mp4", fps=12)
    assert iio.imread(tmp_path / "t.gif", index=None).shape[0] == 7
    video = iio.imread(tmp_path / "t.mp4", index=None)
    assert video.shape == (7, 50, 66, 3)  # yuv420p needs even sides
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.gif", "t.mp4"]
    lit = light_sweep(loaded, 3, (40, 30), span=math.radians(10.0))
    assert len(lit) == 3
    assert np.allclose(sweep(-1.0, 1.0, 4), [-1.0, 0.0, 1.0, 0.0])
    assert np.allclose(sweep(-1.0, 1.0, 3, loop=False), [-1.0, 0.0, 1.0])


def test_save_png_round_trips(tmp_path: Path):
    from PIL import Image

    img = np.random.default_rng(0).integers(0, 256, (7, 9, 3), dtype=np.uint8)
    save_png(img, tmp_path / "a.png")
    assert np.array_equal(np.asarray(Image.open(tmp_path / "a.png")), img)
    assert [p.name for p in tmp_path.iterdir()] == ["a.png"]


def test_cli_commands_write_their_files(folder: Path, tmp_path: Path, capsys):
    from PIL import Image

    out = tmp_path / "r.png"
    assert main(["render", str(folder), "--azimuth", "-25", "--width", "96", "--height", "64",
                 "--grooves", "--ghost", "--out", str(out)]) == 0
    assert Image.open(out).size == (96, 64)
    assert main(["stereo", str(folder), "--mode", "cross", "--width", "80", "--height", "60",
                 "--out", str(tmp_path / "s.png")]) == 0
    assert Image.open(tmp_path / "s.png").size[0] > 160
    assert main(["animate", str(folder), "--frames", "3", "--width", "40", "--height", "30",
                 "--kind", "light", "--out", str(tmp_path / "a.gif")]) == 0
    assert (tmp_path / "a.gif").is_file()
    capsys.readouterr()


@pytest.mark.parametrize("args, message", [
    (["render", "{missing}"], "does not exist"),
    (["render", "{folder}", "--fov", "0"], "fov"),
    (["render", "{folder}", "--fov", "180"], "fov"),
    (["render", "{folder}", "--azimuth", "95"], "not in front of the plate"),
    (["render", "{folder}", "--roughness", "-1"], "roughness"),
    (["render", "{folder}", "--width", "0"], "width"),
    (["render", "{folder}", "--out", "{tmp}/x.jpg"], ".png"),
    (["animate", "{folder}", "--frames", "0"], "frames"),
    (["animate", "{folder}", "--out", "{tmp}/x.avi"], ".gif or .mp4"),
    (["animate", "{folder}", "--fps", "0"], "fps"),
    (["animate", "{missing}"], "does not exist"),
    (["stereo", "{folder}", "--out", "{tmp}/nowhere/x.png"], "does not exist"),
    (["stereo", "{folder}", "--fov", "nan"], "fov"),
])
def test_bad_input_is_one_line(folder: Path, tmp_path: Path, capsys, args: list[str],
                               message: str):
    argv = [a.format(folder=folder, missing=tmp_path / "missing", tmp=tmp_path) for a in args]
    before = sorted(p.name for p in folder.iterdir())
    code = main(argv)
    _, err = capsys.readouterr()
    assert code == 1
    assert err.startswith("error: ") and err.count("\n") == 1 and message in err, err
    assert sorted(p.name for p in folder.iterdir()) == before
    assert list(tmp_path.iterdir()) == []


def test_library_refuses_bad_values(loaded: Loaded, tmp_path: Path):
    setup = loaded.config.setup()
    with pytest.raises(SpecholoError, match="field of view"):
        Camera(0.0, 0.0, 600.0, math.pi, 10, 10)
    with pytest.raises(SpecholoError, match="distance"):
        Camera(0.0, 0.0, -1.0, 0.5, 10, 10)
    cam = design_camera(setup, loaded.grooves, width=16, height=16)
    with pytest.raises(SpecholoError, match="roughness"):
        render_still(loaded.grooves, setup, cam, roughness=float("nan"))
    with pytest.raises(SpecholoError, match="frames"):
        turntable(loaded, 0)
    with pytest.raises(SpecholoError, match=".gif or .mp4"):
        write_animation([np.zeros((4, 4, 3), np.uint8)], tmp_path / "a.webm")
    with pytest.raises(SpecholoError, match="parallel or cross"):
        side_by_side(np.zeros((2, 2, 3), np.uint8), np.zeros((2, 2, 3), np.uint8), "anaglyph")
    with pytest.raises(SpecholoError, match="one size"):
        anaglyph(np.zeros((2, 2, 3), np.uint8), np.zeros((2, 3, 3), np.uint8))


def test_a_big_design_renders_a_run_of_paths_at_a_time(loaded: Loaded,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """Past the chunk size a still finds its glints a run of paths at a time; each
    glint lies on one path, so the picture is the same."""
    import specholo.simulation.verify as verify_module

    setup = loaded.config.setup()
    cam = design_camera(setup, loaded.grooves, width=320, height=240)
    whole = render_still(loaded.grooves, setup, cam)
    monkeypatch.setattr(verify_module, "CHUNK_VERTICES", max(len(loaded.grooves.vertices) // 7,
                                                             10))
    parts = render_still(loaded.grooves, setup, cam)
    assert np.abs(whole.astype(int) - parts.astype(int)).max() <= 1
    assert luminance(whole).max() > 150  # there are glints to compare


def test_a_big_design_is_searched_a_run_of_paths_at_a_time(loaded: Loaded,
                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """The glints each of three eyes sees, found chunk by chunk (each chunk indexed
    once for all of them), are those of the whole design."""
    import specholo.simulation.verify as verify_module
    from specholo.preview.render import glints_seen

    setup = loaded.config.setup()
    eyes = setup.viewer.eye(np.radians([-20.0, 0.0, 20.0]))
    whole = glints_seen(loaded.grooves, setup.tool, eyes, setup.light)
    monkeypatch.setattr(verify_module, "CHUNK_VERTICES", max(len(loaded.grooves.vertices) // 7,
                                                             10))
    parts = glints_seen(loaded.grooves, setup.tool, eyes, setup.light)
    for w, p in zip(whole, parts, strict=True):
        assert len(w) > 20  # there are glints to compare
        np.testing.assert_allclose(np.unique(p, axis=0), np.unique(w, axis=0), atol=1e-9)


def test_preview_dots_are_the_glints_each_eye_sees(small_design: Path, tmp_path: Path) -> None:
    """preview.png: in each panel, a dot wherever that eye's glint projects, and
    nothing lit inside the plate where no glint is."""
    import math

    from PIL import Image

    from specholo.jobs.flat.folder import load_design
    from specholo.preview.preview import PANEL, panel_transform, project, render_preview
    from specholo.preview.render import glints_seen

    loaded = load_design(small_design)
    setup = loaded.config.setup()
    out = tmp_path / "preview.png"
    render_preview(loaded.grooves, setup, out)
    img = np.asarray(Image.open(out).convert("L"))
    w, h, title = PANEL
    az = [-30.0, 0.0, 30.0]
    assert img.shape == (h, w * len(az))
    eyes = setup.viewer.eye(np.radians(az))
    lo, hi = loaded.grooves.bounds()
    corners = np.array([[lo[0], lo[1], 0], [hi[0], lo[1], 0], [hi[0], hi[1], 0],
                        [lo[0], hi[1], 0]])
    for k, (eye, points) in enumerate(zip(eyes, glints_seen(loaded.grooves, setup.tool,
                                                            eyes, setup.light), strict=True)):
        assert len(points) > 20
        offset, scale = panel_transform(project(corners, eye), k)
        uv = offset + scale * project(points, eye) * np.array([1.0, -1.0])
        lit = img[np.floor(uv[:, 1]).astype(int), np.floor(uv[:, 0]).astype(int)]
        assert np.all(lit > 200)
        # away from every glint (3 px), inside the plate's outline: dark
        rows, cols = np.nonzero(img[title:, k * w:(k + 1) * w] > 200)
        rows, cols = rows + title, cols + k * w
        near = np.min(np.hypot(rows[:, None] - uv[None, :, 1], cols[:, None] - uv[None, :, 0]),
                      axis=1)
        inside = (cols > uv[:, 0].min() - 3) & (cols < uv[:, 0].max() + 3)
        assert np.all(near[inside] < 3.0) or math.isclose(len(points), 0)


# -- the verification chart, drawn in a second process --------------------------------

_ROWS = [{"azimuth": a, "median_error": 0.05 + 0.001 * a, "p95_error": 0.15,
          "p95_depth_error": 0.1, "visibility": 0.99, "false_glints": 0.0}
         for a in (-45.0, -20.0, 0.0, 20.0, 45.0)]


def test_the_chart_drawn_in_a_second_process_is_the_same_png(tmp_path: Path):
    from PIL import Image

    from specholo.preview.chart import ChartDrawer, verification_png

    here = verification_png(_ROWS, "striped: stereo verification")
    with ChartDrawer() as drawer:
        assert drawer._process is not None and drawer._process.is_alive()
        drawer.plot_verification(_ROWS, tmp_path / "verify.png", "striped: stereo verification")
    assert (tmp_path / "verify.png").read_bytes() == here
    assert Image.open(tmp_path / "verify.png").size == (700, 600)


def test_the_chart_is_drawn_here_when_its_process_is_gone(tmp_path: Path):
    from specholo.preview.chart import ChartDrawer, verification_png

    drawer = ChartDrawer()
    drawer._process.terminate()
    drawer._process.join()
    assert drawer.verification_png(_ROWS) == verification_png(_ROWS)
    assert drawer._process is None  # closed: later charts are drawn here too
