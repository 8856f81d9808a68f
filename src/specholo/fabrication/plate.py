"""The plate blank and its registration marks, shared by the SVG, DXF and G-code writers.

Everything is in the plate frame, mm: x right, y up, origin at the plate
centre (where a program's X0 Y0 lies), the plate's top surface at z = 0.

A design's plate is ``--plate-width`` x ``--plate-height`` centred on the
origin or, without them, the smallest whole-millimetre rectangle centred on the
origin that holds the grooves with :data:`PLATE_MARGIN` of blank border
(:func:`fit_plate`). A writer called without a plate draws that one, so every
drawing and program names the plate it was made for.

The registration marks are a crosshair with a circle round its centre: one at
the origin and one just inside each corner, :data:`MARK_INSET` mm from both
edges, so that on a fitted plate the corner marks lie in the blank border
(they reach ``MARK_INSET + MARK_ARM`` = 4 mm in from the edges, the grooves
begin at least 5 mm in). On a plate too small for them they shrink with it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from specholo.errors import SpecholoError

#: The blank's thickness when none is given, mm: a plate (or a cup's wall) a few
#: millimetres thick, for every kind of design.
STOCK_THICKNESS = 3.0
#: Blank border around the grooves when the plate size is not given, mm.
PLATE_MARGIN = 5.0
#: Distance of a corner mark's centre from both edges of its corner, mm.
MARK_INSET = 2.5
#: Half the length of each line of a mark's crosshair, mm.
MARK_ARM = 1.5
#: Radius of a mark's circle, mm.
MARK_RADIUS = 1.0
#: Smallest plate side (mm) that takes the marks at full size: two corner marks
#: and the origin mark side by side, none touching another.
_FULL_SIZE_SIDE = 4.0 * MARK_INSET


def fit_plate(extent: np.ndarray, width: float, margin: float = PLATE_MARGIN) -> np.ndarray:
    """The plate a design gets when no size is given: centred on the origin, whole
    millimetres, ``margin`` mm of blank border beyond the grooves.

    Args:
        extent: (2, 2) corners of the grooves' centrelines (arcs' bulges included).
        width: groove width, mm (grooves reach half of it past their centrelines).
        margin: blank border, mm.

    Returns:
        (2, 2) lower-left and upper-right corners, mm.
    """
    lo, hi = np.asarray(extent, dtype=float)
    reach = np.maximum(np.abs(lo), np.abs(hi)) + 0.5 * float(width)
    size = np.ceil(2.0 * reach + 2.0 * margin)
    return np.stack([-0.5 * size, 0.5 * size])


@dataclass(frozen=True)
class Plate:
    """The plate blank in the plate frame, mm.

    Attributes:
        x0, y0: lower-left corner.
        x1, y1: upper-right corner.
        thickness: the blank's thickness, or None when the writer is not told it.
    """

    x0: float
    y0: float
    x1: float
    y1: float
    thickness: float | None = None

    def __post_init__(self) -> None:
        values = (self.x0, self.y0, self.x1, self.y1)
        for name, v in zip(("x0", "y0", "x1", "y1"), values, strict=True):
            object.__setattr__(self, name, float(v))
        if not all(math.isfinite(v) for v in values) or not (
                self.x0 < self.x1 and self.y0 < self.y1):
            raise SpecholoError(f"plate corners must be finite with x0 < x1 and y0 < y1, "
                                f"got {values}")
        if self.thickness is not None:
            t = float(self.thickness)
            if not (math.isfinite(t) and t > 0):
                raise SpecholoError(f"plate thickness must be a finite number > 0 mm, "
                                    f"got {self.thickness}")
            object.__setattr__(self, "thickness", t)

    @classmethod
    def from_corners(cls, corners: np.ndarray, thickness: float | None = None) -> Plate:
        """A plate from (2, 2) lower-left and upper-right corners, mm."""
        (x0, y0), (x1, y1) = np.asarray(corners, dtype=float)
        return cls(float(x0), float(y0), float(x1), float(y1), thickness)

    @classmethod
    def fitted(cls, extent: np.ndarray, width: float,
               thickness: float | None = None) -> Plate:
        """The plate of :func:`fit_plate` for grooves of this extent and width."""
        return cls.from_corners(fit_plate(extent, width), thickness)

    @property
    def width(self) -> float:
        return self.x1 - self.x0

    @property
    def height(self) -> float:
        return self.y1 - self.y0

    @property
    def box(self) -> np.ndarray:
        """(2, 2) lower-left and upper-right corners."""
        return np.array([[self.x0, self.y0], [self.x1, self.y1]])

    def corners(self) -> np.ndarray:
        """(4, 2) corners counter-clockwise from the lower left."""
        return np.array([[self.x0, self.y0], [self.x1, self.y0], [self.x1, self.y1],
                         [self.x0, self.y1]])

    @property
    def mark_scale(self) -> float:
        """Size of the marks against their full size: 1, less on a small plate."""
        return min(1.0, min(self.width, self.height) / _FULL_SIZE_SIDE)

    @property
    def mark_arm(self) -> float:
        """Half the length of a crosshair line, mm."""
        return MARK_ARM * self.mark_scale

    @property
    def mark_radius(self) -> float:
        """Radius of a mark's circle, mm."""
        return MARK_RADIUS * self.mark_scale

    def marks(self) -> np.ndarray:
        """(5, 2) centres of the registration marks: inside each corner,
        counter-clockwise from the lower left, then the origin."""
        inset = MARK_INSET * self.mark_scale
        inner = self.corners() + inset * np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]])
        return np.vstack([inner, np.zeros((1, 2))])



