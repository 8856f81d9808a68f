"""Fitting a model to a given plate: the largest size whose grooves lie on it."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from specholo.errors import SpecholoError
from specholo.scene.fit import crossing_extent, fit_size
from specholo.setup import Viewer
from specholo_cli.cli import main

BUNNY = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"
CUBE = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])


def test_crossings_are_where_sightlines_meet_the_plate() -> None:
    viewer = Viewer(distance=600.0, half_range=math.radians(30.0), ipd=64.0)
    p = np.array([[10.0, 5.0, -40.0]])
    lo, hi = crossing_extent(p, viewer)
    # the outermost eyes, on the eyes' circle at the design range
    for sign, x in ((-1, lo[0]), (1, hi[0])):
        eye = viewer.eye(np.array([sign * viewer.design_range]))[0]
        t = eye[2] / (eye[2] - p[0, 2])
        assert x == pytest.approx(eye[0] + t * (p[0, 0] - eye[0]), abs=1e-9)
    # a point on the plate glints where it is, from every eye
    assert crossing_extent(np.array([[3.0, -2.0, 0.0]]), viewer) == pytest.approx(
        np.array([[3.0, -2.0], [3.0, -2.0]]))


def test_the_fitted_size_is_the_largest_that_fits() -> None:
    viewer = Viewer()
    center = np.array([5.0, 0.0, -30.0])
    size = fit_size(CUBE, center, (100.0, 80.0), viewer, (0.1, 0.3), 5.0)
    room = np.array([50.0 - 5.0 - 0.1, 40.0 - 5.0 - 0.3])

    def extent(s: float) -> np.ndarray:
        return crossing_extent(center + s * CUBE, viewer)

    lo, hi = extent(size)
    assert np.all(-lo <= room + 1e-6) and np.all(hi <= room + 1e-6)
    lo, hi = extent(size * 1.001)  # a hair larger leaves the room on some side
    assert np.any(-lo > room) or np.any(hi > room)
    # a model on the plate's surface spreads least: it may be larger
    assert fit_size(CUBE, np.array([5.0, 0.0, -0.0]), (100.0, 80.0), viewer, (0.1, 0.3),
                    5.0) > size
    with pytest.raises(SpecholoError, match="cannot hold the model"):
        fit_size(CUBE, np.array([60.0, 0.0, -30.0]), (100.0, 80.0), viewer, (0.1, 0.3), 5.0)


def test_design_fit_puts_the_grooves_on_the_plate(tmp_path: Path, capsys) -> None:
    out = tmp_path / "holo"
    args = ["design", str(BUNNY), "--out", str(out), "--stipples", "150", "--center-z", "-25",
            "--plate-width", "90", "--plate-height", "70", "--fit", "--offset-x", "4"]
    assert main(args) == 0
    info = json.loads((out / "hologram.json").read_text())
    size = info["settings"]["size"]
    assert info["settings"]["fit"] is True and 5.0 < size < 60.0
    g = np.load(out / "grooves.npz")
    xy = g["vertices"]
    assert np.abs(xy[:, 0]).max() <= 45.0 - 5.0 + 1e-6
    assert np.abs(xy[:, 1]).max() <= 35.0 - 5.0 + 1e-6
    # fit needs a plate
    capsys.readouterr()
    assert main(["design", str(BUNNY), "--out", str(tmp_path / "x"), "--fit"]) == 1
    assert "give plate-width and plate-height" in capsys.readouterr().err


def test_the_eyes_are_any_array() -> None:
    from specholo.scene.fit import crossing_extent_from, eyes_of, fit_size_from

    viewer = Viewer()
    p = np.array([[10.0, 5.0, -40.0], [-3.0, 2.0, 12.0]])
    assert crossing_extent_from(p, eyes_of(viewer)) == pytest.approx(crossing_extent(p, viewer))
    # two eyes straight in front: a point behind the plate crosses it nearer the middle
    eyes = np.array([[-32.0, 0.0, 600.0], [32.0, 0.0, 600.0]])
    lo, hi = crossing_extent_from(np.array([[0.0, 0.0, -60.0]]), eyes)
    assert lo[0] == pytest.approx(-32.0 * 60.0 / 660.0) and hi[0] == pytest.approx(-lo[0])
    # the same eyes fit a larger model than the whole arc
    center = np.array([0.0, 0.0, -30.0])
    assert fit_size_from(CUBE, center, (100.0, 80.0), eyes, (0.1, 0.1), 5.0) > \
        fit_size(CUBE, center, (100.0, 80.0), viewer, (0.1, 0.1), 5.0)


def _one_line(err: str) -> bool:
    return len([line for line in err.splitlines() if line.strip()]) == 1


@pytest.mark.parametrize("kind", ["steady", "spin"])
def test_steady_and_spin_fit_put_the_cuts_on_the_plate(kind: str, tmp_path: Path,
                                                       capsys) -> None:
    from specholo.jobs.steady.design import load_steady_folder
    from specholo.toolpaths.steady import tool_tips

    plate = ["--plate-width", "90", "--plate-height", "70"]
    # spin: whole grooves (no occlusion crop), so a few dozen stipples reach
    # near the model's outline and a larger size shows
    extra = {"steady": ["--center-z", "-20", "--stipples", "40"],
             "spin": ["--stipples", "40", "--no-occlusion", "--frames", "0"]}[kind]

    def reach(folder: Path) -> np.ndarray:
        """How far the cuts reach from the plate centre in x and y, the tool's edge in."""
        if kind == "steady":
            design, config = load_steady_folder(folder)
            return np.abs(tool_tips(design, config.tool)[:, :2]).max(axis=0) \
                + 0.5 * config.tool.width
        info = json.loads((folder / "hologram.json").read_text())
        r, d = info["settings"]["tool_radius"], info["settings"]["depth"]
        xy = np.load(folder / "grooves.npz")["vertices"]
        return np.abs(xy).max(axis=0) + math.sqrt(r * r - (r - d) ** 2)

    out = tmp_path / kind
    assert main([kind, str(BUNNY), "--out", str(out), *plate, "--fit", *extra]) == 0
    info = json.loads((out / "hologram.json").read_text())
    size = info["settings"]["size"]
    assert info["settings"]["fit"] is True and info["settings"]["plate_width"] == 90.0
    assert 5.0 < size < 200.0 and size == round(size, 3)
    room = np.array([45.0 - 5.0, 35.0 - 5.0])
    assert np.all(reach(out) <= room + 1e-6)
    # the program names the given plate
    assert "(plate: 90 x 70 mm, corners X-45 Y-35 to X45 Y35)" in \
        (out / "hologram.gcode").read_text()
    capsys.readouterr()
    assert main(["verify", str(out), "--step", "5"]) == 0
    # near the largest: 15% larger, the cuts leave the border or the plate
    bigger = tmp_path / "bigger"
    code = main([kind, str(BUNNY), "--out", str(bigger), *plate, "--size",
                 f"{1.15 * size:.3f}", *extra])
    if code == 0:
        assert np.any(reach(bigger) > room)
    else:
        assert code == 1 and "smaller than the design" in capsys.readouterr().err
    # fit needs a plate
    capsys.readouterr()
    assert main([kind, str(BUNNY), "--out", str(tmp_path / "x"), "--fit"]) == 1
    err = capsys.readouterr().err
    assert "give plate-width and plate-height" in err and _one_line(err)


