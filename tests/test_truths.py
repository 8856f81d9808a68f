"""What the product states agrees with what is cut and what a maker meets: the
labels of every file of one design, the plate the pictures frame, the figures
verify names, and the summary in a maker's words."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from specholo_cli.cli import main

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"
# A plate larger than the grooves, the model moved off its centre: what the
# pictures frame is then visible.
PLATE = ["--plate-width", "100", "--plate-height", "80", "--offset-x", "5", "--center-z", "-15"]


def run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def fitted(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """A design fitted to a 100 x 80 mm plate with the formats a maker may ask for,
    and its summary."""
    import contextlib
    import io

    out = tmp_path_factory.mktemp("truths") / "holo"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["design", str(BUNNY), "--out", str(out), "--stipples", "200", "--fit",
                     "--formats", "gcode,svg,dxf", *PLATE])
    assert code == 0
    return out, buf.getvalue()


def _header(gcode: Path) -> str:
    return "\n".join(line for line in gcode.read_text().splitlines()[:30] if line.startswith("("))


def test_every_file_states_the_groove_as_cut(fitted: tuple[Path, str]):
    """The G-code header, hologram.json and the SVG and DXF layers give the same
    width and depth: those of the drag tip's cone at the design's depth, not of
    its round model (which stops where the sphere meets the cone)."""
    import ezdxf

    out, _ = fitted
    info = json.loads((out / "hologram.json").read_text())
    depth, width = info["tool"]["depth_mm"], info["tool"]["groove_width_mm"]
    head = _header(out / "hologram.gcode")
    got = float(re.search(r"groove width ([\d.]+) mm", head).group(1))  # type: ignore[union-attr]
    assert got == pytest.approx(width, abs=1e-5)
    assert float(re.search(r"\(depth: ([\d.]+) mm", head).group(1)) == pytest.approx(  # type: ignore[union-attr]
        depth, abs=1e-5)
    svg = (out / "hologram.svg").read_text()
    layer = re.search(r'inkscape:label="\d+ (GROOVES_D([\d.]+)_R[\d.]+)"', svg)
    assert layer is not None and float(layer.group(2)) == pytest.approx(depth, abs=1e-3)
    stroke = re.search(r'stroke-width="([\d.]+)"', svg)
    assert stroke is not None and float(stroke.group(1)) == pytest.approx(width, abs=1e-3)
    doc = ezdxf.readfile(out / "hologram.dxf")
    names = [layer.dxf.name for layer in doc.layers if layer.dxf.name.startswith("GROOVES")]
    assert names == [layer.group(1)]


def test_the_summary_names_the_plate_and_the_fitted_size(fitted: tuple[Path, str]):
    out, summary = fitted
    info = json.loads((out / "hologram.json").read_text())
    size = info["settings"]["size"]
    assert "plate: 100 x 80 mm, 3 mm thick (as given)" in summary
    assert f"--fit sized the model {size:g} mm" in summary


def test_the_pictures_frame_the_plate_not_the_grooves(fitted: tuple[Path, str],
                                                        capsys: pytest.CaptureFixture[str]):
    """The straight-on panel of preview.png outlines the 100 x 80 plate (its
    shape, 1.25:1), and a render draws the same plate."""
    out, _ = fitted
    img = np.asarray(Image.open(out / "preview.png").convert("L"))
    w = img.shape[1] // 3
    middle = img[34:, w:2 * w]  # below the title's band
    # The outline is the dim grey line (70), the glints are bright (235).
    rows, cols = np.nonzero(middle == 70)
    ratio = (cols.max() - cols.min()) / (rows.max() - rows.min())
    assert ratio == pytest.approx(100 / 80, rel=0.05)
    # The grooves, offset 5 mm to the right, are off the outline's centre there too.
    _, bright_c = np.nonzero(middle > 200)
    scale = (cols.max() - cols.min()) / 100.0
    shift = (bright_c.mean() - 0.5 * (cols.max() + cols.min())) / scale
    assert 1.0 < shift < 9.0
    code, _, _ = run(["render", out, "--width", "200", "--height", "200"], capsys)
    assert code == 0
    shot = np.asarray(Image.open(out / "render.png").convert("L")).astype(int)
    plate = shot > shot[0, 0] + 8  # the plate is drawn lighter than the background
    r, c = np.nonzero(plate)
    assert (c.max() - c.min()) / (r.max() - r.min()) == pytest.approx(100 / 80, rel=0.08)


def test_verify_names_the_ideal_and_the_as_cut_figures(fitted: tuple[Path, str],
                                                       capsys: pytest.CaptureFixture[str]):
    out, summary = fitted
    code, text, _ = run(["verify", out], capsys)
    assert code == 0
    assert "ideal grooves" in text
    stated = re.search(r"as cut, about (\d+)% of the stipples", summary)
    assert stated is not None
    assert f"as cut (the design's estimate; --cut simulates hologram.gcode): about " \
           f"{stated.group(1)}% of the stipples show in both eyes" in text
    assert not re.search(r"^worst p95", text, re.M)  # no unnamed figures


def test_the_summary_speaks_to_a_maker(fitted: tuple[Path, str]):
    """Plain words for the rate, the air travel and the wall slope; no jargon."""
    _, summary = fitted
    assert "stipples/s" not in summary and "unordered" not in summary
    assert "walls tilted" not in summary
    assert re.search(r"stipples an? (second|minute|hour) \(Brand's paper reports about 4 a "
                     r"second\)", summary)
    assert "in the air" in summary


def test_a_z_up_model_read_as_y_up_gets_a_hint(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]):
    """The bunny turned z-up and read without --up z lies on its back: most
    stipples face away from every view, and the summary says to try --up z
    (which the bunny as shipped, y-up, never hears)."""
    import trimesh

    mesh = trimesh.load(BUNNY, force="mesh")
    mesh.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    zup = tmp_path / "bunny_zup.obj"
    mesh.export(zup)
    code, out, err = run(["design", zup, "--out", tmp_path / "a", "--stipples", "200",
                          "--formats", "gcode"], capsys)
    assert code == 0
    assert "add --up z" in out + err
    code, out, err = run(["design", zup, "--up", "z", "--out", tmp_path / "b",
                          "--stipples", "200", "--formats", "gcode"], capsys)
    assert code == 0 and "--up z" not in out + err
    shutil.rmtree(tmp_path / "a")


def test_which_way_a_mesh_stands():
    """The flat base a part stands on names its up axis; a relief lying flat
    toward the viewer is shown as meant and hears nothing."""
    import trimesh

    from specholo.jobs.flat.design import up_hint
    from specholo.jobs.flat.folder import DesignConfig
    from specholo.scene.loading import Model
    from specholo.scene.mesh import Mesh
    from specholo.scene.pose import standing_up

    bunny = trimesh.load(BUNNY, force="mesh")
    assert standing_up(bunny.vertices, bunny.faces) == "y"
    turned = bunny.copy()
    turned.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0]))
    assert standing_up(turned.vertices, turned.faces) == "z"
    turned.apply_transform(trimesh.transformations.rotation_matrix(np.pi, [1, 0, 0]))
    assert standing_up(turned.vertices, turned.faces) == "-z"
    ball = trimesh.creation.icosphere(3)
    assert standing_up(ball.vertices, ball.faces) is None  # nothing to stand on
    plaque = trimesh.creation.box((40.0, 30.0, 3.0))
    model = Model(Mesh(plaque.vertices, plaque.faces), np.asarray(plaque.vertices))
    assert up_hint(model, DesignConfig()) == ""
    tower = trimesh.creation.cone(10.0, 40.0)  # standing on its base at z = 0
    model = Model(Mesh(tower.vertices, tower.faces), np.asarray(tower.vertices))
    assert "add --up z" in up_hint(model, DesignConfig())


def test_a_hand_pattern_gives_the_hand_s_time(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]):
    """Asked only for the printed pattern, the summary gives the strokes and the
    time by hand at the pattern's own 10 s a stroke, not a machine's time."""
    from specholo.fabrication.drawings.stroke_pattern import SECONDS_PER_STROKE
    from specholo.fabrication.programs.timing import plain_duration
    from specholo.toolpaths.grooves import Grooves

    out = tmp_path / "hand"
    code, text, err = run(["design", BUNNY, "--out", out, "--tool", "scriber", "--formats",
                           "pdf", "--stipples", "60"], capsys)
    assert code == 0, err
    info = json.loads((out / "hologram.json").read_text())
    grooves = Grooves.load(out / "grooves.npz", len(info["stipples"]))
    strokes = int(grooves.n_paths - grooves.is_dot.sum())
    assert f"by hand: {strokes:,} strokes" in text
    assert plain_duration(strokes * SECONDS_PER_STROKE) in text
    assert "machining:" not in text and "mm/min" not in text


def test_the_header_names_only_the_drawings_written(fitted: tuple[Path, str], tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]):
    out, _ = fitted
    assert "layer PLATE of the SVG and DXF" in _header(out / "hologram.gcode")
    code, _, err = run(["design", BUNNY, "--out", tmp_path / "g", "--stipples", "40",
                        "--formats", "gcode"], capsys)
    assert code == 0, err
    head = _header(tmp_path / "g" / "hologram.gcode")
    assert "in no drawing of this design" in head and "SVG" not in head


def test_a_model_facing_the_floor_gets_a_hint(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]):
    """A plaque standing upright in a z-up file (its face toward -y, as CAD's
    front view has it), read y-up, turns its face to the floor: most stipples
    face away from every view, and the summary says to try --up z, after which
    they face the viewer."""
    import trimesh

    plaque = trimesh.creation.box((40.0, 3.0, 30.0))
    path = tmp_path / "plaque.stl"
    plaque.export(path)
    code, out, err = run(["design", path, "--out", tmp_path / "a", "--stipples", "300",
                          "--formats", "gcode"], capsys)
    assert code == 0, err
    hidden = re.search(r"(\d+) of 300 stipples are hidden from every view", out + err)
    assert hidden is not None and int(hidden.group(1)) > 180
    assert "add --up z" in out + err
    code, out, err = run(["design", path, "--up", "z", "--out", tmp_path / "b",
                          "--stipples", "300", "--formats", "gcode"], capsys)
    assert code == 0 and "--up z" not in out + err
    after = re.search(r"(\d+) of 300 stipples are hidden", out + err)
    assert after is not None and int(after.group(1)) < int(hidden.group(1)) - 60


def test_the_band_is_stated_as_the_eye_sees_it(fitted: tuple[Path, str]):
    """The stripes' band in arcminutes at the viewing distance, beside how far
    apart neighbouring stipples look: the vertical error budget in the eye's terms."""
    import math

    out, summary = fitted
    info = json.loads((out / "hologram.json").read_text())
    band = info["settings"]["band"] or 0.2
    distance = info["settings"]["view_distance"]
    m = re.search(r"stripes: band ([\d.]+) mm, .* ([\d.]+) arcmin seen from ([\d.]+) mm, "
                  r"where neighbouring stipples look ([\d.]+) arcmin apart", summary)
    assert m is not None
    assert float(m.group(1)) == pytest.approx(band)
    assert float(m.group(2)) == pytest.approx(math.degrees(band / distance) * 60, abs=0.05)
    assert float(m.group(4)) > float(m.group(2))
