"""A plate sampled on a square grid as a watertight STL solid.

The top is the height field (two triangles per grid square), the bottom a flat
face at z = -thickness, and four side walls join them. Used for a ridged
design's plate (:class:`~specholo.toolpaths.heightmap.HeightMap`) and for the
cut-plate simulation's field (:class:`~specholo.simulation.cut.HeightField`).
"""

from __future__ import annotations

import math
from os import PathLike
from typing import Any, Protocol

import numpy as np

from specholo.errors import SpecholoError
from specholo.errors import positive as _positive
from specholo.fabrication.atomic import atomic_open

#: Default triangle budget of :func:`write_stl`.
STL_FACES = 4_000_000


class Grid(Protocol):
    """A plate sampled on a square grid: heights z (ny, nx), mm, sample [0, 0] at
    ``origin`` (2,), spacing ``resolution``, and the (2, 2) first and last sample
    positions ``bounds``."""

    @property
    def z(self) -> np.ndarray: ...

    @property
    def origin(self) -> np.ndarray: ...

    @property
    def resolution(self) -> float: ...

    @property
    def bounds(self) -> np.ndarray: ...


def write_stl(path: str | PathLike[str], field: Grid, thickness: float,
              region: np.ndarray | None = None, step: int | None = None,
              max_faces: int = STL_FACES) -> Any:
    """Write a plate sampled on a grid as a watertight solid, atomically (binary STL).

    The top is the height field (two triangles per grid square), the bottom a
    flat face at z = -thickness, and four side walls join them.

    Args:
        path: destination ``.stl`` file.
        field: the plate: a designed height map or a simulated cut.
        thickness: plate thickness, mm (more than the deepest cut).
        region: (2, 2) lower-left and upper-right corners to export, mm (snapped
            to samples); default the whole field.
        step: keep every step-th sample in x and y (the last row and column
            always, so the solid keeps its extent); default the smallest step
            that stays within ``max_faces``.
        max_faces: triangle budget used to choose ``step``.

    Returns:
        The ``trimesh.Trimesh`` written.

    Raises:
        SpecholoError: on a bad thickness, region or step.
    """
    import trimesh

    thickness = _positive("plate thickness", thickness)
    z = field.z
    if region is not None:
        region = np.asarray(region, dtype=float)
        if region.shape != (2, 2) or not np.all(np.isfinite(region)) or np.any(
                region[1] <= region[0]):
            raise SpecholoError(f"region must be [[x0, y0], [x1, y1]] with x1 > x0 and "
                                f"y1 > y0, got {region.tolist()}")
        lo = np.clip(np.rint((region[0] - field.origin) / field.resolution), 0,
                     np.array(z.shape[::-1]) - 1).astype(np.int64)
        hi = np.clip(np.rint((region[1] - field.origin) / field.resolution), 0,
                     np.array(z.shape[::-1]) - 1).astype(np.int64)
        if np.any(hi <= lo):
            raise SpecholoError(f"region {region.tolist()} holds less than one grid square "
                                f"of the field (bounds {field.bounds.tolist()})")
    else:
        lo, hi = np.zeros(2, np.int64), np.array(z.shape[::-1], np.int64) - 1
    n = hi - lo + 1
    if step is None:
        step = 1
        while 2 * (math.ceil((n[0] - 1) / step)) * math.ceil((n[1] - 1) / step) > max_faces:
            step += 1
    elif int(step) != step or step < 1:
        raise SpecholoError(f"step must be a positive integer, got {step}")
    step = int(step)
    ii = np.unique(np.append(np.arange(lo[0], hi[0] + 1, step), hi[0]))
    jj = np.unique(np.append(np.arange(lo[1], hi[1] + 1, step), hi[1]))
    top = z[np.ix_(jj, ii)].astype(float)
    if -top.min() >= thickness:
        raise SpecholoError(f"plate thickness {thickness:g} mm does not exceed the deepest "
                            f"cut {-top.min():g} mm")
    x = field.origin[0] + field.resolution * ii
    y = field.origin[1] + field.resolution * jj
    mesh = trimesh.Trimesh(*_solid(x, y, top, thickness), process=False)
    if not mesh.is_watertight:
        raise SpecholoError("the plate's mesh is not watertight")  # a bug, not bad input
    with atomic_open(path, "wb", encoding=None) as fh:
        fh.write(mesh.export(file_type="stl"))
    return mesh


def _solid(x: np.ndarray, y: np.ndarray, top: np.ndarray,
           thickness: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (v, 3) and outward-wound faces (f, 3) of a plate with a height-field top."""
    my, mx = top.shape
    gx, gy = np.meshgrid(x, y)
    bottom = np.array([[x[0], y[0]], [x[-1], y[0]], [x[-1], y[-1]], [x[0], y[-1]]])
    verts = np.concatenate([np.stack([gx.ravel(), gy.ravel(), top.ravel()], axis=1),
                            np.column_stack([bottom, np.full(4, -thickness)])])
    v = np.arange(my * mx).reshape(my, mx)
    a, b, c, d = v[:-1, :-1].ravel(), v[:-1, 1:].ravel(), v[1:, 1:].ravel(), v[1:, :-1].ravel()
    faces = [np.stack([a, b, c], 1), np.stack([a, c, d], 1)]  # counter-clockwise from above
    b0 = my * mx
    # Each wall follows the rim counter-clockwise seen from above, from the bottom
    # corner below its first top vertex: a fan from that corner.
    for rim, start, end in ((v[0, :], b0, b0 + 1), (v[:, -1], b0 + 1, b0 + 2),
                            (v[-1, ::-1], b0 + 2, b0 + 3), (v[::-1, 0], b0 + 3, b0)):
        fan = np.stack([np.full(len(rim) - 1, start), rim[1:], rim[:-1]], 1)
        faces += [fan, np.array([[start, end, rim[-1]]])]
    faces.append(np.array([[b0, b0 + 2, b0 + 1], [b0, b0 + 3, b0 + 2]]))
    return verts, np.concatenate(faces)
