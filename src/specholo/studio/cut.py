"""What will be cut, for the studio's page: a finished design's grooves as
polylines, and its plate with the registration marks.

A groove is a chain of circular arcs (:class:`~specholo.toolpaths.grooves.Grooves`);
the page draws straight strokes, so each arc is cut into as many equal pieces
as keep the chords within :data:`TOLERANCE` of the arc (most of a design's arcs
bow less than that over their whole length and stay one chord). The polylines
keep every vertex of the grooves and are sent to the micrometre
(:data:`ROUNDING`), as flat arrays: a 2,000-stipple bunny is some 130,000
paths of 530,000 points, 8.6 MB of JSON (3.3 MB gzipped).

Above :data:`MAX_POINTS` points the page gets the grooves of every k-th
stipple only, whole, and is told so (``decimated``): a 5,000-stipple design
would otherwise be 20 MB of JSON for the page to parse and draw.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from specholo.fabrication.plate import Plate
from specholo.jobs.flat.folder import plate_of
from specholo.jobs.plate_common import design_json
from specholo.toolpaths.grooves import Grooves

#: Farthest a chord of the page's polylines lies from its arc, mm.
TOLERANCE = 0.001
#: The polylines' points are sent rounded to this, mm.
ROUNDING = 0.001
#: Most polyline points sent to the page (some 16 MB of JSON, 6 MB gzipped):
#: above it the page gets every k-th stipple's grooves.
MAX_POINTS = 1_000_000


def arc_pieces(chord: np.ndarray, bulge: np.ndarray, tolerance: float = TOLERANCE) -> np.ndarray:
    """How many equal pieces keep each arc's chords within ``tolerance`` of it.

    An arc of radius r and sweep s cut in n pieces bows r (1 - cos(s / 2n))
    from each piece's chord.

    Args:
        chord: (k,) chord lengths, mm.
        bulge: (k,) bulges (tan of a quarter of the sweep).

    Returns:
        (k,) piece counts, 1 or more.
    """
    b = np.abs(np.asarray(bulge, dtype=float))
    sweep = 4.0 * np.arctan(b)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        radius = np.where(b > 0, chord * (1.0 + b * b) / (4.0 * b), np.inf)
        # the largest sweep a piece may have: r (1 - cos(p / 2)) <= tolerance
        cosine = np.clip(1.0 - tolerance / radius, -1.0, 1.0)
        most = 2.0 * np.arccos(cosine)
        n = np.where((b > 0) & (radius * (1.0 - np.cos(0.5 * sweep)) > tolerance),
                     np.ceil(sweep / np.maximum(most, 1e-300)), 1.0)
    return np.maximum(n, 1).astype(np.int64)


def polylines(grooves: Grooves, tolerance: float = TOLERANCE) -> tuple[np.ndarray, np.ndarray]:
    """The grooves as polylines: every vertex, and points along each arc that
    bows more than ``tolerance`` from its chord.

    Returns:
        points (p, 2), mm, and offsets (n_paths + 1,): path j is
        ``points[offsets[j]:offsets[j + 1]]`` (a dot is a path of one point).
    """
    v = np.asarray(grooves.vertices, dtype=float)
    b = np.asarray(grooves.bulges, dtype=float)
    offsets = np.asarray(grooves.offsets, dtype=np.int64)
    m = len(v)
    # each vertex that starts an arc (all but a path's last) is followed by n - 1 new points
    starts = np.ones(m, dtype=bool)
    starts[offsets[1:][offsets[1:] > offsets[:-1]] - 1] = False
    extra = np.zeros(m, dtype=np.int64)
    first = np.flatnonzero(starts & (b != 0.0))
    if len(first):
        d = v[first + 1] - v[first]
        n = arc_pieces(np.hypot(d[:, 0], d[:, 1]), b[first], tolerance)
        extra[first] = n - 1
    where = np.arange(m, dtype=np.int64) + np.concatenate([[0], np.cumsum(extra)[:-1]])
    out = np.empty((m + int(extra.sum()), 2))
    out[where] = v
    split = np.flatnonzero(extra)
    if len(split):
        k = extra[split]
        p0, p1, bb = v[split], v[split + 1], b[split]
        chord = p1 - p0
        offset = (1.0 - bb * bb) / (4.0 * bb)
        centre = 0.5 * (p0 + p1) + np.column_stack([-chord[:, 1], chord[:, 0]]) * offset[:, None]
        radius = np.hypot(chord[:, 0], chord[:, 1]) * (1.0 + bb * bb) / (4.0 * np.abs(bb))
        angle0 = np.arctan2(p0[:, 1] - centre[:, 1], p0[:, 0] - centre[:, 0])
        sweep = 4.0 * np.arctan(bb)
        # the j-th of the n - 1 points inside each arc, j = 1 .. n - 1
        arc = np.repeat(np.arange(len(split)), k)
        j = np.arange(int(k.sum())) - np.repeat(np.cumsum(k) - k, k) + 1
        t = angle0[arc] + sweep[arc] * j / (k[arc] + 1)
        out[np.repeat(where[split], k) + j] = centre[arc] + radius[arc, None] * np.column_stack(
            [np.cos(t), np.sin(t)])
    return out, np.concatenate([where, [len(out)]])[offsets]


def plate_json(plate: Plate) -> dict[str, Any]:
    """The plate as the design's files draw it: outline, size and registration marks."""
    return {"corners_mm": plate.box.tolist(), "width_mm": plate.width,
            "height_mm": plate.height, "thickness_mm": plate.thickness,
            "marks_mm": plate.marks().tolist(), "mark_arm_mm": plate.mark_arm,
            "mark_radius_mm": plate.mark_radius}


