"""The normality constraint (Brand, eq. 1) and the laws it encodes.

A glint at s needs the optical surface normal n parallel to the normality vector
    h(s) = eta1 u(i - s) + eta2 u(e - s),    u(v) = v / |v|,
with i the light (or u(i - s) replaced by the sun direction) and e the eye. For
reflection eta1 = eta2 and h is the half vector.
"""

from __future__ import annotations

import numpy as np

from specholo.setup import Light


def unit(v: np.ndarray) -> np.ndarray:
    """Normalise vectors along the last axis; shape preserved."""
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def normality(points: np.ndarray, light: Light, eyes: np.ndarray,
              eta1: float = 1.0, eta2: float = 1.0) -> np.ndarray:
    """Normality vectors h at glint candidates (not normalised).

    Args:
        points: (n, 3) surface points s in mm.
        light: the light.
        eyes: (n, 3) eye positions in mm (or (3,), broadcast).
        eta1: refractive index on the light's side.
        eta2: refractive index on the eye's side.

    Returns:
        (n, 3) vectors eta1 u(i - s) + eta2 u(e - s).
    """
    points = np.asarray(points, dtype=float)
    return eta1 * light.towards(points) + eta2 * unit(np.asarray(eyes, dtype=float) - points)


def reflect(direction: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Mirror reflection of ray directions about surface normals.

    Args:
        direction: (n, 3) incoming ray directions (toward the surface).
        normal: (n, 3) surface normals (any length, either orientation).

    Returns:
        (n, 3) reflected directions, same lengths as ``direction``.
    """
    n = unit(normal)
    return direction - 2.0 * np.sum(direction * n, axis=-1, keepdims=True) * n


def tilt(h: np.ndarray) -> np.ndarray:
    """Angle (radians) between vectors h (n, 3) and the plate normal +z."""
    return np.arccos(np.clip(unit(h)[..., 2], -1.0, 1.0))
