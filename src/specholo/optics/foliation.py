"""Closed forms from the paper for a flat host and a sun (Brand, section 3).

With the eye and the sun at infinity, light (0, cos a, sin a) and eyes at
elevation 0, the glint-condition tangent is t1 ~ (cos a, -sin theta, 0) and the
sightline crosses the plate at x = p_x - p_z tan theta. Integrating gives the
hyperbola
    y(x) = p_y + p_z sec a (sqrt(((x - p_x) / p_z)^2 + 1) - 1),
with a plus sign (the paper's eq. 4 prints a minus; its eq. 5 and this agree).
The classic scratch is its osculating circle at the apex, radius |p_z| cos a.
"""

from __future__ import annotations

import numpy as np


def hyperbola_y(x: np.ndarray, apex: np.ndarray, pz: np.ndarray,
                elevation: float) -> np.ndarray:
    """Height of the closed-form toolpath with its apex at p's straight-on image.

    Args:
        x: (n,) plate x in mm.
        apex: (n, 2) straight-on image of p on the plate ((p_x, p_y) for eyes at infinity).
        pz: (n,) depth p_z of the points (nonzero).
        elevation: sun elevation a in radians.

    Returns:
        (n,) plate y in mm.
    """
    q = (x - apex[:, 0]) / pz
    return apex[:, 1] + pz / np.cos(elevation) * (np.sqrt(q * q + 1.0) - 1.0)


def hyperbola_slope(x: np.ndarray, apex: np.ndarray, pz: np.ndarray,
                    elevation: float) -> np.ndarray:
    """dy/dx of :func:`hyperbola_y`; equals -sin(theta) / cos(a) on the sightline."""
    q = (x - apex[:, 0]) / pz
    return q / np.sqrt(q * q + 1.0) / np.cos(elevation)


def classic_radius(pz: np.ndarray, elevation: float) -> np.ndarray:
    """Radius |p_z| cos a of the classic circular scratch (the apex osculating circle)."""
    return np.abs(pz) * np.cos(elevation)


def classic_glint_direction(theta: np.ndarray, elevation: float) -> np.ndarray:
    """Unit radial direction (n, 2) of the classic arc's glint for eyes at azimuth theta.

    The glint sits where the radius is parallel to the half vector's plate
    component (sin theta, cos a).
    """
    v = np.stack([np.sin(theta), np.full_like(theta, np.cos(elevation))], axis=1)
    return v / np.linalg.norm(v, axis=1, keepdims=True)
