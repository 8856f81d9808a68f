"""Verification of a plate given as a height field (ridged, full-parallax designs).

Each eye's glints are found on the field (:mod:`specholo.simulation.field_glints`
for a mirror lit from the front, :mod:`specholo.simulation.transmission` for a
clear plate lit from behind); for stereo eye pairs over azimuth and elevation
each stipple's two glints are triangulated with
:func:`specholo.simulation.verify.stereo_errors` and reported per head as
:class:`FullViewReport` (a :class:`~specholo.simulation.verify.ViewReport`
with the elevation and the views the design serves).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from specholo.setup import BackLight, Light, Setup, Viewer
from specholo.simulation.cut import MIN_COVERAGE
from specholo.simulation.field_glints import LOBE, FieldGlints, find_reflected_glints
from specholo.simulation.field_glints import SlopeIndex as SlopeIndex
from specholo.simulation.glints import Glints
from specholo.simulation.transmission import find_transmitted_glints
from specholo.simulation.verify import ViewReport, VisibilityFn
from specholo.simulation.verify import view_report as verify_view_report
from specholo.toolpaths.heightmap import HeightMap


def find_field_glints(field: HeightMap | SlopeIndex, eye: np.ndarray, light: Light,
                      lobe: float = LOBE, shadows: bool = True,
                      min_coverage: float = MIN_COVERAGE,
                      estimate: str = "centroid") -> FieldGlints:
    """All glints an eye sees on a labelled height field: a mirror lit from the front
    (:func:`~specholo.simulation.field_glints.find_reflected_glints`), or a clear
    plate lit from behind by a :class:`~specholo.setup.BackLight`
    (:func:`~specholo.simulation.transmission.find_transmitted_glints`). The
    arguments and the result are theirs.
    """
    if isinstance(light, BackLight):
        return find_transmitted_glints(field, eye, light, lobe, shadows, min_coverage,
                                       estimate)
    return find_reflected_glints(field, eye, light, lobe, shadows, min_coverage, estimate)


@dataclass(frozen=True)
class FullViewReport(ViewReport):
    """A :class:`~specholo.simulation.verify.ViewReport` for a head at an azimuth
    and an elevation.

    Attributes:
        elevation: head elevation in degrees.
        served: unoccluded stipples whose regions hold both eyes' sightline
            crossings (views the design serves); -1 without labels.
        served_visibility: share of those glinting for both eyes.
    """

    elevation: float = 0.0
    served: int = -1
    served_visibility: float = math.nan


def head_eyes(viewer: Viewer, azimuth: float, elevation: float) -> tuple[np.ndarray, np.ndarray]:
    """Left and right eyes (3,) of a head at an azimuth and elevation (radians) on
    the sphere of radius D about the plate centre raised to the eye height, IPD
    apart along the horizontal tangent."""
    d = viewer.distance
    head = np.array([d * math.cos(elevation) * math.sin(azimuth),
                     viewer.height + d * math.sin(elevation),
                     d * math.cos(elevation) * math.cos(azimuth)])
    tangent = np.array([math.cos(azimuth), 0.0, -math.sin(azimuth)])
    return head - 0.5 * viewer.ipd * tangent, head + 0.5 * viewer.ipd * tangent


def crossing_labels(hm: HeightMap, eye: np.ndarray, points: np.ndarray,
                    depth: float = 0.0) -> np.ndarray:
    """The label of the cell where each point's sightline from the eye crosses
    z = depth (-1 outside the field).

    Args:
        hm: the labelled plate. eye: (3,). points: (n, 3). depth: crossing height, mm.

    Returns:
        (n,) int labels.
    """
    if hm.labels is None:
        return np.full(len(points), -1)
    t = (eye[2] - depth) / (eye[2] - points[:, 2])
    xy = eye[:2] + t[:, None] * (points[:, :2] - eye[:2])
    ij = np.rint((xy - hm.origin) / hm.resolution).astype(np.int64)
    ny, nx = hm.shape
    inside = (ij[:, 0] >= 0) & (ij[:, 0] < nx) & (ij[:, 1] >= 0) & (ij[:, 1] < ny)
    out = np.full(len(points), -1, dtype=np.int64)
    out[inside] = hm.labels[ij[inside, 1], ij[inside, 0]]
    return out


def view_report(azimuth: float, elevation: float, points: np.ndarray, gl: Glints, gr: Glints,
                eye_l: np.ndarray, eye_r: np.ndarray, visible: VisibilityFn | None,
                served: np.ndarray | None = None) -> FullViewReport:
    """The figures of one head (angles in radians), as ``verify`` reports them.

    Args:
        azimuth, elevation: the head's, radians.
        points: (n, 3) stipples.
        gl, gr: each eye's glints, sorted by stipple.
        eye_l, eye_r: (3,) eyes.
        visible: occlusion test, None for none.
        served: (n,) bool, stipples whose regions serve both eyes; None if unknown.
    """
    n = len(points)
    gl, gr = (Glints(g.path[g.stipple < n], g.stipple[g.stipple < n], g.point[g.stipple < n])
              for g in (gl, gr))
    if visible is None or n == 0:
        vis_l = vis_r = np.ones(n, dtype=bool)
    else:
        vis_l = visible(points, np.broadcast_to(eye_l, (n, 3)))
        vis_r = visible(points, np.broadcast_to(eye_r, (n, 3)))
    base = verify_view_report(azimuth, points, gl, gr, eye_l, eye_r, vis_l, vis_r)
    n_served = -1
    served_vis = math.nan
    if served is not None:
        both_lit = ((np.bincount(gl.stipple, minlength=n) > 0)
                    & (np.bincount(gr.stipple, minlength=n) > 0))
        serve = served & vis_l & vis_r
        n_served = int(serve.sum())
        if n_served:
            served_vis = float((serve & both_lit).sum() / n_served)
    return FullViewReport(**dataclasses.asdict(base), elevation=math.degrees(elevation),
                          served=n_served, served_visibility=served_vis)


def default_views() -> tuple[np.ndarray, np.ndarray]:
    """Head azimuths (+-30 degrees) and elevations (+-15 degrees), every 5, radians."""
    return np.radians(np.arange(-30.0, 30.1, 5.0)), np.radians(np.arange(-15.0, 15.1, 5.0))


def verify_field(hm: HeightMap, points: np.ndarray, setup: Setup,
                 visible: VisibilityFn | None = None, azimuths: np.ndarray | None = None,
                 elevations: np.ndarray | None = None, lobe: float = LOBE,
                 shadows: bool = True, estimate: str = "centroid",
                 shell: float = 0.0) -> list[FullViewReport]:
    """Simulate stereo heads over azimuth and elevation on a labelled height field.

    Args:
        hm: the plate with labels.
        points: (n, 3) stipples the labels refer to.
        setup: light and viewer (distance, eye height, IPD).
        visible: occlusion test; None means every stipple is unoccluded.
        azimuths, elevations: head angles in radians (default :func:`default_views`);
            every combination is simulated.
        lobe, shadows, estimate: see :func:`find_field_glints`.
        shell: depth of the sightline crossings used to decide which views a
            region serves (the middle of the facets), mm below the plate.

    Returns:
        One report per (azimuth, elevation), azimuth-major.
    """
    points = np.asarray(points, dtype=float)
    az_default, el_default = default_views()
    azimuths = az_default if azimuths is None else np.asarray(azimuths, dtype=float)
    elevations = el_default if elevations is None else np.asarray(elevations, dtype=float)
    reports = []
    ids = np.arange(len(points))
    index = SlopeIndex.build(hm)
    for az in azimuths:
        for el in elevations:
            eye_l, eye_r = head_eyes(setup.viewer, float(az), float(el))
            found = [find_field_glints(index, e, setup.light, lobe, shadows,
                                       estimate=estimate)
                     for e in (eye_l, eye_r)]
            served = None
            if hm.labels is not None:
                served = ((crossing_labels(hm, eye_l, points, -shell) == ids)
                          & (crossing_labels(hm, eye_r, points, -shell) == ids))
            reports.append(view_report(float(az), float(el), points, found[0].glints,
                                       found[1].glints, eye_l, eye_r, visible, served))
    return reports


def report_table(reports: list[FullViewReport], key: str = "p95_error") -> str:
    """A text table of one figure by elevation (rows) and azimuth (columns)."""
    az = sorted({r.azimuth for r in reports})
    el = sorted({r.elevation for r in reports}, reverse=True)
    cell = {(r.azimuth, r.elevation): getattr(r, key) for r in reports}
    head = "el \\ az " + "".join(f"{a:>8.0f}" for a in az)
    rows = [head]
    for e in el:
        vals = [cell.get((a, e), math.nan) for a in az]
        rows.append(f"{e:>7.0f} " + "".join(f"{v:>8.3f}" if isinstance(v, float) else f"{v:>8d}"
                                            for v in vals))
    return "\n".join(rows)