COMPOSITION = """
mode = "walk"
stipples = 60
[host]
kind = "{kind}"
width = 90
height = 70
[light]
elevation = 45
[viewer]
distance = 600
range = 30
[tool]
radius = 0.05
depth = 0.02
[[scene]]
model = "{model}"
center_z = -25
{scene}
"""


def test_a_composition_scene_fits_its_plane_host(tmp_path: Path, capsys) -> None:
    from specholo.jobs.composition.design import (
        fitted_scene_size,
        parse_composition,
        prepare_scenes,
    )
    from specholo.scene.loading import load_model

    toml = tmp_path / "fit.toml"
    toml.write_text(COMPOSITION.format(kind="plane", model=BUNNY.as_posix(), scene="fit = true"))
    assert main(["compose", str(toml), "--out", str(tmp_path / "fit"), "--frames", "0",
                 "--step", "15"]) == 0
    points = np.load(tmp_path / "fit" / "grooves.npz")["point"]
    room = np.array([45.0 - 5.0, 35.0 - 5.0])
    assert np.all(np.abs(points[:, :2]).max(axis=0) <= room)
    # the largest: 15% larger, the grooves leave the border
    comp = parse_composition(toml.read_text(), tmp_path)
    scene = comp.scenes[0]
    key = prepare_scenes(comp)[0].key
    size = fitted_scene_size(comp, scene, key, load_model(BUNNY))
    assert 5.0 < size < 60.0
    big = tmp_path / "big.toml"
    big.write_text(COMPOSITION.format(kind="plane", model=BUNNY.as_posix(),
                                      scene=f"size = {1.15 * size}"))
    assert main(["compose", str(big), "--out", str(tmp_path / "big"), "--frames", "0",
                 "--step", "15"]) == 0
    points = np.load(tmp_path / "big" / "grooves.npz")["point"]
    assert np.any(np.abs(points[:, :2]).max(axis=0) > room)
    # a scene fits a plane with a size only
    capsys.readouterr()
    toml.write_text(COMPOSITION.format(kind="cylinder", model=BUNNY.as_posix(),
                                       scene="fit = true").replace("width = 90\n", ""))
    assert main(["compose", str(toml), "--out", str(tmp_path / "no")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "fit scales the scene to a plate" in err[0]