def check_plate_options(width: float | None, height: float | None, fit: bool) -> None:
    """Refuse a job's plate settings that do not make a plate: a size needs both
    sides, each a positive number of mm, and ``fit`` needs the size.

    Raises:
        SpecholoError: in one line, naming the options.
    """
    if fit and (width is None or height is None):
        raise SpecholoError("fit scales the model to a plate: give plate-width and "
                            "plate-height")
    if (width is None) != (height is None):
        raise SpecholoError("plate-width and plate-height go together: give both or neither")
    for name, v in (("plate-width", width), ("plate-height", height)):
        if v is not None and not (isinstance(v, (int, float)) and not isinstance(v, bool)
                                  and math.isfinite(v) and v > 0):
            raise SpecholoError(f"{name} must be a positive number of mm, got {v}")


def job_plate(extent: np.ndarray, width: float, size: tuple[float, float] | None,
              thickness: float | None = None) -> Plate:
    """The plate a job's writers name: ``size`` (width, height) centred on the
    origin, or without one the plate fitted to the cuts (:func:`fit_plate`).

    Args:
        extent: (2, 2) corners of the cuts' centrelines, mm.
        width: the cuts' width, mm (they reach half of it past their centrelines).
        size: the plate's width and height, mm, or None.
        thickness: the blank's thickness, if known.

    Raises:
        SpecholoError: a given plate is smaller than the cuts (one line).
    """
    if size is None:
        return Plate.fitted(extent, width, thickness)
    lo, hi = np.asarray(extent, dtype=float)
    reach = np.maximum(np.abs(lo), np.abs(hi)) + 0.5 * float(width)
    for axis, name in ((0, "width"), (1, "height")):
        if size[axis] < 2.0 * reach[axis]:
            raise SpecholoError(
                f"plate {name} {size[axis]:g} mm is smaller than the design, which needs "
                f"{2.0 * reach[axis]:.1f} mm (cuts reach +-{reach[axis]:.1f} mm from the centre)")
    half = 0.5 * np.asarray(size, dtype=float)
    return Plate.from_corners(np.stack([-half, half]), thickness)
