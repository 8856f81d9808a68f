"""Placing a model behind, in or in front of the plate."""

from __future__ import annotations

import math

import numpy as np
import trimesh

from specholo.errors import SpecholoError
from specholo.scene.loading import Model


def place(model: Model, size: float, center_z: float) -> Model:
    """Scale a model uniformly and centre it on the plate axis.

    The largest side of the model's axis-aligned bounding box becomes ``size``
    and the box centre moves to (0, 0, center_z).

    Args:
        model: the model, in any units.
        size: largest side of the placed bounding box, mm (> 0).
        center_z: z of the box centre, mm (negative = behind the plate).

    Returns:
        A new model in mm; a mesh keeps its faces and winding.

    Raises:
        SpecholoError: size is not a positive finite number, center_z is not
            finite, or the model has zero extent (all points equal).
    """
    size = float(size)
    center_z = float(center_z)
    if not math.isfinite(size) or size <= 0:
        raise SpecholoError(f"model size must be a positive number of mm, got {size:g}")
    if not math.isfinite(center_z):
        raise SpecholoError(f"model centre z must be a finite number of mm, got {center_z:g}")

    points = np.asarray(model.points, dtype=np.float64)
    lo, hi = points.min(axis=0), points.max(axis=0)
    extent = float(np.max(hi - lo))
    if not extent > 0:
        raise SpecholoError("model has zero extent (all its points coincide); cannot scale it")

    scale = size / extent
    offset = np.array([0.0, 0.0, center_z]) - 0.5 * (lo + hi) * scale
    placed = points * scale + offset

    if model.mesh is None:
        return Model(mesh=None, points=placed)
    # Uniform positive scaling keeps winding, so face normals stay outward.
    mesh = trimesh.Trimesh(vertices=placed, faces=np.asarray(model.mesh.faces), process=False)
    return Model(mesh=mesh, points=np.asarray(mesh.vertices, dtype=np.float64))
