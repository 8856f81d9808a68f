"""Ridged (full-parallax) designs from the command line: files, G-code, verification,
stills and the interactive page."""

from __future__ import annotations

import io
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial import cKDTree

from specholo.fabrication.check import Stock, check_gcode
from specholo.fabrication.heightmap import load_ridged, read_image
from specholo.jobs.ridged.design import load_ridged_design
from specholo.preview.page import FieldViews
from specholo.preview.render import Camera, field_glint_pixels, field_plate, plate_camera
from specholo_cli.cli import main

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"
# The bunny at 60 mm, 40 mm behind the plate; heads +-30 deg azimuth, +-15 elevation;
# a coarse raster keeps the plate small (2,250 x 1,700 cells).
RIDGED = ["--method", "ridged", "--stipples", "150", "--view-range", "30",
          "--elevation-range", "15", "--raster", "0.05"]
# A smaller plate still: narrow ranges, few stipples, height maps only.
TINY = ["--method", "ridged", "--stipples", "40", "--view-range", "8",
        "--elevation-range", "4", "--raster", "0.05", "--formats", "png"]
FILES = {"hologram.json", "plate.npz", "stipples.npz", "model.ply", "heightmap.png",
         "heightmap.tif", "heightmap.json", "hologram.stl", "hologram.gcode", "preview.png"}


