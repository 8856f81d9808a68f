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