def _table(info: dict[str, Any], key: str) -> dict[str, Any]:
    """``info[key]`` if it is a table, else an empty one (an older or odd folder)."""
    value = info.get(key)
    return value if isinstance(value, dict) else {}


def design_grooves(folder: Path, max_points: int | None = None,
                   tolerance: float = TOLERANCE) -> dict[str, Any]:
    """A finished design's grooves and plate, for the page (see the module's notes).

    Args:
        folder: the design folder (``grooves.npz``, ``hologram.json``).
        max_points: most points sent (None: :data:`MAX_POINTS`); above it every
            k-th stipple's grooves are.
        tolerance: farthest a chord lies from its arc, mm.

    Raises:
        SpecholoError: the folder is not a finished flat design.
    """
    max_points = MAX_POINTS if max_points is None else max_points
    info = design_json(folder)
    grooves = Grooves.load(folder / "grooves.npz")
    points, offsets = polylines(grooves, tolerance)
    total_points = len(points)
    stipple = np.asarray(grooves.stipple, dtype=np.int64)
    cut = np.unique(stipple)
    decimated: dict[str, Any] | None = None
    if total_points > max_points:
        sizes = np.diff(offsets)
        stride = max(2, math.ceil(total_points / max_points))
        while True:
            keep = np.isin(stipple, cut[::stride])
            if int(sizes[keep].sum()) <= max_points or stride >= len(cut):
                break
            stride += 1
        points = points[np.repeat(keep, sizes)]
        offsets = np.concatenate([[0], np.cumsum(sizes[keep])]).astype(np.int64)
        stipple = stipple[keep]
        decimated = {"stride": stride, "stipples_drawn": int(len(np.unique(stipple))),
                     "stipples_cut": int(len(cut)), "points_drawn": int(len(points)),
                     "points_all": total_points, "max_points": max_points}
    tool = _table(info, "tool")
    width = float(tool.get("groove_width_mm", 0.0) or 0.0)
    corners = plate_of(info)
    if corners is None:
        # an older folder names no plate: the one its files were drawn on
        corners = Plate.fitted(grooves.extent(), width).box
    thickness = _table(info, "plate").get("stock_thickness_mm")
    plate = Plate.from_corners(corners, float(thickness) if isinstance(
        thickness, (int, float)) and thickness > 0 else None)
    return {
        "paths": int(len(stipple)),
        "stipple": stipple.tolist(),
        "offsets": offsets.tolist(),
        "xy": np.round(points, 3).ravel().tolist(),
        "tolerance_mm": tolerance, "rounding_mm": ROUNDING,
        "groove_width_mm": width,
        "depth_mm": tool.get("depth_mm"),
        "groove_length_mm": float(grooves.total_length()),
        "plate": plate_json(plate),
        "settings": info.get("settings", {}),
        "decimated": decimated,
    }
