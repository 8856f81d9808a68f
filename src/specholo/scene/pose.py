"""How a model is turned and moved onto the plate (no mesh library needed).

Models are taken y-up, facing +z (toward the viewer). :data:`UP_AXES` names the
quarter turn that brings another axis up; rotations about the plate's x, y and z
axes follow (:func:`orientation`); :class:`Pose` holds them in the user's units
with the offset on the plate, for :func:`specholo.scene.placement.place`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from specholo.errors import SpecholoError

#: The model axis that points up on the plate, and the quarter turn (about the
#: plate's x or z axis) that takes it there: rows are where the model's x, y, z go.
UP_AXES: dict[str, tuple[tuple[int, int, int], ...]] = {
    "y": ((1, 0, 0), (0, 1, 0), (0, 0, 1)),
    "-y": ((1, 0, 0), (0, -1, 0), (0, 0, -1)),
    "z": ((1, 0, 0), (0, 0, -1), (0, 1, 0)),
    "-z": ((1, 0, 0), (0, 0, 1), (0, -1, 0)),
    "x": ((0, 1, 0), (-1, 0, 0), (0, 0, 1)),
    "-x": ((0, -1, 0), (1, 0, 0), (0, 0, 1)),
}


def orientation(up: str = "y", rotate: tuple[float, float, float] = (0.0, 0.0, 0.0)
                ) -> np.ndarray:
    """The rotation (3, 3) from model to plate axes: the model's ``up`` axis to the
    plate's +y, then ``rotate`` radians about the plate's x, y and z axes in turn.
    Applied to row vectors: ``plate = model @ R``.

    Raises:
        SpecholoError: an unknown axis or a rotation that is not finite.
    """
    if up not in UP_AXES:
        raise SpecholoError(f"up must be one of {', '.join(UP_AXES)}, got {up!r}")
    angles = [float(a) for a in rotate]
    if len(angles) != 3 or not all(math.isfinite(a) for a in angles):
        raise SpecholoError(f"rotations must be three finite angles, got {rotate!r}")
    r = np.array(UP_AXES[up], dtype=float)
    for axis, a in enumerate(angles):
        if a == 0.0:
            continue
        c, s = math.cos(a), math.sin(a)
        i, j = [(1, 2), (2, 0), (0, 1)][axis]
        turn = np.eye(3)
        turn[i, i], turn[i, j], turn[j, i], turn[j, j] = c, s, -s, c
        r = r @ turn
    return r


#: The command-line and TOML names of a pose (:meth:`Pose.from_options`).
POSE_OPTIONS = ("up", "rotate_x", "rotate_y", "rotate_z", "offset_x", "offset_y")


@dataclass(frozen=True)
class Pose:
    """How a model is turned and moved onto the plate, in the user's units.

    Attributes:
        up: the model's axis that points up on the plate (see :data:`UP_AXES`).
        rotate_deg: turns about the plate's x, y and z axes after that, degrees.
        offset: the model's box centre on the plate (x, y), mm.
    """

    up: str = "y"
    rotate_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    offset: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        try:
            rot = tuple(float(a) for a in self.rotate_deg)
            off = tuple(float(v) for v in self.offset)
        except (TypeError, ValueError) as exc:
            raise SpecholoError(f"placement angles and offset must be numbers: {exc}") from exc
        if len(rot) != 3 or not all(math.isfinite(a) and abs(a) <= 360.0 for a in rot):
            raise SpecholoError(f"rotations must be three angles in [-360, 360] degrees, "
                                f"got {self.rotate_deg!r}")
        if len(off) != 2 or not all(math.isfinite(v) and abs(v) <= 1e4 for v in off):
            raise SpecholoError(f"offset must be two numbers of mm within +-10000, got "
                                f"{self.offset!r}")
        if self.up not in UP_AXES:
            raise SpecholoError(f"up must be one of {', '.join(UP_AXES)}, got {self.up!r}")
        object.__setattr__(self, "rotate_deg", rot)
        object.__setattr__(self, "offset", off)

    @classmethod
    def from_options(cls, up: str | None = None, rotate_x: float | None = None,
                     rotate_y: float | None = None, rotate_z: float | None = None,
                     offset_x: float | None = None, offset_y: float | None = None) -> Pose:
        """The pose the command-line and TOML names ask for (None: the default)."""
        return cls(up or "y", (rotate_x or 0.0, rotate_y or 0.0, rotate_z or 0.0),
                   (offset_x or 0.0, offset_y or 0.0))

    @classmethod
    def from_saved(cls, saved: Any) -> Pose:
        """The pose a job's ``hologram.json`` recorded (:func:`dataclasses.asdict`);
        an empty table or None (a folder written before poses) is the default pose."""
        saved = saved or {}
        if not isinstance(saved, dict):
            raise SpecholoError("the pose must be a table")
        return cls(str(saved.get("up", "y")), tuple(saved.get("rotate_deg", (0.0, 0.0, 0.0))),
                   tuple(saved.get("offset", (0.0, 0.0))))

    def rotation(self) -> np.ndarray:
        """(3, 3) model-to-plate rotation (:func:`orientation`; degrees to radians here)."""
        rx, ry, rz = (math.radians(a) for a in self.rotate_deg)
        return orientation(self.up, (rx, ry, rz))


def split_pose(values: Mapping[str, Any]) -> tuple[Pose, dict[str, Any]]:
    """The pose that settings by the command-line names ask for (:data:`POSE_OPTIONS`),
    and the other settings; settings given as None are left out (their defaults)."""
    given = {k: v for k, v in values.items() if v is not None}
    return Pose.from_options(**{k: given.pop(k) for k in POSE_OPTIONS if k in given}), given


#: A flat base: faces within this angle of an axis, at the model's extreme along
#: it (within :data:`BASE_BAND` of its size), holding at least :data:`BASE_SHARE`
#: of the area and :data:`BASE_LEAD` times more than any other axis's base.
BASE_ANGLE = math.radians(10.0)
BASE_BAND = 0.02
BASE_SHARE = 0.02
BASE_LEAD = 1.5


def standing_up(vertices: np.ndarray, faces: np.ndarray) -> str | None:
    """Which way is up for a mesh that stands on a flat base (a key of
    :data:`UP_AXES`: ``"z"`` for a base at the lowest z facing -z, as CAD and
    slicer files place a part on the bed), or None where no base stands out.

    Args:
        vertices: (n, 3) vertex positions.
        faces: (m, 3) vertex indices of the triangles.
    """
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces, dtype=np.int64)
    if len(v) < 3 or len(f) == 0:
        return None
    tri = v[f]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = np.linalg.norm(cross, axis=1)  # twice each triangle's area
    total = float(area.sum())
    if not total > 0:
        return None
    unit = cross / np.maximum(area, 1e-300)[:, None]
    centre = tri.mean(axis=1)
    lo, hi = v.min(axis=0), v.max(axis=0)
    band = BASE_BAND * float((hi - lo).max())
    share: dict[str, float] = {}
    for axis, name in enumerate("xyz"):
        for sign, end in ((1.0, lo[axis]), (-1.0, hi[axis])):
            # A base at the low end faces -axis, and the model's up is +axis.
            base = (sign * -unit[:, axis] > math.cos(BASE_ANGLE)) & (
                np.abs(centre[:, axis] - end) < band)
            share[("" if sign > 0 else "-") + name] = float(area[base].sum()) / total
    best = max(share, key=lambda k: share[k])
    rival = max(s for k, s in share.items() if k.strip("-") != best.strip("-"))
    if share[best] < BASE_SHARE or share[best] < BASE_LEAD * rival:
        return None
    return best


def axis_name(vector: np.ndarray) -> str | None:
    """The key of :data:`UP_AXES` of a unit vector along an axis, else None."""
    v = np.asarray(vector, dtype=float)
    k = int(np.argmax(np.abs(v)))
    if abs(abs(v[k]) - 1.0) > 1e-9:
        return None
    return ("" if v[k] > 0 else "-") + "xyz"[k]
