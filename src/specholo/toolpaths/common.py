"""Pieces shared by every toolpath design."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from specholo.hosts.flat import sightline_crossing
from specholo.optics.normality import normality, unit
from specholo.setup import Setup, Viewer
from specholo.toolpaths.grooves import Grooves


@dataclass(frozen=True)
class Runs:
    """View intervals to design, one row per (stipple, interval).

    Attributes:
        stipple: (r,) stipple ids.
        point: (r, 3) the stipple's virtual point, mm.
        start: (r,) first eye azimuth served, radians.
        end: (r,) last eye azimuth served, radians (> start).
    """

    stipple: np.ndarray
    point: np.ndarray
    start: np.ndarray
    end: np.ndarray

    def __len__(self) -> int:
        return len(self.stipple)

    def take(self, mask: np.ndarray) -> Runs:
        """The runs selected by a boolean mask or index array."""
        return Runs(self.stipple[mask], self.point[mask], self.start[mask], self.end[mask])


def make_runs(points: np.ndarray, stipple: np.ndarray, start: np.ndarray,
              end: np.ndarray, min_span: float = 1e-4) -> Runs:
    """Runs for visibility intervals, dropping intervals narrower than ``min_span``.

    Args:
        points: (n, 3) all stipple points.
        stipple: (r,) stipple id of each interval.
        start: (r,) interval starts, radians.
        end: (r,) interval ends, radians.
        min_span: narrowest interval kept, radians.
    """
    stipple = np.asarray(stipple, dtype=np.int64)
    keep = (np.asarray(end) - np.asarray(start)) > min_span
    stipple = stipple[keep]
    return Runs(stipple, np.asarray(points, dtype=float)[stipple],
                np.asarray(start, dtype=float)[keep], np.asarray(end, dtype=float)[keep])


def straight_on_image(points: np.ndarray, viewer: Viewer) -> np.ndarray:
    """Where the central eye (azimuth 0) sees each point on the plate, shape (n, 2).

    The closed-form designs assume eyes at infinity; centring them on this
    image instead of (p_x, p_y) keeps them right for the straight-on view of a
    viewer at a finite distance, a fairer baseline.
    """
    eye = viewer.eye(np.zeros(1))
    return sightline_crossing(np.broadcast_to(eye, points.shape), points)[:, :2]


def dot_grooves(points: np.ndarray, stipple: np.ndarray, setup: Setup) -> Grooves:
    """Single plunges (spherical dimples) showing points on or very near the plate.

    A point on the plate is seen at the same place by every eye, and a dimple
    offers every normal up to the tool's wall tilt. Its glint sits on the wall,
    R h/|h| from the dimple's centre, so the centre is moved by that offset as
    seen straight on; other views keep a residue of R times the turn of h.

    Args:
        points: (k, 3) points on or very near the plate.
        stipple: (k,) their ids.
        setup: light, viewer and tool.
    """
    k = len(stipple)
    points = np.asarray(points, dtype=float)
    plate = points.copy()
    plate[:, 2] = 0.0
    eye = setup.viewer.eye(np.zeros(1))
    h = unit(normality(plate, setup.light, np.broadcast_to(eye, plate.shape)))
    centre = points[:, :2] + setup.tool.radius * h[:, :2]
    return Grooves(centre, np.zeros(k), np.arange(k + 1, dtype=np.int64),
                   np.asarray(stipple, dtype=np.int64))


def split_near_plate(runs: Runs, setup: Setup,
                     threshold: float | None = None) -> tuple[Runs, Runs]:
    """Separate runs whose point lies within ``threshold`` mm of the plate.

    Args:
        runs: the runs to design.
        setup: the setup (its groove width sets the default).
        threshold: |p_z| at or below which a stipple becomes a dimple; default
            half the groove width, where a groove would be shorter than it is wide.

    Returns:
        The runs to engrave as grooves, and those to engrave as dimples.
    """
    if threshold is None:
        threshold = 0.5 * setup.tool.width
    near = np.abs(runs.point[:, 2]) <= threshold
    return runs.take(~near), runs.take(near)


def dots_for(runs: Runs, setup: Setup) -> Grooves:
    """One dimple per stipple among ``runs`` (however many intervals it has)."""
    ids, first = np.unique(runs.stipple, return_index=True)
    return dot_grooves(runs.point[first], ids, setup)
