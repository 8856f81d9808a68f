"""The flat host: the plate z = 0, and where sightlines cross it."""

from __future__ import annotations

import numpy as np

from specholo.setup import Viewer


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


def crossing_components(viewer: Viewer, theta: np.ndarray, px: np.ndarray, py: np.ndarray,
                        pz: np.ndarray) -> tuple[np.ndarray, ...]:
    """Sightline crossings for eyes on the viewing arc, component-wise (hot loops).

    Args:
        viewer: the viewing arc.
        theta: (n,) eye azimuths in radians.
        px, py, pz: (n,) virtual point coordinates.

    Returns:
        s_x, s_y, ds_x/dtheta, ds_y/dtheta, each (n,).
    """
    sin, cos = np.sin(theta), np.cos(theta)
    d = viewer.eye_radius
    ex, ey, ez = d * sin, viewer.height, d * cos
    dex, dez = ez, -ex  # d eye / d theta
    inv = 1.0 / (ez - pz)
    t = ez * inv
    dt = -pz * dez * inv * inv
    rx, ry = px - ex, py - ey
    one_t = 1.0 - t
    return ex + t * rx, ey + t * ry, one_t * dex + dt * rx, dt * ry


def crossing_on_arc(viewer: Viewer, theta: np.ndarray,
                    points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sightline crossings for eyes on the viewing arc, and their theta-derivative.

    Args:
        viewer: the viewing arc.
        theta: (n,) eye azimuths in radians.
        points: (n, 3) virtual points.

    Returns:
        s (n, 3) crossing points and ds/dtheta (n, 3).
    """
    sx, sy, dsx, dsy = crossing_components(viewer, np.asarray(theta, dtype=float),
                                           points[:, 0], points[:, 1], points[:, 2])
    zero = np.zeros_like(sx)
    return np.stack([sx, sy, zero], axis=1), np.stack([dsx, dsy, zero], axis=1)
