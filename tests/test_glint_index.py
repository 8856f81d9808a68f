"""The arc index only skips arcs that cannot glint: same glints as testing every arc."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from specholo.fabrication.programs.gcode_reader import read_gcode
from specholo.jobs.flat.folder import DesignConfig, design, write_design
from specholo.setup import Light
from specholo.simulation.glints import Engraved, find_glints
from specholo.toolpaths.grooves import Grooves

BUNNY = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"
EYES = [(0, 0, 600), (30, 0, 600), (-47, 12, 600), (20, -25, 300), (55, 30, 1500),
        (-10, 60, 600), (5, 3, 2500)]
LIGHTS = [None, Light(math.radians(45.0), 400.0), Light(math.radians(75.0)),
          Light(math.radians(20.0), 900.0)]


def _zigzags() -> Grooves:
    """Straight zigzags (sharp corners) and arcs turning both ways."""
    zig = [np.array([[-15 + 1.5 * i, y + 0.6 * (i % 2)] for i in range(21)])
           for y in np.linspace(-18, 18, 5)]
    vertices = np.concatenate(zig)
    bulges = np.tile(np.r_[np.linspace(-0.3, 0.3, 20), 0.0], 5)
    bulges[::3] = 0.0
    sizes = [len(z) for z in zig]
    return Grooves(vertices, bulges, np.concatenate([[0], np.cumsum(sizes)]),
                   np.arange(len(sizes)))


@pytest.fixture(scope="module", params=["striped", "hyperbola", "arc", "gcode", "corners"])
def engraved(request, tmp_path_factory):
    if request.param == "corners":
        setup = DesignConfig().setup()
        return Engraved.from_grooves(_zigzags(), setup.tool), setup
    method = "striped" if request.param == "gcode" else request.param
    cfg = DesignConfig(stipples=150, method=method)
    d = design(BUNNY, cfg)
    grooves = d.grooves
    if request.param == "gcode":
        # Read back from the file: rounding leaves small corners between arcs.
        out = tmp_path_factory.mktemp("idx") / "holo"
        write_design(d, out)
        grooves = read_gcode(out / "hologram.gcode")
    return Engraved.from_grooves(grooves, cfg.setup().tool), cfg.setup()


def test_index_finds_exactly_the_glints_of_every_arc(engraved):
    eng, setup = engraved
    seen = 0
    for light in LIGHTS:
        light = light or setup.light
        for az, el, d in EYES:
            a, e = math.radians(az), math.radians(el)
            eye = d * np.array([math.cos(e) * math.sin(a), math.sin(e), math.cos(e) * math.cos(a)])
            fast = find_glints(eng, eye, light)
            full = find_glints(eng, eye, light, indexed=False)
            k1 = np.lexsort((fast.point[:, 1], fast.point[:, 0], fast.path))
            k0 = np.lexsort((full.point[:, 1], full.point[:, 0], full.path))
            np.testing.assert_array_equal(fast.path[k1], full.path[k0])
            np.testing.assert_allclose(fast.point[k1], full.point[k0], atol=1e-9)
            seen += len(full.path)
    assert seen > 20  # the comparison is not vacuous
