"""Stereo: where two eyes place a pair of glints in depth."""

from __future__ import annotations

import numpy as np


def triangulate(eye_l: np.ndarray, glint_l: np.ndarray, eye_r: np.ndarray,
                glint_r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Apparent points of glint pairs: midpoints of the closest points of two sightlines.

    Args:
        eye_l: (n, 3) left eyes. glint_l: (n, 3) glints the left eyes see.
        eye_r: (n, 3) right eyes. glint_r: (n, 3) glints the right eyes see.

    Returns:
        points (n, 3), and the gap (n,) between the two sightlines (their
        vertical disparity, in mm); parallel sightlines give NaN points.
    """
    d1 = glint_l - eye_l
    d2 = glint_r - eye_r
    w0 = eye_l - eye_r
    a = np.sum(d1 * d1, axis=1)
    b = np.sum(d1 * d2, axis=1)
    c = np.sum(d2 * d2, axis=1)
    d = np.sum(d1 * w0, axis=1)
    e = np.sum(d2 * w0, axis=1)
    den = a * c - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (b * e - c * d) / den
        t = (a * e - b * d) / den
    p1 = eye_l + s[:, None] * d1
    p2 = eye_r + t[:, None] * d2
    return 0.5 * (p1 + p2), np.linalg.norm(p1 - p2, axis=1)