def run(argv: list[Any], capsys) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def designed(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("ridged") / "holo"
    assert main(["design", str(BUNNY), "--out", str(out), *RIDGED]) == 0
    return out


def test_design_writes_every_file(designed: Path):
    names = {p.name for p in designed.iterdir()}
    assert FILES <= names and names - FILES <= {"verify.json", "verify.png", "run.json"}
    # Staged beside the folder and moved in: nothing left over.
    assert [p.name for p in designed.parent.iterdir()] == [designed.name]
    info = json.loads((designed / "hologram.json").read_text())
    assert info["design"] == "ridged" and info["settings"]["method"] == "ridged"
    assert info["settings"]["tool"] == "ball" and set(info["files"]) == FILES
    stipples = info["stipples"]
    assert len(stipples) == 150
    kept = [s for s in stipples if not s["dropped"]]
    assert len(kept) == info["ridged"]["kept_stipples"] > 50
    assert all(0 < s["kept_share"] <= 1 for s in kept)
    assert all(s["kept_share"] == 0 for s in stipples if s["dropped"])
    # A dropped stipple is one no eye in the ranges sees (the bunny's far side).
    assert all(s["visible_share"] == 0 for s in stipples if s["dropped"])
    assert info["ridged"]["shell_mm"] == [-0.2, 0.0]
    # The 16-bit height maps give back the exact heights to their quantisation step.
    exact = load_ridged(designed)
    assert exact.z.min() >= -0.2 - 1e-6 and exact.z.max() <= 0.0
    for name in ("heightmap.png", "heightmap.tif"):
        back = read_image(designed / name)
        step = (exact.z.max() - exact.z.min()) / 65535
        assert np.max(np.abs(back.z - exact.z)) <= 0.5 * step + 1e-6
        np.testing.assert_allclose(back.origin, exact.origin)


def test_gcode_passes_the_safety_check(designed: Path):
    info = json.loads((designed / "hologram.json").read_text())
    assert info["machining"]["safety_check"]["violations"] == 0
    (x0, y0), (x1, y1) = info["plate"]["plate_mm"]
    r = info["tool"]["ball_radius_mm"]
    s = info["settings"]
    # The ball's centre stays a radius inside the plate, no deeper than the shell.
    report = check_gcode(designed / "hologram.gcode", Stock(x0 + r, y0 + r, x1 - r, y1 - r, 3.0),
                         max_depth=0.2, safe_z=s["safe_z"],
                         feed_range=(s["plunge"], s["feed"]),
                         spindle_range=(s["spindle"], s["spindle"]))
    assert report.ok, report.summary()
    assert report.moves["cutting"] > 100_000
    # the header names the plate the program was made for, as a grooved plate's does
    head = (designed / "hologram.gcode").read_text().split("G21", 1)[0]
    thick = s["stock_thickness"]
    assert (f"(plate: {x1 - x0:g} x {y1 - y0:g} mm, {thick:g} mm thick, corners "
            f"X{x0:g} Y{y0:g} to X{x1:g} Y{y1:g})") in head
    # a ridged design draws no marks: the header names none and sets zero at the centre
    assert "(plate zero: X0 Y0 at the plate centre" in head and "plate marks" not in head


@pytest.mark.slow
def test_verify_over_azimuth_and_elevation(designed: Path, capsys):
    code, out, _ = run(["verify", designed], capsys)
    assert code == 0 and "p95 error" in out
    result = json.loads((designed / "verify.json").read_text())
    assert result["method"] == "ridged" and result["source"] == "plate.npz"
    views = result["views"]
    assert {round(v["azimuth"], 6) for v in views} == set(np.arange(-30.0, 30.1, 5.0))
    assert {round(v["elevation"], 6) for v in views} == set(np.arange(-15.0, 15.1, 5.0))
    glinting = [v for v in views if not math.isnan(v["p95_error"])]
    # Most heads see stipples in stereo, all over the ranges. Each sees a few
    # (1 to 8 of 150), so a head's p95 is nearly its worst glint: nearly all
    # heads' apparent points are within 0.25 mm of the stipples, and every one
    # within 0.5 mm. The 0.05 mm raster places a glint to within a cell, and
    # one cell of disparity between eyes 64 mm apart at 600 mm moves a point
    # 40 mm behind the plate by (640 mm)^2 / (64 mm 600 mm) x 0.05 mm = 0.53 mm.
    assert len(glinting) >= 0.7 * len(views)
    for key in ("azimuth", "elevation"):
        values = [v[key] for v in glinting]
        assert min(values) < -10 and max(values) > 10
    assert sum(v["p95_error"] < 0.25 for v in glinting) >= 0.95 * len(glinting)
    assert max(v["max_error"] for v in glinting) < 0.5
    assert result["summary"]["max_false_glints"] < 0.02
    assert (designed / "verify.png").is_file()


def test_a_light_size_is_refused_on_a_ridged_plate(designed: Path, capsys):
    """Streaks are followed along grooves: a ridged plate has none, and says so."""
    before = (designed / "verify.json").stat().st_mtime_ns if (designed / "verify.json").exists() \
        else None
    code, _, err = run(["verify", designed, "--light-size", "0.53"], capsys)
    assert code != 0 and "for grooved flat-plate designs" in err
    assert len(err.strip().splitlines()) == 1
    after = (designed / "verify.json").stat().st_mtime_ns if (designed / "verify.json").exists() \
        else None
    assert after == before
    code, _, err = run(["render", designed, "--light-size", "0.53", "--out",
                        designed / "streaks.png"], capsys)
    assert code != 0 and "for flat-plate designs" in err
    assert not (designed / "streaks.png").exists()


@pytest.mark.parametrize("azimuth, elevation", [(-20.0, -8.0), (0.0, 0.0), (15.0, 10.0)])
def test_render_spots_are_the_glints(designed: Path, tmp_path: Path, capsys,
                                     azimuth: float, elevation: float):
    from PIL import Image
    from test_render import spots

    out = tmp_path / "still.png"
    code, _, err = run(["render", designed, "--azimuth", azimuth, "--elevation", elevation,
                        "--width", 1024, "--height", 768, "--out", out], capsys)
    assert code == 0, err
    loaded = load_ridged_design(designed)
    setup = loaded.config.setup()
    camera = plate_camera(setup, field_plate(loaded.heights), math.radians(azimuth),
                          math.radians(elevation), width=1024, height=768)
    glints = field_glint_pixels(loaded.heights, setup, camera)
    assert glints.valid.all() and len(glints.pixel) >= 2  # 150 stipples: a few glint per eye
    found, _ = spots(np.asarray(Image.open(out).convert("RGB")))
    assert len(found) == len(glints.pixel)
    d, _ = cKDTree(glints.pixel).query(found)
    assert d.max() < 2.0
    d, _ = cKDTree(found).query(glints.pixel)
    assert d.max() < 2.0


def test_page_is_self_contained(designed: Path, tmp_path: Path, capsys):
    page = tmp_path / "view.html"
    code, out, _ = run(["view", designed, "--step", "5", "--out", page], capsys)
    assert code == 0 and "interactive page" in out
    text = page.read_text()
    assert "http://" not in text and "https://" not in text
    assert "<script src" not in text and "<link" not in text
    assert '"mode": "field"' in text


@pytest.mark.slow
def test_page_shows_the_glints_of_the_nearest_view(designed: Path, tmp_path: Path, capsys):
    from conftest import CHROMIUM, CHROMIUM_ARGS
    from test_page import HUD, H, W, spots

    if not Path(CHROMIUM).exists():
        pytest.skip("Chromium not installed at /usr/bin/chromium")
    sync_api = pytest.importorskip("playwright.sync_api")
    from PIL import Image

    page_file = tmp_path / "view.html"
    assert run(["view", designed, "--step", "5", "--out", page_file, "--width", W,
                "--height", H], capsys)[0] == 0
    loaded = load_ridged_design(designed)
    setup = loaded.config.setup()
    total = 0
    with sync_api.sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": W + 20, "height": H + HUD + 20},
                                device_scale_factor=1)
        errors: list[str] = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.on("request", lambda r: errors.append(r.url)
                if not r.url.startswith(("file:", "data:", "blob:")) else None)
        page.goto(page_file.as_uri())
        page.wait_for_function("window.specholo && (window.specholo.ready "
                               "|| window.specholo.error)")
        assert page.evaluate("window.specholo.error") is None
        # Pointer angles between the views: the page shows the nearest one.
        for az, el in ((-21.0, -6.0), (1.5, 2.0), (13.0, 11.0)):
            view = page.evaluate(f"window.specholo.setView({az}, {el})")
            assert abs(view["viewAzimuth"] - az) <= 2.5 and abs(view["viewElevation"] - el) <= 2.5
            shot = page.locator("#view").screenshot()
            found = spots(np.asarray(Image.open(io.BytesIO(shot)).convert("L")))
            ref = FieldViews.build(loaded.heights, setup, np.array([view["viewAzimuth"]]),
                                   np.array([view["viewElevation"]]))
            camera = Camera(math.radians(view["viewAzimuth"]),
                            math.radians(view["viewElevation"]), view["distance"],
                            math.radians(view["fov"]), view["width"], view["height"],
                            view["eyeHeight"])
            pixel = camera.project(ref.points).pixel
            assert view["glints"] == len(pixel) == len(found)
            if len(pixel):
                d, _ = cKDTree(pixel).query(found)
                assert d.max() < 0.5
            total += len(pixel)
        browser.close()
    assert total >= 5 and not errors


