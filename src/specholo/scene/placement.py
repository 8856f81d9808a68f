"""Placing a model behind, in or in front of the plate, turned the way the maker wants.

Models are taken y-up, facing +z (toward the viewer), as most mesh formats for
3D graphics are. A CAD or slicer file is usually z-up, its front facing -y:
``up="z"`` stands it up (model +z to the plate's +y, model -y toward the
viewer). Rotations about the plate's x, y and z axes follow, then the model is
scaled and centred, and moved by an offset on the plate."""

from __future__ import annotations

import math

import numpy as np

from specholo.errors import SpecholoError
from specholo.scene.loading import Model
from specholo.scene.mesh import Mesh
from specholo.scene.pose import UP_AXES as UP_AXES
from specholo.scene.pose import Pose as Pose
from specholo.scene.pose import orientation as orientation

# Largest relative error of the placed model's size.
_SIZE_TOLERANCE = 1e-9
def place(model: Model, size: float, center_z: float, rotation: np.ndarray | None = None,
          offset: tuple[float, float] = (0.0, 0.0)) -> Model:
    """Turn a model, scale it uniformly and centre it on the plate.

    The model is turned by ``rotation`` (see :func:`orientation`); the largest
    side of its axis-aligned bounding box then becomes ``size`` and the box
    centre moves to (offset x, offset y, center_z).

    Args:
        model: the model, in any units.
        size: largest side of the placed bounding box, mm (> 0).
        center_z: z of the box centre, mm (negative = behind the plate).
        rotation: (3, 3) proper rotation from model to plate axes, or None.
        offset: the box centre's x and y on the plate, mm.

    Returns:
        A new model in mm; a mesh keeps its faces and winding.

    Raises:
        SpecholoError: size is not a positive finite number, center_z is not
            finite, the model has no points, NaN or infinite ones, or zero
            extent (all points equal), or the placed model would not fit in
            floating point.
    """
    try:
        size = float(size)
        center_z = float(center_z)
    except (TypeError, ValueError, OverflowError) as exc:
        raise SpecholoError(f"model size and centre z must be numbers of mm, got {size!r} "
                            f"and {center_z!r}") from exc
    if not math.isfinite(size) or size <= 0:
        raise SpecholoError(f"model size must be a positive number of mm, got {size:g}")
    if not math.isfinite(center_z):
        raise SpecholoError(f"model centre z must be a finite number of mm, got {center_z:g}")

    ox, oy = (float(v) for v in offset)
    if not (math.isfinite(ox) and math.isfinite(oy)):
        raise SpecholoError(f"model offset must be finite mm, got {offset!r}")
    points = np.asarray(model.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3 or len(points) == 0:
        raise SpecholoError(f"model has no points to place (points of shape {points.shape})")
    if not np.isfinite(points).all():
        raise SpecholoError("model has NaN or infinite coordinates; cannot place it")
    if rotation is not None:
        # A proper rotation keeps a mesh's winding, so its normals stay outward.
        with np.errstate(over="ignore", invalid="ignore"):
            points = points @ np.asarray(rotation, dtype=np.float64)
        if not np.isfinite(points).all():
            raise SpecholoError("model coordinates are beyond floating-point range once turned")
    # Bring the coordinates below 1 by a power of two (exact) first, so that
    # the extent of a model spanning +-1e308 does not overflow and one of 1e-320
    # does not lose its digits.
    largest = float(np.max(np.abs(points)))
    k = math.frexp(largest)[1] if largest > 0 else 0
    unit = np.ldexp(points, -k)
    lo, hi = unit.min(axis=0), unit.max(axis=0)
    extent = float(np.max(hi - lo))
    if not extent > 0:
        raise SpecholoError("model has zero extent (all its points coincide); cannot scale it")

    scale = size / extent
    with np.errstate(over="ignore", invalid="ignore"):
        placed = (unit - 0.5 * (lo + hi)) * scale + np.array([ox, oy, center_z])
    if not np.isfinite(placed).all():
        raise SpecholoError(f"model size {size:g} mm at centre z {center_z:g} mm is beyond "
                            "floating-point range")
    # Far from the origin, floating point is coarse: a small model there would
    # be squashed. Halves, so that a model spanning +-1e308 does not overflow.
    got = 2.0 * float(np.max(placed.max(axis=0) / 2 - placed.min(axis=0) / 2))
    if not abs(got - size) <= _SIZE_TOLERANCE * size:
        raise SpecholoError(f"model size {size:g} mm is too small to place at centre z "
                            f"{center_z:g} mm (floating point is too coarse there)")

    if model.mesh is None:
        return Model(mesh=None, points=placed)
    # Uniform positive scaling keeps winding, so face normals stay outward.
    mesh = Mesh(placed, model.mesh.faces)
    return Model(mesh=mesh, points=mesh.vertices)
