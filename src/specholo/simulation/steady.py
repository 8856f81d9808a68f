"""What a still viewer sees on scoops (or flat grooves) as the sun moves.

On each cut's ball-centre polyline the glint condition t . h = 0 (t the path's
3D tangent, h the unit half vector at the wall point) is tested between
neighbouring segments (a sign change) and the glint placed by linear
interpolation. The ball's wall point there is the centre minus R h; the glint
exists only where that point is below the plate's surface (inside the cut).
A glint on a cut made for the other eye, or a second glint on one cut, is
stray. Each stipple's two glints are triangulated and compared with the
stipple; the drift is how far the triangulated point moves from where it is
with the light at the middle of its range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from specholo.optics.stereo import triangulate
from specholo.setup import Tool
from specholo.toolpaths.steady import SteadyDesign, unit_half


@dataclass(frozen=True)
class SteadyGlints:
    """Glints for one eye and one light elevation.

    Attributes:
        point: (g, 3) wall points that glint, mm.
        cut: (g,) the cut each lies on.
    """

    point: np.ndarray
    cut: np.ndarray


def find_steady_glints(design: SteadyDesign, eye: np.ndarray, light: np.ndarray,
                       tool: Tool) -> SteadyGlints:
    """Glints of every cut for an eye (3,) and sun direction (3,)."""
    c = design.centres
    if len(c) < 2:
        return SteadyGlints(np.zeros((0, 3)), np.zeros(0, dtype=np.int64))
    seg_t = c[1:] - c[:-1]
    seg_t /= np.maximum(np.linalg.norm(seg_t, axis=1, keepdims=True), 1e-15)
    mid = 0.5 * (c[1:] + c[:-1])
    # h at the wall point, which itself depends on h: two passes
    h = unit_half(mid, eye, light)
    h = unit_half(mid - tool.radius * h, eye, light)
    f = np.einsum("ij,ij->i", seg_t, h)
    vc = np.repeat(np.arange(design.n_cuts), np.diff(design.offsets))
    cut_of = vc[:-1]
    real = vc[:-1] == vc[1:]  # segments within one cut, not joining two
    pair = real[:-1] & real[1:] & (cut_of[:-1] == cut_of[1:])
    a = np.flatnonzero(pair & (np.sign(f[:-1]) != np.sign(f[1:])))
    w = f[a] / (f[a] - f[a + 1])
    centre = mid[a] + (mid[a + 1] - mid[a]) * w[:, None]
    hh = h[a] + (h[a + 1] - h[a]) * w[:, None]
    hh /= np.linalg.norm(hh, axis=1, keepdims=True)
    wall = centre - tool.radius * hh
    inside = wall[:, 2] < 0.0
    return SteadyGlints(wall[inside], cut_of[a][inside])


@dataclass(frozen=True)
class SteadyReport:
    """What both eyes see with the sun at one elevation.

    Attributes:
        elevation_deg: the light's elevation, degrees.
        median_mm, p95_mm: error of the triangulated point against the stipple.
        depth_p95_mm: the same for z alone.
        drift_p95_mm: how far the triangulated points moved from where they are
            with the light at the middle of the range (95th percentile).
        visibility: share of the stipples both eyes see.
        stray: glints on the other eye's cuts, or extra glints on a cut.
    """

    elevation_deg: float
    median_mm: float
    p95_mm: float
    depth_p95_mm: float
    drift_p95_mm: float
    visibility: float
    stray: int

    def as_dict(self) -> dict[str, float]:
        return dict(self.__dict__)


def _seen(design: SteadyDesign, tool: Tool, elevation: float
          ) -> tuple[np.ndarray, np.ndarray, int]:
    """Triangulated points (n, 3) (NaN where not both eyes see), and stray count."""
    setup = design.setup
    eyes = setup.eyes()
    light = setup.light(elevation)
    n = len(design.points)
    glint = np.full((2, n, 3), np.nan)
    stray = 0
    for e in range(2):
        g = find_steady_glints(design, eyes[e], light, tool)
        own = design.eye[g.cut] == e
        stray += int((~own).sum())
        s = design.stipple[g.cut[own]]
        count = np.bincount(s, minlength=n)
        stray += int(np.maximum(count - 1, 0).sum())
        glint[e, s] = g.point[own]
    both = np.all(np.isfinite(glint[:, :, 0]), axis=0)
    p = np.full((n, 3), np.nan)
    sel = np.flatnonzero(both)
    if len(sel):
        p[sel] = triangulate(np.broadcast_to(eyes[0], (len(sel), 3)), glint[0, sel],
                             np.broadcast_to(eyes[1], (len(sel), 3)), glint[1, sel])[0]
    return p, both, stray


def verify_steady(design: SteadyDesign, tool: Tool, elevations_deg: np.ndarray
                  ) -> list[SteadyReport]:
    """Move the sun through ``elevations_deg`` and measure what the eyes see."""
    ref, _, _ = _seen(design, tool, design.setup.light_elevation)
    out = []
    n = len(design.points)
    for el in np.asarray(elevations_deg, dtype=float):
        p, both, stray = _seen(design, tool, math.radians(el))
        sel = np.flatnonzero(both)
        if len(sel):
            err = np.linalg.norm(p[sel] - design.points[sel], axis=1)
            dz = np.abs(p[sel, 2] - design.points[sel, 2])
            moved = np.linalg.norm(p[sel] - ref[sel], axis=1)
            moved = moved[np.isfinite(moved)]
            rep = (float(np.median(err)), float(np.percentile(err, 95)),
                   float(np.percentile(dz, 95)),
                   float(np.percentile(moved, 95)) if len(moved) else math.nan)
        else:
            rep = (math.nan,) * 4
        out.append(SteadyReport(float(el), *rep, len(sel) / max(n, 1), stray))
    return out
