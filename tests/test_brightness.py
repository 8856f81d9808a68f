"""How bright a glint is, and which glints make a stipple's image.

A glint's brightness is the wall's reflecting area per steradian of its normal
(the product of its two radii of curvature there): on a ball-end groove of
centreline radius rho, about R rho / sin(tilt); at a corner where the path turns,
or a dimple, a sphere of the ball's radius, R^2. The point model's figure is
checked against the cut plate's own (the height field swept by the same ball,
whose glint search measures the reflecting area directly), and a corner's
faint glints are haze beside the designed ones.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from specholo.jobs.flat.folder import DesignConfig, design
from specholo.setup import Light, Tool, Viewer
from specholo.simulation.cut import cut_surface, find_cut_glints
from specholo.simulation.glints import FAINT_RATIO, INVISIBLE_RATIO, Engraved, Glints, find_glints
from specholo.simulation.verify import verify
from specholo.toolpaths.grooves import Grooves
from specholo.toolpaths.joining import join_stripes

BUNNY = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"
TOOL = Tool(0.25, 0.08)
LIGHT = Light(math.radians(45.0), 600.0)


def _arc_ends(rho: float, half: float = 3.0, y: float = 0.0) -> tuple[np.ndarray, float]:
    """The ends (2, 2) and bulge of an arc of radius rho spanning x in [-half, half]."""
    return np.array([[-half, y], [half, y]]), math.tan(math.asin(half / rho) / 2.0)


@pytest.mark.parametrize("rho", [5.0, 20.0])
def test_a_grooves_brightness_is_the_cut_walls(rho: float) -> None:
    ends, bulge = _arc_ends(rho)
    grooves = Grooves(ends, np.array([bulge, 0.0]), np.array([0, 2]), np.array([0]))
    eng = Engraved.from_grooves(grooves, TOOL)
    field = cut_surface(grooves, TOOL, TOOL.depth, resolution=0.005)
    for azimuth in (-5.0, 0.0, 5.0):
        eye = Viewer().eye(np.radians([azimuth]))[0]
        ideal = find_glints(eng, eye, LIGHT)
        cut = find_cut_glints(field, eye, LIGHT)
        assert ideal.brightness is not None and len(ideal.path) == len(cut.glints.path) == 1
        # the same glint, and as bright (the height field measures it within its sampling)
        assert np.allclose(ideal.point[:, :2], cut.glints.point[:, :2], atol=5e-3)
        assert ideal.brightness[0] == pytest.approx(cut.brightness[0], rel=0.08)
        # about R rho / sin(tilt): brighter on a flatter groove
        assert ideal.brightness[0] > TOOL.radius * rho


def test_a_dimple_glints_as_a_sphere() -> None:
    grooves = Grooves(np.zeros((1, 2)), np.zeros(1), np.array([0, 1]), np.array([0]))
    eye = Viewer().eye(np.radians([0.0]))[0]
    ideal = find_glints(Engraved.from_grooves(grooves, TOOL), eye, LIGHT)
    cut = find_cut_glints(cut_surface(grooves, TOOL, TOOL.depth, resolution=0.005), eye, LIGHT)
    assert ideal.brightness is not None
    assert ideal.brightness[0] == pytest.approx(TOOL.radius**2)
    assert ideal.brightness[0] == pytest.approx(cut.brightness[0], rel=0.15)


def _corner_and_arc() -> Grooves:
    """Stipple 0: a V whose legs never glint for eyes ahead, only its corner;
    stipple 1: an arc of radius 20 mm, glinting ahead."""
    ends, bulge = _arc_ends(20.0, y=5.0)
    vertices = np.concatenate([[[-2.0, -2.0], [0.0, 0.0], [2.0, -2.0]], ends])
    return Grooves(vertices, np.array([0.0, 0.0, 0.0, bulge, 0.0]), np.array([0, 3, 5]),
                   np.array([0, 1]))


def test_a_corner_is_haze_beside_a_groove() -> None:
    eng = Engraved.from_grooves(_corner_and_arc(), TOOL)
    eye = Viewer().eye(np.radians([0.0]))[0]
    gl = find_glints(eng, eye, LIGHT)
    assert gl.brightness is not None
    assert sorted(gl.stipple.tolist()) == [0, 1]
    corner = gl.brightness[gl.stipple == 0][0]
    groove = gl.brightness[gl.stipple == 1][0]
    assert corner == pytest.approx(TOOL.radius**2)
    assert groove > INVISIBLE_RATIO * corner  # far past what an eye sees beside it
    # the image keeps the groove's glint and drops the corner's
    assert gl.image().stipple.tolist() == [1]
    # a plate of corners (or dots) alone is its own typical stipple: it keeps them
    alone = gl.take(gl.stipple == 0)
    assert alone.image().stipple.tolist() == [0]


def test_a_stipples_faint_glint_beside_its_bright_one_is_haze() -> None:
    bright = np.array([1.0, 1.0 / (2 * FAINT_RATIO), 0.5])
    gl = Glints(np.array([0, 0, 1]), np.array([0, 0, 1]), np.zeros((3, 3)), bright)
    kept = gl.image()
    assert kept.brightness is not None and kept.brightness.tolist() == [1.0, 0.5]
    # without brightness every glint counts alike
    assert len(Glints(gl.path, gl.stipple, gl.point).image().path) == 3


def test_joined_stripes_show_what_the_stripes_show() -> None:
    """Joining a stipple's stripes adds corners that glint for many eyes, each
    about 1/2000 as bright as a designed glint: on the ideal grooves the eyes
    see the same stipples where they saw them, with the same errors."""
    cfg = DesignConfig(stipples=60, size=40, center_z=-30, light_elevation=45,
                       view_distance=600, view_range=30)
    d = design(BUNNY, cfg, expect_as_cut=False)
    setup = d.config.setup()
    joined = join_stripes(d.grooves, setup)
    assert joined.joined > 100 and joined.grooves.n_paths < d.grooves.n_paths / 5
    eye = setup.viewer.eye(np.radians([10.0]))[0]
    corners = find_glints(Engraved.from_grooves(joined.grooves, setup.tool), eye, setup.light)
    assert corners.brightness is not None
    assert (corners.brightness <= setup.tool.radius**2 * 1.0001).sum() > 10  # corner glints
    az = np.radians([-25.0, -10.0, 0.0, 15.0, 25.0])
    for a, b in zip(verify(d.grooves, d.points, setup, azimuths=az),
                    verify(joined.grooves, d.points, setup, azimuths=az), strict=True):
        assert b.visibility == pytest.approx(a.visibility)
        assert b.p95_error == pytest.approx(a.p95_error, abs=1e-6)
        assert b.false_glints == pytest.approx(a.false_glints)
