"""Glints smaller than a cell of the height field: a ridged optic for a point a
few millimetres behind the plate turns its normal by several lobe widths
across one 0.02 mm cell. Its glints must still be found, where the eye's
sightline through the point crosses the plate, about as often as those of a
deep point, whose optic the cells resolve."""

from __future__ import annotations

import math

import numpy as np

from specholo.hosts.flat import sightline_crossing
from specholo.jobs.ridged.settings import RidgedConfig
from specholo.simulation.field_glints import LOBE, SlopeIndex, find_reflected_glints
from specholo.toolpaths.ridged import RidgeOptions, design_ridged, view_eyes


def _seen(depth: float) -> tuple[int, int, float]:
    """Views (of a grid) that see the one stipple's glint, the views, and the
    farthest glint from its sightline's crossing, mm."""
    setup = RidgedConfig.from_dict({"view_range": 10, "elevation_range": 4}).setup()
    points = np.array([[0.0, 0.0, -depth]])
    plate = design_ridged(points, None, None, setup,
                          RidgeOptions(delta=0.1, resolution=0.02, block=0.2,
                                       elevation_range=math.radians(4.0)))
    index = SlopeIndex.build(plate.heights)
    found, views, worst = 0, 0, 0.0
    for a in np.radians(np.arange(-9.0, 9.1, 2.0)):
        for e in np.radians(np.arange(-3.5, 3.6, 1.0)):
            eye = view_eyes(setup.viewer, a, e)
            views += 1
            g = find_reflected_glints(index, eye, setup.light)
            mine = g.glints.point[g.glints.stipple == 0]
            if len(mine):
                found += 1
                cross = sightline_crossing(eye[None], points)[0, :2]
                worst = max(worst, float(np.hypot(*(mine[:, :2] - cross).T).max()))
    return found, views, worst


def test_a_glint_smaller_than_a_cell_is_found_on_its_sightline():
    # The normal turns by about res / 2d a cell: many lobes at 3 mm, a fraction at 40.
    assert 0.02 / (2 * 3.0) > 5 * LOBE > 5 * 0.02 / (2 * 40.0)
    near, views, near_worst = _seen(3.0)
    deep, _, deep_worst = _seen(40.0)
    assert deep > 0.5 * views
    assert near >= 0.7 * deep
    # On the sightline, within the shell's depth offset (0.2 mm deep at <= 10 deg).
    assert near_worst < 0.05 and deep_worst < 0.05
