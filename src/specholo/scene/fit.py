"""Fitting a model to the plate a maker has: the largest size whose grooves lie on it.

A stipple's grooves pass through the points where its sightlines cross the
plate: for each eye on the viewing arc, the line from the eye to the stipple
meets z = 0 where the glint must be. Over the view range those crossings are
where the grooves go (the striped design keeps them within its band), so the
plate a design needs is known before any groove is designed. Seen from one
eye, the crossings are a central projection of the model onto the plate,
which maps the model's convex hull onto the hull of its crossings: the hull's
vertices and the eyes at the ends and middle of the range bound them all.
"""

from __future__ import annotations

import math

import numpy as np

from specholo.errors import SpecholoError
from specholo.setup import Viewer

#: Eye azimuths sampled over the design range: the crossings of a point move
#: monotonically with the azimuth, so the ends bound them; the rest cover the
#: vertical, which peaks in between.
_EYE_SAMPLES = 61
#: Sizes tried between these, mm, by bisection of the logarithm.
_SMALLEST, _LARGEST = 0.1, 10_000.0
_STEPS = 40


def hull_points(points: np.ndarray) -> np.ndarray:
    """(k, 3) the vertices of the convex hull of (n, 3) points (all of them when
    the hull is flat or there are fewer than five)."""
    from scipy.spatial import ConvexHull, QhullError

    points = np.asarray(points, dtype=float)
    if len(points) < 5:
        return points
    try:
        return points[ConvexHull(points).vertices]
    except (QhullError, ValueError):  # flat or degenerate: every point bounds it
        return points


def crossing_extent(points: np.ndarray, viewer: Viewer) -> np.ndarray:
    """(2, 2) lowest and highest (x, y) where the sightlines from every eye
    within the design range to (n, 3) points cross the plate, mm.

    Raises:
        SpecholoError: a point is not in front of every eye.
    """
    theta = np.linspace(-viewer.design_range, viewer.design_range, _EYE_SAMPLES)
    eyes = viewer.eye(theta)  # (m, 3)
    ez = eyes[None, :, 2]
    depth = ez - points[:, None, 2]
    if np.any(depth <= 1e-6 * viewer.distance):
        raise SpecholoError("the model reaches the eyes: no sightline to it crosses the plate")
    t = ez / depth  # where along eye -> point the line meets z = 0
    x = eyes[None, :, 0] + t * (points[:, None, 0] - eyes[None, :, 0])
    y = eyes[None, :, 1] + t * (points[:, None, 1] - eyes[None, :, 1])
    return np.array([[x.min(), y.min()], [x.max(), y.max()]])


def fit_size(points: np.ndarray, center: np.ndarray, plate: tuple[float, float],
             viewer: Viewer, reach: tuple[float, float], margin: float) -> float:
    """The largest size (mm) at which a model's grooves lie on the plate.

    The model grows about its box centre: at size s its points are
    ``center + s * points``, with ``points`` the model scaled to size 1 about
    its own box centre.

    Args:
        points: (n, 3) the model at size 1, about its box centre (its hull will do).
        center: (3,) where its box centre goes (offset x, y and the depth), mm.
        plate: the plate's width and height, mm, centred on the plate origin.
        viewer: the eyes.
        reach: how far grooves reach past their crossings in x and in y, mm
            (half a groove width; in y also the band).
        margin: blank border kept at each edge of the plate, mm.

    Raises:
        SpecholoError: the plate cannot hold even a tiny model there.
    """
    points = hull_points(points)
    room = np.array(plate, dtype=float) / 2.0 - margin - np.asarray(reach, dtype=float)
    nearest_eye = viewer.distance * math.cos(viewer.design_range)

    def fits(size: float) -> bool:
        placed = center + size * points
        if placed[:, 2].max() >= 0.9 * nearest_eye:
            return False  # as the design would refuse it: too close to the eyes
        lo, hi = crossing_extent(placed, viewer)
        return bool(np.all(-lo <= room) and np.all(hi <= room))

    if np.any(room <= 0) or not fits(_SMALLEST):
        raise SpecholoError(
            f"a {plate[0]:g} x {plate[1]:g} mm plate cannot hold the model at depth "
            f"{center[2]:g} mm, offset ({center[0]:g}, {center[1]:g}) mm: its grooves would "
            "leave the plate at any size; move it nearer the plate's middle and surface")
    if fits(_LARGEST):
        return _LARGEST
    lo, hi = math.log(_SMALLEST), math.log(_LARGEST)
    for _ in range(_STEPS):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if fits(math.exp(mid)) else (lo, mid)
    return math.exp(lo)
