"""The paper's closed-form design: one continuous hyperbola per view interval.

Horizontal parallax is right for eyes and sun at infinity, but the glint slides
along the hyperbola's arms, off the sightline: this design shows how far the
closed form drifts at finite distances and away from the straight-on view.
"""

from __future__ import annotations

import math

import numpy as np

from specholo.hosts.flat import sightline_crossing
from specholo.optics.foliation import hyperbola_slope, hyperbola_y
from specholo.setup import Setup
from specholo.toolpaths.arcs import arc_chain
from specholo.toolpaths.common import Runs, dots_for, split_near_plate, straight_on_image
from specholo.toolpaths.grooves import Grooves

#: Smallest |h_y| / |h| the closed form serves (as the striped design): below it
#: the sun is too near the eyes' plane and the hyperbola's arms, y ~ sec a, run
#: off any plate (at a = 90 degrees, sec a ~ 1e16).
MIN_LIGHT_TILT = 0.05


def serves(runs: Runs, setup: Setup, near_plate: float | None = None) -> np.ndarray:
    """Which runs the closed form can design: all of them unless the sun lies
    within about 6 degrees of the eyes' plane (then only the dimples of points on
    the plate); for eyes at infinity straight on, h = l + z has
    |h_y| / |h| = cos a / sqrt(2 + 2 sin a)."""
    a = setup.light.elevation
    if math.cos(a) / math.sqrt(2.0 + 2.0 * math.sin(a)) >= MIN_LIGHT_TILT:
        return np.ones(len(runs), dtype=bool)
    threshold = 0.5 * setup.tool.width if near_plate is None else near_plate
    return np.abs(runs.point[:, 2]) <= threshold


def design_hyperbola(runs: Runs, setup: Setup, step: float = math.radians(0.5),
                     near_plate: float | None = None) -> Grooves:
    """Closed-form hyperbolic grooves, cropped to each run's azimuth interval.

    Args:
        runs: (stipple, interval) pairs.
        setup: light, viewer and tool (the light's elevation is the sun's).
        step: azimuth spacing of the samples joined by biarcs, radians.
        near_plate: |p_z| below which a stipple becomes a dimple (mm).
    """
    far, near = split_near_plate(runs, setup, near_plate)
    if len(far) == 0:
        return dots_for(near, setup)
    a = setup.light.elevation
    k = np.maximum(2, np.ceil((far.end - far.start) / step).astype(np.int64) + 1)
    run = np.repeat(np.arange(len(far)), k)
    first = np.concatenate([[0], np.cumsum(k)[:-1]])
    frac = (np.arange(run.size) - first[run]) / (k[run] - 1)
    theta = far.start[run] + (far.end - far.start)[run] * frac
    p = far.point[run]
    # Crop where this viewer's sightlines actually cross the plate.
    x = sightline_crossing(setup.viewer.eye(theta), p)[:, 0]
    apex = straight_on_image(far.point, setup.viewer)[run]
    y = hyperbola_y(x, apex, p[:, 2], a)
    direction = np.sign(x[np.minimum(first[run] + 1, run.size - 1)] - x[first[run]])
    direction[direction == 0] = 1.0
    slope = hyperbola_slope(x, apex, p[:, 2], a)
    tangent = np.stack([np.ones_like(x), slope], axis=1) * direction[:, None]
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    breaks = np.zeros(run.size, dtype=bool)
    breaks[first] = True
    vertices, bulges, offsets = arc_chain(np.stack([x, y], axis=1), tangent, breaks)
    grooves = Grooves(vertices, bulges, offsets, far.stipple.copy())
    return Grooves.concatenate([grooves, dots_for(near, setup)])
