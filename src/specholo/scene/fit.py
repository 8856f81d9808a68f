"""Fitting a model to the plate a maker has: the largest size whose grooves lie on it.

A stipple's grooves pass through the points where its sightlines cross the
plate: for each eye on the viewing arc, the line from the eye to the stipple
meets z = 0 where the glint must be. Over the view range those crossings are
where the grooves go (the striped design keeps them within its band), so the
plate a design needs is known before any groove is designed. Seen from one
eye, the crossings are a central projection of the model onto the plate,
which maps the model's convex hull onto the hull of its crossings: the hull's
vertices and the eyes at the ends and middle of the range bound them all.

The eyes are any (m, 3) array: a flat design's along its viewing arc
(:func:`eyes_of`), a steady image's two eyes straight in front, a turning
plate's all round its axis. Jobs whose cuts reach past the crossings by more
than half a groove (a steady image's scoops run a few mm along the plate, a
turning plate's closed grooves are fitted curves through them) measure how far
on a first design and fit again (:func:`fit_design`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TypeVar

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


def eyes_of(viewer: Viewer) -> np.ndarray:
    """(m, 3) the eyes a flat design is seen from: single eyes on the viewing arc,
    sampled over its design range (the ends bound the crossings, the rest their
    vertical spread)."""
    theta = np.linspace(-viewer.design_range, viewer.design_range, _EYE_SAMPLES)
    return viewer.eye(theta)


def crossing_extent_from(points: np.ndarray, eyes: np.ndarray) -> np.ndarray:
    """(2, 2) lowest and highest (x, y) where the sightlines from (m, 3) eyes to
    (n, 3) points cross the plate z = 0, mm.

    Raises:
        SpecholoError: a point is not in front of every eye (nearer the eyes' side
            than the plate's, or level with an eye).
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    eyes = np.asarray(eyes, dtype=float).reshape(-1, 3)
    ez = eyes[None, :, 2]
    depth = ez - points[:, None, 2]
    # relative to the eyes' distance: a point level with an eye has no crossing
    scale = float(np.abs(eyes).max()) if eyes.size else 1.0
    if np.any(depth <= 1e-6 * scale):
        raise SpecholoError("the model reaches the eyes: no sightline to it crosses the plate")
    t = ez / depth  # where along eye -> point the line meets z = 0
    x = eyes[None, :, 0] + t * (points[:, None, 0] - eyes[None, :, 0])
    y = eyes[None, :, 1] + t * (points[:, None, 1] - eyes[None, :, 1])
    return np.array([[x.min(), y.min()], [x.max(), y.max()]])


def crossing_extent(points: np.ndarray, viewer: Viewer) -> np.ndarray:
    """(2, 2) lowest and highest (x, y) where the sightlines from every eye
    within the design range to (n, 3) points cross the plate, mm.

    Raises:
        SpecholoError: a point is not in front of every eye.
    """
    return crossing_extent_from(points, eyes_of(viewer))


def fit_size(points: np.ndarray, center: np.ndarray, plate: tuple[float, float],
             viewer: Viewer, reach: tuple[float, float], margin: float) -> float:
    """The largest size (mm) at which a model's grooves lie on the plate, seen
    from a flat design's eyes (:func:`eyes_of`); see :func:`fit_size_from`."""
    # as the design would refuse it: a model this near the nearest eye is too close
    nearest = 0.9 * viewer.distance * math.cos(viewer.design_range)
    return fit_size_from(points, center, plate, eyes_of(viewer), reach, margin, nearest)


def fit_size_from(points: np.ndarray, center: np.ndarray, plate: tuple[float, float],
                  eyes: np.ndarray, reach: tuple[float, float] | np.ndarray, margin: float,
                  nearest: float | None = None) -> float:
    """The largest size (mm) at which a model's crossings, from these eyes, lie on
    the plate.

    The model grows about its box centre: at size s its points are
    ``center + s * points``, with ``points`` the model scaled to size 1 about
    its own box centre.

    Args:
        points: (n, 3) the model at size 1, about its box centre (its hull will do).
        center: (3,) where its box centre goes (offset x, y and the depth), mm.
        plate: the plate's width and height, mm, centred on the plate origin.
        eyes: (m, 3) the eyes the plate is seen from, in the plate's frame, mm.
        reach: how far cuts reach past their crossings in x and in y, mm
            (half a groove width; in y also a striped design's band).
        margin: blank border kept at each edge of the plate, mm.
        nearest: highest z the model may reach, mm (default nine tenths of the
            lowest eye's height above the plate).

    Raises:
        SpecholoError: the plate cannot hold even a tiny model there.
    """
    points = hull_points(points)
    eyes = np.asarray(eyes, dtype=float).reshape(-1, 3)
    room = plate_room(plate, margin) - np.asarray(reach, dtype=float)
    top = 0.9 * float(eyes[:, 2].min()) if nearest is None else nearest

    def fits(size: float) -> bool:
        placed = center + size * points
        if placed[:, 2].max() >= top:
            return False
        lo, hi = crossing_extent_from(placed, eyes)
        return bool(np.all(-lo <= room) and np.all(hi <= room))

    if np.any(room <= 0) or not fits(_SMALLEST):
        raise SpecholoError(
            f"a {plate[0]:g} x {plate[1]:g} mm plate cannot hold the model at depth "
            f"{center[2]:g} mm, offset ({center[0]:g}, {center[1]:g}) mm: its grooves would "
            "leave the plate at any size; move it nearer the plate's middle and surface")
    return largest_size(fits)


def largest_size(fits: Callable[[float], bool]) -> float:
    """The largest size (mm) ``fits`` holds, by bisection of its logarithm
    between the smallest and the largest size tried (``fits`` of the smallest
    is known to hold)."""
    if fits(_LARGEST):
        return _LARGEST
    lo, hi = math.log(_SMALLEST), math.log(_LARGEST)
    for _ in range(_STEPS):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if fits(math.exp(mid)) else (lo, mid)
    return math.exp(lo)


def moving_crossings_fit(targets: Callable[[float], list[tuple[np.ndarray, np.ndarray]]],
                         room: np.ndarray) -> Callable[[float], bool]:
    """Whether a moving scene's crossings lie within ``room`` at a size: for
    each set of states, ``targets(size)`` gives the scene's points at each
    state (n, m, 3) and the eye at each state (m, 3), both in the plate's frame."""

    def fits(size: float) -> bool:
        for points, eyes in targets(size):
            ez = eyes[None, :, 2]
            depth = ez - points[:, :, 2]
            if np.any(depth <= 1e-6 * np.abs(ez)):
                return False  # the scene reaches an eye
            t = ez / depth
            for axis in (0, 1):
                e = eyes[None, :, axis]
                cross = e + t * (points[:, :, axis] - e)
                if float(np.abs(cross).max(initial=0.0)) > room[axis]:
                    return False
        return True

    return fits


def plate_room(plate: tuple[float, float], margin: float) -> np.ndarray:
    """(2,) how far from the plate's centre cuts may reach in x and y, mm: half
    the plate less its blank border."""
    return np.asarray(plate, dtype=float) / 2.0 - margin


def round_size(size: float) -> float:
    """A fitted size as a design records it: down to 0.001 mm (the rounded size
    still fits), at most the largest tried."""
    return math.floor(min(size, _LARGEST) * 1e3) / 1e3


_D = TypeVar("_D")

#: Shrinks by this factor at most this many times when a design's cuts still
#: leave the room after the second fit (fitted curves move a little with the size).
_SHRINK, _SHRINKS = 0.99, 20


def fit_design(size_with: Callable[[np.ndarray], float], design_at: Callable[[float], _D],
               spread: Callable[[_D], tuple[np.ndarray, np.ndarray]], room: np.ndarray,
               reach: np.ndarray) -> tuple[float, _D]:
    """The largest size, and its design, whose cuts lie within ``room``, for jobs
    whose cuts reach past their crossings by more than can be said beforehand.

    The size from the crossings alone is designed; how far its cuts reach past
    the crossings of its stipples, in x and in y, is the reach of a second fit,
    and that size is designed. Should its cuts still leave the room (the reach
    changes a little with the size), the size shrinks 1% at a time.

    Args:
        size_with: the fitted size (rounded) for (2,) reach past the crossings, mm.
        design_at: the design at a size.
        spread: (2,) how far from the plate's centre a design's cuts reach (the
            tool's edge included) and (2,) how far its stipples' crossings do, mm.
        room: (2,) how far cuts may reach, mm (:func:`plate_room`).
        reach: (2,) the least reach past the crossings (half a groove), mm.

    Raises:
        SpecholoError: the plate cannot hold the model at any size.
    """
    size = size_with(reach)
    design = design_at(size)
    cuts, crossed = spread(design)
    if np.all(cuts <= room):
        return size, design
    size = min(size, size_with(np.maximum(reach, cuts - crossed)))
    for _ in range(_SHRINKS):
        design = design_at(size)
        cuts, _ = spread(design)
        if np.all(cuts <= room):
            return size, design
        size = round_size(size * _SHRINK)
    raise SpecholoError("the cuts reach past the plate's blank border at every size tried, "
                        f"down to {size:g} mm: give a larger plate")
