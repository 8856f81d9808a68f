"""A plate surface given as a height field: what a ridged design produces.

:class:`HeightMap` is a plate sampled on a square grid (sample [j, i] at
origin + (i, j) * resolution: rows run up the plate, columns to the right),
heights in mm with 0 the uncut surface and cuts below it, and optionally the
stipple each sample belongs to. Its files (images, STL, raster G-code) are
written by :mod:`specholo.fabrication.heightmap`; the simulator reads it as it is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from specholo import __version__
from specholo.errors import SpecholoError

#: Largest value of a 16-bit sample.
LEVELS = 65535


@dataclass(frozen=True, eq=False)
class HeightMap:
    """A plate sampled on a square grid.

    Attributes:
        z: (ny, nx) float32 heights, mm (0 the plate surface, < 0 cut).
        origin: (2,) position of sample [0, 0], mm.
        resolution: sample spacing, mm.
        labels: (ny, nx) int32 stipple of each sample (-1 blank), or None.
    """

    z: np.ndarray
    origin: np.ndarray
    resolution: float
    labels: np.ndarray | None = None

    def __post_init__(self) -> None:
        z = np.asarray(self.z)
        if z.ndim != 2 or min(z.shape) < 2:
            raise SpecholoError(f"a height map needs at least 2 x 2 samples, got shape {z.shape}")
        res = float(self.resolution)
        if not (math.isfinite(res) and res > 0):
            raise SpecholoError(f"resolution must be a positive number of mm, got {res:g}")
        origin = np.asarray(self.origin, dtype=float)
        if origin.shape != (2,) or not np.all(np.isfinite(origin)):
            raise SpecholoError(f"origin must be 2 finite numbers, got {origin}")
        if self.labels is not None and np.shape(self.labels) != z.shape:
            raise SpecholoError(f"labels must have the heights' shape {z.shape}, got "
                                f"{np.shape(self.labels)}")
        object.__setattr__(self, "origin", origin)
        object.__setattr__(self, "resolution", res)

    @property
    def shape(self) -> tuple[int, int]:
        """(ny, nx)."""
        return (int(self.z.shape[0]), int(self.z.shape[1]))

    @property
    def x(self) -> np.ndarray:
        """(nx,) sample x positions, mm."""
        return self.origin[0] + self.resolution * np.arange(self.z.shape[1])

    @property
    def y(self) -> np.ndarray:
        """(ny,) sample y positions, mm."""
        return self.origin[1] + self.resolution * np.arange(self.z.shape[0])

    @property
    def bounds(self) -> np.ndarray:
        """(2, 2) first and last sample positions (x, y), mm."""
        hi = self.origin + self.resolution * (np.array(self.z.shape[::-1]) - 1)
        return np.stack([self.origin, hi])

    def scale(self) -> dict[str, Any]:
        """The record that maps image pixels back to millimetres."""
        lo = float(np.min(self.z))
        hi = float(np.max(self.z))
        return {
            "format": "specholo height map",
            "specholo_version": __version__,
            "frame": "plate mm: x right, y up, z toward the viewer, plate surface at z = 0",
            "width_px": int(self.z.shape[1]), "height_px": int(self.z.shape[0]),
            "mm_per_px": self.resolution,
            "origin_mm": self.origin.tolist(),
            "origin_is": "centre of the bottom-left pixel (image row height_px - 1, column 0)",
            "rows": "image row 0 is the top edge (y max)",
            "z_min_mm": lo, "z_max_mm": hi,
            "levels": LEVELS,
            "z_step_mm": (hi - lo) / LEVELS,
            "value": "z = z_min_mm + pixel * (z_max_mm - z_min_mm) / levels",
        }

    def quantised(self) -> np.ndarray:
        """(ny, nx) uint16 image, row 0 the top edge (y max)."""
        lo, hi = float(np.min(self.z)), float(np.max(self.z))
        if hi == lo:
            return np.zeros(self.shape, np.uint16)
        q = np.rint((self.z.astype(np.float64) - lo) * (LEVELS / (hi - lo)))
        return np.ascontiguousarray(np.clip(q, 0, LEVELS).astype(np.uint16)[::-1])