def _one_line_error(argv: list[Any], capsys) -> str:
    code, _, err = run(argv, capsys)
    assert code != 0, argv
    assert err.startswith("error: ") and err.count("\n") == 1 and "Traceback" not in err, err
    return err


def test_bad_ridged_settings_are_one_line_and_write_nothing(tmp_path: Path, capsys):
    toml = tmp_path / "bad.toml"
    toml.write_text("method = 'ridged'\nshell = 'thick'\n")
    bad = [
        (["--shell", "-0.1"], "shell"),
        (["--shell", "2"], "stock thickness"),
        (["--raster", "0"], "raster"),
        (["--raster", "5"], "raster"),
        (["--elevation-range", "85"], "elevation-range"),
        (["--elevation-range", "nan"], "elevation-range"),
        (["--tool", "drag"], "ball"),
        (["--units", "inch"], "mm"),
        (["--dialect", "marlin"], "laser"),
        (["--tool-radius", "0.01"], "raster"),
        (["--depth", "0.1"], "shell"),
        (["--formats", "svg"], "png, tiff, stl, gcode"),
        (["--plate-width", "50"], "plate-height"),
        (["--spindle", "0"], "spindle"),
        (["--config", toml], "shell"),
    ]
    for extra, message in bad:
        out = tmp_path / "out"
        err = _one_line_error(["design", BUNNY, "--out", out, "--method", "ridged", *extra],
                              capsys)
        assert message in err, (extra, err)
        assert not out.exists(), extra
        assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml"], extra


def test_ridged_folder_refuses_groove_options(designed: Path, tmp_path: Path, capsys):
    before = sorted(p.name for p in designed.iterdir())
    assert "no grooves" in _one_line_error(
        ["render", designed, "--grooves", "--out", tmp_path / "r.png"], capsys)
    assert "height field" in _one_line_error(["verify", designed, "--cut"], capsys)
    assert "ridged" in _one_line_error(["animate", designed, "--kind", "turn", "--out",
                                        tmp_path / "t.gif"], capsys)
    assert "--azimuth" in _one_line_error(["stereo", designed, "--at", "10", "--out",
                                           tmp_path / "s.png"], capsys)
    assert sorted(p.name for p in designed.iterdir()) == before
    assert list(tmp_path.iterdir()) == []


def test_failed_safety_check_leaves_no_folder(tmp_path: Path, capsys,
                                              monkeypatch: pytest.MonkeyPatch):
    """A program that leaves the plate is refused before any file is kept."""
    from specholo.fabrication import heightmap

    real = heightmap.write_raster_gcode

    def off_the_plate(path: Any, *args: Any, **kwargs: Any) -> Any:
        stats = real(path, *args, **kwargs)
        text = Path(path).read_text().replace("M2\n", "G1 X500 Z-0.05 F300\nM2\n")
        Path(path).write_text(text)
        return stats

    monkeypatch.setattr(heightmap, "write_raster_gcode", off_the_plate)
    out = tmp_path / "out"
    argv = ["design", BUNNY, "--out", out, *TINY[:-2], "--formats", "gcode"]
    assert "safety check" in _one_line_error(argv, capsys)
    assert list(tmp_path.iterdir()) == []


def test_a_new_design_replaces_the_other_kind(tmp_path: Path, capsys):
    out = tmp_path / "out"
    assert run(["design", BUNNY, "--out", out, *TINY], capsys)[0] == 0
    assert {"plate.npz", "heightmap.png", "heightmap.json"} <= {p.name for p in out.iterdir()}
    assert run(["design", BUNNY, "--out", out, "--stipples", "40"], capsys)[0] == 0
    names = {p.name for p in out.iterdir()}
    assert "grooves.npz" in names and not names & {"plate.npz", "heightmap.png",
                                                   "heightmap.json"}
    assert run(["verify", out], capsys)[0] == 0
    assert json.loads((out / "verify.json").read_text())["method"] == "striped"
    assert run(["design", BUNNY, "--out", out, *TINY], capsys)[0] == 0
    names = {p.name for p in out.iterdir()}
    assert not names & {"grooves.npz", "hologram.svg", "hologram.gcode", "verify.json"}
    assert "preview.png" in names  # the ridged plate's own
    assert load_ridged_design(out).heights.labels is not None
