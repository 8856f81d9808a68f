"""The classic circular scratch every scratch-hologram tool draws, for comparison.

One circular arc per view interval, radius |p_z| cos a, touching p's straight-on
image: right near the straight-on view only (about 8 degrees, says the paper).
"""

from __future__ import annotations

import numpy as np

from specholo.optics.foliation import classic_glint_direction, classic_radius
from specholo.setup import Setup
from specholo.toolpaths.common import Runs, dots_for, split_near_plate, straight_on_image
from specholo.toolpaths.grooves import Grooves


def design_classic(runs: Runs, setup: Setup, near_plate: float | None = None) -> Grooves:
    """Circular-arc grooves, each spanning its run's azimuth interval.

    Args:
        runs: (stipple, interval) pairs.
        setup: light (its elevation sets the radius) and tool.
        near_plate: |p_z| below which a stipple becomes a dimple (mm).
    """
    far, near = split_near_plate(runs, setup, near_plate)
    if len(far) == 0:
        return dots_for(near, setup)
    a = setup.light.elevation
    r = classic_radius(far.point[:, 2], a)
    # Behind the plate the glint rides the top of a circle below p; in front, the bottom.
    side = np.where(far.point[:, 2] < 0, 1.0, -1.0)
    centre = straight_on_image(far.point, setup.viewer)
    centre[:, 1] -= side * r
    start = centre + (side * r)[:, None] * classic_glint_direction(far.start, a)
    end = centre + (side * r)[:, None] * classic_glint_direction(far.end, a)
    ang0 = np.arctan2(start[:, 1] - centre[:, 1], start[:, 0] - centre[:, 0])
    ang1 = np.arctan2(end[:, 1] - centre[:, 1], end[:, 0] - centre[:, 0])
    sweep = (ang1 - ang0 + np.pi) % (2 * np.pi) - np.pi
    n = len(far)
    vertices = np.empty((2 * n, 2))
    vertices[0::2] = start
    vertices[1::2] = end
    bulges = np.zeros(2 * n)
    bulges[0::2] = np.tan(sweep / 4.0)
    grooves = Grooves(vertices, bulges, np.arange(0, 2 * n + 1, 2, dtype=np.int64),
                      far.stipple.copy())
    return Grooves.concatenate([grooves, dots_for(near, setup)])
