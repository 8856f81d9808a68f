"""The flat host: the plate z = 0, and where sightlines cross it."""

from __future__ import annotations

import numpy as np


def sightline_crossing(eyes: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Where the line from each eye through each point crosses the plate z = 0.

    Args:
        eyes: (n, 3) eye positions (z > 0).
        points: (n, 3) virtual points, on either side of the plate but nearer
            the plate than the eye (p_z < e_z).

    Returns:
        (n, 3) crossings with z = 0.
    """
    eyes = np.asarray(eyes, dtype=float)
    points = np.asarray(points, dtype=float)
    t = eyes[..., 2] / (eyes[..., 2] - points[..., 2])
    s = eyes + t[..., None] * (points - eyes)
    s[..., 2] = 0.0
    return s
